"""Narrow phase: one contact manifold per candidate pair, for every pair of shape kinds.

A manifold is one unit normal ``n`` (from the antagonist ``j`` towards the candidate ``i``, see
:mod:`granpack.contact.contacts`) and one or more points, each with its own signed gap (> 0 open,
< 0 interpenetration, in d), kept when the gap is at most the alert distance. Kernels work in a
frame centred on the antagonist's image ``x_j + shift`` (called body A) with the candidate ``i``
(body B) at offset ``x_i - x_j - shift``; the normal points from A to B.

Pair kinds (docs/method/contact-detection.md):

- sphere-sphere, sphere-wall: closed forms (a plane wall: the centre's height less the radius; the
  cylinder: ``R - |c_xy| - r`` along the inward radial direction).
- polyhedron-plane wall (the floor z = 0, a box's wall): every vertex at a height ``h < alert``
  is a point, gap ``h``, the wall's normal.
- polyhedron-cylinder: every vertex with ``R - |v_xy| < alert`` is a manifold of its own (one
  point, gap ``R - |v_xy|``, the inward radial normal at the vertex), :func:`_walls`.
- sphere-polyhedron: exact closest point of the polyhedron to the centre (GJK with a one-point
  set); centre inside: face of least depth.
- polyhedron-polyhedron: separating-axis test
  (:func:`~granpack.contact.separating_axes._sat`) over the face normals of both bodies
  and the cross products of their edge directions, stopping at the first axis that separates by
  more than the alert distance. The manifold comes from the best axis: for a face axis, the
  incident face of the other body (the face holding its support vertices,
  :func:`~granpack.contact.manifold._incident_face`) clipped against the reference face's side
  planes (Sutherland-Hodgman), **every vertex of the clipped polygon a point** (up to eight for two
  pinacoid faces); for an edge axis, the closest points of the two supporting edges. Face axes
  are preferred unless an edge axis is better by more than ``eps_f`` (hysteresis).

Gaps are exact. A separated pair's manifold is accepted when its smallest gap equals its axis's
separation or the best separation of all axes (a lower bound of the distance, which the gap, a
distance between two surface points, bounds from above: both are then the distance). No gap of
a separated face manifold is below the best separation: a clipped point is a point of the
incident body within the reference face's side planes, so its gap, its height over that face, is
at least the distance. That needs the reference face to be the one whose outward normal is the
axis; a face axis whose sign points away from every face of its body gives no face manifold.
When neither gap matches (vertex-vertex, vertex-edge, parallel edges) the distance and closest
points come from GJK. For an interpenetrating pair the smallest gap is minus the penetration
depth, the best separating-axis value ``σ <= 0``, and no point's gap is set below ``σ`` even when
the hysteresis keeps another axis: along such an axis the bodies seem to overlap by up to
``_KEEP_BAND eps_f`` more, and the position correction would chase those phantom overlaps. For
the same reason the point such a manifold adds at the depth is the best axis's deepest feature,
not the kept axis's deepest vertex, which may lie beside the reference face, outside the other
body.

Why every vertex: keeping four points of a clipped polygon (a common reduction) leaves the
others unconstrained, and a grain rocking about the kept ones slowly sinks them into its
neighbour, even in a pile at rest (measurements: docs/design-notes.md).

Temporal coherence: a pair keeps the code of the axis that last separated it (tried first), and
a touching pair's previous normal orders the manifold candidates (a previous edge-edge normal
that is also nearly a face axis selects the face: the faces have met), and the axis it matches
stays a candidate within ``5 eps_f`` of the best separation (the others within ``eps_f``). With
one band, an axis at its edge would flicker in and out from step to step, the normal and the force
of the manifold turning with it, and a pile at rest would never balance its forces. The loop between
the two bands is wide on purpose: a manifold switching between two axes a fraction of a degree
apart turns its normal at a place that depends on the direction of travel, so its force feeds a
grain sliding to and fro (in a slot between parallel faces) energy in proportion to the loop's
width, while the end game's damping takes it in proportion to the square of the swing needed to
go round the loop; a narrow loop keeps such a grain swinging (docs/design-notes.md).

Tolerances: ``eps_f`` (default 1e-3 d_min) is the feature band and the axis hysteresis; points
closer than ``1e-3 eps_f`` are merged.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from granpack._numba import jit
from granpack.contact._gjk import gjk_distance
from granpack.contact.contacts import manifold_type_nb
from granpack.contact.manifold import (
    _apart,
    _clamp_gaps,
    _clip_face,
    _deepest_feature,
    _deepest_point,
    _edge_contact,
    _gjk_manifold,
    _merge_points,
)
from granpack.contact.separating_axes import GENERAL, GeneralTables, _general_axes, _sat, world_geometry

__all__ = ["CandidatePairs", "KindBounds", "KindTables", "PreviousNormals", "Scratch", "narrow_phase", "world_geometry"]

_AXIS_FACE_A, _AXIS_FACE_B, _AXIS_EDGE = 0, 1, 2
#: |cos| between the previous normal and an axis above which the axis counts as the previous one
_HINT_COS = 0.999
#: the previous step's axis stays a manifold candidate within this many eps_f of the best
#: separation (the others within one); the edge-axis pruning of
#: :func:`~granpack.contact.separating_axes._sat` keeps as many
_KEEP_BAND = 5.0


#: The shape table's rows that the manifolds are built from (per kind, ``K`` kinds), and each
#: particle's kind; built by :meth:`granpack.contact.detect._Tables.tab`.
KindTables = namedtuple("KindTables", [
    "face_start",  # (K+1,) int64: CSR over kinds of the face rows
    "face_offsets",  # (NF,) float64: distance of each face's plane from its kind's centre, d
    "face_vertex_start",  # (NF+1,) int64: CSR over face rows of face_vertices
    "face_vertices",  # (NFV,) int64: local vertex indices of each face, counter-clockwise seen from outside
    "edge_start",  # (K+1,) int64: CSR over kinds of the edge rows
    "edges",  # (NE, 2) int64: local indices of the two vertices of each edge
    "edge_direction",  # (NE,) int64: local index of each edge's direction among its kind's edge directions
    "edge_faces",  # (NE, 2) int64: local indices of the two faces of each edge
    "kind",  # (N,) int64: each particle's kind
])

#: Per kind, whether it is a sphere, its bounding sphere, and the bounds of the separating-axis
#: test of general polyhedra (:func:`_general_tables`); built once per shape table by
#: :class:`granpack.contact.detect._Tables`.
KindBounds = namedtuple("KindBounds", [
    "is_sphere",  # (K,) bool: the kind is a sphere
    "radius",  # (K,) float64: circumscribed radius of each kind (a sphere's radius), d
    "axis_extent",  # (NA, 2) float64: least and largest a . v over a kind's vertices v along its face axis a, d
    "edge_arc",  # (NE, 2) float64: cosine between the normals of an edge's two faces, secant of half their angle
])

#: The work arrays of one narrow-phase call (one thread), from :func:`_scratch`; ``M`` is the
#: ``max_points`` of :func:`narrow_phase`.
Scratch = namedtuple("Scratch", [
    "simplex",  # (4, 3) float64: GJK's simplex, each point a vertex of A minus a vertex of B, d (gjk_distance)
    "simplex_a",  # (4,) int64: the vertex row of A of each simplex point
    "simplex_b",  # (4,) int64: the vertex row of B of each simplex point
    "weights",  # (4,) float64: barycentric weights of the simplex's point closest to the origin
    "face_weights",  # (4,) float64: the weights of one face of a tetrahedral simplex
    "band_rows",  # (4,) int64: vertex rows of two parallel edges, two of A then two of B (_gjk_manifold)
    "polygon",  # (M, 3) float64: the incident face as it is clipped, A-centred frame, d (_clip_face)
    "clipped",  # (M, 3) float64: the polygon after one more side plane, d (_clip_face)
    "vertex_block",  # (3, 2M) float64: a pair's vertices, coordinate-major, A's then B's shifted, d (X of _sat)
    "heights",  # (2M,) float64: vertex heights along an axis, d (_edge_contact's block, _clip_face's incident body)
])

#: The candidate pairs of the broad phase, as CSR over the first body ``i``.
CandidatePairs = namedtuple("CandidatePairs", [
    "start",  # (N+1,) int64: CSR offsets of each body's pairs
    "partner",  # (C,) int64: the other body j > i of each pair, each row sorted
    "axis",  # (C,) int64: code of the axis that separated a pair of polyhedra at the previous call, -1 none (updated)
])

#: The previous step's manifolds between two bodies, for the temporal axis hysteresis of
#: :func:`poly_poly`.
PreviousNormals = namedtuple("PreviousNormals", [
    "body_i",  # (Q,) int64: first body of each pair, sorted by (i, j)
    "body_j",  # (Q,) int64: second body, j > i
    "normal",  # (Q, 3) float64: unit normal of the manifold, from j to i
])

#: The output arrays of :func:`narrow_phase` (the arrays of a
#: :class:`~granpack.contact.contacts.ContactSet`), ``cap`` manifolds of at most ``max_points``
#: points each.
_Manifolds = namedtuple("_Manifolds", [
    "body_i",  # (cap,) int64: first body
    "body_j",  # (cap,) int64: second body, -1 the wall
    "shift",  # (cap, 3) float64: periodic image shift of body j, d
    "normal",  # (cap, 3) float64: unit normal from j to i
    "ctype",  # (cap,) int64: contact type 1/2/3
    "point_start",  # (cap + 1,) int64: CSR over manifolds of the points
    "point",  # (max_points cap, 3) float64: world contact points, d
    "gap",  # (max_points cap,) float64: gap of each point, d (< 0 overlap)
])


@jit(inline="always")
def poly_poly(a, b, ox, oy, oz, hx, hy, hz, sat, geo, tab, alert, eps_f, scr, pts, gp):
    """Manifold between polyhedra ``a`` (antagonist image, at the origin) and ``b`` (at ``o``, d).

    ``sat`` is the pair's :class:`~granpack.contact.separating_axes.SatResult`, one that does not
    separate the pair (the caller runs the test, so that the half of the pairs it rejects cost no
    call here), and its vertex block must still be in ``scr.vertex_block``. ``(hx, hy, hz)`` is
    the pair's normal at the previous step (zero if none): the separating axis closest to it is
    tried first when it is within ``eps_f`` (d) of the best separation (:func:`_candidate_order`).
    ``alert`` in d; ``geo``, ``tab``, ``scr``: the
    :class:`~granpack.contact.separating_axes.WorldGeometry`, :class:`KindTables` and
    :class:`Scratch`.

    Returns ``(count, nx, ny, nz)``: number of points written to ``pts`` (A-centred frame) and
    ``gp``, and the normal from A to B; count 0 means no contact within ``alert``.
    """
    pv, pf, rv, fn, ax = geo.vertex_start, geo.face_start, geo.vertices, geo.normals, geo.axes
    face_start, fvs, fverts = tab.face_start, tab.face_vertex_start, tab.face_vertices
    edge_start, edges, kind = tab.edge_start, tab.edges, tab.kind
    W, ia, ib, lam, tmp = scr.simplex, scr.simplex_a, scr.simplex_b, scr.weights, scr.face_weights
    buf, buf2, X, h = scr.polygon, scr.clipped, scr.vertex_block, scr.heights
    a0, a1, b0, b1 = pv[a], pv[a + 1], pv[b], pv[b + 1]
    sfa, kfa, gfa, sfb, kfb, gfb = sat.sfa, sat.kfa, sat.gfa, sat.sfb, sat.kfb, sat.gfb
    se, ex, ey, ez = sat.se, sat.ex, sat.ey, sat.ez
    sface = max(sfa, sfb)
    sigma = max(sface, se)
    tol_x = 1e-10 * (1.0 + abs(sigma))
    ka, kb = kind[a], kind[b]
    hinted = hx != 0.0 or hy != 0.0 or hz != 0.0
    ca = abs(hx * ax[kfa, 0] + hy * ax[kfa, 1] + hz * ax[kfa, 2]) if hinted else 0.0
    cb = abs(hx * ax[kfb, 0] + hy * ax[kfb, 1] + hz * ax[kfb, 2]) if hinted else 0.0
    ce = abs(hx * ex + hy * ey + hz * ez) if hinted else 0.0
    o0, o1, o2, band_a, band_b, band_e = _candidate_order(sfa, sfb, se, sigma, eps_f, hinted, ca, cb, ce)
    gjk_done = False
    st, dist, px, py, pz, qx, qy, qz = 1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for c in range(3):
        which = o0 if c == 0 else (o1 if c == 1 else o2)
        if which == _AXIS_FACE_A:
            sk, band = sfa, band_a
        elif which == _AXIS_FACE_B:
            sk, band = sfb, band_b
        else:
            sk, band = se, band_e
        if sk < sigma - band or sk == -math.inf:
            continue
        if which == _AXIS_FACE_A or which == _AXIS_FACE_B:
            if which == _AXIS_FACE_A:
                g = gfa
                nx, ny, nz = g * ax[kfa, 0], g * ax[kfa, 1], g * ax[kfa, 2]
                cnt, gmin = _clip_face(rv, a0, a1, 0.0, 0.0, 0.0, pf[a], pf[a + 1], b0, b1, ox, oy, oz, pf[b], pf[b + 1],
                                       fn, fvs, fverts, face_start[ka], face_start[kb], nx, ny, nz, alert, eps_f, h, buf,
                                       buf2, pts, gp)
            else:
                g = gfb
                nx, ny, nz = g * ax[kfb, 0], g * ax[kfb, 1], g * ax[kfb, 2]
                # reference face on B, outward normal -n
                cnt, gmin = _clip_face(rv, b0, b1, ox, oy, oz, pf[b], pf[b + 1], a0, a1, 0.0, 0.0, 0.0, pf[a], pf[a + 1],
                                       fn, fvs, fverts, face_start[kb], face_start[ka], -nx, -ny, -nz, alert, eps_f, h,
                                       buf, buf2, pts, gp)
            if cnt == 0:
                continue
            if sigma <= 0.0 and sk < sigma:
                # interpenetration on a face axis the hysteresis kept over a better one (module
                # docstring): no gap below sigma, the point at that depth the best axis's deepest feature
                _clamp_gaps(gp, cnt, sigma)
                if cnt < pts.shape[0] and _deepest_feature(
                        rv, a0, a1, b0, b1, ox, oy, oz, sfa, sfb, se, gfa, kfa, gfb, kfb, ex, ey, ez, ax,
                        edge_start[ka], edge_start[ka + 1], edge_start[kb], edge_start[kb + 1], edges, X, h,
                        pts[cnt:], gp[cnt:]) == 1 and _apart(pts, cnt, eps_f):
                    cnt += 1
                return cnt, nx, ny, nz
            if abs(gmin - sk) <= tol_x or (sigma > 0.0 and gmin - sigma <= tol_x):
                # the smallest gap is the axis separation, or, separated, the best separation of
                # every axis (a lower bound of the distance that a pair of surface points meets)
                return cnt, nx, ny, nz
            if sigma <= 0.0 and cnt < buf.shape[0]:
                # interpenetration whose deepest vertex lies outside the reference face: add it
                _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, nx, ny, nz, sk, which == _AXIS_FACE_B, 0.0,
                               pts[cnt:], gp[cnt:])
                return cnt + 1, nx, ny, nz
            if sigma > 0.0 and cnt < pts.shape[0]:
                # separated, but the closest points lie outside the overlap of the two faces (e.g.
                # nearly parallel faces, a corner of the incident face hanging over the reference
                # face's edge): keep the face manifold if it is within eps_f of the exact distance,
                # and add the exact closest-point pair so that the smallest gap is the distance
                if not gjk_done:
                    st, dist, px, py, pz, qx, qy, qz = gjk_distance(rv, a0, a1, rv, b0, b1, ox, oy, oz, alert,
                                                                    W, ia, ib, lam, tmp)
                    gjk_done = True
                if st == 0 and dist <= alert and gmin - dist <= eps_f:
                    if gmin - dist <= tol_x:
                        return cnt, nx, ny, nz
                    pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = 0.5 * (px + qx), 0.5 * (py + qy), 0.5 * (pz + qz)
                    gp[cnt] = dist
                    return cnt + 1, nx, ny, nz
        else:
            if _edge_contact(rv, a0, a1, b0, b1, ox, oy, oz, edge_start[ka], edge_start[ka + 1], edge_start[kb],
                             edge_start[kb + 1], edges, ex, ey, ez, se, X, h, pts, gp) == 1:
                if sigma <= 0.0:
                    _clamp_gaps(gp, 1, sigma)  # as for a face axis: the gap is the exact depth
                return 1, ex, ey, ez
    if sigma > 0.0:
        cnt, nx, ny, nz = _gjk_manifold(rv, a0, a1, b0, b1, ox, oy, oz, alert, eps_f, scr, pts, gp)
        if cnt >= 0:
            return cnt, nx, ny, nz
    # interpenetration (or touching) without an exact manifold: the deepest support vertex and
    # those within eps_f of it, along the best axis
    if se >= sface:
        nx, ny, nz = ex, ey, ez
        from_a = False
    elif sfa >= sfb:
        nx, ny, nz = gfa * ax[kfa, 0], gfa * ax[kfa, 1], gfa * ax[kfa, 2]
        from_a = False
    else:
        nx, ny, nz = gfb * ax[kfb, 0], gfb * ax[kfb, 1], gfb * ax[kfb, 2]
        from_a = True
    return _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, nx, ny, nz, sigma, from_a, eps_f, pts, gp), nx, ny, nz


@jit(inline="always")
def _candidate_order(sfa, sfb, se, sigma, eps_f, hinted, ca, cb, ce):
    """The order in which :func:`poly_poly` tries its three axes, separations ``sfa`` (A's best
    face axis), ``sfb`` (B's) and ``se`` (the best edge-edge axis), d, best ``sigma``, and the
    band below ``sigma`` (d) within which each is a candidate. ``hinted``: the pair had a normal at
    the previous step, whose ``|cos|`` with each axis is ``ca``, ``cb``, ``ce``.

    Candidate order: the better face axis, the other one, the edge axis; the edge axis first only
    if it beats both face axes by more than ``eps_f`` (hysteresis); a candidate whose axis is the
    previous step's normal goes first (temporal hysteresis). An axis is a candidate within
    ``eps_f`` of the best separation, or within ``_KEEP_BAND eps_f`` if it is the previous normal:
    one band would let an axis at its edge flicker in and out from step to step (the manifold's
    normal and type flipping at every step, its force with them), and a narrow loop between the
    two bands pumps a sliding grain (module docstring).

    Returns ``(o0, o1, o2, band_a, band_b, band_e)``: the axis kinds (``_AXIS_FACE_A``,
    ``_AXIS_FACE_B``, ``_AXIS_EDGE``) in order, and the bands of the three axes, d.
    """
    first_face = _AXIS_FACE_A if sfa >= sfb else _AXIS_FACE_B
    second_face = _AXIS_FACE_B if sfa >= sfb else _AXIS_FACE_A
    if se > max(sfa, sfb) + eps_f:
        o0, o1, o2 = _AXIS_EDGE, first_face, second_face
    else:
        o0, o1, o2 = first_face, second_face, _AXIS_EDGE
    band_a = band_b = band_e = eps_f
    if hinted:
        hint = max(ca, cb, ce)
        if hint > _HINT_COS:
            band_a = _KEEP_BAND * eps_f if ca == hint else eps_f
            band_b = _KEEP_BAND * eps_f if cb == hint and ca != hint else eps_f
            band_e = _KEEP_BAND * eps_f if ce == hint and ca != hint and cb != hint else eps_f
        ca = ca if sfa >= sigma - band_a else 0.0
        cb = cb if sfb >= sigma - band_b else 0.0
        ce = ce if se >= sigma - band_e else 0.0
        if max(ca, cb, ce) > _HINT_COS:
            if ca >= cb and ca >= ce:
                o0, o1, o2 = _AXIS_FACE_A, _AXIS_FACE_B, _AXIS_EDGE
            elif cb >= ce:
                o0, o1, o2 = _AXIS_FACE_B, _AXIS_FACE_A, _AXIS_EDGE
            elif ca > _HINT_COS or cb > _HINT_COS:
                # the previous edge-edge normal is also (nearly) a face axis: the faces have come
                # into contact, and a one-point edge-edge manifold would leave their corners free
                if ca >= cb:
                    o0, o1, o2 = _AXIS_FACE_A, _AXIS_FACE_B, _AXIS_EDGE
                else:
                    o0, o1, o2 = _AXIS_FACE_B, _AXIS_FACE_A, _AXIS_EDGE
            else:
                o0, o1, o2 = _AXIS_EDGE, first_face, second_face
    return o0, o1, o2, band_a, band_b, band_e


@jit
def _sphere_poly(ra, b, ox, oy, oz, geo, tab, alert, scr, one, pts, gp):
    """Sphere A (radius ``ra``, at the origin) against polyhedron ``b`` (at ``o``), lengths in d;
    ``one``: a ``(1, 3)`` zero row, the sphere's centre as a one-point set.

    Returns ``(count, nx, ny, nz)`` as :func:`poly_poly` (one point at most: the midpoint of the
    closest points; centre inside B: the face of least depth gives the normal and the gap).
    """
    pv, pf, rv, fn = geo.vertex_start, geo.face_start, geo.vertices, geo.normals
    face_start, face_offsets, kind = tab.face_start, tab.face_offsets, tab.kind
    W, ia, ib, lam, tmp = scr.simplex, scr.simplex_a, scr.simplex_b, scr.weights, scr.face_weights
    b0, b1 = pv[b], pv[b + 1]
    st, dist, px, py, pz, qx, qy, qz = gjk_distance(one, 0, 1, rv, b0, b1, ox, oy, oz, alert + ra, W, ia, ib, lam, tmp)
    if st == 1:
        return 0, 0.0, 0.0, 0.0
    if st == 0:
        g = dist - ra
        if g > alert:
            return 0, 0.0, 0.0, 0.0
        nx, ny, nz = qx / dist, qy / dist, qz / dist
        pts[0, 0] = 0.5 * (ra * nx + qx)
        pts[0, 1] = 0.5 * (ra * ny + qy)
        pts[0, 2] = 0.5 * (ra * nz + qz)
        gp[0] = g
        return 1, nx, ny, nz
    # centre inside B: face of least depth; B leaves along -n_f
    f0 = face_start[kind[b]]
    best = math.inf
    fb = pf[b]
    for f in range(pf[b], pf[b + 1]):
        depth = face_offsets[f0 + f - pf[b]] + fn[f, 0] * ox + fn[f, 1] * oy + fn[f, 2] * oz
        if depth < best:
            best, fb = depth, f
    nx, ny, nz = -fn[fb, 0], -fn[fb, 1], -fn[fb, 2]
    pts[0, 0] = -0.5 * (best - ra) * nx
    pts[0, 1] = -0.5 * (best - ra) * ny
    pts[0, 2] = -0.5 * (best - ra) * nz
    gp[0] = -(best + ra)
    return 1, nx, ny, nz


@jit
def _poly_sphere(a, rb, ox, oy, oz, geo, tab, alert, scr, one, pts, gp):
    """Polyhedron ``a`` (at the origin) against sphere B (radius ``rb``, at ``o``), lengths in d:
    the sphere-polyhedron manifold seen from the other body (normal flipped, points moved by
    ``o``); returns ``(count, nx, ny, nz)`` as :func:`poly_poly`."""
    cnt, nx, ny, nz = _sphere_poly(rb, a, -ox, -oy, -oz, geo, tab, alert, scr, one, pts, gp)
    for k in range(cnt):
        pts[k, 0] += ox
        pts[k, 1] += oy
        pts[k, 2] += oz
    return cnt, -nx, -ny, -nz


@jit
def _poly_plane(i, wx, wy, wz, hc, geo, alert, pts, gp):
    """Vertices of polyhedron ``i`` within ``alert`` (d) of a plane wall of inward unit normal
    ``w`` whose centre is at height ``hc`` (d) above it; points relative to its centre.

    A vertex ``v`` (body-to-world turned, relative to the centre) is at height
    ``h = hc + w . v``; each point lies midway between its vertex and the wall, ``v - h w / 2``,
    gap ``h``. Returns the count; ``pts`` must have at least as many rows as the polyhedron has
    vertices. The floor is ``w = e_z``, ``hc = z_i``.
    """
    rv = geo.vertices
    cnt = 0
    for k in range(geo.vertex_start[i], geo.vertex_start[i + 1]):
        z = hc + wx * rv[k, 0] + wy * rv[k, 1] + wz * rv[k, 2]
        if z < alert:
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = (rv[k, 0] - 0.5 * z * wx, rv[k, 1] - 0.5 * z * wy,
                                                     rv[k, 2] - 0.5 * z * wz)
            gp[cnt] = z
            cnt += 1
    return cnt


@jit(inline="always")
def _box_wall(w, xi, yi, lx, ly):
    """Inward unit normal ``(wx, wy)`` of the box's wall ``w`` (0: x = 0, 1: x = lx, 2: y = 0,
    3: y = ly; wall id ``-2 - w``) and the height above it of the centre ``(xi, yi)``, d."""
    if w == 0:
        return 1.0, 0.0, xi
    if w == 1:
        return -1.0, 0.0, lx - xi
    if w == 2:
        return 0.0, 1.0, yi
    return 0.0, -1.0, ly - yi


@jit(inline="always")
def _emit(i, j, sx, sy, nx, ny, nz, cx, cy, cz, pts, gp, cnt, eps_f, eps_pt, body_i, body_j, shift, normal, ctype,
          pstart, point, gap, m, npt):
    """Write manifold ``m`` of bodies ``i``, ``j`` (image shift ``(sx, sy, 0)``, normal ``n``) from
    its ``cnt`` points ``pts`` relative to ``c`` (d) and gaps ``gp`` (points closer than ``eps_pt``
    merged, the type from their rank within ``eps_f``); returns the next ``(m, npt)``."""
    cnt = _merge_points(pts, gp, cnt, eps_pt)
    body_i[m], body_j[m] = i, j
    shift[m, 0], shift[m, 1], shift[m, 2] = sx, sy, 0.0
    normal[m, 0], normal[m, 1], normal[m, 2] = nx, ny, nz
    ctype[m] = manifold_type_nb(pts, cnt, nx, ny, nz, eps_f)
    for k in range(cnt):
        point[npt, 0], point[npt, 1], point[npt, 2] = cx + pts[k, 0], cy + pts[k, 1], cz + pts[k, 2]
        gap[npt] = gp[k]
        npt += 1
    m += 1
    pstart[m] = npt
    return m, npt


@jit(inline="always")
def _nearest_wall(xi, yi, zi, container, lx, ly):
    """Distance (d) from the centre ``x_i`` to the nearest wall of the container (``container``
    and ``lx``, ``ly`` as :func:`narrow_phase`): the floor, the box's four walls, the cylinder.
    A body farther than its circumscribed radius plus the wall alert from every wall has no wall
    manifold, and is not handed to :func:`_walls` (a compiled call that increfs every array it is
    given)."""
    near = zi
    if container == 1:
        near = min(near, xi, lx - xi, yi, ly - yi)
    elif container == 2:
        dx, dy = xi - 0.5 * lx, yi - 0.5 * ly
        near = min(near, 0.5 * lx - math.sqrt(dx * dx + dy * dy))
    return near


@jit
def _walls(i, xi, yi, zi, ri, sphere, container, lx, ly, aw, geo, eps_f, eps_pt, pts, gp, out, m, npt):
    """The manifolds of body ``i`` (centre ``x_i``, circumscribed radius ``ri``, d; ``sphere``:
    a sphere of that radius, else a polyhedron) with the walls within ``aw`` (d), written to the
    :class:`_Manifolds` ``out`` from row ``m``, point ``npt``: the floor (-1), then the box's walls
    (``container`` 1: -2 to -5, planes, as the floor with their own normal) or the cylinder's
    (``container`` 2: -6, axis ``(lx/2, ly/2)``, inside radius ``R = lx/2``). Returns the next
    ``(m, npt)``.

    Cylinder: a sphere's gap is ``R - |c_xy| - r`` along the inward radial normal; a polyhedron
    touches it by vertices only (``|v_xy|`` is convex), each vertex ``v`` within ``aw`` its own
    manifold of one point, gap ``R - |v_xy|``, normal ``-v_xy / |v_xy|``, the point midway between
    the vertex and the wall (docs/design-notes.md: why one manifold per vertex).
    """
    bi, bj, sh, nr, ct, ps, po, ga = out.body_i, out.body_j, out.shift, out.normal, out.ctype, out.point_start, \
        out.point, out.gap
    for w in range(-1, 4 if container == 1 else 0):
        if w < 0:
            wx, wy, wz, hc = 0.0, 0.0, 1.0, zi
        else:
            wx, wy, hc = _box_wall(w, xi, yi, lx, ly)
            wz = 0.0
        if hc - ri >= aw:
            continue
        if w < 0 and sphere:
            g = zi - ri
            pts[0, 0], pts[0, 1], pts[0, 2] = 0.0, 0.0, 0.5 * g - zi
            gp[0] = g
            cnt = 1
        elif sphere:
            g = hc - ri
            pts[0, 0], pts[0, 1], pts[0, 2] = -(ri + 0.5 * g) * wx, -(ri + 0.5 * g) * wy, 0.0
            gp[0] = g
            cnt = 1
        else:
            cnt = _poly_plane(i, wx, wy, wz, hc, geo, aw, pts, gp)
        if cnt > 0:
            m, npt = _emit(i, -2 - w if w >= 0 else -1, 0.0, 0.0, wx, wy, wz, xi, yi, zi, pts, gp, cnt, eps_f, eps_pt,
                           bi, bj, sh, nr, ct, ps, po, ga, m, npt)
    if container != 2:
        return m, npt
    radius = 0.5 * lx
    dx, dy = xi - 0.5 * lx, yi - 0.5 * ly
    if radius - math.sqrt(dx * dx + dy * dy) - ri >= aw:
        return m, npt
    rv = geo.vertices
    k0, k1 = (0, 1) if sphere else (geo.vertex_start[i], geo.vertex_start[i + 1])
    for k in range(k0, k1):
        vx, vy, vz = (0.0, 0.0, 0.0) if sphere else (rv[k, 0], rv[k, 1], rv[k, 2])
        px, py = dx + vx, dy + vy
        rho = math.sqrt(px * px + py * py)
        ux, uy = (px / rho, py / rho) if rho > 0.0 else (1.0, 0.0)
        g = radius - rho - (ri if sphere else 0.0)
        if g >= aw:
            continue
        reach = (ri if sphere else 0.0) + 0.5 * g
        pts[0, 0], pts[0, 1], pts[0, 2] = vx + reach * ux, vy + reach * uy, vz
        gp[0] = g
        m, npt = _emit(i, -6, 0.0, 0.0, -ux, -uy, 0.0, xi, yi, zi, pts, gp, 1, eps_f, eps_pt, bi, bj, sh, nr, ct, ps,
                       po, ga, m, npt)
    return m, npt


@jit
def _manifold_buffers(cap, max_points):
    """Empty :class:`_Manifolds` for ``cap`` manifolds of at most ``max_points`` points."""
    return _Manifolds(np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 3)), np.empty((cap, 3)),
                      np.empty(cap, np.int64), np.zeros(cap + 1, np.int64), np.empty((max_points * cap, 3)),
                      np.empty(max_points * cap))


@jit
def _trimmed(out, m, npt, tested):
    """The first ``m`` manifolds and ``npt`` points of ``out`` (copies), and ``tested``, as
    :func:`narrow_phase` returns them."""
    return (out.body_i[:m].copy(), out.body_j[:m].copy(), out.shift[:m].copy(), out.normal[:m].copy(),
            out.ctype[:m].copy(), out.point_start[:m + 1].copy(), out.point[:npt].copy(), out.gap[:npt].copy(), tested)


@jit
def _scratch(max_points):
    """The :class:`Scratch` of one narrow-phase call, for polyhedra of at most ``max_points``
    vertices and faces of at most ``(max_points - 1) / 2`` vertices."""
    return Scratch(np.empty((4, 3)), np.empty(4, np.int64), np.empty(4, np.int64), np.empty(4), np.empty(4),
                   np.empty(4, np.int64), np.empty((max_points, 3)), np.empty((max_points, 3)),
                   np.empty((3, 2 * max_points)), np.empty(2 * max_points))


@jit
def _general_tables(tab, axis_extent, edge_arc, n_kinds):
    """The :class:`~granpack.contact.separating_axes.GeneralTables` of the ``n_kinds`` kinds of
    ``tab`` (a :class:`KindTables`; ``axis_extent``, ``edge_arc`` those of :class:`KindBounds`),
    with their scratch, for the separating-axis test of polyhedra that are not both centrally
    symmetric; ``inradius[k]`` is the radius of the largest ball about the centre inside kind
    ``k`` (its smallest face offset, d; 0 for a sphere), which prunes the axes of every pair."""
    face_start, face_offsets, edge_start = tab.face_start, tab.face_offsets, tab.edge_start
    inradius = np.zeros(n_kinds)
    for k in range(n_kinds):
        if face_start[k + 1] > face_start[k]:
            inradius[k] = face_offsets[face_start[k]:face_start[k + 1]].min()
    max_edges = max(np.diff(edge_start).max(), 1)
    max_faces = max(np.diff(face_start).max(), 1)
    return GeneralTables(edge_start, tab.edge_faces, tab.edge_direction, edge_arc, axis_extent, inradius,
                         np.empty((2, max_faces)), np.empty((4, max_edges)), np.empty(max_edges, np.int64), tab.edges,
                         face_start, face_offsets)


@jit
def narrow_phase(position, geo, tab, bounds, symmetric, pairs, previous, lx, ly, container, alert, reach, eps_f,
                 max_points, i0, i1):
    """Contact manifolds of the candidate pairs and wall pairs of the bodies ``i0 <= i < i1``.

    Rows are independent (a pair belongs to its row ``i``, the previous normals are looked up by
    ``(i, j)``), so disjoint row ranges may be computed by concurrent threads (the kernel releases
    the GIL) and their outputs concatenated in row order: the result is that of one call.

    Args:
        position: ``(N, 3)`` centres (x, y wrapped into the cell), d.
        geo, tab, bounds, symmetric: the :class:`~granpack.contact.separating_axes.WorldGeometry`
            of the particles, the :class:`KindTables` and :class:`KindBounds` of the shape table
            and its :class:`~granpack.contact.separating_axes.SymmetricTables`.
        pairs: the :class:`CandidatePairs` (``j > i``); their ``axis`` codes are read and updated
            in rows ``i0:i1`` (:func:`~granpack.contact.separating_axes._sat`).
        previous: the previous step's :class:`PreviousNormals` (temporal axis hysteresis).
        lx, ly: periods, d (a container's inside side, or the cylinder's diameter twice);
        container: 0 periodic, 1 box, 2 cylinder (:class:`granpack.box.Box` ``code``; a container
            has no image shifts and walls of its own, :func:`_walls`).
        alert: alert distance, d, the largest gap reported.
        reach: ``(N,)`` per body, d: pair ``(i, j)`` reports gaps up to ``min(alert, reach_i +
            reach_j)``, the wall pairs of ``i`` up to ``min(alert, 2 reach_i)``.
        eps_f: feature band / rank tolerance, d.
        max_points: scratch rows, at least the largest vertex count and twice the largest face
            size plus one; i0, i1: the rows computed (``0, N`` for all).

    Returns:
        ``(body_i, body_j, shift, normal, ctype, point_start, point, gap, n_tested)``: the
        :class:`~granpack.contact.contacts.ContactSet` arrays, ordered by ``i`` then ``j`` (the
        walls first: the floor, ``j = -1``, then the box's or the cylinder's), and the number of pairs whose bounding spheres overlap within
        ``alert`` (narrow-phase tests).
    """
    per_body = 1 if container == 0 else (5 if container == 1 else 1 + max_points)  # wall manifolds
    cap = pairs.start[i1] - pairs.start[i0] + per_body * (i1 - i0)
    out = _manifold_buffers(cap, max_points)
    body_i, body_j, shift, normal, ctype = out.body_i, out.body_j, out.shift, out.normal, out.ctype
    pstart, point, gap = out.point_start, out.point, out.gap
    scr = _scratch(max_points)
    one = np.zeros((1, 3))
    X, Y = scr.vertex_block, np.empty((3, 2 * max_points))
    pts, gp = np.empty((max_points, 3)), np.empty(max_points)
    eps_pt = 1e-3 * eps_f
    margin = _KEEP_BAND * eps_f  # the widest hysteresis band, which the separating-axis test's pruning keeps
    kind, is_sphere, radius = tab.kind, bounds.is_sphere, bounds.radius
    gauss = _general_tables(tab, bounds.axis_extent, bounds.edge_arc, len(radius))
    inradius = gauss.inradius
    pair_start, pair_j, pair_axis = pairs.start, pairs.partner, pairs.axis
    prev_i, prev_j, prev_n = previous.body_i, previous.body_j, previous.normal
    m = npt = tested = 0
    nprev = len(prev_i)
    pp = np.searchsorted(prev_i, i0)
    for i in range(i0, i1):
        ki = kind[i]
        xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
        ri = radius[ki]
        aw = min(alert, 2.0 * reach[i])
        if _nearest_wall(xi, yi, zi, container, lx, ly) - ri < aw:
            m, npt = _walls(i, xi, yi, zi, ri, is_sphere[ki], container, lx, ly, aw, geo, eps_f, eps_pt, pts, gp, out,
                            m, npt)
        for q in range(pair_start[i], pair_start[i + 1]):
            j = pair_j[q]
            kj = kind[j]
            dx = xi - position[j, 0]
            dy = yi - position[j, 1]
            if container == 0:
                sx = lx * math.floor(dx / lx + 0.5)
                sy = ly * math.floor(dy / ly + 0.5)
            else:
                sx = sy = 0.0
            ox, oy, oz = dx - sx, dy - sy, zi - position[j, 2]
            a = min(alert, reach[i] + reach[j])
            rr = ri + radius[kj] + a
            if ox * ox + oy * oy + oz * oz >= rr * rr:
                continue
            tested += 1
            if is_sphere[ki] and is_sphere[kj]:
                d = math.sqrt(ox * ox + oy * oy + oz * oz)
                g = d - ri - radius[kj]
                if g > a:
                    continue
                nx, ny, nz = (ox / d, oy / d, oz / d) if d > 0.0 else (0.0, 0.0, 1.0)
                c = radius[kj] + 0.5 * g
                pts[0, 0], pts[0, 1], pts[0, 2] = c * nx, c * ny, c * nz
                gp[0] = g
                cnt = 1
            elif is_sphere[kj]:
                cnt, nx, ny, nz = _sphere_poly(radius[kj], i, ox, oy, oz, geo, tab, a, scr, one, pts, gp)
            elif is_sphere[ki]:
                cnt, nx, ny, nz = _poly_sphere(j, ri, ox, oy, oz, geo, tab, a, scr, one, pts, gp)
            else:
                rin = inradius[kj] + inradius[ki]
                sat = _sat(geo, j, i, kj, ki, ox, oy, oz, symmetric, a, rin, margin, X, Y, pair_axis[q])
                if sat.axis == GENERAL:
                    sat = _general_axes(geo, j, i, kj, ki, ox, oy, oz, gauss, symmetric.axis_start, a, rin, margin, X)
                pair_axis[q] = sat.axis
                if sat.far:
                    continue
                while pp < nprev and (prev_i[pp] < i or (prev_i[pp] == i and prev_j[pp] < j)):
                    pp += 1
                if pp < nprev and prev_i[pp] == i and prev_j[pp] == j:
                    hx, hy, hz = prev_n[pp, 0], prev_n[pp, 1], prev_n[pp, 2]
                else:
                    hx, hy, hz = 0.0, 0.0, 0.0
                cnt, nx, ny, nz = poly_poly(j, i, ox, oy, oz, hx, hy, hz, sat, geo, tab, a, eps_f, scr, pts, gp)
            if cnt == 0:
                continue
            m, npt = _emit(i, j, sx, sy, nx, ny, nz, position[j, 0] + sx, position[j, 1] + sy, position[j, 2], pts, gp,
                           cnt, eps_f, eps_pt, body_i, body_j, shift, normal, ctype, pstart, point, gap, m, npt)
    return _trimmed(out, m, npt, tested)

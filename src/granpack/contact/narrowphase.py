"""Narrow phase: one contact manifold per candidate pair, for every pair of shape kinds.

A manifold is one unit normal ``n`` (from the antagonist ``j`` towards the candidate ``i``, see
:mod:`granpack.contact.contacts`) and one or more points, each with its own signed gap (> 0 open,
< 0 interpenetration, in d), kept when the gap is at most the alert distance. Kernels work in a
frame centred on the antagonist's image ``x_j + shift`` (called body A) with the candidate ``i``
(body B) at offset ``x_i - x_j - shift``; the normal points from A to B.

Pair kinds (docs/method/contact-detection.md):

- sphere-sphere, sphere-wall: closed forms.
- polyhedron-wall (plane z = 0): every vertex with ``z < alert`` is a point, gap ``z``.
- sphere-polyhedron: exact closest point of the polyhedron to the centre (GJK with a one-point
  set); centre inside: face of least depth.
- polyhedron-polyhedron: separating-axis test
  (:func:`~granpack.contact.separating_axes._sat`) over the face normals of both bodies
  and the cross products of their edge directions, stopping at the first axis that separates by
  more than the alert distance. The manifold comes from the best axis: for a face axis, the
  incident face of the other body clipped against the reference face's side planes
  (Sutherland-Hodgman), **every vertex of the clipped polygon a point** (up to eight for two
  pinacoid faces); for an edge axis, the closest points of the two supporting edges. Face axes
  are preferred unless an edge axis is better by more than ``eps_f`` (hysteresis).

Gaps are exact. A separated pair's manifold is accepted when its smallest gap equals its axis's
separation or the best separation of all axes (a lower bound of the distance, which the gap, a
distance between two surface points, bounds from above: both are then the distance); otherwise
(vertex-vertex, vertex-edge, parallel edges) the distance and closest points come from GJK. For
an interpenetrating pair the smallest gap is minus the penetration depth, the best
separating-axis value ``σ <= 0``, and no point's gap is set below ``σ`` even when the hysteresis
keeps another axis: along such an axis the bodies seem to overlap by up to ``eps_f`` more, and
the position correction would chase those phantom overlaps.

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
from granpack.contact._gjk import GjkScratch, gjk_distance
from granpack.contact.contacts import manifold_type_nb
from granpack.contact.manifold import (
    _clamp_gaps,
    _clip_face,
    _deepest_point,
    _edge_contact,
    _gjk_manifold,
    _merge_points,
)
from granpack.contact.separating_axes import GeneralTables, _sat, world_geometry

__all__ = ["CandidatePairs", "KindTables", "PreviousNormals", "Scratch", "narrow_phase", "world_geometry"]

_AXIS_FACE_A, _AXIS_FACE_B, _AXIS_EDGE = 0, 1, 2
#: |cos| between the previous normal and an axis above which the axis counts as the previous one
_HINT_COS = 0.999
#: the previous step's axis stays a manifold candidate within this many eps_f of the best
#: separation (the others within one); the edge-axis pruning of
#: :func:`~granpack.contact.separating_axes._sat` keeps as many
_KEEP_BAND = 5.0


#: The shape table's rows that the narrow phase reads (per kind, ``K`` kinds), and each
#: particle's kind; built by :meth:`granpack.contact.detect._Tables.tab`.
KindTables = namedtuple("KindTables", [
    "kind",  # (N,) int64: each particle's kind
    "is_sphere",  # (K,) bool: the kind is a sphere
    "radius",  # (K,) float64: circumscribed radius of each kind (a sphere's radius), d
    "face_start",  # (K+1,) int64: CSR over kinds of the face rows
    "face_offsets",  # (NF,) float64: distance of each face's plane from its kind's centre, d
    "face_vertex_start",  # (NF+1,) int64: CSR over face rows of face_vertices
    "face_vertices",  # (NFV,) int64: local vertex indices of each face, counter-clockwise seen from outside
    "edge_start",  # (K+1,) int64: CSR over kinds of the edge rows
    "edges",  # (NE, 2) int64: local indices of the two vertices of each edge
    "edge_direction",  # (NE,) int64: local index of each edge's direction among its kind's edge directions
    "edge_faces",  # (NE, 2) int64: local indices of the two faces of each edge
    "axis_extent",  # (NA, 2) float64: least and largest a . v over a kind's vertices v along its face axis a, d
    "edge_arc",  # (NE, 2) float64: cosine between the normals of an edge's two faces, secant of half their angle
])

#: The work arrays of one narrow-phase call (one thread), from :func:`_scratch`; ``M`` is the
#: ``max_points`` of :func:`narrow_phase`.
Scratch = namedtuple("Scratch", [
    "gjk",  # GjkScratch of gjk_distance
    "band_rows",  # (4,) int64: vertex rows of two parallel edges, two of A then two of B (_gjk_manifold)
    "polygon",  # (M, 3) float64: the incident face as it is clipped, A-centred frame, d (_clip_face)
    "clipped",  # (M, 3) float64: the polygon after one more side plane, d (_clip_face)
    "vertex_block",  # (3, 2M) float64: a pair's vertices, coordinate-major, A's then B's shifted, d (X of _sat)
    "half_block",  # (3, 2M) float64: one vertex of each antipodal pair of two symmetric bodies, d (Y of _sat)
    "heights",  # (2M,) float64: heights of the vertex block along an edge-edge axis, d (_edge_contact)
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

#: The manifolds written by :func:`narrow_phase`, one row per manifold and one per point; the
#: arrays of a :class:`~granpack.contact.contacts.ContactSet`.
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
    tried first when it is within ``eps_f`` (d) of the best separation. ``alert`` in d; ``geo``,
    ``tab``, ``scr``: the :class:`~granpack.contact.separating_axes.WorldGeometry`,
    :class:`KindTables` and :class:`Scratch`.

    Returns ``(count, nx, ny, nz)``: number of points written to ``pts`` (A-centred frame) and
    ``gp``, and the normal from A to B; count 0 means no contact within ``alert``.
    """
    sface = max(sat.sfa, sat.sfb)
    sigma = max(sface, sat.se)
    tol_x = 1e-10 * (1.0 + abs(sigma))
    o0, o1, o2, band_a, band_b, band_e = _candidate_order(sat, geo.axes, hx, hy, hz, eps_f, sigma)
    gjk_done = False
    st, dist, px, py, pz, qx, qy, qz = 1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for c in range(3):
        which = o0 if c == 0 else (o1 if c == 1 else o2)
        if which == _AXIS_FACE_A:
            sk, band = sat.sfa, band_a
        elif which == _AXIS_FACE_B:
            sk, band = sat.sfb, band_b
        else:
            sk, band = sat.se, band_e
        if sk < sigma - band or sk == -math.inf:
            continue
        if which == _AXIS_FACE_A or which == _AXIS_FACE_B:
            cnt, gmin, nx, ny, nz = _face_axis_clip(which == _AXIS_FACE_A, a, b, ox, oy, oz, sat, geo, tab, alert,
                                                    scr, pts, gp)
            if cnt == 0:
                continue
            if sigma <= 0.0 and sk < sigma:
                # interpenetration, this face axis preferred to the best one by the hysteresis:
                # along it the bodies overlap by up to eps_f more than their penetration depth
                # -sigma (a vertex below the face's plane but beside the face), so no point is
                # given a gap below sigma and the smallest gap is the exact depth
                gmin = _clamp_gaps(gp, cnt, sigma)
                sk = sigma
            if abs(gmin - sk) <= tol_x or (sigma > 0.0 and gmin - sigma <= tol_x):
                # the smallest gap is the axis separation, or, separated, the best separation of
                # every axis (a lower bound of the distance that a pair of surface points meets)
                return cnt, nx, ny, nz
            if sigma <= 0.0 and cnt < scr.polygon.shape[0]:
                # interpenetration whose deepest vertex lies outside the reference face: add it
                _deepest_point(geo, a, b, ox, oy, oz, nx, ny, nz, sk, which == _AXIS_FACE_B, pts[cnt:], gp[cnt:])
                return cnt + 1, nx, ny, nz
            if sigma > 0.0 and cnt < pts.shape[0]:
                # separated, but the closest points lie outside the overlap of the two faces (e.g.
                # nearly parallel faces, a corner of the incident face hanging over the reference
                # face's edge): keep the face manifold if it is within eps_f of the exact distance,
                # and add the exact closest-point pair so that the smallest gap is the distance
                if not gjk_done:
                    a0, a1 = geo.vertex_start[a], geo.vertex_start[a + 1]
                    b0, b1 = geo.vertex_start[b], geo.vertex_start[b + 1]
                    st, dist, px, py, pz, qx, qy, qz = gjk_distance(geo.vertices, a0, a1, geo.vertices, b0, b1, ox,
                                                                    oy, oz, alert, scr.gjk)
                    gjk_done = True
                if st == 0 and dist <= alert and gmin - dist <= eps_f:
                    if gmin - dist <= tol_x:
                        return cnt, nx, ny, nz
                    pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = 0.5 * (px + qx), 0.5 * (py + qy), 0.5 * (pz + qz)
                    gp[cnt] = dist
                    return cnt + 1, nx, ny, nz
        else:
            if _edge_contact(geo, tab, a, b, ox, oy, oz, sat.ex, sat.ey, sat.ez, sat.se, scr, pts, gp) == 1:
                if sigma <= 0.0:
                    _clamp_gaps(gp, 1, sigma)  # as for a face axis: the gap is the exact depth
                return 1, sat.ex, sat.ey, sat.ez
    return _fallback_manifold(a, b, ox, oy, oz, sat, geo, alert, eps_f, sigma, scr, pts, gp)


@jit(inline="always")
def _candidate_order(sat, axes, hx, hy, hz, eps_f, sigma):
    """The order in which :func:`poly_poly` tries the three axes of ``sat`` (best separation
    ``sigma``, d), and the band below ``sigma`` (d) within which each is a candidate.

    Candidate order: the better face axis, the other one, the edge axis; the edge axis first only
    if it beats both face axes by more than ``eps_f`` (hysteresis); a candidate whose axis is the
    previous step's normal ``(hx, hy, hz)`` goes first (temporal hysteresis). An axis is a
    candidate within ``eps_f`` of the best separation, or within ``_KEEP_BAND eps_f`` if it is the
    previous normal: one band would let an axis at its edge flicker in and out from step to step
    (the manifold's normal and type flipping at every step, its force with them), and a narrow
    loop between the two bands pumps a sliding grain (module docstring).

    Returns ``(o0, o1, o2, band_a, band_b, band_e)``: the axis kinds (``_AXIS_FACE_A``,
    ``_AXIS_FACE_B``, ``_AXIS_EDGE``) in order, and the bands of A's face axis, B's and the edge
    axis, d; ``axes``: the world face axes of the pair's
    :class:`~granpack.contact.separating_axes.WorldGeometry`.
    """
    sfa, kfa, sfb, kfb, se = sat.sfa, sat.kfa, sat.sfb, sat.kfb, sat.se
    first_face = _AXIS_FACE_A if sfa >= sfb else _AXIS_FACE_B
    second_face = _AXIS_FACE_B if sfa >= sfb else _AXIS_FACE_A
    if se > max(sfa, sfb) + eps_f:
        o0, o1, o2 = _AXIS_EDGE, first_face, second_face
    else:
        o0, o1, o2 = first_face, second_face, _AXIS_EDGE
    band_a = band_b = band_e = eps_f
    if hx != 0.0 or hy != 0.0 or hz != 0.0:
        ca = abs(hx * axes[kfa, 0] + hy * axes[kfa, 1] + hz * axes[kfa, 2])
        cb = abs(hx * axes[kfb, 0] + hy * axes[kfb, 1] + hz * axes[kfb, 2])
        ce = abs(hx * sat.ex + hy * sat.ey + hz * sat.ez)
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


@jit(inline="always")
def _face_axis_clip(face_of_a, a, b, ox, oy, oz, sat, geo, tab, alert, scr, pts, gp):
    """The face manifold of the best face axis of A (``face_of_a``) or of B in ``sat``: the
    incident face of the other body clipped against the reference face (:func:`_clip_face`), A
    at the origin and B at ``o`` (d); ``alert`` in d.

    Returns ``(count, gmin, nx, ny, nz)``: the points written to ``pts``, ``gp``, the smallest
    gap of the clipped polygon (d) and the normal from A to B.
    """
    if face_of_a:
        g = sat.gfa
        nx, ny, nz = g * geo.axes[sat.kfa, 0], g * geo.axes[sat.kfa, 1], g * geo.axes[sat.kfa, 2]
        cnt, gmin = _clip_face(geo, tab, a, b, 0.0, 0.0, 0.0, ox, oy, oz, nx, ny, nz, alert, scr, pts, gp)
    else:
        g = sat.gfb
        nx, ny, nz = g * geo.axes[sat.kfb, 0], g * geo.axes[sat.kfb, 1], g * geo.axes[sat.kfb, 2]
        # reference face on B, outward normal -n
        cnt, gmin = _clip_face(geo, tab, b, a, ox, oy, oz, 0.0, 0.0, 0.0, -nx, -ny, -nz, alert, scr, pts, gp)
    return cnt, gmin, nx, ny, nz


@jit(inline="always")
def _fallback_manifold(a, b, ox, oy, oz, sat, geo, alert, eps_f, sigma, scr, pts, gp):
    """The manifold of :func:`poly_poly` when no axis of ``sat`` gave an exact one: the exact
    closest points of a separated pair (GJK), else the deepest support point along the best axis
    (interpenetrating or touching), gap ``sigma`` (d). Returns ``(count, nx, ny, nz)``."""
    if sigma > 0.0:
        cnt, nx, ny, nz = _gjk_manifold(geo, a, b, ox, oy, oz, alert, eps_f, scr, pts, gp)
        if cnt >= 0:
            return cnt, nx, ny, nz
    # interpenetration (or touching) without an exact manifold: deepest support point, best axis
    if sat.se >= max(sat.sfa, sat.sfb):
        nx, ny, nz = sat.ex, sat.ey, sat.ez
        from_a = False
    elif sat.sfa >= sat.sfb:
        g, k = sat.gfa, sat.kfa
        nx, ny, nz = g * geo.axes[k, 0], g * geo.axes[k, 1], g * geo.axes[k, 2]
        from_a = False
    else:
        g, k = sat.gfb, sat.kfb
        nx, ny, nz = g * geo.axes[k, 0], g * geo.axes[k, 1], g * geo.axes[k, 2]
        from_a = True
    _deepest_point(geo, a, b, ox, oy, oz, nx, ny, nz, sigma, from_a, pts, gp)
    return 1, nx, ny, nz


@jit
def _sphere_poly(ra, b, ox, oy, oz, geo, tab, alert, scr, one, pts, gp):
    """Sphere A (radius ``ra``, at the origin) against polyhedron ``b`` (at ``o``), lengths in d;
    ``one``: a ``(1, 3)`` zero row, the sphere's centre as a one-point set.

    Returns ``(count, nx, ny, nz)`` as :func:`poly_poly` (one point at most: the midpoint of the
    closest points; centre inside B: the face of least depth gives the normal and the gap).
    """
    b0, b1 = geo.vertex_start[b], geo.vertex_start[b + 1]
    st, dist, px, py, pz, qx, qy, qz = gjk_distance(one, 0, 1, geo.vertices, b0, b1, ox, oy, oz, alert + ra, scr.gjk)
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
    fn = geo.normals
    f0 = tab.face_start[tab.kind[b]]
    best = math.inf
    fb0, fb1 = geo.face_start[b], geo.face_start[b + 1]
    fb = fb0
    for f in range(fb0, fb1):
        depth = tab.face_offsets[f0 + f - fb0] + fn[f, 0] * ox + fn[f, 1] * oy + fn[f, 2] * oz
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
def _poly_wall(i, zc, geo, alert, pts, gp):
    """Vertices of polyhedron ``i`` (centre height ``zc``, d) below ``alert`` (d); points relative to its centre.

    Each point lies midway between its vertex and the wall, gap the vertex height. Returns the
    count; ``pts`` must have at least as many rows as the polyhedron has vertices.
    """
    rv = geo.vertices
    cnt = 0
    for k in range(geo.vertex_start[i], geo.vertex_start[i + 1]):
        z = zc + rv[k, 2]
        if z < alert:
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = rv[k, 0], rv[k, 1], rv[k, 2] - 0.5 * z
            gp[cnt] = z
            cnt += 1
    return cnt


@jit(inline="always")
def _wall_points(i, zi, ri, sphere, geo, alert, pts, gp):
    """Points of body ``i`` (centre height ``zi``, circumscribed radius ``ri``, d; a sphere if
    ``sphere``) on the wall z = 0 with gaps up to ``alert`` (d), relative to its centre; returns
    their count (a sphere: its lowest point's midpoint with the wall)."""
    if sphere:
        g = zi - ri
        if g < alert:
            pts[0, 0], pts[0, 1], pts[0, 2] = 0.0, 0.0, 0.5 * g - zi
            gp[0] = g
            return 1
        return 0
    return _poly_wall(i, zi, geo, alert, pts, gp)


@jit(inline="always")
def _sphere_pair(i, j, ox, oy, oz, ri, rj, sphere_i, sphere_j, geo, tab, alert, scr, one, pts, gp):
    """Manifold of a pair with at least one sphere: candidate ``i`` (radius ``ri``) at ``o`` from
    antagonist ``j`` (``rj``), d, up to the gap ``alert`` (d). Two spheres: one point midway
    between their surfaces on the centre line (normal ``e_z`` for coincident centres); else
    :func:`_sphere_poly` or :func:`_poly_sphere`. Returns ``(count, nx, ny, nz)``."""
    if sphere_i and sphere_j:
        d = math.sqrt(ox * ox + oy * oy + oz * oz)
        g = d - ri - rj
        if g > alert:
            return 0, 0.0, 0.0, 0.0
        if d > 0.0:
            nx, ny, nz = ox / d, oy / d, oz / d
        else:
            nx, ny, nz = 0.0, 0.0, 1.0
        c = rj + 0.5 * g
        pts[0, 0], pts[0, 1], pts[0, 2] = c * nx, c * ny, c * nz
        gp[0] = g
        return 1, nx, ny, nz
    if sphere_j:
        return _sphere_poly(rj, i, ox, oy, oz, geo, tab, alert, scr, one, pts, gp)
    return _poly_sphere(j, ri, ox, oy, oz, geo, tab, alert, scr, one, pts, gp)


@jit(inline="always")
def _previous_normal(previous, pp, i, j):
    """The normal of pair ``(i, j)`` at the previous step, zero if it had none, walking the sorted
    :class:`PreviousNormals` from row ``pp`` (pairs are visited in ``(i, j)`` order). Returns
    ``(pp, hx, hy, hz)``, ``pp`` the walk's new row."""
    nprev = len(previous.body_i)
    while pp < nprev and (previous.body_i[pp] < i or (previous.body_i[pp] == i and previous.body_j[pp] < j)):
        pp += 1
    if pp < nprev and previous.body_i[pp] == i and previous.body_j[pp] == j:
        return pp, previous.normal[pp, 0], previous.normal[pp, 1], previous.normal[pp, 2]
    return pp, 0.0, 0.0, 0.0


@jit(inline="always")
def _append_manifold(out, m, npt, i, j, sx, sy, nx, ny, nz, cx, cy, cz, pts, gp, cnt, eps_pt, eps_f):
    """Write manifold ``m`` of bodies ``i``, ``j`` (shift ``(sx, sy, 0)``, normal ``n``) to the
    :class:`_Manifolds` ``out``, its ``cnt`` points ``pts`` relative to ``c`` (d) from point row
    ``npt`` on, after merging points closer than ``eps_pt`` (d); its type from the rank of the
    points with tolerance ``eps_f`` (d). Returns ``(m, npt)`` past what was written."""
    cnt = _merge_points(pts, gp, cnt, eps_pt)
    out.body_i[m], out.body_j[m] = i, j
    out.shift[m, 0], out.shift[m, 1], out.shift[m, 2] = sx, sy, 0.0
    out.normal[m, 0], out.normal[m, 1], out.normal[m, 2] = nx, ny, nz
    out.ctype[m] = manifold_type_nb(pts, cnt, nx, ny, nz, eps_f)
    for k in range(cnt):
        out.point[npt, 0], out.point[npt, 1], out.point[npt, 2] = cx + pts[k, 0], cy + pts[k, 1], cz + pts[k, 2]
        out.gap[npt] = gp[k]
        npt += 1
    m += 1
    out.point_start[m] = npt
    return m, npt


@jit
def _scratch(max_points):
    """The :class:`Scratch` of one narrow-phase call, for polyhedra of at most ``max_points``
    vertices and faces of at most ``(max_points - 1) / 2`` vertices."""
    gjk = GjkScratch(np.empty((4, 3)), np.empty(4, np.int64), np.empty(4, np.int64), np.empty(4), np.empty(4))
    return Scratch(gjk, np.empty(4, np.int64), np.empty((max_points, 3)), np.empty((max_points, 3)),
                   np.empty((3, 2 * max_points)), np.empty((3, 2 * max_points)), np.empty(2 * max_points))


@jit
def _general_tables(tab):
    """The :class:`~granpack.contact.separating_axes.GeneralTables` of the kinds of ``tab`` (a
    :class:`KindTables`), with their scratch, for the separating-axis test of polyhedra that are
    not both centrally symmetric; ``inradius[k]`` is the radius of the largest ball about the
    centre inside kind ``k`` (its smallest face offset, d; 0 for a sphere), which prunes the axes
    of every pair."""
    face_start, face_offsets, edge_start = tab.face_start, tab.face_offsets, tab.edge_start
    n_kinds = len(tab.radius)
    inradius = np.zeros(n_kinds)
    for k in range(n_kinds):
        if face_start[k + 1] > face_start[k]:
            inradius[k] = face_offsets[face_start[k]:face_start[k + 1]].min()
    max_edges = max(np.diff(edge_start).max(), 1)
    max_faces = max(np.diff(face_start).max(), 1)
    return GeneralTables(edge_start, tab.edge_faces, tab.edge_direction, tab.edge_arc, tab.axis_extent, inradius,
                         np.empty((2, max_faces)), np.empty((4, max_edges)), np.empty(max_edges, np.int64), tab.edges,
                         face_start, face_offsets)


@jit
def narrow_phase(position, geo, tab, symmetric, pairs, previous, lx, ly, alert, reach, eps_f, max_points, i0, i1):
    """Contact manifolds of the candidate pairs and wall pairs of the bodies ``i0 <= i < i1``.

    Rows are independent (a pair belongs to its row ``i``, the previous normals are looked up by
    ``(i, j)``), so disjoint row ranges may be computed by concurrent threads (the kernel releases
    the GIL) and their outputs concatenated in row order: the result is that of one call over all
    rows.

    Args:
        position: ``(N, 3)`` centres (x, y wrapped into the cell), d.
        geo: the :class:`~granpack.contact.separating_axes.WorldGeometry` of :func:`world_geometry`.
        tab: the :class:`KindTables` of the shape table and the particles' kinds.
        symmetric: the :class:`~granpack.contact.separating_axes.SymmetricTables` of the shape
            table: the faster separating-axis test of two centrally symmetric polyhedra
            (:func:`~granpack.contact.separating_axes._sat`).
        pairs: the :class:`CandidatePairs` (``j > i``); their ``axis`` codes are read and updated
            in rows ``i0:i1`` (see :func:`~granpack.contact.separating_axes._sat`).
        previous: the previous step's :class:`PreviousNormals`, for the temporal axis hysteresis
            of :func:`poly_poly`.
        lx, ly: periods, d.
        alert: alert distance, d: the largest gap reported.
        reach: ``(N,)`` per body, d: pair ``(i, j)`` reports gaps up to ``min(alert, reach_i + reach_j)``,
            the wall pair of ``i`` up to ``min(alert, 2 reach_i)`` (``alert / 2`` everywhere: the
            one alert distance for every pair).
        eps_f: feature band / rank tolerance, d.
        max_points: scratch rows, at least the largest vertex count and twice the largest face
            size plus one.
        i0, i1: the rows computed (``0, N`` for all).

    Returns:
        ``(body_i, body_j, shift, normal, ctype, point_start, point, gap, n_tested)``: the
        :class:`~granpack.contact.contacts.ContactSet` arrays, ordered by ``i`` then ``j`` (the
        wall, ``j = -1``, first), and the number of pairs whose bounding spheres overlap within
        ``alert`` (narrow-phase tests).
    """
    cap = pairs.start[i1] - pairs.start[i0] + (i1 - i0)
    out = _Manifolds(np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 3)), np.empty((cap, 3)),
                     np.empty(cap, np.int64), np.zeros(cap + 1, np.int64), np.empty((max_points * cap, 3)),
                     np.empty(max_points * cap))
    scr = _scratch(max_points)
    one = np.zeros((1, 3))
    pts = np.empty((max_points, 3))
    gp = np.empty(max_points)
    eps_pt = 1e-3 * eps_f
    gauss = _general_tables(tab)
    is_sphere, radius, inradius = tab.is_sphere, tab.radius, gauss.inradius
    m = 0
    npt = 0
    tested = 0
    pp = np.searchsorted(previous.body_i, i0)
    for i in range(i0, i1):
        ki = tab.kind[i]
        xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
        ri = radius[ki]
        aw = min(alert, 2.0 * reach[i])
        if zi - ri < aw:
            cnt = _wall_points(i, zi, ri, is_sphere[ki], geo, aw, pts, gp)
            if cnt > 0:
                m, npt = _append_manifold(out, m, npt, i, -1, 0.0, 0.0, 0.0, 0.0, 1.0, xi, yi, zi, pts, gp, cnt,
                                          eps_pt, eps_f)
        for q in range(pairs.start[i], pairs.start[i + 1]):
            j = pairs.partner[q]
            kj = tab.kind[j]
            dx = xi - position[j, 0]
            dy = yi - position[j, 1]
            sx = lx * math.floor(dx / lx + 0.5)
            sy = ly * math.floor(dy / ly + 0.5)
            ox, oy, oz = dx - sx, dy - sy, zi - position[j, 2]
            a = min(alert, reach[i] + reach[j])
            rr = ri + radius[kj] + a
            if ox * ox + oy * oy + oz * oz >= rr * rr:
                continue
            tested += 1
            if is_sphere[ki] or is_sphere[kj]:
                cnt, nx, ny, nz = _sphere_pair(i, j, ox, oy, oz, ri, radius[kj], is_sphere[ki], is_sphere[kj], geo,
                                               tab, a, scr, one, pts, gp)
            else:
                sat = _sat(geo, j, i, kj, ki, ox, oy, oz, symmetric, gauss, a, inradius[kj] + inradius[ki],
                           _KEEP_BAND * eps_f, scr.vertex_block, scr.half_block, pairs.axis[q])
                pairs.axis[q] = sat.axis
                if sat.far:
                    continue
                pp, hx, hy, hz = _previous_normal(previous, pp, i, j)
                cnt, nx, ny, nz = poly_poly(j, i, ox, oy, oz, hx, hy, hz, sat, geo, tab, a, eps_f, scr, pts, gp)
            if cnt == 0:
                continue
            m, npt = _append_manifold(out, m, npt, i, j, sx, sy, nx, ny, nz, position[j, 0] + sx, position[j, 1] + sy,
                                      position[j, 2], pts, gp, cnt, eps_pt, eps_f)
    return (out.body_i[:m].copy(), out.body_j[:m].copy(), out.shift[:m].copy(), out.normal[:m].copy(),
            out.ctype[:m].copy(), out.point_start[:m + 1].copy(), out.point[:npt].copy(), out.gap[:npt].copy(), tested)

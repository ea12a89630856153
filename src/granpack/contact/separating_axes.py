"""Separating-axis test of two convex polyhedra (:func:`_sat`) and the world-frame hull tables it reads.

Axes: both bodies' face normals and the cross products of their edge directions (Ericson, *Real-Time
Collision Detection*, 2005, §5.2.1); a pair is apart when its projections on one axis do not overlap.
It runs first because most candidate pairs end at the first axis that separates them by more than the
alert distance; the best axes of the others are where :mod:`granpack.contact.manifold` builds the contact.

Pruning. A contains the ball of radius ``rho_A`` (its smallest face offset) about its centre, B
likewise, so along an edge-edge axis ``u`` (B at ``o`` from A)

.. math:: s(u) \\le |u \\cdot o| - \\rho_A - \\rho_B ,

and an axis whose bound is below the best separation found so far minus ``margin`` (d, the widest
hysteresis band) can neither separate the pair nor be a manifold candidate, so its projections are
skipped. Whole edges of two general polyhedra are pruned before their pairs: for ``u`` on the arc
of an edge of A (joining the normals of its two faces on the Gauss map), :math:`s(u) \\le u \\cdot
(o - p) - \\rho_B` with ``p`` a point of the edge, and :math:`n_k \\cdot (o - p) = n_k \\cdot o -
d_k` with ``d_k`` the offset of face ``k`` (``p`` lies on both faces), so :func:`_arc_max` of those
two values bounds the edge's every axis (B's edges likewise, along ``-m`` of their arc, less
``rho_A``); a cheaper bound, the larger value times the secant of half the arc (no square root),
rejects most edges first.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from granpack._numba import jit, prange
from granpack.rotations import quat_to_matrix_nb

__all__ = ["GeneralTables", "SatResult", "SymmetricTables", "WorldGeometry", "world_geometry"]

#: The world-frame hull tables of every polyhedron of one configuration (:func:`world_geometry`):
#: particle ``p`` owns rows ``vertex_start[p]:vertex_start[p + 1]`` of ``vertices``, and likewise
#: for the other three tables, in the row order of its kind in the
#: :class:`~granpack.shapes.ShapeTable` (a sphere owns no rows).
WorldGeometry = namedtuple("WorldGeometry", [
    "vertex_start",  # (N+1,) int64: CSR offsets of each particle's rows of vertices
    "face_start",  # (N+1,) int64: CSR offsets of each particle's rows of normals
    "axis_start",  # (N+1,) int64: CSR offsets of each particle's rows of axes
    "direction_start",  # (N+1,) int64: CSR offsets of each particle's rows of directions
    "vertices",  # (NV, 3) float64: vertex offsets from the particle's centre, x - x_p, world frame, d
    "normals",  # (NF, 3) float64: unit outward face normals, world frame
    "axes",  # (NA, 3) float64: unit face axes (one per set of parallel faces), world frame
    "directions",  # (ND, 3) float64: unit edge directions (one per set of parallel edges), world frame
])

#: The tables of the separating-axis test of two centrally symmetric polyhedra (:func:`_sat`),
#: per kind of the :class:`~granpack.shapes.ShapeTable`.
SymmetricTables = namedtuple("SymmetricTables", [
    "half_start",  # (K+1,) int64: CSR over kinds of half; a kind's block is empty unless it is centrally symmetric
    "half",  # (H,) int64: local index of one vertex of each antipodal pair (v, -v)
    "axis_start",  # (K+1,) int64: each kind's rows of axis_support (the shape table's face-axis rows)
    "axis_support",  # (NA,) float64: support max_v |a . v| of a kind along its own face axis a, d
])

#: The tables and scratch of the separating-axis test of polyhedra that are not both centrally
#: symmetric (:func:`_sat`, :func:`_face_axes`, :func:`_minkowski_edge_axes`), built by
#: :func:`~granpack.contact.narrowphase._general_tables`; rows of the shape table, local indices
#: within a kind.
GeneralTables = namedtuple("GeneralTables", [
    "edge_start",  # (K+1,) int64: CSR over kinds of the edge rows
    "edge_faces",  # (NE, 2) int64: local indices of the two faces of each edge
    "edge_direction",  # (NE,) int64: local index of each edge's direction among its kind's edge directions
    "edge_arc",  # (NE, 2) float64: cosine between the normals of an edge's two faces, secant of half their angle
    "axis_extent",  # (NA, 2) float64: least and largest a . v over a kind's vertices v along its face axis a, d
    "inradius",  # (K,) float64: radius of the largest ball about a kind's centre inside it (smallest face offset), d
    "face_bound",  # (2, >= most faces) float64 scratch: per face of A (row 0), of B (row 1), n . o - offset, d
    "edge_bound",  # (4, >= most edges) float64 scratch: per edge of B, its arc's pole (rows 0-2), bound (row 3), d
    "selected_edges",  # (>= most edges,) int64 scratch: the edges of B kept by their bound
    "edges",  # (NE, 2) int64: local indices of the two vertices of each edge
    "face_start",  # (K+1,) int64: CSR over kinds of the face rows
    "face_offsets",  # (NF,) float64: distance of each face's plane from its kind's centre, d
])

#: The result of :func:`_sat`. ``far``: some axis separates by more than the alert distance;
#: ``axis``: its code (-1 if none, or the centre line). Otherwise the best face axis of A
#: (separation ``sfa``, d; row ``kfa`` of the world face axes; side ``gfa`` = +-1, B on the
#: ``gfa * axis`` side), of B (``sfb``, ``kfb``, ``gfb``), and the best edge-edge axis (``se``, d,
#: ``-inf`` when every edge pair is parallel; local direction indices ``ie`` on A and ``je`` on
#: B; the oriented unit axis ``(ex, ey, ez)`` from A to B).
SatResult = namedtuple("SatResult", ["far", "sfa", "kfa", "gfa", "sfb", "kfb", "gfb", "se", "ie", "je", "ex", "ey",
                                     "ez", "axis"])

#: The ``axis`` of a :class:`SatResult` that :func:`_sat` leaves undecided (bodies not both
#: centrally symmetric): :func:`_general_axes` finishes the test.
GENERAL = -2


@jit(parallel=True)
def world_geometry(position, quaternion, kind, vertex_start, vertices, face_start, face_normals, axis_start, face_axes,
                   direction_start, edge_directions, chunks=1):
    """Rotate every polyhedron's body-frame geometry into the world frame (relative to its centre).

    Args:
        position: ``(N, 3)`` centres, d (only its length is used).
        quaternion: ``(N, 4)`` unit quaternions ``(w, x, y, z)``.
        kind: ``(N,)`` kind index into the shape table.
        vertex_start, vertices, face_start, face_normals, axis_start, face_axes, direction_start, edge_directions: the
            :class:`~granpack.shapes.ShapeTable` arrays of the same names.
        chunks: consecutive ranges of particles rotated at once (threads); the result does not
            depend on it.

    Returns:
        a :class:`WorldGeometry`.
    """
    n = len(kind)
    pv = np.zeros(n + 1, np.int64)
    pf = np.zeros(n + 1, np.int64)
    pa = np.zeros(n + 1, np.int64)
    pd = np.zeros(n + 1, np.int64)
    for p in range(n):
        k = kind[p]
        pv[p + 1] = pv[p] + vertex_start[k + 1] - vertex_start[k]
        pf[p + 1] = pf[p] + face_start[k + 1] - face_start[k]
        pa[p + 1] = pa[p] + axis_start[k + 1] - axis_start[k]
        pd[p + 1] = pd[p] + direction_start[k + 1] - direction_start[k]
    rv = np.empty((pv[n], 3))
    fn = np.empty((pf[n], 3))
    ax = np.empty((pa[n], 3))
    dr = np.empty((pd[n], 3))
    for c in prange(chunks):
        for p in range(n * c // chunks, n * (c + 1) // chunks):
            if pv[p + 1] == pv[p]:
                continue
            k = kind[p]
            R = quat_to_matrix_nb(quaternion[p])
            _rotate_rows(R, vertices, vertex_start[k], vertex_start[k + 1], rv, pv[p])
            _rotate_rows(R, face_normals, face_start[k], face_start[k + 1], fn, pf[p])
            _rotate_rows(R, face_axes, axis_start[k], axis_start[k + 1], ax, pa[p])
            _rotate_rows(R, edge_directions, direction_start[k], direction_start[k + 1], dr, pd[p])
    return WorldGeometry(pv, pf, pa, pd, rv, fn, ax, dr)


@jit
def _rotate_rows(R, src, s0, s1, dst, d0):
    """Write ``R @ src[s0 + r]`` to ``dst[d0 + r]`` for ``r < s1 - s0`` (rows of 3; any unit)."""
    for r in range(s1 - s0):
        x, y, z = src[s0 + r, 0], src[s0 + r, 1], src[s0 + r, 2]
        dst[d0 + r, 0] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
        dst[d0 + r, 1] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
        dst[d0 + r, 2] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z


# ---------------------------------------------------------------------------------------------
# separating-axis test


@jit
def _interval(rv, v0, v1, ox, oy, oz, ux, uy, uz):
    """Min and max of ``u . (o + rv[k])`` over rows ``k`` in ``[v0, v1)``: the extent of a body
    (vertex offsets ``rv``, centre ``o``, d) along the unit vector ``u``, d."""
    lo = math.inf
    hi = -math.inf
    for k in range(v0, v1):
        d = ux * (ox + rv[k, 0]) + uy * (oy + rv[k, 1]) + uz * (oz + rv[k, 2])
        lo = min(lo, d)
        hi = max(hi, d)
    return lo, hi


@jit
def _separation(X, na, nb, ux, uy, uz):
    """Signed separation along the line of ``u`` of A (columns ``0:na`` of ``X``) and B (columns
    ``na:na+nb``), vertex coordinates stored coordinate-major (``X[c, k]``) in A's frame.

    Returns ``(s, sign)``: ``s`` (d, > 0 apart along ``u``) = the larger of ``min_B - max_A`` (B
    on the +u side, sign +1) and ``min_A - max_B`` (sign -1); ``u`` a unit vector.
    """
    loa = math.inf
    hia = -math.inf
    for k in range(na):
        d = ux * X[0, k] + uy * X[1, k] + uz * X[2, k]
        loa = min(loa, d)
        hia = max(hia, d)
    lob = math.inf
    hib = -math.inf
    for k in range(na, na + nb):
        d = ux * X[0, k] + uy * X[1, k] + uz * X[2, k]
        lob = min(lob, d)
        hib = max(hib, d)
    s1 = lob - hia
    s2 = loa - hib
    if s1 >= s2:
        return s1, 1.0
    return s2, -1.0


@jit(inline="always")
def _own_axis_separation(X, c0, c1, ux, uy, uz, lo, hi, own_is_a):
    """Signed separation along one body's own face axis ``u`` of :func:`_separation`, from that
    body's interval ``[lo, hi]`` along ``u`` (d, in A's frame: a constant of its shape plus its
    centre's projection) and the other body's vertices, columns ``c0:c1`` of ``X``: half the
    projections of :func:`_separation`. ``own_is_a``: the axis is A's (the other body is B)."""
    lo_o = math.inf
    hi_o = -math.inf
    for k in range(c0, c1):
        d = ux * X[0, k] + uy * X[1, k] + uz * X[2, k]
        lo_o = min(lo_o, d)
        hi_o = max(hi_o, d)
    if own_is_a:
        s1, s2 = lo_o - hi, lo - hi_o
    else:
        s1, s2 = lo - hi_o, lo_o - hi
    if s1 >= s2:
        return s1, 1.0
    return s2, -1.0


@jit(inline="always")
def _half_support(Y, k0, k1, ux, uy, uz):
    """Support ``h(u) = max_k |u . Y[:, k]|`` of a centrally symmetric body about its centre, from
    one vertex of each antipodal pair (columns ``k0:k1``, offsets from the centre ``c``, d): its
    projection on the unit vector ``u`` is ``c . u +- h``, d."""
    h = 0.0
    for k in range(k0, k1):
        h = max(h, abs(ux * Y[0, k] + uy * Y[1, k] + uz * Y[2, k]))
    return h


@jit
def _signed_gap(ox, oy, oz, ux, uy, uz, ha, hb):
    """Separation ``|u . o| - h_A - h_B`` (d) of two symmetric bodies along the unit vector ``u``,
    centres ``0`` and ``o`` and supports ``ha``, ``hb`` (d), and the side of B (+-1)."""
    c = ux * ox + uy * oy + uz * oz
    if c >= 0.0:
        return c - ha - hb, 1.0
    return -c - ha - hb, -1.0


@jit(inline="always")
def _separated(axis):
    """The :class:`SatResult` of a pair that the axis of code ``axis`` separates by more than the
    alert distance (the other fields unset)."""
    return SatResult(True, 0.0, -1, 0.0, 0.0, -1, 0.0, 0.0, -1, -1, 0.0, 0.0, 0.0, axis)


@jit(inline="always")
def _sat(geo, a, b, ka, kb, ox, oy, oz, symmetric, alert, rin, margin, X, Y, cached):
    """Separating-axis test between polyhedra ``a`` (A, centred) and ``b`` (B, offset ``o``, d).

    ``geo`` is the :class:`WorldGeometry` of :func:`world_geometry`, ``ka``, ``kb`` the two kinds.
    The vertices of both bodies are gathered into the scratch ``X`` (``(3, >= nA + nB)``, B's
    shifted by ``o``), so every axis reads them from one small contiguous block. ``symmetric`` is
    a :class:`SymmetricTables`: when both bodies are centrally symmetric (kinds with a non-empty
    block of ``half``) the separation along ``u`` is ``|u . o| - h_A - h_B`` with the supports
    ``h`` read from half the vertices in ``Y`` (:func:`_half_support`), or, along a body's own
    face axes, from ``axis_support`` (d), a constant of the shape; ``X`` is then filled only for
    a pair that is not separated. The two paths are written out at each axis on purpose
    (docs/design-notes.md, "Separating-axis test: speed").

    Axes: both bodies' face axes, then the edge-edge axes: every pair of edge directions of two
    symmetric bodies (:func:`_direction_pair_axes`). A pair of bodies that are not both
    symmetric, once the cheap tries below have not separated it, is returned undecided (``axis``
    :data:`GENERAL`) with its vertex block in ``X``, for :func:`_general_axes` to finish: that
    test needs the :class:`GeneralTables`, and a bundle handed to this inlined function would be
    increfed and decrefed, every array of it, at every pair of the narrow phase. Either way the
    best separation of an overlapping pair is the largest over all directions, minus the
    penetration depth; that of a separated pair is a lower bound of the distance (the manifold's
    gaps are exact: :mod:`granpack.contact.narrowphase`).

    Edge-edge axes are pruned by the bound of the module docstring (``rin = rho_A + rho_B``, d;
    ``margin``, d, the widest hysteresis band, ``_KEEP_BAND eps_f`` of
    :mod:`granpack.contact.narrowphase`; :func:`_unit_cross`).

    ``cached`` is the axis that separated the pair at the previous call (code below, -1 if
    none): it is tried first, and a pair it still separates by more than ``alert`` (d) costs one
    axis (the separating axis of a pair that stays apart changes rarely between steps).

    Returns:
        a :class:`SatResult`. Axis codes: ``k`` for A's face axis ``axis_start[a] + k``, ``nfa +
        k`` for B's ``axis_start[b] + k``, ``nfa + nfb + i ndb + j`` for the edge-direction pair
        ``(direction_start[a] + i, direction_start[b] + j)`` (rows of ``geo``), -1 for the centre
        line (``nfa``, ``nfb`` the face-axis counts, ``ndb`` B's edge-direction count). A pair that
        is not separated has ``axis`` -1, an undecided one :data:`GENERAL`.
    """
    vertex_start, axis_start, rv, ax = geo.vertex_start, geo.axis_start, geo.vertices, geo.axes
    direction_start, dr = geo.direction_start, geo.directions
    half_start, half, kind_axis_start, support = (symmetric.half_start, symmetric.half, symmetric.axis_start,
                                                  symmetric.axis_support)
    a0, a1, b0, b1 = vertex_start[a], vertex_start[a + 1], vertex_start[b], vertex_start[b + 1]
    aa0, aa1, ab0, ab1 = axis_start[a], axis_start[a + 1], axis_start[b], axis_start[b + 1]
    inf = math.inf
    na = a1 - a0
    nb = b1 - b0
    ha0, hb0 = half_start[ka], half_start[kb]
    nha = half_start[ka + 1] - ha0
    nhb = half_start[kb + 1] - hb0
    sa0, sb0 = kind_axis_start[ka], kind_axis_start[kb]
    sym = nha > 0 and nhb > 0
    if sym:
        for k in range(nha):
            r = a0 + half[ha0 + k]
            Y[0, k], Y[1, k], Y[2, k] = rv[r, 0], rv[r, 1], rv[r, 2]
        for k in range(nhb):
            r = b0 + half[hb0 + k]
            Y[0, nha + k], Y[1, nha + k], Y[2, nha + k] = rv[r, 0], rv[r, 1], rv[r, 2]
    else:
        _gather(rv, a0, a1, b0, b1, ox, oy, oz, X)
    nfa = aa1 - aa0
    nfb = ab1 - ab0
    da0, da1, db0, db1 = direction_start[a], direction_start[a + 1], direction_start[b], direction_start[b + 1]
    # cheap first tries: the cached axis, then the centre-to-centre direction
    for attempt in range(2):
        if attempt == 0:
            if cached < 0:
                continue
            ux, uy, uz = _axis_of_code(ax, dr, aa0, ab0, da0, db0, db1 - db0, cached, nfa, nfb)
        else:
            dd = math.sqrt(ox * ox + oy * oy + oz * oz)
            if dd == 0.0:
                continue
            ux, uy, uz = ox / dd, oy / dd, oz / dd
        if sym:
            s, _ = _signed_gap(ox, oy, oz, ux, uy, uz, _half_support(Y, 0, nha, ux, uy, uz),
                               _half_support(Y, nha, nha + nhb, ux, uy, uz))
        else:
            s, _ = _separation(X, na, nb, ux, uy, uz)
        if s > alert:
            return _separated(cached if attempt == 0 else -1)
    if not sym:
        return SatResult(False, -inf, -1, 1.0, -inf, -1, 1.0, -inf, -1, -1, 0.0, 0.0, 0.0, GENERAL)
    sfa, kfa, gfa = -inf, -1, 1.0
    for k in range(aa0, aa1):
        s, g = _signed_gap(ox, oy, oz, ax[k, 0], ax[k, 1], ax[k, 2], support[sa0 + k - aa0],
                           _half_support(Y, nha, nha + nhb, ax[k, 0], ax[k, 1], ax[k, 2]))
        if s > alert:
            return _separated(k - aa0)
        if s > sfa:
            sfa, kfa, gfa = s, k, g
    sfb, kfb, gfb = -inf, -1, 1.0
    for k in range(ab0, ab1):
        s, g = _signed_gap(ox, oy, oz, ax[k, 0], ax[k, 1], ax[k, 2],
                           _half_support(Y, 0, nha, ax[k, 0], ax[k, 1], ax[k, 2]), support[sb0 + k - ab0])
        if s > alert:
            return _separated(nfa + k - ab0)
        if s > sfb:
            sfb, kfb, gfb = s, k, g
    far, se, ie, je, ex, ey, ez, code = _direction_pair_axes(dr, da0, da1, db0, db1, ox, oy, oz, Y, nha, nhb, alert,
                                                             max(sfa, sfb), margin, rin)
    if far:
        return _separated(nfa + nfb + code)
    _gather(rv, a0, a1, b0, b1, ox, oy, oz, X)
    return SatResult(False, sfa, kfa, gfa, sfb, kfb, gfb, se, ie, je, ex, ey, ez, -1)


@jit
def _general_axes(geo, a, b, ka, kb, ox, oy, oz, gauss, kind_axis_start, alert, rin, margin, X):
    """The separating-axis test of two bodies that are not both centrally symmetric, for a pair
    that :func:`_sat` (same arguments, ``kind_axis_start`` that of its ``symmetric``) left
    :data:`GENERAL` with its vertex block in ``X``: both bodies' face axes (:func:`_face_axes`),
    then the pairs of edges that make a face of the Minkowski difference
    (:func:`_minkowski_edge_axes`, ``gauss`` its :class:`GeneralTables`). Compiled apart, not
    inlined, so that only the pairs that need ``gauss`` are handed it. Returns a
    :class:`SatResult` as :func:`_sat`."""
    vertex_start, axis_start, ax = geo.vertex_start, geo.axis_start, geo.axes
    na, nb = vertex_start[a + 1] - vertex_start[a], vertex_start[b + 1] - vertex_start[b]
    aa0, aa1, ab0, ab1 = axis_start[a], axis_start[a + 1], axis_start[b], axis_start[b + 1]
    nfa, nfb = aa1 - aa0, ab1 - ab0
    sa0, sb0 = kind_axis_start[ka], kind_axis_start[kb]
    extent, inradius = gauss.axis_extent, gauss.inradius
    far, sfa, kfa, gfa = _face_axes(X, na, nb, ax, aa0, aa1, ox, oy, oz, extent, sa0, inradius[kb], alert, True)
    if far:
        return _separated(kfa - aa0)
    far, sfb, kfb, gfb = _face_axes(X, na, nb, ax, ab0, ab1, -ox, -oy, -oz, extent, sb0, inradius[ka], alert, False)
    if far:
        return _separated(nfa + kfb - ab0)
    far, se, ie, je, ex, ey, ez, code = _minkowski_edge_axes(geo, a, b, ka, kb, ox, oy, oz, gauss, X, na, nb, alert,
                                                             max(sfa, sfb), margin, rin)
    if far:
        return _separated(nfa + nfb + code)
    return SatResult(False, sfa, kfa, gfa, sfb, kfb, gfb, se, ie, je, ex, ey, ez, -1)


@jit(inline="always")
def _arc_max(a1, a2, c, slack):
    """Upper bound of ``u . o`` over the arc of unit vectors ``u`` from ``n1`` to ``n2`` (a great
    circle's arc shorter than a half-turn, an edge's on the Gauss map), ``o`` any vector, from
    :math:`a_k = n_k \\cdot o` and :math:`c = n_1 \\cdot n_2`.

    The projection of ``o`` on the arc's plane points inside the arc iff
    :math:`a_2 - c a_1 \\ge 0` and :math:`a_1 - c a_2 \\ge 0`; the largest value is then its
    length, :math:`\\sqrt{(a_1^2 + a_2^2 - 2 c a_1 a_2) / (1 - c^2)}`, otherwise
    :math:`\\max(a_1, a_2)`; raised by ``slack`` (d, the caller's :math:`10^{-9} |o|`, for the
    round-off of ``c`` and ``a``). An arc with :math:`1 - c^2 < 10^{-6}` takes the coarser
    :math:`\\max(a_1, a_2) / \\cos(\\theta / 2)`, :math:`\\cos(\\theta/2) = \\sqrt{(1 + c) / 2}`
    (a point of the arc is :math:`(\\sin(\\theta - \\varphi) n_1 + \\sin\\varphi\\, n_2) / \\sin\\theta`,
    whose weights sum to :math:`\\cos(\\varphi - \\theta/2) / \\cos(\\theta/2) \\in [1, 1 / \\cos(\\theta/2)]`),
    or :math:`\\max(a_1, a_2)` when that is negative.
    """
    den = 1.0 - c * c
    top = max(a1, a2)
    if den < 1e-6:
        return (top / math.sqrt(0.5 * (1.0 + c)) if top > 0.0 else top) + slack
    if a2 - c * a1 >= 0.0 and a1 - c * a2 >= 0.0:
        return math.sqrt(max(a1 * a1 + a2 * a2 - 2.0 * c * a1 * a2, 0.0) / den) + slack
    return top + slack


@jit(inline="always")
def _face_axes(X, na, nb, ax, k0, k1, dx, dy, dz, extent, e0, rho, alert, own_is_a):
    """Best of one body P's face axes (world rows ``k0:k1`` of ``ax``) for the vertex block ``X``
    of :func:`_sat`; the other body Q is at ``d`` from P (d).

    P spans ``[lo, hi]`` along its axis ``a`` about its centre (``extent[e0 + k - k0]``, d, a
    constant of the shape) and Q contains the ball of radius ``rho`` (d) about its centre, so the
    separation along ``a`` is at most

    .. math:: \\max(a \\cdot d - hi,\\; lo - a \\cdot d) - \\rho ;

    an axis whose bound is below the best separation found so far (less 1e-12 d) is not
    projected on, and the axis of largest bound is tried first. The result is that of projecting
    on every axis in row order: among equal separations the first row is kept.

    Returns ``(far, s, k, g)``: ``far`` when axis ``k`` separates by more than ``alert`` (d);
    otherwise the best separation ``s`` (d), its row ``k`` and the side ``g = +-1`` of B.
    """
    first, top = k0, -math.inf
    for k in range(k0, k1):
        ad = ax[k, 0] * dx + ax[k, 1] * dy + ax[k, 2] * dz
        bound = max(ad - extent[e0 + k - k0, 1], extent[e0 + k - k0, 0] - ad)
        if bound > top:
            first, top = k, bound
    sf, kf, gf = -math.inf, -1, 1.0
    for r in range(k0 - 1, k1):
        k = first if r < k0 else r
        if r >= k0:
            if k == first:
                continue
            ad = ax[k, 0] * dx + ax[k, 1] * dy + ax[k, 2] * dz
            if max(ad - extent[e0 + k - k0, 1], extent[e0 + k - k0, 0] - ad) - rho < sf - 1e-12:
                continue
        # P's interval along its own axis is a constant of its shape about its centre, which is
        # A's origin or B's offset o = -d
        if own_is_a:
            s, g = _own_axis_separation(X, na, na + nb, ax[k, 0], ax[k, 1], ax[k, 2], extent[e0 + k - k0, 0],
                                        extent[e0 + k - k0, 1], True)
        else:
            ad = -(ax[k, 0] * dx + ax[k, 1] * dy + ax[k, 2] * dz)
            s, g = _own_axis_separation(X, 0, na, ax[k, 0], ax[k, 1], ax[k, 2], ad + extent[e0 + k - k0, 0],
                                        ad + extent[e0 + k - k0, 1], False)
        if s > alert:
            return True, s, k, g
        if s > sf or (s == sf and k < kf):
            sf, kf, gf = s, k, g
    return False, sf, kf, gf


@jit(inline="always")
def _axis_of_code(ax, dr, aa0, ab0, da0, db0, ndb, code, nfa, nfb):
    """World unit axis of the axis code ``code >= 0`` of :func:`_sat` for a pair whose face axes
    are the rows ``aa0:aa0 + nfa`` (A) and ``ab0:ab0 + nfb`` (B) of ``ax`` and edge directions the
    rows from ``da0`` (A) and ``db0:db0 + ndb`` (B) of ``dr``: a face axis, or the normalised
    cross product ``c`` of the two edge directions (``c |c|^2``, a vector too short to separate
    anything, when they have turned parallel, ``|c|^2 <= 1e-12``). Arrays and row bounds, not the
    :class:`WorldGeometry`: an inlined helper increfs and decrefs every array it is handed, at
    each pair."""
    if code < nfa + nfb:
        r = aa0 + code if code < nfa else ab0 + code - nfa
        return ax[r, 0], ax[r, 1], ax[r, 2]
    i = da0 + (code - nfa - nfb) // ndb
    j = db0 + (code - nfa - nfb) % ndb
    cx = dr[i, 1] * dr[j, 2] - dr[i, 2] * dr[j, 1]
    cy = dr[i, 2] * dr[j, 0] - dr[i, 0] * dr[j, 2]
    cz = dr[i, 0] * dr[j, 1] - dr[i, 1] * dr[j, 0]
    c = cx * cx + cy * cy + cz * cz
    if c > 1e-12:  # the two edges may have turned parallel since
        c = 1.0 / math.sqrt(c)
    return cx * c, cy * c, cz * c


@jit(inline="always")
def _gather(rv, a0, a1, b0, b1, ox, oy, oz, X):
    """Vertex block of a pair, coordinate-major: ``X[:, 0:nA]`` A's offsets, then B's plus ``o``."""
    na = a1 - a0
    for k in range(na):
        X[0, k], X[1, k], X[2, k] = rv[a0 + k, 0], rv[a0 + k, 1], rv[a0 + k, 2]
    for k in range(b1 - b0):
        X[0, na + k], X[1, na + k], X[2, na + k] = ox + rv[b0 + k, 0], oy + rv[b0 + k, 1], oz + rv[b0 + k, 2]


@jit(inline="always")
def _edge_cross_offset(dr, j, ox, oy, oz):
    """:math:`w = e_j \\times o` for :func:`_unit_cross`, ``e_j = dr[j]`` (unit), ``o`` in d."""
    return dr[j, 1] * oz - dr[j, 2] * oy, dr[j, 2] * ox - dr[j, 0] * oz, dr[j, 0] * oy - dr[j, 1] * ox


@jit(inline="always")
def _unit_cross(dr, i, j, wx, wy, wz, t):
    """The unit axis ``c / |c|``, ``c = e_i x e_j``, of the world edge directions ``dr[i]``,
    ``dr[j]``, or ``ok`` False when the axis is not worth a projection: the directions are
    parallel (``|c|^2 < 1e-12``), or ``t > 0`` (d) and :math:`(c \\cdot o)^2 < t^2 |c|^2`, i.e. the
    bound :math:`|u \\cdot o|` on the separation plus ``rho_A + rho_B`` (see :func:`_sat`) is
    below ``t``. Computed as :math:`c \\cdot o = e_i \\cdot w` with ``w`` :math:`= e_j \\times o`
    (d; the caller's, formed once for every ``i`` it pairs with ``j``, by :func:`_edge_cross_offset`),
    :math:`|c|^2 = 1 - (e_i \\cdot e_j)^2`, so that a pruned axis is never formed.

    Returns ``(ok, ux, uy, uz)``.
    """
    cos = dr[i, 0] * dr[j, 0] + dr[i, 1] * dr[j, 1] + dr[i, 2] * dr[j, 2]
    c2 = 1.0 - cos * cos
    if c2 < 1e-12:
        return False, 0.0, 0.0, 0.0
    co = dr[i, 0] * wx + dr[i, 1] * wy + dr[i, 2] * wz
    if t > 0.0 and co * co < t * t * c2:
        return False, 0.0, 0.0, 0.0
    cx = dr[i, 1] * dr[j, 2] - dr[i, 2] * dr[j, 1]
    cy = dr[i, 2] * dr[j, 0] - dr[i, 0] * dr[j, 2]
    cz = dr[i, 0] * dr[j, 1] - dr[i, 1] * dr[j, 0]
    c = 1.0 / math.sqrt(cx * cx + cy * cy + cz * cz)
    return True, cx * c, cy * c, cz * c


@jit(inline="always")
def _direction_pair_axes(dr, da0, da1, db0, db1, ox, oy, oz, Y, nha, nhb, alert, best, margin, rin):
    """Edge-edge axes of two centrally symmetric bodies: every pair of their edge directions, the
    rows ``da0:da1`` (A) and ``db0:db1`` (B) of ``dr``.

    Each has 3 to 6 directions (pinacoids: 6), so trying every pair costs less than finding the
    pairs that are faces of the Minkowski difference. ``Y`` holds the half vertices of
    :func:`_sat`. An axis whose bound (:func:`_unit_cross`) is below ``t = max(best, se) - margin
    + rin - 1e-12`` (d; ``best`` the best face separation, ``se`` the best edge separation found
    so far, ``margin`` and ``rin`` those of :func:`_sat`) is skipped.

    Returns ``(far, se, ie, je, ex, ey, ez, code)`` as :func:`_minkowski_edge_axes`.
    """
    ndb = db1 - db0
    se, ie, je, ex, ey, ez = -math.inf, -1, -1, 0.0, 0.0, 0.0
    t = best - margin + rin - 1e-12
    for j in range(db0, db1):
        wx, wy, wz = _edge_cross_offset(dr, j, ox, oy, oz)
        for i in range(da0, da1):
            ok, cx, cy, cz = _unit_cross(dr, i, j, wx, wy, wz, t)
            if not ok:
                continue
            s, g = _signed_gap(ox, oy, oz, cx, cy, cz, _half_support(Y, 0, nha, cx, cy, cz),
                               _half_support(Y, nha, nha + nhb, cx, cy, cz))
            if s > alert:
                return True, s, i - da0, j - db0, cx, cy, cz, (i - da0) * ndb + j - db0
            if s > se:
                se, ie, je, ex, ey, ez = s, i - da0, j - db0, g * cx, g * cy, g * cz
                t = max(best, se) - margin + rin - 1e-12
    return False, se, ie, je, ex, ey, ez, -1


@jit(inline="always")
def _minkowski_edge_axes(geo, a, b, ka, kb, ox, oy, oz, gauss, X, na, nb, alert, best, margin, rin):
    """Edge-edge axes of two polyhedra: the pairs of edges whose cross product is the normal of a
    face of the Minkowski difference ``A - B`` (Gregorius, "The Separating Axis Test between
    Convex Polyhedra", GDC 2013).

    The separation ``s(u)`` along every unit vector is at most the largest over the face normals
    of ``A - B``: A's face normals, B's, and the cross products of an edge of A and an edge of B
    whose arcs on the Gauss map cross, A's arc joining the normals ``n1``, ``n2`` of the edge's two
    faces, B's joining ``-m1``, ``-m2`` (a vertex of ``A - B`` is a vertex of A minus one of B,
    and ``s`` along a direction inside its normal cone is at most its largest value at the
    cone's corners when the bodies overlap). The arcs cross iff, with ``c = -m1``, ``d = -m2``,
    ``p = n2 x n1``, ``q = d x c``:

    .. math:: (c \\cdot p)(d \\cdot p) < 0, \\quad (n_1 \\cdot q)(n_2 \\cdot q) < 0, \\quad
              (c \\cdot p)(n_2 \\cdot q) > 0

    (``c``, ``d`` on either side of A's great circle, ``n1``, ``n2`` of B's, both arcs in one
    hemisphere): four dot products per pair of edges, so only the few crossing pairs are
    measured. The axis ``u`` of a crossing pair, the cross product of the two edges' direction
    rows turned towards ``n1 + n2``, lies on both arcs: A's support along ``u`` is its edge (a
    point ``p`` of it) and B's along ``-u`` is its edge (``q``), so the separation is exact from
    those two points, :math:`s(u) = u \\cdot (o + q - p)`, without projecting the vertices. Among
    equal separations the pair of directions ``(i, j)`` first in ``j``-major order is kept; axes
    are pruned by :func:`_unit_cross` (threshold ``max(best, se) - margin + rin - 1e-12``, d).

    Whole edges are pruned first (module docstring): an edge whose bound is below ``max(best, se) -
    margin - 1e-12`` pairs with no edge worth trying. ``gauss``: the :class:`GeneralTables`.

    Returns ``(far, se, ie, je, ex, ey, ez, code)``: ``far`` when an axis separates by more than
    ``alert`` (d), its code ``i ndb + j`` (local direction indices); otherwise the best
    separation ``se`` (d; ``-inf`` if no crossing pair), its direction indices and the unit axis
    oriented from A to B.
    """
    pv, pf, pd = geo.vertex_start, geo.face_start, geo.direction_start
    rv, fn, dr = geo.vertices, geo.normals, geo.directions
    edge_start, edge_faces, edge_dir = gauss.edge_start, gauss.edge_faces, gauss.edge_direction
    edge_arc, inradius, edges = gauss.edge_arc, gauss.inradius, gauss.edges
    face_start, face_offsets, W = gauss.face_start, gauss.face_offsets, gauss.face_bound
    Z, sel = gauss.edge_bound, gauss.selected_edges
    a0, b0, fa0, fb0, da0, db0 = pv[a], pv[b], pf[a], pf[b], pd[a], pd[b]
    oa0, ob0 = face_start[ka], face_start[kb]
    ea0, ea1, eb0, eb1 = edge_start[ka], edge_start[ka + 1], edge_start[kb], edge_start[kb + 1]
    ndb = pd[b + 1] - db0
    # the axes' bound (_unit_cross) is compared with t, the edges' own bound (below) with t_edge
    t, t_edge = best - margin + rin - 1e-12, best - margin - 1e-12
    rho_a, rho_b = inradius[ka], inradius[kb]
    slack = 1e-9 * math.sqrt(ox * ox + oy * oy + oz * oz)
    for f in range(pf[a + 1] - fa0):
        W[0, f] = fn[fa0 + f, 0] * ox + fn[fa0 + f, 1] * oy + fn[fa0 + f, 2] * oz - face_offsets[oa0 + f]
    for f in range(pf[b + 1] - fb0):
        W[1, f] = -(fn[fb0 + f, 0] * ox + fn[fb0 + f, 1] * oy + fn[fb0 + f, 2] * oz) - face_offsets[ob0 + f]
    nsel = 0
    for e in range(eb1 - eb0):
        f1, f2 = edge_faces[eb0 + e, 0], edge_faces[eb0 + e, 1]
        # B's arc is that of -m1, -m2, B's edge at q on both faces (m . q their offsets): along
        # u = -m of the arc, s(u) = u . (o + q) - h_A(u) <= -m . o - m . q - rho_A
        top = max(W[1, f1], W[1, f2])
        if (top * edge_arc[eb0 + e, 1] if top > 0.0 else top) + slack - rho_a < t_edge:
            continue  # the cheap bound of _arc_max's, no square root
        Z[3, e] = _arc_max(W[1, f1], W[1, f2], edge_arc[eb0 + e, 0], slack) - rho_a
        m1, m2 = fb0 + f1, fb0 + f2
        if Z[3, e] < t_edge:
            continue
        # q = (-m2) x (-m1) = m2 x m1
        Z[0, e] = fn[m2, 1] * fn[m1, 2] - fn[m2, 2] * fn[m1, 1]
        Z[1, e] = fn[m2, 2] * fn[m1, 0] - fn[m2, 0] * fn[m1, 2]
        Z[2, e] = fn[m2, 0] * fn[m1, 1] - fn[m2, 1] * fn[m1, 0]
        sel[nsel] = e
        nsel += 1
    se, ie, je, ex, ey, ez = -math.inf, -1, -1, 0.0, 0.0, 0.0
    for ea in range(ea0, ea1):
        n1 = fa0 + edge_faces[ea, 0]
        n2 = fa0 + edge_faces[ea, 1]
        # A's edge at p on both faces: along u of its arc, s(u) <= u . (o - p) - rho_B
        top = max(W[0, edge_faces[ea, 0]], W[0, edge_faces[ea, 1]])
        if (top * edge_arc[ea, 1] if top > 0.0 else top) + slack - rho_b < t_edge:
            continue
        bound = _arc_max(W[0, edge_faces[ea, 0]], W[0, edge_faces[ea, 1]], edge_arc[ea, 0], slack) - rho_b
        if bound < t_edge:
            continue
        px = fn[n2, 1] * fn[n1, 2] - fn[n2, 2] * fn[n1, 1]
        py = fn[n2, 2] * fn[n1, 0] - fn[n2, 0] * fn[n1, 2]
        pz = fn[n2, 0] * fn[n1, 1] - fn[n2, 1] * fn[n1, 0]
        for r in range(nsel):
            e = sel[r]
            if Z[3, e] < t_edge:
                continue
            m1 = fb0 + edge_faces[eb0 + e, 0]
            m2 = fb0 + edge_faces[eb0 + e, 1]
            cp = -(fn[m1, 0] * px + fn[m1, 1] * py + fn[m1, 2] * pz)
            dp = -(fn[m2, 0] * px + fn[m2, 1] * py + fn[m2, 2] * pz)
            if cp * dp >= 0.0:
                continue
            n1q = fn[n1, 0] * Z[0, e] + fn[n1, 1] * Z[1, e] + fn[n1, 2] * Z[2, e]
            n2q = fn[n2, 0] * Z[0, e] + fn[n2, 1] * Z[1, e] + fn[n2, 2] * Z[2, e]
            if n1q * n2q >= 0.0 or cp * n2q <= 0.0:
                continue
            i, j = edge_dir[ea], edge_dir[eb0 + e]
            wx, wy, wz = _edge_cross_offset(dr, db0 + j, ox, oy, oz)
            ok, cx, cy, cz = _unit_cross(dr, da0 + i, db0 + j, wx, wy, wz, t)
            if not ok:
                continue
            # the axis lies in A's edge's normal cone (the arc n1..n2) once turned towards
            # n1 + n2, and then in B's edge's cone about -u: A's support along u is its edge, B's
            # along -u is its edge, so the separation is exact from one vertex of each
            if cx * (fn[n1, 0] + fn[n2, 0]) + cy * (fn[n1, 1] + fn[n2, 1]) + cz * (fn[n1, 2] + fn[n2, 2]) < 0.0:
                cx, cy, cz = -cx, -cy, -cz
            p = a0 + edges[ea, 0]
            q = b0 + edges[eb0 + e, 0]
            s = (cx * (ox + rv[q, 0] - rv[p, 0]) + cy * (oy + rv[q, 1] - rv[p, 1])
                 + cz * (oz + rv[q, 2] - rv[p, 2]))
            if s > alert:
                return True, s, i, j, cx, cy, cz, i * ndb + j
            if s > se or (s == se and (j < je or (j == je and i < ie))):
                se, ie, je, ex, ey, ez = s, i, j, cx, cy, cz
                t = max(best, se) - margin + rin - 1e-12
                t_edge = max(best, se) - margin - 1e-12
                if bound < t_edge:
                    break
    return False, se, ie, je, ex, ey, ez, -1

"""Separating-axis test of two convex polyhedra (:func:`_sat`) and the world-frame hull tables it reads.

Axes: both bodies' face normals and the cross products of their edge directions (Ericson, *Real-Time
Collision Detection*, 2005, §5.2.1); a pair is apart when its projections on one axis do not overlap.
It runs first because most candidate pairs end at the first axis that separates them by more than the
alert distance; the best axes of the others are where :mod:`granpack.contact.manifold` builds the contact.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from granpack._numba import jit, prange
from granpack.rotations import quat_to_matrix_nb

__all__ = ["SatResult", "world_geometry"]

#: The result of :func:`_sat`. ``far``: some axis separates by more than the alert distance;
#: ``axis``: its code (-1 if none, or the centre line). Otherwise the best face axis of A
#: (separation ``sfa``, d; row ``kfa`` of the world face axes; side ``gfa`` = +-1, B on the
#: ``gfa * axis`` side), of B (``sfb``, ``kfb``, ``gfb``), and the best edge-edge axis (``se``, d,
#: ``-inf`` when every edge pair is parallel; local direction indices ``ie`` on A and ``je`` on
#: B; the oriented unit axis ``(ex, ey, ez)`` from A to B).
SatResult = namedtuple("SatResult", ["far", "sfa", "kfa", "gfa", "sfb", "kfb", "gfb", "se", "ie", "je", "ex", "ey",
                                     "ez", "axis"])


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
        ``(pv, pf, pa, pd, rv, fn, ax, dr)``: per-particle CSR offsets ``(N+1,)`` into the world
        vertex offsets ``rv`` (``x - x_p``, d), face normals ``fn``, face axes ``ax`` and edge
        directions ``dr`` (all ``(n, 3)``, same row order as the kind's table rows).
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
    return pv, pf, pa, pd, rv, fn, ax, dr


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

    ``geo`` is the :func:`world_geometry` output, ``ka``, ``kb`` the two kinds. The vertices of
    both bodies are gathered into the scratch ``X`` (``(3, >= nA + nB)``, B's shifted by ``o``),
    so every axis reads them from one small contiguous block. ``symmetric`` is ``(half_start,
    half, axis_start, support)``: when both bodies are centrally symmetric (kinds with a non-empty
    block in the CSR ``half_start``, ``half``: local indices of one vertex of each antipodal pair)
    the separation along ``u`` is ``|u . o| - h_A - h_B`` with the supports ``h`` read from half
    the vertices in ``Y`` (:func:`_half_support`), or, along a body's own face axes, from
    ``support`` (d; rows ``axis_start[k]:axis_start[k+1]`` of kind ``k``), a constant of the
    shape; ``X`` is then filled only for a pair that is not separated. The two paths are written
    out at each axis on purpose (docs/design-notes.md, "Separating-axis test: speed").

    Edge-edge axes are pruned with a rigorous bound: A contains the ball of radius ``rho_A`` (its
    smallest face offset) about its centre, B likewise, so along the axis ``u = c / |c|`` of an
    edge-direction cross product ``c``

    .. math:: s(u) \\le |u \\cdot o| - \\rho_A - \\rho_B ,

    and an axis whose bound is below the best separation found so far minus ``margin`` (d, the
    widest hysteresis band, ``_KEEP_BAND eps_f`` of :mod:`granpack.contact.narrowphase`) can
    neither separate the pair nor be a manifold candidate, so its projections are skipped
    (``rin = rho_A + rho_B``, d). The test is first made without the square root,
    :math:`(c \\cdot o)^2 < (t + \\rho_A + \\rho_B)^2 |c|^2` with ``t`` the threshold lowered by
    1e-12 d (round-off), and without the cross product (unit directions:
    :math:`c \\cdot o = e_A \\cdot (e_B \\times o)`, :math:`|c|^2 = 1 - (e_A \\cdot e_B)^2`), so
    most pruned axes are never formed.

    ``cached`` is the axis that separated the pair at the previous call (code below, -1 if
    none): it is tried first, and a pair it still separates by more than ``alert`` (d) costs one
    axis (the separating axis of a pair that stays apart changes rarely between steps).

    Returns:
        a :class:`SatResult`. Axis codes: ``k`` for A's face axis ``pa[a] + k``, ``nfa + k`` for
        B's ``pa[b] + k``, ``nfa + nfb + i ndb + j`` for the edge-direction pair ``(pd[a] + i,
        pd[b] + j)``, -1 for the centre line (``nfa``, ``nfb`` the face-axis counts, ``ndb`` B's
        edge-direction count). A pair that is not separated has ``axis`` -1.
    """
    pv, _, pa, pd, rv, _, ax, dr = geo
    half_start, half, axis_start, support = symmetric
    a0, a1, b0, b1 = pv[a], pv[a + 1], pv[b], pv[b + 1]
    aa0, aa1, ab0, ab1 = pa[a], pa[a + 1], pa[b], pa[b + 1]
    da0, da1, db0, db1 = pd[a], pd[a + 1], pd[b], pd[b + 1]
    inf = math.inf
    na = a1 - a0
    nb = b1 - b0
    ha0, hb0 = half_start[ka], half_start[kb]
    nha = half_start[ka + 1] - ha0
    nhb = half_start[kb + 1] - hb0
    sa0, sb0 = axis_start[ka], axis_start[kb]
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
    ndb = db1 - db0
    # cheap first tries: the cached axis, then the centre-to-centre direction
    for attempt in range(2):
        if attempt == 0:
            if cached < 0:
                continue
            if cached < nfa + nfb:
                r = aa0 + cached if cached < nfa else ab0 + cached - nfa
                ux, uy, uz = ax[r, 0], ax[r, 1], ax[r, 2]
            else:
                i = da0 + (cached - nfa - nfb) // ndb
                j = db0 + (cached - nfa - nfb) % ndb
                cx = dr[i, 1] * dr[j, 2] - dr[i, 2] * dr[j, 1]
                cy = dr[i, 2] * dr[j, 0] - dr[i, 0] * dr[j, 2]
                cz = dr[i, 0] * dr[j, 1] - dr[i, 1] * dr[j, 0]
                c = cx * cx + cy * cy + cz * cz
                if c > 1e-12:  # the two edges may have turned parallel since
                    c = 1.0 / math.sqrt(c)
                ux, uy, uz = cx * c, cy * c, cz * c
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
    sfa, kfa, gfa = -inf, -1, 1.0
    for k in range(aa0, aa1):
        if sym:
            s, g = _signed_gap(ox, oy, oz, ax[k, 0], ax[k, 1], ax[k, 2], support[sa0 + k - aa0],
                               _half_support(Y, nha, nha + nhb, ax[k, 0], ax[k, 1], ax[k, 2]))
        else:
            s, g = _separation(X, na, nb, ax[k, 0], ax[k, 1], ax[k, 2])
        if s > alert:
            return _separated(k - aa0)
        if s > sfa:
            sfa, kfa, gfa = s, k, g
    sfb, kfb, gfb = -inf, -1, 1.0
    for k in range(ab0, ab1):
        if sym:
            s, g = _signed_gap(ox, oy, oz, ax[k, 0], ax[k, 1], ax[k, 2],
                               _half_support(Y, 0, nha, ax[k, 0], ax[k, 1], ax[k, 2]), support[sb0 + k - ab0])
        else:
            s, g = _separation(X, na, nb, ax[k, 0], ax[k, 1], ax[k, 2])
        if s > alert:
            return _separated(nfa + k - ab0)
        if s > sfb:
            sfb, kfb, gfb = s, k, g
    se, ie, je, ex, ey, ez = -inf, -1, -1, 0.0, 0.0, 0.0
    # pruning threshold on |c . o| / |c|, updated when the best separation improves
    t = max(sfa, sfb) - margin + rin - 1e-12
    for j in range(db0, db1):
        # w = e_B x o, so that (e_A x e_B) . o = e_A . w; |e_A x e_B|^2 = 1 - (e_A . e_B)^2
        wx = dr[j, 1] * oz - dr[j, 2] * oy
        wy = dr[j, 2] * ox - dr[j, 0] * oz
        wz = dr[j, 0] * oy - dr[j, 1] * ox
        for i in range(da0, da1):
            cos = dr[i, 0] * dr[j, 0] + dr[i, 1] * dr[j, 1] + dr[i, 2] * dr[j, 2]
            c2 = 1.0 - cos * cos
            if c2 < 1e-12:
                continue
            co = dr[i, 0] * wx + dr[i, 1] * wy + dr[i, 2] * wz
            if t > 0.0 and co * co < t * t * c2:
                continue
            cx = dr[i, 1] * dr[j, 2] - dr[i, 2] * dr[j, 1]
            cy = dr[i, 2] * dr[j, 0] - dr[i, 0] * dr[j, 2]
            cz = dr[i, 0] * dr[j, 1] - dr[i, 1] * dr[j, 0]
            c = 1.0 / math.sqrt(cx * cx + cy * cy + cz * cz)
            cx *= c
            cy *= c
            cz *= c
            if sym:
                s, g = _signed_gap(ox, oy, oz, cx, cy, cz, _half_support(Y, 0, nha, cx, cy, cz),
                                   _half_support(Y, nha, nha + nhb, cx, cy, cz))
            else:
                s, g = _separation(X, na, nb, cx, cy, cz)
            if s > alert:
                return _separated(nfa + nfb + (i - da0) * ndb + j - db0)
            if s > se:
                se, ie, je, ex, ey, ez = s, i - da0, j - db0, g * cx, g * cy, g * cz
                t = max(sfa, sfb, se) - margin + rin - 1e-12
    if sym:
        _gather(rv, a0, a1, b0, b1, ox, oy, oz, X)
    return SatResult(False, sfa, kfa, gfa, sfb, kfb, gfb, se, ie, je, ex, ey, ez, -1)


@jit(inline="always")
def _gather(rv, a0, a1, b0, b1, ox, oy, oz, X):
    """Vertex block of a pair, coordinate-major: ``X[:, 0:nA]`` A's offsets, then B's plus ``o``."""
    na = a1 - a0
    for k in range(na):
        X[0, k], X[1, k], X[2, k] = rv[a0 + k, 0], rv[a0 + k, 1], rv[a0 + k, 2]
    for k in range(b1 - b0):
        X[0, na + k], X[1, na + k], X[2, na + k] = ox + rv[b0 + k, 0], oy + rv[b0 + k, 1], oz + rv[b0 + k, 2]



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
- polyhedron-polyhedron: separating-axis test (:func:`_sat`) over the face normals of both bodies
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
one band, an axis at its edge flickered in and out from step to step, the normal and the force of
the manifold turning with it, and a pile at rest never balanced its forces. The loop between
the two bands is wide on purpose: a manifold switching between two axes a fraction of a degree
apart turns its normal at a place that depends on the direction of travel, so its force feeds a
grain sliding to and fro (in a slot between parallel faces) energy in proportion to the loop's
width, while the end game's damping takes it in proportion to the square of the swing needed to
go round the loop; a narrow loop kept such a grain swinging (docs/design-notes.md).

Tolerances: ``eps_f`` (default 1e-3 d_min) is the feature band and the axis hysteresis; points
closer than ``1e-3 eps_f`` are merged.
"""

from __future__ import annotations

import math

import numpy as np

from granpack._numba import jit, prange
from granpack.contact._gjk import gjk_distance
from granpack.contact.contacts import manifold_type_nb
from granpack.rotations import quat_to_matrix_nb

__all__ = ["world_geometry", "narrow_phase"]

_AXIS_FACE_A, _AXIS_FACE_B, _AXIS_EDGE = 0, 1, 2
#: |cos| between the previous normal and an axis above which the axis counts as the previous one
_HINT_COS = 0.999
#: the previous step's axis stays a manifold candidate within this many eps_f of the best
#: separation (the others within one); the edge-axis pruning of :func:`_sat` keeps as many
_KEEP_BAND = 5.0


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
    for r in range(s1 - s0):
        x, y, z = src[s0 + r, 0], src[s0 + r, 1], src[s0 + r, 2]
        dst[d0 + r, 0] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
        dst[d0 + r, 1] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
        dst[d0 + r, 2] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z


# ---------------------------------------------------------------------------------------------
# separating-axis test


@jit
def _interval(rv, v0, v1, ox, oy, oz, ux, uy, uz):
    """Min and max of ``u . (o + rv[k])`` over rows ``k`` in ``[v0, v1)``."""
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

    Returns ``(s, sign)``: ``s`` = the larger of ``min_B - max_A`` (B on the +u side, sign +1)
    and ``min_A - max_B`` (sign -1).
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
    one vertex of each antipodal pair (columns ``k0:k1``): its projection on ``u`` is ``c . u +- h``."""
    h = 0.0
    for k in range(k0, k1):
        h = max(h, abs(ux * Y[0, k] + uy * Y[1, k] + uz * Y[2, k]))
    return h


@jit
def _signed_gap(ox, oy, oz, ux, uy, uz, ha, hb):
    """Separation ``|u . o| - h_A - h_B`` of two symmetric bodies along ``u`` and the side of B."""
    c = ux * ox + uy * oy + uz * oz
    if c >= 0.0:
        return c - ha - hb, 1.0
    return -c - ha - hb, -1.0


@jit(inline="always")
def _sat(rv, a0, a1, b0, b1, ax, aa0, aa1, ab0, ab1, dr, da0, da1, db0, db1, half_start, half, axis_start, support, ka,
         kb, ox, oy, oz, alert, rin, margin, X, Y, cached):
    """Separating-axis test between polyhedra A (centred) and B (offset ``o``).

    The vertices of both bodies are gathered into the scratch ``X`` (``(3, >= nA + nB)``, B's
    shifted by ``o``), so every axis reads them from one small contiguous block. When both bodies
    are centrally symmetric (kinds ``ka``, ``kb`` with a non-empty block in the CSR ``half_start``,
    ``half``: local indices of one vertex of each antipodal pair) the separation along ``u`` is
    ``|u . o| - h_A - h_B`` with the supports ``h`` read from half the vertices in ``Y``
    (:func:`_half_support`), or, along a body's own face axes, from ``support`` (rows
    ``axis_start[k]:axis_start[k+1]`` of kind ``k``), a constant of the shape; ``X`` is then
    filled only for a pair that is not separated. (The two paths are written out at each axis on
    purpose: one helper taking both, inlined, made the detection of a 3000-pinacoid pile 17 %
    slower.)

    Edge-edge axes are pruned with a rigorous bound: A contains the ball of radius ``rho_A`` (its
    smallest face offset) about its centre, B likewise, so along the axis ``u = c / |c|`` of an
    edge-direction cross product ``c``

    .. math:: s(u) \\le |u \\cdot o| - \\rho_A - \\rho_B ,

    and an axis whose bound is below the best separation found so far minus ``margin`` (the
    widest hysteresis band, ``_KEEP_BAND eps_f``) can neither separate the pair nor be a manifold
    candidate, so its projections are skipped (``rin = rho_A + rho_B``). The test is first made
    without the square root, :math:`(c \\cdot o)^2 < (t + \\rho_A + \\rho_B)^2 |c|^2` with ``t`` the
    threshold lowered by 1e-12 d (round-off), and without the cross product (unit directions:
    :math:`c \\cdot o = e_A \\cdot (e_B \\times o)`, :math:`|c|^2 = 1 - (e_A \\cdot e_B)^2`), so
    most pruned axes are never formed.

    ``cached`` is the axis that separated the pair at the previous call (code below, -1 if
    none): it is tried first, and a pair it still separates by more than ``alert`` costs one axis
    (the separating axis of a pair that stays apart changes rarely between steps).

    Returns:
        ``(far, sfa, kfa, gfa, sfb, kfb, gfb, se, ie, je, ex, ey, ez, axis)``: ``far`` is True
        when some axis separates by more than ``alert``, ``axis`` then its code (``k`` for A's
        face axis ``aa0 + k``, ``nfa + k`` for B's ``ab0 + k``, ``nfa + nfb + i ndb + j`` for the
        edge-direction pair ``(da0 + i, db0 + j)``, -1 for the centre line; ``nfa``, ``nfb``
        the face-axis counts, ``ndb`` B's edge-direction count). Otherwise the best face axis of
        A (separation, row in ``ax``, sign), of B, the best edge-edge axis (separation, local
        direction indices on A and B, and the oriented unit axis from A to B; ``se = -inf`` when
        every edge pair is parallel) and ``axis`` -1.
    """
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
            return True, 0.0, -1, 0.0, 0.0, -1, 0.0, 0.0, -1, -1, 0.0, 0.0, 0.0, cached if attempt == 0 else -1
    sfa, kfa, gfa = -inf, -1, 1.0
    for k in range(aa0, aa1):
        if sym:
            s, g = _signed_gap(ox, oy, oz, ax[k, 0], ax[k, 1], ax[k, 2], support[sa0 + k - aa0],
                               _half_support(Y, nha, nha + nhb, ax[k, 0], ax[k, 1], ax[k, 2]))
        else:
            s, g = _separation(X, na, nb, ax[k, 0], ax[k, 1], ax[k, 2])
        if s > alert:
            return True, 0.0, -1, 0.0, 0.0, -1, 0.0, 0.0, -1, -1, 0.0, 0.0, 0.0, k - aa0
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
            return True, 0.0, -1, 0.0, 0.0, -1, 0.0, 0.0, -1, -1, 0.0, 0.0, 0.0, nfa + k - ab0
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
                code = nfa + nfb + (i - da0) * ndb + j - db0
                return True, 0.0, -1, 0.0, 0.0, -1, 0.0, 0.0, -1, -1, 0.0, 0.0, 0.0, code
            if s > se:
                se, ie, je, ex, ey, ez = s, i - da0, j - db0, g * cx, g * cy, g * cz
                t = max(sfa, sfb, se) - margin + rin - 1e-12
    if sym:
        _gather(rv, a0, a1, b0, b1, ox, oy, oz, X)
    return False, sfa, kfa, gfa, sfb, kfb, gfb, se, ie, je, ex, ey, ez, -1


@jit(inline="always")
def _gather(rv, a0, a1, b0, b1, ox, oy, oz, X):
    """Vertex block of a pair, coordinate-major: ``X[:, 0:nA]`` A's offsets, then B's plus ``o``."""
    na = a1 - a0
    for k in range(na):
        X[0, k], X[1, k], X[2, k] = rv[a0 + k, 0], rv[a0 + k, 1], rv[a0 + k, 2]
    for k in range(b1 - b0):
        X[0, na + k], X[1, na + k], X[2, na + k] = ox + rv[b0 + k, 0], oy + rv[b0 + k, 1], oz + rv[b0 + k, 2]


# ---------------------------------------------------------------------------------------------
# manifold construction


@jit(inline="always")
def _clip_face(ref_rv, ref_v0, ref_v1, rox, roy, roz, ref_f0, ref_f1, ref_fn, rvi, inc_v0, iox, ioy, ioz, inc_f0,
               inc_f1, inc_fn, fvs, fverts, face_row_ref, face_row_inc, nx, ny, nz, alert, buf, buf2, out, gout):
    """Clip the incident face against the reference face with outward normal ``n``.

    The reference body has vertices ``ro + ref_rv[ref_v0:ref_v1]``, world face normals
    ``ref_fn[ref_f0:ref_f1]`` (global face rows of its kind start at ``face_row_ref``); the
    reference face is the one whose normal is closest to ``n``. The incident body's face is the
    one whose normal is most opposed to ``n``.

    Returns:
        ``(count, gmin)``: points written to ``out`` (position on the midpoint between the two
        surfaces) and their gaps ``gout`` (``n . p - delta_ref``), keeping gaps ``<= alert``;
        ``gmin`` is the smallest gap over all clipped points (``inf`` if the clip is empty).
    """
    # reference face: normal closest to n; incident face: normal most opposed to n
    fr = ref_f0
    best = -math.inf
    for f in range(ref_f0, ref_f1):
        d = ref_fn[f, 0] * nx + ref_fn[f, 1] * ny + ref_fn[f, 2] * nz
        if d > best:
            best, fr = d, f
    fi = inc_f0
    best = math.inf
    for f in range(inc_f0, inc_f1):
        d = inc_fn[f, 0] * nx + inc_fn[f, 1] * ny + inc_fn[f, 2] * nz
        if d < best:
            best, fi = d, f
    _, delta = _interval(ref_rv, ref_v0, ref_v1, rox, roy, roz, nx, ny, nz)
    row_i = face_row_inc + fi - inc_f0
    m = 0
    for k in range(fvs[row_i], fvs[row_i + 1]):
        v = inc_v0 + fverts[k]
        buf[m, 0] = iox + rvi[v, 0]
        buf[m, 1] = ioy + rvi[v, 1]
        buf[m, 2] = ioz + rvi[v, 2]
        m += 1
    row_r = face_row_ref + fr - ref_f0
    r0, r1 = fvs[row_r], fvs[row_r + 1]
    nr = r1 - r0
    for e in range(nr):
        va = ref_v0 + fverts[r0 + e]
        vb = ref_v0 + fverts[r0 + (e + 1) % nr]
        ax_, ay_, az_ = rox + ref_rv[va, 0], roy + ref_rv[va, 1], roz + ref_rv[va, 2]
        ex = rox + ref_rv[vb, 0] - ax_
        ey = roy + ref_rv[vb, 1] - ay_
        ez = roz + ref_rv[vb, 2] - az_
        # side plane normal (outward of the face polygon) and offset
        sx = ey * nz - ez * ny
        sy = ez * nx - ex * nz
        sz = ex * ny - ey * nx
        so = sx * ax_ + sy * ay_ + sz * az_
        m2 = 0
        d0 = sx * buf[0, 0] + sy * buf[0, 1] + sz * buf[0, 2] - so
        d2 = d0
        for k in range(m):
            k2 = (k + 1) % m
            d1 = d2
            d2 = d0 if k2 == 0 else sx * buf[k2, 0] + sy * buf[k2, 1] + sz * buf[k2, 2] - so
            if d1 <= 0.0:
                buf2[m2, 0], buf2[m2, 1], buf2[m2, 2] = buf[k, 0], buf[k, 1], buf[k, 2]
                m2 += 1
            if (d1 < 0.0 and d2 > 0.0) or (d1 > 0.0 and d2 < 0.0):
                t = d1 / (d1 - d2)
                buf2[m2, 0] = buf[k, 0] + t * (buf[k2, 0] - buf[k, 0])
                buf2[m2, 1] = buf[k, 1] + t * (buf[k2, 1] - buf[k, 1])
                buf2[m2, 2] = buf[k, 2] + t * (buf[k2, 2] - buf[k, 2])
                m2 += 1
        m = m2
        for k in range(m):
            buf[k, 0], buf[k, 1], buf[k, 2] = buf2[k, 0], buf2[k, 1], buf2[k, 2]
        if m == 0:
            return 0, math.inf
    cnt = 0
    gmin = math.inf
    for k in range(m):
        g = nx * buf[k, 0] + ny * buf[k, 1] + nz * buf[k, 2] - delta
        gmin = min(gmin, g)
        if g <= alert:
            out[cnt, 0] = buf[k, 0] - 0.5 * g * nx
            out[cnt, 1] = buf[k, 1] - 0.5 * g * ny
            out[cnt, 2] = buf[k, 2] - 0.5 * g * nz
            gout[cnt] = g
            cnt += 1
    return cnt, gmin


@jit(inline="always")
def _edge_contact(rv, a0, a1, b0, b1, ox, oy, oz, ea0, ea1, eb0, eb1, edges, nx, ny, nz, se, X, h, pts, gp):
    """One point from the crossing edges that realise an edge-edge axis ``n`` (from A to B).

    An edge realising the separation along ``n = e_A x e_B`` is perpendicular to ``n``, so it
    lies whole in A's support plane (``n . x = max_A``), resp. B's (``n . x = min_B``). Several
    edge pairs can give the same axis (parallel edges of one body, or edge directions of a face
    lying in the support plane), so the pair is not taken from the direction indices of the
    axis: every non-parallel pair of edges lying in the two support planes is tried and the first
    whose closest points are interior to both segments is the contact.

    The vertex heights ``n . x`` are computed once into ``h`` from the vertex block ``X`` left by
    :func:`_sat` (A's vertices, then B's shifted by ``o``).

    Returns the number of points written (1, or 0 when no such pair exists, e.g. when the
    closest features are not two crossing edges).
    """
    na = a1 - a0
    topa = -math.inf
    botb = math.inf
    for k in range(na + b1 - b0):
        h[k] = nx * X[0, k] + ny * X[1, k] + nz * X[2, k]
        if k < na:
            topa = max(topa, h[k])
        else:
            botb = min(botb, h[k])
    tol = 1e-9 * (1.0 + abs(topa) + abs(botb))
    for ea in range(ea0, ea1):
        if h[edges[ea, 0]] < topa - tol or h[edges[ea, 1]] < topa - tol:
            continue
        p0 = a0 + edges[ea, 0]
        p1 = a0 + edges[ea, 1]
        d1x, d1y, d1z = rv[p1, 0] - rv[p0, 0], rv[p1, 1] - rv[p0, 1], rv[p1, 2] - rv[p0, 2]
        for eb in range(eb0, eb1):
            if h[na + edges[eb, 0]] > botb + tol or h[na + edges[eb, 1]] > botb + tol:
                continue
            q0 = b0 + edges[eb, 0]
            q1 = b0 + edges[eb, 1]
            d2x, d2y, d2z = rv[q1, 0] - rv[q0, 0], rv[q1, 1] - rv[q0, 1], rv[q1, 2] - rv[q0, 2]
            cx = d1y * d2z - d1z * d2y
            cy = d1z * d2x - d1x * d2z
            cz = d1x * d2y - d1y * d2x
            if cx * cx + cy * cy + cz * cz < 1e-12 * (d1x * d1x + d1y * d1y + d1z * d1z) * (
                    d2x * d2x + d2y * d2y + d2z * d2z):
                continue
            s, t = _line_params(rv[p0, 0], rv[p0, 1], rv[p0, 2], d1x, d1y, d1z, ox + rv[q0, 0], oy + rv[q0, 1],
                                oz + rv[q0, 2], d2x, d2y, d2z)
            if -1e-9 <= s <= 1.0 + 1e-9 and -1e-9 <= t <= 1.0 + 1e-9:
                cax = rv[p0, 0] + s * d1x
                cay = rv[p0, 1] + s * d1y
                caz = rv[p0, 2] + s * d1z
                cbx = ox + rv[q0, 0] + t * d2x
                cby = oy + rv[q0, 1] + t * d2y
                cbz = oz + rv[q0, 2] + t * d2z
                pts[0, 0], pts[0, 1], pts[0, 2] = 0.5 * (cax + cbx), 0.5 * (cay + cby), 0.5 * (caz + cbz)
                gp[0] = se
                return 1
    return 0


@jit
def _line_params(p1x, p1y, p1z, d1x, d1y, d1z, p2x, p2y, p2z, d2x, d2y, d2z):
    """Parameters ``(s, t)`` of the closest points of lines ``p1 + s d1`` and ``p2 + t d2``."""
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    b = d1x * d2x + d1y * d2y + d1z * d2z
    c = d1x * rx + d1y * ry + d1z * rz
    f = d2x * rx + d2y * ry + d2z * rz
    den = a * e - b * b
    if den <= 1e-300:
        return 0.0, f / e
    s = (b * f - c * e) / den
    t = (b * s + f) / e
    return s, t


@jit(inline="always")
def _merge_points(pts, gp, cnt, eps_pt):
    """Merge points closer than ``eps_pt`` (the deeper gap kept); returns the new count.

    No other point is dropped: every vertex of a clipped contact polygon is a constraint of its
    own (a point left out is free to sink when the grain rocks about the others, see the module
    docstring).
    """
    m = 0
    for k in range(cnt):
        dup = -1
        for q in range(m):
            dx = pts[k, 0] - pts[q, 0]
            dy = pts[k, 1] - pts[q, 1]
            dz = pts[k, 2] - pts[q, 2]
            if dx * dx + dy * dy + dz * dz <= eps_pt * eps_pt:
                dup = q
                break
        if dup >= 0:
            gp[dup] = min(gp[dup], gp[k])
            continue
        pts[m, 0], pts[m, 1], pts[m, 2] = pts[k, 0], pts[k, 1], pts[k, 2]
        gp[m] = gp[k]
        m += 1
    return m


@jit
def _band_vertices(rv, v0, v1, ox, oy, oz, nx, ny, nz, top, band, idx):
    """Rows k with ``n . (o + rv[k]) >= top - band``; returns their count (first two in ``idx``)."""
    c = 0
    for k in range(v0, v1):
        h = nx * (ox + rv[k, 0]) + ny * (oy + rv[k, 1]) + nz * (oz + rv[k, 2])
        if h >= top - band:
            if c < 2:
                idx[c] = k
            c += 1
    return c


@jit
def _gjk_manifold(rv, a0, a1, b0, b1, ox, oy, oz, alert, eps_f, scr, pts, gp):
    """Manifold from the exact closest points (GJK) of A and B.

    Returns ``(count, nx, ny, nz)`` with count 0 if the pair is farther than ``alert`` and -1 if
    GJK finds the bodies touching or intersecting.
    """
    W, ia, ib, lam, tmp, idx, _, _, _, _ = scr
    st, dist, px, py, pz, qx, qy, qz = gjk_distance(rv, a0, a1, rv, b0, b1, ox, oy, oz, alert, W, ia, ib, lam, tmp)
    if st == 1 or (st == 0 and dist > alert):
        return 0, 0.0, 0.0, 0.0
    if st == 2:
        return -1, 0.0, 0.0, 0.0
    nx, ny, nz = (qx - px) / dist, (qy - py) / dist, (qz - pz) / dist
    # parallel edges overlapping along a segment: two points
    topa = nx * px + ny * py + nz * pz
    na = _band_vertices(rv, a0, a1, 0.0, 0.0, 0.0, nx, ny, nz, topa, eps_f, idx[0:2])
    nb = _band_vertices(rv, b0, b1, ox, oy, oz, -nx, -ny, -nz, -(nx * qx + ny * qy + nz * qz), eps_f, idx[2:4])
    cnt = 0
    if na == 2 and nb == 2:
        p0, p1, q0, q1 = idx[0], idx[1], idx[2], idx[3]
        dx, dy, dz = rv[p1, 0] - rv[p0, 0], rv[p1, 1] - rv[p0, 1], rv[p1, 2] - rv[p0, 2]
        la = math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx / la, dy / la, dz / la
        fx, fy, fz = rv[q1, 0] - rv[q0, 0], rv[q1, 1] - rv[q0, 1], rv[q1, 2] - rv[q0, 2]
        lb = math.sqrt(fx * fx + fy * fy + fz * fz)
        cross = math.sqrt((dy * fz - dz * fy) ** 2 + (dz * fx - dx * fz) ** 2 + (dx * fy - dy * fx) ** 2) / lb
        if cross < eps_f / la:
            # parameters of B's ends along A's edge
            tb0 = (dx * (ox + rv[q0, 0] - rv[p0, 0]) + dy * (oy + rv[q0, 1] - rv[p0, 1])
                   + dz * (oz + rv[q0, 2] - rv[p0, 2]))
            tb1 = (dx * (ox + rv[q1, 0] - rv[p0, 0]) + dy * (oy + rv[q1, 1] - rv[p0, 1])
                   + dz * (oz + rv[q1, 2] - rv[p0, 2]))
            lo = max(0.0, min(tb0, tb1))
            hi = min(la, max(tb0, tb1))
            if hi - lo > eps_f and tb1 != tb0:
                for t in (lo, hi):
                    u = (t - tb0) / (tb1 - tb0)
                    bx = ox + rv[q0, 0] + u * (rv[q1, 0] - rv[q0, 0])
                    by = oy + rv[q0, 1] + u * (rv[q1, 1] - rv[q0, 1])
                    bz = oz + rv[q0, 2] + u * (rv[q1, 2] - rv[q0, 2])
                    axp = rv[p0, 0] + t * dx
                    ayp = rv[p0, 1] + t * dy
                    azp = rv[p0, 2] + t * dz
                    g = nx * (bx - axp) + ny * (by - ayp) + nz * (bz - azp)
                    pts[cnt, 0] = bx - 0.5 * g * nx
                    pts[cnt, 1] = by - 0.5 * g * ny
                    pts[cnt, 2] = bz - 0.5 * g * nz
                    gp[cnt] = g
                    cnt += 1
                if min(gp[0], gp[1]) <= dist + 1e-12 * (1.0 + dist):
                    return cnt, nx, ny, nz
                cnt = 2
    pts[cnt, 0] = 0.5 * (px + qx)
    pts[cnt, 1] = 0.5 * (py + qy)
    pts[cnt, 2] = 0.5 * (pz + qz)
    gp[cnt] = dist
    return cnt + 1, nx, ny, nz


@jit
def _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, nx, ny, nz, sigma, from_a, pts, gp):
    """Single point at the support vertex of B along -n (or of A along n), gap ``sigma``."""
    if from_a:
        best = -math.inf
        k0 = a0
        for k in range(a0, a1):
            h = nx * rv[k, 0] + ny * rv[k, 1] + nz * rv[k, 2]
            if h > best:
                best, k0 = h, k
        pts[0, 0] = rv[k0, 0] + 0.5 * sigma * nx
        pts[0, 1] = rv[k0, 1] + 0.5 * sigma * ny
        pts[0, 2] = rv[k0, 2] + 0.5 * sigma * nz
    else:
        best = math.inf
        k0 = b0
        for k in range(b0, b1):
            h = nx * (ox + rv[k, 0]) + ny * (oy + rv[k, 1]) + nz * (oz + rv[k, 2])
            if h < best:
                best, k0 = h, k
        pts[0, 0] = ox + rv[k0, 0] - 0.5 * sigma * nx
        pts[0, 1] = oy + rv[k0, 1] - 0.5 * sigma * ny
        pts[0, 2] = oz + rv[k0, 2] - 0.5 * sigma * nz
    gp[0] = sigma
    return 1


@jit(inline="always")
def _clamp_gaps(gp, cnt, floor):
    """Raise the first ``cnt`` gaps to at least ``floor``; returns the smallest."""
    low = math.inf
    for k in range(cnt):
        if gp[k] < floor:
            gp[k] = floor
        low = min(low, gp[k])
    return low


@jit(inline="always")
def poly_poly(a, b, ox, oy, oz, hx, hy, hz, sat, geo, tab, alert, eps_f, scr, pts, gp):
    """Manifold between polyhedra ``a`` (antagonist image, at the origin) and ``b`` (at ``o``).

    ``sat`` is the :func:`_sat` result of the pair, without its leading ``far`` (the caller runs
    the test, so that the half of the pairs it rejects cost no call here), and its vertex block
    must still be in the scratch ``X``. ``(hx, hy, hz)`` is the pair's normal at the previous step
    (zero if none): the separating axis closest to it is tried first when it is within ``eps_f``
    of the best separation.

    Returns ``(count, nx, ny, nz)``: number of points written to ``pts`` (A-centred frame) and
    ``gp``, and the normal from A to B; count 0 means no contact within ``alert``.
    """
    pv, pf, pa, pd, rv, fn, ax, dr = geo
    vertex_start, face_start, face_offsets, fvs, fverts, edge_start, edges, edge_dir, kind = tab
    _, _, _, _, _, _, buf, buf2, X, h = scr
    a0, a1, b0, b1 = pv[a], pv[a + 1], pv[b], pv[b + 1]
    sfa, kfa, gfa, sfb, kfb, gfb, se, ie, je, ex, ey, ez = sat
    sface = max(sfa, sfb)
    sigma = max(sface, se)
    tol_x = 1e-10 * (1.0 + abs(sigma))
    ka, kb = kind[a], kind[b]
    # candidate order: the better face axis, the other one, the edge axis; the edge axis first
    # only if it beats both face axes by more than eps_f (hysteresis); a candidate whose axis is
    # the previous step's normal (hx, hy, hz) goes first (temporal hysteresis)
    first_face = _AXIS_FACE_A if sfa >= sfb else _AXIS_FACE_B
    second_face = _AXIS_FACE_B if sfa >= sfb else _AXIS_FACE_A
    if se > sface + eps_f:
        o0, o1, o2 = _AXIS_EDGE, first_face, second_face
    else:
        o0, o1, o2 = first_face, second_face, _AXIS_EDGE
    # an axis is a candidate within eps_f of the best separation, or within _KEEP_BAND eps_f if it
    # is the previous normal: one band would let an axis at its edge flicker in and out from step
    # to step (the manifold's normal and type flipping at every step, its force with them), and a
    # narrow loop between the two bands pumps a sliding grain (module docstring)
    band_a = band_b = band_e = eps_f
    if hx != 0.0 or hy != 0.0 or hz != 0.0:
        ca = abs(hx * ax[kfa, 0] + hy * ax[kfa, 1] + hz * ax[kfa, 2])
        cb = abs(hx * ax[kfb, 0] + hy * ax[kfb, 1] + hz * ax[kfb, 2])
        ce = abs(hx * ex + hy * ey + hz * ez)
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
                o0, o1, o2 = (_AXIS_FACE_A, _AXIS_FACE_B, _AXIS_EDGE) if ca >= cb else (_AXIS_FACE_B, _AXIS_FACE_A, _AXIS_EDGE)
            else:
                o0, o1, o2 = _AXIS_EDGE, first_face, second_face
    W, ia, ib, lam, tmp, _, _, _, _, _ = scr
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
                cnt, gmin = _clip_face(rv, a0, a1, 0.0, 0.0, 0.0, pf[a], pf[a + 1], fn, rv, b0, ox, oy, oz, pf[b],
                                       pf[b + 1], fn, fvs, fverts, face_start[ka], face_start[kb], nx, ny, nz, alert,
                                       buf, buf2, pts, gp)
            else:
                g = gfb
                nx, ny, nz = g * ax[kfb, 0], g * ax[kfb, 1], g * ax[kfb, 2]
                # reference face on B, outward normal -n
                cnt, gmin = _clip_face(rv, b0, b1, ox, oy, oz, pf[b], pf[b + 1], fn, rv, a0, 0.0, 0.0, 0.0, pf[a],
                                       pf[a + 1], fn, fvs, fverts, face_start[kb], face_start[ka], -nx, -ny, -nz, alert,
                                       buf, buf2, pts, gp)
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
            if sigma <= 0.0 and cnt < buf.shape[0]:
                # interpenetration whose deepest vertex lies outside the reference face: add it
                _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, nx, ny, nz, sk, which == _AXIS_FACE_B,
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
    # interpenetration (or touching) without an exact manifold: deepest support point, best axis
    if se >= sface:
        nx, ny, nz = ex, ey, ez
        from_a = False
    elif sfa >= sfb:
        nx, ny, nz = gfa * ax[kfa, 0], gfa * ax[kfa, 1], gfa * ax[kfa, 2]
        from_a = False
    else:
        nx, ny, nz = gfb * ax[kfb, 0], gfb * ax[kfb, 1], gfb * ax[kfb, 2]
        from_a = True
    _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, nx, ny, nz, sigma, from_a, pts, gp)
    return 1, nx, ny, nz


@jit
def _sphere_poly(ra, b, ox, oy, oz, geo, tab, alert, scr, one, pts, gp):
    """Sphere A (radius ``ra``, at the origin) against polyhedron ``b`` (at ``o``)."""
    pv, pf, pa, pd, rv, fn, ax, dr = geo
    vertex_start, face_start, face_offsets, fvs, fverts, edge_start, edges, edge_dir, kind = tab
    W, ia, ib, lam, tmp, idx, _, _, _, _ = scr
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
    """Polyhedron ``a`` (at the origin) against sphere B (radius ``rb``, at ``o``): the
    sphere-polyhedron manifold seen from the other body (normal flipped, points moved by ``o``)."""
    cnt, nx, ny, nz = _sphere_poly(rb, a, -ox, -oy, -oz, geo, tab, alert, scr, one, pts, gp)
    for k in range(cnt):
        pts[k, 0] += ox
        pts[k, 1] += oy
        pts[k, 2] += oz
    return cnt, -nx, -ny, -nz


@jit
def _poly_wall(i, zc, geo, alert, pts, gp):
    """Vertices of polyhedron ``i`` (centre height ``zc``) below ``alert``; points relative to its centre.

    ``pts`` must have at least as many rows as the polyhedron has vertices.
    """
    pv, pf, pa, pd, rv, fn, ax, dr = geo
    cnt = 0
    for k in range(pv[i], pv[i + 1]):
        z = zc + rv[k, 2]
        if z < alert:
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = rv[k, 0], rv[k, 1], rv[k, 2] - 0.5 * z
            gp[cnt] = z
            cnt += 1
    return cnt


@jit
def narrow_phase(position, kind, is_sphere, radius, geo, tab, half_start, half, axis_start, axis_support, pair_start,
                 pair_j, pair_axis, lx, ly, alert, reach, eps_f, max_points, prev_i, prev_j, prev_n, i0, i1):
    """Contact manifolds of the candidate pairs and wall pairs of the bodies ``i0 <= i < i1``.

    Rows are independent (a pair belongs to its row ``i``, the previous normals are looked up by
    ``(i, j)``), so disjoint row ranges may be computed by concurrent threads (the kernel releases
    the GIL) and their outputs concatenated in row order: the result is that of one call over all
    rows.

    Args:
        position: ``(N, 3)`` centres (x, y wrapped into the cell), d.
        kind: ``(N,)`` kind index; is_sphere, radius: ``(K,)`` per kind (radius in d).
        geo: :func:`world_geometry` output; tab: ``(vertex_start, face_start, face_offsets,
            face_vertex_start, face_vertices, edge_start, edges, edge_dir, kind)``.
        half_start, half: ``(K+1,)`` CSR over kinds of the local indices of one vertex of each
            antipodal pair for centrally symmetric polyhedra (empty block otherwise): the faster
            separating-axis test of :func:`_sat`.
        axis_start, axis_support: ``(K+1,)``, ``(NA,)`` the shape table's face-axis rows and the
            support ``max_v |a . v|`` of each kind along its own face axes ``a``, d.
        pair_start, pair_j: candidate pairs as CSR over ``i`` (``(N+1,)``, ``(C,)``), ``j > i``.
        pair_axis: ``(C,)`` per candidate pair of polyhedra, the code of the axis that separated
            it at the previous call (-1: none), read and updated (see :func:`_sat`).
        lx, ly: periods, d.
        alert: alert distance, d: the largest gap reported.
        reach: ``(N,)`` per body, d: pair ``(i, j)`` reports gaps up to ``min(alert, reach_i + reach_j)``,
            the wall pair of ``i`` up to ``min(alert, 2 reach_i)`` (``alert / 2`` everywhere: the
            one alert distance for every pair).
        eps_f: feature band / rank tolerance, d.
        max_points: scratch rows, at least the largest vertex count and twice the largest face
            size plus one.
        prev_i, prev_j, prev_n: previous step's pairs (``i < j``, sorted by ``(i, j)``) and
            normals ``(Q, 3)``, for the temporal axis hysteresis of :func:`poly_poly`.
        i0, i1: the rows computed (``0, N`` for all); ``pair_axis`` is written in these rows only.

    Returns:
        ``(body_i, body_j, shift, normal, ctype, point_start, point, gap, n_tested)``: the
        :class:`~granpack.contact.contacts.ContactSet` arrays, ordered by ``i`` then ``j`` (the
        wall, ``j = -1``, first), and the number of pairs whose bounding spheres overlap within
        ``alert`` (narrow-phase tests).
    """
    cap = pair_start[i1] - pair_start[i0] + (i1 - i0)
    body_i = np.empty(cap, np.int64)
    body_j = np.empty(cap, np.int64)
    shift = np.empty((cap, 3))
    normal = np.empty((cap, 3))
    ctype = np.empty(cap, np.int64)
    pstart = np.zeros(cap + 1, np.int64)
    point = np.empty((max_points * cap, 3))
    gap = np.empty(max_points * cap)
    scr = (np.empty((4, 3)), np.empty(4, np.int64), np.empty(4, np.int64), np.empty(4), np.empty(4),
           np.empty(4, np.int64), np.empty((max_points, 3)), np.empty((max_points, 3)), np.empty((3, 2 * max_points)),
           np.empty(2 * max_points))
    one = np.zeros((1, 3))
    pv, pa, pd, rv, ax, dr = geo[0], geo[2], geo[3], geo[4], geo[6], geo[7]
    X = scr[8]
    Y = np.empty((3, 2 * max_points))
    pts = np.empty((max_points, 3))
    gp = np.empty(max_points)
    eps_pt = 1e-3 * eps_f
    # radius of the largest centred ball inside each polyhedron kind (edge-axis pruning in _sat)
    face_start, face_offsets = tab[1], tab[2]
    inradius = np.zeros(len(radius))
    for k in range(len(radius)):
        if face_start[k + 1] > face_start[k]:
            inradius[k] = face_offsets[face_start[k]:face_start[k + 1]].min()
    m = 0
    npt = 0
    tested = 0
    nprev = len(prev_i)
    pp = np.searchsorted(prev_i, i0)
    for i in range(i0, i1):
        ki = kind[i]
        xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
        ri = radius[ki]
        aw = min(alert, 2.0 * reach[i])
        if zi - ri < aw:
            if is_sphere[ki]:
                cnt = 0
                g = zi - ri
                if g < aw:
                    pts[0, 0], pts[0, 1], pts[0, 2] = 0.0, 0.0, 0.5 * g - zi
                    gp[0] = g
                    cnt = 1
            else:
                cnt = _poly_wall(i, zi, geo, aw, pts, gp)
            if cnt > 0:
                cnt = _merge_points(pts, gp, cnt, eps_pt)
                body_i[m], body_j[m] = i, -1
                shift[m, 0], shift[m, 1], shift[m, 2] = 0.0, 0.0, 0.0
                normal[m, 0], normal[m, 1], normal[m, 2] = 0.0, 0.0, 1.0
                ctype[m] = manifold_type_nb(pts, cnt, 0.0, 0.0, 1.0, eps_f)
                for k in range(cnt):
                    point[npt, 0], point[npt, 1], point[npt, 2] = xi + pts[k, 0], yi + pts[k, 1], zi + pts[k, 2]
                    gap[npt] = gp[k]
                    npt += 1
                m += 1
                pstart[m] = npt
        for q in range(pair_start[i], pair_start[i + 1]):
            j = pair_j[q]
            kj = kind[j]
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
            if is_sphere[ki] and is_sphere[kj]:
                d = math.sqrt(ox * ox + oy * oy + oz * oz)
                g = d - ri - radius[kj]
                if g > a:
                    continue
                if d > 0.0:
                    nx, ny, nz = ox / d, oy / d, oz / d
                else:
                    nx, ny, nz = 0.0, 0.0, 1.0
                c = radius[kj] + 0.5 * g
                pts[0, 0], pts[0, 1], pts[0, 2] = c * nx, c * ny, c * nz
                gp[0] = g
                cnt = 1
            elif is_sphere[kj]:
                cnt, nx, ny, nz = _sphere_poly(radius[kj], i, ox, oy, oz, geo, tab, a, scr, one, pts, gp)
            elif is_sphere[ki]:
                cnt, nx, ny, nz = _poly_sphere(j, ri, ox, oy, oz, geo, tab, a, scr, one, pts, gp)
            else:
                sat = _sat(rv, pv[j], pv[j + 1], pv[i], pv[i + 1], ax, pa[j], pa[j + 1], pa[i], pa[i + 1], dr, pd[j],
                           pd[j + 1], pd[i], pd[i + 1], half_start, half, axis_start, axis_support, kj, ki, ox, oy,
                           oz, a, inradius[kj] + inradius[ki], _KEEP_BAND * eps_f, X, Y, pair_axis[q])
                pair_axis[q] = sat[13]
                if sat[0]:
                    continue
                while pp < nprev and (prev_i[pp] < i or (prev_i[pp] == i and prev_j[pp] < j)):
                    pp += 1
                if pp < nprev and prev_i[pp] == i and prev_j[pp] == j:
                    hx, hy, hz = prev_n[pp, 0], prev_n[pp, 1], prev_n[pp, 2]
                else:
                    hx, hy, hz = 0.0, 0.0, 0.0
                cnt, nx, ny, nz = poly_poly(j, i, ox, oy, oz, hx, hy, hz, sat[1:13], geo, tab, a, eps_f, scr, pts, gp)
            if cnt == 0:
                continue
            cnt = _merge_points(pts, gp, cnt, eps_pt)
            body_i[m], body_j[m] = i, j
            shift[m, 0], shift[m, 1], shift[m, 2] = sx, sy, 0.0
            normal[m, 0], normal[m, 1], normal[m, 2] = nx, ny, nz
            ctype[m] = manifold_type_nb(pts, cnt, nx, ny, nz, eps_f)
            cx, cy, cz = position[j, 0] + sx, position[j, 1] + sy, position[j, 2]
            for k in range(cnt):
                point[npt, 0], point[npt, 1], point[npt, 2] = cx + pts[k, 0], cy + pts[k, 1], cz + pts[k, 2]
                gap[npt] = gp[k]
                npt += 1
            m += 1
            pstart[m] = npt
    return (body_i[:m].copy(), body_j[:m].copy(), shift[:m].copy(), normal[:m].copy(), ctype[:m].copy(),
            pstart[:m + 1].copy(), point[:npt].copy(), gap[:npt].copy(), tested)

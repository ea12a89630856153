"""Contact manifold of two polyhedra from their best separating axis: clipped faces, crossing edges, GJK.

Face axis: the incident face clipped against the side planes of the reference face (Sutherland-Hodgman);
edge axis: the closest points of the two edges; otherwise the exact closest points (GJK).
Every vertex of a clipped polygon is a point of its own: a grain resting on a face cannot rock about
some of them and sink the others (docs/design-notes.md, "Contact manifolds").
"""

from __future__ import annotations

import math

from granpack._numba import jit
from granpack.contact._gjk import gjk_distance
from granpack.contact.separating_axes import _interval

__all__: list[str] = []

#: cosine between ``n`` and the reference face's normal below which :func:`_clip_face` finds no
#: face: a face axis is one face's normal up to sign, and on a body that is not centrally
#: symmetric the other sign meets the body at a vertex or an edge, not at a face
_FACE_COS = 1.0 - 1e-9


@jit(inline="always")
def _incident_face(rvi, inc_v0, inc_v1, inc_f0, inc_f1, inc_fn, fvs, fverts, face_row_inc, nx, ny, nz, band, heights):
    """The incident face of a face axis ``n`` (from the reference body towards the incident one):
    the face (rows ``inc_f0:inc_f1``, world normals ``inc_fn``) that holds the most of the
    incident body's support vertices along ``-n`` (those within ``band``, d, of the deepest), and
    of those the one whose normal is most opposed to ``n``. ``heights`` (at least
    ``inc_v1 - inc_v0`` rows) is scratch for the vertices' heights along ``n``, d.

    Why not simply the face most opposed to ``n``: that face need not touch the reference face. An
    edge of a scanned grain lying across a face has its two faces tilted off ``-n``, and a third
    face holding one end of the edge may be more opposed; clipped, it missed the edge, the
    manifold fell back to one crossing of the edge, and the edge's other end, unconstrained, sank
    into the face (docs/design-notes.md, "Contact manifolds").
    """
    lowest = math.inf
    for v in range(inc_v0, inc_v1):
        hv = rvi[v, 0] * nx + rvi[v, 1] * ny + rvi[v, 2] * nz
        heights[v - inc_v0] = hv
        lowest = min(lowest, hv)
    top = lowest + band
    fi = inc_f0
    most = 0
    best = math.inf
    for f in range(inc_f0, inc_f1):
        row = face_row_inc + f - inc_f0
        held = 0
        for k in range(fvs[row], fvs[row + 1]):
            if heights[fverts[k]] <= top:
                held += 1
        d = inc_fn[f, 0] * nx + inc_fn[f, 1] * ny + inc_fn[f, 2] * nz
        if held > most or (held == most and d < best):
            most, best, fi = held, d, f
    return fi


@jit(inline="always")
def _clip_face(rv, ref_v0, ref_v1, rox, roy, roz, ref_f0, ref_f1, inc_v0, inc_v1, iox, ioy, ioz, inc_f0, inc_f1, fn,
               fvs, fverts, face_row_ref, face_row_inc, nx, ny, nz, alert, band, heights, buf, buf2, out, gout):
    """Clip the incident face against the reference face with outward normal ``n``.

    Both bodies are rows of the world vertices ``rv`` and face normals ``fn`` (one pair of arrays
    for both: CPython compiles a call of more than 30 arguments as ``f(*args)``, which Numba
    cannot inline). The reference body has vertices ``ro + rv[ref_v0:ref_v1]`` and faces
    ``fn[ref_f0:ref_f1]`` (global face rows of its kind start at ``face_row_ref``), the incident
    one ``io + rv[inc_v0:inc_v1]`` and ``fn[inc_f0:inc_f1]`` (``face_row_inc``); the
    reference face is the one whose normal is closest to ``n``. The incident body's face is the one
    that holds the most of its vertices within ``band`` of its deepest along ``-n``, the most
    opposed to ``n`` of those (:func:`_incident_face`). Lengths (offsets ``ro``, ``io``, vertex
    offsets, ``alert``, ``band``) in d, ``n`` a unit vector; ``heights``: scratch of at least the
    incident body's vertex count; ``buf``, ``buf2``: scratch rows, at least twice the largest face
    size plus one.

    Returns:
        ``(count, gmin)``: points written to ``out`` (position on the midpoint between the two
        surfaces) and their gaps ``gout`` (``n . p - delta_ref``), keeping gaps ``<= alert``;
        ``gmin`` is the smallest gap over all clipped points (``inf`` if the clip is empty).
    """
    # reference face: normal closest to n
    fr = ref_f0
    best = -math.inf
    for f in range(ref_f0, ref_f1):
        d = fn[f, 0] * nx + fn[f, 1] * ny + fn[f, 2] * nz
        if d > best:
            best, fr = d, f
    if best < _FACE_COS:
        return 0, math.inf  # n is a face axis of the other side of the body: no face here
    fi = _incident_face(rv, inc_v0, inc_v1, inc_f0, inc_f1, fn, fvs, fverts, face_row_inc, nx, ny, nz, band,
                        heights)
    _, delta = _interval(rv, ref_v0, ref_v1, rox, roy, roz, nx, ny, nz)
    row_i = face_row_inc + fi - inc_f0
    m = 0
    for k in range(fvs[row_i], fvs[row_i + 1]):
        v = inc_v0 + fverts[k]
        buf[m, 0] = iox + rv[v, 0]
        buf[m, 1] = ioy + rv[v, 1]
        buf[m, 2] = ioz + rv[v, 2]
        m += 1
    row_r = face_row_ref + fr - ref_f0
    r0, r1 = fvs[row_r], fvs[row_r + 1]
    nr = r1 - r0
    for e in range(nr):
        va = ref_v0 + fverts[r0 + e]
        vb = ref_v0 + fverts[r0 + (e + 1) % nr]
        ax_, ay_, az_ = rox + rv[va, 0], roy + rv[va, 1], roz + rv[va, 2]
        ex = rox + rv[vb, 0] - ax_
        ey = roy + rv[vb, 1] - ay_
        ez = roz + rv[vb, 2] - az_
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

    Returns the number of points written (1, at the midpoint of the two closest points, gap
    ``se``, the axis separation, d; or 0 when no such pair exists, e.g. when the closest features
    are not two crossing edges). Lengths in d; ``edges`` local vertex pairs, rows ``ea0:ea1`` of
    A's kind and ``eb0:eb1`` of B's.
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
    """Parameters ``(s, t)`` of the closest points of lines ``p1 + s d1`` and ``p2 + t d2`` (in
    units of ``|d1|``, ``|d2|``; ``s = 0`` when the lines are parallel)."""
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

    ``pts`` ``(>= cnt, 3)`` and ``eps_pt`` in d. No other point is dropped: every vertex of a
    clipped contact polygon is a constraint of its own (a point left out is free to sink when the
    grain rocks about the others, see :mod:`granpack.contact.narrowphase`).
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
    """Rows k in ``[v0, v1)`` with ``n . (o + rv[k]) >= top - band`` (``top``, ``band``, ``o``, ``rv``
    in d, ``n`` a unit vector); returns their count, the first two rows written to ``idx``."""
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

    A centred (vertex rows ``a0:a1`` of ``rv``), B at ``o`` (rows ``b0:b1``); lengths in d. Two
    points for parallel edges overlapping by more than ``eps_f``, else one at the midpoint of the
    closest points, gap the distance; ``scr``: the :class:`~granpack.contact.narrowphase.Scratch`.

    Returns ``(count, nx, ny, nz)``: points written to ``pts``/``gp`` and the unit normal from A
    to B; count 0 if the pair is farther than ``alert``, -1 if GJK finds the bodies touching or
    intersecting.
    """
    W, ia, ib, lam, tmp = scr.simplex, scr.simplex_a, scr.simplex_b, scr.weights, scr.face_weights
    idx = scr.band_rows
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
def _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, nx, ny, nz, sigma, from_a, band, pts, gp):
    """Points midway between the support vertices of B along -n (or of A along n, ``from_a``) and
    the other body's support plane: the deepest vertex, gap ``sigma`` (d), then every other vertex
    within ``band`` (d) of it, each with its own gap ``sigma`` plus its height above the deepest
    (at most ``len(pts)``); returns their number. With ``band`` > 0 an edge or a face lying in the
    other body's support plane gives a point at each of its ends or corners, not one of them: which
    one is deepest turns on the last digits of the heights, and a single point jumping between them
    from step to step rocks the grain under it for ever. Frame and units as :func:`_gjk_manifold`."""
    sign = 1.0 if from_a else -1.0
    lo, hi = (a0, a1) if from_a else (b0, b1)
    sx, sy, sz = (0.0, 0.0, 0.0) if from_a else (ox, oy, oz)
    best = -math.inf
    k0 = lo
    for k in range(lo, hi):
        h = sign * (nx * (sx + rv[k, 0]) + ny * (sy + rv[k, 1]) + nz * (sz + rv[k, 2]))
        if h > best:
            best, k0 = h, k
    pts[0, 0] = sx + rv[k0, 0] + sign * 0.5 * sigma * nx
    pts[0, 1] = sy + rv[k0, 1] + sign * 0.5 * sigma * ny
    pts[0, 2] = sz + rv[k0, 2] + sign * 0.5 * sigma * nz
    gp[0] = sigma
    cnt = 1
    if band > 0.0:
        for k in range(lo, hi):
            if cnt == pts.shape[0]:
                break
            if k == k0:
                continue
            below = best - sign * (nx * (sx + rv[k, 0]) + ny * (sy + rv[k, 1]) + nz * (sz + rv[k, 2]))
            if below <= band:
                g = sigma + below
                pts[cnt, 0] = sx + rv[k, 0] + sign * 0.5 * g * nx
                pts[cnt, 1] = sy + rv[k, 1] + sign * 0.5 * g * ny
                pts[cnt, 2] = sz + rv[k, 2] + sign * 0.5 * g * nz
                gp[cnt] = g
                cnt += 1
    return cnt


@jit(inline="always")
def _clamp_gaps(gp, cnt, floor):
    """Raise the first ``cnt`` gaps to at least ``floor`` (d); returns the smallest, d."""
    low = math.inf
    for k in range(cnt):
        if gp[k] < floor:
            gp[k] = floor
        low = min(low, gp[k])
    return low


@jit
def _deepest_feature(rv, a0, a1, b0, b1, ox, oy, oz, sfa, sfb, se, gfa, kfa, gfb, kfb, ex, ey, ez, ax, ea0, ea1, eb0,
                     eb1, edges, X, h, pts, gp):
    """The point where the best separating axis finds the bodies deepest, in ``pts[0]``, ``gp[0]``
    (frame and units as :func:`_gjk_manifold`): the other body's support vertex below the best face
    axis's face (``sfa``: A's face, normal ``gfa ax[kfa]``; ``sfb``: B's), or the crossing of the
    best edge axis (``se``, normal ``e``); its gap is that axis's separation. Returns 1, or 0 if
    the edge axis gives no crossing.

    Why: a manifold built on another axis that the hysteresis keeps (a fraction of a degree away)
    clips one face against the other, and the vertex that is deepest along the best axis may belong
    to neither face; without a point there, nothing stops it sinking further, step after step.
    """
    if se >= sfa and se >= sfb:
        if _edge_contact(rv, a0, a1, b0, b1, ox, oy, oz, ea0, ea1, eb0, eb1, edges, ex, ey, ez, se, X, h, pts, gp) == 1:
            _clamp_gaps(gp, 1, se)
            return 1
        return 0
    if sfa >= sfb:
        return _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, gfa * ax[kfa, 0], gfa * ax[kfa, 1], gfa * ax[kfa, 2], sfa,
                              False, 0.0, pts, gp)
    return _deepest_point(rv, a0, a1, b0, b1, ox, oy, oz, gfb * ax[kfb, 0], gfb * ax[kfb, 1], gfb * ax[kfb, 2], sfb,
                          True, 0.0, pts, gp)


@jit(inline="always")
def _apart(pts, cnt, eps):
    """Whether ``pts[cnt]`` is farther than ``eps`` (d) from each of ``pts[:cnt]``."""
    for k in range(cnt):
        dx, dy, dz = pts[cnt, 0] - pts[k, 0], pts[cnt, 1] - pts[k, 1], pts[cnt, 2] - pts[k, 2]
        if dx * dx + dy * dy + dz * dz <= eps * eps:
            return False
    return True

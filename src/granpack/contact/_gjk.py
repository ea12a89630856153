"""Gilbert-Johnson-Keerthi distance between two convex vertex sets (Numba kernels).

Used by the narrow phase where the separating-axis test only gives a lower bound of the distance
(closest features vertex-vertex, vertex-edge or parallel edges) and for sphere-polyhedron pairs
(a sphere centre is a one-point set). Both sets are given as rows of ``(n, 3)`` arrays plus an
offset added to the second set, so that the caller can work in a frame centred on the first body.

The closest point of the current simplex to the origin uses the Voronoi-region formulas of
Ericson, *Real-Time Collision Detection* (2005), §5.1; the loop stops when the support point
brings no improvement (Gilbert, Johnson & Keerthi 1988; van den Bergen 2003, §4.3), which for
polytopes is an exact finite termination up to rounding.
"""

from __future__ import annotations

import math


from granpack._numba import jit

__all__ = ["gjk_distance"]


@jit
def _segment(W, lam, i0, i1):
    """Closest point of segment ``W[i0] W[i1]`` to the origin; writes ``lam[i0], lam[i1]``."""
    ex = W[i1, 0] - W[i0, 0]
    ey = W[i1, 1] - W[i0, 1]
    ez = W[i1, 2] - W[i0, 2]
    ee = ex * ex + ey * ey + ez * ez
    t = 0.0
    if ee > 0.0:
        t = -(W[i0, 0] * ex + W[i0, 1] * ey + W[i0, 2] * ez) / ee
        t = min(1.0, max(0.0, t))
    lam[i0] = 1.0 - t
    lam[i1] = t
    px = W[i0, 0] + t * ex
    py = W[i0, 1] + t * ey
    pz = W[i0, 2] + t * ez
    return px * px + py * py + pz * pz


@jit
def _triangle(W, lam, ia, ib, ic):
    """Closest point of triangle ``W[ia] W[ib] W[ic]`` to the origin (Ericson §5.1.5).

    Writes the barycentric coordinates into ``lam[ia], lam[ib], lam[ic]`` and returns the
    squared distance. Degenerate (flat) triangles fall back to their best edge.
    """
    ax, ay, az = W[ia, 0], W[ia, 1], W[ia, 2]
    abx, aby, abz = W[ib, 0] - ax, W[ib, 1] - ay, W[ib, 2] - az
    acx, acy, acz = W[ic, 0] - ax, W[ic, 1] - ay, W[ic, 2] - az
    lam[ia] = 0.0
    lam[ib] = 0.0
    lam[ic] = 0.0
    d1 = -(abx * ax + aby * ay + abz * az)
    d2 = -(acx * ax + acy * ay + acz * az)
    if d1 <= 0.0 and d2 <= 0.0:
        lam[ia] = 1.0
        return ax * ax + ay * ay + az * az
    bx, by, bz = W[ib, 0], W[ib, 1], W[ib, 2]
    d3 = -(abx * bx + aby * by + abz * bz)
    d4 = -(acx * bx + acy * by + acz * bz)
    if d3 >= 0.0 and d4 <= d3:
        lam[ib] = 1.0
        return bx * bx + by * by + bz * bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0 and d1 - d3 > 0.0:
        return _segment(W, lam, ia, ib)
    cx, cy, cz = W[ic, 0], W[ic, 1], W[ic, 2]
    d5 = -(abx * cx + aby * cy + abz * cz)
    d6 = -(acx * cx + acy * cy + acz * cz)
    if d6 >= 0.0 and d5 <= d6:
        lam[ic] = 1.0
        return cx * cx + cy * cy + cz * cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0 and d2 - d6 > 0.0:
        return _segment(W, lam, ia, ic)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0 and (d4 - d3) + (d5 - d6) > 0.0:
        return _segment(W, lam, ib, ic)
    denom = va + vb + vc
    if not denom > 0.0:
        # flat triangle: the closest point lies on one of its edges
        l0, l1, l2 = 0.0, 0.0, 0.0
        best = _segment(W, lam, ia, ib)
        l0, l1 = lam[ia], lam[ib]
        dd = _segment(W, lam, ib, ic)
        if dd < best:
            best = dd
            l0, l1, l2 = 0.0, lam[ib], lam[ic]
        dd = _segment(W, lam, ia, ic)
        if dd < best:
            best = dd
            l0, l1, l2 = lam[ia], 0.0, lam[ic]
        lam[ia], lam[ib], lam[ic] = l0, l1, l2
        return best
    v = vb / denom
    w = vc / denom
    lam[ia] = 1.0 - v - w
    lam[ib] = v
    lam[ic] = w
    px = ax + abx * v + acx * w
    py = ay + aby * v + acy * w
    pz = az + abz * v + acz * w
    return px * px + py * py + pz * pz


@jit
def _outside(W, ia, ib, ic, io):
    """True if the origin is not strictly on the side of face (ia, ib, ic) where ``W[io]`` is."""
    ax, ay, az = W[ia, 0], W[ia, 1], W[ia, 2]
    abx, aby, abz = W[ib, 0] - ax, W[ib, 1] - ay, W[ib, 2] - az
    acx, acy, acz = W[ic, 0] - ax, W[ic, 1] - ay, W[ic, 2] - az
    nx = aby * acz - abz * acy
    ny = abz * acx - abx * acz
    nz = abx * acy - aby * acx
    sp = -(ax * nx + ay * ny + az * nz)
    sd = (W[io, 0] - ax) * nx + (W[io, 1] - ay) * ny + (W[io, 2] - az) * nz
    return sp * sd <= 0.0


@jit
def _tetrahedron(W, lam, tmp):
    """Closest point of tetrahedron ``W[0:4]`` to the origin; ``-1.0`` if the origin is inside."""
    best = -1.0
    faces = ((0, 1, 2, 3), (0, 1, 3, 2), (0, 2, 3, 1), (1, 2, 3, 0))
    for f in faces:
        if _outside(W, f[0], f[1], f[2], f[3]):
            for k in range(4):
                tmp[k] = 0.0
            dd = _triangle(W, tmp, f[0], f[1], f[2])
            if best < 0.0 or dd < best:
                best = dd
                for k in range(4):
                    lam[k] = tmp[k]
    return best


@jit
def _support(rv, v0, v1, ox, oy, oz, dx, dy, dz):
    """Index of the vertex ``o + rv[k]`` (k in [v0, v1)) maximising the dot product with d."""
    best = v0
    bestval = -math.inf
    for k in range(v0, v1):
        val = dx * (ox + rv[k, 0]) + dy * (oy + rv[k, 1]) + dz * (oz + rv[k, 2])
        if val > bestval:
            bestval = val
            best = k
    return best


@jit
def gjk_distance(rva, a0, a1, rvb, b0, b1, ox, oy, oz, cutoff, W, ia, ib, lam, tmp):
    """Euclidean distance between the convex hulls of two vertex sets.

    Set A is ``rva[a0:a1]`` (as given), set B is ``(ox, oy, oz) + rvb[b0:b1]``.

    Args:
        rva, rvb: ``(n, 3)`` vertex arrays, d.
        a0, a1, b0, b1: row ranges of the two sets.
        ox, oy, oz: offset added to the rows of B, d.
        cutoff: stop early (returning ``status = 1``) once the distance is proven larger, d.
        W: ``(4, 3)`` scratch; ia, ib: ``(4,)`` int64 scratch; lam, tmp: ``(4,)`` scratch.

    Returns:
        ``(status, dist, px, py, pz, qx, qy, qz)``: status 0 = separated (``p`` in A and ``q`` in
        B are the closest points, ``dist = |q - p|``), 1 = farther than ``cutoff`` (other values
        meaningless), 2 = intersecting or touching (``dist = 0``).
    """
    vx = rva[a0, 0] - (ox + rvb[b0, 0])
    vy = rva[a0, 1] - (oy + rvb[b0, 1])
    vz = rva[a0, 2] - (oz + rvb[b0, 2])
    W[0, 0], W[0, 1], W[0, 2] = vx, vy, vz
    ia[0] = a0
    ib[0] = b0
    lam[0] = 1.0
    n = 1
    cut2 = cutoff * cutoff
    for _ in range(64):
        ka = _support(rva, a0, a1, 0.0, 0.0, 0.0, -vx, -vy, -vz)
        kb = _support(rvb, b0, b1, ox, oy, oz, vx, vy, vz)
        wx = rva[ka, 0] - (ox + rvb[kb, 0])
        wy = rva[ka, 1] - (oy + rvb[kb, 1])
        wz = rva[ka, 2] - (oz + rvb[kb, 2])
        vv = vx * vx + vy * vy + vz * vz
        vw = vx * wx + vy * wy + vz * wz
        if vw > 0.0 and vw * vw > cut2 * vv:
            return 1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        dup = False
        for k in range(n):
            if ia[k] == ka and ib[k] == kb:
                dup = True
        if dup or vv - vw <= 1e-13 * vv:
            break
        W[n, 0], W[n, 1], W[n, 2] = wx, wy, wz
        ia[n] = ka
        ib[n] = kb
        n += 1
        if n == 1:
            lam[0] = 1.0
            dd = wx * wx + wy * wy + wz * wz
        elif n == 2:
            dd = _segment(W, lam, 0, 1)
        elif n == 3:
            dd = _triangle(W, lam, 0, 1, 2)
        else:
            dd = _tetrahedron(W, lam, tmp)
            if dd < 0.0:
                return 2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        # keep the support points with non-zero weight
        m = 0
        for k in range(n):
            if lam[k] > 0.0:
                W[m, 0], W[m, 1], W[m, 2] = W[k, 0], W[k, 1], W[k, 2]
                ia[m] = ia[k]
                ib[m] = ib[k]
                lam[m] = lam[k]
                m += 1
        n = m
        vx, vy, vz = 0.0, 0.0, 0.0
        for k in range(n):
            vx += lam[k] * W[k, 0]
            vy += lam[k] * W[k, 1]
            vz += lam[k] * W[k, 2]
        if dd <= 1e-30 or vx * vx + vy * vy + vz * vz <= 1e-30:
            return 2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    px, py, pz, qx, qy, qz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n):
        px += lam[k] * rva[ia[k], 0]
        py += lam[k] * rva[ia[k], 1]
        pz += lam[k] * rva[ia[k], 2]
        qx += lam[k] * (ox + rvb[ib[k], 0])
        qy += lam[k] * (oy + rvb[ib[k], 1])
        qz += lam[k] * (oz + rvb[ib[k], 2])
    dist = math.sqrt((qx - px) ** 2 + (qy - py) ** 2 + (qz - pz) ** 2)
    if not dist > 0.0:
        return 2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return 0, dist, px, py, pz, qx, qy, qz

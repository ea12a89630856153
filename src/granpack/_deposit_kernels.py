"""Numba kernels of the geometric sequential deposition (private; the API is :mod:`granpack.deposit`).

Geometry used by every kernel here:

* The centre ``p`` of the sphere being placed (radius ``R``) is constrained by *supports*. A
  sphere support is one periodic image of a deposited sphere ``j``: centre ``c`` (image shift
  included) and contact distance ``D = R + R_j``; the constraint is ``|p - c| >= D`` and its unit
  normal at contact is ``n = (p - c) / D``. A plane support has a unit normal ``n`` pointing into
  the admissible region and an offset ``h``; the constraint is ``n . p >= h``. Plane ids:
  ``FLOOR`` (``z >= R``), ``X_LO`` (``x >= R``), ``X_HI`` (``x <= L - R``), ``Y_LO``, ``Y_HI``.
* Every motion of ``p`` is a vertical segment ``p0 - t e_z`` or a circular arc

  .. math:: p(t) = c_c + r (\\cos t\\, f_1 + \\sin t\\, f_2), \\qquad f_1 \\perp f_2,

  on which the gap to a sphere (as ``|p - c|^2 - D^2``) and to a plane (as ``n . p - h``) both
  read ``A + B cos t + C sin t``: first contacts along an arc are computed in closed form (the
  downward zero crossing of a sinusoid), so no step size or bisection tolerance enters.
* Gravity is ``-e_z``; a set of touching supports holds the sphere iff
  ``e_z = sum_k lambda_k n_k`` with all ``lambda_k >= 0`` (the supports' reactions balance the
  weight). The quasi-static steepest descent keeps exactly the supports of the non-negative least
  squares solution of that equation (:func:`_active_set`) and moves along the constraint manifold
  they leave free (fall, roll on a sphere, roll on the circle of two supports); a support is
  released where its multiplier, linear in the height along the circle, crosses zero.
* Deposited spheres are binned in a cell grid (``nx * ny`` lateral cells of side ``hxy >= 2 R_max``,
  ``nz`` layers of height ``hz``; the top layer also holds everything above). Periodic images are
  found by walking unwrapped cell indices and carrying the shift ``(kx L, ky L)``.
"""

from __future__ import annotations

import math

import numpy as np

from granpack._numba import jit

FLOOR = -1
X_LO = -2
X_HI = -3
Y_LO = -4
Y_HI = -5

EPS_T = 1e-9  # motion parameter (rad, or length / d for falls) below which a released support is ignored
LAMBDA_TOL = 1e-12  # multipliers at or below this are inactive
STABLE_TOL = 1e-9  # |e_z - sum lambda n| below this: the sphere is held
OVERLAP_TOL = 1e-9  # accepted overlap, in d
CONTACT_TOL = 1e-9  # gap (in d) counted as a geometric contact (LMGC90 reference bookkeeping)
MAX_MOTIONS = 2000  # motions of one drop before the attempt is abandoned
MAX_ATTEMPTS = 1000  # attempts (random (x, y)) per sphere before the deposit fails
LMGC_REFERENCES = 100  # most recent spheres that may serve as first support (LMGC90 n_actif)
LMGC_MAX_CONTACTS = 8  # a sphere with this many contacts stops being a reference

STATUS_DONE = 0
STATUS_NEED_UNIFORMS = 1
STATUS_FAILED = 2
STATUS_BUFFER = 3


@jit
def _cell(v, h, n):
    """Index of the cell of coordinate ``v`` in cells of size ``h``, clamped to ``[0, n)``."""
    i = int(math.floor(v / h))
    if i < 0:
        return 0
    if i >= n:
        return n - 1
    return i


@jit
def grid_insert(i, pos, head, nxt, nx, ny, nz, hxy, hz):
    """Push sphere ``i`` (wrapped centre ``pos[i]``) on the linked list of its cell."""
    c = (_cell(pos[i, 2], hz, nz) * ny + _cell(pos[i, 1], hxy, ny)) * nx + _cell(pos[i, 0], hxy, nx)
    nxt[i] = head[c]
    head[c] = i


@jit
def grid_build(pos, n, head, nxt, nx, ny, nz, hxy, hz):
    """Bin spheres ``0 .. n-1`` into a fresh grid (``head`` of size ``nx*ny*nz``)."""
    head[:] = -1
    for i in range(n):
        grid_insert(i, pos, head, nxt, nx, ny, nz, hxy, hz)


@jit
def _gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k):
    """Sphere images whose centre lies in the box ``[lo, hi]`` (unwrapped coordinates).

    Returns the count ``m`` (``out_i[:m]`` indices, ``out_k[:m]`` integer image shifts
    ``(kx, ky)``), or -1 if the buffers are too small.
    """
    if periodic:
        ix0 = int(math.floor(lo[0] / hxy))
        ix1 = int(math.floor(hi[0] / hxy))
        iy0 = int(math.floor(lo[1] / hxy))
        iy1 = int(math.floor(hi[1] / hxy))
    else:
        ix0 = _cell(lo[0], hxy, nx)
        ix1 = _cell(hi[0], hxy, nx)
        iy0 = _cell(lo[1], hxy, ny)
        iy1 = _cell(hi[1], hxy, ny)
    iz0 = _cell(lo[2], hz, nz)
    iz1 = _cell(hi[2], hz, nz)
    m = 0
    cap = out_i.shape[0]
    for iz in range(iz0, iz1 + 1):
        for iy in range(iy0, iy1 + 1):
            ky = iy // ny
            wy = iy - ky * ny
            for ix in range(ix0, ix1 + 1):
                kx = ix // nx
                wx = ix - kx * nx
                j = head[(iz * ny + wy) * nx + wx]
                while j >= 0:
                    x = pos[j, 0] + kx * lsize
                    y = pos[j, 1] + ky * lsize
                    z = pos[j, 2]
                    if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]:
                        if m == cap:
                            return -1
                        out_i[m] = j
                        out_k[m, 0] = kx
                        out_k[m, 1] = ky
                        m += 1
                    j = nxt[j]
    return m


@jit
def _plane(pid, radius, lsize, out):
    """Unit inward normal (``out[:3]``) and offset (``out[3]``) of plane ``pid`` for radius ``R``."""
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if pid == FLOOR:
        out[2] = 1.0
        out[3] = radius
    elif pid == X_LO:
        out[0] = 1.0
        out[3] = radius
    elif pid == X_HI:
        out[0] = -1.0
        out[3] = radius - lsize
    elif pid == Y_LO:
        out[1] = 1.0
        out[3] = radius
    else:
        out[1] = -1.0
        out[3] = radius - lsize


@jit
def _first_entry(a, b, c, lower, upper):
    """First downward zero crossing of ``g(t) = a + b cos t + c sin t`` with ``lower <= t <= upper``.

    ``g`` enters negative values at ``t = atan2(c, b) + acos(-a / hypot(b, c))`` (mod 2 pi), where
    ``g' < 0``; returns that ``t`` (clamped to >= 0) or ``inf`` if it is outside the window or
    ``g`` never changes sign.
    """
    m = math.hypot(b, c)
    if m <= 0.0:
        return math.inf
    q = -a / m
    if q <= -1.0 or q >= 1.0:
        return math.inf
    t = math.atan2(c, b) + math.acos(q)
    if t > math.pi:
        t -= 2.0 * math.pi
    if t < lower or t > upper:
        return math.inf
    return max(t, 0.0)


@jit
def _active_set(nrm, m, skip):
    """Non-negative least squares ``min |e_z - sum_k lambda_k n_k|``, ``lambda >= 0``, for m <= 4.

    Enumerates the subsets of at most three normals (rows of ``nrm``; ``skip`` >= 0 excludes one),
    solves each exactly, keeps those with all ``lambda > LAMBDA_TOL`` and returns the bit mask of
    the one with the smallest residual and that residual (the empty set has residual 1, a free
    fall). The minimiser over these subsets is the NNLS solution, whose active set defines the
    steepest feasible descent ``v = -(e_z - sum lambda n)``.
    """
    best_mask = 0
    best_res = 1.0
    for mask in range(1, 1 << m):
        if skip >= 0 and (mask >> skip) & 1:
            continue
        i0 = -1
        i1 = -1
        i2 = -1
        k = 0
        for s in range(m):
            if (mask >> s) & 1:
                if k == 0:
                    i0 = s
                elif k == 1:
                    i1 = s
                elif k == 2:
                    i2 = s
                k += 1
        if k > 3:
            continue
        l0 = 0.0
        l1 = 0.0
        l2 = 0.0
        if k == 1:
            l0 = nrm[i0, 2]
            if l0 <= LAMBDA_TOL:
                continue
        elif k == 2:
            cs = nrm[i0, 0] * nrm[i1, 0] + nrm[i0, 1] * nrm[i1, 1] + nrm[i0, 2] * nrm[i1, 2]
            det = 1.0 - cs * cs
            if det < 1e-14:
                continue
            l0 = (nrm[i0, 2] - cs * nrm[i1, 2]) / det
            l1 = (nrm[i1, 2] - cs * nrm[i0, 2]) / det
            if l0 <= LAMBDA_TOL or l1 <= LAMBDA_TOL:
                continue
        else:
            # Cramer: lambda_a = e_z . (n_b x n_c) / det(n_0, n_1, n_2)
            c12 = nrm[i1, 0] * nrm[i2, 1] - nrm[i1, 1] * nrm[i2, 0]
            c20 = nrm[i2, 0] * nrm[i0, 1] - nrm[i2, 1] * nrm[i0, 0]
            c01 = nrm[i0, 0] * nrm[i1, 1] - nrm[i0, 1] * nrm[i1, 0]
            det = (
                nrm[i0, 0] * (nrm[i1, 1] * nrm[i2, 2] - nrm[i1, 2] * nrm[i2, 1])
                + nrm[i0, 1] * (nrm[i1, 2] * nrm[i2, 0] - nrm[i1, 0] * nrm[i2, 2])
                + nrm[i0, 2] * c12
            )
            if abs(det) < 1e-12:
                continue
            l0 = c12 / det
            l1 = c20 / det
            l2 = c01 / det
            if l0 <= LAMBDA_TOL or l1 <= LAMBDA_TOL or l2 <= LAMBDA_TOL:
                continue
        rx = -l0 * nrm[i0, 0]
        ry = -l0 * nrm[i0, 1]
        rz = 1.0 - l0 * nrm[i0, 2]
        if k >= 2:
            rx -= l1 * nrm[i1, 0]
            ry -= l1 * nrm[i1, 1]
            rz -= l1 * nrm[i1, 2]
        if k == 3:
            rx -= l2 * nrm[i2, 0]
            ry -= l2 * nrm[i2, 1]
            rz -= l2 * nrm[i2, 2]
        res = math.sqrt(rx * rx + ry * ry + rz * rz)
        if res < best_res:
            best_res = res
            best_mask = mask
    return best_mask, best_res


@jit
def _circle(c1, d1, kind2, c2, v2, circ):
    """Circle of centres touching sphere support 1 and support 2 (sphere or plane).

    Sphere 2 (centre ``c2``, distance ``v2``): with ``d = |c2 - c1|``, ``u = (c2 - c1) / d``,
    ``alpha_1 = (D_1^2 - D_2^2 + d^2) / (2 d)``. Plane 2 (normal ``c2``, offset ``v2``): ``u = n``,
    ``alpha_1 = h - n . c1``. Then the centre is ``c_c = c1 + alpha_1 u``, the radius
    ``r = sqrt(D_1^2 - alpha_1^2)``, and on the circle the support normals are
    ``n_k = A_k u + B_k rhat`` (``rhat`` the unit radius vector).

    Writes ``circ = (c_c[3], u[3], r, A_1, B_1, A_2, B_2)``; returns False if the circle is
    empty or degenerate (``r`` below ``1e-12 D_1``).
    """
    if kind2 == 0:
        dx = c2[0] - c1[0]
        dy = c2[1] - c1[1]
        dz = c2[2] - c1[2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        if d <= 0.0:
            return False
        ux = dx / d
        uy = dy / d
        uz = dz / d
        al1 = (d1 * d1 - v2 * v2 + d * d) / (2.0 * d)
    else:
        ux = c2[0]
        uy = c2[1]
        uz = c2[2]
        al1 = v2 - (ux * c1[0] + uy * c1[1] + uz * c1[2])
    r2 = d1 * d1 - al1 * al1
    if r2 <= (1e-12 * d1) ** 2:
        return False
    r = math.sqrt(r2)
    circ[0] = c1[0] + al1 * ux
    circ[1] = c1[1] + al1 * uy
    circ[2] = c1[2] + al1 * uz
    circ[3] = ux
    circ[4] = uy
    circ[5] = uz
    circ[6] = r
    circ[7] = al1 / d1
    circ[8] = r / d1
    if kind2 == 0:
        circ[9] = (al1 - d) / v2
        circ[10] = r / v2
    else:
        circ[9] = 1.0
        circ[10] = 0.0
    return True


@jit
def _support_status(sid, skx, sky, sact, ns, ident, kx, ky):
    """-1 if ``(ident, kx, ky)`` is not a support, 1 if an active one, 0 if an inactive one."""
    for s in range(ns):
        if sid[s] == ident and skx[s] == kx and sky[s] == ky:
            return 1 if sact[s] else 0
    return -1


@jit
def _arc_first_contact(
    radius, cc, rc, f1, f2, tmax, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
    sid, skx, sky, sact, ns, out_i, out_k, pl, lo, hi, hit,
):
    """First contact along the arc ``cc + rc (cos t f1 + sin t f2)``, ``0 <= t <= tmax``.

    Candidates are the sphere images in the bounding box of the arc grown by ``R + R_max`` and the
    planes; active supports are skipped and inactive (just released) ones only count after
    ``t > EPS_T``. Writes ``hit = (id, kx, ky)`` (``id`` = -100 if none) and returns the contact
    parameter (``tmax`` if none) or -1.0 if the candidate buffers overflowed.
    """
    reach = radius + rmax
    for a in range(3):
        # extremes of cc_a + rc (f1_a cos t + f2_a sin t) over [0, tmax]
        v0 = cc[a] + rc * f1[a]
        v1 = cc[a] + rc * (f1[a] * math.cos(tmax) + f2[a] * math.sin(tmax))
        vmin = min(v0, v1)
        vmax = max(v0, v1)
        amp = math.hypot(f1[a], f2[a])
        if amp > 0.0:
            tm = math.atan2(f2[a], f1[a])
            for tt in (tm, tm + math.pi, tm - math.pi, tm + 2.0 * math.pi):
                if 0.0 < tt < tmax:
                    v = cc[a] + rc * (f1[a] * math.cos(tt) + f2[a] * math.sin(tt))
                    vmin = min(vmin, v)
                    vmax = max(vmax, v)
        lo[a] = vmin - reach
        hi[a] = vmax + reach
    m = _gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
    if m < 0:
        return -1.0
    best = tmax
    hit[0] = -100
    for q in range(m):
        j = out_i[q]
        kx = out_k[q, 0]
        ky = out_k[q, 1]
        st = _support_status(sid, skx, sky, sact, ns, j, kx, ky)
        if st == 1:
            continue
        lower = EPS_T if st == 0 else -EPS_T
        wx = cc[0] - (pos[j, 0] + kx * lsize)
        wy = cc[1] - (pos[j, 1] + ky * lsize)
        wz = cc[2] - pos[j, 2]
        dd = radius + rad[j]
        a = wx * wx + wy * wy + wz * wz + rc * rc - dd * dd
        b = 2.0 * rc * (wx * f1[0] + wy * f1[1] + wz * f1[2])
        c = 2.0 * rc * (wx * f2[0] + wy * f2[1] + wz * f2[2])
        t = _first_entry(a, b, c, lower, best)
        if t < best:
            best = t
            hit[0] = j
            hit[1] = kx
            hit[2] = ky
    npl = 1 if periodic else 5
    for q in range(npl):
        pid = -1 - q
        st = _support_status(sid, skx, sky, sact, ns, pid, 0, 0)
        if st == 1:
            continue
        lower = EPS_T if st == 0 else -EPS_T
        _plane(pid, radius, lsize, pl)
        a = pl[0] * cc[0] + pl[1] * cc[1] + pl[2] * cc[2] - pl[3]
        b = rc * (pl[0] * f1[0] + pl[1] * f1[1] + pl[2] * f1[2])
        c = rc * (pl[0] * f2[0] + pl[1] * f2[1] + pl[2] * f2[2])
        t = _first_entry(a, b, c, lower, best)
        if t < best:
            best = t
            hit[0] = pid
            hit[1] = 0
            hit[2] = 0
    return best


@jit
def _fall_first_contact(
    radius, p, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
    sid, skx, sky, sact, ns, hit,
):
    """First contact of the vertical fall ``p - t e_z``: the floor (``t = z - R``) or the sphere
    image maximising the touching height ``z_j + sqrt(D^2 - rho^2)`` (``rho`` horizontal distance).

    Scans the grid layers from that of ``p`` downwards and stops when no lower layer can beat the
    best contact. Writes ``hit = (id, kx, ky)`` and returns the fall distance ``t``.
    """
    reach = radius + rmax
    best = p[2] - radius
    hit[0] = FLOOR
    hit[1] = 0
    hit[2] = 0
    eps = EPS_T * 2.0 * rmax
    if periodic:
        ix0 = int(math.floor((p[0] - reach) / hxy))
        ix1 = int(math.floor((p[0] + reach) / hxy))
        iy0 = int(math.floor((p[1] - reach) / hxy))
        iy1 = int(math.floor((p[1] + reach) / hxy))
    else:
        ix0 = _cell(p[0] - reach, hxy, nx)
        ix1 = _cell(p[0] + reach, hxy, nx)
        iy0 = _cell(p[1] - reach, hxy, ny)
        iy1 = _cell(p[1] + reach, hxy, ny)
    iz = _cell(p[2], hz, nz)
    while iz >= 0:
        for iy in range(iy0, iy1 + 1):
            ky = iy // ny
            wy = iy - ky * ny
            for ix in range(ix0, ix1 + 1):
                kx = ix // nx
                wx = ix - kx * nx
                j = head[(iz * ny + wy) * nx + wx]
                while j >= 0:
                    dx = p[0] - (pos[j, 0] + kx * lsize)
                    dy = p[1] - (pos[j, 1] + ky * lsize)
                    dd = radius + rad[j]
                    h2 = dd * dd - dx * dx - dy * dy
                    if h2 > 0.0:
                        t = p[2] - pos[j, 2] - math.sqrt(h2)
                        st = _support_status(sid, skx, sky, sact, ns, j, kx, ky)
                        lower = eps if st == 0 else -eps
                        if lower <= t and max(t, 0.0) < best:
                            best = max(t, 0.0)
                            hit[0] = j
                            hit[1] = kx
                            hit[2] = ky
                    j = nxt[j]
        # spheres of lower layers have z < iz hz, so they touch below iz hz + R + R_max
        if best <= p[2] - iz * hz - reach:
            break
        iz -= 1
    return best


@jit
def _drop_one(
    radius, x0, y0, z0, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
    out_i, out_k, p,
):
    """Drop-and-roll (PHYSICS §4.2) of one sphere released at ``(x0, y0, z0)``.

    Repeats: find the active supports (NNLS on the touching supports' normals); stop if they hold
    the sphere; otherwise fall (no support), roll on one sphere in the vertical plane through its
    centre down to its equator, or roll on the circle of two supports down to its lowest point or
    to where one multiplier vanishes; the motion stops earlier at the first new contact, which
    joins the supports. Writes the resting centre (unwrapped) to ``p``.

    Returns 1 if the sphere came to rest, 0 if the attempt must be retried (too many motions,
    degenerate geometry) and -1 if the candidate buffers overflowed.
    """
    cap = 4
    sid = np.empty(cap, np.int64)
    skx = np.zeros(cap, np.int64)
    sky = np.zeros(cap, np.int64)
    skind = np.zeros(cap, np.int64)
    sact = np.zeros(cap, np.bool_)
    sc = np.zeros((cap, 3))
    sv = np.zeros(cap)
    nrm = np.zeros((cap, 3))
    pl = np.empty(4)
    circ = np.empty(11)
    cc = np.empty(3)
    f1 = np.empty(3)
    f2 = np.empty(3)
    lo = np.empty(3)
    hi = np.empty(3)
    hit = np.zeros(3, np.int64)
    p[0] = x0
    p[1] = y0
    p[2] = z0
    ns = 0
    skip = -1
    for _ in range(MAX_MOTIONS):
        for s in range(ns):
            if skind[s] == 0:
                for a in range(3):
                    nrm[s, a] = (p[a] - sc[s, a]) / sv[s]
            else:
                for a in range(3):
                    nrm[s, a] = sc[s, a]
        mask, res = _active_set(nrm, ns, skip)
        if res < STABLE_TOL:
            return 1
        na = 0
        i0 = -1
        i1 = -1
        for s in range(ns):
            sact[s] = (mask >> s) & 1 == 1
            if sact[s]:
                if na == 0:
                    i0 = s
                else:
                    i1 = s
                na += 1
        if na == 0:
            t = _fall_first_contact(
                radius, p, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
                sid, skx, sky, sact, ns, hit,
            )
            p[2] -= t
            ns = 0
            skip = -1
        else:
            if na == 1:
                if skind[i0] != 0:
                    return 0
                for a in range(3):
                    cc[a] = sc[i0, a]
                rc = sv[i0]
                nrm_len = 0.0
                for a in range(3):
                    f1[a] = p[a] - cc[a]
                    nrm_len += f1[a] * f1[a]
                nrm_len = math.sqrt(nrm_len)
                for a in range(3):
                    f1[a] /= nrm_len
                    p[a] = cc[a] + rc * f1[a]
                hor = math.sqrt(max(1.0 - f1[2] * f1[2], 0.0))
                if hor < 1e-12:
                    f2[0] = 1.0
                    f2[1] = 0.0
                    f2[2] = 0.0
                else:
                    f2[0] = f1[2] * f1[0] / hor
                    f2[1] = f1[2] * f1[1] / hor
                    f2[2] = (-1.0 + f1[2] * f1[2]) / hor
                tmax = math.asin(min(f1[2], 1.0))
                release = i0
            else:
                if skind[i0] != 0:
                    i0, i1 = i1, i0
                if skind[i0] != 0:
                    return 0
                if not _circle(sc[i0], sv[i0], skind[i1], sc[i1], sv[i1], circ):
                    return 0
                for a in range(3):
                    cc[a] = circ[a]
                ux = circ[3]
                uy = circ[4]
                uz = circ[5]
                rc = circ[6]
                w0 = p[0] - cc[0]
                w1 = p[1] - cc[1]
                w2 = p[2] - cc[2]
                wu = w0 * ux + w1 * uy + w2 * uz
                w0 -= wu * ux
                w1 -= wu * uy
                w2 -= wu * uz
                wl = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
                if wl <= 0.0:
                    return 0
                f1[0] = w0 / wl
                f1[1] = w1 / wl
                f1[2] = w2 / wl
                for a in range(3):
                    p[a] = cc[a] + rc * f1[a]
                f2[0] = uy * f1[2] - uz * f1[1]
                f2[1] = uz * f1[0] - ux * f1[2]
                f2[2] = ux * f1[1] - uy * f1[0]
                if f2[2] > 0.0:
                    for a in range(3):
                        f2[a] = -f2[a]
                if f2[2] > -1e-14:
                    # lowest point of the circle (or a horizontal circle): no tangential gravity
                    return 1
                # height of rhat: b(t) = f1_z cos t + f2_z sin t = s cos(t - psi), falling to -s
                s = math.hypot(f1[2], f2[2])
                psi = math.atan2(f2[2], f1[2])
                tmax = math.pi + psi
                release = -1
                a1 = circ[7]
                b1 = circ[8]
                a2 = circ[9]
                b2 = circ[10]
                # lambda_1 = (u_z B_2 - A_2 b) / det and lambda_2 = (A_1 b - u_z B_1) / det vanish at b*
                if abs(a2) > 1e-14:
                    bs = uz * b2 / a2
                    if -s < bs < f1[2]:
                        t = psi + math.acos(bs / s)
                        if 0.0 <= t < tmax:
                            tmax = t
                            release = i0
                if abs(a1) > 1e-14:
                    bs = uz * b1 / a1
                    if -s < bs < f1[2]:
                        t = psi + math.acos(bs / s)
                        if 0.0 <= t < tmax:
                            tmax = t
                            release = i1
            t = _arc_first_contact(
                radius, cc, rc, f1, f2, tmax, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize,
                periodic, rmax, sid, skx, sky, sact, ns, out_i, out_k, pl, lo, hi, hit,
            )
            if t < 0.0:
                return -1
            ct = math.cos(t)
            st = math.sin(t)
            for a in range(3):
                p[a] = cc[a] + rc * (ct * f1[a] + st * f2[a])
            # keep the active supports (compacted), then the new contact
            k = 0
            for s in range(ns):
                if sact[s]:
                    if s == release:
                        release = k
                    sid[k] = sid[s]
                    skx[k] = skx[s]
                    sky[k] = sky[s]
                    skind[k] = skind[s]
                    sv[k] = sv[s]
                    for a in range(3):
                        sc[k, a] = sc[s, a]
                    k += 1
            ns = k
            if hit[0] != -100:
                skip = -1
            else:
                skip = release
                continue
        # append the contact found by the motion
        j = hit[0]
        sid[ns] = j
        skx[ns] = hit[1]
        sky[ns] = hit[2]
        if j >= 0:
            skind[ns] = 0
            sc[ns, 0] = pos[j, 0] + hit[1] * lsize
            sc[ns, 1] = pos[j, 1] + hit[2] * lsize
            sc[ns, 2] = pos[j, 2]
            sv[ns] = radius + rad[j]
        else:
            skind[ns] = 1
            _plane(j, radius, lsize, pl)
            for a in range(3):
                sc[ns, a] = pl[a]
            sv[ns] = pl[3]
        ns += 1
    return 0


@jit
def _admissible(radius, q, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax, out_i, out_k, lo, hi):
    """True if a sphere of radius ``R`` at ``q`` overlaps nothing by more than ``OVERLAP_TOL d``.

    Returns 1 (admissible), 0 (overlap or outside the box) or -1 (buffer overflow).
    """
    tol = OVERLAP_TOL * 2.0 * rmax
    if q[2] < radius - tol:
        return 0
    if not periodic:
        if q[0] < radius - tol or q[0] > lsize - radius + tol:
            return 0
        if q[1] < radius - tol or q[1] > lsize - radius + tol:
            return 0
    reach = radius + rmax
    for a in range(3):
        lo[a] = q[a] - reach
        hi[a] = q[a] + reach
    m = _gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
    if m < 0:
        return -1
    for k in range(m):
        j = out_i[k]
        dx = q[0] - (pos[j, 0] + out_k[k, 0] * lsize)
        dy = q[1] - (pos[j, 1] + out_k[k, 1] * lsize)
        dz = q[2] - pos[j, 2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) < radius + rad[j] - tol:
            return 0
    return 1


@jit
def _count_contacts(i, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax, out_i, out_k, lo, hi):
    """Add the geometric contacts (gap < ``CONTACT_TOL d``) of new sphere ``i`` to ``ncont``."""
    tol = CONTACT_TOL * 2.0 * rmax
    reach = rad[i] + rmax + tol
    for a in range(3):
        lo[a] = pos[i, a] - reach
        hi[a] = pos[i, a] + reach
    m = _gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
    for k in range(m):
        j = out_i[k]
        if j == i:
            continue
        dx = pos[i, 0] - (pos[j, 0] + out_k[k, 0] * lsize)
        dy = pos[i, 1] - (pos[j, 1] + out_k[k, 1] * lsize)
        dz = pos[i, 2] - pos[j, 2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) < rad[i] + rad[j] + tol:
            ncont[i] += 1
            ncont[j] += 1
    return m


@jit
def _lmgc_one(
    i, radius, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
    out_i, out_k, nbc, nbd, p,
):
    """LMGC90 ``depositInBox3D`` placement (PHYSICS §4.3) of sphere ``i``: the lowest admissible
    centre touching three supports, the first of which is a reference sphere.

    References are the last ``LMGC_REFERENCES`` deposited spheres with fewer than
    ``LMGC_MAX_CONTACTS`` geometric contacts. For each reference ``j`` (taken by increasing lower
    bound ``z_j - D_j``) the positions touching ``j`` + plane + plane, ``j`` + sphere + plane and
    ``j`` + sphere + sphere are the intersections of the circle of the first two supports with the
    third (closed form); a position is kept if it is inside the box, overlaps no neighbour of ``j``
    and is held by its three supports (gravity inside their cone of normals). Writes the centre to
    ``p`` and returns 1, 0 if no such position exists, -1 on buffer overflow.
    """
    start = max(0, i - LMGC_REFERENCES)
    nref = 0
    refs = np.empty(i - start, np.int64)
    for j in range(start, i):
        if ncont[j] < LMGC_MAX_CONTACTS:
            refs[nref] = j
            nref += 1
    if nref == 0:
        return 0
    bound = np.empty(nref)
    for r in range(nref):
        j = refs[r]
        bound[r] = pos[j, 2] - (radius + rad[j])
    order = np.argsort(bound)
    best = math.inf
    npl = 1 if periodic else 5
    tol = OVERLAP_TOL * 2.0 * rmax
    circ = np.empty(11)
    pl = np.empty(4)
    pl3 = np.empty(4)
    lo = np.empty(3)
    hi = np.empty(3)
    cj = np.empty(3)
    c2 = np.empty(3)
    e1 = np.empty(3)
    e2 = np.empty(3)
    q = np.empty(3)
    nrm = np.zeros((4, 3))
    for r in range(nref):
        if bound[order[r]] >= best:
            break
        j = refs[order[r]]
        dj = radius + rad[j]
        for a in range(3):
            cj[a] = pos[j, a]
        # neighbours k of j that the new sphere can touch together with j: |c_k - c_j| < D_j + D_k
        reach = dj + radius + rmax
        for a in range(3):
            lo[a] = cj[a] - reach
            hi[a] = cj[a] + reach
        m = _gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
        if m < 0:
            return -1
        nn = 0
        for k in range(m):
            jj = out_i[k]
            if jj == j and out_k[k, 0] == 0 and out_k[k, 1] == 0:
                continue
            x = pos[jj, 0] + out_k[k, 0] * lsize
            y = pos[jj, 1] + out_k[k, 1] * lsize
            z = pos[jj, 2]
            dk = radius + rad[jj]
            dist = math.sqrt((x - cj[0]) ** 2 + (y - cj[1]) ** 2 + (z - cj[2]) ** 2)
            if dist < dj + dk:
                nbc[nn, 0] = x
                nbc[nn, 1] = y
                nbc[nn, 2] = z
                nbd[nn] = dk
                nn += 1
        # second support: a plane (index -1-a) or a neighbour (index b >= 0); third: after it
        for second in range(-npl, nn):
            if second < 0:
                _plane(second, radius, lsize, pl)
                if abs(pl[0] * cj[0] + pl[1] * cj[1] + pl[2] * cj[2] - pl[3]) >= dj:
                    continue
                for a in range(3):
                    c2[a] = pl[a]
                ok = _circle(cj, dj, 1, c2, pl[3], circ)
            else:
                for a in range(3):
                    c2[a] = nbc[second, a]
                ok = _circle(cj, dj, 0, c2, nbd[second], circ)
            if not ok:
                continue
            ux = circ[3]
            uy = circ[4]
            uz = circ[5]
            rc = circ[6]
            s = math.sqrt(max(1.0 - uz * uz, 0.0))
            if circ[2] - rc * s >= best:
                continue
            # e1: lowest direction on the circle, e2 = u x e1
            if s > 1e-12:
                e1[0] = uz * ux / s
                e1[1] = uz * uy / s
                e1[2] = (uz * uz - 1.0) / s
            else:
                e1[0] = 1.0
                e1[1] = 0.0
                e1[2] = 0.0
            e2[0] = uy * e1[2] - uz * e1[1]
            e2[1] = uz * e1[0] - ux * e1[2]
            e2[2] = ux * e1[1] - uy * e1[0]
            for third in range(-npl, nn):
                # each unordered pair once: plane + plane (third below second), sphere + plane,
                # sphere + sphere (third after second)
                if second < 0:
                    if third >= second:
                        continue
                elif 0 <= third <= second:
                    continue
                if third < 0:
                    _plane(third, radius, lsize, pl3)
                    ca = pl3[0] * circ[0] + pl3[1] * circ[1] + pl3[2] * circ[2] - pl3[3]
                    cb = rc * (pl3[0] * e1[0] + pl3[1] * e1[1] + pl3[2] * e1[2])
                    ccs = rc * (pl3[0] * e2[0] + pl3[1] * e2[1] + pl3[2] * e2[2])
                else:
                    wx = circ[0] - nbc[third, 0]
                    wy = circ[1] - nbc[third, 1]
                    wz = circ[2] - nbc[third, 2]
                    dk = nbd[third]
                    ca = wx * wx + wy * wy + wz * wz + rc * rc - dk * dk
                    cb = 2.0 * rc * (wx * e1[0] + wy * e1[1] + wz * e1[2])
                    ccs = 2.0 * rc * (wx * e2[0] + wy * e2[1] + wz * e2[2])
                mm = math.hypot(cb, ccs)
                if mm <= 0.0:
                    continue
                qq = -ca / mm
                if qq < -1.0 or qq > 1.0:
                    continue
                psi = math.atan2(ccs, cb)
                ac = math.acos(qq)
                for sign in (-1.0, 1.0):
                    phi = psi + sign * ac
                    cph = math.cos(phi)
                    sph = math.sin(phi)
                    for a in range(3):
                        q[a] = circ[a] + rc * (cph * e1[a] + sph * e2[a])
                    if q[2] >= best:
                        continue
                    # inside the box
                    if q[2] < radius - tol:
                        continue
                    if not periodic and (
                        q[0] < radius - tol or q[0] > lsize - radius + tol
                        or q[1] < radius - tol or q[1] > lsize - radius + tol
                    ):
                        continue
                    # no overlap: any sphere overlapping q is a neighbour of j (|c - c_j| < D_j + D)
                    clear = True
                    for k in range(nn):
                        dist = math.sqrt(
                            (q[0] - nbc[k, 0]) ** 2 + (q[1] - nbc[k, 1]) ** 2 + (q[2] - nbc[k, 2]) ** 2
                        )
                        if dist < nbd[k] - tol:
                            clear = False
                            break
                    if not clear:
                        continue
                    # held by its three supports
                    for a in range(3):
                        nrm[0, a] = (q[a] - cj[a]) / dj
                        if second < 0:
                            nrm[1, a] = pl[a]
                        else:
                            nrm[1, a] = (q[a] - nbc[second, a]) / nbd[second]
                        if third < 0:
                            nrm[2, a] = pl3[a]
                        else:
                            nrm[2, a] = (q[a] - nbc[third, a]) / nbd[third]
                    _, res = _active_set(nrm, 3, -1)
                    if res >= STABLE_TOL:
                        continue
                    best = q[2]
                    for a in range(3):
                        p[a] = q[a]
    return 1 if best < math.inf else 0


@jit
def deposit_chunk(
    lmgc, pos, rad, ncont, start, stop, uni, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
    top, out_i, out_k, nbc, nbd,
):
    """Place spheres ``start .. stop-1`` in order; each attempt consumes a row of ``uni`` (U(0,1)^2).

    ``lmgc`` selects the LMGC90 rule (drop-and-roll is then used only where it finds no
    three-support position: the first spheres). With lateral walls the release point is
    ``(R + u_0 (L - 2R), R + u_1 (L - 2R))``, periodic ``(u_0 L, u_1 L)``; the release height is
    ``top + R + 0.01 d`` with ``top`` the highest point of the deposit. Accepted centres (x, y
    wrapped when periodic) go to ``pos`` and the grid.

    Returns ``(next, used, top, status)``: the first sphere not placed, the rows of ``uni``
    consumed, the updated ``top`` and ``STATUS_DONE``, ``STATUS_NEED_UNIFORMS`` (call again with
    fresh ``uni`` from ``next``), ``STATUS_FAILED`` (sphere ``next`` could not be placed in
    ``MAX_ATTEMPTS`` attempts) or ``STATUS_BUFFER`` (candidate buffers too small).
    """
    p = np.empty(3)
    lo = np.empty(3)
    hi = np.empty(3)
    used = 0
    dmax = 2.0 * rmax
    for i in range(start, stop):
        radius = rad[i]
        placed = 0
        if lmgc and i > 0:
            placed = _lmgc_one(
                i, radius, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
                out_i, out_k, nbc, nbd, p,
            )
            if placed < 0:
                return i, used, top, STATUS_BUFFER
        attempts = 0
        while placed == 0:
            if attempts == MAX_ATTEMPTS:
                return i, used, top, STATUS_FAILED
            if used == uni.shape[0]:
                return i, used, top, STATUS_NEED_UNIFORMS
            if periodic:
                x0 = uni[used, 0] * lsize
                y0 = uni[used, 1] * lsize
            else:
                x0 = radius + uni[used, 0] * (lsize - 2.0 * radius)
                y0 = radius + uni[used, 1] * (lsize - 2.0 * radius)
            used += 1
            attempts += 1
            ok = _drop_one(
                radius, x0, y0, top + radius + 0.01 * dmax, pos, rad, head, nxt, nx, ny, nz, hxy, hz,
                lsize, periodic, rmax, out_i, out_k, p,
            )
            if ok < 0:
                return i, used, top, STATUS_BUFFER
            if ok == 1:
                placed = _admissible(
                    radius, p, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax,
                    out_i, out_k, lo, hi,
                )
                if placed < 0:
                    return i, used, top, STATUS_BUFFER
        if periodic:
            p[0] -= lsize * math.floor(p[0] / lsize)
            p[1] -= lsize * math.floor(p[1] / lsize)
            if p[0] >= lsize:
                p[0] = 0.0
            if p[1] >= lsize:
                p[1] = 0.0
        for a in range(3):
            pos[i, a] = p[a]
        grid_insert(i, pos, head, nxt, nx, ny, nz, hxy, hz)
        top = max(top, p[2] + radius)
        if lmgc and _count_contacts(
            i, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax, out_i, out_k, lo, hi
        ) < 0:
            return i, used, top, STATUS_BUFFER
    return stop, used, top, STATUS_DONE

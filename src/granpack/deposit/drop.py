"""Drop-and-roll of one sphere (Visscher & Bolsterli 1972; docs/method/pluviation.md; Numba,
private to :mod:`granpack.deposit`).

The sphere, released at a given point, follows the quasi-static steepest descent of its height
among the fixed deposited spheres, the floor and the walls. At each step the touching supports
kept are the active set of the non-negative least squares solution of
``e_z = sum_k lambda_k n_k`` (:func:`~granpack.deposit.geometry.active_set`), and the sphere moves
along the constraint manifold they leave free: it falls (no support), rolls on one sphere in the
vertical plane through its centre down to its equator, or rolls on the circle of two supports
down to its lowest point or to where one multiplier, linear in the height along the circle,
crosses zero (that support is released). A motion stops at its first new contact, found in closed
form, which joins the supports; the drop ends where the supports hold the sphere.
"""

from __future__ import annotations

import math

import numpy as np

from granpack._numba import jit
from granpack.deposit.geometry import (
    FLOOR, STABLE_TOL, active_set, arc_point, circle, cross, down_perp, first_entry, normals, plane,
    plane_on_arc, set_plane, set_sphere, sphere_on_arc, supports,
)
from granpack.deposit.grid import cell, cell_head, gather, xy_cells

EPS_T = 1e-9  # motion parameter (rad, or length / d for falls) below which a released support is ignored
MAX_MOTIONS = 2000  # motions of one drop before the attempt is abandoned
NO_HIT = -100  # id of "no contact" in ``hit``


@jit
def _support_status(sid, skx, sky, sact, ns, ident, kx, ky):
    """-1 if ``(ident, kx, ky)`` is not a support, 1 if an active one, 0 if an inactive one."""
    for s in range(ns):
        if sid[s] == ident and skx[s] == kx and sky[s] == ky:
            return 1 if sact[s] else 0
    return -1


@jit
def _arc_first_contact(
    radius, cc, rc, f1, f2, tmax, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, rmax,
    sid, skx, sky, sact, ns, out_i, out_k, pl, lo, hi, hit,
):
    """First contact along the arc ``cc + rc (cos t f1 + sin t f2)``, ``0 <= t <= tmax``.

    Candidates are the sphere images in the bounding box of the arc grown by ``R + R_max`` and the
    planes of ``walls`` (:func:`~granpack.deposit.geometry.wall_table`); active supports are skipped and inactive (just released) ones only count after
    ``t > EPS_T``. Writes ``hit = (id, kx, ky)`` (``id`` = ``NO_HIT`` if none) and returns the
    contact parameter (``tmax`` if none) or -1.0 if the candidate buffers overflowed.
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
    m = gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
    if m < 0:
        return -1.0
    best = tmax
    hit[0] = NO_HIT
    npl = walls.shape[0]
    # spheres (q < m), then planes (pid = -1 - (q - m))
    for q in range(m + npl):
        if q < m:
            j = out_i[q]
            kx = out_k[q, 0]
            ky = out_k[q, 1]
        else:
            j = m - 1 - q
            kx = 0
            ky = 0
        st = _support_status(sid, skx, sky, sact, ns, j, kx, ky)
        if st == 1:
            continue
        lower = EPS_T if st == 0 else -EPS_T
        if j >= 0:
            a, b, c = sphere_on_arc(
                pos[j, 0] + kx * lsize, pos[j, 1] + ky * lsize, pos[j, 2], radius + rad[j], cc, rc, f1, f2
            )
        else:
            plane(j, radius, walls, pl)
            a, b, c = plane_on_arc(pl, cc, rc, f1, f2)
        t = first_entry(a, b, c, lower, best)
        if t < best:
            best = t
            hit[0] = j
            hit[1] = kx
            hit[2] = ky
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
    ix0, ix1, iy0, iy1 = xy_cells(p[0] - reach, p[0] + reach, p[1] - reach, p[1] + reach, hxy, nx, ny, periodic)
    iz = cell(p[2], hz, nz)
    while iz >= 0:
        for iy in range(iy0, iy1 + 1):
            for ix in range(ix0, ix1 + 1):
                j, kx, ky = cell_head(head, iz, iy, ix, nx, ny)
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
def _release_angle(ak, bk, uz, s, top, psi):
    """Where the multiplier ``(u_z B_k - A_k h) / det`` of one of two supports vanishes on their
    circle (``A_k``, ``B_k``: the normal coefficients of the other support, see
    :func:`~granpack.deposit.geometry.circle`).

    ``h = s cos(t - psi)`` is the height of the unit radius vector, falling from ``top`` to ``-s``;
    the multiplier vanishes at ``h* = u_z B_k / A_k``. Returns that ``t``, or ``inf`` if ``h*`` is
    not passed on the way down.
    """
    if abs(ak) > 1e-14:
        hs = uz * bk / ak
        if -s < hs < top:
            return psi + math.acos(hs / s)
    return math.inf


@jit
def drop_one(
    radius, x0, y0, z0, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, rmax,
    out_i, out_k, lo, hi, p,
):
    """Drop-and-roll of one sphere released at ``(x0, y0, z0)``; writes its resting centre
    (unwrapped) to ``p`` (``lo``, ``hi``: scratch (3,); ``walls``: the planes,
    :func:`~granpack.deposit.geometry.wall_table`).

    The supports (at most 4) are kept in ``sid``, ``skx``, ``sky`` (the id of a sphere or plane
    and its periodic image), ``sact`` (active in the current motion) and ``skind``, ``sc``,
    ``sv`` (their geometry, :func:`~granpack.deposit.geometry.supports`).

    Returns 1 if the sphere came to rest, 0 if the attempt must be retried (too many motions,
    degenerate geometry) and -1 if the candidate buffers overflowed.
    """
    cap = 4
    sid = np.empty(cap, np.int64)
    skx = np.zeros(cap, np.int64)
    sky = np.zeros(cap, np.int64)
    sact = np.zeros(cap, np.bool_)
    skind, sc, sv, nrm = supports(cap)
    pl = np.empty(4)
    circ = np.empty(11)
    cc = np.empty(3)
    f1 = np.empty(3)
    f2 = np.empty(3)
    hit = np.zeros(3, np.int64)
    p[0] = x0
    p[1] = y0
    p[2] = z0
    ns = 0
    skip = -1
    for _ in range(MAX_MOTIONS):
        normals(p, skind, sc, sv, ns, nrm)
        mask, res = active_set(nrm, ns, skip)
        if res < STABLE_TOL:
            return 1
        na, i0, i1 = _mark_active(mask, ns, sact)
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
                status, rc, tmax, release = _roll_on_sphere(p, i0, skind, sc, sv, cc, f1, f2)
            else:
                status, rc, tmax, release = _roll_on_circle(p, i0, i1, skind, sc, sv, circ, cc, f1, f2)
            if status >= 0:
                return status
            t = _arc_first_contact(
                radius, cc, rc, f1, f2, tmax, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize,
                periodic, walls, rmax, sid, skx, sky, sact, ns, out_i, out_k, pl, lo, hi, hit,
            )
            if t < 0.0:
                return -1
            arc_point(cc, rc, f1, f2, t, p)
            ns, release = _keep_active(ns, release, sact, sid, skx, sky, skind, sc, sv)
            if hit[0] != NO_HIT:
                skip = -1
            else:
                skip = release
                continue
        # append the contact found by the motion
        ns = _add_support(ns, hit, radius, pos, rad, lsize, walls, pl, sid, skx, sky, skind, sc, sv)
    return 0


@jit(inline="always")
def _mark_active(mask, ns, sact):
    """Set ``sact[s]`` for the supports ``s < ns`` in the bit mask ``mask`` of the active set;
    returns ``(count, first, last)``, the active supports' number and first and last index (-1
    if none)."""
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
    return na, i0, i1


@jit(inline="always")
def _roll_on_sphere(p, i0, skind, sc, sv, cc, f1, f2):
    """The roll on support ``i0`` alone (a sphere of centre ``sc[i0]``, contact radius ``sv[i0]``,
    d) in the vertical plane through its centre, down to its equator: puts ``p`` on that sphere
    and writes the arc ``cc + rc (cos t f1 + sin t f2)`` to ``cc``, ``f1``, ``f2``.

    Returns ``(status, rc, tmax, release)``: status 0 (retry: the support is a plane) or -1 (roll
    for ``0 <= t <= tmax`` rad, then release support ``release``).
    """
    if skind[i0] != 0:
        return 0, 0.0, 0.0, -1
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
    down_perp(f1, f2)
    tmax = math.asin(min(f1[2], 1.0))
    return -1, rc, tmax, i0


@jit(inline="always")
def _roll_on_circle(p, i0, i1, skind, sc, sv, circ, cc, f1, f2):
    """The roll on the circle of supports ``i0`` and ``i1`` (one of them a sphere), down to its
    lowest point or to where one multiplier, linear in the height along the circle, crosses zero:
    puts ``p`` on the circle and writes the arc ``cc + rc (cos t f1 + sin t f2)`` to ``cc``,
    ``f1``, ``f2`` (``circ``: scratch (11,), :func:`~granpack.deposit.geometry.circle`).

    Returns ``(status, rc, tmax, release)``: status 0 (retry: degenerate geometry), 1 (at rest:
    the lowest point of the circle, or a horizontal circle) or -1 (roll for ``0 <= t <= tmax``
    rad, then release support ``release``, -1 none).
    """
    if skind[i0] != 0:
        i0, i1 = i1, i0
    if skind[i0] != 0:
        return 0, 0.0, 0.0, -1
    if not circle(sc[i0], sv[i0], skind[i1], sc[i1], sv[i1], circ):
        return 0, 0.0, 0.0, -1
    for a in range(3):
        cc[a] = circ[a]
    u = circ[3:6]
    rc = circ[6]
    wu = (p[0] - cc[0]) * u[0] + (p[1] - cc[1]) * u[1] + (p[2] - cc[2]) * u[2]
    for a in range(3):
        f1[a] = p[a] - cc[a] - wu * u[a]
    wl = math.sqrt(f1[0] * f1[0] + f1[1] * f1[1] + f1[2] * f1[2])
    if wl <= 0.0:
        return 0, 0.0, 0.0, -1
    for a in range(3):
        f1[a] /= wl
        p[a] = cc[a] + rc * f1[a]
    cross(u, f1, f2)
    if f2[2] > 0.0:
        for a in range(3):
            f2[a] = -f2[a]
    if f2[2] > -1e-14:
        # lowest point of the circle (or a horizontal circle): no tangential gravity
        return 1, 0.0, 0.0, -1
    # height of rhat: b(t) = f1_z cos t + f2_z sin t = s cos(t - psi), falling to -s
    s = math.hypot(f1[2], f2[2])
    psi = math.atan2(f2[2], f1[2])
    tmax = math.pi + psi
    release = -1
    # lambda_1 = (u_z B_2 - A_2 b) / det and lambda_2 = (A_1 b - u_z B_1) / det
    t = _release_angle(circ[9], circ[10], u[2], s, f1[2], psi)
    if 0.0 <= t < tmax:
        tmax = t
        release = i0
    t = _release_angle(circ[7], circ[8], u[2], s, f1[2], psi)
    if 0.0 <= t < tmax:
        tmax = t
        release = i1
    return -1, rc, tmax, release


@jit(inline="always")
def _keep_active(ns, release, sact, sid, skx, sky, skind, sc, sv):
    """Compact the support arrays to their active supports (``sact``), in order; returns the new
    count and the new index of support ``release`` (unchanged if it is not active)."""
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
    return k, release


@jit(inline="always")
def _add_support(ns, hit, radius, pos, rad, lsize, walls, pl, sid, skx, sky, skind, sc, sv):
    """Append the contact ``hit = (id, kx, ky)`` (a sphere image of the deposit, or a plane
    ``id < 0`` of ``walls``) to the ``ns`` supports of the sphere of radius ``radius`` (d); returns ``ns + 1``
    (``pl``: scratch (4,))."""
    j = hit[0]
    sid[ns] = j
    skx[ns] = hit[1]
    sky[ns] = hit[2]
    if j >= 0:
        set_sphere(ns, pos[j, 0] + hit[1] * lsize, pos[j, 1] + hit[2] * lsize, pos[j, 2], radius + rad[j], skind, sc,
                   sv)
    else:
        plane(j, radius, walls, pl)
        set_plane(ns, pl, skind, sc, sv)
    return ns + 1

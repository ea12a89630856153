"""LMGC90 ``depositInBox3D``-like placement of one sphere (docs/method/pluviation.md; Numba,
private to :mod:`granpack.deposit`).

The sphere goes to the lowest centre touching three supports (sphere + plane + plane,
sphere + sphere + plane or three spheres), the first of which is a *reference*: one of the last
``LMGC_REFERENCES`` deposited spheres with fewer than ``LMGC_MAX_CONTACTS`` geometric contacts,
as in LMGC90. A position is kept if it lies in the box, overlaps nothing and is held by its three
supports under gravity (this last filter is ours: without it a sphere may rest on a slope).
Each position is the intersection of the circle of the first two supports with the third, in
closed form, so the search has no tolerance but the overlap one.
"""

from __future__ import annotations

import math

import numpy as np

from granpack._numba import jit
from granpack.deposit.geometry import (
    OVERLAP_TOL, arc_point, circle, cross, down_perp, held, inside_box, plane, plane_on_arc, set_plane,
    set_sphere, sphere_on_arc, supports,
)
from granpack.deposit.grid import gather_ball

CONTACT_TOL = 1e-9  # gap (in d) counted as a geometric contact (LMGC90 reference bookkeeping)
LMGC_REFERENCES = 100  # most recent spheres that may serve as first support (LMGC90 n_actif)
LMGC_MAX_CONTACTS = 8  # a sphere with this many contacts stops being a reference


@jit
def count_contacts(i, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax, out_i, out_k, lo, hi):
    """Add the geometric contacts (gap < ``CONTACT_TOL d``) of new sphere ``i`` to ``ncont``.

    Returns the number of candidates examined, or -1 on buffer overflow.
    """
    tol = CONTACT_TOL * 2.0 * rmax
    m = gather_ball(pos[i], rad[i] + rmax + tol, lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
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
def _references(i, radius, pos, rad, ncont):
    """Reference spheres for sphere ``i`` (radius ``R``), by increasing lower bound ``z_j - D_j``
    of a centre touching them, and those bounds (in that order)."""
    start = max(0, i - LMGC_REFERENCES)
    nref = 0
    refs = np.empty(i - start, np.int64)
    for j in range(start, i):
        if ncont[j] < LMGC_MAX_CONTACTS:
            refs[nref] = j
            nref += 1
    bound = np.empty(nref)
    for r in range(nref):
        j = refs[r]
        bound[r] = pos[j, 2] - (radius + rad[j])
    order = np.argsort(bound)
    return refs[:nref][order], bound[order]


@jit
def lmgc_one(
    i, radius, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, rmax,
    out_i, out_k, nbc, nbd, lo, hi, p,
):
    """Lowest admissible centre of sphere ``i`` touching a reference and two more supports.

    For each reference ``j`` (by increasing lower bound, stopping once it exceeds the best height)
    the neighbours ``k`` that can touch the new sphere together with ``j``
    (``|c_k - c_j| < D_j + D_k``) go to ``nbc``/``nbd``; then for each second support (plane or
    neighbour) the circle of centres touching ``j`` and it is cut with each third support (both
    roots of ``A + B cos t + C sin t = 0``). Writes the centre to ``p`` and returns 1, 0 if no
    such position exists, -1 on buffer overflow (``lo``, ``hi``: scratch (3,); the planes are those
    of ``walls``, :func:`~granpack.deposit.geometry.wall_table`).
    """
    refs, bound = _references(i, radius, pos, rad, ncont)
    best = math.inf
    npl = walls.shape[0]
    tol = OVERLAP_TOL * 2.0 * rmax
    circ = np.empty(11)
    pl = np.empty(4)
    e1 = np.empty(3)
    e2 = np.empty(3)
    q = np.empty(3)
    # the three supports of a candidate: the reference, the second, the third
    kind, sc, sv, nrm = supports(3)
    for r in range(refs.shape[0]):
        if bound[r] >= best:
            break
        j = refs[r]
        dj = radius + rad[j]
        set_sphere(0, pos[j, 0], pos[j, 1], pos[j, 2], dj, kind, sc, sv)
        cj = sc[0]
        m = gather_ball(cj, dj + radius + rmax, lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
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
                plane(second, radius, walls, pl)
                if abs(pl[0] * cj[0] + pl[1] * cj[1] + pl[2] * cj[2] - pl[3]) >= dj:
                    continue
                set_plane(1, pl, kind, sc, sv)
            else:
                set_sphere(1, nbc[second, 0], nbc[second, 1], nbc[second, 2], nbd[second], kind, sc, sv)
            if not circle(cj, dj, kind[1], sc[1], sv[1], circ):
                continue
            rc = circ[6]
            # e1: lowest direction on the circle, e2 = u x e1
            s = down_perp(circ[3:6], e1)
            if circ[2] - rc * s >= best:
                continue
            cross(circ[3:6], e1, e2)
            for third in range(-npl, nn):
                # each unordered pair once: plane + plane (third below second), sphere + plane,
                # sphere + sphere (third after second)
                if second < 0:
                    if third >= second:
                        continue
                elif 0 <= third <= second:
                    continue
                if third < 0:
                    plane(third, radius, walls, pl)
                    ca, cb, ccs = plane_on_arc(pl, circ, rc, e1, e2)
                else:
                    ca, cb, ccs = sphere_on_arc(nbc[third, 0], nbc[third, 1], nbc[third, 2], nbd[third], circ, rc, e1, e2)
                mm = math.hypot(cb, ccs)
                if mm <= 0.0:
                    continue
                qq = -ca / mm
                if qq < -1.0 or qq > 1.0:
                    continue
                psi = math.atan2(ccs, cb)
                ac = math.acos(qq)
                for sign in (-1.0, 1.0):
                    arc_point(circ, rc, e1, e2, psi + sign * ac, q)
                    if q[2] >= best or not inside_box(radius, q, walls, tol):
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
                    if third < 0:
                        set_plane(2, pl, kind, sc, sv)
                    else:
                        set_sphere(2, nbc[third, 0], nbc[third, 1], nbc[third, 2], nbd[third], kind, sc, sv)
                    if not held(q, kind, sc, sv, 3, nrm):
                        continue
                    best = q[2]
                    for a in range(3):
                        p[a] = q[a]
    return 1 if best < math.inf else 0

"""Supports, arcs and the equilibrium of a sphere on its supports (Numba; private to
:mod:`granpack.deposit`, shared by both rules).

* The centre ``p`` of the sphere being placed (radius ``R``) is constrained by *supports*. A
  sphere support is one periodic image of a deposited sphere ``j``: centre ``c`` (image shift
  included) and contact distance ``D = R + R_j``; the constraint is ``|p - c| >= D`` and its unit
  normal at contact is ``n = (p - c) / D``. A plane support has a unit normal ``n`` pointing into
  the admissible region and an offset ``h``; the constraint is ``n . p >= h``. The planes of a
  deposit are the rows of its ``walls`` table (:func:`wall_table`), plane id ``-1 - row``:
  ``FLOOR`` (``z >= R``), then with walls ``X_LO`` (``x >= R``), ``X_HI`` (``x <= L - R``),
  ``Y_LO``, ``Y_HI``, or in a cylinder the sides of the regular polygon of
  ``CYLINDER_SIDES`` sides inscribed in it (a sphere inside the polygon is inside the cylinder).
  A list of supports is stored as ``kind`` (0 sphere, 1 plane), ``sc`` (centre, or normal) and
  ``sv`` (``D``, or ``h``).
* Every motion or candidate set of ``p`` is a vertical segment ``p0 - t e_z`` or a circular arc

  .. math:: p(t) = c_c + r (\\cos t\\, f_1 + \\sin t\\, f_2), \\qquad f_1 \\perp f_2,

  on which the gap to a sphere (as ``|p - c|^2 - D^2``) and to a plane (as ``n . p - h``) both
  read ``A + B cos t + C sin t`` (:func:`sphere_on_arc`, :func:`plane_on_arc`): contacts along an
  arc are computed in closed form, so no step size or bisection tolerance enters.
* Gravity is ``-e_z``; a set of touching supports holds the sphere iff
  ``e_z = sum_k lambda_k n_k`` with all ``lambda_k >= 0`` (the supports' reactions balance the
  weight). :func:`active_set` solves the non-negative least squares problem of that equation; its
  active set is what the drop keeps, its residual is the test of :func:`held`.
"""

from __future__ import annotations

import math

import numpy as np

from granpack._numba import jit

FLOOR = -1

LAMBDA_TOL = 1e-12  # multipliers at or below this are inactive
STABLE_TOL = 1e-9  # |e_z - sum lambda n| below this: the sphere is held
OVERLAP_TOL = 1e-9  # accepted overlap, in d
#: sides of the regular polygon inscribed in a cylinder that holds the deposit's spheres: it is
#: at most ``R (1 - cos(pi / 64)) = 1.2e-3 R`` inside the cylinder of radius R
CYLINDER_SIDES = 64


def wall_table(lateral: str, lsize: float) -> np.ndarray:
    """``(K, 4)`` the planes of a deposit, one row ``(n_x, n_y, n_z, h_0)`` each (the centre of a
    sphere of radius R must have ``n . p >= h_0 + R``): the floor, then ``"walls"``: x = 0, x = L,
    y = 0, y = L; ``"cylinder"``: the ``CYLINDER_SIDES`` sides of the regular polygon inscribed in
    the cylinder of axis ``(L/2, L/2)`` and diameter L (apothem ``L/2 cos(pi / K)``);
    ``"periodic"``: the floor alone. Lengths in d."""
    rows = [(0.0, 0.0, 1.0, 0.0)]
    if lateral == "walls":
        rows += [(1.0, 0.0, 0.0, 0.0), (-1.0, 0.0, 0.0, -lsize), (0.0, 1.0, 0.0, 0.0), (0.0, -1.0, 0.0, -lsize)]
    elif lateral == "cylinder":
        apothem = 0.5 * lsize * math.cos(math.pi / CYLINDER_SIDES)
        for k in range(CYLINDER_SIDES):
            ux, uy = math.cos(2.0 * math.pi * k / CYLINDER_SIDES), math.sin(2.0 * math.pi * k / CYLINDER_SIDES)
            rows.append((-ux, -uy, 0.0, -(ux + uy) * 0.5 * lsize - apothem))
    return np.array(rows, dtype=np.float64)


@jit
def plane(pid, radius, walls, out):
    """Unit inward normal (``out[:3]``) and offset (``out[3]``) of plane ``pid`` (row ``-1 - pid``
    of the ``walls`` table, :func:`wall_table`) for radius ``R``."""
    row = -1 - pid
    out[0] = walls[row, 0]
    out[1] = walls[row, 1]
    out[2] = walls[row, 2]
    out[3] = walls[row, 3] + radius


@jit
def supports(cap):
    """Empty support list of capacity ``cap``: ``(kind, sc, sv, nrm)``, ``nrm`` for the normals."""
    return np.zeros(cap, np.int64), np.zeros((cap, 3)), np.zeros(cap), np.zeros((cap, 3))


@jit
def set_sphere(s, cx, cy, cz, dist, kind, sc, sv):
    """Store sphere support ``s``: centre ``(cx, cy, cz)``, contact distance ``dist``."""
    kind[s] = 0
    sc[s, 0] = cx
    sc[s, 1] = cy
    sc[s, 2] = cz
    sv[s] = dist


@jit
def set_plane(s, pl, kind, sc, sv):
    """Store plane support ``s`` from ``pl`` (normal ``pl[:3]``, offset ``pl[3]``, see :func:`plane`)."""
    kind[s] = 1
    for a in range(3):
        sc[s, a] = pl[a]
    sv[s] = pl[3]


@jit
def normals(p, kind, sc, sv, ns, nrm):
    """Unit normals (rows of ``nrm``) at ``p`` of the ``ns`` supports ``(kind, sc, sv)``."""
    for s in range(ns):
        if kind[s] == 0:
            for a in range(3):
                nrm[s, a] = (p[a] - sc[s, a]) / sv[s]
        else:
            for a in range(3):
                nrm[s, a] = sc[s, a]


@jit
def sphere_on_arc(cx, cy, cz, dist, cc, rc, f1, f2):
    """``(A, B, C)`` with ``|p(t) - c|^2 - D^2 = A + B cos t + C sin t`` on the arc ``(cc, rc, f1, f2)``."""
    wx = cc[0] - cx
    wy = cc[1] - cy
    wz = cc[2] - cz
    return (
        wx * wx + wy * wy + wz * wz + rc * rc - dist * dist,
        2.0 * rc * (wx * f1[0] + wy * f1[1] + wz * f1[2]),
        2.0 * rc * (wx * f2[0] + wy * f2[1] + wz * f2[2]),
    )


@jit
def arc_point(cc, rc, f1, f2, t, out):
    """The point ``out = cc + rc (cos t f1 + sin t f2)`` of an arc."""
    ct = math.cos(t)
    st = math.sin(t)
    for a in range(3):
        out[a] = cc[a] + rc * (ct * f1[a] + st * f2[a])


@jit
def plane_on_arc(pl, cc, rc, f1, f2):
    """``(A, B, C)`` with ``n . p(t) - h = A + B cos t + C sin t`` on the arc ``(cc, rc, f1, f2)``."""
    return (
        pl[0] * cc[0] + pl[1] * cc[1] + pl[2] * cc[2] - pl[3],
        rc * (pl[0] * f1[0] + pl[1] * f1[1] + pl[2] * f1[2]),
        rc * (pl[0] * f2[0] + pl[1] * f2[1] + pl[2] * f2[2]),
    )


@jit
def first_entry(a, b, c, lower, upper):
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
def down_perp(v, out):
    """Unit vector ``out`` orthogonal to the unit vector ``v`` in the vertical plane through ``v``,
    pointing down (``(1, 0, 0)`` if ``v`` is vertical); returns the horizontal length of ``v``.

    It is the direction of steepest descent on a circle of axis ``v`` and on a sphere at ``v``.
    """
    s = math.sqrt(max(1.0 - v[2] * v[2], 0.0))
    if s < 1e-12:
        out[0] = 1.0
        out[1] = 0.0
        out[2] = 0.0
    else:
        out[0] = v[2] * v[0] / s
        out[1] = v[2] * v[1] / s
        out[2] = (v[2] * v[2] - 1.0) / s
    return s


@jit
def cross(u, v, out):
    """``out = u x v``."""
    out[0] = u[1] * v[2] - u[2] * v[1]
    out[1] = u[2] * v[0] - u[0] * v[2]
    out[2] = u[0] * v[1] - u[1] * v[0]


@jit
def circle(c1, d1, kind2, c2, v2, circ):
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
def active_set(nrm, m, skip):
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
def held(p, kind, sc, sv, ns, nrm):
    """True if the ``ns`` supports ``(kind, sc, sv)`` hold a sphere at ``p`` under gravity
    (NNLS residual below ``STABLE_TOL``); ``nrm`` is scratch of shape ``(>= ns, 3)``."""
    normals(p, kind, sc, sv, ns, nrm)
    _, res = active_set(nrm, ns, -1)
    return res < STABLE_TOL


@jit
def inside_box(radius, q, walls, tol):
    """True if a sphere of radius ``R`` at ``q`` lies on the admissible side of every plane of
    ``walls`` (:func:`wall_table`: above the floor, inside the walls or the cylinder's polygon),
    within ``tol``."""
    for row in range(walls.shape[0]):
        if walls[row, 0] * q[0] + walls[row, 1] * q[1] + walls[row, 2] * q[2] < walls[row, 3] + radius - tol:
            return False
    return True

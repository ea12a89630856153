"""The assembled contact problem of one Moreau–Jean step (docs: Method > NSCD, contact kinematics and contact law).

A :class:`ContactProblem` is what every solver of :mod:`granpack.nscd` takes: for each contact
point α (frozen at the predicted configuration of the step)

- the bodies ``i`` (candidate) and ``j`` (antagonist; the wall is body ``N``, infinite mass),
- the unit normal ``n`` (from j to i), a tangent frame ``(t, s)`` and the lever arms
  ``a_i = x_α - x_i``, ``a_j = x_α - (x_j + shift)``,
- the matrix-free operator: ``a × n`` and ``J_w^{-1}(a × n)`` for both bodies (and the same for
  ``t``, ``s`` when friction is on), the inverse masses,
- the diagonal Delassus entry (docs: Method > NSCD, contact kinematics)

  .. math:: W_{nn,α} = \\sum_{b \\in \\{i, j\\}} \\frac{1}{m_b} + (a_b \\times n)^T J_{w,b}^{-1} (a_b \\times n)

  (the full 3 x 3 diagonal block when friction is on),
- the offset ``c_α`` of the velocity-level Signorini condition, in sqrt(g d),

  .. math:: 0 \\le r_{n,α} \\perp u_{n,α} + c_α \\ge 0, \\qquad
            c_α = \\begin{cases} g_α / h & g_α > 0 \\ \\text{(IQS gap anticipation)} \\\\
                                 e_N \\min(0, u^n_{n,α}) - ρ_α & g_α \\le 0 \\ \\text{(Newton restitution)}
                  \\end{cases}

  with the overlap recovery ``ρ_α = max(min(v_r, β (-g_α - s_r)^+ / h), min(v_s, β (-g_α - s_s)^+ / h))``:
  an overlap deeper than ``s_r`` is pushed back at a fraction β of its excess per step, at most at
  the speed ``v_r`` (β = 0: none, the plain velocity-level law); its slow tier, ``s_s < s_r`` and
  ``v_s << v_r``, pushes the overlaps between the two slops back at no more than ``v_s`` (``v_s`` 0:
  none; a pile at rest, :mod:`granpack.settling`); both slops are multiplied by the pair's slop
  factor, its smaller grain's size over the largest grain's when the slops are scaled by the pair
  (:func:`body_slop_scale`), else 1,

- the friction coefficient μ_α (Coulomb: ``|r_T| <= μ r_n``, maximal dissipation): the grains'
  μ between grains, the walls' against a wall,
- the free velocities ``V_free`` ``(N + 1, 6)`` (world rows ``(v, ω^w)``, see
  :mod:`granpack.nscd.rigid`) and the warm-start impulses.

Local velocity of α (relative velocity of i with respect to j at the point, in ``(n, t, s)``):

.. math:: U_α = [n\\,t\\,s]^T \\big((v_i + ω_i \\times a_i) - (v_j + ω_j \\times a_j)\\big), \\qquad
          V = V_{free} + M^{-1} H r

Impulses are local ``(r_n, r_t, r_s)`` per point, in m sqrt(g d); the world impulse on body i is
``r_n n + r_t t + r_s s`` (and its opposite on j).

Packed layout (for cache-friendly Numba sweeps): ``normal_data[α]`` holds, in this order,
``n`` (3), ``a_i × n`` (3), ``a_j × n`` (3), ``J_{w,i}^{-1}(a_i × n)`` (3),
``J_{w,j}^{-1}(a_j × n)`` (3), ``1/m_i``, ``1/m_j``, ``1/W_nn``, ``W_nn``; ``friction_data[α]``
holds ``t``, ``s``, ``a_i × t``, ``a_i × s``, ``a_j × t``, ``a_j × s``, ``J_{w,i}^{-1}(a_i × t)``,
``J_{w,i}^{-1}(a_i × s)``, ``J_{w,j}^{-1}(a_j × t)``, ``J_{w,j}^{-1}(a_j × s)`` (3 each), the six
entries ``(nn, tt, ss, nt, ns, ts)`` of the diagonal Delassus block, the tangential step
``ρ_T = 1 / max(W_tt, W_ss)`` and μ.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from granpack._numba import MIN_PARALLEL_POINTS, jit, prange, thread_count
from granpack.contact.contacts import ContactSet

__all__ = ["ContactProblem", "assemble", "body_slop_scale", "pair_slop_scale", "tangent_frame", "NORMAL_WIDTH",
           "FRICTION_WIDTH"]

# normal_data columns
N0, AIN, AJN, KIN, KJN, IMI, IMJ, INVW, WNN = 0, 3, 6, 9, 12, 15, 16, 17, 18
NORMAL_WIDTH = 19
# friction_data columns
T0, S0, AIT, AIS, AJT, AJS, KIT, KIS, KJT, KJS, WBLK, RHOT, MU = 0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 36, 37
FRICTION_WIDTH = 38


@jit
def _tangent_nb(n0, n1, n2):
    """Numba: ``t = normalize(n × e_k)`` with ``e_k`` the axis least aligned with n; returns t and ``s = n × t``."""
    a0, a1, a2 = abs(n0), abs(n1), abs(n2)
    if a0 <= a1 and a0 <= a2:  # e_x
        t0, t1, t2 = 0.0, n2, -n1
    elif a1 <= a2:  # e_y
        t0, t1, t2 = -n2, 0.0, n0
    else:  # e_z
        t0, t1, t2 = n1, -n0, 0.0
    norm = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0, t1, t2 = t0 / norm, t1 / norm, t2 / norm
    return t0, t1, t2, n1 * t2 - n2 * t1, n2 * t0 - n0 * t2, n0 * t1 - n1 * t0


@jit
def _tangent_frame_kernel(normal, out):
    for k in range(normal.shape[0]):
        t0, t1, t2, s0, s1, s2 = _tangent_nb(normal[k, 0], normal[k, 1], normal[k, 2])
        out[k, 0, 0], out[k, 0, 1], out[k, 0, 2] = t0, t1, t2
        out[k, 1, 0], out[k, 1, 1], out[k, 1, 2] = s0, s1, s2


def tangent_frame(normal: np.ndarray) -> np.ndarray:
    """Tangent vectors ``(t, s)`` completing unit normals into right-handed frames ``(n, t, s)``.

    Args:
        normal: ``(P, 3)`` unit normals.

    Returns:
        ``(P, 2, 3)``: ``t = normalize(n × e_k)`` (``e_k`` the axis least aligned with n), ``s = n × t``.
    """
    normal = np.ascontiguousarray(normal, dtype=np.float64).reshape(-1, 3)
    out = np.empty((len(normal), 2, 3))
    _tangent_frame_kernel(normal, out)
    return out


@jit
def _store_arm(row, col, a, e, inv_iw):
    """Numba: ``row[col:col+3] = a × e`` and returns ``J_w^{-1}(a × e)`` (inverse inertia as 6 entries)."""
    c0 = a[1] * e[2] - a[2] * e[1]
    c1 = a[2] * e[0] - a[0] * e[2]
    c2 = a[0] * e[1] - a[1] * e[0]
    row[col], row[col + 1], row[col + 2] = c0, c1, c2
    k0 = inv_iw[0] * c0 + inv_iw[3] * c1 + inv_iw[4] * c2
    k1 = inv_iw[3] * c0 + inv_iw[1] * c1 + inv_iw[5] * c2
    k2 = inv_iw[4] * c0 + inv_iw[5] * c1 + inv_iw[2] * c2
    return c0, c1, c2, k0, k1, k2


@jit
def _recovery_push(excess, rate, speed, h):
    """Numba: the separating speed one tier of the overlap recovery asks, ``min(v, β excess / h)``
    for an overlap ``excess`` d beyond its slop, 0 for none or for β = 0."""
    if rate > 0.0 and excess > 0.0:
        return min(speed, rate * excess / h)
    return 0.0


@jit(parallel=True)
def _assemble_parallel(
    chunks, body_i, body_j, shift, normal, point_start, point, gap, x, inv_mass, inv_iw, v_start, h, restitution, mu,
    body, data, offset, tangent, lever_i, lever_j, fdata, with_friction, recovery_slop, recovery_rate, recovery_speed,
    slow_slop, slow_speed, slop_scale,
):
    """Numba: :func:`_assemble_kernel` over ``chunks`` consecutive ranges of manifolds at once (the
    manifolds write disjoint rows, so the result does not depend on ``chunks``)."""
    n = body_i.shape[0]
    for c in prange(chunks):
        _assemble_kernel(
            n * c // chunks, n * (c + 1) // chunks, body_i, body_j, shift, normal, point_start, point, gap, x,
            inv_mass, inv_iw, v_start, h, restitution, mu, body, data, offset, tangent, lever_i, lever_j, fdata,
            with_friction, recovery_slop, recovery_rate, recovery_speed, slow_slop, slow_speed, slop_scale,
        )


@jit
def _assemble_kernel(
    m0, m1, body_i, body_j, shift, normal, point_start, point, gap, x, inv_mass, inv_iw, v_start, h, restitution, mu,
    body, data, offset, tangent, lever_i, lever_j, fdata, with_friction, recovery_slop, recovery_rate, recovery_speed,
    slow_slop, slow_speed, slop_scale,
):
    """Numba: the rows of the points of manifolds ``m0 <= m < m1`` (see :func:`assemble`)."""
    wall = x.shape[0]
    n = np.empty(3)
    t = np.empty(3)
    s = np.empty(3)
    ai = np.empty(3)
    aj = np.empty(3)
    for m in range(m0, m1):
        i = body_i[m]
        j = body_j[m] if body_j[m] >= 0 else wall
        scale = min(slop_scale[i], slop_scale[j])
        n[0], n[1], n[2] = normal[m, 0], normal[m, 1], normal[m, 2]
        t[0], t[1], t[2], s[0], s[1], s[2] = _tangent_nb(n[0], n[1], n[2])
        for k in range(point_start[m], point_start[m + 1]):
            body[k, 0] = i
            body[k, 1] = j
            for c in range(3):
                ai[c] = point[k, c] - x[i, c]
                aj[c] = 0.0 if j == wall else point[k, c] - x[j, c] - shift[m, c]
                lever_i[k, c] = ai[c]
                lever_j[k, c] = aj[c]
                tangent[k, 0, c] = t[c]
                tangent[k, 1, c] = s[c]
            row = data[k]
            row[N0], row[N0 + 1], row[N0 + 2] = n[0], n[1], n[2]
            cin0, cin1, cin2, kin0, kin1, kin2 = _store_arm(row, AIN, ai, n, inv_iw[i])
            cjn0, cjn1, cjn2, kjn0, kjn1, kjn2 = _store_arm(row, AJN, aj, n, inv_iw[j])
            row[KIN], row[KIN + 1], row[KIN + 2] = kin0, kin1, kin2
            row[KJN], row[KJN + 1], row[KJN + 2] = kjn0, kjn1, kjn2
            imi, imj = inv_mass[i], inv_mass[j]
            row[IMI], row[IMJ] = imi, imj
            w_nn = imi + imj + cin0 * kin0 + cin1 * kin1 + cin2 * kin2 + cjn0 * kjn0 + cjn1 * kjn1 + cjn2 * kjn2
            row[WNN] = w_nn
            row[INVW] = 1.0 / w_nn
            if gap[k] > 0.0:
                offset[k] = gap[k] / h
            else:
                u0 = 0.0
                for c in range(3):
                    u0 += n[c] * (v_start[i, c] - v_start[j, c])
                u0 += cin0 * v_start[i, 3] + cin1 * v_start[i, 4] + cin2 * v_start[i, 5]
                u0 -= cjn0 * v_start[j, 3] + cjn1 * v_start[j, 4] + cjn2 * v_start[j, 5]
                offset[k] = restitution * min(0.0, u0)
                offset[k] -= max(_recovery_push(-gap[k] - recovery_slop * scale, recovery_rate, recovery_speed, h),
                                 _recovery_push(-gap[k] - slow_slop * scale, recovery_rate, slow_speed, h))
            if with_friction:
                f = fdata[k]
                f[T0], f[T0 + 1], f[T0 + 2] = t[0], t[1], t[2]
                f[S0], f[S0 + 1], f[S0 + 2] = s[0], s[1], s[2]
                cit0, cit1, cit2, kit0, kit1, kit2 = _store_arm(f, AIT, ai, t, inv_iw[i])
                cis0, cis1, cis2, kis0, kis1, kis2 = _store_arm(f, AIS, ai, s, inv_iw[i])
                cjt0, cjt1, cjt2, kjt0, kjt1, kjt2 = _store_arm(f, AJT, aj, t, inv_iw[j])
                cjs0, cjs1, cjs2, kjs0, kjs1, kjs2 = _store_arm(f, AJS, aj, s, inv_iw[j])
                f[KIT], f[KIT + 1], f[KIT + 2] = kit0, kit1, kit2
                f[KIS], f[KIS + 1], f[KIS + 2] = kis0, kis1, kis2
                f[KJT], f[KJT + 1], f[KJT + 2] = kjt0, kjt1, kjt2
                f[KJS], f[KJS + 1], f[KJS + 2] = kjs0, kjs1, kjs2
                im = imi + imj
                # the diagonal block: (1/m) e_a.e_b + (a×e_a).J^-1 (a×e_b), e in (n, t, s) orthonormal
                w_tt = im + cit0 * kit0 + cit1 * kit1 + cit2 * kit2 + cjt0 * kjt0 + cjt1 * kjt1 + cjt2 * kjt2
                w_ss = im + cis0 * kis0 + cis1 * kis1 + cis2 * kis2 + cjs0 * kjs0 + cjs1 * kjs1 + cjs2 * kjs2
                w_nt = cin0 * kit0 + cin1 * kit1 + cin2 * kit2 + cjn0 * kjt0 + cjn1 * kjt1 + cjn2 * kjt2
                w_ns = cin0 * kis0 + cin1 * kis1 + cin2 * kis2 + cjn0 * kjs0 + cjn1 * kjs1 + cjn2 * kjs2
                w_ts = cit0 * kis0 + cit1 * kis1 + cit2 * kis2 + cjt0 * kjs0 + cjt1 * kjs1 + cjt2 * kjs2
                f[WBLK], f[WBLK + 1], f[WBLK + 2] = w_nn, w_tt, w_ss
                f[WBLK + 3], f[WBLK + 4], f[WBLK + 5] = w_nt, w_ns, w_ts
                f[RHOT] = 1.0 / max(w_tt, w_ss)
                f[MU] = mu[0] if body_j[m] >= 0 else mu[1]


@jit
def _apply_kernel(body, data, fdata, tangent, impulse, velocity, with_friction):
    """Numba: ``velocity += M^{-1} H r`` for local impulses ``impulse`` (P, 3)."""
    for k in range(body.shape[0]):
        i, j = body[k, 0], body[k, 1]
        rn = impulse[k, 0]
        for c in range(3):
            pw = rn * data[k, N0 + c]
            dwi = rn * data[k, KIN + c]
            dwj = rn * data[k, KJN + c]
            if with_friction:
                rt, rs = impulse[k, 1], impulse[k, 2]
                pw += rt * tangent[k, 0, c] + rs * tangent[k, 1, c]
                dwi += rt * fdata[k, KIT + c] + rs * fdata[k, KIS + c]
                dwj += rt * fdata[k, KJT + c] + rs * fdata[k, KJS + c]
            velocity[i, c] += data[k, IMI] * pw
            velocity[j, c] -= data[k, IMJ] * pw
            velocity[i, 3 + c] += dwi
            velocity[j, 3 + c] -= dwj


@jit
def _world_impulse_kernel(data, tangent, impulse, out):
    """Numba: ``out = r_n n + r_t t + r_s s`` per point (P, 3), world impulses of local ones."""
    for k in range(impulse.shape[0]):
        rn, rt, rs = impulse[k, 0], impulse[k, 1], impulse[k, 2]
        for c in range(3):
            out[k, c] = rn * data[k, N0 + c] + rt * tangent[k, 0, c] + rs * tangent[k, 1, c]


@jit(parallel=True)
def _local_velocity_kernel(body, data, tangent, lever_i, lever_j, velocity, out):
    """Numba: local relative velocities ``(u_n, u_t, u_s)`` (P, 3) from world body velocities
    (points independent: all threads)."""
    for k in prange(body.shape[0]):
        i, j = body[k, 0], body[k, 1]
        wi0, wi1, wi2 = velocity[i, 3], velocity[i, 4], velocity[i, 5]
        wj0, wj1, wj2 = velocity[j, 3], velocity[j, 4], velocity[j, 5]
        ai0, ai1, ai2 = lever_i[k, 0], lever_i[k, 1], lever_i[k, 2]
        aj0, aj1, aj2 = lever_j[k, 0], lever_j[k, 1], lever_j[k, 2]
        u0 = velocity[i, 0] + wi1 * ai2 - wi2 * ai1 - velocity[j, 0] - (wj1 * aj2 - wj2 * aj1)
        u1 = velocity[i, 1] + wi2 * ai0 - wi0 * ai2 - velocity[j, 1] - (wj2 * aj0 - wj0 * aj2)
        u2 = velocity[i, 2] + wi0 * ai1 - wi1 * ai0 - velocity[j, 2] - (wj0 * aj1 - wj1 * aj0)
        out[k, 0] = data[k, N0] * u0 + data[k, N0 + 1] * u1 + data[k, N0 + 2] * u2
        out[k, 1] = tangent[k, 0, 0] * u0 + tangent[k, 0, 1] * u1 + tangent[k, 0, 2] * u2
        out[k, 2] = tangent[k, 1, 0] * u0 + tangent[k, 1, 1] * u1 + tangent[k, 1, 2] * u2


@dataclass(frozen=True)
class ContactProblem:
    """The frozen contact problem of one step, ``P`` points, ``N`` bodies (+ the wall).

    Attributes:
        time_step: h, sqrt(d/g).
        body: ``(P, 2)`` int64 bodies ``(i, j)``; ``j = N`` is the wall.
        normal_data: ``(P, 19)`` packed normal operator (module docstring).
        offset: ``(P,)`` Signorini offsets ``c_α``, sqrt(g d).
        friction_data: ``(P, 38)`` packed tangential operator, or ``None`` when frictionless.
        tangent: ``(P, 2, 3)`` tangent vectors ``t``, ``s``.
        lever_i, lever_j: ``(P, 3)`` lever arms (zero for the wall), d.
        gap: ``(P,)`` gaps at the predicted configuration, d.
        free_velocity: ``(N + 1, 6)`` world free velocities (row N: wall, zeros).
        initial_impulse: ``(P, 3)`` local impulses the solver starts from (warm start).
        side: ``(N + 1,)`` 0 or 1 per body (the lower and the upper part of the pile, whose
            points a solver may sweep in parallel), or ``None``.
    """

    time_step: float
    body: np.ndarray
    normal_data: np.ndarray
    offset: np.ndarray
    friction_data: np.ndarray | None
    tangent: np.ndarray
    lever_i: np.ndarray
    lever_j: np.ndarray
    gap: np.ndarray
    free_velocity: np.ndarray
    initial_impulse: np.ndarray
    side: np.ndarray | None = None

    @property
    def n_points(self) -> int:
        return len(self.offset)

    @property
    def n_bodies(self) -> int:
        """N (the wall row excluded)."""
        return len(self.free_velocity) - 1

    @property
    def frictional(self) -> bool:
        return self.friction_data is not None

    @property
    def normal(self) -> np.ndarray:
        """``(P, 3)`` unit normals (view)."""
        return self.normal_data[:, N0 : N0 + 3]

    @property
    def delassus(self) -> np.ndarray:
        """``(P,)`` diagonal Delassus entries W_nn (view), 1/m."""
        return self.normal_data[:, WNN]

    @property
    def mu(self) -> np.ndarray:
        """``(P,)`` friction coefficients (zeros when frictionless)."""
        return np.zeros(self.n_points) if self.friction_data is None else self.friction_data[:, MU]

    def velocity(self, impulse: np.ndarray) -> np.ndarray:
        """Body velocities ``V = V_free + M^{-1} H r`` ``(N + 1, 6)`` for local impulses ``(P, 3)``."""
        out = self.free_velocity.copy()
        fdata = self.friction_data if self.friction_data is not None else np.zeros((0, FRICTION_WIDTH))
        _apply_kernel(self.body, self.normal_data, fdata, self.tangent, np.ascontiguousarray(impulse, dtype=np.float64), out, self.frictional)
        return out

    def local_velocity(self, velocity: np.ndarray) -> np.ndarray:
        """Local relative velocities ``(u_n, u_t, u_s)`` ``(P, 3)`` of body velocities ``(N + 1, 6)``."""
        out = np.empty((self.n_points, 3))
        kernel = _local_velocity_kernel.sized(self.n_points, MIN_PARALLEL_POINTS)
        kernel(self.body, self.normal_data, self.tangent, self.lever_i, self.lever_j, velocity, out)
        return out

    def world_impulse(self, impulse: np.ndarray) -> np.ndarray:
        """World impulses on body i ``r_n n + r_t t + r_s s`` ``(P, 3)`` of local impulses ``(P, 3)``."""
        out = np.empty((self.n_points, 3))
        _world_impulse_kernel(self.normal_data, self.tangent, np.ascontiguousarray(impulse, dtype=np.float64), out)
        return out

    def residual(self, impulse: np.ndarray) -> float:
        """Relative natural-map residual of local impulses ``(P, 3)``: 0 at an exact solution.

        With ``U`` the local velocities of ``V(r)``, ``ρ_n = 1/W_nn``, ``ρ_T`` as stored (``1/W_nn``
        when frictionless) and ``D(μ r_n)`` the friction disc,

        .. math::

            e_α = \\Big(r_n - \\max(0, r_n - ρ_n (u_n + c)),\\;
                  r_T - \\mathrm{proj}_{D(μ r_n)}(r_T - ρ_T u_T)\\Big), \\qquad
            \\mathrm{res} = \\frac{\\big(\\sum_α W_{nn}^2 |e_α|^2\\big)^{1/2}}
                               {\\big(\\sum_α W_{nn}^2 |r_α|^2\\big)^{1/2}}

        (0 when every impulse is zero and every condition holds). Shared by every solver.
        """
        r = np.asarray(impulse, dtype=np.float64)
        if self.n_points == 0:
            return 0.0
        u = self.local_velocity(self.velocity(r))
        w = self.delassus
        e = np.zeros_like(r)
        rn_new = np.maximum(0.0, r[:, 0] - (u[:, 0] + self.offset) / w)
        e[:, 0] = r[:, 0] - rn_new
        if self.frictional:
            rho = self.friction_data[:, RHOT]
            trial = r[:, 1:] - rho[:, None] * u[:, 1:]
            norm = np.linalg.norm(trial, axis=1)
            limit = self.mu * rn_new
            scale = np.where(norm > limit, limit / np.where(norm > 0, norm, 1.0), 1.0)
            e[:, 1:] = r[:, 1:] - scale[:, None] * trial
        num = np.sqrt(np.sum((w[:, None] * e) ** 2))
        den = np.sqrt(np.sum((w[:, None] * r) ** 2))
        if den == 0.0:
            return float(num)
        return float(num / den)

    def projection(self, offset: np.ndarray) -> "ContactProblem":
        """The translational frictionless problem of the same points for the position correction.

        New offsets, zero free velocity, no warm start, and no angular terms: ``W_nn = 1/m_i + 1/m_j``,
        so the 'velocities' of its solution are translations only (see
        :mod:`granpack.nscd.integrator` for why rotations are left out).
        """
        data = self.normal_data.copy()
        data[:, AIN : KJN + 3] = 0.0
        data[:, WNN] = data[:, IMI] + data[:, IMJ]  # > 0: every point has a grain on one side at least
        data[:, INVW] = 1.0 / data[:, WNN]
        return replace(
            self,
            normal_data=data,
            offset=np.ascontiguousarray(offset, dtype=np.float64),
            friction_data=None,
            free_velocity=np.zeros_like(self.free_velocity),
            initial_impulse=np.zeros((self.n_points, 3)),
        )


def body_slop_scale(radius: np.ndarray) -> np.ndarray:
    """``(N + 1,)`` the factor of each body's overlap slops when they are scaled by the pair
    (``overlap.slop_scale = "pair"``): its circumscribed radius over the largest one, 1 for the wall
    (row N), so that a pair's factor, the smaller of its two, is its smaller grain's size in units
    of the largest grain's.

    Why: a slop in d bounds every pair's overlap alike, so the overlaps of the small grains of a
    wide grading are deeper relative to their size, by the size ratio, than those of the large ones.

    Args:
        radius: ``(N,)`` circumscribed radius of each grain, d.
    """
    radius = np.asarray(radius, dtype=np.float64)
    scale = np.ones(len(radius) + 1)
    if len(radius):
        scale[:-1] = radius / radius.max()
    return scale


def pair_slop_scale(body_i: np.ndarray, body_j: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """``(M,)`` the slop factor of each pair ``(body_i, body_j)`` (``body_j < 0``: a wall), the smaller
    of the two bodies' factors in ``scale`` (:func:`body_slop_scale`)."""
    body_j = np.where(np.asarray(body_j) >= 0, body_j, len(scale) - 1)
    return np.minimum(scale[np.asarray(body_i)], scale[body_j])


def assemble(
    contacts: ContactSet,
    position: np.ndarray,
    inv_mass: np.ndarray,
    inv_inertia_world: np.ndarray,
    start_velocity: np.ndarray,
    free_velocity: np.ndarray,
    time_step: float,
    *,
    restitution: float = 0.0,
    friction: float = 0.0,
    wall_friction: float | None = None,
    initial_impulse: np.ndarray | None = None,
    side: np.ndarray | None = None,
    recovery_slop: float = 0.0,
    recovery_rate: float = 0.0,
    recovery_speed: float = 0.0,
    slow_recovery_slop: float = 0.0,
    slow_recovery_speed: float = 0.0,
    slop_scale: np.ndarray | None = None,
) -> ContactProblem:
    """Build the contact problem of a step from the detected contacts.

    Args:
        contacts: the manifolds detected at the predicted configuration.
        position: ``(N, 3)`` centres of that configuration (the ones detection used), d.
        inv_mass: ``(N + 1,)`` inverse masses, last entry 0 (wall), 1/(ρ d^3).
        inv_inertia_world: ``(N + 1, 6)`` world inverse inertias (``(xx, yy, zz, xy, xz, yz)``),
            last row 0.
        start_velocity: ``(N + 1, 6)`` world velocities at t_n (for restitution).
        free_velocity: ``(N + 1, 6)`` world free velocities.
        time_step: h, sqrt(d/g).
        restitution: e_N in [0, 1].
        friction: Coulomb μ >= 0 between grains; 0 (with a frictionless wall) builds a frictionless
            problem (no tangential data).
        wall_friction: Coulomb μ >= 0 of the points against a wall (``body_j < 0``: the floor and
            a container's walls); ``None``: ``friction``.
        initial_impulse: ``(P, 3)`` local warm-start impulses, zeros if ``None``.
        recovery_slop, recovery_rate, recovery_speed: ``s_r`` (d), β and ``v_r`` (sqrt(g d)) of the
            overlap recovery (module docstring); ``recovery_rate`` 0: none.
        slow_recovery_slop, slow_recovery_speed: ``s_s`` (d) and ``v_s`` (sqrt(g d)) of its slow
            tier (module docstring); ``v_s`` 0: none.
        slop_scale: ``(N + 1,)`` a factor per body (:func:`body_slop_scale`); a pair's slops are both
            slops times the smaller factor of its two bodies. ``None``: 1 for all, the slops as given.
        side: ``(N + 1,)`` 0 or 1 per body, the two parts of the pile a solver may sweep in
            parallel (:mod:`granpack.nscd.nlgs`), or ``None``.

    Returns:
        The :class:`ContactProblem`.
    """
    p = contacts.n_points
    mu = np.array([friction, friction if wall_friction is None else wall_friction], dtype=np.float64)
    with_friction = bool(mu.max() > 0.0)
    body = np.empty((p, 2), np.int64)
    data = np.empty((p, NORMAL_WIDTH))
    offset = np.empty(p)
    tangent = np.empty((p, 2, 3))
    lever_i = np.empty((p, 3))
    lever_j = np.empty((p, 3))
    fdata = np.empty((p if with_friction else 0, FRICTION_WIDTH))
    _assemble_parallel.sized(p, MIN_PARALLEL_POINTS)(
        thread_count(),
        np.ascontiguousarray(contacts.body_i, dtype=np.int64),
        np.ascontiguousarray(contacts.body_j, dtype=np.int64),
        np.ascontiguousarray(contacts.shift, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(contacts.normal, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(contacts.point_start, dtype=np.int64),
        np.ascontiguousarray(contacts.point, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(contacts.gap, dtype=np.float64),
        np.ascontiguousarray(position, dtype=np.float64),
        inv_mass,
        inv_inertia_world,
        start_velocity,
        float(time_step),
        float(restitution),
        mu,
        body,
        data,
        offset,
        tangent,
        lever_i,
        lever_j,
        fdata,
        with_friction,
        float(recovery_slop),
        float(recovery_rate),
        float(recovery_speed),
        float(slow_recovery_slop),
        float(slow_recovery_speed),
        np.ones(len(inv_mass)) if slop_scale is None else np.ascontiguousarray(slop_scale, dtype=np.float64),
    )
    if initial_impulse is None:
        initial_impulse = np.zeros((p, 3))
    return ContactProblem(
        time_step=float(time_step),
        body=body,
        normal_data=data,
        offset=offset,
        friction_data=fdata if with_friction else None,
        tangent=tangent,
        lever_i=lever_i,
        lever_j=lever_j,
        gap=np.array(contacts.gap, dtype=np.float64),
        free_velocity=free_velocity,
        initial_impulse=np.ascontiguousarray(initial_impulse, dtype=np.float64),
        side=None if side is None else np.ascontiguousarray(side, dtype=np.int64),
    )

"""Non-linear Gauss–Seidel (NLGS) solver of a :class:`~granpack.nscd.problem.ContactProblem`.

Matrix-free (docs: Method > NSCD, NLGS): body velocities ``V`` (world rows ``(v, ω^w)``) are kept current,
starting from ``V_free + M^{-1} H r_0`` (warm start ``r_0``); each point reads its local velocity
from them, solves its local problem exactly for the normal part and updates both bodies:

.. math::

    u_n = n \\cdot (v_i - v_j) + (a_i \\times n) \\cdot ω_i - (a_j \\times n) \\cdot ω_j, \\qquad
    r_n \\leftarrow \\max\\big(0,\\, r_n - (u_n + c) / W_{nn}\\big)

    v_i \\mathrel{+}= Δr_n\\, n / m_i, \\quad ω_i \\mathrel{+}= Δr_n\\, J_{w,i}^{-1}(a_i \\times n), \\quad
    (\\text{opposite on } j)

With Coulomb friction (a separate kernel, so μ = 0 costs nothing) the tangential impulse is
projected on the disc ``|r_T| <= μ r_n`` after the normal update (maximal dissipation; its fixed
points are exactly the Signorini–Coulomb solutions):

.. math:: r_T \\leftarrow \\mathrm{proj}_{D(μ r_n)}\\big(r_T - ρ_T u_T\\big), \\qquad ρ_T = 1/\\max(W_{tt}, W_{ss})

Sweeps alternate forward and backward over the points (symmetric Gauss–Seidel, deterministic);
each pair of sweeps may get the NNCG momentum (:func:`_solve_frictionless`; with friction
:func:`_solve_coulomb`, the momentum projected on the Coulomb cone; docs: Method > NSCD, NNCG
momentum).
Convergence: LMGC90's 'Quad' norm (docs: Method > NSCD, convergence) evaluated on the sweep that ends each block
of ``check_every`` sweeps, from the last two iterates ``r^k``, ``r^{k-1}`` of each active point
(``r^k ≠ 0`` or ``r^{k-1} ≠ 0``), ``ΔU = W_αα (r^k - r^{k-1})``, ``r̄ = (r^k + r^{k-1})/2``:

.. math::

    \\mathrm{QuadDV} = \\frac{\\sqrt{Σ|ΔU|^2 / N}}{\\sqrt{Σ\\tfrac12(|W r^k|^2 + |W r^{k-1}|^2)/N}\\; tol}, \\quad
    \\mathrm{QuadDVR} = \\frac{\\sqrt{Σ|ΔU|^2 |r̄|^2 / N}}{Σ\\tfrac12(W r^k \\cdot r^k + W r^{k-1} \\cdot r^{k-1}) / N\\; tol}, \\quad
    \\mathrm{MeanDVoR} = \\frac{Σ r̄ \\cdot ΔU}{Σ\\tfrac12(W r^k \\cdot r^k + W r^{k-1} \\cdot r^{k-1})\\; tol}

converged when all three are below 1 in magnitude. The reported ``error`` is
``tol * max(|QuadDV|, |QuadDVR|, |MeanDVoR|)`` (converged ⇔ error < tol).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from granpack._numba import (MIN_PARALLEL_POINTS, atomic_add, atomic_cas, atomic_load, atomic_store, jit, prange,
                             spin_pause, thread_count)
from granpack.nscd.problem import (
    AIN,
    AIS,
    AIT,
    AJN,
    AJS,
    AJT,
    IMI,
    IMJ,
    INVW,
    KIN,
    KIS,
    KIT,
    KJN,
    KJS,
    KJT,
    MU,
    N0,
    RHOT,
    S0,
    T0,
    WBLK,
    WNN,
    ContactProblem,
)

__all__ = ["NLGSOptions", "SolverInfo", "solve"]


@dataclass(frozen=True)
class NLGSOptions:
    """NLGS settings.

    Attributes:
        tolerance: 'Quad' norm tolerance (LMGC90 default 1e-4).
        max_iterations: largest number of sweeps.
        check_every: sweeps per convergence check (LMGC90 ``gs_it1``).
        parallel_points: a frictionless problem of at least this many points whose bodies are
            split in two sides (``ContactProblem.side``) is swept by two threads
            (:func:`_solve_frictionless_two_parts`; the result does not depend on the number of
            threads Numba has); smaller ones by one (the threads' start-up would cost more than
            they save).
        nncg: the sweeps get the NNCG momentum: :func:`_solve_frictionless`, and with friction
            :func:`_solve_coulomb` (the momentum projected on the Coulomb cone; measured to converge
            wherever plain NLGS does, in half the sweeps while a pile moves: docs, design notes).
    """

    tolerance: float = 1e-4
    max_iterations: int = 2000
    check_every: int = 10
    parallel_points: int = 2**62
    nncg: bool = False

    def __post_init__(self):
        if not self.tolerance > 0:
            raise ValueError(f"tolerance must be > 0, got {self.tolerance}")
        if self.max_iterations < 1 or self.check_every < 1:
            raise ValueError("max_iterations and check_every must be >= 1")


@dataclass(frozen=True)
class SolverInfo:
    """What a solve reports.

    Attributes:
        iterations: sweeps done.
        error: ``tol * max(|QuadDV|, |QuadDVR|, |MeanDVoR|)`` at the last check (0 without active point).
        converged: whether the last check passed.
    """

    iterations: int
    error: float
    converged: bool



@jit
def _quad_error(n_act, dvdv, wrwr, dvdvrr, wrr, dvor):
    """Numba: ``max(|QuadDV|, |QuadDVR|, |MeanDVoR|) * tol`` (i.e. without the 1/tol) from the accumulated sums."""
    if n_act == 0 or wrwr <= 0.0 or wrr <= 0.0:
        return 0.0
    quad_wr = np.sqrt(wrwr / n_act)
    quad_dv = np.sqrt(dvdv / n_act) / quad_wr
    quad_dvr = np.sqrt(dvdvrr / n_act) / (wrr / n_act)
    mean_dvor = abs(dvor) / wrr
    return max(quad_dv, quad_dvr, mean_dvor)


@jit(inline="always")
def _push(d, i, j, dr, v):
    """Numba: add the velocities of a normal impulse ``dr`` at the point of data row ``d`` to bodies i and j."""
    a = dr * d[IMI]
    b = dr * d[IMJ]
    v[i, 0] += a * d[N0]
    v[i, 1] += a * d[N0 + 1]
    v[i, 2] += a * d[N0 + 2]
    v[i, 3] += dr * d[KIN]
    v[i, 4] += dr * d[KIN + 1]
    v[i, 5] += dr * d[KIN + 2]
    v[j, 0] -= b * d[N0]
    v[j, 1] -= b * d[N0 + 1]
    v[j, 2] -= b * d[N0 + 2]
    v[j, 3] -= dr * d[KJN]
    v[j, 4] -= dr * d[KJN + 1]
    v[j, 5] -= dr * d[KJN + 2]


@jit(inline="always")
def _sweep(body, data, offset, r, v, start, stop, forward, check, sums):
    """Numba: one Gauss–Seidel pass over points ``start..stop-1`` (forward or backward), in place.

    When ``check``, the 'Quad' sums of the pass's active points are added to ``sums``
    ``(n_act, dvdv, wrwr, dvdvrr, wrr, dvor)``. Inlined into its callers: a compiled call per
    point would cost a factor 2 in speed.
    """
    n = stop - start
    n_act = 0
    dvdv = wrwr = dvdvrr = wrr = dvor = 0.0
    for step in range(n):
        k = start + step if forward else stop - 1 - step
        i = body[k, 0]
        j = body[k, 1]
        d = data[k]
        u = (
            d[N0] * (v[i, 0] - v[j, 0])
            + d[N0 + 1] * (v[i, 1] - v[j, 1])
            + d[N0 + 2] * (v[i, 2] - v[j, 2])
            + d[AIN] * v[i, 3]
            + d[AIN + 1] * v[i, 4]
            + d[AIN + 2] * v[i, 5]
            - d[AJN] * v[j, 3]
            - d[AJN + 1] * v[j, 4]
            - d[AJN + 2] * v[j, 5]
        )
        r_old = r[k]
        r_new = r_old - (u + offset[k]) * d[INVW]
        if r_new < 0.0:
            r_new = 0.0
        dr = r_new - r_old
        r[k] = r_new
        _push(d, i, j, dr, v)
        if check and (r_old != 0.0 or r_new != 0.0):
            w = d[WNN]
            du = w * dr
            rbar = 0.5 * (r_new + r_old)
            n_act += 1
            dvdv += du * du
            wrwr += 0.5 * w * w * (r_new * r_new + r_old * r_old)
            dvdvrr += du * du * rbar * rbar
            wrr += 0.5 * w * (r_new * r_new + r_old * r_old)
            dvor += rbar * du
    if check:
        sums[0] += n_act
        sums[1] += dvdv
        sums[2] += wrwr
        sums[3] += dvdvrr
        sums[4] += wrr
        sums[5] += dvor


@jit
def _solve_frictionless(body, data, offset, r, v, tol, max_iterations, check_every, nncg):
    """Numba: NLGS sweeps on normal impulses ``r`` (P,) and velocities ``v`` (N + 1, 6), in place.

    With ``nncg``, each symmetric pair of sweeps (forward then backward, a fixed map ``G``) gets
    the momentum of nonsmooth nonlinear conjugate gradients (NNCG, Silcowitz, Niebe & Erleben
    2010): with ``g_k = G(r_k) - r_k`` and ``β = Σ W g_k² / Σ W g_{k-1}²``,
    ``r <- max(0, G(r_k) + β p)``, ``p <- β p + g_k`` (the velocities follow every change of
    ``r``); ``β > 1`` restarts (``p = 0``). Gauss–Seidel carries a load through a pile one layer
    per sweep, so its sweeps grow with the pile's height; the momentum carries it further.

    Returns:
        ``(sweeps, error, converged)``.
    """
    p = r.shape[0]
    if p == 0:
        return 0, 0.0, True
    error = np.inf
    sums = np.zeros(6)
    before = r.copy() if nncg else np.zeros(0)
    direction = np.zeros(p if nncg else 0)
    previous = np.inf
    for it in range(max_iterations):
        check = (it + 1) % check_every == 0 or it + 1 == max_iterations
        sums[:] = 0.0
        forward = it % 2 == 0
        _sweep(body, data, offset, r, v, 0, p, forward, check, sums)
        if check:
            error = _quad_error(sums[0], sums[1], sums[2], sums[3], sums[4], sums[5])
            if error < tol:
                return it + 1, error, True
        if nncg and not forward:
            previous = _momentum(body, data, r, v, before, direction, previous)
    return max_iterations, error, False


@jit
def _momentum(body, data, r, v, before, direction, previous):
    """Numba: the NNCG step of :func:`_solve_frictionless` after a pair of sweeps that took ``before``
    to ``r`` (in place on ``r``, ``v``, ``before``, ``direction``); returns ``Σ W g²`` of this pair."""
    p = r.shape[0]
    norm = _momentum_norm(data, r, before, 0, p)
    beta = _momentum_factor(norm, previous, direction)
    _momentum_update(body, data, r, v, before, direction, beta, 0, p)
    return norm


@jit(inline="always")
def _momentum_norm(data, r, before, start, stop):
    """Numba: ``Σ W g²`` over points ``start..stop-1``, ``g = r - before`` (the last pair of sweeps' change)."""
    norm = 0.0
    for k in range(start, stop):
        g = r[k] - before[k]
        norm += data[k, WNN] * g * g
    return norm


@jit(inline="always")
def _momentum_factor(norm, previous, direction):
    """Numba: NNCG's ``β = norm / previous``; a ``β > 1`` restarts (``direction`` zeroed, ``β = 0``)."""
    beta = norm / previous if previous > 0.0 else 0.0
    if beta > 1.0:
        direction[:] = 0.0
        beta = 0.0
    return beta


@jit(inline="always")
def _momentum_update(body, data, r, v, before, direction, beta, start, stop):
    """Numba: ``r <- max(0, r + β p)`` (velocities following), ``p <- β p + g``, ``before <- r`` on
    points ``start..stop-1``."""
    for k in range(start, stop):
        g = r[k] - before[k]
        if beta > 0.0:
            r_new = r[k] + beta * direction[k]
            if r_new < 0.0:
                r_new = 0.0
            dr = r_new - r[k]
            if dr != 0.0:
                r[k] = r_new
                _push(data[k], body[k, 0], body[k, 1], dr, v)
        direction[k] = beta * direction[k] + g
        before[k] = r[k]


#: spins (:func:`~granpack._numba.spin_pause`) the helper of the two-part sweeps makes with no
#: part to take before it leaves the solve to the leader (:func:`_help`): about 1.4 ms on a
#: 2-core x86-64 VM, some 25 times what the leader's points across take between two offers
HELPER_SPINS = 1 << 16
_WORD, _DONE = 0, 1  # the shared words of the two threads: the parts on offer, the parts swept


@jit(parallel=True)
def _solve_frictionless_two_parts(body, data, offset, r, v, bounds, tol, max_iterations, check_every, nncg):
    """Numba: the sweeps of :func:`_solve_frictionless` (same contract) with the points in three
    groups: the lower and the upper part of the pile, which share no body and are swept at once
    by two threads, and the points across them.

    A forward sweep takes the two parts at once, then the points across; a backward sweep the
    points across (backwards), then the two parts (backwards). The NNCG momentum after a backward
    sweep is applied to the points across first, then to each part just before it is swept
    forward. Each part is swept by one thread, which reads only bodies of its own part or written
    before the part was offered, so the sweeps are those of :func:`_solve_frictionless` on the
    points in the order lower, upper, across (up to the order of additions on the bodies of the
    points across), whatever the number of threads and whichever thread sweeps which part.
    ``bounds`` ``(4,)``: group g is the points ``bounds[g]..bounds[g+1]-1``. The wall (row N,
    zero inverse mass) may appear in both parts: its velocity stays 0.

    The threads are launched once per solve: one leads (:func:`_lead`: the points across, the
    checks, the momentum) and offers the two parts of each sweep, the other (:func:`_help`) takes
    what it can; the two meet through atomic words, without a system call. The serial build runs
    the leader alone, which then sweeps both parts itself.
    """
    p = r.shape[0]
    if p == 0:
        return 0, 0.0, True
    sums = np.zeros((3, 6))
    before = r.copy() if nncg else np.zeros(0)
    direction = np.zeros(p if nncg else 0)
    task = np.zeros(4)  # the sweep on offer: forward, check, momentum, beta
    shared = np.zeros(2, np.int64)
    result = np.zeros(3)
    for thread in prange(2):
        if thread == 0:
            sweeps, error, converged = _lead(body, data, offset, r, v, bounds, tol, max_iterations, check_every, nncg,
                                             sums, before, direction, task, shared)
            result[0], result[1], result[2] = sweeps, error, converged  # written here: Numba's parfors do
            # not see a called function's writes to an array of the kernel, and would read it unchanged
        else:
            _help(body, data, offset, r, v, bounds, sums, before, direction, task, shared)
    return int(result[0]), result[1], result[2] != 0.0


@jit
def _lead(body, data, offset, r, v, bounds, tol, max_iterations, check_every, nncg, sums, before, direction, task,
          shared):
    """Numba: the loop of :func:`_solve_frictionless_two_parts`, offering each sweep's two parts
    through ``shared`` and sweeping those the helper has not taken; ends by offering none (word
    -1). Returns ``(sweeps, error, converged)``."""
    error = np.inf
    previous = np.inf
    beta = 0.0
    momentum = False
    offered = 0
    sweeps, converged = max_iterations, False
    for it in range(max_iterations):
        check = (it + 1) % check_every == 0 or it + 1 == max_iterations
        forward = it % 2 == 0
        sums[:, :] = 0.0
        task[0], task[1], task[2], task[3] = forward, check, momentum and forward, beta
        if forward:
            if momentum:
                _momentum_update(body, data, r, v, before, direction, beta, bounds[2], bounds[3])
            offered = _sweep_parts(body, data, offset, r, v, bounds, sums, before, direction, task, shared, offered)
            momentum = False
            _sweep(body, data, offset, r, v, bounds[2], bounds[3], True, check, sums[2])
        else:
            _sweep(body, data, offset, r, v, bounds[2], bounds[3], False, check, sums[2])
            offered = _sweep_parts(body, data, offset, r, v, bounds, sums, before, direction, task, shared, offered)
        if check:
            error = _quad_error(sums[:, 0].sum(), sums[:, 1].sum(), sums[:, 2].sum(), sums[:, 3].sum(),
                                sums[:, 4].sum(), sums[:, 5].sum())
            if error < tol:
                sweeps, converged = it + 1, True
                break
        if nncg and not forward:
            norm = _momentum_norm(data, r, before, 0, r.shape[0])
            beta = _momentum_factor(norm, previous, direction)
            previous = norm
            momentum = True
    if momentum and not converged:  # the last sweep was backward: its momentum, as in _solve_frictionless
        _momentum_update(body, data, r, v, before, direction, beta, 0, r.shape[0])
    atomic_store(shared, _WORD, -1)
    return sweeps, error, converged


@jit
def _sweep_parts(body, data, offset, r, v, bounds, sums, before, direction, task, shared, offered):
    """Numba: offer the two parts of the sweep ``task`` (the ``offered``-th offer, counted from 0),
    sweep those not taken, and wait until both are swept; returns the offers made."""
    atomic_store(shared, _DONE, 0)
    atomic_store(shared, _WORD, 4 * (offered + 1))  # the offer number, and the parts taken (none)
    while True:
        g = _take(shared)
        if g < 0:
            break
        _sweep_part(g, body, data, offset, r, v, bounds, sums, before, direction, task)
        atomic_add(shared, _DONE, 1)
    while atomic_load(shared, _DONE) < 2:
        spin_pause()
    return offered + 1


@jit
def _help(body, data, offset, r, v, bounds, sums, before, direction, task, shared):
    """Numba: the helper of :func:`_solve_frictionless_two_parts`: sweeps the parts it takes until
    the leader offers none (word -1), or until it has spun :data:`HELPER_SPINS` times with
    nothing to take (the leader is held up: it sweeps the parts alone from then on)."""
    idle = 0
    while idle < HELPER_SPINS:
        g = _take(shared)
        if g == -2:
            return
        if g < 0:
            idle += 1
            spin_pause()
            continue
        idle = 0
        _sweep_part(g, body, data, offset, r, v, bounds, sums, before, direction, task)
        atomic_add(shared, _DONE, 1)


@jit(inline="always")
def _take(shared):
    """Numba: take a part of the offer in ``shared``: its index (0 or 1), -1 when none is left, -2
    when the solve is over."""
    while True:
        word = atomic_load(shared, _WORD)
        if word < 0:
            return -2
        if word == 0 or word % 4 >= 2:
            return -1
        if atomic_cas(shared, _WORD, word, word + 1):
            return word % 4


@jit(inline="always")
def _sweep_part(g, body, data, offset, r, v, bounds, sums, before, direction, task):
    """Numba: part g's share of the sweep ``task`` (forward, check, momentum, beta): the momentum
    update (forward, when due), then the sweep."""
    forward = task[0] != 0.0
    if forward and task[2] != 0.0:
        _momentum_update(body, data, r, v, before, direction, task[3], bounds[g], bounds[g + 1])
    _sweep(body, data, offset, r, v, bounds[g], bounds[g + 1], forward, task[1] != 0.0, sums[g])


@jit(inline="always")
def _friction_point(k, body, data, fdata, offset, r, v):
    """Numba: local Signorini–Coulomb update of point k (normal exact, tangential projected).

    Updates ``r[k]`` (local ``(r_n, r_t, r_s)``) and both bodies; returns the previous impulse
    ``(r_n, r_t, r_s)``. Inlined into the sweeps (a compiled call per point costs a factor 2, as
    for the frictionless sweep).
    """
    i = body[k, 0]
    j = body[k, 1]
    dv0 = v[i, 0] - v[j, 0]
    dv1 = v[i, 1] - v[j, 1]
    dv2 = v[i, 2] - v[j, 2]
    un = data[k, N0] * dv0 + data[k, N0 + 1] * dv1 + data[k, N0 + 2] * dv2
    ut = fdata[k, T0] * dv0 + fdata[k, T0 + 1] * dv1 + fdata[k, T0 + 2] * dv2
    us = fdata[k, S0] * dv0 + fdata[k, S0 + 1] * dv1 + fdata[k, S0 + 2] * dv2
    for c in range(3):
        wi = v[i, 3 + c]
        wj = v[j, 3 + c]
        un += data[k, AIN + c] * wi - data[k, AJN + c] * wj
        ut += fdata[k, AIT + c] * wi - fdata[k, AJT + c] * wj
        us += fdata[k, AIS + c] * wi - fdata[k, AJS + c] * wj
    rn0, rt0, rs0 = r[k, 0], r[k, 1], r[k, 2]
    rn = rn0 - (un + offset[k]) * data[k, INVW]
    if rn < 0.0:
        rn = 0.0
    rho = fdata[k, RHOT]
    rt, rs = _disc(rt0 - rho * ut, rs0 - rho * us, fdata[k, MU] * rn)
    r[k, 0], r[k, 1], r[k, 2] = rn, rt, rs
    _push3(k, body, data, fdata, rn - rn0, rt - rt0, rs - rs0, v)
    return rn0, rt0, rs0


@jit(inline="always")
def _disc(rt, rs, limit):
    """Numba: ``(r_t, r_s)`` projected on the friction disc of radius ``limit`` (``μ r_n``)."""
    norm2 = rt * rt + rs * rs
    if norm2 > limit * limit:
        scale = limit / np.sqrt(norm2)
        rt *= scale
        rs *= scale
    return rt, rs


@jit(inline="always")
def _push3(k, body, data, fdata, drn, drt, drs, v):
    """Numba: add the velocities of a local impulse ``(drn, drt, drs)`` at point k to its bodies."""
    i = body[k, 0]
    j = body[k, 1]
    a = data[k, IMI]
    b = data[k, IMJ]
    for c in range(3):
        pw = drn * data[k, N0 + c] + drt * fdata[k, T0 + c] + drs * fdata[k, S0 + c]
        v[i, c] += a * pw
        v[j, c] -= b * pw
        v[i, 3 + c] += drn * data[k, KIN + c] + drt * fdata[k, KIT + c] + drs * fdata[k, KIS + c]
        v[j, 3 + c] -= drn * data[k, KJN + c] + drt * fdata[k, KJT + c] + drs * fdata[k, KJS + c]


@jit(inline="always")
def _block_product(fdata, k, x0, x1, x2):
    """Numba: ``W_αα x`` with the symmetric diagonal block of point k (entries nn, tt, ss, nt, ns, ts)."""
    w = fdata[k]
    y0 = w[WBLK] * x0 + w[WBLK + 3] * x1 + w[WBLK + 4] * x2
    y1 = w[WBLK + 3] * x0 + w[WBLK + 1] * x1 + w[WBLK + 5] * x2
    y2 = w[WBLK + 4] * x0 + w[WBLK + 5] * x1 + w[WBLK + 2] * x2
    return y0, y1, y2


@jit(inline="always")
def _coulomb_sweep(body, data, fdata, offset, r, v, forward, check, sums):
    """Numba: one Gauss–Seidel pass of :func:`_friction_point` over every point (forward or
    backward), in place; when ``check``, the 'Quad' sums of its active points (``r_n`` or the
    previous ``r_n`` nonzero, the norms in the diagonal blocks ``W_αα``) are added to ``sums``
    ``(n_act, dvdv, wrwr, dvdvrr, wrr, dvor)``."""
    p = r.shape[0]
    for step in range(p):
        k = step if forward else p - 1 - step
        o0, o1, o2 = _friction_point(k, body, data, fdata, offset, r, v)
        if check:
            n0, n1, n2 = r[k, 0], r[k, 1], r[k, 2]
            if n0 != 0.0 or o0 != 0.0:
                d0, d1, d2 = _block_product(fdata, k, n0 - o0, n1 - o1, n2 - o2)
                wn0, wn1, wn2 = _block_product(fdata, k, n0, n1, n2)
                wo0, wo1, wo2 = _block_product(fdata, k, o0, o1, o2)
                b0, b1, b2 = 0.5 * (n0 + o0), 0.5 * (n1 + o1), 0.5 * (n2 + o2)
                du2 = d0 * d0 + d1 * d1 + d2 * d2
                sums[0] += 1
                sums[1] += du2
                sums[2] += 0.5 * (wn0 * wn0 + wn1 * wn1 + wn2 * wn2 + wo0 * wo0 + wo1 * wo1 + wo2 * wo2)
                sums[3] += du2 * (b0 * b0 + b1 * b1 + b2 * b2)
                sums[4] += 0.5 * (wn0 * n0 + wn1 * n1 + wn2 * n2 + wo0 * o0 + wo1 * o1 + wo2 * o2)
                sums[5] += b0 * d0 + b1 * d1 + b2 * d2


@jit
def _solve_coulomb(body, data, fdata, offset, r, v, tol, max_iterations, check_every, nncg):
    """Numba: NLGS sweeps with Coulomb friction on local impulses ``r`` (P, 3), in place.

    Sweeps alternate forward and backward; the 'Quad' norm is checked on the sweep that ends each
    block of ``check_every``. With ``nncg``, each symmetric pair of sweeps gets the NNCG momentum
    of :func:`_solve_frictionless`, projected on the Coulomb cone (:func:`_coulomb_momentum`).

    Returns:
        ``(sweeps, error, converged)``.
    """
    p = r.shape[0]
    if p == 0:
        return 0, 0.0, True
    error = np.inf
    sums = np.zeros(6)
    before = r.copy() if nncg else np.zeros((0, 3))
    direction = np.zeros((p if nncg else 0, 3))
    previous = np.inf
    for it in range(max_iterations):
        check = (it + 1) % check_every == 0 or it + 1 == max_iterations
        sums[:] = 0.0
        forward = it % 2 == 0
        _coulomb_sweep(body, data, fdata, offset, r, v, forward, check, sums)
        if check:
            error = _quad_error(sums[0], sums[1], sums[2], sums[3], sums[4], sums[5])
            if error < tol:
                return it + 1, error, True
        if nncg and not forward:
            previous = _coulomb_momentum(body, data, fdata, r, v, before, direction, previous)
    return max_iterations, error, False


@jit
def _coulomb_momentum(body, data, fdata, r, v, before, direction, previous):
    """Numba: the NNCG step of :func:`_solve_coulomb` after a pair of sweeps that took ``before``
    to ``r`` (in place on ``r``, ``v``, ``before``, ``direction``); returns ``Σ g·W_αα g`` of this
    pair.

    As :func:`_momentum` with the local impulses ``(r_n, r_t, r_s)``: ``g = r - before`` (the
    pair's change), ``β = Σ g_k·W g_k / Σ g_{k-1}·W g_{k-1}`` (the diagonal blocks' metric),
    ``β > 1`` restarts; ``r <- proj_C(r + β p)`` with ``proj_C`` the projection of the normal part
    on ``r_n >= 0`` then of the tangential part on the disc ``μ r_n`` (the local solution set of
    NLGS), the velocities following; ``p <- β p + g``.
    """
    p = r.shape[0]
    norm = 0.0
    for k in range(p):
        g0, g1, g2 = r[k, 0] - before[k, 0], r[k, 1] - before[k, 1], r[k, 2] - before[k, 2]
        w0, w1, w2 = _block_product(fdata, k, g0, g1, g2)
        norm += g0 * w0 + g1 * w1 + g2 * w2
    beta = _momentum_factor(norm, previous, direction)
    for k in range(p):
        g0, g1, g2 = r[k, 0] - before[k, 0], r[k, 1] - before[k, 1], r[k, 2] - before[k, 2]
        if beta > 0.0:
            rn = r[k, 0] + beta * direction[k, 0]
            if rn < 0.0:
                rn = 0.0
            rt, rs = _disc(r[k, 1] + beta * direction[k, 1], r[k, 2] + beta * direction[k, 2], fdata[k, MU] * rn)
            drn, drt, drs = rn - r[k, 0], rt - r[k, 1], rs - r[k, 2]
            if drn != 0.0 or drt != 0.0 or drs != 0.0:
                r[k, 0], r[k, 1], r[k, 2] = rn, rt, rs
                _push3(k, body, data, fdata, drn, drt, drs, v)
        direction[k, 0] = beta * direction[k, 0] + g0
        direction[k, 1] = beta * direction[k, 1] + g1
        direction[k, 2] = beta * direction[k, 2] + g2
        before[k, 0], before[k, 1], before[k, 2] = r[k, 0], r[k, 1], r[k, 2]
    return norm


@jit(parallel=True)
def _gather_points(order, body, data, offset, r):
    """Numba: the rows ``order`` of the points' bodies, packed operator, offsets and impulses
    (copies, in that order), gathered by all threads."""
    p = order.shape[0]
    body_out = np.empty((p, body.shape[1]), body.dtype)
    data_out = np.empty((p, data.shape[1]))
    offset_out = np.empty(p)
    r_out = np.empty(p)
    for k in prange(p):
        q = order[k]
        body_out[k, 0], body_out[k, 1] = body[q, 0], body[q, 1]
        for c in range(data.shape[1]):
            data_out[k, c] = data[q, c]
        offset_out[k] = offset[q]
        r_out[k] = r[q]
    return body_out, data_out, offset_out, r_out


def _two_parts(problem: ContactProblem) -> tuple[np.ndarray, np.ndarray] | None:
    """Points ordered in the three groups of :func:`_solve_frictionless_two_parts`, and the group bounds.

    The bodies are split by ``problem.side`` (0 or 1: the lower or the upper part of the pile;
    the wall counts on either side): a point whose bodies are on one side goes to that side's
    group, the others to group 2. ``None`` when the problem has no sides.
    """
    if problem.side is None:
        return None
    return _group_order(problem.body, problem.side)


@jit
def _group_order(body, side):
    """Numba: :func:`_two_parts`'s order (stable within each group) and bounds ``(4,)``."""
    wall = side.shape[0] - 1
    p = body.shape[0]
    group = np.empty(p, np.int64)
    bounds = np.zeros(4, np.int64)
    for k in range(p):
        si, sj = side[body[k, 0]], side[body[k, 1]]
        g = si if body[k, 1] == wall or si == sj else 2
        group[k] = g
        bounds[g + 1] += 1
    for g in range(3):
        bounds[g + 1] += bounds[g]
    fill = bounds[:3].copy()
    order = np.empty(p, np.int64)
    for k in range(p):
        order[fill[group[k]]] = k
        fill[group[k]] += 1
    return order, bounds


def solve(problem: ContactProblem, options: NLGSOptions) -> tuple[np.ndarray, SolverInfo]:
    """Solve the contact problem by NLGS from its warm-start impulses.

    Args:
        problem: the assembled problem (frictionless or with Coulomb friction).
        options: tolerance, sweep budget, check interval.

    Returns:
        ``(impulses, info)``: local impulses ``(P, 3)`` ``(r_n, r_t, r_s)`` in m sqrt(g d)
        (tangential zeros when frictionless) and the :class:`SolverInfo`.
    """
    r0 = problem.initial_impulse
    tol, max_it, every = float(options.tolerance), int(options.max_iterations), int(options.check_every)
    if problem.frictional:
        r = np.ascontiguousarray(r0, dtype=np.float64).copy()
        v = problem.velocity(r)
        it, err, ok = _solve_coulomb(problem.body, problem.normal_data, problem.friction_data, problem.offset, r, v,
                                     tol, max_it, every, bool(options.nncg))
        impulse = r
    else:
        impulse = np.zeros((problem.n_points, 3))
        impulse[:, 0] = r0[:, 0]
        v = problem.velocity(impulse)
        rn = np.array(r0[:, 0], dtype=np.float64)
        groups = _two_parts(problem) if problem.n_points >= options.parallel_points else None
        if groups is None:
            it, err, ok = _solve_frictionless(problem.body, problem.normal_data, problem.offset, rn, v, tol, max_it, every,
                                              bool(options.nncg))
        else:
            order, bounds = groups
            gather = _gather_points.sized(len(order), MIN_PARALLEL_POINTS)
            body, data, offset, r_sorted = gather(order, problem.body, problem.normal_data, problem.offset, rn)
            sweeps = _solve_frictionless_two_parts.sized(problem.n_points, MIN_PARALLEL_POINTS)
            threads = thread_count()
            narrowed = sweeps is _solve_frictionless_two_parts.parallel and threads > 2
            if narrowed:
                numba.set_num_threads(2)  # the other threads would only join the barriers
            try:
                it, err, ok = sweeps(body, data, offset, r_sorted, v, bounds, tol, max_it, every, bool(options.nncg))
            finally:
                if narrowed:
                    numba.set_num_threads(threads)
            rn[order] = r_sorted
        impulse[:, 0] = rn
    return impulse, SolverInfo(iterations=int(it), error=float(err), converged=bool(ok))

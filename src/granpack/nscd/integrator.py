"""One Moreau–Jean step: predict, detect, assemble, solve (NLGS), correct positions, update.

The scheme (PHYSICS.md §2.2, formulas in :mod:`granpack.nscd.rigid`): free velocities with
gravity ``(0, 0, -1)`` and the explicit gyroscopic term; contacts detected on the predicted
configuration ``x^{TT} = x^n + (1-θ) h v^n`` (periodic images carried by the contacts' shifts);
the contact problem (:mod:`granpack.nscd.problem`) solved by NLGS (:mod:`granpack.nscd.nlgs`)
from the previous step's impulses (:mod:`granpack.nscd.warmstart`); then
``x^{n+1} = x^{TT} + θ h v^{n+1} + δx`` and positions wrapped into the cell.

Position correction (keeps interpenetration small without adding kinetic energy). The
velocity-level Signorini law of the scheme (IQS, ``u_n + max(0, g)/h >= 0``) only stops
overlaps from growing; solver residuals and the rotation non-linearity let them drift. After the
velocity solve, the end-of-step gap of every point is predicted to first order,

.. math:: g^{end}_α = g_α + θ h\\, u_{n,α}^{n+1},

and when some overlap exceeds the slop ``s`` (``min g^end < -s``), a post-step projection
(post-stabilisation, Cline & Pai 2003) solves, with the same NLGS, the linear complementarity
problem for pseudo-impulses ``p`` whose 'velocities' are translations:

.. math:: 0 \\le p_α \\perp g^{end}_α + (H_x^T M^{-1} H_x p)_α + κ s \\ge 0, \\qquad
          δx = M^{-1} H_x p, \\quad δφ = 0

(``H_x`` the translational rows of ``H``: ``n`` on body i, ``-n`` on j), i.e. the smallest
mass-weighted translations that bring every linearised gap to ``>= -κ s``, with ``κ`` =
``CORRECTED_OVERLAP`` (0.1: nearly the whole overlap, see below). Rotations are left
out on purpose: in the mass metric a rotation of a small grain is cheap, and a small grain wedged
between larger ones was turned by 20-30 degrees per step, far outside the linearisation, into
its other neighbours (overlaps of 0.05 d that the next projection moved elsewhere, a pile kept
agitated; translations only: 0.015 d at worst, measured on a bidisperse pour, size ratio 3).
No body is pushed further than the overlap it had (no ejection), nor, in one step, by more
than ``correction_step`` (1e-3 d) in each of two passes (overlaps deeper than that are removed
over several steps):

1. the projection above, each body's translation then scaled down to ``correction_step``;
2. if some body was bounded, the bounded bodies are held still (inverse mass 0) and the others solve
   the same projection with offsets ``max(g^{end}_α + κ s, 0) + n_α·(δx_i - δx_j)``: no contact
   may end deeper than it was before the correction, nor a non-overlapping one below
   ``-κ s``; their translations are scaled by one common factor to ``correction_step``.

Pass 1's bound alone is inconsistent: a grain lifted by a deep overlap below it (scaled down 20
times) no longer makes room for a neighbour pushed sideways into it by a small overlap (not
scaled), and the correction itself digs new overlaps of up to ``correction_step`` per step. In
piles of thin plates (flat and flat & elongated pinacoids) this outran the correction: after
landing, overlaps grew to 0.1-0.2 d, deeper than the plates are thick. Pass 2 undoes it: the
translations that satisfy its constraints form a convex set holding 0 (where pass 1 dug
nothing) and its solution, so the common factor keeps them satisfied. One common factor for the
whole correction (instead of pass 2) is consistent too, but while one overlap is deep (a small
grain wedged between large ones, an impact) it slows the correction of every other: measured on
400 flat grains (L/G 1, G/E 3, 2.25 d cell, 30 sqrt(d/g)), the common factor ended with overlaps
of 0.057 d (mean 5.6e-3, 48 m g d added by the correction), the two passes with 3.4e-3 d (mean
1.5e-4, 12 m g d); 400 flat & elongated grains: per-body bound 0.091 d at t = 20, two passes
4.3e-3 d (mean 2.5e-4) at the end. Asking each contact for at most ``correction_step`` (Box2D's
clamp) with one common factor corrected faster still and fed the treadmill below (flat &
elongated grains reached 0.13 d). Without the bound the correction and
the gap anticipation of IQS (``u_n >= -g/h``) fed each other: a corrected grain fell back, at the
speed it had, into the gaps the correction had opened around it, and the next correction lifted
it again: a treadmill that kept a column of 600 flat & elongated grains 'falling' at up to
4 sqrt(g d) (0.35 at the bottom, 4.1 at the top) while it stood still, with a kinetic energy of
65 m g d and 717 m g d of potential energy added by the correction at the end of a 35 sqrt(d/g)
run. The bound caps the speed such a cycle can reach at ``2 correction_step / h`` (0.4 sqrt(g d)),
below which the velocity solve stops it (300 flat grains in a 2.25 d cell after 30 sqrt(d/g):
wall force 1.009 weight, kinetic energy 2e-3 m g d, mean overlap 1.8e-4 d). Zeroing the
velocity against the correction instead also breaks the cycle, but acts as a drag on every
corrected grain (solid fraction 0.55 instead of 0.65, wall force 0.11 weight) and, along ``δx``,
does not conserve horizontal momentum. Velocities are not changed by the correction; the
energy it adds is the potential energy ``Σ m g δz`` of lifting overlapping grains back to
contact, which :class:`StepInfo` reports as ``correction_energy`` so that energy budgets can
account for it. Overlaps then stay below about ``s`` (plus the detection and linearisation
error).

Where the overlaps come from (measured on the demo pile, 300 isometric pinacoids, by comparing
each step's predicted end gaps ``g^{end} + n·(δx_i - δx_j)`` with a detection at the end
configuration, and by continuing a pile at rest; ``benchmarks/overlap_study.py``):

- Points left out of a contact: the narrow phase reduced a clipped contact polygon (up to eight
  vertices for two pinacoid faces) to four points, and a grain rocking about those sank the
  others into its neighbour, even in a pile at rest (1000 steps from the demo pile at
  t = 60: 42 pairs 1e-5 to 1.2e-4 d deeper). Every vertex is now a point
  (:mod:`granpack.contact.narrowphase`): no pair deeper by more than 1e-5 d. With the
  reduction, a small ``s`` kept the correction busy at rest (16 % of the steps, 1300 NLGS sweeps
  per step, the pile never at rest: largest net force 3e-2 d^2 P after 150 sqrt(d/g)).
- Phantom overlaps: along the face normal that the axis hysteresis keeps (within ``eps_f`` =
  1e-3 d of the best separating axis) a tilted face-on-face pair overlapped by up to 1e-3 d more
  than its penetration depth, and the correction pushed the grains along the face normal by
  them (``s`` = 1e-4 with them: correction at every step, kinetic energy 3.6e-2 m g d, 64 m g d
  added in 60 sqrt(d/g)). Gaps are never below the penetration depth now.
- A face-face contact that had begun as an edge-edge one was kept as a single point by the
  contact hysteresis, its corners free to sink (45 % of the overlap growth between steps of a
  collapsing pile); fixed in the narrow phase.
- What remains is made while the pile settles (the NLGS residual at the settling tolerance
  1e-3, impacts) and is what the correction removes.

Measured on the demo (60 sqrt(d/g), seeds 1, 2, 3; penetration depths of the final touching
pairs, d; largest net force on a grain, d^2 P; NLGS sweeps per step; tables in
benchmarks/README.md):

- default (every polygon vertex a point, exact depths, ``s`` = 1e-4, ``κ`` = 0.1): max depth
  4.9e-5, 8.7e-5, 5.5e-5; mean per pair 8.9e-6, 1.1e-5, 9.4e-6; net force 3.3e-4, 2.6e-4,
  6.7e-4; 88, 89, 81 sweeps;
- before (four points, depths along the hysteresis face axis, ``s`` = 5e-3 corrected to
  ``s/2``): max depth 2.9e-3, 4.0e-3, 1.6e-3; mean 1.3e-4, 1.3e-4, 1.0e-4; net force 5.5e-4,
  4.1e-4, 1.2e-3; 59, 155, 76 sweeps.

The corrections die out as the pile comes to rest (none after about 45-55 sqrt(d/g)), the NLGS
then converging in its first check (10 sweeps). The target ``κ`` matters as much as ``s``: a
correction that leaves half the slop holds many contacts at ``-s/2`` and the velocity NLGS then
needed about 1700 sweeps per step at rest; one that leaves a tenth (``CORRECTED_OVERLAP``)
brings the contacts back nearly to touching; one that leaves 0.9 of it corrected at every step
and kept the pile moving (measured with the four-point manifolds).

The projection gets at most ``correction_sweeps`` (200) NLGS sweeps: lifting a column by
Gauss–Seidel converges slowly (on
a pour of flat grains it used its 2000 sweeps at every step, 4 times the cost of the velocity
solve); a partial correction, which pushes less than the full one, is completed at the next
steps (measured on 250 isometric pinacoids: half the run time, mean overlap 4.3e-4 d vs 5.1e-4).

Energy (e_N = 0, μ = 0). The budget of a step is ``ΔE - correction_energy``. With θ = 1 it is
``Σ_α r_α u^{n+1}_α - ½|ΔV|²_M <= 0`` (strictly dissipative). With θ = ½ the impulses work at
the mean velocity, ``Σ_α r_α (u^n_α + u^{n+1}_α)/2``, and since ``u^{n+1}_α <= 0`` wherever
``r_α > 0`` a step gains at most ``Σ_α r_α max(0, u^n_α)/2`` (a contact pushing although it was
opening at t_n): tiny (measured <= 1e-9 of E on a pour) but not zero. Both are checked in
tests/test_nscd_dynamics.py.

Alert distance: detection sees a pair when its gap at ``TT`` is at most ``params.alert``; a gap
larger than that must not close within one step, so the alert must exceed the largest approach
per step, ``2 h max(|v| + r|ω|) + g h²`` (:func:`granpack.nscd.rigid.required_alert`). The
default 0.05 d covers grains up to 5 sqrt(g d) at h = 5e-3; a pour reaching 8 sqrt(g d) needs
0.08 d or more, otherwise a contact can appear already interpenetrating by up to the missing
distance (IQS does not push it back; the position correction then removes it).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from granpack.contact.contacts import ContactSet
from granpack.nscd.nlgs import NLGSOptions, solve
from granpack.nscd.problem import assemble
from granpack.nscd.rigid import predict_kernel, update_kernel
from granpack.nscd.warmstart import warm_impulses
from granpack.state import ParticleState

__all__ = ["StepParameters", "StepInfo", "Prediction", "predict", "advance", "step", "CORRECTED_OVERLAP"]

#: overlap left by a position correction, as a fraction of the slop (module docstring)
CORRECTED_OVERLAP = 0.1


@dataclass(frozen=True)
class StepParameters:
    """Settings of a Moreau–Jean step (units: d, sqrt(d/g)).

    Attributes:
        time_step: h, sqrt(d/g).
        theta: θ of the scheme, in [0.5, 1].
        friction: Coulomb μ >= 0 (0: frictionless kernel).
        restitution: normal restitution e_N in [0, 1].
        tolerance: NLGS 'Quad' norm tolerance.
        max_iterations: NLGS sweep budget per solve.
        check_every: sweeps per convergence check.
        alert: detection distance, d.
        overlap_slop: overlap above which positions are corrected (to ``CORRECTED_OVERLAP`` of it), d;
            ``0`` disables the correction. The default (1e-4 d) keeps every overlap of a pile at
            rest below about 1e-4 d; 5e-3 leaves overlaps of up to 5e-3 d (module docstring).
        warm_tolerance: warm-start matching distance, as a fraction of the smallest grain size.
        correction_sweeps: NLGS sweep budget of the position correction (at most
            ``max_iterations``); a partial correction is completed at the next steps.
        correction_step: largest translation of a body by one position correction, d.
    """

    time_step: float = 5e-3
    theta: float = 0.5
    friction: float = 0.0
    restitution: float = 0.0
    tolerance: float = 1e-4
    max_iterations: int = 2000
    check_every: int = 10
    alert: float = 0.05
    overlap_slop: float = 1e-4
    warm_tolerance: float = 0.05
    correction_sweeps: int = 200
    correction_step: float = 1e-3

    def __post_init__(self):
        if not self.time_step > 0:
            raise ValueError(f"time_step must be > 0, got {self.time_step}")
        if not 0.5 <= self.theta <= 1.0:
            raise ValueError(f"theta must be in [0.5, 1], got {self.theta}")
        if not self.friction >= 0:
            raise ValueError(f"friction must be >= 0, got {self.friction}")
        if not 0.0 <= self.restitution <= 1.0:
            raise ValueError(f"restitution must be in [0, 1], got {self.restitution}")
        if not self.alert >= 0 or not self.overlap_slop >= 0 or not self.warm_tolerance >= 0:
            raise ValueError("alert, overlap_slop and warm_tolerance must be >= 0")
        if self.correction_sweeps < 1:
            raise ValueError(f"correction_sweeps must be >= 1, got {self.correction_sweeps}")
        if not self.correction_step > 0:
            raise ValueError(f"correction_step must be > 0, got {self.correction_step}")

    @property
    def solver_options(self) -> NLGSOptions:
        return NLGSOptions(tolerance=self.tolerance, max_iterations=self.max_iterations, check_every=self.check_every)

    @property
    def correction_options(self) -> NLGSOptions:
        sweeps = min(self.correction_sweeps, self.max_iterations)
        return NLGSOptions(tolerance=self.tolerance, max_iterations=sweeps, check_every=self.check_every)


@dataclass(frozen=True)
class StepInfo:
    """Diagnostics of one step.

    Attributes:
        iterations: NLGS sweeps of the velocity solve.
        error: its final 'Quad' error (see :mod:`granpack.nscd.nlgs`).
        converged: whether it met the tolerance.
        n_contacts: manifolds.
        n_points: contact points.
        n_warm: points warm-started from the previous step.
        max_overlap: largest overlap ``max(0, -g)`` at the predicted configuration, d.
        correction_iterations: NLGS sweeps of the position correction (0 when not needed).
        correction_energy: potential energy ``Σ m g δz`` added by the position correction, m g d.
        solver_seconds: assembly, warm start, solves and update, s.
        detection_seconds: contact detection, s.
    """

    iterations: int
    error: float
    converged: bool
    n_contacts: int
    n_points: int
    n_warm: int
    max_overlap: float
    correction_iterations: int
    correction_energy: float
    solver_seconds: float
    detection_seconds: float


@dataclass(frozen=True)
class Prediction:
    """The predicted configuration of a step and what the solve needs from the bodies.

    Attributes:
        state: the bodies at ``TT`` (positions wrapped), what detection sees.
        x_tt: ``(N, 3)`` predicted centres (wrapped, same as ``state.position``).
        rot_tt: ``(N, 3, 3)`` rotation matrices at TT.
        inv_mass: ``(N + 1,)`` inverse masses, wall last (0).
        inv_inertia_world: ``(N + 1, 6)`` world inverse inertias at TT.
        start_velocity, free_velocity: ``(N + 1, 6)`` world generalised velocities.
    """

    state: ParticleState
    x_tt: np.ndarray
    rot_tt: np.ndarray
    inv_mass: np.ndarray
    inv_inertia_world: np.ndarray
    start_velocity: np.ndarray
    free_velocity: np.ndarray


def predict(state: ParticleState, params: StepParameters) -> Prediction:
    """Predicted configuration ``x^TT``, ``q^TT`` and free velocities of a step (state unchanged)."""
    n = state.n
    x_tt = np.empty((n, 3))
    q_tt = np.empty((n, 4))
    rot_tt = np.empty((n, 3, 3))
    inv_iw = np.empty((n + 1, 6))
    v_start = np.empty((n + 1, 6))
    v_free = np.empty((n + 1, 6))
    predict_kernel(
        state.position, state.quaternion, state.velocity, state.omega, np.ascontiguousarray(state.inertia),
        float(params.time_step), float(params.theta), x_tt, q_tt, rot_tt, inv_iw, v_start, v_free,
    )
    x_tt = state.box.wrap(x_tt)
    inv_mass = np.zeros(n + 1)
    inv_mass[:n] = 1.0 / state.mass
    tt = ParticleState(
        box=state.box, shapes=state.shapes, kind=state.kind, population=state.population,
        position=x_tt, quaternion=q_tt, velocity=state.velocity, omega=state.omega, time=state.time,
    )
    return Prediction(tt, x_tt, rot_tt, inv_mass, inv_iw, v_start, v_free)


def advance(
    state: ParticleState,
    prediction: Prediction,
    contacts: ContactSet,
    params: StepParameters,
    warm: ContactSet | None = None,
    detection_seconds: float = 0.0,
) -> tuple[ContactSet, StepInfo]:
    """Finish a step from the contacts detected at the predicted configuration (state advanced in place).

    Args:
        state: the state at t_n (becomes the state at t_{n+1}).
        prediction: ``predict(state, params)``.
        contacts: the contacts at the predicted configuration.
        params: step settings.
        warm: the previous step's returned contacts (impulses), or ``None``.
        detection_seconds: reported in the :class:`StepInfo`.

    Returns:
        ``(contacts, info)``: ``contacts`` with ``impulse`` set (world impulse on body i over the
        step, per point; force = impulse / h).
    """
    t0 = time.perf_counter()
    h, theta = float(params.time_step), float(params.theta)
    pr = prediction
    problem = assemble(
        contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, h,
        restitution=params.restitution, friction=params.friction,
    )
    tol_warm = params.warm_tolerance * 2.0 * float(state.shapes.radius.min())
    r0, n_warm = warm_impulses(
        warm, contacts, problem.tangent, pr.x_tt, pr.rot_tt, state.velocity, state.omega, h,
        (state.box.lx, state.box.ly), tol_warm, params.friction,
    )
    problem = replace(problem, initial_impulse=r0)
    impulse, info = solve(problem, params.solver_options)
    v_end = problem.velocity(impulse)
    displacement = np.zeros_like(v_end)
    correction_iterations = 0
    correction_energy = 0.0
    max_overlap = float(max(0.0, -problem.gap.min())) if problem.n_points else 0.0
    if problem.n_points and params.overlap_slop > 0:
        gap_end = problem.gap + theta * h * problem.local_velocity(v_end)[:, 0]
        if gap_end.min() < -params.overlap_slop:
            displacement, correction_iterations = _position_correction(problem, gap_end, params)
            correction_energy = float(np.sum(state.mass * displacement[:-1, 2]))
    update_kernel(
        pr.x_tt, pr.state.quaternion, pr.rot_tt, v_end, displacement, h, theta, state.box.lx, state.box.ly,
        state.position, state.quaternion, state.velocity, state.omega,
    )
    state.time += h
    contacts.impulse = problem.world_impulse(impulse)
    solver_seconds = time.perf_counter() - t0
    return contacts, StepInfo(
        iterations=info.iterations,
        error=info.error,
        converged=info.converged,
        n_contacts=contacts.n_manifolds,
        n_points=contacts.n_points,
        n_warm=n_warm,
        max_overlap=max_overlap,
        correction_iterations=correction_iterations,
        correction_energy=correction_energy,
        solver_seconds=solver_seconds,
        detection_seconds=detection_seconds,
    )


def _position_correction(problem, gap_end: np.ndarray, params: StepParameters) -> tuple[np.ndarray, int]:
    """Bounded post-step projection (see the module docstring): ``(displacements (N + 1, 6), sweeps)``.

    Pass 1 projects every linearised gap to ``>= -κ s`` and bounds each body's translation to
    ``correction_step``. When a bound binds, pass 2 holds the bounded bodies still and moves the
    others so that no contact ends deeper than before the correction (what pass 1's bound dug),
    its translations scaled by one common factor to the same bound.
    """
    c = params.correction_step
    target = gap_end + CORRECTED_OVERLAP * params.overlap_slop
    first = problem.projection(target)
    pseudo, info = solve(first, params.correction_options)
    sweeps = info.iterations
    displacement = first.velocity(pseudo)
    length = np.linalg.norm(displacement[:, :3], axis=1)
    held = length > c
    if not held.any():
        return displacement, sweeps
    displacement *= np.minimum(1.0, c / np.maximum(length, 1e-300))[:, None]
    moved = first.local_velocity(displacement)[:, 0]
    second = problem.projection(np.maximum(target, 0.0) + moved, held=held)
    if second.offset.min() < 0.0:
        pseudo, info = solve(second, params.correction_options)
        sweeps += info.iterations
        extra = second.velocity(pseudo)
        longest = float(np.linalg.norm(extra[:, :3], axis=1).max())
        displacement += extra * min(1.0, c / max(longest, 1e-300))
    return displacement, sweeps


def step(state: ParticleState, params: StepParameters, warm: ContactSet | None = None) -> tuple[ContactSet, StepInfo]:
    """Advance ``state`` in place by one Moreau–Jean step.

    Args:
        state: bodies at t_n (positions wrapped; omega in the body frame).
        params: step settings.
        warm: the contacts returned by the previous step (warm start), or ``None``.

    Returns:
        ``(contacts, info)``: the contacts of the step (detected at the predicted configuration)
        with their per-point world impulses on body i (``impulse``, force = impulse / h), and the
        :class:`StepInfo`.
    """
    from granpack.contact import detect

    prediction = predict(state, params)
    t0 = time.perf_counter()
    contacts = detect(prediction.state, params.alert, previous=warm)
    detection_seconds = time.perf_counter() - t0
    return advance(state, prediction, contacts, params, warm, detection_seconds)

"""One Moreau–Jean step: predict, detect, assemble, solve (NLGS), correct positions, update.

The scheme (docs: Method > NSCD, formulas in :mod:`granpack.nscd.rigid`): free velocities with
gravity (``StepParameters.gravity``, ``(0, 0, -1)``) and the explicit gyroscopic term; contacts
detected on the predicted configuration ``x^{TT} = x^n + (1-θ) h v^n`` (periodic images carried
by the contacts' shifts); the contact problem (:mod:`granpack.nscd.problem`) solved by NLGS
(:mod:`granpack.nscd.nlgs`) from the previous step's impulses (:mod:`granpack.nscd.warmstart`); then
``x^{n+1} = x^{TT} + θ h v^{n+1} + δx`` and positions wrapped into a periodic cell.

Position correction (docs: Method > Overlap recovery and position correction). The velocity law
pushes back overlaps deeper than ``recovery_slop`` at a bounded speed (:mod:`granpack.nscd.problem`);
the projection here is the backstop for deeper ones, those an impact leaves. After the velocity
solve the end-of-step gap of every point is predicted to first order,

.. math:: g^{end}_α = g_α + θ h\\, u_{n,α}^{n+1},

and when some overlap exceeds the slop ``s`` (``min g^end < -s``; each point's ``s`` times its
pair's slop factor when the slops are scaled by the pair, :func:`granpack.nscd.problem.body_slop_scale`),
a post-step projection
(post-stabilisation, Cline & Pai 2003) solves, with the same NLGS, the linear complementarity
problem for pseudo-impulses ``p`` whose 'velocities' are translations:

.. math:: 0 \\le p_α \\perp g^{end}_α + (H_x^T M^{-1} H_x p)_α + κ s \\ge 0, \\qquad
          δx = M^{-1} H_x p, \\quad δφ = 0

(``H_x`` the translational rows of ``H``), i.e. the smallest mass-weighted translations that bring
every linearised gap to ``>= -κ s``, ``κ = CORRECTED_OVERLAP``. Velocities are not changed (no
kinetic energy is added); the potential energy ``Σ m g δz`` of the lift is reported
(``StepInfo.correction_energy``). Why it is built this way, in short (the measurements are in the
docs' design notes):

- translations only: in the mass metric a rotation of a small grain is cheap, and grains wedged
  between larger ones were turned far outside the linearisation;
- no body moves by more than ``correction_step`` in one step, and the bound is one common factor
  on every translation: an unbounded correction and the gap anticipation of IQS fed each other
  (a corrected grain fell back into the gaps the correction opened); a per-body bound dug new
  overlaps, and where most bodies of a column reached it, it lifted the column rigidly, which fell
  back at the next step, every step (a pile of flat pinacoids never came to rest);
- ``κ = 0.1``: a correction that leaves half the slop holds many contacts at ``-s/2`` and the
  velocity solve then needed far more sweeps at rest;
- at most ``correction_sweeps`` NLGS sweeps: a partial correction is completed at the next steps.

End-game damping (:mod:`granpack.settling` decides when): with ``damping`` γ > 0 every velocity
is scaled by ``e^{-γ h}`` after the update, and the kinetic energy removed is reported
(``StepInfo.damped_energy``).

Energy (e_N = 0, μ = 0). The budget of a step is ``ΔE - correction_energy + damped_energy``. With
θ = 1 it is ``Σ_α r_α u^{n+1}_α - ½|ΔV|²_M <= 0`` (strictly dissipative). With θ = ½ the impulses
work at the mean velocity, ``Σ_α r_α (u^n_α + u^{n+1}_α)/2``, and a step gains at most
``Σ_α r_α max(0, u^n_α)/2`` (a contact pushing although it was opening at t_n): tiny, not zero.
Both are checked in tests/test_nscd_dynamics.py.

Alert distance: detection sees a pair when its gap at ``TT`` is at most ``params.alert``; a larger
gap must not close within one step, so the alert must exceed the largest approach per step,
``2 h max(|v| + r|ω|) + g h²`` (:func:`granpack.nscd.rigid.required_alert`); otherwise a contact
can appear already interpenetrating by up to the missing distance.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace


import numpy as np

from granpack._numba import thread_count
from granpack.contact.contacts import ContactSet
from granpack.nscd.nlgs import NLGSOptions, solve
from granpack.nscd.problem import assemble, body_slop_scale
from granpack.nscd.rigid import kinetic_energy, predict_kernel, update_kernel
from granpack.nscd.warmstart import warm_impulses
from granpack.state import ParticleState

__all__ = ["StepParameters", "StepInfo", "Prediction", "predict", "advance", "step", "CORRECTED_OVERLAP"]

#: overlap left by a position correction, as a fraction of the slop (module docstring)
CORRECTED_OVERLAP = 0.1


@dataclass(frozen=True)
class StepParameters:
    """Settings of a Moreau–Jean step (units: d, sqrt(d/g)).

    A run builds its own from its config with :func:`granpack.settling.step_parameters`; the
    defaults here are plain numbers, those of a run config's settings (``alert`` the automatic one
    of grains of size 1 d; tests/test_config.py holds them to :mod:`granpack.config`), so that the
    step depends on no config schema.

    Attributes:
        time_step: h, sqrt(d/g).
        theta: θ of the scheme, in [0.5, 1].
        rotation_from_start: the end orientation is the start one turned by ``h ω^{n+1}``
            (``time_stepping.rotation_update = "from-start"``, :func:`granpack.nscd.rigid.update_kernel`);
            otherwise ``q^TT`` turned by ``θ h ω^{n+1}``, the θ scheme.
        friction: Coulomb μ >= 0 between grains (0: frictionless kernel).
        wall_friction: Coulomb μ >= 0 against the walls (the floor and a container's walls);
            ``None``: ``friction`` (a run's ``container.wall_friction``).
        restitution: normal restitution e_N in [0, 1].
        tolerance: NLGS 'Quad' norm tolerance.
        max_iterations: NLGS sweep budget per solve.
        check_every: sweeps per convergence check.
        alert: detection distance, d.
        overlap_slop: overlap above which positions are corrected (to ``CORRECTED_OVERLAP`` of it), d;
            ``0`` disables the correction (a run's ``overlap.projection_slop``).
        warm_tolerance: warm-start matching distance, as a fraction of the smallest grain size.
        correction_sweeps: NLGS sweep budget of the position correction (at most
            ``max_iterations``); a partial correction is completed at the next steps.
        correction_step: largest translation of a body by one position correction, d.
        recovery_slop, recovery_rate, recovery_speed: the overlap recovery of the velocity law
            (:mod:`granpack.nscd.problem`): an overlap deeper than ``recovery_slop`` (d) is pushed
            back at ``recovery_rate`` of its excess per step, at most at ``recovery_speed``
            (sqrt(g d)); ``recovery_rate`` 0: none.
        slow_recovery_slop, slow_recovery_speed: its slow tier: an overlap deeper than
            ``slow_recovery_slop`` (d) is pushed back at ``recovery_rate`` of that excess per step, at
            most at ``slow_recovery_speed`` (sqrt(g d)); speed 0: none (a pile at rest,
            :mod:`granpack.settling`).
        slops_by_pair: every slop above (recovery, slow tier, projection) is, for each pair,
            multiplied by its smaller grain's circumscribed size over the largest grain's
            (:func:`granpack.nscd.problem.body_slop_scale`), so that the overlap relative to the
            pair's grains is bounded alike; ``False``: the slops in d for every pair
            (``overlap.slop_scale``).
        damping: rate γ of a viscous damping of every grain's velocity after the step,
            ``(v, ω) <- e^{-γ h} (v, ω)``, 1/sqrt(d/g); 0: none (the end game of a settling run,
            :mod:`granpack.settling`).
        parallel_points: frictionless problems of at least this many points are swept by two
            threads, the lower and the upper part of the pile at once (:func:`_sides`,
            :func:`granpack.nscd.nlgs.solve`).
        nncg: the velocity solve (frictionless or with friction) and the position correction use
            the NNCG momentum (:mod:`granpack.nscd.nlgs`).
        gravity: acceleration of gravity ``(g_x, g_y, g_z)``, g. A run always has ``(0, 0, -1)``
            (no config key: the wall is the floor, and the equilibrium criteria, the energies and
            the alert distance take gravity vertical). Tests tilt it, ``(sin θ, 0, -cos θ)``, to
            put a grain on an incline of angle θ whose surface is the wall: the exact results of
            Coulomb friction (stick below ``tan θ = μ``, slide at ``g (sin θ - μ cos θ)`` above,
            roll at ``5/7 g sin θ``) need a slope, and the engine's only plane is the wall.
    """

    time_step: float = 5e-3
    theta: float = 0.5
    rotation_from_start: bool = False
    friction: float = 0.0
    wall_friction: float | None = None
    restitution: float = 0.0
    tolerance: float = 1e-4
    max_iterations: int = 2000
    check_every: int = 10
    alert: float = 0.02
    overlap_slop: float = 2e-3
    warm_tolerance: float = 0.05
    correction_sweeps: int = 200
    correction_step: float = 1e-3
    recovery_slop: float = 5e-4
    recovery_rate: float = 0.2
    recovery_speed: float = 0.05
    slow_recovery_slop: float = 0.0
    slow_recovery_speed: float = 0.0
    slops_by_pair: bool = False
    damping: float = 0.0
    parallel_points: int = 2000
    nncg: bool = True
    gravity: tuple[float, float, float] = (0.0, 0.0, -1.0)

    def __post_init__(self):
        if not self.time_step > 0:
            raise ValueError(f"time_step must be > 0, got {self.time_step}")
        if not 0.5 <= self.theta <= 1.0:
            raise ValueError(f"theta must be in [0.5, 1], got {self.theta}")
        if not self.friction >= 0:
            raise ValueError(f"friction must be >= 0, got {self.friction}")
        if self.wall_friction is not None and not self.wall_friction >= 0:
            raise ValueError(f"wall_friction must be >= 0, got {self.wall_friction}")
        if not 0.0 <= self.restitution <= 1.0:
            raise ValueError(f"restitution must be in [0, 1], got {self.restitution}")
        if not self.alert >= 0 or not self.overlap_slop >= 0 or not self.warm_tolerance >= 0:
            raise ValueError("alert, overlap_slop and warm_tolerance must be >= 0")
        if self.correction_sweeps < 1:
            raise ValueError(f"correction_sweeps must be >= 1, got {self.correction_sweeps}")
        if not min(self.recovery_slop, self.recovery_rate, self.recovery_speed, self.slow_recovery_slop,
                   self.slow_recovery_speed) >= 0:
            raise ValueError("recovery_slop, recovery_rate, recovery_speed and the slow tier's slop and speed "
                             "must be >= 0")
        if not self.correction_step > 0:
            raise ValueError(f"correction_step must be > 0, got {self.correction_step}")
        if len(self.gravity) != 3 or not all(np.isfinite(self.gravity)):
            raise ValueError(f"gravity must be three finite numbers, got {self.gravity}")

    @property
    def solver_options(self) -> NLGSOptions:
        return NLGSOptions(tolerance=self.tolerance, max_iterations=self.max_iterations, check_every=self.check_every,
                           parallel_points=self.parallel_points, nncg=self.nncg)

    @property
    def correction_options(self) -> NLGSOptions:
        sweeps = min(self.correction_sweeps, self.max_iterations)
        return NLGSOptions(tolerance=self.tolerance, max_iterations=sweeps, check_every=self.check_every,
                           parallel_points=self.parallel_points, nncg=self.nncg)


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
        damped_energy: kinetic energy removed by the damping (0 without it), m g d.
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
    damped_energy: float
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
    predict_kernel.sized(n)(
        state.position, state.quaternion, state.velocity, state.omega, np.ascontiguousarray(state.inertia),
        float(params.time_step), float(params.theta), np.asarray(params.gravity, dtype=np.float64), x_tt, q_tt, rot_tt,
        inv_iw, v_start, v_free, thread_count(),
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
    warm_time_step: float | None = None,
) -> tuple[ContactSet, StepInfo]:
    """Finish a step from the contacts detected at the predicted configuration (state advanced in place).

    Args:
        state: the state at t_n (becomes the state at t_{n+1}).
        prediction: ``predict(state, params)``.
        contacts: the contacts at the predicted configuration.
        params: step settings.
        warm: the previous step's returned contacts (impulses), or ``None``.
        detection_seconds: reported in the :class:`StepInfo`.
        warm_time_step: the step over which ``warm``'s impulses were taken, when it differs from
            ``params.time_step``: they are scaled by ``h / warm_time_step`` (a resting contact
            carries ``m g h``), so a change of step does not start the solve from wrong loads.

    Returns:
        ``(contacts, info)``: ``contacts`` with ``impulse`` set (world impulse on body i over the
        step, per point; force = impulse / h).
    """
    t0 = time.perf_counter()
    h, theta = float(params.time_step), float(params.theta)
    pr = prediction
    scale = body_slop_scale(state.radius) if params.slops_by_pair else None
    problem = assemble(
        contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, h,
        restitution=params.restitution, friction=params.friction,
        wall_friction=params.wall_friction,
        side=_sides(pr.x_tt, contacts.point[:, 2]) if contacts.n_points >= params.parallel_points else None,
        recovery_slop=params.recovery_slop, recovery_rate=params.recovery_rate, recovery_speed=params.recovery_speed,
        slow_recovery_slop=params.slow_recovery_slop, slow_recovery_speed=params.slow_recovery_speed,
        slop_scale=scale,
    )
    tol_warm = params.warm_tolerance * 2.0 * float(state.shapes.radius.min())
    r0, n_warm = warm_impulses(
        warm, contacts, problem.tangent, pr.x_tt, pr.rot_tt, state.velocity, state.omega, h,
        (state.box.lx, state.box.ly), tol_warm, params.friction,
        params.friction if params.wall_friction is None else params.wall_friction,
    )
    if warm_time_step is not None and warm_time_step != h:
        r0 *= h / float(warm_time_step)
    problem = replace(problem, initial_impulse=r0)
    impulse, info = solve(problem, params.solver_options)
    v_end = problem.velocity(impulse)
    displacement = np.zeros_like(v_end)
    correction_iterations = 0
    correction_energy = 0.0
    max_overlap = float(max(0.0, -problem.gap.min())) if problem.n_points else 0.0
    if problem.n_points and params.overlap_slop > 0:
        gap_end = problem.gap + theta * h * problem.local_velocity(v_end)[:, 0]
        slop = params.overlap_slop
        if scale is not None:
            slop = slop * np.minimum(scale[problem.body[:, 0]], scale[problem.body[:, 1]])
        if np.any(gap_end < -slop):
            displacement, correction_iterations = _position_correction(problem, gap_end, slop, params)
            correction_energy = float(np.sum(state.mass * displacement[:-1, 2]))
    update_kernel.sized(state.n)(
        pr.x_tt, pr.state.quaternion, pr.rot_tt, v_end, displacement, h, theta, params.rotation_from_start,
        state.box.lx, state.box.ly, state.box.periodic,
        state.position, state.quaternion, state.velocity, state.omega, thread_count(),
    )
    damped_energy = 0.0
    if params.damping > 0:
        factor = np.exp(-params.damping * h)
        damped_energy = kinetic_energy(state) * (1.0 - factor * factor)
        state.velocity *= factor
        state.omega *= factor
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
        damped_energy=damped_energy,
        solver_seconds=solver_seconds,
        detection_seconds=detection_seconds,
    )


def _sides(position: np.ndarray, point_height: np.ndarray) -> np.ndarray:
    """``(N + 1,)`` 0 for the bodies whose centre lies below the median height of the contact
    points, 1 for the others (wall: 0).

    The two parts of the pile then hold about as many points each, and a load on its way down
    crosses from one to the other once: a split by height leaves the sweeps as they were, where
    one by the halves of the cell in x doubled them (loads zigzag across a vertical plane).
    """
    side = np.zeros(len(position) + 1, np.int64)
    if len(point_height):
        side[:-1] = position[:, 2] >= np.median(point_height)
    return side


def _position_correction(problem, gap_end: np.ndarray, slop, params: StepParameters) -> tuple[np.ndarray, int]:
    """Bounded post-step projection (see the module docstring): ``(displacements (N + 1, 6), sweeps)``;
    ``slop`` is ``s``, d, one for all points or ``(P,)`` one per point.

    The projection brings every linearised gap to ``>= -κ s``; when some body would move by more
    than ``correction_step``, every translation is scaled by one common factor ``λ`` so that the
    longest is ``correction_step``. The linearised gaps then end at ``(1 - λ) g^end + λ g^full``
    with ``g^full >= -κ s``: none deeper than before the correction, every overlap smaller.
    """
    target = gap_end + CORRECTED_OVERLAP * slop
    projection = problem.projection(target)
    pseudo, info = solve(projection, params.correction_options)
    displacement = projection.velocity(pseudo)
    longest = float(np.linalg.norm(displacement[:, :3], axis=1).max())
    if longest > params.correction_step:
        displacement *= params.correction_step / longest
    return displacement, info.iterations


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

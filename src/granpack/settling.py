"""The settling of a poured pile: NSCD steps through named phases, with observers around the loop.

A :class:`Settling` advances the grains by Moreau–Jean steps (:mod:`granpack.nscd`, the step policy
of :mod:`granpack.nscd.step_policy`) and checks the equilibrium criteria (:mod:`granpack.equilibrium`)
every ``equilibrium.check_interval``; the phase it is in (:attr:`Settling.phase`) decides how:

- ``"collapse"``: the pour and collapse, undamped, the NLGS solved to ``solver.settling_tolerance``;
- ``"end game"``: from the first check whose kinetic criterion is below ``end_game.damping_below``
  or whose net forces already meet their criterion (no grain accelerated: those still moving move
  freely, as a grain spinning in place or sliding on a frictionless floor, and nothing else stops
  them), with
  ``end_game.mode = "damping"``, every step but the checked ones scales the velocities by
  ``exp(-damping_rate h)``: frictionless grains swinging on closed contacts dissipate nothing, and
  the damping, which vanishes at rest, changes how fast the pile reaches its static equilibrium,
  not which forces hold it there; the checks judge undamped steps;
- ``"settle"``: from the first check below ``solver.tolerance_below``, the NLGS is solved to
  ``solver.tolerance``, and only these checks count towards the window, since the force criteria
  need converged forces; with ``overlap.recovery_near_rest = false`` the velocity law's overlap
  recovery stops (a pile of scanned grains held overlaps it pushed against for ever); a pile
  that stays near rest without meeting the criteria may be shaken (``end_game.shake_speed``);
- ``"certify"``: checks passed in a row; ``equilibrium.window`` of them end the run at rest (with
  ``overlap.rest_recovery_speed`` > 0, the first time its deeper overlaps are pushed back slowly
  and the window starts again).

A run that reaches ``equilibrium.max_time`` first ends ``"not at rest"``. Observers (progress,
checkpoints, trajectory, Ctrl-C) are called after every check (``checked``) and at the end of
every step that does not end the run (``stepped``); they read the run and never change it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from granpack.config import RunConfig
from granpack.contact import ContactSet, Detector
from granpack.equilibrium import EquilibriumReport, check_equilibrium, criteria_of
from granpack.mixture import Mixture
from granpack.nscd import StepParameters, advance, predict
from granpack.nscd.problem import body_slop_scale, pair_slop_scale
from granpack.nscd.step_policy import step_alert, step_reach
from granpack.packing import Packing
from granpack.run_record import RunRecord, timeline_row
from granpack.state import ParticleState

__all__ = ["PHASES", "STATUS_AT_REST", "STATUS_NOT_AT_REST", "Observer", "Settling", "SettlingPolicy", "shake",
           "settling_policy", "step_parameters"]

PHASES = ("collapse", "end game", "settle", "certify")
STATUS_AT_REST = "equilibrium"
STATUS_NOT_AT_REST = "not at rest"

#: Verlet skin of the broad phase, as a fraction of the smallest grain size ...
_SKIN_FRACTION = 0.1
#: ... but at least this fraction of the largest (a wide grading: docs/design-notes.md, Gradings)
_SKIN_FLOOR = 1.0 / 32.0


def step_parameters(config: RunConfig) -> StepParameters:
    """The NSCD settings of a run config."""
    t, s, o = config.time_stepping, config.solver, config.overlap
    points = config.threads.parallel_points
    return StepParameters(
        time_step=t.time_step, theta=t.theta, rotation_from_start=t.rotation_update == "from-start", friction=s.friction,
        wall_friction=config.container.wall_friction, restitution=s.restitution,
        tolerance=s.tolerance, max_iterations=s.max_iterations, check_every=s.check_every,
        alert=config.resolved_alert_distance, overlap_slop=o.projection_slop,
        recovery_slop=o.recovery_slop, recovery_rate=o.recovery_rate, recovery_speed=o.recovery_speed,
        slops_by_pair=o.slop_scale == "pair", parallel_points=points if points > 0 else 2**62,
        nncg=s.acceleration == "nncg",
    )


@dataclass(frozen=True)
class SettlingPolicy:
    """What the settling loop decides beside the NSCD step (:class:`StepParameters`): its phases,
    checks and stopping rules, from a run config (:func:`settling_policy`). Units: d, sqrt(d/g),
    d^3 P for the kinetic thresholds.

    Attributes:
        max_steps: steps to ``equilibrium.max_time``.
        check_every: steps between two equilibrium checks (``equilibrium.check_interval``).
        window: consecutive passed checks that end the run (``equilibrium.window``).
        max_rotation: ``time_stepping.max_rotation``, rad per step (the step policy).
        settling_tolerance: the NLGS tolerance before the pile is near rest.
        tolerance_below: the kinetic criterion below which the pile is near rest.
        pour_projection_slop: the projection's slop on a step of the pour ...
        pour_projection_interval: ... every this many steps (none between).
        damping: ``end_game.mode == "damping"``.
        damping_rate: the end game's velocity damping rate, 1/sqrt(d/g).
        damping_below: the kinetic criterion below which the end game starts.
        shake_speed: the speed of a shake, sqrt(g d); 0: never.
        shake_below: the kinetic criterion below which a pile near rest may be shaken ...
        shake_interval: ... at most once per this simulated time.
        rest_recovery_slop: the overlap a pile at rest is pushed back to, d ...
        rest_recovery_speed: ... at most at this speed, sqrt(g d); 0: never.
        recovery_near_rest: whether the velocity law's overlap recovery still pushes near rest
            (``overlap.recovery_near_rest``).
        seed: the run's seed (the random directions of the shakes).
    """

    max_steps: int
    check_every: int
    window: int
    max_rotation: float
    settling_tolerance: float
    tolerance_below: float
    pour_projection_slop: float
    pour_projection_interval: int
    damping: bool
    damping_rate: float
    damping_below: float
    shake_speed: float
    shake_below: float
    shake_interval: float
    rest_recovery_slop: float
    rest_recovery_speed: float
    recovery_near_rest: bool
    seed: int


def steps_of(interval: float, time_step: float) -> int:
    """The whole number of steps closest to a simulated ``interval``, at least one: how the loop
    and its observers turn every interval of a config into steps."""
    return max(1, int(round(interval / time_step)))


def settling_policy(config: RunConfig) -> SettlingPolicy:
    """The settling loop's settings of a run config, read once."""
    h, eq, e, o = config.time_stepping.time_step, config.equilibrium, config.end_game, config.overlap
    return SettlingPolicy(
        max_steps=int(math.ceil(eq.max_time / h - 1e-9)), check_every=steps_of(eq.check_interval, h), window=eq.window,
        max_rotation=config.time_stepping.max_rotation, settling_tolerance=config.solver.settling_tolerance,
        tolerance_below=config.solver.tolerance_below, pour_projection_slop=o.pour_projection_slop,
        pour_projection_interval=o.pour_projection_interval, damping=e.mode == "damping", damping_rate=e.damping_rate,
        damping_below=e.damping_below, shake_speed=e.shake_speed, shake_below=e.shake_below,
        shake_interval=e.shake_interval, rest_recovery_slop=o.rest_recovery_slop,
        rest_recovery_speed=o.rest_recovery_speed, recovery_near_rest=o.recovery_near_rest, seed=config.seed,
    )


class Observer(Protocol):
    """What watches a :class:`Settling`: it reads the run, and may stop it by raising."""

    def checked(self, run: "Settling") -> None:
        """After each equilibrium check (its timeline row written, the clock stamped)."""

    def stepped(self, run: "Settling") -> None:
        """At the end of each step that does not end the run."""


class Settling:
    """The settling loop of one run: its grains, contacts, settings and :class:`RunRecord`.

    Args:
        config: the run config.
        mixture: its mixture (population names of the packings written).
        state: the grains, advanced in place.
        contacts: the previous step's contacts (warm start), None for a fresh pile.
        record: the run's record (a fresh one, or a checkpoint's), updated in place.
    """

    def __init__(self, config: RunConfig, mixture: Mixture, state: ParticleState, contacts: ContactSet | None,
                 record: RunRecord):
        self.config, self.mixture, self.state, self.contacts, self.record = config, mixture, state, contacts, record
        self.params = step_parameters(config)
        self.policy = settling_policy(config)
        self.criteria = criteria_of(config.equilibrium)
        h = self.params.time_step
        d_min = 2.0 * float(state.shapes.radius.min())
        d_max = 2.0 * float(state.shapes.radius.max())
        room = 0.5 * state.box.lx - d_max - 1e-9  # one periodic image per pair: alert + skin < room
        skin = max(0.0, min(max(_SKIN_FRACTION * d_min, _SKIN_FLOOR * d_max), 0.25 * (room - self.params.alert)))
        self.ceiling = max(self.params.alert, room - skin)  # the largest alert distance of a step
        self.detector = Detector(skin=skin)
        self.step_h = h  # the (sub)step of the last solve: the contacts' impulses are over it
        self.tolerance = self.params.tolerance  # the NLGS tolerance of the last step
        self.report: EquilibriumReport | None = None
        self.status = STATUS_NOT_AT_REST
        self.notes: list[str] = []  # what the run has to say (the slow recovery starting), for the observers

    def steps_of(self, interval: float) -> int:
        """The steps of this run in a simulated ``interval`` (:func:`steps_of`): what the loop tells
        its observers (checkpoints, snapshots) instead of each converting its own."""
        return steps_of(interval, self.params.time_step)

    @property
    def phase(self) -> str:
        """The phase the run is in (:data:`PHASES`)."""
        m = self.record.milestones
        if m.passes > 0:
            return "certify"
        if m.near_rest:
            return "settle"
        return "end game" if m.end_game else "collapse"

    def packing(self, metadata: dict) -> Packing:
        """The grains and contacts now, with ``metadata`` (step and time added)."""
        from granpack import __version__

        config = self.config
        meta = {"seed": config.seed, "version": __version__, "config": config.to_toml(),
                "step": self.record.milestones.step, "time": self.state.time, **metadata}
        return Packing(state=self.state, contacts=self.contacts if self.contacts is not None else ContactSet.empty(),
                       time_step=self.step_h, population_names=self.mixture.names, metadata=meta)

    def run(self, observers: tuple[Observer, ...] = ()) -> str:
        """Step until at rest or ``max_time``; return the status. A check is made at the end too
        when the last step was not a checked one, so that :attr:`report` is the final state's."""
        m, every = self.record.milestones, self.policy.check_every
        while m.step < self.policy.max_steps:
            self.advance()
            if m.step % every == 0:
                at_rest = self.check()
                for observer in observers:
                    observer.checked(self)
                self.notes.clear()
                if at_rest:
                    self.status = STATUS_AT_REST
                    break
            for observer in observers:
                observer.stepped(self)
        if self.report is None or m.step % every != 0:
            self.report = check_equilibrium(self.state, self._contacts(), self.step_h, criteria=self.criteria)
            self.record.last_report = self.report.as_dict()
        return self.status

    def advance(self) -> None:
        """One time step (split into substeps where the step policy says so), with the phase's settings."""
        policy, params, m, state = self.policy, self.params, self.record.milestones, self.state
        h = params.time_step
        alert, substeps = step_alert(state, params.alert, h, self.ceiling, policy.max_rotation)
        reach = step_reach(state, params.alert, h, substeps, self.contacts) if alert > params.alert else None
        self.tolerance = params.tolerance if m.near_rest else max(params.tolerance, policy.settling_tolerance)
        if alert == params.alert:
            slop = params.overlap_slop
        elif m.step % policy.pour_projection_interval == 0:
            slop = min(params.overlap_slop, policy.pour_projection_slop)
        else:
            slop = 0.0  # no projection on this step of the pour
        self.step_h = h / substeps
        checking = (m.step + 1) % policy.check_every == 0
        damping = policy.damping_rate if m.end_game and not checking else 0.0
        step_params = replace(params, alert=alert, tolerance=self.tolerance, overlap_slop=slop, time_step=self.step_h,
                              damping=damping)
        if m.near_rest and not policy.recovery_near_rest:
            step_params = replace(step_params, recovery_speed=0.0)
        if m.rest_recovery_from is not None:
            step_params = replace(step_params, slow_recovery_slop=policy.rest_recovery_slop,
                                  slow_recovery_speed=policy.rest_recovery_speed)
        for _ in range(substeps):
            prediction = predict(state, step_params)
            t0 = time.perf_counter()
            detected = self.detector.detect(prediction.state, alert, previous=self.contacts, reach=reach)
            t1 = time.perf_counter()
            self.contacts, info = advance(state, prediction, detected, step_params, self.contacts, t1 - t0,
                                          warm_time_step=m.last_step or None)
            m.last_step = self.step_h
            self.record.totals.add(info)
        m.step += 1
        self.record.totals.split_steps += 1 if substeps > 1 else 0

    def check(self) -> bool:
        """The equilibrium check: the phase's milestones, a shake if due, the timeline row; whether the
        run ends at rest."""
        policy, m, state = self.policy, self.record.milestones, self.state
        self.report = report = check_equilibrium(state, self.contacts, self.step_h, criteria=self.criteria)
        m.passes = m.passes + 1 if report.passed and m.near_rest else 0
        # with every net force balanced, a grain still moving moves freely (spinning in place, sliding
        # on a frictionless floor): nothing but the damping stops it, so the end game starts then too
        m.end_game = m.end_game or (policy.damping and (report.kinetic_energy < policy.damping_below
                                                        or report.force_ok))
        m.near_rest = m.near_rest or report.kinetic_energy < policy.tolerance_below
        if shake_due(policy, self.record, report, state.time):
            shake(state, policy.shake_speed, np.random.default_rng([policy.seed, m.shakes]))
            m.shakes += 1
            m.last_shake = state.time
        self.record.clock.stamp()
        self.record.timeline.append(timeline_row(self.record, state, self.contacts, report, self.tolerance))
        self.record.last_report = report.as_dict()
        if m.passes < policy.window:
            return False
        if not rest_recovery_due(policy, self.params, self.record, self.contacts, state.radius):
            return True
        m.rest_recovery_from = state.time
        m.passes = 0
        self.notes.append(f"at rest at t = {state.time:.6g} sqrt(d/g) with overlaps up to {-self.contacts.gap.min():.2g} "
                          f"d: pushing them back to {policy.rest_recovery_slop:g} d (at most {policy.rest_recovery_speed:g} "
                          "sqrt(g d)), then checking again")
        return False

    def _contacts(self) -> ContactSet:
        return self.contacts if self.contacts is not None else ContactSet.empty()


def rest_recovery_due(policy: SettlingPolicy, params: StepParameters, record: RunRecord, contacts: ContactSet,
                      radius: np.ndarray) -> bool:
    """Whether a pile that has just met the criteria starts the slow overlap recovery instead of
    ending: once per run, when it is on (``overlap.rest_recovery_speed > 0``) and some overlap is
    deeper than ``overlap.rest_recovery_slop`` (times the pair's slop factor when the slops are
    scaled by the pair, :func:`granpack.nscd.problem.body_slop_scale`).

    Why: a pile comes to rest with its loaded contacts overlapping by up to the fast recovery's
    slop, deepest where the load is largest, and the overlaps weighted by their forces make k (the
    relative overestimate of the solid fraction). Pushed back at a speed far below that of the
    settling, they shrink to the slow slop while the pile stays quasi-static; the window then
    starts again, so the packing written is one at rest with the small overlaps.
    """
    if not (record.milestones.rest_recovery_from is None and policy.rest_recovery_speed > 0 and params.recovery_rate > 0
            and contacts.n_points > 0):
        return False
    slop = policy.rest_recovery_slop
    if params.slops_by_pair:
        pair = pair_slop_scale(contacts.body_i, contacts.body_j, body_slop_scale(radius))
        slop = slop * np.repeat(pair, np.diff(contacts.point_start))
    return bool(np.any(-contacts.gap > slop))


def shake_due(policy: SettlingPolicy, record: RunRecord, report: EquilibriumReport, time_now: float) -> bool:
    """Whether this check shakes the pile: shakes on, the fine tolerance in use, the kinetic criterion
    below ``end_game.shake_below``, ``end_game.shake_interval`` past the last shake, and the check failed
    (a pile that meets the criteria is counting its window towards rest: a shake would restart it)."""
    p, m = policy, record.milestones
    return (p.shake_speed > 0 and m.near_rest and not report.passed and report.kinetic_energy < p.shake_below
            and (m.last_shake is None or time_now - m.last_shake >= p.shake_interval - 1e-9))


def shake(state: ParticleState, speed: float, rng: np.random.Generator) -> None:
    """Add ``speed`` (sqrt(g d)) in a random direction (uniform on the sphere) to every grain's velocity.

    Why: a frictionless pile near rest holds grains by contacts that carry almost no force; such a
    grain leaves its contact and slides to the next one tens of sqrt(d/g) later, setting off a burst
    of rearrangements (docs/design-notes.md, Settling to rest). A small kick makes those grains leave
    at once, while the grains held firmly return to rest within a few sqrt(d/g) under the end game's
    damping.
    """
    direction = rng.normal(size=(state.n, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    state.velocity += speed * direction

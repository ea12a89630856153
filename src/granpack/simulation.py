"""The packing protocol: pluviation, NSCD settling to equilibrium, checkpoints, outputs.

:func:`run_packing` is the whole of ``granpack run`` (docs: Method > Pluviation):

1. grains get their population (shuffled, :mod:`granpack.mixture`), a random orientation and
   their circumscribed sphere (the shell); the shells are deposited one by one
   (:mod:`granpack.deposit`, lateral walls or periodic as configured); the walls then give way to
   the periodic cell (the centres are already inside it);
2. the grains replace the shells, at rest, and the Moreau–Jean scheme (:mod:`granpack.nscd`)
   advances them under gravity until the equilibrium criteria (docs: Method > Equilibrium,
   :mod:`granpack.equilibrium`) hold at ``window`` consecutive checks (one every
   ``check_interval``), or until ``max_time``: the run then ends with status ``"not at rest"``
   and its figures, not an error.

NLGS tolerance. While the pile is far from rest (kinetic criterion above
``solver.tolerance_below``, 1e-5) the contact problems are solved to ``solver.settling_tolerance``
(1e-3); from the first check below that level on, to ``solver.tolerance``, and only checks made
with it count towards the equilibrium window, since the force criteria need converged forces.
Switching at the start of the end game instead (kinetic 1e-3) cost 600-1500 sweeps per step while
the collapsed pile still moved, and brought the demo pile to rest later (t = 57.75 against 42.75).

End game. Once the kinetic criterion falls below ``solver.damping_below`` (the collapse is over),
with ``solver.end_game = "damping"`` every step but the checked ones scales the velocities by
``exp(-damping_rate h)`` (:mod:`granpack.nscd.integrator`). Frictionless grains swinging on closed contacts dissipate nothing, and an
undamped pile keeps a steady level of small motions long after it has collapsed; the damping
vanishes at rest, so it changes how fast the pile gets to its static equilibrium, not which
forces hold it there. The criteria are evaluated on undamped steps: a grain creeping at the
terminal speed ``v`` of the drag shows its unbalanced force ``γ m v`` there, and its kinetic energy.

Overlap correction. The post-step projection of :mod:`granpack.nscd.integrator` removes overlaps
above ``solver.overlap_slop`` (``solver.pour_overlap_slop`` if smaller while grains move fast, the
alert distance raised, see below); the velocity-level law alone never pushes an overlap back.

Alert distance and substeps: the step policy of :mod:`granpack.nscd.step_policy`
(:func:`~granpack.nscd.step_policy.step_alert`, :func:`~granpack.nscd.step_policy.step_reach`).

Outputs in ``out_dir`` (written to a temporary name and renamed, but for the trajectory, which
grows frame by frame and is cut back to the checkpoint on resume):
``config.toml`` (resolved), ``checkpoint.gsd`` (every ``output.checkpoint_interval``; removed at
the end), ``trajectory.gsd`` (a frame every ``output.snapshot_interval`` if > 0), ``final.gsd``,
``summary.json`` and ``timeline.csv`` (one row per equilibrium check: :data:`TIMELINE_COLUMNS`).
A killed run resumed with ``resume=True`` continues from its checkpoint
and ends with the same packing, bit for bit, as an uninterrupted run: the checkpoint holds the
exact double-precision state, the contacts that warm-start the next step, and the loop counters.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from granpack.box import Box
from granpack.config import RunConfig
from granpack.contact import ContactSet, Detector
from granpack.deposit import deposit
from granpack.equilibrium import EquilibriumCriteria, EquilibriumReport, check_equilibrium
from granpack.errors import InputError, RunInterrupted
from granpack.io.atomic import write_text_atomic
from granpack.io.gsd import append_frame, read_packing, truncate_frames, write_packing
from granpack.io.json import read_json, write_json
from granpack.io.run_folder import (
    CHECKPOINT_FILE,
    CONFIG_FILE,
    FINAL_FILE,
    PROGRESS_FILE,
    SUMMARY_FILE,
    TIMELINE_FILE,
    TRAJECTORY_FILE,
    claim_folder,
)
from granpack.mixture import Mixture
from granpack.nscd import StepParameters, advance, kinetic_energy, potential_energy, predict
from granpack.nscd.step_policy import step_alert, step_reach
from granpack.packing import Packing
from granpack.progress import Interrupt, Lines, Notes, SettlingProgress, progress_mode
from granpack.rotations import random_quaternions
from granpack.state import ParticleState

__all__ = ["run_packing", "initial_state", "step_parameters", "criteria_of", "step_alert",
           "STATUS_AT_REST", "STATUS_NOT_AT_REST", "CONFIG_FILE", "CHECKPOINT_FILE", "FINAL_FILE",
           "SUMMARY_FILE", "TRAJECTORY_FILE", "PROGRESS_FILE"]

STATUS_AT_REST = "equilibrium"
STATUS_NOT_AT_REST = "not at rest"
#: columns of ``timeline.csv``, one row per equilibrium check; counts and sums over the interval
#: since the previous check, figures of the equilibrium test at the check
TIMELINE_COLUMNS = (
    "time", "step", "kinetic_energy_total", "potential_energy_change", "kinetic_criterion", "max_net_force", "max_net_torque",
    "wall_force_over_weight", "nlgs_tolerance", "mean_sweeps", "max_sweeps", "unconverged_steps",
    "corrected_steps", "correction_sweeps", "correction_energy", "damped_energy", "contacts", "contact_points", "max_overlap",
    "wall_seconds", "cpu_seconds",
)

_OVERLAP_COLUMN = TIMELINE_COLUMNS.index("max_overlap")

#: Verlet skin of the broad phase, as a fraction of the smallest grain size
_SKIN_FRACTION = 0.1


@dataclass
class _Counters:
    """Loop state that a checkpoint carries (everything but the particles and contacts)."""

    step: int = 0
    passes: int = 0  # consecutive equilibrium checks passed
    near_rest: bool = False  # the fine NLGS tolerance is in use (once set, for good)
    iterations_total: int = 0
    iterations_max: int = 0
    interval_max_sweeps: int = 0  # most sweeps of a step since the last check
    unconverged_steps: int = 0
    point_updates: int = 0
    max_overlap: float = 0.0
    correction_steps: int = 0
    correction_iterations: int = 0  # NLGS sweeps of the position corrections
    correction_energy: float = 0.0
    end_game: bool = False  # the end game's damping has started (once set, for good)
    rest_recovery_from: float | None = None  # simulated time the slow overlap recovery started (for good)
    shakes: int = 0  # shakes given (solver.shake_speed)
    last_shake: float | None = None  # simulated time of the last shake, sqrt(d/g)
    last_step: float = 0.0  # the (sub)step of the last solve, sqrt(d/g) (0: none yet)
    damped_energy: float = 0.0
    split_steps: int = 0  # steps split into substeps (alert distance above the cell's ceiling)
    solves: int = 0  # NLGS velocity solves (one per step, k per split step)
    detection_seconds: float = 0.0
    solver_seconds: float = 0.0
    deposit_seconds: float = 0.0
    initial_order: dict = field(default_factory=dict)  # Q00, Q22 of the deposit before gravity acts
    wall_seconds: float = 0.0
    cpu_seconds: float = 0.0  # process CPU time of the settling (all threads)
    last_report: dict = field(default_factory=dict)
    timeline: list = field(default_factory=list)  # one row per equilibrium check, TIMELINE_COLUMNS

    def as_dict(self) -> dict:
        """The counters for a checkpoint's JSON metadata: the timeline's NaN and infinities as the
        strings ``"nan"``, ``"inf"``, ``"-inf"`` (JSON would make them ``null``)."""
        saved = dict(self.__dict__)
        saved["timeline"] = [[v if not isinstance(v, float) or math.isfinite(v) else repr(v) for v in row]
                             for row in self.timeline]
        return saved


def step_parameters(config: RunConfig) -> StepParameters:
    """The NSCD settings of a run config."""
    s = config.solver
    return StepParameters(
        time_step=s.time_step, theta=s.theta, friction=s.friction, restitution=s.restitution,
        tolerance=s.tolerance, max_iterations=s.max_iterations, check_every=s.check_every,
        alert=config.resolved_alert_distance, overlap_slop=s.overlap_slop,
        recovery_slop=s.recovery_slop, recovery_rate=s.recovery_rate, recovery_speed=s.recovery_speed,
        parallel_points=s.parallel_points if s.parallel_points > 0 else 2**62, nncg=s.acceleration == "nncg",
    )


def criteria_of(config: RunConfig) -> EquilibriumCriteria:
    """The equilibrium tolerances of a run config."""
    e = config.equilibrium
    return EquilibriumCriteria(force=e.force_tolerance, torque=e.torque_tolerance,
                               kinetic_energy=e.kinetic_tolerance, wall=e.wall_tolerance)


def deposit_order(state: ParticleState) -> dict:
    """``{"Q00", "Q22"}`` of the deposited grains, gravity not yet applied (the "initial state"
    of the study's order figure): over every non-spherical grain, nan with none."""
    from granpack.analysis.order import order_parameters
    from granpack.rotations import quat_to_matrix

    shaped = ~state.shapes.is_sphere[state.kind]
    if not shaped.any():
        return {"Q00": math.nan, "Q22": math.nan}
    q00, q22, _, _ = order_parameters(quat_to_matrix(state.quaternion[shaped]))
    return {"Q00": q00, "Q22": q22}


def initial_state(config: RunConfig, progress: bool = False) -> tuple[ParticleState, Mixture]:
    """Pluviation: shuffled populations, deposited shells, random orientations, grains at rest.

    The random stream of ``config.seed`` draws, in order, the population order, the deposit's
    release points and the orientations, so a seed gives one packing.
    """
    mixture = Mixture.from_config(config)
    shapes = mixture.particle_shape_table()
    rng = np.random.default_rng(config.seed)
    population = mixture.particle_populations(rng)
    radii = shapes.radius[population]
    centres = deposit(radii, config.lateral_size, rng, lateral=config.deposit.lateral,
                      method=config.deposit.method, progress=progress)
    quaternion = random_quaternions(len(population), rng)
    box = Box.square(config.lateral_size)
    state = ParticleState(box=box, shapes=shapes, kind=population, population=population,
                          position=box.wrap(centres), quaternion=quaternion)
    return state, mixture


def _packing(state: ParticleState, contacts: ContactSet, config: RunConfig, mixture: Mixture, metadata: dict) -> Packing:
    from granpack import __version__

    meta = {"seed": config.seed, "version": __version__, "config": config.to_toml(), **metadata}
    return Packing(state=state, contacts=contacts, time_step=config.solver.time_step,
                   population_names=mixture.names, metadata=meta)


def _same_config(saved_text: str | None, config: RunConfig) -> bool:
    """Whether a checkpoint's resolved config is ``config``: the same settings, whatever the
    comments of the version that wrote it (the descriptions of the keys)."""
    if saved_text == config.to_toml():
        return True
    import tomllib

    from granpack.config import load_config_dict

    try:
        return load_config_dict(tomllib.loads(saved_text or "")) == config
    except (InputError, tomllib.TOMLDecodeError):
        return False


def _resume_from(out_dir: Path, config: RunConfig, mixture: Mixture) -> tuple[ParticleState, ContactSet, _Counters] | None:
    """State, warm contacts and counters of the checkpoint in ``out_dir``, or None if there is none."""
    path = out_dir / CHECKPOINT_FILE
    if not path.is_file():
        return None
    saved = read_packing(path)
    meta = saved.metadata
    if not _same_config(meta.get("config"), config):
        raise InputError(f"{path}: checkpoint of another config than {out_dir / CONFIG_FILE}; resume with that config, "
                         "or replace the run with --overwrite")
    s = saved.state
    state = ParticleState(box=Box.square(config.lateral_size), shapes=mixture.particle_shape_table(), kind=s.kind,
                          population=s.population, position=s.position, quaternion=s.quaternion,
                          velocity=s.velocity, omega=s.omega, time=s.time)
    counters = _Counters(**meta["counters"])
    # non-finite values come back from their strings; a checkpoint of an older version wrote null
    counters.timeline = [_current_layout([math.nan if v is None else float(v) if isinstance(v, str) else v for v in row])
                         for row in counters.timeline]
    return state, saved.contacts, counters


_POTENTIAL_COLUMN = TIMELINE_COLUMNS.index("potential_energy_change")
#: length of a timeline row in checkpoints written before the potential energy was recorded:
#: the other columns, then seven running totals
_ROW_WITHOUT_POTENTIAL = len(TIMELINE_COLUMNS) - 1 + 7


def _current_layout(row: list) -> list:
    """A checkpoint's timeline row in today's layout: a row written before ``potential_energy_change``
    existed gets NaN for it and for its running total, so that such a run resumes."""
    if len(row) != _ROW_WITHOUT_POTENTIAL:
        return row
    return [*row[:_POTENTIAL_COLUMN], math.nan, *row[_POTENTIAL_COLUMN:], math.nan]


def run_packing(config: RunConfig, out_dir: str | os.PathLike, *, resume: bool = False, overwrite: bool = False,
                progress: bool | str = True, warnings: Sequence[str] = ()) -> dict:
    """Pour and settle one packing; write its files; return its summary.

    No work is lost without a word: a folder that holds a run (any of :data:`RUN_FILES`) is
    continued with ``resume``, replaced with ``overwrite``, and refused otherwise; a
    ``config.toml`` there that is not a granpack run's (a folder without a run, a config that
    is not a resolved one) is never replaced.

    Args:
        config: the validated run config.
        out_dir: output folder (created if needed).
        resume: continue from ``out_dir/checkpoint.gsd``; a finished run (``summary.json`` and
            ``final.gsd``) of the same config is returned as it is; a folder without a run is
            started afresh.
        overwrite: replace the run that ``out_dir`` holds: its :data:`RUN_FILES` and the
            figures and exports of :data:`RUN_FOLDERS` are removed first (other files stay).
        progress: ``"bar"``: progress bars on stderr; ``"lines"``: a progress line on stderr
            every 30 s of wall time (for logs); ``"log"``: the same lines and the notes appended
            to ``out_dir/progress.log`` instead (a campaign's runs, whose stderr nobody reads);
            ``True``: the bars if stderr is a terminal, else the lines; ``False``: nothing. Notes
            (resuming, overwriting) go to stderr unless ``False`` or ``"log"``.
        warnings: lines written as ``warning: ...`` notes once the folder is accepted, before a
            new run pours (what ``granpack check`` warns of; none on a resume).

    Returns:
        The summary written to ``summary.json``: ``status`` (``"equilibrium"`` or
        ``"not at rest"``), steps, simulated and wall times, NLGS statistics, the last
        equilibrium figures (``equilibrium``: the criteria, e.g. ``kinetic_energy`` is the largest
        kinetic energy of a grain over ``d_p^3 P``) and the final state (``final``:
        ``total_kinetic_energy`` is the sum over the grains, in ``rho g d^4``, i.e. ``m g d`` for
        a mass ``m`` of ``d^3`` of grain; contacts; the largest overlap in d).

    Raises:
        InputError: ``out_dir`` cannot be created or is a file; it holds a run and neither
            ``resume`` nor ``overwrite`` is given (or both are); its ``config.toml`` is not a
            granpack run's; its checkpoint or finished run belongs to another config.
        RunInterrupted: Ctrl-C (SIGINT, when running in the main thread) while settling: the run
            stopped at the end of the step and wrote its checkpoint (a second Ctrl-C stops at once,
            keeping the last checkpoint). During the pour Ctrl-C raises KeyboardInterrupt (there is
            no checkpoint yet).
    """
    out_dir = Path(out_dir)
    mode = progress_mode(progress)
    write = Lines(out_dir / PROGRESS_FILE if mode == "log" else None)
    note = Notes(mode, write)
    config_text = config.to_toml()
    if claim_folder(out_dir, config_text, resume=resume, overwrite=overwrite, note=note):
        return read_json(out_dir / SUMMARY_FILE)
    wall_start = time.perf_counter()
    mixture = Mixture.from_config(config)
    resumed = _resume_from(out_dir, config, mixture) if resume else None  # refused before anything is written
    write_text_atomic(out_dir / CONFIG_FILE, config_text)
    for stale in (SUMMARY_FILE, FINAL_FILE):
        (out_dir / stale).unlink(missing_ok=True)
    if resumed is None:
        (out_dir / CHECKPOINT_FILE).unlink(missing_ok=True)
        (out_dir / TRAJECTORY_FILE).unlink(missing_ok=True)
        for warning in warnings:
            note(f"warning: {warning}")
        t0 = time.perf_counter()
        note(f"pouring {config.n_particles} grains (deposit {config.deposit.method}, lateral {config.deposit.lateral})",
             lines_only=True)
        state, mixture = initial_state(config, progress=mode == "bar")
        counters = _Counters(deposit_seconds=time.perf_counter() - t0, initial_order=deposit_order(state))
        note(f"poured in {counters.deposit_seconds:.0f} s; settling", lines_only=True)
        contacts = None
    else:
        state, contacts, counters = resumed
        note(f"resuming from t = {state.time:.6g} sqrt(d/g) (step {counters.step}) of {out_dir / CHECKPOINT_FILE}")
        truncate_frames(out_dir / TRAJECTORY_FILE, counters.step)
    wall_before = counters.wall_seconds
    cpu_before, cpu_start = counters.cpu_seconds, time.process_time()

    params = step_parameters(config)
    settling_tolerance = config.solver.settling_tolerance
    pour_slop = config.solver.pour_overlap_slop
    criteria = criteria_of(config)
    eq = config.equilibrium
    h = params.time_step
    d_min = 2.0 * float(state.shapes.radius.min())
    d_max = 2.0 * float(state.shapes.radius.max())
    room = 0.5 * config.lateral_size - d_max - 1e-9  # one periodic image per pair: alert + skin < room
    skin = max(0.0, min(_SKIN_FRACTION * d_min, 0.25 * (room - params.alert)))
    ceiling = max(params.alert, room - skin)
    detector = Detector(skin=skin)
    n_steps_max = int(math.ceil(eq.max_time / h - 1e-9))
    check_every = max(1, int(round(eq.check_interval / h)))
    checkpoint_every = max(1, int(round(config.output.checkpoint_interval / h)))
    snapshot_every = int(round(config.output.snapshot_interval / h)) if config.output.snapshot_interval > 0 else 0
    report: EquilibriumReport | None = None
    status = STATUS_NOT_AT_REST

    def packing_now(extra: dict) -> Packing:
        packing = _packing(state, contacts if contacts is not None else ContactSet.empty(), config, mixture,
                           {"step": counters.step, "time": state.time, **extra})
        return replace(packing, time_step=step_h)  # the contacts' impulses are over the last (sub)step

    step_h = h

    bar = SettlingProgress(mode, eq.max_time, h, write)
    interrupt = Interrupt()
    with bar, interrupt:
        while counters.step < n_steps_max:
            alert, substeps = step_alert(state, params.alert, h, ceiling, config.solver.max_rotation)
            reach = step_reach(state, params.alert, h, substeps, contacts) if alert > params.alert else None
            tolerance = params.tolerance if counters.near_rest else max(params.tolerance, settling_tolerance)
            if alert == params.alert:
                slop = params.overlap_slop
            elif counters.step % config.solver.pour_correction_interval == 0:
                slop = min(params.overlap_slop, pour_slop)
            else:
                slop = 0.0  # no correction on this step of the pour
            step_h = h / substeps
            checking = (counters.step + 1) % check_every == 0
            damping = config.solver.damping_rate if counters.end_game and not checking else 0.0
            step_params = replace(params, alert=alert, tolerance=tolerance, overlap_slop=slop, time_step=step_h,
                                  damping=damping)
            if counters.rest_recovery_from is not None:
                step_params = replace(step_params, slow_recovery_slop=config.solver.rest_recovery_slop,
                                      slow_recovery_speed=config.solver.rest_recovery_speed)
            for _ in range(substeps):
                prediction = predict(state, step_params)
                t0 = time.perf_counter()
                detected = detector.detect(prediction.state, alert, previous=contacts, reach=reach)
                t1 = time.perf_counter()
                contacts, info = advance(state, prediction, detected, step_params, contacts, t1 - t0,
                                         warm_time_step=counters.last_step or None)
                counters.last_step = step_h
                counters.solves += 1
                counters.iterations_total += info.iterations
                counters.iterations_max = max(counters.iterations_max, info.iterations)
                counters.interval_max_sweeps = max(counters.interval_max_sweeps, info.iterations)
                counters.unconverged_steps += 0 if info.converged else 1
                counters.point_updates += info.iterations * info.n_points
                counters.max_overlap = max(counters.max_overlap, info.max_overlap)
                counters.correction_steps += 1 if info.correction_iterations else 0
                counters.correction_iterations += info.correction_iterations
                counters.correction_energy += info.correction_energy
                counters.damped_energy += info.damped_energy
                counters.detection_seconds += info.detection_seconds
                counters.solver_seconds += info.solver_seconds
            counters.step += 1
            counters.split_steps += 1 if substeps > 1 else 0
            bar.tick(state.time)

            if counters.step % check_every == 0:
                report = check_equilibrium(state, contacts, step_h, criteria=criteria)
                counters.passes = counters.passes + 1 if report.passed and counters.near_rest else 0
                counters.end_game = counters.end_game or (
                    config.solver.end_game == "damping" and report.kinetic_energy < config.solver.damping_below)
                counters.near_rest = counters.near_rest or report.kinetic_energy < config.solver.tolerance_below
                if _shake_due(config, counters, report, state.time):
                    shake(state, config.solver.shake_speed, np.random.default_rng([config.seed, counters.shakes]))
                    counters.shakes += 1
                    counters.last_shake = state.time
                counters.wall_seconds = wall_before + time.perf_counter() - wall_start
                counters.cpu_seconds = cpu_before + time.process_time() - cpu_start
                _timeline_row(counters, state, contacts, report, tolerance)
                counters.last_report = report.as_dict()
                bar.update(state.time, kinetic_energy(state), contacts.n_manifolds, report, counters.passes, eq.window,
                           counters.timeline[-1][_OVERLAP_COLUMN])
                if counters.passes >= eq.window:
                    if not _rest_recovery_due(config, counters, contacts):
                        status = STATUS_AT_REST
                        break
                    counters.rest_recovery_from = state.time
                    counters.passes = 0
                    note(f"at rest at t = {state.time:.6g} sqrt(d/g) with overlaps up to "
                         f"{-contacts.gap.min():.2g} d: pushing them back to {config.solver.rest_recovery_slop:g} d "
                         f"(at most {config.solver.rest_recovery_speed:g} sqrt(g d)), then checking again")
            if snapshot_every and counters.step % snapshot_every == 0:
                append_frame(out_dir / TRAJECTORY_FILE, packing_now({"status": "settling"}))
            if counters.step % checkpoint_every == 0:
                counters.wall_seconds = wall_before + time.perf_counter() - wall_start
                write_packing(out_dir / CHECKPOINT_FILE, packing_now({"counters": counters.as_dict()}))
            if interrupt.requested:  # Ctrl-C: stop here, the checkpoint of this step written
                if counters.step % checkpoint_every != 0:
                    counters.wall_seconds = wall_before + time.perf_counter() - wall_start
                    write_packing(out_dir / CHECKPOINT_FILE, packing_now({"counters": counters.as_dict()}))
                raise RunInterrupted(out_dir / CHECKPOINT_FILE, state.time, counters.step)

    if report is None or counters.step % check_every != 0:
        report = check_equilibrium(state, contacts if contacts is not None else ContactSet.empty(), step_h,
                                   criteria=criteria)
        counters.last_report = report.as_dict()
    counters.wall_seconds = wall_before + time.perf_counter() - wall_start
    counters.cpu_seconds = cpu_before + time.process_time() - cpu_start
    summary = _summary(config, state, contacts, counters, report, status)
    write_packing(out_dir / FINAL_FILE, packing_now({"status": status, "summary": _headline(summary)}))
    write_json(out_dir / SUMMARY_FILE, summary)
    write_text_atomic(out_dir / TIMELINE_FILE, _timeline_csv(counters.timeline))
    (out_dir / CHECKPOINT_FILE).unlink(missing_ok=True)
    note(f"{status} at t = {state.time:.6g} sqrt(d/g) after {counters.wall_seconds:.0f} s: "
         f"largest net force {report.max_net_force:.3g} d^2 P", lines_only=True)
    return summary


def _rest_recovery_due(config: RunConfig, c: _Counters, contacts: ContactSet) -> bool:
    """Whether a pile that has just met the criteria starts the slow overlap recovery instead of
    ending: once per run, when it is on (``solver.rest_recovery_speed > 0``) and some overlap is
    deeper than ``solver.rest_recovery_slop``.

    Why: a pile comes to rest with its loaded contacts overlapping by up to the fast recovery's
    slop, deepest where the load is largest, and the overlaps weighted by their forces make k (the
    relative overestimate of the solid fraction). Pushed back at a speed far below that of the
    settling, they shrink to the slow slop while the pile stays quasi-static; the window then
    starts again, so the packing written is one at rest with the small overlaps.
    """
    s = config.solver
    return (c.rest_recovery_from is None and s.rest_recovery_speed > 0 and s.recovery_rate > 0
            and contacts.n_points > 0 and float(-contacts.gap.min()) > s.rest_recovery_slop)


def _shake_due(config: RunConfig, c: _Counters, report: EquilibriumReport, time_now: float) -> bool:
    """Whether this check shakes the pile: shakes on, the fine tolerance in use, the kinetic criterion
    below ``solver.shake_below``, ``solver.shake_interval`` past the last shake, and the check failed
    (a pile that meets the criteria is counting its window towards rest: a shake would restart it)."""
    s = config.solver
    return (s.shake_speed > 0 and c.near_rest and not report.passed and report.kinetic_energy < s.shake_below
            and (c.last_shake is None or time_now - c.last_shake >= s.shake_interval - 1e-9))


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


def _timeline_row(c: _Counters, state: ParticleState, contacts: ContactSet, report: EquilibriumReport,
                  tolerance: float) -> None:
    """Append the row of this check to ``c.timeline`` (interval sums from the previous row's totals)."""
    totals = (c.solves, c.iterations_total, c.unconverged_steps, c.correction_steps, c.correction_iterations,
              c.correction_energy, c.damped_energy, potential_energy(state))
    # the first check has no previous potential energy: its change is NaN
    previous = c.timeline[-1][len(TIMELINE_COLUMNS):] if c.timeline else (0,) * (len(totals) - 1) + (math.nan,)
    d = [a - b for a, b in zip(totals, previous)]
    gaps = contacts.gap
    c.timeline.append([
        state.time, c.step, kinetic_energy(state), d[7], report.kinetic_energy, report.max_net_force,
        report.max_net_torque, report.wall_force_over_weight, tolerance, d[1] / max(d[0], 1), c.interval_max_sweeps,
        d[2], d[3], d[4] / max(d[0], 1), d[5], d[6], contacts.n_manifolds, contacts.n_points,
        float(max(0.0, -gaps.min())) if len(gaps) else 0.0, c.wall_seconds, c.cpu_seconds, *totals,
    ])
    c.interval_max_sweeps = 0


def _timeline_csv(rows: list) -> str:
    """``timeline.csv``: a header and one line per check (the running totals kept in the rows dropped)."""
    lines = [",".join(TIMELINE_COLUMNS)]
    for row in rows:
        lines.append(",".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in row[:len(TIMELINE_COLUMNS)]))
    return "\n".join(lines) + "\n"


def _headline(summary: dict) -> dict:
    return {k: summary[k] for k in ("status", "steps", "simulated_time", "wall_time")}


def _summary(config: RunConfig, state: ParticleState, contacts: ContactSet | None, c: _Counters,
             report: EquilibriumReport, status: str) -> dict:
    from granpack import __version__
    from granpack._numba import thread_count, threading_layer

    steps = max(c.step, 1)
    n_points = contacts.n_points if contacts is not None else 0
    gaps = contacts.gap if contacts is not None and n_points else np.zeros(0)
    return {
        "version": __version__,
        "status": status,
        "seed": config.seed,
        "n_particles": state.n,
        "steps": c.step,
        "simulated_time": state.time,
        "time_step": config.solver.time_step,
        "wall_time": c.wall_seconds,
        "cpu_time": c.cpu_seconds,
        "threads": {"numba": thread_count(), "layer": threading_layer()},
        "initial_order": dict(c.initial_order),
        "timing": {
            "deposit_seconds": c.deposit_seconds,
            "detection_seconds": c.detection_seconds,
            "solver_seconds": c.solver_seconds,
            "detection_ms_per_step": 1e3 * c.detection_seconds / steps,
            "solver_ms_per_step": 1e3 * c.solver_seconds / steps,
            "point_updates_per_second": c.point_updates / c.solver_seconds if c.solver_seconds > 0 else None,
        },
        "nlgs": {
            "mean_iterations": c.iterations_total / max(c.solves, 1),
            "max_iterations": c.iterations_max,
            "unconverged_steps": c.unconverged_steps,
            "solves": c.solves,
            "tolerance": config.solver.tolerance,
        },
        "split_steps": c.split_steps,
        "position_correction": {"steps": c.correction_steps, "potential_energy_added": c.correction_energy},
        "end_game": {"mode": config.solver.end_game, "started": c.end_game, "kinetic_energy_removed": c.damped_energy,
                     "shakes": c.shakes, "rest_recovery_from": c.rest_recovery_from},
        "equilibrium": report.as_dict(),
        "final": {  # the last state; total kinetic energy in rho g d^4 (the per-grain criterion: "equilibrium")
            "total_kinetic_energy": kinetic_energy(state),
            "contacts": contacts.n_manifolds if contacts is not None else 0,
            "contact_points": n_points,
            "max_overlap": float(max(0.0, -gaps.min())) if len(gaps) else 0.0,
            "height": float(np.max(state.position[:, 2] + state.radius)) if state.n else 0.0,
        },
        "max_overlap_during_run": c.max_overlap,
    }




"""One packing, pour to rest: the run folder, the pluviation, the settling, the outputs.

:func:`run_packing` is the whole of ``granpack run`` (docs: Method > Pluviation):

1. the deposit: grains get their population (shuffled, :mod:`granpack.mixture`), a random
   orientation and their circumscribed sphere (the shell); the shells are deposited one by one
   (:mod:`granpack.deposit`, lateral walls or periodic as configured); the walls then give way to
   the periodic cell (the centres are already inside it);
2. the settling (:mod:`granpack.settling`): the grains replace the shells, at rest, and Moreau–Jean
   steps advance them under gravity through the phases collapse, end game, settle and certify,
   until the equilibrium criteria (docs: Method > Equilibrium) hold at ``equilibrium.window``
   consecutive checks, or until ``equilibrium.max_time``: the run then ends with status
   ``"not at rest"`` and its figures, not an error.

Around the settling, observers: the progress display (:mod:`granpack.progress`), the trajectory
frames and the checkpoints (here), Ctrl-C (a checkpoint, then :class:`~granpack.errors.RunInterrupted`).
The rules of the run folder are :mod:`granpack.io.run_folder`'s; what a run measures is
:mod:`granpack.run_record`'s.

Outputs in ``out_dir`` (written to a temporary name and renamed, but for the trajectory, which
grows frame by frame and is cut back to the checkpoint on resume): ``config.toml`` (resolved),
``checkpoint.gsd`` (every ``output.checkpoint_interval``; removed at the end), ``trajectory.gsd``
(a frame every ``output.snapshot_interval`` if > 0), ``final.gsd``, ``summary.json`` and
``timeline.csv`` (one row per equilibrium check: :data:`~granpack.run_record.TIMELINE_COLUMNS`).
A killed run resumed with ``resume=True`` continues from its checkpoint and ends with the same
packing, bit for bit, as an uninterrupted run: the checkpoint holds the exact double-precision
state, the contacts that warm-start the next step, and the run's record. ``final.gsd`` holds them
too, so that a run that ended not at rest goes on from it, resumed with ``equilibrium.max_time``
raised, as far as the longer run would have gone; resumed, a run may also change
``solver.tolerance`` (:data:`~granpack.config.CONTINUABLE_SETTINGS`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from granpack.advice import advise
from granpack.box import Box
from granpack.config import CONTINUABLE_SETTINGS, RunConfig
from granpack.contact import ContactSet
from granpack.deposit import deposit
from granpack.errors import InputError, RunInterrupted
from granpack.io.atomic import write_text_atomic
from granpack.io.container import write_container_stl
from granpack.io.gsd import append_frame, read_packing, truncate_frames, write_packing
from granpack.io.json import read_json, write_json
from granpack.io.run_folder import (
    CHECKPOINT_FILE,
    CONFIG_FILE,
    CONTAINER_FILE,
    DERIVED_FILES,
    FINAL_FILE,
    PROGRESS_FILE,
    SUMMARY_FILE,
    TIMELINE_FILE,
    TRAJECTORY_FILE,
    changed_settings,
    claim_folder,
    clear_run,
    config_differences,
)
from granpack.mixture import Mixture
from granpack.nscd import kinetic_energy
from granpack.interrupt import Interrupt
from granpack.progress import Lines, Notes, SettlingProgress, progress_mode
from granpack.rotations import random_quaternions
from granpack.run_record import Clock, RunRecord, timeline_csv
from granpack.settling import STATUS_AT_REST, STATUS_NOT_AT_REST, Settling, settling_policy
from granpack.state import ParticleState

__all__ = ["run_packing", "initial_state", "deposit_order", "carries_on", "continued_settings", "STATUS_AT_REST",
           "STATUS_NOT_AT_REST"]


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


def initial_state(config: RunConfig, progress: bool = False,
                  mixture: Mixture | None = None) -> tuple[ParticleState, Mixture]:
    """Pluviation: shuffled populations, deposited shells, random orientations, grains at rest.

    The random stream of ``config.seed`` draws, in order, the population order, the deposit's
    release points and the orientations, so a seed gives one packing. ``mixture`` is
    ``Mixture.from_config(config)``, built here if not given.
    """
    mixture = Mixture.from_config(config) if mixture is None else mixture
    shapes = mixture.particle_shape_table()
    rng = np.random.default_rng(config.seed)
    population = mixture.particle_populations(rng)
    kind = mixture.particle_kinds(population)
    radii = shapes.radius[kind]
    box = Box.square(config.lateral_size, config.container.shape)
    lateral = {"periodic": config.deposit.lateral, "box": "walls", "cylinder": "cylinder"}[box.container]
    centres = deposit(radii, config.lateral_size, rng, lateral=lateral, method=config.deposit.method,
                      progress=progress)
    quaternion = random_quaternions(len(population), rng)
    state = ParticleState(box=box, shapes=shapes, kind=kind, population=population,
                          position=box.wrap(centres), quaternion=quaternion)
    return state, mixture


def _as_today(saved_text: str | None) -> str:
    """A run's saved resolved config written as today's (an older layout of the same settings, or
    other comments), or as it is when it does not load."""
    import tomllib

    from granpack.config import load_config_dict

    try:
        return load_config_dict(tomllib.loads(saved_text or "")).to_toml()
    except (InputError, tomllib.TOMLDecodeError):
        return saved_text or ""


def continued_settings(saved_text: str | None, config: RunConfig) -> dict[str, tuple] | None:
    """The settings of :data:`~granpack.config.CONTINUABLE_SETTINGS` in which ``config`` differs
    from a run's saved config, ``{key: (saved, given)}`` (empty: the same settings); None when any
    other setting differs, so that the run cannot go on under ``config``."""
    changed = changed_settings(_as_today(saved_text), config.to_toml())
    return changed if set(changed) <= set(CONTINUABLE_SETTINGS) else None


def _changes(changed: dict[str, tuple]) -> str:
    """``equilibrium.max_time = 400 (was 300), ...``"""
    return ", ".join(f"{key} = {new:g} (was {old:g})" for key, (old, new) in changed.items())


def saved_state(saved: ParticleState, config: RunConfig, mixture: Mixture) -> ParticleState:
    """A state read from a GSD file (``read_packing(path).state``) set up to settle on under
    ``config``: its grains (kinds, populations, positions, orientations, velocities, time) in the
    container of ``config`` with ``mixture``'s shape table, which the kernels index (the file's
    own shapes are for viewers)."""
    return ParticleState(box=Box.square(config.lateral_size, config.container.shape),
                         shapes=mixture.particle_shape_table(), kind=saved.kind, population=saved.population,
                         position=saved.position, quaternion=saved.quaternion, velocity=saved.velocity,
                         omega=saved.omega, time=saved.time)


def _resume_from(out_dir: Path, config: RunConfig, mixture: Mixture, source: str | None = None
                 ) -> tuple[ParticleState, ContactSet, RunRecord, dict[str, tuple]] | None:
    """State, warm contacts and record of the checkpoint in ``out_dir``, and the settings it goes on
    under with other values (:func:`continued_settings`), or None if there is none; a checkpoint of
    other settings is refused, naming them (``source``: where ``config`` came from), and one past
    the cap given (a run does not end before its last checkpoint; at the checkpoint's time it ends
    there, not at rest, which is how a run is stopped where it stands and kept)."""
    path = out_dir / CHECKPOINT_FILE
    if not path.is_file():
        return None
    saved = read_packing(path)
    meta = saved.metadata
    changed = continued_settings(meta.get("config"), config)
    if changed is None:
        differences = config_differences(_as_today(meta.get("config")), config.to_toml(),
                                         f"the checkpoint (and {out_dir / CONFIG_FILE})", source or "the config given")
        raise InputError(f"{path}: made with other settings than the config given: {differences}; resume with "
                         f"{out_dir / CONFIG_FILE} (or those settings, {' and '.join(CONTINUABLE_SETTINGS)} aside), "
                         "or replace the run with --overwrite")
    state = saved_state(saved.state, config, mixture)
    try:
        record = RunRecord.from_dict(meta["counters"])
    except (KeyError, TypeError) as exc:
        raise InputError(f"{path}: not a checkpoint this version reads ({exc}); replace the run with --overwrite") from None
    if settling_policy(config).max_steps < record.milestones.step:
        raise InputError(f"equilibrium.max_time = {config.equilibrium.max_time:g}: the checkpoint in {out_dir} is at "
                         f"t = {state.time:.6g} sqrt(d/g); set it to that (the run then ends there, not at rest) or "
                         "beyond")
    return state, saved.contacts, record, changed


#: how a finished run carries on under a config that changes its :data:`~granpack.config.CONTINUABLE_SETTINGS`
#: (:func:`_finished_run_carrying_on`): it goes on from its final state, or it is that config's run already
GO_ON, SAME_RUN = "go on", "same run"


def _saved_config(out_dir: Path) -> str:
    """The resolved config a run folder was last run with: its ``config.toml``, or its final
    state's where it has none (a campaign's kept run: only the run's own results are kept); empty
    if there is neither."""
    path, final = out_dir / CONFIG_FILE, out_dir / FINAL_FILE
    if path.is_file():
        return path.read_text(encoding="utf-8")
    if not final.is_file():
        return ""
    try:
        return read_packing(final).metadata.get("config") or ""
    except InputError:
        return ""


def _finished_run_carrying_on(out_dir: Path, config: RunConfig) -> tuple[str, dict[str, tuple], float] | None:
    """How the finished run of ``out_dir`` carries on under ``config``, whose settings differ from
    its own only in :data:`~granpack.config.CONTINUABLE_SETTINGS`: :data:`GO_ON` for a run that
    ended not at rest given a cap beyond its end, :data:`SAME_RUN` for one that came to rest given
    another cap only, not before its end (the run would have stopped at the same step); with the
    settings changed, ``{key: (run's, given)}``, and the run's end, sqrt(d/g). None when ``out_dir``
    holds a checkpoint, no finished run, or one of ``config`` or of other settings
    (:func:`~granpack.io.run_folder.claim_folder` judges those).

    Raises:
        InputError: a run at rest given another tolerance or an earlier cap; a run not at rest
            given a cap not beyond its end.
    """
    summary_path = out_dir / SUMMARY_FILE
    if not ((out_dir / FINAL_FILE).is_file() and summary_path.is_file()) or (out_dir / CHECKPOINT_FILE).is_file():
        return None
    changed = continued_settings(_saved_config(out_dir), config)
    if not changed:
        return None
    summary = read_json(summary_path)
    end, steps, max_steps = float(summary["simulated_time"]), int(summary["steps"]), settling_policy(config).max_steps
    if summary.get("status") == STATUS_NOT_AT_REST:
        if max_steps > steps:
            return GO_ON, changed, end
        raise InputError(f"equilibrium.max_time = {config.equilibrium.max_time:g}: the run in {out_dir} ended not at "
                         f"rest at t = {end:.6g} sqrt(d/g); set it beyond that to take the run further")
    if set(changed) == {"equilibrium.max_time"} and max_steps >= steps:
        return SAME_RUN, changed, end
    raise InputError(f"{out_dir}: holds a run that came to rest at t = {end:.6g} sqrt(d/g), which is not the run "
                     f"of {_changes(changed)}: --overwrite replaces it, or choose another --out folder")


def carries_on(out_dir: str | os.PathLike, config: RunConfig) -> bool:
    """Whether ``run_packing(config, out_dir, resume=True)`` takes the run in ``out_dir`` (a
    checkpoint or a finished run) on as ``config``'s: of the same settings, or of other
    :data:`~granpack.config.CONTINUABLE_SETTINGS` only, from a checkpoint or as
    :func:`_finished_run_carrying_on` allows; a campaign keeps such runs."""
    out_dir = Path(out_dir)
    checkpoint = (out_dir / CHECKPOINT_FILE).is_file()
    finished = (out_dir / FINAL_FILE).is_file() and (out_dir / SUMMARY_FILE).is_file()
    changed = continued_settings(_saved_config(out_dir), config)
    if changed is None or not (checkpoint or finished):
        return False
    if checkpoint or not changed:
        return True
    try:
        return _finished_run_carrying_on(out_dir, config) is not None
    except InputError:
        return False


def _go_on_from_final(out_dir: Path, config: RunConfig, note: Notes) -> None:
    """Carry on the finished run of ``out_dir`` under ``config`` (:func:`_finished_run_carrying_on`):
    a run that ended not at rest goes on, its final state (which carries the run's record) made its
    checkpoint, its summary and what was made from its final state
    (:data:`~granpack.io.run_folder.DERIVED_FILES`, figures, exports) removed; a run at rest that is
    ``config``'s run too gets ``config`` as its ``config.toml`` (and is then returned as it is).
    Touches nothing when neither applies.

    Raises:
        InputError: :func:`_finished_run_carrying_on` refuses; the final state holds no record
            (written by an older granpack).
    """
    carrying = _finished_run_carrying_on(out_dir, config)
    if carrying is None:
        return
    kind, changed, end = carrying
    if kind == SAME_RUN:
        write_text_atomic(out_dir / CONFIG_FILE, config.to_toml())
        note(f"{out_dir} holds a run that came to rest at t = {end:.6g} sqrt(d/g), before either cap "
             f"({_changes(changed)}): it is this config's run too")
        return
    final = out_dir / FINAL_FILE
    if "counters" not in read_packing(final).metadata:
        raise InputError(f"{final}: holds no run record to go on from (written by an older granpack): replace the "
                         "run with --overwrite")
    os.replace(final, out_dir / CHECKPOINT_FILE)
    removed = clear_run(out_dir, (SUMMARY_FILE, *DERIVED_FILES))
    note(f"{out_dir} ended not at rest at t = {end:.6g} sqrt(d/g): going on from its final state, now its "
         f"{CHECKPOINT_FILE}; removed {', '.join([FINAL_FILE, *removed])}")


class _Checkpoints:
    """Observer: a checkpoint every ``output.checkpoint_interval``, trajectory frames every
    ``output.snapshot_interval``, and on Ctrl-C a checkpoint of the step just made, then
    :class:`RunInterrupted`."""

    def __init__(self, out_dir: Path, interrupt: Interrupt, note: Notes, checkpoint_every: int, snapshot_every: int):
        self.out_dir, self.interrupt, self.note = out_dir, interrupt, note
        self.checkpoint_every, self.snapshot_every = checkpoint_every, snapshot_every  # steps; 0: no snapshots

    def checked(self, run: Settling) -> None:
        for line in run.notes:
            self.note(line)

    def stepped(self, run: Settling) -> None:
        step = run.record.milestones.step
        if self.snapshot_every and step % self.snapshot_every == 0:
            append_frame(self.out_dir / TRAJECTORY_FILE, run.packing({"status": "settling"}))
        due = step % self.checkpoint_every == 0
        if due or self.interrupt.requested:
            run.record.clock.stamp(cpu=False)
            write_packing(self.out_dir / CHECKPOINT_FILE, run.packing({"counters": run.record.as_dict()}))
        if self.interrupt.requested:  # Ctrl-C: stop here, the checkpoint of this step written
            raise RunInterrupted(self.out_dir / CHECKPOINT_FILE, run.state.time, step)


def run_packing(config: RunConfig, out_dir: str | os.PathLike, *, resume: bool = False, overwrite: bool = False,
                progress: bool | str = True, warnings: Sequence[str] = (), source: str | None = None) -> dict:
    """Pour and settle one packing; write its files; return its summary.

    No work is lost without a word: a folder that holds a run (any of :data:`RUN_FILES`) is
    continued with ``resume``, replaced with ``overwrite``, and refused otherwise; a
    ``config.toml`` there that is not a granpack run's (a folder without a run, a config that
    is not a resolved one) is never replaced.

    Args:
        config: the validated run config.
        out_dir: output folder (created if needed).
        resume: continue from ``out_dir/checkpoint.gsd``; a finished run (``summary.json`` and
            ``final.gsd``) of the same config is returned as it is, one that ended not at rest goes
            on from ``final.gsd`` when ``config`` raises ``equilibrium.max_time`` beyond its end; a
            folder without a run is started afresh. ``config`` may differ from the run's own in
            :data:`~granpack.config.CONTINUABLE_SETTINGS` only.
        overwrite: replace the run that ``out_dir`` holds: its :data:`RUN_FILES` and the
            figures and exports of :data:`RUN_FOLDERS` are removed first (other files stay).
        progress: ``"bar"``: progress bars on stderr; ``"lines"``: a progress line on stderr
            every 30 s of wall time (for logs); ``"log"``: the same lines and the notes appended
            to ``out_dir/progress.log`` instead (a campaign's runs, whose stderr nobody reads);
            ``True``: the bars if stderr is a terminal, else the lines; ``False``: nothing. Notes
            (resuming, overwriting) go to stderr unless ``False`` or ``"log"``.
        warnings: lines written as ``warning: ...`` notes once the folder is accepted, before a
            new run pours (none on a resume), after those of :func:`granpack.advice.advise`, which
            this function asks itself (the CLI adds the file's own, e.g. an old layout).
        source: where ``config`` came from (a file name), named when a resume finds a run of other
            settings.

    Returns:
        The summary written to ``summary.json``: ``status`` (``"equilibrium"`` or
        ``"not at rest"``), steps, simulated and wall times, NLGS statistics, the last
        equilibrium figures (``equilibrium``: the criteria, e.g. ``kinetic_energy`` is the largest
        kinetic energy of a grain over ``d_p^3 P``) and the final state (``final``:
        ``total_kinetic_energy`` is the sum over the grains, in ``rho g d^4``, i.e. ``m g d`` for
        a mass ``m`` of ``d^3`` of grain; contacts; the largest overlap in d).

    Raises:
        InputError: ``config`` is refused by :func:`granpack.advice.advise` (a grading its grains
            cannot represent), before anything is written; ``out_dir`` cannot be created or is a file; it holds a run and neither
            ``resume`` nor ``overwrite`` is given (or both are); its ``config.toml`` is not a
            granpack run's; its checkpoint or finished run belongs to another config (or, to go
            on, a run at rest, a cap not raised: :func:`_go_on_from_final`).
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
    mixture = Mixture.from_config(config)
    advice = advise(config, mixture)  # a refusal raises before the folder is touched
    if resume and not overwrite:
        _go_on_from_final(out_dir, config, note)
    if claim_folder(out_dir, config_text, resume=resume, overwrite=overwrite, note=note, source=source):
        return read_json(out_dir / SUMMARY_FILE)
    wall_start = time.perf_counter()
    resumed = _resume_from(out_dir, config, mixture, source) if resume else None  # refused before anything is written
    write_text_atomic(out_dir / CONFIG_FILE, config_text)
    for stale in (SUMMARY_FILE, FINAL_FILE, CONTAINER_FILE):
        (out_dir / stale).unlink(missing_ok=True)
    if resumed is None:
        (out_dir / CHECKPOINT_FILE).unlink(missing_ok=True)
        (out_dir / TRAJECTORY_FILE).unlink(missing_ok=True)
        for warning in [*advice, *warnings]:
            note(f"warning: {warning}")
        t0 = time.perf_counter()
        note(f"pouring {config.n_particles} grains (deposit {config.deposit.method}, lateral {config.deposit.lateral})",
             lines_only=True)
        state, mixture = initial_state(config, progress=mode == "bar", mixture=mixture)
        record = RunRecord(clock=Clock(deposit_seconds=time.perf_counter() - t0), initial_order=deposit_order(state))
        note(f"poured in {record.clock.deposit_seconds:.0f} s; settling", lines_only=True)
        contacts = None
    else:
        state, contacts, record, changed = resumed
        note(f"resuming from t = {state.time:.6g} sqrt(d/g) (step {record.milestones.step}) of {out_dir / CHECKPOINT_FILE}"
             + (f" with {_changes(changed)}" if changed else ""))
        truncate_frames(out_dir / TRAJECTORY_FILE, record.milestones.step)
    record.clock.start(wall_start)

    run = Settling(config, mixture, state, contacts, record)
    bar = SettlingProgress(mode, config.equilibrium.max_time, write)
    interrupt = Interrupt()
    output = config.output
    checkpoints = _Checkpoints(out_dir, interrupt, note, run.steps_of(output.checkpoint_interval),
                               run.steps_of(output.snapshot_interval) if output.snapshot_interval > 0 else 0)
    with bar, interrupt:
        status = run.run((bar, checkpoints))
    summary = write_run(out_dir, config, run, status)
    (out_dir / CHECKPOINT_FILE).unlink(missing_ok=True)
    note(f"{status} at t = {state.time:.6g} sqrt(d/g) after {record.clock.wall_seconds:.0f} s: "
         f"largest net force {run.report.max_net_force:.3g} d^2 P", lines_only=True)
    return summary


def write_run(out_dir: Path, config: RunConfig, run: Settling, status: str) -> dict:
    """Write a settled run's files into ``out_dir``: ``final.gsd`` (with the status, the
    summary's headline and the run's record), the container's STL for a mould, ``summary.json`` and ``timeline.csv``;
    returns the summary, whose wall and CPU times (the clock is stamped first) end where the writing starts."""
    run.record.clock.stamp()
    summary = _summary(config, run, status)
    final = run.packing({"status": status, "summary": headline(summary), "counters": run.record.as_dict()})
    write_packing(out_dir / FINAL_FILE, final)
    if not final.box.periodic:
        write_container_stl(out_dir / CONTAINER_FILE, final)
    write_json(out_dir / SUMMARY_FILE, summary)
    write_text_atomic(out_dir / TIMELINE_FILE, timeline_csv(run.record.timeline))
    return summary


def headline(summary: dict) -> dict:
    """The four fields of a run's summary that say how it ended: status, steps, simulated and
    wall time."""
    return {k: summary[k] for k in ("status", "steps", "simulated_time", "wall_time")}


def _summary(config: RunConfig, run: Settling, status: str) -> dict:
    from granpack import __version__
    from granpack._numba import thread_count, threading_layer

    state, contacts, report = run.state, run.contacts, run.report
    t, m, clock = run.record.totals, run.record.milestones, run.record.clock
    steps = max(m.step, 1)
    n_points = contacts.n_points if contacts is not None else 0
    gaps = contacts.gap if contacts is not None and n_points else np.zeros(0)
    return {
        "version": __version__,
        "status": status,
        "seed": config.seed,
        "n_particles": state.n,
        "container": state.box.to_dict(),
        "steps": m.step,
        "simulated_time": state.time,
        "time_step": config.time_stepping.time_step,
        "wall_time": clock.wall_seconds,
        "cpu_time": clock.cpu_seconds,
        "threads": {"numba": thread_count(), "layer": threading_layer()},
        "initial_order": dict(run.record.initial_order),
        "timing": {
            "deposit_seconds": clock.deposit_seconds,
            "detection_seconds": t.detection_seconds,
            "solver_seconds": t.solver_seconds,
            "detection_ms_per_step": 1e3 * t.detection_seconds / steps,
            "solver_ms_per_step": 1e3 * t.solver_seconds / steps,
            "point_updates_per_second": t.point_updates / t.solver_seconds if t.solver_seconds > 0 else None,
        },
        "nlgs": {
            "mean_iterations": t.iterations_total / max(t.solves, 1),
            "max_iterations": t.iterations_max,
            "unconverged_steps": t.unconverged_steps,
            "solves": t.solves,
            "tolerance": config.solver.tolerance,
        },
        "split_steps": t.split_steps,
        "position_correction": {"steps": t.correction_steps, "potential_energy_added": t.correction_energy},
        "end_game": {"mode": config.end_game.mode, "started": m.end_game, "kinetic_energy_removed": t.damped_energy,
                     "shakes": m.shakes, "rest_recovery_from": m.rest_recovery_from},
        "equilibrium": report.as_dict(),
        "final": {  # the last state; total kinetic energy in rho g d^4 (the per-grain criterion: "equilibrium")
            "total_kinetic_energy": kinetic_energy(state),
            "contacts": contacts.n_manifolds if contacts is not None else 0,
            "contact_points": n_points,
            "max_overlap": float(max(0.0, -gaps.min())) if len(gaps) else 0.0,
            "height": float(np.max(state.position[:, 2] + state.radius)) if state.n else 0.0,
        },
        "max_overlap_during_run": t.max_overlap,
    }

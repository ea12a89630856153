"""What a settling run measures, each quantity declared once: solver effort, milestones, clocks, timeline.

A :class:`RunRecord` is everything a checkpoint carries besides the grains and the contacts. Each
part is updated in one place: :meth:`SolverTotals.add` after every NSCD solve, the milestones by
the loop of :mod:`granpack.settling`, :meth:`Clock.stamp` before a check or a checkpoint, and the
timeline by :func:`timeline_row` at every check; it is saved as one flat dict (a checkpoint's
``counters``, :meth:`RunRecord.as_dict`) so that the checkpoints of granpack 0.1.0 resume.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields

import numpy as np

from granpack.contact import ContactSet
from granpack.equilibrium import EquilibriumReport
from granpack.nscd import StepInfo, kinetic_energy, potential_energy
from granpack.state import ParticleState

__all__ = ["TIMELINE_COLUMNS", "SolverTotals", "Milestones", "Clock", "RunRecord", "timeline_row", "timeline_csv"]

#: columns of ``timeline.csv``, one row per equilibrium check: counts and sums over the interval
#: since the previous check, figures of the equilibrium test at the check; ``overlap_sum`` is the
#: sum of the contact points' overlaps, d, which grows while a pile sinks into its overlaps and
#: stays put while it rearranges (the largest overlap stays at the recovery's slop either way)
TIMELINE_COLUMNS = (
    "time", "step", "kinetic_energy_total", "potential_energy_change", "kinetic_criterion", "max_net_force", "max_net_torque",
    "wall_force_over_weight", "nlgs_tolerance", "mean_sweeps", "max_sweeps", "unconverged_steps",
    "corrected_steps", "correction_sweeps", "correction_energy", "damped_energy", "contacts", "contact_points", "max_overlap",
    "overlap_sum", "wall_seconds", "cpu_seconds",
)
#: the running totals kept after the columns in each row, from which the next row's interval sums
#: come: fields of :class:`SolverTotals`, then the potential energy
_TOTALS = ("solves", "iterations_total", "unconverged_steps", "correction_steps", "correction_iterations",
           "correction_energy", "damped_energy", "potential_energy")
_POTENTIAL_COLUMN = TIMELINE_COLUMNS.index("potential_energy_change")
_OVERLAP_SUM_COLUMN = TIMELINE_COLUMNS.index("overlap_sum")
#: length of a timeline row in checkpoints written before the overlaps' sum was recorded ...
_ROW_WITHOUT_OVERLAP_SUM = len(TIMELINE_COLUMNS) + len(_TOTALS) - 1
#: ... and before the potential energy was
_ROW_WITHOUT_POTENTIAL = _ROW_WITHOUT_OVERLAP_SUM - 2


@dataclass
class SolverTotals:
    """The effort and side effects of the NSCD solves since the run started (sums, or the largest)."""

    solves: int = 0  # NLGS velocity solves (one per step, k per step split into k substeps)
    split_steps: int = 0  # steps split into substeps
    iterations_total: int = 0  # NLGS sweeps of the velocity solves
    iterations_max: int = 0
    interval_max_sweeps: int = 0  # most sweeps of a solve since the last check
    unconverged_steps: int = 0
    point_updates: int = 0  # sweeps x contact points
    max_overlap: float = 0.0  # d
    correction_steps: int = 0  # solves followed by a position correction
    correction_iterations: int = 0  # NLGS sweeps of the position corrections
    correction_energy: float = 0.0  # potential energy added by the corrections, rho g d^4
    damped_energy: float = 0.0  # kinetic energy removed by the end game's damping, rho g d^4
    detection_seconds: float = 0.0
    solver_seconds: float = 0.0

    def add(self, info: StepInfo) -> None:
        """Count one solve."""
        self.solves += 1
        self.iterations_total += info.iterations
        self.iterations_max = max(self.iterations_max, info.iterations)
        self.interval_max_sweeps = max(self.interval_max_sweeps, info.iterations)
        self.unconverged_steps += 0 if info.converged else 1
        self.point_updates += info.iterations * info.n_points
        self.max_overlap = max(self.max_overlap, info.max_overlap)
        self.correction_steps += 1 if info.correction_iterations else 0
        self.correction_iterations += info.correction_iterations
        self.correction_energy += info.correction_energy
        self.damped_energy += info.damped_energy
        self.detection_seconds += info.detection_seconds
        self.solver_seconds += info.solver_seconds


@dataclass
class Milestones:
    """Where the run stands in its phases (:mod:`granpack.settling`); the flags, once set, stay set."""

    step: int = 0
    passes: int = 0  # consecutive equilibrium checks passed
    end_game: bool = False  # the end game's damping has started
    near_rest: bool = False  # the fine NLGS tolerance is in use
    rest_recovery_from: float | None = None  # simulated time the slow overlap recovery started
    shakes: int = 0  # shakes given (end_game.shake_speed)
    last_shake: float | None = None  # simulated time of the last shake, sqrt(d/g)
    last_step: float = 0.0  # the (sub)step of the last solve, sqrt(d/g) (0: none yet)


@dataclass
class Clock:
    """Wall and CPU seconds of the run, summed over the commands that ran it (a resumed run)."""

    deposit_seconds: float = 0.0
    wall_seconds: float = 0.0
    cpu_seconds: float = 0.0  # process CPU time of the settling (all threads)

    def __post_init__(self):
        self.start(time.perf_counter())

    def start(self, wall_start: float) -> None:
        """Count from now (CPU) and from ``wall_start`` (a ``perf_counter`` reading: the wall time of
        this command counts from its start, the pour included)."""
        self._wall_before, self._wall_start = self.wall_seconds, wall_start
        self._cpu_before, self._cpu_start = self.cpu_seconds, time.process_time()

    def stamp(self, cpu: bool = True) -> None:
        """Bring ``wall_seconds`` (and ``cpu_seconds``) up to now."""
        self.wall_seconds = self._wall_before + time.perf_counter() - self._wall_start
        if cpu:
            self.cpu_seconds = self._cpu_before + time.process_time() - self._cpu_start


@dataclass
class RunRecord:
    """Everything a run measures and a checkpoint carries besides the grains and contacts."""

    totals: SolverTotals = field(default_factory=SolverTotals)
    milestones: Milestones = field(default_factory=Milestones)
    clock: Clock = field(default_factory=Clock)
    initial_order: dict = field(default_factory=dict)  # Q00, Q22 of the deposit before gravity acts
    last_report: dict = field(default_factory=dict)  # the last equilibrium check, EquilibriumReport.as_dict
    timeline: list = field(default_factory=list)  # one row per check: TIMELINE_COLUMNS, then the running totals

    def as_dict(self) -> dict:
        """One flat dict for a checkpoint's JSON metadata; the timeline's NaN and infinities as the
        strings ``"nan"``, ``"inf"``, ``"-inf"`` (JSON would make them ``null``)."""
        saved = {}
        for part in (self.totals, self.milestones, self.clock):
            saved.update({f.name: getattr(part, f.name) for f in fields(part)})
        saved["initial_order"] = dict(self.initial_order)
        saved["last_report"] = dict(self.last_report)
        saved["timeline"] = [[v if not isinstance(v, float) or math.isfinite(v) else repr(v) for v in row]
                             for row in self.timeline]
        return saved

    @classmethod
    def from_dict(cls, saved: dict) -> "RunRecord":
        """The record of :meth:`as_dict`, or of a checkpoint of an older version (NaN written as null,
        timeline rows without ``potential_energy_change``).

        Raises:
            KeyError: a key that no part of the record declares.
        """
        parts = {part: {f.name for f in fields(part)} for part in (SolverTotals, Milestones, Clock)}
        unknown = set(saved) - set().union(*parts.values()) - {"initial_order", "last_report", "timeline"}
        if unknown:
            raise KeyError(f"unknown counters {sorted(unknown)}")
        totals, milestones, clock = (part(**{k: saved[k] for k in names if k in saved}) for part, names in parts.items())
        timeline = [_current_layout([math.nan if v is None else float(v) if isinstance(v, str) else v for v in row])
                    for row in saved.get("timeline", [])]
        return cls(totals=totals, milestones=milestones, clock=clock, initial_order=dict(saved.get("initial_order", {})),
                   last_report=dict(saved.get("last_report", {})), timeline=timeline)


def _current_layout(row: list) -> list:
    """A checkpoint's timeline row in today's layout, so that a run of an older version resumes:
    a row written before ``potential_energy_change`` existed gets NaN for it and for its running
    total, one written before ``overlap_sum`` NaN for it."""
    if len(row) == _ROW_WITHOUT_POTENTIAL:
        row = [*row[:_POTENTIAL_COLUMN], math.nan, *row[_POTENTIAL_COLUMN:], math.nan]
    if len(row) == _ROW_WITHOUT_OVERLAP_SUM:
        row = [*row[:_OVERLAP_SUM_COLUMN], math.nan, *row[_OVERLAP_SUM_COLUMN:]]
    return row


def timeline_row(record: RunRecord, state: ParticleState, contacts: ContactSet, report: EquilibriumReport,
                 tolerance: float) -> list:
    """The timeline row of this check (interval sums from the previous row's running totals); starts
    the next interval's largest sweep count afresh."""
    t, m = record.totals, record.milestones
    totals = (*(getattr(t, name) for name in _TOTALS[:-1]), potential_energy(state))
    # the first check has no previous potential energy: its change is NaN
    previous = record.timeline[-1][len(TIMELINE_COLUMNS):] if record.timeline else (0,) * (len(totals) - 1) + (math.nan,)
    d = [a - b for a, b in zip(totals, previous)]
    overlaps = np.maximum(-contacts.gap, 0.0)
    row = [
        state.time, m.step, kinetic_energy(state), d[7], report.kinetic_energy, report.max_net_force,
        report.max_net_torque, report.wall_force_over_weight, tolerance, d[1] / max(d[0], 1), t.interval_max_sweeps,
        d[2], d[3], d[4] / max(d[0], 1), d[5], d[6], contacts.n_manifolds, contacts.n_points,
        float(overlaps.max(initial=0.0)), float(overlaps.sum()), record.clock.wall_seconds, record.clock.cpu_seconds,
        *totals,
    ]
    t.interval_max_sweeps = 0
    return row


def timeline_csv(rows: list) -> str:
    """``timeline.csv``: a header and one line per check (the running totals kept in the rows dropped)."""
    lines = [",".join(TIMELINE_COLUMNS)]
    for row in rows:
        lines.append(",".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in row[:len(TIMELINE_COLUMNS)]))
    return "\n".join(lines) + "\n"

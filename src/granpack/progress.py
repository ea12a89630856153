"""What a run tells while it settles: progress bars or lines, and one-line notes.

The settling loop (:mod:`granpack.settling`) reports to :class:`SettlingProgress` as an observer;
these decide where the messages go (stderr, a bar, or the run's ``progress.log``) and how often.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from granpack.equilibrium import EquilibriumReport

__all__ = ["PROGRESS_LINE_SECONDS", "Lines", "Notes", "SettlingProgress", "criteria_met", "progress_mode"]


def progress_mode(progress: bool | str) -> str:
    """``"bar"``, ``"lines"``, ``"log"`` or ``"off"`` for the ``progress`` argument of
    :func:`granpack.simulation.run_packing`."""
    if progress is True:
        isatty = getattr(sys.stderr, "isatty", None)
        return "bar" if isatty is not None and isatty() else "lines"
    if progress is False or progress is None:
        return "off"
    if progress in ("bar", "lines", "log", "off"):
        return str(progress)
    raise ValueError(f"progress must be True, False, 'bar', 'lines', 'log' or 'off' (got {progress!r})")


class Lines:
    """Where a run's one-line messages go: stderr, or appended to ``log`` (a file opened and
    closed per line, so that a reader sees each line at once and an interrupted run leaves a
    whole file)."""

    def __init__(self, log: Path | None = None):
        self.log = log

    def __call__(self, line: str) -> None:
        if self.log is None:
            print(line, file=sys.stderr, flush=True)
        else:
            with open(self.log, "a", encoding="utf-8") as f:
                f.write(line + "\n")


class Notes:
    """One-line notes (resuming, overwriting; the pour in ``"lines"`` and ``"log"`` modes); none when silent."""

    def __init__(self, mode: str, write: Lines):
        self.mode = mode
        self.write = write

    def __call__(self, message: str, lines_only: bool = False) -> None:
        if self.mode == "off" or (lines_only and self.mode not in ("lines", "log")):
            return
        self.write(message)


#: wall-clock seconds between two progress lines (``progress="lines"`` or ``"log"``)
PROGRESS_LINE_SECONDS = 30.0


def net_force(report: EquilibriumReport, fmt: str = ".3g", unit: str = " d^2 P") -> str:
    """The largest net force of ``report`` in d^2 P, or why there is none yet: until a contact
    carries force the stress scale P is 0 and the normalised force infinite."""
    value = report.max_net_force
    if math.isfinite(value):
        return f"{value:{fmt}}{unit}"
    return "n/a (no contact carries force yet)"


def criteria_met(report: EquilibriumReport) -> str:
    met = [name for name, ok in (("force", report.force_ok), ("torque", report.torque_ok),
                                 ("energy", report.energy_ok), ("wall", report.wall_ok)) if ok]
    return " ".join(met) if met else "none"


class SettlingProgress:
    """Progress of the settling on stderr, updated at each equilibrium check.

    ``"bar"``: a rich progress bar; the simulated time comes first and stays on an 80-column
    terminal, the figures after the bar are cut to the width left. ``"lines"``: one line every
    :data:`PROGRESS_LINE_SECONDS` of wall time (the first at the first check): simulated time,
    step, steps per second, total kinetic energy, largest net force, contacts, largest overlap,
    criteria met, written by ``write``; a line falling due between two checks (a long
    ``check_interval``) gives the figures of the last check and its time; ``"log"``: the same.
    ``"off"``: nothing.
    """

    def __init__(self, mode: str, max_time: float, write: Lines):
        self.mode = mode
        self.write = write
        self.max_time = max_time
        self._bar = None
        self._task = None
        self._last: tuple[float, int] | None = None  # (wall clock, step) of the last line
        self._checked: tuple | None = None  # the last check's figures and its simulated time

    def __enter__(self):
        if self.mode == "bar":
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
            from rich.table import Column

            self._bar = Progress(
                TextColumn("settling t = {task.completed:.2f}/{task.total:g}", table_column=Column(no_wrap=True)),
                BarColumn(bar_width=12),
                TimeElapsedColumn(),
                TextColumn("{task.fields[info]}", table_column=Column(no_wrap=True, overflow="ellipsis", ratio=1)),
                console=Console(stderr=True),
                expand=True,
            )
            self._bar.__enter__()
            self._task = self._bar.add_task("settling", total=self.max_time, info="")
        return self

    def update(self, t: float, step: int, ek: float, n_contacts: int, report: EquilibriumReport, passes: int,
               window: int, overlap: float) -> None:
        if self.mode == "bar" and self._bar is not None:
            flags = "".join(name if ok else "." for name, ok in (("F", report.force_ok), ("T", report.torque_ok),
                                                                  ("E", report.energy_ok), ("W", report.wall_ok)))
            info = (f"[{flags}] {passes}/{window}  |F| {net_force(report, '.1e', '')}  E {report.kinetic_energy:.1e}  "
                    f"Ek {ek:.2e}  contacts {n_contacts}  |T| {report.max_net_torque:.1e}  "
                    f"W {report.wall_force_over_weight:.4f}  overlap {overlap:.1e}")
            self._bar.update(self._task, completed=min(t, self.max_time), info=info)
        elif self.mode in ("lines", "log"):
            self._checked = (ek, n_contacts, report, passes, window, overlap, t)
            self._line(t, step, time.perf_counter())

    def checked(self, run) -> None:
        """Observer of a :class:`granpack.settling.Settling`: the figures of the check just made."""
        from granpack.run_record import TIMELINE_COLUMNS

        row = run.record.timeline[-1]
        self.update(run.state.time, run.record.milestones.step, row[TIMELINE_COLUMNS.index("kinetic_energy_total")],
                    run.contacts.n_manifolds, run.report, run.record.milestones.passes, run.policy.window,
                    row[TIMELINE_COLUMNS.index("max_overlap")])

    def stepped(self, run) -> None:
        """Observer of a :class:`granpack.settling.Settling`: a line when one is due (:meth:`tick`)
        on a step without a check (a check has just given its own)."""
        step = run.record.milestones.step
        if step % run.policy.check_every:
            self.tick(run.state.time, step)

    def tick(self, t: float, step: int) -> None:
        """After each step: a line in ``"lines"`` / ``"log"`` mode when one is due since the last."""
        if self._checked is None or self.mode not in ("lines", "log"):
            return
        now = time.perf_counter()
        if now - self._last[0] >= PROGRESS_LINE_SECONDS:
            self._line(t, step, now)

    def _line(self, t: float, step: int, now: float) -> None:
        if self._last is not None and now - self._last[0] < PROGRESS_LINE_SECONDS:
            return
        ek, n_contacts, report, passes, window, overlap, t_check = self._checked
        rate = ""
        if self._last is not None and now > self._last[0]:
            rate = f", {(step - self._last[1]) / (now - self._last[0]):.3g} steps/s"
        self._last = (now, step)
        when = "" if t_check == t else f" (at the last check, t = {t_check:.2f})"
        self.write(f"settling t = {t:.2f}/{self.max_time:g} sqrt(d/g), step {step}{rate}, "
                   f"kinetic energy {ek:.3g}, largest net force {net_force(report)}, "
                   f"{n_contacts} contacts, largest overlap {overlap:.2g} d, "
                   f"criteria met: {criteria_met(report)} ({passes}/{window} checks){when}")

    def __exit__(self, *exc):
        if self._bar is not None:
            self._bar.__exit__(*exc)
        return False

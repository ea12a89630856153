"""Run a campaign on Dask: one task per (mixture, replica), resumable, failures isolated.

Each task runs :func:`granpack.simulation.run_packing` then
:func:`granpack.analysis.report.analyze_run` in its own run folder ``<out>/<mixture>/seed-<s>``
(see :mod:`granpack.campaign.store` for what a folder holds). Rerunning a campaign

- skips finished runs (valid ``analysis.json`` for the same run config);
- only analyses a run whose simulation completed (``summary.json`` and ``final.gsd`` present);
- resumes a run from its checkpoint when it has one, else starts it afresh; the interrupted runs
  start before the others, then the longest first;
- carries on a run whose folder was made for a config that differs from its own only in the
  settings a resumed run may change (:data:`granpack.config.CONTINUABLE_SETTINGS`): with a later
  ``max_time`` a run that ended not at rest goes on from its final state and one at rest is kept;
- starts afresh a run whose folder was made for another config (its old outputs are removed);
- runs only the mixtures asked for, if any (``mixtures``: shell patterns of their names), so that
  machines without a Dask cluster in common can share a campaign, each taking its own mixtures
  into a copy of the output folder; the tables list every run (``missing`` for those not run).

Each run appends its progress lines and notes to ``progress.log`` in its folder (nobody reads
a worker's stderr); every ten minutes the campaign prints the last of those lines for each run
in progress, so that a campaign of hour-long runs shows where each stands in its log.

A task that fails is retried once; if it fails again, its traceback is saved as ``error.txt`` in
its folder and its row in ``runs.csv`` says ``failed``; the other tasks go on.

The tasks run on a :class:`distributed.LocalCluster` of ``workers`` processes with one thread
each (Numba and BLAS limited to one thread per worker), or on an existing cluster given by its
scheduler address (e.g. one started by dask-jobqueue); the output folder must then be on a file
system that the workers share.
"""

from __future__ import annotations

import contextlib
import fnmatch
import logging
import os
import shutil
import signal
import threading
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Iterator

import pandas as pd
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from granpack.analysis._base import AnalysisWarning
from granpack.campaign.spec import CampaignSpec, RunSpec
from granpack.campaign.store import (
    clear_error,
    is_finished,
    read_task,
    runs_table,
    task_matches,
    write_error,
    write_tables,
    write_task,
)
from granpack.errors import InputError
from granpack.io.atomic import output_folder
from granpack.io.run_folder import (
    ANALYSIS_FILE,
    CAMPAIGN_SPEC_FILE,
    CONFIG_FILE,
    FINAL_FILE,
    PROGRESS_FILE,
    RUN_FILES,
    SUMMARY_FILE,
)

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["CampaignReport", "changed_runs", "run_campaign", "run_task", "selected_runs", "status_line", "MAX_ATTEMPTS"]

#: attempts per task (the first run and one retry)
MAX_ATTEMPTS = 2
#: environment of the local workers: one thread each for Numba, OpenMP and BLAS
_WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
_PROGRESS_SECONDS = 2.0  # longest wait between two refreshes of the progress line
#: wall-clock seconds between two rounds of status lines of the runs in progress
_STATUS_SECONDS = 600.0
_CHECKPOINT_GLOB = "checkpoint*"
#: held by a task while it simulates and analyses: the runs a worker process is given at once (a
#: worker with several threads) take turns, since the parallel kernels of one process share one
#: pool of Numba threads, which takes one caller at a time (granpack._numba)
_ONE_RUN_AT_A_TIME = threading.Lock()


@dataclass(frozen=True)
class CampaignReport:
    """What a campaign command did.

    Attributes:
        n_runs: tasks this call was asked for (the whole campaign, or the mixtures selected).
        n_skipped: runs already finished before this call.
        n_done: runs finished now (computed by this call, or skipped).
        n_failed: runs that failed twice in this call.
        n_at_rest: runs asked for that are finished at certified rest (the others done stopped at
            the time cap, ``equilibrium.max_time``).
        runs: the runs table written to ``runs.csv``.
        summary: the per-mixture table written to ``summary.csv``.
    """

    n_runs: int
    n_skipped: int
    n_done: int
    n_failed: int
    n_at_rest: int
    runs: pd.DataFrame
    summary: pd.DataFrame


def _clear_outputs(run_dir: Path) -> None:
    """Remove the outputs of a run made for another config (so none of them is reused)."""
    for name in (ANALYSIS_FILE, SUMMARY_FILE, FINAL_FILE):
        (run_dir / name).unlink(missing_ok=True)
    for checkpoint in run_dir.glob(_CHECKPOINT_GLOB):
        if checkpoint.is_file():
            checkpoint.unlink()


def run_task(run: RunSpec, out_dir: str) -> dict:
    """One campaign task (runs on a worker): simulate as needed, then analyse.

    Args:
        run: the task.
        out_dir: the campaign output folder (absolute path, shared with the workers).

    Returns:
        ``{"status": "done" | "failed", "action": "simulated" | "resumed" | "analysed",
        "error": last line of the error or None, "wall_time": seconds, "warnings": number of
        analysis warnings (listed in the run's analysis.json)}``.
    """
    run_dir = Path(out_dir) / run.folder
    start = time.perf_counter()
    action = "simulated"
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        from granpack.analysis.report import analyze_run
        from granpack.simulation import run_packing

        if task_matches(run_dir, run):
            if (run_dir / SUMMARY_FILE).is_file() and (run_dir / FINAL_FILE).is_file():
                action = "analysed"
            elif any(run_dir.glob(_CHECKPOINT_GLOB)):
                action = "resumed"
        elif _carries_on(run_dir, run):
            write_task(run_dir, run)
            action = "resumed"
        else:
            _clear_outputs(run_dir)
            write_task(run_dir, run)
        with _ONE_RUN_AT_A_TIME:
            if action != "analysed":  # the campaign owns its run folders: a run started afresh replaces what is there
                run_packing(run.config, run_dir, resume=action == "resumed", overwrite=action == "simulated", progress="log")
            with warnings.catch_warnings():  # kept in analysis.json ("warnings"), not printed by the workers
                warnings.simplefilter("ignore", AnalysisWarning)
                result = analyze_run(run_dir)
        clear_error(run_dir)
        return {"status": "done", "action": action, "error": None, "wall_time": time.perf_counter() - start,
                "warnings": len(result.get("warnings") or [])}
    except Exception as exc:  # a task reports its failure instead of raising: the others go on
        with contextlib.suppress(OSError):
            write_error(run_dir, traceback.format_exc())
        message = " ".join(f"{type(exc).__name__}: {exc}".split())
        return {"status": "failed", "action": action, "error": message, "wall_time": time.perf_counter() - start}


class _QuietShutdown:
    """Ctrl-C: while the interrupted cluster closes, its races (a nanny's CancelledError ...) are
    logged as errors with tracebacks; the ``distributed`` loggers are silenced from the interrupt
    until the cluster is closed (:meth:`closing`, entered first, restores them)."""

    def __init__(self):
        self._saved: dict[logging.Logger, int] = {}

    @contextlib.contextmanager
    def closing(self) -> Iterator[None]:
        try:
            yield
        finally:
            for logger, level in self._saved.items():
                logger.setLevel(level)
            self._saved.clear()

    @contextlib.contextmanager
    def interrupted(self) -> Iterator[None]:
        try:
            yield
        except KeyboardInterrupt:
            names = ["distributed", *(n for n in logging.root.manager.loggerDict if n.startswith("distributed."))]
            for logger in map(logging.getLogger, names):
                self._saved.setdefault(logger, logger.level)
                logger.setLevel(logging.CRITICAL + 1)
            raise


def dask_setup(worker: object) -> None:
    """Preload of the local workers (run in each worker process as it starts, restarts
    included): ignore SIGINT, and log only critical ``distributed`` messages.

    Ctrl-C in a terminal signals the whole process group. A worker that took it would close
    itself while this process closes the cluster, and the two shutdowns race (a worker's
    ``CommClosedError`` logged with its traceback); with the workers deaf to it, this process
    alone closes the cluster and the interrupted runs keep their checkpoints. A worker whose
    heartbeat is in flight when the scheduler closes still logs that failure with a traceback
    onto the campaign's stderr, so the workers' own ``distributed`` errors are not logged: a
    run's failure reaches the campaign as the task's outcome (and the run's error file), and a
    lost worker is logged by its nanny, in this process.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed").setLevel(logging.CRITICAL)


@contextlib.contextmanager
def _client(scheduler: str | None, workers: int | None, n_tasks: int) -> Iterator[Client]:
    """A Dask client on the given scheduler, or on a new local cluster of processes."""
    from distributed import Client, LocalCluster

    quiet = _QuietShutdown()
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler: cannot connect to {scheduler!r} ({exc})") from None
        with quiet.closing(), client, quiet.interrupted():
            yield client
        return
    n_workers = workers if workers is not None else max(1, min(os.cpu_count() or 1, n_tasks))
    with quiet.closing(), LocalCluster(
        n_workers=n_workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",  # any free port: with the default, 8787, a second campaign on the machine warns
        silence_logs=logging.ERROR,
        env=_WORKER_ENV,
        preload=[__name__],  # dask_setup below: the workers leave Ctrl-C to this process
    ) as cluster, Client(cluster) as client, quiet.interrupted():
        yield client


def estimated_cost(run: RunSpec) -> int:
    """Relative cost of a run: grains x settling-time cap (``n_particles * max_time``)."""
    return int(run.config.n_particles * run.config.equilibrium.max_time)


def _carries_on(run_dir: Path, run: RunSpec) -> bool:
    """Whether the work in ``run_dir``, made for another config of the run, carries on under
    ``run``'s: the two differ only in settings a resumed run may change
    (:func:`granpack.simulation.carries_on`: a later cap, a finer tolerance)."""
    from granpack.simulation import carries_on

    return read_task(run_dir) is not None and carries_on(run_dir, run.config)


def has_checkpoint(out_dir: Path, run: RunSpec) -> bool:
    """Whether ``run`` was interrupted in ``out_dir``: a checkpoint in a folder made for this
    very run config, or one it carries on from (a task there resumes from it)."""
    run_dir = Path(out_dir) / run.folder
    return any(run_dir.glob(_CHECKPOINT_GLOB)) and (task_matches(run_dir, run) or _carries_on(run_dir, run))


def run_order(runs: list[RunSpec], out_dir: Path) -> list[RunSpec]:
    """The order in which ``runs`` start: interrupted runs (:func:`has_checkpoint`) first, then by
    decreasing :func:`estimated_cost` (stable sort).

    Resuming first finishes the work already paid for before new runs start, so that a campaign
    stopped again and again carries few checkpoints; the longest runs then start first, so that
    a big run does not start last and leave the other workers idle (longest-processing-time rule).
    """
    return sorted(runs, key=lambda run: (has_checkpoint(out_dir, run), estimated_cost(run)), reverse=True)


def _last_line(path: Path) -> str | None:
    """The last non-blank line of the text file ``path`` (read from its end); None if it has none
    or does not exist."""
    try:
        with open(path, "rb") as f:
            size = f.seek(0, os.SEEK_END)
            f.seek(max(0, size - 4096))
            tail = f.read().decode("utf-8", errors="replace")
    except FileNotFoundError:
        return None
    lines = [line for line in tail.splitlines() if line.strip()]
    return lines[-1] if lines else None


def status_line(out_dir: Path, run: RunSpec, since: float | None = None) -> str | None:
    """``running <mixture>/seed-<s>: <the last line of its progress.log>``, or None before the
    run has written one (a run still pouring its first grains) or, with ``since`` (seconds since
    the epoch), one since then (a task waiting for a worker, whose log is an earlier call's)."""
    path = Path(out_dir) / run.folder / PROGRESS_FILE
    try:
        if since is not None and path.stat().st_mtime < since:
            return None
    except FileNotFoundError:
        return None
    line = _last_line(path)
    return None if line is None else f"running {run.folder.as_posix()}: {line}"


def _execute(client: Client, todo: list[RunSpec], out_dir: Path, progress: bool, errors: dict[Path, str]) -> tuple[int, int]:
    """Submit ``todo`` (in :func:`run_order`), retry failures once, show progress (every
    :data:`_STATUS_SECONDS`, the :func:`status_line` of each run in progress); returns (done,
    failed) counts."""
    from distributed import wait

    attempts: dict[Path, int] = {}
    active: dict = {}
    order = run_order(todo, out_dir)
    priority = {run.folder: len(order) - rank for rank, run in enumerate(order)}  # Dask starts the highest first

    def submit(run: RunSpec) -> None:
        attempts[run.folder] = attempts.get(run.folder, 0) + 1
        key = f"granpack-{run.mixture}-seed-{run.seed}-attempt-{attempts[run.folder]}"
        future = client.submit(run_task, run, str(out_dir), key=key, pure=False, priority=priority[run.folder])
        active[future] = run

    for run in order:
        submit(run)
    done = failed = 0
    columns = (
        TextColumn("[bold]campaign"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("done {task.fields[done]}  running {task.fields[running]}  failed {task.fields[failed]}"),
        TimeElapsedColumn(),
    )
    started, last_status = time.time(), time.monotonic()
    console = Console(stderr=True, soft_wrap=True)  # progress and notes on stderr, a line each however long
    with Progress(*columns, console=console, disable=not progress or not console.is_terminal, transient=False) as bar:
        task = bar.add_task("runs", total=len(todo), done=0, running=0, failed=0)
        while active:
            finished = [future for future in active if future.done()]
            for future in finished:
                run = active.pop(future)
                if future.status == "finished":
                    outcome = future.result()
                else:  # the task itself could not run (worker lost, unpicklable input, ...)
                    exc = future.exception()
                    outcome = {"status": "failed", "error": " ".join(f"{type(exc).__name__}: {exc}".split())}
                label = run.folder.as_posix()
                if outcome["status"] == "done":
                    done += 1
                    n_warnings = outcome.get("warnings") or 0
                    note = f"; {n_warnings} analysis warning(s) in its analysis.json" if n_warnings else ""
                    console.print(f"done    {label} ({outcome['action']}, {outcome['wall_time']:.1f} s{note})",
                                  markup=False, highlight=False)
                elif attempts[run.folder] < MAX_ATTEMPTS:
                    console.print(f"retry   {label}: {outcome['error']}", markup=False, highlight=False)
                    submit(run)
                else:
                    failed += 1
                    errors[run.folder] = outcome["error"]
                    console.print(f"failed  {label}: {outcome['error']}", markup=False, highlight=False)
            # tasks given to a worker, some of them queued there behind the one each thread runs
            processing = {key for keys in client.processing().values() for key in keys}
            running = min(len(processing), sum(client.nthreads().values()))
            bar.update(task, completed=done + failed, done=done, running=running, failed=failed)
            if progress and time.monotonic() - last_status >= _STATUS_SECONDS:
                last_status = time.monotonic()
                for future, run in active.items():
                    line = status_line(out_dir, run, since=started) if future.key in processing else None
                    if line is not None:
                        console.print(line, markup=False, highlight=False)
            if active:
                try:  # block until a run ends (a bounded wait, to refresh the running count)
                    wait(list(active), timeout=_PROGRESS_SECONDS, return_when="FIRST_COMPLETED")
                except TimeoutError:
                    pass
    return done, failed


def selected_runs(spec: CampaignSpec, mixtures: list[str] | None) -> tuple[RunSpec, ...]:
    """The runs of the mixtures whose names match one of the shell patterns ``mixtures`` (all
    runs when ``None``), in the campaign's order.

    Raises:
        InputError: a pattern that matches no mixture (the message lists the mixtures).
    """
    if mixtures is None:
        return spec.runs
    names = [m.name for m in spec.mixtures]
    for pattern in mixtures:
        if not any(fnmatch.fnmatchcase(name, pattern) for name in names):
            raise InputError(f"--mixture: {pattern!r} matches no mixture of the campaign (mixtures: {', '.join(names)})")
    return tuple(run for run in spec.runs if any(fnmatch.fnmatchcase(run.mixture, p) for p in mixtures))


def changed_runs(out_dir: Path, runs: Iterable[RunSpec]) -> list[RunSpec]:
    """The runs whose folders in ``out_dir`` hold the work (outputs or a checkpoint) of another
    config than theirs, which does not carry on under theirs (:func:`_carries_on`): what running
    them would replace."""
    changed = []
    for run in runs:
        run_dir = out_dir / run.folder
        work = [name for name in (ANALYSIS_FILE, SUMMARY_FILE, FINAL_FILE) if (run_dir / name).is_file()]
        if ((work or any(run_dir.glob(_CHECKPOINT_GLOB))) and read_task(run_dir) is not None
                and not task_matches(run_dir, run) and not _carries_on(run_dir, run)):
            changed.append(run)
    return changed


def _check_folder(out_dir: Path, runs: tuple[RunSpec, ...], overwrite: bool) -> None:
    """Refuse a folder that holds a single run, or runs of another config without ``overwrite``
    (then remove the stale campaign figures)."""
    if (out_dir / CONFIG_FILE).is_file() and any((out_dir / name).is_file() for name in RUN_FILES):
        raise InputError(f"--out {out_dir}: holds a single run (granpack run); a campaign goes into a folder of its own")
    changed = changed_runs(out_dir, runs)
    if changed and not overwrite:
        names = ", ".join(run.folder.as_posix() for run in changed[:4]) + (f" and {len(changed) - 4} more" if len(changed) > 4 else "")
        raise InputError(f"--out {out_dir}: {len(changed)} run(s) there were computed for another config of the same "
                         f"mixture and seed ({names}): --overwrite recomputes them with this campaign file, or choose "
                         "another --out folder")
    if changed and (out_dir / "figures").is_dir():
        shutil.rmtree(out_dir / "figures")


def run_campaign(
    spec: CampaignSpec,
    out_dir: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    mixtures: list[str] | None = None,
    overwrite: bool = False,
) -> CampaignReport:
    """Run every unfinished (mixture, replica) of ``spec`` and write the result tables.

    Args:
        spec: the validated campaign.
        out_dir: the output folder (created); with ``scheduler``, it must be visible to the
            workers under the same path.
        scheduler: address of an existing Dask scheduler (``tcp://host:8786``); ``None`` starts
            a local cluster.
        workers: processes of the local cluster (default: CPU count, at most one per task).
        progress: show a progress bar and one line per finished run.
        mixtures: run only the mixtures whose names match one of these shell patterns
            (``"spheres-*"``), e.g. to share a campaign between machines that have no Dask
            cluster in common, each with its own patterns and the same output folder (copied
            together afterwards); ``None``: every mixture. The tables always list every run.
        overwrite: recompute the runs whose folders hold the work of another config of the same
            (mixture, seed) (the campaign file was edited), and remove the campaign's figures,
            drawn from the runs replaced; without it such a campaign is refused.

    Returns:
        The report with both tables. The tables are written even when interrupted.

    Raises:
        InputError: bad ``workers``/``scheduler`` combination, a pattern that matches no
            mixture, an unreachable scheduler, an ``out_dir`` that is a file or cannot be
            created, holds a single run, or holds runs of another config and ``overwrite`` is
            not given.
        KeyboardInterrupt: Ctrl-C; the tables are written, the runs' checkpoints are kept, and a
            new call goes on from them.
    """
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be >= 1 (got {workers})")
    if workers is not None and scheduler is not None:
        raise InputError("--workers applies to the local cluster only; leave it out with --scheduler")
    selected = selected_runs(spec, mixtures)
    out_dir = Path(out_dir).resolve()
    _check_folder(out_dir, selected, overwrite)
    output_folder(out_dir)
    if spec.source_text:
        (out_dir / CAMPAIGN_SPEC_FILE).write_text(spec.source_text, encoding="utf-8")
    todo = [run for run in selected if not is_finished(out_dir, run)]
    n_skipped = len(selected) - len(todo)
    errors: dict[Path, str] = {}
    done = failed = 0
    try:
        if todo:
            with _client(scheduler, workers, len(todo)) as client:
                done, failed = _execute(client, todo, out_dir, progress, errors)
    finally:
        table = runs_table(out_dir, spec.runs, errors)
        summary = write_tables(out_dir, table)
    asked = table["path"].isin([run.folder.as_posix() for run in selected])
    at_rest = table["run.status"] == "equilibrium" if "run.status" in table else pd.Series(False, index=table.index)
    return CampaignReport(
        n_runs=len(selected),
        n_skipped=n_skipped,
        n_done=n_skipped + done,
        n_failed=failed,
        n_at_rest=int((asked & at_rest & (table["status"] == "done")).sum()),
        runs=table,
        summary=summary,
    )

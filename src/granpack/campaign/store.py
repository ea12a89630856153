"""Campaign results on disk: run-folder state, the runs table and the per-mixture summary.

Every run folder ``<out>/<mixture>/seed-<s>/`` holds, besides the run's own files
(``config.toml``, ``final.gsd``, ``summary.json``, checkpoints, ``analysis.json``):

- ``task.json``: the campaign task (mixture, family, share, seed, and the run config's keys as the
  campaign file gives them) it was started for;
- ``error.txt``: the traceback of its last failure (removed when it succeeds).

A run is **finished** when ``analysis.json`` is valid (a JSON object with every key of
:data:`ANALYSIS_KEYS` and the run's seed) and ``task.json`` records the same run config; a finished
run is never recomputed. The tables are always rebuilt from the folders, so they describe what
is on disk:

- ``runs.csv`` / ``runs.parquet``: one row per run: ``path, mixture, family, share, shapes,
  replica, seed, status, error``, the substituted grains in words (``substituted``), the curve of
  the first graded population and its exponent or polydispersity (``grading``,
  ``grading_parameter``; empty and NaN without one), then every scalar of ``analysis.json`` flattened with dots
  (``solid_fraction.bulk``, ``coordination.N``, ``order.Q00``, ...; lists such as profiles are
  left out) and every scalar of ``summary.json`` prefixed ``run.``. ``status`` is ``done``,
  ``failed`` (see ``error``) or ``missing`` (not run yet, or interrupted).
- ``summary.csv``: one row per mixture: ``mixture, family, share, grading, grading_parameter,
  shapes, n_done, n_failed``, then
  ``<column>.mean`` and ``<column>.std`` (sample standard deviation over the replicas, NaN with
  one replica) of every numeric column over the ``done`` runs.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Iterable

import pandas as pd
from pandas.api.types import is_numeric_dtype

from granpack.campaign.spec import RunSpec
from granpack.io.atomic import atomic_path, write_text_atomic
from granpack.io.run_folder import ANALYSIS_FILE, RUNS_PARQUET, RUNS_TABLE, SUMMARY_FILE, SUMMARY_TABLE

__all__ = [
    "ANALYSIS_KEYS",
    "read_analysis",
    "read_task",
    "write_task",
    "task_matches",
    "write_error",
    "clear_error",
    "is_finished",
    "flatten",
    "run_row",
    "runs_table",
    "summary_table",
    "write_tables",
]

TASK_FILE = "task.json"
ERROR_FILE = "error.txt"

#: top-level keys every analysis.json has (a contract: docs/reference/outputs.md#analysisjson)
ANALYSIS_KEYS = (
    "solid_fraction",
    "coordination",
    "order",
    "pair_correlation",
    "equilibrium",
    "interpenetration",
    "homogeneity",
    "n_particles",
    "populations",
    "seed",
    "version",
)

_ID_COLUMNS = ("path", "mixture", "family", "share", "shapes", "replica", "seed", "status", "error")
_NOT_AVERAGED = ("share", "grading_parameter", "replica", "seed")


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def read_analysis(run_dir: Path, seed: int | None = None) -> dict | None:
    """The run's ``analysis.json`` if it is valid, else ``None``.

    Args:
        run_dir: the run folder.
        seed: when given, the analysis must report this seed.
    """
    data = _read_json(Path(run_dir) / ANALYSIS_FILE)
    if not isinstance(data, dict) or any(key not in data for key in ANALYSIS_KEYS):
        return None
    if seed is not None and data.get("seed") != seed:
        return None
    return data


def read_task(run_dir: Path) -> dict | None:
    """The run folder's ``task.json``, or ``None`` when absent or unreadable."""
    data = _read_json(Path(run_dir) / TASK_FILE)
    return data if isinstance(data, dict) else None


def _task_record(run: RunSpec) -> dict:
    return {
        "mixture": run.mixture,
        "family": run.family,
        "share": run.share,
        "replica": run.replica,
        "seed": run.seed,
        "config": run.settings,
    }


def write_task(run_dir: Path, run: RunSpec) -> None:
    """Record in ``run_dir/task.json`` the task the folder is being computed for."""
    write_text_atomic(Path(run_dir) / TASK_FILE, json.dumps(_task_record(run), indent=2, sort_keys=True))


def task_matches(run_dir: Path, run: RunSpec) -> bool:
    """Whether ``run_dir/task.json`` records this run's config: the same keys (JSON round trip), or
    keys that validate to the same config (a default written out, the flat ``[solver]`` layout of
    granpack 0.1.0)."""
    from granpack.config import load_config_dict
    from granpack.errors import InputError

    task = read_task(run_dir)
    if task is None:
        return False
    if task.get("config") == json.loads(json.dumps(run.settings)):
        return True
    try:
        return load_config_dict(task.get("config")) == run.config
    except InputError:
        return False


def write_error(run_dir: Path, message: str) -> None:
    """Save a failure message (traceback) as ``run_dir/error.txt``."""
    write_text_atomic(Path(run_dir) / ERROR_FILE, message)


def clear_error(run_dir: Path) -> None:
    """Remove ``run_dir/error.txt`` if present."""
    (Path(run_dir) / ERROR_FILE).unlink(missing_ok=True)


def is_finished(out_dir: Path, run: RunSpec) -> bool:
    """Whether ``run`` is complete in ``out_dir``: valid analysis, for the same run config."""
    run_dir = Path(out_dir) / run.folder
    return read_analysis(run_dir, run.seed) is not None and task_matches(run_dir, run)


def _scalar(value: Any) -> Any:
    if value is None:
        return math.nan
    if isinstance(value, (bool, str, int, float)):
        return value
    return None


def flatten(mapping: dict, prefix: str = "") -> dict[str, Any]:
    """Scalars of a nested mapping with dotted keys (lists and arrays are left out).

    ``None`` becomes NaN so that a missing figure stays a numeric column.

    Args:
        mapping: e.g. a parsed ``analysis.json``.
        prefix: prepended to every key.

    Returns:
        ``{"solid_fraction.bulk": 0.64, "coordination.N": 5.9, ...}``.
    """
    out: dict[str, Any] = {}
    for key, value in mapping.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, prefix=f"{name}."))
        else:
            scalar = _scalar(value)
            if scalar is not None:
                out[name] = scalar
    return out


def substituted(run: RunSpec) -> str:
    """The grains a mixture's ``share`` counts, in words: the population whose volume fraction is
    the share (``"pinacoid, size 0.333 d"``, ``"pinacoid 2 x 1"``; a graded population's size reads
    1 d), or ``""`` when none is."""
    if run.share is None:
        return ""
    for population in run.config.populations:
        if abs(population.volume_fraction - run.share) < 1e-6 and run.share > 0:
            words = population.shape
            aspect = population.aspect
            if aspect is not None and tuple(aspect) != (1.0, 1.0):
                words += f" {aspect[0]:g} x {aspect[1]:g}"
            size = 1.0 if population.size is None else population.size
            return f"{words}, size {size:.3g} d"
    return ""


def grading_of(run: RunSpec) -> tuple[str, float]:
    """The curve of the run's first graded population and its parameter, the Fuller exponent or
    the lognormal's polydispersity (``("", nan)`` when no population is graded; NaN for a sieve
    table, which no single number describes)."""
    for population in run.config.populations:
        grading = population.grading
        if grading is not None:  # a validated grading sets the one parameter of its curve, if any
            parameter = next((value for value in (grading.exponent, grading.polydispersity) if value is not None), None)
            return grading.curve, math.nan if parameter is None else float(parameter)
    return "", math.nan


def run_row(out_dir: Path, run: RunSpec, error: str | None = None) -> dict[str, Any]:
    """The runs-table row of one run, read from its folder.

    Args:
        out_dir: the campaign output folder.
        run: the task.
        error: a failure message to report when the folder holds none (e.g. it could not be
            written).

    Returns:
        The row (identification columns, then the flattened figures when finished).
    """
    run_dir = Path(out_dir) / run.folder
    row: dict[str, Any] = {
        "path": run.folder.as_posix(),
        "mixture": run.mixture,
        "family": run.family,
        "share": math.nan if run.share is None else run.share,
        "substituted": substituted(run),
        "grading": grading_of(run)[0],
        "grading_parameter": grading_of(run)[1],
        "shapes": run.shapes,
        "replica": run.replica,
        "seed": run.seed,
    }
    if is_finished(out_dir, run):
        row.update(status="done", error=None)
        figures = flatten(read_analysis(run_dir) or {})
        summary = _read_json(run_dir / SUMMARY_FILE)
        if isinstance(summary, dict):
            figures.update(flatten(summary, prefix="run."))
        row.update({k: v for k, v in figures.items() if k not in row})
        return row
    saved = (run_dir / ERROR_FILE).read_text(encoding="utf-8") if (run_dir / ERROR_FILE).is_file() else None
    message = saved or error
    if message:
        lines = [line for line in message.strip().splitlines() if line.strip()]
        row.update(status="failed", error=lines[-1] if lines else "failed")
    else:
        row.update(status="missing", error=None)
    return row


def runs_table(out_dir: Path, runs: Iterable[RunSpec], errors: dict[Path, str] | None = None) -> pd.DataFrame:
    """The runs table (see module docstring) built from the run folders.

    Args:
        out_dir: the campaign output folder.
        runs: the campaign's tasks.
        errors: failure messages by run folder (relative), used when a folder holds none.
    """
    errors = errors or {}
    rows = [run_row(out_dir, run, errors.get(run.folder)) for run in runs]
    table = pd.DataFrame(rows)
    ordered = [c for c in _ID_COLUMNS if c in table.columns]
    return table[ordered + [c for c in table.columns if c not in ordered]]


def summary_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean and standard deviation per mixture of every numeric column of the done runs.

    Args:
        runs: a runs table.

    Returns:
        One row per mixture (first-appearance order): ``mixture, family, share, shapes, n_done,
        n_failed, <col>.mean, <col>.std, ...``.
    """
    rows = []
    for mixture, group in runs.groupby("mixture", sort=False):
        done = group[group["status"] == "done"]
        row: dict[str, Any] = {
            "mixture": mixture,
            "family": group["family"].iloc[0],
            "share": group["share"].iloc[0],
            "grading": group["grading"].iloc[0] if "grading" in group else "",
            "grading_parameter": group["grading_parameter"].iloc[0] if "grading_parameter" in group else math.nan,
            "shapes": group["shapes"].iloc[0],
            "n_done": len(done),
            "n_failed": int((group["status"] == "failed").sum()),
        }
        for column in runs.columns:
            if column in _ID_COLUMNS or column in _NOT_AVERAGED or not is_numeric_dtype(runs[column]):
                continue
            values = done[column].astype(float)
            row[f"{column}.mean"] = values.mean()
            row[f"{column}.std"] = values.std(ddof=1)
        rows.append(row)
    return pd.DataFrame(rows)


def write_tables(out_dir: Path, runs: pd.DataFrame) -> pd.DataFrame:
    """Write ``runs.csv``, ``runs.parquet`` and ``summary.csv`` into ``out_dir`` (atomic renames).

    Args:
        out_dir: the campaign output folder.
        runs: the runs table.

    Returns:
        The summary table.
    """
    out_dir = Path(out_dir)
    summary = summary_table(runs)
    for name, write in (
        (RUNS_TABLE, lambda p: runs.to_csv(p, index=False)),
        (RUNS_PARQUET, lambda p: runs.to_parquet(p, index=False)),
        (SUMMARY_TABLE, lambda p: summary.to_csv(p, index=False)),
    ):
        with atomic_path(out_dir / name) as tmp:
            write(tmp)
    return summary

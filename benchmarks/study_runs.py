"""The study campaign's finished runs, kept in the repository so the campaign can span machines.

`examples/study.toml` is some 80 to 90 CPU hours of pinacoid runs: more than one machine or one
session gives. A finished run is defined by small files (``granpack.campaign.store``: a valid
``analysis.json`` and the ``task.json`` of the same run config); with ``summary.json`` and
``timeline.csv`` beside them they hold every figure the campaign's tables and ``granpack
figures`` read. A run still in progress is defined by its ``checkpoint.gsd`` (the exact state,
warm contacts and timeline, some MB) and its ``task.json``: kept too, a run that a session's end
interrupts goes on in the next session instead of starting afresh. This script copies those files
(not ``final.gsd``) between a campaign folder and ``benchmarks/study/``:

- ``save OUT``: the finished runs of campaign folder ``OUT`` into ``benchmarks/study/``, and the
  checkpoints of its unfinished runs (a kept checkpoint of a run that has since finished is removed);
- ``restore OUT``: the kept runs into ``OUT``, where ``granpack campaign examples/study.toml
  --out OUT`` then skips the finished ones, resumes the checkpointed ones and runs the others
  (a checkpoint is restored only into a run folder that holds neither a checkpoint nor a result);
- ``table OUT``: a markdown table, one row per run of ``OUT`` that has an ``analysis.json``
  (bulk solid fraction, N, Ns / Nd / Nt, Nc, rattlers, Q00 with its isotropic baseline, k,
  status and time to rest, CPU minutes);
- ``mixtures OUT``: a markdown table, one row per mixture: runs at rest of runs analysed, bulk
  solid fraction (mean ± sample standard deviation over every analysed run: a run stopped at the
  time cap is dense already, its solid fraction moves by less than the seeds' spread), and N, Nc,
  rattlers, Q00 and Q22 averaged over the runs **at rest** only (a pile still moving has contacts
  that open and close: its coordination is not that of a packing in equilibrium); a mixture
  none of whose runs came to rest has them over all its runs, marked ``(cap)``.

Usage::

    python benchmarks/study_runs.py restore /work/study
    granpack campaign examples/study.toml --out /work/study --workers 2 --mixture 'pinacoids-*'
    python benchmarks/study_runs.py save /work/study
    python benchmarks/study_runs.py table /work/study
    python benchmarks/study_runs.py mixtures /work/study
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
from pathlib import Path

KEPT = Path(__file__).resolve().parent / "study"
#: the files of a finished run that are kept (final.gsd, some MB, is not)
FILES = ("task.json", "summary.json", "analysis.json", "timeline.csv")
#: the files of an unfinished run that are kept: enough for the campaign to resume it
CHECKPOINT_FILES = ("task.json", "config.toml", "checkpoint.gsd", "progress.log")


def _run_folders(root: Path) -> list[Path]:
    """Run folders ``root/<mixture>/seed-<s>`` holding an ``analysis.json``, sorted."""
    return sorted(p.parent for p in root.glob("*/seed-*/analysis.json"))


def _copy_files(runs: list[Path], source: Path, target: Path, names: tuple[str, ...]) -> int:
    """Copy the files ``names`` (those present) of each run folder of ``source`` in ``runs`` to the
    same place under ``target``; returns the number of runs copied."""
    for run in runs:
        dest = target / run.relative_to(source)
        dest.mkdir(parents=True, exist_ok=True)
        for name in names:
            if (run / name).is_file():
                shutil.copy2(run / name, dest / name)
    return len(runs)


def _copy_runs(source: Path, target: Path) -> int:
    return _copy_files(_run_folders(source), source, target, FILES)


def _checkpointed_folders(root: Path) -> list[Path]:
    """Run folders ``root/<mixture>/seed-<s>`` holding a checkpoint and no ``analysis.json``, sorted."""
    return sorted(p.parent for p in root.glob("*/seed-*/checkpoint.gsd") if not (p.parent / "analysis.json").is_file())


def _copy_checkpoints(source: Path, target: Path, *, replace: bool) -> int:
    """Copy the unfinished runs of ``source`` into ``target``; with ``replace`` False, only into run
    folders of ``target`` that hold neither a checkpoint nor an ``analysis.json``."""
    runs = [run for run in _checkpointed_folders(source)
            if replace or not any((target / run.relative_to(source) / name).is_file()
                                  for name in ("checkpoint.gsd", "analysis.json"))]
    return _copy_files(runs, source, target, CHECKPOINT_FILES)


def _drop_stale_checkpoints(root: Path) -> int:
    """Remove the kept checkpoint files of runs that ``root`` now holds finished."""
    dropped = 0
    for checkpoint in root.glob("*/seed-*/checkpoint.gsd"):
        if (checkpoint.parent / "analysis.json").is_file():
            for name in set(CHECKPOINT_FILES) - set(FILES):  # task.json stays: the finished run's own
                (checkpoint.parent / name).unlink(missing_ok=True)
            dropped += 1
    return dropped


def _f(value, fmt: str) -> str:
    """``value`` formatted, or ``–`` where the analysis left it undefined (None or NaN)."""
    return "–" if value is None or value != value else format(value, fmt)


def _row(run: Path) -> str:
    a = json.loads((run / "analysis.json").read_text())
    s = json.loads((run / "summary.json").read_text()) if (run / "summary.json").is_file() else {}
    phi, c, o = a["solid_fraction"], a["coordination"], a["order"]
    base = o.get("isotropic_baseline") or {}
    q00 = f"{_f(o.get('Q00'), '.3f')} ({_f(base.get('Q00'), '.3f')} ± {_f(base.get('Q00_std'), '.3f')})"
    at = f", t = {s['simulated_time']:.2f}" if s else ""
    cpu = _f(s["cpu_time"] / 60, ".0f") if s.get("cpu_time") else ""
    return (f"| {run.parent.name} | {run.name.removeprefix('seed-')} | {a['n_particles']} | {s.get('status', '?')}{at} | "
            f"{_f(phi['bulk'], '.4f')} ± {_f(phi['std'], '.4f')} | {_f(c['N'], '.2f')} | "
            f"{_f(c['Ns'], '.2f')} / {_f(c['Nd'], '.2f')} / {_f(c['Nt'], '.2f')} | {_f(c['Nc'], '.2f')} | "
            f"{_f(c['rattler_fraction'], '.1%')} | {q00} | {_f(a['interpenetration'].get('expansion_k'), '.1e')} | {cpu} |")


def table(root: Path) -> str:
    lines = ["| mixture | seed | grains | status | bulk phi | N | Ns / Nd / Nt | Nc | rattlers | Q00 (isotropic) | k | CPU min |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    lines += [_row(run) for run in _run_folders(root)]
    return "\n".join(lines)


def _mean(values: list[float]) -> float:
    """Mean of the defined ``values`` (NaN where none is)."""
    kept = [v for v in values if v is not None and v == v]
    return statistics.fmean(kept) if kept else float("nan")


#: the per-mixture columns averaged over the runs at rest: (section, key, format)
_AT_REST_COLUMNS = (("coordination", "N", ".2f"), ("coordination", "Nc", ".2f"),
                    ("coordination", "rattler_fraction", ".1%"), ("order", "Q00", ".3f"), ("order", "Q22", ".3f"))


def mixtures(root: Path) -> str:
    lines = ["| mixture | at rest / runs | bulk phi | N | Nc | rattlers | Q00 | Q22 |",
             "|---|---|---|---|---|---|---|---|"]
    by_mixture: dict[str, list[dict]] = {}
    for run in _run_folders(root):
        by_mixture.setdefault(run.parent.name, []).append(json.loads((run / "analysis.json").read_text()))
    for name, runs in by_mixture.items():
        phi = [a["solid_fraction"]["bulk"] for a in runs]
        std = statistics.stdev(phi) if len(phi) > 1 else float("nan")
        rest = [a for a in runs if a.get("status") == "equilibrium"]
        mark = "" if rest else " (cap)"
        cells = [f"{_f(_mean([a[section][key] for a in rest or runs]), fmt)}{mark}" for section, key, fmt in _AT_REST_COLUMNS]
        lines.append(f"| {name} | {len(rest)} / {len(runs)} | {_f(_mean(phi), '.4f')} ± {_f(std, '.4f')} | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=("save", "restore", "table", "mixtures"))
    parser.add_argument("campaign", type=Path, help="the campaign output folder")
    parser.add_argument("--kept", type=Path, default=KEPT,
                        help=f"the folder of kept runs in the repository (default {KEPT.relative_to(KEPT.parents[1])})")
    args = parser.parse_args(argv)
    kept = args.kept
    if args.action == "save":
        finished = _copy_runs(args.campaign, kept)
        dropped = _drop_stale_checkpoints(kept)
        checkpoints = _copy_checkpoints(args.campaign, kept, replace=True)
        print(f"kept {finished} finished runs and {checkpoints} checkpoints of unfinished runs in {kept} "
              f"({dropped} checkpoints of runs now finished removed)", file=sys.stderr)
    elif args.action == "restore":
        finished = _copy_runs(kept, args.campaign)
        checkpoints = _copy_checkpoints(kept, args.campaign, replace=False)
        print(f"restored {finished} finished runs and {checkpoints} checkpoints of unfinished runs into "
              f"{args.campaign}", file=sys.stderr)
    elif args.action == "table":
        print(table(args.campaign))
    else:
        print(mixtures(args.campaign))
    return 0


if __name__ == "__main__":
    sys.exit(main())

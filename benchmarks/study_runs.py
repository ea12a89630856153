"""The study campaign's finished runs, kept in the repository so the campaign can span machines.

`examples/study.toml` is some 80 to 90 CPU hours of pinacoid runs: more than one machine gives in
one go. A finished run is defined by small files (``granpack.campaign.store``: a valid
``analysis.json`` and the ``task.json`` of the same run config); with ``summary.json`` and
``timeline.csv`` beside them they hold every figure the campaign's tables and ``granpack
figures`` read. A run still in progress is defined by its ``checkpoint.gsd`` (the exact state,
warm contacts and timeline, some MB) and its ``task.json``: kept too, an interrupted run goes on
at the next call of the campaign instead of starting afresh. This script copies those files (not
``final.gsd``) between a campaign folder and ``benchmarks/study/``, and builds the tables and the
documentation page of the results from them:

- ``save OUT``: the finished runs of campaign folder ``OUT`` into ``benchmarks/study/``, and the
  checkpoints of its unfinished runs (a kept checkpoint of a run that has since finished is removed);
  ``--final`` copies the finished runs' ``final.gsd`` too (a packing to analyse again, which
  ``.gitignore`` keeps out of commits: ``benchmarks/final_states.py``), ``--kept``
  another folder of kept runs (``benchmarks/validation/runs/...``);
- ``restore OUT``: the kept runs into ``OUT``, where ``granpack campaign examples/study.toml
  --out OUT`` then skips the finished ones, resumes the checkpointed ones and runs the others
  (a checkpoint is restored only into a run folder that holds neither a checkpoint nor a result);
- ``table OUT``: a markdown table, one row per run of ``OUT`` that has an ``analysis.json``
  (bulk solid fraction, N, Ns / Nd / Nt, Nc, rattlers, Q00 with its isotropic baseline, k,
  status and time to rest, CPU minutes);
- ``mixtures OUT``: a markdown table, one row per mixture: runs at rest of runs analysed, bulk
  solid fraction (mean ± sample standard deviation over every analysed run: a run stopped at the
  time cap is dense already, its solid fraction moves by less than the seeds' spread), and N, Nc,
  rattlers, Q00 and Q22 averaged over the runs **at rest** only, and the Q00 of the deposit before gravity over every run (a pile still moving has contacts
  that open and close: its coordination is not that of a packing in equilibrium); a mixture
  none of whose runs came to rest has them over all its runs, marked ``(cap)``;
- ``page [KEPT]``: the documentation page ``docs/study.md`` ("The study campaign: results") from
  the kept runs (default ``benchmarks/study/``): the campaign and its protocol, the mixtures'
  cells and grains (from each run's ``task.json``), the runs' outcome and cost (``summary.json``),
  the two tables above and the campaign's figures, copied from ``benchmarks/study/figures/`` to
  ``docs/study/figures/`` (mkdocs serves only what is under ``docs/``). The page is generated,
  never edited by hand, and the same kept runs give the same bytes
  (``tests/test_benchmarks_tables.py`` checks that the committed page is up to date);
- ``initial-order OUT``: the order of the deposit before gravity (Q00, Q22) written into the
  ``summary.json`` of each finished run that lacks it (made by a version that did not record it),
  the deposit made again from the run's config and seed.

Usage::

    python benchmarks/study_runs.py restore /work/study
    granpack campaign examples/study.toml --out /work/study --workers 2 --mixture 'pinacoids-*'
    python benchmarks/study_runs.py save /work/study
    python benchmarks/study_runs.py table /work/study
    python benchmarks/study_runs.py mixtures /work/study
    python benchmarks/study_runs.py page
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
KEPT = ROOT / "benchmarks" / "study"
#: the documentation page of the study's results and the folder of its figures (generated)
PAGE = ROOT / "docs" / "study.md"
PAGE_FIGURES = ROOT / "docs" / "study" / "figures"
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
    lines = ["| mixture | at rest / runs | bulk phi | N | Nc | rattlers | Q00 | Q22 | Q00 of the deposit |",
             "|---|---|---|---|---|---|---|---|---|"]
    by_mixture: dict[str, list[dict]] = {}
    deposit: dict[str, list] = {}
    for run in _run_folders(root):
        by_mixture.setdefault(run.parent.name, []).append(json.loads((run / "analysis.json").read_text()))
        summary = json.loads((run / "summary.json").read_text()) if (run / "summary.json").is_file() else {}
        deposit.setdefault(run.parent.name, []).append((summary.get("initial_order") or {}).get("Q00"))
    for name, runs in by_mixture.items():
        phi = [a["solid_fraction"]["bulk"] for a in runs]
        std = statistics.stdev(phi) if len(phi) > 1 else float("nan")
        rest = [a for a in runs if a.get("status") == "equilibrium"]
        mark = "" if rest else " (cap)"
        cells = [f"{_f(_mean([a[section][key] for a in rest or runs]), fmt)}{mark}" for section, key, fmt in _AT_REST_COLUMNS]
        lines.append(f"| {name} | {len(rest)} / {len(runs)} | {_f(_mean(phi), '.4f')} ± {_f(std, '.4f')} | "
                     + " | ".join(cells) + f" | {_f(_mean(deposit[name]), '.3f')} |")
    return "\n".join(lines)


def sphere_coordination(root: Path) -> str:
    """The page's sentence on the N of the sphere mixtures: the backbone's above 6, and why."""
    by_mixture: dict[str, list[dict]] = {}
    for run in _run_folders(root):
        if run.parent.name.startswith("spheres"):
            by_mixture.setdefault(run.parent.name, []).append(json.loads((run / "analysis.json").read_text()))
    if not by_mixture:
        return ""
    rows = {}
    for name, runs in by_mixture.items():
        rest = [a for a in runs if a.get("status") == "equilibrium"] or runs
        rows[name] = (_mean([a["coordination"]["N"] for a in rest]),
                      _mean([a["coordination"]["with_rattlers"]["N"] for a in rest]),
                      _mean([a["coordination"]["rattler_fraction"] for a in rest]))
    top = max(rows, key=lambda m: rows[m][0])
    backbone, every, rattlers = rows[top]
    low, high = min(r[1] for r in rows.values()), max(r[1] for r in rows.values())
    return (f"The spheres' N is that of the backbone, the rattlers removed, and reads above the isostatic 6 "
            f"(up to {backbone:.2f} for {top}, against {every:.2f} over all its bulk grains, {rattlers:.0%} of them "
            f"rattlers) by the rattler rule under gravity: the rule counts a sphere with fewer than 4 "
            f"force-bearing contacts a rattler, what a frictionless sphere needs to be held without gravity, "
            f"while under gravity a sphere rests on 3, so it removes grains that carry their weight, and their "
            f"contacts with the backbone. Over all bulk grains N is {low:.2f} to {high:.2f} "
            f"([Method > Analysis](method/analysis.md#coordination-numbers); the contacts of the removed grains "
            f"counted on kept piles: [Gradings](gradings.md#the-example-campaign-fuller-curves)).")


#: the families of the study in the order the page lists them (others follow, sorted)
_FAMILIES = ("spheres", "pinacoids", "elongated", "flat", "flat-elongated")
#: the campaign figures of the page: (file stem, caption)
PAGE_FIGURES_CAPTIONS = (
    ("solid_fraction", "Bulk solid fraction against the share of the substituted grains, one curve per family "
     "(error bars: standard deviation over the seeds). Left, the size mixtures (spheres, isometric pinacoids, "
     "large d and small d/3); right, the shape mixtures, which start from the monodisperse isometric pinacoids "
     "(share 0)."),
    ("order", "Nematic order $Q^2_{00}$ of the bulk against the share, with the same panels (the pinacoid "
     "families only: a sphere has no orientation) "
     "([Method > Analysis](method/analysis.md#orientational-order))."),
    ("coordination", "Coordination numbers of the bulk against the share, one panel per family: all contacts "
     "(N), simple (Ns), double (Nd) and triple (Nt) ones "
     "([Method > Analysis](method/analysis.md#coordination-numbers))."),
    ("coordination_vs_order", "Coordination number N against the nematic order $Q^2_{00}$, one point per "
     "pinacoid packing, with the exponential fit and its parameters "
     "([Method > Analysis](method/analysis.md#n-versus-q00-fit))."),
    ("pair_correlation", "Pair correlation g(r) of the grains' centres in the bulk, mean over the seeds, one "
     "panel per family ([Method > Analysis](method/analysis.md#pair-correlation))."),
    ("homogeneity", "Volume proportion of the substituted grains in each layer against height (dotted: the "
     "nominal share), one panel per family: a check that the mixtures did not segregate "
     "([Method > Analysis](method/analysis.md#homogeneity))."),
)


def _display(path: Path) -> str:
    """``path`` relative to the repository where it lies in it (the page names no machine's folders)."""
    try:
        return path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return path.name


def _size(size: float) -> str:
    """A grain size in d: ``d``, ``d/3``, ..."""
    if abs(size - 1.0) < 1e-6:
        return "d"
    inverse = 1.0 / size
    return f"d/{round(inverse)}" if abs(inverse - round(inverse)) < 1e-6 else f"{size:g} d"


def _grain(population: dict) -> str:
    """A population's grains in words: shape, size and, for a pinacoid, its aspect (L/G, G/E)."""
    if population["shape"] == "pinacoid":
        aspect = population.get("aspect") or (1.0, 1.0)
        return f"pinacoids {_size(population['size'])}, (L/G, G/E) = ({aspect[0]:g}, {aspect[1]:g})"
    return f"{population['shape']}s {_size(population['size'])}"


def _tasks(root: Path) -> dict[str, dict]:
    """The ``task.json`` of each analysed mixture's first run folder, by mixture name."""
    tasks: dict[str, dict] = {}
    for run in _run_folders(root):
        if run.parent.name not in tasks and (run / "task.json").is_file():
            tasks[run.parent.name] = json.loads((run / "task.json").read_text())
    return tasks


def _family_order(family: str) -> tuple[int, str]:
    return (_FAMILIES.index(family) if family in _FAMILIES else len(_FAMILIES), family)


def families(root: Path) -> str:
    """A markdown table, one row per family of the kept runs' mixtures: the substituted grains, and
    for each share its cell's lateral size and, where not the most common, its number of grains."""
    by_family: dict[str, list[dict]] = {}
    for task in _tasks(root).values():
        by_family.setdefault(task["family"], []).append(task)
    lines = ["| family | substituted grains | share % (cell lateral size, d) | grains |", "|---|---|---|---|"]
    for family in sorted(by_family, key=_family_order):
        tasks = sorted(by_family[family], key=lambda t: t["share"])
        # the substituted grains: the only population at share 1, else the last of a mixture of two
        full = [t for t in tasks if len(t["config"]["populations"]) == 1 and t["share"] > 0]
        mixed = [t for t in tasks if len(t["config"]["populations"]) > 1]
        grain = (_grain(full[0]["config"]["populations"][0]) if full
                 else _grain(mixed[0]["config"]["populations"][-1]) if mixed else "–")
        shares = ", ".join(f"{t['share'] * 100:g} ({t['config']['lateral_size']:g})" for t in tasks)
        counts = [t["config"]["n_particles"] for t in tasks]
        common = max(sorted(set(counts)), key=counts.count)
        others = [f"{t['config']['n_particles']} at {t['share'] * 100:g} %" for t in tasks
                  if t["config"]["n_particles"] != common]
        lines.append(f"| {family} | {grain} | {shares} | {common}" + (f" ({', '.join(others)})" if others else "") + " |")
    return "\n".join(lines)


def _minutes(values: list[float]) -> str:
    return (f"{min(values) / 60:.0f} to {max(values) / 60:.0f} CPU minutes (mean {statistics.fmean(values) / 60:.0f})"
            if values else "–")


def outcome(root: Path) -> str:
    """One paragraph: how many runs were analysed, came to rest or stopped at the time cap, and what
    they cost (``cpu_time`` of their ``summary.json``), for the sphere and the pinacoid runs."""
    runs = _run_folders(root)
    status = [json.loads((run / "analysis.json").read_text()).get("status") for run in runs]
    summaries = [json.loads((run / "summary.json").read_text()) if (run / "summary.json").is_file() else {}
                 for run in runs]
    tasks = [json.loads((run / "task.json").read_text()) if (run / "task.json").is_file() else {} for run in runs]
    cpu = [s.get("cpu_time") for s in summaries]
    spheres = [c for c, t in zip(cpu, tasks) if c and all(p["shape"] == "sphere" for p in t["config"]["populations"])]
    others = [c for c, t in zip(cpu, tasks) if c and not all(p["shape"] == "sphere" for p in t["config"]["populations"])]
    at_rest = status.count("equilibrium")
    return (f"{len(runs)} runs analysed ({len({run.parent.name for run in runs})} mixtures): {at_rest} certified at "
            f"rest, {len(runs) - at_rest} stopped at the time cap. They took {sum(c for c in cpu if c) / 3600:.1f} CPU "
            f"hours in all: a pinacoid run {_minutes(others)}, set by when the pile stops "
            f"rearranging rather than by the cost of a step; a sphere run {_minutes(spheres)}.")


def page(root: Path, out: Path, figures_out: Path, figures_in: Path | None = None) -> Path:
    """Write the documentation page of the kept runs of ``root`` to ``out`` and copy the PNG campaign
    figures of ``figures_in`` (default ``root/figures``) to ``figures_out``, which the page links to
    relatively. Deterministic: the same kept runs and figures give the same bytes."""
    figures_in = root / "figures" if figures_in is None else figures_in
    figures_out.mkdir(parents=True, exist_ok=True)
    link = Path(os.path.relpath(figures_out.resolve(), out.resolve().parent)).as_posix()
    kept = _display(root)
    figure_blocks = []
    for stem, caption in PAGE_FIGURES_CAPTIONS:
        source = figures_in / f"{stem}.png"
        if not source.is_file():
            continue
        shutil.copyfile(source, figures_out / f"{stem}.png")
        figure_blocks.append(f"### `{stem}`\n\n![{stem}]({link}/{stem}.png)\n\n{caption}\n")
    text = rf"""<!-- Generated by `python benchmarks/study_runs.py page` from {kept}/: do not edit by hand. -->

# The study campaign: results

`examples/study.toml` is the study's campaign: 30 mixtures of grains in five families, three
seeds each (1, 2 and 3), 90 runs. Each family substitutes one kind of grain for part of the solid
volume of large isometric pinacoids (of large spheres, for the spheres family); a mixture is named
after its family and that share in percent, and the 0 % point of the elongated, flat and flat &
elongated series is `pinacoids-small-0` ([Method > The study's settings](method/index.md#the-studys-settings)).
Every run pours 3000 grains (more for the two mixtures richest in small pinacoids, so that their
columns keep a bulk region) into a cell periodic in x and y over a flat bottom wall, frictionless
($\mu = 0$), without restitution ($e = 0$), with a time step of $5 \times 10^{{-3}}\sqrt{{d/g}}$, and
lets it settle until the default [equilibrium criteria](method/equilibrium.md#the-criteria) certify
it at rest or the default time cap, `max_time` = 300 $\sqrt{{d/g}}$, is reached. Each mixture's cell is
set in the campaign file (the study's 8 d, 10 d for the elongated series, made narrower where the
column would otherwise be too short for a bulk region):

{families(root)}

{outcome(root)}

This page is generated from the kept results in `{kept}/` (each run's `task.json`,
`summary.json`, `analysis.json` and `timeline.csv`, and the campaign's figures) by
`python benchmarks/study_runs.py page`; the [tutorial](tutorial.md#4-the-full-study) tells how to
run the campaign or rebuild its tables and figures from those results.

## Per mixture

Runs at rest of runs analysed; bulk solid fraction, mean ± sample standard deviation over every
analysed run (a run stopped at the time cap is dense already: its solid fraction moves by less
than the seeds' spread); the coordination number N, the number of constraints Nc, the rattlers'
share and the order parameters $Q^2_{{00}}$ and $Q^2_{{22}}$ averaged over the runs at rest only (a pile
still moving has contacts that open and close). A mixture none of whose runs came to rest has
them over all its runs, marked (cap).

{mixtures(root)}

{sphere_coordination(root)}

## Per run

Status and simulated time at the end (in $\sqrt{{d/g}}$), bulk solid fraction ± its standard
deviation over the bulk's layers, N and its simple / double / triple contacts Ns / Nd / Nt, Nc,
rattlers, $Q^2_{{00}}$ with the mean ± standard deviation of an isotropic packing of as many grains,
the expansion coefficient k of the interpenetration and the run's CPU time
([Method > Analysis](method/analysis.md)).

{table(root)}

## Figures

Drawn by `granpack figures` over the campaign folder
([Output files > Campaign folder](reference/outputs.md#campaign-folder)).

""" + "\n".join(figure_blocks)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8", newline="\n")
    return out


def initial_order(root: Path) -> int:
    """Write the ``initial_order`` (Q00, Q22 of the deposit before gravity) into the summary.json
    of every finished run of ``root`` that has none (runs of a version that did not record it):
    the deposit is made again from the run's config, seed included, which fixes it bit for bit.
    Returns the number of summaries written."""
    from granpack.config import load_config_dict
    from granpack.io.json import write_json
    from granpack.simulation import deposit_order, initial_state

    written = 0
    for run in _run_folders(root):
        path = run / "summary.json"
        summary = json.loads(path.read_text()) if path.is_file() else None
        if summary is None or "initial_order" in summary:
            continue
        config = load_config_dict(json.loads((run / "task.json").read_text())["config"], source=str(run))
        state, _ = initial_state(config)
        summary["initial_order"] = deposit_order(state)
        write_json(path, summary)
        written += 1
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=("save", "restore", "table", "mixtures", "page", "initial-order"))
    parser.add_argument("campaign", type=Path, nargs="?",
                        help="the campaign output folder (page: the kept runs, default the --kept folder)")
    parser.add_argument("--kept", type=Path, default=KEPT,
                        help=f"the folder of kept runs in the repository (default {KEPT.relative_to(KEPT.parents[1])})")
    parser.add_argument("--final", action="store_true", help="save: keep each finished run's final.gsd too")
    parser.add_argument("--page", type=Path, default=PAGE, help="page: the page to write (default docs/study.md)")
    parser.add_argument("--figures", type=Path, default=PAGE_FIGURES,
                        help="page: the folder its figures are copied to (default docs/study/figures)")
    args = parser.parse_args(argv)
    kept = args.kept
    if args.action == "page":
        written = page(args.campaign or kept, args.page, args.figures)
        print(f"wrote {written} and its figures in {args.figures}", file=sys.stderr)
        return 0
    if args.campaign is None:
        parser.error(f"{args.action}: the campaign output folder is required")
    if args.action == "initial-order":
        print(f"recorded the deposit's order in {initial_order(args.campaign)} summaries", file=sys.stderr)
        return 0
    if args.action == "save":
        finished = _copy_files(_run_folders(args.campaign), args.campaign, kept, FILES + (("final.gsd",) if args.final else ()))
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

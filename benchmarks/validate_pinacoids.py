"""Validation of the study's pinacoid mixtures at the study's size, too slow for CI.

Runs ``granpack.simulation.run_packing`` then ``granpack.analysis.report.analyze_run`` on each
mixture and seed (or, with ``--reuse``, re-analyses the run folders a previous call left), prints
one JSON object per run, then a markdown table: one row per mixture (figures averaged over the
seeds) and one row per run.

Mixtures (``--mixture NAME``, repeatable; default: all, in this order); the populations are read
from the examples, so the study and its example configs cannot drift apart:

- ``isometric``: ``examples/pinacoids-isometric.toml`` (aspect L/G 1, G/E 1);
- ``elongated``: ``examples/pinacoids-elongated.toml`` (2, 1);
- ``flat``: ``examples/pinacoids-flat.toml`` (1, 3);
- ``flat-elongated``: ``examples/pinacoids-flat-elongated.toml`` (2, 3);
- ``bidisperse-30``: ``examples/pinacoids-bidisperse-30.toml`` (isometric, sizes d and d/3, 30 %
  of the solid volume small).

The cell: ``--lateral`` if given (the same for every mixture, nothing adapted), else 8 d for
``--n`` >= 3000, 4 d for ``--n`` >= 1000, 3 d below. A bulk region needs
``n_bottom d + d + n_top d`` (2 d + 1 d + 2 d) of column (docs/method/analysis.md#bulk-region):
when the column expected at a solid fraction of 0.6 (as ``granpack check`` estimates it) is below
``--min-column`` (default 8 d: the free surface of a nearly settled pile of 120 isometric grains
stood at 0.9 of the estimate, so this leaves about 2-3 d of bulk, at least two d-thick layers for
their std), the cell is narrowed (in steps of 0.5 d, not below ``--min-lateral``, 3 d) and, if
that is not enough, the number of grains is raised. Both are said in the JSON (``cell_note``), on
stderr and under the table. Small or flat grains need it: at 3000 grains in an 8 d cell the
expected column is 11 d for isometric grains but 6.3 d (elongated), 4.3 d (flat), 2.3 d (flat &
elongated) and 1.3 d (bidisperse). Each run's ``analysis.json`` says whether it has a bulk
(``bulk.valid``); a run without one is flagged in the table.

Table columns: bulk solid fraction (mean ± std over the seeds; with one seed, ± the std of the
bulk's d-thick layers), the coordination of the backbone N, Ns, Nd, Nt, Nc and the rattler
fraction (contact types from the force-bearing points), Q00 and Q22 with the isotropic baseline
of the same number of grains (mean ± std of uniformly random orientations), the expansion
coefficient k (``interpenetration.expansion_k``), the status (and whether the final state meets
the settling benchmark's first level of rest), the worst equilibrium figures over the seeds
(largest net force / d^2 P, net torque / d^3 P, kinetic criterion / d^3 P, wall force over
weight) and the wall time of a run (``summary.json``'s ``wall_time``: pour and settling).

Run folders: ``OUT/MIXTURE-nN-seedS`` (N the ``--n`` asked for). Seeds ``--first-seed`` ..
``--first-seed + --seeds - 1``.

Usage::

    python benchmarks/validate_pinacoids.py [--n 3000] [--seeds 2] [--mixture flat ...]
        [--out runs/validate-pinacoids] [--max-time 200] [--table table.md] [--reuse]
    python benchmarks/validate_pinacoids.py --n 120 --seeds 1 --max-time 5 --mixture isometric --lateral 2.5

Cost: not measured for this script. The default is ten packings of 3000 grains; the settling
benchmark's five cases (four of 1000 grains, one of 3000; benchmarks/bench_settle.py) take about
two hours on 2 cores. ``--n 1000`` is the fallback where time does not allow.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import statistics
import sys
import time
import tomllib
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: mixture name -> example config whose populations it uses
MIXTURES = {
    "isometric": "pinacoids-isometric.toml",
    "elongated": "pinacoids-elongated.toml",
    "flat": "pinacoids-flat.toml",
    "flat-elongated": "pinacoids-flat-elongated.toml",
    "bidisperse-30": "pinacoids-bidisperse-30.toml",
}

#: solid fraction of the column estimate (as ``granpack check``)
PHI_ESTIMATE = 0.6

#: the settling benchmark's first level of rest (benchmarks/bench_settle.py, LEVEL_ONE)
LEVEL_ONE = {"max_net_force": 1e-3, "max_net_torque": 1e-3, "kinetic_energy": 1e-7, "wall": 5e-3}

COORDINATION_KEYS = ("N", "Ns", "Nd", "Nt", "Nc")


# ----------------------------------------------------------------------------------------------
# mixtures and cells


def load_populations(name: str, examples: Path = EXAMPLES) -> list[dict]:
    """The ``[[populations]]`` tables of the mixture's example config."""
    with (examples / MIXTURES[name]).open("rb") as f:
        return tomllib.load(f)["populations"]


def nominal_lateral(n: int) -> float:
    """The study's cell side for ``n`` grains: 8 d from 3000 grains, 4 d from 1000, else 3 d."""
    return 8.0 if n >= 3000 else 4.0 if n >= 1000 else 3.0


def _config(populations: list[dict], n: int, lateral: float, seed: int = 1, max_time: float | None = None):
    from granpack.config import load_config_dict

    raw = {"seed": seed, "n_particles": n, "lateral_size": lateral, "populations": populations}
    if max_time is not None:
        raw["equilibrium"] = {"max_time": max_time}
    return load_config_dict(raw, source="validate_pinacoids")


def expected_column(populations: list[dict], n: int, lateral: float) -> float:
    """Height of the settled pile at a solid fraction of 0.6, in d (the largest grain size)."""
    from granpack.mixture import Mixture

    config = _config(populations, n, lateral)
    return Mixture.from_config(config).pile_height(lateral ** 2, PHI_ESTIMATE) / config.largest_size


def needed_column() -> float:
    """The column a bulk region needs at the least, n_bottom d + d + n_top d."""
    from granpack.analysis.report import AnalysisOptions

    opt = AnalysisOptions()
    return opt.n_bottom + 1.0 + opt.n_top


def plan_cell(populations: list[dict], n: int, lateral: float, min_column: float, min_lateral: float,
              ) -> tuple[float, int, str | None]:
    """``(lateral, n, note)``: the cell and grain count giving an expected column of ``min_column``.

    The cell is narrowed first (a multiple of 0.5 d, not below ``min_lateral`` nor above
    ``lateral``), then the grain count raised; ``note`` says what changed (None: nothing).
    """
    height = expected_column(populations, n, lateral)
    if height >= min_column:
        return lateral, n, None
    ideal = lateral * math.sqrt(height / min_column)
    new_lateral = min(lateral, max(min_lateral, math.floor(2.0 * ideal) / 2.0))
    new_n = n
    new_height = expected_column(populations, n, new_lateral)
    while new_height < min_column:
        new_n = math.ceil(new_n * min_column / new_height) + 1
        new_height = expected_column(populations, new_n, new_lateral)
    changes = []
    if new_lateral != lateral:
        changes.append(f"cell {lateral:g} d -> {new_lateral:g} d")
    if new_n != n:
        changes.append(f"grains {n} -> {new_n}")
    note = (f"{', '.join(changes)}: expected column {height:.2g} d -> {new_height:.2g} d "
            f"(phi {PHI_ESTIMATE}; at least {min_column:g} d asked, {needed_column():g} d needed for a bulk)")
    return new_lateral, new_n, note


# ----------------------------------------------------------------------------------------------
# one run


def _finite(value) -> float | None:
    if value is None or isinstance(value, bool):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _baseline(order: dict) -> tuple[dict, str]:
    """The isotropic baseline of ``order`` and where it comes from (``analysis.json`` or recomputed)."""
    base = order.get("isotropic_baseline")
    if isinstance(base, dict) and base.get("Q00") is not None:
        return base, "analysis.json"
    n = order.get("n_analysed") or 0
    if n < 1:
        return {"Q00": None, "Q00_std": None, "Q22": None, "Q22_std": None}, "none (no grain analysed)"
    from granpack.analysis.order import isotropic_baseline

    q00, s00, q22, s22 = isotropic_baseline(int(n))
    return {"Q00": q00, "Q00_std": s00, "Q22": q22, "Q22_std": s22}, "granpack.analysis.order.isotropic_baseline"


def level_one(eq: dict) -> bool:
    """The final state meets the settling benchmark's first level of rest."""
    values = [_finite(eq.get(k)) for k in ("max_net_force", "max_net_torque", "kinetic_energy", "wall_force_over_weight")]
    if any(v is None for v in values):
        return False
    force, torque, kinetic, wall = values
    return (force <= LEVEL_ONE["max_net_force"] and torque <= LEVEL_ONE["max_net_torque"]
            and kinetic <= LEVEL_ONE["kinetic_energy"] and abs(wall - 1.0) <= LEVEL_ONE["wall"])


def run_record(mixture: str, analysis: dict, summary: dict | None = None, **extra) -> dict:
    """The figures of one run from its ``analysis.json`` (and ``summary.json``) as a flat record.

    ``analysis`` is the document as read from the file (undefined figures ``None``).
    """
    bulk, sf, co = analysis["bulk"], analysis["solid_fraction"], analysis["coordination"]
    order, ip, eq = analysis["order"], analysis["interpenetration"], analysis["equilibrium"]
    base, base_source = _baseline(order)
    summary = summary or {}
    record = {
        "mixture": mixture,
        "seed": analysis.get("seed"),
        "n_particles": analysis.get("n_particles"),
        **extra,
        "status": summary.get("status", analysis.get("status")),
        "level_one": level_one(eq),
        "simulated_time": summary.get("simulated_time"),
        "steps": summary.get("steps"),
        "wall_time": summary.get("wall_time"),
        "bulk": {k: bulk.get(k) for k in ("valid", "z_bottom", "z_top", "z_surface")},
        "phi": sf.get("bulk"),
        "phi_layers_std": sf.get("std"),
        "phi_layers": len(sf.get("layers") or []),
        "phi_corrected_for_overlap": sf.get("corrected_for_overlap"),
        **{k: co.get(k) for k in COORDINATION_KEYS},
        "rattler_fraction": co.get("rattler_fraction"),
        "n_coordination": co.get("n_analysed"),
        "with_rattlers": co.get("with_rattlers"),
        "gap_rule": {k: (co.get("gap_rule") or {}).get(k) for k in (*COORDINATION_KEYS, "rattler_fraction")},
        "geometric": {k: (co.get("geometric") or {}).get(k) for k in (*COORDINATION_KEYS, "rattler_fraction")},
        "Q00": order.get("Q00"),
        "Q22": order.get("Q22"),
        "director_axis": order.get("director_axis"),
        "n_order": order.get("n_analysed"),
        "baseline": base,
        "baseline_source": base_source,
        "k": ip.get("expansion_k"),
        "k_all": ip.get("k"),
        "overlap_max": ip.get("max"),
        "equilibrium": {k: eq.get(k) for k in ("max_net_force", "max_net_torque", "kinetic_energy",
                                               "wall_force_over_weight", "passed")},
        "warnings": analysis.get("warnings", []),
    }
    return record


def _read_json(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def validate_run(mixture: str, seed: int, args, progress: str | bool = "lines") -> dict:
    """Run (or with ``args.reuse`` re-analyse) one mixture and seed; return its record."""
    from granpack.analysis.report import analyze_run
    from granpack.config import load_config
    from granpack.io.json import to_jsonable
    from granpack.simulation import run_packing

    run_dir = args.out / f"{mixture}-n{args.n}-seed{seed}"
    populations = load_populations(mixture)
    if args.reuse:
        if not (run_dir / "final.gsd").is_file():
            raise FileNotFoundError(f"{run_dir}: no final.gsd to re-analyse (run without --reuse first)")
        config = load_config(run_dir / "config.toml")
        note = None  # the cell and grain count are the folder's (config.toml)
        wall = None
    else:
        if args.lateral is not None:
            lateral, n, note = args.lateral, args.n, None
            height = expected_column(populations, n, lateral)
            if height < args.min_column:
                print(f"{mixture}: warning: expected column {height:.2g} d in the {lateral:g} d cell (phi "
                      f"{PHI_ESTIMATE}), below {args.min_column:g} d: the bulk may be thin or absent "
                      f"({needed_column():g} d needed)", file=sys.stderr, flush=True)
        else:
            lateral, n, note = plan_cell(populations, args.n, nominal_lateral(args.n), args.min_column, args.min_lateral)
        if note:
            print(f"{mixture}: {note}", file=sys.stderr, flush=True)
        config = _config(populations, n, lateral, seed=seed, max_time=args.max_time)
        start = time.perf_counter()
        run_packing(config, run_dir, overwrite=True, progress=progress)
        wall = time.perf_counter() - start
    start = time.perf_counter()
    analysis = to_jsonable(analyze_run(run_dir))
    analysis_seconds = time.perf_counter() - start
    summary = _read_json(run_dir / "summary.json")
    record = run_record(
        mixture, analysis, summary,
        n_requested=args.n,
        lateral_size=config.lateral_size,
        expected_column=expected_column(populations, config.n_particles, config.lateral_size),
        cell_note=note,
        run_dir=str(run_dir),
        reused=bool(args.reuse),
        analysis_seconds=analysis_seconds,
        call_wall_seconds=wall,
    )
    return record


# ----------------------------------------------------------------------------------------------
# tables


def _fmt(value, spec: str) -> str:
    value = _finite(value)
    return "n/a" if value is None else format(value, spec)


def _values(records: list[dict], key) -> list[float]:
    get = key if callable(key) else (lambda r: r.get(key))
    return [v for v in (_finite(get(r)) for r in records) if v is not None]


def _mean(records: list[dict], key, spec: str) -> str:
    """Mean over the runs; ``(k/n)`` when only k of the n runs define it."""
    values = _values(records, key)
    if not values:
        return "n/a"
    text = format(statistics.fmean(values), spec)
    return text if len(values) == len(records) else f"{text} ({len(values)}/{len(records)})"


def _worst(records: list[dict], key: str, spec: str, distance=abs) -> str:
    values = _values(records, lambda r: r["equilibrium"].get(key))
    if not values:
        return "n/a"
    return format(max(values, key=distance), spec)


def _phi(records: list[dict]) -> str:
    values = _values(records, "phi")
    if not values:
        return "n/a"
    if len(values) >= 2:
        text = f"{statistics.fmean(values):.4f} ± {statistics.stdev(values):.4f}"
    else:
        one = next(r for r in records if _finite(r.get("phi")) is not None)
        text = f"{values[0]:.4f} ± {_fmt(one.get('phi_layers_std'), '.4f')} (layers)"
    return text if len(values) == len(records) else f"{text} ({len(values)}/{len(records)})"


def _order(records: list[dict], key: str) -> str:
    value = _mean(records, key, ".3f")
    base = _values(records, lambda r: r["baseline"].get(key))
    spread = _values(records, lambda r: r["baseline"].get(f"{key}_std"))
    if not base:
        return f"{value} (n/a)"
    return f"{value} ({statistics.fmean(base):.3f} ± {statistics.fmean(spread) if spread else math.nan:.3f})"


def _status(records: list[dict]) -> str:
    counts: dict[str, int] = {}
    for r in records:
        label = str(r.get("status"))
        if r.get("status") != "equilibrium":
            label += ", level 1" if r.get("level_one") else ", not level 1"
        counts[label] = counts.get(label, 0) + 1
    return "; ".join(f"{label}" + (f" x{c}" if len(records) > 1 else "") for label, c in counts.items())


def _duration(seconds) -> str:
    seconds = _finite(seconds)
    if seconds is None:
        return "n/a"
    if seconds >= 3600:
        return f"{seconds / 3600:.1f} h"
    if seconds >= 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds:.0f} s"


def _grains(records: list[dict]) -> str:
    ns = sorted({r.get("n_particles") for r in records}, key=str)
    cells = sorted({r.get("lateral_size") for r in records}, key=str)
    text = f"{'/'.join(str(n) for n in ns)}, {'/'.join(_fmt(c, 'g') for c in cells)} d"
    if any(not r["bulk"].get("valid") for r in records):
        text += f", no bulk in {sum(not r['bulk'].get('valid') for r in records)}"
    return text


HEADER = ("mixture", "grains, cell", "seeds", "φ bulk ± std", "N", "Ns", "Nd", "Nt", "Nc", "rattlers",
          "Q00 (isotropic)", "Q22 (isotropic)", "k", "status", "max F/(d²P)", "max T/(d³P)", "max E/(d³P)",
          "wall F/W", "wall time")


def table_row(label: str, records: list[dict]) -> list[str]:
    """One table row over ``records`` (the runs of one mixture, or one run)."""
    return [
        label,
        _grains(records),
        ", ".join(str(r.get("seed")) for r in records),
        _phi(records),
        *(_mean(records, k, ".2f") for k in COORDINATION_KEYS),
        _mean(records, "rattler_fraction", ".3f"),
        _order(records, "Q00"),
        _order(records, "Q22"),
        _mean(records, "k", ".1e"),
        _status(records),
        _worst(records, "max_net_force", ".1e"),
        _worst(records, "max_net_torque", ".1e"),
        _worst(records, "kinetic_energy", ".1e"),
        _worst(records, "wall_force_over_weight", ".5f", distance=lambda w: abs(w - 1.0)),
        _duration(statistics.fmean(_values(records, "wall_time"))) if _values(records, "wall_time") else "n/a",
    ]


def _markdown(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def mixture_table(records: list[dict]) -> str:
    """Markdown: one row per mixture (in order of first appearance), figures over its seeds."""
    by_mixture: dict[str, list[dict]] = {}
    for r in records:
        by_mixture.setdefault(r["mixture"], []).append(r)
    return _markdown([table_row(name, runs) for name, runs in by_mixture.items()])


def runs_table(records: list[dict]) -> str:
    """Markdown: one row per run."""
    return _markdown([table_row(f"{r['mixture']} seed {r.get('seed')}", [r]) for r in records])


NOTES = (
    "φ: bulk solid fraction, mean ± std over the seeds (one seed: ± std of the bulk's d-thick layers); "
    "N, Ns, Nd, Nt, Nc, rattlers: backbone coordination (types from the force-bearing points), mean over the "
    "seeds; Q00, Q22: mean over the seeds (isotropic baseline for the same number of grains: mean ± std); "
    "k: interpenetration.expansion_k; status: 'equilibrium' (the default criteria held over the window) or "
    "not, with whether the final state meets level 1 of benchmarks/bench_settle.py; equilibrium figures: "
    "the worst over the seeds; wall time: mean per run (pour and settling). (k/n): defined in k of n runs."
)


def report(records: list[dict], command: str) -> str:
    """The markdown document: context line, mixture table, notes, per-run table, cell notes."""
    date = datetime.date.today().isoformat()
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    parts = [f"{date}, {machine}, `{command}`:", "", mixture_table(records), "", NOTES, "",
             "Per run:", "", runs_table(records)]
    notes = sorted({f"- {r['mixture']}: {r['cell_note']}" for r in records if r.get("cell_note")})
    if notes:
        parts += ["", "Cells adapted for a bulk region:", "", *notes]
    missing = [f"- {r['mixture']} seed {r.get('seed')}: {w}" for r in records for w in r.get("warnings", [])]
    if missing:
        parts += ["", "Analysis warnings:", "", *missing]
    return "\n".join(parts) + "\n"


# ----------------------------------------------------------------------------------------------


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mixture", action="append", choices=list(MIXTURES), help="mixture (repeatable; default all)")
    parser.add_argument("--n", type=int, default=3000, help="grains per packing (default 3000)")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per mixture (default 2)")
    parser.add_argument("--first-seed", type=int, default=1, help="first seed (default 1)")
    parser.add_argument("--out", type=Path, default=Path("runs/validate-pinacoids"), help="folder of the run folders")
    parser.add_argument("--max-time", type=float, default=300.0, help="max_time of every run, sqrt(d/g) (default 300)")
    parser.add_argument("--lateral", type=float, default=None,
                        help="cell side for every mixture, d (default: 8 d from 3000 grains, 4 d from 1000, 3 d "
                             "below, narrowed or with more grains where the column would be too short)")
    parser.add_argument("--min-column", type=float, default=8.0,
                        help="expected column (solid fraction 0.6) to reach by adapting the cell, d (default 8)")
    parser.add_argument("--min-lateral", type=float, default=3.0, help="narrowest adapted cell, d (default 3)")
    parser.add_argument("--reuse", action="store_true", help="re-analyse the existing run folders instead of running")
    parser.add_argument("--table", type=Path, help="write the markdown tables to this file")
    parser.add_argument("--quiet", action="store_true", help="no progress lines from the runs")
    args = parser.parse_args(argv)
    command = "python benchmarks/validate_pinacoids.py " + " ".join(sys.argv[1:] if argv is None else argv)
    records, failed = [], []
    for mixture in args.mixture or list(MIXTURES):
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            try:
                record = validate_run(mixture, seed, args, progress=not args.quiet and "lines")
            except FileNotFoundError as exc:
                print(f"error: {exc}", file=sys.stderr, flush=True)
                failed.append((mixture, seed))
                continue
            records.append(record)
            print(json.dumps(record), flush=True)
    if records:
        text = report(records, command.strip())
        print(text, flush=True)
        if args.table:
            args.table.write_text(text)
    return 1 if failed or not records else 0


if __name__ == "__main__":
    sys.exit(main())

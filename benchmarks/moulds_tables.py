"""The tables of docs/moulds-and-friction.md, from kept runs.

``friction ROOT``: every ``FAMILY-mu-M/seed-S`` run folder of a campaign's kept runs
(``friction.toml``, ``friction-pinacoids.toml``: ``benchmarks/validation/runs/friction``,
``.../friction-pinacoids``) with its ``analysis.json`` and ``summary.json``, one markdown row per
μ: runs at rest, simulated time at rest, mean CPU seconds, then means ± standard deviations over the
seeds of the bulk solid fraction, the backbone's and all grains' coordination N, the rattler
fraction, and the frictional figures of ``analysis.json`` (sliding fraction, mean mobilisation,
hyperstaticity).

``walls ROOT``: every ``MIXTURE/seed-S`` folder of the moulds' kept runs (``moulds.toml``:
``benchmarks/validation/runs/moulds``) with its ``analysis.json``, ``summary.json`` and
``task.json``, one markdown row per run: the container and its D/d (the inside diameter or side over
the grain size), the simulated time at rest, the core's solid fraction (the bulk slab less
``n_wall`` = 2 d at the wall) ± the standard deviation of its layers, the backbone's N and the
rattler fraction, the solid fraction over the bulk slab's whole section, and for a cylinder of
spheres the mean solid fraction of Benyahia & O'Neill (2005), 1 - (0.390 + 1.740 / (D/d + 1.140)^2).

Usage::

    python benchmarks/moulds_tables.py friction benchmarks/validation/runs/friction
    python benchmarks/moulds_tables.py walls benchmarks/validation/runs/moulds
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

FRICTION_HEADER = ("| μ | at rest / runs | t at rest | CPU s | bulk φ | N (backbone) | N (all) | rattlers | sliding contacts "
          "| mean mobilisation | hyperstaticity |")


def run_row(run: Path) -> dict | None:
    """The figures of one run folder, or None while it has no analysis."""
    if not (run / "analysis.json").is_file() or not (run / "summary.json").is_file():
        return None
    a = json.loads((run / "analysis.json").read_text())
    s = json.loads((run / "summary.json").read_text())
    c = a["coordination"]
    frictional = c.get("frictional") or {}
    return {"at_rest": s["status"] == "equilibrium", "t": s["simulated_time"], "cpu": s["cpu_time"],
            "phi": a["solid_fraction"]["bulk"], "N": c["N"], "N_all": c["with_rattlers"]["N"],
            "rattlers": 100.0 * c["rattler_fraction"], "sliding": frictional.get("sliding_fraction"),
            "mobilisation": frictional.get("mean_mobilisation"), "hyperstaticity": frictional.get("hyperstaticity")}


def _mean_std(values: list, fmt: str) -> str:
    kept = [v for v in values if v is not None]
    if not kept:
        return "–"
    text = format(statistics.fmean(kept), fmt)
    return text + (" ± " + format(statistics.stdev(kept), fmt) if len(kept) > 1 else "")


def _span(values: list) -> str:
    low, high = f"{min(values):.0f}", f"{max(values):.0f}"
    return low if low == high else f"{low}-{high}"


def friction_table(root: Path) -> str:
    """The frictional packings' table of the kept runs under ``root`` (module docstring)."""
    rows: dict[str, list[dict]] = {}
    for run in sorted(root.glob("*-mu-*/seed-*")):
        row = run_row(run)
        if row is not None:
            rows.setdefault(run.parent.name.rpartition("-mu-")[2], []).append(row)
    lines = [FRICTION_HEADER, "|---|---|---|---|---|---|---|---|---|---|---|"]
    for mu in sorted(rows, key=float):
        r = rows[mu]
        col = {k: [x[k] for x in r] for k in r[0]}
        lines.append(
            f"| {mu} | {sum(col['at_rest'])} / {len(r)} | {_span(col['t'])} | "
            f"{statistics.fmean(col['cpu']):.0f} | {_mean_std(col['phi'], '.4f')} | {_mean_std(col['N'], '.2f')} | "
            f"{_mean_std(col['N_all'], '.2f')} | {_mean_std(col['rattlers'], '.1f')} % | {_mean_std(col['sliding'], '.3f')} | "
            f"{_mean_std(col['mobilisation'], '.3f')} | {_mean_std(col['hyperstaticity'], '.3f')} |")
    return "\n".join(lines)


WALLS_HEADER = ("| run | container, D/d | at rest at t | φ core | N (backbone) | rattlers | φ whole section "
          "| Benyahia & O'Neill φ |")


def benyahia_oneill(ratio: float) -> float:
    """The mean solid fraction of a bed of spheres in a tube of ``ratio`` = D/d (their voidage fit,
    1.5 < D/d < 50)."""
    return 1.0 - (0.390 + 1.740 / (ratio + 1.140) ** 2)


def _f(value, fmt: str) -> str:
    return "–" if value is None else format(value, fmt)


def wall_row(run: Path) -> str | None:
    """The table row of one run folder, or None while it has no analysis."""
    if not (run / "analysis.json").is_file():
        return None
    a = json.loads((run / "analysis.json").read_text())
    s = json.loads((run / "summary.json").read_text())
    config = json.loads((run / "task.json").read_text())["config"]
    container = config.get("container", {}).get("shape", "periodic")
    size = max(p.get("size", 1.0) for p in config["populations"])
    ratio = config["lateral_size"] / size
    phi, c = a["solid_fraction"], a["coordination"]
    section = (a.get("wall_profile") or {}).get("section_solid_fraction")
    shape = config["populations"][0]["shape"]
    reference = benyahia_oneill(ratio) if container == "cylinder" and shape == "sphere" else None
    rest = f"{s['simulated_time']:.4g}" if s["status"] == "equilibrium" else f"not at rest ({s['simulated_time']:.4g})"
    return (f"| {run.parent.name}, seed {run.name.split('-')[-1]} | {container}, {ratio:g} | {rest} | "
            f"{_f(phi['bulk'], '.4f')} ± {_f(phi['std'], '.4f')} | {_f(c['N'], '.2f')} | "
            f"{_f(None if c['rattler_fraction'] is None else 100 * c['rattler_fraction'], '.1f')} % | "
            f"{_f(section, '.4f')} | {_f(reference, '.4f')} |")


def walls_table(root: Path) -> str:
    """The wall effect's table of the kept runs under ``root`` (module docstring)."""
    rows = [row for run in sorted(root.glob("*/seed-*")) if (row := wall_row(run)) is not None]
    return "\n".join([WALLS_HEADER, "|---|---|---|---|---|---|---|---|", *rows])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", choices=("friction", "walls"), help="which table")
    parser.add_argument("root", type=Path, help="a campaign's kept runs, e.g. benchmarks/validation/runs/friction")
    args = parser.parse_args(argv)
    print((friction_table if args.table == "friction" else walls_table)(args.root))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

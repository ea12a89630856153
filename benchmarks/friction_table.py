"""The table of poured frictional packings in docs/moulds-and-friction.md, from kept runs.

Reads every ``FAMILY-mu-M/seed-S`` run folder of a campaign's kept runs (``friction.toml``,
``friction-pinacoids.toml``: ``benchmarks/validation/runs/friction``, ``.../friction-pinacoids``)
with its ``analysis.json`` and ``summary.json``, and prints one markdown row per μ: runs at rest,
simulated time at rest, mean CPU seconds, then means ± standard deviations over the seeds of the
bulk solid fraction, the backbone's and all grains' coordination N, the rattler fraction, and the
frictional figures of ``analysis.json`` (sliding fraction, mean mobilisation, hyperstaticity).

Usage::

    python benchmarks/friction_table.py benchmarks/validation/runs/friction
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

HEADER = ("| μ | at rest / runs | t at rest | CPU s | bulk φ | N (backbone) | N (all) | rattlers | sliding contacts "
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


def table(root: Path) -> str:
    """The markdown table of the kept runs under ``root`` (module docstring)."""
    rows: dict[str, list[dict]] = {}
    for run in sorted(root.glob("*-mu-*/seed-*")):
        row = run_row(run)
        if row is not None:
            rows.setdefault(run.parent.name.rpartition("-mu-")[2], []).append(row)
    lines = [HEADER, "|---|---|---|---|---|---|---|---|---|---|---|"]
    for mu in sorted(rows, key=float):
        r = rows[mu]
        col = {k: [x[k] for x in r] for k in r[0]}
        lines.append(
            f"| {mu} | {sum(col['at_rest'])} / {len(r)} | {_span(col['t'])} | "
            f"{statistics.fmean(col['cpu']):.0f} | {_mean_std(col['phi'], '.4f')} | {_mean_std(col['N'], '.2f')} | "
            f"{_mean_std(col['N_all'], '.2f')} | {_mean_std(col['rattlers'], '.1f')} % | {_mean_std(col['sliding'], '.3f')} | "
            f"{_mean_std(col['mobilisation'], '.3f')} | {_mean_std(col['hyperstaticity'], '.3f')} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="a campaign's kept runs, e.g. benchmarks/validation/runs/friction")
    print(table(parser.parse_args(argv).root))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""What the bursts of a pile near rest cost, from the kept runs' timelines.

A run solves the NLGS to ``solver.settling_tolerance`` (1e-3) until its kinetic criterion first
falls below ``solver.tolerance_below`` (1e-5), then to ``solver.tolerance`` (1e-4) for good
(docs: design notes, "Settling tolerance"). A rearrangement after that switch (a burst) is solved
to the finer tolerance, at more sweeps per step. This script bounds what a rule that went back to
the settling tolerance during a burst could save, without running anything.

For every ``timeline.csv`` under the folders given (one row per equilibrium check), the CPU time
between two checks is charged to the later row. Rows solved to ``solver.tolerance`` whose kinetic
criterion is above ``--above`` (d^3 P) are the bursts. The bound assumes that the burst's steps
would take the sweeps per step of the same run's late settling steps (``mean_sweeps`` of the rows
at the settling tolerance with kinetic criterion below 1e-3; 10 if none), that a step's CPU time is
proportional to its sweeps, and that the trajectory is unchanged:

    saving = sum over burst rows of cpu_row * max(0, 1 - late_settling_sweeps / mean_sweeps_row)

It is an upper bound: a step's detection does not shrink with the sweeps, and a coarser solve
changes the trajectory (it may rest later).

Prints one JSON object: the runs read, their CPU seconds, the shares near rest and in bursts, the
bound on the saving, and the runs whose own bound exceeds 10 %.

Usage::

    python benchmarks/near_rest_bursts.py benchmarks/study benchmarks/validation/runs
    python benchmarks/near_rest_bursts.py benchmarks/study --above 1e-3
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

#: the settling tolerance's sweeps per step assumed where a run has no late settling row
_DEFAULT_SWEEPS = 10.0


def run_figures(timeline: pd.DataFrame, fine_tolerance: float, above: float) -> dict | None:
    """CPU seconds of one run in all, near rest and in bursts, and the bound on its saving; None
    for a timeline without the NLGS columns or that never reached the fine tolerance."""
    if "nlgs_tolerance" not in timeline or "cpu_seconds" not in timeline:
        return None
    cpu = timeline["cpu_seconds"].diff().fillna(timeline["cpu_seconds"].iloc[0]).clip(lower=0.0)
    near = timeline["nlgs_tolerance"] <= fine_tolerance * (1.0 + 1e-9)
    if not near.any():
        return None
    late = timeline["mean_sweeps"][~near & (timeline["kinetic_criterion"] < 1e-3)]
    late_sweeps = float(late.median()) if len(late) else _DEFAULT_SWEEPS
    burst = near & (timeline["kinetic_criterion"] > above)
    saved = cpu[burst] * (1.0 - late_sweeps / timeline["mean_sweeps"][burst]).clip(lower=0.0)
    return {"cpu": float(cpu.sum()), "near_rest": float(cpu[near].sum()), "bursts": float(cpu[burst].sum()),
            "saving": float(saved.sum())}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", type=Path, nargs="+", help="folders searched for run folders' timeline.csv")
    parser.add_argument("--above", type=float, default=1e-4,
                        help="kinetic criterion (d^3 P) above which a row near rest is a burst (default 1e-4)")
    parser.add_argument("--tolerance", type=float, default=1e-4, help="the fine NLGS tolerance (default 1e-4)")
    args = parser.parse_args(argv)
    runs = {}
    for root in args.roots:
        for path in sorted(root.rglob("timeline.csv")):
            figures = run_figures(pd.read_csv(path), args.tolerance, args.above)
            if figures is not None:
                runs[str(path.parent)] = figures
    total = {key: sum(run[key] for run in runs.values()) for key in ("cpu", "near_rest", "bursts", "saving")}
    cpu = total["cpu"] or np.nan
    print(json.dumps({
        "runs": len(runs), "above": args.above, "cpu_seconds": round(total["cpu"]),
        "near_rest_share": round(total["near_rest"] / cpu, 3), "burst_share": round(total["bursts"] / cpu, 3),
        "saving_bound": round(total["saving"] / cpu, 3),
        "runs_over_10_percent": {name: round(run["saving"] / run["cpu"], 2) for name, run in
                                 sorted(runs.items(), key=lambda item: -item[1]["saving"] / item[1]["cpu"])
                                 if run["saving"] > 0.1 * run["cpu"]},
    }, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

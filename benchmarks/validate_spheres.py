"""Validation of the protocol on frictionless spheres (docs/method/analysis.md#reference-values-spheres), too slow for CI.

Runs ``granpack.simulation.run_packing`` then the analysis on

- ``mono``: N monodisperse spheres (default 1000, L = 8 d): bulk solid fraction (2 d above the
  wall, 2 d below the free surface) expected in [0.630, 0.645] (random close packing, 0.636-0.640
  in the literature) and coordination about 6 once rattlers are removed (isostatic);
- ``bidisperse``: N spheres of sizes d and d/3 with 30 % small by volume (default 3000, L = 4 d:
  the small spheres are 92 % of the grains, so an 8 d cell would leave a column 4 d tall, no bulk):
  expected about 0.72 (0.7207 molecular dynamics, Roux & Chareyre 2007; 0.72-0.73 literature);
- ``mono-friction``: the monodisperse case with mu = 0.3, which must be looser.

Usage::

    python benchmarks/validate_spheres.py mono [--n 1000] [--out runs/validate] [--seed 1]

Prints one JSON object per case: status, settling time, wall time, bulk solid fraction (mean and
std over the bulk slices), coordination (all grains and backbone), rattler fraction, largest overlap.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from granpack.analysis.report import analyze_run
from granpack.config import load_config_dict
from granpack.simulation import run_packing

CASES = {
    "mono": {"populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}], "friction": 0.0, "n": 1000,
             "lateral": 8.0},
    "mono-friction": {"populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}], "friction": 0.3,
                      "n": 1000, "lateral": 8.0},
    "bidisperse": {"populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 0.7},
                                   {"shape": "sphere", "size": 1.0 / 3.0, "volume_fraction": 0.3}],
                   "friction": 0.0, "n": 3000, "lateral": 4.0},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=sorted(CASES))
    parser.add_argument("--n", type=int, default=None, help="number of spheres (default: the case's)")
    parser.add_argument("--lateral", type=float, default=None, help="cell side, d (default: the case's)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--max-time", type=float, default=200.0)
    parser.add_argument("--out", type=Path, default=Path("runs/validate"))
    parser.add_argument("--progress", action="store_true")
    args = parser.parse_args()
    case = CASES[args.case]
    config = load_config_dict({
        "seed": args.seed,
        "n_particles": args.n or case["n"],
        "lateral_size": args.lateral or case["lateral"],
        "populations": case["populations"],
        "solver": {"friction": case["friction"]},
        "equilibrium": {"max_time": args.max_time},
    })
    out = args.out / f"{args.case}-n{config.n_particles}-seed{args.seed}"
    start = time.perf_counter()
    summary = run_packing(config, out, overwrite=True, progress=args.progress)  # a scratch folder per case
    analysis = analyze_run(out)
    co = analysis["coordination"]
    print(json.dumps({
        "case": args.case,
        "n_particles": config.n_particles,
        "lateral_size": config.lateral_size,
        "seed": args.seed,
        "friction": case["friction"],
        "status": summary["status"],
        "simulated_time": summary["simulated_time"],
        "steps": summary["steps"],
        "wall_seconds": time.perf_counter() - start,
        "mean_nlgs_sweeps": summary["nlgs"]["mean_iterations"],
        "solid_fraction_bulk": analysis["solid_fraction"]["bulk"],
        "solid_fraction_std": analysis["solid_fraction"]["std"],
        "bulk": [analysis["bulk"]["z_bottom"], analysis["bulk"]["z_top"]],
        "coordination": co,
        "max_overlap": summary["final"]["max_overlap"],
        "wall_force_over_weight": summary["equilibrium"]["wall_force_over_weight"],
    }, indent=1, default=float))


if __name__ == "__main__":
    main()

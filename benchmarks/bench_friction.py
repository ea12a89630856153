"""Frictional against frictionless spheres, poured to certified rest: the cost of Coulomb friction.

Each case is one `granpack run` (defaults but for the mixture, the cell and `solver.friction`) of
1000 spheres of diameter d in an 8 d periodic cell (seed 7: the spheres of the Yade comparison in
benchmarks/README.md), timed by `bench_settle.run_case` from its `timeline.csv`. Run it on one
thread (`NUMBA_NUM_THREADS=1`) and one case at a time. Per friction coefficient mu:

- `status`: "equilibrium" (certified at rest by the run's criteria, held over the window) or
  "not at rest" at `--max-time`, with the final criteria (`final`);
- `level_two` (certified) and `level_one` (the study's looser level): simulated time, steps, wall
  and CPU seconds since the start of the run (the deposit included);
- `mean_sweeps` (NLGS sweeps per step over the run) and after level one; `detection_ms_per_step`,
  `solver_ms_per_step`, and `cpu_ms_per_step` (the whole run's CPU over its steps);
- `cpu_seconds`, `simulated_time`, `steps` of the whole run.

The criteria are those of docs/method/equilibrium.md, the same with and without friction: every
grain's net force and torque (what the contact forces sum to, whatever their split between the
contacts of a grain, which friction leaves indeterminate), its kinetic energy, and the wall force
against the weight.

Prints one JSON object per case, then a last one comparing the cases with mu > 0 to mu = 0
(`cpu_to_rest_ratio`: CPU seconds to certified rest over the frictionless run's).

    NUMBA_NUM_THREADS=1 nohup python benchmarks/bench_friction.py --out /tmp/friction > friction.json &
    NUMBA_NUM_THREADS=1 python benchmarks/bench_friction.py --mu 0.5 --set solver.acceleration=none
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_settle  # noqa: E402

CASE = "spheres-1000-8d"
bench_settle.CASES[CASE] = {"n_particles": 1000, "lateral_size": 8.0, "seed": 7,
                            "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]}


def run(mu: float, out: Path, max_time: float, seed: int | None, overrides: list[str]) -> dict:
    result = bench_settle.run_case(CASE, out / f"mu{mu:g}", max_time, seed, [f"solver.friction={mu!r}", *overrides])
    result.pop("timeline")
    result["mu"] = mu
    result["cpu_ms_per_step"] = 1e3 * result["cpu_seconds"] / max(result["steps"], 1)
    result["threads"] = os.environ.get("NUMBA_NUM_THREADS", "all")
    return result


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mu", type=float, action="append", help="friction coefficients (default 0 and 0.5)")
    parser.add_argument("--out", type=Path, default=Path("bench-friction"))
    parser.add_argument("--max-time", type=float, default=200.0)
    parser.add_argument("--seed", type=int)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args(argv)
    results = []
    for mu in args.mu or [0.0, 0.5]:
        res = run(mu, args.out, args.max_time, args.seed, args.set)
        res["machine"] = platform.platform()
        results.append(res)
        print(json.dumps(res), flush=True)
    base = next((r for r in results if r["mu"] == 0.0), None)
    if base is not None and base["level_two"] is not None:
        print(json.dumps({"compared_to_mu_0": [
            {"mu": r["mu"], "status": r["status"],
             "cpu_to_rest_ratio": (r["level_two"]["cpu_seconds"] / base["level_two"]["cpu_seconds"]
                                   if r["level_two"] else None),
             "sweeps_ratio": r["mean_sweeps"] / base["mean_sweeps"],
             "cpu_per_step_ratio": r["cpu_ms_per_step"] / base["cpu_ms_per_step"]}
            for r in results if r["mu"] > 0]}))


if __name__ == "__main__":
    main()

"""Gradings: the cost of a step against the size ratio, and the time to rest against N.

Frictionless spheres on a Fuller curve (exponent 0.5) between ``d_max / ratio`` and ``d_max``, in
a cell sized so that the settled bed stands about ``--height`` d_max high (default 6; ``cube``: as
tall as wide, so that at the same N the load crosses about as many grains at every ratio), at
least 2.5 d wide.
Each case is one `granpack run` (defaults but for the mixture and the cap on the simulated time);
it prints one JSON object per case: steps, wall and CPU seconds, milliseconds per step (wall and
CPU, and detection and solver apart), contacts at the end, status and time at rest, and the
process's peak resident memory so far (run one case per process to read each case's own). On a
machine with other work beside it, compare the CPU milliseconds.

- ``ratio-1``, ``ratio-3``, ``ratio-10``: N = 3000, poured and settled for ``--time`` (default 10)
  sqrt(d/g): the cost of a step at each size ratio, at the same N;
- ``fuller-3000``, ``fuller-10000``, ``fuller-30000``: ratio 10, to certified rest (cap
  ``--max-time``, default 300): the time a user waits.

Usage::

    python benchmarks/bench_grading.py --case ratio-1 --case ratio-10 --time 10
    python benchmarks/bench_grading.py --case ratio-1 --case ratio-10 --height cube
    python benchmarks/bench_grading.py --case fuller-10000 --out /tmp/grading
    python benchmarks/bench_grading.py --case fuller-30000 --out /tmp/grading --resume   # after a stop
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import resource
import tempfile
import time
from pathlib import Path

from granpack.config import load_config_dict
from granpack.mixture import Mixture
from granpack.simulation import run_packing

#: height of the settled bed, in d_max, that sets each case's cell by default
HEIGHT = 6.0
#: solid fraction assumed for that height
PHI = 0.65

CASES = {
    "ratio-1": (3000, 1.0, "step"),
    "ratio-3": (3000, 3.0, "step"),
    "ratio-10": (3000, 10.0, "step"),
    "fuller-3000": (3000, 10.0, "rest"),
    "fuller-10000": (10_000, 10.0, "rest"),
    "fuller-30000": (30_000, 10.0, "rest"),
}


def case_config(name: str, max_time: float, seed: int, height: float | str = HEIGHT) -> dict:
    """The run config of a case, its cell sized for a bed about ``height`` d_max high (or a cube)."""
    n, ratio, _ = CASES[name]
    population = {"shape": "sphere", "volume_fraction": 1.0}
    if ratio == 1.0:
        population["size"] = 1.0
    else:
        population["grading"] = {"curve": "fuller", "d_min": 1.0 / ratio, "d_max": 1.0, "exponent": 0.5}
    raw = {"seed": seed, "n_particles": n, "lateral_size": 8.0, "populations": [population],
           "equilibrium": {"max_time": max_time}}
    volume = float(Mixture.from_config(load_config_dict(raw)).solid_volumes.sum())
    side = (volume / PHI) ** (1 / 3) if height == "cube" else math.sqrt(volume / (PHI * float(height)))
    raw["lateral_size"] = round(max(2.5, side), 3)
    return raw


def run_case(name: str, out: Path, step_time: float, max_time: float, seed: int,
             height: float | str = HEIGHT, resume: bool = False) -> dict:
    kind = CASES[name][2]
    raw = case_config(name, step_time if kind == "step" else max_time, seed, height)
    config = load_config_dict(raw, source=name)
    t0, c0 = time.perf_counter(), time.process_time()
    summary = run_packing(config, out / name, resume=resume, overwrite=not resume, progress="lines")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if resume:  # the run's totals over all its segments, as its clock kept them
        wall, cpu = summary["wall_time"], summary["cpu_time"]
    steps = max(summary["steps"], 1)
    settle = wall - summary["timing"]["deposit_seconds"]
    return {
        "case": name, "n_particles": config.n_particles, "size_ratio": CASES[name][1],
        "lateral_size": config.lateral_size, "bed": height, "seed": seed, "status": summary["status"],
        "simulated_time": summary["simulated_time"], "steps": summary["steps"],
        "wall_seconds": wall, "cpu_seconds": cpu, "deposit_seconds": summary["timing"]["deposit_seconds"],
        "ms_per_step": 1e3 * settle / steps,
        "cpu_ms_per_step": 1e3 * cpu / steps,
        "detection_ms_per_step": summary["timing"]["detection_ms_per_step"],
        "solver_ms_per_step": summary["timing"]["solver_ms_per_step"],
        "split_steps": summary["split_steps"], "mean_sweeps": summary["nlgs"]["mean_iterations"],
        "contacts": summary["final"]["contacts"], "max_overlap": summary["final"]["max_overlap"],
        "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "machine": platform.node(), "date": time.strftime("%Y-%m-%d"),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", action="append", choices=list(CASES), help="case to run (repeatable; default the ratio cases)")
    parser.add_argument("--time", type=float, default=10.0, help="simulated time of the ratio cases, sqrt(d/g)")
    parser.add_argument("--max-time", type=float, default=300.0, help="cap of the cases run to rest, sqrt(d/g)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--height", type=lambda v: v if v == "cube" else float(v), default=HEIGHT,
                        help="height of the settled bed in d_max, or 'cube' (as tall as wide)")
    parser.add_argument("--out", type=Path, default=None, help="keep the runs here (default: a temporary folder)")
    parser.add_argument("--resume", action="store_true",
                        help="with --out: continue each case's run from its checkpoint there (a stopped long "
                             "case); the times reported are the run's totals")
    args = parser.parse_args(argv)
    names = args.case or ["ratio-1", "ratio-3", "ratio-10"]
    if args.resume and args.out is None:
        parser.error("--resume needs --out (the folder that holds the runs to continue)")
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        for name in names:
            print(json.dumps(run_case(name, out, args.time, args.max_time, args.seed, args.height, args.resume)),
                  flush=True)


if __name__ == "__main__":
    main()

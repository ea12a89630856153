"""Does the NNCG momentum converge with Coulomb friction, and does it save sweeps? Measured on the
contact problems of real frictional runs.

A frictional `granpack run` (defaults but for the mixture, `solver.friction`, the cell and the
simulated time) is stepped with the solver it has; every `--every` steps the assembled velocity
problem of the step (frictional; the position correction's frictionless projections are left
out) is kept with its warm start and its NLGS tolerance (the settling tolerance 1e-3 while the
pile is far from rest, then 1e-4). Each kept problem is then solved again, from its warm start
and from zero, by the frictional NLGS (`granpack.nscd.nlgs._solve_coulomb`) with and without the
momentum, at its own tolerance and at 1e-6, on one thread. Per solve: sweeps, whether it
converged within `solver.max_iterations` (2000), the natural-map residual of the result
(`ContactProblem.residual`, 0 at an exact Signorini-Coulomb solution) and the largest difference
of the end velocities of the two solvers (a frictional problem may have several solutions, so
the velocities need not agree exactly), milliseconds.

Prints one JSON object: per case the problems (time, points, the solves) and the totals.

Cases (`--case`, repeatable; default both): `spheres-1000` (1000 spheres, 8 d cell, seed 7,
to t = 30), `pinacoids-300` (the demo's 300 isometric pinacoids, 3 d cell, seed 1, to t = 30).

    NUMBA_NUM_THREADS=1 python benchmarks/friction_nncg.py --mu 0.5 --every 400 > nncg.json
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import granpack.nscd.integrator as integrator
from granpack.config import load_config_dict
from granpack.nscd.nlgs import _solve_coulomb
from granpack.simulation import run_packing

CASES = {
    "spheres-1000": {"n_particles": 1000, "lateral_size": 8.0, "seed": 7,
                     "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]},
    "pinacoids-300": {"n_particles": 300, "lateral_size": 3.0, "seed": 1,
                      "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [1.0, 1.0],
                                       "volume_fraction": 1.0}]},
}


@dataclass
class Kept:
    step: int
    time: float
    tolerance: float
    problem: object


def capture(case: str, mu: float, max_time: float, every: int) -> list[Kept]:
    """Run ``case`` with friction ``mu`` to ``max_time``, keeping every ``every``-th step's problem."""
    raw = json.loads(json.dumps(CASES[case]))
    raw["solver"] = {"friction": mu}
    raw["equilibrium"] = {"max_time": max_time}
    config = load_config_dict(raw, source=case)
    kept: list[Kept] = []
    counter = {"solves": 0}
    original = integrator.solve

    def keeping(problem, options):
        if problem.frictional:
            counter["solves"] += 1
            if counter["solves"] % every == 0:
                kept.append(Kept(counter["solves"], counter["solves"] * config.time_stepping.time_step,
                                 options.tolerance, problem))
        return original(problem, options)

    integrator.solve = keeping
    try:
        with tempfile.TemporaryDirectory() as out:
            run_packing(config, Path(out) / "run", progress="lines")
    finally:
        integrator.solve = original
    return kept


def solve_once(problem, tolerance: float, nncg: bool, warm: bool, max_iterations: int = 2000):
    r = (problem.initial_impulse if warm else np.zeros_like(problem.initial_impulse)).copy()
    v = problem.velocity(r)
    t0 = time.process_time()
    sweeps, _error, converged = _solve_coulomb(problem.body, problem.normal_data, problem.friction_data,
                                               problem.offset, r, v, tolerance, max_iterations, 10, nncg)
    ms = 1e3 * (time.process_time() - t0)
    return r, {"sweeps": int(sweeps), "converged": bool(converged), "residual": problem.residual(r), "ms": ms}


def measure(kept: list[Kept]) -> dict:
    rows = []
    totals: dict = {}
    for k in kept:
        p = k.problem
        row = {"step": k.step, "points": p.n_points, "run_tolerance": k.tolerance}
        for start in ("warm", "cold"):
            for tol in (k.tolerance, 1e-6):
                label = f"{start}@{tol:g}" if tol != k.tolerance else f"{start}@run"
                r0, plain = solve_once(p, tol, False, start == "warm")
                r1, nncg = solve_once(p, tol, True, start == "warm")
                dv = float(np.abs(p.velocity(r0) - p.velocity(r1))[:-1].max()) if p.n_points else 0.0
                row[label] = {"nlgs": plain, "nncg": nncg, "velocity_difference": dv}
                acc = totals.setdefault(label, {"nlgs_sweeps": 0, "nncg_sweeps": 0, "nlgs_ms": 0.0, "nncg_ms": 0.0,
                                                "nlgs_unconverged": 0, "nncg_unconverged": 0,
                                                "nlgs_worst_residual": 0.0, "nncg_worst_residual": 0.0,
                                                "largest_velocity_difference": 0.0})
                for name, res in (("nlgs", plain), ("nncg", nncg)):
                    acc[f"{name}_sweeps"] += res["sweeps"]
                    acc[f"{name}_ms"] += res["ms"]
                    acc[f"{name}_unconverged"] += not res["converged"]
                    acc[f"{name}_worst_residual"] = max(acc[f"{name}_worst_residual"], res["residual"])
                acc["largest_velocity_difference"] = max(acc["largest_velocity_difference"], dv)
        rows.append(row)
    return {"problems": rows, "totals": totals}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", action="append", choices=sorted(CASES))
    parser.add_argument("--mu", type=float, default=0.5)
    parser.add_argument("--max-time", type=float, default=30.0)
    parser.add_argument("--every", type=int, default=400, help="keep one problem every so many steps")
    args = parser.parse_args(argv)
    result = {"machine": platform.platform(), "processor": platform.processor(), "mu": args.mu, "cases": {}}
    for case in args.case or ["spheres-1000", "pinacoids-300"]:
        t0 = time.process_time()
        kept = capture(case, args.mu, args.max_time, args.every)
        run_cpu = time.process_time() - t0
        result["cases"][case] = {"run_cpu_seconds": run_cpu, **measure(kept)}
        print(json.dumps({case: result["cases"][case]["totals"]}), flush=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()

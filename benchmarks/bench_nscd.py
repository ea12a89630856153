"""Benchmark of the NSCD step (granpack.nscd.step): detection vs solver time, NLGS sweeps, throughput.

Packings (no simulation loop needed): the centres of a periodic sequential sphere deposit
(:func:`granpack.deposit.deposit`, drop-and-roll, d = 1) carry spheres of diameter 1 or isometric
pinacoids (``Pinacoid.from_size(1.0)``, circumscribed diameter 1, random orientations). The
sphere deposit is already a dense contact network; the pinacoids, smaller than their spheres,
are first settled with ``--settle`` frictionless steps (the column collapses and a contact
network forms; the packing is dense in contacts but not yet at equilibrium). ``--gsd PATH``
instead reads a settled packing written by ``granpack.io.gsd.write_packing``; ``--tile K``
(repeatable) replicates it K x K times across its periodic cell, a pile at rest of K^2 times
as many grains (the cost of a step at rest against N). Then ``--steps`` steps are timed (after
``--settle`` untimed ones, which give a tiled pile its warm start).

Reported per case (JSON on stdout):

- ``detection_ms``, ``solver_ms``: mean per step (``StepInfo``; solver = assembly, warm start,
  NLGS, position correction, update);
- ``sweeps``: mean NLGS sweeps per step, ``points``: mean contact points;
- ``step_point_updates_per_s``: ``Σ points x sweeps / Σ solver seconds`` (whole solver phase);
- ``kernel_point_updates_per_s``: the frictionless NLGS kernel alone, re-solving the last step's
  assembled problem for a fixed number of sweeps (tolerance 0), one thread.

Usage::

    python benchmarks/bench_nscd.py                       # the three default cases
    python benchmarks/bench_nscd.py --case pinacoid:1000 --settle 200 --steps 20
    python benchmarks/bench_nscd.py --gsd settled.gsd --steps 20
    python benchmarks/bench_nscd.py --gsd settled.gsd --tile 1 --tile 2 --tile 3 --settle 5
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from granpack import Box, ShapeTable, Sphere
from granpack.contact import detect
from granpack.deposit import deposit
from granpack.nscd import NLGSOptions, StepParameters, assemble, predict, solve, step
from granpack.nscd.warmstart import warm_impulses
from granpack.rotations import random_quaternions
from granpack.shapes import Pinacoid
from granpack.state import ParticleState

SOLID_FRACTION = 0.58  # of the drop deposit, to size the box for a column ~ 12 d high


def packing(kind: str, n: int, seed: int = 1) -> ParticleState:
    rng = np.random.default_rng(seed)
    lateral = max(6.0, float(np.sqrt(n * np.pi / 6 / (SOLID_FRACTION * 12.0))))
    x = deposit(np.full(n, 0.5), lateral, rng, lateral="periodic")
    if kind == "sphere":
        shape, q = Sphere(1.0), np.tile([1.0, 0, 0, 0], (n, 1))
    else:
        shape, q = Pinacoid.from_size(1.0), random_quaternions(n, rng)
    return ParticleState(box=Box.square(lateral), shapes=ShapeTable.from_shapes([shape]), kind=np.zeros(n, int),
                         population=np.zeros(n, int), position=x, quaternion=q)


def tiled(state: ParticleState, k: int) -> ParticleState:
    """``state`` repeated ``k x k`` times across its periodic cell (a cell ``k`` times as wide)."""
    lx, ly = state.box.lx, state.box.ly
    shifts = np.array([(a * lx, b * ly, 0.0) for a in range(k) for b in range(k)])
    position = (state.position[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    return ParticleState(box=Box(lx * k, ly * k), shapes=state.shapes, kind=np.tile(state.kind, k * k),
                         population=np.tile(state.population, k * k), position=position,
                         quaternion=np.tile(state.quaternion, (k * k, 1)),
                         velocity=np.tile(state.velocity, (k * k, 1)), omega=np.tile(state.omega, (k * k, 1)))


def kernel_throughput(state, params, warm, sweeps: int = 200) -> tuple[float, int]:
    """Point-updates per second of the frictionless NLGS kernel on the next step's problem."""
    pr = predict(state.copy(), params)
    contacts = detect(pr.state, params.alert, previous=warm)
    problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity,
                       params.time_step)
    r0, _ = warm_impulses(warm, contacts, problem.tangent, pr.x_tt, pr.rot_tt, state.velocity, state.omega,
                          params.time_step, (state.box.lx, state.box.ly), 0.05, 0.0)
    from dataclasses import replace

    problem = replace(problem, initial_impulse=r0)
    options = NLGSOptions(tolerance=1e-300, max_iterations=sweeps, check_every=sweeps)
    solve(problem, NLGSOptions(tolerance=1e-300, max_iterations=2, check_every=2))  # compiled
    t0 = time.perf_counter()
    _, info = solve(problem, options)
    seconds = time.perf_counter() - t0
    return problem.n_points * info.iterations / seconds, problem.n_points


def run_case(label: str, state: ParticleState, settle: int, steps: int, params: StepParameters) -> dict:
    warm = None
    t0 = time.perf_counter()
    for _ in range(settle):
        warm, _ = step(state, params, warm)
    settle_s = time.perf_counter() - t0
    infos = []
    for _ in range(steps):
        warm, info = step(state, params, warm)
        infos.append(info)
    det = np.array([i.detection_seconds for i in infos])
    sol = np.array([i.solver_seconds for i in infos])
    sweeps = np.array([i.iterations + i.correction_iterations for i in infos])
    points = np.array([i.n_points for i in infos])
    kernel, kernel_points = kernel_throughput(state, params, warm)
    return {
        "case": label,
        "n": state.n,
        "box": [state.box.lx, state.box.ly],
        "settle_steps": settle,
        "settle_s": round(settle_s, 2),
        "steps": steps,
        "points": float(points.mean()),
        "manifolds": float(np.mean([i.n_contacts for i in infos])),
        "sweeps": float(np.mean([i.iterations for i in infos])),
        "correction_sweeps": float(np.mean([i.correction_iterations for i in infos])),
        "converged": int(sum(i.converged for i in infos)),
        "detection_ms": 1e3 * float(det.mean()),
        "solver_ms": 1e3 * float(sol.mean()),
        "step_point_updates_per_s": float((points * sweeps).sum() / sol.sum()),
        "kernel_point_updates_per_s": kernel,
        "kernel_points": kernel_points,
        "max_overlap": float(max(i.max_overlap for i in infos)),
        "max_speed": float(np.abs(state.velocity).max()),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", help="KIND:N with KIND sphere or pinacoid (repeatable)")
    ap.add_argument("--gsd", help="a settled packing (granpack.io.gsd.read_packing) instead of --case")
    ap.add_argument("--tile", type=int, action="append", help="with --gsd: replicate it K x K times (repeatable)")
    ap.add_argument("--settle", type=int, default=300, help="untimed steps before timing (pinacoids, tiled packings)")
    ap.add_argument("--steps", type=int, default=20, help="timed steps")
    ap.add_argument("--tolerance", type=float, default=1e-4)
    args = ap.parse_args(argv)
    params = StepParameters(time_step=5e-3, tolerance=args.tolerance)
    results = []
    if args.gsd:
        from granpack.io.gsd import read_packing

        state = read_packing(args.gsd).state
        for k in args.tile or [1]:
            settle = 0 if args.tile is None else args.settle
            results.append(run_case(f"{args.gsd} x {k}x{k}", tiled(state, k), settle, args.steps, params))
            print(json.dumps(results[-1]), flush=True)
    else:
        for case in args.case or ["pinacoid:1000", "pinacoid:3000", "sphere:3000"]:
            kind, n = case.split(":")
            state = packing(kind, int(n))
            settle = args.settle if kind == "pinacoid" else 0
            results.append(run_case(case, state, settle, args.steps, params))
            print(json.dumps(results[-1]), flush=True)
    print(json.dumps({"machine": f"{platform.machine()} {platform.python_version()}", "results": results}, indent=1))


if __name__ == "__main__":
    main()

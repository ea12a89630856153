"""Where a pile's energy goes, step by step: the contact impulses' work, split by its sources.

Over a Moreau–Jean step without position correction or damping, the kinetic plus potential
energy changes by the work of the contact impulses (docs: Method > NSCD, Energy). With θ = ½:

    dE = 1/2 sum_a r_a (u-_a + u+_a)

with u-, u+ the normal relative velocities at the start and the end of the step. The script
continues a packing (a run folder's ``final.gsd`` and ``config.toml``) for ``--steps`` plain
NSCD steps (the run's solver settings, no end game, no equilibrium checks) and prints, per block
of ``--block`` steps, one JSON line: the measured ``dE`` and the work ``W`` (equal for θ = ½),
split into

- ``opening``: 1/2 sum r u- over loaded points whose start velocity opens (u- > 0): energy given back;
- ``closing``: 1/2 sum r u- over loaded points that approach (u- <= 0): energy taken;
- ``residual``: 1/2 sum r (u+ + c), what the NLGS left undone (0 for an exact solve);
- ``push``: 1/2 sum r (-c) at overlapping points (the overlap recovery);
- ``landing``: 1/2 sum r (-c) at points still open at the predicted configuration (c = g/h);

so ``W = opening + closing + residual + push + landing``; also the correction's energy (reported
apart, excluded from ``dE``), the NLGS sweeps and the kinetic energy at the end of the block.
With θ = 1, ``W`` is sum r u+ and ``dE = W - 1/2 |dV|_M^2``.

Usage::

    python benchmarks/energy_budget.py RUN_DIR --steps 1000 --tolerance 1e-5
    python benchmarks/energy_budget.py RUN_DIR --steps 1000 --tolerance 1e-7 --theta 1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from granpack.config import load_config
from granpack.contact import detect
from granpack.io.gsd import read_packing
from granpack.nscd import advance, kinetic_energy, potential_energy, predict
from granpack.nscd.problem import assemble
from granpack.settling import step_parameters

TERMS = ("dE", "W", "opening", "closing", "residual", "push", "landing", "correction", "sweeps")


def step_terms(state, params, warm):
    """One step of ``state`` (in place): ``(contacts, terms)`` with the energy terms of the step."""
    before = kinetic_energy(state) + potential_energy(state)
    pr = predict(state, params)
    contacts = detect(pr.state, params.alert, previous=warm)
    contacts, info = advance(state, pr, contacts, params, warm)
    terms = dict.fromkeys(TERMS, 0.0)
    terms["dE"] = kinetic_energy(state) + potential_energy(state) - before - info.correction_energy
    terms["correction"] = info.correction_energy
    terms["sweeps"] = info.iterations
    if contacts.n_points:
        problem = assemble(
            contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity,
            params.time_step, restitution=params.restitution, recovery_slop=params.recovery_slop,
            recovery_rate=params.recovery_rate, recovery_speed=params.recovery_speed,
            slow_recovery_slop=params.slow_recovery_slop, slow_recovery_speed=params.slow_recovery_speed,
        )
        r = np.zeros((contacts.n_points, 3))
        r[:, 0] = np.einsum("ij,ij->i", contacts.impulse, problem.normal)
        u_start = problem.local_velocity(pr.start_velocity)[:, 0]
        u_end = problem.local_velocity(problem.velocity(r))[:, 0]
        rn, c, open_ = r[:, 0], problem.offset, problem.gap > 0.0
        terms["W"] = float(np.sum(rn * u_end)) if params.theta == 1.0 else 0.5 * float(np.sum(rn * (u_start + u_end)))
        terms["opening"] = 0.5 * float(np.sum(rn * np.maximum(u_start, 0.0)))
        terms["closing"] = 0.5 * float(np.sum(rn * np.minimum(u_start, 0.0)))
        terms["residual"] = 0.5 * float(np.sum(rn * (u_end + c)))
        terms["push"] = 0.5 * float(np.sum((rn * -c)[~open_]))
        terms["landing"] = 0.5 * float(np.sum((rn * -c)[open_]))
    return contacts, terms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a run folder holding config.toml and final.gsd")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--block", type=int, default=200, help="steps per printed line")
    ap.add_argument("--tolerance", type=float, help="NLGS tolerance (default: the run's)")
    ap.add_argument("--theta", type=float, help="theta (default: the run's)")
    args = ap.parse_args()
    config = load_config(args.run / "config.toml")
    state = read_packing(args.run / "final.gsd").state
    params = step_parameters(config)
    if args.tolerance is not None:
        params = dataclasses.replace(params, tolerance=args.tolerance)
    if args.theta is not None:
        params = dataclasses.replace(params, theta=args.theta)
    warm, block = None, dict.fromkeys(TERMS, 0.0)
    for n in range(1, args.steps + 1):
        warm, terms = step_terms(state, params, warm)
        for key, value in terms.items():
            block[key] += value
        if n % args.block == 0 or n == args.steps:
            line = {"run": str(args.run), "tolerance": params.tolerance, "theta": params.theta, "last_step": n,
                    **{k: float(f"{v:.4g}") for k, v in block.items()}, "kinetic_energy": float(f"{kinetic_energy(state):.3g}")}
            print(json.dumps(line), flush=True)
            block = dict.fromkeys(TERMS, 0.0)


if __name__ == "__main__":
    main()

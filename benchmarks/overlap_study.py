"""Interpenetration left by a run, and what it cost: one `granpack run` with config overrides.

Runs a config (the packaged demo by default) to ``--time`` with ``--set section.key=value``
overrides and prints JSON: the overlaps ``max(0, -gap)`` over all contact points of the final
contacts (max, mean, 99th percentile, points above 1e-4 d), the kinetic energy and wall force at
the end, the penetration depths of the final pairs (max, mean, pairs deeper than 1e-4 d), the
equilibrium criteria and status, the NLGS sweeps, the position corrections and, per interval of
``--every`` sqrt(d/g), the mean NLGS sweeps, the fraction of corrected steps and the unconverged
steps.

    python benchmarks/overlap_study.py --time 60 --set overlap.projection_slop=1e-4 --seed 2

Results are tabled in benchmarks/README.md; the decisions they informed are in docs/design-notes.md
and the module docstring of ``granpack.nscd.integrator``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import tomllib
from importlib.resources import files
from pathlib import Path

import numpy as np

import granpack.settling as settling
import granpack.simulation as simulation
from granpack.contact import Detector
from granpack.config import load_config_dict
from granpack.io.gsd import read_packing
from granpack.io.run_folder import FINAL_FILE
from granpack.nscd import kinetic_energy


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _penetration_depths(state) -> np.ndarray:
    """Penetration depth of every touching pair, d: the smallest gap of a detection whose axis
    hysteresis is 1e-9 d (the best separating axis, without the up to ``eps_f`` deeper face
    axes that the default hysteresis may keep)."""
    contacts = Detector(eps_f=1e-9).detect(state, 0.0)
    low = np.minimum.reduceat(contacts.gap, contacts.point_start[:-1]) if contacts.n_points else np.zeros(0)
    return np.maximum(0.0, -low)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, help="config TOML (default: the packaged demo)")
    parser.add_argument("--time", type=float, default=60.0, help="simulated time, sqrt(d/g)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override")
    parser.add_argument("--seed", type=int)
    parser.add_argument("--every", type=float, default=5.0, help="timeline interval, sqrt(d/g)")
    parser.add_argument("--out", type=Path, help="output folder (default: a temporary one)")
    args = parser.parse_args()

    text = args.config.read_text() if args.config else files("granpack").joinpath("data/demo.toml").read_text()
    raw = tomllib.loads(text)
    raw.setdefault("equilibrium", {})["max_time"] = args.time
    if args.seed is not None:
        raw["seed"] = args.seed
    for item in args.set:
        key, value = item.split("=", 1)
        section, name = key.split(".")
        raw.setdefault(section, {})[name] = _value(value)
    config = load_config_dict(raw, source="overlap_study")

    log = []
    advance = settling.advance

    def logged(state, *a, **k):
        contacts, info = advance(state, *a, **k)
        log.append((state.time, info.iterations, info.correction_iterations, info.converged))
        return contacts, info

    settling.advance = logged
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        start = time.perf_counter()
        summary = simulation.run_packing(config, out, overwrite=True, progress=False)
        wall = time.perf_counter() - start
        packing = read_packing(out / FINAL_FILE)
    overlap = np.maximum(0.0, -packing.contacts.gap)
    depth = _penetration_depths(packing.state)
    steps = np.array(log)
    timeline = []
    for t0 in np.arange(0.0, args.time, args.every):
        sel = (steps[:, 0] > t0) & (steps[:, 0] <= t0 + args.every)
        if sel.any():
            timeline.append({"from": float(t0), "nlgs_sweeps": float(steps[sel, 1].mean()),
                             "corrected_fraction": float((steps[sel, 2] > 0).mean()),
                             "unconverged": int((steps[sel, 3] == 0).sum())})
    print(json.dumps({
        "overrides": args.set, "seed": config.seed, "time": args.time, "wall_seconds": wall,
        "points": int(overlap.size), "max_overlap": float(overlap.max(initial=0.0)),
        "mean_overlap": float(overlap.mean()) if overlap.size else 0.0,
        "p99_overlap": float(np.quantile(overlap, 0.99)) if overlap.size else 0.0,
        "points_over_1e-4": int((overlap > 1e-4).sum()),
        "max_depth": float(depth.max(initial=0.0)),
        "mean_depth": float(depth.mean()) if depth.size else 0.0,
        "pairs_deeper_than_1e-4": int((depth > 1e-4).sum()),
        "status": summary["status"], "simulated_time": summary["simulated_time"],
        "max_net_force": summary["equilibrium"]["max_net_force"],
        "max_net_torque": summary["equilibrium"]["max_net_torque"],
        "kinetic_criterion": summary["equilibrium"]["kinetic_energy"],
        "kinetic_energy": float(kinetic_energy(packing.state)),
        "wall_force_over_weight": summary["equilibrium"]["wall_force_over_weight"],
        "nlgs_mean_sweeps": summary["nlgs"]["mean_iterations"],
        "unconverged_steps": summary["nlgs"]["unconverged_steps"],
        "corrected_steps": summary["position_correction"]["steps"],
        "correction_energy": summary["position_correction"]["potential_energy_added"],
        "timeline": timeline,
    }, indent=2))


if __name__ == "__main__":
    main()

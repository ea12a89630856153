"""Pour to rest: the whole `granpack run` a user runs, timed to each level of rest.

Each case is one `granpack run` (deposit, collapse, settling; defaults but for the mixture) whose
`timeline.csv` (one row per equilibrium check) gives, for two levels of rest, the first check
that meets it and the wall time, CPU time, steps and simulated time spent until then:

- level one, the study's pinacoid packings: largest net force and torque <= 1e-3 (d^2 P,
  d^3 P), kinetic criterion <= 1e-7 d^3 P, wall force within 0.5 % of the weight;
- level two, the default criteria (1e-4, 1e-4, 1e-8, 1e-4), held over the equilibrium window:
  the run's status "equilibrium" and its end.

Also per case: mean NLGS sweeps per step (over the run and after level one), detection and solver
milliseconds per step, the final criteria. Prints one JSON object per case, and writes a timeline
figure (kinetic energy and largest net force against time, one line per case).

Cases (`--case NAME`, repeatable; default: all, in this order, about two hours on 2 cores):

    spheres-1000, pinacoids-1000, flat-elongated-1000, bidisperse-pinacoids-1000, pinacoids-3000,
    scans-1000 (the 20 scan-like grains of bench_shapes.py, written as STL into the output folder
    and read as a "mesh" population, hulls reduced to 24 vertices), rocks-1000 (generated rocks of
    aspect ratios 1), scans-graded-2000 (those 20 and 12 hulls of random points, graded by sieve
    size on an 8/22 mm curve), cubes-1000 (regular cubes, 4.5 d cell, seed 3)

Usage::

    python benchmarks/bench_settle.py --case pinacoids-1000 --out /tmp/settle --figure settle.png
    python benchmarks/bench_settle.py --case pinacoids-1000 --seed 12 --set end_game.mode=none
    python benchmarks/bench_settle.py --figure-of RUN_DIR --figure-of RUN_DIR2 --figure settle.png
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import time
from pathlib import Path

from granpack.config import load_config_dict
from granpack.io.run_folder import TIMELINE_FILE
from granpack.simulation import run_packing

#: the folder of the scan-like grains' STL files, in the output folder
SCAN_FOLDER = "scan-shapes"

LEVEL_ONE = {"max_net_force": 1e-3, "max_net_torque": 1e-3, "kinetic_criterion": 1e-7, "wall": 5e-3}


def _pinacoid(size: float, aspect: tuple[float, float], share: float) -> dict:
    return {"shape": "pinacoid", "size": size, "aspect": list(aspect), "volume_fraction": share}


CASES = {
    "spheres-1000": {"n_particles": 1000, "lateral_size": 4.0, "seed": 11,
                     "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]},
    "pinacoids-1000": {"n_particles": 1000, "lateral_size": 4.0, "seed": 11,
                       "populations": [_pinacoid(1.0, (1.0, 1.0), 1.0)]},
    "flat-elongated-1000": {"n_particles": 1000, "lateral_size": 4.0, "seed": 11,
                            "populations": [_pinacoid(1.0, (3.0, 3.0), 1.0)]},
    "bidisperse-pinacoids-1000": {"n_particles": 1000, "lateral_size": 4.0, "seed": 11,
                                  "populations": [_pinacoid(1.0, (1.0, 1.0), 0.7),
                                                  _pinacoid(1.0 / 3.0, (1.0, 1.0), 0.3)]},
    "pinacoids-3000": {"n_particles": 3000, "lateral_size": 8.0, "seed": 31,
                       "populations": [_pinacoid(1.0, (1.0, 1.0), 1.0)]},
    # the scan-like grains of bench_shapes.py, written into the run's folder as STL files
    "scans-1000": {"n_particles": 1000, "lateral_size": 4.0, "seed": 11,
                   "populations": [{"shape": "mesh", "files": [f"{SCAN_FOLDER}/grain-*.stl"], "size": 1.0,
                                    "volume_fraction": 1.0}]},
    # 1000 regular cubes of circumscribed diameter 1 (edge 1/sqrt(3)), the face-to-face stacks of
    # docs/method/grains.md; run with --set solver.friction=0.5 for the frictional pile
    "cubes-1000": {"n_particles": 1000, "lateral_size": 4.5, "seed": 3,
                   "populations": [{"shape": "polyhedron", "size": 1.0, "volume_fraction": 1.0,
                                    "vertices": [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]}]},
    # 1000 generated rocks of aspect ratios 1 (10 rocks of 14 faces, the defaults)
    "rocks-1000": {"n_particles": 1000, "lateral_size": 4.0, "seed": 11,
                   "populations": [{"shape": "rock", "aspect": [1.0, 1.0], "size": 1.0, "volume_fraction": 1.0}]},
    # a library of 32 scan-like shapes (the 20 ellipsoids and 12 hulls of random points) graded by
    # sieve size on the 8/22 mm curve of docs/how-to/scanned-aggregate.md
    "scans-graded-2000": {"n_particles": 2000, "lateral_size": 4.5, "seed": 11,
                          "time_stepping": {"time_step": 5e-3},
                          "populations": [{"shape": "mesh", "files": [f"{SCAN_FOLDER}/*.stl"],
                                           "size_definition": "sieve", "volume_fraction": 1.0,
                                           "grading": {"curve": "sieves", "sieves": [8.0, 11.2, 16.0, 22.4],
                                                       "percent_passing": [0.0, 30.0, 75.0, 100.0]}}]},
}


def _scan_files(raw: dict, out: Path) -> Path:
    """Write the scan-like STL files a case's mesh population reads into ``out/SCAN_FOLDER``;
    returns ``out``, the folder its file patterns are relative to."""
    from bench_shapes import write_random_hull_stls, write_scan_like_stls

    if any(p.get("shape") == "mesh" for p in raw["populations"]):
        folder = out / SCAN_FOLDER
        folder.mkdir(parents=True, exist_ok=True)
        write_scan_like_stls(folder)
        write_random_hull_stls(folder)
    return out


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def apply_sets(raw: dict, overrides: list[str]) -> dict:
    """``raw`` (a config's TOML tables as a dict) with each ``SECTION.KEY=VALUE`` (or ``KEY=VALUE``
    for a top-level key) of ``overrides`` set, the value read as JSON where it parses (numbers,
    booleans, lists), else as a string."""
    for item in overrides:
        key, value = item.split("=", 1)
        *section, field = key.split(".")
        (raw.setdefault(section[0], {}) if section else raw)[field] = _value(value)
    return raw


def _timeline(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def _level_one(row: dict) -> bool:
    return (row["max_net_force"] <= LEVEL_ONE["max_net_force"] and row["max_net_torque"] <= LEVEL_ONE["max_net_torque"]
            and row["kinetic_criterion"] <= LEVEL_ONE["kinetic_criterion"]
            and abs(row["wall_force_over_weight"] - 1.0) <= LEVEL_ONE["wall"])


def _at(row: dict | None) -> dict | None:
    if row is None:
        return None
    return {"time": row["time"], "step": int(row["step"]), "wall_seconds": row["wall_seconds"],
            "cpu_seconds": row["cpu_seconds"]}


def run_case(name: str, out: Path, max_time: float, seed: int | None, overrides: list[str]) -> dict:
    raw = json.loads(json.dumps(CASES[name]))
    raw.setdefault("equilibrium", {})["max_time"] = max_time
    if seed is not None:
        raw["seed"] = seed
    apply_sets(raw, overrides)
    config = load_config_dict(raw, source=name, base_dir=_scan_files(raw, out))
    run_dir = out / f"{name}-seed{config.seed}"
    t0, c0 = time.perf_counter(), time.process_time()
    summary = run_packing(config, run_dir, overwrite=True, progress="lines")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rows = _timeline(run_dir / TIMELINE_FILE)
    one = next((r for r in rows if _level_one(r)), None)
    after = [r for r in rows if one is not None and r["time"] > one["time"]]
    return {
        "case": name,
        "seed": config.seed,
        "n_particles": config.n_particles,
        "overrides": overrides,
        "status": summary["status"],
        "level_one": _at(one),
        "level_two": _at(rows[-1]) if summary["status"] == "equilibrium" else None,
        "simulated_time": summary["simulated_time"],
        "steps": summary["steps"],
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "deposit_seconds": summary["timing"]["deposit_seconds"],
        "mean_sweeps": summary["nlgs"]["mean_iterations"],
        "mean_sweeps_after_level_one": (sum(r["mean_sweeps"] for r in after) / len(after)) if after else None,
        "detection_ms_per_step": summary["timing"]["detection_ms_per_step"],
        "solver_ms_per_step": summary["timing"]["solver_ms_per_step"],
        "position_correction_steps": summary["position_correction"]["steps"],
        "final": summary["equilibrium"],
        "run_dir": str(run_dir),
        "timeline": [(r["time"], r["kinetic_energy_total"], r["max_net_force"]) for r in rows],
    }


def timeline_of(run_dir: Path) -> dict:
    """What :func:`figure` needs of a finished run folder: its name and its timeline."""
    rows = _timeline(run_dir / TIMELINE_FILE)
    case, _, seed = run_dir.name.rpartition("-seed")
    return {"case": case or run_dir.name, "seed": seed, "timeline": [(r["time"], r["kinetic_energy_total"],
                                                                      r["max_net_force"]) for r in rows]}


def figure(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_e, ax_f) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for res in results:
        t, ek, force = zip(*res["timeline"])
        label = f"{res['case']} (seed {res['seed']})"
        ax_e.semilogy(t, ek, label=label)
        ax_f.semilogy(t, force, label=label)
    ax_e.set_ylabel("kinetic energy, m g d (total)")
    ax_f.set_ylabel("largest net force, d$^2$ P")
    for level in (1e-3, 1e-4):
        ax_f.axhline(level, color="grey", lw=0.8, ls="--")
    ax_f.set_xlabel("time, sqrt(d/g)")
    ax_e.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", action="append", choices=list(CASES), help="case to run (repeatable; default all)")
    parser.add_argument("--out", type=Path, default=Path("bench-settle"), help="folder for the runs")
    parser.add_argument("--max-time", type=float, default=300.0, help="max_time of every run, sqrt(d/g)")
    parser.add_argument("--seed", type=int, help="seed instead of the case's")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override")
    parser.add_argument("--figure", type=Path, help="timeline figure (PNG/SVG)")
    parser.add_argument("--figure-of", type=Path, action="append", default=[], metavar="RUN_DIR",
                        help="draw the figure of these finished run folders instead of running (repeatable)")
    args = parser.parse_args(argv)
    if args.figure_of:
        if not args.figure:
            parser.error("--figure-of needs --figure")
        figure([timeline_of(d) for d in args.figure_of], args.figure)
        return
    results = []
    for name in args.case or list(CASES):
        res = run_case(name, args.out, args.max_time, args.seed, args.set)
        res["machine"] = {"platform": platform.platform(), "cpus": os.cpu_count()}
        results.append(res)
        print(json.dumps({k: v for k, v in res.items() if k != "timeline"}), flush=True)
    if args.figure:
        figure(results, args.figure)


if __name__ == "__main__":
    main()

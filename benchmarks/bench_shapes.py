"""Benchmark of the grain shapes' cost: contact detection and a whole NSCD step for 1000 grains of
isometric pinacoids, reduced scan-like grains and generated rocks.

Cases (every grain of circumscribed diameter 1 d, each grain's shape drawn at random from the
case's shapes):

- ``pinacoid``: isometric pinacoids (8 vertices);
- ``scan``: 20 scan-like grains, noisy tessellated ellipsoids (642 vertices, axes 1 : 0.55-0.9 :
  0.35-0.6, 3 % radial noise) written as STL and read back as a ``"mesh"`` population reads them,
  hulls reduced to ``max_vertices`` 24;
- ``rock14``, ``rock8``: 10 generated rocks of aspect [1, 1] with 14 faces (24 vertices, the
  default) and 8 faces (12 vertices).

Each case is a dense heap (``bench_contact.push_apart`` of a jittered cubic lattice at a spacing
scaled with the grains' mean volume, random orientations). Reported (JSON on stdout): the
detection's CPU milliseconds per step with a Verlet skin of 0.05 d as in ``bench_contact.py``
(grains moved by 0.002 d between steps), then ``bench_nscd.run_case``'s detection and solver
milliseconds per step of ``granpack.nscd.step`` after ``--settle`` untimed steps.

Usage::

    NUMBA_NUM_THREADS=1 python benchmarks/bench_shapes.py [--steps 30] [--step-steps 10] [--only rock8,pinacoid]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import trimesh  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_contact import _lattice, machine_speed, push_apart, time_detection  # noqa: E402
from bench_nscd import run_case  # noqa: E402

from granpack.box import Box  # noqa: E402
from granpack.nscd import StepParameters  # noqa: E402
from granpack.rotations import random_quaternions  # noqa: E402
from granpack.shapes import Pinacoid, ShapeTable  # noqa: E402
from granpack.shapes.from_mesh import population_grains  # noqa: E402
from granpack.shapes.rock import rock_library  # noqa: E402
from granpack.state import ParticleState  # noqa: E402

#: lattice spacing of isometric pinacoids of size 1 at about contact (bench_contact.py)
PINACOID_SPACING = 0.66


def write_scan_like_stls(folder: Path, count: int = 20, seed: int = 1) -> list[Path]:
    """``count`` noisy tessellated ellipsoids (642 vertices, axes 1 : 0.55-0.9 : 0.35-0.6, 3 %
    radial noise) written as STL files ``grain-KK.stl`` in ``folder``; returns their paths."""
    rng = np.random.default_rng(seed)
    paths = []
    for k in range(count):
        mesh = trimesh.creation.icosphere(3)
        axes = np.array([1.0, rng.uniform(0.55, 0.9), rng.uniform(0.35, 0.6)])
        noise = 1.0 + 0.03 * rng.standard_normal((len(mesh.vertices), 1))
        paths.append(folder / f"grain-{k:02d}.stl")
        trimesh.Trimesh(mesh.vertices * axes * noise, mesh.faces).export(paths[-1])
    return paths


def write_random_hull_stls(folder: Path, count: int = 12, seed: int = 2, points: int = 60) -> list[Path]:
    """``count`` hulls of ``points`` random points each (uniform in an ellipsoid of axes 1 :
    0.6-0.95 : 0.4-0.8, the faceted, irregular grains a crusher makes) written as STL files
    ``hull-KK.stl`` in ``folder``; returns their paths."""
    rng = np.random.default_rng(seed)
    paths = []
    for k in range(count):
        axes = np.array([1.0, rng.uniform(0.6, 0.95), rng.uniform(0.4, 0.8)])
        direction = rng.standard_normal((points, 3))
        direction /= np.linalg.norm(direction, axis=1)[:, None]
        cloud = direction * rng.uniform(0.0, 1.0, (points, 1)) ** (1.0 / 3.0) * axes
        paths.append(folder / f"hull-{k:02d}.stl")
        trimesh.Trimesh(cloud).convex_hull.export(paths[-1])
    return paths


def scan_like_shapes(folder: Path, count: int = 20, seed: int = 1) -> list:
    """The :func:`write_scan_like_stls` of ``folder`` read back as a mesh population's grains
    (hulls reduced to 24 vertices), each at circumscribed diameter 1."""
    paths = write_scan_like_stls(folder, count, seed)
    return [g.shape.scaled(1.0 / g.shape.size) for g in population_grains(paths, 24)]


def heap(shapes: list, n: int, rng: np.random.Generator) -> ParticleState:
    """A dense heap of ``n`` grains, each of a shape drawn from ``shapes``."""
    volume = float(np.mean([s.volume for s in shapes]))
    spacing = PINACOID_SPACING * (volume / Pinacoid.from_size(1.0).volume) ** (1.0 / 3.0)
    lateral = max(4, int(round(n ** (1.0 / 3.0))))
    box = Box.square(lateral * spacing)
    kind = rng.integers(0, len(shapes), n).astype(np.int64)
    state = ParticleState(box=box, shapes=ShapeTable.from_shapes(shapes), kind=kind,
                          population=np.zeros(n, np.int64), position=box.wrap(_lattice(n, spacing, lateral, rng)),
                          quaternion=random_quaternions(n, rng))
    return push_apart(state)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=30, help="timed detections")
    parser.add_argument("--step-steps", type=int, default=10, help="timed NSCD steps")
    parser.add_argument("--settle", type=int, default=5, help="untimed NSCD steps before them")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--only", default=None, help="comma-separated case names")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as folder:
        cases = {
            "pinacoid": lambda: [Pinacoid.from_size(1.0)],
            "scan": lambda: scan_like_shapes(Path(folder)),
            "rock14": lambda: list(rock_library(args.seed, 10, faces=14)),
            "rock8": lambda: list(rock_library(args.seed, 10, faces=8)),
        }
        if args.only:
            cases = {k: v for k, v in cases.items() if k in args.only.split(",")}
        out = {"machine": platform.machine(), "python": platform.python_version(),
               "numba_threads": os.environ.get("NUMBA_NUM_THREADS"), "python_loop_1e6_cpu_seconds": machine_speed(),
               "results": {}}
        for name, make in cases.items():
            t0 = time.perf_counter()
            shapes = make()
            state = heap(shapes, args.n, rng)
            print(f"# built {name} in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
            detection = time_detection(state, 0.05, args.steps, 0.002, rng)
            stepped = run_case(name, state.copy(), args.settle, args.step_steps, StepParameters())
            out["results"][name] = {
                "vertices": float(np.mean([len(s.vertices) for s in shapes])),
                "edge_directions": float(np.mean([len(s.edge_directions) for s in shapes])),
                "face_axes": float(np.mean([len(s.face_axes) for s in shapes])),
                "detection_cpu_ms": 1e3 * detection["cpu_seconds_per_step_median"],
                "pairs_tested": detection["pairs_tested"],
                "manifolds": detection["contacts"],
                "step_detection_ms": stepped["detection_ms"],
                "step_solver_ms": stepped["solver_ms"],
                "step_points": stepped["points"],
            }
            print(json.dumps({name: out["results"][name]}), file=sys.stderr, flush=True)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()

"""Benchmark of contact detection (granpack.contact) on dense pinacoid configurations.

Prints one JSON document with, for each configuration, the number of grains, candidate pairs,
pairs tested by the narrow phase, contact manifolds and points found, and the seconds per
detection step (mean, median and fastest step) without a Verlet skin (grid search every step)
and with a skin (pair list reused while no grain has moved more than half the skin).

Configurations (the simulation that settles a packing is not used here):

- ``iso1000``, ``iso3000``: isometric pinacoids (size 1, L/G = G/E = 1).
- ``bidisperse3000``: isometric pinacoids of sizes 1 and 1/3, 30 % small by volume.

Dense configuration, built without dynamics: grains are put on a jittered cubic lattice at about
contact spacing (the small grains of the mix on a finer lattice in the space left by the large
ones) with uniformly random orientations, then overlapping grains are pushed apart along their
contact normals (half the penetration depth each, weighted by the other grain's volume; grains
below the wall are lifted) for a fixed number of sweeps, using the detector itself. The result is
a dense, slightly overlapping heap with many face, edge and vertex contacts, i.e. the same work
for the narrow phase as a settled packing. ``--gsd PATH`` times a settled packing instead
(read with :func:`granpack.io.gsd.read_packing`).

The "step" with a skin applies a random displacement of ``--move`` d (and a small random
rotation) to every grain before each detection, as during settling, so the timing includes the
pair-list rebuilds that the motion triggers.

Usage::

    NUMBA_NUM_THREADS=1 python benchmarks/bench_contact.py [--steps 30] [--skin 0.05] [--gsd PATH]

``NUMBA_NUM_THREADS`` sets the narrow-phase threads (default: every CPU).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import platform
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from granpack.box import Box  # noqa: E402
from granpack.contact import Detector, detect  # noqa: E402
from granpack.rotations import quat_from_axis_angle, quat_multiply, random_quaternions  # noqa: E402
from granpack.shapes import Pinacoid, ShapeTable  # noqa: E402
from granpack.state import ParticleState  # noqa: E402

ALERT = 0.02


def _lattice(n: int, spacing: float, lateral: int, rng: np.random.Generator) -> np.ndarray:
    cells = np.array(list(itertools.product(range(lateral), range(lateral), range(n // lateral**2 + 1))), float)
    cells = cells[np.lexsort((cells[:, 0], cells[:, 1], cells[:, 2]))][:n]
    return (cells + 0.5) * spacing + rng.uniform(-0.05, 0.05, size=(n, 3)) * spacing


def build_dense(n: int, small_volume_share: float, rng: np.random.Generator, sweeps: int = 100,
                spacing: float = 0.66) -> ParticleState:
    """A dense heap of ``n`` isometric pinacoids (see the module docstring)."""
    large, small = Pinacoid.from_size(1.0), Pinacoid.from_size(1.0 / 3.0)
    ratio = small.volume / large.volume
    # number of large grains for the volume share: n_s ratio / (n_s ratio + n_l) = share
    n_large = int(round(n / (1.0 + small_volume_share / (1.0 - small_volume_share) / ratio))) if small_volume_share else n
    n_small = n - n_large
    lateral = max(4, int(round((n_large + n_small * ratio) ** (1 / 3) * 1.0)))
    box = Box.square(lateral * spacing)
    pos_l = _lattice(n_large, spacing, lateral, rng)
    pos = [pos_l]
    if n_small:
        fine = spacing / 3.0
        nf = 3 * lateral
        candidates = _lattice(n_small * 4, fine, nf, rng)
        # keep the fine sites outside the large grains' inscribed region
        keep = []
        for k, p in enumerate(candidates):
            d = box.minimum_image(pos_l - p) if len(pos_l) else np.full((1, 3), 10.0)
            if len(pos_l) == 0 or np.min(np.linalg.norm(d, axis=1)) > 0.42:
                keep.append(k)
            if len(keep) == n_small:
                break
        pos.append(candidates[keep])
        if len(keep) < n_small:  # stack what is left above
            extra = _lattice(n_small - len(keep), fine, nf, rng)
            extra[:, 2] += max(p[:, 2].max() for p in pos) + fine
            pos.append(extra)
    pos = np.vstack(pos)
    kind = np.r_[np.zeros(n_large, np.int64), np.ones(n_small, np.int64)]
    state = ParticleState(box=box, shapes=ShapeTable.from_shapes([large, small]), kind=kind,
                          population=kind.copy(), position=box.wrap(pos), quaternion=random_quaternions(n, rng))
    return push_apart(state, sweeps)


def push_apart(state: ParticleState, sweeps: int = 100) -> ParticleState:
    """``state`` with overlapping grains pushed apart along their contact normals (half the
    penetration depth each, weighted by the other grain's volume; grains below the wall lifted),
    for at most ``sweeps`` sweeps (in place; returned)."""
    box = state.box
    volume = state.shapes.volume[state.kind]
    for _ in range(sweeps):
        cs = detect(state, 0.0)
        if cs.n_manifolds == 0:
            break
        depth = np.minimum.reduceat(cs.gap, cs.point_start[:-1]) if cs.n_points else np.zeros(0)
        push = np.maximum(-depth, 0.0)
        move = np.zeros_like(state.position)
        i, j = cs.body_i, cs.body_j
        wall = j < 0
        vi = volume[i]
        vj = np.where(wall, 0.0, volume[np.maximum(j, 0)])
        wi = np.where(wall, 1.0, vj / (vi + vj))
        np.add.at(move, i, (0.55 * push * wi)[:, None] * cs.normal)
        jj = ~wall
        np.add.at(move, j[jj], -(0.55 * push[jj] * (1.0 - wi[jj]))[:, None] * cs.normal[jj])
        state.position = box.wrap(state.position + move)
    return state


def time_detection(state: ParticleState, skin: float, steps: int, move: float, rng: np.random.Generator) -> dict:
    """Seconds per detection step (mean, median and fastest over ``steps``), with random small moves
    between steps. The median and the fastest step are the figures to compare on a shared machine,
    and the median CPU time of the process (``process_time``, one thread), which other processes on
    the machine disturb far less than the wall time."""
    state = state.copy()
    det = Detector(skin=skin)
    det.detect(state, ALERT)  # compile / warm up and build the first list
    builds0 = det.n_builds
    times, cpu = [], []
    cs = None
    for _ in range(steps):
        state.position = state.box.wrap(state.position + rng.normal(scale=move / math.sqrt(3), size=state.position.shape))
        axes = rng.normal(size=(state.n, 3))
        turn = np.array([quat_from_axis_angle(a, move) for a in axes])
        state.quaternion = quat_multiply(turn, state.quaternion)
        t0, c0 = time.perf_counter(), time.process_time()
        cs = det.detect(state, ALERT, cs)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {
        "skin": skin,
        "seconds_per_step": float(np.mean(times)),
        "seconds_per_step_median": float(np.median(times)),
        "seconds_per_step_min": float(np.min(times)),
        "cpu_seconds_per_step_median": float(np.median(cpu)),
        "candidate_pairs": det.n_candidates,
        "pairs_tested": det.n_tested,
        "contacts": cs.n_manifolds,
        "contact_points": cs.n_points,
        "contact_types": {str(t): int(np.sum(cs.ctype == t)) for t in (1, 2, 3)},
        "list_builds": det.n_builds - builds0,
        "steps": steps,
    }


def machine_speed() -> float:
    """CPU seconds of a plain Python loop of 1e6 additions: VMs of the same kind differ in pace by
    factors of up to 2.5, so timings are compared only between runs with similar values."""
    c0 = time.process_time()
    total = 0
    for k in range(1_000_000):
        total += k
    return time.process_time() - c0


def describe(state: ParticleState) -> dict:
    cs = detect(state, 0.0)
    depth = -cs.gap.min() if cs.n_points else 0.0
    return {"grains": state.n, "box": [state.box.lx, state.box.ly], "height": float(state.position[:, 2].max()),
            "max_overlap": float(max(depth, 0.0))}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--skin", type=float, default=0.05)
    parser.add_argument("--move", type=float, default=0.002, help="random displacement per step, d")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--gsd", default=None, help="time a settled packing read from this GSD file instead")
    parser.add_argument("--only", default=None, help="comma-separated configuration names")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    if args.gsd:
        from granpack.io.gsd import read_packing

        configs = {os.path.basename(args.gsd): read_packing(args.gsd).state}
    else:
        wanted = {"iso1000": (1000, 0.0), "iso3000": (3000, 0.0), "bidisperse3000": (3000, 0.3)}
        if args.only:
            wanted = {k: v for k, v in wanted.items() if k in args.only.split(",")}
        configs = {}
        for name, (n, share) in wanted.items():
            t0 = time.perf_counter()
            configs[name] = build_dense(n, share, rng)
            print(f"# built {name} in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    out = {"alert": ALERT, "move_per_step": args.move, "machine": platform.machine(), "python": platform.python_version(),
           "numba_threads": os.environ.get("NUMBA_NUM_THREADS"), "python_loop_1e6_cpu_seconds": machine_speed(),
           "results": {}}
    for name, state in configs.items():
        res = describe(state)
        res["skin0"] = time_detection(state, 0.0, args.steps, args.move, rng)
        res["verlet"] = time_detection(state, args.skin, args.steps, args.move, rng)
        out["results"][name] = res
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()

"""Benchmark of :func:`granpack.analysis.analyze_packing` on a 3000-grain pinacoid packing.

Prints one JSON document: the packing (grains, manifolds, contact points, height), the wall-clock
seconds of the first call (includes Numba compilation unless the on-disk cache is warm), of the
next ``--repeat`` calls (best and mean), and the seconds of each analysis alone (best of the
repeats), so that the expensive part is visible.

Packing: by default a synthetic one built like ``tests/packing_builders.random_pinacoids``:
3000 isometric pinacoids, sizes 1 and 1/3 (30 % of the grains small, two populations), random
centres in an 8 x 8 x ``--height`` d slab, uniformly random orientations and 1.5 random contact
manifolds per grain (1 to 4 points, small overlaps, random compressive forces). Its geometry is
not a settled packing, but the work of every analysis (slice volumes of every grain, pair
histogram of the bulk slab, order tensors, contact counting, equilibrium sums) scales the same
way. ``--gsd PATH`` times a settled packing written by a run instead.

Usage::

    NUMBA_NUM_THREADS=1 python benchmarks/bench_analyze.py [--repeat 3] [--gsd PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from granpack.analysis import (  # noqa: E402
    AnalysisOptions,
    Coordination,
    Equilibrium,
    Homogeneity,
    Interpenetration,
    Order,
    PairCorrelation,
    SolidFraction,
    analyze_packing,
)
from granpack.box import Box  # noqa: E402
from granpack.contact.contacts import ContactSet  # noqa: E402
from granpack.packing import Packing  # noqa: E402
from granpack.rotations import random_quaternions  # noqa: E402
from granpack.shapes import Pinacoid, ShapeTable  # noqa: E402
from granpack.state import ParticleState  # noqa: E402

H = 5e-3


def build(n: int, rng: np.random.Generator, lateral: float = 8.0, height: float = 10.0, small_fraction: float = 0.3,
          contacts_per_particle: float = 3.0) -> Packing:
    """Random bidisperse pinacoid packing with random contacts (see the module docstring)."""
    big = Pinacoid.family("isometric", 1.0)
    small = Pinacoid.family("isometric", 1.0 / 3.0)
    kind = (rng.random(n) < small_fraction).astype(np.int64)
    pos = np.column_stack([rng.random(n) * lateral, rng.random(n) * lateral, 0.5 + rng.random(n) * (height - 1.0)])
    state = ParticleState(box=Box.square(lateral), shapes=ShapeTable.from_shapes([big, small]), kind=kind,
                          population=kind.copy(), position=pos, quaternion=random_quaternions(n, rng))
    m = int(contacts_per_particle * n / 2)
    i, j = rng.integers(0, n, m), rng.integers(0, n, m)
    keep = i != j
    i, j = i[keep], j[keep]
    m = len(i)
    npts = rng.integers(1, 5, m)
    start = np.concatenate([[0], np.cumsum(npts)]).astype(np.int64)
    delta = state.box.minimum_image(pos[i] - pos[j])
    normal = delta / np.linalg.norm(delta, axis=1)[:, None]
    shift = pos[i] - delta - pos[j]
    seg = np.repeat(np.arange(m), npts)
    p = int(start[-1])
    contacts = ContactSet(body_i=i.astype(np.int64), body_j=j.astype(np.int64), shift=shift, normal=normal,
                          ctype=np.minimum(npts, 3).astype(np.int64), point_start=start,
                          point=pos[j][seg] + shift[seg] + 0.5 * delta[seg] + 0.01 * rng.standard_normal((p, 3)),
                          gap=-1e-4 * rng.random(p), impulse=H * normal[seg] * rng.random(p)[:, None])
    return Packing(state, contacts, H, ["large", "small"], {"seed": 11})


def _time(func, repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        func()
        out.append(time.perf_counter() - t)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=3000, help="grains of the synthetic packing")
    parser.add_argument("--height", type=float, default=10.0, help="height of the synthetic slab, d")
    parser.add_argument("--repeat", type=int, default=3, help="timed calls after the first one")
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--gsd", type=str, default=None, help="time this packing (final.gsd of a run) instead")
    args = parser.parse_args()

    if args.gsd:
        from granpack.io.gsd import read_packing

        packing = read_packing(args.gsd)
        source = args.gsd
    else:
        packing = build(args.n, np.random.default_rng(args.seed), height=args.height)
        source = f"synthetic random pinacoids, n={args.n}, 8 x 8 x {args.height:g} d"

    warnings.simplefilter("ignore")
    opt = AnalysisOptions()
    t0 = time.perf_counter()
    result = analyze_packing(packing, opt)
    first = time.perf_counter() - t0
    times = _time(lambda: analyze_packing(packing, opt), args.repeat)

    sf = SolidFraction().compute(packing)
    z_range = (sf.z_bottom, sf.z_top) if sf.has_bulk else (0.0, 0.0)
    r_max = min(opt.rdf_r_max, 0.5 * min(packing.box.lx, packing.box.ly))
    parts = {
        "solid_fraction": lambda: SolidFraction().compute(packing),
        "pair_correlation": lambda: PairCorrelation(int(round(r_max / opt.rdf_bin_width)), r_max, z_range).compute(packing),
        "order (incl. isotropic baseline)": lambda: Order(z_range).compute(packing),
        "coordination": lambda: Coordination(z_range).compute(packing),
        "equilibrium": lambda: Equilibrium().compute(packing),
        "interpenetration": lambda: Interpenetration().compute(packing),
        "homogeneity": lambda: Homogeneity(1.0, z_range).compute(packing),
    }
    part_times = {name: min(_time(f, max(args.repeat, 1))) for name, f in parts.items()}

    print(json.dumps({
        "benchmark": "analyze_packing",
        "source": source,
        "machine": {"python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count()},
        "grains": packing.n_particles,
        "manifolds": packing.contacts.n_manifolds,
        "points": packing.contacts.n_points,
        "bulk": [result["bulk"]["z_bottom"], result["bulk"]["z_top"]],
        "first_call_s": round(first, 3),
        "best_s": round(min(times), 3) if times else None,
        "mean_s": round(float(np.mean(times)), 3) if times else None,
        "parts_best_s": {k: round(v, 4) for k, v in part_times.items()},
        "target_s": 30.0,
    }, indent=2))


if __name__ == "__main__":
    main()

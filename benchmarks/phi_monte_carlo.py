"""An independent check of a packing's solid fraction: random points inside the grains.

    python benchmarks/phi_monte_carlo.py RUN_DIR_OR_GSD [...] [--points 2000000] [--seed 0]

The solid fraction granpack reports (``granpack.analysis.solid_fraction``) sums, slice by slice,
the exact volume of every grain cut by horizontal planes, from the shape tables' volumes and
vertices. This script measures the same bulk region another way, with nothing in common but the
grains' positions, orientations and face planes: it throws uniform random points into the bulk
slab and tests each against the grains near it (a point is inside a polyhedron when
``n_f . R^T (p - x) <= offset_f`` for all its faces, inside a sphere when ``|p - x| <= r``; the
cell is periodic in x and y). Two figures come out:

- ``phi_sum``: the mean number of grains covering a point, the quantity the exact sum measures
  (an overlap counted twice), which must agree with it within the sampling error;
- ``phi_union``: the share of points inside at least one grain, the solid fraction with the
  overlaps counted once; ``phi_sum - phi_union`` is the volume the overlaps double-count, an
  exact, geometric counterpart of the virtual-work correction ``phi / (1 + k)``.

Prints one JSON object per run: the exact bulk phi, the two estimates with their standard errors
(binomial for the union, of the mean for the sum), the slab and the number of points.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from granpack.analysis.solid_fraction import SolidFraction
from granpack.io.gsd import read_packing
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix

CHUNK = 200_000


def coverage(packing: Packing, points: np.ndarray) -> np.ndarray:
    """``(M,)`` number of grains of ``packing`` that contain each of ``points`` ``(M, 3)`` (d)."""
    state = packing.state
    table = state.shapes
    lx, ly = state.box.lx, state.box.ly
    centres = state.position.copy()
    centres[:, 0] %= lx
    centres[:, 1] %= ly
    z_span = 4.0 * (float(np.max(np.abs(centres[:, 2]))) + float(np.max(np.abs(points[:, 2]))) + 1.0)
    shifted = centres + np.array([0.0, 0.0, z_span / 2])
    wrapped = points + np.array([0.0, 0.0, z_span / 2])
    wrapped[:, 0] %= lx
    wrapped[:, 1] %= ly
    rotation = quat_to_matrix(state.quaternion)
    count = np.zeros(len(points), dtype=np.int64)
    for kind in np.unique(state.kind):
        grains = np.flatnonzero(state.kind == kind)
        tree = cKDTree(shifted[grains], boxsize=(lx, ly, z_span))
        lists = tree.query_ball_point(wrapped, r=float(table.radius[kind]), return_sorted=False)
        lengths = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(lists))
        if not lengths.sum():
            continue
        point_of = np.repeat(np.arange(len(points)), lengths)
        grain_of = grains[np.concatenate([np.asarray(x, dtype=np.int64) for x in lists if len(x)])]
        offset = points[point_of] - centres[grain_of]
        offset[:, 0] -= lx * np.round(offset[:, 0] / lx)
        offset[:, 1] -= ly * np.round(offset[:, 1] / ly)
        if table.is_sphere[kind]:
            inside = np.einsum("ij,ij->i", offset, offset) <= table.radius[kind] ** 2
        else:
            body = np.einsum("nji,nj->ni", rotation[grain_of], offset)
            rows = slice(table.face_start[kind], table.face_start[kind + 1])
            inside = np.all(body @ table.face_normals[rows].T <= table.face_offsets[rows], axis=1)
        np.add.at(count, point_of[inside], 1)
    return count


def check(packing: Packing, n_points: int, rng: np.random.Generator) -> dict:
    """The exact bulk phi of ``packing`` beside its Monte Carlo estimates (module docstring)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sf = SolidFraction().compute(packing)
    if not sf.has_bulk:
        raise ValueError(sf.no_bulk_reason)
    box = packing.state.box
    z0, z1 = sf.z_bottom, sf.z_top
    covered = np.empty(0, dtype=np.int64)
    for start in range(0, n_points, CHUNK):
        m = min(CHUNK, n_points - start)
        pts = rng.random((m, 3)) * np.array([box.lx, box.ly, z1 - z0]) + np.array([0.0, 0.0, z0])
        covered = np.concatenate([covered, coverage(packing, pts)])
    union = float(np.mean(covered > 0))
    return {
        "slab": [z0, z1],
        "points": n_points,
        "phi_exact": sf.bulk,
        "phi_sum": float(covered.mean()),
        "phi_sum_se": float(covered.std(ddof=1) / np.sqrt(n_points)),
        "phi_union": union,
        "phi_union_se": float(np.sqrt(union * (1 - union) / n_points)),
        "points_in_two_or_more": float(np.mean(covered > 1)),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", type=Path, help="run folders (their final.gsd) or GSD files")
    p.add_argument("--points", type=int, default=2_000_000, help="random points per run")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    for run in args.runs:
        path = run / "final.gsd" if run.is_dir() else run
        if not path.is_file():
            print(f"error: {path}: no such file", file=sys.stderr)
            return 2
        try:
            out = {"run": str(run), **check(read_packing(path), args.points, rng)}
        except ValueError as exc:
            print(f"error: {run}: {exc}", file=sys.stderr)
            return 2
        out["difference_sum"] = out["phi_sum"] - out["phi_exact"]
        print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

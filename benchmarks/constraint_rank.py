"""Independent contact constraints of a packing: the global rank against the contact-type count.

Usage::

    python benchmarks/constraint_rank.py RUN_DIR_OR_GSD [...]

For each packing (``final.gsd`` of a run folder, or a GSD file), over the whole pile: the
force-bearing points (the points ``granpack analyze`` counts contact types from:
``force_bearing_points`` of force-bearing manifolds) give the columns of the equilibrium matrix
``H`` (6 rows per grain: ``n`` and ``a × n`` on grain i, their opposites on j; the wall has no
rows). Prints the number of points, the rank of ``H`` (singular values above 1e-9 of the
largest), the sum over the manifolds of the rank of their own columns (what the contact types
count: Ns + 2 Nd + 3 Nt summed), and the excess of that sum over the global rank: constraints
the type count takes as independent although the grains' 6 N degrees of freedom cannot hold
them (degenerate contacts). Dense SVD: about 90 s for 1000 grains.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from granpack.analysis.coordination import force_bearing, force_bearing_points
from granpack.io.gsd import read_packing


def constraint_matrix(packing) -> tuple[np.ndarray, np.ndarray]:
    """``(H (6N, P'), manifold of each column)`` over the force-bearing points."""
    state, contacts = packing.state, packing.contacts
    points = np.nonzero(force_bearing_points(packing) & force_bearing(packing)[contacts.point_manifold])[0]
    manifold = contacts.point_manifold[points]
    h = np.zeros((6 * state.n, len(points)))
    for col, (q, m) in enumerate(zip(points, manifold)):
        i, j, normal = contacts.body_i[m], contacts.body_j[m], contacts.normal[m]
        h[6 * i:6 * i + 3, col] = normal
        h[6 * i + 3:6 * i + 6, col] = np.cross(contacts.point[q] - state.position[i], normal)
        if j >= 0:
            h[6 * j:6 * j + 3, col] = -normal
            h[6 * j + 3:6 * j + 6, col] = -np.cross(contacts.point[q] - (state.position[j] + contacts.shift[m]), normal)
    return h, manifold


def main(paths: list[str]) -> None:
    for arg in paths:
        path = Path(arg)
        packing = read_packing(path / "final.gsd" if path.is_dir() else path)
        h, manifold = constraint_matrix(packing)
        loaded = h[np.abs(h).sum(axis=1) > 0]
        singular = np.linalg.svd(loaded, compute_uv=False)
        rank = int((singular > 1e-9 * singular.max()).sum())
        counted = 0
        for m in np.unique(manifold):
            cols = h[:, manifold == m]
            counted += int(np.linalg.matrix_rank(cols, tol=1e-9 * np.abs(cols).max())) if cols.shape[1] > 1 else 1
        print(f"{arg}: {packing.state.n} grains ({len(loaded) // 6} loaded), {h.shape[1]} force-bearing points, "
              f"global rank {rank}, type count {counted}, excess {counted - rank} ({(counted - rank) / rank:.1%})")


if __name__ == "__main__":
    main(sys.argv[1:])

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
them (degenerate contacts).

Then where the dependent constraints sit: each manifold's columns are replaced by an orthonormal
basis of their span (so that a face's four coplanar points count 3, as the types do), and the
null space of that reduced matrix (its self-stresses, dimension = the excess) is spread over the
manifolds, each getting the squared norm of its components. A manifold is *face-parallel* when
both grains have a face whose normal is within 1 degree of the contact normal (a flat face on
the wall counts for the wall's side). Prints the share of the manifolds, and of the self-stress
weight, that are face-parallel, and the weight by manifold rank. Dense SVDs: about 3 min for
1000 grains.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from granpack.analysis.coordination import force_bearing, force_bearing_points
from granpack.io.gsd import read_packing
from granpack.rotations import quat_to_matrix

#: a manifold is face-parallel when both grains have a face within this angle of its normal, deg
PARALLEL_DEG = 1.0


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


def self_stress_weights(h: np.ndarray, manifold: np.ndarray, n_manifolds: int) -> tuple[np.ndarray, np.ndarray]:
    """``(weight (M,), rank (M,))``: each manifold's share of the self-stress space, and its own rank.

    The columns of every manifold are replaced by an orthonormal basis of their span; the right
    null space ``V0`` of the result (``B v = 0``) is the space of self-stresses between manifolds,
    and manifold ``m`` gets ``sum |V0[rows of m]|^2`` (the weights sum to the null dimension).
    """
    rows = np.abs(h).sum(axis=1) > 0
    blocks, owner = [], []
    rank = np.zeros(n_manifolds, np.int64)
    for m in np.unique(manifold):
        u, s, _ = np.linalg.svd(h[:, manifold == m][rows], full_matrices=False)
        r = int((s > 1e-9 * s.max()).sum())
        blocks.append(u[:, :r])
        owner += [m] * r
        rank[m] = r
    reduced = np.hstack(blocks)
    _, s, vt = np.linalg.svd(reduced, full_matrices=True)
    r = int((s > 1e-9 * s.max()).sum())
    weight = np.zeros(n_manifolds)
    np.add.at(weight, np.array(owner), (vt[r:] ** 2).sum(axis=0))
    return weight, rank


def face_misalignment(packing, m: int) -> float:
    """Largest over the manifold's two grains of the smallest angle (deg) between a face normal
    and the contact normal (0 for the wall's side): small when the two touching faces are parallel."""
    state, contacts, table = packing.state, packing.contacts, packing.state.shapes
    n = contacts.normal[m]
    worst = 0.0
    for body in (contacts.body_i[m], contacts.body_j[m]):
        if body < 0:
            continue
        k = state.kind[body]
        normals = table.face_normals[table.face_start[k]:table.face_start[k + 1]] @ quat_to_matrix(state.quaternion[body]).T
        if len(normals) == 0:
            return 90.0  # a sphere has no face
        worst = max(worst, float(np.degrees(np.arccos(min(1.0, np.abs(normals @ n).max())))))
    return worst


def main(paths: list[str]) -> None:
    for arg in paths:
        path = Path(arg)
        packing = read_packing(path / "final.gsd" if path.is_dir() else path)
        h, manifold = constraint_matrix(packing)
        loaded = h[np.abs(h).sum(axis=1) > 0]
        singular = np.linalg.svd(loaded, compute_uv=False)
        rank = int((singular > 1e-9 * singular.max()).sum())
        weight, own_rank = self_stress_weights(h, manifold, packing.contacts.n_manifolds)
        counted = int(own_rank.sum())
        print(f"{arg}: {packing.state.n} grains ({len(loaded) // 6} loaded), {h.shape[1]} force-bearing points, "
              f"global rank {rank}, type count {counted}, excess {counted - rank} ({(counted - rank) / rank:.1%})")
        loaded_manifolds = np.unique(manifold)
        parallel = np.array([face_misalignment(packing, m) < PARALLEL_DEG for m in loaded_manifolds])
        w = weight[loaded_manifolds]
        by_rank = ", ".join(f"rank {k} {w[own_rank[loaded_manifolds] == k].sum() / w.sum():.2f}" for k in (1, 2, 3))
        print(f"  face-parallel (both faces within {PARALLEL_DEG:g} deg of the normal): {parallel.mean():.1%} of the "
              f"{len(loaded_manifolds)} force-bearing manifolds, {w[parallel].sum() / w.sum():.1%} of the self-stress "
              f"weight ({by_rank}); wall manifolds {(packing.contacts.body_j[loaded_manifolds] < 0).sum()}, their "
              f"weight {w[packing.contacts.body_j[loaded_manifolds] < 0].sum() / w.sum():.1%}")


if __name__ == "__main__":
    main(sys.argv[1:])

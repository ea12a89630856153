"""The whole pile's contact constraints against its grains' degrees of freedom: a frictionless
pile in general position at rest has at most as many as the grains that carry force can hold.

Usage::

    python benchmarks/constraint_count.py RUN_DIR_OR_GSD [...] [--weight-share S]

For each packing (``final.gsd`` of a run folder, or a GSD file), over every grain and with no
rattler removed: the force-bearing manifolds (:func:`granpack.analysis.coordination.force_bearing`;
with ``--weight-share S`` only those whose normal force exceeds S times the weight of their
smaller grain, a wall pair its grain's), counted as one constraint each between spheres and as
the rank of their force-bearing points (``Ns + 2 Nd + 3 Nt``, the analysis' force rule) between
polyhedra, against 3 (spheres) or 6 (polyhedra) degrees of freedom per grain that carries force.
Prints one JSON line per packing: ``constraints``, ``degrees_of_freedom``, their ratio, the grains.
Unlike :mod:`constraint_rank` (a dense SVD of the equilibrium matrix) it takes a second on 3000
grains: a count, not a rank.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from granpack.analysis.coordination import force_bearing, type_rules
from granpack.io.gsd import read_packing


def constraint_count(packing, weight_share: float = 0.0) -> dict:
    """``{constraints, degrees_of_freedom, ratio, grains_carrying, grains}`` of ``packing``."""
    contacts, state = packing.contacts, packing.state
    body_j = contacts.body_j
    active = force_bearing(packing)
    if weight_share > 0:
        weight = state.mass * packing.gravity
        smaller = np.where(body_j >= 0, np.minimum(weight[contacts.body_i], weight[np.maximum(body_j, 0)]),
                           weight[contacts.body_i])
        active &= packing.manifold_normal_force > weight_share * smaller
    carrying = np.zeros(state.n, bool)
    carrying[contacts.body_i[active]] = True
    carrying[body_j[active & (body_j >= 0)]] = True
    spheres = bool(state.shapes.is_sphere[state.kind].all())
    constraints = int(active.sum()) if spheres else int(type_rules(packing)["force"][active].sum())
    dof = (3 if spheres else 6) * int(carrying.sum())
    return {"constraints": constraints, "degrees_of_freedom": dof, "ratio": constraints / dof if dof else float("nan"),
            "grains_carrying": int(carrying.sum()), "grains": int(state.n)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("packings", nargs="+", help="run folders or GSD files")
    parser.add_argument("--weight-share", type=float, default=0.0,
                        help="count only contacts carrying more than this share of their smaller grain's weight")
    args = parser.parse_args()
    for name in args.packings:
        path = Path(name)
        packing = read_packing(path / "final.gsd" if path.is_dir() else path)
        print(json.dumps({"packing": name, **constraint_count(packing, args.weight_share)}))


if __name__ == "__main__":
    main()

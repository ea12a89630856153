"""Where the grains of a mixture touch each other: contacts by the populations of their two grains.

Usage::

    python benchmarks/pair_contacts.py RUN_DIR_OR_GSD [...] [--json OUT.json]

For each packing (a run folder's ``final.gsd`` or a packing GSD) prints, per population of the
bulk's backbone grains (rattlers removed, as :class:`~granpack.analysis.Coordination` removes
them) and per population of the grain they touch, the mean number of force-bearing contacts per
grain by type: ``Ns`` (simple: vertex-face, or a sphere's point), ``Nd`` (double: edge-face or
edge-edge) and ``Nt`` (triple: face-face), and ``N`` their sum; then each population's rattler
fraction and its share of the bulk's grains against its share of the pile's. A small grain that
sits in a large one's void touches large grains by vertices; one wedged between faces touches
them face to face: this is where a mixture's density is won or lost.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from granpack.analysis import Coordination
from granpack.analysis.coordination import force_bearing
from granpack.analysis.solid_fraction import analysed_region, in_region
from granpack.io.gsd import read_packing
from granpack.io.run_folder import FINAL_FILE


def pair_contacts(packing) -> dict:
    """``{population: {partner: {N, Ns, Nd, Nt}, "rattler_fraction", "bulk_share", "pile_share",
    "n_bulk"}}``: force-bearing contacts per backbone bulk grain of ``population`` with grains of
    ``partner``, by type, and the population's rattlers and shares of the grain count."""
    co = Coordination().compute(packing)
    c = packing.contacts
    population = packing.state.population
    names = packing.population_names
    bulk = in_region(packing, analysed_region(packing, None))
    backbone = bulk & ~co.rattlers
    types = co.types
    live = force_bearing(packing) & (types > 0)
    live &= ~co.rattlers[c.body_i] & ~((c.body_j >= 0) & co.rattlers[np.maximum(c.body_j, 0)])
    pair = live & (c.body_j >= 0)
    n = packing.n_particles
    out = {}
    for p, name in enumerate(names):
        grains = backbone & (population == p)
        n_grains = int(grains.sum())
        row = {}
        for q, partner in enumerate(names):
            counts = np.zeros((n, 3))
            for t in range(3):
                # contacts seen from body i with a partner j of population q, and from body j
                sel = pair & (types == t + 1)
                from_i = sel & (population[np.maximum(c.body_j, 0)] == q)
                from_j = sel & (population[c.body_i] == q)
                counts[:, t] += np.bincount(c.body_i[from_i], minlength=n)
                counts[:, t] += np.bincount(c.body_j[from_j], minlength=n)
            mean = counts[grains].mean(axis=0) if n_grains else np.full(3, np.nan)
            row[partner] = {"N": float(mean.sum()), "Ns": float(mean[0]), "Nd": float(mean[1]), "Nt": float(mean[2])}
        members = bulk & (population == p)
        row["n_bulk"] = int(members.sum())
        row["rattler_fraction"] = float((members & co.rattlers).sum() / members.sum()) if members.any() else float("nan")
        row["bulk_share"] = float(members.sum() / bulk.sum()) if bulk.any() else float("nan")
        row["pile_share"] = float((population == p).sum() / n)
        out[name] = row
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("packings", nargs="+", type=Path, help="run folders (their final.gsd) or packing GSD files")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures of every packing here")
    args = parser.parse_args()
    every = {}
    for path in args.packings:
        gsd = path / FINAL_FILE if path.is_dir() else path
        figures = pair_contacts(read_packing(gsd))
        every[str(path)] = figures
        print(f"\n{gsd}")
        names = list(figures)
        print(f"{'grain':<8} " + "  ".join(f"{'with ' + q + ': N (Ns/Nd/Nt)':<30}" for q in names)
              + "  rattlers  bulk/pile share")
        for p in names:
            row = figures[p]
            cells = "  ".join(f"{row[q]['N']:5.2f} ({row[q]['Ns']:4.2f}/{row[q]['Nd']:4.2f}/{row[q]['Nt']:4.2f})".ljust(30)
                              for q in names)
            print(f"{p:<8} {cells}  {row['rattler_fraction']:7.3f}  {row['bulk_share']:.3f}/{row['pile_share']:.3f}")
    if args.json:
        args.json.write_text(json.dumps(every, indent=1) + "\n")


if __name__ == "__main__":
    main()

"""Coordination numbers of a packing under each contact-type rule, and their sensitivity.

Usage::

    python benchmarks/contact_types.py RUN_DIR_OR_GSD [...]

For each ``final.gsd`` (or any packing GSD) prints, over the bulk grains, N / Ns / Nd / Nt / Nc on
the backbone and with the rattlers, and the rattler fraction, for the types from the
force-bearing points (at several point thresholds ``point_tol``, then at several manifold
thresholds ``force_tol``, relative to the mean manifold force), from the gap rule (at several gap
tolerances) and from detection; then by the count of force-bearing points per contact (1 / 2 / 3+:
simple / double / triple), as an NSCD code that keeps at most four points per face contact and
types a contact by how many of them carry force would report it (its polygon's points beyond
three count as three, so the cap changes no type); then the distribution of the point normal forces relative to the
largest one of their manifold, which is what ``point_tol`` cuts, and that of the manifold forces
relative to their mean, which is what ``force_tol`` cuts (the NLGS converges to a relative
tolerance of 1e-4, so a manifold force below about 1e-4 of the mean is within its noise).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from granpack.analysis import Coordination
from granpack.analysis.coordination import (
    _backbone,
    _figures,
    _manifold_max,
    force_bearing,
    force_bearing_points,
    point_normal_force,
)
from granpack.analysis.solid_fraction import bulk_range
from granpack.io.gsd import read_packing


def _row(label: str, backbone: dict, with_rattlers: dict, rattlers: float) -> str:
    def f(d):
        return " / ".join(f"{d[k]:5.2f}" for k in ("N", "Ns", "Nd", "Nt", "Nc"))

    return f"{label:<28} {f(backbone)}   {f(with_rattlers)}   {rattlers:5.3f}"


def point_count_types(packing, point_tol: float = 1e-3) -> np.ndarray:
    """``(M,)`` type of each manifold by its number of force-bearing points: 1, 2, or 3 for three
    or more (0: none)."""
    c = packing.contacts
    bearing = force_bearing_points(packing, point_tol).astype(np.int64)
    per_manifold = np.add.reduceat(bearing, c.point_start[:-1]) if c.n_points else np.zeros(c.n_manifolds, np.int64)
    per_manifold[np.diff(c.point_start) == 0] = 0
    return np.minimum(per_manifold, 3)


def point_count_figures(packing, z_range: tuple[float, float]) -> tuple[dict, dict, float]:
    """Backbone and with-rattler N / Ns / Nd / Nt / Nc of the bulk grains, types by point count."""
    z = packing.state.position[:, 2]
    analysed = (z >= z_range[0]) & (z <= z_range[1])
    active = force_bearing(packing)
    counts_all, counts, removed = _backbone(packing, active, point_count_types(packing), analysed, True)
    n = int(analysed.sum())
    return (_figures(counts[analysed & ~removed]), _figures(counts_all[analysed]),
            float(removed.sum() / n) if n else float("nan"))


def report(path: Path) -> None:
    gsd = path / "final.gsd" if path.is_dir() else path
    packing = read_packing(gsd)
    z_bot, z_top, valid = bulk_range(packing)
    print(f"\n{gsd}: {packing.n_particles} grains, {packing.contacts.n_manifolds} manifolds, "
          f"{packing.contacts.n_points} points, bulk z = {z_bot:.2f} .. {z_top:.2f} d")
    print(f"{'rule':<28} {'backbone N / Ns / Nd / Nt / Nc':<35}   {'with rattlers':<35}   rattlers")
    base = Coordination((z_bot, z_top)).compute(packing)
    print(_row("detection (geometric)", base.by_rule["geometric"], base.by_rule["geometric"]["with_rattlers"],
               base.by_rule["geometric"]["rattler_fraction"]))
    for point_tol in (0.0, 1e-6, 1e-3, 1e-2, 1e-1):
        co = Coordination((z_bot, z_top), point_tol=point_tol).compute(packing)
        print(_row(f"force, point_tol {point_tol:g}", co.figures, co.with_rattlers, co.rattler_fraction))
    for force_tol in (1e-6, 1e-4, 1e-3, 1e-2):
        co = Coordination((z_bot, z_top), force_tol=force_tol).compute(packing)
        print(_row(f"force, force_tol {force_tol:g}", co.figures, co.with_rattlers, co.rattler_fraction))
    for gap_tol in (1e-5, 1e-4, 1e-3):
        co = Coordination((z_bot, z_top), gap_tol=gap_tol).compute(packing)
        g = co.by_rule["gap_rule"]
        print(_row(f"gap rule, gap_tol {gap_tol:g}", g, g["with_rattlers"], g["rattler_fraction"])
              + f"   same type as force: {g['same_type_as_force']:.3f}")
    backbone, with_rattlers, rattlers = point_count_figures(packing, (z_bot, z_top))
    print(_row("points per contact 1/2/3+", backbone, with_rattlers, rattlers))
    c = packing.contacts
    fn = point_normal_force(packing)
    active = force_bearing(packing)[c.point_manifold]
    ratio = fn[active] / _manifold_max(fn, c.point_start)[active]
    edges = np.array([0.0, 1e-9, 1e-6, 1e-4, 1e-3, 1e-2, 1e-1, 1.0])
    counts = np.bincount(np.searchsorted(edges, ratio, side="left"), minlength=len(edges))
    labels = ["<= 0", "(0, 1e-9]", "(1e-9, 1e-6]", "(1e-6, 1e-4]", "(1e-4, 1e-3]", "(1e-3, 1e-2]", "(1e-2, 0.1]", "(0.1, 1]"]
    print("points of force-bearing manifolds by f_n / max f_n of their manifold: "
          + ", ".join(f"{lab}: {n}" for lab, n in zip(labels, counts)))
    fm = packing.manifold_normal_force
    positive = fm[fm > 0]
    if len(positive):
        counts = np.bincount(np.searchsorted(edges, positive / positive.mean(), side="left"), minlength=len(edges) + 1)
        labels = labels[1:] + ["> 1"]
        print("force-bearing manifolds by F_n / mean F_n: " + ", ".join(f"{lab}: {n}" for lab, n in zip(labels, counts[1:])))
    if not valid:
        print("warning: no valid bulk region")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("packings", nargs="+", type=Path, help="run folders (their final.gsd) or packing GSD files")
    for packing_path in parser.parse_args().packings:
        report(packing_path)

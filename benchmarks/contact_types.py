"""Coordination numbers of a packing under each contact-type rule, and their sensitivity.

Usage::

    python benchmarks/contact_types.py RUN_DIR_OR_GSD [...]
    python benchmarks/contact_types.py --split-doubles RUN_DIR_OR_GSD [...]

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

``--split-doubles`` prints instead, over the bulk backbone, the figures with every double contact
whose force rests on two points of very unequal force counted as two simple contacts: a two-point
manifold (exactly two force-bearing points) whose smaller point force is below ``ratio`` times the
larger one counts as two simple contacts of one constraint each (N + 1, Ns + 2, Nd - 1 per such
contact, Nc and the rattlers unchanged), for several ratios; and the two-point doubles per grain by
the ratio of their point forces. It tests whether a code that reports each point of an edge-face
contact as a contact of its own, when one of them carries little, would count granpack's piles
with more simple and fewer double contacts.
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


SPLIT_RATIOS = (1e-3, 1e-2, 0.05, 0.08, 0.1, 0.2, 0.5, 1.0)


def two_point_ratio(packing, point_tol: float = 1e-3) -> np.ndarray:
    """``(M,)`` smaller over larger normal force of the two force-bearing points of every manifold
    that has exactly two (nan for the others)."""
    c = packing.contacts
    bearing = force_bearing_points(packing, point_tol)
    fn = np.where(bearing, point_normal_force(packing), np.nan)
    counts = np.diff(c.point_start)
    n_bearing = np.zeros(c.n_manifolds, np.int64)
    nonempty = counts > 0
    n_bearing[nonempty] = np.add.reduceat(bearing.astype(np.int64), c.point_start[:-1][nonempty])
    ratio = np.full(c.n_manifolds, np.nan)
    two = np.flatnonzero(n_bearing == 2)
    for m in two:
        f = fn[c.point_start[m]:c.point_start[m + 1]]
        f = f[np.isfinite(f)]
        ratio[m] = f.min() / f.max()
    return ratio


def split_double_figures(packing, z_range: tuple[float, float], ratios=SPLIT_RATIOS, target: float | None = None) -> dict:
    """Backbone figures of the bulk with the two-point doubles below each force ratio counted as two
    simple contacts; ``{"base": figures, "split": {ratio: (figures, split per grain)},
    "two_point_doubles": per grain}``, and with ``target`` (split contacts per grain)
    ``"target_ratio"``, the least ratio that splits that many."""
    from granpack.analysis.solid_fraction import analysed_region, in_region

    co = Coordination(z_range).compute(packing)
    c = packing.contacts
    n = packing.n_particles
    analysed = in_region(packing, analysed_region(packing, z_range))
    backbone = analysed & ~co.rattlers
    removed = co.rattlers
    live = force_bearing(packing) & ~removed[c.body_i] & ~((c.body_j >= 0) & removed[np.maximum(c.body_j, 0)])
    ratio = two_point_ratio(packing, co.point_tol)
    doubles2 = live & (co.types == 2) & np.isfinite(ratio)

    def per_grain(sel):
        out = np.bincount(c.body_i[sel], minlength=n).astype(float)
        pair = sel & (c.body_j >= 0)
        return out + np.bincount(c.body_j[pair], minlength=n)

    base = _figures(co.per_particle[backbone])
    out = {"base": base, "two_point_doubles": float(per_grain(doubles2)[backbone].mean()), "split": {}}
    if target is not None:
        candidates = np.flatnonzero(doubles2)
        ends = backbone[c.body_i[candidates]].astype(float) + np.where(c.body_j[candidates] >= 0, backbone[np.maximum(c.body_j[candidates], 0)], False)
        order = np.argsort(ratio[candidates])
        reached = np.cumsum(ends[order]) / backbone.sum()
        k = int(np.searchsorted(reached, target))
        out["target_ratio"] = float(ratio[candidates][order][min(k, len(order) - 1)])
        ratios = tuple(sorted(set(ratios) | {np.nextafter(out["target_ratio"], np.inf)}))
    for r in ratios:
        s = per_grain(doubles2 & (ratio < r))
        counts = co.per_particle.copy()
        counts[:, 0] += 2 * s
        counts[:, 1] -= s
        out["split"][r] = (_figures(counts[backbone]), float(s[backbone].mean()))
    return out


def report_split(path: Path, target: float | None = None) -> None:
    gsd = path / "final.gsd" if path.is_dir() else path
    packing = read_packing(gsd)
    z_bot, z_top, valid = bulk_range(packing)
    res = split_double_figures(packing, (z_bot, z_top), target=target)
    b = res["base"]
    print(f"\n{gsd}: bulk z = {z_bot:.2f} .. {z_top:.2f} d{'' if valid else ' (no valid bulk region)'}")
    print(f"granpack's types: N / Ns / Nd / Nt / Nc = {b['N']:.2f} / {b['Ns']:.2f} / {b['Nd']:.2f} / {b['Nt']:.2f} / "
          f"{b['Nc']:.2f}; two-point doubles per grain {res['two_point_doubles']:.3f} of Nd {b['Nd']:.3f}")
    print(f"{'split below ratio':<18} {'split per grain':>15}   N / Ns / Nd / Nt / Nc")
    for r, (f, s) in res["split"].items():
        print(f"{r:<18.3g} {s:15.3f}   {f['N']:.2f} / {f['Ns']:.2f} / {f['Nd']:.2f} / {f['Nt']:.2f} / {f['Nc']:.2f}")
    if "target_ratio" in res:
        print(f"{target:g} split contacts per grain: the two-point doubles whose weaker point carries up to "
              f"{res['target_ratio']:.3f} of the stronger")


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
    parser.add_argument("--split-doubles", action="store_true",
                        help="count the two-point doubles of unequal point forces as two simple contacts, at several force ratios")
    parser.add_argument("--target", type=float, default=None,
                        help="with --split-doubles: the least force ratio that splits this many contacts per grain")
    args = parser.parse_args()
    for packing_path in args.packings:
        if args.split_doubles:
            report_split(packing_path, args.target)
        else:
            report(packing_path)

"""Polydisperse frictionless spheres against the random close packing of Desmond & Weeks.

Desmond & Weeks (Phys. Rev. E 90, 022204, 2014) fitted the random close packing fraction of
frictionless spheres, packed by compression, to the polydispersity ``δ`` (standard deviation of
the radius over its mean) and the skewness ``S`` (third central moment of the radius over the
cube of its standard deviation), both by number, for δ up to 0.4:

    φ_RCP = 0.634 + 0.0658 δ + 0.0857 S δ²

This script compares it with the bulk solid fraction of granpack's poured, frictionless piles at
rest: the finished runs kept in ``benchmarks/validation/runs/rcp`` (lognormal distributions,
``benchmarks/validation/rcp.toml``) and ``benchmarks/validation/runs/grading`` (the
Fuller spheres of ``examples/grading.toml``), and the sphere mixtures of the study campaign
(``benchmarks/study/spheres-small-*``: one size, and d with d/3 in every proportion). δ and S are those of the sizes each run poured,
recomputed from its config.

Usage::

    python benchmarks/rcp.py            # one JSON object per run, then one per mixture
    python benchmarks/rcp.py table      # the markdown table of docs/gradings.md, a row per mixture
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

from granpack.config import load_config_dict
from granpack.mixture import Mixture

HERE = Path(__file__).resolve().parent
RUNS = (HERE / "validation" / "runs" / "rcp", HERE / "validation" / "runs" / "grading",
        *sorted((HERE / "study").glob("spheres-small-*")))
#: Desmond & Weeks' fit: φ* and the coefficients of δ and S δ²
PHI_STAR, C1, C2 = 0.634, 0.0658, 0.0857
#: the largest polydispersity of their fit
DELTA_FITTED = 0.4


def desmond_weeks(delta: float, skewness: float) -> float:
    """φ_RCP of frictionless spheres of polydispersity ``delta`` and skewness ``skewness``."""
    return PHI_STAR + C1 * delta + C2 * skewness * delta * delta


def size_moments(sizes: np.ndarray) -> tuple[float, float]:
    """``(δ, S)`` of the sizes, by number (the radius's are the diameter's)."""
    mean = float(sizes.mean())
    centred = sizes - mean
    var = float(np.mean(centred**2))
    if var == 0.0:
        return 0.0, 0.0
    return var**0.5 / mean, float(np.mean(centred**3)) / var**1.5


def run_row(run_dir: Path) -> dict | None:
    """The comparison of one finished sphere run, None if it is not a finished sphere run."""
    analysis_file, task_file = run_dir / "analysis.json", run_dir / "task.json"
    if not (analysis_file.is_file() and task_file.is_file()):
        return None
    task = json.loads(task_file.read_text())
    config = load_config_dict(task["config"], source=str(task_file))
    if any(p.shape != "sphere" for p in config.populations):
        return None
    mixture = Mixture.from_config(config)
    sizes = np.concatenate([np.full(c, float(p.size or 0.0)) if s is None else s
                            for p, c, s in zip(mixture.populations, mixture.counts, mixture.sizes)])
    delta, skewness = size_moments(sizes)
    analysis = json.loads(analysis_file.read_text())
    phi = analysis["solid_fraction"]["bulk"]
    predicted = desmond_weeks(delta, skewness)
    return {
        "mixture": task["mixture"], "seed": task["seed"], "n_particles": config.n_particles,
        "status": analysis["status"], "delta": delta, "skewness": skewness,
        "phi_bulk": phi, "phi_std": analysis["solid_fraction"]["std"],
        "k": analysis["interpenetration"]["expansion_k"],
        "phi_desmond_weeks": predicted, "gap": phi / predicted - 1.0,
        "in_fit_range": delta <= DELTA_FITTED,
    }


def rows() -> list[dict]:
    """Every finished sphere run of ``RUNS``, by family (the mixture's name without its last
    part), polydispersity and seed."""
    found = []
    for root in RUNS:
        for analysis in sorted(root.glob("**/analysis.json")):
            row = run_row(analysis.parent)
            if row is not None:
                found.append(row)
    return sorted(found, key=lambda r: (r["mixture"].rsplit("-", 1)[0], r["delta"], r["mixture"], r["seed"]))


def by_mixture(runs: list[dict]) -> list[dict]:
    """Mean over the seeds of each mixture (``phi_seeds_std``: their spread, 0 for one seed)."""
    out = []
    for name in dict.fromkeys(r["mixture"] for r in runs):
        group = [r for r in runs if r["mixture"] == name]
        phis = [r["phi_bulk"] for r in group]
        first = group[0]
        out.append({
            "mixture": name, "seeds": len(group), "delta": first["delta"], "skewness": first["skewness"],
            "phi_bulk": statistics.fmean(phis), "phi_seeds_std": statistics.stdev(phis) if len(phis) > 1 else 0.0,
            "phi_desmond_weeks": first["phi_desmond_weeks"],
            "gap": statistics.fmean(phis) / first["phi_desmond_weeks"] - 1.0,
            "in_fit_range": first["in_fit_range"],
        })
    return out


def table(mixtures: list[dict]) -> str:
    """Markdown: a row per mixture."""
    lines = ["| mixture | seeds | δ | S | granpack bulk φ | Desmond & Weeks φ_RCP | gap |",
             "|---|---|---|---|---|---|---|"]
    for m in mixtures:
        spread = f" ± {m['phi_seeds_std']:.4f}" if m["seeds"] > 1 else ""
        note = "" if m["in_fit_range"] else " (δ beyond the fit)"
        lines.append(f"| {m['mixture']} | {m['seeds']} | {m['delta']:.3f} | {m['skewness']:.2f} | "
                     f"{m['phi_bulk']:.4f}{spread} | {m['phi_desmond_weeks']:.4f}{note} | {100 * m['gap']:+.1f} % |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("command", nargs="?", choices=["json", "table"], default="json")
    args = parser.parse_args(argv)
    runs = rows()
    if args.command == "table":
        print(table(by_mixture(runs)))
        return
    for row in runs + by_mixture(runs):
        print(json.dumps(row))


if __name__ == "__main__":
    main()

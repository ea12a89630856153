"""The example campaign of gradings, run by run: the table of docs/gradings.md.

Reads the finished runs kept in ``benchmarks/validation/runs/grading`` (``examples/grading.toml``:
Fuller curves of exponents 0.3 to 0.7 for spheres and isometric pinacoids) and prints, a row per
run, what the docs table shows: the bulk solid fraction and the spread of its layers, the
coordination N over the grains in contact (and Nc for the polyhedra), the rattler fraction, N and
the rattler fraction per size class (smallest to largest, the classes of ``analysis.json``'s
``size_classes``), the expansion coefficient k, Q00 (polyhedra) and the time at rest.

Usage::

    python benchmarks/gradings.py            # one JSON object per run
    python benchmarks/gradings.py table      # the markdown table
    python benchmarks/gradings.py compare    # pinacoids against spheres of the same curve; N over all grains
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNS = HERE / "validation" / "runs" / "grading"


def run_row(run_dir: Path) -> dict | None:
    """The figures of one finished run (``None`` for a run not finished or without size classes)."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
        analysis = json.loads((run_dir / "analysis.json").read_text())
    except FileNotFoundError:
        return None
    classes = analysis.get("size_classes")
    if classes is None:
        return None
    coordination = analysis["coordination"]
    return {
        "mixture": run_dir.parent.name, "seed": int(run_dir.name.removeprefix("seed-")),
        "status": summary["status"], "t": summary["simulated_time"], "cpu_hours": summary["cpu_time"] / 3600,
        "phi": analysis["solid_fraction"]["bulk"], "phi_std": analysis["solid_fraction"]["std"],
        "N": coordination["N"], "Nc": coordination["Nc"], "rattlers": coordination["rattler_fraction"],
        "N_all": coordination["with_rattlers"]["N"],
        "class_N": classes["coordination"], "class_rattlers": classes["rattler_fraction"],
        "k": analysis["interpenetration"]["expansion_k"], "Q00": analysis["order"]["Q00"],
    }


def rows(runs: Path = RUNS) -> list[dict]:
    """Every finished run under ``runs`` (``MIXTURE/seed-S``), spheres first, by exponent."""
    found = (run_row(d) for d in sorted(runs.glob("*/seed-*")))
    return sorted((r for r in found if r is not None), key=lambda r: (not r["mixture"].startswith("spheres"), r["mixture"]))


def table(runs: list[dict]) -> str:
    """The markdown table of the runs."""
    lines = ["| mixture | bulk φ (± spread of its layers) | N | Nc | rattlers | N per class, smallest to largest "
             "| rattlers per class | k | Q00 | at rest at t |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in runs:
        at_rest = f"{r['t']:g}" if r["status"] == "equilibrium" else f"not at rest ({r['t']:g})"
        q00 = "–" if r["Q00"] is None else f"{r['Q00']:.3f}"  # spheres have no orientation
        lines.append(
            f"| {r['mixture']} | {r['phi']:.4f} ± {r['phi_std']:.4f} | {r['N']:.2f} | {r['Nc']:.2f} "
            f"| {100 * r['rattlers']:.1f} % | {' / '.join(f'{n:.1f}' for n in r['class_N'])} "
            f"| {' / '.join(f'{100 * f:.0f} %' for f in r['class_rattlers'])} | {r['k']:.1e} | {q00} "
            f"| {at_rest} |")
    return "\n".join(lines)


def compare(runs: list[dict]) -> str:
    """The pinacoids' bulk φ less the spheres' of the same Fuller exponent, and the spheres' N on
    the backbone and over all bulk grains."""
    phi = {r["mixture"]: r["phi"] for r in runs}
    lines = []
    for r in runs:
        if r["mixture"].startswith("pinacoids-"):
            spheres = "spheres-" + r["mixture"].removeprefix("pinacoids-")
            if spheres in phi:
                lines.append(f"{r['mixture']}: {r['phi']:.4f} - {phi[spheres]:.4f} = {r['phi'] - phi[spheres]:+.4f}")
    for r in runs:
        if r["mixture"].startswith("spheres-"):
            lines.append(f"{r['mixture']}: N {r['N']:.2f} on the backbone, {r['N_all']:.2f} over all bulk grains")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", nargs="?", choices=["runs", "table", "compare"], default="runs")
    args = parser.parse_args(argv)
    found = rows()
    if args.what == "table":
        print(table(found))
    elif args.what == "compare":
        print(compare(found))
    else:
        for r in found:
            print(json.dumps(r))


if __name__ == "__main__":
    main()

"""The figures docs/validation.md sets beside the study's, computed from the kept runs.

Each action prints what the page quotes, from the kept study runs (``benchmarks/study/``), the
kept final states (``benchmarks/validation/runs/``) and the study's published figures
(``STUDY_PHI`` of ``benchmarks/sensitivity.py``, its text and tables as the page quotes them):

- ``gaps``: granpack's bulk solid fraction per mixture (mean ± standard deviation over the three
  seeds of the study campaign) beside the study's raw φ and its overlap-corrected φ_min, the gaps,
  the spheres against the molecular-dynamics figure the study compares its spheres with, the
  30 % small pinacoid peak under the study's overlap corrections (a conditional: the study gives
  none for that mixture) and what each family gains from one size to 30 % small grains;
- ``convention``: the expansion coefficient k that each of the study's four pairs (raw φ, φ_min)
  implies under each reading, ``phi_min = phi / (1 + k)`` (granpack's: a vertical strain) and
  ``phi_min = phi / (1 + k)^3`` (an isotropic strain), against the study's stated
  k = 0.80 ± 0.47 %;
- ``fit``: the fit N(Q00) = N0 + (N1 - N0)(1 - exp(-Q00/Qc)) over every kept pinacoid run of the
  study campaign (as ``granpack figures`` draws it) and the levels each shape series reaches at
  its largest shares;
- ``fall RUN_DIR ...``: how far the grains of a kept run fall in its pour: the top of its deposit
  (made again from its config and seed: shells' centres plus radii), the height of its pile at
  the end (``summary.json``) and their difference, the fall of the top grains, in d;
- ``sphere-rattlers [RUN_DIR ...]``: N of the sphere mixtures on the backbone and over all bulk
  grains (from the kept analyses), and, for kept sphere final states, how many force-bearing
  contacts the grains removed as rattlers had.

Usage::

    python benchmarks/study_comparison.py gaps
    python benchmarks/study_comparison.py convention
    python benchmarks/study_comparison.py fit
    python benchmarks/study_comparison.py fall benchmarks/study/*-100/seed-1 benchmarks/study/pinacoids-small-0/seed-1
    python benchmarks/study_comparison.py sphere-rattlers benchmarks/validation/runs/sensitivity/width-x3_spheres-small-30/seed-*
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
KEPT = ROOT / "benchmarks" / "study"
sys.path.insert(0, str(ROOT / "benchmarks"))
from sensitivity import STUDY_PHI  # noqa: E402

#: the study's expansion coefficient over its pinacoid packings, mean and standard deviation (%)
STUDY_K = (0.80, 0.47)
#: frictionless molecular dynamics of spheres d and d/3, 30 % small by volume, which the study
#: compares its spheres with (Roux's figure, as the study cites it)
MD_SPHERES_30 = 0.7207
#: the study's fit of N against Q00 over its pinacoid packings: N0, N1, Qc
STUDY_FIT = (7.4, 9.2, 0.2)
#: the shape series and the shares (%) whose N the page reads as each series' level
SERIES_LEVEL = {"flat": (77, 92, 100), "flat-elongated": (50, 70, 100), "elongated": (49, 70, 100)}


def _runs(mixture: str) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((KEPT / mixture).glob("seed-*/analysis.json"))]


def granpack_phi(mixture: str) -> tuple[float, float]:
    """Mean and sample standard deviation of the bulk φ over the kept runs of ``mixture``."""
    phi = [a["solid_fraction"]["bulk"] for a in _runs(mixture)]
    return statistics.fmean(phi), statistics.stdev(phi)


def _pct(x: float) -> str:
    return f"{100 * x:+.1f} %"


def gaps() -> None:
    print("| mixture | granpack | study raw | study phi_min | gap to raw | gap to phi_min |")
    print("|---|---|---|---|---|---|")
    for mixture, (raw, raw_std, corrected) in STUDY_PHI.items():
        mean, std = granpack_phi(mixture)
        to_min = _pct(mean / corrected - 1) if corrected else "-"
        print(f"| {mixture} | {mean:.4f} ± {std:.4f} | {raw} ± {raw_std} | {corrected or '-'} | "
              f"{_pct(mean / raw - 1)} | {to_min} |")
    print("\nthe study's own correction phi / phi_min - 1:")
    for mixture, (raw, _, corrected) in STUDY_PHI.items():
        if corrected:
            print(f"  {mixture}: {_pct(raw / corrected - 1)}")
    spheres, _ = granpack_phi("spheres-small-30")
    raw_spheres = STUDY_PHI["spheres-small-30"][0]
    print(f"\nspheres 30 % small against molecular dynamics {MD_SPHERES_30}: granpack {_pct(spheres / MD_SPHERES_30 - 1)}, "
          f"the study {_pct(raw_spheres / MD_SPHERES_30 - 1)}")
    peak, _ = granpack_phi("pinacoids-small-30")
    raw_peak = STUDY_PHI["pinacoids-small-30"][0]
    corrections = {m: raw / c - 1 for m, (raw, _, c) in STUDY_PHI.items() if c}
    lo, hi = min(corrections.values()), max(corrections.values())
    print(f"\n30 % small pinacoids: granpack {peak:.4f}, the study's raw {raw_peak}: {_pct(peak / raw_peak - 1)}")
    print(f"  the correction that would make them meet: {_pct(raw_peak / peak - 1)}")
    for label, c in (("smallest", lo), ("largest", hi)):
        print(f"  with the study's {label} correction of its other packings ({_pct(c)}): phi_min {raw_peak / (1 + c):.4f}, "
              f"gap {_pct(peak * (1 + c) / raw_peak - 1)}")
    one_sphere, _ = granpack_phi("spheres-small-0")
    one_pin, _ = granpack_phi("pinacoids-small-0")
    raw_one = STUDY_PHI["pinacoids-small-0"][0]
    print(f"\ngain from one size to 30 % small d/3: granpack spheres {_pct(spheres / one_sphere - 1)} "
          f"({one_sphere:.4f} to {spheres:.4f}), pinacoids {_pct(peak / one_pin - 1)} ({one_pin:.4f} to {peak:.4f}); "
          f"the study's pinacoids {_pct(raw_peak / raw_one - 1)} ({raw_one} to {raw_peak})")
    gain, study_gain = peak / one_pin, raw_peak / raw_one
    print(f"the peak's gap {_pct(peak / raw_peak - 1)} = one size {_pct(one_pin / raw_one - 1)} and the gain "
          f"{gain:.3f} against {study_gain:.3f}: {_pct(gain / study_gain - 1)}")


def convention() -> None:
    mean, std = STUDY_K
    print(f"the study's k: {mean} ± {std} %")
    print("| mixture | raw phi | phi_min | phi / phi_min | k if phi_min = phi/(1+k) | (in std) | k if phi_min = phi/(1+k)^3 | (in std) |")
    print("|---|---|---|---|---|---|---|---|")
    for mixture, (raw, _, corrected) in STUDY_PHI.items():
        if not corrected:
            continue
        ratio = raw / corrected
        linear, cubic = 100 * (ratio - 1), 100 * (ratio ** (1 / 3) - 1)
        bound = " (at least: raw 'slightly above')" if mixture == "flat-elongated-100" else ""
        print(f"| {mixture}{bound} | {raw} | {corrected} | {ratio:.4f} | {linear:.2f} % | {(linear - mean) / std:+.1f} | "
              f"{cubic:.2f} % | {(cubic - mean) / std:+.1f} |")


def _pinacoid_runs() -> list[tuple[str, float, float]]:
    out = []
    for path in sorted(KEPT.glob("*/seed-*/analysis.json")):
        if path.parent.parent.name.startswith("spheres"):
            continue
        a = json.loads(path.read_text())
        out.append((path.parent.parent.name, a["order"]["Q00"], a["coordination"]["N"]))
    return out


def fit() -> None:
    from granpack.analysis.fit import ExponentialFit

    runs = _pinacoid_runs()
    q = np.array([r[1] for r in runs])
    n = np.array([r[2] for r in runs])
    f = ExponentialFit().compute(q, n)
    e = f.stderr
    print(f"{len(runs)} pinacoid runs: N0 = {f.N0:.2f} ± {e['N0']:.2f}, N1 = {f.N1:.2f} ± {e['N1']:.2f}, "
          f"Qc = {f.Qc:.3f} ± {e['Qc']:.3f}, rms {f.rms:.3f}; the study's: N0 = {STUDY_FIT[0]}, N1 = {STUDY_FIT[1]}, "
          f"Qc = {STUDY_FIT[2]}")
    for family, shares in SERIES_LEVEL.items():
        rows = [(m, qq, nn) for m, qq, nn in runs if m in {f"{family}-{s}" for s in shares}]
        nn = [r[2] for r in rows]
        qq = [r[1] for r in rows]
        print(f"{family} at {', '.join(map(str, shares))} %: N {statistics.fmean(nn):.2f} ± {statistics.stdev(nn):.2f} "
              f"(runs {len(rows)}, from {min(nn):.2f} to {max(nn):.2f}), Q00 {min(qq):.3f} to {max(qq):.3f}; "
              f"fit at their mean Q00: {float(f.predict(np.array([statistics.fmean(qq)]))[0]):.2f}")


def sphere_rattlers(run_dirs: list[Path]) -> None:
    print("kept analyses, sphere mixtures (means over seeds): backbone N / N over all bulk grains / rattlers")
    for mixture in sorted({p.parent.name for p in KEPT.glob("spheres-small-*/seed-*")}, key=lambda m: int(m.rsplit("-", 1)[1])):
        runs = _runs(mixture)
        print(f"  {mixture}: {statistics.fmean(a['coordination']['N'] for a in runs):.2f} / "
              f"{statistics.fmean(a['coordination']['with_rattlers']['N'] for a in runs):.2f} / "
              f"{statistics.fmean(a['coordination']['rattler_fraction'] for a in runs):.1%}")
    if not run_dirs:
        return
    from granpack.analysis import Coordination
    from granpack.analysis.coordination import force_bearing
    from granpack.analysis.solid_fraction import analysed_region, bulk_range, in_region
    from granpack.io.gsd import read_packing

    for run in run_dirs:
        packing = read_packing(run / "final.gsd" if run.is_dir() else run)
        z_bot, z_top, _ = bulk_range(packing)
        co = Coordination((z_bot, z_top)).compute(packing)
        c = packing.contacts
        active = force_bearing(packing)
        n = packing.n_particles
        contacts = np.bincount(c.body_i[active], minlength=n) + np.bincount(c.body_j[active & (c.body_j >= 0)], minlength=n)
        analysed = in_region(packing, analysed_region(packing, (z_bot, z_top)))
        rattlers = analysed & co.rattlers
        hist = np.bincount(np.minimum(contacts[rattlers], 4), minlength=5)
        print(f"\n{run}: {analysed.sum()} bulk grains, backbone N {co.N:.3f}, over all bulk grains {co.with_rattlers['N']:.3f}, "
              f"rattlers {rattlers.sum()} ({co.rattler_fraction:.1%})")
        print("  rattlers by force-bearing contacts 0 / 1 / 2 / 3 / 4+: " + " / ".join(str(int(h)) for h in hist)
              + f"; mean {contacts[rattlers].mean():.2f}")
        held = analysed & ~co.rattlers
        print(f"  bulk grains with 3 or more contacts (the rattler rule's 4 less one): N over them "
              f"{contacts[analysed & (contacts >= 3)].mean():.3f}; backbone grains' own contacts {contacts[held].mean():.3f}")


def fall(run_dirs: list[Path]) -> None:
    from granpack.config import load_config_dict
    from granpack.simulation import initial_state

    print("| run | cell (d) | grains | deposit top (d) | its centre of mass (d) | pile height at the end (d) | fall of the top grains (d) |")
    print("|---|---|---|---|---|---|---|")
    for run in run_dirs:
        task = json.loads((run / "task.json").read_text())
        config = load_config_dict(task["config"], source=str(run / "task.json"))
        state, _ = initial_state(config)
        radius = state.shapes.radius[state.kind]
        top = float((state.position[:, 2] + radius).max())
        volume = state.shapes.volume[state.kind]
        z_g = float((volume * state.position[:, 2]).sum() / volume.sum())
        height = json.loads((run / "summary.json").read_text())["final"]["height"]
        print(f"| {run} | {config.lateral_size:g} | {config.n_particles} | {top:.1f} | {z_g:.1f} | "
              f"{height:.2f} | {top - height:.0f} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("gaps", help="granpack's solid fractions beside the study's, and the gains from small grains")
    sub.add_parser("convention", help="the k each of the study's (phi, phi_min) pairs implies under each reading")
    sub.add_parser("fit", help="the N(Q00) fit over the kept pinacoid runs and the shape series' levels")
    falls = sub.add_parser("fall", help="deposit top, pile height and the top grains' fall of kept runs")
    falls.add_argument("runs", nargs="+", type=Path, help="kept run folders (task.json, summary.json)")
    rattlers = sub.add_parser("sphere-rattlers", help="N of the sphere piles on the backbone and over all grains")
    rattlers.add_argument("runs", nargs="*", type=Path, help="kept sphere run folders with a final.gsd")
    args = parser.parse_args(argv)
    if args.action == "gaps":
        gaps()
    elif args.action == "convention":
        convention()
    elif args.action == "fit":
        fit()
    elif args.action == "fall":
        fall(args.runs)
    else:
        sphere_rattlers(args.runs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

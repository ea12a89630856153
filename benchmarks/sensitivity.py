"""The sensitivity study behind docs/validation.md: how each free choice of the protocol moves the packing.

Each factor is varied alone against the default protocol of ``examples/study.toml``, whose runs
(seeds 1-3, kept in ``benchmarks/study/``) are the reference cell of every comparison. The
campaign files in ``benchmarks/validation/configs/`` are written from ``examples/study.toml`` by
this script (``configs``), so that a varied run differs from its reference in the one setting
its factor names:

- ``regime-lmgc``: the contact regime of the study's engine, overlaps left as the velocity-level
  law leaves them (``overlap.recovery_rate = 0``, ``overlap.projection_slop =
  overlap.pour_projection_slop = 0``);
- ``cell-study``: the study's cells, 8 d for flat and flat & elongated grains, 10 d for
  elongated ones, with the same 3000 grains (thin beds);
- ``width-x3``: three times the cell area and three times the grains (9000);
- ``deposit-lmgc``: LMGC90's deposit rule instead of the drop;
- ``engine-lmgc``: the study engine's elements granpack can take, all together (its regime, a
  fixed step, its rotation update, its plain NLGS), at the study's size on the 30 % small
  pinacoids, the mixture whose light grains a plain Gauss–Seidel relaxes slowest;
- ``time-600``: the study runs stopped at the cap of 300 sqrt(d/g), run again from their seed with
  a cap of 600 (one campaign file per seed, since each such run has its own seed);
- ``size-ratio``, ``small-23``, ``tapping``, ``end-game-off`` (``bidisperse.toml``, two seeds, and
  ``bidisperse-one-seed.toml``): why granpack's pinacoids gain less from small grains than its
  spheres. The 30 % small mixtures of both families with small grains of d/2 and d/5 (mixtures
  ``...-ratio-R``; the study's d/3 is the default), the 23 % small pinacoids, and the 30 % small
  pinacoids poured with restitution 0.5 (the pile shaken by its own rebounds while it collapses)
  or settled without the end game's damping. A mixture whose small grains change is given the
  cell and grain count of :func:`validate_pinacoids.plan_cell` (an expected column of 8 d, a cell
  of at least 3 d), as the study's own mixtures were;
- ``screen-*``: where the study's overlaps come from, screened on 1000 one-size isometric
  pinacoids (a third of the study's cell area, its bed height): granpack's default, the study
  engine's regime, and that regime with each further element of the study's engine granpack can
  take; on 1000 flat pinacoids, the default and all those elements together (``screening.toml``;
  their own default run is their reference, and their solid fractions, of 1000 grains, are not
  drawn beside the study's).

A mixture of a sensitivity campaign is named ``FACTOR_MIXTURE`` (``regime-lmgc_pinacoids-small-30``);
its ``family`` is the factor, its ``share`` the mixture's.

Usage::

    python benchmarks/sensitivity.py configs                 # (re)write benchmarks/validation/configs/
    benchmarks/validation/run.sh OUT sensitivity 'regime-lmgc_*'  # run, keeping the runs in the repository
    python benchmarks/sensitivity.py csv                      # benchmarks/validation/sensitivity.csv
    python benchmarks/sensitivity.py table                    # its markdown table, a row per cell
    python benchmarks/sensitivity.py status                   # every planned run: finished, checkpointed (at t) or not started
    python benchmarks/sensitivity.py figure                   # docs/validation/figures/sensitivity.png
    python benchmarks/sensitivity.py rerun-check RUN_DIR ...  # a time-600 run repeats its study run to t = 300?
    python benchmarks/sensitivity.py drift                    # how far the capped study runs were still settling
    python benchmarks/sensitivity.py thin-beds                # the series as the study's cells would measure them
    python benchmarks/sensitivity.py bed RUN_DIR ...          # bed.json of a run without a bulk region, from final.gsd
    python benchmarks/sensitivity.py layers RUN_DIR ...       # phi and Q00 layer by layer of final.gsd (phi of the profile without it)
    python benchmarks/sensitivity.py k-deepest RUN_DIR ...    # k beside k with each manifold's points at its deepest overlap (or of a checkpoint.gsd)
    python benchmarks/sensitivity.py layers RUN_DIR ... --figure layers.png   # and their figure

``csv`` reads the finished runs kept in ``benchmarks/validation/runs/`` and, as the ``default``
setting of each cell, seeds 1 and 2 of the same mixtures in ``benchmarks/study/``. ``phi_bed``
is the mean of the run's solid-fraction profile over the bed less a skin of ``BED_SKIN`` d at
the floor and below the surface (the surface: the highest level of the profile above
``SURFACE_PHI``), the figure of a bed too thin for a bulk region; ``phi_corrected`` is the bulk
solid fraction over ``1 + k`` (k: the expansion coefficient in its work form, as the study's).
A bed without a bulk region has its coordination and order figures over the whole bed, computed
from its ``final.gsd`` once and kept in its ``bed.json`` (:func:`write_bed_figures`).
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import math
import re
import statistics
import sys
import tomllib
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
STUDY = ROOT / "examples" / "study.toml"
CONFIGS = HERE / "validation" / "configs"
KEPT = HERE / "validation" / "runs"
#: the campaigns of ``KEPT`` that belong to the sensitivity study (the others are other validations)
SENSITIVITY_CAMPAIGNS = ("sensitivity", "screening", "time-600-seed-*", "bidisperse*", "flat-elongated")
STUDY_RUNS = HERE / "study"
CSV = HERE / "validation" / "sensitivity.csv"
FIGURE = ROOT / "docs" / "validation" / "figures" / "sensitivity.png"
#: skin left out of the bed at the floor and below the surface, d
BED_SKIN = 1.0
#: the surface of the bed: the highest level of the profile whose solid fraction is above this
SURFACE_PHI = 0.3
#: the file of a run without a bulk region that keeps its bed figures (:func:`write_bed_figures`)
BED_FILE = "bed.json"
COLUMNS = ("mixture", "factor", "setting", "seed", "grains", "cell", "status", "t", "phi", "phi_std", "phi_bed", "k",
           "phi_corrected", "N", "Ns", "Nd", "Nt", "Nc", "rattler_fraction", "Q00", "Q22", "cpu_s")

#: the study engine's contact regime: no push-back, no projection of overlaps
LMGC_REGIME = {"recovery_rate": 0.0, "projection_slop": 0.0, "pour_projection_slop": 0.0}

#: LMGC90's example solver settings: plain NLGS, 'Quad' 1.666e-4 from the start, gs_it1 = 51
#: sweeps between checks, at most gs_it2 = 501 checks
LMGC_SOLVER = {"acceleration": "none", "tolerance": 1.666e-4, "settling_tolerance": 1.666e-4, "check_every": 51,
               "max_iterations": 51 * 501}
#: a fixed step: no substeps for the rotations (the alert distance still follows the speeds)
FIXED_STEP = {"max_rotation": 1000.0}
#: the study engine's elements granpack can take, all together
LMGC_ENGINE = {"overlap": LMGC_REGIME, "time_stepping": {**FIXED_STEP, "rotation_update": "from-start"},
               "solver": LMGC_SOLVER}
#: (factor, mixture of examples/study.toml, overrides of the mixture's own keys)
FACTORS: tuple[tuple[str, str, dict], ...] = (
    ("regime-lmgc", "pinacoids-small-0", {"overlap": LMGC_REGIME}),
    ("regime-lmgc", "pinacoids-small-30", {"overlap": LMGC_REGIME}),
    ("regime-lmgc", "flat-100", {"overlap": LMGC_REGIME}),
    ("regime-lmgc", "flat-elongated-100", {"overlap": LMGC_REGIME}),
    ("cell-study", "flat-elongated-100", {"lateral_size": 8.0}),
    ("cell-study", "elongated-100", {"lateral_size": 10.0}),
    ("cell-study", "flat-100", {"lateral_size": 8.0}),
    ("width-x3", "pinacoids-small-30", {"n_particles": 9000, "lateral_scale": math.sqrt(3.0)}),
    ("width-x3", "spheres-small-30", {"n_particles": 9000, "lateral_scale": math.sqrt(3.0)}),
    ("deposit-lmgc", "pinacoids-small-0", {"deposit": {"method": "lmgc"}}),
    ("deposit-lmgc", "pinacoids-small-30", {"deposit": {"method": "lmgc"}}),
    ("deposit-lmgc", "flat-elongated-100", {"deposit": {"method": "lmgc"}}),
    ("engine-lmgc", "pinacoids-small-30", LMGC_ENGINE),
)

#: (factor, mixture of examples/study.toml, overrides, seeds) of the bidisperse study; ``small_size``
#: (d) and ``small_share`` (of the solid volume) change the small population, and the mixture is
#: then renamed and its cell planned again (:func:`_replanned`)
BIDISPERSE: tuple[tuple[str, str, dict, int], ...] = (
    ("size-ratio", "spheres-small-30", {"small_size": 1 / 2}, 2),
    ("size-ratio", "spheres-small-30", {"small_size": 1 / 5}, 2),
    ("size-ratio", "pinacoids-small-30", {"small_size": 1 / 2}, 2),
    ("small-23", "pinacoids-small-30", {"small_share": 0.23}, 2),
    ("tapping", "pinacoids-small-30", {"solver": {"restitution": 0.5}}, 1),
    ("end-game-off", "pinacoids-small-30", {"end_game": {"mode": "none"}}, 1),
    ("size-ratio", "pinacoids-small-30", {"small_size": 1 / 5}, 1),
)
#: (factor, mixture of examples/study.toml, overrides) of the flat & elongated series' runs, one seed:
#: the study engine's elements, those with the study's cell and deposit too, and the end game off
FLAT_ELONGATED: tuple[tuple[str, str, dict], ...] = (
    ("engine-lmgc", "flat-elongated-100", LMGC_ENGINE),
    ("study-protocol", "flat-elongated-100", {**LMGC_ENGINE, "lateral_size": 8.0, "deposit": {"method": "lmgc"}}),
    ("end-game-off", "flat-elongated-100", {"end_game": {"mode": "none"}}),
)

#: the column a replanned mixture is given, d, and its narrowest cell, d (the study's rule)
PLANNED_COLUMN, PLANNED_LEAST_CELL = 8.0, 3.0

#: the grains of a screening run (a third of the study's, in a third of its cell area)
SCREEN_GRAINS = 1000
#: (factor, mixture of examples/study.toml, overrides) of the screening runs
SCREENING: tuple[tuple[str, str, dict], ...] = (
    ("screen-default", "pinacoids-small-0", {}),
    ("screen-lmgc", "pinacoids-small-0", {"overlap": LMGC_REGIME}),
    ("screen-lmgc-fixed-step", "pinacoids-small-0", {"overlap": LMGC_REGIME, "time_stepping": FIXED_STEP}),
    ("screen-lmgc-from-start", "pinacoids-small-0",
     {"overlap": LMGC_REGIME, "time_stepping": {**FIXED_STEP, "rotation_update": "from-start"}}),
    ("screen-lmgc-nlgs", "pinacoids-small-0", {"overlap": LMGC_REGIME, "solver": LMGC_SOLVER}),
    ("screen-lmgc-engine", "pinacoids-small-0", LMGC_ENGINE),
    ("screen-default", "flat-100", {}),
    ("screen-lmgc-engine", "flat-100", LMGC_ENGINE),
)

#: the study runs at the cap of 300 that miss even the study's equilibrium level: seed -> mixtures
CAPPED = {
    1: ("elongated-36", "pinacoids-small-13"),
    2: ("pinacoids-small-13", "flat-elongated-14"),
    3: ("elongated-100", "elongated-20", "elongated-36", "flat-12", "pinacoids-small-13", "spheres-small-3"),
}
LONGER_CAP = 600.0

#: the study's cell widths, d, by family of substituted grains (its text: 8 d for flat & elongated,
#: 6 to 8 d for flat, 8 to 11 d for elongated grains, 3000 grains in every run)
STUDY_CELLS = {"flat-elongated": (8.0,), "flat": (6.0, 8.0), "elongated": (8.0, 11.0)}
#: the least bed height, d, with a bulk region by the study's rule (two grain sizes above the floor
#: and below the surface, and one more to measure)
BULK_BED = 5.0

#: the study's solid fractions (its text and tables, as docs/validation.md quotes them): mixture ->
#: (raw phi, its std, phi_min its overlap-corrected figure, phi / (1 + k)^3); None where the study gives none. Its
#: flat & elongated packing is "slightly above" the one-size isometric 0.676: drawn at 0.676.
STUDY_PHI = {
    "pinacoids-small-0": (0.676, 0.004, 0.664),
    "pinacoids-small-30": (0.769, 0.001, None),
    "spheres-small-30": (0.726, 0.004, None),
    "elongated-100": (0.683, 0.012, 0.662),
    "flat-100": (0.676, 0.001, 0.648),
    "flat-elongated-100": (0.676, None, 0.654),
}


def _toml(value) -> str:
    if isinstance(value, bool):
        raise TypeError("the run config has no booleans")
    if isinstance(value, (int, float, str)):
        return repr(value) if isinstance(value, float) else (f'"{value}"' if isinstance(value, str) else str(value))
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r}")


def _campaign_text(header: str, replicas: int, base: dict, mixtures: list[dict]) -> str:
    """A campaign file: ``replicas``, ``[base]`` with its tables, then ``[[mixtures]]``."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()] + ["", f"replicas = {replicas}", "", "[base]"]
    tables = {k: v for k, v in base.items() if isinstance(v, dict)}
    lines += [f"{k} = {_toml(v)}" for k, v in base.items() if not isinstance(v, dict)]
    for name, table in tables.items():
        lines += ["", f"[base.{name}]"] + [f"{k} = {_toml(v)}" for k, v in table.items()]
    for mixture in mixtures:
        lines += ["", "[[mixtures]]"]
        lines += [f"{k} = {_toml(v)}" for k, v in mixture.items() if not isinstance(v, (dict, list)) or k == "aspect"]
        for name, table in mixture.items():
            if isinstance(table, dict):
                lines += ["", f"[mixtures.{name}]"] + [f"{k} = {_toml(v)}" for k, v in table.items()]
        for population in mixture["populations"]:
            lines += ["", "[[mixtures.populations]]"] + [f"{k} = {_toml(v)}" for k, v in population.items()]
    return "\n".join(lines) + "\n"


def _replanned(study: dict, mixture: dict, small_size: float | None, small_share: float | None) -> dict:
    """``mixture`` with its ``small`` population resized (``small_size``, d) or given another share
    of the solid volume (``small_share``, the ``large`` population the rest), renamed for it
    (``pinacoids-small-23``, ``spheres-small-30-ratio-5``), its cell and grains planned anew."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("validate_pinacoids", HERE / "validate_pinacoids.py")
    validate_pinacoids = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(validate_pinacoids)
    populations = {p["name"]: p for p in mixture["populations"]}
    base = mixture["name"].rpartition("-")[0]
    if small_share is not None:
        populations["small"]["volume_fraction"] = round(small_share, 6)
        populations["large"]["volume_fraction"] = round(1.0 - small_share, 6)
        mixture["name"] = f"{base}-{round(100 * small_share)}"
        mixture["share"] = round(small_share, 6)
    if small_size is not None:
        populations["small"]["size"] = round(small_size, 10)
        mixture["name"] = f"{mixture['name']}-ratio-{round(1.0 / small_size):d}"
    lateral, n, _ = validate_pinacoids.plan_cell(mixture["populations"], study["base"]["n_particles"],
                                                 study["base"]["lateral_size"], PLANNED_COLUMN, PLANNED_LEAST_CELL)
    mixture["lateral_size"] = lateral
    if n != study["base"]["n_particles"]:
        mixture["n_particles"] = n
    return mixture


def _varied(study: dict, factor: str, name: str, overrides: dict) -> dict:
    """The study's mixture ``name`` with ``overrides`` applied, renamed ``FACTOR_NAME``."""
    mixture = copy.deepcopy(next(m for m in study["mixtures"] if m["name"] == name))
    overrides = dict(overrides)
    small_size, small_share = overrides.pop("small_size", None), overrides.pop("small_share", None)
    if small_size is not None or small_share is not None:
        mixture = _replanned(study, mixture, small_size, small_share)
        name = mixture["name"]
    scale = overrides.pop("lateral_scale", None)
    if scale is not None:
        mixture["lateral_size"] = round(mixture.get("lateral_size", study["base"]["lateral_size"]) * scale, 4)
    for key, value in overrides.items():
        if isinstance(value, dict):
            mixture[key] = {**mixture.get(key, {}), **value}
        else:
            mixture[key] = value
    mixture["name"] = f"{factor}_{name}"
    mixture["family"] = factor
    return mixture


def write_configs() -> list[Path]:
    """Write the sensitivity campaign files from ``examples/study.toml``; returns their paths."""
    study = tomllib.loads(STUDY.read_text())
    CONFIGS.mkdir(parents=True, exist_ok=True)
    written = []
    header = ("The sensitivity study's runs: one factor of the protocol varied at a time against\n"
              "examples/study.toml (whose seeds 1 and 2 are each cell's reference).\n"
              "Written by `python benchmarks/sensitivity.py configs`; do not edit by hand.")
    mixtures = [_varied(study, factor, name, overrides) for factor, name, overrides in FACTORS]
    path = CONFIGS / "sensitivity.toml"
    path.write_text(_campaign_text(header, 2, study["base"], mixtures))
    written.append(path)
    scale = {"n_particles": SCREEN_GRAINS, "lateral_scale": math.sqrt(SCREEN_GRAINS / study["base"]["n_particles"])}
    mixtures = [_varied(study, factor, name, {**scale, **overrides}) for factor, name, overrides in SCREENING]
    path = CONFIGS / "screening.toml"
    path.write_text(_campaign_text(
        "Where the study's overlaps come from: 1000 one-size isometric pinacoids, granpack's default, the study\n"
        "engine's regime and that regime with each further element of the study's engine; 1000 flat pinacoids,\n"
        "granpack's default and all those elements together.\n"
        "Written by `python benchmarks/sensitivity.py configs`; do not edit by hand.", 1, study["base"], mixtures))
    written.append(path)
    for seeds, path in ((2, CONFIGS / "bidisperse.toml"), (1, CONFIGS / "bidisperse-one-seed.toml")):
        mixtures = [_varied(study, factor, name, overrides) for factor, name, overrides, n in BIDISPERSE if n == seeds]
        path.write_text(_campaign_text(
            "Why granpack's pinacoids gain less from small grains than its spheres: the size ratio, the\n"
            "23 % point, a pour shaken by restitution, the end game without damping (seeds 1 to "
            f"{seeds}).\nWritten by `python benchmarks/sensitivity.py configs`; do not edit by hand.",
            seeds, study["base"], mixtures))
        written.append(path)
    mixtures = [_varied(study, factor, name, overrides) for factor, name, overrides in FLAT_ELONGATED]
    path = CONFIGS / "flat-elongated.toml"
    path.write_text(_campaign_text(
        "The flat & elongated grains under the study engine's elements, those with the study's 8 d cell\n"
        "and LMGC90's deposit too, and with the end game's damping off (seed 1).\n"
        "Written by `python benchmarks/sensitivity.py configs`; do not edit by hand.", 1, study["base"], mixtures))
    written.append(path)
    for seed, names in CAPPED.items():
        base = copy.deepcopy(study["base"])
        base["seed"] = seed
        base.setdefault("equilibrium", {})["max_time"] = LONGER_CAP
        mixtures = [_varied(study, "time-600", name, {}) for name in names]
        path = CONFIGS / f"time-600-seed-{seed}.toml"
        path.write_text(_campaign_text(
            f"The study runs of seed {seed} stopped at the cap of 300 sqrt(d/g), run again with a cap of "
            f"{LONGER_CAP:g}.\nWritten by `python benchmarks/sensitivity.py configs`; do not edit by hand.",
            1, base, mixtures))
        written.append(path)
    return written


def _bed_phi(profile_z: list[float], profile_phi: list[float]) -> float:
    """Mean solid fraction of the bed less ``BED_SKIN`` at the floor and below the surface."""
    dense = [z for z, phi in zip(profile_z, profile_phi) if phi > SURFACE_PHI]
    if not dense:
        return float("nan")
    top = max(dense)
    kept = [phi for z, phi in zip(profile_z, profile_phi) if BED_SKIN <= z <= top - BED_SKIN]
    return statistics.fmean(kept) if kept else float("nan")


def bed_figures(final: Path, surface: float) -> tuple[dict, dict]:
    """Coordination and order figures of the grains whose centres lie between the floor and
    ``surface`` (d): those of a bed too thin for a bulk region, where ``analysis.json`` has none.
    Contacts with the floor count as contacts of the grains resting on it."""
    from granpack.analysis.coordination import Coordination
    from granpack.analysis.order import Order
    from granpack.io.gsd import read_packing

    packing = read_packing(final)
    c = Coordination((0.0, surface)).compute(packing)
    o = Order((0.0, surface)).compute(packing)
    return ({"N": c.N, **c.figures, "rattler_fraction": c.rattler_fraction}, {"Q00": o.Q00, "Q22": o.Q22})


def write_bed_figures(run: Path) -> Path:
    """``run/bed.json``: the :func:`bed_figures` of a finished run without a bulk region, from its
    ``final.gsd``; kept beside ``analysis.json`` so that the table is rebuilt without the final
    state, which the repository does not hold."""
    a = json.loads((run / "analysis.json").read_text())
    coordination, order = bed_figures(run / "final.gsd", a["bulk"]["z_surface"])
    path = run / BED_FILE
    path.write_text(json.dumps({"coordination": coordination, "order": order}, indent=1) + "\n")
    return path


def kept_bed_figures(run: Path) -> tuple[dict, dict]:
    """The coordination and order figures of ``run/bed.json`` (:func:`write_bed_figures`)."""
    path = run / BED_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{run}: a run without a bulk region needs its {BED_FILE}: "
                                f"python benchmarks/sensitivity.py bed {run} (from its final.gsd)")
    bed = json.loads(path.read_text())
    return bed["coordination"], bed["order"]


def _row(run: Path, mixture: str, factor: str, setting: str) -> dict:
    a = json.loads((run / "analysis.json").read_text())
    s = json.loads((run / "summary.json").read_text())
    task = json.loads((run / "task.json").read_text())
    phi, c, o = a["solid_fraction"], a["coordination"], a["order"]
    if phi["bulk"] is None:
        c, o = kept_bed_figures(run)
    return {"mixture": mixture, "factor": factor, "setting": setting, "seed": a["seed"], "grains": a["n_particles"],
            "cell": task["config"].get("lateral_size", 8.0), "status": s["status"], "t": round(s["simulated_time"], 3),
            "phi": phi["bulk"], "phi_std": phi["std"], "phi_bed": _bed_phi(phi["profile_z"], phi["profile_phi"]),
            "k": a["interpenetration"]["expansion_k"], "phi_corrected": phi.get("corrected_for_overlap"),
            "N": c["N"], "Ns": c["Ns"], "Nd": c["Nd"], "Nt": c["Nt"], "Nc": c["Nc"],
            "rattler_fraction": c["rattler_fraction"], "Q00": o.get("Q00"), "Q22": o.get("Q22"),
            "cpu_s": round(s.get("cpu_time") or float("nan"), 1)}


#: factors whose name is not ``<factor>-<setting>``
WHOLE_NAME_FACTORS = ("end-game-off", "study-protocol")


def rows() -> list[dict]:
    """One row per run of the sensitivity study: the reference runs of every cell first (seeds 1
    and 2 of each varied mixture, and the capped runs the ``time-600`` factor continues, from
    ``benchmarks/study/``), then every finished varied run kept in ``benchmarks/validation/runs/``."""
    references = sorted({(name, seed) for _, name, _ in FACTORS for seed in (1, 2)}
                        | {(name, seed) for seed, names in CAPPED.items() for name in names})
    out = [_row(STUDY_RUNS / name / f"seed-{seed}", name, "default", "default") for name, seed in references
           if (STUDY_RUNS / name / f"seed-{seed}" / "analysis.json").is_file()]
    kept = [path for campaign in SENSITIVITY_CAMPAIGNS for path in KEPT.glob(f"{campaign}/*/seed-*/analysis.json")]
    for path in sorted(kept):
        factor, _, mixture = path.parent.parent.name.partition("_")
        setting = "" if factor in WHOLE_NAME_FACTORS else factor.partition("-")[2]
        out.append(_row(path.parent, mixture, factor, setting))
    return out


def write_csv(table: list[dict]) -> None:
    with CSV.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        for row in table:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})


def _cell(values: list) -> str:
    kept = [v for v in values if v is not None and v == v]
    if not kept:
        return "–"
    if len(kept) == 1:
        return f"{kept[0]:.4g}"
    return f"{statistics.fmean(kept):.4g} ± {statistics.stdev(kept):.2g}"


def markdown(table: list[dict]) -> str:
    """A row per (mixture, factor): mean ± std over its seeds."""
    keys = ("phi", "phi_bed", "k", "phi_corrected", "N", "Nc", "Q00")
    lines = ["| mixture | factor | runs (at rest) | " + " | ".join(keys) + " |", "|---|---|---|" + "---|" * len(keys)]
    cells: dict[tuple[str, str], list[dict]] = {}
    for row in table:
        cells.setdefault((row["mixture"], row["factor"]), []).append(row)
    for (mixture, factor), runs in sorted(cells.items()):
        rest = sum(r["status"] == "equilibrium" for r in runs)
        lines.append(f"| {mixture} | {factor} | {len(runs)} ({rest}) | "
                     + " | ".join(_cell([r[k] for r in runs]) for k in keys) + " |")
    return "\n".join(lines)


def _save(fig, path: Path) -> Path:
    """Write a matplotlib figure to the PNG ``path`` (its folder created) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def figure_cells(table: list[dict]) -> dict[str, dict[str, tuple[float, float, int]]]:
    """What :func:`figure` draws: mixture -> factor -> (mean phi, std or 0, runs) over the cell's
    finished runs (as the table counts them), for the mixtures of :data:`STUDY_PHI` that some factor varies. A bed
    without a bulk region (``cell-study``, ``study-protocol``: no bulk ``phi``) counts by its ``phi_bed``."""
    cells: dict[str, dict[str, list[float]]] = {}
    for row in table:
        if row["mixture"] not in STUDY_PHI or row["factor"].startswith("screen-"):
            continue
        value = row["phi_bed"] if row["factor"] == "cell-study" or row["phi"] is None else row["phi"]
        cells.setdefault(row["mixture"], {}).setdefault(row["factor"], []).append(value)
    varied = {m: c for m, c in cells.items() if set(c) - {"default"}}
    return {m: {f: (statistics.fmean(v), statistics.stdev(v) if len(v) > 1 else 0.0, len(v)) for f, v in c.items()}
            for m, c in varied.items()}


def figure(table: list[dict], path: Path) -> Path:
    """The solid fraction of each varied mixture: the default protocol (mean ± std over its
    seeds), each factor beside it and the study's raw phi and phi_min; a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cells = figure_cells(table)
    mixtures = [m for m in STUDY_PHI if m in cells]
    factors = ["default"] + sorted({f for c in cells.values() for f in c} - {"default"})
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    width = 0.5 / max(1, len(factors) - 1)
    for j, factor in enumerate(factors):
        xs, ys, es = [], [], []
        for i, mixture in enumerate(mixtures):
            if factor in cells[mixture]:
                mean, std, _ = cells[mixture][factor]
                xs.append(i - 0.3 + j * width)
                ys.append(mean)
                es.append(std)
        ax.errorbar(xs, ys, yerr=es, fmt="o", ms=5, capsize=3, label=factor,
                    color="black" if factor == "default" else None)
    raw = [STUDY_PHI[m][:2] for m in mixtures]
    ax.errorbar([i + 0.35 for i in range(len(mixtures))], [r for r, _ in raw], yerr=[e or 0.0 for _, e in raw],
                fmt="*", ms=10, color="tab:red", capsize=3, label="study, raw")
    bounds = [(i, STUDY_PHI[m][2]) for i, m in enumerate(mixtures) if STUDY_PHI[m][2] is not None]
    if bounds:
        ax.plot([i + 0.35 for i, _ in bounds], [b for _, b in bounds], "v", mfc="none", color="tab:red", ms=7,
                linestyle="none", label="study, phi_min")
    ax.set_xticks(range(len(mixtures)), mixtures, rotation=15)
    ax.set_ylabel("bulk solid fraction (bed for thin beds)")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return _save(fig, path)


def layers(final: Path, thickness: float = 1.0) -> list[dict]:
    """Solid fraction and nematic order Q00 of each ``thickness``-thick layer of a packing, from the
    floor to the top of its highest grain: the profile of a bed too thin for a bulk region. A
    layer's Q00 is over the non-spherical grains whose centres lie in it (nan with fewer than 10)."""
    from granpack.analysis.order import order_parameters
    from granpack.analysis.solid_fraction import slice_volumes
    from granpack.io.gsd import read_packing
    from granpack.rotations import quat_to_matrix

    packing = read_packing(final)
    state = packing.state
    top = float((state.position[:, 2] + state.radius).max())
    n = max(1, math.ceil(top / thickness))
    volume = slice_volumes(packing, 0.0, thickness, n)[0]
    area = state.box.lx * state.box.ly
    shaped = ~state.shapes.is_sphere[state.kind]
    out = []
    for k in range(n):
        z0 = k * thickness
        inside = shaped & (state.position[:, 2] >= z0) & (state.position[:, 2] < z0 + thickness)
        q00 = order_parameters(quat_to_matrix(state.quaternion[inside]))[0] if inside.sum() >= 10 else float("nan")
        out.append({"z": z0 + 0.5 * thickness, "phi": float(volume[k] / (area * thickness)), "Q00": q00,
                    "grains": int(inside.sum())})
    return out


def profile_layers(analysis: Path, thickness: float = 1.0) -> list[dict]:
    """The solid fraction of each ``thickness``-thick layer from the profile of an
    ``analysis.json`` (its slices averaged), for a run whose ``final.gsd`` is not kept: the
    layers of :func:`layers` without their Q00 and grain counts."""
    phi = json.loads(analysis.read_text())["solid_fraction"]
    z, values = phi["profile_z"], phi["profile_phi"]
    n = max(1, math.ceil(max(z) / thickness))
    out = []
    for k in range(n):
        kept = [v for zz, v in zip(z, values) if k * thickness <= zz < (k + 1) * thickness]
        out.append({"z": (k + 0.5) * thickness, "phi": statistics.fmean(kept) if kept else float("nan"),
                    "Q00": float("nan"), "grains": 0})
    return out


#: the timeline columns a rerun must repeat for its pile to be the study run's
RERUN_COLUMNS = ("step", "kinetic_energy_total", "max_net_force", "max_net_torque", "contacts", "contact_points",
                 "max_overlap")


def k_manifold_deepest(final: Path, n_bottom: float = 2.0) -> dict:
    """The expansion coefficient k of a packing (work form, more than ``n_bottom`` d above the
    wall) beside the same k with every point of a manifold at the manifold's deepest overlap, as
    an engine that gives all the points of a face contact one common-plane gap reports them; and
    the force-weighted mean of the manifolds' deepest overlaps, d."""
    import numpy as np

    from granpack.io.gsd import read_packing

    packing = read_packing(final)
    c, state = packing.contacts, packing.state
    overlap = np.maximum(-c.gap, 0.0)
    deepest = np.zeros(c.n_manifolds)
    np.maximum.at(deepest, c.point_manifold, overlap)
    weight = np.abs(packing.point_force[:, 2]) * np.abs(c.normal[c.point_manifold, 2])
    above = c.point[:, 2] > n_bottom * packing.max_size
    z = state.position[:, 2]
    moment = float(np.sum(packing.gravity * state.mass[z > n_bottom * packing.max_size] * z[z > n_bottom * packing.max_size]))
    loads = np.abs(packing.manifold_force[:, 2])
    return {"k": float(np.sum((weight * overlap)[above]) / moment),
            "k_manifold_deepest": float(np.sum((weight * deepest[c.point_manifold])[above]) / moment),
            "deepest_force_weighted": float(np.average(deepest, weights=loads)) if loads.sum() > 0 else float("nan")}


def rerun_check(rerun: Path, original: Path) -> dict:
    """Whether a run made again from its seed (a ``time-600`` run) repeats the original run's
    pile: their ``timeline.csv`` rows compared, column by column of :data:`RERUN_COLUMNS` as
    written, over the times both reached. Returns ``same_until`` (the last time of identical
    rows), ``first_difference`` (``None`` or the time and the differing columns) and ``compared``
    (rows)."""
    def timeline(run: Path) -> list[dict]:
        with (run / "timeline.csv").open(newline="") as f:
            return list(csv.DictReader(f))

    same_until, compared = None, 0
    for a, b in zip(timeline(original), timeline(rerun)):
        if a["time"] != b["time"]:
            return {"same_until": same_until, "first_difference": {"time": (a["time"], b["time"])}, "compared": compared}
        differing = {k: (a[k], b[k]) for k in RERUN_COLUMNS if a[k] != b[k]}
        if differing:
            return {"same_until": same_until, "first_difference": {"time": float(a["time"]), **differing},
                    "compared": compared}
        same_until, compared = float(a["time"]), compared + 1
    return {"same_until": same_until, "first_difference": None, "compared": compared}


def settling_drift(run: Path, windows: tuple[tuple[float, float], ...] = ((100.0, 200.0), (200.0, 300.0), (250.0, 300.0))) -> dict:
    """How far a run's pile was still settling: over each window ``(t0, t1]`` of its timeline, the
    descent of the grains' centre of mass, from the potential energy it lost (``dz = dE_p / (rho g
    V)``, d; V the solid volume, the cell area times the integral of the solid-fraction profile),
    and the relative rise of the solid fraction it would make if the whole bed compacted evenly,
    ``-dz / z_G`` (z_G the profile's centre of mass): what a run capped before rest would still
    have gained in the window's time. Returns ``{"z_G", "windows": [{"t0", "t1", "dz", "dphi_rel"}]}``."""
    a = json.loads((run / "analysis.json").read_text())
    task = json.loads((run / "task.json").read_text())
    cell = task["config"].get("lateral_size", 8.0)
    z, phi = a["solid_fraction"]["profile_z"], a["solid_fraction"]["profile_phi"]
    dz_profile = z[1] - z[0]
    volume = cell * cell * dz_profile * math.fsum(phi)
    z_g = math.fsum(zz * f for zz, f in zip(z, phi)) / math.fsum(phi)
    with (run / "timeline.csv").open(newline="") as f:
        timeline = [(float(r["time"]), float(r["potential_energy_change"])) for r in csv.DictReader(f)
                    if r["potential_energy_change"] not in ("", "None", "nan")]
    out = []
    for t0, t1 in windows:
        dz = math.fsum(de for t, de in timeline if t0 < t <= t1) / volume
        out.append({"t0": t0, "t1": t1, "dz": dz, "dphi_rel": -dz / z_g})
    return {"z_G": z_g, "windows": out}


def thin_bed(run: Path, cell: float) -> dict:
    """What a run of ``benchmarks/study/`` would measure in a cell ``cell`` d wide with the same
    grains: its bed height ``H = z_s (L / cell)^2`` (z_s the run's surface, L its cell) and, a thin
    bed being the bottom of a thick one (measured on the study's cells for the flat and flat &
    elongated grains), the solid fraction of the run's profile over the whole 1 d layers below
    ``H``: ``phi_layers`` (None where ``H`` is below 1 d or above the run's own bed), and over the
    bed less ``BED_SKIN`` at the floor and below ``H``: ``phi_bed`` (None where that leaves less
    than 1 d). ``phi_study`` is what the study's rule would report: the bulk where
    ``H >= BULK_BED``, else ``phi_layers``."""
    a = json.loads((run / "analysis.json").read_text())
    own = json.loads((run / "task.json").read_text())["config"].get("lateral_size", 8.0)
    surface = a["bulk"]["z_surface"]
    height = surface * (own / cell) ** 2
    z, phi = a["solid_fraction"]["profile_z"], a["solid_fraction"]["profile_phi"]
    top = math.floor(height)
    kept = [f for zz, f in zip(z, phi) if zz < top]
    layers_phi = statistics.fmean(kept) if kept and height <= surface else None
    inner = [f for zz, f in zip(z, phi) if BED_SKIN <= zz <= height - BED_SKIN]
    bed_phi = statistics.fmean(inner) if height - 2 * BED_SKIN >= 1.0 and height <= surface else None
    bulk = a["solid_fraction"]["bulk"]
    return {"height": height, "phi_layers": layers_phi, "phi_bed": bed_phi, "phi_bulk": bulk,
            "phi_study": bulk if height >= BULK_BED else layers_phi}


def thin_beds() -> list[dict]:
    """:func:`thin_bed` of every run of the flat, flat & elongated and elongated series of
    ``benchmarks/study/`` at each of the study's cells for its family (``STUDY_CELLS``), a row per
    (mixture, cell) with the mean and std over its seeds."""
    out = []
    for family, cells in STUDY_CELLS.items():
        names = sorted((p.name for p in STUDY_RUNS.glob(f"{family}-*") if p.name.rpartition("-")[0] == family),
                       key=lambda name: int(name.rpartition("-")[2]))
        for name in names:
            for cell in cells:
                beds = [thin_bed(run, cell) for run in sorted((STUDY_RUNS / name).glob("seed-*"))]
                row = {"mixture": name, "cell": cell, "height": statistics.fmean(b["height"] for b in beds)}
                for key in ("phi_bulk", "phi_layers", "phi_bed", "phi_study"):
                    values = [b[key] for b in beds if b[key] is not None]
                    row[key] = statistics.fmean(values) if len(values) == len(beds) else None
                    row[f"{key}_std"] = statistics.stdev(values) if len(values) == len(beds) > 1 else None
                out.append(row)
    return out


def layers_figure(profiles: dict[str, list[dict]], path: Path) -> Path:
    """Solid fraction and Q00 layer by layer (the :func:`layers` of each run, by label) side by
    side against the height; a PNG at ``path``: how a thin bed's density and order vary from its
    floor to its surface."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(7.5, 4.2), sharey=True)
    for label, profile in profiles.items():
        z = [layer["z"] for layer in profile]
        line, = left.plot([layer["phi"] for layer in profile], z, "o-", ms=4, label=label)
        right.plot([layer["Q00"] for layer in profile], z, "o-", ms=4, color=line.get_color())
    left.set_xlabel("solid fraction of the layer")
    right.set_xlabel("Q00 of the layer")
    left.set_ylabel("height of the layer's middle (d)")
    for ax in (left, right):
        ax.grid(alpha=0.3)
    left.legend(fontsize=7, loc="lower left")
    return _save(fig, path)


def _checkpoint_time(run: Path) -> float | None:
    """The simulated time of the last progress line of a checkpointed run (``settling t = T/...``)."""
    log = run / "progress.log"
    times = re.findall(r"t = ([0-9.]+)/", log.read_text()) if log.is_file() else []
    return float(times[-1]) if times else None


def plan_status() -> list[dict]:
    """Every run the campaign files of ``CONFIGS`` plan, and where its kept copy in ``KEPT`` stands:
    ``finished`` (with its status, simulated time and CPU hours), ``checkpoint`` (with the time of
    its last progress line) or ``not started``. What is left of the study, read off the repository."""
    from granpack.campaign.runner import selected_runs
    from granpack.campaign.spec import load_campaign

    out = []
    for path in sorted(CONFIGS.glob("*.toml")):
        for run in selected_runs(load_campaign(path), None):
            kept = KEPT / path.stem / run.folder
            row = {"campaign": path.stem, "run": run.folder.as_posix(), "state": "not started", "t": None, "cpu_h": None}
            if (kept / "summary.json").is_file():
                summary = json.loads((kept / "summary.json").read_text())
                row.update(state=f"finished ({summary['status']})", t=round(summary["simulated_time"], 2),
                           cpu_h=round((summary.get("cpu_time") or float("nan")) / 3600, 2))
            elif any(kept.glob("checkpoint*.gsd")):
                row.update(state="checkpoint", t=_checkpoint_time(kept))
            out.append(row)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("configs", help="write the campaign files of benchmarks/validation/configs/")
    sub.add_parser("csv", help="write benchmarks/validation/sensitivity.csv from the kept runs")
    sub.add_parser("table", help="print the markdown table of the kept runs")
    sub.add_parser("status", help="every planned run: finished, checkpointed (at t) or not started")
    drawn = sub.add_parser("figure", help="draw the solid fraction of each varied mixture beside the study's")
    drawn.add_argument("--out", type=Path, default=FIGURE, help=f"PNG to write (default {FIGURE.relative_to(ROOT)})")
    again = sub.add_parser("rerun-check", help="whether time-600 runs repeat the study runs they continue, to t = 300")
    again.add_argument("runs", nargs="+", type=Path, help="run folders of time-600 campaigns (MIXTURE/seed-S)")
    deepest = sub.add_parser("k-deepest", help="k of final.gsd of run folders (or of GSD files: a checkpoint of a "
                             "run under way) beside k with every point of a manifold at its deepest overlap")
    deepest.add_argument("runs", nargs="+", type=Path)
    sub.add_parser("thin-beds", help="the flat, flat & elongated and elongated series as the study's cells would "
                   "measure them: bed height, phi of the bottom layers, phi by the study's rule")
    sub.add_parser("drift", help="how far each capped study run was still settling over its last 200 and 100 "
                   "sqrt(d/g): centre-of-mass descent and the solid fraction it would add")
    bed = sub.add_parser("bed", help="write bed.json (coordination and order over the whole bed) of finished runs "
                         "without a bulk region, from their final.gsd")
    bed.add_argument("runs", nargs="+", type=Path)
    by_layer = sub.add_parser("layers", help="phi and Q00 layer by layer of the final.gsd of run folders "
                              "(phi alone, from analysis.json, where final.gsd is not kept)")
    by_layer.add_argument("runs", nargs="+", type=Path)
    by_layer.add_argument("--thickness", type=float, default=1.0, help="layer thickness, d (default 1)")
    by_layer.add_argument("--figure", type=Path, help="also draw the profiles into this PNG (labels: mixture and seed folders)")
    args = parser.parse_args(argv)
    if args.action == "configs":
        for path in write_configs():
            print(path.relative_to(ROOT))
    elif args.action == "csv":
        table = rows()
        write_csv(table)
        print(f"{len(table)} runs in {CSV.relative_to(ROOT)}", file=sys.stderr)
    elif args.action == "figure":
        print(figure(rows(), args.out).relative_to(ROOT) if args.out.is_relative_to(ROOT) else args.out)
    elif args.action == "rerun-check":
        for run in args.runs:
            mixture = run.parent.name.partition("_")[2]
            print(json.dumps({"run": str(run), **rerun_check(run, STUDY_RUNS / mixture / run.name)}))
    elif args.action == "bed":
        for run in args.runs:
            print(write_bed_figures(run))
    elif args.action == "k-deepest":
        for run in args.runs:
            print(json.dumps({"run": str(run), **k_manifold_deepest(run / "final.gsd" if run.is_dir() else run)}))
    elif args.action == "drift":
        for seed, names in CAPPED.items():
            for name in names:
                print(json.dumps({"run": f"{name}/seed-{seed}", **settling_drift(STUDY_RUNS / name / f"seed-{seed}")}))
    elif args.action == "thin-beds":
        print("| mixture | study's cell (d) | bed height (d) | bulk phi | phi of the whole layers below the height "
              f"| phi less {BED_SKIN:g} d at the floor and the top | phi by the study's rule |")
        print("|---|---|---|---|---|---|---|")
        for row in thin_beds():
            cells = ["–" if row[k] is None else f"{row[k]:.4f}" if row[k + "_std"] is None
                     else f"{row[k]:.4f} ± {row[k + '_std']:.4f}"
                     for k in ("phi_bulk", "phi_layers", "phi_bed", "phi_study")]
            print(f"| {row['mixture']} | {row['cell']:g} | {row['height']:.1f} | " + " | ".join(cells) + " |")
    elif args.action == "status":
        plan = plan_status()
        for row in plan:
            t = "" if row["t"] is None else f"  t = {row['t']:g}"
            cpu = "" if row["cpu_h"] is None else f"  {row['cpu_h']:g} CPU h"
            print(f"{row['campaign']:<18} {row['run']:<48} {row['state']}{t}{cpu}")
        done = sum(row["state"].startswith("finished") for row in plan)
        print(f"{done} of {len(plan)} runs finished", file=sys.stderr)
    elif args.action == "layers":
        profiles = {}
        for run in args.runs:
            folder = run if run.is_dir() else run.parent
            final = run / "final.gsd" if run.is_dir() else run
            profile = profiles[f"{folder.parent.name} {folder.name}"] = (
                layers(final, args.thickness) if final.is_file() else profile_layers(folder / "analysis.json", args.thickness))
            print(f"{run}: z (d), phi, Q00, grains")
            for layer in profile:
                print(f"  {layer['z']:5.2f}  {layer['phi']:.4f}  {layer['Q00']:.3f}  {layer['grains']}")
        if args.figure:
            print(layers_figure(profiles, args.figure))
    else:
        print(markdown(rows()))
    return 0


if __name__ == "__main__":
    sys.exit(main())

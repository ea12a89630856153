"""The sensitivity study behind docs/validation.md: how each free choice of the protocol moves the packing.

Each factor is varied alone against the default protocol of ``examples/study.toml``, whose runs
(seeds 1-3, kept in ``benchmarks/study/``) are the reference cell of every comparison. The
campaign files in ``benchmarks/validation/configs/`` are written from ``examples/study.toml`` by
this script (``configs``), so that a varied run differs from its reference in the one setting
its factor names:

- ``regime-lmgc``: the contact regime of the study's engine, overlaps left as the velocity-level
  law leaves them (``recovery_rate = 0``, ``overlap_slop = pour_overlap_slop = 0``);
- ``cell-study``: the study's cells, 8 d for flat and flat & elongated grains, 10 d for
  elongated ones, with the same 3000 grains (thin beds);
- ``width-x3``: three times the cell area and three times the grains (9000);
- ``deposit-lmgc``: LMGC90's deposit rule instead of the drop;
- ``time-600``: the study runs stopped at the cap of 300 sqrt(d/g), run again from their seed with
  a cap of 600 (one campaign file per seed, since each such run has its own seed).

A mixture of a sensitivity campaign is named ``FACTOR_MIXTURE`` (``regime-lmgc_pinacoids-small-30``);
its ``family`` is the factor, its ``share`` the mixture's.

Usage::

    python benchmarks/sensitivity.py configs                 # (re)write benchmarks/validation/configs/
    benchmarks/validation/run.sh OUT 'regime-lmgc_*' ...       # run, keeping the runs in the repository
    python benchmarks/sensitivity.py csv OUT                  # benchmarks/validation/sensitivity.csv
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
import tomllib
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
STUDY = ROOT / "examples" / "study.toml"
CONFIGS = HERE / "validation" / "configs"

#: the study engine's contact regime: no push-back, no projection of overlaps
LMGC_REGIME = {"recovery_rate": 0.0, "overlap_slop": 0.0, "pour_overlap_slop": 0.0}

#: (factor, mixture of examples/study.toml, overrides of the mixture's own keys)
FACTORS: tuple[tuple[str, str, dict], ...] = (
    ("regime-lmgc", "pinacoids-small-0", {"solver": LMGC_REGIME}),
    ("regime-lmgc", "pinacoids-small-30", {"solver": LMGC_REGIME}),
    ("regime-lmgc", "flat-100", {"solver": LMGC_REGIME}),
    ("regime-lmgc", "flat-elongated-100", {"solver": LMGC_REGIME}),
    ("cell-study", "flat-elongated-100", {"lateral_size": 8.0}),
    ("cell-study", "elongated-100", {"lateral_size": 10.0}),
    ("cell-study", "flat-100", {"lateral_size": 8.0}),
    ("width-x3", "pinacoids-small-30", {"n_particles": 9000, "lateral_scale": math.sqrt(3.0)}),
    ("width-x3", "spheres-small-30", {"n_particles": 9000, "lateral_scale": math.sqrt(3.0)}),
    ("deposit-lmgc", "pinacoids-small-0", {"deposit": {"method": "lmgc"}}),
    ("deposit-lmgc", "pinacoids-small-30", {"deposit": {"method": "lmgc"}}),
)

#: the study runs at the cap of 300 that miss even the study's equilibrium level: seed -> mixtures
CAPPED = {
    1: ("elongated-36", "pinacoids-small-13"),
    2: ("pinacoids-small-13", "flat-elongated-14"),
    3: ("elongated-100", "elongated-20", "elongated-36", "flat-12", "pinacoids-small-13", "spheres-small-3"),
}
LONGER_CAP = 600.0


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


def _varied(study: dict, factor: str, name: str, overrides: dict) -> dict:
    """The study's mixture ``name`` with ``overrides`` applied, renamed ``FACTOR_NAME``."""
    mixture = copy.deepcopy(next(m for m in study["mixtures"] if m["name"] == name))
    overrides = dict(overrides)
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("configs", help="write the campaign files of benchmarks/validation/configs/")
    args = parser.parse_args(argv)
    if args.action == "configs":
        for path in write_configs():
            print(path.relative_to(ROOT))
    return 0


if __name__ == "__main__":
    sys.exit(main())

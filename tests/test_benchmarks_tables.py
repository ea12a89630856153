"""The table builder and cell planning of benchmarks/validate_pinacoids.py, on fake analysis documents;
the generated page of benchmarks/study_runs.py (docs/study.md), against the kept study runs."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "validate_pinacoids.py"


@pytest.fixture(scope="module")
def vp():
    spec = importlib.util.spec_from_file_location("validate_pinacoids", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _analysis(seed: int, phi, Nc, *, baseline=True, valid=True, force=5e-4) -> dict:
    """A minimal analysis.json document as read from the file (undefined figures None)."""
    figures = {"N": 5.0 + seed, "Ns": 4.0, "Nd": 1.5, "Nt": 0.5, "Nc": Nc}
    return {
        "seed": seed,
        "n_particles": 1000,
        "status": "equilibrium",
        "bulk": {"valid": valid, "z_bottom": 2.0, "z_top": 6.0, "z_surface": 8.0},
        "solid_fraction": {"bulk": phi, "std": 0.002, "layers": [phi, phi], "corrected_for_overlap": phi},
        "coordination": {**figures, "rattler_fraction": 0.05, "n_analysed": 400, "with_rattlers": figures,
                         "gap_rule": figures, "geometric": figures},
        "order": {"Q00": 0.05, "Q22": 0.02, "director_axis": "w", "n_analysed": 400,
                  **({"isotropic_baseline": {"Q00": 0.04, "Q00_std": 0.01, "Q22": 0.015, "Q22_std": 0.005}}
                     if baseline else {})},
        "interpenetration": {"expansion_k": 2e-4, "k": {}, "max": 1e-4},
        "equilibrium": {"max_net_force": force, "max_net_torque": 1e-4, "kinetic_energy": 1e-9,
                        "wall_force_over_weight": 0.9999, "passed": True},
        "warnings": [],
    }


def _cells(table: str, row: int = 0) -> dict:
    lines = table.splitlines()
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    values = [c.strip() for c in lines[2 + row].strip("|").split("|")]
    assert len(values) == len(header)
    return dict(zip(header, values))


def test_mixture_row_averages_over_seeds(vp):
    records = [vp.run_record("flat", _analysis(1, 0.60, 12.0), {"status": "equilibrium", "wall_time": 3600.0}),
               vp.run_record("flat", _analysis(2, 0.62, 11.0, force=2e-3), {"status": "not at rest", "wall_time": 7200.0})]
    row = _cells(vp.mixture_table(records))
    assert row["mixture"] == "flat"
    assert row["φ bulk ± std"] == f"0.6100 ± {math.sqrt(2e-4):.4f}"  # std over the seeds, not the layers
    assert row["N"] == "6.50" and row["Nc"] == "11.50"
    assert row["Q00 (isotropic)"] == "0.050 (0.040 ± 0.010)"
    assert row["Q22 (isotropic)"] == "0.020 (0.015 ± 0.005)"
    assert row["max F/(d²P)"] == "2.0e-03"  # the worst seed
    assert row["wall time"] == "1.5 h"
    assert "equilibrium" in row["status"] and "not at rest, level 1" not in row["status"]


def test_one_seed_undefined_figures_and_missing_baseline(vp):
    bad = _analysis(3, None, None, baseline=False, valid=False)
    record = vp.run_record("bidisperse-30", bad)
    assert record["baseline_source"] != "analysis.json"
    assert record["baseline"]["Q00"] == pytest.approx(0.046, abs=0.012)  # recomputed for 400 grains
    row = _cells(vp.runs_table([record]))
    assert row["φ bulk ± std"] == "n/a" and row["Nc"] == "n/a"
    assert "no bulk" in row["grains, cell"]
    good = vp.run_record("bidisperse-30", _analysis(4, 0.70, 12.0))
    row = _cells(vp.mixture_table([record, good]))
    assert row["φ bulk ± std"] == "0.7000 ± 0.0020 (layers) (1/2)"
    assert row["Nc"] == "12.00 (1/2)"


def test_plan_cell_gives_a_bulk(vp):
    pops = vp.load_populations("bidisperse-30")
    lateral, n, note = vp.plan_cell(pops, 3000, 8.0, 7.0, 3.0)
    assert (lateral, n) == (3.0, 3000) and "8 d -> 3 d" in note
    lateral, n, note = vp.plan_cell(pops, 1000, 4.0, 7.0, 3.0)
    assert lateral == 3.0 and n > 1000 and vp.expected_column(pops, n, lateral) >= 7.0
    assert vp.plan_cell(vp.load_populations("isometric"), 3000, 8.0, 7.0, 3.0) == (8.0, 3000, None)


STUDY_RUNS = Path(__file__).resolve().parents[1] / "benchmarks" / "study_runs.py"


@pytest.fixture(scope="module")
def study_runs():
    spec = importlib.util.spec_from_file_location("study_runs", STUDY_RUNS)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_study_page_is_up_to_date(study_runs, tmp_path):
    """docs/study.md and its figures are what ``python benchmarks/study_runs.py page`` generates
    from the kept runs of benchmarks/study/ now: rerun it after changing them."""
    out = study_runs.page(study_runs.KEPT, tmp_path / "study.md", tmp_path / "study" / "figures")
    assert out.read_bytes() == study_runs.PAGE.read_bytes(), "docs/study.md is stale: run `python benchmarks/study_runs.py page`"
    assert out.read_text(encoding="utf-8").startswith("<!-- Generated by `python benchmarks/study_runs.py page`")
    figures = sorted(p.name for p in (tmp_path / "study" / "figures").glob("*.png"))
    assert figures == sorted(f"{stem}.png" for stem, _ in study_runs.PAGE_FIGURES_CAPTIONS)
    for name in figures:
        assert f"](study/figures/{name})" in out.read_text(encoding="utf-8"), name
        assert (tmp_path / "study" / "figures" / name).read_bytes() == (study_runs.PAGE_FIGURES / name).read_bytes(), name
    # the same kept runs give the same bytes
    again = study_runs.page(study_runs.KEPT, tmp_path / "again.md", tmp_path / "study" / "figures")
    assert again.read_bytes() == out.read_bytes()

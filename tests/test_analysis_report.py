"""analyze_packing / analyze_run / ``granpack analyze``: the analysis.json contract and degenerate packings."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from packing_builders import cubic_cubes, random_pinacoids, single, sphere_column

from granpack.analysis import AnalysisWarning, Equilibrium, analyze_packing, analyze_run
from granpack.cli import main
from granpack.errors import InputError
from granpack.io.gsd import write_packing
from granpack.shapes import Pinacoid, Sphere

CONTRACT = {
    "solid_fraction": {"bulk", "std", "profile_z", "profile_phi"},
    "coordination": {"N", "Ns", "Nd", "Nt", "Nc", "rattler_fraction"},
    "order": {"Q00", "Q22", "director"},
    "pair_correlation": {"r", "g"},
    "equilibrium": {"max_net_force", "max_net_torque", "kinetic_energy", "wall_force_over_weight"},
    "interpenetration": {"max", "mean", "expansion_k"},
    "homogeneity": {"z", "proportions"},
}


@pytest.mark.parametrize("layers", [1, 6])
def test_grains_at_rest_on_the_wall_carry_their_weight(layers):
    packing = sphere_column(3, layers) if layers > 1 else cubic_cubes(3, 1)[0]
    eq = Equilibrium().compute(packing)
    assert eq.figures["wall_force_over_weight"] == pytest.approx(1.0, abs=1e-12)
    assert eq.passed and eq.warnings == []


def test_analyze_run_writes_the_contract(tmp_path):
    packing, _ = cubic_cubes(3, 12)
    write_packing(tmp_path / "final.gsd", packing)
    result = analyze_run(tmp_path)
    data = json.loads((tmp_path / "analysis.json").read_text())
    for key, fields in CONTRACT.items():
        assert fields <= set(data[key]), key
    assert {"n_particles", "populations", "seed", "version"} <= set(data)
    assert data["n_particles"] == 108 and data["seed"] == 3
    assert data["populations"][0]["name"] == "cubes" and data["populations"][0]["n"] == 108
    assert data["populations"][0]["volume_fraction"] == pytest.approx(1.0)
    # the figures of this packing: space-filling cubes with triple face contacts, loaded by their weight
    assert data["solid_fraction"]["bulk"] == pytest.approx(1.0, abs=1e-12)
    assert data["coordination"]["Nt"] == 6.0 and data["coordination"]["Nc"] == 18.0
    assert data["coordination"]["rattler_fraction"] == 0.0
    assert data["equilibrium"]["wall_force_over_weight"] == pytest.approx(1.0, abs=1e-12)
    assert data["interpenetration"]["expansion_k"] == 0.0
    assert data["order"]["Q00"] == pytest.approx(1.0) and data["order"]["Q22"] == pytest.approx(1.0)
    assert len(data["order"]["director"]) == 3
    assert len(data["pair_correlation"]["r"]) == len(data["pair_correlation"]["g"]) == 43  # r_max = half of 3 e, bins 0.02
    assert len(data["solid_fraction"]["profile_z"]) == len(data["solid_fraction"]["profile_phi"])
    assert data["homogeneity"]["proportions"]["cubes"][0] == pytest.approx(1.0)
    assert data["warnings"] == [] and result["solid_fraction"]["bulk"] == data["solid_fraction"]["bulk"]


def test_contact_types_from_force_bearing_points_with_gap_rule_and_detection_types(tmp_path):
    """Unloading one side of every lateral face contact of the cube stack makes those contacts
    double under the force rule; the gap rule and the detection types still see triple contacts."""
    packing, _ = cubic_cubes(3, 12)
    c = packing.contacts
    for m in np.flatnonzero(np.abs(c.normal[:, 2]) < 0.5):
        c.impulse[c.point_start[m] + 2:c.point_start[m] + 4] = 0.0  # two adjacent corners of the square
    write_packing(tmp_path / "final.gsd", packing)
    analyze_run(tmp_path)
    co = json.loads((tmp_path / "analysis.json").read_text())["coordination"]
    assert CONTRACT["coordination"] | {"with_rattlers", "n_analysed", "force_tol"} <= set(co)
    assert {k: co[k] for k in ("N", "Ns", "Nd", "Nt", "Nc")} == {"N": 6.0, "Ns": 0.0, "Nd": 4.0, "Nt": 2.0, "Nc": 14.0}
    assert co["with_rattlers"]["Nc"] == 14.0 and co["rattler_fraction"] == 0.0
    for key in ("gap_rule", "geometric"):
        assert {k: co[key][k] for k in ("N", "Ns", "Nd", "Nt", "Nc")} == {"N": 6.0, "Ns": 0.0, "Nd": 0.0, "Nt": 6.0, "Nc": 18.0}
        assert co[key]["rattler_fraction"] == 0.0 and co[key]["with_rattlers"]["Nt"] == 6.0
        assert co[key]["same_type_as_force"] == pytest.approx(1 / 3)  # the vertical and wall contacts: 108 of 324
    assert co["type_rule"] == "force-bearing points" and co["gap_tol"] == 1e-4 and co["point_tol"] == 1e-3


def test_two_populations_in_the_json(tmp_path, rng):
    packing = random_pinacoids(300, rng, lateral=5.0, height=12.0)
    write_packing(tmp_path / "final.gsd", packing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)  # random positions: equilibrium fails, that is fine
        analyze_run(tmp_path)
    data = json.loads((tmp_path / "analysis.json").read_text())
    assert [p["name"] for p in data["populations"]] == ["large", "small"]
    assert set(data["homogeneity"]["proportions"]) == {"large", "small"}
    assert sum(p["volume_fraction"] for p in data["populations"]) == pytest.approx(1.0)


def test_a_sphere_packing_at_rest_has_no_analysis_warning():
    """Spheres have no orientation: their nan order parameters are no warning (a campaign counts
    the warnings of each run, and a sphere run would count one for nothing)."""
    from packing_builders import fcc_spheres

    with warnings.catch_warnings():
        warnings.simplefilter("error", AnalysisWarning)
        result = analyze_packing(fcc_spheres(3, 6)[0])
    assert result["warnings"] == [] and result["bulk"]["valid"]
    assert math.isnan(result["order"]["Q00"]) and result["order"]["n_analysed"] == 0


@pytest.mark.parametrize(
    "packing",
    [
        single(Pinacoid.family("isometric"), position=(1.0, 1.0, 0.4)),
        single(Sphere(1.0), position=(1.0, 1.0, 0.5)),
        cubic_cubes(3, 3)[0],
        random_pinacoids(100, np.random.default_rng(2), contacts_per_particle=0.0),
    ],
    ids=["one-pinacoid", "one-sphere", "too-thin", "no-contacts"],
)
def test_degenerate_packings_warn_and_give_nan(packing, tmp_path):
    with pytest.warns(AnalysisWarning):
        result = analyze_packing(packing)
    assert result["warnings"]
    no_bulk = packing.n_particles == 1 or packing.contacts.n_manifolds > 0  # the no-contact pile is 12 d high
    assert math.isnan(result["solid_fraction"]["bulk"]) == no_bulk
    assert math.isnan(result["order"]["Q00"]) == no_bulk
    assert np.all(np.isnan(result["pair_correlation"]["g"])) == no_bulk
    assert math.isnan(result["coordination"]["N"])
    assert math.isnan(result["interpenetration"]["expansion_k"])
    # still written as strict JSON (nan -> null)
    write_packing(tmp_path / "final.gsd", packing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)
        analyze_run(tmp_path)
    data = json.loads((tmp_path / "analysis.json").read_text())
    assert data["coordination"]["N"] is None


def test_analyze_run_bad_input(tmp_path):
    with pytest.raises(InputError, match="final.gsd"):
        analyze_run(tmp_path)
    with pytest.raises(InputError, match="not a run folder"):
        analyze_run(tmp_path / "missing")


@pytest.mark.parametrize("content", [None, b"not a gsd file\n" * 10, b""], ids=["missing", "corrupt", "empty"])
def test_cli_analyze_bad_final_gsd_exits_2_with_one_line(tmp_path, capsys, content):
    if content is not None:
        (tmp_path / "final.gsd").write_bytes(content)
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "final.gsd" in err
    assert not (tmp_path / "analysis.json").exists()


def test_cli_analyze_writes_analysis_json(tmp_path, capsys):
    packing, _ = cubic_cubes(3, 12)
    write_packing(tmp_path / "final.gsd", packing)
    with pytest.raises(SystemExit) as exc:
        main(["analyze", str(tmp_path)])
    assert exc.value.code == 0
    assert json.loads((tmp_path / "analysis.json").read_text())["coordination"]["Nc"] == 18.0
    assert "solid fraction" in capsys.readouterr().out


def test_analyze_run_judges_with_the_runs_own_criteria(tmp_path):
    """A run certified by looser criteria reads as it was certified: analysis.json's verdicts use
    the run's [equilibrium] settings (config.toml), not the defaults; options given win."""
    warnings.simplefilter("ignore", AnalysisWarning)  # a short column: bulk figures nan
    from granpack.analysis.report import AnalysisOptions
    from granpack.config import EquilibriumConfig
    from granpack.equilibrium import EquilibriumCriteria, criteria_of

    assert criteria_of(EquilibriumConfig()) == EquilibriumCriteria()  # the plain defaults are the config's
    packing = sphere_column(3, 6)
    point = int(np.argmax(packing.contacts.impulse[:, 2]))
    packing.contacts.impulse[point, 2] *= 1.0001  # one grain off balance by a small force
    write_packing(tmp_path / "final.gsd", packing)
    force = Equilibrium().compute(packing).figures["max_net_force"]
    assert 1e-4 < force < 1e-3  # off by the defaults (1e-4), within 1e-3
    assert analyze_run(tmp_path)["equilibrium"]["force_ok"] is False  # no config: the defaults
    (tmp_path / "config.toml").write_text("[equilibrium]\nforce_tolerance = 1e-3\nwall_tolerance = 1e-3\n")
    judged = analyze_run(tmp_path)["equilibrium"]
    assert judged["force_ok"] is True and judged["wall_ok"] is True
    strict = analyze_run(tmp_path, AnalysisOptions(criteria=EquilibriumCriteria()))["equilibrium"]
    assert strict["force_ok"] is False
    (tmp_path / "config.toml").write_text("[equilibrium]\nforce_tolerance = -1\n")
    with pytest.raises(InputError, match=r"config\.toml: cannot read the run's \[equilibrium\] settings"):
        analyze_run(tmp_path)

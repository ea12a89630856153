"""What granpack says of a config before a run (granpack.advice): the same from `check`, `run`,
a campaign and the Python API, and a grading that its grains cannot represent refused before
anything is written."""

from __future__ import annotations

import math

import pytest

from granpack.advice import GRADING_REFUSAL, USEFUL_NARROWING, advise, column_warning, friction_warning, refusal
from granpack.campaign import load_campaign
from granpack.config import load_config, load_config_dict
from granpack.errors import InputError
from granpack.mixture import Mixture
from granpack.simulation import run_packing
from test_cli import run_main

# a Fuller curve down to 0.001 d poured by 500 grains: a dust of the smallest sizes, no pile
IMPOSSIBLE = """\
n_particles = 500
lateral_size = 3.0

[time_stepping]
time_step = 3e-4

[[populations]]
shape = "sphere"
volume_fraction = 1.0

[populations.grading]
curve = "fuller"
d_min = 0.001
d_max = 1.0
exponent = 0.5
"""


def test_an_impossible_grading_is_refused_in_one_line_by_check_and_run_alike(tmp_path, capsys):
    path = tmp_path / "dust.toml"
    path.write_text(IMPOSSIBLE)
    config = load_config(path)
    mixture = Mixture.from_config(config)
    assert mixture.largest_deviation(0) > GRADING_REFUSAL  # the poured curve misses the requested one
    reason = refusal(config, mixture)
    assert reason is not None and reason.startswith("populations[0].grading (fuller curve from 0.001 d to 1 d)")
    assert "n_particles = 500" in reason and "needs about" in reason and "populations[0].grading.d_min" in reason
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 2 and out == "" and err.strip().splitlines() == [f"error: {reason}"]
    out_dir = tmp_path / "out"
    code, out, err = run_main(["run", str(path), "--out", str(out_dir)], capsys)
    assert code == 2 and err.strip().splitlines() == [f"error: {reason}"]
    assert not out_dir.exists()  # nothing written
    with pytest.raises(InputError, match=r"^populations\[0\]\.grading"):
        run_packing(config, out_dir, progress=False)
    assert not out_dir.exists()


def test_a_campaign_with_an_impossible_mixture_is_refused_before_any_run(tmp_path):
    spec = tmp_path / "campaign.toml"
    grading = IMPOSSIBLE.split("[[populations]]")[1].replace("[populations.grading]", "[mixtures.populations.grading]")
    spec.write_text('[base]\nn_particles = 500\nlateral_size = 3.0\n\n[base.time_stepping]\ntime_step = 3e-4\n\n'
                    '[[mixtures]]\nname = "dust"\n\n[[mixtures.populations]]' + grading)
    with pytest.raises(InputError, match=r"campaign\.toml: mixtures\[0\] \(dust\): populations\[0\]\.grading .* needs about"):
        load_campaign(spec)


def test_one_size_piles_are_never_refused_and_a_graded_pile_of_enough_grains_is_not():
    ball = load_config_dict({"n_particles": 1, "lateral_size": 3.0,
                             "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]})
    assert refusal(ball, Mixture.from_config(ball)) is None  # a ball on a floor is a pile by design
    fuller = {"curve": "fuller", "d_min": 0.25, "d_max": 1.0, "exponent": 0.5}
    graded = load_config_dict({"n_particles": 2000, "lateral_size": 4.0,
                               "populations": [{"shape": "sphere", "volume_fraction": 1.0, "grading": fuller}]})
    assert refusal(graded, Mixture.from_config(graded)) is None
    fewer = graded.model_copy(update={"n_particles": 100})
    assert "less than one largest grain" in refusal(fewer, Mixture.from_config(fewer))


def test_the_column_advice_names_a_narrower_cell_only_where_the_cell_can_be_narrowed():
    def advice(lateral_size, n=300):
        config = load_config_dict({"n_particles": n, "lateral_size": lateral_size,
                                   "populations": [{"shape": "pinacoid", "size": 1.0, "volume_fraction": 1.0}]})
        return config, column_warning(config, Mixture.from_config(config))

    config, at_narrowest = advice(2.06, n=60)
    assert config.narrowest_cell < config.lateral_size < USEFUL_NARROWING * config.narrowest_cell
    assert "(the cell is at its narrowest)" in at_narrowest and "cell of about" not in at_narrowest
    config, wide = advice(6.0)
    fitting = float(wide.split("a cell of about ")[1].split(" d")[0])
    assert config.narrowest_cell < fitting < 6.0
    narrowed, none = advice(fitting)  # the advised cell gives the bulk region
    assert none is None
    assert advice(3.0)[1] is None  # the demo's pile


def test_the_column_in_a_cylinder_stands_on_the_cylinders_area():
    def height(container, n=100):
        config = load_config_dict({"n_particles": n, "lateral_size": 6.0, "container": {"shape": container},
                                   "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]})
        warning = column_warning(config, Mixture.from_config(config))
        return config, float(warning.split("stand about ")[1].split(" d high")[0]), warning

    config, cell, _ = height("periodic")
    assert config.floor_area == 36.0
    config, box, in_box = height("box")
    assert box == cell and "6 d x 6 d box" in in_box
    config, cylinder, in_cylinder = height("cylinder")
    assert config.floor_area == pytest.approx(9.0 * math.pi, rel=1e-15)
    assert cylinder == pytest.approx(cell * 4.0 / math.pi, abs=0.06)  # two digits printed
    assert "6 d cylinder" in in_cylinder and "a cylinder of about" in in_cylinder


def test_the_python_api_warns_as_the_cli_does(tmp_path, capsys):
    config = load_config_dict({"n_particles": 4, "lateral_size": 3.0, "equilibrium": {"max_time": 0.05},
                               "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]})
    expected = advise(config)
    assert any(w.startswith("equilibrium.max_time = 0.05") for w in expected)
    assert any("bulk region" in w for w in expected)
    run_packing(config, tmp_path / "api", progress="lines")
    err = capsys.readouterr().err
    assert [line for line in err.splitlines() if line.startswith("warning: ")] == [f"warning: {w}" for w in expected]


def test_check_says_in_one_line_that_a_frictional_pile_is_analysed_by_the_frictional_rules(tmp_path, capsys):
    settings = {"n_particles": 300, "lateral_size": 3.0,
                "populations": [{"shape": "pinacoid", "size": 1.0, "volume_fraction": 1.0}]}
    assert friction_warning(load_config_dict(settings)) is None
    frictional = load_config_dict({**settings, "solver": {"friction": 0.5}})
    line = friction_warning(frictional)
    assert line.startswith("solver.friction = 0.5: `granpack analyze` applies the frictional rules")
    assert "below 3 force-bearing contact points" in line and "\n" not in line
    assert advise(frictional) == [line]  # the demo's pile, but frictional: no other advice
    path = tmp_path / "frictional.toml"
    path.write_text(frictional.to_toml())
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and [x for x in err.splitlines() if x.startswith("warning: ")] == [f"warning: {line}"]

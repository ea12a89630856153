"""The walls' forces of a container packing: shares of the weight, profiles against the depth,
the vertical stress and the fit of Janssen's law."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from granpack.analysis import Equilibrium, analyze_packing
from granpack.analysis.report import summary_rows
from granpack.analysis.wall_forces import WallForces, janssen_stress, plot_vertical_stress
from packing_builders import cylinder_column, fcc_spheres

pytestmark = pytest.mark.filterwarnings("ignore::granpack.analysis.AnalysisWarning")

M = math.pi / 6  # the weight of a sphere of size 1 (g = 1, unit density)
MU_W = "[container]\nshape = \"cylinder\"\nwall_friction = 0.5\n[solver]\nfriction = 0.3\n"


def test_the_built_column_is_at_rest():
    packing = cylinder_column([0.1, 0.2, 0.3], [0.5, 0.6, 0.7])
    assert Equilibrium().compute(packing).report.max_net_force < 1e-12


def test_spheres_pressed_against_a_cylinder_with_a_known_friction_give_the_exact_shares():
    loads, pushes = [0.1 * M, 0.3 * M], [0.4 * M, 0.8 * M]
    walls = WallForces(z_surface=2.0, wall_friction=0.5).compute(cylinder_column(loads, pushes))
    shares = walls.shares
    assert shares["side_vertical"] == pytest.approx(0.2)
    assert shares["floor_vertical"] == pytest.approx(0.8)
    assert shares["total_vertical"] == pytest.approx(1.0)
    assert shares["side_normal"] == pytest.approx(0.6)
    assert shares["side_mobilised_friction"] == pytest.approx(0.4 / 1.2)
    assert walls.per_wall == {"floor": pytest.approx({"vertical": 0.8, "normal": 0.8, "points": 2}),
                              "cylinder": pytest.approx({"vertical": 0.2, "normal": 0.6, "points": 4})}
    profile = walls.profile
    # depth bins [0, 1) and [1, 2): the top layer at depth 0.5, the bottom one at 1.5
    assert profile["depth"] == pytest.approx([0.5, 1.5])
    assert profile["side_vertical_per_height"] == pytest.approx([2 * 0.3 * M, 2 * 0.1 * M])
    assert profile["side_normal_per_height"] == pytest.approx([2 * 0.8 * M, 2 * 0.4 * M])
    assert profile["wall_normal_stress"] == pytest.approx(profile["side_normal_per_height"] / (2 * math.pi))
    # the cut at depth 0.5 (z = 1.5) passes through the top layer's centres: only the grains above count
    assert profile["vertical_stress"] == pytest.approx([0.0, 2 * (M - 0.3 * M) / math.pi])


def test_the_vertical_stress_below_every_centre_is_the_floor_s():
    walls = WallForces(z_surface=3.2, wall_friction=0.5).compute(cylinder_column([0.1, 0.2, 0.3], [0.5, 0.5, 0.6]))
    assert walls.profile["depth"][-1] == pytest.approx(3.1)
    assert walls.profile["vertical_stress"][-1] == pytest.approx(walls.to_dict()["floor_stress"])
    assert walls.to_dict()["floor_stress"] * math.pi == pytest.approx(2 * (3 * M - 0.6))


def test_a_frictionless_container_puts_all_the_weight_on_the_floor():
    packing = cylinder_column([0.0] * 4, [0.2] * 4)
    walls = WallForces(z_surface=4.0, wall_friction=0.0).compute(packing)
    assert walls.shares["floor_vertical"] == pytest.approx(1.0) and walls.shares["side_vertical"] == 0.0
    assert walls.shares["side_normal"] == pytest.approx(1.6 / (8 * M))
    # hydrostatic: the weight of the layers above each cut, over the section
    lifted = WallForces(z_surface=4.0, wall_friction=0.0).compute(cylinder_column([0.0] * 4, [0.2] * 4, lift=0.05))
    assert lifted.profile["vertical_stress"] == pytest.approx(2 * M * np.arange(1, 5) / math.pi)
    assert lifted.profile["hydrostatic_stress"] == pytest.approx(2 * M / math.pi * (np.arange(4) + 0.5))
    assert all(math.isnan(v) for k, v in walls.janssen.items() if k != "K_wall")


def test_a_column_loaded_as_janssen_says_gives_back_its_k_and_saturation():
    n, length = 12, 2.5
    area, saturation = math.pi, 2 * M / math.pi * length  # the hydrostatic slope 2 m g / A
    # each layer's centre 0.05 above the cut at its bin's mid-depth: the cut there counts it
    cut = janssen_stress(np.arange(n) + 0.5, saturation, length) * area
    layer = np.diff(np.concatenate([[0.0], cut]))[::-1]  # from the floor up, what each layer passes down
    loads = M - 0.5 * layer
    assert (loads >= 0).all()
    walls = WallForces(z_surface=float(n), wall_friction=0.5).compute(
        cylinder_column(loads, loads / 0.4, lift=0.05))
    fit = walls.janssen
    assert fit["saturation_stress"] == pytest.approx(saturation, rel=1e-6)
    assert fit["length"] == pytest.approx(length, rel=1e-6)
    assert fit["K"] == pytest.approx(0.5 / (0.5 * length), rel=1e-6)  # A / P = D / 4 = 0.5
    assert fit["K_saturation"] == pytest.approx(fit["K"], rel=1e-6)
    assert fit["K_mobilised"] == pytest.approx(0.5 / (0.4 * length), rel=1e-6)
    assert fit["r_squared"] == pytest.approx(1.0)
    p = walls.profile
    deep = p["depth"] >= 2.0
    assert fit["K_wall"] == pytest.approx(p["wall_normal_stress"][deep].sum() / p["vertical_stress"][deep].sum())


def test_a_box_names_its_walls_and_a_periodic_cell_has_none():
    walls = WallForces(z_surface=2.0, wall_friction=0.5).compute(cylinder_column([0.1, 0.2], [0.3, 0.3], container="box"))
    assert set(walls.per_wall) == {"floor", "x = 0", "x = L", "y = 0", "y = L"}
    assert walls.per_wall["x = 0"]["normal"] == pytest.approx(0.6 / (4 * M))
    assert walls.per_wall["y = 0"] == {"vertical": 0.0, "normal": 0.0, "points": 0}
    assert walls.to_dict()["perimeter"] == 6.0
    packing, _ = fcc_spheres(3, 5)
    assert "walls" not in analyze_packing(packing)
    with pytest.warns(UserWarning, match="no side walls"):
        assert math.isnan(WallForces().compute(packing).shares["side_vertical"])


def test_a_cylinder_packing_s_analysis_carries_its_walls_and_their_figure():
    from matplotlib.figure import Figure

    n = 12
    loads = np.full(n, 0.2 * M)
    packing = cylinder_column(loads, loads / 0.4, metadata={"seed": 1, "config": MU_W})
    assert packing.wall_friction == 0.5 and packing.friction == 0.3
    result = analyze_packing(packing)
    part = json.loads(json.dumps(result["walls"], default=lambda a: a.tolist()))
    assert part["container"] == "cylinder" and part["wall_friction"] == 0.5
    assert part["side_vertical"] == pytest.approx(0.2) and part["z_surface"] == result["bulk"]["z_surface"]
    assert math.isfinite(part["janssen"]["K"])
    rows = dict(summary_rows(result))
    assert rows["weight on the floor / the side walls"].startswith("0.8000 / 0.2000 W")
    assert "Janssen fit (μ_w = 0.5)" in rows
    ax = Figure().add_subplot()
    assert plot_vertical_stress(ax, part)
    assert len(ax.lines) == 5  # σ_v, hydrostatic, the fit, its saturation, σ_h
    assert not plot_vertical_stress(Figure().add_subplot(), {})

"""The wall effect of a container: volumes at a distance from the side walls, the profiles, the core."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from scipy.integrate import quad

from granpack.analysis import Coordination, Order, PairCorrelation, SolidFraction, analyze_packing
from granpack.analysis._wall_volumes import inset_area, inset_volumes
from granpack.analysis.solid_fraction import in_region
from granpack.analysis.wall_profile import WallProfile, plot_wall_profile
from granpack.box import Box
from granpack.contact.contacts import ContactSet
from granpack.packing import Packing
from granpack.rotations import random_quaternions
from granpack.shapes import ShapeTable, Sphere, platonic
from granpack.state import ParticleState
from packing_builders import H, fcc_spheres, identity_quaternions

pytestmark = pytest.mark.filterwarnings("ignore::granpack.analysis.AnalysisWarning")


def _packing(shape, positions, container, lateral, quaternions=None) -> Packing:
    positions = np.asarray(positions, float).reshape(-1, 3)
    n = len(positions)
    state = ParticleState(box=Box.square(lateral, container), shapes=ShapeTable.from_shapes([shape]),
                          kind=np.zeros(n, np.int64), population=np.zeros(n, np.int64), position=positions,
                          quaternion=identity_quaternions(n) if quaternions is None else quaternions)
    return Packing(state, ContactSet.empty(), H, ["grains"], {"seed": 1})


def _lattice(side: int, layers: int, spacing: float = 1.0, shape=None, container="box") -> Packing:
    """A simple cubic lattice of touching grains filling a ``side`` x ``side`` box, ``layers`` high."""
    cells = np.array(list(itertools.product(range(side), range(side), range(layers))), float)
    return _packing(shape or Sphere(1.0), (cells + 0.5) * spacing, container, side * spacing)


def test_a_sphere_on_the_cylinder_axis_has_the_closed_form_volume_inside_each_radius():
    packing = _packing(Sphere(1.0), [[2.0, 2.0, 3.0]], "cylinder", 4.0)
    insets = np.linspace(0.0, 2.0, 81)
    r = 2.0 - insets
    exact = 4.0 / 3.0 * math.pi * (0.125 - np.clip(0.25 - r * r, 0.0, None) ** 1.5)
    assert np.abs(inset_volumes(packing, (0.0, 10.0), insets) - exact).max() < 3e-4 * math.pi / 6


def test_a_sphere_cut_by_the_slab_and_the_box_corner_against_points():
    rng = np.random.default_rng(5)
    centre = np.array([0.7, 0.6, 3.2])
    packing = _packing(Sphere(1.0), [centre], "box", 4.0)
    insets = np.linspace(0.0, 1.5, 31)
    points = rng.uniform(-0.5, 0.5, (2_000_000, 3))
    points = points[(points**2).sum(axis=1) < 0.25] + centre
    share = np.array([((Box.square(4.0, "box").wall_distance(points) >= e) & (points[:, 2] >= 3.0)).mean() for e in insets])
    assert np.abs(inset_volumes(packing, (3.0, 9.0), insets) - share * math.pi / 6).max() < 2e-3 * math.pi / 6


def _box_lattice_profile(s: float, side: int) -> float:
    """Solid fraction at distance s < 1 from the nearest wall of a simple cubic lattice of touching
    unit spheres filling a ``side`` x ``side`` box: on the level set x = s, y in [s, side - s], the
    disks of radius a of the first column, those at the two ends cut by the lines y = s and
    y = side - s."""
    a2 = 0.25 - (s - 0.5) ** 2
    if a2 <= 0:
        return 0.0
    a = math.sqrt(a2)

    def beyond(h):  # area of the disk of radius a more than h (signed) from its centre
        h = max(min(h, a), -a)
        return a2 * math.acos(max(min(h / a, 1.0), -1.0)) - h * math.sqrt(max(a2 - h * h, 0.0))

    return ((side - 2) * math.pi * a2 + 2 * beyond(s - 0.5)) / (side - 2 * s)


def test_a_cubic_lattice_in_a_box_has_the_exact_lateral_profile():
    side, layers = 4, 4
    profile = WallProfile(z_range=(0.0, float(layers)), bin_width=0.05).compute(_lattice(side, layers))
    edges = np.append(profile.distance - 0.025, profile.distance[-1] + 0.025)
    for k, phi in enumerate(profile.solid_fraction):
        lo, hi = edges[k], edges[k + 1]
        frame = lambda s: 4 * (side - 2 * s)  # noqa: E731 - the level set's length
        weighted = quad(lambda s: _box_lattice_profile(s % 1.0, side - 2 * int(s)) * frame(s), lo, hi, limit=200)[0]
        assert phi == pytest.approx(weighted / quad(frame, lo, hi)[0], abs=1e-3), k
    # each grain-size shell holds one ring of spheres: π/6, as the whole section
    whole = inset_volumes(profile_packing := _lattice(side, layers), (0.0, 4.0), [0.0, 1.0, 2.0])
    rings = -np.diff(whole) / (-np.diff(inset_area(profile_packing.box, np.array([0.0, 1.0, 2.0]))) * 4.0)
    assert rings == pytest.approx([math.pi / 6] * 2, abs=1e-4)
    assert profile.section_solid_fraction == pytest.approx(math.pi / 6, abs=1e-4)
    assert profile.grains.tolist() == [0, 0, 48, 0, 0, 0, 16, 0]  # centres at 0.5 and 1.5 d from the walls
    assert profile.number_density[[2, 6]] == pytest.approx([48 / (2.75 * 4), 16 / (0.75 * 4)])


def test_aligned_cubes_filling_a_box_fill_each_ring_of_the_point_clouds():
    cube = platonic("cube", 1.0)
    edge = 1.0 / math.sqrt(3.0)
    packing = _lattice(4, 3, edge, cube)
    volumes = inset_volumes(packing, (0.0, 3 * edge), [0.0, edge, 2 * edge])
    assert volumes == pytest.approx([48 * cube.volume, 12 * cube.volume, 0.0], rel=1e-12, abs=1e-12)
    # turned at random, the clouds still carry each grain's exact volume
    turned = _packing(cube, packing.state.position, "box", 4 * edge, random_quaternions(48, np.random.default_rng(2)))
    assert inset_volumes(turned, (-1.0, 5.0), [-1.0]) == pytest.approx([48 * cube.volume])


def test_the_core_holds_the_grains_n_wall_from_the_walls_and_its_volume():
    packing = _lattice(4, 6)  # centres 0.5 and 1.5 d from the walls
    region = (0.0, 6.0, True)
    core = in_region(packing, region, n_wall=1.0)
    assert core.sum() == 4 * 6
    assert np.all(packing.box.wall_distance(packing.state.position[core]) >= 1.0)
    assert Coordination((0.0, 6.0), n_wall=1.0).compute(packing).n_analysed == 24
    assert Coordination((0.0, 6.0)).compute(packing).n_analysed == 96
    # the core [1, 3]^2 holds the four inner columns whole
    sf = SolidFraction(z_range=(1.0, 5.0), n_wall=1.0).compute(packing)
    assert sf.bulk == pytest.approx(math.pi / 6, abs=1e-4)
    assert sf.layers == pytest.approx([math.pi / 6] * 4, abs=1e-4)
    assert sf.region_to_dict()["n_wall"] == 1.0


def test_the_core_of_a_cylinder_is_its_references_and_its_density():
    rng = np.random.default_rng(3)
    shape = platonic("cube", 1.0)
    points = rng.uniform(0.0, 8.0, (4000, 3))
    points = points[np.hypot(points[:, 0] - 4.0, points[:, 1] - 4.0) < 3.5][:300]
    packing = _packing(shape, points, "cylinder", 8.0, random_quaternions(len(points), rng))
    core = in_region(packing, (1.0, 7.0, True), 2.0)
    assert Order((1.0, 7.0), n_wall=2.0).compute(packing).n_analysed == core.sum()
    with pytest.warns(UserWarning, match="core's distance from the walls"):
        rdf = PairCorrelation(100, 4.0, (1.0, 7.0), n_wall=2.0).compute(packing)
    assert rdf.n_references == core.sum() and rdf.r[-1] < 2.0
    # an ideal gas reads 1 in the core, neighbours taken over the whole section
    assert np.nanmean(rdf.g[50:]) == pytest.approx(1.0, abs=0.25)


def test_a_periodic_packing_ignores_n_wall_and_has_no_wall_profile():
    packing, _ = fcc_spheres(3, 5)
    for quantity in (SolidFraction(n_wall=2.0), Coordination(n_wall=2.0), Order(n_wall=2.0)):
        plain = type(quantity)().compute(packing).to_dict()
        assert json.dumps(quantity.compute(packing).to_dict(), default=str) == json.dumps(plain, default=str)
    result = analyze_packing(packing)
    assert "wall_profile" not in result and "n_wall" not in result["bulk"]
    with pytest.warns(UserWarning, match="no side walls"):
        assert math.isnan(WallProfile().compute(packing).section_solid_fraction)


def test_a_cylinder_packing_reports_its_core_and_its_profiles():
    packing = _lattice(8, 8, container="cylinder")
    inside = packing.box.wall_distance(packing.state.position) > 0.5
    packing = _packing(Sphere(1.0), packing.state.position[inside], "cylinder", 8.0)
    result = analyze_packing(packing)
    part = result["wall_profile"]
    assert result["bulk"]["n_wall"] == 2.0 and part["container"] == "cylinder"
    assert len(part["distance"]) == 80 and part["distance"][0] == pytest.approx(0.025)
    assert part["solid_fraction"][0] < part["section_solid_fraction"] < 1.0
    assert result["pair_correlation"]["r"][-1] < 2.0
    assert result["coordination"]["n_analysed"] == in_region(packing, (result["bulk"]["z_bottom"], result["bulk"]["z_top"],
                                                                         True), 2.0).sum()


def test_the_profile_figure_draws_from_the_part_or_says_it_cannot(tmp_path):
    from matplotlib.figure import Figure

    profile = WallProfile(z_range=(0.0, 4.0)).compute(_lattice(4, 4))
    ax = Figure().add_subplot()
    assert plot_wall_profile(ax, json.loads(json.dumps(profile.to_dict(), default=lambda a: a.tolist())), core=0.52)
    assert len(ax.lines) == 3  # the profile, the whole section, the core
    assert not plot_wall_profile(Figure().add_subplot(), {}, "N")
    with pytest.raises(ValueError, match="quantity"):
        plot_wall_profile(ax, {}, "rho")

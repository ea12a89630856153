"""Gradings: the distributions' exact curves and moments, the sizes given to the grains, the config."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import integrate

from granpack.advice import settings_warnings
from granpack.config import load_config_dict
from granpack.errors import InputError
from granpack.grading import Grading, achieved_passing, largest_deviation
from granpack.mixture import Mixture

FULLER = Grading.fuller(0.1, 1.0, 0.5)
SIEVES = Grading.sieve_table([0.05, 0.1, 0.25, 0.5, 1.0, 2.0], [0.0, 0.1, 0.3, 0.6, 1.0, 1.0])
LOGNORMAL = Grading.lognormal(0.5, 0.2)


def test_fuller_curve_is_the_truncated_power_law():
    d = np.array([0.1, 0.25, 0.5, 1.0])
    expected = (np.sqrt(d) - math.sqrt(0.1)) / (1.0 - math.sqrt(0.1))
    np.testing.assert_allclose(FULLER.passing_at(d), expected, rtol=1e-14)
    assert FULLER.size_ratio == pytest.approx(10.0)


def test_a_sieve_table_is_interpolated_in_log_size_and_trimmed_to_its_grains():
    assert (SIEVES.d_min, SIEVES.d_max) == (0.05, 1.0)  # the sieve 2.0 that 100 % passed holds no grain
    assert SIEVES.passing_at([0.1, 0.25])[1] == pytest.approx(0.3)
    midway = math.sqrt(0.25 * 0.5)  # half way in log D between two sieves: half way in passing
    assert SIEVES.passing_at([midway])[0] == pytest.approx(0.45, rel=1e-12)


@pytest.mark.parametrize("grading", [FULLER, SIEVES, LOGNORMAL], ids=["fuller", "sieves", "lognormal"])
def test_number_moments_are_exact_against_quadrature_of_the_volume_curve(grading):
    """E_N[D^k] = E_V[D^(k-3)] / E_V[D^-3], by quadrature of dP/dD on a fine log grid."""
    d = np.geomspace(grading.d_min, grading.d_max, 400_001)
    density = np.gradient(grading.passing_at(d), d)  # dP/dD
    inverse_cube = integrate.trapezoid(density * d ** -3.0, d)
    for k in (1, 2, 3):
        numeric = integrate.trapezoid(density * d ** (k - 3.0), d) / inverse_cube
        assert grading.number_moments(k) == pytest.approx(numeric, rel=2e-4), k
    assert grading.mean_cube() == pytest.approx(grading.number_moments(3), rel=1e-12)


def test_the_lognormal_has_the_requested_mean_and_polydispersity_before_its_truncation():
    wide = Grading.lognormal(0.5, 0.2, cut=12.0)
    mean, second = wide.number_moments(1), wide.number_moments(2)
    assert mean == pytest.approx(0.5, rel=1e-12)
    assert math.sqrt(second - mean ** 2) / mean == pytest.approx(0.2, rel=1e-10)


@pytest.mark.parametrize("grading", [FULLER, SIEVES, LOGNORMAL], ids=["fuller", "sieves", "lognormal"])
def test_the_grains_sizes_have_the_distributions_moments_and_volume_curve(grading):
    sizes = grading.sizes(20_000)
    assert np.all(np.diff(sizes) >= 0) and sizes[0] >= grading.d_min and sizes[-1] <= grading.d_max
    for k in (1, 2, 3):
        assert np.mean(sizes ** k) == pytest.approx(grading.number_moments(k), rel=2e-3), k
    # the volume curve of the grains: within a few of the largest grains' volume shares
    assert largest_deviation(grading, sizes, sizes ** 3) < 4 * sizes[-1] ** 3 / np.sum(sizes ** 3) + 1e-3


def test_the_largest_deviation_falls_with_the_number_of_grains():
    gaps = [largest_deviation(FULLER, d, d ** 3) for d in (FULLER.sizes(n) for n in (300, 3000, 30_000))]
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 0.003


def test_achieved_passing_counts_volume_below_each_sieve():
    sizes, volumes = np.array([1.0, 2.0, 3.0]), np.array([1.0, 1.0, 2.0])
    np.testing.assert_allclose(achieved_passing(sizes, volumes, [0.5, 1.0, 2.5, 3.0]), [0.0, 0.25, 0.5, 1.0])


def graded(grading: dict, n: int = 2000, shape: str = "sphere", **extra) -> dict:
    population = {"shape": shape, "volume_fraction": 1.0, "grading": grading}
    return {"n_particles": n, "lateral_size": 6.0, "populations": [population], **extra}


FULLER_KEYS = {"curve": "fuller", "d_min": 0.1, "d_max": 1.0, "exponent": 0.5}


@pytest.mark.parametrize("bad, message", [
    ({"curve": "fuller", "d_min": 1.0, "d_max": 0.5, "exponent": 0.5}, "d_min must be below d_max"),
    ({"curve": "fuller", "d_min": 0.1, "d_max": 1.0, "exponent": 0.0}, "grading.exponent: must be > 0"),
    ({"curve": "fuller", "d_min": 0.1, "d_max": 1.0}, "curve 'fuller' needs exponent"),
    ({"curve": "sieves", "sieves": [4, 8, 16], "percent_passing": [0, 60, 50]}, "must not decrease"),
    ({"curve": "sieves", "sieves": [4, 16, 8], "percent_passing": [0, 50, 100]}, "increasing order"),
    ({"curve": "sieves", "sieves": [4, 8, 16], "percent_passing": [10, 50, 100]}, "from 0 at the first sieve"),
    ({"curve": "sieves", "sieves": [4, 8], "percent_passing": [0, 50, 100]}, "the same length"),
    ({"curve": "lognormal", "mean": 0.5, "polydispersity": 0.2, "d_min": 0.1}, "not a key of curve 'lognormal'"),
    ({"curve": "gaussian"}, "grading.curve: must be 'fuller', 'sieves' or 'lognormal'"),
])
def test_impossible_curves_are_one_line_errors_naming_the_key(bad, message):
    with pytest.raises(InputError) as info:
        load_config_dict(graded(bad))
    text = str(info.value)
    assert "\n" not in text and "populations[0].grading" in text and message in text


def test_a_population_gives_a_size_or_a_grading_not_both():
    with pytest.raises(InputError, match="size: required key is missing"):
        load_config_dict({"populations": [{"shape": "sphere", "volume_fraction": 1.0}]})
    both = graded(FULLER_KEYS)
    both["populations"][0]["size"] = 1.0
    with pytest.raises(InputError, match="not both"):
        load_config_dict(both)


def test_a_sieve_table_in_mm_scales_its_largest_grains_to_1_d():
    config = load_config_dict(graded({"curve": "sieves", "sieves": [4, 8, 16, 31.5],
                                      "percent_passing": [0, 30, 70, 100]}, shape="pinacoid"))
    curve = config.populations[0].grading_curve
    assert curve.d_max == pytest.approx(1.0) and curve.d_min == pytest.approx(4 / 31.5)
    assert config.largest_size == pytest.approx(1.0)
    halved = load_config_dict(graded({"curve": "sieves", "sieves": [4, 8, 16, 31.5], "percent_passing": [0, 30, 70, 100],
                                      "sieve_unit": 63.0}, shape="pinacoid"))
    assert halved.populations[0].grading_curve.d_max == pytest.approx(0.5)


def test_the_time_step_is_judged_in_the_time_unit_of_the_smallest_grain():
    def step_warnings(d_min, time_step):
        config = load_config_dict(graded({**FULLER_KEYS, "d_min": d_min}, time_stepping={"time_step": time_step}))
        return [note for note in settings_warnings(config) if note.startswith("time_stepping.time_step")]

    assert step_warnings(0.25, 5e-3) == []  # 0.01 sqrt(0.25) = 5e-3
    assert "d_min = 0.1 d" in step_warnings(0.1, 5e-3)[0]
    assert step_warnings(0.1, 3e-3) == []  # below 0.01 sqrt(0.1) = 3.16e-3


def test_a_graded_config_round_trips_through_its_resolved_toml():
    import tomllib

    config = load_config_dict(graded(FULLER_KEYS))
    assert "[populations.grading]" in config.to_toml()
    assert load_config_dict(tomllib.loads(config.to_toml())) == config


def test_a_graded_mixture_gives_each_grain_its_size_and_kind():
    config = load_config_dict(graded(FULLER_KEYS, n=3000))
    mixture = Mixture.from_config(config)
    sizes = mixture.sizes[0]
    assert mixture.counts[0] == 3000 and len(sizes) == 3000 and mixture.is_graded
    np.testing.assert_allclose(np.sort(sizes), FULLER.sizes(3000))  # the sizes, in an order drawn from the seed
    assert not np.all(np.diff(sizes) >= 0)
    population = mixture.particle_populations(np.random.default_rng(3))
    kinds = mixture.particle_kinds(population)
    table = mixture.particle_shape_table()
    assert table.n_kinds == 3001 and np.all(np.sort(kinds) == np.arange(1, 3001))
    np.testing.assert_allclose(2 * table.radius[kinds], sizes, rtol=1e-14)  # grain m has size m
    assert mixture.solid_volumes[0] == pytest.approx(math.pi / 6 * np.sum(sizes ** 3))
    # the same seed, the same sizes in the same order; another seed, another order
    assert np.array_equal(Mixture.from_config(config).sizes[0], sizes)
    assert not np.array_equal(Mixture.from_config(config.with_seed(2)).sizes[0], sizes)


def test_graded_and_one_size_populations_share_the_volume_by_their_mean_grain_volume():
    config = load_config_dict({"n_particles": 4000, "lateral_size": 6.0, "populations": [
        {"shape": "sphere", "volume_fraction": 0.5, "grading": FULLER_KEYS},
        {"shape": "pinacoid", "size": 1.0, "volume_fraction": 0.5}]})
    mixture = Mixture.from_config(config)
    assert mixture.achieved_shares == pytest.approx([0.5, 0.5], abs=2e-3)
    assert mixture.particle_kinds(np.array([0, 1, 0, 1])).tolist() == [2, 1, 3, 1]


def test_a_graded_pinacoid_is_the_unit_pinacoid_scaled_exactly():
    from granpack.shapes import Pinacoid

    config = load_config_dict(graded(FULLER_KEYS, n=50, shape="pinacoid"))
    mixture = Mixture.from_config(config)
    table = mixture.particle_shape_table()
    k = 1 + int(np.argmax(mixture.sizes[0]))
    size = mixture.sizes[0][k - 1]
    exact = Pinacoid.from_size(size)
    assert table.volume[k] == pytest.approx(exact.volume, rel=1e-13)
    np.testing.assert_allclose(table.inertia[k], exact.principal_moments, rtol=1e-12)
    assert 2 * table.radius[k] == pytest.approx(size, rel=1e-13)


def test_a_graded_pile_pours_and_its_final_state_reads_back(tmp_path):
    from granpack.io.gsd import read_packing
    from granpack.simulation import run_packing

    config = load_config_dict(graded(FULLER_KEYS | {"d_min": 0.3}, n=200, shape="pinacoid", lateral_size=2.1,
                                     equilibrium={"max_time": 1.0}))
    summary = run_packing(config, tmp_path, progress=False)
    packing = read_packing(tmp_path / "final.gsd")
    mixture = Mixture.from_config(config)
    assert packing.state.shapes.n_kinds == 201 and summary["final"]["max_overlap"] < 5e-3
    sizes = 2 * packing.state.radius
    np.testing.assert_allclose(np.sort(sizes), np.sort(mixture.sizes[0]), rtol=1e-12)
    np.testing.assert_allclose(packing.state.mass, (packing.state.shapes.shapes[0].volume * sizes ** 3), rtol=1e-12)
    # its analysis has the size classes, its figures the sieve curve and the classes' profiles
    from granpack.analysis.report import analyze_run
    from granpack.figures import run_figures

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze_run(tmp_path)
    assert sum(result["size_classes"]["counts"]) == 200 and result["populations"][0]["sizes"]["max"] <= 1.0
    files = run_figures(tmp_path)
    assert {p.name for p in files} >= {"grading.png", "grading.svg"}


def two_sizes_stacked(base=None):
    """A lattice packing (the simple-cubic column of unit spheres by default) with its lower half
    replaced by spheres of 0.5 d in the same places, the contacts and forces kept: the small ones
    sink, by construction."""
    from dataclasses import replace

    from packing_builders import sphere_column

    from granpack.shapes import ShapeTable, Sphere

    column = base if base is not None else sphere_column(4, 8)
    state = column.state
    small = state.position[:, 2] < 0.5 * state.position[:, 2].max()
    kind = small.astype(np.int64)
    shapes = ShapeTable.from_shapes([Sphere(1.0), Sphere(0.5)])
    moved = type(state)(box=state.box, shapes=shapes, kind=kind, population=kind, position=state.position,
                        quaternion=state.quaternion)
    return replace(column, state=moved, population_names=["large", "small"]), small


def test_size_classes_of_a_stack_with_its_small_grains_below():
    from granpack.analysis.size_classes import SizeClasses

    packing, small = two_sizes_stacked()
    classes = SizeClasses([0.4, 0.75, 1.0], z_range=(2.0, 6.0)).compute(packing)
    share_small = 0.125 / 1.125  # 64 grains of volume (pi/6) 0.5^3 against 64 of pi/6
    np.testing.assert_array_equal(classes.counts, [64, 64])
    np.testing.assert_allclose(classes.volume_shares, [share_small, 1 - share_small], rtol=1e-12)
    np.testing.assert_allclose(classes.passing, [0.0, share_small, 1.0], atol=1e-12)
    np.testing.assert_allclose(classes.profile[0], [1, 1, 1, 1, 0, 0, 0, 0], atol=1e-12)  # segregated: small below
    np.testing.assert_allclose(classes.z, np.arange(8) + 0.5)
    # the bulk's sieve curve: its grains only (z from 2 to 6: two layers of each size)
    np.testing.assert_allclose(classes.passing_bulk, [0.0, share_small, 1.0], atol=1e-12)
    np.testing.assert_array_equal(classes.bulk_counts, [32, 32])


def test_size_classes_count_the_contacts_and_rattlers_of_each_class():
    from packing_builders import fcc_spheres

    from granpack.analysis.coordination import Coordination
    from granpack.analysis.size_classes import SizeClasses

    packing, small = two_sizes_stacked(fcc_spheres(4, 6)[0])
    z = packing.state.position[:, 2]
    z_range = (float(np.quantile(z, 0.2)), float(np.quantile(z, 0.8)))
    co = Coordination(z_range).compute(packing)
    classes = SizeClasses([0.4, 0.75, 1.0], z_range=z_range, coordination=co).compute(packing)
    bulk = (z >= z_range[0]) & (z <= z_range[1])
    contacts = co.per_particle.sum(axis=1)
    for k, members in enumerate((small, ~small)):
        chosen = bulk & members & ~co.rattlers
        assert chosen.any() and classes.coordination_by_class[k] == pytest.approx(contacts[chosen].mean())
        assert classes.rattler_fraction_by_class[k] == pytest.approx(co.rattlers[bulk & members].mean())
    assert classes.coordination_by_class[0] == pytest.approx(12.0)  # the fcc lattice: 12 neighbours


def test_an_analysis_reports_size_classes_for_a_packing_of_several_sizes_only():
    from packing_builders import sphere_column

    from granpack.analysis.report import AnalysisOptions, analyze_packing

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze_packing(two_sizes_stacked()[0], AnalysisOptions(sieves=(0.4, 0.75, 1.0)))
        assert result["size_classes"]["counts"].tolist() == [64, 64]
        assert "size_classes" not in analyze_packing(sphere_column(4, 8))


# --- grains of very different sizes, hand-built ----------------------------------------------------


def hexagonal_layer_with(small_positions, small_diameters, rows: int = 4, columns: int = 4):
    """A periodic hexagonal layer of touching unit spheres on the wall (each held by its six
    neighbours, so the layer cannot spread) and small spheres placed at ``small_positions``."""
    from granpack import Box, ShapeTable, Sphere
    from granpack.state import ParticleState

    pitch = math.sqrt(3.0) / 2.0
    big = [[c + 0.5 * (r % 2) + 0.25, (r + 0.5) * pitch, 0.5] for r in range(rows) for c in range(columns)]
    positions = np.array(big + [list(p) for p in small_positions], dtype=float)
    shapes = ShapeTable.from_shapes([Sphere(1.0)] + [Sphere(d) for d in small_diameters])
    kind = np.array([0] * len(big) + list(range(1, len(small_diameters) + 1)))
    n = len(positions)
    return ParticleState(box=Box(float(columns), rows * pitch), shapes=shapes, kind=kind, population=(kind > 0).astype(int),
                         position=positions, quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))), len(big)


def forces_on(contacts, body: int, h: float) -> list[np.ndarray]:
    """The resultant force on ``body`` of each of its contact manifolds."""
    out = []
    for k in range(contacts.n_manifolds):
        points = slice(contacts.point_start[k], contacts.point_start[k + 1])
        force = contacts.impulse[points].sum(axis=0) / h
        if contacts.body_i[k] == body:
            out.append(force)
        elif contacts.body_j[k] == body:
            out.append(-force)
    return out


def test_a_ball_of_a_tenth_rests_on_a_ball_of_d_carrying_its_weight():
    from granpack.nscd import StepParameters, step

    top = [1.25, 0.5 * math.sqrt(3.0) / 2.0, 1.0 + 0.05 + 1e-3]  # above the first big ball, 1e-3 d clear
    state, n_big = hexagonal_layer_with([top], [0.1])
    params, warm = StepParameters(), None
    for _ in range(400):
        warm, _ = step(state, params, warm)
    small = n_big
    assert state.position[small, 2] == pytest.approx(1.05, abs=2e-6)
    np.testing.assert_allclose(state.position[small, :2], top[:2], atol=1e-9)
    forces = forces_on(warm, small, params.time_step)
    assert len(forces) == 1 and forces[0] == pytest.approx([0.0, 0.0, state.mass[small]], rel=1e-6, abs=1e-12)
    on_wall = np.repeat(warm.body_j == -1, np.diff(warm.point_start))
    assert warm.impulse[on_wall, 2].sum() / params.time_step == pytest.approx(state.mass.sum(), rel=1e-6)


def test_a_ball_of_a_fifth_rests_in_the_crevice_of_three_balls_of_d():
    """The crevice above three touching unit balls: a ball of diameter below 2 (1/sqrt(3) - 1/2) =
    0.155 d falls through it; one of 0.2 d rests at the height h with (1/sqrt(3))^2 + h^2 = 0.6^2
    above their centres, each of the three contacts carrying m g / (3 cos theta), cos theta = h / 0.6."""
    from granpack.nscd import StepParameters, step

    pitch = math.sqrt(3.0) / 2.0
    # the crevice between the balls (0, 0), (1, 0) of row 0 and (0, 0) of row 1 (shifted by 1/2)
    centres = np.array([[0.25, 0.5 * pitch], [1.25, 0.5 * pitch], [0.75, 1.5 * pitch]])
    axis = centres.mean(axis=0)
    h = math.sqrt(0.6 ** 2 - 1.0 / 3.0)
    state, n_big = hexagonal_layer_with([[axis[0], axis[1], 0.5 + h + 2e-3]], [0.2])
    params, warm = StepParameters(), None
    for _ in range(600):
        warm, _ = step(state, params, warm)
    small = n_big
    assert state.position[small, 2] == pytest.approx(0.5 + h, abs=5e-6)
    np.testing.assert_allclose(state.position[small, :2], axis, atol=1e-7)
    forces = forces_on(warm, small, params.time_step)
    loaded = [f for f in forces if np.linalg.norm(f) > 1e-9]
    assert len(loaded) == 3
    magnitude = state.mass[small] / (3.0 * h / 0.6)
    for f in loaded:
        assert np.linalg.norm(f) == pytest.approx(magnitude, rel=1e-5)
    assert np.sum(loaded, axis=0) == pytest.approx([0.0, 0.0, state.mass[small]], rel=1e-6, abs=1e-9)
    np.testing.assert_allclose(state.position[:n_big, 2], 0.5, atol=1e-5)  # the layer holds

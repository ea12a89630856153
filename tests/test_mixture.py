"""Mixtures: particle counts reproduce the requested volume shares as well as integers allow."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from granpack.config import load_config_dict
from granpack.mixture import Mixture, volume_share_counts
from granpack.shapes import ConvexPolyhedron, Pinacoid, ShapeTable, Sphere


def share_errors(counts, shares, volumes) -> tuple[float, float]:
    """(largest, total) |achieved - requested| volume share error."""
    solid = np.asarray(counts) * np.asarray(volumes)
    err = np.abs(solid / solid.sum() - np.asarray(shares))
    return float(err.max()), float(err.sum())


def brute_force(shares, volumes, n) -> tuple[float, float]:
    """Best (largest, total) error over every composition of n obeying the same rules."""
    positive = [k for k, f in enumerate(shares) if f > 0]
    minimum = 1 if n >= len(positive) else 0
    best = (math.inf, math.inf)
    for head in itertools.product(range(minimum, n + 1), repeat=len(positive) - 1):
        last = n - sum(head)
        if last < minimum:
            continue
        counts = np.zeros(len(shares), dtype=int)
        counts[positive] = list(head) + [last]
        best = min(best, share_errors(counts, shares, volumes))
    return best


@pytest.mark.parametrize("case", range(60))
def test_counts_are_optimal_against_brute_force(case):
    rng = np.random.default_rng(case)
    k = int(rng.integers(2, 5))
    shares = rng.dirichlet(np.ones(k))
    if case % 5 == 0:
        shares[0] = 0.0
        shares /= shares.sum()
    volumes = np.exp(rng.uniform(-4.0, 0.0, k))  # volume ratios up to e^4 ~ 55
    n = int(rng.integers(1, 25 if k < 4 else 13))
    counts = volume_share_counts(shares, volumes, n)
    assert counts.dtype == np.int64 and counts.sum() == n
    assert np.all(counts[shares == 0] == 0)
    positive = shares > 0
    if n >= positive.sum():
        assert np.all(counts[positive] >= 1)
    got = share_errors(counts, shares, volumes)
    best = brute_force(shares, volumes, n)
    assert got[0] == pytest.approx(best[0], abs=1e-12) and got[1] == pytest.approx(best[1], abs=1e-12)


def test_every_positive_population_gets_a_grain():
    counts = volume_share_counts([0.998, 0.001, 0.001], [1e-3, 1.0, 1.0], 3)
    assert counts.tolist() == [1, 1, 1]
    assert volume_share_counts([0.5, 0.5], [1.0, 1.0], 1).sum() == 1  # N too small: no minimum


def test_bidisperse_ratio_three_matches_physics_4_1():
    # N_s / N_l = 27 f_s / (1 - f_s) (docs/method/grains.md#mixtures-volume-shares-to-counts) rounded to integers summing to N
    f_small, n = 0.3, 3000
    counts = volume_share_counts([1 - f_small, f_small], [1.0, 1.0 / 27.0], n)
    ideal_large = n / (1 + 27 * f_small / (1 - f_small))
    assert counts[0] in (math.floor(ideal_large), math.ceil(ideal_large))
    assert counts.tolist() == [239, 2761]
    solid = counts * np.array([1.0, 1.0 / 27.0])
    # within half of one large grain's share of the solid volume
    assert abs(solid[1] / solid.sum() - f_small) <= 0.5 / solid.sum()


@pytest.mark.parametrize("f_small", [0.03, 0.13, 0.23, 0.41, 0.55, 0.64, 0.92])
def test_study_mixtures_within_rounding(f_small):
    volumes = np.array([1.0, 1.0 / 27.0])
    counts = volume_share_counts([1 - f_small, f_small], volumes, 3000)
    largest, _ = share_errors(counts, [1 - f_small, f_small], volumes)
    # moving one grain from a population to the other changes the share by less than v_large / W
    assert largest <= volumes[0] / float(np.sum(counts * volumes))


def mixed_config(n=500):
    return load_config_dict(
        {
            "n_particles": n,
            "populations": [
                {"shape": "pinacoid", "size": 1.0, "aspect": [2.0, 1.0], "volume_fraction": 0.5},
                {"shape": "sphere", "size": 0.5, "volume_fraction": 0.3},
                {"shape": "polyhedron", "size": 0.4, "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                 "volume_fraction": 0.2, "name": "tetra"},
            ],
        }
    )


def test_from_config_shapes_and_counts():
    mixture = Mixture.from_config(mixed_config())
    pinacoid, sphere, tetra = mixture.shapes
    assert isinstance(pinacoid, Pinacoid) and pinacoid.elongation == pytest.approx(2.0)
    assert isinstance(sphere, Sphere) and sphere.diameter == 0.5
    assert isinstance(tetra, ConvexPolyhedron) and tetra.size == pytest.approx(0.4)
    assert [s.size for s in mixture.shapes] == pytest.approx([1.0, 0.5, 0.4])
    assert mixture.n_particles == 500 and mixture.counts.sum() == 500
    assert mixture.names == ["pinacoid-1-2x1", "sphere-0.5", "tetra"]
    assert mixture.achieved_shares.sum() == pytest.approx(1.0)
    assert np.abs(mixture.achieved_shares - mixture.requested_shares).max() < mixture.particle_volumes[0] / float(
        np.sum(mixture.counts * mixture.particle_volumes))
    with pytest.raises(ValueError):
        mixture.counts[0] = 3


def test_from_config_counts_are_optimal():
    mixture = Mixture.from_config(mixed_config(n=20))
    got = share_errors(mixture.counts, [0.5, 0.3, 0.2], mixture.particle_volumes)
    assert got == pytest.approx(brute_force([0.5, 0.3, 0.2], mixture.particle_volumes, 20), abs=1e-12)


def test_table_rows():
    mixture = Mixture.from_config(mixed_config())
    rows = mixture.table()
    assert [r["population"] for r in rows] == mixture.names
    assert set(rows[0]) == {"population", "shape", "size", "aspect", "count", "requested_share", "achieved_share",
                            "particle_volume", "size_definition", "shapes"}
    assert rows[0]["aspect"] == [2.0, 1.0] and rows[1]["aspect"] is None
    assert [r["shape"] for r in rows] == ["pinacoid", "sphere", "polyhedron"]
    assert [r["count"] for r in rows] == mixture.counts.tolist()
    assert rows[1]["particle_volume"] == pytest.approx(math.pi * 0.5**3 / 6)
    assert [r["requested_share"] for r in rows] == [0.5, 0.3, 0.2]
    assert [r["achieved_share"] for r in rows] == pytest.approx(mixture.achieved_shares.tolist())


def test_particle_populations_are_shuffled_counts(rng):
    mixture = Mixture.from_config(mixed_config())
    kinds = mixture.particle_populations(rng)
    assert kinds.shape == (500,) and kinds.dtype == np.int64
    assert np.bincount(kinds, minlength=3).tolist() == mixture.counts.tolist()
    assert np.any(np.diff(kinds) < 0)  # not sorted
    again = mixture.particle_populations(np.random.default_rng(12345))
    assert np.array_equal(kinds, again)


def test_particle_shape_table_kinds_are_populations():
    mixture = Mixture.from_config(mixed_config())
    table = mixture.particle_shape_table()
    assert isinstance(table, ShapeTable) and table.n_kinds == 3
    assert table.is_sphere.tolist() == [False, True, False]
    assert table.volume == pytest.approx(mixture.particle_volumes)
    assert table.radius == pytest.approx([0.5, 0.25, 0.2])


def test_zero_share_population_gets_no_grain():
    cfg = load_config_dict(
        {"n_particles": 10, "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0},
                                            {"shape": "sphere", "size": 0.5, "volume_fraction": 0.0}]}
    )
    mixture = Mixture.from_config(cfg)
    assert mixture.counts.tolist() == [10, 0]
    assert mixture.achieved_shares.tolist() == [1.0, 0.0]


def test_the_pile_height_is_the_solid_volume_over_the_cell_at_its_solid_fraction():
    from granpack.mixture import PHI_MIXED_SIZES, PHI_ONE_SIZE

    one = load_config_dict({"n_particles": 100, "lateral_size": 3.0,
                            "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]})
    assert Mixture.from_config(one).pile_height(9.0, 0.5) == pytest.approx(100 * math.pi / 6 / (0.5 * 9.0))
    assert Mixture.from_config(one).pile_height(9.0) == pytest.approx(100 * math.pi / 6 / (PHI_ONE_SIZE * 9.0))
    two = load_config_dict({"n_particles": 100, "lateral_size": 3.0, "populations": [
        {"shape": "sphere", "size": 1.0, "volume_fraction": 0.5, "name": "a"},
        {"shape": "sphere", "size": 0.5, "volume_fraction": 0.5, "name": "b"}]})
    mixture = Mixture.from_config(two)
    solid = float((mixture.counts * mixture.particle_volumes).sum())
    assert mixture.pile_height(9.0) == pytest.approx(solid / (PHI_MIXED_SIZES * 9.0))

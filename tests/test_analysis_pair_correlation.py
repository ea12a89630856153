"""Pair correlation g(r) in a bi-periodic slab (docs/method/analysis.md#pair-correlation): FCC shells, ideal gas, freud."""

from __future__ import annotations

import math

import freud
import numpy as np
import pytest
from packing_builders import fcc_spheres, points

from granpack.analysis import AnalysisWarning, NotComputedError, PairCorrelation
from granpack.analysis.pair_correlation import ball_in_slab

# FCC neighbour shells in units of the nearest-neighbour distance, with their sizes
FCC_SHELLS = [(1.0, 12), (math.sqrt(2.0), 6), (math.sqrt(3.0), 24), (2.0, 12), (math.sqrt(5.0), 24)]


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        PairCorrelation().g


def test_fcc_peaks_and_shell_counts():
    packing, a = fcc_spheres(4, 6)
    # width 0.03: no shell distance falls near a bin edge; r_max 2.4 < half the period (2.83)
    rdf = PairCorrelation(bins=80, r_max=2.4, z_range=(0.0, 9.0), interior_only=True).compute(packing)
    assert rdf.n_references == 6 * 32  # the six (001) layers at least 2.4 d from both slab planes
    shell_bins = [int(r / 0.03) for r, _ in FCC_SHELLS]
    # g is zero everywhere but in the bins of the shell distances
    assert sorted(np.flatnonzero(rdf.g > 0)) == shell_bins
    np.testing.assert_allclose(rdf.r[shell_bins], [r for r, _ in FCC_SHELLS], atol=0.015)
    # running coordination: 12, 18, 42, 54, 78 neighbours
    expected = np.cumsum([count for _, count in FCC_SHELLS])
    np.testing.assert_allclose(rdf.coordination[shell_bins], expected, rtol=1e-12)
    assert rdf.coordination[shell_bins[0] - 1] == 0.0
    # the peak heights are n_shell / (rho 4 pi r^2 dr) with rho = 4 / a^3 (every reference sees the whole shell)
    rho = len(packing.state.position[(packing.state.position[:, 2] <= 9.0)]) / (packing.box.area * 9.0)
    shells = np.diff(4.0 / 3.0 * math.pi * rdf.bin_edges**3)
    np.testing.assert_allclose(rdf.g[shell_bins], [c / (rho * shells[b]) for (_, c), b in zip(FCC_SHELLS, shell_bins)], rtol=1e-12)


def test_fcc_default_slab_has_the_same_peaks():
    packing, _ = fcc_spheres(4, 6)
    rdf = PairCorrelation(bins=80, r_max=2.4).compute(packing)
    assert rdf.warnings == []
    assert sorted(np.flatnonzero(rdf.g > 0)) == [int(r / 0.03) for r, _ in FCC_SHELLS]
    # the nearest-neighbour shell dominates the running coordination
    assert rdf.coordination[int(1.0 / 0.03)] == pytest.approx(12.0, rel=0.1)


def _ideal_gas(rng, n=4000, lateral=8.0):
    return points(rng.random((n, 3)) * lateral, lateral)


@pytest.mark.parametrize("z_range", [(0.0, 8.0), (2.5, 5.5)])
def test_ideal_gas_in_slab_gives_one(rng, z_range):
    """Truncated-shell normalisation: no bias even when most references sit near the slab faces."""
    packing = _ideal_gas(rng)
    rdf = PairCorrelation(bins=30, r_max=3.0, z_range=z_range).compute(packing)
    z = packing.state.position[:, 2]
    n_slab = int(((z >= z_range[0]) & (z <= z_range[1])).sum())
    rho = n_slab / (packing.box.area * (z_range[1] - z_range[0]))
    # expected ordered-pair count per bin, then a Poisson bound (pairs are counted twice)
    naive = rdf.n_references * rho * np.diff(4.0 / 3.0 * math.pi * rdf.bin_edges**3)
    big = rdf.r > 0.5
    sigma = np.sqrt(2.0 / naive[big])  # the truncated shells are smaller: a loose but fair bound
    assert np.all(np.abs(rdf.g[big] - 1.0) < 5.0 * sigma + 0.02)
    assert rdf.g[rdf.r > 1.0].mean() == pytest.approx(1.0, abs=0.01)


def test_untruncated_normalisation_would_be_biased(rng):
    """The slab correction matters: whole-shell normalisation of the same counts is low by > 10 % at r = 2.5."""
    packing = _ideal_gas(rng)
    truncated = PairCorrelation(bins=30, r_max=3.0, z_range=(2.5, 5.5)).compute(packing)
    periodic = PairCorrelation(bins=30, r_max=3.0, z_range=(2.5, 5.5), interior_only=True)
    # interior_only keeps no reference in a slab thinner than 2 r_max: nan and a warning
    with pytest.warns(AnalysisWarning):
        periodic.compute(packing)
    assert np.all(np.isnan(periodic.g))
    z = packing.state.position[:, 2]
    h = z[(z >= 2.5) & (z <= 5.5)]
    edges = truncated.bin_edges
    truncated_shells = np.diff(ball_in_slab(edges[None, :], (h - 2.5)[:, None], (5.5 - h)[:, None]), axis=1).sum(axis=0)
    whole_shells = len(h) * np.diff(4.0 / 3.0 * math.pi * edges**3)
    biased = truncated.g * truncated_shells / whole_shells
    assert biased[(truncated.r > 2.4) & (truncated.r < 2.6)].mean() < 0.9


def test_matches_freud_on_a_fully_periodic_box(rng):
    """``periodic_z``: the same configuration in a fully periodic cube gives freud's RDF (freud is float32)."""
    lateral = 8.0
    packing_fcc, a = fcc_spheres(4, 4)  # 4 x 4 x 4 cubic cells: periodic in z with period 4 a as well
    jitter = packing_fcc.state.position + 0.05 * rng.standard_normal(packing_fcc.state.position.shape)
    period = 4 * a
    pos = np.mod(jitter, period)
    for pts, box_l in [(pos, period), (rng.random((3000, 3)) * lateral, lateral)]:
        rdf = PairCorrelation(bins=50, r_max=2.5, periodic_z=box_l).compute(points(pts, box_l))
        ref = freud.density.RDF(bins=50, r_max=2.5)
        ref.compute(system=(freud.box.Box.cube(box_l), pts - box_l / 2), reset=True)
        np.testing.assert_allclose(rdf.r, ref.bin_centers, rtol=1e-6)
        # freud works in float32: a pair within ~1e-7 of a bin edge may land in the next bin (atol = one pair)
        np.testing.assert_allclose(rdf.g, ref.rdf, rtol=2e-5, atol=2e-4)
        np.testing.assert_allclose(rdf.coordination, ref.n_r, rtol=2e-5, atol=1e-3)
        assert rdf.g.max() > 0.5


def test_matches_freud_in_the_interior_of_a_thick_slab(rng):
    """Slab mode without periodic z: references at least r_max from the faces see exactly what freud sees."""
    lateral, r_max = 8.0, 2.5
    pos = rng.random((3000, 3)) * lateral
    rdf = PairCorrelation(bins=25, r_max=r_max, z_range=(0.0, lateral), interior_only=True).compute(points(pos, lateral))
    query = pos[(pos[:, 2] >= r_max) & (pos[:, 2] <= lateral - r_max)]
    assert rdf.n_references == len(query)
    ref = freud.density.RDF(bins=25, r_max=r_max)
    ref.compute(system=(freud.box.Box.cube(lateral), pos - lateral / 2), query_points=query - lateral / 2, reset=True)
    # freud counts each query point at distance 0 from itself (the first bin); compare beyond it
    np.testing.assert_allclose(rdf.g[1:], ref.rdf[1:], rtol=2e-5, atol=2e-4)


def test_r_max_is_clipped_to_half_the_period():
    packing, a = fcc_spheres(2, 6)
    with pytest.warns(AnalysisWarning, match="clipped"):
        rdf = PairCorrelation(bins=10, r_max=5.0).compute(packing)
    assert rdf.bin_edges[-1] == pytest.approx(a)  # half of 2 a


def test_too_few_grains_give_nan():
    packing = points([[1.0, 1.0, 3.0]], 4.0)
    with pytest.warns(AnalysisWarning):
        rdf = PairCorrelation(bins=10, r_max=1.0, z_range=(0.0, 6.0)).compute(packing)
    assert np.all(np.isnan(rdf.g))

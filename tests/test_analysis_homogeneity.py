"""Homogeneity profiles (docs/method/analysis.md#homogeneity): a segregated and a mixed two-population lattice."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from packing_builders import relabelled, single, sphere_column

from granpack.analysis import AnalysisWarning, Homogeneity, NotComputedError
from granpack.shapes import Sphere

SIDE, LAYERS = 4, 8


def lattice(segregated: bool):
    """Simple-cubic sphere lattice (one sphere per unit layer [k, k+1)), populations a and b in equal numbers.

    Segregated: a in the lower half, b in the upper half. Mixed: checkerboard in x, y in every layer.
    """
    base = sphere_column(SIDE, LAYERS)
    cells = np.array(list(itertools.product(range(SIDE), range(SIDE), range(LAYERS))))
    population = cells[:, 2] >= LAYERS // 2 if segregated else (cells[:, 0] + cells[:, 1]) % 2
    return relabelled(base, population, ["a", "b"])


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        Homogeneity().z


def test_segregated_layers():
    hom = Homogeneity(z_range=(2.0, 6.0)).compute(lattice(True))
    np.testing.assert_allclose(hom.z, np.arange(LAYERS) + 0.5)
    np.testing.assert_array_equal(hom.counts, SIDE * SIDE)
    np.testing.assert_allclose(hom.proportions["a"], [1, 1, 1, 1, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(hom.proportions["b"], [0, 0, 0, 0, 1, 1, 1, 1], atol=1e-12)
    assert hom.nominal == pytest.approx({"a": 0.5, "b": 0.5})
    # random mixture of 16 grains: SE = 0.125, every layer departs by 0.5 > 3 SE
    np.testing.assert_allclose(hom.standard_error["a"], 0.125)
    assert hom.segregated["a"].all() and hom.segregated["b"].all()
    # bulk [2, 6]: layers 2..5 -> shares 1, 1, 0, 0
    np.testing.assert_array_equal(np.flatnonzero(hom.bulk_layers), [2, 3, 4, 5])
    assert hom.bulk_mean["a"] == pytest.approx(0.5)
    assert hom.bulk_std["a"] == pytest.approx(np.std([1, 1, 0, 0], ddof=1))


def test_mixed_layers():
    hom = Homogeneity(z_range=(2.0, 6.0)).compute(lattice(False))
    np.testing.assert_allclose(hom.proportions["a"], 0.5, atol=1e-12)
    np.testing.assert_allclose(hom.proportions["b"], 0.5, atol=1e-12)
    assert not hom.segregated["a"].any() and not hom.segregated["b"].any()
    assert hom.bulk_mean["b"] == pytest.approx(0.5) and hom.bulk_std["b"] == pytest.approx(0.0, abs=1e-12)


def test_volume_shares_use_exact_clipped_volumes():
    """Half-layer layers cut every sphere: the shares stay exact volume shares."""
    hom = Homogeneity(layer_thickness=0.5, z_range=(2.0, 6.0)).compute(lattice(True))
    np.testing.assert_allclose(hom.proportions["a"][:8], 1.0, atol=1e-12)
    np.testing.assert_allclose(hom.proportions["a"][8:], 0.0, atol=1e-12)


def test_single_grain_has_no_bulk_layers():
    with pytest.warns(AnalysisWarning, match="no bulk region"):  # the true cause: one grain has no bulk
        hom = Homogeneity().compute(single(Sphere(1.0), position=(1, 1, 0.5)))
    assert hom.proportions["grain"] == pytest.approx([1.0])
    assert math.isnan(hom.bulk_mean["grain"])

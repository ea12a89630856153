"""Orientational order Q^2_00 / Q^2_22 (docs/method/analysis.md#orientational-order): perfect, uniaxial, isotropic."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from packing_builders import cubic_cubes, fcc_spheres, oriented_pinacoids

from granpack.analysis import AnalysisWarning, NotComputedError, Order
from granpack.analysis.order import isotropic_baseline
from granpack.rotations import quat_from_axis_angle, quat_multiply, quat_to_matrix, random_quaternions

N = 1000


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        Order().Q00


def test_perfect_biaxial_order(rng):
    q = random_quaternions(1, rng)[0]
    order = Order(bulk=False).compute(oriented_pinacoids(np.tile(q, (N, 1)), rng))
    assert order.n_analysed == N
    assert order.Q00 == pytest.approx(1.0, abs=1e-12)
    assert order.Q22 == pytest.approx(1.0, abs=1e-12)
    # all three tensors have eigenvalue 1; whichever axis is reported, the director is that body axis
    axis = "uvw".index(order.director_axis)
    assert abs(order.director @ quat_to_matrix(q[None])[0][:, axis]) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("axis", [0, 2])
def test_uniaxial_order_with_random_spin(rng, axis):
    """One body axis (u or w) along a fixed direction, random spin about it: Q00 = 1 on that axis, Q22 ~ 0."""
    direction = np.array([1.0, 2.0, 2.0]) / 3.0
    spin = np.array([quat_from_axis_angle(np.eye(3)[axis], a) for a in rng.random(N) * 2 * math.pi])
    # rotate the chosen body axis onto ``direction`` after the spin about it
    e = np.eye(3)[axis]
    tilt_axis = np.cross(e, direction)
    tilt = quat_from_axis_angle(tilt_axis / np.linalg.norm(tilt_axis), math.acos(e @ direction))
    q = quat_multiply(np.tile(tilt, (N, 1)), spin)
    order = Order(bulk=False).compute(oriented_pinacoids(q, rng))
    assert order.Q00 == pytest.approx(1.0, abs=1e-12)
    assert order.director_axis == "uvw"[axis]
    assert abs(order.director @ direction) == pytest.approx(1.0, abs=1e-12)
    # Q22 = |<exp(2 i psi)>| for a random spin psi: Rayleigh, mean sqrt(pi / 4N) = 0.028 for N = 1000
    assert order.Q22 < 0.1


def test_isotropic_orientations_match_the_finite_size_baseline(rng):
    order = Order(bulk=False).compute(oriented_pinacoids(random_quaternions(N, rng), rng))
    # isotropic baseline (docs/method/analysis.md#orientational-order), N = 1000: Q00 = 0.031 +- 0.008, Q22 = 0.012 +- 0.007 (4 sigma bands)
    assert 0.0 < order.Q00 < 0.031 + 4 * 0.008
    assert 0.0 <= order.Q22 < 0.012 + 4 * 0.007
    base = order.baseline
    assert base["Q00"] == pytest.approx(0.031, abs=0.003)
    assert base["Q22"] == pytest.approx(0.012, abs=0.002)
    assert base["Q00_std"] == pytest.approx(0.008, rel=0.35)
    assert base["Q22_std"] == pytest.approx(0.007, rel=0.35)


def test_baseline_decreases_with_n():
    q3000 = isotropic_baseline(3000, 50)
    q500 = isotropic_baseline(500, 50)
    assert q3000[0] == pytest.approx(0.019, abs=0.003)
    assert q500[0] == pytest.approx(0.046, abs=0.005)
    assert q3000[2] < q500[2]


def test_order_counts_only_the_bulk_grains_of_a_population(rng):
    q = random_quaternions(1, rng)[0]
    packing = oriented_pinacoids(np.tile(q, (200, 1)), rng, height=8.0)
    z = packing.state.position[:, 2]
    # tilt the grains outside [2, 6] randomly: the bulk order stays perfect
    outside = (z < 2.0) | (z > 6.0)
    packing.state.quaternion[outside] = random_quaternions(int(outside.sum()), rng)
    order = Order(z_range=(2.0, 6.0)).compute(packing)
    assert order.n_analysed == int((~outside).sum())
    assert order.Q00 == pytest.approx(1.0, abs=1e-12) and order.Q22 == pytest.approx(1.0, abs=1e-12)
    assert Order(bulk=False).compute(packing).Q00 < 0.9


def test_no_bulk_region_is_said_so():
    packing, _ = cubic_cubes(3, 4)  # 4 layers of cubes: too thin for a bulk region
    with pytest.warns(AnalysisWarning, match="no bulk region: order parameters are nan"):
        order = Order().compute(packing)
    assert order.n_analysed == 0 and len(order.warnings) == 1


def test_spheres_only_give_nan_without_a_warning():
    """A sphere packing has no orientation to measure: nan is its answer, not a warning."""
    packing, _ = fcc_spheres(2, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AnalysisWarning)
        order = Order(bulk=False).compute(packing)
        in_bulk = Order().compute(packing)  # too thin for a bulk region too: still nothing to say
    assert math.isnan(order.Q00) and math.isnan(order.Q22) and math.isnan(in_bulk.Q00)
    assert order.director_axis == "" and order.warnings == [] and in_bulk.warnings == []


def test_non_spherical_grains_outside_the_analysed_region_are_said_so():
    packing, _ = cubic_cubes(3, 12)
    with pytest.warns(AnalysisWarning, match="no non-spherical grain in the analysed region"):
        order = Order(z_range=(100.0, 101.0)).compute(packing)
    assert order.n_analysed == 0 and math.isnan(order.Q00)

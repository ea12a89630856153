"""Solid fraction (docs/method/analysis.md#solid-fraction): exact slice volumes, profile and bulk value on crystals."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from packing_builders import cubic_cubes, fcc_spheres, single
from scipy.integrate import quad
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

from granpack.analysis import AnalysisWarning, NotComputedError, SolidFraction
from granpack.analysis.solid_fraction import slice_volumes
from granpack.rotations import quat_to_matrix, random_quaternions
from granpack.shapes import Pinacoid, Sphere

FCC_PHI = math.pi / math.sqrt(18.0)


def clipped_volume(vertices: np.ndarray, a: float, b: float) -> float:
    """Volume of the convex hull of ``vertices`` inside ``a <= z <= b`` (scipy half-space intersection)."""
    hull = ConvexHull(vertices)
    halfspaces = np.vstack([hull.equations, [[0.0, 0.0, -1.0, a], [0.0, 0.0, 1.0, -b]]])
    normals = halfspaces[:, :3]
    # Chebyshev centre: an interior point of the clipped polyhedron (none if it is empty or flat)
    res = linprog(
        [0.0, 0.0, 0.0, -1.0],
        A_ub=np.hstack([normals, np.linalg.norm(normals, axis=1)[:, None]]),
        b_ub=-halfspaces[:, 3],
        bounds=[(None, None)] * 3 + [(0.0, None)],
    )
    if not res.success or res.x[3] < 1e-9:
        return 0.0
    return ConvexHull(HalfspaceIntersection(halfspaces, res.x[:3]).intersections).volume


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        SolidFraction().bulk


def test_sphere_slices_match_spherical_segments():
    radius, zc = 0.5, 0.83
    packing = single(Sphere(2 * radius), position=(1.0, 1.0, zc))
    dz = 0.07
    vols = slice_volumes(packing, 0.0, dz, 25)[0]
    assert vols.sum() == pytest.approx(math.pi / 6.0, rel=1e-13)
    for k, v in enumerate(vols):
        lo, hi = max(k * dz, zc - radius), min((k + 1) * dz, zc + radius)
        expected = quad(lambda z: math.pi * (radius**2 - (z - zc) ** 2), lo, hi)[0] if hi > lo else 0.0
        assert v == pytest.approx(expected, rel=1e-12, abs=1e-15)
    # the slicing may start inside the grain: only the part inside the slices counts
    part = slice_volumes(packing, zc, 1.0, 1)[0, 0]
    assert part == pytest.approx(math.pi / 12.0, rel=1e-13)


@pytest.mark.parametrize("family", ["isometric", "elongated", "flat", "flat_elongated"])
def test_pinacoid_slices_match_clipped_hull(family, rng):
    shape = Pinacoid.family(family, 1.0)
    q = random_quaternions(1, rng)[0]
    centre = np.array([1.0, 2.0, 0.61])
    packing = single(shape, position=centre, quaternion=q)
    dz = 0.05
    vols = slice_volumes(packing, 0.0, dz, 30)[0]
    assert vols.sum() == pytest.approx(shape.volume, rel=1e-12)
    world = shape.vertices @ quat_to_matrix(q[None])[0].T + centre
    expected = np.array([clipped_volume(world, k * dz, (k + 1) * dz) for k in range(30)])
    np.testing.assert_allclose(vols, expected, rtol=1e-9, atol=1e-14)
    assert np.count_nonzero(vols) >= 10  # the grain really is cut by many slices


def test_fcc_bulk_is_pi_over_sqrt18():
    packing, a = fcc_spheres(4, 6)
    # any window of an integer number of (001) layer spacings a/2 inside the crystal is exact
    z0 = 2.0
    sf = SolidFraction(z_range=(z0, z0 + 6 * a / 2)).compute(packing)
    assert sf.bulk == pytest.approx(FCC_PHI, rel=1e-12)
    # the default bulk region (2 d above the wall, 2 d below the surface) is close to it
    sf = SolidFraction().compute(packing)
    assert sf.warnings == []
    assert sf.z_bottom == 2.0
    assert sf.z_surface == pytest.approx(0.5 + 11 * a / 2 + 0.5, abs=0.15)
    assert sf.bulk == pytest.approx(FCC_PHI, abs=2e-3)
    assert sf.std < 2e-3
    # the profile holds all the solid volume
    n = packing.n_particles
    assert sf.profile_phi.sum() * packing.box.area * 0.1 == pytest.approx(n * math.pi / 6, rel=1e-12)


def test_cubes_face_to_face_fill_space():
    packing, edge = cubic_cubes(3, 12)
    sf = SolidFraction().compute(packing)
    assert sf.has_bulk and sf.warnings == []
    assert sf.bulk == pytest.approx(1.0, abs=1e-12)
    assert sf.std == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(sf.layers, 1.0, atol=1e-12)
    inside = sf.profile_z < 12 * edge - 0.1
    np.testing.assert_allclose(sf.profile_phi[inside], 1.0, atol=1e-12)
    assert sf.z_surface == pytest.approx(12 * edge, abs=0.05)


def test_too_thin_for_a_bulk_gives_nan_and_warning():
    packing, _ = cubic_cubes(3, 4)
    with pytest.warns(AnalysisWarning, match="no bulk region"):
        sf = SolidFraction().compute(packing)
    assert not sf.has_bulk
    # the cause, not the negative range it leads to
    surface = f"{sf.z_surface:.3g} d"
    assert sf.no_bulk_reason.startswith(f"no bulk region: the pile's free surface is at {surface}, below the")
    assert sf.warnings == [sf.no_bulk_reason + ": the bulk solid fraction is nan"]
    assert math.isnan(sf.bulk) and math.isnan(sf.std)
    assert len(sf.warnings) == 1
    # the profile is still there
    assert sf.profile_phi.max() == pytest.approx(1.0, abs=1e-12)


def test_single_grain_gives_nan_bulk():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sf = SolidFraction().compute(single(Pinacoid.family("flat"), position=(1, 1, 0.3)))
    assert math.isnan(sf.bulk)
    assert any(issubclass(w.category, AnalysisWarning) for w in caught)

"""Size definitions: the sieve size against exact answers, the equivalent-volume size, and populations
graded in a definition."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from granpack.config import load_config_dict
from granpack.mixture import Mixture
from granpack.shapes import ConvexPolyhedron, Pinacoid, Sphere
from granpack.shapes.sizes import aspect_ratios, equivalent_volume_size, sieve_size, size_of


def box(a, b, c, rotation=None) -> ConvexPolyhedron:
    corners = np.array([[x, y, z] for x in (-a / 2, a / 2) for y in (-b / 2, b / 2) for z in (-c / 2, c / 2)])
    return ConvexPolyhedron(corners if rotation is None else corners @ rotation.T)


def test_a_sphere_passes_its_diameter():
    assert sieve_size(Sphere(0.7)) == 0.7
    assert equivalent_volume_size(Sphere(0.7)) == pytest.approx(0.7, rel=1e-15)


def test_a_cube_passes_its_edge_in_any_orientation():
    assert sieve_size(box(0.8, 0.8, 0.8)) == 0.8
    for seed in range(3):
        turned = box(0.8, 0.8, 0.8, Rotation.random(random_state=seed).as_matrix())
        assert sieve_size(turned) == pytest.approx(0.8, rel=1e-12)


@pytest.mark.parametrize("a,b,c", [(0.1, 1.0, 2.0), (0.2, 0.7, 1.0), (0.6, 1.0, 1.5)])
def test_a_box_passes_the_square_holding_its_smallest_face(a, b, c):
    """The smallest square holding an a x b rectangle (a <= b): its side b, or (a + b)/sqrt 2 turned
    by 45 degrees when a < (sqrt 2 - 1) b."""
    expected = min(b, (a + b) / math.sqrt(2.0))
    for seed in range(2):
        got = sieve_size(box(a, b, c, Rotation.random(random_state=seed).as_matrix()))
        assert got == pytest.approx(expected, rel=1e-12)


def test_every_definition_scales_with_the_grain():
    body = Pinacoid.from_size(1.0, 2.0, 3.0)
    for definition in ("circumscribed", "sieve", "equivalent_volume"):
        assert size_of(body.scaled(0.3), definition) == pytest.approx(0.3 * size_of(body, definition), rel=1e-12)


def population(**keys) -> dict:
    return {"shape": "pinacoid", "volume_fraction": 1.0, "aspect": [2.0, 1.0], **keys}


def test_a_population_is_sized_in_its_definition():
    for definition in ("sieve", "equivalent_volume"):
        config = load_config_dict({"n_particles": 10, "populations": [population(size=0.5, size_definition=definition)]})
        shape = Mixture.from_config(config).shapes[0]
        assert size_of(shape, definition) == pytest.approx(0.5, rel=1e-12)
        assert aspect_ratios(shape) == pytest.approx((2.0, 1.0), rel=1e-12)
        assert config.populations[0].largest_size == pytest.approx(shape.size, rel=1e-12)
        assert config.largest_size == pytest.approx(shape.size, rel=1e-12)


def test_circumscribed_is_the_default_and_unchanged():
    config = load_config_dict({"n_particles": 10, "populations": [population(size=0.5)]})
    assert config.populations[0].size_definition == "circumscribed"
    shape = Mixture.from_config(config).shapes[0]
    reference = Pinacoid.from_size(0.5, 2.0, 1.0)
    assert np.array_equal(shape.vertices, reference.vertices) and shape.volume == reference.volume
    assert 'size_definition = "circumscribed"' in config.to_toml()


def test_a_grading_grades_in_the_definition():
    grading = {"curve": "fuller", "d_min": 0.25, "d_max": 1.0, "exponent": 0.5}
    config = load_config_dict({"n_particles": 30, "lateral_size": 9.0,
                               "populations": [population(grading=grading, size_definition="sieve")]})
    mixture = Mixture.from_config(config)
    table = mixture.particle_shape_table()
    graded = table.shapes[1:]
    assert len(graded) == 30
    for shape, size in zip(graded[:5], mixture.sizes[0][:5]):
        assert sieve_size(shape) == pytest.approx(size, rel=1e-10)

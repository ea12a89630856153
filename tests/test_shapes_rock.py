"""Generated rocks and pinacoids of varying aspect ratios: their geometry, their mass properties
against trimesh, and their populations (shapes drawn from the seed, like a population of files)."""

from __future__ import annotations

import gsd.hoomd
import numpy as np
import pytest
import tomllib
import trimesh
from scipy.spatial.transform import Rotation

from granpack.config import load_config_dict
from granpack.errors import InputError
from granpack.mixture import Mixture
from granpack.shapes import ConvexPolyhedron, Pinacoid
from granpack.shapes.aspect_classes import lognormal_quantiles
from granpack.shapes.rock import rock, rock_library
from granpack.shapes.sizes import aspect_ratios
from granpack.simulation import run_packing

#: a fixed rotation that leaves no axis in place
TURN = Rotation.from_rotvec([0.3, -0.7, 1.1]).as_matrix()


def full_mass_properties_agree(vertices, rel=1e-10):
    """Volume, centroid and inertia tensor of the polyhedron of ``vertices`` (in their frame, about
    the centroid) against trimesh's of their hull, to ``rel`` of the body's scale."""
    shape = ConvexPolyhedron(vertices)
    mesh = trimesh.convex.convex_hull(vertices)
    assert shape.volume == pytest.approx(mesh.volume, rel=rel)
    extent = float(np.ptp(vertices, axis=0).max())
    assert np.abs(shape.input_centroid - mesh.center_mass).max() <= rel * extent
    inertia = shape.rotation.T @ np.diag(shape.principal_moments) @ shape.rotation  # back in the input frame
    assert np.abs(inertia - mesh.moment_inertia).max() <= rel * np.abs(mesh.moment_inertia).max()


@pytest.mark.parametrize("aspect,faces,roughness", [((1.0, 1.0), 8, 0.0), ((1.5, 1.3), 14, 0.5),
                                                    ((2.5, 2.0), 30, 1.0), ((1.2, 3.0), 64, 2.0)])
def test_a_rock_has_its_faces_its_ratios_and_unit_size(aspect, faces, roughness):
    body = rock(np.random.default_rng(7), aspect, faces, roughness)
    assert len(body.faces) == faces and len(body.vertices) == 2 * faces - 4
    assert aspect_ratios(body) == pytest.approx(aspect, rel=1e-10)
    assert body.size == pytest.approx(1.0, rel=1e-12)
    assert np.abs(np.linalg.norm(body.vertices, axis=1) - 0.5).min() < 1e-12  # a corner on the ball


def test_rocks_come_from_their_seed_and_a_larger_library_keeps_the_smaller():
    a, b = rock_library(3, 4, (1.5, 1.3)), rock_library(3, 6, (1.5, 1.3))
    other = rock_library(4, 4, (1.5, 1.3))
    for x, y, z in zip(a, b, other):
        assert np.array_equal(x.vertices, y.vertices)
        assert not np.allclose(np.sort(x.vertices.ravel()), np.sort(z.vertices.ravel()))
    volumes = [r.volume for r in a]
    assert len(set(volumes)) == len(volumes)  # distinct rocks
    smooth = rock(np.random.default_rng(1), (1.0, 1.0), 30, 0.0)
    rough = rock(np.random.default_rng(1), (1.0, 1.0), 30, 1.5)
    spread = [np.std(face_areas(b)) / np.mean(face_areas(b)) for b in (smooth, rough)]
    assert spread[1] > 2 * spread[0], spread


def face_areas(body: ConvexPolyhedron) -> np.ndarray:
    """Area of each face of ``body`` (its vertices in order round the face)."""
    v = body.vertices
    return np.array([0.5 * np.linalg.norm(sum(np.cross(v[f[k]] - v[f[0]], v[f[k + 1]] - v[f[0]])
                                              for k in range(1, len(f) - 1))) for f in body.faces])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_rock_mass_properties_against_trimesh(seed):
    body = rock(np.random.default_rng(seed), (1.8, 1.4), 20, 0.8)
    turned = body.vertices @ trimesh.transformations.random_rotation_matrix(np.random.default_rng(seed).random(3))[:3, :3].T
    full_mass_properties_agree(turned + [3.0, -1.0, 2.0])
    full_mass_properties_agree(body.vertices)


@pytest.mark.parametrize("aspect", [(1.0, 1.0), (2.0, 1.0), (1.0, 3.0), (2.0, 3.0), (1.37, 2.21)])
def test_pinacoid_mass_properties_against_trimesh(aspect):
    body = Pinacoid.from_size(1.3, *aspect)
    full_mass_properties_agree(body.vertices + [0.5, 0.25, -2.0])
    mesh = trimesh.convex.convex_hull(body.vertices)
    assert np.sort(body.principal_moments) == pytest.approx(np.sort(mesh.principal_inertia_components), rel=1e-10)


def body_frame_agrees(shape, rel=1e-10):
    """The shape's own volume, centroid (the origin of its body frame) and inertia tensor (diagonal,
    its principal moments) against trimesh's of the hull of its vertices."""
    mesh = trimesh.convex.convex_hull(shape.vertices)
    assert shape.volume == pytest.approx(mesh.volume, rel=rel)
    assert np.abs(mesh.center_mass).max() <= rel * shape.size
    assert np.abs(np.diag(shape.principal_moments) - mesh.moment_inertia).max() <= rel * shape.principal_moments.max()


def every_kind(tmp_path) -> dict:
    """One shape of each kind: from a file (its hull), reduced, a rock, a pinacoid of an aspect class."""
    from test_shapes_from_mesh import noisy_ellipsoid

    from granpack.shapes.mesh_files import read_mesh
    from granpack.shapes.from_mesh import grain_from_mesh

    noisy_ellipsoid(np.random.default_rng(5)).export(tmp_path / "scan.stl")
    cfg = load_config_dict(config({"shape": "pinacoid", "aspect_distribution": [[1.3, 2.2, 1.0], [1.0, 1.0, 1.0]]}))
    return {"file": grain_from_mesh(read_mesh(tmp_path / "scan.stl"), 1000).shape,
            "reduced": grain_from_mesh(read_mesh(tmp_path / "scan.stl"), 24).shape,
            "rock": Mixture.from_config(load_config_dict(config({"shape": "rock", "shapes": 2}))).population_shapes[0][1],
            "pinacoid class": Mixture.from_config(cfg).population_shapes[0][0]}


@pytest.mark.parametrize("kind", ["file", "reduced", "rock", "pinacoid class"])
def test_every_kind_of_shape_has_trimesh_mass_properties(kind, tmp_path):
    shape = every_kind(tmp_path)[kind]
    body_frame_agrees(shape)
    body_frame_agrees(shape.scaled(3.7))
    full_mass_properties_agree(shape.vertices @ TURN.T + [1.0, 2.0, -0.5])


def config(population: dict, seed: int = 3, n: int = 200) -> dict:
    return {"seed": seed, "n_particles": n, "lateral_size": 6.0,
            "populations": [{"size": 1.0, "volume_fraction": 1.0, **population}]}


def test_a_rock_population_draws_its_grains_from_its_rocks():
    cfg = load_config_dict(config({"shape": "rock", "aspect": [1.5, 1.3], "shapes": 7, "faces": 12}))
    population = cfg.populations[0]
    assert (population.faces, population.shapes, population.roughness, population.seed) == (12, 7, 0.5, None)
    mixture = Mixture.from_config(cfg)
    shapes = mixture.population_shapes[0]
    assert len(shapes) == 7 and all(s.size == pytest.approx(1.0, rel=1e-12) for s in shapes)
    assert all(aspect_ratios(s) == pytest.approx((1.5, 1.3), rel=1e-10) for s in shapes)
    counts = np.bincount(mixture.choices[0], minlength=7)
    assert counts.sum() == 200 and counts.max() - counts.min() <= 1
    library = rock_library(3, 7, (1.5, 1.3), 12, 0.5)  # the run's seed
    assert all(np.allclose(s.vertices, r.vertices, rtol=0, atol=1e-14) for s, r in zip(shapes, library))
    # the resolved config reads back equal; another run seed, or the population's own, other rocks
    assert load_config_dict(tomllib.loads(cfg.to_toml())) == cfg
    other = Mixture.from_config(cfg.with_seed(4)).population_shapes[0]
    assert not np.array_equal(other[0].vertices, shapes[0].vertices)
    own = load_config_dict(config({"shape": "rock", "aspect": [1.5, 1.3], "shapes": 7, "faces": 12, "seed": 3}, seed=9))
    assert np.array_equal(Mixture.from_config(own).population_shapes[0][0].vertices, shapes[0].vertices)


def test_a_rock_population_in_sieve_sizes():
    cfg = load_config_dict(config({"shape": "rock", "shapes": 3, "size_definition": "sieve", "size": 0.5}))
    from granpack.shapes.sizes import sieve_size

    for shape in Mixture.from_config(cfg).population_shapes[0]:
        assert sieve_size(shape) == pytest.approx(0.5, rel=1e-9)


def test_a_table_of_aspect_classes_is_a_population_of_pinacoids_by_weight():
    table = [[1.0, 1.0, 1.0], [2.0, 1.0, 2.0], [1.5, 3.0, 5.0]]
    cfg = load_config_dict(config({"shape": "pinacoid", "aspect_distribution": table}, n=400))
    population = cfg.populations[0]
    assert population.aspect is None and population.name == "pinacoid-1-aspects"
    mixture = Mixture.from_config(cfg)
    shapes = mixture.population_shapes[0]
    assert [aspect_ratios(s) for s in shapes] == [pytest.approx((e, f), rel=1e-12) for e, f, _ in table]
    assert all(isinstance(s, Pinacoid) and s.size == pytest.approx(1.0) for s in shapes)
    counts = np.bincount(mixture.choices[0], minlength=3)
    assert list(counts) == [50, 100, 250]
    assert load_config_dict(tomllib.loads(cfg.to_toml())) == cfg


@pytest.mark.parametrize("median,log_sd,classes", [(1.0, 0.3, 4), (1.6, 0.25, 3), (1.2, 0.5, 8)])
def test_lognormal_classes_are_the_truncated_laws_quantiles(median, log_sd, classes, rng):
    ratios = rng.lognormal(np.log(median), log_sd, size=2_000_000)
    ratios = ratios[ratios >= 1.0]
    q = lognormal_quantiles(median, log_sd, classes)
    below = np.searchsorted(np.sort(ratios), q) / len(ratios)
    assert below == pytest.approx((np.arange(classes) + 0.5) / classes, abs=2e-3)
    assert np.all(q >= 1.0)


def test_aspect_lognormal_gives_classes_squared_shapes_in_equal_numbers():
    cfg = load_config_dict(config({"shape": "pinacoid", "aspect_lognormal": [[1.4, 0.2], [1.5, 0.0]],
                                   "aspect_classes": 3}, n=90))
    mixture = Mixture.from_config(cfg)
    shapes = mixture.population_shapes[0]
    assert len(shapes) == 3  # a spread of 0: one flatness
    assert [aspect_ratios(s) for s in shapes] == [pytest.approx((e, 1.5), rel=1e-12)
                                                 for e in lognormal_quantiles(1.4, 0.2, 3)]
    assert list(np.bincount(mixture.choices[0])) == [30, 30, 30]


@pytest.mark.parametrize("population,match", [
    ({"shape": "rock", "faces": 6}, r"populations\[0\]\.faces: must be >= 8"),
    ({"shape": "rock", "shapes": 0}, r"populations\[0\]\.shapes: must be >= 1"),
    ({"shape": "rock", "aspect": [0.5, 1.0]}, r"populations\[0\]\.aspect: \[L/G, G/E\] must both be >= 1"),
    ({"shape": "sphere", "faces": 12}, r"populations\[0\]\.faces: only allowed for shape 'rock'"),
    ({"shape": "pinacoid", "seed": 2}, r"populations\[0\]\.seed: only allowed for shape 'rock'"),
    ({"shape": "pinacoid", "aspect": [1, 1], "aspect_distribution": [[1, 1, 1]]},
     r"populations\[0\]\.aspect: give either aspect .* or aspect_distribution"),
    ({"shape": "pinacoid", "aspect_distribution": [[1, 0.5, 1]]}, r"aspect_distribution: each row is \[L/G, G/E, weight\]"),
    ({"shape": "pinacoid", "aspect_distribution": [[1, 1, 0]]}, r"aspect_distribution: the weights .* positive sum"),
    ({"shape": "pinacoid", "aspect_lognormal": [[0.9, 0.1], [1, 0]]}, r"aspect_lognormal: .* medians >= 1"),
    ({"shape": "pinacoid", "aspect_classes": 3}, r"aspect_classes: only allowed with aspect_lognormal"),
    ({"shape": "rock", "aspect_distribution": [[1, 1, 1]]}, r"aspect_distribution: only allowed for shape 'pinacoid'"),
])
def test_bad_rock_and_aspect_keys_are_one_line_errors(population, match):
    with pytest.raises(InputError, match=match) as info:
        load_config_dict(config(population))
    assert "\n" not in str(info.value)


def test_a_rock_population_packs_with_one_gsd_type_per_rock(tmp_path):
    cfg = load_config_dict({**config({"shape": "rock", "aspect": [1.4, 1.2], "shapes": 3}, n=20),
                            "lateral_size": 3.0, "equilibrium": {"max_time": 0.2, "check_interval": 0.1}})
    run_packing(cfg, tmp_path / "out", progress=False)
    frame = gsd.hoomd.open(tmp_path / "out" / "final.gsd")[0]
    shapes = Mixture.from_config(cfg).population_shapes[0]
    assert frame.particles.types == [s.name for s in shapes]
    for spec, shape in zip(frame.particles.type_shapes, shapes):
        assert np.array_equal(np.array(spec["vertices"]), shape.vertices)
    assert np.array_equal(np.bincount(frame.particles.typeid, minlength=3),
                          np.bincount(Mixture.from_config(cfg).choices[0], minlength=3))


def test_make_shape_is_the_first_shape_of_every_kind_of_population(tmp_path):
    trimesh.creation.box(extents=(1.0, 0.7, 0.4)).export(tmp_path / "one.stl")
    one_file = load_config_dict(config({"shape": "mesh", "files": ["one.stl"]}), base_dir=tmp_path).populations[0]
    one_row = load_config_dict(config({"shape": "pinacoid", "aspect_distribution": [[2.0, 1.5, 1.0]]})).populations[0]
    rocks = load_config_dict(config({"shape": "rock", "shapes": 2})).populations[0]
    for population in (one_file, one_row, rocks):
        first = population.make_shapes()[0]
        assert np.array_equal(population.make_shape().vertices, first.vertices)
    assert aspect_ratios(one_row.make_shape()) == pytest.approx((2.0, 1.5), rel=1e-12)
    assert one_file.make_shape().size == pytest.approx(1.0, rel=1e-12)

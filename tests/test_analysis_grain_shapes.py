"""Per-grain shape descriptors (elongation, flatness, sphericity, source convexity) and the
coordination and order of each population and shape class."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import trimesh
from packing_builders import random_pinacoids, relabelled, single

from granpack.analysis import AnalysisWarning, analyze_run
from granpack.analysis.coordination import Coordination
from granpack.analysis.grain_shapes import GrainShapes
from granpack.analysis.order import Order
from granpack.io.gsd import read_packing, write_packing
from granpack.shapes.mesh_files import read_mesh
from granpack.shapes import Pinacoid, Sphere, platonic
from granpack.shapes.from_mesh import grain_from_mesh
from granpack.shapes.rock import rock
from granpack.shapes.sizes import sphericity


def wadell(volume: float, area: float) -> float:
    return math.pi ** (1 / 3) * (6 * volume) ** (2 / 3) / area


@pytest.mark.parametrize("shape", [Pinacoid.from_size(1.0, 2.0, 3.0), Pinacoid.from_size(0.4),
                                   rock(np.random.default_rng(2), (1.6, 1.2), 20, 1.0), platonic("octahedron", 1.0)],
                         ids=["pinacoid-2x3", "pinacoid", "rock", "octahedron"])
def test_area_and_sphericity_against_trimesh(shape):
    mesh = trimesh.convex.convex_hull(shape.vertices)
    assert shape.surface_area == pytest.approx(mesh.area, rel=1e-12)
    assert sphericity(shape) == pytest.approx(wadell(mesh.volume, mesh.area), rel=1e-12)


def test_sphericity_of_a_sphere_and_a_cube():
    assert sphericity(Sphere(0.7)) == pytest.approx(1.0, rel=1e-15)
    cube = platonic("cube", 1.0)
    edge = np.ptp(cube.vertices[:, 0])
    assert sphericity(cube) == pytest.approx(wadell(edge ** 3, 6 * edge ** 2), rel=1e-12)


def test_descriptors_per_grain_with_the_source_convexity_through_the_gsd(tmp_path):
    mesh = trimesh.creation.icosphere(2)
    vertices = mesh.vertices * [2.0, 1.2, 0.8]
    dent = vertices[:, 2] > 0.5
    vertices[dent, 2] = 0.5 - 0.3 * (vertices[dent, 2] - 0.5)  # a dented top: convexity below 1
    trimesh.Trimesh(vertices, mesh.faces, process=False).export(tmp_path / "dented.stl")
    grain = grain_from_mesh(read_mesh(tmp_path / "dented.stl"), max_vertices=24)
    assert grain.convexity < 0.999
    write_packing(tmp_path / "final.gsd", single(grain.shape.scaled(1.0 / grain.shape.size)))
    described = GrainShapes().compute(read_packing(tmp_path / "final.gsd"))
    per_grain = described.per_grain
    assert per_grain["convexity"][0] == pytest.approx(grain.convexity, rel=1e-15)
    extents = np.sort(np.ptp(grain.shape.vertices, axis=0))[::-1]
    assert per_grain["elongation"][0] == pytest.approx(extents[0] / extents[1], rel=1e-12)
    assert per_grain["flatness"][0] == pytest.approx(extents[1] / extents[2], rel=1e-12)
    pinacoid = GrainShapes().compute(single(Pinacoid.from_size(1.0, 1.5, 2.5))).per_grain
    assert (pinacoid["elongation"][0], pinacoid["flatness"][0]) == pytest.approx((1.5, 2.5), rel=1e-12)
    assert math.isnan(pinacoid["convexity"][0])


def test_each_population_has_its_coordination_and_the_packing_is_their_mean(rng):
    packing = random_pinacoids(400, rng, lateral=6.0, height=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)
        co = Coordination((2.0, 8.0)).compute(packing)
    rows = [co.figures_of(packing.state.population == a) for a in (0, 1)]
    backbone = np.array([r["n_analysed"] * (1.0 - r["rattler_fraction"]) for r in rows])
    assert backbone.sum() == pytest.approx(co.n_analysed * (1.0 - co.rattler_fraction))
    for key in ("N", "Nc", "Nt"):
        assert np.dot(backbone, [r[key] for r in rows]) / backbone.sum() == pytest.approx(co.figures[key], rel=1e-12)
    assert rows[0]["N"] != rows[1]["N"]
    whole = co.figures_of(np.ones(packing.n_particles, bool))
    assert {k: whole[k] for k in co.figures} == co.figures


def test_order_of_a_shape_class_is_the_order_of_its_grains(rng):
    packing = random_pinacoids(300, rng, lateral=6.0, height=10.0)
    one = relabelled(packing, np.zeros(packing.n_particles), ["all"])
    grains = packing.state.population == 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)
        by_mask = Order((2.0, 8.0), grains=grains).compute(one)
        by_population = Order((2.0, 8.0), population=1).compute(packing)
        whole = Order((2.0, 8.0)).compute(one)
    assert (by_mask.Q00, by_mask.Q22, by_mask.n_analysed) == (by_population.Q00, by_population.Q22, by_population.n_analysed)
    assert by_mask.n_analysed < whole.n_analysed


def test_analysis_json_has_the_populations_figures_and_classes(tmp_path, rng):
    packing = random_pinacoids(300, rng, lateral=5.0, height=12.0)
    write_packing(tmp_path / "final.gsd", packing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)
        result = analyze_run(tmp_path)
    data = json.loads((tmp_path / "analysis.json").read_text())
    assert {k: len(v) for k, v in data["grain_shapes"].items()} == dict.fromkeys(
        ("elongation", "flatness", "sphericity", "convexity"), 300)
    for row, computed in zip(data["populations"], result["populations"]):
        assert {"N", "Nc", "rattler_fraction", "n_analysed"} <= set(row["coordination"])
        assert {"Q00", "Q22", "n_analysed", "isotropic_baseline"} <= set(row["order"])
        assert row["shape_descriptors"]["sphericity"]["mean"] == pytest.approx(sphericity(Pinacoid.from_size(1.0)))
        assert row["shape_descriptors"]["convexity"]["mean"] is None  # no source mesh: null
        (only,) = row["shape_classes"]  # one pinacoid per population
        assert only["n"] == row["n"] and only["coordination"] == computed["coordination"]

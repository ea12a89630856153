"""Grains from mesh files: hull, convexity, reduction, mass properties against trimesh, populations
of several files, and the pinacoid read back from an STL packing as the built-in one."""

from __future__ import annotations

import math

import gsd.hoomd
import numpy as np
import pytest
import trimesh

from granpack.config import load_config
from granpack.errors import InputError
from granpack.shapes.mesh_files import MeshFileError, read_mesh
from granpack.mixture import Mixture, shape_counts
from granpack.shapes import Pinacoid
from granpack.shapes.from_mesh import grain_from_mesh, population_grains
from granpack.shapes.reduction import ASPECT_TOLERANCE, MOMENT_TOLERANCE, hull_descriptors
from granpack.shapes.sizes import aspect_ratios
from granpack.simulation import run_packing

from test_cli import run_main
from test_shapes_mesh_files import write_ascii_stl


def noisy_ellipsoid(rng, axes=(3.0, 2.2, 1.5), subdivisions=3, noise=0.02) -> trimesh.Trimesh:
    """A scan-like grain: a tessellated ellipsoid with radial noise (642 vertices)."""
    mesh = trimesh.creation.icosphere(subdivisions)
    vertices = mesh.vertices * axes * (1.0 + noise * rng.standard_normal((len(mesh.vertices), 1)))
    return trimesh.Trimesh(vertices, mesh.faces, process=False)


def mass_properties_agree(shape, reference: trimesh.Trimesh, rel=1e-10):
    """Volume and principal moments of ``shape`` against trimesh's of ``reference``, to ``rel``."""
    assert shape.volume == pytest.approx(reference.volume, rel=rel)
    moments = np.sort(reference.principal_inertia_components)
    assert np.sort(shape.principal_moments) == pytest.approx(moments, rel=rel)


def test_a_small_hull_is_the_grain_with_trimesh_mass_properties(tmp_path, rng):
    points = rng.normal(size=(12, 3)) * [2.0, 1.0, 0.7] + [5.0, -3.0, 1.0]
    trimesh.convex.convex_hull(points).export(tmp_path / "g.ply")
    hull = trimesh.load(tmp_path / "g.ply").convex_hull  # as written (the format's precision)
    grain = grain_from_mesh(read_mesh(tmp_path / "g.ply"), max_vertices=24)
    assert grain.deviations is None and len(grain.shape.vertices) == len(hull.vertices)
    assert grain.convexity == pytest.approx(1.0, rel=1e-12)
    mass_properties_agree(grain.shape, hull)
    assert grain.shape.input_centroid == pytest.approx(hull.center_mass, rel=1e-10)
    assert np.abs(grain.shape.vertices.mean(axis=0)).max() < 10.0  # body frame, not the file's


def test_convexity_is_mesh_volume_over_hull_volume_and_a_low_one_is_refused(tmp_path, rng):
    mesh = trimesh.creation.icosphere(2)
    dent = mesh.vertices[:, 2] > 0.3
    vertices = mesh.vertices.copy()
    vertices[dent, 2] = 0.3 - (vertices[dent, 2] - 0.3)  # the cap pushed in: a bowl
    trimesh.Trimesh(vertices, mesh.faces, process=False).export(tmp_path / "bowl.stl")
    bowl = trimesh.load(tmp_path / "bowl.stl")
    grain = grain_from_mesh(read_mesh(tmp_path / "bowl.stl"), max_vertices=1000)
    assert grain.convexity == pytest.approx(bowl.volume / bowl.convex_hull.volume, rel=1e-10)
    assert grain.convexity < 0.85
    with pytest.raises(MeshFileError, match=r"bowl.stl: convexity 0\.\d+ .* below min_convexity = 0.85"):
        population_grains([tmp_path / "bowl.stl"], 1000)
    assert population_grains([tmp_path / "bowl.stl"], 1000, min_convexity=0.5)[0].convexity == grain.convexity


def test_reduction_keeps_the_volume_exactly_and_moments_and_ratios_within_tolerance(tmp_path, rng):
    noisy_ellipsoid(rng).export(tmp_path / "scan.stl")
    scan = trimesh.load(tmp_path / "scan.stl")  # as written (float32 coordinates)
    grain = grain_from_mesh(read_mesh(tmp_path / "scan.stl"), max_vertices=24)
    hull = scan.convex_hull
    assert grain.hull_vertex_count == len(hull.vertices) > 24
    assert len(grain.shape.vertices) <= 24
    # the hull's figures against trimesh, then the reduced grain's against its own hull by trimesh
    assert grain.hull_volume == pytest.approx(hull.volume, rel=1e-10)
    assert np.array(grain.hull_moments) == pytest.approx(np.sort(hull.principal_inertia_components), rel=1e-10)
    mass_properties_agree(grain.shape, trimesh.convex.convex_hull(grain.shape.vertices))
    assert grain.shape.volume == pytest.approx(hull.volume, rel=1e-12)
    moments = np.sort(grain.shape.principal_moments) / np.sort(hull.principal_inertia_components) - 1.0
    assert grain.deviations.moments == pytest.approx(moments, abs=1e-12)
    assert np.abs(moments).max() <= MOMENT_TOLERANCE
    aspect = np.array(aspect_ratios(grain.shape)) / np.array(hull_descriptors(hull.vertices)[3]) - 1.0
    assert grain.deviations.aspect == pytest.approx(aspect, abs=1e-12)
    assert np.abs(aspect).max() <= ASPECT_TOLERANCE


def test_a_reduction_beyond_tolerance_is_refused(tmp_path, rng):
    noisy_ellipsoid(rng).export(tmp_path / "scan.stl")
    with pytest.raises(MeshFileError, match="scan.stl: reduced from .* raise max_vertices"):
        population_grains([tmp_path / "scan.stl"], max_vertices=4)


def test_files_in_other_units_are_refused(tmp_path):
    trimesh.creation.box(extents=(1, 1, 1)).export(tmp_path / "a.stl")
    trimesh.creation.box(extents=(1000, 1000, 1000)).export(tmp_path / "b.stl")
    with pytest.raises(MeshFileError, match="b.stl: 1e\\+03 times the size of .*a.stl"):
        population_grains([tmp_path / "a.stl", tmp_path / "b.stl"], 24)


def write_config(folder, files, extra="", population_extra="", n=40):
    folder.joinpath("run.toml").write_text(f"""
seed = 2
n_particles = {n}
lateral_size = 6.0
{extra}
[[populations]]
shape = "mesh"
files = {files!r}
size = 1.0
volume_fraction = 1.0
{population_extra}
""".replace("'", '"'))
    return folder / "run.toml"


@pytest.fixture
def three_grains(tmp_path, rng):
    (tmp_path / "grains").mkdir()
    for k in range(3):
        noisy_ellipsoid(rng, axes=(3.0, 2.0 + 0.3 * k, 1.5), subdivisions=2).export(tmp_path / "grains" / f"g{k}.stl")
    return tmp_path


def test_several_files_share_the_grains_from_the_seed(three_grains):
    config = load_config(write_config(three_grains, ["grains/*.stl"], n=40))
    assert [f.rsplit("/", 1)[1] for f in config.populations[0].files] == ["g0.stl", "g1.stl", "g2.stl"]
    mixture = Mixture.from_config(config)
    assert len(mixture.population_shapes[0]) == 3
    assert np.bincount(mixture.choices[0]).tolist() == shape_counts([1 / 3] * 3, 40).tolist()
    assert sorted(np.bincount(mixture.choices[0]).tolist()) == [13, 13, 14]
    other = Mixture.from_config(config.with_seed(3))
    assert not np.array_equal(mixture.choices[0], other.choices[0])
    table = mixture.particle_shape_table()
    assert table.n_kinds == 3
    population = mixture.particle_populations(np.random.default_rng(0))
    kinds = mixture.particle_kinds(population)
    assert np.array_equal(kinds, mixture.choices[0])
    volumes = np.array([s.volume for s in mixture.population_shapes[0]])
    assert mixture.solid_volumes[0] == pytest.approx(volumes[mixture.choices[0]].sum(), rel=1e-14)
    weighted = Mixture.from_config(load_config(write_config(three_grains, ["grains/*.stl"], n=40,
                                                            population_extra="weights = [2, 1, 1]")))
    assert np.bincount(weighted.choices[0]).tolist() == [20, 10, 10]


def test_bad_population_files_are_one_line_input_errors(three_grains):
    (three_grains / "grains" / "broken.stl").write_bytes(b"")
    with pytest.raises(InputError) as info:
        load_config(write_config(three_grains, ["grains/*.stl"]))
    assert "populations[0].files: " in str(info.value) and "broken.stl: empty file" in str(info.value)
    with pytest.raises(InputError, match="populations\\[0\\].weights: one weight per file: 2 weights for the 1 files"):
        load_config(write_config(three_grains, ["grains/g0.stl"], population_extra="weights = [1, 2]"))
    with pytest.raises(InputError, match="populations\\[0\\].files: .*matches no file"):
        load_config(write_config(three_grains, ["nothing/*.stl"]))


def test_the_gsd_holds_one_type_shape_per_file(three_grains):
    config = load_config(write_config(three_grains, ["grains/g0.stl", "grains/g1.stl", "grains/g2.stl"], n=12,
                                      extra="[equilibrium]\nmax_time = 0.02\ncheck_interval = 0.01"))
    run_packing(config, three_grains / "out", progress=False)
    frame = gsd.hoomd.open(three_grains / "out" / "final.gsd")[0]
    assert frame.particles.types == ["g0", "g1", "g2"]
    assert len(frame.particles.type_shapes) == 3
    shapes = Mixture.from_config(config).population_shapes[0]
    for spec, shape in zip(frame.particles.type_shapes, shapes):
        assert np.array_equal(np.array(spec["vertices"]), shape.vertices)


def exact_size_pinacoid() -> tuple[float, Pinacoid]:
    """An isometric pinacoid whose circumscribed diameter is its ``size`` to the last bit, so that
    the mesh path's scale factor ``size / hull size`` is exactly 1."""
    for k in range(1, 200):
        size = 1.0 - k * 2.0 ** -40
        body = Pinacoid.from_size(size)
        if body.size == size:
            return size, body
    raise AssertionError("no size with an exact circumscribed diameter")


def pinacoid_triangles(body: Pinacoid) -> list[tuple[int, int, int]]:
    """The pinacoid's faces fanned into triangles, counter-clockwise from outside."""
    return [tuple(int(i) for i in (f[0], f[k], f[k + 1])) for f in body.faces for k in range(1, len(f) - 1)]


def write_obj(path, vertices, triangles) -> None:
    """An OBJ with every coordinate written to 17 significant digits (read back exactly)."""
    lines = ["v {!r} {!r} {!r}".format(*(float(x) for x in v)) for v in vertices]
    lines += ["f {} {} {}".format(*(i + 1 for i in t)) for t in triangles]
    path.write_text("\n".join(lines) + "\n")


def pinacoid_corners(body) -> np.ndarray:
    """The vertices of a pinacoid body in the order of the vertex table of docs/method/grains.md."""
    L, G, E, ridge = body.length, body.width, body.thickness, body.ridge
    return np.array([[L / 2, G / 2, 0.0], [-L / 2, G / 2, 0.0], [-L / 2, -G / 2, 0.0], [L / 2, -G / 2, 0.0],
                     [ridge / 2, 0.0, E / 2], [-ridge / 2, 0.0, E / 2], [ridge / 2, 0.0, -E / 2],
                     [-ridge / 2, 0.0, -E / 2]])


def pinacoid_run(size: float) -> str:
    """A short run of 24 grains of ``size`` (seed 5, to t = 2): its population's shape keys follow."""
    return f"""seed = 5
n_particles = 24
lateral_size = 4.0
[equilibrium]
max_time = 2.0
check_interval = 0.1
[[populations]]
size = {size!r}
volume_fraction = 1.0
"""


def test_an_isometric_pinacoid_from_a_file_packs_as_the_built_in_one(tmp_path):
    """Written with its vertex list (OBJ) the pinacoid is the built-in one bit for bit, and so is its
    packing; from an STL, which has no vertex list, it is the same body with its vertices in another
    order (the order in which the triangles bring them)."""
    size, body = exact_size_pinacoid()
    corners = pinacoid_corners(body)  # the vertex table of docs/method/grains.md, in its order
    write_obj(tmp_path / "pinacoid.obj", corners, pinacoid_triangles(body))
    write_ascii_stl(tmp_path / "pinacoid.stl", corners, pinacoid_triangles(body))
    common = pinacoid_run(size)
    (tmp_path / "built_in.toml").write_text(common + 'shape = "pinacoid"\n')
    (tmp_path / "from_file.toml").write_text(common + 'shape = "mesh"\nfiles = ["pinacoid.obj"]\n')
    (tmp_path / "from_stl.toml").write_text(common + 'shape = "mesh"\nfiles = ["pinacoid.stl"]\n')
    built_in, from_file = load_config(tmp_path / "built_in.toml"), load_config(tmp_path / "from_file.toml")
    a, b = Mixture.from_config(built_in).shapes[0], Mixture.from_config(from_file).shapes[0]
    for key in ("vertices", "face_normals", "face_offsets", "edges", "face_axes", "edge_directions"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert a.volume == b.volume and np.array_equal(a.principal_moments, b.principal_moments)
    stl = Mixture.from_config(load_config(tmp_path / "from_stl.toml")).shapes[0]
    assert sorted(map(tuple, stl.vertices.round(15))) == sorted(map(tuple, a.vertices.round(15)))
    assert not np.array_equal(stl.vertices, a.vertices)
    assert stl.volume == pytest.approx(a.volume, rel=1e-14)
    run_packing(built_in, tmp_path / "a", progress=False)
    run_packing(from_file, tmp_path / "b", progress=False)
    fa, fb = (gsd.hoomd.open(tmp_path / name / "final.gsd")[0] for name in ("a", "b"))
    for key in ("position", "orientation", "velocity"):
        assert np.array_equal(fa.log[f"granpack/{key}"], fb.log[f"granpack/{key}"]), key
    assert not math.isclose(float(np.abs(fa.log["granpack/velocity"]).max()), 0.0)


def test_from_an_stl_the_pinacoid_packs_as_the_built_in_one_given_in_the_stl_vertex_order(tmp_path):
    """An STL lists no vertices: they come in the order in which its triangles first bring them, and
    the built-in pinacoid's order is no such order, since its first three vertices are corners of
    the mid-plane z = 0 that no face holds, so that no STL's first triangle brings them. That order
    is all that differs: the grain read from the STL packs bit for bit as the built-in pinacoid's
    vertices given in the STL's order."""
    size, body = exact_size_pinacoid()
    first = body.vertices[:3]
    normal = np.cross(first[1] - first[0], first[2] - first[0])
    side = (body.vertices - first[0]) @ normal
    assert side.min() < 0 < side.max()  # the plane of the first three vertices cuts the body: no face
    corners = pinacoid_corners(body)
    write_ascii_stl(tmp_path / "pinacoid.stl", corners, pinacoid_triangles(body))
    stl_order = read_mesh(tmp_path / "pinacoid.stl").vertices
    assert sorted(map(tuple, stl_order)) == sorted(map(tuple, corners))  # the same points, to the bit
    common = pinacoid_run(size)
    (tmp_path / "from_stl.toml").write_text(common + 'shape = "mesh"\nfiles = ["pinacoid.stl"]\n')
    (tmp_path / "built_in.toml").write_text(common + 'shape = "pinacoid"\n')
    listed = ", ".join("[{!r}, {!r}, {!r}]".format(*(float(x) for x in v)) for v in stl_order)
    (tmp_path / "listed.toml").write_text(common + f'shape = "polyhedron"\nvertices = [{listed}]\n')
    run_packing(load_config(tmp_path / "from_stl.toml"), tmp_path / "stl", progress=False)
    run_packing(load_config(tmp_path / "listed.toml"), tmp_path / "listed", progress=False)
    run_packing(load_config(tmp_path / "built_in.toml"), tmp_path / "built_in", progress=False)
    fa, fb, fc = (gsd.hoomd.open(tmp_path / name / "final.gsd")[0] for name in ("stl", "listed", "built_in"))
    for key in ("position", "orientation", "velocity"):
        assert np.array_equal(fa.log[f"granpack/{key}"], fb.log[f"granpack/{key}"]), key
    assert len(fa.log["contacts/body_i"]) > 10  # the grains have met
    assert not np.array_equal(fa.log["granpack/position"], fc.log["granpack/position"])  # the order tells


def test_check_prints_each_shape_and_a_bad_file_stops_check_and_run(three_grains, capsys):
    config = write_config(three_grains, ["grains/*.stl"], population_extra='size_definition = "sieve"')
    code, out, _ = run_main(["check", "--json", str(config)], capsys)
    assert code == 0
    rows = __import__("json").loads(out)["shapes"]
    assert [r["shape"] for r in rows] == ["g0", "g1", "g2"]
    for row in rows:
        assert row["sizes"]["sieve"] == pytest.approx(1.0, rel=1e-12)
        assert row["vertices"] <= 24 and row["hull_vertices"] > 24 and 0.85 < row["convexity"] <= 1.0
        assert abs(row["deviations"]["volume"]) < 1e-12
    code, out, _ = run_main(["check", str(config)], capsys)
    assert code == 0 and "convexity" in out and "g2" in out
    (three_grains / "grains" / "g1.stl").write_bytes(b"solid nothing\nendsolid nothing\n")
    code, out, err = run_main(["check", str(config)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "g1.stl: holds no triangles" in err
    code, out, err = run_main(["run", str(config), "--out", str(three_grains / "out")], capsys)
    assert code == 2 and "g1.stl" in err and not (three_grains / "out").exists()

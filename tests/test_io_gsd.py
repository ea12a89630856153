"""GSD round trip of packings (exact), OVITO-readable shapes, and bad files."""

from __future__ import annotations

import gsd.hoomd
import numpy as np
import pytest
from packing_builders import cubic_cubes, fcc_spheres, random_pinacoids

from granpack.errors import InputError
from granpack.io.gsd import read_packing, write_packing
from granpack.shapes import Pinacoid, Sphere, platonic

CONTACT_FIELDS = ("body_i", "body_j", "shift", "normal", "ctype", "point_start", "point", "gap", "impulse")


def assert_same(a, b):
    sa, sb = a.state, b.state
    for name in ("kind", "population", "position", "quaternion", "velocity", "omega"):
        np.testing.assert_array_equal(getattr(sa, name), getattr(sb, name), err_msg=name)
    assert sa.time == sb.time
    assert sa.box == sb.box
    for name in CONTACT_FIELDS:
        np.testing.assert_array_equal(getattr(a.contacts, name), getattr(b.contacts, name), err_msg=name)
    assert a.time_step == b.time_step
    assert a.population_names == b.population_names
    assert a.metadata == b.metadata


def test_round_trip_pinacoids_is_exact(tmp_path, rng):
    packing = random_pinacoids(200, rng)
    packing.state.velocity[:] = rng.standard_normal((200, 3)) / 3
    packing.state.omega[:] = rng.standard_normal((200, 3)) / 7
    packing.state.time = 12.345678901234
    packing.metadata.update({"status": "equilibrium", "config": "seed = 11\n", "version": "0.1.0", "step": 42})
    path = write_packing(tmp_path / "final.gsd", packing)
    back = read_packing(path)
    assert_same(packing, back)
    for s, t in zip(packing.state.shapes.shapes, back.state.shapes.shapes):
        assert type(s) is type(t) and isinstance(t, Pinacoid)
        np.testing.assert_array_equal(s.vertices, t.vertices)
    np.testing.assert_array_equal(packing.state.shapes.volume, back.state.shapes.volume)


def test_round_trip_spheres_and_polyhedra(tmp_path):
    fcc, _ = fcc_spheres(2, 2)
    back = read_packing(write_packing(tmp_path / "fcc.gsd", fcc))
    assert_same(fcc, back)
    assert isinstance(back.state.shapes.shapes[0], Sphere)
    assert back.state.shapes.shapes[0].diameter == 1.0
    cubes, _ = cubic_cubes(2, 3)
    back = read_packing(write_packing(tmp_path / "cubes.gsd", cubes))
    assert_same(cubes, back)
    np.testing.assert_allclose(back.state.shapes.vertices, platonic("cube", 1.0).vertices, rtol=0, atol=1e-15)
    assert back.state.shapes.shapes[0].name == "cube"


def test_gsd_schema_opens_with_type_shapes(tmp_path, rng):
    packing = random_pinacoids(50, rng)
    path = write_packing(tmp_path / "final.gsd", packing)
    with gsd.hoomd.open(path, "r") as traj:
        frame = traj[0]
    assert frame.particles.N == 50
    box = frame.configuration.box
    assert box[0] == pytest.approx(8.0) and box[1] == pytest.approx(8.0)
    shapes = frame.particles.type_shapes
    assert [s["type"] for s in shapes] == ["ConvexPolyhedron", "ConvexPolyhedron"]
    assert len(shapes[0]["vertices"]) == 8
    assert list(frame.particles.types) == ["isometric-0", "isometric-1"]
    np.testing.assert_array_equal(frame.particles.typeid, packing.state.kind)
    # positions are centred in the GSD box, inside it, and the origin is logged
    origin = frame.log["granpack/origin"]
    np.testing.assert_allclose(frame.particles.position + origin, packing.state.position, atol=1e-5)
    assert np.all(np.abs(frame.particles.position) <= 0.5 * np.asarray(box[:3]))
    np.testing.assert_allclose(frame.particles.orientation, packing.state.quaternion, atol=1e-6)
    np.testing.assert_array_equal(frame.log["particles/population"], packing.state.population)
    assert frame.log["contacts/point"].shape == (packing.contacts.n_points, 3)


def test_no_contacts_round_trip(tmp_path):
    from packing_builders import single

    packing = single(Sphere(1.0), position=(1.0, 1.0, 0.5))
    back = read_packing(write_packing(tmp_path / "one.gsd", packing))
    assert back.contacts.n_manifolds == 0 and back.contacts.point.shape == (0, 3)
    assert_same(packing, back)


def test_missing_and_corrupt_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_packing(tmp_path / "nope.gsd")
    bad = tmp_path / "bad.gsd"
    bad.write_bytes(b"this is not a gsd file at all" * 10)
    with pytest.raises(InputError, match="not a readable GSD file") as info:
        read_packing(bad)
    assert "\n" not in str(info.value)
    plain = tmp_path / "plain.gsd"
    frame = gsd.hoomd.Frame()
    frame.particles.N = 1
    frame.particles.position = np.zeros((1, 3))
    frame.configuration.box = [2, 2, 2, 0, 0, 0]
    with gsd.hoomd.open(plain, "w") as traj:
        traj.append(frame)
    with pytest.raises(InputError, match="not a granpack packing"):
        read_packing(plain)


def test_truncated_file(tmp_path, rng):
    path = write_packing(tmp_path / "final.gsd", random_pinacoids(100, rng))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError):
        read_packing(path)


def test_write_is_atomic(tmp_path, rng):
    path = write_packing(tmp_path / "final.gsd", random_pinacoids(20, rng))
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def _packing_of(shapes, kind, rng, population=None):
    """Grains of the given kinds at random places, no contacts."""
    from granpack.box import Box
    from granpack.contact.contacts import ContactSet
    from granpack.packing import Packing
    from granpack.rotations import random_quaternions
    from granpack.shapes import ShapeTable
    from granpack.state import ParticleState

    kind = np.asarray(kind, dtype=np.int64)
    n = len(kind)
    state = ParticleState(box=Box.square(4.0), shapes=ShapeTable.from_shapes(shapes), kind=kind,
                          population=np.zeros(n, np.int64) if population is None else np.asarray(population),
                          position=np.column_stack([rng.random(n) * 4, rng.random(n) * 4, 0.5 + rng.random(n) * 3]),
                          quaternion=random_quaternions(n, rng))
    return Packing(state, ContactSet.empty(), 5e-3, ["a", "b"], {"step": 3})


def assert_same_table(a, b):
    assert a.n_kinds == b.n_kinds
    for name in ("vertices", "volume", "radius", "is_sphere"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for s, t in zip(a.shapes, b.shapes):
        assert type(s) is type(t) and s.gsd_shape() == t.gsd_shape()


def test_equal_shapes_share_one_gsd_type_and_read_back_as_their_kinds(tmp_path, rng):
    """Kinds of equal shapes (two populations of one pinacoid, the same mesh file twice) share a GSD
    type; a kind no grain has gets none; the kinds, the shape table and the state read back exact."""
    big, twin = Pinacoid.family("isometric", 1.0), Pinacoid.family("isometric", 1.0)
    small, unused = Pinacoid.family("isometric", 0.5), Sphere(0.3)
    kind = np.array([0, 1, 2, 1, 0, 2, 2, 1])
    packing = _packing_of([big, twin, small, unused], kind, rng, population=[0, 1, 0, 1, 0, 0, 0, 1])
    path = write_packing(tmp_path / "final.gsd", packing)
    with gsd.hoomd.open(path, "r") as traj:
        frame = traj[0]
    assert list(frame.particles.types) == ["isometric-0", "isometric-1"]
    assert frame.particles.type_shapes == [big.gsd_shape(), small.gsd_shape()]
    np.testing.assert_array_equal(frame.particles.typeid, [0, 0, 1, 0, 0, 1, 1, 0])
    np.testing.assert_array_equal(frame.log["particles/kind"], kind)
    back = read_packing(path)
    assert_same(packing, back)
    assert_same_table(packing.state.shapes, back.state.shapes)


def test_graded_grains_take_one_gsd_type_each(tmp_path, rng):
    """A graded population's grains are the population's shape scaled to their sizes: every one a
    shape of its own, so a type each; the unscaled shape (kind 0, no grain) gets none."""
    base = Pinacoid.family("isometric", 1.0)
    sizes = np.linspace(0.4, 1.0, 12)
    packing = _packing_of([base, *(base.scaled(s) for s in sizes)], np.arange(1, 13)[::-1], rng)
    path = write_packing(tmp_path / "graded.gsd", packing)
    with gsd.hoomd.open(path, "r") as traj:
        frame = traj[0]
    assert len(frame.particles.types) == 12 and len(frame.particles.type_shapes) == 12
    for typeid, k in zip(frame.particles.typeid, packing.state.kind):
        assert frame.particles.type_shapes[typeid] == packing.state.shapes.shapes[k].gsd_shape()
    back = read_packing(path)
    assert_same(packing, back)
    assert_same_table(packing.state.shapes, back.state.shapes)


def test_a_format_1_file_reads_its_kinds_from_typeid(tmp_path, rng):
    """Files written before types were shared hold one type per kind, the kind in typeid, and no
    log/particles/kind: they read as they did."""
    shapes = [Pinacoid.family("isometric", 1.0), Pinacoid.family("isometric", 1.0), Sphere(0.3)]
    packing = _packing_of(shapes, [0, 1, 1, 0, 2], rng)
    path = write_packing(tmp_path / "new.gsd", packing)
    with gsd.hoomd.open(path, "r") as traj:
        frame = traj[0]
    frame.particles.types = ["isometric-0", "isometric-1", "sphere"]
    frame.particles.type_shapes = [s.gsd_shape() for s in shapes]
    frame.particles.typeid = packing.state.kind.astype(np.uint32)
    del frame.log["particles/kind"]
    frame.log["granpack/format"] = np.array([1], dtype=np.int64)
    old = tmp_path / "old.gsd"
    with gsd.hoomd.open(old, "w") as traj:
        traj.append(frame)
    back = read_packing(old)
    assert_same(packing, back)
    assert_same_table(packing.state.shapes, back.state.shapes)
    frame.log["granpack/format"] = np.array([9], dtype=np.int64)
    with gsd.hoomd.open(tmp_path / "future.gsd", "w") as traj:
        traj.append(frame)
    with pytest.raises(InputError, match="unsupported granpack GSD format 9"):
        read_packing(tmp_path / "future.gsd")

"""Grain surfaces (`granpack export --format stl|obj|ply`): closed, outward, in place, ids kept, images."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh

from granpack.box import Box
from granpack.cli import main
from granpack.contact.contacts import ContactSet
from granpack.io.gsd import write_packing
from granpack.mesh.surfaces import grain_surfaces, write_surfaces
from granpack.packing import Packing
from granpack.rotations import random_quaternions
from granpack.shapes import Pinacoid, ShapeTable, Sphere
from granpack.state import ParticleState


@pytest.fixture
def packing(rng) -> Packing:
    """A sphere inside the 3 d cell, a sphere across x = 3, a pinacoid across the corner, one inside."""
    shapes = ShapeTable.from_shapes([Sphere(1.0), Pinacoid.from_size(1.0, 2.0, 1.0)])
    state = ParticleState(box=Box.square(3.0), shapes=shapes, kind=np.array([0, 0, 1, 1]), population=np.array([0, 0, 1, 1]),
                          position=np.array([[1.5, 1.5, 0.5], [2.8, 1.5, 0.5], [0.1, 0.1, 1.5], [1.5, 1.5, 2.0]]),
                          quaternion=random_quaternions(4, rng))
    return Packing(state, ContactSet.empty(), 5e-3, ["spheres", "elongated"], {"seed": 1})


def test_surfaces_closed_outward_and_in_place(packing):
    bodies = grain_surfaces(packing)
    assert [b.grain for b in bodies] == [0, 1, 2, 3]
    for body in bodies:
        mesh = body.mesh
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0  # closed, outward
        exact = packing.state.shapes.volume[packing.state.kind[body.grain]]
        tolerance = 0.01 if body.grain < 2 else 1e-12  # icosphere facets; polyhedra exact
        assert mesh.volume == pytest.approx(exact, rel=tolerance)
        assert np.allclose(mesh.center_mass, packing.state.position[body.grain], atol=1e-9)


def test_periodic_images(packing):
    bodies = grain_surfaces(packing, images=True)
    shifts = {b.grain: [] for b in bodies}
    for b in bodies:
        shifts[b.grain].append(b.shift)
    assert shifts[0] == [(0, 0)] and shifts[3] == [(0, 0)]
    assert shifts[1] == [(0, 0), (-1, 0)]  # reaches past x = 3
    assert sorted(shifts[2]) == [(0, 0), (0, 1), (1, 0), (1, 1)]  # across the corner x = y = 0
    image = next(b for b in bodies if b.grain == 1 and b.shift == (-1, 0))
    assert np.allclose(image.mesh.center_mass, [2.8 - 3.0, 1.5, 0.5])


def test_files_keep_grain_ids(tmp_path, packing):
    n_faces = [len(b.mesh.faces) for b in grain_surfaces(packing, images=True)]
    path, count = write_surfaces(packing, tmp_path / "g.stl", "stl", images=True)
    assert count == 4 + 1 + 3
    scene = trimesh.load_scene(path)
    assert sorted(scene.geometry) == sorted(["grain_0", "grain_1", "grain_1_image_-1_0", "grain_2", "grain_2_image_0_1",
                                             "grain_2_image_1_0", "grain_2_image_1_1", "grain_3"])
    assert all(g.is_watertight for g in scene.geometry.values())

    path, _ = write_surfaces(packing, tmp_path / "g.ply", "ply", images=True)
    raw = trimesh.load(path, process=False).metadata["_ply_raw"]["face"]["data"]
    assert np.array_equal(np.bincount(raw["grain"]), [n_faces[0], n_faces[1] * 2, n_faces[3] * 4, n_faces[-1]])
    assert np.count_nonzero(raw["image"] != 4) == n_faces[1] + 3 * n_faces[3]

    path, _ = write_surfaces(packing, tmp_path / "g.obj", "obj")
    text = path.read_text()
    assert re.findall(r"^o (\S+)$", text, re.M) == ["grain_0", "grain_1", "grain_2", "grain_3"]
    whole = trimesh.load(path, process=False)
    assert len(whole.faces) == sum(n_faces[:2]) + 2 * n_faces[3]
    assert list(tmp_path.glob(".*tmp*")) == []


def test_export_command(tmp_path, packing, capsys):
    write_packing(tmp_path / "final.gsd", packing)
    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(tmp_path), "--format", "stl", "--images"])
    assert exit_info.value.code == 0
    assert "8 closed surfaces: 4 grains, 4 periodic images" in capsys.readouterr().out
    assert len(trimesh.load_scene(tmp_path / "surfaces" / "grains.stl").geometry) == 8

    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(tmp_path), "--format", "vtk", "--images"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --images goes with --format stl, obj, ply") and len(err.splitlines()) == 1

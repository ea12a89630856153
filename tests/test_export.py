"""VTK export of a hand-built packing (read back with meshio) and the `granpack export` command."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from matplotlib.image import imread

from granpack.box import Box
from granpack.cli import main
from granpack.contact.contacts import ContactSet
from granpack.io.vtk import contact_counts, grain_surfaces, shape_surface, write_vtk
from granpack.packing import Packing
from granpack.rotations import random_quaternions
from granpack.shapes import Pinacoid, ShapeTable, Sphere
from granpack.state import ParticleState

H = 5e-3
SEGMENTS = 8  # sphere tessellation: 8 meridians x 4 bands = 16 triangles + 16 quads


@pytest.fixture
def packing(rng) -> Packing:
    """Two spheres and two pinacoids in a 3 d cell; contacts: 0-1, 1-2 across the x period, 3-wall."""
    shapes = ShapeTable.from_shapes([Sphere(1.0), Pinacoid.from_size(1.0, 2.0, 1.0)])
    position = np.array([[0.6, 1.5, 0.5], [1.6, 1.5, 0.5], [2.7, 1.5, 0.9], [1.5, 0.5, 0.3]])
    state = ParticleState(
        box=Box.square(3.0),
        shapes=shapes,
        kind=np.array([0, 0, 1, 1]),
        population=np.array([0, 0, 1, 1]),
        position=position,
        quaternion=random_quaternions(4, rng),
    )
    contacts = ContactSet(
        body_i=np.array([1, 1, 3]),
        body_j=np.array([0, 2, -1]),
        shift=np.array([[0.0, 0.0, 0.0], [-3.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        normal=np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        ctype=np.array([1, 1, 3]),
        point_start=np.array([0, 1, 2, 5]),
        point=np.array([[1.1, 1.5, 0.5], [0.1, 1.5, 0.6], [1.4, 0.4, 0.0], [1.6, 0.4, 0.0], [1.5, 0.6, 0.0]]),
        gap=np.zeros(5),
        impulse=H * np.array([[2.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 0.1], [0.0, 0.0, 0.1], [0.0, 0.0, 0.1]]),
    )
    return Packing(state, contacts, H, ["spheres", "elongated"], {"seed": 1})


def test_vtk_files_read_back(tmp_path, packing):
    paths = write_vtk(packing, tmp_path / "vtk", sphere_segments=SEGMENTS)
    assert [p.name for p in paths] == ["grains.vtu", "centres.vtu", "contacts.vtu"]

    grains = meshio.read(paths[0])
    n_sphere_faces = len(shape_surface(Sphere(1.0), SEGMENTS)[1])
    assert n_sphere_faces == 2 * SEGMENTS + SEGMENTS * (SEGMENTS // 2 - 2)
    assert sum(len(c.data) for c in grains.cells) == 2 * n_sphere_faces + 2 * 8  # pinacoids: 8 faces
    ids = np.concatenate(grains.cell_data["particle_id"])
    assert np.bincount(ids).tolist() == [n_sphere_faces, n_sphere_faces, 8, 8]
    population = np.concatenate(grains.cell_data["population"])
    assert np.array_equal(population, packing.state.population[ids])
    assert np.concatenate(grains.cell_data["orientation"]).shape == (len(ids), 4)
    # every grain's surface points lie within its circumscribed sphere, the sphere ones on it
    radius = packing.state.radius
    for block, owner in zip(grains.cells, grains.cell_data["particle_id"]):
        dist = np.linalg.norm(grains.points[block.data] - packing.state.position[owner][:, None, :], axis=-1)
        assert np.all(dist <= radius[owner][:, None] + 1e-12)
        assert np.allclose(dist[owner < 2], 0.5)

    centres = meshio.read(paths[1])
    assert len(centres.cells[0].data) == 4
    assert np.allclose(centres.points, packing.state.position)
    assert np.allclose(centres.point_data["radius"], radius)
    assert centres.point_data["contact_count"].tolist() == [1, 2, 1, 1]

    network = meshio.read(paths[2])
    assert len(network.cells[0].data) == 3 and network.cells[0].type == "line"
    ends = network.points[network.cells[0].data]
    assert np.allclose(ends[1, 1], [2.7 - 3.0, 1.5, 0.9])  # through the periodic image of grain 2
    assert np.allclose(ends[2, 1], [1.5, 0.5, 0.0])  # wall contact: foot on z = 0
    assert np.allclose(network.cell_data["force_magnitude"][0], [2.0, 0.5, 0.3])
    assert np.allclose(network.cell_data["normal_force"][0], [2.0, 0.5, 0.3])
    assert network.cell_data["ctype"][0].tolist() == [1, 1, 3]


def test_surfaces_and_counts(packing):
    surfaces = grain_surfaces(packing.state, SEGMENTS)
    for k, faces in surfaces.faces.items():
        assert faces.shape[1] == k and faces.max() < len(surfaces.points)
        # outward normals: each face's normal points away from its grain's centre
        centre = packing.state.position[surfaces.particle[k]]
        out = np.einsum("ij,ij->i", surfaces.points[faces].mean(axis=1) - centre, surfaces.normal[k])
        assert np.all(out > 0)
    assert contact_counts(packing).tolist() == [1, 2, 1, 1]


def test_export_command(tmp_path, packing, capsys):
    gsd_io = pytest.importorskip("granpack.io.gsd", reason="granpack.io.gsd not written yet")
    gsd_io.write_packing(tmp_path / "final.gsd", packing)

    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(tmp_path), "--format", "vtk"])
    assert exit_info.value.code == 0
    grains = meshio.read(tmp_path / "vtk" / "grains.vtu")
    assert set(np.concatenate(grains.cell_data["particle_id"]).tolist()) == {0, 1, 2, 3}
    assert len(meshio.read(tmp_path / "vtk" / "contacts.vtu").cells[0].data) == 3

    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(tmp_path), "--format", "png"])
    assert exit_info.value.code == 0
    image = imread(tmp_path / "packing.png")
    assert image.shape[0] > 100 and image[..., :3].std() > 0.01

    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(tmp_path), "--format", "dxf"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --format") and "vtk, png, stl, obj, ply" in err and len(err.splitlines()) == 1

    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(tmp_path / "nowhere"), "--format", "vtk"])
    assert exit_info.value.code == 2

"""Reading grain surfaces from mesh files: formats, vertex order, and one-line errors naming the file."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from granpack.shapes.mesh_files import MeshFileError, expand_files, read_mesh


def box_mesh(extents=(1.0, 2.0, 3.0)) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=extents)


@pytest.mark.parametrize("name,file_type", [("g.stl", "stl"), ("g.stl", "stl_ascii"), ("g.obj", "obj"),
                                            ("g.ply", "ply"), ("g.off", "off")])
def test_every_format_reads_the_same_closed_surface(tmp_path, name, file_type):
    mesh = box_mesh((1.0, 2.0, 3.0))
    path = tmp_path / name
    mesh.export(path, file_type=file_type)
    read = read_mesh(path)
    assert read.path == path.resolve()
    assert len(read.vertices) == 8 and len(read.faces) == 12
    assert read.volume == pytest.approx(6.0, rel=1e-12)
    assert {tuple(v) for v in read.vertices} == {tuple(v) for v in mesh.vertices}


def write_ascii_stl(path, vertices, triangles) -> None:
    """An ascii STL with every coordinate written to 17 significant digits (read back exactly)."""
    lines = ["solid grain"]
    for tri in triangles:
        a, b, c = (np.asarray(vertices[i], dtype=np.float64) for i in tri)
        n = np.cross(b - a, c - a)
        lines.append("facet normal {!r} {!r} {!r}".format(*(float(x) for x in n)))
        lines.append("outer loop")
        for p in (a, b, c):
            lines.append("vertex {!r} {!r} {!r}".format(*(float(x) for x in p)))
        lines += ["endloop", "endfacet"]
    lines.append("endsolid grain")
    path.write_text("\n".join(lines) + "\n")


def test_vertices_come_in_the_order_they_first_appear_bit_for_bit(tmp_path, rng):
    points = rng.normal(size=(4, 3))
    hull = trimesh.convex.convex_hull(points)
    order = rng.permutation(len(hull.faces))
    write_ascii_stl(tmp_path / "t.stl", hull.vertices, hull.faces[order])
    read = read_mesh(tmp_path / "t.stl")
    first = []
    for i in hull.faces[order].ravel():
        if int(i) not in first:
            first.append(int(i))
    assert np.array_equal(read.vertices, hull.vertices[first])
    assert np.array_equal(read.vertices[read.faces], hull.vertices[hull.faces[order]])


def test_patterns_relative_to_the_base_folder_sorted_and_once(tmp_path):
    (tmp_path / "grains").mkdir()
    for name in ("b.stl", "a.stl", "c.obj"):
        box_mesh().export(tmp_path / "grains" / name)
    files = expand_files(["grains/*.stl", "grains/a.stl", "grains/c.obj"], tmp_path)
    assert [p.name for p in files] == ["a.stl", "b.stl", "c.obj"]
    assert all(p.is_absolute() for p in files)


def open_box(path):
    mesh = box_mesh()
    trimesh.Trimesh(mesh.vertices, mesh.faces[:-1], process=False).export(path)


def flat_surface(path):
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    trimesh.Trimesh(tri, [[0, 1, 2], [0, 2, 1]], process=False).export(path)


@pytest.mark.parametrize("make,reason", [
    (lambda p: p.write_bytes(b""), "empty file"),
    (lambda p: p.write_bytes(b"not a mesh at all " * 20), "holds no triangles"),
    (open_box, "not closed"),
    (flat_surface, "encloses no volume"),
])
def test_bad_files_give_one_line_naming_the_file(tmp_path, make, reason):
    path = tmp_path / "bad.stl"
    make(path)
    with pytest.raises(MeshFileError) as info:
        read_mesh(path)
    message = str(info.value)
    assert message.startswith(str(path.resolve()) + ": ") and reason in message and "\n" not in message


def test_missing_files_patterns_and_folders(tmp_path):
    (tmp_path / "folder").mkdir()
    (tmp_path / "notes.txt").write_text("x")
    cases = {"nothing/*.stl": "matches no file", "gone.stl": "no such file", "folder": "is a directory",
             "notes.txt": "not a mesh file"}
    for pattern, reason in cases.items():
        with pytest.raises(MeshFileError, match=reason):
            expand_files([pattern], tmp_path)

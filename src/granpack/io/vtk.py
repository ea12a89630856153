"""Packings as VTK files for ParaView (written with meshio).

:func:`write_vtk` writes three XML unstructured grids (``.vtu``) into a folder:

- ``grains.vtu``: the true surface of every grain as polygon cells: the faces of each polyhedron
  (triangles, quads, polygons), and a latitude-longitude tessellation of each sphere. Cell data
  (one value per face, constant over a grain): ``particle_id``, ``population``, ``kind``,
  ``contact_count``, ``orientation`` (quaternion w, x, y, z).
- ``centres.vtu``: one vertex cell per grain at its centre of mass, with ``particle_id``,
  ``population``, ``kind``, ``radius`` (circumscribed, d; for the "Glyph" filter with spheres),
  ``contact_count``, ``orientation``, ``axis_x``, ``axis_y``, ``axis_z`` (body axes in the world
  frame), ``velocity`` (sqrt(g d)).
- ``contacts.vtu``: the contact network, one line cell per manifold from the centre of ``i`` to
  the centre of ``j`` **through its periodic image** (``x_j + shift``, so lines never cross the
  cell); wall contacts go from the centre to its foot on the wall: on the floor z = 0 straight
  down, on a container's wall along the contact's normal to the wall's tangent plane at the
  contact (:meth:`granpack.packing.Packing.branch_vectors`). Cell data: ``body_i``, ``body_j``
  (< 0: a wall, its id), ``ctype`` (1 simple, 2 double, 3 triple), ``force``
  (resultant on ``i``, vector), ``force_magnitude`` and ``normal_force`` (> 0 compressive), in
  units of rho g d^3 (``impulse / time_step``; density 1, g = 1).

- ``container.vtu`` (a box or a cylinder only, :class:`granpack.box.Box`): the container's inside
  surface (:mod:`granpack.io.container`): the floor as triangles, the walls as quads; cell data
  ``wall`` (the wall's id, -1 the floor, :mod:`granpack.contact.contacts`). ParaView shows it with
  the grains (opacity below 1 to see inside).

``contact_count`` is the number of contact manifolds of a grain, the walls included. Lengths are
in d. Each file is written under a temporary name and renamed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np

from granpack.io.atomic import atomic_path
from granpack.io.container import container_surface
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix
from granpack.shapes import ConvexPolyhedron, Shape, Sphere
from granpack.state import ParticleState

__all__ = ["SurfaceMesh", "shape_surface", "grain_surfaces", "contact_counts", "write_vtk"]

#: meshio cell type of a polygon with k vertices
_CELL_TYPE = {3: "triangle", 4: "quad"}


@dataclass(frozen=True)
class SurfaceMesh:
    """Polygonal surfaces of grains, faces grouped by their number of vertices.

    Attributes:
        points: ``(P, 3)`` vertex coordinates, d.
        faces: ``{k: (F_k, k) int64}`` vertex indices of the faces with k vertices,
            counter-clockwise seen from outside.
        particle: ``{k: (F_k,) int64}`` grain owning each face.
        normal: ``{k: (F_k, 3)}`` outward unit normal of each face (for spheres, of the
            tessellation facet).
    """

    points: np.ndarray
    faces: dict[int, np.ndarray]
    particle: dict[int, np.ndarray]
    normal: dict[int, np.ndarray]


def _sphere_surface(radius: float, segments: int) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """Latitude-longitude tessellation: ``segments`` meridians, ``segments // 2`` bands."""
    n_lat, n_lon = max(segments // 2, 2), max(segments, 3)
    theta = np.linspace(0.0, np.pi, n_lat + 1)[1:-1]
    phi = np.linspace(0.0, 2.0 * np.pi, n_lon, endpoint=False)
    ring = np.stack(
        [np.outer(np.sin(theta), np.cos(phi)), np.outer(np.sin(theta), np.sin(phi)), np.outer(np.cos(theta), np.ones(n_lon))],
        axis=-1,
    ).reshape(-1, 3)
    unit = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    south = len(unit) - 1
    faces: list[np.ndarray] = []
    for b in range(n_lon):
        nb = (b + 1) % n_lon
        faces.append(np.array([0, 1 + b, 1 + nb]))
        for r in range(n_lat - 2):
            top, bottom = 1 + r * n_lon, 1 + (r + 1) * n_lon
            faces.append(np.array([top + b, bottom + b, bottom + nb, top + nb]))
        last = 1 + (n_lat - 2) * n_lon
        faces.append(np.array([last + b, south, last + nb]))
    normals = np.array([unit[f].mean(axis=0) for f in faces])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return radius * unit, faces, normals


def shape_surface(shape: Shape, sphere_segments: int = 16) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """Body-frame surface of a shape.

    Args:
        shape: a :class:`~granpack.shapes.Sphere` or :class:`~granpack.shapes.ConvexPolyhedron`.
        sphere_segments: meridians of a sphere's tessellation (``segments // 2`` bands).

    Returns:
        ``(vertices (V, 3), faces (list of index arrays, counter-clockwise from outside),
        normals (F, 3))``, in d.
    """
    if isinstance(shape, Sphere):
        return _sphere_surface(shape.radius, sphere_segments)
    if isinstance(shape, ConvexPolyhedron):
        return shape.vertices, [np.asarray(f, dtype=np.int64) for f in shape.faces], shape.face_normals
    raise TypeError(f"no surface for shape {shape!r}")


def grain_surfaces(state: ParticleState, sphere_segments: int = 16) -> SurfaceMesh:
    """World-frame surfaces of all grains (each grain drawn at its wrapped centre).

    Args:
        state: the grains.
        sphere_segments: meridians of each sphere's tessellation.

    Returns:
        The surfaces, faces grouped by vertex count.
    """
    rotation = quat_to_matrix(state.quaternion)
    points: list[np.ndarray] = []
    faces: dict[int, list[np.ndarray]] = {}
    owner: dict[int, list[np.ndarray]] = {}
    normal: dict[int, list[np.ndarray]] = {}
    offset = 0
    # the grains of each kind, in index order (one sort: a graded population has a kind per grain)
    order = np.argsort(state.kind, kind="stable")
    bounds = np.searchsorted(state.kind[order], np.arange(state.shapes.n_kinds + 1))
    for kind, shape in enumerate(state.shapes.shapes):
        members = order[bounds[kind]:bounds[kind + 1]]
        if not len(members):
            continue
        vertices, kind_faces, kind_normals = shape_surface(shape, sphere_segments)
        rot = rotation[members]
        world = np.einsum("nij,vj->nvi", rot, vertices) + state.position[members, None, :]
        base = offset + len(vertices) * np.arange(len(members))
        points.append(world.reshape(-1, 3))
        offset += world.shape[0] * world.shape[1]
        sizes = np.array([len(f) for f in kind_faces])
        for k in np.unique(sizes):
            pick = np.flatnonzero(sizes == k)
            template = np.stack([kind_faces[f] for f in pick])  # (F_k, k)
            faces.setdefault(int(k), []).append((base[:, None, None] + template[None]).reshape(-1, int(k)))
            owner.setdefault(int(k), []).append(np.repeat(members, len(pick)))
            normal.setdefault(int(k), []).append(np.einsum("nij,fj->nfi", rot, kind_normals[pick]).reshape(-1, 3))
    return SurfaceMesh(
        points=np.concatenate(points) if points else np.zeros((0, 3)),
        faces={k: np.concatenate(v).astype(np.int64) for k, v in sorted(faces.items())},
        particle={k: np.concatenate(v).astype(np.int64) for k, v in sorted(owner.items())},
        normal={k: np.concatenate(v) for k, v in sorted(normal.items())},
    )


def contact_counts(packing: Packing) -> np.ndarray:
    """``(N,)`` int64 number of contact manifolds of each grain (wall contacts included)."""
    c = packing.contacts
    n = packing.n_particles
    counts = np.bincount(c.body_i, minlength=n)
    others = c.body_j[c.body_j >= 0]
    return (counts + np.bincount(others, minlength=n)).astype(np.int64)


def _write(mesh: meshio.Mesh, path: Path) -> Path:
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return path


def _grains_mesh(packing: Packing, counts: np.ndarray, sphere_segments: int) -> meshio.Mesh:
    state = packing.state
    surfaces = grain_surfaces(state, sphere_segments)
    cells, data = [], {"particle_id": [], "population": [], "kind": [], "contact_count": [], "orientation": []}
    for k, faces in surfaces.faces.items():
        cells.append((_CELL_TYPE.get(k, "polygon"), faces))
        owner = surfaces.particle[k]
        data["particle_id"].append(owner)
        data["population"].append(state.population[owner])
        data["kind"].append(state.kind[owner])
        data["contact_count"].append(counts[owner])
        data["orientation"].append(state.quaternion[owner])
    return meshio.Mesh(surfaces.points, cells, cell_data=data)


def _centres_mesh(packing: Packing, counts: np.ndarray) -> meshio.Mesh:
    state = packing.state
    axes = quat_to_matrix(state.quaternion)  # columns: body axes in the world frame
    point_data = {
        "particle_id": np.arange(state.n, dtype=np.int64),
        "population": state.population,
        "kind": state.kind,
        "radius": state.radius,
        "contact_count": counts,
        "orientation": state.quaternion,
        "axis_x": axes[:, :, 0],
        "axis_y": axes[:, :, 1],
        "axis_z": axes[:, :, 2],
        "velocity": state.velocity,
    }
    vertices = np.arange(state.n, dtype=np.int64)[:, None]
    return meshio.Mesh(state.position, [("vertex", vertices)], point_data=point_data)


def _contacts_mesh(packing: Packing) -> meshio.Mesh:
    c = packing.contacts
    x = packing.state.position
    start = x[c.body_i]
    end = np.where((c.body_j >= 0)[:, None], x[np.maximum(c.body_j, 0)] + c.shift, start * np.array([1.0, 1.0, 0.0]))
    side = c.body_j < -1  # a container's wall: the foot along the normal (packing.branch_vectors)
    end[side] = start[side] - packing.branch_vectors()[side]
    points = np.stack([start, end], axis=1).reshape(-1, 3)
    lines = np.arange(2 * c.n_manifolds, dtype=np.int64).reshape(-1, 2)
    force = packing.manifold_force
    data = {
        "body_i": [c.body_i],
        "body_j": [c.body_j],
        "ctype": [c.ctype],
        "force": [force],
        "force_magnitude": [np.linalg.norm(force, axis=1)],
        "normal_force": [packing.manifold_normal_force],
    }
    return meshio.Mesh(points, [("line", lines)], cell_data=data)


def _container_mesh(packing: Packing) -> meshio.Mesh:
    """The inside surface of a box or a cylinder (:func:`granpack.io.container.container_surface`)."""
    surface = container_surface(packing)
    k = len(surface.wall)
    return meshio.Mesh(surface.points, [("triangle", surface.triangles), ("quad", surface.quads)],
                       cell_data={"wall": [np.full(k, -1), surface.wall]})


def write_vtk(packing: Packing, out_dir: str | os.PathLike, *, sphere_segments: int = 16) -> list[Path]:
    """Write ``grains.vtu``, ``centres.vtu``, ``contacts.vtu`` and for a box or a cylinder
    ``container.vtu`` (see module docstring).

    Args:
        packing: the packing.
        out_dir: the folder (created).
        sphere_segments: meridians of each sphere's tessellation (bands: half as many).

    Returns:
        The paths written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    counts = contact_counts(packing)
    written = [
        _write(_grains_mesh(packing, counts, sphere_segments), out / "grains.vtu"),
        _write(_centres_mesh(packing, counts), out / "centres.vtu"),
        _write(_contacts_mesh(packing), out / "contacts.vtu"),
    ]
    if not packing.box.periodic:
        written.append(_write(_container_mesh(packing), out / "container.vtu"))
    return written

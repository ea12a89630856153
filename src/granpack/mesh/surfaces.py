"""Grain surfaces as closed triangulated meshes (trimesh), for CAD and mesh generators.

Each grain is one closed, outward-oriented triangle surface in the packing's frame (lengths in d):
a polyhedron's planar faces split into triangles fanned from their first vertex (exact), a sphere
an icosphere of :data:`SPHERE_SUBDIVISIONS` subdivisions (``20 * 4**s`` triangles, vertices on the
sphere). Grain ``i`` is at its wrapped centre; with ``images`` the periodic copies of the grains that
cross the cell's x or y sides are written too, shifted by the periods. The grain id is kept: one
solid ``grain_<i>`` per body in STL (ASCII), one object ``o grain_<i>`` in OBJ, a face property
``grain`` (int) in PLY (binary); an image is named ``grain_<i>_image_<a>_<b>`` (STL, OBJ; shift
``(a lx, b ly)``) and carries ``image = 3 (a + 1) + (b + 1)`` in PLY (4: the grain itself).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from granpack.errors import InputError
from granpack.io.atomic import atomic_path
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix
from granpack.shapes import ConvexPolyhedron, Sphere

__all__ = ["FORMATS", "SPHERE_SUBDIVISIONS", "GrainSurface", "grain_surfaces", "write_surfaces"]

#: the surface formats (file suffix = format)
FORMATS = ("stl", "obj", "ply")
#: icosphere subdivisions of a sphere (3: 1280 triangles, volume 0.86 % under the sphere's)
SPHERE_SUBDIVISIONS = 3


class GrainSurface:
    """One body written: ``grain`` (index in the packing), ``shift`` ``(a, b)`` in periods, ``mesh`` (trimesh)."""

    __slots__ = ("grain", "shift", "mesh")

    def __init__(self, grain: int, shift: tuple[int, int], mesh):
        self.grain = grain
        self.shift = shift
        self.mesh = mesh

    @property
    def name(self) -> str:
        """``grain_<i>``, or ``grain_<i>_image_<a>_<b>`` for a periodic image."""
        a, b = self.shift
        return f"grain_{self.grain}" if (a, b) == (0, 0) else f"grain_{self.grain}_image_{a}_{b}"


def _template(shape):
    """``(vertices, triangles)`` of a shape's surface in its body frame, triangles counter-clockwise from outside."""
    import trimesh

    if isinstance(shape, Sphere):
        ball = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=shape.radius)
        return np.asarray(ball.vertices), np.asarray(ball.faces, dtype=np.int64)
    if isinstance(shape, ConvexPolyhedron):
        triangles = [(f[0], f[k], f[k + 1]) for f in shape.faces for k in range(1, len(f) - 1)]
        return shape.vertices, np.array(triangles, dtype=np.int64)
    raise TypeError(f"no surface for shape {shape!r}")


def grain_surfaces(packing: Packing, *, images: bool = False) -> list[GrainSurface]:
    """Every grain as a closed surface at its wrapped centre, then (``images``) the periodic images
    of those reaching past ``x = 0``, ``x = lx``, ``y = 0`` or ``y = ly``, in grain order. In a box
    or a cylinder (:class:`granpack.box.Box`) the centres are not wrapped and there are no images."""
    import trimesh

    state = packing.state
    lx, ly = packing.box.lx, packing.box.ly
    rotation = quat_to_matrix(state.quaternion)
    position = state.position.copy()
    periodic = packing.box.periodic
    if periodic:
        position[:, 0] = np.mod(position[:, 0], lx)
        position[:, 1] = np.mod(position[:, 1], ly)
    templates = [_template(s) for s in state.shapes.shapes]
    out = []
    for i in range(state.n):
        vertices, triangles = templates[state.kind[i]]
        world = vertices @ rotation[i].T + position[i]
        shifts = [(0, 0)]
        if images and periodic:
            lo, hi = world.min(axis=0), world.max(axis=0)
            along_x = [0] + ([1] if lo[0] < 0 else []) + ([-1] if hi[0] > lx else [])
            along_y = [0] + ([1] if lo[1] < 0 else []) + ([-1] if hi[1] > ly else [])
            shifts += [(a, b) for a in along_x for b in along_y if (a, b) != (0, 0)]
        for a, b in shifts:
            mesh = trimesh.Trimesh(world + np.array([a * lx, b * ly, 0.0]), triangles, process=False)
            out.append(GrainSurface(i, (a, b), mesh))
    return out


def _stl(bodies: list[GrainSurface]) -> bytes:
    from trimesh.exchange.stl import export_stl_ascii

    parts = []
    for body in bodies:
        text = export_stl_ascii(body.mesh)
        parts.append(text.replace("solid ", f"solid {body.name}", 1).rstrip().rsplit("\n", 1)[0] + f"\nendsolid {body.name}\n")
    return "".join(parts).encode()


def _obj(bodies: list[GrainSurface]) -> bytes:
    import trimesh
    from trimesh.exchange.obj import export_obj

    scene = trimesh.Scene()
    for body in bodies:
        scene.add_geometry(body.mesh, geom_name=body.name)
    return export_obj(scene, include_normals=False, include_color=False, include_texture=False, header=None).encode()


def _ply(bodies: list[GrainSurface]) -> bytes:
    import trimesh
    from trimesh.exchange.ply import export_ply

    merged = trimesh.util.concatenate([b.mesh for b in bodies])
    counts = [len(b.mesh.faces) for b in bodies]
    merged.face_attributes["grain"] = np.repeat([b.grain for b in bodies], counts).astype(np.int32)
    merged.face_attributes["image"] = np.repeat([3 * (b.shift[0] + 1) + b.shift[1] + 1 for b in bodies], counts).astype(np.int32)
    return export_ply(merged, encoding="binary")


def write_surfaces(packing: Packing, path: str | os.PathLike, fmt: str, *, images: bool = False) -> tuple[Path, int]:
    """Write the grain surfaces (module docstring) to ``path`` atomically.

    Returns:
        ``(path, number of bodies written)``.

    Raises:
        InputError: ``fmt`` is not one of :data:`FORMATS`.
    """
    writers = {"stl": _stl, "obj": _obj, "ply": _ply}
    if fmt not in writers:
        raise InputError(f"--format must be one of {', '.join(FORMATS)} for surfaces (got {fmt!r})")
    bodies = grain_surfaces(packing, images=images)
    data = writers[fmt](bodies)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path), len(bodies)

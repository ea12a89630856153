"""The inside surface of a box or a cylinder, for the viewers: ``container.stl`` beside
``final.gsd`` (OVITO) and ``vtk/container.vtu`` (ParaView, :mod:`granpack.io.vtk`).

The surface runs from the floor z = 0 to 1 d above the highest grain, the height of the GSD
file's box: the floor (a fan of triangles about the container's axis) and the four walls of a box,
or the floor and the wall of a cylinder in :data:`CYLINDER_SEGMENTS` flat facets whose corners lie
on the cylinder. Every facet faces the grains (its normal points into the container), so a viewer
that culls back faces shows the far walls behind the grains and hides the near ones.

GSD has no place for a wall that OVITO draws, and a particle standing for the container would be
counted as a grain by every reader of the file, so the container goes beside it:
``container.stl`` is in ``final.gsd``'s own frame (positions less ``log/granpack/origin``), and
File > Load File > "Add to scene" in OVITO puts it where the grains are. Lengths in d.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from granpack.io.atomic import atomic_path
from granpack.io.gsd import frame_origin
from granpack.packing import Packing

__all__ = ["CYLINDER_SEGMENTS", "ContainerSurface", "container_surface", "write_container_stl"]

#: flat facets of a cylinder's wall
CYLINDER_SEGMENTS = 96


@dataclass(frozen=True)
class ContainerSurface:
    """The container's inside surface: ``points`` (P, 3), the floor's ``triangles`` (k, 3), the
    walls' ``quads`` (k, 4), each wall quad's ``wall`` id (k,) (-2..-5 a box's walls, -6 the
    cylinder; the floor is -1, :mod:`granpack.contact.contacts`)."""

    points: np.ndarray
    triangles: np.ndarray
    quads: np.ndarray
    wall: np.ndarray

    def as_triangles(self) -> np.ndarray:
        """Every facet as triangles (floor first, each quad split along its first diagonal), facing in."""
        q = self.quads
        return np.vstack([self.triangles, q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def container_surface(packing: Packing) -> ContainerSurface:
    """The inside surface of ``packing``'s box or cylinder in the packing's frame (module docstring).

    Raises:
        ValueError: the packing is in a periodic cell, which has no container.
    """
    box = packing.box
    if box.periodic:
        raise ValueError("a periodic cell has no container surface")
    height = 2.0 * frame_origin(packing)[2]  # the GSD box's height
    if box.container == "cylinder":
        angle = 2.0 * np.pi * np.arange(CYLINDER_SEGMENTS) / CYLINDER_SEGMENTS
        ring = np.column_stack([0.5 * box.lx * (1.0 + np.cos(angle)), 0.5 * box.ly + 0.5 * box.lx * np.sin(angle)])
    else:
        ring = np.array([[0.0, 0.0], [box.lx, 0.0], [box.lx, box.ly], [0.0, box.ly]])
    k = len(ring)  # the ring runs counter-clockwise seen from above
    centre = [0.5 * box.lx, 0.5 * box.ly, 0.0]
    points = np.vstack([np.column_stack([ring, np.zeros(k)]), np.column_stack([ring, np.full(k, height)]), [centre]])
    a = np.arange(k)
    b = (a + 1) % k
    floor = np.column_stack([np.full(k, 2 * k), a, b])  # counter-clockwise from above: facing up, into the container
    walls = np.column_stack([b, a, a + k, b + k])  # clockwise seen from outside: facing the axis
    # the box's walls y = 0, x = L, y = L, x = 0 in ring order; the cylinder's facets all -6
    wall = np.array([-4, -3, -5, -2]) if box.container == "box" else np.full(k, -6)
    return ContainerSurface(points, floor, walls, wall)


def write_container_stl(path: str | os.PathLike, packing: Packing) -> Path:
    """Write the container's inside surface as a binary STL in the frame of ``packing``'s GSD file
    (shifted by :func:`granpack.io.gsd.frame_origin`), atomically.

    Returns:
        The path written.
    """
    import meshio

    surface = container_surface(packing)
    mesh = meshio.Mesh(surface.points - frame_origin(packing), [("triangle", surface.as_triangles())])
    path = Path(path)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="stl", binary=True)
    return path

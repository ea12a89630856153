"""Shape tables: every particle kind's geometry packed as flat arrays for Numba kernels.

Layout (CSR: the rows of kind ``k`` are ``start[k]:start[k+1]``; polyhedron index data is
**local** to the kind, i.e. vertex index 0 is ``vertices[vertex_start[k]]``). Spheres have empty
vertex/face/edge blocks. All geometry is in the body frame (centroid at origin, principal axes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from granpack.shapes.base import Shape
from granpack.shapes.polyhedron import ConvexPolyhedron
from granpack.shapes.sphere import Sphere

__all__ = ["ShapeTable"]


def _csr(blocks: list[np.ndarray], width: int | None, dtype) -> tuple[np.ndarray, np.ndarray]:
    start = np.zeros(len(blocks) + 1, dtype=np.int64)
    start[1:] = np.cumsum([len(b) for b in blocks])
    shape = (int(start[-1]),) if width is None else (int(start[-1]), width)
    data = np.concatenate(blocks).astype(dtype) if start[-1] else np.zeros(shape, dtype=dtype)
    return start, data.reshape(shape)


@dataclass(frozen=True)
class ShapeTable:
    """Geometry of ``K`` particle kinds as flat arrays.

    Attributes:
        shapes: the ``K`` shape objects.
        is_sphere: ``(K,)`` bool.
        radius: ``(K,)`` circumscribed radius (sphere radius for spheres), d.
        volume: ``(K,)`` volume = mass at unit density, d^3.
        inertia: ``(K, 3)`` principal moments (unit density), d^5.
        vertex_start, vertices: ``(K+1,)``, ``(NV, 3)`` body-frame vertices.
        face_start, face_normals, face_offsets: ``(K+1,)``, ``(NF, 3)``, ``(NF,)``; face f of a
            kind is ``{x : n_f . x <= offset_f}``.
        face_vertex_start, face_vertices: ``(NF+1,)`` (indexed by global face row), ``(NFV,)``
            local vertex indices, counter-clockwise from outside.
        edge_start, edges: ``(K+1,)``, ``(NE, 2)`` local vertex index pairs.
        edge_faces: ``(NE, 2)`` local indices of the two faces meeting at each edge (rows of
            ``edges``).
        axis_start, face_axes: ``(K+1,)``, ``(NA, 3)`` distinct face normals up to sign.
        direction_start, edge_directions: ``(K+1,)``, ``(ND, 3)`` distinct edge directions up to sign.
    """

    shapes: tuple[Shape, ...]
    is_sphere: np.ndarray
    radius: np.ndarray
    volume: np.ndarray
    inertia: np.ndarray
    vertex_start: np.ndarray
    vertices: np.ndarray
    face_start: np.ndarray
    face_normals: np.ndarray
    face_offsets: np.ndarray
    face_vertex_start: np.ndarray
    face_vertices: np.ndarray
    edge_start: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    axis_start: np.ndarray
    face_axes: np.ndarray
    direction_start: np.ndarray
    edge_directions: np.ndarray

    @classmethod
    def from_shapes(cls, shapes: list[Shape] | tuple[Shape, ...]) -> "ShapeTable":
        """Pack ``shapes`` (kind k = position in the list)."""
        shapes = tuple(shapes)
        if not shapes:
            raise ValueError("a shape table needs at least one shape")
        empty3 = np.zeros((0, 3))
        poly = [s if isinstance(s, ConvexPolyhedron) else None for s in shapes]
        for s in shapes:
            if not isinstance(s, (Sphere, ConvexPolyhedron)):
                raise TypeError(f"unsupported shape {s!r}")
        vertex_start, vertices = _csr([p.vertices if p else empty3 for p in poly], 3, np.float64)
        face_start, face_normals = _csr([p.face_normals if p else empty3 for p in poly], 3, np.float64)
        _, face_offsets = _csr([p.face_offsets if p else np.zeros(0) for p in poly], None, np.float64)
        all_faces = [f for p in poly if p for f in p.faces]
        face_vertex_start, face_vertices = _csr(all_faces or [np.zeros(0, np.int64)], None, np.int64)
        if not all_faces:
            face_vertex_start = np.zeros(1, dtype=np.int64)
        edge_start, edges = _csr([p.edges if p else np.zeros((0, 2), np.int64) for p in poly], 2, np.int64)
        _, edge_faces = _csr([p.edge_faces if p else np.zeros((0, 2), np.int64) for p in poly], 2, np.int64)
        axis_start, face_axes = _csr([p.face_axes if p else empty3 for p in poly], 3, np.float64)
        direction_start, edge_directions = _csr([p.edge_directions if p else empty3 for p in poly], 3, np.float64)
        return cls(
            shapes=shapes,
            is_sphere=np.array([isinstance(s, Sphere) for s in shapes]),
            radius=np.array([s.circumscribed_radius for s in shapes]),
            volume=np.array([s.volume for s in shapes]),
            inertia=np.array([s.principal_moments for s in shapes]),
            vertex_start=vertex_start,
            vertices=vertices,
            face_start=face_start,
            face_normals=face_normals,
            face_offsets=face_offsets,
            face_vertex_start=face_vertex_start,
            face_vertices=face_vertices,
            edge_start=edge_start,
            edges=edges,
            edge_faces=edge_faces,
            axis_start=axis_start,
            face_axes=face_axes,
            direction_start=direction_start,
            edge_directions=edge_directions,
        )

    @property
    def n_kinds(self) -> int:
        return len(self.shapes)

    @property
    def max_radius(self) -> float:
        """Largest circumscribed radius over the kinds, d."""
        return float(self.radius.max())

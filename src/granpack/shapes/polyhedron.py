"""Convex polyhedra with exact mass properties.

Mass properties use the signed-tetrahedron (covariance) decomposition (Tonon 2004; Mirtich 1996;
Eberly): every face is fanned into triangles (v0, vk, vk+1) that form tetrahedra with the origin.
With ``A = [a b c]`` (vertex columns) and ``D = det A``:

.. math::

    V = \\sum D/6, \\qquad V x_G = \\sum (D/6)(a + b + c)/4, \\qquad
    C = \\int x x^T dV = \\sum D\\, A K A^T, \\quad K = \\frac{1}{120}
    \\begin{pmatrix}2&1&1\\\\1&2&1\\\\1&1&2\\end{pmatrix},

    C_G = C - V x_G x_G^T, \\qquad J = \\rho(\\mathrm{tr}(C_G) I - C_G).
"""

from __future__ import annotations

import copy
import math
from functools import cached_property

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from granpack.shapes.base import Shape, ShapeError

__all__ = ["ConvexPolyhedron", "mass_properties"]

_K = np.array([[2.0, 1.0, 1.0], [1.0, 2.0, 1.0], [1.0, 1.0, 2.0]]) / 120.0


def mass_properties(vertices: np.ndarray, faces: list[np.ndarray]) -> tuple[float, np.ndarray, np.ndarray]:
    """Exact volume, centroid and inertia tensor (unit density, about the centroid) of a polyhedron.

    Args:
        vertices: ``(V, 3)`` vertex coordinates.
        faces: vertex index lists, counter-clockwise seen from outside.

    Returns:
        ``(volume, centroid (3,), inertia (3, 3))``.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    tri = np.array([(f[0], f[k], f[k + 1]) for f in faces for k in range(1, len(f) - 1)])
    a, b, c = vertices[tri[:, 0]], vertices[tri[:, 1]], vertices[tri[:, 2]]
    mats = np.stack([a, b, c], axis=-1)  # (T, 3, 3), columns a, b, c
    det = np.linalg.det(mats)
    volume = det.sum() / 6.0
    centroid = ((det / 6.0)[:, None] * (a + b + c) / 4.0).sum(axis=0) / volume
    cov = np.einsum("t,tij,jk,tlk->il", det, mats, _K, mats)
    cov_g = cov - volume * np.outer(centroid, centroid)
    inertia = np.trace(cov_g) * np.eye(3) - cov_g
    return float(volume), centroid, inertia


def _length(v: np.ndarray) -> float:
    """Euclidean length of a 3-vector, ``sqrt(x² + y² + z²)`` summed in this order.

    ``np.linalg.norm`` goes through BLAS, whose kernel is chosen by the CPU and rounds the last
    bit differently from one machine to another; with this length the edge directions and face
    normals, hence the pinacoids' shape tables, have the same bits on every machine, so that a
    seed gives the same packing everywhere."""
    x, y, z = (float(c) for c in v)
    return math.sqrt(x * x + y * y + z * z)


def _unique_directions(vectors: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Unit vectors with duplicates up to sign removed (first occurrence kept, sign normalised)."""
    out: list[np.ndarray] = []
    for v in vectors:
        u = v / _length(v)
        if not any(abs(abs(float(u @ w)) - 1.0) < tol for w in out):
            out.append(u)
    return np.array(out).reshape(-1, 3)


class ConvexPolyhedron(Shape):
    """A convex polyhedron in its body frame.

    Built from a vertex list: the convex hull is taken, coplanar hull triangles are merged into
    polygonal faces (counter-clockwise from outside), the body is translated so that its centroid
    is at the origin and, unless its inertia tensor is already diagonal, rotated onto its
    principal axes (ascending moments, right-handed).

    Args:
        vertices: ``(V, 3)`` coordinates, in d. Every point must be a vertex of the hull.
        name: a label (shown in tables and GSD type names).

    Raises:
        ShapeError: fewer than 4 points, coplanar (zero volume) or repeated points, or a point
            that is not an extreme vertex (non-convex list).

    Attributes:
        vertices: ``(V, 3)`` body-frame vertices.
        faces: list of ``F`` integer arrays, vertex indices counter-clockwise seen from outside.
        face_normals: ``(F, 3)`` outward unit normals.
        face_offsets: ``(F,)`` plane offsets: the body is ``{x : n_f . x <= offset_f}``.
        edges: ``(E, 2)`` vertex index pairs, each edge once.
        rotation: ``(3, 3)`` matrix taking the input frame (after centring) to the body frame.
        input_centroid: ``(3,)`` centroid of the input vertices' hull, in the input frame.
    """

    kind = "polyhedron"
    #: convexity of the surface this grain is the convex hull of (volume it encloses / hull
    #: volume, :mod:`granpack.shapes.from_mesh`); None for a grain given as a convex body
    source_convexity: float | None = None

    def __init__(self, vertices, name: str = "polyhedron", *, coplanar_tol: float = 1e-9):
        pts = np.asarray(vertices, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ShapeError(f"vertices must be a list of [x, y, z] triples, got shape {pts.shape}")
        if len(pts) < 4:
            raise ShapeError(f"a polyhedron needs at least 4 vertices, got {len(pts)}")
        if not np.all(np.isfinite(pts)):
            raise ShapeError("vertices must be finite numbers")
        scale = float(np.ptp(pts, axis=0).max())
        if scale <= 0:
            raise ShapeError("vertices are all identical (degenerate polyhedron)")
        try:
            hull = ConvexHull(pts)
        except QhullError:
            raise ShapeError("vertices are coplanar or collinear (degenerate polyhedron, zero volume)") from None
        if hull.volume <= 1e-12 * scale**3:
            raise ShapeError("vertices are coplanar (degenerate polyhedron, zero volume)")
        missing = sorted(set(range(len(pts))) - set(hull.vertices.tolist()))
        if missing:
            raise ShapeError(
                f"vertex {missing[0]} {pts[missing[0]].tolist()} is not an extreme point of the convex hull "
                "(non-convex shape, repeated or redundant vertex)"
            )
        faces, normals, offsets = self._merge_faces(pts, hull, coplanar_tol * scale)
        volume, centroid, inertia = mass_properties(pts, faces)

        centred = pts - centroid
        off = inertia - np.diag(np.diag(inertia))
        if np.abs(off).max() > 1e-12 * np.trace(inertia):
            moments, axes = np.linalg.eigh(inertia)
            if np.linalg.det(axes) < 0:
                axes[:, 2] *= -1.0
            rotation = axes.T
        else:
            rotation = np.eye(3)
        self.name = name
        self.input_centroid = centroid
        self.rotation = rotation
        self.vertices = centred @ rotation.T
        self.faces = faces
        self.face_normals = normals @ rotation.T
        self.face_offsets = offsets - normals @ centroid
        self.edges = self._edges(faces)
        self._volume = volume
        self._moments = np.diag(rotation @ inertia @ rotation.T).copy()

    @staticmethod
    def _merge_faces(pts, hull, tol):
        """Group coplanar hull triangles into polygons ordered counter-clockwise from outside."""
        eq = hull.equations  # (T, 4): n . x + c = 0, n outward unit
        groups: list[list[int]] = []
        for t, e in enumerate(eq):
            for g in groups:
                ref = eq[g[0]]
                if ref[:3] @ e[:3] > 1.0 - 1e-9 and abs(ref[3] - e[3]) < tol:
                    g.append(t)
                    break
            else:
                groups.append([t])
        faces, normals, offsets = [], [], []
        for g in groups:
            normal = eq[g].mean(axis=0)[:3]
            normal /= _length(normal)
            idx = np.unique(hull.simplices[g].ravel())
            centre = pts[idx].mean(axis=0)
            e1 = pts[idx[0]] - centre
            e1 /= _length(e1)
            e2 = np.cross(normal, e1)
            rel = pts[idx] - centre
            order = np.argsort(np.arctan2(rel @ e2, rel @ e1))
            faces.append(idx[order].astype(np.int64))
            normals.append(normal)
            offsets.append(float(np.mean(pts[idx] @ normal)))
        return faces, np.array(normals), np.array(offsets)

    @staticmethod
    def _edges(faces) -> np.ndarray:
        pairs = {tuple(sorted((int(f[k]), int(f[(k + 1) % len(f)])))) for f in faces for k in range(len(f))}
        return np.array(sorted(pairs), dtype=np.int64)

    @property
    def volume(self) -> float:
        return self._volume

    @property
    def principal_moments(self) -> np.ndarray:
        return self._moments.copy()

    @property
    def surface_area(self) -> float:
        """Area of the surface, d^2: the sum over faces of :math:`\\tfrac12 |\\sum_k (v_k - v_0) \\times
        (v_{k+1} - v_0)|` (each face a convex polygon, its vertices in order round it)."""
        v = self.vertices
        return float(sum(0.5 * _length(np.cross(v[f[1:-1]] - v[f[0]], v[f[2:]] - v[f[0]]).sum(axis=0))
                         for f in self.faces))

    @property
    def circumscribed_radius(self) -> float:
        """Largest vertex distance from the centroid, d (the minimal ball for centrally symmetric bodies)."""
        return float(np.linalg.norm(self.vertices, axis=1).max())

    @property
    def is_centrally_symmetric(self) -> bool:
        """True if ``-v`` is a vertex for every vertex ``v``."""
        v = self.vertices
        tol = 1e-9 * self.size
        return bool(all(np.min(np.linalg.norm(v + p, axis=1)) < tol for p in v))

    @cached_property
    def face_axes(self) -> np.ndarray:
        """``(A, 3)`` distinct face-normal directions up to sign (separating-axis candidates)."""
        return _unique_directions(self.face_normals)

    @cached_property
    def edge_directions(self) -> np.ndarray:
        """``(D, 3)`` distinct unit edge directions up to sign (for edge x edge axes)."""
        v = self.vertices
        return _unique_directions(v[self.edges[:, 1]] - v[self.edges[:, 0]])

    @cached_property
    def edge_faces(self) -> np.ndarray:
        """``(E, 2)`` the indices of the two faces meeting at each edge (rows of ``edges``), the
        face on whose boundary the edge runs from ``edges[e, 0]`` to ``edges[e, 1]``
        counter-clockwise first: the edge's arc on the Gauss map joins their normals."""
        row = {(int(a), int(b)): e for e, (a, b) in enumerate(self.edges)}
        out = np.empty((len(self.edges), 2), dtype=np.int64)
        for f, face in enumerate(self.faces):
            for k in range(len(face)):
                a, b = int(face[k]), int(face[(k + 1) % len(face)])
                out[row[(min(a, b), max(a, b))], 0 if a < b else 1] = f
        return out

    def face_kinds(self) -> list[int]:
        """Number of vertices of each face."""
        return [len(f) for f in self.faces]

    def gsd_shape(self) -> dict:
        return {"type": "ConvexPolyhedron", "rounding_radius": 0.0, "vertices": self.vertices.tolist()}

    def scaled(self, factor: float) -> "ConvexPolyhedron":
        """The same body ``factor`` times larger, in the same body frame: vertices, offsets and the
        centroid scale by ``factor``, the volume by its cube, the moments by its fifth power (the
        hull is not computed again, so a grading's thousands of grains cost little)."""
        factor = float(factor)
        if not factor > 0:
            raise ShapeError(f"scale factor must be > 0, got {factor}")
        self.face_axes, self.edge_directions  # noqa: B018 (computed once, shared by the copies: they do not scale)
        out = copy.copy(self)
        out.vertices = self.vertices * factor
        out.face_offsets = self.face_offsets * factor
        out.input_centroid = self.input_centroid * factor
        out._volume = self._volume * factor ** 3
        out._moments = self._moments * factor ** 5
        base, times = self.scale_of if self.scale_of is not None else (self, 1.0)
        out.scale_of = (base, times * factor)
        return out

    def __repr__(self) -> str:
        return (
            f"ConvexPolyhedron(name={self.name!r}, vertices={len(self.vertices)}, faces={len(self.faces)}, "
            f"edges={len(self.edges)}, size={self.size:.6g})"
        )

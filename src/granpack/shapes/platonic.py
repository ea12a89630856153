"""The five Platonic solids, scaled to a circumscribed diameter ``size`` (in d)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from granpack.shapes.base import ShapeError
from granpack.shapes.polyhedron import ConvexPolyhedron

__all__ = ["platonic", "PLATONIC_SOLIDS"]

_PHI = (1.0 + math.sqrt(5.0)) / 2.0


def _tetrahedron():
    return np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)


def _cube():
    return np.array(list(itertools.product([-1.0, 1.0], repeat=3)))


def _octahedron():
    return np.vstack([np.eye(3), -np.eye(3)])


def _icosahedron():
    pts = []
    for s1, s2 in itertools.product([-1.0, 1.0], repeat=2):
        pts += [[0, s1, s2 * _PHI], [s1, s2 * _PHI, 0], [s2 * _PHI, 0, s1]]
    return np.array(pts)


def _dodecahedron():
    pts = [list(p) for p in itertools.product([-1.0, 1.0], repeat=3)]
    for s1, s2 in itertools.product([-1.0, 1.0], repeat=2):
        pts += [[0, s1 / _PHI, s2 * _PHI], [s1 / _PHI, s2 * _PHI, 0], [s2 * _PHI, 0, s1 / _PHI]]
    return np.array(pts)


PLATONIC_SOLIDS = {
    "tetrahedron": _tetrahedron,
    "cube": _cube,
    "octahedron": _octahedron,
    "dodecahedron": _dodecahedron,
    "icosahedron": _icosahedron,
}


def platonic(name: str, size: float = 1.0) -> ConvexPolyhedron:
    """A Platonic solid of circumscribed diameter ``size``.

    Args:
        name: one of ``tetrahedron``, ``cube``, ``octahedron``, ``dodecahedron``, ``icosahedron``.
        size: circumscribed diameter, d.
    """
    if name not in PLATONIC_SOLIDS:
        raise ShapeError(f"unknown Platonic solid {name!r}; allowed: {', '.join(PLATONIC_SOLIDS)}")
    if not size > 0:
        raise ShapeError(f"size must be > 0, got {size}")
    v = PLATONIC_SOLIDS[name]()
    v = v * (0.5 * size / np.linalg.norm(v, axis=1).max())
    return ConvexPolyhedron(v, name=name)

"""Particle shapes: spheres, convex polyhedra, pinacoids, Platonic solids, and kernel tables."""

from __future__ import annotations

from granpack.shapes.base import Shape, ShapeError
from granpack.shapes.pinacoid import PINACOID_FAMILIES, Pinacoid
from granpack.shapes.platonic import PLATONIC_SOLIDS, platonic
from granpack.shapes.polyhedron import ConvexPolyhedron, mass_properties
from granpack.shapes.sphere import Sphere
from granpack.shapes.table import ShapeTable

__all__ = [
    "Shape",
    "ShapeError",
    "Sphere",
    "ConvexPolyhedron",
    "Pinacoid",
    "PINACOID_FAMILIES",
    "platonic",
    "PLATONIC_SOLIDS",
    "mass_properties",
    "ShapeTable",
    "polyhedron_of_size",
]


def polyhedron_of_size(vertices, size: float, name: str = "polyhedron") -> ConvexPolyhedron:
    """A user polyhedron from ``vertices`` scaled so its circumscribed diameter equals ``size`` (d)."""
    if not size > 0:
        raise ShapeError(f"size must be > 0, got {size}")
    body = ConvexPolyhedron(vertices, name=name)
    return body.scaled(size / body.size)

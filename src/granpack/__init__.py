"""granpack: dense random packings of rigid grains by pluviation and Non-Smooth Contact Dynamics.

Units (owned here, used everywhere): lengths in d (the largest grain's circumscribed diameter),
gravity g = 1, mass density 1, time in sqrt(d/g).
"""

from __future__ import annotations

from granpack.box import Box
from granpack.shapes import ConvexPolyhedron, Pinacoid, ShapeTable, Sphere, platonic

__version__ = "0.1.0"

__all__ = ["Box", "ConvexPolyhedron", "Pinacoid", "ShapeTable", "Sphere", "platonic", "__version__"]

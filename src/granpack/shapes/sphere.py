"""Spheres."""

from __future__ import annotations

import math

import numpy as np

from granpack.shapes.base import Shape, ShapeError

__all__ = ["Sphere"]


class Sphere(Shape):
    """A sphere of diameter ``diameter`` (in d).

    .. math:: V = \\pi D^3 / 6, \\qquad J = m D^2 / 10
    """

    kind = "sphere"

    def __init__(self, diameter: float):
        diameter = float(diameter)
        if not diameter > 0 or not math.isfinite(diameter):
            raise ShapeError(f"sphere diameter must be a finite number > 0, got {diameter}")
        self.diameter = diameter

    @property
    def radius(self) -> float:
        """Radius, d."""
        return 0.5 * self.diameter

    @property
    def volume(self) -> float:
        return math.pi * self.diameter**3 / 6.0

    @property
    def principal_moments(self) -> np.ndarray:
        return np.full(3, self.mass * self.diameter**2 / 10.0)

    @property
    def surface_area(self) -> float:
        """:math:`\\pi d^2`, d^2."""
        return math.pi * self.diameter ** 2

    @property
    def circumscribed_radius(self) -> float:
        return self.radius

    def gsd_shape(self) -> dict:
        return {"type": "Sphere", "diameter": self.diameter}

    def scaled(self, factor: float) -> "Sphere":
        out = Sphere(self.diameter * factor)
        base, times = self.scale_of if self.scale_of is not None else (self, 1.0)
        out.scale_of = (base, times * factor)
        return out

    def __repr__(self) -> str:
        return f"Sphere(diameter={self.diameter:g})"

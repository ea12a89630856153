"""Common interface of particle shapes.

Convention (owned here): a shape is stored in its **body frame**: centre of mass at the origin
and principal axes of inertia along x, y, z. Mass properties are for unit mass density
(so ``mass == volume``). ``size`` is the circumscribed diameter (the sphere diameter, or
``sqrt(L^2 + G^2)`` for a pinacoid), in units of d.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

__all__ = ["Shape", "ShapeError"]


class ShapeError(ValueError):
    """A shape cannot be built from the given parameters (degenerate, non-convex, ...)."""


class Shape(ABC):
    """A rigid grain shape in its body frame (unit density)."""

    #: short kind name: ``"sphere"`` or ``"polyhedron"``
    kind: str = ""
    #: ``(shape, factor)`` when this one is ``shape.scaled(factor)`` (a graded grain), else None
    scale_of: "tuple[Shape, float] | None" = None

    @property
    @abstractmethod
    def volume(self) -> float:
        """Volume, d^3."""

    @property
    @abstractmethod
    def principal_moments(self) -> np.ndarray:
        """Principal moments of inertia ``(J1, J2, J3)`` for unit density, d^5, about body x, y, z."""

    @property
    @abstractmethod
    def circumscribed_radius(self) -> float:
        """Radius of the smallest centred ball containing the shape, d."""

    @property
    def mass(self) -> float:
        """Mass for unit density (equals the volume), d^3."""
        return self.volume

    @property
    def size(self) -> float:
        """Circumscribed diameter, d."""
        return 2.0 * self.circumscribed_radius

    @property
    def inertia_tensor(self) -> np.ndarray:
        """Inertia tensor about the centre of mass in the body frame (diagonal), d^5."""
        return np.diag(self.principal_moments)

    @abstractmethod
    def gsd_shape(self) -> dict:
        """The GSD ``particles/type_shapes`` entry (OVITO draws the true shape from it)."""

    @abstractmethod
    def scaled(self, factor: float) -> "Shape":
        """The same shape with every length multiplied by ``factor``."""

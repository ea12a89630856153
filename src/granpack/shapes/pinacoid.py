"""The pinacoid: the eight-face "double hip roof" grain of crushed-aggregate models.

Body frame (docs/method/grains.md#the-pinacoid): x along the length L, y along the width G, z along the thickness E.
The mid-plane z = 0 holds an L x G rectangle; each half is a hip roof whose ridge (length l,
parallel to x) sits at z = +-E/2. The triangular end faces make the angle alpha with the
mid-plane, which fixes

.. math:: l = L - E / \\tan\\alpha, \\qquad V = \\frac{EG}{6}(2L + l),

and the circumscribed diameter is the rectangle diagonal :math:`d = \\sqrt{L^2 + G^2}`.
Shape ratios: elongation L/G >= 1, flatness G/E >= 1.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.shapes.base import ShapeError
from granpack.shapes.polyhedron import ConvexPolyhedron

__all__ = ["Pinacoid", "PINACOID_FAMILIES"]

#: the study's four families: name -> (elongation L/G, flatness G/E)
PINACOID_FAMILIES: dict[str, tuple[float, float]] = {
    "isometric": (1.0, 1.0),
    "elongated": (2.0, 1.0),
    "flat": (1.0, 3.0),
    "flat_elongated": (2.0, 3.0),
}


class Pinacoid(ConvexPolyhedron):
    """A pinacoid of length ``length`` (L), width ``width`` (G), thickness ``thickness`` (E), in d.

    Args:
        length: L, along body x.
        width: G, along body y; ``L >= G``.
        thickness: E, along body z; ``G >= E > 0``.
        alpha_deg: dihedral angle of the triangular end faces with the mid-plane, degrees.

    Raises:
        ShapeError: if the dimensions are not ``L >= G >= E > 0`` or the ridge length
            ``l = L - E / tan(alpha)`` is not positive.
    """

    def __init__(self, length: float, width: float, thickness: float, alpha_deg: float = 60.0, name: str = "pinacoid"):
        L, G, E = float(length), float(width), float(thickness)
        if not (math.isfinite(L) and math.isfinite(G) and math.isfinite(E) and E > 0):
            raise ShapeError(f"pinacoid dimensions must be finite and > 0, got L={L}, G={G}, E={E}")
        if not (L >= G * (1 - 1e-12) and G >= E * (1 - 1e-12)):
            raise ShapeError(f"pinacoid needs L >= G >= E (aspect ratios >= 1), got L={L}, G={G}, E={E}")
        if not 0.0 < alpha_deg < 90.0:
            raise ShapeError(f"pinacoid alpha must be in (0, 90) degrees, got {alpha_deg}")
        ridge = L - E / math.tan(math.radians(alpha_deg))
        if ridge <= 0:
            raise ShapeError(f"pinacoid ridge length l = L - E/tan(alpha) = {ridge:.4g} must be > 0")
        self.length, self.width, self.thickness, self.ridge, self.alpha_deg = L, G, E, ridge, float(alpha_deg)
        verts = np.array(
            [
                [L / 2, G / 2, 0.0],
                [-L / 2, G / 2, 0.0],
                [-L / 2, -G / 2, 0.0],
                [L / 2, -G / 2, 0.0],
                [ridge / 2, 0.0, E / 2],
                [-ridge / 2, 0.0, E / 2],
                [ridge / 2, 0.0, -E / 2],
                [-ridge / 2, 0.0, -E / 2],
            ]
        )
        super().__init__(verts, name=name)

    @classmethod
    def from_size(cls, size: float, elongation: float = 1.0, flatness: float = 1.0, alpha_deg: float = 60.0, name: str = "pinacoid") -> "Pinacoid":
        """Pinacoid of circumscribed diameter ``size = sqrt(L^2 + G^2)`` and ratios L/G, G/E.

        .. math:: G = d / \\sqrt{(L/G)^2 + 1}, \\quad L = (L/G)\\, G, \\quad E = G / (G/E)
        """
        size, elongation, flatness = float(size), float(elongation), float(flatness)
        if not size > 0:
            raise ShapeError(f"pinacoid size must be > 0, got {size}")
        if not (elongation >= 1.0 and flatness >= 1.0):
            raise ShapeError(f"pinacoid aspect [L/G, G/E] must both be >= 1, got [{elongation}, {flatness}]")
        width = size / math.sqrt(elongation**2 + 1.0)
        return cls(elongation * width, width, width / flatness, alpha_deg=alpha_deg, name=name)

    @classmethod
    def family(cls, name: str, size: float = 1.0) -> "Pinacoid":
        """One of the study's families (:data:`PINACOID_FAMILIES`) at circumscribed diameter ``size``."""
        if name not in PINACOID_FAMILIES:
            raise ShapeError(f"unknown pinacoid family {name!r}; allowed: {', '.join(PINACOID_FAMILIES)}")
        elongation, flatness = PINACOID_FAMILIES[name]
        return cls.from_size(size, elongation, flatness, name=name)

    @property
    def elongation(self) -> float:
        """L/G."""
        return self.length / self.width

    @property
    def flatness(self) -> float:
        """G/E."""
        return self.width / self.thickness

    def scaled(self, factor: float) -> "Pinacoid":
        out = super().scaled(factor)
        out.length, out.width, out.thickness, out.ridge = (self.length * factor, self.width * factor,
                                                          self.thickness * factor, self.ridge * factor)
        return out

    def __repr__(self) -> str:
        return (
            f"Pinacoid(L={self.length:.6g}, G={self.width:.6g}, E={self.thickness:.6g}, "
            f"alpha={self.alpha_deg:g}, size={self.size:.6g})"
        )

"""The simulation cell and its container.

Convention (owned here): the cell has a rigid flat bottom wall at z = 0 with normal +z and an
open top; lengths are in d (the largest grain size). Its sides are one of three containers
(``Box.container``):

- ``"periodic"`` (the default): periodic in x and y with periods ``lx`` and ``ly`` (both equal to
  ``lateral_size`` for the square cells of the config). Wrapped centres lie in
  ``[0, lx) x [0, ly)``; a periodic image of body j is ``x_j + shift`` with
  ``shift = (kx lx, ky ly, 0)``, ``kx, ky`` in {-1, 0, 1}.
- ``"box"``: four rigid vertical walls, the planes x = 0, x = lx, y = 0 and y = ly (inside side
  ``lx`` by ``ly``); nothing is periodic, centres are never wrapped and every shift is zero.
- ``"cylinder"``: a rigid vertical cylinder of axis ``(lx/2, ly/2)`` and inside radius ``lx/2``
  (``lx = ly``, the inside diameter); nothing is periodic.

Each wall has an id, the negative antagonist of a contact manifold
(:mod:`granpack.contact.contacts`): -1 the floor, -2 to -5 the box's walls x = 0, x = lx, y = 0,
y = ly, -6 the cylinder.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Box", "CONTAINERS"]

#: the container shapes, in the order of their kernel codes (``Box.code``)
CONTAINERS = ("periodic", "box", "cylinder")


@dataclass(frozen=True)
class Box:
    """The cell: floor z = 0, sides periodic or a container.

    Attributes:
        lx: period (or inside side, or the cylinder's inside diameter) along x, in d.
        ly: the same along y, in d.
        container: ``"periodic"``, ``"box"`` or ``"cylinder"`` (module docstring).
    """

    lx: float
    ly: float
    container: str = "periodic"

    def __post_init__(self):
        if not (self.lx > 0 and self.ly > 0):
            raise ValueError(f"box periods must be > 0, got lx={self.lx}, ly={self.ly}")
        if self.container not in CONTAINERS:
            raise ValueError(f"box container must be one of {', '.join(CONTAINERS)}, got {self.container!r}")
        if self.container == "cylinder" and self.lx != self.ly:
            raise ValueError(f"a cylinder needs lx = ly (its diameter), got lx={self.lx}, ly={self.ly}")

    @classmethod
    def square(cls, lateral_size: float, container: str = "periodic") -> "Box":
        """Square cell of side ``lateral_size`` (in d) with the given sides."""
        return cls(float(lateral_size), float(lateral_size), container)

    @property
    def periodic(self) -> bool:
        """Whether x and y are periodic (else a box or a cylinder holds the grains)."""
        return self.container == "periodic"

    @property
    def code(self) -> int:
        """Kernel code of the container: 0 periodic, 1 box, 2 cylinder."""
        return CONTAINERS.index(self.container)

    @property
    def area(self) -> float:
        """Horizontal area inside the sides in d^2: ``lx * ly``, or ``pi lx^2 / 4`` for a cylinder."""
        if self.container == "cylinder":
            return 0.25 * math.pi * self.lx * self.lx
        return self.lx * self.ly

    @property
    def periods(self) -> np.ndarray:
        """``(lx, ly, 0)``: the periods as a 3-vector (0 means not periodic; all 0 for a container)."""
        return np.array([self.lx, self.ly, 0.0]) if self.periodic else np.zeros(3)

    @property
    def depth(self) -> float:
        """The largest distance from the side walls inside a container, d: the cylinder's radius,
        half the box's shorter side (``inf`` for a periodic cell, which has no side walls)."""
        if self.periodic:
            return math.inf
        return 0.5 * min(self.lx, self.ly)

    def wall_distance(self, xy: np.ndarray) -> np.ndarray:
        """``(n,)`` distance from the nearest side wall of the points ``xy`` ``(n, 2)`` (or ``(n, 3)``,
        z ignored), d: ``lx/2 - |xy - axis|`` in a cylinder, the distance to the nearest of the four
        planes in a box, negative outside; ``inf`` in a periodic cell."""
        xy = np.asarray(xy, dtype=np.float64)[..., :2]
        if self.container == "cylinder":
            return 0.5 * self.lx - np.hypot(xy[..., 0] - 0.5 * self.lx, xy[..., 1] - 0.5 * self.ly)
        if self.container == "box":
            x, y = xy[..., 0], xy[..., 1]
            return np.minimum(np.minimum(x, self.lx - x), np.minimum(y, self.ly - y))
        return np.full(xy.shape[:-1], math.inf)

    def to_dict(self) -> dict:
        """The container as summary.json and the GSD file record it: ``shape`` and its inside size,
        d (``lateral_size`` of a periodic cell or a box, ``diameter`` of a cylinder, and for a
        cylinder its ``axis`` (x, y))."""
        if self.container == "cylinder":
            return {"shape": "cylinder", "diameter": self.lx, "axis": [0.5 * self.lx, 0.5 * self.ly]}
        return {"shape": self.container, "lateral_size": [self.lx, self.ly]}

    def wrap(self, positions: np.ndarray) -> np.ndarray:
        """Positions ``(N, 3)`` with x, y wrapped into ``[0, lx) x [0, ly)`` (new array); a copy
        unchanged for a container."""
        out = np.array(positions, dtype=np.float64, copy=True)
        if not self.periodic:
            return out
        out[..., 0] = np.mod(out[..., 0], self.lx)
        out[..., 1] = np.mod(out[..., 1], self.ly)
        # np.mod can return exactly lx for tiny negative inputs
        out[..., 0][out[..., 0] >= self.lx] = 0.0
        out[..., 1][out[..., 1] >= self.ly] = 0.0
        return out

    def minimum_image(self, delta: np.ndarray) -> np.ndarray:
        """Separation vectors ``(..., 3)`` reduced to the nearest periodic image in x, y (a copy
        unchanged for a container)."""
        out = np.array(delta, dtype=np.float64, copy=True)
        if not self.periodic:
            return out
        out[..., 0] -= self.lx * np.round(out[..., 0] / self.lx)
        out[..., 1] -= self.ly * np.round(out[..., 1] / self.ly)
        return out

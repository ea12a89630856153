"""The simulation cell.

Convention (owned here): the cell is periodic in x and y with periods ``lx`` and ``ly`` (both
equal to ``lateral_size`` for the square cells of the config), has a rigid flat bottom wall at
z = 0 with normal +z, and an open top. Lengths are in units of d (the largest grain size).
Wrapped centres lie in ``[0, lx) x [0, ly)``; a periodic image of body j is ``x_j + shift`` with
``shift = (kx lx, ky ly, 0)``, ``kx, ky`` in {-1, 0, 1}.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Box"]


@dataclass(frozen=True)
class Box:
    """Bi-periodic cell with a bottom wall.

    Attributes:
        lx: period along x, in d.
        ly: period along y, in d.
    """

    lx: float
    ly: float

    def __post_init__(self):
        if not (self.lx > 0 and self.ly > 0):
            raise ValueError(f"box periods must be > 0, got lx={self.lx}, ly={self.ly}")

    @classmethod
    def square(cls, lateral_size: float) -> "Box":
        """Square cell of side ``lateral_size`` (in d)."""
        return cls(float(lateral_size), float(lateral_size))

    @property
    def area(self) -> float:
        """Horizontal area ``lx * ly`` in d^2."""
        return self.lx * self.ly

    @property
    def periods(self) -> np.ndarray:
        """``(lx, ly, 0)``: the periods as a 3-vector (0 means not periodic)."""
        return np.array([self.lx, self.ly, 0.0])

    def wrap(self, positions: np.ndarray) -> np.ndarray:
        """Positions ``(N, 3)`` with x, y wrapped into ``[0, lx) x [0, ly)`` (new array)."""
        out = np.array(positions, dtype=np.float64, copy=True)
        out[..., 0] = np.mod(out[..., 0], self.lx)
        out[..., 1] = np.mod(out[..., 1], self.ly)
        # np.mod can return exactly lx for tiny negative inputs
        out[..., 0][out[..., 0] >= self.lx] = 0.0
        out[..., 1][out[..., 1] >= self.ly] = 0.0
        return out

    def minimum_image(self, delta: np.ndarray) -> np.ndarray:
        """Separation vectors ``(..., 3)`` reduced to the nearest periodic image in x, y."""
        out = np.array(delta, dtype=np.float64, copy=True)
        out[..., 0] -= self.lx * np.round(out[..., 0] / self.lx)
        out[..., 1] -= self.ly * np.round(out[..., 1] / self.ly)
        return out

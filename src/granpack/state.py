"""Particle state as structures of arrays.

Convention (owned here): ``omega`` is the angular velocity in the **body** (principal) frame, as
in LMGC90; ``velocity`` is the translational velocity of the centre of mass in the world frame.
Quaternions are ``(w, x, y, z)`` (see :mod:`granpack.rotations`). ``kind[p]`` indexes the
:class:`~granpack.shapes.ShapeTable`; ``population[p]`` indexes the config's populations.
Positions are wrapped into the periodic cell in x, y (see :mod:`granpack.box`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from granpack.box import Box
from granpack.shapes import ShapeTable

__all__ = ["ParticleState"]


@dataclass
class ParticleState:
    """Positions, orientations and velocities of ``N`` rigid grains, plus their shape table.

    Attributes:
        box: the periodic cell.
        shapes: geometry of the particle kinds.
        kind: ``(N,)`` int64 index into ``shapes``.
        population: ``(N,)`` int64 population index (config order).
        position: ``(N, 3)`` centre of mass, d.
        quaternion: ``(N, 4)`` unit quaternions ``(w, x, y, z)``, body -> world.
        velocity: ``(N, 3)`` world-frame velocity, sqrt(g d).
        omega: ``(N, 3)`` body-frame angular velocity, sqrt(g/d).
        time: simulated time, sqrt(d/g).
    """

    box: Box
    shapes: ShapeTable
    kind: np.ndarray
    population: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray = field(default=None)  # type: ignore[assignment]
    omega: np.ndarray = field(default=None)  # type: ignore[assignment]
    time: float = 0.0

    def __post_init__(self):
        n = len(self.kind)
        self.kind = np.ascontiguousarray(self.kind, dtype=np.int64)
        self.population = np.ascontiguousarray(self.population, dtype=np.int64)
        self.position = np.ascontiguousarray(self.position, dtype=np.float64).reshape(n, 3)
        self.quaternion = np.ascontiguousarray(self.quaternion, dtype=np.float64).reshape(n, 4)
        self.velocity = np.zeros((n, 3)) if self.velocity is None else np.ascontiguousarray(self.velocity, dtype=np.float64)
        self.omega = np.zeros((n, 3)) if self.omega is None else np.ascontiguousarray(self.omega, dtype=np.float64)
        if len(self.population) != n:
            raise ValueError("population must have one entry per particle")

    @property
    def n(self) -> int:
        """Number of particles."""
        return len(self.kind)

    @property
    def mass(self) -> np.ndarray:
        """``(N,)`` masses (unit density), d^3."""
        return self.shapes.volume[self.kind]

    @property
    def inertia(self) -> np.ndarray:
        """``(N, 3)`` principal moments (unit density), d^5."""
        return self.shapes.inertia[self.kind]

    @property
    def radius(self) -> np.ndarray:
        """``(N,)`` circumscribed radii, d."""
        return self.shapes.radius[self.kind]

    def copy(self) -> "ParticleState":
        """A deep copy of the arrays (the box and shape table are shared, they are immutable)."""
        return ParticleState(
            box=self.box,
            shapes=self.shapes,
            kind=self.kind.copy(),
            population=self.population.copy(),
            position=self.position.copy(),
            quaternion=self.quaternion.copy(),
            velocity=self.velocity.copy(),
            omega=self.omega.copy(),
            time=self.time,
        )

"""Contact manifolds as flat arrays (the output of detection, the input of the solver).

Conventions (owned here):

- A manifold couples a **candidate** body ``i`` and an **antagonist** ``j`` (``j = -1`` is the
  bottom wall). The antagonist is used through its periodic image ``x_j + shift``.
- The unit ``normal`` points **from j towards i** (i moves along +normal to separate); for the
  wall it is +z.
- Each manifold has one or more points (rows ``point_start[m]:point_start[m+1]``), each with a
  world position (the midpoint between the two surfaces) and its own ``gap`` (> 0 open,
  < 0 interpenetration), in d.
- ``ctype``: 1 = simple (vertex-face, edge-edge, any single point), 2 = double (edge-face),
  3 = triple (face-face), decided by the rank of the manifold (PHYSICS.md §3.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ContactSet", "SIMPLE", "DOUBLE", "TRIPLE", "WALL"]

SIMPLE, DOUBLE, TRIPLE = 1, 2, 3
WALL = -1


@dataclass
class ContactSet:
    """``M`` contact manifolds with ``P`` points in total.

    Attributes:
        body_i: ``(M,)`` int64 candidate body.
        body_j: ``(M,)`` int64 antagonist body, ``-1`` for the wall.
        shift: ``(M, 3)`` periodic image shift added to ``x_j``, d.
        normal: ``(M, 3)`` unit normal from j towards i.
        ctype: ``(M,)`` int64 contact type 1/2/3.
        point_start: ``(M+1,)`` int64 CSR offsets into the point arrays.
        point: ``(P, 3)`` contact points (world), d.
        gap: ``(P,)`` signed gaps, d.
        impulse: ``(P, 3)`` world impulse on body i over the last step (set by the solver;
            ``None`` before solving); the force is ``impulse / time_step``.
    """

    body_i: np.ndarray
    body_j: np.ndarray
    shift: np.ndarray
    normal: np.ndarray
    ctype: np.ndarray
    point_start: np.ndarray
    point: np.ndarray
    gap: np.ndarray
    impulse: np.ndarray | None = None

    @classmethod
    def empty(cls) -> "ContactSet":
        return cls(
            body_i=np.zeros(0, np.int64),
            body_j=np.zeros(0, np.int64),
            shift=np.zeros((0, 3)),
            normal=np.zeros((0, 3)),
            ctype=np.zeros(0, np.int64),
            point_start=np.zeros(1, np.int64),
            point=np.zeros((0, 3)),
            gap=np.zeros(0),
            impulse=np.zeros((0, 3)),
        )

    @property
    def n_manifolds(self) -> int:
        return len(self.body_i)

    @property
    def n_points(self) -> int:
        return len(self.gap)

    @property
    def point_manifold(self) -> np.ndarray:
        """``(P,)`` manifold index of every point."""
        return np.repeat(np.arange(self.n_manifolds), np.diff(self.point_start))

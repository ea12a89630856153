"""Contact manifolds as flat arrays (the output of detection, the input of the solver).

Conventions (owned here):

- A manifold couples a **candidate** body ``i`` and an **antagonist** ``j``: a grain ``j >= 0``,
  used through its periodic image ``x_j + shift``, or a wall ``j < 0`` (:data:`WALL_IDS`, the
  container's of :mod:`granpack.box`): -1 the floor z = 0 (:data:`WALL`), -2 to -5 the box's walls
  x = 0, x = L, y = 0, y = L, -6 the cylinder. A grain has at most one manifold per other grain
  and per plane wall; against the cylinder a polyhedron has one manifold per vertex within the
  alert distance, each with its own (radial) normal.
- The unit ``normal`` points **from j towards i** (i moves along +normal to separate); for the
  floor it is +z, for a side wall its inward normal, for the cylinder the inward radial
  direction at the point.
- Each manifold has one or more points (rows ``point_start[m]:point_start[m+1]``), each with a
  world position (the midpoint between the two surfaces) and its own ``gap`` (> 0 open,
  < 0 interpenetration), in d.
- ``ctype``: 1 = simple (vertex-face, edge-edge, any single point), 2 = double (edge-face),
  3 = triple (face-face), decided by the rank of the manifold (docs/method/contact-detection.md#contact-types).
  This is the geometric (detection) type, from every point within the alert distance; the
  analysis of a static packing types a contact by the rank of its force-bearing points instead
  (:mod:`granpack.analysis.coordination`), since nearly parallel faces touching along one edge
  have every point within the alert distance but carry force on the edge only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from granpack._numba import jit

__all__ = ["ContactSet", "SIMPLE", "DOUBLE", "TRIPLE", "WALL", "WALL_IDS", "WALL_CYLINDER", "contact_types",
           "manifold_type_nb"]

SIMPLE, DOUBLE, TRIPLE = 1, 2, 3
#: the floor z = 0, antagonist of the grains that rest on it
WALL = -1
#: the box's walls x = 0, x = L, y = 0, y = L (``Box.container == "box"``)
WALL_X_LO, WALL_X_HI, WALL_Y_LO, WALL_Y_HI = -2, -3, -4, -5
#: the cylinder's wall (``Box.container == "cylinder"``)
WALL_CYLINDER = -6
#: every wall id and its name (outputs, analysis)
WALL_IDS = {WALL: "floor", WALL_X_LO: "x = 0", WALL_X_HI: "x = L", WALL_Y_LO: "y = 0", WALL_Y_HI: "y = L",
            WALL_CYLINDER: "cylinder"}


@dataclass
class ContactSet:
    """``M`` contact manifolds with ``P`` points in total.

    Attributes:
        body_i: ``(M,)`` int64 candidate body.
        body_j: ``(M,)`` int64 antagonist body, or the wall's id (< 0, module docstring).
        shift: ``(M, 3)`` periodic image shift added to ``x_j``, d.
        normal: ``(M, 3)`` unit normal from j towards i.
        ctype: ``(M,)`` int64 geometric contact type 1/2/3 (rank of all the points).
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


@jit
def manifold_type_nb(points, count, nx, ny, nz, eps):
    """Numba: contact type of one manifold from the rank of its points (see :func:`contact_types`).

    The points ``points[:count]`` are projected on a tangent basis ``(t, s)`` of the normal ``n``
    and centred; with :math:`\\sigma_1 \\ge \\sigma_2` the singular values of the ``2 x K``
    matrix of in-plane coordinates, the type is 1 (simple) if :math:`\\sigma_1 < \\epsilon`,
    2 (double) if :math:`\\sigma_2 < \\epsilon`, else 3 (triple).

    Args:
        points: ``(>= count, 3)`` point coordinates (any origin), d.
        count: number of points.
        nx, ny, nz: unit normal.
        eps: tolerance :math:`\\epsilon_f`, d.
    """
    if count < 2:
        return SIMPLE
    # tangent basis (any orthonormal pair is fine: singular values are rotation invariant)
    if abs(nx) <= abs(ny) and abs(nx) <= abs(nz):
        tx, ty, tz = 0.0, nz, -ny
    elif abs(ny) <= abs(nz):
        tx, ty, tz = -nz, 0.0, nx
    else:
        tx, ty, tz = ny, -nx, 0.0
    tn = math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / tn, ty / tn, tz / tn
    sx, sy, sz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
    mu = 0.0
    mw = 0.0
    for k in range(count):
        mu += points[k, 0] * tx + points[k, 1] * ty + points[k, 2] * tz
        mw += points[k, 0] * sx + points[k, 1] * sy + points[k, 2] * sz
    mu /= count
    mw /= count
    cuu = 0.0
    cww = 0.0
    cuw = 0.0
    for k in range(count):
        u = points[k, 0] * tx + points[k, 1] * ty + points[k, 2] * tz - mu
        w = points[k, 0] * sx + points[k, 1] * sy + points[k, 2] * sz - mw
        cuu += u * u
        cww += w * w
        cuw += u * w
    half = 0.5 * (cuu + cww)
    root = math.sqrt(max(0.0, 0.25 * (cuu - cww) ** 2 + cuw * cuw))
    s1 = math.sqrt(max(0.0, half + root))
    s2 = math.sqrt(max(0.0, half - root))
    if s1 < eps:
        return SIMPLE
    if s2 < eps:
        return DOUBLE
    return TRIPLE


@jit
def _types_kernel(point_start, point, normal, mask, eps):
    m = len(point_start) - 1
    out = np.zeros(m, np.int64)
    buf = np.empty((point.shape[0] if point.shape[0] > 0 else 1, 3))
    for c in range(m):
        cnt = 0
        for k in range(point_start[c], point_start[c + 1]):
            if mask[k]:
                buf[cnt, 0], buf[cnt, 1], buf[cnt, 2] = point[k, 0], point[k, 1], point[k, 2]
                cnt += 1
        if cnt > 0:
            out[c] = manifold_type_nb(buf, cnt, normal[c, 0], normal[c, 1], normal[c, 2], eps)
    return out


def contact_types(contacts: ContactSet, eps: float, mask: np.ndarray | None = None) -> np.ndarray:
    """Contact type of every manifold from the rank of a subset of its points.

    Detection already sets ``ctype`` from all the points within the alert distance; analysis uses
    this to re-classify from the points that matter for a static packing, e.g.
    ``mask = contacts.gap <= g_tol`` (geometric) or force-bearing points (mechanical).

    Args:
        contacts: the manifolds.
        eps: rank tolerance :math:`\\epsilon_f`, d (detection default: 1e-3 d_min).
        mask: ``(P,)`` bool, the points to use (default: all).

    Returns:
        ``(M,)`` int64 types 1/2/3, or 0 for a manifold with no selected point.
    """
    if mask is None:
        mask = np.ones(contacts.n_points, dtype=bool)
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    if mask.shape != (contacts.n_points,):
        raise ValueError(f"mask must have one entry per point ({contacts.n_points}), got shape {mask.shape}")
    return _types_kernel(contacts.point_start, contacts.point, contacts.normal, mask, float(eps))

"""Sizes and shape ratios of a grain: the three size definitions and the aspect ratios.

A population's ``size`` (and its grading's sizes) are measured in one of :data:`SIZE_DEFINITIONS`
(method: docs/method/grains.md#sizes-circumscribed-sieve-equivalent-volume):

- ``"circumscribed"``: the diameter of the smallest centred ball holding the grain
  (:attr:`granpack.shapes.Shape.size`), granpack's unit d;
- ``"sieve"``: the side of the smallest square aperture the grain passes through
  (:func:`sieve_size`), what a sieve analysis measures;
- ``"equivalent_volume"``: the diameter of the ball of the same volume, :math:`(6V/\\pi)^{1/3}`.

Every definition is proportional to the grain's scale, so a shape of size ``s`` in one definition
is ``shape.scaled(s / size_of(shape, definition))``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from granpack.shapes.base import Shape
from granpack.shapes.polyhedron import ConvexPolyhedron
from granpack.shapes.sphere import Sphere

__all__ = ["SIZE_DEFINITIONS", "SIEVE_TOLERANCE", "size_of", "sieve_size", "equivalent_volume_size",
           "aspect_ratios", "principal_extents", "sphericity"]

#: the size definitions a population may grade in
SIZE_DEFINITIONS = ("circumscribed", "sieve", "equivalent_volume")

#: relative tolerance the sieve size's local searches stop at (the result is the smallest aperture
#: found, never below the true one: every candidate is an aperture the grain passes through)
SIEVE_TOLERANCE = 1e-12

#: random starting orientations of the sieve size's search, besides the frames of the faces
_SIEVE_STARTS = 64
#: local searches run from the best starting orientations
_SIEVE_REFINED = 8


def size_of(shape: Shape, definition: str) -> float:
    """The size of ``shape`` in ``definition`` (one of :data:`SIZE_DEFINITIONS`), in d."""
    if definition == "circumscribed":
        return shape.size
    if definition == "sieve":
        return sieve_size(shape)
    if definition == "equivalent_volume":
        return equivalent_volume_size(shape)
    raise ValueError(f"unknown size definition {definition!r}; allowed: {', '.join(SIZE_DEFINITIONS)}")


def equivalent_volume_size(shape: Shape) -> float:
    """Diameter of the ball of the same volume, :math:`(6V/\\pi)^{1/3}`, d."""
    return (6.0 * shape.volume / math.pi) ** (1.0 / 3.0)


def _aperture(vertices: np.ndarray, frame: np.ndarray) -> float:
    """Side of the smallest square, with sides along ``frame[:, 0]`` and ``frame[:, 1]``, that holds
    the projection of ``vertices`` along ``frame[:, 2]``: the larger of the two widths."""
    p = vertices @ frame[:, :2]
    w = p.max(axis=0) - p.min(axis=0)
    return float(max(w[0], w[1]))


def _start_frames(vertices: np.ndarray, shape: ConvexPolyhedron) -> list[np.ndarray]:
    """Candidate orientations of the square: the body axes (each as the passing direction, the
    square's sides along the other two or at 45 degrees to them), every face normal as the passing
    direction with the square's sides along each edge of that face, and random orientations."""
    frames = []
    eye = np.eye(3)
    for k in range(3):
        axes = eye[:, [(k + 1) % 3, (k + 2) % 3, k]]
        frames.append(axes)
        c = math.sqrt(0.5)
        turned = axes.copy()
        turned[:, 0], turned[:, 1] = c * (axes[:, 0] + axes[:, 1]), c * (axes[:, 1] - axes[:, 0])
        frames.append(turned)
    for face, normal in zip(shape.faces, shape.face_normals):
        for a, b in zip(face, np.roll(face, -1)):
            edge = vertices[b] - vertices[a]
            edge = edge - (edge @ normal) * normal
            length = float(np.sqrt(edge @ edge))
            if length <= 0:
                continue
            e1 = edge / length
            frames.append(np.column_stack([e1, np.cross(normal, e1), normal]))
    rng = np.random.default_rng(0x53494556)
    frames += list(Rotation.random(_SIEVE_STARTS, random_state=rng).as_matrix())
    return frames


def sieve_size(shape: Shape) -> float:
    """Side of the smallest square aperture the grain passes through, d.

    A convex grain passes a square hole of side ``a`` moving along the hole's normal ``u`` iff its
    projection along ``u`` fits in the square; with the square's sides along ``e1``, ``e2``
    (``e1, e2, u`` orthonormal) the smallest such ``a`` is the larger of the projection's widths

    .. math:: a(e_1, e_2) = \\max\\big(w(e_1), w(e_2)\\big), \\qquad
              w(e) = \\max_v v\\cdot e - \\min_v v\\cdot e

    over the vertices ``v``, and the sieve size is its minimum over orientations of the frame.
    Search: ``a`` at the candidate frames of :func:`_start_frames`, then Nelder-Mead over a rotation
    vector from the best :data:`_SIEVE_REFINED` of them, to :data:`SIEVE_TOLERANCE`. Every value
    tried is an aperture the grain passes, so the result is never below the true size. A sphere's
    is its diameter; a cube's is its edge (an axis frame is a candidate); a box's
    ``a <= b <= c`` is ``min(b, (a + b)/sqrt 2)`` (the square turned 45 degrees about ``c``).
    """
    if isinstance(shape, Sphere):
        return shape.diameter
    if not isinstance(shape, ConvexPolyhedron):
        raise TypeError(f"no sieve size for {shape!r}")
    vertices = shape.vertices
    frames = _start_frames(vertices, shape)
    values = np.array([_aperture(vertices, f) for f in frames])
    best = float(values.min())

    def objective(r: np.ndarray, base: np.ndarray) -> float:
        return _aperture(vertices, Rotation.from_rotvec(r).as_matrix() @ base)

    for k in np.argsort(values, kind="stable")[:_SIEVE_REFINED]:
        base = frames[k]
        result = minimize(objective, np.zeros(3), args=(base,), method="Nelder-Mead",
                          options={"xatol": SIEVE_TOLERANCE, "fatol": SIEVE_TOLERANCE * best,
                                   "initial_simplex": 0.05 * np.vstack([np.zeros(3), np.eye(3)]),
                                   "maxiter": 4000, "maxfev": 8000})
        best = min(best, float(result.fun))
    return best


def principal_extents(shape: Shape) -> np.ndarray:
    """``(L, G, E)``: the grain's extents along its principal axes of inertia, largest first, d
    (a pinacoid's length, width and thickness; a sphere's diameter thrice)."""
    if isinstance(shape, Sphere):
        return np.full(3, shape.diameter)
    v = shape.vertices  # body frame: principal axes along x, y, z
    return np.sort(v.max(axis=0) - v.min(axis=0))[::-1]


def aspect_ratios(shape: Shape) -> tuple[float, float]:
    """``(L/G, G/E)``: elongation and flatness from :func:`principal_extents` (a pinacoid's
    ``aspect``; ``(1, 1)`` for a sphere or a cube)."""
    length, width, thickness = principal_extents(shape)
    return float(length / width), float(width / thickness)


def sphericity(shape: Shape) -> float:
    """Wadell's sphericity, the area of the ball of the same volume over the grain's area,
    :math:`\\psi = \\pi^{1/3} (6V)^{2/3} / A`, in (0, 1]: 1 for a sphere, 0.806 for a cube,
    0.846 for a regular octahedron."""
    return float(math.pi ** (1.0 / 3.0) * (6.0 * shape.volume) ** (2.0 / 3.0) / shape.surface_area)

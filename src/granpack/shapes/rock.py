"""Generated rocks: convex grains cut by ``faces`` planes, with target elongation and flatness.

Method (docs/method/grains.md#generated-rocks): a rock is the intersection of ``F`` half-spaces
tangent to the ellipsoid of semi-axes :math:`(L, G, E)/2`,

.. math:: P = \\bigcap_{i=1}^{F} \\{x : n_i \\cdot x \\le h(n_i)\\}, \\qquad
          h(n) = \\tfrac12 \\sqrt{L^2 n_x^2 + G^2 n_y^2 + E^2 n_z^2},

with normals ``n_i`` spread evenly over the sphere (a Fibonacci lattice of ``F`` points, turned
at random) and each pushed aside by a random tangent step of ``roughness`` times the mean spacing
:math:`\\sqrt{4\\pi/F}` rad. Every plane touches the ellipsoid at a point inside all the other
half-spaces, so every plane bounds a face: the rock has exactly ``F`` faces and, three planes
meeting at each corner, :math:`2F - 4` vertices. The rock is then stretched along its principal
axes of inertia (a stretch along principal axes keeps them principal) so that its extents along
them (:func:`granpack.shapes.sizes.principal_extents`) have exactly the target ratios ``L/G`` and
``G/E``, and scaled to circumscribed diameter 1 d.

Rock ``s`` of a library with seed ``seed`` is drawn from the random stream ``(seed, ROCK_STREAM,
s)`` alone, so a larger library keeps the rocks of a smaller one.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, HalfspaceIntersection
from scipy.spatial.transform import Rotation

from granpack.shapes.base import ShapeError
from granpack.shapes.polyhedron import ConvexPolyhedron

__all__ = ["rock", "rock_library", "ROCK_STREAM", "MIN_FACES", "MAX_FACES", "DEFAULT_FACES", "DEFAULT_SHAPES",
           "DEFAULT_ROUGHNESS"]

#: the random stream of the rocks, apart from the run's
ROCK_STREAM = 0x726F636B
#: fewest faces of a rock (a cut cube has 6; 8 keep every draw a closed body)
MIN_FACES = 8
#: most faces of a rock (2F - 4 = 124 vertices; the narrow phase's cost grows with them)
MAX_FACES = 64
#: faces of a rock by default: 24 vertices, the ``max_vertices`` of grains from files
DEFAULT_FACES = 14
#: distinct rocks of a population by default
DEFAULT_SHAPES = 10
#: the normals' random step by default, in mean spacings
DEFAULT_ROUGHNESS = 0.5
#: draws of the normals tried before a rock is given up (a draw whose normals leave a direction
#: uncut makes an unbounded intersection and is drawn again)
_DRAWS = 100


def _fibonacci_directions(count: int) -> np.ndarray:
    """``(count, 3)`` unit vectors of the Fibonacci lattice, nearly even over the sphere."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    phi = math.pi * (3.0 - math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _cut_ellipsoid(normals: np.ndarray, semi_axes: np.ndarray) -> np.ndarray | None:
    """Corners of the intersection of the half-spaces tangent to the ellipsoid along ``normals``,
    or None when the normals leave it unbounded (the origin not inside their hull)."""
    hull = ConvexHull(normals)
    if not np.all(hull.equations[:, 3] < -1e-6):
        return None
    support = np.sqrt(((normals * semi_axes) ** 2).sum(axis=1))
    halfspaces = np.column_stack([normals, -support])  # n . x - h <= 0
    corners = HalfspaceIntersection(halfspaces, np.zeros(3)).intersections
    return corners[np.sort(ConvexHull(corners).vertices)]


def rock(rng: np.random.Generator, aspect: tuple[float, float] = (1.0, 1.0), faces: int = DEFAULT_FACES,
         roughness: float = DEFAULT_ROUGHNESS, name: str = "rock") -> ConvexPolyhedron:
    """One rock of ``faces`` faces whose principal extents have the ratios ``aspect`` = (L/G, G/E),
    at circumscribed diameter 1 d (module docstring).

    Args:
        rng: the random generator it is drawn from.
        aspect: ``(L/G, G/E)``, each >= 1.
        faces: number of faces, in [:data:`MIN_FACES`, :data:`MAX_FACES`].
        roughness: the normals' random step, in mean spacings (0: the even lattice, turned).
        name: the shape's label.

    Raises:
        ShapeError: a ratio below 1, a number of faces out of range, a negative roughness, or no
            bounded rock in :data:`_DRAWS` draws.
    """
    elongation, flatness = float(aspect[0]), float(aspect[1])
    if not (elongation >= 1.0 and flatness >= 1.0):
        raise ShapeError(f"rock aspect [L/G, G/E] must both be >= 1, got [{elongation:g}, {flatness:g}]")
    if not MIN_FACES <= int(faces) <= MAX_FACES:
        raise ShapeError(f"rock faces must be in [{MIN_FACES}, {MAX_FACES}], got {faces}")
    if not roughness >= 0:
        raise ShapeError(f"rock roughness must be >= 0, got {roughness:g}")
    target = np.array([elongation * flatness, flatness, 1.0])  # L, G, E up to a factor
    spacing = math.sqrt(4.0 * math.pi / faces)
    lattice = _fibonacci_directions(int(faces))
    for _ in range(_DRAWS):
        normals = lattice @ Rotation.random(random_state=rng).as_matrix().T
        normals = normals + roughness * spacing * rng.standard_normal(normals.shape)
        normals /= np.sqrt((normals ** 2).sum(axis=1))[:, None]
        corners = _cut_ellipsoid(normals, target / 2.0)
        if corners is not None:
            break
    else:
        raise ShapeError(f"no bounded rock of {faces} faces at roughness {roughness:g} in {_DRAWS} draws")
    body = ConvexPolyhedron(corners, name=name)
    extents = np.ptp(body.vertices, axis=0)
    order = np.argsort(-extents, kind="stable")  # body axes from the longest extent to the shortest
    stretch = np.empty(3)
    stretch[order] = target / extents[order]
    body = ConvexPolyhedron(body.vertices * stretch, name=name)
    return body.scaled(1.0 / body.size)


def rock_library(seed: int, count: int, aspect: tuple[float, float] = (1.0, 1.0), faces: int = DEFAULT_FACES,
                 roughness: float = DEFAULT_ROUGHNESS, name: str = "rock") -> tuple[ConvexPolyhedron, ...]:
    """``count`` rocks (:func:`rock`), rock ``s`` drawn from the stream ``(seed, ROCK_STREAM, s)``
    and named ``f"{name}-{s}"``; each at circumscribed diameter 1 d."""
    return tuple(rock(np.random.default_rng([int(seed), ROCK_STREAM, s]), aspect, faces, roughness,
                      name=f"{name}-{s}") for s in range(int(count)))


"""Lean hulls: a convex hull of many vertices reduced to at most ``max_vertices`` of them.

Method (docs/method/grains.md#reduction-to-max_vertices): greedy vertex removal. Removing hull
vertex ``v`` takes off the cap between ``v`` and the hull of its neighbours ``N(v)`` (the vertices
it shares an edge with), of volume

.. math:: \\Delta V(v) = V(\\mathrm{hull}(N(v) \\cup \\{v\\})) - V(\\mathrm{hull}(N(v))),

and each round removes, among the vertices of smallest :math:`\\Delta V`, a set of which no two
are neighbours (at most a tenth of the vertices, at most as many as are too many), recomputing
the hull and the caps whose neighbourhood changed. The reduced hull lies inside the original one;
it is then stretched along the original hull's principal axes (:func:`fit_to_hull`): the product
of the three stretches gives back the original volume exactly (the volume sets the solid
fraction), and their ratios are chosen to bring the principal moments and the aspect ratios
closest to the original's, leaving the deviations that :class:`Deviations` reports (scan-like
grains: docs/design-notes.md#shapes-from-files).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.spatial import ConvexHull, QhullError

from granpack.shapes.polyhedron import mass_properties

__all__ = ["reduce_hull", "fit_to_hull", "hull_descriptors", "Deviations", "DEFAULT_MAX_VERTICES", "MOMENT_TOLERANCE", "ASPECT_TOLERANCE"]

#: default ``max_vertices`` of a population from files (docs/design-notes.md#shapes-from-files)
DEFAULT_MAX_VERTICES = 24
#: largest relative deviation of a principal moment that a reduction may leave
MOMENT_TOLERANCE = 0.05
#: largest relative deviation of an aspect ratio (L/G or G/E) that a reduction may leave
ASPECT_TOLERANCE = 0.05


@dataclass(frozen=True)
class Deviations:
    """Relative deviations of a reduced grain from the hull it was reduced from, (reduced - hull) / hull.

    Attributes:
        volume: of the volume.
        moments: ``(3,)`` of the principal moments, ascending.
        aspect: ``(2,)`` of the aspect ratios L/G and G/E.
    """

    volume: float
    moments: tuple[float, float, float]
    aspect: tuple[float, float]

    @property
    def largest_moment(self) -> float:
        """Largest absolute moment deviation."""
        return max(abs(m) for m in self.moments)

    @property
    def largest_aspect(self) -> float:
        """Largest absolute aspect-ratio deviation."""
        return max(abs(a) for a in self.aspect)


def _volume(points: np.ndarray) -> float:
    """Volume of the hull of ``points`` (0 if flat)."""
    if len(points) < 4:
        return 0.0
    try:
        return float(ConvexHull(points).volume)
    except QhullError:
        return 0.0


def _neighbours(hull: ConvexHull, n: int) -> list[frozenset[int]]:
    """Each hull vertex's neighbours (indices into the hull's points) through the triangles."""
    out: list[set[int]] = [set() for _ in range(n)]
    for a, b, c in hull.simplices:
        out[a].update((b, c))
        out[b].update((a, c))
        out[c].update((a, b))
    return [frozenset(s) for s in out]


def reduce_hull(points: np.ndarray, max_vertices: int) -> np.ndarray:
    """Indices of at most ``max_vertices`` of ``points`` whose hull keeps most of its volume.

    Args:
        points: ``(V, 3)`` hull vertices (every one extreme), any unit.
        max_vertices: the most vertices kept, >= 4.

    Returns:
        ``(K,)`` int64 indices into ``points``, increasing (the kept points keep their order).
    """
    points = np.asarray(points, dtype=np.float64)
    if max_vertices < 4:
        raise ValueError(f"max_vertices must be >= 4, got {max_vertices}")
    kept = np.arange(len(points))
    cache: dict[tuple[int, frozenset[int]], float] = {}
    while len(kept) > max_vertices:
        hull = ConvexHull(points[kept])
        kept = kept[np.sort(hull.vertices)]  # a vertex made redundant by an earlier round goes
        if len(kept) <= max_vertices:
            break
        hull = ConvexHull(points[kept])
        near = _neighbours(hull, len(kept))
        loss = np.empty(len(kept))
        for i, ring in enumerate(near):
            key = (int(kept[i]), frozenset(int(kept[j]) for j in ring))
            if key not in cache:
                around = points[sorted(key[1])]
                cache[key] = _volume(np.vstack([around, points[kept[i]]])) - _volume(around)
            loss[i] = cache[key]
        budget = min(len(kept) - max_vertices, max(1, len(kept) // 10))
        removed: list[int] = []
        blocked: set[int] = set()
        for i in np.argsort(loss, kind="stable"):
            if i in blocked:
                continue
            removed.append(int(i))
            blocked.update(near[i])
            if len(removed) == budget:
                break
        kept = np.delete(kept, removed)
    return kept


def _oriented_triangles(hull: ConvexHull) -> np.ndarray:
    """The hull's triangles, each turned counter-clockwise seen from outside."""
    tri = hull.simplices.copy()
    p = hull.points
    normal = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    flip = np.einsum("ij,ij->i", normal, hull.equations[:, :3]) < 0
    tri[flip] = tri[flip][:, ::-1]
    return tri


def _ratios(extents: np.ndarray) -> tuple[float, float]:
    """``(L/G, G/E)`` of three extents in any order."""
    e = np.sort(extents)[::-1]
    return float(e[0] / e[1]), float(e[1] / e[2])


def hull_descriptors(points: np.ndarray) -> tuple[float, np.ndarray, tuple[float, float, float],
                                                   tuple[float, float], np.ndarray]:
    """Mass properties and shape ratios of the convex hull of ``points`` ``(V, 3)``.

    Returns:
        ``(volume, centroid (3,), principal moments ascending (unit density), (L/G, G/E), axes)``:
        ``axes`` ``(3, 3)`` holds the principal axes as columns, in the order of the moments; L, G,
        E are the hull's extents along them, largest first.
    """
    hull = ConvexHull(points)
    volume, centroid, inertia = mass_properties(points, list(_oriented_triangles(hull)))
    moments, axes = np.linalg.eigh(inertia)
    along = (points - centroid) @ axes
    return (volume, centroid, tuple(float(m) for m in moments), _ratios(along.max(axis=0) - along.min(axis=0)),
            axes)


def fit_to_hull(points: np.ndarray, volume: float, moments, aspect, axes: np.ndarray) -> np.ndarray:
    """``points`` (a reduced hull's vertices) stretched about their centroid along ``axes``.

    With stretches :math:`s_1 s_2 s_3 = V / V_r` (``V`` the original hull's ``volume``, ``V_r``
    the reduced one's) the volume is the original's exactly; the free ratios minimise, by
    Nelder-Mead from equal stretches, the largest relative deviation of the principal moments
    (``moments``, ascending) and of the aspect ratios (``aspect``).

    Returns:
        ``(K, 3)`` the stretched points, in the frame of ``points``.
    """
    reduced_volume, centroid, inertia = mass_properties(points, list(_oriented_triangles(ConvexHull(points))))
    inertia_local = axes.T @ inertia @ axes
    spread = 0.5 * np.trace(inertia_local) * np.eye(3) - inertia_local  # int x x^T dV, principal frame of the hull
    local = (points - centroid) @ axes
    target_moments, target_aspect = np.asarray(moments), np.asarray(aspect)
    log_total = float(np.log(volume / reduced_volume))

    def stretches(x: np.ndarray) -> np.ndarray:
        return np.exp(np.array([x[0], x[1], log_total - x[0] - x[1]]))

    def deviation(x: np.ndarray) -> float:
        s = stretches(x)
        cov = np.prod(s) * (s[:, None] * spread * s[None, :])
        got, frame = np.linalg.eigh(np.trace(cov) * np.eye(3) - cov)
        along = (local * s) @ frame
        got_aspect = np.array(_ratios(along.max(axis=0) - along.min(axis=0)))
        return float(max(np.abs(got / target_moments - 1.0).max(), np.abs(got_aspect / target_aspect - 1.0).max()))

    start = np.full(2, log_total / 3.0)
    result = minimize(deviation, start, method="Nelder-Mead",
                      options={"xatol": 1e-10, "fatol": 1e-10, "initial_simplex": start + 0.02 * np.vstack([np.zeros(2), np.eye(2)])})
    best = result.x if result.fun < deviation(start) else start
    return centroid + (local * stretches(best)) @ axes.T

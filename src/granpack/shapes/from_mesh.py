"""Grains from mesh files: the convex hull of a scanned surface, reduced to ``max_vertices``.

Method (docs/method/grains.md#grains-from-mesh-files): the grain is the convex hull of the
file's points (granpack's grains are convex); its **convexity** is the volume the surface encloses
over the hull's volume, 1 for a convex surface, and what the hull adds to a grain. A hull of more
than ``max_vertices`` vertices is reduced (:mod:`granpack.shapes.reduction`), scaled back to the
hull's volume, and the deviations of its principal moments and aspect ratios from the hull's are
kept. The hull's vertices keep the file's order (:mod:`granpack.shapes.mesh_files`), so a hull that
needs no reduction is the :class:`~granpack.shapes.ConvexPolyhedron` of those points, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from granpack.shapes.mesh_files import MeshFile, MeshFileError, read_mesh
from granpack.shapes.polyhedron import ConvexPolyhedron
from granpack.shapes.reduction import (ASPECT_TOLERANCE, MOMENT_TOLERANCE, Deviations, fit_to_hull,
                                      hull_descriptors, reduce_hull)
from granpack.shapes.sizes import aspect_ratios, size_of

__all__ = ["MeshGrain", "grain_from_mesh", "population_grains", "MIN_CONVEXITY", "MAX_SIZE_SPREAD",
           "MAX_OFFSET"]

#: default least convexity (mesh volume / hull volume) of a grain from a file: below it the hull
#: adds more than about a sixth of the grain's volume, more than a scanned crushed stone's hull
#: does (0.9 to 1), and the grain packs as another shape
MIN_CONVEXITY = 0.85
#: largest ratio of two files' circumscribed sizes within one population before it is taken for a
#: unit mismatch (one file in m, another in mm)
MAX_SIZE_SPREAD = 100.0
#: largest distance of a grain's centroid from the file's origin, in grain sizes: farther, the
#: coordinates keep fewer than 10 of their 16 digits for the grain's shape
MAX_OFFSET = 1e6


@dataclass(frozen=True)
class MeshGrain:
    """One grain from a file, in the file's unit, body frame (centroid at the origin, principal axes).

    Attributes:
        source: the file.
        shape: the hull, reduced to at most ``max_vertices`` vertices when it had more.
        mesh_volume: volume the file's surface encloses (file unit cubed).
        hull_volume: volume of its convex hull.
        hull_vertex_count: vertices of the hull before reduction.
        hull_moments: ``(3,)`` principal moments of the hull at unit density, ascending.
        hull_aspect: ``(L/G, G/E)`` of the hull.
        deviations: of the reduced grain from the hull; None when the hull needed no reduction.
    """

    source: Path
    shape: ConvexPolyhedron
    mesh_volume: float
    hull_volume: float
    hull_vertex_count: int
    hull_moments: tuple[float, float, float]
    hull_aspect: tuple[float, float]
    deviations: Deviations | None

    @property
    def convexity(self) -> float:
        """Mesh volume over hull volume, in (0, 1]."""
        return self.mesh_volume / self.hull_volume

    @cached_property
    def sizes(self) -> dict[str, float]:
        """The grain's size in each definition (:data:`granpack.shapes.sizes.SIZE_DEFINITIONS`), file unit."""
        from granpack.shapes.sizes import SIZE_DEFINITIONS

        return {definition: size_of(self.shape, definition) for definition in SIZE_DEFINITIONS}


def grain_from_mesh(mesh: MeshFile, max_vertices: int) -> MeshGrain:
    """The grain of one file: its hull, reduced to at most ``max_vertices`` vertices.

    Raises:
        MeshFileError: a flat or degenerate hull, or a grain far from the file's origin
            (:data:`MAX_OFFSET`).
    """
    points = mesh.vertices
    extent = float(np.ptp(points, axis=0).max())
    try:
        hull = ConvexHull(points)
    except QhullError:
        raise MeshFileError(f"{mesh.path}: flat or degenerate (its points lie in a plane or on a line)") from None
    if not hull.volume > 1e-9 * extent ** 3:
        raise MeshFileError(f"{mesh.path}: flat or degenerate (its hull has no volume)")
    if float(np.abs(points.mean(axis=0)).max()) > MAX_OFFSET * extent:
        raise MeshFileError(f"{mesh.path}: the grain lies {float(np.abs(points.mean(axis=0)).max()):.3g} file units "
                            f"from the origin, over {MAX_OFFSET:g} times its size {extent:.3g}: move it near the origin")
    vertices = points[np.sort(hull.vertices)]
    volume, _, moments, aspect, axes = hull_descriptors(vertices)
    if len(vertices) <= max_vertices:
        shape = ConvexPolyhedron(vertices, name=mesh.path.stem)
        shape.source_convexity = mesh.volume / volume
        return MeshGrain(source=mesh.path, shape=shape, mesh_volume=mesh.volume, hull_volume=volume,
                         hull_vertex_count=len(vertices), hull_moments=moments, hull_aspect=aspect, deviations=None)
    reduced = fit_to_hull(vertices[reduce_hull(vertices, max_vertices)], volume, moments, aspect, axes)
    reduced = reduced[np.sort(ConvexHull(reduced).vertices)]  # every point extreme after the scaling too
    shape = ConvexPolyhedron(reduced, name=mesh.path.stem)
    shape.source_convexity = mesh.volume / volume
    got_aspect = aspect_ratios(shape)
    got_moments = np.sort(shape.principal_moments)
    deviations = Deviations(
        volume=float(shape.volume / volume - 1.0),
        moments=tuple(float(g / m - 1.0) for g, m in zip(got_moments, moments)),
        aspect=tuple(float(g / a - 1.0) for g, a in zip(got_aspect, aspect)),
    )
    return MeshGrain(source=mesh.path, shape=shape, mesh_volume=mesh.volume, hull_volume=volume,
                     hull_vertex_count=len(vertices), hull_moments=moments, hull_aspect=aspect, deviations=deviations)


@lru_cache(maxsize=4096)
def _cached_grain(path: Path, size: int, mtime_ns: int, max_vertices: int) -> MeshGrain:
    """:func:`grain_from_mesh` of a file as it is at ``(size, mtime_ns)`` (the cache key)."""
    return grain_from_mesh(read_mesh(path), max_vertices)


def population_grains(files: tuple[Path, ...] | list[Path], max_vertices: int,
                      min_convexity: float = MIN_CONVEXITY) -> tuple[MeshGrain, ...]:
    """The grains of a population's files, checked.

    Raises:
        MeshFileError: a file that cannot be read or is not a closed surface, a hull that is flat,
            a convexity below ``min_convexity``, a reduction whose moments or aspect ratios stray
            beyond :data:`~granpack.shapes.reduction.MOMENT_TOLERANCE` /
            :data:`~granpack.shapes.reduction.ASPECT_TOLERANCE`, or files whose sizes differ by more
            than :data:`MAX_SIZE_SPREAD` times (a unit mismatch).
    """
    grains = []
    for path in files:
        path = Path(path).resolve()
        try:
            stat = path.stat()
        except OSError:
            read_mesh(path)  # raises the file's error
            raise
        grain = _cached_grain(path, stat.st_size, stat.st_mtime_ns, int(max_vertices))
        if grain.convexity < min_convexity:
            raise MeshFileError(f"{path}: convexity {grain.convexity:.3f} (mesh volume / hull volume) is below "
                                f"min_convexity = {min_convexity:g}: the grain would be its hull, "
                                f"{100 * (1 / grain.convexity - 1):.0f} % larger; lower min_convexity to accept it")
        d = grain.deviations
        if d is not None and (d.largest_moment > MOMENT_TOLERANCE or d.largest_aspect > ASPECT_TOLERANCE):
            raise MeshFileError(f"{path}: reduced from {grain.hull_vertex_count} to {max_vertices} vertices its principal "
                                f"moments move by up to {100 * d.largest_moment:.1f} % and its aspect ratios by up to "
                                f"{100 * d.largest_aspect:.1f} % (allowed: {100 * MOMENT_TOLERANCE:g} %, "
                                f"{100 * ASPECT_TOLERANCE:g} %); raise max_vertices")
        grains.append(grain)
    sizes = np.array([g.shape.size for g in grains])
    if len(grains) > 1 and sizes.max() > MAX_SIZE_SPREAD * sizes.min():
        big, small = grains[int(sizes.argmax())], grains[int(sizes.argmin())]
        raise MeshFileError(f"{big.source}: {sizes.max() / sizes.min():.3g} times the size of {small.source} "
                            f"(more than {MAX_SIZE_SPREAD:g}): files in different length units?")
    return tuple(grains)

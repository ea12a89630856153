"""Grain volume at a distance from a container's side walls (docs/method/analysis.md#wall-effect).

:func:`inset_volumes` gives the volume of the grains inside a horizontal slab ``[z_b, z_t)`` and
at least ``e`` from the side walls (:meth:`granpack.box.Box.wall_distance`), for several ``e``: the
region is the cylinder of radius ``D/2 - e`` about the axis, or the box inset by ``e`` on its four
sides. Differences of consecutive insets are the volumes of shells (annuli in a cylinder, square
frames in a box). Two methods:

- **spheres**: the integral over the height of the area of each cross-section disk (radius
  ``a(z) = sqrt(R^2 - (z - z_c)^2)``) inside the inset region, in closed form (the lens of two
  circles; a disk cut by a rectangle through the area of a disk cut by a quadrant), integrated by
  Gauss-Legendre in ``theta`` with ``z = z_c + R sin theta`` (:data:`SPHERE_NODES` nodes over the
  part of the sphere in the slab). The only error is that of the quadrature where the disk meets
  the region's boundary (a kink of the integrand): within 3e-4 of a grain's volume (a sphere on the axis of a
  cylinder, against the closed form).
- **polyhedra**: a cloud of points filling the grain, a cubic grid of :data:`POLYHEDRON_GRID`
  points across its circumscribed diameter in the body frame kept inside its faces, each carrying
  an equal share of the grain's exact volume, turned and moved with the grain; a shell's volume is
  the weight of the points in it. The error of one grain's share of a shell is about the grid
  step over the shell's width; it averages out over grains in random orientations.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.box import Box
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix

__all__ = ["inset_volumes", "inset_area", "POLYHEDRON_GRID", "SPHERE_NODES"]

#: Gauss-Legendre nodes over the height of a sphere
SPHERE_NODES = 64
#: grid points across a polyhedron's circumscribed diameter
POLYHEDRON_GRID = 24
#: grains per vectorised block
_BLOCK = 128


def inset_area(box: Box, inset: np.ndarray) -> np.ndarray:
    """Horizontal area of the part of the container at least ``inset`` from its side walls, d^2
    (0 beyond its depth); the whole area :attr:`Box.area` at ``inset = 0``."""
    e = np.asarray(inset, dtype=np.float64)
    if box.container == "cylinder":
        r = np.clip(0.5 * box.lx - e, 0.0, None)
        return math.pi * r * r
    return np.clip(box.lx - 2.0 * e, 0.0, None) * np.clip(box.ly - 2.0 * e, 0.0, None)


def _lens(a: np.ndarray, rho: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Area of the disk of radius ``a`` at distance ``rho`` from the centre of the disk of radius
    ``r`` inside that disk (broadcast)."""
    a, rho, r = np.broadcast_arrays(a, rho, r)
    out = np.zeros(a.shape)
    inside = rho + a <= r
    out[inside] = math.pi * a[inside] ** 2
    holds = ~inside & (rho + r <= a)
    out[holds] = math.pi * r[holds] ** 2
    cut = ~inside & ~holds & (rho < a + r) & (r > 0) & (a > 0)
    a, rho, r = a[cut], rho[cut], r[cut]
    ca = np.clip((rho * rho + a * a - r * r) / (2.0 * rho * a), -1.0, 1.0)
    cr = np.clip((rho * rho + r * r - a * a) / (2.0 * rho * r), -1.0, 1.0)
    kite = np.sqrt(np.clip((-rho + a + r) * (rho + a - r) * (rho - a + r) * (rho + a + r), 0.0, None))
    out[cut] = a * a * np.arccos(ca) + r * r * np.arccos(cr) - 0.5 * kite
    return out


def _quadrant(a: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Area of the disk of radius ``a`` about the origin with abscissa below ``x`` and ordinate below ``y``.

    The disk's vertical chord at abscissa u, below y, is ``min(y, h) + h`` long (``h = sqrt(a^2 - u^2)``)
    where positive; it is ``2 h`` where ``|u| > sqrt(a^2 - y^2)`` if ``y >= 0``, and 0 there if
    ``y < 0``; integrated with the primitive ``G`` of ``h``.
    """
    a = np.maximum(a, 1e-300)

    def primitive(u):
        u = np.clip(u, -a, a)
        return 0.5 * (u * np.sqrt(np.clip(a * a - u * u, 0.0, None)) + a * a * np.arcsin(np.clip(u / a, -1.0, 1.0)))

    def span(lo, hi):  # an empty interval where hi < lo
        return np.minimum(lo, hi), hi

    top = np.clip(x, -a, a)
    star = np.sqrt(np.clip(a * a - y * y, 0.0, None))
    star = np.where(np.abs(y) >= a, 0.0, star)
    outer = np.where(y >= 0.0, 1.0, 0.0)
    # [-a, -star], [-star, star], [star, a], each clipped to below ``top``
    lo1, hi1 = span(-a, np.minimum(-star, top))
    lo2, hi2 = span(-star, np.minimum(star, top))
    lo3, hi3 = span(star, np.minimum(a, top))
    total = outer * 2.0 * ((primitive(hi1) - primitive(lo1)) + (primitive(hi3) - primitive(lo3)))
    middle = (y * (hi2 - lo2) + primitive(hi2) - primitive(lo2)) * np.where(np.abs(y) >= a, 0.0, 1.0)
    return total + middle


def _disk_in_rectangle(a, cx, cy, x0, x1, y0, y1) -> np.ndarray:
    """Area of the disk of radius ``a`` centred at ``(cx, cy)`` inside ``[x0, x1] x [y0, y1]`` (broadcast;
    0 for an empty rectangle)."""
    u0, u1, v0, v1 = x0 - cx, x1 - cx, y0 - cy, y1 - cy
    area = _quadrant(a, u1, v1) - _quadrant(a, u0, v1) - _quadrant(a, u1, v0) + _quadrant(a, u0, v0)
    return np.where((x1 > x0) & (y1 > y0), np.clip(area, 0.0, None), 0.0)


def _sphere_insets(box: Box, centres: np.ndarray, radii: np.ndarray, z_range, insets: np.ndarray) -> np.ndarray:
    """``(K,)`` volume of the spheres inside the slab and at least ``insets`` from the side walls."""
    z_b, z_t = z_range
    t, w = np.polynomial.legendre.leggauss(SPHERE_NODES)
    out = np.zeros(len(insets))
    zc, radius = centres[:, 2], radii
    lo = np.clip((z_b - zc) / radius, -1.0, 1.0)
    hi = np.clip((z_t - zc) / radius, -1.0, 1.0)
    cut = hi > lo
    centres, radius, lo, hi = centres[cut], radius[cut], lo[cut], hi[cut]
    for s in range(0, len(radius), _BLOCK):
        c, r = centres[s:s + _BLOCK], radius[s:s + _BLOCK]
        t_lo, t_hi = np.arcsin(lo[s:s + _BLOCK]), np.arcsin(hi[s:s + _BLOCK])
        mid, half = 0.5 * (t_hi + t_lo), 0.5 * (t_hi - t_lo)
        theta = mid[:, None] + half[:, None] * t[None, :]  # (S, n)
        a = (r[:, None] * np.cos(theta))[:, :, None]  # (S, n, 1)
        weight = half[:, None] * w[None, :] * r[:, None] * np.cos(theta)  # dz = R cos(theta) d theta
        e = insets[None, None, :]
        if box.container == "cylinder":
            rho = np.hypot(c[:, 0] - 0.5 * box.lx, c[:, 1] - 0.5 * box.ly)[:, None, None]
            area = _lens(a, rho, np.clip(0.5 * box.lx - e, 0.0, None))
        else:
            cx, cy = c[:, 0, None, None], c[:, 1, None, None]
            area = _disk_in_rectangle(a, cx, cy, e, box.lx - e, e, box.ly - e)
        out += np.einsum("sn,snk->k", weight, area)
    return out


def _body_points(table, kind: int) -> np.ndarray:
    """The body-frame points of a polyhedron's cloud (module docstring)."""
    radius = float(table.radius[kind])
    step = 2.0 * radius / POLYHEDRON_GRID
    axis = (np.arange(POLYHEDRON_GRID) + 0.5) * step - radius
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    f0, f1 = table.face_start[kind], table.face_start[kind + 1]
    inside = np.all(grid @ table.face_normals[f0:f1].T <= table.face_offsets[f0:f1][None, :], axis=1)
    return grid[inside]


def _polyhedron_insets(packing: Packing, grains: np.ndarray, z_range, insets: np.ndarray) -> np.ndarray:
    """``(K,)`` volume of the polyhedra ``grains`` (indices) inside the slab and at least ``insets``
    from the side walls, from their point clouds."""
    state, box = packing.state, packing.box
    table = state.shapes
    z_b, z_t = z_range
    out = np.zeros(len(insets))
    for kind in np.unique(state.kind[grains]):
        points = _body_points(table, int(kind))
        if not len(points):
            continue
        share = table.volume[kind] / len(points)
        members = grains[state.kind[grains] == kind]
        for s in range(0, len(members), _BLOCK):
            block = members[s:s + _BLOCK]
            world = np.einsum("gij,pj->gpi", quat_to_matrix(state.quaternion[block]), points)
            world += state.position[block][:, None, :]
            world = world.reshape(-1, 3)
            world = world[(world[:, 2] >= z_b) & (world[:, 2] < z_t)]
            distance = np.sort(box.wall_distance(world))
            out += share * (len(distance) - np.searchsorted(distance, insets, side="left"))
    return out


def inset_volumes(packing: Packing, z_range: tuple[float, float], insets) -> np.ndarray:
    """``(K,)`` volume of the grains inside the slab ``z_range`` and at least ``insets[k]`` from
    the side walls of the packing's container, d^3 (module docstring: exact to the quadrature for
    spheres, a point cloud for polyhedra).

    Args:
        packing: a packing in a box or a cylinder.
        z_range: ``(z_b, z_t)``, d.
        insets: ``(K,)`` distances from the walls, d.
    """
    box = packing.box
    if box.periodic:
        raise ValueError("inset_volumes needs a container: a periodic cell has no side walls")
    insets = np.atleast_1d(np.asarray(insets, dtype=np.float64))
    state = packing.state
    if state.n == 0 or not z_range[1] > z_range[0]:
        return np.zeros(len(insets))
    sphere = state.shapes.is_sphere[state.kind]
    out = _sphere_insets(box, state.position[sphere], state.radius[sphere], z_range, insets)
    polyhedra = np.flatnonzero(~sphere)
    if len(polyhedra):
        out += _polyhedron_insets(packing, polyhedra, z_range, insets)
    return out

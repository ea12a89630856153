"""Solid fraction: exact slice volumes, the profile phi(z), the free surface and the bulk value.

Definitions: docs/method/analysis.md#solid-fraction and #bulk-region.

For a slice ``[a, b)`` of the column of horizontal area ``Lx Ly``:

.. math:: \\phi = \\frac{\\sum_p V_p([a, b))}{L_x L_y (b - a)}

with the exact volume of each grain inside the slice: spherical segments for spheres,
:math:`F(u) = \\pi (R^2 u - u^3/3)`; for convex polyhedra :math:`V_{below}(b) - V_{below}(a)` by the
divergence theorem over the faces clipped to ``z <= h`` plus the cap polygon (kernels in
:mod:`granpack.analysis._kernels`).

Bulk region (used by every analysis): ``z_bottom = n_bottom d`` and ``z_top = z_surface - n_top d``
(``d`` the largest grain size, ``n_bottom = n_top = 2`` by default). The free surface
``z_surface`` is where the profile (slices ``0.1 d``) last crosses half its plateau, the
plateau being the median of the profile between ``n_bottom d`` and the height holding 75 % of
the solid volume. A bulk thinner than ``d`` is not a bulk: the bulk figures are then ``nan``.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, any_finite, as_array, result
from granpack.analysis._kernels import slice_volumes_kernel
from granpack.analysis._wall_volumes import inset_area, inset_volumes
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix

__all__ = ["SolidFraction", "slice_volumes", "bulk_range", "plot_profile"]


def slice_volumes(packing: Packing, z0: float, dz: float, nslices: int, groups: np.ndarray | None = None) -> np.ndarray:
    """Exact grain volume inside each slice ``[z0 + k dz, z0 + (k+1) dz)``, ``k < nslices``.

    Args:
        packing: the packing.
        z0, dz: first plane and slice thickness, d.
        nslices: number of slices.
        groups: ``(N,)`` non-negative int group per particle (e.g. ``state.population``); one
            group if omitted.

    Returns:
        ``(G, nslices)`` volumes, d^3 (``G`` = number of groups).
    """
    state = packing.state
    table = state.shapes
    if groups is None:
        groups = np.zeros(state.n, dtype=np.int64)
    groups = np.ascontiguousarray(groups, dtype=np.int64)
    ngroups = int(groups.max()) + 1 if state.n else 1
    nslices = int(nslices)
    if state.n == 0 or nslices <= 0:
        return np.zeros((ngroups, max(nslices, 0)))
    return slice_volumes_kernel(
        float(z0),
        float(dz),
        nslices,
        groups,
        ngroups,
        state.position,
        quat_to_matrix(state.quaternion),
        state.kind,
        table.is_sphere,
        table.radius,
        table.volume,
        table.vertex_start,
        table.vertices,
        table.face_start,
        table.face_normals,
        table.face_offsets,
        table.face_vertex_start,
        table.face_vertices,
    )


def _surface(z: np.ndarray, phi: np.ndarray, volume: np.ndarray, dz: float, d: float, n_bottom: float) -> tuple[float, float]:
    """``(plateau, z_surface)`` of a profile (see the module docstring); ``nan`` for an empty profile."""
    total = volume.sum()
    if not total > 0:
        return math.nan, math.nan
    cumulative = np.cumsum(volume) / total
    z_fill = (np.searchsorted(cumulative, 0.75) + 1) * dz
    sel = (z >= n_bottom * d) & (z <= z_fill)
    if not sel.any():
        sel = (z <= z_fill) & (phi > 0)
    plateau = float(np.median(phi[sel]))
    half = 0.5 * plateau
    k = int(np.flatnonzero(phi >= half)[-1])
    if k + 1 < len(phi):
        z_surf = z[k] + (phi[k] - half) / (phi[k] - phi[k + 1]) * dz
    else:
        z_surf = z[k] + 0.5 * dz
    return plateau, float(z_surf)


class SolidFraction(Compute):
    """Solid-fraction profile, free surface and bulk value.

    Args:
        slice_thickness: profile slice thickness in units of the largest grain size d.
        n_bottom: the bulk starts ``n_bottom d`` above the wall.
        n_top: the bulk ends ``n_top d`` below the free surface.
        z_range: explicit bulk ``(z_bottom, z_top)`` in d (overrides ``n_bottom``, ``n_top``).
        n_wall: in a box or a cylinder, the bulk figures (:attr:`bulk`, :attr:`layers`) are those
            of the **core**, the volume at least ``n_wall d`` from the side walls
            (docs/method/analysis.md#wall-effect); 0 the whole section. A periodic cell has no
            side walls: ignored there. The profile is always over the whole section.

    Example::

        sf = SolidFraction().compute(packing)
        sf.bulk, sf.std, sf.z_surface
    """

    def __init__(self, slice_thickness: float = 0.1, n_bottom: float = 2.0, n_top: float = 2.0,
                 z_range: tuple[float, float] | None = None, n_wall: float = 0.0):
        if not slice_thickness > 0:
            raise ValueError(f"slice_thickness must be > 0, got {slice_thickness}")
        self.slice_thickness = float(slice_thickness)
        self.n_bottom = float(n_bottom)
        self.n_top = float(n_top)
        self.z_range = None if z_range is None else (float(z_range[0]), float(z_range[1]))
        if not n_wall >= 0:
            raise ValueError(f"n_wall must be >= 0, got {n_wall}")
        self.n_wall = float(n_wall)

    def compute(self, packing: Packing) -> "SolidFraction":
        """Compute the profile, the surface and the bulk figures of ``packing``."""
        self._start()
        state = packing.state
        area = packing.box.area
        d = packing.max_size if state.n else 1.0
        dz = self.slice_thickness * d
        top = float(np.max(state.position[:, 2] + state.radius)) if state.n else 0.0
        nslices = max(int(math.ceil(top / dz)), 0)
        volume = slice_volumes(packing, 0.0, dz, nslices)[0]
        self._d = d
        self._container = not packing.box.periodic
        self._z = (np.arange(nslices) + 0.5) * dz
        self._phi = volume / (area * dz)
        self._plateau, self._z_surface = _surface(self._z, self._phi, volume, dz, d, self.n_bottom)
        if self.z_range is not None:
            z_bot, z_top = self.z_range
            valid = z_top > z_bot
        else:
            z_bot, z_top = self.n_bottom * d, self._z_surface - self.n_top * d
            valid = bool(z_top - z_bot >= d)
        self._z_bottom, self._z_top = z_bot, z_top
        self._valid = valid
        self._bulk = self._std = math.nan
        self._layers = np.zeros(0)
        if not valid:
            self._warn(self._no_bulk_reason() + ": the bulk solid fraction is nan")
            return self._done()
        height = z_top - z_bot
        nlayers = int(math.floor(height / d + 1e-9))
        if self._container and self.n_wall > 0:
            self._core_figures(packing, z_bot, z_top, nlayers)
        else:
            self._bulk = float(slice_volumes(packing, z_bot, height, 1).sum() / (area * height))
            if nlayers >= 2:
                self._layers = slice_volumes(packing, z_bot, d, nlayers)[0] / (area * d)
        if len(self._layers) >= 2:
            self._std = float(np.std(self._layers, ddof=1))
        elif nlayers < 2:
            self._warn("bulk region holds fewer than two grain-size layers: solid-fraction std is nan")
        return self._done()

    def _core_figures(self, packing: Packing, z_bot: float, z_top: float, nlayers: int) -> None:
        """The bulk value and the layers of a container's core (:func:`inset_volumes`)."""
        margin = self.n_wall * self._d
        core = float(inset_area(packing.box, margin))
        if not core > 0:
            self._warn(f"the core, {self.n_wall:g} d from the side walls, is empty: the bulk solid fraction is nan")
            return
        self._bulk = float(inset_volumes(packing, (z_bot, z_top), [margin])[0] / (core * (z_top - z_bot)))
        if nlayers >= 2:
            self._layers = np.array([inset_volumes(packing, (z_bot + k * self._d, z_bot + (k + 1) * self._d), [margin])[0]
                                     for k in range(nlayers)]) / (core * self._d)

    @result
    def no_bulk_reason(self) -> str:
        """Why there is no bulk region, in one line (empty when there is one)."""
        return "" if self._valid else self._no_bulk_reason()

    def _no_bulk_reason(self) -> str:
        if self.z_range is not None:
            return f"no bulk region: the given range z = {self._z_bottom:.3g} .. {self._z_top:.3g} d is empty"
        if not math.isfinite(self._z_surface):
            return "no bulk region: no grain, hence no free surface"
        d, needed = self._d, (self.n_bottom + 1.0 + self.n_top) * self._d
        return (f"no bulk region: the pile's free surface is at {self._z_surface:.3g} d, below the {needed:.3g} d a "
                f"bulk region needs ({self.n_bottom:g} d above the wall, at least {d:.3g} d thick, {self.n_top:g} d "
                "below the surface)")

    @result
    def profile_z(self) -> np.ndarray:
        """``(K,)`` slice mid-heights, d."""
        return self._z.copy()

    @result
    def profile_phi(self) -> np.ndarray:
        """``(K,)`` solid fraction of each slice."""
        return self._phi.copy()

    @result
    def plateau(self) -> float:
        """Median profile value in the lower filled part (reference for the surface detection)."""
        return self._plateau

    @result
    def z_surface(self) -> float:
        """Free-surface height (profile crosses half the plateau), d."""
        return self._z_surface

    @result
    def z_bottom(self) -> float:
        """Bottom of the bulk region, d."""
        return self._z_bottom

    @result
    def z_top(self) -> float:
        """Top of the bulk region, d."""
        return self._z_top

    @result
    def has_bulk(self) -> bool:
        """Whether the bulk region is at least one grain size thick (or the explicit range is non-empty)."""
        return self._valid

    @result
    def bulk(self) -> float:
        """Solid fraction of the bulk slab ``[z_bottom, z_top]`` (``nan`` without bulk)."""
        return self._bulk

    @result
    def layers(self) -> np.ndarray:
        """Solid fraction of the consecutive d-thick layers from ``z_bottom`` (those fully in the bulk)."""
        return self._layers.copy()

    @result
    def std(self) -> float:
        """Standard deviation (ddof 1) of :attr:`layers` (``nan`` with fewer than two layers)."""
        return self._std

    def to_dict(self, expansion_k: float = math.nan) -> dict:
        """The ``solid_fraction`` part of ``analysis.json``: ``bulk``, ``std``, ``profile_z``,
        ``profile_phi``, ``layers``, ``plateau``, and ``corrected_for_overlap`` = bulk / (1 + k),
        the bulk value once the overlaps are released, from the expansion coefficient ``k`` of
        :class:`~granpack.analysis.interpenetration.Interpenetration` (nan when ``k`` is not finite).
        """
        return {
            "bulk": self.bulk,
            "std": self.std,
            "profile_z": self.profile_z,
            "profile_phi": self.profile_phi,
            "layers": self.layers,
            "plateau": self.plateau,
            "corrected_for_overlap": self.bulk / (1.0 + expansion_k) if math.isfinite(expansion_k) else math.nan,
        }

    def region_to_dict(self) -> dict:
        """The ``bulk`` part of ``analysis.json``, the region every bulk figure reads: ``z_bottom``,
        ``z_top``, ``z_surface`` (d), ``valid`` (:attr:`has_bulk`), ``n_bottom``, ``n_top``, and in
        a box or a cylinder ``n_wall`` (the core's distance from the side walls, in d; a periodic
        cell's part has no such key)."""
        out = {
            "z_bottom": self.z_bottom,
            "z_top": self.z_top,
            "z_surface": self.z_surface,
            "valid": self.has_bulk,
            "n_bottom": self.n_bottom,
            "n_top": self.n_top,
        }
        if self._container:
            out["n_wall"] = self.n_wall
        return out

    def plot(self, ax):
        """The profile figure (:func:`plot_profile`) on ``ax``; returns ``ax``."""
        plot_profile(ax, self.to_dict(), self.region_to_dict())
        return ax


def plot_profile(ax, output: dict | None, region: dict | None = None) -> bool:
    """Draw the solid-fraction profile phi(z) on ``ax``: the slice averages, the bulk region
    shaded, the bulk value dashed with its standard deviation.

    Pyplot-free: it draws on the given axes and creates no figure, so the same function serves a
    computed :class:`SolidFraction` and a run's ``analysis.json`` (``granpack figures``).

    Args:
        ax: matplotlib axes.
        output: a ``solid_fraction`` part (:meth:`SolidFraction.to_dict` or read from the file).
        region: the ``bulk`` part (:meth:`SolidFraction.region_to_dict`); no shading without it.

    Returns:
        Whether there was a profile to draw (nothing is drawn otherwise).
    """
    sf = output or {}
    z, phi = as_array(sf.get("profile_z")), as_array(sf.get("profile_phi"))
    if not any_finite(phi) or len(z) != len(phi):
        return False
    ax.plot(phi, z, color="C0", label="slice average")
    region = region or {}
    if region.get("valid") and all(isinstance(region.get(k), (int, float)) for k in ("z_bottom", "z_top")):
        ax.axhspan(region["z_bottom"], region["z_top"], color="0.9", zorder=0, label="bulk region")
    bulk, std = sf.get("bulk"), sf.get("std")
    if isinstance(bulk, (int, float)) and math.isfinite(bulk):
        label = f"bulk {bulk:.4f}" + (f" ± {std:.4f}" if isinstance(std, (int, float)) and math.isfinite(std) else "")
        ax.axvline(bulk, color="C3", linestyle="--", label=label)
    ax.set_xlabel("solid fraction φ")
    ax.set_ylabel("height z (d)")
    ax.legend(loc="best")
    return True


def analysed_region(packing: Packing, z_range: tuple[float, float] | None = None) -> tuple[float, float, bool]:
    """``(z_bottom, z_top, valid)`` of the region an analysis reads: ``z_range`` when given (valid
    when not empty), else the default bulk region (:func:`bulk_range`)."""
    if z_range is None:
        return bulk_range(packing)
    return float(z_range[0]), float(z_range[1]), z_range[1] > z_range[0]


def in_region(packing: Packing, region: tuple[float, float, bool], n_wall: float = 0.0) -> np.ndarray:
    """``(N,)`` True for the grains whose centres lie in ``region``, an :func:`analysed_region`
    (none if it is not valid), and in a container's **core**: at least ``n_wall d`` from its side
    walls (:meth:`~granpack.box.Box.wall_distance`; a periodic cell has none, every grain is in)."""
    z_bot, z_top, valid = region
    z = packing.state.position[:, 2]
    inside = (z >= z_bot) & (z <= z_top) if valid else np.zeros(packing.state.n, bool)
    if n_wall > 0 and not packing.box.periodic and packing.state.n:
        inside &= packing.box.wall_distance(packing.state.position) >= n_wall * packing.max_size
    return inside


def bulk_range(packing: Packing, n_bottom: float = 2.0, n_top: float = 2.0) -> tuple[float, float, bool]:
    """``(z_bottom, z_top, valid)`` of the default bulk region (see :class:`SolidFraction`)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sf = SolidFraction(n_bottom=n_bottom, n_top=n_top).compute(packing)
    return sf.z_bottom, sf.z_top, sf.has_bulk

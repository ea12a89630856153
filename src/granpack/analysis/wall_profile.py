"""The wall effect of a box or a cylinder: profiles against the distance from the side walls
(docs/method/analysis.md#wall-effect).

Over the heights of the bulk slab ``[z_b, z_t]``, with ``s`` the distance from the nearest side wall
(:meth:`granpack.box.Box.wall_distance`: ``D/2 - r`` in a cylinder of diameter D, the distance to
the nearest of the four planes in a box):

- the **solid fraction** of each shell ``[s_k, s_k + Δs)`` (annuli in a cylinder, square frames in
  a box; ``Δs = 0.05 d`` by default), the volume of the grains inside the shell and the slab over
  the shell's volume (:func:`~granpack.analysis._wall_volumes.inset_volumes`: exact to the
  quadrature for spheres, a point cloud for polyhedra), and that of the whole section (the wall
  zone included);
- per shell of ``Δs = 0.25 d``, over the grains whose **centre** lies in it: their number and number
  density, the backbone coordination ``N`` and ``N_c`` and the rattler fraction (the rules of
  :class:`~granpack.analysis.coordination.Coordination` over the whole slab, the grains above and
  below it a boundary), and the nematic order :math:`Q^2_{00}` of the non-spherical grains
  (:func:`~granpack.analysis.order.order_parameters`).

A periodic cell has no side walls: the figures are nan, with a warning.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, any_finite, as_array, result
from granpack.analysis._wall_volumes import POLYHEDRON_GRID, SPHERE_NODES, inset_area, inset_volumes
from granpack.analysis.coordination import Coordination
from granpack.analysis.order import order_parameters
from granpack.analysis.solid_fraction import analysed_region
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix

__all__ = ["WallProfile", "plot_wall_profile", "PROFILE_QUANTITIES"]

#: the profiles :func:`plot_wall_profile` draws: key of the part -> axis label
PROFILE_QUANTITIES = {
    "solid_fraction": "solid fraction φ",
    "N": "backbone coordination N",
    "Q00": "nematic order Q²₀₀",
}

#: the volume method in words (``analysis.json`` carries it beside the profile)
METHOD = (f"spheres: area of each cross-section disk inside the shell in closed form, {SPHERE_NODES} Gauss-Legendre "
          f"nodes over the height; polyhedra: a cloud of {POLYHEDRON_GRID}^3-grid points inside each grain")


def _edges(depth: float, width: float) -> np.ndarray:
    """Shell edges from the wall (0) to the container's ``depth``, ``width`` apart, the last shell
    ending at ``depth``."""
    edges = np.arange(0.0, depth, width)
    return np.append(edges, depth)


class WallProfile(Compute):
    """Profiles of a container packing against the distance from its side walls.

    Args:
        z_range: the slab ``(z_bottom, z_top)`` in d; the default bulk region if omitted.
        bin_width: shells of the solid-fraction profile, in units of the largest grain size d.
        grain_bin_width: shells of the profiles over grain centres (coordination, order), in d.
        coordination: a :class:`Coordination` computed over the whole slab (no core) whose
            backbone the profile reads; computed with its defaults if omitted.

    Example::

        wp = WallProfile().compute(packing)
        wp.distance, wp.solid_fraction, wp.section_solid_fraction
    """

    def __init__(self, z_range: tuple[float, float] | None = None, bin_width: float = 0.05,
                 grain_bin_width: float = 0.25, coordination: Coordination | None = None):
        if not (bin_width > 0 and grain_bin_width > 0):
            raise ValueError(f"bin widths must be > 0, got {bin_width}, {grain_bin_width}")
        self.z_range = z_range
        self.bin_width = float(bin_width)
        self.grain_bin_width = float(grain_bin_width)
        self.coordination = coordination

    def compute(self, packing: Packing) -> "WallProfile":
        """Compute the profiles of ``packing``."""
        self._start()
        self._container = ""
        box, state = packing.box, packing.state
        d = packing.max_size if state.n else 1.0
        self._container = box.container
        self._z_bottom, self._z_top, valid = analysed_region(packing, self.z_range)
        depth = box.depth
        self._edges = _edges(depth, self.bin_width * d) if math.isfinite(depth) else np.zeros(1)
        self._grain_edges = _edges(depth, self.grain_bin_width * d) if math.isfinite(depth) else np.zeros(1)
        self._phi = np.full(len(self._edges) - 1, math.nan)
        self._section = math.nan
        k = len(self._grain_edges) - 1
        self._counts = np.zeros(k, np.int64)
        self._density = self._n = self._nc = self._rattlers = self._q00 = np.full(k, math.nan)
        self._n_oriented = np.zeros(k, np.int64)
        if box.periodic:
            self._warn("a periodic cell has no side walls: the wall profiles are nan")
            return self._done()
        if not valid:
            self._warn("no bulk region: the wall profiles are nan")
            return self._done()
        height = self._z_top - self._z_bottom
        inside = inset_volumes(packing, (self._z_bottom, self._z_top), self._edges)
        with np.errstate(invalid="ignore", divide="ignore"):
            self._phi = -np.diff(inside) / (-np.diff(inset_area(box, self._edges)) * height)
        self._section = float(inside[0] / (box.area * height))
        self._grain_profiles(packing, height)
        return self._done()

    def _grain_profiles(self, packing: Packing, height: float) -> None:
        """The profiles over grain centres (module docstring)."""
        state, box = packing.state, packing.box
        z = state.position[:, 2]
        in_slab = (z >= self._z_bottom) & (z <= self._z_top)
        shell = np.searchsorted(self._grain_edges, box.wall_distance(state.position), side="right") - 1
        k = len(self._grain_edges) - 1
        shell = np.where(in_slab & (shell >= 0) & (shell < k), shell, -1)
        co = self.coordination
        if co is None:
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                co = Coordination((self._z_bottom, self._z_top)).compute(packing)
        counts, rattlers = co.per_particle, co.rattlers
        oriented = ~state.shapes.is_sphere[state.kind]
        rotations = quat_to_matrix(state.quaternion)
        self._counts = np.bincount(shell[shell >= 0], minlength=k)[:k]
        with np.errstate(invalid="ignore", divide="ignore"):
            self._density = self._counts / (-np.diff(inset_area(box, self._grain_edges)) * height)
        n, nc, rattled, q00 = (np.full(k, math.nan) for _ in range(4))
        for b in range(k):
            grains = shell == b
            if not grains.any():
                continue
            backbone = grains & ~rattlers
            rattled[b] = float((grains & rattlers).sum() / grains.sum())
            if backbone.any():
                n[b] = float(counts[backbone].sum(axis=1).mean())
                nc[b] = float((counts[backbone] @ np.array([1.0, 2.0, 3.0])).mean())
            self._n_oriented[b] = int((grains & oriented).sum())
            if self._n_oriented[b]:
                q00[b] = order_parameters(rotations[grains & oriented])[0]
        self._n, self._nc, self._rattlers, self._q00 = n, nc, rattled, q00

    @result
    def distance(self) -> np.ndarray:
        """``(K,)`` mid-distance of each solid-fraction shell from the side walls, d."""
        return 0.5 * (self._edges[1:] + self._edges[:-1])

    @result
    def solid_fraction(self) -> np.ndarray:
        """``(K,)`` solid fraction of each shell over the slab's heights."""
        return self._phi.copy()

    @result
    def section_solid_fraction(self) -> float:
        """Solid fraction of the whole section over the slab's heights (the wall zone included)."""
        return self._section

    @result
    def grain_distance(self) -> np.ndarray:
        """``(J,)`` mid-distance of each shell of the profiles over grain centres, d."""
        return 0.5 * (self._grain_edges[1:] + self._grain_edges[:-1])

    @result
    def grains(self) -> np.ndarray:
        """``(J,)`` grain centres in each shell (and the slab)."""
        return self._counts.copy()

    @result
    def number_density(self) -> np.ndarray:
        """``(J,)`` grain centres per unit volume of each shell, d^-3."""
        return self._density.copy()

    @result
    def N(self) -> np.ndarray:
        """``(J,)`` backbone coordination of the grains of each shell (rattlers removed)."""
        return self._n.copy()

    @result
    def Nc(self) -> np.ndarray:
        """``(J,)`` backbone constraints ``Ns + 2 Nd + 3 Nt`` per grain of each shell."""
        return self._nc.copy()

    @result
    def rattler_fraction(self) -> np.ndarray:
        """``(J,)`` share of each shell's grains that are rattlers."""
        return self._rattlers.copy()

    @result
    def Q00(self) -> np.ndarray:
        """``(J,)`` nematic order of each shell's non-spherical grains (nan without any)."""
        return self._q00.copy()

    def to_dict(self) -> dict:
        """The ``wall_profile`` part of ``analysis.json``: ``container``, the slab (``z_bottom``,
        ``z_top``), ``distance`` and ``solid_fraction`` (the shells of ``bin_width``),
        ``section_solid_fraction``, ``grain_distance`` with ``grains``, ``number_density``, ``N``,
        ``Nc``, ``rattler_fraction``, ``Q00`` and ``n_oriented`` (the shells of
        ``grain_bin_width``), and ``method`` (the volume method in words)."""
        return {
            "container": self._container,
            "z_bottom": self._z_bottom,
            "z_top": self._z_top,
            "bin_width": self.bin_width,
            "distance": self.distance,
            "solid_fraction": self.solid_fraction,
            "section_solid_fraction": self.section_solid_fraction,
            "grain_bin_width": self.grain_bin_width,
            "grain_distance": self.grain_distance,
            "grains": self.grains,
            "number_density": self.number_density,
            "N": self.N,
            "Nc": self.Nc,
            "rattler_fraction": self.rattler_fraction,
            "Q00": self.Q00,
            "n_oriented": self._n_oriented.copy(),
            "method": METHOD,
        }

    def plot(self, ax, quantity: str = "solid_fraction"):
        """One profile (:func:`plot_wall_profile`) on ``ax``; returns ``ax``."""
        plot_wall_profile(ax, self.to_dict(), quantity)
        return ax


def plot_wall_profile(ax, output: dict | None, quantity: str = "solid_fraction", core: float | None = None) -> bool:
    """Draw one profile against the distance from the side walls on ``ax``: ``"solid_fraction"``
    (a line, the whole section's value dotted, and the core's value dashed when ``core`` is given),
    ``"N"`` or ``"Q00"`` (markers at the shells' mid-distances); keys of :data:`PROFILE_QUANTITIES`.

    Pyplot-free: it draws on the given axes and creates no figure, so the same function serves a
    computed :class:`WallProfile` and a run's ``analysis.json`` (``granpack figures``).

    Args:
        ax: matplotlib axes.
        output: a ``wall_profile`` part (:meth:`WallProfile.to_dict` or read from the file).
        quantity: which profile.
        core: the bulk (core) value of the quantity, drawn dashed; none if omitted or not finite.

    Returns:
        Whether there was a profile to draw (nothing is drawn otherwise).
    """
    if quantity not in PROFILE_QUANTITIES:
        raise ValueError(f"quantity must be one of {', '.join(PROFILE_QUANTITIES)}, got {quantity!r}")
    data = output or {}
    x = as_array(data.get("distance" if quantity == "solid_fraction" else "grain_distance"))
    y = as_array(data.get(quantity))
    if not any_finite(y) or len(x) != len(y):
        return False
    if quantity == "solid_fraction":
        ax.plot(x, y, color="C0", label="shell")
        section = data.get("section_solid_fraction")
        if isinstance(section, (int, float)) and math.isfinite(section):
            ax.axhline(section, color="0.4", linestyle=":", label=f"whole section {section:.4f}")
    else:
        ax.plot(x, y, color="C0", marker="o", markersize=3, label="grains centred in the shell")
    if isinstance(core, (int, float)) and math.isfinite(core):
        ax.axhline(core, color="C3", linestyle="--", label=f"core {core:.4g}")
    ax.set_xlabel("distance from the side wall s (d)")
    ax.set_ylabel(PROFILE_QUANTITIES[quantity])
    ax.legend(loc="best")
    return True

"""Pair correlation function g(r) of grain centres in a bi-periodic slab (docs/method/analysis.md#pair-correlation).

Reference grains and neighbours are the grains with centre in the bulk slab ``[z_b, z_t]``
(minimum image in x, y). With ``n_k`` the number of ordered pairs (reference i, neighbour j != i)
at distance in ``[r_k, r_k + Δr)``, the slab is not periodic in z, so each reference's shell is
truncated by the slab planes:

.. math::

    g(r_k + Δr/2) = \\frac{n_k}{\\rho \\sum_i [B(r_k + Δr; h_i) - B(r_k; h_i)]}, \\qquad
    \\rho = \\frac{N_{slab}}{L_x L_y (z_t - z_b)},

    B(r; h) = \\tfrac43 \\pi r^3 - c(r, h - z_b) - c(r, z_t - h), \\qquad
    c(r, a) = \\pi (r - a)^2 (2r + a) / 3 \\ (a < r), \\ 0 \\text{ otherwise}.

(The untruncated normalisation, as in freud's RDF, is biased low in a slab.) Partials
``g_ab = n_ab / (rho_b sum_{i in a} ΔB_i)``. The running coordination
:math:`Z(r) = \\int_0^r \\rho g\\, 4\\pi s^2 ds` is reported too. ``r_max`` must stay below half
the lateral period; it is clipped there with a warning.

Option ``interior_only``: only references at least ``r_max`` away from both slab planes (their
shells are whole; Z(r) is then the exact mean neighbour count). Option ``periodic_z``: treat the
configuration as periodic in z with that period (configurations built in fully periodic cells,
e.g. to cross-check against freud); all grains are then references.

Option ``n_wall`` (a box or a cylinder, docs/method/analysis.md#wall-effect): the references are
the grains of the **core**, centres at least ``n_wall d`` from the side walls; the neighbours are
every grain of the slab, whatever its distance from the walls; ``rho`` is the number density of
the core's centres, and ``r_max`` is clipped at ``n_wall d``, so that every reference's shell lies
inside the container (only the slab planes truncate it, as above).
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, any_finite, as_array, result
from granpack.analysis._kernels import pair_histogram_kernel
from granpack.analysis._wall_volumes import inset_area
from granpack.analysis.solid_fraction import analysed_region, in_region
from granpack.packing import Packing

__all__ = ["PairCorrelation", "ball_in_slab", "g_of", "plot_g"]


def ball_in_slab(r: np.ndarray, below: np.ndarray, above: np.ndarray) -> np.ndarray:
    """Volume of balls of radius ``r`` inside a slab, centre ``below`` above its bottom and ``above`` below its top.

    Broadcasts its arguments; ``B = 4/3 π r^3 - c(r, below) - c(r, above)``.
    """

    def cap(r, a):
        return np.where(a < r, np.pi * (r - a) ** 2 * (2.0 * r + a) / 3.0, 0.0)

    return 4.0 / 3.0 * np.pi * r**3 - cap(r, below) - cap(r, above)


class PairCorrelation(Compute):
    """g(r) of the grain centres in the bulk slab.

    Args:
        bins: number of bins on ``[0, r_max)``.
        r_max: largest distance, in d.
        z_range: slab ``(z_b, z_t)`` in d; the default bulk region if omitted.
        interior_only: take as references only grains whose whole shell of radius ``r_max`` is in the slab.
        partials: also compute ``g_ab`` between populations.
        periodic_z: period along z (fully periodic configuration); ``None`` for the slab.
        n_wall: in a box or a cylinder, references in the core only, ``n_wall d`` from the side
            walls (module docstring); 0 every grain of the slab; ignored in a periodic cell.

    Example::

        rdf = PairCorrelation(bins=200, r_max=4.0).compute(packing)
        rdf.r, rdf.g
    """

    def __init__(
        self,
        bins: int = 200,
        r_max: float = 4.0,
        z_range: tuple[float, float] | None = None,
        interior_only: bool = False,
        partials: bool = False,
        periodic_z: float | None = None,
        n_wall: float = 0.0,
    ):
        if bins < 1 or not r_max > 0:
            raise ValueError(f"need bins >= 1 and r_max > 0, got bins={bins}, r_max={r_max}")
        self.bins = int(bins)
        self.r_max = float(r_max)
        self.z_range = z_range
        self.interior_only = bool(interior_only)
        self.partials = bool(partials)
        self.periodic_z = periodic_z
        self.n_wall = float(n_wall)

    def compute(self, packing: Packing) -> "PairCorrelation":
        """Histogram the pair distances of ``packing`` and normalise."""
        self._start()
        state = packing.state
        box = packing.box
        r_max = self.r_max
        limit = 0.5 * min(box.lx, box.ly, self.periodic_z or math.inf)
        core = not box.periodic and self.n_wall > 0 and self.periodic_z is None
        if core:
            limit = self.n_wall * (packing.max_size if state.n else 1.0)
        if r_max > limit:
            what = "the core's distance from the walls" if core else "half the period"
            self._warn(f"r_max = {r_max:g} d exceeds {what} ({limit:g} d); clipped")
            r_max = limit
        width = r_max / self.bins
        self._edges = np.arange(self.bins + 1) * width
        npop = len(packing.population_names) if state.n else 1
        self._g = np.full(self.bins, math.nan)
        self._z_cum = np.full(self.bins, math.nan)
        self._partial = np.full((npop, npop, self.bins), math.nan)
        self._n_ref = 0
        self._names = list(packing.population_names)
        self._r_min = float(state.radius.min()) if state.n else math.nan

        z = state.position[:, 2]
        if self.periodic_z is not None:
            z_b, z_t, valid = 0.0, float(self.periodic_z), True
            members = np.ones(state.n, bool)
        else:
            z_b, z_t, valid = region = analysed_region(packing, self.z_range)
            members = in_region(packing, region)
        refs = in_region(packing, region, self.n_wall) if core else members.copy()
        n_core = int(refs.sum())
        if self.interior_only and self.periodic_z is None:
            refs &= (z >= z_b + r_max) & (z <= z_t - r_max)
        self._n_ref = int(refs.sum())
        if not valid:
            self._warn(f"the analysed slab is empty (no bulk region: z from {z_b:.3g} to {z_t:.3g} d): g(r) is nan")
            return self._done()
        if members.sum() < 2 or self._n_ref == 0:
            self._warn(f"{int(members.sum())} grain(s) in the slab z = {z_b:.3g} .. {z_t:.3g} d, {self._n_ref} of them "
                       f"at least r_max = {r_max:g} d from its faces (reference grains): g(r) needs two grains and "
                       "one reference; it is nan")
            return self._done()

        idx = np.flatnonzero(members)
        idx = idx[np.argsort(z[idx], kind="stable")]
        group = state.population[idx]
        counts = pair_histogram_kernel(
            state.position[idx], refs[idx], group, npop, box.periods[0], box.periods[1], float(self.periodic_z or 0.0),
            r_max, self.bins
        ).astype(np.float64)
        volume = box.area * (z_t - z_b)
        rho = len(idx) / volume
        if core:  # the density of the references' region
            rho = n_core / (float(inset_area(box, limit)) * (z_t - z_b))
        rho_b = np.bincount(group, minlength=npop) / volume
        ref_group = state.population[refs]
        if self.periodic_z is not None:
            shells = np.diff(4.0 / 3.0 * np.pi * self._edges**3)
            shell_sum = np.outer(np.bincount(ref_group, minlength=npop), shells)  # (npop, bins)
        else:
            h = z[refs]
            b = ball_in_slab(self._edges[None, :], (h - z_b)[:, None], (z_t - h)[:, None])
            per_ref = np.diff(b, axis=1)
            shell_sum = np.stack([per_ref[ref_group == a].sum(axis=0) for a in range(npop)])
        total = counts.sum(axis=(0, 1))
        with np.errstate(invalid="ignore", divide="ignore"):
            self._g = total / (rho * shell_sum.sum(axis=0))
            if self.partials:
                self._partial = counts / (rho_b[None, :, None] * shell_sum[:, None, :])
        shell_volumes = np.diff(4.0 / 3.0 * np.pi * self._edges**3)
        self._z_cum = np.cumsum(np.nan_to_num(self._g) * rho * shell_volumes)
        return self._done()

    @result
    def bin_edges(self) -> np.ndarray:
        """``(bins + 1,)`` bin edges, d."""
        return self._edges.copy()

    @result
    def r(self) -> np.ndarray:
        """``(bins,)`` bin centres, d."""
        return 0.5 * (self._edges[1:] + self._edges[:-1])

    @result
    def r_over_rmin(self) -> np.ndarray:
        """``(bins,)`` bin centres in units of the smallest grain's circumscribed radius R_min."""
        return self.r / self._r_min

    @result
    def g(self) -> np.ndarray:
        """``(bins,)`` total g(r) (nan when not computable)."""
        return self._g.copy()

    @result
    def coordination(self) -> np.ndarray:
        """``(bins,)`` running coordination Z at the upper edge of each bin."""
        return self._z_cum.copy()

    @result
    def partial(self) -> np.ndarray:
        """``(P, P, bins)`` partial g_ab(r) (reference population a, neighbour b); nan unless ``partials``."""
        return self._partial.copy()

    @result
    def n_references(self) -> int:
        """Number of reference grains."""
        return self._n_ref

    def to_dict(self) -> dict:
        """The ``pair_correlation`` part of ``analysis.json``: ``r``, ``g``, ``r_over_rmin``,
        ``coordination`` (running Z), ``n_references``, and with ``partials`` the partial g_ab(r)
        under ``"a|b"`` (reference population a, neighbour population b, by name)."""
        out = {
            "r": self.r,
            "g": self.g,
            "r_over_rmin": self.r_over_rmin,
            "coordination": self.coordination,
            "n_references": self.n_references,
        }
        if self.partials:
            partial = self.partial
            names = self._names
            out["partial"] = {f"{a}|{b}": partial[i, j] for i, a in enumerate(names) for j, b in enumerate(names)}
        return out

    def plot(self, ax):
        """The g(r) figure of a run (:func:`plot_g`, with its legend) on ``ax``; returns ``ax``."""
        if plot_g(ax, self.to_dict()):
            ax.legend()
        return ax


def g_of(output: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """``(r, g)`` of a ``pair_correlation`` part (:meth:`PairCorrelation.to_dict` or read from
    ``analysis.json``); empty arrays when absent, of unequal lengths or all nan."""
    output = output or {}
    r, g = as_array(output.get("r")), as_array(output.get("g"))
    return (r, g) if len(r) == len(g) and any_finite(g) else (np.zeros(0), np.zeros(0))


def plot_g(ax, output: dict | None, *, reference: bool = True, **style) -> bool:
    """Draw one g(r) curve on ``ax`` and name the axes; with ``reference``, then the line g = 1.

    Pyplot-free: it draws on the given axes and creates no figure, so the same function serves a
    computed :class:`PairCorrelation`, a run's ``analysis.json`` (``granpack figures``) and a
    campaign's mean over replicas (an ``{"r", "g"}`` dict, several curves on one axes: the
    reference line with the last). The legend is the caller's, once its curves are drawn.

    Args:
        ax: matplotlib axes.
        output: a ``pair_correlation`` part (:meth:`PairCorrelation.to_dict` or read from the file).
        reference: draw the line g = 1 after the curve.
        style: matplotlib line keywords; default colour ``C0`` and label ``all grains``.

    Returns:
        Whether there was a curve to draw (:func:`g_of`; nothing is drawn otherwise).
    """
    r, g = g_of(output)
    if not len(g):
        return False
    ax.plot(r, g, **{"color": "C0", "label": "all grains", **style})
    ax.set_xlabel("distance between centres r (d)")
    ax.set_ylabel("pair correlation g(r)")
    if reference:
        ax.axhline(1.0, color="0.5", linewidth=0.8)
    return True

"""Homogeneity: share of each population by volume in horizontal layers (docs/method/analysis.md#homogeneity).

Layers ``[k t, (k+1) t)`` of thickness ``t = d`` (largest grain size) from the wall up. With the
exact volume of every grain inside every layer (:func:`~granpack.analysis.solid_fraction.slice_volumes`):

.. math:: p_\\pi(z) = \\frac{\\sum_{p \\in \\pi} V_p(\\text{layer})}{\\sum_p V_p(\\text{layer})}.

The nominal composition is the share of each population in the whole packing. A layer is
flagged as segregated for population π when :math:`|p_\\pi - p^{nom}_\\pi| > 3\\, SE`, SE being the
standard error of a random mixture of ``n`` grains (``n`` = centres in the layer) with the nominal
number fractions ``x_c`` and mean grain volumes ``v_c`` (delta method for a ratio of sums):

.. math:: SE_\\pi = \\frac{\\sqrt{\\sum_c x_c v_c^2 (\\delta_{c\\pi} - p^{nom}_\\pi)^2 / n}}{\\sum_c x_c v_c}.

Bulk statistics (mean and std of p_π) use the layers lying entirely in the bulk region.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, any_finite, as_array, result
from granpack.analysis.solid_fraction import analysed_region, slice_volumes
from granpack.packing import Packing

__all__ = ["Homogeneity", "plot_proportions", "proportions_of"]


class Homogeneity(Compute):
    """Volume share of each population per layer.

    Args:
        layer_thickness: in units of the largest grain size d.
        z_range: bulk ``(z_bottom, z_top)`` in d for the bulk statistics; default bulk region if omitted.
    """

    def __init__(self, layer_thickness: float = 1.0, z_range: tuple[float, float] | None = None):
        if not layer_thickness > 0:
            raise ValueError(f"layer_thickness must be > 0, got {layer_thickness}")
        self.layer_thickness = float(layer_thickness)
        self.z_range = z_range

    def compute(self, packing: Packing) -> "Homogeneity":
        """Compute the layer compositions of ``packing``."""
        self._start()
        state = packing.state
        names = list(packing.population_names)
        npop = max(len(names), 1)
        self._names = names
        d = packing.max_size if state.n else 1.0
        t = self.layer_thickness * d
        top = float(np.max(state.position[:, 2] + state.radius)) if state.n else 0.0
        nlayers = max(int(math.ceil(top / t)), 0)
        vols = np.zeros((npop, nlayers))
        got = slice_volumes(packing, 0.0, t, nlayers, groups=state.population)
        vols[: got.shape[0]] = got
        total = vols.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            self._p = vols / total
        self._z = (np.arange(nlayers) + 0.5) * t
        layer_of = np.floor(state.position[:, 2] / t).astype(np.int64)
        inside = (layer_of >= 0) & (layer_of < nlayers)
        self._count = np.bincount(layer_of[inside], minlength=nlayers)[:nlayers]

        grain_volume = state.mass
        pop_volume = np.bincount(state.population, weights=grain_volume, minlength=npop)[:npop]
        pop_count = np.bincount(state.population, minlength=npop)[:npop].astype(np.float64)
        self._nominal = pop_volume / pop_volume.sum() if state.n else np.full(npop, math.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            x = pop_count / pop_count.sum()
            v = np.where(pop_count > 0, pop_volume / np.maximum(pop_count, 1), 0.0)
            spread = np.array([(x * v**2 * ((np.arange(npop) == a) - self._nominal[a]) ** 2).sum() for a in range(npop)])
            self._se = np.sqrt(spread[:, None] / self._count[None, :]) / (x * v).sum()
        self._segregated = np.abs(self._p - self._nominal[:, None]) > 3.0 * self._se

        z_bot, z_top, valid = analysed_region(packing, self.z_range)
        edges = np.arange(nlayers + 1) * t
        self._bulk_layers = (edges[:-1] >= z_bot - 1e-12) & (edges[1:] <= z_top + 1e-12) if valid else np.zeros(nlayers, bool)
        if not valid:
            self._warn("no bulk region: bulk homogeneity statistics are nan")
        elif not self._bulk_layers.any():
            self._warn(f"no {t:g} d layer lies entirely in the bulk region (z = {z_bot:.3g} .. {z_top:.3g} d): "
                       "bulk homogeneity statistics are nan")
        return self._done()

    @result
    def z(self) -> np.ndarray:
        """``(K,)`` layer mid-heights, d."""
        return self._z.copy()

    @result
    def proportions(self) -> dict[str, np.ndarray]:
        """Population name -> ``(K,)`` volume share per layer (nan in empty layers)."""
        return {name: self._p[a].copy() for a, name in enumerate(self._names)}

    @result
    def counts(self) -> np.ndarray:
        """``(K,)`` grain centres per layer."""
        return self._count.copy()

    @result
    def nominal(self) -> dict[str, float]:
        """Population name -> volume share in the whole packing."""
        return {name: float(self._nominal[a]) for a, name in enumerate(self._names)}

    @result
    def standard_error(self) -> dict[str, np.ndarray]:
        """Population name -> ``(K,)`` standard error of a random mixture with the layer's grain count."""
        return {name: self._se[a].copy() for a, name in enumerate(self._names)}

    @result
    def segregated(self) -> dict[str, np.ndarray]:
        """Population name -> ``(K,)`` True where the share departs from nominal by more than 3 SE."""
        return {name: self._segregated[a].copy() for a, name in enumerate(self._names)}

    @result
    def bulk_layers(self) -> np.ndarray:
        """``(K,)`` True for the layers entirely inside the bulk region."""
        return self._bulk_layers.copy()

    @result
    def bulk_mean(self) -> dict[str, float]:
        """Population name -> mean share over the bulk layers (nan without any)."""
        sel = self._bulk_layers
        return {name: float(self._p[a, sel].mean()) if sel.any() else math.nan for a, name in enumerate(self._names)}

    @result
    def bulk_std(self) -> dict[str, float]:
        """Population name -> std (ddof 1) of the share over the bulk layers (nan with fewer than two)."""
        sel = self._bulk_layers
        return {name: float(self._p[a, sel].std(ddof=1)) if sel.sum() > 1 else math.nan for a, name in enumerate(self._names)}

    def to_dict(self) -> dict:
        """The ``homogeneity`` part of ``analysis.json``: ``z``, ``proportions``, ``nominal``,
        ``bulk_mean``, ``bulk_std`` (each by population name) and ``segregated_layers``: per
        population, the bulk layers flagged as segregated."""
        return {
            "z": self.z,
            "proportions": self.proportions,
            "nominal": self.nominal,
            "bulk_mean": self.bulk_mean,
            "bulk_std": self.bulk_std,
            "segregated_layers": {name: int((flags & self._bulk_layers).sum()) for name, flags in self.segregated.items()},
        }

    def plot(self, ax):
        """The homogeneity figure (:func:`plot_proportions`) on ``ax``; returns ``ax``."""
        plot_proportions(ax, self.to_dict())
        return ax


def proportions_of(output: dict | None) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, float]]:
    """Layer heights, the volume proportion profile of each population (those of the heights'
    length with a finite value) and the nominal proportions, of a ``homogeneity`` part
    (:meth:`Homogeneity.to_dict` or read from ``analysis.json``); empty where absent."""
    data = output or {}
    z = as_array(data.get("z"))
    proportions, nominal = data.get("proportions"), data.get("nominal")
    if not isinstance(proportions, dict):
        return z, {}, {}
    profiles = {str(name): as_array(p) for name, p in proportions.items()}
    nominal = {str(k): float(v) for k, v in nominal.items() if isinstance(v, (int, float))} if isinstance(nominal, dict) else {}
    return z, {name: p for name, p in profiles.items() if len(p) == len(z) and any_finite(p)}, nominal


def plot_proportions(ax, output: dict | None) -> int:
    """Draw each population's volume proportion against the height on ``ax``, its nominal share
    dotted in the same colour.

    Pyplot-free: it draws on the given axes and creates no figure, so the same function serves a
    computed :class:`Homogeneity` and a run's ``analysis.json`` (``granpack figures``).

    Returns:
        The number of profiles drawn (:func:`proportions_of`).
    """
    z, profiles, nominal = proportions_of(output)
    for k, (name, p) in enumerate(profiles.items()):
        ax.plot(p, z, marker=".", color=f"C{k}", label=name)
        if name in nominal:
            ax.axvline(nominal[name], color=f"C{k}", linewidth=0.8, linestyle=":")
    ax.set_xlabel("proportion of the solid volume")
    ax.set_ylabel("height z (d)")
    ax.set_xlim(-0.02, 1.02)
    ax.legend(title="population")
    return len(profiles)

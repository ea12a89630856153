"""Size classes: the packing's sieve curve, and per class its layer profile, coordination and rattlers.

A grain's size is its circumscribed diameter ``D`` (docs/method/analysis.md#size-classes). The
sieve curve is the share of the solid volume in grains smaller than each sieve,
:math:`P(D) = \\sum_{D_p \\le D} V_p / \\sum_p V_p`, over the whole packing and over the grains
whose centres lie in the bulk region. The classes lie between consecutive sieves ``[D_k, D_{k+1})``
(the last one closed); per class: its grains, its share of the volume, its share of the volume in
each horizontal layer of thickness ``d`` (exact, as :mod:`granpack.analysis.homogeneity`: a class
that sinks or floats is segregated), and over its bulk grains the backbone coordination ``N``
(force-bearing contacts per non-rattler) and the rattler fraction of
:class:`~granpack.analysis.coordination.Coordination`. Engineers read a packing by its grading;
the small grains of a wide grading are those that rattle in the voids of the large ones.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, as_array, result
from granpack.analysis.coordination import Coordination
from granpack.analysis.solid_fraction import analysed_region, in_region, slice_volumes
from granpack.packing import Packing

__all__ = ["SizeClasses", "DEFAULT_CLASSES", "plot_class_profiles"]

#: classes between the smallest and largest grain, evenly spaced in log D, when no sieves are given
DEFAULT_CLASSES = 4


class SizeClasses(Compute):
    """Grains sorted into classes between sieve sizes.

    Args:
        sieves: increasing sieve sizes, d; default :data:`DEFAULT_CLASSES` classes evenly spaced in
            log D from the smallest to the largest grain.
        layer_thickness: of the profile's layers, in units of the largest grain size d.
        z_range: bulk ``(z_bottom, z_top)`` in d; default the bulk region.
        coordination: a computed :class:`Coordination` of the same packing (its rattlers and
            per-grain counts); computed here over the bulk if omitted.
    """

    def __init__(self, sieves=None, layer_thickness: float = 1.0, z_range: tuple[float, float] | None = None,
                 coordination: Coordination | None = None):
        if sieves is not None:
            sieves = np.asarray(sieves, dtype=np.float64)
            if sieves.ndim != 1 or len(sieves) < 2 or not np.all(np.diff(sieves) > 0) or not sieves[0] > 0:
                raise ValueError(f"sieves must be at least 2 increasing sizes > 0, got {sieves.tolist()}")
        if not layer_thickness > 0:
            raise ValueError(f"layer_thickness must be > 0, got {layer_thickness}")
        self.sieves = sieves
        self.layer_thickness = float(layer_thickness)
        self.z_range = z_range
        self.coordination = coordination

    def compute(self, packing: Packing) -> "SizeClasses":
        """Sort the grains of ``packing`` by size and measure each class."""
        self._start()
        state = packing.state
        size, volume = 2.0 * state.radius, state.mass
        if self.sieves is not None:
            edges = self.sieves
        elif state.n and size.max() > size.min() * (1 + 1e-9):
            edges = np.geomspace(size.min(), size.max(), DEFAULT_CLASSES + 1)
        else:
            edges = np.array([size.min(), size.max() * (1 + 1e-9)]) if state.n else np.array([0.0, 1.0])
        n_classes = len(edges) - 1
        in_class = np.clip(np.searchsorted(edges, size, side="right") - 1, 0, n_classes - 1)
        outside = (size < edges[0] * (1 - 1e-12)) | (size > edges[-1] * (1 + 1e-12))
        if outside.any():
            self._warn(f"{int(outside.sum())} grains lie outside the sieves {edges[0]:.4g} .. {edges[-1]:.4g} d: "
                       "counted in the first or last class")
        region = analysed_region(packing, self.z_range)
        z_bot, z_top, valid = region
        bulk = in_region(packing, region)
        z = state.position[:, 2]
        self._edges, self._class = edges, in_class
        self._passing = _passing(size, volume, edges)
        self._passing_bulk = _passing(size[bulk], volume[bulk], edges) if bulk.any() else np.full(len(edges), math.nan)
        self._count = np.bincount(in_class, minlength=n_classes)
        total = volume.sum()
        self._share = np.bincount(in_class, weights=volume, minlength=n_classes) / total if total > 0 else \
            np.full(n_classes, math.nan)

        d = packing.max_size if state.n else 1.0
        t = self.layer_thickness * d
        top = float(np.max(z + state.radius)) if state.n else 0.0
        layers = max(int(math.ceil(top / t)), 0)
        volumes = np.zeros((n_classes, layers))
        got = slice_volumes(packing, 0.0, t, layers, groups=in_class)
        volumes[: got.shape[0]] = got
        with np.errstate(invalid="ignore", divide="ignore"):
            self._profile = volumes / volumes.sum(axis=0)
        self._z = (np.arange(layers) + 0.5) * t

        co = self.coordination
        if co is None:
            co = Coordination((z_bot, z_top) if valid else (0.0, 0.0)).compute(packing)
        contacts, rattler = co.per_particle.sum(axis=1), co.rattlers
        self._N = np.full(n_classes, math.nan)
        self._rattlers = np.full(n_classes, math.nan)
        self._bulk_count = np.zeros(n_classes, np.int64)
        for k in range(n_classes):
            members = bulk & (in_class == k)
            self._bulk_count[k] = int(members.sum())
            if members.any():
                self._rattlers[k] = float(rattler[members].mean())
                backbone = members & ~rattler
                if backbone.any():
                    self._N[k] = float(contacts[backbone].mean())
        if not bulk.any():
            self._warn("no grain in the bulk region: the classes' coordination and the bulk sieve curve are nan")
        return self._done()

    @result
    def edges(self) -> np.ndarray:
        """``(K+1,)`` sieve sizes bounding the classes, d."""
        return self._edges.copy()

    @result
    def particle_class(self) -> np.ndarray:
        """``(N,)`` class of each grain."""
        return self._class.copy()

    @result
    def passing(self) -> np.ndarray:
        """``(K+1,)`` share of the solid volume passing each sieve, whole packing."""
        return self._passing.copy()

    @result
    def passing_bulk(self) -> np.ndarray:
        """``(K+1,)`` the same over the bulk grains (nan without bulk)."""
        return self._passing_bulk.copy()

    @result
    def counts(self) -> np.ndarray:
        """``(K,)`` grains in each class."""
        return self._count.copy()

    @result
    def volume_shares(self) -> np.ndarray:
        """``(K,)`` share of the solid volume in each class."""
        return self._share.copy()

    @result
    def z(self) -> np.ndarray:
        """``(L,)`` mid-heights of the layers, d."""
        return self._z.copy()

    @result
    def profile(self) -> np.ndarray:
        """``(K, L)`` share of each layer's solid volume in each class (nan in an empty layer)."""
        return self._profile.copy()

    @result
    def coordination_by_class(self) -> np.ndarray:
        """``(K,)`` backbone coordination N of each class's bulk grains (nan where none)."""
        return self._N.copy()

    @result
    def rattler_fraction_by_class(self) -> np.ndarray:
        """``(K,)`` share of each class's bulk grains that are rattlers (nan where none)."""
        return self._rattlers.copy()

    @result
    def bulk_counts(self) -> np.ndarray:
        """``(K,)`` bulk grains in each class."""
        return self._bulk_count.copy()

    def to_dict(self) -> dict:
        """The ``size_classes`` part of ``analysis.json``: ``sieves`` (the class bounds, d),
        ``passing``, ``passing_bulk``, ``counts``, ``volume_shares``, ``bulk_counts``,
        ``coordination`` and ``rattler_fraction`` (each class's bulk grains), and the layer
        profile ``z``, ``profile``."""
        return {
            "sieves": self.edges,
            "passing": self.passing,
            "passing_bulk": self.passing_bulk,
            "counts": self.counts,
            "volume_shares": self.volume_shares,
            "bulk_counts": self.bulk_counts,
            "coordination": self.coordination_by_class,
            "rattler_fraction": self.rattler_fraction_by_class,
            "z": self.z,
            "profile": self.profile,
        }

    def plot(self, ax):
        """The classes' layer profiles (:func:`plot_class_profiles`) on ``ax``; returns ``ax``."""
        plot_class_profiles(ax, self.to_dict())
        return ax


def plot_class_profiles(ax, output: dict) -> None:
    """Draw each size class's share of the layers' solid volume against the height on ``ax``,
    its share of the whole packing dotted in the same colour (a class that sinks or floats leaves
    its dotted line).

    Pyplot-free: it draws on the given axes and creates no figure, so the same function serves a
    computed :class:`SizeClasses` and a run's ``analysis.json`` (the ``grading`` figure of
    ``granpack figures``).

    Args:
        ax: matplotlib axes.
        output: a ``size_classes`` part (:meth:`SizeClasses.to_dict` or read from the file).
    """
    sieves, z = as_array(output["sieves"]), as_array(output["z"])
    profile = np.atleast_2d(as_array(output["profile"]))
    for k in range(len(sieves) - 1):
        ax.plot(profile[k], z, marker=".", color=f"C{k}", label=f"{sieves[k]:.3g} - {sieves[k + 1]:.3g} d")
        share = as_array(output["volume_shares"])[k]
        ax.axvline(share, color=f"C{k}", linewidth=0.8, linestyle=":")
    ax.set_xlabel("share of the layer's solid volume")
    ax.set_ylabel("height z (d)")
    ax.set_xlim(-0.02, 1.02)
    ax.legend(title="size class", fontsize=8)


def _passing(size: np.ndarray, volume: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Share of ``volume`` in grains of size at most each edge (the last edge passes everything)."""
    if not len(size):
        return np.full(len(edges), math.nan)
    order = np.argsort(size, kind="stable")
    cumulative = np.concatenate([[0.0], np.cumsum(volume[order])]) / volume.sum()
    out = cumulative[np.searchsorted(size[order], edges * (1 + 1e-12), side="right")]
    out[-1] = 1.0
    return out

"""Grading curves: continuous size distributions of a population, and the sizes of its grains.

A grading is the share by volume of the grains smaller than a size ``D``, ``P(D)`` (what passes a
sieve of aperture ``D``), between ``D_min`` and ``D_max`` (docs: Method > Grains, gradings):

- Fuller / Talbot: :math:`P(D) = (D^n - D_{min}^n) / (D_{max}^n - D_{min}^n)`, the curve
  :math:`(D / D_{max})^n` with the fines below ``D_min`` left out;
- a sieve table: ``P`` given at the sieve sizes, interpolated linearly in ``log D`` between them
  (the grading charts of the standards have a logarithmic size axis);
- lognormal: ``ln D`` normal by number, of number mean ``mean`` and polydispersity
  ``δ = std(D) / mean(D)`` (before the truncation), truncated at ``cut`` standard deviations of
  ``ln D`` each side.

A grain's size is its circumscribed diameter (the sphere's diameter, :math:`\\sqrt{L^2 + G^2}` for
a pinacoid), as everywhere in granpack, and its volume is ``v_1 D^3`` with ``v_1`` the volume of
the shape at size 1. The number density of sizes is then :math:`f_N(D) \\propto P'(D) / D^3`, and
:meth:`Grading.sizes` gives ``n`` grains the sizes :math:`D_i = F_N^{-1}((i + 1/2) / n)`, the
midpoint of each of ``n`` equal slices of the number distribution: their moments converge as
``1/n^2`` and their volume curve follows ``P`` to within about the volume share of the largest
grain (a seed then orders the sizes among the grains, :class:`granpack.mixture.Mixture`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

__all__ = ["Grading", "achieved_passing", "largest_deviation"]

#: points of the tabulated number distribution of a lognormal (inverse sampling by interpolation)
_TABLE_POINTS = 4097


@dataclass(frozen=True)
class Grading:
    """A size distribution by volume between ``d_min`` and ``d_max`` (d).

    Attributes:
        kind: ``"fuller"``, ``"sieves"`` or ``"lognormal"``.
        d_min, d_max: the smallest and largest grain sizes, d.
        exponent: Fuller / Talbot exponent ``n > 0``.
        sieves, passing: the sieve table (sizes in d, increasing; cumulative share passing by volume,
            non-decreasing from 0 at the first sieve to 1 at the last).
        mean, polydispersity, cut: the lognormal's number mean (d), ``std / mean`` and truncation.
    """

    kind: str
    d_min: float
    d_max: float
    exponent: float = 0.0
    sieves: tuple[float, ...] = ()
    passing: tuple[float, ...] = ()
    mean: float = 0.0
    polydispersity: float = 0.0
    cut: float = 3.0

    @classmethod
    def fuller(cls, d_min: float, d_max: float, exponent: float) -> "Grading":
        """Fuller / Talbot curve ``(D / d_max)^exponent`` above ``d_min``."""
        return cls("fuller", float(d_min), float(d_max), exponent=float(exponent))

    @classmethod
    def sieve_table(cls, sieves, passing) -> "Grading":
        """A sieve table: sizes (d, increasing) and cumulative shares passing, non-decreasing from 0
        to 1; the sieves below the last one passing 0 and above the first one passing 1 hold no
        grain and are dropped (``d_min``, ``d_max`` are those two sieves)."""
        sieves, passing = [float(s) for s in sieves], [float(p) for p in passing]
        first = max(k for k, share in enumerate(passing) if share <= 0.0)
        last = min(k for k, share in enumerate(passing) if share >= 1.0)
        sieves, passing = tuple(sieves[first:last + 1]), tuple(passing[first:last + 1])
        return cls("sieves", sieves[0], sieves[-1], sieves=sieves, passing=passing)

    @classmethod
    def lognormal(cls, mean: float, polydispersity: float, cut: float = 3.0) -> "Grading":
        """Lognormal by number of mean ``mean`` (d) and ``std / mean = polydispersity``, truncated
        at ``cut`` standard deviations of ``ln D``."""
        sigma = math.sqrt(math.log1p(polydispersity ** 2))
        mu = math.log(mean) - 0.5 * sigma ** 2
        return cls("lognormal", math.exp(mu - cut * sigma), math.exp(mu + cut * sigma), mean=float(mean),
                   polydispersity=float(polydispersity), cut=float(cut))

    @property
    def size_ratio(self) -> float:
        """``d_max / d_min``."""
        return self.d_max / self.d_min

    def passing_at(self, sizes) -> np.ndarray:
        """``P(D)``: the share by volume of the grains smaller than each of ``sizes`` (d)."""
        d = np.clip(np.asarray(sizes, dtype=np.float64), self.d_min, self.d_max)
        if self.kind == "fuller":
            n = self.exponent
            return (d ** n - self.d_min ** n) / (self.d_max ** n - self.d_min ** n)
        if self.kind == "sieves":
            return np.interp(np.log(d), np.log(self.sieves), self.passing)
        grid, _, volume = self._lognormal_table()
        return np.interp(d, grid, volume)

    def number_quantile(self, q) -> np.ndarray:
        """:math:`F_N^{-1}(q)`: the size below which a share ``q`` of the grains by number lies (d)."""
        q = np.clip(np.asarray(q, dtype=np.float64), 0.0, 1.0)
        if self.kind == "fuller":
            return _power_quantile(q, self.d_min, self.d_max, self.exponent - 4.0)
        if self.kind == "sieves":
            return self._sieve_quantile(q)
        grid, number, _ = self._lognormal_table()
        return np.interp(q, number, grid)

    def sizes(self, n: int) -> np.ndarray:
        """``n`` grain sizes (d), increasing: the midpoints of ``n`` equal slices of the number
        distribution, :math:`D_i = F_N^{-1}((i + 1/2) / n)`."""
        return self.number_quantile((np.arange(n) + 0.5) / n)

    def mean_cube(self) -> float:
        """:math:`E_N[D^3]`, the mean of ``D^3`` over the grains by number (d^3): a grain's mean volume
        is ``v_1 E_N[D^3]``."""
        # E_N[D^3] = 1 / E_V[D^-3] (f_N ∝ f_V / D^3)
        return 1.0 / self._volume_mean_of_inverse_cube()

    def number_moments(self, k: int) -> float:
        """:math:`E_N[D^k]` (d^k), exact: ``E_V[D^(k-3)] / E_V[D^-3]``."""
        return self._volume_mean(k - 3.0) / self._volume_mean_of_inverse_cube()

    # ------------------------------------------------------------------------------ by kind

    def _volume_mean_of_inverse_cube(self) -> float:
        return self._volume_mean(-3.0)

    def _volume_mean(self, p: float) -> float:
        """:math:`E_V[D^p] = \\int D^p dP(D)`, exact for Fuller and sieve tables."""
        if self.kind == "fuller":
            n, a, b = self.exponent, self.d_min, self.d_max
            return n * _power_integral(a, b, n - 1.0 + p) / (b ** n - a ** n)
        if self.kind == "sieves":
            total = 0.0
            for (a, b), (pa, pb) in zip(zip(self.sieves, self.sieves[1:]), zip(self.passing, self.passing[1:])):
                if pb > pa:  # dP = c dlnD on [a, b], c = (pb - pa) / ln(b / a)
                    total += (pb - pa) / math.log(b / a) * _power_integral(a, b, p - 1.0)
            return total
        sigma = math.sqrt(math.log1p(self.polydispersity ** 2))
        mu = math.log(self.mean) - 0.5 * sigma ** 2
        # truncated normal in ln D by number: E_N[D^q] = exp(q mu + q^2 sigma^2 / 2) Z(q) / Z(0)
        def number_mean(q: float) -> float:
            lo, hi = -self.cut - q * sigma, self.cut - q * sigma
            mass = special.ndtr(hi) - special.ndtr(lo)
            return math.exp(q * mu + 0.5 * (q * sigma) ** 2) * mass / (special.ndtr(self.cut) - special.ndtr(-self.cut))
        return number_mean(3.0 + p) / number_mean(3.0)

    def _sieve_quantile(self, q: np.ndarray) -> np.ndarray:
        """Inverse number CDF of a sieve table: on each interval ``dP = c dlnD``, so the number
        density is ``∝ c D^-4`` and its integral is a power law, inverted interval by interval
        (the intervals with nothing passing take no grain)."""
        s, p = np.array(self.sieves), np.array(self.passing)
        keep = np.diff(p) > 0
        lo, hi = s[:-1][keep], s[1:][keep]
        c = np.diff(p)[keep] / np.log(hi / lo)
        mass = c * (lo ** -3.0 - hi ** -3.0) / 3.0  # grains by number in each interval (unnormalised)
        cumulative = np.concatenate([[0.0], np.cumsum(mass)]) / mass.sum()
        k = np.clip(np.searchsorted(cumulative, q, side="right") - 1, 0, len(mass) - 1)
        local = (q - cumulative[k]) / (cumulative[k + 1] - cumulative[k])
        return _power_quantile(np.clip(local, 0.0, 1.0), lo[k], hi[k], -4.0)

    def _lognormal_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sizes on a log grid with the number and volume CDFs there (for the lognormal)."""
        sigma = math.sqrt(math.log1p(self.polydispersity ** 2))
        mu = math.log(self.mean) - 0.5 * sigma ** 2
        z = np.linspace(-self.cut, self.cut, _TABLE_POINTS)
        grid = np.exp(mu + sigma * z)
        number = (special.ndtr(z) - special.ndtr(-self.cut)) / (special.ndtr(self.cut) - special.ndtr(-self.cut))
        # by volume: ln D normal of mean mu + 3 sigma^2, the same truncation in D
        zv = z - 3.0 * sigma
        volume = (special.ndtr(zv) - special.ndtr(zv[0])) / (special.ndtr(zv[-1]) - special.ndtr(zv[0]))
        return grid, number, volume


def _power_integral(a: float, b: float, e: float) -> float:
    """:math:`\\int_a^b D^e dD`."""
    if abs(e + 1.0) < 1e-12:
        return math.log(b / a)
    return (b ** (e + 1.0) - a ** (e + 1.0)) / (e + 1.0)


def _power_quantile(q, a, b, e):
    """The inverse CDF of a density ``∝ D^e`` on ``[a, b]``."""
    if np.isscalar(e) and abs(e + 1.0) < 1e-12:
        return a * (b / a) ** q
    k = e + 1.0
    return (a ** k + q * (b ** k - a ** k)) ** (1.0 / k)


def achieved_passing(sizes: np.ndarray, volumes: np.ndarray, at) -> np.ndarray:
    """The sieve curve of a set of grains: the share of their volume in grains smaller than each of
    ``at`` (a grain of size exactly ``D`` counts as passing ``D``)."""
    order = np.argsort(sizes, kind="stable")
    d, v = np.asarray(sizes)[order], np.asarray(volumes)[order]
    cumulative = np.concatenate([[0.0], np.cumsum(v)]) / v.sum()
    return cumulative[np.searchsorted(d, np.asarray(at, dtype=np.float64), side="right")]


def largest_deviation(grading: Grading, sizes: np.ndarray, volumes: np.ndarray) -> float:
    """The largest gap between the requested and the achieved sieve curves, over the grains' sizes
    (the Kolmogorov distance of the two volume distributions)."""
    d = np.sort(np.asarray(sizes))
    requested = grading.passing_at(d)
    after = achieved_passing(sizes, volumes, d)
    before = np.concatenate([[0.0], after[:-1]])
    return float(max(np.max(np.abs(after - requested)), np.max(np.abs(before - requested))))

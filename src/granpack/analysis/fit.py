"""Exponential fit of a coordination number against nematic order (docs/method/analysis.md#n-versus-q00-fit).

.. math:: N(Q) = N_0 + (N_1 - N_0)\\,(1 - e^{-Q/Q_c})

fitted by bounded non-linear least squares (``scipy.optimize.curve_fit``; ``N0, N1 >= 0``,
``Qc > 0``; start ``N0`` = N at the smallest Q, ``N1`` = max N, ``Qc = 0.2``). Standard errors are
the square roots of the covariance diagonal; ``R^2 = 1 - SS_res / SS_tot``; an optional bootstrap
over the packings (resampling points with replacement) gives a second spread estimate: the
standard deviation of the resampled fits and, less swayed by the few resamples of a small set that
miss the points pinning a parameter (and fit it far off), the central 68 % of them.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.optimize import OptimizeWarning, curve_fit

from granpack.analysis._base import Compute, NotComputedError, result

__all__ = ["ExponentialFit", "exponential_model"]


def exponential_model(q, n0: float, n1: float, qc: float):
    """:math:`N_0 + (N_1 - N_0)(1 - e^{-Q/Q_c})`."""
    return n0 + (n1 - n0) * (1.0 - np.exp(-np.asarray(q, dtype=np.float64) / qc))


def _fit(q: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p0 = [max(float(n[np.argmin(q)]), 1e-9), max(float(n.max()), 1e-9), 0.2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OptimizeWarning)
        params, cov = curve_fit(exponential_model, q, n, p0=p0, bounds=([0.0, 0.0, 1e-9], [np.inf, np.inf, np.inf]), maxfev=20000)
    return params, cov


class ExponentialFit(Compute):
    """Fit of ``N(Q)`` over packings.

    Args:
        n_bootstrap: bootstrap resamples (0: none).
        seed: seed of the bootstrap resampling.

    Example::

        fit = ExponentialFit().compute(q00_values, n_values)
        fit.N0, fit.N1, fit.Qc, fit.stderr, fit.r_squared
    """

    def __init__(self, n_bootstrap: int = 0, seed: int = 0):
        self.n_bootstrap = int(n_bootstrap)
        self.seed = int(seed)

    def compute(self, q, n) -> "ExponentialFit":
        """Fit ``n`` (coordination of each packing) against ``q`` (its Q00).

        Args:
            q: ``(K,)`` order parameters.
            n: ``(K,)`` coordination numbers.
        """
        self._start()
        q = np.asarray(q, dtype=np.float64).ravel()
        n = np.asarray(n, dtype=np.float64).ravel()
        if q.shape != n.shape:
            raise ValueError(f"q and n must have the same length, got {len(q)} and {len(n)}")
        ok = np.isfinite(q) & np.isfinite(n)
        q, n = q[ok], n[ok]
        self._q, self._n = q, n
        self._params = np.full(3, math.nan)
        self._stderr = np.full(3, math.nan)
        self._boot = np.full(3, math.nan)
        self._boot_range = np.full((2, 3), math.nan)
        self._r2 = self._rms = math.nan
        if len(q) < 3:
            self._warn(f"an exponential fit needs at least 3 packings, got {len(q)}: parameters are nan")
            return self._done()
        try:
            params, cov = _fit(q, n)
        except RuntimeError as exc:
            self._warn(f"exponential fit did not converge ({exc})")
            return self._done()
        self._params = params
        self._stderr = np.sqrt(np.clip(np.diag(cov), 0.0, np.inf)) if np.all(np.isfinite(cov)) else np.full(3, math.nan)
        residual = n - exponential_model(q, *params)
        ss_tot = float(((n - n.mean()) ** 2).sum())
        self._r2 = 1.0 - float((residual**2).sum()) / ss_tot if ss_tot > 0 else math.nan
        self._rms = float(np.sqrt((residual**2).mean()))
        if self.n_bootstrap > 0:
            rng = np.random.default_rng(self.seed)
            samples = []
            for _ in range(self.n_bootstrap):
                pick = rng.integers(0, len(q), len(q))
                if len(np.unique(q[pick])) < 3:
                    continue
                try:
                    samples.append(_fit(q[pick], n[pick])[0])
                except RuntimeError:
                    continue
            if len(samples) > 1:
                self._boot = np.std(samples, axis=0, ddof=1)
                self._boot_range = np.percentile(samples, [15.87, 84.13], axis=0)
        return self._done()

    @result
    def N0(self) -> float:
        """Value at Q = 0 (isotropic packing)."""
        return float(self._params[0])

    @result
    def N1(self) -> float:
        """Asymptote for strong order."""
        return float(self._params[1])

    @result
    def Qc(self) -> float:
        """Order scale."""
        return float(self._params[2])

    @result
    def stderr(self) -> dict:
        """Standard errors ``{N0, N1, Qc}`` from the covariance."""
        return dict(zip(("N0", "N1", "Qc"), map(float, self._stderr)))

    @result
    def bootstrap_std(self) -> dict:
        """Bootstrap standard deviations ``{N0, N1, Qc}`` (nan without bootstrap)."""
        return dict(zip(("N0", "N1", "Qc"), map(float, self._boot)))

    @result
    def bootstrap_interval(self) -> dict:
        """The central 68 % of the bootstrap fits, ``{N0: (low, high), N1: ..., Qc: ...}`` (the
        16th and 84th percentiles: plus or minus one standard deviation for a normal spread; nan
        without bootstrap). On a few packings, a resample that misses the points pinning a
        parameter fits it far off: the standard deviation follows those, this range does not."""
        return {name: (float(self._boot_range[0, k]), float(self._boot_range[1, k]))
                for k, name in enumerate(("N0", "N1", "Qc"))}

    @result
    def r_squared(self) -> float:
        """Coefficient of determination."""
        return self._r2

    @result
    def rms(self) -> float:
        """Root-mean-square residual."""
        return self._rms

    def predict(self, q):
        """Model values at ``q`` with the fitted parameters."""
        if not self._computed:
            raise NotComputedError("ExponentialFit.predict is available after compute()")
        return exponential_model(q, *self._params)

    def plot(self, ax):
        """Data points and the fitted curve on ``ax`` (pyplot-free: no figure is created); returns ``ax``."""
        ax.plot(self._q, self._n, "o", label="packings")
        if np.all(np.isfinite(self._params)):
            qq = np.linspace(0.0, max(float(self._q.max()), 1e-3) * 1.05, 200)
            ax.plot(qq, self.predict(qq), "-", label=f"fit, Qc = {self.Qc:.3g}")
        ax.set_xlabel(r"$Q^2_{00}$")
        ax.set_ylabel("N")
        ax.legend(loc="best")
        return ax

"""Exponential fit N(Q) (docs/method/analysis.md#n-versus-q00-fit) on synthetic data with known parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from granpack.analysis import AnalysisWarning, ExponentialFit, NotComputedError
from granpack.analysis.fit import exponential_model

TRUE = {"N0": 10.4, "N1": 13.1, "Qc": 0.15}


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        ExponentialFit().N0
    with pytest.raises(NotComputedError):
        ExponentialFit().predict([0.1])


def test_noiseless_data_is_recovered_exactly():
    q = np.linspace(0.0, 0.8, 12)
    fit = ExponentialFit().compute(q, exponential_model(q, *TRUE.values()))
    assert [fit.N0, fit.N1, fit.Qc] == pytest.approx(list(TRUE.values()), rel=1e-7)
    assert fit.r_squared == pytest.approx(1.0, abs=1e-12)
    assert fit.rms < 1e-7


def test_noisy_data_recovers_parameters_within_errors(rng):
    q = np.repeat(np.linspace(0.02, 0.8, 15), 3)  # three replicas per mixture
    sigma = 0.05
    n = exponential_model(q, *TRUE.values()) + sigma * rng.standard_normal(len(q))
    fit = ExponentialFit(n_bootstrap=50, seed=1).compute(q, n)
    for name, value in TRUE.items():
        got = getattr(fit, name)
        assert abs(got - value) < 4 * fit.stderr[name], name
        assert fit.stderr[name] > 0 and math.isfinite(fit.bootstrap_std[name])
    assert fit.N0 == pytest.approx(TRUE["N0"], abs=0.1)
    assert fit.N1 == pytest.approx(TRUE["N1"], abs=0.1)
    assert fit.Qc == pytest.approx(TRUE["Qc"], rel=0.2)
    assert 0.97 < fit.r_squared < 1.0
    assert fit.rms == pytest.approx(sigma, rel=0.3)
    np.testing.assert_allclose(fit.predict([0.0]), [fit.N0])


def test_bootstrap_interval_of_seven_packings_is_not_swayed_by_a_few_far_off_resamples():
    """On seven packings a few resamples miss the least-ordered ones and fit N0 far off: their
    standard deviation is several times the range that holds the middle 68 % of the resampled
    fits, which brackets the fit."""
    q = np.array([0.02, 0.15, 0.3, 0.45, 0.6, 0.75, 0.85])
    n = exponential_model(q, 8.2, 9.4, 0.3) + 0.15 * np.random.default_rng(1).standard_normal(len(q))
    fit = ExponentialFit(n_bootstrap=500, seed=1).compute(q, n)
    for name in ("N0", "N1", "Qc"):
        low, high = fit.bootstrap_interval[name]
        assert low <= getattr(fit, name) <= high, name
    low, high = fit.bootstrap_interval["N0"]
    assert 0 < high - low < fit.bootstrap_std["N0"] / 2
    assert all(math.isnan(v) for v in ExponentialFit().compute(q, n).bootstrap_interval["N0"])


def test_too_few_points_give_nan_and_warning():
    with pytest.warns(AnalysisWarning, match="at least 3"):
        fit = ExponentialFit().compute([0.1, float("nan"), 0.3], [10.0, 11.0, 12.0])
    assert math.isnan(fit.N0) and math.isnan(fit.r_squared)
    with pytest.raises(ValueError):
        ExponentialFit().compute([0.1, 0.2], [1.0])

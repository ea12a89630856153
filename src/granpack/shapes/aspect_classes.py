"""Aspect-ratio classes: a distribution of (L/G, G/E) as a finite set of classes with number weights.

Method (docs/method/grains.md#aspect-ratio-distributions). A population whose aspect ratios vary
grain by grain is packed as a population of several shapes, one per class, each grain's class
drawn from the seed in proportion to the weights (:class:`granpack.mixture.Mixture`), so the
engine's per-shape tables hold one shape per class, not one per grain. The classes come from

- a table of rows ``(L/G, G/E, weight)`` (a flakiness / elongation test's classes): one class per
  row, its weight the row's share of the weights;
- two lognormals: :math:`\\ln(L/G) \\sim N(\\ln m_e, s_e^2)` and :math:`\\ln(G/E) \\sim
  N(\\ln m_f, s_f^2)`, independent, each truncated to ratios >= 1 and cut into ``classes``
  classes of equal probability, a class at the truncated distribution's quantile
  :math:`(i + 1/2)/k` (the median of its class): ``k_e k_f`` classes of weight
  :math:`1/(k_e k_f)`, one class for a ratio of spread 0.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["table_classes", "lognormal_classes", "lognormal_quantiles", "MAX_CLASSES", "MAX_CLASSES_PER_RATIO",
           "DEFAULT_CLASSES_PER_RATIO"]

#: most classes of one population, rows of a table (each is a shape of the engine's tables)
MAX_CLASSES = 64
#: most classes per ratio of two lognormals (their product at most :data:`MAX_CLASSES`)
MAX_CLASSES_PER_RATIO = 8
#: classes per ratio of two lognormals by default (16 shapes)
DEFAULT_CLASSES_PER_RATIO = 4


def lognormal_quantiles(median: float, log_sd: float, classes: int) -> np.ndarray:
    """``(k,)`` the ratios at quantiles ``(i + 1/2)/k`` of the lognormal of ``median`` (of the
    untruncated law, >= 1) and ``log_sd`` (standard deviation of the log) truncated to ratios >= 1;
    ``[median]`` when ``log_sd`` is 0."""
    if log_sd == 0:
        return np.array([float(median)])
    from scipy.stats import truncnorm  # here: scipy.stats takes 0.6 s to import, which no run should pay

    mu = math.log(median)
    law = truncnorm(-mu / log_sd, np.inf, loc=mu, scale=log_sd)
    return np.exp(law.ppf((np.arange(classes) + 0.5) / classes))


def lognormal_classes(elongation: tuple[float, float], flatness: tuple[float, float],
                      classes: int) -> list[tuple[tuple[float, float], float]]:
    """Classes ``((L/G, G/E), weight)`` of two truncated lognormals (module docstring), each given as
    ``(median, log_sd)``; elongation varies slowest."""
    e = lognormal_quantiles(*elongation, classes)
    f = lognormal_quantiles(*flatness, classes)
    weight = 1.0 / (len(e) * len(f))
    return [((float(a), float(b)), weight) for a in e for b in f]


def table_classes(rows) -> list[tuple[tuple[float, float], float]]:
    """Classes ``((L/G, G/E), weight)`` of table rows ``(L/G, G/E, weight)``, weights normalised to sum 1."""
    total = math.fsum(r[2] for r in rows)
    return [((float(r[0]), float(r[1])), float(r[2]) / total) for r in rows]

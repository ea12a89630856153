"""Common machinery of the compute objects (freud style: ``Q(options).compute(packing)`` -> self).

Results are read-only properties that raise :class:`NotComputedError` before ``compute``.
Degenerate inputs (too thin for a bulk region, no contacts, one grain) never raise: they give
``nan`` figures, an :class:`AnalysisWarning`, and a line in ``obj.warnings``.

A quantity's ``to_dict()`` is its part of ``analysis.json``; the figure functions of the modules
read that part either as ``to_dict()`` returns it (NumPy arrays, ``nan``) or as the file holds it
(lists, ``null``), through :func:`as_array`.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np

__all__ = ["AnalysisWarning", "NotComputedError", "Compute", "result", "as_array", "any_finite"]


class AnalysisWarning(UserWarning):
    """A figure could not be computed meaningfully (it is ``nan``)."""


class NotComputedError(RuntimeError):
    """A result was read before ``compute()`` was called."""


class Compute:
    """Base of the compute objects: tracks whether ``compute`` ran and collects warnings."""

    _computed: bool = False

    def _start(self) -> None:
        self._computed = False
        self._warnings: list[str] = []

    def _done(self):
        self._computed = True
        return self

    def _warn(self, message: str) -> None:
        self._warnings.append(message)
        warnings.warn(message, AnalysisWarning, stacklevel=3)

    @property
    def warnings(self) -> list[str]:
        """Messages about figures that are ``nan`` (empty when everything was computed)."""
        if not self._computed:
            raise NotComputedError(f"{type(self).__name__}.warnings is available after compute()")
        return list(self._warnings)


def result(func):
    """A read-only property that raises :class:`NotComputedError` before ``compute``."""

    @functools.wraps(func)
    def getter(self):
        if not self._computed:
            raise NotComputedError(f"{type(self).__name__}.{func.__name__} is available after compute()")
        return func(self)

    return property(getter)


def as_array(value) -> np.ndarray:
    """A list (``None`` -> nan, as JSON's ``null``) or array of numbers as a float array; anything
    else (absent, a scalar, a mapping) -> an empty array, so that a figure reading an incomplete
    ``analysis.json`` finds no data instead of failing."""
    if isinstance(value, np.ndarray):
        return value.astype(float)
    if not isinstance(value, list):
        return np.zeros(0)
    return np.array([math.nan if v is None else v for v in value], dtype=float)


def any_finite(values: np.ndarray) -> bool:
    """Whether ``values`` holds at least one finite number."""
    return bool(len(values)) and bool(np.isfinite(values).any())

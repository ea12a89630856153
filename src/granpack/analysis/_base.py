"""Common machinery of the compute objects (freud style: ``Q(options).compute(packing)`` -> self).

Results are read-only properties that raise :class:`NotComputedError` before ``compute``.
Degenerate inputs (too thin for a bulk region, no contacts, one grain) never raise: they give
``nan`` figures, an :class:`AnalysisWarning`, and a line in ``obj.warnings``.
"""

from __future__ import annotations

import functools
import warnings

__all__ = ["AnalysisWarning", "NotComputedError", "Compute", "result"]


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

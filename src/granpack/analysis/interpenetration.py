"""Interpenetration of the rigid grains and the virtual-work expansion coefficient k.

Definitions: docs/method/analysis.md#interpenetration-and-the-expansion-coefficient-k.

Overlaps are the contact-point gaps ``g < 0`` taken as positive depths ``δ = -g`` (in d). The
coefficient ``k`` is the vertical strain of a virtual affine expansion ``u_z = k (z - z_ref)`` that
would release the overlaps, from the balance of the work of gravity and of the contact forces:

.. math::

    k_{work} = \\frac{\\sum_\\alpha |f_{\\alpha,z}|\\, |\\delta_{\\alpha,z}|}{\\sum_p m_p g (z_p - z_{ref})},
    \\qquad
    k_{Love} = \\frac{\\sum_\\alpha |f_{\\alpha,z}|\\, |\\delta_{\\alpha,z}|}{\\sum_m F_{m,z}\\, \\ell_{m,z}},

with ``δ_α = -min(g_α, 0) n_α`` per contact point, ``F_m`` the manifold resultant on grain i and
``ℓ_m`` its branch vector (``x_i - (x_j + shift)``; ``(0, 0, z_i)`` for the wall). In static
equilibrium the Love identity :math:`\\sum_p m_p g z_p = \\sum_m F_{m,z} \\ell_{m,z}` makes the two
agree for the whole column (``z_ref = 0``, the wall). The study's value sums only over grains and
contact points more than ``n_bottom`` grain sizes above the wall (``expansion_k``, work form; the
Love form over that region is reported for comparison, it is not expected to match exactly).
``φ/(1 + k)`` bounds the solid fraction once the overlaps are released, so ``k`` is the relative
overestimate of φ attributable to interpenetration.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, result
from granpack.packing import Packing

__all__ = ["Interpenetration"]


def _safe_ratio(num: float, den: float) -> float:
    return float(num / den) if den > 0 else math.nan


class Interpenetration(Compute):
    """Overlap statistics and the expansion coefficient k.

    Args:
        n_bottom: the "bulk" sums start ``n_bottom`` grain sizes (largest) above the wall.
        deep: overlap depth (d) counted by :attr:`fraction_deep`.
    """

    def __init__(self, n_bottom: float = 2.0, deep: float = 1e-3):
        self.n_bottom = float(n_bottom)
        self.deep = float(deep)

    def compute(self, packing: Packing) -> "Interpenetration":
        """Compute overlap statistics and k for ``packing``."""
        self._start()
        c = packing.contacts
        state = packing.state
        g = packing.gravity
        overlap = np.maximum(-c.gap, 0.0)
        has = overlap > 0
        self._max = float(overlap.max()) if c.n_points else 0.0
        self._mean = float(overlap[has].mean()) if has.any() else 0.0
        self._fraction = float(has.mean()) if c.n_points else math.nan
        self._fraction_deep = float((overlap > self.deep).mean()) if c.n_points else math.nan

        seg = c.point_manifold
        f_z = packing.point_force[:, 2]
        delta_z = overlap * c.normal[seg, 2]
        work = np.abs(f_z) * np.abs(delta_z)
        z = state.position[:, 2]
        weight_moment = g * state.mass * z
        fm_z = packing.manifold_force[:, 2]
        love = fm_z * packing.branch_vectors()[:, 2]

        z0 = self.n_bottom * packing.max_size if state.n else 0.0
        point_bulk = c.point[:, 2] > z0
        manifold_bulk = packing.manifold_point[:, 2] > z0
        particle_bulk = z > z0
        self._k = {
            "work_column": _safe_ratio(work.sum(), weight_moment.sum()),
            "love_column": _safe_ratio(work.sum(), love.sum()),
            "work_bulk": _safe_ratio(work[point_bulk].sum(), weight_moment[particle_bulk].sum()),
            "love_bulk": _safe_ratio(work[point_bulk].sum(), love[manifold_bulk].sum()),
        }
        if c.n_points == 0:
            self._k = dict.fromkeys(self._k, math.nan)
            self._warn("no contact point: overlap statistics are 0 and k is nan")
        elif not particle_bulk.any():
            self._warn(f"no grain more than {self.n_bottom:g} d above the wall: the bulk k is nan")
        return self._done()

    @result
    def max(self) -> float:
        """Largest overlap depth, d (0 without overlap)."""
        return self._max

    @result
    def mean(self) -> float:
        """Mean overlap depth over the overlapping contact points, d (0 without overlap)."""
        return self._mean

    @result
    def fraction(self) -> float:
        """Share of the contact points that overlap."""
        return self._fraction

    @result
    def fraction_deep(self) -> float:
        """Share of the contact points overlapping by more than ``deep``."""
        return self._fraction_deep

    @result
    def expansion_k(self) -> float:
        """The study's k: work form, sums more than ``n_bottom`` d above the wall."""
        return self._k["work_bulk"]

    @result
    def k(self) -> dict:
        """All four estimates: ``work_column``, ``love_column``, ``work_bulk``, ``love_bulk``."""
        return dict(self._k)

    def to_dict(self) -> dict:
        """The ``interpenetration`` part of ``analysis.json``: ``max``, ``mean`` (d),
        ``expansion_k``, the four estimates ``k``, ``fraction_overlapping``, ``fraction_deep``, and
        ``phi_relative_overestimate`` (= ``expansion_k``: the share by which the overlaps raise the
        solid fraction)."""
        k = self.expansion_k
        return {
            "max": self.max,
            "mean": self.mean,
            "expansion_k": k,
            "k": self.k,
            "fraction_overlapping": self.fraction,
            "fraction_deep": self.fraction_deep,
            "phi_relative_overestimate": k,
        }

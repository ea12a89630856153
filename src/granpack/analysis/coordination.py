"""Coordination numbers by contact type, with and without rattlers (PHYSICS.md §5f).

A manifold (pair of grains, or grain and wall) is **force-bearing** when the normal component
of its resultant force exceeds ``f_tol = force_tol x`` the mean of the positive ones. Its type is
the manifold's ``ctype`` (1 simple, 2 double, 3 triple; classified by the rank of the manifold at
detection, §3.5). For the grains with centre in the bulk region (their contacts with grains
outside the bulk and with the wall count):

.. math:: N = \\langle n_p \\rangle, \\quad N_s, N_d, N_t \\text{ likewise per type}, \\quad N_c = N_s + 2 N_d + 3 N_t .

Rattlers (open question Q6; the rule chosen here): a bulk grain is a rattler when its force-bearing
constraints are fewer than ``f + 1`` — fewer than 4 contacts for a sphere (``f = 3``), fewer than
7 constraints ``n_s + 2 n_d + 3 n_t`` for a polyhedron (``f = 6``). Rattlers are removed with their
contacts and the rule is applied again until no bulk grain is removed. Grains outside the bulk are
never removed (they act as a boundary, like the wall, so that the open surface does not erode the
backbone). The main figures are those of the backbone (rattlers and their contacts removed);
``with_rattlers`` gives the same figures over all bulk grains.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, result
from granpack.analysis.solid_fraction import bulk_range
from granpack.packing import Packing

__all__ = ["Coordination", "force_bearing"]


def force_bearing(packing: Packing, force_tol: float = 1e-9) -> np.ndarray:
    """``(M,)`` True for manifolds whose normal resultant exceeds ``force_tol`` times the mean positive one."""
    fn = packing.manifold_normal_force
    positive = fn[fn > 0]
    if len(positive) == 0:
        return np.zeros(len(fn), bool)
    return fn > force_tol * positive.mean()


def _type_counts(packing: Packing, active: np.ndarray) -> np.ndarray:
    """``(N, 3)`` number of active manifolds of type 1, 2, 3 per grain (as i or as j)."""
    c = packing.contacts
    n = packing.n_particles
    out = np.zeros((n, 3))
    for t in range(3):
        sel = active & (c.ctype == t + 1)
        out[:, t] += np.bincount(c.body_i[sel], minlength=n)
        pair = sel & (c.body_j >= 0)
        out[:, t] += np.bincount(c.body_j[pair], minlength=n)
    return out


def _figures(counts: np.ndarray) -> dict:
    if len(counts) == 0:
        return {k: math.nan for k in ("N", "Ns", "Nd", "Nt", "Nc")}
    mean = counts.mean(axis=0)
    return {
        "N": float(mean.sum()),
        "Ns": float(mean[0]),
        "Nd": float(mean[1]),
        "Nt": float(mean[2]),
        "Nc": float(mean[0] + 2 * mean[1] + 3 * mean[2]),
    }


class Coordination(Compute):
    """Coordination numbers N, Ns, Nd, Nt, Nc of the bulk grains.

    Args:
        z_range: bulk ``(z_bottom, z_top)`` in d; the default bulk region if omitted.
        force_tol: relative threshold for force-bearing contacts.
        remove_rattlers: apply the iterative rattler rule (else ``rattler_fraction`` is 0).
    """

    def __init__(self, z_range: tuple[float, float] | None = None, force_tol: float = 1e-9, remove_rattlers: bool = True):
        self.z_range = z_range
        self.force_tol = float(force_tol)
        self.remove_rattlers = bool(remove_rattlers)

    def compute(self, packing: Packing) -> "Coordination":
        """Count the contacts of the bulk grains of ``packing``."""
        self._start()
        state = packing.state
        c = packing.contacts
        if self.z_range is None:
            z_bot, z_top, valid = bulk_range(packing)
        else:
            (z_bot, z_top), valid = self.z_range, self.z_range[1] > self.z_range[0]
        z = state.position[:, 2]
        analysed = (z >= z_bot) & (z <= z_top) if valid else np.zeros(state.n, bool)
        active = force_bearing(packing, self.force_tol)
        sphere = state.shapes.is_sphere[state.kind]
        needed = np.where(sphere, 4, 7)
        weights = np.array([1.0, 2.0, 3.0])

        removed = np.zeros(state.n, bool)
        counts = _type_counts(packing, active)
        self._with = _figures(counts[analysed])
        if self.remove_rattlers:
            while True:
                live = active & ~removed[c.body_i] & ~((c.body_j >= 0) & removed[np.maximum(c.body_j, 0)])
                counts = _type_counts(packing, live)
                constraints = np.where(sphere, counts.sum(axis=1), counts @ weights)
                new = analysed & ~removed & (constraints < needed)
                if not new.any():
                    break
                removed |= new
        self._rattlers = removed
        self._analysed = analysed
        self._counts = counts
        self._backbone = _figures(counts[analysed & ~removed])
        self._n = int(analysed.sum())
        if self._n == 0:
            self._warn("no grain in the bulk region: coordination numbers are nan")
        elif not active.any():
            self._warn("no force-bearing contact: every bulk grain is a rattler, backbone coordination numbers are nan")
        elif not (analysed & ~removed).any():
            self._warn("every bulk grain is a rattler: backbone coordination numbers are nan (see with_rattlers)")
        return self._done()

    @result
    def n_analysed(self) -> int:
        """Number of bulk grains."""
        return self._n

    @result
    def rattlers(self) -> np.ndarray:
        """``(N,)`` True for the grains removed as rattlers."""
        return self._rattlers.copy()

    @result
    def rattler_fraction(self) -> float:
        """Share of the bulk grains that are rattlers (nan without bulk grains)."""
        return float(self._rattlers.sum() / self._n) if self._n else math.nan

    @result
    def per_particle(self) -> np.ndarray:
        """``(N, 3)`` backbone contacts of type simple/double/triple per grain."""
        return self._counts.copy()

    @result
    def figures(self) -> dict:
        """Backbone figures ``{N, Ns, Nd, Nt, Nc}`` (rattlers removed)."""
        return dict(self._backbone)

    @result
    def with_rattlers(self) -> dict:
        """Figures ``{N, Ns, Nd, Nt, Nc}`` over all bulk grains and force-bearing contacts."""
        return dict(self._with)

    @result
    def N(self) -> float:
        """Mean number of force-bearing contacts per backbone grain."""
        return self._backbone["N"]

    @result
    def Nc(self) -> float:
        """Mean number of constraints ``Ns + 2 Nd + 3 Nt`` per backbone grain."""
        return self._backbone["Nc"]

    def plot(self, ax=None):
        """Histogram of the contacts per backbone grain; returns the axes."""
        import matplotlib.pyplot as plt

        ax = ax or plt.gca()
        keep = self._analysed & ~self._rattlers
        n = self._counts[keep].sum(axis=1).astype(int)
        if len(n):
            ax.hist(n, bins=np.arange(n.max() + 2) - 0.5)
        ax.set_xlabel("force-bearing contacts per grain")
        ax.set_ylabel("grains")
        return ax

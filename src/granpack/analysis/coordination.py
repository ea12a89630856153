"""Coordination numbers by contact type, with and without rattlers.

A manifold (pair of grains, or grain and wall) is **force-bearing** when the normal component
of its resultant force exceeds ``f_tol = force_tol x`` the mean of the positive ones. Only
force-bearing manifolds are counted. For the grains with centre in the bulk region (their
contacts with grains outside the bulk and with the wall count):

.. math:: N = \\langle n_p \\rangle, \\quad N_s, N_d, N_t \\text{ likewise per type}, \\quad N_c = N_s + 2 N_d + 3 N_t .

**Contact type** (1 simple, 2 double, 3 triple) is the rank of a subset of the manifold's points
as unilateral constraints: the in-plane singular-value rule of
:func:`granpack.contact.contact_types` (tolerance ``rank_tol x`` the smallest grain size, the
detection default). Three subsets are classified:

- ``force`` (the main figures): the **force-bearing points**, those whose normal force
  :math:`f_{n,k} = (\\mathbf{r}_k \\cdot \\mathbf{n}) / h` exceeds ``point_tol x`` the largest
  point normal force of the same manifold. A point that carries no load constrains nothing, so
  only the loaded points give the number of independent constraints of the contact; nearly
  parallel faces that touch along one edge carry force on the two points of the edge only, hence
  are double, not triple. See :func:`force_bearing_points` for why the threshold is relative to
  the manifold.
- ``gap_rule`` (cross-check): the points with gap ``<= gap_tol x`` the largest grain size, plus the
  manifold's closest point (so that every force-bearing manifold has a type).
- ``geometric``: the detection type ``ContactSet.ctype``, the rank of every point within the alert
  distance (it overcounts nearly parallel faces; kept for comparison).

Rattlers: a bulk grain is a rattler when its force-bearing constraints are fewer than ``f + 1`` —
fewer than 4 contacts for a sphere (``f = 3``), fewer than 7 constraints ``n_s + 2 n_d + 3 n_t``
for a polyhedron (``f = 6``). Rattlers are removed with their contacts and the rule is applied
again until no bulk grain is removed. Grains outside the bulk are never removed (they act as a
boundary, like the wall, so that the open surface does not erode the backbone). The rule depends
on the types, so each classification has its own backbone. The main figures are those of the
backbone (rattlers and their contacts removed); ``with_rattlers`` gives the same figures over all
bulk grains. Isostaticity of rigid frictionless grains predicts ``N = 6`` (spheres) and
``Nc = 12`` (polyhedra) on the backbone.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, NotComputedError, result
from granpack.analysis.solid_fraction import analysed_region, in_region
from granpack.contact.contacts import contact_types
from granpack.packing import Packing

__all__ = ["Coordination", "RULES", "force_bearing", "force_bearing_points", "near_points", "point_normal_force", "type_rules"]

#: the classifications of :func:`type_rules`, the first one gives the main figures
RULES = ("force", "gap_rule", "geometric")


def force_bearing(packing: Packing, force_tol: float = 1e-9) -> np.ndarray:
    """``(M,)`` True for manifolds whose normal resultant exceeds ``force_tol`` times the mean positive one."""
    fn = packing.manifold_normal_force
    positive = fn[fn > 0]
    if len(positive) == 0:
        return np.zeros(len(fn), bool)
    return fn > force_tol * positive.mean()


def _manifold_max(values: np.ndarray, point_start: np.ndarray) -> np.ndarray:
    """``(P,)`` the largest of ``values`` over the manifold of every point (CSR ``point_start``)."""
    counts = np.diff(point_start)
    out = np.full(len(values), -np.inf)
    nonempty = counts > 0
    if len(values):
        largest = np.maximum.reduceat(values, point_start[:-1][nonempty])
        out = np.repeat(largest, counts[nonempty])
    return out


def point_normal_force(packing: Packing) -> np.ndarray:
    """``(P,)`` normal force of every contact point, :math:`f_{n,k} = (\\mathbf{r}_k \\cdot \\mathbf{n}_m) / h`.

    In units of the packing's forces (impulse over the time step); > 0 compressive.
    """
    c = packing.contacts
    return np.einsum("ij,ij->i", packing.point_force, c.normal[c.point_manifold])


def force_bearing_points(packing: Packing, point_tol: float = 1e-3) -> np.ndarray:
    """``(P,)`` True for the points that carry a share of their manifold's load.

    A point is force-bearing when its normal force is positive and

    .. math:: f_{n,k} > \\mathrm{point\\_tol} \\cdot \\max_{k' \\in m} f_{n,k'}

    over the points of its manifold ``m``. The threshold is relative to the manifold, not to the
    packing, because the contact solver fixes a point's force only to within a small fraction of
    the forces it is balanced with (its convergence tolerance, 1e-4 by default, is relative), and
    the loads of a pile under gravity span orders of magnitude with depth, so that one packing-wide
    threshold would be either below the noise of the deep contacts or above the real forces of the
    shallow ones. It also keeps at least one point of every manifold whose resultant is
    compressive, so every force-bearing manifold has a type.

    Args:
        packing: the packing with its converged point impulses.
        point_tol: relative threshold (dimensionless, ``0 <= point_tol < 1``).

    Returns:
        ``(P,)`` bool.
    """
    if not 0.0 <= point_tol < 1.0:
        raise ValueError(f"point_tol must be in [0, 1), got {point_tol}")
    fn = point_normal_force(packing)
    return (fn > 0.0) & (fn > point_tol * _manifold_max(fn, packing.contacts.point_start))


def near_points(packing: Packing, gap_tol: float = 1e-4) -> np.ndarray:
    """``(P,)`` True for the points closer than ``gap_tol x`` the largest grain size, and for the
    closest point of every manifold.

    The geometric cross-check of :func:`force_bearing_points`: a point nearly touching is taken as
    a constraint whatever its force. The closest point is always kept so that a manifold whose gaps
    all exceed the tolerance (a contact closing during the step) still has a type.

    Args:
        packing: the packing.
        gap_tol: gap tolerance relative to the largest grain size (dimensionless).

    Returns:
        ``(P,)`` bool.
    """
    c = packing.contacts
    if c.n_points == 0:
        return np.zeros(0, bool)
    closest = -_manifold_max(-c.gap, c.point_start)
    return (c.gap <= gap_tol * packing.max_size) | (c.gap <= closest)


def type_rules(packing: Packing, point_tol: float = 1e-3, gap_tol: float = 1e-4, rank_tol: float = 1e-3) -> dict[str, np.ndarray]:
    """Contact type of every manifold under each rule of :data:`RULES`.

    Args:
        packing: the packing.
        point_tol: relative force threshold of :func:`force_bearing_points`.
        gap_tol: gap tolerance of :func:`near_points`, relative to the largest grain size.
        rank_tol: rank tolerance relative to the smallest grain size (detection uses the same).

    Returns:
        ``{"force": types, "gap_rule": types, "geometric": ctype}``, each ``(M,)`` int64 in
        1/2/3 (0 for a manifold with no selected point, i.e. one that carries no compressive force
        under the ``force`` rule).
    """
    c = packing.contacts
    eps = rank_tol * float(packing.particle_size.min()) if packing.n_particles else rank_tol
    return {
        "force": contact_types(c, eps, force_bearing_points(packing, point_tol)),
        "gap_rule": contact_types(c, eps, near_points(packing, gap_tol)),
        "geometric": np.asarray(c.ctype, np.int64).copy(),
    }


def _type_counts(packing: Packing, active: np.ndarray, ctype: np.ndarray) -> np.ndarray:
    """``(N, 3)`` number of active manifolds of type 1, 2, 3 per grain (as i or as j)."""
    c = packing.contacts
    n = packing.n_particles
    out = np.zeros((n, 3))
    for t in range(3):
        sel = active & (ctype == t + 1)
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


def _backbone(packing: Packing, active: np.ndarray, ctype: np.ndarray, analysed: np.ndarray, remove: bool):
    """Iterative rattler rule for one classification.

    Returns:
        ``(counts_all, counts_backbone, removed)``: ``(N, 3)`` active contacts per type and grain
        before and after removing the rattlers, and the ``(N,)`` rattler flags.
    """
    state = packing.state
    c = packing.contacts
    sphere = state.shapes.is_sphere[state.kind]
    needed = np.where(sphere, 4, 7)
    weights = np.array([1.0, 2.0, 3.0])
    removed = np.zeros(state.n, bool)
    counts_all = counts = _type_counts(packing, active, ctype)
    if remove:
        while True:
            live = active & ~removed[c.body_i] & ~((c.body_j >= 0) & removed[np.maximum(c.body_j, 0)])
            counts = _type_counts(packing, live, ctype)
            constraints = np.where(sphere, counts.sum(axis=1), counts @ weights)
            new = analysed & ~removed & (constraints < needed)
            if not new.any():
                break
            removed |= new
    return counts_all, counts, removed


class Coordination(Compute):
    """Coordination numbers N, Ns, Nd, Nt, Nc of the bulk grains.

    The main figures type each force-bearing manifold by the rank of its force-bearing points
    (:func:`force_bearing_points`); :attr:`by_rule` also gives them with the types of the gap rule
    and of detection (see the module docstring).

    Args:
        z_range: bulk ``(z_bottom, z_top)`` in d; the default bulk region if omitted.
        force_tol: relative threshold for force-bearing contacts (of the mean positive manifold
            normal force).
        remove_rattlers: apply the iterative rattler rule (else ``rattler_fraction`` is 0).
        point_tol: relative threshold of force-bearing points within a manifold
            (:func:`force_bearing_points`).
        gap_tol: gap tolerance of the cross-check, relative to the largest grain size
            (:func:`near_points`).
        rank_tol: rank tolerance of the types, relative to the smallest grain size.
    """

    def __init__(self, z_range: tuple[float, float] | None = None, force_tol: float = 1e-9, remove_rattlers: bool = True,
                 point_tol: float = 1e-3, gap_tol: float = 1e-4, rank_tol: float = 1e-3):
        self.z_range = z_range
        self.force_tol = float(force_tol)
        self.remove_rattlers = bool(remove_rattlers)
        self.point_tol = float(point_tol)
        self.gap_tol = float(gap_tol)
        self.rank_tol = float(rank_tol)

    def compute(self, packing: Packing) -> "Coordination":
        """Count the contacts of the bulk grains of ``packing``."""
        self._start()
        analysed = in_region(packing, analysed_region(packing, self.z_range))
        active = force_bearing(packing, self.force_tol)
        types = type_rules(packing, self.point_tol, self.gap_tol, self.rank_tol)
        self._n = int(analysed.sum())
        self._by_rule = {}
        for rule in RULES:
            counts_all, counts, removed = _backbone(packing, active, types[rule], analysed, self.remove_rattlers)
            same = types[rule][active] == types["force"][active]
            self._by_rule[rule] = {
                **_figures(counts[analysed & ~removed]),
                "rattler_fraction": float(removed.sum() / self._n) if self._n else math.nan,
                "with_rattlers": _figures(counts_all[analysed]),
                "same_type_as_force": float(same.mean()) if len(same) else math.nan,
            }
            if rule == "force":
                self._with = _figures(counts_all[analysed])
                self._backbone = _figures(counts[analysed & ~removed])
                self._rattlers, self._counts = removed, counts
        self._types = types
        self._analysed = analysed
        removed = self._rattlers
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
    def types(self) -> np.ndarray:
        """``(M,)`` type 1/2/3 of every manifold from its force-bearing points (0: no compressive point)."""
        return self._types["force"].copy()

    @result
    def by_rule(self) -> dict:
        """Figures under each classification of :data:`RULES`.

        ``{rule: {N, Ns, Nd, Nt, Nc, rattler_fraction, with_rattlers, same_type_as_force}}``:
        backbone figures with that rule's types (and its own rattlers), the figures over all bulk
        grains, and the share of the force-bearing manifolds (whole packing) typed as by the
        ``force`` rule. ``by_rule["force"]`` repeats the main figures.
        """
        return {rule: {**v, "with_rattlers": dict(v["with_rattlers"])} for rule, v in self._by_rule.items()}

    def figures_of(self, grains: np.ndarray) -> dict:
        """Backbone figures ``{N, Ns, Nd, Nt, Nc}`` of the bulk grains flagged in ``grains`` ``(N,)``
        (a population, a shape class), with their ``rattler_fraction`` and ``n_analysed``; their
        contacts with every other grain count."""
        if not self._computed:
            raise NotComputedError("Coordination.figures_of is available after compute()")
        analysed = self._analysed & grains
        n = int(analysed.sum())
        return {**_figures(self._counts[analysed & ~self._rattlers]), "n_analysed": n,
                "rattler_fraction": float((analysed & self._rattlers).sum() / n) if n else math.nan}

    @result
    def N(self) -> float:
        """Mean number of force-bearing contacts per backbone grain."""
        return self._backbone["N"]

    @result
    def Nc(self) -> float:
        """Mean number of constraints ``Ns + 2 Nd + 3 Nt`` per backbone grain."""
        return self._backbone["Nc"]

    def to_dict(self) -> dict:
        """The ``coordination`` part of ``analysis.json``: the backbone figures
        (:attr:`~granpack.analysis.coordination.Coordination.figures`), ``rattler_fraction``,
        ``with_rattlers``, ``n_analysed``, the settings the types were drawn with (``force_tol``,
        ``type_rule``, ``point_tol``, ``gap_tol``, ``rank_tol``), and the figures of the
        cross-check classifications ``gap_rule`` and ``geometric`` (:attr:`by_rule`)."""
        by_rule = self.by_rule
        return {
            **self.figures,
            "rattler_fraction": self.rattler_fraction,
            "with_rattlers": self.with_rattlers,
            "n_analysed": self.n_analysed,
            "force_tol": self.force_tol,
            "type_rule": "force-bearing points",
            "point_tol": self.point_tol,
            "gap_tol": self.gap_tol,
            "rank_tol": self.rank_tol,
            "gap_rule": by_rule["gap_rule"],
            "geometric": by_rule["geometric"],
        }

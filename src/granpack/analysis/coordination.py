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

Rattlers (frictionless rule, friction μ = 0): a bulk grain is a rattler when its force-bearing
constraints are fewer than ``f + 1`` — fewer than 4 contacts for a sphere (``f = 3``: its rotations
are free), fewer than 7 constraints ``n_s + 2 n_d + 3 n_t`` for a polyhedron (``f = 6``). Rattlers
are removed with their contacts and the rule is applied again until no bulk grain is removed.
Grains outside the bulk are never removed (they act as a boundary, like the wall, so that the open
surface does not erode the backbone). The rule depends on the types, so each classification has
its own backbone. The main figures are those of the backbone (rattlers and their contacts
removed); ``with_rattlers`` gives the same figures over all bulk grains. Isostaticity of rigid
frictionless grains predicts ``N = 6`` (spheres) and ``Nc = 12`` (polyhedra) on the backbone.

**Frictional rule** (μ > 0: the packing's :attr:`~granpack.packing.Packing.friction`, the run's
``solver.friction``, or the ``friction`` given). A force-bearing point then carries a force anywhere
in its Coulomb cone, three components, and a sphere's contacts turn it, so spheres and polyhedra
alike have ``f = 6``:

- **Rattlers**: a grain under gravity is held only when its force-bearing points can balance any
  force and torque, which needs three points not on one line (two points leave the turn about the
  line through them free: a sphere on two contacts rolls about it). A bulk grain is a rattler when
  ``n_s + 2 n_d + 3 n_t < 3`` (fewer than 3 contacts for a sphere); a cube resting on one face (a
  triple contact) is held. Points on one line are not looked for: three separate contacts on one
  line, or a double and a simple contact in line, are exceptional, and a sphere's never are. The
  same iteration and boundary as above.
- **Constraints**: the independent force components of a contact, the rank of the forces its
  points can exert on a grain: 3 for a simple contact, 5 for a double one (the two points' forces
  along the edge between them cancel), 6 for a triple one (frictionless: 1, 2, 3).
  ``constraints_per_grain`` ``C = 3 N_s + 5 N_d + 6 N_t`` (frictionless ``N_s + 2 N_d + 3 N_t``)
  on the backbone, against the isostatic ``C = 2 f = 12`` (frictionless: 6 for a sphere, 12 for a
  polyhedron, averaged over the backbone grains); ``hyperstaticity`` ``(C - C_iso) / 2`` is the
  excess of contact force unknowns over equilibrium equations per grain. With simple contacts only
  the isostatic count is ``N = 4`` (3 N / 2 = 6), the lower bound of rigid frictional spheres
  (Agnolin & Roux, Phys. Rev. E 76, 061302 (2007), find 4.5 at μ = 0.3 on the force-carrying
  backbone). Without
  gravity two opposite forces hold a grain, and their rattlers are the grains without force; under
  gravity every grain carries its weight, hence the three points.
- **Sliding contacts**: a force-bearing contact of a backbone grain slides when its resultant is on
  the Coulomb cone, ``|F_T| >= (1 - slide_tol) μ F_n`` (:func:`mobilisation`; ``slide_tol`` 1e-3,
  ten times the solver's relative tolerance). Each point's force stays in its own cone, so the
  resultant reaches the cone only when every point of the contact slides the same way.
"""

from __future__ import annotations

import math

import numpy as np

from granpack.analysis._base import Compute, NotComputedError, result
from granpack.analysis.solid_fraction import analysed_region, in_region
from granpack.contact.contacts import contact_types
from granpack.packing import Packing

__all__ = ["COMPONENTS", "Coordination", "RULES", "force_bearing", "force_bearing_points", "mobilisation", "near_points",
           "point_normal_force", "type_rules"]

#: the classifications of :func:`type_rules`, the first one gives the main figures
RULES = ("force", "gap_rule", "geometric")

#: independent force components of a force-bearing contact of type simple, double, triple, under
#: each rattler rule (module docstring)
COMPONENTS = {"frictionless": np.array([1.0, 2.0, 3.0]), "frictional": np.array([3.0, 5.0, 6.0])}

#: force-bearing points (``n_s + 2 n_d + 3 n_t``) below which a grain is a frictional rattler
FRICTIONAL_LEAST_POINTS = 3


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


def mobilisation(packing: Packing, friction: float) -> np.ndarray:
    """``(M,)`` how far each manifold's resultant is up its Coulomb cone, :math:`|F_T| / (\\mu F_n)`.

    :math:`F_n = \\mathbf F_m \\cdot \\mathbf n_m` and :math:`F_T = |\\mathbf F_m - F_n \\mathbf n_m|`
    from the resultant force :math:`\\mathbf F_m` of the manifold's point impulses over the step
    (:attr:`~granpack.packing.Packing.manifold_force`): 0 for a contact without tangential force, 1
    on the cone (sliding); dimensionless. Each point's force stays in its cone, so the resultant's
    ratio is at most 1, and 1 only when every point slides the same way. ``nan`` where
    :math:`F_n \\le 0`.

    Args:
        packing: the packing with its converged point impulses.
        friction: the Coulomb coefficient μ > 0.
    """
    if not friction > 0:
        raise ValueError(f"friction must be > 0, got {friction}")
    force, normal = packing.manifold_force, packing.contacts.normal
    fn = np.einsum("ij,ij->i", force, normal)
    ft = np.linalg.norm(force - fn[:, None] * normal, axis=1)
    out = np.full(len(fn), math.nan)
    loaded = fn > 0
    out[loaded] = ft[loaded] / (friction * fn[loaded])
    return out


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


def _kept(packing: Packing, active: np.ndarray, removed: np.ndarray) -> np.ndarray:
    """``(M,)`` the ``active`` manifolds neither of whose grains is ``removed`` (the wall never is)."""
    c = packing.contacts
    return active & ~removed[c.body_i] & ~((c.body_j >= 0) & removed[np.maximum(c.body_j, 0)])


def _held(packing: Packing, counts: np.ndarray, frictional: bool) -> np.ndarray:
    """``(N,)`` True for the grains whose force-bearing contacts ``counts`` ``(N, 3)`` (per type)
    hold them under the rattler rule (module docstring): frictional, at least
    :data:`FRICTIONAL_LEAST_POINTS` points ``n_s + 2 n_d + 3 n_t``; frictionless, 4 contacts for a
    sphere and 7 constraints ``n_s + 2 n_d + 3 n_t`` for a polyhedron."""
    weights = COMPONENTS["frictionless"]
    if frictional:
        return counts @ weights >= FRICTIONAL_LEAST_POINTS
    sphere = packing.state.shapes.is_sphere[packing.state.kind]
    return np.where(sphere, counts.sum(axis=1), counts @ weights) >= np.where(sphere, 4, 7)


def _backbone(packing: Packing, active: np.ndarray, ctype: np.ndarray, analysed: np.ndarray, remove: bool,
              frictional: bool):
    """Iterative rattler rule (:func:`_held`) for one classification.

    Returns:
        ``(counts_all, counts_backbone, removed)``: ``(N, 3)`` active contacts per type and grain
        before and after removing the rattlers, and the ``(N,)`` rattler flags.
    """
    removed = np.zeros(packing.n_particles, bool)
    counts_all = counts = _type_counts(packing, active, ctype)
    if remove:
        while True:
            counts = _type_counts(packing, _kept(packing, active, removed), ctype)
            new = analysed & ~removed & ~_held(packing, counts, frictional)
            if not new.any():
                break
            removed |= new
    return counts_all, counts, removed


def _constraint_figures(packing: Packing, counts: np.ndarray, grains: np.ndarray, frictional: bool) -> dict:
    """``{constraints_per_grain, isostatic_constraints, hyperstaticity}`` of the backbone grains
    flagged in ``grains`` ``(N,)``, whose force-bearing contacts per type are ``counts`` ``(n, 3)``
    (module docstring): the mean of their contacts' independent force components
    (:data:`COMPONENTS`), the mean of ``2 f`` (frictional: 12; frictionless: 6 for a sphere, 12 for
    a polyhedron) and half their difference; nan without grains."""
    if len(counts) == 0:
        return {"constraints_per_grain": math.nan, "isostatic_constraints": math.nan, "hyperstaticity": math.nan}
    constraints = float((counts @ COMPONENTS["frictional" if frictional else "frictionless"]).mean())
    sphere = packing.state.shapes.is_sphere[packing.state.kind[grains]]
    isostatic = 12.0 if frictional else float(np.where(sphere, 6.0, 12.0).mean())
    return {"constraints_per_grain": constraints, "isostatic_constraints": isostatic,
            "hyperstaticity": 0.5 * (constraints - isostatic)}


def _sliding_figures(packing: Packing, kept: np.ndarray, backbone: np.ndarray, friction: float, slide_tol: float) -> dict:
    """``{sliding_fraction, mean_mobilisation, n_contacts}`` over the ``kept`` force-bearing
    manifolds ``(M,)`` that touch a grain flagged in ``backbone`` ``(N,)`` (the contacts ``N``
    counts): the share whose :func:`mobilisation` is at least ``1 - slide_tol``, and its mean;
    nan when frictionless or without such contacts."""
    c = packing.contacts
    counted = kept & (backbone[c.body_i] | ((c.body_j >= 0) & backbone[np.maximum(c.body_j, 0)]))
    if not friction > 0 or not counted.any():
        return {"sliding_fraction": math.nan, "mean_mobilisation": math.nan, "n_contacts": int(counted.sum())}
    ratio = mobilisation(packing, friction)[counted]
    return {"sliding_fraction": float((ratio >= 1.0 - slide_tol).mean()), "mean_mobilisation": float(ratio.mean()),
            "n_contacts": int(counted.sum())}


class Coordination(Compute):
    """Coordination numbers N, Ns, Nd, Nt, Nc of the bulk grains.

    The main figures type each force-bearing manifold by the rank of its force-bearing points
    (:func:`force_bearing_points`); :attr:`by_rule` also gives them with the types of the gap rule
    and of detection (see the module docstring). The rattler rule is the frictional one when the
    friction coefficient is positive, else the frictionless one (module docstring).

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
        friction: the Coulomb coefficient μ >= 0 of the contacts; None: the packing's own
            (:attr:`~granpack.packing.Packing.friction`, the run's ``solver.friction``).
        slide_tol: a contact slides when its resultant's :func:`mobilisation` is at least
            ``1 - slide_tol`` (dimensionless, in ``[0, 1)``).
        n_wall: in a box or a cylinder, count only the grains of the core, centres at least
            ``n_wall d`` from the side walls (the others are a boundary, never removed as
            rattlers); 0 the whole section; ignored in a periodic cell.
    """

    def __init__(self, z_range: tuple[float, float] | None = None, force_tol: float = 1e-9, remove_rattlers: bool = True,
                 point_tol: float = 1e-3, gap_tol: float = 1e-4, rank_tol: float = 1e-3, friction: float | None = None,
                 slide_tol: float = 1e-3, n_wall: float = 0.0):
        if friction is not None and not friction >= 0:
            raise ValueError(f"friction must be >= 0, got {friction}")
        if not 0.0 <= slide_tol < 1.0:
            raise ValueError(f"slide_tol must be in [0, 1), got {slide_tol}")
        self.z_range = z_range
        self.force_tol = float(force_tol)
        self.remove_rattlers = bool(remove_rattlers)
        self.point_tol = float(point_tol)
        self.gap_tol = float(gap_tol)
        self.rank_tol = float(rank_tol)
        self.friction = None if friction is None else float(friction)
        self.slide_tol = float(slide_tol)
        self.n_wall = float(n_wall)

    def compute(self, packing: Packing) -> "Coordination":
        """Count the contacts of the bulk grains of ``packing``."""
        self._start()
        self._mu = packing.friction if self.friction is None else self.friction
        frictional = self._mu > 0
        analysed = in_region(packing, analysed_region(packing, self.z_range), self.n_wall)
        active = force_bearing(packing, self.force_tol)
        types = type_rules(packing, self.point_tol, self.gap_tol, self.rank_tol)
        self._n = int(analysed.sum())
        self._by_rule = {}
        for rule in RULES:
            counts_all, counts, removed = _backbone(packing, active, types[rule], analysed, self.remove_rattlers, frictional)
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
        backbone = analysed & ~removed
        self._constraints = _constraint_figures(packing, self._counts[backbone], backbone, frictional)
        self._sliding = _sliding_figures(packing, _kept(packing, active, removed), backbone, self._mu, self.slide_tol)
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

    @result
    def mu(self) -> float:
        """The Coulomb coefficient the rules assumed (the ``friction`` given, else the packing's)."""
        return self._mu

    @result
    def rattler_rule(self) -> str:
        """``"frictional"`` (μ > 0) or ``"frictionless"``: the rattler rule and constraint count used."""
        return "frictional" if self._mu > 0 else "frictionless"

    @result
    def constraints(self) -> dict:
        """``{constraints_per_grain, isostatic_constraints, hyperstaticity}`` of the backbone
        (module docstring): the mean independent force components of a grain's force-bearing
        contacts (:data:`COMPONENTS` of :attr:`rattler_rule`), their isostatic value ``2 f`` and
        ``(C - C_iso) / 2``, the excess of contact force unknowns over equilibrium equations per
        grain; nan without backbone grains."""
        return dict(self._constraints)

    @result
    def sliding(self) -> dict:
        """``{sliding_fraction, mean_mobilisation, n_contacts}``: over the force-bearing contacts of
        the backbone grains (``n_contacts`` of them), the share whose resultant is on the Coulomb
        cone to within ``slide_tol`` (:func:`mobilisation` at least ``1 - slide_tol``) and the mean
        mobilisation; nan for a frictionless packing."""
        return dict(self._sliding)

    def to_dict(self) -> dict:
        """The ``coordination`` part of ``analysis.json``: the backbone figures
        (:attr:`~granpack.analysis.coordination.Coordination.figures`), ``rattler_fraction``,
        ``with_rattlers``, ``n_analysed``, the settings the types were drawn with (``force_tol``,
        ``type_rule``, ``point_tol``, ``gap_tol``, ``rank_tol``), the figures of the
        cross-check classifications ``gap_rule`` and ``geometric`` (:attr:`by_rule`), and for a
        frictional packing only, ``frictional``: the friction coefficient ``mu``, ``rattler_rule``,
        :attr:`constraints`, :attr:`sliding` and ``slide_tol`` (a frictionless packing's part is
        that of the frictionless rule alone, without the key)."""
        by_rule = self.by_rule
        out = {
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
        if self.rattler_rule == "frictional":
            out["frictional"] = {
                "mu": self.mu,
                "rattler_rule": f"fewer than {FRICTIONAL_LEAST_POINTS} force-bearing points (Ns + 2 Nd + 3 Nt)",
                **self.constraints,
                **self.sliding,
                "slide_tol": self.slide_tol,
            }
        return out

"""The frozen result of a run: what analysis reads.

A :class:`Packing` bundles the final :class:`~granpack.state.ParticleState`, the last
:class:`~granpack.contact.ContactSet` with its converged point impulses, the time step that turns
impulses into forces (``force = impulse / time_step``) and the run metadata. Helpers compute the
per-manifold resultants used by stresses, torques and contact counting (docs/method/contact-detection.md#manifolds:
analyses use the pair resultant, never the split between the points of a manifold).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace

import numpy as np

from granpack.box import Box
from granpack.contact.contacts import WALL, ContactSet
from granpack.errors import InputError
from granpack.state import ParticleState

__all__ = ["Packing"]


@dataclass(frozen=True)
class Packing:
    """A static packing with its contact forces.

    Attributes:
        state: particle positions, orientations, velocities and shapes.
        contacts: contact manifolds; ``contacts.impulse`` ``(P, 3)`` is the world impulse on body
            ``i`` over the last step (a missing impulse is stored as zeros: no force known).
        time_step: the step ``h`` of the last solve, sqrt(d/g); forces are ``impulse / h``.
        population_names: one name per population (``state.population`` indexes it).
        metadata: free-form run information (``seed``, ``config`` TOML text, ``version``,
            ``status``, ``gravity`` ...); JSON-serialisable. The contact law's friction is read
            from ``config`` (:attr:`friction`).
    """

    state: ParticleState
    contacts: ContactSet
    time_step: float
    population_names: list[str] = field(default_factory=list)
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        if not self.time_step > 0:
            raise ValueError(f"time_step must be > 0, got {self.time_step}")
        if self.contacts.impulse is None:
            object.__setattr__(self, "contacts", replace(self.contacts, impulse=np.zeros((self.contacts.n_points, 3))))
        if self.state.n and len(self.population_names) <= int(self.state.population.max()):
            names = list(self.population_names) + [
                f"population {k}" for k in range(len(self.population_names), int(self.state.population.max()) + 1)
            ]
            object.__setattr__(self, "population_names", names)

    @property
    def box(self) -> Box:
        """The periodic cell."""
        return self.state.box

    @property
    def n_particles(self) -> int:
        """Number of grains."""
        return self.state.n

    @property
    def gravity(self) -> float:
        """Magnitude of gravity (``metadata["gravity"]``, default 1 in the units of d and sqrt(d/g))."""
        return float(self.metadata.get("gravity", 1.0))

    @property
    def friction(self) -> float:
        """Coulomb friction coefficient μ of the contacts (dimensionless, >= 0; 0: frictionless).

        The run's ``solver.friction``, read from the resolved config text in ``metadata["config"]``;
        0 when the metadata holds no config (a packing built by other means) or the config no
        ``[solver]`` friction (its default). The one place analysis learns whether a packing is
        frictional: :class:`~granpack.analysis.coordination.Coordination` applies the frictional
        rules when it is positive, unless told another μ.

        Raises:
            InputError: ``metadata["config"]`` is not TOML, or its friction not a number >= 0.
        """
        text = self.metadata.get("config")
        if not text:
            return 0.0
        try:
            mu = tomllib.loads(text).get("solver", {}).get("friction", 0.0)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"the packing's config (metadata) is not TOML ({exc})") from None
        if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not mu >= 0:
            raise InputError(f"the packing's config (metadata) has solver.friction = {mu!r}, not a number >= 0")
        return float(mu)

    @property
    def wall_friction(self) -> float:
        """Coulomb friction coefficient of the grains against the floor and a container's walls
        (dimensionless, >= 0): the run's ``container.wall_friction``, or :attr:`friction` where the
        config leaves it unset (as the run does).

        Raises:
            InputError: ``metadata["config"]`` is not TOML, or a friction not a number >= 0.
        """
        mu = self.friction
        text = self.metadata.get("config")
        if not text:
            return mu
        value = tomllib.loads(text).get("container", {}).get("wall_friction")
        if value is None:
            return mu
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
            raise InputError(f"the packing's config (metadata) has container.wall_friction = {value!r}, not a number >= 0")
        return float(value)

    @property
    def seed(self):
        """The run's seed from the metadata (``None`` when unknown)."""
        return self.metadata.get("seed")

    @property
    def particle_size(self) -> np.ndarray:
        """``(N,)`` circumscribed diameters, d."""
        return 2.0 * self.state.radius

    @property
    def max_size(self) -> float:
        """Largest circumscribed diameter among the grains present (``nan`` when empty), d."""
        return float(self.particle_size.max()) if self.state.n else float("nan")

    @property
    def point_force(self) -> np.ndarray:
        """``(P, 3)`` force on body ``i`` at every contact point, ``impulse / time_step``."""
        return self.contacts.impulse / self.time_step

    @property
    def manifold_force(self) -> np.ndarray:
        """``(M, 3)`` resultant force on body ``i`` of every manifold (sum over its points)."""
        return _segment_sum(self.point_force, self.contacts.point_start)

    @property
    def manifold_normal_force(self) -> np.ndarray:
        """``(M,)`` normal component of the resultant, ``F_m . n_m`` (> 0 compressive)."""
        return np.einsum("ij,ij->i", self.manifold_force, self.contacts.normal)

    @property
    def manifold_point(self) -> np.ndarray:
        """``(M, 3)`` point of application of each resultant.

        Weighted by the normal force of the points,
        :math:`x_m = \\sum_k f_{n,k} x_k / \\sum_k f_{n,k}`; the plain centroid of the points when
        the manifold carries no force.
        """
        c = self.contacts
        fn = np.maximum(np.einsum("ij,ij->i", self.point_force, c.normal[c.point_manifold]), 0.0)
        weight_sum = _segment_sum(fn[:, None], c.point_start)[:, 0]
        weighted = _segment_sum(fn[:, None] * c.point, c.point_start)
        counts = np.diff(c.point_start).astype(np.float64)
        plain = _segment_sum(c.point, c.point_start) / np.maximum(counts, 1.0)[:, None]
        loaded = weight_sum > 0
        out = plain
        out[loaded] = weighted[loaded] / weight_sum[loaded, None]
        return out

    @property
    def is_wall_contact(self) -> np.ndarray:
        """``(M,)`` True for manifolds with a wall: the floor or a container's (``body_j < 0``)."""
        return self.contacts.body_j < 0

    def branch_vectors(self) -> np.ndarray:
        """``(M, 3)`` branch vector from the antagonist centre to the candidate centre, d.

        ``x_i - (x_j + shift)``; for a wall the antagonist centre is the projection of ``x_i`` on
        the wall along the manifold's normal ``n``: ``(0, 0, z_i)`` for the floor, and
        ``((x_i - w) . n) n`` for a container's wall, ``w = x_1 - g_1 n / 2`` the wall's point
        beside the manifold's first point ``x_1`` (gap ``g_1``). Lateral components are reduced to
        the minimum image (positions may have been wrapped after detection).
        """
        c = self.contacts
        x = self.state.position
        out = np.zeros((c.n_manifolds, 3))
        pair = c.body_j >= 0
        out[pair] = self.box.minimum_image(x[c.body_i[pair]] - (x[c.body_j[pair]] + c.shift[pair]))
        floor = c.body_j == WALL
        out[floor, 2] = x[c.body_i[floor], 2]
        side = c.body_j < WALL
        first = c.point_start[:-1][side]
        normal = c.normal[side]
        wall_point = c.point[first] - 0.5 * c.gap[first][:, None] * normal
        out[side] = np.einsum("ij,ij->i", x[c.body_i[side]] - wall_point, normal)[:, None] * normal
        return out


def _segment_sum(values: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Sum ``values`` ``(P, k)`` over the CSR segments ``start`` ``(M+1,)``; empty segments give 0."""
    m = len(start) - 1
    seg = np.repeat(np.arange(m), np.diff(start))
    flat = values.reshape(len(values), int(np.prod(values.shape[1:])))  # also for P = 0
    out = np.zeros((m, flat.shape[1]))
    for k in range(flat.shape[1]):
        out[:, k] += np.bincount(seg, weights=flat[:, k], minlength=m)
    return out.reshape((m,) + values.shape[1:])

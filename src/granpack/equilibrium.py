"""Mechanical equilibrium of a packing under gravity (docs/method/equilibrium.md).

Used by the simulation loop as its stopping test (every few tens of steps) and by the analysis.
Everything is vectorised NumPy over contact points (``np.bincount``), so a check costs a few
milliseconds for 3000 grains.

Forces are point impulses over the last step divided by the step, ``f = r / h`` (world frame, on
body ``i``; body ``j`` receives ``-f``). For particle ``p``, with gravity ``(0, 0, -g)``:

.. math::

    F_p = m_p \\mathbf g + \\sum_{\\alpha \\ni p} f_\\alpha, \\qquad
    T_p = \\sum_{\\alpha \\ni p} (x_\\alpha - x_p) \\times f_\\alpha, \\qquad
    E_p = \\tfrac12 m_p |v_p|^2 + \\tfrac12 \\omega_p^T J_p \\omega_p .

Lever arms ``x_alpha - x_p`` are reduced to the minimum image in x, y, so they are right whether
or not positions were wrapped after detection.

**Stress scale P** (granpack's choice: under gravity the pressure grows with depth). The particle Love–Weber moment
:math:`s_p = \\sum_{\\alpha \\ni p} (x_\\alpha - x_p) \\otimes f_\\alpha` is averaged over the
horizontal slab of thickness ``t = d_max`` centred on the particle (a sliding window over centre
heights; compression positive):

.. math::

    P_{LW}(z) = -\\frac{1}{3 L_x L_y t} \\sum_{q : |z_q - z| \\le t/2} \\mathrm{tr}\\, s_q .

Near the free surface :math:`P_{LW} \\to 0` and the criteria would become meaningless, so it is
floored: :math:`P_p = \\max(P_{LW}(z_p), P_{floor})` with :math:`P_{floor} = P_{LW}(z_{top})` at
:math:`z_{top} = z_{surf} - n_{top} d_{max}` (the top of the bulk; ``z_surf`` = mean over lateral
``d_max x d_max`` columns of the highest centre, ``n_top = 2`` by default). If no force crosses that
slab the floor is the column average of the Love–Weber pressure. When no contact carries force at
all, P is 0 and the normalised figures are ``inf`` (the test fails).

Criteria (defaults after Agnolin & Roux 2007):

.. math::

    |F_p| < \\epsilon_F d_p^2 P_p, \\quad |T_p| < \\epsilon_T d_p^3 P_p, \\quad
    E_p < \\epsilon_E d_p^3 \\bar P, \\quad |W - F_S| < \\epsilon_W W,

with ``d_p`` the circumscribed diameter, :math:`\\bar P` the Love–Weber pressure averaged over the
column below ``z_top`` (the whole column when ``z_top`` is below every centre), ``W = g Σ m_p`` the
total weight and ``F_S`` the vertical force of the walls (the floor, and a container's walls).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from granpack.contact.contacts import ContactSet
from granpack.state import ParticleState

__all__ = [
    "EquilibriumCriteria",
    "criteria_of",
    "EquilibriumFields",
    "EquilibriumReport",
    "particle_balance",
    "stress_moments",
    "surface_height",
    "slab_pressure",
    "wall_force",
    "equilibrium_fields",
    "check_equilibrium",
    "report_from_fields",
]


@dataclass(frozen=True)
class EquilibriumCriteria:
    """Tolerances of the equilibrium test (dimensionless).

    Attributes:
        force: bound on :math:`|F_p| / (d_p^2 P_p)`.
        torque: bound on :math:`|T_p| / (d_p^3 P_p)`.
        kinetic_energy: bound on :math:`E_p / (d_p^3 \\bar P)`.
        wall: bound on :math:`|1 - F_S / W|`.
        top_margin: ``n_top``: the pressure floor is taken ``n_top d_max`` below the surface.
    """

    force: float = 1e-4
    torque: float = 1e-4
    kinetic_energy: float = 1e-8
    wall: float = 1e-4
    top_margin: float = 2.0


def criteria_of(settings) -> EquilibriumCriteria:
    """The criteria of a run: its config's ``[equilibrium]`` table
    (:class:`granpack.config.EquilibriumConfig`: ``force_tolerance``, ``torque_tolerance``,
    ``kinetic_tolerance``, ``wall_tolerance``). The only source of a run's criteria: the run is
    certified and its analysis judged by the same ones. The defaults of
    :class:`EquilibriumCriteria` are plain numbers (this module reads no config schema), held to
    the config's by a test."""
    return EquilibriumCriteria(force=settings.force_tolerance, torque=settings.torque_tolerance,
                               kinetic_energy=settings.kinetic_tolerance, wall=settings.wall_tolerance)


@dataclass(frozen=True)
class EquilibriumFields:
    """Per-particle figures behind the test.

    Attributes:
        net_force: ``(N, 3)`` net force including gravity, m g units (d^3 at unit density, g = 1).
        net_torque: ``(N, 3)`` net torque about the centre of mass (world frame).
        kinetic_energy: ``(N,)`` translational + rotational kinetic energy.
        pressure: ``(N,)`` floored local pressure :math:`P_p` (compression positive), per d^2.
        bulk_pressure: :math:`\\bar P`.
        pressure_floor: :math:`P_{floor}`.
        z_surface: free-surface height used for the floor, d.
        force_ratio: ``(N,)`` :math:`|F_p| / (d_p^2 P_p)`.
        torque_ratio: ``(N,)`` :math:`|T_p| / (d_p^3 P_p)`.
        energy_ratio: ``(N,)`` :math:`E_p / (d_p^3 \\bar P)`.
        wall_force: vertical force of the walls, F_S.
        weight: total weight W.
    """

    net_force: np.ndarray
    net_torque: np.ndarray
    kinetic_energy: np.ndarray
    pressure: np.ndarray
    bulk_pressure: float
    pressure_floor: float
    z_surface: float
    force_ratio: np.ndarray
    torque_ratio: np.ndarray
    energy_ratio: np.ndarray
    wall_force: float
    weight: float


@dataclass(frozen=True)
class EquilibriumReport:
    """Outcome of the equilibrium test: the worst normalised values and the verdicts.

    Attributes:
        max_net_force: :math:`\\max_p |F_p| / (d_p^2 P_p)`.
        max_net_torque: :math:`\\max_p |T_p| / (d_p^3 P_p)`.
        kinetic_energy: :math:`\\max_p E_p / (d_p^3 \\bar P)`.
        wall_force_over_weight: :math:`F_S / W` (1 at equilibrium).
        bulk_pressure: :math:`\\bar P`.
        pressure_floor: :math:`P_{floor}`.
        force_ok, torque_ok, energy_ok, wall_ok: each criterion's verdict.
        worst_force_particle, worst_torque_particle: indices of the worst particles (-1 if none).
    """

    max_net_force: float
    max_net_torque: float
    kinetic_energy: float
    wall_force_over_weight: float
    bulk_pressure: float
    pressure_floor: float
    force_ok: bool
    torque_ok: bool
    energy_ok: bool
    wall_ok: bool
    worst_force_particle: int
    worst_torque_particle: int

    @property
    def passed(self) -> bool:
        """True when all four criteria hold."""
        return self.force_ok and self.torque_ok and self.energy_ok and self.wall_ok

    def as_dict(self) -> dict:
        """Plain-dict view (for JSON summaries)."""
        return {
            "max_net_force": self.max_net_force,
            "max_net_torque": self.max_net_torque,
            "kinetic_energy": self.kinetic_energy,
            "wall_force_over_weight": self.wall_force_over_weight,
            "bulk_pressure": self.bulk_pressure,
            "pressure_floor": self.pressure_floor,
            "force_ok": self.force_ok,
            "torque_ok": self.torque_ok,
            "energy_ok": self.energy_ok,
            "wall_ok": self.wall_ok,
            "passed": self.passed,
        }


def _bincount3(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """``(n, k)`` sums of the rows of ``values`` ``(P, k)`` grouped by ``index`` ``(P,)``."""
    out = np.zeros((n, values.shape[1]))
    for k in range(values.shape[1]):
        out[:, k] += np.bincount(index, weights=values[:, k], minlength=n)
    return out


def _point_arrays(state: ParticleState, contacts: ContactSet, time_step: float):
    """Per point: body i, body j (< 0 a wall), force on i, lever arms about x_i and x_j (min. image)."""
    seg = contacts.point_manifold
    bi = contacts.body_i[seg]
    bj = contacts.body_j[seg]
    impulse = contacts.impulse if contacts.impulse is not None else np.zeros((contacts.n_points, 3))
    force = impulse / time_step
    arm_i = state.box.minimum_image(contacts.point - state.position[bi])
    arm_j = state.box.minimum_image(contacts.point - state.position[np.maximum(bj, 0)])
    return bi, bj, force, arm_i, arm_j


def particle_balance(
    state: ParticleState, contacts: ContactSet, time_step: float, gravity: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Net force, net torque and kinetic energy of every particle.

    Args:
        state: the particles (``omega`` in the body frame).
        contacts: manifolds with ``impulse`` ``(P, 3)`` (world impulse on body i over the step).
        time_step: ``h``, sqrt(d/g).
        gravity: ``g``.

    Returns:
        ``(F (N, 3), T (N, 3), E (N,))`` as defined in the module docstring.
    """
    n = state.n
    bi, bj, f, arm_i, arm_j = _point_arrays(state, contacts, time_step)
    pair = bj >= 0
    force = _bincount3(bi, f, n) - _bincount3(bj[pair], f[pair], n)
    force[:, 2] -= state.mass * gravity
    torque = _bincount3(bi, np.cross(arm_i, f), n) - _bincount3(bj[pair], np.cross(arm_j[pair], f[pair]), n)
    energy = 0.5 * state.mass * np.einsum("ij,ij->i", state.velocity, state.velocity) + 0.5 * np.einsum(
        "ij,ij->i", state.inertia, state.omega**2
    )
    return force, torque, energy


def stress_moments(state: ParticleState, contacts: ContactSet, time_step: float, *, trace_only: bool = False) -> np.ndarray:
    """Love–Weber moments :math:`s_p = \\sum_{\\alpha \\ni p} (x_\\alpha - x_p) \\otimes f_\\alpha` (on p).

    Args:
        trace_only: return only :math:`\\mathrm{tr}\\, s_p`.

    Returns:
        ``(N, 3, 3)`` moments (row i: lever arm component, column j: force component), or
        ``(N,)`` traces; units of force x length. Summed over a region of volume ``V`` and divided
        by ``V`` they give the average stress (tension positive).
    """
    n = state.n
    bi, bj, f, arm_i, arm_j = _point_arrays(state, contacts, time_step)
    pair = bj >= 0
    if trace_only:
        trace = np.zeros(n)
        trace += np.bincount(bi, weights=np.einsum("ij,ij->i", arm_i, f), minlength=n)
        trace -= np.bincount(bj[pair], weights=np.einsum("ij,ij->i", arm_j[pair], f[pair]), minlength=n)
        return trace
    outer_i = (arm_i[:, :, None] * f[:, None, :]).reshape(-1, 9)
    outer_j = (arm_j[pair][:, :, None] * f[pair][:, None, :]).reshape(-1, 9)
    return (_bincount3(bi, outer_i, n) - _bincount3(bj[pair], outer_j, n)).reshape(n, 3, 3)


def surface_height(state: ParticleState, column: float) -> float:
    """Free-surface height: mean over lateral ``column x column`` cells of the highest centre, d.

    Cells without any centre are skipped; ``nan`` for an empty state.
    """
    if state.n == 0:
        return float("nan")
    box = state.box
    nx, ny = max(1, int(box.lx // column)), max(1, int(box.ly // column))
    ix = np.minimum((state.position[:, 0] / box.lx * nx).astype(np.int64), nx - 1) % nx
    iy = np.minimum((state.position[:, 1] / box.ly * ny).astype(np.int64), ny - 1) % ny
    top = np.full(nx * ny, -np.inf)
    np.maximum.at(top, ix * ny + iy, state.position[:, 2])
    return float(top[np.isfinite(top)].mean())


def slab_pressure(z: np.ndarray, trace: np.ndarray, area: float, thickness: float, at: np.ndarray) -> np.ndarray:
    """Love–Weber pressure in the slabs ``[at - t/2, at + t/2]`` (compression positive).

    Args:
        z: ``(N,)`` centre heights.
        trace: ``(N,)`` traces of the particle moments :math:`\\mathrm{tr}\\, s_p`.
        area: ``Lx Ly``, d^2.
        thickness: ``t``, d.
        at: ``(K,)`` slab mid-heights.

    Returns:
        ``(K,)`` :math:`-\\sum_{|z_q - a| \\le t/2} \\mathrm{tr}\\, s_q / (3 L_x L_y t)`.
    """
    order = np.argsort(z, kind="stable")
    zs = z[order]
    csum = np.concatenate([[0.0], np.cumsum(trace[order])])
    at = np.asarray(at, dtype=np.float64)
    lo = np.searchsorted(zs, at - 0.5 * thickness, side="left")
    hi = np.searchsorted(zs, at + 0.5 * thickness, side="right")
    return -(csum[hi] - csum[lo]) / (3.0 * area * thickness)


def wall_force(contacts: ContactSet, time_step: float) -> float:
    """Total vertical force of the walls on the grains, :math:`F_S = \\sum_{walls} f_z` (upward): the
    floor's, and a container's walls' (their friction carries part of the weight)."""
    if contacts.impulse is None or contacts.n_points == 0:
        return 0.0
    wall_points = contacts.body_j[contacts.point_manifold] < 0
    return float(contacts.impulse[wall_points, 2].sum() / time_step)


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """``num / den`` with ``inf`` where ``den <= 0 < num`` and 0 where both vanish."""
    out = np.where(num > 0, np.inf, 0.0)
    ok = den > 0
    out[ok] = num[ok] / den[ok]
    return out


def equilibrium_fields(
    state: ParticleState,
    contacts: ContactSet,
    time_step: float,
    *,
    gravity: float = 1.0,
    criteria: EquilibriumCriteria | None = None,
) -> EquilibriumFields:
    """All per-particle figures of the test (see the module docstring for the definitions)."""
    criteria = criteria or EquilibriumCriteria()
    force, torque, energy = particle_balance(state, contacts, time_step, gravity)
    size = 2.0 * state.radius
    d_max = float(size.max()) if state.n else 1.0
    z = state.position[:, 2]
    area = state.box.area
    trace = stress_moments(state, contacts, time_step, trace_only=True)
    z_surf = surface_height(state, d_max)
    column_pressure = -trace.sum() / (3.0 * area * max(z_surf + 0.5 * d_max, d_max)) if state.n else 0.0
    if state.n:
        bulk_top = z_surf - criteria.top_margin * d_max
        z_top = max(bulk_top, float(z.min()))
        p_floor = float(slab_pressure(z, trace, area, d_max, np.array([z_top]))[0])
        if not p_floor > 0:
            p_floor = float(column_pressure)
        if bulk_top > z.min():
            bulk_pressure = -trace[z <= bulk_top].sum() / (3.0 * area * max(bulk_top + 0.5 * d_max, d_max))
        else:  # a pile thinner than the top margin: the whole column
            bulk_pressure = column_pressure
        if not bulk_pressure > 0:
            bulk_pressure = float(column_pressure)
        local = slab_pressure(z, trace, area, d_max, z)
    else:
        p_floor = bulk_pressure = 0.0
        local = np.zeros(0)
    pressure = np.maximum(local, p_floor)
    weight = float(gravity * state.mass.sum())
    return EquilibriumFields(
        net_force=force,
        net_torque=torque,
        kinetic_energy=energy,
        pressure=pressure,
        bulk_pressure=float(bulk_pressure),
        pressure_floor=float(p_floor),
        z_surface=z_surf,
        force_ratio=_ratio(np.linalg.norm(force, axis=1), size**2 * pressure),
        torque_ratio=_ratio(np.linalg.norm(torque, axis=1), size**3 * pressure),
        energy_ratio=_ratio(energy, size**3 * bulk_pressure),
        wall_force=wall_force(contacts, time_step),
        weight=weight,
    )


def check_equilibrium(
    state: ParticleState,
    contacts: ContactSet,
    time_step: float,
    *,
    gravity: float = 1.0,
    criteria: EquilibriumCriteria | None = None,
) -> EquilibriumReport:
    """The equilibrium test (module docstring; docs/method/equilibrium.md).

    Args:
        state: particles (velocities and body-frame ``omega`` of the last step).
        contacts: the converged manifolds with ``impulse`` ``(P, 3)``.
        time_step: ``h`` (forces are ``impulse / h``), sqrt(d/g).
        gravity: ``g``.
        criteria: tolerances (defaults 1e-4, 1e-4, 1e-8, 1e-4).

    Returns:
        The worst normalised values and the verdicts; ``report.passed`` is the stopping test.
    """
    criteria = criteria or EquilibriumCriteria()
    return report_from_fields(equilibrium_fields(state, contacts, time_step, gravity=gravity, criteria=criteria), criteria)


def report_from_fields(fields: EquilibriumFields, criteria: EquilibriumCriteria | None = None) -> EquilibriumReport:
    """The worst values and verdicts of already computed :class:`EquilibriumFields`."""
    criteria = criteria or EquilibriumCriteria()
    if len(fields.force_ratio):
        pf, pt = int(np.argmax(fields.force_ratio)), int(np.argmax(fields.torque_ratio))
        max_f, max_t = float(fields.force_ratio[pf]), float(fields.torque_ratio[pt])
        max_e = float(fields.energy_ratio.max())
    else:
        pf = pt = -1
        max_f = max_t = max_e = 0.0
    ratio = fields.wall_force / fields.weight if fields.weight > 0 else float("nan")
    return EquilibriumReport(
        max_net_force=max_f,
        max_net_torque=max_t,
        kinetic_energy=max_e,
        wall_force_over_weight=ratio,
        bulk_pressure=fields.bulk_pressure,
        pressure_floor=fields.pressure_floor,
        force_ok=bool(max_f < criteria.force),
        torque_ok=bool(max_t < criteria.torque),
        energy_ok=bool(max_e < criteria.kinetic_energy),
        wall_ok=bool(abs(ratio - 1.0) < criteria.wall),
        worst_force_particle=pf,
        worst_torque_particle=pt,
    )

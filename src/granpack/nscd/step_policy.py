"""The step policy: how far ahead each step looks for contacts and into how many substeps it is cut.

Alert distance. Contacts are detected on the predicted configuration of each step; a pair must
be a candidate before it can close. During the pour grains fall at several sqrt(g d), more than
the configured alert distance per step, so the alert distance of a step is raised to cover the
largest closing speed (docs: Method > NSCD, alert distance and substeps):

.. math:: a_n = \\max\\big(a, \\; 1.5\\,(2 h \\max_p (|v_p| + R_p |ω_p|) + g h^2)\\big)

(two bodies approaching, see :func:`granpack.nscd.required_alert`, with a margin of 1.5), rounded
up to ``a 2^k`` so that the Verlet list is rebuilt only when the level changes. The alert distance
plus the Verlet skin must stay below ``L/2 - d_max`` (one periodic image per pair); when ``a_n``
would exceed that ceiling (narrow cells, fast pours), the step is split into ``k`` substeps of
``h/k``, ``k`` the smallest integer for which ``a_n/k`` fits: a missed contact would appear
already interpenetrating by up to the missing distance, and thin grains can then pass through
each other. The Verlet skin is at most a quarter of the room the alert distance leaves. Only the
pairs of fast grains need the raised distance: each grain gets its share (:func:`step_reach`) and
a pair is searched up to the sum of its two shares, so one thin grain spinning fast does not fill
the contact problem with the far neighbours of every grain.

Rotation per step. The contact law holds the gaps linearised in the velocities; a polyhedron that
turns by φ in one step moves its surface off that tangent path by up to ``R φ²/2``, an overlap the
velocity law never saw coming (and a neighbouring face that turns into contact was not in the
step's manifold at all). Impacts spin thin grains at 30-50 rad/sqrt(d/g), 0.15-0.25 rad per step
of 5e-3. So a step is also split into at least ``ceil(h max_p |ω_p| sqrt(2 R_p) / time_stepping.max_rotation)``
substeps (R_p in d: the same surface deviation for every size), over the polyhedra that may touch a
grain or the wall during the step (a sphere's gaps do not depend on its rotation, and a grain in
free flight has no gap to keep).
"""

from __future__ import annotations

import math

import numpy as np

from granpack.contact import ContactSet
from granpack.nscd.rigid import required_alert
from granpack.state import ParticleState

__all__ = ["ALERT_MARGIN", "step_alert", "step_reach"]

#: safety factor on the distance two grains can close in one step (see the module docstring)
ALERT_MARGIN = 1.5


def step_alert(state: ParticleState, base: float, time_step: float, ceiling: float,
               max_rotation: float = math.inf) -> tuple[float, int]:
    """Alert distance (d) and number of substeps of the next step (module docstring).

    ``need = ALERT_MARGIN *`` :func:`~granpack.nscd.required_alert` ``(h)``; the step is split
    into ``k = max(ceil(need / ceiling), ceil(φ / max_rotation))`` substeps of ``h/k``, with ``φ``
    the largest turn in the step of a polyhedron that may touch something during it, scaled to a
    grain of circumscribed radius d/2 (:func:`_turn_in_reach`; a substep closes at most
    ``need/k``: the bound is ``2 h s + h^2``), and the alert distance is ``base 2^j`` covering
    ``need/k``, at most ``ceiling``.
    """
    need = ALERT_MARGIN * required_alert(state, time_step)
    substeps = max(1, math.ceil(need / ceiling - 1e-12))
    if math.isfinite(max_rotation):
        turn = _turn_in_reach(state, time_step, ceiling, max_rotation)
        substeps = max(substeps, math.ceil(turn / max_rotation - 1e-12))
    need /= substeps
    if need <= base:
        return base, substeps
    level = base * 2.0 ** math.ceil(math.log2(need / base))
    return min(level, ceiling), substeps


def _turn_in_reach(state: ParticleState, time_step: float, ceiling: float, max_rotation: float) -> float:
    """Largest scaled turn ``φ_p = h |ω_p| sqrt(R_p / (d/2))`` (rad) above ``max_rotation`` of the
    polyhedra that may come within the alert distance of another grain or the wall during the
    step of ``time_step``; 0 if none.

    Why: the rotation bound is there for the contacts. A turn by ``h |ω|`` moves a grain's surface
    off the linearised path the contact law holds it to by up to ``R (h |ω|)^2 / 2``; the scaled
    turn gives every grain the deviation a grain of radius d/2 gets at ``max_rotation``, so a
    small grain (d/3: R = d/6) may turn sqrt(3) times further. A grain in free flight has no
    contact to keep: a small grain thrown up spinning at 50 rad/sqrt(d/g) above a bidisperse pile
    split every step of the whole pile into six for as long as it flew. A grain is in free flight
    when, for every other grain q, the centres' distance minus both circumscribed radii exceeds
    ``ceiling`` (the largest alert distance a step can take) plus what both can close in the step,
    ``ALERT_MARGIN h (s_p + s_q + 2h)`` with ``s = |v| + R |ω|`` (the bound of
    :func:`~granpack.nscd.required_alert`), and its height above the wall exceeds
    ``R_p + ceiling + ALERT_MARGIN h (s_p + h)``. Grains are examined largest turn first; the
    first that is not free sets the figure.
    """
    spin = np.sqrt(np.einsum("ij,ij->i", state.omega, state.omega))
    radius = state.radius
    turn = time_step * spin * np.sqrt(radius / 0.5)
    turning = np.flatnonzero((turn > max_rotation) & ~state.shapes.is_sphere[state.kind])
    if not len(turning):
        return 0.0
    travel = ALERT_MARGIN * time_step * (np.linalg.norm(state.velocity, axis=1) + radius * spin + time_step)
    for p in turning[np.argsort(-turn[turning], kind="stable")]:
        gap = np.linalg.norm(state.box.minimum_image(state.position - state.position[p]), axis=1) - radius - radius[p]
        gap[p] = math.inf
        if (state.position[p, 2] - radius[p] <= ceiling + travel[p]
                or np.any(gap <= ceiling + travel[p] + travel)):
            return float(turn[p])
    return 0.0


def step_reach(state: ParticleState, base: float, time_step: float, substeps: int,
               contacts: ContactSet | None = None) -> np.ndarray:
    """``(N,)`` per-grain share of the alert distance of the next step, d (:meth:`Detector.detect`).

    Grain p closes at most ``h_s s_p + g h h_s / 2`` of a gap in a substep of ``h_s = h / substeps``
    (its half of the bound of :func:`step_alert`), with ``s_p`` the largest surface speed
    ``|v| + R |ω|`` of p and of the grains it touched at the last step (``contacts``): a resting
    grain struck by a fast one leaves with at most the striker's speed (inelastic impact), so it
    gets the striker's reach. Taken with the same margin as the alert distance and at least
    ``base / 2``: a pair is searched up to the sum of its two reaches, so a fast grain raises the
    alert distance of its own neighbourhood only.
    """
    speed = np.linalg.norm(state.velocity, axis=1) + state.radius * np.linalg.norm(state.omega, axis=1)
    if contacts is not None and contacts.n_manifolds:
        pair = contacts.body_j >= 0
        i, j = contacts.body_i[pair], contacts.body_j[pair]
        touched = speed.copy()
        np.maximum.at(touched, i, speed[j])
        np.maximum.at(touched, j, speed[i])
        speed = touched
    h_sub = time_step / substeps
    return np.maximum(0.5 * base, ALERT_MARGIN * (h_sub * speed + 0.5 * time_step * h_sub))

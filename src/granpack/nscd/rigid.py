"""Rigid-body kinematics of the Moreau–Jean step (docs: Method > NSCD).

Generalised velocities inside the solver are **world-frame** rows ``V[p] = (v_p, ω_p^w)`` of an
``(N + 1, 6)`` array; row ``N`` is the bottom wall (infinite mass, zero velocity), so a wall
contact is an ordinary contact whose antagonist has zero inverse mass and zero inverse inertia.
The state itself keeps ``omega`` in the body frame (:mod:`granpack.state`).

World inverse inertia, never inverting a full matrix (stored as its 6 independent entries
``(xx, yy, zz, xy, xz, yz)``):

.. math:: J_w^{-1} = R\\, \\mathrm{diag}(1/J_1, 1/J_2, 1/J_3)\\, R^T

Free velocity over a step ``h`` (gravity ``g``, ``(0, 0, -1)`` unless a test tilts it through
:attr:`granpack.nscd.StepParameters.gravity`, explicit gyroscopic term in the body
frame, then rescaled so that the rotational kinetic energy of a free body is unchanged — the
exact torque-free flow conserves it, the explicit Euler step would raise it by O(h²)):

.. math::

    v^{free} = v^n + h\\,\\mathbf g, \\qquad
    \\tilde\\omega = \\omega^n + h\\, J^{-1} (J\\omega^n \\times \\omega^n), \\qquad
    \\omega^{free} = \\tilde\\omega\\, \\sqrt{\\frac{\\omega^n \\cdot J \\omega^n}
                                               {\\tilde\\omega \\cdot J \\tilde\\omega}}

Predicted configuration (where contacts are detected and the contact problem is frozen) and
end-of-step update (θ-scheme, body-frame rotation increments, quaternions renormalised):

.. math::

    x^{TT} = x^n + (1-θ) h v^n, \\quad q^{TT} = q^n \\otimes \\exp\\big(\\tfrac12 (1-θ) h ω^n\\big)

    x^{n+1} = x^{TT} + θ h v^{n+1} + δx, \\quad
    q^{n+1} = q^{TT} \\otimes \\exp\\big(\\tfrac12 (θ h ω^{n+1} + R^{TT\\,T} δφ)\\big)

where ``(δx, δφ)`` is the position correction of :mod:`granpack.nscd.integrator` (zero when no
overlap exceeds the slop). Angular velocities are converted between frames with ``R^{TT}``,
the rotation at which the lever arms and inverse inertias of the step are evaluated.
"""

from __future__ import annotations

import numpy as np

from granpack._numba import jit, prange
from granpack.rotations import quat_integrate_body_nb, quat_to_matrix_nb
from granpack.state import ParticleState

__all__ = ["world_inverse_inertia", "required_alert", "kinetic_energy", "potential_energy", "total_energy"]


@jit
def _sym_inverse_inertia(rot, inv_j, out):
    """Numba: the 6 entries ``(xx, yy, zz, xy, xz, yz)`` of ``R diag(inv_j) R^T`` into ``out``."""
    out[0] = rot[0, 0] * rot[0, 0] * inv_j[0] + rot[0, 1] * rot[0, 1] * inv_j[1] + rot[0, 2] * rot[0, 2] * inv_j[2]
    out[1] = rot[1, 0] * rot[1, 0] * inv_j[0] + rot[1, 1] * rot[1, 1] * inv_j[1] + rot[1, 2] * rot[1, 2] * inv_j[2]
    out[2] = rot[2, 0] * rot[2, 0] * inv_j[0] + rot[2, 1] * rot[2, 1] * inv_j[1] + rot[2, 2] * rot[2, 2] * inv_j[2]
    out[3] = rot[0, 0] * rot[1, 0] * inv_j[0] + rot[0, 1] * rot[1, 1] * inv_j[1] + rot[0, 2] * rot[1, 2] * inv_j[2]
    out[4] = rot[0, 0] * rot[2, 0] * inv_j[0] + rot[0, 1] * rot[2, 1] * inv_j[1] + rot[0, 2] * rot[2, 2] * inv_j[2]
    out[5] = rot[1, 0] * rot[2, 0] * inv_j[0] + rot[1, 1] * rot[2, 1] * inv_j[1] + rot[1, 2] * rot[2, 2] * inv_j[2]


@jit
def _world_inverse_inertia_kernel(quaternion, inertia, out):
    for p in range(quaternion.shape[0]):
        rot = quat_to_matrix_nb(quaternion[p])
        inv_j = 1.0 / inertia[p]
        _sym_inverse_inertia(rot, inv_j, out[p])


def world_inverse_inertia(quaternion: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """World-frame inverse inertia ``R diag(1/J) R^T`` of every body.

    Args:
        quaternion: ``(N, 4)`` unit quaternions ``(w, x, y, z)``.
        inertia: ``(N, 3)`` principal moments, d^5 (unit density).

    Returns:
        ``(N, 6)`` entries ``(xx, yy, zz, xy, xz, yz)`` of the symmetric inverse, d^-5.
    """
    q = np.ascontiguousarray(quaternion, dtype=np.float64)
    out = np.empty((len(q), 6))
    _world_inverse_inertia_kernel(q, np.ascontiguousarray(inertia, dtype=np.float64), out)
    return out


@jit(parallel=True)
def predict_kernel(position, quaternion, velocity, omega, inertia, h, theta, gravity, x_tt, q_tt, rot_tt, inv_inertia_w,
                   v_start, v_free, chunks):
    """Numba: predicted configuration, world inverse inertia, start and free velocities.

    Args:
        position, quaternion, velocity, omega: state at t_n, ``(N, 3)``, ``(N, 4)``, ``(N, 3)``,
            ``(N, 3)`` (omega in the body frame).
        inertia: ``(N, 3)`` principal moments.
        h, theta: time step (sqrt(d/g)) and θ.
        gravity: ``(3,)`` acceleration of gravity, g (``(0, 0, -1)`` in a run); a zero horizontal
            component adds nothing, so the vertical default gives the bits of ``v_z - h``.
        x_tt, q_tt, rot_tt: outputs ``(N, 3)``, ``(N, 4)``, ``(N, 3, 3)``: predicted
            configuration (positions not wrapped) and its rotation matrices.
        inv_inertia_w: output ``(N + 1, 6)`` world inverse inertia at TT (row N: wall, zeros).
        v_start, v_free: outputs ``(N + 1, 6)`` world generalised velocities at t_n and free
            velocities (row N: wall, zeros).
        chunks: consecutive ranges of bodies computed at once (threads); the bodies are
            independent, so the result does not depend on it.
    """
    n = position.shape[0]
    for c in prange(chunks):
        _predict_bodies(n * c // chunks, n * (c + 1) // chunks, position, quaternion, velocity, omega, inertia, h,
                        theta, gravity, x_tt, q_tt, rot_tt, inv_inertia_w, v_start, v_free)
    for k in range(6):
        inv_inertia_w[n, k] = 0.0
        v_start[n, k] = 0.0
        v_free[n, k] = 0.0


@jit
def _predict_bodies(p0, p1, position, quaternion, velocity, omega, inertia, h, theta, gravity, x_tt, q_tt, rot_tt,
                    inv_inertia_w, v_start, v_free):
    """Numba: :func:`predict_kernel` for the bodies ``p0 <= p < p1``."""
    a = (1.0 - theta) * h
    phi = np.empty(3)
    inv_j = np.empty(3)
    for p in range(p0, p1):
        for k in range(3):
            x_tt[p, k] = position[p, k] + a * velocity[p, k]
            phi[k] = a * omega[p, k]
        q = quat_integrate_body_nb(quaternion[p], phi)
        for k in range(4):
            q_tt[p, k] = q[k]
        rot = quat_to_matrix_nb(q)
        rot_tt[p] = rot
        j0, j1, j2 = inertia[p, 0], inertia[p, 1], inertia[p, 2]
        inv_j[0], inv_j[1], inv_j[2] = 1.0 / j0, 1.0 / j1, 1.0 / j2
        _sym_inverse_inertia(rot, inv_j, inv_inertia_w[p])
        w0, w1, w2 = omega[p, 0], omega[p, 1], omega[p, 2]
        l0, l1, l2 = j0 * w0, j1 * w1, j2 * w2
        m0 = w0 + 0.5 * h * (l1 * w2 - l2 * w1) / j0
        m1 = w1 + 0.5 * h * (l2 * w0 - l0 * w2) / j1
        m2 = w2 + 0.5 * h * (l0 * w1 - l1 * w0) / j2
        n0, n1, n2 = j0 * m0, j1 * m1, j2 * m2
        f0 = w0 + h * (n1 * m2 - n2 * m1) / j0
        f1 = w1 + h * (n2 * m0 - n0 * m2) / j1
        f2 = w2 + h * (n0 * m1 - n1 * m0) / j2
        e_old = l0 * w0 + l1 * w1 + l2 * w2
        e_new = j0 * f0 * f0 + j1 * f1 * f1 + j2 * f2 * f2
        if e_new > 0.0:
            s = np.sqrt(e_old / e_new)
            f0, f1, f2 = s * f0, s * f1, s * f2
        for k in range(3):
            v_start[p, k] = velocity[p, k]
            v_free[p, k] = velocity[p, k]
            v_start[p, 3 + k] = rot[k, 0] * w0 + rot[k, 1] * w1 + rot[k, 2] * w2
            v_free[p, 3 + k] = rot[k, 0] * f0 + rot[k, 1] * f1 + rot[k, 2] * f2
        for k in range(2):
            if gravity[k] != 0.0:  # a vertical gravity leaves v_x, v_y untouched (signed zeros included)
                v_free[p, k] += h * gravity[k]
        v_free[p, 2] += h * gravity[2]  # h * -1.0 is -h exactly: the bits of v_z - h


@jit(parallel=True)
def update_kernel(x_tt, q_tt, rot_tt, v_end, displacement, h, theta, from_start, lx, ly, periodic, position, quaternion,
                  velocity, omega, chunks):
    """Numba: end-of-step positions, orientations and velocities, positions wrapped in x, y in a
    periodic cell (``periodic``; a box or a cylinder holds its grains, nothing is wrapped).

    The end orientation is ``q^TT`` turned by ``θ h ω^{n+1}``; with ``from_start`` it is ``q^n``
    turned by ``h ω^{n+1}`` instead (``time_stepping.rotation_update = "from-start"``), which differs
    from the θ scheme the gaps are linearised in by ``(1 - θ) h (ω^{n+1} - ω^n)``.

    Args:
        x_tt, q_tt, rot_tt: predicted configuration ``(N, 3)``, ``(N, 4)``, ``(N, 3, 3)``.
        v_end: ``(N + 1, 6)`` world generalised velocities at t_{n+1}.
        displacement: ``(N + 1, 6)`` world position correction ``(δx, δφ)``, d and radians.
        h, theta: time step and θ.
        from_start: turn the orientation at t_n by ``h ω^{n+1}`` (see above).
        lx, ly: periods of the cell, d; periodic: wrap the positions (else lx, ly unused).
        position, quaternion, velocity, omega: state arrays, overwritten (omega body frame).
        chunks: consecutive ranges of bodies computed at once (threads); the result does not
            depend on it.
    """
    n = position.shape[0]
    for c in prange(chunks):
        _update_bodies(n * c // chunks, n * (c + 1) // chunks, x_tt, q_tt, rot_tt, v_end, displacement, h, theta,
                       from_start, lx, ly, periodic, position, quaternion, velocity, omega)


@jit
def _update_bodies(p0, p1, x_tt, q_tt, rot_tt, v_end, displacement, h, theta, from_start, lx, ly, periodic, position,
                   quaternion, velocity, omega):
    """Numba: :func:`update_kernel` for the bodies ``p0 <= p < p1``."""
    b = theta * h
    phi = np.empty(3)
    for p in range(p0, p1):
        rot = rot_tt[p]
        for k in range(3):
            velocity[p, k] = v_end[p, k]
            position[p, k] = x_tt[p, k] + b * v_end[p, k] + displacement[p, k]
        for k in range(3):
            w_body = rot[0, k] * v_end[p, 3] + rot[1, k] * v_end[p, 4] + rot[2, k] * v_end[p, 5]
            d_body = rot[0, k] * displacement[p, 3] + rot[1, k] * displacement[p, 4] + rot[2, k] * displacement[p, 5]
            omega[p, k] = w_body
            phi[k] = b * w_body + d_body
        if from_start:
            start = quat_to_matrix_nb(quaternion[p])
            for k in range(3):
                phi[k] = (h * (start[0, k] * v_end[p, 3] + start[1, k] * v_end[p, 4] + start[2, k] * v_end[p, 5])
                          + start[0, k] * displacement[p, 3] + start[1, k] * displacement[p, 4]
                          + start[2, k] * displacement[p, 5])
            q = quat_integrate_body_nb(quaternion[p], phi)
        else:
            q = quat_integrate_body_nb(q_tt[p], phi)
        for k in range(4):
            quaternion[p, k] = q[k]
        if periodic:
            x = position[p, 0] - lx * np.floor(position[p, 0] / lx)
            y = position[p, 1] - ly * np.floor(position[p, 1] / ly)
            position[p, 0] = x if x < lx else 0.0
            position[p, 1] = y if y < ly else 0.0


def required_alert(state: ParticleState, time_step: float, minimum: float = 0.0) -> float:
    """Smallest alert distance that cannot miss a contact over the next step, d.

    A pair is detected at the predicted configuration of a step when its gap is at most the
    alert ``a``; it must not close a gap larger than ``a`` before the next detection, one step
    later. The surface points of body p move at most ``|v_p| + r_p |ω_p|`` (``r_p`` the
    circumscribed radius), two bodies approach at most twice the largest such speed, and gravity
    adds at most ``g h`` to the speed over the step (toward the wall), so

    .. math:: a \\ge 2 h \\max_p (|v_p| + r_p |ω_p|) + g h^2

    (g = 1). Velocities change during the step through contacts, but contacts only slow
    approaches down, so the bound holds for free grains; callers should add a margin (e.g. take
    ``minimum`` = 0.02 d) and refresh it every step or every few steps.

    Args:
        state: the bodies (velocities at the start of the step).
        time_step: h, sqrt(d/g).
        minimum: returned when larger, d.

    Returns:
        The alert distance, d.
    """
    if state.n == 0:
        return float(minimum)
    speed = np.linalg.norm(state.velocity, axis=1) + state.radius * np.linalg.norm(state.omega, axis=1)
    h = float(time_step)
    return float(max(minimum, 2.0 * h * float(speed.max()) + h * h))


def kinetic_energy(state: ParticleState) -> float:
    """Total kinetic energy, translational plus rotational (body frame), m g d.

    .. math:: E_k = \\sum_p \\tfrac12 m_p |v_p|^2 + \\tfrac12 ω_p \\cdot J_p ω_p
    """
    m = state.mass
    return float(0.5 * np.sum(m * np.sum(state.velocity**2, axis=1)) + 0.5 * np.sum(state.inertia * state.omega**2))


def potential_energy(state: ParticleState) -> float:
    """Gravitational potential energy ``Σ m_p g z_p`` above the wall (g = 1), m g d."""
    return float(np.sum(state.mass * state.position[:, 2]))


def total_energy(state: ParticleState) -> float:
    """Kinetic plus gravitational potential energy, m g d."""
    return kinetic_energy(state) + potential_energy(state)

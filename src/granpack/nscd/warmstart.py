"""Warm start: the previous step's impulses carried over to the same contacts (docs: Method > NSCD, warm start).

Identity of a contact point: the same pair of bodies (in either candidate/antagonist order, a
wall being its negative id) and a contact point within ``tolerance`` of the previous one **in the body
frame of the new candidate i**. The periodic image is implied by the pair, because the cell is
more than twice the interaction range (docs: Method, the cell), so a pair whose shift changed only
because one body was wrapped across the boundary keeps its impulses.

The previous points were computed at the previous predicted configuration ``TT'`` and the new
ones at ``TT``. Between the two, body i moved rigidly by ``h v^n`` and turned by ``h ω^n``
(body frame; the two θ-split increments of the scheme compose to exactly this), so the old point
in the old body frame is

.. math::

    b_{old} = Δ\\, R^{TT\\,T}\\, \\mathrm{mi}\\big(x_{old} - (x_i^{TT} - h v_i^n)\\big), \\qquad
    Δ = \\mathrm{Rot}(h ω_i^n),

(``mi``: minimum image in x, y), compared with ``b_new = R^{TT T}(x_new - x_i^{TT})``. The
position correction moved bodies by far less than the tolerance and is ignored here. Each old
point is used at most once (nearest first). The old world impulse ``P`` (on the old candidate;
sign flipped if the roles swapped) gives the local impulse ``(max(0, P·n), P·t, P·s)``, the
tangential part clipped to the friction disc ``μ r_n`` (the grains' μ, or the walls' against a
wall). A polyhedron has one manifold per vertex near a cylinder, so a new cylinder manifold takes
the old one of the same grain whose point is nearest its own in the world frame.
"""

from __future__ import annotations

import numpy as np

from granpack._numba import MIN_PARALLEL_POINTS, jit, prange, thread_count
from granpack.contact.contacts import WALL_CYLINDER, ContactSet

__all__ = ["warm_impulses"]


@jit
def _rotation(phi):
    """Numba: ``(k0, k1, k2, cos, sin, turns)`` of the rotation vector ``phi`` (tuple of 3): unit
    axis, cosine and sine of its angle, and whether it turns at all (angle >= 1e-300)."""
    angle = np.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    if angle < 1e-300:
        return 0.0, 0.0, 1.0, 1.0, 0.0, False
    return phi[0] / angle, phi[1] / angle, phi[2] / angle, np.cos(angle), np.sin(angle), True


@jit
def _rotate(k0, k1, k2, c, s, x0, x1, x2):
    """Numba: Rodrigues rotation of ``(x0, x1, x2)`` about the unit axis ``k`` by the angle whose
    cosine and sine are ``c``, ``s``."""
    kx0 = k1 * x2 - k2 * x1
    kx1 = k2 * x0 - k0 * x2
    kx2 = k0 * x1 - k1 * x0
    kd = (1.0 - c) * (k0 * x0 + k1 * x1 + k2 * x2)
    return x0 * c + kx0 * s + k0 * kd, x1 * c + kx1 * s + k1 * kd, x2 * c + kx2 * s + k2 * kd


@jit(parallel=True)
def _warm_kernel(
    old_i, old_j, old_start, old_point, old_impulse,
    new_i, new_j, new_start, new_point, normal, tangent,
    x_tt, rot_tt, velocity, omega, h, lx, ly, tol, mu, out, chunks,
):
    """Numba: the warm start of every new point (module docstring); returns the points matched.

    The new manifolds are matched in ``chunks`` consecutive ranges at once: each old manifold is
    the pair of at most one new manifold, so the ranges share no old point and the result does
    not depend on ``chunks``.
    """
    n_bodies = x_tt.shape[0]
    # CSR of old manifolds per body (each manifold listed under both of its particles)
    count = np.zeros(n_bodies + 1, np.int64)
    widest = 0
    for m in range(old_i.shape[0]):
        count[old_i[m] + 1] += 1
        if old_j[m] >= 0:
            count[old_j[m] + 1] += 1
        widest = max(widest, old_start[m + 1] - old_start[m])
    start = np.cumsum(count)
    fill = start[:-1].copy()
    listed = np.empty(start[-1], np.int64)
    for m in range(old_i.shape[0]):
        listed[fill[old_i[m]]] = m
        fill[old_i[m]] += 1
        if old_j[m] >= 0:
            listed[fill[old_j[m]]] = m
            fill[old_j[m]] += 1
    used = np.zeros(old_point.shape[0], np.bool_)
    matched = np.zeros(chunks, np.int64)
    n = new_i.shape[0]
    for c in prange(chunks):
        matched[c] = _match(
            n * c // chunks, n * (c + 1) // chunks, start, listed, used, widest, old_i, old_j, old_start, old_point,
            old_impulse, new_i, new_j, new_start, new_point, normal, tangent, x_tt, rot_tt, velocity, omega, h, lx,
            ly, tol, mu, out,
        )
    return matched.sum()


@jit
def _match(
    m0, m1, start, listed, used, widest, old_i, old_j, old_start, old_point, old_impulse,
    new_i, new_j, new_start, new_point, normal, tangent, x_tt, rot_tt, velocity, omega, h, lx, ly, tol, mu, out,
):
    """Numba: the warm start of the points of new manifolds ``m0 <= m < m1``; returns the points
    matched (``start``, ``listed``: CSR of the old manifolds of each body; ``used``: old points
    taken)."""
    old_body = np.empty((widest, 3))  # the old points of the matched manifold, in i's new body frame
    matched = 0
    tol2 = tol * tol
    last = -1
    k0, k1, k2, cos, sin, turns = 0.0, 0.0, 1.0, 1.0, 0.0, False
    for m in range(m0, m1):
        i, j = new_i[m], new_j[m]
        found = -1
        sign = 1.0
        nearest = np.inf
        for e in range(start[i], start[i + 1]):
            o = listed[e]
            if old_i[o] == i and old_j[o] == j:
                if j != WALL_CYLINDER:
                    found = o
                    break
                q, k = old_start[o], new_start[m]
                d2 = ((old_point[q, 0] - new_point[k, 0]) ** 2 + (old_point[q, 1] - new_point[k, 1]) ** 2
                      + (old_point[q, 2] - new_point[k, 2]) ** 2)
                if d2 < nearest:
                    found, nearest = o, d2
                continue
            if j >= 0 and old_i[o] == j and old_j[o] == i:
                found = o
                sign = -1.0
                break
        for k in range(new_start[m], new_start[m + 1]):
            out[k, 0] = 0.0
            out[k, 1] = 0.0
            out[k, 2] = 0.0
        if found < 0:
            continue
        rot = rot_tt[i]
        if i != last:  # manifolds come ordered by i: one rotation per body
            k0, k1, k2, cos, sin, turns = _rotation((h * omega[i, 0], h * omega[i, 1], h * omega[i, 2]))
            last = i
        back0 = x_tt[i, 0] - h * velocity[i, 0]
        back1 = x_tt[i, 1] - h * velocity[i, 1]
        back2 = x_tt[i, 2] - h * velocity[i, 2]
        q0 = old_start[found]
        for q in range(q0, old_start[found + 1]):
            a0 = old_point[q, 0] - back0
            a1 = old_point[q, 1] - back1
            a2 = old_point[q, 2] - back2
            if abs(a0) > 0.5 * lx:  # minimum image (most points are not across the boundary)
                a0 -= lx * np.round(a0 / lx)
            if abs(a1) > 0.5 * ly:
                a1 -= ly * np.round(a1 / ly)
            c0 = rot[0, 0] * a0 + rot[1, 0] * a1 + rot[2, 0] * a2
            c1 = rot[0, 1] * a0 + rot[1, 1] * a1 + rot[2, 1] * a2
            c2 = rot[0, 2] * a0 + rot[1, 2] * a1 + rot[2, 2] * a2
            if turns:
                c0, c1, c2 = _rotate(k0, k1, k2, cos, sin, c0, c1, c2)
            old_body[q - q0, 0], old_body[q - q0, 1], old_body[q - q0, 2] = c0, c1, c2
        for k in range(new_start[m], new_start[m + 1]):
            d0 = new_point[k, 0] - x_tt[i, 0]
            d1 = new_point[k, 1] - x_tt[i, 1]
            d2 = new_point[k, 2] - x_tt[i, 2]
            b0 = rot[0, 0] * d0 + rot[1, 0] * d1 + rot[2, 0] * d2
            b1 = rot[0, 1] * d0 + rot[1, 1] * d1 + rot[2, 1] * d2
            b2 = rot[0, 2] * d0 + rot[1, 2] * d1 + rot[2, 2] * d2
            best = -1
            best_d2 = tol2
            for q in range(q0, old_start[found + 1]):
                if used[q]:
                    continue
                dist2 = (old_body[q - q0, 0] - b0) ** 2 + (old_body[q - q0, 1] - b1) ** 2 + (old_body[q - q0, 2] - b2) ** 2
                if dist2 < best_d2:
                    best_d2 = dist2
                    best = q
            if best < 0:
                continue
            used[best] = True
            matched += 1
            p0, p1, p2 = sign * old_impulse[best, 0], sign * old_impulse[best, 1], sign * old_impulse[best, 2]
            rn = max(0.0, p0 * normal[m, 0] + p1 * normal[m, 1] + p2 * normal[m, 2])
            rt = p0 * tangent[k, 0, 0] + p1 * tangent[k, 0, 1] + p2 * tangent[k, 0, 2]
            rs = p0 * tangent[k, 1, 0] + p1 * tangent[k, 1, 1] + p2 * tangent[k, 1, 2]
            limit = (mu[0] if j >= 0 else mu[1]) * rn
            norm = np.sqrt(rt * rt + rs * rs)
            if norm > limit:
                scale = limit / norm
                rt *= scale
                rs *= scale
            out[k, 0], out[k, 1], out[k, 2] = rn, rt, rs
    return matched


def warm_impulses(
    previous: ContactSet | None,
    contacts: ContactSet,
    tangent: np.ndarray,
    x_tt: np.ndarray,
    rot_tt: np.ndarray,
    velocity: np.ndarray,
    omega: np.ndarray,
    time_step: float,
    periods: tuple[float, float],
    tolerance: float,
    friction: float,
    wall_friction: float | None = None,
) -> tuple[np.ndarray, int]:
    """Local warm-start impulses of the new contact points from the previous step's solution.

    Args:
        previous: the previous step's contacts with their ``impulse`` (``None``: no warm start).
        contacts: the new contacts, detected at the predicted configuration.
        tangent: ``(P, 2, 3)`` tangent vectors of the new points.
        x_tt: ``(N, 3)`` predicted centres (as given to detection), d.
        rot_tt: ``(N, 3, 3)`` predicted rotation matrices.
        velocity, omega: ``(N, 3)`` velocities at t_n (omega body frame).
        time_step: h, sqrt(d/g).
        periods: ``(lx, ly)``, d.
        tolerance: matching distance in the body frame, d.
        friction: μ between grains (the tangential part is clipped to ``μ r_n``).
        wall_friction: μ against a wall (``None``: ``friction``).

    Returns:
        ``((P, 3) local impulses, number of points matched)``.
    """
    p = contacts.n_points
    out = np.zeros((p, 3))
    if previous is None or previous.impulse is None or previous.n_points == 0 or p == 0:
        return out, 0
    matched = _warm_kernel.sized(p, MIN_PARALLEL_POINTS)(
        np.ascontiguousarray(previous.body_i, dtype=np.int64),
        np.ascontiguousarray(previous.body_j, dtype=np.int64),
        np.ascontiguousarray(previous.point_start, dtype=np.int64),
        np.ascontiguousarray(previous.point, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(previous.impulse, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(contacts.body_i, dtype=np.int64),
        np.ascontiguousarray(contacts.body_j, dtype=np.int64),
        np.ascontiguousarray(contacts.point_start, dtype=np.int64),
        np.ascontiguousarray(contacts.point, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(contacts.normal, dtype=np.float64).reshape(-1, 3),
        tangent,
        x_tt,
        rot_tt,
        velocity,
        omega,
        float(time_step),
        float(periods[0]),
        float(periods[1]),
        float(tolerance),
        np.array([friction, friction if wall_friction is None else wall_friction], dtype=np.float64),
        out,
        thread_count(),
    )
    return out, int(matched)

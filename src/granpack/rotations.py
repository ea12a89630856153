"""Quaternion helpers.

Convention (owned here): unit quaternions are scalar-first ``(w, x, y, z)``, the GSD / HOOMD
order. ``R(q)`` rotates body-frame vectors into the world frame, so the columns of ``R`` are the
body axes expressed in world coordinates (u = R e_x, v = R e_y, w = R e_z).

Scalar kernels (``*_nb``) are Numba-compiled for use inside other kernels; the array helpers
are vectorised NumPy for setup and analysis.
"""

from __future__ import annotations

import numpy as np

from granpack._numba import jit

__all__ = [
    "quat_to_matrix",
    "quat_multiply",
    "quat_from_axis_angle",
    "random_quaternions",
    "rotate",
    "quat_to_matrix_nb",
    "quat_multiply_nb",
    "quat_integrate_body_nb",
]


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices of unit quaternions.

    Args:
        q: quaternions ``(w, x, y, z)``, shape ``(4,)`` or ``(N, 4)``.

    Returns:
        Rotation matrices, shape ``(3, 3)`` or ``(N, 3, 3)``, body -> world.
    """
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = np.moveaxis(q, -1, 0)
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - z * w)
    m[..., 0, 2] = 2 * (x * z + y * w)
    m[..., 1, 0] = 2 * (x * y + z * w)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - x * w)
    m[..., 2, 0] = 2 * (x * z - y * w)
    m[..., 2, 1] = 2 * (y * z + x * w)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` (apply ``b`` first, then ``a``), shapes ``(..., 4)``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_from_axis_angle(axis, angle: float) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle`` (radians) about ``axis`` (any length > 0)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def random_quaternions(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` quaternions uniform (Haar) on SO(3), Shoemake's method, shape ``(n, 4)``."""
    u1, u2, u3 = rng.random((3, n))
    a, b = np.sqrt(1.0 - u1), np.sqrt(u1)
    q = np.stack(
        [b * np.cos(2 * np.pi * u3), a * np.sin(2 * np.pi * u2), a * np.cos(2 * np.pi * u2), b * np.sin(2 * np.pi * u3)],
        axis=-1,
    )
    return q


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate body-frame vectors ``v`` (``(..., 3)``) by quaternions ``q`` into the world frame."""
    return np.einsum("...ij,...j->...i", quat_to_matrix(q), v)


@jit
def quat_to_matrix_nb(q):
    """Numba: rotation matrix (3, 3) of one unit quaternion ``(w, x, y, z)``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    m = np.empty((3, 3))
    m[0, 0] = 1 - 2 * (y * y + z * z)
    m[0, 1] = 2 * (x * y - z * w)
    m[0, 2] = 2 * (x * z + y * w)
    m[1, 0] = 2 * (x * y + z * w)
    m[1, 1] = 1 - 2 * (x * x + z * z)
    m[1, 2] = 2 * (y * z - x * w)
    m[2, 0] = 2 * (x * z - y * w)
    m[2, 1] = 2 * (y * z + x * w)
    m[2, 2] = 1 - 2 * (x * x + y * y)
    return m


@jit
def quat_multiply_nb(a, b):
    """Numba: Hamilton product ``a ⊗ b`` of two quaternions, returns a new (4,) array."""
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    return out


@jit
def quat_integrate_body_nb(q, phi):
    """Numba: ``q ⊗ exp(phi / 2)`` for a body-frame rotation vector ``phi`` (radians), renormalised.

    .. math:: q \\leftarrow q \\otimes (\\cos(|\\phi|/2), \\sin(|\\phi|/2)\\, \\phi/|\\phi|)
    """
    angle = np.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    dq = np.empty(4)
    if angle < 1e-300:
        dq[0] = 1.0
        dq[1] = 0.5 * phi[0]
        dq[2] = 0.5 * phi[1]
        dq[3] = 0.5 * phi[2]
    else:
        s = np.sin(0.5 * angle) / angle
        dq[0] = np.cos(0.5 * angle)
        dq[1] = s * phi[0]
        dq[2] = s * phi[1]
        dq[3] = s * phi[2]
    out = quat_multiply_nb(q, dq)
    norm = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    for k in range(4):
        out[k] /= norm
    return out

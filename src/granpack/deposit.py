"""Geometric sequential deposition of spheres (the shells of PHYSICS §4.1) in a vertical box.

Box (owned here for the deposit only): square cross-section ``[0, L] x [0, L]``, floor ``z = 0``,
open top, either lateral walls at ``x = 0, L`` and ``y = 0, L`` or periodic in x and y with
period ``L`` (then centres are returned wrapped into ``[0, L)``, as in :mod:`granpack.box`).
Lengths are in the caller's unit (d in granpack). Gravity is ``-e_z``.

Two rules, both sequential (spheres are placed one by one in the given order; the caller
shuffles the populations):

``method="drop"`` (PHYSICS §4.2, Visscher & Bolsterli 1972): each sphere is released above the
pile at a uniformly random ``(x, y)`` and follows the quasi-static steepest descent of its height
among the fixed deposited spheres, the floor and the walls: it falls vertically to a first
support, rolls on one sphere (on the sphere of radius ``R + R_j`` about ``x_j``, in the vertical
plane through ``x_j``) until it touches a second support or reaches the equator of ``j`` (then it
falls again), rolls on the circle of two supports until a third contact, a multiplier vanishes
(it then rolls on the other support) or the lowest point of the circle, and stops where the
supports ``k`` in contact hold it:

.. math:: e_z = \\sum_k \\lambda_k n_k, \\qquad \\lambda_k \\ge 0,

with ``n_k`` the unit normal of support ``k`` pointing to the centre. The supports kept at each
step are the active set of the non-negative least squares solution of that equation, which
drops the supports with negative multipliers. Touching the floor ends the drop. Contacts along
the arcs are exact (closed form); a final position overlapping anything by more than
``1e-9 d`` (d the largest diameter) is rejected and the sphere is dropped again at a new
``(x, y)``. Bulk solid fraction of a monodisperse deposit in a periodic column: 0.581
(Visscher & Bolsterli: 0.582; see tests/test_deposit.py).

``method="lmgc"`` (PHYSICS §4.3, LMGC90 ``depositInBox3D``): each sphere goes to the lowest
position touching three supports (sphere + plane + plane, sphere + sphere + plane or three
spheres), the first support being one of the 100 most recent spheres with fewer than 8
contacts, among the positions inside the box, free of overlap and held by their supports
(this last filter is ours). Where no such position exists (the first spheres) the sphere is
dropped as with ``"drop"``. This gives a denser, layered deposit with a nearly flat top.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from granpack import _deposit_kernels as _k

__all__ = ["deposit"]

_CHUNK = 1024  # spheres per kernel call (fixed: the random stream must not depend on progress)
_INITIAL_FRACTION = 0.45  # solid fraction assumed to size the grid height (it grows if needed)


def deposit(
    radii,
    lateral_size: float,
    rng: np.random.Generator,
    *,
    lateral: str = "walls",
    method: str = "drop",
    progress: bool | Callable[[int, int], None] | None = None,
) -> np.ndarray:
    """Deposit spheres one by one in a vertical box; return their resting centres.

    Args:
        radii: sphere radii, shape ``(N,)``, > 0, in d; spheres are placed in this order.
        lateral_size: side ``L`` of the square cross-section, in d; at least the largest diameter.
        rng: random generator; it draws the release points (2 numbers per attempt, in chunks),
            so the same seed gives identical centres.
        lateral: ``"walls"`` (planes ``x = 0, L``, ``y = 0, L``) or ``"periodic"`` (period ``L``
            in x and y, centres wrapped into ``[0, L)``).
        method: ``"drop"`` (drop-and-roll, PHYSICS §4.2) or ``"lmgc"`` (lowest three-support
            position, PHYSICS §4.3).
        progress: ``None``/``False`` (quiet, default), ``True`` (a rich progress bar) or a
            callable ``progress(done, total)`` called after each chunk of spheres.

    Returns:
        Centres, shape ``(N, 3)``, float64, in d: no two spheres (periodic images included)
        overlap by more than ``1e-9 d``, every sphere lies inside the box and above the floor
        within that tolerance and rests on supports that hold it under gravity.

    Raises:
        ValueError: radii not a non-empty 1-D array of finite positive numbers, ``lateral_size``
            not finite or smaller than the largest diameter, or an unknown ``lateral``/``method``.
        RuntimeError: a sphere could not be placed in ``MAX_ATTEMPTS`` release attempts.
    """
    rad, lsize, periodic, lmgc = _validate(radii, lateral_size, rng, lateral, method)
    n = rad.shape[0]
    rmax = float(rad.max())
    dmax = 2.0 * rmax

    # cell grid: lateral cells of side >= d_max (>= R + R_max for every pair), layers of d_max
    nx = max(1, int(lsize // dmax))
    hxy = lsize / nx
    hz = dmax
    height = (4.0 / 3.0) * math.pi * float(np.sum(rad**3)) / (lsize * lsize * _INITIAL_FRACTION)
    nz = int(height / hz) + 3
    head = np.full(nx * nx * nz, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    pos = np.zeros((n, 3))
    ncont = np.zeros(n, dtype=np.int64)

    # candidate buffers: a query box is at most 4 d_max wide, so it meets at most
    # (4 d_max / L + 2)^2 periodic images of each sphere
    images = (int(4.0 * dmax / lsize) + 2) ** 2 if periodic else 1
    cap = n * images + 16
    out_i = np.empty(cap, dtype=np.int64)
    out_k = np.empty((cap, 2), dtype=np.int64)
    nbc = np.empty((cap, 3))
    nbd = np.empty(cap)

    report = _progress_reporter(progress, n)
    top = 0.0
    done = 0
    with report as tick:
        while done < n:
            stop = min(done + _CHUNK, n)
            uni = rng.random((stop - done + _k.MAX_ATTEMPTS, 2))
            nxt_i, _, top, status = _k.deposit_chunk(
                lmgc, pos, rad, ncont, done, stop, uni, head, nxt, nx, nx, nz, hxy, hz, lsize,
                periodic, rmax, top, out_i, out_k, nbc, nbd,
            )
            done = nxt_i
            if status == _k.STATUS_FAILED:
                raise RuntimeError(
                    f"deposit: sphere {done} (radius {rad[done]:g}) found no resting place in "
                    f"{_k.MAX_ATTEMPTS} release attempts"
                )
            if status == _k.STATUS_BUFFER:
                raise RuntimeError("deposit: neighbour buffer overflow (internal error)")
            if top > 0.75 * nz * hz:
                nz = 2 * int(top / hz) + 3
                head = np.full(nx * nx * nz, -1, dtype=np.int64)
                _k.grid_build(pos, done, head, nxt, nx, nx, nz, hxy, hz)
            tick(done)
    return pos


def _validate(radii, lateral_size, rng, lateral, method):
    """Checked inputs: ``(radii float64 (N,), L, periodic, lmgc)``; ValueError names the culprit."""
    rad = np.asarray(radii, dtype=np.float64)
    if rad.ndim != 1 or rad.shape[0] == 0:
        raise ValueError(f"deposit: radii must be a non-empty 1-D array, got shape {rad.shape}")
    if not np.all(np.isfinite(rad)) or np.any(rad <= 0.0):
        bad = rad[~(np.isfinite(rad) & (rad > 0.0))][0]
        raise ValueError(f"deposit: radii must be finite and > 0, got {bad!r}")
    lsize = float(lateral_size)
    dmax = 2.0 * float(rad.max())
    if not math.isfinite(lsize) or lsize < dmax:
        raise ValueError(
            f"deposit: lateral_size must be at least the largest diameter {dmax:g}, got {lsize!r}"
        )
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"deposit: rng must be a numpy.random.Generator, got {type(rng).__name__}")
    if lateral not in ("walls", "periodic"):
        raise ValueError(f"deposit: lateral must be 'walls' or 'periodic', got {lateral!r}")
    if method not in ("drop", "lmgc"):
        raise ValueError(f"deposit: method must be 'drop' or 'lmgc', got {method!r}")
    return np.ascontiguousarray(rad), lsize, lateral == "periodic", method == "lmgc"


class _progress_reporter:
    """Context manager yielding ``tick(done)``: silent, a user callback, or a rich progress bar."""

    def __init__(self, progress, total):
        self._progress = progress
        self._total = total
        self._bar = None

    def __enter__(self):
        if callable(self._progress):
            return lambda done: self._progress(done, self._total)
        if self._progress:
            from rich.progress import Progress

            self._bar = Progress(transient=True)
            self._bar.__enter__()
            task = self._bar.add_task("deposit", total=self._total)
            return lambda done: self._bar.update(task, completed=done)
        return lambda done: None

    def __exit__(self, *exc):
        if self._bar is not None:
            self._bar.__exit__(*exc)
        return False

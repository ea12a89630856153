"""The sequential loop shared by both rules: :func:`deposit` (Python: checks, grid, chunks of
random numbers, progress) and :func:`deposit_chunk` (Numba: one sphere after the other).

Each sphere first gets the rule's own placement (``"lmgc"``: :func:`~granpack.deposit.lmgc.lmgc_one`;
``"drop"``: none); where that finds nothing, it is dropped (:func:`~granpack.deposit.drop.drop_one`)
from random release points until it rests at an admissible place. The random numbers are drawn
in fixed chunks of release points, so the centres depend on the generator only, not on progress.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from granpack._numba import jit
from granpack.deposit.drop import drop_one
from granpack.deposit.geometry import CYLINDER_SIDES, OVERLAP_TOL, inside_box, wall_table
from granpack.deposit.grid import gather_ball, grid_build, grid_insert
from granpack.deposit.lmgc import count_contacts, lmgc_one

__all__ = ["deposit"]

MAX_ATTEMPTS = 1000  # attempts (random (x, y)) per sphere before the deposit fails

STATUS_DONE = 0
STATUS_NEED_UNIFORMS = 1
STATUS_FAILED = 2
STATUS_BUFFER = 3

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
        lateral: ``"walls"`` (planes ``x = 0, L``, ``y = 0, L``), ``"periodic"`` (period ``L``
            in x and y, centres wrapped into ``[0, L)``) or ``"cylinder"`` (inside a vertical
            cylinder of diameter ``L`` and axis ``(L/2, L/2)``: inside the regular polygon of
            ``CYLINDER_SIDES`` sides inscribed in it, :func:`~granpack.deposit.geometry.wall_table`).
        method: ``"drop"`` (drop-and-roll) or ``"lmgc"`` (lowest three-support position);
            see :mod:`granpack.deposit`.
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
    walls = wall_table(lateral, lsize)
    # release points of a cylinder: in the disc of the polygon's apothem
    disc = 0.5 * lsize * math.cos(math.pi / CYLINDER_SIDES) if lateral == "cylinder" else 0.0
    n = rad.shape[0]
    rmax = float(rad.max())
    dmax = 2.0 * rmax

    # cell grid: lateral cells of side >= d_max (>= R + R_max for every pair), layers of d_max
    nx = max(1, int(lsize // dmax))
    hxy = lsize / nx
    hz = dmax
    area = 0.25 * math.pi * lsize * lsize if lateral == "cylinder" else lsize * lsize
    height = (4.0 / 3.0) * math.pi * float(np.sum(rad**3)) / (area * _INITIAL_FRACTION)
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
            uni = rng.random((stop - done + MAX_ATTEMPTS, 2))
            nxt_i, _, top, status = deposit_chunk(
                lmgc, pos, rad, ncont, done, stop, uni, head, nxt, nx, nx, nz, hxy, hz, lsize,
                periodic, walls, disc, rmax, top, out_i, out_k, nbc, nbd,
            )
            done = nxt_i
            if status == STATUS_FAILED:
                raise RuntimeError(
                    f"deposit: sphere {done} (radius {rad[done]:g}) found no resting place in "
                    f"{MAX_ATTEMPTS} release attempts"
                )
            if status == STATUS_BUFFER:
                raise RuntimeError("deposit: neighbour buffer overflow (internal error)")
            if top > 0.75 * nz * hz:
                nz = 2 * int(top / hz) + 3
                head = np.full(nx * nx * nz, -1, dtype=np.int64)
                grid_build(pos, done, head, nxt, nx, nx, nz, hxy, hz)
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
    if lateral not in ("walls", "periodic", "cylinder"):
        raise ValueError(f"deposit: lateral must be 'walls', 'periodic' or 'cylinder', got {lateral!r}")
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


@jit
def admissible(radius, q, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, rmax, out_i, out_k, lo,
               hi):
    """Whether a sphere of radius ``R`` at ``q`` lies inside the planes ``walls`` and overlaps no
    deposited sphere by more than ``OVERLAP_TOL d``: 1 (admissible), 0 (not) or -1 (buffer
    overflow)."""
    tol = OVERLAP_TOL * 2.0 * rmax
    if not inside_box(radius, q, walls, tol):
        return 0
    m = gather_ball(q, radius + rmax, lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)
    if m < 0:
        return -1
    for k in range(m):
        j = out_i[k]
        dx = q[0] - (pos[j, 0] + out_k[k, 0] * lsize)
        dy = q[1] - (pos[j, 1] + out_k[k, 1] * lsize)
        dz = q[2] - pos[j, 2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) < radius + rad[j] - tol:
            return 0
    return 1


@jit
def deposit_chunk(
    lmgc, pos, rad, ncont, start, stop, uni, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, disc, rmax,
    top, out_i, out_k, nbc, nbd,
):
    """Place spheres ``start .. stop-1`` in order; each drop attempt consumes a row of ``uni``
    (U(0,1)^2).

    ``lmgc`` selects the LMGC90 rule (drop-and-roll is then used only where it finds no
    three-support position: the first spheres). With lateral walls the release point is
    ``(R + u_0 (L - 2R), R + u_1 (L - 2R))``, periodic ``(u_0 L, u_1 L)``, in a cylinder (``disc``
    > 0, the apothem of its polygon ``walls``) uniform in the disc of radius ``disc - R`` about
    the axis, ``(L/2, L/2) + (disc - R) sqrt(u_0) (cos 2 pi u_1, sin 2 pi u_1)``; the release height is
    ``top + R + 0.01 d`` with ``top`` the highest point of the deposit. Accepted centres (x, y
    wrapped when periodic) go to ``pos`` and the grid.

    Returns ``(next, used, top, status)``: the first sphere not placed, the rows of ``uni``
    consumed, the updated ``top`` and ``STATUS_DONE``, ``STATUS_NEED_UNIFORMS`` (call again with
    fresh ``uni`` from ``next``), ``STATUS_FAILED`` (sphere ``next`` could not be placed in
    ``MAX_ATTEMPTS`` attempts) or ``STATUS_BUFFER`` (candidate buffers too small).
    """
    p = np.empty(3)
    lo = np.empty(3)
    hi = np.empty(3)
    used = 0
    dmax = 2.0 * rmax
    for i in range(start, stop):
        radius = rad[i]
        placed = 0
        if lmgc and i > 0:
            placed = lmgc_one(
                i, radius, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, rmax,
                out_i, out_k, nbc, nbd, lo, hi, p,
            )
            if placed < 0:
                return i, used, top, STATUS_BUFFER
        attempts = 0
        while placed == 0:
            if attempts == MAX_ATTEMPTS:
                return i, used, top, STATUS_FAILED
            if used == uni.shape[0]:
                return i, used, top, STATUS_NEED_UNIFORMS
            if periodic:
                x0 = uni[used, 0] * lsize
                y0 = uni[used, 1] * lsize
            elif disc > 0.0:
                rho = (disc - radius) * math.sqrt(uni[used, 0])
                x0 = 0.5 * lsize + rho * math.cos(2.0 * math.pi * uni[used, 1])
                y0 = 0.5 * lsize + rho * math.sin(2.0 * math.pi * uni[used, 1])
            else:
                x0 = radius + uni[used, 0] * (lsize - 2.0 * radius)
                y0 = radius + uni[used, 1] * (lsize - 2.0 * radius)
            used += 1
            attempts += 1
            ok = drop_one(
                radius, x0, y0, top + radius + 0.01 * dmax, pos, rad, head, nxt, nx, ny, nz, hxy, hz,
                lsize, periodic, walls, rmax, out_i, out_k, lo, hi, p,
            )
            if ok < 0:
                return i, used, top, STATUS_BUFFER
            if ok == 1:
                placed = admissible(
                    radius, p, pos, rad, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, walls, rmax,
                    out_i, out_k, lo, hi,
                )
                if placed < 0:
                    return i, used, top, STATUS_BUFFER
        if periodic:
            p[0] -= lsize * math.floor(p[0] / lsize)
            p[1] -= lsize * math.floor(p[1] / lsize)
            if p[0] >= lsize:
                p[0] = 0.0
            if p[1] >= lsize:
                p[1] = 0.0
        for a in range(3):
            pos[i, a] = p[a]
        grid_insert(i, pos, head, nxt, nx, ny, nz, hxy, hz)
        top = max(top, p[2] + radius)
        if lmgc and count_contacts(
            i, pos, rad, ncont, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, rmax, out_i, out_k, lo, hi
        ) < 0:
            return i, used, top, STATUS_BUFFER
    return stop, used, top, STATUS_DONE

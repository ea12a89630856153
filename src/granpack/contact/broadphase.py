"""Broad phase: candidate pairs from a cell grid in the bi-periodic box, with a Verlet skin.

Every grain is bounded by its circumscribed sphere (radius ``R``, centred on the centre of mass,
so orientation does not matter). A pair ``(i, j)`` is a candidate when, for the nearest periodic
image ``x_j + shift`` (``shift = (kx lx, ky ly, 0)``),

.. math:: |x_i - x_j - \\mathrm{shift}| < R_i + R_j + \\mathrm{cutoff},

with ``cutoff`` = alert distance + skin. Because the box satisfies
``lx, ly > 2 (d_max + alert)`` (docs/method/index.md#the-cell), a pair interacts through one image at most,
which is the minimum image; the shift is therefore not stored and is recomputed from the current
positions by the narrow phase (it changes when a grain is wrapped across the boundary).

Grid: cells of side about ``2 R_min + cutoff`` (at least a quarter of ``2 R_max + cutoff``) in x,
y (periodic, ``nx = floor(lx / c)`` columns) and z (non-periodic, from the lowest to the highest
centre). Grain i searches the cells within ``2 R_i + cutoff`` and keeps the grains j that are
smaller than itself, so every pair of unequal grains is found once, from its larger member, and
small grains of a bidisperse mix (size ratio 3 and more) only scan a small neighbourhood. A pair of
equal grains is taken from the half shell: by the grain whose neighbour lies in a forward cell
(cell offset ``(z, y, x)`` lexicographically positive), or in the same cell by the lower index;
grains of the smallest size then skip the backward cells. A neighbourhood wider than the box (one
or two columns) visits each column once and keeps equal grains with ``j > i``, so no pair is
counted twice in small boxes.

Verlet reuse: pairs found with a skin stay valid while every grain has moved less than half the
skin since the list was built (displacements by minimum image).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from granpack._numba import jit

__all__ = ["candidate_pairs", "max_displacement", "VerletList"]


@jit
def _cell_index(x, period, n, width):
    """Column of coordinate ``x`` in a periodic direction of ``n`` columns of ``width``."""
    xw = x - period * math.floor(x / period)
    c = int(xw / width)
    if c >= n:
        c = n - 1
    if c < 0:
        c = 0
    return c


@jit
def _periodic_window(center, k, n, out):
    """Write the periodic cell indices ``center - k .. center + k`` (mod ``n``, each once) to
    ``out``; returns how many."""
    if 2 * k + 1 >= n:
        for c in range(n):
            out[c] = c
        return n
    for c in range(2 * k + 1):
        out[c] = (center - k + c) % n
    return 2 * k + 1


#: The cell grid of :func:`candidate_pairs`: cells of ``cell`` in z from the lowest centre up,
#: ``nx`` by ``ny`` periodic columns in x, y.
_CellGrid = namedtuple("_CellGrid", [
    "cell",  # float: side of a cell in z, and the least width of a column in x, y, d
    "nx",  # int: columns in x
    "ny",  # int: columns in y
    "nz",  # int: cells in z
    "wx",  # float: width of a column in x, d
    "wy",  # float: width of a column in y, d
    "cx",  # (N,) int64: column of each grain in x
    "cy",  # (N,) int64: column of each grain in y
    "cz",  # (N,) int64: cell of each grain in z
    "cell_start",  # (nx ny nz + 1,) int64: CSR over cells ((z ny + y) nx + x) of members
    "members",  # (N,) int64: the grains, cell after cell, each cell's in index order
    "rmin",  # float: the smallest radius, d
])


@jit
def candidate_pairs(position, radius, lx, ly, cutoff):
    """All pairs whose bounding spheres are closer than ``cutoff`` (nearest periodic image).

    Args:
        position: ``(N, 3)`` centres, d (x, y need not be wrapped).
        radius: ``(N,)`` circumscribed radii, d.
        lx, ly: periods, d; must exceed ``2 (2 max(radius) + cutoff)``.
        cutoff: extra distance (alert + skin), d.

    Returns:
        ``(pair_start, pair_j)``: CSR over ``i`` (``(N+1,)``) of the partners ``j > i``, each row
        sorted, so the pair list is in lexicographic order.
    """
    n = position.shape[0]
    if n == 0:
        return np.zeros(1, np.int64), np.zeros(0, np.int64)
    grid = _cell_grid(position, radius, lx, ly, cutoff)
    lo, hi, m = _close_pairs(position, radius, lx, ly, cutoff, grid)
    return _pair_rows(lo, hi, m, n)


@jit
def _cell_grid(position, radius, lx, ly, cutoff):
    """The :class:`_CellGrid` of ``N >= 1`` grains (centres ``position``, radii ``radius``, d) for
    the cutoff ``cutoff`` (d) in a box of periods ``lx``, ``ly`` (d): cells of side ``2 R_min +
    cutoff``, at least a quarter of ``2 R_max + cutoff`` (module docstring)."""
    n = position.shape[0]
    rmin = radius.min()
    rmax = radius.max()
    cell = max(2.0 * rmin + cutoff, 0.25 * (2.0 * rmax + cutoff))
    nx = max(1, int(lx / cell))
    ny = max(1, int(ly / cell))
    wx = lx / nx
    wy = ly / ny
    zmin = position[:, 2].min()
    zmax = position[:, 2].max()
    nz = int((zmax - zmin) / cell) + 1
    cx = np.empty(n, np.int64)
    cy = np.empty(n, np.int64)
    cz = np.empty(n, np.int64)
    counts = np.zeros(nx * ny * nz + 1, np.int64)
    for p in range(n):
        cx[p] = _cell_index(position[p, 0], lx, nx, wx)
        cy[p] = _cell_index(position[p, 1], ly, ny, wy)
        cz[p] = min(nz - 1, int((position[p, 2] - zmin) / cell))
        counts[(cz[p] * ny + cy[p]) * nx + cx[p] + 1] += 1
    cell_start = np.cumsum(counts)
    fill = cell_start[:-1].copy()
    members = np.empty(n, np.int64)
    for p in range(n):
        c = (cz[p] * ny + cy[p]) * nx + cx[p]
        members[fill[c]] = p
        fill[c] += 1
    return _CellGrid(cell, nx, ny, nz, wx, wy, cx, cy, cz, cell_start, members, rmin)


@jit
def _close_pairs(position, radius, lx, ly, cutoff, grid):
    """The pairs closer than ``cutoff`` (d, bounding spheres, nearest image), each found once,
    from the cells of the :class:`_CellGrid` ``grid`` (module docstring: larger grain first, half
    shell for equal grains).

    Returns ``(lo, hi, m)``: the ``m`` pairs ``(lo[k], hi[k])``, ``lo < hi``, in the order found.
    """
    n = position.shape[0]
    nx, ny, nz, wx, wy, cell = grid.nx, grid.ny, grid.nz, grid.wx, grid.wy, grid.cell
    cx, cy, cz, cell_start, members, rmin = grid.cx, grid.cy, grid.cz, grid.cell_start, grid.members, grid.rmin
    # image index from a product: it can differ from floor(dx / lx + 0.5) only for dx within
    # round-off of +-lx / 2, a pair farther apart than the cutoff either way
    ilx = 1.0 / lx
    ily = 1.0 / ly
    # grains in cell order: the inner loop reads contiguous coordinates
    sx = np.empty(n)
    sy = np.empty(n)
    sz = np.empty(n)
    sr = np.empty(n)
    for q in range(n):
        p = members[q]
        sx[q], sy[q], sz[q], sr[q] = position[p, 0], position[p, 1], position[p, 2], radius[p]
    cap = 16 * n
    lo = np.empty(cap, np.int64)
    hi = np.empty(cap, np.int64)
    m = 0
    colx = np.empty(nx, np.int64)
    coly = np.empty(ny, np.int64)
    for i in range(n):
        ri = radius[i]
        reach = 2.0 * ri + cutoff
        kx = int(math.ceil(reach / wx))
        ky = int(math.ceil(reach / wy))
        kz = int(math.ceil(reach / cell))
        ncx = _periodic_window(cx[i], kx, nx, colx)
        ncy = _periodic_window(cy[i], ky, ny, coly)
        # half shell: when the window does not wrap around the box, a partner of the same size is
        # taken only from the forward cells (offset (z, y, x) > 0, or the own cell with j > i), as
        # it finds i in its backward cells; the smallest grains skip the backward cells
        half = 2 * kx + 1 < nx and 2 * ky + 1 < ny
        z0 = max(0, cz[i] - kz)
        z1 = min(nz - 1, cz[i] + kz)
        xi, yi, zi = position[i, 0], position[i, 1], position[i, 2]
        for iz in range(z0, z1 + 1):
            for a in range(ncy):
                for b in range(ncx):
                    offset = ((iz - cz[i]) * (2 * ky + 1) + a - ky) * (2 * kx + 1) + b - kx
                    if half and offset < 0 and ri == rmin:
                        continue
                    c = (iz * ny + coly[a]) * nx + colx[b]
                    for q in range(cell_start[c], cell_start[c + 1]):
                        rj = sr[q]
                        if rj > ri:
                            continue
                        if rj == ri:
                            if half:
                                if offset < 0 or (offset == 0 and members[q] <= i):
                                    continue
                            elif members[q] <= i:
                                continue
                        dx = xi - sx[q]
                        dy = yi - sy[q]
                        dx -= lx * math.floor(dx * ilx + 0.5)
                        dy -= ly * math.floor(dy * ily + 0.5)
                        dz = zi - sz[q]
                        rr = ri + rj + cutoff
                        if dx * dx + dy * dy + dz * dz < rr * rr:
                            j = members[q]
                            if m == cap:
                                cap *= 2
                                lo2 = np.empty(cap, np.int64)
                                hi2 = np.empty(cap, np.int64)
                                lo2[:m] = lo[:m]
                                hi2[:m] = hi[:m]
                                lo, hi = lo2, hi2
                            lo[m] = min(i, j)
                            hi[m] = max(i, j)
                            m += 1
    return lo, hi, m


@jit
def _pair_rows(lo, hi, m, n):
    """The pairs ``(lo[k], hi[k])``, ``k < m``, of ``n`` grains as CSR over the first:
    ``(pair_start, pair_j)``, each row sorted."""
    pair_start = np.zeros(n + 1, np.int64)
    for k in range(m):
        pair_start[lo[k] + 1] += 1
    pair_start = np.cumsum(pair_start)
    fill = pair_start[:-1].copy()
    pair_j = np.empty(m, np.int64)
    for k in range(m):
        pair_j[fill[lo[k]]] = hi[k]
        fill[lo[k]] += 1
    for i in range(n):
        # insertion sort of the (short) row
        for k in range(pair_start[i] + 1, pair_start[i + 1]):
            v = pair_j[k]
            r = k - 1
            while r >= pair_start[i] and pair_j[r] > v:
                pair_j[r + 1] = pair_j[r]
                r -= 1
            pair_j[r + 1] = v
    return pair_start, pair_j


@jit
def max_displacement(position, reference, lx, ly):
    """Largest displacement of a grain between ``reference`` and ``position`` (minimum image), d."""
    best = 0.0
    for p in range(position.shape[0]):
        dx = position[p, 0] - reference[p, 0]
        dy = position[p, 1] - reference[p, 1]
        dx -= lx * math.floor(dx / lx + 0.5)
        dy -= ly * math.floor(dy / ly + 0.5)
        dz = position[p, 2] - reference[p, 2]
        best = max(best, dx * dx + dy * dy + dz * dz)
    return math.sqrt(best)


class VerletList:
    """Candidate pairs kept between steps while no grain has moved more than half the skin.

    Args:
        skin: extra search distance beyond the alert distance, d (0 rebuilds every call).

    Attributes:
        pair_start, pair_j: the current CSR pair list (``j > i``, lexicographic order).
        n_builds: number of grid searches done so far.
    """

    def __init__(self, skin: float = 0.0):
        if not skin >= 0.0:
            raise ValueError(f"skin must be >= 0, got {skin}")
        self.skin = float(skin)
        self.pair_start = np.zeros(1, np.int64)
        self.pair_j = np.zeros(0, np.int64)
        self.n_builds = 0
        self._reference: np.ndarray | None = None
        self._key: tuple | None = None

    def update(self, position: np.ndarray, radius: np.ndarray, lx: float, ly: float, alert: float) -> bool:
        """Rebuild the list if needed for these positions; returns True if it was rebuilt.

        Args:
            position: ``(N, 3)`` centres, d.
            radius: ``(N,)`` circumscribed radii, d.
            lx, ly: periods, d.
            alert: alert distance, d.
        """
        key = (len(position), float(lx), float(ly), float(alert), radius.tobytes())
        if (
            self._reference is None
            or key != self._key
            or 2.0 * max_displacement(position, self._reference, lx, ly) > self.skin
        ):
            self.pair_start, self.pair_j = candidate_pairs(position, radius, lx, ly, alert + self.skin)
            self._reference = position.copy()
            self._key = key
            self.n_builds += 1
            return True
        return False

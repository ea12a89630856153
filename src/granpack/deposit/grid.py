"""Cell grid of the deposited spheres (Numba; private to :mod:`granpack.deposit`).

Deposited spheres are binned in ``nx * ny`` lateral cells of side ``hxy >= 2 R_max`` and ``nz``
layers of height ``hz`` (the top layer also holds everything above), as linked lists: ``head[c]``
is the last sphere of cell ``c = (iz * ny + iy) * nx + ix``, ``nxt[i]`` the next one in its cell
(-1 ends a list). Centres are stored wrapped into the box; periodic images are found by walking
unwrapped cell indices ``ix = wx + kx nx`` and carrying the shift ``(kx L, ky L)``, so no image
is ever stored.
"""

from __future__ import annotations

import math

from granpack._numba import jit


@jit
def cell(v, h, n):
    """Index of the cell of coordinate ``v`` in cells of size ``h``, clamped to ``[0, n)``."""
    i = int(math.floor(v / h))
    if i < 0:
        return 0
    if i >= n:
        return n - 1
    return i


@jit
def grid_insert(i, pos, head, nxt, nx, ny, nz, hxy, hz):
    """Push sphere ``i`` (wrapped centre ``pos[i]``) on the linked list of its cell."""
    c = (cell(pos[i, 2], hz, nz) * ny + cell(pos[i, 1], hxy, ny)) * nx + cell(pos[i, 0], hxy, nx)
    nxt[i] = head[c]
    head[c] = i


@jit
def grid_build(pos, n, head, nxt, nx, ny, nz, hxy, hz):
    """Bin spheres ``0 .. n-1`` into a fresh grid (``head`` of size ``nx*ny*nz``)."""
    head[:] = -1
    for i in range(n):
        grid_insert(i, pos, head, nxt, nx, ny, nz, hxy, hz)


@jit
def xy_cells(xlo, xhi, ylo, yhi, hxy, nx, ny, periodic):
    """Lateral cell range ``(ix0, ix1, iy0, iy1)`` covering ``[xlo, xhi] x [ylo, yhi]``:
    unwrapped (any integer, images beyond the box) when periodic, clamped to the box otherwise."""
    if periodic:
        return (
            int(math.floor(xlo / hxy)),
            int(math.floor(xhi / hxy)),
            int(math.floor(ylo / hxy)),
            int(math.floor(yhi / hxy)),
        )
    return cell(xlo, hxy, nx), cell(xhi, hxy, nx), cell(ylo, hxy, ny), cell(yhi, hxy, ny)


@jit
def cell_head(head, iz, iy, ix, nx, ny):
    """First sphere of unwrapped cell ``(ix, iy)`` in layer ``iz`` and its image shift ``(kx, ky)``."""
    ky = iy // ny
    kx = ix // nx
    return head[(iz * ny + iy - ky * ny) * nx + ix - kx * nx], kx, ky


@jit
def gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k):
    """Sphere images whose centre lies in the box ``[lo, hi]`` (unwrapped coordinates).

    Returns the count ``m`` (``out_i[:m]`` indices, ``out_k[:m]`` integer image shifts
    ``(kx, ky)``), or -1 if the buffers are too small.
    """
    ix0, ix1, iy0, iy1 = xy_cells(lo[0], hi[0], lo[1], hi[1], hxy, nx, ny, periodic)
    iz0 = cell(lo[2], hz, nz)
    iz1 = cell(hi[2], hz, nz)
    m = 0
    cap = out_i.shape[0]
    for iz in range(iz0, iz1 + 1):
        for iy in range(iy0, iy1 + 1):
            for ix in range(ix0, ix1 + 1):
                j, kx, ky = cell_head(head, iz, iy, ix, nx, ny)
                while j >= 0:
                    x = pos[j, 0] + kx * lsize
                    y = pos[j, 1] + ky * lsize
                    z = pos[j, 2]
                    if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]:
                        if m == cap:
                            return -1
                        out_i[m] = j
                        out_k[m, 0] = kx
                        out_k[m, 1] = ky
                        m += 1
                    j = nxt[j]
    return m


@jit
def gather_ball(c, reach, lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k):
    """:func:`gather` on the cube of half-side ``reach`` about ``c`` (``lo``, ``hi``: scratch (3,))."""
    for a in range(3):
        lo[a] = c[a] - reach
        hi[a] = c[a] + reach
    return gather(lo, hi, pos, head, nxt, nx, ny, nz, hxy, hz, lsize, periodic, out_i, out_k)

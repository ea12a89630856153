"""Orientational order: nematic :math:`Q^2_{00}` and biaxial :math:`Q^2_{22}`.

Definitions and conventions: docs/method/analysis.md#orientational-order.

For the analysed grains with body axes ``u = R e_x`` (long), ``v = R e_y``, ``w = R e_z`` (thickness):

.. math:: Q^{aa} = \\frac{1}{|S|} \\sum_i \\left(\\tfrac32 a_i \\otimes a_i - \\tfrac12 I\\right), \\quad a \\in \\{u, v, w\\}.

The largest eigenvalue over the three tensors is :math:`Q^2_{00}`; the molecular axis owning it is
``m_z`` and its eigenvector the director ``Z``. With the other two axes ``m_x, m_y`` (in the order
u, v, w) and any orthonormal ``X, Y = Z x X`` spanning the plane normal to ``Z``:

.. math::

    Q^2_{22}(\\varphi) = \\tfrac13 \\left[X Q^{xx} X + Y Q^{yy} Y - X Q^{yy} X - Y Q^{xx} Y\\right]
                      = A \\cos 2\\varphi + B \\sin 2\\varphi, \\qquad Q^2_{22} = \\sqrt{A^2 + B^2},

the maximum over the angle of ``X`` in that plane. Convention: prefactor 1/3 on the tensor form, so
perfect biaxial order gives :math:`Q^2_{00} = Q^2_{22} = 1` (the average form with prefactor 1/4 found
in part of the literature is half of it).

Finite-size baseline: for ``n`` uniformly random orientations both figures are positive (about
0.019 and 0.007 for n = 3000); :func:`isotropic_baseline` gives their mean and standard deviation for
the actual number of grains, so that values of that size are read as "no order".

Spheres carry no orientation: they are left out; with no non-spherical grain the figures are nan,
without a warning (a warning says that non-spherical grains were left out of the analysed region).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from granpack.analysis._base import Compute, result
from granpack.analysis.solid_fraction import analysed_region, in_region
from granpack.packing import Packing
from granpack.rotations import quat_to_matrix, random_quaternions

__all__ = ["Order", "order_parameters", "isotropic_baseline", "AXIS_NAMES"]

#: how Q22 is normalised, in words (``analysis.json`` carries it beside the figure)
Q22_CONVENTION = "tensor form with prefactor 1/3, max over the in-plane frame (perfect order = 1)"
#: names of the body axes, in order: u (length L, body x), v (width G, body y), w (thickness E, body z)
AXIS_NAMES = ("u", "v", "w")


def order_parameters(rotations: np.ndarray) -> tuple[float, float, np.ndarray, int]:
    """:math:`Q^2_{00}`, :math:`Q^2_{22}`, the director and the index of the aligned body axis.

    Args:
        rotations: ``(n, 3, 3)`` body -> world matrices (columns are u, v, w), ``n >= 1``.

    Returns:
        ``(Q00, Q22, director (3,), axis)`` with ``axis`` in {0, 1, 2} for u, v, w.
    """
    axes = np.moveaxis(rotations, 2, 0)  # (3, n, 3): axes[a, i] = body axis a of grain i
    tensors = 1.5 * np.einsum("ani,anj->aij", axes, axes) / rotations.shape[0] - 0.5 * np.eye(3)
    values, vectors = np.linalg.eigh(tensors)  # ascending per tensor
    axis = int(np.argmax(values[:, 2]))
    q00 = float(values[axis, 2])
    director = vectors[axis, :, 2]
    mx, my = [a for a in range(3) if a != axis]
    qxx, qyy = tensors[mx], tensors[my]
    x0 = vectors[axis, :, 0]
    y0 = np.cross(director, x0)

    def q22(x, y):
        return (x @ qxx @ x + y @ qyy @ y - x @ qyy @ x - y @ qxx @ y) / 3.0

    a = q22(x0, y0)
    x1, y1 = (x0 + y0) / math.sqrt(2.0), (y0 - x0) / math.sqrt(2.0)
    b = q22(x1, y1)
    if director[np.argmax(np.abs(director))] < 0:
        director = -director
    return q00, float(math.hypot(a, b)), director, axis


@functools.lru_cache(maxsize=64)
def isotropic_baseline(n: int, samples: int = 100, seed: int = 2017) -> tuple[float, float, float, float]:
    """Mean and std of :math:`Q^2_{00}` and :math:`Q^2_{22}` for ``n`` uniformly random orientations.

    Monte Carlo over ``samples`` sets (fixed ``seed``, so the figure is reproducible).

    Returns:
        ``(Q00_mean, Q00_std, Q22_mean, Q22_std)``; nans for ``n < 1``.
    """
    if n < 1:
        return (math.nan,) * 4
    rng = np.random.default_rng(seed)
    values = np.array([order_parameters(quat_to_matrix(random_quaternions(n, rng)))[:2] for _ in range(samples)])
    return (float(values[:, 0].mean()), float(values[:, 0].std()), float(values[:, 1].mean()), float(values[:, 1].std()))


class Order(Compute):
    """Nematic and biaxial order of the non-spherical grains with centre in the bulk.

    Args:
        z_range: bulk ``(z_bottom, z_top)`` in d; the default bulk region if omitted, all grains
            if ``bulk=False``.
        bulk: restrict to the bulk region.
        population: restrict to one population index (all if ``None``).
        baseline_samples: Monte Carlo samples of the isotropic baseline.
        grains: ``(N,)`` bool, restrict to these grains (a shape class; all if ``None``).
        n_wall: with ``bulk``, in a box or a cylinder, only the grains of the core, centres at
            least ``n_wall d`` from the side walls; 0 the whole section; ignored in a periodic cell.
    """

    def __init__(self, z_range: tuple[float, float] | None = None, bulk: bool = True, population: int | None = None,
                 baseline_samples: int = 100, grains: np.ndarray | None = None, n_wall: float = 0.0):
        self.z_range = z_range
        self.bulk = bulk
        self.population = population
        self.baseline_samples = int(baseline_samples)
        self.grains = grains
        self.n_wall = float(n_wall)

    def compute(self, packing: Packing) -> "Order":
        """Compute the order parameters of ``packing``."""
        self._start()
        state = packing.state
        mask = ~state.shapes.is_sphere[state.kind]
        if self.population is not None:
            mask &= state.population == self.population
        if self.grains is not None:
            mask &= self.grains
        oriented = bool(mask.any())  # spheres only: no orientation, the figures nan by nature (no warning)
        if self.bulk:
            region = analysed_region(packing, self.z_range)
            valid = region[2]
            mask &= in_region(packing, region, self.n_wall)
        self._n = int(mask.sum())
        self._q00 = self._q22 = math.nan
        self._director = np.full(3, math.nan)
        self._axis = -1
        if self._n == 0:
            if oriented and self.bulk and not valid:
                self._warn("no bulk region: order parameters are nan")
            elif oriented:
                self._warn("no non-spherical grain in the analysed region: order parameters are nan")
        else:
            self._q00, self._q22, self._director, self._axis = order_parameters(quat_to_matrix(state.quaternion[mask]))
        self._baseline = isotropic_baseline(self._n, self.baseline_samples) if self._n else (math.nan,) * 4
        return self._done()

    @result
    def n_analysed(self) -> int:
        """Number of grains analysed."""
        return self._n

    @result
    def Q00(self) -> float:
        """Nematic order :math:`Q^2_{00}` in [-1/2, 1]."""
        return self._q00

    @result
    def Q22(self) -> float:
        """Biaxial order :math:`Q^2_{22}` in [0, 1]."""
        return self._q22

    @result
    def director(self) -> np.ndarray:
        """``(3,)`` unit director Z (sign: largest component positive)."""
        return self._director.copy()

    @result
    def director_axis(self) -> str:
        """Body axis aligned with the director: ``"u"`` (length), ``"v"`` (width) or ``"w"`` (thickness); ``""`` if none."""
        return AXIS_NAMES[self._axis] if self._axis >= 0 else ""

    @result
    def baseline(self) -> dict:
        """Isotropic finite-N expectation for :attr:`n_analysed` grains: ``Q00``, ``Q00_std``, ``Q22``, ``Q22_std``."""
        q00, s00, q22, s22 = self._baseline
        return {"Q00": q00, "Q00_std": s00, "Q22": q22, "Q22_std": s22}

    def to_dict(self) -> dict:
        """The ``order`` part of ``analysis.json``: ``Q00``, ``Q22``, ``director``,
        ``director_axis``, ``n_analysed``, ``isotropic_baseline`` (:attr:`baseline`) and the
        convention of Q22 in words."""
        return {
            "Q00": self.Q00,
            "Q22": self.Q22,
            "director": self.director,
            "director_axis": self.director_axis,
            "n_analysed": self.n_analysed,
            "isotropic_baseline": self.baseline,
            "Q22_convention": Q22_CONVENTION,
        }

"""The forces of a box's or a cylinder's walls on the grains, and Janssen's law
(docs/method/analysis.md#janssen).

Forces are the wall points' impulses over the last step divided by the step (world frame, on the
grain; :mod:`granpack.equilibrium`), ``W = g Σ m_p`` the total weight:

- the **shares of the weight**: the floor's vertical force, the side walls' vertical (frictional)
  force and their normal (horizontal) force, each over ``W``; per wall (``WALL_IDS``) too, and the
  friction the side walls mobilise on average, their vertical over their normal force;
- **profiles against the depth** ``ζ = z_s - z`` below the free surface ``z_s`` (that of the solid
  fraction, :class:`~granpack.analysis.solid_fraction.SolidFraction`), in bins of ``bin_height d``:
  the side walls' vertical and normal force per unit height (a point above the surface counts at
  depth 0), the same over the perimeter ``P`` (the wall's shear and normal stress), and the
  **vertical stress** of the packing

  .. math:: \\sigma_v(z) A = \\sum_{p: z_p > z} \\big(m_p g - F^{side}_{z,p}\\big),

  the weight of the grains centred above ``z`` less the side walls' vertical force on them: the
  force the grains below push up on them, exact for a packing at rest (the floor's force,
  ``σ_v A`` below every centre), ``A`` the section;
- **Janssen's law** fitted to σ_v(ζ) by least squares,

  .. math:: \\sigma_v(\\zeta) = \\sigma_\\infty\\,(1 - e^{-\\zeta/\\lambda}), \\qquad
            \\lambda = \\frac{A}{P\\,\\mu_w K}\\ \\Big(= \\frac{D}{4 \\mu_w K}\\ \\text{in a cylinder}\\Big),

  ``σ∞`` and ``λ`` free: ``K`` from ``λ`` with the walls' friction coefficient ``μ_w``, ``K`` again
  from the saturation, ``σ∞ = ρ_b g A / (P μ_w K)`` with the column's mean weight density
  ``ρ_b g = W / (A z_s)``, ``K`` from ``λ`` with the friction the walls mobilise instead of ``μ_w``,
  and the stress ratio measured at the wall, ``Σ σ_h / Σ σ_v`` over the bins 2 d or more below the
  surface. Frictionless walls carry no weight: the fit is nan.

A periodic cell has no walls but its floor: the figures are nan, with a warning.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.optimize import OptimizeWarning, curve_fit

from granpack.analysis._base import Compute, any_finite, as_array, result
from granpack.contact.contacts import WALL, WALL_IDS
from granpack.packing import Packing

__all__ = ["WallForces", "janssen_stress", "plot_vertical_stress"]

#: the depth (in d) below the free surface from which the stress ratio at the wall is averaged
RATIO_DEPTH = 2.0
#: the fewest depth bins Janssen's law is fitted to
MIN_FIT_BINS = 4
#: the walls of each container (ids of ``WALL_IDS``)
CONTAINER_WALLS = {"box": (WALL, -2, -3, -4, -5), "cylinder": (WALL, -6)}
#: the profiles against the depth, in the order of ``analysis.json``
_PROFILE_KEYS = ("depth", "side_vertical_per_height", "side_normal_per_height", "wall_shear_stress",
                 "wall_normal_stress", "vertical_stress", "hydrostatic_stress", "stress_ratio")


def janssen_stress(depth, saturation: float, length: float):
    """Janssen's vertical stress :math:`\\sigma_\\infty (1 - e^{-\\zeta/\\lambda})` at ``depth`` ζ."""
    return saturation * -np.expm1(-np.asarray(depth, dtype=np.float64) / length)


def perimeter_of(box) -> float:
    """The length of the side walls around the section, d: ``π D`` or ``2 (L_x + L_y)``."""
    return math.pi * box.lx if box.container == "cylinder" else 2.0 * (box.lx + box.ly)


def _wall_points(packing: Packing):
    """Per wall point: the wall's id, the grain, the point, the force on the grain and the wall's
    normal (towards the grain)."""
    contacts = packing.contacts
    seg = contacts.point_manifold
    wall = contacts.body_j[seg]
    keep = wall < 0
    force = contacts.impulse[keep] / packing.time_step
    return wall[keep], contacts.body_i[seg][keep], contacts.point[keep], force, contacts.normal[seg][keep]


def _nan_janssen() -> dict:
    return {k: math.nan for k in ("saturation_stress", "saturation_stress_stderr", "length", "length_stderr", "K",
                                  "K_saturation", "K_mobilised", "K_wall", "r_squared")}


class WallForces(Compute):
    """The walls' forces on the grains of a container packing and the fit of Janssen's law.

    Args:
        bin_height: the depth bins of the profiles, in units of the largest grain size d.
        z_surface: the free surface, d; that of :class:`~granpack.analysis.solid_fraction.SolidFraction`
            if omitted.
        wall_friction: ``μ_w``; the packing's own (:attr:`~granpack.packing.Packing.wall_friction`) if omitted.

    Example::

        wf = WallForces().compute(packing)
        wf.shares["side_vertical"], wf.janssen["K"]
    """

    def __init__(self, bin_height: float = 1.0, z_surface: float | None = None, wall_friction: float | None = None):
        if not bin_height > 0:
            raise ValueError(f"bin_height must be > 0, got {bin_height}")
        self.bin_height = float(bin_height)
        self.z_surface = z_surface
        self.wall_friction = wall_friction

    def compute(self, packing: Packing) -> "WallForces":
        """The shares, the profiles and the fit of ``packing``."""
        self._start()
        box, state = packing.box, packing.state
        self._container = box.container
        self._weight = float(packing.gravity * state.mass.sum())
        self._mu = float(packing.wall_friction if self.wall_friction is None else self.wall_friction)
        self._area, self._perimeter = box.area, (math.nan if box.periodic else perimeter_of(box))
        self._shares = dict.fromkeys(("floor_vertical", "side_vertical", "side_normal", "total_vertical",
                                      "side_mobilised_friction"), math.nan)
        self._per_wall: dict = {}
        self._z_surface = math.nan
        self._profile = {k: np.zeros(0) for k in _PROFILE_KEYS}
        self._floor_stress = self._bulk_weight = math.nan
        self._janssen = _nan_janssen()
        if box.periodic:
            self._warn("a periodic cell has no side walls: the walls' forces are nan")
            return self._done()
        if not self._weight > 0:
            self._warn("no grain: the walls' forces are nan")
            return self._done()
        wall, owner, point, force, normal = _wall_points(packing)
        side = wall != WALL
        vertical, pressing = force[:, 2], np.einsum("ij,ij->i", force, normal)
        w = self._weight
        floor_force = float(vertical[~side].sum())
        self._shares.update(floor_vertical=floor_force / w, side_vertical=float(vertical[side].sum()) / w,
                            side_normal=float(pressing[side].sum()) / w, total_vertical=float(vertical.sum()) / w)
        if pressing[side].sum() > 0:
            self._shares["side_mobilised_friction"] = float(vertical[side].sum() / pressing[side].sum())
        for wid in CONTAINER_WALLS[box.container]:
            mine = wall == wid
            self._per_wall[WALL_IDS[wid]] = {"vertical": float(vertical[mine].sum()) / w,
                                             "normal": float(pressing[mine].sum()) / w, "points": int(mine.sum())}
        self._z_surface = self._surface(packing)
        self._floor_stress = floor_force / self._area
        if not (math.isfinite(self._z_surface) and self._z_surface > 0):
            self._warn("no free surface: the profiles against the depth are nan")
            return self._done()
        self._bulk_weight = w / (self._area * self._z_surface)
        self._profiles(packing, owner[side], point[side], vertical[side], pressing[side])
        self._fit()
        return self._done()

    def _surface(self, packing: Packing) -> float:
        """The free surface: the given one, or the solid fraction's."""
        if self.z_surface is not None:
            return float(self.z_surface)
        from granpack.analysis.solid_fraction import SolidFraction

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return float(SolidFraction().compute(packing).z_surface)

    def _profiles(self, packing: Packing, owner, point, vertical, pressing) -> None:
        """The side walls' forces per unit height and the vertical stress against the depth."""
        state, d = packing.state, packing.max_size
        z_s = self._z_surface
        edges = np.append(np.arange(0.0, z_s, self.bin_height * d), z_s)
        k = len(edges) - 1
        height = np.diff(edges)
        depth = 0.5 * (edges[1:] + edges[:-1])
        bins = np.clip(np.searchsorted(edges, np.clip(z_s - point[:, 2], 0.0, z_s), side="right") - 1, 0, k - 1)
        per_height_v = np.bincount(bins, weights=vertical, minlength=k)[:k] / height
        per_height_n = np.bincount(bins, weights=pressing, minlength=k)[:k] / height
        # the load of each grain once its side walls' vertical force is taken off, summed from the top
        load = packing.gravity * state.mass - np.bincount(owner, weights=vertical, minlength=state.n)
        order = np.argsort(state.position[:, 2], kind="stable")
        z_sorted = state.position[order, 2]
        above = np.concatenate([np.cumsum(load[order][::-1])[::-1], [0.0]])
        sigma_v = above[np.searchsorted(z_sorted, z_s - depth, side="right")] / self._area
        wall_normal = per_height_n / self._perimeter
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(sigma_v > 0, wall_normal / sigma_v, math.nan)
        self._profile = {
            "depth": depth, "side_vertical_per_height": per_height_v, "side_normal_per_height": per_height_n,
            "wall_shear_stress": per_height_v / self._perimeter, "wall_normal_stress": wall_normal,
            "vertical_stress": sigma_v, "hydrostatic_stress": self._bulk_weight * depth, "stress_ratio": ratio,
        }

    def _fit(self) -> None:
        """Janssen's law fitted to the vertical stress (module docstring)."""
        p = self._profile
        depth, sigma_v = p["depth"], p["vertical_stress"]
        deep = depth >= RATIO_DEPTH
        if deep.any() and p["vertical_stress"][deep].sum() > 0:
            self._janssen["K_wall"] = float(p["wall_normal_stress"][deep].sum() / sigma_v[deep].sum())
        if not (self._mu > 0 and self._shares["side_vertical"] > 0 and len(depth) >= MIN_FIT_BINS):
            return
        hydraulic = self._area / self._perimeter
        start = [max(float(sigma_v.max()), 1e-9), hydraulic / (self._mu * 0.5)]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", OptimizeWarning)
                params, cov = curve_fit(janssen_stress, depth, sigma_v, p0=start, bounds=([0.0, 1e-9], [np.inf, np.inf]),
                                        maxfev=20000)
        except (RuntimeError, ValueError) as exc:
            self._warn(f"Janssen's law could not be fitted ({exc})")
            return
        saturation, length = (float(v) for v in params)
        stderr = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        residual = sigma_v - janssen_stress(depth, saturation, length)
        total = ((sigma_v - sigma_v.mean()) ** 2).sum()
        mobilised = self._shares["side_mobilised_friction"]
        self._janssen.update(
            saturation_stress=saturation, saturation_stress_stderr=float(stderr[0]), length=length,
            length_stderr=float(stderr[1]), K=hydraulic / (self._mu * length),
            K_saturation=self._bulk_weight * hydraulic / (self._mu * saturation) if saturation > 0 else math.nan,
            K_mobilised=hydraulic / (mobilised * length) if mobilised > 0 else math.nan,
            r_squared=float(1.0 - (residual**2).sum() / total) if total > 0 else math.nan)

    @result
    def shares(self) -> dict:
        """``floor_vertical``, ``side_vertical``, ``side_normal``, ``total_vertical`` (over the
        weight) and ``side_mobilised_friction`` (the side walls' vertical over normal force)."""
        return dict(self._shares)

    @result
    def per_wall(self) -> dict:
        """Wall name -> its ``vertical`` and ``normal`` force over the weight and its ``points``."""
        return {k: dict(v) for k, v in self._per_wall.items()}

    @result
    def profile(self) -> dict:
        """The profiles against the depth (keys of :data:`_PROFILE_KEYS`), arrays over the bins."""
        return {k: v.copy() for k, v in self._profile.items()}

    @result
    def janssen(self) -> dict:
        """The fit of Janssen's law: ``saturation_stress`` σ∞ (ρ g d), ``length`` λ (d), their
        standard errors, ``K`` (from λ and μ_w), ``K_saturation``, ``K_mobilised``, ``K_wall`` and
        ``r_squared``."""
        return dict(self._janssen)

    def to_dict(self) -> dict:
        """The ``walls`` part of ``analysis.json`` (docs/reference/outputs.md)."""
        return {
            "container": self._container,
            "weight": self._weight,
            "wall_friction": self._mu,
            "area": self._area,
            "perimeter": self._perimeter,
            **self._shares,
            "per_wall": self.per_wall,
            "z_surface": self._z_surface,
            "floor_stress": self._floor_stress,
            "bulk_weight": self._bulk_weight,
            "bin_height": self.bin_height,
            **self.profile,
            "janssen": self.janssen,
        }

    def plot(self, ax):
        """The vertical stress against the depth (:func:`plot_vertical_stress`) on ``ax``; returns ``ax``."""
        plot_vertical_stress(ax, self.to_dict())
        return ax



def plot_vertical_stress(ax, output: dict | None) -> bool:
    """Draw the vertical stress σ_v against the depth below the free surface on ``ax`` (depth
    downwards), with the hydrostatic stress ``ρ_b g ζ`` dotted, the fit of Janssen's law and the
    wall's normal stress σ_h.

    Pyplot-free: it draws on the given axes and creates no figure, so the same function serves a
    computed :class:`WallForces` and a run's ``analysis.json`` (``granpack figures``).

    Args:
        ax: matplotlib axes.
        output: a ``walls`` part (:meth:`WallForces.to_dict` or read from the file).

    Returns:
        Whether there was a profile to draw (nothing is drawn otherwise).
    """
    data = output or {}
    depth, sigma_v = as_array(data.get("depth")), as_array(data.get("vertical_stress"))
    if not any_finite(sigma_v) or len(depth) != len(sigma_v):
        return False
    ax.plot(sigma_v, depth, color="C0", marker="o", markersize=3, linestyle="none", label="σ_v (weight less wall friction)")
    hydrostatic = as_array(data.get("hydrostatic_stress"))
    if len(hydrostatic) == len(depth):
        ax.plot(hydrostatic, depth, color="0.4", linestyle=":", label="hydrostatic ρ_b g ζ")
    fit = data.get("janssen") or {}
    saturation, length = fit.get("saturation_stress"), fit.get("length")
    if all(isinstance(v, (int, float)) and math.isfinite(v) for v in (saturation, length)):
        grid = np.linspace(0.0, float(np.nanmax(depth)), 200)
        ax.plot(janssen_stress(grid, saturation, length), grid, color="C3",
                label=f"Janssen: σ∞ = {saturation:.3g} ρgd, λ = {length:.3g} d, K = {fit.get('K', math.nan):.2f}")
        ax.axvline(saturation, color="C3", linestyle="--", linewidth=0.8)
    sigma_h = as_array(data.get("wall_normal_stress"))
    if any_finite(sigma_h) and len(sigma_h) == len(depth):
        ax.plot(sigma_h, depth, color="C2", marker="s", markersize=3, linestyle="none", label="σ_h at the wall")
    ax.set_ylim(float(np.nanmax(depth)) + 0.5, 0.0)
    ax.set_xlim(left=0.0)
    ax.set_xlabel("stress (ρ g d)")
    ax.set_ylabel("depth below the free surface ζ (d)")
    ax.legend(loc="best", fontsize="small")
    return True

"""The standard figures of a run, as PNG and SVG, drawn without a display.

Figures are built as :class:`matplotlib.figure.Figure` objects without pyplot, so nothing here
needs a GUI or changes the user's matplotlib backend (the Agg canvas renders them). Lengths are
in d (the largest grain's circumscribed diameter).

For a **run folder** (``analysis.json`` and ``final.gsd``), :func:`run_figures` writes into
``<run>/figures/``: ``solid_fraction_profile``, ``pair_correlation``, ``homogeneity``, ``grading``
(a packing of several sizes), ``wall_profile`` and ``vertical_stress`` (a packing in a box or a
cylinder) and ``packing`` (a 3D picture, grains coloured by population). Each
figure's axes are drawn from the run's ``analysis.json`` by the figure function of its quantity's
module (:func:`~granpack.analysis.solid_fraction.plot_profile`,
:func:`~granpack.analysis.pair_correlation.plot_g`,
:func:`~granpack.analysis.homogeneity.plot_proportions`,
:func:`~granpack.analysis.size_classes.plot_class_profiles`,
:func:`~granpack.analysis.wall_profile.plot_wall_profile`,
:func:`~granpack.analysis.wall_forces.plot_vertical_stress`), the same functions a computed
quantity's ``.plot(ax)`` calls; this module lays out the figures and writes the files.

The figures of a campaign folder are :mod:`granpack.campaign.figures`'s.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from granpack.analysis.homogeneity import plot_proportions, proportions_of
from granpack.analysis.pair_correlation import plot_g
from granpack.analysis.size_classes import plot_class_profiles
from granpack.analysis.solid_fraction import plot_profile
from granpack.analysis.wall_forces import plot_vertical_stress
from granpack.analysis.wall_profile import plot_wall_profile
from granpack.errors import InputError
from granpack.io.atomic import atomic_path
from granpack.io.run_folder import ANALYSIS_FILE, CONFIG_FILE, FINAL_FILE
from granpack.io.vtk import grain_surfaces
from granpack.packing import Packing

__all__ = [
    "FORMATS",
    "FigureFiles",
    "save_figure",
    "render_packing",
    "read_analysis",
    "run_figures",
]

#: file formats written for every figure
FORMATS = ("png", "svg")


class FigureFiles(list):
    """The files written (a list of paths), with :attr:`skipped`: figure name -> why it was not
    drawn (no data for it), so that no empty figure file is ever written."""

    def __init__(self, paths: Iterable[Path] = (), skipped: dict[str, str] | None = None):
        super().__init__(paths)
        self.skipped: dict[str, str] = dict(skipped or {})


def save_figure(fig: Figure, out_dir: Path, stem: str, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Save ``fig`` as ``out_dir/stem.<format>`` for each format (folder created; each file
    written under a temporary name and renamed).

    Args:
        fig: the figure.
        out_dir: the folder.
        stem: the file name without extension.
        formats: matplotlib file formats, default PNG (150 dpi) and SVG.

    Returns:
        The files written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = out_dir / f"{stem}.{fmt}"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=150, bbox_inches="tight")
        paths.append(path)
    return paths


# --------------------------------------------------------------------------- 3D picture


def render_packing(
    packing: Packing,
    *,
    elev: float = 18.0,
    azim: float = -60.0,
    sphere_segments: int = 12,
    size_inches: float = 7.0,
) -> Figure:
    """A 3D picture of the packing: true grain surfaces, coloured by population, lit from the viewer.

    Polyhedra are drawn with their faces, spheres as tessellated surfaces; faces turned away
    from the (orthographic) viewer are left out. Each grain is drawn at its wrapped centre, so
    grains across a periodic side stick out of the cell.

    Args:
        packing: the packing.
        elev: viewing elevation, degrees.
        azim: viewing azimuth, degrees.
        sphere_segments: meridians of each sphere's tessellation.
        size_inches: figure width and height, inches.

    Returns:
        The figure (not shown; save it with :func:`save_figure`).
    """
    state = packing.state
    surfaces = grain_surfaces(state, sphere_segments)
    e, a = math.radians(elev), math.radians(azim)
    eye = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    light = eye + np.array([0.0, 0.0, 0.6])
    light /= np.linalg.norm(light)
    palette = colormaps["tab10"]
    polygons: list[np.ndarray] = []
    colours: list[np.ndarray] = []
    edges: list[np.ndarray] = []
    for k, faces in surfaces.faces.items():
        owner, normal = surfaces.particle[k], surfaces.normal[k]
        sphere = state.shapes.is_sphere[state.kind[owner]]
        # tessellated spheres: keep facets near the silhouette, their normals are approximate
        keep = normal @ eye > np.where(sphere, -0.35, 1e-9)
        shade = 0.45 + 0.55 * np.clip(normal[keep] @ light, 0.0, 1.0)
        base = np.array([palette(p % 10)[:3] for p in state.population[owner[keep]]]).reshape(-1, 3)
        face_colour = np.clip(base * shade[:, None], 0.0, 1.0)
        polygons.extend(surfaces.points[faces[keep]])
        colours.append(face_colour)
        # polyhedra show their edges; sphere facets do not
        edges.append(np.where(sphere[keep, None], face_colour, 0.25 * face_colour))
    fig = Figure(figsize=(size_inches, size_inches))
    ax = fig.add_subplot(projection="3d")
    ax.set_proj_type("ortho")
    ax.view_init(elev=elev, azim=azim)
    if polygons:
        collection = Poly3DCollection(
            polygons, facecolors=np.concatenate(colours), edgecolors=np.concatenate(edges), linewidths=0.2
        )
        collection.set_rasterized(True)  # keeps the SVG small; axes and labels stay vector
        # the limits are set below; matplotlib's autoscaling would read the uninitialised padding
        # of its ragged face array (triangles and quads), and failed on NaN or Inf now and then
        ax.add_collection3d(collection, autolim=False)
    lx, ly = packing.box.lx, packing.box.ly
    top = float((state.position[:, 2] + state.radius).max()) if state.n else 1.0
    ax.plot([0, lx, lx, 0, 0], [0, 0, ly, ly, 0], [0, 0, 0, 0, 0], color="0.4", linewidth=0.8)
    ax.set_xlim(0, lx)
    ax.set_ylim(0, ly)
    ax.set_zlim(0, top)
    ax.set_box_aspect((lx, ly, top))
    # the x and y axes meet at the corner (0, 0): without their 0 ticks, the labels there do not collide
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(MaxNLocator(nbins=4, prune="lower"))
    ax.set_xlabel("x (d)")
    ax.set_ylabel("y (d)")
    ax.set_zlabel("z (d)")
    present = np.unique(state.population)
    handles = [Patch(color=palette(p % 10), label=packing.population_names[p]) for p in present]
    ax.legend(handles=handles, loc="upper left", title="population")
    holder = {"periodic": f"cell {lx:g} d x {ly:g} d", "box": f"box {lx:g} d x {ly:g} d",
              "cylinder": f"cylinder of diameter {lx:g} d"}[state.box.container]
    ax.set_title(f"{state.n} grains, {holder}")
    return fig



# --------------------------------------------------------------------------- one run


def read_analysis(run_dir: Path) -> dict:
    """The ``analysis.json`` of ``run_dir`` as a dict (``null`` stays ``None``).

    Raises:
        InputError: the file is missing, unreadable, or not a JSON object (one line naming it).
    """
    path = run_dir / ANALYSIS_FILE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: not found (run `granpack analyze {run_dir}` first)") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a readable analysis file ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: not an analysis file (expected a JSON object)")
    return data


def _no_bulk(analysis: dict) -> str:
    """`` (no bulk region)`` when the analysis had none, else nothing."""
    bulk = analysis.get("bulk") or {}
    return " (no bulk region: the pile is too low, see analysis.json 'warnings')" if bulk.get("valid") is False else ""


def run_figures(run_dir: str | Path) -> FigureFiles:
    """The figures of one run folder, written into ``<run_dir>/figures/``.

    A figure without data (an empty g(r), no homogeneity profile) is not written; the result
    says which and why.

    Args:
        run_dir: a run folder with ``analysis.json`` (and ``final.gsd`` for the 3D picture).

    Returns:
        The files written, and in ``.skipped`` the figures left out with the reason.

    Raises:
        InputError: no readable ``analysis.json``, or an unreadable ``final.gsd``.
    """
    from granpack.io.gsd import read_packing

    run_dir = Path(run_dir)
    analysis = read_analysis(run_dir)
    out = run_dir / "figures"
    written = FigureFiles()

    fig = Figure(figsize=(4.5, 6))
    if plot_profile(fig.add_subplot(), analysis.get("solid_fraction"), analysis.get("bulk")):
        written += save_figure(fig, out, "solid_fraction_profile")
    else:
        written.skipped["solid_fraction_profile"] = "analysis.json has no solid-fraction profile"

    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    if plot_g(ax, analysis.get("pair_correlation")):
        ax.legend()
        written += save_figure(fig, out, "pair_correlation")
    else:
        written.skipped["pair_correlation"] = "g(r) is empty" + (_no_bulk(analysis) or " (fewer than two grains in the analysed slab)")

    _, profiles, _ = proportions_of(analysis.get("homogeneity"))
    if not profiles:
        written.skipped["homogeneity"] = "no volume proportion profile in analysis.json"
    elif len(profiles) < 2:
        written.skipped["homogeneity"] = "one population: its volume proportion is 1 at every height"
    else:
        fig = Figure(figsize=(4.5, 6))
        plot_proportions(fig.add_subplot(), analysis.get("homogeneity"))
        written += save_figure(fig, out, "homogeneity")

    wall = _wall_figure(analysis)
    if isinstance(wall, str):
        written.skipped["wall_profile"] = wall
    else:
        written += save_figure(wall, out, "wall_profile")

    stress = _stress_figure(analysis)
    if isinstance(stress, str):
        written.skipped["vertical_stress"] = stress
    else:
        written += save_figure(stress, out, "vertical_stress")

    final = run_dir / FINAL_FILE
    packing = read_packing(final) if final.is_file() else None
    if "size_classes" not in analysis:
        written.skipped["grading"] = "the grains have one size"
    elif packing is None:
        written.skipped["grading"] = f"no {final.name} in {run_dir}"
    else:
        written += save_figure(_grading_figure(run_dir, analysis, packing), out, "grading")
    if packing is not None:
        written += save_figure(render_packing(packing), out, "packing")
    else:
        written.skipped["packing"] = f"no {final.name} in {run_dir}"
    return written


def _wall_figure(analysis: dict) -> Figure | str:
    """The profiles against the distance from the side walls, stacked: the solid fraction, the
    backbone coordination and, with non-spherical grains, the nematic order, each with its core
    value dashed; or why there is none."""
    part = analysis.get("wall_profile")
    if not isinstance(part, dict):
        return "a periodic cell has no side walls (no wall_profile in analysis.json)"
    core = {"solid_fraction": (analysis.get("solid_fraction") or {}).get("bulk"),
            "N": (analysis.get("coordination") or {}).get("N"), "Q00": (analysis.get("order") or {}).get("Q00")}
    drawn = [q for q in core if q == "solid_fraction" or any(v is not None for v in part.get(q) or [])]
    fig = Figure(figsize=(6, 2.6 * len(drawn)))
    axes = fig.subplots(len(drawn), 1, sharex=True, squeeze=False)[:, 0]
    if not plot_wall_profile(axes[0], part, "solid_fraction", core["solid_fraction"]):
        return "wall_profile has no solid-fraction profile (no bulk region)"
    for ax, quantity in zip(axes[1:], drawn[1:]):
        plot_wall_profile(ax, part, quantity, core[quantity])
    for ax in axes[:-1]:
        ax.set_xlabel("")
    n_wall = (analysis.get("bulk") or {}).get("n_wall")
    if isinstance(n_wall, (int, float)):
        lo, hi = axes[0].get_xlim()
        for ax in axes:
            ax.axvspan(n_wall, hi, color="0.92", zorder=0)
        axes[0].set_xlim(lo, hi)  # shared by every panel
    z = [v if isinstance(v, (int, float)) else math.nan for v in (part.get("z_bottom"), part.get("z_top"))]
    axes[0].set_title(f"{part.get('container', 'container')}: slab z = {z[0]:.2f} .. {z[1]:.2f} d, core shaded")
    fig.tight_layout()
    return fig


def _stress_figure(analysis: dict) -> Figure | str:
    """The vertical stress against the depth with the fit of Janssen's law, titled with the shares
    of the weight the floor and the side walls carry; or why there is none."""
    part = analysis.get("walls")
    if not isinstance(part, dict):
        return "a periodic cell has no side walls (no walls in analysis.json)"
    fig = Figure(figsize=(5.5, 6))
    ax = fig.add_subplot()
    if not plot_vertical_stress(ax, part):
        return "walls has no vertical-stress profile (no free surface)"
    shares = [part.get(k) if isinstance(part.get(k), (int, float)) else math.nan for k in ("floor_vertical", "side_vertical")]
    ax.set_title(f"{part.get('container', 'container')}, μ_w = {part.get('wall_friction', math.nan):g}: "
                 f"floor {shares[0]:.3f} W, side walls {shares[1]:.3f} W", fontsize="medium")
    fig.tight_layout()
    return fig


def _grading_figure(run_dir: Path, analysis: dict, packing) -> Figure:
    """Left: the sieve curve requested (each graded population of the run's config), poured and in
    the bulk; right: each size class's share of the solid volume against the height."""
    from granpack.config import load_config
    from granpack.grading import achieved_passing

    fig = Figure(figsize=(10, 4.5))
    ax, ax_z = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    state = packing.state
    size, volume = 2.0 * state.radius, state.mass
    grid = np.geomspace(size.min(), size.max(), 200)
    config_path = run_dir / CONFIG_FILE
    if config_path.is_file():
        config = load_config(config_path)
        graded = [p for p in config.populations if p.grading is not None]
        if len(config.populations) == 1 and graded:
            ax.semilogx(grid, 100 * graded[0].grading_curve.passing_at(grid), color="k", linestyle=":", linewidth=1.5,
                        zorder=3, label=f"requested ({graded[0].grading.curve})")
    ax.semilogx(grid, 100 * achieved_passing(size, volume, grid), color="C0", label="poured")
    bulk = analysis.get("bulk", {})
    if bulk.get("valid"):
        z = state.position[:, 2]
        inside = (z >= bulk["z_bottom"]) & (z <= bulk["z_top"])
        if inside.any():
            ax.semilogx(grid, 100 * achieved_passing(size[inside], volume[inside], grid), color="C1", linestyle="--",
                        label="bulk")
    ax.set_xlabel("sieve size D (d)")
    ax.set_ylabel("% passing by volume")
    ax.set_ylim(-2, 102)
    ax.legend()
    plot_class_profiles(ax_z, analysis["size_classes"])
    fig.tight_layout()
    return fig

"""The standard figures of a run and of a campaign, as PNG and SVG, drawn without a display.

Figures are built as :class:`matplotlib.figure.Figure` objects without pyplot, so nothing here
needs a GUI or changes the user's matplotlib backend (the Agg canvas renders them). Lengths are
in d (the largest grain's circumscribed diameter).

For a **run folder** (``analysis.json`` and ``final.gsd``), :func:`run_figures` writes into
``<run>/figures/``: ``solid_fraction_profile``, ``pair_correlation``, ``homogeneity`` and
``packing`` (a 3D picture, grains coloured by population).

For a **campaign folder** (``runs.csv`` and the run folders), :func:`campaign_figures` writes into
``<campaign>/figures/``:

- ``solid_fraction`` and ``order``: bulk solid fraction and nematic order Q00 against the share
  of the substituted grains, one curve per family, error bars = standard deviation over the
  replicas; the left panel shows the size mixtures (spheres and isometric pinacoids, share of
  small grains), the right panel the shape mixtures (elongated, flat, flat & elongated), which
  start from the monodisperse isometric pinacoids (family ``pinacoids``, share 0);
- ``coordination``: N, Ns, Nd, Nt against the share, one panel per family;
- ``coordination_vs_order``: N against Q00 for every non-spherical run, with the fit
  ``N(Q) = N0 + (N1 - N0)(1 - exp(-Q/Qc))`` of :mod:`granpack.analysis.fit` (docs/method/analysis.md#n-versus-q00-fit);
- ``pair_correlation`` and ``homogeneity``: g(r) and the volume proportion profiles of the
  chosen mixtures (default: all), one panel per family.

A mixture's family and share come from the ``family`` and ``share`` keys of its campaign entry.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Sequence

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from granpack.errors import InputError
from granpack.io.atomic import atomic_path
from granpack.io.run_folder import ANALYSIS_FILE, CONFIG_FILE, FINAL_FILE, RUNS_TABLE
from granpack.io.vtk import grain_surfaces
from granpack.packing import Packing

if TYPE_CHECKING:
    from granpack.analysis.fit import ExponentialFit

__all__ = [
    "FAMILIES",
    "FORMATS",
    "FigureFiles",
    "save_figure",
    "render_packing",
    "run_figures",
    "campaign_figures",
    "make_figures",
]

#: file formats written for every figure
FORMATS = ("png", "svg")
#: known mixture families: name -> (legend label, marker, panel); panel "size" or "shape"
FAMILIES: dict[str, tuple[str, str, str]] = {
    "spheres": ("spheres", "o", "size"),
    "pinacoids": ("isometric pinacoids", "s", "size"),
    "elongated": ("elongated pinacoids", "^", "shape"),
    "flat": ("flat pinacoids", "v", "shape"),
    "flat-elongated": ("flat & elongated pinacoids", "D", "shape"),
}
#: the shape families' share-0 point: monodisperse isometric pinacoids
_REFERENCE_FAMILY = "pinacoids"
_COORDINATION = (("coordination.N", "N"), ("coordination.Ns", "Ns"), ("coordination.Nd", "Nd"), ("coordination.Nt", "Nt"))


class FigureFiles(list):
    """The files written (a list of paths), with :attr:`skipped`: figure name -> why it was not
    drawn (no data for it), so that no empty figure file is ever written."""

    def __init__(self, paths: Iterable[Path] = (), skipped: dict[str, str] | None = None):
        super().__init__(paths)
        self.skipped: dict[str, str] = dict(skipped or {})


def _finite(values: np.ndarray) -> bool:
    return bool(len(values)) and bool(np.isfinite(values).any())


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
    ax.set_title(f"{state.n} grains, cell {lx:g} d x {ly:g} d")
    return fig


# --------------------------------------------------------------------------- one run


def _read_analysis(run_dir: Path) -> dict:
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


def _array(value) -> np.ndarray:
    """A list of numbers (``None`` -> NaN) as a float array; anything else -> empty."""
    if not isinstance(value, list):
        return np.zeros(0)
    return np.array([math.nan if v is None else v for v in value], dtype=float)


def _homogeneity(analysis: dict) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, float]]:
    """Layer heights, the volume proportion profile of each population, and the nominal
    proportions (``homogeneity`` {z, proportions, nominal} of an analysis)."""
    data = analysis.get("homogeneity") or {}
    z = _array(data.get("z"))
    proportions, nominal = data.get("proportions"), data.get("nominal")
    if not isinstance(proportions, dict):
        return z, {}, {}
    profiles = {str(name): _array(p) for name, p in proportions.items()}
    nominal = {str(k): float(v) for k, v in nominal.items() if isinstance(v, (int, float))} if isinstance(nominal, dict) else {}
    return z, {name: p for name, p in profiles.items() if len(p) == len(z) and _finite(p)}, nominal


def _plot_profile(ax: Axes, analysis: dict) -> bool:
    sf = analysis.get("solid_fraction") or {}
    z, phi = _array(sf.get("profile_z")), _array(sf.get("profile_phi"))
    if not _finite(phi) or len(z) != len(phi):
        return False
    ax.plot(phi, z, color="C0", label="slice average")
    bulk_region = analysis.get("bulk") or {}
    if bulk_region.get("valid") and all(isinstance(bulk_region.get(k), (int, float)) for k in ("z_bottom", "z_top")):
        ax.axhspan(bulk_region["z_bottom"], bulk_region["z_top"], color="0.9", zorder=0, label="bulk region")
    bulk, std = sf.get("bulk"), sf.get("std")
    if isinstance(bulk, (int, float)) and math.isfinite(bulk):
        label = f"bulk {bulk:.4f}" + (f" ± {std:.4f}" if isinstance(std, (int, float)) else "")
        ax.axvline(bulk, color="C3", linestyle="--", label=label)
    ax.set_xlabel("solid fraction φ")
    ax.set_ylabel("height z (d)")
    ax.legend(loc="best")
    return True


def _plot_gr(ax: Axes, r: np.ndarray, g: np.ndarray, **style) -> None:
    ax.plot(r, g, **style)
    ax.set_xlabel("distance between centres r (d)")
    ax.set_ylabel("pair correlation g(r)")


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
    analysis = _read_analysis(run_dir)
    out = run_dir / "figures"
    written = FigureFiles()

    fig = Figure(figsize=(4.5, 6))
    if _plot_profile(fig.add_subplot(), analysis):
        written += save_figure(fig, out, "solid_fraction_profile")
    else:
        written.skipped["solid_fraction_profile"] = "analysis.json has no solid-fraction profile"

    r, g = _pair_correlation(analysis)
    if not _finite(g):
        written.skipped["pair_correlation"] = "g(r) is empty" + (_no_bulk(analysis) or " (fewer than two grains in the analysed slab)")
    else:
        fig = Figure(figsize=(6, 4))
        ax = fig.add_subplot()
        _plot_gr(ax, r, g, color="C0", label="all grains")
        ax.axhline(1.0, color="0.5", linewidth=0.8)
        ax.legend()
        written += save_figure(fig, out, "pair_correlation")

    z, profiles, nominal = _homogeneity(analysis)
    if not any(_finite(p) for p in profiles.values()):
        written.skipped["homogeneity"] = "no volume proportion profile in analysis.json"
    elif len(profiles) < 2:
        written.skipped["homogeneity"] = "one population: its volume proportion is 1 at every height"
    else:
        fig = Figure(figsize=(4.5, 6))
        ax = fig.add_subplot()
        for k, (name, p) in enumerate(profiles.items()):
            ax.plot(p, z, marker=".", color=f"C{k}", label=name)
            if name in nominal:
                ax.axvline(nominal[name], color=f"C{k}", linewidth=0.8, linestyle=":")
        ax.set_xlabel("proportion of the solid volume")
        ax.set_ylabel("height z (d)")
        ax.set_xlim(-0.02, 1.02)
        ax.legend(title="population")
        written += save_figure(fig, out, "homogeneity")

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
    classes = analysis["size_classes"]
    sieves, z = _array(classes["sieves"]), _array(classes["z"])
    profile = np.atleast_2d(_array(classes["profile"]))
    for k in range(len(sieves) - 1):
        ax_z.plot(profile[k], z, marker=".", color=f"C{k}", label=f"{sieves[k]:.3g} - {sieves[k + 1]:.3g} d")
        share = _array(classes["volume_shares"])[k]
        ax_z.axvline(share, color=f"C{k}", linewidth=0.8, linestyle=":")
    ax_z.set_xlabel("share of the layer's solid volume")
    ax_z.set_ylabel("height z (d)")
    ax_z.set_xlim(-0.02, 1.02)
    ax_z.legend(title="size class", fontsize=8)
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------- campaign


def _read_runs(campaign_dir: Path) -> pd.DataFrame:
    path = campaign_dir / RUNS_TABLE
    if not path.is_file():
        raise InputError(f"{campaign_dir}: no {RUNS_TABLE} (not a campaign folder; run `granpack campaign` first)")
    try:
        runs = pd.read_csv(path)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: not a readable runs table ({exc})") from None
    missing = [c for c in ("path", "mixture", "family", "share", "shapes", "status") if c not in runs.columns]
    if missing:
        raise InputError(f"{path}: not a granpack runs table (no column '{missing[0]}')")
    runs["family"] = runs["family"].fillna("").astype(str)
    return runs[runs["status"] == "done"].reset_index(drop=True)


def _panel(family: str) -> str:
    return FAMILIES[family][2] if family in FAMILIES else "other"


def _label(family: str) -> str:
    return FAMILIES[family][0] if family in FAMILIES else (family or "no family")


def _marker(family: str) -> str:
    return FAMILIES[family][1] if family in FAMILIES else "x"


def _families(runs: pd.DataFrame) -> list[str]:
    """Families in the order of :data:`FAMILIES`, then the others in table order."""
    present = list(dict.fromkeys(runs["family"].tolist()))
    return [f for f in FAMILIES if f in present] + [f for f in present if f not in FAMILIES]


def _series(runs: pd.DataFrame, family: str, column: str) -> pd.DataFrame:
    """Mean, std and count of ``column`` per share for one family (shape families get the
    isometric reference at share 0)."""
    if column not in runs:
        return pd.DataFrame(columns=["share", "mean", "std", "count"])
    rows = runs[runs["family"] == family]
    if _panel(family) == "shape" and not (rows["share"] == 0).any():
        reference = runs[(runs["family"] == _REFERENCE_FAMILY) & (runs["share"] == 0)]
        rows = pd.concat([reference, rows])
    rows = rows[rows["share"].notna() & rows[column].notna()]
    stats = rows.groupby("share")[column].agg(["mean", "std", "count"]).reset_index().sort_values("share")
    stats["std"] = stats["std"].fillna(0.0)
    return stats


def _errorbar(ax: Axes, stats: pd.DataFrame, **style) -> None:
    ax.errorbar(100 * stats["share"], stats["mean"], yerr=stats["std"], capsize=3, **style)


def _share_axis(ax: Axes, shares: Iterable[float]) -> None:
    """Finish a panel against the share (in %): a panel of one share (a family of one mixture)
    gets the whole share scale instead of matplotlib's few hundredths of a percent around its
    point, and the legend goes where no point is."""
    shares = {round(100 * float(s), 9) for s in shares}
    if len(shares) == 1:
        ax.set_xlim(-5.0, 105.0)
    ax.legend(loc="best")


def _versus_share(runs: pd.DataFrame, column: str, ylabel: str, title: str, before: str | None = None) -> Figure | None:
    """One panel per group of families (size / shape / other) of ``column`` against the share;
    with ``before``, that column too, open markers and dashed, for the state before gravity."""
    if column not in runs or runs[column].notna().sum() == 0:
        return None
    groups: dict[str, list] = {}
    for family in _families(runs):
        if len(_series(runs, family, column)):
            groups.setdefault(_panel(family), []).append(family)
    if not groups:
        return None
    fig = Figure(figsize=(5.5 * len(groups), 4.2), layout="constrained")
    axes = fig.subplots(1, len(groups), squeeze=False, sharey=True)[0]
    for ax, panel in zip(axes, [p for p in ("size", "shape", "other") if p in groups]):
        shares = []
        for k, family in enumerate(groups[panel]):
            stats = _series(runs, family, column)
            shares += stats["share"].tolist()
            _errorbar(ax, stats, marker=_marker(family), color=f"C{k}", label=_label(family))
            if before is not None and before in runs and len(_series(runs, family, before)):
                _errorbar(ax, _series(runs, family, before), marker=_marker(family), color=f"C{k}", linestyle="--",
                          markerfacecolor="none", label=f"{_label(family)}: initial state")
        ax.set_xlabel(_panel_xlabel(runs, groups[panel]))
        _share_axis(ax, shares)
    axes[0].set_ylabel(ylabel)
    fig.suptitle(title)
    return fig


def _panel_xlabel(runs: pd.DataFrame, families: list[str]) -> str:
    """The share axis of a panel: which grains the share counts, from the campaign's own
    mixtures (the ``substituted`` column of the runs table) where they say it."""
    if all(_panel(f) == "shape" for f in families):
        return f"share of {' / '.join(_label(f).removesuffix(' pinacoids') for f in families)} grains, by volume (%)"
    grains = runs.loc[runs["family"].isin(families) & (runs["share"] > 0), "substituted"] if "substituted" in runs else []
    kinds = sorted({g for g in grains if isinstance(g, str) and g})
    sizes = sorted({g.rpartition("size ")[2] for g in kinds})
    if len(sizes) == 1 and all(_panel(f) == "size" for f in families):
        return f"share of small grains (size {sizes[0]}), by volume (%)"
    if len(kinds) == 1:
        return f"share of the {kinds[0]} grains, by volume (%)"
    return "share of the substituted grains, by volume (%)"


def _coordination_figure(runs: pd.DataFrame) -> Figure | None:
    families = [f for f in _families(runs) if any(len(_series(runs, f, c)) for c, _ in _COORDINATION)]
    if not families:
        return None
    fig = Figure(figsize=(4.5 * len(families), 4.2), layout="constrained")  # the suptitle clear of the panel titles
    axes = fig.subplots(1, len(families), squeeze=False, sharey=True)[0]
    for ax, family in zip(axes, families):
        shares = []
        for k, (column, name) in enumerate(_COORDINATION):
            stats = _series(runs, family, column)
            shares += stats["share"].tolist()
            if len(stats):
                _errorbar(ax, stats, marker="osDv"[k], color=f"C{k}", label=name)
        ax.set_title(_label(family))
        ax.set_xlabel(_panel_xlabel(runs, [family]))
        _share_axis(ax, shares)
    axes[0].set_ylabel("contacts per grain (bulk)")
    fig.suptitle("Coordination: all (N), simple (Ns), double (Nd), triple (Nt) contacts")
    return fig


def _fit(q: np.ndarray, n: np.ndarray) -> ExponentialFit:
    """The fit N(Q) = N0 + (N1 - N0)(1 - exp(-Q/Qc)) of :mod:`granpack.analysis.fit` (nan
    parameters, without a warning, when it cannot be made)."""
    from granpack.analysis._base import AnalysisWarning
    from granpack.analysis.fit import ExponentialFit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)
        return ExponentialFit().compute(q, n)


def _coordination_vs_order(runs: pd.DataFrame) -> Figure | None:
    if "order.Q00" not in runs or "coordination.N" not in runs:
        return None
    grains = runs[~runs["shapes"].astype(str).str.contains("sphere")]
    grains = grains[grains["order.Q00"].notna() & grains["coordination.N"].notna()]
    if not len(grains):
        return None
    fig = Figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    for family in _families(grains):
        rows = grains[grains["family"] == family]
        ax.plot(rows["order.Q00"], rows["coordination.N"], linestyle="none", marker=_marker(family), label=_label(family))
    fit = _fit(grains["order.Q00"].to_numpy(), grains["coordination.N"].to_numpy())
    if math.isfinite(fit.N0):
        q = np.linspace(0.0, float(grains["order.Q00"].max()) * 1.05, 200)
        err = fit.stderr
        label = (
            f"fit N0 = {fit.N0:.2f} ± {err['N0']:.2f}, N1 = {fit.N1:.2f} ± {err['N1']:.2f},\n"
            f"Qc = {fit.Qc:.3f} ± {err['Qc']:.3f} (rms {fit.rms:.3f})"
        )
        ax.plot(q, fit.predict(q), color="k", label=label)
    ax.set_xlabel("nematic order $Q^2_{00}$")
    ax.set_ylabel("coordination number N (bulk)")
    ax.legend(fontsize="small")
    ax.set_title("Coordination against orientational order (one point per packing)")
    return fig


def _chosen(runs: pd.DataFrame, mixtures: Iterable[str] | None) -> pd.DataFrame:
    if mixtures is None:
        return runs
    mixtures = list(mixtures)
    unknown = [m for m in mixtures if m not in set(runs["mixture"])]
    if unknown:
        raise InputError(f"--mixture: no finished run of mixture '{unknown[0]}' in this campaign")
    return runs[runs["mixture"].isin(mixtures)]


def _pair_correlation(analysis: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(r, g)`` from an analysis (empty arrays when absent, inconsistent or all nan)."""
    pc = analysis.get("pair_correlation") or {}
    r, g = _array(pc.get("r")), _array(pc.get("g"))
    return (r, g) if len(r) == len(g) and _finite(g) else (np.zeros(0), np.zeros(0))


def _share_colour(share: float):
    return colormaps["viridis"](0.9 * share) if math.isfinite(share) else "k"


def _family_axes(families: list[str], height: float, sharey: bool) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=(5 * len(families), height), layout="constrained")  # the suptitle clear of the panel titles
    axes = fig.subplots(1, len(families), squeeze=False, sharey=sharey)[0]
    for ax, family in zip(axes, families):
        ax.set_title(_label(family))
    return fig, axes


def _pair_correlation_figure(campaign_dir: Path, runs: pd.DataFrame) -> Figure | None:
    """g(r) of each mixture (mean over its replicas with the same r grid), one panel per family."""
    curves: dict[str, list] = {}
    for (family, mixture, share), rows in runs.groupby(["family", "mixture", "share"], sort=False, dropna=False):
        pairs = [_pair_correlation(_read_analysis(campaign_dir / p)) for p in rows["path"]]
        pairs = [(r, g) for r, g in pairs if len(r)]
        if not pairs:
            continue
        r0 = pairs[0][0]
        same = [g for r, g in pairs if len(r) == len(r0) and np.allclose(r, r0)]
        curves.setdefault(family, []).append((mixture, share, r0, np.mean(same, axis=0)))
    if not curves:
        return None
    # each panel its own g scale: the contact peaks of spheres are ten times those of polyhedra
    fig, axes = _family_axes([f for f in _families(runs) if f in curves], 4.5, sharey=False)
    for ax, family in zip(axes, [f for f in _families(runs) if f in curves]):
        for mixture, share, r, g in curves[family]:
            _plot_gr(ax, r, g, color=_share_colour(share), label=mixture, linewidth=1.0)
        ax.axhline(1.0, color="0.5", linewidth=0.8)
        ax.legend(fontsize="x-small")
    fig.suptitle("Pair correlation of the centres (bulk, mean over replicas)")
    return fig


def _homogeneity_figure(campaign_dir: Path, runs: pd.DataFrame) -> Figure | None:
    """Volume proportion profiles of the substituted populations (all but the first) of each
    mixture's first replica, one panel per family; dotted: the nominal share."""
    curves: dict[str, list] = {}
    for (family, mixture, share), rows in runs.groupby(["family", "mixture", "share"], sort=False, dropna=False):
        z, profiles, nominal = _homogeneity(_read_analysis(campaign_dir / rows["path"].iloc[0]))
        substituted = [(name, p, nominal.get(name, math.nan)) for name, p in list(profiles.items())[1:]]
        if substituted:
            curves.setdefault(family, []).append((mixture, share, z, substituted))
    if not curves:
        return None
    families = [f for f in _families(runs) if f in curves]
    fig, axes = _family_axes(families, 6.0, sharey=True)
    for ax, family in zip(axes, families):
        for mixture, share, z, substituted in curves[family]:
            colour = _share_colour(share)
            for k, (name, p, expected) in enumerate(substituted):
                ax.plot(p, z, color=colour, linestyle=("-", "--", "-.")[k % 3], label=f"{mixture}: {name}")
                if math.isfinite(expected):
                    ax.axvline(expected, color=colour, linewidth=0.6, linestyle=":")
        ax.set_xlabel("proportion of the solid volume")
        ax.set_xlim(-0.02, 1.02)
        ax.legend(fontsize="x-small")
    axes[0].set_ylabel("height z (d)")
    fig.suptitle("Homogeneity: volume proportion of the substituted grains per layer (dotted: nominal)")
    return fig


def _versus_grading(runs: pd.DataFrame) -> Figure | None:
    """Bulk solid fraction against the grading's parameter (Fuller exponent or lognormal
    polydispersity), one line per family and curve: the mean over the replicas, with their
    standard deviation, or for a point of one run the spread of its bulk layers
    (``solid_fraction.std``), so that a campaign of one replica still shows what a difference
    between two points is worth."""
    graded = runs[runs["grading_parameter"].notna() & runs["solid_fraction.bulk"].notna()]
    if not len(graded):
        return None
    fig = Figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    labels = {"fuller": "Fuller exponent n", "lognormal": "polydispersity δ"}
    for k, ((family, curve), rows) in enumerate(graded.groupby(["family", "grading"], sort=False, dropna=False)):
        by_point = rows.groupby("grading_parameter")
        stats = by_point["solid_fraction.bulk"].agg(["mean", "std", "count"])
        layers = by_point["solid_fraction.std"].first()
        spread = stats["std"].where(stats["count"] > 1, layers).fillna(0.0)
        ax.errorbar(stats.index, stats["mean"], yerr=spread, marker="o", capsize=3,
                    color=f"C{k}", label=f"{family or 'runs'} ({curve})")
    curves = sorted(set(graded["grading"]))
    ax.set_xlabel(" / ".join(labels.get(c, c) for c in curves))
    ax.set_ylabel("bulk solid fraction φ")
    ax.set_title("Solid fraction against the grading")
    ax.legend(fontsize="small")
    fig.text(0.01, 0.005, "error bars: standard deviation over the replicas (one run: the spread of its bulk layers)",
             fontsize="x-small", color="0.4")
    fig.tight_layout()
    return fig


def _campaign_skip_reason(stem: str, runs: pd.DataFrame, chosen: pd.DataFrame) -> str:
    """Why a campaign figure has nothing to show."""
    if not len(runs):
        return "no finished run in runs.csv (status 'done')"
    columns = {
        "solid_fraction": ["solid_fraction.bulk"], "order": ["order.Q00"],
        "coordination": [c for c, _ in _COORDINATION], "coordination_vs_order": ["order.Q00", "coordination.N"],
    }
    if stem == "coordination_vs_order" and runs["shapes"].astype(str).str.contains("sphere").all():
        return "every finished run is of spheres (no orientational order)"
    for column in columns.get(stem, []):
        if column not in runs or runs[column].notna().sum() == 0:
            return (f"no finished run has a value of {column} (nan when a run has no bulk region, "
                    "or no non-spherical grain for the order)")
    if stem in ("pair_correlation", "homogeneity") and len(chosen) < len(runs):
        return "none of the chosen mixtures has one (--mixture)"
    if stem == "pair_correlation":
        return "no finished run has a g(r) (empty when a run has no bulk region)"
    if stem == "homogeneity":
        return "no mixture has a second population (the figure shows the substituted grains)"
    if stem == "solid_fraction_vs_grading":
        return "no run of a Fuller or lognormal grading has a bulk solid fraction"
    if stem in ("solid_fraction", "order", "coordination"):
        valued = runs[runs[columns[stem]].notna().any(axis=1)]
        if valued["share"].notna().sum() == 0:
            return ("no mixture with a value has a share, the figure's x axis (give each [[mixtures]] entry of "
                    "the campaign file its `share`, and a `family` per curve)")
    return "nothing to draw"


def campaign_figures(campaign_dir: str | Path, mixtures: Iterable[str] | None = None) -> FigureFiles:
    """The campaign figures (module docstring), written into ``<campaign_dir>/figures/``.

    Args:
        campaign_dir: a folder written by ``granpack campaign`` (``runs.csv`` and run folders).
        mixtures: mixtures drawn in the g(r) and homogeneity figures (default: all).

    Returns:
        The files written, and in ``.skipped`` the figures left out (nothing to draw) with the reason.

    Raises:
        InputError: no readable ``runs.csv``, or an unknown mixture name.
    """
    campaign_dir = Path(campaign_dir)
    runs = _read_runs(campaign_dir)
    out = campaign_dir / "figures"
    chosen = _chosen(runs, mixtures)
    figures = {
        "solid_fraction": _versus_share(runs, "solid_fraction.bulk", "bulk solid fraction φ", "Solid fraction"),
        "order": _versus_share(runs, "order.Q00", "nematic order $Q^2_{00}$",
                               "Orientational order (dashed: the deposit before gravity)", before="run.initial_order.Q00"),
        "coordination": _coordination_figure(runs),
        "coordination_vs_order": _coordination_vs_order(runs),
        "pair_correlation": _pair_correlation_figure(campaign_dir, chosen),
        "homogeneity": _homogeneity_figure(campaign_dir, chosen),
    }
    if "grading_parameter" in runs and runs["grading_parameter"].notna().any():  # a campaign of gradings
        figures["solid_fraction_vs_grading"] = _versus_grading(runs)
    written = FigureFiles()
    for stem, fig in figures.items():
        if fig is not None:
            written += save_figure(fig, out, stem)
        else:
            written.skipped[stem] = _campaign_skip_reason(stem, runs, chosen)
    return written


def make_figures(folder: str | Path, mixtures: Iterable[str] | None = None) -> FigureFiles:
    """Figures of a campaign folder (it has ``runs.csv``) or of a run folder (see
    :func:`campaign_figures`, :func:`run_figures`; ``.skipped`` of the result says what was left
    out and why).

    Args:
        folder: the folder.
        mixtures: campaign only: the mixtures of the g(r) and homogeneity figures.

    Raises:
        InputError: the folder is neither, or ``mixtures`` is given for a run folder.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder")
    if (folder / RUNS_TABLE).is_file():
        return campaign_figures(folder, mixtures)
    if mixtures:
        raise InputError(f"--mixture applies to campaign folders only ({folder} has no {RUNS_TABLE})")
    if not (folder / ANALYSIS_FILE).is_file():
        raise InputError(f"{folder}: neither a campaign folder ({RUNS_TABLE}) nor an analysed run folder "
                         f"({ANALYSIS_FILE})")
    return run_figures(folder)

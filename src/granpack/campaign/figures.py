"""The figures of a campaign folder (``runs.csv`` and the run folders), as PNG and SVG.

:func:`campaign_figures` writes into ``<campaign>/figures/``:

- ``solid_fraction`` and ``order``: bulk solid fraction and nematic order Q00 against the share
  of the substituted grains, one curve per family, error bars = standard deviation over the
  replicas; the left panel shows the size mixtures (spheres and isometric pinacoids, share of
  small grains), the right panel the shape mixtures (elongated, flat, flat & elongated), which
  start from the monodisperse isometric pinacoids (family ``pinacoids``, share 0);
- ``coordination``: N, Ns, Nd, Nt against the share, one panel per family;
- ``coordination_vs_order``: N against Q00 for every non-spherical run, with the fit
  ``N(Q) = N0 + (N1 - N0)(1 - exp(-Q/Qc))`` of :mod:`granpack.analysis.fit` (docs/method/analysis.md#n-versus-q00-fit);
- ``pair_correlation`` and ``homogeneity``: g(r) and the volume proportion profiles of the
  chosen mixtures (default: all), one panel per family, read from each run's ``analysis.json``
  by the readers of their quantities (:func:`~granpack.analysis.pair_correlation.g_of`,
  :func:`~granpack.analysis.homogeneity.proportions_of`), g(r) drawn by
  :func:`~granpack.analysis.pair_correlation.plot_g` as in a run's figure;
- ``solid_fraction_vs_grading``: a campaign of gradings only, the bulk solid fraction against
  the grading's parameter.

A mixture's family and share come from the ``family`` and ``share`` keys of its campaign entry;
:data:`FAMILIES` are the study's, which fix their labels, markers and panels.
:func:`make_figures` is ``granpack figures``: a campaign folder's figures, or a run folder's
(:func:`granpack.figures.run_figures`). Figures are built without pyplot (:mod:`granpack.figures`).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from granpack.analysis.homogeneity import proportions_of
from granpack.analysis.pair_correlation import g_of, plot_g
from granpack.errors import InputError
from granpack.figures import FigureFiles, read_analysis, run_figures, save_figure
from granpack.io.run_folder import ANALYSIS_FILE, RUNS_TABLE

if TYPE_CHECKING:
    from granpack.analysis.fit import ExponentialFit

__all__ = ["FAMILIES", "campaign_figures", "make_figures"]

#: the study's mixture families: name -> (legend label, marker, panel); panel "size" or "shape"
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
        pairs = [g_of(read_analysis(campaign_dir / p).get("pair_correlation")) for p in rows["path"]]
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
        for k, (mixture, share, r, g) in enumerate(curves[family]):
            plot_g(ax, {"r": r, "g": g}, reference=k == len(curves[family]) - 1,  # the line g = 1 once, last
                   color=_share_colour(share), label=mixture, linewidth=1.0)
        ax.legend(fontsize="x-small")
    fig.suptitle("Pair correlation of the centres (bulk, mean over replicas)")
    return fig


def _homogeneity_figure(campaign_dir: Path, runs: pd.DataFrame) -> Figure | None:
    """Volume proportion profiles of the substituted populations (all but the first) of each
    mixture's first replica, one panel per family; dotted: the nominal share."""
    curves: dict[str, list] = {}
    for (family, mixture, share), rows in runs.groupby(["family", "mixture", "share"], sort=False, dropna=False):
        z, profiles, nominal = proportions_of(read_analysis(campaign_dir / rows["path"].iloc[0]).get("homogeneity"))
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
    :func:`campaign_figures`, :func:`granpack.figures.run_figures`; ``.skipped`` of the result
    says what was left out and why): what ``granpack figures`` draws. It lives here, above both,
    because the run figures know nothing of campaigns.

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

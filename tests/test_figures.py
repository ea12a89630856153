"""Figures of a campaign (from a synthetic results table) and of a run (from a hand-built packing)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from matplotlib.image import imread

from granpack.box import Box
from granpack.contact.contacts import ContactSet
from granpack.errors import InputError
from granpack.campaign.figures import (
    _coordination_figure,
    _homogeneity_figure,
    _pair_correlation_figure,
    _read_runs,
    campaign_figures,
    make_figures,
)
from granpack.figures import render_packing, save_figure
from granpack.packing import Packing
from granpack.rotations import random_quaternions
from granpack.shapes import Pinacoid, ShapeTable, Sphere
from granpack.state import ParticleState

FAMILIES = {  # family -> (shares, shape of the runs, the grains the share counts)
    "spheres": ((0.0, 0.13, 0.30), "sphere", "sphere, size 0.333 d"),
    "pinacoids": ((0.0, 0.30, 1.0), "pinacoid", "pinacoid, size 0.333 d"),
    "flat": ((0.28, 0.77, 1.0), "pinacoid", "pinacoid 1 x 3, size 1 d"),
}


def _analysis(rng, share: float, seed: int, order: float) -> dict:
    z = np.arange(0.5, 8.0, 1.0)
    r = np.linspace(0.01, 3.0, 150)
    coordination = 4.0 + 2.0 * (1.0 - math.exp(-order / 0.2)) + 0.05 * rng.standard_normal()
    return {
        "solid_fraction": {
            "bulk": 0.62 + 0.1 * share * (1 - share) + 0.005 * rng.standard_normal(),
            "std": 0.01,
            "profile_z": z.tolist(),
            "profile_phi": (0.6 + 0.02 * rng.standard_normal(len(z))).tolist(),
        },
        "coordination": {"N": coordination, "Ns": 2.0, "Nd": 1.5, "Nt": 0.5, "Nc": 6.5, "rattler_fraction": 0.02},
        "order": {"Q00": order, "Q22": 0.01, "director": [0.0, 0.0, 1.0]},
        "pair_correlation": {"r": r.tolist(), "g": (1.0 + np.exp(-r) * np.cos(6 * r)).tolist()},
        "equilibrium": {"max_net_force": 1e-5, "max_net_torque": 1e-5, "kinetic_energy": 1e-10, "wall_force_over_weight": 1.0},
        "interpenetration": {"max": 1e-3, "mean": 1e-4, "expansion_k": 1.001},
        "homogeneity": {
            "z": z.tolist(),
            "proportions": {"large": (1 - share + 0 * z).tolist(), "small": (share + 0 * z).tolist()},
            "nominal": {"large": 1 - share, "small": share},
        },
        "bulk": {"z_bottom": 2.0, "z_top": 6.0, "valid": True},
        "n_particles": 100,
        "populations": [{"name": "large"}, {"name": "small"}],
        "seed": seed,
        "version": "test",
    }


@pytest.fixture
def campaign_dir(tmp_path, rng):
    """A campaign folder as `granpack campaign` leaves it: runs.csv and analysed run folders."""
    from granpack.campaign.store import flatten

    rows = []
    for family, (shares, shape, grains) in FAMILIES.items():
        for share in shares:
            mixture = f"{family}-{round(100 * share)}"
            for seed in (1, 2):
                analysis = _analysis(rng, share, seed, order=0.0 if shape == "sphere" else 0.05 + 0.5 * share)
                run_dir = tmp_path / mixture / f"seed-{seed}"
                run_dir.mkdir(parents=True)
                (run_dir / "analysis.json").write_text(json.dumps(analysis))
                row = dict(path=f"{mixture}/seed-{seed}", mixture=mixture, family=family, share=share, shapes=shape,
                           substituted=grains if share > 0 else "", replica=seed - 1, seed=seed, status="done", error=None)
                row.update(flatten(analysis))
                rows.append(row)
    rows.append(dict(path="broken/seed-1", mixture="broken", family="flat", share=0.5, shapes="pinacoid", replica=0,
                     seed=1, status="failed", error="RuntimeError: boom"))
    pd.DataFrame(rows).to_csv(tmp_path / "runs.csv", index=False)
    return tmp_path


def _check_images(paths):
    assert paths
    for path in paths:
        assert path.stat().st_size > 0
        if path.suffix == ".png":
            image = imread(path)
            assert image.ndim == 3 and image.shape[0] > 50 and image.shape[1] > 50
            assert image[..., :3].std() > 0.01  # not a blank canvas
        else:
            assert path.read_text().lstrip().startswith("<?xml")


def test_campaign_figures_written(campaign_dir):
    paths = campaign_figures(campaign_dir)
    names = {p.name for p in paths}
    for stem in ("solid_fraction", "order", "coordination", "coordination_vs_order", "pair_correlation", "homogeneity"):
        assert f"{stem}.png" in names and f"{stem}.svg" in names
    assert all(p.parent == campaign_dir / "figures" for p in paths)
    _check_images(paths)


def test_campaign_panels_name_their_grains_and_keep_their_own_g_scale(campaign_dir):
    """Each family's coordination panel says which grains its share counts; the g(r) panels do
    not share a y axis (the sphere peaks would flatten the polyhedra's), the homogeneity ones do
    (one height scale)."""
    runs = _read_runs(campaign_dir)
    labels = [ax.get_xlabel() for ax in _coordination_figure(runs).axes]
    assert labels == ["share of small grains (size 0.333 d), by volume (%)"] * 2 + ["share of flat grains, by volume (%)"]
    # the sizes are the campaign's own: another size ratio, another label; a family of its own, its grains
    runs.loc[runs["family"] == "spheres", "substituted"] = "sphere, size 0.1 d"
    assert [ax.get_xlabel() for ax in _coordination_figure(runs).axes][0] == "share of small grains (size 0.1 d), by volume (%)"
    runs.loc[runs["family"] == "spheres", "family"] = "fines"
    assert "share of the sphere, size 0.1 d grains" in [ax.get_xlabel() for ax in _coordination_figure(runs).axes][-1]
    gr = _pair_correlation_figure(campaign_dir, runs).axes
    assert not any(gr[0].get_shared_y_axes().joined(gr[0], ax) for ax in gr[1:])
    profiles = _homogeneity_figure(campaign_dir, runs).axes
    assert all(profiles[0].get_shared_y_axes().joined(profiles[0], ax) for ax in profiles[1:])


def test_campaign_figures_chosen_mixtures_and_dispatch(campaign_dir):
    paths = make_figures(campaign_dir, mixtures=["flat-28"])
    assert (campaign_dir / "figures" / "pair_correlation.png") in paths
    with pytest.raises(InputError, match="--mixture.*nope"):
        make_figures(campaign_dir, mixtures=["nope"])


def test_figures_bad_folders(tmp_path):
    with pytest.raises(InputError, match="no such folder"):
        make_figures(tmp_path / "absent")
    with pytest.raises(InputError, match="neither a campaign folder"):
        make_figures(tmp_path)


def _mixed_packing(rng) -> Packing:
    """Spheres and pinacoids on a loose grid (no contacts needed for a picture)."""
    shapes = ShapeTable.from_shapes([Sphere(1.0), Pinacoid.from_size(1.0, 2.0, 3.0)])
    grid = np.array([(x, y, z) for x in range(3) for y in range(3) for z in range(2)], dtype=float) + 0.5
    n = len(grid)
    kind = np.arange(n) % 2
    state = ParticleState(
        box=Box.square(3.0), shapes=shapes, kind=kind, population=kind, position=grid,
        quaternion=random_quaternions(n, rng),
    )
    return Packing(state, ContactSet.empty(), 5e-3, ["spheres", "flat-elongated"], {"seed": 3})


def test_render_packing_draws_every_grain(tmp_path, rng):
    packing = _mixed_packing(rng)
    fig = render_packing(packing)
    ax = fig.axes[0]
    n_faces = len(ax.collections[0].get_facecolor())
    # 9 spheres of 72 facets (12 meridians) and 9 pinacoids of 8 faces; back faces are culled
    assert 9 * (8 + 72) // 3 < n_faces < 9 * (8 + 72)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["spheres", "flat-elongated"]
    # the x and y axes meet at (0, 0): no 0 tick on either, so their labels do not collide there
    assert 0.0 not in ax.get_xticks() and 0.0 not in ax.get_yticks()
    assert ax.get_title() == "18 grains, cell 3 d x 3 d"
    _check_images(save_figure(fig, tmp_path, "packing"))
    for container, title in (("box", "18 grains, box 3 d x 3 d"), ("cylinder", "18 grains, cylinder of diameter 3 d")):
        packing.state.box = Box.square(3.0, container)
        assert render_packing(packing).axes[0].get_title() == title


def test_run_figures(tmp_path, rng):
    gsd_io = pytest.importorskip("granpack.io.gsd", reason="granpack.io.gsd not written yet")
    packing = _mixed_packing(rng)
    gsd_io.write_packing(tmp_path / "final.gsd", packing)
    (tmp_path / "analysis.json").write_text(json.dumps(_analysis(rng, 0.3, 3, 0.2)))
    paths = make_figures(tmp_path)
    assert {p.stem for p in paths} == {"solid_fraction_profile", "pair_correlation", "homogeneity", "packing"}
    _check_images(paths)


def test_campaign_figures_say_what_they_skipped_and_why(campaign_dir, capsys):
    from granpack.cli import main

    assert campaign_figures(campaign_dir).skipped == {}
    runs = pd.read_csv(campaign_dir / "runs.csv")
    runs[runs["family"] == "spheres"].to_csv(campaign_dir / "runs.csv", index=False)
    paths = campaign_figures(campaign_dir)
    assert paths.skipped == {"coordination_vs_order": "every finished run is of spheres (no orientational order)"}
    assert not any(p.stem == "coordination_vs_order" for p in paths)
    runs.assign(status="failed").to_csv(campaign_dir / "runs.csv", index=False)
    with pytest.raises(SystemExit) as info:
        main(["figures", str(campaign_dir)])
    out, err = capsys.readouterr()
    assert info.value.code == 0 and out.startswith("no figure written") and "skipped" not in out
    assert "skipped solid_fraction: no finished run in runs.csv (status 'done')" in err.splitlines()  # a note: stderr


def test_a_campaign_without_shares_says_so_instead_of_nothing_to_draw(campaign_dir):
    runs = pd.read_csv(campaign_dir / "runs.csv")
    runs.assign(share=math.nan).to_csv(campaign_dir / "runs.csv", index=False)
    skipped = campaign_figures(campaign_dir).skipped
    assert set(skipped) == {"solid_fraction", "order", "coordination"}
    assert all("no mixture with a value has a share" in why and "`share`" in why for why in skipped.values())


def _extent(artist, renderer):
    return artist.get_window_extent(renderer)


def test_a_family_of_one_point_gets_the_share_scale_and_its_legend_beside_the_point(campaign_dir):
    """A family of one mixture (share 0) is drawn on the 0-100 % scale, not a few hundredths of a
    percent around its point; no legend covers a point; the suptitle clears the panel titles."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from granpack.campaign.figures import _versus_share

    runs = _read_runs(campaign_dir)
    runs = runs[(runs["family"] != "spheres") | (runs["share"] == 0)]
    for fig in (_coordination_figure(runs), _versus_share(runs, "solid_fraction.bulk", "phi", "Solid fraction")):
        assert isinstance(fig, Figure)
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        renderer = canvas.get_renderer()
        single = fig.axes[0]  # the size panel: the spheres family, one share
        low, high = single.get_xlim()
        assert low <= 0.0 and high >= 100.0, (low, high)
        for ax in fig.axes:
            legend = _extent(ax.get_legend(), renderer)
            for line in ax.get_lines():
                for x, y in line.get_xydata():
                    px, py = ax.transData.transform((x, y))
                    assert not legend.contains(px, py), (ax.get_title(), x, y)
            if ax.get_title():
                assert not _extent(fig._suptitle, renderer).overlaps(_extent(ax.title, renderer))


def test_run_figures_skip_an_empty_pair_correlation(tmp_path, rng):
    analysis = _analysis(rng, 0.3, 1, 0.1)
    analysis["pair_correlation"]["g"] = [None] * len(analysis["pair_correlation"]["r"])  # nan: no bulk region
    analysis["bulk"]["valid"] = False
    (tmp_path / "analysis.json").write_text(json.dumps(analysis))
    paths = make_figures(tmp_path)
    assert not (tmp_path / "figures" / "pair_correlation.png").exists()
    assert paths.skipped["pair_correlation"].startswith("g(r) is empty (no bulk region")
    assert paths.skipped["packing"] == f"no final.gsd in {tmp_path}"
    assert {p.stem for p in paths} == {"solid_fraction_profile", "homogeneity"}


def test_a_run_of_one_population_has_no_homogeneity_figure_and_says_why(tmp_path, rng):
    analysis = _analysis(rng, 0.0, 1, 0.1)
    analysis["homogeneity"]["proportions"] = {"large": analysis["homogeneity"]["proportions"]["large"]}
    analysis["homogeneity"]["nominal"] = {"large": 1.0}
    (tmp_path / "analysis.json").write_text(json.dumps(analysis))
    paths = make_figures(tmp_path)
    assert "homogeneity" not in {p.stem for p in paths}
    assert paths.skipped["homogeneity"] == "one population: its volume proportion is 1 at every height"


def test_the_order_figure_shows_the_deposit_before_gravity_beside_the_final_order(campaign_dir):
    from granpack.campaign.figures import _versus_share

    runs = _read_runs(campaign_dir)
    runs["run.initial_order.Q00"] = 0.02
    fig = _versus_share(runs, "order.Q00", "Q00", "Orientational order", before="run.initial_order.Q00")
    labels = [t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()]
    assert "flat pinacoids: initial state" in labels and "flat pinacoids" in labels
    dashed = [line for ax in fig.axes for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert dashed and all(np.allclose(line.get_ydata(), 0.02) for line in dashed)


def test_a_campaign_of_gradings_draws_its_solid_fraction_against_the_exponent(campaign_dir):
    """The runs table's grading columns (Fuller exponents here) give one more figure; a campaign
    without gradings does not have it."""
    runs = pd.read_csv(campaign_dir / "runs.csv")
    assert "solid_fraction_vs_grading" not in {p.stem for p in campaign_figures(campaign_dir)}
    runs["grading"] = np.where(runs["family"] == "flat", "", "fuller")
    runs["grading_parameter"] = np.where(runs["family"] == "flat", np.nan, 0.3 + runs["share"])
    runs.to_csv(campaign_dir / "runs.csv", index=False)
    from granpack.campaign.figures import _versus_grading

    fig = _versus_grading(_read_runs(campaign_dir))
    ax = fig.axes[0]
    assert ax.get_xlabel() == "Fuller exponent n" and len(ax.get_legend().get_texts()) == 2
    paths = campaign_figures(campaign_dir)
    _check_images([p for p in paths if p.stem == "solid_fraction_vs_grading"])
    runs["solid_fraction.bulk"] = np.nan
    runs.to_csv(campaign_dir / "runs.csv", index=False)
    assert "solid_fraction_vs_grading" in campaign_figures(campaign_dir).skipped


def test_the_runs_table_names_each_runs_grading():
    from granpack.campaign.spec import campaign_from_dict
    from granpack.campaign.store import grading_of

    spec = campaign_from_dict({"mixtures": [
        {"name": "fuller", "populations": [{"shape": "sphere", "volume_fraction": 1.0, "grading": {
            "curve": "fuller", "d_min": 0.25, "d_max": 1.0, "exponent": 0.45}}]},
        {"name": "one-size", "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}]}]})
    assert grading_of(spec.runs[0]) == ("fuller", 0.45)
    curve, value = grading_of(spec.runs[1])
    assert curve == "" and math.isnan(value)


def _lines(ax) -> list:
    return [(line.get_label(), line.get_xydata()) for line in ax.get_lines()]


def test_a_computed_quantity_draws_from_its_own_part_what_the_run_figure_draws_from_the_file(tmp_path, rng):
    """One plotting path: a quantity's ``.plot(ax)`` draws from its ``to_dict()`` the lines that
    ``granpack figures`` draws from the run's analysis.json, through the same function."""
    import warnings

    from matplotlib.figure import Figure
    from packing_builders import random_pinacoids

    from granpack.analysis import Homogeneity, PairCorrelation, SolidFraction, analyze_run
    from granpack.analysis.homogeneity import plot_proportions
    from granpack.analysis.pair_correlation import plot_g
    from granpack.analysis.size_classes import SizeClasses, plot_class_profiles
    from granpack.analysis.solid_fraction import plot_profile
    from granpack.figures import read_analysis
    from granpack.io.gsd import write_packing

    packing = random_pinacoids(400, rng)
    write_packing(tmp_path / "final.gsd", packing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analyze_run(tmp_path)
        sf = SolidFraction().compute(packing)
        bulk = (sf.z_bottom, sf.z_top)
        quantities = {
            "solid_fraction": (sf, lambda ax, data: plot_profile(ax, data["solid_fraction"], data["bulk"])),
            "pair_correlation": (PairCorrelation(200, 4.0, bulk).compute(packing),
                                 lambda ax, data: plot_g(ax, data["pair_correlation"]) and ax.legend()),
            "homogeneity": (Homogeneity(1.0, bulk).compute(packing),
                            lambda ax, data: plot_proportions(ax, data["homogeneity"])),
            "size_classes": (SizeClasses(None, 1.0, bulk).compute(packing),
                             lambda ax, data: plot_class_profiles(ax, data["size_classes"])),
        }
    data = read_analysis(tmp_path)
    assert sf.has_bulk and data["bulk"]["valid"]
    for key, (quantity, from_file) in quantities.items():
        mine, theirs = Figure().add_subplot(), Figure().add_subplot()
        assert quantity.plot(mine) is mine
        from_file(theirs, data)
        assert len(_lines(mine)) >= 2, key
        for (label, xy), (label_file, xy_file) in zip(_lines(mine), _lines(theirs), strict=True):
            assert label == label_file and np.allclose(xy, xy_file, equal_nan=True), (key, label)
        assert mine.get_xlabel() == theirs.get_xlabel() and mine.get_ylabel() == theirs.get_ylabel(), key
        legends = [[t.get_text() for t in ax.get_legend().get_texts()] for ax in (mine, theirs)]
        assert legends[0] == legends[1], key


@pytest.mark.filterwarnings("ignore::granpack.analysis.AnalysisWarning")
def test_a_container_run_draws_its_wall_profile_and_a_periodic_one_says_why_not(tmp_path, rng):
    from granpack.analysis import analyze_run
    from granpack.figures import run_figures
    from matplotlib.figure import Figure

    from granpack.io.gsd import read_packing, write_packing

    grid = np.array([(x, y, z) for x in range(6) for y in range(6) for z in range(8)], dtype=float) + 0.5
    grid = grid[np.hypot(grid[:, 0] - 3.0, grid[:, 1] - 3.0) <= 2.5]
    state = ParticleState(box=Box.square(6.0, "cylinder"), shapes=ShapeTable.from_shapes([Sphere(1.0)]),
                          kind=np.zeros(len(grid), np.int64), population=np.zeros(len(grid), np.int64), position=grid,
                          quaternion=random_quaternions(len(grid), rng))
    write_packing(tmp_path / "final.gsd", Packing(state, ContactSet.empty(), 5e-3, ["spheres"], {"seed": 3}))
    analyze_run(tmp_path)
    written = run_figures(tmp_path)
    assert {"wall_profile", "vertical_stress"} <= {p.stem for p in written}
    _check_images([p for p in written if p.stem in ("wall_profile", "vertical_stress")])
    # the vertical stress drawn from the file is the computed quantity's
    from granpack.analysis.wall_forces import WallForces, plot_vertical_stress
    from granpack.figures import read_analysis

    data = read_analysis(tmp_path)
    mine, theirs = Figure().add_subplot(), Figure().add_subplot()
    WallForces(z_surface=data["walls"]["z_surface"]).compute(read_packing(tmp_path / "final.gsd")).plot(mine)
    plot_vertical_stress(theirs, data["walls"])
    assert len(_lines(mine)) >= 2
    for (label, xy), (label_file, xy_file) in zip(_lines(mine), _lines(theirs), strict=True):
        assert label == label_file and np.allclose(xy, xy_file, equal_nan=True), label
    periodic = tmp_path / "periodic"
    periodic.mkdir()
    (periodic / "analysis.json").write_text(json.dumps(_analysis(rng, 0.3, 3, 0.2)))
    skipped = run_figures(periodic).skipped
    assert "periodic cell has no side walls" in skipped["wall_profile"]
    assert "periodic cell has no side walls" in skipped["vertical_stress"]

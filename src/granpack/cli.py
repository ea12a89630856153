"""The ``granpack`` command.

Exit status: 0 on success; 2 for bad input or a usage error (one line ``error: ...`` on stderr,
never a traceback: an unknown command or option, a missing or malformed value, a bad config, an
output folder that would lose work); 1 for a campaign with failed runs, or a file the system
refuses (permissions, disk full); 130 when interrupted by Ctrl-C (one line; a run keeps its
checkpoint and the line gives the command that resumes it). SIGTERM (``kill``, a batch
scheduler's stop before its SIGKILL) is taken as Ctrl-C, so a stopped job ends the same way.

Streams: results go to stdout (with ``--json``, one JSON document instead of the tables);
progress, notes and warnings go to stderr, one line each. Tables are cut to the terminal's width
on a terminal only: redirected, they are printed whole.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import threading
import warnings
from pathlib import Path
from typing import NoReturn, Optional

import typer
import typer.main

from granpack import __version__
from granpack.errors import InputError, RunInterrupted
from granpack.shapes import ShapeError

__all__ = ["app", "main", "demo_config"]

#: plain help (click's): flags without a value type, each paragraph wrapped to the terminal as one text
app = typer.Typer(add_completion=False, rich_markup_mode=None, help="Dense random packings of rigid grains (NSCD).")


class _Stop(Exception):
    """Ends a command with one line on stderr and an exit status (raised inside commands)."""

    def __init__(self, message: str, code: int):
        super().__init__(message)
        self.message = message
        self.code = code


def _click_module():
    """The click that typer really uses: its own copy (typer >= 0.20) or the click package."""
    vendored = getattr(typer.main, "_click", None)
    if vendored is not None:
        return vendored
    import click

    return click


_CLICK = _click_module()
_CLICK_EXCEPTION = _CLICK.exceptions.ClickException
_ABORT = tuple({typer.Abort, getattr(_CLICK.exceptions, "Abort", typer.Abort)})


def _version(value: bool) -> None:
    if value:
        from granpack._numba import numba, thread_count, threading_layer  # granpack's Numba settings first

        threads = thread_count()
        typer.echo(f"granpack {__version__} (Numba {numba.__version__}, threading layer {threading_layer()}, "
                   f"{threads} thread{'s' if threads > 1 else ''})")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Print the version and exit."),
) -> None:
    """Dense random packings of rigid grains (NSCD): check a config, run, analyse, draw, export."""


def _console(stderr: bool = False):
    """A rich console: the terminal's width on a terminal, unlimited otherwise (files, pipes)."""
    from rich.console import Console

    stream = sys.stderr if stderr else sys.stdout
    isatty = getattr(stream, "isatty", None)
    if isatty is not None and isatty():
        return Console(stderr=stderr)
    return Console(stderr=stderr, width=100_000, no_color=True, highlight=False)


def _print_json(data) -> None:
    from granpack.io.json import to_jsonable

    typer.echo(json.dumps(to_jsonable(data), indent=2, allow_nan=False))


def _note(message: str) -> None:
    typer.echo(message, err=True)


def _shape_table(mixture):
    """Each population's shapes (:meth:`granpack.mixture.Mixture.shape_rows`) as a rich table: sizes in
    every definition, volume, aspect ratios, vertices, and for shapes from files the convexity and
    the deviations of the reduction."""
    from rich.table import Table
    from rich.text import Text

    rows = mixture.shape_rows()
    meshes = any(r.get("file") for r in rows)
    table = Table(title=Text("shapes (a graded population's at size 1)"))
    headings = ["population", "shape", "count", "circumscribed (d)", "sieve (d)", "equiv. volume (d)",
                "volume (d^3)", "L/G, G/E", "vertices"]
    headings += ["convexity", "hull vertices", "reduction: volume, moments, L/G, G/E (%)"] if meshes else []
    for heading in headings:
        table.add_column(heading, justify="left" if heading in ("population", "shape") else "right")
    for r in rows:
        cells = [r["population"], r["shape"], str(r["count"]), *(f"{v:.6g}" for v in r["sizes"].values()),
                 f"{r['volume']:.6g}", "{:.4g}, {:.4g}".format(*r["aspect"]), str(r["vertices"])]
        if meshes:
            dev = r.get("deviations")
            change = ("" if dev is None else ", ".join(f"{100 * x:+.2f}" for x in
                                                       [dev["volume"], *dev["moments"], *dev["aspect"]]))
            cells += ([f"{r['convexity']:.4f}", str(r["hull_vertices"]), change or "none needed"] if r.get("file")
                      else ["", "", ""])
        table.add_row(*cells)
    return table


def _sieve_table(mixture, k: int):
    """The requested and poured sieve curves of graded population ``k`` as a rich table."""
    from rich.table import Table
    from rich.text import Text

    population = mixture.populations[k]
    table = Table(title=Text(f"{population.name}: % passing by volume"),
                  caption=Text(f"{population.grading.curve} curve; largest gap {100 * mixture.largest_deviation(k):.2f} %"))
    for heading in ("sieve (d)", "requested", "poured"):
        table.add_column(heading, justify="right")
    for row in mixture.sieve_curve(k):
        table.add_row(f"{row['size']:.4g}", f"{100 * row['requested']:.2f}", f"{100 * row['achieved']:.2f}")
    return table


def _settings_lines(cfg) -> list[str]:
    """The settings of a resolved run config, one line per table (:data:`granpack.config.SETTING_TABLES`)
    with each key's value and unit, as `granpack check` prints them."""
    from granpack.config import SETTING_TABLES, unit_of

    lines = []
    for table in SETTING_TABLES:
        model = getattr(cfg, table)
        items = []
        for key in type(model).model_fields:
            value, unit = getattr(model, key), unit_of(type(model), key)
            if key == "alert_distance" and value is None:
                items.append(f"{key} {cfg.resolved_alert_distance:g} d (automatic)")
            elif key == "wall_friction" and value is None:
                items.append(f"{key} {cfg.solver.friction:g} (solver.friction)")
            else:
                items.append(f"{key} {value:g}" if isinstance(value, float) else f"{key} {value}")
                items[-1] += f" {unit}" if unit else ""
        lines.append(f"{table}: " + ", ".join(items))
    return lines


def _layout_warnings(data: dict) -> list[str]:
    """A warning naming the new keys when ``data`` (a parsed config) uses the flat ``[solver]``
    layout of granpack 0.1.0, which is still read (:data:`granpack.config.MOVED_SOLVER_KEYS`)."""
    from granpack.config import moved_keys

    moved = moved_keys(data)
    if not moved:
        return []
    return [f"the flat [solver] table of granpack 0.1.0 is read as today's tables ({', '.join(moved)}); "
            "write the keys there"]


def _toml_of(path: Path) -> dict:
    """The parsed TOML of a config file that has already been validated."""
    import tomllib

    return tomllib.loads(path.read_text(encoding="utf-8"))


def _is_campaign_file(path: Path) -> bool:
    """True when ``path`` reads as TOML with a top-level ``mixtures`` key (a campaign spec).

    Anything unreadable is left to the run-config loader, whose errors name the file.
    """
    import tomllib

    try:
        return "mixtures" in tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False


def _is_run_config(path: Path) -> bool:
    """True when ``path`` reads as TOML with a top-level ``populations`` key and no ``mixtures``
    (a run config)."""
    import tomllib

    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return "populations" in data and "mixtures" not in data


def _check_campaign(path: Path, json_output: bool) -> None:
    """`granpack check` on a campaign spec: every run config validated, one row per mixture."""
    from rich.table import Table
    from rich.text import Text

    from granpack.advice import advise
    from granpack.campaign.spec import load_campaign
    from granpack.mixture import Mixture

    spec = load_campaign(path)
    rows, warnings, first_config = [], [], None
    for mix in spec.mixtures:
        runs = [r for r in spec.runs if r.mixture == mix.name]
        cfg = runs[0].config
        first_config = first_config or cfg
        mixture = Mixture.from_config(cfg)
        for warning in advise(cfg, mixture):
            warnings.append(f"{mix.name}: {warning}")
        for warning in _layout_warnings(runs[0].settings):
            if warning not in warnings:
                warnings.append(warning)
        rows.append({"mixture": mix.name, "family": mix.family, "share": mix.share, "n_particles": cfg.n_particles,
                     "lateral_size": cfg.lateral_size, "seeds": [r.seed for r in runs], "populations": mixture.table()})
    if json_output:
        _print_json({"campaign": str(path), "valid": True, "replicas": spec.replicas, "n_runs": len(spec.runs),
                     "mixtures": rows, "warnings": warnings})
        return
    table = Table(title=Text(f"{path}: campaign"))
    for heading in ("mixture", "family", "share", "N", "cell (d)", "seeds", "populations (count, achieved share)"):
        table.add_column(heading, justify="right" if heading in ("share", "N", "cell (d)") else "left")
    for row in rows:
        pops = "; ".join(f"{p['population']} ({p['count']}, {p['achieved_share']:.4f})" for p in row["populations"])
        table.add_row(row["mixture"], row["family"] or "", "" if row["share"] is None else f"{row['share']:g}",
                      str(row["n_particles"]), f"{row['lateral_size']:g}", ", ".join(map(str, row["seeds"])), pops)
    console = _console()
    console.print(table)
    console.print(f"{len(spec.mixtures)} mixtures x {spec.replicas} replicas = {len(spec.runs)} runs", markup=False)
    console.print("settings of the first mixture (others differ only where their [[mixtures]] entry says):",
                  markup=False)
    for line in _settings_lines(first_config):
        console.print(line, markup=False)
    for warning in warnings:
        _note(f"warning: {warning}")


@app.command()
def check(
    config: Path = typer.Argument(..., metavar="CONFIG", help="Run config or campaign spec (TOML)."),
    json_output: bool = typer.Option(False, "--json", help="Print the result as JSON."),
) -> None:
    """Validate CONFIG and print the mixture table and the settings (one row per mixture for a campaign)."""
    from rich.table import Table
    from rich.text import Text

    from granpack.advice import advise, expected_height
    from granpack.config import load_config
    from granpack.mixture import Mixture

    if _is_campaign_file(config):
        _check_campaign(config, json_output)
        return
    cfg = load_config(config)
    mixture = Mixture.from_config(cfg)
    found = _layout_warnings(_toml_of(config)) + advise(cfg, mixture)
    if json_output:
        _print_json({
            "config": str(config), "valid": True, "n_particles": mixture.n_particles,
            "lateral_size": cfg.lateral_size, "seed": cfg.seed, "alert_distance": cfg.resolved_alert_distance,
            "mixture": mixture.table(), "shapes": mixture.shape_rows(), "resolved": cfg.model_dump(mode="json"),
            "sieve_curves": {cfg.populations[k].name: mixture.sieve_curve(k) for k in range(len(cfg.populations))
                             if cfg.populations[k].grading is not None and mixture.counts[k]},
            "warnings": found,
        })
        return
    table = Table(title=Text(f"{config}: mixture of N = {mixture.n_particles} grains"))
    for heading in ("population", "shape", "size (d)", "aspect L/G, G/E", "count", "requested share",
                    "achieved share", "grain volume (d^3)"):
        table.add_column(heading, justify="left" if heading in ("population", "shape") else "right")
    for row in mixture.table():
        aspect = "" if row["aspect"] is None else "{:g}, {:g}".format(*row["aspect"])
        size = f"{row['size']:.6g}" if row["size"] is not None else f"{row['d_min']:.4g} to {row['d_max']:.4g}"
        table.add_row(row["population"], row["shape"], size, aspect, str(row["count"]),
                      f"{row['requested_share']:.6f}", f"{row['achieved_share']:.6f}", f"{row['particle_volume']:.6g}")
    console = _console()
    console.print(table)
    console.print(_shape_table(mixture))
    for k, population in enumerate(cfg.populations):
        if population.grading is not None and mixture.counts[k]:
            console.print(_sieve_table(mixture, k))
    console.print(f"N = {cfg.n_particles}, lateral size = {cfg.lateral_size:g} d, seed = {cfg.seed}, "
                  f"alert distance = {cfg.resolved_alert_distance:g} d"
                  f"{'' if cfg.time_stepping.alert_distance is not None else ' (automatic)'}", markup=False)
    height, phi = expected_height(cfg, mixture)
    floor = {"periodic": "the cell's", "box": "the box's", "cylinder": "the cylinder's"}[cfg.container.shape]
    console.print(f"expected pile: about {height:.3g} d high (solid fraction {phi:g} assumed over {floor} "
                  f"{cfg.floor_area:.4g} d^2)", markup=False)
    for line in _settings_lines(cfg):
        console.print(line, markup=False)
    for warning in found:
        _note(f"warning: {warning}")


@app.command()
def demo(
    out: Path = typer.Option(Path("granpack-demo"), "--out", help="Output folder."),
    resume: bool = typer.Option(False, "--resume", help="Continue the demo run in OUT from its checkpoint."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the run that OUT holds (analysis, figures, exports too)."),
) -> None:
    """A small complete packing (about 300 isometric pinacoids), poured, settled and analysed."""
    from granpack.io.run_folder import ANALYSIS_FILE, FINAL_FILE, SUMMARY_FILE

    config = demo_config()
    typer.echo(f"granpack demo: {config.n_particles} isometric pinacoids in a {config.lateral_size:g} d x "
               f"{config.lateral_size:g} d periodic cell -> {out}/")
    _run_and_report(config, out, resume=resume, overwrite=overwrite, again=f"granpack demo --out {out}")
    analyze(out, json_output=False)
    typer.echo(f"files: {out / FINAL_FILE} (OVITO), {out / SUMMARY_FILE}, {out / ANALYSIS_FILE}; "
               f"ParaView: granpack export {out} --format vtk; figures: granpack figures {out}")


def demo_config():
    """The packaged demo config (``granpack/data/demo.toml``, a copy of ``examples/demo.toml``)."""
    import tomllib
    from importlib.resources import files

    from granpack.config import load_config_dict

    text = files("granpack").joinpath("data/demo.toml").read_text(encoding="utf-8")
    return load_config_dict(tomllib.loads(text), source="demo.toml")


def _interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is Ctrl-C: a KeyboardInterrupt, or the SystemError that Numba raises when
    one lands inside a compiled function (the KeyboardInterrupt is its cause or context)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _run_interrupted(exc: BaseException, out: Path, again: str) -> _Stop:
    """The one-line message and exit status 130 of a run stopped by Ctrl-C."""
    from granpack.io.run_folder import CHECKPOINT_FILE, checkpoint_when

    if isinstance(exc, RunInterrupted):
        return _Stop(f"interrupted at t = {exc.time:.6g} sqrt(d/g) (step {exc.step}), checkpoint written to "
                     f"{exc.checkpoint}; continue with: {again} --resume", 130)
    checkpoint = out / CHECKPOINT_FILE
    if checkpoint.is_file():
        return _Stop(f"interrupted; the last checkpoint{checkpoint_when(checkpoint)} is kept in {checkpoint}; "
                     f"continue with: {again} --resume", 130)
    return _Stop("interrupted before the first checkpoint: there is nothing for --resume to continue from; "
                 "run the same command again to start over", 130)


def _run_and_report(config, out: Path, *, resume: bool, overwrite: bool, again: str, json_output: bool = False,
                    layout: tuple[str, ...] = (), source: str | None = None) -> dict:
    from granpack.simulation import run_packing

    try:  # run_packing warns as `check` does, before hours of work
        summary = run_packing(config, out, resume=resume, overwrite=overwrite, progress=True, source=source,
                              warnings=layout)
    except (KeyboardInterrupt, SystemError) as exc:
        if not _interrupted(exc):
            raise
        raise _run_interrupted(exc, out, again) from None
    if json_output:
        return summary
    eq = summary["equilibrium"]
    typer.echo(
        f"{summary['status']} after {summary['simulated_time']:.2f} sqrt(d/g) ({summary['steps']} steps, "
        f"{summary['wall_time']:.0f} s); NLGS {summary['nlgs']['mean_iterations']:.0f} sweeps/step; "
        f"max |F|/(d^2 P) {eq['max_net_force']:.1e}, wall force / weight {eq['wall_force_over_weight']:.6f}, "
        f"max overlap {summary['final']['max_overlap']:.1e} d"
    )
    if summary["end_game"].get("rest_recovery_from") is not None:
        typer.echo(f"first at rest at t = {summary['end_game']['rest_recovery_from']:.2f} sqrt(d/g); its overlaps were "
                   f"then pushed back to {config.overlap.rest_recovery_slop:g} d and the criteria checked again")
    failing = [name for key, name in (("force_ok", "net force"), ("torque_ok", "net torque"), ("energy_ok", "kinetic energy"),
                                       ("wall_ok", "wall force")) if not eq.get(key)]
    if failing:
        from granpack.io.run_folder import SUMMARY_FILE

        go_on = f"; to go on, raise its equilibrium.max_time and run: {again} --resume" if source else ""
        typer.echo(f"criteria not met at the end: {', '.join(failing)} (values in {out / SUMMARY_FILE}, 'equilibrium')"
                   + go_on)
    return summary


def _protect_input(config_path: Path, out: Path, resolved_text: str) -> None:
    """Refuse a run whose resolved config would replace the input file itself with other text
    (``granpack run config.toml --out .``)."""
    from granpack.io.run_folder import CONFIG_FILE

    target = out / CONFIG_FILE
    try:
        same = target.exists() and config_path.exists() and target.samefile(config_path)
    except OSError:
        return
    if same and config_path.read_text(encoding="utf-8") != resolved_text:
        raise InputError(f"{config_path}: the run writes its resolved config (every default filled in) to "
                         f"{target}, which would replace this file; choose another --out folder")


@app.command()
def run(
    config: Path = typer.Argument(..., metavar="CONFIG", help="Run config (TOML)."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    resume: bool = typer.Option(False, "--resume", help="Continue the run in OUT from its checkpoint, or from its "
                                "final state if it ended not at rest and CONFIG raises equilibrium.max_time."),
    overwrite: bool = typer.Option(False, "--overwrite",
                                   help="Replace the run that OUT holds (its analysis, figures and exports too)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Override the config's seed."),
    json_output: bool = typer.Option(False, "--json", help="Print the result (files and summary) as JSON."),
) -> None:
    """One packing to equilibrium: writes OUT/config.toml, final.gsd, summary.json (and checkpoints).

    A folder that holds a run is refused unless --resume (continue it; a finished run is left as
    it is, or goes on if it ended not at rest and CONFIG raises equilibrium.max_time; a run may
    change solver.tolerance on the way) or --overwrite (replace it) is given. Ctrl-C stops at the end of the step and writes
    the checkpoint (exit status 130).
    """
    from granpack.config import load_config
    from granpack.io.run_folder import CONFIG_FILE, CONTAINER_FILE, FINAL_FILE, SUMMARY_FILE

    if _is_campaign_file(config):
        raise InputError(f"{config}: a campaign file ([[mixtures]]), not a run config: run it with "
                         f"granpack campaign {config} --out DIR")
    cfg = load_config(config)
    if seed is not None:
        cfg = cfg.with_seed(seed)
    _protect_input(config, out, cfg.to_toml())
    again = f"granpack run {config} --out {out}" + (f" --seed {seed}" if seed is not None else "")
    summary = _run_and_report(cfg, out, resume=resume, overwrite=overwrite, again=again, json_output=json_output,
                              layout=tuple(_layout_warnings(_toml_of(config))),
                              source=f"{config}" + (f" with --seed {seed}" if seed is not None else ""))
    names = (CONFIG_FILE, FINAL_FILE, SUMMARY_FILE, *((CONTAINER_FILE,) if (out / CONTAINER_FILE).is_file() else ()))
    if json_output:
        _print_json({"out": str(out), "files": {name: str(out / name) for name in names}, "summary": summary})
        return
    container = f" (OVITO: add {out / CONTAINER_FILE} to the scene)" if CONTAINER_FILE in names else ""
    typer.echo(f"files: {out / FINAL_FILE}{container}, {out / SUMMARY_FILE}; next: granpack analyze {out}")


@app.command()
def analyze(
    run_dir: Path = typer.Argument(..., metavar="RUN_DIR", help="A run folder holding final.gsd."),
    json_output: bool = typer.Option(False, "--json", help="Print the analysis (analysis.json) as JSON."),
) -> None:
    """Analyse a packing: writes RUN_DIR/analysis.json and prints a table."""
    from rich.table import Table

    from granpack.analysis import AnalysisWarning
    from granpack.analysis.report import analyze_run, summary_rows
    from granpack.io.run_folder import ANALYSIS_FILE

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AnalysisWarning)  # printed below, one line each
        result = analyze_run(run_dir)
    for message in result["warnings"]:
        _note(f"warning: {message}")
    if json_output:
        _print_json({"run_dir": str(run_dir), "file": str(run_dir / ANALYSIS_FILE), "analysis": result})
        return
    table = Table(title=f"{run_dir / ANALYSIS_FILE}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for name, value in summary_rows(result):
        table.add_row(name, value)
    _console().print(table)


@app.command()
def campaign(
    spec: Path = typer.Argument(..., metavar="SPEC", help="Campaign spec (TOML)."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of an existing Dask scheduler."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Workers of the local Dask cluster."),
    mixture: Optional[list[str]] = typer.Option(
        None, "--mixture", metavar="PATTERN", help="Run only the mixtures matching this name or shell pattern, e.g. 'spheres-*' (repeatable; "
        "default all). The tables still list every run."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Recompute the runs that OUT holds for another config "
                                   "of the same mixture and seed (an edited campaign file); refused without it."),
) -> None:
    """A sweep of mixtures x replicas; rerunning skips finished runs and resumes interrupted ones.

    A campaign file whose max_time was raised takes its runs that ended not at rest further and
    keeps those at rest (so may a changed solver.tolerance for unfinished runs); any other edit is
    refused without --overwrite. Writes one run folder per (mixture, replica) in OUT, runs.csv, runs.parquet and summary.csv.
    Exit status 1 when some runs failed (their errors are in runs.csv and their folders), 130
    when interrupted (Ctrl-C; finished runs and checkpoints are kept).
    """
    from granpack.campaign import load_campaign, run_campaign
    from granpack.io.run_folder import RUNS_TABLE, SUMMARY_TABLE

    if _is_run_config(spec):
        raise InputError(f"{spec}: a run config ([[populations]]), not a campaign file: run it with "
                         f"granpack run {spec} --out DIR")
    loaded = load_campaign(spec)
    try:
        report = run_campaign(loaded, out, scheduler=scheduler, workers=workers, mixtures=mixture or None,
                              overwrite=overwrite)
    except (KeyboardInterrupt, SystemError) as exc:
        if not _interrupted(exc):
            raise
        again = "".join(f" --mixture '{m}'" for m in mixture or [])
        raise _Stop(f"interrupted; finished runs and the checkpoints of unfinished ones are kept in {out}: continue "
                    f"with: granpack campaign {spec} --out {out}{again} (each unfinished run resumes from its checkpoint, "
                    "as with run --resume)", 130) from None
    chosen = f" of mixtures {', '.join(mixture)}" if mixture else ""
    typer.echo(
        f"{report.n_runs} runs{chosen}: {report.n_done} done ({report.n_skipped} already finished; "
        f"{report.n_at_rest} at rest, {report.n_done - report.n_at_rest} stopped at the time cap), "
        f"{report.n_failed} failed; tables in {out / RUNS_TABLE} and {out / SUMMARY_TABLE}"
    )
    if report.n_failed:
        raise _Stop(f"error: {report.n_failed} run(s) failed; see the 'error' column of {out / RUNS_TABLE}", 1)


@app.command()
def figures(
    run_dir: Path = typer.Argument(..., metavar="RUN_DIR", help="A run or campaign folder."),
    mixture: Optional[list[str]] = typer.Option(
        None, "--mixture", metavar="NAME", help="Campaign: a mixture to show in the g(r) and homogeneity figures (repeatable; default all)."
    ),
) -> None:
    """PNG/SVG figures for a run or a campaign, written into RUN_DIR/figures/; says which it skipped and why."""
    from granpack.campaign.figures import make_figures

    paths = make_figures(run_dir, mixtures=mixture or None)
    if paths:
        typer.echo(f"{len(paths)} files in {run_dir / 'figures'}: {', '.join(sorted({p.stem for p in paths}))}")
    else:
        typer.echo(f"no figure written in {run_dir / 'figures'}")
    for stem, why in getattr(paths, "skipped", {}).items():
        _note(f"skipped {stem}: {why}")


@app.command()
def export(
    run_dir: Path = typer.Argument(..., help="A run folder."),
    format: str = typer.Option("vtk", "--format", help="vtk, png, or grain surfaces: stl, obj, ply."),
    images: bool = typer.Option(False, "--images", help="stl, obj, ply: also the periodic images of the grains crossing the cell's sides."),
) -> None:
    """Files for ParaView (vtk: RUN_DIR/vtk/*.vtu), a rendered picture (png: RUN_DIR/packing.png), or every
    grain as a closed triangulated surface, grain ids kept (stl, obj, ply: RUN_DIR/surfaces/grains.FORMAT)."""
    from granpack.mesh.surfaces import FORMATS as SURFACE_FORMATS

    formats = ("vtk", "png", *SURFACE_FORMATS)
    if format not in formats:
        raise InputError(f"--format must be one of {', '.join(formats)} (got {format!r})")
    if images and format not in SURFACE_FORMATS:
        raise InputError(f"--images goes with --format {', '.join(SURFACE_FORMATS)} (got --format {format})")
    from granpack.io.gsd import read_packing
    from granpack.io.run_folder import FINAL_FILE, PICTURE_FILE

    packing = read_packing(run_dir / FINAL_FILE)
    if format in SURFACE_FORMATS:
        from granpack.io.atomic import output_folder
        from granpack.mesh.surfaces import write_surfaces

        output_folder(run_dir / "surfaces", "RUN_DIR")
        path, count = write_surfaces(packing, run_dir / "surfaces" / f"grains.{format}", format, images=images)
        typer.echo(f"wrote {path} ({count} closed surfaces: {packing.state.n} grains"
                   f"{f', {count - packing.state.n} periodic images' if images else ''})")
        return
    if format == "vtk":
        from granpack.io.vtk import write_vtk

        paths = write_vtk(packing, run_dir / "vtk")
    else:
        from granpack.figures import render_packing, save_figure

        paths = save_figure(render_packing(packing), run_dir, Path(PICTURE_FILE).stem, formats=("png",))
    typer.echo("wrote " + ", ".join(str(p) for p in paths))


@app.command()
def mesh(
    run_dir: Path = typer.Argument(..., metavar="RUN_DIR", help="A run folder (its final.gsd)."),
    out: Path = typer.Option(..., "--out", metavar="FILE", help="The mesh: .msh (gmsh), .inp (Abaqus), .xdmf or .vtu; its report goes to FILE.json."),
    box: Optional[tuple[float, float, float, float, float, float]] = typer.Option(
        None, "--box", metavar="X0 Y0 Z0 X1 Y1 Z1", help="The region (d); default: the cell's full width over the bulk's height."),
    size: Optional[float] = typer.Option(None, "--size", metavar="H", help="Largest element size (d); default: --size-factor times the smallest grain."),
    size_factor: float = typer.Option(0.2, "--size-factor", metavar="F", help="Largest element size relative to the smallest grain's size."),
    curvature: int = typer.Option(60, "--curvature", metavar="N", help="Elements per turn on spheres (60: a sphere's volume within 0.5 %)."),
    gap: Optional[float] = typer.Option(None, "--gap", metavar="G", help="Clearance the shrink opens between touching grains (d); default 0.02 times the smallest grain."),
    itz: float = typer.Option(0.0, "--itz", metavar="T", help="Thickness of an ITZ shell around every grain (d; 0: none)."),
    periodic: bool = typer.Option(False, "--periodic", help="Matching nodes on the opposite x and y faces (the cell's full width)."),
    grain_groups: bool = typer.Option(False, "--grain-groups", help="One group grain_<i> per grain besides aggregate, matrix, itz."),
    threads: int = typer.Option(0, "--threads", metavar="N", help="gmsh threads (0: gmsh's default)."),
) -> None:
    """A conforming tetrahedral mesh of the grains (shrunk apart by --gap) and the matrix in a box, for finite elements (needs the mesh extra: gmsh)."""
    from granpack.io.atomic import output_folder
    from granpack.io.gsd import read_packing
    from granpack.io.run_folder import FINAL_FILE
    from granpack.mesh.region import MeshOptions
    from granpack.mesh.volume import MEAN_GAMMA, TOLERANCE, check_suffix, require_gmsh, write_mesh

    check_suffix(out)
    require_gmsh()
    options = MeshOptions(box=box, gap=gap, size=size, size_factor=size_factor, curvature=curvature, itz=itz,
                          periodic=periodic, grain_groups=grain_groups, threads=threads)
    packing = read_packing(run_dir / FINAL_FILE)
    output_folder(out.parent, "--out")
    paths, report = write_mesh(out, packing, options)
    fraction = report["aggregate_fraction"]
    exact = f" (exact {fraction['exact']:.4f})" if fraction["exact"] is not None else ""
    typer.echo(f"wrote {', '.join(str(p) for p in paths)}: {report['nodes']} nodes, {report['elements']['tetra']} tetrahedra; "
               f"aggregate fraction {fraction['meshed']:.4f}{exact} after a {report['shrink']['gap']:.3g} d gap; "
               f"quality min {report['quality']['min_gamma']:.3f}, mean {report['quality']['mean_gamma']:.3f}")
    failed = [name for name, ok in report["checks"].items() if ok is False]
    if failed:
        _note(f"checks not met: {', '.join(failed)} (volumes within {100 * TOLERANCE:g} %, mean quality at least "
              f"{MEAN_GAMMA:g}; values in {out.with_suffix('.json')})")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _usage_line(exc) -> str:
    """``error: granpack run: Missing option '--out'. (see granpack run --help)``."""
    ctx = getattr(exc, "ctx", None)
    where = ctx.command_path if ctx is not None and getattr(ctx, "command_path", None) else "granpack"
    message = _one_line(exc.format_message())
    if isinstance(exc, _CLICK.exceptions.UsageError):
        return f"error: {where}: {message} (see {where} --help)"
    return f"error: {where}: {message}"


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings as one line on stderr, without the source path and line."""
    from granpack.analysis import AnalysisWarning

    text = _one_line(message)
    if not issubclass(category, AnalysisWarning):
        text = f"{category.__name__}: {text}"
    print(f"warning: {text}", file=sys.stderr if file is None else file)


def _commands() -> str:
    return ", ".join(getattr(typer.main.get_command(app), "commands", {}))


@contextlib.contextmanager
def _sigterm_taken_as_ctrl_c():
    """While the command runs, SIGTERM goes to :func:`~granpack.interrupt.sigterm_as_ctrl_c` (only over the default
    action, which would end the process at once: a half-written step lost since the last
    checkpoint, a campaign's tables not written)."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return
    from granpack.interrupt import sigterm_as_ctrl_c

    previous = signal.signal(signal.SIGTERM, sigterm_as_ctrl_c)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _main(args: list[str]) -> int:
    """Run the command of ``args``; return the exit status (messages already printed)."""
    if not args:
        print(f"error: no command given (one of {_commands()}); see granpack --help", file=sys.stderr)
        return 2
    command = typer.main.get_command(app)
    shown = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        with _sigterm_taken_as_ctrl_c():
            code = command.main(args=args, prog_name="granpack", standalone_mode=False)
    except _Stop as exc:
        print(exc.message, file=sys.stderr)
        return exc.code
    except (InputError, ShapeError) as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except _CLICK_EXCEPTION as exc:  # usage errors (exit 2) and click's own (file errors, exit 1)
        print(_usage_line(exc), file=sys.stderr)
        return exc.exit_code
    except _ABORT as exc:
        if _interrupted(exc):
            print("interrupted", file=sys.stderr)
            return 130
        print("error: aborted", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, SystemError) as exc:
        if not _interrupted(exc):
            raise
        print("interrupted", file=sys.stderr)
        return 130
    except OSError as exc:  # the system refused a file (permissions, disk full, ...): not a bug
        name = f" {exc.filename}" if exc.filename else ""
        print(f"error:{name}: {exc.strerror or _one_line(exc)}", file=sys.stderr)
        return 1
    finally:
        warnings.showwarning = shown
    if code == 130:  # typer turns a KeyboardInterrupt in a command into exit status 130, silently
        print("interrupted", file=sys.stderr)
    return code if isinstance(code, int) else 0


def main(argv: list[str] | None = None) -> NoReturn:
    """Entry point: run the command; exit with its status (0, 1, 2 or 130, module docstring).

    Where the parallel kernels ran on oneTBB (``NUMBA_THREADING_LAYER=tbb`` in the environment),
    the process ends without Python's finalisation, once its output is flushed: TBB's finalizer
    spins for good once Numba code has run in a thread other than the main one (the narrow
    phase's), and every file of the command is written and closed by then.
    """
    code = _main(sys.argv[1:] if argv is None else list(argv))
    if "granpack._numba" in sys.modules and sys.modules["granpack._numba"].threading_layer() == "tbb":
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    raise SystemExit(code)

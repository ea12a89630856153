"""The ``granpack`` command.

Every command turns bad input (:class:`~granpack.errors.InputError`,
:class:`~granpack.shapes.ShapeError`) into a one-line ``error: ...`` on stderr and exit status 2.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from granpack.errors import InputError
from granpack.shapes import ShapeError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Dense random packings of rigid grains (NSCD).")


@app.command()
def check(config: Path = typer.Argument(..., help="Run config (TOML).")) -> None:
    """Validate CONFIG and print the mixture table."""
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    from granpack.config import load_config
    from granpack.mixture import Mixture

    cfg = load_config(config)
    mixture = Mixture.from_config(cfg)
    table = Table(title=Text(f"{config}: mixture of N = {mixture.n_particles} grains"))
    for heading in ("population", "shape", "size (d)", "aspect L/G, G/E", "count", "requested share",
                    "achieved share", "grain volume (d^3)"):
        table.add_column(heading, justify="left" if heading in ("population", "shape") else "right")
    for row in mixture.table():
        aspect = "" if row["aspect"] is None else "{:g}, {:g}".format(*row["aspect"])
        table.add_row(row["population"], row["shape"], f"{row['size']:.6g}", aspect, str(row["count"]),
                      f"{row['requested_share']:.6f}", f"{row['achieved_share']:.6f}", f"{row['particle_volume']:.6g}")
    solver, eq = cfg.solver, cfg.equilibrium
    console = Console()
    console.print(table)
    console.print(f"N = {cfg.n_particles}, lateral size = {cfg.lateral_size:g} d, seed = {cfg.seed}, "
                  f"alert distance = {cfg.resolved_alert_distance:g} d"
                  f"{'' if solver.alert_distance is not None else ' (automatic)'}", markup=False)
    console.print(f"solver: time step {solver.time_step:g} sqrt(d/g), friction {solver.friction:g}, restitution "
                  f"{solver.restitution:g}, tolerance {solver.tolerance:g} ({solver.settling_tolerance:g} far from rest), max "
                  f"iterations {solver.max_iterations}, theta {solver.theta:g}, check every {solver.check_every} sweeps, "
                  f"overlap slop {solver.overlap_slop:g} d ({solver.pour_overlap_slop:g} while grains move fast)", markup=False)
    console.print(f"equilibrium: max time {eq.max_time:g} sqrt(d/g); deposit: {cfg.deposit.method}, "
                  f"{cfg.deposit.lateral} lateral boundaries", markup=False)


@app.command()
def demo(out: Path = typer.Option(Path("granpack-demo"), "--out", help="Output folder.")) -> None:
    """A small complete packing (about 300 isometric pinacoids), poured, settled and analysed."""
    config = demo_config()
    typer.echo(f"granpack demo: {config.n_particles} isometric pinacoids in a {config.lateral_size:g} d x "
               f"{config.lateral_size:g} d periodic cell -> {out}/")
    _run_and_report(config, out, resume=False)
    analyze(out)
    typer.echo(f"files: {out / 'final.gsd'} (OVITO), {out / 'summary.json'}, {out / 'analysis.json'}; "
               f"ParaView: granpack export {out} --format vtk; figures: granpack figures {out}")


def demo_config():
    """The packaged demo config (``granpack/data/demo.toml``, a copy of ``examples/demo.toml``)."""
    import tomllib
    from importlib.resources import files

    from granpack.config import load_config_dict

    text = files("granpack").joinpath("data/demo.toml").read_text(encoding="utf-8")
    return load_config_dict(tomllib.loads(text), source="demo.toml")


def _run_and_report(config, out: Path, resume: bool) -> dict:
    from granpack.simulation import run_packing

    summary = run_packing(config, out, resume=resume, progress=sys.stderr.isatty())
    eq = summary["equilibrium"]
    typer.echo(
        f"{summary['status']} after {summary['simulated_time']:.2f} sqrt(d/g) ({summary['steps']} steps, "
        f"{summary['wall_time']:.0f} s); NLGS {summary['nlgs']['mean_iterations']:.0f} sweeps/step; "
        f"max |F|/(d^2 P) {eq['max_net_force']:.1e}, wall force / weight {eq['wall_force_over_weight']:.6f}, "
        f"max overlap {summary['final']['max_overlap']:.1e} d"
    )
    failing = [name for key, name in (("force_ok", "net force"), ("torque_ok", "net torque"), ("energy_ok", "kinetic energy"),
                                       ("wall_ok", "wall force")) if not eq.get(key)]
    if failing:
        typer.echo(f"criteria not met at the end: {', '.join(failing)} (values in {out / 'summary.json'}, 'equilibrium')")
    return summary


@app.command()
def run(
    config: Path = typer.Argument(..., help="Run config (TOML)."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    resume: bool = typer.Option(False, "--resume", help="Continue from the last checkpoint."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Override the config's seed."),
) -> None:
    """One packing to equilibrium: writes OUT/config.toml, final.gsd, summary.json (and checkpoints)."""
    from granpack.config import load_config

    cfg = load_config(config)
    if seed is not None:
        cfg = cfg.with_seed(seed)
    _run_and_report(cfg, out, resume=resume)
    typer.echo(f"files: {out / 'final.gsd'}, {out / 'summary.json'}; next: granpack analyze {out}")


@app.command()
def analyze(run_dir: Path = typer.Argument(..., help="A run folder holding final.gsd.")) -> None:
    """Analyse a packing: writes RUN_DIR/analysis.json and prints a table."""
    from rich.console import Console
    from rich.table import Table

    from granpack.analysis.report import analyze_run, summary_rows

    result = analyze_run(run_dir)
    table = Table(title=f"{run_dir / 'analysis.json'}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for name, value in summary_rows(result):
        table.add_row(name, value)
    Console().print(table)


@app.command()
def campaign(
    spec: Path = typer.Argument(..., help="Campaign spec (TOML)."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Address of an existing Dask scheduler."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Workers of the local Dask cluster."),
) -> None:
    """A sweep of mixtures x replicas; rerunning skips finished runs.

    Writes one run folder per (mixture, replica) in OUT, runs.csv, runs.parquet and summary.csv.
    Exit status 1 when some runs failed (their errors are in runs.csv and their folders).
    """
    from granpack.campaign import load_campaign, run_campaign

    report = run_campaign(load_campaign(spec), out, scheduler=scheduler, workers=workers)
    typer.echo(
        f"{report.n_runs} runs: {report.n_done} done ({report.n_skipped} already finished), "
        f"{report.n_failed} failed; tables in {out / 'runs.csv'} and {out / 'summary.csv'}"
    )
    if report.n_failed:
        typer.echo(f"error: {report.n_failed} run(s) failed; see the 'error' column of {out / 'runs.csv'}", err=True)
        raise typer.Exit(1)


@app.command()
def figures(
    run_dir: Path = typer.Argument(..., help="A run or campaign folder."),
    mixture: Optional[list[str]] = typer.Option(
        None, "--mixture", help="Campaign: a mixture to show in the g(r) and homogeneity figures (repeatable; default all)."
    ),
) -> None:
    """PNG/SVG figures for a run or a campaign, written into RUN_DIR/figures/."""
    from granpack.figures import make_figures

    paths = make_figures(run_dir, mixtures=mixture or None)
    typer.echo(f"{len(paths)} files in {run_dir / 'figures'}: {', '.join(sorted({p.stem for p in paths}))}")


@app.command()
def export(
    run_dir: Path = typer.Argument(..., help="A run folder."),
    format: str = typer.Option("vtk", "--format", help="vtk or png."),
) -> None:
    """Files for ParaView (vtk: RUN_DIR/vtk/*.vtu) or a rendered picture (png: RUN_DIR/packing.png)."""
    formats = ("vtk", "png")
    if format not in formats:
        raise InputError(f"--format must be one of {', '.join(formats)} (got {format!r})")
    from granpack.io.gsd import read_packing

    packing = read_packing(run_dir / "final.gsd")
    if format == "vtk":
        from granpack.io.vtk import write_vtk

        paths = write_vtk(packing, run_dir / "vtk")
    else:
        from granpack.figures import render_packing, save_figure

        paths = save_figure(render_packing(packing), run_dir, "packing", formats=("png",))
    typer.echo("wrote " + ", ".join(str(p) for p in paths))


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the typer app, mapping input errors to exit status 2."""
    try:
        app(args=argv, standalone_mode=False)
    except (InputError, ShapeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    except typer.Exit as exc:  # --help and friends
        raise SystemExit(exc.exit_code) from None
    except Exception as exc:  # click usage errors (bad option) also exit 2
        import click

        if isinstance(exc, click.exceptions.ClickException):
            exc.show()
            raise SystemExit(exc.exit_code) from None
        if isinstance(exc, click.exceptions.Abort):
            raise SystemExit(130) from None
        raise
    raise SystemExit(0)

"""The ``granpack`` command: ``check`` on good and bad configs; usage errors, exit statuses and Ctrl-C;
what ``run`` does with a folder that holds work; output for scripts and logs (``--json``, whole
tables, progress lines, one-line warnings)."""

from __future__ import annotations

import contextlib
import json
import re
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from granpack.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

GOOD = """\
seed = 3
n_particles = 3000
lateral_size = 8.0

[[populations]]
shape = "pinacoid"
size = 1.0
aspect = [1.0, 1.0]
volume_fraction = 0.7

[[populations]]
shape = "pinacoid"
size = 0.3333333333
aspect = [1.0, 1.0]
volume_fraction = 0.3

[time_stepping]
time_step = 2e-3

[solver]
tolerance = 1e-4
"""


def good_with(old: str, new: str) -> str:
    assert old in GOOD
    return GOOD.replace(old, new, 1)


COPLANAR = '''
[[populations]]
shape = "polyhedron"
size = 1.0
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
volume_fraction = 1.0
'''
NON_CONVEX = '''
[[populations]]
shape = "polyhedron"
size = 1.0
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.2, 0.2]]
volume_fraction = 1.0
'''

BAD = {
    "not-toml": ("seed = = 1\n", "not valid TOML"),
    "unknown-key": (good_with("seed = 3", "seed = 3\ncolour = 1"), "colour: unknown key"),
    "unknown-solver-key": (good_with("tolerance = 1e-4", "dt = 2e-3"), "solver.dt: unknown key"),
    "unknown-shape": (good_with('shape = "pinacoid"', 'shape = "cube"'), "populations[0].shape: must be"),
    "size-zero": (good_with("size = 1.0", "size = 0.0"), "populations[0].size: must be > 0"),
    "size-negative": (good_with("size = 0.3333333333", "size = -1"), "populations[1].size: must be > 0 (got -1)"),
    "aspect-below-1": (good_with("aspect = [1.0, 1.0]", "aspect = [0.5, 1.0]"), "populations[0].aspect:"),
    "shares-not-1": (good_with("volume_fraction = 0.3", "volume_fraction = 0.2"), "populations: volume_fraction values must sum to 1"),
    "share-negative": (good_with("volume_fraction = 0.3", "volume_fraction = -0.3"), "populations[1].volume_fraction: must be >= 0"),
    "n-zero": (good_with("n_particles = 3000", "n_particles = 0"), "n_particles: must be >= 1"),
    "lateral-too-small": (good_with("lateral_size = 8.0", "lateral_size = 2.0"), "lateral_size: must exceed 2 x (largest grain size"),
    "coplanar-vertices": (COPLANAR, "populations[0].vertices: vertices are coplanar"),
    "non-convex-vertices": (NON_CONVEX, "populations[0].vertices: vertex 4"),
    "time-step-zero": (good_with("time_step = 2e-3", "time_step = 0.0"), "time_stepping.time_step: must be > 0"),
    "friction-negative": (good_with("tolerance = 1e-4", "friction = -0.2"), "solver.friction: must be >= 0"),
    "restitution-above-1": (good_with("tolerance = 1e-4", "restitution = 1.2"), "solver.restitution: must be <= 1"),
    "restitution-negative": (good_with("tolerance = 1e-4", "restitution = -0.1"), "solver.restitution: must be >= 0"),
    "container-shape": (GOOD + '\n[container]\nshape = "sphere"\n',
                        "container.shape: must be 'periodic', 'box' or 'cylinder' (got 'sphere')"),
    "cylinder-too-narrow": (good_with("lateral_size = 8.0", "lateral_size = 2.0") + '\n[container]\nshape = "cylinder"\n',
                            "the cylinder holds two of the largest grains side by side"),
    "box-too-narrow": (good_with("lateral_size = 8.0", "lateral_size = 2.0") + '\n[container]\nshape = "box"\n',
                       "the box holds two grains side by side"),
}


def run_main(argv, capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    return info.value.code, out, err


def test_check_and_run_name_the_new_keys_of_a_file_in_the_flat_solver_layout_of_0_1_0(tmp_path, capsys):
    path = tmp_path / "old.toml"
    path.write_text(GOOD.replace("[time_stepping]\ntime_step = 2e-3\n\n[solver]\n",
                                 "[solver]\ntime_step = 2e-3\noverlap_slop = 1e-3\n"))
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and "time_stepping: time_step 0.002 sqrt(d/g)" in out and "projection_slop 0.001 d" in out
    warning = next(line for line in err.splitlines() if "granpack 0.1.0" in line)
    assert "solver.time_step -> time_stepping.time_step" in warning
    assert "solver.overlap_slop -> overlap.projection_slop" in warning
    path.write_text(GOOD.replace("[time_stepping]\ntime_step = 2e-3\n\n[solver]\n", "[solver]\ntime_step = 2e-3\n")
                    + "\n[time_stepping]\ntime_step = 1e-3\n")
    code, _, err = run_main(["check", str(path)], capsys)
    assert code == 2 and "solver.time_step: the same setting as time_stepping.time_step" in _one_error_line(err)


def test_check_prints_mixture_table(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "160")  # rich folds wide tables on a narrow console
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0
    # 3000 grains, 70 % of the volume in 239 unit pinacoids: 1.1 d high over 8 d x 8 d at a solid
    # fraction of 0.72 (a mix of sizes), 1.3 d at 0.6
    assert err.startswith("warning: the settled pile will stand about 1.1 d high (solid fraction about 0.72")
    assert err.count("\n") == 1
    for text in ("pinacoid-1-1x1", "pinacoid-0.333333-1x1", "239", "2761", "0.700000", "0.700347", "0.299653",
                 "N = 3000", "lateral size = 8 d", "time_stepping: time_step 0.002 sqrt(d/g)",
                 "alert distance = 0.02 d (automatic)", "force_tolerance 0.0001 d_p^2 P",
                 "kinetic_tolerance 1e-08 d^3 P", "window 5 checks", "overlap: recovery_slop 0.0005 d",
                 "end_game: mode damping", "threads: parallel_points 2000 points"):
        assert text in out, text


@pytest.mark.parametrize("name", sorted(BAD))
def test_check_bad_input_exits_2_with_one_line(name, tmp_path, capsys):
    text, expected = BAD[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"error: {path}: "), err
    assert expected in err, err


def test_check_missing_file(tmp_path, capsys):
    path = tmp_path / "absent.toml"
    code, out, err = run_main(["check", str(path)], capsys)
    assert (code, out, err) == (2, "", f"error: {path}: no such file\n")


def test_python_dash_m_granpack(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(BAD["size-negative"][0])
    bad = subprocess.run([sys.executable, "-m", "granpack", "check", str(path)], capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr == f"error: {path}: populations[1].size: must be > 0 (got -1)\n"
    good = subprocess.run([sys.executable, "-m", "granpack", "check", str(EXAMPLES / "demo.toml")],
                          capture_output=True, text=True)
    assert good.returncode == 0 and good.stderr == ""
    assert "N = 300" in good.stdout and "lateral size = 3 d" in good.stdout


# ----------------------------------------------------------------------------- usage errors, exit statuses


def _one_error_line(err: str) -> str:
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("error: "), err
    return err


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["runn"], "No such command 'runn'"),
        (["run", "c.toml"], "Missing option '--out'"),
        (["run"], "Missing argument 'CONFIG'"),
        (["run", "c.toml", "--out", "o", "--seed", "abc"], "'--seed'"),
        (["run", "c.toml", "--out", "o", "--colour", "1"], "No such option: --colour"),
        (["campaign", "s.toml", "--out", "o", "--workers", "abc"], "'--workers'"),
        (["check"], "Missing argument 'CONFIG'"),
        (["analyze", "a", "b"], "unexpected extra argument"),
        (["export", "d", "--format", "dxf"], "--format must be one of vtk, png, stl, obj, ply"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(argv, expected, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_main(argv, capsys)
    assert code == 2 and out == ""
    assert expected.lower() in _one_error_line(err).lower()
    assert not (tmp_path / "o").exists()


def test_no_command_version_and_help_from_the_installed_entry_point():
    granpack = [sys.executable, "-m", "granpack"]
    bare = subprocess.run(granpack, capture_output=True, text=True)
    assert bare.returncode == 2 and bare.stdout == ""
    assert "no command given" in _one_error_line(bare.stderr) and "run" in bare.stderr
    version = subprocess.run(granpack + ["--version"], capture_output=True, text=True)
    from granpack import __version__

    assert (version.returncode, version.stderr) == (0, "")
    assert version.stdout.startswith(f"granpack {__version__} (Numba ") and "threading layer" in version.stdout
    usage = subprocess.run(granpack + ["runn"], capture_output=True, text=True)
    assert usage.returncode == 2 and "No such command 'runn'" in _one_error_line(usage.stderr)
    helped = subprocess.run(granpack + ["run", "--help"], capture_output=True, text=True)
    assert helped.returncode == 0 and "--overwrite" in helped.stdout and "--resume" in helped.stdout


@pytest.mark.parametrize("command", ["run", "campaign", "check"])
def test_help_shows_flags_without_a_value_and_wraps_each_paragraph_as_one_text(command, capsys, monkeypatch):
    """``--resume`` takes no value, so its help shows none (``<bool>`` suggested ``--resume true``);
    a paragraph of a command's help is wrapped to the terminal as one text, not cut again at the
    line ends of its docstring."""
    import typer.main

    from granpack.cli import app

    width = 60
    monkeypatch.setenv("COLUMNS", str(width))
    code, out, err = run_main([command, "--help"], capsys)
    assert (code, err) == (0, "")
    lines = out.splitlines()
    options = typer.main.get_command(app).commands[command].params
    flags = [param.opts[0] for param in options if getattr(param, "is_flag", False)] + ["--help"]
    for flag in flags:
        row = next(line.split() for line in lines if line.split()[:1] == [flag])
        assert not row[1].startswith("<"), row  # e.g. "--resume <bool>"
    assert "<bool>" not in out and "list[" not in out
    paragraphs, current = [], []
    for line in lines[1:]:
        if line.startswith("  ") and not line.startswith("   ") and not line.strip().endswith(":"):
            current.append(line.strip())
        elif current:
            paragraphs.append(current)
            current = []
        if line.endswith(":") and not line.startswith(" "):  # "Arguments:", "Options:"
            break
    assert paragraphs
    for paragraph in paragraphs:  # every line but the last is full: the next word would not fit
        for line, following in zip(paragraph, paragraph[1:]):
            assert 2 + len(line) + 1 + len(following.split()[0]) > width - 2, (line, following)


@pytest.mark.parametrize("command, example, kind, other", [
    ("run", "study-small.toml", "a campaign file", "granpack campaign"),
    ("campaign", "demo.toml", "a run config", "granpack run"),
])
def test_a_file_of_the_other_command_is_named_with_its_command(command, example, kind, other, tmp_path, capsys):
    """A campaign file given to `run` (or a run config to `campaign`) says what it is and which
    command takes it, instead of the key the other format misses."""
    path = EXAMPLES / example
    code, out, err = run_main([command, str(path), "--out", str(tmp_path / "o")], capsys)
    line = _one_error_line(err)
    assert code == 2 and out == ""
    assert line.startswith(f"error: {path}: {kind}") and f"{other} {path} --out DIR" in line, line
    assert not (tmp_path / "o").exists()


def test_usage_errors_are_caught_as_the_installed_typer_raises_them():
    """The handler catches the exception classes of the click that typer really uses (typer >= 0.20
    ships its own copy: catching the click package's classes never matched)."""
    import typer.main

    import granpack.cli as cli

    command = typer.main.get_command(cli.app)
    with pytest.raises(cli._CLICK_EXCEPTION) as info:
        command.main(args=["runn"], prog_name="granpack", standalone_mode=False)
    assert info.value.exit_code == 2


def test_a_failed_campaign_exits_1(tmp_path, capsys, monkeypatch):
    import granpack.campaign as campaign
    from granpack.campaign.runner import CampaignReport

    spec = tmp_path / "c.toml"
    spec.write_text(_TINY_CAMPAIGN)
    report = CampaignReport(n_runs=2, n_skipped=0, n_done=1, n_failed=1, n_at_rest=1, runs=None, summary=None)
    monkeypatch.setattr(campaign, "run_campaign", lambda *a, **k: report)
    code, out, err = run_main(["campaign", str(spec), "--out", str(tmp_path / "out")], capsys)
    assert code == 1 and "1 failed" in out
    assert "1 run(s) failed" in _one_error_line(err)


def test_campaign_out_is_a_file_exits_2(tmp_path, capsys):
    spec = tmp_path / "c.toml"
    spec.write_text(_TINY_CAMPAIGN)
    target = tmp_path / "results.csv"
    target.write_text("mine")
    code, out, err = run_main(["campaign", str(spec), "--out", str(target)], capsys)
    assert code == 2 and "is a file, not a folder" in _one_error_line(err)
    assert target.read_text() == "mine"


def test_an_interrupted_campaign_exits_130_with_one_line(tmp_path, capsys, monkeypatch):
    import granpack.campaign as campaign

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    spec = tmp_path / "c.toml"
    spec.write_text(_TINY_CAMPAIGN)
    monkeypatch.setattr(campaign, "run_campaign", interrupted)
    code, out, err = run_main(["campaign", str(spec), "--out", str(tmp_path / "out")], capsys)
    assert code == 130 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("interrupted") and "resume" in err


_TINY_CAMPAIGN = """\
replicas = 1
[base]
n_particles = 20
lateral_size = 3.0
[base.equilibrium]
max_time = 0.5
[[mixtures]]
name = "mono"
[[mixtures.populations]]
shape = "sphere"
size = 1.0
volume_fraction = 1.0
"""

# ----------------------------------------------------------------------------- runs: tiny configs

TINY_RUN = """\
seed = 3
n_particles = 20
lateral_size = 3.0

[[populations]]
shape = "sphere"
size = 1.0
volume_fraction = 1.0

[equilibrium]
max_time = 1.0

[output]
checkpoint_interval = 0.5
"""


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished tiny run (20 spheres, 1 sqrt(d/g)) made by `granpack run`, umask 022."""
    root = tmp_path_factory.mktemp("finished")
    config = root / "tiny.toml"
    config.write_text(TINY_RUN)
    saved = os.umask(0o022)
    try:
        done = subprocess.run([sys.executable, "-m", "granpack", "run", str(config), "--out", str(root / "run")],
                              capture_output=True, text=True)
    finally:
        os.umask(saved)
    assert done.returncode == 0, done.stderr
    return config, root / "run", done


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_run_outputs_are_readable_by_others_and_piped_progress_is_lines(finished):
    _, out, done = finished
    for name in ("config.toml", "final.gsd", "summary.json"):
        assert stat.S_IMODE((out / name).stat().st_mode) == 0o644, name
    # stderr was a pipe: progress lines (no bar, no terminal control codes)
    assert "\x1b[" not in done.stderr and "━" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if not line.startswith("warning: ")]  # the tiny pile's
    assert lines[0].startswith("pouring 20 grains") and lines[1].startswith("poured in")
    settling = [line for line in lines if line.startswith("settling t = ")]
    assert settling and "kinetic energy" in settling[0] and "largest net force" in settling[0]
    assert "contacts" in settling[0] and "largest overlap" in settling[0] and "criteria met" in settling[0]
    assert done.stdout.startswith("not at rest after 1.00 sqrt(d/g)")


def test_summary_names_the_total_kinetic_energy(finished):
    _, out, _ = finished
    summary = json.loads((out / "summary.json").read_text())
    assert "total_kinetic_energy" in summary["final"] and "kinetic_energy" not in summary["final"]
    assert "kinetic_energy" in summary["equilibrium"]  # the per-grain criterion


@pytest.mark.parametrize("extra", [[], ["--seed", "4"]])
def test_run_into_a_finished_run_exits_2_naming_resume_and_overwrite(finished, capsys, extra):
    config, out, _ = finished
    before = _snapshot(out)
    code, stdout, err = run_main(["run", str(config), "--out", str(out), *extra], capsys)
    assert code == 2 and stdout == ""
    assert "finished run" in _one_error_line(err) and "--resume" in err and "--overwrite" in err
    assert _snapshot(out) == before


def test_resume_of_a_finished_run_leaves_it(finished, capsys):
    config, out, _ = finished
    before = _snapshot(out)
    code, stdout, err = run_main(["run", str(config), "--out", str(out), "--resume"], capsys)
    assert code == 0 and "nothing to resume" in err and "not at rest after 1.00" in stdout, err
    assert _snapshot(out) == before


def test_resume_of_a_finished_run_of_other_settings_names_them(finished, tmp_path, capsys):
    config, out, _ = finished
    other = tmp_path / "longer.toml"
    other.write_text(TINY_RUN.replace("max_time = 1.0", "max_time = 2.0").replace("seed = 3", "seed = 4"))
    before = _snapshot(out)
    code, _, err = run_main(["run", str(other), "--out", str(out), "--resume"], capsys)
    line = _one_error_line(err)
    assert code == 2 and "holds a finished run of another config" in line
    assert f"seed = 3 in {out / 'config.toml'}, 4 in {other}" in line
    assert f"equilibrium.max_time = 1.0 in {out / 'config.toml'}, 2.0 in {other}" in line
    assert _snapshot(out) == before


def test_resume_with_a_later_cap_takes_a_run_that_ended_not_at_rest_further(finished, tmp_path, capsys):
    _, out, _ = finished
    copy = tmp_path / "run"
    shutil.copytree(out, copy)
    longer = tmp_path / "longer.toml"
    longer.write_text(TINY_RUN.replace("max_time = 1.0", "max_time = 1.5"))
    code, stdout, err = run_main(["run", str(longer), "--out", str(copy), "--resume"], capsys)
    assert code == 0 and "going on from its final state" in err and "max_time = 1.5 (was 1)" in err, err
    assert stdout.startswith("not at rest after 1.50 sqrt(d/g)"), stdout


def test_resume_and_overwrite_exclude_each_other(finished, capsys):
    config, out, _ = finished
    code, _, err = run_main(["run", str(config), "--out", str(out), "--resume", "--overwrite"], capsys)
    assert code == 2 and "exclude each other" in _one_error_line(err)


def test_run_out_is_a_file_exits_2(finished, tmp_path, capsys):
    config, _, _ = finished
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    code, _, err = run_main(["run", str(config), "--out", str(target)], capsys)
    assert code == 2 and "is a file, not a folder" in _one_error_line(err) and target.read_text() == "mine"


def test_overwrite_replaces_the_run_its_analysis_figures_and_exports_not_the_users_files(finished, tmp_path, capsys):
    config, source, _ = finished
    out = tmp_path / "run"
    shutil.copytree(source, out)
    (out / "analysis.json").write_text("{}")
    for folder, name in (("figures", "packing.png"), ("vtk", "grains.vtu")):
        (out / folder).mkdir()
        (out / folder / name).write_text("old")
    (out / "figures" / "my-notes.txt").write_text("mine")
    (out / "README.txt").write_text("mine")
    code, stdout, err = run_main(["run", str(config), "--out", str(out), "--seed", "5", "--overwrite"], capsys)
    assert code == 0, err
    assert "--overwrite: removed final.gsd, summary.json" in err and "analysis.json" in err
    assert not (out / "analysis.json").exists() and not (out / "vtk").exists()
    assert [p.name for p in (out / "figures").iterdir()] == ["my-notes.txt"]
    assert (out / "README.txt").read_text() == "mine"
    assert json.loads((out / "summary.json").read_text())["seed"] == 5


def test_run_never_replaces_the_users_config(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "config.toml").write_text(TINY_RUN)
    code, _, err = run_main(["run", "config.toml", "--out", "."], capsys)
    assert code == 2 and "would replace this file" in _one_error_line(err)
    (tmp_path / "mine.toml").write_text(TINY_RUN)
    code, _, err = run_main(["run", "mine.toml", "--out", "."], capsys)
    assert code == 2 and "not a granpack run's resolved config" in _one_error_line(err)
    assert (tmp_path / "config.toml").read_text() == TINY_RUN
    assert sorted(p.name for p in tmp_path.iterdir()) == ["config.toml", "mine.toml"]


def test_run_json_prints_the_summary(finished, tmp_path, capsys):
    config, _, _ = finished
    code, stdout, err = run_main(["run", str(config), "--out", str(tmp_path / "r"), "--json"], capsys)
    assert code == 0, err
    result = json.loads(stdout)
    assert result["out"] == str(tmp_path / "r") and result["files"]["final.gsd"] == str(tmp_path / "r" / "final.gsd")
    assert result["summary"]["status"] == "not at rest" and result["summary"]["steps"] == 200


# ----------------------------------------------------------------------------- Ctrl-C


@pytest.fixture
def default_sigint():
    """Python's default SIGINT handler for the test: a library used by an earlier test (e.g. a Dask
    cluster) may have left its own or SIG_IGN, and ``run`` only takes over the default one (a child
    process inherits SIG_IGN, and would never see the Ctrl-C)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def _interrupting_advance(monkeypatch, at_calls, times=1):
    """Make the settling's advance send SIGINT to this process (``times`` in a row) at the given calls,
    as Ctrl-C would."""
    import granpack.settling as settling

    advance = settling.advance
    calls = {"n": 0}

    def wrapped(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] in at_calls:
            for _ in range(times):
                signal.raise_signal(signal.SIGINT)
        return advance(*args, **kwargs)

    monkeypatch.setattr(settling, "advance", wrapped)
    return advance


def test_ctrl_c_while_settling_writes_the_checkpoint_and_resumes_bit_for_bit(finished, tmp_path, capsys, monkeypatch, default_sigint):
    from granpack.io.gsd import read_packing

    config, whole, _ = finished
    out = tmp_path / "run"
    advance = _interrupting_advance(monkeypatch, {137})
    code, stdout, err = run_main(["run", str(config), "--out", str(out)], capsys)
    assert code == 130 and stdout == ""
    last = err.splitlines()[-1]
    assert last.startswith("interrupted at t = 0.685 sqrt(d/g) (step 137)") and "Traceback" not in err
    assert last.endswith(f"continue with: granpack run {config} --out {out} --resume")
    checkpoint = read_packing(out / "checkpoint.gsd")
    assert checkpoint.metadata["counters"]["step"] == 137 and not (out / "final.gsd").exists()

    import granpack.settling as settling

    monkeypatch.setattr(settling, "advance", advance)
    code, stdout, err = run_main(["run", str(config), "--out", str(out)], capsys)  # no silent restart
    assert code == 2 and "unfinished run" in _one_error_line(err) and "t = 0.685" in err
    code, stdout, err = run_main(["run", str(config), "--out", str(out), "--resume"], capsys)
    assert code == 0 and f"resuming from t = 0.685 sqrt(d/g) (step 137) of {out / 'checkpoint.gsd'}" in err
    a, b = read_packing(whole / "final.gsd"), read_packing(out / "final.gsd")
    for name in ("position", "quaternion", "velocity", "omega"):
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name))


def test_a_second_ctrl_c_stops_at_once_keeping_the_last_checkpoint(finished, tmp_path, capsys, monkeypatch, default_sigint):
    config, _, _ = finished
    out = tmp_path / "run"
    _interrupting_advance(monkeypatch, {150}, times=2)
    code, stdout, err = run_main(["run", str(config), "--out", str(out)], capsys)
    last = err.splitlines()[-1]
    assert code == 130 and "Traceback" not in err
    assert last.startswith("interrupted; the last checkpoint at t = 0.5 sqrt(d/g) (step 100) is kept in")
    assert last.endswith("--resume")


def test_ctrl_c_inside_a_numba_kernel_is_an_interruption(finished, tmp_path, capsys, monkeypatch):
    """A KeyboardInterrupt raised while a compiled function runs surfaces as a SystemError
    ("CPUDispatcher(...) returned a result with an exception set") with the interrupt as context."""
    import granpack.simulation as simulation

    def kernel_interrupted(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("CPUDispatcher(<function f>) returned a result with an exception set")

    config, _, _ = finished
    monkeypatch.setattr(simulation, "run_packing", kernel_interrupted)
    code, stdout, err = run_main(["run", str(config), "--out", str(tmp_path / "r")], capsys)
    assert code == 130 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("interrupted before the first checkpoint") and "--resume" in err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_sigint_or_sigterm_to_a_running_command_stops_it_cleanly(tmp_path, default_sigint, sig):
    """A real Ctrl-C (SIGINT to the process) while settling, or SIGTERM (a batch scheduler's
    stop): exit 130, one line naming --resume, the checkpoint of the step written."""
    config = tmp_path / "long.toml"
    # never done: more passing checks in a row than the run can make (its 20 spheres come to rest)
    config.write_text(TINY_RUN.replace("max_time = 1.0", "max_time = 500.0\nwindow = 100000"))
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "granpack", "run", str(config), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        for line in proc.stderr:  # progress lines: the first comes at the first check (t = 0.25)
            lines.append(line)
            if line.startswith("settling t = "):
                break
        proc.send_signal(sig)
        stdout, rest = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = "".join(lines) + rest
    assert proc.returncode == 130 and stdout == "" and "Traceback" not in err
    assert rest.count("\n") == 1 and rest.startswith("interrupted at t = ") and rest.rstrip().endswith("--resume")
    assert (out / "checkpoint.gsd").is_file() and not (out / "final.gsd").exists()


@pytest.mark.skipif(shutil.which("nohup") is None or shutil.which("sh") is None, reason="needs nohup and sh")
def test_sigterm_to_a_run_started_with_nohup_writes_the_step_checkpoint(tmp_path):
    """``nohup granpack run ... &`` from a script, as users start long runs: the shell starts the
    job with SIGINT ignored. SIGTERM must still stop it at the end of the step with that step's
    checkpoint written (not the last periodic one), exit 130."""
    config = tmp_path / "long.toml"
    config.write_text(TINY_RUN.replace("max_time = 1.0", "max_time = 500.0\nwindow = 100000")
                      .replace("checkpoint_interval = 0.5", "checkpoint_interval = 400.0"))
    out, log = tmp_path / "run", tmp_path / "nohup.log"
    script = (f'nohup "{sys.executable}" -m granpack run "{config}" --out "{out}" > "{log}" 2>&1 &\n'
              'echo $!\nwait $!\necho "exit $?"\n')
    shell = subprocess.Popen(["sh", "-c", script], stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        pid = int(shell.stdout.readline())
        deadline = time.monotonic() + 300
        while "settling t = " not in (log.read_text() if log.is_file() else ""):
            assert time.monotonic() < deadline and shell.poll() is None, log.read_text() if log.is_file() else ""
            time.sleep(0.2)
        with open(f"/proc/{pid}/status") if Path(f"/proc/{pid}/status").is_file() else contextlib.nullcontext() as f:
            if f is not None:  # the job's SIGINT is ignored, as under nohup ... &
                ignored = int(next(line for line in f if line.startswith("SigIgn:")).split()[1], 16)
                assert ignored & (1 << (signal.SIGINT - 1))
        os.kill(pid, signal.SIGTERM)
        rest, _ = shell.communicate(timeout=120)
    finally:
        if shell.poll() is None:
            os.killpg(shell.pid, signal.SIGKILL)
    assert rest.strip() == "exit 130"
    last = log.read_text().splitlines()[-1]
    assert last.startswith("interrupted at t = ") and last.endswith("--resume"), last
    step = int(re.search(r"\(step (\d+)\)", last).group(1))
    from granpack.io.gsd import read_packing

    assert step > 0 and read_packing(out / "checkpoint.gsd").metadata["counters"]["step"] == step


# ----------------------------------------------------------------------------- output for scripts and logs


def test_check_prints_whole_tables_when_not_a_terminal(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "40")
    path = tmp_path / "seven.toml"
    shares = [1 / 7] * 6 + [1 - 6 / 7]
    body = "".join(f'[[populations]]\nshape = "pinacoid"\nsize = {1 - 0.1 * k:g}\naspect = [1.5, 1.25]\n'
                   f"volume_fraction = {share!r}\n\n" for k, share in enumerate(shares))
    path.write_text(f"n_particles = 3000\nlateral_size = 8.0\n\n{body}")
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and "…" not in out
    assert "pinacoid-0.4-1.5x1.25" in out and "0.142857" in out and "recovery_slop 0.0005 d" in out
    assert max(len(line) for line in out.splitlines()) > 80


def test_check_json_and_the_short_column_warning(tmp_path, capsys):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_RUN)
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and err.count("\n") == 2  # the pile too short, and max_time = 1 (an advisory)
    assert "warning: the settled pile will stand about 1.9 d high" in err and "bulk region" in err
    assert "warning: equilibrium.max_time = 1 sqrt(d/g)" in err
    code, out, err = run_main(["check", str(path), "--json"], capsys)
    result = json.loads(out)
    assert result["valid"] and result["n_particles"] == 20 and result["mixture"][0]["count"] == 20
    assert result["resolved"]["time_stepping"]["time_step"] == 5e-3 and any("bulk region" in w for w in result["warnings"])
    code, out, err = run_main(["check", str(EXAMPLES / "demo.toml")], capsys)
    assert code == 0 and err == ""  # the demo's pile has a bulk region


def test_check_estimates_the_pile_height_on_the_floor_of_the_container(tmp_path, capsys):
    """100 spheres of volume pi/6 at the one-size solid fraction 0.6 over a 6 d cylinder's section
    (9 pi d^2) stand 100 (pi/6) / (0.6 * 9 pi) = 3.086 d high; spheres of size 2 leave the bulk
    region's margins two sizes, 4 d, above the wall and below the surface."""
    path = tmp_path / "mould.toml"
    path.write_text('n_particles = 100\nlateral_size = 6.0\n[container]\nshape = "cylinder"\n'
                    '[[populations]]\nshape = "sphere"\nsize = 1.0\nvolume_fraction = 1.0\n')
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0
    assert "expected pile: about 3.09 d high (solid fraction 0.6 assumed over the cylinder's 28.27 d^2)" in out
    path.write_text(path.read_text().replace("size = 1.0", "size = 2.0").replace("6.0", "8.0").replace("100", "20"))
    code, out, err = run_main(["check", str(path)], capsys)
    assert "below the 10 d that a bulk region needs (4 d above the wall, 2 d of bulk, 4 d below the surface)" in err


def test_check_expects_a_mix_of_sizes_to_settle_denser(tmp_path, capsys):
    """1040 grains of study-small's pinacoids-small-30 (sizes 1 and 1/3, 30 % small, 2.25 d cell)
    fill 5.5 d at a solid fraction of 0.6, but such a pile settled at 0.72-0.74 with its surface
    at 4.59 d and no bulk region: the check estimates mixes of sizes at 0.72 and warns; one size
    with the same grains' volume stands above 5 d and does not warn."""
    mix = """n_particles = {n}
lateral_size = 2.25
[[populations]]
shape = "pinacoid"
size = 1.0
volume_fraction = {large}
{small}"""
    small = """[[populations]]
shape = "pinacoid"
size = 0.3333333333
volume_fraction = 0.3
"""
    path = tmp_path / "mix.toml"
    path.write_text(mix.format(n=1040, large=0.7, small=small))
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and err.startswith("warning: the settled pile will stand about 4.6 d high (solid fraction about 0.72")
    path.write_text(mix.format(n=1320, large=0.7, small=small))
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and err == ""
    path.write_text(mix.format(n=117, large=1.0, small=""))  # 117 large grains: about the same volume, one size
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and err == "", err


def test_analyze_warnings_are_clean_lines_with_the_true_cause(finished, tmp_path, capsys):
    _, source, _ = finished
    out = tmp_path / "run"
    shutil.copytree(source, out)
    code, stdout, err = run_main(["analyze", str(out)], capsys)
    assert code == 0
    assert err.splitlines() == [line for line in err.splitlines() if line.startswith("warning: ")]
    assert "no bulk region: the pile's free surface is at" in err and "Warning" not in err and ".py" not in err
    assert "no non-spherical grain" not in err and "fewer than two grains" not in err
    assert "none (surface at" in stdout and " .. " not in stdout.split("bulk region")[1].splitlines()[0]
    code, stdout, err = run_main(["analyze", str(out), "--json"], capsys)
    result = json.loads(stdout)
    assert result["file"] == str(out / "analysis.json") and result["analysis"]["bulk"]["valid"] is False
    assert result["analysis"]["warnings"][0].startswith("no bulk region")

    code, stdout, err = run_main(["figures", str(out)], capsys)
    assert code == 0 and not (out / "figures" / "pair_correlation.png").exists()
    assert "skipped pair_correlation: g(r) is empty (no bulk region" in err and "skipped" not in stdout


def test_settling_bar_keeps_the_time_on_an_80_column_terminal():
    import io
    from types import SimpleNamespace

    from rich.console import Console

    from granpack.progress import Lines as _Lines, SettlingProgress as _SettlingProgress

    report = SimpleNamespace(force_ok=True, torque_ok=False, energy_ok=False, wall_ok=True, max_net_force=1.2e-2,
                             kinetic_energy=3e-5, max_net_torque=1e-3, wall_force_over_weight=0.9998)
    progress = _SettlingProgress("bar", 200.0, _Lines())
    with progress:
        progress._bar.stop()
        progress.update(123.456, 24691, 1.23e-3, 1234, report, 2, 5, 3.2e-4)
        screen = io.StringIO()
        Console(file=screen, width=80).print(progress._bar.get_renderable())
    line = screen.getvalue().splitlines()[0]
    assert line.startswith("settling t = 123.46/200") and len(line) <= 80


def test_progress_before_any_contact_force_says_so_instead_of_an_infinite_force():
    """Until a contact carries force the stress scale P is 0: the line and the bar say there is
    no net force figure yet, not "inf d^2 P"."""
    import io
    import math
    from types import SimpleNamespace

    from rich.console import Console

    from granpack.progress import SettlingProgress as _SettlingProgress

    report = SimpleNamespace(force_ok=False, torque_ok=False, energy_ok=False, wall_ok=False, max_net_force=math.inf,
                             kinetic_energy=math.inf, max_net_torque=math.inf, wall_force_over_weight=0.0)
    written = []
    with _SettlingProgress("lines", 80.0, written.append) as progress:
        progress.update(0.25, 50, 1.3, 0, report, 0, 5, 0.0)
    assert len(written) == 1 and "inf" not in written[0]
    assert "largest net force n/a (no contact carries force yet)" in written[0]
    progress = _SettlingProgress("bar", 80.0, written.append)
    with progress:
        progress._bar.stop()
        progress.update(0.25, 50, 1.3, 0, report, 0, 5, 0.0)
        screen = io.StringIO()
        Console(file=screen, width=200).print(progress._bar.get_renderable())
    assert "|F| n/a" in screen.getvalue()
    report.max_net_force = 3.68e3
    with _SettlingProgress("lines", 80.0, written.append) as progress:
        progress.update(0.5, 100, 1.3, 2, report, 0, 5, 0.0)
    assert "largest net force 3.68e+03 d^2 P" in written[-1]


def test_progress_lines_every_interval(tmp_path, capsys, monkeypatch):
    import granpack.progress as progress
    import granpack.simulation as simulation

    from granpack.config import load_config

    monkeypatch.setattr(progress, "PROGRESS_LINE_SECONDS", 0.0)
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_RUN)
    simulation.run_packing(load_config(path), tmp_path / "r", progress="lines")
    printed = capsys.readouterr().err.splitlines()
    lines = [line for line in printed if line.startswith("settling t = ") and "(at the last check" not in line]
    assert len(lines) == 4 and lines[-1].startswith("settling t = 1.00/1 sqrt(d/g), step 200, ")
    assert "steps/s" in lines[-1]
    # between two checks too: every step without a check is due here, each line with the last check's time
    between = [line for line in printed if line.endswith("(at the last check, t = 0.25)")]
    assert len(between) == 49 and between[0].startswith("settling t = 0.26/1 sqrt(d/g), step 51, ")


def test_progress_lines_come_between_checks_far_apart(tmp_path, capsys, monkeypatch):
    """A check interval longer than the line interval: lines still come, not only at checks."""
    import granpack.progress as progress
    import granpack.simulation as simulation

    from granpack.config import load_config

    monkeypatch.setattr(progress, "PROGRESS_LINE_SECONDS", 0.0)
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_RUN.replace("max_time = 1.0", "max_time = 1.0\ncheck_interval = 0.5"))
    simulation.run_packing(load_config(path), tmp_path / "r", progress="lines")
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("settling t = ")]
    assert len(lines) > 2 and any(line.endswith("(at the last check, t = 0.50)") for line in lines)


def test_progress_log_takes_the_lines_and_notes_and_overwrite_removes_it(tmp_path, capsys, monkeypatch):
    """``progress="log"`` (a campaign's runs): nothing on stderr, the notes and progress lines
    appended to progress.log, the last one saying how the run ended; --overwrite removes it."""
    import granpack.progress as progress
    import granpack.simulation as simulation

    from granpack.config import load_config

    monkeypatch.setattr(progress, "PROGRESS_LINE_SECONDS", 0.0)
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_RUN)
    out = tmp_path / "r"
    simulation.run_packing(load_config(path), out, progress="log")
    assert capsys.readouterr().err == ""
    lines = (out / "progress.log").read_text().splitlines()
    from granpack.advice import advise

    warned = [f"warning: {w}" for w in advise(load_config(path))]  # max_time = 1, a short pile
    assert len(warned) == 2 and lines[:2] == warned
    lines = lines[2:]
    assert lines[0].startswith("pouring 20 grains") and lines[1].startswith("poured in")
    at_checks = [line for line in lines[2:-1] if "(at the last check" not in line]
    assert [line.split(", step")[0] for line in at_checks] == [f"settling t = {t:.2f}/1 sqrt(d/g)"
                                                                for t in (0.25, 0.5, 0.75, 1.0)]
    assert lines[-1].startswith("not at rest at t = 1 sqrt(d/g) after ") and "largest net force" in lines[-1]
    simulation.run_packing(load_config(path), out, resume=True, progress="log")
    assert (out / "progress.log").read_text().splitlines()[-1].endswith("nothing to resume, its summary stands")
    simulation.run_packing(load_config(path), out, overwrite=True, progress=False)
    assert not (out / "progress.log").exists()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_sigint_or_sigterm_to_a_campaign_keeps_the_checkpoints(tmp_path, default_sigint, sig):
    """Ctrl-C in a terminal signals the whole process group (the command and its Dask workers);
    SIGTERM (``kill PID``) reaches the command alone: either way exit 130, one line saying how to
    continue, the tables written, the runs' checkpoints kept, no traceback, and no worker left."""
    spec = tmp_path / "c.toml"
    spec.write_text(_TINY_CAMPAIGN.replace("max_time = 0.5", "max_time = 500.0\nwindow = 100000"))
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "granpack", "campaign", str(spec), "--out", str(out), "--workers", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        checkpoint = out / "mono" / "seed-1" / "checkpoint.gsd"
        for _ in range(600):
            if checkpoint.is_file() or proc.poll() is not None:
                break
            time.sleep(0.5)
        assert checkpoint.is_file()
        if sig == signal.SIGINT:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        stdout, err = proc.communicate(timeout=120)
        for _ in range(100):  # the workers end with the cluster the command closed
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
        else:
            pytest.fail("a process of the campaign's group outlived it")
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130 and "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("interrupted; finished runs and the checkpoints of unfinished ones are kept")
    assert checkpoint.is_file() and (out / "runs.csv").is_file()


def test_a_resolved_config_of_an_older_version_is_granpacks_own(tmp_path, capsys):
    """A folder left with only config.toml (a run stopped during the pour) by a version whose
    resolved config had fewer keys: the file starts with granpack's header, the run may replace it."""
    from granpack.config import load_config

    config = tmp_path / "tiny.toml"
    config.write_text(TINY_RUN)
    resolved = load_config(config).with_seed(8).to_toml()
    older = "\n".join(line for line in resolved.splitlines() if not line.startswith("theta ="))
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.toml").write_text(older)
    code, stdout, err = run_main(["run", str(config), "--out", str(out)], capsys)
    assert code == 0, err
    assert (out / "config.toml").read_text() == load_config(config).to_toml()


def test_run_warns_before_pouring_a_pile_too_short_for_a_bulk_region(tmp_path, capsys):
    """The warning `check` gives comes from `run` too, on stderr, before the work starts."""
    config = tmp_path / "thin.toml"
    config.write_text(TINY_RUN)  # 20 spheres in a 3 d cell: about 2 d tall
    with pytest.raises(SystemExit) as info:
        main(["run", str(config), "--out", str(tmp_path / "run")])
    assert info.value.code == 0
    err = capsys.readouterr().err.splitlines()
    warned = [line for line in err if line.startswith("warning: the settled pile will stand about")]
    assert warned and "bulk region" in warned[0] and err.index(warned[0]) < err.index(next(l for l in err if l.startswith("pouring")))

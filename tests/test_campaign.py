"""Campaigns: spec validation, the results store, and a tiny campaign end to end on Dask."""

from __future__ import annotations

import dataclasses
import json
import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from granpack.campaign import campaign_from_dict, load_campaign, run_campaign
from granpack.campaign.runner import estimated_cost, run_order, selected_runs, status_line
from granpack.campaign.store import ANALYSIS_KEYS, flatten, is_finished, run_row, summary_table, write_task
from granpack.cli import main
from granpack.config import load_config_dict
from granpack.mixture import Mixture
from granpack.simulation import initial_state
from granpack.errors import InputError

TINY = textwrap.dedent(
    """
    replicas = 2
    [base]
    seed = 11
    n_particles = 150
    lateral_size = 3.0
    [base.equilibrium]
    max_time = 15.0

    [[mixtures]]
    name = "mono"
    family = "spheres"
    share = 0.0
    [[mixtures.populations]]
    shape = "sphere"
    size = 1.0
    volume_fraction = 1.0

    [[mixtures]]
    name = "bi-30"
    family = "spheres"
    share = 0.3
    lateral_size = 2.5
    [mixtures.equilibrium]
    max_time = 6.0
    [[mixtures.populations]]
    name = "large"
    shape = "sphere"
    size = 1.0
    volume_fraction = 0.7
    [[mixtures.populations]]
    name = "small"
    shape = "sphere"
    size = 0.5
    volume_fraction = 0.3
    """
)


def _tiny_dict() -> dict:
    import tomllib

    return tomllib.loads(TINY)


def _with_settings(run, settings: dict):
    """``run`` with other run-config keys, and the config they validate to."""
    return dataclasses.replace(run, config=load_config_dict(settings), settings=settings)


# ----------------------------------------------------------------------------- spec


def test_spec_runs_seeds_folders_and_overrides():
    spec = campaign_from_dict(_tiny_dict())
    assert [(r.mixture, r.seed, r.replica) for r in spec.runs] == [
        ("mono", 11, 0), ("mono", 12, 1), ("bi-30", 11, 0), ("bi-30", 12, 1)
    ]
    assert [r.folder.as_posix() for r in spec.runs[:2]] == ["mono/seed-11", "mono/seed-12"]
    bi = spec.runs[2].settings
    assert bi["lateral_size"] == 2.5 and bi["n_particles"] == 150
    assert bi["equilibrium"] == {"max_time": 6.0}
    assert spec.runs[0].settings["lateral_size"] == 3.0 and spec.runs[0].settings["equilibrium"] == {"max_time": 15.0}
    assert spec.runs[2].family == "spheres" and spec.runs[2].share == 0.3 and spec.runs[2].shapes == "sphere"


def test_example_campaigns_load():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "examples"
    study, small = load_campaign(root / "study.toml"), load_campaign(root / "study-small.toml")
    assert len(study.mixtures) == len(small.mixtures) == 30
    assert len(study.runs) == 90 and len(small.runs) == 30
    assert {m.name for m in study.mixtures} == {m.name for m in small.mixtures}
    shares = {f: sorted(round(100 * m.share) for m in study.mixtures if m.family == f) for f in
              ("spheres", "pinacoids", "elongated", "flat", "flat-elongated")}
    assert shares == {
        "spheres": [0, 3, 13, 23, 30, 41, 55],
        "pinacoids": [0, 13, 30, 51, 64, 100],
        "elongated": [14, 20, 36, 49, 70, 100],
        "flat": [12, 28, 47, 77, 92, 100],
        "flat-elongated": [14, 29, 50, 70, 100],
    }
    # 3000 grains, but the two mixtures that a 3 d cell leaves short (see the example's header)
    raised = {"pinacoids-small-51": 4322, "pinacoids-small-64": 5346}
    assert all(r.config.n_particles == raised.get(r.mixture, 3000) for r in study.runs)
    # every small run is a column 7 largest grains tall (at solid fraction 0.66, see the example's
    # header): a bulk region of about 3 d_max between the 2 d_max margins of the analysis, except
    # where a cap binds: 600 grains where small grains dominate, 400 for the thin-plate mixtures;
    # where the cap would leave less than 5.6 d_max at solid fraction 0.6 (5.1 at 0.66; a bulk
    # region needs 5), the fewest grains (in tens) reaching it; the pinacoid mixes rich in small
    # grains, which settle at 0.72-0.74, about 7 d_max at 0.6 (5.8 at 0.72). max_time is a cap
    # (the runs stop at rest), 60 for spheres and 100 for pinacoids, beyond the fall of the top
    # grain of the deposited column plus 15 sqrt(d/g)
    capped = {"pinacoids-small-13": 600, "flat-92": 400, "flat-100": 400, "flat-elongated-50": 400}
    floored = {"flat-elongated-70": 450, "flat-elongated-100": 590}
    dense = {"pinacoids-small-30": 1300, "pinacoids-small-51": 2120, "pinacoids-small-64": 2620}
    for run in small.runs:
        config = run.config
        mixture = Mixture.from_config(config)
        solid = float(np.sum(mixture.counts * mixture.particle_volumes))
        d_max = max(p.size for p in config.populations)
        height = solid / ((0.64 if run.family == "spheres" else 0.66) * config.lateral_size**2) / d_max
        if run.mixture in floored:
            assert config.n_particles == floored[run.mixture]
            assert 5.05 <= height <= 5.15, (run.mixture, height)
            fewer = load_config_dict({**run.settings, "n_particles": config.n_particles - 10})
            less = float(np.sum(Mixture.from_config(fewer).counts * mixture.particle_volumes))
            assert less / (0.6 * config.lateral_size**2) / d_max < 5.0 / 0.9, run.mixture
        elif run.mixture in dense:
            assert config.n_particles == dense[run.mixture]
            assert 6.9 <= solid / (0.6 * config.lateral_size**2) / d_max <= 7.05, run.mixture
        else:
            assert 250 <= config.n_particles <= 1000
            if run.family != "spheres":
                assert config.n_particles <= 300 or config.n_particles == capped.get(run.mixture) or height >= 6.5
            assert 6.5 <= height <= 7.5 or config.n_particles == capped.get(run.mixture), (run.mixture, height)
        state, _ = initial_state(config)
        fall = np.sqrt(2.0 * state.position[:, 2].max())
        assert config.equilibrium.max_time == (60.0 if run.family == "spheres" else 100.0), run.mixture
        assert fall + 15.0 <= config.equilibrium.max_time, (run.mixture, fall)


def test_interrupted_runs_then_longest_runs_start_first(tmp_path):
    spec = campaign_from_dict(_tiny_dict())
    costs = [estimated_cost(run) for run in spec.runs]
    assert costs == [150 * 15, 150 * 15, 150 * 6, 150 * 6]
    bad = dataclasses.replace(spec.runs[0], config=spec.runs[0].config.model_copy(update={"n_particles": 0}))
    assert estimated_cost(bad) == 0
    ordered = run_order([spec.runs[2], bad, spec.runs[0]], tmp_path)
    assert [estimated_cost(run) for run in ordered] == [2250, 900, 0]
    # a checkpoint of the short run bi-30/seed-12 puts it first; one left by another config does not
    resumed, stale = spec.runs[3], spec.runs[2]
    for run, settings in ((resumed, resumed.settings), (stale, {**stale.settings, "n_particles": 160})):
        run_dir = tmp_path / run.folder
        run_dir.mkdir(parents=True)
        write_task(run_dir, _with_settings(run, settings))
        (run_dir / "checkpoint.gsd").write_bytes(b"")
    ordered = run_order(list(spec.runs), tmp_path)
    folders = [run.folder.as_posix() for run in ordered]
    assert folders == ["bi-30/seed-12", "mono/seed-11", "mono/seed-12", "bi-30/seed-11"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.update(replica=2), "unknown key 'replica'"),
        (lambda d: d.update(replicas=0), "replicas must be an integer >= 1"),
        (lambda d: d.update(mixtures=[]), "mixtures must be a non-empty list"),
        (lambda d: d["mixtures"][1].update(name="mono"), r"mixtures\[1\].name 'mono' is used"),
        (lambda d: d["mixtures"][0].update(name="a/b"), r"mixtures\[0\].name must be a folder name"),
        (lambda d: d["mixtures"][0].update(share=30), r"mixtures\[0\] \(mono\).share must be a number in \[0, 1\]"),
        (lambda d: d["mixtures"][0].pop("populations"), r"mixtures\[0\] \(mono\).populations"),
        (lambda d: d["mixtures"][0].update(seed=3), r"mixtures\[0\] \(mono\).seed is not allowed"),
        (lambda d: d["base"].update(populations=[]), "base.populations is not allowed"),
        (lambda d: d["mixtures"][1]["populations"][1].update(size=-1.0),
         r"mixtures\[1\] \(bi-30\): populations\[1\].size: must be > 0"),
        (lambda d: d["mixtures"][1].update(lateral_size=1.0), r"mixtures\[1\] \(bi-30\): lateral_size: must exceed"),
        (lambda d: d["base"].update(n_particle=3), r"mixtures\[0\] \(mono\): n_particle: unknown key"),
    ],
)
def test_spec_errors_are_one_line(change, message):
    data = _tiny_dict()
    change(data)
    with pytest.raises(InputError, match=message) as info:
        campaign_from_dict(data, source="c.toml")
    assert str(info.value).startswith("c.toml: ") and "\n" not in str(info.value)


def _check(argv, capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as info:
        main(["check", *argv])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def test_check_reads_a_campaign_one_row_per_mixture(tmp_path, capsys):
    """`granpack check` on a campaign checks each mixture's own run config: one row per mixture
    with its overrides (cell, seeds base.seed + replica, populations), the column warning of the
    mixture whose 20 d cell leaves its 150 grains a pile too low, a bad value named by mixture and
    field; the example campaigns pass."""
    path = tmp_path / "c.toml"
    path.write_text(TINY.replace("lateral_size = 2.5", "lateral_size = 20.0"))
    code, out, err = _check([str(path)], capsys)
    assert code == 0 and "2 mixtures x 2 replicas = 4 runs" in out and "force_tolerance 0.0001 d_p^2 P" in out
    cells = {row[0]: row for row in ([c.strip() for c in line.split("│")[1:-1]] for line in out.splitlines()
                                     if line.startswith("│"))}
    assert cells["mono"] == ["mono", "spheres", "0", "150", "3", "11, 12", "sphere-1 (150, 1.0000)"]
    assert cells["bi-30"] == ["bi-30", "spheres", "0.3", "150", "20", "11, 12", "large (34, 0.7010); small (116, 0.2990)"]
    piles = [line for line in err.splitlines() if "the settled pile will stand about" in line]
    assert len(piles) == 1 and piles[0].startswith("warning: bi-30: the settled pile will stand about")
    code, out, err = _check([str(path), "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["n_runs"] == 4 and [m["seeds"] for m in result["mixtures"]] == [[11, 12], [11, 12]]
    assert result["mixtures"][1]["lateral_size"] == 20.0
    assert [w for w in result["warnings"] if "settled pile" in w][0].startswith("bi-30: ")
    path.write_text(TINY.replace("size = 0.5", "size = -1"))
    code, out, err = _check([str(path)], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(f"error: {path}: mixtures[1] (bi-30): populations[1].size: must be > 0 (got -1)"), err
    root = Path(__file__).resolve().parents[1] / "examples"
    for name, n_runs in (("study.toml", 90), ("study-small.toml", 30)):
        code, out, err = _check([str(root / name), "--json"], capsys)
        assert code == 0 and json.loads(out)["n_runs"] == n_runs


def test_campaign_command_bad_spec_exits_2(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text(TINY.replace("replicas = 2", "replicas = -1"))
    with pytest.raises(SystemExit) as info:
        main(["campaign", str(path), "--out", str(tmp_path / "out")])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {path}: replicas") and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()
    path.write_text("replicas = [")
    with pytest.raises(SystemExit) as info:
        main(["campaign", str(path), "--out", str(tmp_path / "out")])
    assert info.value.code == 2


def test_workers_option_checked(tmp_path):
    spec = campaign_from_dict(_tiny_dict())
    with pytest.raises(InputError, match="--workers must be >= 1"):
        run_campaign(spec, tmp_path, workers=0)
    with pytest.raises(InputError, match="--workers applies to the local cluster only"):
        run_campaign(spec, tmp_path, workers=2, scheduler="tcp://127.0.0.1:1")


# ----------------------------------------------------------------------------- store


def _fake_analysis(seed: int, phi: float) -> dict:
    data = {key: {} for key in ANALYSIS_KEYS}
    data.update(
        solid_fraction={"bulk": phi, "std": 0.01, "profile_z": [0.5, 1.5], "profile_phi": [0.6, 0.6]},
        coordination={"N": 6.0, "Ns": 6.0, "Nd": 0.0, "Nt": 0.0, "Nc": 6.0, "rattler_fraction": None},
        order={"Q00": 0.02, "Q22": 0.01, "director": [0, 0, 1]},
        n_particles=30, populations=[{"name": "a"}], seed=seed, version="x",
    )
    return data


def test_flatten_keeps_scalars_only():
    flat = flatten(_fake_analysis(3, 0.64))
    assert flat["solid_fraction.bulk"] == 0.64 and flat["coordination.N"] == 6.0 and flat["seed"] == 3
    assert math.isnan(flat["coordination.rattler_fraction"])
    assert "solid_fraction.profile_z" not in flat and "order.director" not in flat and "populations" not in flat


def test_finished_runs_and_tables(tmp_path):
    spec = campaign_from_dict(_tiny_dict())
    done, stale, failed, missing = spec.runs
    for run, phi in ((done, 0.62), (stale, 0.64)):
        folder = tmp_path / run.folder
        folder.mkdir(parents=True)
        (folder / "analysis.json").write_text(json.dumps(_fake_analysis(run.seed, phi)))
        write_task(folder, run)
    write_task(tmp_path / stale.folder, _with_settings(stale, {**stale.settings, "n_particles": 31}))
    (tmp_path / failed.folder).mkdir(parents=True)
    (tmp_path / failed.folder / "error.txt").write_text("Traceback ...\nRuntimeError: solver diverged\n")
    assert is_finished(tmp_path, done)
    assert not is_finished(tmp_path, stale)  # made for another config
    wrong_seed = dataclasses.replace(done, seed=99)
    assert not is_finished(tmp_path, wrong_seed)

    rows = pd.DataFrame([run_row(tmp_path, r) for r in spec.runs])
    assert rows["status"].tolist() == ["done", "missing", "failed", "missing"]
    assert rows.loc[2, "error"] == "RuntimeError: solver diverged"
    assert rows.loc[0, "solid_fraction.bulk"] == 0.62
    summary = summary_table(rows)
    assert summary["mixture"].tolist() == ["mono", "bi-30"]
    assert summary["n_done"].tolist() == [1, 0] and summary["n_failed"].tolist() == [0, 1]
    assert summary.loc[0, "solid_fraction.bulk.mean"] == 0.62
    assert math.isnan(summary.loc[0, "solid_fraction.bulk.std"])  # one replica


def test_mixture_patterns_choose_the_runs_and_the_tables_list_every_run(tmp_path):
    spec = campaign_from_dict(_tiny_dict())
    assert [r.mixture for r in selected_runs(spec, ["bi-*"])] == ["bi-30", "bi-30"]
    assert [r.mixture for r in selected_runs(spec, ["mono", "bi-30"])] == ["mono", "mono", "bi-30", "bi-30"]
    assert selected_runs(spec, None) == spec.runs
    with pytest.raises(InputError, match=r"--mixture: 'flat-\*' matches no mixture of the campaign \(mixtures: mono, bi-30\)"):
        selected_runs(spec, ["mono", "flat-*"])
    # the selected mixture's runs are finished: nothing to run, no cluster; mono's runs stay missing
    for run in spec.runs[2:]:
        folder = tmp_path / run.folder
        folder.mkdir(parents=True)
        (folder / "analysis.json").write_text(json.dumps(_fake_analysis(run.seed, 0.7)))
        write_task(folder, run)
    report = run_campaign(spec, tmp_path, progress=False, mixtures=["bi-*"])
    assert (report.n_runs, report.n_skipped, report.n_done, report.n_failed) == (2, 2, 2, 0)
    assert report.runs["status"].tolist() == ["missing", "missing", "done", "done"]
    assert pd.read_csv(tmp_path / "runs.csv")["status"].tolist() == ["missing", "missing", "done", "done"]


def test_campaign_command_unknown_mixture_exits_2_and_writes_nothing(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text(TINY)
    with pytest.raises(SystemExit) as info:
        main(["campaign", str(path), "--out", str(tmp_path / "out"), "--mixture", "sphere*"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err == "error: --mixture: 'sphere*' matches no mixture of the campaign (mixtures: mono, bi-30)"
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- end to end


def _mtimes(out, runs):
    return {r.folder: (out / r.folder / "analysis.json").stat().st_mtime_ns for r in runs}


def test_campaign_end_to_end_resume_and_failure(tmp_path, capsys, monkeypatch):
    pytest.importorskip("granpack.simulation", reason="granpack.simulation (run_packing) is not written yet")
    pytest.importorskip("granpack.analysis.report", reason="granpack.analysis.report (analyze_run) is not written yet")
    spec_path = tmp_path / "tiny.toml"
    spec_path.write_text(TINY)
    spec = load_campaign(spec_path)
    good = spec.runs
    # a grading that 150 grains cannot pour: valid keys, refused by the run itself on the worker
    graded = {"shape": "sphere", "volume_fraction": 1.0,
              "grading": {"curve": "fuller", "d_min": 0.05, "d_max": 1.0, "exponent": 0.5}}
    bad = dataclasses.replace(_with_settings(good[0], {**good[0].settings, "populations": [graded]}), mixture="bad")
    out = tmp_path / "out"

    import granpack.campaign.runner as runner

    monkeypatch.setattr(runner, "_STATUS_SECONDS", 0.0)  # a status round at every refresh (2 s)
    report = run_campaign(dataclasses.replace(spec, runs=good + (bad,)), out, workers=2)
    captured = capsys.readouterr()
    printed = captured.err  # progress and notes on stderr, nothing on stdout (no bar off a terminal)
    assert captured.out == ""
    status = [line.removeprefix("running ").split(": ", 1) for line in printed.splitlines() if line.startswith("running ")]
    assert status  # each a whole line of the run's progress.log, however long (not wrapped at 80 columns)
    assert all(text in (out / folder / "progress.log").read_text().splitlines() for folder, text in status)
    assert any(len(text) > 80 for _, text in status)
    assert (report.n_runs, report.n_done, report.n_failed, report.n_skipped) == (5, 4, 1, 0)
    assert "retry   bad/seed-11" in printed and "failed  bad/seed-11" in printed
    runs = pd.read_csv(out / "runs.csv")
    assert len(runs) == 5 and len(pd.read_parquet(out / "runs.parquet")) == 5
    assert runs["status"].tolist() == ["done"] * 4 + ["failed"]
    assert "cannot be represented by n_particles" in runs.loc[4, "error"]
    assert "cannot be represented by n_particles" in (out / "bad" / "seed-11" / "error.txt").read_text()
    for run in good:  # each run's progress went to its progress.log, ending with how it ended
        log = (out / run.folder / "progress.log").read_text().splitlines()
        warned = [line for line in log if line.startswith("warning: ")]  # its advice first (max_time)
        assert warned and log[:len(warned)] == warned
        log = log[len(warned):]
        assert log[0].startswith(f"pouring {run.config.n_particles} grains") and "settling t = " in log[2]
        assert log[-1].startswith(("equilibrium at t = ", "not at rest at t = "))
    for column in ("solid_fraction.bulk", "coordination.N"):
        assert runs.loc[:3, column].notna().all()
    assert runs.loc[:3, "order.Q00"].isna().all()  # spheres have no orientational order
    assert np.all((runs.loc[:3, "solid_fraction.bulk"] > 0.2) & (runs.loc[:3, "solid_fraction.bulk"] < 0.8))
    summary = pd.read_csv(out / "summary.csv")
    assert summary["mixture"].tolist() == ["mono", "bi-30", "bad"]
    assert summary["n_done"].tolist() == [2, 2, 0]
    assert np.isfinite(summary.loc[:1, "solid_fraction.bulk.mean"]).all()
    assert np.isfinite(summary.loc[:1, "solid_fraction.bulk.std"]).all()

    # an interrupted campaign: one run lost its analysis, another its whole simulation output
    before = _mtimes(out, good)
    (out / good[1].folder / "analysis.json").unlink()
    for name in ("analysis.json", "summary.json", "final.gsd"):
        (out / good[3].folder / name).unlink()
    with pytest.raises(SystemExit) as info:
        main(["campaign", str(spec_path), "--out", str(out), "--workers", "2"])
    assert info.value.code == 0
    captured = capsys.readouterr()
    printed = captured.err
    assert "done    mono/seed-12 (analysed" in printed and "done    bi-30/seed-12 (" in printed
    assert "mono/seed-11" not in printed  # finished runs are not resubmitted
    at_rest = int((pd.read_csv(out / "runs.csv")["run.status"] == "equilibrium").sum())
    assert captured.out.startswith(f"4 runs: 4 done (2 already finished; {at_rest} at rest, {4 - at_rest} stopped at "
                                   "the time cap), 0 failed")
    after = _mtimes(out, good)
    assert after[good[0].folder] == before[good[0].folder] and after[good[2].folder] == before[good[2].folder]
    assert after[good[1].folder] > before[good[1].folder] and after[good[3].folder] > before[good[3].folder]
    assert (out / good[3].folder / "final.gsd").is_file()
    runs = pd.read_csv(out / "runs.csv")
    assert runs["status"].tolist() == ["done"] * 4

    # nothing left to do: no cluster is started, the tables are rewritten
    report = run_campaign(spec, out, progress=False)
    assert (report.n_skipped, report.n_done, report.n_failed) == (4, 4, 0)


def test_status_line_is_the_last_line_of_the_runs_progress_log(tmp_path):
    run = campaign_from_dict(_tiny_dict()).runs[0]
    assert status_line(tmp_path, run) is None  # not started: no progress.log yet
    folder = tmp_path / run.folder
    folder.mkdir(parents=True)
    (folder / "progress.log").write_text("")
    assert status_line(tmp_path, run) is None
    lines = [f"settling t = {i * 0.25:.2f}/15 sqrt(d/g), step {i * 50}, " + "x" * 200 for i in range(1, 40)]
    (folder / "progress.log").write_text("\n".join(lines) + "\n\n")
    assert status_line(tmp_path, run) == f"running mono/seed-11: {lines[-1]}"
    written = (folder / "progress.log").stat().st_mtime
    assert status_line(tmp_path, run, since=written) == f"running mono/seed-11: {lines[-1]}"
    assert status_line(tmp_path, run, since=written + 1.0) is None  # an earlier call's log: a queued task


def test_a_local_worker_ignores_sigint_and_logs_only_critical_distributed_messages(monkeypatch):
    """The workers' preload: Ctrl-C is left to the campaign's process, and a worker's own
    ``distributed`` errors (a heartbeat cut by the closing scheduler) do not reach its stderr."""
    import logging
    import signal

    from granpack.campaign.runner import dask_setup

    handlers = {}
    monkeypatch.setattr(signal, "signal", lambda signum, handler: handlers.update({signum: handler}))
    logger = logging.getLogger("distributed")
    saved = logger.level
    logger.setLevel(logging.INFO)
    try:
        dask_setup(object())
        assert handlers == {signal.SIGINT: signal.SIG_IGN}
        assert logger.getEffectiveLevel() == logging.CRITICAL
        assert not logging.getLogger("distributed.worker").isEnabledFor(logging.ERROR)
    finally:
        logger.setLevel(saved)


# ----------------------------------------------------------------------------- a folder's owner


def _finished_under_another_config(tmp_path: Path, spec) -> list:
    """Fake finished runs of ``spec`` in ``tmp_path``, each computed for another max_time."""
    for run in spec.runs:
        other = _with_settings(run, {**run.settings, "equilibrium": {"max_time": 99.0}})
        folder = tmp_path / run.folder
        folder.mkdir(parents=True)
        (folder / "analysis.json").write_text(json.dumps(_fake_analysis(run.seed, 0.7)))
        write_task(folder, other)
    return [tmp_path / run.folder / "analysis.json" for run in spec.runs]


def test_a_campaign_rerun_with_an_edited_config_refuses_to_replace_its_runs(tmp_path, capsys):
    """An edited campaign file over a folder of finished runs: exit 2 naming the runs and
    --overwrite; nothing touched (the runs' files, no campaign.toml written)."""
    path = tmp_path / "c.toml"
    path.write_text(TINY)
    out = tmp_path / "out"
    kept = _finished_under_another_config(out, load_campaign(path))
    with pytest.raises(SystemExit) as info:
        main(["campaign", str(path), "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "4 run(s) there were computed for another config" in err
    assert "mono/seed-11" in err and "--overwrite" in err
    assert all(p.is_file() for p in kept) and not (out / "campaign.toml").exists()


def test_overwrite_lets_an_edited_campaign_replace_its_runs_and_drops_the_stale_figures(tmp_path):
    from granpack.campaign.runner import _check_folder, changed_runs

    spec = load_campaign_from_text(tmp_path, TINY)
    _finished_under_another_config(tmp_path, spec)
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "solid_fraction.png").write_bytes(b"png")
    assert changed_runs(tmp_path, spec.runs) == list(spec.runs)
    _check_folder(tmp_path, spec.runs, overwrite=True)
    assert not (tmp_path / "figures").exists()
    for run in spec.runs:  # the runs' own task records match now: nothing reported as changed
        write_task(tmp_path / run.folder, run)
    assert changed_runs(tmp_path, spec.runs) == []


def test_a_campaign_with_a_later_cap_takes_its_run_not_at_rest_further(tmp_path):
    """A run that ended not at rest under a cap of 1 is no changed run for the campaign given a cap
    of 2: its task goes on from the final state to the packing of a run made to t = 2 at once, bit
    for bit, and its task record is the new config's; another changed setting is a changed run."""
    from granpack.campaign.runner import changed_runs, run_task
    from granpack.campaign.store import task_matches
    from granpack.io.gsd import read_packing
    from granpack.io.json import read_json
    from granpack.simulation import run_packing

    run = campaign_from_dict(_tiny_dict()).runs[0]
    short, longer, other = (_with_settings(run, {**run.settings, "n_particles": n, "equilibrium": {"max_time": t}})
                            for n, t in ((40, 1.0), (40, 2.0), (41, 2.0)))
    out = tmp_path / "out"
    assert run_task(short, str(out))["status"] == "done"
    assert read_json(out / short.folder / "summary.json")["status"] == "not at rest"
    (out / short.folder / "config.toml").unlink()  # as a kept run has none: the final state's config tells
    assert changed_runs(out, [longer]) == [] and changed_runs(out, [other]) == [other]
    result = run_task(longer, str(out))
    assert result["status"] == "done" and result["action"] == "resumed", result
    assert task_matches(out / longer.folder, longer) and (out / longer.folder / "analysis.json").is_file()
    direct = run_packing(longer.config, tmp_path / "direct", progress=False)
    assert read_json(out / longer.folder / "summary.json")["steps"] == direct["steps"]
    np.testing.assert_array_equal(read_packing(out / longer.folder / "final.gsd").state.position,
                                  read_packing(tmp_path / "direct" / "final.gsd").state.position)


def test_runs_kept_in_the_flat_solver_layout_of_0_1_0_are_the_same_runs_as_in_todays_layout(tmp_path):
    """A campaign file rewritten from ``[base.solver] time_step`` to ``[base.time_stepping] time_step``
    leaves its finished runs finished; a changed value still counts as another config."""
    from granpack.campaign.runner import changed_runs
    from granpack.campaign.store import task_matches

    spec = load_campaign_from_text(tmp_path, TINY)
    for run in spec.runs:
        old = _with_settings(run, {**run.settings, "solver": {"time_step": 5e-3, "tolerance": 1e-4}})
        (tmp_path / run.folder).mkdir(parents=True)
        (tmp_path / run.folder / "analysis.json").write_text(json.dumps(_fake_analysis(run.seed, 0.7)))
        write_task(tmp_path / run.folder, old)
    new = [_with_settings(r, {**r.settings, "time_stepping": {"time_step": 5e-3}}) for r in spec.runs]
    assert all(task_matches(tmp_path / r.folder, r) for r in new) and changed_runs(tmp_path, new) == []
    other = [_with_settings(r, {**r.settings, "time_stepping": {"time_step": 4e-3}}) for r in spec.runs]
    assert changed_runs(tmp_path, other) == other


def load_campaign_from_text(folder: Path, text: str):
    path = folder / "campaign-spec.toml"
    path.write_text(text)
    return load_campaign(path)


def test_a_run_and_a_campaign_each_refuse_the_others_folder(tmp_path, capsys):
    """`run` into a campaign's folder and `campaign` into a run's folder: exit 2, one line, nothing written."""
    run_config = tmp_path / "run.toml"
    run_config.write_text('n_particles = 20\nlateral_size = 3.0\n[[populations]]\nshape = "sphere"\nsize = 1.0\n'
                          'volume_fraction = 1.0\n')
    spec = tmp_path / "c.toml"
    spec.write_text(TINY)
    campaign_dir = tmp_path / "campaign"
    campaign_dir.mkdir()
    (campaign_dir / "runs.csv").write_text("mixture\n")
    with pytest.raises(SystemExit) as info:
        main(["run", str(run_config), "--out", str(campaign_dir)])
    assert info.value.code == 2 and "is a campaign's folder (runs.csv)" in capsys.readouterr().err
    assert sorted(p.name for p in campaign_dir.iterdir()) == ["runs.csv"]
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "config.toml").write_text("# granpack run config\n")
    (run_dir / "summary.json").write_text("{}")
    with pytest.raises(SystemExit) as info:
        main(["campaign", str(spec), "--out", str(run_dir)])
    assert info.value.code == 2 and "holds a single run" in capsys.readouterr().err
    assert sorted(p.name for p in run_dir.iterdir()) == ["config.toml", "summary.json"]


def test_the_substituted_grains_are_the_population_whose_share_the_mixture_gives():
    from granpack.campaign.store import substituted

    spec = campaign_from_dict(_tiny_dict())
    assert [substituted(run) for run in spec.runs] == ["", "", "sphere, size 0.5 d", "sphere, size 0.5 d"]
    flat = _with_settings(spec.runs[2], {**spec.runs[2].settings, "populations": [
        {"shape": "pinacoid", "size": 1.0, "volume_fraction": 0.7},
        {"shape": "pinacoid", "size": 1.0, "aspect": [1.0, 3.0], "volume_fraction": 0.3}]})
    assert substituted(flat) == "pinacoid 1 x 3, size 1 d"

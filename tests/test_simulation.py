"""The packing protocol end to end: ``run_packing`` and ``granpack run`` / ``granpack demo`` files."""

import math
from dataclasses import replace
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

import granpack.settling as settling
import granpack.simulation as simulation
from granpack.nscd import step_policy
from granpack.run_record import TIMELINE_COLUMNS, Milestones, RunRecord
from granpack.analysis.report import analyze_run
from granpack.cli import main
from granpack.config import load_config, load_config_dict
from granpack.equilibrium import check_equilibrium
from granpack.errors import InputError
from granpack.io.gsd import read_packing
from granpack.io.json import read_json, to_jsonable
from granpack.mixture import Mixture
from granpack.simulation import STATUS_AT_REST, STATUS_NOT_AT_REST, run_packing


def sphere_config(n=100, max_time=30.0, seed=3, **output):
    return load_config_dict({
        "seed": seed,
        "n_particles": n,
        "lateral_size": 3.0,
        "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}],
        "equilibrium": {"max_time": max_time},
        "output": {"checkpoint_interval": 0.5, **output},
    })


@pytest.fixture(scope="module")
def settled(tmp_path_factory):
    """100 spheres poured in a 3 d x 3 d cell and settled (about 10 s)."""
    out = tmp_path_factory.mktemp("run")
    config = sphere_config()
    return config, run_packing(config, out, progress=False), out


def test_small_run_reaches_certified_equilibrium(settled):
    config, summary, out = settled
    assert summary["status"] == STATUS_AT_REST
    assert summary["simulated_time"] < config.equilibrium.max_time
    eq = summary["equilibrium"]
    assert eq["passed"] and abs(eq["wall_force_over_weight"] - 1.0) < 1e-4
    assert eq["max_net_force"] < 1e-4 and eq["kinetic_energy"] < 1e-8
    assert summary["final"]["max_overlap"] < 1e-4
    assert summary["nlgs"]["mean_iterations"] > 0 and summary["steps"] == round(summary["simulated_time"] / 5e-3)


def test_a_pile_at_rest_with_deeper_overlaps_than_the_rest_slop_pushes_them_back_and_is_checked_again(
        settled, tmp_path):
    """The settled pile (the slow recovery off, the default) ends where it first meets the
    criteria, with overlaps up to 2.3e-5 d. With the slow recovery on at a rest slop of 1e-5 d,
    the same run (the same steps up to then) goes on from that check, pushes its overlaps back to
    1e-5 d and ends at rest after a full window more. With it on at 5e-5 d, above every overlap,
    the run ends at the first pass as without it."""
    config, summary, _ = settled
    assert summary["end_game"]["rest_recovery_from"] is None and summary["final"]["max_overlap"] > 1e-5

    def slow(slop):
        return config.model_copy(update={"overlap": config.overlap.model_copy(
            update={"rest_recovery_slop": slop, "rest_recovery_speed": 2e-4})})

    tight = slow(1e-5)
    again = run_packing(tight, tmp_path, progress=False)
    assert again["status"] == STATUS_AT_REST
    assert again["end_game"]["rest_recovery_from"] == pytest.approx(summary["simulated_time"], abs=1e-9)
    window = config.equilibrium.window * config.equilibrium.check_interval
    assert again["simulated_time"] >= summary["simulated_time"] + window - 1e-9
    assert again["final"]["max_overlap"] < 1.001e-5
    assert again["equilibrium"]["passed"]
    loose = run_packing(slow(5e-5), tmp_path / "loose", progress=False)
    assert loose["end_game"]["rest_recovery_from"] is None
    assert loose["simulated_time"] == summary["simulated_time"]


@pytest.mark.parametrize("keep", [True, False])
def test_the_velocity_laws_recovery_stops_near_rest_when_the_setting_says_so(keep, monkeypatch):
    """``overlap.recovery_near_rest = false``: once the pile is near rest its steps are solved
    without the recovery's push (speed 0); before that, and always with the default, with the
    configured speed."""
    config = sphere_config(n=20)
    config = config.model_copy(update={"overlap": config.overlap.model_copy(update={"recovery_near_rest": keep})})
    state, mixture = simulation.initial_state(config)
    run = settling.Settling(config, mixture, state, None, RunRecord())
    speeds = []
    solve = settling.advance

    def spy(state, prediction, detected, params, *args, **kwargs):
        speeds.append(params.recovery_speed)
        return solve(state, prediction, detected, params, *args, **kwargs)

    monkeypatch.setattr(settling, "advance", spy)
    run.advance()
    run.record.milestones.near_rest = True
    run.advance()
    assert speeds[0] == config.overlap.recovery_speed > 0
    assert speeds[-1] == (config.overlap.recovery_speed if keep else 0.0)


def test_timeline_records_every_check_and_the_end_game(settled):
    """timeline.csv: one row per equilibrium check, its columns; the end game started once the
    kinetic criterion fell below end_game.damping_below, and from then on the damping (none on the
    checked steps, so the last checks judge free dynamics); the fine NLGS tolerance from the first
    check below solver.tolerance_below."""
    import csv

    config, summary, out = settled
    with (out / simulation.TIMELINE_FILE).open(newline="") as f:
        reader = csv.DictReader(f)
        assert tuple(reader.fieldnames) == TIMELINE_COLUMNS
        rows = [{k: float(v) for k, v in row.items()} for row in reader]
    check_steps = round(config.equilibrium.check_interval / config.time_stepping.time_step)
    assert [int(r["step"]) for r in rows] == list(range(check_steps, summary["steps"] + 1, check_steps))
    assert rows[-1]["time"] == pytest.approx(summary["simulated_time"])
    start = next(k for k, r in enumerate(rows) if r["kinetic_criterion"] < config.end_game.damping_below)
    assert all(r["damped_energy"] == 0 for r in rows[: start + 1])
    assert sum(r["damped_energy"] for r in rows[start + 1:]) > 0
    assert summary["end_game"]["started"] and summary["end_game"]["kinetic_energy_removed"] == pytest.approx(
        sum(r["damped_energy"] for r in rows), rel=1e-6)
    fine = next(k for k, r in enumerate(rows) if r["kinetic_criterion"] < config.solver.tolerance_below)
    assert all(r["nlgs_tolerance"] == config.solver.settling_tolerance for r in rows[: fine + 1])
    assert all(r["nlgs_tolerance"] == config.solver.tolerance for r in rows[fine + 1:])
    assert rows[-1]["wall_seconds"] > 0 and rows[-1]["cpu_seconds"] > 0
    # the last check is the final state's: its overlaps, summed and largest, are those of final.gsd
    gaps = read_packing(out / "final.gsd").contacts.gap
    assert rows[-1]["overlap_sum"] == pytest.approx(float(np.clip(-gaps, 0, None).sum()), rel=1e-5)
    assert rows[-1]["max_overlap"] == pytest.approx(float(-gaps.min()), rel=1e-5) and rows[-1]["max_overlap"] > 0
    assert all(r["max_overlap"] <= r["overlap_sum"] <= r["max_overlap"] * r["contact_points"] for r in rows)


def test_timeline_energy_budget_has_no_source_but_the_corrections(settled):
    """Between two checks the total energy (kinetic_energy_total + the potential energy's change)
    rises by no more than the position correction added; the rest is what the contacts and the
    end game's damping took. Over the pour the contacts dissipate (a plastic pour of 100 spheres
    loses energy of order one m g d); the first row has no previous check (NaN). Tolerance: the
    six significant digits of the CSV."""
    import csv

    _, _, out = settled
    with (out / simulation.TIMELINE_FILE).open(newline="") as f:
        rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    assert math.isnan(rows[0]["potential_energy_change"])
    dissipated = 0.0
    for before, row in zip(rows, rows[1:]):
        kinetic_change = row["kinetic_energy_total"] - before["kinetic_energy_total"]
        gain = row["potential_energy_change"] + kinetic_change - row["correction_energy"] + row["damped_energy"]
        scale = max(before["kinetic_energy_total"], row["kinetic_energy_total"], abs(row["potential_energy_change"]))
        assert gain <= 1e-5 * scale + 1e-10
        dissipated -= gain
    assert dissipated > 1.0


def test_pour_corrects_positions_every_interval_steps_only(tmp_path):
    """overlap.pour_projection_interval = 5: while the alert distance is raised (grains falling fast)
    only every fifth step may be corrected, so 80 pinacoids poured for 4 sqrt(d/g) (800 steps, most
    of them fast) are corrected at far fewer steps than with an interval of 1 (measured 114 and 470
    with the slops of a correction that does all the work, 5e-4 and 1e-4 d, no recovery)."""
    corrected = {}
    for interval in (1, 5):
        config = load_config_dict({
            "seed": 2, "n_particles": 80, "lateral_size": 3.0,
            "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [1.0, 1.0], "volume_fraction": 1.0}],
            "equilibrium": {"max_time": 4.0}, "overlap": {"pour_projection_interval": interval, "projection_slop": 5e-4,
                        "pour_projection_slop": 1e-4, "recovery_rate": 0.0},
        })
        summary = run_packing(config, tmp_path / str(interval), progress=False)
        corrected[interval] = summary["position_correction"]["steps"]
    assert corrected[1] > 200
    assert 0 < corrected[5] < 0.5 * corrected[1]


def test_run_folder_holds_resolved_config_final_packing_and_summary(settled):
    config, summary, out = settled
    assert {p.name for p in out.iterdir()} == {"config.toml", "final.gsd", "summary.json", "timeline.csv"}  # checkpoint removed
    assert load_config(out / "config.toml") == config
    assert read_json(out / "summary.json") == to_jsonable(summary)
    packing = read_packing(out / "final.gsd")
    assert packing.n_particles == 100 and packing.metadata["status"] == STATUS_AT_REST
    assert packing.metadata["seed"] == 3 and packing.population_names == ["sphere-1"]
    state = packing.state
    assert np.all(state.position[:, :2] >= 0) and np.all(state.position[:, :2] < 3.0)
    assert np.all(state.position[:, 2] > 0.5 - 1e-4)  # on or above the wall
    # the stored contacts certify the same equilibrium again
    report = check_equilibrium(state, packing.contacts, packing.time_step)
    assert report.passed
    # settled, the pile is dense: 100 unit spheres (52.4 d^3) in a 9 d^2 cell would stand 10.6 d
    # tall at a solid fraction of 0.55; the deposited shells stood about twice as high
    assert np.max(state.position[:, 2]) < 10.6


@pytest.mark.filterwarnings("ignore::granpack.analysis.AnalysisWarning")  # spheres: no orientational order
def test_analysis_of_a_run(settled):
    _, _, out = settled
    result = analyze_run(out)
    assert result["n_particles"] == 100 and result["status"] == STATUS_AT_REST
    assert result["equilibrium"]["wall_force_over_weight"] == pytest.approx(1.0, abs=1e-4)
    # the 3 d cell is commensurate with unit spheres: the pile orders, but no packing of equal
    # spheres beats the FCC density pi / sqrt(18)
    assert 0.6 < result["solid_fraction"]["bulk"] < np.pi / np.sqrt(18.0) + 1e-3


def test_same_seed_same_packing_other_seed_other_packing(tmp_path):
    a = run_packing(sphere_config(n=30, max_time=1.0), tmp_path / "a", progress=False)
    b = run_packing(sphere_config(n=30, max_time=1.0), tmp_path / "b", progress=False)
    c = run_packing(sphere_config(n=30, max_time=1.0, seed=4), tmp_path / "c", progress=False)
    pa, pb, pc = (read_packing(tmp_path / k / "final.gsd").state.position for k in "abc")
    np.testing.assert_array_equal(pa, pb)
    assert not np.array_equal(pa, pc)
    assert a["status"] == b["status"] == c["status"] == STATUS_NOT_AT_REST  # 1 sqrt(d/g) is too short


class Killed(BaseException):
    """Stands for SIGKILL: nothing after it runs (not even ``except Exception`` handlers)."""


def killed_run(config, out, monkeypatch, at_solve):
    """Run ``config`` into ``out`` and kill it (:class:`Killed`) at its ``at_solve``-th solve,
    leaving the checkpoint a killed process leaves."""
    advance = settling.advance
    calls = {"n": 0}

    def dying_advance(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == at_solve:
            raise Killed
        return advance(*args, **kwargs)

    monkeypatch.setattr(settling, "advance", dying_advance)
    with pytest.raises(Killed):
        run_packing(config, out, progress=False)
    monkeypatch.setattr(settling, "advance", advance)


def test_killed_run_resumes_to_the_same_packing(tmp_path, monkeypatch):
    config = sphere_config(n=40, max_time=2.0)
    whole = run_packing(config, tmp_path / "whole", progress=False)

    out = tmp_path / "killed"
    killed_run(config, out, monkeypatch, at_solve=250)  # after the checkpoints of steps 100 and 200
    assert (out / "checkpoint.gsd").is_file() and not (out / "final.gsd").exists()
    assert read_packing(out / "checkpoint.gsd").metadata["counters"]["step"] == 200

    resumed = run_packing(config, out, resume=True, progress=False)
    a, b = read_packing(tmp_path / "whole" / "final.gsd"), read_packing(out / "final.gsd")
    for name in ("position", "quaternion", "velocity", "omega"):
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name))
    np.testing.assert_array_equal(a.contacts.impulse, b.contacts.impulse)
    assert resumed["steps"] == whole["steps"] and resumed["nlgs"] == whole["nlgs"]
    # the timeline reads as the uninterrupted run's (nan and inf kept through the checkpoint), clocks aside
    import csv

    def timeline(folder):
        with (folder / simulation.TIMELINE_FILE).open(newline="") as f:
            return [{k: v for k, v in row.items() if k not in ("wall_seconds", "cpu_seconds")} for row in csv.DictReader(f)]

    assert timeline(out) == timeline(tmp_path / "whole")
    assert "None" not in (out / simulation.TIMELINE_FILE).read_text()
    # resuming a finished run returns its summary without running again
    assert run_packing(config, out, resume=True, progress=False) == read_json(out / "summary.json")


def _timeline(folder):
    """The rows of a run's timeline.csv, clocks aside."""
    import csv

    with (folder / simulation.TIMELINE_FILE).open(newline="") as f:
        return [{k: v for k, v in row.items() if k not in ("wall_seconds", "cpu_seconds")} for row in csv.DictReader(f)]


def test_a_run_that_ended_not_at_rest_goes_on_to_the_longer_runs_packing(tmp_path, capsys):
    """40 spheres run to t = 1 end not at rest; resumed with ``equilibrium.max_time = 2`` they go
    on from their final state to the packing of a run made to t = 2 at once, bit for bit, with its
    timeline and solver figures; the analysis of the state at t = 1 is removed."""
    whole = run_packing(sphere_config(n=40, max_time=2.0), tmp_path / "whole", progress=False)
    out = tmp_path / "short"
    short = run_packing(sphere_config(n=40, max_time=1.0), out, progress=False)
    assert short["status"] == STATUS_NOT_AT_REST and short["steps"] < whole["steps"]
    analyze_run(out)
    assert (out / "analysis.json").is_file()

    longer = run_packing(sphere_config(n=40, max_time=2.0), out, resume=True, progress=True)
    err = capsys.readouterr().err
    assert "going on from its final state" in err and "removed final.gsd, summary.json, analysis.json" in err
    assert "with equilibrium.max_time = 2 (was 1)" in err
    a, b = read_packing(tmp_path / "whole" / "final.gsd"), read_packing(out / "final.gsd")
    for name in ("position", "quaternion", "velocity", "omega"):
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name))
    np.testing.assert_array_equal(a.contacts.impulse, b.contacts.impulse)
    assert longer["steps"] == whole["steps"] and longer["nlgs"] == whole["nlgs"]
    assert _timeline(out) == _timeline(tmp_path / "whole")
    assert not (out / "analysis.json").exists() and not (out / "checkpoint.gsd").exists()
    assert load_config(out / "config.toml").equilibrium.max_time == 2.0


def test_a_run_at_rest_given_a_later_cap_is_that_configs_run_too(settled, tmp_path, capsys):
    """The settled pile came to rest before t = 30: resumed with a cap of 60 it is returned as it
    is, its config.toml the one given (so that it is the same run from then on), nothing run."""
    import shutil

    config, summary, folder = settled
    rested = tmp_path / "rested"
    shutil.copytree(folder, rested)
    later = config.model_copy(update={"equilibrium": config.equilibrium.model_copy(update={"max_time": 60.0})})
    capsys.readouterr()
    assert run_packing(later, rested, resume=True) == read_json(folder / "summary.json")
    err = capsys.readouterr().err
    assert "holds a run that came to rest at t = " in err and "it is this config's run too" in err
    assert (rested / "config.toml").read_text() == later.to_toml()
    assert (rested / "final.gsd").read_bytes() == (folder / "final.gsd").read_bytes()
    assert simulation.carries_on(rested, later) and simulation.carries_on(folder, later)


def test_a_run_goes_on_only_where_it_ended_short_of_rest_and_the_cap_is_raised(settled, tmp_path, capsys):
    """Refused in one line, the folder untouched: a run at rest given a finer tolerance, or a cap
    before its end; a run that ended not at rest given only a finer tolerance (its cap not beyond
    its end), or another setting beside a raised cap, or whose final state was written without the
    run's record."""
    import shutil

    from granpack.io.gsd import write_packing

    config, summary, folder = settled
    rested = tmp_path / "rested"
    shutil.copytree(folder, rested)
    short = tmp_path / "short"
    run_packing(sphere_config(n=20, max_time=0.5), short, progress=False)
    old = tmp_path / "old"
    shutil.copytree(short, old)
    saved = read_packing(old / "final.gsd")
    write_packing(old / "final.gsd", replace(saved, metadata={k: v for k, v in saved.metadata.items() if k != "counters"}))

    def refused(folder, given, *expected):
        path = _write(tmp_path / "given.toml", given)
        before = {p.name: p.read_bytes() for p in folder.iterdir()}
        with pytest.raises(SystemExit) as info:
            main(["run", str(path), "--out", str(folder), "--resume"])
        err = capsys.readouterr().err
        assert info.value.code == 2 and err.count("\n") == 1 and err.startswith("error: "), err
        for text in expected:
            assert text in err, err
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before

    def finer(config):
        return config.model_copy(update={"solver": config.solver.model_copy(update={"tolerance": 1e-5})})

    refused(rested, finer(config), "holds a run that came to rest at t = ",
            "which is not the run of solver.tolerance = 1e-05 (was 0.0001)")
    end = summary["simulated_time"]
    refused(rested, config.model_copy(update={"equilibrium": config.equilibrium.model_copy(update={"max_time": end - 1})}),
            "holds a run that came to rest at t = ", f"which is not the run of equilibrium.max_time = {end - 1:g} (was 30)")
    refused(short, finer(sphere_config(n=20, max_time=0.5)),
            "equilibrium.max_time = 0.5: the run in", "ended not at rest at t = 0.5 sqrt(d/g); set it beyond")
    assert not simulation.carries_on(short, finer(sphere_config(n=20, max_time=0.5)))
    assert simulation.carries_on(short, finer(sphere_config(n=20, max_time=0.75)))
    refused(short, sphere_config(n=20, max_time=1.0, seed=4), "holds a finished run of another config",
            "seed = 3 in")
    refused(old, sphere_config(n=20, max_time=1.0), "holds no run record to go on from")


def test_a_checkpoint_resumes_with_a_finer_tolerance(tmp_path, monkeypatch, capsys):
    """A killed run resumed with ``solver.tolerance = 1e-5`` goes on from its checkpoint under it
    and says so; its resolved config is the one given."""
    config = sphere_config(n=20, max_time=1.0)
    killed_run(config, tmp_path, monkeypatch, at_solve=150)
    finer = config.model_copy(update={"solver": config.solver.model_copy(update={"tolerance": 1e-5})})
    capsys.readouterr()
    summary = run_packing(finer, tmp_path, resume=True)
    err = capsys.readouterr().err
    assert "resuming from t = 0.5 sqrt(d/g) (step 100)" in err and "with solver.tolerance = 1e-05 (was 0.0001)" in err
    assert load_config(tmp_path / "config.toml").solver.tolerance == 1e-5
    assert summary["simulated_time"] == pytest.approx(1.0)


def test_a_checkpoint_resumed_with_its_own_time_as_the_cap_ends_there_and_an_earlier_cap_is_refused(
        tmp_path, monkeypatch, capsys):
    """A killed run (checkpoint at t = 0.5) resumed with ``equilibrium.max_time = 0.25`` is refused
    in one line, the folder unchanged; with 0.5 it ends at the checkpoint, not at rest, its final
    state the checkpoint's."""
    config = sphere_config(n=20, max_time=1.0)
    killed_run(config, tmp_path, monkeypatch, at_solve=150)
    checkpoint = read_packing(tmp_path / "checkpoint.gsd")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}

    def capped(max_time):
        return config.model_copy(update={"equilibrium": config.equilibrium.model_copy(update={"max_time": max_time})})

    with pytest.raises(InputError, match=r"equilibrium.max_time = 0.25: the checkpoint in .* is at t = 0.5 sqrt"):
        run_packing(capped(0.25), tmp_path, resume=True, progress=False)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before

    summary = run_packing(capped(0.5), tmp_path, resume=True, progress=False)
    assert summary["status"] == STATUS_NOT_AT_REST and summary["steps"] == 100
    assert summary["simulated_time"] == pytest.approx(0.5)
    final = read_packing(tmp_path / "final.gsd")
    np.testing.assert_array_equal(final.state.position, checkpoint.state.position)
    assert not (tmp_path / "checkpoint.gsd").exists()


@pytest.mark.parametrize("missing", [("overlap_sum",), ("overlap_sum", "potential_energy_change")])
def test_a_checkpoint_written_before_the_newer_timeline_columns_resumes(tmp_path, monkeypatch, missing):
    """A checkpoint whose timeline rows lack ``overlap_sum`` (and, older still,
    ``potential_energy_change`` and its running total) resumes: those rows get NaN for what they
    lack, and so does the first row after them for the potential energy's change (it has no
    previous total); later rows have both."""
    import csv

    from granpack.io.gsd import write_packing

    config = sphere_config(n=40, max_time=2.0)
    killed_run(config, tmp_path, monkeypatch, at_solve=250)
    saved = read_packing(tmp_path / "checkpoint.gsd")
    counters = dict(saved.metadata["counters"])
    gone = {TIMELINE_COLUMNS.index(name) for name in missing}
    if "potential_energy_change" in missing:
        gone.add(len(TIMELINE_COLUMNS) + 7)  # its running total, the last of the row
    counters["timeline"] = [[v for k, v in enumerate(row) if k not in gone] for row in counters["timeline"]]
    old_rows = len(counters["timeline"])
    assert old_rows > 0
    write_packing(tmp_path / "checkpoint.gsd", replace(saved, metadata={**saved.metadata, "counters": counters}))

    run_packing(config, tmp_path, resume=True, progress=False)
    with (tmp_path / simulation.TIMELINE_FILE).open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) > old_rows + 1
    sums = [float(row["overlap_sum"]) for row in rows]
    assert all(math.isnan(v) for v in sums[:old_rows]) and all(v >= float(row["max_overlap"]) for v, row in
                                                                 zip(sums[old_rows:], rows[old_rows:]))
    changes = [float(row["potential_energy_change"]) for row in rows]
    first_known = old_rows + 1 if "potential_energy_change" in missing else 1
    assert all(math.isnan(v) for v in changes[:first_known]) and not any(math.isnan(v) for v in changes[first_known:])


def test_resume_refuses_a_checkpoint_of_another_config(tmp_path, monkeypatch, capsys):
    """The refusal names each setting that differs, its value in the checkpoint and in the file
    given, and the file to resume with."""
    config = sphere_config(n=20, max_time=1.0)
    killed_run(config, tmp_path, monkeypatch, at_solve=150)
    other = _write(tmp_path.parent / f"{tmp_path.name}-other.toml", sphere_config(n=20, max_time=1.5, seed=9))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    with pytest.raises(SystemExit) as info:
        main(["run", str(other), "--out", str(tmp_path), "--resume"])
    assert info.value.code == 2
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # nothing touched
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert f"seed = 3 in the checkpoint (and {tmp_path / 'config.toml'}), 9 in {other}" in err
    assert f"equilibrium.max_time = 1.0 in the checkpoint (and {tmp_path / 'config.toml'}), 1.5 in {other}" in err
    assert f"resume with {tmp_path / 'config.toml'}" in err
    # the same file with --seed: that is where the seed came from
    with pytest.raises(SystemExit):
        main(["run", str(other), "--out", str(tmp_path), "--resume", "--seed", "4"])
    assert f", 4 in {other} with --seed 4" in capsys.readouterr().err


def _write(path, config):
    path.write_text(config.to_toml())
    return path


def test_snapshots_make_a_trajectory(tmp_path):
    from gsd.hoomd import open as gsd_open

    run_packing(sphere_config(n=20, max_time=1.0, snapshot_interval=0.25), tmp_path, progress=False)
    with gsd_open(tmp_path / "trajectory.gsd") as traj:
        assert [int(f.configuration.step) for f in traj] == [50, 100, 150, 200]
        assert traj[0].particles.type_shapes == [{"type": "Sphere", "diameter": 1.0}]


def test_pinacoids_pour_without_deep_overlaps(tmp_path):
    """A short pour of 30 pinacoids: grains fall into contact with overlaps kept below 2e-3 d while
    they are still moving fast (docs/method/nscd.md#contact-law: the velocity-level law lets them creep; the
    position correction removes them as the pile slows down)."""
    config = load_config_dict({
        "seed": 5, "n_particles": 30, "lateral_size": 3.0,
        "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [1.0, 1.0], "volume_fraction": 1.0}],
        "equilibrium": {"max_time": 3.0},
        "deposit": {"method": "lmgc", "lateral": "periodic"},
    })
    summary = run_packing(config, tmp_path, progress=False)
    assert summary["status"] == STATUS_NOT_AT_REST
    assert summary["final"]["contacts"] > 30 and summary["final"]["max_overlap"] < 2e-3
    packing = read_packing(tmp_path / "final.gsd")
    assert packing.state.shapes.shapes[0].gsd_shape()["type"] == "ConvexPolyhedron"
    assert np.all(packing.state.position[:, 2] > 0.0)


def test_cli_run_with_seed_and_bad_inputs(tmp_path, capsys):
    config = _write(tmp_path / "c.toml", sphere_config(n=10, max_time=0.5))
    with pytest.raises(SystemExit) as info:
        main(["run", str(config), "--out", str(tmp_path / "r"), "--seed", "8"])
    assert info.value.code == 0
    printed = capsys.readouterr().out
    assert "not at rest after 0.50" in printed and "criteria not met at the end: " in printed
    assert (f"to go on, raise its equilibrium.max_time and run: granpack run {config} --out {tmp_path / 'r'} --seed 8 "
            "--resume") in printed
    assert load_config(tmp_path / "r" / "config.toml").seed == 8
    for argv in (["run", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "x")],
                 ["run", str(config), "--out", str(tmp_path / "y"), "--seed", "-1"]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_demo_config_is_the_example():
    packaged = files("granpack").joinpath("data/demo.toml").read_text(encoding="utf-8")
    example = (Path(__file__).parents[1] / "examples" / "demo.toml").read_text(encoding="utf-8")
    assert packaged == example


def test_narrowest_allowed_cell_runs(tmp_path):
    """The config allows L just above 2 (d + alert); the Verlet skin and the raised alert distance
    must then fit in what is left (one periodic image per pair)."""
    config = load_config_dict({
        "n_particles": 8, "lateral_size": 2.05,
        "populations": [{"shape": "sphere", "size": 1.0, "volume_fraction": 1.0}],
        "equilibrium": {"max_time": 1.0},
    })
    summary = run_packing(config, tmp_path, progress=False)
    assert summary["steps"] == 200 and summary["final"]["max_overlap"] < 1e-4


@pytest.mark.filterwarnings("ignore::granpack.analysis.AnalysisWarning")  # 40 grains have no bulk region
def test_demo_command_pours_settles_and_analyses(tmp_path, monkeypatch, capsys):
    """``granpack demo`` wiring, on a shrunken demo config (the real one takes minutes)."""
    import granpack.cli as cli

    small = load_config_dict({**cli.demo_config().model_dump(), "n_particles": 40, "equilibrium": {"max_time": 2.0}})
    monkeypatch.setattr(cli, "demo_config", lambda: small)
    with pytest.raises(SystemExit) as info:
        main(["demo", "--out", str(tmp_path / "demo")])
    assert info.value.code == 0
    printed = capsys.readouterr().out
    assert "granpack demo: 40 isometric pinacoids" in printed and "solid fraction (bulk)" in printed
    assert {"config.toml", "final.gsd", "summary.json", "analysis.json"} <= {p.name for p in (tmp_path / "demo").iterdir()}
    assert read_json(tmp_path / "demo" / "analysis.json")["n_particles"] == 40


def test_packaged_demo_config_is_valid():
    import granpack.cli as cli

    config = cli.demo_config()
    assert config.n_particles == 300 and config.lateral_size == 3.0 and config.populations[0].shape == "pinacoid"


def test_step_alert_splits_the_step_when_the_cell_cannot_hold_the_alert():
    config = sphere_config(n=2)
    state, _ = simulation.initial_state(config)
    state.velocity[:] = 0.0
    state.velocity[0, 2] = -10.0  # closing distance 1.5 (2 h 10 + h^2) = 0.15004 d per step of 5e-3
    assert step_policy.step_alert(state, 0.02, 5e-3, 1.0) == (0.16, 1)  # 0.02 x 2^3 covers it
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.06) == (0.06, 3)  # 0.15004 / 3 fits 0.06
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.05) == (0.04, 4)  # / 3 does not fit 0.05
    state.velocity[0, 2] = 0.0
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.05) == (0.02, 1)


def test_step_alert_splits_the_step_of_a_fast_spinning_polyhedron_in_reach_of_something_but_not_of_a_sphere():
    pinacoid = load_config_dict({
        "n_particles": 2, "lateral_size": 4.0,
        "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [2.0, 3.0], "volume_fraction": 1.0}],
    })
    state, _ = simulation.initial_state(pinacoid)
    state.velocity[:] = 0.0
    state.omega[:] = 0.0
    state.omega[1] = [0.0, 30.0, 40.0]  # |ω| h = 0.25 rad per step of 5e-3
    radius = state.radius[0]
    state.position[0] = [1.0, 1.0, 3.0]
    state.position[1] = [1.0, 1.0 + 2 * radius + 0.3, 3.0]  # circumscribed spheres 0.3 d apart
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.5, max_rotation=0.05)[1] == 5
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.5)[1] == 1  # no bound on the turn
    # in free flight: 0.8 d is more than the largest alert (0.5) plus what the pair can close in
    # the step (1.5 x 5e-3 x (R |ω| + 2 h) = 0.19 for R = 0.5), so the turn cannot touch anything
    state.position[1] = [1.0, 1.0 + 2 * radius + 0.8, 3.0]
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.5, max_rotation=0.05)[1] == 1
    state.position[1] = [3.0, 3.0, radius + 0.6]  # far from the other grain, within reach of the wall
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.5, max_rotation=0.05)[1] == 5
    state.position[1, 2] = 2.0  # in free flight
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.5, max_rotation=0.05)[1] == 1
    state.position[1] = [1.0, 1.0 + 2 * radius + 0.3, 3.0]
    state.omega[1] = [0.0, 0.0, 17.0]  # 0.085 rad per step: two substeps for R = d/2 ...
    assert step_policy.step_alert(state, 0.02, 5e-3, 0.5, max_rotation=0.05)[1] == 2
    small = replace(state, shapes=Mixture.from_config(load_config_dict({
        "n_particles": 2, "lateral_size": 4.0,
        "populations": [{"shape": "pinacoid", "size": 1 / 3, "aspect": [2.0, 3.0], "volume_fraction": 1.0}],
    })).particle_shape_table())
    assert small.radius[1] == pytest.approx(1 / 6)
    # ... one for R = d/6: 0.085 sqrt(1/3) = 0.049 rad scaled, the same surface deviation as 0.049 rad at d/2
    assert step_policy.step_alert(small, 0.02, 5e-3, 0.5, max_rotation=0.05)[1] == 1
    spheres, _ = simulation.initial_state(sphere_config(n=2))
    spheres.velocity[:] = 0.0
    spheres.omega[0] = [0.0, 30.0, 40.0]  # a sphere's gaps do not depend on its rotation
    assert step_policy.step_alert(spheres, 0.02, 5e-3, 10.0, max_rotation=0.05)[1] == 1


@pytest.mark.parametrize("max_rotation, deepest", [(0.05, 1e-4), (np.inf, None)])
def test_a_plate_spinning_onto_another_does_not_sink_into_it_when_its_steps_are_split(max_rotation, deepest):
    """A flat & elongated pinacoid (thickness 0.15 d) lying on the floor, a second one above it
    spinning at 57 rad/sqrt(d/g) about a horizontal axis (0.28 rad per step of 5e-3): in whole
    steps it turns into the lower one 1.7e-2 d deep (the gaps are held linearised in the
    velocities); split by :func:`step_policy.step_alert` to 0.05 rad, not at all (measured 0)."""
    from dataclasses import replace

    from granpack import Box, ShapeTable
    from granpack.contact import Detector
    from granpack.nscd.integrator import StepParameters, step
    from granpack.shapes import Pinacoid
    from granpack.state import ParticleState

    plate = Pinacoid.from_size(1.0, 2, 3)
    half = float(plate.vertices[:, 2].max())  # half thickness, lying flat
    width = float(plate.vertices[:, 1].max())
    state = ParticleState(box=Box.square(6.0), shapes=ShapeTable.from_shapes([plate]), kind=np.zeros(2, int),
                          population=np.zeros(2, int), position=[[3.0, 3.0, half], [3.0, 3.0, 2 * half + width + 0.05]],
                          quaternion=[[1.0, 0.0, 0.0, 0.0]] * 2)
    state.omega[1] = [40.0, 40.0, 0.0]
    params = StepParameters(time_step=5e-3)
    warm, sinks = None, 0.0
    for _ in range(200):
        alert, substeps = step_policy.step_alert(state, params.alert, 5e-3, 2.0, max_rotation)
        for _ in range(substeps):
            warm, _ = step(state, replace(params, alert=alert, time_step=5e-3 / substeps), warm)
        exact = Detector().detect(state, 0.0)
        pair = np.repeat(exact.body_j >= 0, np.diff(exact.point_start))
        sinks = max(sinks, -exact.gap[pair].min(initial=0.0))
    if deepest is None:
        assert sinks > 5e-3
    else:
        assert sinks < deepest


def test_thin_grains_poured_into_a_narrow_cell_do_not_pass_through_each_other(tmp_path):
    # flat & elongated pinacoids (thickness 0.15 d) in a 2.25 d cell: the alert distance can grow
    # to 0.1 d at most, short of what a pour needs, so steps are split; without that, grains met
    # already interpenetrating by up to the missing distance and some passed through others
    config = load_config_dict({
        "seed": 2, "n_particles": 80, "lateral_size": 2.25,
        "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [2.0, 3.0], "volume_fraction": 1.0}],
        "equilibrium": {"max_time": 6.0},
    })
    summary = run_packing(config, tmp_path, progress=False)
    assert summary["split_steps"] > 0
    assert summary["nlgs"]["solves"] > summary["steps"]
    # a grain passing through a plate (thickness 0.15 d) overlaps it by half that on the way.
    # Measured: 7.4e-3 d at worst during the run (one impact); at the end, while the pile still
    # moves, max 1.7e-3 d and mean 1.2e-4 d (overlaps above overlap.recovery_slop = 5e-4 d are
    # pushed back at a bounded speed, those above overlap.projection_slop = 2e-3 d also projected out)
    assert summary["max_overlap_during_run"] < 0.05
    final_gaps = read_packing(tmp_path / "final.gsd").contacts.gap
    assert summary["final"]["max_overlap"] < 5e-3
    assert -final_gaps[final_gaps < 0].mean() < 3e-4
    # the stored impulses are those of the last (sub)step: its length goes with them
    k = 5e-3 / read_packing(tmp_path / "final.gsd").time_step
    assert k == pytest.approx(round(k)) and round(k) >= 1


@pytest.mark.parametrize("slop", [None, 1e-4, 5e-3])
def test_overlap_slop_bounds_the_overlaps_of_a_settling_pinacoid_pile(tmp_path, slop):
    # 60 isometric pinacoids poured and settled for 12 sqrt(d/g). Default: every overlap of the final
    # contacts below the projection's slop (2e-3 d) and all but a few below the recovery slop
    # (5e-4 d), which pushes deeper ones back at a bounded speed while the pile still moves
    # (measured: 3 points of 561 at 5.2-5.6e-4 d, mean overlap 3e-5 d). A slop of 1e-4 d (the
    # pour's slop throughout): every overlap below it. A slop of 5e-3 d: the same pile keeps the
    # overlaps made while it settles, above 3e-4 d
    raw = {"seed": 4, "n_particles": 60, "lateral_size": 2.25, "equilibrium": {"max_time": 12.0},
           "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [1.0, 1.0], "volume_fraction": 1.0}]}
    if slop is not None:
        raw["overlap"] = {"projection_slop": slop}
    summary = run_packing(load_config_dict(raw), tmp_path, progress=False)
    gaps = read_packing(tmp_path / "final.gsd").contacts.gap
    assert len(gaps) > 300 and summary["final"]["max_overlap"] == pytest.approx(max(0.0, -gaps.min()))
    if slop is None:
        assert summary["final"]["max_overlap"] < 2e-3
        assert np.count_nonzero(gaps < -5e-4) <= 0.01 * len(gaps) and -gaps[gaps < 0].mean() < 1e-4
    elif slop == 1e-4:
        assert summary["final"]["max_overlap"] < 1e-4
    else:
        assert summary["final"]["max_overlap"] > 3e-4


def test_step_reach_gives_a_struck_grain_the_reach_of_the_grain_that_strikes_it():
    """Grain 0 falls at 4 sqrt(g d) onto grain 1, at rest and in contact with it; grain 2, far
    away, rests: 0 and 1 get 1.5 (h 4 + h^2 / 2), 2 keeps base / 2 (no contacts given: 1 keeps it too)."""
    from granpack import Box, ShapeTable, Sphere
    from granpack.contact import ContactSet
    from granpack.state import ParticleState

    centres = np.array([[1.0, 1.0, 2.5], [1.0, 1.0, 1.5], [4.0, 4.0, 0.5]])
    state = ParticleState(box=Box.square(6.0), shapes=ShapeTable.from_shapes([Sphere(1.0)]), kind=np.zeros(3, int),
                          population=np.zeros(3, int), position=centres, quaternion=np.tile([1.0, 0, 0, 0], (3, 1)),
                          velocity=np.array([[0, 0, -4.0], [0, 0, 0], [0, 0, 0]]))
    touching = ContactSet(body_i=np.array([1, 2]), body_j=np.array([0, -1]), shift=np.zeros((2, 3)),
                          normal=np.array([[0, 0, -1.0], [0, 0, 1.0]]), ctype=np.ones(2, int),
                          point_start=np.array([0, 1, 2]), point=np.array([[1.0, 1.0, 2.0], [4.0, 4.0, 0.0]]),
                          gap=np.zeros(2))
    h, base = 5e-3, 0.02
    fast = 1.5 * (h * 4.0 + 0.5 * h * h)
    np.testing.assert_allclose(step_policy.step_reach(state, base, h, 1, touching), [fast, fast, base / 2])
    np.testing.assert_allclose(step_policy.step_reach(state, base, h, 1), [fast, base / 2, base / 2])


def test_shake_adds_the_speed_in_a_random_direction_reproducibly():
    state = simulation.initial_state(sphere_config(n=30))[0]
    state.velocity[:] = 0.0
    settling.shake(state, 1e-3, np.random.default_rng([3, 0]))
    np.testing.assert_allclose(np.linalg.norm(state.velocity, axis=1), 1e-3, rtol=1e-12)
    assert abs(state.velocity.mean(axis=0)).max() < 5e-4  # directions spread over the sphere
    again = simulation.initial_state(sphere_config(n=30))[0]
    again.velocity[:] = 0.0
    settling.shake(again, 1e-3, np.random.default_rng([3, 0]))
    np.testing.assert_array_equal(state.velocity, again.velocity)


def test_shake_is_due_near_rest_at_most_once_per_interval():
    config = settling.settling_policy(load_config_dict({**sphere_config().model_dump(), "end_game": {"shake_speed": 1e-3}}))
    report = type("Report", (), {"kinetic_energy": 1e-9, "passed": False})()
    quiet = RunRecord(milestones=Milestones(near_rest=True))
    assert settling.shake_due(config, quiet, report, 40.0)
    assert not settling.shake_due(settling.settling_policy(sphere_config()), quiet, report, 40.0)  # shake_speed 0: never
    assert not settling.shake_due(config, RunRecord(milestones=Milestones(near_rest=False)), report, 40.0)
    assert not settling.shake_due(config, quiet, type("Report", (), {"kinetic_energy": 1e-6, "passed": False})(), 40.0)
    # a pile that meets the criteria is counting its window: no shake
    assert not settling.shake_due(config, quiet, type("Report", (), {"kinetic_energy": 1e-9, "passed": True})(), 40.0)
    shaken = RunRecord(milestones=Milestones(near_rest=True, last_shake=38.0))
    assert not settling.shake_due(config, shaken, report, 40.0)
    assert settling.shake_due(config, shaken, report, 43.0)


def test_a_shaken_pile_comes_back_to_certified_rest(tmp_path):
    """The shake is given (the summary counts it) and the pile still ends at certified rest. (This
    small pile goes from moving to passing the criteria within one check interval, so the shake is
    asked for below a higher kinetic criterion.)"""
    config = load_config_dict({**sphere_config().model_dump(), "end_game": {"shake_speed": 1e-3, "shake_below": 1e-4}})
    summary = run_packing(config, tmp_path / "shaken", progress=False)
    assert summary["end_game"]["shakes"] >= 1
    assert summary["status"] == STATUS_AT_REST and summary["equilibrium"]["kinetic_energy"] < 1e-8


def test_the_deposit_order_is_recorded_before_gravity_acts(tmp_path):
    """summary.json carries the Q00 / Q22 of the deposit: 1 for grains all aligned, near the
    isotropic baseline for the drop's random orientations, nan for spheres."""
    from granpack.analysis.order import isotropic_baseline

    config = load_config_dict({"n_particles": 60, "lateral_size": 3.0, "seed": 4, "equilibrium": {"max_time": 0.05},
                               "populations": [{"shape": "pinacoid", "size": 1.0, "aspect": [2.0, 1.0],
                                                "volume_fraction": 1.0}]})
    state, _ = simulation.initial_state(config)
    mean, std, _, _ = isotropic_baseline(state.n)
    assert abs(simulation.deposit_order(state)["Q00"] - mean) < 5 * std
    aligned = replace(state, quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (state.n, 1)))
    assert simulation.deposit_order(aligned) == pytest.approx({"Q00": 1.0, "Q22": 1.0})
    summary = run_packing(config, tmp_path / "run", progress=False)
    assert summary["initial_order"] == pytest.approx(simulation.deposit_order(state))
    spheres = run_packing(sphere_config(n=20, max_time=0.05), tmp_path / "spheres", progress=False)
    assert math.isnan(spheres["initial_order"]["Q00"])


def test_a_checkpoint_whose_config_comments_differ_resumes(tmp_path, monkeypatch):
    """A checkpoint written by a version whose key descriptions read otherwise resumes (the
    settings decide, not the comments); one of other settings is still refused."""
    from granpack.io.gsd import write_packing

    config = sphere_config(n=40, max_time=2.0)
    killed_run(config, tmp_path, monkeypatch, at_solve=250)
    saved = read_packing(tmp_path / "checkpoint.gsd")
    reworded = saved.metadata["config"].replace("# Time step h", "# The time step h")
    assert reworded != saved.metadata["config"]
    write_packing(tmp_path / "checkpoint.gsd", replace(saved, metadata={**saved.metadata, "config": reworded}))
    assert run_packing(config, tmp_path, resume=True, progress=False)["steps"] > 0


def test_the_settling_policy_takes_each_of_its_settings_from_the_config():
    """The loop reads its settings from one object built once (settling.settling_policy), each
    field from its own key: a config that changes every one of them changes every field."""
    changed = load_config_dict({**sphere_config().model_dump(), "seed": 9,
                                "time_stepping": {"max_rotation": 0.1},
                                "solver": {"settling_tolerance": 2e-3, "tolerance_below": 2e-5},
                                "overlap": {"pour_projection_slop": 3e-3, "pour_projection_interval": 7,
                                            "rest_recovery_slop": 6e-5, "rest_recovery_speed": 1e-3,
                                            "recovery_near_rest": False},
                                "end_game": {"mode": "none", "damping_rate": 2.0, "damping_below": 2e-3,
                                             "shake_speed": 1e-3, "shake_below": 2e-7, "shake_interval": 6.0},
                                "equilibrium": {"max_time": 50.0, "check_interval": 0.5, "window": 3}})
    default, policy = settling.settling_policy(sphere_config()), settling.settling_policy(changed)
    differing = {name for name in type(policy).__dataclass_fields__ if getattr(policy, name) != getattr(default, name)}
    assert differing == set(type(policy).__dataclass_fields__)
    assert (policy.max_steps, policy.check_every, policy.window, policy.damping) == (10_000, 100, 3, False)
    assert settling.steps_of(0.25, 5e-3) == 50 and settling.steps_of(1e-4, 5e-3) == 1

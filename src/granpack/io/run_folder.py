"""The rules of a run folder: which files make it hold a run, and who may write there.

The names of the files granpack writes into a run folder and into a campaign folder are declared
here, once; every other module takes them from here.

A folder holds a run when it has any of :data:`RUN_FILES`; a run goes on there only when told
(resume), replaces it only when told (overwrite), and never replaces a ``config.toml`` that is
not a granpack run's own. A campaign's folder (:data:`CAMPAIGN_FILES`) takes no run.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from granpack.errors import InputError
from granpack.io.atomic import output_folder
from granpack.io.gsd import read_packing

__all__ = ["CONFIG_FILE", "CHECKPOINT_FILE", "FINAL_FILE", "CONTAINER_FILE", "SUMMARY_FILE", "TRAJECTORY_FILE",
           "TIMELINE_FILE", "PROGRESS_FILE", "ANALYSIS_FILE", "PICTURE_FILE", "CAMPAIGN_SPEC_FILE", "RUNS_TABLE", "RUNS_PARQUET",
           "SUMMARY_TABLE", "RUN_FILES", "CAMPAIGN_FILES", "RUN_FOLDERS", "DERIVED_FILES", "is_resolved_config",
           "checkpoint_when", "config_differences", "changed_settings", "clear_run", "claim_folder"]

CONFIG_FILE = "config.toml"
CHECKPOINT_FILE = "checkpoint.gsd"
FINAL_FILE = "final.gsd"
#: the inside surface of a box or a cylinder in ``final.gsd``'s frame, for OVITO (:mod:`granpack.io.container`)
CONTAINER_FILE = "container.stl"
SUMMARY_FILE = "summary.json"
TRAJECTORY_FILE = "trajectory.gsd"
TIMELINE_FILE = "timeline.csv"
#: the progress lines and notes of a run with ``progress="log"`` (a campaign's runs), appended
PROGRESS_FILE = "progress.log"
#: the analysis of a run (``granpack analyze``, :func:`granpack.analysis.report.analyze_run`)
ANALYSIS_FILE = "analysis.json"
#: the rendered picture of a run's final state (``granpack export --format png``)
PICTURE_FILE = "packing.png"

#: a campaign folder's copy of the campaign file it was run from
CAMPAIGN_SPEC_FILE = "campaign.toml"
#: a campaign folder's table of its runs, as CSV and as Parquet (:mod:`granpack.campaign.store`)
RUNS_TABLE = "runs.csv"
RUNS_PARQUET = "runs.parquet"
#: a campaign folder's table of its mixtures (means and deviations over the replicas)
SUMMARY_TABLE = "summary.csv"

#: files of a run folder that make it "hold a run" (see :func:`claim_folder`): the run's own
#: outputs, then what ``granpack analyze`` and ``granpack export --format png`` add
RUN_FILES = (FINAL_FILE, SUMMARY_FILE, CHECKPOINT_FILE, TRAJECTORY_FILE, TIMELINE_FILE, PROGRESS_FILE, ANALYSIS_FILE,
             PICTURE_FILE, CONTAINER_FILE)
#: files that make a folder a campaign's (``granpack campaign`` writes them): no run goes there
CAMPAIGN_FILES = (CAMPAIGN_SPEC_FILE, RUNS_TABLE, SUMMARY_TABLE)
#: sub-folders of a run folder written by ``granpack figures`` and ``granpack export``, and the
#: suffixes of the files granpack writes there (``overwrite`` removes those, never other files)
RUN_FOLDERS = {"figures": (".png", ".svg"), "vtk": (".vtu",), "surfaces": (".stl", ".obj", ".ply")}
#: the files made from a run's final state (with those of :data:`RUN_FOLDERS`): stale once it goes on
DERIVED_FILES = (ANALYSIS_FILE, PICTURE_FILE)


def is_resolved_config(path: Path, config_text: str) -> bool:
    """Whether ``path`` is a resolved config as granpack writes it (this run's or another's, of
    this version or an older one: it starts with the header line of :meth:`RunConfig.to_toml`)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    header = config_text.partition("\n")[0]
    if text == config_text or (header.startswith("#") and text.startswith(header + "\n")):
        return True
    from granpack.config import load_config

    try:
        return load_config(path).to_toml() == text
    except InputError:
        return False


def _flat_settings(text: str) -> dict[str, object]:
    """``{"equilibrium.max_time": 80.0, "populations[0].size": 1.0, ...}`` of a TOML text (empty
    if it does not parse)."""
    import tomllib

    try:
        data = tomllib.loads(text or "")
    except tomllib.TOMLDecodeError:
        return {}
    flat: dict[str, object] = {}

    def walk(key: str, value) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                walk(f"{key}.{k}" if key else k, v)
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for i, v in enumerate(value):
                walk(f"{key}[{i}]", v)
        else:
            flat[key] = value

    walk("", data)
    return flat


def config_differences(run_text: str, given_text: str, run_name: str, given_name: str, limit: int = 3) -> str:
    """The settings in which two resolved configs differ, for a message:
    ``equilibrium.max_time = 80.0 in RUN_NAME, 100.0 in GIVEN_NAME`` (at most ``limit`` of them,
    then how many more)."""
    import json

    def shown(value) -> str:
        return "absent" if value is None else json.dumps(value)

    changed = changed_settings(run_text, given_text)
    if not changed:
        return f"the settings of {run_name} and {given_name} are written otherwise"
    parts = [f"{k} = {shown(old)} in {run_name}, {shown(new)} in {given_name}" for k, (old, new) in list(changed.items())[:limit]]
    more = f" (and {len(changed) - limit} more setting(s))" if len(changed) > limit else ""
    return "; ".join(parts) + more


def changed_settings(run_text: str, given_text: str) -> dict[str, tuple]:
    """The settings in which two resolved configs differ, ``{"equilibrium.max_time": (300.0,
    400.0), ...}``: the value in ``run_text``, then in ``given_text`` (None where absent)."""
    run, given = _flat_settings(run_text), _flat_settings(given_text)
    return {k: (run.get(k), given.get(k)) for k in dict.fromkeys([*run, *given]) if run.get(k) != given.get(k)}


def checkpoint_when(path: Path) -> str:
    """`` at t = ... (step ...)`` of a checkpoint, or nothing if it cannot be read."""
    try:
        meta = read_packing(path).metadata
        return f" at t = {float(meta['time']):.6g} sqrt(d/g) (step {int(meta['step'])})"
    except (InputError, KeyError, TypeError, ValueError, OSError):
        return ""


def clear_run(out_dir: Path, files: tuple[str, ...] = RUN_FILES) -> list[str]:
    """Remove the run in ``out_dir`` (:data:`RUN_FILES`, granpack's files in :data:`RUN_FOLDERS`),
    or with ``files`` = :data:`DERIVED_FILES` what was made from its final state; a sub-folder goes
    too when nothing else is left in it. Returns what was removed."""
    removed = []
    for name in files:
        if (out_dir / name).is_file():
            (out_dir / name).unlink()
            removed.append(name)
    for folder, suffixes in RUN_FOLDERS.items():
        path = out_dir / folder
        if not path.is_dir():
            continue
        ours = [p for p in path.iterdir() if p.is_file() and p.suffix in suffixes]
        for p in ours:
            p.unlink()
        if ours:
            removed.append(f"{folder}/")
        if not any(path.iterdir()):
            path.rmdir()
    return removed


def claim_folder(out_dir: Path, config_text: str, *, resume: bool, overwrite: bool, note: Callable[[str], None],
                 source: str | None = None) -> bool:
    """Check ``out_dir`` for a run of the resolved config ``config_text`` and create it; clear it
    with ``overwrite``; ``note`` takes the one-line notes (resuming, overwriting); ``source`` names
    where the config came from in messages (a file name).

    Returns:
        True if ``resume`` finds a finished run of this config (returned as it is).

    Raises:
        InputError: ``resume`` and ``overwrite`` both; a campaign's folder; a ``config.toml`` that is
            not a granpack run's; a run there that neither ``resume`` nor ``overwrite`` lets go on
            (:func:`granpack.simulation.run_packing`).
    """
    if resume and overwrite:
        raise InputError("--resume and --overwrite exclude each other: continue the run in the folder, or replace it")
    campaign = [name for name in CAMPAIGN_FILES if (out_dir / name).is_file()]
    if campaign:
        raise InputError(f"{out_dir}: is a campaign's folder ({', '.join(campaign)}); a run goes into a folder of its own: "
                         "choose another --out folder")
    output_folder(out_dir)
    present = [name for name in RUN_FILES if (out_dir / name).is_file()]
    config_path = out_dir / CONFIG_FILE
    if config_path.exists() and not present and not is_resolved_config(config_path, config_text):
        raise InputError(f"{config_path}: not a granpack run's resolved config (your own file?) and the run writes "
                         "its resolved config there; choose another --out folder")
    finished = (out_dir / SUMMARY_FILE).is_file() and (out_dir / FINAL_FILE).is_file()
    checkpoint = out_dir / CHECKPOINT_FILE
    replace_hint = "--overwrite replaces it (its analysis, figures and exports go too)"
    if resume:
        if finished:
            if config_path.is_file() and config_path.read_text(encoding="utf-8") == config_text:
                note(f"{out_dir} holds a finished run of this config: nothing to resume, its summary stands")
                return True
            differences = config_differences(config_path.read_text(encoding="utf-8") if config_path.is_file() else "",
                                             config_text, str(config_path), source or "the config given")
            raise InputError(f"{out_dir}: holds a finished run of another config ({differences}); nothing to "
                             f"--resume: {replace_hint}, or choose another --out folder")
        if checkpoint.is_file():
            return False
        if present:
            raise InputError(f"{out_dir}: no {CHECKPOINT_FILE} to --resume from, but the folder holds "
                             f"{', '.join(present)}: {replace_hint}, or choose another --out folder")
        note(f"no {CHECKPOINT_FILE} in {out_dir}: nothing to resume, starting afresh")
        return False
    if present and not overwrite:
        if finished:
            what = f"a finished run ({FINAL_FILE}, {SUMMARY_FILE}): --resume returns it as it is, " + replace_hint
        elif checkpoint.is_file():
            what = (f"an unfinished run (its checkpoint{checkpoint_when(checkpoint)}): --resume continues it, "
                    + replace_hint)
        else:
            what = f"the outputs of a run ({', '.join(present)}): {replace_hint} (--resume needs a checkpoint)"
        raise InputError(f"{out_dir}: holds {what}")
    if overwrite:
        removed = clear_run(out_dir)
        if removed:
            note(f"--overwrite: removed {', '.join(removed)} from {out_dir}")
    return False

"""The final states of the kept runs: out of the repository's tree, got back from its history or made again.

A kept run (``benchmarks/validation/runs/CAMPAIGN/MIXTURE/seed-S``) holds in the tree the small
files every table and figure of the docs is rebuilt from (``task.json``, ``summary.json``,
``analysis.json``, ``timeline.csv``, and the figures derived from the final state once:
``bed.json``, ``benchmarks/validation/pair-contacts.json``). Its ``final.gsd`` (the exact
packing with its contacts, 1 to 25 MB) is not: the tree stays small enough to clone
(``git clone --depth 1``), and ``.gitignore`` keeps a final state that ``run.sh`` writes locally
out of commits. The final states once committed stay in the history; the manifest
``benchmarks/validation/final-states.csv`` names each one's run folder, the commit that holds it,
its blob and its size:

- ``get [RUN_DIR ...]``: writes each named kept run's ``final.gsd`` (all of the manifest's if
  none is named) from the history into its folder, checked against the manifest's blob; a clone
  without that history (``--depth 1``) is told to ``git fetch --unshallow`` first, or to make the
  state again;
- ``regenerate RUN_DIR --out DIR``: runs the kept run's config (``task.json`` or ``config.toml``) again into
  ``DIR`` with ``granpack run`` at one thread, as the kept runs were made; with the code that made
  it the final state is bit-identical, with later code the same up to the changes the CHANGELOG
  lists (about an hour of CPU for a 3000-grain pinacoid pile);
- ``manifest``: (re)writes the manifest from the ``final.gsd`` files tracked at ``HEAD``, with the
  rows of those already listed; run it before removing final states from the tree.

Usage::

    python benchmarks/final_states.py get benchmarks/validation/runs/bidisperse/*/seed-1
    python benchmarks/final_states.py regenerate benchmarks/validation/runs/grading/fuller-4-22/seed-1 --out /tmp/fuller
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

from granpack.io.run_folder import FINAL_FILE as FINAL

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "benchmarks" / "validation" / "runs"
MANIFEST = ROOT / "benchmarks" / "validation" / "final-states.csv"
COLUMNS = ("run", "commit", "blob", "bytes")


def _git(*args: str, binary: bool = False):
    out = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(out.stderr.decode(errors="replace").strip() or f"git {' '.join(args)} failed")
    return out.stdout if binary else out.stdout.decode().strip()


def read_manifest() -> dict[str, dict]:
    """``{run folder relative to the repository: row}`` of the manifest (empty if none)."""
    if not MANIFEST.is_file():
        return {}
    with MANIFEST.open(newline="") as f:
        return {row["run"]: row for row in csv.DictReader(f)}


def write_manifest() -> int:
    """The manifest from the final states tracked at ``HEAD`` and the rows already listed;
    returns the number of rows."""
    rows = read_manifest()
    tracked = [p for p in _git("ls-files", "--", str(RUNS.relative_to(ROOT))).splitlines() if p.endswith("/" + FINAL)]
    for path in tracked:
        run = str(Path(path).parent)
        commit = _git("log", "-1", "--format=%H", "--", path)
        blob = _git("rev-parse", f"HEAD:{path}")
        size = _git("cat-file", "-s", blob)
        rows[run] = {"run": run, "commit": commit, "blob": blob, "bytes": size}
    with MANIFEST.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
        writer.writeheader()
        for run in sorted(rows):
            writer.writerow(rows[run])
    return len(rows)


def _blob_id(data: bytes) -> str:
    """The git blob id of ``data`` (sha1 of ``blob <size>\\0`` and the bytes)."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def get(run: str, row: dict) -> Path:
    """Write ``run``'s final state from the history; returns its path."""
    target = ROOT / run / FINAL
    try:
        data = _git("cat-file", "blob", row["blob"], binary=True)
    except RuntimeError:
        raise SystemExit(f"{run}: its final state (commit {row['commit'][:12]}) is not in this clone's history; "
                         f"run `git fetch --unshallow` (a --depth 1 clone), or make it again: "
                         f"python benchmarks/final_states.py regenerate {run} --out DIR") from None
    if _blob_id(data) != row["blob"]:
        raise SystemExit(f"{run}: the history's {FINAL} is not the manifest's blob {row['blob']}")
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(".gsd.part")
    partial.write_bytes(data)
    os.replace(partial, target)
    return target


def regenerate(run: Path, out: Path) -> dict:
    """Run the kept run's config (its ``task.json``, a campaign's run, or its ``config.toml``) again
    into ``out`` at one thread; returns its summary."""
    os.environ["NUMBA_NUM_THREADS"] = "1"
    from granpack.config import load_config, load_config_dict
    from granpack.simulation import run_packing

    task = run / "task.json"
    config = (load_config_dict(json.loads(task.read_text())["config"], str(task)) if task.is_file()
              else load_config(run / "config.toml"))
    return run_packing(config, out, progress=True)


def _relative(path: Path) -> str:
    return str(path.resolve().relative_to(ROOT))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("manifest", help="(re)write the manifest from the final states tracked at HEAD")
    got = sub.add_parser("get", help="write kept runs' final.gsd from the history (all of the manifest's if none named)")
    got.add_argument("runs", nargs="*", type=Path)
    again = sub.add_parser("regenerate", help="run a kept run's config again (one thread) into --out")
    again.add_argument("run", type=Path)
    again.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if args.action == "manifest":
        print(f"{write_manifest()} final states in {MANIFEST.relative_to(ROOT)}", file=sys.stderr)
    elif args.action == "get":
        manifest = read_manifest()
        runs = [_relative(r) for r in args.runs] if args.runs else sorted(manifest)
        unknown = [r for r in runs if r not in manifest]
        if unknown:
            print(f"error: no final state listed in {MANIFEST.relative_to(ROOT)} for: {', '.join(unknown)}", file=sys.stderr)
            return 2
        for run in runs:
            print(get(run, manifest[run]).relative_to(ROOT))
    else:
        if not any((args.run / name).is_file() for name in ("task.json", "config.toml")):
            print(f"error: {args.run}: not a kept run folder (no task.json or config.toml)", file=sys.stderr)
            return 2
        summary = regenerate(args.run, args.out)
        print(f"{args.out / FINAL}: {summary['status']} at t = {summary['simulated_time']:g}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

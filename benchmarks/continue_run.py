"""Continue a finished run from its final state under other settings: a what-if on a real pile.

Usage::

    python benchmarks/continue_run.py RUN_DIR OUT_DIR --max-time T [--set SECTION.KEY=VALUE ...]

``granpack run --resume`` continues a checkpoint, or a run that ended not at rest, under its own
settings but for a later cap or another NLGS tolerance, and writes into the run's folder; this continues ``RUN_DIR/final.gsd`` (a run that ended at rest or at its cap) with
``RUN_DIR/config.toml`` changed by ``--set`` (``container.wall_friction=0.5``,
``end_game.mode=none``, ...) up to ``equilibrium.max_time = T``. The settling starts in the
phase the run ended in: the end game's damping on (where the config has it) and the fine NLGS
tolerance in use, the equilibrium window empty. The continuation is a run folder of its own
(``OUT_DIR``: config, final.gsd, summary.json, timeline.csv, and a mould's container.stl), which ``granpack analyze`` reads;
it prints one line per equilibrium check every ``--every`` sqrt(d/g) and the summary's JSON
headline at the end.

It answers questions like "what holds this pile back?": 1000 frictionless cubes not at rest at
t = 120 were certified at rest within 1.25 sqrt(d/g) with the floor made frictional
(``--set container.wall_friction=0.5``) and were still moving at t = 135 without it.
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path

from granpack.config import load_config_dict
from granpack.io.gsd import read_packing
from granpack.io.run_folder import CONFIG_FILE, FINAL_FILE
from granpack.mixture import Mixture
from granpack.run_record import RunRecord
from granpack.settling import Settling
from granpack.simulation import headline, saved_state, write_run

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_settle import apply_sets  # noqa: E402


class _Lines:
    """Observer: a line of the equilibrium figures every ``every`` sqrt(d/g) of simulated time."""

    def __init__(self, every: float):
        self.every, self.next = every, None

    def checked(self, run: Settling) -> None:
        t = run.state.time
        if self.next is None or t >= self.next - 1e-9:
            r = run.report
            print(f"t = {t:.2f}: largest net force {r.max_net_force:.3g} d^2 P, kinetic criterion "
                  f"{r.kinetic_energy:.3g}, checks passed in a row {run.record.milestones.passes}", flush=True)
            self.next = t + self.every

    def stepped(self, run: Settling) -> None:
        pass


def continue_run(run_dir: Path, out_dir: Path, max_time: float, overrides: list[str], every: float = 1.0) -> dict:
    """Settle ``run_dir``'s final state on under its config with ``overrides`` to ``max_time``,
    writing a run folder in ``out_dir``; returns its summary."""
    raw = tomllib.loads((run_dir / CONFIG_FILE).read_text())
    config = load_config_dict(apply_sets(raw, [*overrides, f"equilibrium.max_time={max_time}"]),
                              source=str(run_dir / CONFIG_FILE), base_dir=run_dir)
    mixture = Mixture.from_config(config)
    final = read_packing(run_dir / FINAL_FILE)
    if not max_time > final.state.time + 0.5 * config.time_stepping.time_step:
        raise SystemExit(f"--max-time {max_time:g} is not beyond the run's end at t = {final.state.time:.6g}")
    state = saved_state(final.state, config, mixture)
    record = RunRecord()
    m = record.milestones
    m.step = int(round(state.time / config.time_stepping.time_step))
    m.end_game, m.near_rest, m.last_step = True, True, config.time_stepping.time_step
    run = Settling(config, mixture, state, final.contacts, record)
    status = run.run((_Lines(every),))
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / CONFIG_FILE).write_text(config.to_toml())
    return write_run(out_dir, config, run, status)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path, help="a finished run folder (config.toml, final.gsd)")
    parser.add_argument("out_dir", type=Path, help="folder for the continuation")
    parser.add_argument("--max-time", type=float, required=True, help="simulated time to stop at, sqrt(d/g)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override")
    parser.add_argument("--every", type=float, default=1.0, help="sqrt(d/g) between printed lines")
    args = parser.parse_args(argv)
    summary = continue_run(args.run_dir, args.out_dir, args.max_time, args.set, args.every)
    json.dump(headline(summary), sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

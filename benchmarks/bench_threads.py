"""Threads: the cost of a whole `granpack run` on each threading layer, at 1 and 2 threads, alone
and with a second run beside it on the same cores.

Each case is run as a user runs it (`granpack run CONFIG --out DIR` in a child process) under
``NUMBA_THREADING_LAYER`` = workqueue (granpack's default), omp and tbb (each where Numba can
load it) and ``NUMBA_NUM_THREADS`` = 1 and 2; "paired" starts two identical runs at once and
reports the slower. Per run: wall seconds, user and system CPU seconds of the child (from
``os.wait4``), and the steps; the runs are deterministic, so every setting makes the same steps.

Cases (``--case``, repeatable; default both):

- ``demo``: ``examples/demo.toml`` (300 isometric pinacoids, 3 d cell) poured to certified rest;
- ``pinacoids-1000``: 1000 isometric pinacoids in a 4 d cell, seed 11, poured to t = 5 sqrt(d/g)
  (the pour and the collapse, the costliest part of a step's work).

Prints one JSON object per (case, layer, threads, alone | paired).

Usage::

    python benchmarks/bench_threads.py --out /tmp/threads
    python benchmarks/bench_threads.py --case demo --layer workqueue --layer tbb --out /tmp/threads
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINACOIDS_1000 = """\
seed = 11
n_particles = 1000
lateral_size = 4.0

[[populations]]
shape = "pinacoid"
size = 1.0
volume_fraction = 1.0

[equilibrium]
max_time = 5.0
"""
LAYERS = ("workqueue", "omp", "tbb")


def _config(case: str, folder: Path) -> Path:
    if case == "demo":
        return ROOT / "examples" / "demo.toml"
    path = folder / f"{case}.toml"
    path.write_text(PINACOIDS_1000)
    return path


def _layer_available(layer: str) -> bool:
    probe = ("import numba, numpy as np\n"
             "numba.njit(parallel=True)(lambda a: a + 1)(np.ones(2))\n"
             "print(numba.threading_layer())")
    env = {**os.environ, "NUMBA_THREADING_LAYER": layer}
    proc = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True)
    return proc.stdout.strip() == layer


def _runs(config: Path, out: Path, layer: str, threads: int, copies: int) -> list[dict]:
    """``copies`` runs of ``config`` started at once; each one's wall, user and system seconds."""
    env = {**os.environ, "NUMBA_THREADING_LAYER": layer, "NUMBA_NUM_THREADS": str(threads)}
    started = {}
    for k in range(copies):
        folder = out / f"{layer}-{threads}-{copies}-{k}"
        cmd = [sys.executable, "-m", "granpack", "run", str(config), "--out", str(folder), "--overwrite"]
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        started[proc.pid] = (proc, folder, time.perf_counter())
    results = []
    while started:
        pid, status, usage = os.wait4(-1, 0)
        if pid not in started:
            continue
        proc, folder, t0 = started.pop(pid)
        proc.returncode = os.waitstatus_to_exitcode(status)
        summary = json.loads((folder / "summary.json").read_text())
        results.append({"wall_s": round(time.perf_counter() - t0, 2), "user_s": round(usage.ru_utime, 2),
                        "system_s": round(usage.ru_stime, 2), "steps": summary["steps"],
                        "status": summary["status"], "layer_used": summary["threads"]["layer"]})
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", action="append", choices=("demo", "pinacoids-1000"))
    parser.add_argument("--layer", action="append", choices=LAYERS)
    parser.add_argument("--threads", action="append", type=int, choices=(1, 2))
    parser.add_argument("--out", type=Path, required=True, help="a scratch folder for the runs")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    layers = [layer for layer in (args.layer or LAYERS) if _layer_available(layer)]
    for case in args.case or ("demo", "pinacoids-1000"):
        config = _config(case, args.out)
        subprocess.run([sys.executable, "-m", "granpack", "run", str(config), "--out", str(args.out / "warm"),
                        "--overwrite"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # compile once
        for layer in layers:
            for threads in args.threads or (1, 2):
                for copies, mode in ((1, "alone"), (2, "paired")):
                    runs = _runs(config, args.out / case, layer, threads, copies)
                    slowest = max(runs, key=lambda r: r["wall_s"])
                    print(json.dumps({"case": case, "layer": layer, "threads": threads, "mode": mode, **slowest,
                                      "machine": f"{platform.node()} ({os.cpu_count()} CPUs)",
                                      "date": time.strftime("%Y-%m-%d")}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

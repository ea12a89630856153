"""Threads: granpack's choice of threading layer, the serial build of its kernels at one thread,
and a clean stop on every layer Numba can find (workqueue, OpenMP, oneTBB).

The stop tests run `granpack run` in a child process with two Numba threads and the narrow phase
split at any pair count, so that Numba code runs in the narrow phase's second thread, as in
every pile of some thousand grains: that is where oneTBB's finalizer used to spin for good.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

#: a run that never ends by itself (more passing checks in a row than it can make): 120 pinacoids
_LONG_RUN = """\
seed = 2
n_particles = 120
lateral_size = 3.0

[[populations]]
shape = "pinacoid"
size = 1.0
volume_fraction = 1.0

[equilibrium]
max_time = 500.0
window = 100000

[output]
checkpoint_interval = 2.0
"""

#: `granpack run` with the narrow phase cut into two thread ranges at any pair count
_RUN_WITH_NARROW_PHASE_THREADS = textwrap.dedent("""\
    import sys
    import granpack.contact.detect as detect
    detect._PAIRS_PER_THREAD = 1
    from granpack.cli import main
    main(sys.argv[1:])
""")


def _layer_available(layer: str) -> bool:
    """Whether Numba can run a parallel kernel on ``layer`` here (oneTBB is often absent)."""
    probe = ("import numba, numpy as np\n"
             "@numba.njit(parallel=True)\n"
             "def g(a):\n"
             "    s = 0.0\n"
             "    for i in numba.prange(a.size):\n"
             "        s += a[i]\n"
             "    return s\n"
             "g(np.ones(4)); print(numba.threading_layer())")
    env = {**os.environ, "NUMBA_THREADING_LAYER": layer, "NUMBA_NUM_THREADS": "2"}
    proc = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    return proc.returncode == 0 and proc.stdout.strip() == layer


def _default_sigint() -> None:
    """In the child: SIGINT's default action, as a terminal gives a command (a library used by an
    earlier test, a Dask cluster, may have left SIG_IGN in this process, which a child inherits)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _env(**settings) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    env.update({k: v for k, v in settings.items() if v is not None})
    return env


def test_granpack_runs_its_kernels_on_the_workqueue_layer_unless_the_environment_names_one():
    """The layer is granpack's choice, not the first Numba finds (oneTBB where it is installed);
    NUMBA_THREADING_LAYER still decides where set; `granpack --version` says which."""
    default = subprocess.run([sys.executable, "-m", "granpack", "--version"], env=_env(), capture_output=True,
                             text=True, timeout=120)
    assert default.returncode == 0 and "threading layer workqueue" in default.stdout, default.stdout
    chosen = subprocess.run([sys.executable, "-m", "granpack", "--version"], env=_env(NUMBA_THREADING_LAYER="omp"),
                            capture_output=True, text=True, timeout=120)
    assert "threading layer omp" in chosen.stdout, chosen.stdout


def test_a_kernel_at_one_thread_starts_no_thread():
    """At NUMBA_NUM_THREADS=1 the serial build runs: the process has as many OS threads after a
    parallel kernel as before it (a parallel build would start the layer's worker threads)."""
    script = textwrap.dedent("""\
        import os
        import numpy as np
        from granpack.nscd.problem import _local_velocity_kernel
        body = np.zeros((1, 2), np.int64); body[0, 1] = 1
        data = np.zeros((1, 19)); tangent = np.zeros((1, 2, 3)); lever = np.zeros((1, 3))
        velocity = np.zeros((2, 6)); out = np.zeros((1, 3))
        before = len(os.listdir("/proc/self/task"))
        for _ in range(2):
            _local_velocity_kernel(body, data, tangent, lever, lever, velocity, out)
        print(before, len(os.listdir("/proc/self/task")))
    """)
    proc = subprocess.run([sys.executable, "-c", script], env=_env(NUMBA_NUM_THREADS="1"), capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    before, after = map(int, proc.stdout.split())
    assert after == before


@pytest.mark.parametrize("layer", [None, "workqueue", "omp", "tbb"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_run_stopped_on_any_threading_layer_exits_130_within_seconds(tmp_path, layer, sig):
    """Ctrl-C or SIGTERM while settling, with Numba code in two threads: exit 130 with the
    checkpoint written, on granpack's layer and on each that the environment may name."""
    if layer is not None and not _layer_available(layer):
        pytest.skip(f"the {layer} threading layer is not available here")
    config = tmp_path / "long.toml"
    config.write_text(_LONG_RUN)
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-c", _RUN_WITH_NARROW_PHASE_THREADS, "run", str(config), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env(NUMBA_THREADING_LAYER=layer, NUMBA_NUM_THREADS="2"),
                            preexec_fn=_default_sigint)
    try:
        # the first checkpoint, at t = 2: the grains touch, the narrow phase runs in two threads; from a
        # cold Numba cache on a loaded 2-core machine it takes some 150 s (compiling), so wait up to 600
        for _ in range(6000):
            if (out / "checkpoint.gsd").is_file() or proc.poll() is not None:
                break
            time.sleep(0.1)
        if not (out / "checkpoint.gsd").is_file():
            pytest.fail(f"no checkpoint within 600 s (exit status {proc.poll()})")
        proc.send_signal(sig)
        try:
            _, rest = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the run did not exit within 30 s of the signal (layer {layer or 'granpack default'})")
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, rest
    assert rest.splitlines()[-1].startswith("interrupted at t = ") and (out / "checkpoint.gsd").is_file()

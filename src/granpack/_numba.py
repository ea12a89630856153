"""The one place where Numba is configured.

Every kernel in granpack is compiled through :func:`jit` so that caching, fastmath and
parallelism are decided here only. Kernels are compiled on first call and cached on disk
(``cache=True``), so the second process that imports a kernel pays no compilation.

Threads that wait spin only briefly (``GOMP_SPINCOUNT``, unless the environment sets it): GNU
OpenMP's default lets an idle worker of a ``prange`` loop spin for about a millisecond, and on a
machine of two CPUs it then takes one of them from the narrow phase's threads and from the
sequential kernels that run between two parallel loops (a step of a 3000-pinacoid pile a fifth
slower; benchmarks/README.md). The variable is read when the OpenMP runtime is loaded, at the
first parallel loop, so it is set here, before any kernel runs.
"""

from __future__ import annotations

import os

os.environ.setdefault("GOMP_SPINCOUNT", "10000")

import numba  # noqa: E402  (after the OpenMP setting above)

__all__ = ["jit", "prange"]

prange = numba.prange


def jit(func=None, *, parallel: bool = False, fastmath: bool = False, inline: str = "never"):
    """Compile ``func`` in nopython mode with on-disk caching.

    Args:
        func: the Python function to compile (decorator use without arguments).
        parallel: allow ``prange`` loops (thread-parallel); off by default because the
            engine is deterministic and the target machines have few cores.
        fastmath: allow reassociation of floating-point operations; off by default so
            results are bit-reproducible run to run.
        inline: ``"always"`` inlines the function into its Numba callers (Numba IR level),
            for the per-pair kernels of the narrow phase: a compiled call that receives tuples
            of arrays increfs and decrefs each array, which cost a fifth of the narrow phase on
            a settled pinacoid pile (benchmarks/README.md); ``"never"`` (default) compiles a
            separate function. Results are the same bit for bit either way.
    """

    def wrap(f):
        return numba.njit(cache=True, parallel=parallel, fastmath=fastmath, nogil=True, inline=inline)(f)

    if func is None:
        return wrap
    return wrap(func)

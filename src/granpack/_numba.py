"""The one place where Numba is configured: threading layer, caching, and the kernels' two builds.

granpack runs its parallel kernels on Numba's ``workqueue`` threading layer unless the
environment names another (``NUMBA_THREADING_LAYER``): it ships with every Numba, so every
machine runs the same code path, its idle threads sleep instead of spinning, and it has no
finalizer to hang at exit (oneTBB's, which Numba picks first where TBB is installed, spins
forever once Numba code has run in a second thread). A kernel compiled with ``parallel=True``
is built twice: the parallel build runs when Numba has more than one thread, a serial build
otherwise, so that a one-thread run wakes no thread at all; a kernel called on little work (fewer
rows than :data:`MIN_PARALLEL_ROWS`, or a caller's own bound) runs its serial build too. A kernel
whose threads must meet many times in one call (the two-part NLGS sweeps) meets through the atomic
operations below (:func:`atomic_load`, :func:`atomic_store`, :func:`atomic_cas`, :func:`atomic_add`,
:func:`spin_pause`) in one launch, instead of one launch per meeting.
"""

from __future__ import annotations

import os
import platform
import types

#: the threading layer granpack asks for where the environment names none
THREADING_LAYER = "workqueue"
#: fewest rows for which a kernel runs its parallel build: below, a launch (tens of microseconds:
#: waking the workers and waiting for them) costs more than the second thread saves. Bodies cost
#: about ten times as much per row as contact points, hence two bounds.
MIN_PARALLEL_ROWS = 1000
MIN_PARALLEL_POINTS = 10_000

os.environ.setdefault("NUMBA_THREADING_LAYER", THREADING_LAYER)
os.environ.setdefault("GOMP_SPINCOUNT", "10000")  # OpenMP, if asked for: idle threads spin briefly

import numba  # noqa: E402  (after the environment settings above)
from llvmlite import ir  # noqa: E402
from numba.core import cgutils  # noqa: E402
from numba.extending import intrinsic  # noqa: E402

__all__ = ["MIN_PARALLEL_POINTS", "MIN_PARALLEL_ROWS", "THREADING_LAYER", "ThreadedKernel", "atomic_add", "atomic_cas",
           "atomic_load", "atomic_store", "jit", "prange", "spin_pause", "thread_count", "threading_layer"]

prange = numba.prange


class ThreadedKernel:
    """A ``prange`` kernel built twice: ``parallel`` for several threads, ``serial`` for one.

    Calling it runs the parallel build when ``numba.get_num_threads() > 1`` and the serial one
    otherwise (at ``NUMBA_NUM_THREADS=1`` the layer's threads are never started); both give the same result bit for bit (each ``prange`` loop of granpack runs over
    explicit chunks whose partition does not depend on the thread count). Call it from Python
    only: a Numba caller would need one build, not a choice between two.
    """

    def __init__(self, func, **options):
        self.parallel = numba.njit(parallel=True, **options)(func)
        serial = types.FunctionType(func.__code__, func.__globals__, func.__name__, func.__defaults__, func.__closure__)
        serial.__qualname__ = f"{func.__qualname__}_serial"  # its own on-disk cache entry
        serial.__doc__ = func.__doc__
        self.serial = numba.njit(parallel=False, **options)(serial)
        self.__doc__, self.__name__, self.__qualname__ = func.__doc__, func.__name__, func.__qualname__
        self.__module__, self.__wrapped__ = func.__module__, func

    def __call__(self, *args):
        return (self.parallel if thread_count() > 1 else self.serial)(*args)

    def sized(self, rows: int, least: int = MIN_PARALLEL_ROWS):
        """The build for ``rows`` rows of work: the parallel one from ``least`` rows on (and
        several threads), the serial one below; the two give the same bits."""
        return self.parallel if rows >= least and thread_count() > 1 else self.serial


def jit(func=None, *, parallel: bool = False, fastmath: bool = False, inline: str = "never"):
    """Compile ``func`` in nopython mode with on-disk caching (``cache=True``) and the GIL released.

    Args:
        func: the Python function to compile (decorator use without arguments).
        parallel: the function has ``prange`` loops: build a :class:`ThreadedKernel` (a parallel
            build for several threads and a serial one for one thread).
        fastmath: allow reassociation of floating-point operations; off by default so
            results are bit-reproducible run to run.
        inline: ``"always"`` inlines the function into its Numba callers (Numba IR level), for
            the per-pair kernels of the narrow phase, so that a call passing tuples of arrays does
            not incref and decref each array; ``"never"`` (default) compiles a separate function.
            Results are the same bit for bit either way.
    """

    def wrap(f):
        options = dict(cache=True, fastmath=fastmath, nogil=True, inline=inline)
        return ThreadedKernel(f, **options) if parallel else numba.njit(**options)(f)

    if func is None:
        return wrap
    return wrap(func)


def thread_count() -> int:
    """The threads a parallel kernel would run on now (``numba.get_num_threads()``), without
    starting the layer's threads where Numba has only one (``NUMBA_NUM_THREADS=1``)."""
    return 1 if numba.config.NUMBA_NUM_THREADS == 1 else numba.get_num_threads()


def threading_layer() -> str:
    """The threading layer the parallel builds run on: the one Numba chose where a parallel kernel
    has run already, else the one configured (``NUMBA_THREADING_LAYER``, ``workqueue`` by default)."""
    try:
        return numba.threading_layer()
    except ValueError:  # no parallel kernel has run yet
        return numba.config.THREADING_LAYER


def _element_pointer(context, builder, signature, args):
    """The address of ``array[index]`` (an int64 array, an integer index) in an intrinsic's code."""
    array_type = signature.args[0]
    array = context.make_array(array_type)(context, builder, args[0])
    return cgutils.get_item_pointer(context, builder, array_type, array, [args[1]])


@intrinsic
def atomic_load(typingctx, array, index):
    """Numba: ``array[index]`` of an int64 array, read atomically (sequentially consistent): what a
    thread wrote before its atomic store or operation on that element is visible after this read."""
    def codegen(context, builder, signature, args):
        return builder.load_atomic(_element_pointer(context, builder, signature, args), "seq_cst", 8)

    return numba.types.int64(array, index), codegen


@intrinsic
def atomic_store(typingctx, array, index, value):
    """Numba: ``array[index] = value`` on an int64 array, atomically (sequentially consistent): every
    write the thread made before it is visible to a thread that reads the new value."""
    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[2], signature.args[2], numba.types.int64)
        builder.store_atomic(value, _element_pointer(context, builder, signature, args), "seq_cst", 8)
        return context.get_dummy_value()

    return numba.types.void(array, index, value), codegen


@intrinsic
def atomic_cas(typingctx, array, index, expected, value):
    """Numba: compare and swap on ``array[index]`` (int64): writes ``value`` where the element holds
    ``expected``, atomically; returns whether it did."""
    def codegen(context, builder, signature, args):
        expected = context.cast(builder, args[2], signature.args[2], numba.types.int64)
        value = context.cast(builder, args[3], signature.args[3], numba.types.int64)
        pointer = _element_pointer(context, builder, signature, args)
        pair = builder.cmpxchg(pointer, expected, value, "seq_cst", "seq_cst")
        return builder.extract_value(pair, 1)

    return numba.types.boolean(array, index, expected, value), codegen


@intrinsic
def atomic_add(typingctx, array, index, value):
    """Numba: ``array[index] += value`` on an int64 array, atomically; returns the value before."""
    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[2], signature.args[2], numba.types.int64)
        return builder.atomic_rmw("add", _element_pointer(context, builder, signature, args), value, "seq_cst")

    return numba.types.int64(array, index, value), codegen


#: the processor's spin-wait hint, as an LLVM intrinsic and its arguments
_PAUSE = {"x86_64": ("llvm.x86.sse2.pause", ()), "amd64": ("llvm.x86.sse2.pause", ()),
          "aarch64": ("llvm.aarch64.hint", (1,)), "arm64": ("llvm.aarch64.hint", (1,))}.get(platform.machine().lower())


@intrinsic
def spin_pause(typingctx):
    """Numba: the processor's hint that the thread spins on a value (``pause`` on x86-64, ``yield``
    on ARM64, nothing elsewhere); no system call."""
    def codegen(context, builder, signature, args):
        if _PAUSE is not None:
            name, operands = _PAUSE
            i32 = ir.IntType(32)
            kind = ir.FunctionType(ir.VoidType(), [i32] * len(operands))
            hint = cgutils.get_or_insert_function(builder.module, kind, name)
            builder.call(hint, [i32(x) for x in operands])
        return context.get_dummy_value()

    return numba.types.void(), codegen

"""How a command is stopped: Ctrl-C (SIGINT) and SIGTERM, turned into a flag while a run settles.

The checkpoints of :mod:`granpack.simulation` read :attr:`Interrupt.requested` once per step;
the command line (:mod:`granpack.cli`) sends SIGTERM to :func:`sigterm_as_ctrl_c` outside the
settling loop. Both work whatever SIGINT's inherited disposition (``nohup ... &`` and many batch
schedulers start jobs with SIGINT ignored).
"""

from __future__ import annotations

import signal
import threading

__all__ = ["Interrupt", "sigterm_as_ctrl_c"]


def sigterm_as_ctrl_c(signum, frame) -> None:
    """SIGTERM handler outside the settling loop: do what Ctrl-C does now. The current SIGINT
    handler is called (Python's raises KeyboardInterrupt); where SIGINT is ignored (a job started
    with ``nohup ... &`` or by a batch scheduler), KeyboardInterrupt is raised, so SIGTERM still
    stops the command. While a run settles, :class:`Interrupt` takes SIGTERM over."""
    handler = signal.getsignal(signal.SIGINT)
    if callable(handler):
        handler(signal.SIGINT, frame)
    else:
        raise KeyboardInterrupt


class Interrupt:
    """Ctrl-C or SIGTERM while settling: the signal sets :attr:`requested`, which the loop reads
    once per step (it then writes its checkpoint and raises :class:`~granpack.errors.RunInterrupted`);
    a second signal raises KeyboardInterrupt at once.

    A flag rather than an exception because a signal often lands inside a Numba kernel, where an
    exception surfaces as ``SystemError: CPUDispatcher(...) returned a result with an exception
    set`` with the state half-updated. The handlers are installed only in the main thread, each
    signal apart: SIGINT over Python's default handler only (a host that handles SIGINT keeps its
    handler; a job whose SIGINT is ignored, as under ``nohup ... &``, keeps ignoring it), SIGTERM
    over its default action or :func:`sigterm_as_ctrl_c` whatever SIGINT's disposition, so that a
    background job stopped by ``kill`` writes the step's checkpoint.
    """

    def __init__(self):
        self.requested = False
        self._previous: dict[int, object] = {}

    def _handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for signum, ours_to_take in ((signal.SIGINT, (signal.default_int_handler,)),
                                         (signal.SIGTERM, (signal.SIG_DFL, sigterm_as_ctrl_c))):
                if signal.getsignal(signum) in ours_to_take:
                    self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc):
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous.clear()
        return False

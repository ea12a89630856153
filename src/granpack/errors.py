"""Errors that the command line turns into a one-line message and an exit status.

- :class:`InputError`: bad input (config, file, option, output folder): exit status 2.
- :class:`RunInterrupted`: a run stopped by Ctrl-C (SIGINT) at the end of a step, its checkpoint
  written: exit status 130, the line says how to resume.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError", "RunInterrupted"]


class InputError(ValueError):
    """Bad user input (config, file, option). The message names the field/file and what is allowed."""


class RunInterrupted(KeyboardInterrupt):
    """A run stopped on Ctrl-C at the end of a step, after writing its checkpoint.

    A :class:`KeyboardInterrupt`, so code that lets Ctrl-C through lets this through too.

    Attributes:
        checkpoint: the checkpoint file written (``run_packing(..., resume=True)`` goes on from it).
        time: simulated time of the checkpoint, sqrt(d/g).
        step: its step number.
    """

    def __init__(self, checkpoint: Path, time: float, step: int):
        super().__init__(f"interrupted at t = {time:.6g} sqrt(d/g) (step {step}); checkpoint {checkpoint}")
        self.checkpoint = Path(checkpoint)
        self.time = float(time)
        self.step = int(step)

"""Errors that the command line turns into a one-line message and exit status 2."""

from __future__ import annotations

__all__ = ["InputError"]


class InputError(ValueError):
    """Bad user input (config, file, option). The message names the field/file and what is allowed."""

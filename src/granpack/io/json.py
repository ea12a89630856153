"""JSON summaries written atomically, with NaN and infinities as ``null``.

Strict JSON has no NaN or Infinity; analysis figures that are undefined (a packing too thin for a
bulk region, no contacts ...) are ``nan`` in Python and ``null`` in the file. NumPy scalars and
arrays are converted to plain lists and numbers.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from granpack.errors import InputError
from granpack.io.atomic import write_text_atomic

__all__ = ["to_jsonable", "write_json", "read_json"]


def to_jsonable(value):
    """A copy of ``value`` made of dicts, lists, str, int, float, bool and None only.

    NumPy arrays become (nested) lists, NumPy scalars Python scalars, tuples lists, paths strings,
    and non-finite floats ``None``.
    """
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path: str | os.PathLike, data, *, indent: int = 2) -> Path:
    """Write ``data`` as strict JSON to ``path`` atomically (temporary file in the same folder, then rename).

    Returns:
        The path written.
    """
    path = Path(path)
    text = json.dumps(to_jsonable(data), indent=indent, allow_nan=False) + "\n"
    return write_text_atomic(path, text)


def read_json(path: str | os.PathLike):
    """Read a JSON file (``null`` stays ``None``).

    Raises:
        InputError: the file is missing or is not valid JSON (one-line message naming it).
    """
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable JSON file ({str(exc).splitlines()[0]})") from None

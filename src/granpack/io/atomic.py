"""Atomic file output: every file granpack writes appears whole or not at all.

Owned here: outputs are written to a temporary name in the destination folder (``.NAME.XXXX.tmp.SUFFIX``)
and renamed over the destination only once complete; on any error the temporary file is removed
and the destination is left as it was.

The temporary file is created with mode ``0666`` filtered by the process umask (and the folder's
default ACL), as ``open()`` would create the destination itself: with the usual umask 022 the
outputs are readable by the group and by others (``tempfile.mkstemp`` would make them 0600).
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_text_atomic", "output_folder"]

_ATTEMPTS = 100


def output_folder(path: Path, option: str = "--out") -> None:
    """Create the output folder ``path`` (and its parents) if needed.

    Raises:
        InputError: ``path`` is a file or has a file in its path (one line naming ``option``).
        OSError: the system refuses to create it (permissions), naming ``path``.
    """
    from granpack.errors import InputError

    if path.exists() and not path.is_dir():
        raise InputError(f"{option} {path}: is a file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:  # a file on the way: a path that cannot be a folder
        raise InputError(f"{option} {path}: cannot create the folder (a file is in its path)") from None
    except OSError as exc:  # the system refuses (permissions, a read-only disk): a system error
        raise OSError(exc.errno, f"cannot create the folder ({exc.strerror})", str(path)) from None


def _create_temporary(path: Path) -> Path:
    """Create an empty, new temporary file beside ``path`` (mode 0666 & ~umask); return its path."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(_ATTEMPTS):
        tmp = path.parent / f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}"
        try:
            fd = os.open(tmp, flags, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"{path.parent}: no free temporary name for {path.name}")


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); rename it to ``path`` on success.

    The folder of ``path`` must exist. The temporary file exists, empty, with the mode of a new
    file (0666 less the umask); writers that open it for writing keep that mode. An
    :class:`OSError` on the temporary file (a folder one cannot write, a full disk) is raised
    naming ``path``, the file the caller asked for.
    """
    path = Path(path)
    try:
        tmp = _create_temporary(path)
    except OSError as exc:
        raise _naming(exc, path) from None
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        if exc.filename is not None and Path(exc.filename) == tmp:
            raise _naming(exc, path) from None
        raise
    finally:
        tmp.unlink(missing_ok=True)


def _naming(exc: OSError, path: Path) -> OSError:
    """``exc`` as the same system error on ``path``."""
    return OSError(exc.errno, exc.strerror or str(exc), str(path))


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)

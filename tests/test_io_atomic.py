"""Atomic outputs: whole or absent, and created with the mode the umask gives (not 0600)."""

from __future__ import annotations

import os
import stat

import pytest

from granpack.io.atomic import atomic_path, write_text_atomic
from granpack.io.json import write_json


@pytest.fixture
def umask():
    """Set the process umask for a test, restore it after."""
    saved = os.umask(0o022)
    os.umask(saved)
    yield lambda mask: os.umask(mask)
    os.umask(saved)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077])
def test_outputs_get_the_mode_of_the_umask(tmp_path, umask, mask):
    umask(mask)
    write_text_atomic(tmp_path / "a.txt", "x")
    write_json(tmp_path / "b.json", {"a": 1})
    with atomic_path(tmp_path / "c.bin") as tmp:
        with open(tmp, "wb") as fh:  # how gsd, matplotlib and meshio write: open the given name
            fh.write(b"x")
    for name in ("a.txt", "b.json", "c.bin"):
        assert _mode(tmp_path / name) == 0o666 & ~mask, name


def test_gsd_and_figure_outputs_are_readable_by_the_group(tmp_path, umask):
    from matplotlib.figure import Figure

    from granpack.figures import save_figure

    umask(0o022)
    fig = Figure()
    fig.add_subplot().plot([0, 1], [0, 1])
    for path in save_figure(fig, tmp_path, "line"):
        assert _mode(path) == 0o644, path


def test_a_failed_write_leaves_the_destination_and_no_temporary(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(path) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_a_folder_the_system_refuses_is_named_not_the_hidden_temporary(tmp_path, monkeypatch, capsys):
    """A write into a folder one cannot write: the error names the file asked for, and the CLI
    reports it as a system error (exit 1), one line."""
    import granpack.io.atomic as atomic
    from granpack.cli import main

    def refused(path):
        raise PermissionError(13, "Permission denied", str(path.parent / f".{path.stem}.0123abcd.tmp{path.suffix}"))

    monkeypatch.setattr(atomic, "_create_temporary", refused)
    target = tmp_path / "summary.json"
    with pytest.raises(PermissionError) as info:
        write_text_atomic(target, "{}")
    assert info.value.filename == str(target) and info.value.strerror == "Permission denied"
    config = tmp_path / "run.toml"
    config.write_text('n_particles = 5\nlateral_size = 3.0\n[[populations]]\nshape = "sphere"\nsize = 1.0\n'
                      'volume_fraction = 1.0\n')
    with pytest.raises(SystemExit) as exit_info:
        main(["run", str(config), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert exit_info.value.code == 1 and err.count("\n") == 1 and ".tmp" not in err
    assert err.startswith(f"error: {tmp_path / 'out' / 'config.toml'}: Permission denied")


def test_an_output_folder_the_system_cannot_create_is_a_system_error(tmp_path, monkeypatch):
    from pathlib import Path

    from granpack.io.atomic import output_folder

    def refused(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "mkdir", refused)
    with pytest.raises(OSError) as info:
        output_folder(tmp_path / "new")
    assert info.value.filename == str(tmp_path / "new") and "Permission denied" in info.value.strerror

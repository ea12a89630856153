"""``granpack check``: the mixture table on good input; exit 2 and one line on bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from granpack.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

GOOD = """\
seed = 3
n_particles = 3000
lateral_size = 8.0

[[populations]]
shape = "pinacoid"
size = 1.0
aspect = [1.0, 1.0]
volume_fraction = 0.7

[[populations]]
shape = "pinacoid"
size = 0.3333333333
aspect = [1.0, 1.0]
volume_fraction = 0.3

[solver]
time_step = 2e-3
"""


def good_with(old: str, new: str) -> str:
    assert old in GOOD
    return GOOD.replace(old, new, 1)


COPLANAR = '''
[[populations]]
shape = "polyhedron"
size = 1.0
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
volume_fraction = 1.0
'''
NON_CONVEX = '''
[[populations]]
shape = "polyhedron"
size = 1.0
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.2, 0.2]]
volume_fraction = 1.0
'''

BAD = {
    "not-toml": ("seed = = 1\n", "not valid TOML"),
    "unknown-key": (good_with("seed = 3", "seed = 3\ncolour = 1"), "colour: unknown key"),
    "unknown-solver-key": (good_with("time_step = 2e-3", "dt = 2e-3"), "solver.dt: unknown key"),
    "unknown-shape": (good_with('shape = "pinacoid"', 'shape = "cube"'), "populations[0].shape: must be"),
    "size-zero": (good_with("size = 1.0", "size = 0.0"), "populations[0].size: must be > 0"),
    "size-negative": (good_with("size = 0.3333333333", "size = -1"), "populations[1].size: must be > 0 (got -1)"),
    "aspect-below-1": (good_with("aspect = [1.0, 1.0]", "aspect = [0.5, 1.0]"), "populations[0].aspect:"),
    "shares-not-1": (good_with("volume_fraction = 0.3", "volume_fraction = 0.2"), "populations: volume_fraction values must sum to 1"),
    "share-negative": (good_with("volume_fraction = 0.3", "volume_fraction = -0.3"), "populations[1].volume_fraction: must be >= 0"),
    "n-zero": (good_with("n_particles = 3000", "n_particles = 0"), "n_particles: must be >= 1"),
    "lateral-too-small": (good_with("lateral_size = 8.0", "lateral_size = 2.0"), "lateral_size: must exceed 2 x (largest grain size"),
    "coplanar-vertices": (COPLANAR, "populations[0].vertices: vertices are coplanar"),
    "non-convex-vertices": (NON_CONVEX, "populations[0].vertices: vertex 4"),
    "time-step-zero": (good_with("time_step = 2e-3", "time_step = 0.0"), "solver.time_step: must be > 0"),
    "friction-negative": (good_with("time_step = 2e-3", "friction = -0.2"), "solver.friction: must be >= 0"),
    "restitution-above-1": (good_with("time_step = 2e-3", "restitution = 1.2"), "solver.restitution: must be <= 1"),
    "restitution-negative": (good_with("time_step = 2e-3", "restitution = -0.1"), "solver.restitution: must be >= 0"),
}


def run_main(argv, capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    return info.value.code, out, err


def test_check_prints_mixture_table(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "160")  # rich folds wide tables on a narrow console
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 0 and err == ""
    for text in ("pinacoid-1-1x1", "pinacoid-0.333333-1x1", "239", "2761", "0.700000", "0.700347", "0.299653",
                 "N = 3000", "lateral size = 8 d", "time step 0.002", "alert distance = 0.02 d (automatic)"):
        assert text in out, text


@pytest.mark.parametrize("name", sorted(BAD))
def test_check_bad_input_exits_2_with_one_line(name, tmp_path, capsys):
    text, expected = BAD[name]
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    code, out, err = run_main(["check", str(path)], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"error: {path}: "), err
    assert expected in err, err


def test_check_missing_file(tmp_path, capsys):
    path = tmp_path / "absent.toml"
    code, out, err = run_main(["check", str(path)], capsys)
    assert (code, out, err) == (2, "", f"error: {path}: no such file\n")


def test_python_dash_m_granpack(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(BAD["size-negative"][0])
    bad = subprocess.run([sys.executable, "-m", "granpack", "check", str(path)], capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr == f"error: {path}: populations[1].size: must be > 0 (got -1)\n"
    good = subprocess.run([sys.executable, "-m", "granpack", "check", str(EXAMPLES / "demo.toml")],
                          capture_output=True, text=True)
    assert good.returncode == 0 and good.stderr == ""
    assert "N = 300" in good.stdout and "lateral size = 3 d" in good.stdout

"""The names of a run folder's and a campaign folder's files have one home: io/run_folder.py."""

from __future__ import annotations

import ast
from pathlib import Path

from granpack.io import run_folder


def _docstrings(tree: ast.AST) -> set[int]:
    """The ids of the docstring nodes of a module, its classes and its functions."""
    owners = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, owners) and node.body and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)}


def test_no_other_module_spells_a_file_name():
    names = {value for key, value in vars(run_folder).items()
             if key.endswith(("_FILE", "_TABLE", "_PARQUET")) and isinstance(value, str)}
    assert {"final.gsd", "analysis.json", "runs.csv", "campaign.toml", "packing.png"} <= names
    package = Path(run_folder.__file__).resolve().parents[1]
    spelled = []
    for path in sorted(package.rglob("*.py")):
        if path == Path(run_folder.__file__).resolve():
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        prose = _docstrings(tree)
        spelled += [f"{path.relative_to(package)}:{node.lineno}: {node.value!r}" for node in ast.walk(tree)
                    if isinstance(node, ast.Constant) and node.value in names and id(node) not in prose]
    assert not spelled, spelled

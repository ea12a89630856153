"""The package's source keeps the shape its contributors agreed on: no function longer than
120 lines (a longer one does several things, each of which wants a name and a docstring)."""

from __future__ import annotations

import ast
from pathlib import Path

import granpack

MAX_FUNCTION_LINES = 120


def _long_functions(source: str, limit: int) -> list[tuple[str, int]]:
    """``(name, lines)`` of the functions of ``source`` longer than ``limit`` lines."""
    return [(node.name, node.end_lineno - node.lineno + 1) for node in ast.walk(ast.parse(source))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno + 1 > limit]


def test_the_rule_finds_a_long_function():
    body = "\n".join(f"    x{k} = {k}" for k in range(MAX_FUNCTION_LINES))
    assert _long_functions(f"def f():\n{body}\n", MAX_FUNCTION_LINES) == [("f", MAX_FUNCTION_LINES + 1)]
    assert _long_functions(f"def f():\n{body}\n", MAX_FUNCTION_LINES + 1) == []


def test_no_function_of_the_package_is_longer_than_120_lines():
    package = Path(granpack.__file__).resolve().parent
    long = [f"{path.relative_to(package)}: {name} ({lines} lines)" for path in sorted(package.rglob("*.py"))
            for name, lines in _long_functions(path.read_text(encoding="utf-8"), MAX_FUNCTION_LINES)]
    assert not long, long

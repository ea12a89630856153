"""The generated documentation pages (docs/hooks/reference.py) cover the code they describe.

The docs themselves are built by ``mkdocs build --strict`` in CI (the ``docs`` extra); these
tests only need the package, so that a config key, campaign key or command the generator
cannot describe fails here too.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from granpack.config import PopulationConfig, RunConfig

HOOKS = Path(__file__).resolve().parents[1] / "docs" / "hooks"


@pytest.fixture(scope="module")
def reference():
    sys.path.insert(0, str(HOOKS))
    try:
        spec = importlib.util.spec_from_file_location("granpack_docs_reference", HOOKS / "reference.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(HOOKS))


def test_config_reference_has_every_key(reference):
    from granpack.config import MOVED_SOLVER_KEYS, SETTING_TABLES, unit_of

    page = reference.config_reference()
    models = [RunConfig, PopulationConfig] + [type(getattr(RunConfig.model_fields[t], "default_factory")())
                                              for t in SETTING_TABLES]
    for model in models:
        for key in model.model_fields:
            if key not in {"populations", *SETTING_TABLES}:
                unit = unit_of(model, key)
                assert f"| `{key}` |" in page and (not unit or f"| {unit} |" in page), key
    for table in ("[[populations]]", *(f"[{t}]" for t in SETTING_TABLES)):
        assert f"## `{table}`" in page
    for old, (table, key) in MOVED_SOLVER_KEYS.items():
        assert f"| `{old}` | `{table}.{key}` |" in page
    assert "```toml\n# granpack run config, fully resolved" in page


def test_campaign_reference_has_every_key(reference):
    from granpack.campaign import spec

    page = reference.campaign_reference()
    for key in spec._TOP_KEYS + spec._MIXTURE_META:
        assert f"| `{key}` |" in page, key


def test_cli_reference_has_every_command_and_option(reference):
    import typer.main

    from granpack.cli import app

    page = reference.cli_reference()
    group = typer.main.get_command(app)
    for name, command in group.commands.items():
        assert f"## `granpack {name}`" in page, name
        for param in command.params:
            if getattr(param, "param_type_name", "") == "option":
                assert f"`{param.opts[0]}`" in page, (name, param.opts[0])


def test_committed_reference_pages_are_current(reference):
    """docs/reference/config.md, campaign.md and cli.md are committed so that they read in the
    repository (links from the other pages reach them there): they must be what the code gives
    now. After changing a setting, a campaign key or a command: ``python docs/hooks/reference.py``."""
    docs = HOOKS.parent
    for uri, make in reference.PAGES.items():
        committed = docs / uri
        assert committed.is_file(), f"{uri} is missing: run `python docs/hooks/reference.py`"
        assert committed.read_text(encoding="utf-8") == make(), f"{uri} is stale: run `python docs/hooks/reference.py`"


def test_rst_roles_and_math_become_markdown():
    sys.path.insert(0, str(HOOKS))
    try:
        from griffe_rst import rst_to_markdown
    finally:
        sys.path.remove(str(HOOKS))
    text = "Uses :func:`~granpack.config.load_config` and ``x``.\n\n.. math:: a = b\n\nExample::\n\n    f(1)\n"
    out = rst_to_markdown(text)
    assert '<autoref identifier="granpack.config.load_config" optional><code>load_config</code></autoref>' in out
    assert "`x`" in out and "``x``" not in out
    assert "$$\na = b\n$$" in out
    assert "Example:\n\n```\nf(1)\n```" in out


def _demo_figures():
    spec = importlib.util.spec_from_file_location("granpack_demo_figures", ROOT / "benchmarks" / "demo_figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ROOT = HOOKS.parents[1]


def test_the_demo_figures_quoted_by_the_pages_are_those_of_its_recorded_run():
    """README.md and docs/getting-started.md quote the demo's cap, rest time, solid fraction and
    cost between markers that ``benchmarks/demo_figures.py`` fills from a run; the cap must be the
    packaged demo config's, and every marked figure the recorded run's."""
    import json

    from granpack.cli import demo_config

    demo = _demo_figures()
    record = json.loads(demo.RECORD.read_text(encoding="utf-8"))
    assert record["max_time"] == f"{demo_config().equilibrium.max_time:g}"
    for page in demo.PAGES:
        text = page.read_text(encoding="utf-8")
        marked = demo.MARKER.findall(text)
        assert {"rest_time", "phi", "cpu_seconds"} <= {key for key, _ in marked}, page.name
        for key, value in marked:
            assert value == record[key], f"{page.name}: demo:{key} reads {value}, the recorded run {record[key]}"
    assert demo.fill("<!-- demo:phi -->0.1<!-- /demo -->", {"phi": "0.675"}) == "<!-- demo:phi -->0.675<!-- /demo -->"

"""Generated reference pages: the run config, the campaign file and the command line.

Nothing here is written by hand: the pages are rebuilt from the code at every ``mkdocs build`` /
``mkdocs serve``, so the site cannot drift from it, and are committed under ``docs/reference/`` so
that they read in the repository too (``tests/test_docs.py`` checks that the committed pages are
what the code gives now: run ``python docs/hooks/reference.py`` after changing a setting, a
campaign key or a command).

- ``reference/config.md``: every key of the run config from the pydantic models of
  :mod:`granpack.config` (type, default, constraints, description), and the demo config fully
  resolved by ``RunConfig.to_toml()``;
- ``reference/campaign.md``: the campaign file from :mod:`granpack.campaign.spec` (its keys and its
  module docstring) and the run-config keys a ``[base]`` table takes;
- ``reference/cli.md``: every command, argument and option of the ``granpack`` command, read from
  the typer app of :mod:`granpack.cli`.

``mkdocs.yml`` loads this file as a hook (``on_files``). Run as a script,
``python docs/hooks/reference.py [OUTDIR]`` writes the three pages into ``OUTDIR`` (default
``docs/``, the committed pages).
"""

from __future__ import annotations

import inspect
import sys
import tomllib
import types
import typing
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
if str(ROOT / "src") not in sys.path:
    sys.path.insert(1, str(ROOT / "src"))

from griffe_rst import rst_to_markdown  # noqa: E402

GENERATED = ("<!-- Generated from the code by `python docs/hooks/reference.py` (and at every docs build): "
             "edit the code, not this page. -->\n\n")


# --------------------------------------------------------------------------------------------- config

def _strip_annotated(tp):
    while typing.get_origin(tp) is typing.Annotated:
        tp = typing.get_args(tp)[0]
    return tp


def _type_name(tp) -> str:
    """A TOML-minded name of a field's type."""
    from pydantic import BaseModel

    tp = _strip_annotated(tp)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        rest = [a for a in args if a is not type(None)]
        return " or ".join(_type_name(a) for a in rest)
    if origin is typing.Literal:
        return " \\| ".join(f'`"{a}"`' if isinstance(a, str) else f"`{a}`" for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            inner = _strip_annotated(args[0])
            if isinstance(inner, type) and issubclass(inner, BaseModel):
                return "array of tables"
            return f"array of ({_type_name(args[0])})"
        return f"array of {len(args)} {_type_name(args[0])}s"
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return "table"
    return {float: "number", int: "integer", str: "string", bool: "boolean"}.get(tp, getattr(tp, "__name__", str(tp)))


def _constraints(field) -> str:
    import annotated_types as at

    out = []
    for item in field.metadata:
        for cls, attr, sign in ((at.Gt, "gt", ">"), (at.Ge, "ge", ">="), (at.Lt, "lt", "<"), (at.Le, "le", "<=")):
            if isinstance(item, cls):
                out.append(f"{sign} {getattr(item, attr)}")
        if isinstance(item, at.MinLen):
            out.append(f"at least {item.min_length} item(s)")
    return ", ".join(out)


def _default(name: str, field) -> str:
    from pydantic_core import PydanticUndefined

    if field.is_required():
        return "**required**"
    if field.default_factory is not None:
        return "(table)"
    value = field.default
    if value is PydanticUndefined:
        return ""
    if value is None:
        return "automatic" if name in ("alert_distance", "name") else "unset"
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, str):
        return f'`"{value}"`'
    if isinstance(value, tuple):
        return "`[" + ", ".join(repr(v) for v in value) + "]`"
    return f"`{value!r}`"


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _model_table(model, skip: tuple[str, ...] = ()) -> list[str]:
    from pydantic import BaseModel

    from granpack.config import unit_of

    lines = ["| key | type | default | unit | allowed | meaning |", "|---|---|---|---|---|---|"]
    for name, field in model.model_fields.items():
        if name in skip:
            continue
        tp = _strip_annotated(field.annotation)
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            continue  # nested tables get their own section
        lines.append(
            f"| `{name}` | {_type_name(field.annotation)} | {_default(name, field)} | {_cell(unit_of(model, name))} | "
            f"{_cell(_constraints(field))} | {_cell(field.description or '')} |"
        )
    return lines


def _doc(obj) -> str:
    """The first paragraph of a model's docstring (the rest is for developers)."""
    return rst_to_markdown(inspect.cleandoc(obj.__doc__ or "").split("\n\n", 1)[0])


def config_reference() -> str:
    """The run-config reference page (Markdown)."""
    import granpack.config as config
    from granpack.cli import demo_config

    run = config.RunConfig
    tables = [(name, _strip_annotated(f.annotation)) for name, f in run.model_fields.items()
              if f.default_factory is not None]
    lines = [
        "# Run config reference",
        "",
        GENERATED.strip(),
        "",
        "A run is one TOML file, read by `granpack check CONFIG.toml` and `granpack run CONFIG.toml --out DIR`.",
        "Lengths are in d (the largest grain's circumscribed diameter), times in sqrt(d/g)",
        "(see [Method > Units and the cell](../method/index.md#units-and-conventions)).",
        "Unknown keys are errors, and so are values of the wrong type (`n_particles = 3.0`, `size = \"1\"`;",
        "an integer is accepted where a number is expected): each error is one line naming the file and",
        "the key, e.g. `config.toml: populations[1].size: must be > 0 (got -1)`.",
        "`granpack run` writes the fully resolved config, every default filled in, to `DIR/config.toml`.",
        "",
        "## Top level",
        "",
        _doc(run),
        "",
        *_model_table(run),
        "",
        "`lateral_size` must exceed 2 x (largest grain size + alert distance), so that a pair of grains",
        "interacts through at most one periodic image (see",
        "[Method > Contact detection](../method/contact-detection.md#broad-phase)); in a box or a cylinder",
        "(`[container]`) it is the inside side or diameter, and the same bound keeps two of the largest",
        "grains side by side ([Containers](../method/contact-detection.md#containers)).",
        "",
        "## `[[populations]]`",
        "",
        _doc(config.PopulationConfig),
        "One `[[populations]]` table per population; at least one.",
        "",
        *_model_table(config.PopulationConfig),
        "",
        "The shares of all populations must sum to 1 (within "
        f"{config.SHARE_TOLERANCE:g}) and their names must differ. How shares become grain counts:",
        "[Method > Grains](../method/grains.md#mixtures-volume-shares-to-counts).",
        "",
        "## `[populations.grading]`",
        "",
        _doc(config.GradingConfig),
        "The table follows its `[[populations]]` table; the population then has no `size`. Each curve takes",
        "its own keys: `fuller` `d_min`, `d_max`, `exponent`; `sieves` `sieves`, `percent_passing` and",
        "optionally `sieve_unit`; `lognormal` `mean`, `polydispersity` and optionally `cut`.",
        "",
        *_model_table(config.GradingConfig),
    ]
    for name, model in tables:
        lines += ["", f"## `[{name}]`", "", _doc(model), "", *_model_table(model)]
    lines += [
        "",
        "## Config files of granpack 0.1.0",
        "",
        "granpack 0.1.0 had one flat `[solver]` table. Such files (and the runs and checkpoints made",
        "with them) are still read: each of these keys of `[solver]` is taken as the key of today's",
        "table, and `granpack check` and `granpack run` name the new keys in a warning. Giving a",
        "setting in both places is an error.",
        "",
        "| `[solver]` key of 0.1.0 | today's key |",
        "|---|---|",
        *[f"| `{old}` | `{table}.{key}` |" for old, (table, key) in config.MOVED_SOLVER_KEYS.items()],
    ]
    lines += [
        "",
        "## Example: the demo config, fully resolved",
        "",
        "`granpack demo` runs this config (`examples/demo.toml`); this is what its `config.toml` holds,",
        "with every default written out:",
        "",
        "```toml",
        demo_config().to_toml().rstrip(),
        "```",
        "",
    ]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------- campaign

#: what each campaign key is; the generator fails if spec.py has a key not described here
_CAMPAIGN_TOP = {
    "replicas": ("integer >= 1", "`1`", "Runs per mixture; their seeds are `seed, seed + 1, ...` with `seed` the resolved `base.seed`."),
    "base": ("table", "empty", "Every run-config key but `populations` (see below): the settings shared by all runs."),
    "mixtures": ("array of tables", "**required**", "One `[[mixtures]]` entry per mixture, at least one."),
}
_CAMPAIGN_MIXTURE = {
    "name": ("string", "**required**", "Folder name of the mixture's runs (letters, digits, `.`, `_`, `-`; not starting with `.`, `_` or `-`); unique."),
    "family": ("string", "none", "The mixture series it belongs to (a curve of the campaign figures), e.g. `\"flat\"`."),
    "share": ("number in [0, 1]", "none", "Volume share of the substituted grains that the mixture stands for (the figures' x axis)."),
    "populations": ("array of tables", "**required**", "The run config's `[[populations]]`, as `[[mixtures.populations]]`."),
}


def campaign_reference() -> str:
    """The campaign-file reference page (Markdown)."""
    import granpack.campaign.spec as spec
    from granpack.config import RunConfig

    for keys, described in ((spec._TOP_KEYS, _CAMPAIGN_TOP), (spec._MIXTURE_META, _CAMPAIGN_MIXTURE)):
        missing = set(keys) - set(described)
        if missing:
            raise RuntimeError(f"docs/hooks/reference.py: describe the campaign key(s) {sorted(missing)}")

    def table(described, keys) -> list[str]:
        rows = ["| key | type | default | meaning |", "|---|---|---|---|"]
        rows += [f"| `{k}` | {described[k][0]} | {described[k][1]} | {described[k][2]} |" for k in keys]
        return rows

    base_keys = [k for k in RunConfig.model_fields if k != "populations"]
    example = (ROOT / "examples" / "study-small.toml").read_text(encoding="utf-8")
    start = example.index("replicas")
    head = example[start:]
    first_mixture_end = head.index("[[mixtures]]", head.index("[[mixtures]]") + 1)
    lines = [
        "# Campaign file reference",
        "",
        GENERATED.strip(),
        "",
        "`granpack campaign CAMPAIGN.toml --out DIR` runs every (mixture, replica) of a campaign file",
        "as one task (see the [tutorial](../tutorial.md) and the [CLI reference](cli.md#granpack-campaign)).",
        "",
        "## What the file holds",
        "",
        rst_to_markdown(inspect.cleandoc(spec.__doc__)).split("\n", 1)[1].strip(),
        "",
        "## Top-level keys",
        "",
        *table(_CAMPAIGN_TOP, spec._TOP_KEYS),
        "",
        "No other top-level key is allowed.",
        "",
        "## `[base]`",
        "",
        "Any key of the [run config](config.md) but `populations`: "
        + ", ".join(f"[`{k}`](config.md#{'top-level' if k not in ('solver', 'equilibrium', 'deposit', 'output') else k})"
                    for k in base_keys)
        + ". Tables are written `[base.solver]`, `[base.equilibrium]`, ... Absent keys take the run",
        "config's defaults.",
        "",
        "## `[[mixtures]]`",
        "",
        *table(_CAMPAIGN_MIXTURE, spec._MIXTURE_META),
        "",
        "Any other key of a mixture entry is a run-config key that **overrides** `[base]` for this mixture",
        "only (`n_particles = 600`, `lateral_size = 4.0`, `[mixtures.equilibrium]`, ...); tables are merged",
        "key by key. `seed` is not allowed there: seeds come from `base.seed` and the replica number.",
        "Every run config is validated before anything runs, so a typo fails at once with one line",
        "naming the mixture and the key.",
        "",
        "## Example",
        "",
        "The start of `examples/study-small.toml` (its [base] and first mixture):",
        "",
        "```toml",
        head[:first_mixture_end].rstrip(),
        "```",
        "",
        "## Outputs",
        "",
        "In `--out DIR`: one run folder per (mixture, replica), `DIR/<mixture>/seed-<seed>/`, holding the",
        "[run's files](outputs.md#run-folder) plus `task.json` (the task it was started for) and, after a",
        "failure, `error.txt`; and the tables `runs.csv`, `runs.parquet` and `summary.csv`",
        "([Outputs > Campaign folder](outputs.md#campaign-folder)).",
        "",
    ]
    # the example must stay valid TOML
    tomllib.loads(head[:first_mixture_end])
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------------ CLI

def _param_type(param) -> str:
    """The value type of a click / typer parameter (works with typer's own click and with click)."""
    if getattr(param, "is_flag", False):
        return "flag"
    kind = getattr(param, "type", None)
    name = getattr(kind, "name", None)
    if not name:
        annotation = getattr(getattr(param, "type_descriptor", None), "annotation", None)
        if typing.get_origin(annotation) is list:
            annotation = typing.get_args(annotation)[0]
        name = {Path: "path", str: "text", int: "integer", float: "number", bool: "flag"}.get(annotation, "")
        if name == "flag":
            return name
    return name.lower() if name else ""


def _param_row(param) -> str:
    kind = getattr(param, "param_type_name", "option")
    if kind == "argument":
        name = f"`{param.name.upper()}`"
    else:
        names = list(param.opts) + list(getattr(param, "secondary_opts", []) or [])
        name = ", ".join(f"`{n}`" for n in names)
    type_name = _param_type(param)
    if getattr(param, "multiple", False):
        type_name += " (repeatable)"
    default = getattr(param, "default", None)
    if getattr(param, "required", False):
        shown = "**required**"
    elif default is None or callable(default) or default is False or default == ():
        shown = ""
    else:
        shown = f"`{default}`"
    return f"| {name} | {kind} | {type_name} | {shown} | {_cell(getattr(param, 'help', '') or '')} |"


def _command_section(cmd, path: str, level: int) -> list[str]:
    params = [p for p in cmd.params if not getattr(p, "hidden", False)]
    arguments = [p.name.upper() for p in params if getattr(p, "param_type_name", "") == "argument"]
    usage = " ".join([path, "[OPTIONS]", *arguments] + (["COMMAND [ARGS]..."] if hasattr(cmd, "commands") else []))
    help_text = inspect.cleandoc(getattr(cmd, "help", None) or "")
    lines = [f"{'#' * level} `{path}`", "", "```", usage, "```", "", help_text, ""]
    lines += ["| name | kind | type | default | meaning |", "|---|---|---|---|---|"]
    lines += [_param_row(p) for p in params]
    lines.append("| `--help` | option | flag | | Show the command's help and exit. |")
    lines.append("")
    return lines


def cli_reference() -> str:
    """The command-line reference page (Markdown)."""
    import typer.main

    from granpack.cli import app

    group = typer.main.get_command(app)
    lines = [
        "# Command line reference",
        "",
        GENERATED.strip(),
        "",
        "Every command prints its help with `--help`. Bad input (a config key, a file, an option) ends",
        "with one line `error: ...` on stderr naming what is wrong, and exit status 2.",
        "",
    ]
    lines += _command_section(group, "granpack", 2)
    for name in sorted(group.commands):
        cmd = group.commands[name]
        if getattr(cmd, "hidden", False):
            continue
        lines += _command_section(cmd, f"granpack {name}", 2)
    return "\n".join(lines)


# -------------------------------------------------------------------------------------------- hooks

PAGES = {
    "reference/config.md": config_reference,
    "reference/campaign.md": campaign_reference,
    "reference/cli.md": cli_reference,
}


def on_files(files, config):
    """MkDocs hook: add the generated pages to the site's files."""
    from mkdocs.structure.files import File

    for uri, make in PAGES.items():
        existing = files.get_file_from_path(uri)
        if existing is not None:
            files.remove(existing)
        files.append(File.generated(config, uri, content=make()))
    return files


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs"
    for uri, make in PAGES.items():
        target = out / uri
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(make(), encoding="utf-8")
        print(target)

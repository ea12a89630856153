"""Griffe extension: the reStructuredText bits of granpack's docstrings, rendered as Markdown.

granpack's docstrings are Google style with a few Sphinx idioms (``.. math::`` blocks, roles such
as :func:`x` and :math:`x`, double-backtick literals, ``Example::`` literal blocks). mkdocstrings
renders docstrings as Markdown, so this extension rewrites those idioms before parsing:

- ``.. math:: f`` and indented ``.. math::`` blocks -> ``$$ ... $$`` (pymdownx.arithmatex);
- :math:`x` -> ``$x$``;
- :func:, :class:, :mod:, :meth:, :attr:, :data:, :exc: -> an optional cross-reference (a link
  when the target is documented, plain code otherwise; ``~`` shows the last name only);
- double backticks -> single backticks; ``Text::`` + indented block -> ``Text:`` + fenced code.

Used by ``mkdocs.yml`` (``plugins.mkdocstrings.handlers.python.options.extensions``).
"""

from __future__ import annotations

import re

try:  # the docs extra; the tests import rst_to_markdown without it
    import griffe
except ImportError:  # pragma: no cover
    griffe = None

_ROLE = re.compile(r":(?:py:)?(func|class|mod|meth|attr|data|exc|obj):`(~?)([^`]+)`")
_MATH_ROLE = re.compile(r":math:`([^`]+)`")
_LITERAL = re.compile(r"(?<!`)``(?!`)(.+?)(?<!`)``(?!`)", re.S)  # not the ``` of code fences


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _blocks(text: str) -> str:
    """``.. math::`` directives and ``::`` literal blocks -> arithmatex / fenced code."""
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        lead = " " * _indent(line)
        if stripped.startswith(".. math::"):
            # reStructuredText nests by 2 spaces, Markdown by 4: a block indented by 2 under a
            # list item would end up inside a paragraph, so round the indent down to a multiple of 4
            math_lead = " " * (4 * (len(lead) // 4))
            first = stripped[len(".. math::"):].strip()
            body = [first] if first else []
            i += 1
            while i < len(lines) and (not lines[i].strip() or _indent(lines[i]) > len(lead)):
                body.append(lines[i].strip())
                i += 1
            while body and not body[-1]:
                body.pop()
            groups: list[list[str]] = [[]]
            for b in body:
                if b:
                    groups[-1].append(b)
                elif groups[-1]:
                    groups.append([])
            if out and out[-1].strip():
                out.append("")
            for group in groups:
                if group:
                    out += [math_lead + "$$", *(math_lead + g for g in group), math_lead + "$$", ""]
            continue
        if stripped.endswith("::") and not stripped.startswith(".."):
            # a literal block follows (after a blank line, indented further)
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            if j < len(lines) and _indent(lines[j]) > len(lead):
                text_part = line.rstrip()[:-2].rstrip()
                if text_part.strip():
                    out.append(text_part + ":")
                    out.append("")
                block = []
                k = j
                while k < len(lines) and (not lines[k].strip() or _indent(lines[k]) > len(lead)):
                    block.append(lines[k])
                    k += 1
                while block and not block[-1].strip():
                    block.pop()
                cut = min(_indent(b) for b in block if b.strip())
                out += [lead + "```", *(lead + b[cut:] for b in block), lead + "```", ""]
                i = k
                continue
        out.append(line)
        i += 1
    return "\n".join(out)


def rst_to_markdown(text: str, module: str | None = None, known: set[str] | frozenset = frozenset()) -> str:
    """The Markdown form of a granpack docstring (see the module docstring).

    Args:
        text: the docstring.
        module: dotted path of the module the docstring belongs to, to qualify short role targets.
        known: names defined in that module (a short target is qualified only if it is one).
    """
    text = _blocks(text)
    text = _MATH_ROLE.sub(lambda m: f"${m.group(1)}$", text)

    def role(m: re.Match) -> str:
        tilde, target = m.group(2), m.group(3).strip()
        target = target.rstrip("()")
        shown = target.rsplit(".", 1)[-1] if tilde else target
        if "." not in target and module and target in known:
            target = f"{module}.{target}"
        return f'<autoref identifier="{target}" optional><code>{shown}</code></autoref>'

    text = _ROLE.sub(role, text)
    return _LITERAL.sub(lambda m: f"`{m.group(1)}`", text)


class RstToMarkdown(griffe.Extension if griffe is not None else object):
    """Rewrites every docstring of a package with :func:`rst_to_markdown` once it is loaded."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:  # noqa: ARG002
        self._walk(pkg, set())

    def _walk(self, obj: griffe.Object, seen: set[str]) -> None:
        if obj.path in seen:
            return
        seen.add(obj.path)
        module = obj if obj.is_module else obj.module
        if obj.docstring is not None:
            obj.docstring.value = rst_to_markdown(obj.docstring.value, module.path, set(module.members))
        for member in obj.members.values():
            if not member.is_alias:
                self._walk(member, seen)

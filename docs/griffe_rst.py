"""Griffe extension for the API page: the docstrings' reStructuredText roles as Markdown.

The docstrings are numpy-style with Sphinx roles (``:math:`x```, ``.. math::``, ``:class:`X```,
double-backquoted literals). mkdocstrings renders Markdown, so before rendering this rewrites
them: math to ``$...$`` / ``$$...$$`` (``pymdownx.arithmatex``, shown by MathJax), references
and literals to code spans. The source files are left as they are.
"""

from __future__ import annotations

import re

import griffe

_MATH_ROLE = re.compile(r":math:`([^`]+)`")
_REF_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|obj|exc|const):`~?([^`]+)`")
_LITERAL = re.compile(r"(?<!`)``([^`]+?)``(?!`)")
_MATH_DIRECTIVE = re.compile(r"^(\s*)\.\. math::\s*(.*)$")
_ITEM = re.compile(r"^\s*(?:[-*]|\d+\.) ")


def _lists_apart(text: str) -> str:
    """A blank line before each list item that follows wrapped text: reST reads the item without
    it, Python-Markdown reads it as the text's continuation."""
    out: list[str] = []
    for line in text.split("\n"):
        if _ITEM.match(line) and out and out[-1].strip() and not _ITEM.match(out[-1]):
            out.append("")
        out.append(line)
    return "\n".join(out)


def _ref(match: re.Match[str]) -> str:
    target = match.group(1)
    if match.group(0).split("`", 1)[1].startswith("~"):
        target = target.rsplit(".", 1)[-1]
    return f"`{target}`"


def _math_blocks(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = _MATH_DIRECTIVE.match(lines[i])
        if not m:
            out.append(lines[i])
            i += 1
            continue
        indent = m.group(1)
        body = [m.group(2)] if m.group(2).strip() else []
        i += 1
        while i < len(lines) and (not lines[i].strip() or len(lines[i]) - len(lines[i].lstrip()) > len(indent)):
            body.append(lines[i].strip())
            i += 1
        while body and not body[-1]:
            body.pop()
        while body and not body[0]:
            body.pop(0)
        trailing = [""] if i < len(lines) else []
        out.extend(["", f"{indent}$$", *(f"{indent}{b}" for b in body if b), f"{indent}$$", *trailing])
    return "\n".join(out)


def rst_to_markdown(text: str) -> str:
    """The docstring ``text`` with its reST math, references and literals as Markdown."""
    text = _lists_apart(_math_blocks(text))
    text = _MATH_ROLE.sub(lambda m: f"${m.group(1)}$", text)
    text = _REF_ROLE.sub(_ref, text)
    return _LITERAL.sub(lambda m: f"`{m.group(1)}`", text)


class RstToMarkdown(griffe.Extension):
    """Rewrite every loaded object's docstring with :func:`rst_to_markdown`."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: object) -> None:
        if obj.docstring is not None:
            obj.docstring.value = rst_to_markdown(obj.docstring.value)

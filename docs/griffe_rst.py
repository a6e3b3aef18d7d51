"""A griffe extension for the API reference: the reStructuredText bits of numpydoc docstrings.

terracone's docstrings are numpydoc (the style of numpy, scipy and pvlib), whose prose
uses a few reStructuredText constructs that Markdown does not know.  Before mkdocstrings
renders a docstring, this extension rewrites them:

* cross-reference roles, ``:func:`~terracone.physics.cone.cone_index``` and the like
  (``func``, ``class``, ``meth``, ``mod``, ``data``, ``attr``, ``obj``, ``exc``), become
  code spans (``cone_index``; the full path without ``~``; the text of ``text <target>``);
* citations ``[1]_`` become ``[1]`` and reference entries ``.. [1] ...`` become ``[1] ...``;
* ``.. math:: expression`` becomes a code span of the expression;
* simple tables (columns between lines of ``=====  =====``) become Markdown tables;
* ``::`` closing a paragraph before a literal block becomes ``:`` (the indented block
  stays a code block);
* a unit in brackets after a bracketed value (``in [lo, hi] [m]``) is escaped, lest
  Markdown read the pair as a reference link.

Used by mkdocs.yml (``extensions: [docs/griffe_rst.py]``); not part of the package.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|obj|exc|const):`([^`]+)`")
CITATION = re.compile(r"(\[[0-9#*]+\])_")
REFERENCE = re.compile(r"^(\s*)\.\. (\[[0-9#*]+\])", re.MULTILINE)
MATH = re.compile(r"^(\s*)\.\. math::\s*(.+)$", re.MULTILINE)
UNIT_AFTER_BRACKETS = re.compile(r"\]([ \t]*)\[")
BORDER = re.compile(r"^=+(?: +=+)+ *$")
LITERAL = re.compile(r"(\S)::$", re.MULTILINE)


def table_rows(lines: list[str]) -> list[list[str]]:
    """The rows of one simple table (its lines from border to border, both included).

    A line whose first cell is blank continues the row above it.
    """
    spans = [m.span() for m in re.finditer(r"=+", lines[0])]
    rows: list[list[str]] = []
    for line in lines[1:]:
        if BORDER.match(line):
            continue
        ends = [s for s, _ in spans[1:]] + [len(line) + 1]
        cells = [line[s:e].strip() for (s, _), e in zip(spans, ends, strict=True)]
        if rows and not cells[0]:
            rows[-1] = [f"{a} {b}".strip() for a, b in zip(rows[-1], cells, strict=True)]
        else:
            rows.append(cells)
    return rows


def simple_tables(text: str) -> str:
    """Each reStructuredText simple table of ``text`` as a Markdown table."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        if not BORDER.match(lines[i]):
            out.append(lines[i])
            i += 1
            continue
        j = i  # the closing border: the last border before a blank line or the end
        for k in range(i + 1, len(lines)):
            if not lines[k].strip():
                break
            if BORDER.match(lines[k]):
                j = k
        rows = table_rows(lines[i : j + 1])
        cells = [[c.replace("|", "\\|") for c in row] for row in rows]
        out.append("| " + " | ".join(cells[0]) + " |")
        out.append("|" + "---|" * len(cells[0]))
        out.extend("| " + " | ".join(row) + " |" for row in cells[1:])
        i = j + 1
    return "\n".join(out)


def role_text(match: re.Match[str]) -> str:
    """The code span of one role: its explicit text, its last part (``~``) or its target."""
    body = match.group(1).strip()
    explicit = re.fullmatch(r"(.+?)\s*<(.+)>", body)
    if explicit:
        return f"`{explicit.group(1)}`"
    if body.startswith("~"):
        return f"`{body[1:].rsplit('.', 1)[-1]}`"
    return f"`{body.lstrip('.')}`"


def markdown(text: str) -> str:
    """A numpydoc docstring's reStructuredText roles, citations and math as Markdown."""
    text = simple_tables(text)
    text = LITERAL.sub(r"\1:", text)
    text = ROLE.sub(role_text, text)
    text = CITATION.sub(r"\1", text)
    text = REFERENCE.sub(r"\1\2", text)
    text = MATH.sub(lambda m: f"{m.group(1)}`{m.group(2).strip()}`", text)
    return UNIT_AFTER_BRACKETS.sub(r"]\1\\[", text)


class RstToMarkdown(griffe.Extension):
    """Rewrite every docstring of the loaded objects with :func:`markdown`."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)

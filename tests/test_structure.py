"""The shape of the package (issue 13): short functions, no private names shared
between modules, and a library that never imports its command line.

These read the source with :mod:`ast`; nothing is imported or run.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "terracone"
#: Longest function allowed, in lines from ``def`` to its last line (issue 13),
#: and the longest body of code, its docstring not counted (the brief's "about 100").
MAX_LINES = 120
MAX_CODE_LINES = 100


def modules() -> list[tuple[str, ast.Module]]:
    """(path relative to terracone/, parsed module) of every module of the package."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        out.append((path.relative_to(PACKAGE).as_posix(), ast.parse(path.read_text())))
    return out


def function_lengths(tree: ast.Module) -> list[tuple[int, str, int]]:
    """(lines without the docstring, name, first line) of every function and method."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            n = node.end_lineno - node.lineno + 1
            first = node.body[0]
            if (
                isinstance(first, ast.Expr)
                and isinstance(first.value, ast.Constant)
                and isinstance(first.value.value, str)
            ):
                n -= first.end_lineno - first.lineno + 1
            out.append((n, node.name, node.lineno))
    return out


def is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def imported_names(node: ast.ImportFrom | ast.Import) -> list[str]:
    """The dotted names an import statement binds from other modules."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    base = node.module or ""
    return [base] + [f"{base}.{a.name}" if base else a.name for a in node.names]


def test_the_measures_by_hand():
    tree = ast.parse(
        "def f(x):\n"
        '    """Doc\n\n    more doc\n    """\n'
        "    y = x\n"
        "    return y\n"
        "class C:\n"
        "    def m(self):\n"
        "        return 1\n"
        "from .a import _b, c\n"
        "from ._d import e\n"
        "from . import __version__\n"
    )
    assert sorted(function_lengths(tree)) == [(2, "m", 9), (3, "f", 1)]
    assert sorted(total_lengths(tree)) == [(2, "m", 9), (7, "f", 1)]
    names = [n for s in tree.body if isinstance(s, ast.ImportFrom) for n in imported_names(s)]
    assert [n for n in names if any(is_private(p) for p in n.split("."))] == ["a._b", "_d", "_d.e"]


def total_lengths(tree: ast.Module) -> list[tuple[int, str, int]]:
    """(lines from ``def`` to the last line, docstring included, name, first line)."""
    return [
        (node.end_lineno - node.lineno + 1, node.name, node.lineno)
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
    ]


@pytest.mark.parametrize(
    "measure, limit", [(total_lengths, MAX_LINES), (function_lengths, MAX_CODE_LINES)]
)
def test_no_function_is_too_long(measure, limit):
    rows = sorted(
        ((n, f"{path}:{line} {name}") for path, tree in modules()
         for n, name, line in measure(tree)),
        reverse=True,
    )  # fmt: skip
    longest = "\n".join(f"{n:4d} {where}" for n, where in rows[:15])
    print(f"longest functions ({measure.__name__}):\n{longest}")
    too_long = [where for n, where in rows if n > limit]
    assert rows[0][0] <= limit, f"{len(too_long)} over {limit} lines:\n{longest}"


def test_no_private_name_is_imported_from_another_module():
    offenders = []
    for path, tree in modules():
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom | ast.Import):
                continue
            if isinstance(node, ast.ImportFrom) and not (
                node.level or (node.module or "").split(".")[0] == "terracone"
            ):
                continue  # third-party modules are theirs to name
            for name in imported_names(node):
                if any(is_private(part) for part in name.split(".")):
                    offenders.append(f"{path}:{node.lineno} {name}")
    assert offenders == []


def test_no_library_module_imports_the_cli():
    offenders = []
    for path, tree in modules():
        if path.startswith("cli/") or path == "__main__.py":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom | ast.Import):
                names = imported_names(node)
                if any(n == "cli" or n.endswith(".cli") or ".cli." in n for n in names):
                    offenders.append(f"{path}:{node.lineno}")
    assert offenders == []

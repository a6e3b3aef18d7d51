"""The shape of the package (issues 13 and 20): short functions, no private names
shared between modules, a library that never imports its command line, no import
cycle (function-level imports included), no import of a higher layer, no module
``__getattr__`` outside package ``__init__`` files, result classes in one place.

These read the source with :mod:`ast`; nothing is imported or run.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "terracone"
#: Longest function allowed, in lines from ``def`` to its last line (issue 13),
#: and the longest body of code, its docstring not counted (the brief's "about 100").
MAX_LINES = 120
MAX_CODE_LINES = 100


@functools.cache
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


# ---------------------------------------------------------------------------
# the module graph (issue 20): no import cycles, no upward imports
# ---------------------------------------------------------------------------

#: Rank of each top folder or top module of the package (docs/architecture.md):
#: physics -> data/io -> inverse -> apps -> report -> cli; a module imports only
#: modules of its own rank or below.  The package's own ``__init__`` re-exports the
#: data model and the forward physics, so it sits with data (anything may read
#: ``terracone.__version__``).
RANKS = {
    "physics": 0,
    "vocabulary": 0,
    "jit": 0,
    "data": 1,
    "notebook": 1,
    "io": 1,
    "result": 1,
    "resultunits": 1,
    "__init__": 1,
    "inverse": 2,
    "apps": 3,
    "report": 4,
    "cli": 5,
    "__main__": 5,
}
#: Classes named ``*Result`` outside result.py and inverse/: Sobol indices.
RESULT_CLASSES_ALLOWED = {("apps/sensitivity.py", "SobolResult")}


def module_name(path: str) -> str:
    """Dotted name of a module from its path relative to terracone/ (a package: its __init__)."""
    parts = ["terracone", *path.removesuffix(".py").split("/")]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_edges(path: str, tree: ast.Module, known: set[str]) -> set[str]:
    """Modules of ``known`` that the module at ``path`` imports, function-level imports included.

    Relative imports are resolved; ``from pkg import sub`` is an edge to the
    submodule ``pkg.sub`` when it is one, else to ``pkg`` (its ``__init__``).
    """
    name = module_name(path)
    package = name.split(".") if path.endswith("__init__.py") else name.split(".")[:-1]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name in known}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package[: len(package) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            if base in known:
                out |= {
                    f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names
                }
    out.discard(name)
    return out


def module_graph(mods: list[tuple[str, ast.Module]]) -> dict[str, set[str]]:
    known = {module_name(p) for p, _ in mods}
    return {module_name(p): import_edges(p, t, known) for p, t in mods}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def rank_of(name: str) -> int:
    parts = name.split(".")
    return RANKS[parts[1] if len(parts) > 1 else "__init__"]


def upward_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) for every import of a module of a higher rank."""
    return sorted(
        (v, w) for v, ws in graph.items() for w in ws if rank_of(w) > rank_of(v)
    )  # fmt: skip


def test_the_graph_measures_by_hand():
    mods = [
        ("__init__.py", ast.parse("from terracone.data import X\n")),
        ("data.py", ast.parse("import numpy\nfrom terracone.physics import cone\n")),
        ("physics/__init__.py", ast.parse("")),
        ("physics/cone.py", ast.parse("def f():\n    from ..data import X\n")),  # lazy, relative
        ("io/__init__.py", ast.parse("from .scan import Y\n")),
        ("io/scan.py", ast.parse("from terracone.io import Z\n")),  # its own package's __init__
        ("cli.py", ast.parse("from terracone import data, physics\n")),
    ]
    g = module_graph(mods)
    assert g["terracone.physics.cone"] == {"terracone.data"}
    assert g["terracone.cli"] == {"terracone.data", "terracone.physics"}
    assert g["terracone.data"] == {"terracone.physics.cone"}
    assert sorted(import_cycles(g)) == [
        ["terracone.data", "terracone.physics.cone"],
        ["terracone.io", "terracone.io.scan"],
    ]
    assert upward_imports(g) == [("terracone.physics.cone", "terracone.data")]
    # an application drawing with report/ imports upward (no exception since issue 28)
    drawing = [
        ("apps/reproduce.py", ast.parse("from terracone.report import html\n")),
        ("report/__init__.py", ast.parse("")),
        ("report/html.py", ast.parse("")),
    ]
    assert upward_imports(module_graph(drawing)) == [
        ("terracone.apps.reproduce", "terracone.report.html")
    ]
    with pytest.raises(KeyError):
        rank_of("terracone.maps.grid")  # a new folder must be given its place
    del g["terracone.physics.cone"]
    assert import_cycles(g) == [["terracone.io", "terracone.io.scan"]]


def test_no_import_cycle():
    assert import_cycles(module_graph(modules())) == []


def test_every_module_has_a_layer_and_imports_none_above_it():
    graph = module_graph(modules())
    for name in graph:
        rank_of(name)  # a KeyError names a folder or module that needs its place in RANKS
    assert upward_imports(graph) == []


def getattr_modules(mods: list[tuple[str, ast.Module]]) -> list[str]:
    """Modules, other than a package's __init__, that define a module-level __getattr__."""
    return [
        path
        for path, tree in mods
        if not path.endswith("__init__.py")
        and any(isinstance(n, ast.FunctionDef) and n.name == "__getattr__" for n in tree.body)
    ]


def result_classes(mods: list[tuple[str, ast.Module]]) -> list[tuple[str, str]]:
    """(path, class) of every class named ``*Result`` outside result.py and inverse/."""
    return [
        (path, n.name)
        for path, tree in mods
        if path != "result.py" and not path.startswith("inverse/")
        for n in tree.body
        if isinstance(n, ast.ClassDef) and n.name.endswith("Result")
    ]


def test_getattr_and_result_classes_by_hand():
    mods = [
        ("io/__init__.py", ast.parse("def __getattr__(name):\n    pass\n")),
        (
            "io/stream.py",
            ast.parse("def __getattr__(name):\n    pass\nclass ScanResult:\n    pass\n"),
        ),
        ("inverse/x.py", ast.parse("class FitResult:\n    pass\n")),
        ("result.py", ast.parse("class PredictionResult:\n    pass\n")),
    ]
    assert getattr_modules(mods) == ["io/stream.py"]
    assert result_classes(mods) == [("io/stream.py", "ScanResult")]


def test_no_module_getattr_outside_package_inits():
    assert getattr_modules(modules()) == []


def test_results_are_classes_of_result_or_inverse():
    assert [c for c in result_classes(modules()) if c not in RESULT_CLASSES_ALLOWED] == []

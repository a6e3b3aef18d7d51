"""terracone.text: the plain-text tables the CLI and the demo share."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from terracone.data import PlateTest, TerrainParameters
from terracone.inverse.evaluate import cross_table
from terracone.text import evaluate_text, format_value, table

PACKAGE = Path(__file__).resolve().parents[1] / "terracone"


def test_format_value_by_hand():
    assert format_value(None) == "-"
    assert format_value(float("nan")) == "-"
    assert format_value(np.float64(np.inf)) == "-"
    assert format_value(1234.5678) == "1235"
    assert format_value(0.000123456, digits=2) == "0.00012"
    assert format_value(7) == "7"
    assert format_value("LS_1") == "LS_1"


def test_table_layout_by_hand():
    text = table(["id", "value"], [["a", 1.5], ["bbb", None]])
    # first column left-aligned, the others right-aligned, two spaces apart
    assert text.splitlines() == [
        "id   value",
        "---  -----",
        "a      1.5",
        "bbb      -",
    ]


def test_evaluate_text_converts_units_at_the_edge():
    # a plate generated from the very parameters evaluated: R = R2 = 1, RMSD = 0
    from terracone.plate import plate_pressure

    s = np.linspace(0.01, 0.1, 10)
    p = TerrainParameters(102.0, 5301.0, 0.79)
    plate = PlateTest(
        "A", 0.0508, "circular", s, plate_pressure(s, kc=102.0, kphi=5301.0, n=0.79, radius=0.0508)
    )
    rows = cross_table([("given", p)], [plate])
    si = evaluate_text(rows, "si").splitlines()
    us = evaluate_text(rows, "us").splitlines()
    assert "b [m]" in si[0] and "b [in]" in us[0]
    assert si[2].split()[:3] == ["given", "A", "0.0508"]
    assert us[2].split()[:3] == ["given", "A", "2"]  # 0.0508 m = 2 in
    assert si[2].split()[3:5] == ["1", "1"]


def test_no_library_module_imports_the_cli():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.name in ("cli.py", "__main__.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                names = [base] + [f"{base}.{a.name}".lstrip(".") for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            if any(n == "cli" or n.endswith(".cli") for n in names):
                offenders.append(str(path.relative_to(PACKAGE)))
    assert offenders == []

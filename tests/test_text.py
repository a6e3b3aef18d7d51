"""terracone.report.text: the plain-text tables the CLI and the demo share."""

from __future__ import annotations

import ast
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from terracone.data import PlateTest, TerrainParameters
from terracone.inverse.evaluate import cross_table
from terracone.report.text import (
    curve_text,
    evaluate_text,
    format_value,
    layered_text,
    library_text,
    plate_fit_text,
    posterior_text,
    shear_fit_text,
    table,
)

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
    from terracone.physics.plate import plate_pressure

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
        if path.name in ("cli.py", "__main__.py") or path.relative_to(PACKAGE).parts[0] == "cli":
            continue  # the CLI itself (a package since issue 20) may import its own modules
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


def test_curve_and_library_tables_by_hand():
    lines = curve_text(["depth [m]", "CI [kPa]"], np.array([0.0, 0.05]), [1.0, 123.456])
    lines = lines.splitlines()
    assert [r.split() for r in lines] == [
        ["depth", "[m]", "CI", "[kPa]"],
        ["---------", "--------"],
        ["0", "1"],
        ["0.05", "123.5"],
    ]
    assert {len(r) for r in lines} == {len("depth [m]  CI [kPa]")}  # right-aligned numbers
    rec = SimpleNamespace(name="LETE", kind="reference", params={"kc": 102.0, "n": 0.793})
    lines = library_text([rec]).splitlines()
    assert lines[0].split() == ["name", "kind", "kc", "[kN/m^(n+1)]", "kphi", "[kN/m^(n+2)]", "n"]
    assert lines[2].split() == ["LETE", "reference", "102", "-", "0.793"]


def test_fit_texts_say_what_was_fitted():
    plates = {
        "tests": [{"test": "P1", "b": 0.05, "k": 800.0, "n": 0.8, "points_used": 9, "r2": 0.99}],
        "n": 0.8,
        "n_ci": [0.7, 0.9],
        "kc": None,
        "kphi": None,
        "notes": ["one plate size: kc and kphi undetermined"],
        "undetermined": ["kc", "kphi"],
    }
    text = plate_fit_text(plates, "si")
    assert "Common n = 0.8, 95% interval 0.7 to 0.9" in text and "\nkc =" not in text
    assert text.endswith("one plate size: kc and kphi undetermined\nUndetermined: kc, kphi")
    shear = {
        "tests": [
            {"test": "S1", "normal_pressure": 10.0, "tau_max": 7.0, "K": 0.01, "points_used": 5}
        ],
        "c": 1.5,
        "phi_deg": 31.0,
        "K": 0.0125,
        "notes": [],
    }
    text = shear_fit_text(shear, "us")
    assert text.splitlines()[0].split()[:3] == ["test", "sigma", "[psi]"]
    assert text.endswith("c = 1.5 psi, phi = 31 deg, common K = 0.0125 in")


def test_posterior_and_layered_texts_convert_at_the_edge():
    post = SimpleNamespace(
        as_dict=lambda units: {
            "intervals": {"n": [0.7, 0.9]},
            "medians": {"n": 0.8},
            "identifiability": {"n": "identified"},
            "plate_bands": [
                {"radius": 2.0, "sinkage": [0.5, 1.0], "median": [3.0, 5.0], "lo": [2, 4],
                 "hi": [4, 6]}
            ],
        }
    )  # fmt: skip
    text = posterior_text({"P1": post}, "us")
    assert "P1:" in text and "identified" in text
    assert text.endswith("plate r = 2 in: pressure at 1 in sinkage 5 [4, 6] psi (90% band)")
    ok = SimpleNamespace(
        ok=True, interfaces=[0.0254], layers=[SimpleNamespace(n=0.5), SimpleNamespace(n=1.0)],
        r2_ci=0.99, bic_single=10.0, bic=5.0, preferred_layers=2,
    )  # fmt: skip
    bad = SimpleNamespace(ok=False, error="too few points")
    rows = layered_text({"A": ok, "B": bad}, "us").splitlines()
    assert rows[2] == "Layered fits (element-wise integration; lower BIC wins):"
    assert rows[5].split() == ["A", "ok", "1", "0.5,1", "0.99", "10", "5", "2"]  # 0.0254 m = 1 in
    assert rows[6].split()[:4] == ["B", "error", "too", "few"]

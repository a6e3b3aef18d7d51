"""One parameter vocabulary: model names, the table of names and the two parameter types.

References are hand computations (exact unit factors: 1 in = 0.0254 m,
1 lbf = 4.4482216152605 N), the published reference table shipped with the
package, and calibration files written in the documented format.
"""

from __future__ import annotations

import ast
import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from terracone.apps.library import Library, record_params, reference_records
from terracone.apps.sensitivity import BOXES, SobolBox
from terracone.data import TerrainParameters, TerrainShear
from terracone.inverse.bounds import Bounds
from terracone.inverse.problem import Calibration
from terracone.physics import cone, plate, shear
from terracone.report.tables import parameters_table, shear_table
from terracone.vocabulary import NAMES, markdown_table

ROOT = Path(__file__).resolve().parents[1]
INCH = 0.0254
LBF_KN = 4.4482216152605e-3  # 1 lbf in kN
PSI_KPA = LBF_KN / INCH**2  # 1 psi in kPa = 6.894757293168361


# ---------------------------------------------------------------------------
# model functions by hand


def test_pressure_bekker_by_hand():
    # (kc/b + kphi) z^n with kc = 102, kphi = 5301, n = 0.79, b = 0.05 m, z = 0.02 m
    p = plate.pressure_bekker(0.02, kc=102.0, kphi=5301.0, n=0.79, b=0.05)
    assert p == pytest.approx((102.0 / 0.05 + 5301.0) * 0.02**0.79, rel=1e-14)


def test_shear_stress_janosi_hanamoto_by_hand():
    # at j = K the stress is tau_max (1 - 1/e); at j = 3K, tau_max (1 - e^-3)
    tau = shear.shear_stress_janosi_hanamoto([0.01, 0.03], 10.0, 0.01)
    np.testing.assert_allclose(tau, [10 * (1 - math.exp(-1)), 10 * (1 - math.exp(-3))], rtol=1e-14)


def test_cone_index_janosi_by_hand():
    # eq. (2-1) at z = 1 in, kc = 1, kphi = 0, n = 1: 1.625 (2.5^2 - 1)/2
    ci = cone.cone_index_janosi(1.0, kc=1.0, kphi=0.0, n=1.0)
    assert ci == pytest.approx(1.625 * (2.5**2 - 1.0) / 2.0, rel=1e-14)


# ---------------------------------------------------------------------------
# TerrainParameters and TerrainShear


def test_terrain_parameters_by_hand():
    a = TerrainParameters(102.0, 5301.0, 0.79, 1.0, 11.0, 0.01, "rm1", 0.008)
    b = TerrainParameters(kc=102.0, kphi=5301.0, n=0.79, cc=1.0, phic_deg=11.0, K_cone=0.01,
                          model="rm1", r_min=0.008)  # fmt: skip
    assert a == b
    assert a.K_cone == 0.01 and a.phic_deg == 11.0
    assert a.kc_over_kphi == pytest.approx(102.0 / 5301.0, rel=1e-15)
    assert TerrainParameters(1.0, 0.0, 1.0).kc_over_kphi is None
    d = a.as_dict("us")
    assert d["Kc"] == pytest.approx(0.01 / INCH, rel=1e-14)  # JSON key unchanged
    assert d["cc"] == pytest.approx(1.0 / PSI_KPA, rel=1e-14)
    assert d["kc"] == pytest.approx(102.0 * INCH**1.79 / LBF_KN, rel=1e-12)
    assert d["kphi"] == pytest.approx(5301.0 * INCH**2.79 / LBF_KN, rel=1e-12)
    back = TerrainParameters.from_dict(d)
    for f in ("kc", "kphi", "n", "cc", "phic_deg", "K_cone", "r_min"):
        assert getattr(back, f) == pytest.approx(getattr(a, f), rel=1e-13)


@pytest.mark.parametrize(
    ("si", "us"),
    [
        # hand conversions: 1 psi = 6.894757... kPa, 1 in = 0.0254 m, degrees as they are
        ({"c": PSI_KPA, "phi_deg": 31.1, "K": INCH}, {"c": 1.0, "phi_deg": 31.1, "K": 1.0}),
        ({"c": 2 * PSI_KPA, "phi_deg": 0.0, "K": 0.0127}, {"c": 2.0, "phi_deg": 0.0, "K": 0.5}),
        ({"c": None, "phi_deg": 20.0, "K": None}, {"c": None, "phi_deg": 20.0, "K": None}),
    ],
)
def test_terrain_shear_round_trip(si, us):
    sh = TerrainShear(**si)
    d_us = sh.as_dict("us")
    assert d_us["units"] == "us"
    for k, v in us.items():
        assert d_us[k] == (None if v is None else pytest.approx(v, rel=1e-14))
    assert sh.as_dict("si") == {**si, "units": "si"}
    for d in (d_us, sh.as_dict("si")):
        back = TerrainShear.from_dict(d)
        for k, v in si.items():
            assert getattr(back, k) == (None if v is None else pytest.approx(v, rel=1e-14))
    # an explicit unit system overrides the dict's
    assert TerrainShear.from_dict({"c": 1.0}, units="us").c == pytest.approx(PSI_KPA, rel=1e-14)


def test_terrain_shear_checks_its_values():
    with pytest.raises(ValueError, match=r"terrain shear phi_deg out of range \(got 95"):
        TerrainShear(phi_deg=95.0)
    with pytest.raises(ValueError, match=r"terrain shear K out of range \(got 0"):
        TerrainShear(K=0.0)
    with pytest.raises(ValueError, match=r"terrain shear c out of range \(got -1"):
        TerrainShear(c=-1.0)


# ---------------------------------------------------------------------------
# Calibration


# a calibration file in today's documented format (docs/learn.md), written by hand
TODAYS_FILE = {
    "terracone_calibration": 1,
    "units": "si",
    "terrain": "LETE sand",
    "model": "rm1",
    "r_min": 0.0086,
    "plate_pair": [0.0375, 0.05],
    "phic_deg": 11.9,
    "cc": 0.0,
    "kc": 99.97,
    "kphi": 5359.0,
    "n": 0.791,
    "cone": "asabe-large",
    "provenance": {"created": "2026-01-01T00:00:00+00:00", "method": "terracone learn"},
}


def test_calibration_in_todays_format_loads_with_the_same_values(tmp_path):
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(TODAYS_FILE, indent=2))
    cal = Calibration.load(path)
    assert (cal.terrain, cal.model, cal.r_min, cal.plate_pair) == (
        "LETE sand",
        "rm1",
        0.0086,
        (0.0375, 0.05),
    )
    assert (cal.phic_deg, cal.cc, cal.kc, cal.kphi, cal.n) == (11.9, 0.0, 99.97, 5359.0, 0.791)
    assert cal.params == TerrainParameters(99.97, 5359.0, 0.791, 0.0, 11.9, None, "rm1", 0.0086)
    assert cal.kc_over_kphi == pytest.approx(99.97 / 5359.0, rel=1e-15)
    # saved again: the same file, key for key (no new keys without a K_cone)
    cal.save(tmp_path / "again.json")
    assert json.loads((tmp_path / "again.json").read_text()) == TODAYS_FILE
    assert list(cal.to_json()) == list(TODAYS_FILE)


def test_calibration_old_positional_form_equals_params_form():
    old = Calibration("sand", "rm0", None, None, 11.0, 5.0, 50.0, 1500.0, 0.9)
    new = Calibration("sand", params=TerrainParameters(50.0, 1500.0, 0.9, 5.0, 11.0))
    assert old == new
    assert (old.kc, old.kphi, old.n, old.cc, old.phic_deg, old.model) == (
        50.0, 1500.0, 0.9, 5.0, 11.0, "rm0"
    )  # fmt: skip
    with pytest.raises(TypeError, match="Calibration needs params= or kc"):
        Calibration("sand", "rm0", None, None, 11.0, 5.0)
    with pytest.raises(TypeError, match="not both"):
        Calibration("sand", "rm0", params=new.params)


def test_calibration_with_K_cone_keeps_it_in_its_file():
    cal = Calibration("s", params=TerrainParameters(50.0, 1500.0, 0.9, K_cone=0.01))
    d = cal.to_json()
    assert d["Kc"] == 0.01
    assert Calibration.from_json(d).params.K_cone == 0.01


def test_calibration_library_params_keep_their_keys():
    cal = Calibration.from_json(TODAYS_FILE)
    assert cal.library_params() == {
        "kc": 99.97,
        "kphi": 5359.0,
        "n": 0.791,
        "cc": 0.0,
        "phic_deg": 11.9,
        "model": "rm1",
        "r_min": 0.0086,
        "plate_pair": [0.0375, 0.05],
        "cone": "asabe-large",
    }


# ---------------------------------------------------------------------------
# library records


def test_reference_record_keeps_its_stored_keys():
    # LETE sand row of terracone/data/wong_terrain_values.csv: 0.79, 102, 5301, 1.3, 31.1, K 1.2 cm
    rec = {r.name: r for r in reference_records()}["LETE sand"]
    assert rec.params == {
        "kc": 102.0,
        "kphi": 5301.0,
        "n": 0.79,
        "c_kpa": 1.3,
        "phi_deg": 31.1,
        "K_m": pytest.approx(0.012, rel=1e-15),
    }
    sh = rec.terrain_shear
    assert (sh.c, sh.phi_deg, sh.K) == (1.3, 31.1, pytest.approx(0.012, rel=1e-15))
    tp = rec.terrain_parameters
    assert (tp.kc, tp.kphi, tp.n, tp.cc, tp.phic_deg, tp.K_cone) == (
        102.0,
        5301.0,
        0.79,
        0,
        0,
        None,
    )


def test_records_built_from_the_types_store_the_old_keys(tmp_path):
    params = record_params(
        TerrainParameters(102.0, 5301.0, 0.79, 1.0, 11.0, K_cone=0.01),
        TerrainShear(c=1.3, phi_deg=31.1, K=0.012),
        moisture_pct=5.0,
    )
    with Library(tmp_path / "lib.sqlite") as lib:
        rec = lib.add("site", "bevameter-fit", params)
    raw = sqlite3.connect(tmp_path / "lib.sqlite").execute("SELECT params FROM terrains").fetchone()
    assert json.loads(raw[0]) == {
        "kc": 102.0,
        "kphi": 5301.0,
        "n": 0.79,
        "cc": 1.0,
        "phic_deg": 11.0,
        "Kc": 0.01,
        "model": "rm0",
        "c_kpa": 1.3,
        "phi_deg": 31.1,
        "K_m": 0.012,
        "moisture_pct": 5.0,
    }
    assert rec.terrain_parameters == TerrainParameters(102.0, 5301.0, 0.79, 1.0, 11.0, 0.01)
    assert rec.terrain_shear == TerrainShear(1.3, 31.1, 0.012)
    with pytest.raises(TypeError, match="expected TerrainParameters, TerrainShear or a mapping"):
        record_params(42)


# ---------------------------------------------------------------------------
# report tables


def test_parameters_table_same_numbers_from_dict_or_type():
    tp = TerrainParameters(102.0, 5301.0, 0.79, 1.0, 11.0)
    flat = {"id": "a", "kc": 102.0, "kphi": 5301.0, "n": 0.79, "cc": 1.0, "phic_deg": 11.0}
    t1 = parameters_table([flat], key="k", title="t")
    t2 = parameters_table([{"id": "a", "parameters": tp}], key="k", title="t")
    assert t1.rows == t2.rows
    # hand conversions of the US columns
    kc_us = 102.0 * INCH**1.79 / LBF_KN
    kphi_us = 5301.0 * INCH**2.79 / LBF_KN
    want = ["a", 102.0, kc_us, 5301.0, kphi_us, 0.79, 1.0, 1.0 / PSI_KPA, 11.0]
    assert t1.rows[0] == [pytest.approx(v, rel=1e-12) if isinstance(v, float) else v for v in want]
    # a row with unknowns keeps its gaps
    t3 = parameters_table([{"id": "b", "kc": 5.0, "n": None}], key="k", title="t")
    assert t3.rows[0] == ["b", 5.0, None, None, None, None, None, None, None]


def test_shear_table_by_hand():
    tab = shear_table([("s", TerrainShear(c=PSI_KPA, phi_deg=30.0, K=INCH))], key="k", title="t")
    assert tab.columns[1:] == [
        ("c", "kPa"), ("c", "psi"), ("phi", "deg"), ("K", "cm"), ("K", "in")
    ]  # fmt: skip
    want = ["s", PSI_KPA, 1.0, 30.0, 2.54, 1.0]
    assert tab.rows[0] == [pytest.approx(v, rel=1e-14) if isinstance(v, float) else v for v in want]


# ---------------------------------------------------------------------------
# sensitivity boxes and bounds


def test_sobol_boxes_read_like_the_old_dicts():
    assert dict(BOXES["lete"]) == {
        "kc": (51.0, 153.0),
        "kphi": (2650.0, 7950.0),
        "n": (0.5, 1.1),
        "cc": (0.0, 2.0),
        "phic": (5.0, 20.0),
        "Kc": (1e-4, 0.1),
    }
    assert dict(BOXES["bounds"])["kphi"] == (0.0, 20000.0)
    b = BOXES["lete"]
    assert isinstance(b.lo, TerrainParameters) and b.hi.phic_deg == 20.0 and b.lo.K_cone == 1e-4
    assert SobolBox.from_ranges(dict(b)) == b
    with pytest.raises(ValueError, match=r"box lacks \['Kc'\]"):
        SobolBox.from_ranges({k: v for k, v in b.items() if k != "Kc"})


def test_bounds_cli_keys_fill_the_python_fields():
    b = Bounds()
    assert b.phic_deg == (0.0, 45.0) and b.K_cone == (1e-4, 0.1)
    assert b.fixed(phic_deg=11.0).phic_deg == (11.0, 11.0)
    # the CLI's --bounds keys (a contract) and the field names give the same bounds
    parsed = Bounds.parse("phic=1:2,Kc=0.1:1", "us")
    assert parsed == Bounds.parse("phic_deg=1:2,K_cone=0.1:1", "us")
    assert parsed.phic_deg == (1.0, 2.0)
    assert parsed.K_cone == pytest.approx((0.1 * INCH, INCH), rel=1e-15)
    assert Bounds().as_dict()["phic_deg"] == [0.0, 45.0]  # the report's key


# ---------------------------------------------------------------------------
# the table of names and function lengths


def test_docs_show_the_table_of_names():
    text = (ROOT / "docs" / "physics.md").read_text()
    assert markdown_table() in text
    pythons = [nm.python for nm in NAMES]
    assert len(set(pythons)) == len(pythons)  # one name per concept


@pytest.mark.parametrize(
    ("path", "name"),
    [
        ("terracone/inverse/learning/learn.py", "learn"),
        ("terracone/apps/sensitivity.py", "sobol_ci"),
    ],
)
def test_split_functions_are_under_100_lines(path, name):
    tree = ast.parse((ROOT / path).read_text())
    fn = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == name)
    assert 10 < fn.end_lineno - fn.lineno + 1 < 100


def test_shear_fit_gives_its_terrain_shear():
    from terracone.inverse.bevameter.shear import ShearFit

    fit = ShearFit.__new__(ShearFit)
    object.__setattr__(fit, "c", 1.5)
    object.__setattr__(fit, "phi_deg", 31.0)
    object.__setattr__(fit, "K", 0.02)
    ts = fit.terrain_shear
    assert (ts.c, ts.phi_deg, ts.K) == (1.5, 31.0, 0.02)
    assert ts.library_params() == fit.params()

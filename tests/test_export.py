"""Export of terrains (terracone.export)."""

from __future__ import annotations

import csv
import json

import pytest

from terracone.data import TerrainParameters
from terracone.export import (
    CHRONO_KEYS,
    PLAIN_FIELDS,
    export_terrain,
    plain_units,
    to_chrono_scm,
    to_plain,
    write_plain_csv,
)
from terracone.library import Library, TerrainRecord, reference_records


@pytest.fixture
def lete() -> TerrainRecord:
    return next(r for r in reference_records() if r.name == "LETE sand")


def test_chrono_lete_sand_by_hand(lete):
    doc, missing = to_chrono_scm(lete, "LETE sand")
    assert doc["Name"] == "LETE sand"
    assert doc["Type"] == "Terrain Properties"
    assert doc["Template"] == "SCM Soil Parameters"
    soil = doc["Soil Parameters"]
    # by hand: kphi 5301 kN/m^(n+2) = 5301e3 N/m^(n+2) = 5.301e6 Pa/m^n
    assert soil["Bekker Kphi"] == pytest.approx(5.301e6, rel=1e-12)
    # kc 102 kN/m^(n+1) = 1.02e5 Pa/m^(n-1)
    assert soil["Bekker Kc"] == pytest.approx(1.02e5, rel=1e-12)
    assert soil["Bekker n"] == 0.79
    # c 1.3 kPa = 1300 Pa; phi 31.1 deg; K 1.2 cm = 0.012 m
    assert soil["Mohr Cohesion"] == pytest.approx(1300.0, rel=1e-12)
    assert soil["Mohr Friction"] == 31.1
    assert soil["Janosi Shear"] == pytest.approx(0.012, rel=1e-12)
    # SCM's elastic stiffness and damping are not Bekker-Wong values
    assert missing == ["Elastic K", "Dampening R"]
    assert list(soil) == [k for k in CHRONO_KEYS if k in soil]  # Chrono's order
    # same pressure: Chrono (Pa) and terracone (kPa) for a 0.1 m plate at 5 cm
    b, z, n = 0.1, 0.05, 0.79
    p_pa = (soil["Bekker Kc"] / b + soil["Bekker Kphi"]) * z**n
    p_kpa = (102.0 / b + 5301.0) * z**n
    assert p_pa == pytest.approx(1000.0 * p_kpa, rel=1e-12)


def test_chrono_missing_keys_and_extras():
    doc, missing = to_chrono_scm({"kc": 10.0, "kphi": 500.0, "n": 1.0}, "plates only")
    assert set(doc["Soil Parameters"]) == {"Bekker Kphi", "Bekker Kc", "Bekker n"}
    assert missing == ["Mohr Cohesion", "Mohr Friction", "Janosi Shear", "Elastic K", "Dampening R"]
    doc, missing = to_chrono_scm({"n": 0.8, "K_m": 0.02}, "partial", elastic_k=4e8, damping_r=3e4)
    assert doc["Soil Parameters"] == {
        "Bekker n": 0.8,
        "Janosi Shear": 0.02,
        "Elastic K": 4e8,
        "Dampening R": 3e4,
    }
    assert missing == ["Bekker Kphi", "Bekker Kc", "Mohr Cohesion", "Mohr Friction"]
    with pytest.raises(ValueError, match="name"):
        to_chrono_scm({"n": 1.0})


def test_cone_metal_values_never_become_mohr_parameters():
    # a calibration from cone data: cc, phic_deg are cone (metal)-terrain values
    cone = {"kc": 20.0, "kphi": 900.0, "n": 0.8, "cc": 2.5, "phic_deg": 24.0, "Kc": 0.01}
    doc, missing = to_chrono_scm(cone, "from cone")
    soil = doc["Soil Parameters"]
    assert "Mohr Cohesion" not in soil and "Mohr Friction" not in soil
    assert "Janosi Shear" not in soil  # Kc is the cone-metal K, not the terrain's
    assert {"Mohr Cohesion", "Mohr Friction", "Janosi Shear"} <= set(missing)
    assert 2500.0 not in soil.values() and 24.0 not in soil.values()
    # the same through TerrainParameters and through a library record
    tp = TerrainParameters(kc=20.0, kphi=900.0, n=0.8, cc=2.5, phic_deg=24.0, Kc=0.01)
    doc2, missing2 = to_chrono_scm(tp, "from cone")
    assert doc2 == doc and missing2 == missing
    doc3, _ = to_chrono_scm(TerrainParameters(kc=1.0, kphi=2.0, n=1.0).as_dict(), "as_dict")
    assert "Mohr Cohesion" not in doc3["Soil Parameters"]
    rec = TerrainRecord("cal", "calibration", cone)
    doc4, _ = to_chrono_scm(rec)
    assert doc4["Name"] == "cal" and doc4["Soil Parameters"] == soil
    # with both kinds present, only the internal values are used
    doc5, _ = to_chrono_scm({**cone, "c_kpa": 1.0, "phi_deg": 30.0}, "both")
    assert doc5["Soil Parameters"]["Mohr Cohesion"] == 1000.0
    assert doc5["Soil Parameters"]["Mohr Friction"] == 30.0
    # ambiguous keys are refused rather than guessed
    with pytest.raises(ValueError, match="ambiguous"):
        to_chrono_scm({"c": 2.5, "phi": 24.0}, "which c?")


def test_to_plain_si_and_us(lete):
    si = to_plain(lete)
    assert si["name"] == "LETE sand" and si["units"] == "si"
    assert si["kc"] == 102.0 and si["kphi"] == 5301.0 and si["c"] == 1.3
    assert si["K"] == pytest.approx(0.012) and si["cc"] is None
    assert set(PLAIN_FIELDS) <= set(si)
    us = to_plain(lete, "us")
    # by hand: 1 lb/in^(n+2) = 4.4482216152605e-3 kN / 0.0254^(n+2) m^(n+2)
    f2 = 4.4482216152605e-3 / 0.0254 ** (0.79 + 2)
    f1 = 4.4482216152605e-3 / 0.0254 ** (0.79 + 1)
    assert us["kphi"] == pytest.approx(5301.0 / f2, rel=1e-12)
    assert us["kc"] == pytest.approx(102.0 / f1, rel=1e-12)
    assert us["c"] == pytest.approx(1.3 / 6.894757293168361, rel=1e-9)  # psi
    assert us["K"] == pytest.approx(0.012 / 0.0254)  # in
    assert us["phi_deg"] == 31.1 and us["n"] == 0.79
    with pytest.raises(ValueError, match="without n"):
        to_plain({"kc": 1.0}, "us")
    assert plain_units("us")["kphi"] == "lb/in^(n+2)"


def test_write_plain_csv(tmp_path, lete):
    out = tmp_path / "t.csv"
    write_plain_csv(out, [lete, ("mine", {"n": 0.5, "cc": 3.0})], units="si")
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:4] == ["name", "kc [kN/m^(n+1)]", "kphi [kN/m^(n+2)]", "n"]
    assert "c [kPa]" in rows[0] and "K [m]" in rows[0]
    d = dict(zip(rows[0], rows[1]))
    assert d["name"] == "LETE sand" and float(d["kphi [kN/m^(n+2)]"]) == 5301.0
    d2 = dict(zip(rows[0], rows[2]))
    assert d2["kc [kN/m^(n+1)]"] == "" and d2["cc [kPa]"] == "3.0" and d2["c [kPa]"] == ""
    write_plain_csv(tmp_path / "us.csv", [lete], units="us")
    header = (tmp_path / "us.csv").read_text().splitlines()[0]
    assert "kc [lb/in^(n+1)]" in header and "c [psi]" in header


def test_export_terrain_formats(tmp_path, lete):
    missing = export_terrain(lete, "chrono-scm", tmp_path / "l.json")
    doc = json.loads((tmp_path / "l.json").read_text())
    assert doc["Soil Parameters"]["Bekker Kphi"] == pytest.approx(5.301e6)
    assert missing == ["Elastic K", "Dampening R"]
    missing = export_terrain(lete, "json", tmp_path / "p.json", units="us")
    d = json.loads((tmp_path / "p.json").read_text())
    assert d["name"] == "LETE sand" and d["units"] == "us" and missing == []
    assert export_terrain({"n": 1.0}, "csv", tmp_path / "p.csv", name="x") == [
        "kc",
        "kphi",
        "c",
        "phi_deg",
        "K",
    ]
    with pytest.raises(ValueError, match="format"):
        export_terrain(lete, "xml", tmp_path / "x")


def test_library_record_round_trip_to_chrono(tmp_path):
    with Library(tmp_path / "l.sqlite") as lib:
        lib.add("fit", "bevameter-fit", {"kc": 5.0, "kphi": 800.0, "n": 0.9, "K_m": 0.01})
        doc, missing = to_chrono_scm(lib.get("fit"))
    assert doc["Name"] == "fit"
    assert doc["Soil Parameters"]["Bekker Kc"] == 5000.0
    assert missing == ["Mohr Cohesion", "Mohr Friction", "Elastic K", "Dampening R"]

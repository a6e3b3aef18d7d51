"""Export of terrains (terracone.apps.export)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from terracone.apps.export import (
    CHRONO_KEYS,
    PLAIN_FIELDS,
    export_terrain,
    plain_units,
    to_chrono_scm,
    to_plain,
    write_plain_csv,
)
from terracone.apps.library import Library, TerrainRecord, reference_records
from terracone.data import TerrainParameters


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
    tp = TerrainParameters(kc=20.0, kphi=900.0, n=0.8, cc=2.5, phic_deg=24.0, K_cone=0.01)
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


# ---------------------------------------------------------------------------
# complete Chrono SCM files, export from results, GeoJSON
# ---------------------------------------------------------------------------

# A soil file in the format of Project Chrono's own SCM soil files
# (projectchrono/chrono, data/vehicle/terrain/scm_soil_parameters/scm_hard.json,
# scm_medium.json, scm_soft.json: these four top-level keys and these eight soil
# keys, in this order, values in Pa, m, deg; SCMTerrain::SetSoilParameters takes
# the same eight, "elastic stiffness K per unit area [Pa/m] (must be larger than
# Kphi)").  Written here by hand with made-up values: only its layout is Chrono's.
CHRONO_FORMAT = """{
  "Name": "a soil in Chrono's own format",
  "Type": "Terrain Properties",
  "Template": "SCM Soil Parameters",
  "Soil Parameters": {
    "Bekker Kphi": 1.5e6,
    "Bekker Kc": 2e4,
    "Bekker n": 0.9,
    "Mohr Cohesion": 500,
    "Mohr Friction": 28,
    "Janosi Shear": 0.02,
    "Elastic K": 4e8,
    "Dampening R": 3e4
  }
}"""


def test_complete_chrono_file_matches_chronos_format(tmp_path, lete):
    from terracone.apps.export import DEFAULT_DAMPING_R, DEFAULT_ELASTIC_K, chrono_scm

    ref = json.loads(CHRONO_FORMAT)
    scm = chrono_scm(lete)
    assert scm.complete and scm.missing == []
    assert list(scm.doc) == list(ref)  # same top-level keys, same order
    assert list(scm.doc["Soil Parameters"]) == list(ref["Soil Parameters"])
    assert {k: scm.doc[k] for k in ("Type", "Template")} == {
        k: ref[k] for k in ("Type", "Template")
    }
    soil = scm.doc["Soil Parameters"]
    # the documented defaults (Chrono's scm_hard.json: 4e8 Pa/m, 3e4 Pa s/m), flagged
    assert soil["Elastic K"] == DEFAULT_ELASTIC_K == 4e8
    assert soil["Dampening R"] == DEFAULT_DAMPING_R == 3e4
    assert scm.defaulted == ["Elastic K", "Dampening R"]
    assert "not from data" in scm.provenance_text()
    # units as Chrono's: the same plate pressure in Pa as terracone's in kPa * 1000
    b, z = 0.1, 0.05
    p_pa = (soil["Bekker Kc"] / b + soil["Bekker Kphi"]) * z ** soil["Bekker n"]
    assert p_pa == pytest.approx(1000.0 * (102.0 / b + 5301.0) * z**0.79, rel=1e-12)
    assert soil["Elastic K"] > soil["Bekker Kphi"]
    scm.write(tmp_path / "s.json")
    back = json.loads((tmp_path / "s.json").read_text())
    assert back == scm.doc and all(isinstance(v, float) for v in back["Soil Parameters"].values())


def test_chrono_options_and_elastic_k_check():
    from terracone.apps.export import chrono_scm

    cone = {"kc": 20.0, "kphi": 900.0, "n": 0.8, "cc": 2.5, "phic_deg": 24.0}
    scm = chrono_scm(cone, "cone", cohesion_kpa=1.5, friction_deg=30.0, janosi_m=0.01)
    soil = scm.doc["Soil Parameters"]
    assert scm.complete and soil["Mohr Cohesion"] == 1500.0 and soil["Mohr Friction"] == 30.0
    assert scm.given == ["Mohr Cohesion", "Mohr Friction", "Janosi Shear"]
    # without them: missing (never taken from the cone-metal cc, phic)
    bare = chrono_scm(cone, "cone")
    assert bare.missing == ["Mohr Cohesion", "Mohr Friction", "Janosi Shear"]
    assert "give --cohesion, --friction, --janosi" in bare.provenance_text()
    # Elastic K must exceed Kphi = 900 kN/m^(n+2) = 9e5 Pa/m^n
    with pytest.raises(ValueError) as exc:
        chrono_scm(cone, "cone", elastic_k=9e5)
    assert str(exc.value) == (
        "Elastic K must exceed Bekker Kphi: Elastic K = 900000 Pa/m, Bekker Kphi = 900000 "
        "Pa/m^n; give a larger --elastic-k (elastic_k=)"
    )
    with pytest.raises(ValueError, match="the default Elastic K = 4e\\+08"):
        chrono_scm({"kc": 0.0, "kphi": 5e5, "n": 1.0}, "very stiff")
    with pytest.raises(ValueError, match="Dampening R must be >= 0"):
        chrono_scm(cone, "cone", damping_r=-1.0)


def _predict_doc(units: str = "si") -> dict:
    """A hand-written predict --json document: 3 profiles, 2 located, 1 error."""

    def prof(pid, lat, lon, kc, status="ok"):
        meta = {} if lat is None else {"Latitude": lat, "LON": str(lon)}
        d = {"id": pid, "status": status, "units": units, "metadata": meta, "error": None}
        vals = dict(kc=kc, kphi=1000.0, n=1.0, cc=2.0, phic_deg=20.0, r2_ci=0.9, lack_of_fit=None)
        if status != "ok":
            vals = {k: None for k in vals}
            d["error"] = "empty cell between readings"
        d.update(vals)
        return d

    a = prof("a", -34.5, 19.25, 10.0)
    a["intervals"] = {"kc": [5.0, 15.0]}
    a["samples"] = {
        "names": ["kc", "kphi", "n", "cc", "phic_deg"],
        "units": units,
        "values": [[float(k), 1000.0 + k, 1.0, 2.0, 20.0] for k in range(10)],
    }
    a["layered"] = {"interfaces": [0.1], "bic": 1.0, "depth": [1, 2], "ci": [3, 4]}
    return {
        "settings": {"units": units},
        "profiles": [a, prof("b", None, None, 20.0), prof("c", 10.0, 20.0, None, "error")],
    }


def test_load_results_pick_and_draw(tmp_path):
    from terracone.apps.export import draw_samples, load_results, pick_profile
    from terracone.physics.units import INCH, LBF

    path = tmp_path / "p.json"
    path.write_text(json.dumps(_predict_doc("us")))
    res = load_results(path)
    assert [r.id for r in res] == ["a", "b", "c"]
    a = res[0]
    # US to SI by hand with n = 1: kc [lb/in^2] -> kN/m^2, kphi [lb/in^3] -> kN/m^3, psi -> kPa
    assert a.params["kc"] == pytest.approx(10.0 * LBF / 1000 / INCH**2, rel=1e-12)
    assert a.params["kphi"] == pytest.approx(1000.0 * LBF / 1000 / INCH**3, rel=1e-12)
    assert a.params["cc"] == pytest.approx(2.0 * LBF / 1000 / INCH**2, rel=1e-12)
    assert (a.lat, a.lon) == (-34.5, 19.25)  # metadata keys in any case, numbers as text
    assert "depth" not in a.layered and a.layered["interfaces"] == [0.1]
    with pytest.raises(ValueError, match="2 fitted profiles; choose one with --profile ID"):
        pick_profile(res, None, "p.json")
    with pytest.raises(ValueError, match="profile 'c' was not fitted"):
        pick_profile(res, "c", "p.json")
    with pytest.raises(ValueError, match="no profile 'z'"):
        pick_profile(res, "z", "p.json")
    d = draw_samples(a, 6, seed=3)
    kcs = d[:, 0] / (LBF / 1000 / INCH**2)  # back to the stored values 0..9
    assert len(set(np.round(kcs, 9))) == 6 and set(np.round(kcs, 9)) <= set(range(10))
    with pytest.raises(ValueError, match="between 1 and 10"):
        draw_samples(a, 11)
    with pytest.raises(ValueError, match="has no posterior draws: --samples needs"):
        draw_samples(res[1], 1)
    with pytest.raises(ValueError, match="not the JSON of terracone predict"):
        (tmp_path / "x.json").write_text("[1]")
        load_results(tmp_path / "x.json")


def test_geojson_features(tmp_path):
    from terracone.apps.export import geojson, load_results

    (tmp_path / "p.json").write_text(json.dumps(_predict_doc()))
    doc, unlocated = geojson(load_results(tmp_path / "p.json"))
    assert doc["type"] == "FeatureCollection" and unlocated == ["b"]
    a, c = doc["features"]
    assert a["geometry"] == {"type": "Point", "coordinates": [19.25, -34.5]}  # [lon, lat]
    props = a["properties"]
    for k in ("id", "status", "kc", "kphi", "n", "cc", "phic_deg", "r2_ci", "lack_of_fit"):
        assert k in props
    assert props["intervals"] == {"kc": [5.0, 15.0]} and props["layered"]["bic"] == 1.0
    assert c["properties"]["status"] == "error" and c["properties"]["kc"] is None


def test_write_scm_samples_and_geojson_files(tmp_path):
    import csv

    from terracone.apps.export import load_results, write_geojson, write_scm_samples

    (tmp_path / "p.json").write_text(json.dumps(_predict_doc()))
    res = load_results(tmp_path / "p.json")
    files = write_scm_samples(res[0], 4, tmp_path / "draws", seed=1, cohesion_kpa=1.0)
    assert len(files) == 4
    names = sorted(p.name for p in (tmp_path / "draws").iterdir())
    assert names == [f"a-draw-000{k}.json" for k in range(1, 5)] + ["draws.csv"]
    with open(tmp_path / "draws" / "draws.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:2] == ["file", "kc [kN/m^(n+1)]"] and len(rows) == 5
    # each file is the Chrono SCM file of its row (n = 1 in every stored draw)
    for row in rows[1:]:
        doc = json.loads((tmp_path / "draws" / row[0]).read_text())
        assert float(row[1]) in {float(k) for k in range(10)}
        assert doc["Soil Parameters"]["Bekker n"] == pytest.approx(1.0)
    unlocated = write_geojson(res, tmp_path / "p.geojson")
    assert unlocated == ["b"]
    assert len(json.loads((tmp_path / "p.geojson").read_text())["features"]) == 2


def _run(*args):
    from click.testing import CliRunner

    from terracone.cli import cli

    return CliRunner().invoke(cli, list(args))


def test_cli_export_from_results_end_to_end(tmp_path):
    # a generated wide file with coordinates, predicted with --uncertainty
    wide = tmp_path / "w.csv"
    wide.write_text(
        "# ci unit: kPa\nid,lat,lon,0cm,2cm,4cm,6cm,8cm\n"
        "A,34°30.0S,19°15.0E,100,300,500,650,800\n"
        "B,,,120,310,480,700,820\n"
    )
    pred = tmp_path / "pred.json"
    r = _run(
        "predict", str(wide), "--uncertainty", "--draws", "60", "--seed", "1", "--out", str(pred)
    )
    assert r.exit_code == 0, r.output
    stored = json.loads(pred.read_text())["profiles"][0]["samples"]
    assert stored["names"] == ["kc", "kphi", "n", "cc", "phic_deg"] and len(stored["values"]) == 60
    gj = tmp_path / "g.geojson"
    r = _run("export", "--results", str(pred), "--format", "geojson", "--out", str(gj))
    assert r.exit_code == 0, r.output
    assert "1 located profile of 2; 1 without coordinates" in r.stderr
    (f,) = json.loads(gj.read_text())["features"]
    assert f["geometry"]["coordinates"] == [pytest.approx(19.25), pytest.approx(-34.5)]
    assert f["properties"]["id"] == "A" and "intervals" in f["properties"]
    # one Chrono file of profile A, then 5 from posterior draws
    out = tmp_path / "a.json"
    args = ["export", "--results", str(pred), "--profile", "A", "--format", "chrono-scm"]
    r = _run(*args, "--out", str(out), "--cohesion", "1", "--friction", "30", "--janosi", "1cm")
    assert r.exit_code == 0, r.output
    assert "Elastic K = 4e+08, Dampening R = 30000: documented defaults, not from data" in r.stderr
    assert len(json.loads(out.read_text())["Soil Parameters"]) == 8
    r = _run(*args, "--out", str(tmp_path / "draws"), "--samples", "5", "--seed", "2")
    assert r.exit_code == 0, r.output
    files = sorted((tmp_path / "draws").glob("A-draw-*.json"))
    assert len(files) == 5
    kphis = {json.loads(p.read_text())["Soil Parameters"]["Bekker Kphi"] for p in files}
    stored_kphi = {1000.0 * row[1] for row in stored["values"]}  # SI kN -> Pa
    assert len(kphis) == 5 and all(any(abs(k - s) < 1e-6 * s for s in stored_kphi) for k in kphis)
    # errors: one message, non-zero exit
    r = _run("export", "--format", "geojson", "--out", str(gj), "--terrain", "x")
    assert r.exit_code != 0 and "needs --results" in r.output
    r = _run("export", "--results", str(pred), "--format", "chrono-scm", "--out", str(out))
    assert r.exit_code != 0 and "choose one with --profile" in r.output


def test_marsden_geojson_counts_unlocated(tmp_path):
    from conftest import require_shared

    src = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    pred = tmp_path / "pred.json"
    assert _run("predict", str(src), "--out", str(pred)).exit_code == 0
    gj = tmp_path / "m.geojson"
    r = _run("export", "--results", str(pred), "--format", "geojson", "--out", str(gj))
    assert r.exit_code == 0, r.output
    # the real export's Longitude/Latitude cells are empty: no feature, all counted
    assert json.loads(gj.read_text()) == {"type": "FeatureCollection", "features": []}
    assert "0 located profiles of 83; 83 without coordinates" in r.stderr

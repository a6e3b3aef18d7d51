"""Export of terrains (terracone.apps.export)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from terracone.apps.export import (
    PLAIN_FIELDS,
    export_terrain,
    plain_units,
    to_plain,
    write_plain_csv,
)
from terracone.apps.library import TerrainRecord, reference_records
from terracone.result import read_results


@pytest.fixture
def lete() -> TerrainRecord:
    return next(r for r in reference_records() if r.name == "LETE sand")


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
    # Chrono's formats are written by terracone.apps.chrono, not as plain parameters
    with pytest.raises(ValueError, match="format must be one of json, csv"):
        export_terrain(lete, "chrono-scm", tmp_path / "x")


# ---------------------------------------------------------------------------
# export from results (read by terracone.result.read_results), GeoJSON
# ---------------------------------------------------------------------------


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


def test_results_pick_locate_and_draw(tmp_path):
    from terracone.apps.export import draw_samples, location, pick_profile
    from terracone.physics.units import INCH, LBF

    path = tmp_path / "p.json"
    path.write_text(json.dumps(_predict_doc("us")))
    res = read_results(path)
    assert [r.id for r in res] == ["a", "b", "c"]
    a = res[0]
    # US to SI by hand with n = 1: kc [lb/in^2] -> kN/m^2, kphi [lb/in^3] -> kN/m^3, psi -> kPa
    assert a.params.kc == pytest.approx(10.0 * LBF / 1000 / INCH**2, rel=1e-12)
    assert a.params.kphi == pytest.approx(1000.0 * LBF / 1000 / INCH**3, rel=1e-12)
    assert a.params.cc == pytest.approx(2.0 * LBF / 1000 / INCH**2, rel=1e-12)
    assert location(a) == (-34.5, 19.25)  # metadata keys in any case, numbers as text
    assert location(res[1]) is None
    for meta, where in (
        ({"LATITUDE": "-1.5", "lng": 2}, (-1.5, 2.0)),
        ({"lat": 91.0, "lon": 2}, None),  # not a latitude
        ({"lat": "", "lon": 2}, None),
        ({"lat": float("nan"), "long": 2}, None),
    ):
        a.metadata = meta
        assert location(a) == where, meta
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


def test_geojson_features(tmp_path):
    from terracone.apps.export import geojson

    (tmp_path / "p.json").write_text(json.dumps(_predict_doc()))
    doc, unlocated = geojson(read_results(tmp_path / "p.json"))
    assert doc["type"] == "FeatureCollection" and unlocated == ["b"]
    a, c = doc["features"]
    assert a["geometry"] == {"type": "Point", "coordinates": [19.25, -34.5]}  # [lon, lat]
    props = a["properties"]
    for k in ("id", "status", "kc", "kphi", "n", "cc", "phic_deg", "r2_ci", "lack_of_fit"):
        assert k in props
    assert props["kc"] == 10.0 and props["units"] == "si" and props["r2_ci"] == 0.9
    # the posterior interval of the stored draws (kc 0..9): the 5% and 95% quantiles
    assert props["intervals"]["kc"] == pytest.approx([0.45, 8.55])
    assert props["layered"] == {"interfaces": [0.1], "bic": 1.0}  # curves left out
    assert c["properties"]["status"] == "error" and c["properties"]["kc"] is None
    # in US units: kc [lb/in^2] with n = 1
    doc, _ = geojson(read_results(tmp_path / "p.json"), "us")
    kc_us = doc["features"][0]["properties"]["kc"]
    assert kc_us == pytest.approx(10.0 / (4.4482216152605e-3 / 0.0254**2), rel=1e-12)


def test_write_geojson_file(tmp_path):
    from terracone.apps.export import write_geojson

    (tmp_path / "p.json").write_text(json.dumps(_predict_doc()))
    unlocated = write_geojson(read_results(tmp_path / "p.json"), tmp_path / "p.geojson")
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
    # the Parquet of the same run reads the same way
    pq_out = tmp_path / "pred.parquet"
    r = _run("predict", str(wide), "--parquet", str(pq_out))
    assert r.exit_code == 0, r.output
    r = _run("export", "--results", str(pq_out), "--format", "geojson", "--out", str(gj))
    assert r.exit_code == 0 and "1 located profile of 2" in r.stderr
    # the Chrono SCM spec of profile A: eight values ([Pa/m^n] = [kN/m^(n+2)] x 1000)
    out = tmp_path / "a.json"
    args = ["export", "--results", str(pred), "--profile", "A", "--format", "chrono-scm"]
    r = _run(*args, "--out", str(out), "--cohesion", "1", "--friction", "30", "--janosi", "1cm")
    assert r.exit_code == 0, r.output
    assert "Elastic stiffness = 4e+08 Pa/m, Damping = 30000 Pa s/m" in r.stderr
    soil = json.loads(out.read_text())["Soil parameters"]
    a = json.loads(pred.read_text())["profiles"][0]
    assert len(soil) == 8 and soil["Bekker Kphi"] == pytest.approx(1000 * a["kphi"], rel=1e-12)
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

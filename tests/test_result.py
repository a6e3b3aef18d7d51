"""terracone.result: the result model, its versioned schema, and the JSON and Parquet writers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.data import CIProfile, InputError, TerrainParameters
from terracone.inverse import predict
from terracone.io import read_ci_profiles, write_ci_profiles
from terracone.physics.cone import cone_index
from terracone.report import build_report, result_kind
from terracone.result import (
    PARQUET_COLUMNS,
    SCHEMA,
    PlateCurve,
    PosteriorSummary,
    PredictionResult,
    PredictionResults,
    check_schema,
    check_table_schema,
    from_document,
    read_json,
    read_results,
    to_document,
    to_table,
    write_json,
    write_parquet,
)

# unit factors by hand (NIST SP 811): 1 lbf = 4.4482216152605 N, 1 in = 0.0254 m
LBF_N = 4.4482216152605
INCH_M = 0.0254
PSI_KPA = LBF_N / INCH_M**2 / 1000.0


def _kc_us(kc, n):  # kN/m^(n+1) -> lb/in^(n+1)
    return kc * 1000.0 / LBF_N * INCH_M ** (n + 1)


def _kphi_us(kphi, n):  # kN/m^(n+2) -> lb/in^(n+2)
    return kphi * 1000.0 / LBF_N * INCH_M ** (n + 2)


def _result(i: int = 0) -> PredictionResult:
    """A fitted result written by hand (SI), no solver involved."""
    z = np.array([0.0, 0.05, 0.10, 0.15])
    params = TerrainParameters(100.0 + i, 5000.0, 0.8, 2.0, 10.0, None, "rm1", 0.008)
    return PredictionResult(
        id=f"P{i}",
        status="ok",
        params=params,
        rmsd=50.0,
        r2_ci=0.99,
        longest_run=3,
        depth=z,
        ci=np.array([100.0, 300.0, 500.0, 650.0]),
        ci_model=np.array([110.0, 290.0, 505.0, 640.0]),
        undetermined=["phic", "phic~scale(kc,kphi)"],
        phic_range=(8.0, 12.0),
        profile_intervals={"n": (0.7, 0.9), "kc": (80.0, 120.0), "cc": (0.0, 5.0)},
        nfev=123,
        nit=4,
        converged=True,
        message="global optimum",
        metadata={"site": "north", "n": 7},
        plate_curves=[PlateCurve(0.05, np.array([0.0, 0.01]), np.array([0.0, 42.0]))],
    )


def _error_result() -> PredictionResult:
    exc = InputError("CI must be >= 0", file="f.csv", profile="B", row=7, column="ci_kpa")
    return PredictionResult(id="B", status="error", error=exc, source="f.csv")


# ---------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------


def test_optimize_result_fields():
    r = _result()
    assert r.success and r.ok and r.status == "ok"
    assert r.fun == 50.0 and r.nfev == 123 and r.message == "global optimum"
    np.testing.assert_array_equal(r.x, [100.0, 5000.0, 0.8, 2.0, 10.0])
    e = _error_result()
    assert not e.success and e.status == "error"
    assert e.error == "file f.csv, profile B, row 7, column ci_kpa: CI must be >= 0"
    assert (e.error_row, e.error_column) == (7, "ci_kpa")
    assert e.message == e.error  # why it stopped, as OptimizeResult.message
    assert np.isnan(e.x).all()


# ---------------------------------------------------------------------------
# JSON
# ---------------------------------------------------------------------------


def test_us_document_against_hand_conversions():
    doc = to_document([_result()], "us", input="x.csv")
    assert doc["schema"] == SCHEMA == "terracone.prediction/1" and doc["schema_version"] == 1
    assert doc["units"] == "us"
    p = doc["profiles"][0]
    n = 0.8
    assert p["kc"] == pytest.approx(_kc_us(100.0, n), rel=1e-12)
    assert p["kphi"] == pytest.approx(_kphi_us(5000.0, n), rel=1e-12)
    assert p["cc"] == pytest.approx(2.0 / PSI_KPA, rel=1e-12)
    assert p["rmsd"] == pytest.approx(50.0 / PSI_KPA, rel=1e-12)
    assert p["r_min"] == pytest.approx(0.008 / INCH_M, rel=1e-12)
    assert p["phic_deg"] == 10.0 and p["n"] == 0.8
    np.testing.assert_allclose(p["depth"], np.array([0.0, 0.05, 0.10, 0.15]) / INCH_M, rtol=1e-12)
    np.testing.assert_allclose(p["ci"], np.array([100, 300, 500, 650]) / PSI_KPA, rtol=1e-12)
    assert p["profile_intervals"]["kc"] == pytest.approx(
        [_kc_us(80.0, n), _kc_us(120.0, n)], rel=1e-12
    )
    assert p["profile_intervals"]["n"] == [0.7, 0.9]
    assert p["plates"][0]["radius"] == pytest.approx(0.05 / INCH_M, rel=1e-12)
    assert p["plates"][0]["pressure"][1] == pytest.approx(42.0 / PSI_KPA, rel=1e-12)
    # every key earlier issues named is still there
    for key in (
        "id status error kc kphi n cc phic_deg Kc model r_min rmsd r2_ci longest_run "
        "lack_of_fit units undetermined phic_range_deg profile_intervals solver diagnostics "
        "cone metadata notes source depth ci ci_model plates"
    ).split():
        assert key in p, key


@pytest.mark.parametrize("units", ["si", "us"])
def test_json_round_trip(tmp_path, units):
    results = [_result(0), _result(1), _error_result()]
    path = write_json(tmp_path / "p.json", results, units, input="x.csv")
    back = read_json(path)
    assert [r.id for r in back] == ["P0", "P1", "B"]
    for a, b in zip(results[:2], back[:2]):
        for k in ("kc", "kphi", "n", "cc", "phic_deg", "r_min"):
            assert getattr(b.params, k) == pytest.approx(getattr(a.params, k), rel=1e-12)
        assert b.rmsd == pytest.approx(a.rmsd, rel=1e-12)
        np.testing.assert_allclose(b.depth, a.depth, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(b.ci_model, a.ci_model, rtol=1e-12)
        assert b.profile_intervals["kc"] == pytest.approx(a.profile_intervals["kc"], rel=1e-12)
        assert b.phic_range == a.phic_range and b.undetermined == a.undetermined
        assert (b.nfev, b.nit, b.message) == (123, 4, "global optimum")
        assert b.plate_curves[0].radius == pytest.approx(0.05, rel=1e-12)
        np.testing.assert_allclose(b.plate_curves[0].pressure, [0.0, 42.0], rtol=1e-12)
        assert b.metadata == a.metadata
    e = back[2]
    assert (
        not e.ok and e.error == results[2].error and (e.error_row, e.error_column) == (7, "ci_kpa")
    )
    # writing what was read gives the same document
    assert to_document(back, units, input="x.csv") == json.loads(path.read_text())


def test_unknown_schema_version_is_refused(tmp_path):
    doc = to_document([_result()], "si")
    doc["schema_version"] = 99
    with pytest.raises(
        ValueError, match=r"schema_version 99 of terracone.prediction is not supported"
    ):
        check_schema(doc)
    f = tmp_path / "future.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=rf"file {f}: schema_version 99"):
        read_json(f)
    with pytest.raises(ValueError, match="schema_version 99"):
        build_report(f, tmp_path / "r.html")
    r = CliRunner().invoke(cli, ["report", str(f), "--out", str(tmp_path / "r.html")])
    assert r.exit_code == 1 and "schema_version 99 of terracone.prediction" in r.output
    assert "Traceback" not in r.output
    with pytest.raises(ValueError, match=r"unknown schema 'other.thing/1'"):
        check_schema({"schema": "other.thing/1", "profiles": []})
    with pytest.raises(ValueError, match=r"schema_version '2' of terracone.prediction"):
        check_schema({"schema": "terracone.prediction/2"})


def test_old_document_without_schema_still_reads():
    doc = {"profiles": [_result().as_dict("si")]}  # a predict document of before schemas
    assert check_schema(doc) == 0 and result_kind(doc) == "predict"
    (r,) = from_document(doc)
    assert r.params.kc == pytest.approx(100.0, rel=1e-12)


def test_report_reads_a_document_by_its_schema_key(tmp_path):
    doc = to_document([_result(0), _result(1), _error_result()], "si", input="x.csv")
    del doc["command"]  # only the schema says what it is
    assert result_kind(doc) == "predict"
    f = tmp_path / "results.json"
    f.write_text(json.dumps(doc))
    html = build_report(f, tmp_path / "r.html").read_text()
    assert "P0" in html and "P1" in html and "CI must be &gt;= 0" in html


# ---------------------------------------------------------------------------
# Parquet
# ---------------------------------------------------------------------------


def test_table_has_batch_columns_and_the_results_values(tmp_path):
    from terracone.result import PARQUET_COLUMNS as OUTPUT_COLUMNS

    results = [_result(0), _result(1), _error_result()]
    path = write_parquet(tmp_path / "p.parquet", results, "us")
    t = pq.read_table(path)
    assert t.schema.metadata[b"terracone.schema"] == SCHEMA.encode()
    assert check_table_schema(path) == 1
    names = [c for c, _ in OUTPUT_COLUMNS]
    assert t.column_names == names + ["site", "meta_n"]  # metadata after, clash renamed
    assert [t.schema.field(c).type for c in names] == [ty for _, ty in OUTPUT_COLUMNS]
    d = t.to_pylist()
    n = 0.8
    for i in (0, 1):
        row = d[i]
        assert row["profile"] == f"P{i}" and row["status"] == "ok" and row["error"] is None
        assert row["kc"] == pytest.approx(_kc_us(100.0 + i, n), rel=1e-12)
        assert row["kphi"] == pytest.approx(_kphi_us(5000.0, n), rel=1e-12)
        assert row["cc"] == pytest.approx(2.0 / PSI_KPA, rel=1e-12)
        assert row["rmsd"] == pytest.approx(50.0 / PSI_KPA, rel=1e-12)
        assert row["r_min"] == pytest.approx(0.008 / INCH_M, rel=1e-12)
        assert (row["phic_lo"], row["phic_deg"], row["phic_hi"]) == (8.0, 10.0, 12.0)
        assert (row["n_lo"], row["n_hi"]) == (0.7, 0.9)
        assert row["undetermined"] == "phic;phic~scale(kc,kphi)"
        assert row["longest_run"] == 3.0 and row["n_points"] == 4 and row["units"] == "us"
        assert row["model"] == "rm1" and row["site"] == "north" and row["meta_n"] == 7
        assert row["kc_q05"] is None and row["bic_layered"] is None and row["chunk"] is None
    e = d[2]
    assert e["status"] == "error" and e["error"].endswith("CI must be >= 0")
    assert (e["error_row"], e["error_column"]) == (7, "ci_kpa")
    assert e["kc"] is None and e["undetermined"] is None and e["source"] == "f.csv"


def test_an_old_parquet_without_schema_reads_and_a_future_one_is_refused(tmp_path):
    t = to_table([_result()], "si")
    pq.write_table(t.replace_schema_metadata({}), tmp_path / "old.parquet")
    assert check_table_schema(tmp_path / "old.parquet") == 0
    future = t.replace_schema_metadata({b"terracone.schema": b"terracone.prediction/3"})
    pq.write_table(future, tmp_path / "new.parquet")
    with pytest.raises(ValueError, match=r"new.parquet: schema_version '3'"):
        check_table_schema(tmp_path / "new.parquet")


# ---------------------------------------------------------------------------
# the CLI, Python and batch agree
# ---------------------------------------------------------------------------

TRUTH = [  # noise-free profiles of known parameters
    dict(kc=20.0, kphi=1500.0, n=0.6, cc=3.0, phic_deg=15.0),
    dict(kc=5.0, kphi=800.0, n=1.0, cc=1.0, phic_deg=25.0),
]


@pytest.fixture(scope="module")
def ci_file(tmp_path_factory) -> Path:
    z = np.linspace(0.0, 0.4, 30)
    profiles = [
        CIProfile(f"T{i}", z, cone_index(z, **t), metadata={"plot": f"p{i}"})
        for i, t in enumerate(TRUTH)
    ]
    f = tmp_path_factory.mktemp("result_cli") / "ci.csv"
    write_ci_profiles(f, profiles)
    with f.open("a") as fh:  # a third profile with a negative reading
        fh.write(
            "".join(f"BAD,asabe-large,p9,{z},{c}\n" for z, c in ((0, 100), (0.1, -5), (0.2, 300)))
        )
    return f


@pytest.mark.parametrize("units", ["si", "us"])
def test_predict_json_and_parquet_agree_with_python(ci_file, tmp_path, units):
    pq_path = tmp_path / "p.parquet"
    r = CliRunner().invoke(
        cli, ["predict", str(ci_file), "--units", units, "--json", "--parquet", str(pq_path)]
    )
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["schema"] == SCHEMA and doc["units"] == units
    rows = pq.read_table(pq_path).to_pylist()
    items = read_ci_profiles(ci_file, on_error="collect")
    py = [predict(p) if not isinstance(p, InputError) else None for p in items]
    assert [p["id"] for p in doc["profiles"]] == [row["profile"] for row in rows]
    assert [row["profile"] for row in rows] == ["T0", "T1", "BAD"]
    for k, (p, row) in enumerate(zip(doc["profiles"], rows)):
        assert p["status"] == row["status"]
        if k == 2:
            # the reader's error: header, 2 x 30 rows, then BAD's rows 62 to 64
            assert row["status"] == "error" and row["error"] == p["error"]
            assert f"file {ci_file}, profile BAD, row 63, column ci_kpa" in row["error"]
            assert (row["error_row"], row["error_column"]) == (63, "ci_kpa")
            assert (p["error_row"], p["error_column"]) == (63, "ci_kpa")
            continue
        expect = to_document([py[k]], units)["profiles"][0]
        for key in ("kc", "kphi", "n", "cc", "phic_deg", "rmsd", "r2_ci"):
            assert p[key] == pytest.approx(expect[key], rel=1e-9, abs=1e-12), key
            assert row[key] == pytest.approx(p[key], rel=1e-12, abs=1e-15), key
        assert row["undetermined"] == ";".join(p["undetermined"])
        assert [row["phic_lo"], row["phic_hi"]] == p["phic_range_deg"]
        assert [row["n_lo"], row["n_hi"]] == p["profile_intervals"]["n"]
        assert row["plot"] == p["metadata"]["plot"]
        assert row["n"] == pytest.approx(TRUTH[k]["n"], abs=2e-3)  # the truth, recovered


def test_batch_part_files_have_the_predict_table_schema(ci_file, tmp_path):
    from terracone.apps.batch import run_batch

    pq_path = tmp_path / "p.parquet"
    r = CliRunner().invoke(cli, ["predict", str(ci_file), "--parquet", str(pq_path)])
    assert r.exit_code == 0, r.output
    s = run_batch(ci_file, tmp_path / "out", workers=1, progress=False)
    assert s.profiles == 3 and s.profiles_ok == 2
    (part,) = sorted((tmp_path / "out").glob("part-*.parquet"))
    assert check_table_schema(part) == 1
    a, b = pq.read_table(part), pq.read_table(pq_path)
    k = len(PARQUET_COLUMNS)
    assert a.schema.names[:k] == b.schema.names[:k]
    assert [f.type for f in a.schema][:k] == [f.type for f in b.schema][:k]
    assert a.column("profile").to_pylist() == b.column("profile").to_pylist()
    for c in ("status", "error_row", "error_column"):
        assert a.column(c).to_pylist() == b.column(c).to_pylist(), c
    # predict's reader keeps neither the rows nor the metadata of a profile it rejects
    assert a.column("n_points").to_pylist() == [30, 30, 3]
    assert b.column("n_points").to_pylist() == [30, 30, None]
    assert a.column("plot").to_pylist() == ["p0", "p1", "p9"]
    assert b.column("plot").to_pylist() == ["p0", "p1", None]
    # batch does not compute the profile intervals of kc, kphi and cc (docs/batch.md): its
    # undetermined tokens are those of predict without them
    for x, y in zip(a.column("undetermined").to_pylist()[:2], b.column("undetermined").to_pylist()):
        assert x.split(";") == [t for t in y.split(";") if t not in ("kc", "kphi", "cc")]
    np.testing.assert_allclose(
        a.column("n").to_numpy(zero_copy_only=False)[:2], [t["n"] for t in TRUTH], atol=2e-3
    )


def test_posterior_and_layered_fit_reach_json_and_table_alike(tmp_path):
    z = np.linspace(0.0, 0.4, 25)
    rng = np.random.default_rng(3)
    ci = cone_index(z, **TRUTH[0]) * (1 + 0.02 * rng.standard_normal(z.size))
    f = tmp_path / "one.csv"
    write_ci_profiles(f, [CIProfile("U", z, np.round(ci, 3))])
    pq_path = tmp_path / "u.parquet"
    args = ["predict", str(f), "--uncertainty", "--draws", "300", "--layers", "2", "--json"]
    r = CliRunner().invoke(cli, [*args, "--units", "us", "--parquet", str(pq_path)])
    assert r.exit_code == 0, r.output
    (p,) = json.loads(r.output)["profiles"]
    (row,) = pq.read_table(pq_path).to_pylist()
    for k in ("kc", "kphi", "n", "cc", "phic_deg"):
        lo, hi = p["intervals"][k]
        assert (row[f"{k}_q05"], row[f"{k}_q95"]) == (lo, hi)
        assert row[f"ident_{k}"] == p["identifiability"][k]
    assert len(p["samples"]["values"]) > 0
    lay = p["layered"]
    assert row["bic_layered"] == lay["bic"] and row["bic_single"] == lay["bic_single"]
    assert row["preferred_layers"] == lay["preferred_layers"]
    assert row["interfaces"] == ",".join(f"{v:.6g}" for v in lay["interfaces"])  # in inches
    assert row["n_layers"] == ",".join(f"{q['n']:.6g}" for q in lay["layers"])


# ---------------------------------------------------------------------------
# reading results back: one reader for JSON, Parquet and a batch directory
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("units", ["si", "us"])
@pytest.mark.parametrize("kind", ["json", "parquet", "batch"])
def test_read_results_gives_back_the_si_values_written(tmp_path, units, kind):
    """The hand-made results come back in SI from every file kind, in either unit system."""
    results = PredictionResults([_result(0), _result(1), _error_result()])
    post = PosteriorSummary(
        intervals={"kc": (90.0, 110.0), "kphi": (4000.0, 6000.0), "n": (0.8, 0.8),
                   "cc": (1.0, 3.0), "phic_deg": (5.0, 15.0)},
        identifiability={"n": "determined"},
    )  # fmt: skip
    results[0].posterior = post  # n's interval is a point: kc, kphi convert exactly
    if kind == "json":
        path = tmp_path / "r.json"
        path.write_text(json.dumps(to_document(results, units, settings={"calibration": "X"})))
    elif kind == "parquet":
        path = tmp_path / "r.parquet"
        pq.write_table(to_table(results, units), path)
    else:
        path = tmp_path / "batch"
        path.mkdir()
        pq.write_table(to_table(results, units), path / "part-000000.parquet")
        (path / "_run.json").write_text(json.dumps({"settings": {"calibration": "X"}}))
    back = read_results(path)
    assert [r.id for r in back] == ["P0", "P1", "B"]
    assert [r.status for r in back] == ["ok", "ok", "error"]
    assert back[2].error == "file f.csv, profile B, row 7, column ci_kpa: CI must be >= 0"
    assert back[2].params is None and back[2].posterior is None
    for i in (0, 1):
        p = back[i].params
        assert (p.kc, p.kphi, p.n, p.cc, p.phic_deg) == pytest.approx(
            (100.0 + i, 5000.0, 0.8, 2.0, 10.0), rel=1e-12
        )
        assert back[i].rmsd == pytest.approx(50.0, rel=1e-12)
        assert back[i].metadata == {"site": "north", "n": 7}
        assert back[i].undetermined == ["phic", "phic~scale(kc,kphi)"]
    iv = back[0].posterior.intervals
    assert iv["kc"] == pytest.approx((90.0, 110.0), rel=1e-12)
    assert iv["kphi"] == pytest.approx((4000.0, 6000.0), rel=1e-12)
    assert iv["cc"] == pytest.approx((1.0, 3.0), rel=1e-12)
    assert back[0].posterior.identifiability["n"] == "determined"
    assert back[1].posterior is None
    if kind != "parquet":
        assert back.settings["calibration"] == "X"


def test_read_results_names_what_it_cannot_read(tmp_path):
    with pytest.raises(ValueError, match=r"nothing.json: file not found"):
        read_results(tmp_path / "nothing.json")
    with pytest.raises(
        ValueError, match=r"no part-\*.parquet files \(not a terracone batch directory\)"
    ):
        read_results(tmp_path)


def test_a_tables_layered_columns_come_back_in_si(tmp_path):
    """A layered fit written to a US table reads back in metres (6 in = 0.1524 m by hand)."""
    from terracone.result import LayeredSummary

    ok, bad = _result(0), _result(1)
    nan = float("nan")  # what a table knows of a layer: its n
    ok.layered = LayeredSummary(
        status="ok", bic=-10.0, bic_single=-4.0, preferred_layers=2, r2_ci=0.99,
        interfaces=[6 * INCH_M], lack_of_fit=None,
        layers=[TerrainParameters(nan, nan, n, nan, nan) for n in (0.4, 1.0)],
    )  # fmt: skip
    bad.layered = LayeredSummary(status="error", error="3 points; at least 9 are needed")
    path = tmp_path / "t.parquet"
    pq.write_table(to_table([ok, bad], "us"), path)
    row = pq.read_table(path).to_pylist()[0]
    assert row["interfaces"] == "6" and row["n_layers"] == "0.4,1"
    back = read_results(path)
    lay = back[0].layered
    assert lay.ok and lay.preferred_layers == 2 and lay.layer_n == [0.4, 1.0]
    assert lay.interfaces == pytest.approx([0.1524], rel=1e-12)
    assert (lay.bic, lay.bic_single, lay.r2_ci) == (-10.0, -4.0, 0.99)
    assert not back[1].layered.ok
    assert back[1].layered.error == "3 points; at least 9 are needed"


def test_report_of_a_predict_parquet_table(ci_file, tmp_path):
    """terracone report FILE.parquet (new): every profile, n as predict wrote it."""
    table = tmp_path / "p.parquet"
    r = CliRunner().invoke(cli, ["predict", str(ci_file), "--parquet", str(table)])
    assert r.exit_code == 0, r.output
    out = tmp_path / "p.html"
    r = CliRunner().invoke(cli, ["report", str(table), "--out", str(out)])
    assert r.exit_code == 0, r.output
    html = out.read_text()
    assert "terracone report: prediction table" in html
    for pid in ("T0", "T1", "BAD"):
        assert f">{pid}<" in html
    for t in TRUTH:  # noise-free profiles: the fitted n is the generating one
        assert f">{t['n']:.3g}<" in html

"""Wide tables of cone index (one row per push, one column per depth): terracone.io.read_wide_ci.

Every expected value is written by hand from the generated file's text; the
real Marsden SC900 export is re-written as a wide table (by string
manipulation here, not by terracone) and must read as the SC900 reader reads
the original.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner
from conftest import require_shared

from terracone.cli import cli
from terracone.data import CIProfile, InputError
from terracone.io import detect_format, parse_coordinate, read_ci_profiles, read_wide_ci
from terracone.physics.cone import CONES, get_cone

PSI = 6.894757293168361  # kPa, = 4.4482216152605 N / 0.0254^2 m^2 / 1000

# a Penetrologger-like export: BOM, ';' with decimal commas, the unit stated
# in the preamble, COORD_Y/COORD_X in degrees and decimal minutes, bare depth
# headers (cm given by --depth-unit)
SEMI = (
    "\ufeffPenetrologger export\n"  # line 1
    "Unit: MPa\n"  # line 2
    "PLOT;POINT;COORD_Y;COORD_X;0;1;2;3;4;5\n"  # line 3 (header)
    "north;P1;34°22,92106S;019°10,50000E;0,10;0,25;0,5;0,75;0;0\n"  # 4: 2 trailing zeros
    "north;P2;S34 22.5;E19 10.0;0,2;0,4;0,6;;;\n"  # 5: empty cells end the push
    "south;P3;;;0,3;0,6;;0,9;;\n"  # 6: empty cell between readings
    "south;P4;-34,5;19,25;;0,4;0,6;0,8;1,0;\n"  # 7: starts at 1 cm
)


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def semi(tmp_path: Path) -> Path:
    return _write(tmp_path / "pushes.csv", SEMI)


def test_semicolon_decimal_comma_bom_dms(semi: Path):
    assert detect_format(semi) == "wide"
    items = read_wide_ci(semi, depth_unit="cm", on_error="collect", cone="penetrologger-1cm2")
    assert [getattr(p, "id", None) or p.profile for p in items] == ["P1", "P2", "P3", "P4"]
    p1, p2, p3, p4 = items
    # P1: 0.10 ... 0.75 MPa = 100 ... 750 kPa at 0..3 cm, two trailing zeros dropped
    np.testing.assert_allclose(p1.depth, [0.0, 0.01, 0.02, 0.03], rtol=0, atol=1e-15)
    np.testing.assert_allclose(p1.ci, [100.0, 250.0, 500.0, 750.0], rtol=1e-12)
    assert p1.metadata["trailing_zeros_dropped"] == 2
    assert any("dropped 2 trailing zero readings" in n for n in p1.notes)
    # 34 deg 22.92106 min S = -(34 + 22.92106 / 60); 19 deg 10.5 min E
    assert p1.metadata["lat"] == pytest.approx(-(34 + 22.92106 / 60), abs=1e-12)
    assert p1.metadata["lon"] == pytest.approx(19 + 10.5 / 60, abs=1e-12)
    assert p1.metadata["PLOT"] == "north" and p1.metadata["pressure_unit"] == "mpa"
    assert p1.cone == CONES["penetrologger-1cm2"] and p1.cone.angle_deg == 60.0
    assert list(p1.rows) == [4, 4, 4, 4]  # the file line of the push
    # P2: hemisphere letters in front, dot decimals are accepted too
    assert p2.metadata["lat"] == pytest.approx(-(34 + 22.5 / 60), abs=1e-12)
    assert p2.metadata["lon"] == pytest.approx(19 + 10 / 60, abs=1e-12)
    np.testing.assert_allclose(p2.ci, [200.0, 400.0, 600.0], rtol=1e-12)
    assert p2.metadata["trailing_zeros_dropped"] == 0
    # P3: the empty cell at 1 cm lies between readings (0 and 3 cm): an error naming it
    assert isinstance(p3, InputError)
    assert str(p3) == (
        f"file {semi}, profile P3, row 6, column 2: empty cell between readings "
        "('1' and '3' have readings)"
    )
    assert "lat" not in getattr(p3, "metadata", {})
    # P4: decimal degrees with decimal commas; first reading at 1 cm, noted
    assert p4.metadata["lat"] == -34.5 and p4.metadata["lon"] == 19.25
    np.testing.assert_allclose(p4.depth, [0.01, 0.02, 0.03, 0.04], atol=1e-15)
    assert any("first reading at 1" in n for n in p4.notes)


def test_missing_units_are_refused_with_the_option_named(tmp_path: Path, semi: Path):
    with pytest.raises(InputError) as exc:
        read_wide_ci(semi)
    assert str(exc.value) == (
        f"file {semi}, row 3: refusing to guess units; give --depth-unit m|cm|mm|in "
        "(depth_unit= in Python): the depth columns '0', ... have no unit"
    )
    no_unit = _write(tmp_path / "nounit.csv", "id,5cm,10cm,15cm\na,1,2,3\n")
    with pytest.raises(InputError) as exc:
        read_wide_ci(no_unit)
    assert str(exc.value) == (
        f"file {no_unit}, row 1: refusing to guess units; give --ci-unit kpa|mpa|psi "
        "(ci_unit= in Python): the file does not state the unit of its readings"
    )
    neither = _write(tmp_path / "neither.csv", "id,5,10,15\na,1,2,3\n")
    with pytest.raises(InputError, match=r"give --depth-unit .* and --ci-unit"):
        read_wide_ci(neither)
    # the file's statement wins over nothing, and a contradiction is an error
    with pytest.raises(InputError, match="states cone index in mpa but ci_unit"):
        read_wide_ci(semi, depth_unit="cm", ci_unit="kpa")
    # with both given: psi readings, inch depth headers of their own
    p = read_wide_ci(
        _write(tmp_path / "us.csv", "id\t1 in\t2 in\t3 in\na\t10\t20\t30\n"), ci_unit="psi"
    )[0]
    np.testing.assert_allclose(p.depth, [0.0254, 0.0508, 0.0762], rtol=1e-15)
    np.testing.assert_allclose(p.ci, [10 * PSI, 20 * PSI, 30 * PSI], rtol=1e-12)


def test_headers_ids_and_comma_files(tmp_path: Path):
    text = (
        "# a comment line\n"
        "latitude,longitude,depth_0cm,depth_2.5cm,depth_5cm,note\n"
        '"34°22\'55.2""S",18.5,100,200,300,dry\n'
        ",,150,250,350,wet\n"
    )
    path = _write(tmp_path / "plain.csv", text)
    assert detect_format(path) == "wide"
    a, b = read_wide_ci(path, ci_unit="kpa")
    # no id column: the 1-based data row after the file stem
    assert (a.id, b.id) == ("plain/1", "plain/2")
    # degrees, minutes and seconds: 34 + 22/60 + 55.2/3600, south
    assert a.metadata["lat"] == pytest.approx(-(34 + 22 / 60 + 55.2 / 3600), abs=1e-12)
    assert a.metadata["lon"] == 18.5 and "lat" not in b.metadata
    np.testing.assert_allclose(a.depth, [0.0, 0.025, 0.05], atol=1e-15)
    assert a.metadata["note"] == "dry" and a.rows[0] == 3
    # the same through read_ci_profiles (detected) and a long CSV stays long
    assert read_ci_profiles(path, units=None, ci_unit="kpa")[1].id == "plain/2"
    long = _write(tmp_path / "long.csv", "depth_cm,ci_kpa\n0,1\n2,2\n4,3\n")
    assert detect_format(long) == "csv"


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("a,1,x,3", "column 10: not a number: 'x'"),
        ("a,1,2,-3", "column 15: negative cone index -3 (reading '-3')"),
        ("a,,,", "column 5: no readings (every depth cell is empty)"),
        ("a,1,2,3,4", "5 fields but the header has 4"),
    ],
)
def test_bad_cells_are_located(tmp_path: Path, row: str, message: str):
    path = _write(tmp_path / "bad.csv", f"# ci unit: kPa\nid,5,10,15\n{row}\n")
    with pytest.raises(InputError) as exc:
        read_wide_ci(path, depth_unit="mm")
    where = f"file {path}, row 3: " if "fields" in message else f"file {path}, profile a, row 3, "
    assert str(exc.value) == where + message


def test_file_level_errors(tmp_path: Path):
    dec = _write(tmp_path / "dec.csv", "id,10cm,5cm,15cm\na,1,2,3\n")
    with pytest.raises(InputError, match="column 5cm: depth columns are not strictly increasing"):
        read_wide_ci(dec, ci_unit="kpa")
    dup = _write(tmp_path / "dup.csv", "id,5cm,10cm,15cm\na,1,2,3\na,1,2,3\n")
    items = read_wide_ci(dup, ci_unit="kpa", on_error="collect")
    assert isinstance(items[0], CIProfile)
    assert (
        str(items[1]) == f"file {dup}, profile a, row 3, column id: duplicate id (also on line 2)"
    )
    none = _write(tmp_path / "none.csv", "id,site\na,b\n")
    with pytest.raises(InputError, match="no header line with at least 3 depth columns"):
        read_wide_ci(none, ci_unit="kpa")
    bad_lat = _write(tmp_path / "lat.csv", "id,lat,5cm,10cm,15cm\na,34°22.5E,1,2,3\n")
    with pytest.raises(InputError, match=r"column lat: hemisphere 'E' in a lat cell"):
        read_wide_ci(bad_lat, ci_unit="kpa")


def test_parse_coordinate_by_hand():
    assert parse_coordinate("34°22.92106S", "lat") == pytest.approx(-34.382017666, abs=1e-9)
    assert parse_coordinate("-18.25", "lon") == -18.25
    assert parse_coordinate("18 15 W", "lon") == -18.25
    assert parse_coordinate("  ", "lat") is None
    for bad, why in [("95", "outside"), ("34°61S", "below 60"), ("N34S", "two hemisphere")]:
        with pytest.raises(ValueError, match=why):
            parse_coordinate(bad, "lat")


def test_penetrologger_cones_and_area_syntax():
    # 60 deg cones of 1, 2, 3.33 and 5 cm^2: R = sqrt(A / pi), H = R / tan(30 deg)
    for a in (1.0, 2.0, 3.33, 5.0):
        c = get_cone(f"penetrologger-{a:g}cm2")
        assert c.base_area == pytest.approx(a * 1e-4, rel=1e-15) and c.angle_deg == 60.0
        assert c.height == pytest.approx(math.sqrt(a * 1e-4 / math.pi) / math.tan(math.pi / 6))
    assert get_cone("5cm2:60").base_area == pytest.approx(5e-4, rel=1e-15)
    assert get_cone("500 mm^2:60").base_area == pytest.approx(5e-4, rel=1e-15)
    assert get_cone("0.5in2:30").base_area == pytest.approx(0.5 * 0.0254**2, rel=1e-15)
    with pytest.raises(ValueError, match=r"AREA<cm2\|mm2\|in2>:ANGLE"):
        get_cone("5cm3:60")


# ---------------------------------------------------------------------------
# the command line
# ---------------------------------------------------------------------------


def test_cli_predict_and_batch_on_a_wide_file(tmp_path: Path, semi: Path):
    r = CliRunner().invoke(cli, ["predict", str(semi), "--json"])
    assert r.exit_code != 0 and "--depth-unit" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(
        cli, ["predict", str(semi), "--depth-unit", "cm", "--cone", "5cm2:60", "--json"]
    )
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    status = {d["id"]: d["status"] for d in doc["profiles"]}
    assert status == {"P1": "ok", "P2": "ok", "P3": "error", "P4": "ok"}
    p3 = next(d for d in doc["profiles"] if d["id"] == "P3")
    assert "row 6, column 2: empty cell between readings" in p3["error"]
    p1 = next(d for d in doc["profiles"] if d["id"] == "P1")
    assert p1["cone"] == "5cm2:60" and p1["metadata"]["lat"] < 0
    out = tmp_path / "batch"
    args = ["batch", str(semi), "--out", str(out), "--depth-unit", "cm", "--quiet"]
    r = CliRunner().invoke(cli, [*args, "--workers", "1"])
    assert r.exit_code == 0, r.output
    assert (out / "_input" / "pushes.parquet").exists()  # converted once, kept for --resume
    rows = {row["profile"]: row for row in pq.read_table(out).to_pylist()}
    assert set(rows) == {"P1", "P2", "P3", "P4"} and rows["P3"]["status"] == "error"
    assert "empty cell between readings" in rows["P3"]["error"]
    assert float(rows["P1"]["lat"]) == pytest.approx(-(34 + 22.92106 / 60), abs=1e-12)
    # GeoJSON from the batch directory: P3 has no coordinates and is counted, not dropped
    gj = tmp_path / "b.geojson"
    r = CliRunner().invoke(
        cli, ["export", "--results", str(out), "--format", "geojson", "--out", str(gj)]
    )
    assert r.exit_code == 0, r.output
    assert "3 located profiles of 4; 1 without coordinates (no lat/lon in their metadata: P3)" in (
        r.stderr
    )
    feats = {f["properties"]["id"]: f for f in json.loads(gj.read_text())["features"]}
    assert set(feats) == {"P1", "P2", "P4"}
    assert feats["P4"]["geometry"]["coordinates"] == [19.25, -34.5]
    assert feats["P1"]["properties"]["status"] == "ok" and feats["P1"]["properties"]["kc"] >= 0


# ---------------------------------------------------------------------------
# the real Marsden SC900 export, re-written as wide tables
# ---------------------------------------------------------------------------


def _sc900_as_wide(src: Path, sep: str, comma: bool) -> str:
    """The push lines of the SC900 export as a wide table (plain string work)."""
    lines = src.read_text(encoding="utf-8").splitlines()
    head = next(ln for ln in lines if ln.startswith("Longitude,Latitude,Number,"))
    depths = [c.strip() for c in head.split(",")[3:-1]]  # "0.0 cm", ...
    out = ["# ci unit: kPa", sep.join(["id", *depths])]
    k = 0
    for ln in lines:
        cells = [c.strip() for c in ln.split(",")]
        if len(cells) > 3 and cells[2].startswith("N="):
            k += 1
            readings = cells[3:-1]
            if comma:
                readings = [c.replace(".", ",") for c in readings]
            out.append(sep.join([f"push{k}", *readings]))
    text = "\n".join(out) + "\n"
    return text.replace("0.0 cm", "0,0 cm") if comma else text


@pytest.mark.parametrize(("sep", "comma", "bom"), [(",", False, False), (";", True, True)])
def test_real_sc900_export_as_a_wide_table(tmp_path: Path, sep: str, comma: bool, bom: bool):
    src = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    assert detect_format(src) == "sc900"  # the export itself is not mistaken for a wide table
    wide = tmp_path / "marsden_wide.csv"
    wide.write_text(("\ufeff" if bom else "") + _sc900_as_wide(src, sep, comma), encoding="utf-8")
    assert detect_format(wide) == "wide"
    ref = read_ci_profiles(src, on_error="collect")
    got = read_wide_ci(wide, cone="asabe-small", on_error="collect")
    assert len(got) == len(ref) == 83
    for r, g in zip(ref, got):
        assert isinstance(r, CIProfile) == isinstance(g, CIProfile)
        if isinstance(r, CIProfile):
            np.testing.assert_array_equal(g.depth, r.depth)
            np.testing.assert_array_equal(g.ci, r.ci)
            assert g.metadata["trailing_zeros_dropped"] == r.metadata["trailing_zeros_dropped"]
    dropped = sum(g.metadata["trailing_zeros_dropped"] for g in got if isinstance(g, CIProfile))
    assert dropped > 0  # the real export has pushes that stopped early


def test_cli_learn_reads_a_wide_table(tmp_path: Path):
    from terracone.physics.cone import cone_index

    z_cm = np.arange(0.0, 31.0, 2.5)
    truth = dict(kc=100.0, kphi=5000.0, n=0.8, cc=2.0, phic_deg=20.0)
    ci = cone_index(z_cm / 100, cone=CONES["asabe-large"], **truth)
    wide = _write(
        tmp_path / "w.tsv",
        "\t".join(["id", *(f"{z:g}" for z in z_cm)])
        + "\n"
        + "\t".join(["s1", *(repr(float(c)).replace(".", ",") for c in ci)])
        + "\n",
    )
    sink = [5.0 * k for k in range(1, 11)]  # mm
    rows = [
        f"r{r:g},{r!r},{s!r},{(100 / (r / 100) + 5000) * (s / 1000) ** 0.8!r}\n"
        for r in (3.75, 5.0)
        for s in sink
    ]
    plates = _write(
        tmp_path / "p.csv", "test,plate_radius_cm,sinkage_mm,pressure_kpa\n" + "".join(rows)
    )
    common = ["--plates", str(plates), "--model", "rm0", "--json"]
    r = CliRunner().invoke(cli, ["learn", "--ci", str(wide), *common])
    assert r.exit_code != 0 and "--depth-unit" in r.output and "--ci-unit" in r.output
    args = ["learn", "--ci", str(wide), "--depth-unit", "cm", "--ci-unit", "kpa", *common]
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    # the P-S parameters of the (noise-free) plates, and a fit of the wide table's CI
    assert d["kc"] == pytest.approx(100.0, rel=0.05)
    assert d["kphi"] == pytest.approx(5000.0, rel=0.02)
    assert d["n"] == pytest.approx(0.8, abs=0.01)
    assert d["terrain"] == "w"

"""File readers and writers: terracone.io.

Expected values are typed by hand from the fixtures (tests/data/ or the
inline texts below) and from the real files in ../shared, counted with
grep/cut/awk; conversions use the exact factors 1 in = 0.0254 m and
1 psi = 6.894757293168361 kPa (4.4482216152605 N / 0.0254^2 m^2).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import require_shared

from terracone import CIProfile, InputError, PlateTest, ShearTest, get_cone
from terracone.io import (
    read_ci_profiles,
    read_plate_tests,
    read_shear_tests,
    write_ci_profiles,
    write_plate_tests,
    write_shear_tests,
)

DATA = Path(__file__).resolve().parent / "data"
PSI = 6.894757293168361  # kPa
INCH = 0.0254  # m
TAN15 = math.tan(math.radians(15.0))
H_SMALL = math.sqrt(0.2 * INCH**2 / math.pi) / TAN15  # ASABE small cone height [m]
H_LARGE = math.sqrt(0.5 * INCH**2 / math.pi) / TAN15  # ASABE large cone height [m]


def write(tmp_path: Path, text: str, name: str = "profiles.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def assert_located(
    exc: InputError,
    path: Path | str,
    *,
    profile: str | None = None,
    row: int | None = None,
    column: str | None = None,
    reason: str | None = None,
) -> None:
    """The error names file, profile, row and column, as attributes and in the text."""
    msg = str(exc)
    assert exc.file == str(path)
    assert f"file {path}" in msg
    assert exc.profile == profile
    if profile is not None:
        # plate and shear tests are named "test", CI profiles "profile"
        assert f"{exc.item} {profile}" in msg
        assert exc.item in ("profile", "test")
    assert exc.row == row
    if row is not None:
        assert f"row {row}" in msg
    assert exc.column == column
    if column is not None:
        assert f"column {column}" in msg
    if reason is not None:
        assert reason in exc.reason


# ---------------------------------------------------------------------------
# CI profiles, CSV
# ---------------------------------------------------------------------------


def test_single_profile_uses_file_stem_and_line_numbers(tmp_path):
    path = write(
        tmp_path,
        "# synthetic data\ndepth_m,ci_kpa\n0.0,100\n0.05,200\n# note\n0.10,300\n",
        "plot7.csv",
    )
    (p,) = read_ci_profiles(path)
    assert isinstance(p, CIProfile)
    assert p.id == "plot7"
    assert p.source == str(path)
    np.testing.assert_array_equal(p.depth, [0.0, 0.05, 0.10])
    np.testing.assert_array_equal(p.ci, [100.0, 200.0, 300.0])
    np.testing.assert_array_equal(p.rows, [3, 4, 6])  # comments count as lines
    assert p.cone == get_cone("asabe-large")
    assert p.metadata == {}
    assert p.notes == []


def test_fixture_profiles_metadata_cone_comments_and_case():
    path = DATA / "ci_two_profiles.csv"
    a, b = read_ci_profiles(path)
    assert (a.id, b.id) == ("A", "B")
    np.testing.assert_allclose(a.depth, [0.0, 0.025, 0.05], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(a.ci, [100.0, 250.0, 400.0])
    np.testing.assert_array_equal(a.rows, [4, 5, 7])
    np.testing.assert_array_equal(b.rows, [8, 9, 11, 12])  # blank line 10 skipped
    np.testing.assert_allclose(b.depth, [0.0, 0.01, 0.02, 0.03], rtol=0, atol=1e-15)
    # the cone column wins over the cone argument
    assert a.cone == get_cone("asabe-small")
    assert b.cone == get_cone("asabe-large")
    # metadata: first row, column order, floats where numeric
    assert a.metadata == {
        "Site": "north field",
        "Soil": "silt loam",
        "Lat": 42.01,
        "Lon": -93.74,
        "Date": "2019-06-11",
    }
    assert list(a.metadata) == ["Site", "Soil", "Lat", "Lon", "Date"]
    assert b.metadata["Site"] == "south field"
    assert b.metadata["Lat"] == 42.02


def test_metadata_only_decimal_numbers_become_floats(tmp_path):
    path = write(
        tmp_path,
        "plot,rep,moisture,flag,depth_cm,ci_kpa\n"
        "2018_13,3,,n/a,0,1\n2018_13,3,,n/a,1,2\n2018_13,3,,n/a,2,3\n",
    )
    (p,) = read_ci_profiles(path)
    # float("2018_13") would be 201813.0: a plot id must stay text
    assert p.metadata == {"plot": "2018_13", "rep": 3.0, "moisture": "", "flag": "n/a"}


@pytest.mark.parametrize(
    ("unit", "values", "expected_m"),
    [
        ("m", "0,0.5,1.25", [0.0, 0.5, 1.25]),
        ("cm", "0,2.5,10", [0.0, 0.025, 0.10]),
        ("mm", "0,25,100", [0.0, 0.025, 0.10]),
        ("in", "0,1,2.5", [0.0, 0.0254, 0.0635]),
        ("IN", "0,1,2.5", [0.0, 0.0254, 0.0635]),
    ],
)
def test_depth_units(tmp_path, unit, values, expected_m):
    rows = "".join(f"{v},100\n" for v in values.split(","))
    (p,) = read_ci_profiles(write(tmp_path, f"depth_{unit},ci_kpa\n{rows}"))
    np.testing.assert_allclose(p.depth, expected_m, rtol=1e-15, atol=1e-17)


@pytest.mark.parametrize(
    ("unit", "values", "expected_kpa"),
    [
        ("kpa", [100, 250, 1000], [100.0, 250.0, 1000.0]),
        ("mpa", [0.1, 0.25, 1.5], [100.0, 250.0, 1500.0]),
        ("psi", [10, 50, 100], [68.94757293168361, 344.73786465841806, 689.4757293168361]),
        ("KPa", [100, 250, 1000], [100.0, 250.0, 1000.0]),
    ],
)
def test_ci_units(tmp_path, unit, values, expected_kpa):
    rows = "".join(f"{z},{v}\n" for z, v in zip((0, 1, 2), values))
    (p,) = read_ci_profiles(write(tmp_path, f"depth_cm,ci_{unit}\n{rows}"))
    np.testing.assert_allclose(p.ci, expected_kpa, rtol=1e-15)


def test_bare_columns_need_a_unit_system(tmp_path):
    path = write(tmp_path, "depth,ci\n0,10\n1,20\n2,30\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=1, column="depth", reason="no unit")
    (si,) = read_ci_profiles(path, units="si")
    np.testing.assert_array_equal(si.depth, [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(si.ci, [10.0, 20.0, 30.0])
    (us,) = read_ci_profiles(path, units="us")
    np.testing.assert_allclose(us.depth, [0.0, 0.0254, 0.0508], rtol=1e-15)
    np.testing.assert_allclose(us.ci, [10 * PSI, 20 * PSI, 30 * PSI], rtol=1e-15)


def test_cone_argument_and_depth_ref_tip(tmp_path):
    path = write(tmp_path, "depth_cm,ci_kpa\n0,0\n2.5,300\n5,500\n")
    (base,) = read_ci_profiles(path, cone="asabe-small")
    assert base.cone == get_cone("asabe-small")
    np.testing.assert_allclose(base.depth, [0.0, 0.025, 0.05], atol=1e-15)
    (tip,) = read_ci_profiles(path, cone="asabe-small", depth_ref="tip")
    # a tip at the surface is a base at -H: a legal (empty) partial penetration
    np.testing.assert_allclose(tip.depth, [-H_SMALL, 0.025 - H_SMALL, 0.05 - H_SMALL], atol=1e-15)
    (big,) = read_ci_profiles(path, depth_ref="tip")
    np.testing.assert_allclose(big.depth[0], -H_LARGE, rtol=1e-12)


def test_bad_arguments_are_value_errors(tmp_path):
    path = write(tmp_path, "depth_cm,ci_kpa\n0,0\n1,1\n2,2\n")
    with pytest.raises(ValueError, match="on_error"):
        read_ci_profiles(path, on_error="ignore")
    with pytest.raises(ValueError, match="depth_ref"):
        read_ci_profiles(path, depth_ref="middle")
    with pytest.raises(ValueError, match="cone"):
        read_ci_profiles(path, cone="giant")
    with pytest.raises(ValueError, match="format"):
        read_ci_profiles(path, format="xlsx")


# --- file-level errors -------------------------------------------------------


def test_missing_file(tmp_path):
    path = tmp_path / "nope.csv"
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, reason="not found")


def test_missing_ci_column(tmp_path):
    path = write(tmp_path, "profile,depth_cm,site\nA,0,x\nA,1,x\nA,2,x\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=1, column="ci_<kpa|mpa|psi|pa>", reason="missing")


def test_missing_depth_column_after_comment_reports_the_header_line(tmp_path):
    path = write(tmp_path, "# synthetic data\nci_kpa\n1\n2\n3\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=2, column="depth_<m|cm|mm|in>", reason="missing")


@pytest.mark.parametrize(
    ("header", "column"),
    [
        ("depth_ft,ci_kpa", "depth_ft"),
        ("depth_cm,ci_bar", "ci_bar"),
        ("Depth_FT,ci_kpa", "Depth_FT"),
    ],
)
def test_unknown_unit_suffix(tmp_path, header, column):
    path = write(tmp_path, f"{header}\n0,1\n1,2\n2,3\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=1, column=column, reason="unknown")


def test_two_depth_columns(tmp_path):
    path = write(tmp_path, "depth_cm,ci_kpa,depth_in\n0,1,0\n1,2,0.4\n2,3,0.8\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=1, column="depth_in", reason="depth_cm")


def test_duplicate_column_name(tmp_path):
    path = write(tmp_path, "site,depth_cm,ci_kpa,Site\na,0,1,b\na,1,2,b\na,2,3,b\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=1, column="Site", reason="duplicate")


def test_row_with_extra_fields(tmp_path):
    path = write(tmp_path, "depth_cm,ci_kpa\n0,1\n1,2,7\n2,3\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path, on_error="collect")  # file-level: raises in both modes
    assert_located(ei.value, path, row=3, reason="3 fields")


# --- profile-level errors ------------------------------------------------------

GOOD_B = "B,0,10\nB,1,20\nB,2,30\n"


def test_non_numeric_cell(tmp_path):
    path = write(tmp_path, "profile,depth_cm,ci_kpa\nA,0,10\nA,1,abc\nA,2,30\n" + GOOD_B)
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=3, column="ci_kpa", reason="abc")


def test_nan_cell(tmp_path):
    path = write(tmp_path, "profile,depth_cm,ci_kpa\nA,0,10\nA,NaN,20\nA,2,30\n" + GOOD_B)
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=3, column="depth_cm", reason="NaN")


def test_empty_cell(tmp_path):
    path = write(tmp_path, "profile,depth_cm,CI_KPA\nA,0,10\nA,1,20\nA,2,\n" + GOOD_B)
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=4, column="CI_KPA", reason="empty")


def test_short_row_is_an_empty_cell(tmp_path):
    path = write(tmp_path, "profile,depth_cm,ci_kpa\nA,0,10\nA,1\nA,2,30\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=3, column="ci_kpa", reason="empty")


def test_negative_ci(tmp_path):
    path = write(tmp_path, "profile,depth_cm,ci_psi\n" + GOOD_B + "A,0,10\nA,1,-3\nA,2,30\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=6, column="ci_psi", reason="negative")
    assert "'-3'" in str(ei.value)  # the file's own value is quoted


def test_depth_not_strictly_increasing(tmp_path):
    path = write(tmp_path, "profile,depth_cm,ci_kpa\nA,0,10\nA,1,20\nA,1,25\nA,2,30\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=4, column="depth_cm", reason="increasing")
    assert "line 3" in str(ei.value)  # the previous point


def test_too_few_points(tmp_path):
    path = write(
        tmp_path, "# two points only\nprofile,depth_cm,ci_kpa\n" + GOOD_B + "A,0,10\nA,1,20\n"
    )
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=6, column="ci_kpa", reason="at least 3")


def test_base_depth_above_minus_h(tmp_path):
    # base reference: -5 cm is above -H = -3.78 cm of the large cone
    path = write(tmp_path, "profile,depth_cm,ci_kpa\nA,-5,0\nA,0,20\nA,2,30\n")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=2, column="depth_cm", reason="-H")
    # -3 cm is within the cone height: a partial penetration, legal
    ok = write(tmp_path, "profile,depth_cm,ci_kpa\nA,-3,0\nA,0,20\nA,2,30\n", "ok.csv")
    (p,) = read_ci_profiles(ok)
    assert p.depth[0] == pytest.approx(-0.03)


def test_tip_depth_above_surface(tmp_path):
    path = write(tmp_path, "depth_cm,ci_kpa\n-0.5,0\n0,20\n2,30\n", "tipfile.csv")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path, depth_ref="tip")
    assert_located(ei.value, path, profile="tipfile", row=2, column="depth_cm", reason="-H")
    assert "tip depth" in str(ei.value)


def test_unknown_cone_in_cone_column(tmp_path):
    path = write(
        tmp_path, "profile,cone,depth_cm,ci_kpa\n" + "A,huge,0,1\nA,huge,1,2\nA,huge,2,3\n"
    )
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=2, column="cone", reason="cone")


def test_cone_changing_within_profile(tmp_path):
    path = write(
        tmp_path,
        "profile,Cone,depth_cm,ci_kpa\nA,asabe-small,0,1\nA,asabe-small,1,2\nA,asabe-large,2,3\n",
    )
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, profile="A", row=4, column="Cone", reason="changes")


def test_custom_cone_in_cone_column(tmp_path):
    path = write(tmp_path, "cone,depth_cm,ci_kpa\n20mm:30,0,1\n20mm:30,1,2\n20mm:30,2,3\n")
    (p,) = read_ci_profiles(path)
    assert p.cone.radius == pytest.approx(0.01)


def test_collect_returns_good_profiles_and_errors_in_file_order(tmp_path):
    text = (
        "# synthetic data\n"
        "profile,site,depth_cm,ci_kpa\n"
        "good1,x,0,10\ngood1,x,1,20\ngood1,x,2,30\n"  # lines 3-5
        "bad1,y,0,10\nbad1,y,1,oops\nbad1,y,2,30\n"  # line 7: non-numeric
        "good2,z,0,5\ngood2,z,2.5,6\ngood2,z,5,7\n"  # lines 9-11
        "bad2,w,0,10\nbad2,w,1,-1\nbad2,w,2,30\n"  # line 13: negative
        "bad3,v,0,1\n"  # line 15: one point
    )
    path = write(tmp_path, text)
    items = read_ci_profiles(path, on_error="collect")
    assert [type(x).__name__ for x in items] == [
        "CIProfile",
        "InputError",
        "CIProfile",
        "InputError",
        "InputError",
    ]
    g1, e1, g2, e2, e3 = items
    assert (g1.id, g2.id) == ("good1", "good2")
    np.testing.assert_array_equal(g2.ci, [5.0, 6.0, 7.0])
    np.testing.assert_array_equal(g2.rows, [9, 10, 11])
    assert g2.metadata == {"site": "z"}
    assert_located(e1, path, profile="bad1", row=7, column="ci_kpa", reason="oops")
    assert_located(e2, path, profile="bad2", row=13, column="ci_kpa", reason="negative")
    assert_located(e3, path, profile="bad3", row=15, column="ci_kpa", reason="at least 3")
    # raise mode: the first bad profile raises
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert ei.value.profile == "bad1"


def test_interleaved_profile_rows_are_grouped_by_id(tmp_path):
    path = write(tmp_path, "profile,depth_cm,ci_kpa\nA,0,1\nB,0,4\nA,1,2\nB,1,5\nA,2,3\nB,2,6\n")
    a, b = read_ci_profiles(path)
    np.testing.assert_array_equal(a.ci, [1, 2, 3])
    np.testing.assert_array_equal(a.rows, [2, 4, 6])
    np.testing.assert_array_equal(b.rows, [3, 5, 7])


def test_quoted_multiline_metadata_keeps_line_numbers(tmp_path):
    path = write(tmp_path, 'note,depth_cm,ci_kpa\n"two\nlines",0,1\nx,1,2\n# c\nx,2,3\n')
    (p,) = read_ci_profiles(path)
    assert p.metadata == {"note": "two\nlines"}
    np.testing.assert_array_equal(p.rows, [2, 4, 6])


def test_crlf_and_byte_order_mark(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbf# exported\r\nDepth_cm,CI_kPa,\r\n0,1,\r\n1,2,\r\n2,3,\r\n")
    (p,) = read_ci_profiles(path)  # BOM, CRLF and trailing separators (Excel)
    np.testing.assert_array_equal(p.ci, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(p.rows, [3, 4, 5])
    assert p.metadata == {}


def test_large_file_reads_quickly(tmp_path):
    n_prof, n_pts = 5000, 20  # 10^5 rows
    z = np.arange(n_pts) * 2.5
    lines = ["profile,site,depth_cm,ci_kpa"]
    for k in range(n_prof):
        lines += [f"p{k},s,{zz},{100 + j}" for j, zz in enumerate(z)]
    path = write(tmp_path, "\n".join(lines) + "\n")
    t0 = time.perf_counter()
    profiles = read_ci_profiles(path)
    elapsed = time.perf_counter() - t0
    assert len(profiles) == n_prof
    assert profiles[-1].rows[-1] == n_prof * n_pts + 1
    assert elapsed < 10.0  # about 1 s on a laptop; generous for CI machines


# --- round trips ---------------------------------------------------------------


def _profiles() -> list[CIProfile]:
    return [
        CIProfile(
            "A/1",
            depth=[-0.01, 0.0, 0.0254, 0.0508],
            ci=[0.0, 123.456789, 1e3 / 3, 2e3],
            cone="asabe-small",
            metadata={"site": "north, field", "lat": 42.0123456789, "rep": 3.0},
        ),
        CIProfile(
            "#B",  # would read as a comment if not quoted
            depth=[0.0, 0.1, 0.2],
            ci=[1.0, 2.0, 3.0],
            metadata={"site": 'say "hi"', "date": "2019-06-11"},
        ),
    ]


def test_ci_round_trip_si_is_exact(tmp_path):
    path = tmp_path / "out.csv"
    original = _profiles()
    write_ci_profiles(path, original, comment="synthetic data\nsecond line")
    text = path.read_text()
    assert text.startswith("# synthetic data\n# second line\n")
    back = read_ci_profiles(path)
    assert len(back) == 2
    for p, q in zip(original, back):
        assert q.id == p.id
        assert q.cone == p.cone
        np.testing.assert_array_equal(q.depth, p.depth)
        np.testing.assert_array_equal(q.ci, p.ci)
        assert q.source == str(path)
    assert back[0].metadata == {
        "site": "north, field",
        "lat": 42.0123456789,
        "rep": 3.0,
        "date": "",
    }
    assert back[1].metadata == {"site": 'say "hi"', "lat": "", "rep": "", "date": "2019-06-11"}
    np.testing.assert_array_equal(back[0].rows, [4, 5, 6, 7])  # 2 comments + header


@pytest.mark.parametrize(("lu", "pu"), [("cm", "psi"), ("mm", "mpa"), ("in", "kpa")])
def test_ci_round_trip_other_units(tmp_path, lu, pu):
    path = tmp_path / "out.csv"
    original = _profiles()
    write_ci_profiles(path, original, length_unit=lu, pressure_unit=pu)
    assert f"depth_{lu},ci_{pu}" in path.read_text().splitlines()[0]
    back = read_ci_profiles(path)
    for p, q in zip(original, back):
        np.testing.assert_allclose(q.depth, p.depth, rtol=1e-14, atol=1e-18)
        np.testing.assert_allclose(q.ci, p.ci, rtol=1e-14, atol=1e-18)


def test_ci_round_trip_custom_cone(tmp_path):
    cone = get_cone("20.27mm:30")
    p = CIProfile("c", depth=[0, 0.01, 0.02], ci=[1, 2, 3], cone=cone)
    path = tmp_path / "c.csv"
    write_ci_profiles(path, [p])
    (q,) = read_ci_profiles(path)
    assert q.cone == cone


def test_ci_writer_rejects_ambiguous_input(tmp_path):
    p = CIProfile("a", depth=[0, 1, 2], ci=[1, 2, 3])
    with pytest.raises(ValueError, match="duplicate"):
        write_ci_profiles(tmp_path / "x.csv", [p, p])
    bad = CIProfile("b", depth=[0, 1, 2], ci=[1, 2, 3], metadata={"depth_in": 1.0})
    with pytest.raises(ValueError, match="data column"):
        write_ci_profiles(tmp_path / "x.csv", [bad])
    with pytest.raises(ValueError, match="unit"):
        write_ci_profiles(tmp_path / "x.csv", [p], length_unit="ft")


# ---------------------------------------------------------------------------
# plate and shear tests
# ---------------------------------------------------------------------------


def test_plate_fixture_diameter_negative_values_and_unloading():
    path = DATA / "plate_small.csv"
    p1, p2 = read_plate_tests(path)
    assert isinstance(p1, PlateTest)
    assert (p1.id, p1.shape, p1.b) == ("p1", "circular", pytest.approx(0.075))
    assert p1.radius == pytest.approx(0.075)
    np.testing.assert_allclose(p1.sinkage, [0.0, -1e-5, 0.005, 0.010, 0.008], atol=1e-18)
    np.testing.assert_array_equal(p1.pressure, [0.0, -0.5, 20.0, 35.0, 12.0])
    np.testing.assert_array_equal(p1.rows, [3, 4, 5, 6, 7])
    assert p1.metadata == {"operator": "ann"}
    assert p1.source == str(path)
    assert (p2.id, p2.b) == ("p2", pytest.approx(0.05))
    assert p2.metadata == {"operator": "bob"}


@pytest.mark.parametrize(
    ("column", "shape", "b"),
    [("plate_radius_cm", "circular", 0.1), ("plate_width_in", "rectangular", 0.254)],
)
def test_plate_size_columns(tmp_path, column, shape, b):
    path = write(tmp_path, f"{column},sinkage_in,pressure_psi\n10,0,0\n10,1,10\n", "plate.csv")
    (t,) = read_plate_tests(path)
    assert (t.id, t.shape) == ("plate", shape)
    assert t.b == pytest.approx(b, rel=1e-15)
    np.testing.assert_allclose(t.sinkage, [0.0, 0.0254], rtol=1e-15)
    np.testing.assert_allclose(t.pressure, [0.0, 10 * PSI], rtol=1e-15)


def test_plate_two_size_columns(tmp_path):
    path = write(tmp_path, "plate_radius_m,plate_diameter_m,sinkage_m,pressure_kpa\n1,2,0,0\n")
    with pytest.raises(InputError) as ei:
        read_plate_tests(path)
    assert_located(ei.value, path, row=1, column="plate_diameter_m", reason="plate_radius_m")


def test_plate_missing_size_column(tmp_path):
    path = write(tmp_path, "sinkage_m,pressure_kpa\n0,0\n")
    with pytest.raises(InputError) as ei:
        read_plate_tests(path)
    assert "plate_radius_<m|cm|mm|in>" in ei.value.column
    assert "plate_width_<m|cm|mm|in>" in ei.value.column
    assert ei.value.row == 1


def test_plate_size_changes_within_test(tmp_path):
    path = write(
        tmp_path,
        "test,plate_diameter_mm,sinkage_mm,pressure_kpa\nt,150,0,0\nt,150,1,1\nt,100,2,2\n",
    )
    with pytest.raises(InputError) as ei:
        read_plate_tests(path)
    assert_located(ei.value, path, profile="t", row=4, column="plate_diameter_mm", reason="changes")


@pytest.mark.parametrize(
    ("cell", "reason"), [("x", "not a number"), ("nan", "finite"), ("", "empty")]
)
def test_plate_bad_cells_collect(tmp_path, cell, reason):
    path = write(
        tmp_path,
        "test,plate_radius_m,sinkage_m,pressure_kpa\n"
        f"bad,0.1,0,0\nbad,0.1,0.01,{cell}\ngood,0.1,0,0\ngood,0.1,0.01,5\n",
    )
    bad, good = read_plate_tests(path, on_error="collect")
    assert_located(bad, path, profile="bad", row=3, column="pressure_kpa", reason=reason)
    assert isinstance(good, PlateTest) and good.id == "good"


def test_plate_size_must_be_positive(tmp_path):
    path = write(tmp_path, "test,plate_radius_m,sinkage_m,pressure_kpa\nt,0,0,0\nt,0,1,1\n")
    with pytest.raises(InputError) as ei:
        read_plate_tests(path)
    assert_located(ei.value, path, profile="t", row=2, column="plate_radius_m", reason="> 0")


def test_plate_round_trip(tmp_path):
    tests = [
        PlateTest(
            "a",
            0.075,
            "circular",
            [0.0, -1e-5, 0.01, 0.008],
            [0.0, -0.5, 30.0, 10.0],
            metadata={"method": 5.0},
        ),
        PlateTest("b", 0.05, "circular", [0.0, 0.02], [0.0, 40.0], metadata={"method": "M1"}),
    ]
    path = tmp_path / "plates.csv"
    write_plate_tests(path, tests, comment="synthetic data")
    back = read_plate_tests(path)
    for t, r in zip(tests, back):
        assert (r.id, r.shape, r.b, r.metadata) == (t.id, t.shape, t.b, t.metadata)
        np.testing.assert_array_equal(r.sinkage, t.sinkage)
        np.testing.assert_array_equal(r.pressure, t.pressure)
    rect = [PlateTest("r", 0.1, "rectangular", [0.0, 0.01], [0.0, 20.0])]
    write_plate_tests(path, rect, length_unit="mm", pressure_unit="psi")
    (r,) = read_plate_tests(path)
    assert r.shape == "rectangular" and r.b == pytest.approx(0.1, rel=1e-15)
    np.testing.assert_allclose(r.pressure, [0.0, 20.0], rtol=1e-14)
    with pytest.raises(ValueError, match="circular and rectangular"):
        write_plate_tests(path, tests + rect)


def test_shear_fixture_units_and_metadata():
    path = DATA / "shear_small.csv"
    s1, s2 = read_shear_tests(path)
    assert isinstance(s1, ShearTest)
    assert (s1.id, s2.id) == ("s1", "s2")
    assert s1.normal_pressure == pytest.approx(50.0, rel=1e-15)  # 0.05 MPa
    assert s2.normal_pressure == pytest.approx(100.0, rel=1e-15)
    np.testing.assert_allclose(s1.displacement, [0.0, -1e-4, 0.005], atol=1e-18)
    np.testing.assert_allclose(s1.stress, [0.0, 0.1 * PSI, 3 * PSI], rtol=1e-15)
    np.testing.assert_array_equal(s2.rows, [6, 7, 8])  # comment, header, s1 x 3
    assert s1.metadata == {"note": "first"}


def test_shear_normal_pressure_changes_within_test(tmp_path):
    path = write(
        tmp_path,
        "test,normal_pressure_kpa,shear_displacement_mm,shear_stress_kpa\n"
        "t,93,0,0\nt,93,1,5\nt,94,2,8\n",
    )
    with pytest.raises(InputError) as ei:
        read_shear_tests(path)
    assert_located(
        ei.value, path, profile="t", row=4, column="normal_pressure_kpa", reason="changes"
    )


def test_shear_missing_column_and_bad_cell(tmp_path):
    path = write(tmp_path, "test,normal_pressure_kpa,shear_stress_kpa\nt,93,0\n")
    with pytest.raises(InputError) as ei:
        read_shear_tests(path)
    assert_located(ei.value, path, row=1, column="shear_displacement_<m|cm|mm|in>")
    path = write(
        tmp_path,
        "test,normal_pressure_kpa,shear_displacement_mm,shear_stress_kpa\nt,93,0,0\nt,93,1,?\n",
    )
    with pytest.raises(InputError) as ei:
        read_shear_tests(path)
    assert_located(ei.value, path, profile="t", row=3, column="shear_stress_kpa")


def test_shear_round_trip(tmp_path):
    tests = [ShearTest("s", 93.0, [0.0, -6e-5, 0.01], [0.0, 0.2, 40.0], metadata={"m": "x"})]
    path = tmp_path / "shear.csv"
    write_shear_tests(path, tests)
    (r,) = read_shear_tests(path)
    assert (r.id, r.normal_pressure, r.metadata) == ("s", 93.0, {"m": "x"})
    np.testing.assert_array_equal(r.displacement, tests[0].displacement)
    np.testing.assert_array_equal(r.stress, tests[0].stress)


# ---------------------------------------------------------------------------
# FieldScout SC900 exports
# ---------------------------------------------------------------------------

# Hand counts from sc900_export_2019-06-11.txt (grep/awk): 111 lines = 5 header
# lines + 23 "Logger Started" lines + 83 push lines; file line of each push with
# trailing zeros -> number of trailing zeros.
SC900_PUSHES = 83
SC900_LOGGER_STARTED = 23
SC900_TRAILING = {
    8: 12, 20: 10, 24: 5, 30: 11, 31: 3, 35: 5, 36: 4, 38: 2, 44: 1, 45: 1,
    47: 2, 48: 2, 49: 2, 50: 1, 51: 3, 52: 1, 54: 4, 57: 2, 59: 2, 60: 7,
    62: 1, 64: 5, 65: 1, 66: 7, 67: 1, 70: 1, 72: 5, 73: 2, 74: 2, 75: 2,
    76: 5, 77: 1, 78: 6, 80: 1, 81: 1, 82: 1, 88: 1, 93: 2, 94: 1, 95: 1,
    98: 1, 99: 1, 102: 1, 103: 2, 104: 1, 105: 1, 106: 1, 107: 1, 108: 2, 109: 1,
    110: 2, 111: 1,
}  # fmt: skip


def test_sc900_real_export():
    path = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    lines = path.read_text().splitlines()
    assert len(lines) == 111
    assert sum(ln.strip() == ",,Logger Started" for ln in lines) == SC900_LOGGER_STARTED
    profiles = read_ci_profiles(path)  # format detected
    assert len(profiles) == SC900_PUSHES
    assert all(isinstance(p, CIProfile) for p in profiles)
    assert len({p.id for p in profiles}) == SC900_PUSHES
    assert all(p.cone == get_cone("asabe-small") for p in profiles)  # "1/2 Inch"
    assert {p.metadata["pressure_unit"] for p in profiles} == {"kpa"}
    assert {p.metadata["length_unit"] for p in profiles} == {"cm"}
    # no push line is a Logger Started line: the rows are the push lines
    push_lines = [int(p.rows[0]) for p in profiles]
    assert push_lines[:4] == [8, 20, 24, 25] and push_lines[-1] == 111
    assert all(",,N=" in lines[r - 1] for r in push_lines)
    # trailing zeros
    dropped = {p.metadata["line"]: p.metadata["trailing_zeros_dropped"] for p in profiles}
    assert {k: v for k, v in dropped.items() if v} == SC900_TRAILING
    assert sum(dropped.values()) == 142
    for p in profiles:
        assert len(p) == 19 - p.metadata["trailing_zeros_dropped"]
        assert bool(p.notes) == (p.metadata["trailing_zeros_dropped"] > 0)
    # first push, line 8: ",,N= 1 , 34 , 34 , 1208 , 1449 , 1138 , 1104 , 1760 , 0 x 12"
    first = profiles[0]
    assert first.id == "sc900_export_2019-06-11/0001-N1"
    np.testing.assert_array_equal(first.ci, [34, 34, 1208, 1449, 1138, 1104, 1760])
    np.testing.assert_allclose(first.depth, [0, 0.025, 0.05, 0.075, 0.10, 0.125, 0.15], atol=1e-15)
    np.testing.assert_array_equal(first.rows, [8] * 7)
    assert first.notes == ["dropped 12 trailing zero readings (push stopped at 17.5 cm)"]
    assert first.metadata == {
        "logger": "Archontoulis_PokeMe",
        "serial": "2543",
        "datum": "WGS 84",
        "push": 1,
        "line": 8,
        "pressure_unit": "kpa",
        "length_unit": "cm",
        "trailing_zeros_dropped": 12,
    }
    assert first.source == str(path)
    # push numbers restart: 10 pushes are "N= 1", all with distinct ids
    n1 = [p.id for p in profiles if p.metadata["push"] == 1]
    assert len(n1) == 10 and n1[1] == "sc900_export_2019-06-11/0002-N1"
    assert profiles[-1].id == "sc900_export_2019-06-11/0083-N10"
    # line 31 (N= 8): an interior zero at 32.5 cm is a reading and is kept
    p31 = next(p for p in profiles if p.metadata["line"] == 31)
    assert len(p31) == 16 and p31.ci[13] == 0.0 and p31.ci[-1] == 794.0
    # stable across runs
    assert [p.id for p in read_ci_profiles(path, format="sc900")] == [p.id for p in profiles]


def test_sc900_real_export_tip_reference():
    path = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    profiles = read_ci_profiles(path, depth_ref="tip")
    assert len(profiles) == SC900_PUSHES
    assert profiles[0].depth[0] == pytest.approx(-H_SMALL, rel=1e-12)
    assert profiles[0].depth[1] == pytest.approx(0.025 - H_SMALL, rel=1e-12)


def test_sc900_synthetic_psi_inch_large_cone_and_errors():
    path = DATA / "sc900_psi_inch.txt"
    items = read_ci_profiles(path, on_error="collect")
    assert len(items) == 6  # six push lines, two Logger Started lines ignored
    p1, p2, zeros, p4, unknown, p6 = items
    stem = "sc900_psi_inch"
    # push numbers repeat (N= 1, 2 then N= 1, 2 again): ordinals make ids unique
    assert [p1.id, p2.id, p4.id, p6.id] == [
        f"{stem}/0001-N1",
        f"{stem}/0002-N2",
        f"{stem}/0004-N2",
        f"{stem}/0006-N4",
    ]
    assert p1.cone == get_cone("asabe-large")  # "3/4 Inch"
    np.testing.assert_allclose(p1.depth, [0, 0.0254, 0.0508, 0.0762, 0.1016], rtol=1e-15)
    np.testing.assert_allclose(p1.ci, np.array([10, 20, 30, 40, 50]) * PSI, rtol=1e-15)
    np.testing.assert_array_equal(p1.rows, [7] * 5)
    assert p1.metadata == {
        "logger": "TEST_LOGGER",
        "serial": "1234",
        "datum": "WGS 84",
        "push": 1,
        "line": 7,
        "longitude": -93.5,
        "latitude": 42.25,
        "pressure_unit": "psi",
        "length_unit": "in",
        "trailing_zeros_dropped": 0,
    }
    assert p2.notes == ["dropped 2 trailing zero readings (push stopped at 3.0 in)"]
    np.testing.assert_allclose(p2.ci, [5 * PSI, 15 * PSI, 25 * PSI], rtol=1e-15)
    assert p2.metadata["trailing_zeros_dropped"] == 2
    # all zeros: an error for that push only
    assert isinstance(zeros, InputError)
    assert_located(zeros, path, profile=f"{stem}/0003-N1", row=10, column="0.0 in")
    assert "5 trailing zero" in zeros.reason and "at least 3" in zeros.reason
    # "1/2 Inch" is the small cone; an interior zero is kept
    assert p4.cone == get_cone("asabe-small")
    np.testing.assert_allclose(p4.ci, np.array([100, 0, 200, 300]) * PSI, rtol=1e-15)
    assert p4.notes == ["dropped 1 trailing zero reading (push stopped at 4.0 in)"]
    assert_located(unknown, path, profile=f"{stem}/0005-N3", row=12, column="Cone Size")
    assert "1 Inch" in unknown.reason
    assert isinstance(p6, CIProfile)
    # raise mode stops at the all-zero push
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert ei.value.profile == f"{stem}/0003-N1"


def test_sc900_profiles_round_trip_through_csv(tmp_path):
    path = DATA / "sc900_psi_inch.txt"
    good = [p for p in read_ci_profiles(path, on_error="collect") if isinstance(p, CIProfile)]
    out = tmp_path / "sc900.csv"
    write_ci_profiles(out, good, length_unit="in", pressure_unit="psi", comment="from SC900")
    back = read_ci_profiles(out)
    assert [q.id for q in back] == [p.id for p in good]
    for p, q in zip(good, back):
        assert q.cone == p.cone
        np.testing.assert_allclose(q.depth, p.depth, rtol=1e-14, atol=1e-18)
        np.testing.assert_allclose(q.ci, p.ci, rtol=1e-14)
        # numbers come back as floats (serial "1234" too): the CSV rule
        assert q.metadata["trailing_zeros_dropped"] == float(p.metadata["trailing_zeros_dropped"])
        assert q.metadata["pressure_unit"] == "psi"


SC900_HEAD = (
    "Name: X\nSerial #: 1\nDatum: WGS 84\nSoil Compation In KPa\n"
    "Longitude,Latitude,Number,0.0 cm,2.5 cm,5.0 cm,Cone Size\n"
)


def test_sc900_bad_reading_and_wrong_field_count(tmp_path):
    path = write(
        tmp_path,
        SC900_HEAD + ",,N= 1 , 10 , x , 30 ,1/2 Inch\n,,N= 2 , 10 , 20 ,1/2 Inch\n"
        ",,N= 3 , 10 , 20 , 30 ,1/2 Inch\n",
        "push.txt",
    )
    bad, short, good = read_ci_profiles(path, on_error="collect")
    assert_located(bad, path, profile="push/0001-N1", row=6, column="2.5 cm", reason="'x'")
    assert_located(short, path, profile="push/0002-N2", row=7, column="5.0 cm", reason="2 readings")
    np.testing.assert_array_equal(good.ci, [10, 20, 30])


def test_sc900_decreasing_depth_label_and_negative_reading(tmp_path):
    head = SC900_HEAD.replace("5.0 cm", "2.0 cm")
    path = write(tmp_path, head + ",,N= 1 , 10 , 20 , 30 ,1/2 Inch\n", "dec.txt")
    (err,) = read_ci_profiles(path, on_error="collect")
    assert_located(err, path, profile="dec/0001-N1", row=6, column="2.0 cm", reason="increasing")
    path = write(tmp_path, SC900_HEAD + ",,N= 1 , 10 , -20 , 30 ,1/2 Inch\n", "neg.txt")
    (err,) = read_ci_profiles(path, on_error="collect")
    assert_located(err, path, profile="neg/0001-N1", row=6, column="2.5 cm", reason="negative")


def test_sc900_file_level_errors(tmp_path):
    path = write(
        tmp_path,
        SC900_HEAD.replace("0.0 cm", "0.0 ft") + ",,N= 1 , 1 , 2 , 3 ,1/2 Inch\n",
        "ft.txt",
    )
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=5, column="0.0 ft")
    path = write(
        tmp_path,
        SC900_HEAD.replace("Soil Compation In KPa\n", "") + ",,N= 1 , 1 , 2 , 3 ,1/2 Inch\n",
        "nounit.txt",
    )
    with pytest.raises(InputError, match="unit line"):
        read_ci_profiles(path)
    (p,) = read_ci_profiles(path, units="us")
    np.testing.assert_allclose(p.ci, [PSI, 2 * PSI, 3 * PSI], rtol=1e-15)
    path = write(tmp_path, SC900_HEAD + "garbage line\n", "garbage.txt")
    with pytest.raises(InputError) as ei:
        read_ci_profiles(path)
    assert_located(ei.value, path, row=6, reason="not a push line")


# ---------------------------------------------------------------------------
# real CSV files in ../shared
# ---------------------------------------------------------------------------


def test_marsden_ci_profiles_csv():
    path = require_shared("data", "marsden-penetrometer", "ci_profiles.csv")
    profiles = read_ci_profiles(path, cone="asabe-small")
    # `tail -n +2 ci_profiles.csv | cut -d, -f1 | sort -u | wc -l` -> 224
    assert len(profiles) == 224
    assert all(isinstance(p, CIProfile) for p in profiles)
    assert sum(len(p) for p in profiles) == 4003  # data lines
    by_date: dict[str, int] = {}
    for p in profiles:
        by_date[p.metadata["date"]] = by_date.get(p.metadata["date"], 0) + 1
    assert by_date == {"2018-05-10": 79, "2018-07-16": 64, "2019-06-11": 81}
    first = profiles[0]
    assert first.id == "2018-05-10/2018_13-1"
    assert first.metadata == {"date": "2018-05-10", "plot": "2018_13", "soil_moisture_g_g": 0.2398}
    # depth_cm 2.54 -> 0.0254 m, ci_kpa 861.845 kept
    assert first.depth[1] == pytest.approx(0.0254, rel=1e-15)
    assert first.ci[1] == 861.845
    assert len(first) == 19 and first.depth[-1] == pytest.approx(0.4572, rel=1e-15)
    late = next(p for p in profiles if p.id == "2019-06-11/2019_12-1")
    assert late.rows[0] == 2591 and late.metadata["soil_moisture_g_g"] == ""
    np.testing.assert_allclose(late.depth[:3], [0, 0.025, 0.05], atol=1e-15)


def test_cullinan_plate_and_shear_csv():
    plate_path = require_shared("data", "cullinan-sand", "plate_sinkage.csv")
    plates = read_plate_tests(plate_path)
    assert len(plates) == 13
    assert [t.id for t in plates][:2] == ["method_5_test_1", "method_1_test_1"]
    assert all(t.shape == "circular" for t in plates)
    assert all(t.b == pytest.approx(0.0757, rel=1e-12) for t in plates)  # 151.4 mm / 2
    assert all(len(t.sinkage) == 2000 for t in plates)
    m5 = plates[0]
    # line 4: "method_5_test_1,5,1538,151.4,-0.0030224,-0.80808"
    assert m5.sinkage[2] == pytest.approx(-3.0224e-6, rel=1e-12)
    assert m5.pressure[2] == -0.80808
    assert m5.sinkage.min() == pytest.approx(-4.2138e-6, rel=1e-12)
    assert m5.sinkage.max() == pytest.approx(0.080, rel=1e-12)
    assert m5.metadata == {"method": 5.0, "dry_density_kg_m3": 1538.0}
    assert plates[1].metadata == {"method": "Method 1", "dry_density_kg_m3": ""}
    assert plates[1].rows[0] == 2002

    shear_path = require_shared("data", "cullinan-sand", "shear.csv")
    shear = read_shear_tests(shear_path)
    assert len(shear) == 4
    assert [s.id for s in shear] == [
        "Method 5_sn93_test1",
        "Method 4_sn93_test2",
        "Method 2_sn93_test3",
        "Method 3_sn93_test4",
    ]
    assert all(s.normal_pressure == 93.0 for s in shear)
    assert all(len(s.stress) == 2000 for s in shear)
    # line 3: "...,93,-0.059889,0.20074": mm -> m, kPa kept
    assert shear[0].displacement[1] == pytest.approx(-5.9889e-5, rel=1e-12)
    assert shear[0].stress[1] == 0.20074

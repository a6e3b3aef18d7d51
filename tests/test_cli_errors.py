"""Bad input through the command line: one exact message, a non-zero exit.

The contract (README, terracone.cli): bad input ends with one message naming
the file, profile (or test), row and column, and a non-zero exit; never a
traceback.  Every test here builds a file with one known defect on a known
file line and asserts the whole error line expected for it.  An internal
crash (``terracone.cli.common.Group`` turns it into "Error: internal error (...)") fails every
test, since its text is not the expected one.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.physics.cone import cone_index


def run(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


def error_line(r, code: int = 1) -> str:
    """The one 'Error: ...' line of a failed run (exit ``code``), without 'Error: '."""
    assert r.exit_code == code, r.output
    assert "internal error" not in r.output and "Traceback" not in r.output, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    errors = [ln for ln in r.output.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1, r.output
    return errors[0][len("Error: ") :]


# ---------------------------------------------------------------------------
# files with one known defect each (the header is file line 1)
# ---------------------------------------------------------------------------

Z_CM = np.arange(0.0, 31.0, 2.0)  # 16 readings on file lines 2-17
CI_HEAD = "profile,depth_cm,ci_kpa"
PLATE_HEAD = "test,plate_radius_cm,sinkage_mm,pressure_kpa"
SHEAR_HEAD = "test,normal_pressure_kpa,shear_displacement_mm,shear_stress_kpa"


def ci_lines() -> list[str]:
    ci = cone_index(Z_CM * 0.01, kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
    return [CI_HEAD] + [f"A,{z:g},{c:.3f}" for z, c in zip(Z_CM, ci)]


def plate_lines() -> list[str]:
    s_mm = np.arange(2.0, 42.0, 4.0)  # 10 points per test: r3.75 on lines 2-11, r5 on 12-21
    out = [PLATE_HEAD]
    for r_cm in (3.75, 5.0):
        p = (100.0 / (r_cm / 100) + 5000.0) * (s_mm / 1000) ** 0.8
        out += [f"r{r_cm:g},{r_cm:g},{s:g},{v:.3f}" for s, v in zip(s_mm, p)]
    return out


def shear_lines() -> list[str]:
    out = [SHEAR_HEAD]  # 21 points per test: s10 on lines 2-22, s20 on 23-43, s40 on 44-64
    for sig in (10.0, 20.0, 40.0):
        for j in np.arange(0.0, 101.0, 5.0):
            tau = (2.0 + sig * math.tan(math.radians(30))) * (1 - math.exp(-j / 20.0))
            out.append(f"s{sig:g},{sig:g},{j:g},{tau:.4f}")
    return out


def edit(lines: list[str], line_no: int, text: str) -> list[str]:
    """Replace file line ``line_no`` (1-based) with ``text``."""
    out = list(lines)
    out[line_no - 1] = text
    return out


def located(path: Path, why: str) -> str:
    """The expected message: 'file PATH, row R, ...: reason' or 'file PATH: reason'."""
    sep = ", " if why.startswith(("row ", "profile ", "test ")) else ": "
    return f"file {path}{sep}{why}"


def write(tmp_path: Path, name: str, lines: list[str]) -> Path:
    path = tmp_path / name
    path.write_text("".join(ln + "\n" for ln in lines))
    return path


@pytest.fixture
def good(tmp_path: Path) -> dict[str, Path]:
    return {
        "ci": write(tmp_path, "ci.csv", ci_lines()),
        "plates": write(tmp_path, "plates.csv", plate_lines()),
        "shear": write(tmp_path, "shear.csv", shear_lines()),
    }


# (file name, lines, expected message without "file PATH, ")
CI_DEFECTS = [
    ("badcell", edit(ci_lines(), 6, "A,8,abc"), "profile A, row 6, column ci_kpa: not a number: 'abc'"),
    ("emptycell", edit(ci_lines(), 6, "A,8,"), "profile A, row 6, column ci_kpa: empty cell"),
    ("nan", edit(ci_lines(), 6, "A,8,nan"), "profile A, row 6, column ci_kpa: not a finite number: 'nan'"),
    (
        "negative",
        edit(ci_lines(), 6, "A,8,-5"),
        "profile A, row 6, column ci_kpa: negative cone index -5 (cell '-5')",
    ),
    (
        "order",
        edit(ci_lines(), 6, "A,2,300"),
        "profile A, row 6, column depth_cm: depth is not strictly increasing "
        "(cell '2'; previous depth '6' on line 5)",
    ),
    (
        "twopoints",
        ci_lines()[:3],
        "profile A, row 2, column ci_kpa: 2 points; at least 3 are needed "
        "(the profile is on lines 2-3)",
    ),
]  # fmt: skip

FILE_DEFECTS = [
    ("empty", [], "no header line (the file is empty or all comments)"),
    ("headeronly", [CI_HEAD], "row 1: no data rows"),
    ("extrafield", edit(ci_lines(), 6, "A,8,12,13"), "row 6: 4 fields but the header has 3"),
    (
        "badunit",
        ["profile,depth_xx,ci_kpa"] + ci_lines()[1:],
        "row 1, column depth_xx: unknown length unit 'xx' (use depth_<m|cm|mm|in>)",
    ),
]

PLATE_DEFECTS = [
    (
        "badcell",
        edit(plate_lines(), 8, "r3.75,3.75,26,xyz"),
        "test r3.75, row 8, column pressure_kpa: not a number: 'xyz'",
    ),
    (
        "emptycell",
        edit(plate_lines(), 15, "r5,5,14,"),
        "test r5, row 15, column pressure_kpa: empty cell",
    ),
    (
        "sizechange",
        edit(plate_lines(), 5, "r3.75,4,14,250"),
        "test r3.75, row 5, column plate_radius_cm: plate size changes within the test "
        "(4 here, 3.75 on line 2)",
    ),
    (
        "zerosize",
        [PLATE_HEAD] + [ln.replace(",3.75,", ",0,") for ln in plate_lines()[1:]],
        "test r3.75, row 2, column plate_radius_cm: plate size must be > 0",
    ),
    (
        "emptyid",
        edit(plate_lines(), 5, ",3.75,14,250"),
        "test , row 5, column test: empty test id",
    ),
    (
        "badunit",
        ["test,plate_radius_cm,sinkage_mm,pressure_bar"] + plate_lines()[1:],
        "row 1, column pressure_bar: unknown pressure unit 'bar' (use pressure_<kpa|mpa|psi|pa>)",
    ),
    (
        "nosize",
        ["test,sinkage_mm,pressure_kpa"]
        + [",".join(ln.split(",")[:1] + ln.split(",")[2:]) for ln in plate_lines()[1:]],
        "row 1, column plate_radius_<m|cm|mm|in> or plate_diameter_<m|cm|mm|in> or "
        "plate_width_<m|cm|mm|in>: missing required column plate_radius_<m|cm|mm|in> or "
        "plate_diameter_<m|cm|mm|in> or plate_width_<m|cm|mm|in>",
    ),
]

SHEAR_DEFECTS = [
    (
        "badcell",
        edit(shear_lines(), 9, "s10,10,35,??"),
        "test s10, row 9, column shear_stress_kpa: not a number: '??'",
    ),
    (
        "sigmachange",
        edit(shear_lines(), 30, "s20,25,35,5"),
        "test s20, row 30, column normal_pressure_kpa: normal pressure changes within the test "
        "(25 here, 20 on line 23)",
    ),
    (
        "badunit",
        [SHEAR_HEAD.replace("displacement_mm", "displacement_xx")] + shear_lines()[1:],
        "row 1, column shear_displacement_xx: unknown length unit 'xx' "
        "(use shear_displacement_<m|cm|mm|in>)",
    ),
    (
        "nostress",
        [SHEAR_HEAD.rsplit(",", 1)[0]] + [ln.rsplit(",", 1)[0] for ln in shear_lines()[1:]],
        "row 1, column shear_stress_<kpa|mpa|psi|pa>: missing required column "
        "shear_stress_<kpa|mpa|psi|pa>",
    ),
    (
        "toofew",
        [SHEAR_HEAD, "a,10,0,0", "a,10,5,1"] + shear_lines()[23:],
        "test a, row 2: 2 usable point(s) with j >= 0 up to the peak stress; at least 3 with "
        "distinct displacements and a positive peak are needed (the test is on lines 2-3)",
    ),
]


def ids(cases):
    return [c[0] for c in cases]


# ---------------------------------------------------------------------------
# predict
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name, lines, why", CI_DEFECTS, ids=ids(CI_DEFECTS))
def test_predict_profile_defect(tmp_path, name, lines, why):
    # the only profile is bad: it is listed with its reason and the exit is 1
    path = write(tmp_path, f"{name}.csv", lines)
    expected = located(path, why)
    r = run("predict", path)
    assert r.exit_code == 1 and "internal error" not in r.output
    assert r.output.rstrip().endswith(f"Profiles not fitted:\n  A: {expected}"), r.output
    r = run("predict", path, "--json")
    assert r.exit_code == 1
    (prof,) = json.loads(r.stdout)["profiles"]
    assert prof["status"] == "error" and prof["error"] == expected


def test_predict_a_bad_profile_among_good_ones(tmp_path):
    # profile B (file lines 18-33) breaks on line 20; A and C are fitted, exit 0
    lines = ci_lines()
    body = lines[1:]
    lines = [CI_HEAD] + body + [ln.replace("A,", "B,", 1) for ln in body]
    lines += [ln.replace("A,", "C,", 1) for ln in body]
    lines = edit(lines, 20, "B,4,n/a")
    path = write(tmp_path, "abc.csv", lines)
    r = run("predict", path, "--json")
    assert r.exit_code == 0, r.output
    by = {p["id"]: p for p in json.loads(r.stdout)["profiles"]}
    assert [by[k]["status"] for k in "ABC"] == ["ok", "error", "ok"]
    assert by["B"]["error"] == f"file {path}, profile B, row 20, column ci_kpa: not a number: 'n/a'"


@pytest.mark.parametrize("name, lines, why", FILE_DEFECTS, ids=ids(FILE_DEFECTS))
def test_predict_file_defect(tmp_path, name, lines, why):
    path = write(tmp_path, f"{name}.csv", lines)
    assert error_line(run("predict", path)) == located(path, why)


def test_predict_missing_file_and_calibration(tmp_path, good):
    missing = tmp_path / "nope.csv"
    assert error_line(run("predict", missing)) == f"file {missing}: file not found"
    cal = tmp_path / "cal.json"
    cal.write_text("{not json")
    assert error_line(run("predict", good["ci"], "--calibration", cal)) == (
        f"file {cal}: cannot read JSON "
        "(Expecting property name enclosed in double quotes: line 1 column 2 (char 1))"
    )
    none = tmp_path / "none.json"
    assert error_line(run("predict", good["ci"], "--calibration", none)) == (
        f"file {none}: file not found"
    )


def test_predict_option_values(good):
    r = run("predict", good["ci"], "--r-min", "abc")
    assert error_line(r, code=2) == (
        "Invalid value: --r-min: expected a length such as 0.05, 5cm or 2in, got 'abc'"
    )
    r = run("predict", good["ci"], "--plates", "5xx")
    assert error_line(r, code=2) == (
        "Invalid value: --plates: expected a length such as 0.05, 5cm or 2in, got '5xx'"
    )
    r = run("predict", good["ci"], "--model", "rm1")
    assert error_line(r, code=2) == "--model rm1 needs --r-min (or a --calibration / --terrain)"
    r = run("predict", good["ci"], "--depth-range", "30cm:10cm")
    assert (
        error_line(r, code=2)
        == "Invalid value: --depth-range: LO must be below HI, got '30cm:10cm'"
    )


# ---------------------------------------------------------------------------
# --bounds, in every command that takes it
# ---------------------------------------------------------------------------

BOUNDS_CASES = [
    ("kc=1", "bounds: expected NAME=LO:HI, got 'kc=1'"),
    ("kc=a:b", "bounds: 'kc=a:b' is not NAME=LO:HI with numbers"),
    ("foo=1:2", "bounds: unknown parameter 'foo' (use kc, kphi, n, cc, phic, Kc)"),
    ("kphi=9:3", "bounds of kphi: need LO <= HI (got 9.0:3.0)"),
    ("n=-1:2", "bounds of n must lie in (0, 3]"),
    ("phic=0:95", "bounds of phic must lie in [0, 90) deg"),
    ("cc=-1:5", "bounds of kc, kphi and cc must be >= 0"),
]


@pytest.mark.parametrize("text, expected", BOUNDS_CASES, ids=[c[0] for c in BOUNDS_CASES])
@pytest.mark.parametrize("command", ["predict", "learn", "batch"])
def test_bounds_parsing(tmp_path, good, command, text, expected):
    args = {
        "predict": ["predict", good["ci"]],
        "learn": ["learn", "--ci", good["ci"], "--plates", good["plates"]],
        "batch": ["batch", good["ci"], "--out", tmp_path / "out", "--quiet"],
    }[command]
    assert error_line(run(*args, "--bounds", text)) == expected
    assert not (tmp_path / "out").exists()  # batch refused before it started


# ---------------------------------------------------------------------------
# learn
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name, lines, why", CI_DEFECTS, ids=ids(CI_DEFECTS))
def test_learn_ci_defect(tmp_path, good, name, lines, why):
    # learning needs every profile: the first bad one stops it
    path = write(tmp_path, f"{name}.csv", lines)
    r = run("learn", "--ci", path, "--plates", good["plates"], "--model", "rm0")
    assert error_line(r) == located(path, why)


@pytest.mark.parametrize("name, lines, why", PLATE_DEFECTS, ids=ids(PLATE_DEFECTS))
def test_learn_plate_defect(tmp_path, good, name, lines, why):
    path = write(tmp_path, f"{name}.csv", lines)
    r = run("learn", "--ci", good["ci"], "--plates", path, "--model", "rm0")
    assert error_line(r) == located(path, why)


def test_learn_missing_files_and_window(tmp_path, good):
    missing = tmp_path / "none.csv"
    r = run("learn", "--ci", good["ci"], "--plates", missing)
    assert error_line(r) == f"file {missing}: file not found"
    r = run("learn", "--ci", missing, "--plates", good["plates"])
    assert error_line(r) == f"file {missing}: file not found"
    # a depth window that leaves one reading
    r = run("learn", "--ci", good["ci"], "--plates", good["plates"], "--depth-range", "25cm:26cm")
    assert error_line(r) == f"file {good['ci']}, profile A: 1 points; at least 3 are needed"


# ---------------------------------------------------------------------------
# evaluate
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name, lines, why", PLATE_DEFECTS, ids=ids(PLATE_DEFECTS))
def test_evaluate_plate_defect(tmp_path, name, lines, why):
    path = write(tmp_path, f"{name}.csv", lines)
    r = run("evaluate", "--plates", path, "--kc", "1", "--kphi", "2", "--n", "0.5")
    assert error_line(r) == located(path, why)


def test_evaluate_params_file_and_options(tmp_path, good):
    pl = good["plates"]
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    msg = error_line(run("evaluate", "--plates", pl, "--params", bad))
    assert msg == (
        f"file {bad}: cannot read JSON "
        "(Expecting property name enclosed in double quotes: line 1 column 2 (char 1))"
    )
    empty = tmp_path / "empty.json"
    empty.write_text('{"profiles": [{"id": "x", "status": "error"}]}')
    assert error_line(run("evaluate", "--plates", pl, "--params", empty)) == (
        f"file {empty}: no fitted parameters found (expected predict or learn JSON)"
    )
    partial = tmp_path / "partial.json"
    partial.write_text('{"profiles": [{"id": "P7", "status": "ok", "kc": 1.0}]}')
    assert error_line(run("evaluate", "--plates", pl, "--params", partial)) == (
        f"file {partial}, profile 1 (id 'P7'): key 'n': missing"
    )
    notnum = tmp_path / "site.json"
    notnum.write_text('{"kc": "x", "kphi": 3000, "n": 0.8}')
    assert error_line(run("evaluate", "--plates", pl, "--params", notnum)) == (
        f"file {notnum}, terrain site: could not convert string to float: 'x'"
    )
    r = run("evaluate", "--plates", pl, "--kc", "50")
    assert error_line(r, code=2) == "give --kc, --kphi and --n, or --params"
    r = run("evaluate", "--plates", pl, "--kc", "50", "--params", partial)
    assert error_line(r, code=2) == "give either --kc/--kphi/--n or --params, not both"


# ---------------------------------------------------------------------------
# fit-plates and fit-shear
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name, lines, why", PLATE_DEFECTS, ids=ids(PLATE_DEFECTS))
def test_fit_plates_defect(tmp_path, name, lines, why):
    path = write(tmp_path, f"{name}.csv", lines)
    assert error_line(run("fit-plates", path)) == located(path, why)


def test_fit_plates_without_usable_points(tmp_path):
    # test r3.75 has two points, both at negative sinkage (legal raw data, nothing to fit)
    lines = [PLATE_HEAD, "r3.75,3.75,-2,50", "r3.75,3.75,-1,60"] + plate_lines()[11:]
    path = write(tmp_path, "neg.csv", lines)
    assert error_line(run("fit-plates", path)) == (
        f"file {path}, test r3.75, row 2: 0 usable loading-branch point(s) with distinct "
        "sinkage > 0 and pressure > 0; at least 2 are needed (the test is on lines 2-3)"
    )


@pytest.mark.parametrize("name, lines, why", SHEAR_DEFECTS, ids=ids(SHEAR_DEFECTS))
def test_fit_shear_defect(tmp_path, name, lines, why):
    path = write(tmp_path, f"{name}.csv", lines)
    assert error_line(run("fit-shear", path)) == located(path, why)


def test_fit_commands_on_the_wrong_kind_of_file(good):
    assert error_line(run("fit-shear", good["plates"])) == (
        f"file {good['plates']}, row 1, column normal_pressure_<kpa|mpa|psi|pa>: "
        "missing required column normal_pressure_<kpa|mpa|psi|pa>"
    )
    assert error_line(run("fit-plates", good["shear"])).startswith(
        f"file {good['shear']}, row 1, column plate_radius_<m|cm|mm|in> or "
    )


# ---------------------------------------------------------------------------
# library, report
# ---------------------------------------------------------------------------


def test_library_json_errors(tmp_path, monkeypatch):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "lib.sqlite"))
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    why = "(Expecting property name enclosed in double quotes: line 1 column 2 (char 1))"
    assert error_line(run("library", "import", bad)) == f"file {bad}: cannot read JSON {why}"
    assert error_line(run("library", "add", "x", "--from-json", bad)) == (
        f"file {bad}: cannot read JSON {why}"
    )
    items = tmp_path / "items.json"
    items.write_text('[{"name": "x", "kind": "user", "params": {"kc": "abc"}}]')
    assert error_line(run("library", "import", items)) == (
        f'file {items}, item 0 (x), key params.kc: must be a number (got "abc")'
    )
    assert error_line(run("library", "show", "nothing-here")).startswith(
        "no terrain 'nothing-here'"
    )


def test_report_of_something_else(tmp_path, good):
    other = tmp_path / "other.json"
    other.write_text('{"hello": 1}')
    assert error_line(run("report", other, "--out", tmp_path / "r.html")) == (
        f"file {other}: not a terracone result: expected the JSON of predict, learn or evaluate "
        "(keys 'profiles', 'datasets' or 'plates')"
    )
    assert error_line(run("report", good["ci"], "--out", tmp_path / "r.html")) == (
        f"file {good['ci']}: cannot read JSON (Expecting value: line 1 column 1 (char 0))"
    )
    assert not (tmp_path / "r.html").exists()


def test_an_output_folder_that_does_not_exist_is_named(tmp_path):
    out = tmp_path / "nodir" / "x.json"
    r = run(
        "export", "--terrain", "Dry sand (Land Locomotion Lab)", "--format", "json", "--out", out
    )
    assert error_line(r) == (
        f"cannot use {out}: no such file or directory (folder {out.parent} does not exist)"
    )


# ---------------------------------------------------------------------------
# calibration and library files: every key checked on load (issue 23)
# ---------------------------------------------------------------------------

DROP = object()  # a key left out of the file

# a calibration file in the documented format (docs/learn.md), written by hand
CALIBRATION = {
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
    "provenance": {"method": "terracone learn (section 3.3.1)"},
}
CALIBRATION_KEYS = (
    "terracone_calibration, units, terrain, model, r_min, plate_pair, phic_deg, cc, kc, kphi, "
    "n, Kc, cone, provenance"
)
CONES = (
    "cone must be one of ['asabe-large', 'asabe-small', 'penetrologger-1cm2', "
    "'penetrologger-2cm2', 'penetrologger-3.33cm2', 'penetrologger-5cm2'], "
    "'DIAMETER<m|cm|mm|in>:ANGLE' (e.g. 20.27mm:30) or 'AREA<cm2|mm2|in2>:ANGLE' "
    "(e.g. 5cm2:60) (got 'big')"
)

# (defect, changed keys, expected message after "file PATH, ")
CALIBRATION_DEFECTS = [
    ("no terrain", {"terrain": DROP}, "key terrain: missing (the terrain or site label)"),
    ("empty terrain", {"terrain": "  "}, 'key terrain: must be non-empty text (got "  ")'),
    ("no kphi", {"kphi": DROP}, "key kphi: missing (Bekker frictional modulus)"),
    ("NaN", {"phic_deg": math.nan}, "key phic_deg: must be a finite number (got NaN)"),
    ("Infinity", {"kc": math.inf}, "key kc: must be a finite number (got Infinity)"),
    ("text for a number", {"kphi": "5359"}, 'key kphi: must be a number (got "5359")'),
    ("true for a number", {"n": True}, "key n: must be a number (got true)"),
    ("null for a required key", {"cc": None}, "key cc: missing (cone-terrain adhesion)"),
    ("n = 0", {"n": 0}, "key n: must be in (0, 5] (got 0)"),
    ("phic = 90", {"phic_deg": 90}, "key phic_deg: must be in [0, 90) deg (got 90)"),
    ("negative cc", {"cc": -1.5}, "key cc: must be in [0, 100000] kPa (got -1.5)"),
    ("r_min = 0", {"r_min": 0.0}, "key r_min: must be in (0, 100] m (got 0)"),
    ("n = 1e300", {"n": 1e300}, "key n: must be in (0, 5] (got 1e+300)"),
    ("kc = 1e300", {"kc": 1e300}, "key kc: must be in [-1e+09, 1e+09] kN/m^(n+1) (got 1e+300)"),
    ("cc = 1e300", {"cc": 1e300}, "key cc: must be in [0, 100000] kPa (got 1e+300)"),
    ("r_min = 1e300", {"r_min": 1e300}, "key r_min: must be in (0, 100] m (got 1e+300)"),
    ("negative Kc", {"Kc": -0.01}, "key Kc: must be in (0, 100] m (got -0.01)"),
    ("rm1 without r_min", {"r_min": DROP}, 'key r_min: missing (model "rm1" needs r_min)'),
    (
        "model",
        {"model": "RM1"},
        'key model: must be "rm0" or "rm1" (pressure law) (got "RM1")',
    ),
    (
        "one plate",
        {"plate_pair": [0.05]},
        "key plate_pair: must be two different plate radii > 0 m (got [0.05])",
    ),
    (
        "equal plates",
        {"plate_pair": [0.05, 0.05]},
        "key plate_pair: must be two different plate radii > 0 m (got [0.05, 0.05])",
    ),
    ("cone", {"cone": "big"}, f"key cone: {CONES}"),
    (
        "US units",
        {"units": "us"},
        'key units: must be "si" (calibration files are stored in SI) (got "us")',
    ),
    (
        "a newer format",
        {"terracone_calibration": 2},
        "key terracone_calibration: must be 1 (the calibration format this terracone reads) "
        "(got 2)",
    ),
    (
        "not a calibration",
        {"terracone_calibration": DROP},
        "key terracone_calibration: missing: not a terracone calibration file "
        "(`terracone learn --save` writes them)",
    ),
    ("a misspelt key", {"phic": 11.9}, f"key phic: unknown key 'phic'; known: {CALIBRATION_KEYS}"),
    (
        "provenance",
        {"provenance": "learn"},
        'key provenance: must be a JSON object (got "learn")',
    ),
]


def changed(doc: dict, changes: dict) -> dict:
    out = dict(doc)
    for key, value in changes.items():
        if value is DROP:
            del out[key]
        else:
            out[key] = value
    return out


def test_the_calibration_of_the_defect_tests_is_good(tmp_path, good):
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps(CALIBRATION))
    r = run("predict", good["ci"], "--calibration", cal, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["settings"]["calibration"] == "LETE sand"


@pytest.mark.parametrize(
    "changes, why", [c[1:] for c in CALIBRATION_DEFECTS], ids=[c[0] for c in CALIBRATION_DEFECTS]
)
def test_calibration_file_defect(tmp_path, good, changes, why):
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps(changed(CALIBRATION, changes)))  # NaN, Infinity as JSON spells them
    assert error_line(run("predict", good["ci"], "--calibration", cal)) == f"file {cal}, {why}"


def test_calibration_file_that_is_not_an_object(tmp_path, good):
    cal = tmp_path / "cal.json"
    cal.write_text("[1, 2]")
    assert error_line(run("predict", good["ci"], "--calibration", cal)) == (
        f"file {cal}: expected a JSON object (got [1, 2])"
    )


RECORD = {"name": "a", "kind": "user", "params": {"kc": 5.0, "kphi": 800.0, "n": 0.7}}
RECORD_KEYS = "name, kind, params, provenance, notes, created, modified, builtin"
PARAMETERS = (
    "kc, kphi, n, k, b_m, c_kpa, phi_deg, K_m, cc, phic_deg, Kc, model, r_min, plate_pair, "
    "cone, moisture_pct, density_kg_m3"
)

# (defect, second record of the file, expected message after "file PATH, ")
LIBRARY_DEFECTS = [
    ("not an object", 3, "item 1: expected a JSON object (got 3)"),
    ("no name", {"kind": "user"}, "item 1, key name: missing (the terrain's unique name)"),
    (
        "name not text",
        {"name": 3, "kind": "user"},
        "item 1, key name: must be non-empty text (got 3)",
    ),
    (
        "no kind",
        {"name": "b"},
        "item 1 (b), key kind: missing (e.g. calibration or bevameter-fit)",
    ),
    (
        "a misspelt record key",
        {"name": "b", "kind": "user", "parms": {}},
        f"item 1 (b), key parms: unknown key 'parms'; known: {RECORD_KEYS}",
    ),
    (
        "params not an object",
        {"name": "b", "kind": "user", "params": [1.0]},
        "item 1 (b), key params: must be a JSON object (got [1.0])",
    ),
    (
        "NaN",
        {"name": "b", "kind": "user", "params": {"phic_deg": math.nan}},
        "item 1 (b), key params.phic_deg: must be a finite number (got NaN)",
    ),
    (
        "text for a number",
        {"name": "b", "kind": "user", "params": {"n": "0.7"}},
        'item 1 (b), key params.n: must be a number (got "0.7")',
    ),
    (
        "n < 0",
        {"name": "b", "kind": "user", "params": {"n": -0.5}},
        "item 1 (b), key params.n: must be in (0, 5] (got -0.5)",
    ),
    (
        "phi = 95",
        {"name": "b", "kind": "user", "params": {"phi_deg": 95}},
        "item 1 (b), key params.phi_deg: must be in [0, 90) deg (got 95)",
    ),
    (
        "negative cohesion",
        {"name": "b", "kind": "user", "params": {"c_kpa": -2}},
        "item 1 (b), key params.c_kpa: must be in [0, 100000] kPa (got -2)",
    ),
    (
        "zero density",
        {"name": "b", "kind": "user", "params": {"density_kg_m3": 0}},
        "item 1 (b), key params.density_kg_m3: must be > 0 kg/m^3 (got 0)",
    ),
    (
        "rm1 without r_min",
        {"name": "b", "kind": "calibration", "params": {"model": "rm1"}},
        'item 1 (b), key params.r_min: missing (model "rm1" needs r_min)',
    ),
    (
        "an ambiguous parameter",
        {"name": "b", "kind": "user", "params": {"c": 1.0}},
        "item 1 (b), key params.c: ambiguous parameter 'c': use 'c_kpa' (terrain internal "
        "cohesion) or 'cc' (cone-metal adhesion)",
    ),
    (
        "an unknown parameter",
        {"name": "b", "kind": "user", "params": {"kphii": 1.0}},
        f"item 1 (b), key params.kphii: unknown parameter 'kphii'; known: {PARAMETERS}",
    ),
    (
        "notes not text",
        {"name": "b", "kind": "user", "notes": 5},
        "item 1 (b), key notes: must be text (got 5)",
    ),
    (
        "builtin not a flag",
        {"name": "b", "kind": "user", "builtin": "no"},
        'item 1 (b), key builtin: must be true or false (got "no")',
    ),
]


@pytest.mark.parametrize(
    "second, why", [c[1:] for c in LIBRARY_DEFECTS], ids=[c[0] for c in LIBRARY_DEFECTS]
)
def test_library_file_defect(tmp_path, second, why):
    lib = tmp_path / "lib.sqlite"
    path = tmp_path / "terrains.json"
    path.write_text(json.dumps([RECORD, second]))
    assert error_line(run("library", "--library", lib, "import", path)) == f"file {path}, {why}"
    r = run("library", "--library", lib, "list", "--json")  # nothing was imported
    assert r.exit_code == 0 and [d for d in json.loads(r.output) if not d["builtin"]] == []
    path.write_text(json.dumps([RECORD]))  # the good record alone imports
    assert run("library", "--library", lib, "import", path).output == "imported 1, skipped 0\n"


def test_library_file_that_is_not_a_list_and_repeated_names(tmp_path):
    lib = tmp_path / "lib.sqlite"
    path = tmp_path / "terrains.json"
    path.write_text('"terrains"')
    assert error_line(run("library", "--library", lib, "import", path)) == (
        f"file {path}: expected a JSON list of terrain records"
    )
    path.write_text(json.dumps([RECORD, RECORD]))
    assert error_line(run("library", "--library", lib, "import", path)) == (
        f"file {path}: repeated names ['a']"
    )


def test_library_add_from_json_names_the_file_and_key(tmp_path):
    lib = tmp_path / "lib.sqlite"
    path = tmp_path / "params.json"
    path.write_text('{"kc": 5.0, "phic_deg": NaN}')
    assert error_line(run("library", "--library", lib, "add", "x", "--from-json", path)) == (
        f"file {path}, key phic_deg: must be a finite number (got NaN)"
    )

"""The command line (terracone.cli) through click's CliRunner.

Values are checked against hand computations: closed forms of the cone
index for n = 1, Bekker's plate equation, the exact unit factors
(1 in = 0.0254 m, 1 lbf = 4.4482216152605 N) and Pearson's R from the
standard library.  Input files are generated here with known truth.
"""

from __future__ import annotations

import json
import math
import re
import statistics
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import require_shared

from terracone import __version__
from terracone.cli import cli
from terracone.physics.cone import CONES, cone_index

INCH = 0.0254  # m, exact
LBF = 4.4482216152605  # N, exact
PSI = LBF / INCH**2 / 1000.0  # kPa
R_L = math.sqrt(0.5 * INCH**2 / math.pi)  # asabe-large: 0.5 in^2 base
H_L = R_L / math.tan(math.radians(15.0))  # 30 deg cone: H = R / tan 15


def run(*args: str, env: dict | None = None):
    return CliRunner().invoke(cli, list(args), env=env)


def ok_json(*args: str):
    r = run(*args)
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


def error_line(r, code: int = 1) -> str:
    """The one 'Error: ...' line of a failed run (exit ``code``), without 'Error: '.

    An internal crash ("Error: internal error (...)") never matches an expected
    message, and is refused here outright."""
    assert r.exit_code == code, r.output
    assert "internal error" not in r.output and "Traceback" not in r.output, r.output
    errors = [ln for ln in r.output.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1, r.output
    return errors[0][len("Error: ") :]


def _write(path: Path, header: str, rows) -> Path:
    lines = [header] + [
        ",".join(c if isinstance(c, str) else repr(float(c)) for c in r) for r in rows
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------------------
# version and help
# ---------------------------------------------------------------------------


def test_version():
    r = run("--version")
    assert r.exit_code == 0
    assert __version__ in r.output and "terracone" in r.output


def _commands():
    out = [[]]
    for name, cmd in cli.commands.items():
        out.append([name])
        for sub in getattr(cmd, "commands", {}):
            out.append([name, sub])
    return out


@pytest.mark.parametrize("path", _commands(), ids=lambda p: " ".join(p) or "terracone")
def test_help_of_every_command(path):
    r = run(*path, "--help")
    assert r.exit_code == 0, r.output
    assert "Usage:" in r.output
    assert "Traceback" not in r.output


def test_the_documented_commands_exist():
    names = set(cli.commands)
    expected = {"ci", "plate", "predict", "learn", "evaluate", "demo", "fit-plates"}
    assert expected | {"fit-shear", "library", "export"} <= names


# ---------------------------------------------------------------------------
# forward models
# ---------------------------------------------------------------------------


def test_ci_json_against_the_closed_form_n1():
    # n = 1, RM0, fully mobilised shear, z >= 0 (eqs. (2-5) to (2-7)), with
    # h from the base down to the tip, r = R (1 - h/H):
    #   normal: (2 tan15 / R^2) int_0^H (kc + r kphi)(z + h) dh
    #         = 2 kc (z + H/2) / R + kphi (z + H/3)
    #   friction: tan(phic)/tan15 times the normal part; adhesion: cc H / R
    kc, kphi, cc, phic = 20.0, 3000.0, 5.0, 10.0
    z = [0.0, 0.05, 0.1, 0.3]
    d = ok_json(
        "ci", "--kc", "20", "--kphi", "3000", "--n", "1", "--cc", "5", "--phic", "10",
        "--depths", "0,0.05,0.1,0.3", "--json",
    )  # fmt: skip
    assert set(d) == {"depth", "ci", "units"}
    assert d["units"] == "si" and d["depth"] == z
    s = 1.0 + math.tan(math.radians(phic)) / math.tan(math.radians(15.0))
    hand = [
        s * (2 * kc * (zi + H_L / 2) / R_L + kphi * (zi + H_L / 3)) + cc * H_L / R_L for zi in z
    ]
    assert d["ci"] == pytest.approx(hand, rel=1e-10)


def test_ci_json_us_units_closed_form():
    # in consistent US units the same closed form holds: kphi [lb/in^3] * in = psi
    kphi_us = 10.0
    h_in = H_L / INCH
    d = ok_json(
        "ci", "--kc", "0", "--kphi", "10", "--n", "1", "--units", "us",
        "--depths", "0,1,2.5", "--json",
    )  # fmt: skip
    assert d["units"] == "us"
    assert d["ci"] == pytest.approx([kphi_us * (z + h_in / 3) for z in (0, 1, 2.5)], rel=1e-10)


def test_ci_partial_penetration_and_errors():
    # tip entering: base depth z in (-H, 0); n = 1, kc = 0: the cone's embedded part is
    # a cone of height u1 = z + H: CI = (2/H^2) kphi int_0^u1 u (u1 - u) du = kphi u1^3/(3 H^2)
    z = -0.5 * H_L
    d = ok_json("ci", "--kc", "0", "--kphi", "3000", "--n", "1", "--depths", repr(z), "--json")
    u1 = z + H_L
    assert d["ci"][0] == pytest.approx(3000 * u1**3 / (3 * H_L**2), rel=1e-10)
    msg = error_line(run("ci", "--kc", "0", "--kphi", "3000", "--n", "1", "--depths", "-0.5"))
    m = re.fullmatch(
        r"depth must be >= -H = (\S+) m \(the tip above the surface carries no load\)", msg
    )
    assert m and float(m.group(1)) == pytest.approx(-H_L, rel=1e-5), msg
    r = run("ci", "--kc", "0", "--kphi", "3000", "--n", "1", "--depths", "a,b")
    assert error_line(r, code=2) == (
        "Invalid value: --depths: expected comma-separated numbers, got 'a,b'"
    )


def test_plate_json_against_bekker_by_hand():
    d = ok_json(
        "plate", "--kc", "100", "--kphi", "5000", "--n", "0.8", "--radius", "0.05",
        "--sinkages", "0.01,0.02,0.05", "--json",
    )  # fmt: skip
    assert set(d) == {"sinkage", "pressure", "units"}
    assert d["sinkage"] == [0.01, 0.02, 0.05] and d["units"] == "si"
    hand = [(100 / 0.05 + 5000) * s**0.8 for s in (0.01, 0.02, 0.05)]
    assert d["pressure"] == pytest.approx(hand, rel=1e-12)
    # a rectangular plate: b = its smaller side; and US units in the same formula
    d = ok_json(
        "plate", "--kc", "2", "--kphi", "3", "--n", "0.5", "--width", "4", "--units", "us",
        "--sinkages", "1,4", "--json",
    )  # fmt: skip
    assert d["units"] == "us"
    assert d["pressure"] == pytest.approx([(2 / 4 + 3) * 1.0, (2 / 4 + 3) * 2.0], rel=1e-12)
    r = run("plate", "--kc", "1", "--kphi", "1", "--n", "1", "--sinkages", "0.01")
    assert error_line(r, code=2) == "give exactly one of --radius and --width"


# ---------------------------------------------------------------------------
# predict
# ---------------------------------------------------------------------------

CONTRACT = {
    "id", "status", "error", "kc", "kphi", "n", "cc", "phic_deg", "rmsd", "model",
    "r_min", "units", "undetermined", "r2_ci", "lack_of_fit",
}  # fmt: skip

TRUTH = dict(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
Z_CM = np.arange(0.0, 31.0, 2.0)  # 16 depths


def _profile_rows(pid: str, seed: int):
    rng = np.random.default_rng(seed)
    ci = cone_index(Z_CM * 0.01, cone=CONES["asabe-large"], **TRUTH)
    ci = ci * (1.0 + 0.01 * rng.standard_normal(ci.size))
    return [(pid, float(z), float(c)) for z, c in zip(Z_CM, ci)]


@pytest.fixture
def three_profiles(tmp_path: Path) -> Path:
    """Profiles A and C are good; B has a non-number on file line 23."""
    rows = _profile_rows("A", 1) + _profile_rows("B", 2) + _profile_rows("C", 3)
    lines = [
        "# generated: kc=30, kphi=4000, n=0.8, cc=2, phic=20; 1 % noise",
        "profile,depth_cm,ci_kpa",
    ]
    lines += [f"{p},{z!r},{c!r}" for p, z, c in rows]
    # B's rows are records 17-32, file lines 19-34 (line 1 comment, line 2 header);
    # break its 5th reading (depth 8 cm) on file line 23
    assert lines[22].startswith("B,8.0,")
    lines[22] = "B,8.0,n/a"
    path = tmp_path / "three.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_predict_json_contract_and_a_bad_profile(three_profiles):
    r = run("predict", str(three_profiles), "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["command"] == "predict" and doc["terracone"] == __version__
    assert doc["input"] == str(three_profiles)
    profs = {p["id"]: p for p in doc["profiles"]}
    assert list(profs) == ["A", "B", "C"]
    for p in profs.values():
        assert CONTRACT <= set(p), CONTRACT - set(p)
    for pid in ("A", "C"):
        p = profs[pid]
        assert p["status"] == "ok" and p["error"] is None
        assert p["n"] == pytest.approx(0.8, abs=0.1)
        assert p["units"] == "si" and p["model"] == "rm0" and p["r_min"] is None
        assert p["rmsd"] > 0 and 0.9 < p["r2_ci"] <= 1.0
        assert "phic" in p["undetermined"]
        assert len(p["depth"]) == len(p["ci"]) == len(p["ci_model"]) == 16
    b = profs["B"]
    assert b["status"] == "error"
    assert b["n"] is None and b["rmsd"] is None
    err = b["error"]
    assert str(three_profiles) in err
    assert "profile B" in err and "row 23" in err and "column ci_kpa" in err
    assert "n/a" in err


def test_predict_table_names_the_bad_profile(three_profiles):
    r = run("predict", str(three_profiles))
    assert r.exit_code == 0
    assert "Profiles not fitted" in r.output
    assert "B: file" in r.output and "row 23" in r.output


def test_predict_missing_file_is_one_message(tmp_path: Path):
    missing = tmp_path / "nope.csv"
    r = run("predict", str(missing))
    assert error_line(r) == f"file {missing}: file not found"
    assert len([ln for ln in r.output.splitlines() if ln.strip()]) == 1, r.output


@pytest.mark.parametrize(
    "header, expected",
    [
        ("depth_xx,ci_kpa", "column depth_xx: unknown length unit 'xx' (use depth_<m|cm|mm|in>)"),
        (
            "depth_cm,ci_bar",
            "column ci_bar: unknown pressure unit 'bar' (use ci_<kpa|mpa|psi|pa>)",
        ),
        (
            "depth_cm,pressure_kpa",
            "column ci_<kpa|mpa|psi|pa>: missing required column ci_<kpa|mpa|psi|pa>",
        ),
    ],
)
def test_predict_bad_column_is_one_message(tmp_path: Path, header, expected):
    path = tmp_path / "badcol.csv"
    path.write_text(header + "\n0,100\n2,200\n4,300\n")
    r = run("predict", str(path), "--json")
    assert error_line(r) == f"file {path}, row 1, {expected}"
    assert len([ln for ln in r.output.splitlines() if ln.strip()]) == 1, r.output


def test_predict_every_profile_bad_exits_non_zero(tmp_path: Path):
    path = _write(tmp_path / "neg.csv", "depth_cm,ci_kpa", [(0, -1), (1, 2), (2, 3)])
    r = run("predict", str(path))
    assert r.exit_code == 1 and "internal error" not in r.output
    assert r.output.rstrip().endswith(
        f"Profiles not fitted:\n  neg: file {path}, profile neg, row 2, column ci_kpa: "
        "negative cone index -1 (cell '-1.0')"
    ), r.output


def test_predict_us_units_by_hand(tmp_path: Path):
    path = tmp_path / "one.csv"
    path.write_text(
        "profile,depth_cm,ci_kpa\n"
        + "".join(f"{p},{z!r},{c!r}\n" for p, z, c in _profile_rows("A", 4))
    )
    si = ok_json("predict", str(path), "--json")["profiles"][0]
    us = ok_json("predict", str(path), "--json", "--units", "us")["profiles"][0]
    assert us["units"] == "us"
    n = si["n"]
    assert us["n"] == pytest.approx(n, rel=1e-12)
    # kc [kN/m^(n+1)] = kc [lb/in^(n+1)] * (LBF/1000) / INCH^(n+1); kphi likewise with n+2
    assert us["kc"] == pytest.approx(si["kc"] / (LBF / 1000 / INCH ** (n + 1)), rel=1e-9)
    assert us["kphi"] == pytest.approx(si["kphi"] / (LBF / 1000 / INCH ** (n + 2)), rel=1e-9)
    assert us["cc"] == pytest.approx(si["cc"] / PSI, rel=1e-9, abs=1e-12)
    assert us["rmsd"] == pytest.approx(si["rmsd"] / PSI, rel=1e-9)
    assert us["phic_deg"] == pytest.approx(si["phic_deg"], rel=1e-12)
    np.testing.assert_allclose(us["depth"], Z_CM / 2.54, rtol=1e-12)
    np.testing.assert_allclose(np.array(us["ci"]) * PSI, si["ci"], rtol=1e-12)


def test_predict_layers_option(tmp_path: Path):
    # a strong top over a weak subsoil (interface 10 cm): --layers 2 prefers two layers
    from terracone.data import TerrainParameters
    from terracone.physics.layers import layered_cone_index

    z = np.arange(0.0, 0.305, 0.02)
    top = TerrainParameters(kc=50.0, kphi=8000.0, n=0.5, cc=2.0, phic_deg=20.0)
    bot = TerrainParameters(kc=10.0, kphi=1500.0, n=1.0, cc=2.0, phic_deg=20.0)
    ci = layered_cone_index(z, [top, bot], [0.10], cone=CONES["asabe-large"])
    path = _write(tmp_path / "pan.csv", "depth_m,ci_kpa", zip(z, ci))
    p = ok_json("predict", str(path), "--layers", "2", "--json")["profiles"][0]
    assert p["status"] == "ok"
    assert p["lack_of_fit"] is not None  # the homogeneous fit cannot fall with depth
    lay = p["layered"]
    assert lay["status"] == "ok" and lay["preferred_layers"] == 2
    assert lay["interfaces"][0] == pytest.approx(0.10, abs=0.02)
    assert [q["n"] for q in lay["layers"]] == pytest.approx([0.5, 1.0], abs=0.05)
    assert lay["bic"] < lay["bic_single"]
    r = run("predict", str(path), "--layers", "2")
    assert r.exit_code == 0 and "Layered fits" in r.output


# ---------------------------------------------------------------------------
# SC900 exports
# ---------------------------------------------------------------------------


def _sc900_pushes(path: Path):
    """(push number, readings) of each push line, parsed by hand."""
    out = []
    for line in path.read_text().splitlines():
        f = [c.strip() for c in line.split(",")]
        if len(f) > 3 and f[2].replace(" ", "").startswith("N="):
            out.append((int(f[2].replace(" ", "")[2:]), [float(v) for v in f[3:-1]], f[-1]))
    return out


def test_sc900_sample_through_predict():
    path = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    pushes = _sc900_pushes(path)
    assert len(pushes) > 10
    doc = ok_json("predict", str(path), "--format", "sc900", "--json")
    profs = doc["profiles"]
    assert len(profs) == len(pushes)
    labels_cm = np.arange(19) * 2.5  # 0.0 cm, 2.5 cm, ..., 45.0 cm
    for k, (p, (number, readings, size)) in enumerate(zip(profs, pushes), 1):
        assert p["id"] == f"{path.stem}/{k:04d}-N{number}"
        assert size == "1/2 Inch" and p["cone"] == "asabe-small"
        trailing = len(readings) - (max(i for i, v in enumerate(readings) if v != 0) + 1)
        assert p["metadata"]["trailing_zeros_dropped"] == trailing
        if trailing:
            s = "" if trailing == 1 else "s"
            assert any(f"dropped {trailing} trailing zero reading{s}" in n for n in p["notes"])
        if p["status"] == "ok":
            np.testing.assert_allclose(p["depth"], labels_cm[: 19 - trailing] / 100, atol=1e-15)
            np.testing.assert_allclose(p["ci"], readings[: 19 - trailing], rtol=1e-12)
    assert sum(p["status"] == "ok" for p in profs) > 0.5 * len(profs)


def test_sc900_autodetected(tmp_path: Path):
    src = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    # the header and the first six pushes, under the same name (ids carry the stem)
    lines = src.read_text().splitlines()
    push_lines = [i for i, ln in enumerate(lines) if re.search(r",\s*N\s*=", ln)]
    part = tmp_path / src.name
    part.write_text("\n".join(lines[: push_lines[5] + 1]) + "\n")
    auto = ok_json("predict", str(part), "--json")["profiles"]
    given = ok_json("predict", str(part), "--format", "sc900", "--json")["profiles"]
    assert len(auto) == 6
    assert [p["id"] for p in auto] == [p["id"] for p in given]
    assert [p["n"] for p in auto] == [p["n"] for p in given]
    assert auto[0]["id"].startswith(f"{src.stem}/0001-N")
    # read as CSV instead, the export is refused with one message
    # (its first line, "Name: ...", is taken as a one-column header)
    r = run("predict", str(part), "--format", "csv")
    assert error_line(r) == f"file {part}, row 5: 23 fields but the header has 1"


def test_sc900_lat_lon_and_cones():
    path = Path(__file__).parent / "data" / "sc900_psi_inch.txt"
    doc = ok_json("predict", str(path), "--json")
    by = {p["id"]: p for p in doc["profiles"]}
    first = by["sc900_psi_inch/0001-N1"]
    assert first["metadata"]["longitude"] == -93.5 and first["metadata"]["latitude"] == 42.25
    assert first["cone"] == "asabe-large"  # 3/4 Inch
    assert first["ci"] == pytest.approx([v * PSI for v in (10, 20, 30, 40, 50)], rel=1e-12)
    # "1 Inch" is not a known cone size: that push is an error naming its column
    bad = [p for p in doc["profiles"] if p["status"] == "error"]
    assert any("Cone Size" in p["error"] for p in bad)


# ---------------------------------------------------------------------------
# evaluate, learn, bevameter fits
# ---------------------------------------------------------------------------

SINK_MM = np.arange(2.0, 42.0, 4.0)


def _plates(path: Path, kc=100.0, kphi=5000.0, n=0.8, noise=0.0, seed=0) -> Path:
    rng = np.random.default_rng(seed)
    rows = []
    for r_cm in (3.75, 5.0):
        p = (kc / (r_cm / 100) + kphi) * (SINK_MM / 1000) ** n
        p = p * (1.0 + noise * rng.standard_normal(p.size))
        rows += [(f"r{r_cm:g}", r_cm, s, v) for s, v in zip(SINK_MM, p)]
    return _write(path, "test,plate_radius_cm,sinkage_mm,pressure_kpa", rows)


def test_evaluate_against_a_hand_computation(tmp_path: Path):
    path = _plates(tmp_path / "plates.csv")
    d = ok_json(
        "evaluate", "--kc", "50", "--kphi", "4000", "--n", "0.9", "--plates", str(path), "--json"
    )
    rows = d["plates"]
    assert [r["test"] for r in rows] == ["r3.75", "r5"]
    for row, r_cm in zip(rows, (3.75, 5.0)):
        b = r_cm / 100
        s = SINK_MM / 1000
        meas = list((100 / b + 5000) * s**0.8)
        pred = list((50 / b + 4000) * s**0.9)
        R = statistics.correlation(meas, pred)
        rmsd = math.sqrt(statistics.fmean((p - m) ** 2 for p, m in zip(pred, meas)))
        assert row["plate_radius"] == pytest.approx(b)
        assert row["R"] == pytest.approx(R, rel=1e-9)
        assert row["R2"] == pytest.approx(R * R, rel=1e-9)
        assert row["RMSD"] == pytest.approx(rmsd, rel=1e-9)
        assert row["CV"] == pytest.approx(rmsd / statistics.fmean(meas), rel=1e-9)
        assert row["n_points"] == len(SINK_MM)
    r = run("evaluate", "--kc", "50", "--plates", str(path))
    assert error_line(r, code=2) == "give --kc, --kphi and --n, or --params"


def test_learn_save_then_predict_calibration(tmp_path: Path):
    rng = np.random.default_rng(5)
    z = np.arange(0.0, 31.0, 2.0)
    truth = dict(kc=100.0, kphi=5000.0, n=0.8, cc=1.0, phic_deg=12.0)
    ci = cone_index(z * 0.01, **truth) * (1.0 + 0.02 * rng.standard_normal(z.size))
    ci_path = _write(tmp_path / "site.csv", "depth_cm,ci_kpa", zip(z, ci))
    pl_path = _plates(tmp_path / "plates.csv", noise=0.02, seed=6)
    cal_path = tmp_path / "cal.json"
    d = ok_json(
        "learn", "--ci", str(ci_path), "--plates", str(pl_path), "--model", "rm0",
        "--save", str(cal_path), "--json",
    )  # fmt: skip
    assert d["saved"] == str(cal_path) and d["terrain"] == "site"
    assert d["kc"] == pytest.approx(100.0, rel=0.15)
    assert d["kphi"] == pytest.approx(5000.0, rel=0.1)
    assert d["n"] == pytest.approx(0.8, abs=0.05)
    cal = json.loads(cal_path.read_text())
    assert cal["model"] == "rm0" and cal["terrain"] == "site"
    for k in ("kc", "kphi", "n", "cc", "phic_deg"):
        assert cal[k] == pytest.approx(d[k], rel=1e-12, abs=1e-12)
    # predict a second profile of the same terrain with the calibration
    z2 = np.arange(1.0, 30.0, 2.0)
    ci2 = cone_index(z2 * 0.01, **truth) * (1.0 + 0.02 * rng.standard_normal(z2.size))
    ci2_path = _write(tmp_path / "other.csv", "depth_cm,ci_kpa", zip(z2, ci2))
    doc = ok_json("predict", str(ci2_path), "--calibration", str(cal_path), "--json")
    assert doc["settings"]["calibration"] == "site"
    p = doc["profiles"][0]
    assert p["status"] == "ok"
    assert p["phic_deg"] == pytest.approx(cal["phic_deg"], abs=1e-9)
    assert p["cc"] == pytest.approx(cal["cc"], abs=1e-9)
    assert p["kc"] / p["kphi"] == pytest.approx(cal["kc"] / cal["kphi"], rel=1e-6)
    assert p["n"] == pytest.approx(0.8, abs=0.05)
    assert any("calibration 'site'" in note for note in p["notes"])
    # a missing calibration file is one message
    none = tmp_path / "none.json"
    msg = error_line(run("predict", str(ci2_path), "--calibration", str(none)))
    assert msg == f"file {none}: file not found"


def test_fit_plates_json(tmp_path: Path):
    path = _plates(tmp_path / "plates.csv")
    d = ok_json("fit-plates", str(path), "--json")
    assert {"kc", "kphi", "n", "tests"} <= set(d)
    assert d["kc"] == pytest.approx(100.0, rel=1e-6)
    assert d["kphi"] == pytest.approx(5000.0, rel=1e-6)
    assert d["n"] == pytest.approx(0.8, rel=1e-6)
    assert [t["test"] for t in d["tests"]] == ["r3.75", "r5"]
    for t, r_cm in zip(d["tests"], (3.75, 5.0)):
        assert {"test", "plate_radius", "k", "n", "points_used"} <= set(t)
        assert t["plate_radius"] == pytest.approx(r_cm / 100)
        assert t["k"] == pytest.approx(100 / (r_cm / 100) + 5000, rel=1e-6)  # k = kc/b + kphi
        assert t["n"] == pytest.approx(0.8, rel=1e-6)
        assert t["points_used"] == len(SINK_MM)


def test_fit_shear_json(tmp_path: Path):
    # tau = (c + sigma tan phi)(1 - exp(-j/K)), c = 2 kPa, phi = 30 deg, K = 2 cm
    rows = []
    for sig in (10.0, 20.0, 40.0):
        for j_mm in np.arange(0.0, 101.0, 5.0):
            tau = (2.0 + sig * math.tan(math.radians(30))) * (1 - math.exp(-j_mm / 20.0))
            rows.append((f"s{sig:g}", sig, j_mm, tau))
    path = _write(
        tmp_path / "shear.csv",
        "test,normal_pressure_kpa,shear_displacement_mm,shear_stress_kpa",
        rows,
    )
    d = ok_json("fit-shear", str(path), "--json")
    assert {"c", "phi_deg", "K", "tests"} <= set(d)
    assert d["c"] == pytest.approx(2.0, rel=1e-6)
    assert d["phi_deg"] == pytest.approx(30.0, rel=1e-6)
    assert d["K"] == pytest.approx(0.02, rel=1e-6)
    for t, sig in zip(d["tests"], (10.0, 20.0, 40.0)):
        assert {"test", "normal_pressure", "tau_max", "K"} <= set(t)
        assert t["normal_pressure"] == sig
        assert t["tau_max"] == pytest.approx(2.0 + sig * math.tan(math.radians(30)), rel=1e-6)
        assert t["K"] == pytest.approx(0.02, rel=1e-6)
    # US units: c in psi, K in inches
    u = ok_json("fit-shear", str(path), "--json", "--units", "us")
    assert u["c"] == pytest.approx(2.0 / PSI, rel=1e-6)
    assert u["K"] == pytest.approx(0.02 / INCH, rel=1e-6)


# ---------------------------------------------------------------------------
# library and export
# ---------------------------------------------------------------------------


def test_library_and_chrono_export(tmp_path: Path, monkeypatch):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "lib.sqlite"))
    listed = ok_json("library", "list", "--json")
    builtin = [r for r in listed if r["kind"] == "reference"]
    assert builtin and len(builtin) == len(listed)  # a new library shows only the references
    r = run(
        "library", "add", "my-soil", "--param", "kc=100", "--param", "kphi=5000",
        "--param", "n=0.8", "--param", "c_kpa=1.5", "--param", "phi_deg=30",
        "--param", "K_m=0.02", "--source", "test",
    )  # fmt: skip
    assert r.exit_code == 0 and "my-soil" in r.output
    assert (tmp_path / "lib.sqlite").exists()
    shown = ok_json("library", "show", "my-soil")
    assert shown["name"] == "my-soil" and shown["kind"] == "user"
    assert shown["params"] == {
        "kc": 100.0,
        "kphi": 5000.0,
        "n": 0.8,
        "c_kpa": 1.5,
        "phi_deg": 30.0,
        "K_m": 0.02,
    }
    names = [x["name"] for x in ok_json("library", "list", "--json")]
    assert "my-soil" in names and len(names) == len(listed) + 1
    r = run("library", "list")
    assert r.exit_code == 0 and "my-soil" in r.output
    # Chrono SCM: Pa and m; Kphi [Pa/m^n] = kphi [kN/m^(n+2)] * 1000, Kc likewise
    out = tmp_path / "scm.json"
    r = run("export", "--terrain", "my-soil", "--format", "chrono-scm", "--out", str(out))
    assert r.exit_code == 0, r.output
    soil = json.loads(out.read_text())["Soil parameters"]  # Chrono's co-simulation spec
    assert soil["Bekker Kphi"] == pytest.approx(5.0e6)
    assert soil["Bekker Kc"] == pytest.approx(1.0e5)
    assert soil["Bekker n exponent"] == pytest.approx(0.8)
    assert soil["Mohr cohesive limit"] == pytest.approx(1500.0)
    assert soil["Mohr friction limit"] == pytest.approx(30.0)
    assert soil["Janosi shear coefficient"] == pytest.approx(0.02)
    # remove, then it is gone (one message, non-zero exit)
    r = run("library", "remove", "my-soil")
    assert r.exit_code == 0 and "my-soil" in r.output
    lib = tmp_path / "lib.sqlite"
    assert error_line(run("library", "show", "my-soil")) == f"no terrain 'my-soil' in {lib}"
    # the packaged references cannot be removed
    ref = builtin[0]["name"]
    assert error_line(run("library", "remove", ref)) == (
        f"{ref!r} is a packaged reference terrain and cannot be removed"
    )
    assert ref in [x["name"] for x in ok_json("library", "list", "--json")]
    r = run("export", "--terrain", "nothing-here", "--format", "chrono-scm", "--out", str(out))
    assert error_line(r) == f"no terrain 'nothing-here' in {lib}"


def test_fit_plates_save_as_then_export(tmp_path: Path, monkeypatch):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "lib.sqlite"))
    path = _plates(tmp_path / "plates.csv")
    d = ok_json("fit-plates", str(path), "--save-as", "plate-fit", "--json")
    assert d["saved_as"] == "plate-fit"
    rec = ok_json("library", "show", "plate-fit")
    assert rec["params"]["kc"] == pytest.approx(100.0, rel=1e-6)
    assert rec["params"]["kphi"] == pytest.approx(5000.0, rel=1e-6)
    out = tmp_path / "plain.json"
    r = run("export", "--terrain", "plate-fit", "--format", "json", "--out", str(out))
    assert r.exit_code == 0, r.output
    assert out.exists()


# ---------------------------------------------------------------------------
# demo
# ---------------------------------------------------------------------------


def test_demo_recovers_the_example_truth(tmp_path: Path):
    """The README's main job, against the tolerances docs/learn.md states for it."""
    from terracone.apps.example import TRUTH as T

    out = tmp_path / "demo"
    r = run("demo", "--out", str(out))
    assert r.exit_code == 0, r.output
    assert r.output.startswith("terracone demo: SYNTHETIC")
    assert r.output.rstrip().endswith(f"JSON written to {out}")
    learned = json.loads((out / "learn.json").read_text())
    cal = json.loads((out / "calibration.json").read_text())
    profiles = json.loads((out / "predict.json").read_text())["profiles"]
    plates = json.loads((out / "evaluate.json").read_text())["plates"]
    # the learned calibration: kc and kphi within 10%, n within 0.03
    assert learned["units"] == "si" and learned["model"] == T["model"]
    assert learned["kc"] == pytest.approx(T["kc"], rel=0.10)
    assert learned["kphi"] == pytest.approx(T["kphi"], rel=0.10)
    assert learned["n"] == pytest.approx(T["n"], abs=0.03)
    for k in ("kc", "kphi", "n", "cc", "phic_deg", "r_min"):
        assert cal[k] == pytest.approx(learned[k], rel=1e-12, abs=1e-15), k
    # each calibrated prediction: kc and kphi within 15%, n within 0.05
    assert [p["id"] for p in profiles] == ["LS_syn_1", "LS_syn_2", "LS_syn_3"]
    for p in profiles:
        assert p["status"] == "ok" and p["units"] == "si"
        assert p["kc"] == pytest.approx(T["kc"], rel=0.15), p["id"]
        assert p["kphi"] == pytest.approx(T["kphi"], rel=0.15), p["id"]
        assert p["n"] == pytest.approx(T["n"], abs=0.05), p["id"]
        assert p["phic_deg"] == pytest.approx(cal["phic_deg"], abs=1e-9)  # fixed by the calibration
    # the predicted plate curves against both plates: R2 >= 0.99, CV <= 0.06
    assert len(plates) == 3 * 2
    assert {(x["prediction"], x["test"]) for x in plates} == {
        (p, t)
        for p in ("LS_syn_1", "LS_syn_2", "LS_syn_3")
        for t in ("LS_syn_A_r3.75cm", "LS_syn_A_r5cm")
    }
    for x in plates:
        assert x["R2"] >= 0.99 and x["CV"] <= 0.06, x
    # the same learned parameters through `terracone evaluate`, and a report of every part
    from terracone.apps.example import PLATES_FILE, example_dir

    ev = ok_json(
        "evaluate",
        "--plates",
        str(example_dir() / PLATES_FILE),
        "--params",
        str(out / "learn.json"),
        "--json",
    )
    assert [x["test"] for x in ev["plates"]] == ["LS_syn_A_r3.75cm", "LS_syn_A_r5cm"]
    assert all(x["R2"] >= 0.99 and x["CV"] <= 0.06 for x in ev["plates"])
    html = tmp_path / "demo.html"
    r = run("report", str(out), "--out", str(html))
    assert r.exit_code == 0 and r.output.strip() == f"wrote {html}"
    text = html.read_text()
    # one part per JSON file of the folder
    for part in ("evaluate.json: Agreement", "learn.json: Results", "predict.json: Parameters"):
        assert f">{part}</h2>" in text, part
    assert "http://" not in text and "https://" not in text

"""Chrono reads what terracone writes (issue 21): co-simulation SCM specs and PyChrono modules.

The references are Chrono's own sources (key names, argument order, units)
and conversions done by hand in the tests; the PyChrono modules run against
the recording stand-in of ``tests/pychrono_standin.py`` (PyChrono is
conda-only and cannot be installed here).
"""

from __future__ import annotations

import ast
import importlib.util
import json
import math
import runpy
import sys

import pytest
from pychrono_standin import CALLS, SCMTerrain, install

from terracone.apps.chrono import (
    LocatedSoil,
    pychrono_module,
    scm_settings,
    scm_spec,
    scm_values,
)

# Chrono's co-simulation SCM terrain spec, key by key, as read by
# ChVehicleCosimTerrainNodeSCM::SetFromSpecfile
# (projectchrono/chrono, src/chrono_vehicle/cosim/terrain/ChVehicleCosimTerrainNodeSCM.cpp:
#  d["Patch dimensions"]["Length"|"Width"], d["Grid spacing"], d["Soil parameters"][...],
#  d["Simulation settings"]["Proxy contact radius"|"Fix proxies"] (GetBool)) and by
# ChVehicleCosimTerrainNodeChrono::GetTypeFromSpecfile (d["Type"] == "SCM"), as in the
# sample data/vehicle/cosim/terrain/scm_soft.json.  Every key is read without a check.
CHRONO_SPEC_KEYS = {
    "Type": None,
    "Patch dimensions": {"Length", "Width"},
    "Grid spacing": None,
    "Soil parameters": {
        "Bekker Kphi",
        "Bekker Kc",
        "Bekker n exponent",
        "Mohr cohesive limit",
        "Mohr friction limit",
        "Janosi shear coefficient",
        "Elastic stiffness",
        "Damping",
    },
    "Simulation settings": {"Proxy contact radius", "Fix proxies"},
}
# Chrono's own sample (data/vehicle/cosim/terrain/scm_soft.json), for its value types.
CHRONO_SCM_SOFT = {
    "Type": "SCM",
    "Patch dimensions": {"Length": 4, "Width": 1},
    "Grid spacing": 0.1,
    "Soil parameters": {
        "Bekker Kphi": 2e6,
        "Bekker Kc": 0,
        "Bekker n exponent": 1.1,
        "Mohr cohesive limit": 0,
        "Mohr friction limit": 30,
        "Janosi shear coefficient": 0.01,
        "Elastic stiffness": 4e7,
        "Damping": 3e4,
    },
    "Simulation settings": {"Proxy contact radius": 0.002, "Fix proxies": True},
}
LBF, INCH = 4.4482216152605, 0.0254  # N, m (exact)


def key_set(doc: dict) -> dict:
    return {k: (set(v) if isinstance(v, dict) else None) for k, v in doc.items()}


def run(*args, env=None):
    from click.testing import CliRunner

    from terracone.cli import cli

    return CliRunner().invoke(cli, [str(a) for a in args], env=env)


@pytest.fixture
def library(tmp_path, monkeypatch):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "lib.sqlite"))
    return tmp_path / "lib.sqlite"


WIDE = (
    "# ci unit: kPa\nid,lat,lon,0cm,2cm,4cm,6cm,8cm,10cm\n"
    "A,34°30.0S,19°15.0E,100,300,500,650,800,900\n"
    "B,34°30.5S,19°15.2E,150,420,700,900,1100,1250\n"
    "C,34°29.8S,19°14.6E,80,200,330,450,560,650\n"
    "D,,,120,310,480,700,820,900\n"
    "E,34°30.1S,19°15.1E,120,x,480,700,820,900\n"
)


@pytest.fixture(scope="module")
def predicted(tmp_path_factory):
    """predict --json (US units, kc bounded away from 0) of 3 located, 1 unlocated, 1 bad profile."""
    folder = tmp_path_factory.mktemp("pred")
    (folder / "w.csv").write_text(WIDE)
    out = folder / "pred.json"
    r = run("predict", folder / "w.csv", "--bounds", "kc=1:2", "--units", "us", "--out", out)
    assert r.exit_code == 0, r.output
    return out


def profiles_of(path) -> dict:
    return {p["id"]: p for p in json.loads(path.read_text())["profiles"]}


# ---------------------------------------------------------------------------
# the co-simulation spec (--format chrono-scm)
# ---------------------------------------------------------------------------


def test_spec_has_chronos_keys_and_hand_converted_values(tmp_path, library):
    out = tmp_path / "lete.json"
    r = run("export", "--terrain", "LETE sand", "--format", "chrono-scm", "--out", out)
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    assert key_set(doc) == CHRONO_SPEC_KEYS == key_set(CHRONO_SCM_SOFT)
    assert doc["Type"] == "SCM" and doc["Simulation settings"]["Fix proxies"] is True
    # GetDouble() on every number, GetBool() on "Fix proxies"
    for section in ("Patch dimensions", "Soil parameters", "Simulation settings"):
        for k, v in doc[section].items():
            assert isinstance(v, bool) if k == "Fix proxies" else type(v) is float, k
    soil = doc["Soil parameters"]
    # Wong's LETE sand: n 0.79, kc 102 kN/m^(n+1), kphi 5301 kN/m^(n+2), c 1.3 kPa,
    # phi 31.1 deg, K 1.2 cm.  kN/m^(n+1) = 1000 N/m^(n+1) = 1000 Pa/m^(n-1).
    assert soil["Bekker Kc"] == pytest.approx(102.0 * 1000, rel=1e-12)
    assert soil["Bekker Kphi"] == pytest.approx(5301.0 * 1000, rel=1e-12)
    assert soil["Bekker n exponent"] == 0.79
    assert soil["Mohr cohesive limit"] == pytest.approx(1300.0, rel=1e-12)
    assert soil["Mohr friction limit"] == 31.1
    assert soil["Janosi shear coefficient"] == pytest.approx(0.012, rel=1e-12)
    # not data: the defaults of Chrono's samples, said on stderr
    assert soil["Elastic stiffness"] == 4e8 and soil["Damping"] == 3e4
    assert doc["Patch dimensions"] == {"Length": 4.0, "Width": 1.0} and doc["Grid spacing"] == 0.1
    assert (
        "Elastic stiffness = 4e+08 Pa/m, Damping = 30000 Pa s/m, Patch dimensions = 4 x 1 m, "
        "Grid spacing = 0.1 m, Proxy contact radius = 0.002 m, Fix proxies = true: defaults "
        "(Chrono's own samples), not from data"
    ) in r.stderr
    assert "from library terrain 'LETE sand'" in r.stderr
    # Chrono's pressure (Pa) on a 0.1 m plate at 5 cm is terracone's (kPa) x 1000
    b, z = 0.1, 0.05
    p_pa = (soil["Bekker Kc"] / b + soil["Bekker Kphi"]) * z ** soil["Bekker n exponent"]
    assert p_pa == pytest.approx(1000 * (102.0 / b + 5301.0) * z**0.79, rel=1e-12)


def test_spec_from_a_us_prediction_by_hand(tmp_path, library, predicted):
    a = profiles_of(predicted)["A"]
    assert a["units"] == "us" and a["kc"] == pytest.approx(1.0)
    fit = tmp_path / "shear.json"  # the layout of `fit-shear --json --units us`
    fit.write_text(json.dumps({"c": 0.19, "phi_deg": 29.0, "K": 0.5, "units": "us"}))
    out = tmp_path / "a.json"
    args = ["--patch", "160x40", "--grid-spacing", "2", "--elastic-k", "5e8", "--damping", "0"]
    r = run("export", "--results", predicted, "--profile", "A", "--format", "chrono-scm",
            "--out", out, "--shear", fit, "--units", "us", *args)  # fmt: skip
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    soil, n = doc["Soil parameters"], a["n"]
    # by hand: lb/in^(n+1) = 4.4482216152605 N / (0.0254 m)^(n+1) = N/m^(n+1) = Pa/m^(n-1)
    assert soil["Bekker Kc"] == pytest.approx(a["kc"] * LBF / INCH ** (n + 1), rel=1e-9)
    assert soil["Bekker Kphi"] == pytest.approx(a["kphi"] * LBF / INCH ** (n + 2), rel=1e-9)
    assert soil["Bekker n exponent"] == pytest.approx(n, rel=1e-12)
    assert soil["Mohr cohesive limit"] == pytest.approx(0.19 * LBF / INCH**2, rel=1e-9)  # psi
    assert soil["Mohr friction limit"] == 29.0
    assert soil["Janosi shear coefficient"] == pytest.approx(0.5 * INCH, rel=1e-12)
    assert soil["Elastic stiffness"] == 5e8 and soil["Damping"] == 0.0
    # --patch 160x40 and --grid-spacing 2 are inches with --units us
    assert doc["Patch dimensions"] == pytest.approx({"Length": 4.064, "Width": 1.016})
    assert doc["Grid spacing"] == pytest.approx(0.0508)
    assert "Proxy contact radius = 0.002 m, Fix proxies = true: defaults" in r.stderr
    assert "Elastic stiffness" not in r.stderr and "Grid spacing =" not in r.stderr
    assert (
        f"Mohr cohesive limit, Mohr friction limit, Janosi shear coefficient from shear fit {fit}"
        in r.stderr
    )


def test_explicit_values_take_unit_suffixes(tmp_path, library, predicted):
    out = tmp_path / "a.json"
    base = ["export", "--results", predicted, "--profile", "B", "--format", "chrono-scm"]
    r = run(*base, "--out", out, "--cohesion", "0.19psi", "--friction", "31deg", "--janosi", "12mm")
    assert r.exit_code == 0, r.output
    soil = json.loads(out.read_text())["Soil parameters"]
    assert soil["Mohr cohesive limit"] == pytest.approx(0.19 * LBF / INCH**2, rel=1e-9)
    assert soil["Mohr friction limit"] == 31.0
    assert soil["Janosi shear coefficient"] == pytest.approx(0.012, rel=1e-12)
    # bare numbers are in --units: kPa and m, or psi and in
    r = run(*base, "--out", out, "--cohesion", "1.3", "--friction", "31", "--janosi", "0.5",
            "--units", "us")  # fmt: skip
    assert r.exit_code == 0, r.output
    soil = json.loads(out.read_text())["Soil parameters"]
    assert soil["Mohr cohesive limit"] == pytest.approx(1.3 * LBF / INCH**2, rel=1e-9)
    assert soil["Janosi shear coefficient"] == pytest.approx(0.5 * INCH, rel=1e-12)
    # explicit values override --shear, and the library terrain's own
    r = run(*base, "--out", out, "--shear", "LETE sand", "--janosi", "2cm")
    assert r.exit_code == 0, r.output
    soil = json.loads(out.read_text())["Soil parameters"]
    assert (
        soil["Mohr cohesive limit"] == pytest.approx(1300.0) and soil["Mohr friction limit"] == 31.1
    )
    assert soil["Janosi shear coefficient"] == pytest.approx(0.02)
    assert "Janosi shear coefficient from --janosi" in r.stderr
    assert "Mohr cohesive limit, Mohr friction limit from library terrain 'LETE sand'" in r.stderr
    r = run(*base, "--out", out, "--cohesion", "1.3bar", "--friction", "31", "--janosi", "1cm")
    assert r.exit_code != 0 and "--cohesion: expected a pressure such as 1.3kPa" in r.output


# ---------------------------------------------------------------------------
# complete or refused
# ---------------------------------------------------------------------------

SHEAR_NAMES = ("Mohr cohesive limit", "Mohr friction limit", "Janosi shear coefficient")


@pytest.mark.parametrize("fmt", ["chrono-scm", "pychrono"])
def test_export_without_shear_values_is_refused_and_writes_nothing(
    tmp_path, library, predicted, fmt
):
    out = tmp_path / "out"
    r = run("export", "--results", predicted, "--profile", "A", "--format", fmt, "--out", out)
    assert r.exit_code != 0 and not out.exists()
    msg = r.output
    assert msg.startswith("Error: Chrono's SCM needs all eight soil parameters and 'A' lacks ")
    for name, arg in zip(SHEAR_NAMES, ("Mohr_cohesion", "Mohr_friction", "Janosi_shear")):
        assert f"{name} ({arg})" in msg
    assert "--shear FIT.json (the output of `terracone fit-shear --json`)" in msg
    assert "--shear TERRAIN (a library terrain that has them)" in msg
    assert "--cohesion, --friction, --janosi" in msg and "nothing was written" in msg
    assert "Traceback" not in msg
    # one of three given: the other two named, still nothing written
    r = run("export", "--results", predicted, "--profile", "A", "--format", fmt, "--out", out,
            "--friction", "30")  # fmt: skip
    assert r.exit_code != 0 and not out.exists()
    assert "lacks Mohr cohesive limit (Mohr_cohesion), Janosi shear coefficient" in r.output
    assert "Mohr friction limit (" not in r.output
    assert "found: Bekker Kphi, Bekker Kc, Bekker n exponent from the cone" in r.output
    assert "Mohr friction limit from --friction" in r.output


def test_samples_refused_leave_no_folder(tmp_path, library, predicted):
    out = tmp_path / "draws"
    r = run("export", "--results", predicted, "--profile", "A", "--format", "chrono-scm",
            "--samples", "2", "--out", out, "--cohesion", "1", "--friction", "30")  # fmt: skip
    assert r.exit_code != 0 and not out.exists()


def test_shear_fit_on_one_normal_pressure_gives_only_janosi(tmp_path, library, predicted):
    # two generated shear tests at one normal pressure (93 kPa, as the Cullinan sand's four):
    # Janosi-Hanamoto tau = tau_max (1 - exp(-j / K)), K = 15 mm, tau_max 60 and 61 kPa
    src = tmp_path / "shear.csv"
    rows = ["test,normal_pressure_kpa,shear_displacement_mm,shear_stress_kpa"]
    for test, tau_max in (("a", 60.0), ("b", 61.0)):
        rows += [f"{test},93,{j},{tau_max * (1 - math.exp(-j / 15.0))!r}" for j in range(0, 101, 5)]
    src.write_text("\n".join(rows) + "\n")
    fit = tmp_path / "fit.json"
    r = run("fit-shear", src, "--json")
    assert r.exit_code == 0, r.output
    fit.write_text(r.stdout)
    fitted = json.loads(r.stdout)
    assert fitted["c"] is None and fitted["phi_deg"] is None  # one normal pressure
    assert fitted["K"] == pytest.approx(0.015, rel=1e-6)  # the known truth [m]
    out = tmp_path / "a.json"
    base = ["export", "--results", predicted, "--profile", "A", "--format", "chrono-scm"]
    r = run(*base, "--out", out, "--shear", fit)
    assert r.exit_code != 0 and not out.exists()
    assert (
        "lacks Mohr cohesive limit (Mohr_cohesion), Mohr friction limit (Mohr_friction):"
        in r.output
    )
    assert f"Janosi shear coefficient from shear fit {fit}" in r.output
    r = run(*base, "--out", out, "--shear", fit, "--cohesion", "0", "--friction", "30")
    assert r.exit_code == 0, r.output
    soil = json.loads(out.read_text())["Soil parameters"]
    assert soil["Janosi shear coefficient"] == pytest.approx(fitted["K"], rel=1e-12)  # m (si)
    assert soil["Mohr cohesive limit"] == 0.0


def test_scm_values_refuse_rather_than_guess():
    settings = scm_settings()
    # a calibration from cone data: cc, phic_deg, Kc are cone (metal)-terrain values
    cone = {"kc": 20.0, "kphi": 900.0, "n": 0.8, "cc": 2.5, "phic_deg": 24.0, "Kc": 0.01}
    with pytest.raises(ValueError, match=r"lacks Mohr cohesive limit \(Mohr_cohesion\), Mohr "):
        scm_values(cone, settings, "cal")
    values = scm_values({**cone, "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.02}, settings)
    assert values[3:6] == (1000.0, 30.0, 0.02)  # the terrain's, never cc, phic, Kc
    # Bekker values missing: named, with another way out
    with pytest.raises(ValueError, match=r"lacks Bekker Kphi \(Bekker_Kphi\): export a terrain"):
        scm_values({"kc": 1.0, "n": 1.0, "c_kpa": 1, "phi_deg": 30, "K_m": 0.01}, settings, "x")
    full = {"kc": 0.0, "kphi": 900.0, "n": 0.8, "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.02}
    # Chrono raises an elastic stiffness below Kphi silently; terracone refuses
    with pytest.raises(ValueError) as exc:
        scm_values(full, scm_settings(elastic_k=9e5), "soft")
    assert str(exc.value) == (
        "soft: Elastic stiffness must exceed Bekker Kphi (Chrono raises it silently to Kphi): "
        "Elastic stiffness = 900000 Pa/m, Bekker Kphi = 900000 Pa/m^n; give a larger "
        "--elastic-k (elastic_k=)"
    )
    with pytest.raises(ValueError, match="the default Elastic stiffness = 4e\\+08"):
        scm_values({**full, "kphi": 5e5}, settings, "stiff")
    with pytest.raises(ValueError, match="friction angle must be in"):
        scm_values({**full, "phi_deg": 95.0}, settings)
    with pytest.raises(ValueError, match=r"damping_r \(--damping\) must be >= 0 \(got -1"):
        scm_settings(damping_r=-1.0)
    with pytest.raises(ValueError, match=r"patch \(--patch\) must be > 0"):
        scm_settings(patch=(4.0, 0.0))
    with pytest.raises(ValueError, match=r"elastic_k \(--elastic-k\) must be > 0"):
        scm_settings(elastic_k=math.inf)
    assert scm_settings(damping_r=0.0).damping_r == 0.0
    assert "damping_r" not in scm_settings(damping_r=0.0).defaulted


def test_spec_of_library_terrain_without_shear_is_refused(tmp_path, library):
    r = run("library", "add", "plates", "--param", "kc=5", "--param", "kphi=800",
            "--param", "n=0.9", "--param", "K_m=0.01", "--source", "test")  # fmt: skip
    assert r.exit_code == 0, r.output
    out = tmp_path / "p.json"
    r = run("export", "--terrain", "plates", "--format", "chrono-scm", "--out", out)
    assert r.exit_code != 0 and not out.exists()
    assert "'plates' lacks Mohr cohesive limit (Mohr_cohesion), Mohr friction limit" in r.output
    assert "Janosi shear coefficient from library terrain 'plates'" in r.output
    assert scm_spec({"kc": 5, "kphi": 800, "n": 0.9, "c_kpa": 0, "phi_deg": 30, "K_m": 0.01},
                    scm_settings())["Soil parameters"]["Bekker Kc"] == 5000.0  # fmt: skip


# ---------------------------------------------------------------------------
# the PyChrono module (--format pychrono), run against the stand-in
# ---------------------------------------------------------------------------


def load(path, monkeypatch, name="soil_module"):
    install(monkeypatch)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_module_imports_only_pychrono_and_the_standard_library(tmp_path, library):
    out = tmp_path / "lete_soil.py"
    assert (
        run("export", "--terrain", "LETE sand", "--format", "pychrono", "--out", out).exit_code == 0
    )
    tree = ast.parse(out.read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add(node.module)
    stdlib = {m for m in imported if m in sys.stdlib_module_names}
    assert imported - stdlib == {"pychrono", "pychrono.vehicle"}


def test_module_one_terrain_sets_the_eight_values(tmp_path, library, monkeypatch, capsys):
    out = tmp_path / "lete_soil.py"
    r = run("export", "--terrain", "LETE sand", "--format", "pychrono", "--out", out)
    assert r.exit_code == 0, r.output
    assert "Elastic stiffness = 4e+08 Pa/m, Damping = 30000 Pa s/m" in r.stderr
    assert "Proxy contact radius" not in r.stderr  # not in a module
    m = load(out, monkeypatch)
    assert m.ORIGIN is None and m.N_SAMPLES == 0
    terrain = SCMTerrain(system=None)
    assert m.apply(terrain) is None
    # SetSoilParameters(Kphi [Pa/m^n], Kc [Pa/m^(n-1)], n, cohesion [Pa], friction [deg],
    # Janosi [m], elastic K [Pa/m], damping R [Pa s/m]), by hand from Wong's LETE sand
    expected = (5301e3, 102e3, 0.79, 1300.0, 31.1, 0.012, 4e8, 3e4)
    assert terrain.params == pytest.approx(expected, rel=1e-12)
    assert [c[0] for c in CALLS] == ["SCMTerrain", "SetSoilParameters"]
    # run as a script: a patch of PATCH and GRID_SPACING in a Chrono system, a plate on it
    CALLS.clear()
    runpy.run_path(str(out), run_name="__main__")
    names = [c[0] for c in CALLS]
    assert names[:4] == [
        "SetCollisionSystemType",
        "SetGravitationalAcceleration",
        "SCMTerrain",
        "Initialize",
    ]
    assert dict(CALLS)["Initialize"] == (4.0, 1.0, 0.1)
    assert dict(CALLS)["SetSoilParameters"] == pytest.approx(expected, rel=1e-12)
    assert dict(CALLS)["SetGravitationalAcceleration"] == (0.0, 0.0, -9.81)  # SCM: z up
    printed = capsys.readouterr().out
    assert "SCM patch 4 x 1 m, grid 0.1 m, soil of 'LETE sand'" in printed
    # Bekker's static sinkage of a 0.2 m square plate at 20 kPa, b = 2 area / perimeter = 0.1 m:
    # (20e3 Pa / (102e3 / 0.1 + 5301e3) Pa/m^n) ** (1 / 0.79) = 0.000685 m
    static = (20e3 / (102e3 / 0.1 + 5301e3)) ** (1 / 0.79)
    assert static == pytest.approx(6.85097e-4, rel=1e-5)
    # on SCM's 0.1 m grid the plate is centred half a step off the grid lines (its edges would
    # fall on them): it covers the nodes x, y in {0, 0.1}, 4 nodes of 0.01 m^2 = 800 N / 0.04 m^2
    # = 20 kPa; their hull is 0.1 m square, 1/b = 0.4 / (2 * 0.01) = 20 /m, so
    # (20e3 / (102e3 * 20 + 5301e3)) ** (1 / 0.79); the stand-in rests the plate there
    on_grid = (20e3 / (102e3 * 20 + 5301e3)) ** (1 / 0.79)
    assert on_grid == pytest.approx(5.66908e-4, rel=1e-5)
    assert (
        f"sinkage {on_grid:.3g} m after 1 s (static on SCM's grid: {on_grid:.3g} m; "
        f"Bekker, continuous plate: {static:.3g} m)"
    ) in printed
    sinkage, grid, bekker = m.demo()
    assert sinkage == pytest.approx(on_grid, rel=1e-12) and grid == pytest.approx(
        on_grid, rel=1e-12
    )
    assert bekker == pytest.approx(static, rel=1e-12)
    # a plate of 0.4 m at 40 kPa, centred at 0.05 m: nodes -0.1 .. 0.2 (4 x 4, 0.16 m^2, 40 kPa),
    # hull 0.3 m square: 1/b = 1.2 / 0.18 = 20/3 /m
    sinkage, _, _ = m.demo(plate=0.4, pressure=40e3)
    assert sinkage == pytest.approx((40e3 / (102e3 * 20 / 3 + 5301e3)) ** (1 / 0.79), rel=1e-12)
    # a plate of 0.3 m (an odd number of steps, centred on a node): 3 x 3 nodes, 0.09 m^2 carry
    # 20e3 * 0.09 N: 20 kPa; hull 0.2 m square, 1/b = 10 /m
    sinkage, _, _ = m.demo(plate=0.3)
    assert sinkage == pytest.approx((20e3 / (102e3 * 10 + 5301e3)) ** (1 / 0.79), rel=1e-12)


def test_standin_rests_a_box_where_bekker_carries_it(monkeypatch):
    """The stand-in's plate: 0.2 x 0.4 m at (1.05, 0.55) m on a 0.1 m grid, 0.05 m thick, 160 kg
    under 10 m/s^2: it covers nodes x in {1.0, 1.1}, y in {0.4 .. 0.7}, 8 nodes of 0.01 m^2 carry
    1600 N: 20 kPa; their hull is 0.1 x 0.3 m, 1/b = 0.8 / 0.06 = 40/3 /m; soil Kphi 2e6
    Pa/m^n, Kc 1e5 Pa/m^(n-1), n 1.1: z = (20e3 / (1e5 * 40 / 3 + 2e6)) ** (1 / 1.1)."""
    install(monkeypatch)
    import pychrono as chrono
    import pychrono.vehicle as veh

    system = chrono.ChSystemSMC()
    terrain = veh.SCMTerrain(system)
    terrain.SetSoilParameters(2e6, 1e5, 1.1, 0.0, 30.0, 0.01, 4e7, 3e4)
    terrain.Initialize(4.0, 2.0, 0.1)
    body = chrono.ChBodyEasyBox(0.2, 0.4, 0.05, 160.0 / (0.2 * 0.4 * 0.05), True, True, None)
    body.SetPos(chrono.ChVector3d(1.05, 0.55, 0.03))
    system.Add(body)
    system.DoStepDynamics(1e-3)  # Chrono's default gravity (0, -9.8, 0) loads nothing along z
    assert body.GetPos().z == pytest.approx(0.025)
    system.SetGravitationalAcceleration(chrono.ChVector3d(0, 0, -10.0))
    system.DoStepDynamics(1e-3)
    z = (20e3 / (1e5 * 40 / 3 + 2e6)) ** (1 / 1.1)
    assert z == pytest.approx(0.0095529, rel=1e-4)
    assert body.GetPos().z == pytest.approx(0.025 - z, rel=1e-12)
    assert (body.GetPos().x, body.GetPos().y) == (1.05, 0.55)


def test_module_three_located_profiles_nearest_values(tmp_path, library, monkeypatch, predicted):
    out = tmp_path / "site_soil.py"
    r = run("export", "--results", predicted, "--format", "pychrono", "--out", out,
            "--cohesion", "1.3kPa", "--friction", "31", "--janosi", "12mm")  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "wrote 3 located soils to" in r.stdout
    assert "left out 2: E (not fitted: file " in r.stderr and "D (no lat/lon)" in r.stderr
    m = load(out, monkeypatch)
    profiles = profiles_of(predicted)
    where = {"A": (-34.5, 19.25), "B": (-34.5 - 0.5 / 60, 19.25 + 0.2 / 60),
             "C": (-34.5 + 0.2 / 60, 19.25 - 0.4 / 60)}  # fmt: skip
    # ORIGIN: the middle of the profiles' bounding box
    lats, lons = [w[0] for w in where.values()], [w[1] for w in where.values()]
    assert m.ORIGIN == pytest.approx(((min(lats) + max(lats)) / 2, (min(lons) + max(lons)) / 2))
    terrain = SCMTerrain(system=None)
    callback = m.apply(terrain)
    assert terrain.callback is callback and callback in m._KEEP and terrain.params is None
    for pid, (lat, lon) in where.items():
        p, n = profiles[pid], profiles[pid]["n"]
        expected = (
            p["kphi"] * LBF / INCH ** (n + 2),  # lb/in^(n+2) -> N/m^(n+2) = Pa/m^n
            p["kc"] * LBF / INCH ** (n + 1),
            n,
            1300.0,
            31.0,
            0.012,
            4e8,
            3e4,
        )
        x, y = m.to_local(lat, lon)
        assert terrain.soil_at(x, y) == pytest.approx(expected, rel=1e-9), pid
        assert terrain.soil_at(x + 20.0, y - 20.0) == pytest.approx(expected, rel=1e-9), pid
    # the frame: x east, y north [m] from ORIGIN; A lies north-east of B
    xa, ya = m.to_local(*where["A"])
    xb, yb = m.to_local(*where["B"])
    assert xa < xb and ya > yb
    # 0.5 minute of latitude is about 0.5 * 1852 m (a nautical mile is one minute)
    assert ya - yb == pytest.approx(0.5 * 1852.0, rel=0.01)
    # the script's plate at ORIGIN rests on the soil of the nearest profile (the callback's)
    near = min(where, key=lambda k: math.hypot(*m.to_local(*where[k])))
    kphi, kc, n = terrain.soil_at(*m.to_local(*where[near]))[:3]
    sinkage, on_grid, static = m.demo()  # 4 nodes, 1/b = 20 /m (as test_module_one_terrain)
    assert sinkage == pytest.approx((20e3 / (kc * 20 + kphi)) ** (1 / n), rel=1e-12)
    assert on_grid == pytest.approx(sinkage, rel=1e-12) and sinkage > 0
    assert static == pytest.approx((20e3 / (kc / 0.1 + kphi)) ** (1 / n), rel=1e-12)


def test_to_local_by_hand_at_the_equator(monkeypatch, tmp_path):
    soil = {"kc": 1.0, "kphi": 100.0, "n": 1.0, "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.01}
    soils = [LocatedSoil("a", soil, 0.0, 0.0), LocatedSoil("b", soil, 0.001, 0.001)]
    path = tmp_path / "eq.py"
    path.write_text(pychrono_module(soils, scm_settings(), origin=(0.0, 0.0)))
    m = load(path, monkeypatch)
    # WGS 84: a = 6378137 m, 1/f = 298.257223563; at the equator the prime-vertical radius
    # is a and the meridional radius a (1 - e^2), e^2 = f (2 - f)
    f = 1 / 298.257223563
    deg = math.pi / 180
    assert m.to_local(0.0, 0.001) == pytest.approx((6378137.0 * 0.001 * deg, 0.0), rel=1e-9)
    y = 6378137.0 * (1 - f * (2 - f)) * 0.001 * deg
    assert m.to_local(0.001, 0.0) == pytest.approx((0.0, y), rel=1e-9, abs=1e-9)
    assert m.to_local(0.0, -179.9995 + 360) == pytest.approx(m.to_local(0.0, -179.9995))


def test_nearest_site_agrees_with_brute_force(monkeypatch, tmp_path):
    import numpy as np

    rng = np.random.default_rng(7)
    lat = -34.5 + rng.uniform(-0.01, 0.01, 300)
    lon = 19.25 + rng.uniform(-0.02, 0.02, 300)
    soils = [
        LocatedSoil(
            f"s{k}",
            {"kc": float(k), "kphi": 100.0, "n": 1.0, "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.01},
            float(a),
            float(b),
        )  # fmt: skip
        for k, (a, b) in enumerate(zip(lat, lon))
    ]
    path = tmp_path / "many.py"
    path.write_text(pychrono_module(soils, scm_settings()))
    m = load(path, monkeypatch)
    xy = [m.to_local(a, b) for a, b in zip(lat, lon)]
    nearest = m.Nearest(xy)
    queries = [(float(x), float(y)) for x, y in rng.uniform(-2500, 2500, (400, 2))]
    queries += [(float(x), float(y)) for x, y in rng.uniform(-1e5, 1e5, (50, 2))]  # far away
    queries += xy[:20]  # at the sites
    for x, y in queries:
        d = [(px - x) ** 2 + (py - y) ** 2 for px, py in xy]
        assert nearest(x, y) == d.index(min(d))
        assert nearest(x, y) == d.index(min(d))  # again, from the cache
    terrain = SCMTerrain(system=None)
    m.apply(terrain)
    x, y = xy[123]
    assert terrain.soil_at(x, y)[1] == pytest.approx(123.0 * 1000)  # Kc of site s123


# ---------------------------------------------------------------------------
# ensembles (--samples N)
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def with_draws(tmp_path_factory):
    """predict --uncertainty --json of two located profiles, A and B (40 stored draws each)."""
    folder = tmp_path_factory.mktemp("draws")
    wide = folder / "w.csv"
    wide.write_text("\n".join(WIDE.splitlines()[:4]) + "\n")
    out = folder / "pred.json"
    r = run("predict", wide, "--uncertainty", "--draws", "40", "--seed", "1", "--out", out)
    assert r.exit_code == 0, r.output
    return out


def stored_draws(path, pid) -> list[list[float]]:
    block = profiles_of(path)[pid]["samples"]
    assert block["names"] == ["kc", "kphi", "n", "cc", "phic_deg"] and block["units"] == "si"
    return block["values"]


def test_spec_ensemble_writes_n_files_from_the_draws(tmp_path, library, with_draws):
    out = tmp_path / "draws"
    r = run("export", "--results", with_draws, "--profile", "A", "--format", "chrono-scm",
            "--samples", "5", "--seed", "2", "--out", out, "--shear", "LETE sand")  # fmt: skip
    assert r.exit_code == 0, r.output
    files = sorted(out.glob("A-draw-*.json"))
    assert [f.name for f in files] == [f"A-draw-000{k}.json" for k in range(1, 6)]
    stored = {round(row[1] * 1000, 6) for row in stored_draws(with_draws, "A")}  # Kphi [Pa/m^n]
    kphis = set()
    for f in files:
        doc = json.loads(f.read_text())
        assert key_set(doc) == CHRONO_SPEC_KEYS
        kphis.add(round(doc["Soil parameters"]["Bekker Kphi"], 6))
        assert doc["Soil parameters"]["Mohr cohesive limit"] == pytest.approx(1300.0)
    assert len(kphis) == 5 and kphis <= stored
    rows = (out / "draws.csv").read_text().splitlines()
    assert rows[0].startswith("file,kc [kN/m^(n+1)],kphi [kN/m^(n+2)],n") and len(rows) == 6


def test_module_ensemble_apply_sample_i(tmp_path, library, monkeypatch, with_draws):
    out = tmp_path / "ens.py"
    r = run("export", "--results", with_draws, "--format", "pychrono", "--samples", "4",
            "--seed", "3", "--out", out, "--shear", "LETE sand")  # fmt: skip
    assert r.exit_code == 0, r.output
    assert "wrote 2 located soils with 4 posterior draws" in r.stdout
    m = load(out, monkeypatch)
    assert m.N_SAMPLES == 4 and len(m.SAMPLES[0]) == 2
    terrain = SCMTerrain(system=None)
    seen = {pid: set() for pid in "AB"}
    for i in range(4):
        m.apply(terrain, sample=i)
        for pid, lat, lon in m.SITES:
            v = terrain.soil_at(*m.to_local(lat, lon))
            assert v[3:] == pytest.approx((1300.0, 31.1, 0.012, 4e8, 3e4))
            seen[pid].add((round(v[0] / 1000, 6), round(v[1] / 1000, 6), round(v[2], 9)))
    for pid in "AB":
        stored = {
            (round(r[1], 6), round(r[0], 6), round(r[2], 9)) for r in stored_draws(with_draws, pid)
        }
        assert len(seen[pid]) == 4 and seen[pid] <= stored, pid
    with pytest.raises(IndexError, match=r"sample must be in 0..3 \(got 4\)"):
        m.apply(terrain, sample=4)


def test_usage_errors(tmp_path, library, predicted):
    out = tmp_path / "x"
    r = run("export", "--terrain", "LETE sand", "--format", "json", "--out", out, "--cohesion", "1")
    assert r.exit_code != 0 and "--cohesion: only with --format chrono-scm or pychrono" in r.output
    r = run("export", "--terrain", "LETE sand", "--format", "pychrono", "--out", out,
            "--samples", "3")  # fmt: skip
    assert r.exit_code != 0 and "--samples needs --results with posterior draws" in r.output
    r = run("export", "--results", predicted, "--profile", "A", "--format", "pychrono",
            "--out", out, "--shear", "LETE sand", "--origin", "-34,19")  # fmt: skip
    assert r.exit_code != 0 and "--origin: only with --format pychrono and several" in r.output
    r = run("export", "--results", predicted, "--format", "chrono-scm", "--out", out,
            "--shear", "LETE sand")  # fmt: skip
    assert r.exit_code != 0 and "4 fitted profiles; choose one with --profile ID" in r.output
    r = run("export", "--results", predicted, "--profile", "A", "--format", "chrono-scm",
            "--out", out, "--shear", "no-such")  # fmt: skip
    assert (
        r.exit_code != 0 and "--shear no-such: no such file, and no terrain 'no-such'" in r.output
    )
    r = run("export", "--results", predicted, "--profile", "A", "--format", "chrono-scm",
            "--out", out, "--shear", "LETE sand", "--samples", "2")  # fmt: skip
    assert r.exit_code != 0 and "profile 'A' has no posterior draws" in r.output
    assert not out.exists()

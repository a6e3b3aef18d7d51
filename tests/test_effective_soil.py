"""An effective SCM soil for a layered ground (issue 31): plate law, wheel, fit, export.

References: hand values of eq. (2-2) layer by layer, Bekker's closed form of a
rigid wheel (exact at n = 1 with his shallow contact), the beta-function
integral of that contact for any n, the contact arc integrated over its angle
by scipy's adaptive quadrature (another variable and another rule than the
code's Gauss-Jacobi sums), brute force over the effective exponent, and the
PyChrono stand-in of tests/pychrono_standin.py for the written module.
"""

from __future__ import annotations

import importlib.util
import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import require_shared
from pychrono_standin import CALLS, SCMTerrain, install
from scipy import integrate
from scipy.special import beta

from terracone.cli import cli
from terracone.data import TerrainParameters
from terracone.physics.cone import get_cone
from terracone.physics.effective import N_BOUNDS, effective_soil, plate_misfit
from terracone.physics.layers import (
    LayeredPlate,
    layered_cone_index,
    layered_plate,
    layered_plate_pressure,
)
from terracone.physics.plate import plate_pressure, pressure_law
from terracone.physics.sinkage import sinkage_rigid_wheel, sinkage_track, wheel_load
from terracone.physics.vehicle import sinkage_rigid_wheel_bekker

SOFT_OVER_HARD = [TerrainParameters(10.0, 800.0, 0.9), TerrainParameters(30.0, 3000.0, 1.1)]
HARD_OVER_SOFT = [TerrainParameters(20.0, 1500.0, 0.8), TerrainParameters(5.0, 300.0, 0.7)]
WIDTHS = (0.1, 0.2, 0.4, 0.6)


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def load_by_hand(layers, interfaces, *, width, diameter, sinkage, law=None) -> float:
    """W [N] = b int_0^theta0 p(r (cos t - cos theta0)) r cos t dt, adaptive quadrature."""
    r = diameter / 2
    c0 = 1 - sinkage / r
    th0 = math.acos(c0)

    def f(t):
        z = r * (math.cos(t) - c0)
        p = layered_plate_pressure(np.array([z]), layers, interfaces, width=width, law=law)[0]
        return p * r * math.cos(t)

    pts = [math.acos(c0 + d / r) for d in interfaces if d < sinkage] or None
    val, _ = integrate.quad(f, 0, th0, points=pts, epsabs=0, epsrel=1e-12, limit=400)
    return 1000.0 * width * val


# ---------------------------------------------------------------------------
# the layered plate law
# ---------------------------------------------------------------------------


def test_layered_plate_is_the_law_of_the_layer_at_the_plates_depth():
    b = 0.2
    z = np.array([0.0, 0.05, 0.1199, 0.12, 0.3])
    p = layered_plate_pressure(z, SOFT_OVER_HARD, [0.12], width=b)
    top = (10.0 / b + 800.0) * z**0.9  # eq. (2-2) by hand, layer 1
    bottom = (30.0 / b + 3000.0) * z**1.1  # layer 2; the interface belongs to it
    assert p == pytest.approx(np.where(z < 0.12, top, bottom), rel=1e-14)
    assert p[2] < p[3]  # a jump up onto the harder layer
    drop = layered_plate_pressure(np.array([0.1199, 0.12]), HARD_OVER_SOFT, [0.12], width=b)
    assert drop[1] < drop[0]  # and down onto a softer one


def test_one_layer_plate_is_bekkers_plate_rm0_and_rm1():
    law = pressure_law("rm1", r_min=0.3)
    for b in (0.1, 0.5):  # below and above r_min
        for model, lw in (("rm0", None), ("rm1", law)):
            kw = {"r_min": 0.3} if model == "rm1" else {}
            ref = plate_pressure([0.02, 0.1], kc=12.0, kphi=900.0, n=0.8, width=b, model=model,
                                 **kw)  # fmt: skip
            one = layered_plate([TerrainParameters(12.0, 900.0, 0.8)], [], width=b, law=lw)
            assert one.pressure(np.array([0.02, 0.1])) == pytest.approx(ref, rel=1e-14)


def test_layered_plate_refuses_what_is_not_a_ground():
    with pytest.raises(ValueError, match="one k and one n per layer"):
        LayeredPlate((1.0, 2.0), (1.0, 1.0), (), 0.1)
    with pytest.raises(ValueError, match="interfaces must be positive and increase"):
        LayeredPlate((1.0, 2.0, 3.0), (1.0, 1.0, 1.0), (0.2, 0.1), 0.1)
    with pytest.raises(ValueError, match="n must be finite and > 0"):
        LayeredPlate((1.0,), (0.0,), (), 0.1)
    with pytest.raises(ValueError, match="width must be > 0 m"):
        layered_plate(SOFT_OVER_HARD, [0.1], width=0.0)


# ---------------------------------------------------------------------------
# the wheel and the track
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("load", [1e3, 4e3, 1e4])
@pytest.mark.parametrize("width", WIDTHS)
def test_one_layer_n1_reproduces_bekkers_closed_form(load, width):
    """With Bekker's shallow contact the closed form is exact at n = 1."""
    plate = layered_plate([TerrainParameters(25.0, 1200.0, 1.0)], [], width=width)
    z = sinkage_rigid_wheel(load, diameter=0.94, plate=plate, geometry="shallow")
    ref = sinkage_rigid_wheel_bekker(load, diameter=0.94, width=width, kc=25.0, kphi=1200.0, n=1.0)
    assert z == pytest.approx(float(ref), rel=1e-6)


@pytest.mark.parametrize("n", [0.3, 0.5, 0.8, 1.0, 1.5, 2.0])
def test_shallow_contact_is_the_beta_function_integral_for_any_n(n):
    """W = b k sqrt(D) z0^(n+1/2) B(n+1, 1/2) / 2; the closed form has (3 - n)/3 for B/2."""
    b, D, k, z0 = 0.3, 0.94, 1500.0, 0.06
    plate = LayeredPlate((k,), (n,), (), b)
    ref = 1000 * b * k * math.sqrt(D) * z0 ** (n + 0.5) * beta(n + 1, 0.5) / 2
    assert wheel_load(z0, diameter=D, plate=plate, geometry="shallow") == pytest.approx(
        ref, rel=1e-10
    )
    closed = float(sinkage_rigid_wheel_bekker(ref, diameter=D, width=b, kc=0, kphi=k, n=n))
    gap = ((3 - n) / 3 / (beta(n + 1, 0.5) / 2)) ** (-1 / (n + 0.5)) - 1
    assert closed / z0 - 1 == pytest.approx(gap, rel=1e-9, abs=1e-12)  # 0 at n = 1 only


@pytest.mark.parametrize("layers", [SOFT_OVER_HARD, HARD_OVER_SOFT], ids=["soft-hard", "hard-soft"])
@pytest.mark.parametrize("sinkage", [0.05, 0.12, 0.2, 0.4])
def test_wheel_load_against_the_arc_by_hand(layers, sinkage):
    for b in (0.1, 0.6):
        plate = layered_plate(layers, [0.12], width=b)
        got = wheel_load(sinkage, diameter=0.94, plate=plate)
        ref = load_by_hand(layers, [0.12], width=b, diameter=0.94, sinkage=sinkage)
        assert got == pytest.approx(ref, rel=1e-9)


def test_wheel_sinkage_is_the_first_equilibrium():
    """Hard over soft: the load first rises with the sinkage, then falls past the interface."""
    layers = [TerrainParameters(0.0, 4000.0, 1.0), TerrainParameters(0.0, 100.0, 1.0)]
    plate = layered_plate(layers, [0.05], width=0.3)
    zs = np.linspace(1e-4, 0.3, 600)
    loads = np.array([wheel_load(z, diameter=1.0, plate=plate) for z in zs])
    peak = float(loads.max())
    assert loads[-1] < peak  # not monotone: two equilibria for a load below the peak
    W = 0.9 * peak
    z0 = sinkage_rigid_wheel(W, diameter=1.0, plate=plate)
    assert load_by_hand(layers, [0.05], width=0.3, diameter=1.0, sinkage=z0) == pytest.approx(
        W, rel=1e-9
    )
    assert np.all(loads[zs < z0 * (1 - 1e-6)] < W)  # none carries it earlier
    assert math.isnan(sinkage_rigid_wheel(1.01 * peak, diameter=1.0, plate=plate))


def test_track_sinkage_by_hand_and_resting_on_a_pan():
    plate = layered_plate(SOFT_OVER_HARD, [0.12], width=0.4)
    k1, k2 = 10.0 / 0.4 + 800.0, 30.0 / 0.4 + 3000.0
    assert sinkage_track(20.0, plate=plate) == pytest.approx((20.0 / k1) ** (1 / 0.9), rel=1e-14)
    q = 0.5 * (k1 * 0.12**0.9 + k2 * 0.12**1.1)  # between the pressures either side of 0.12 m
    assert sinkage_track(q, plate=plate) == 0.12
    q = 1.2 * k2 * 0.12**1.1
    assert sinkage_track(q, plate=plate) == pytest.approx((q / k2) ** (1 / 1.1), rel=1e-14)


# ---------------------------------------------------------------------------
# the effective soil
# ---------------------------------------------------------------------------


def test_effective_soil_of_one_layer_is_that_layer():
    for b in WIDTHS:
        plate = layered_plate([TerrainParameters(25.0, 1200.0, 0.85)], [], width=b)
        eff = effective_soil(plate, load=8e3, diameter=0.94)
        assert eff.kc == 0.0
        assert eff.n == pytest.approx(0.85, abs=1e-5)
        assert eff.kphi == pytest.approx(25.0 / b + 1200.0, rel=1e-4)
        assert eff.pressure_rms < 1e-4 and abs(eff.sinkage_error) < 1e-9


def test_effective_soil_is_the_constrained_least_squares_optimum():
    """Brute force over m (k from the load at each m); the misfit against quadrature by hand."""
    plate = layered_plate(SOFT_OVER_HARD, [0.12], width=0.3)
    load = wheel_load(0.2, diameter=0.94, plate=plate)
    eff = effective_soil(plate, load=load, diameter=0.94)
    assert eff.sinkage == pytest.approx(0.2, rel=1e-10)
    best = math.inf
    for m in np.linspace(*N_BOUNDS, 2901):
        k = load / wheel_load(0.2, diameter=0.94, plate=LayeredPlate((1.0,), (m,), (), 0.3))
        best = min(best, plate_misfit(plate, k, m, 0.2)[0])
    got = plate_misfit(plate, eff.kphi, eff.n, 0.2)[0]
    assert got <= best * (1 + 1e-9)
    hand = integrate.quad(lambda z: (eff.kphi * z**eff.n - plate.pressure(np.array([z]))[0]) ** 2,
                          0, 0.2, points=[0.12], epsabs=0, epsrel=1e-12)[0]  # fmt: skip
    assert got == pytest.approx(hand, rel=1e-8)
    own = integrate.quad(lambda z: plate.pressure(np.array([z]))[0] ** 2, 0, 0.2, points=[0.12])[0]
    assert eff.pressure_rms == pytest.approx(math.sqrt(hand / own), rel=1e-6)
    # the effective soil carries the load at that sinkage, by the arc integrated by hand
    one = [TerrainParameters(0.0, eff.kphi, eff.n)]
    assert load_by_hand(one, [], width=0.3, diameter=0.94, sinkage=0.2) == pytest.approx(
        load, rel=1e-8
    )


def test_effective_soil_refuses_a_wheel_that_sinks_past_its_axle():
    plate = layered_plate(HARD_OVER_SOFT, [0.12], width=0.2)
    with pytest.raises(ValueError, match=r"sinks past its axle under 1e\+06 N at width 0.2 m"):
        effective_soil(plate, load=1e6, diameter=0.94)
    with pytest.raises(ValueError, match="exactly one of diameter"):
        effective_soil(plate, load=1e3)


#: A calibration that holds phic, cc and kc/kphi (the generated one of test_hostile), so that
#: each layer's plate pressure follows from its CI; Problem() leaves them free.
CAL = dict(terrain="generated", model="rm0", phic_deg=11.0, cc=5.0, kc=50.0, kphi=1500.0, n=0.9)


@pytest.fixture(scope="module", params=["Problem()", "calibrated"])
def sc900_grounds(request):
    """The two-layer fits (`predict --layers 2`) of the SC900 pushes that BIC prefers."""
    from terracone.inverse.layered import fit_layered
    from terracone.inverse.problem import Calibration, Problem
    from terracone.io import read_ci_profiles

    path = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    problem = Problem() if request.param == "Problem()" else Problem(calibration=Calibration(**CAL))
    out = []
    for profile in read_ci_profiles(path):
        fit = fit_layered(profile, problem, layers=2)
        if fit.ok and fit.preferred_layers == 2:
            out.append((profile.id, fit.layers, fit.interfaces))
    return request.param, out


def test_must_show_effective_sinkage_within_10_percent_on_sc900_pushes(sc900_grounds):
    """Each push, each width 0.1-0.6 m: a 0.94 m wheel loaded to sink 0.5, 1.5 and 3 times the
    interface depth (at most 0.45 D) on the layered ground; the effective soil sinks within 10%."""
    which, grounds = sc900_grounds
    assert len(grounds) >= 40  # most of the 83 pushes are layered
    D, rows = 0.94, []
    for pid, layers, interfaces in grounds:
        for b in WIDTHS:
            plate = layered_plate(layers, interfaces, width=b)
            for f in (0.5, 1.5, 3.0):
                load = wheel_load(min(f * interfaces[0], 0.45 * D), diameter=D, plate=plate)
                eff = effective_soil(plate, load=load, diameter=D)
                rows.append((pid, b, f, eff.sinkage, eff.sinkage_effective, eff.sinkage_error,
                             eff.pressure_rms, eff.sinkage > interfaces[0]))  # fmt: skip
    errors = np.array([abs(r[5]) for r in rows])
    worst = rows[int(np.argmax(errors))]
    crossing = [r for r in rows if r[7]]
    print(f"\n{which}: {len(grounds)} pushes x {len(WIDTHS)} widths x 3 loads, {len(crossing)} "
          f"with the wheel in both layers; worst sinkage error {worst[5]:.2e} ({worst[0]}, "
          f"b = {worst[1]} m); pressure RMS up to {max(r[6] for r in rows):.3f}")  # fmt: skip
    assert errors.max() < 0.10
    # the wheel reaches the second layer of many pushes (elsewhere it punches through first)
    assert len(crossing) >= (40 if which == "Problem()" else 150)
    assert all(0 < r[6] < 1 for r in crossing)  # a one-layer law cannot follow the jump


# ---------------------------------------------------------------------------
# the export: --vehicle
# ---------------------------------------------------------------------------

GROUNDS = {
    "A": (SOFT_OVER_HARD, [0.12], (-34.5, 19.25)),
    "B": (HARD_OVER_SOFT, [0.15], (-34.508, 19.2533)),
    "C": ([TerrainParameters(8.0, 500.0, 1.0), TerrainParameters(40.0, 4000.0, 1.0)], [0.2],
          (-34.4967, 19.2433)),
}  # fmt: skip
WHEELED = {"name": "test truck", "kind": "wheeled", "mobility_index": 60,
           "wheel": {"load": "30 kN", "diameter": "1 m", "width": "30 cm"}}  # fmt: skip
TRACKED = {
    "name": "test tracks", "kind": "tracked",
    "mobility_index_inputs": {
        "gross_weight": "100 kN", "track_width": "40 cm", "track_contact_length": "2.5 m",
        "tracks": 2, "bogies": 10, "shoe_area": "0.05 m2", "grouser_height": "3 cm",
        "ground_clearance": "40 cm", "engine_power": "200 kW"},
}  # fmt: skip
SHEAR = ("--cohesion", "1kPa", "--friction", "30", "--janosi", "1cm")


@pytest.fixture(scope="module")
def layered_json(tmp_path_factory):
    """predict --layers 2 --json of three located two-layer profiles (CI of known layers)."""
    folder = tmp_path_factory.mktemp("layered")
    z = np.arange(0.025, 0.4501, 0.025)
    lines = ["profile,lat,lon,depth_cm,ci_kpa"]
    for pid, (layers, interfaces, (lat, lon)) in GROUNDS.items():
        layers = [TerrainParameters(p.kc, p.kphi, p.n, 2.0, 20.0) for p in layers]
        ci = layered_cone_index(z, layers, interfaces, cone=get_cone("asabe-large"))
        lines += [f"{pid},{lat},{lon},{d * 100:.4g},{c:.8g}" for d, c in zip(z, ci)]
    (folder / "l.csv").write_text("\n".join(lines) + "\n")
    out = folder / "pred.json"
    r = run("predict", folder / "l.csv", "--layers", "2", "--json", "--out", out)
    assert r.exit_code == 0, r.output
    plain = folder / "one.json"
    assert run("predict", folder / "l.csv", "--json", "--out", plain).exit_code == 0
    table = folder / "pred.parquet"
    r = run("predict", folder / "l.csv", "--layers", "2", "--parquet", table)
    assert r.exit_code == 0, r.output
    return out, plain, table


def write(tmp_path, d, name="v.json"):
    (tmp_path / name).write_text(json.dumps(d))
    return tmp_path / name


def fitted_layers(pred, pid):
    block = next(p for p in json.loads(pred.read_text())["profiles"] if p["id"] == pid)["layered"]
    layers = [TerrainParameters.from_dict(x) for x in block["layers"]]
    return layers, block["interfaces"]


def test_export_chrono_scm_writes_the_effective_soil_and_its_notes(tmp_path, layered_json):
    pred, _, _ = layered_json
    out = tmp_path / "a.json"
    r = run("export", "--results", pred, "--profile", "A", "--format", "chrono-scm", "--vehicle",
            write(tmp_path, WHEELED), "--out", out, *SHEAR)  # fmt: skip
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    eff = doc["Notes"]["effective"]
    assert {"width_m", "load_n", "sinkage_m", "error"} <= set(eff)
    assert eff["width_m"] == 0.3 and eff["load_n"] == 30e3 and eff["running_gear"] == "wheel"
    assert {"pressure_rms", "sinkage"} <= set(eff["error"])
    soil = doc["Soil parameters"]
    assert soil["Bekker Kc"] == 0.0
    assert soil["Bekker Kphi"] == pytest.approx(eff["kphi"] * 1000, rel=1e-12)
    assert soil["Bekker n exponent"] == eff["n"]
    # by hand: the layered ground carries 30 kN at sinkage_m, and so does the effective soil
    layers, interfaces = fitted_layers(pred, "A")
    z0 = eff["sinkage_m"]
    assert load_by_hand(layers, interfaces, width=0.3, diameter=1.0, sinkage=z0) == pytest.approx(
        30e3, rel=1e-7
    )
    one = [TerrainParameters(0.0, soil["Bekker Kphi"] / 1000, soil["Bekker n exponent"])]
    assert load_by_hand(one, [], width=0.3, diameter=1.0, sinkage=z0) == pytest.approx(
        30e3, rel=1e-7
    )
    assert z0 > interfaces[0]  # the wheel reaches the second layer
    assert abs(eff["error"]["sinkage"]) < 1e-6 and 0 < eff["error"]["pressure_rms"] < 1
    assert "effective soil" in r.output and "test truck's wheel: width 0.3 m" in r.output


def test_export_pychrono_every_located_push_on_the_standin(tmp_path, layered_json, monkeypatch):
    pred, _, _ = layered_json
    out = tmp_path / "site_soil.py"
    name = 'evil""" + __import__("os").system("touch PWNED") + """x\' + str(1) + \''
    r = run("export", "--results", pred, "--format", "pychrono", "--vehicle",
            write(tmp_path, {**TRACKED, "name": name}), "--out", out, *SHEAR)  # fmt: skip
    assert r.exit_code == 0, r.output
    monkeypatch.chdir(tmp_path)
    install(monkeypatch)
    spec = importlib.util.spec_from_file_location("site_soil_eff", out)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert [s[0] for s in module.SITES] == ["A", "B", "C"]
    assert len(module.EFFECTIVE) == 3
    assert all(e["vehicle"] == name for e in module.EFFECTIVE)  # data, never code
    assert not (tmp_path / "PWNED").exists()
    q = 50e3 / (0.4 * 2.5) / 1000  # one track's load over its width and contact length [kPa]
    for (pid, _, _), row, eff in zip(module.SITES, module.SOIL, module.EFFECTIVE):
        assert eff["running_gear"] == "track" and eff["width_m"] == pytest.approx(0.4)
        assert eff["load_n"] == pytest.approx(50e3) and eff["pressure_kpa"] == pytest.approx(q)
        kphi, kc, n = row[:3]
        assert kc == 0.0 and kphi / 1000 * eff["sinkage_m"] ** n == pytest.approx(q, rel=1e-9)
        layers, interfaces = fitted_layers(pred, pid)
        p = layered_plate_pressure(np.array([eff["sinkage_m"]]), layers, interfaces, width=0.4)
        assert p[0] >= q * (1 - 1e-9)  # Bekker's track: the first depth that carries q
    CALLS.clear()
    terrain = SCMTerrain(None)
    module.apply(terrain)
    assert any(name == "RegisterSoilParametersCallback" for name, _ in CALLS)


def test_export_vehicle_refusals(tmp_path, layered_json):
    pred, plain, _ = layered_json
    vehicle = write(tmp_path, WHEELED)
    out = tmp_path / "x.json"

    def refused(*args):
        r = run("export", *args, "--out", out, *SHEAR)
        assert r.exit_code != 0 and not out.exists(), r.output
        assert "Traceback" not in r.output
        return " ".join(r.output.split())

    base = ("--format", "chrono-scm", "--vehicle", vehicle)
    assert "profile 'A' has no layered fit: run `terracone predict FILE --layers 2 --json`" in (
        refused("--results", plain, "--profile", "A", *base)
    )
    assert "a terrain map's cells carry one layer" in refused("--map", tmp_path, *base[2:],
                                                              "--format", "pychrono")  # fmt: skip
    assert "--vehicle: a library terrain has one layer" in refused("--terrain", "LETE sand", *base)
    assert (
        "Error: --vehicle, --cohesion, --friction, --janosi: only with --format chrono-scm"
        in refused("--results", pred, "--profile", "A", "--format", "json", "--vehicle", vehicle)
    )
    heavy = write(tmp_path, {**WHEELED, "wheel": {**WHEELED["wheel"], "load": "1000 kN"}}, "h.json")
    assert "profile 'A': the wheel (D = 1 m) sinks past its axle under 1e+06 N" in refused(
        "--results", pred, "--profile", "A", "--format", "chrono-scm", "--vehicle", heavy
    )
    bare = write(tmp_path, {k: v for k, v in WHEELED.items() if k != "wheel"}, "w.json")
    assert "key 'wheel': missing" in refused("--results", pred, "--profile", "A", "--format",
                                              "chrono-scm", "--vehicle", bare)  # fmt: skip
    tracked = {"name": "t", "kind": "tracked", "mobility_index": 50}
    assert "a tracked vehicle's effective soil needs its track" in refused(
        "--results", pred, "--profile", "A", "--format", "chrono-scm", "--vehicle",
        write(tmp_path, tracked, "t.json"),
    )  # fmt: skip


def test_export_vehicle_from_a_parquet_table_is_refused(tmp_path, layered_json):
    _, _, table = layered_json
    r = run("export", "--results", table, "--profile", "A", "--format", "chrono-scm", "--vehicle",
            write(tmp_path, WHEELED), "--out", tmp_path / "x.json", *SHEAR)  # fmt: skip
    assert r.exit_code != 0
    assert "keeps only each layer's n, not its kc and kphi" in " ".join(r.output.split())

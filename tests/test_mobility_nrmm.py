"""terracone mobility as analysts practise it (issue 30) and careful vehicle files (issue 33).

Every number is worked by hand here, with the source of every constant:

* tracked-vehicle mobility index and VCI_1: Wong, Jayakumar, Toma and Preston-Thomas
  (2020), J. Terramechanics 87, 11-20, and FM 5-430-00-1 (1994), as transcribed in
  public code (the papers themselves could not be opened; terracone.physics.vehicle);
* wheeled-vehicle MI (Rula and Nuttall 1971 as tabulated by Wong 2008), VCI_1 (Priddy
  and Willoughby 2006) and VCI_50 (Rula and Nuttall 1971);
* the M113 (afvdatabase.com/usa/m113.html): combat weight 22,900 lb, track 15 in wide
  with a 6 in pitch, 105 in of each track on the ground, 5 road wheels per track, ground
  clearance 16.1 in, 215 hp gross, Allison TX-200-2A transmission (it "shifted
  automatically", russian-tanks.com/armored-personnel-carrier-m113.php), and a published
  ground pressure at zero penetration of 7.3 psi;
* critical layers: EN5341 (armyengineer.tpub.com), Priddy and Willoughby (2006, Fig. 2),
  FASST (ERDC/CRREL SR-04-1) (terracone.apps.trafficability);
* MAVS's units: src/mavs_python/mavs_interface.py of MAVS's public source
  (``MavsEnvironment.SetTerrainProperties``: Pa; ``MavsRp3d.SetTerrainProperties``: psi,
  times 6894.76).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import require_shared
from scipy.optimize import minimize_scalar

from terracone.apps.mavs import MAVS_PSI_TO_PA, mavs_set_terrain_properties
from terracone.apps.mobility import COARSE_NOTE, LayerChoice, evaluate_mobility
from terracone.apps.trafficability import (
    critical_layer_mean,
    critical_layer_rule,
    soil_class_of,
    uscs_class,
    weakest_layer,
)
from terracone.apps.vehicles import vehicle_from_dict
from terracone.cli import cli
from terracone.data import TerrainParameters
from terracone.physics import units as u
from terracone.physics import vehicle as v
from terracone.result import PredictionResult, PredictionResults

PSI = 6.894757293168361  # kPa per psi: 4.4482216152605 N / 0.0254^2 m^2 / 1000
SC900 = ("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")

#: The M113 of afvdatabase.com (see the module docstring).  Shoe area = width x pitch =
#: 15 x 6 = 90 in^2; grouser height: the T130E1 shoe carries a rubber pad and no figure
#: is published, so grousers lower than 1.5 in are assumed (GF = 1.0; GF = 1.1 below).
M113 = {
    "name": "M113",
    "kind": "tracked",
    "mobility_index_inputs": {
        "gross_weight": "22900 lb", "track_width": "15 in", "track_contact_length": "105 in",
        "tracks": 2, "bogies": 10, "shoe_area": "90 in2", "grouser_height": "0 in",
        "ground_clearance": "16.1 in", "engine_power": "215 hp", "transmission": "automatic",
    },
}  # fmt: skip
#: The HMMWV M1152 of docs/mobility.md (AM General's datasheet).
HMMWV = {
    "name": "HMMWV M1152",
    "kind": "wheeled",
    "mobility_index_inputs": {
        "gross_weight": "13450 lb", "axles": 2, "tires": 4, "tire_width": "12.5 in",
        "tire_diameter": "37 in", "ground_clearance": "17.4 in", "engine_power": "190 hp",
    },
    "wheel": {"load": "3363 lb", "diameter": "37 in", "width": "12.5 in"},
}  # fmt: skip


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def write(tmp_path: Path, d: dict, name: str) -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(d))
    return p


# ---------------------------------------------------------------------------
# MI, VCI_1 and VCI_50 by hand: a tracked and a wheeled vehicle
# ---------------------------------------------------------------------------


def test_mobility_index_and_vci_of_the_m113_by_hand():
    veh = vehicle_from_dict(M113, "m113.json")
    # contact pressure factor = W / (tracks x L x b) = 22900 / (2 x 105 x 15) = 22900 / 3150
    #   = 7.2698413 psi: the published 7.3 psi ground pressure at zero penetration
    assert 22900 / 3150 == pytest.approx(7.3, abs=0.05)
    # weight factor 1.0 (W < 50,000 lb); track factor 15 / 100 = 0.15; grouser factor 1.0
    # bogie factor (W / 10) / (bogies x shoe area) = 2290 / (10 x 90) = 2.5444444
    # clearance factor 16.1 / 10 = 1.61; engine factor 1.0: 215 hp / 11.45 short tons
    #   = 18.8 hp/ton >= 10; transmission factor 1.0 (automatic)
    # MI = 7.2698413 x 1.0 / (0.15 x 1.0) + 2.5444444 - 1.61 = 48.465608 + 0.9344444
    #    = 49.400053
    assert veh.mobility_index == pytest.approx(49.400053, rel=1e-7)
    # VCI_1 = 7.0 + 0.2 x 49.400053 - 39.2 / (49.400053 + 5.6) = 16.880011 - 0.7127266
    #       = 16.167284 psi = 111.4695 kPa
    vci1, why = veh.vci_of(1)
    assert why is None and vci1 / PSI == pytest.approx(16.167284, rel=1e-7)
    assert vci1 == pytest.approx(111.4695, rel=1e-6)
    # VCI_50 of a tracked vehicle: no public source could be opened, so none is given
    vci50, why = veh.vci_of(50)
    assert vci50 is None and "no public source" in why


def test_tracked_factors_by_hand():
    base = dict(track_width=15 * u.INCH, track_contact_length=105 * u.INCH, tracks=2,
                bogies=10, shoe_area=90 * u.INCH**2, grouser_height=0.0,
                ground_clearance=16.1 * u.INCH, engine_power=215 * u.HP)  # fmt: skip
    w = 22900 * u.LBF
    # grousers of 2 in (> 1.5 in): GF = 1.1 divides the first term only
    tall = v.mobility_index_tracked(w, **{**base, "grouser_height": 2 * u.INCH})
    assert tall == pytest.approx(48.465608 / 1.1 + 0.9344444, rel=1e-7)
    # 100 hp: 100 / 11.45 = 8.73 hp/ton < 10: EF = 1.05; manual: XF = 1.05
    weak = v.mobility_index_tracked(w, **{**base, "engine_power": 100 * u.HP})
    assert weak == pytest.approx(1.05 * 49.400053, rel=1e-7)
    manual = v.mobility_index_tracked(w, **base, manual_transmission=True)
    assert manual == pytest.approx(1.05 * 49.400053, rel=1e-7)
    # weight factor bands: 1.0 below 50,000 lb, 1.2 to 70,000, 1.4 to 100,000, 1.8 above
    got = v.weight_factor_tracked([49_999, 50_000, 69_999, 70_000, 99_999, 100_000, 140_000])
    assert list(got) == [1.0, 1.2, 1.2, 1.4, 1.4, 1.8, 1.8]


def test_mobility_index_and_vci_of_the_hmmwv_by_hand():
    veh = vehicle_from_dict(HMMWV, "hmmwv.json")
    # CPF = 13450 / (12.5 x 37/2 x 4) = 14.540541 psi; axle load 6.725 kips: WF = 0.033 x
    # 6.725 + 1.050 = 1.271925; TF = (10 + 12.5) / 100 = 0.225; WLF = 13.45 / 4 = 3.3625;
    # CF = 1.74; EF = 1 (28.3 hp/ton); XF = 1
    # MI = 14.540541 x 1.271925 / 0.225 + 3.3625 - 1.74 = 83.820176
    assert veh.mobility_index == pytest.approx(83.820176, rel=1e-7)
    # VCI_1 = (11.48 + 0.2 x 83.820176 - 39.2 / 87.560176) x DCF 1
    #       = (11.48 + 16.764035 - 0.447692) x 1 = 27.796343 psi = 191.649 kPa
    assert veh.vci(1) / PSI == pytest.approx(27.796343, rel=1e-6)
    # VCI_50 = 28.23 + 0.43 x 83.820176 - 92.67 / 87.490176 = 28.23 + 36.042676 - 1.059205
    #        = 63.213471 psi = 435.842 kPa
    assert veh.vci(50) / PSI == pytest.approx(63.213471, rel=1e-6)
    # the drive was not given: all axles assumed, and said
    assert veh.drive == "all" and "assumed 'all'" in veh.notes[0]


def test_a_vehicle_outside_the_domain_of_vci1_is_refused_with_the_reason(tmp_path):
    partial = {**HMMWV, "drive": "partial"}
    veh = vehicle_from_dict(partial)
    vci1, why = veh.vci_of(1)
    assert vci1 is None and "only to vehicles with all axles powered" in why
    assert veh.vci(50) == pytest.approx(63.213471 * PSI, rel=1e-6)  # VCI_50 still given
    res = located([300.0])
    doc = evaluate_mobility(res, veh, remolding_index=1.0).as_dict()
    p = doc["profiles"][0]
    assert p["vci"] is None and p["go"] is None and p["margin"] is None
    assert p["critical_layer"]["rci"] == pytest.approx(300.0)  # the RCI is still given
    assert any("all axles powered" in n and "no GO/NO-GO" in n for n in p["notes"])
    assert doc["vehicle"]["vci"] is None and "all axles powered" in doc["vehicle"]["vci_note"]
    assert doc["vehicle"]["mi"] == pytest.approx(83.820176, rel=1e-7)


# ---------------------------------------------------------------------------
# soil class
# ---------------------------------------------------------------------------


def located(cis, meta=None, z=None):
    """Profiles of constant CI [kPa] over 0-0.4 m, RI in the metadata or not."""
    z = np.linspace(0.0, 0.4, 17) if z is None else z
    out = []
    for i, c in enumerate(cis):
        out.append(PredictionResult(f"p{i}", "ok", params=TerrainParameters(102, 5301, 0.79, 1, 11),
                                    depth=z, ci=np.full(z.size, c), metadata=dict(meta or {})))  # fmt: skip
    return PredictionResults(out, {"calibration": "LETE sand"})


def test_the_same_ci_in_a_fine_and_a_coarse_soil_and_an_unknown_one():
    veh = vehicle_from_dict(HMMWV)
    res = located([300.0], {"RI": 0.8})
    fine = evaluate_mobility(res, veh, soil="fine").profiles[0]
    coarse = evaluate_mobility(res, veh, soil="coarse").profiles[0]
    unknown = evaluate_mobility(res, veh).profiles[0]
    # fine-grained: RCI = 300 x 0.8 = 240 kPa against VCI_1 = 27.796343 psi = 191.649 kPa:
    # GO by 48.351 kPa, on the 6-12 in layer of a wheeled vehicle's one pass
    assert (fine.soil_class, fine.assumed) == ("fine", False)
    assert fine.rci == pytest.approx(240.0) and fine.go is True
    assert fine.margin == pytest.approx(240.0 - 27.796343 * PSI, rel=1e-6)
    assert fine.layer == pytest.approx((6 * u.INCH, 12 * u.INCH))
    # coarse-grained: rated by CI on 0-6 in, no RCI (no remolding index applies), and no
    # VCI, GO or margin (no public source of NRMM's coarse-grained VCI relations)
    assert (coarse.soil_class, coarse.assumed) == ("coarse", False)
    assert coarse.ci == pytest.approx(300.0) and coarse.rci is None and coarse.ri is None
    assert coarse.vci is None and coarse.go is None and coarse.margin is None
    assert coarse.layer == pytest.approx((0.0, 6 * u.INCH)) and coarse.layer_rule == "coarse"
    assert COARSE_NOTE in coarse.notes
    # unknown: assumed fine-grained, and said
    assert (unknown.soil_class, unknown.assumed) == ("fine", True)
    assert unknown.go is True and any("assumed fine-grained" in n for n in unknown.notes)


def test_the_soil_class_from_uscs_metadata():
    veh = vehicle_from_dict(HMMWV)
    sand = evaluate_mobility(located([300.0], {"USCS": "SP"}), veh).as_dict()["profiles"][0]
    clay = evaluate_mobility(located([300.0], {"uscs": "CH", "RI": 1}), veh).as_dict()
    assert (sand["soil_class"], sand["assumed"], sand["go"]) == ("coarse", False, None)
    assert clay["profiles"][0]["soil_class"] == "fine" and clay["profiles"][0]["go"] is True
    assert uscs_class("SM-SC") == "coarse" and uscs_class("cl-ml") == "fine"
    assert uscs_class("GW") == "coarse" and uscs_class("Pt") == "fine"
    cls, assumed, note = soil_class_of({"uscs": "loam"})
    assert (cls, assumed) == ("fine", True) and "'loam' is not a USCS group symbol" in note


# ---------------------------------------------------------------------------
# the critical layer by rule, by weakest layer, and --layer
# ---------------------------------------------------------------------------


def sc900_file(tmp_path_factory):
    src = require_shared(*SC900)
    tmp = tmp_path_factory.mktemp("marsden")
    small = tmp / "marsden5.txt"
    small.write_text("".join(src.read_text().splitlines(keepends=True)[:26]))
    out = tmp / "pred.json"
    res = run("predict", small, "--json", "--out", out)
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def marsden(tmp_path_factory):
    """predict JSON of the first five pushes of the Marsden SC900 export."""
    return sc900_file(tmp_path_factory)


def p3_of(doc):
    return next(p for p in doc["profiles"] if p["id"].endswith("0003-N1"))


def test_the_critical_layer_rule_of_three_vehicles(marsden, tmp_path):
    hm, m113 = write(tmp_path, HMMWV, "hmmwv.json"), write(tmp_path, M113, "m113.json")
    heavy = {**M113, "name": "heavy tracked",
             "mobility_index_inputs": {**M113["mobility_index_inputs"], "gross_weight": "60000 lb"}}  # fmt: skip
    cases = [
        (hm, "1", [], "fine-wheeled-1pass", (6, 12)),  # Priddy and Willoughby (2006), Fig. 2
        (m113, "1", [], "fine-tracked-1pass", (0, 6)),  # EN5341: 46,000-lb M37, one pass
        (m113, "50", [], "fine-tracked-50pass", (6, 12)),  # EN5341: the same, 50 passes
        (hm, "1", ["--soil", "coarse"], "coarse", (0, 6)),  # FASST: top 15 cm
        (write(tmp_path, heavy, "heavy.json"), "1", [], "fine-tracked-1pass", (0, 6)),
    ]
    for path, passes, extra, rule, (top_in, bottom_in) in cases:
        res = run("mobility", marsden, "--vehicle", path, "--passes", passes,
                  "--remolding-index", "1", *extra, "--json")  # fmt: skip
        assert res.exit_code == 0, res.output
        doc = json.loads(res.output)
        cl = p3_of(doc)["critical_layer"]
        assert cl["rule"] == rule, (path, passes)
        assert (cl["top"], cl["bottom"]) == pytest.approx((top_in * 0.0254, bottom_in * 0.0254))
        assert cl["source"]
        assert doc["settings"]["critical_layer"] == {"mode": "rule"}
    # the heavy tracked vehicle: the rule's example weighs 46,000 lb, and the run says so
    assert any("comes from a 46,000-lb vehicle" in n for n in doc["notes"])


def test_the_rule_layer_of_a_real_push_by_hand(marsden, tmp_path):
    """Push 0003-N1, 6-12 in = 15.24-30.48 cm: readings every 2.5 cm, 794 at 15 cm, 1000,
    1138, 1173, 1104, 759, 862 at 17.5 to 30 cm, 828 at 32.5 cm."""
    # CI(15.24) = 794 + 206 x 0.24/2.5 = 813.776; CI(30.48) = 862 - 34 x 0.48/2.5 = 855.472
    # trapezoids [cm kPa]: 2.26 x 906.888 = 2049.56688; 2.5 x (1069 + 1155.5 + 1138.5
    # + 931.5 + 810.5) = 12762.5; 0.48 x 858.736 = 412.19328; sum 15224.26016 / 15.24
    # = 998.96720 kPa
    res = run("mobility", marsden, "--vehicle", write(tmp_path, HMMWV, "h.json"),
              "--remolding-index", "0.8", "--json")  # fmt: skip
    p = p3_of(json.loads(res.output))
    assert p["critical_layer"]["ci"] == pytest.approx(998.96720, rel=1e-7)
    # RCI = 0.8 x 998.9672 = 799.17376 kPa >= VCI_1 191.649 kPa: GO by 607.525 kPa
    assert p["critical_layer"]["rci"] == pytest.approx(799.17376, rel=1e-7)
    assert p["go"] is True and p["margin"] == pytest.approx(799.17376 - 27.796343 * PSI, rel=1e-6)


def test_the_m113_on_a_real_push_by_hand(marsden, tmp_path):
    """docs/mobility.md: the M113, one pass, RI 0.8, on push 0003-N1: the rule's 0-6 in
    layer (tracked, one pass), CI 805.14653 kPa (test_mobility.py, by hand), RCI = 0.8 x
    805.14653 = 644.11722 kPa against VCI_1 = 111.4695 kPa: GO by 532.6477 kPa."""
    res = run("mobility", marsden, "--vehicle", write(tmp_path, M113, "m113.json"),
              "--remolding-index", "0.8", "--soil", "fine", "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    p = p3_of(doc)
    assert (p["soil_class"], p["assumed"]) == ("fine", False)
    assert p["critical_layer"]["rule"] == "fine-tracked-1pass"
    assert p["critical_layer"]["rci"] == pytest.approx(644.11722, rel=1e-7)
    assert p["vci"] == pytest.approx(16.167284 * PSI, rel=1e-7)
    assert p["go"] is True and p["margin"] == pytest.approx(532.6477, rel=1e-6)
    assert doc["vehicle"]["kind"] == "tracked" and doc["vehicle"]["wheel"] is None
    assert any("gives no wheel" in n for n in p["notes"])


def brute_force_weakest(z, c, t, top, bottom):
    """The weakest layer by a grid of 20,001 starts, polished by a bounded minimiser."""
    starts = np.linspace(top, bottom - t, 20001)
    means = [critical_layer_mean(z, c, s, s + t) for s in starts]
    i = int(np.argmin(means))
    lo, hi = starts[max(i - 1, 0)], starts[min(i + 1, len(starts) - 1)]
    if hi > lo:
        best = minimize_scalar(lambda s: critical_layer_mean(z, c, s, s + t), bounds=(lo, hi),
                               method="bounded", options={"xatol": 1e-12})  # fmt: skip
        if best.fun < means[i]:
            return float(best.x), float(best.fun)
    return float(starts[i]), float(means[i])


def test_the_weakest_layer_of_a_real_push(marsden, tmp_path):
    """Push 0003-N1: the weakest 5 cm within 10-30.48 cm, by hand and by brute force."""
    res = run("mobility", marsden, "--vehicle", write(tmp_path, HMMWV, "h.json"),
              "--remolding-index", "1", "--critical-layer", "weakest:5cm:10cm:12in",
              "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    p = p3_of(doc)
    # CI falls 897 -> 794 over 10-12.5 cm and climbs 794 -> 1000 over 15-17.5 cm:
    # F'(t) = CI(t + 5 cm) - CI(t) = 0 at t = 10 + 103 / 12360 x 100 = 10.8333 cm; the layer
    # 10.8333-15.8333 cm: 1.6667 x 828.333 + 2.5 x 794 + 0.8333 x 828.333 = 4055.833 cm kPa,
    # a mean of 811.1667 kPa
    cl = p["critical_layer"]
    assert cl["top"] == pytest.approx(0.108333333, rel=1e-7)
    assert cl["bottom"] == pytest.approx(0.158333333, rel=1e-7)
    assert cl["ci"] == pytest.approx(811.1666667, rel=1e-8)
    assert cl["rule"] == "weakest:0.05m in 0.1-0.3048m"
    z = np.arange(14) * 0.025
    c = np.array([310, 414, 1208, 966, 897, 794, 794, 1000, 1138, 1173, 1104, 759, 862, 828.0])
    t_ref, m_ref = brute_force_weakest(z, c, 0.05, 0.10, 12 * u.INCH)
    assert cl["ci"] <= m_ref * (1 + 1e-9) and cl["ci"] == pytest.approx(m_ref, rel=1e-9)
    assert cl["top"] == pytest.approx(t_ref, abs=1e-6)
    # the default window (0-12 in) and 6 in: the weakest 6 in of this push is its top 6 in
    got = weakest_layer(z, c, 6 * u.INCH, 0.0, 12 * u.INCH)
    assert got[0] == 0.0 and got[2] == pytest.approx(805.14653, rel=1e-7)
    assert doc["settings"]["critical_layer"]["mode"] == "weakest"


def test_weakest_layer_against_brute_force_on_random_profiles():
    rng = np.random.default_rng(3)
    for _ in range(20):
        z = np.sort(rng.uniform(0, 0.45, 12))
        z[0] = 0.0
        c = rng.uniform(50, 2000, z.size)
        t = rng.uniform(0.02, 0.15)
        got = weakest_layer(z, c, t, 0.0, float(z[-1]))
        t_ref, m_ref = brute_force_weakest(z, c, t, 0.0, float(z[-1]))
        assert got[2] <= m_ref * (1 + 1e-9) and got[2] == pytest.approx(m_ref, rel=1e-7)


def test_layer_overrides_the_rule_and_bad_critical_layer_options(marsden, tmp_path):
    path = write(tmp_path, HMMWV, "h.json")
    res = run("mobility", marsden, "--vehicle", path, "--critical-layer", "weakest:6in",
              "--layer", "0:6in", "--json")  # fmt: skip
    p = p3_of(json.loads(res.output))
    assert p["critical_layer"]["rule"] == "--layer"
    assert p["critical_layer"]["ci"] == pytest.approx(805.14653, rel=1e-7)
    for bad in ("weakest", "weakest:", "strongest:6in", "weakest:20in"):
        res = run("mobility", marsden, "--vehicle", path, "--critical-layer", bad)
        assert res.exit_code != 0 and "--critical-layer" in res.output, bad
        assert "Traceback" not in res.output
    with pytest.raises(ValueError, match="thickness > 0 within the window"):
        LayerChoice("weakest", thickness=0.4)
    assert critical_layer_rule("coarse", "tracked", 50).rule == "coarse"


# ---------------------------------------------------------------------------
# MAVS
# ---------------------------------------------------------------------------


def test_mavs_set_terrain_properties_against_mavs_own_unit_conversions(marsden, tmp_path):
    out = tmp_path / "surface.json"
    res = run("export", "--results", marsden, "--profile", "marsden5/0003-N1", "--format",
              "mavs", "--material", "sand", "--out", out, "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    stp = doc["set_terrain_properties"]
    assert stp == json.loads(out.read_text())["terracone"]["set_terrain_properties"]
    env, veh = stp["environment"], stp["vehicle"]
    # the 0-6 in CI of push 0003-N1, 805.14653 kPa (test_mobility.py, by hand):
    # MavsEnvironment.SetTerrainProperties(type, strength): strength "in Cone-Index (Pascals)"
    assert (env["type"], env["unit"]) == ("sand", "Pa")
    assert env["strength"] == pytest.approx(805146.53, rel=1e-7)
    # MavsRp3d.SetTerrainProperties(..., soil_type, soil_strength): psi, and MAVS passes
    # 6894.76 * soil_strength on as Pa; its factor is rounded, so within 4e-7
    assert (veh["soil_type"], veh["unit"]) == ("sand", "psi")
    assert veh["soil_strength"] == pytest.approx(805.14653 / PSI, rel=1e-7)
    assert MAVS_PSI_TO_PA * veh["soil_strength"] == pytest.approx(env["strength"], rel=4e-7)
    # the scene entry says the same strength in psi (MAVS's loader: 6894.76 * Cone Index)
    assert doc["Surface Mesh"][0]["Cone Index"] == pytest.approx(veh["soil_strength"], rel=1e-12)
    # and stderr tells the user which calls reach the tyres
    assert "does not pass it to the vehicle" in res.stderr
    assert "env.SetTerrainProperties('sand', 805147)" in res.stderr


def test_mavs_set_terrain_properties_of_clay_by_hand():
    got = mavs_set_terrain_properties(644.117, "clay")
    # 644.117 kPa = 644117 Pa = 644.117 / 6.894757293 = 93.42130 psi
    assert got["environment"]["strength"] == pytest.approx(644117.0)
    assert got["vehicle"]["soil_strength"] == pytest.approx(93.42130, rel=1e-6)
    with pytest.raises(ValueError, match="MAVS material"):
        mavs_set_terrain_properties(100.0, "dry")


def test_export_json_only_with_mavs(marsden, tmp_path):
    res = run("export", "--results", marsden, "--format", "json", "--out", tmp_path / "x",
              "--json")  # fmt: skip
    assert res.exit_code != 0 and "--json: only with --format mavs" in res.output


# ---------------------------------------------------------------------------
# issue 33: careless vehicle files are refused, one line naming the file and the key
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "change, key, message",
    [
        ({"tire_deflection_ration": 0.3}, "tire_deflection_ration",
         "unknown key (did you mean 'tire_deflection_ratio'?)"),
        ({"wheel": {**HMMWV["wheel"], "load": "1e300 N"}}, "wheel.load",
         "is outside the physical range (0, 1e+07] N"),
        ({"wheel": {**HMMWV["wheel"], "diameter": 1e-300}}, "wheel.diameter",
         "is outside the physical range [0.02, 10] m"),
        ({"mobility_index_inputs": {**HMMWV["mobility_index_inputs"], "axels": 2}},
         "mobility_index_inputs.axels", "unknown key (did you mean 'axles'?)"),
        ({"mobility_index_inputs": {**HMMWV["mobility_index_inputs"], "gross_weight": "1e9 kN"}},
         "mobility_index_inputs.gross_weight", "outside the physical range"),
        ({"drive": "front"}, "drive", "expected 'all' or 'partial'"),
    ],
)  # fmt: skip
def test_careless_vehicle_files_are_refused(marsden, tmp_path, change, key, message):
    path = write(tmp_path, {**HMMWV, **change}, "bad.json")
    res = run("mobility", marsden, "--vehicle", path)
    assert res.exit_code != 0
    errors = [line for line in res.output.splitlines() if line.startswith("Error")]
    assert len(errors) == 1, res.output
    assert f"vehicle file {path}: key {key!r}: " in errors[0] and message in errors[0]
    assert "Traceback" not in res.output


def test_a_tracked_vehicle_refuses_wheeled_keys():
    with pytest.raises(ValueError, match="key 'tire_deflection_ratio': unknown key"):
        vehicle_from_dict({**M113, "tire_deflection_ratio": 0.15}, "m.json")
    with pytest.raises(ValueError, match="key 'mobility_index_inputs.shoe_area': missing"):
        inputs = {k: x for k, x in M113["mobility_index_inputs"].items() if k != "shoe_area"}
        vehicle_from_dict({**M113, "mobility_index_inputs": inputs}, "m.json")
    with pytest.raises(ValueError, match="shoe_area': unknown area unit 'in' in '90 in'"):
        inputs = {**M113["mobility_index_inputs"], "shoe_area": "90 in"}
        vehicle_from_dict({**M113, "mobility_index_inputs": inputs}, "m.json")

"""terracone mobility: NRMM go/no-go and Bekker's rigid wheel (issue 25).

Every number is checked against arithmetic written out here (the formulas of
Priddy and Willoughby 2006, Rula and Nuttall 1971 as tabulated by Wong, and
Bekker's rigid wheel), against quadrature (the compaction resistance is the
work of making the rut), against a real SC900 push worked by hand, or
against generated profiles of known truth (LETE sand) for the posterior
bands.  MAVS is not installed here: its export is read the way MAVS's own
source reads a scene (``"Surface Mesh"`` entries, ``"Material"``,
``"Cone Index"`` times 6894.76 to Pa).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import require_shared
from scipy.integrate import quad

from terracone.apps.library import reference_records
from terracone.apps.mavs import write_mavs
from terracone.apps.mobility import evaluate_mobility
from terracone.apps.trafficability import critical_layer_mean
from terracone.apps.vehicles import vehicle_from_dict
from terracone.apps.workflow import predict_profiles
from terracone.cli import cli
from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.predict import RunSettings
from terracone.inverse.problem import Calibration, CalibrationPrior, Problem
from terracone.io import read_ci_profiles
from terracone.physics import units as u
from terracone.physics import vehicle as v
from terracone.physics.cone import cone_index_huang
from terracone.report.mobility import mobility_document
from terracone.result import (
    PredictionResult,
    PredictionResults,
    read_results,
    write_json,
    write_parquet,
)

PSI = 6.894757293168361  # kPa per psi: 4.4482216152605 N / 0.0254^2 m^2 / 1000
SC900 = ("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")

VEHICLE = {  # MI given: VCI_1 = 132.566 kPa at delta/h = 0.30 (test_vci1_at_mi_60_...)
    "name": "test truck",
    "kind": "wheeled",
    "mobility_index": 60,
    "tire_deflection_ratio": 0.30,
    "wheel": {"load": "10 kN", "diameter": "1 m", "width": "30 cm"},
}
VCI1_60_030 = 19.227097 * PSI  # kPa, by hand below


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def write_vehicle(tmp_path: Path, d=VEHICLE, name="vehicle.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(d))
    return p


# ---------------------------------------------------------------------------
# NRMM formulas by hand
# ---------------------------------------------------------------------------


def test_vci1_at_mi_60_with_tyre_deflection_030_by_hand():
    # DCF = (0.15 / 0.30)^0.25 = 0.5^0.25 = 0.8408964
    assert float(v.deflection_correction_factor(0.30)) == pytest.approx(0.8408964, rel=1e-7)
    # MI = 60 <= 115: 11.48 + 0.2*60 - 39.2/(60 + 3.74) = 23.48 - 0.6149984 = 22.8650016 psi
    # times the DCF: 22.8650016 * 0.8408964 = 19.227097 psi = 132.5662 kPa
    vci = float(v.vci1_priddy_willoughby(60.0, 0.30))
    assert vci / PSI == pytest.approx(19.227097, rel=1e-6)
    assert vci == pytest.approx(132.5662, rel=1e-6)
    # at the nominal 15% deflection the DCF is 1: 22.8650016 psi
    assert float(v.vci1_priddy_willoughby(60.0)) / PSI == pytest.approx(22.8650016, rel=1e-8)


def test_vci1_power_law_above_mi_115_and_vci50_by_hand():
    # MI = 150 > 115: 4.1 * 150^0.446; ln 150 = 5.0106353, * 0.446 = 2.2347433,
    # exp = 9.344083, * 4.1 = 38.31074 psi
    assert float(v.vci1_priddy_willoughby(150.0)) / PSI == pytest.approx(38.31074, rel=1e-6)
    # VCI_50 at MI = 60: 28.23 + 0.43*60 - 92.67/(60 + 3.67) = 54.03 - 1.4554735 = 52.5745 psi
    assert float(v.vci50_rula_nuttall(60.0)) / PSI == pytest.approx(52.574527, rel=1e-7)


@pytest.mark.parametrize("ratio", [0.0, -0.1, 1.0, float("nan")])
def test_tyre_deflection_ratio_outside_0_1_is_refused(ratio):
    with pytest.raises(ValueError, match=r"delta/h must lie in \(0, 1\)"):
        v.deflection_correction_factor(ratio)


def hmmwv_inputs():
    """HMMWV M1152 (AM General's M1152 datasheet): 13,450 lb on 2 axles, four 37x12.50R16.5
    tyres, 17.4 in clearance, 190 hp, automatic transmission."""
    return dict(
        axles=2,
        tires=4,
        tire_width=12.5 * u.INCH,
        tire_diameter=37.0 * u.INCH,
        ground_clearance=17.4 * u.INCH,
        engine_power=190.0 * u.HP,
    )


def test_mobility_index_of_the_hmmwv_m1152_by_hand():
    # contact pressure factor 13450 / (12.5 * 37/2 * 4) = 13450 / 925 = 14.540541 psi
    # weight factor: axle load 6.725 kips in 2-13.5: 0.033 * 6.725 + 1.050 = 1.271925
    # tyre factor (10 + 12.5)/100 = 0.225; grouser factor 1 (no chains)
    # wheel load factor 13.45 kips / (2 * 2) = 3.3625; clearance factor 17.4/10 = 1.74
    # engine factor 1 (190 hp / 6.725 short tons = 28.25 hp/ton >= 10); automatic: 1
    # MI = 14.540541 * 1.271925 / 0.225 + 3.3625 - 1.74 = 82.197676 + 1.6225 = 83.820176
    mi = v.mobility_index_wheeled(13450 * u.LBF, **hmmwv_inputs())
    assert mi == pytest.approx(83.820176, rel=1e-7)
    # VCI_1 = 11.48 + 0.2 * 83.820176 - 39.2 / 87.560176 = 27.7962 psi = 191.65 kPa and
    # VCI_50 = 28.23 + 0.43 * 83.820176 - 92.67 / 87.490176 = 63.2126 psi = 435.84 kPa: an
    # independent application of the same formulas to the M1152 (a public RCI trafficability
    # model, University of Tartu course project, 2026) reports 191.6 and 435.8 kPa.
    assert float(v.vci1_priddy_willoughby(mi)) == pytest.approx(191.65, abs=0.01)
    assert float(v.vci50_rula_nuttall(mi)) == pytest.approx(435.84, abs=0.01)


def test_mobility_index_factors_by_hand():
    base = v.mobility_index_wheeled(13450 * u.LBF, **hmmwv_inputs())
    # manual transmission: the whole index times 1.05
    manual = v.mobility_index_wheeled(13450 * u.LBF, **hmmwv_inputs(), manual_transmission=True)
    assert manual == pytest.approx(1.05 * base, rel=1e-12)
    # 60 hp: 60 / 6.725 = 8.92 hp per short ton < 10: engine factor 1.05
    weak = {**hmmwv_inputs(), "engine_power": 60 * u.HP}
    assert v.mobility_index_wheeled(13450 * u.LBF, **weak) == pytest.approx(1.05 * base)
    # chains: grouser factor 1.05 divides the first term only: 82.197676/1.05 + 1.6225
    chained = v.mobility_index_wheeled(13450 * u.LBF, **hmmwv_inputs(), chains=True)
    assert chained == pytest.approx(82.197676 / 1.05 + 1.6225, rel=1e-7)


def test_weight_factor_pieces_meet_at_the_breaks():
    """The tabulated pieces are one curve: at 2, 13.5, 20 and 31.5 kips they agree to 0.03."""
    for x in (2.0, 13.5, 20.0, 31.5):
        left, right = v.weight_factor_wheeled([x - 1e-9, x + 1e-9])
        assert abs(left - right) < 0.03, x
    # by hand inside the pieces: 0.553*1, 0.033*10 + 1.05, 0.142*15 - 0.42, 0.278*25 - 3.115,
    # 0.836*40 - 20.686
    got = v.weight_factor_wheeled([1.0, 10.0, 15.0, 25.0, 40.0])
    assert got == pytest.approx([0.553, 1.38, 1.71, 3.835, 12.754], rel=1e-12)


def test_rating_cone_index_and_its_range():
    assert float(v.rating_cone_index(500.0, 0.8)) == 400.0
    for ri in (0.0, 2.01, -1.0):
        with pytest.raises(ValueError, match=r"remolding index must lie in \(0, 2\]"):
            v.rating_cone_index(500.0, ri)


# ---------------------------------------------------------------------------
# Bekker's rigid wheel
# ---------------------------------------------------------------------------


def lete():
    return {r.name: r for r in reference_records()}["LETE sand"].params


def test_wheel_sinkage_and_resistance_on_lete_sand_by_hand():
    p = lete()  # Wong's LETE sand: n = 0.79, kc = 102 kN/m^1.79, kphi = 5301 kN/m^2.79
    assert (p["n"], p["kc"], p["kphi"]) == (0.79, 102.0, 5301.0)
    # 1 m by 0.3 m wheel under 10 kN: kc + b kphi = 102 + 0.3 * 5301 = 1692.3 kN/m^1.79
    # 3W / ((3 - n)(kc + b kphi) sqrt(D)) = 30 / (2.21 * 1692.3 * 1) = 0.00802143 m^1.29
    # z0 = 0.00802143^(2/2.58) = exp(0.7751938 * -4.825639) = exp(-3.740805) = 0.02373498 m
    z = float(
        v.sinkage_rigid_wheel_bekker(10e3, diameter=1.0, width=0.3, kc=102, kphi=5301, n=0.79)
    )
    assert z == pytest.approx(0.02373498, rel=1e-6)
    # Rc = 1692.3 * z0^1.79 / 1.79 = 1692.3 * exp(1.79 * -3.740805) / 1.79
    #    = 1692.3 * 0.001235794 / 1.79 = 1.168343 kN
    r = float(v.compaction_resistance_bekker(z, width=0.3, kc=102, kphi=5301, n=0.79))
    assert r == pytest.approx(1168.343, rel=1e-6)


def test_compaction_resistance_is_the_work_of_making_the_rut():
    """Rc = b * integral_0^z0 (kc/b + kphi) z^n dz (quadrature) for a few terrains."""
    for kc, kphi, n, b in (
        (102, 5301, 0.79, 0.3),
        (4.37, 196.72, 1.6, 0.5),
        (52.5, 1128, 0.9, 0.2),
    ):
        z0 = float(v.sinkage_rigid_wheel_bekker(8e3, diameter=1.2, width=b, kc=kc, kphi=kphi, n=n))
        work, _ = quad(lambda z, b=b, kc=kc, kphi=kphi, n=n: b * (kc / b + kphi) * z**n, 0, z0)
        rc = float(v.compaction_resistance_bekker(z0, width=b, kc=kc, kphi=kphi, n=n))
        assert rc == pytest.approx(1000.0 * work, rel=1e-9)


# ---------------------------------------------------------------------------
# the critical layer
# ---------------------------------------------------------------------------


def test_critical_layer_mean_by_hand_and_too_shallow():
    # readings 100, 200, 400 kPa at 0, 0.1, 0.2 m; layer 0.05-0.15 m:
    # CI(0.05) = 150, CI(0.15) = 300; trapezoids (150+200)/2*0.05 + (200+300)/2*0.05 = 21.25
    # kPa m over 0.1 m: 212.5 kPa
    assert critical_layer_mean([0, 0.1, 0.2], [100, 200, 400], 0.05, 0.15) == pytest.approx(212.5)
    assert critical_layer_mean([0, 0.1, 0.2], [100, 200, 400], 0.0, 0.2) == pytest.approx(225.0)
    assert critical_layer_mean([0, 0.1, 0.2], [100, 200, 400], 0.05, 0.25) is None  # too shallow
    assert critical_layer_mean([0.02, 0.1, 0.2], [100, 200, 400], 0.0, 0.1) is None  # starts low


def sc900_profiles():
    path = require_shared(*SC900)
    return [p for p in read_ci_profiles(path, on_error="collect") if isinstance(p, CIProfile)]


def test_critical_layer_mean_of_a_real_sc900_push_by_hand():
    """Third push of the Marsden SC900 export (file line 24), 0-6 in (0-15.24 cm)."""
    prof = {p.id.rsplit("/", 1)[1]: p for p in sc900_profiles()}["0003-N1"]
    assert list(prof.ci[:8]) == [310, 414, 1208, 966, 897, 794, 794, 1000]
    # readings every 2.5 cm from 0 to 15 cm: 310, 414, 1208, 966, 897, 794, 794 kPa, and 1000 at
    # 17.5 cm, so CI(15.24 cm) = 794 + (1000 - 794) * 0.24/2.5 = 813.776 kPa.
    # trapezoids [cm kPa]: 2.5 * (362 + 811 + 1087 + 931.5 + 845.5 + 794) = 12077.5,
    # plus 0.24 * (794 + 813.776)/2 = 192.93312: 12270.43312 cm kPa / 15.24 cm = 805.14653 kPa
    got = critical_layer_mean(prof.depth, prof.ci, 0.0, 6 * u.INCH)
    assert got == pytest.approx(805.14653, rel=1e-7)
    # the first push ends at 15.0 cm: too shallow for 0-15.24 cm, not extrapolated
    first = {p.id.rsplit("/", 1)[1]: p for p in sc900_profiles()}["0001-N1"]
    assert first.depth[-1] == pytest.approx(0.15)
    assert critical_layer_mean(first.depth, first.ci, 0.0, 6 * u.INCH) is None


# ---------------------------------------------------------------------------
# the command on the Marsden SC900 export
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def marsden(tmp_path_factory):
    """predict JSON of the first five pushes of the Marsden export (a copy in a tmp folder)."""
    src = require_shared(*SC900)
    tmp = tmp_path_factory.mktemp("marsden")
    small = tmp / "marsden5.txt"
    small.write_text("".join(src.read_text().splitlines(keepends=True)[:26]))
    out = tmp / "pred.json"
    res = run("predict", small, "--json", "--out", out)
    assert res.exit_code == 0, res.output
    return out


#: Five generated pushes, CI = a + b z [kPa] read every 2.5 cm from 0 to the depth given [m]:
#: s1 stops at 15 cm (too shallow for 0-6 in), s2 at 20 cm (too shallow for 6-12 in).
LINEAR = {
    "s1": (0.15, 250.0, 2000.0),
    "s2": (0.20, 280.0, 2500.0),
    "s3": (0.45, 300.0, 3000.0),
    "s4": (0.45, 350.0, 2000.0),
    "s5": (0.45, 400.0, 1500.0),
}


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """predict JSON of the five LINEAR pushes (a CSV made here: no real data needed)."""
    tmp = tmp_path_factory.mktemp("synthetic")
    rows = ["# SYNTHETIC DATA: CI = a + b z", "profile,depth_m,ci_kpa"]
    for pid, (bottom, a, b) in LINEAR.items():
        for k in range(round(bottom / 0.025) + 1):
            rows.append(f"{pid},{0.025 * k:.3f},{a + b * 0.025 * k:.2f}")
    src = tmp / "synthetic.csv"
    src.write_text("\n".join(rows) + "\n")
    out = tmp / "pred.json"
    res = run("predict", src, "--json", "--out", out)
    assert res.exit_code == 0, res.output
    return out


def test_cli_end_to_end_on_the_marsden_sc900_file_with_an_ri(marsden, tmp_path):
    out = tmp_path / "mob.json"
    res = run("mobility", marsden, "--vehicle", write_vehicle(tmp_path), "--remolding-index",
              "0.8", "--layer", "0:6in", "--json", "--out", out)  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    cl = doc["settings"]["critical_layer"]
    assert cl == {"mode": "layer", "top": 0.0, "bottom": pytest.approx(0.1524)}
    assert doc["schema"] == "terracone.mobility/1" and doc["command"] == "mobility"
    assert doc["vehicle"]["vci"] == pytest.approx(VCI1_60_030, rel=1e-6)
    by = {p["id"].rsplit("/", 1)[1]: p for p in doc["profiles"]}
    p3 = by["0003-N1"]
    assert p3["critical_layer"]["ci"] == pytest.approx(805.14653, rel=1e-7)  # by hand above
    assert p3["critical_layer"]["rci"] == pytest.approx(0.8 * 805.14653, rel=1e-7)
    assert p3["go"] is True
    assert p3["margin"] == pytest.approx(0.8 * 805.14653 - VCI1_60_030, rel=1e-6)
    assert p3["critical_layer"]["top"] == 0 and p3["critical_layer"]["bottom"] == pytest.approx(
        0.1524
    )
    assert p3["critical_layer"]["rule"] == "--layer"
    assert p3["wheel"]["sinkage"] > 0 and p3["wheel"]["resistance"] > 0
    first = by["0001-N1"]
    assert first["critical_layer"]["status"] == "too shallow" and first["go"] is None
    assert any("too shallow" in n for n in first["notes"])
    # the table says the same in US units: CI in psi
    res = run("mobility", marsden, "--vehicle", write_vehicle(tmp_path), "--remolding-index",
              "0.8", "--units", "us", "--layer", "0:6in")  # fmt: skip
    assert res.exit_code == 0, res.output
    row = next(line for line in res.output.splitlines() if "0003-N1" in line)
    assert f"{805.14653 / PSI:.4g}" in row and "GO" in row


def test_cli_without_an_ri_decides_nothing(synthetic, tmp_path):
    res = run("mobility", synthetic, "--vehicle", write_vehicle(tmp_path), "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    decided = [p for p in doc["profiles"] if p["critical_layer"]["ci"] is not None]
    # 6-12 in (the rule of a wheeled vehicle, one pass): s1 and s2 are too shallow
    assert [p["id"] for p in decided] == ["s3", "s4", "s5"]
    # the mean of a + b z over 0.1524-0.3048 m is a + b 0.2286 (the trapezoids are exact)
    for p in decided:
        _, a, b = LINEAR[p["id"]]
        assert p["critical_layer"]["ci"] == pytest.approx(a + b * 0.2286, rel=1e-12)
        assert p["critical_layer"]["rci"] is None and p["go"] is None and p["margin"] is None
        assert any(n.startswith("no remolding index") for n in p["notes"])
    text = run("mobility", synthetic, "--vehicle", write_vehicle(tmp_path)).output
    assert "no remolding index (--remolding-index or an RI column in the metadata)" in text


def test_fifty_passes_use_the_6_to_12_in_layer_and_vci50(synthetic, tmp_path):
    res = run("mobility", synthetic, "--vehicle", write_vehicle(tmp_path), "--passes", "50",
              "--remolding-index", "1", "--json")  # fmt: skip
    doc = json.loads(res.output)
    assert doc["vehicle"]["vci"] == pytest.approx(52.574527 * PSI, rel=1e-7)
    by = {q["id"]: q for q in doc["profiles"]}
    assert by["s2"]["critical_layer"]["status"] == "too shallow"  # ends at 20 cm < 30.48 cm
    # s3: the mean of 300 + 3000 z over 0.1524-0.3048 m is CI(0.2286 m) = 985.8 kPa
    assert by["s3"]["critical_layer"]["ci"] == pytest.approx(985.8, rel=1e-12)


def test_layer_deeper_than_every_profile_is_an_error(synthetic, tmp_path):
    res = run("mobility", synthetic, "--vehicle", write_vehicle(tmp_path), "--layer", "40cm:60cm")
    assert res.exit_code != 0
    assert "critical layer 0.4-0.6 m is deeper than every profile" in res.output
    assert "0.45 m" in res.output and "Traceback" not in res.output


@pytest.mark.parametrize("ri", ["0", "2.5", "-1"])
def test_remolding_index_outside_0_2_is_an_error(synthetic, tmp_path, ri):
    res = run("mobility", synthetic, "--vehicle", write_vehicle(tmp_path), "--remolding-index", ri)
    assert res.exit_code != 0
    assert "--remolding-index" in res.output and "outside (0, 2]" in res.output


def located_results(ri=None):
    z = np.linspace(0.0, 0.36, 13)
    out = []
    for i, (site, scale) in enumerate([("A", 1.0), ("A", 2.0), ("B", 3.0)]):
        meta = {"site": site, "lat": 41.5 + 0.001 * i, "lon": -93.7 + 0.001 * i}
        if ri is not None:
            meta["RI"] = ri[i]
        out.append(
            PredictionResult(f"p{i}", "ok", params=TerrainParameters(102, 5301, 0.79, 1, 11),
                             depth=z, ci=100.0 * scale + 1000.0 * z, metadata=meta)
        )  # fmt: skip
    return PredictionResults(out, {"calibration": "LETE sand"})


def test_remolding_index_from_metadata_and_a_bad_one_recorded():
    veh = vehicle_from_dict(VEHICLE)
    run_ = evaluate_mobility(located_results(ri=[0.5, 3.0, "x"]), veh, by=[])
    p0, p1, p2 = run_.profiles
    # CI = 100 + 1000 z, the rule's 6-12 in layer (wheeled, one pass): the mean of a linear
    # profile is its value at mid-layer, 100 + 1000 * 0.2286 = 328.6 kPa; RCI = 164.3 kPa
    # >= VCI_1 = 132.566 kPa: GO
    assert p0.ci == pytest.approx(328.6) and p0.rci == pytest.approx(164.3) and p0.go is True
    assert p1.rci is None and any("remolding index 3 outside (0, 2]" in n for n in p1.notes)
    assert p2.rci is None and any("'x' is not a number" in n for n in p2.notes)


def test_sites_pool_their_profiles():
    veh = vehicle_from_dict(VEHICLE)
    run_ = evaluate_mobility(located_results(), veh, remolding_index=1.0)
    assert run_.by == ["site"]
    a, b = run_.sites
    # 6-12 in: site A: profile CIs 328.6 and 428.6 kPa -> 378.6; site B: 528.6
    assert (a.site, a.ci, b.ci) == ("A", pytest.approx(378.6), pytest.approx(528.6))
    assert a.go is True and a.go_fraction == 1.0 and a.profiles == ["p0", "p1"]
    doc = run_.as_dict("us")
    assert doc["sites"][0]["critical_layer"]["ci"] == pytest.approx(378.6 / PSI)
    assert doc["sites"][0]["critical_layer"]["rule"] == "fine-wheeled-1pass"
    assert doc["sites"][0]["wheel"]["sinkage"] == pytest.approx(0.02373498 / 0.0254, rel=1e-6)


def test_report_section_maps_go_and_no_go(tmp_path):
    veh = vehicle_from_dict(VEHICLE)
    doc = evaluate_mobility(located_results(), veh, remolding_index=0.3).as_dict("si")
    # RCI: 0.3 * 328.6 = 98.58 (NO-GO), 128.58 (NO-GO), 158.58 (GO) against VCI 132.57 kPa
    assert [p["go"] for p in doc["profiles"]] == [False, False, True]
    section = mobility_document(doc, source="m.json")["sections"][0]
    assert [p["type"] for p in section["parts"]].count("figure") == 1  # the map
    path = tmp_path / "m.json"
    path.write_text(json.dumps(doc))
    res = run("report", path, "--out", tmp_path / "m.html")
    assert res.exit_code == 0, res.output
    html = (tmp_path / "m.html").read_text()
    assert "Vehicle mobility" in html and "NO-GO" in html and "data:image/png" in html


# ---------------------------------------------------------------------------
# the vehicle file
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "change, message",
    [
        ({"name": None}, "key 'name': missing"),
        ({"kind": "boat"}, "key 'kind': expected 'wheeled' or 'tracked'"),
        ({"mobility_index": None}, "give 'mobility_index' or 'mobility_index_inputs'"),
        ({"mobility_index": -3}, "key 'mobility_index': expected a number in (0, 1000]"),
        ({"tire_deflection_ratio": 1.5}, "key 'tire_deflection_ratio'"),
        ({"wheel": None}, "key 'wheel': missing"),
        ({"wheel": {"diameter": "1 m", "width": "0.3 m"}}, "key 'wheel.load': missing"),
        ({"wheel": {"load": "10", "diameter": "1 m", "width": "0.3 m"}}, "'10' has no unit"),
        (
            {"wheel": {"load": "10 kN", "diameter": "1 furlong", "width": "0.3 m"}},
            "unknown length unit 'furlong'",
        ),  # fmt: skip
    ],
)
def test_vehicle_file_errors_name_the_file_and_the_key(tmp_path, synthetic, change, message):
    bad = {**VEHICLE, **change}
    path = write_vehicle(tmp_path, bad, "bad.json")
    res = run("mobility", synthetic, "--vehicle", path)
    assert res.exit_code != 0
    assert f"vehicle file {path}" in res.output and message in res.output, res.output
    assert "Traceback" not in res.output


def test_vehicle_file_with_the_mi_inputs_and_units():
    d = {**VEHICLE, "mobility_index": None, "tire_deflection_ratio": 0.15,
         "mobility_index_inputs": {
             "gross_weight": "13450 lb", "axles": 2, "tires": 4, "tire_width": "12.5 in",
             "tire_diameter": "37 in", "ground_clearance": "17.4 in", "engine_power": "190 hp"}}  # fmt: skip
    veh = vehicle_from_dict(d, "v.json")
    assert veh.mobility_index == pytest.approx(83.820176, rel=1e-7) and veh.mi_from == "inputs"
    assert veh.wheel.load == 10e3 and veh.wheel.width == pytest.approx(0.3)
    missing = {**d, "mobility_index_inputs": {"gross_weight": "13450 lb"}}
    with pytest.raises(
        ValueError, match="vehicle file v.json: key 'mobility_index_inputs.axles': missing"
    ):
        vehicle_from_dict(missing, "v.json")


def test_quantities_with_units_by_hand():
    assert u.quantity_to_si("3363 lb", "force") == pytest.approx(3363 * 4.4482216152605)
    assert u.quantity_to_si("10 kN", "force") == 10000.0
    assert u.quantity_to_si("1 kip", "force") == pytest.approx(4448.2216152605)
    assert u.quantity_to_si("190 hp", "power") == pytest.approx(190 * 745.69987158227)
    assert u.quantity_to_si("12.5 in", "length") == pytest.approx(0.3175)
    assert u.quantity_to_si("2 ft", "length") == pytest.approx(0.6096)
    assert u.quantity_to_si(1.5, "length") == 1.5  # bare numbers are SI
    with pytest.raises(ValueError, match="has no unit"):
        u.quantity_to_si("40", "length")
    with pytest.raises(ValueError, match="unknown force unit 'in'"):
        u.quantity_to_si("40 in", "force")


# ---------------------------------------------------------------------------
# posterior bands
# ---------------------------------------------------------------------------

TRUTH = dict(kc=102.0, kphi=5301.0, n=0.79, cc=1.0, phic_deg=11.0)  # LETE sand
DEPTH = np.round(np.arange(0.0, 0.3001, 0.01), 6)
LETE = Calibration("LETE sand", "rm0", None, None, 11.0, 1.0, 102.0, 5301.0, 0.79)


def noisy(noise: float, seed: int) -> CIProfile:
    m = cone_index_huang(DEPTH, **TRUTH)
    e = np.random.default_rng(seed).standard_normal(DEPTH.size)
    return CIProfile(f"s{noise:g}-{seed}", DEPTH, m * (1.0 + noise * e))


def test_wheel_band_contains_the_median_sinkage_and_widens_with_the_ci_noise(tmp_path):
    """LETE profiles with 2% and 20% CI noise, three seeds each, through predict's JSON.

    A tight calibration prior (phic and cc fixed, ln(kc/kphi) within 2%; the fit at the
    calibration's values) leaves the band to what the CI determines (the strength and n), so
    more noise must widen it on both sides.
    """
    items = [noisy(s, k) for s in (0.02, 0.20) for k in range(3)]
    prior = CalibrationPrior(LETE, phic_sd=0.0, cc_sd=0.0, ratio_log_sd=0.02)
    run = RunSettings(uncertainty=True, draws=600, seed=5)
    fitted = predict_profiles(items, Problem(prior=prior), run)
    path = write_json(tmp_path / "pred.json", fitted.results, command="predict",
                      settings={"calibration": "LETE sand"})  # fmt: skip
    results = read_results(path)  # the draws come back from the JSON
    run_ = evaluate_mobility(results, vehicle_from_dict(VEHICLE), remolding_index=1.0,
                             layer=(0.0, 6 * u.INCH))  # fmt: skip
    bands = {}
    for p, r in zip(run_.profiles, results, strict=True):
        med = np.median(r.posterior.samples, axis=0)
        z_med = float(v.sinkage_rigid_wheel_bekker(10e3, diameter=1.0, width=0.3, kc=med[0],
                                                   kphi=med[1], n=med[2]))  # fmt: skip
        lo, hi = p.band["sinkage"]
        assert lo < z_med < hi, (p.id, lo, z_med, hi)
        assert p.band["label"] == "posterior" and p.band["level"] == 0.9
        bands[p.id] = (lo, hi)
    low = [bands[f"s0.02-{k}"] for k in range(3)]
    high = [bands[f"s0.2-{k}"] for k in range(3)]
    assert max(b[0] for b in high) < min(b[0] for b in low)  # the lower end goes down
    assert min(b[1] for b in high) > max(b[1] for b in low)  # and the upper end up
    assert min(b[1] - b[0] for b in high) > 2 * max(b[1] - b[0] for b in low)
    d = run_.as_dict("us")["profiles"][0]["wheel"]
    assert d["lo"]["sinkage"] == pytest.approx(bands["s0.02-0"][0] / u.INCH)
    assert d["band"] == "posterior" and set(d["hi"]) == {"sinkage", "resistance"}


def test_bounds_prior_band_is_labelled_set_by_prior(tmp_path):
    fitted = predict_profiles(
        [noisy(0.05, 1)], settings=RunSettings(uncertainty=True, draws=300, seed=2)
    )
    path = write_json(tmp_path / "p.json", fitted.results, settings={"calibration": None})
    run_ = evaluate_mobility(read_results(path), vehicle_from_dict(VEHICLE), remolding_index=1,
                             layer=(0.0, 6 * u.INCH))  # fmt: skip
    assert run_.profiles[0].band["label"] == "set by prior"
    assert any("set by the bounds prior" in n for n in run_.notes)
    assert run_.as_dict()["profiles"][0]["wheel"]["band"] == "set by prior"


# ---------------------------------------------------------------------------
# results without CI, and MAVS
# ---------------------------------------------------------------------------


def test_parquet_results_keep_no_ci_unless_the_ci_file_is_given(tmp_path):
    res = located_results()
    table = write_parquet(tmp_path / "r.parquet", res)
    veh = vehicle_from_dict(VEHICLE)
    run_ = evaluate_mobility(read_results(table), veh, remolding_index=1.0)
    p = run_.profiles[0]
    assert p.ci is None and p.layer_status == "no ci" and p.sinkage is not None
    assert any("the results keep no CI" in n for n in p.notes)
    cis = {r.id: CIProfile(r.id, r.depth, r.ci) for r in res}
    run_ = evaluate_mobility(read_results(table), veh, remolding_index=1.0, ci_profiles=cis)
    assert run_.profiles[0].ci == pytest.approx(328.6)  # 6-12 in, as above


def read_mavs_like_mavs(path: Path) -> list[tuple[str, float]]:
    """(Material, cone index [Pa]) of each surface, as MAVS's scene loader reads them:
    ``d["Surface Mesh"][i]["Material"]`` and ``6894.76f * d[...]["Cone Index"]``."""
    d = json.loads(path.read_text())
    return [(s["Material"], 6894.76 * s["Cone Index"]) for s in d["Surface Mesh"]]


def test_mavs_export_of_a_profile_and_of_a_site(synthetic, tmp_path):
    out = tmp_path / "mavs.json"
    res = run("export", "--results", synthetic, "--profile", "s3", "--format", "mavs",
              "--material", "sand", "--out", out)  # fmt: skip
    assert res.exit_code == 0, res.output
    [(material, pa)] = read_mavs_like_mavs(out)
    assert material in ("dry", "wet", "ice", "snow", "clay", "sand") and material == "sand"
    # the 0-6 in mean of 300 + 3000 z [kPa]: CI(0.0762 m) = 528.6 kPa, in Pa (MAVS's factor
    # 6894.76 Pa/psi against the exact 6894.757...: rel 4e-7)
    assert pa == pytest.approx(528.6e3, rel=1e-6)
    # a site: the mean of its profiles' critical-layer RCI for clay (RI from the metadata)
    site = located_results(ri=[0.5, 0.5, 0.5])
    doc, notes = write_mavs(site, out, material="clay", profile="A")
    # the 0-6 in means of site A: 100 + 1000 * 0.0762 = 176.2 and 276.2 kPa -> 226.2 kPa
    assert read_mavs_like_mavs(out)[0][1] == pytest.approx(0.5 * 226.2e3, rel=1e-6)
    assert doc["terracone"]["cone_index_of"] == "rci" and notes == []
    _, notes = write_mavs(located_results(), out, material="clay", profile="B")
    assert "no remolding index" in notes[0]


def test_mavs_export_errors(synthetic, tmp_path):
    out = tmp_path / "m.json"
    res = run("export", "--results", synthetic, "--format", "mavs", "--material", "sand",
              "--out", out)  # fmt: skip
    assert res.exit_code != 0 and "5 profiles: name one (or a site) with --profile" in res.output
    res = run("export", "--results", synthetic, "--format", "mavs", "--profile", "s1",
              "--material", "clay", "--out", out)  # fmt: skip
    assert res.exit_code != 0 and "too shallow" in res.output
    res = run("export", "--results", synthetic, "--format", "mavs", "--out", out)
    assert res.exit_code != 0 and "--material" in res.output


def test_the_worked_example_of_docs_mobility(marsden):
    """docs/mobility.md: the M1152 on push 0003-N1 with RI 0.8 and the 0-6 in layer of
    --layer: RCI 644.1 kPa against VCI_1 191.6 kPa, GO by 452.5 kPa (each step by hand in
    the docs and above)."""
    d = {**VEHICLE, "mobility_index": None, "tire_deflection_ratio": 0.15,
         "mobility_index_inputs": {
             "gross_weight": "13450 lb", "axles": 2, "tires": 4, "tire_width": "12.5 in",
             "tire_diameter": "37 in", "ground_clearance": "17.4 in", "engine_power": "190 hp"}}  # fmt: skip
    run_ = evaluate_mobility(read_results(marsden), vehicle_from_dict(d), remolding_index=0.8,
                             layer=(0.0, 6 * u.INCH))  # fmt: skip
    p = next(q for q in run_.profiles if q.id.endswith("0003-N1"))
    assert p.rci == pytest.approx(0.8 * 805.14653, rel=1e-7) and p.go is True
    assert p.margin == pytest.approx(644.117 - 191.649, abs=0.01)


def test_profiles_outside_every_site_are_said():
    run_ = evaluate_mobility(located_results(), vehicle_from_dict(VEHICLE), by=["plot"])
    assert run_.sites == [] and "3 profile(s) without plot in their metadata" in run_.notes[-1]

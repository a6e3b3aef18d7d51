"""The prediction process API: terracone.inverse.predict and predict_many.

Data are generated with :func:`terracone.cone_index` from known terrain
parameters; unit conversions are checked against hand-written exact factors
(1 in = 0.0254 m, 1 lbf = 4.4482216152605 N) and against the US columns of
Tables 4-1 and 4-3 of the paper.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import paper_parameter_rows

from terracone import CIProfile, InputError, TerrainParameters, cone_index
from terracone.inverse import Bounds, Problem, RunSettings, predict, predict_many
from terracone.inverse.problem import Calibration
from terracone.physics import units as tu
from terracone.result import PredictionResult

INCH = 0.0254  # m, exact
LBF = 4.4482216152605  # N, exact
PSI = LBF / INCH**2 / 1000.0  # kPa

CONTRACT_KEYS = {
    "id",
    "status",
    "error",
    "kc",
    "kphi",
    "n",
    "cc",
    "phic_deg",
    "rmsd",
    "model",
    "r_min",
    "units",
    "undetermined",
}

# Tables 4-1 and 4-3 (Huang et al.), SI and US columns (the package's copies, held equal to
# ../shared/reference/ by tests/test_paper_tables.py); the data sets run here:
NAMES = ("LS_1", "LS_2", "KRC_1", "KRC_3", "KRC_7", "KRC_24")


def _table():
    """dataset -> kc_si, kc_us, kphi_si, kphi_us, n, cc_kpa, phic_deg."""
    keys = ("kc_si", "kc_us", "kphi_si", "kphi_us", "n", "cc_kpa", "phic_deg")
    return {r["dataset"]: tuple(float(r[k]) for k in keys) for r in paper_parameter_rows()}


TABLE = _table()
Z = np.round(np.arange(0.0, 0.3001, 0.01), 10)


def generated(name="LS_1", **kw) -> CIProfile:
    kc, _, kphi, _, n, cc, phic = TABLE[name]
    ci = cone_index(Z, kc=kc, kphi=kphi, n=n, cc=cc, phic_deg=phic, **kw)
    return CIProfile(name, Z.copy(), ci)


# ---------------------------------------------------------------------------
# bad input is reported per profile
# ---------------------------------------------------------------------------


def bad_profiles() -> dict[str, tuple[CIProfile, tuple[str, ...]]]:
    good = generated("LS_2")
    nan_ci = good.ci.copy()
    nan_ci[5] = np.nan
    neg_ci = good.ci.copy()
    neg_ci[7] = -12.0
    back = good.depth.copy()
    back[10] = back[9]  # repeated depth
    down_up = good.depth.copy()
    down_up[[3, 4]] = down_up[[4, 3]]
    return {
        "two": (CIProfile("two", [0.0, 0.01], [100.0, 250.0]), ("2 points", "at least 3")),
        "nan": (CIProfile("nan", good.depth, nan_ci), ("ci", "not a finite number")),
        "neg": (CIProfile("neg", good.depth, neg_ci), ("negative cone index", "-12")),
        "flat": (CIProfile("flat", back, good.ci), ("depth", "not strictly increasing")),
        "swap": (CIProfile("swap", down_up, good.ci), ("depth", "not strictly increasing")),
    }


def test_bad_profiles_reported_while_the_rest_are_fitted():
    bad = bad_profiles()
    goods = [generated("LS_1"), generated("KRC_1")]
    reader_error = InputError("unparseable number 'x'", file="f.csv", profile="P9", row=4)
    items = [goods[0], *[p for p, _ in bad.values()], reader_error, goods[1]]
    results = predict_many(items)
    assert [r.id for r in results] == ["LS_1", *bad, "P9", "KRC_1"]
    by_id = {r.id: r for r in results}
    for pid, (_, words) in bad.items():
        r = by_id[pid]
        assert r.status == "error" and not r.ok
        assert r.params is None
        for w in words:
            assert w in r.error, (pid, r.error)
        assert f"profile {pid}" in r.error
    r = by_id["P9"]
    assert r.status == "error"
    assert "unparseable number" in r.error and "row 4" in r.error and "f.csv" in r.error
    for g in goods:
        r = by_id[g.id]
        assert r.status == "ok" and r.error is None
        assert r.rmsd < 1e-6 * float(np.sqrt(np.mean(g.ci**2)))
        _, _, _, _, n, _, _ = TABLE[g.id]
        assert abs(r.params.n - n) < 1e-3


def test_error_results_serialise_with_the_contract_keys():
    results = predict_many([p for p, _ in bad_profiles().values()])
    for r in results:
        for units in ("si", "us"):
            d = r.as_dict(units)
            assert CONTRACT_KEYS <= set(d)
            assert d["status"] == "error" and d["error"]
            for k in ("kc", "kphi", "n", "cc", "phic_deg", "rmsd", "model", "r_min"):
                assert d[k] is None
            assert d["units"] == units
            assert d["undetermined"] == []
            json.dumps(d, allow_nan=False)


# ---------------------------------------------------------------------------
# the JSON dict and its units
# ---------------------------------------------------------------------------


def test_ok_result_dict_contract_and_strict_json():
    res = predict(generated("KRC_1"))
    for units in ("si", "us"):
        d = res.as_dict(units)
        assert CONTRACT_KEYS <= set(d)
        assert d["status"] == "ok" and d["error"] is None and d["id"] == "KRC_1"
        assert d["model"] == "rm0" and d["r_min"] is None
        assert d["units"] == units
        assert "phic" in d["undetermined"]
        text = json.dumps(d, allow_nan=False)
        assert json.loads(text)["kc"] == d["kc"]


def test_us_units_by_hand():
    kc, _, kphi, _, n, cc, phic = TABLE["KRC_1"]
    prof = generated("KRC_1", model="rm1", r_min=0.004)
    res = predict(
        prof,
        Problem(
            model="rm1",
            r_min=0.004,
            bounds=Bounds().fixed(phic_deg=phic, cc=cc),
            noise_floor=0.01,
        ),
    )
    si, us = res.as_dict("si"), res.as_dict("us")
    p = res.params
    # SI is what is stored
    assert si["kc"] == p.kc and si["kphi"] == p.kphi and si["cc"] == p.cc
    # 1 lb/in^(n+1) = LBF/1000 kN / (INCH m)^(n+1)
    assert us["kc"] == pytest.approx(p.kc * 1000.0 * INCH ** (p.n + 1) / LBF, rel=1e-12)
    assert us["kphi"] == pytest.approx(p.kphi * 1000.0 * INCH ** (p.n + 2) / LBF, rel=1e-12)
    assert us["cc"] == pytest.approx(p.cc / PSI, rel=1e-12)
    assert us["rmsd"] == pytest.approx(res.rmsd / PSI, rel=1e-12)
    assert us["r_min"] == pytest.approx(0.004 / INCH, rel=1e-12)
    assert us["n"] == si["n"] and us["phic_deg"] == si["phic_deg"] == phic
    np.testing.assert_allclose(us["depth"], prof.depth / INCH, rtol=1e-12)
    np.testing.assert_allclose(us["ci"], prof.ci / PSI, rtol=1e-12)
    np.testing.assert_allclose(us["ci_model"], res.ci_model / PSI, rtol=1e-12)
    # and the constants agree with terracone.physics.units
    assert tu.INCH == INCH and tu.LBF == LBF
    assert PSI == pytest.approx(6.894757293168361, rel=1e-15)
    # recovered values in US units are the paper's US columns (4 significant figures)
    assert us["kc"] == pytest.approx(TABLE["KRC_1"][1], rel=2e-3)
    assert us["kphi"] == pytest.approx(TABLE["KRC_1"][3], rel=2e-3)


@pytest.mark.parametrize("name", NAMES)
def test_table_us_columns(name):
    """A result holding a table row's SI values reports the row's US columns."""
    kc, kc_us, kphi, kphi_us, n, cc, phic = TABLE[name]
    res = PredictionResult(
        id=name, status="ok", params=TerrainParameters(kc, kphi, n, cc, phic), rmsd=1.0
    )
    us = res.as_dict("us", curves=False)
    assert us["kc"] == pytest.approx(kc_us, rel=2e-3, abs=1e-3)
    assert us["kphi"] == pytest.approx(kphi_us, rel=2e-3)
    assert us["cc"] == pytest.approx(cc / PSI, rel=1e-12)
    assert us["rmsd"] == pytest.approx(1.0 / PSI, rel=1e-12)


# ---------------------------------------------------------------------------
# solvers through predict
# ---------------------------------------------------------------------------


def test_pso_through_predict_is_seeded():
    prof = generated("LS_2")
    prof.ci = prof.ci * (1 + 0.02 * np.random.default_rng(0).standard_normal(prof.ci.size))
    a = predict(prof, settings=RunSettings(solver="pso", seed=7))
    b = predict(prof, settings=RunSettings(solver="pso", seed=7))
    c = predict(prof, settings=RunSettings(solver="pso", seed=8))
    assert a.params == b.params and a.rmsd == b.rmsd
    assert a.params != c.params
    assert a.solver == "pso" and "phic" in a.undetermined
    # its RMSD is the RMSD of its own curve
    m = cone_index(
        prof.depth,
        kc=a.params.kc,
        kphi=a.params.kphi,
        n=a.params.n,
        cc=a.params.cc,
        phic_deg=a.params.phic_deg,
    )
    assert a.rmsd == pytest.approx(float(np.sqrt(np.mean((m - prof.ci) ** 2))), rel=1e-12)


def test_rm1_prediction_with_known_r_min():
    pair = (0.0375, 0.05)
    kc, _, kphi, _, n, cc, phic = TABLE["LS_1"]
    prof = generated("LS_1", model="rm1", r_min=0.006, plate_pair=pair)
    res = predict(
        prof,
        Problem(
            model="rm1", r_min=0.006, plate_pair=pair, bounds=Bounds().fixed(phic_deg=phic, cc=cc)
        ),
    )
    p = res.params
    assert p.model == "rm1" and p.r_min == 0.006
    assert abs(p.n - n) < 1e-4
    assert p.kc == pytest.approx(kc, rel=1e-3)
    assert p.kphi == pytest.approx(kphi, rel=1e-3)


# ---------------------------------------------------------------------------
# calibrations
# ---------------------------------------------------------------------------

TRUTH = dict(
    kc=102.0, kphi=5301.0, n=0.79, cc=1.5, phic_deg=12.0
)  # Wong's LETE sand + chosen shear
PAIR = (0.0375, 0.05)


def lete_calibration(**over) -> Calibration:
    fields = dict(
        terrain="LETE sand",
        model="rm1",
        r_min=0.006,
        plate_pair=PAIR,
        phic_deg=TRUTH["phic_deg"],
        cc=TRUTH["cc"],
        kc=TRUTH["kc"],
        kphi=TRUTH["kphi"],
        n=TRUTH["n"],
        provenance={"source": "test"},
    )
    fields.update(over)
    return Calibration(**fields)


def test_calibration_round_trip(tmp_path):
    cal = lete_calibration()
    path = tmp_path / "lete.json"
    cal.save(path)
    raw = json.loads(path.read_text())
    assert raw["terracone_calibration"] == 1 and raw["units"] == "si"
    back = Calibration.load(path)
    assert back == cal
    assert back.plate_pair == PAIR and isinstance(back.plate_pair, tuple)


def test_calibration_load_rejects_other_files(tmp_path):
    p = tmp_path / "x.json"
    p.write_text(json.dumps({"kc": 1}))
    with pytest.raises(ValueError, match="not a terracone calibration"):
        Calibration.load(p)
    p.write_text("{not json")
    with pytest.raises(ValueError, match="cannot read"):
        Calibration.load(p)
    with pytest.raises(ValueError, match="missing.json: file not found"):
        Calibration.load(tmp_path / "missing.json")


def test_predict_with_calibration_fixes_model_rmin_phic_cc(tmp_path):
    cal = lete_calibration()
    cal.save(tmp_path / "c.json")
    cal = Calibration.load(tmp_path / "c.json")
    # a new CI profile of the calibrated terrain, a different push (depths shifted)
    z = np.round(np.arange(0.005, 0.3001, 0.0125), 10)
    ci = cone_index(
        z,
        kc=TRUTH["kc"],
        kphi=TRUTH["kphi"],
        n=TRUTH["n"],
        cc=TRUTH["cc"],
        phic_deg=TRUTH["phic_deg"],
        model="rm1",
        r_min=0.006,
        plate_pair=PAIR,
    )
    prof = CIProfile("push-2", z, ci)
    res = predict(
        prof, Problem(calibration=cal)
    )  # model defaults to rm0: the calibration overrides it
    p = res.params
    assert p.model == "rm1" and p.r_min == 0.006
    assert p.phic_deg == TRUTH["phic_deg"] and p.cc == TRUTH["cc"]
    assert "phic" not in res.undetermined
    assert p.kc == pytest.approx(TRUTH["kc"], rel=1e-3)
    assert p.kphi == pytest.approx(TRUTH["kphi"], rel=1e-3)
    assert abs(p.n - TRUTH["n"]) < 1e-4
    assert any("calibration" in note for note in res.notes)
    d = res.as_dict("us")
    assert d["model"] == "rm1" and d["r_min"] == pytest.approx(0.006 / INCH, rel=1e-12)
    assert d["cc"] == pytest.approx(TRUTH["cc"] / PSI, rel=1e-12)
    # a calibration with the wrong r_min fits this profile worse
    wrong = predict(prof, Problem(calibration=lete_calibration(r_min=0.02)))
    assert wrong.rmsd > 100 * max(res.rmsd, 1e-9)


def test_calibration_pso_respects_fixed_parameters():
    cal = lete_calibration(model="rm0", r_min=None)
    ci = cone_index(Z, **{k: v for k, v in TRUTH.items()})
    res = predict(
        CIProfile("p", Z, ci), Problem(calibration=cal), RunSettings(solver="pso", seed=3)
    )
    assert res.params.phic_deg == TRUTH["phic_deg"] and res.params.cc == TRUTH["cc"]
    assert res.params.model == "rm0"
    assert "phic" not in res.undetermined
    assert math.isfinite(res.rmsd)

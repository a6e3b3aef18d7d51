"""Janosi-Hanamoto shear fits (terracone.physics.shear)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import require_shared

from terracone.data import InputError, ShearTest
from terracone.inverse.bevameter.shear import ShearFit, fit_shear, fit_shear_test
from terracone.physics.shear import shear_stress_janosi_hanamoto

# LETE sand internal shear (Wong): c [kPa], phi [deg], K [m]
C, PHI, K = 1.3, 31.1, 0.012


def jh_test(sigma: float, j=None, tid=None, c=C, phi=PHI, K=K) -> ShearTest:
    j = np.linspace(0.0, 0.1, 150) if j is None else np.asarray(j, float)
    tau = (c + sigma * math.tan(math.radians(phi))) * (1.0 - np.exp(-j / K))
    return ShearTest(tid or f"s{sigma:g}", sigma, j, tau)


def test_janosi_hanamoto_shape():
    j = np.array([0.0, K, 3 * K])
    tau = shear_stress_janosi_hanamoto(j, 10.0, K)
    assert tau[0] == 0.0
    assert tau[1] == pytest.approx(10.0 * (1 - math.exp(-1)))
    assert tau[2] == pytest.approx(9.502129316, rel=1e-9)  # 95 % at j = 3K


def test_recovery_three_normal_pressures():
    res = fit_shear([jh_test(s) for s in (10.0, 25.0, 40.0)])
    assert isinstance(res, ShearFit)
    assert res.c == pytest.approx(C, rel=1e-8)
    assert res.phi_deg == pytest.approx(PHI, rel=1e-9)
    assert res.K == pytest.approx(K, rel=1e-9)
    assert res.undetermined == []
    for f, s in zip(res.tests, (10.0, 25.0, 40.0)):
        assert f.normal_pressure == s
        assert f.tau_max == pytest.approx(C + s * math.tan(math.radians(PHI)), rel=1e-9)
        assert f.K == pytest.approx(K, rel=1e-9)
        assert f.points_used == 150
        assert f.rmsd < 1e-8
    # 3 tests, 3 pressures: intervals from the regression, collapsed (no noise)
    assert res.c_ci[0] <= res.c <= res.c_ci[1]
    assert res.phi_deg_ci[1] - res.phi_deg_ci[0] < 1e-6
    assert res.params() == {
        "c_kpa": pytest.approx(C),
        "phi_deg": pytest.approx(PHI),
        "K_m": pytest.approx(K),
    }


def test_two_pressures_exact_no_interval():
    res = fit_shear([jh_test(10.0), jh_test(40.0)])
    assert res.c == pytest.approx(C, rel=1e-8)
    assert res.phi_deg == pytest.approx(PHI, rel=1e-9)
    assert res.c_ci is None and res.phi_deg_ci is None


def test_noisy_recovery():
    rng = np.random.default_rng(5)
    tests = []
    for i, s in enumerate((10.0, 20.0, 30.0, 40.0, 50.0)):
        t = jh_test(s, tid=f"n{i}")
        tests.append(ShearTest(t.id, s, t.displacement, t.stress + rng.normal(0, 0.3, 150)))
    res = fit_shear(tests)
    assert res.phi_deg == pytest.approx(PHI, abs=0.5)
    assert res.c == pytest.approx(C, abs=0.5)
    assert res.K == pytest.approx(K, rel=0.05)
    assert res.c_ci[0] < res.c < res.c_ci[1]
    assert res.phi_deg_ci[0] < res.phi_deg < res.phi_deg_ci[1]


def test_single_pressure_undetermined():
    tests = [jh_test(93.0, tid="a"), jh_test(93.0, tid="b", K=0.02)]
    res = fit_shear(tests)
    assert res.c is None and res.phi_deg is None
    assert res.undetermined == ["c", "phi_deg"]
    assert res.c_ci is None
    assert [f.K for f in res.tests] == [pytest.approx(0.012), pytest.approx(0.02)]
    assert 0.012 < res.K < 0.02  # common K between the two
    assert set(res.params()) == {"K_m"}
    assert any("one normal pressure" in s for s in res.notes)


def test_points_up_to_peak_region():
    # a post-peak drop (dense soil) is not fitted; negative j is dropped
    j = np.concatenate([[-0.001, -0.0005], np.linspace(0, 0.05, 51), np.linspace(0.051, 0.1, 50)])
    tau = 40.0 * (1 - np.exp(-np.clip(j, 0, None) / 0.005))
    tau[j > 0.05] = 40.0 * (1 - np.exp(-10)) - 200.0 * (j[j > 0.05] - 0.05)  # softening
    t = ShearTest("peak", 50.0, j, tau)
    f = fit_shear_test(t)
    # by hand: peak 39.998 kPa at j = 0.05; the softening of 200 kPa/m loses
    # 0.2, 0.4, 0.6, 0.8 kPa at j = 0.051 ... 0.054 and 2 % of the peak is
    # 0.79996 kPa, so 0.051, 0.052, 0.053 are in the peak region, 0.054 not:
    # 51 points j = 0 ... 0.05 plus 3; the two negative j are dropped
    assert f.points_used == 54
    assert f.j_end == pytest.approx(0.053)
    assert f.tau_max == pytest.approx(40.0, rel=2e-3)
    assert f.K == pytest.approx(0.005, rel=2e-2)
    f2 = fit_shear_test(t, peak_tolerance=0.0)
    assert f2.points_used == 51  # j = 0 ... 0.05 exactly
    assert f2.tau_max == pytest.approx(40.0, rel=1e-6)
    assert f2.K == pytest.approx(0.005, rel=1e-6)
    f3 = fit_shear_test(t, j_max=0.02)
    assert f3.j_end <= 0.02 and f3.points_used == 21


def test_errors():
    with pytest.raises(ValueError, match="no shear tests"):
        fit_shear([])
    with pytest.raises(InputError, match="tiny"):
        fit_shear_test(ShearTest("tiny", 10.0, [0.0, 0.001], [0.0, 1.0]))
    with pytest.raises(InputError, match="bad"):
        fit_shear([jh_test(10.0), InputError("bad", row=4)])


def test_as_dict_us():
    res = fit_shear([jh_test(10.0), jh_test(40.0)])
    d = res.as_dict("us")
    assert d["K"] == pytest.approx(K / 0.0254)
    assert d["c"] == pytest.approx(C / 6.894757293168361, rel=1e-9)
    assert d["unit_labels"]["c"] == "psi"


# --------------------------------------------------------------------------
# real data: Cullinan sand, 4 shear tests at 93 kPa


def load_cullinan_shear() -> list[ShearTest]:
    csv = require_shared("data", "cullinan-sand", "shear.csv")
    try:
        from terracone.io import read_shear_tests
    except ImportError:
        read_shear_tests = None
    if read_shear_tests is not None:
        tests = read_shear_tests(csv)
        assert all(isinstance(t, ShearTest) for t in tests), tests
        return tests
    import pandas as pd  # terracone.io not there yet

    d = pd.read_csv(csv)
    return [
        ShearTest(
            str(tid),
            float(g["normal_pressure_kpa"].iloc[0]),
            g["shear_displacement_mm"].to_numpy() / 1000.0,
            g["shear_stress_kpa"].to_numpy(),
        )
        for tid, g in d.groupby("test", sort=False)
    ]


def test_cullinan_shear():
    tests = load_cullinan_shear()
    assert len(tests) == 4
    res = fit_shear(tests)
    assert res.undetermined == ["c", "phi_deg"]
    assert res.c is None and res.phi_deg is None
    assert 0.001 < res.K < 0.05
    for t, f in zip(tests, res.tests):
        assert f.test == t.id
        assert f.normal_pressure == pytest.approx(93.0)
        assert 30.0 < f.tau_max < 80.0, (f.test, f.tau_max)
        assert 0.0005 < f.K < 0.05, (f.test, f.K)
        assert 0 < f.points_used <= t.displacement.size
        assert f.rmsd < 6.0
    # Method 5 peaks early (about 53 kPa at j ~ 10 mm) and softens: the
    # softening tail is not fitted
    m5 = next(f for f in res.tests if f.test.startswith("Method 5"))
    assert m5.j_end < 0.02
    assert m5.K < 0.005
    # tan(phi) bound implied by one pressure (c >= 0): tau_max / sigma
    for f in res.tests:
        assert math.degrees(math.atan(f.tau_max / 93.0)) < 40.0

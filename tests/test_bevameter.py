"""Plate pressure-sinkage fits (terracone.bevameter)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import require_shared

from terracone.data import InputError, PlateTest
from terracone.inverse.bevameter.plates import (
    METHODS,
    PlateFit,
    PlatesFit,
    fit_plate_test,
    fit_plates,
)
from terracone.physics import units as u
from terracone.physics.plate import plate_pressure

# LETE sand (Wong): kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n
KC, KPHI, N = 102.0, 5301.0, 0.79
RADII = (0.0375, 0.05)  # [m], the LETE plate pair


def lete_test(radius: float, z=None, tid=None) -> PlateTest:
    z = np.linspace(0.001, 0.08, 60) if z is None else np.asarray(z, float)
    p = plate_pressure(z, kc=KC, kphi=KPHI, n=N, radius=radius)
    return PlateTest(tid or f"r{radius}", radius, "circular", z, p)


def log_sse(t: PlateTest, f: PlateFit) -> float:
    """Sum of squared log residuals (what loglog minimises)."""
    return float(np.sum(np.log(t.pressure / f.pressure(t.sinkage)) ** 2))


def wong_sse(t: PlateTest, f: PlateFit) -> float:
    """sum p^2 (ln p - ln p_hat)^2 (what wong minimises)."""
    return float(np.sum(t.pressure**2 * np.log(t.pressure / f.pressure(t.sinkage)) ** 2))


# --------------------------------------------------------------------------
# noiseless data


@pytest.mark.parametrize("method", METHODS)
def test_two_plates_exact_recovery(method):
    res = fit_plates([lete_test(r) for r in RADII], method=method)
    assert isinstance(res, PlatesFit)
    assert res.kc == pytest.approx(KC, rel=1e-9)
    assert res.kphi == pytest.approx(KPHI, rel=1e-9)
    assert res.n == pytest.approx(N, rel=1e-9)
    assert res.undetermined == []
    assert res.method == method
    # two tests over two sizes: exact, no intervals, and it says so
    assert res.kc_ci is None and res.kphi_ci is None and res.n_ci is None
    assert "at least 3 tests" in res.ci_note
    for f, r in zip(res.tests, RADII):
        assert f.b == r and f.radius == r and f.shape == "circular"
        assert f.k == pytest.approx(KC / r + KPHI, rel=1e-9)
        assert f.n == pytest.approx(N, rel=1e-9)
        assert f.points_used == 60
        assert f.r2 == pytest.approx(1.0, abs=1e-12)
        assert f.rmsd < 1e-8


def test_methods_agree_on_noiseless_data():
    t = lete_test(0.05)
    fits = [fit_plate_test(t, m) for m in METHODS]
    for f in fits[1:]:
        assert f.k == pytest.approx(fits[0].k, rel=1e-9)
        assert f.n == pytest.approx(fits[0].n, rel=1e-9)


def test_three_sizes_regression_with_intervals():
    # rectangular plates too: b is the smaller side
    tests = [lete_test(r) for r in (0.03, 0.05, 0.08)]
    tests.append(
        PlateTest(
            "rect", 0.1, "rectangular", tests[0].sinkage, (KC / 0.1 + KPHI) * tests[0].sinkage ** N
        )
    )
    res = fit_plates(tests, "wong")
    assert res.kc == pytest.approx(KC, rel=1e-9)
    assert res.kphi == pytest.approx(KPHI, rel=1e-9)
    assert res.tests[-1].radius is None and res.tests[-1].shape == "rectangular"
    # noiseless: the intervals exist and collapse on the estimates
    for est, ci in ((res.kc, res.kc_ci), (res.kphi, res.kphi_ci), (res.n, res.n_ci)):
        assert ci is not None
        assert ci[0] <= est <= ci[1]
        assert ci[1] - ci[0] < 1e-6 * abs(est)
    assert res.ci_note is None


def test_intervals_cover_scatter_between_tests():
    rng = np.random.default_rng(7)
    tests = []
    for i, r in enumerate((0.0375, 0.05) * 4):
        t = lete_test(r, tid=f"t{i}")
        # each test a little stiffer or softer (test-to-test variability)
        tests.append(PlateTest(t.id, r, "circular", t.sinkage, t.pressure * rng.normal(1, 0.03)))
    res = fit_plates(tests, "wong")
    assert res.kc_ci[0] < res.kc < res.kc_ci[1]
    assert res.kphi_ci[0] < res.kphi < res.kphi_ci[1]
    assert res.kc_ci[1] - res.kc_ci[0] > 0
    # a constant factor per test changes k, not n: every n is exact
    assert res.n == pytest.approx(N, rel=1e-9)


# --------------------------------------------------------------------------
# noisy data: the methods differ the way their weighting says


def test_multiplicative_noise_each_method_minimises_its_own_objective():
    rng = np.random.default_rng(3)
    t0 = lete_test(0.05, z=np.linspace(0.002, 0.08, 40))
    p = t0.pressure * np.exp(rng.normal(0.0, 0.15, t0.pressure.size))
    t = PlateTest("noisy", 0.05, "circular", t0.sinkage, p)
    f = {m: fit_plate_test(t, m) for m in METHODS}
    # the methods give different answers on noisy data
    assert abs(f["wong"].n - f["loglog"].n) > 0.01
    # loglog: least squares in log space
    assert log_sse(t, f["loglog"]) <= log_sse(t, f["wong"])
    assert log_sse(t, f["loglog"]) <= log_sse(t, f["nonlinear"])
    # wong: log residuals weighted by p^2
    assert wong_sse(t, f["wong"]) <= wong_sse(t, f["loglog"])
    assert wong_sse(t, f["wong"]) <= wong_sse(t, f["nonlinear"])
    # nonlinear: least squares on p itself
    assert f["nonlinear"].rmsd <= f["wong"].rmsd
    assert f["nonlinear"].rmsd <= f["loglog"].rmsd
    assert f["nonlinear"].r2 >= max(f["wong"].r2, f["loglog"].r2)


def test_constant_additive_noise_loglog_is_led_by_the_low_end():
    # noise of constant size in p is heteroscedastic in ln p: large at the
    # low-pressure end.  loglog gives those points full weight, wong (weights
    # p^2, a linearised least squares on p) does not: over repeated samples
    # wong's n scatters much less than loglog's and stays near the nonlinear fit.
    z = np.linspace(0.001, 0.08, 80)
    p0 = lete_test(0.05, z=z).pressure  # 31 to 1000 kPa
    ns = {m: [] for m in METHODS}
    for seed in range(30):
        p = p0 + np.random.default_rng(seed).normal(0.0, 8.0, z.size)
        t = PlateTest(f"s{seed}", 0.05, "circular", z, p)
        for m in METHODS:
            ns[m].append(fit_plate_test(t, m).n)
    ns = {m: np.array(v) for m, v in ns.items()}
    assert ns["wong"].std() < 0.5 * ns["loglog"].std()
    assert np.mean(np.abs(ns["wong"] - ns["nonlinear"])) < np.mean(
        np.abs(ns["loglog"] - ns["nonlinear"])
    )


def test_low_pressure_outlier_pulls_loglog_not_wong():
    z = np.linspace(0.002, 0.08, 40)
    t0 = lete_test(0.05, z=z)
    p = t0.pressure.copy()
    p[0] /= 20.0  # one bad reading at the low-pressure end
    t = PlateTest("outlier", 0.05, "circular", z, p)
    f = {m: fit_plate_test(t, m) for m in METHODS}
    # loglog is dominated by the low end: the outlier drags n far off
    assert abs(f["loglog"].n - N) > 0.1
    assert abs(f["wong"].n - N) < 0.01
    assert abs(f["wong"].n - N) < abs(f["loglog"].n - N)
    # wong weights the high-pressure end: its residuals there are smaller
    top = t0.pressure >= np.quantile(t0.pressure, 0.8)
    res = {m: np.abs(p - f[m].pressure(z))[top] for m in METHODS}
    assert res["wong"].max() < res["loglog"].max()
    assert res["wong"].mean() < 0.01 * res["loglog"].mean()


# --------------------------------------------------------------------------
# one plate size, loading branch, errors


def test_one_plate_size_leaves_kc_kphi_undetermined():
    tests = [lete_test(0.05, tid=f"t{i}") for i in range(3)]
    res = fit_plates(tests)
    assert res.kc is None and res.kphi is None
    assert res.undetermined == ["kc", "kphi"]
    assert res.kc_ci is None and res.kphi_ci is None
    assert res.n == pytest.approx(N, rel=1e-9)
    assert res.n_ci is not None  # 3 tests: spread of per-test n
    for f, k in zip(res.tests, res.k_common):
        assert f.k == pytest.approx(KC / 0.05 + KPHI, rel=1e-9)
        assert k == pytest.approx(f.k, rel=1e-9)
    assert res.params() == {"n": pytest.approx(N)}
    assert any("one plate size" in s for s in res.notes)


def test_loading_branch_selection_by_hand():
    # p = 2000 z^0.8 on the loading points; drift at the start, unloading at the end
    s = np.array([-0.0005, 0.0002, 0.001, 0.002, 0.003, 0.004, 0.005, 0.004, 0.002, 0.0])
    p = 2000.0 * np.clip(s, 0, None) ** 0.8
    p[0], p[1] = -0.3, -0.1  # negative drift: row 0 (s < 0, p < 0), row 1 (p < 0)
    p[7:] = [12.0, 3.0, 0.0]  # unloading tail, off the loading curve
    t = PlateTest("hand", 0.05, "circular", s, p)
    # kept by hand: rows 2, 3, 4, 5, 6 (up to the max sinkage 0.005, s > 0, p > 0)
    assert t.loading_branch().sinkage.tolist() == [0.001, 0.002, 0.003, 0.004, 0.005]
    for m in METHODS:
        f = fit_plate_test(t, m)
        assert f.points_used == 5
        # exact recovery proves the drift and unloading points were not used
        assert f.k == pytest.approx(2000.0, rel=1e-9)
        assert f.n == pytest.approx(0.8, rel=1e-9)


def test_errors():
    t = lete_test(0.05)
    with pytest.raises(ValueError, match="method"):
        fit_plate_test(t, "ols")
    with pytest.raises(ValueError, match="no plate tests"):
        fit_plates([])
    short = PlateTest("short", 0.05, "circular", [0.0, 0.01], [0.0, 5.0])
    with pytest.raises(InputError, match="short"):
        fit_plate_test(short)
    bad = InputError("bad row", file="x.csv", row=3)
    with pytest.raises(InputError, match="bad row"):
        fit_plates([t, bad])


def test_as_dict_units_round_trip():
    res = fit_plates([lete_test(r) for r in RADII])
    us = res.as_dict("us")
    assert us["units"] == "us" and us["unit_labels"]["kc"] == "lb/in^(n+1)"
    assert float(u.kc_to_si(us["kc"], us["n"], "us")) == pytest.approx(KC, rel=1e-9)
    assert float(u.kphi_to_si(us["kphi"], us["n"], "us")) == pytest.approx(KPHI, rel=1e-9)
    assert us["tests"][0]["b"] == pytest.approx(0.0375 / 0.0254)
    si = res.as_dict()
    assert si["kc"] == pytest.approx(KC, rel=1e-9) and si["kc_ci"] is None
    assert res.params() == {
        "kc": pytest.approx(KC),
        "kphi": pytest.approx(KPHI),
        "n": pytest.approx(N),
    }


# --------------------------------------------------------------------------
# real data: Cullinan sand (Kruger, Els & Hamersma 2023), 13 tests, one plate


def load_cullinan_plates() -> list[PlateTest]:
    csv = require_shared("data", "cullinan-sand", "plate_sinkage.csv")
    try:
        from terracone.io import read_plate_tests
    except ImportError:
        read_plate_tests = None
    if read_plate_tests is not None:
        tests = read_plate_tests(csv)
        assert all(isinstance(t, PlateTest) for t in tests), tests
        return tests
    import pandas as pd  # terracone.io not there yet: read the file's columns here

    d = pd.read_csv(csv)
    return [
        PlateTest(
            str(tid),
            float(g["plate_diameter_mm"].iloc[0]) / 2000.0,
            "circular",
            g["sinkage_mm"].to_numpy() / 1000.0,
            g["pressure_kpa"].to_numpy(),
        )
        for tid, g in d.groupby("test", sort=False)
    ]


def test_cullinan_plates():
    tests = load_cullinan_plates()
    assert len(tests) == 13
    for t in tests:
        assert t.shape == "circular"
        assert t.b == pytest.approx(0.1514 / 2, rel=1e-6)  # 151.4 mm diameter
    res = fit_plates(tests, "wong")
    assert len(res.tests) == 13
    assert res.undetermined == ["kc", "kphi"]  # one plate size
    assert res.kc is None and res.kphi is None
    assert 0.2 < res.n < 2.5
    for t, f in zip(tests, res.tests):
        assert f.test == t.id
        # the raw file starts with small negative values: they are dropped
        assert 0 < f.points_used <= t.sinkage.size
        assert np.all(t.loading_branch().sinkage > 0)
        assert 0.1 < f.n < 2.5, (f.test, f.n)
        assert f.k > 0 and math.isfinite(f.k)
        assert f.r2 > 0.5, (f.test, f.r2)
        assert f.rmsd < 0.15 * t.pressure.max()
    # the four method-2 preparations are repeats: similar k and n
    m2 = [f for f in res.tests if f.test.startswith("method_2")]
    assert len(m2) == 4
    ns = np.array([f.n for f in m2])
    assert ns.max() - ns.min() < 0.1

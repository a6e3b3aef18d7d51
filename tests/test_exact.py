"""The ``exact`` solver of the prediction process against known truths.

CI profiles are generated with :func:`terracone.cone_index` from terrain
parameters of the paper (Tables 4-1 and 4-3 of Huang et al., the package's
copies, which tests/test_paper_tables.py holds equal to
``../shared/reference/huang2020_predicted_parameters.csv``) and from Wong's
LETE sand values.  The
references are these known truths, the closed-form ridge of fully mobilised
shear (phic trades exactly with a common scale of kc and kphi), and
independent optimisers (terracone's own swarm and
``scipy.optimize.differential_evolution``) run on the same objective and
bounds.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import paper_parameter_rows
from scipy.optimize import differential_evolution

from terracone import CIProfile, cone_index
from terracone.inverse import Bounds, predict
from terracone.inverse.predict import RunSettings, rmsd_objective
from terracone.inverse.problem import Problem
from terracone.physics.plate import pressure_law
from terracone.physics.units import kc_from_si, kphi_from_si

TAN15 = math.tan(math.radians(15.0))

# LETE sand, Wong (1981) as quoted in section 2 of the paper: kc = 102
# kN/m^(n+1), kphi = 5301 kN/m^(n+2), n = 0.79; cone-metal shear chosen here
# (cc = 1.5 kPa, phic = 12 deg).
WONG_LETE = (102.0, 5301.0, 0.79, 1.5, 12.0)


def _table() -> dict[str, tuple[float, float, float, float, float]]:
    """Tables 4-1 (LETE sand) and 4-3 (KRC soils) of Huang et al.: kc [kN/m^(n+1)], kphi
    [kN/m^(n+2)], n, cc [kPa], phic [deg] of each data set."""
    keys = ("kc_si", "kphi_si", "n", "cc_kpa", "phic_deg")
    return {r["dataset"]: tuple(float(r[k]) for k in keys) for r in paper_parameter_rows()}


TABLE = _table()


def terrain(name: str) -> tuple[float, float, float, float, float]:
    return WONG_LETE if name == "LETE" else TABLE[name]


def depths(dz: float, top: float = 0.0, bottom: float = 0.3) -> np.ndarray:
    return np.round(np.arange(top, bottom + dz / 2, dz), 10)


def make_profile(name: str, dz: float, noise: float = 0.0, seed: int = 0) -> CIProfile:
    kc, kphi, n, cc, phic = terrain(name)
    z = depths(dz)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=cc, phic_deg=phic)
    if noise:
        rng = np.random.default_rng(seed)
        ci = ci * (1.0 + noise * rng.standard_normal(ci.size))
    return CIProfile(f"{name}-{dz}-{noise}", z, ci)


def rms(a) -> float:
    a = np.asarray(a, float)
    return float(np.sqrt(np.mean(a * a)))


def S(phic_deg) -> np.ndarray:
    """Shear factor 1 + tan(phic)/tan(15 deg) of fully mobilised shear."""
    return 1.0 + np.tan(np.radians(phic_deg)) / TAN15


def phic_of_S(s: float) -> float:
    return math.degrees(math.atan((s - 1.0) * TAN15))


def ridge_interval(kc, kphi, phic, bounds: Bounds) -> tuple[float, float]:
    """Closed form: the phic' for which kc*S(phic)/S(phic') and kphi*S(phic)/S(phic')
    stay within the (SI) bounds."""
    lo, hi = bounds.phic_deg
    for v, (b_lo, b_hi) in ((kc, bounds.kc), (kphi, bounds.kphi)):
        if v == 0:
            continue
        k = v * S(phic)
        # k / S(p) <= b_hi  <=>  S(p) >= k / b_hi
        lo = max(lo, phic_of_S(max(k / b_hi, 1.0)))
        if b_lo > 0:
            hi = min(hi, phic_of_S(k / b_lo)) if k / b_lo >= 1.0 else -1.0
    return lo, hi


def vec(p, bounds: Bounds) -> np.ndarray:
    """Position (kc, kphi, n, cc, phic) in the units of ``bounds`` (rmsd_objective's)."""
    return np.array(
        [
            float(kc_from_si(p.kc, p.n, bounds.kc_units)),
            float(kphi_from_si(p.kphi, p.n, bounds.kphi_units)),
            p.n,
            p.cc,
            p.phic_deg,
        ]
    )


def de_minimum(profile: CIProfile, bounds: Bounds, *, seed: int = 1, maxiter: int = 200):
    f = rmsd_objective(profile, pressure_law("rm0"), bounds)
    box = [bounds.kc, bounds.kphi, bounds.n, bounds.cc, bounds.phic_deg]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = differential_evolution(
            lambda x: f(x.T),
            box,
            seed=seed,
            maxiter=maxiter,
            tol=1e-12,
            polish=True,
            vectorized=True,
            updating="deferred",
        )
    return float(res.fun), res.x


# ---------------------------------------------------------------------------
# recovery from noiseless data
# ---------------------------------------------------------------------------

NAMES = list(TABLE) + ["LETE"]


@pytest.mark.parametrize("dz", [0.01, 0.025])
@pytest.mark.parametrize("name", NAMES)
def test_recovers_n_and_the_curve(name, dz):
    kc, kphi, n, cc, phic = terrain(name)
    prof = make_profile(name, dz)
    res = predict(prof, settings=RunSettings(solver="exact"))
    assert res.ok, res.error
    p = res.params
    assert abs(p.n - n) < 1e-3
    # the fitted curve is the generating curve
    assert res.rmsd < 1e-6 * rms(prof.ci)
    np.testing.assert_allclose(res.ci_model, prof.ci, rtol=1e-5, atol=1e-6 * rms(prof.ci))
    # phic is free: reported as such, and its range contains the truth
    assert "phic" in res.undetermined
    lo, hi = res.phic_range
    assert lo - 1e-9 <= phic <= hi + 1e-9
    assert lo - 1e-9 <= p.phic_deg <= hi + 1e-9
    # the reported kc, kphi are the truth moved along the ridge to the reported phic
    s = S(phic) / S(p.phic_deg)
    assert p.kphi == pytest.approx(kphi * s, rel=1e-3)
    assert p.kc == pytest.approx(kc * s, rel=1e-3, abs=1e-2)  # abs for the kc = 0 sites


@pytest.mark.parametrize("dz", [0.01, 0.025])
@pytest.mark.parametrize("name", NAMES)
def test_fixed_phic_and_cc_recover_kc_kphi(name, dz):
    kc, kphi, n, cc, phic = terrain(name)
    prof = make_profile(name, dz)
    res = predict(
        prof, Problem(bounds=Bounds().fixed(phic_deg=phic, cc=cc)), RunSettings(solver="exact")
    )
    assert res.ok, res.error
    p = res.params
    assert p.phic_deg == phic and p.cc == cc
    assert abs(p.n - n) < 1e-4
    assert p.kphi == pytest.approx(kphi, rel=1e-4)
    assert abs(p.kc - kc) <= 1e-3 * max(kc, 1.0)
    assert res.rmsd < 1e-6 * rms(prof.ci)
    assert "phic" not in res.undetermined
    assert res.phic_range == (phic, phic)


@pytest.mark.parametrize("name", ["KRC_3", "KRC_25"])
def test_kc_zero_terrains(name):
    """Two KRC sites were predicted with kc = 0: the lower bound is reached."""
    kc, kphi, n, cc, phic = terrain(name)
    assert kc == 0.0
    prof = make_profile(name, 0.01)
    res = predict(prof, Problem(bounds=Bounds().fixed(phic_deg=phic, cc=cc)))
    assert 0.0 <= res.params.kc <= 1e-3
    assert res.params.kphi == pytest.approx(kphi, rel=1e-5)
    assert abs(res.params.n - n) < 1e-5


def test_recovery_with_points_above_the_surface_and_us_bounds():
    """Depths from -H (tip entering) and bounds given in US units."""
    kc, kphi, n, cc, phic = terrain("LS_3")
    z = np.round(np.arange(-0.03, 0.3001, 0.01), 10)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=cc, phic_deg=phic)
    prof = CIProfile("neg", z, ci)
    b = Bounds.parse("kc=0:100,kphi=0:100,n=0.2:1.5", "us").fixed(phic_deg=phic, cc=cc)
    res = predict(prof, Problem(bounds=b))
    p = res.params
    assert abs(p.n - n) < 1e-4
    assert p.kphi == pytest.approx(kphi, rel=1e-4)
    assert p.kc == pytest.approx(kc, rel=1e-3)


# ---------------------------------------------------------------------------
# the phic ridge
# ---------------------------------------------------------------------------


def test_phic_range_spans_whole_range_when_bounds_do_not_cut_the_ridge():
    kc, kphi, n, cc, phic = terrain("LS_1")
    b = Bounds()
    assert ridge_interval(kc, kphi, phic, b) == (0.0, 45.0)  # the closed form
    res = predict(make_profile("LS_1", 0.01), Problem(bounds=b))
    assert res.phic_range == pytest.approx((0.0, 45.0))
    assert "phic" in res.undetermined


@pytest.mark.parametrize(
    "text",
    ["kphi=3000:6000,cc=0:0", "kc=0:120,cc=0:0", "kc=0:1000,kphi=2500:20000,cc=0:0"],
)
def test_phic_range_matches_closed_form_ridge(text):
    """Bounds on kc, kphi cut the ridge where the scaled value leaves them."""
    kc, kphi, n, cc, phic = terrain("LS_1")
    b = Bounds.parse(text)
    lo, hi = ridge_interval(kc, kphi, phic, b)
    assert 0.0 < lo or hi < 45.0  # the bounds really cut it
    res = predict(make_profile("LS_1", 0.01), Problem(bounds=b))
    r_lo, r_hi = res.phic_range
    step = 45.0 / 180  # the solver scans phic in 0.25 deg steps
    assert abs(r_lo - lo) <= step + 1e-9
    assert abs(r_hi - hi) <= step + 1e-9
    assert r_lo <= res.params.phic_deg <= r_hi
    assert "phic" in res.undetermined


@pytest.mark.parametrize("noise", [0.0, 0.03])
@pytest.mark.parametrize("name", ["LS_2", "KRC_1", "LETE"])
def test_ridge_is_real(name, noise):
    """Along phic_range, kc and kphi scaled by S(phic)/S(phic') give the same CI."""
    prof = make_profile(name, 0.01, noise=noise, seed=4)
    res = predict(prof)
    p = res.params
    lo, hi = res.phic_range
    assert hi - lo > 10.0
    base = cone_index(prof.depth, kc=p.kc, kphi=p.kphi, n=p.n, cc=p.cc, phic_deg=p.phic_deg)
    np.testing.assert_allclose(base, res.ci_model, rtol=1e-12)
    f = rmsd_objective(prof, pressure_law("rm0"), Bounds())
    for phic2 in np.linspace(lo, hi, 7):
        s = S(p.phic_deg) / S(phic2)
        other = cone_index(prof.depth, kc=p.kc * s, kphi=p.kphi * s, n=p.n, cc=p.cc, phic_deg=phic2)
        np.testing.assert_allclose(other, base, rtol=1e-12, atol=1e-9)
        x2 = np.array([p.kc * s, p.kphi * s, p.n, p.cc, phic2])
        assert f(x2)[0] == pytest.approx(res.rmsd, rel=1e-9, abs=1e-9 * rms(prof.ci))


# ---------------------------------------------------------------------------
# never worse than the swarm and differential evolution
# ---------------------------------------------------------------------------

CASES = [
    (name, dz, noise)
    for name in ("LS_2", "KRC_1", "LETE")
    for dz in (0.01, 0.025)
    for noise in (0.0, 0.02, 0.05)
]


@pytest.mark.parametrize(("name", "dz", "noise"), CASES)
def test_exact_never_worse_than_pso_and_de(name, dz, noise):
    """RMSD of exact <= RMSD of pso and of DE, to 1e-9 relative.

    Noise-free data have optimum 0; there exact works from normal equations
    and reaches ~1e-8 of the CI scale, so a floor of 1e-7 * rms(CI) is added
    for noise 0 only.
    """
    seed = 100 * NAMES.index(name) + int(dz * 1000) + int(noise * 100)
    prof = make_profile(name, dz, noise=noise, seed=seed)
    b = Bounds()
    f = rmsd_objective(prof, pressure_law("rm0"), b)
    ex = predict(prof, Problem(bounds=b), RunSettings(solver="exact"))
    ps = predict(prof, Problem(bounds=b), RunSettings(solver="pso", seed=seed))
    f_ex = float(f(vec(ex.params, b))[0])
    f_ps = float(f(vec(ps.params, b))[0])
    assert f_ex == pytest.approx(ex.rmsd, rel=1e-12, abs=1e-12)
    f_de, _ = de_minimum(prof, b, seed=seed)
    floor = 1e-7 * rms(prof.ci) if noise == 0 else 0.0
    assert f_ex <= f_ps * (1 + 1e-9) + floor, (f_ex, f_ps)
    assert f_ex <= f_de * (1 + 1e-9) + floor, (f_ex, f_de)


def test_exact_never_worse_than_de_with_us_bounds():
    prof = make_profile("LS_1", 0.01, noise=0.02, seed=3)
    b = Bounds.parse("kc=0:20,kphi=0:30,n=0.3:1.2", "us")
    ex = predict(prof, Problem(bounds=b))
    x = vec(ex.params, b)
    lo = np.array([b.kc[0], b.kphi[0], b.n[0], b.cc[0], b.phic_deg[0]])
    hi = np.array([b.kc[1], b.kphi[1], b.n[1], b.cc[1], b.phic_deg[1]])
    assert np.all(x >= lo - 1e-9 * (1 + np.abs(lo))) and np.all(x <= hi + 1e-9 * (1 + hi))
    f = rmsd_objective(prof, pressure_law("rm0"), b)
    f_ex = float(f(x)[0])
    f_de, _ = de_minimum(prof, b, seed=3)
    assert f_ex <= f_de * (1 + 1e-9)


# ---------------------------------------------------------------------------
# finite Kc (eq. (2-4)): phic is no longer a pure scale, so it is identified
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("K_cone", [0.002, 0.005])
def test_fixed_finite_Kc_reaches_the_truth(K_cone):
    kc, kphi, n, _, phic = TABLE["LS_1"]
    z = depths(0.025)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=1.0, phic_deg=phic, K_cone=K_cone)
    res = predict(CIProfile("Kc", z, ci), Problem(K_cone=K_cone))
    p = res.params
    assert res.rmsd <= 1e-6 * rms(ci)
    assert p.K_cone == K_cone
    assert abs(p.n - n) < 1e-4
    assert abs(p.phic_deg - phic) < 0.01
    assert p.kc == pytest.approx(kc, rel=1e-3)
    assert p.kphi == pytest.approx(kphi, rel=1e-3)
    assert abs(p.cc - 1.0) < 0.05
    assert "phic" not in res.undetermined


def test_fit_Kc_reaches_the_truth():
    kc, kphi, n, _, phic = TABLE["LS_1"]
    z = depths(0.025)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=1.0, phic_deg=phic, K_cone=0.02)
    res = predict(CIProfile("fitKc", z, ci), Problem(fit_K_cone=True, bounds=Bounds(n=(0.5, 1.0))))
    assert res.rmsd <= 1e-6 * rms(ci)
    assert res.params.K_cone == pytest.approx(0.02, rel=1e-3)
    assert abs(res.params.n - n) < 1e-4


def test_fit_Kc_reaches_the_truth_dense_profile():
    kc, kphi, n, _, phic = TABLE["LS_1"]
    z = depths(0.01)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=1.0, phic_deg=phic, K_cone=0.005)
    res = predict(
        CIProfile("fitKc-dense", z, ci), Problem(fit_K_cone=True, bounds=Bounds(n=(0.5, 1.0)))
    )
    assert res.rmsd <= 1e-6 * rms(ci)

"""Layered terrain (terracone.physics.layers) against independent references.

References: the homogeneous model (a stack of identical layers must be one
layer), a closed form of the two-layer integral for n = 1, and generated
profiles with known layers, interface and exponents.
"""

from __future__ import annotations

import numpy as np
import pytest

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.layered import LayeredResult, fit_layered
from terracone.physics.cone import CONES, cone_index
from terracone.physics.layers import layered_basis, layered_cone_index
from terracone.physics.plate import pressure_law

CONE = CONES["asabe-large"]
H = CONE.height  # 37.8 mm
R = CONE.radius

# base depths from the tip just touching (-H) through partial penetration to 50 cm
Z = np.concatenate([[-H, -0.7 * H, -0.2 * H, 0.0], np.linspace(0.005, 0.5, 34)])


def _homogeneous(z, p: TerrainParameters, **kw):
    return cone_index(z, kc=p.kc, kphi=p.kphi, n=p.n, cc=p.cc, phic_deg=p.phic_deg, cone=CONE, **kw)


@pytest.mark.parametrize(
    "interfaces",
    [
        [-0.02],  # above the surface: every element is in the lower layer
        [0.0],
        [0.5 * H],  # inside the range of the partly entered cone
        [0.1],
        [0.5],  # the deepest base depth
        [0.5 + H + 0.01],  # below the deepest tip
        [0.05, 0.12],  # three layers
        [-0.01, 0.3, 0.7],  # four layers, one interface above the surface
    ],
)
def test_identical_layers_are_one_homogeneous_layer(interfaces):
    p = TerrainParameters(kc=40.0, kphi=3000.0, n=0.7, cc=3.0, phic_deg=12.0)
    L = len(interfaces) + 1
    X = layered_basis(Z, n=[p.n] * L, interfaces=interfaces, phic_deg=p.phic_deg, cone=CONE)
    assert X.shape == (Z.size, 3 * L)
    ci = X @ np.tile([p.kc, p.kphi, p.cc], L)
    ref = _homogeneous(Z, p)
    assert ref[0] == 0.0 and ci[0] == pytest.approx(0.0, abs=1e-9)  # tip on the surface
    np.testing.assert_allclose(ci, ref, rtol=1e-10, atol=1e-9)
    # the same through layered_cone_index
    ci2 = layered_cone_index(Z, [p] * L, interfaces, cone=CONE)
    np.testing.assert_allclose(ci2, ref, rtol=1e-10, atol=1e-9)


def test_identical_layers_rm1():
    law = pressure_law("rm1", r_min=0.008)
    p = TerrainParameters(kc=102.0, kphi=5301.0, n=0.79, cc=1.0, phic_deg=11.0)
    for d in (-0.01, 0.02, 0.2):
        ci = layered_cone_index(Z, [p, p], [d], cone=CONE, law=law)
        ref = _homogeneous(Z, p, model="rm1", r_min=0.008)
        np.testing.assert_allclose(ci, ref, rtol=1e-10, atol=1e-9)


TOP = TerrainParameters(kc=50.0, kphi=8000.0, n=0.5, cc=2.0, phic_deg=20.0)
BOT = TerrainParameters(kc=10.0, kphi=1500.0, n=1.0, cc=2.0, phic_deg=20.0)


def test_interface_below_every_tip_gives_exactly_the_top_layer():
    d = Z.max() + H + 0.001
    X = layered_basis(Z, n=[TOP.n, BOT.n], interfaces=[d], phic_deg=TOP.phic_deg, cone=CONE)
    assert np.all(X[:, 3:] == 0.0)  # the lower layer carries nothing
    ci = layered_cone_index(Z, [TOP, BOT], [d], cone=CONE)
    np.testing.assert_allclose(ci, _homogeneous(Z, TOP), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("d", [-0.05, -0.001, 0.0])
def test_interface_at_or_above_the_surface_gives_exactly_the_bottom_layer(d):
    X = layered_basis(Z, n=[TOP.n, BOT.n], interfaces=[d], phic_deg=TOP.phic_deg, cone=CONE)
    assert np.all(X[:, :3] == 0.0)  # the upper layer carries nothing
    ci = layered_cone_index(Z, [TOP, BOT], [d], cone=CONE)
    np.testing.assert_allclose(ci, _homogeneous(Z, BOT), rtol=1e-12, atol=1e-12)


def test_two_layers_closed_form_n1():
    # n = 1 in both layers, kc = cc = phic = 0: with u the depth from the surface,
    # d = u1 - u the distance from the tip (u1 = z + H) and r = (R/H) d,
    # CI = (2 tan15 / R^2) int p r du = (2 / H^2) int kphi(u) u (u1 - u) du.
    # With F(u) = u1 u^2/2 - u^3/3 (antiderivative of u (u1 - u)) and the
    # interface D inside [z, u1]:
    # CI = 2/H^2 [kphi1 (F(D) - F(z)) + kphi2 (F(u1) - F(D))]
    k1, k2, D = 6000.0, 1000.0, 0.15
    top = TerrainParameters(kc=0.0, kphi=k1, n=1.0)
    bot = TerrainParameters(kc=0.0, kphi=k2, n=1.0)
    z = np.array([0.0, 0.05, D - H, D - 0.02, D - 0.001, D, 0.2, 0.3])
    u1 = z + H
    Dc = np.clip(D, z, u1)

    def F(v):
        return u1 * v**2 / 2 - v**3 / 3

    ref = 2.0 / H**2 * (k1 * (F(Dc) - F(z)) + k2 * (F(u1) - F(Dc)))
    ci = layered_cone_index(z, [top, bot], [D], cone=CONE)
    np.testing.assert_allclose(ci, ref, rtol=1e-11)
    # far from the interface the homogeneous closed form kphi (z + H/3) holds
    assert ci[0] == pytest.approx(k1 * H / 3, rel=1e-11)
    assert ci[-1] == pytest.approx(k2 * (0.3 + H / 3), rel=1e-11)
    # the strong top layer still carries part of the load while the tip is below D
    assert ci[3] > k2 * (z[3] + H / 3)


def test_continuity_in_the_interface_depth():
    z = np.array([-0.5 * H, 0.0, 0.05, 0.1, 0.15, 0.2])

    def ci(d):
        return layered_cone_index(z, [TOP, BOT], [d], cone=CONE)

    scale = float(np.max(ci(0.6)))  # all in the strong top layer
    eps = 1e-9
    # the kinks: the interface at the surface, at a base depth, at a tip depth
    kinks = [0.0] + list(z[z >= 0]) + list(z + H)
    for d in kinks:
        jump = np.max(np.abs(ci(d + eps) - ci(d - eps)))
        assert jump < 1e-5 * scale, d
    # a sweep in 0.31 mm steps: small increments everywhere, and where the
    # increment is largest a ten times smaller step gives a smaller change (no jump)
    ds = np.linspace(-0.01, 0.3, 1001)
    h = ds[1] - ds[0]
    vals = np.array([ci(d) for d in ds])
    inc = np.max(np.abs(np.diff(vals, axis=0)), axis=1)
    assert np.max(inc) < 0.02 * scale
    k = int(np.argmax(inc))
    fine = np.max(np.abs(ci(ds[k] + h / 10) - ci(ds[k])))
    assert fine < 0.3 * inc[k]


# a tillage pan: a strong top layer over a weaker subsoil, interface at 15 cm
STEP = 0.02
ZFIT = np.arange(0, 0.40 + STEP / 2, STEP)
D_TRUE = 0.15


def _layered_profile(noise: float, seed: int = 0) -> CIProfile:
    ci = layered_cone_index(ZFIT, [TOP, BOT], [D_TRUE], cone=CONE)
    if noise:
        ci = ci * (1.0 + noise * np.random.default_rng(seed).standard_normal(ci.size))
    return CIProfile(f"pan-{noise}", ZFIT, ci, cone=CONE)


def test_fit_layered_recovers_a_two_layer_profile_noiseless():
    prof = _layered_profile(0.0)
    # the generated profile rises to a peak above the interface and falls below it
    assert np.argmax(prof.ci) < np.searchsorted(ZFIT, D_TRUE)
    res = fit_layered(prof, layers=2)
    assert isinstance(res, LayeredResult) and res.ok
    assert len(res.layers) == 2 and len(res.interfaces) == 1
    assert abs(res.interfaces[0] - D_TRUE) < 0.25 * STEP
    assert res.layers[0].n == pytest.approx(TOP.n, abs=0.05)
    assert res.layers[1].n == pytest.approx(BOT.n, abs=0.05)
    assert res.bic < res.bic_single
    assert res.preferred_layers == 2
    assert res.rmsd < 1e-3 * float(np.mean(prof.ci))
    # the layered model may fall with depth: no falling-CI flag for it
    assert res.lack_of_fit is None
    # kc and kphi trade with phic (common scale), their ratio per layer does not
    assert res.layers[0].kc / res.layers[0].kphi == pytest.approx(TOP.kc / TOP.kphi, rel=0.05)
    assert res.layers[1].kc / res.layers[1].kphi == pytest.approx(BOT.kc / BOT.kphi, rel=0.05)
    lo, hi = res.phic_range
    assert lo - 1e-6 <= TOP.phic_deg <= hi + 1e-6
    d = res.as_dict()
    assert d["preferred_layers"] == 2 and len(d["layers"]) == 2
    assert d["interfaces"][0] == pytest.approx(res.interfaces[0])


@pytest.fixture(scope="module")
def noisy_fit() -> LayeredResult:
    """The tillage-pan profile with 2 % multiplicative noise, fitted once."""
    return fit_layered(_layered_profile(0.02, seed=7), layers=2)


def test_fit_layered_recovers_a_two_layer_profile_with_noise(noisy_fit):
    res = noisy_fit
    assert res.ok
    assert abs(res.interfaces[0] - D_TRUE) <= STEP
    assert res.layers[0].n == pytest.approx(TOP.n, abs=0.2)
    assert res.layers[1].n == pytest.approx(BOT.n, abs=0.25)
    assert res.preferred_layers == 2
    # the gain of the second layer is large (Kass-Raftery "very strong": > 10)
    assert res.bic_single - res.bic > 50


def test_homogeneous_noisy_profile_does_not_want_a_second_layer(noisy_fit):
    # 21 points with 3 % multiplicative noise: the 5 extra parameters of a second
    # layer can absorb some of the noise of the deep points, so an unlucky draw
    # may tip BIC to 2 layers (seed 3 does, by a gain of about 8); but the
    # majority of draws prefer one layer and no draw shows strong evidence
    # (Kass-Raftery: a BIC gain above 10)
    p = TerrainParameters(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
    clean = _homogeneous(ZFIT, p)
    prefs, gains = [], []
    for seed in (1, 2, 3):
        y = clean * (1.0 + 0.03 * np.random.default_rng(seed).standard_normal(ZFIT.size))
        res = fit_layered(CIProfile(f"hom{seed}", ZFIT, y, cone=CONE), layers=2)
        assert res.ok
        assert res.preferred_layers == (2 if res.bic < res.bic_single else 1)
        prefs.append(res.preferred_layers)
        gains.append(res.bic_single - res.bic)
    assert prefs.count(1) >= 2, (prefs, gains)
    assert max(gains) < 10.0, gains
    # compare: the layered profile (2 % noise) gains far more
    assert noisy_fit.bic_single - noisy_fit.bic > 5 * 10.0


def test_fit_layered_one_layer_matches_the_homogeneous_fit():
    # with noise (noiseless, both SSEs are rounding noise and their logs differ)
    p = TerrainParameters(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
    y = _homogeneous(ZFIT, p) * (1.0 + 0.03 * np.random.default_rng(2).standard_normal(ZFIT.size))
    res = fit_layered(CIProfile("hom", ZFIT, y, cone=CONE), layers=1)
    assert res.ok and len(res.layers) == 1 and res.interfaces == []
    assert res.layers[0].n == pytest.approx(p.n, abs=0.05)
    assert res.bic == pytest.approx(res.bic_single, rel=1e-6, abs=1e-6)
    assert res.preferred_layers == 1


def test_fit_layered_errors_are_results():
    short = CIProfile("short", [0.0, 0.01, 0.02], [10.0, 20.0, 30.0], cone=CONE)
    res = fit_layered(short, layers=2)
    assert not res.ok and res.error
    assert res.as_dict() == {"id": "short", "status": "error", "error": res.error}


def test_a_calibration_is_held_in_every_layer_and_every_draw():
    """Issue 28: a calibration's phic, cc and kc/kphi hold in every layer of a layered fit and
    in every draw of its posterior.  Known truth: two layers sharing the calibration's phic
    (12 deg), cc (2 kPa) and kc/kphi (0.01 m), noise-free, come back."""
    from terracone.inverse.layered import layered_posterior
    from terracone.inverse.problem import Calibration, Problem

    ratio, cc, phic = 0.01, 2.0, 12.0
    top = TerrainParameters(ratio * 8000.0, 8000.0, 0.4, cc, phic)
    bot = TerrainParameters(ratio * 1500.0, 1500.0, 1.0, cc, phic)
    ci = layered_cone_index(ZFIT, [top, bot], [D_TRUE], cone=CONE)
    prof = CIProfile("held", ZFIT, ci, cone=CONE)
    cal = Calibration("pan", "rm0", None, None, phic, cc, ratio * 3000.0, 3000.0, 0.8)
    pb = Problem(calibration=cal)
    res = fit_layered(prof, pb, layers=2)
    assert res.ok and len(res.layers) == 2
    for got in res.layers:
        assert got.phic_deg == phic and got.cc == cc
        assert got.kc == pytest.approx(ratio * got.kphi, rel=1e-12)
    assert "phic" not in res.undetermined and res.phic_range == (phic, phic)
    assert res.rmsd < 1e-3 * float(np.mean(ci))
    assert abs(res.interfaces[0] - D_TRUE) < 0.25 * STEP
    for got, truth in zip(res.layers, (top, bot)):
        assert got.n == pytest.approx(truth.n, abs=0.05)
    assert any("calibration 'pan'" in note for note in res.notes)
    post = layered_posterior(prof, res, pb, draws=200, seed=1, burn=200, thin=2)
    for j in (1, 2):
        kc, kphi = (post.samples[:, post.names.index(f"{k}_{j}")] for k in ("kc", "kphi"))
        np.testing.assert_array_equal(post.samples[:, post.names.index(f"cc_{j}")], cc)
        np.testing.assert_allclose(kc, ratio * kphi, rtol=1e-12)
    assert post.phic_deg == phic

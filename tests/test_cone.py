"""Cone index: terracone.cone_index against independent references.

The reference is adaptive quadrature (scipy.integrate.quad) of eqs. (2-5)
and (2-6) of Huang et al., written directly in the paper's variable h (the
height above the cone tip's level, measured down from the cone base: the
surface element at h lies at depth z + h and has radius r = R (H - h) / H,
eq. (2-3)), with CI = (Fp + Fs) / (pi R^2), eq. (2-7).  The RM1 pressure is
the one printed in section 3.2.  Closed forms and hand calculations of the
Janosi equation (2-1) complete the picture.  No expected value here was
produced by terracone itself.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import IntegrationWarning, quad

import terracone
from terracone import cone_index

# ---------------------------------------------------------------------------
# independent geometry and reference
# ---------------------------------------------------------------------------

INCH = 0.0254  # m, exact
LBF = 4.4482216152605  # N, exact
PSI = LBF / INCH**2 / 1000.0  # kPa
TAN15 = math.tan(math.radians(15.0))
COS15 = math.cos(math.radians(15.0))
AREA_IN2 = {"asabe-large": 0.5, "asabe-small": 0.2}  # ASABE S313 base areas


def geometry(cone: str) -> tuple[float, float]:
    """(R, H) [m] of a standard 30 deg cone: R = sqrt(A/pi), H = R / tan 15 deg."""
    R = math.sqrt(AREA_IN2[cone] * INCH**2 / math.pi)
    return R, R / TAN15


def ci_quad(
    z: float,
    *,
    kc: float,
    kphi: float,
    n: float,
    cc: float = 0.0,
    phic_deg: float = 0.0,
    K_cone: float | None = None,
    r_min: float | None = None,
    pair: tuple[float, float] | None = None,
    cone: str = "asabe-large",
) -> float:
    """CI [kPa] by quadrature of eqs. (2-5) and (2-6), SI units.

    ``r_min`` None: RM0.  ``r_min`` given: RM1, tangent to Bekker at r_min
    (section 3.2); with ``pair`` = (r1, r2) and r_min > r2, the line through
    (r1, p1) and (r2, p2) instead.
    """
    R, H = geometry(cone)
    tan_phic = math.tan(math.radians(phic_deg))
    h0 = max(0.0, -z)  # the tip is entering: only h >= -z is in the soil

    def pressure(h: float) -> float:
        u = max(z + h, 0.0)  # depth of the element
        r = R * (H - h) / H  # eq. (2-3)
        un = u**n
        if r_min is None or r >= r_min:
            return (kc / r + kphi) * un  # eq. (2-2), RM0
        if pair is not None and r_min > max(pair):
            r1, r2 = sorted(pair)
            p1 = (kc / r1 + kphi) * un
            p2 = (kc / r2 + kphi) * un
            return p1 + (p2 - p1) * (r - r1) / (r2 - r1)
        # RM1 of section 3.2, tangent at r = r_min
        return (kc / r_min + kphi) * un + (r_min - r) * kc / r_min**2 * un

    def integrand(h: float) -> float:
        r = R * (H - h) / H
        if r == 0.0:  # only reachable through rounding at the tip; p*r -> kc z^n
            pr = kc * max(z + h, 0.0) ** n if r_min is None else 0.0
        else:
            pr = pressure(h) * r
        mob = 1.0 if K_cone is None else -math.expm1(-(z + h) / (COS15 * K_cone))  # eq. (2-4)
        # eq. (2-5): tan15 * p * r ; eq. (2-6): (cc r + p r tan phic) (1 - e^(-j/K))
        return TAN15 * pr + (cc * r + pr * tan_phic) * mob

    # Break points: r = r_min, where the pressure law changes branch, and a
    # mesh graded towards the shallow end h0, where u^n (n < 1) and the
    # mobilisation 1 - exp(-u / (cos15 Kc)) vary fastest (a near-singularity
    # at h = -z just outside [0, H] defeats the extrapolation of a single
    # interval at z ~ 1e-9 m).
    points = {h0 + (H - h0) * 10.0**-k for k in range(1, 16)}
    if r_min is not None and r_min < R:
        points.add(H * (1.0 - r_min / R))
    gap = 1e3 * np.finfo(float).eps * H  # no sliver subintervals of a few ulps
    points = sorted(p for p in points if h0 + gap < p < H - gap)
    with warnings.catch_warnings():
        # a reference that does not trust itself must not be compared against
        warnings.simplefilter("error", IntegrationWarning)
        val, _ = quad(integrand, h0, H, points=points or None, epsabs=0.0, epsrel=1e-13, limit=500)
    # CI = (Fp + Fs) / (pi R^2), Fp + Fs = 2 pi * integral
    return 2.0 * math.pi * val / (math.pi * R * R)


def closed_form(z, *, kc, kphi, n, cc=0.0, phic_deg=0.0, cone="asabe-large"):
    """RM0, fully mobilised shear, z >= 0: eqs. (2-5) to (2-7) integrated by hand.

    int_0^H (z+h)^n dh = [(z+H)^(n+1) - z^(n+1)] / (n+1)
    int_0^H (1 - h/H)(z+h)^n dh
        = [(z+H)^(n+2)/((n+1)(n+2)) - (z+H) z^(n+1)/(n+1) + z^(n+2)/(n+2)] / H
    CI = (1 + tan(phic)/tan 15) (kc*A + kphi*B) + cc*H/R.
    """
    R, H = geometry(cone)
    z = np.asarray(z, dtype=float)
    i0 = ((z + H) ** (n + 1) - z ** (n + 1)) / (n + 1)
    i1 = ((z + H) ** (n + 2) / ((n + 1) * (n + 2)) - (z + H) * z ** (n + 1) / (n + 1)) / H
    i1 = i1 + z ** (n + 2) / (n + 2) / H
    A = 2.0 * TAN15 * i0 / R**2
    B = 2.0 * TAN15 * R * i1 / R**2
    return (1.0 + math.tan(math.radians(phic_deg)) / TAN15) * (kc * A + kphi * B) + cc * H / R


def rel_err(got: float, ref: float, floor: float = 1e-300) -> float:
    return abs(got - ref) / max(abs(ref), floor)


def assert_close_to_quad(got: float, ref: float, z: float, n: float, cone: str) -> None:
    """|got - ref| <= 1e-9 |ref|, plus the reference's own resolution limit.

    Written in h, the reference cannot resolve an embedded tip length
    u1 = z + H below a few ulps of H: its nodes h in [-z, H] are rounded to
    ulp(H), a relative error of about (n + 2) eps H / u1 in the integrand.  That
    term (x8) is added; it is below 3e-10 for u1 > 1 um and only matters when
    the tip is within a micrometre of the surface (CI ~ 0 there).
    """
    R, H = geometry(cone)
    u1 = z + H
    tol = 1e-9 * abs(ref)
    if 0.0 < u1 < 1e-6:
        tol += 8.0 * (n + 3.0) * np.finfo(float).eps * H / u1 * max(abs(ref), abs(got))
    assert abs(got - ref) <= tol, (got, ref, rel_err(got, ref))


# ---------------------------------------------------------------------------
# property test over the valid domain
# ---------------------------------------------------------------------------


def _param(lo: float, hi: float) -> st.SearchStrategy[float]:
    # exactly 0 or a realistic magnitude (no subnormal garbage)
    return st.one_of(st.just(0.0), st.floats(lo, hi))


@st.composite
def cases(draw):
    cone = draw(st.sampled_from(["asabe-large", "asabe-small"]))
    R, H = geometry(cone)
    model = draw(st.sampled_from(["rm0", "rm1"]))
    return dict(
        cone=cone,
        z=draw(st.floats(-H, 2.0)),
        kc=draw(_param(1e-6, 2000.0)),
        kphi=draw(_param(1e-6, 30000.0)),
        n=draw(st.floats(0.0, 3.0, exclude_min=True)),
        cc=draw(_param(1e-6, 100.0)),
        phic_deg=draw(st.floats(0.0, 89.0, exclude_max=True)),
        K_cone=draw(st.one_of(st.none(), st.floats(1e-4, 1.0))),
        r_min=None if model == "rm0" else draw(st.floats(1e-4, 0.2)),
    )


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cases())
def test_cone_index_matches_quadrature(case):
    c = dict(case)
    z = c.pop("z")
    r_min = c.pop("r_min")
    ref = ci_quad(z, r_min=r_min, **c)
    got = cone_index(z, model="rm0" if r_min is None else "rm1", r_min=r_min, **c)
    assert np.shape(got) == ()
    assert_close_to_quad(float(got), ref, z, c["n"], c["cone"])


# Deterministic corners of the same comparison (also run when hypothesis
# would not happen to draw them).
CORNERS = [
    dict(z=0.0, kc=100.0, kphi=5000.0, n=0.8),
    dict(z=1e-9, kc=100.0, kphi=5000.0, n=0.3),
    dict(z=2.0, kc=2000.0, kphi=30000.0, n=3.0, cc=100.0, phic_deg=88.9),
    dict(z=0.5, kc=50.0, kphi=3000.0, n=0.05, cc=2.0, phic_deg=12.0, K_cone=1e-4),
    dict(z=0.0, kc=50.0, kphi=3000.0, n=0.05, cc=2.0, phic_deg=12.0, K_cone=1e-4),
    dict(z=1e-3, kc=50.0, kphi=3000.0, n=1.5, cc=2.0, phic_deg=20.0, K_cone=1e-4),
    dict(z=0.1, kc=0.0, kphi=3000.0, n=0.7, phic_deg=10.0, r_min=0.002),
    dict(z=0.1, kc=80.0, kphi=4700.0, n=0.74, phic_deg=12.5, r_min=0.002),
    dict(z=0.1, kc=80.0, kphi=4700.0, n=0.74, phic_deg=12.5, r_min=0.2),
    dict(z=0.1, kc=80.0, kphi=4700.0, n=0.74, phic_deg=12.5, r_min=1e-4, K_cone=0.01),
    dict(z=0.3, kc=80.0, kphi=4700.0, n=0.74, cc=1.0, phic_deg=12.5, r_min=0.004, K_cone=0.02),
    dict(z=0.3, kc=80.0, kphi=4700.0, n=2.2, cc=1.0, r_min=0.003, cone="asabe-small"),
]


@pytest.mark.parametrize("case", CORNERS)
def test_cone_index_corners(case):
    c = dict(case)
    z = c.pop("z")
    r_min = c.get("r_min")
    ref = ci_quad(z, **c)
    got = cone_index(z, model="rm0" if r_min is None else "rm1", **c)
    assert rel_err(float(got), ref) <= 1e-9


@pytest.mark.parametrize("cone", ["asabe-large", "asabe-small"])
@pytest.mark.parametrize("model", ["rm0", "rm1"])
@pytest.mark.parametrize("K_cone", [None, 0.01])
def test_tip_at_surface_gives_zero(cone, model, K_cone):
    R, H = geometry(cone)
    ci = cone_index(
        -H,
        kc=90.0,
        kphi=4000.0,
        n=0.7,
        cc=3.0,
        phic_deg=15.0,
        K_cone=K_cone,
        model=model,
        r_min=0.003 if model == "rm1" else None,
        cone=cone,
    )
    assert float(ci) == 0.0


@pytest.mark.parametrize("frac", [1e-6, 0.01, 0.25, 0.5, 0.9, 0.999999])
@pytest.mark.parametrize("K_cone", [None, 0.005])
def test_partial_penetration(frac, K_cone):
    """-H < z < 0: only the part of the cone below the surface carries load."""
    R, H = geometry("asabe-large")
    z = -H * (1.0 - frac)  # the tip is frac*H deep
    kw = dict(kc=90.0, kphi=4000.0, n=0.7, cc=3.0, phic_deg=15.0, K_cone=K_cone)
    for r_min in (None, 0.002, 0.05):
        ref = ci_quad(z, r_min=r_min, **kw)
        got = cone_index(z, model="rm0" if r_min is None else "rm1", r_min=r_min, **kw)
        assert rel_err(float(got), ref) <= 1e-9
    if K_cone is None:
        # closed form of the embedded tip: u1 = z + H, L = u1
        u1 = z + H
        n = 0.7
        a = 2 * TAN15 * u1 ** (n + 1) / (n + 1) / R**2
        b = 2 * TAN15 * R * u1 ** (n + 2) / ((n + 1) * (n + 2)) / H / R**2
        c = u1**2 / (R * H)
        ref = (1 + math.tan(math.radians(15.0)) / TAN15) * (90.0 * a + 4000.0 * b) + 3.0 * c
        got = cone_index(z, **kw)
        assert rel_err(float(got), ref) <= 1e-9


@pytest.mark.parametrize("r_min", [0.002, 0.006, 0.007, 0.0375, 0.08])
@pytest.mark.parametrize("K_cone", [None, 0.01])
def test_rm1_secant_variant(r_min, K_cone):
    """plate_pair (r1, r2) and r_min > r2: p on the line through (r1, p1), (r2, p2)."""
    kw = dict(kc=80.0, kphi=4700.0, n=0.74, cc=1.0, phic_deg=12.5, K_cone=K_cone)
    # LETE plates (the whole cone is on the line); plates smaller than the cone
    # (r1 < r2 < r_min = 0.007 < R: the break at r_min lies on the cone)
    for pair in ((0.0375, 0.05), (0.003, 0.006)):
        for z in (-0.01, 0.0, 0.05, 0.6):
            ref = ci_quad(z, r_min=r_min, pair=pair, **kw)
            got = cone_index(z, model="rm1", r_min=r_min, plate_pair=pair, **kw)
            assert rel_err(float(got), ref) <= 1e-9, (pair, z)
    # US units: pair and r_min in inches give the same CI in psi
    pair = (0.0375, 0.05)
    z = 0.05
    got_us = cone_index(
        z / INCH,
        kc=kw["kc"] * INCH ** (0.74 + 1) / (LBF / 1000),
        kphi=kw["kphi"] * INCH ** (0.74 + 2) / (LBF / 1000),
        n=0.74,
        cc=1.0 / PSI,
        phic_deg=12.5,
        K_cone=None if K_cone is None else K_cone / INCH,
        model="rm1",
        r_min=r_min / INCH,
        plate_pair=(pair[0] / INCH, pair[1] / INCH),
        units="us",
    )
    ref = ci_quad(z, r_min=r_min, pair=pair, **kw) / PSI
    assert rel_err(float(got_us), ref) <= 1e-9


def test_secant_differs_from_tangent():
    """The secant variant is a different law from the tangent (not silently ignored)."""
    kw = dict(kc=80.0, kphi=4700.0, n=0.74, z=0.1)
    z = kw.pop("z")
    tangent = ci_quad(z, r_min=0.08, **kw)
    secant = ci_quad(z, r_min=0.08, pair=(0.0375, 0.05), **kw)
    assert abs(secant - tangent) > 1e-3 * tangent
    got = cone_index(z, model="rm1", r_min=0.08, plate_pair=(0.0375, 0.05), **kw)
    assert rel_err(float(got), secant) <= 1e-9


# ---------------------------------------------------------------------------
# closed form with fully mobilised shear
# ---------------------------------------------------------------------------

Z_GRID = np.array([0.0, 1e-6, 1e-3, 0.01, 0.05, 0.1, 0.3, 0.6, 1.0, 2.0])


@pytest.mark.parametrize("n", [0.05, 0.391, 0.74, 1.0, 2.0, 3.0])
@pytest.mark.parametrize("cone", ["asabe-large", "asabe-small"])
def test_closed_form(n, cone):
    kw = dict(kc=80.14, kphi=4727.2, n=n, cc=1.0, phic_deg=12.5, cone=cone)
    ref = closed_form(Z_GRID, **kw)
    got = cone_index(Z_GRID, **kw)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=0)


@pytest.mark.parametrize("s", [0.5, 0.9, 1.1, 1.2])
@pytest.mark.parametrize("n", [0.4, 0.8, 1.7])
def test_exact_tradeoff_between_k_and_phic(s, n):
    """(1 + tan phic / tan 15) multiplies kc and kphi: scale one, undo with the other."""
    phic = 20.0
    factor = 1.0 + math.tan(math.radians(phic)) / TAN15
    phic2 = math.degrees(math.atan(TAN15 * (factor / s - 1.0)))
    assert 0.0 <= phic2 < 90.0
    z = np.linspace(-0.02, 1.0, 41)
    a = cone_index(z, kc=60.0, kphi=3000.0, n=n, cc=2.0, phic_deg=phic)
    b = cone_index(z, kc=60.0 * s, kphi=3000.0 * s, n=n, cc=2.0, phic_deg=phic2)
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=0)
    np.testing.assert_allclose(
        a[z >= 0],
        closed_form(z[z >= 0], kc=60.0, kphi=3000.0, n=n, cc=2.0, phic_deg=phic),
        rtol=1e-9,
    )


@pytest.mark.parametrize("cone", ["asabe-large", "asabe-small"])
def test_adhesion_contribution_is_cc_H_over_R(cone):
    R, H = geometry(cone)
    z = np.array([0.0, 1e-8, 0.01, 0.5, 2.0])
    for cc in (1.0, 0.15 * PSI, 37.5, 100.0):
        only = cone_index(z, kc=0.0, kphi=0.0, n=0.7, cc=cc, phic_deg=17.0, cone=cone)
        np.testing.assert_allclose(only, cc * H / R, rtol=1e-14, atol=0)
        with_k = cone_index(z, kc=40.0, kphi=900.0, n=0.7, cc=cc, phic_deg=17.0, cone=cone)
        without = cone_index(z, kc=40.0, kphi=900.0, n=0.7, cc=0.0, phic_deg=17.0, cone=cone)
        np.testing.assert_allclose(with_k - without, cc * H / R, rtol=1e-9 * with_k.max() / cc)
    # H/R = 1/tan 15 for a 30 deg cone
    assert math.isclose(H / R, 1.0 / math.tan(math.radians(15.0)), rel_tol=1e-15)
    assert math.isclose(
        terracone.get_cone(cone).height / terracone.get_cone(cone).radius, H / R, rel_tol=1e-14
    )


def test_kc_zero_rm1_equals_rm0():
    """Section 3.2: with kc = 0 RM1 is RM0 whatever r_min."""
    z = np.linspace(-0.02, 1.0, 21)
    a = cone_index(z, kc=0.0, kphi=2000.0, n=0.6, phic_deg=14.0)
    for r_min in (1e-4, 0.004, 0.2):
        b = cone_index(z, kc=0.0, kphi=2000.0, n=0.6, phic_deg=14.0, model="rm1", r_min=r_min)
        np.testing.assert_allclose(b, a, rtol=1e-13, atol=0)


def test_cone_geometry():
    for name in ("asabe-large", "asabe-small"):
        R, H = geometry(name)
        c = terracone.get_cone(name)
        assert math.isclose(c.radius, R, rel_tol=1e-15)
        assert math.isclose(c.height, H, rel_tol=1e-14)
        assert math.isclose(c.base_area, AREA_IN2[name] * INCH**2, rel_tol=1e-15)
    # 0.5 in^2: D = 0.798 in = 20.27 mm, H = 1.489 in (about Janosi's 1.5 in)
    R, H = geometry("asabe-large")
    assert abs(2 * R / INCH - 0.7979) < 1e-4
    assert abs(H / INCH - 1.4888) < 1e-4


# ---------------------------------------------------------------------------
# Janosi, eq. (2-1)
# ---------------------------------------------------------------------------

# Hand calculation (40-digit decimal arithmetic) of eq. (2-1) for the LETE sand
# values quoted with Figure 2-1: kc = 32 lb/in^(n+1), kphi = 42.2 lb/in^(n+2),
# n = 0.79; z in inches, CI in psi.
JANOSI_HAND = {0.0: 82.031571142036, 1.0: 175.430838480710, 3.0: 328.574917689761}
KC_US, KPHI_US, N_LS = 32.0, 42.2, 0.79


def janosi_plain(z: float, kc: float, kphi: float, n: float) -> float:
    """Eq. (2-1) with plain Python floats."""
    zz = z + 1.5
    return 1.625 * (
        kc / (n + 1) * (zz ** (n + 1) - z ** (n + 1))
        + 0.517
        * kphi
        * (
            zz ** (n + 2) / ((n + 1) * (n + 2))
            + z ** (n + 2) / (n + 2)
            - zz * z ** (n + 1) / (n + 1)
        )
    )


def test_janosi_hand_values_us():
    z = np.array(sorted(JANOSI_HAND))
    got = cone_index(z, kc=KC_US, kphi=KPHI_US, n=N_LS, model="janosi", units="us")
    for zi, gi in zip(z, got):
        assert rel_err(gi, JANOSI_HAND[zi]) <= 1e-11
        assert rel_err(gi, janosi_plain(zi, KC_US, KPHI_US, N_LS)) <= 1e-13
    # first term at z = 0 by hand: 1.625 * 32/1.79 * 1.5**1.79 ~= 60.03 psi
    assert abs(1.625 * 32 / 1.79 * 1.5**1.79 - 60.03) < 0.01


def test_janosi_si_inputs():
    kc_si = KC_US * (LBF / 1000.0) / INCH ** (N_LS + 1)  # ~102 kN/m^(n+1) in the paper
    kphi_si = KPHI_US * (LBF / 1000.0) / INCH ** (N_LS + 2)  # ~5301 kN/m^(n+2)
    assert abs(kc_si - 102) < 0.5 and abs(kphi_si - 5301) < 0.05 * 125.6 + 0.5
    z_in = np.array(sorted(JANOSI_HAND))
    got_kpa = cone_index(z_in * INCH, kc=kc_si, kphi=kphi_si, n=N_LS, model="janosi", units="si")
    for zi, gi in zip(z_in, got_kpa):
        assert rel_err(gi / PSI, JANOSI_HAND[zi]) <= 1e-11


def test_janosi_small_cone_rejected():
    with pytest.raises(ValueError, match="cone"):
        cone_index(
            1.0, kc=KC_US, kphi=KPHI_US, n=N_LS, model="janosi", units="us", cone="asabe-small"
        )


# ---------------------------------------------------------------------------
# invalid input
# ---------------------------------------------------------------------------

GOOD = dict(kc=80.0, kphi=4700.0, n=0.74, cc=1.0, phic_deg=12.5)


@pytest.mark.parametrize(
    "change, pattern",
    [
        (dict(n=0.0), r"\bn\b"),
        (dict(n=-0.5), r"\bn\b"),
        (dict(n=3.0001), r"\bn\b"),
        (dict(n=float("nan")), r"\bn\b"),
        (dict(kc=-1.0), r"\bkc\b"),
        (dict(kphi=-1e-9), r"\bkphi\b"),
        (dict(cc=-0.1), r"\bcc\b"),
        (dict(phic_deg=90.0), r"\bphic\b"),
        (dict(phic_deg=-1.0), r"\bphic\b"),
        (dict(model="rm1", r_min=0.0), r"\br_min\b"),
        (dict(model="rm1", r_min=-0.01), r"\br_min\b"),
        (dict(model="rm1"), r"\br_min\b"),
        (dict(K_cone=0.0), r"\bKc\b"),
        (dict(K_cone=-0.01), r"\bKc\b"),
        (dict(model="rm2"), r"\bmodel\b"),
        (dict(units="metric"), r"\bunits\b"),
        (dict(cone="asabe-huge"), r"\bcone\b"),
    ],
)
def test_invalid_input(change, pattern):
    kw = {**GOOD, **change}
    with pytest.raises(ValueError, match=pattern):
        cone_index(0.1, **kw)


@pytest.mark.parametrize("cone", ["asabe-large", "asabe-small"])
def test_depth_above_minus_H_rejected(cone):
    R, H = geometry(cone)
    with pytest.raises(ValueError, match="depth"):
        cone_index(-1.001 * H, cone=cone, **GOOD)
    with pytest.raises(ValueError, match="depth"):
        cone_index(np.array([0.1, -1.01 * H / INCH]), units="us", cone=cone, **GOOD)
    assert float(cone_index(-H, cone=cone, **GOOD)) == 0.0


# ---------------------------------------------------------------------------
# broadcasting and finiteness
# ---------------------------------------------------------------------------


def test_broadcasting_params_by_depths():
    R, H = geometry("asabe-large")
    z = np.array([-H, -0.5 * H, 0.0, 0.01, 0.1, 1.0, 2.0])
    kc = np.array([[0.0], [80.0], [2000.0]])
    kphi = np.array([[30000.0], [4700.0], [0.0]])
    n = np.array([[0.05], [0.74], [3.0]])
    cc = np.array([[0.0], [1.0], [100.0]])
    phic = np.array([[0.0], [12.5], [88.0]])
    r_min = np.array([[1e-4], [0.004], [0.2]])
    for extra in (
        dict(),
        dict(K_cone=0.01),
        dict(model="rm1", r_min=r_min),
        dict(model="rm1", r_min=r_min, K_cone=np.array([[1e-4], [0.01], [1.0]])),
    ):
        ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=cc, phic_deg=phic, **extra)
        assert ci.shape == (3, z.size)
        assert np.all(np.isfinite(ci))
        assert np.all(ci[:, 0] == 0.0)
        for i in range(3):
            row = {k: (v[i, 0] if isinstance(v, np.ndarray) else v) for k, v in extra.items()}
            one = cone_index(
                z, kc=kc[i, 0], kphi=kphi[i, 0], n=n[i, 0], cc=cc[i, 0], phic_deg=phic[i, 0], **row
            )
            np.testing.assert_allclose(ci[i], one, rtol=1e-13, atol=0)


@pytest.mark.parametrize("model", ["rm0", "rm1"])
@pytest.mark.parametrize("K_cone", [None, 1e-4, 1.0])
def test_finite_over_grid(model, K_cone):
    for cone in ("asabe-large", "asabe-small"):
        R, H = geometry(cone)
        z = np.array([-H, -H * (1 - 1e-12), -0.5 * H, -1e-12, 0.0, 1e-12, 0.5, 2.0])
        n = np.array([0.05, 0.1, 0.5, 1.0, 2.0, 3.0])[:, None]
        ci = cone_index(
            z,
            kc=2000.0,
            kphi=30000.0,
            n=n,
            cc=100.0,
            phic_deg=88.0,
            K_cone=K_cone,
            model=model,
            r_min=1e-4 if model == "rm1" else None,
            cone=cone,
        )
        assert ci.shape == (n.size, z.size)
        assert np.all(np.isfinite(ci))
        assert np.all(ci >= 0)
        assert np.all(np.diff(ci, axis=1) >= 0)  # deeper never gives a smaller CI here

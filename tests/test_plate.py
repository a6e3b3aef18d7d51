"""Plate pressure-sinkage: Bekker (RM0) and RM1 against hand values.

Expected values are worked out by hand from p = (kc/b + kphi) z^n (eq. (2-2)
of Huang et al.) and the RM1 law of section 3.2, with numbers chosen so the
arithmetic is exact or nearly so.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from terracone import plate_pressure

INCH = 0.0254
LBF = 4.4482216152605
PSI = LBF / INCH**2 / 1000.0

# (kc, kphi, n, b, z, p by hand)
HAND = [
    # (50/0.05 + 1000) * 0.1 = (1000 + 1000) * 0.1 = 200
    (50.0, 1000.0, 1.0, 0.05, 0.1, 200.0),
    # (20/0.1 + 800) * 0.04^0.5 = 1000 * 0.2 = 200
    (20.0, 800.0, 0.5, 0.1, 0.04, 200.0),
    # (25/0.25 + 900) * 0.3^2 = 1000 * 0.09 = 90
    (25.0, 900.0, 2.0, 0.25, 0.3, 90.0),
    # (0/0.0375 + 4000) * 0.0625^0.25 = 4000 * 0.5 = 2000
    (0.0, 4000.0, 0.25, 0.0375, 0.0625, 2000.0),
    # (10/0.02 + 0) * 0.027^3 = 500 * 1.9683e-5 = 0.0098415
    (10.0, 0.0, 3.0, 0.02, 0.027, 0.0098415),
    # zero sinkage: zero pressure
    (80.0, 4700.0, 0.74, 0.05, 0.0, 0.0),
]


@pytest.mark.parametrize("kc, kphi, n, b, z, p", HAND)
def test_bekker_circular_and_rectangular(kc, kphi, n, b, z, p):
    circ = plate_pressure(z, kc=kc, kphi=kphi, n=n, radius=b)
    rect = plate_pressure(z, kc=kc, kphi=kphi, n=n, width=b)
    assert float(circ) == pytest.approx(p, rel=1e-13, abs=0)
    assert float(rect) == pytest.approx(p, rel=1e-13, abs=0)


def test_bekker_curve_and_broadcasting():
    z = np.array([0.0, 0.01, 0.04, 0.09])
    # n = 0.5: sqrt(z) = 0, 0.1, 0.2, 0.3; (40/0.1 + 600) = 1000
    p = plate_pressure(z, kc=40.0, kphi=600.0, n=0.5, radius=0.1)
    np.testing.assert_allclose(p, [0.0, 100.0, 200.0, 300.0], rtol=1e-14, atol=1e-12)
    # two plates as a column: (P, 1) x (Z,) -> (P, Z)
    b = np.array([[0.1], [0.05]])
    p2 = plate_pressure(z, kc=40.0, kphi=600.0, n=0.5, radius=b)
    assert p2.shape == (2, 4)
    # (40/0.05 + 600) = 1400
    np.testing.assert_allclose(p2[1], [0.0, 140.0, 280.0, 420.0], rtol=1e-14, atol=1e-12)


def test_us_units():
    # kc = 4 lb/in^2, kphi = 3 lb/in^3, n = 1, b = 2 in, z = 1.5 in:
    # p = (4/2 + 3) * 1.5 = 7.5 psi
    p = plate_pressure(1.5, kc=4.0, kphi=3.0, n=1.0, radius=2.0, units="us")
    assert float(p) == pytest.approx(7.5, rel=1e-14)
    # same in SI with converted inputs gives 7.5 psi in kPa
    n = 0.74
    kc_us, kphi_us, b_in, z_in = 30.2, 45.25, 1.5, 2.0
    p_us = plate_pressure(z_in, kc=kc_us, kphi=kphi_us, n=n, radius=b_in, units="us")
    hand_psi = (kc_us / b_in + kphi_us) * z_in**n
    assert float(p_us) == pytest.approx(hand_psi, rel=1e-13)
    p_si = plate_pressure(
        z_in * INCH,
        kc=kc_us * LBF / 1000 / INCH ** (n + 1),
        kphi=kphi_us * LBF / 1000 / INCH ** (n + 2),
        n=n,
        radius=b_in * INCH,
    )
    assert float(p_si) == pytest.approx(hand_psi * PSI, rel=1e-13)


# ---------------------------------------------------------------------------
# RM1, section 3.2
# ---------------------------------------------------------------------------

KC, KPHI, N = 50.0, 1000.0, 1.0


def rm1_tangent_hand(b, z, r_min, kc=KC, kphi=KPHI, n=N):
    """p = (kc/r_min + kphi) z^n + (r_min - r) kc/r_min^2 z^n for r < r_min, as printed."""
    if b >= r_min:
        return (kc / b + kphi) * z**n
    return (kc / r_min + kphi) * z**n + (r_min - b) * kc / r_min**2 * z**n


def test_rm1_tangent_hand_value():
    # r_min = 0.05, b = 0.02, z = 0.1, n = 1:
    # (50/0.05 + 1000)*0.1 + (0.05 - 0.02) * 50/0.0025 * 0.1 = 200 + 60 = 260
    p = plate_pressure(0.1, kc=KC, kphi=KPHI, n=N, radius=0.02, model="rm1", r_min=0.05)
    assert float(p) == pytest.approx(260.0, rel=1e-13)
    for b in (1e-6, 0.001, 0.01, 0.03, 0.0499, 0.05, 0.08, 0.2):
        for z in (0.0, 0.05, 0.3):
            got = plate_pressure(z, kc=KC, kphi=KPHI, n=N, radius=b, model="rm1", r_min=0.05)
            assert float(got) == pytest.approx(rm1_tangent_hand(b, z, 0.05), rel=1e-13, abs=0)
    # b -> 0: finite, (2 kc / r_min + kphi) z^n = (2000 + 1000) * 0.1 = 300
    p0 = plate_pressure(0.1, kc=KC, kphi=KPHI, n=N, radius=1e-300, model="rm1", r_min=0.05)
    assert float(p0) == pytest.approx(300.0, rel=1e-13)


@pytest.mark.parametrize("r_min", [0.004, 0.05, 0.3])
def test_rm1_tangent_is_continuous_and_tangent(r_min):
    z, n = 0.2, 0.74
    kw = dict(kc=80.0, kphi=4700.0, n=n, model="rm1", r_min=r_min)
    d = 1e-7 * r_min
    below = float(plate_pressure(z, radius=r_min - d, **kw))
    at = float(plate_pressure(z, radius=r_min, **kw))
    above = float(plate_pressure(z, radius=r_min + d, **kw))
    bekker_at = (80.0 / r_min + 4700.0) * z**n
    assert at == pytest.approx(bekker_at, rel=1e-14)
    # continuity
    assert below == pytest.approx(bekker_at, rel=1e-6)
    assert above == pytest.approx(bekker_at, rel=1e-6)
    # slopes on both sides equal the Bekker slope -kc/b^2 z^n at r_min
    slope = -80.0 / r_min**2 * z**n
    left = (at - float(plate_pressure(z, radius=r_min - 100 * d, **kw))) / (100 * d)
    right = (float(plate_pressure(z, radius=r_min + 100 * d, **kw)) - at) / (100 * d)
    assert left == pytest.approx(slope, rel=1e-6)  # the line has exactly this slope
    assert right == pytest.approx(slope, rel=1e-4)  # Bekker, curvature O(d)


def test_rm1_kc_zero_is_bekker():
    b = np.array([0.001, 0.01, 0.1])
    a = plate_pressure(0.1, kc=0.0, kphi=3000.0, n=0.6, radius=b)
    c = plate_pressure(0.1, kc=0.0, kphi=3000.0, n=0.6, radius=b, model="rm1", r_min=0.05)
    np.testing.assert_array_equal(a, c)


PAIR = (0.0375, 0.05)  # LETE sand plates, radius 1.5 in and 2 in (about)


@pytest.mark.parametrize("r_min", [0.06, 0.1, 1.0])
def test_rm1_secant_through_the_plate_pair(r_min):
    kc, kphi, n, z = 80.0, 4700.0, 0.74, 0.1
    kw = dict(kc=kc, kphi=kphi, n=n, model="rm1", r_min=r_min, plate_pair=PAIR)
    r1, r2 = PAIR
    p1 = (kc / r1 + kphi) * z**n
    p2 = (kc / r2 + kphi) * z**n
    # the pair's Bekker pressures reproduced
    assert float(plate_pressure(z, radius=r1, **kw)) == pytest.approx(p1, rel=1e-14)
    assert float(plate_pressure(z, radius=r2, **kw)) == pytest.approx(p2, rel=1e-14)
    # the line, hand-written, below r_min; Bekker above
    for b in (0.001, 0.008, 0.02, 0.0375, 0.045, 0.05, 0.055, 0.9 * r_min, r_min, 1.1 * r_min):
        line = p1 + (p2 - p1) * (b - r1) / (r2 - r1)
        expect = line if b < r_min else (kc / b + kphi) * z**n
        got = float(plate_pressure(z, radius=b, **kw))
        assert got == pytest.approx(expect, rel=1e-13), b
    # linear in b: second differences vanish
    b = np.linspace(0.001, 0.059, 30)
    p = plate_pressure(z, radius=b, **kw)
    assert np.max(np.abs(np.diff(p, 2))) <= 1e-12 * np.max(p)
    # pair given in reverse order: same law
    rev = dict(kw, plate_pair=(r2, r1))
    np.testing.assert_allclose(plate_pressure(z, radius=b, **rev), p, rtol=1e-15)


def test_rm1_pair_with_r_min_inside_pair_is_tangent():
    kc, kphi, n, z = 80.0, 4700.0, 0.74, 0.1
    r_min = 0.045  # below r2: the tangent law applies
    got = plate_pressure(
        z, kc=kc, kphi=kphi, n=n, radius=0.01, model="rm1", r_min=r_min, plate_pair=PAIR
    )
    expect = rm1_tangent_hand(0.01, z, r_min, kc=kc, kphi=kphi, n=n)
    assert float(got) == pytest.approx(expect, rel=1e-13)


def test_rm1_us_units():
    # r_min = 2 in, b = 1 in, kc = 4 lb/in^2, kphi = 3 lb/in^3, n = 1, z = 1 in:
    # (4/2 + 3) * 1 + (2 - 1) * 4/4 * 1 = 5 + 1 = 6 psi
    p = plate_pressure(1.0, kc=4.0, kphi=3.0, n=1.0, radius=1.0, model="rm1", r_min=2.0, units="us")
    assert float(p) == pytest.approx(6.0, rel=1e-14)
    # secant with the pair (1 in, 1.5 in) and r_min = 3 in at b = 0.5 in, z = 1 in:
    # p1 = 4 + 3 = 7, p2 = 8/3 + 3 = 17/3; slope (17/3 - 7)/0.5 = -8/3;
    # p(0.5) = 7 + (-8/3)(-0.5) = 25/3
    p = plate_pressure(
        1.0,
        kc=4.0,
        kphi=3.0,
        n=1.0,
        radius=0.5,
        model="rm1",
        r_min=3.0,
        plate_pair=(1.0, 1.5),
        units="us",
    )
    assert float(p) == pytest.approx(25.0 / 3.0, rel=1e-14)


# ---------------------------------------------------------------------------
# errors
# ---------------------------------------------------------------------------

OK = dict(kc=80.0, kphi=4700.0, n=0.74, radius=0.05)


@pytest.mark.parametrize(
    "change, pattern",
    [
        (dict(radius=None), "radius"),
        (dict(width=0.05), "radius"),
        (dict(radius=0.0), "radius"),
        (dict(radius=None, width=-0.1), "width"),
        (dict(n=0.0), r"\bn\b"),
        (dict(n=3.5), r"\bn\b"),
        (dict(kc=-1.0), r"\bkc\b"),
        (dict(kphi=-1.0), r"\bkphi\b"),
        (dict(kc=math.inf), r"\bkc\b"),
        (dict(model="rm1"), r"\br_min\b"),
        (dict(model="rm1", r_min=0.0), r"\br_min\b"),
        (dict(model="rm1", r_min=0.1, plate_pair=(0.05, 0.05)), "plate_pair"),
        (dict(model="rm9"), r"\bmodel\b"),
        (dict(units="imperial"), r"\bunits\b"),
    ],
)
def test_errors(change, pattern):
    kw = {**OK, **change}
    with pytest.raises(ValueError, match=pattern):
        plate_pressure(0.1, **kw)


def test_negative_sinkage_rejected():
    with pytest.raises(ValueError, match="sinkage"):
        plate_pressure([0.1, -0.01], **OK)

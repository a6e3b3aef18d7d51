"""Unit conversions: exact factors, round trips and the paper's own tables.

The tables of Huang et al. (Tables 4-1 and 4-3) print every parameter in
both SI and US customary units; each pair must agree within the precision
printed, which is a check of the n-dependent factors of kc and kphi that
owes nothing to terracone.  The tables are read from the package's copies
(terracone/data/paper/), which tests/test_paper_tables.py holds equal, as
printed, to the independently typed ones of ../shared/reference/.
"""

from __future__ import annotations

import math
from decimal import Decimal

import numpy as np
import pytest
from conftest import paper_parameter_rows, require_shared
from hypothesis import given, settings
from hypothesis import strategies as st

from terracone.physics import units as u

# exact definitions, typed independently of terracone.physics.units
INCH_M = 0.0254
LBF_N = 4.4482216152605
PSI_KPA = 6.894757293168361  # 1 lbf/in^2 in kPa (4.4482216152605 N / 0.0254^2 m^2 / 1000)


def test_exact_constants():
    assert u.INCH == INCH_M
    assert u.LBF == LBF_N
    assert math.isclose(u.PSI, PSI_KPA, rel_tol=2e-16)
    # 1 psi = 6.894757293168361 kPa, to the last digit (exact: 6.89475729316836133...)
    exact = Decimal("4.4482216152605") / Decimal("0.0254") ** 2 / 1000
    assert abs(Decimal(u.PSI) - exact) <= Decimal("1e-15")
    assert float(u.pressure_to_si(1.0, "us")) == u.PSI
    assert math.isclose(float(u.pressure_to_si(1.0, "us")), PSI_KPA, rel_tol=2e-16)
    assert float(u.length_to_si(1.0, "us")) == INCH_M
    assert float(u.length_to_si(2.5, "si")) == 2.5
    assert u.LENGTH_UNITS == {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": INCH_M}
    assert u.PRESSURE_UNITS["psi"] == u.PSI
    assert u.PRESSURE_UNITS["mpa"] == 1000.0 and u.PRESSURE_UNITS["pa"] == 0.001


def test_k_factors_dimensional_analysis():
    # n = 1: kc in lb/in^2 is a pressure, so 1 lb/in^2 = 1 psi = PSI kPa
    assert math.isclose(float(u.kc_to_si(1.0, 1.0, "us")), PSI_KPA, rel_tol=1e-15)
    # n = 0: kphi in lb/in^2, likewise
    assert math.isclose(float(u.kphi_to_si(1.0, 0.0, "us")), PSI_KPA, rel_tol=1e-15)
    # n = 0: kc in lb/in = 4.4482216152605e-3 kN / 0.0254 m
    assert math.isclose(float(u.kc_to_si(1.0, 0.0, "us")), LBF_N / 1000 / INCH_M, rel_tol=1e-15)
    # n = 1: kphi in lb/in^3 = psi per inch
    assert math.isclose(float(u.kphi_to_si(1.0, 1.0, "us")), PSI_KPA / INCH_M, rel_tol=1e-15)
    # general n: 1 lb/in^(n+1) = 4.4482216152605e-3 / 0.0254^(n+1) kN/m^(n+1)
    for n in (0.05, 0.391, 0.74, 1.1, 2.0, 3.0):
        assert math.isclose(
            float(u.kc_to_si(1.0, n, "us")), LBF_N / 1000 / INCH_M ** (n + 1), rel_tol=1e-14
        )
        assert math.isclose(
            float(u.kphi_to_si(1.0, n, "us")), LBF_N / 1000 / INCH_M ** (n + 2), rel_tol=1e-14
        )
        # SI is the identity
        assert float(u.kc_to_si(3.7, n, "si")) == 3.7
        assert float(u.kphi_from_si(3.7, n, "si")) == 3.7


def test_paper_quoted_values():
    # Section 2: kc = 32 lb/in^(n+1) (102 kN/m^(n+1)), kphi = 42.2 lb/in^(n+2)
    # (5,301 kN/m^(n+2)), n = 0.79
    kc = float(u.kc_to_si(32.0, 0.79, "us"))
    kphi = float(u.kphi_to_si(42.2, 0.79, "us"))
    # within half a unit of each printed last digit ("32" -> 0.5, "102" -> 0.5 ...)
    assert abs(kc - 102) <= 0.5 * LBF_N / 1000 / INCH_M**1.79 + 0.5
    assert abs(kphi - 5301) <= 0.05 * LBF_N / 1000 / INCH_M**2.79 + 0.5


def test_unit_names_and_errors():
    assert u.length_unit("si") == "m" and u.length_unit("us") == "in"
    assert u.pressure_unit("si") == "kPa" and u.pressure_unit("us") == "psi"
    assert u.kc_unit("us") == "lb/in^(n+1)" and u.kphi_unit("si") == "kN/m^(n+2)"
    for bad in ("SI", "metric", "", None):
        with pytest.raises(ValueError, match="units"):
            u.check_system(bad)
        with pytest.raises(ValueError, match="units"):
            u.kc_to_si(1.0, 0.5, bad)


finite = st.floats(-1e12, 1e12, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(x=finite, n=st.floats(0.0, 3.0, exclude_min=True), system=st.sampled_from(["si", "us"]))
def test_round_trips(x, n, system):
    for to, back in (
        (u.length_to_si, u.length_from_si),
        (u.pressure_to_si, u.pressure_from_si),
    ):
        assert math.isclose(float(back(to(x, system), system)), x, rel_tol=4e-16, abs_tol=1e-300)
    for to, back in ((u.kc_to_si, u.kc_from_si), (u.kphi_to_si, u.kphi_from_si)):
        assert math.isclose(
            float(back(to(x, n, system), n, system)), x, rel_tol=4e-16, abs_tol=1e-300
        )


def test_broadcasting():
    n = np.array([[0.5], [1.0]])
    kc = np.array([1.0, 2.0, 3.0])
    out = u.kc_to_si(kc, n, "us")
    assert out.shape == (2, 3)
    np.testing.assert_allclose(out[1], kc * PSI_KPA, rtol=1e-15)


# ---------------------------------------------------------------------------
# Tables 4-1 and 4-3, both unit systems as printed
# ---------------------------------------------------------------------------


def _half_ulp(printed: str) -> float:
    """Half a unit of the last printed digit: '30.2' -> 0.05, '4075' -> 0.5."""
    return 0.5 * 10.0 ** Decimal(printed).as_tuple().exponent


def _table_rows():
    return paper_parameter_rows()


PAIRS = [  # (US column, SI column, US -> SI, SI -> US)
    (
        "kc_us",
        "kc_si",
        lambda v, n: u.kc_to_si(v, n, "us"),
        lambda v, n: u.kc_from_si(v, n, "us"),
    ),
    (
        "kphi_us",
        "kphi_si",
        lambda v, n: u.kphi_to_si(v, n, "us"),
        lambda v, n: u.kphi_from_si(v, n, "us"),
    ),
    (
        "cc_psi",
        "cc_kpa",
        lambda v, n: u.pressure_to_si(v, "us"),
        lambda v, n: u.pressure_from_si(v, "us"),
    ),
]


@pytest.mark.parametrize("us_col, si_col, to_si, from_si", PAIRS, ids=[p[0] for p in PAIRS])
def test_paper_tables_both_units_agree(us_col, si_col, to_si, from_si):
    """|convert(a) - b| <= convert(half ulp of a) + half ulp of b, both directions."""
    rows = _table_rows()
    assert len(rows) == 12
    for row in rows:
        n = float(row["n"])
        a, b = row[us_col], row[si_col]
        conv = float(to_si(float(a), n))
        tol = float(to_si(_half_ulp(a), n)) + _half_ulp(b)
        assert abs(conv - float(b)) <= tol, (row["dataset"], us_col, a, conv, b, tol)
        back = float(from_si(float(b), n))
        tol_back = float(from_si(_half_ulp(b), n)) + _half_ulp(a)
        assert abs(back - float(a)) <= tol_back, (row["dataset"], si_col, b, back, a, tol_back)


def test_half_ulp_parser():
    assert _half_ulp("30.2") == pytest.approx(0.05)
    assert _half_ulp("4075") == 0.5
    assert _half_ulp("0.318") == pytest.approx(0.0005)
    assert _half_ulp("0") == 0.5


def test_require_shared_skips_when_absent_and_fails_in_ci(monkeypatch, tmp_path):
    monkeypatch.setenv("TERRACONE_SHARED", str(tmp_path))
    (tmp_path / "here.txt").write_text("x")
    assert require_shared("here.txt") == tmp_path.resolve() / "here.txt"
    missing = f"../shared not found: {tmp_path.resolve() / 'absent'} is needed by this test"
    for ci in ("", "0", "false"):
        monkeypatch.setenv("CI", ci)
        with pytest.raises(pytest.skip.Exception) as exc:
            require_shared("absent")
        assert str(exc.value) == missing
    monkeypatch.delenv("CI")
    with pytest.raises(pytest.skip.Exception):
        require_shared("absent")
    for ci in ("true", "1"):
        monkeypatch.setenv("CI", ci)
        with pytest.raises(pytest.fail.Exception) as exc:
            require_shared("absent")
        assert str(exc.value) == f"{missing} (CI: a missing dependency fails)"

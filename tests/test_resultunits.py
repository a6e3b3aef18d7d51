"""The one conversion of results for output (terracone.resultunits), against hand values.

References: 1 in = 0.0254 m and 1 lbf = 4.4482216152605 N exactly (NIST SP 811,
appendix B), so 1 psi = 4.4482216152605 / 0.0254^2 / 1000 kPa; kc [lb/in^(n+1)] =
kc [kN/m^(n+1)] x 0.0254^(n+1) / 0.0044482216152605, kphi likewise with n+2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from decimal import Decimal, getcontext

import numpy as np
import pytest

from terracone.resultunits import (
    Written,
    convert_array,
    convert_parameters,
    field_value,
    from_si,
    output,
    parameter_quantity,
    quantity,
)

getcontext().prec = 40
INCH, LBF = Decimal("0.0254"), Decimal("4.4482216152605")
PSI = LBF / INCH**2 / 1000  # kPa
PSI_F = float(PSI)


def close(a: float, b: Decimal) -> bool:
    return abs(Decimal(a) - b) <= abs(b) * Decimal("4e-16")


def test_lengths_pressures_forces_by_hand():
    assert close(from_si(1.0, "length", "us"), 1 / INCH)
    assert close(from_si(100.0, "pressure", "us"), 100 / PSI)
    assert close(from_si(1000.0, "force", "us"), 1000 / LBF)
    assert close(from_si(2.0, "pressure2", "us"), 2 / PSI**2)  # an SSE [kPa^2] in psi^2
    for q in ("none", "length", "pressure", "pressure2", "force"):
        assert from_si(1.2345, q, "si") == 1.2345  # SI is the identity


@pytest.mark.parametrize("n", [0.5, 1.0, 1.37])
def test_kc_and_kphi_with_their_n_by_hand(n):
    kn_per_lbf = LBF / 1000
    dn = Decimal(n)
    assert close(from_si(50.0, "kc", "us", n), 50 * INCH ** (dn + 1) / kn_per_lbf)
    assert close(from_si(3000.0, "kphi", "us", n), 3000 * INCH ** (dn + 2) / kn_per_lbf)
    assert from_si(50.0, "kc", "si") == 50.0  # no n needed in SI
    with pytest.raises(ValueError, match="kc is converted to US units with its n"):
        from_si(50.0, "kc", "us")


def test_shapes_none_and_non_finite():
    assert from_si(None, "length", "us") is None
    v = from_si(np.float64(0.0254), "length", "us")
    assert type(v) is float and v == pytest.approx(1.0, rel=1e-15)
    assert from_si((0.0254, 0.0508), "length", "us") == pytest.approx([1.0, 2.0], rel=1e-15)
    out = from_si(np.array([0.0254, np.nan]), "length", "us")
    assert isinstance(out, list) and out[0] == pytest.approx(1.0) and math.isnan(out[1])
    assert from_si(np.array([0.0254, np.nan, np.inf]), "length", "us", finite=True)[1:] == [
        None,
        None,
    ]
    assert from_si([None, 0.0254], "length", "us") == [None, pytest.approx(1.0)]
    assert from_si(float("nan"), "none", finite=True) is None
    assert from_si([], "pressure", "us") == []
    with pytest.raises(ValueError, match="unknown quantity 'area'"):
        from_si(1.0, "area", "us")
    with pytest.raises(ValueError, match="units must be 'si' or 'us'"):
        from_si(1.0, "length", "imperial")


def test_arrays_back_and_forth_with_each_values_n():
    kc, n = np.array([10.0, 80.0]), np.array([0.6, 1.2])
    us = convert_array(kc, "kc", "us", n)
    assert us[1] == pytest.approx(float(80 * INCH ** (Decimal(1.2) + 1) / (LBF / 1000)), rel=1e-15)
    assert convert_array(us, "kc", "us", n, to_si=True) == pytest.approx(kc, rel=1e-15)


def test_parameter_names_and_their_quantities():
    assert [parameter_quantity(k) for k in ("kc", "kphi_2", "cc", "interface_1", "r_min")] == [
        "kc",
        "kphi",
        "pressure",
        "length",
        "length",
    ]
    assert parameter_quantity("n_2") == parameter_quantity("phic_deg") == "none"
    iv = convert_parameters({"cc": (0.0, PSI_F), "n": (0.5, 0.9), "r_min": 0.0254}, "us", 1.0)
    assert iv == {"cc": [0.0, pytest.approx(1.0)], "n": [0.5, 0.9], "r_min": pytest.approx(1.0)}


@dataclass
class _Inner(Written):
    depth: np.ndarray = quantity("length")
    units_key = True


@dataclass
class _Fit:
    name: str
    kc: float = quantity("kc", n="n")
    n: float = quantity("none")
    K_cone: float | None = quantity("length", key="Kc", default=None)
    curve: _Inner | None = None
    notes: tuple[str, ...] = ("a",)
    cv: list[float] = quantity("none", finite=True, default_factory=list)
    tests: list[_Inner] = field(default_factory=list)


def test_output_walks_the_declared_fields_in_order():
    fit = _Fit("x", 50.0, 1, 0.0254, _Inner(np.array([0.0254])), cv=[0.1, math.nan])
    fit.tests = [_Inner(np.array([0.0508]))]
    d = output(fit, "us")
    assert list(d) == ["name", "kc", "n", "Kc", "curve", "notes", "cv", "tests"]
    assert close(d["kc"], 50 * INCH**2 / (LBF / 1000))
    assert d["n"] == 1.0 and type(d["n"]) is float
    assert d["Kc"] == pytest.approx(1.0) and d["notes"] == ["a"] and d["cv"] == [0.1, None]
    assert d["curve"] == {"depth": [pytest.approx(1.0)], "units": "us"}
    assert d["tests"] == [{"depth": [pytest.approx(2.0)], "units": "us"}]
    assert list(output(fit, "si", fields=("n", "name"))) == ["n", "name"]
    assert field_value(fit, "K_cone", "us") == pytest.approx(1.0)
    with pytest.raises(ValueError, match="_Fit has no field 'Kc'"):
        field_value(fit, "Kc", "us")

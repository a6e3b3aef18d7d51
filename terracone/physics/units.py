"""Unit systems and exact conversion factors.

quantity       SI (``"si"``)           US customary (``"us"``)
=============  ======================  =========================
length         m                       in
pressure       kPa                     psi
kc             kN/m^(n+1)              lb/in^(n+1)
kphi           kN/m^(n+2)              lb/in^(n+2)
force          N                       lbf
=============  ======================  =========================

terracone computes in the paper's SI system and converts at the edges to US
customary units.  The factors are exact: 1 in = 0.0254 m and 1 lbf =
4.4482216152605 N.  The factors of kc and kphi depend on the sinkage exponent n.

Quantities written with their unit (``"10 kN"``, ``"40 in"``, ``"190 hp"``,
``"90 in2"``, as in a vehicle file) are read by :func:`quantity_to_si`.  Its factors are
exact by definition [2]_: 1 ft = 12 in, 1 kip = 1000 lbf, 1 kgf = 9.80665 N
(standard gravity), 1 hp = 550 ft lbf/s = 745.69987158227 W (mechanical
horsepower); a mass (kg, t) stands for its weight under standard gravity.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Nomenclature and Tables 4-1 to 4-4.
.. [2] NIST Special Publication 811 (2008), Guide for the Use of the
   International System of Units, Appendix B (conversion factors) and
   section 8.6 (standard acceleration of gravity g_n = 9.80665 m/s^2).
"""

from __future__ import annotations

import math
import re
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "INCH",
    "LBF",
    "PSI",
    "UnitSystem",
    "LENGTH_UNITS",
    "PRESSURE_UNITS",
    "check_system",
    "length_to_si",
    "length_from_si",
    "pressure_to_si",
    "pressure_from_si",
    "kc_to_si",
    "kc_from_si",
    "kphi_to_si",
    "kphi_from_si",
    "length_unit",
    "pressure_unit",
    "kc_unit",
    "kphi_unit",
    "force_unit",
    "force_from_si",
    "force_to_si",
    "G_N",
    "HP",
    "QUANTITY_UNITS",
    "quantity_to_si",
]

INCH = 0.0254  # [m], exact
LBF = 4.4482216152605  # [N], exact
PSI = LBF / INCH**2 / 1000.0  # [kPa]

G_N = 9.80665  # standard acceleration of gravity [m/s^2], exact [2]
HP = 550.0 * 12.0 * INCH * LBF  # mechanical horsepower, 550 ft lbf/s [W], exact [2]

UnitSystem = Literal["si", "us"]

#: Length units accepted in file column suffixes and on the command line [m].
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": INCH}
#: Pressure units accepted in file column suffixes [kPa].
PRESSURE_UNITS: dict[str, float] = {"kpa": 1.0, "mpa": 1000.0, "psi": PSI, "pa": 0.001}

#: Units of quantities written with their unit (:func:`quantity_to_si`), per kind,
#: as factors to SI (m, N, W); names are matched without regard to case.
QUANTITY_UNITS: dict[str, dict[str, float]] = {
    "length": {**LENGTH_UNITS, "ft": 12.0 * INCH},
    "force": {
        "n": 1.0,
        "kn": 1000.0,
        "lbf": LBF,
        "lb": LBF,
        "kip": 1000.0 * LBF,
        "kips": 1000.0 * LBF,
        "kgf": G_N,
        "kg": G_N,  # a mass: its weight under standard gravity
        "t": 1000.0 * G_N,
    },
    "power": {"w": 1.0, "kw": 1000.0, "hp": HP},
    "area": {"m2": 1.0, "cm2": 1e-4, "mm2": 1e-6, "in2": INCH**2, "ft2": (12.0 * INCH) ** 2},
}
_SI_NAME = {"length": "m", "force": "N", "power": "W", "area": "m^2"}
_EXAMPLE = {"length": "'40 in'", "force": "'10 kN'", "power": "'190 hp'", "area": "'90 in2'"}
_QUANTITY_RE = re.compile(
    r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z][A-Za-z0-9^]*)?\s*$"
)

_SYSTEM_LENGTH = {"si": 1.0, "us": INCH}
_SYSTEM_PRESSURE = {"si": 1.0, "us": PSI}
_KN_PER_LBF = LBF / 1000.0


def check_system(units: str) -> UnitSystem:
    """Return ``units`` if it names a unit system, else raise ValueError."""
    if units not in ("si", "us"):
        raise ValueError(f"units must be 'si' or 'us' (got {units!r})")
    return units  # type: ignore[return-value]


def length_to_si(value: ArrayLike, units: str) -> np.ndarray:
    """Length in the system's unit (m or in) to [m]."""
    return np.asarray(value, dtype=float) * _SYSTEM_LENGTH[check_system(units)]


def length_from_si(value: ArrayLike, units: str) -> np.ndarray:
    """Length in [m] to the system's unit (m or in)."""
    return np.asarray(value, dtype=float) / _SYSTEM_LENGTH[check_system(units)]


def pressure_to_si(value: ArrayLike, units: str) -> np.ndarray:
    """Pressure in the system's unit (kPa or psi) to [kPa]."""
    return np.asarray(value, dtype=float) * _SYSTEM_PRESSURE[check_system(units)]


def pressure_from_si(value: ArrayLike, units: str) -> np.ndarray:
    """Pressure in [kPa] to the system's unit (kPa or psi)."""
    return np.asarray(value, dtype=float) / _SYSTEM_PRESSURE[check_system(units)]


def _k_factor(n: ArrayLike, extra: int, units: str) -> np.ndarray | float:
    # 1 lb/in^(n+extra) expressed in kN/m^(n+extra); 1 in SI
    if check_system(units) == "si":
        return 1.0
    return _KN_PER_LBF / INCH ** (np.asarray(n, dtype=float) + extra)


def kc_to_si(kc: ArrayLike, n: ArrayLike, units: str) -> np.ndarray:
    """kc in the system's unit to [kN/m^(n+1)]; lb/in^(n+1) for ``"us"``."""
    return np.asarray(kc, dtype=float) * _k_factor(n, 1, units)


def kc_from_si(kc: ArrayLike, n: ArrayLike, units: str) -> np.ndarray:
    """kc in [kN/m^(n+1)] to the system's unit."""
    return np.asarray(kc, dtype=float) / _k_factor(n, 1, units)


def kphi_to_si(kphi: ArrayLike, n: ArrayLike, units: str) -> np.ndarray:
    """kphi in the system's unit to [kN/m^(n+2)]; lb/in^(n+2) for ``"us"``."""
    return np.asarray(kphi, dtype=float) * _k_factor(n, 2, units)


def kphi_from_si(kphi: ArrayLike, n: ArrayLike, units: str) -> np.ndarray:
    """kphi in [kN/m^(n+2)] to the system's unit."""
    return np.asarray(kphi, dtype=float) / _k_factor(n, 2, units)


def length_unit(units: str) -> str:
    """Name of the length unit of a system."""
    return {"si": "m", "us": "in"}[check_system(units)]


def pressure_unit(units: str) -> str:
    """Name of the pressure unit of a system."""
    return {"si": "kPa", "us": "psi"}[check_system(units)]


def kc_unit(units: str) -> str:
    """Name of the unit of kc in a system."""
    return {"si": "kN/m^(n+1)", "us": "lb/in^(n+1)"}[check_system(units)]


def kphi_unit(units: str) -> str:
    """Name of the unit of kphi in a system."""
    return {"si": "kN/m^(n+2)", "us": "lb/in^(n+2)"}[check_system(units)]


def force_to_si(value: ArrayLike, units: str) -> np.ndarray:
    """Force in the system's unit (N or lbf) to [N]."""
    return np.asarray(value, dtype=float) * {"si": 1.0, "us": LBF}[check_system(units)]


def force_from_si(value: ArrayLike, units: str) -> np.ndarray:
    """Force in [N] to the system's unit (N or lbf)."""
    return np.asarray(value, dtype=float) / {"si": 1.0, "us": LBF}[check_system(units)]


def force_unit(units: str) -> str:
    """Name of the force unit of a system."""
    return {"si": "N", "us": "lbf"}[check_system(units)]


def quantity_to_si(value: Any, kind: str) -> float:
    """A quantity written with its unit (``"10 kN"``, ``"40 in"``) or a bare number in SI.

    Parameters
    ----------
    value : str or float
        A string ``"<number> <unit>"`` with a unit of :data:`QUANTITY_UNITS`
        for ``kind`` (case ignored), or a bare number (int or float) taken
        as SI (m, N, W).
    kind : {"length", "force", "power", "area"}

    Returns
    -------
    float
        The value in SI: [m], [N], [W] or [m^2] (areas: ``m2 cm2 mm2 in2 ft2``,
        also written ``in^2``).

    Raises
    ------
    ValueError
        A string without a unit, an unknown unit, a non-finite number or
        another type; the message says what was expected.
    """
    table = QUANTITY_UNITS[kind]
    if isinstance(value, bool) or value is None:
        raise ValueError(f"expected a {kind} such as {_EXAMPLE[kind]}, got {value!r}")
    if isinstance(value, int | float):
        v = float(value)
    elif isinstance(value, str):
        m = _QUANTITY_RE.match(value)
        if not m:
            raise ValueError(
                f"expected a {kind} with its unit, e.g. {_EXAMPLE[kind]}, got {value!r}"
            )
        if m.group(2) is None:
            raise ValueError(
                f"{value!r} has no unit: write it with one ({', '.join(table)}) "
                f"or as a bare number in {_SI_NAME[kind]}"
            )
        unit = m.group(2).lower().replace("^", "")
        if unit not in table:
            raise ValueError(
                f"unknown {kind} unit {m.group(2)!r} in {value!r} (known: {', '.join(table)})"
            )
        v = float(m.group(1)) * table[unit]
    else:
        raise ValueError(f"expected a {kind} such as {_EXAMPLE[kind]} or a number, got {value!r}")
    if not math.isfinite(v):
        raise ValueError(f"{value!r} is not a finite {kind}")
    return v

"""Unit systems and exact conversion factors.

terracone computes in the paper's SI system (m, kPa, kN/m^(n+1), kN/m^(n+2))
and converts at the edges to US customary (in, psi, lb/in^(n+1),
lb/in^(n+2)); 1 in = 0.0254 m and 1 lbf = 4.4482216152605 N exactly.  The
factors of kc and kphi depend on the sinkage exponent n.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Nomenclature and Tables 4-1 to 4-4.
"""

from __future__ import annotations

from typing import Literal

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
]

INCH = 0.0254  # [m], exact
LBF = 4.4482216152605  # [N], exact
PSI = LBF / INCH**2 / 1000.0  # [kPa]

UnitSystem = Literal["si", "us"]

#: Length units accepted in file column suffixes and on the command line [m].
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": INCH}
#: Pressure units accepted in file column suffixes [kPa].
PRESSURE_UNITS: dict[str, float] = {"kpa": 1.0, "mpa": 1000.0, "psi": PSI, "pa": 0.001}

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

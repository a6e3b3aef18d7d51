"""Plate pressure-sinkage: the Bekker equation and the RM1 variant of [1]_.

Bekker's p = (kc/b + kphi) z^n (eq. (2-2) in [1]_) and RM1 (section 3.2)
both have the form p = [kc (alpha - beta b) + kphi] z^n, so a
:class:`PressureLaw` is described by (r_t, alpha, beta); ``docs/physics.md``
gives them for RM0, the RM1 tangent and the RM1 secant.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-2) and section 3.2.
.. [2] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
   University of Michigan Press.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from terracone.physics import units as u

__all__ = [
    "PressureLaw",
    "pressure_law",
    "pressure_bekker",
    "plate_pressure",
    "plate_basis",
]


@dataclass(frozen=True)
class PressureLaw:
    """Size dependence of the pressure: RM0 or RM1 (section 3.2 in [1]_).

    Attributes
    ----------
    model : {"rm0", "rm1"}
    r_min : float or ndarray or None
        Transition radius [m] (RM1 only); may be an array to evaluate many
        laws at once.
    plate_pair : (r1, r2) or None
        Plate radii [m] of the pair used in the learning process.
    """

    model: str = "rm0"
    r_min: object = None
    plate_pair: tuple[float, float] | None = None

    @property
    def is_rm0(self) -> bool:
        return self.model == "rm0"

    def coefficients(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(r_t, alpha, beta) of the linear branch p = [kc(alpha - beta b) + kphi] z^n."""
        if self.is_rm0:
            z = np.zeros(())
            return z, z, z
        rm = np.asarray(self.r_min, dtype=float)
        alpha = 2.0 / rm  # tangent at r_min (RM1 in section 3.2)
        beta = 1.0 / rm**2
        if self.plate_pair is not None:
            r1, r2 = sorted(self.plate_pair)
            secant = rm > r2  # line through (r1, p1) and (r2, p2)
            alpha = np.where(secant, (r1 + r2) / (r1 * r2), alpha)
            beta = np.where(secant, 1.0 / (r1 * r2), beta)
        return rm, alpha, beta

    def kc_factor(self, b: ArrayLike) -> np.ndarray:
        """Multiplier of kc in p / z^n for a plate of size b [m]: 1/b or alpha - beta b."""
        b = np.asarray(b, dtype=float)
        if self.is_rm0:
            return 1.0 / b
        r_t, alpha, beta = self.coefficients()
        return np.where(b < r_t, alpha - beta * b, 1.0 / b)


def pressure_law(
    model: str = "rm0",
    *,
    r_min: ArrayLike | None = None,
    plate_pair: tuple[float, float] | None = None,
    units: str = "si",
) -> PressureLaw:
    """Build and check a :class:`PressureLaw` (lengths r_min, plate_pair in [m] or [in] for us)."""
    if model not in ("rm0", "rm1"):
        raise ValueError(f"model must be 'rm0' or 'rm1' (got {model!r})")
    if model == "rm0":
        return PressureLaw("rm0")
    if r_min is None:
        raise ValueError("r_min is required with model 'rm1'")
    rm = u.length_to_si(r_min, units)
    if not np.all(np.isfinite(rm)) or np.any(rm <= 0):
        raise ValueError("r_min must be > 0")
    if plate_pair is not None:
        r1, r2 = (float(v) for v in u.length_to_si(plate_pair, units))
        if not (r1 > 0 and r2 > 0 and r1 != r2):
            raise ValueError("plate_pair must be two different positive radii")
        plate_pair = (min(r1, r2), max(r1, r2))
    return PressureLaw("rm1", rm if rm.ndim else float(rm), plate_pair)


def pressure_bekker(
    sinkage: ArrayLike, *, kc: ArrayLike, kphi: ArrayLike, n: ArrayLike, b: ArrayLike
) -> np.ndarray:
    """Bekker's pressure-sinkage equation p = (kc/b + kphi) z^n, SI.

    Parameters
    ----------
    sinkage : array_like
        Sinkage z [m].
    kc : array_like
        [kN/m^(n+1)]
    kphi : array_like
        [kN/m^(n+2)]
    n : array_like
        Sinkage exponent [-].
    b : array_like
        Plate size [m]: radius of a circular plate, smaller side of a
        rectangular one.

    Returns
    -------
    ndarray
        Pressure p [kPa].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eq. (2-2).
    .. [2] Bekker (1969).
    """
    # eq. (2-2)
    return (np.asarray(kc) / np.asarray(b) + np.asarray(kphi)) * np.asarray(
        sinkage, float
    ) ** np.asarray(n)


def plate_basis(sinkage: ArrayLike, *, n: ArrayLike, b: ArrayLike, law: PressureLaw | None = None):
    """Columns (A, B) with p = kc*A + kphi*B for a plate of size b [m], SI."""
    law = law or PressureLaw()
    z = np.asarray(sinkage, dtype=float)
    zn = np.where(z > 0, np.abs(z), 0.0) ** np.asarray(n, dtype=float)
    return law.kc_factor(b) * zn, zn


def plate_pressure(
    sinkage: ArrayLike,
    *,
    kc: ArrayLike,
    kphi: ArrayLike,
    n: ArrayLike,
    radius: ArrayLike | None = None,
    width: ArrayLike | None = None,
    model: str = "rm0",
    r_min: ArrayLike | None = None,
    units: str = "si",
    plate_pair: tuple[float, float] | None = None,
) -> np.ndarray:
    """Pressure under a plate at given sinkages.

    Parameters
    ----------
    sinkage : array_like
        Sinkage z >= 0 [m or in].
    kc, kphi, n : array_like
        Bekker parameters [kN/m^(n+1), kN/m^(n+2), -] or [lb/in^(n+1), lb/in^(n+2), -].
    radius : array_like, optional
        Radius of a circular plate (b = radius) [m or in].
    width : array_like, optional
        Smaller side of a rectangular plate (b = width) [m or in].
    model : {"rm0", "rm1"}
        Bekker (RM0) or RM1 of section 3.2.
    r_min : array_like, optional
        RM1 transition radius [m or in].
    units : {"si", "us"}
    plate_pair : (r1, r2), optional
        Plate radii [m or in]; with RM1 and r_min > r2 the linear branch is
        the line through the pair's Bekker pressures (section 3.2 in [1]_).

    Returns
    -------
    ndarray
        Pressure [kPa or psi].
    """
    units = u.check_system(units)
    if (radius is None) == (width is None):
        raise ValueError("give exactly one of radius and width")
    b = u.length_to_si(radius if radius is not None else width, units)
    if not np.all(np.isfinite(b)) or np.any(b <= 0):
        raise ValueError(("radius" if radius is not None else "width") + " must be > 0")
    n_arr = np.asarray(n, dtype=float)
    if not np.all(np.isfinite(n_arr)) or np.any(n_arr <= 0) or np.any(n_arr > 3):
        raise ValueError("n must satisfy 0 < n <= 3")
    for name, val in (("kc", kc), ("kphi", kphi)):
        a = np.asarray(val, dtype=float)
        if not np.all(np.isfinite(a)) or np.any(a < 0):
            raise ValueError(f"{name} must be finite and >= 0")
    z = u.length_to_si(sinkage, units)
    if not np.all(np.isfinite(z)) or np.any(z < 0):
        raise ValueError("sinkage must be finite and >= 0")
    law = pressure_law(model, r_min=r_min, plate_pair=plate_pair, units=units)
    A, B = plate_basis(z, n=n_arr, b=b, law=law)
    p = u.kc_to_si(kc, n_arr, units) * A + u.kphi_to_si(kphi, n_arr, units) * B
    return u.pressure_from_si(p, units)

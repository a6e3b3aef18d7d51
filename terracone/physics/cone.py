"""Cone geometry and the cone-index models of Huang et al. [1]_.

:func:`cone_index_huang` is the improved model, eqs. (2-2) to (2-7);
:func:`cone_index_janosi` Janosi's equation (2-1); :func:`cone_index` either,
with unit conversion at the edges.  The integrals over the cone are
incomplete moments G_k(eps) = integral_0^eps w^k (1 - w)^n dw, k = 0, 1, 2,
in closed form or by their binomial series deep below the surface;
``docs/physics.md`` explains the evaluation.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 2 and section 3.2.
.. [2] ASABE S313.3, Soil cone penetrometer.
.. [3] Eijkelkamp Soil & Water, Penetrologger operating instructions: cones
   of 1, 2, 3.33 and 5 cm^2 base area, 60 deg top angle.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from terracone.physics import units as u
from terracone.physics.plate import PressureLaw, pressure_law

__all__ = [
    "Cone",
    "CONES",
    "CONE_ANGLE_RANGE",
    "CONE_DIAMETER_RANGE",
    "get_cone",
    "cone_index",
    "cone_index_basis",
    "cone_index_huang",
    "cone_index_janosi",
    "normal_integrals",
    "check_depth",
]


@dataclass(frozen=True)
class Cone:
    """A right circular cone penetrometer tip.

    Parameters
    ----------
    name : str
        Label of the cone.
    base_area : float
        Area of the cone base [m^2].
    angle_deg : float
        Included (apex) angle [deg]; the half angle is the paper's 15 deg for
        the standard 30 deg cone.
    """

    name: str
    base_area: float
    angle_deg: float

    def __post_init__(self) -> None:
        if not (self.base_area > 0 and math.isfinite(self.base_area)):
            raise ValueError(
                f"cone {self.name!r}: base area must be positive (got {self.base_area})"
            )
        _check_diameter(self.name, 2.0 * math.sqrt(self.base_area / math.pi))
        lo, hi = CONE_ANGLE_RANGE
        if not lo <= self.angle_deg <= hi:
            raise ValueError(
                f"cone {self.name!r}: included angle {self.angle_deg:g} deg is outside the "
                f"range of penetrometer cones, {lo:g} to {hi:g} deg (ASABE cones: 30, "
                "Penetrologger cones: 60)"
            )

    @property
    def radius(self) -> float:
        """Base radius R = sqrt(A / pi) [m]."""
        return math.sqrt(self.base_area / math.pi)

    @property
    def half_angle(self) -> float:
        """Half of the included angle [rad] (15 deg in the paper)."""
        return math.radians(self.angle_deg) / 2.0

    @property
    def height(self) -> float:
        """Height from base to tip H = R / tan(angle / 2) [m] (Figure 2-2 in [1])."""
        return self.radius / math.tan(self.half_angle)


#: Included angle [deg] and base diameter [m] a cone must have: a plausibility
#: guard, not a standard.  The named cones below span 30 to 60 deg and 12.8 to
#: 25.2 mm; the ranges are wide enough for every penetrometer cone terracone
#: knows of, while a cone sharper than 10 deg is a needle (its height is more
#: than 11 diameters), one blunter than 120 deg nearly a flat plate, and a
#: diameter below 1 mm or above 150 mm a typing error (20mm:1e-300, 1e300mm:30).
CONE_ANGLE_RANGE = (10.0, 120.0)
CONE_DIAMETER_RANGE = (1e-3, 0.15)


def _check_diameter(name: str, d: float) -> None:
    lo, hi = CONE_DIAMETER_RANGE
    if not (math.isfinite(d) and lo <= d <= hi):
        raise ValueError(
            f"cone {name!r}: base diameter {d * 1000:.4g} mm is outside the range of "
            f"penetrometer cones, {lo * 1000:g} to {hi * 1000:g} mm (base area "
            f"{math.pi * (lo * 100) ** 2 / 4:.3g} to {math.pi * (hi * 100) ** 2 / 4:.3g} cm^2)"
        )


#: Named cones of ASABE S313 [2]_: 30 deg, 0.5 in^2 (large) and 0.2 in^2 (small),
#: and the 60 deg cones of the Eijkelkamp Penetrologger [3]_: 1, 2, 3.33, 5 cm^2.
CONES: dict[str, Cone] = {
    "asabe-large": Cone("asabe-large", 0.5 * u.INCH**2, 30.0),
    "asabe-small": Cone("asabe-small", 0.2 * u.INCH**2, 30.0),
    **{
        f"penetrologger-{a}cm2": Cone(f"penetrologger-{a}cm2", float(a) * 1e-4, 60.0)
        for a in ("1", "2", "3.33", "5")
    },
}

_CUSTOM = re.compile(r"^\s*([0-9.eE+-]+)\s*(m|cm|mm|in)\s*[:@]\s*([0-9.eE+-]+)\s*(deg)?\s*$")
_CUSTOM_AREA = re.compile(
    r"^\s*([0-9.eE+-]+)\s*(m|cm|mm|in)(?:2|\^2|²)\s*[:@]\s*([0-9.eE+-]+)\s*(deg)?\s*$"
)


def get_cone(cone: str | Cone) -> Cone:
    """Return a :class:`Cone` from a name, a custom spec or a Cone.

    ``"20.27mm:30"`` is a custom cone of 20.27 mm base diameter and 30 deg
    included angle; ``"5cm2:60"`` (also ``"5 cm^2:60"``, ``"0.5in2:30"``) one
    of 5 cm^2 base area and 60 deg.  Names: :data:`CONES` (``asabe-large``,
    ``asabe-small``, ``penetrologger-1cm2``, ``-2cm2``, ``-3.33cm2``,
    ``-5cm2``).
    """
    if isinstance(cone, Cone):
        return cone
    if cone in CONES:
        return CONES[cone]
    m = _CUSTOM_AREA.match(str(cone))
    if m:
        try:
            area = float(m.group(1)) * u.LENGTH_UNITS[m.group(2)] ** 2
            angle = float(m.group(3))
        except ValueError as exc:
            raise ValueError(f"cone {cone!r}: {exc}") from None
        return Cone(str(cone).strip(), area, angle)
    m = _CUSTOM.match(str(cone))
    if m:
        try:
            d = float(m.group(1)) * u.LENGTH_UNITS[m.group(2)]
            angle = float(m.group(3))
        except ValueError as exc:
            raise ValueError(f"cone {cone!r}: {exc}") from None
        _check_diameter(str(cone).strip(), d)  # before d**2 can overflow
        return Cone(str(cone).strip(), math.pi * d**2 / 4.0, angle)
    raise ValueError(
        f"cone must be one of {sorted(CONES)}, 'DIAMETER<m|cm|mm|in>:ANGLE' (e.g. 20.27mm:30) "
        f"or 'AREA<cm2|mm2|in2>:ANGLE' (e.g. 5cm2:60) (got {cone!r})"
    )


# ---------------------------------------------------------------------------
# incomplete moments
# ---------------------------------------------------------------------------

_SERIES_EPS = 0.01  # below this the series is used (closed form loses ~1e-16/eps^2)
_SERIES_TERMS = 10  # 0.01**10 = 1e-20


def _tail_moments(eps: np.ndarray, n: np.ndarray, second: bool = True):
    """G_k(eps) = int_0^eps w^k (1-w)^n dw for k = 0, 1 (and 2), eps in [0, 1].

    With x = 1 - eps and e1 = x^(n+1) - 1 (one ``expm1``), the closed forms
    are G_0 = (1 - x^(n+1))/(n+1) and G_1 = G_0 - (1 - x^(n+2))/(n+2), with
    1 - x^(n+2) = eps - e1 x and 1 - x^(n+3) = eps(2 - eps) - e1 x^2, sums
    of non-negative terms.  Below eps = 0.01 (deep below the surface) G_1
    and G_2 would cancel, and the binomial series
    G_k = sum_j binom(n, j) (-1)^j eps^(j+k+1)/(j+k+1) is used instead.
    """
    eps = np.asarray(eps, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = 1.0 - eps
        e1 = np.expm1((n + 1.0) * np.log1p(-eps))
        n1 = n + 1.0
        n2 = n + 2.0
        g0 = -e1 / n1
        g1 = g0 - (eps - e1 * x) / n2
        g2 = (
            g1 - (eps - e1 * x) / n2 + (eps * (2.0 - eps) - e1 * x * x) / (n + 3.0)
            if second
            else None
        )
    small = eps < _SERIES_EPS
    if small.any():
        shape = np.broadcast_shapes(eps.shape, np.shape(n))
        sm = np.broadcast_to(small, shape)
        e = np.broadcast_to(eps, shape)[sm]
        nn = np.broadcast_to(n, shape)[sm]
        emax = float(e.max())  # terms needed for 1e-17 at the largest eps of the subset
        need = int(math.ceil(-17 / math.log10(emax))) + 1 if emax > 0 else _SERIES_TERMS
        terms = min(_SERIES_TERMS, max(2, need))
        s0 = np.zeros_like(e)
        s1 = np.zeros_like(e)
        s2 = np.zeros_like(e) if second else None
        cp = e.copy()  # binom(n, j) (-1)^j eps^(j+1)
        for jj in range(terms):
            s0 += cp / (jj + 1)
            ce = cp * e
            s1 += ce / (jj + 2)
            if second:
                s2 += ce * e / (jj + 3)
            cp = ce * ((jj - nn) / (jj + 1))
        g = [g0, g1, g2]
        for k, sk in enumerate((s0, s1, s2) if second else (s0, s1)):
            g[k] = np.array(np.broadcast_to(g[k], shape), dtype=float)
            g[k][sm] = sk
        g0, g1, g2 = g
    return g0, g1, g2


# Double-exponential (tanh-sinh) rule on [0, 1], used only for finite Kc.
def _de_rule(h: float = 1.0 / 16.0, tmax: float = 3.6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(-tmax, tmax + h / 2, h)
    v = 0.5 * math.pi * np.sinh(t)
    sigma = 1.0 / (1.0 + np.exp(-2.0 * v))
    one_minus = 1.0 / (1.0 + np.exp(2.0 * v))
    w = h * 0.5 * math.pi * np.cosh(t) / (2.0 * np.cosh(v) ** 2)
    return sigma, one_minus, w


_DE_SIGMA, _DE_ONE_MINUS, _DE_W = _de_rule()


def _check_nonneg(name: str, value: ArrayLike) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    lo, hi = (a.min(), a.max()) if a.size else (0.0, 0.0)
    if not (lo >= 0 and hi < np.inf):  # NaN fails both comparisons
        raise ValueError(f"{name} must be finite and >= 0 (got {lo if lo < 0 else hi})")
    return a


def _check_n(n: ArrayLike) -> np.ndarray:
    a = np.asarray(n, dtype=float)
    if a.size and not (a.min() > 0 and a.max() <= 3):
        raise ValueError("n must satisfy 0 < n <= 3")
    return a


def _check_phic(phic_deg: ArrayLike) -> np.ndarray:
    a = np.asarray(phic_deg, dtype=float)
    if a.size and not (a.min() >= 0 and a.max() < 90):
        raise ValueError("phic must satisfy 0 <= phic < 90 deg")
    return a


def _check_K_cone(K_cone: ArrayLike | None) -> np.ndarray | None:
    if K_cone is None:
        return None
    a = np.asarray(K_cone, dtype=float)
    if a.size and not (a.min() > 0 and a.max() < np.inf):
        raise ValueError("Kc must be > 0 (or None for fully mobilised shear)")
    return a


def check_depth(depth: ArrayLike, cone: Cone) -> np.ndarray:
    """Cone-base depths [m] as a float array, checked: finite and not above -H.

    The tip enters the surface at z = -H (Figure 2-2 of [1]_); a depth a rounding
    step above -H is taken as -H.

    Raises
    ------
    ValueError
        A depth that is not finite or lies above -H (the cone then carries no load).
    """
    z = np.asarray(depth, dtype=float)
    lo, hi = (z.min(), z.max()) if z.size else (0.0, 0.0)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ValueError("depth must be finite")
    if lo < -cone.height * (1 + 1e-12):
        raise ValueError(
            f"depth must be >= -H = {-cone.height:.6g} m (the tip above the surface carries no load)"
        )
    return np.maximum(z, -cone.height) if lo < -cone.height else z


def cone_index_basis(
    depth: ArrayLike,
    *,
    n: ArrayLike,
    phic_deg: ArrayLike = 0.0,
    K_cone: ArrayLike | None = None,
    law: PressureLaw | None = None,
    cone: str | Cone = "asabe-large",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Columns A, B, C with CI = kc*A + kphi*B + cc*C, all in SI.

    For fixed n, phic, Kc and pressure law, the improved model (eq. (2-7)) is
    linear in kc, kphi and cc.  This returns its three columns.

    Parameters
    ----------
    depth : array_like
        Depth of the cone base below the surface [m]; -H <= z.
    n : array_like
        Sinkage exponent [-].
    phic_deg : array_like
        Cone-terrain friction angle [deg].
    K_cone : array_like or None
        Cone-terrain shear deformation parameter [m]; None for fully
        mobilised shear.
    law : PressureLaw
        RM0 or RM1 pressure law (section 3.2); RM0 when None.
    cone : str or Cone

    Returns
    -------
    A, B, C : ndarray
        [kPa per kN/m^(n+1)], [kPa per kN/m^(n+2)] and [-].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eqs. (2-5) to (2-7).
    """
    cone = get_cone(cone)
    law = law or pressure_law("rm0")
    z = check_depth(depth, cone)
    n = _check_n(n)
    phic_deg = _check_phic(phic_deg)
    return _basis(z, n, phic_deg, K_cone, law, cone)


def _integrals(z: np.ndarray, n: np.ndarray, law: PressureLaw, cone: Cone):
    """int p r du per unit kc and kphi, and int r du, over the embedded cone (unchecked)."""
    H = cone.height
    t = cone.radius / H  # tan(half angle), tan 15 deg in the paper
    u1 = z + H  # depth of the tip
    L = np.where(z >= 0.0, H, u1)  # embedded length along the axis (rec. F of [1])
    live = u1 > 0.0
    if live.all():
        return normal_integrals(u1, None, L, n, law, t), u1, L
    u1s = np.where(live, u1, 1.0)
    ints = normal_integrals(u1s, None, L, n, law, t)
    return tuple(np.where(live, v, 0.0) for v in ints), u1, L


def _basis(z, n, phic, Kc, law: PressureLaw, cone: Cone):
    """Columns A, B, C of :func:`cone_index_basis` without input checks."""
    R, H = cone.radius, cone.height
    t = R / H
    tan_phic = np.tan(np.radians(phic))
    (I_c, I_phi, I_cc), u1, L = _integrals(z, n, law, cone)
    if Kc is None:
        # fully mobilised shear: eq. (2-6) with 1 - exp(-j/Kc) = 1
        S_c, S_phi, S_cc = I_c, I_phi, I_cc
    else:
        r_t = law.coefficients()[0]
        d_s = np.minimum(np.asarray(r_t, dtype=float) / t, L)
        S_c, S_phi, S_cc = _mobilised(z, u1, L, d_s, n, law, np.asarray(Kc, float), cone)

    # eq. (2-7): CI = (Fp + Fs) / (pi R^2), Fp = 2 pi tan(a) I, Fs = 2 pi (cc I_cc + tan(phic) I)
    A = 2.0 * (t * I_c + tan_phic * S_c) / (R * R)
    B = 2.0 * (t * I_phi + tan_phic * S_phi) / (R * R)
    C = 2.0 * S_cc / (R * R)
    return A, B, C


def _improved(z, kc, kphi, n, cc, phic, Kc, law: PressureLaw, cone: Cone) -> np.ndarray:
    """Eq. (2-7) without input checks (SI)."""
    if Kc is not None:
        A, B, C = _basis(z, n, phic, Kc, law, cone)
        return kc * A + kphi * B + cc * C
    R, H = cone.radius, cone.height
    t = R / H
    fac = (2.0 / (R * R)) * (t + np.tan(np.radians(phic)))
    u1 = z + H
    if law.is_rm0 and u1.size and u1.min() > 0:
        L = np.where(z >= 0.0, H, u1)
        eps = L / u1
        if eps.min() >= _SERIES_EPS:
            # fast path of the same closed form (RM0, fully mobilised, no series needed):
            # kc I_c + kphi I_phi = u1^(n+1) [e1 (-kc/(n+1) + kphi t (u0/(n+2) - u1/(n+1)))
            #                                 - kphi t L/(n+2)],  e1 = (u0/u1)^(n+1) - 1
            n1 = n + 1.0
            n2 = n + 2.0
            kpt = kphi * t
            with np.errstate(divide="ignore"):  # eps = 1 (tip entering): log1p(-1) = -inf
                e1 = np.expm1(n1 * np.log1p(-eps))
            p1 = np.exp(n1 * np.log(u1))
            u0 = u1 - L
            inner = e1 * (kpt * (u0 / n2 - u1 / n1) - kc / n1) - (kpt / n2) * L
            return (fac * p1) * inner + ((2.0 / (R * R)) * cc) * (0.5 * t * L * L)
    (I_c, I_phi, I_cc), _, _ = _integrals(z, n, law, cone)
    # fully mobilised: CI = 2/R^2 [(t + tan phic)(kc I_c + kphi I_phi) + cc I_cc]
    return fac * (kc * I_c + kphi * I_phi) + ((2.0 / (R * R)) * cc) * I_cc


def normal_integrals(
    u1: ArrayLike,
    a: ArrayLike | None,
    b: ArrayLike,
    n: ArrayLike,
    law: PressureLaw,
    t: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrals of p*r over the part of the cone between distances a and b from the tip.

    With u the depth of a surface element, d = u1 - u its distance from the
    tip and r = t d its radius (eq. (2-3) in [1]_), returns per unit kc and
    kphi the integral of p r du (eqs. (2-2), (2-5); RM1 of section 3.2 below
    r_t) and the integral of r du, over a <= d <= b.  These are the cone's
    normal-load integrals from which the cone index of eqs. (2-5) to (2-7) is
    assembled; they are exact (closed form in incomplete moments of d).

    Parameters
    ----------
    u1 : array_like
        Depth of the tip [m], > 0.
    a, b : array_like
        Distances from the tip bounding the part of the cone [m]; ``a=None``
        means 0 (from the tip).
    n : array_like
        Pressure-sinkage exponent [-].
    law : PressureLaw
        RM0 or RM1 (section 3.2 of [1]_).
    t : float
        tan of the cone's half angle [-] (r = t d).

    Returns
    -------
    i_kc, i_kphi, i_r : ndarray
        The integral of p r du per unit kc (under Bekker's law p r = kc z^n +
        kphi r z^n, so this is the integral of z^n du), per unit kphi (the
        integral of r z^n du), and the integral of r du [m^2], which carries cc.

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eqs. (2-2) to (2-7).
    """
    r_t, alpha, beta = law.coefficients()
    rm1 = not law.is_rm0
    p1 = np.exp((n + 1.0) * np.log(u1))  # u1^(n+1)
    p2 = p1 * u1
    g0b, g1b, g2b = _tail_moments(np.clip(b / u1, 0.0, 1.0), n, rm1)
    if a is None:
        g0a = g1a = g2a = 0.0
        a_ = 0.0
    else:
        g0a, g1a, g2a = _tail_moments(np.clip(a / u1, 0.0, 1.0), n, rm1)
        a_ = a
    I_phi = t * p2 * (g1b - g1a)
    I_cc = 0.5 * t * (b * b - a_ * a_)
    if not rm1:
        return p1 * (g0b - g0a), I_phi, I_cc
    p3 = p2 * u1
    # distance from the tip below which the linear branch applies: r < r_t
    d_s = np.asarray(r_t, dtype=float) / t
    lin_hi = np.minimum(b, d_s)  # linear branch over [a, lin_hi] when a < d_s
    g0s, g1s, g2s = _tail_moments(np.clip(lin_hi / u1, 0.0, 1.0), n)
    below = a_ < d_s
    # Bekker branch over [max(a, d_s), b]; linear over [a, min(b, d_s)]
    bek = np.where(below, g0b - g0s, g0b - g0a)
    lin1 = np.where(below, g1s - g1a, 0.0)
    lin2 = np.where(below, g2s - g2a, 0.0)
    I_c = p1 * bek + alpha * t * p2 * lin1 - beta * t * t * p3 * lin2
    return I_c, I_phi, I_cc


def _mobilised(z, u1, L, d_s, n, law, Kc, cone):
    """Shear integrals of eq. (2-6) with 1 - exp(-j/Kc), j = u / cos(a) (eq. (2-4)).

    Tanh-sinh quadrature in the distance from the tip, split where the
    pressure law changes branch; exact to rounding for these integrands.
    """
    if np.any(~np.isfinite(Kc)) or np.any(Kc <= 0):
        raise ValueError("Kc must be > 0 (or None for fully mobilised shear)")
    R, H = cone.radius, cone.height
    t = R / H
    cos_a = math.cos(cone.half_angle)
    r_t, alpha, beta = law.coefficients()
    u0 = np.maximum(z, 0.0)
    shape = np.broadcast_shapes(np.shape(z), np.shape(n), np.shape(Kc), np.shape(d_s))
    u1, n_, K_, L_, ds, u0, alpha, beta = (
        np.broadcast_to(np.asarray(v, float), shape)[..., None]
        for v in (u1, n, Kc, L, d_s, u0, alpha, beta)
    )

    def segment(d_lo, d_hi, u_far, linear):
        # nodes in d = distance from the tip, d in [d_lo, d_hi]; u = u1 - d
        width = d_hi - d_lo
        d = d_lo + width * _DE_SIGMA
        uu = u_far + width * _DE_ONE_MINUS  # accurate near the far (shallow) end
        uu = np.maximum(uu, 0.0)
        r = t * d
        un = np.where(uu > 0, uu, 0.0) ** n_
        mob = -np.expm1(-uu / (cos_a * K_))
        pc = alpha * r - beta * r * r if linear else 1.0
        wts = width * _DE_W * mob
        return (
            np.sum(wts * pc * un, axis=-1),
            np.sum(wts * r * un, axis=-1),
            np.sum(wts * r, axis=-1),
        )

    zero = np.zeros_like(L_)
    bc, bp, bcc = segment(ds, L_, u0, False)
    if law.is_rm0:
        return bc, bp, bcc
    lc, lp, lcc = segment(zero, ds, u1 - ds, True)
    return bc + lc, bp + lp, bcc + lcc


def cone_index_huang(
    depth: ArrayLike,
    *,
    kc: ArrayLike,
    kphi: ArrayLike,
    n: ArrayLike,
    cc: ArrayLike = 0.0,
    phic_deg: ArrayLike = 0.0,
    K_cone: ArrayLike | None = None,
    law: PressureLaw | None = None,
    cone: str | Cone = "asabe-large",
) -> np.ndarray:
    """Cone index of the improved model of Huang et al., eqs. (2-2) to (2-7) in [1]_, in SI.

    CI = (Fp + Fs) / (pi R^2) (eq. (2-7)) with the normal force Fp of the
    Bekker pressure (eqs. (2-2), (2-3), (2-5)) and the shear force Fs of the
    cone-metal shear stress (eqs. (2-4), (2-6)) over the embedded cone.

    Parameters
    ----------
    depth : array_like
        Depth of the cone base [m] (origin where the base is flush, Figure 2-2).
    kc : array_like
        [kN/m^(n+1)]
    kphi : array_like
        [kN/m^(n+2)]
    n : array_like
        [-]
    cc : array_like
        Cone-terrain adhesion [kPa].
    phic_deg : array_like
        Cone-terrain friction angle [deg].
    K_cone : array_like or None
        Cone-terrain shear deformation parameter [m]; None: fully
        mobilised shear.
    law : PressureLaw
        RM0 (default) or RM1.
    cone : str or Cone

    Returns
    -------
    ndarray
        Cone index [kPa].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eqs. (2-2) to (2-7).
    """
    K_cone = _check_K_cone(K_cone)
    kc = _check_nonneg("kc", kc)
    kphi = _check_nonneg("kphi", kphi)
    cc = _check_nonneg("cc", cc)
    cone = get_cone(cone)
    z = check_depth(depth, cone)
    phic_deg = _check_phic(phic_deg)
    law = law or pressure_law("rm0")
    return _improved(z, kc, kphi, _check_n(n), cc, phic_deg, K_cone, law, cone)


def cone_index_janosi(
    depth: ArrayLike, *, kc: ArrayLike, kphi: ArrayLike, n: ArrayLike
) -> np.ndarray:
    """Janosi's cone index, eq. (2-1) in [1]_, for the standard cone.

    US customary units throughout, as in the paper: depth z [in] from the
    point where the cone base is flush, kc [lb/in^(n+1)], kphi
    [lb/in^(n+2)], CI [psi].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eq. (2-1).
    """
    z = np.asarray(depth, dtype=float)
    if np.any(z < 0) or not np.all(np.isfinite(z)):
        raise ValueError("depth must be >= 0 for the Janosi equation (2-1)")
    kc = _check_nonneg("kc", kc)
    kphi = _check_nonneg("kphi", kphi)
    n = _check_n(n)
    zz = z + 1.5
    # eq. (2-1)
    return 1.625 * (
        kc / (n + 1.0) * (zz ** (n + 1.0) - z ** (n + 1.0))
        + 0.517
        * kphi
        * (
            zz ** (n + 2.0) / ((n + 1.0) * (n + 2.0))
            + z ** (n + 2.0) / (n + 2.0)
            - zz * z ** (n + 1.0) / (n + 1.0)
        )
    )


def _janosi_in(depth, kc, kphi, n: np.ndarray, units: str) -> np.ndarray:
    """Eq. (2-1) with inputs and output in a unit system (the equation itself is in US units)."""
    z_in = u.length_to_si(depth, units) / u.INCH
    kc_us = u.kc_from_si(u.kc_to_si(kc, n, units), n, "us")
    kphi_us = u.kphi_from_si(u.kphi_to_si(kphi, n, units), n, "us")
    ci_psi = cone_index_janosi(z_in, kc=kc_us, kphi=kphi_us, n=n)
    return u.pressure_from_si(u.pressure_to_si(ci_psi, "us"), units)


def cone_index(
    depth: ArrayLike,
    *,
    kc: ArrayLike,
    kphi: ArrayLike,
    n: ArrayLike,
    cc: ArrayLike = 0.0,
    phic_deg: ArrayLike = 0.0,
    K_cone: ArrayLike | None = None,
    model: str = "rm0",
    r_min: ArrayLike | None = None,
    cone: str | Cone = "asabe-large",
    units: str = "si",
    plate_pair: tuple[float, float] | None = None,
) -> np.ndarray:
    """Cone index against depth for given terrain parameters.

    Parameters
    ----------
    depth : array_like
        Depth of the cone base below the surface (origin where the base is
        flush; -H <= depth), in the length unit of ``units`` [m or in].
    kc, kphi, n : array_like
        Bekker pressure-sinkage parameters [kN/m^(n+1), kN/m^(n+2), -] or
        [lb/in^(n+1), lb/in^(n+2), -].
    cc : array_like
        Cone (metal)-terrain adhesion [kPa or psi].
    phic_deg : array_like
        Cone-terrain friction angle [deg].
    K_cone : array_like or None
        Cone-terrain shear deformation parameter [m or in]; None means
        fully mobilised shear (the paper's setting), a number uses eq.
        (2-4).
    model : {"rm0", "rm1", "janosi"}
        Pressure model of section 3.2, or eq. (2-1).
    r_min : array_like, optional
        Transition radius of RM1 [m or in].
    cone : str or Cone
        ``"asabe-large"`` (default), ``"asabe-small"`` or ``"D<unit>:ANGLE"``.
    units : {"si", "us"}
    plate_pair : (r1, r2), optional
        Radii of the bevameter plate pair [m or in]; with RM1 and r_min above
        r2 the linear branch is the line through the two plates' Bekker
        pressures (section 3.2).

    Returns
    -------
    ndarray
        Cone index [kPa or psi], the broadcast shape of the inputs.

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eqs. (2-1) to (2-7), section 3.2.
    """
    units = u.check_system(units)
    n_arr = _check_n(n)
    if model == "janosi":
        if get_cone(cone) != CONES["asabe-large"]:
            raise ValueError(
                "cone: the Janosi equation (2-1) holds for the standard asabe-large cone"
            )
        if K_cone is not None or np.any(np.asarray(cc) != 0) or np.any(np.asarray(phic_deg) != 0):
            raise ValueError("cc, phic and Kc are not parameters of the Janosi equation (2-1)")
        return _janosi_in(depth, kc, kphi, n_arr, units)
    law = pressure_law(model, r_min=r_min, plate_pair=plate_pair, units=units)
    cone = get_cone(cone)
    # checked once here, then the unchecked SI core
    ci = _improved(
        check_depth(u.length_to_si(depth, units), cone),
        u.kc_to_si(_check_nonneg("kc", kc), n_arr, units),
        u.kphi_to_si(_check_nonneg("kphi", kphi), n_arr, units),
        n_arr,
        u.pressure_to_si(_check_nonneg("cc", cc), units),
        _check_phic(phic_deg),
        _check_K_cone(None if K_cone is None else u.length_to_si(K_cone, units)),
        law,
        cone,
    )
    return ci if units == "si" else u.pressure_from_si(ci, units)

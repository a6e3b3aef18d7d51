"""What a terrain means for a vehicle: NRMM cone-index go/no-go and Bekker's rigid wheel.

Two schools read cone-index records for vehicle mobility.

**NRMM, empirical.**  The rating cone index RCI = CI x RI [1]_ (CI averaged
over the critical layer, RI the remolding index) is compared with the
vehicle cone index VCI, the least RCI on which the vehicle completes one
(VCI_1) or fifty (VCI_50) passes; the vehicle goes when RCI >= VCI.  VCI
comes from the vehicle's mobility index MI [2]_ [3]_, with the deflection
correction factor DCF for tyres deflected otherwise than 15% of their
section height [1]_.  Wheeled and tracked vehicles have mobility indices
and VCI relations of their own [2]_ [6]_.  The formulas are fits in US
customary units (psi, lb, in); the functions here take and return SI and
convert inside.

**Bekker-Wong, physics.**  A rigid wheel of diameter D and width b under the
load W sinks, by Bekker's analysis with the pressure p = (kc/b + kphi) z^n,
to z0 [4]_ [5]_ and meets the compaction resistance Rc [4]_ [5]_.

References
----------
.. [1] Priddy, J.D., Willoughby, W.E. (2006). Clarification of vehicle cone
   index with reference to mean maximum pressure. Journal of Terramechanics
   43(2), 85-96 (online 2004), doi:10.1016/j.jterra.2004.10.001.  The DCF
   and the VCI_1 equations of the ERDC VCI prediction methodology.
.. [2] Rula, A.A., Nuttall, C.J. (1971). An analysis of ground mobility
   models (ANAMOB). Technical Report M-71-4, U.S. Army Engineer Waterways
   Experiment Station, Vicksburg; the mobility index of wheeled vehicles
   and VCI_50, as tabulated in [5]_ (chapter 2, empirical methods based on
   the cone index).
.. [3] Priddy, J.D. (1999). Improving the traction prediction capabilities
   in the NATO Reference Mobility Model (NRMM). Technical Report GL-99-8,
   U.S. Army Engineer Research and Development Center (DTIC ADA368656):
   the mobility-index factors, with the axle load in the weight factor.
.. [4] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
   University of Michigan Press.
.. [5] Wong, J.Y. (2008). Theory of Ground Vehicles, 4th ed. Wiley;
   chapter 2: the WES cone-index methods, and the sinkage and motion
   resistance of a rigid wheel.
.. [6] Wong, J.Y., Jayakumar, P., Toma, E., Preston-Thomas, J. (2020). A
   review of mobility metrics for next generation vehicle mobility models.
   Journal of Terramechanics 87, 11-20, doi:10.1016/j.jterra.2019.10.003:
   the mobility index and VCI_1 of tracked vehicles.  Neither this review
   nor [2]_ could be opened here: the tracked-vehicle factors and VCI_1 were
   read in public transcriptions of [6]_ and of FM 5-430-00-1 (1994), which
   agree on the weight, track, grouser, bogie and clearance factors and VCI_1;
   the engine and transmission factors are taken as for wheeled vehicles, the
   transcriptions being unreliable there (docs/mobility.md, Not done).  No
   public source of a tracked-vehicle VCI_50 could be opened, so none is given.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from terracone.physics import units as u

__all__ = [
    "deflection_correction_factor",
    "vci1_priddy_willoughby",
    "vci50_rula_nuttall",
    "mobility_index_wheeled",
    "weight_factor_wheeled",
    "vci1_tracked",
    "mobility_index_tracked",
    "weight_factor_tracked",
    "rating_cone_index",
    "sinkage_rigid_wheel_bekker",
    "compaction_resistance_bekker",
]

#: Tyre deflection ratio delta/h at which MI predicts VCI without correction [1].
NOMINAL_DEFLECTION = 0.15
#: MI above which VCI_1 follows the power law of [1].
MI_POWER_LAW = 115.0


def deflection_correction_factor(deflection_ratio: ArrayLike) -> np.ndarray:
    """Deflection correction factor DCF = (0.15 / (delta/h))^0.25 [1]_.

    Parameters
    ----------
    deflection_ratio : array_like
        Hard-surface tyre deflection over section height, delta/h [-], in (0, 1).

    Returns
    -------
    ndarray
        DCF [-]; 1 at the nominal 15% deflection.

    References
    ----------
    .. [1] Priddy and Willoughby (2006), DCF (as in :mod:`terracone.physics.vehicle`).
    """
    r = np.asarray(deflection_ratio, dtype=float)
    if np.any(~(r > 0)) or np.any(~(r < 1)):
        raise ValueError(f"tyre deflection ratio delta/h must lie in (0, 1), got {r}")
    return (NOMINAL_DEFLECTION / r) ** 0.25  # DCF of [1]


def vci1_priddy_willoughby(
    mobility_index: ArrayLike, deflection_ratio: ArrayLike = 0.15
) -> np.ndarray:
    """One-pass vehicle cone index VCI_1 of a wheeled vehicle [kPa] [1]_.

    VCI_1 = (11.48 + 0.2 MI - 39.2 / (MI + 3.74)) DCF [psi] for MI <= 115,
    VCI_1 = 4.1 MI^0.446 DCF [psi] above (the ERDC VCI prediction
    methodology, for vehicles with all axles powered), returned in kPa.

    Parameters
    ----------
    mobility_index : array_like
        Mobility index MI [-] (:func:`mobility_index_wheeled`), > 0.
    deflection_ratio : array_like
        Tyre deflection ratio delta/h [-] (:func:`deflection_correction_factor`).

    Returns
    -------
    ndarray
        VCI_1 [kPa].

    References
    ----------
    .. [1] Priddy and Willoughby (2006), VCI_1(MI, DCF).
    """
    mi = _check_mi(mobility_index)
    dcf = deflection_correction_factor(deflection_ratio)
    low = 11.48 + 0.2 * mi - 39.2 / (mi + 3.74)  # MI <= 115, [1]
    high = 4.1 * mi**0.446  # MI > 115, [1]
    return u.pressure_to_si(np.where(mi <= MI_POWER_LAW, low, high) * dcf, "us")


def vci50_rula_nuttall(mobility_index: ArrayLike) -> np.ndarray:
    """Fifty-pass vehicle cone index VCI_50 of a wheeled vehicle [kPa] [1]_ [2]_.

    VCI_50 = 28.23 + 0.43 MI - 92.67 / (MI + 3.67) [psi], returned in kPa.
    No deflection correction: [3]_ gives the DCF for VCI_1 only.

    Parameters
    ----------
    mobility_index : array_like
        Mobility index MI [-], > 0.

    Returns
    -------
    ndarray
        VCI_50 [kPa].

    References
    ----------
    .. [1] Rula and Nuttall (1971), as tabulated by [2]_.
    .. [2] Wong (2008), chapter 2.
    .. [3] Priddy and Willoughby (2006).
    """
    mi = _check_mi(mobility_index)
    return u.pressure_to_si(28.23 + 0.43 * mi - 92.67 / (mi + 3.67), "us")  # [1]


def _check_mi(mobility_index: ArrayLike) -> np.ndarray:
    mi = np.asarray(mobility_index, dtype=float)
    if np.any(~(mi > 0)) or np.any(~np.isfinite(mi)):
        raise ValueError(f"mobility index must be a positive number, got {mi}")
    return mi


def weight_factor_wheeled(axle_load_kips: ArrayLike) -> np.ndarray:
    """Weight factor of the wheeled-vehicle mobility index [-] [1]_ [2]_.

    Piecewise linear in the axle load X [kips] (gross weight / axles):
    0.553 X below 2; 0.033 X + 1.050 to 13.5; 0.142 X - 0.420 to 20;
    0.278 X - 3.115 to 31.5; 0.836 X - 20.686 above (the pieces meet to
    within 0.01 at the breaks).

    Parameters
    ----------
    axle_load_kips : array_like
        Mean axle load [kips] (1 kip = 1000 lbf).

    Returns
    -------
    ndarray

    References
    ----------
    .. [1] Rula and Nuttall (1971), as tabulated by Wong (2008), chapter 2.
    .. [2] Priddy (1999), TR GL-99-8.
    """
    x = np.asarray(axle_load_kips, dtype=float)
    return np.select(
        [x < 2.0, x < 13.5, x < 20.0, x < 31.5],
        [0.553 * x, 0.033 * x + 1.050, 0.142 * x - 0.420, 0.278 * x - 3.115],
        0.836 * x - 20.686,
    )


def mobility_index_wheeled(
    gross_weight: float,
    *,
    axles: int,
    tires: int,
    tire_width: float,
    tire_diameter: float,
    ground_clearance: float,
    engine_power: float,
    manual_transmission: bool = False,
    chains: bool = False,
) -> float:
    """Mobility index MI of a self-propelled wheeled vehicle [-] [1]_ [2]_ [3]_.

    MI = (CPF WF / (TF GF) + WLF - CF) EF XF, in US customary units:

    * contact pressure factor CPF = W [lb] / (b [in] (d [in] / 2) tyres);
    * weight factor WF of the axle load W / axles [kips]
      (:func:`weight_factor_wheeled`);
    * tyre factor TF = (10 + b [in]) / 100;
    * grouser factor GF = 1.05 with chains, else 1;
    * wheel load factor WLF = W [kips] / (2 axles);
    * clearance factor CF = clearance [in] / 10;
    * engine factor EF = 1 at 10 hp per short ton of W or more, else 1.05;
    * transmission factor XF = 1 automatic, 1.05 manual.

    Parameters
    ----------
    gross_weight : float
        Gross vehicle weight W [N].
    axles, tires : int
        Number of axles and of tyres.
    tire_width, tire_diameter : float
        Nominal tyre section width b and outside diameter d [m].
    ground_clearance : float
        Ground clearance [m].
    engine_power : float
        Engine power [W].
    manual_transmission : bool
        True for a manual transmission (False: automatic).
    chains : bool
        True with tyre chains.

    Returns
    -------
    float
        MI [-].

    References
    ----------
    .. [1] Rula and Nuttall (1971), as tabulated by Wong (2008), chapter 2.
    .. [2] Priddy (1999), TR GL-99-8.
    .. [3] Priddy and Willoughby (2006): MI is the principal predictor of VCI.
    """
    if not (gross_weight > 0 and tire_width > 0 and tire_diameter > 0):
        raise ValueError("gross weight, tyre width and tyre diameter must be > 0")
    if int(axles) < 1 or int(tires) < 1 or ground_clearance < 0 or engine_power < 0:
        raise ValueError("need axles >= 1, tyres >= 1, clearance >= 0 and engine power >= 0")
    w_lb = gross_weight / u.LBF
    b_in, d_in = tire_width / u.INCH, tire_diameter / u.INCH
    cpf = w_lb / (b_in * (d_in / 2.0) * tires)  # contact pressure factor [psi]
    wf = float(weight_factor_wheeled(w_lb / 1000.0 / axles))  # weight factor
    tf = (10.0 + b_in) / 100.0  # tyre factor
    gf = 1.05 if chains else 1.0  # grouser factor
    wlf = w_lb / 1000.0 / (2.0 * axles)  # wheel load factor
    cf = ground_clearance / u.INCH / 10.0  # clearance factor
    ef = _engine_factor(engine_power, w_lb)  # engine factor
    xf = 1.05 if manual_transmission else 1.0  # transmission factor
    return float((cpf * wf / (tf * gf) + wlf - cf) * ef * xf)


#: Tracked-vehicle weight factor by gross weight [lb]: (upper bound, factor) [6].
TRACKED_WEIGHT_FACTORS = ((50_000.0, 1.0), (70_000.0, 1.2), (100_000.0, 1.4), (math.inf, 1.8))
#: Grouser height above which the tracked grouser factor is 1.1, else 1.0 [in] [6].
GROUSER_HEIGHT_IN = 1.5


def vci1_tracked(mobility_index: ArrayLike) -> np.ndarray:
    """One-pass vehicle cone index VCI_1 of a tracked vehicle [kPa] [1]_.

    VCI_1 = 7.0 + 0.2 MI - 39.2 / (MI + 5.6) [psi], returned in kPa (fine-grained
    soils; tracks carry no deflection correction).

    Parameters
    ----------
    mobility_index : array_like
        Mobility index MI [-] (:func:`mobility_index_tracked`), > 0.

    Returns
    -------
    ndarray
        VCI_1 [kPa].

    References
    ----------
    .. [1] Wong et al. (2020), as transcribed (:mod:`terracone.physics.vehicle`, [6]).
    """
    mi = _check_mi(mobility_index)
    return u.pressure_to_si(7.0 + 0.2 * mi - 39.2 / (mi + 5.6), "us")  # VCI_1, tracked [6]


def weight_factor_tracked(gross_weight_lb: ArrayLike) -> np.ndarray:
    """Weight factor of the tracked-vehicle mobility index [-] [1]_.

    1.0 below 50,000 lb, 1.2 to 70,000 lb, 1.4 to 100,000 lb, 1.8 above
    (each band includes its lower bound).

    Parameters
    ----------
    gross_weight_lb : array_like
        Gross vehicle weight [lb].

    References
    ----------
    .. [1] Wong et al. (2020), as transcribed (:mod:`terracone.physics.vehicle`, [6]).
    """
    w = np.asarray(gross_weight_lb, dtype=float)
    bounds = [b for b, _ in TRACKED_WEIGHT_FACTORS[:-1]]
    return np.select([w < b for b in bounds], [f for _, f in TRACKED_WEIGHT_FACTORS[:-1]],
                     TRACKED_WEIGHT_FACTORS[-1][1])  # fmt: skip


def _engine_factor(engine_power: float, w_lb: float) -> float:
    """EF = 1 at 10 hp per short ton (2000 lb) of gross weight or more, else 1.05 [2], [6]."""
    hp_per_ton = (engine_power / u.HP) / (w_lb / 2000.0)
    return 1.0 if hp_per_ton >= 10.0 else 1.05


def mobility_index_tracked(
    gross_weight: float,
    *,
    track_width: float,
    track_contact_length: float,
    tracks: int,
    bogies: int,
    shoe_area: float,
    grouser_height: float,
    ground_clearance: float,
    engine_power: float,
    manual_transmission: bool = False,
) -> float:
    """Mobility index MI of a self-propelled tracked vehicle [-] [1]_.

    MI = (CPF WF / (TF GF) + BF - CF) EF XF, in US customary units:

    * contact pressure factor CPF = W [lb] / (tracks L [in] b [in]), the
      gross weight over the area of the tracks on the ground;
    * weight factor WF of W (:func:`weight_factor_tracked`);
    * track factor TF = b [in] / 100;
    * grouser factor GF = 1.1 with grousers higher than 1.5 in, else 1.0;
    * bogie factor BF = (W [lb] / 10) / (bogies x shoe area [in^2]), bogies
      being the road wheels in contact with the ground on all tracks;
    * clearance factor CF = clearance [in] / 10;
    * engine factor EF = 1 at 10 hp per short ton of W or more, else 1.05;
    * transmission factor XF = 1 automatic, 1.05 manual.

    Parameters
    ----------
    gross_weight : float
        Gross vehicle weight W [N].
    track_width, track_contact_length : float
        Width b of a track and the length L of one track on the ground [m].
    tracks, bogies : int
        Number of tracks; road wheels in contact with the ground, all tracks.
    shoe_area : float
        Area of one track shoe [m^2].
    grouser_height, ground_clearance : float
        Grouser height and ground clearance [m].
    engine_power : float
        Engine power [W].
    manual_transmission : bool
        True for a manual transmission (False: automatic).

    Returns
    -------
    float
        MI [-].

    References
    ----------
    .. [1] Wong et al. (2020), as transcribed (:mod:`terracone.physics.vehicle`, [6]).
    """
    dims = (gross_weight, track_width, track_contact_length, shoe_area, engine_power)
    if not all(x > 0 for x in dims) or grouser_height < 0 or ground_clearance < 0:
        raise ValueError("need weight, track width, contact length, shoe area and engine power "
                         "> 0, grouser height and clearance >= 0")  # fmt: skip
    if int(tracks) < 1 or int(bogies) < 1:
        raise ValueError("need tracks >= 1 and bogies >= 1")
    w_lb = gross_weight / u.LBF
    b_in, l_in = track_width / u.INCH, track_contact_length / u.INCH
    cpf = w_lb / (tracks * l_in * b_in)  # contact pressure factor [psi]
    wf = float(weight_factor_tracked(w_lb))  # weight factor
    tf = b_in / 100.0  # track factor
    gf = 1.1 if grouser_height / u.INCH > GROUSER_HEIGHT_IN else 1.0  # grouser factor
    bf = (w_lb / 10.0) / (bogies * shoe_area / u.INCH**2)  # bogie factor
    cf = ground_clearance / u.INCH / 10.0  # clearance factor
    ef = _engine_factor(engine_power, w_lb)  # engine factor
    xf = 1.05 if manual_transmission else 1.0  # transmission factor
    return float((cpf * wf / (tf * gf) + bf - cf) * ef * xf)


def rating_cone_index(ci: ArrayLike, remolding_index: ArrayLike) -> np.ndarray:
    """Rating cone index RCI = CI x RI [kPa] [1]_ [2]_.

    Parameters
    ----------
    ci : array_like
        Cone index averaged over the critical layer [kPa].
    remolding_index : array_like
        Remolding index RI [-], in (0, 2].

    Returns
    -------
    ndarray
        RCI [kPa].

    References
    ----------
    .. [1] Priddy and Willoughby (2006).
    .. [2] Wong (2008), chapter 2.
    """
    ri = np.asarray(remolding_index, dtype=float)
    if np.any(~(ri > 0)) or np.any(~(ri <= 2)):
        raise ValueError(f"remolding index must lie in (0, 2], got {ri}")
    return np.asarray(ci, dtype=float) * ri  # RCI = CI x RI


def sinkage_rigid_wheel_bekker(
    load: ArrayLike,
    *,
    diameter: ArrayLike,
    width: ArrayLike,
    kc: ArrayLike,
    kphi: ArrayLike,
    n: ArrayLike,
) -> np.ndarray:
    """Sinkage of a rigid wheel on Bekker's terrain [m] [1]_ [2]_.

    z0 = [3 W / ((3 - n)(kc + b kphi) sqrt(D))]^(2/(2n + 1)), from the
    pressure p = (kc/b + kphi) z^n acting on the wheel's arc of contact.
    [2]_ finds it acceptable for D > 50 cm and z0 < D/6.

    Parameters
    ----------
    load : array_like
        Vertical load W on the wheel [N].
    diameter, width : array_like
        Wheel diameter D and width b [m].
    kc, kphi, n : array_like
        Bekker's terrain values: kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-]
        (n < 3).

    Returns
    -------
    ndarray
        Sinkage z0 [m]; inf where kc + b kphi = 0.

    References
    ----------
    .. [1] Bekker (1969).
    .. [2] Wong (2008), chapter 2, sinkage of a rigid wheel.
    """
    W = np.asarray(load, dtype=float) / 1000.0  # [kN], the unit of kc and kphi
    D, b = np.asarray(diameter, dtype=float), np.asarray(width, dtype=float)
    n = np.asarray(n, dtype=float)
    k = np.asarray(kc, dtype=float) + b * np.asarray(kphi, dtype=float)
    with np.errstate(divide="ignore"):
        base = 3.0 * W / ((3.0 - n) * k * np.sqrt(D))
    return base ** (2.0 / (2.0 * n + 1.0))  # z0 of [1], [2]


def compaction_resistance_bekker(
    sinkage: ArrayLike, *, width: ArrayLike, kc: ArrayLike, kphi: ArrayLike, n: ArrayLike
) -> np.ndarray:
    """Compaction resistance of a rigid wheel [N] [1]_ [2]_.

    Rc = b (kc/b + kphi) z0^(n+1) / (n + 1) = (kc + b kphi) z0^(n+1) / (n + 1):
    the work of making a rut of depth z0 and width b, per unit length.

    Parameters
    ----------
    sinkage : array_like
        Sinkage z0 [m] (:func:`sinkage_rigid_wheel_bekker`).
    width : array_like
        Wheel width b [m].
    kc, kphi, n : array_like
        kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-].

    Returns
    -------
    ndarray
        Rc [N].

    References
    ----------
    .. [1] Bekker (1969).
    .. [2] Wong (2008), chapter 2, motion resistance of a rigid wheel.
    """
    z = np.asarray(sinkage, dtype=float)
    n = np.asarray(n, dtype=float)
    k = np.asarray(kc, dtype=float) + np.asarray(width, dtype=float) * np.asarray(kphi, dtype=float)
    return 1000.0 * k * z ** (n + 1.0) / (n + 1.0)  # Rc of [1], [2], kN -> N

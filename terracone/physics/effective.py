"""An effective one-layer Bekker soil of a layered ground, for one wheel or track under one load.

Chrono's SCM, and any one-layer Bekker model, takes one (kc, kphi, n) per
location.  A layered ground's plate pressure p(z; b)
(:func:`terracone.physics.layers.layered_plate`) is not a power of z, so its
top layer, or a one-layer fit through its cone-index profile, sinks a wheel by
the wrong amount.  :func:`effective_soil` fits, for the running gear's width b
and load W, the power law p_e = k z^m that

* carries the load at the layered ground's own sinkage z0 (a rigid wheel:
  :func:`terracone.physics.sinkage.wheel_load` (z0) = W, Bekker's
  assumptions; a track: k z0^m = q, its uniform pressure), so that the
  effective soil sinks the running gear exactly as the layered ground does
  [1]_ [2]_; and
* among those, is nearest the layered p(z; b) over the sinkages the load
  produces: least squares int_0^z0 (k z^m - p(z; b))^2 dz, uniform in z,
  over m in :data:`N_BOUNDS` (a grid of step 0.05, then Brent's method
  around its best point; k follows from the load at each m).

The fit is reported as kc = 0 and kphi = k [kN/m^(m+2)]: Chrono's SCM
presses with (Kc oob + Kphi) z^n, oob = perimeter / (2 area) of each contact
patch as Chrono measures it, not the tyre's width [3]_; with Kc = 0 its
pressure is k z^m whatever that patch, which is what the fit was made for.
The price: the values hold for this width (and load) only.

The error is said two ways: the relative RMS of p_e - p over [0, z0]
(over the RMS of p there), which a one-layer law cannot bring to 0 across an
interface, and the relative error of the effective soil's sinkage, solved
afresh by the same wheel or track model (0 up to the solver's tolerance, by
the constraint), beside that of Bekker's closed form with the effective
values (:func:`terracone.physics.vehicle.sinkage_rigid_wheel_bekker`, which
departs from the exact integral when m is far from 1) and at 80% and 125% of
the load (how far the soil holds off its design load).

References
----------
.. [1] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
   University of Michigan Press.
.. [2] Wong, J.Y. (2008). Theory of Ground Vehicles, 4th ed. Wiley; chapter 2.
.. [3] Project Chrono, ``src/chrono_vehicle/terrain/SCMTerrain.cpp``,
   ``SCMLoader::ComputeInternalForces``: ``oob = perimeter / (2 * area)`` of
   each contact patch's convex hull, ``sigma = (oob * Bekker_Kc + Bekker_Kphi)
   * pow(sinkage, Bekker_n)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize

from terracone.physics.layers import LayeredPlate
from terracone.physics.sinkage import sinkage_rigid_wheel, sinkage_track, wheel_load
from terracone.physics.vehicle import sinkage_rigid_wheel_bekker

__all__ = ["N_BOUNDS", "OFF_LOADS", "EffectiveSoil", "effective_soil", "plate_misfit"]

#: Range of the effective exponent m [-] (Bekker's closed form needs n < 3).
N_BOUNDS = (0.05, 2.95)
#: Loads, as fractions of the design load, at which the sinkage error is also said.
OFF_LOADS = (0.8, 1.25)
#: Step of the grid over m before Brent's method [-].
N_STEP = 0.05


@dataclass(frozen=True)
class EffectiveSoil:
    """The effective one-layer soil of a layered ground for one running gear (SI).

    Attributes
    ----------
    kc, kphi, n : float
        The soil: kc = 0 [kN/m^(n+1)], kphi = k [kN/m^(n+2)], n [-]; p = k z^n.
    gear : {"wheel", "track"}
    width : float
        Width b of the wheel or track [m].
    load : float
        Load on the wheel, or on one track [N].
    diameter, contact_length : float or None
        Wheel diameter D, or track contact length L [m].
    sinkage : float
        z0 of the layered ground [m].
    sinkage_effective : float
        z0 of the effective soil, solved afresh [m].
    pressure_rms : float
        RMS of p_e - p over [0, z0] over the RMS of p there [-].
    sinkage_error : float
        sinkage_effective / sinkage - 1 [-].
    closed_form_error : float or None
        Bekker's closed form with the effective values over the layered z0,
        less 1 (wheel only).
    off_load_errors : dict
        {fraction of the load: sinkage error of the effective soil there}
        (NaN where the layered ground has no equilibrium at that load).
    at_bound : bool
        m at an end of :data:`N_BOUNDS`.
    """

    kc: float
    kphi: float
    n: float
    gear: str
    width: float
    load: float
    sinkage: float
    sinkage_effective: float
    pressure_rms: float
    sinkage_error: float
    diameter: float | None = None
    contact_length: float | None = None
    closed_form_error: float | None = None
    off_load_errors: dict[float, float] = field(default_factory=dict)
    at_bound: bool = False

    def as_dict(self) -> dict[str, Any]:
        """The ``effective`` block of an export's notes (SI, keys with their unit; NaN as None)."""
        d: dict[str, Any] = {"running_gear": self.gear, "width_m": self.width,
                             "load_n": self.load, "sinkage_m": self.sinkage}  # fmt: skip
        if self.gear == "wheel":
            d["diameter_m"] = self.diameter
        else:
            d["contact_length_m"] = self.contact_length
            d["pressure_kpa"] = self.load / (1000.0 * self.width * self.contact_length)
        err = {"pressure_rms": self.pressure_rms, "sinkage": self.sinkage_error}
        if self.closed_form_error is not None:
            err["sinkage_closed_form"] = self.closed_form_error
        for f, e in self.off_load_errors.items():
            err[f"sinkage_at_{round(100 * f)}pct_load"] = e
        d.update(sinkage_effective_m=self.sinkage_effective, error=err,
                 kc=self.kc, kphi=self.kphi, n=self.n, n_at_bound=self.at_bound)  # fmt: skip
        return _finite(d)


def _finite(v: Any) -> Any:
    """JSON-safe: a number that is not finite becomes None (JSON has no NaN)."""
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def plate_misfit(plate: LayeredPlate, k: float, m: float, sinkage: float) -> tuple[float, float]:
    """(int_0^z0 (k z^m - p)^2 dz, int_0^z0 p^2 dz) [kPa^2 m] of a power law against a plate.

    In closed form, layer by layer: p = k_j z^(n_j) on each layer's part of
    [0, z0] (eq. (2-2) of the layer, :class:`~terracone.physics.layers.LayeredPlate`).
    """
    z0, bounds = float(sinkage), plate.bounds
    cross = own = 0.0
    for j, (kj, nj) in enumerate(zip(plate.k, plate.n)):
        a, c = bounds[j], min(bounds[j + 1], z0)
        if a >= z0:
            break
        cross += kj * (c ** (m + nj + 1) - a ** (m + nj + 1)) / (m + nj + 1)  # int z^m p
        own += kj * kj * (c ** (2 * nj + 1) - a ** (2 * nj + 1)) / (2 * nj + 1)  # int p^2
    sq = k * k * z0 ** (2 * m + 1) / (2 * m + 1) - 2 * k * cross + own
    return max(sq, 0.0), own


def _modulus(m: float, plate: LayeredPlate, z0: float, load: float, gear: dict) -> float:
    """k of p = k z^m that carries the load at z0 (the equilibrium constraint)."""
    if gear["diameter"] is None:
        return gear["pressure"] / z0**m  # a track: k z0^m = q
    unit = LayeredPlate((1.0,), (m,), (), plate.width)
    return load / wheel_load(z0, diameter=gear["diameter"], plate=unit, geometry=gear["geometry"])


def _sinkage(plate: LayeredPlate, load: float, gear: dict) -> float:
    if gear["diameter"] is None:
        q = load / (1000.0 * plate.width * gear["contact_length"])  # [kPa]
        return sinkage_track(q, plate=plate)
    return sinkage_rigid_wheel(
        load, diameter=gear["diameter"], plate=plate, geometry=gear["geometry"]
    )


def effective_soil(
    plate: LayeredPlate,
    *,
    load: float,
    diameter: float | None = None,
    contact_length: float | None = None,
    geometry: str = "arc",
) -> EffectiveSoil:
    """The effective one-layer soil (kc = 0, kphi = k, n = m) of a layered ground.

    Parameters
    ----------
    plate : LayeredPlate
        p(z; b) of the layered ground at the running gear's width b
        (:func:`terracone.physics.layers.layered_plate`).
    load : float
        W [N]: on the wheel, or on one track.
    diameter : float, optional
        A rigid wheel's diameter D [m] (Bekker's wheel,
        :func:`terracone.physics.sinkage.sinkage_rigid_wheel`).
    contact_length : float, optional
        A track's contact length L [m] (uniform pressure W / (b L),
        :func:`terracone.physics.sinkage.sinkage_track`); give exactly one.
    geometry : {"arc", "shallow"}
        The wheel's contact (:func:`terracone.physics.sinkage.wheel_load`).

    Returns
    -------
    EffectiveSoil

    Raises
    ------
    ValueError
        No equilibrium: the wheel sinks past its axle, or no layer carries
        the track (the message says which).

    References
    ----------
    .. [1] Bekker (1969); Wong (2008), chapter 2 (as :mod:`terracone.physics.effective`).
    """
    if (diameter is None) == (contact_length is None):
        raise ValueError("give exactly one of diameter (a wheel) and contact_length (a track)")
    if not (math.isfinite(load) and load > 0):
        raise ValueError(f"load must be > 0 N (got {load!r})")
    if contact_length is not None and not (math.isfinite(contact_length) and contact_length > 0):
        raise ValueError(f"contact length must be > 0 m (got {contact_length!r})")
    gear = {"diameter": diameter, "contact_length": contact_length, "geometry": geometry}
    if contact_length is not None:
        gear["pressure"] = load / (1000.0 * plate.width * contact_length)  # q [kPa]
    z0 = _sinkage(plate, load, gear)
    if not math.isfinite(z0) or z0 <= 0:
        what = (
            f"the wheel (D = {diameter:g} m) sinks past its axle"
            if diameter is not None
            else "no layer carries the track's pressure"
        )
        raise ValueError(f"{what} under {load:g} N at width {plate.width:g} m: no equilibrium "
                         "in Bekker's model, so no effective soil")  # fmt: skip

    def misfit(m: float) -> float:
        return plate_misfit(plate, _modulus(m, plate, z0, load, gear), m, z0)[0]

    lo, hi = N_BOUNDS
    grid = np.arange(lo, hi + 0.5 * N_STEP, N_STEP)
    values = [misfit(float(m)) for m in grid]
    i = int(np.argmin(values))
    a, b = float(grid[max(i - 1, 0)]), float(grid[min(i + 1, grid.size - 1)])
    res = optimize.minimize_scalar(misfit, bounds=(a, b), method="bounded",
                                   options={"xatol": 1e-7})  # fmt: skip
    m = float(res.x) if res.fun <= values[i] else float(grid[i])
    k = _modulus(m, plate, z0, load, gear)
    sq, own = plate_misfit(plate, k, m, z0)
    soil = LayeredPlate((k,), (m,), (), plate.width)
    z_eff = _sinkage(soil, load, gear)
    off = {}
    for f in OFF_LOADS:
        z_l, z_e = _sinkage(plate, f * load, gear), _sinkage(soil, f * load, gear)
        off[f] = z_e / z_l - 1.0 if z_l > 0 else math.nan
    closed = None
    if diameter is not None:
        z_cf = sinkage_rigid_wheel_bekker(load, diameter=diameter, width=plate.width, kc=0.0,
                                          kphi=k, n=m)  # fmt: skip
        closed = float(z_cf) / z0 - 1.0
    return EffectiveSoil(
        kc=0.0, kphi=k, n=m, gear="wheel" if diameter is not None else "track",
        width=plate.width, load=float(load), sinkage=z0, sinkage_effective=z_eff,
        pressure_rms=math.sqrt(sq / own) if own > 0 else math.nan,
        sinkage_error=z_eff / z0 - 1.0, diameter=diameter, contact_length=contact_length,
        closed_form_error=closed, off_load_errors=off,
        at_bound=min(m - lo, hi - m) < 1e-6,
    )  # fmt: skip

"""Terrain internal shear: Janosi-Hanamoto fits of shear tests (the inverse side).

The terrain's internal shear follows tau = (c + sigma tan(phi)) (1 -
exp(-j/K)) [1]_ (:func:`terracone.physics.shear.shear_stress_janosi_hanamoto`,
the form of eq. (2-4) of [2]_ for the terrain's own shear, not the cone-metal
cc, phic).  :func:`fit_shear` fits each test's tau_max and K, then the
Mohr-Coulomb line ``tau_max = c + sigma tan(phi)`` over the tests and a common
K [3]_; with a single normal pressure c and phi are undetermined (None).
Details: ``docs/bevameter.md``.

References
----------
.. [1] Janosi, Z., Hanamoto, B. (1961). The analytical determination of
   drawbar pull as a function of slip for tracked vehicles in deformable
   soils. Proc. 1st Int. Conf. on Terrain-Vehicle Systems, Turin.
.. [2] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-4).
.. [3] Wong, J.Y. (1980). Data processing methodology in the characterization
   of the mechanical properties of terrain. Journal of Terramechanics 17(1),
   13-41.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize

from terracone.data import InputError, ShearTest, TerrainShear
from terracone.inverse.bevameter.plates import line_fit, of_type
from terracone.physics import units as u
from terracone.physics.shear import shear_stress_janosi_hanamoto
from terracone.resultunits import Written, output, quantity

__all__ = ["ShearTestFit", "ShearFit", "fit_shear", "fit_shear_test"]


@dataclass(frozen=True)
class ShearTestFit(Written):
    """Janosi-Hanamoto fit of one shear test.

    Attributes
    ----------
    test : str
        Test id.
    normal_pressure : float
        sigma [kPa].
    tau_max : float
        Asymptotic shear stress c + sigma tan(phi) [kPa].
    K : float
        Shear deformation modulus [m].
    points_used : int
    rmsd : float
        Root mean square deviation of the fitted from the measured stress [kPa].
    r2 : float
        Coefficient of determination on tau [-].
    j_end : float
        Largest displacement among the points used [m].
    """

    test: str
    normal_pressure: float = quantity("pressure")
    tau_max: float = quantity("pressure")
    K: float = quantity("length")
    points_used: int
    rmsd: float = quantity("pressure")
    r2: float = quantity("none")
    j_end: float = quantity("length")
    units_key = True  # as_dict(units): the fit in a unit system, then "units"

    def stress(self, displacement: Any) -> np.ndarray:
        """Fitted shear stress [kPa] at displacement j [m]."""
        return shear_stress_janosi_hanamoto(displacement, self.tau_max, self.K)


@dataclass(frozen=True)
class ShearFit:
    """Terrain internal shear parameters from shear tests (:func:`fit_shear`).

    Attributes
    ----------
    c : float or None
        Cohesion [kPa]; None with a single normal pressure.
    phi_deg : float or None
        Angle of internal friction [deg]; None with a single normal pressure.
    K : float
        Common shear deformation modulus [m] (joint fit of all tests).
    tests : list of ShearTestFit
        Per-test tau_max and K.
    undetermined : list of str
        ``["c", "phi_deg"]`` with a single normal pressure, else empty.
    c_ci, phi_deg_ci : (float, float) or None
        95 % confidence intervals from the regression (at least 3 tests over
        at least 2 normal pressures), else None.
    notes : list of str
    """

    c: float | None = quantity("pressure")
    phi_deg: float | None = quantity("none")
    K: float = quantity("length")
    tests: list[ShearTestFit]
    undetermined: list[str]
    c_ci: tuple[float, float] | None = quantity("pressure", default=None)
    phi_deg_ci: tuple[float, float] | None = quantity("none", default=None)
    notes: list[str] = field(default_factory=list)

    @property
    def terrain_shear(self) -> TerrainShear:
        """The fitted c, phi and K as a :class:`terracone.data.TerrainShear`."""
        return TerrainShear(c=self.c, phi_deg=self.phi_deg, K=self.K)

    def params(self) -> dict[str, float]:
        """Determined parameters as library/export keys (SI): c_kpa, phi_deg, K_m."""
        out = {"c_kpa": self.c, "phi_deg": self.phi_deg, "K_m": self.K}
        return {k: float(v) for k, v in out.items() if v is not None}

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """JSON-ready result in a unit system (c in kPa or psi, K in m or in)."""
        keys = ("c", "phi_deg", "K", "c_ci", "phi_deg_ci", "undetermined", "notes", "tests")
        return {
            **output(self, units, fields=keys),
            "units": units,
            "unit_labels": {
                "c": u.pressure_unit(units),
                "K": u.length_unit(units),
                "tau_max": u.pressure_unit(units),
            },
        }


def _points(test: ShearTest, peak_tolerance: float, j_max: float | None):
    j, tau = of_type(test, ShearTest).displacement, test.stress
    ok = np.isfinite(j) & np.isfinite(tau) & (j >= 0)
    if j_max is not None:
        ok &= j <= j_max
    idx = np.flatnonzero(ok)
    if idx.size:
        # last point within peak_tolerance of the peak stress: the end of the
        # "peak stress region"; a post-peak drop beyond it is not fitted
        t_ok = tau[idx]
        peak = t_ok.max()
        last = idx[np.flatnonzero(t_ok >= peak - peak_tolerance * abs(peak))[-1]]
        idx = idx[idx <= last]
    j, tau = j[idx], tau[idx]
    if j.size < 3 or np.ptp(j) <= 0 or tau.max() <= 0:
        raise InputError(
            f"{j.size} usable point(s) with j >= 0 up to the peak stress; at least 3 with "
            f"distinct displacements and a positive peak are needed{test.lines_note()}",
            file=test.source,
            profile=test.id,
            item="test",
            row=test.first_row(),
        )
    return j, tau


def _start_K(j: np.ndarray, tau: np.ndarray, tau0: float) -> float:
    # displacement where tau first reaches (1 - 1/e) tau_max: j = K on the curve
    hit = np.flatnonzero(tau >= (1.0 - math.exp(-1.0)) * tau0)
    K0 = float(j[hit[0]]) if hit.size else 0.0
    return K0 if K0 > 0 else float(np.max(j)) / 10.0


def _fit_common_K(
    data: list[tuple[np.ndarray, np.ndarray]], tau0: np.ndarray, K0: float
) -> tuple[np.ndarray, float]:
    """One tau_max per test and one shared K, least squares on all stresses (from tau0, K0)."""
    m = len(data)
    j = np.concatenate([d[0] for d in data])
    tau = np.concatenate([d[1] for d in data])
    g = np.concatenate([np.full(d[0].size, i) for i, d in enumerate(data)])

    def fun(x):
        return shear_stress_janosi_hanamoto(j, x[g], x[m]) - tau

    def jac(x):
        e = np.exp(-j / x[m])
        J = np.zeros((j.size, m + 1))
        J[np.arange(j.size), g] = 1.0 - e
        J[:, m] = -x[g] * e * j / x[m] ** 2
        return J

    x0 = np.concatenate([tau0, [K0]])
    lo = np.concatenate([np.zeros(m), [1e-12]])
    res = optimize.least_squares(
        fun,
        x0,
        jac=jac,
        bounds=(lo, np.full(m + 1, np.inf)),
        x_scale=np.maximum(x0, 1e-9),
        xtol=1e-14,
    )
    return res.x[:m], float(res.x[m])


def fit_shear_test(
    test: ShearTest, *, peak_tolerance: float = 0.02, j_max: float | None = None
) -> ShearTestFit:
    """Fit ``tau = tau_max (1 - exp(-j/K))`` to one shear test.

    Parameters
    ----------
    test : ShearTest
        Displacement j [m], stress tau [kPa], normal pressure [kPa].
    peak_tolerance : float
        Relative drop from the peak stress that ends the fitted range [-]
        (see the module docstring).
    j_max : float, optional
        Largest displacement fitted [m].

    Returns
    -------
    ShearTestFit
        tau_max [kPa], K [m], points used, RMSD [kPa].
    """
    if not 0 <= peak_tolerance < 1:
        raise ValueError("peak_tolerance must be in [0, 1)")
    j, tau = _points(test, peak_tolerance, j_max)
    tau0 = float(tau.max())
    tau_max, K = _fit_common_K([(j, tau)], np.array([tau0]), _start_K(j, tau, tau0))
    tau_max = float(tau_max[0])
    res = tau - shear_stress_janosi_hanamoto(j, tau_max, K)
    ss_tot = float(np.sum((tau - tau.mean()) ** 2))
    return ShearTestFit(
        test=test.id,
        normal_pressure=float(test.normal_pressure),
        tau_max=tau_max,
        K=K,
        points_used=int(j.size),
        rmsd=float(np.sqrt(np.mean(res * res))),
        r2=1.0 - float(res @ res) / ss_tot if ss_tot > 0 else float("nan"),
        j_end=float(j.max()),
    )


def fit_shear(
    tests: Iterable[ShearTest], *, peak_tolerance: float = 0.02, j_max: float | None = None
) -> ShearFit:
    """c, phi and K of the terrain from shear tests.

    Parameters
    ----------
    tests : iterable of ShearTest
        Shear tests of one terrain, SI (j [m], tau and sigma [kPa]).  An
        :class:`InputError` in the iterable is raised.
    peak_tolerance, j_max
        Fitted range of each test, see :func:`fit_shear_test`.

    Returns
    -------
    ShearFit
        c [kPa] and phi [deg] from ``tau_max = c + sigma tan(phi)`` when the
        tests cover two or more normal pressures (else None, listed in
        ``undetermined``), the common K [m] and the per-test fits.
    """
    tests = list(tests)
    if not tests:
        raise ValueError("no shear tests to fit")
    data = [_points(t, peak_tolerance, j_max) for t in tests]
    fits = [fit_shear_test(t, peak_tolerance=peak_tolerance, j_max=j_max) for t in tests]
    m = len(fits)

    # common K: tau_ij = tau_max_i (1 - exp(-j_ij / K)), one K for all tests
    tau0 = np.array([f.tau_max for f in fits])
    _, K = _fit_common_K(data, tau0, float(np.median([f.K for f in fits])))

    sigma = np.array([f.normal_pressure for f in fits])
    if np.unique(np.round(sigma, 9)).size < 2:
        note = (
            f"one normal pressure ({sigma[0]:g} kPa): c and phi cannot be separated "
            "(tau_max = c + sigma tan(phi)); tau_max and K are given per test"
        )
        return ShearFit(None, None, K, fits, ["c", "phi_deg"], notes=[note])
    # Mohr-Coulomb: tau_max_i = c + sigma_i tan(phi), OLS over the tests
    coef, half = line_fit(np.column_stack([np.ones(m), sigma]), tau0)
    c, slope = float(coef[0]), float(coef[1])
    c_ci = phi_ci = None
    notes = []
    if half is not None:
        c_ci = (c - half[0], c + half[0])
        # arctan is monotonic: the slope interval maps to a phi interval
        phi_ci = (
            math.degrees(math.atan(slope - half[1])),
            math.degrees(math.atan(slope + half[1])),
        )
    else:
        notes.append("confidence intervals need at least 3 tests over 2 normal pressures")
    if c < 0:
        notes.append(f"c = {c:.4g} kPa < 0 (regression intercept)")
    return ShearFit(c, math.degrees(math.atan(slope)), K, fits, [], c_ci, phi_ci, notes)

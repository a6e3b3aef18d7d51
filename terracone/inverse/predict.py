"""The prediction process (section 3.3.2 of [1]_): CI profile -> parameters.

Two solvers behind :func:`predict`:

* ``"exact"`` (default): global optimum from the linear structure of the
  model (:mod:`terracone.inverse.exact`);
* ``"pso"``: the paper's particle swarm (:mod:`terracone.inverse.pso`) on the
  same objective and bounds.

The objective is the RMSD between measured CI and model CI at the measured
depths.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3.2.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from typing import Any

import numpy as np

from .. import units as u
from ..cone import improved
from ..data import CIProfile, InputError, TerrainParameters
from ..metrics import check_fit_fast
from ..plate import PressureLaw, pressure_law
from ..result import PredictionResult, PredictionResults
from .bounds import Bounds
from .exact import solve_exact
from .pso import pso

__all__ = ["PredictionResult", "PredictionResults", "predict", "predict_many", "rmsd_objective"]


def rmsd_objective(profile: CIProfile, law: PressureLaw, bounds: Bounds, Kc: float | None = None):
    """RMSD [kPa] of positions (P, 5) = (kc, kphi, n, cc, phic) in the bounds' units.

    With ``bounds`` in US units the kc and kphi coordinates are in
    lb/in^(n+1) and lb/in^(n+2); cc is in kPa and phic in degrees.
    """
    z, y = profile.depth, profile.ci

    def f(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x)
        n = x[:, 2:3]
        kc = u.kc_to_si(x[:, 0:1], n, bounds.kc_units)
        kphi = u.kphi_to_si(x[:, 1:2], n, bounds.kphi_units)
        K = x[:, 5:6] if x.shape[1] > 5 else Kc
        ci = improved(
            z, kc=kc, kphi=kphi, n=n, cc=x[:, 3:4], phic=x[:, 4:5], Kc=K, law=law, cone=profile.cone
        )
        r = ci - y
        return np.sqrt(np.mean(r * r, axis=-1))

    return f


def predict(
    profile: CIProfile,
    *,
    model: str = "rm0",
    r_min: float | None = None,
    plate_pair: tuple[float, float] | None = None,
    calibration: Any = None,
    solver: str = "exact",
    bounds: Bounds | None = None,
    Kc: float | None = None,
    fit_Kc: bool = False,
    seed: int | None = None,
    noise_floor: float = 0.01,
    pso_options: dict[str, Any] | None = None,
    fix_ratio: bool = True,
) -> PredictionResult:
    """Fit the improved cone model to one CI profile (prediction process).

    Parameters
    ----------
    profile : CIProfile
    model : {"rm0", "rm1"}
    r_min : float, optional
        RM1 transition radius [m].
    plate_pair : (r1, r2), optional
        Plate radii [m] defining the RM1 secant when r_min > r2.
    calibration : Calibration, optional
        A learned calibration (section 3.3.1): fixes model, r_min, phic and
        cc, and (``fix_ratio``) the ratio kc/kphi of the calibrated terrain.
    solver : {"exact", "pso"}
    bounds : Bounds, optional
        Search bounds (defaults in SI: kc 0-1000, kphi 0-20000, n 0.05-2,
        cc 0-100 kPa, phic 0-45 deg).
    Kc : float, optional
        Fixed shear deformation parameter [m]; None: fully mobilised shear.
    fit_Kc : bool
        Search Kc as a sixth parameter within ``bounds.Kc``.
    seed : int, optional
        Seed of the particle swarm.
    noise_floor : float
        Smallest relative noise assumed when judging identifiability.
    fix_ratio : bool
        With a calibration, hold kc/kphi at the calibrated terrain's value:
        the cone barely separates kc from kphi (their columns are nearly
        collinear), plates of two sizes do.  Only the exact solver uses it.
    """
    t0 = time.perf_counter()
    if solver not in ("exact", "pso"):
        raise ValueError(f"solver must be 'exact' or 'pso' (got {solver!r})")
    bounds = bounds or Bounds()
    try:
        profile.validate()
    except InputError as exc:
        return _error(profile, str(exc))
    if calibration is not None:
        model = calibration.model
        r_min = calibration.r_min
        plate_pair = calibration.plate_pair
        bounds = bounds.fixed(phic=calibration.phic_deg, cc=calibration.cc)
    ratio = None
    if calibration is not None and fix_ratio and calibration.kphi > 0:
        ratio = calibration.kc / calibration.kphi
    law = pressure_law(model, r_min=r_min, plate_pair=plate_pair)
    z, y = profile.depth, profile.ci
    try:
        if solver == "exact":
            sol = solve_exact(
                z,
                y,
                cone=profile.cone,
                law=law,
                bounds=bounds,
                Kc=Kc,
                fit_Kc=fit_Kc,
                noise_floor=noise_floor,
                kc_over_kphi=ratio,
            )
            params = TerrainParameters(
                sol.kc, sol.kphi, sol.n, sol.cc, sol.phic_deg, sol.Kc, model, r_min
            )
            extra = dict(
                undetermined=sol.undetermined,
                phic_range=sol.phic_range,
                profile_intervals=sol.profile_intervals,
                sigma=sol.sigma,
                nfev=sol.nfev,
                nit=sol.nit,
                converged=True,
                message="global optimum of the bounded linear least squares over the n, phic grid",
            )
        elif solver == "pso":
            f = rmsd_objective(profile, law, bounds, Kc)
            lo = [bounds.kc[0], bounds.kphi[0], bounds.n[0], bounds.cc[0], bounds.phic[0]]
            hi = [bounds.kc[1], bounds.kphi[1], bounds.n[1], bounds.cc[1], bounds.phic[1]]
            if fit_Kc:
                lo.append(bounds.Kc[0])
                hi.append(bounds.Kc[1])
            res = pso(f, np.array(lo), np.array(hi), seed=seed, **(pso_options or {}))
            x = res.x
            n = float(x[2])
            params = TerrainParameters(
                float(u.kc_to_si(x[0], n, bounds.kc_units)),
                float(u.kphi_to_si(x[1], n, bounds.kphi_units)),
                n,
                float(x[3]),
                float(x[4]),
                float(x[5]) if fit_Kc else Kc,
                model,
                r_min,
            )
            und = (
                ["phic", "phic~scale(kc,kphi)"]
                if (not fit_Kc and Kc is None and bounds.phic[0] != bounds.phic[1])
                else []
            )
            extra = dict(
                undetermined=und,
                nfev=res.nfev,
                nit=res.nit,
                converged=res.converged,
                message=res.message + " (pso does not analyse identifiability beyond phic)",
            )
        else:
            raise ValueError(f"solver must be 'exact' or 'pso' (got {solver!r})")
        m = improved(
            z,
            kc=params.kc,
            kphi=params.kphi,
            n=params.n,
            cc=params.cc,
            phic=params.phic_deg,
            Kc=params.Kc,
            law=law,
            cone=profile.cone,
        )
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return _error(profile, f"solver failed: {exc}")
    r = m - y
    rmsd = float(np.sqrt(np.mean(r * r)))
    chk = check_fit_fast(z, y, m)
    notes = list(profile.notes)
    if calibration is not None:
        fixed = "model, r_min, phic, cc" + (
            " and kc/kphi" if ratio is not None and solver == "exact" else ""
        )
        notes.append(f"calibration {calibration.terrain!r}: {fixed} fixed")
    return PredictionResult(
        id=profile.id,
        status="ok",
        params=params,
        rmsd=rmsd,
        r2_ci=chk.r2,
        longest_run=chk.longest_run,
        lack_of_fit=chk.lack_of_fit,
        depth=z,
        ci=y,
        ci_model=m,
        solver=solver,
        time_s=time.perf_counter() - t0,
        cone=profile.cone.name,
        metadata=dict(profile.metadata),
        notes=notes,
        source=profile.source,
        **extra,
    )


def _error(profile: CIProfile, reason: str) -> PredictionResult:
    return PredictionResult(
        id=profile.id,
        status="error",
        error=reason,
        cone=profile.cone.name,
        metadata=dict(profile.metadata),
        notes=list(profile.notes),
        source=profile.source,
    )


def predict_many(items: Iterable[CIProfile | InputError], **kwargs: Any) -> PredictionResults:
    """:func:`predict` for each item; reader errors become error results.

    Returns a :class:`PredictionResults` (a list) in the order of the items.
    """
    out = PredictionResults()
    for it in items:
        if isinstance(it, InputError):
            out.append(
                PredictionResult(id=str(it.profile), status="error", error=str(it), source=it.file)
            )
        else:
            out.append(predict(it, **kwargs))
    return out

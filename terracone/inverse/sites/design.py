"""Test planning: which one extra test narrows the predicted plate pressure most?

A linearised (Fisher) preposterior analysis [1]_: around the best fit of the
CI profile the posterior of the free parameters is normal with precision
``I_0 = P + J^T S^-1 J`` (prior precision P, Jacobian J of eq. (2-7), CI
error covariance S as in :mod:`terracone.inverse.sites.statistics`); a
candidate test (``plate:R``, ``ci``, ``shear``) with Jacobian H and noise
covariance R adds ``H^T R^-1 H``, and the expected 90% width of the predicted
plate pressure (eq. (2-2)) after it is ``2 z_0.95 sqrt(g^T (I_0 + H^T R^-1
H)^-1 g)``.  A shear test measures the terrain's internal shear, which enters
neither (2-2) nor (2-7): it narrows nothing, and the analysis says so.  The
candidates, priors and the check against a brute-force preposterior
simulation: ``docs/sites.md``.

References
----------
.. [1] Raiffa, H., Schlaifer, R. (1961). Applied Statistical Decision
   Theory. Harvard University (preposterior analysis).
.. [2] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2), (2-6), (2-7), section 2.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from terracone.data import CIProfile
from terracone.inverse.bounds import Bounds
from terracone.inverse.evaluate import predicted_plate_pressure
from terracone.inverse.predict import predict
from terracone.inverse.problem import CalibrationPrior, Problem
from terracone.inverse.sites.statistics import ci_error_covariance, default_sinkages
from terracone.physics import units as u
from terracone.physics.cone import cone_index_huang
from terracone.resultunits import Written, output, quantity

__all__ = ["CandidateResult", "DesignResult", "parse_candidates", "plan_test"]

_NAMES = ("kc", "kphi", "n", "cc", "phic_deg")
_LEN = re.compile(r"^\s*([0-9.eE+-]+)\s*(m|cm|mm|in)?\s*$")
#: The keys of a :class:`DesignResult` document before ``best``, in order.
_PLAN_KEYS = (
    "id", "status", "error", "prior", "plates", "sinkage", "median", "current_width", "candidates",
)  # fmt: skip


@dataclass
class CandidateResult(Written):
    """One candidate test.

    Attributes
    ----------
    test : str
        As given (``plate:5cm``, ``ci``, ``shear``).
    kind : {"plate", "ci", "shear"}
    radius : float or None
        Plate radius [m].
    expected_width : ndarray
        Expected 90% width of the predicted plate pressure after the test,
        per target plate [kPa].
    width_ratio : float
        Mean over the target plates of expected / current width [-].
    rank : int
        1 = narrows the prediction most.
    note : str
    """

    test: str
    kind: str
    radius: float | None = quantity("length")
    expected_width: np.ndarray = quantity("pressure")
    width_ratio: float
    rank: int = 0
    note: str = ""


@dataclass
class DesignResult:
    """Preposterior analysis of one profile (SI inside).

    Attributes
    ----------
    id : str
    status : {"ok", "error"}
    error : str or None
    prior : str
    plates : list of float
        Target plate radii [m].
    sinkage : float
        Sinkage at which the widths are taken [m].
    median : ndarray
        Predicted plate pressure per target plate [kPa].
    current_width : ndarray
        90% width before any extra test [kPa].
    candidates : list of CandidateResult
        Ranked, best first.
    lack_of_fit : str or None
    notes : list of str
    """

    id: str
    status: str
    error: str | None = None
    prior: str = "bounds"
    plates: list[float] = quantity("length", default_factory=list)
    sinkage: float = quantity("length", default=float("nan"))
    median: np.ndarray | None = quantity("pressure", default=None)
    current_width: np.ndarray | None = quantity("pressure", default=None)
    candidates: list[CandidateResult] = field(default_factory=list)
    lack_of_fit: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """JSON-ready plan (plates and sinkage in m or in, pressures in kPa or psi)."""
        plan = output(self, units, fields=_PLAN_KEYS)
        best = self.candidates[0].test if self.candidates else None
        tail = output(self, units, fields=("lack_of_fit", "notes"))
        return {**plan, "best": best, **tail, "units": units}


def parse_candidates(text: str, units: str = "si") -> list[tuple[str, str, float | None]]:
    """``"plate:5cm,plate:10cm,ci,shear"`` -> [(label, kind, radius [m] or None)]."""
    out = []
    for part in (s.strip() for s in text.split(",")):
        if not part:
            continue
        if part in ("ci", "shear"):
            out.append((part, part, None))
            continue
        kind, _, size = part.partition(":")
        m = _LEN.match(size)
        if kind != "plate" or not m or float(m.group(1)) <= 0:
            raise ValueError(
                f"candidates: expected plate:RADIUS (e.g. plate:5cm), ci or shear, got {part!r}"
            )
        v = float(m.group(1))
        r = v * u.LENGTH_UNITS[m.group(2)] if m.group(2) else float(u.length_to_si(v, units))
        out.append((part, "plate", r))
    if not out:
        raise ValueError("candidates: none given")
    return out


def _prior_precision(theta, free, bounds: Bounds, cal: CalibrationPrior | None) -> np.ndarray:
    """Prior precision over the free parameters (normal approximation)."""
    kc, kphi, n = theta[0], theta[1], theta[2]
    boxes = (bounds.kc_si(n), bounds.kphi_si(n), bounds.n, bounds.cc, bounds.phic_deg)
    rng = [hi - lo for lo, hi in boxes]
    P = np.diag([12.0 / max(float(r), 1e-9) ** 2 for r in rng])  # variance of a uniform
    if cal is not None:
        c = cal.calibration
        P[3, 3] = 1.0 / max(cal.cc_width, 1e-6) ** 2
        P[4, 4] = 1.0 / max(cal.phic_sd, 1e-6) ** 2
        if kc > 0 and kphi > 0 and c.kc > 0:
            P[0, 0] = 0.0  # kc follows kphi through the ratio prior
            a = np.array([1.0 / kc, -1.0 / kphi, 0, 0, 0])
            P += np.outer(a, a) / cal.ratio_log_sd**2
    return P[np.ix_(free, free)]


def _jacobian(f, theta: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Central differences of f (returning a vector) with respect to the free parameters."""
    cols = []
    for i in np.flatnonzero(free):
        h = 1e-4 * max(abs(theta[i]), 1.0 if i >= 2 else 1e-2)
        tp, tm = theta.copy(), theta.copy()
        tp[i] += h
        tm[i] = max(tm[i] - h, 0.0) if i != 2 else tm[i] - h
        cols.append((f(tp) - f(tm)) / (tp[i] - tm[i]))
    return np.column_stack(cols)


def _ci_precision(profile: CIProfile, model_ci, J, ci_noise: float | None) -> np.ndarray:
    """J^T S^-1 J for the CI noise: given (independent) or estimated as in the site model."""
    if ci_noise is not None:
        return J.T @ J / ci_noise**2
    S = ci_error_covariance(profile.depth, profile.ci, model_ci, J, floor=1e-12)[0]
    return J.T @ np.linalg.solve(S, J)


def _plate(t: np.ndarray, law, r: float, s) -> np.ndarray:
    """Plate pressure [kPa] of theta = (kc, kphi, n, cc, phic) at sinkages s [m] (eq. (2-2))."""
    t = np.maximum(t, [0, 0, 1e-3, 0, 0])
    return (t[0] * law.kc_factor(r) + t[1]) * np.asarray(s, float) ** t[2]


def _candidate(cand, widths, I0, I_ci, current, theta, free, pb: Problem, plate_noise, s_test):
    """Expected widths after one candidate test (Fisher information added to I0)."""
    label, kind, r = cand
    law = pb.law
    if kind == "plate":
        H = _jacobian(lambda t: _plate(_held(t, pb), law, r, s_test), theta, free)
        sd = plate_noise * np.maximum(_plate(theta, law, r, s_test), 1e-6)
        w = widths(I0 + H.T @ (H / sd[:, None] ** 2))
        note = (
            f"{s_test.size} readings to {s_test.max() * 100:.3g} cm, {plate_noise:.0%} error each"
        )
    elif kind == "ci":
        w = widths(I0 + I_ci)
        note = "another push of the same terrain, same noise"
    else:
        w = current.copy()
        note = "internal shear (c, phi, K) enters neither eq. (2-2) nor eq. (2-7): no information"
    ratio = float(np.mean(w / np.maximum(current, 1e-300)))
    return CandidateResult(label, kind, r, w, ratio, note=note)


def _held(t: np.ndarray, pb: Problem) -> np.ndarray:
    """theta with kc = ratio kphi where the problem holds the ratio."""
    if pb.ratio is None or pb.centre is not None:
        return t
    t = np.array(t, dtype=float, copy=True)
    t[0] = pb.ratio * t[1]
    return t


def _information(
    profile: CIProfile, res: Any, pb: Problem, ci_noise
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The fitted parameters, which of them are free, and the Fisher information of
    the CI data alone and of the CI data with the prior (free parameters only).

    The prior is the problem's: the held box (phic, cc pinned; kc following
    kphi through a held ratio), or normal around a calibration given as the prior.
    """
    cal = pb.centre
    bounds = pb.bounds if cal is not None else pb.fit_bounds
    prm = res.params
    theta = np.array([prm.kc, prm.kphi, prm.n, prm.cc, prm.phic_deg])
    fixed = [bounds.kc, bounds.kphi, bounds.n, bounds.cc, bounds.phic_deg]
    free = np.array([lo < hi for lo, hi in fixed])
    if (cal is not None and cal.calibration.kc <= 0) or (cal is None and pb.ratio is not None):
        free[0] = False

    def ci_of(t):  # eq. (2-7)
        t = _held(t, pb)
        c = dict(kc=t[0], kphi=t[1], n=t[2], cc=t[3], phic_deg=t[4])
        return cone_index_huang(profile.depth, **c, K_cone=None, law=pb.law, cone=profile.cone)

    J = _jacobian(ci_of, theta, free)
    I_ci = _ci_precision(profile, res.ci_model, J, ci_noise)
    return theta, free, I_ci, _prior_precision(theta, free, bounds, cal) + I_ci


def plan_test(
    profile: CIProfile,
    problem: Problem | None = None,
    *,
    candidates: Sequence[tuple[str, str, float | None]] | str = "plate:5cm,plate:10cm,ci,shear",
    plates: Sequence[float] = (0.05,),
    plate_noise: float = 0.05,
    ci_noise: float | None = None,
    sinkage: float | None = None,
    plate_sinkages: Sequence[float] | None = None,
    level: float = 0.9,
) -> DesignResult:
    """Expected 90% width of the predicted plate pressure after each candidate test.

    Parameters
    ----------
    profile : CIProfile
        The CI data in hand.
    problem : Problem, optional
        What is fitted and the prior: the bounds (uniform), with the values a
        calibration holds held, or a calibration given as the prior (normal
        around its phic, cc and kc/kphi).
    candidates : str or list of (label, kind, radius)
        See :func:`parse_candidates`.
    plates : sequence of float
        Target plate radii [m] of the prediction.
    plate_noise : float
        Relative standard error of a plate reading [-].
    ci_noise : float, optional
        Independent CI noise [kPa]; by default estimated from the fit.
    sinkage : float, optional
        Sinkage of the prediction [m]; the middle of the site sinkages
        (2.6 cm) by default.
    plate_sinkages : sequence of float, optional
        Sinkages read in a candidate plate test [m] (10 to 5 cm by default).
    level : float

    Returns
    -------
    DesignResult
        Candidates ranked by expected width (mean ratio over the plates).
    """
    if isinstance(candidates, str):
        candidates = parse_candidates(candidates)
    if not plates:
        raise ValueError("give at least one target plate radius")
    pb = problem or Problem()
    pb.require_single("plan_test")
    res = predict(profile, pb)
    label = pb.prior_label()
    if not res.ok:
        return DesignResult(profile.id, "error", res.error, label)
    prm, law = res.params, pb.law
    theta, free, I_ci, I0 = _information(profile, res, pb, ci_noise)
    s_mid = default_sinkages()[12] if sinkage is None else float(sinkage)
    G = np.stack([_jacobian(lambda t, r=r: np.atleast_1d(_plate(_held(t, pb), law, r, s_mid)),
                            theta, free)[0] for r in plates])  # fmt: skip
    zq = stats.norm.ppf(0.5 + level / 2)

    def widths(info):
        cov = np.linalg.pinv(info, rcond=1e-14, hermitian=True)
        return 2 * zq * np.sqrt(np.maximum(np.einsum("ri,ij,rj->r", G, cov, G), 0.0))

    current = widths(I0)
    median = np.array(
        [float(predicted_plate_pressure(prm, s_mid, r, law.plate_pair)) for r in plates]
    )
    s_test = np.linspace(0.005, 0.05, 10) if plate_sinkages is None else np.asarray(plate_sinkages)
    out = [
        _candidate(c, widths, I0, I_ci, current, theta, free, pb, plate_noise, s_test)
        for c in candidates
    ]
    out.sort(key=lambda cnd: cnd.width_ratio)  # best first
    for i, cnd in enumerate(out):
        cnd.rank = i + 1
    notes = list(res.notes)
    if res.undetermined:
        notes.append("left free by the CI: " + ", ".join(res.undetermined))
    return DesignResult(
        profile.id, "ok", None, label, list(plates), s_mid, median, current, out,
        res.lack_of_fit, notes,
    )  # fmt: skip

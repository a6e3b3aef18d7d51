"""Agreement between measured and predicted curves (Tables 4-2 and 4-4 of [1]_).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-2 and 4-4.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from terracone.jit import enabled, njit

__all__ = ["Agreement", "agreement", "pearson_r", "rmsd", "cv", "finite_median"]


def finite_median(values: Iterable[float | None]) -> float | None:
    """Median of the finite values (None and NaN left out); None when there are none."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.median(v)) if v else None


def pearson_r(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Coefficient of correlation R (Pearson) [-]; NaN if either is constant."""
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    dm, dp = m - m.mean(), p - p.mean()
    den = np.sqrt(np.sum(dm * dm) * np.sum(dp * dp))
    return float(np.sum(dm * dp) / den) if den > 0 else float("nan")


def rmsd(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Root mean square deviation, in the unit of the data."""
    d = np.asarray(predicted, dtype=float) - np.asarray(measured, dtype=float)
    return float(np.sqrt(np.mean(d * d)))


def cv(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Coefficient of variation CV = RMSD / mean(measured) [-]."""
    return rmsd(measured, predicted) / float(np.mean(np.asarray(measured, dtype=float)))


@dataclass(frozen=True)
class Agreement:
    """R, R^2, RMSD and CV of Tables 4-2 and 4-4 (RMSD in the data's unit)."""

    R: float
    R2: float
    RMSD: float
    CV: float
    n_points: int

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def agreement(measured: ArrayLike, predicted: ArrayLike) -> Agreement:
    """R, R^2 = R*R, RMSD and CV between measured and predicted values."""
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    if m.shape != p.shape or m.size < 2:
        raise ValueError("measured and predicted must have one shape and >= 2 points")
    r = pearson_r(m, p)
    return Agreement(R=r, R2=r * r, RMSD=rmsd(m, p), CV=cv(m, p), n_points=int(m.size))


@dataclass(frozen=True)
class FitCheck:
    """Whether a homogeneous-terrain fit follows its data.

    Attributes
    ----------
    r2 : float
        Coefficient of determination of the fit [-].
    longest_run : int
        Largest number of consecutive residuals of one sign.
    runs_z : float
        z-score of the Wald-Wolfowitz runs test of the residual signs
        (strongly negative: residuals in long same-sign stretches).
    lack_of_fit : str or None
        None, or why the fit must not be taken for parameters.
    """

    r2: float
    longest_run: int
    runs_z: float
    lack_of_fit: str | None


def check_fit(
    depth: ArrayLike,
    measured: ArrayLike,
    model: ArrayLike,
    *,
    min_r2: float = 0.8,
    max_runs_z: float = -3.0,
    max_drop: float = 0.15,
    min_cv: float = 0.05,
    monotone_model: bool = True,
) -> FitCheck:
    """Lack-of-fit diagnostics of a CI fit.

    Three independent reasons flag a fit:

    * R^2 below ``min_r2`` while the RMSD exceeds ``min_cv`` of the mean
      (a flat profile fitted to its noise level has a low R^2 and no lack
      of fit);
    * residual signs that cluster (runs test z below ``max_runs_z``, with
      10 or more points): the model's shape does not follow the data;
    * measured CI that falls with depth by more than ``max_drop`` of its
      running peak (after a 3-point running median): the homogeneous
      model, assumption (a) of section 2 of [1]_, only rises with depth,
      so such a profile is layered.

    Parameters
    ----------
    depth : array_like
        Base depths [m].
    measured, model : array_like
        Measured and model CI (same unit).
    monotone_model : bool
        The model's CI can only rise with depth (one homogeneous layer), so
        falling measured CI is a lack of fit; False for layered models.
    """
    z = np.asarray(depth, float)
    y = np.asarray(measured, float)
    m = np.asarray(model, float)
    r = m - y
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(r @ r) / ss_tot if ss_tot > 0 else float("nan")
    # residuals at rounding level carry no sign: an exact fit is not a lack of fit
    tiny = 1e-9 * float(np.sqrt(np.mean(y * y))) if y.size else 0.0
    s = np.where(np.abs(r) > tiny, np.sign(r), 0.0)
    s = s[s != 0]
    edges = np.concatenate([[0], np.flatnonzero(s[1:] != s[:-1]) + 1, [s.size]])
    best = int(np.diff(edges).max()) if s.size else 0
    n_pos, n_neg = int(np.sum(s > 0)), int(np.sum(s < 0))
    N = n_pos + n_neg
    runs = edges.size - 1 if N else 0
    z_runs = float("nan")
    if N >= 2 and n_pos and n_neg:
        mu = 2.0 * n_pos * n_neg / N + 1.0
        var = (mu - 1.0) * (mu - 2.0) / (N - 1.0)
        if var > 0:
            z_runs = (runs - mu) / np.sqrt(var)
    reasons = []
    cv_fit = float(np.sqrt(np.mean(r * r)) / np.mean(np.abs(y))) if np.any(y) else 0.0
    if np.isfinite(r2) and r2 < min_r2 and cv_fit > min_cv:
        reasons.append(
            f"R2 of the CI fit is {r2:.2f} (below {min_r2:g}) with RMSD {cv_fit * 100:.0f}% of the mean CI"
        )
    if N >= 10 and np.isfinite(z_runs) and z_runs < max_runs_z:
        reasons.append(
            f"residuals keep one sign over long stretches (longest run {best} of {y.size} points, "
            f"runs test z = {z_runs:.1f}): the model's shape does not follow the data"
        )
    if monotone_model and y.size >= 4:
        sm = y.copy()
        sm[1:-1] = np.median(np.stack([y[:-2], y[1:-1], y[2:]]), axis=0)
        peak = np.maximum.accumulate(sm)
        drop = (peak - sm) / np.where(peak > 0, peak, np.inf)
        k = int(np.argmax(drop))
        if drop[k] > max_drop:
            i_peak = int(np.argmax(sm[: k + 1]))
            reasons.append(
                f"CI falls with depth between {z[i_peak] * 100:.3g} and {z[k] * 100:.3g} cm "
                f"({drop[k] * 100:.0f}% below its peak): layered soil, which the homogeneous "
                "model (assumption (a), section 2) cannot follow"
            )
    return FitCheck(r2, int(best), z_runs, "; ".join(reasons) if reasons else None)


def check_fit_fast(depth: ArrayLike, measured: ArrayLike, model: ArrayLike) -> FitCheck:
    """:func:`check_fit` with its default limits, the numbers from a compiled kernel.

    :func:`fit_stats` (compiled) computes R^2, the longest run and the
    runs-test z; check_fit itself runs only when a reason may
    apply (within 1e-9 of a limit), and then decides and words it.  Plain
    check_fit when compiled kernels are off (:func:`terracone.jit.enabled`).
    """
    if not enabled():
        return check_fit(depth, measured, model)
    y = np.ascontiguousarray(measured, dtype=float)
    m = np.ascontiguousarray(model, dtype=float)
    r2, best, z_runs, flagged = fit_stats(y, m, *_FIT_LIMITS)
    if flagged:
        return check_fit(depth, y, m)
    return FitCheck(float(r2), int(best), float(z_runs), None)


#: check_fit's default limits, in the order of fit_stats' arguments.
_FIT_LIMITS = tuple(check_fit.__kwdefaults__.values())


@njit(error_model="numpy")
def fit_stats(y, m, min_r2, max_runs_z, max_drop, min_cv, monotone):
    """The numbers behind :func:`terracone.physics.metrics.check_fit` for one profile.

    Returns (r2, longest_run, z_runs, flagged): flagged is True when any of
    check_fit's three reasons applies or is within 1e-9 of its threshold
    (then the caller asks check_fit, which decides and words the reason).  The same arithmetic as check_fit, with the 3-point running
    median as the middle of three values.
    """
    N = y.shape[0]
    mean = 0.0
    for q in range(N):
        mean += y[q]
    mean /= N
    ss_tot = 0.0
    rr = 0.0
    yy = 0.0
    ay = 0.0
    for q in range(N):
        ss_tot += (y[q] - mean) ** 2
        rq = m[q] - y[q]
        rr += rq * rq
        yy += y[q] * y[q]
        ay += abs(y[q])
    r2 = 1.0 - rr / ss_tot if ss_tot > 0 else np.nan
    tiny = 1e-9 * math.sqrt(yy / N) if N else 0.0
    best = 0
    run = 0
    prev = 0.0
    n_pos = 0
    n_neg = 0
    runs = 0
    for q in range(N):
        rq = m[q] - y[q]
        if abs(rq) > tiny:
            v = 1.0 if rq > 0 else -1.0
            if v == prev:
                run += 1
            else:
                run = 1
                runs += 1
            prev = v
            best = max(best, run)
            if v > 0:
                n_pos += 1
            else:
                n_neg += 1
    M = n_pos + n_neg
    z_runs = np.nan
    if M >= 2 and n_pos > 0 and n_neg > 0:
        mu = 2.0 * n_pos * n_neg / M + 1.0
        var = (mu - 1.0) * (mu - 2.0) / (M - 1.0)
        if var > 0:
            z_runs = (runs - mu) / math.sqrt(var)
    flagged = False
    cv_fit = math.sqrt(rr / N) / (ay / N) if ay > 0 else 0.0
    if (not math.isnan(r2)) and r2 < min_r2 + 1e-9 and cv_fit > min_cv - 1e-9:
        flagged = True
    if M >= 10 and (not math.isnan(z_runs)) and z_runs < max_runs_z + 1e-9:
        flagged = True
    if monotone and N >= 4:
        peak = -np.inf
        for q in range(N):
            if 0 < q < N - 1:
                a, b, c = y[q - 1], y[q], y[q + 1]
                sm = max(min(a, b), min(max(a, b), c))
            else:
                sm = y[q]
            peak = max(peak, sm)
            drop = (peak - sm) / peak if peak > 0 else 0.0
            if drop > max_drop - 1e-9:
                flagged = True
    return r2, best, z_runs, flagged

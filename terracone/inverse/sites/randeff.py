"""Random-effects pooling of per-push estimates: between-push variance apart from estimation noise.

``y_j = mu + b_j + e_j``, ``b_j ~ N(0, tau^2)``, ``e_j ~ N(0, v_j)`` with
known ``v_j``, vectorised over independent problems: ``tau^2`` by
Paule-Mandel [1]_ (as [2]_ recommends for few studies), the interval of ``mu``
by Hartung-Knapp-Sidik-Jonkman [3]_, that of ``tau^2`` by the Q-profile
method [4]_ (docs/sites.md, step 3).

References
----------
.. [1] Paule, R.C., Mandel, J. (1982). Consensus values and weighting
   factors. J. Res. Natl. Bur. Stand. 87(5), 377-385.
.. [2] Veroniki, A.A. et al. (2016). Methods to estimate the between-study
   variance and its uncertainty in meta-analysis. Res. Synth. Methods 7,
   55-79.
.. [3] Roever, C., Knapp, G., Friede, T. (2015). Hartung-Knapp-Sidik-Jonkman
   approach and its modification for random-effects meta-analysis with few
   studies. BMC Med. Res. Methodol. 15, 99.
.. [4] Viechtbauer, W. (2007). Confidence intervals for the amount of
   heterogeneity in meta-analysis. Stat. Med. 26, 37-52.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

__all__ = ["RandomEffects", "random_effects"]


@dataclass
class RandomEffects:
    """Pooled estimates, one per problem (arrays of the problems' shape).

    Attributes
    ----------
    mu : ndarray
        Pooled mean.
    tau2 : ndarray
        Between-push variance (Paule-Mandel, >= 0).
    tau2_lo, tau2_hi : ndarray
        Its Q-profile interval at ``level`` [4]_.
    se : ndarray
        Standard error of ``mu`` (HKSJ).
    df : ndarray
        Degrees of freedom of the t quantile (k - 1; 0 when k < 2).
    lo, hi : ndarray
        Two-sided interval of ``mu`` at the requested level.
    k : ndarray
        Number of estimates pooled.
    sample_var : ndarray
        Plain sample variance of the estimates (what ignoring the
        estimation noise would call variability).
    mean_v : ndarray
        Mean estimation variance of the pooled estimates.
    """

    mu: np.ndarray
    tau2: np.ndarray
    tau2_lo: np.ndarray
    tau2_hi: np.ndarray
    se: np.ndarray
    df: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    k: np.ndarray
    sample_var: np.ndarray
    mean_v: np.ndarray


def random_effects(
    y: ArrayLike, v: ArrayLike, mask: ArrayLike | None = None, *, level: float = 0.9
) -> RandomEffects:
    """Random-effects pooling along the last axis.

    Parameters
    ----------
    y : array_like, shape (..., J)
        Estimates (one per push along the last axis).
    v : array_like, shape (..., J)
        Their sampling variances (>= 0), same units squared.
    mask : array_like of bool, optional
        Which entries are present (padding for unequal numbers of pushes).
    level : float
        Level of the two-sided interval of ``mu``.

    Returns
    -------
    RandomEffects
        With ``k < 2`` the variance terms are NaN and ``mu`` is the single
        estimate with an interval from its own variance (normal quantile).

    References
    ----------
    Paule and Mandel (1982); Roever, Knapp and Friede (2015).
    """
    y = np.asarray(y, dtype=float)
    v = np.broadcast_to(np.asarray(v, dtype=float), y.shape)
    m = np.ones(y.shape, bool) if mask is None else np.broadcast_to(np.asarray(mask, bool), y.shape)
    m = m & np.isfinite(y) & np.isfinite(v)
    y0 = np.where(m, y, 0.0)
    v0 = np.where(m, np.maximum(v, 0.0), 1.0)
    k = m.sum(-1)
    kk = np.maximum(k, 1)
    ybar = y0.sum(-1) / kk
    dev = np.where(m, y0 - ybar[..., None], 0.0)
    sample_var = np.where(k > 1, (dev * dev).sum(-1) / np.maximum(k - 1, 1), np.nan)
    mean_v = np.where(m, v0, 0.0).sum(-1) / kk
    # a tiny floor keeps the weights finite when a push is exactly determined
    scale = np.maximum(np.where(k > 1, sample_var, 0.0), 1e-300)
    v0 = np.maximum(v0, np.maximum(1e-12 * scale[..., None], 1e-30))

    def q_of(t2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = np.where(m, 1.0 / (v0 + t2[..., None]), 0.0)
        sw = w.sum(-1)
        mu = (w * y0).sum(-1) / sw
        r = np.where(m, y0 - mu[..., None], 0.0)
        return (w * r * r).sum(-1), mu, sw

    # Paule-Mandel: Q(tau^2) decreases in tau^2; Q = k - 1 solved by bisection
    top = 10.0 * np.maximum(scale, mean_v) + 1e-30

    def root(target: np.ndarray) -> np.ndarray:
        q0 = q_of(np.zeros(ybar.shape))[0]
        positive = (q0 > target) & (k > 1)
        lo = np.zeros(ybar.shape)
        hi = np.where(positive, top, 0.0)
        for _ in range(40):  # widen until Q(hi) <= target
            grow = positive & (q_of(hi)[0] > target)
            if not grow.any():
                break
            hi = np.where(grow, 10.0 * hi, hi)
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            above = q_of(mid)[0] > target
            lo = np.where(above, mid, lo)
            hi = np.where(above, hi, mid)
        return np.where(positive, 0.5 * (lo + hi), 0.0)

    kf = np.maximum(k - 1, 1).astype(float)
    tau2 = root(k - 1.0)
    # Q-profile interval of tau^2 (Viechtbauer 2007): Q(tau^2) ~ chi^2_(k-1)
    tau2_lo = root(stats.chi2.ppf(0.5 + level / 2, kf))
    tau2_hi = root(stats.chi2.ppf(0.5 - level / 2, kf))
    q, mu, sw = q_of(tau2)
    df = np.maximum(k - 1, 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        hk = np.where(k > 1, q / np.maximum(k - 1, 1), 1.0)
        se = np.sqrt(hk / sw)
        tq = np.where(
            k > 1, stats.t.ppf(0.5 + level / 2, np.maximum(df, 1)), stats.norm.ppf(0.5 + level / 2)
        )
    tau2, tau2_lo, tau2_hi = (np.where(k > 1, t, np.nan) for t in (tau2, tau2_lo, tau2_hi))
    mu = np.where(k > 0, mu, np.nan)
    lo, hi = mu - tq * se, mu + tq * se
    return RandomEffects(mu, tau2, tau2_lo, tau2_hi, se, df, lo, hi, k, sample_var, mean_v)

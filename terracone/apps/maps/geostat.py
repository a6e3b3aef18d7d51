"""Variograms, ordinary kriging and leave-one-out cross-validation of located pushes (gstools).

The model of a quantity ``Z`` (log of a positive quantity, or n itself) at
push ``i`` is ``Z_i = S(x_i) + e_i``: a smooth field ``S`` with a stationary
covariance, plus the nugget ``e_i``, which absorbs the push-to-push variation
of the terrain and each push's estimation variance.  The map is the ordinary
kriging estimate of ``S`` with its kriging variance.

* **Variogram**: a :class:`gstools.Stable` model (exponential to Gaussian,
  ``alpha`` in (0, 2]) plus a nugget.  gstools estimates the empirical
  semivariogram (:func:`gstools.vario_estimate`, Matheron estimator, its
  standard bins) and fits the model to it
  (:meth:`gstools.CovModel.fit_variogram`, bins weighted by their pairs);
  that fit starts the restricted maximum likelihood fit of the same model to
  the pushes themselves (:func:`fit_reml`), which is kept.
* **Spatial structure**: a permutation test of the semivariogram at the
  shortest lags: the mean of (Z_i - Z_j)^2 / 2 over each push's 5 nearest
  neighbours, divided by the variance, against 199 random permutations of the
  values over the same places (seed 0).  Under no structure it is as likely
  as any permutation's; at p >= 0.05, or a fitted model with no partial sill,
  the variogram is a pure nugget: the field has no spatial structure that the
  pushes show, and every cell gets the field's pooled estimate (the mean with
  its t interval).
* **Kriging**: :class:`gstools.krige.Ordinary` with ``exact=False`` and the
  nugget as the measurement error of every push.  gstools' kriging variance
  is that of a new push (it contains the nugget); a cell's interval is that
  of the smooth field, the kriging variance less the nugget.  Up to
  :data:`GLOBAL_PUSHES` pushes every push conditions every cell; above, each
  block of cells is kriged from the :data:`NEIGHBOURS` pushes nearest to its
  centre (local neighbourhoods: gstools' kriging variance costs cells x
  pushes^2, 300 s for 1,000 pushes on 36,864 cells against 1.2 s local;
  benchmarks/map.py).
* **Cross-validation**: leave-one-out with the fitted variogram held fixed,
  by the closed form of Dubrule (1983) on the kriging system gstools solves
  (exactly gstools' kriging of each push from the others; checked against it
  in the tests): the error of each push's prediction from the others and its
  kriging variance, which includes the nugget since a push is predicted.
  Above :data:`LOO_GLOBAL_PUSHES` pushes, from each push's
  :data:`LOO_NEIGHBOURS` nearest pushes.

References
----------
.. [1] Dubrule, O. (1983). Cross validation of kriging in a unique
   neighborhood. Mathematical Geology 15, 687-699.
.. [2] Mueller, S., Schueler, L., Zech, A., Hesse, F. (2022). GSTools v1.3: a
   toolbox for geostatistical modelling in Python. Geosci. Model Dev. 15, 3161-3182.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import stats
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist
from threadpoolctl import threadpool_limits

from terracone.result import finite_or_none

__all__ = [
    "GLOBAL_PUSHES",
    "LOO_GLOBAL_PUSHES",
    "NEIGHBOURS",
    "CrossValidation",
    "Variogram",
    "fit_reml",
    "fit_variogram",
    "krige",
    "kriging_weights",
    "leave_one_out",
    "neighbourhoods",
    "pooled",
    "restricted_nll",
    "structure_test",
    "variogram_from_dict",
]

#: Up to this many pushes, every push conditions every cell (one global kriging system).
GLOBAL_PUSHES = 250
#: Above it, each block of cells is kriged from this many nearest pushes.
NEIGHBOURS = 250
#: Pushes per block of cells in local kriging (about).
BLOCK_PUSHES = 25
#: Neighbours of each push in local leave-one-out.
LOO_NEIGHBOURS = 64
#: Up to this many pushes, leave-one-out uses every push (one inverse of the kriging matrix).
LOO_GLOBAL_PUSHES = 1000
#: The permutation test's level, neighbours and permutations.
STRUCTURE_ALPHA = 0.05
STRUCTURE_NEIGHBOURS = 5
PERMUTATIONS = 199
#: Pushes the empirical variogram uses at most (gstools' sampling_size above it).
VARIOGRAM_SAMPLE = 2000
#: Pushes the likelihood fit uses at most (a random subset above it).
REML_PUSHES = 600
#: Bounds of the nugget's share of the sill in the likelihood fit (the lower one keeps the
#: kriging systems of smooth fields well conditioned; the upper one is a pure nugget).
REML_NUGGET = (1e-4, 0.999)
#: Largest shape of the Stable model (2: Gaussian).
MAX_ALPHA = 2.0


@dataclass
class Variogram:
    """A fitted variogram, or a pure nugget.

    Attributes
    ----------
    model : gstools.CovModel or None
        The fitted Stable model with its nugget; None for a pure nugget.
    structure : bool
        Whether the pushes show spatial structure (permutation test and a
        positive partial sill).
    p_value : float
        The permutation test's p-value.
    nugget, partial_sill : float
        In the kriged space (log or linear) [-]; a pure nugget has the
        pushes' variance as nugget and 0 partial sill.
    len_scale, alpha, range : float
        Stable model's length scale [m], shape, and the practical range
        [m], where the variogram reaches 95% of the sill (NaN for a pure nugget).
    r2 : float
        Coefficient of determination of the fit to the binned variogram.
    lags, gamma, counts : ndarray
        The empirical variogram: bin centres [m], semivariance, pairs.
    """

    model: Any
    structure: bool
    p_value: float
    nugget: float
    partial_sill: float
    len_scale: float
    alpha: float
    range: float
    r2: float
    lags: np.ndarray
    gamma: np.ndarray
    counts: np.ndarray

    def as_dict(self) -> dict[str, Any]:
        """The variogram as ``map.json`` records it (lengths in metres of the CRS)."""
        return {
            "model": "Stable" if self.structure else "pure nugget",
            "structure": self.structure,
            "nugget": finite_or_none(self.nugget),
            "partial_sill": finite_or_none(self.partial_sill),
            "sill": finite_or_none(self.nugget + self.partial_sill),
            "len_scale": finite_or_none(self.len_scale),
            "alpha": finite_or_none(self.alpha),
            "range": finite_or_none(self.range),
            "r2": finite_or_none(self.r2),
            "structure_test": {
                "p_value": finite_or_none(self.p_value),
                "method": f"permutation test ({PERMUTATIONS} permutations, seed 0) of the mean "
                f"semivariance over each push's {STRUCTURE_NEIGHBOURS} nearest neighbours",
                "level": STRUCTURE_ALPHA,
            },
            "empirical": {
                "lag": [float(v) for v in self.lags],
                "gamma": [float(v) for v in self.gamma],
                "pairs": [int(v) for v in self.counts],
            },
        }


def variogram_from_dict(d: dict[str, Any]) -> Variogram:
    """The :class:`Variogram` that :meth:`Variogram.as_dict` recorded (``map.json``).

    The model is rebuilt from its nugget, partial sill, length scale and
    shape (JSON keeps floats exactly), so kriging with it repeats the map's.
    """
    import gstools as gs

    def num(key: str) -> float:
        v = d.get(key)
        return math.nan if v is None else float(v)

    emp = d.get("empirical") or {}
    lags, gamma, counts = (
        np.asarray(emp.get(k, []), dtype=float) for k in ("lag", "gamma", "pairs")
    )
    p_value = float((d.get("structure_test") or {}).get("p_value") or math.nan)
    if not d.get("structure"):
        return Variogram(
            None, False, p_value, num("nugget"), 0.0, *(math.nan,) * 4, lags, gamma, counts
        )
    model = gs.Stable(
        dim=2, var=num("partial_sill"), len_scale=num("len_scale"), alpha=num("alpha"),
        nugget=num("nugget"),
    )  # fmt: skip
    return Variogram(
        model, True, p_value, num("nugget"), num("partial_sill"), num("len_scale"), num("alpha"),
        num("range"), num("r2"), lags, gamma, counts,
    )  # fmt: skip


@dataclass
class CrossValidation:
    """Leave-one-out cross-validation of a quantity's map.

    Attributes
    ----------
    prediction, variance : ndarray
        Each push's prediction from the others and its variance (a push's,
        nugget included), in the kriged space.
    observed : ndarray
        Each push's value in the kriged space.
    quantile : float
        The 95% quantile of the predictive distribution (normal, or t for a
        pure nugget).
    """

    prediction: np.ndarray
    variance: np.ndarray
    observed: np.ndarray
    quantile: float

    @property
    def standardised(self) -> np.ndarray:
        return (self.observed - self.prediction) / np.sqrt(self.variance)

    def summary(self, log: bool) -> dict[str, Any]:
        """``rmse`` (in the quantity's SI unit), ``mean_standardised_error``, ``coverage_90``, ``n``.

        For a quantity kriged in log space ``rmse`` compares each push with the
        median of its prediction, and ``rmse_log`` is the error of the logs.
        """
        e = self.observed - self.prediction
        t = self.standardised
        if log:
            rmse = float(np.sqrt(np.mean((np.exp(self.observed) - np.exp(self.prediction)) ** 2)))
        else:
            rmse = float(np.sqrt(np.mean(e**2)))
        out = {
            "rmse": rmse,
            "mean_standardised_error": float(np.mean(t)),
            "rms_standardised_error": float(np.sqrt(np.mean(t**2))),
            "coverage_90": float(np.mean(np.abs(t) <= self.quantile)),
            "n": int(e.size),
        }
        if log:
            out["rmse_log"] = float(np.sqrt(np.mean(e**2)))
        return out

    def point_summary(self) -> dict[str, Any]:
        """The point band's leave-one-out check: ``coverage_90``, ``below``, ``above``, ``n``.

        A push is a value at a point, so each push against the 90% band of
        the value at its place from the others (the band includes the
        nugget) checks the map's point band: ``coverage_90`` is the share
        inside it, ``below`` and ``above`` the shares under its 5% and over
        its 95% bound (each about 0.05 when the band is right and symmetric).
        """
        t = self.standardised
        return {
            "coverage_90": float(np.mean(np.abs(t) <= self.quantile)),
            "below": float(np.mean(t < -self.quantile)),
            "above": float(np.mean(t > self.quantile)),
            "n": int(t.size),
        }


def _xy(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.column_stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)])


def structure_test(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, *, seed: int = 0
) -> tuple[float, float]:
    """(p-value, statistic) of the permutation test for spatial structure.

    The statistic is the mean semivariance over each push's
    :data:`STRUCTURE_NEIGHBOURS` nearest neighbours divided by the variance
    of ``z`` (about 1 without structure, below 1 with it); the p-value is the
    share of :data:`PERMUTATIONS` permutations of ``z`` over the same places
    at or below it (counting the data's own order).
    """
    n = z.size
    k = min(STRUCTURE_NEIGHBOURS, n - 1)
    _, nb = cKDTree(_xy(x, y)).query(_xy(x, y), k=k + 1)
    i = np.repeat(np.arange(n), k)
    j = nb[:, 1:].ravel()
    var = float(np.var(z))
    if var <= 0:
        return 1.0, 1.0

    def stat(v: np.ndarray) -> float:
        return float(np.mean((v[i] - v[j]) ** 2) / 2.0 / var)

    t0 = stat(z)
    rng = np.random.default_rng(seed)
    perm = np.array([stat(rng.permutation(z)) for _ in range(PERMUTATIONS)])
    return float((1 + np.sum(perm <= t0)) / (PERMUTATIONS + 1)), t0


def _empirical(x: np.ndarray, y: np.ndarray, z: np.ndarray, seed: int):
    import gstools as gs

    sample = None if z.size <= VARIOGRAM_SAMPLE else VARIOGRAM_SAMPLE
    lags, gamma, counts = gs.vario_estimate(
        (x, y), z, return_counts=True, sampling_size=sample, sampling_seed=seed
    )
    keep = counts > 0
    return lags[keep], gamma[keep], counts[keep]


def _wls_start(lags, gamma, counts, diam: float) -> tuple[float, float, float] | None:
    """(log len_scale, nugget fraction, alpha) of gstools' weighted least-squares fit, or None."""
    import gstools as gs

    model = gs.Stable(dim=2)
    model.len_scale_bounds = [1e-3 * diam, 10.0 * diam]
    try:
        model.fit_variogram(lags, gamma, nugget=True, weights=counts)
    except (RuntimeError, ValueError):  # scipy's curve_fit found no fit
        return None
    sill = model.var + model.nugget
    if not sill > 0:
        return None
    f = min(max(model.nugget / sill, REML_NUGGET[0]), REML_NUGGET[1])
    return math.log(model.len_scale), f, min(max(model.alpha, 0.1), MAX_ALPHA)


def restricted_nll(theta: Sequence[float], d: np.ndarray, z: np.ndarray) -> float:
    """Negative restricted log-likelihood of ``z`` (constants dropped), the scale profiled out.

    ``theta = (log len_scale, nugget fraction f, alpha)``: the correlation of
    two pushes at distance d is ``(1 - f) exp(-(d / len_scale)^alpha)`` (the
    gstools Stable model) and ``f`` at d = 0; the mean is unknown (ordinary
    kriging's model), so the likelihood is that of the contrasts (REML).
    """
    n = z.size
    r = (1.0 - theta[1]) * np.exp(-((d / math.exp(theta[0])) ** theta[2]))
    r[np.diag_indices(n)] = 1.0
    try:
        c = cho_factor(r, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return 1e300
    one = np.ones(n)
    ri1 = cho_solve(c, one, check_finite=False)
    s11 = float(one @ ri1)
    e = z - float(ri1 @ z) / s11
    q = float(e @ cho_solve(c, e, check_finite=False))
    if not (q > 0 and s11 > 0):
        return 1e300
    logdet = 2.0 * float(np.sum(np.log(np.diag(c[0]))))
    return 0.5 * ((n - 1) * math.log(q / (n - 1)) + logdet + math.log(s11))


def fit_reml(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, start: Sequence[float] | None = None
) -> Any:
    """The gstools Stable model (with nugget) of largest restricted likelihood for ``z``.

    Started from ``start`` (gstools' binned fit) and from a generic point;
    bounds: len_scale from 0.001 to 10 times the field's diameter, the nugget
    fraction in :data:`REML_NUGGET`, alpha in [0.1, :data:`MAX_ALPHA`].
    """
    import gstools as gs

    pts = _xy(x, y)
    d = cdist(pts, pts)
    diam = float(d.max())
    bounds = [(math.log(1e-3 * diam), math.log(10.0 * diam)), REML_NUGGET, (0.1, MAX_ALPHA)]
    starts = [(math.log(diam / 5.0), 0.3, 1.0)] + ([tuple(start)] if start is not None else [])
    best = None
    for t0 in starts:
        res = minimize(restricted_nll, t0, args=(d, z), method="L-BFGS-B", bounds=bounds)
        if best is None or res.fun < best.fun:
            best = res
    ls, f, alpha = math.exp(best.x[0]), float(best.x[1]), float(best.x[2])
    n = z.size
    r = (1.0 - f) * np.exp(-((d / ls) ** alpha))
    r[np.diag_indices(n)] = 1.0
    c = cho_factor(r, lower=True)
    ri1 = cho_solve(c, np.ones(n))
    e = z - float(ri1 @ z) / float(ri1.sum())
    s2 = float(e @ cho_solve(c, e)) / (n - 1)
    return gs.Stable(dim=2, var=s2 * (1 - f), len_scale=ls, alpha=alpha, nugget=s2 * f)


def fit_variogram(x: np.ndarray, y: np.ndarray, z: np.ndarray, *, seed: int = 0) -> Variogram:
    """Fit the variogram of ``z`` at the places (x, y) [m], or find a pure nugget.

    gstools fits the Stable model to the empirical variogram (weighted least
    squares); that fit starts the restricted maximum likelihood fit of the
    same model to the pushes themselves (:func:`fit_reml`, on
    :data:`REML_PUSHES` pushes drawn with ``seed`` when there are more).  The
    binned fit alone leaves the nugget to the few pairs of the first bins:
    on generated fields it under-estimated it and the leave-one-out 90%
    intervals covered 82-88% on average (some fields 30%); the likelihood
    uses every pair.  See the module's description for the test of spatial
    structure.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    emp = _empirical(x, y, z, seed)
    p_value, _ = structure_test(x, y, z, seed=seed)
    var = float(np.var(z, ddof=1))
    pure = Variogram(None, False, p_value, var, 0.0, *(math.nan,) * 4, *emp)
    if p_value >= STRUCTURE_ALPHA or emp[0].size < 3 or not var > 0:
        return pure
    diam = float(np.hypot(np.ptp(x), np.ptp(y)))
    sub = np.arange(z.size)
    if z.size > REML_PUSHES:
        sub = np.sort(np.random.default_rng(seed).choice(z.size, REML_PUSHES, replace=False))
    with threadpool_limits(1, user_api="blas"):  # small systems: threads only contend
        model = fit_reml(x[sub], y[sub], z[sub], _wls_start(*emp, diam))
    if not model.var > 1e-6 * (model.var + model.nugget) or model.nugget >= REML_NUGGET[1] * (
        model.var + model.nugget
    ):
        return pure
    lags, gamma, counts = emp
    fitted = model.variogram(lags)
    mean = np.average(gamma, weights=counts)
    r2 = 1.0 - np.sum(counts * (gamma - fitted) ** 2) / np.sum(counts * (gamma - mean) ** 2)
    return Variogram(
        model, True, p_value, float(model.nugget), float(model.var), float(model.len_scale),
        float(model.alpha), float(model.percentile_scale(0.95)), float(r2), *emp,
    )  # fmt: skip


def _krige_all(model: Any, px, py, z, gx, gy) -> tuple[np.ndarray, np.ndarray]:
    import gstools as gs

    k = gs.krige.Ordinary(model, (px, py), z, exact=False, cond_err="nugget")
    m, v = k((gx, gy), mesh_type="unstructured", chunk_size=20000, store=False)
    return np.asarray(m, dtype=float), np.asarray(v, dtype=float)


def _blocks(px, py, gx, gy) -> Iterable[np.ndarray]:
    """Indices of the cells of each block of about :data:`BLOCK_PUSHES` pushes' area."""
    area = max(float(np.ptp(px) * np.ptp(py)), 1e-12)
    side = math.sqrt(area / px.size * BLOCK_PUSHES)
    bx = np.floor((gx - gx.min()) / side).astype(np.int64)
    by = np.floor((gy - gy.min()) / side).astype(np.int64)
    key = bx * (int(by.max()) + 1) + by
    order = np.argsort(key, kind="stable")
    cuts = np.flatnonzero(np.diff(key[order])) + 1
    return np.split(order, cuts)


def neighbourhoods(
    px: np.ndarray,
    py: np.ndarray,
    gx: np.ndarray,
    gy: np.ndarray,
    *,
    neighbourhood: str = "auto",
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The cells and the pushes that condition them: (cells, pushes) index arrays per block.

    "global": one block of every cell and every push; "local": each block of
    about :data:`BLOCK_PUSHES` pushes' area with the :data:`NEIGHBOURS`
    pushes nearest to its centre; "auto": global up to :data:`GLOBAL_PUSHES`
    pushes.  :func:`krige` and the conditional simulations
    (:mod:`terracone.apps.maps.simulation`) use the same blocks, so a
    simulation's mean is the map's median.
    """
    if neighbourhood not in ("auto", "global", "local"):
        raise ValueError(f"neighbourhood must be auto, global or local (got {neighbourhood!r})")
    if neighbourhood == "global" or (neighbourhood == "auto" and px.size <= GLOBAL_PUSHES):
        yield np.arange(gx.size), np.arange(px.size)
        return
    tree = cKDTree(_xy(px, py))
    for cells in _blocks(px, py, gx, gy):
        _, nb = tree.query([gx[cells].mean(), gy[cells].mean()], k=min(NEIGHBOURS, px.size))
        yield cells, np.atleast_1d(nb)


def krige(
    vg: Variogram,
    px: np.ndarray,
    py: np.ndarray,
    z: np.ndarray,
    gx: np.ndarray,
    gy: np.ndarray,
    *,
    neighbourhood: str = "auto",
    progress: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Ordinary kriging of the smooth field at (gx, gy): estimate and its variance.

    Parameters
    ----------
    vg : Variogram
        With spatial structure (a pure nugget is :func:`pooled`).
    px, py, z : ndarray
        The pushes' places [m] and values (kriged space).
    gx, gy : ndarray
        The places to estimate [m].
    neighbourhood : {"auto", "global", "local"}
        Every push for every cell, or the :data:`NEIGHBOURS` nearest pushes
        of each block of cells; "auto": global up to :data:`GLOBAL_PUSHES`
        pushes (:func:`neighbourhoods`).
    progress : callable, optional
        ``progress(k)`` after each block of ``k`` cells.

    Returns
    -------
    (estimate, variance) : ndarray
        The variance is that of the smooth field (gstools' kriging variance
        less the nugget, at least 0).
    """
    m, v = np.empty(gx.size), np.empty(gx.size)
    # small systems: BLAS threads only contend (16x slower seen on a busy machine); the limit
    # is set once, not per block (entering it reads the process's libraries, ~15 ms)
    one = neighbourhood == "global" or (neighbourhood == "auto" and px.size <= GLOBAL_PUSHES)
    small = not one or px.size <= NEIGHBOURS  # local blocks hold at most NEIGHBOURS pushes
    with threadpool_limits(1 if small else None, user_api="blas"):
        for cells, nb in neighbourhoods(px, py, gx, gy, neighbourhood=neighbourhood):
            m[cells], v[cells] = _krige_all(vg.model, px[nb], py[nb], z[nb], gx[cells], gy[cells])
            if progress:
                progress(cells.size)
    return m, np.maximum(v - vg.nugget, 0.0)


def kriging_weights(
    model: Any, px: np.ndarray, py: np.ndarray, gx: np.ndarray, gy: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Ordinary kriging weights of the pushes for the smooth field at (gx, gy), and its variance.

    The system gstools solves in :func:`krige` (``Ordinary``, ``exact=False``,
    the nugget as every push's measurement error), solved here for the
    weights themselves: ``[K, 1; 1', 0] [w; mu] = [c0; 1]`` with K = C +
    nugget I, C the covariance of the smooth field between the pushes and c0
    that between the pushes and each place.  K is factorised once (Cholesky)
    and the unbiasedness condition eliminated: ``mu = (1' K^-1 c0 - 1) /
    (1' K^-1 1)``, ``w = K^-1 (c0 - mu 1)`` (twice as fast as the bordered
    system); the smooth field's kriging variance is ``C(0) - w' c0 - mu``.
    The estimate at the places is ``w' z``.  Small systems run fastest on one
    BLAS thread: call it under ``threadpoolctl.threadpool_limits(1)`` (once:
    entering it costs ~15 ms).

    Returns
    -------
    (weights, variance) : ndarray
        Weights (pushes, places) and the variance of each place (at least 0).
    """
    k = px.size
    kk = model.covariance(np.hypot(px[:, None] - px[None, :], py[:, None] - py[None, :]))
    kk[np.diag_indices(k)] += model.nugget
    rhs = np.empty((k, gx.size + 1))
    rhs[:, :-1] = model.covariance(np.hypot(px[:, None] - gx[None, :], py[:, None] - gy[None, :]))
    rhs[:, -1] = 1.0
    try:
        y = cho_solve(cho_factor(kk, lower=True, check_finite=False), rhs, check_finite=False)
    except np.linalg.LinAlgError:
        y = np.linalg.pinv(kk, hermitian=True) @ rhs
    k1 = y[:, -1]
    mu = (rhs[:, :-1].T @ k1 - 1.0) / k1.sum()
    w = y[:, :-1] - np.outer(k1, mu)
    v = model.var - np.einsum("ij,ij->j", w, rhs[:, :-1]) - mu
    return w, np.maximum(v, 0.0)


def _augmented(model: Any, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """The ordinary kriging matrices of gstools for stacks of places (..., m) -> (..., m+1, m+1).

    Covariance without the nugget off the diagonal, the sill on it (the
    nugget as every push's measurement error), and the unbiasedness border.
    """
    d = np.hypot(px[..., :, None] - px[..., None, :], py[..., :, None] - py[..., None, :])
    m = px.shape[-1]
    a = np.zeros(px.shape[:-1] + (m + 1, m + 1))
    a[..., :m, :m] = model.covariance(d)
    idx = np.arange(m)
    a[..., idx, idx] += model.nugget
    a[..., :m, m] = 1.0
    a[..., m, :m] = 1.0
    return a


def _inverse(a: np.ndarray) -> np.ndarray:
    """Inverse of (stacks of) kriging matrices; the pseudo-inverse where one is singular."""
    with threadpool_limits(1, user_api="blas"):
        try:
            return np.linalg.inv(a)
        except np.linalg.LinAlgError:
            return np.linalg.pinv(a, hermitian=True)


def leave_one_out(
    vg: Variogram,
    px: np.ndarray,
    py: np.ndarray,
    z: np.ndarray,
    *,
    subset: np.ndarray | None = None,
) -> CrossValidation:
    """Leave-one-out predictions of every push from the others, with the variogram held fixed.

    Kriging (Dubrule's closed form): with ``B`` the inverse of the kriging
    matrix, the error of push i's prediction from the others is
    ``(B [z, 0])_i / B_ii`` and its variance ``1 / B_ii``.  Above
    :data:`LOO_GLOBAL_PUSHES` pushes, each push is predicted from its
    :data:`LOO_NEIGHBOURS` nearest pushes.  A pure nugget predicts each push
    by the mean of the others, with the t predictive interval.
    """
    n = z.size
    rows = np.arange(n) if subset is None else np.asarray(subset)
    if not vg.structure:
        s = (z.sum() - z) / (n - 1)
        ss = ((z**2).sum() - z**2 - (n - 1) * s**2) / (n - 2)
        q = float(stats.t.ppf(0.95, n - 2))
        return CrossValidation(s[rows], ss[rows] * (1 + 1 / (n - 1)), z[rows], q)
    q = float(stats.norm.ppf(0.95))
    if n <= LOO_GLOBAL_PUSHES:
        b = _inverse(_augmented(vg.model, px, py))
        d = np.diag(b)[:n]
        err = (b[:n, :n] @ z) / d
        return CrossValidation((z - err)[rows], 1.0 / d[rows], z[rows], q)
    k = min(LOO_NEIGHBOURS, n - 1)
    pts = _xy(px, py)
    _, nb = cKDTree(pts).query(pts[rows], k=min(k + 2, n))  # the push itself and k others
    me = rows[:, None]
    others = np.take_along_axis(nb, np.argsort(nb == me, axis=1, kind="stable"), axis=1)
    nb = np.column_stack([me, others[:, :k]])  # the push first, then its k nearest others
    pred, var = np.empty(rows.size), np.empty(rows.size)
    for part in np.array_split(np.arange(rows.size), max(1, rows.size // 500)):
        idx = nb[part]
        b = _inverse(_augmented(vg.model, px[idx], py[idx]))
        err = np.einsum("ij,ij->i", b[:, 0, : k + 1], z[idx]) / b[:, 0, 0]
        pred[part], var[part] = z[rows[part]] - err, 1.0 / b[:, 0, 0]
    return CrossValidation(pred, var, z[rows], q)


def pooled(z: np.ndarray, level: float = 0.9) -> tuple[float, float, float, float, float]:
    """The field's pooled estimate of a pure nugget (kriged space): the mean, its t interval,
    and the t prediction interval of the value at a new point.

    Returns (mean, lo, hi, point_lo, point_hi): mean +- t s / sqrt(n) and
    mean +- t s sqrt(1 + 1/n), t the (1 + level)/2 quantile of Student's t
    with n - 1 degrees of freedom and s the pushes' standard deviation.
    """
    n = z.size
    m = float(np.mean(z))
    s = float(np.std(z, ddof=1))
    q = float(stats.t.ppf(0.5 + level / 2, n - 1))
    se, sp = s / math.sqrt(n), s * math.sqrt(1.0 + 1.0 / n)
    return m, m - q * se, m + q * se, m - q * sp, m + q * sp

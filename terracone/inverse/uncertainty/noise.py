"""The CI error model of the posterior: noise weights and AR(1) correlation along depth.

The CI error at depth z_i is Gaussian with standard deviation ``sigma w_i``:
relative weights ``w_i ~ sqrt(m_i^2 + (floor max m)^2)`` of the best-fit
model CI (``noise_model="relative"``, plug-in, normalised to an RMS of 1) or
``w_i = 1`` (``"absolute"``); readings Delta apart correlate with
``rho**(Delta / dz0)`` (AR(1) at the median spacing, exact for irregular
spacing, whitened in O(N)), rho estimated from the residuals
(:func:`estimate_correlation`) or sampled; sigma is marginalised under
p(sigma) ~ 1/sigma.  ``docs/uncertainty.md`` (The noise model) gives the
details and their checks.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 2 and 3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.physics.cone import Cone, cone_index_basis
from terracone.physics.plate import PressureLaw
from terracone.resultunits import from_si, output, quantity

__all__ = [
    "POSTERIOR_MAX_POINTS",
    "RHO_MAX",
    "NoiseModel",
    "NoiseSetup",
    "ar1_coefficients",
    "ar1_noise",
    "bin_readings",
    "estimate_correlation",
    "noise_setup",
    "whiten_ar1",
]

#: Largest AR(1) coefficient used.
RHO_MAX = 0.95

#: Most readings the posterior samples with.  Its likelihood tabulates every reading's basis
#: columns over n (about 9 kB a reading) and each of its ~22,000 evaluations visits every
#: reading, so a longer profile is sampled on bins of consecutive readings
#: (:func:`bin_readings`), with a note: memory stays under about 250 MB whatever the length.
POSTERIOR_MAX_POINTS = 5000


@dataclass
class NoiseModel:
    """The CI error model used (see the module docstring).

    Attributes
    ----------
    kind : {"relative", "absolute"}
    sigma : float
        RMS noise standard deviation over the profile [kPa]: the given value,
        or the posterior median when estimated.
    sigma_interval : (float, float) or None
        90% interval of sigma [kPa] when estimated.
    sigma_rel : float or None
        With relative noise, sigma relative to the model CI where the floor
        does not matter [-].
    rho : float
        AR(1) coefficient at the reference spacing [-] (the posterior median
        when sampled).
    spacing : float
        Reference (median) spacing dz0 [m].
    floor : float
        Additive floor of the relative model, as a fraction of the largest
        model CI [-].
    sigma_estimated, rho_estimated : bool
    rho_raw : float or None
        Lag-1 autocorrelation of the best-fit residuals before the
        small-sample correction [-].
    weights : ndarray
        w_i, RMS 1 [-].
    rho_interval : (float, float) or None
        90% interval of rho when sampled.
    rho_sampled : bool
        Whether rho was a sampled parameter (``correlation="sample"``).
    """

    kind: str = quantity(key="model")
    sigma: float = quantity("pressure")
    sigma_interval: tuple[float, float] | None = quantity("pressure")
    sigma_rel: float | None
    rho: float
    spacing: float = quantity("length")
    floor: float
    sigma_estimated: bool
    rho_estimated: bool
    rho_raw: float | None = None
    weights: np.ndarray | None = None
    rho_interval: tuple[float, float] | None = None
    rho_sampled: bool = False

    @property
    def correlation_length(self) -> float:
        """Depth over which the correlation falls by 1/e, -dz0 / ln(rho) [m] (0 if rho = 0)."""
        if self.rho <= 0:
            return 0.0
        return -self.spacing / math.log(self.rho)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``noise`` of a posterior in a document (sigma in kPa or psi, lengths in m or in)."""
        d = output(self, units, fields=_WRITTEN)
        d["correlation_length"] = from_si(self.correlation_length, "length", units)
        d["floor"] = self.floor
        return d


#: The fields of a noise model written before its correlation length, in order.
_WRITTEN = (
    "kind", "sigma", "sigma_interval", "sigma_rel", "sigma_estimated", "rho", "rho_estimated",
    "rho_sampled", "rho_interval", "rho_raw", "spacing",
)  # fmt: skip


def ar1_coefficients(depth: ArrayLike, rho: float, spacing: float | None = None) -> np.ndarray:
    """Lag-1 coefficients phi_i = rho**(Delta_i / dz0) between neighbouring readings.

    Parameters
    ----------
    depth : array_like
        Increasing depths [m].
    rho : float
        Correlation at the reference spacing [-], 0 <= rho < 1.
    spacing : float, optional
        Reference spacing dz0 [m]; the median spacing by default.

    Returns
    -------
    ndarray, shape (N - 1,)
    """
    z = np.asarray(depth, dtype=float)
    dz = np.diff(z)
    if dz.size == 0:
        return dz
    dz0 = float(np.median(dz)) if spacing is None else float(spacing)
    if not 0 <= rho < 1:
        raise ValueError(f"rho must satisfy 0 <= rho < 1 (got {rho})")
    if rho == 0:
        return np.zeros_like(dz)
    return rho ** (dz / dz0)


def ar1_noise(
    depth: ArrayLike,
    rho: float,
    rng: np.random.Generator,
    *,
    spacing: float | None = None,
    size: int | None = None,
) -> np.ndarray:
    """Standard-normal AR(1) noise along depth, the correlation model of the posterior.

    Parameters
    ----------
    depth : array_like
        Increasing depths [m].
    rho : float
        Correlation of neighbours at the reference spacing [-].
    rng : numpy.random.Generator
    spacing : float, optional
        Reference spacing [m]; the median spacing by default.
    size : int, optional
        Number of independent series (rows); one 1-D series when None.

    Returns
    -------
    ndarray
        Unit-variance series with corr(e_i, e_j) = rho**(|z_i - z_j| / dz0).
    """
    z = np.asarray(depth, dtype=float)
    phi = ar1_coefficients(z, rho, spacing)
    m = 1 if size is None else int(size)
    e = rng.standard_normal((m, z.size))  # white, made AR(1) in place along depth
    c = np.sqrt(1.0 - phi * phi)
    for i in range(1, z.size):
        e[:, i] = phi[i - 1] * e[:, i - 1] + c[i - 1] * e[:, i]
    return e[0] if size is None else e


def whiten_ar1(v: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Whiten AR(1) series along the last axis (the inverse of its Cholesky factor).

    ``u_1 = v_1``, ``u_i = (v_i - phi_i v_(i-1)) / sqrt(1 - phi_i^2)``: AR(1)
    noise of unit variance with lag-1 coefficients ``phi`` becomes white noise
    of unit variance.

    Parameters
    ----------
    v : ndarray, shape (..., N)
        Series along the last axis (residuals, or basis columns).
    phi : ndarray, shape (N - 1,)
        Lag-1 coefficients between neighbours (:func:`ar1_coefficients`) [-].

    Returns
    -------
    ndarray, shape (..., N)
        A new array (also when ``phi`` is all zero).
    """
    if not np.any(phi):
        return np.array(v, dtype=float, copy=True)
    out = np.empty(np.shape(v))
    out[..., 0] = v[..., 0]
    out[..., 1:] = (v[..., 1:] - phi * v[..., :-1]) / np.sqrt(1.0 - phi * phi)
    return out


def bin_readings(depth: ArrayLike, ci: ArrayLike, most: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Readings on at most ``most`` depths: means over bins of k consecutive readings.

    Parameters
    ----------
    depth, ci : array_like
        Increasing depths [m] and CI [kPa] of one profile.
    most : int
        Most bins.

    Returns
    -------
    depth, ci : ndarray
        The bins' mean depths and CI (the readings themselves when there are
        at most ``most``).
    k : int
        Readings per bin, ceil(N / most) (the last bin may hold fewer); 1
        when not binned.
    """
    z = np.asarray(depth, dtype=float)
    y = np.asarray(ci, dtype=float)
    N = z.size
    if N <= most:
        return z, y, 1
    k = -(-N // int(most))
    starts = np.arange(0, N, k)
    count = np.diff(np.append(starts, N)).astype(float)
    return np.add.reduceat(z, starts) / count, np.add.reduceat(y, starts) / count, k


def estimate_correlation(
    residuals: ArrayLike,
    depth: ArrayLike,
    *,
    design: np.ndarray | None = None,
) -> tuple[float, float]:
    """AR(1) coefficient of the CI error from best-fit (weighted) residuals.

    The lag-1 autocorrelation r1 of the residuals, corrected for what the fit
    absorbs: ``rho = f^-1(r1)``, ``f(rho) = tr(D M S(rho) M) / tr(M S(rho) M)``
    with ``M`` the residual maker of the columns of ``design`` and a constant
    (docs/uncertainty.md, The noise model), clipped to [0, 0.95].  Without
    ``design`` the fallback ``r1 + (1 + 11 r1+) / N`` (small-sample bias plus
    absorption of 4 parameters, calibrated on 31-61 point profiles).

    Parameters
    ----------
    residuals : array_like
        Residuals divided by their noise weights, in depth order [-].
    depth : array_like
        Depths of the readings [m].
    design : ndarray, shape (N, p), optional
        Weighted Jacobian of the model at the fit with respect to the
        parameters that are free there (not at a bound).

    Returns
    -------
    rho, r1 : float
        The estimate at the median spacing dz0 and the raw lag-1
        autocorrelation.
    """
    e = np.asarray(residuals, dtype=float)
    z = np.asarray(depth, dtype=float)
    N = e.size
    if N < 6:
        return 0.0, float("nan")
    e = e - e.mean()
    den = float(e @ e)
    if den <= 0:
        return 0.0, float("nan")
    r1 = float(e[1:] @ e[:-1]) / den
    dz0 = float(np.median(np.diff(z)))
    if design is None or dz0 <= 0:
        rho = r1 + (1.0 + 11.0 * max(r1, 0.0)) / N  # (3 + 2 n_params) with 4 parameters
        return float(np.clip(rho, 0.0, RHO_MAX)), r1
    X = np.column_stack([np.ones(N), np.asarray(design, dtype=float).reshape(N, -1)])
    X = X / np.maximum(np.linalg.norm(X, axis=0), 1e-300)
    U, sv, _ = np.linalg.svd(X, full_matrices=False)
    Q = U[:, sv > 1e-8 * sv[0]]
    grid = np.linspace(0.0, RHO_MAX, 96)
    f = _absorbed_lag1(Q, np.diff(z) / dz0, grid)
    f = np.maximum.accumulate(f)  # monotone (it is, up to rounding)
    if r1 <= f[0]:
        return 0.0, r1
    if r1 >= f[-1]:
        return RHO_MAX, r1
    return float(np.interp(r1, f, grid)), r1


def _absorbed_lag1(Q: np.ndarray, lag: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """f(rho) = tr(D M S M) / tr(M S M) at each rho of ``grid``, in O(N q^2) memory and time.

    M = I - Q Q' (Q (N, q) orthonormal) is the residual maker, S(rho) the
    AR(1) correlation rho**(|z_i - z_j| / dz0) (``lag``: the N - 1 spacings
    over dz0) and tr(D A) the sum of A's first superdiagonal.  With W = S Q
    and T = Q' W: tr(M S M) = N - tr(T) (M idempotent, tr S = N) and
    tr(D M S M) = sum_i [S_(i,i+1) - (Q W')_(i,i+1) - (W Q')_(i,i+1) +
    (Q T Q')_(i,i+1)], S_(i,i+1) = phi_i.  S Q comes from the AR(1)
    recursions (S v = f + b - v, f_i = v_i + phi_(i-1) f_(i-1), b_i = v_i +
    phi_i b_(i+1)), all rho at once: no N x N matrix (those took 75 GiB at
    100,000 readings).
    """
    N, q = Q.shape
    out = np.empty(grid.size)
    step = max(1, min(grid.size, (1 << 20) // max(N * q, 1)))  # rho values at once: <= 8 MB
    for g0 in range(0, grid.size, step):
        out[g0 : g0 + step] = _absorbed_chunk(Q, lag, grid[g0 : g0 + step])
    return out


def _absorbed_chunk(Q: np.ndarray, lag: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """:func:`_absorbed_lag1` at the few rho values ``rho`` (G,): arrays (G, N, q)."""
    N, q = Q.shape
    G = rho.size
    phi = np.zeros((G, N - 1))
    pos = rho > 0
    phi[pos] = rho[pos, None] ** lag[None, :]
    fw = np.empty((G, N, q))
    bw = np.empty((G, N, q))
    fw[:, 0] = Q[0]
    for i in range(1, N):
        fw[:, i] = Q[i] + phi[:, i - 1, None] * fw[:, i - 1]
    bw[:, N - 1] = Q[N - 1]
    for i in range(N - 2, -1, -1):
        bw[:, i] = Q[i] + phi[:, i, None] * bw[:, i + 1]
    W = fw + bw - Q  # (G, N, q) = S Q
    del fw, bw
    T = np.einsum("nk,gnl->gkl", Q, W)  # Q' S Q
    den = N - np.einsum("gkk->g", T)
    QT = np.einsum("nk,gkl->gnl", Q, T)
    num = phi.sum(axis=1)
    num -= np.einsum("nk,gnk->g", Q[:-1], W[:, 1:])
    num -= np.einsum("gnk,nk->g", W[:, :-1], Q[1:])
    num += np.einsum("gnl,nl->g", QT[:, :-1], Q[1:])
    return num / den


def _fit_design(
    z: np.ndarray,
    p0: TerrainParameters,
    bounds: Bounds,
    ratio: float | None,
    law: PressureLaw,
    K_cone: float | None,
    cone: Cone,
) -> np.ndarray:
    """Jacobian (N, p) of the model CI at the best fit w.r.t. the parameters the fit moved.

    Linear parameters at a bound, and those a calibration pins, are left
    out; with a held ratio kc and kphi move together.
    """
    kw = dict(phic_deg=p0.phic_deg, K_cone=K_cone, law=law, cone=cone)
    A, B, C = (np.broadcast_to(c, z.shape) for c in cone_index_basis(z, n=p0.n, **kw))
    cols = []

    def inside(v, lo, hi):
        tol = 1e-9 * max(abs(lo), abs(hi), 1.0)
        return lo + tol < v < hi - tol

    kc_box, kphi_box = ([float(v) for v in f(p0.n)] for f in (bounds.kc_si, bounds.kphi_si))
    if ratio is not None:
        if inside(p0.kphi, *kphi_box):
            cols.append(ratio * A + B)
    else:
        if inside(p0.kc, *kc_box):
            cols.append(A)
        if inside(p0.kphi, *kphi_box):
            cols.append(B)
        if inside(p0.cc, *bounds.cc):
            cols.append(C)
    if inside(p0.n, *bounds.n):
        h = 1e-5
        mm = [
            p0.kc * a + p0.kphi * b + p0.cc * c
            for a, b, c in (cone_index_basis(z, n=p0.n + d, **kw) for d in (h, -h))
        ]
        cols.append((mm[0] - mm[1]) / (2 * h))
    return np.column_stack(cols) if cols else np.zeros((z.size, 0))


@dataclass
class NoiseSetup:
    """Weights and AR(1) coefficient of the CI error, from the best fit (:func:`noise_setup`).

    Attributes
    ----------
    w : ndarray
        Noise weights, RMS 1 [-]; ``w_rms`` the RMS of the raw weights [kPa].
    rho, rho_raw : float
        AR(1) coefficient used and the raw lag-1 autocorrelation [-].
    rho_est, rho_sampled : bool
    phi : ndarray
        Lag-1 coefficients between neighbouring readings [-].
    dz0 : float
        Median spacing [m].
    notes : list of str
    """

    w: np.ndarray
    w_rms: float
    rho: float
    rho_raw: float | None
    rho_est: bool
    rho_sampled: bool
    phi: np.ndarray
    dz0: float
    notes: list[str]


def noise_setup(
    profile: CIProfile,
    p0: TerrainParameters,
    law: PressureLaw,
    K_cone: float | None,
    bounds: Bounds,
    ratio: float | None,
    noise_model: str,
    noise_floor: float,
    correlation: str | float,
) -> NoiseSetup:
    """Plug-in noise weights and the AR(1) coefficient of the CI error (module docstring).

    Parameters
    ----------
    profile : CIProfile
    p0 : TerrainParameters
        The best fit: its model CI of eq. (2-7) sets the relative weights and
        its residuals the AR(1) estimate.
    law : PressureLaw
    K_cone : float or None
        [m]; None: fully mobilised shear.
    bounds : Bounds
        The fit's bounds: parameters at a bound (or pinned) are left out of its
        design (:func:`estimate_correlation`).
    ratio : float or None
        kc/kphi held by the fit [m]: kc and kphi move together.
    noise_model : {"relative", "absolute"}
    noise_floor : float
        [-]
    correlation : "estimate", "sample", "none" or float

    Returns
    -------
    NoiseSetup
        Of the profile's readings, or of their bins when there are more than
        :data:`POSTERIOR_MAX_POINTS` (:func:`bin_readings`, with a note).
    """
    z, y, k = bin_readings(profile.depth, profile.ci, POSTERIOR_MAX_POINTS)
    N = y.size
    notes = []
    if k > 1:
        notes.append(
            f"posterior from {N} depth bins of the {profile.depth.size} readings (means of {k} "
            f"consecutive readings; at most {POSTERIOR_MAX_POINTS} are sampled): sigma and rho "
            "are those of a bin's mean"
        )
    A, B, C = cone_index_basis(
        z, n=p0.n, phic_deg=p0.phic_deg, K_cone=K_cone, law=law, cone=profile.cone
    )
    m0 = p0.kc * A + p0.kphi * B + p0.cc * C  # eq. (2-7)
    w_raw = np.ones(N)
    if noise_model == "relative":
        scale_ci = float(np.max(np.abs(m0))) or float(np.max(np.abs(y))) or 1.0
        w_raw = np.sqrt(m0 * m0 + (noise_floor * scale_ci) ** 2)
        if not np.all(w_raw > 0):
            w_raw = np.ones(N)
            notes.append("relative noise weights degenerate (zero CI): constant weights used")
    w_rms = float(np.sqrt(np.mean(w_raw * w_raw)))
    w = w_raw / w_rms
    dz = np.diff(z)
    dz0 = float(np.median(dz)) if dz.size else 0.0
    rho_raw, rho_sampled = None, False
    rho_est = isinstance(correlation, str) and correlation in ("estimate", "sample")
    if rho_est:
        X = _fit_design(z, p0, bounds, ratio, law, K_cone, profile.cone) / w[:, None]
        rho, rho_raw = estimate_correlation((y - m0) / w, z, design=X)
        rho_sampled = correlation == "sample" and N > 2
    elif correlation == "none":
        rho = 0.0
    elif isinstance(correlation, str):
        raise ValueError(
            f"correlation must be 'estimate', 'sample', 'none' or a number (got {correlation!r})"
        )
    else:
        rho = float(correlation)
        if not 0 <= rho <= RHO_MAX:
            raise ValueError(f"correlation must lie in [0, {RHO_MAX}] (got {rho})")
    phi = ar1_coefficients(z, rho, dz0) if N > 1 else np.zeros(0)
    if rho_raw is not None and not math.isfinite(rho_raw):
        rho_raw = None
    return NoiseSetup(w, w_rms, float(rho), rho_raw, rho_est, rho_sampled, phi, dz0, notes)

"""Intervals and identifiability of fitted profile sets (prediction process).

What :func:`terracone.inverse.predict_many` reports beside each optimum:
the interval of n whose best fit stays within the chi-square threshold, the
profile intervals of kc, kphi and cc, and which parameters the data leave
free (the phic ridge of eq. (2-6), the kc, kphi, cc trade).  Vectorised over
the profiles of a set; the per-profile scans are
:func:`identify_scans` and :func:`identify_extents`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-5) to (2-7), section 3.3.2.
"""

from __future__ import annotations

import math

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.boxlsq import box_lsq3, gram
from terracone.inverse.solver.columns import bounds_arrays, design
from terracone.inverse.solver.kernels import box_grid, identify_extent, identify_scan
from terracone.inverse.solver.many import ManySolution, bounds_params, grid
from terracone.jit import enabled
from terracone.physics.cone import Cone
from terracone.physics.plate import PressureLaw

__all__ = [
    "CHI2_1_95",
    "n_interval",
    "n_intervals",
    "linear_intervals",
    "identification",
    "identify_scans",
    "identify_extents",
    "scan_extents",
]

CHI2_1_95 = 3.841458820694124  # 95% quantile of chi-square with 1 dof


def n_intervals(
    ms: ManySolution,
    sse: np.ndarray,
    yy: np.ndarray,
    mask: np.ndarray,
    bounds: Bounds,
    noise_floor: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """sigma [kPa], the threshold [kPa^2] and the approximate 95% profile interval of n.

    sigma is the residual standard deviation, floored at ``noise_floor``
    times the mean CI (no penetrometer reads better).  The n interval holds
    the grid values of n whose best fit (over phic and the linear
    parameters) raises the sum of squares by less than 3.84 sigma^2, widened
    by one grid step and always holding the optimum (one value per profile).
    """
    npts = mask.sum(axis=1)
    mean_abs = np.where(mask, np.abs(yy), 0.0).sum(axis=1) / npts
    sigma2 = np.maximum(sse / np.maximum(npts - 5, 1), (noise_floor * mean_abs) ** 2)
    thr = sse + CHI2_1_95 * sigma2
    return np.sqrt(sigma2), thr, *n_interval(ms.n_grid, ms.sse_n, thr, ms.n, bounds)


def n_interval(
    ns: np.ndarray, sse_n: np.ndarray, thr: np.ndarray, n: np.ndarray | float, bounds: Bounds
) -> tuple[np.ndarray, np.ndarray]:
    """The n interval of :func:`n_intervals` from the best SSE ``sse_n`` (P, Nn) at ``ns``."""
    ok = sse_n <= thr[:, None]
    has = ok.any(axis=1)
    small = np.where(ok, ns[None, :], np.inf).min(axis=1)
    big = np.where(ok, ns[None, :], -np.inf).max(axis=1)
    step = (ns[1] - ns[0]) if ns.size > 1 else 0.0
    n_lo = np.where(has, np.maximum(bounds.n[0], np.minimum(small - step, n)), n)
    n_hi = np.where(has, np.minimum(bounds.n[1], np.maximum(big + step, n)), n)
    return n_lo, n_hi


def linear_intervals(
    z: np.ndarray,
    y: np.ndarray,
    x: np.ndarray,
    n: float,
    phic_deg: float,
    thr: float,
    n_range: tuple[float, float],
    *,
    bounds: Bounds,
    law: PressureLaw,
    cone: Cone,
    ratio: float | None = None,
    K_cone: float | None = None,
) -> tuple[list[str], dict[str, tuple[float, float]]]:
    """Profile intervals of kc, kphi, cc [SI] of one profile, and which the data leave free.

    Each is pinned on a grid of 61 fractions of its box, the other two
    re-fitted with n inside its own interval ``n_range``
    (:func:`identify_extents`, eq. (2-7) with phic
    held); the interval is the pinned values whose best fit stays within
    ``thr`` [kPa^2].  A parameter whose interval covers half its box or more
    is undetermined.  ``ratio``: kc/kphi held fixed (a calibration); ``Kc``: a finite
    cone-terrain shear deformation [m] (None: fully mobilised).
    """
    b = bounds
    n_lo, n_hi = n_range
    n_loc = np.unique(
        np.concatenate([np.linspace(n_lo, n_hi, 17), np.clip(n + grid(-0.1, 0.1, 9), n_lo, n_hi)])
    )
    vals = grid(0.0, 1.0, 61)
    jlo, jhi, _, _ = identify_extents(z, y, n_loc, phic_deg, K_cone, b, cone, law, vals, thr, ratio)  # noqa: E501
    lo_at, hi_at = (a[0, 0] for a in box_grid(np.full((1, 1), n), bounds_params(b, ratio)))
    tokens: list[str] = []
    intervals: dict[str, tuple[float, float]] = {}
    for idx, name in enumerate(("kc", "kphi", "cc")):
        if jlo[idx] == -2:  # fixed at every n
            continue
        if jlo[idx] < 0:
            intervals[name] = (float(x[idx]), float(x[idx]))
            continue
        f_lo, f_hi = vals[jlo[idx]], vals[jhi[idx]]
        lo_n, hi_n = float(lo_at[idx]), float(hi_at[idx])  # in SI at the optimum's n
        a = min(lo_n + max(f_lo - 1 / 60, 0) * (hi_n - lo_n), float(x[idx]))
        c = max(lo_n + min(f_hi + 1 / 60, 1) * (hi_n - lo_n), float(x[idx]))
        intervals[name] = (a, c)
        if f_hi - f_lo >= 0.5:
            tokens.append(name)
    if ratio is not None and "kphi" in intervals:
        intervals["kc"] = (ratio * intervals["kphi"][0], ratio * intervals["kphi"][1])
    return tokens, intervals


def identification(
    bounds: Bounds,
    n_range: tuple[float, float],
    phic_range: tuple[float, float],
    linear: tuple[list[str], dict[str, tuple[float, float]]] = ([], {}),
    K_cone: float | None = None,
) -> tuple[list[str], dict[str, tuple[float, float]]]:
    """The undetermined list and profile intervals of one fully mobilised fit.

    n is undetermined when its interval covers half its range or more;
    phic always is when its bounds are open and shear is fully mobilised
    (``Kc`` None), since it then trades exactly against the scale of kc and
    kphi (eq. (2-6)); with a finite Kc only when its fitted range is open.
    ``linear`` adds the tokens and intervals of :func:`linear_intervals`.
    """
    und: list[str] = []
    intervals = {"n": (float(n_range[0]), float(n_range[1]))}
    if bounds.n[0] != bounds.n[1] and n_range[1] - n_range[0] >= 0.5 * (bounds.n[1] - bounds.n[0]):
        und.append("n")
    und += linear[0]
    intervals.update(linear[1])
    if phic_range[1] - phic_range[0] > 1e-9 or (
        K_cone is None and bounds.phic_deg[0] != bounds.phic_deg[1]
    ):
        und = ["phic", *und, "phic~scale(kc,kphi)"]
        intervals["phic_deg"] = (float(phic_range[0]), float(phic_range[1]))
    return und, intervals


def _pinned_scan(G, g, yy, lo, hi, idx: int, vals: np.ndarray) -> np.ndarray:
    """SSE (Nn, V) of the box LSQ with variable idx pinned at lo + v (hi - lo), v in vals."""
    lo_s, hi_s = lo[..., idx], hi[..., idx]
    v = lo_s[:, None] + vals[None, :] * (hi_s - lo_s)[:, None]  # (Nn, V)
    lo2 = np.repeat(lo[:, None, :], vals.size, axis=1).copy()
    hi2 = np.repeat(hi[:, None, :], vals.size, axis=1).copy()
    lo2[..., idx] = v
    hi2[..., idx] = v
    return box_lsq3(G[:, None], g[:, None], yy[:, None], lo2, hi2)[1]


def _compiled_args(z, y, n_loc, phic_deg, K_cone, bounds, cone, law, vals, ratio):
    """The arguments of the compiled scans (data; geometry and law), or None for numpy.

    The kernels take fully mobilised shear, a scalar law and numba switched on.
    """
    coef = [np.asarray(c, dtype=float) for c in law.coefficients()]
    if K_cone is not None or not enabled() or any(c.size != 1 for c in coef):
        return None
    s = 1.0 + math.tan(math.radians(phic_deg)) / math.tan(cone.half_angle)
    arr = [np.ascontiguousarray(a, dtype=float) for a in (z, y, n_loc)]
    data = (*arr, s, bounds_params(bounds, ratio), np.ascontiguousarray(vals, dtype=float))
    return data, (cone.height, cone.radius, not law.is_rm0, *(float(c.item()) for c in coef))


def identify_scans(
    z: np.ndarray,
    y: np.ndarray,
    n_loc: np.ndarray,
    phic_deg: float,
    K_cone: float | None,
    bounds: Bounds,
    cone: Cone,
    law: PressureLaw,
    vals: np.ndarray,
    ratio: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Profile scans of the identifiability analysis.

    For each n of ``n_loc`` and each of kc, kphi, cc: the SSE [kPa^2] of the
    best fit with that variable pinned at lo + v (hi - lo) for v in ``vals``
    (fractions of its box at that n), the other two re-fitted in their box
    (eq. (2-7) with phic and Kc held).  Compiled
    (:func:`terracone.inverse.solver.kernels.identify_scan`) for fully mobilised
    shear when numba is enabled, else numpy.

    Returns
    -------
    sse : (3, Nn, V) ndarray
        NaN for a variable fixed at every n.
    lo, hi : (Nn, 3) ndarray
        The box of (kc, kphi, cc) [SI] at each n.
    """
    args = _compiled_args(z, y, n_loc, phic_deg, K_cone, bounds, cone, law, vals, ratio)
    if args is not None:
        return identify_scan(*args[0], *args[1])
    X = design(
        z, n_loc[:, None], np.array(phic_deg), cone=cone, law=law, K_cone=K_cone, ratio=ratio
    )
    G, g, yy = gram(X, np.broadcast_to(y, X.shape[:-1]))
    lo, hi = bounds_arrays(bounds, n_loc, ratio)
    sse = np.full((3, n_loc.size, vals.size), np.nan)
    for idx in range(3):
        if not np.all(lo[:, idx] == hi[:, idx]):
            sse[idx] = _pinned_scan(G, g, yy, lo, hi, idx, vals)
    return sse, lo, hi


def scan_extents(sse: np.ndarray, thr: float) -> tuple[np.ndarray, np.ndarray]:
    """First and last index v of the scans ``sse`` (3, Nn, V) with SSE <= thr at some n.

    -1 where no value is within thr, -2 for a variable fixed at every n (NaN rows).
    """
    jlo, jhi = np.full((2, 3), -1, dtype=np.int64)
    for idx in range(3):
        if np.all(np.isnan(sse[idx])):
            jlo[idx] = jhi[idx] = -2
            continue
        ok = np.flatnonzero((sse[idx] <= thr).any(axis=0))
        if ok.size:
            jlo[idx], jhi[idx] = ok[0], ok[-1]
    return jlo, jhi


def identify_extents(
    z: np.ndarray,
    y: np.ndarray,
    n_loc: np.ndarray,
    phic_deg: float,
    K_cone: float | None,
    bounds: Bounds,
    cone: Cone,
    law: PressureLaw,
    vals: np.ndarray,
    thr: float,
    ratio: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`scan_extents` of :func:`identify_scans` (same arguments, and thr [kPa^2]).

    Compiled (:func:`terracone.inverse.solver.kernels.identify_extent`, which
    bisects each n's convex scan instead of evaluating all of it) for fully
    mobilised shear when numba is enabled; else from the full numpy scans.

    Returns
    -------
    jlo, jhi : (3,) int ndarray
        Per kc, kphi, cc: first and last index of ``vals`` within thr (-1:
        none; -2: the variable is fixed at every n).
    lo, hi : (Nn, 3) ndarray
        The box of (kc, kphi, cc) [SI] at each n.
    """
    args = _compiled_args(z, y, n_loc, phic_deg, K_cone, bounds, cone, law, vals, ratio)
    if args is not None:
        return identify_extent(*args[0], float(thr), *args[1])
    sse, lo, hi = identify_scans(z, y, n_loc, phic_deg, K_cone, bounds, cone, law, vals, ratio)
    return (*scan_extents(sse, thr), lo, hi)

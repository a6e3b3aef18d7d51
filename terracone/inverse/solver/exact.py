"""The ``exact`` solver of the prediction process.

For fixed n and phic the improved model (eq. (2-7) in [1]_) is linear in kc,
kphi and cc, so the inner problem is bounded linear least squares, solved to
its global optimum by :func:`terracone.inverse.solver.boxlsq.box_lsq3`.  The
remaining nonlinear parameters are searched globally: a dense grid over n
and phic (and Kc when it is fitted), then a bounded scalar refinement of n
around the best grid cell.

With fully mobilised shear, phic enters only through the factor
(1 + tan(phic)/tan(a)) that multiplies both kc and kphi, so phic trades
exactly against their common scale.  The solver reports the whole interval
of phic that attains the optimum and picks its middle, never one arbitrary
point of the ridge.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7), section 3.3.2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.boxlsq import box_lsq3, gram
from terracone.inverse.solver.columns import bounds_arrays, design
from terracone.inverse.solver.intervals import (
    CHI2_1_95,
    identification,
    linear_intervals,
    n_interval,
)
from terracone.inverse.solver.many import grid, solve_exact_many
from terracone.inverse.solver.polish import polish_many
from terracone.physics.cone import Cone
from terracone.physics.plate import PressureLaw

__all__ = ["ExactSolution", "solve_exact"]


@dataclass
class ExactSolution:
    """Raw output of :func:`solve_exact` (SI)."""

    kc: float
    kphi: float
    n: float
    cc: float
    phic_deg: float
    K_cone: float | None
    sse: float
    nfev: int
    nit: int
    phic_range: tuple[float, float]
    profile_intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    undetermined: list[str] = field(default_factory=list)
    sigma: float = float("nan")


def solve_exact(
    z: np.ndarray,
    y: np.ndarray,
    *,
    cone: Cone,
    law: PressureLaw,
    bounds: Bounds,
    K_cone: float | None = None,
    fit_K_cone: bool = False,
    n_grid: int = 97,
    phic_grid: int = 19,
    noise_floor: float = 0.01,
    profiles: bool = True,
    kc_over_kphi: float | None = None,
) -> ExactSolution:
    """Global least-squares fit of the improved model to one CI profile.

    Parameters
    ----------
    z : (Z,) ndarray
        Base depths [m].
    y : (Z,) ndarray
        Measured CI [kPa].
    cone, law, bounds
        Cone, pressure law (RM0/RM1) and search bounds.
    K_cone : float or None
        Fixed shear deformation parameter [m]; None for fully mobilised.
    fit_K_cone : bool
        Search Kc (log grid within ``bounds.Kc``) as a sixth parameter.
    n_grid, phic_grid : int
        Grid sizes of the global stage.
    noise_floor : float
        Smallest noise standard deviation assumed, as a fraction of the mean
        CI, when judging which parameters the data leave free.
    profiles : bool
        Compute profile intervals and the ``undetermined`` list.
    kc_over_kphi : float, optional
        Hold the ratio kc/kphi [m] fixed (from a calibration): the cone
        alone barely separates kc from kphi, plates of two sizes do.
    """
    ratio = kc_over_kphi
    z = np.asarray(z, float)
    y = np.asarray(y, float)
    if K_cone is None and not fit_K_cone:
        return _solve_mobilised(z, y, cone, law, bounds, n_grid, noise_floor, profiles, ratio)
    fp = _Finite(z, y, cone, law, bounds, K_cone, fit_K_cone, ratio)
    return _solve_finite(fp, n_grid, phic_grid, noise_floor, profiles)


@dataclass
class _Finite:
    """One profile with finite Kc (fixed or fitted): cells and the scaled outer variables."""

    z: np.ndarray
    y: np.ndarray
    cone: Cone
    law: PressureLaw
    bounds: Bounds
    K_cone: float | None
    fit_K_cone: bool
    ratio: float | None

    def __post_init__(self) -> None:
        b = self.bounds
        lo_v = [b.n[0], b.phic_deg[0]] + ([math.log(b.K_cone[0])] if self.fit_K_cone else [])
        hi_v = [b.n[1], b.phic_deg[1]] + ([math.log(b.K_cone[1])] if self.fit_K_cone else [])
        self.lo_v, self.hi_v = np.array(lo_v), np.array(hi_v)
        self.span = np.where(self.hi_v > self.lo_v, self.hi_v - self.lo_v, 1.0)

    def design(self, n, phi, K):
        return design(self.z, n, phi, cone=self.cone, law=self.law, K_cone=K, ratio=self.ratio)

    def cell_sse(self, n, phi, kc_val):
        """Box-LS over (kc, kphi, cc) for arrays of n, phi, Kc (broadcast)."""
        K = kc_val[..., None] if self.fit_K_cone else self.K_cone
        X = self.design(n[..., None], phi[..., None], K)
        G, g, yy = gram(X, np.broadcast_to(self.y, X.shape[:-1]))
        lo, hi = bounds_arrays(self.bounds, np.broadcast_to(n, G.shape[:-2]), self.ratio)
        return box_lsq3(G, g, yy, lo, hi)

    def unpack(self, v):
        """(n, phic [deg], Kc [m] or NaN) of the scaled outer point v."""
        w = np.clip(self.lo_v + v * self.span, self.lo_v, self.hi_v)
        K = math.exp(w[2]) if self.fit_K_cone else np.nan
        return float(w[0]), float(w[1]), K

    def scaled(self, n, phi, K):
        """The scaled outer point of (n, phic, Kc)."""
        v0 = [n, phi] + ([math.log(K)] if self.fit_K_cone else [])
        return (np.array(v0) - self.lo_v) / self.span

    def resid_v(self, v):
        nv, pv, Kv = self.unpack(v)
        x_, _ = self.cell_sse(np.array([nv]), np.array([pv]), np.array([Kv]))
        Xv = self.design(np.array(nv), np.array(pv), Kv if self.fit_K_cone else self.K_cone)
        return Xv @ x_[0] - self.y


def _grid_starts(sse_grid: np.ndarray) -> np.ndarray:
    """Starts of the joint refinement: flat indices of the grid's local minima and the best
    cell of every Kc slice (a valley between phic and Kc need not show as a local minimum on
    a coarse Kc grid), the ten best by SSE, ties by position."""
    from scipy.ndimage import minimum_filter  # only for finite Kc (scipy.ndimage: 0.2 s import)

    local = sse_grid <= minimum_filter(sse_grid, size=3, mode="nearest")
    for kk in range(sse_grid.shape[2]):
        sl = sse_grid[..., kk]
        local[np.unravel_index(np.argmin(sl), sl.shape) + (kk,)] = True
    idx = np.flatnonzero(local)
    return idx[np.lexsort((idx, sse_grid.reshape(-1)[idx]))][:10]


def _solve_finite(
    fp: _Finite, n_grid: int, phic_grid: int, noise_floor: float, profiles: bool
) -> ExactSolution:
    """Finite Kc: grid over n, phic (and Kc), then a joint refinement from the best minima."""
    z, y, bounds, ratio = fp.z, fp.y, fp.bounds, fp.ratio
    ns = grid(*bounds.n, n_grid)
    phis = grid(*bounds.phic_deg, phic_grid)
    Kcs = np.exp(grid(*np.log(bounds.K_cone), 7)) if fp.fit_K_cone else np.array([np.nan])
    N, P, K = np.meshgrid(ns, phis, Kcs, indexing="ij")
    sse_grid = fp.cell_sse(N, P, K)[1]
    nfev = sse_grid.size

    # joint refinement of all parameters (Gauss-Newton, bounded) from the grid's best
    # local minima: with finite Kc phic is no longer a pure scale, and n, phic and Kc
    # form curved valleys that a simplex search can stop in
    best_v, best_f = None, np.inf
    nit = 0
    zero = 1e-24 * float(y @ y)
    for flat_i in _grid_starts(sse_grid):
        ii, jj, kk = np.unravel_index(flat_i, sse_grid.shape)
        v0 = fp.scaled(ns[ii], phis[jj], Kcs[kk])
        v, fv, ne = _joint_refine(v0, fp.resid_v)
        nfev += ne
        nit += 1
        if fv < best_f * (1 - 1e-12):
            best_v, best_f = v, fv
        if best_f <= zero:  # an exact fit: the global minimum
            break
    n_best, phi_best, best_K = fp.unpack(best_v)

    x = fp.cell_sse(np.array([n_best]), np.array([phi_best]), np.array([best_K]))[0][0].copy()
    Kc_out = float(best_K) if fp.fit_K_cone else fp.K_cone
    # report the SSE from the residuals themselves
    X = fp.design(np.array(n_best), np.array(phi_best), Kc_out)
    # the normal equations lose digits near an exact fit: re-solve on X itself
    lo_b, hi_b = (a[0] for a in bounds_arrays(bounds, np.array([n_best]), ratio))
    x = _polish(X, y, lo_b, hi_b, x)
    resid = X @ x - y
    if ratio is not None:
        x[0] = ratio * x[1]
    sol = _solution(x, n_best, phi_best, Kc_out, resid, nfev, nit, (phi_best, phi_best))
    if profiles:
        _identify(
            sol, z, y, ns, sse_grid.min(axis=(1, 2)), bounds, fp.cone, fp.law, noise_floor, ratio
        )
    return sol


def _joint_refine(v0, resid_v):
    """Bounded Gauss-Newton on the scaled (n, phic[, log Kc]), variable projection.

    The residual at each outer point has the linear parameters (kc, kphi,
    cc) solved exactly within their bounds, so the long valley where phic
    trades against the scale of kc and kphi is not walked.  Returns the
    scaled outer point, its SSE and the function evaluations.
    """
    from scipy.optimize import least_squares  # on first use (0.3 s import)

    res = least_squares(
        resid_v,
        v0,
        bounds=(np.zeros(v0.size), np.ones(v0.size)),
        method="trf",
        diff_step=1e-7,
        xtol=1e-14,
        ftol=1e-14,
        gtol=1e-14,
        max_nfev=200,
    )
    f0, f1 = (float(r @ r) for r in (resid_v(v0), resid_v(res.x)))
    return (res.x, f1, int(res.nfev)) if f1 <= f0 else (v0, f0, int(res.nfev))


def _polish(X: np.ndarray, y: np.ndarray, lo, hi, x0) -> np.ndarray:
    """:func:`~terracone.inverse.solver.polish.polish_many` on one profile (QR, not the normal equations)."""
    return polish_many(X[None], y[None], lo[None], hi[None], np.asarray(x0, dtype=float)[None])[0]


def _solution(x, n, phic, K_cone, resid, nfev, nit, phic_range) -> ExactSolution:
    """The ExactSolution of (kc, kphi, cc) = x at (n, phic, K_cone), its SSE from ``resid``."""
    x, sse = [float(v) for v in x], float(resid @ resid)
    return ExactSolution(
        x[0], x[1], float(n), x[2], float(phic), K_cone, sse, nfev, nit, phic_range
    )


def _solve_mobilised(
    z, y, cone, law, bounds, n_grid, noise_floor, profiles, ratio
) -> ExactSolution:
    """Fully mobilised shear: the vectorised solver of :mod:`many` on one profile."""
    ms = solve_exact_many(
        [z], [y], cone=cone, law=law, bounds=bounds, n_grid=n_grid, noise_floor=noise_floor,
        kc_over_kphi=ratio,
    )  # fmt: skip
    x = np.array([ms.kc[0], ms.kphi[0], ms.cc[0]])
    n, phic = np.array(ms.n[0]), np.array(ms.phic_deg[0])
    if ratio is not None:  # kc = ratio * kphi: one column, and both bounds on kphi
        x[0] = 0.0
    X = design(z, n, phic, cone=cone, law=law, K_cone=None)
    Xr = X if ratio is None else design(z, n, phic, cone=cone, law=law, K_cone=None, ratio=ratio)
    x = _polish(Xr, y, *bounds_arrays(bounds, n, ratio), x)
    if ratio is not None:
        x[0] = ratio * x[1]
    resid = X @ x - y
    phic_range = (float(ms.phic_lo[0]), float(ms.phic_hi[0]))
    sol = _solution(x, ms.n[0], ms.phic_deg[0], None, resid, int(ms.nfev), 1, phic_range)
    if profiles:
        _identify(sol, z, y, ms.n_grid, ms.sse_n[0], bounds, cone, law, noise_floor, ratio)
    return sol


def _identify(sol, z, y, ns, sse_n, bounds, cone, law, noise_floor, ratio) -> None:
    """Approximate 95% profile-likelihood intervals and the undetermined list
    (:func:`~terracone.inverse.solver.intervals.n_intervals` on one profile)."""
    sigma2 = max(sol.sse / max(y.size - 5, 1), (noise_floor * float(np.mean(np.abs(y)))) ** 2)
    sol.sigma = math.sqrt(sigma2)
    thr = sol.sse + CHI2_1_95 * sigma2

    # n: profile from the global grid (min over phic, Kc and the linear parameters)
    n_lo, n_hi = (float(v[0]) for v in n_interval(ns, sse_n[None], np.array([thr]), sol.n, bounds))
    # kc, kphi, cc: pin one on a grid, re-fit the others and n (shared with the
    # vectorised path of predict_many)
    x = np.array([sol.kc, sol.kphi, sol.cc])
    linear = linear_intervals(
        z, y, x, sol.n, sol.phic_deg, thr, (n_lo, n_hi),
        bounds=bounds, law=law, cone=cone, ratio=ratio, K_cone=sol.K_cone,
    )  # fmt: skip
    und, intervals = identification(bounds, (n_lo, n_hi), sol.phic_range, linear, K_cone=sol.K_cone)
    sol.undetermined = und
    sol.profile_intervals = intervals

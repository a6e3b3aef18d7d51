"""The exact solver vectorised over many profiles at once (batch work).

Same problem as :mod:`terracone.inverse.solver.exact` (fully mobilised shear):
minimise the RMSD of CI over kc, kphi, cc, n, phic within bounds.  Profiles
of different lengths are padded and masked; everything runs as a few numpy
calls over (profile, n) cells:

1. a grid over n; for each cell the bounded linear least squares in
   (kc', kphi', cc) with kc' = s kc, kphi' = s kphi and
   s = 1 + tan(phic)/tan(a) (eq. (2-6) with fully mobilised shear, so phic
   only scales the kc and kphi columns);
2. phic: when the lower bounds of kc and kphi are 0 the feasible boxes for
   increasing s are nested, so the optimum over phic is attained at the
   upper bound of phic and on the whole interval [phic*, phic_hi] where the
   scaled solution still fits in the box; the middle of that interval is
   reported (the exact ridge of section 2, never hidden).  Otherwise phic
   is put on a grid;
3. a refinement of n around each profile's best grid cell: Brent's method
   (parabolic steps through the best three points, golden-section steps
   when a parabola does not shrink the bracket, as where a bound of the box
   becomes active), compiled profile by profile, or vectorised across
   profiles in the numpy reference (:func:`brent_many`, the same steps);
   both stop at the same bracket width, so the reference reaches the
   compiled path's optimum on any CPU: they differ by the rounding of the
   SSE, never by where the search stops.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-5) to (2-7), section 3.3.2.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.boxlsq import box_lsq3
from terracone.jit import enabled
from terracone.physics.cone import Cone, cone_index_basis
from terracone.physics.plate import PressureLaw

__all__ = [
    "ManySolution",
    "solve_exact_many",
    "bounds_params",
    "first_min",
    "parabola_vertices",
    "brent_steps",
    "brent_many",
    "grid",
]

_GOLD = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass
class ManySolution:
    """Per-profile arrays (length P), SI."""

    kc: np.ndarray
    kphi: np.ndarray
    n: np.ndarray
    cc: np.ndarray
    phic_deg: np.ndarray
    phic_lo: np.ndarray
    phic_hi: np.ndarray
    sse: np.ndarray
    n_lo: np.ndarray
    n_hi: np.ndarray
    nfev: int
    n_grid: np.ndarray | None = None
    sse_n: np.ndarray | None = None


def _minimise_1d(f, a: np.ndarray, b: np.ndarray, iters: int):
    """Minimise f over [a, b] for each of P problems at once; f maps (P, K) to (P, K).

    Many problems: golden section (one new point per problem per step).
    Few problems: a zooming grid of 17 points (8 steps), which needs fewer
    calls, each as cheap as one golden step when numpy's call overhead
    dominates.  Returns (x, f(x), evaluations).
    """
    P = a.size
    if P < 32:
        lo, hi = a.astype(float), b.astype(float)
        K = 17
        best_x = 0.5 * (lo + hi)
        best_f = np.full(P, np.inf)
        used = 0
        while used < 8 * K:
            grid = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, K)[None, :]
            fv = f(grid)
            used += K
            kk = np.argmin(fv, axis=1)
            fk = fv[np.arange(P), kk]
            better = fk < best_f
            best_f = np.where(better, fk, best_f)
            best_x = np.where(better, grid[np.arange(P), kk], best_x)
            h = (hi - lo) / (K - 1)
            lo = np.maximum(lo, best_x - h)
            hi = np.minimum(hi, best_x + h)
            if np.all(hi - lo < 1e-10):
                break
        return best_x, best_f, used * P
    c = b - _GOLD * (b - a)
    d = a + _GOLD * (b - a)
    fc, fd = f(c[:, None])[:, 0], f(d[:, None])[:, 0]
    fa = np.full(P, np.inf)  # SSE at the bracket's ends, once evaluated
    fb = np.full(P, np.inf)
    for _ in range(iters):
        left = fc < fd
        fb = np.where(left, fd, fb)
        fa = np.where(left, fa, fc)
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        d_new = np.where(left, c, a + _GOLD * (b - a))
        c_new = np.where(left, b - _GOLD * (b - a), d)
        new_pt = np.where(left, c_new, d_new)
        fnew = f(new_pt[:, None])[:, 0]
        fc, fd = np.where(left, fnew, fd), np.where(left, fc, fnew)
        c, d = c_new, d_new
    left = fc < fd
    x = np.where(left, c, d)
    fx = np.where(left, fc, fd)
    # one parabolic step through the best point and its bracketing neighbours
    v = np.where(
        left,
        parabola_vertices(a, fa, c, fc, d, fd),
        parabola_vertices(c, fc, d, fd, b, fb),
    )
    has = ~np.isnan(v)
    used = (iters + 2) * P
    if has.any():
        fv = f(np.where(has, v, x)[:, None])[:, 0]
        used += int(has.sum())
        better = has & (fv < fx)
        x, fx = np.where(better, v, x), np.where(better, fv, fx)
    return x, fx, used


def parabola_vertices(xl, fl, xm, fm, xr, fr) -> np.ndarray:
    """Vertex of the parabola through (xl, fl), (xm, fm), (xr, fr) per element, xl < xm < xr, or NaN.

    NaN unless fm <= min(fl, fr), the parabola opens upwards and the vertex
    lies strictly between xl and xr.
    """
    with np.errstate(all="ignore"):
        p = (xm - xl) * (fm - fr)
        q = (xm - xr) * (fm - fl)
        den = p - q
        x = xm - 0.5 * ((xm - xl) * p - (xm - xr) * q) / den
        ok = (fm <= fl) & (fm <= fr) & np.isfinite(fl) & np.isfinite(fr) & (den < 0.0)
        ok &= (xl < x) & (x < xr)
    return np.where(ok, x, np.nan)


class _Kernels:
    """The compiled kernels of :mod:`terracone.inverse.solver.kernels` with a law, cone and box filled in."""

    def __init__(self, law: PressureLaw, cone: Cone, bounds: Bounds, ratio: float | None, coef):
        from terracone.inverse.solver import kernels

        self.k = kernels
        self.geom = (cone.height, cone.radius, not law.is_rm0, *coef)
        self.bp = bounds_params(bounds, ratio)

    def __call__(self, zz, yy, w, n, sv):
        n = np.ascontiguousarray(n, dtype=float)
        lo, hi = self.k.box_grid(n, self.bp)
        return self.k.cells_kernel(zz, yy, w, n, sv, lo, hi, self.bp[10], *self.geom)

    def brent(self, zz, yy, w, a, b, x0, f0, fa, fb, s, xtol, maxiter=200):
        return self.k.brent_refine(
            zz, yy, w, a, b, x0, f0, fa, fb, s, self.bp, xtol, maxiter, *self.geom
        )


def _cells_kernel(
    law: PressureLaw, cone: Cone, bounds: Bounds, ratio: float | None
) -> _Kernels | None:
    """The compiled kernels bound to a law and cone, or None (numpy path).

    None when compilation is off (:func:`terracone.jit.enabled`) or the law's
    coefficients are not scalars.
    """
    if not enabled():
        return None
    try:
        return _kernels_for(law, cone, bounds, ratio)
    except TypeError:  # unhashable (array coefficients): not cached
        return _kernels_for.__wrapped__(law, cone, bounds, ratio)


@functools.lru_cache(maxsize=32)
def _kernels_for(law: PressureLaw, cone: Cone, bounds: Bounds, ratio: float | None):
    """_Kernels of a law, cone, box (built once per combination: predict calls it per profile)."""
    coef = [np.asarray(c, dtype=float) for c in law.coefficients()]
    if any(c.size != 1 for c in coef):
        return None
    return _Kernels(law, cone, bounds, ratio, tuple(float(c.item()) for c in coef))


def bounds_params(bounds: Bounds, ratio: float | None) -> np.ndarray:
    """Bounds of (kc, kphi, cc) as the array ``bp`` of :func:`terracone.inverse.solver.kernels.kbounds`."""
    from terracone.physics import units as u

    def conv(units: str, extra: float) -> tuple[float, float]:
        if u.check_system(units) == "si":
            return 1.0, 1.0
        # kc [SI] = kc * c / INCH^(n + extra): c from n = -extra
        f = u.kc_to_si if extra == 1.0 else u.kphi_to_si
        return float(f(1.0, -extra, units)), float(u.INCH)

    return np.array(
        [
            *bounds.kc,
            *bounds.kphi,
            *bounds.cc,
            *conv(bounds.kc_units, 1.0),
            *conv(bounds.kphi_units, 2.0),
            math.nan if ratio is None else float(ratio),
        ],
        dtype=float,
    )


@functools.lru_cache(maxsize=64)
def _grid_cached(lo: float, hi: float, k: int) -> np.ndarray:
    g = np.array([lo]) if lo == hi else np.linspace(lo, hi, k)
    g.flags.writeable = False
    return g


def grid(lo: float, hi: float, k: int) -> np.ndarray:
    """``linspace(lo, hi, k)`` (one point when lo == hi), read-only and cached: per-profile
    fits ask for the same few grids again and again."""
    return _grid_cached(float(lo), float(hi), int(k))


def first_min(v: np.ndarray, tol: np.ndarray | float) -> np.ndarray:
    """Per row of v (P, M), the first index whose value is within tol (P,) of the row's minimum.

    A deterministic argmin: values that differ only by rounding (compiled
    and numpy kernels sum in different orders) count as ties, and ties go
    to the first index.
    """
    m = np.nanmin(v, axis=1)
    ok = v <= (m + np.asarray(tol, dtype=float))[:, None]
    return np.argmax(ok, axis=1)


def _pad(depths: list[np.ndarray], cis: list[np.ndarray]):
    P = len(depths)
    Z = max(d.size for d in depths)
    zz = np.zeros((P, Z))
    yy = np.zeros((P, Z))
    w = np.zeros((P, Z))
    for i, (d, c) in enumerate(zip(depths, cis)):
        k = d.size
        zz[i, :k] = d
        zz[i, k:] = d[-1]
        yy[i, :k] = c
        w[i, :k] = 1.0
    return zz, yy, w


@dataclass
class _Problem:
    """The padded profiles, box and phic grid of one :func:`solve_exact_many` call."""

    zz: np.ndarray  # (P, Z) base depths [m], padded with the last depth
    yy: np.ndarray  # (P, Z) CI [kPa], padded with 0
    w: np.ndarray  # (P, Z) 1 at the profile's points, 0 at the padding
    yty: np.ndarray  # (P,) y'y
    cone: Cone
    law: PressureLaw
    bounds: Bounds
    ratio: float | None
    phis: np.ndarray  # (F,) phic grid [deg] (one point: the nested boxes or a fixed phic)
    kern: _Kernels | None  # compiled kernels, or None (numpy path)

    def take(self, idx: np.ndarray) -> _Problem:
        """The problem of the profiles ``idx`` only (numpy path)."""
        return replace(self, zz=self.zz[idx], yy=self.yy[idx], w=self.w[idx], yty=self.yty[idx])

    def s_of(self, phi):
        """Scale s = 1 + tan(phic)/tan(a) of the kc and kphi columns (eq. (2-6))."""
        return 1.0 + np.tan(np.radians(phi)) / math.tan(self.cone.half_angle)

    def kbounds(self, n):
        """Box of kc, kphi [SI] at n (kc pinned at 0 with a ratio)."""
        kc_lo, kc_hi = self.bounds.kc_si(n)
        kp_lo, kp_hi = self.bounds.kphi_si(n)
        ratio = self.ratio
        if ratio is not None:
            if ratio > 0:
                kp_lo = np.maximum(kp_lo, kc_lo / ratio)
                kp_hi = np.maximum(np.minimum(kp_hi, kc_hi / ratio), kp_lo)
            kc_lo = kc_hi = np.zeros(np.shape(n))
        return kc_lo, kc_hi, kp_lo, kp_hi

    def cells(self, n: np.ndarray, sv: np.ndarray | None = None):
        """Primed x (P, K, F, 3) and SSE (P, K, F) for n (P, K) and each s of sv ((P, F), or the
        phic grid)."""
        sv = self.s_of(self.phis)[None, :] if sv is None else sv
        if self.kern is not None:
            return self.kern(self.zz, self.yy, self.w, n, np.ascontiguousarray(sv))
        return numpy_cells(self, n, sv)


def numpy_cells(pb: _Problem, n: np.ndarray, sv: np.ndarray):
    """The numpy reference of the cells (:func:`terracone.inverse.solver.kernels.cells_kernel`)."""
    zz, yy, w = pb.zz, pb.yy, pb.w
    A, B, C = cone_index_basis(
        zz[:, None, :], n=n[..., None], phic_deg=0.0, law=pb.law, cone=pb.cone
    )
    if pb.ratio is not None:
        A, B = np.zeros_like(A), pb.ratio * A + B
    Aw, Bw = A * w[:, None, :], B * w[:, None, :]
    Cw = np.broadcast_to(C * w[:, None, :], Aw.shape)
    ab, ac, bc = (Aw * B).sum(-1), (Aw * C).sum(-1), (Bw * C).sum(-1)
    G = np.stack(
        [
            np.stack([(Aw * A).sum(-1), ab, ac], -1),
            np.stack([ab, (Bw * B).sum(-1), bc], -1),
            np.stack([ac, bc, (Cw * C).sum(-1)], -1),
        ],
        -2,
    )
    yk = yy[:, None, :]
    g = np.stack([(Aw * yk).sum(-1), (Bw * yk).sum(-1), (Cw * yk).sum(-1)], -1)
    # phic scales the kc and kphi columns by s, eq. (2-6)
    D = np.ones(sv.shape + (3,))
    D[..., 0] = sv
    D[..., 1] = sv
    Dk = D[:, None]  # (P or 1, 1, F, 3)
    Gs = G[:, :, None] * Dk[..., :, None] * Dk[..., None, :]
    gs = g[:, :, None] * Dk
    kc_lo, kc_hi, kp_lo, kp_hi = pb.kbounds(n)
    cc = pb.bounds.cc
    lo = np.stack(np.broadcast_arrays(kc_lo, kp_lo, cc[0]), axis=-1)[:, :, None] + 0 * Dk
    hi = np.stack(np.broadcast_arrays(kc_hi, kp_hi, cc[1]), axis=-1)[:, :, None] + 0 * Dk
    x, _ = box_lsq3(Gs, gs, pb.yty[:, None, None], lo, hi)
    xp = x * Dk  # (kc', kphi', cc): primed values, CI = kc' A + kphi' B + cc C
    # the SSE from the residuals: the normal-equation form cancels near a perfect fit,
    # which would blind the refinement of n on clean data
    r = (
        A[:, :, None, :] * xp[..., 0:1]
        + B[:, :, None, :] * xp[..., 1:2]
        + C[:, :, None, :] * xp[..., 2:3]
        - yy[:, None, None, :]
    )
    return xp, np.einsum("pkfz,pz->pkf", r * r, w)


def brent_steps(a, b, x, w, v, fx, fw, fv, d, e, tol1):
    """The next trial points of Brent's minimiser per element, and the new (d, e).

    The numpy twin of :func:`terracone.inverse.solver.kernels.brent_step`:
    a parabolic step through x, w, v (the best three points so far) where it
    falls inside the bracket [a, b] and is shorter than half the step before
    last, a golden-section step into the larger part of the bracket
    elsewhere; steps are at least ``tol1`` long.
    """
    cg = 1.0 - _GOLD  # (3 - sqrt(5)) / 2
    xm = 0.5 * (a + b)
    with np.errstate(all="ignore"):
        r = (x - w) * (fx - fv)
        q = (x - v) * (fx - fw)
        p = (x - v) * q - (x - w) * r
        q = 2.0 * (q - r)
        p = np.where(q > 0.0, -p, p)
        q = np.abs(q)
        para = (np.abs(e) > tol1) & (np.abs(p) < np.abs(0.5 * q * e))
        para &= (p > q * (a - x)) & (p < q * (b - x))
        dp = p / q
    up = x + dp
    dp = np.where((up - a < 2.0 * tol1) | (b - up < 2.0 * tol1), np.where(xm >= x, tol1, -tol1), dp)
    e_new = np.where(para, d, np.where(x >= xm, a - x, b - x))
    d_new = np.where(para, dp, cg * e_new)
    u = np.where(np.abs(d_new) >= tol1, x + d_new, x + np.where(d_new > 0.0, tol1, -tol1))
    return u, d_new, e_new


def brent_many(f, a, b, x0, f0, fa, fb, xtol: float, maxiter: int = 200):
    """Brent's minimisation of f over [a_p, b_p] for P problems at once: the numpy twin of
    :func:`terracone.inverse.solver.kernels.brent_refine`, step for step.

    ``f(rows, u)`` gives f of the problems ``rows`` at the points ``u``.
    Starts from x0 (value f0) with the bracket's ends (values fa, fb) as the
    two other points; each problem stops when its bracket is at most 4 xtol
    wide around its best point, so every problem ends within 2 xtol of a
    local minimum of f on [a, b] whatever the rounding of f.  Returns (x,
    f(x), evaluations); f(x) is never above f0.
    """
    lo, hi = np.array(a, dtype=float), np.array(b, dtype=float)
    x, fx = np.array(x0, dtype=float), np.array(f0, dtype=float)
    fa, fb = np.asarray(fa, dtype=float), np.asarray(fb, dtype=float)
    # the other two points: the bracket's ends (the one at x, if any, left out)
    at_lo, at_hi = lo == x, (hi == x) & (lo != x)
    lo_first = ~at_lo & ~at_hi & (fa <= fb)
    w_ = np.where(at_lo | ~(at_hi | lo_first), hi, lo)
    fw = np.where(at_lo | ~(at_hi | lo_first), fb, fa)
    v = np.where(at_hi, lo, hi)
    fv = np.where(at_hi, fa, fb)
    d = hi - lo
    e = d.copy()
    used = 0
    for _ in range(maxiter):
        act = np.flatnonzero(np.abs(x - 0.5 * (lo + hi)) > 2.0 * xtol - 0.5 * (hi - lo))
        if act.size == 0:
            break
        sl = (lo[act], hi[act], x[act], w_[act], v[act], fx[act], fw[act], fv[act])
        u, d[act], e[act] = brent_steps(*sl, d[act], e[act], xtol)
        fu = f(act, u)
        used += act.size
        lo_a, hi_a, x_a, w_a, v_a, fx_a, fw_a, fv_a = sl
        ok = fu <= fx_a  # u is the new best: the old best bounds the bracket
        lo[act] = np.where(ok, np.where(u >= x_a, x_a, lo_a), np.where(u < x_a, u, lo_a))
        hi[act] = np.where(ok, np.where(u >= x_a, hi_a, x_a), np.where(u < x_a, hi_a, u))
        to_w = ~ok & ((fu <= fw_a) | (w_a == x_a))
        to_v = ~ok & ~to_w & ((fu <= fv_a) | (v_a == x_a) | (v_a == w_a))
        v[act] = np.where(ok | to_w, w_a, np.where(to_v, u, v_a))
        fv[act] = np.where(ok | to_w, fw_a, np.where(to_v, fu, fv_a))
        w_[act] = np.where(ok, x_a, np.where(to_w, u, w_a))
        fw[act] = np.where(ok, fx_a, np.where(to_w, fu, fw_a))
        x[act] = np.where(ok, u, x_a)
        fx[act] = np.where(ok, fu, fx_a)
    return x, fx, used


def _refine_n(pb: _Problem, ns, sseg, i_n, i_f, refine_iter: int):
    """n of each profile refined around its best grid cell (same phic scale); (n, SSE, nfev).

    Brent's method from the grid's three points to the bracket width that
    ``refine_iter`` golden steps would leave, compiled
    (:func:`terracone.inverse.solver.kernels.brent_refine`) or in numpy
    (:func:`brent_many`, the reference): the same steps, so both end within
    the same distance of the optimum in n whatever the CPU's rounding.
    """
    P = pb.zz.shape[0]
    rows = np.arange(P)
    step = ns[1] - ns[0]
    n_best = ns[i_n]
    a_n, b_n = np.clip(n_best - step, *pb.bounds.n), np.clip(n_best + step, *pb.bounds.n)
    s = pb.s_of(pb.phis)[i_f]
    f0 = sseg[rows, i_n, i_f]
    fa = sseg[rows, np.maximum(i_n - 1, 0), i_f]
    fb = sseg[rows, np.minimum(i_n + 1, ns.size - 1), i_f]
    xtol = 0.5 * step * _GOLD**refine_iter
    if pb.kern is not None:
        return pb.kern.brent(pb.zz, pb.yy, pb.w, a_n, b_n, n_best, f0, fa, fb, s, xtol)

    def f(idx, nv):  # the SSE of profiles idx at n = nv (one each)
        sub = pb if idx.size == P else pb.take(idx)
        return numpy_cells(sub, nv[:, None], s[idx, None])[1][:, 0, 0]

    return brent_many(f, a_n, b_n, n_best, f0, fa, fb, xtol)


def _refine_phi(pb: _Problem, n_best, i_f, refine_iter: int):
    """phic scale of each profile refined between its phic grid neighbours at n_best; (s, nfev)."""
    phis = pb.phis
    s_best = pb.s_of(phis)[i_f]

    def fphi(pv):  # pv (P, K) -> SSE (P, K)
        return pb.cells(n_best[:, None], pb.s_of(pv))[1][:, 0, :]

    lo, hi = phis[np.maximum(i_f - 1, 0)], phis[np.minimum(i_f + 1, phis.size - 1)]
    p_ref, f_ref, used = _minimise_1d(fphi, lo, hi, refine_iter)
    f_grid = pb.cells(n_best[:, None], s_best[:, None])[1][:, 0, 0]
    return np.where(f_ref < f_grid, pb.s_of(p_ref), s_best), used


def _phic_ridge(pb: _Problem, x, n_best, s_best):
    """phic (middle, low, high) [deg] of the ridge: every s whose box still holds the optimal
    primed (kc', kphi'), lo <= x'/s <= hi, fits equally well (eq. (2-6) fully mobilised)."""
    phi_lo, phi_hi = pb.bounds.phic_deg
    P = x.shape[0]
    if phi_lo == phi_hi:
        ph = np.full(P, phi_lo)
        return ph, ph, ph
    kc_lo, kc_hi, kp_lo, kp_hi = pb.kbounds(n_best)
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.maximum(
            np.where(kc_hi > 0, x[:, 0] / kc_hi, 0.0), np.where(kp_hi > 0, x[:, 1] / kp_hi, 0.0)
        )
        room = np.minimum(
            np.where(kc_lo > 0, x[:, 0] / kc_lo, np.inf),
            np.where(kp_lo > 0, x[:, 1] / kp_lo, np.inf),
        )
    s_min, s_max = pb.s_of(phi_lo), pb.s_of(phi_hi)
    s_lo_r = np.minimum(np.clip(need, s_min, s_max), s_best)
    s_hi_r = np.maximum(np.clip(room, s_min, s_max), s_best)
    t = math.tan(pb.cone.half_angle)
    ph_lo = np.degrees(np.arctan((s_lo_r - 1.0) * t))
    ph_hi = np.degrees(np.arctan((s_hi_r - 1.0) * t))
    return 0.5 * (ph_lo + ph_hi), ph_lo, ph_hi


def _n_interval(pb: _Problem, ns, sse_n, sse, n_best, noise_floor: float):
    """n interval from the grid profile of SSE (95% profile likelihood, noise floor)."""
    w, yy = pb.w, pb.yy
    npts = w.sum(axis=1)
    mean_y = np.einsum("pz,pz->p", w, np.abs(yy)) / npts
    sigma2 = np.maximum(sse / np.maximum(npts - 5, 1), (noise_floor * mean_y) ** 2)
    thr = sse + 3.841458820694124 * sigma2
    ok = sse_n <= thr[:, None]
    big = np.where(ok, ns[None, :], -np.inf).max(axis=1)
    small = np.where(ok, ns[None, :], np.inf).min(axis=1)
    n_lo = np.minimum(np.where(np.isfinite(small), small, n_best), n_best)
    n_hi = np.maximum(np.where(np.isfinite(big), big, n_best), n_best)
    return n_lo, n_hi


def _problem(depths, cis, cone, law, bounds, ratio) -> _Problem:
    zz, yy, w = _pad(depths, cis)
    phi_lo, phi_hi = bounds.phic_deg
    nested = bounds.kc[0] == 0.0 and bounds.kphi[0] == 0.0
    if phi_lo == phi_hi or nested:
        phis = np.array([phi_hi])
    else:
        phis = np.linspace(phi_lo, phi_hi, 19)
    yty = np.einsum("pz,pz->p", w * yy, yy)
    kern = _cells_kernel(law, cone, bounds, ratio)
    return _Problem(zz, yy, w, yty, cone, law, bounds, ratio, phis, kern)


def solve_exact_many(
    depths: list[np.ndarray],
    cis: list[np.ndarray],
    *,
    cone: Cone,
    law: PressureLaw,
    bounds: Bounds,
    n_grid: int = 41,
    refine_iter: int = 40,
    noise_floor: float = 0.01,
    kc_over_kphi: float | None = None,
) -> ManySolution:
    """Fit the improved model (fully mobilised shear) to many profiles.

    Parameters
    ----------
    depths, cis : list of (Z_i,) ndarray
        Base depths [m] and CI [kPa] of each profile (one cone).
    cone, law, bounds
        Cone, pressure law and search bounds (as in :func:`solve_exact`).
    n_grid : int
        Points of the global grid over n.
    refine_iter : int
        Accuracy of the refinement of n: the bracket of two grid steps
        around the best grid point shrinks to what ``refine_iter`` golden
        steps leave (4e-10 in n at 40), by Brent's method (parabolic
        steps, golden fallback; about 15 evaluations), compiled or in
        numpy alike.  Fewer iterations leave
        the noise-free optimum visibly short where a bound becomes active
        at n* (kc = 0 or cc = 0): the SSE over n has a kink in curvature
        there, which a parabola does not model.
    noise_floor : float
        Relative noise floor for the n interval (see :mod:`exact`).
    kc_over_kphi : float, optional
        Hold kc/kphi [m] fixed (a calibration): the kc column folds into
        the kphi column and kc = ratio * kphi.

    Returns
    -------
    ManySolution
        Per-profile parameters [SI], SSE [kPa^2], phic ridge and n interval.

    References
    ----------
    .. [1] Huang et al., eqs. (2-5) to (2-7), section 3.3.2 (see the module).
    """
    ratio = kc_over_kphi
    pb = _problem(depths, cis, cone, law, bounds, ratio)
    P = pb.zz.shape[0]
    ns = grid(bounds.n[0], bounds.n[1], n_grid)
    xg, sseg = pb.cells(np.broadcast_to(ns, (P, ns.size)))  # (P, Nn, F)
    nfev = sseg.size
    flat = sseg.reshape(P, -1)
    k = first_min(flat, 1e-12 * pb.yty)
    i_n, i_f = np.unravel_index(k, sseg.shape[1:])
    sse_n = sseg.min(axis=2)  # (P, Nn)

    n_best = ns[i_n]
    if ns.size > 1:
        n_ref, f_ref, used = _refine_n(pb, ns, sseg, i_n, i_f, refine_iter)
        nfev += used
        n_best = np.where(f_ref <= flat[np.arange(P), k], n_ref, n_best)

    s_best = pb.s_of(pb.phis)[i_f]
    if pb.phis.size > 1:  # refinement of phic between its grid neighbours (bounds cut the ridge)
        s_best, used = _refine_phi(pb, n_best, i_f, refine_iter)
        nfev += used
    x, sse = pb.cells(n_best[:, None], s_best[:, None])
    x = x[:, 0, 0]  # primed values (kc', kphi', cc)
    sse = sse[:, 0, 0]
    nfev += P

    ph, ph_lo, ph_hi = _phic_ridge(pb, x, n_best, s_best)
    s = pb.s_of(ph)
    kphi = x[:, 1] / s
    kc = ratio * kphi if ratio is not None else x[:, 0] / s
    n_lo, n_hi = _n_interval(pb, ns, sse_n, sse, n_best, noise_floor)
    return ManySolution(
        kc, kphi, n_best, x[:, 2], ph, ph_lo, ph_hi, sse, n_lo, n_hi, nfev, ns, sse_n
    )

"""The learning problem's least squares by variable projection (section 3.3.1 of [1]_).

For fixed (n, r_min) every model value is linear in x = (kc, kphi, cc) and
affine in tau = tan(phic): the shear term of eqs. (2-6) and (2-7) multiplies
the kc and kphi columns of the CI design by tan(phic) (fully mobilised or
with a fixed K_cone), and plate pressures do not depend on phic.  So each
design matrix is X_d = Xa_d + tau Xb_d (:func:`tau_designs`), and the
weighted least-squares cost

    F = sum_d w_d ||X_d x - y_d||^2      (w_d = a_d^2 by default)

is minimised over (tau, x) for fixed (n, log r_min) almost in closed form
(:func:`project`: a scan of tau, each value a bounded linear least squares
from Gram terms, then Gauss-Newton in (tau, x) on the residuals themselves).
The outer variables (n, log r_min) then move by Levenberg-Marquardt steps
on the projected residual (:func:`descend`), with Kaufman's Jacobian [2]_
(the residual's derivative with the inner variables' directions projected
out).  Profiling phic out this way removes the long curved valley in
(phic, cc, r_min) that a joint search crawls along: on noise-free data the
outer iteration converges quadratically to a zero residual.

Each row of a batch is an independent search (its own start and r_min
stretch); all rows advance together, every design matrix of an iteration
from one vectorised call.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-6), (2-7), section 3.3.1.
.. [2] Kaufman, L. (1975). A variable projection method for solving separable
   nonlinear least squares problems. BIT 15, 49-57.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from terracone.inverse.learning.search import LearnProblem
from terracone.inverse.solver.boxlsq import box_lsq3

__all__ = ["Projected", "VarproResult", "descend", "project", "tau_designs"]

#: spacing [deg] of the scan of phic in :func:`project`
SCAN_DEG = 1.5

#: Levenberg-Marquardt dampings of :func:`descend` (times the current one; 0: Gauss-Newton)
DAMPINGS = (0.0, 1.0, 64.0)

#: fractions of the Gauss-Newton step that :func:`descend` tries too
BACKTRACK = (0.5, 0.25, 0.125)


def tau_designs(prob: LearnProblem, n, t) -> tuple[list, list]:
    """Design matrices at points (n, log r_min) (K,) as X_d = Xa_d + tan(phic) Xb_d.

    Returns (Xa, Xb), lists over data sets of (K, N_d, 3) arrays.  Fully
    mobilised shear (eq. (2-6)): the CI design at phic scales its kc and
    kphi columns by 1 + tan(phic)/tan(a), so Xb_d is those columns divided by
    tan(a); with a fixed K_cone the columns are affine in tan(phic) too, and
    Xb_d is the difference of the designs at phic = 45 deg and 0.
    """
    n = np.asarray(n, float)
    t = np.asarray(t, float)
    k = len(prob.profiles)
    if prob.K_cone is None:
        Xa = prob.designs(n, np.zeros_like(n), t)
        Xb = [
            X * (np.array([1.0, 1.0, 0.0]) / math.tan(p.cone.half_angle))
            for X, p in zip(Xa[:k], prob.profiles)
        ]
        return Xa, Xb + [np.zeros_like(X) for X in Xa[k:]]
    both = prob.designs(np.concatenate([n, n]), np.repeat([0.0, 45.0], n.size), np.tile(t, 2))
    tan45 = math.tan(math.radians(45.0))
    Xa = [X[: n.size] for X in both]
    Xb = [(X[n.size :] - X[: n.size]) / tan45 for X in both]
    return Xa, Xb


def _stack(prob: LearnProblem, Xa, Xb, sw):
    """Weighted stacked designs Aa, Ab (K, N, 3) and data b (K, N); sw (K, D) = sqrt(w_d)."""
    Aa = np.concatenate([sw[:, d, None, None] * X for d, X in enumerate(Xa)], axis=1)
    Ab = np.concatenate([sw[:, d, None, None] * X for d, X in enumerate(Xb)], axis=1)
    b = np.concatenate([sw[:, d, None] * y for d, y in enumerate(prob.ys)], axis=1)
    return Aa, Ab, b


@dataclass
class Projected:
    """The inner minimum of :func:`project` per row: tau = tan(phic), x, residual, cost."""

    tau: np.ndarray  # (K,)
    x: np.ndarray  # (K, 3)
    r: np.ndarray  # (K, N) weighted residuals
    F: np.ndarray  # (K,)

    def take(self, sel) -> Projected:
        return Projected(self.tau[sel], self.x[sel], self.r[sel], self.F[sel])


def _scan(Aa, Ab, b, lo, hi, taus):
    """Bounded least squares at every tau of ``taus`` (K, S), from Gram terms:
    (x (K, S, 3), F (K, S))."""
    P = np.einsum("kni,knj->kij", Aa, Aa)
    Q = np.einsum("kni,knj->kij", Aa, Ab)
    R = np.einsum("kni,knj->kij", Ab, Ab)
    ga, gb = np.einsum("kni,kn->ki", Aa, b), np.einsum("kni,kn->ki", Ab, b)
    yy = np.einsum("kn,kn->k", b, b)
    T = taus[..., None, None]
    G = P[:, None] + T * (Q + np.swapaxes(Q, 1, 2))[:, None] + T * T * R[:, None]
    g = ga[:, None] + taus[..., None] * gb[:, None]
    return box_lsq3(G, g, yy[:, None], lo[:, None], hi[:, None])


def _residual(Aa, Ab, b, tau, x):
    return np.einsum("kni,ki->kn", Aa + tau[:, None, None] * Ab, x) - b


def _inner_gn(Aa, Ab, b, lo, hi, tlo, thi, tau, x, steps: int = 3):
    """Gauss-Newton in (tau, x) on the residuals themselves (bilinear in them), from a
    start near the minimum; variables on a bound stay there unless the gradient points
    inwards; a step is kept where it lowers the cost.  (tau, x, r, F)."""
    r = _residual(Aa, Ab, b, tau, x)
    F = np.einsum("kn,kn->k", r, r)
    for _ in range(steps):
        A = Aa + tau[:, None, None] * Ab
        C = np.concatenate([A, np.einsum("kni,ki->kn", Ab, x)[..., None]], axis=2)  # (K, N, 4)
        grad = np.einsum("kni,kn->ki", C, r)
        v = np.concatenate([x, tau[:, None]], axis=1)
        vlo = np.concatenate([lo, tlo[:, None]], axis=1)
        vhi = np.concatenate([hi, thi[:, None]], axis=1)
        free = ((v > vlo) | (grad < 0)) & ((v < vhi) | (grad > 0)) & (vhi > vlo)
        H = np.einsum("kni,knj->kij", C, C)
        d = np.sqrt(np.maximum(np.einsum("kii->ki", H), 1e-300))
        Hs = H / (d[:, :, None] * d[:, None, :]) + 1e-13 * np.eye(4)
        Hs = np.where(free[:, :, None] & free[:, None, :], Hs, np.eye(4))
        step = -np.linalg.solve(Hs, np.where(free, grad / d, 0.0)[..., None])[..., 0] / d
        vn = np.clip(v + step, vlo, vhi)
        xn, tn = vn[:, :3], vn[:, 3]
        rn = _residual(Aa, Ab, b, tn, xn)
        Fn = np.einsum("kn,kn->k", rn, rn)
        ok = Fn < F
        if not ok.any():
            break
        tau, x = np.where(ok, tn, tau), np.where(ok[:, None], xn, x)
        r, F = np.where(ok[:, None], rn, r), np.where(ok, Fn, F)
    return tau, x, r, F


def project(Aa, Ab, b, lo, hi, tlo, thi, tau0=None) -> Projected:
    """Minimum of ||(Aa + tau Ab) x - b||^2 over tlo <= tau <= thi and lo <= x <= hi, per row.

    tau is scanned (phic every ``SCAN_DEG``, and ``tau0`` when given), each
    value's x a bounded linear least squares from Gram terms (exact per
    value); the best value is refined by a parabola through its neighbours,
    then by Gauss-Newton in (tau, x) on the residuals (:func:`_inner_gn`), so
    that a zero residual is reached to rounding rather than to the Gram
    terms' resolution.
    """
    K = b.shape[0]
    plo, phi = np.degrees(np.arctan(tlo)), np.degrees(np.arctan(thi))
    m = max(2, int(math.ceil(float(np.max(phi - plo, initial=0.0)) / SCAN_DEG)) + 1)
    taus = np.tan(np.radians(plo[:, None] + (phi - plo)[:, None] * np.linspace(0.0, 1.0, m)))
    if tau0 is not None:
        taus = np.concatenate([taus, np.clip(tau0, tlo, thi)[:, None]], axis=1)
    xs, F = _scan(Aa, Ab, b, lo, hi, taus)
    j = np.argmin(F, axis=1)
    rows = np.arange(K)
    tau, x, Fb = taus[rows, j], xs[rows, j], F[rows, j]
    # parabola through the best scan node and its neighbours
    inner = (j > 0) & (j < m - 1)
    jj = np.clip(j, 1, m - 2)
    t0, t1, t2 = taus[rows, jj - 1], taus[rows, jj], taus[rows, jj + 1]
    f0, f1, f2 = F[rows, jj - 1], F[rows, jj], F[rows, jj + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        num = (t1 - t0) ** 2 * (f1 - f2) - (t1 - t2) ** 2 * (f1 - f0)
        den = (t1 - t0) * (f1 - f2) - (t1 - t2) * (f1 - f0)
        tv = np.where(inner & (den != 0), t1 - 0.5 * num / den, t1)
    tv = np.clip(np.nan_to_num(tv, nan=0.0), t0, t2)
    xv, Fv = _scan(Aa, Ab, b, lo, hi, tv[:, None])
    better = inner & (Fv[:, 0] < Fb)
    tau, x = np.where(better, tv, tau), np.where(better[:, None], xv[:, 0], x)
    tau, x, r, F = _inner_gn(Aa, Ab, b, lo, hi, tlo, thi, tau, x)
    return Projected(tau, x, r, F)


@dataclass
class VarproResult:
    """The end of :func:`descend` per row: theta = (n, phic [deg], log r_min), x = (kc, kphi,
    cc), the least-squares cost F, J = sum_d a_d ||r_d||, and the work done."""

    theta: np.ndarray  # (K, 3)
    x: np.ndarray  # (K, 3)
    F: np.ndarray  # (K,)
    J: np.ndarray  # (K,)
    iterations: int
    evaluations: int


class _Rows:
    """The batch of :func:`descend`: bounds of (n, log r_min) per row and the evaluator."""

    def __init__(self, prob: LearnProblem, t_lo, t_hi, t_free, w):
        self.prob = prob
        K = t_lo.size
        self.sw = np.sqrt(np.broadcast_to(w, (K, len(prob.ys))))
        self.lo = np.stack([np.full(K, prob.theta_lo[0]), t_lo], axis=1)
        self.hi = np.stack([np.full(K, prob.theta_hi[0]), t_hi], axis=1)
        self.free = np.stack([self.hi[:, 0] > self.lo[:, 0], t_free & (t_hi > t_lo)], axis=1)
        tl, th = np.radians(prob.theta_lo[1]), np.radians(prob.theta_hi[1])
        self.tau_lo, self.tau_hi = np.full(K, math.tan(tl)), np.full(K, math.tan(th))
        sizes = [y.size for y in prob.ys]
        self.edges = np.concatenate([[0], np.cumsum(sizes)])

    def designs(self, rows, U):
        """Stacked weighted designs of rows ``rows`` at points U (len(rows), 2)."""
        Xa, Xb = tau_designs(self.prob, U[:, 0], U[:, 1])
        return _stack(self.prob, Xa, Xb, self.sw[rows])

    def evaluate(self, rows, U, tau0=None):
        """The inner minimum at points U of rows ``rows``, and the designs there."""
        Aa, Ab, b = self.designs(rows, U)
        lo, hi = self.prob.box(U[:, 0])
        pr = project(Aa, Ab, b, lo, hi, self.tau_lo[rows], self.tau_hi[rows], tau0)
        return pr, (Aa, Ab)

    def J(self, rows, r) -> np.ndarray:
        """J = sum_d a_d ||r_d|| from weighted residuals (K, N)."""
        out = np.zeros(r.shape[0])
        for d, a in enumerate(self.prob.a):
            blk = r[:, self.edges[d] : self.edges[d + 1]]
            out += a * np.sqrt(np.einsum("kn,kn->k", blk, blk)) / self.sw[rows, d]
        return out


def _inner_directions(rows: _Rows, idx, U, pr: Projected, Aa, Ab) -> np.ndarray:
    """Orthonormal directions (K, N, 4) of the inner variables (x, tau) at the rows' points,
    those held on a bound (gradient pointing out of the box) left out (zero columns)."""
    A = Aa + pr.tau[:, None, None] * Ab
    C = np.concatenate([A, np.einsum("kni,ki->kn", Ab, pr.x)[..., None]], axis=2)
    lo, hi = rows.prob.box(U[:, 0])
    v = np.concatenate([pr.x, pr.tau[:, None]], axis=1)
    vlo = np.concatenate([lo, rows.tau_lo[idx, None]], axis=1)
    vhi = np.concatenate([hi, rows.tau_hi[idx, None]], axis=1)
    grad = np.einsum("kni,kn->ki", C, pr.r)
    inside = ((v > vlo) | (grad < 0)) & ((v < vhi) | (grad > 0)) & (vhi > vlo)
    norm = np.linalg.norm(C, axis=1)  # columns to unit length: the rank test sees directions
    C = C * (inside / np.where(norm > 0, norm, 1.0))[:, None, :]
    Uc, s, _ = np.linalg.svd(C, full_matrices=False)
    keep = s > 1e-10 * np.max(s, axis=1, keepdims=True, initial=1e-300)
    return Uc * keep[:, None, :]


def _projected_jacobian(rows: _Rows, idx, U, pr: Projected, Aa, Ab) -> np.ndarray:
    """Kaufman's Jacobian (K, N, 2) of the projected residual in (n, log r_min): central
    differences of the residual at fixed (tau, x) (one-sided on a bound), the inner
    variables' directions (:func:`_inner_directions`) projected out."""
    h = 1e-6 * np.maximum(1.0, np.abs(U))
    S = np.repeat(U[:, None, :], 4, axis=1)  # +n, -n, +t, -t
    for k in range(2):
        S[:, 2 * k, k] += h[:, k]
        S[:, 2 * k + 1, k] -= h[:, k]
    S = np.clip(S, rows.lo[idx, None], rows.hi[idx, None])
    Sa, Sb, b = rows.designs(np.repeat(idx, 4), S.reshape(-1, 2))
    rs = _residual(Sa, Sb, b, np.repeat(pr.tau, 4), np.repeat(pr.x, 4, axis=0))
    rs = rs.reshape(U.shape[0], 4, -1)
    D = np.zeros((U.shape[0], rs.shape[2], 2))
    for k in range(2):
        dk = S[:, 2 * k, k] - S[:, 2 * k + 1, k]
        ok = rows.free[idx, k] & (dk > 0)
        D[:, :, k] = (rs[:, 2 * k] - rs[:, 2 * k + 1]) * (ok / np.where(ok, dk, 1.0))[:, None]
    Q = _inner_directions(rows, idx, U, pr, Aa, Ab)
    return D - np.einsum("kni,kim->knm", Q, np.einsum("kni,knm->kim", Q, D))


def _lm_candidates(Dp, r, U, lo, hi, free, mu):
    """Levenberg-Marquardt steps in (n, log r_min) at the dampings ``mu * DAMPINGS``
    (Marquardt's diagonal scaling), the Gauss-Newton step shortened by ``BACKTRACK``,
    and steps in n alone and in log r_min alone at damping ``mu``, clipped to the box:
    points (K, L, 2) and dampings (K, L).

    The one-variable steps matter where log r_min is weakly determined (its curvature a
    millionth of n's): a joint step then throws it across the stretch, however damped.
    The shortened steps matter where the inner minimum's active set changes (phic or cc
    reaching its bound): F(log r_min) then bends sharply, the Gauss-Newton step of the
    gentle side overshoots into the steep one, and damping, scaled to each variable's
    curvature, does not shorten it.
    """
    H = np.einsum("kni,knj->kij", Dp, Dp)
    g = np.einsum("kni,kn->ki", Dp, r)
    # a variable on a bound that the gradient pushes outwards stays there
    free = free & ~(((U <= lo) & (g > 0)) | ((U >= hi) & (g < 0)))
    f2 = free[:, :, None] & free[:, None, :]
    sd = np.sqrt(np.maximum(np.where(free, np.einsum("kii->ki", H), 1.0), 1e-300))
    H = np.where(f2, H, np.eye(2)) / (sd[:, :, None] * sd[:, None, :])
    g = np.where(free, g, 0.0) / sd
    lams = mu[:, None] * np.array(DAMPINGS)[None, :]
    M = H[:, None] + (lams[..., None, None] + 1e-12) * np.eye(2)
    step = -np.linalg.solve(M, np.broadcast_to(g[:, None, :, None], M.shape[:-1] + (1,)))[..., 0]
    one = -g[:, None, :] * np.eye(2)[None] / (1.0 + mu)[:, None, None]  # unit diagonal
    short = step[:, :1] * np.array(BACKTRACK)[None, :, None]  # Gauss-Newton's, shortened
    step = np.concatenate([step, short, one], axis=1)
    lams = np.concatenate([lams, np.repeat(mu[:, None], 2 + len(BACKTRACK), axis=1)], axis=1)
    P = U[:, None, :] + step / sd[:, None, :]
    return np.clip(P, lo[:, None], hi[:, None]), lams


#: fractions of a stretch at which a row stopped on an end of it probes the inside
PROBES = (1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0, 1.0 / 2.0, 3.0 / 4.0)


@dataclass
class _State:
    """The rows' current points (n, log r_min), inner minima, designs and step control."""

    U: np.ndarray
    pr: Projected
    Aa: np.ndarray
    Ab: np.ndarray
    mu: np.ndarray
    fails: np.ndarray
    probes: np.ndarray

    def move(self, rows, P, cand: Projected, Ca, Cb) -> None:
        """Rows ``rows`` go to points P with inner minima ``cand`` and designs (Ca, Cb)."""
        self.U[rows] = P
        pr = self.pr
        pr.tau[rows], pr.x[rows], pr.r[rows], pr.F[rows] = cand.tau, cand.x, cand.r, cand.F
        self.Aa[rows], self.Ab[rows] = Ca, Cb
        self.fails[rows] = 0


def _probe(rows: _Rows, st: _State, idx) -> np.ndarray:
    """Rows ``idx`` stopped on an end of their stretch of log r_min: F at points inside it
    (``PROBES`` of its length from that end, n kept); each row moves to the best if it is
    lower.  An RM1 branch point can be a stationary point of F in r_min (at the larger plate
    the tangent meets the secant with its slope), which no step from derivatives leaves.
    Returns the rows that moved."""
    at_hi = st.U[idx, 1] >= rows.hi[idx, 1]
    span = rows.hi[idx, 1] - rows.lo[idx, 1]
    t = np.where(at_hi, rows.hi[idx, 1], rows.lo[idx, 1])
    f = np.array(PROBES)
    T = t[:, None] + np.where(at_hi, -1.0, 1.0)[:, None] * span[:, None] * f
    L = f.size
    P = np.stack([np.repeat(st.U[idx, 0], L), T.reshape(-1)], axis=1)
    cand, (Ca, Cb) = rows.evaluate(np.repeat(idx, L), P, np.repeat(st.pr.tau[idx], L))
    k = np.argmin(cand.F.reshape(-1, L), axis=1)
    p = np.arange(idx.size) * L + k
    ok = cand.F[p] < st.pr.F[idx]
    st.move(idx[ok], P[p[ok]], cand.take(p[ok]), Ca[p[ok]], Cb[p[ok]])
    st.mu[idx[ok]] = 1e-3
    st.probes[idx] += 1
    return idx[ok]


def descend(
    prob: LearnProblem,
    theta0: np.ndarray,
    t_lo: np.ndarray,
    t_hi: np.ndarray,
    t_free: np.ndarray,
    *,
    w: np.ndarray | None = None,
    max_iter: int = 40,
    stop_at_zero: bool = True,
) -> VarproResult:
    """Minimise F = sum_d w_d ||r_d||^2 from each row's start, (tan(phic), x) projected out.

    Parameters
    ----------
    prob : LearnProblem
    theta0 : (K, 3) ndarray
        Starts (n, phic [deg], log r_min); phic only seeds the inner scan.
    t_lo, t_hi : (K,) ndarray
        Each row's range of log r_min (an RM1 stretch between branch points).
    t_free : (K,) bool ndarray
        False where log r_min is held (RM0, or above the larger plate where J
        does not depend on it).
    w : (D,) ndarray, optional
        Weights w_d (default a_d^2, as J weighs the data sets).
    max_iter : int
        Most outer iterations.
    stop_at_zero : bool
        Stop every row as soon as one reaches a zero residual (J >= 0 makes
        it the global minimum).

    Returns
    -------
    VarproResult
        Each row's end point, converged when the cost is zero to rounding,
        falls by less than 1e-12 relative, or no damping lowers it (after up
        to two probes inside its stretch when it stopped on an end of it,
        :func:`_probe`).
    """
    w = prob.a**2 if w is None else np.asarray(w, float)
    rows = _Rows(prob, np.asarray(t_lo, float), np.asarray(t_hi, float), np.asarray(t_free), w)
    K = theta0.shape[0]
    U = np.clip(theta0[:, [0, 2]], rows.lo, rows.hi)
    pr, (Aa, Ab) = rows.evaluate(np.arange(K), U, np.tan(np.radians(theta0[:, 1])))
    st = _State(U, pr, Aa, Ab, np.full(K, 1e-3), np.zeros(K, int), np.zeros(K, int))
    zero = 1e-13 * float(sum(a * np.linalg.norm(y) for a, y in zip(prob.a, prob.ys)))
    active = rows.J(np.arange(K), pr.r) > zero
    nev, it = K, 0
    done = stop_at_zero and not active.all()  # a start fitted exactly
    while it < max_iter and not done:
        it += 1
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        cur = pr.take(idx)
        Dp = _projected_jacobian(rows, idx, st.U[idx], cur, st.Aa[idx], st.Ab[idx])
        P, lams = _lm_candidates(
            Dp, cur.r, st.U[idx], rows.lo[idx], rows.hi[idx], rows.free[idx], st.mu[idx]
        )
        L = P.shape[1]
        cand, (Ca, Cb) = rows.evaluate(np.repeat(idx, L), P.reshape(-1, 2), np.repeat(cur.tau, L))
        nev += idx.size * (L + 4)
        k = np.argmin(cand.F.reshape(-1, L), axis=1)
        p = np.arange(idx.size) * L + k
        gain = cand.F[p] < cur.F
        lost = idx[~gain]  # no damping gains: more damping next time, until three misses
        st.mu[lost] = np.maximum(64.0 * st.mu[lost], 1.0)
        st.fails[lost] += 1
        won, p = idx[gain], p[gain]
        st.move(won, P.reshape(-1, 2)[p], cand.take(p), Ca[p], Cb[p])
        lam = lams[gain, k[gain]]
        st.mu[won] = np.where(lam > 0, lam, np.maximum(st.mu[won] / 64.0, 1e-9))
        Jw = rows.J(won, pr.r[won])
        active[won] = (cur.F[gain] - cand.F[p] > 1e-12 * cand.F[p]) & (Jw > zero)
        active[lost] = st.fails[lost] < 3
        # rows that stop on an end of their stretch probe its inside (twice at most)
        J = rows.J(idx, pr.r[idx])
        t = st.U[idx, 1]
        end = rows.free[idx, 1] & ((t <= rows.lo[idx, 1]) | (t >= rows.hi[idx, 1]))
        stuck = idx[~active[idx] & end & (st.probes[idx] < 2) & (J > zero)]
        if stuck.size:
            nev += stuck.size * len(PROBES)
            active[_probe(rows, st, stuck)] = True
        done = stop_at_zero and bool(np.any(J <= zero))
    theta = np.stack([st.U[:, 0], np.degrees(np.arctan(pr.tau)), st.U[:, 1]], axis=1)
    return VarproResult(theta, pr.x, pr.F, rows.J(np.arange(K), pr.r), it, nev)

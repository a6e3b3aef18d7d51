"""Global search of the learning objective (section 3.3.1 of [1]_).

J(kc, kphi, n, cc, phic, r_min) = sum_d RMSD_d / mean_d over data sets d
(each CI profile and each plate test).  For fixed theta = (n, phic, r_min)
J is convex in x = (kc, kphi, cc) and is minimised with a certificate by
:func:`terracone.inverse.learning.sumnorm.sum_norm_box`.  theta is searched on a
vectorised grid (n, phic, log r_min) whose log r_min nodes are laid out per
stretch between RM1 branch points (:func:`stretches`, :func:`r_axis`); each
stretch's best grid points (:func:`stretch_starts`) start the least squares of
:mod:`terracone.inverse.learning.varpro`, whose end points start
:func:`refine` (Levenberg-Marquardt steps on J itself, every candidate step of
an iteration evaluated in one vectorised call, log r_min held in its stretch),
and the grid with a branch and bound (:func:`certify`) gives a bound on how far
the answer can be from the global minimum.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7), sections 3.2 and 3.3.1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import minimum_filter

from terracone.data import CIProfile, PlateTest
from terracone.inverse.bounds import Bounds
from terracone.inverse.learning.kernels import cone_columns
from terracone.inverse.learning.sumnorm import SumNormResult, sum_norm_box
from terracone.inverse.solver.boxlsq import gram
from terracone.inverse.solver.columns import design
from terracone.jit import enabled
from terracone.physics.plate import plate_basis, pressure_law

__all__ = [
    "branch_points",
    "certify",
    "Cells",
    "flat_set",
    "secant_twin",
    "jacobians",
    "objectives",
    "polish",
    "LearnProblem",
    "GridStage",
    "Refined",
    "grid_stage",
    "r_axis",
    "refine",
    "Starts",
    "Stretch",
    "stretch_starts",
    "stretches",
]


@dataclass
class LearnProblem:
    """The data and search space of one learning run (SI).

    theta = (n, phic [deg], log r_min [log m]); for RM0 r_min is absent and
    the third coordinate is ignored.
    """

    profiles: list[CIProfile]
    plates: list[PlateTest]
    model: str
    bounds: Bounds
    r_min_bounds: tuple[float, float] | None
    K_cone: float | None
    pair: tuple[float, float] | None

    def __post_init__(self) -> None:
        self.ys = [p.ci for p in self.profiles] + [b.pressure for b in self.plates]
        self.means = np.array([float(np.mean(y)) for y in self.ys])
        # J = sum_d a_d ||r_d||, a_d = 1 / (mean_d sqrt(N_d))
        self.a = np.array([1.0 / (m * math.sqrt(y.size)) for m, y in zip(self.means, self.ys)])
        lo = [self.bounds.n[0], self.bounds.phic_deg[0]]
        hi = [self.bounds.n[1], self.bounds.phic_deg[1]]
        rb = self.r_min_bounds or (1.0, 1.0)
        self.theta_lo = np.array(lo + [math.log(rb[0])])
        self.theta_hi = np.array(hi + [math.log(rb[1])])

    def law(self, log_rm):
        if self.model == "rm0":
            return pressure_law("rm0")
        return pressure_law("rm1", r_min=np.exp(log_rm), plate_pair=self.pair)

    def designs(self, n, phi, log_rm) -> list[np.ndarray]:
        """Design matrices X_d (S..., N_d, 3) with model_d = X_d @ (kc, kphi, cc)."""
        n, phi, log_rm = np.broadcast_arrays(*(np.asarray(v, float) for v in (n, phi, log_rm)))
        law = self.law(log_rm[..., None])
        out = []
        for p in self.profiles:
            if self.K_cone is None and enabled():
                out.append(self._cone_design(p, n, phi, law))
                continue
            X = design(
                p.depth, n[..., None], phi[..., None], cone=p.cone, law=law, K_cone=self.K_cone
            )
            out.append(np.broadcast_to(X, n.shape + X.shape[-2:]))
        for b in self.plates:
            A, B = plate_basis(b.sinkage, n=n[..., None], b=b.b, law=law)
            A, B = np.broadcast_arrays(A, B)
            out.append(np.stack([A, B, np.zeros_like(A)], axis=-1))
        return out

    @staticmethod
    def _cone_design(p: CIProfile, n, phi, law) -> np.ndarray:
        """X of one CI profile at points of one shape S (fully mobilised shear), compiled:
        (S..., Z, 3), as :func:`terracone.inverse.solver.columns.design`."""
        coef = [np.broadcast_to(c, n.shape + (1,)).reshape(-1) for c in law.coefficients()]
        A, B, C = cone_columns(
            np.ascontiguousarray(p.depth, dtype=float),
            np.ascontiguousarray(n, dtype=float).reshape(-1),
            p.cone.height,
            p.cone.radius,
            not law.is_rm0,
            *(np.ascontiguousarray(c, dtype=float) for c in coef),
        )
        # eq. (2-6) fully mobilised: phic only scales the kc and kphi columns
        s = (1.0 + np.tan(np.radians(phi)) / math.tan(p.cone.half_angle)).reshape(-1, 1)
        return np.stack([s * A, s * B, C], axis=-1).reshape(n.shape + (p.depth.size, 3))

    def grams(self, n, phi, log_rm):
        Gs, gs, yys = [], [], []
        for X, y in zip(self.designs(n, phi, log_rm), self.ys):
            G, g, yy = gram(X, np.broadcast_to(y, X.shape[:-1]))
            Gs.append(G)
            gs.append(g)
            yys.append(yy)
        return np.stack(Gs), np.stack(gs), np.stack(yys)

    def box(self, n, cc_pin=None):
        """Bounds (lo, hi) of x = (kc, kphi, cc) at exponent n, shape (S..., 3)."""
        n = np.asarray(n, float)
        kl, kh = self.bounds.kc_si(n)
        pl, ph = self.bounds.kphi_si(n)
        pin = np.full(n.shape, np.nan) if cc_pin is None else cc_pin + 0 * n  # NaN: free
        cl = np.where(np.isnan(pin), self.bounds.cc[0], pin)
        ch = np.where(np.isnan(pin), self.bounds.cc[1], pin)
        return np.stack([kl, pl, cl], axis=-1), np.stack([kh, ph, ch], axis=-1)

    def solve_cells(self, n, phi, log_rm, cc_pin=None, rtol=1e-7, max_iter=200) -> SumNormResult:
        """Certified inner minimum over x for each theta (arrays of one shape)."""
        G, g, yy = self.grams(n, phi, log_rm)
        lo, hi = self.box(np.broadcast_to(n, yy.shape[1:]), cc_pin)
        return sum_norm_box(G, g, yy, self.a, lo, hi, rtol=rtol, max_iter=max_iter)

    def residuals(self, x, theta) -> list[np.ndarray]:
        Xs = self.designs(theta[0], theta[1], theta[2])
        return [X @ x - y for X, y in zip(Xs, self.ys)]

    def objective(self, x, theta) -> float:
        """J from the residuals themselves (not the Gram form)."""
        return float(sum(a * np.linalg.norm(r) for a, r in zip(self.a, self.residuals(x, theta))))


@dataclass
class GridStage:
    """The vectorised grid over theta and its certified inner solutions."""

    axes: list[np.ndarray]  # n, phic, log r_min values
    cells: SumNormResult


def _axis(lo: float, hi: float, k: int) -> np.ndarray:
    return np.array([lo]) if lo == hi or k <= 1 else np.linspace(lo, hi, k)


@dataclass
class Stretch:
    """A stretch [lo, hi] of log r_min between RM1 branch points, where J is smooth in r_min.

    ``flat``: above the larger plate, where the law is the secant through both
    plates' pressures and J does not depend on r_min (the stretch is then
    (lo, hi], lo the larger plate); ``rep`` is the value reported there.
    RM0 has one flat stretch of zero width.
    """

    lo: float
    hi: float
    flat: bool

    @property
    def rep(self) -> float:
        """The middle of the stretch: the value of log r_min reported on a flat one."""
        return 0.5 * (self.lo + self.hi)


def stretches(prob: LearnProblem) -> list[Stretch]:
    """The stretches of the log r_min range between the RM1 branch points (section 3.2).

    The cone radii and the smaller plate change the branch of some data set
    (J is continuous there, its curvature jumps); above the larger plate the
    law is the secant, where J is flat in r_min.  RM0: one stretch, flat.
    """
    lo, hi = float(prob.theta_lo[2]), float(prob.theta_hi[2])
    if prob.model != "rm1" or lo == hi:
        return [Stretch(lo, hi, True)]
    ks = [k for k in branch_points(prob) if lo < k < hi]
    ends = [lo] + ks + [hi]
    r2 = math.log(max(prob.pair)) if prob.pair else math.inf
    return [Stretch(a, b, a >= r2) for a, b in zip(ends[:-1], ends[1:])]


def flat_set(prob: LearnProblem, t: float) -> tuple[float, float] | None:
    """The stretch (lo, hi] of log r_min holding t when J does not depend on r_min there
    (RM1 above the larger plate), else None."""
    if prob.model != "rm1":
        return None
    for st in stretches(prob):
        if st.flat and st.hi > st.lo and st.lo < t <= st.hi:
            return st.lo, st.hi
    return None


def secant_twin(prob: LearnProblem, x, theta) -> tuple[np.ndarray, np.ndarray] | None:
    """The other parameters that give the same model values as (x, theta) on the secant set.

    For r <= r2 the secant through both plates' Bekker pressures with (kc, kphi)
    (r_min > r2) and the tangent at r_min = r2 with (kc r2/r1, kphi + kc/r2 - kc/r1)
    are the same line in r (section 3.2: both pass through the two plates'
    pressures and the tangent's slope -kc'/r2^2 equals the secant's -kc/(r1 r2)).
    So when every cone's base radius is at most r2, data fitted on one side are
    fitted exactly as well on the other: the data cannot tell kc and kphi apart.
    Returns the twin (x, theta) (r_min = r2 for a secant answer, the middle of the
    secant set for an answer at r2) when it lies within the bounds, else None.
    """
    if prob.model != "rm1" or not prob.pair:
        return None
    r1, r2 = prob.pair
    t2 = math.log(r2)
    if max(p.cone.radius for p in prob.profiles) > r2 or not prob.theta_lo[2] <= t2:
        return None
    kc, kphi = float(x[0]), float(x[1])
    flat = flat_set(prob, float(theta[2]))
    if flat is not None:  # secant with (kc, kphi): the tangent at r2
        twin = [kc * r2 / r1, kphi + kc / r2 - kc / r1, t2]
    elif abs(float(theta[2]) - t2) <= 1e-9 and prob.theta_hi[2] > t2:  # tangent at r2
        kc_s = kc * r1 / r2
        twin = [kc_s, kphi - kc_s / r2 + kc_s / r1, 0.5 * (t2 + float(prob.theta_hi[2]))]
    else:
        return None
    lo, hi = prob.box(np.asarray(theta[0]))
    xt = np.array([twin[0], twin[1], float(x[2])])
    if np.any(xt < lo - 1e-12 * np.abs(lo)) or np.any(xt > hi + 1e-12 * np.abs(hi)):
        return None
    return xt, np.array([theta[0], theta[1], twin[2]])


def r_axis(prob: LearnProblem, k: int) -> np.ndarray:
    """The grid's log r_min nodes: every stretch's ends and nodes inside it no further apart
    than ``k`` even nodes over the range would be; one node (the range's end) where J is
    flat in r_min."""
    lo, hi = float(prob.theta_lo[2]), float(prob.theta_hi[2])
    if prob.model != "rm1" or lo == hi or k <= 1:
        return np.array([lo])
    step = (hi - lo) / (k - 1)
    nodes = [np.array([lo, hi])]
    for st in stretches(prob):
        if not st.flat:
            nodes.append(np.linspace(st.lo, st.hi, max(1, math.ceil((st.hi - st.lo) / step)) + 1))
    return np.unique(np.concatenate(nodes))


def grid_stage(prob: LearnProblem, grid: tuple[int, int, int]) -> GridStage:
    """Certified inner minima on the (n, phic, log r_min) grid (log r_min: :func:`r_axis`)."""
    axes = [_axis(prob.theta_lo[k], prob.theta_hi[k], grid[k]) for k in range(2)]
    axes.append(r_axis(prob, grid[2]))
    N, P, R = np.meshgrid(*axes, indexing="ij")
    return GridStage(axes, prob.solve_cells(N, P, R))


@dataclass
class Starts:
    """Starts of the local searches, one row each: theta (K, 3), x (K, 3), the row's stretch."""

    theta: np.ndarray
    x: np.ndarray
    stretch: list[Stretch]

    @property
    def t_lo(self) -> np.ndarray:
        return np.array([s.lo for s in self.stretch])

    @property
    def t_hi(self) -> np.ndarray:
        return np.array([s.hi for s in self.stretch])

    @property
    def t_free(self) -> np.ndarray:
        return np.array([not s.flat for s in self.stretch])


def _stretch_cells(stage: GridStage, st: Stretch):
    """A stretch's stretches between grid nodes, as starts: J (n, phic, K) the smaller of
    each interval's two end nodes, its middle t (K,), and the node of the smaller J
    (n, phic, K).  A flat stretch: its nodes, t its reported value."""
    U, r = stage.cells.J, stage.axes[2]
    if st.flat:
        cols = np.flatnonzero(((r > st.lo) | (st.hi == st.lo)) & (r <= st.hi))
        return (
            U[:, :, cols],
            np.full(cols.size, st.rep),
            np.broadcast_to(cols, U.shape[:2] + cols.shape),
        )
    cols = np.flatnonzero((r >= st.lo) & (r <= st.hi))
    a, b = cols[:-1], cols[1:]
    node = np.where(U[:, :, a] <= U[:, :, b], a, b)
    return np.minimum(U[:, :, a], U[:, :, b]), 0.5 * (r[a] + r[b]), node


def stretch_starts(prob: LearnProblem, stage: GridStage, count: int) -> Starts:
    """Per stretch of log r_min, up to ``count`` starts, best first (ties by position): the
    middles of the intervals between its grid nodes whose J (the smaller at their ends) is
    a local minimum over (n, phic) and the intervals, n and phic of that node.

    A start is never a node itself: an RM1 branch point can be a stationary point of the
    least squares in r_min (at the larger plate the tangent and the secant meet with
    their slopes), where a local search would not move.  A flat stretch's start has r_min
    at its reported value.  Without a node in a stretch, its middle from the grid's best.
    """
    U, ax = stage.cells.J, stage.axes
    theta, xs, rows = [], [], []
    for st in stretches(prob):
        sub, tm, node = _stretch_cells(stage, st)
        if sub.shape[2] == 0:
            i, j, c = np.unravel_index(int(np.argmin(U)), U.shape)
            theta.append([ax[0][i], ax[1][j], st.rep])
            xs.append(stage.cells.x[i, j, c])
            rows.append(st)
            continue
        loc = np.flatnonzero(sub <= minimum_filter(sub, size=3, mode="nearest"))
        # by J quantised to 1e-9 of the scale (last-bit differences do not reorder)
        q = np.floor(sub.reshape(-1)[loc] / (1e-9 * max(float(U.max()), 1e-300)))
        for f in loc[np.lexsort((loc, q))][:count]:
            i, j, c = np.unravel_index(f, sub.shape)
            theta.append([ax[0][i], ax[1][j], tm[c]])
            xs.append(stage.cells.x[i, j, node[i, j, c]])
            rows.append(st)
    return Starts(np.array(theta), np.array(xs), rows)


@dataclass
class Refined:
    """A locally refined point: x = (kc, kphi, cc), theta, J and the cost evaluations."""

    x: np.ndarray
    theta: np.ndarray
    J: float
    nfev: int


def _search_box(prob: LearnProblem, theta0: np.ndarray):
    """Bounds (lo, hi) of p = (kc, kphi, cc, n, phic, log r_min) and the free mask."""
    lo_x, hi_x = prob.box(np.asarray(theta0[0]))
    lo = np.concatenate([lo_x, prob.theta_lo])
    hi = np.concatenate([hi_x, prob.theta_hi])
    free = hi > lo
    if prob.model == "rm0":
        free[5] = False
    return lo, hi, free


def objectives(prob: LearnProblem, P: np.ndarray, power: int = 1) -> np.ndarray:
    """J = sum_d a_d ||r_d|| at many points P (K, 6) = (kc, kphi, cc, n, phic, log r_min),
    in one vectorised call; with ``power`` 2 the least-squares cost sum_d a_d^2 ||r_d||^2."""
    Xs = prob.designs(P[:, 3], P[:, 4], P[:, 5])
    J = np.zeros(P.shape[0])
    for X, y, a in zip(Xs, prob.ys, prob.a):
        r = np.einsum("kij,kj->ki", X, P[:, :3]) - y
        rr = np.einsum("ki,ki->k", r, r)
        J += a * np.sqrt(rr) if power == 1 else a * a * rr
    return J


def _stencil(th: np.ndarray, free: np.ndarray, lo, hi):
    """theta points of :func:`_local_model`'s central differences: (T, 3), the axes
    differenced, their steps and the side of a one-sided log r_min difference (or 0).

    Steps are 1e-4 relative (about the fourth root of the rounding unit, for
    second differences).  log r_min within a step of its stretch's ends (RM1
    branch points, where J jumps) is not differenced across them: it gets a
    one-sided first difference of 1e-6 instead.
    """
    h = 1e-4 * np.maximum(1.0, np.abs(th))
    ks = [k for k in range(3) if free[3 + k]]
    side = 0.0
    if 2 in ks and not (lo[5] + h[2] <= th[2] <= hi[5] - h[2]):
        ks.remove(2)
        side = -1.0 if th[2] + h[2] > hi[5] else 1.0
    pts = [th.copy()]
    for k in ks:
        for sgn in (1.0, -1.0):
            pts.append(th.copy())
            pts[-1][k] += sgn * h[k]
    for i, k in enumerate(ks):
        for m in ks[i + 1 :]:
            for sk, sm in ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)):
                pts.append(th.copy())
                pts[-1][k] += sk * h[k]
                pts[-1][m] += sm * h[m]
    if side:
        pts.append(th.copy())
        pts[-1][2] += side * 1e-6 * max(1.0, abs(th[2]))
    return np.array(pts), ks, h, side


def _local_model(prob: LearnProblem, p: np.ndarray, free: np.ndarray, lo, hi):
    """Residuals r_d, Jacobians D_d (N_d, 6) and second-order terms S_d = sum_i r_di
    Hess(r_di) (6, 6) at p, by central differences in theta (:func:`_stencil`), all
    design matrices in one vectorised call.  r is linear in x = (kc, kphi, cc), so S_d
    has only its theta-x and theta-theta blocks."""
    x, th = p[:3], p[3:]
    T, ks, h, side = _stencil(th, free, lo, hi)
    out = []
    for X, y in zip(prob.designs(T[:, 0], T[:, 1], T[:, 2]), prob.ys):
        r = X[0] @ x - y
        D, S = np.zeros((y.size, 6)), np.zeros((6, 6))
        D[:, :3] = X[0]
        for i, k in enumerate(ks):
            up, down = X[1 + 2 * i], X[2 + 2 * i]
            dX = (up - down) / (2.0 * h[k])
            D[:, 3 + k] = dX @ x
            S[:3, 3 + k] = S[3 + k, :3] = dX.T @ r
            S[3 + k, 3 + k] = r @ ((up - 2.0 * X[0] + down) @ x) / h[k] ** 2
        j = 1 + 2 * len(ks)
        for i, k in enumerate(ks):
            for m in ks[i + 1 :]:
                d2 = (X[j] - X[j + 1] - X[j + 2] + X[j + 3]) @ x / (4.0 * h[k] * h[m])
                S[3 + k, 3 + m] = S[3 + m, 3 + k] = r @ d2
                j += 4
        if side:
            D[:, 5] = (X[-1] - X[0]) @ x / (T[-1, 2] - th[2])
        out.append((r, D, S))
    return out


#: Levenberg-Marquardt dampings of every iteration of :func:`refine`, times the last
#: accepted damping (and no damping: Newton's step)
DAMPINGS = (1.0 / 64.0, 1.0 / 8.0, 1.0, 8.0, 64.0)


def _box_qp(A, g, ls, us, free) -> np.ndarray:
    """Minimiser s of g's + s'As/2 over ls <= s <= us (ls <= 0 <= us; s = 0 where not
    ``free``), by an active set: the free variables solved by Newton (pseudo-inverse),
    those it takes out of the box held on the bound they cross, held ones released when
    their multiplier says the model falls inwards; at most 12 rounds."""
    at_lo = free & (ls >= 0) & (g > 0)
    at_hi = free & (us <= 0) & (g < 0)
    s = np.zeros(g.size)
    for _ in range(12):
        s[:] = 0.0
        s[at_lo], s[at_hi] = ls[at_lo], us[at_hi]
        F = free & ~at_lo & ~at_hi
        if F.any():
            e, V = np.linalg.eigh(A[np.ix_(F, F)])
            tiny = 1e-13 * max(float(np.abs(e).max()), 1e-300)
            rhs = V.T @ (g[F] + A[np.ix_(F, ~F)] @ s[~F])
            s[F] = -(V @ np.where(e > tiny, rhs / np.where(e > tiny, e, 1.0), 0.0))
        out_lo, out_hi = F & (s < ls), F & (s > us)
        if out_lo.any() or out_hi.any():
            at_lo, at_hi = at_lo | out_lo, at_hi | out_hi
            continue
        m = g + A @ s  # the model's gradient: inwards on a held variable, release it
        wrong = np.where((at_lo & (m < 0)) | (at_hi & (m > 0)), np.abs(m), 0.0)
        if not wrong.any():
            break
        k = int(np.argmax(wrong))
        at_lo[k] = at_hi[k] = False
    return np.clip(s, ls, us)


def _lm_steps(H, g, p, lo, hi, free, scale, mu: float):
    """Levenberg-Marquardt steps: minimisers of the model g's + s'(H + lambda m I)s/2 over the
    box (:func:`_box_qp`) in variables scaled by ``scale`` (m the mean curvature,
    lambda = 0 and ``mu`` times ``DAMPINGS``): (steps (L, 6), their lambda)."""
    if not free.any():
        return np.zeros((0, 6)), np.zeros(0)
    Hs, gs = H * np.outer(scale, scale), g * scale
    ls, us = (lo - p) / scale, (hi - p) / scale
    m = max(float(np.trace(Hs[np.ix_(free, free)])) / int(free.sum()), 1e-300)
    lams = np.array([0.0] + [mu * k for k in DAMPINGS])
    # all dampings at once on the free set of the start (one eigen-decomposition); those
    # whose step leaves the box, or pushes a held variable, go through the active set
    f = free & ~(((ls >= 0) & (gs > 0)) | ((us <= 0) & (gs < 0)))
    S = np.zeros((lams.size, 6))
    if f.any():
        e, V = np.linalg.eigh(Hs[np.ix_(f, f)])
        tiny = 1e-13 * max(float(np.abs(e).max()), 1e-300)
        d = e[None, :] + (lams * m)[:, None]
        ok = d > tiny
        S[:, f] = -(np.where(ok, (V.T @ gs[f]) / np.where(ok, d, 1.0), 0.0) @ V.T)
    grad = gs + S @ Hs + (lams * m)[:, None] * S  # the model's gradient at each step
    held = free & ~f
    bad = np.any((S < ls) | (S > us), axis=1) | np.any(
        held & (((ls >= 0) & (grad < 0)) | ((us <= 0) & (grad > 0))), axis=1
    )
    for i in np.flatnonzero(bad):
        S[i] = _box_qp(Hs + lams[i] * m * np.eye(6), gs, ls, us, free)
    return S * scale, lams


def _models(prob: LearnProblem, p, lo, hi, free, power: int = 1) -> list[tuple]:
    """Quadratic models (gradient, Hessian) at p: of J with its Hessian and with its
    Gauss-Newton part sum_d w_d (D_d'D_d - g_d g_d') (w_d = a_d/||r_d||,
    g_d = D_d'r_d/||r_d||; positive semi-definite, but blind to the residuals'
    curvature, which matters with noisy data), and of least squares with weights a_d^2
    (which reaches zero-residual data quadratically; with ``power`` 2 only this)."""
    floor = 1e-14 * np.array([np.linalg.norm(y) for y in prob.ys])
    grad, g_ls = np.zeros(6), np.zeros(6)
    H_J, H_S, H_ls = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros((6, 6))
    for (r, D, S), a, fl in zip(_local_model(prob, p, free, lo, hi), prob.a, floor):
        wd = a / max(float(np.linalg.norm(r)), fl)
        DtD, Dr = D.T @ D, D.T @ r
        gd = Dr * (wd / a)
        grad += wd * Dr
        H_J += wd * (DtD - np.outer(gd, gd))
        H_S += wd * S
        g_ls += a * a * Dr
        H_ls += a * a * (DtD + S)
    if power == 2:
        return [(g_ls, H_ls)]
    return [(grad, H_J + H_S), (grad, H_J), (g_ls, H_ls)]


#: steps of the extrapolation along the last iterates of :func:`refine` (long flat valleys)
EXTRAPOLATE = (1.0, 3.0, 7.0)


def _extrapolated(prob: LearnProblem, hist, lo, hi):
    """Points further along the path of the last iterates in theta (linear and quadratic
    extrapolation by ``EXTRAPOLATE`` steps), each with x = (kc, kphi, cc) the certified
    inner minimum there: (P (K, 6), J (K,))."""
    d1 = hist[-1] - hist[-2]
    acc = d1 - (hist[-2] - hist[-3]) if len(hist) == 3 else np.zeros(3)
    T = [hist[-1] + m * d1 for m in EXTRAPOLATE]
    if len(hist) == 3:
        T += [hist[-1] + m * d1 + 0.5 * m * (m + 1) * acc for m in EXTRAPOLATE]
    T = np.clip(np.array(T), lo[3:], hi[3:])
    sol = prob.solve_cells(T[:, 0], T[:, 1], T[:, 2], rtol=1e-9, max_iter=60)
    P = np.concatenate([sol.x, T], axis=1)
    return P, objectives(prob, P)


def _descend(prob: LearnProblem, p, lo, hi, free, max_iter: int, power=1, tol=1e-14):
    """The iteration of :func:`refine` in one box: (p, J, evaluations, converged).

    ``power`` 2 minimises the least-squares cost instead of J (and returns it); ``tol``
    is the relative fall of the cost below which an iteration ends the search."""
    scale = np.maximum(np.abs(p), np.where(hi > lo, hi - lo, 1.0) * 1e-3)
    J = float(objectives(prob, p[None], power)[0])
    zero = 1e-13 * float(sum(a * np.linalg.norm(y) for a, y in zip(prob.a, prob.ys)))
    nfev, done, mu = 1, False, 1e-3
    hist: list[np.ndarray] = []
    for _ in range(max_iter):
        if J <= zero:  # zero residual: nothing left to gain
            done = True
            break
        hist = (hist + [p[3:].copy()])[-3:]
        if power == 1 and len(hist) >= 2:
            E, Je = _extrapolated(prob, hist, lo, hi)
            k = int(np.argmin(Je)) if Je.size else -1
            if k >= 0 and Je[k] < J:
                done = J - Je[k] <= tol * J
                p, J = E[k], float(Je[k])
                nfev += E.shape[0]
                if done:
                    break
                continue
        models = _models(prob, p, lo, hi, free, power)
        for _ in range(4):  # no step gains: more damping (shorter steps) on the same models
            parts = [_lm_steps(H, g, p, lo, hi, free, scale, mu) for g, H in models]
            steps = np.concatenate([st for st, _ in parts])
            lams = np.concatenate([lm for _, lm in parts])
            if steps.shape[0] == 0:
                break
            P = np.clip(p + steps, lo, hi)
            Jc = objectives(prob, P, power)
            nfev += P.shape[0]
            k = int(np.argmin(Jc))
            if Jc[k] < J:
                break
            mu *= 4096.0
        nfev += 1
        if steps.shape[0] == 0 or not Jc[k] < J:
            done = True
            break
        done = J - Jc[k] <= tol * J
        mu = float(lams[k]) if lams[k] > 0 else max(mu / 64.0, 1e-12)
        p, J = P[k], float(Jc[k])
        if done:
            break
    # values a hair from a bound go onto it when J does not rise
    q = p.copy()
    near_lo, near_hi = q - lo <= 1e-9 * (hi - lo), hi - q <= 1e-9 * (hi - lo)
    q[near_lo], q[near_hi] = lo[near_lo], hi[near_hi]
    Jq = float(objectives(prob, q[None], power)[0])
    if Jq <= J * (1 + 1e-12) + zero * 1e-3:
        p, J = q, Jq
    return p, J, nfev + 1, done


def refine(prob: LearnProblem, x0: np.ndarray, theta0: np.ndarray, st: Stretch) -> Refined:
    """Minimise J jointly over (kc, kphi, cc, n, phic, log r_min) from a start, in the box
    with log r_min in one stretch (held at its reported value where J is flat in it).

    Each iteration first tries points further along the path of the last
    iterates in theta (:func:`_extrapolated`, x re-solved there: noisy RM1
    data often leave a long, flat, curved valley in (phic, cc, r_min) that
    Newton steps follow only slowly) and moves to the best if it lowers J;
    else it takes the residuals, their Jacobian and second differences at
    the current point (one vectorised call of the design matrices), the
    Levenberg-Marquardt steps of three quadratic models (:func:`_models`: J
    with its Hessian, J with its Gauss-Newton part, least squares) at six
    dampings each, every one the exact minimiser of its model over the box
    (:func:`_lm_steps`), then J at all of them (one more vectorised call),
    and moves to the candidate of least J (the damping adapts to it; when
    none gains, more damping on the same models).  Stops when J falls by
    less than 1e-14 relative, on a zero-residual fit or after 100
    iterations.  Values within 1e-9 of their range from a bound then go onto
    it when J does not rise.
    """
    lo, hi, free = _search_box(prob, theta0)
    lo[5], hi[5] = st.lo, st.hi
    if st.flat:
        lo[5] = hi[5] = st.rep
        free[5] = False
    p = np.clip(np.concatenate([x0, theta0]), lo, hi)
    p, J, nfev, _ = _descend(prob, p, lo, hi, free, 100)
    return Refined(p[:3].copy(), p[3:].copy(), J, nfev)


def jacobians(prob: LearnProblem, x, theta) -> list[np.ndarray]:
    """Per data set d/dp of the residuals, p = (kc, kphi, cc, n, phic, log r_min).

    The first three columns are the design matrix itself (exactly linear);
    the last three are central differences of X(theta) @ x.
    """
    T = np.repeat(np.asarray(theta, float)[None, :], 7, axis=0)
    hs = [1e-6 * max(1.0, abs(float(t))) for t in theta]
    up = [hs[0], hs[1], hs[2]]
    if prob.model == "rm1" and any(abs(theta[2] - k) <= 1e-9 for k in branch_points(prob)):
        up[2] = 0.0  # on a branch point: the tangent side (r_min <= r) is the continuous one
    for k in range(3):
        T[1 + 2 * k, k] += up[k]
        T[2 + 2 * k, k] -= hs[k]
    Xs = prob.designs(T[:, 0], T[:, 1], T[:, 2])
    out = []
    for X in Xs:
        cols = [X[0]] + [
            ((X[1 + 2 * k] - X[2 + 2 * k]) @ x / (up[k] + hs[k]))[:, None] for k in range(3)
        ]
        out.append(np.hstack(cols))
    return out


def polish(prob: LearnProblem, x: np.ndarray, theta: np.ndarray, *, steps: int = 12) -> Refined:
    """Newton steps on J itself from a refined point, to pin the minimiser down.

    Reweighting converges linearly, so a tolerance on J leaves the
    parameters known to only about the square root of it.  Here the
    gradient sum_d a_d D_d' r_d / ||r_d|| is driven to zero with the
    Gauss-Newton Hessian of J (sum_d w_d (D_d'D_d - g_d g_d')), over the
    parameters not held at a bound, with step halving so that J never rises.

    RM1 changes branch where r_min equals a plate or cone radius (section
    3.2); J jumps there (r_min = r2 is still the tangent, above it the
    secant), so an optimum may sit on the branch point itself.  When r_min
    is within 1e-5 (relative) of one, the point with r_min exactly on it is
    polished too and kept unless J is lower elsewhere by more than 1e-12
    relative.
    """
    p = np.concatenate([x, theta])
    best = _newton(prob, p, steps, fix_rm=False)
    if prob.model == "rm1":
        for k in branch_points(prob):
            if abs(theta[2] - k) <= 1e-5 and prob.theta_lo[2] <= k <= prob.theta_hi[2]:
                q = p.copy()
                q[5] = k
                cand = _newton(prob, q, steps, fix_rm=True)
                if cand.J <= best.J * (1 + 1e-12):
                    best = cand
    return best


def branch_points(prob: LearnProblem) -> list[float]:
    """log radii where the RM1 law changes branch: cone radii and the plate pair."""
    radii = {p.cone.radius for p in prob.profiles} | set(prob.pair or ())
    return [math.log(r) for r in sorted(radii)]


def _newton(prob: LearnProblem, p: np.ndarray, steps: int, fix_rm: bool) -> Refined:
    lo_x, hi_x = prob.box(np.asarray(p[3]))
    lo = np.concatenate([lo_x, prob.theta_lo])
    hi = np.concatenate([hi_x, prob.theta_hi])
    fixed = hi <= lo
    fixed[5] |= prob.model == "rm0" or fix_rm
    J = prob.objective(p[:3], p[3:])
    scale = np.maximum(np.abs(p), np.where(hi > lo, hi - lo, 1.0) * 1e-3)
    for _ in range(steps):
        rs = prob.residuals(p[:3], p[3:])
        norms = np.array([np.linalg.norm(r) for r in rs])
        if np.any(norms <= 1e-12 * np.array([np.linalg.norm(y) for y in prob.ys])):
            break  # a data set fitted exactly: J is not smooth there
        Ds = jacobians(prob, p[:3], p[3:])
        grad = np.zeros(6)
        H = np.zeros((6, 6))
        for D, r, a, nr in zip(Ds, rs, prob.a, norms):
            gd = D.T @ (r / nr)
            grad += a * gd
            H += (a / nr) * (D.T @ D - np.outer(gd, gd))
        # parameters on a bound whose gradient pushes them outward stay there
        f = ~(fixed | ((p <= lo) & (grad > 0)) | ((p >= hi) & (grad < 0)))
        if not f.any():
            break
        Hs = H[np.ix_(f, f)] * np.outer(scale[f], scale[f])
        step = np.zeros(6)
        step[f] = -scale[f] * (np.linalg.pinv(Hs, rcond=1e-13) @ (grad[f] * scale[f]))
        moved = False
        for t in (1.0, 0.5, 0.25, 0.125):
            q = np.clip(p + t * step, lo, hi)
            Jq = prob.objective(q[:3], q[3:])
            if Jq <= J:
                moved = bool(np.any(np.abs(q - p) > 1e-12 * scale))
                p, J = q, Jq
                break
        if not moved:
            break
    return Refined(p[:3].copy(), p[3:].copy(), J, 0)


#: the curvature inside a cell is taken as at most this many times the largest
#: second difference of J seen on the cell's own sample points (the bound's assumption)
CURVATURE_SAFETY = 2.0


def _curvature(U: np.ndarray, t: np.ndarray, axis: int, cut: np.ndarray) -> np.ndarray:
    """|d2J/dt2| estimated at every node along an axis (NaN where undefined).

    The second divided difference over each node and its two neighbours
    (spacing may vary); NaN at the ends and where either neighbouring
    interval holds an RM1 branch point (``cut``, bool per interval).
    """
    out = np.full(U.shape, np.nan)
    if U.shape[axis] < 3:
        return out
    Um = np.moveaxis(U, axis, 0)
    h = np.diff(t)
    d1 = np.diff(Um, axis=0) / h.reshape((-1,) + (1,) * (Um.ndim - 1))
    hh = (h[:-1] + h[1:]).reshape((-1,) + (1,) * (Um.ndim - 1))
    d2 = np.abs(2.0 * np.diff(d1, axis=0) / hh)
    bad = (cut[:-1] | cut[1:]).reshape((-1,) + (1,) * (Um.ndim - 1))
    om = np.moveaxis(out, axis, 0)
    om[1:-1] = np.where(bad, np.nan, d2)
    return out


def _cell_bound(L: np.ndarray, M: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Lower bound of J per cell: smallest corner bound less the interpolation allowance.

    Tensor-product linear interpolation of f with |d2f/dt_k^2| <= M_k in a
    cell of sides h_k misses f by at most sum_k M_k h_k^2 / 8, and its
    minimum is at a corner.  L: corner bounds (K, ...); M, h: (K, 3), M_k
    already multiplied by ``CURVATURE_SAFETY`` (inf: no estimate).
    """
    with np.errstate(invalid="ignore"):
        err = np.where(h > 0, M * h**2 / 8.0, 0.0).sum(axis=1)
    return L.reshape(L.shape[0], int(np.prod(L.shape[1:]))).min(axis=1, initial=np.inf) - err


def _block_max(m: np.ndarray) -> np.ndarray:
    """Largest finite value per leading index of a block (K, ...), inf when none."""
    m = np.where(np.isnan(m), -np.inf, m)
    mk = np.max(m.reshape(m.shape[0], int(np.prod(m.shape[1:]))), axis=1, initial=-np.inf)
    return np.where(np.isfinite(mk), mk, np.inf)


def _kink_cut(prob: LearnProblem, ax: np.ndarray) -> np.ndarray:
    """Per interval [a, b) of the log r_min axis: does it hold an RM1 branch point?

    At a branch point the law is still the lower branch (tangent for the
    plates), so a cell ending on one is continuous; one starting on it is not.
    """
    cut = np.zeros(max(ax.size - 1, 0), bool)
    if prob.model != "rm1" or ax.size < 2:
        return cut
    ks = np.array(branch_points(prob))
    return np.array([bool(np.any((ks >= a) & (ks < b))) for a, b in zip(ax[:-1], ax[1:])])


def _augmented(prob: LearnProblem, stage: GridStage, rtol: float):
    """The grid with log r_min nodes added a hair (1e-9) either side of each RM1
    branch point inside the range (above it only, when it is a node itself), solved with
    certificates: (axes, J, lower, new solves).
    """
    ax = list(stage.axes)
    U, L = stage.cells.J, stage.cells.lower
    if prob.model != "rm1" or ax[2].size < 2:
        return ax, U, L, 0
    ks = np.array(branch_points(prob))
    # a branch point that is a node already (:func:`r_axis`) ends the stretch below it
    extra = np.concatenate([ks[~np.isin(ks, ax[2])] - 1e-9, ks + 1e-9])
    extra = extra[(extra > ax[2][0]) & (extra < ax[2][-1])]
    extra = np.setdiff1d(extra, ax[2])
    # a stretch between branch points with no node inside gets its midpoint (for a curvature)
    r = np.union1d(ax[2], extra)
    cut = _kink_cut(prob, r)
    run = np.concatenate([[True], cut, [True]])
    lone = np.flatnonzero(~cut & run[:-2] & run[2:])
    extra = np.union1d(extra, 0.5 * (r[lone] + r[lone + 1]))
    if extra.size == 0:
        return ax, U, L, 0
    N, P, R = np.meshgrid(ax[0], ax[1], extra, indexing="ij")
    sol = prob.solve_cells(N, P, R, rtol=rtol)
    r = np.concatenate([ax[2], extra])
    order = np.argsort(r, kind="stable")
    U = np.concatenate([U, sol.J], axis=2)[:, :, order]
    L = np.concatenate([L, sol.lower], axis=2)[:, :, order]
    ax[2] = r[order]
    return ax, U, L, int(sol.J.size)


@dataclass
class Cells:
    """Cells of the outer search box: corners, curvatures and corner values.

    lo, hi : (C, 3) lower and upper corners in (n, phic, log r_min);
    M : (C, 3) curvature allowance per axis (already times the safety factor);
    U, L : (C, 2, 2, 2) J and its certified lower bound at the cell's corners.
    """

    lo: np.ndarray
    hi: np.ndarray
    M: np.ndarray
    U: np.ndarray
    L: np.ndarray

    def bound(self) -> np.ndarray:
        return _cell_bound(self.L, self.M, self.hi - self.lo)

    def take(self, sel) -> Cells:
        return Cells(self.lo[sel], self.hi[sel], self.M[sel], self.U[sel], self.L[sel])

    @staticmethod
    def join(parts: list[Cells]) -> Cells:
        return Cells(
            *(np.concatenate([getattr(c, f) for c in parts]) for f in ("lo", "hi", "M", "U", "L"))
        )


def _base_cells(prob: LearnProblem, stage: GridStage, rtol: float):
    """The (augmented) grid's cells: corners (C, 3), curvatures (C, 3), bounds, cut flags, solves.

    A cut cell holds an RM1 branch point and is 2e-9 wide in log r_min: J
    there is within that of its corner values on either side, so its bound
    is its smallest corner bound (no allowance) and it is never halved.
    """
    ax, U, L, n_new = _augmented(prob, stage, rtol)
    free = [k for k in range(3) if ax[k].size > 1]
    cuts = [np.zeros(max(a.size - 1, 0), bool) for a in ax[:2]] + [_kink_cut(prob, ax[2])]
    M = [_curvature(U, ax[k], k, cuts[k]) for k in range(3)]
    ranges = [np.arange(ax[k].size - 1) if k in free else np.zeros(1, int) for k in range(3)]
    base = np.stack([g.reshape(-1) for g in np.meshgrid(*ranges, indexing="ij")], axis=-1)
    off = [np.arange(2) if k in free else np.zeros(1, int) for k in range(3)]
    idx = tuple(
        base[:, k][:, None, None, None] + off[k].reshape([-1 if j == k else 1 for j in range(3)])
        for k in range(3)
    )
    lo = np.stack([ax[k][base[:, k]] for k in range(3)], axis=-1)
    hi = np.stack([ax[k][base[:, k] + (1 if k in free else 0)] for k in range(3)], axis=-1)
    cut = cuts[2][base[:, 2]] if 2 in free else np.zeros(base.shape[0], bool)
    Mc = np.zeros(lo.shape)
    for k in free:
        Mc[:, k] = CURVATURE_SAFETY * _block_max(M[k][idx])
    Mc[cut] = 0.0
    full = (base.shape[0], 2, 2, 2)
    cells = Cells(
        lo, hi, Mc, np.broadcast_to(U[idx], full).copy(), np.broadcast_to(L[idx], full).copy()
    )
    return cells, cut, n_new


def certify(
    prob: LearnProblem,
    stage: GridStage,
    J_best: float,
    *,
    levels: int = 3,
    cap: int = 96,
    target: float = 0.0,
    rtol: float = 1e-7,
) -> tuple[float, int, int]:
    """Branch and bound on the grid's cells: a lower bound of J over the search box.

    Each cell's bound is its smallest certified corner bound (the inner
    problem's dual value) less an interpolation allowance
    (:func:`_cell_bound`) from a curvature M_k per axis, taken as
    ``CURVATURE_SAFETY`` times the largest second divided difference of J
    on the cell's sample points.  Cells whose bound is below J_best are
    halved, ``levels`` rounds of at most ``cap`` cells (lowest bound first),
    along the axis with the largest allowance: the three points along it
    (and the cell's corners across) are solved with certificates, the
    children take the new curvature along it and their parent's across.
    Cells not refined keep their bound; cells whose bound is within
    ``target`` (relative) of J_best are not refined either (the bound then
    aims at a gap of ``target`` J_best, not at excluding every cell).  The
    inner solves stop at a duality gap of ``rtol`` times the data's scale
    (their dual value is a valid bound at any rtol).  The RM1 branch points,
    where J jumps, are never inside a cell (:func:`_base_cells`).  Assumption: J's
    curvature inside a cell is at most ``CURVATURE_SAFETY`` times what the
    cell's samples show.  Returns (lower bound, cells still open, points
    solved).
    """
    free = [k for k in range(3) if stage.axes[k].size > 1]
    cells, cut, evals = _base_cells(prob, stage, rtol)
    tol = max(1e-6, target) * max(J_best, 1e-300)
    parked: list[float] = []
    kept = cells.take(cut).bound()  # cut cells are never halved: their bound is final
    cells = cells.take(~cut)
    lb = cells.bound()
    for _ in range(levels):
        open_ = np.flatnonzero(lb < J_best - tol)
        if open_.size == 0:
            break
        order = open_[np.lexsort((open_, lb[open_]))]
        if order.size > cap:
            parked.append(float(lb[order[cap:]].min()))
            order = order[:cap]
        done = np.ones(lb.size, bool)
        done[order] = False
        out = [cells.take(done)]
        h = cells.hi - cells.lo
        with np.errstate(invalid="ignore"):
            share = np.where(h > 0, cells.M * h**2, -1.0)[order]
        axis = np.argmax(np.where(np.isnan(share), np.inf, share), axis=1)  # ties: lowest axis
        for k in free:
            sel = order[axis == k]
            if sel.size:
                kids, n_solved = _halve(prob, cells.take(sel), k, rtol)
                out.append(kids)
                evals += n_solved
        cells = Cells.join(out)
        lb = cells.bound()
    lb = np.concatenate([lb, kept])
    remaining = int(np.sum(lb < J_best * (1 - 1e-6)))
    lower = min([J_best, float(lb.min()) if lb.size else J_best] + parked)
    return max(lower, 0.0), remaining + (1 if parked else 0), evals


def _halve(prob: LearnProblem, c: Cells, k: int, rtol: float) -> tuple[Cells, int]:
    """Halve cells along axis k: solve the 4 midpoints of the edges along k (the
    corners are known; each distinct point once), the new curvature along k from the
    3 points of each edge."""
    mid = 0.5 * (c.lo[:, k] + c.hi[:, k])
    corner = [np.stack([c.lo[:, j], c.hi[:, j]], axis=-1) for j in range(3)]  # (K, 2)
    corner[k] = np.stack([mid, mid], axis=-1)
    G = np.broadcast_arrays(
        *[corner[j].reshape([-1] + [2 if i == j else 1 for i in range(3)]) for j in range(3)]
    )
    # each distinct point once: the midpoints repeat along k, and edges shared by
    # neighbouring cells (or a fixed axis, RM0's r_min) repeat them too
    pts, inv = np.unique(np.stack([a.reshape(-1) for a in G], axis=-1), axis=0, return_inverse=True)
    sol = prob.solve_cells(pts[:, 0], pts[:, 1], pts[:, 2], rtol=rtol)
    Um = np.take(sol.J[inv.reshape(-1)].reshape(G[0].shape), [0], axis=1 + k)  # the midpoints
    Lm = np.take(sol.lower[inv.reshape(-1)].reshape(G[0].shape), [0], axis=1 + k)
    half = 0.5 * (c.hi[:, k] - c.lo[:, k])
    U0, U1 = np.take(c.U, [0], axis=1 + k), np.take(c.U, [1], axis=1 + k)
    L0, L1 = np.take(c.L, [0], axis=1 + k), np.take(c.L, [1], axis=1 + k)
    d2 = np.abs(U0 - 2.0 * Um + U1) / np.maximum(half, 1e-300).reshape(-1, 1, 1, 1) ** 2
    M = c.M.copy()
    M[:, k] = CURVATURE_SAFETY * _block_max(d2)
    lo_mid, hi_mid = c.lo.copy(), c.hi.copy()
    lo_mid[:, k], hi_mid[:, k] = mid, mid
    first = Cells(c.lo, hi_mid, M, np.concatenate([U0, Um], 1 + k), np.concatenate([L0, Lm], 1 + k))
    second = Cells(
        lo_mid, c.hi, M, np.concatenate([Um, U1], 1 + k), np.concatenate([Lm, L1], 1 + k)
    )
    return Cells.join([first, second]), int(sol.J.size)

"""The layered fit's global search: a grid with branch and bound over interfaces and n's.

For fixed interface depths D = (D_1 .. D_(L-1)) and exponents n = (n_1 .. n_L)
the layered cone index of :mod:`terracone.physics.layers` is linear in each
layer's (kc, kphi, cc): the inner problem is a bounded linear least squares in
3L variables, solved exactly (:func:`~terracone.inverse.solver.layered_kernels.boxqp`).
The outer search covers D and n with the structure of the one-layer solver
(:mod:`terracone.inverse.solver.many`): a grid over n (compiled kernels with
numpy twins), the interfaces on the cells between the depths where an
interface meets a cone base or tip, refinement, and a bound on the distance
from the global optimum as learning gives one (:mod:`terracone.inverse.learning.search`).

Why it is fast: a measured cone lies wholly in one layer unless an interface
cuts it.  Over a cell of interface depths (each interface between two
consecutive "breakpoints", the depths of the cone bases and tips) the rows
wholly inside layer j are a run of consecutive rows, fixed for the whole
cell, and only the few rows the interfaces may cut couple the layers.  So

* **separable bound** (B1): dropping the rows an interface may cut leaves
  one independent one-layer problem per layer; the sum over the layers of
  their minima over n (a table of the one-layer SSE of every run of rows at
  every n, :func:`~terracone.inverse.solver.layered_kernels.segment_sse`) is
  a lower bound of the SSE anywhere in the cell, for any n's;
* **Lagrangian bound** (B2): a cut row's squared residual r^2 is at least
  2 lam r - lam^2 for any lam, which is linear in each layer's parameters;
  the part of a cut cone in a layer grows or shrinks monotonically with
  each interface, so taking it at the cell end that makes lam x . P
  smallest (x >= 0) keeps the bound valid over the cell and separable over
  the layers again (:func:`~terracone.inverse.solver.layered_kernels.cell_terms`).
  With lam the residuals of the best fit found, the bound is tight at its
  cell as the cell shrinks;
* **branch and bound**: cells whose bound is below the best SSE found less
  the target gap are halved (along their widest interface), bounded again,
  and searched locally (compiled Nelder-Mead over D and n from the cell's
  middle and each layer's best n), until every cell is within the target or
  the levels run out.

The bound over n in a layer term is the smallest value on a grid of n
(41 points, and a 4 times finer grid around its minimum) less the
interpolation allowance M h^2 / 8 of a cell of width h, with M = 2 times
the largest second difference seen at the cell's ends (the assumption, as
in learning: the curvature in n inside a cell is at most twice what its
neighbouring samples show).  Over D the bound makes no assumption.  With one
layer there are no interfaces and the search is the one-layer fit.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver import layered_numpy as lnp
from terracone.inverse.solver.many import bounds_params
from terracone.jit import enabled
from terracone.physics.cone import Cone
from terracone.physics.plate import PressureLaw

__all__ = ["CURVATURE_SAFETY", "LayeredProblem", "SearchResult", "search_layers"]

#: the curvature in n inside a grid cell is taken as at most this many times the largest
#: second difference seen at the cell's ends (the bound's assumption, as learning's)
CURVATURE_SAFETY = 2.0
SUB = 4  # the fine grid of n: this many steps per step of the grid
CHI2_1_95 = 3.841458820694124


@dataclass
class SearchResult:
    """Best layered fit found at one phic scale and the bound on the global minimum (SI).

    ``lower`` is a lower bound of the SSE over the whole search space (up to
    the curvature assumption in n), ``intervals`` the outer approximations
    of the 95% profile intervals of each interface and n (name -> (lo, hi)).
    """

    D: np.ndarray
    n: np.ndarray
    x: np.ndarray
    sse: float
    lower: float
    cells_open: int
    nfev: int
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    threshold: float = math.nan
    d_range: tuple[float, float] = (math.nan, math.nan)
    residuals: np.ndarray | None = None  # model minus data (Z,) [kPa]


class LayeredProblem:
    """One profile's layered fit: data, search space, grids and the kernels (compiled or numpy).

    Parameters
    ----------
    z, y : (Z,) ndarray
        Base depths [m] (increasing) and CI [kPa].
    cone, law, bounds
        Cone, pressure law (RM0/RM1) and the bounds of each layer's kc,
        kphi, n, cc [SI or as given].
    layers : int
    min_thickness : float
        The first interface lies at least this far below the first depth
        and the last at least this far above the last depth; interfaces lie
        at least half of it apart [m].
    s : float
        Scale of the kc and kphi columns, 1 + tan(phic)/tan(alpha) (eq. (2-6)).
    n_grid : int
        Points of the grid over each layer's n.
    ratio : float, optional
        kc/kphi held in every layer [m] (a calibration's).
    """

    def __init__(self, z, y, cone: Cone, law: PressureLaw, bounds: Bounds, layers: int,
                 min_thickness: float, s: float, n_grid: int = 41,
                 ratio: float | None = None) -> None:  # fmt: skip
        self.z = np.ascontiguousarray(z, dtype=float)
        self.y = np.ascontiguousarray(y, dtype=float)
        self.cone, self.law, self.bounds, self.L, self.s = cone, law, bounds, int(layers), float(s)
        self.ratio = ratio
        H = cone.height
        coef = [float(np.asarray(c)) for c in law.coefficients()]
        self.geom = (H, cone.radius, not law.is_rm0, coef[0], coef[1], coef[2])
        self.bp = bounds_params(bounds, ratio)
        self.u1 = self.z + H
        self.e = np.maximum(self.z, 0.0)
        self.lu1 = lnp.log_tip(self.z, H)
        self.lo_d = float(self.z[0] + min_thickness)
        self.hi_d = float(self.z[-1] - min_thickness)
        self.gap = 0.5 * float(min_thickness)
        nlo, nhi = (float(v) for v in bounds.n)
        K = max(int(n_grid), 3) if nhi > nlo else 1
        self.ng = np.linspace(nlo, nhi, K)
        self.nsf = np.linspace(nlo, nhi, (K - 1) * SUB + 1) if K > 1 else self.ng
        self.h = (nhi - nlo) / (K - 1) if K > 1 else 0.0
        self.compiled = enabled()
        self.nfev = 0
        self.yy = float(self.y @ self.y)
        self.Ff = self._full_columns(self.nsf)
        self.lof, self.hif = lnp.layer_box(bounds, self.nsf[:, None])
        self.F = self.Ff[::SUB] if K > 1 else self.Ff
        self.seg_table: np.ndarray | None = None  # one-layer SSE of runs of rows (search_layers)

    # -- kernels -----------------------------------------------------------------------------
    def _full_columns(self, ns: np.ndarray) -> np.ndarray:
        if self.compiled:
            from terracone.inverse.solver import layered_kernels as lk

            return lk.full_columns(self.z, ns, self.s, self.geom)
        return lnp.full_columns(self.z, ns, self.s, self.law, self.cone)

    def sse_many(self, Ds: np.ndarray, nss: np.ndarray):
        """SSE (M,), (kc, kphi, cc) per layer (M, 3L) and residuals (M, Z), model minus data, at
        interfaces Ds (M, L-1) and exponents nss (M, L)."""
        Ds = np.ascontiguousarray(np.reshape(Ds, (len(nss), self.L - 1)), dtype=float)
        nss = np.ascontiguousarray(nss, dtype=float)
        self.nfev += len(nss)
        if self.compiled:
            from terracone.inverse.solver import layered_kernels as lk

            return lk.layered_sse_many(self.z, self.y, Ds, nss, self.s, self.bp, self.geom)
        return lnp.layered_sse_many(
            self.z, self.y, Ds, nss, self.s, self.bounds, self.law, self.cone, self.ratio
        )

    def segments(self) -> np.ndarray:
        """One-layer SSE of the runs of rows a layer can hold at every n: (Z + 1, Z + 1, K).

        Runs [i, j) with i <= j; with two layers only those from the first row
        or to the last (the others are NaN).
        """
        lo, hi = self.lof[::SUB], self.hif[::SUB]
        Z = self.z.size
        need = np.triu(np.ones((Z + 1, Z + 1), dtype=bool))
        if self.L <= 2:
            need[1:, :Z] = False
            if self.L == 1:
                need[0, :Z] = False
        if self.compiled:
            from terracone.inverse.solver import layered_kernels as lk

            return lk.segment_sse(self.F, self.y, lo, hi, need)
        return lnp.segment_sse(self.F, self.y, lo, hi, need)

    def terms(self, kidx, seg, mixed, lam, ends):
        """Per-layer Lagrangian terms (C, L, M) at the fine-grid indices kidx (C, L, M), and the
        cut rows' x . P of their minimisers (C, L, M, Z)."""
        args = (np.ascontiguousarray(kidx), seg, mixed, np.ascontiguousarray(lam), ends)
        if self.compiled:
            from terracone.inverse.solver import layered_kernels as lk

            return lk.cell_terms(
                self.z, self.y, self.lu1, self.Ff, self.nsf, self.lof, self.hif, *args,
                self.s, self.geom,
            )  # fmt: skip
        return lnp.cell_terms(
            self.z, self.y, self.Ff, self.nsf, self.lof, self.hif, *args, self.s, self.law,
            self.cone,
        )  # fmt: skip

    def local(self, start: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, float]:
        """Nelder-Mead over p = (D, n) from ``start`` (:func:`~.layered_kernels.nelder_mead`)."""
        lo = np.array([self.lo_d] * (self.L - 1) + [self.bounds.n[0]] * self.L, dtype=float)
        hi = np.array([self.hi_d] * (self.L - 1) + [self.bounds.n[1]] * self.L, dtype=float)
        start = np.clip(np.asarray(start, dtype=float), lo, hi)
        xtol, ftol, maxiter = 1e-7, 1e-13 * max(self.yy, 1e-300), 200 * start.size
        if self.compiled:
            from terracone.inverse.solver import layered_kernels as lk

            p, f, used = lk.nelder_mead(
                self.z, self.y, start, np.asarray(step, float), lo, hi, self.gap, self.s,
                self.bp, self.geom, maxiter, xtol, ftol,
            )  # fmt: skip
            self.nfev += int(used)
            return p, float(f)

        def fun(p):
            q = np.clip(p, lo, hi)
            D = np.sort(q[: self.L - 1])
            if np.any(np.diff(D) < self.gap):
                return math.inf
            return float(self.sse_many(D[None], q[None, self.L - 1 :])[0][0])

        p, f, _ = lnp.nelder_mead(fun, start, np.asarray(step, float), maxiter, xtol, ftol)
        q = np.clip(p, lo, hi)
        q[: self.L - 1] = np.sort(q[: self.L - 1])
        return q, f

    # -- cells ---------------------------------------------------------------------------------
    def breakpoints(self) -> np.ndarray:
        """Interface depths where a cone base or tip lies, with the range's ends (sorted)."""
        b = np.concatenate([self.e, self.u1, [self.lo_d, self.hi_d]])
        b = b[(b >= self.lo_d) & (b <= self.hi_d)]
        return np.unique(b)

    def base_cells(self) -> np.ndarray:
        """Cells (C, L-1, 2) of the interfaces: each between consecutive breakpoints, in order."""
        B = self.breakpoints()
        if self.L == 1:
            return np.zeros((1, 0, 2))
        m = B.size - 1
        if m < 1:
            return np.zeros((0, self.L - 1, 2))
        idx = np.stack(np.meshgrid(*[np.arange(m)] * (self.L - 1), indexing="ij"), axis=-1).reshape(
            -1, self.L - 1
        )
        lo, hi = B[idx], B[idx + 1]
        ok = np.all(np.diff(idx, axis=1) >= 0, axis=1)
        ok &= np.all(hi[:, 1:] - lo[:, :-1] >= self.gap, axis=1)  # some D in the cell keeps the gap
        return np.stack([lo[ok], hi[ok]], axis=-1)

    def classify(self, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per cell: the run of rows held in each layer (C, L, 2) and the rows it may cut (C, Z)."""
        C, Z = ends.shape[0], self.z.size
        top = np.concatenate([np.full((C, 1), -np.inf), ends[:, :, 1]], axis=1)  # (C, L)
        bot = np.concatenate([ends[:, :, 0], np.full((C, 1), np.inf)], axis=1)
        i0 = np.searchsorted(self.e, top, side="left")
        i1 = np.maximum(np.searchsorted(self.u1, bot, side="right"), i0)
        seg = np.stack([i0, i1], axis=-1).astype(np.int64)
        q = np.arange(Z)
        held = (q[None, None, :] >= i0[:, :, None]) & (q[None, None, :] < i1[:, :, None])
        return seg, ~held.any(axis=1)

    def residuals(self, D: np.ndarray, ns: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Model minus data (Z,) of a layered fit (the numpy forward model)."""
        X = lnp.design_matrix(self.z, D, ns, self.s, self.law, self.cone)
        return X @ x - self.y


def cell_lower(f: np.ndarray, h: float) -> np.ndarray:
    """Lower bounds of f between grid nodes: (..., K) values at spacing h -> (..., K - 1) cells.

    Each cell's bound is its smaller end value less M h^2 / 8 with M =
    :data:`CURVATURE_SAFETY` times the larger second difference at its two
    ends (at the grid's ends, that of the neighbour).  One node: f itself.
    """
    K = f.shape[-1]
    if K == 1:
        return f
    d2 = np.zeros(f.shape)
    if K >= 3:
        d2[..., 1:-1] = np.abs(f[..., :-2] - 2.0 * f[..., 1:-1] + f[..., 2:]) / (h * h)
        d2[..., 0], d2[..., -1] = d2[..., 1], d2[..., -2]
    M = CURVATURE_SAFETY * np.maximum(d2[..., :-1], d2[..., 1:])
    return np.minimum(f[..., :-1], f[..., 1:]) - M * h * h / 8.0


@dataclass
class _Cells:
    """Open cells of the branch and bound: interface ends, n boxes, row classes, bounds, origin.

    A cell is a box of interface depths (ends) times a box of each layer's n,
    the fine-grid cells [a, b) of ``nsf`` (nbox).
    """

    ends: np.ndarray  # (C, L-1, 2) [m]
    nbox: np.ndarray  # (C, L, 2) fine-grid cell range [a, b) of each n
    seg: np.ndarray  # (C, L, 2) run of rows held in each layer
    mixed: np.ndarray  # (C, Z) rows an interface may cut
    bound: np.ndarray  # (C,) lower bound of the SSE in the cell
    nbest: np.ndarray  # (C, L) each layer's best n found for the cell
    base: np.ndarray  # (C,) index of the base cell
    lam: np.ndarray  # (C, Z) multipliers of the rows an interface may cut (NaN: not set yet)

    FIELDS = ("ends", "nbox", "seg", "mixed", "bound", "nbest", "base", "lam")

    def take(self, sel) -> _Cells:
        return _Cells(*(getattr(self, f)[sel] for f in self.FIELDS))

    @staticmethod
    def join(parts: list[_Cells]) -> _Cells:
        return _Cells(*(np.concatenate([getattr(c, f) for c in parts]) for f in _Cells.FIELDS))


def layer_bounds(pb: LayeredProblem, cells: _Cells, lam: np.ndarray, goal: float = math.inf):
    """The Lagrangian bound of each cell with multipliers lam (C, Z) on the rows it may cut.

    Returns (bound (C,), best n per layer (C, L), n boxes (C, L, 2), the cut
    rows' residuals under the layers' minimisers (C, Z): the supergradient
    of the bound in lam is 2 (rhat - lam)).  Each
    layer term is bounded over its n box: on the grid of n (the coarse cells
    meeting the box) and on a window of the fine grid (the box itself when
    it is small, else around the smallest grid value in it),
    :func:`cell_lower`.  The returned n box of a layer is the hull of the
    cells of n whose bound, with the other layers at their lower bounds,
    stays below ``goal`` (the rest of the box cannot hold a better point).
    """
    C, L = cells.seg.shape[:2]
    lamc = np.where(cells.mixed, lam, 0.0)
    const = -np.sum(lamc * (2.0 * pb.y + lamc), axis=1)
    Kf = pb.nsf.size
    if Kf == 1:
        k0 = np.zeros((C, L, 1), dtype=np.int64)
        f, xp = pb.terms(k0, cells.seg, cells.mixed, lamc, cells.ends)
        rhat = np.where(cells.mixed, xp[:, :, 0].sum(axis=1) - pb.y, 0.0)
        return f[..., 0].sum(axis=1) + const, np.full((C, L), pb.nsf[0]), cells.nbox, rhat
    a, b = cells.nbox[..., 0:1], cells.nbox[..., 1:2]  # (C, L, 1) fine cells [a, b)
    coarse = np.arange(0, Kf, SUB)
    # the coarse nodes of the cells meeting the box (others repeat the nearest: not recomputed)
    kc_lo = SUB * (a // SUB)
    kc_hi = np.minimum(SUB * -(-b // SUB), Kf - 1)
    kcn = np.clip(coarse, kc_lo, kc_hi)  # (C, L, K)
    if pb.seg_table is not None and not lamc.any():  # lam = 0: the one-layer SSE of the runs
        f = pb.seg_table[cells.seg[..., 0], cells.seg[..., 1]]  # (C, L, K)
    else:
        f, _ = pb.terms(kcn, cells.seg, cells.mixed, lamc, cells.ends)
    lbc = cell_lower(f, pb.h)  # (C, L, K-1); coarse cell k spans fine nodes [SUB k, SUB k + SUB]
    kc = SUB * np.arange(coarse.size - 1)
    meets = (kc < b) & (kc + SUB > a)
    inbox = (coarse >= a) & (coarse <= b)
    k = np.argmin(np.where(inbox, f, np.inf), axis=2)  # best grid node in the box
    has = inbox.any(axis=2)
    W = 2 * SUB + 3
    small = (b - a)[..., 0] <= W - 3
    centre = np.where(small | ~has, a[..., 0] - 1, SUB * k - SUB - 1)
    start = np.clip(centre, 0, Kf - W)
    kf = start[..., None] + np.arange(W)
    ff, xpf = pb.terms(kf, cells.seg, cells.mixed, lamc, cells.ends)
    lbf = cell_lower(ff, pb.h / SUB)  # (C, L, W-1): fine cell [kf, kf + 1]
    fin = (kf[..., :-1] >= a) & (kf[..., :-1] + 1 <= b)
    lbf = np.where(fin, lbf, np.inf)
    # coarse cells whose part in the box lies in the window are bounded by the fine cells
    lo_part, hi_part = np.maximum(kc, a), np.minimum(kc + SUB, b)
    covered = (lo_part >= start[..., None]) & (hi_part <= start[..., None] + W - 1)
    lbc = np.where(meets & ~covered, lbc, np.inf)
    lower = np.minimum(lbc.min(axis=2), lbf.min(axis=2))  # (C, L)
    node_ok = (kf >= a) & (kf <= b)
    best = np.argmin(np.where(node_ok, ff, np.inf), axis=2)
    nbest = pb.nsf[np.take_along_axis(kf, best[..., None], axis=2)[..., 0]]
    # the cut rows' residuals under each layer's minimiser at its best n (a supergradient)
    xb = np.take_along_axis(xpf, best[..., None, None], axis=2)[:, :, 0, :]  # (C, L, Z)
    rhat = np.where(cells.mixed, xb.sum(axis=1) - pb.y, 0.0)
    bound = lower.sum(axis=1) + const
    # shrink each n box to the cells that can still beat the goal
    rest = (bound[:, None] - lower)[..., None]  # the other layers at their bounds, and the constant
    okc, okf = lbc + rest < goal, lbf + rest < goal
    lo_c = np.where(okc, np.maximum(kc, a), Kf).min(axis=2)
    hi_c = np.where(okc, np.minimum(kc + SUB, b), -1).max(axis=2)
    lo_f = np.where(okf, kf[..., :-1], Kf).min(axis=2)
    hi_f = np.where(okf, kf[..., :-1] + 1, -1).max(axis=2)
    nbox = np.stack([np.minimum(lo_c, lo_f), np.maximum(hi_c, hi_f)], axis=-1)
    nbox = np.where((nbox[..., 1:] > nbox[..., :1]), nbox, cells.nbox)
    return bound, nbest, nbox, rhat


@dataclass
class _Incumbent:
    p: np.ndarray  # (D, n)
    sse: float
    x: np.ndarray
    r: np.ndarray  # residuals, model minus data


class _Tracker:
    """The best point found, and every evaluated point within a threshold (for the intervals)."""

    def __init__(self, pb: LayeredProblem) -> None:
        self.pb = pb
        self.inc: _Incumbent | None = None
        self.points: list[np.ndarray] = []  # (M, 2L - 1) points evaluated
        self.values: list[np.ndarray] = []

    def offer(self, P: np.ndarray, sse: np.ndarray, x: np.ndarray, r: np.ndarray) -> None:
        self.points.append(P)
        self.values.append(sse)
        k = int(np.argmin(sse))
        if self.inc is None or sse[k] < self.inc.sse:
            self.inc = _Incumbent(P[k].copy(), float(sse[k]), x[k].copy(), r[k].copy())

    def evaluate(self, D: np.ndarray, ns: np.ndarray):
        sse, x, r = self.pb.sse_many(D, ns)
        self.offer(np.concatenate([D.reshape(len(ns), -1), ns], axis=1), sse, x, r)
        return sse, r

    def local(self, p0: np.ndarray, dstep: float) -> None:
        """A local search from p0 (Nelder-Mead); its end point offered."""
        pb = self.pb
        step = np.concatenate([np.full(pb.L - 1, dstep), np.full(pb.L, 2.0 * max(pb.h, 1e-3))])
        p, _ = pb.local(p0, step)
        self.evaluate(p[None, : pb.L - 1], p[None, pb.L - 1 :])


def search_layers(
    pb: LayeredProblem,
    *,
    target: float = 0.02,
    levels: int = 24,
    cap: int = 16,
    starts: int = 1,
    noise_floor: float = 0.01,
    intervals: bool = True,
) -> SearchResult:
    """Global search of the layered fit of ``pb`` (see the module): best (D, n, x) and the bound.

    Parameters
    ----------
    target : float
        Relative gap aimed at: cells whose bound is within ``target`` of the
        best SSE are not refined.
    levels : int
        Rounds of branch and bound (each halves the open cells once).
    cap : int
        Most cells bounded per round (lowest bound first; the rest wait).
    starts : int
        Local searches from the cells of lowest separable bound before the
        branch and bound, and at most as many per round after.
    noise_floor : float
        Relative noise floor of the profile intervals (as the one-layer fit).
    intervals : bool
        Compute the profile intervals of the interfaces and n's.
    """
    Z, L = pb.z.size, pb.L
    Seg = pb.segments()  # (Z+1, Z+1, K)
    pb.seg_table = Seg
    with np.errstate(invalid="ignore"):
        seg_lower = cell_lower(Seg, pb.h).min(axis=-1) if pb.ng.size > 1 else Seg[..., 0]
        seg_best = pb.ng[np.argmin(np.where(np.isnan(Seg), np.inf, Seg), axis=-1)]
    ends = pb.base_cells()
    if ends.shape[0] == 0:
        raise ValueError("no interface fits the profile with the minimum layer thickness")
    seg, mixed = pb.classify(ends)
    i0, i1 = seg[..., 0], seg[..., 1]
    C = ends.shape[0]
    nbox = np.zeros((C, L, 2), dtype=np.int64)
    nbox[..., 1] = max(pb.nsf.size - 1, 0)
    base = _Cells(ends, nbox, seg, mixed, seg_lower[i0, i1].sum(axis=1), seg_best[i0, i1],
                  np.arange(C), np.full((C, Z), np.nan))  # fmt: skip
    dstep = max(float(np.median(np.diff(pb.z))) / 2.0, 1e-4) if Z > 1 else 1e-3
    tr = _Tracker(pb)
    searched: set[tuple[int, ...]] = set()
    # every base cell's middle with each layer's best n (one evaluation each), then local
    # searches from the cells of lowest separable bound and from those whose middles fit best
    mid = tr.evaluate(ends.mean(axis=-1), base.nbest)[0]
    first = np.concatenate([np.argsort(base.bound, kind="stable")[:starts],
                            np.argsort(mid, kind="stable")[: 2 * starts]])  # fmt: skip
    for c in first:
        key = (int(c), *np.round(base.nbest[c] / (4 * max(pb.h, 1e-3))).astype(int))
        if key not in searched:
            tr.local(np.concatenate([ends[c].mean(axis=-1), base.nbest[c]]), dstep)
            searched.add(key)
    cells, closed = base, math.inf
    for _ in range(levels):
        goal = tr.inc.sse * (1.0 - target)
        done = cells.bound >= goal
        closed = min(closed, float(cells.bound[done].min(initial=math.inf)))
        cells = cells.take(~done)
        if cells.bound.size == 0:
            break
        order = np.argsort(cells.bound, kind="stable")
        work, wait = cells.take(order[:cap]), cells.take(order[cap:])
        mid = _bound_cells(pb, tr, work, goal)
        # local searches from the cells whose middles fit best, once per cell and region of n
        done_here = 0
        for i in np.argsort(mid):
            if done_here >= starts or not work.bound[i] < tr.inc.sse:
                continue
            key = (int(work.base[i]), *np.round(work.nbest[i] / (4 * max(pb.h, 1e-3))).astype(int))
            if key in searched:
                continue
            tr.local(np.concatenate([work.ends[i].mean(axis=-1), work.nbest[i]]), dstep)
            searched.add(key)
            done_here += 1
        cells = _Cells.join([_split(pb, work), wait])
    lower = min(closed, float(cells.bound.min(initial=math.inf)), tr.inc.sse)
    tr.local(tr.inc.p, dstep / 8.0)  # Nelder-Mead restarted from the best, smaller steps
    inc = tr.inc
    res = SearchResult(
        D=inc.p[: L - 1].copy(), n=inc.p[L - 1 :].copy(), x=inc.x, sse=inc.sse,
        lower=max(min(lower, inc.sse), 0.0),
        cells_open=int(np.sum(cells.bound < inc.sse * (1 - target))), nfev=pb.nfev,
        d_range=(pb.lo_d, pb.hi_d), residuals=inc.r,
    )  # fmt: skip
    if intervals:
        _profile_intervals(pb, tr, res, base, noise_floor)
    res.nfev = pb.nfev
    return res


def _bound_cells(pb: LayeredProblem, tr: _Tracker, cells: _Cells, goal: float = math.inf):
    """Bound cells in place with two sets of multipliers, keeping the better bound.

    lam = 0 (the rows an interface may cut dropped: the separable bound over
    the cell's n boxes) and the cell's own lam, which starts at the
    residuals of the best fit found (tight around it) and moves half way
    to the residuals under the bound's minimisers at every round (a damped
    supergradient step of the dual; children inherit it).  Each n box
    shrinks to what either bound leaves below ``goal``; the cells' middles
    with their best n's are evaluated (offered to the tracker: they may
    improve the best point); returns their SSE (C,).
    """
    C = cells.bound.size
    if C == 0:
        return np.zeros(0)
    inc = tr.inc
    unset = np.isnan(cells.lam[:, 0])
    if unset.any():
        cells.lam[unset] = inc.r
    B0, n0, box0, _ = layer_bounds(pb, cells, np.zeros((C, pb.z.size)), goal)
    cells.bound = np.maximum(cells.bound, B0)
    cells.nbest = n0
    lo, hi = box0[..., 0], box0[..., 1]
    live = np.flatnonzero((cells.bound < goal) & cells.mixed.any(axis=1))
    if live.size:  # the cells lam = 0 leaves open: the cell's own multipliers
        sub = cells.take(live)
        B1, n1, box1, rhat = layer_bounds(pb, sub, sub.lam, goal)
        cells.lam[live] = np.where(sub.mixed, 0.5 * (sub.lam + rhat), sub.lam)
        better = B1 > cells.bound[live]
        cells.bound[live] = np.maximum(cells.bound[live], B1)
        cells.nbest[live] = np.where(better[:, None], n1, cells.nbest[live])
        lo[live] = np.maximum(lo[live], box1[..., 0])
        hi[live] = np.minimum(hi[live], box1[..., 1])
    empty = np.any(hi <= lo, axis=1)  # no n left in some layer: nothing in the cell beats the goal
    cells.bound = np.where(empty, np.maximum(cells.bound, goal), cells.bound)
    cells.nbox = np.where(empty[:, None, None], cells.nbox, np.stack([lo, hi], axis=-1))
    return tr.evaluate(cells.ends.mean(axis=-1), cells.nbest)[0]


def _split(pb: LayeredProblem, c: _Cells) -> _Cells:
    """Halve each cell along its widest side: an interface, relative to the cone height, or a
    layer's n box, relative to the range of n (cells too small on every side stay whole)."""
    C = c.bound.size
    if C == 0:
        return c
    dw = (c.ends[..., 1] - c.ends[..., 0]) / pb.cone.height  # (C, L-1)
    dw = np.where(dw * pb.cone.height > 1e-6, dw, -1.0)
    span = max(pb.nsf.size - 1, 1)
    nw = np.where(
        c.nbox[..., 1] - c.nbox[..., 0] >= 2, (c.nbox[..., 1] - c.nbox[..., 0]) / span, -1.0
    )
    w = np.concatenate([dw, nw], axis=1)  # (C, 2L-1)
    i = np.argmax(w, axis=1)
    can = w[np.arange(C), i] > 0
    keep, s = c.take(~can), c.take(can)
    i = i[can]
    r = np.arange(i.size)
    other = s.take(r)
    s.ends, other.ends, s.nbox, other.nbox = (s.ends.copy(), other.ends.copy(), s.nbox.copy(),
                                              other.nbox.copy())  # fmt: skip
    d, nj = i < pb.L - 1, i - (pb.L - 1)
    rd, rn = r[d], r[~d]
    mid = 0.5 * (s.ends[rd, i[d], 0] + s.ends[rd, i[d], 1])
    s.ends[rd, i[d], 1] = mid
    other.ends[rd, i[d], 0] = mid
    m = (s.nbox[rn, nj[~d], 0] + s.nbox[rn, nj[~d], 1]) // 2
    s.nbox[rn, nj[~d], 1] = m
    other.nbox[rn, nj[~d], 0] = m
    return _Cells.join([keep, s, other])


def _profile_intervals(pb, tr: _Tracker, res: SearchResult, base: _Cells, noise_floor) -> None:
    """Approximate 95% profile intervals of each interface and each n (inner approximations).

    The threshold is SSE + 3.84 sigma^2 with sigma^2 = max(SSE / (N - 5L),
    (noise_floor mean|CI|)^2), as the one-layer fit's.  The points are those
    the search evaluated (the middle of every base cell with each layer's
    best n, the cells it refined, its local searches) and a sweep of each n
    over its grid at the best fit's interfaces and other n's.  An interval
    holds the values of the points within the threshold (so the data cannot
    exclude them), widened by a grid step.
    """
    N, L = pb.y.size, pb.L
    sigma2 = max(res.sse / max(N - 5 * L, 1), (noise_floor * float(np.mean(np.abs(pb.y)))) ** 2)
    thr = res.sse + CHI2_1_95 * sigma2
    res.threshold = thr
    if pb.ng.size > 1:
        for j in range(L):
            nss = np.repeat(res.n[None, :], pb.ng.size, axis=0)
            nss[:, j] = pb.ng
            tr.evaluate(np.repeat(res.D[None, :], pb.ng.size, axis=0), nss)
    P = np.concatenate(tr.points)
    ok = P[np.concatenate(tr.values) <= thr]
    B = pb.breakpoints()
    dstep = float(np.max(np.diff(B))) if B.size > 1 else 0.0
    for i in range(L - 1):
        lo = max(float(min(ok[:, i].min(), res.D[i])) - dstep, pb.lo_d)
        hi = min(float(max(ok[:, i].max(), res.D[i])) + dstep, pb.hi_d)
        res.intervals[f"interface_{i + 1}"] = (lo, hi)
    for j in range(L):
        v = ok[:, L - 1 + j]
        lo = max(float(min(v.min(), res.n[j])) - pb.h, float(pb.bounds.n[0]))
        hi = min(float(max(v.max(), res.n[j])) + pb.h, float(pb.bounds.n[1]))
        res.intervals[f"n_{j + 1}"] = (lo, hi)

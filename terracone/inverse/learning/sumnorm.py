"""Sum of data-set norms over a box, with a duality-gap certificate, vectorised.

For fixed (n, phic, r_min) the learning objective of section 3.3.1 of [1]_ is
``J(x) = sum_d a_d ||X_d x - y_d||`` over ``lo <= x <= hi``, x = (kc, kphi,
cc), a_d = 1 / (mean_d sqrt(N_d)): convex, but not differentiable where a
data set is fitted exactly.  :func:`sum_norm_box` first tests the
zero-residual case (a joint box least-squares fit), then runs a smoothed
reweighted least-squares iteration whose every iterate gives a dual-feasible
point and so a lower bound [2]_; it stops when the duality gap is below the
tolerance and returns it.  All from the Gram terms, thousands of cells in one
numpy call.  See ``docs/learn.md`` (Search: a certified global minimum).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3.1, eqs. (2-2) to (2-7).
.. [2] Boyd, S., Vandenberghe, L. (2004). Convex Optimization. Cambridge
   University Press. Section 5.2 (Lagrange dual) and 6.1 (norm approximation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from terracone.inverse.learning.kernels import sum_norm_cells
from terracone.inverse.solver.boxlsq import box_lsq3
from terracone.jit import enabled

__all__ = ["SumNormResult", "sum_norm_box", "sum_norm_box_reference", "sum_norm_value"]

#: relative resolution of sqrt(SSE_d) in the Gram form (about sqrt of the rounding unit)
GRAM_RESOLUTION = 1e-7


@dataclass
class SumNormResult:
    """Result of :func:`sum_norm_box`, per cell (leading shape S).

    Attributes
    ----------
    x : (S..., 3) ndarray
        Minimiser (kc, kphi, cc) in the units of the Gram terms.
    J : (S...) ndarray
        Objective at x (upper bound of the minimum).
    lower : (S...) ndarray
        Certified lower bound of the minimum (Lagrange dual value, >= 0).
    sse : (D, S...) ndarray
        Each data set's sum of squared residuals at x.
    iterations : int
        Reweighting steps of the cell that took most.
    """

    x: np.ndarray
    J: np.ndarray
    lower: np.ndarray
    sse: np.ndarray
    iterations: int

    @property
    def gap(self) -> np.ndarray:
        """Duality gap J - lower (>= 0): how far J can be above the minimum."""
        return np.maximum(self.J - self.lower, 0.0)


def sum_norm_value(G, g, yy, a, x) -> tuple[np.ndarray, np.ndarray]:
    """(J, SSE_d) at x from Gram terms: J = sum_d a_d sqrt(SSE_d)."""
    sse = (
        np.einsum("...i,d...ij,...j->d...", x, G, x)
        - 2.0 * np.einsum("d...i,...i->d...", g, x)
        + yy
    )
    sse = np.maximum(sse, 0.0)
    return np.einsum("d,d...->...", a, np.sqrt(sse)), sse


def _dual(G, g, yy, a, x, sse, eps2, lo, hi):
    """Lagrange dual value at u_d = a_d r_d / sqrt(SSE_d + eps_d^2)."""
    shp = (-1,) + (1,) * (x.ndim - 1)
    t = a.reshape(shp) / np.sqrt(sse + eps2)  # (D, S): u_d = t_d r_d
    c = np.einsum("d...,d...i->...i", t, np.einsum("d...ij,...j->d...i", G, x) - g)
    uy = np.einsum("d...,d...->...", t, np.einsum("d...i,...i->d...", g, x) - yy)  # u.y
    return -uy + np.sum(np.minimum(c * lo, c * hi), axis=-1)


def _flat(v: np.ndarray, S: tuple, lead: int) -> np.ndarray:
    """Flatten the cell dimensions S of v (after ``lead`` leading data-set axes)."""
    return v.reshape(v.shape[:lead] + (-1,) + v.shape[lead + len(S) :])


def _newton_or_mm(G, g, yy, a, x0, sse0, eps2, lo, hi, x_mm):
    """Best of the reweighting step x_mm and damped projected Newton steps from x0.

    Newton on the smoothed objective sum_d a_d sqrt(SSE_d + eps_d^2): its
    quadratic model is minimised over the box exactly (box_lsq3), then the
    step is scaled by 1, 1/2, ..., 1/64; the candidate of least J is kept.
    """
    s = np.sqrt(sse0 + eps2)  # (D, A)
    res = np.einsum("daij,aj->dai", G, x0) - g  # X_d'(X_d x - y_d)
    grad = np.einsum("da,dai->ai", a[:, None] / s, res)
    H = np.einsum("da,daij->aij", a[:, None] / s, G) - np.einsum(
        "da,dai,daj->aij", a[:, None] / s**3, res, res
    )
    H = H + 1e-12 * np.einsum("aii->a", H)[:, None, None] * np.eye(3)
    x_n, _ = box_lsq3(0.5 * H, 0.5 * (np.einsum("aij,aj->ai", H, x0) - grad), 0.0, lo, hi)
    cands = [x_mm] + [x0 + t * (x_n - x0) for t in (1.0, 0.5, 0.25, 0.125, 1 / 64)]
    Js = np.stack([sum_norm_value(G, g, yy, a, c)[0] for c in cands])  # (C, A)
    k = np.argmin(Js, axis=0)
    return np.stack(cands)[k, np.arange(k.size)]


def sum_norm_box(
    G: np.ndarray,
    g: np.ndarray,
    yy: np.ndarray,
    a: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    rtol: float = 1e-7,
    max_iter: int = 200,
) -> SumNormResult:
    """Global minimum of sum_d a_d ||X_d x - y_d|| over lo <= x <= hi, certified.

    Parameters
    ----------
    G : (D, S..., 3, 3) ndarray
        X_d' X_d per data set and cell.
    g : (D, S..., 3) ndarray
        X_d' y_d.
    yy : (D, S...) ndarray
        y_d' y_d.
    a : (D,) ndarray
        Data-set weights a_d > 0.
    lo, hi : (S..., 3) ndarray
        Bounds of x (lo == hi fixes a variable).
    rtol : float
        Stop when the duality gap is below rtol * sum_d a_d ||y_d|| in every
        cell (the scale of J), or when a cell's J is at the Gram resolution.
    max_iter : int
        Most reweighting steps.

    Returns
    -------
    SumNormResult
        With ``gap`` the certified distance of J from the cell's minimum.

    Notes
    -----
    The compiled kernel :func:`terracone.inverse.learning.kernels.sum_norm_cells`
    (cell by cell) when numba is enabled (:func:`terracone.jit.enabled`), else
    the numpy reference :func:`sum_norm_box_reference` (all cells at once); the
    same iteration, results equal to rounding.
    """
    if not enabled():
        return sum_norm_box_reference(G, g, yy, a, lo, hi, rtol=rtol, max_iter=max_iter)
    a = np.asarray(a, float)
    yy = np.asarray(yy, float)
    D, S = yy.shape[0], yy.shape[1:]
    M = int(np.prod(S, dtype=np.int64))
    tol = rtol * np.einsum("d,d...->...", a, np.sqrt(yy)).reshape(M)

    def flat(v, tail):
        return np.ascontiguousarray(np.broadcast_to(v, S + tail), dtype=float).reshape((M,) + tail)

    x, J, lower, sse, steps = sum_norm_cells(
        np.ascontiguousarray(G, dtype=float).reshape(D, M, 3, 3),
        np.ascontiguousarray(g, dtype=float).reshape(D, M, 3),
        np.ascontiguousarray(yy).reshape(D, M),
        a,
        flat(lo, (3,)),
        flat(hi, (3,)),
        tol,
        int(max_iter),
        GRAM_RESOLUTION,
    )
    it = int(steps.max()) if M else 0
    return SumNormResult(
        x.reshape(S + (3,)), J.reshape(S), lower.reshape(S), sse.reshape((D,) + S), it
    )


def sum_norm_box_reference(
    G: np.ndarray,
    g: np.ndarray,
    yy: np.ndarray,
    a: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    rtol: float = 1e-7,
    max_iter: int = 200,
) -> SumNormResult:
    """:func:`sum_norm_box` in numpy, all cells at once: the reference of the compiled
    kernel :func:`terracone.inverse.learning.kernels.sum_norm_cells` (same parameters,
    same result to rounding)."""
    a = np.asarray(a, float)
    scale = np.einsum("d,d...->...", a, np.sqrt(yy))  # sum a_d ||y_d||
    tol = rtol * scale
    floor2 = (GRAM_RESOLUTION**2) * yy  # SSE_d indistinguishable from 0
    # 1. joint box least squares (weights a_d^2): exact when it reaches zero residual
    x, _ = box_lsq3(
        np.einsum("d,d...ij->...ij", a**2, G),
        np.einsum("d,d...i->...i", a**2, g),
        np.einsum("d,d...->...", a**2, yy),
        lo,
        hi,
    )
    J, sse = sum_norm_value(G, g, yy, a, x)
    zero = np.all(sse <= floor2, axis=0)
    lower = np.where(zero, 0.0, -np.inf)
    best_x, best_J, best_sse = x, J, sse
    # reweighting on the cells not yet certified, compressed to a flat active set
    S = np.shape(yy)[1:]
    Gf, gf, yyf = _flat(G, S, 1), _flat(g, S, 1), _flat(yy, S, 1)
    lof = _flat(np.broadcast_to(lo, S + (3,)), S, 0)
    hif = _flat(np.broadcast_to(hi, S + (3,)), S, 0)
    bx, bJ, bsse, low = (
        _flat(best_x, S, 0).copy(),
        best_J.reshape(-1).copy(),
        _flat(best_sse, S, 1).copy(),
        lower.reshape(-1).copy(),
    )
    tolf = np.broadcast_to(tol, S).reshape(-1)
    act = np.flatnonzero(~(zero.reshape(-1) | (bJ - np.maximum(low, 0.0) <= tolf)))
    sse_a, xa = bsse[:, act], bx[act]
    steps = 0
    for it in range(1, max_iter + 1):
        if act.size == 0:
            break
        steps = it
        Ga, ga, yya = Gf[:, act], gf[:, act], yyf[:, act]
        la, ha = lof[act], hif[act]
        eps2 = max(1e-3 * 0.3 ** (it - 1), GRAM_RESOLUTION) ** 2 * yya
        w = a[:, None] / (2.0 * np.sqrt(sse_a + eps2))  # majorise sqrt(SSE) at the current point
        x_mm, _ = box_lsq3(
            np.einsum("da,daij->aij", w, Ga),
            np.einsum("da,dai->ai", w, ga),
            np.einsum("da,da->a", w, yya),
            la,
            ha,
        )
        xa = _newton_or_mm(Ga, ga, yya, a, xa, sse_a, eps2, la, ha, x_mm)
        J, sse_a = sum_norm_value(Ga, ga, yya, a, xa)
        # dual points of the current and two fixed smoothing levels; keep the best bound
        for e2 in (eps2, 1e-8 * yya, 1e-12 * yya):
            low[act] = np.maximum(low[act], _dual(Ga, ga, yya, a, xa, sse_a, e2, la, ha))
        better = J < bJ[act]
        idx = act[better]
        bJ[idx], bx[idx], bsse[:, idx] = J[better], xa[better], sse_a[:, better]
        keep = bJ[act] - np.maximum(low[act], 0.0) > tolf[act]
        act, sse_a, xa = act[keep], sse_a[:, keep], xa[keep]
    best_x, best_J = bx.reshape(S + (3,)), bJ.reshape(S)
    best_sse, lower = bsse.reshape((-1,) + S), low.reshape(S)
    lower = np.clip(lower, 0.0, best_J)
    return SumNormResult(best_x, best_J, lower, best_sse, steps)

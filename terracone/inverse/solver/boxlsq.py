"""Bounded linear least squares in three variables, vectorised.

For fixed n and phic the improved cone model (eq. (2-7) in [1]_) is linear
in (kc, kphi, cc); the convex quadratic is minimised over the box exactly by
a closed-form solve on each of its 27 faces (docs/predict.md, Solvers),
broadcast over leading dimensions.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-7).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from terracone.jit import enabled

__all__ = ["box_lsq3", "box_lsq3_reference", "gram"]

_SMALL = 64  # up to this many problems the 27 faces go to LAPACK in one stacked call

# state per variable: 0 free, 1 at lower bound, 2 at upper bound
_STATES = np.array(list(itertools.product((0, 1, 2), repeat=3)))  # (27, 3)


def gram(X: np.ndarray, y: np.ndarray, w: np.ndarray | None = None):
    """Weighted normal-equation terms of y ~ X @ x.

    X : (..., N, 3), y : (..., N), w : (..., N) or None.
    Returns G (..., 3, 3), g (..., 3), yy (...).
    """
    Xw, yw = (X, y) if w is None else (X * w[..., None], y * w)
    G = np.einsum("...ni,...nj->...ij", Xw, X)
    g = np.einsum("...ni,...n->...i", Xw, y)
    yy = np.einsum("...n,...n->...", yw, y)
    return G, g, yy


def box_lsq3(
    G: np.ndarray, g: np.ndarray, yy: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Global minimum of x'Gx - 2g'x + yy subject to lo <= x <= hi.

    The compiled kernel (:func:`terracone.inverse.solver.kernels.box_lsq3_flat`)
    when numba is enabled (:func:`terracone.jit.enabled`), else the numpy
    reference :func:`box_lsq3_reference`; same arguments and results (to
    rounding).

    Parameters
    ----------
    G : (..., 3, 3) symmetric positive semi-definite
    g : (..., 3)
    yy : (...)
    lo, hi : (..., 3) with lo <= hi (lo == hi fixes a variable)

    Returns
    -------
    x : (..., 3)
    sse : (...)
        The objective at x (the weighted sum of squared residuals).
    """
    if not enabled():
        return box_lsq3_reference(G, g, yy, lo, hi)
    from terracone.inverse.solver.kernels import box_lsq3_flat

    G, g, lo, hi = (np.asarray(a, dtype=float) for a in (G, g, lo, hi))
    yy = np.asarray(yy, dtype=float)
    shape = np.broadcast_shapes(
        G.shape[:-2], g.shape[:-1], lo.shape[:-1], hi.shape[:-1], np.shape(yy)
    )
    M = math.prod(shape)

    def flat(a: np.ndarray, tail: tuple[int, ...]) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(a, shape + tail)).reshape((M,) + tail)

    x, sse = box_lsq3_flat(
        flat(G, (3, 3)), flat(g, (3,)), flat(yy, ()), flat(lo, (3,)), flat(hi, (3,))
    )
    return x.reshape(shape + (3,)), sse.reshape(shape)


def box_lsq3_reference(
    G: np.ndarray, g: np.ndarray, yy: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Global minimum of x'Gx - 2g'x + yy subject to lo <= x <= hi (numpy reference).

    Parameters
    ----------
    G : (..., 3, 3) symmetric positive semi-definite
    g : (..., 3)
    yy : (...)
    lo, hi : (..., 3) with lo <= hi (lo == hi fixes a variable)

    Returns
    -------
    x : (..., 3)
    sse : (...)
        The objective at x (the weighted sum of squared residuals).

    Notes
    -----
    Each of the 27 faces is solved in closed form (1x1, 2x2 or 3x3
    Cramer's rule on the reduced normal equations, after scaling to unit
    diagonal), elementwise over the leading dimensions.
    """
    G, g, lo, hi = (np.asarray(a, dtype=float) for a in (G, g, lo, hi))
    shape = np.broadcast_shapes(
        G.shape[:-2], g.shape[:-1], lo.shape[:-1], hi.shape[:-1], np.shape(yy)
    )
    G = np.broadcast_to(G, shape + (3, 3))
    g, lo, hi = (np.broadcast_to(a, shape + (3,)) for a in (g, lo, hi))
    yy = np.broadcast_to(np.asarray(yy, dtype=float), shape)
    if math.prod(shape) <= _SMALL:
        return _box_lsq3_stacked(G, g, yy, lo, hi)

    # scale to unit diagonal for conditioning
    d = [np.sqrt(np.clip(G[..., i, i], 1e-300, None)) for i in range(3)]
    S = [[G[..., i, j] / (d[i] * d[j]) for j in range(3)] for i in range(3)]
    diag = [S[i][i] for i in range(3)]  # the objective uses the unperturbed diagonal
    for i in range(3):
        S[i][i] = S[i][i] + 1e-13  # tiny ridge in the solves: keeps collinear faces solvable
    b = [g[..., i] / d[i] for i in range(3)]
    L = [lo[..., i] * d[i] for i in range(3)]
    H = [hi[..., i] * d[i] for i in range(3)]
    best, bx, bstate = _best_face(S, diag, b, L, H, shape)
    # variables held at a bound get the bound itself, not a rescaled copy of it
    state, x = np.stack(bstate, axis=-1), np.stack(bx, axis=-1) / np.stack(d, axis=-1)
    xs = np.clip(np.where(state == 1, lo, np.where(state == 2, hi, x)), lo, hi)
    return xs, np.maximum(best + yy, 0.0)


def _best_face(S, diag, b, L, H, shape):
    """The best feasible face of each problem scaled to unit diagonal (lists per variable).

    Returns the objective without y'y, the scaled x and the state of each
    variable (0 free, 1 lower, 2 upper).
    """
    tol = [1e-9 * np.maximum(H[i] - L[i], 1e-300) + 1e-12 for i in range(3)]
    best = np.full(shape, np.inf)
    bx = [np.zeros(shape) for _ in range(3)]
    bstate = [np.zeros(shape, dtype=np.int8) for _ in range(3)]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for state in _STATES:
            free = [i for i in range(3) if state[i] == 0]
            x: list = [L[i] if state[i] == 1 else H[i] if state[i] == 2 else None for i in range(3)]
            _solve_face(S, b, x, state, free)
            feas = np.ones(shape, dtype=bool)
            for i in free:
                feas &= (x[i] >= L[i] - tol[i]) & (x[i] <= H[i] + tol[i])
                x[i] = np.clip(x[i], L[i], H[i])
            obj = (
                diag[0] * x[0] * x[0]
                + diag[1] * x[1] * x[1]
                + diag[2] * x[2] * x[2]
                + 2.0 * (S[0][1] * x[0] * x[1] + S[0][2] * x[0] * x[2] + S[1][2] * x[1] * x[2])
                - 2.0 * (b[0] * x[0] + b[1] * x[1] + b[2] * x[2])
            )
            better = feas & (obj < best)
            best = np.where(better, obj, best)
            for i in range(3):
                bx[i] = np.where(better, x[i], bx[i])
                bstate[i] = np.where(better, state[i], bstate[i])
    return best, bx, bstate


def _solve_face(S, b, x, state, free) -> None:
    """The free variables of x (list) on one face: the reduced normal equations, Cramer's rule."""
    r = {}  # right-hand sides of the free rows, fixed variables moved over
    for i in free:
        r[i] = b[i]
        for j in range(3):
            if state[j] != 0:
                r[i] = r[i] - S[i][j] * x[j]
    if len(free) == 1:
        (i,) = free
        x[i] = r[i] / S[i][i]
    elif len(free) == 2:
        i, j = free
        det = S[i][i] * S[j][j] - S[i][j] * S[j][i]
        x[i] = (r[i] * S[j][j] - S[i][j] * r[j]) / det
        x[j] = (S[i][i] * r[j] - S[j][i] * r[i]) / det
    elif len(free) == 3:
        a00, a01, a02 = S[0]
        a10, a11, a12 = S[1]
        a20, a21, a22 = S[2]
        c00 = a11 * a22 - a12 * a21
        c01 = a12 * a20 - a10 * a22
        c02 = a10 * a21 - a11 * a20
        det = a00 * c00 + a01 * c01 + a02 * c02
        r0, r1, r2 = r[0], r[1], r[2]
        x[0] = (r0 * c00 + r1 * (a02 * a21 - a01 * a22) + r2 * (a01 * a12 - a02 * a11)) / det
        x[1] = (r0 * c01 + r1 * (a00 * a22 - a02 * a20) + r2 * (a02 * a10 - a00 * a12)) / det
        x[2] = (r0 * c02 + r1 * (a01 * a20 - a00 * a21) + r2 * (a00 * a11 - a01 * a10)) / det


def _box_lsq3_stacked(G, g, yy, lo, hi):
    """:func:`box_lsq3` for a few problems: the 27 faces as one stacked LAPACK solve.

    Fewer numpy calls than the elementwise Cramer path, so faster when the
    leading dimensions are small (a single profile's refinement steps).
    """
    shape = yy.shape
    d = np.sqrt(np.clip(np.einsum("...ii->...i", G), 1e-300, None))
    Gs = G / (d[..., :, None] * d[..., None, :])
    gs = g / d
    los, his = lo * d, hi * d
    S = _STATES.reshape((27,) + (1,) * len(shape) + (3,))
    free = S == 0
    fixed_val = np.where(S == 1, los, his)  # (27, ..., 3)
    eye = np.eye(3)
    # reduced normal equations: identity rows for variables held at a bound
    A = np.where(free[..., :, None], Gs, eye) + (1e-13 * free)[..., :, None] * eye
    b = np.where(free, gs, fixed_val)
    try:
        xs = np.linalg.solve(A, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        xs = np.einsum("...ij,...j->...i", np.linalg.pinv(A), b)
    tol = 1e-9 * np.maximum(his - los, 1e-300) + 1e-12
    feasible = np.all(~free | ((xs >= los - tol) & (xs <= his + tol)), axis=-1)
    xs = np.clip(xs, los, his)
    obj = np.einsum("...i,...ij,...j->...", xs, Gs, xs) - 2.0 * np.einsum("...i,...i->...", gs, xs)
    obj = np.where(feasible, obj, np.inf)
    k = np.argmin(obj, axis=0)
    x = np.take_along_axis(xs, k[None, ..., None], axis=0)[0] / d
    # variables held at a bound get the bound itself
    state = _STATES[k]  # (..., 3)
    x = np.clip(np.where(state == 1, lo, np.where(state == 2, hi, x)), lo, hi)
    sse = np.take_along_axis(obj, k[None], axis=0)[0] + yy
    return x, np.maximum(sse, 0.0)

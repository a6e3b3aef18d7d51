"""Bounded linear least squares in three variables, vectorised.

For fixed n and phic the improved cone model (eq. (2-7) in [1]_) is linear
in (kc, kphi, cc).  Minimising a convex quadratic over a box is done exactly
by enumerating the 3^3 = 27 faces of the box (each variable free, at its
lower or at its upper bound): the minimiser of the quadratic on each face's
affine hull is a closed-form 3x3 solve, and the best feasible one is the
global optimum.  All of it broadcasts over leading dimensions, so thousands
of (n, phic, profile) cells are solved in one numpy call.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-7).
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["box_lsq3", "gram"]

# state per variable: 0 free, 1 at lower bound, 2 at upper bound
_STATES = np.array(list(itertools.product((0, 1, 2), repeat=3)))  # (27, 3)


def gram(X: np.ndarray, y: np.ndarray, w: np.ndarray | None = None):
    """Weighted normal-equation terms of y ~ X @ x.

    X : (..., N, 3), y : (..., N), w : (..., N) or None.
    Returns G (..., 3, 3), g (..., 3), yy (...).
    """
    if w is not None:
        Xw = X * w[..., None]
        yw = y * w
    else:
        Xw, yw = X, y
    G = np.einsum("...ni,...nj->...ij", Xw, X)
    g = np.einsum("...ni,...n->...i", Xw, y)
    yy = np.einsum("...n,...n->...", yw, y)
    return G, g, yy


def box_lsq3(
    G: np.ndarray, g: np.ndarray, yy: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Global minimum of x'Gx - 2g'x + yy subject to lo <= x <= hi.

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
    G, g, lo, hi = (np.asarray(a, dtype=float) for a in (G, g, lo, hi))
    shape = np.broadcast_shapes(
        G.shape[:-2], g.shape[:-1], lo.shape[:-1], hi.shape[:-1], np.shape(yy)
    )
    G = np.broadcast_to(G, shape + (3, 3))
    g = np.broadcast_to(g, shape + (3,))
    lo = np.broadcast_to(lo, shape + (3,))
    hi = np.broadcast_to(hi, shape + (3,))
    yy = np.broadcast_to(np.asarray(yy, dtype=float), shape)

    # scale to unit diagonal for conditioning
    d = np.sqrt(np.clip(np.einsum("...ii->...i", G), 1e-300, None))
    Gs = G / (d[..., :, None] * d[..., None, :])
    gs = g / d
    los, his = lo * d, hi * d

    S = _STATES.reshape((27,) + (1,) * len(shape) + (3,))
    free = S == 0
    fixed_val = np.where(S == 1, los, his)  # (27, ..., 3)
    eye = np.eye(3)
    # reduced normal equations: identity rows for variables held at a bound
    A = np.where(free[..., :, None], Gs, eye)
    b = np.where(free, gs, fixed_val)
    ridge = 1e-13 * np.where(free, 1.0, 0.0)
    A = A + ridge[..., :, None] * eye
    try:
        xs = np.linalg.solve(A, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        xs = np.einsum("...ij,...j->...i", np.linalg.pinv(A), b)
    span = his - los
    tol = 1e-9 * np.maximum(span, 1e-300) + 1e-12
    feasible = np.all((xs >= los - tol) & (xs <= his + tol), axis=-1)
    xs = np.clip(xs, los, his)
    obj = np.einsum("...i,...ij,...j->...", xs, Gs, xs) - 2.0 * np.einsum("...i,...i->...", gs, xs)
    obj = np.where(feasible, obj, np.inf)
    k = np.argmin(obj, axis=0)
    x = np.take_along_axis(xs, k[None, ..., None], axis=0)[0] / d
    sse = np.take_along_axis(obj, k[None], axis=0)[0] + yy
    return x, np.maximum(sse, 0.0)

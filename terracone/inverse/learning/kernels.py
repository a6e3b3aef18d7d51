"""Compiled kernels of the learning process (numba, see :mod:`terracone.jit`).

:func:`cone_columns` gives the cone's design columns at many (n, r_min) points
at once (the numpy reference is :func:`terracone.physics.cone.cone_index_basis`).
:func:`sum_norm_cells` is a scalar port of
:func:`terracone.inverse.learning.sumnorm.sum_norm_box_reference`, looped over
cells so that one call does per cell what the reference does in some hundred
numpy calls on (data set, cell) arrays: the joint bounded least squares, then
the smoothed reweighting with its Newton candidates and the Lagrange dual
values, cell by cell until each cell's duality gap is below its tolerance.
The bounded 3-variable least squares is
:func:`terracone.inverse.solver.kernels.box_lsq3_one`.

The numpy implementations stay the reference: ``tests/test_learn_kernels.py``
compares each kernel with its twin, and ``TERRACONE_NUMBA=0`` (or :func:`terracone.jit.disabled`)
makes the learning process take the numpy paths.

References
----------
.. [1] Boyd, S., Vandenberghe, L. (2004). Convex Optimization. Cambridge
   University Press. Section 5.2 (Lagrange dual) and 6.1 (norm approximation).
"""

from __future__ import annotations

import math

import numpy as np

from terracone.inverse.solver import kernels as solver_kernels
from terracone.jit import njit

__all__ = ["cone_columns", "sum_norm_cells"]

#: step lengths of the Newton candidates (as :func:`sumnorm._newton_or_mm`)
NEWTON_STEPS = (1.0, 0.5, 0.25, 0.125, 1.0 / 64.0)


@njit(error_model="numpy")
def cell_value(G, g, yy, a, c, x, sse) -> float:
    """J = sum_d a_d sqrt(SSE_d) of cell c at x (3,); SSE_d (clipped at 0) into sse (D,)."""
    J = 0.0
    for d in range(a.shape[0]):
        s = yy[d, c]
        for i in range(3):
            gx = 0.0
            for j in range(3):
                gx += G[d, c, i, j] * x[j]
            s += x[i] * gx - 2.0 * g[d, c, i] * x[i]
        s = max(s, 0.0)
        sse[d] = s
        J += a[d] * math.sqrt(s)
    return J


@njit(error_model="numpy")
def cell_dual(G, g, yy, a, c, x, sse, e2, lo, hi) -> float:
    """Lagrange dual value at u_d = a_d r_d / sqrt(SSE_d + e2_d): a lower bound of the minimum."""
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    uy = 0.0
    for d in range(a.shape[0]):
        t = a[d] / math.sqrt(sse[d] + e2[d])
        r0 = G[d, c, 0, 0] * x[0] + G[d, c, 0, 1] * x[1] + G[d, c, 0, 2] * x[2] - g[d, c, 0]
        r1 = G[d, c, 1, 0] * x[0] + G[d, c, 1, 1] * x[1] + G[d, c, 1, 2] * x[2] - g[d, c, 1]
        r2 = G[d, c, 2, 0] * x[0] + G[d, c, 2, 1] * x[1] + G[d, c, 2, 2] * x[2] - g[d, c, 2]
        c0 += t * r0
        c1 += t * r1
        c2 += t * r2
        uy += t * (g[d, c, 0] * x[0] + g[d, c, 1] * x[1] + g[d, c, 2] * x[2] - yy[d, c])
    return (
        -uy
        + min(c0 * lo[0], c0 * hi[0])
        + min(c1 * lo[1], c1 * hi[1])
        + min(c2 * lo[2], c2 * hi[2])
    )


@njit(error_model="numpy")
def weighted_normal(G, g, yy, w, c, Gw, gw) -> float:
    """sum_d w_d G_d, sum_d w_d g_d into Gw (3, 3), gw (3,); returns sum_d w_d yy_d."""
    Gw[:, :] = 0.0
    gw[:] = 0.0
    yw = 0.0
    for d in range(w.shape[0]):
        for i in range(3):
            gw[i] += w[d] * g[d, c, i]
            for j in range(3):
                Gw[i, j] += w[d] * G[d, c, i, j]
        yw += w[d] * yy[d, c]
    return yw


@njit(error_model="numpy")
def newton_candidate(G, g, yy, a, c, x0, sse0, eps2, lo, hi, x_mm, ws, work, sse_t, x_out):
    """The best of the reweighting step x_mm and damped projected Newton steps from x0 on
    the smoothed objective sum_d a_d sqrt(SSE_d + eps2_d) (as ``_newton_or_mm``), into x_out."""
    H = work[0:3]
    rhs, x_n, xt, res, grad = work[3], work[4], work[5], work[6], work[7]
    H[:, :] = 0.0
    grad[:] = 0.0
    for d in range(a.shape[0]):
        s = math.sqrt(sse0[d] + eps2[d])
        for i in range(3):
            ri = -g[d, c, i]
            for j in range(3):
                ri += G[d, c, i, j] * x0[j]
            res[i] = ri
        for i in range(3):
            grad[i] += a[d] / s * res[i]
            for j in range(3):
                H[i, j] += a[d] / s * G[d, c, i, j] - a[d] / s**3 * res[i] * res[j]
    tr = H[0, 0] + H[1, 1] + H[2, 2]
    for i in range(3):
        H[i, i] += 1e-12 * tr
    for i in range(3):
        hx = 0.0
        for j in range(3):
            hx += H[i, j] * x0[j]
        rhs[i] = 0.5 * (hx - grad[i])
    for i in range(3):
        for j in range(3):
            H[i, j] *= 0.5
    solver_kernels.box_lsq3_one(H, rhs, 0.0, lo, hi, x_n, ws)
    best = cell_value(G, g, yy, a, c, x_mm, sse_t)
    x_out[:] = x_mm
    for t in NEWTON_STEPS:
        for i in range(3):
            xt[i] = x0[i] + t * (x_n[i] - x0[i])
        Jt = cell_value(G, g, yy, a, c, xt, sse_t)
        if Jt < best:
            best = Jt
            x_out[:] = xt


@njit(error_model="numpy")
def sum_norm_cells(G, g, yy, a, lo, hi, tol, max_iter, gram_res):
    """Certified minimum of sum_d a_d ||X_d x - y_d|| over lo <= x <= hi, cell by cell.

    G (D, M, 3, 3), g (D, M, 3), yy (D, M): Gram terms of M cells; a (D,);
    lo, hi (M, 3); tol (M,): duality gap at which a cell stops; gram_res:
    relative resolution of sqrt(SSE_d).  Returns x (M, 3), J (M,), lower
    (M,) (>= 0, <= J), SSE (D, M) at x and the reweighting steps per cell.
    """
    D, M = yy.shape
    x_best = np.empty((M, 3))
    J_best = np.empty(M)
    lower = np.empty(M)
    sse_best = np.empty((D, M))
    steps = np.zeros(M, np.int64)
    ws = np.empty((18, 3))
    ws[7, 0] = -1.0
    work = np.empty((8, 3))
    Gw, gw = np.empty((3, 3)), np.empty(3)
    x, xa, x_mm = np.empty(3), np.empty(3), np.empty(3)
    w, sse, sse_a, sse_t = np.empty(D), np.empty(D), np.empty(D), np.empty(D)
    eps2, e2 = np.empty(D), np.empty(D)
    for c in range(M):
        for d in range(D):
            w[d] = a[d] * a[d]
        yw = weighted_normal(G, g, yy, w, c, Gw, gw)
        solver_kernels.box_lsq3_one(Gw, gw, yw, lo[c], hi[c], x, ws)
        J = cell_value(G, g, yy, a, c, x, sse)
        zero = True
        for d in range(D):
            if sse[d] > gram_res**2 * yy[d, c]:
                zero = False
        low = 0.0 if zero else -np.inf
        x_best[c] = x
        J_best[c] = J
        sse_best[:, c] = sse
        xa[:] = x
        sse_a[:] = sse
        done = zero or J - max(low, 0.0) <= tol[c]
        it = 0
        while not done and it < max_iter:
            it += 1
            eps = max(1e-3 * 0.3 ** (it - 1), gram_res)
            for d in range(D):
                eps2[d] = eps * eps * yy[d, c]
                w[d] = a[d] / (2.0 * math.sqrt(sse_a[d] + eps2[d]))
            yw = weighted_normal(G, g, yy, w, c, Gw, gw)
            solver_kernels.box_lsq3_one(Gw, gw, yw, lo[c], hi[c], x_mm, ws)
            newton_candidate(
                G, g, yy, a, c, xa, sse_a, eps2, lo[c], hi[c], x_mm, ws, work, sse_t, x
            )
            xa[:] = x
            J = cell_value(G, g, yy, a, c, xa, sse_a)
            for k in range(3):  # dual points of the current and two fixed smoothing levels
                for d in range(D):
                    e2[d] = eps2[d] if k == 0 else (1e-8 if k == 1 else 1e-12) * yy[d, c]
                low = max(low, cell_dual(G, g, yy, a, c, xa, sse_a, e2, lo[c], hi[c]))
            if J < J_best[c]:
                J_best[c] = J
                x_best[c] = xa
                sse_best[:, c] = sse_a
            done = J_best[c] - max(low, 0.0) <= tol[c]
        steps[c] = it
        lower[c] = min(max(low, 0.0), J_best[c])
    return x_best, J_best, lower, sse_best, steps


@njit(error_model="numpy")
def cone_columns(z, n, H, R, rm1, r_t, alpha, beta):
    """Columns A, B, C (K, Z) of eq. (2-7) at depths z (Z,) for K points, each with its own
    exponent n and pressure law (r_t, alpha, beta), fully mobilised shear, phic = 0.

    As :func:`terracone.physics.cone.cone_index_basis` at phic = 0: the depth
    table and columns of :mod:`terracone.inverse.solver.kernels`
    (:func:`~terracone.inverse.solver.kernels.depth_table`,
    :func:`~terracone.inverse.solver.kernels.columns_at`) per point, since the
    table depends on the law's r_t.
    """
    K = n.shape[0]
    Z = z.shape[0]
    A = np.empty((K, Z))
    B = np.empty((K, Z))
    C = np.empty((K, Z))
    tab = np.empty((7, Z))
    last = np.nan
    for k in range(K):
        if not r_t[k] == last:  # the table depends on the law only through r_t
            solver_kernels.depth_table(z, H, R, r_t[k], tab)
            last = r_t[k]
        solver_kernels.columns_at(
            z, tab, n[k], H, R, rm1, r_t[k], alpha[k], beta[k], z, False, A[k], B[k], C[k]
        )
    return A, B, C

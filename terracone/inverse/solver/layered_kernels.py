"""Compiled kernels of the layered solver (numba, see :mod:`terracone.jit`).

The layered terrain of :mod:`terracone.physics.layers` is linear in each
layer's (kc, kphi, cc) once the interfaces D and the layers' exponents n are
fixed: a bounded linear least squares in 3L variables.  These kernels do the
inner work of :mod:`terracone.inverse.layered.search`:

* :func:`part_columns`: the columns of eq. (2-7) for the part of one cone
  between two distances from its tip (eqs. (2-2) to (2-6), RM0 or RM1 of
  section 3.2 of [1]_), the scalar port of
  :func:`terracone.physics.cone.normal_integrals`;
* :func:`design_rows`: the layered design matrix of one profile
  (:func:`terracone.physics.layers.layered_basis`);
* :func:`boxqp`: the exact bounded least squares in any number of variables
  (a primal active-set method on the normal equations scaled to unit
  diagonal, warm-started from the previous problem's active set);
* :func:`layered_sse_many`: the SSE and solution at many (D, n) points;
* :func:`segment_sse`: the one-layer SSE of every run of consecutive
  measured depths at every n of a grid (the pieces of the separable bound);
* :func:`cell_terms`: the per-layer Lagrangian terms of the bound of a cell
  of interface depths (see the search module);
* :func:`nelder_mead`: the local refinement of (D, n).

Each has a numpy twin in :mod:`terracone.inverse.solver.layered_numpy`
(tested against each other to 1e-12 in ``tests/test_layered_kernels.py``);
with ``TERRACONE_NUMBA=0`` the search takes the numpy paths.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7), section 3.2.
"""

from __future__ import annotations

import math

import numpy as np

from terracone.inverse.solver import kernels as k3  # called as k3.name: numba resolves it then
from terracone.jit import njit

__all__ = [
    "part_columns",
    "part_columns_log",
    "embedded_logs",
    "layer_part",
    "design_rows",
    "boxqp",
    "cholesky_solve",
    "release_candidate",
    "layered_sse",
    "design_rows_from",
    "design_sse",
    "layered_sse_many",
    "full_columns",
    "segment_sse",
    "cell_terms",
    "nelder_mead",
]

RIDGE = 1e-13  # on the unit diagonal of the scaled normal equations, as the 3-variable solver


@njit(error_model="numpy")
def part_columns(u1, lu1, a, b, n, s, t, R, rm1, r_t, alpha, beta):
    """Columns (A, B, C) of eq. (2-7) for the part of a cone between distances a <= b from its tip.

    u1 : depth of the tip [m] (> 0), lu1 = log(u1); n : exponent; s : scale of
    the kc and kphi columns, 1 + tan(phic)/tan(alpha) (eq. (2-6) fully
    mobilised); t = R/H; R : base radius [m]; RM1 (``rm1``) with
    (r_t, alpha, beta) of :meth:`terracone.physics.plate.PressureLaw.coefficients`.
    CI = kc A + kphi B + cc C for that part of the cone, as
    :func:`terracone.physics.cone.normal_integrals` (eqs. (2-2), (2-5), (2-7)).
    """
    return part_columns_log(u1, lu1, a, b, n, s, t, R, rm1, r_t, alpha, beta, -1.0, 0.0, 0.0)


@njit(error_model="numpy")
def part_columns_log(u1, lu1, a, b, n, s, t, R, rm1, r_t, alpha, beta, emb, l1e, l1s):
    """:func:`part_columns` with, when b == emb (the part reaches the cone's base), the n-free
    logarithms log1p(-b/u1) = l1e and (RM1) log1p(-min(b, r_t/t)/u1) = l1s given (as
    :func:`embedded_logs`): the same numbers, two logarithms fewer."""
    if not (b > a) or not (u1 > 0.0):
        return 0.0, 0.0, 0.0
    base = b == emb
    eb = min(max(b / u1, 0.0), 1.0)
    if base:
        g0b, g1b, g2b = k3.tail_moments_log(eb, l1e, n)
    else:
        g0b, g1b, g2b = k3.tail_moments(eb, n)
    g0a = g1a = g2a = 0.0
    if a > 0.0:
        g0a, g1a, g2a = k3.tail_moments(min(max(a / u1, 0.0), 1.0), n)
    p1 = math.exp((n + 1.0) * lu1)  # u1^(n+1)
    p2 = p1 * u1
    i_phi = t * p2 * (g1b - g1a)  # eq. (2-5), per unit kphi
    i_cc = 0.5 * t * (b * b - a * a)
    if not rm1:
        i_c = p1 * (g0b - g0a)  # eq. (2-2), per unit kc
    else:  # RM1 of section 3.2: the linear branch below r_t
        p3 = p2 * u1
        d_s = r_t / t
        es = min(max(min(b, d_s) / u1, 0.0), 1.0)
        if base:
            g0s, g1s, g2s = k3.tail_moments_log(es, l1s, n)
        else:
            g0s, g1s, g2s = k3.tail_moments(es, n)
        if a < d_s:
            i_c = p1 * (g0b - g0s) + alpha * t * p2 * (g1s - g1a) - beta * t * t * p3 * (g2s - g2a)
        else:
            i_c = p1 * (g0b - g0a)
    rr = R * R
    return 2.0 * t * s * i_c / rr, 2.0 * t * s * i_phi / rr, 2.0 * i_cc / rr


@njit(error_model="numpy")
def embedded_logs(z, geom, lg) -> None:
    """Per base depth z (Z,) the n-free logarithms of the design rows into lg (3, Z): log of
    the tip depth u1, log1p(-emb/u1) and log1p(-min(emb, r_t/t)/u1) (emb the embedded
    length; -inf where the ratio is 1), as :func:`part_columns` computes them."""
    H, R, rm1, r_t, alpha, beta = geom
    t = R / H
    for q in range(z.shape[0]):
        u1 = z[q] + H
        lg[0, q], lg[1, q], lg[2, q] = 0.0, 0.0, 0.0
        if not u1 > 0.0:
            continue
        lg[0, q] = math.log(u1)
        emb = H if z[q] >= 0.0 else u1
        eb = min(max(emb / u1, 0.0), 1.0)
        es = min(max(min(emb, r_t / t) / u1, 0.0), 1.0)
        lg[1, q] = math.log1p(-eb) if eb < 1.0 else -math.inf
        lg[2, q] = math.log1p(-es) if es < 1.0 else -math.inf


@njit(error_model="numpy")
def layer_part(z, H, lu1, d_top, d_bot, n, s, R, rm1, r_t, alpha, beta):
    """Columns of the part of the cone at base depth z [m] lying between depths d_top and d_bot.

    The cone's embedded part spans the depths max(z, 0) to z + H; the layer
    between d_top and d_bot (d_bot = inf for the last layer) takes distances
    from the tip in [clip(u1 - d_bot), clip(u1 - d_top)] (as
    :func:`terracone.physics.layers.layered_basis`).
    """
    u1 = z + H
    if not u1 > 0.0:
        return 0.0, 0.0, 0.0
    emb = H if z >= 0.0 else u1
    a = min(max(u1 - d_bot, 0.0), emb)
    b = min(max(u1 - d_top, 0.0), emb)
    return part_columns(u1, lu1, a, b, n, s, R / H, R, rm1, r_t, alpha, beta)


@njit(error_model="numpy")
def design_rows(z, lu1, D, ns, s, geom, X) -> None:
    """The layered design matrix X (Z, 3L): CI = X @ (kc_1, kphi_1, cc_1, kc_2, ...).

    z (Z,) base depths [m], lu1 (Z,) log of the tip depths, D (L-1,)
    interfaces [m] increasing, ns (L,) exponents, geom = (H, R, rm1, r_t,
    alpha, beta).  The first layer starts at the surface (depth 0).
    """
    H, R, rm1, r_t, alpha, beta = geom
    L = ns.shape[0]
    for q in range(z.shape[0]):
        for j in range(L):
            d_top = 0.0 if j == 0 else D[j - 1]
            d_bot = math.inf if j == L - 1 else D[j]
            a, b, c = layer_part(z[q], H, lu1[q], d_top, d_bot, ns[j], s, R, rm1, r_t, alpha, beta)
            X[q, 3 * j], X[q, 3 * j + 1], X[q, 3 * j + 2] = a, b, c


@njit(error_model="numpy")
def cholesky_free(S, st, C, idx, valid=0) -> int:
    """Cholesky factor C of S restricted to the variables with st == 0 (their indices into idx).

    S has unit diagonal plus :data:`RIDGE`.  The first ``valid`` rows of C and
    idx may hold the factor of an earlier free set of the same S: the rows
    up to the first free variable that differs are kept (they depend only on
    the variables before them), the rest computed.  Returns the number of
    free variables, or -1 when a pivot is not positive (numerically singular).
    """
    k = S.shape[0]
    m = 0
    first = -1
    for i in range(k):
        if st[i] == 0:
            if first < 0 and (m >= valid or idx[m] != i):
                first = m
            idx[m] = i
            m += 1
    if first < 0:
        first = m
    for a in range(first, m):
        for b in range(a + 1):
            acc = S[idx[a], idx[b]] + (RIDGE if a == b else 0.0)
            for c in range(b):
                acc -= C[a, c] * C[b, c]
            if a == b:
                if not acc > 0.0:
                    return -1
                C[a, a] = math.sqrt(acc)
            else:
                C[a, b] = acc / C[b, b]
    return m


@njit(error_model="numpy")
def cholesky_solve(C, w, m) -> None:
    """Solve (C C') u = w in place for the leading m rows (C lower triangular)."""
    for a in range(m):  # forward then back substitution
        acc = w[a]
        for c in range(a):
            acc -= C[a, c] * w[c]
        w[a] = acc / C[a, a]
    for a in range(m - 1, -1, -1):
        acc = w[a]
        for c in range(a + 1, m):
            acc -= C[c, a] * w[c]
        w[a] = acc / C[a, a]


@njit(error_model="numpy")
def release_candidate(S, b, v, st, Lb, Ub, gr) -> int:
    """The held variable of :func:`boxqp` whose gradient (stored in ``gr``) points most into
    the box beyond a relative 1e-11, or -1 when every held variable is optimal."""
    worst, viol = -1, 0.0
    for i in range(S.shape[0]):
        if st[i] == 1 or st[i] == 2:
            if Lb[i] == Ub[i]:
                continue
            gi = -b[i]
            size = abs(b[i])
            for j in range(S.shape[0]):
                gi += S[i, j] * v[j]
                size += abs(S[i, j] * v[j])
            gr[i] = gi
            tol = 1e-11 * size + 1e-300
            if st[i] == 1 and gi < -tol and -gi > viol:
                worst, viol = i, -gi
            elif st[i] == 2 and gi > tol and gi > viol:
                worst, viol = i, gi
    return worst


@njit(error_model="numpy")
def boxqp(G, g, lo, hi, x, st, ws, C, idx) -> int:
    """Minimise x'Gx - 2 g'x over lo <= x <= hi (G symmetric positive semi-definite, k variables).

    A primal active-set method on the normal equations scaled to unit
    diagonal (with :data:`RIDGE`): solve for the free variables with the
    others at their bounds, step back to the box when the solution leaves
    it (holding the variable that blocks), release the held variable whose
    gradient points most into the box, until every held variable's gradient
    points out of it (the optimality conditions of a convex quadratic over a
    box, to a relative 1e-11).  ``st`` (k,) int: in, the face to start from
    (0 free, 1 at lo, 2 at hi; the previous problem's, or all 0) with x the
    previous solution; out, the optimal face.  A variable whose column is
    zero is held at lo.  ws (7, k), C (k, k), idx (k,) work arrays.
    Returns the iterations used (-1: no convergence).
    """
    k = G.shape[0]
    d, v, w, Lb, Ub, b, gr = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], ws[6]
    for i in range(k):
        d[i] = math.sqrt(G[i, i]) if G[i, i] > 0.0 else 0.0
    for i in range(k):
        if d[i] == 0.0:
            st[i] = 3  # dead: held at lo, out of the problem
            d[i] = 1.0
        elif st[i] == 3:
            st[i] = 0
        Lb[i] = lo[i] * d[i]
        Ub[i] = hi[i] * d[i]
        b[i] = g[i] / d[i]
        if st[i] == 1 or st[i] == 3 or Lb[i] == Ub[i]:
            v[i] = Lb[i]
            if st[i] != 3:
                st[i] = 1
        elif st[i] == 2:
            v[i] = Ub[i]
        else:
            v[i] = min(max(x[i] * d[i], Lb[i]), Ub[i])
    S = ws[7 : 7 + k]  # the scaled matrix
    for i in range(k):
        for j in range(k):
            S[i, j] = G[i, j] / (d[i] * d[j]) if st[i] != 3 and st[j] != 3 else 0.0
    it = 0
    m = 0
    while it < 20 + 10 * k:
        it += 1
        m = cholesky_free(S, st, C, idx, m)  # the rows of the free variables kept are kept
        if m < 0:
            return -1
        # right-hand side of the free rows, held variables moved over
        for a in range(m):
            i = idx[a]
            r = b[i]
            for j in range(k):
                if st[j] != 0:
                    r -= S[i, j] * v[j]
            w[a] = r
        cholesky_solve(C, w, m)
        step, block, side = 1.0, -1, 0
        for a in range(m):
            i = idx[a]
            if w[a] < Lb[i] and w[a] < v[i]:
                f = (Lb[i] - v[i]) / (w[a] - v[i])
                if f < step:
                    step, block, side = f, i, 1
            elif w[a] > Ub[i] and w[a] > v[i]:
                f = (Ub[i] - v[i]) / (w[a] - v[i])
                if f < step:
                    step, block, side = f, i, 2
        step = max(step, 0.0)
        for a in range(m):
            i = idx[a]
            v[i] = min(max(v[i] + step * (w[a] - v[i]), Lb[i]), Ub[i])
        if block >= 0:
            st[block] = side
            v[block] = Lb[block] if side == 1 else Ub[block]
            continue
        # optimal on this face: release the held variable whose gradient points most inwards
        worst = release_candidate(S, b, v, st, Lb, Ub, gr)
        if worst < 0:
            break
        st[worst] = 0
    for i in range(k):
        if st[i] == 1 or st[i] == 3:
            x[i] = lo[i]
        elif st[i] == 2:
            x[i] = hi[i]
        else:
            x[i] = min(max(v[i] / d[i], lo[i]), hi[i])
        if st[i] == 3:
            d[i] = 0.0
    return it


@njit(error_model="numpy")
def new_work(Z, k):
    """Work arrays of :func:`layered_sse`: X (Z, k), G (k, k), g, lo, hi, x (k,), st (k,),
    ws (7 + k, k), C (k, k), idx (k,)."""
    return (
        np.zeros((Z, k)),
        np.zeros((k, k)),
        np.zeros(k),
        np.zeros(k),
        np.zeros(k),
        np.zeros(k),
        np.zeros(k, dtype=np.int64),
        np.zeros((7 + k, k)),
        np.zeros((k, k)),
        np.zeros(k, dtype=np.int64),
    )


@njit(error_model="numpy")
def layered_sse(z, y, lu1, D, ns, s, bp, geom, work) -> float:
    """SSE [kPa^2] of the best (kc, kphi, cc) per layer at interfaces D and exponents ns.

    The box of each layer is :func:`terracone.inverse.solver.kernels.kbounds`
    at its n (``bp`` as there); the SSE is summed from the residuals (the
    normal-equation form cancels near a perfect fit).  The solution is left
    in work[5] (x) and its face in work[6] (the next call starts there).
    """
    design_rows(z, lu1, D, ns, s, geom, work[0])
    return design_sse(y, ns, bp, work, False)


@njit(error_model="numpy")
def design_rows_from(z, lg, D, ns, s, geom, X, D0, ns0, X0) -> None:
    """:func:`design_rows` into X, the columns of a layer whose top, bottom and n are those of
    (D0, ns0) copied from X0 (the design there) instead of computed: the same numbers.  lg
    (3, Z): the logarithms of :func:`embedded_logs`."""
    H, R, rm1, r_t, alpha, beta = geom
    L = ns.shape[0]
    t = R / H
    for j in range(L):
        d_top = 0.0 if j == 0 else D[j - 1]
        d_bot = math.inf if j == L - 1 else D[j]
        same = ns[j] == ns0[j] and (j == 0 or D0[j - 1] == d_top) and (j == L - 1 or D0[j] == d_bot)
        for q in range(z.shape[0]):
            if same:
                X[q, 3 * j], X[q, 3 * j + 1], X[q, 3 * j + 2] = (
                    X0[q, 3 * j],
                    X0[q, 3 * j + 1],
                    X0[q, 3 * j + 2],
                )
                continue
            u1 = z[q] + H  # as layer_part
            if not u1 > 0.0:
                X[q, 3 * j], X[q, 3 * j + 1], X[q, 3 * j + 2] = 0.0, 0.0, 0.0
                continue
            emb = H if z[q] >= 0.0 else u1
            a = min(max(u1 - d_bot, 0.0), emb)
            b = min(max(u1 - d_top, 0.0), emb)
            A, B, C = part_columns_log(
                u1, lg[0, q], a, b, ns[j], s, t, R, rm1, r_t, alpha, beta, emb, lg[1, q], lg[2, q]
            )
            X[q, 3 * j], X[q, 3 * j + 1], X[q, 3 * j + 2] = A, B, C


@njit(error_model="numpy")
def design_sse(y, ns, bp, work, boxed) -> float:
    """:func:`layered_sse` with the design already in work[0]: the normal equations into work[1]
    and work[2], the box at ns into work[3] and work[4] (there already when ``boxed``), the best
    x into work[5] (from the face in work[6] and the x in work[5]); returns its SSE.  With a held
    kc/kphi (``bp[10]`` not NaN) each layer's kc column is folded into its kphi column in
    work[0] first (kc = ratio kphi; its box is pinned at 0 by ``kbounds``)."""
    X, G, g, lo, hi, x, st, ws, C, idx = work
    Z = X.shape[0]
    k = X.shape[1]
    ratio = bp[10]
    if not math.isnan(ratio):  # kc = ratio kphi: the kc columns fold into kphi's (idempotent)
        for q in range(Z):
            for j in range(k // 3):
                X[q, 3 * j + 1] += ratio * X[q, 3 * j]
                X[q, 3 * j] = 0.0
    for i in range(k):
        g[i] = 0.0
        for j in range(k):
            G[i, j] = 0.0
    for q in range(Z):
        for i in range(k):
            xi = X[q, i]
            if xi != 0.0:
                g[i] += xi * y[q]
                for j in range(i + 1):
                    G[i, j] += xi * X[q, j]
    for i in range(k):
        for j in range(i):
            G[j, i] = G[i, j]
    for j in range(k // 3):
        if not boxed:
            k3.kbounds(ns[j], bp, lo[3 * j : 3 * j + 3], hi[3 * j : 3 * j + 3])
    if boxqp(G, g, lo, hi, x, st, ws, C, idx) < 0:
        for i in range(k):  # a singular face: start again from nothing held
            st[i] = 0
            x[i] = 0.0
        boxqp(G, g, lo, hi, x, st, ws, C, idx)
    acc = 0.0
    for q in range(Z):
        r = -y[q]
        for i in range(k):
            r += X[q, i] * x[i]
        acc += r * r
    return acc


@njit(error_model="numpy")
def layered_sse_many(z, y, Ds, nss, s, bp, geom):
    """:func:`layered_sse` at M points: Ds (M, L-1), nss (M, L).

    Returns SSE (M,), the solutions x (M, 3L) and the residuals (M, Z), model minus data.
    """
    M, L = nss.shape
    Z = z.shape[0]
    lu1 = np.empty(Z)
    for q in range(Z):
        u1 = z[q] + geom[0]
        lu1[q] = math.log(u1) if u1 > 0.0 else 0.0
    work = new_work(Z, 3 * L)
    sse = np.empty(M)
    xs = np.empty((M, 3 * L))
    res = np.empty((M, Z))
    X, x = work[0], work[5]
    for m in range(M):
        sse[m] = layered_sse(z, y, lu1, Ds[m], nss[m], s, bp, geom, work)
        xs[m, :] = x
        for q in range(Z):
            r = -y[q]
            for i in range(3 * L):
                r += X[q, i] * x[i]
            res[m, q] = r
    return sse, xs, res


@njit(error_model="numpy")
def full_columns(z, ns, s, geom):
    """Columns (K, Z, 3) of the whole cone at every exponent of ns (K,) (one layer)."""
    H, R, rm1, r_t, alpha, beta = geom
    K = ns.shape[0]
    Z = z.shape[0]
    F = np.zeros((K, Z, 3))
    for q in range(Z):
        u1 = z[q] + H
        if not u1 > 0.0:
            continue
        lu1 = math.log(u1)
        for k in range(K):
            a, b, c = layer_part(z[q], H, lu1, 0.0, math.inf, ns[k], s, R, rm1, r_t, alpha, beta)
            F[k, q, 0], F[k, q, 1], F[k, q, 2] = a, b, c
    return F


@njit(error_model="numpy")
def quad3(G, g, yy, lo, hi, x, st, ws, C, idx) -> float:
    """min of x'Gx - 2 g'x + yy over lo <= x <= hi in 3 variables (:func:`boxqp`, warm start
    from x and st), the value from the normal equations (not clipped)."""
    boxqp(G, g, lo, hi, x, st, ws, C, idx)
    f = yy
    for a in range(3):
        f -= 2.0 * g[a] * x[a]
        for b in range(3):
            f += x[a] * G[a, b] * x[b]
    return f


@njit(error_model="numpy")
def add_row(G, g, F, k, q, yq) -> float:
    """Add row q of the full columns at grid index k, F[k, q] (3,), to the normal equations G
    (3, 3), g (3,) of data yq; returns yq^2 (for y'y)."""
    A, B, C = F[k, q, 0], F[k, q, 1], F[k, q, 2]
    G[0, 0] += A * A
    G[0, 1] += A * B
    G[0, 2] += A * C
    G[1, 1] += B * B
    G[1, 2] += B * C
    G[2, 2] += C * C
    G[1, 0], G[2, 0], G[2, 1] = G[0, 1], G[0, 2], G[1, 2]
    g[0] += A * yq
    g[1] += B * yq
    g[2] += C * yq
    return yq * yq


@njit(error_model="numpy")
def segment_sse(F, y, lo, hi, need):
    """One-layer SSE of runs of rows [i, j) at every n: (Z + 1, Z + 1, K).

    F (K, Z, 3) full columns, lo, hi (K, 3) the box at each n; only the runs
    with need[i, j] are solved (the others are NaN); an empty run has SSE 0.
    The normal equations are summed from row i down (no differences of
    running sums); the SSE is their minimum over the box (:func:`boxqp`),
    floored at 0, which is what a lower bound needs.
    """
    K, Z, _ = F.shape
    out = np.full((Z + 1, Z + 1, K), np.nan)
    G = np.zeros((3, 3))
    g = np.zeros(3)
    x = np.zeros(3)
    st = np.zeros(3, dtype=np.int64)
    ws = np.zeros((10, 3))
    Cw = np.zeros((3, 3))
    idx = np.zeros(3, dtype=np.int64)
    for i in range(Z + 1):
        last = -1
        for j in range(i, Z + 1):
            if need[i, j]:
                last = j
        if last < 0:
            continue
        for k in range(K):
            G[:] = 0.0
            g[:] = 0.0
            yy = 0.0
            if need[i, i]:
                out[i, i, k] = 0.0
            for j in range(i, last):  # running sums from row i
                yy += add_row(G, g, F, k, j, y[j])
                if need[i, j + 1]:
                    out[i, j + 1, k] = max(quad3(G, g, yy, lo[k], hi[k], x, st, ws, Cw, idx), 0.0)
    return out


@njit(error_model="numpy")
def cell_terms(z, y, lu1, F, ns, lo, hi, kidx, seg, mixed, lam, ends, s, geom):
    """Per-layer terms of the Lagrangian bound of cells of interface depths, on grids of n.

    For each cell c, layer j and m: with k = kidx[c, j, m] an index into the
    grid ns (K,), f[c, j, m] = min over the box (lo[k], hi[k]) of
    x'G x - 2 g'x + yy + 2 sum_q lam[c, q] x . P_qj at n = ns[k], where G, g,
    yy are the normal equations of the rows held in layer j throughout the
    cell (the run seg[c, j] = (i, i_end) of full-cone rows, F (K, Z, 3)) and
    q runs over the rows the cell's interfaces may cut (mixed[c, q] true),
    whose part P_qj in layer j is taken at the cell's interface ends
    ``ends`` (C, L-1, 2) that make lam x . P smallest (the part grows with
    the layer's lower interface and shrinks with its upper one; x >= 0;
    lam = 0 takes the smallest part).  Not clipped at 0 (a Lagrangian term
    may be negative).  An index equal to the one before it repeats its
    values (padding).  Returns f (C, L, M) and xp (C, L, M, Z), the
    minimiser's x . P_qj of each cut row (0 elsewhere), from which the
    search moves the multipliers (a supergradient step of the dual).
    """
    H, R, rm1, r_t, alpha, beta = geom
    Cn = seg.shape[0]
    L = seg.shape[1]
    Mk = kidx.shape[2]
    Z = z.shape[0]
    out = np.empty((Cn, L, Mk))
    xp = np.zeros((Cn, L, Mk, Z))
    P = np.zeros((Z, 3))
    G = np.zeros((3, 3))
    g = np.zeros(3)
    x = np.zeros(3)
    st = np.zeros(3, dtype=np.int64)
    ws = np.zeros((10, 3))
    Cw = np.zeros((3, 3))
    idx = np.zeros(3, dtype=np.int64)
    for c in range(Cn):
        for j in range(L):
            i0, i1 = seg[c, j, 0], seg[c, j, 1]
            for m in range(Mk):
                k = kidx[c, j, m]
                if m > 0 and k == kidx[c, j, m - 1]:  # a repeated index (padding): same values
                    out[c, j, m] = out[c, j, m - 1]
                    for q in range(Z):
                        xp[c, j, m, q] = xp[c, j, m - 1, q]
                    continue
                G[:] = 0.0
                g[:] = 0.0
                yy = 0.0
                for q in range(i0, i1):
                    yy += add_row(G, g, F, k, q, y[q])
                for q in range(Z):
                    P[q, 0] = P[q, 1] = P[q, 2] = 0.0
                    if not mixed[c, q]:
                        continue
                    lq = lam[c, q]
                    # lam >= 0: the smallest part (top end of the lower interface, bottom
                    # end of the upper one); lam < 0: the largest
                    e_top = 1 if lq >= 0.0 else 0
                    e_bot = 0 if lq >= 0.0 else 1
                    d_top = 0.0 if j == 0 else ends[c, j - 1, e_top]
                    d_bot = math.inf if j == L - 1 else ends[c, j, e_bot]
                    if not d_bot > d_top:
                        continue
                    A, B, C = layer_part(
                        z[q], H, lu1[q], d_top, d_bot, ns[k], s, R, rm1, r_t, alpha, beta
                    )
                    P[q, 0], P[q, 1], P[q, 2] = A, B, C
                    g[0] -= lq * A
                    g[1] -= lq * B
                    g[2] -= lq * C
                if i1 <= i0:  # no row held in the layer: a linear term, smallest at a corner
                    f = 0.0
                    for a in range(3):
                        x[a] = lo[k, a] if g[a] * lo[k, a] >= g[a] * hi[k, a] else hi[k, a]
                        f -= 2.0 * g[a] * x[a]
                    out[c, j, m] = f
                else:
                    out[c, j, m] = quad3(G, g, yy, lo[k], hi[k], x, st, ws, Cw, idx)
                for q in range(Z):
                    if mixed[c, q]:
                        xp[c, j, m, q] = x[0] * P[q, 0] + x[1] * P[q, 1] + x[2] * P[q, 2]
    return out, xp


@njit(error_model="numpy")
def clip_point(p, lo, hi, L, gap, out) -> bool:
    """p = (D_1..D_{L-1}, n_1..n_L) clipped to the box into out; False when two interfaces
    lie closer than ``gap`` (the point is outside the search space)."""
    for i in range(p.shape[0]):
        out[i] = min(max(p[i], lo[i]), hi[i])
    for i in range(L - 2):  # the interfaces sorted
        for j in range(L - 2 - i):
            if out[j] > out[j + 1]:
                out[j], out[j + 1] = out[j + 1], out[j]
    for i in range(L - 2):
        if out[i + 1] - out[i] < gap:
            return False
    return True


@njit(error_model="numpy")
def nelder_mead(z, y, start, step, lo, hi, gap, s, bp, geom, maxiter, xtol, ftol):
    """Nelder-Mead over p = (D_1..D_{L-1}, n_1..n_L) of the layered SSE, from ``start``.

    Simplex from start and start + step_i e_i; points are clipped to
    [lo, hi] and count as +inf when two interfaces lie closer than ``gap``.
    Standard coefficients (1, 2, 0.5, 0.5).  Stops after ``maxiter``
    iterations or when the simplex spans less than ``xtol`` in every
    coordinate and less than ``ftol`` [kPa^2] in SSE.  Returns (best p, its SSE,
    evaluations).
    """
    P = start.shape[0]
    L = (P + 1) // 2
    Z = z.shape[0]
    lu1 = np.empty(Z)
    for q in range(Z):
        u1 = z[q] + geom[0]
        lu1[q] = math.log(u1) if u1 > 0.0 else 0.0
    work = new_work(Z, 3 * L)
    sim = np.empty((P + 1, P))
    fs = np.empty(P + 1)
    pt = np.empty(P)
    cen = np.empty(P)
    xr = np.empty(P)
    xe = np.empty(P)
    nfev = 0
    for i in range(P + 1):
        for c in range(P):
            sim[i, c] = start[c]
        if i > 0:
            sim[i, i - 1] += step[i - 1]
            if sim[i, i - 1] > hi[i - 1]:
                sim[i, i - 1] = start[i - 1] - step[i - 1]
        fs[i] = nm_eval(z, y, lu1, sim[i], lo, hi, L, gap, s, bp, geom, work, pt)
        nfev += 1
    for _ in range(maxiter):
        order = np.argsort(fs)
        sim[:] = sim[order]
        fs[:] = fs[order]
        span = 0.0
        for i in range(1, P + 1):
            for c in range(P):
                span = max(span, abs(sim[i, c] - sim[0, c]))
        if span <= xtol and fs[P] - fs[0] <= ftol:
            break
        for c in range(P):
            cen[c] = 0.0
            for i in range(P):
                cen[c] += sim[i, c] / P
        for c in range(P):
            xr[c] = cen[c] + (cen[c] - sim[P, c])
        fr = nm_eval(z, y, lu1, xr, lo, hi, L, gap, s, bp, geom, work, pt)
        nfev += 1
        if fr < fs[0]:
            for c in range(P):
                xe[c] = cen[c] + 2.0 * (cen[c] - sim[P, c])
            fe = nm_eval(z, y, lu1, xe, lo, hi, L, gap, s, bp, geom, work, pt)
            nfev += 1
            if fe < fr:
                sim[P, :] = xe
                fs[P] = fe
            else:
                sim[P, :] = xr
                fs[P] = fr
            continue
        if fr < fs[P - 1]:
            sim[P, :] = xr
            fs[P] = fr
            continue
        if fr < fs[P]:  # outside contraction
            for c in range(P):
                xe[c] = cen[c] + 0.5 * (xr[c] - cen[c])
        else:  # inside contraction
            for c in range(P):
                xe[c] = cen[c] + 0.5 * (sim[P, c] - cen[c])
        fc = nm_eval(z, y, lu1, xe, lo, hi, L, gap, s, bp, geom, work, pt)
        nfev += 1
        if fc < min(fr, fs[P]):
            sim[P, :] = xe
            fs[P] = fc
            continue
        for i in range(1, P + 1):  # shrink towards the best
            for c in range(P):
                sim[i, c] = sim[0, c] + 0.5 * (sim[i, c] - sim[0, c])
            fs[i] = nm_eval(z, y, lu1, sim[i], lo, hi, L, gap, s, bp, geom, work, pt)
            nfev += 1
    best = 0
    for i in range(P + 1):
        if fs[i] < fs[best]:
            best = i
    clip_point(sim[best], lo, hi, L, gap, pt)
    return pt.copy(), fs[best], nfev


@njit(error_model="numpy")
def nm_eval(z, y, lu1, p, lo, hi, L, gap, s, bp, geom, work, pt) -> float:
    """The layered SSE at p clipped to the box (+inf outside the search space)."""
    if not clip_point(p, lo, hi, L, gap, pt):
        return math.inf
    return layered_sse(z, y, lu1, pt[: L - 1], pt[L - 1 :], s, bp, geom, work)

"""Compiled kernels of the exact solver (numba, see :mod:`terracone.jit`).

Scalar ports of the numpy references, looped over cells so that one call
does what the reference does in hundreds of numpy calls on tiny arrays:

* :func:`tail_moments`, :func:`basis_point`: the closed-form cone integrals
  and basis columns of :func:`terracone.physics.cone.cone_index_basis` (fully
  mobilised shear, phic = 0, RM0 or RM1), eqs. (2-2) to (2-7) of [1]_;
* :func:`box_lsq3_one`, :func:`box_lsq3_flat`: the 27-face bounded least
  squares of :func:`terracone.inverse.solver.boxlsq.box_lsq3_reference`;
* :func:`cells_kernel`: the (profile, n, phic-scale) cells of
  :func:`terracone.inverse.solver.many.solve_exact_many` (basis, normal equations,
  box solve and the SSE from the residuals) in one pass;
* :func:`brent_refine`: the refinement of n of each profile (Brent's
  parabolic steps with a golden-section fallback) from its best grid cell.

The columns at the cells come from :func:`columns_at`, which reads the
n-free part of each depth (logarithms, the cc column) from a table built
once per profile (:func:`depth_table`), so that a cell costs two
transcendental functions per depth (RM0).

The numpy implementations stay the reference: ``tests/test_kernels.py``
compares each kernel with its twin to 1e-12, and ``TERRACONE_NUMBA=0`` (or
:func:`terracone.jit.disabled`) makes the solvers take the numpy paths.
This module is imported only when a solver runs (it imports numba).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
"""

from __future__ import annotations

import math

import numpy as np

from terracone.jit import njit

__all__ = [
    "tail_moments",
    "basis_point",
    "box_lsq3_one",
    "box_lsq3_flat",
    "cells_kernel",
    "brent_refine",
    "brent_step",
    "depth_table",
    "columns_at",
    "normal_eq",
    "cell_fast",
    "profile_columns",
    "kbounds",
    "box_grid",
    "identify_scan",
    "identify_extent",
    "basis_columns",
]

SERIES_EPS = 0.01  # as terracone.physics.cone: below this the binomial series is used
SERIES_TERMS = 10


@njit(error_model="numpy")
def tail_moments_log(eps: float, l1: float, n: float) -> tuple[float, float, float]:
    """:func:`tail_moments` with l1 = log1p(-eps) given (it does not depend on n)."""
    if eps < SERIES_EPS:
        # binomial series, terms for 1e-17 at this eps
        terms = SERIES_TERMS
        if eps > 0:
            terms = min(SERIES_TERMS, max(2, int(math.ceil(-17.0 / math.log10(eps))) + 1))
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        cp = eps
        for jj in range(terms):
            s0 += cp / (jj + 1)
            ce = cp * eps
            s1 += ce / (jj + 2)
            s2 += ce * eps / (jj + 3)
            cp = ce * ((jj - n) / (jj + 1))
        return s0, s1, s2
    x = 1.0 - eps
    e1 = math.expm1((n + 1.0) * l1)  # x^(n+1) - 1
    n1 = n + 1.0
    n2 = n + 2.0
    g0 = -e1 / n1
    g1 = g0 - (eps - e1 * x) / n2
    g2 = g1 - (eps - e1 * x) / n2 + (eps * (2.0 - eps) - e1 * x * x) / (n + 3.0)
    return g0, g1, g2


@njit(error_model="numpy")
def tail_moments(eps: float, n: float) -> tuple[float, float, float]:
    """G_k(eps) = int_0^eps w^k (1-w)^n dw, k = 0, 1, 2 (one point; see terracone.physics.cone).

    Closed form with expm1/log1p, or the binomial series below eps = 0.01.
    """
    return tail_moments_log(eps, math.log1p(-eps) if eps < 1.0 else -math.inf, n)


@njit(error_model="numpy")
def depth_logs(z: float, H: float, R: float, r_t: float) -> tuple[float, float, float]:
    """The n-free logarithms of :func:`basis_point_log` at one depth.

    log(u1), log1p(-eps_b) and log1p(-eps_s) with u1 = z + H the tip depth,
    eps_b = L/u1 (L the embedded length) and eps_s = min(L, r_t/t)/u1 (RM1).
    """
    u1 = z + H
    if not u1 > 0.0:
        return 0.0, 0.0, 0.0
    t = R / H
    L = H if z >= 0.0 else u1
    eb = min(max(L / u1, 0.0), 1.0)
    es = min(max(min(L, r_t / t) / u1, 0.0), 1.0)
    # eps = 1 (the tip still entering): log1p(-1) = -inf, which plain Python refuses
    l1b = math.log1p(-eb) if eb < 1.0 else -math.inf
    l1s = math.log1p(-es) if es < 1.0 else -math.inf
    return math.log(u1), l1b, l1s


@njit(error_model="numpy")
def basis_point_log(z, n, lu1, l1b, l1s, H, R, rm1, r_t, alpha, beta) -> tuple[float, float, float]:
    """:func:`basis_point` with the logarithms of :func:`depth_logs` given."""
    u1 = z + H  # depth of the tip
    if not u1 > 0.0:
        return 0.0, 0.0, 0.0
    return basis_point_p1(z, n, math.exp((n + 1.0) * lu1), l1b, l1s, H, R, rm1, r_t, alpha, beta)


@njit(error_model="numpy")
def basis_point_p1(z, n, p1, l1b, l1s, H, R, rm1, r_t, alpha, beta) -> tuple[float, float, float]:
    """:func:`basis_point_log` with p1 = (z + H)^(n + 1) given (u1 > 0)."""
    t = R / H
    u1 = z + H  # depth of the tip
    L = H if z >= 0.0 else u1  # embedded length along the axis
    p2 = p1 * u1
    eb = min(max(L / u1, 0.0), 1.0)
    g0b, g1b, _ = tail_moments_log(eb, l1b, n)
    I_phi = t * p2 * g1b  # eq. (2-5), per unit kphi
    I_cc = 0.5 * t * L * L
    if not rm1:
        I_c = p1 * g0b  # eq. (2-2), per unit kc
    else:
        d_s = r_t / t  # RM1 of section 3.2: linear branch below r_t
        if 0.0 < d_s:
            es = min(max(min(L, d_s) / u1, 0.0), 1.0)
            g0s, g1s, g2s = tail_moments_log(es, l1s, n)
            I_c = p1 * (g0b - g0s) + alpha * t * p2 * g1s - beta * t * t * (p2 * u1) * g2s
        else:
            I_c = p1 * g0b
    RR = R * R
    return 2.0 * (t * I_c) / RR, 2.0 * (t * I_phi) / RR, 2.0 * I_cc / RR


@njit(error_model="numpy")
def basis_point(
    z: float, n: float, H: float, R: float, rm1: bool, r_t: float, alpha: float, beta: float
) -> tuple[float, float, float]:
    """Columns A, B, C of eq. (2-7) at one depth, fully mobilised shear, phic = 0.

    As :func:`terracone.physics.cone.cone_index_basis` (RM0 or RM1, cone of height H
    and base radius R [m]): CI = kc A + kphi B + cc C.
    """
    lu1, l1b, l1s = depth_logs(z, H, R, r_t)
    return basis_point_log(z, n, lu1, l1b, l1s, H, R, rm1, r_t, alpha, beta)


@njit(error_model="numpy")
def profile_logs(z, H, R, r_t, out) -> None:
    """:func:`depth_logs` of every depth of z (Z,) into out (3, Z)."""
    for q in range(z.shape[0]):
        out[0, q], out[1, q], out[2, q] = depth_logs(z[q], H, R, r_t)


@njit(error_model="numpy")
def box_lsq3_one(G, g, yy, lo, hi, x_out, ws) -> float:
    """Minimise x'Gx - 2g'x + yy over lo <= x <= hi (3 variables); x into x_out, returns SSE.

    ``ws`` is an (18, 3) float work array (no allocation per problem).  The
    face chosen by the previous problem solved with the same ``ws`` (left in
    ws[7]) is tried first: consecutive problems (neighbouring n or pinned
    values) mostly share it, and it is accepted only on the optimality
    conditions (:func:`box_faces_from`).
    """
    box_scale(G, g, ws)
    return box_faces_from(yy, lo, hi, x_out, ws, last_face(ws))


@njit(error_model="numpy")
def last_face(ws) -> int:
    """The face left in ws[7] by the previous solve, or -1 when ws[7] holds no face."""
    for i in range(3):
        if not (ws[7, i] == 0.0 or ws[7, i] == 1.0 or ws[7, i] == 2.0):
            return -1
    return int(ws[7, 0]) * 9 + int(ws[7, 1]) * 3 + int(ws[7, 2])


@njit(error_model="numpy")
def box_scale(G, g, ws) -> None:
    """Scale the normal equations to unit diagonal into ws (rows 0-2 and 11-13)."""
    d, diag, b, S = ws[0], ws[1], ws[2], ws[11:14]
    for i in range(3):
        d[i] = math.sqrt(max(G[i, i], 1e-300))
    for i in range(3):
        for j in range(3):
            S[i, j] = G[i, j] / (d[i] * d[j])
    for i in range(3):
        diag[i] = S[i, i]
        S[i, i] = S[i, i] + 1e-13  # tiny ridge in the solves, as the reference
        b[i] = g[i] / d[i]


@njit(error_model="numpy")
def solve_free(S, r, st, x, Mt) -> float:
    """Solve the rows and columns of S (3, 3) with st == 0 for x, right-hand side r.

    Gaussian elimination with partial pivoting (as LAPACK's gesv that the
    reference uses for few problems): accurate when kc and kphi are nearly
    collinear, where Cramer's rule loses digits.  Mt (4, 3) is work space
    holding the reduced system transposed (column 3 the right-hand side).
    Returns the smallest pivot magnitude (S has unit diagonal: a small pivot
    means a nearly singular face).
    """
    pmin = np.inf
    i0 = 0 if st[0] == 0 else (1 if st[1] == 0 else 2)
    i2 = 2 if st[2] == 0 else (1 if st[1] == 0 else 0)
    k = 0
    for i in range(3):
        if st[i] == 0:
            k += 1
    if k == 2:  # the same steps written out for two unknowns
        a, b, ra = S[i0, i0], S[i0, i2], r[i0]
        c, d, rc = S[i2, i0], S[i2, i2], r[i2]
        if abs(c) > abs(a):
            a, b, ra, c, d, rc = c, d, rc, a, b, ra
        f = c / a
        d = d - f * b
        rc = rc - f * ra
        x[i2] = rc / d
        x[i0] = (ra - b * x[i2]) / a
        return min(abs(a), abs(d))
    i1 = 1 if k == 3 else i2
    # reduced system M[a, c] = Mt[c, a], rows a < k
    for a, ia in enumerate((i0, i1, i2)):
        if a >= k:
            break
        for c, ic in enumerate((i0, i1, i2)):
            if c >= k:
                break
            Mt[c, a] = S[ia, ic]
        Mt[3, a] = r[ia]
    for col in range(k):
        piv = col
        for a in range(col + 1, k):
            if abs(Mt[col, a]) > abs(Mt[col, piv]):
                piv = a
        if piv != col:
            for c in range(4):
                Mt[c, col], Mt[c, piv] = Mt[c, piv], Mt[c, col]
        pmin = min(pmin, abs(Mt[col, col]))
        for a in range(col + 1, k):
            f = Mt[col, a] / Mt[col, col]
            for c in range(col, 4):
                Mt[c, a] -= f * Mt[c, col]
    for a in range(k - 1, -1, -1):
        acc = Mt[3, a]
        for c in range(a + 1, k):
            acc -= Mt[c, a] * Mt[3, c]
        Mt[3, a] = acc / Mt[a, a]
    x[i0] = Mt[3, 0]
    x[i2] = Mt[3, k - 1]
    if k == 3:
        x[1] = Mt[3, 1]
    return pmin


@njit(error_model="numpy")
def box_faces(yy, lo, hi, x_out, ws) -> float:
    """The 27 faces of :func:`box_lsq3_one` on normal equations scaled by :func:`box_scale`."""
    return box_faces_from(yy, lo, hi, x_out, ws, -1)


@njit(error_model="numpy")
def box_faces_from(yy, lo, hi, x_out, ws, hint) -> float:
    """:func:`box_faces`, trying face ``hint`` (0-26, or -1) first.

    The first face tried is accepted at once when it is well conditioned
    (pivots above 1e-6 of the unit diagonal), its free variables lie clear
    of their bounds and the gradient pushes every variable held at a bound
    outwards (the optimality conditions of a convex quadratic over a box,
    with a margin): no other face can then do better but by rounding.
    Otherwise all faces are compared, as the reference does.  The face
    chosen is left in ws[7] (the state of each variable).
    """
    d, diag, b, L, U, tol = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5]
    bx, bst, x, st, S = ws[6], ws[7], ws[8], ws[9], ws[11:14]
    for i in range(3):
        L[i] = lo[i] * d[i]
        U[i] = hi[i] * d[i]
        tol[i] = 1e-9 * max(U[i] - L[i], 1e-300) + 1e-12
        bx[i] = 0.0
        bst[i] = 0.0
    best = np.inf
    first = True
    for kk in range(28):  # itertools.product((0, 1, 2), repeat=3): 0 free, 1 lower, 2 upper
        if kk == 0:
            if hint < 0:
                continue
            face = hint
        else:
            face = kk - 1
            if face == hint:
                continue
        st[0] = face // 9
        st[1] = (face // 3) % 3
        st[2] = face % 3
        skip = False
        for i in range(3):  # a pinned variable (lo == hi): only its "lower" face
            if L[i] == U[i] and st[i] != 1:
                skip = True
        if skip:
            continue
        pmin = face_point(ws)
        feas = True
        inside = first and pmin > 1e-6
        for i in range(3):
            if st[i] == 0:
                if not ((x[i] >= L[i] - tol[i]) and (x[i] <= U[i] + tol[i])):
                    feas = False
                m = 1e-6 * (U[i] - L[i])
                if not (L[i] + m < x[i] < U[i] - m):
                    inside = False
                x[i] = min(max(x[i], L[i]), U[i])
        obj = (
            diag[0] * x[0] * x[0]
            + diag[1] * x[1] * x[1]
            + diag[2] * x[2] * x[2]
            + 2.0 * (S[0, 1] * x[0] * x[1] + S[0, 2] * x[0] * x[2] + S[1, 2] * x[1] * x[2])
            - 2.0 * (b[0] * x[0] + b[1] * x[1] + b[2] * x[2])
        )
        if feas and obj < best:
            best = obj
            for i in range(3):
                bx[i] = x[i]
                bst[i] = st[i]
        if inside and held_outward(ws):
            # a well-conditioned face satisfying the optimality conditions with a margin
            # holds the minimum over the box, which no other face can beat but by rounding
            break
        first = False
    for i in range(3):
        if bst[i] == 1:
            v = lo[i]
        elif bst[i] == 2:
            v = hi[i]
        else:
            v = bx[i] / d[i]
        x_out[i] = min(max(v, lo[i]), hi[i])
    return max(best + yy, 0.0)


@njit(error_model="numpy")
def face_point(ws) -> float:
    """The minimiser x (ws[8]) of the scaled quadratic on the face ws[9] (states of the
    variables), held variables at their scaled bounds ws[3] / ws[4].  Returns the smallest
    pivot of the solve (1 with fewer than two free variables)."""
    b, L, U, x, st, r, S = ws[2], ws[3], ws[4], ws[8], ws[9], ws[10], ws[11:14]
    nfree = 0
    for i in range(3):
        if st[i] == 1:
            x[i] = L[i]
        elif st[i] == 2:
            x[i] = U[i]
        else:
            nfree += 1
    for i in range(3):
        if st[i] == 0:
            ri = b[i]
            for j in range(3):
                if st[j] != 0:
                    ri = ri - S[i, j] * x[j]
            r[i] = ri
    if nfree == 1:
        for i in range(3):
            if st[i] == 0:
                x[i] = r[i] / S[i, i]
    elif nfree >= 2:
        return solve_free(S, r, st, x, ws[14:18])
    return 1.0


@njit(error_model="numpy")
def held_outward(ws) -> bool:
    """True when the gradient at x (ws[8]) pushes every variable held at a bound (face ws[9])
    out of the box, with a relative margin of 1e-9."""
    diag, b, x, st, S = ws[1], ws[2], ws[8], ws[9], ws[11:14]
    L, U = ws[3], ws[4]
    for i in range(3):
        if st[i] != 0 and L[i] != U[i]:
            gi = diag[i] * x[i] - b[i]
            size = abs(diag[i] * x[i]) + abs(b[i])
            for j in range(3):
                if j != i:
                    gi += S[i, j] * x[j]
                    size += abs(S[i, j] * x[j])
            if st[i] == 1 and not gi > 1e-9 * size:
                return False
            if st[i] == 2 and not gi < -1e-9 * size:
                return False
    return True


@njit(error_model="numpy")
def box_lsq3_flat(G, g, yy, lo, hi):
    """:func:`box_lsq3_one` over M problems: G (M, 3, 3), g, lo, hi (M, 3), yy (M,)."""
    M = yy.shape[0]
    x = np.empty((M, 3))
    sse = np.empty(M)
    ws = np.empty((18, 3))
    for m in range(M):
        sse[m] = box_lsq3_one(G[m], g[m], yy[m], lo[m], hi[m], x[m], ws)
    return x, sse


@njit(error_model="numpy")
def cells_kernel(zz, yy, w, n, sv, lo, hi, ratio, H, R, rm1, r_t, alpha, beta):
    """Cells of :func:`terracone.inverse.solver.many.solve_exact_many` (fully mobilised).

    zz, yy, w : (P, Z) depths [m], CI [kPa], weights; n : (P, K);
    sv : (1 or P, F) phic scales s = 1 + tan(phic)/tan(a); lo, hi : (P, K, 3)
    bounds of (kc, kphi, cc); ratio : kc/kphi [m], or NaN for none.
    Returns the primed solutions xp (P, K, F, 3) and the SSE (P, K, F)
    from the residuals.  A profile with the depths and n of the one before
    it (an instrument's common depth grid) reuses its columns
    (:func:`profile_columns`), so the transcendental work of the grid is
    done once per run of such profiles.
    """
    P, Z = zz.shape
    K = n.shape[1]
    F = sv.shape[1]
    xp = np.empty((P, K, F, 3))
    sse = np.empty((P, K, F))
    cols = np.empty((3, K, Z))  # columns at every n of the current depth vector
    G = np.empty((3, 3))
    g = np.empty(3)
    x = np.empty(3)
    ws = np.empty((18, 3))
    ws[7, 0] = -1.0  # no face yet
    tab = np.empty((7, Z))
    ratio_q = np.empty(Z)
    p1q = np.empty(Z)
    for p in range(P):
        yty = 0.0
        for q in range(Z):
            yty += w[p, q] * yy[p, q] * yy[p, q]
        ps = p if sv.shape[0] > 1 else 0
        if not (p > 0 and same_rows(zz, p) and same_rows(n, p)):
            # a new depth vector (profiles of one instrument share theirs: computed once)
            profile_columns(
                zz[p], n[p], tab, H, R, rm1, r_t, alpha, beta, ratio, ratio_q, p1q, cols
            )
        for k in range(K):
            A, B, C = cols[0, k], cols[1, k], cols[2, k]
            for f in range(F):
                s = sv[ps, f]  # phic scales the kc and kphi columns, eq. (2-6)
                normal_eq(yy[p], w[p], A, B, C, s, G, g)
                box_lsq3_one(G, g, yty, lo[p, k], hi[p, k], x, ws)
                x0, x1, x2 = x[0] * s, x[1] * s, x[2]
                xp[p, k, f, 0], xp[p, k, f, 1], xp[p, k, f, 2] = x0, x1, x2
                sse[p, k, f] = residual_sse(yy[p], w[p], A, B, C, x0, x1, x2)
    return xp, sse


@njit(error_model="numpy")
def same_rows(a, p) -> bool:
    """True when row p of a (P, M) equals row p - 1."""
    for j in range(a.shape[1]):
        if a[p, j] != a[p - 1, j]:
            return False
    return True


@njit(error_model="numpy")
def profile_columns(z, n, tab, H, R, rm1, r_t, alpha, beta, ratio, ratio_q, p1q, cols) -> None:
    """Columns A, B, C of depths z (Z,) at every n of (K,) into cols (3, K, Z).

    kc folded into kphi with a ratio (:func:`fold_ratio`); over a uniform grid
    of n the powers u1^(n+1) by recurrence, one exp per depth instead of one
    per cell (k ulp at step k).  tab, ratio_q, p1q are work arrays.
    """
    K = n.shape[0]
    depth_table(z, H, R, r_t, tab)
    uniform = uniform_grid(n)
    if uniform:
        dn = (n[K - 1] - n[0]) / (K - 1)
        for q in range(z.shape[0]):
            ratio_q[q] = math.exp(dn * tab[0, q])
            p1q[q] = math.exp((n[0] + 1.0) * tab[0, q])
    for k in range(K):
        if uniform and k > 0:
            for q in range(z.shape[0]):
                p1q[q] *= ratio_q[q]
        A, B, C = cols[0, k], cols[1, k], cols[2, k]
        columns_at(z, tab, n[k], H, R, rm1, r_t, alpha, beta, p1q, uniform, A, B, C)
        fold_ratio(A, B, ratio)


@njit(error_model="numpy")
def uniform_grid(n) -> bool:
    """True when n (K,) is an evenly spaced grid of more than two points (to 1e-15)."""
    K = n.shape[0]
    if K <= 2:
        return False
    dn = (n[K - 1] - n[0]) / (K - 1)
    for k in range(K):
        if abs(n[k] - (n[0] + k * dn)) > 1e-15 * (1.0 + abs(n[k])):
            return False
    return True


@njit(error_model="numpy")
def kbounds(n, bp, lo, hi) -> None:
    """Box of (kc, kphi, cc) in SI at exponent n into lo, hi (3,).

    bp = (kc_lo, kc_hi, kphi_lo, kphi_hi, cc_lo, cc_hi, kc_c, kc_base, kphi_c,
    kphi_base, ratio): kc [SI] = kc * kc_c / kc_base^(n + 1), kphi likewise with
    n + 2 (1, 1 for SI bounds); ratio kc/kphi [m] or NaN (as many.py's _kbounds).
    """
    fkc = bp[6] / bp[7] ** (n + 1.0)
    fkp = bp[8] / bp[9] ** (n + 2.0)
    kc_lo, kc_hi = bp[0] * fkc, bp[1] * fkc
    kp_lo, kp_hi = bp[2] * fkp, bp[3] * fkp
    ratio = bp[10]
    if not math.isnan(ratio):
        if ratio > 0:
            kp_lo = max(kp_lo, kc_lo / ratio)
            kp_hi = max(min(kp_hi, kc_hi / ratio), kp_lo)
        kc_lo = 0.0
        kc_hi = 0.0
    lo[0], lo[1], lo[2] = kc_lo, kp_lo, bp[4]
    hi[0], hi[1], hi[2] = kc_hi, kp_hi, bp[5]


@njit(error_model="numpy")
def box_grid(n, bp):
    """:func:`kbounds` at every n of (P, K): lo, hi (P, K, 3)."""
    P, K = n.shape
    lo = np.empty((P, K, 3))
    hi = np.empty((P, K, 3))
    for p in range(P):
        for k in range(K):
            kbounds(n[p, k], bp, lo[p, k], hi[p, k])
    return lo, hi


@njit(error_model="numpy")
def normal_at(z, y, w, lg, n, s, ratio, H, R, rm1, r_t, alpha, beta, A, B, C, G, g) -> float:
    """Columns A, B, C (Z,) at n and the normal equations G (3, 3), g (3,) at scale s.

    The kc and kphi columns are multiplied by s = 1 + tan(phic)/tan(a)
    (eq. (2-6) fully mobilised) in G and g, not in A, B; with ratio (not
    NaN) the kc column folds into the kphi column.  Returns y'y (weighted).
    """
    Z = z.shape[0]
    use_ratio = not math.isnan(ratio)
    yty = 0.0
    for q in range(Z):
        a, bb, c = basis_point_log(
            z[q], n, lg[0, q], lg[1, q], lg[2, q], H, R, rm1, r_t, alpha, beta
        )
        if use_ratio:
            A[q], B[q] = 0.0, ratio * a + bb
        else:
            A[q], B[q] = a, bb
        C[q] = c
        yty += w[q] * y[q] * y[q]
    for i in range(3):
        g[i] = 0.0
        for j in range(3):
            G[i, j] = 0.0
    for q in range(Z):
        aw, bw, cw = A[q] * w[q], B[q] * w[q], C[q] * w[q]
        G[0, 0] += aw * A[q]
        G[0, 1] += aw * B[q]
        G[0, 2] += aw * C[q]
        G[1, 1] += bw * B[q]
        G[1, 2] += bw * C[q]
        G[2, 2] += cw * C[q]
        g[0] += aw * y[q]
        g[1] += bw * y[q]
        g[2] += cw * y[q]
    G[0, 0] = G[0, 0] * s * s
    G[0, 1] = G[0, 1] * s * s
    G[1, 1] = G[1, 1] * s * s
    G[0, 2] = G[0, 2] * s
    G[1, 2] = G[1, 2] * s
    g[0] = g[0] * s
    g[1] = g[1] * s
    G[1, 0], G[2, 0], G[2, 1] = G[0, 1], G[0, 2], G[1, 2]
    return yty


@njit(error_model="numpy")
def cell_sse(z, y, w, lg, n, s, bp, H, R, rm1, r_t, alpha, beta, A, B, C, ws, xp) -> float:
    """SSE (from the residuals) of one profile at one (n, s); primed solution into xp (3,).

    lg (3, Z) holds :func:`profile_logs` of z; A, B, C (Z,) and ws (24, 3)
    are work arrays; bp as :func:`kbounds`.
    """
    Z = z.shape[0]
    G = ws[18:21]
    lo, hi, g = ws[21], ws[22], ws[23]
    yty = normal_at(z, y, w, lg, n, s, bp[10], H, R, rm1, r_t, alpha, beta, A, B, C, G, g)
    kbounds(n, bp, lo, hi)
    box_lsq3_one(G, g, yty, lo, hi, xp, ws)
    xp[0] *= s
    xp[1] *= s
    acc = 0.0
    for q in range(Z):
        rq = A[q] * xp[0] + B[q] * xp[1] + C[q] * xp[2] - y[q]
        acc += rq * rq * w[q]
    return acc


@njit(error_model="numpy")
def depth_table(z, H, R, r_t, tab) -> None:
    """The n-free quantities of every depth of z (Z,) into tab (7, Z).

    Rows 0-2 are :func:`depth_logs` (log(u1), log1p(-eps_b), log1p(-eps_s));
    row 3 the tip depth u1 = z + H [m], row 4 eps_b = L/u1, row 5 the cc
    column C of eq. (2-7) (it does not depend on n) and row 6 is 1 where the
    closed form of :func:`columns_at` applies (u1 > 0, 0.01 <= eps_b < 1,
    no binomial series), else 0.
    """
    t = R / H
    RR = R * R
    for q in range(z.shape[0]):
        tab[0, q], tab[1, q], tab[2, q] = depth_logs(z[q], H, R, r_t)
        u1 = z[q] + H
        if not u1 > 0.0:
            tab[3, q] = tab[4, q] = tab[5, q] = tab[6, q] = 0.0
            continue
        L = H if z[q] >= 0.0 else u1
        eb = min(max(L / u1, 0.0), 1.0)
        tab[3, q] = u1
        tab[4, q] = eb
        tab[5, q] = 2.0 * (0.5 * t * L * L) / RR  # eq. (2-7), per unit cc
        tab[6, q] = 1.0 if SERIES_EPS <= eb < 1.0 else 0.0


@njit(error_model="numpy")
def columns_at(z, tab, n, H, R, rm1, r_t, alpha, beta, p1, use_p1, A, B, C) -> None:
    """Columns A, B, C (Z,) of eq. (2-7) at exponent n (fully mobilised, phic = 0).

    RM0 at the depths flagged in row 6 of ``tab`` (:func:`depth_table`):
    A = 2t/R^2 u1^(n+1) G_0, B = 2t^2/R^2 u1^(n+2) G_1 with the closed forms
    of G_0, G_1 of :func:`tail_moments_log` (eqs. (2-2), (2-5)) and the
    n-free parts read from ``tab``; elsewhere (RM1, the tip entering, the
    binomial series) :func:`basis_point_log`.  With ``use_p1`` the powers
    u1^(n+1) are taken from p1 (Z,) (a recurrence over a uniform grid).
    """
    t = R / H
    RR = R * R
    ka = 2.0 * t / RR
    kb = 2.0 * t * t / RR
    n1 = n + 1.0
    inv1 = 1.0 / n1
    inv2 = 1.0 / (n + 2.0)
    for q in range(z.shape[0]):
        if rm1 or tab[6, q] == 0.0:
            if use_p1 and tab[3, q] > 0.0:
                a, b, c = basis_point_p1(
                    z[q], n, p1[q], tab[1, q], tab[2, q], H, R, rm1, r_t, alpha, beta
                )
            else:
                a, b, c = basis_point_log(
                    z[q], n, tab[0, q], tab[1, q], tab[2, q], H, R, rm1, r_t, alpha, beta
                )
            A[q], B[q], C[q] = a, b, c
            continue
        pw = p1[q] if use_p1 else math.exp(n1 * tab[0, q])  # u1^(n+1)
        eb = tab[4, q]
        e1 = math.expm1(n1 * tab[1, q])  # (1 - eps)^(n+1) - 1
        g0 = -e1 * inv1
        g1 = g0 - (eb - e1 * (1.0 - eb)) * inv2
        A[q] = ka * (pw * g0)  # eq. (2-2)
        B[q] = kb * (pw * tab[3, q] * g1)  # eq. (2-5)
        C[q] = tab[5, q]


@njit(error_model="numpy")
def fold_ratio(A, B, ratio) -> None:
    """With kc/kphi = ratio [m] held (not NaN): B = ratio A + B and A = 0 (kc = ratio kphi)."""
    if not math.isnan(ratio):
        for q in range(A.shape[0]):
            B[q] = ratio * A[q] + B[q]
            A[q] = 0.0


@njit(error_model="numpy")
def normal_eq(y, w, A, B, C, s, G, g) -> None:
    """Normal equations G (3, 3), g (3,) of columns A, B, C (Z,) at scale s.

    As :func:`normal_at` (kc and kphi columns times s, eq. (2-6) fully
    mobilised), with the sums in scalar accumulators.
    """
    aa = ab = ac = bb = bc = cc = ay = by = cy = 0.0
    for q in range(A.shape[0]):
        aw, bw, cw = A[q] * w[q], B[q] * w[q], C[q] * w[q]
        aa += aw * A[q]
        ab += aw * B[q]
        ac += aw * C[q]
        bb += bw * B[q]
        bc += bw * C[q]
        cc += cw * C[q]
        ay += aw * y[q]
        by += bw * y[q]
        cy += cw * y[q]
    G[0, 0], G[0, 1], G[1, 1] = aa * s * s, ab * s * s, bb * s * s
    G[0, 2], G[1, 2], G[2, 2] = ac * s, bc * s, cc
    G[1, 0], G[2, 0], G[2, 1] = G[0, 1], G[0, 2], G[1, 2]
    g[0], g[1], g[2] = ay * s, by * s, cy


@njit(error_model="numpy")
def residual_sse(y, w, A, B, C, x0, x1, x2) -> float:
    """Weighted sum of squared residuals of CI = x0 A + x1 B + x2 C (the primed solution)."""
    acc = 0.0
    for q in range(y.shape[0]):
        rq = A[q] * x0 + B[q] * x1 + C[q] * x2 - y[q]
        acc += rq * rq * w[q]
    return acc


@njit(error_model="numpy")
def cell_fast(z, y, w, tab, yty, n, s, bp, H, R, rm1, r_t, alpha, beta, A, B, C, ws, xp) -> float:
    """:func:`cell_sse` with the depth table of :func:`depth_table` and y'y given.

    ws is a (24, 3) work array whose rows 0-17 carry the last optimal face
    from call to call (:func:`box_lsq3_one`).
    """
    G = ws[18:21]
    lo, hi, g = ws[21], ws[22], ws[23]
    columns_at(z, tab, n, H, R, rm1, r_t, alpha, beta, A, False, A, B, C)
    fold_ratio(A, B, bp[10])
    normal_eq(y, w, A, B, C, s, G, g)
    kbounds(n, bp, lo, hi)
    box_lsq3_one(G, g, yty, lo, hi, xp, ws)
    xp[0] *= s
    xp[1] *= s
    return residual_sse(y, w, A, B, C, xp[0], xp[1], xp[2])


@njit(error_model="numpy")
def brent_step(a, b, x, w, v, fx, fw, fv, d, e, tol1):
    """The next trial point of Brent's minimiser on [a, b] and the new (d, e).

    A parabolic step through x, w, v (the best three points so far) when it
    falls inside the bracket and is shorter than half the step before last;
    otherwise a golden-section step into the larger part of the bracket.
    Steps are at least tol1 long.
    """
    cg = 0.3819660112501051  # (3 - sqrt(5)) / 2
    xm = 0.5 * (a + b)
    golden = True
    if abs(e) > tol1:
        r = (x - w) * (fx - fv)
        q = (x - v) * (fx - fw)
        p = (x - v) * q - (x - w) * r
        q = 2.0 * (q - r)
        if q > 0.0:
            p = -p
        q = abs(q)
        etemp = e
        if abs(p) < abs(0.5 * q * etemp) and p > q * (a - x) and p < q * (b - x):
            e = d
            d = p / q
            u = x + d
            if u - a < 2.0 * tol1 or b - u < 2.0 * tol1:
                d = tol1 if xm >= x else -tol1
            golden = False
    if golden:
        e = (a - x) if x >= xm else (b - x)
        d = cg * e
    u = x + d if abs(d) >= tol1 else x + (tol1 if d > 0.0 else -tol1)
    return u, d, e


@njit(error_model="numpy")
def brent_refine(
    zz, yy, w, a, b, x0, f0, fa, fb, s, bp, xtol, maxiter, H, R, rm1, r_t, alpha, beta
):
    """Brent's minimisation of the SSE over n in [a_p, b_p] at scale s_p, per profile.

    Starts from the best grid point x0_p (SSE f0_p) with the bracket's ends
    (SSE fa_p, fb_p, from the grid) as the two other points, so the first
    step is already parabolic; parabolic steps with a golden-section
    fallback (:func:`brent_step`) keep the bracket around the best point and
    stop when it is at most 4 xtol wide.  A kink of the SSE where a bound of
    the box becomes active costs a few golden steps, never accuracy: the
    bracket still shrinks to 4 xtol around the best point.  Returns (n, SSE,
    evaluations); the SSE is never above f0.
    """
    P, Z = zz.shape
    bx = np.empty(P)
    bf = np.empty(P)
    A = np.empty(Z)
    B = np.empty(Z)
    C = np.empty(Z)
    ws = np.empty((24, 3))
    ws[7, 0] = -1.0  # no face yet
    xp = np.empty(3)
    tab = np.empty((7, Z))
    used = 0
    for p in range(P):
        z, y, wp, sp = zz[p], yy[p], w[p], s[p]
        depth_table(z, H, R, r_t, tab)
        yty = 0.0
        for q in range(Z):
            yty += wp[q] * y[q] * y[q]
        lo, hi = a[p], b[p]
        x, fx = x0[p], f0[p]
        # the other two points: the bracket's ends (the one at x, if any, left out)
        if lo == x:
            w_, fw, v, fv = hi, fb[p], hi, fb[p]
        elif hi == x:
            w_, fw, v, fv = lo, fa[p], lo, fa[p]
        elif fa[p] <= fb[p]:
            w_, fw, v, fv = lo, fa[p], hi, fb[p]
        else:
            w_, fw, v, fv = hi, fb[p], lo, fa[p]
        d = e = hi - lo
        for _ in range(maxiter):
            if abs(x - 0.5 * (lo + hi)) <= 2.0 * xtol - 0.5 * (hi - lo):
                break
            u, d, e = brent_step(lo, hi, x, w_, v, fx, fw, fv, d, e, xtol)
            fu = cell_fast(
                z, y, wp, tab, yty, u, sp, bp, H, R, rm1, r_t, alpha, beta, A, B, C, ws, xp
            )
            used += 1
            if fu <= fx:
                if u >= x:
                    lo = x
                else:
                    hi = x
                v, fv, w_, fw, x, fx = w_, fw, x, fx, u, fu
            else:
                if u < x:
                    lo = u
                else:
                    hi = u
                if fu <= fw or w_ == x:
                    v, fv, w_, fw = w_, fw, u, fu
                elif fu <= fv or v == x or v == w_:
                    v, fv = u, fu
        bx[p], bf[p] = x, fx
    return bx, bf, used


@njit(error_model="numpy")
def scan_buffers(z, H, R, r_t):
    """Work arrays of the identifiability scans of one profile (z (Z,) [m]).

    Returns (w, lg, A, B, C, G, g, lo2, hi2, x, ws): unit weights, the
    profile's n-free logarithms (:func:`profile_logs`), the basis columns,
    the normal equations and the box solve's scratch.
    """
    Z = z.shape[0]
    lg = np.empty((3, Z))
    profile_logs(z, H, R, r_t, lg)
    return (
        np.ones(Z), lg, np.empty(Z), np.empty(Z), np.empty(Z), np.empty((3, 3)), np.empty(3),
        np.empty(3), np.empty(3), np.empty(3), np.empty((18, 3)),
    )  # fmt: skip


@njit(error_model="numpy")
def scan_boxes(n_loc, bp):
    """The box (lo, hi), each (N, 3), of kc, kphi, cc at each n of n_loc, and which
    of the three are fixed at every n (pinned (3,) bool)."""
    N = n_loc.shape[0]
    lo = np.empty((N, 3))
    hi = np.empty((N, 3))
    pinned = np.ones(3, dtype=np.bool_)
    for i in range(N):
        kbounds(n_loc[i], bp, lo[i], hi[i])
        for j in range(3):
            if lo[i, j] != hi[i, j]:
                pinned[j] = False
    return lo, hi, pinned


@njit(error_model="numpy")
def identify_scan(z, y, n_loc, s, bp, vals, H, R, rm1, r_t, alpha, beta):
    """Profile scans of exact.py's identifiability analysis, fully mobilised shear.

    For each n of n_loc (N,) at scale s: the normal equations, the box of
    :func:`kbounds`, and for each of kc, kphi, cc the SSE with that variable
    pinned at lo + v (hi - lo), v in vals (V,), the others re-fitted.
    Returns (sse (3, N, V), lo (N, 3), hi (N, 3)).
    """
    N = n_loc.shape[0]
    V = vals.shape[0]
    w, lg, A, B, C, G, g, lo2, hi2, x, ws = scan_buffers(z, H, R, r_t)
    lo, hi, pinned = scan_boxes(n_loc, bp)  # pinned: fixed at every n, nothing to scan
    out = np.empty((3, N, V))
    for i in range(N):
        yty = normal_at(
            z, y, w, lg, n_loc[i], s, bp[10], H, R, rm1, r_t, alpha, beta, A, B, C, G, g
        )
        box_scale(G, g, ws)
        for idx in range(3):
            if pinned[idx]:
                out[idx, i, :] = np.nan
                continue
            hint = -1  # neighbouring pinned values mostly share the optimal face
            for v in range(V):
                for j in range(3):
                    lo2[j], hi2[j] = lo[i, j], hi[i, j]
                pin = lo[i, idx] + vals[v] * (hi[i, idx] - lo[i, idx])
                lo2[idx], hi2[idx] = pin, pin
                out[idx, i, v] = box_faces_from(yty, lo2, hi2, x, ws, hint)
                hint = last_face(ws)
    return out, lo, hi


@njit(error_model="numpy")
def pinned_sse(yty, lo, hi, idx, val, x, ws, lo2, hi2) -> float:
    """SSE of the box LSQ scaled in ws with variable idx pinned at lo + val (hi - lo)."""
    for j in range(3):
        lo2[j], hi2[j] = lo[j], hi[j]
    pin = lo[idx] + val * (hi[idx] - lo[idx])
    lo2[idx], hi2[idx] = pin, pin
    return box_faces_from(yty, lo2, hi2, x, ws, last_face(ws))


@njit(error_model="numpy")
def first_true(yty, lo, hi, idx, vals, thr, a, b, x, ws, lo2, hi2) -> int:
    """Smallest j in [a, b] with SSE(vals[j]) <= thr, the SSE non-increasing on [a, b]; or -1."""
    if a > b or not pinned_sse(yty, lo, hi, idx, vals[b], x, ws, lo2, hi2) <= thr:
        return -1
    while a < b:  # invariant: b is inside
        m = (a + b) // 2
        if pinned_sse(yty, lo, hi, idx, vals[m], x, ws, lo2, hi2) <= thr:
            b = m
        else:
            a = m + 1
    return b


@njit(error_model="numpy")
def last_true(yty, lo, hi, idx, vals, thr, a, b, x, ws, lo2, hi2) -> int:
    """Largest j in [a, b] with SSE(vals[j]) <= thr, the SSE non-decreasing on [a, b]; or -1."""
    if a > b or not pinned_sse(yty, lo, hi, idx, vals[a], x, ws, lo2, hi2) <= thr:
        return -1
    while a < b:  # invariant: a is inside
        m = (a + b + 1) // 2
        if pinned_sse(yty, lo, hi, idx, vals[m], x, ws, lo2, hi2) <= thr:
            a = m
        else:
            b = m - 1
    return a


@njit(error_model="numpy")
def identify_extent(z, y, n_loc, s, bp, vals, thr, H, R, rm1, r_t, alpha, beta):
    """The extent of :func:`identify_scan`'s sets SSE <= thr, without the full scan.

    For each of kc, kphi, cc: the first and last index j of ``vals``
    (increasing) such that SSE(n, vals[j]) <= thr at some n of n_loc, or -1
    (-2 for a variable fixed at every n).  At fixed n the SSE with one
    variable pinned is a convex function of the pinned value (the minimum of
    a convex quadratic over the others' box), smallest at the unpinned
    optimum: it is non-increasing up to it and non-decreasing after, so
    bisection finds each row's ends, and only rows that can widen the
    extent found so far are searched.  Returns (jlo (3,), jhi (3,), lo (N, 3),
    hi (N, 3)); equal to the extent of the full scan (tested).
    """
    N = n_loc.shape[0]
    V = vals.shape[0]
    w, lg, A, B, C, G, g, lo2, hi2, x, ws = scan_buffers(z, H, R, r_t)
    lo, hi, pinned = scan_boxes(n_loc, bp)  # pinned: fixed at every n, nothing to scan
    jlo = np.full(3, V, dtype=np.int64)
    jhi = np.full(3, -1, dtype=np.int64)
    for i in range(N):
        yty = normal_at(
            z, y, w, lg, n_loc[i], s, bp[10], H, R, rm1, r_t, alpha, beta, A, B, C, G, g
        )
        box_scale(G, g, ws)
        # the unpinned optimum at this n: the smallest SSE of every pinned scan
        smin = box_faces_from(yty, lo[i], hi[i], x, ws, -1)
        if smin > thr + 1e-9 * max(thr, 1e-300):  # no pinned value can come within thr
            continue
        xs0, xs1, xs2 = x[0], x[1], x[2]
        for idx in range(3):
            if pinned[idx] or (jlo[idx] == 0 and jhi[idx] == V - 1):
                continue
            width = hi[i, idx] - lo[i, idx]
            xv = xs0 if idx == 0 else (xs1 if idx == 1 else xs2)
            vs = (xv - lo[i, idx]) / width if width > 0 else 0.0
            k = 0  # the last index with vals[k] <= vs: the SSE decreases up to k, rises after
            while k + 1 < V and vals[k + 1] <= vs:
                k += 1
            in_l = pinned_sse(yty, lo[i], hi[i], idx, vals[k], x, ws, lo2, hi2) <= thr
            in_r = (
                k + 1 < V
                and pinned_sse(yty, lo[i], hi[i], idx, vals[k + 1], x, ws, lo2, hi2) <= thr
            )
            if in_l:  # the row's set reaches down from k
                a = first_true(
                    yty, lo[i], hi[i], idx, vals, thr, 0, min(k, jlo[idx] - 1), x, ws, lo2, hi2
                )
                if a >= 0:
                    jlo[idx] = a
                if not in_r:
                    jhi[idx] = max(jhi[idx], k)
            if in_r:  # the row's set reaches up from k + 1
                b = last_true(
                    yty,
                    lo[i],
                    hi[i],
                    idx,
                    vals,
                    thr,
                    max(k + 1, jhi[idx] + 1),
                    V - 1,
                    x,
                    ws,
                    lo2,
                    hi2,
                )
                if b >= 0:
                    jhi[idx] = b
                if not in_l:
                    jlo[idx] = min(jlo[idx], k + 1)
    for idx in range(3):
        if pinned[idx]:
            jlo[idx], jhi[idx] = -2, -2
        elif jhi[idx] < 0:
            jlo[idx] = -1
    return jlo, jhi, lo, hi


@njit(error_model="numpy")
def basis_columns(z, n, H, R, rm1, r_t, alpha, beta):
    """:func:`basis_point` over depths z (Z,) and exponents n (K,): A, B, C each (K, Z)."""
    K = n.shape[0]
    Z = z.shape[0]
    A = np.empty((K, Z))
    B = np.empty((K, Z))
    C = np.empty((K, Z))
    tab = np.empty((7, Z))
    depth_table(z, H, R, r_t, tab)
    for k in range(K):
        columns_at(z, tab, n[k], H, R, rm1, r_t, alpha, beta, z, False, A[k], B[k], C[k])
    return A, B, C


@njit(error_model="numpy")
def basis_rows(z, n, H, R, rm1, r_t, alpha, beta):
    """:func:`basis_columns` for profiles z (P, Z), each at its own n (P,): A, B, C each (P, Z)."""
    P, Z = z.shape
    A = np.empty((P, Z))
    B = np.empty((P, Z))
    C = np.empty((P, Z))
    tab = np.empty((7, Z))
    for p in range(P):
        depth_table(z[p], H, R, r_t, tab)
        columns_at(z[p], tab, n[p], H, R, rm1, r_t, alpha, beta, z[p], False, A[p], B[p], C[p])
    return A, B, C

"""Compiled Markov chain of the layered posterior (numba, see :mod:`terracone.jit`).

The state of a chain is p = (D_1 .. D_(L-1), n_1 .. n_L), the linear
parameters x = (kc, kphi, cc per layer) and the noise sigma.  The target is

    p(p, x, sigma | CI) ~ sigma^-(N+1) exp(-SSE(p, x) / (2 sigma^2)) 1[x in box(n)] / vol(box(n))

(uniform priors on the search space of the interfaces, the n's and each
layer's box; 1/sigma for the noise).  Each iteration makes three moves, each
leaving the target invariant:

* **(p, x) together**: a random-walk step of p, and x carried along: its
  offset from the best x in the box, standardised by the normal equations
  at p over the variables free (not held at a bound) at both p and p', is
  kept at p' (x' = xhat' + D'^-1 L'^-T L^T D (x - xhat), with the Jacobian
  in the acceptance; a variable held at a bound keeps its distance from
  it), accepted by Metropolis.  Moving x with its
  conditional optimum and spread follows the strong ridge between n and the
  k's that a step of p alone cannot cross, and makes the step of p see the
  profile of the likelihood rather than a slice of it;
* **x given (p, sigma)**: exact Gibbs draws along fixed directions (the
  principal axes of the normal equations at the fit, and the coordinate
  axes; every other one at each iteration): along a line the conditional is
  a normal truncated to where the line meets the box (:func:`truncated_normal`);
* **sigma given the rest**: sigma^2 = SSE / chi^2_N, exact.

Of the ``moves`` steps of p per iteration, the even ones are joint steps (the
shape adapted from the chains' spread halfway through the burn-in, the scale
towards a third accepted), the odd ones move one coordinate (scale towards
0.44 accepted), and the last draws an interface anew over its whole range
(a jump between modes of a multimodal interface).  All adaptation stops
with the burn-in.
Numbers come from numba's generator seeded at the start of each call; when
compilation is off the same code runs as Python and the caller saves and
restores numpy's global generator around it.
"""

from __future__ import annotations

import math

import numpy as np

from terracone.inverse.solver import kernels as k3  # called as k3.name (see layered_kernels)
from terracone.inverse.solver import layered_kernels as lk
from terracone.jit import njit

__all__ = ["run_chains", "truncated_normal"]


@njit(error_model="numpy")
def truncated_normal(mu: float, sd: float, a: float, b: float) -> float:
    """A draw of N(mu, sd^2) truncated to [a, b] (a < b; infinite ends allowed).

    Standardised to [alpha, beta]: a plain normal when the interval holds
    the mean and enough mass, uniform proposals with the exact acceptance
    exp(-(u^2 - m^2)/2) when it is narrow, and Robert's exponential
    proposals (1995) in a far tail; every branch is exact.
    """
    if not sd > 0.0 or not math.isfinite(sd):
        return min(max(mu, a), b) if math.isfinite(mu) else 0.5 * (a + b)
    al, be = (a - mu) / sd, (b - mu) / sd
    flip = False
    if be <= 0.0:  # the left tail: mirror it
        al, be = -be, -al
        flip = True
    if al <= 0.0 and be - al > 0.5:  # holds the mean: plain normal draws
        while True:
            t = np.random.standard_normal()
            if al <= t <= be:
                break
    elif be - al < 0.5 or (al > 0.0 and (be - al) * al < 1.0):  # narrow: uniform proposals
        m = 0.0 if al <= 0.0 else al
        while True:
            t = al + (be - al) * np.random.random()
            if np.random.random() <= math.exp(-0.5 * (t * t - m * m)):
                break
    else:  # a right tail al > 0: exponential proposals (Robert 1995)
        lam = 0.5 * (al + math.sqrt(al * al + 4.0))
        while True:
            t = al + np.random.exponential(1.0 / lam)
            if t <= be and np.random.random() <= math.exp(-0.5 * (t - lam) * (t - lam)):
                break
    return mu + sd * (-t if flip else t)


@njit(error_model="numpy")
def feasible(p, L, lo_d, hi_d, gap, nlo, nhi) -> bool:
    """p inside the search space: interfaces in [lo_d, hi_d], ordered, gap apart; n's in bounds."""
    for i in range(L - 1):
        if not (lo_d <= p[i] <= hi_d):
            return False
        if i > 0 and not p[i] - p[i - 1] >= gap:
            return False
    for j in range(L):
        if not (nlo <= p[L - 1 + j] <= nhi):
            return False
    return True


@njit(error_model="numpy")
def log_box_volume(p, L, bp, lo, hi) -> float:
    """log of the volume of the box of (kc, kphi, cc) of every layer at the n's of p (pinned
    sides count 1); lo, hi (3L,) are filled with the box."""
    acc = 0.0
    for j in range(L):
        k3.kbounds(p[L - 1 + j], bp, lo[3 * j : 3 * j + 3], hi[3 * j : 3 * j + 3])
        for a in range(3 * j, 3 * j + 3):
            if hi[a] > lo[a]:
                acc += math.log(hi[a] - lo[a])
    return acc


@njit(error_model="numpy")
def state_at(z, y, lg, p, L, s, bp, geom, work, p0, X0, x0, st0) -> float:
    """Design, box and best x at p into ``work`` (X in work[0], G, g in work[1], work[2], the
    box in work[3], work[4], the best x in work[5] and its face in work[6]); returns the log
    of the box's volume (:func:`log_box_volume`) and the SSE.  The columns of the layers that
    p leaves as p0 has them are copied from X0, the design at p0; the solve starts from the
    best x x0 at p0 and its face st0."""
    D, ns = p[: L - 1], p[L - 1 :]
    lk.design_rows_from(z, lg, D, ns, s, geom, work[0], p0[: L - 1], p0[L - 1 :], X0)
    lv = log_box_volume(p, L, bp, work[3], work[4])
    work[5][:] = x0
    work[6][:] = st0
    return lv, lk.design_sse(y, p[L - 1 :], bp, work, True)


@njit(error_model="numpy")
def line_update(x, v, G, gr, Gv, lo, hi, sigma) -> None:
    """x moved along v by an exact draw of the conditional N(., sigma^2 (v'Gv)^-1) on the line;
    gr = Gx - g (the gradient at x, kept up to date) and Gv (k,) scratch."""
    k = x.shape[0]
    vgv = 0.0
    grad = 0.0
    for i in range(k):
        acc = 0.0
        for j in range(k):
            acc += G[i, j] * v[j]
        Gv[i] = acc
        vgv += v[i] * acc
        grad += v[i] * gr[i]
    ta, tb = -math.inf, math.inf
    for i in range(k):  # where the line meets the box
        if v[i] > 0.0:
            ta = max(ta, (lo[i] - x[i]) / v[i])
            tb = min(tb, (hi[i] - x[i]) / v[i])
        elif v[i] < 0.0:
            ta = max(ta, (hi[i] - x[i]) / v[i])
            tb = min(tb, (lo[i] - x[i]) / v[i])
    ta, tb = min(ta, 0.0), max(tb, 0.0)  # x is in the box: t = 0 is allowed
    if not tb > ta:
        return
    if vgv > 0.0:
        t = truncated_normal(-grad / vgv, sigma / math.sqrt(vgv), ta, tb)
    elif math.isfinite(ta) and math.isfinite(tb):
        t = ta + (tb - ta) * np.random.random()
    else:
        return
    for i in range(k):  # the clip only undoes rounding: the gradient moves by t Gv
        x[i] = min(max(x[i] + t * v[i], lo[i]), hi[i])
        gr[i] += t * Gv[i]


@njit(error_model="numpy")
def gradient(G, g, x, gr) -> None:
    """gr = G x - g."""
    k = x.shape[0]
    for i in range(k):
        acc = -g[i]
        for j in range(k):
            acc += G[i, j] * x[j]
        gr[i] = acc


@njit(error_model="numpy")
def residual_sse(X, y, x) -> float:
    acc = 0.0
    for q in range(y.shape[0]):
        r = -y[q]
        for i in range(x.shape[0]):
            r += X[q, i] * x[i]
        acc += r * r
    return acc


@njit(error_model="numpy")
def whitening(G, Lw, d, free) -> float:
    """Cholesky factor Lw of G scaled to unit diagonal (plus 1e-10) over the variables ``free``,
    and the scales d: the offset from the best x is x - xhat = D^-1 Lw^-T w for a standardised
    w.  Returns log |det(D^-1 Lw^-T)|.  A variable not free (or with a zero column) counts as
    unit: its offset is kept as it is."""
    k = G.shape[0]
    for i in range(k):
        d[i] = math.sqrt(G[i, i]) if G[i, i] > 0.0 and free[i] else 1.0
    logdet, prod = 0.0, 1.0
    for a in range(k):
        for b in range(a + 1):
            if G[a, a] > 0.0 and G[b, b] > 0.0 and free[a] and free[b]:
                v = G[a, b] / (d[a] * d[b]) + (1e-10 if a == b else 0.0)
            else:
                v = 1.0 if a == b else 0.0
            for c in range(b):
                v -= Lw[a, c] * Lw[b, c]
            if a == b:
                Lw[a, a] = math.sqrt(max(v, 1e-300))
            else:
                Lw[a, b] = v / Lw[b, b]
        prod *= d[a] * Lw[a, a]  # log det from products: a logarithm when it nears the limits
        if not 1e-100 < prod < 1e100:
            logdet -= math.log(prod)
            prod = 1.0
    return logdet - math.log(prod)


@njit(error_model="numpy")
def carry(x, xb, Lw, d, xb2, Lw2, d2, out, w) -> None:
    """out = xb2 + D2^-1 Lw2^-T Lw^T D (x - xb): the offset from the best x, standardised at
    one (D, n) and unstandardised at the other; w (k,) scratch."""
    k = x.shape[0]
    for a in range(k):  # w = Lw^T D (x - xb)
        acc = 0.0
        for c in range(a, k):
            acc += Lw[c, a] * d[c] * (x[c] - xb[c])
        w[a] = acc
    for a in range(k - 1, -1, -1):  # solve Lw2^T v = w
        acc = w[a]
        for c in range(a + 1, k):
            acc -= Lw2[c, a] * w[c]
        w[a] = acc / Lw2[a, a]
    for a in range(k):
        out[a] = xb2[a] + w[a] / d2[a]


@njit(error_model="numpy")
def propose(pn, pc, it, m, moves, L, chol, scale, cscale, space):
    """Fill pn with a proposal from pc (move m of ``moves`` at iteration it); returns the
    coordinate moved alone (-1: a joint step, -2: a jump of an interface)."""
    P = pc.shape[0]
    one = m % 2 == 1  # even moves: the joint step (adapted shape); odd: one coordinate
    ci = (it + m // 2) % P
    jump = L > 1 and m == moves - 1  # the last: an interface anywhere in its range
    for i in range(P):
        if jump:
            pn[i] = pc[i]
            if i == it % (L - 1):
                pn[i] = space[0] + (space[1] - space[0]) * np.random.random()
        elif one:
            pn[i] = pc[i] + (cscale[i] * np.random.standard_normal() if i == ci else 0.0)
        else:
            acc_i = 0.0
            for j in range(i + 1):
                acc_i += chol[i, j] * np.random.standard_normal()
            pn[i] = pc[i] + scale * acc_i
    return -2 if jump else (ci if one else -1)


@njit(error_model="numpy")
def whitened(c, G, free, wc):
    """The whitening of chain c's normal equations G over ``free`` (:func:`whitening`), from the
    chain's cache wc = (Lw, d, log det, free, valid) when it holds that free set: the same
    numbers, computed once per state."""
    Lwc, dc, ldc, fc, valid = wc
    same = valid[c]
    for i in range(free.shape[0]):
        if fc[c, i] != free[i]:
            same = False
    if not same:
        ldc[c] = whitening(G, Lwc[c], dc[c], free)
        fc[c] = free
        valid[c] = True
    return Lwc[c], dc[c], ldc[c]


@njit(error_model="numpy")
def try_move(c, pn, st, sc, z, y, lg, L, s, bp, geom, space) -> bool:
    """Metropolis step of chain c to pn with x carried (see the module); st, sc the chains'
    state and the scratch arrays of :func:`run_chains`.  True when accepted."""
    p, x, xb, Xs, Gs, gs, lo, hi, lvol, sig, sse, sts = st
    work, xn, wv, Lw2, d2, free, wc = sc
    k = x.shape[1]
    if not feasible(pn, L, space[0], space[1], space[2], space[3], space[4]):
        return False
    lv = state_at(z, y, lg, pn, L, s, bp, geom, work, p[c], Xs[c], xb[c], sts[c])[0]
    lo2, hi2 = work[3], work[4]
    for i in range(k):  # whitened over the variables free at both ends
        free[i] = sts[c, i] == 0 and work[6][i] == 0
    Lw1, d1, ld1 = whitened(c, Gs[c], free, wc)
    ld2 = whitening(work[1], Lw2, d2, free)
    carry(x[c], xb[c], Lw1, d1, work[5], Lw2, d2, xn, wv)
    for i in range(k):
        if not (lo2[i] <= xn[i] <= hi2[i]):
            return False
    s_new = residual_sse(work[0], y, xn)
    log_a = -(s_new - sse[c]) / (2.0 * sig[c] * sig[c]) + lvol[c] - lv
    log_a += ld2 - ld1  # the Jacobian of the carried offset
    if not math.log(np.random.random()) < log_a:
        return False
    p[c] = pn
    x[c], xb[c] = xn, work[5]
    Xs[c], Gs[c], gs[c] = work[0], work[1], work[2]
    sts[c] = work[6]
    lo[c], hi[c] = lo2, hi2
    lvol[c], sse[c] = lv, s_new
    wc[0][c], wc[1][c], wc[2][c], wc[3][c] = Lw2, d2, ld2, free  # the new state's whitening
    wc[4][c] = True
    return True


@njit(error_model="numpy")
def init_chains(z, y, lu1, p0, L, s, bp, geom, work):
    """The chains' state at p0: (p, x, best x, design, normal equations, box, log box
    volume, sigma, SSE, face of the best x), x at its best value."""
    C, P = p0.shape
    Z, k = z.shape[0], 3 * L
    st = (
        p0.copy(), np.empty((C, k)), np.empty((C, k)), np.empty((C, Z, k)),
        np.empty((C, k, k)), np.empty((C, k)), np.empty((C, k)), np.empty((C, k)),
        np.empty(C), np.empty(C), np.empty(C), np.zeros((C, k), dtype=np.int64),
    )  # fmt: skip
    p, x, xb, Xs, Gs, gs, lo, hi, lvol, sig, sse, sts = st
    for c in range(C):
        sse[c] = lk.layered_sse(z, y, lu1, p[c, : L - 1], p[c, L - 1 :], s, bp, geom, work)
        x[c], xb[c] = work[5], work[5]
        Xs[c], Gs[c], gs[c] = work[0], work[1], work[2]
        sts[c] = work[6]
        lvol[c] = log_box_volume(p[c], L, bp, lo[c], hi[c])
        sig[c] = math.sqrt(max(sse[c], 1e-300) / Z)
    return st


@njit(error_model="numpy")
def run_chains(z, y, p0, s, bp, geom, space, dirs, step, iters, burn, thin, seed, moves):
    """Run C chains from p0 (C, 2L-1); returns (draws (C, K, 2L-1 + 3L + 1), acceptance (C,)).

    Each kept draw is (p, x, sigma); K = (iters - burn) // thin.  space =
    (lo_d, hi_d, gap, nlo, nhi) is the search space of p; dirs (m, 3L) the
    fixed directions of the Gibbs moves of x; step (2L-1,) the initial
    random-walk scales; ``moves`` moves of p per iteration.
    """
    np.random.seed(seed)
    C, P = p0.shape
    L = (P + 1) // 2
    k = 3 * L
    Z = z.shape[0]
    K = (iters - burn) // thin
    out = np.empty((C, K, P + k + 1))
    acc = np.zeros(C)
    work = lk.new_work(Z, k)
    lg = np.empty((3, Z))
    lk.embedded_logs(z, geom, lg)
    st = init_chains(z, y, lg[0], p0, L, s, bp, geom, work)
    p, x, Xs, Gs, gs, lo, hi, sig, sse = (
        st[0],
        st[1],
        st[3],
        st[4],
        st[5],
        st[6],
        st[7],
        st[9],
        st[10],
    )
    wc = (
        np.zeros((C, k, k)),
        np.ones((C, k)),
        np.zeros(C),
        np.zeros((C, k), dtype=np.bool_),
        np.zeros(C, dtype=np.bool_),
    )  # whitening cache (see whitened)
    sc = (work, np.empty(k), np.empty(k), np.zeros((k, k)), np.empty(k),
          np.empty(k, dtype=np.bool_), wc)  # fmt: skip
    pn = np.empty(P)
    gr, Gv = np.empty(k), np.empty(k)
    chol = np.diag(step.copy())
    scale, cscale = np.ones(C), np.empty((C, P))
    for c in range(C):
        cscale[c] = step
    hist = np.empty((C, max(burn // 4, 1), P))
    nh = 0
    for it in range(iters):
        if it == burn // 2 and nh > 2 * P:  # the step's shape from the chains' spread
            chol = adapted_shape(hist[:, :nh], chol)
        for c in range(C):
            for m in range(moves):  # (p, x) together: x carried with its best value
                ci = propose(pn, p[c], it, m, moves, L, chol, scale[c], cscale[c], space)
                ok = try_move(c, pn, st, sc, z, y, lg, L, s, bp, geom, space)
                acc[c] += 1.0 / moves if ok and it >= burn else 0.0
                if it < burn and ci >= 0:  # Robbins-Monro: one coordinate towards 0.44
                    cscale[c, ci] *= math.exp((0.56 if ok else -0.44) / math.sqrt(it + 1.0))
                elif it < burn and ci == -1:  # the joint step towards 0.3 accepted
                    scale[c] *= math.exp((0.7 if ok else -0.3) / math.sqrt(it + 1.0))
            # x given (p, sigma): exact draws along every other fixed direction (the other
            # half at the next iteration)
            gradient(Gs[c], gs[c], x[c], gr)
            for d in range(it % 2, dirs.shape[0], 2):
                line_update(x[c], dirs[d], Gs[c], gr, Gv, lo[c], hi[c], sig[c])
            sse[c] = residual_sse(Xs[c], y, x[c])
            sig[c] = math.sqrt(max(sse[c], 1e-300) / np.random.chisquare(Z))  # sigma | rest
            if burn // 4 <= it < burn // 2 and nh < hist.shape[1]:
                hist[c, nh] = p[c]
            if it >= burn and (it - burn) % thin == 0 and (it - burn) // thin < K:
                r = (it - burn) // thin
                out[c, r, :P] = p[c]
                out[c, r, P : P + k] = x[c]
                out[c, r, P + k] = sig[c]
        if burn // 4 <= it < burn // 2 and nh < hist.shape[1]:
            nh += 1
    for c in range(C):
        acc[c] /= max(iters - burn, 1)
    return out, acc


@njit(error_model="numpy")
def adapted_shape(h, chol):
    """Cholesky factor of 2.38^2 / P times the pooled covariance of the chains' states h (C, T, P)
    (Haario et al.), or chol when it is not positive definite."""
    C, T, P = h.shape
    mean = np.zeros(P)
    for c in range(C):
        for t in range(T):
            mean += h[c, t]
    mean /= C * T
    cov = np.zeros((P, P))
    for c in range(C):
        for t in range(T):
            d = h[c, t] - mean
            cov += np.outer(d, d)
    cov *= (2.38 * 2.38 / P) / (C * T - 1)
    for i in range(P):
        cov[i, i] += 1e-12 * (1.0 + cov[i, i])
    out = np.zeros((P, P))
    for a in range(P):
        for b in range(a + 1):
            v = cov[a, b]
            for c2 in range(b):
                v -= out[a, c2] * out[b, c2]
            if a == b:
                if not v > 0.0:
                    return chol
                out[a, a] = math.sqrt(v)
            else:
                out[a, b] = v / out[b, b]
    return out

"""numpy twins of the compiled kernels of the layered solver.

Each function here is the reference of the kernel of the same name in
:mod:`terracone.inverse.solver.layered_kernels` (same arguments where the
shapes allow, same results to rounding; ``tests/test_layered_kernels.py``),
written with numpy array operations, and the path the layered search takes
when compilation is off (``TERRACONE_NUMBA=0``, :func:`terracone.jit.disabled`).
The columns come from the forward model itself,
:func:`terracone.physics.layers.layered_basis` and
:func:`terracone.physics.cone.normal_integrals`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
"""

from __future__ import annotations

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.boxlsq import box_lsq3_reference
from terracone.physics.cone import Cone, normal_integrals
from terracone.physics.layers import layered_basis
from terracone.physics.plate import PressureLaw

__all__ = [
    "RIDGE",
    "boxqp",
    "layer_box",
    "design_matrix",
    "layered_sse_many",
    "full_columns",
    "segment_sse",
    "layer_parts",
    "cell_terms",
    "nelder_mead",
    "fold_ratio",
]

RIDGE = 1e-13


def layer_box(
    bounds: Bounds, ns: np.ndarray, ratio: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Box (lo, hi) of (kc, kphi, cc) of each layer in SI at the exponents ns (..., L): (..., 3L).

    With a held kc/kphi ``ratio`` [m] the kc side is pinned at 0 (its column
    folded into kphi's, :func:`fold_ratio`) and kphi kept where ratio kphi is
    in kc's box, as :func:`terracone.inverse.solver.kernels.kbounds` does.
    """
    ns = np.asarray(ns, dtype=float)
    kl, kh = bounds.kc_si(ns)
    pl, ph = bounds.kphi_si(ns)
    if ratio is not None:
        if ratio > 0:
            pl = np.maximum(pl, kl / ratio)
            ph = np.maximum(np.minimum(ph, kh / ratio), pl)
        kl = kh = np.zeros(ns.shape)
    cl = np.full(ns.shape, float(bounds.cc[0]))
    ch = np.full(ns.shape, float(bounds.cc[1]))
    lo = np.stack([kl, pl, cl], axis=-1).reshape(ns.shape[:-1] + (3 * ns.shape[-1],))
    hi = np.stack([kh, ph, ch], axis=-1).reshape(ns.shape[:-1] + (3 * ns.shape[-1],))
    return lo, hi


def boxqp(
    G: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Minimise x'Gx - 2 g'x over lo <= x <= hi for a stack of problems G (M, k, k), g (M, k).

    The same primal active-set method as the compiled
    :func:`~terracone.inverse.solver.layered_kernels.boxqp`, all problems at
    once (one stacked ``numpy.linalg.solve`` per step; finished problems drop
    out).  Returns (x (M, k), iterations (M,)).
    """
    G, g, lo, hi = (np.asarray(a, dtype=float) for a in (G, g, lo, hi))
    M, k = g.shape
    diag = np.einsum("mii->mi", G)
    dead = ~(diag > 0.0)
    d = np.where(dead, 1.0, np.sqrt(np.where(dead, 1.0, diag)))
    S = np.where(dead[:, :, None] | dead[:, None, :], 0.0, G / (d[:, :, None] * d[:, None, :]))
    b = g / d
    Lb, Ub = lo * d, hi * d
    st = np.where(dead | (Lb == Ub), 1, 0)
    v = np.where(st == 1, Lb, np.clip(0.0, Lb, Ub))
    eye = np.eye(k)
    todo = np.ones(M, dtype=bool)
    iters = np.zeros(M, dtype=int)
    for _ in range(20 + 10 * k):
        rows = np.flatnonzero(todo)
        if rows.size == 0:
            break
        iters[rows] += 1
        s_, v_, S_, b_ = st[rows], v[rows], S[rows], b[rows]
        free = s_ == 0
        # the free rows of the normal equations, identity rows for the held variables
        ff = free[:, :, None] & free[:, None, :]
        A = np.where(ff, S_ + RIDGE * eye, eye)
        held = np.where(free, 0.0, v_)
        rhs = np.where(free, b_ - np.einsum("mij,mj->mi", S_, held), v_)
        w = np.linalg.solve(A, rhs[..., None])[..., 0]
        L_, U_ = Lb[rows], Ub[rows]
        with np.errstate(divide="ignore", invalid="ignore"):
            to_lo = free & (w < L_) & (w < v_)
            to_hi = free & (w > U_) & (w > v_)
            frac = np.where(to_lo, (L_ - v_) / (w - v_), np.where(to_hi, (U_ - v_) / (w - v_), 2.0))
        j = np.argmin(frac, axis=1)
        step = np.clip(frac[np.arange(rows.size), j], 0.0, 1.0)
        blocked = frac[np.arange(rows.size), j] < 1.0
        step = np.where(blocked, step, 1.0)
        v_ = np.where(free, np.clip(v_ + step[:, None] * (w - v_), L_, U_), v_)
        side = np.where(to_lo[np.arange(rows.size), j], 1, 2)
        br = np.flatnonzero(blocked)
        s_[br, j[br]] = side[br]
        v_[br, j[br]] = np.where(side[br] == 1, L_[br, j[br]], U_[br, j[br]])
        # unblocked: optimal on the face; release the most inward-pointing held variable
        grad = np.einsum("mij,mj->mi", S_, v_) - b_
        size = np.einsum("mij,mj->mi", np.abs(S_), np.abs(v_)) + np.abs(b_)
        tol = 1e-11 * size + 1e-300
        pin = L_ == U_
        viol = np.where((s_ == 1) & ~pin & (grad < -tol), -grad, 0.0)
        viol = np.where((s_ == 2) & ~pin & (grad > tol), grad, viol)
        viol[dead[rows]] = 0.0
        worst = np.argmax(viol, axis=1)
        release = ~blocked & (viol[np.arange(rows.size), worst] > 0.0)
        rr = np.flatnonzero(release)
        s_[rr, worst[rr]] = 0
        st[rows], v[rows] = s_, v_
        todo[rows[~blocked & ~release]] = False
    x = np.where(st == 1, lo, np.where(st == 2, hi, np.clip(v / d, lo, hi)))
    x = np.where(dead, lo, x)
    return x, iters


def design_matrix(
    z: np.ndarray, D: np.ndarray, ns: np.ndarray, s: float, law: PressureLaw, cone: Cone
) -> np.ndarray:
    """The layered design matrix (Z, 3L) with the kc and kphi columns times s.

    :func:`terracone.physics.layers.layered_basis` at phic = 0, scaled by the
    phic scale s = 1 + tan(phic)/tan(alpha) (eq. (2-6) fully mobilised).
    """
    X = layered_basis(z, n=ns, interfaces=D, law=law, cone=cone)
    X[:, 0::3] *= s
    X[:, 1::3] *= s
    return X


def fold_ratio(X: np.ndarray, ratio: float | None) -> np.ndarray:
    """Columns (..., 3L) with kc = ratio kphi: the kc column folded into kphi's, then 0."""
    if ratio is None:
        return X
    X = np.array(X, dtype=float, copy=True)
    X[..., 1::3] += ratio * X[..., 0::3]
    X[..., 0::3] = 0.0
    return X


def layered_sse_many(
    z: np.ndarray,
    y: np.ndarray,
    Ds: np.ndarray,
    nss: np.ndarray,
    s: float,
    bounds: Bounds,
    law: PressureLaw,
    cone: Cone,
    ratio: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """SSE (M,), solution (M, 3L) and residuals (M, Z) at interfaces Ds (M, L-1), exponents nss (M, L).

    With a held kc/kphi ``ratio`` [m] the solution's kc entries are 0 and
    each layer's kc is ratio kphi (:func:`fold_ratio`).
    """
    nss = np.atleast_2d(np.asarray(nss, dtype=float))
    Ds = np.asarray(Ds, dtype=float).reshape(nss.shape[0], -1)
    X = np.stack([design_matrix(z, D, ns, s, law, cone) for D, ns in zip(Ds, nss)])
    X = fold_ratio(X, ratio)
    G = np.einsum("mqi,mqj->mij", X, X)
    g = np.einsum("mqi,q->mi", X, y)
    lo, hi = layer_box(bounds, nss, ratio)
    x, _ = boxqp(G, g, lo, hi)
    r = np.einsum("mqi,mi->mq", X, x) - y
    return np.einsum("mq,mq->m", r, r), x, r


def full_columns(z: np.ndarray, ns: np.ndarray, s: float, law: PressureLaw, cone: Cone):
    """Columns (K, Z, 3) of the whole cone at every exponent of ns (one layer, kc/kphi times s)."""
    return np.stack([design_matrix(z, np.array([]), np.array([n]), s, law, cone) for n in ns])


def segment_sse(
    F: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray, need: np.ndarray
) -> np.ndarray:
    """One-layer SSE of the runs of rows [i, j) with need[i, j] at every n: (Z + 1, Z + 1, K)."""
    K, Z, _ = F.shape
    out = np.full((Z + 1, Z + 1, K), np.nan)
    outer = np.einsum("kqa,kqb->qkab", F, F)  # (Z, K, 3, 3)
    gy = np.einsum("kqa,q->qka", F, y)
    for i in range(Z + 1):
        out[i, i] = 0.0
        if i == Z:
            break
        G = np.cumsum(outer[i:], axis=0)
        g = np.cumsum(gy[i:], axis=0)
        yy = np.cumsum(y[i:] ** 2)[:, None] + np.zeros(K)
        _, sse = box_lsq3_reference(G, g, yy, lo[None], hi[None])
        out[i, i + 1 :] = sse
    return np.where(need[..., None], out, np.nan)


def layer_parts(
    z: np.ndarray,
    d_top: np.ndarray,
    d_bot: np.ndarray,
    ns: np.ndarray,
    s: float,
    law: PressureLaw,
    cone: Cone,
) -> np.ndarray:
    """Columns (..., 3) of the part of each cone between depths d_top and d_bot (broadcast)."""
    H, R = cone.height, cone.radius
    t = R / H
    z, d_top, d_bot, ns = np.broadcast_arrays(
        *(np.asarray(v, float) for v in (z, d_top, d_bot, ns))
    )
    u1 = z + H
    emb = np.where(z >= 0.0, H, u1)
    live = u1 > 0
    a = np.clip(u1 - d_bot, 0.0, emb)
    b = np.clip(u1 - d_top, 0.0, emb)
    with np.errstate(invalid="ignore"):
        Ic, Ip, Icc = normal_integrals(np.where(live, u1, 1.0), a, b, ns, law, t)
    ok = live & (b > a)
    cols = [2.0 * t * s * Ic / (R * R), 2.0 * t * s * Ip / (R * R), 2.0 * Icc / (R * R)]
    return np.stack([np.where(ok, c, 0.0) for c in cols], axis=-1)


def cell_terms(
    z: np.ndarray,
    y: np.ndarray,
    F: np.ndarray,
    ns: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    kidx: np.ndarray,
    seg: np.ndarray,
    mixed: np.ndarray,
    lam: np.ndarray,
    ends: np.ndarray,
    s: float,
    law: PressureLaw,
    cone: Cone,
) -> np.ndarray:
    """Per-layer Lagrangian terms (C, L, M) and cut rows' x . P (C, L, M, Z) of cells (the twin
    of the compiled ``cell_terms``)."""
    Cn, L, _ = seg.shape
    Z = F.shape[1]
    q = np.arange(Z)
    out = np.empty(kidx.shape)
    xp = np.zeros(kidx.shape + (Z,))
    for j in range(L):
        kk = kidx[:, j]  # (C, M)
        inside = (q[None, :] >= seg[:, j, 0:1]) & (q[None, :] < seg[:, j, 1:2])  # (C, Z)
        Fw = F[kk] * inside[:, None, :, None]  # (C, M, Z, 3)
        G = np.einsum("cmqa,cmqb->cmab", Fw, Fw)
        g = np.einsum("cmqa,q->cma", Fw, y)
        yy = np.einsum("cq,q->c", inside, y * y)[:, None] + np.zeros(kk.shape)
        pos = lam >= 0.0
        top = (
            np.zeros((Cn, Z)) if j == 0 else np.where(pos, ends[:, j - 1, 1:2], ends[:, j - 1, 0:1])
        )
        bot = (
            np.full((Cn, Z), np.inf)
            if j == L - 1
            else np.where(pos, ends[:, j, 0:1], ends[:, j, 1:2])
        )
        P = layer_parts(
            z[None, None, :], top[:, None, :], bot[:, None, :], ns[kk][:, :, None], s, law, cone
        )
        use = mixed & (bot > top)
        P = np.where(use[:, None, :, None], P, 0.0)
        g = g - np.einsum("cmqa,cq->cma", P, np.where(use, lam, 0.0))
        x, _ = box_lsq3_reference(G, g, yy, lo[kk], hi[kk])
        f = yy - 2.0 * np.einsum("cma,cma->cm", g, x) + np.einsum("cma,cmab,cmb->cm", x, G, x)
        # no row held in the layer: a linear term, smallest at a corner of the box
        corner = np.where(-2.0 * g * lo[kk] <= -2.0 * g * hi[kk], lo[kk], hi[kk])
        empty = seg[:, j, 1] <= seg[:, j, 0]
        x = np.where(empty[:, None, None], corner, x)
        out[:, j] = np.where(empty[:, None], -2.0 * np.einsum("cma,cma->cm", g, corner), f)
        xp[:, j] = np.einsum("cmqa,cma->cmq", P, x)
    return out, xp


def nelder_mead(
    fun, start: np.ndarray, step: np.ndarray, maxiter: int, xtol: float, ftol: float
) -> tuple[np.ndarray, float, int]:
    """scipy's Nelder-Mead from the simplex (start, start + step_i e_i); (p, f, evaluations).

    ``fun`` maps a point to its SSE (+inf outside the search space), as the
    compiled :func:`~terracone.inverse.solver.layered_kernels.nelder_mead`
    evaluates it.
    """
    from scipy.optimize import minimize  # 0.3 s to import: only on this (numpy) path

    sim = np.vstack([start, start + np.diag(step)])
    res = minimize(
        fun,
        start,
        method="Nelder-Mead",
        options={
            "initial_simplex": sim,
            "maxiter": maxiter,
            "xatol": xtol,
            "fatol": ftol,
            "adaptive": False,
        },
    )
    return np.asarray(res.x, float), float(res.fun), int(res.nfev)


def log_tip(z: np.ndarray, H: float) -> np.ndarray:
    """log of the tip depths z + H (0 where the tip is not below the surface)."""
    u1 = z + H
    return np.where(u1 > 0, np.log(np.where(u1 > 0, u1, 1.0)), 0.0)

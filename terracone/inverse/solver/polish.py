"""Polish of many bounded linear least-squares fits at once.

The last step of the vectorised exact solver of the prediction process: for
each profile's optimum (n, phic) the linear parameters (kc, kphi, cc) are
solved again on the active face of their box, stacked over the set, so that
noise-free profiles are fitted to rounding (eq. (2-6) with fully mobilised
shear is linear in kc, kphi and cc for fixed n and phic).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-6), section 3.3.2.
.. [2] Bjorck, A. (1996). Numerical Methods for Least Squares Problems. SIAM.
"""

from __future__ import annotations

import numpy as np

from terracone.jit import enabled, njit

__all__ = ["polish_many", "polish_many_numpy", "polish_kernel", "mgs_lstsq"]


def polish_many(
    X: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray, x0: np.ndarray
) -> np.ndarray:
    """Re-solve bounded linear least squares on the design matrices themselves, per profile.

    ``X`` (P, Z, 3) and ``y`` (P, Z) (padded rows zero), box ``lo``, ``hi``
    and start ``x0`` (P, 3).  The compiled :func:`polish_kernel` (one loop
    per profile), or its numpy twin :func:`polish_many_numpy` with
    ``TERRACONE_NUMBA=0``; profiles whose face solve fails go to scipy's BVLS
    either way.  A profile keeps x0 unless its sum of squares drops.
    """
    if not enabled():
        return polish_many_numpy(X, y, lo, hi, x0)
    X = np.ascontiguousarray(X, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    x, done = polish_kernel(X, y, lo.astype(float), hi.astype(float), x0.astype(float))
    for p in np.flatnonzero(~done):
        xb = _bvls(X[p], y[p], lo[p], hi[p], x0[p])
        r1, r0 = X[p] @ xb - y[p], X[p] @ x0[p] - y[p]
        x[p] = xb if r1 @ r1 < r0 @ r0 else x0[p]
    return x


def polish_many_numpy(
    X: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray, x0: np.ndarray
) -> np.ndarray:
    """The numpy reference of :func:`polish_many` (same arguments), vectorised over profiles.

    On x0's face of the box (the variables strictly inside re-solved, the
    others held) one stacked QR per face pattern; where that leaves the box
    or breaks the optimality signs, scipy's BVLS.
    """
    free = hi > lo
    act = free & (x0 > lo) & (x0 < hi)
    x = x0.copy()
    todo = free.any(axis=1)
    norms = np.sqrt(np.stack([np.einsum("pz,pz->p", X[..., i], X[..., i]) for i in range(3)], 1))
    code = act @ np.array([1, 2, 4])  # the face: which variables are strictly inside
    for c in np.unique(code[todo]):
        pattern = (c & np.array([1, 2, 4])) > 0
        sel = np.flatnonzero(todo & (code == c))
        Xs, ys, x0s = X[sel], y[sel], x0[sel]
        cand, ok = _on_face(Xs, ys, x0s, lo[sel], hi[sel], pattern)
        r = _times(Xs, cand) - ys
        grad = np.stack([np.einsum("pz,pz->p", Xs[..., i], r) for i in range(3)], 1)  # dSSE/2
        tol = 1e-8 * norms[sel] * np.sqrt(np.einsum("pz,pz->p", r, r) + 1e-300)[:, None]
        held = free[sel] & ~pattern
        wrong = (held & (x0s <= lo[sel]) & (grad < -tol)) | (held & (x0s >= hi[sel]) & (grad > tol))
        ok &= ~wrong.any(axis=1)
        x[sel[ok]] = cand[ok]
        todo[sel[ok]] = False
    for p in np.flatnonzero(todo):
        x[p] = _bvls(X[p], y[p], lo[p], hi[p], x0[p])
    r1, r0 = _times(X, x) - y, _times(X, x0) - y
    better = np.einsum("pz,pz->p", r1, r1) < np.einsum("pz,pz->p", r0, r0)
    return np.where(better[:, None], x, x0)


def _times(X: np.ndarray, x: np.ndarray) -> np.ndarray:
    """X (P, Z, k) times x (P, k): (P, Z), element by element.

    Each profile's values do not depend on the others or on the padding (a
    batched matmul may block differently), and it is faster than einsum here.
    """
    out = X[..., 0] * x[:, 0, None]
    for i in range(1, X.shape[-1]):
        out += X[..., i] * x[:, i, None]
    return out


def _on_face(X, y, x0, lo, hi, pattern) -> tuple[np.ndarray, np.ndarray]:
    """Least squares in the ``pattern`` columns (the others held at x0), per profile.

    Returns the candidates and whether each is usable: full rank and
    strictly inside the box (the caller checks the signs at held bounds).
    """
    G = X.shape[0]
    cand = x0.copy()
    if not pattern.any():
        return cand, np.ones(G, dtype=bool)
    rhs = y.copy()
    for i in np.flatnonzero(~pattern):
        rhs -= X[:, :, i] * x0[:, i, None]
    cols = np.flatnonzero(pattern)
    scale = np.sqrt(np.stack([np.einsum("pz,pz->p", X[:, :, i], X[:, :, i]) for i in cols], 1))
    ok = (scale > 0).all(axis=1)
    scale = np.where(scale > 0, scale, 1.0)
    sol, full = mgs_lstsq([X[:, :, i] / scale[:, m, None] for m, i in enumerate(cols)], rhs)
    sol = sol / scale
    cand[:, pattern] = sol
    inside = ((sol > lo[:, pattern]) & (sol < hi[:, pattern])).all(axis=1)
    return cand, ok & full & inside


def mgs_lstsq(
    A: list[np.ndarray], b: np.ndarray, rtol: float = 1e-13
) -> tuple[np.ndarray, np.ndarray]:
    """Least squares min ||A x - b|| for a stack of small problems, by modified Gram-Schmidt.

    ``A``: the k columns, each (P, Z); ``b`` (P, Z).  MGS applied to the
    augmented matrix [A | b] is backward stable for least squares ([1]_),
    unlike the normal equations, and vectorised over P it needs a few
    passes over the data instead of one LAPACK call per problem.  Returns
    x (P, k) and whether each problem has full rank (|R_ii| > rtol max
    |R_jj|; x is 0 where not).

    References
    ----------
    .. [1] Bjorck, A. (1967). Solving linear least squares problems by
       Gram-Schmidt orthogonalization. BIT 7, 1-21.
    """
    k = len(A)
    P = b.shape[0]
    q = [np.array(a, dtype=float) for a in A]
    c = np.array(b, dtype=float)
    R = np.zeros((P, k, k))
    qb = np.zeros((P, k))
    for i in range(k):
        R[:, i, i] = np.sqrt(np.einsum("pz,pz->p", q[i], q[i]))
        q[i] = q[i] / np.where(R[:, i, i] > 0, R[:, i, i], 1.0)[:, None]
        for j in range(i + 1, k):
            R[:, i, j] = np.einsum("pz,pz->p", q[i], q[j])
            q[j] = q[j] - R[:, i, j, None] * q[i]
        qb[:, i] = np.einsum("pz,pz->p", q[i], c)
        c = c - qb[:, i, None] * q[i]
    d = np.abs(np.diagonal(R, axis1=1, axis2=2))
    full = d.min(axis=1) > rtol * d.max(axis=1)
    x = np.zeros((P, k))
    with np.errstate(all="ignore"):
        for i in range(k - 1, -1, -1):  # back substitution, R x = Q'b
            rest = np.einsum("pj,pj->p", R[:, i, i + 1 :], x[:, i + 1 :])
            x[:, i] = (qb[:, i] - rest) / R[:, i, i]
    return np.where(full[:, None], x, 0.0), full


def _bvls(X, y, lo, hi, x0) -> np.ndarray:
    """scipy's BVLS on one profile's free variables (columns scaled); x0 if it fails."""
    free = hi > lo
    xf = np.where(free, 0.0, lo)
    Xf = X[:, free]
    scale = np.sqrt(np.sum(Xf * Xf, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    try:
        from scipy.optimize import lsq_linear  # on first use (0.3 s import)

        bnd = (lo[free] * scale, hi[free] * scale)
        res = lsq_linear(Xf / scale, y - X @ xf, bounds=bnd, method="bvls", tol=1e-15)
    except (ValueError, np.linalg.LinAlgError):
        return x0
    xf[free] = np.clip(res.x / scale, lo[free], hi[free])
    return xf


@njit(error_model="numpy")
def polish_kernel(X, y, lo, hi, x0):  # pragma: no cover - numba (twin: polish_many_numpy)
    """:func:`polish_many_numpy` profile by profile, compiled.

    For each profile: least squares by modified Gram-Schmidt in the
    variables strictly inside the box at x0 (the others held), on columns
    scaled to unit norm; the candidate is kept when it has full rank, stays
    strictly inside, the gradient at held bounds points outward (tolerance
    1e-8 |X_i| |r|) and the sum of squares drops.  Returns (x (P, 3), done
    (P,)); ``done`` is False where the caller must fall back to BVLS.
    """
    P, Z = X.shape[0], X.shape[1]
    x = x0.copy()
    done = np.ones(P, dtype=np.bool_)
    q = np.empty((3, Z))
    c = np.empty(Z)
    cand = np.empty(3)
    norms = np.empty(3)
    inside = np.zeros(3, dtype=np.bool_)
    for p in range(P):
        anyfree = False
        for i in range(3):
            free = hi[p, i] > lo[p, i]
            anyfree = anyfree or free
            inside[i] = free and lo[p, i] < x0[p, i] < hi[p, i]
            s2 = 0.0
            for z in range(Z):
                s2 += X[p, z, i] * X[p, z, i]
            norms[i] = np.sqrt(s2)
        if not anyfree:
            continue
        ok = face_solve(X[p], y[p], lo[p], hi[p], x0[p], inside, norms, q, c, cand)
        if ok:
            ok, better = face_accept(X[p], y[p], lo[p], hi[p], x0[p], inside, norms, cand)
            if ok and better:
                x[p] = cand
        done[p] = ok
    return x, done


@njit(error_model="numpy")
def face_solve(X, y, lo, hi, x0, inside, norms, q, c, cand):  # pragma: no cover - numba
    """Least squares of one profile (X (Z, 3), y (Z,)) in the ``inside`` variables, the
    others held at x0, by MGS on unit-norm columns as :func:`mgs_lstsq`; the result in
    ``cand``.  True when it has full rank and stays strictly inside the box."""
    Z = X.shape[0]
    cols = np.flatnonzero(inside)
    k = cols.size
    for z in range(Z):  # rhs: y minus the held columns at x0
        v = y[z]
        for i in range(3):
            if not inside[i]:
                v -= X[z, i] * x0[i]
        c[z] = v
    cand[:] = x0
    if k == 0:
        return True
    ok = True
    for m in range(k):
        sc = norms[cols[m]]
        if not sc > 0:
            ok = False
            sc = 1.0
        q[m] = X[:, cols[m]] / sc
    R = np.zeros((3, 3))
    qb = np.zeros(3)
    for m in range(k):  # MGS on [A | b]
        R[m, m] = np.sqrt(np.sum(q[m] * q[m]))
        q[m] /= R[m, m] if R[m, m] > 0 else 1.0
        for j in range(m + 1, k):
            R[m, j] = np.sum(q[m] * q[j])
            q[j] -= R[m, j] * q[m]
        qb[m] = np.sum(q[m] * c)
        c -= qb[m] * q[m]
    d = np.abs(np.diag(R)[:k])
    if not d.min() > 1e-13 * d.max():
        ok = False
    sol = np.zeros(3)
    for m in range(k - 1, -1, -1):  # back substitution, R x = Q'b
        v = qb[m]
        for j in range(m + 1, k):
            v -= R[m, j] * sol[j]
        sol[m] = v / R[m, m]
    for m in range(k):
        i = cols[m]
        cand[i] = sol[m] / (norms[i] if norms[i] > 0 else 1.0)
        if not (lo[i] < cand[i] < hi[i]):
            ok = False
    return ok


@njit(error_model="numpy")
def face_accept(X, y, lo, hi, x0, inside, norms, cand):  # pragma: no cover - numba
    """(signs ok, better): the gradient of the SSE at ``cand`` points out of the box at
    every held bound (tolerance 1e-8 |X_i| |r|), and cand's SSE is below x0's."""
    r = X @ cand - y
    e = X @ x0 - y
    rr = np.sum(r * r)
    g = X.T @ r
    rn = np.sqrt(rr + 1e-300)
    for i in range(3):
        if inside[i] or not hi[i] > lo[i]:
            continue
        tol = 1e-8 * norms[i] * rn
        if (x0[i] <= lo[i] and g[i] < -tol) or (x0[i] >= hi[i] and g[i] > tol):
            return False, False
    return True, rr < np.sum(e * e)

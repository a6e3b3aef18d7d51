"""Bounded 3-variable least squares: terracone's box_lsq3 against scipy.

The reference is ``scipy.optimize.lsq_linear(method="bvls")`` with a tight
tolerance, run on the design matrix itself (not on the normal equations that
box_lsq3 takes).  scipy refuses lo == hi, so pinned variables are moved to
the right-hand side and the reduced problem is solved by scipy.  Nothing
expected here was produced by terracone.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

from terracone.inverse.solver.boxlsq import box_lsq3, gram
from terracone.physics.cone import cone_index_basis

# ---------------------------------------------------------------------------
# independent reference
# ---------------------------------------------------------------------------


def normal_terms(X: np.ndarray, y: np.ndarray):
    """G = X'X, g = X'y, yy = y'y computed with plain numpy."""
    return X.T @ X, X.T @ y, float(y @ y)


def sse_of(X: np.ndarray, y: np.ndarray, x: np.ndarray) -> float:
    r = X @ x - y
    return float(r @ r)


def reference(X: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Global minimiser of ||X x - y||^2 over lo <= x <= hi via scipy BVLS.

    Pinned variables (lo == hi) are substituted; if all are pinned the
    answer is the pinned point.
    """
    pinned = lo == hi
    x = np.where(pinned, lo, 0.0)
    free = ~pinned
    if free.any():
        y_red = y - X[:, pinned] @ lo[pinned]
        res = lsq_linear(
            X[:, free],
            y_red,
            bounds=(lo[free], hi[free]),
            method="bvls",
            tol=1e-14,
            max_iter=1000,
        )
        x[free] = res.x
    return x, sse_of(X, y, x)


def random_problem(rng: np.random.Generator, *, N: int = 12, collinear: float | None = None):
    X = rng.normal(size=(N, 3)) * rng.uniform(0.1, 10.0, size=3)
    if collinear is not None:
        # third column nearly a combination of the first two
        X[:, 2] = 0.7 * X[:, 0] - 1.3 * X[:, 1] + collinear * rng.normal(size=N)
    x_true = rng.normal(size=3) * 3
    y = X @ x_true + 0.5 * rng.normal(size=N)
    return X, y


def random_box(rng: np.random.Generator, kind: str):
    if kind == "loose":  # optimum usually interior
        lo = -100.0 * np.ones(3)
        hi = 100.0 * np.ones(3)
    elif kind == "tight":  # several bounds active
        c = rng.normal(size=3)
        w = rng.uniform(0.05, 1.0, size=3)
        lo, hi = c - w, c + w
    elif kind == "nonneg":
        lo = np.zeros(3)
        hi = rng.uniform(0.5, 5.0, size=3)
    else:
        raise ValueError(kind)
    return lo, hi


def assert_matches(X, y, lo, hi, *, rtol=1e-9, atol_yy=1e-11):
    """box_lsq3 attains scipy's minimum: |SSE - SSE_ref| <= rtol SSE_ref + atol_yy y'y.

    box_lsq3 works from the normal equations, so its resolution is
    ~eps * cond(X)^2 relative to y'y; ``atol_yy`` is that floor.
    """
    G, g, yy = normal_terms(X, y)
    x, sse = box_lsq3(G, g, yy, lo, hi)
    x_ref, sse_ref = reference(X, y, lo, hi)
    # feasible
    assert np.all(x >= lo - 1e-12 * (1 + np.abs(lo))), (x, lo)
    assert np.all(x <= hi + 1e-12 * (1 + np.abs(hi))), (x, hi)
    # the returned sse is the objective at the returned x (up to the rounding
    # of the Gram form x'Gx - 2g'x + y'y, which scales with its largest term)
    sse_x = sse_of(X, y, x)
    gram_scale = float(np.abs(x) @ np.abs(G) @ np.abs(x)) + yy
    assert abs(sse - sse_x) <= 1e-9 * sse_x + 1e-12 * gram_scale, (sse, sse_x)
    # same minimum as scipy (neither may be lower than the other)
    tol = rtol * sse_ref + atol_yy * yy
    assert sse_x <= sse_ref + tol, (sse_x, sse_ref)
    assert sse_ref <= sse_x + tol, (sse_x, sse_ref)
    return x, x_ref


# ---------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["loose", "tight", "nonneg"])
def test_random_problems_match_bvls(kind):
    rng = np.random.default_rng(12345)
    for _ in range(60):
        X, y = random_problem(rng, N=int(rng.integers(3, 30)))
        lo, hi = random_box(rng, kind)
        x, x_ref = assert_matches(X, y, lo, hi)
        # well-conditioned: the minimiser is unique, so x agrees too
        scale = 1.0 + np.abs(x_ref)
        assert np.all(np.abs(x - x_ref) <= 1e-6 * scale), (x, x_ref)


def test_interior_optimum_is_ordinary_least_squares():
    rng = np.random.default_rng(7)
    X, y = random_problem(rng, N=20)
    x_ols = np.linalg.lstsq(X, y, rcond=None)[0]
    G, g, yy = normal_terms(X, y)
    x, sse = box_lsq3(G, g, yy, x_ols - 10.0, x_ols + 10.0)
    np.testing.assert_allclose(x, x_ols, rtol=1e-9, atol=1e-12)
    assert sse == pytest.approx(sse_of(X, y, x_ols), rel=1e-9)


@pytest.mark.parametrize("eps", [1e-2, 1e-3])
@pytest.mark.parametrize("kind", ["loose", "tight", "nonneg"])
def test_near_collinear_columns(eps, kind):
    """cond(X) up to ~1e7: scipy's minimum to 1e-9 relative or 1e-10 of y'y."""
    rng = np.random.default_rng(round(-np.log10(eps)) * 10 + len(kind))
    for _ in range(40):
        X, y = random_problem(rng, N=int(rng.integers(3, 20)), collinear=eps)
        lo, hi = random_box(rng, kind)
        assert_matches(X, y, lo, hi, atol_yy=1e-10)


@pytest.mark.parametrize("eps", [1e-4, 1e-6, 1e-9, 0.0])
@pytest.mark.parametrize("kind", ["loose", "tight", "nonneg"])
def test_numerically_singular_columns(eps, kind):
    """cond(X) >= ~1e8, so cond(X'X) >= 1/eps_machine: the normal equations
    cannot resolve the minimum better than ~1e-8 of y'y (measured worst
    1.1e-8 over 300 cases; relative SSE excess up to ~1e-5 at cond(X) ~ 1e8);
    the minimiser itself is not unique."""
    rng = np.random.default_rng(99 + len(kind) + int(eps * 1e10))
    for _ in range(40):
        X, y = random_problem(rng, N=int(rng.integers(3, 20)), collinear=eps)
        lo, hi = random_box(rng, kind)
        assert_matches(X, y, lo, hi, atol_yy=1e-7)


@pytest.mark.parametrize(
    "mask",
    [
        (True, False, False),
        (False, True, False),
        (False, False, True),
        (True, True, False),
        (True, False, True),
        (True, True, True),
    ],
)
def test_pinned_variables(mask):
    rng = np.random.default_rng(2024 + sum(i * m for i, m in enumerate(mask)))
    mask = np.array(mask)
    for _ in range(30):
        X, y = random_problem(rng, N=10)
        lo, hi = random_box(rng, "tight")
        v = lo + rng.uniform(size=3) * (hi - lo)
        lo = np.where(mask, v, lo)
        hi = np.where(mask, v, hi)
        G, g, yy = normal_terms(X, y)
        x, _ = box_lsq3(G, g, yy, lo, hi)
        # pinned (to a few ulp: box_lsq3 scales and unscales each variable)
        np.testing.assert_array_max_ulp(x[mask], v[mask], maxulp=4)
        assert_matches(X, y, lo, hi)


def test_pinned_with_collinear_columns():
    rng = np.random.default_rng(5)
    for _ in range(20):
        X, y = random_problem(rng, N=10, collinear=1e-7)
        lo, hi = random_box(rng, "nonneg")
        lo[2] = hi[2] = 0.3
        assert_matches(X, y, lo, hi)


def test_zero_column():
    """A column of zeros: that variable is arbitrary, the minimum is not."""
    rng = np.random.default_rng(11)
    for kind in ("loose", "tight", "nonneg"):
        X, y = random_problem(rng, N=8)
        X[:, 1] = 0.0
        lo, hi = random_box(rng, kind)
        assert_matches(X, y, lo, hi)


def test_batched_shapes_and_broadcasting():
    rng = np.random.default_rng(3)
    batch = (4, 5)
    N = 9
    Xs = rng.normal(size=batch + (N, 3)) * np.array([1.0, 30.0, 0.2])
    ys = rng.normal(size=batch + (N,)) * 5
    lo = np.array([-0.5, 0.0, -1.0])  # (3,) broadcast over the batch
    hi_rows = rng.uniform(0.1, 2.0, size=(5, 3))  # (5, 3) broadcast over axis 0
    G = np.einsum("...ni,...nj->...ij", Xs, Xs)
    g = np.einsum("...ni,...n->...i", Xs, ys)
    yy = np.einsum("...n,...n->...", ys, ys)
    x, sse = box_lsq3(G, g, yy, lo, hi_rows)
    assert x.shape == batch + (3,)
    assert sse.shape == batch
    for i in range(batch[0]):
        for j in range(batch[1]):
            X, y = Xs[i, j], ys[i, j]
            x_ref, sse_ref = reference(X, y, lo, hi_rows[j])
            yy_ij = float(y @ y)
            assert sse[i, j] == pytest.approx(sse_ref, rel=1e-9, abs=1e-11 * yy_ij)
            assert sse_of(X, y, x[i, j]) == pytest.approx(sse_ref, rel=1e-9, abs=1e-11 * yy_ij)
            # each cell equals the unbatched call
            x1, s1 = box_lsq3(X.T @ X, X.T @ y, y @ y, lo, hi_rows[j])
            np.testing.assert_allclose(x[i, j], x1, rtol=1e-12, atol=1e-12)


def test_gram_against_numpy():
    rng = np.random.default_rng(8)
    X = rng.normal(size=(2, 7, 3))
    y = rng.normal(size=(2, 7))
    w = rng.uniform(0.1, 2.0, size=(2, 7))
    G, g, yy = gram(X, y, w)
    for b in range(2):
        W = np.diag(w[b])
        np.testing.assert_allclose(G[b], X[b].T @ W @ X[b], rtol=1e-13)
        np.testing.assert_allclose(g[b], X[b].T @ W @ y[b], rtol=1e-13)
        assert yy[b] == pytest.approx(y[b] @ W @ y[b], rel=1e-13)
    G0, g0, yy0 = gram(X[0], y[0])
    np.testing.assert_allclose(G0, X[0].T @ X[0], rtol=1e-13)
    np.testing.assert_allclose(g0, X[0].T @ y[0], rtol=1e-13)
    assert yy0 == pytest.approx(y[0] @ y[0], rel=1e-13)


@pytest.mark.parametrize("n", [0.2, 0.74, 1.0, 1.3])
def test_cone_design_matrix(n):
    """The solver's real use: CI columns (kc, kphi, cc) of very different scale.

    At n = 1 and z >= 0 the three columns are exactly dependent (each is an
    affine function of z), so that case is rank deficient.
    """
    z = np.arange(0.0, 0.3001, 0.01)
    A, B, C = cone_index_basis(z, n=n, phic_deg=10.0)
    X = np.stack(np.broadcast_arrays(A, B, C), axis=-1)
    rng = np.random.default_rng(int(n * 100))
    y = X @ np.array([50.0, 3000.0, 2.0]) * (1 + 0.03 * rng.normal(size=z.size))
    for lo, hi in [
        (np.array([0.0, 0.0, 0.0]), np.array([1000.0, 20000.0, 100.0])),
        (np.array([0.0, 0.0, 0.0]), np.array([20.0, 2500.0, 100.0])),  # kc, kphi active
        (np.array([60.0, 0.0, 5.0]), np.array([1000.0, 20000.0, 5.0])),  # cc pinned
    ]:
        assert_matches(X, y, lo, hi, atol_yy=1e-10)


def test_cone_columns_rank_two_at_n_equal_one():
    """Closed form behind the n = 1 case above: for n = 1 and z >= 0 the kc,
    kphi and cc columns are affine in z, so rank([A, B, C]) = 2."""
    z = np.arange(0.0, 0.3001, 0.025)
    A, B, C = np.broadcast_arrays(*cone_index_basis(z, n=1.0))
    V = np.stack([np.ones_like(z), z], axis=-1)
    for col in (A, B, C):
        coef = np.linalg.lstsq(V, col, rcond=None)[0]
        np.testing.assert_allclose(V @ coef, col, rtol=1e-12, atol=1e-12 * np.abs(col).max())


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    N=st.integers(3, 25),
    collinear=st.sampled_from([(None, 1e-10), (1e-2, 1e-10), (1e-3, 1e-10), (1e-6, 1e-7)]),
    kind=st.sampled_from(["loose", "tight", "nonneg"]),
    pin=st.lists(st.booleans(), min_size=3, max_size=3),
)
def test_property_matches_bvls(seed, N, collinear, kind, pin):
    rng = np.random.default_rng(seed)
    collinear, atol_yy = collinear
    X, y = random_problem(rng, N=N, collinear=collinear)
    lo, hi = random_box(rng, kind)
    pin = np.array(pin)
    v = lo + rng.uniform(size=3) * (hi - lo)
    lo = np.where(pin, v, lo)
    hi = np.where(pin, v, hi)
    assert_matches(X, y, lo, hi, atol_yy=atol_yy)


@pytest.mark.parametrize("kind", ["loose", "tight", "nonneg"])
def test_large_batch_path_matches_bvls_and_small_path(kind):
    """Above 64 problems box_lsq3 solves the faces elementwise (Cramer); same answers."""
    rng = np.random.default_rng(99 + len(kind))
    P = 150
    Xs, ys, los, his = [], [], [], []
    for i in range(P):
        X, y = random_problem(rng, N=12, collinear=1e-4 if i % 4 == 0 else None)
        lo, hi = random_box(rng, kind)
        if i % 5 == 0:
            hi[2] = lo[2]  # a pinned variable
        Xs.append(X)
        ys.append(y)
        los.append(lo)
        his.append(hi)
    terms = [normal_terms(X, y) for X, y in zip(Xs, ys)]
    G = np.stack([t[0] for t in terms])
    g = np.stack([t[1] for t in terms])
    yy = np.array([t[2] for t in terms])
    x_big, _ = box_lsq3(G, g, yy, np.array(los), np.array(his))
    for i in range(P):
        x_one, _ = box_lsq3(G[i], g[i], yy[i], los[i], his[i])  # the stacked small path
        _, sse_ref = reference(Xs[i], ys[i], los[i], his[i])
        s_big = sse_of(Xs[i], ys[i], x_big[i])
        s_one = sse_of(Xs[i], ys[i], x_one)
        tol = 1e-9 * max(sse_ref, 1e-300) + 1e-11 * yy[i]
        assert s_big <= sse_ref + tol
        assert s_one <= sse_ref + tol
        assert np.all(x_big[i] >= los[i]) and np.all(x_big[i] <= his[i])

"""Compiled kernels of the layered solver against their numpy twins and independent references.

Each kernel of :mod:`terracone.inverse.solver.layered_kernels` is compared
with its twin in :mod:`terracone.inverse.solver.layered_numpy` to 1e-12 (on
the minimum where the two solve the same small systems in a different
order), and the twins with independent references: the forward model
:func:`terracone.physics.layers.layered_basis`, scipy's BVLS
(:func:`scipy.optimize.lsq_linear`), and weak duality (a Lagrangian bound
never above the SSE it bounds).  With ``TERRACONE_NUMBA=0`` both sides are
numpy and the twin comparisons hold trivially; the reference comparisons
still run.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from terracone import jit
from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.layered import fit_layered
from terracone.inverse.layered.fit import phic_scale
from terracone.inverse.layered.search import LayeredProblem, search_layers
from terracone.inverse.problem import Problem
from terracone.inverse.solver import layered_kernels as lk
from terracone.inverse.solver import layered_numpy as lnp
from terracone.inverse.solver.exact import solve_exact
from terracone.inverse.solver.many import bounds_params
from terracone.physics.cone import get_cone
from terracone.physics.layers import layered_basis, layered_cone_index
from terracone.physics.plate import pressure_law

CONE = get_cone("asabe-small")
H = CONE.height
LAWS = {"rm0": pressure_law("rm0"), "rm1": pressure_law("rm1", r_min=0.004)}
# base depths from the tip entering to 45 cm, as an SC900 push (2.5 cm steps)
Z = np.concatenate([[-H, -0.6 * H, 0.0], np.arange(0.025, 0.451, 0.025)])


def geom(law):
    c = [float(np.asarray(v)) for v in law.coefficients()]
    return (H, CONE.radius, not law.is_rm0, c[0], c[1], c[2])


def bvls(X, y, lo, hi) -> float:
    """SSE of scipy's bounded-variable least squares (columns scaled to unit norm; pinned
    variables, lo == hi, moved to the right-hand side, as scipy wants lo < hi)."""
    pin = lo == hi
    y = y - X[:, pin] @ lo[pin]
    X, lo, hi = X[:, ~pin], lo[~pin], hi[~pin]
    sc = np.sqrt((X * X).sum(axis=0))
    sc = np.where(sc > 0, sc, 1.0)
    res = lsq_linear(X / sc, y, bounds=(lo * sc, hi * sc), method="bvls", tol=1e-15)
    r = X @ (res.x / sc) - y
    return float(r @ r)


@pytest.mark.parametrize("law", sorted(LAWS))
@pytest.mark.parametrize(
    "D, ns",
    [
        ([], [0.7]),
        ([0.11], [0.4, 1.3]),
        ([0.012], [1.0, 0.3]),  # inside the cone's reach of the surface rows
        ([0.11, 0.2], [0.4, 1.1, 0.8]),
        ([0.101, 0.12, 0.3], [0.05, 2.0, 0.9, 1.5]),  # a layer thinner than the cone
    ],
)
def test_design_rows_equal_layered_basis(law, D, ns):
    """The compiled layered design matrix equals the forward model's to 1e-12 (with the kc and
    kphi columns scaled by s), and so does the numpy twin."""
    s = 1.37
    D, ns = np.array(D, float), np.array(ns, float)
    X = np.zeros((Z.size, 3 * ns.size))
    lk.design_rows(Z, lnp.log_tip(Z, H), D, ns, s, geom(LAWS[law]), X)
    ref = layered_basis(Z, n=ns, interfaces=D, law=LAWS[law], cone=CONE)
    ref[:, 0::3] *= s
    ref[:, 1::3] *= s
    np.testing.assert_allclose(X, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(lnp.design_matrix(Z, D, ns, s, LAWS[law], CONE), ref, rtol=1e-15)


@pytest.mark.parametrize("law", ["rm0", "rm1"])
def test_design_rows_from_equals_design_rows(law):
    """The sampler's design (the columns of unchanged layers copied from the design at another
    point, the n-free logarithms given) is the design computed afresh, to the last bit: for a
    move of one n, of one interface, and of everything."""
    s, g = 1.37, geom(LAWS[law])
    lg = np.empty((3, Z.size))
    lk.embedded_logs(Z, g, lg)
    np.testing.assert_array_equal(lg[0], lnp.log_tip(Z, H))
    D0, n0 = np.array([0.11, 0.2]), np.array([0.4, 1.1, 0.8])
    X0 = np.zeros((Z.size, 9))
    lk.design_rows(Z, lg[0], D0, n0, s, g, X0)
    for D, ns in (
        (D0, np.array([0.4, 1.3, 0.8])),
        (np.array([0.11, 0.26]), n0),
        (np.array([0.05, 0.31]), np.array([0.9, 0.2, 1.7])),
    ):
        X, ref = np.full((Z.size, 9), np.nan), np.zeros((Z.size, 9))
        lk.design_rows_from(Z, lg, D, ns, s, g, X, D0, n0, X0)
        lk.design_rows(Z, lg[0], D, ns, s, g, ref)
        np.testing.assert_array_equal(X, ref)


def random_boxes(rng, M, k, binding=True):
    X = np.abs(rng.standard_normal((M, 24, k))) * rng.uniform(0.1, 10.0, (M, 1, k))
    X[:, :, 1] += 3.0 * X[:, :, 0]  # nearly collinear columns, as kc and kphi
    y = np.einsum("mqk,mk->mq", X, rng.uniform(0.0, 2.0, (M, k))) + rng.normal(0, 0.5, (M, 24))
    lo = np.zeros((M, k))
    hi = rng.uniform(0.2, 1.5, (M, k)) if binding else np.full((M, k), 1e6)
    lo[:, -1] = hi[:, -1] = np.where(rng.uniform(size=M) < 0.2, 0.5, np.nan)  # some pinned
    lo[:, -1] = np.nan_to_num(lo[:, -1], nan=0.0)
    hi[:, -1] = np.nan_to_num(hi[:, -1], nan=1.3)
    X[: M // 10, :, 2] = 0.0  # a zero column (an empty layer): held at its lower bound
    return X, y, lo, hi


@pytest.mark.parametrize("k", [3, 6, 9])
def test_boxqp_twins_reach_the_bvls_minimum(k):
    """The compiled and numpy active-set solvers reach scipy's BVLS minimum on random boxed
    problems where upper bounds bind, variables are pinned and a column is zero."""
    rng = np.random.default_rng(k)
    M = 80
    X, y, lo, hi = random_boxes(rng, M, k)
    G = np.einsum("mqi,mqj->mij", X, X)
    g = np.einsum("mqi,mq->mi", X, y)
    xn, _ = lnp.boxqp(G, g, lo, hi)
    x = np.zeros(k)
    st = np.zeros(k, dtype=np.int64)
    ws, C, idx = np.zeros((7 + k, k)), np.zeros((k, k)), np.zeros(k, dtype=np.int64)
    binding = 0
    for m in range(M):
        assert lk.boxqp(G[m], g[m], lo[m], hi[m], x, st, ws, C, idx) > 0
        assert np.all(x >= lo[m]) and np.all(x <= hi[m])
        sse_c = float(np.sum((X[m] @ x - y[m]) ** 2))
        sse_n = float(np.sum((X[m] @ xn[m] - y[m]) ** 2))
        ref = bvls(X[m], y[m], lo[m], hi[m])
        assert sse_c == pytest.approx(sse_n, rel=1e-12)
        assert sse_c <= ref * (1 + 1e-10)
        assert sse_c == pytest.approx(ref, rel=1e-9)
        binding += int(np.any(np.isclose(x, hi[m]) & (lo[m] < hi[m])))
    assert binding >= M // 4  # the upper bounds really bind


@pytest.mark.parametrize("law", sorted(LAWS))
@pytest.mark.parametrize("L", [1, 2, 3])
def test_layered_sse_twins_and_bvls(law, L):
    """The SSE at random (D, n) points: compiled = numpy twin to 1e-12, = BVLS on the forward
    model's design matrix to 1e-9, residuals of the solution."""
    rng = np.random.default_rng(L)
    b = Bounds()
    y = layered_cone_index(
        Z[3:],
        [TerrainParameters(30, 3000, 0.6, 5, 45), TerrainParameters(5, 800, 1.2, 0, 45)][
            : max(L, 1)
        ]
        + [TerrainParameters(50, 2000, 0.9, 3, 45)] * max(L - 2, 0),
        sorted(rng.uniform(0.05, 0.4, L - 1)),
        cone=CONE,
        law=LAWS[law],
    ) * (1 + 0.05 * rng.standard_normal(Z.size - 3))
    z = Z[3:]
    M = 30
    Ds = np.sort(rng.uniform(0.05, 0.4, (M, L - 1)), axis=1)
    nss = rng.uniform(0.05, 2.0, (M, L))
    s = float(phic_scale(45.0, CONE))
    sse, x, r = lk.layered_sse_many(z, y, Ds, nss, s, bounds_params(b, None), geom(LAWS[law]))
    ssen, xn, rn = lnp.layered_sse_many(z, y, Ds, nss, s, b, LAWS[law], CONE)
    np.testing.assert_allclose(sse, ssen, rtol=1e-11)
    np.testing.assert_allclose(r, rn, rtol=1e-8, atol=1e-9 * np.abs(y).max())
    np.testing.assert_allclose(np.sum(r * r, axis=1), sse, rtol=1e-12)
    for m in range(M):
        X = lnp.design_matrix(z, Ds[m], nss[m], s, LAWS[law], CONE)
        lo, hi = lnp.layer_box(b, nss[m])
        assert sse[m] == pytest.approx(bvls(X, y, lo, hi), rel=1e-9)


def test_segment_sse_twins_and_bvls():
    """One-layer SSE of runs of rows: compiled = numpy (box_lsq3_reference) to 1e-12 of y'y, and
    = BVLS on the run's rows; runs not asked for are NaN, empty runs 0."""
    law = LAWS["rm0"]
    z = Z[3:]
    y = 900.0 * (1 + 0.1 * np.sin(9 * z)) * (z + 0.02) ** 0.3
    ns = np.linspace(0.05, 2.0, 9)
    s = float(phic_scale(30.0, CONE))
    F = lk.full_columns(z, ns, s, geom(law))
    np.testing.assert_allclose(F, lnp.full_columns(z, ns, s, law, CONE), rtol=1e-12, atol=0)
    lo, hi = lnp.layer_box(Bounds(), ns[:, None])
    need = np.triu(np.ones((z.size + 1, z.size + 1), dtype=bool))
    need[3, :] = False
    got = lk.segment_sse(F, y, lo, hi, need)
    ref = lnp.segment_sse(F, y, lo, hi, need)
    yy = float(y @ y)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * yy)
    assert np.all(np.isnan(got[3])) and np.all(
        np.diagonal(got)[:, [i for i in range(z.size + 1) if i != 3]] == 0
    )
    for i, j, k in [(0, z.size, 4), (2, 9, 0), (5, 17, 8), (10, 12, 3)]:
        assert got[i, j, k] == pytest.approx(
            bvls(F[k, i:j], y[i:j], lo[k], hi[k]), rel=1e-9, abs=1e-9 * yy
        )


def cells_problem(L=2):
    law = LAWS["rm0"]
    z = Z[3:]
    rng = np.random.default_rng(5)
    top, bot = TerrainParameters(40, 6000, 0.5, 4, 45), TerrainParameters(8, 900, 1.1, 1, 45)
    y = layered_cone_index(z, [top, bot, top][:L], [0.15, 0.3][: L - 1], cone=CONE, law=law)
    y = y * (1 + 0.05 * rng.standard_normal(z.size))
    s = float(phic_scale(45.0, CONE))
    return LayeredProblem(z, y, CONE, law, Bounds(), L, 0.05, s)


@pytest.mark.parametrize("L", [2, 3])
def test_cell_terms_twins_and_weak_duality(L):
    """The Lagrangian cell terms: compiled = numpy to 1e-12, and their sum never exceeds the SSE
    at any point of the cell (weak duality, for any multipliers): the bound is a bound."""
    pb = cells_problem(L)
    ends = pb.base_cells()
    rng = np.random.default_rng(L)
    sel = rng.choice(ends.shape[0], 6, replace=False)
    ends = ends[sel].copy()
    seg, mixed = pb.classify(ends)
    C, Zn = ends.shape[0], pb.z.size
    lam = np.where(mixed, rng.normal(0.0, 60.0, (C, Zn)), 0.0)
    kidx = np.broadcast_to(np.arange(0, pb.nsf.size, 8), (C, L, (pb.nsf.size + 7) // 8)).copy()
    args = (kidx, seg, mixed, lam, ends)
    f, xp = lk.cell_terms(pb.z, pb.y, pb.lu1, pb.Ff, pb.nsf, pb.lof, pb.hif, *args, pb.s, pb.geom)
    fn, xpn = lnp.cell_terms(
        pb.z, pb.y, pb.Ff, pb.nsf, pb.lof, pb.hif, *args, pb.s, pb.law, pb.cone
    )
    scale = float(pb.y @ pb.y)
    np.testing.assert_allclose(f, fn, rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(xp, xpn, rtol=1e-8, atol=1e-9 * np.abs(pb.y).max())
    const = -np.sum(lam * (2.0 * pb.y + lam), axis=1)
    for c in range(C):
        for _ in range(20):  # random points of the cell at grid n's: SSE >= sum of the terms
            m = rng.integers(0, kidx.shape[2], L)
            D = np.sort(rng.uniform(ends[c, :, 0], ends[c, :, 1]))
            if np.any(np.diff(D) <= 0):
                continue
            ns = pb.nsf[kidx[c, np.arange(L), m]]
            sse = float(pb.sse_many(D[None], ns[None])[0][0])
            low = float(f[c, np.arange(L), m].sum() + const[c])
            assert low <= sse * (1 + 1e-9) + 1e-9 * scale, (c, D, ns, low, sse)


@pytest.mark.parametrize("L", [1, 2, 3])
def test_search_compiled_and_numpy_agree(L):
    """The whole search with the compiled kernels and with the numpy twins: the same minimum (on
    the objective, not the path), both with a valid bound."""
    pb = cells_problem(L)
    got = search_layers(pb, levels=6)
    with jit.disabled():
        pbn = LayeredProblem(pb.z, pb.y, CONE, pb.law, Bounds(), L, 0.05, pb.s)
        assert not pbn.compiled
        ref = search_layers(pbn, levels=6)
    assert got.sse == pytest.approx(ref.sse, rel=1e-6)
    for r in (got, ref):
        assert 0.0 <= r.lower <= r.sse
        assert r.lower >= 0.5 * r.sse  # a bound that says something


@pytest.mark.parametrize("noise", [0.0, 0.03])
def test_one_layer_is_the_exact_one_layer_fit(noise):
    """fit_layered(layers=1) (the layered search without interfaces) reaches the one-layer exact
    solver's minimum, and its bound lies below it."""
    p = TerrainParameters(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
    z = Z[3:]
    y = layered_cone_index(z, [p], [], cone=CONE)
    y = y * (1 + noise * np.random.default_rng(3).standard_normal(z.size))
    res = fit_layered(CIProfile("hom", z, y, cone=CONE), layers=1)
    ref = solve_exact(z, y, cone=CONE, law=LAWS["rm0"], bounds=Bounds(), profiles=False)
    yy = float(y @ y)
    assert res.ok and res.interfaces == [] and len(res.layers) == 1
    assert res.sse <= ref.sse * (1 + 1e-9) + 1e-12 * yy
    assert res.sse >= ref.sse * (1 - 1e-6) - 1e-12 * yy
    assert res.certificate["lower_bound"] <= ref.sse * (1 + 1e-9) + 1e-12 * yy
    assert res.layers[0].n == pytest.approx(ref.n, abs=1e-3 if noise else 1e-5)


def test_one_layer_with_open_lower_bounds_searches_phic():
    """With lower bounds of kc and kphi above 0 the scaled boxes do not nest: phic is searched
    on a grid, and the one-layer special case stays within the grid's reach of the exact solver
    (which refines phic between its grid values)."""
    b = Bounds(kc=(5.0, 1000.0), kphi=(100.0, 20000.0))
    p = TerrainParameters(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
    z = Z[3:]
    y = layered_cone_index(z, [p], [], cone=CONE)
    y = y * (1 + 0.03 * np.random.default_rng(4).standard_normal(z.size))
    res = fit_layered(CIProfile("hom", z, y, cone=CONE), Problem(bounds=b), layers=1)
    ref = solve_exact(z, y, cone=CONE, law=LAWS["rm0"], bounds=b, profiles=False)
    assert res.ok
    assert res.sse <= ref.sse * (1 + 1e-3)
    assert res.certificate["lower_bound"] <= ref.sse * (1 + 1e-9)
    lo, hi = res.phic_range
    assert b.phic_deg[0] <= lo <= res.layers[0].phic_deg <= hi <= b.phic_deg[1]
    for q in res.layers:
        assert b.kc[0] <= q.kc <= b.kc[1] and b.kphi[0] <= q.kphi <= b.kphi[1]

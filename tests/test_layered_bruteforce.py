"""The layered search against a dense brute force, on generated 2- and 3-layer profiles.

Brute force: every combination of interfaces on the midpoints between
measured depths (inside the search space: two depth steps from the ends,
interfaces a step apart) and of each layer's n on a grid, with an exact
bounded least-squares solve at each point (scipy's NNLS with the variables
that exceed their caps held there, accepted on the optimality conditions,
else scipy's BVLS).  The search must never end above the brute-force
optimum (beyond 1e-9 of it: a tolerance on the objective, not on the
parameters), and its lower bound of the global minimum must lie below the
brute-force optimum, which is the SSE of a feasible point.  Profiles:
noise-free, noisy (5 % multiplicative) and weak contrast (two layers a few
per cent apart, whose interface the data cannot place).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import lsq_linear, nnls

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.layered import fit_layered
from terracone.inverse.solver.layered_numpy import layer_box
from terracone.physics.cone import get_cone
from terracone.physics.layers import layered_basis, layered_cone_index
from terracone.physics.plate import pressure_law

CONE = get_cone("asabe-small")
LAW = pressure_law("rm0")
TOL = 1e-9  # relative, on the SSE


def exact_box_lsq(X: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """min |Xx - y|^2 over lo <= x <= hi (lo = 0): NNLS, capping what exceeds hi, accepted on the
    KKT conditions; otherwise BVLS.  Independent of terracone's solvers."""
    sc = np.sqrt((X * X).sum(axis=0))
    sc = np.where(sc > 0, sc, 1.0)
    Xs = X / sc
    k = X.shape[1]
    cap = np.zeros(k, dtype=bool)
    x = np.zeros(k)
    for _ in range(k + 1):
        x[cap] = hi[cap]
        free = ~cap
        if free.any():
            xs, _ = nnls(Xs[:, free], y - X[:, cap] @ hi[cap], maxiter=50 * k)
            x[free] = xs / sc[free]
        over = free & (x > hi)
        if not over.any():
            break
        cap |= over
    r = X @ x - y
    g = X.T @ r
    tol = 1e-9 * sc * math.sqrt(float(r @ r) + 1e-300)
    inner = (x > lo) & (x < hi)
    ok = np.all(np.abs(g[inner]) <= tol[inner])
    ok &= np.all(g[(x <= lo) & ~inner] >= -tol[(x <= lo) & ~inner])
    ok &= np.all(g[(x >= hi) & ~inner] <= tol[(x >= hi) & ~inner])
    if not ok:
        res = lsq_linear(Xs, y, bounds=(lo * sc, hi * sc), method="bvls", tol=1e-14)
        r = X @ (res.x / sc) - y
    return float(r @ r)


def layer_columns(z: np.ndarray, top: float, bot: float, n: float, s: float) -> np.ndarray:
    """Columns (Z, 3) of the layer between depths top and bot (0 and inf at the ends) at n,
    from the forward model, kc and kphi columns times s."""
    if top == 0.0 and bot == math.inf:
        X = layered_basis(z, n=[n], interfaces=[], law=LAW, cone=CONE)
    elif top == 0.0:
        X = layered_basis(z, n=[n, n], interfaces=[bot], law=LAW, cone=CONE)[:, :3]
    elif bot == math.inf:
        X = layered_basis(z, n=[n, n], interfaces=[top], law=LAW, cone=CONE)[:, 3:]
    else:
        X = layered_basis(z, n=[n, n, n], interfaces=[top, bot], law=LAW, cone=CONE)[:, 3:6]
    return X * np.array([s, s, 1.0])


def brute_force(z: np.ndarray, y: np.ndarray, L: int, n_grid: int) -> tuple[float, tuple]:
    """The smallest SSE over the grid of interfaces (midpoints) and n's; (SSE, (D, n))."""
    b = Bounds()
    h = float(np.median(np.diff(z)))
    mids = 0.5 * (z[1:] + z[:-1])
    mids = mids[(mids >= z[0] + 2 * h) & (mids <= z[-1] - 2 * h)]
    ng = np.linspace(b.n[0], b.n[1], n_grid)
    s = 1.0 + math.tan(math.radians(b.phic_deg[1])) / (CONE.radius / CONE.height)
    cols: dict[tuple, np.ndarray] = {}
    best = (math.inf, None)
    for D in itertools.combinations(mids, L - 1):
        if np.any(np.diff(D) < h * (1 - 1e-9)):
            continue
        edges = [0.0, *D, math.inf]
        for ns in itertools.product(range(n_grid), repeat=L):
            blocks = []
            for j, k in enumerate(ns):
                key = (edges[j], edges[j + 1], k)
                if key not in cols:
                    cols[key] = layer_columns(z, edges[j], edges[j + 1], ng[k], s)
                blocks.append(cols[key])
            lo, hi = layer_box(b, ng[list(ns)])
            f = exact_box_lsq(np.concatenate(blocks, axis=1), y, lo, hi)
            if f < best[0]:
                best = (f, (D, ng[list(ns)]))
    return best


STRONG = [
    TerrainParameters(kc=40.0, kphi=7000.0, n=0.5, cc=3.0, phic_deg=45.0),  # a tillage pan
    TerrainParameters(kc=5.0, kphi=900.0, n=1.1, cc=1.0, phic_deg=45.0),
    TerrainParameters(kc=20.0, kphi=9000.0, n=0.8, cc=0.0, phic_deg=45.0),
]
WEAK = [
    TerrainParameters(kc=20.0, kphi=3000.0, n=0.8, cc=2.0, phic_deg=45.0),
    TerrainParameters(kc=20.0, kphi=3090.0, n=0.81, cc=2.0, phic_deg=45.0),  # 3 % apart
]

CASES = {
    # name: (layers, layer parameters, interfaces, noise, depths, n grid of the brute force)
    "2-clean": (2, STRONG[:2], [0.16], 0.0, np.arange(0.0, 0.451, 0.025), 41),
    "2-noisy": (2, STRONG[:2], [0.16], 0.05, np.arange(0.0, 0.451, 0.025), 41),
    "2-weak": (2, WEAK, [0.2], 0.02, np.arange(0.0, 0.451, 0.025), 41),
    "3-clean": (3, STRONG, [0.11, 0.24], 0.0, np.arange(0.0, 0.376, 0.025), 9),
    "3-noisy": (3, STRONG, [0.11, 0.24], 0.05, np.arange(0.0, 0.376, 0.025), 9),
    "3-weak": (3, [WEAK[0], WEAK[1], WEAK[0]], [0.11, 0.24], 0.02, np.arange(0.0, 0.376, 0.025), 9),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    """(name, profile, layers, fit, brute-force optimum) of one generated profile."""
    L, layers, D, noise, z, n_grid = CASES[request.param]
    y = layered_cone_index(z, layers, D, cone=CONE)
    rng = np.random.default_rng(sorted(CASES).index(request.param))
    y = y * (1.0 + noise * rng.standard_normal(z.size))
    prof = CIProfile(request.param, z, y, cone=CONE)
    fit = fit_layered(prof, layers=L)
    return request.param, prof, L, fit, brute_force(z, y, L, n_grid)


def test_never_above_the_brute_force_and_the_bound_holds(case):
    name, prof, L, fit, (bf, arg) = case
    yy = float(prof.ci @ prof.ci)
    assert fit.ok, fit.error
    assert fit.sse <= bf * (1 + TOL) + TOL * 1e-3 * yy, (name, fit.sse, bf, arg)
    lower = fit.certificate["lower_bound"]
    assert 0.0 <= lower <= fit.sse
    assert lower <= bf * (1 + TOL) + TOL * 1e-3 * yy, (name, lower, bf)
    exact = fit.sse <= 1e-12 * yy  # noise-free: a fit to rounding, no gap
    assert fit.certificate["gap"] == pytest.approx(0.0 if exact else (fit.sse - lower) / fit.sse)
    if "weak" not in name:  # the bound says something: a few per cent
        assert fit.certificate["gap"] < 0.05, (name, fit.certificate)
    assert fit.certificate["gap"] < 0.25, (name, fit.certificate)  # a weak contrast: looser


def test_truth_recovered_where_the_data_tell(case):
    name, prof, L, fit, _ = case
    _, layers, D, noise, z, _ = CASES[name]
    h = float(np.median(np.diff(z)))
    if "weak" in name:
        # a weak contrast: the data leave the interface (at least one) free, and say so
        assert any(t.startswith("interface_") for t in fit.undetermined), fit.undetermined
        return
    for got, want in zip(fit.interfaces, D):
        assert abs(got - want) < (0.02 * h if noise == 0 else h), (name, fit.interfaces)
    for got, want in zip(fit.layers, layers):
        assert got.n == pytest.approx(want.n, abs=1e-3 if noise == 0 else 0.35), name
    assert not any(t.startswith("interface_") for t in fit.undetermined), fit.undetermined
    if noise == 0:
        assert fit.rmsd < 1e-6 * float(np.mean(prof.ci))

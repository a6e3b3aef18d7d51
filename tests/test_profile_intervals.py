"""predict's 95% profile intervals and its "undetermined" rule, against brute force.

docs/predict.md defines them: the profile interval of a parameter is the set
of its values whose best fit (over every other parameter, within the bounds)
raises the sum of squares by less than 3.84 sigma^2, with sigma^2 the residual
variance SSE/(N - 5) floored at (1% of the mean CI)^2; a parameter whose
interval covers half of its search range or more is "undetermined".

The reference here computes that definition by brute force, independently
of terracone's solver: with phic held fixed the forward model
(terracone.physics.cone.cone_index) is linear in kc, kphi and cc at each n, so its
three columns are evaluated by calling the forward model with unit
parameters; n is scanned on a fine grid, each n's bounded least squares is
solved by scipy.optimize.lsq_linear, and for kc, kphi and cc each pinned
value is re-fitted over the other two (a 2-variable box problem solved
exactly: the interior minimum or the best of the four edges) at every n of a
fine grid.  Data are generated with known truth and a seeded noise.

terracone scans coarser grids (41 values of n, 61 of each pinned parameter)
and widens each interval by one grid step, so its intervals must hold the
brute-force ones and exceed them by at most about one grid step.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from terracone.data import CIProfile
from terracone.inverse import Bounds, predict
from terracone.inverse.problem import Problem
from terracone.physics.cone import cone_index

CHI2_1_95 = 3.841458820694124  # scipy.stats.chi2.ppf(0.95, 1)
PHIC = 20.0  # held fixed (bounds phic=20:20), as a calibration does
LINEAR = ("kc", "kphi", "cc")


def columns(z: np.ndarray, n: float) -> np.ndarray:
    """(Z, 3) model columns of kc, kphi and cc at n, from the forward model itself."""
    return np.stack(
        [
            cone_index(z, kc=1.0, kphi=0.0, n=n, cc=0.0, phic_deg=PHIC),
            cone_index(z, kc=0.0, kphi=1.0, n=n, cc=0.0, phic_deg=PHIC),
            cone_index(z, kc=0.0, kphi=0.0, n=n, cc=1.0, phic_deg=PHIC),
        ],
        axis=1,
    )


def box2_sse(A: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """min |A x - y|^2 over lo <= x <= hi for A (..., Z, 2), y (..., Z): exact.

    A convex quadratic on a rectangle has its minimum at the unconstrained
    minimiser when that is inside, else on an edge, where it is the 1-D
    minimiser clipped to the edge."""
    G = np.einsum("...zi,...zj->...ij", A, A)
    g = np.einsum("...zi,...z->...i", A, y)
    yy = np.einsum("...z,...z->...", y, y)

    def sse(x):
        return (
            yy - 2 * np.einsum("...i,...i->...", g, x) + np.einsum("...i,...ij,...j->...", x, G, x)
        )

    det = G[..., 0, 0] * G[..., 1, 1] - G[..., 0, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.stack(
            [
                (G[..., 1, 1] * g[..., 0] - G[..., 0, 1] * g[..., 1]) / det,
                (G[..., 0, 0] * g[..., 1] - G[..., 0, 1] * g[..., 0]) / det,
            ],
            axis=-1,
        )
    inside = (det > 0) & np.all((x >= lo) & (x <= hi), axis=-1)
    best = np.where(inside, sse(np.where(inside[..., None], x, 0.0)), np.inf)
    for i in (0, 1):
        j = 1 - i
        for edge in (lo[i], hi[i]):
            xe = np.empty(yy.shape + (2,))
            xe[..., i] = edge
            xe[..., j] = np.clip((g[..., j] - G[..., i, j] * edge) / G[..., j, j], lo[j], hi[j])
            best = np.minimum(best, sse(xe))
    return best


def brute_force(z: np.ndarray, y: np.ndarray, b: Bounds) -> dict:
    """Profile intervals and the global minimum of the SSE by brute force."""
    lo3 = np.array([b.kc[0], b.kphi[0], b.cc[0]])
    hi3 = np.array([b.kc[1], b.kphi[1], b.cc[1]])

    def profile_n(ns):
        return np.array(
            [2 * lsq_linear(columns(z, n), y, bounds=(lo3, hi3), method="bvls").cost for n in ns]
        )

    def threshold(sse_min):
        return sse_min + CHI2_1_95 * max(sse_min / (y.size - 5), (0.01 * np.mean(y)) ** 2)

    coarse = np.linspace(b.n[0], b.n[1], 391)
    s_coarse = profile_n(coarse)
    near = np.flatnonzero(s_coarse <= 1.2 * threshold(s_coarse.min()))
    fine = np.linspace(coarse[max(near[0] - 2, 0)], coarse[min(near[-1] + 2, 390)], 401)
    s_fine = profile_n(fine)
    sse_min = min(s_fine.min(), s_coarse.min())
    thr = threshold(sse_min)
    n_in = fine[s_fine <= thr]
    out = {"sse_min": sse_min, "n": (n_in.min(), n_in.max()), "frac": {}}
    out["frac"]["n"] = (n_in.max() - n_in.min()) / (b.n[1] - b.n[0])
    # a fit at an n whose own profile is above the threshold cannot be below it
    ns = np.linspace(n_in.min(), n_in.max(), 200)
    cols = np.stack([columns(z, n) for n in ns])  # (Nn, Z, 3)
    for k, name in enumerate(LINEAR):
        vals = np.linspace(lo3[k], hi3[k], 601)
        rest = [i for i in range(3) if i != k]
        resid = y - vals[None, :, None] * cols[:, None, :, k]  # (Nn, V, Z)
        A = np.broadcast_to(cols[:, None][..., rest], resid.shape + (2,))
        prof = box2_sse(A, resid, lo3[rest], hi3[rest]).min(axis=0)
        ok = vals[prof <= thr]
        out[name] = (ok.min(), ok.max())
        out["frac"][name] = (ok.max() - ok.min()) / (hi3[k] - lo3[k])
    return out


def generated(kc, kphi, n, noise, z, seed):
    rng = np.random.default_rng(seed)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=2.0, phic_deg=PHIC)
    return CIProfile("gen", z, ci * (1.0 + noise * rng.standard_normal(z.size)))


CASES = {
    # 46 depths to 45 cm, 0.5% noise: kc, kphi and cc all determined
    "determined": dict(
        truth=dict(kc=10.0, kphi=3000.0, n=0.9, noise=0.005, z=np.linspace(0, 0.45, 46), seed=1),
        bounds="phic=20:20",
        determined={"kc", "kphi", "cc"},
    ),
    # 11 depths to 10 cm, 3% noise, a realistic kc range: kc and kphi trade
    "undetermined": dict(
        truth=dict(kc=100.0, kphi=1000.0, n=1.0, noise=0.03, z=np.linspace(0, 0.10, 11), seed=1),
        bounds="phic=20:20,kc=0:200",
        determined=set(),
    ),
}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    c = CASES[request.param]
    prof = generated(**c["truth"])
    b = Bounds.parse(c["bounds"])
    res = predict(prof, Problem(bounds=b))
    assert res.ok, res.error
    return c, prof, b, res, brute_force(prof.depth, prof.ci, b)


def test_the_optimum_is_the_brute_force_minimum(case):
    _, prof, _, res, bf = case
    sse = float(np.sum((res.ci_model - prof.ci) ** 2))
    assert sse <= bf["sse_min"] * (1 + 1e-6)  # never worse than the brute-force minimum
    assert sse >= bf["sse_min"] * (1 - 1e-3)  # and the brute force is fine enough to judge it


def test_n_interval_holds_the_brute_force_one(case):
    _, _, b, res, bf = case
    step = (b.n[1] - b.n[0]) / 40  # terracone's n grid, and its widening
    lo, hi = res.profile_intervals["n"]
    assert bf["n"][0] - step - 1e-3 <= lo <= bf["n"][0] + 1e-3
    assert bf["n"][1] - 1e-3 <= hi <= bf["n"][1] + step + 1e-3


@pytest.mark.parametrize("name", LINEAR)
def test_linear_parameter_interval_holds_the_brute_force_one(case, name):
    _, _, b, res, bf = case
    k_lo, k_hi = {"kc": b.kc, "kphi": b.kphi, "cc": b.cc}[name]
    step = (k_hi - k_lo) / 60  # terracone's grid of each pinned parameter, and its widening
    tol = (k_hi - k_lo) / 600  # the brute-force grid
    lo, hi = res.profile_intervals[name]
    assert max(bf[name][0] - step, k_lo) - tol <= lo <= bf[name][0] + tol, (lo, bf[name])
    assert bf[name][1] - tol <= hi <= min(bf[name][1] + step, k_hi) + tol, (hi, bf[name])


def test_undetermined_follows_the_half_range_rule(case):
    c, _, _, res, bf = case
    for name in ("n",) + LINEAR:
        frac = bf["frac"][name]
        # the cases are chosen well clear of the rule's edge at one half
        assert abs(frac - 0.5) > 0.1, (name, frac)
        assert (name in res.undetermined) == (frac >= 0.5), (name, frac, res.undetermined)
    assert {p for p in ("kc", "kphi", "cc") if bf["frac"][p] < 0.5} == c["determined"]
    assert "phic" not in res.undetermined  # held fixed by the bounds

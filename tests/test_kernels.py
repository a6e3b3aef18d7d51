"""Compiled kernels (terracone.inverse.solver.kernels) against their numpy references.

Each kernel is compared with the numpy implementation it replaces, which
stays the reference (itself tested against closed forms, quadrature and
scipy elsewhere): to 1e-12 where the arithmetic is the same, and on the
minimum (SSE) where the two solve the same small linear systems in a
different order, so that the minimiser is only as sharp as its condition
number allows.  The solvers are then run end to end with and without the
compiled kernels (:func:`terracone.jit.disabled`).

With ``TERRACONE_NUMBA=0`` (the second CI run) both sides are numpy and the
comparisons hold trivially; the start-up and cache tests run in fresh
subprocesses either way.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from terracone import cone_index, jit
from terracone.data import CIProfile
from terracone.inverse import Bounds, Problem, predict
from terracone.inverse.solver.boxlsq import box_lsq3, box_lsq3_reference, gram
from terracone.inverse.solver.intervals import identify_extents, identify_scans, scan_extents
from terracone.inverse.solver.many import (
    brent_many,
    brent_steps,
    first_min,
    parabola_vertices,
    solve_exact_many,
)
from terracone.physics.cone import cone_index_basis, get_cone
from terracone.physics.plate import pressure_law

CONE = get_cone("asabe-large")
LAWS = {"rm0": pressure_law("rm0"), "rm1": pressure_law("rm1", r_min=0.004)}
ROOT = Path(__file__).resolve().parents[1]


def both_paths():
    """(label, context) for the compiled path (when numba is on) and the numpy path."""
    return [("compiled", contextlib.nullcontext()), ("numpy", jit.disabled())]


@pytest.mark.parametrize("law", sorted(LAWS))
def test_basis_point_equals_cone_index_basis(law):
    """Kernel columns A, B, C equal the numpy closed forms to 1e-12 (tip entering, shallow,
    deep below the surface where the binomial series takes over)."""
    from terracone.inverse.solver.kernels import basis_point

    H = CONE.height
    z = np.concatenate([[-H + 1e-6, -H / 2, 0.0, 1e-4], np.linspace(0.005, 0.6, 25), [3.0, 8.0]])
    c = [float(np.asarray(v)) for v in LAWS[law].coefficients()]
    for n in (0.05, 0.37, 0.8, 1.0, 1.9, 3.0):
        A, B, C = cone_index_basis(z, n=n, law=LAWS[law], cone=CONE)
        got = np.array([basis_point(float(zi), n, H, CONE.radius, law == "rm1", *c) for zi in z])
        for k, ref in enumerate((A, B, C)):
            np.testing.assert_allclose(got[:, k], ref, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("law", sorted(LAWS))
def test_columns_from_the_depth_table_equal_cone_index_basis(law):
    """The cells' columns (n-free parts from a per-profile table, closed form or series per
    depth, powers u1^(n+1) given or computed) equal the numpy closed forms to 1e-12."""
    from terracone.inverse.solver.kernels import basis_columns, basis_rows, columns_at, depth_table

    H, R = CONE.height, CONE.radius
    z = np.concatenate([[-H + 1e-6, -H / 2, 0.0, 1e-4], np.linspace(0.005, 0.6, 25), [3.0, 8.0]])
    c = [float(np.asarray(v)) for v in LAWS[law].coefficients()]
    tab = np.empty((7, z.size))
    depth_table(z, H, R, c[0], tab)
    for n in (0.05, 0.37, 0.8, 1.0, 1.9, 3.0):
        ref = cone_index_basis(z, n=n, law=LAWS[law], cone=CONE)
        p1 = np.where(z + H > 0, np.abs(z + H) ** (n + 1.0), 1.0)
        for use_p1 in (False, True):
            got = np.empty((3, z.size))
            columns_at(z, tab, n, H, R, law == "rm1", *c, p1, use_p1, *got)
            for k in range(3):
                np.testing.assert_allclose(got[k], ref[k], rtol=1e-12, atol=1e-300)
    ns = np.array([0.05, 0.8, 1.9])
    cols = basis_columns(z, ns, H, R, law == "rm1", *c)  # every n at once
    ref = cone_index_basis(z[None, :], n=ns[:, None], law=LAWS[law], cone=CONE)
    for k in range(3):
        np.testing.assert_allclose(
            cols[k], np.broadcast_to(ref[k], cols[k].shape), rtol=1e-12, atol=1e-300
        )
    # profile by profile, each at its own n (predict_many's polish)
    zz = np.stack([z, z * 0.5, z + 0.01])
    rows = basis_rows(zz, ns, H, R, law == "rm1", *c)
    ref = cone_index_basis(zz, n=ns[:, None], law=LAWS[law], cone=CONE)
    for k in range(3):
        np.testing.assert_allclose(rows[k], ref[k], rtol=1e-12, atol=1e-300)


def random_box_problems(rng, M):
    X = rng.normal(size=(M, 12, 3)) * rng.uniform(0.1, 10.0, size=(M, 1, 3))
    y = rng.normal(size=(M, 12)) * 5.0
    G, g, yy = gram(X, y)
    c = rng.normal(size=(M, 3))
    half = rng.uniform(0.05, 2.0, size=(M, 3))
    lo, hi = c - half, c + half
    pin = rng.uniform(size=(M, 3)) < 0.15
    lo = np.where(pin, c, lo)
    hi = np.where(pin, c, hi)
    return G, g, yy, lo, hi


def test_box_lsq3_matches_the_numpy_reference():
    """Well-conditioned random boxes (some variables pinned): SSE and x to 1e-12."""
    rng = np.random.default_rng(20261123)
    G, g, yy, lo, hi = random_box_problems(rng, 400)
    x, sse = box_lsq3(G, g, yy, lo, hi)
    x_ref, sse_ref = box_lsq3_reference(G, g, yy, lo, hi)
    np.testing.assert_allclose(sse, sse_ref, rtol=1e-12, atol=1e-12 * yy.max())
    scale = 1.0 + np.abs(x_ref)
    assert np.all(np.abs(x - x_ref) <= 1e-12 * scale * 10), np.max(np.abs(x - x_ref) / scale)
    assert np.all((x >= lo) & (x <= hi))
    assert np.array_equal(x[lo == hi], lo[lo == hi])  # pinned values exactly


def test_box_lsq3_broadcasts_like_the_reference():
    rng = np.random.default_rng(3)
    G, g, yy, lo, hi = random_box_problems(rng, 6)
    x, sse = box_lsq3(G[:, None], g[:, None], yy[:, None], lo[None], hi[None])
    assert x.shape == (6, 6, 3) and sse.shape == (6, 6)
    x_ref, sse_ref = box_lsq3_reference(G[:, None], g[:, None], yy[:, None], lo[None], hi[None])
    np.testing.assert_allclose(sse, sse_ref, rtol=1e-12, atol=1e-12 * yy.max())


def noisy_profile(seed, terrain=(102.0, 5301.0, 0.79, 1.5, 12.0), noise=0.03, dz=0.01):
    kc, kphi, n, cc, phic = terrain
    z = np.round(np.arange(0.0, 0.3 + dz / 2, dz), 10)
    ci = cone_index(z, kc=kc, kphi=kphi, n=n, cc=cc, phic_deg=phic)
    rng = np.random.default_rng(seed)
    return z, ci * (1.0 + noise * rng.standard_normal(z.size))


@pytest.mark.parametrize("law", sorted(LAWS))
def test_identify_scans_match(law):
    """Profile scans of the identifiability analysis: the SSE of every pinned fit to 1e-12
    (relative, or of y'y)."""
    z, y = noisy_profile(1)
    n_loc = np.linspace(0.7, 0.9, 9)
    vals = np.linspace(0.0, 1.0, 61)
    b = Bounds()
    out = {}
    for label, ctx in both_paths():
        with ctx:
            out[label] = identify_scans(z, y, n_loc, 14.0, None, b, CONE, LAWS[law], vals)
    (s1, lo1, hi1), (s0, lo0, hi0) = out["compiled"], out["numpy"]
    np.testing.assert_allclose(lo1, lo0, rtol=1e-12)
    np.testing.assert_allclose(hi1, hi0, rtol=1e-12)
    np.testing.assert_allclose(s1, s0, rtol=1e-12, atol=1e-12 * float(y @ y))


@pytest.mark.parametrize("law", sorted(LAWS))
def test_identify_extents_equal_the_full_scan(law):
    """The bisected extents of the pinned scans (first and last value within the threshold at
    some n) equal those read off the full scan of the same path, over terrains, noise levels,
    kc = 0, cc fixed, and thresholds from just above the best SSE to far above it."""
    vals = np.linspace(0.0, 1.0, 61)
    cases = [
        (1, dict()),
        (2, dict(noise=0.0)),
        (3, dict(terrain=(0.0, 1948.9, 0.514, 0.0, 14.37))),
        (4, dict(noise=0.05, dz=0.025)),
    ]
    for seed, kw in cases:
        z, y = noisy_profile(seed, **kw)
        n_loc = np.unique(np.r_[np.linspace(0.45, 1.05, 17), np.linspace(0.64, 0.84, 9)])
        for b in (Bounds(), Bounds(cc=(0.0, 0.0))):
            sse = identify_scans(z, y, n_loc, 14.0, None, b, CONE, LAWS[law], vals)[0]
            best = float(np.nanmin(sse))
            for f in (1.001, 1.05, 1.5, 3.0, 30.0, 1e4):
                thr = best * f + 1e-9 * float(y @ y)
                want = scan_extents(sse, thr)
                got = identify_extents(z, y, n_loc, 14.0, None, b, CONE, LAWS[law], vals, thr)
                assert got[0].tolist() == want[0].tolist(), (seed, f)
                assert got[1].tolist() == want[1].tolist(), (seed, f)
            if b.cc == (0.0, 0.0):
                assert got[0][2] == got[1][2] == -2  # cc fixed at every n: not scanned


def test_parabola_vertices_by_hand():
    """The vertex of a parabola through three of its points (hand-made bracket), NaN without a
    bracket."""
    q = lambda x: 3.0 * (x - 0.37) ** 2 + 2.0  # noqa: E731
    xl, xm, xr = np.array([0.1, 0.2, 0.0]), np.array([0.35, 0.4, 0.2]), np.array([0.6, 0.9, 0.3])
    v = parabola_vertices(xl, q(xl), xm, q(xm), xr, q(xr))
    assert v[0] == pytest.approx(0.37, abs=1e-12)
    assert v[1] == pytest.approx(0.37, abs=1e-12)
    assert np.isnan(v[2])  # 0.37 is outside (0, 0.3): no bracket


def test_brent_steps_equal_the_kernel_step():
    """brent_steps (numpy, vectorised) takes the step of kernels.brent_step (run as Python,
    the same arithmetic) on random states: parabolic, golden and minimum-length steps alike."""
    from terracone.inverse.solver import kernels

    step = getattr(kernels.brent_step, "py_func", kernels.brent_step)
    rng = np.random.default_rng(23)
    M = 2000
    a, b = rng.uniform(-1, 0, M), rng.uniform(0.5, 2, M)
    x, w, v = (a + (b - a) * rng.uniform(size=M) for _ in range(3))
    x[::7] = w[::7]  # coincident points: no parabola
    fx, fw, fv = rng.uniform(0, 1, M) * 0.5, rng.uniform(0.5, 1, M), rng.uniform(0.5, 1, M)
    d, e = rng.uniform(-1, 1, M), rng.uniform(-1, 1, M) * rng.choice([1e-12, 1.0], M)
    tol = 1e-3
    got = brent_steps(a, b, x, w, v, fx, fw, fv, d, e, tol)
    kinds = set()
    for i in range(M):
        want = step(a[i], b[i], x[i], w[i], v[i], fx[i], fw[i], fv[i], d[i], e[i], tol)
        assert [float(g[i]) for g in got] == [float(c) for c in want], i
        kinds.add("parabolic" if want[2] == d[i] else "golden")  # a parabola keeps e = d
    assert kinds == {"golden", "parabolic"}


@pytest.mark.parametrize("kink", [False, True])
def test_brent_many_reaches_the_minimum_within_its_tolerance(kink):
    """Closed-form minima (a quadratic, and a kinked function as where a bound of the box becomes
    active): every problem ends within 2 xtol of its minimiser, and agrees with the compiled
    scalar loop's stopping rule (the bracket at most 4 xtol wide)."""
    rng = np.random.default_rng(5 + kink)
    P = 300
    c = rng.uniform(0.2, 0.8, P)
    k = rng.uniform(0.5, 50.0, P)

    def fun(x, rows):
        d = x - c[rows]
        return k[rows] * d * d + (np.where(d > 0, 30.0 * d, -0.1 * d) if kink else 0.0)

    a, b = np.zeros(P), np.ones(P)
    x0 = np.clip(c + rng.uniform(-0.3, 0.3, P), 0.01, 0.99)
    x0[:5] = 0.0  # starting at an end of the bracket
    x0[5:10] = 1.0
    calls = []

    def f(rows, u):
        calls.append(rows.size)
        return fun(u, rows)

    xtol = 1e-9
    rows = np.arange(P)
    x, fx, used = brent_many(f, a, b, x0, fun(x0, rows), fun(a, rows), fun(b, rows), xtol)
    assert np.all(np.abs(x - c) <= 2 * xtol)
    np.testing.assert_array_equal(fx, fun(x, rows))
    assert used == sum(calls) and P < used < 60 * P
    assert calls[-1] < P  # problems stop one by one


def fit_many(zs, ys, **kw):
    kw.setdefault("cone", CONE)
    kw.setdefault("law", LAWS["rm0"])
    kw.setdefault("bounds", Bounds())
    out = {}
    for label, ctx in both_paths():
        with ctx:
            out[label] = solve_exact_many(zs, ys, **kw)
    return out["compiled"], out["numpy"]


@pytest.mark.parametrize("P", [3, 40])  # phic: the zooming grid (few profiles), golden section
def test_solve_exact_many_same_with_and_without_kernels(P):
    """Same fits: the grid profile of SSE over n to 1e-12, the optimum's SSE to 1e-9 (the
    refinement of n ends in rounding noise), n to 1e-6."""
    rng = np.random.default_rng(P)
    zs, ys = [], []
    for i in range(P):
        t = (rng.uniform(0, 60), rng.uniform(500, 6000), rng.uniform(0.4, 1.2), 2.0, 10.0)
        z, y = noisy_profile(i, t, noise=0.02 * (i % 3), dz=(0.01, 0.02)[i % 2])
        zs.append(z)
        ys.append(y)
    c, r = fit_many(zs, ys)
    yy = np.array([float(y @ y) for y in ys])
    np.testing.assert_allclose(c.sse_n, r.sse_n, rtol=1e-12, atol=1e-12 * yy.max())
    np.testing.assert_allclose(c.sse, r.sse, rtol=1e-9, atol=1e-12 * yy.max())
    np.testing.assert_allclose(c.n, r.n, atol=1e-6)
    np.testing.assert_allclose(c.phic_deg, r.phic_deg, atol=1e-4)


def test_first_min_breaks_near_ties_to_the_first_index():
    v = np.array([[3.0, 1.0 + 1e-15, 1.0, 2.0], [5.0, 4.0, 4.0, 0.5]])
    assert first_min(v, 1e-12).tolist() == [1, 3]
    assert first_min(v, 0.0).tolist() == [2, 3]


CASES = {
    "noisy": dict(),
    "noise-free": dict(noise=0.0),
    "kc=0": dict(terrain=(0.0, 1948.9, 0.514, 0.0, 14.37)),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("law", sorted(LAWS))
def test_predict_same_with_and_without_kernels(case, law):
    z, y = noisy_profile(7, **CASES[case])
    prof = CIProfile("p", z, y)
    kw = dict(model=law, r_min=0.004 if law == "rm1" else None)
    out = {}
    for label, ctx in both_paths():
        with ctx:
            out[label] = predict(prof, Problem(**kw))
    c, r = out["compiled"], out["numpy"]
    assert c.ok and r.ok
    rms = float(np.sqrt(np.mean(y * y)))
    assert abs(c.rmsd - r.rmsd) <= 1e-9 * r.rmsd + 1e-9 * rms
    assert c.params.n == pytest.approx(r.params.n, abs=1e-6)
    assert sorted(c.undetermined) == sorted(r.undetermined)
    assert set(c.profile_intervals) == set(r.profile_intervals)


def run_py(code: str, **env_extra: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["TERRACONE_NUMBA"] = "1"  # compiled on demand (tests/test_jit.py tests the default)
    env.update(env_extra)
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=600,
    )


def test_cli_start_up_imports_no_numba():
    """`terracone --help` and a forward curve neither import numba nor compile."""
    p = run_py(
        """
        import sys
        from click.testing import CliRunner
        from terracone.cli import cli as main
        r = CliRunner().invoke(main, ["--help"])
        assert r.exit_code == 0, r.output
        r = CliRunner().invoke(main, ["ci", "--kc", "100", "--kphi", "5000", "--n", "0.8", "--depths", "0,0.1"])
        assert r.exit_code == 0, r.output
        print("numba" in sys.modules)
        """
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip().splitlines()[-1] == "False"


def test_switch_disables_the_kernels():
    p = run_py("from terracone import jit; print(jit.enabled(), jit.mode())", TERRACONE_NUMBA="0")
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["False", "off"]


KERNEL_RUN = """
    import os
    {pre}
    import numpy as np
    from terracone import jit
    from terracone.inverse.solver.boxlsq import box_lsq3
    if not jit.enabled():
        print("disabled"); raise SystemExit(0)
    G = np.eye(3)[None] * 2.0
    box_lsq3(G, np.ones((1, 3)), np.ones(1), np.zeros((1, 3)), np.ones((1, 3)))
    from terracone.inverse.solver import kernels
    d = kernels.box_lsq3_flat
    print(os.environ.get("NUMBA_CACHE_DIR"), sum(d.stats.cache_hits.values()),
          sum(d.stats.cache_misses.values()))
"""


@pytest.mark.skipif(os.environ.get("TERRACONE_NUMBA") == "0", reason="kernels switched off")
def test_cache_in_user_dir_when_package_dir_is_read_only(tmp_path):
    """A read-only package directory (simulated: os.access says so) sends the cache to
    $XDG_CACHE_HOME/terracone/numba; the second process loads the kernel from it."""
    pre = textwrap.dedent(
        """
        _real = os.access
        os.access = lambda p, m, *a, **k: False if "terracone" in str(p) else _real(p, m, *a, **k)
        """
    ).replace("\n", "\n    ")
    code = KERNEL_RUN.format(pre=pre)
    first = run_py(code, XDG_CACHE_HOME=str(tmp_path))
    assert first.returncode == 0, first.stderr
    cache, hits, misses = first.stdout.split()
    assert Path(cache) == tmp_path / "terracone" / "numba"
    assert any(Path(cache).rglob("*.nbi")), "no index written to the user cache"
    assert (int(hits), int(misses)) == (0, 1)
    second = run_py(code, XDG_CACHE_HOME=str(tmp_path))
    assert second.returncode == 0, second.stderr
    assert second.stdout.split()[1:] == ["1", "0"]  # loaded from the cache, not compiled


def test_explicit_cache_dir_is_kept(tmp_path):
    """NUMBA_CACHE_DIR set by the user is left alone, even for a read-only package dir."""
    p = run_py(
        """
        import os
        os.access = lambda *a, **k: False
        from terracone import jit
        jit.enabled()
        print(os.environ["NUMBA_CACHE_DIR"])
        """,
        NUMBA_CACHE_DIR=str(tmp_path / "nc"),
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == [str(tmp_path / "nc")]


def test_check_fits_equal_check_fit():
    """batch's check_fits (compiled screen + check_fit for the flagged) gives check_fit's
    longest run and lack-of-fit reason for every profile: clean, noisy, clustered residuals,
    a low R2 and a layered (falling) profile."""
    from terracone.apps.batch import check_fits
    from terracone.physics.metrics import check_fit

    rng = np.random.default_rng(11)
    Z = 40
    z = np.linspace(0.0, 0.4, Z)
    ys, ms = [], []
    for i in range(60):
        m = 100.0 + 800.0 * z ** rng.uniform(0.5, 1.2)
        kind = i % 5
        if kind == 0:
            y = m.copy()  # exact fit
        elif kind == 1:
            y = m * (1 + 0.03 * rng.standard_normal(Z))
        elif kind == 2:
            y = m + 20.0 * np.sin(6 * z / 0.4)  # residuals of one sign over long stretches
        elif kind == 3:
            y = m.mean() + 300.0 * rng.standard_normal(Z)  # R2 far below 0.8
        else:
            y = np.where(z > 0.2, 0.5 * m, m)  # CI falls with depth
        ys.append(y)
        ms.append(m)
    npts = rng.integers(4, Z + 1, size=len(ys))
    npts[:5] = Z
    yy = np.zeros((len(ys), Z))
    mm = np.zeros((len(ys), Z))
    zz = np.broadcast_to(z, yy.shape).copy()
    for i, (y, m) in enumerate(zip(ys, ms)):
        yy[i, : npts[i]] = y[: npts[i]]
        mm[i, : npts[i]] = m[: npts[i]]
    runs, lof = check_fits(zz, yy, mm, npts)
    flagged = 0
    for i in range(len(ys)):
        k = int(npts[i])
        ref = check_fit(z[:k], yy[i, :k], mm[i, :k])
        assert runs[i] == ref.longest_run
        assert lof[i] == ref.lack_of_fit
        flagged += ref.lack_of_fit is not None
    assert 10 <= flagged <= 50  # the three reasons and clean fits are all exercised


def brute_force_n(z, y, bounds, law, n_vals, phis):
    """Best (SSE, n) over a grid of n x phic, each cell solved exactly: the columns of
    cone_index_basis, the 27-face box solve of box_lsq3_reference, the SSE from the residuals."""
    A, B, C = cone_index_basis(z[None, :], n=n_vals[:, None], phic_deg=0.0, law=law, cone=CONE)
    s = 1.0 + np.tan(np.radians(phis)) / np.tan(CONE.half_angle)  # eq. (2-6) fully mobilised
    X = np.stack(
        np.broadcast_arrays(A[:, None] * s[:, None], B[:, None] * s[:, None], C[:, None]), -1
    )
    G, g, yy = gram(X, y)
    kc, kp = bounds.kc_si(n_vals), bounds.kphi_si(n_vals)
    lo = np.stack([kc[0], kp[0], np.full(n_vals.size, bounds.cc[0])], -1)[:, None]
    hi = np.stack([kc[1], kp[1], np.full(n_vals.size, bounds.cc[1])], -1)[:, None]
    x, _ = box_lsq3_reference(G, g, yy, lo + 0 * G[..., 0], hi + 0 * G[..., 0])
    r = np.einsum("nfzk,nfk->nfz", X, x) - y
    sse = np.einsum("nfz,nfz->nf", r, r).min(axis=1)
    i = int(np.argmin(sse))
    return float(sse[i]), float(n_vals[i])


def dense_optimum(z, y, bounds, law):
    """Brute force: n on a grid of step 1e-3 over the bounds, then twice 2001 points within two
    steps of the best (steps 2e-6, 4e-9), phic on ten values each time."""
    lo, hi = bounds.n
    phis = np.linspace(*bounds.phic_deg, 10)
    sse, n = brute_force_n(
        z, y, bounds, law, np.linspace(lo, hi, int(round((hi - lo) / 1e-3)) + 1), phis
    )
    for h in (1e-3, 2e-6):
        vals = np.linspace(max(lo, n - 2 * h), min(hi, n + 2 * h), 2001)
        sse2, n2 = brute_force_n(z, y, bounds, law, vals, phis)
        if sse2 <= sse:
            sse, n = sse2, n2
    return sse, n


SEARCH_CASES = {
    "noisy": (dict(), Bounds(), "rm0"),
    "noise-free": (dict(noise=0.0), Bounds(), "rm0"),
    "noisy rm1": (dict(), Bounds(), "rm1"),
    # kc = cc = 0: both lower bounds become active at n* (a kink of the SSE over n)
    "kc=cc=0 noise-free": (
        dict(noise=0.0, terrain=(0.0, 1948.9, 0.514, 0.0, 14.37)),
        Bounds(),
        "rm0",
    ),
    "kc=cc=0 noisy": (dict(noise=0.02, terrain=(0.0, 1948.9, 0.514, 0.0, 14.37)), Bounds(), "rm0"),
    # the upper bound of kc holds at the optimum, which moves n
    "kc capped noise-free": (dict(noise=0.0), Bounds(kc=(0.0, 20.0)), "rm0"),
    # the optimum sits on the upper bound of n (truth n = 0.79)
    "n capped noisy": (dict(), Bounds(n=(0.05, 0.6)), "rm0"),
}


@pytest.mark.parametrize("case", sorted(SEARCH_CASES))
def test_n_search_finds_the_brute_force_optimum(case):
    """The refinement of n (Brent's method, compiled and in numpy) ends at least as
    low as a dense brute force over n and phic (resolution 4e-9 in n), within 1e-9 of the SSE or
    1e-15 of y'y at a perfect fit (the box solve compares faces by the normal equations, which
    resolve about 1e-16 of y'y; 20 golden steps leave the noise-free kink case at 3e-14), and at
    the same n where the data determine it."""
    kw, bounds, law = SEARCH_CASES[case]
    z, y = noisy_profile(11, **kw)
    best, n_star = dense_optimum(z, y, bounds, LAWS[law])
    yty = float(y @ y)
    for label, ctx in both_paths():
        with ctx:
            sol = solve_exact_many([z], [y], cone=CONE, law=LAWS[law], bounds=bounds)
        assert sol.sse[0] <= best * (1.0 + 1e-9) + 1e-15 * yty, (label, sol.sse[0], best)
        # and a real optimum: the brute force is not far below either
        assert sol.sse[0] >= best * (1.0 - 1e-6) - 1e-12 * yty, (label, sol.sse[0], best)
        if "noise-free" in case or "capped" in case:
            assert sol.n[0] == pytest.approx(n_star, abs=1e-6), label


def test_profiles_sharing_depths_fit_as_they_do_alone():
    """Profiles on one depth grid (as an SC900's) share the grid's columns: each fit equals the
    same profile fitted alone, and the grid profile of SSE over n equals the numpy path's."""
    z = np.round(np.arange(0.0, 0.3 + 0.005, 0.01), 10)
    terrains = [
        (102.0, 5301.0, 0.79, 1.5, 12.0),
        (0.0, 1948.9, 0.514, 0.0, 14.37),
        (30, 900, 1.1, 4, 20),
    ]
    ys = [noisy_profile(i, t, noise=0.02 * i)[1] for i, t in enumerate(terrains)]
    zs = [z, z, z[:-3], z[:-3], z]  # runs of equal depth vectors, a shorter one in between
    ys = [ys[0], ys[1], ys[2][:-3], ys[0][:-3], ys[2]]
    c, r = fit_many(zs, ys)
    yy = np.array([float(y @ y) for y in ys])
    np.testing.assert_allclose(c.sse_n, r.sse_n, rtol=1e-12, atol=1e-12 * yy.max())
    for i in range(len(zs)):
        one = solve_exact_many([zs[i]], [ys[i]], cone=CONE, law=LAWS["rm0"], bounds=Bounds())
        np.testing.assert_allclose(c.sse_n[i], one.sse_n[0], rtol=1e-12, atol=1e-12 * yy[i])
        assert c.n[i] == pytest.approx(one.n[0], abs=1e-6)
        assert c.sse[i] == pytest.approx(one.sse[0], rel=1e-9, abs=1e-15 * yy[i])

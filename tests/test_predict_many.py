"""predict_many: one vectorised solving path for a set of CI profiles.

References are independent of the path under test: predict run profile by
profile, the forward model with known parameters (noise-free data), numpy's
and scipy's least-squares solvers, and pools that must not change results.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.pool import ThreadPool

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from terracone.data import CIProfile, InputError, ProfileSet
from terracone.inverse.bounds import Bounds
from terracone.inverse.predict import RunSettings, predict, predict_many
from terracone.inverse.problem import Problem
from terracone.inverse.solver.many import solve_exact_many
from terracone.inverse.solver.polish import mgs_lstsq, polish_many
from terracone.jit import enabled
from terracone.physics.cone import cone_index, get_cone

LARGE, SMALL = get_cone("asabe-large"), get_cone("asabe-small")
#: The compiled kernels treat each profile alone whatever the set around it (a set's
#: profiles are padded to one length and masked), so a set and one-by-one agree to the
#: last digits.  The numpy twins (TERRACONE_NUMBA=0) sum the padded rows in another
#: order (and numpy's sums follow the CPU's vector units): their Brent search of n takes
#: the same steps on slightly different values and ends within the same bracket width of
#: the optimum, where kc, kphi, cc (nearly collinear) may still move at the same optimum
#: value.  There (:func:`same_fit`) the value of the optimum is compared, not its location.
RTOL, ATOL = 1e-9, 1e-12


def synthetic(
    n_profiles: int, seed: int = 0, noise: float = 0.0, prefix: str = "s"
) -> tuple[list, list]:
    """Profiles from the forward model with known parameters, alternating two cones."""
    rng = np.random.default_rng(seed)
    profiles, truths = [], []
    for i in range(n_profiles):
        cone = LARGE if i % 2 == 0 else SMALL
        z = np.linspace(0.0, float(rng.uniform(0.3, 0.5)), int(rng.integers(20, 45)))
        truth = dict(
            kc=float(rng.uniform(0, 50)),
            kphi=float(rng.uniform(300, 3000)),
            n=float(rng.uniform(0.4, 1.2)),
            cc=float(rng.uniform(0, 10)),
            phic_deg=float(rng.uniform(5, 30)),
        )
        ci = cone_index(z, cone=cone, **truth)
        if noise:
            ci = ci * (1 + noise * rng.standard_normal(ci.size))
        profiles.append(CIProfile(f"{prefix}{i:03d}", z, ci, cone=cone, metadata={"i": i}))
        truths.append(truth)
    return profiles, truths


def mixed_items() -> list:
    """Two cones, noisy and noise-free, a bad profile, a windowed one, a reader error."""
    good, _ = synthetic(6, seed=1)
    noisy, _ = synthetic(4, seed=2, noise=0.03, prefix="noisy")
    bad = CIProfile(
        "bad", good[0].depth, np.where(np.arange(good[0].ci.size) == 4, -3.0, good[0].ci)
    )
    windowed = noisy[1].window(0.05, 0.25)
    windowed.id = "windowed"
    reader = InputError("not a number: 'x'", file="f.csv", profile="R1", row=7, column="ci_kpa")
    return [good[0], bad, *noisy, reader, windowed, *good[1:]]


def fields(r) -> dict:
    """Everything a result reports, numbers as floats (for comparison)."""
    d = r.as_dict("si")
    d.pop("diagnostics")  # time_s is a measurement
    return d


def assert_same(a: dict, b: dict, rtol: float = RTOL, atol: float = ATOL, where: str = "") -> None:
    assert set(a) == set(b), where
    for k, va in a.items():
        vb = b[k]
        if isinstance(va, float) or isinstance(vb, float):
            assert va == pytest.approx(vb, rel=rtol, abs=atol), (where, k)
        elif isinstance(va, list) and va and isinstance(va[0], float):
            np.testing.assert_allclose(va, vb, rtol=rtol, atol=atol, err_msg=f"{where} {k}")
        elif isinstance(va, dict) and k == "profile_intervals":
            assert list(va) == list(vb), (where, k)
            for p in va:
                np.testing.assert_allclose(va[p], vb[p], rtol=rtol, atol=atol, err_msg=p)
        else:
            assert va == vb, (where, k)


def same_fit(a, b) -> None:
    """a and b report the same fit (to RTOL; with the numpy twins, the same optimum value)."""
    if enabled():
        assert_same(fields(a), fields(b), where=a.id)
        return
    assert (a.id, a.status, a.error) == (b.id, b.status, b.error)
    if a.ok:
        scale = float(np.sqrt(np.mean(a.ci**2)))
        assert a.rmsd == pytest.approx(b.rmsd, rel=1e-9, abs=1e-6 * scale), a.id


def test_set_equals_predict_one_by_one():
    items = mixed_items()
    together = predict_many(items)
    assert len(together) == len(items)
    statuses = [r.status for r in together]
    assert statuses.count("error") == 2 and statuses.count("ok") == len(items) - 2
    for it, r in zip(items, together):
        if isinstance(it, InputError):
            assert r.status == "error" and r.error == str(it)
            continue
        alone = predict(it)
        assert r.id == it.id
        same_fit(r, alone)
    by_id = {r.id: r for r in together}
    assert "negative cone index -3" in by_id["bad"].error
    assert by_id["s000"].metadata == {"i": 0}
    w = by_id["windowed"]
    assert w.ok and w.depth.min() >= 0.05 and w.depth.max() <= 0.25
    assert {r.cone for r in together if r.ok} == {"asabe-large", "asabe-small"}


def test_summary_equals_full_where_both_report():
    items = [it for it in mixed_items() if not isinstance(it, InputError)]
    full = predict_many(items, settings=RunSettings(detail="full"))
    summ = predict_many(items, settings=RunSettings(detail="summary"))
    shared = ("kc", "kphi", "n", "cc", "phic_deg", "rmsd", "r2_ci", "longest_run", "lack_of_fit")
    for f, s in zip(full, summ):
        assert f.status == s.status
        if not f.ok:
            assert f.error == s.error
            continue
        df, ds = fields(f), fields(s)
        assert_same({k: df[k] for k in shared}, {k: ds[k] for k in shared}, where=f.id)
        assert f.phic_range == s.phic_range and f.sigma == s.sigma
        for p in ("n", "phic_deg"):
            if p in f.profile_intervals:
                assert s.profile_intervals[p] == f.profile_intervals[p]
        # summary leaves out only the scans of kc, kphi and cc
        assert set(f.profile_intervals) - set(s.profile_intervals) <= {"kc", "kphi", "cc"}
        assert "kphi" in f.profile_intervals and "kphi" not in s.profile_intervals
        assert [t for t in f.undetermined if t not in ("kc", "kphi", "cc")] == s.undetermined


def results_of(pool, chunk_size):
    profiles, _ = synthetic(12, seed=5, noise=0.02)
    return predict_many(profiles, pool=pool, chunk_size=chunk_size)


def test_pools_give_the_same_results():
    ref = results_of(None, 1000)
    with ThreadPool(2) as tp:
        threads = results_of(tp, 5)
    with ProcessPoolExecutor(max_workers=2) as pp:
        procs = results_of(pp, 4)
    plain = results_of(None, 3)
    for other in (threads, procs, plain):
        assert [r.id for r in other] == [r.id for r in ref]
        for a, b in zip(ref, other):
            same_fit(a, b)


def truth_bound(p, t, rss: float) -> dict[str, float]:
    """How far from the truth an answer whose residual norm is ``rss`` can lie, per quantity.

    Noise-free data y = CI(truth): an answer theta with residuals r = CI(theta) - y has, to
    first order, J (theta - truth) = r for the Jacobian J of the forward model at the truth
    in (kc, kphi, cc, n) with phic held at the truth, so by Cauchy-Schwarz any quantity
    g(theta) lies within |r| sqrt(grad g' (J'J)^-1 grad g) of g(truth).  The tolerance of
    each parameter then follows from the objective, not from the path of the search.
    """
    z, cone = p.depth, p.cone
    lin = [cone_index(z, cone=cone, **{**t, "kc": 0.0, "kphi": 0.0, "cc": 0.0, k: 1.0})
           for k in ("kc", "kphi", "cc")]  # fmt: skip
    h = 1e-6
    dn = (cone_index(z, cone=cone, **{**t, "n": t["n"] + h})
          - cone_index(z, cone=cone, **{**t, "n": t["n"] - h})) / (2 * h)  # fmt: skip
    cov = np.linalg.inv(np.column_stack([*lin, dn]).T @ np.column_stack([*lin, dn]))
    grads = {
        "kc": [1, 0, 0, 0],
        "kphi": [0, 1, 0, 0],
        "cc": [0, 0, 1, 0],
        "n": [0, 0, 0, 1],
        "ratio": [1 / t["kphi"], -t["kc"] / t["kphi"] ** 2, 0, 0],
    }
    return {k: rss * float(np.sqrt(np.array(g) @ cov @ np.array(g))) for k, g in grads.items()}


def test_known_truth_recovered():
    """Noise-free forward-model data: the optimum's RMSD is zero up to rounding (the tolerance
    is on the objective, 1e-9 of rms(CI)), and kc, kphi, n, cc and kc/kphi lie as close to the
    truth as that residual allows (:func:`truth_bound`, twice the first-order bound); phic only
    up to the ridge."""
    profiles, truths = synthetic(10, seed=11)
    results = predict_many(profiles)
    for p, r, t in zip(profiles, results, truths):
        assert r.ok, r.error
        q = r.params
        scale = float(np.sqrt(np.mean(p.ci**2)))
        assert r.rmsd < 1e-9 * scale, (p.id, r.rmsd / scale)
        # the residual norm the answer may have: its own, or rounding of CI if larger
        rss = math.sqrt(p.ci.size) * max(r.rmsd, 1e-13 * scale)
        tol = {k: 2 * v for k, v in truth_bound(p, t, rss).items()}
        assert q.n == pytest.approx(t["n"], abs=tol["n"]), p.id
        assert q.kc / q.kphi == pytest.approx(t["kc"] / t["kphi"], abs=tol["ratio"]), p.id
        assert q.cc == pytest.approx(t["cc"], abs=tol["cc"]), p.id
        # fully mobilised shear: phic trades against the scale of kc, kphi (eq. (2-6)) and
        # the true phic lies on the reported ridge, where it gives back the true kc, kphi
        lo, hi = r.phic_range
        assert lo - 1e-6 <= t["phic_deg"] <= hi + 1e-6
        t_a = math.tan(p.cone.half_angle)
        to_truth = (1 + math.tan(math.radians(q.phic_deg)) / t_a) / (
            1 + math.tan(math.radians(t["phic_deg"])) / t_a
        )
        assert q.kphi * to_truth == pytest.approx(t["kphi"], abs=tol["kphi"]), p.id
        assert q.kc * to_truth == pytest.approx(t["kc"], abs=tol["kc"]), p.id
        assert "phic" in r.undetermined
        # and the bounds are tight enough to mean something at this objective
        assert tol["ratio"] < 1e-4 * t["kc"] / t["kphi"] and tol["n"] < 1e-6, p.id
    # with phic held at the truth the scale is fixed and kc, kphi come back themselves
    p, t = profiles[0], truths[0]
    fixed = predict_many(profiles[:1], Problem(bounds=Bounds().fixed(phic_deg=t["phic_deg"])))[0]
    scale = float(np.sqrt(np.mean(p.ci**2)))
    assert fixed.rmsd < 1e-9 * scale
    tol = truth_bound(p, t, math.sqrt(p.ci.size) * max(fixed.rmsd, 1e-13 * scale))
    assert fixed.params.kc == pytest.approx(t["kc"], abs=2 * tol["kc"])
    assert fixed.params.kphi == pytest.approx(t["kphi"], abs=2 * tol["kphi"])
    assert "phic" not in fixed.undetermined


def test_profile_set_input_and_located_errors():
    profiles, _ = synthetic(4, seed=3)
    bad = CIProfile("dup", [0.0, 0.1, 0.1, 0.2], [10.0, 20.0, 30.0, 40.0], rows=np.arange(4) + 2)
    reader = InputError("empty cell", file="in.csv", profile="gone", row=9, column="ci_kpa")
    pset = ProfileSet.from_profiles([*profiles, bad, reader])
    res = predict_many(pset)
    assert [r.id for r in res] == [p.id for p in profiles] + ["dup", "gone"]
    assert all(r.ok for r in res[:4])
    # the set's rows are file lines: the error names the line and the previous depth's line
    assert res[4].error == (
        "profile dup, row 4, column depth: depth is not strictly increasing "
        "(previous depth on row 3)"
    )
    assert res[5].error == str(reader)
    for a, b in zip(res[:4], predict_many(profiles)):
        same_fit(a, b)


def test_a_failing_profile_is_isolated():
    profiles, truths = synthetic(7, seed=4)
    broken = profiles[3].depth

    def flaky(depths, cis, **kw):
        if any(d.size == broken.size and np.array_equal(d, broken) for d in depths):
            raise FloatingPointError("synthetic failure")
        return solve_exact_many(depths, cis, **kw)

    res = predict_many(profiles, settings=RunSettings(solve_many=flaky))
    assert [r.status for r in res] == ["ok"] * 3 + ["error"] + ["ok"] * 3
    assert res[3].error == "profile s003: solver failed: synthetic failure"
    for r, t in zip(res, truths):
        if r.ok:
            assert r.params.n == pytest.approx(t["n"], abs=1e-5)


def test_bad_settings_are_refused():
    profiles, _ = synthetic(1)
    with pytest.raises(ValueError, match="detail must be 'full' or 'summary' \\(got 'all'\\)"):
        predict_many(profiles, settings=RunSettings(detail="all"))
    with pytest.raises(ValueError, match="solver must be 'exact' or 'pso' \\(got 'de'\\)"):
        predict_many(profiles, settings=RunSettings(solver="de"))
    with pytest.raises(ValueError, match="chunk_size must be >= 1 \\(got 0\\)"):
        predict_many(profiles, chunk_size=0)


# ---------------------------------------------------------------------------
# the linear algebra of the polish, against numpy and scipy
# ---------------------------------------------------------------------------


def test_mgs_lstsq_equals_numpy_lstsq():
    rng = np.random.default_rng(0)
    P, Z, k = 50, 30, 3
    A = rng.standard_normal((P, Z, k)) * np.array([1.0, 100.0, 0.01])  # column scales differ
    b = rng.standard_normal((P, Z))
    x, full = mgs_lstsq([A[..., i] for i in range(k)], b)
    assert full.all()
    for p in range(P):
        ref = np.linalg.lstsq(A[p], b[p], rcond=None)[0]
        np.testing.assert_allclose(x[p], ref, rtol=1e-10)
    # a rank-deficient problem is reported, not solved
    A[0, :, 2] = 2.0 * A[0, :, 0]
    x, full = mgs_lstsq([A[..., i] for i in range(k)], b)
    assert not full[0] and full[1:].all()


def test_polish_many_reaches_the_box_optimum():
    """Against scipy's BVLS on random boxed problems: never a higher sum of squares."""
    rng = np.random.default_rng(1)
    P, Z = 40, 25
    X = np.abs(rng.standard_normal((P, Z, 3)))
    y = rng.standard_normal((P, Z)) + 2.0
    lo = np.zeros((P, 3))
    hi = np.full((P, 3), 0.8)
    x0 = np.clip(rng.uniform(-0.2, 1.0, (P, 3)), lo, hi)  # a rough start in the box
    x = polish_many(X, y, lo, hi, x0)
    assert np.all(x >= lo) and np.all(x <= hi)
    for p in range(P):
        ref = lsq_linear(X[p], y[p], bounds=(lo[p], hi[p]), method="bvls", tol=1e-15).x
        sse = float(np.sum((X[p] @ x[p] - y[p]) ** 2))
        sse_ref = float(np.sum((X[p] @ ref - y[p]) ** 2))
        assert sse <= sse_ref * (1 + 1e-10)
        np.testing.assert_allclose(x[p], ref, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("seed", [1, 2])
def test_polish_compiled_equals_its_numpy_twin(seed):
    """polish_kernel (compiled) against polish_many_numpy to 1e-12, on starts at the box's
    faces, inside and at its corners, with padded rows and a fixed variable."""
    import importlib

    from terracone.jit import enabled

    pol = importlib.import_module("terracone.inverse.solver.polish")
    if not enabled():
        pytest.skip("kernels switched off (TERRACONE_NUMBA=0): nothing compiled to compare")
    rng = np.random.default_rng(seed)
    P, Z = 60, 30
    X = np.abs(rng.standard_normal((P, Z, 3)))
    y = rng.standard_normal((P, Z)) + 2.0
    X[::3, 20:] = 0.0  # padded rows
    y[::3, 20:] = 0.0
    lo = np.zeros((P, 3))
    hi = np.full((P, 3), 0.8)
    hi[::5, 2] = 0.0  # cc fixed at 0
    x0 = np.clip(rng.uniform(-0.3, 1.1, (P, 3)), lo, hi)
    # the starts polish meets: the box optimum where BVLS finds it, rounded a little
    for p in range(0, P, 2):
        free = hi[p] > lo[p]
        ref = lsq_linear(X[p][:, free], y[p], bounds=(lo[p, free], hi[p, free]), method="bvls").x
        x0[p, free] = np.clip(ref * (1 + 1e-7), lo[p, free], hi[p, free])
    a = pol.polish_many(X, y, lo, hi, x0)
    b = pol.polish_many_numpy(X, y, lo, hi, x0)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    assert not np.array_equal(a, x0)  # it did polish


def test_one_problem_and_one_run_settings_object():
    # what is fitted is one Problem, how it runs one RunSettings; a typo is refused
    import dataclasses

    from terracone.inverse.problem import Calibration

    with pytest.raises(TypeError, match="unexpected keyword argument 'modle'"):
        Problem(modle="rm1")
    with pytest.raises(TypeError, match="unexpected keyword argument 'slover'"):
        RunSettings(slover="pso")
    profiles, _ = synthetic(1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'model'"):
        predict_many(profiles, model="rm1")  # the keyword options are gone
    with pytest.raises(ValueError, match="r_min is required with model 'rm1'"):
        Problem(model="rm1")
    with pytest.raises(ValueError, match="model must be 'rm0' or 'rm1' \\(got 'rm2'\\)"):
        Problem(model="rm2")
    with pytest.raises(ValueError, match="prior 'calibration' needs a calibration"):
        Problem(prior="calibration")
    with pytest.raises(dataclasses.FrozenInstanceError):
        Problem().model = "rm1"
    with pytest.raises(dataclasses.FrozenInstanceError):
        RunSettings().solver = "pso"
    # a calibration is applied once, by the problem: its model, r_min, plates, phic, cc, ratio
    cal = Calibration("t", "rm1", 0.03, (0.05, 0.1), 12.0, 2.0, 20.0, 1000.0, 0.8)
    pb = Problem(calibration=cal, prior="calibration")
    assert (pb.model, pb.r_min, pb.plate_pair) == ("rm1", 0.03, (0.05, 0.1))
    assert pb.fit_bounds.phic_deg == (12.0, 12.0) and pb.fit_bounds.cc == (2.0, 2.0)
    assert pb.bounds == Bounds() and pb.ratio == pytest.approx(20.0 / 1000.0)
    assert pb.centre is None and pb.law.r_min == 0.03 and pb.calibrated
    assert pb.held() == {"phic_deg": 12.0, "cc": 2.0, "kc_over_kphi": pytest.approx(0.02)}
    assert pb.prior_label() == "calibration:t"
    # the same calibration given as the prior: the point fit held at its values, the
    # posterior around them (nothing held in the draws)
    pc = Problem(prior=cal)
    assert pc.centre is not None and pc.centre.calibration is cal and pc.calibration is None
    assert pc.fit_bounds == pb.fit_bounds and pc.ratio == pb.ratio and pc.held() == {}
    assert (pc.model, pc.r_min, pc.plate_pair) == ("rm1", 0.03, (0.05, 0.1))
    other = Calibration("u", "rm1", 0.03, (0.05, 0.1), 13.0, 2.0, 20.0, 1000.0, 0.8)
    with pytest.raises(ValueError, match="give the calibration once"):
        Problem(calibration=cal, prior=other)
    # the calibration held with either prior, or given as the prior, fits alike
    a = predict_many(profiles, pb)[0]
    b = predict_many(profiles, Problem(calibration=cal))[0]
    c = predict_many(profiles, pc)[0]
    assert a.params == b.params and a.notes == b.notes
    assert c.params == a.params
    assert a.params.phic_deg == 12.0 and a.params.cc == 2.0
    assert a.params.kc == pytest.approx(0.02 * a.params.kphi, rel=1e-12)

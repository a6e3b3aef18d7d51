"""The particle swarm of the paper's processes (terracone.inverse.solver.pso).

References are closed forms: the minimiser of a shifted sphere and of
Rosenbrock's function, the corner minimiser of a linear function on a box,
and the stopping rule re-derived from the returned history.
"""

from __future__ import annotations

import numpy as np
import pytest

from terracone.inverse.solver.pso import PSOResult, pso


def sphere(center):
    center = np.asarray(center, float)

    def f(x):
        return np.sum((x - center) ** 2, axis=1)

    return f


def rosenbrock(x):
    return (1.0 - x[:, 0]) ** 2 + 100.0 * (x[:, 1] - x[:, 0] ** 2) ** 2


class Recorder:
    """Objective wrapper that keeps every position evaluated."""

    def __init__(self, f):
        self.f = f
        self.calls: list[np.ndarray] = []

    def __call__(self, x):
        self.calls.append(np.array(x, copy=True))
        return self.f(x)

    @property
    def positions(self) -> np.ndarray:
        return np.concatenate(self.calls, axis=0)


LO4 = np.array([-3.0, -3.0, -3.0, -3.0])
HI4 = np.array([3.0, 3.0, 3.0, 3.0])
C4 = np.array([0.3, -1.2, 2.5, 0.0])


def test_same_seed_same_answer_bit_for_bit():
    a = pso(rosenbrock, [-2, -2], [2, 2], seed=123, max_iter=150)
    b = pso(rosenbrock, [-2, -2], [2, 2], seed=123, max_iter=150)
    assert isinstance(a, PSOResult)
    assert np.array_equal(a.x, b.x)
    assert a.fun == b.fun
    assert np.array_equal(a.history, b.history)
    assert (a.nit, a.nfev, a.converged, a.message) == (b.nit, b.nfev, b.converged, b.message)
    # an int seed and a Generator built from it are the same stream
    c = pso(rosenbrock, [-2, -2], [2, 2], seed=np.random.default_rng(123), max_iter=150)
    assert np.array_equal(a.x, c.x)
    assert np.array_equal(a.history, c.history)


def test_same_seed_same_positions_evaluated():
    r1, r2 = Recorder(sphere(C4)), Recorder(sphere(C4))
    pso(r1, LO4, HI4, seed=5, max_iter=40)
    pso(r2, LO4, HI4, seed=5, max_iter=40)
    assert np.array_equal(r1.positions, r2.positions)


def test_different_seeds_differ():
    a = pso(rosenbrock, [-2, -2], [2, 2], seed=1, max_iter=60)
    b = pso(rosenbrock, [-2, -2], [2, 2], seed=2, max_iter=60)
    assert not np.array_equal(a.history, b.history)
    assert not np.array_equal(a.x, b.x)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_minimises_shifted_sphere(seed):
    res = pso(sphere(C4), LO4, HI4, seed=seed)
    np.testing.assert_allclose(res.x, C4, atol=1e-6)
    assert res.fun < 1e-10
    assert res.fun == pytest.approx(float(sphere(C4)(res.x[None])[0]), abs=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_minimises_rosenbrock(seed):
    res = pso(rosenbrock, [-2.0, -2.0], [2.0, 2.0], seed=seed, max_iter=2000)
    np.testing.assert_allclose(res.x, [1.0, 1.0], atol=1e-3)
    assert res.fun < 1e-6


def test_result_consistency():
    rec = Recorder(sphere(C4))
    res = pso(rec, LO4, HI4, seed=9, n_particles=20, max_iter=50)
    # fun is the objective at x; history is the best value so far
    assert res.fun == float(sphere(C4)(res.x[None])[0])
    assert res.history[-1] == res.fun
    assert np.all(np.diff(res.history) <= 0)
    assert res.history.size == res.nit + 1
    # one call for the initial swarm and one per iteration, each of the whole swarm
    assert len(rec.calls) == res.nit + 1
    assert all(c.shape == (20, 4) for c in rec.calls)
    assert res.nfev == 20 * (res.nit + 1) == rec.positions.shape[0]
    # the best value is the minimum over everything evaluated
    assert res.fun == float(sphere(C4)(rec.positions).min())
    assert res.time_s >= 0


def test_respects_bounds_when_the_minimum_is_outside():
    lo = np.array([-1.0, 0.5, 2.0])
    hi = np.array([1.0, 4.0, 2.5])
    rec = Recorder(lambda x: x.sum(axis=1))  # minimum at the lower corner
    res = pso(rec, lo, hi, seed=3)
    X = rec.positions
    assert np.all(X >= lo) and np.all(X <= hi)
    np.testing.assert_allclose(res.x, lo, atol=1e-6 * (hi - lo).max())


def test_respects_bounds_minimum_beyond_upper_corner():
    lo = np.array([0.0, 0.0])
    hi = np.array([1.0, 2.0])
    rec = Recorder(sphere([5.0, -7.0]))  # nearest feasible point (1, 0)
    res = pso(rec, lo, hi, seed=4)
    X = rec.positions
    assert np.all(X >= lo) and np.all(X <= hi)
    np.testing.assert_allclose(res.x, [1.0, 0.0], atol=1e-6)


def test_fixed_dimension_stays_fixed():
    lo = np.array([-3.0, 0.75, -3.0])
    hi = np.array([3.0, 0.75, 3.0])
    rec = Recorder(sphere([1.0, 0.0, -2.0]))
    res = pso(rec, lo, hi, seed=11)
    X = rec.positions
    assert np.all(X[:, 1] == 0.75)
    assert res.x[1] == 0.75
    # the relative stopping rule (tol 1e-8 of f ~ 0.56) limits the accuracy
    np.testing.assert_allclose(res.x[[0, 2]], [1.0, -2.0], atol=1e-3)
    assert res.fun == pytest.approx(0.75**2, rel=1e-7)


def _check_stopping_rule(res: PSOResult, tol: float, window: int) -> int:
    """Re-derive the rule from the history: stop at the first iteration k >= window
    with history[k - window] - history[k] <= tol * |history[k - window]|.
    Returns the number of iterations checked for not stopping early."""
    h = res.history
    checked = 0
    for k in range(window, res.nit):
        old = h[k - window]
        assert old - h[k] > tol * max(abs(old), 1e-300), f"should have stopped at {k}"
        checked += 1
    if res.converged:
        old = h[res.nit - window]
        assert res.nit >= window
        assert old - h[res.nit] <= tol * max(abs(old), 1e-300)
    return checked


def test_stopping_rule_on_a_flat_function():
    rec = Recorder(lambda x: np.full(x.shape[0], 3.0))
    res = pso(rec, [0.0, 0.0], [1.0, 1.0], seed=0, n_particles=10, window=7, max_iter=100)
    assert res.converged
    assert res.nit == 7
    assert res.history.size == 8
    assert res.nfev == 10 * 8 == rec.positions.shape[0]
    assert "7 iterations" in res.message
    _check_stopping_rule(res, 1e-8, 7)


@pytest.mark.parametrize("window", [5, 30])
@pytest.mark.parametrize("tol", [1e-3, 1e-8])
def test_stopping_rule_matches_history(window, tol):
    res = pso(rosenbrock, [-2.0, -2.0], [2.0, 2.0], seed=7, tol=tol, window=window, max_iter=3000)
    assert res.converged
    assert res.nit < 3000
    _check_stopping_rule(res, tol, window)


def improving_by_construction():
    """An objective whose value is 1/(call number) for every particle: the best
    value improves at every iteration, whatever the swarm does."""
    calls = []

    def f(x):
        calls.append(1)
        return np.full(x.shape[0], 1.0 / len(calls))

    return f


def test_max_iter_reached_is_not_converged():
    # with tol=0 the rule can never fire on a strictly improving history, so the
    # swarm runs to max_iter, and every window from 5 to 24 is checked
    res = pso(improving_by_construction(), LO4, HI4, seed=0, tol=0.0, window=5, max_iter=25)
    assert not res.converged
    assert res.nit == 25
    assert res.history.size == 26
    np.testing.assert_array_equal(res.history, 1.0 / np.arange(1, 27))
    assert "maximum number of iterations" in res.message
    assert _check_stopping_rule(res, 0.0, 5) == 20
    # a tolerance above its relative gain over a window (1 - 1/6) stops at the window
    res = pso(improving_by_construction(), LO4, HI4, seed=0, tol=0.9, window=5, max_iter=25)
    assert res.converged and res.nit == 5
    assert _check_stopping_rule(res, 0.9, 5) == 0


def test_init_positions_seed_the_swarm():
    best = np.array([[0.3, -1.2, 2.5, 0.0]])
    res = pso(sphere(C4), LO4, HI4, seed=0, init=best, max_iter=3)
    assert res.history[0] == 0.0
    assert res.fun == 0.0
    np.testing.assert_array_equal(res.x, C4)


def test_nonfinite_objective_values_are_ignored():
    def f(x):
        v = np.sum((x - 0.5) ** 2, axis=1)
        return np.where(x[:, 0] < 0.0, np.nan, v)  # NaN on half the box

    res = pso(f, [-1.0, -1.0], [1.0, 1.0], seed=2)
    assert np.isfinite(res.fun)
    np.testing.assert_allclose(res.x, [0.5, 0.5], atol=1e-6)

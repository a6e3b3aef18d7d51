"""Particle swarm optimisation, the search of the paper's processes.

A global-best swarm (Kennedy and Eberhart [2]_) with the constriction
coefficients of Clerc and Kennedy [3]_ and a stopping rule on the improvement
of the best value, as in section 3.3 of [1]_; settings: ``docs/predict.md``
(Solvers).  Vectorised over the swarm; the same seed gives the same answer.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 3.1 and 3.3.
.. [2] Kennedy, J., Eberhart, R. (1995). Particle swarm optimization.
   Proc. IEEE ICNN, 1942-1948.
.. [3] Clerc, M., Kennedy, J. (2002). The particle swarm - explosion,
   stability, and convergence in a multidimensional complex space. IEEE
   Trans. Evol. Comput. 6(1), 58-73.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PSOResult", "pso"]


@dataclass
class PSOResult:
    """Outcome of :func:`pso`.

    Attributes
    ----------
    x : ndarray
        Best position found.
    fun : float
        Objective at ``x``.
    nit : int
        Iterations run.
    nfev : int
        Objective evaluations (particles x iterations).
    converged : bool
        True when the stopping rule fired before ``max_iter``.
    message : str
    history : ndarray
        Best objective after each iteration.
    time_s : float
    """

    x: np.ndarray
    fun: float
    nit: int
    nfev: int
    converged: bool
    message: str
    history: np.ndarray = field(repr=False)
    time_s: float = 0.0


def pso(
    fun: Callable[[np.ndarray], np.ndarray],
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    n_particles: int = 64,
    max_iter: int = 300,
    inertia: float = 0.7298,
    cognitive: float = 1.49618,
    social: float = 1.49618,
    vmax_fraction: float = 0.5,
    tol: float = 1e-8,
    window: int = 30,
    seed: int | np.random.Generator | None = None,
    init: np.ndarray | None = None,
) -> PSOResult:
    """Minimise ``fun`` over the box [lower, upper] with a particle swarm.

    Parameters
    ----------
    fun : callable
        Maps positions (P, D) to objective values (P,).
    lower, upper : (D,) array_like
        Bounds; a dimension with lower == upper is held fixed.
    n_particles, max_iter : int
    inertia, cognitive, social : float
        Velocity update v = w v + c1 r1 (pbest - x) + c2 r2 (gbest - x).
    vmax_fraction : float
        Velocity clamp as a fraction of each dimension's range.
    tol, window : float, int
        Stop when the best value improved by less than ``tol`` (relative)
        over the last ``window`` iterations.
    seed : int or Generator
    init : (k, D) array_like, optional
        Positions to seed the swarm with (the rest are uniform).
    """
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    span = hi - lo
    D = lo.size
    x = lo + rng.random((n_particles, D)) * span
    if init is not None:
        init = np.clip(np.atleast_2d(np.asarray(init, float)), lo, hi)
        x[: init.shape[0]] = init[:n_particles]
    vmax = vmax_fraction * span
    v = (rng.random((n_particles, D)) * 2 - 1) * vmax * 0.1
    f = np.asarray(fun(x), dtype=float)
    f = np.where(np.isfinite(f), f, np.inf)
    pbest, pbest_f = x.copy(), f.copy()
    g = int(np.argmin(pbest_f))
    gbest, gbest_f = pbest[g].copy(), float(pbest_f[g])
    history = [gbest_f]
    nfev = n_particles
    converged = False
    message = "maximum number of iterations reached"
    it = 0
    for it in range(1, max_iter + 1):
        r1 = rng.random((n_particles, D))
        r2 = rng.random((n_particles, D))
        v = inertia * v + cognitive * r1 * (pbest - x) + social * r2 * (gbest - x)
        v = np.clip(v, -vmax, vmax)
        x = x + v
        # reflect at the bounds, and damp the reflected velocity component
        below, above = x < lo, x > hi
        x = np.where(below, 2 * lo - x, x)
        x = np.where(above, 2 * hi - x, x)
        v = np.where(below | above, -0.5 * v, v)
        x = np.clip(x, lo, hi)
        f = np.asarray(fun(x), dtype=float)
        f = np.where(np.isfinite(f), f, np.inf)
        nfev += n_particles
        better = f < pbest_f
        pbest[better] = x[better]
        pbest_f[better] = f[better]
        g = int(np.argmin(pbest_f))
        if pbest_f[g] < gbest_f:
            gbest, gbest_f = pbest[g].copy(), float(pbest_f[g])
        history.append(gbest_f)
        if it >= window:
            old = history[-window - 1]
            if old - gbest_f <= tol * max(abs(old), 1e-300):
                converged = True
                message = (
                    f"best value improved by less than {tol:g} (relative) over {window} iterations"
                )
                break
    return PSOResult(
        x=gbest,
        fun=gbest_f,
        nit=it,
        nfev=nfev,
        converged=converged,
        message=message,
        history=np.asarray(history),
        time_s=time.perf_counter() - t0,
    )

"""Posterior of a layered fit (:func:`layered_posterior`): calibrated intervals of every layer.

The parameters are each layer's kc, kphi, n, cc and the interface depths;
phic is held at the fit's value (it trades exactly with the scale of each
layer's kc and kphi, eq. (2-6)).  Priors: uniform over the bounds of each
layer's kc, kphi (at its n), n and cc, and over the fit's search space of
the interfaces (ordered, the first and last at least the minimum thickness
from the ends of the profile, neighbours half of it apart).  Residuals are
independent Gaussian with an unknown sigma (1/sigma prior).  The chains are
those of :mod:`terracone.inverse.layered.sampler` (compiled): random-walk
moves of the interfaces and n's that carry the linear parameters along with
their conditional optimum and spread, jumps of an interface across its
range, exact Gibbs draws of the linear parameters and of sigma.

Calibration is checked in ``tests/test_layered_uncertainty.py``: over 200
profiles generated from the prior with known truth, the 90% intervals of
each interface and each n cover the truth within a binomial window around
90%.  An interface or n whose posterior is nearly as wide as its prior is
labelled "set by prior" (a weak contrast) and listed in ``undetermined``.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
.. [2] Haario, H., Saksman, E., Tamminen, J. (2001). An adaptive Metropolis
   algorithm. Bernoulli 7(2), 223-242.
.. [3] Robert, C.P. (1995). Simulation of truncated normal variables.
   Statistics and Computing 5, 121-125.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from terracone.data import CIProfile
from terracone.inverse.bounds import Bounds
from terracone.inverse.layered.fit import LayeredResult, bin_profile, max_depths, phic_scale
from terracone.inverse.problem import Problem
from terracone.inverse.solver.layered_numpy import design_matrix, fold_ratio, layer_box
from terracone.inverse.solver.many import bounds_params
from terracone.jit import enabled
from terracone.physics import units as u
from terracone.result import PosteriorSummary

__all__ = ["LayeredPosterior", "layered_posterior", "prior_draws"]


@dataclass(kw_only=True)
class LayeredPosterior(PosteriorSummary):
    """Posterior of a layered fit: per layer kc, kphi, n, cc, and the interfaces (SI).

    A :class:`~terracone.result.PosteriorSummary` whose ``names`` are
    ``kc_1, kphi_1, n_1, cc_1, kc_2, ..., interface_1, ...`` (``samples``
    (draws, len(names)), ``intervals`` and ``medians`` at ``level``,
    ``identifiability`` from the posterior/prior width ratio as the one-layer
    posterior labels it, ``notes``), with the run's details.

    Attributes
    ----------
    phic_deg : float
        The common phic held at the fit's value (labelled "set by prior").
    acceptance : float
        Mean acceptance of the random-walk moves of the interfaces and n's.
    rhat : dict
        Gelman-Rubin statistic of each interface and n over the chains.
    undetermined : list of str
        Interfaces and n's "set by prior": the data leave them free (a weak contrast).
    time_s : float
    """

    phic_deg: float
    acceptance: float
    rhat: dict[str, float] = field(default_factory=dict)
    undetermined: list[str] = field(default_factory=list)
    time_s: float = 0.0

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``posterior`` block of a profile's ``layered`` fit in predict JSON (``units``)."""
        from terracone.inverse.uncertainty.posterior import LABELS  # emcee: only when sampled

        units = u.check_system(units)
        q = self.quantiles(units)
        labels = dict(self.identifiability)
        labels["phic_deg"] = LABELS[2]
        return {
            "intervals": {k: [v[0], v[2]] for k, v in q.items()},
            "medians": {k: v[1] for k, v in q.items()},
            "identifiability": labels,
            "undetermined": list(self.undetermined),
            "phic_deg": self.phic_deg,
            "acceptance": self.acceptance,
            "rhat": dict(self.rhat),
            "level": self.level,
            "notes": list(self.notes),
            "units": units,
        }


def _space(z: np.ndarray, bounds: Bounds, min_thickness: float | None):
    """(lo_d, hi_d, gap, n_lo, n_hi): the search space of the interfaces and n's (as the fit)."""
    step = float(np.median(np.diff(z)))
    mt = min_thickness if min_thickness is not None else 2 * step
    return (float(z[0] + mt), float(z[-1] - mt), 0.5 * mt, float(bounds.n[0]), float(bounds.n[1]))


def prior_draws(L: int, space: tuple, draws: int, rng: np.random.Generator) -> np.ndarray:
    """Draws (draws, L-1) of the interfaces from their prior: uniform, ordered, gap apart."""
    lo_d, hi_d, gap = space[:3]
    out = np.empty((0, L - 1))
    while out.shape[0] < draws:
        d = np.sort(rng.uniform(lo_d, hi_d, (4 * draws, L - 1)), axis=1)
        ok = np.all(np.diff(d, axis=1) >= gap, axis=1)
        out = np.concatenate([out, d[ok]])
    return out[:draws]


def _directions(z, p, L, s, law, cone, bounds, ratio) -> np.ndarray:
    """Gibbs directions of x: the principal axes of the scaled normal equations at p (over the
    variables whose box is open) and the coordinate axes."""
    X = fold_ratio(design_matrix(z, p[: L - 1], p[L - 1 :], s, law, cone), ratio)
    lo, hi = layer_box(bounds, p[L - 1 :], ratio)
    k = X.shape[1]
    free = (hi > lo) & (np.sum(X * X, axis=0) > 0)
    dirs = [np.eye(k)[i] for i in range(k) if free[i]]
    if free.sum() > 1:
        Xf = X[:, free]
        d = np.sqrt(np.sum(Xf * Xf, axis=0))
        _, V = np.linalg.eigh((Xf / d).T @ (Xf / d))
        for j in range(V.shape[1]):
            v = np.zeros(k)
            v[free] = V[:, j] / d
            dirs.append(v / np.linalg.norm(v))
    return np.ascontiguousarray(np.array(dirs).reshape(-1, k))


def _run(z, y, p0, s, bp, geom, space, dirs, step, iters, burn, thin, seed, moves):
    from terracone.inverse.layered import sampler

    args = (z, y, p0, s, bp, geom, np.array(space), dirs, step, iters, burn, thin, seed, moves)
    if enabled():
        return sampler.run_chains(*args)
    state = np.random.get_state()  # plain Python: numba's seed would set numpy's global one
    try:
        return sampler.run_chains(*args)
    finally:
        np.random.set_state(state)


def _rhat(chains: np.ndarray) -> np.ndarray:
    """Split-chain Gelman-Rubin statistic per column of chains (C, K, P)."""
    C, K, P = chains.shape
    h = K // 2
    if h < 2:
        return np.full(P, np.nan)
    parts = np.concatenate([chains[:, :h], chains[:, h : 2 * h]], axis=0)
    W = parts.var(axis=1, ddof=1).mean(axis=0)
    B = h * parts.mean(axis=1).var(axis=0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(((h - 1) / h * W + B / h) / W)
    return np.where(W > 0, r, 1.0)


def layered_posterior(
    profile: CIProfile,
    fit: LayeredResult,
    problem: Problem | None = None,
    *,
    draws: int = 2000,
    seed: int | None = None,
    nwalkers: int = 4,
    burn: int = 1000,
    thin: int = 8,
    level: float = 0.9,
    min_thickness: float | None = None,
    phic_deg: float | None = None,
    moves: int = 6,
) -> LayeredPosterior:
    """Posterior of a layered fit (:func:`~terracone.inverse.layered.fit_layered`).

    Parameters
    ----------
    profile : CIProfile
        The profile ``fit`` was fitted to.
    fit : LayeredResult
        An ``ok`` layered fit under ``problem``; the chains start around it.  A
        profile longer than the fit searches
        (:func:`~terracone.inverse.layered.fit.max_depths`) is sampled on the
        same bins as the fit (the fit's ``notes`` say so).
    problem : Problem, optional
        What was fitted: the pressure law and the bounds (the support of the
        prior) with the values a calibration holds, held in every draw.
    draws : int
        Posterior draws returned (over all chains).
    seed : int, optional
        The same seed gives the same draws.
    nwalkers : int
        Chains run side by side.
    burn, thin : int
        Iterations per chain discarded (while the random walk adapts), and
        kept every ``thin``-th after.
    level : float
        Credibility of the intervals.
    min_thickness : float, optional
        As :func:`~terracone.inverse.layered.fit_layered` (the prior's support
        of the interfaces); default two depth steps.
    phic_deg : float, optional
        The common phic held [deg]; default the fit's (the middle of its
        equally good interval).
    moves : int
        Moves of the interfaces and n's per iteration: random-walk steps
        (joint, and of one coordinate at a time) and a jump of an interface
        across its range; each iteration also draws the linear parameters
        and sigma once.

    Returns
    -------
    LayeredPosterior

    Raises
    ------
    ValueError
        A fit that is not ``ok``.
    """
    if not fit.ok:
        raise ValueError(f"profile {fit.id}: no layered fit to sample ({fit.error})")
    t0 = time.perf_counter()
    problem = problem or Problem()
    problem.require_single("layered_posterior")
    bounds, law = problem.fit_bounds, problem.law
    L = len(fit.layers)
    profile, _ = bin_profile(profile, max_depths(L))  # the depths the fit searched (its notes)
    z, y, cone = profile.depth, profile.ci, profile.cone
    phic = float(fit.layers[0].phic_deg if phic_deg is None else phic_deg)
    s = float(phic_scale(phic, cone))
    space = _space(z, bounds, min_thickness)
    p_fit = np.array([*fit.interfaces, *(q.n for q in fit.layers)], float)
    rng = np.random.default_rng(seed)
    C = max(int(nwalkers), 2)
    step = np.array([0.1 * (space[1] - space[0]) / max(L - 1, 1)] * (L - 1) + [0.05] * L)
    jit = np.concatenate([np.full(L - 1, 0.02 * step[0] if L > 1 else 0.0), np.full(L, 0.01)])
    p0 = p_fit + jit * rng.standard_normal((C, p_fit.size))
    p0[:, : L - 1] = np.sort(np.clip(p0[:, : L - 1], space[0], space[1]), axis=1)
    p0[:, L - 1 :] = np.clip(p0[:, L - 1 :], space[3], space[4])
    ok = np.all(np.diff(p0[:, : L - 1], axis=1) >= space[2], axis=1)
    p0[~ok] = np.clip(
        p_fit, [space[0]] * (L - 1) + [space[3]] * L, [space[1]] * (L - 1) + [space[4]] * L
    )
    coef = [float(np.asarray(c)) for c in law.coefficients()]
    geom = (cone.height, cone.radius, not law.is_rm0, coef[0], coef[1], coef[2])
    dirs = _directions(z, p_fit, L, s, law, cone, bounds, problem.ratio)
    iters = burn + int(math.ceil(draws / C)) * thin
    out, acc = _run(z, y, np.ascontiguousarray(p0), s, bounds_params(bounds, problem.ratio), geom,
                    space, dirs, step, iters, burn, thin, int(rng.integers(2**31 - 1)),
                    moves)  # fmt: skip
    if problem.ratio is not None:  # kc = ratio kphi in every draw (folded in the sampler)
        kc_cols = 2 * L - 1 + 3 * np.arange(L)
        out[..., kc_cols] = problem.ratio * out[..., kc_cols + 1]
    post = _summary(out, acc, L, space, bounds, phic, level, draws, rng, t0, problem.ratio)
    post.notes = list(fit.notes)
    return post


def _summary(out, acc, L, space, bounds, phic, level, draws, rng, t0, ratio) -> LayeredPosterior:
    """The :class:`LayeredPosterior` of the chains' draws out (C, K, 2L-1 + 3L + 1)."""
    # the one-layer posterior's labels (its module imports emcee: not for a fit without one)
    from terracone.inverse.uncertainty.posterior import LABELS, identifiability_label

    P = 2 * L - 1
    names, cols = [], []
    for j in range(L):
        names += [f"kc_{j + 1}", f"kphi_{j + 1}", f"n_{j + 1}", f"cc_{j + 1}"]
        cols += [P + 3 * j, P + 3 * j + 1, L - 1 + j, P + 3 * j + 2]
    names += [f"interface_{i + 1}" for i in range(L - 1)]
    cols += list(range(L - 1))
    flat = out.reshape(-1, out.shape[-1])
    samples = flat[:, cols][-draws:]
    q = [(1 - level) / 2, 0.5, (1 + level) / 2]
    lo_q, med, hi_q = np.quantile(samples, q, axis=0)
    # prior widths: the box at the median n (kc, kphi, cc), the bounds of n, the interfaces' prior
    prior_iv = _prior_widths(L, space, bounds, med, names, q, rng, ratio)
    intervals = {nm: (float(lo_q[k]), float(hi_q[k])) for k, nm in enumerate(names)}
    medians = {nm: float(med[k]) for k, nm in enumerate(names)}
    labels = {}
    for k, nm in enumerate(names):
        w = prior_iv[nm]
        labels[nm] = identifiability_label((hi_q[k] - lo_q[k]) / w if w > 0 else math.inf)
    rh = _rhat(out[:, :, :P])
    rhat = {nm: float(rh[c]) for nm, c in zip(names, cols) if c < P}
    und = [nm for nm in names if nm.startswith(("interface_", "n_")) and labels[nm] == LABELS[2]]
    return LayeredPosterior(
        names=tuple(names), samples=samples, intervals=intervals, medians=medians,
        identifiability=labels, phic_deg=phic, acceptance=float(np.mean(acc)), rhat=rhat,
        undetermined=und, level=level, time_s=time.perf_counter() - t0,
    )  # fmt: skip


def _prior_widths(L, space, bounds, med, names, q, rng, ratio) -> dict[str, float]:
    """Width of each parameter's prior interval at the same level (interfaces from draws); with
    a held ratio kphi's box where ratio kphi is in kc's, and kc's width ratio times kphi's."""
    frac = q[2] - q[0]
    out = {}
    Dp = prior_draws(L, space, 4000, rng) if L > 1 else np.zeros((0, 0))
    for nm in names:
        kind, j = nm.rsplit("_", 1)
        j = int(j) - 1
        if kind == "interface":
            a, b = np.quantile(Dp[:, j], [q[0], q[2]])
            out[nm] = float(b - a)
        elif kind == "n":
            out[nm] = frac * (bounds.n[1] - bounds.n[0])
        elif kind == "cc":
            out[nm] = frac * (bounds.cc[1] - bounds.cc[0])
        else:
            n = med[names.index(f"n_{j + 1}")]
            lo, hi = layer_box(bounds, np.array([n]), ratio)
            w = float(hi[1] - lo[1]) if kind == "kphi" or ratio is not None else 0.0
            w = (ratio * w if ratio is not None else float(hi[0] - lo[0])) if kind == "kc" else w
            out[nm] = frac * w
    return out

"""The posterior's sampler: emcee's ensemble sampler over the sampling coordinates.

emcee [2]_ with differential-evolution (80%) and stretch [3]_ (20%) moves,
vectorised over a half-ensemble.  With fully mobilised shear the sampler
moves in ``(s kc, s kphi, n, cc, phic)``, ``s = 1 + tan(phic)/tan(15 deg)``,
where the exact phic ridge of [1]_ is a coordinate direction (the Jacobian
``s^-2`` is part of the target).  128 walkers start from a Laplace
approximation around the exact optimum; 80 burn-in steps, thinning by 6.
Settings and their cost: ``docs/uncertainty.md`` (The sampler).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 2 (the phic ridge, eqs. (2-6), (2-7)).
.. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013). emcee:
   the MCMC hammer. PASP 125, 306-312.
.. [3] Goodman, J., Weare, J. (2010). Ensemble samplers with affine
   invariance. Comm. App. Math. Comp. Sci. 5(1), 65-80.
"""

from __future__ import annotations

import math

import emcee
import numpy as np

from terracone.inverse.uncertainty.likelihood import Likelihood
from terracone.inverse.uncertainty.noise import RHO_MAX
from terracone.inverse.uncertainty.priors import PARAM_NAMES, Prior
from terracone.physics.cone import Cone

__all__ = [
    "LogPosterior",
    "SamplerCoordinates",
    "chain_diagnostics",
    "integrated_time",
    "run_chain",
    "start_walkers",
]


class SamplerCoordinates:
    """Map between sampler coordinates x (free subset) and parameters (SI).

    Scaled coordinates (fully mobilised shear, phic free): x = (s kc, s kphi,
    n, cc, phic), s = 1 + tan(phic)/tan(half angle); plain (kc, kphi, n, cc,
    phic) otherwise (docs/uncertainty.md, Coordinates).
    """

    def __init__(self, prior: Prior, cone: Cone, K_cone: float | None, fixed_values: np.ndarray):
        self.prior = prior
        self.t = math.tan(cone.half_angle)
        nb = np.array(prior.b.n, dtype=float)
        fixed = (prior.kc_fixed, prior.kphi_fixed, prior.n_fixed, prior.cc_fixed, prior.phic_fixed)
        # a kc or kphi held at a non-zero value breaks the exact phic ridge; kc = ratio kphi does not
        held = [fixed[0] and prior.held_ratio is None, fixed[1]]
        nonzero = [held[j] and not np.all(prior.fixed_value(j, nb) == 0) for j in (0, 1)]
        self.scaled = K_cone is None and not prior.phic_fixed and not any(nonzero)
        self.free = ~np.array(fixed)
        self.nscale = int(self.free[0]) + int(self.free[1])
        self.fixed_values = np.asarray(fixed_values, dtype=float)
        pre = ("s*", "s*", "", "", "") if self.scaled else ("",) * 5
        self.names = [p + name for p, name, f in zip(pre, PARAM_NAMES, self.free) if f]

    @property
    def ndim(self) -> int:
        return int(self.free.sum())

    def to_params(self, xf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Parameters (P, 5) and log |d params / d x| (P,)."""
        xf = np.atleast_2d(xf)
        P = np.empty((xf.shape[0], 5))
        P[:] = self.fixed_values
        P[:, self.free] = xf
        logj = np.zeros(xf.shape[0])
        if self.scaled:
            s = 1.0 + np.tan(np.radians(P[:, 4])) / self.t
            P[:, :2] /= s[:, None]
            logj = -self.nscale * np.log(s)
        for j in np.flatnonzero(~self.free[:2]):  # kc, kphi held
            P[:, j] = self.prior.fixed_value(j, P[:, 2])
        if self.prior.held_ratio is not None:  # kc = ratio kphi (a calibration's)
            P[:, 0] = self.prior.held_ratio * P[:, 1]
        return P, logj

    def from_params(self, params: np.ndarray) -> np.ndarray:
        """Free coordinates of parameter rows (P, 5)."""
        X = np.array(np.atleast_2d(params), dtype=float, copy=True)
        if self.scaled:
            s = 1.0 + np.tan(np.radians(X[:, 4])) / self.t
            X[:, :2] *= s[:, None]
        return X[:, self.free]


class LogPosterior:
    """Log posterior density in the sampler's coordinates, vectorised over walkers.

    Columns: the free parameters (:class:`SamplerCoordinates`), then rho when it
    is sampled.  sigma is marginalised (``-N/2 log Q``) unless fixed.
    """

    def __init__(
        self,
        coords: SamplerCoordinates,
        prior: Prior,
        lik: Likelihood,
        sigma_fixed: float | None,
        rho_sampled: bool,
        rho: float,
    ) -> None:
        self.coords, self.prior, self.lik = coords, prior, lik
        self.sigma_fixed, self.rho_sampled, self.rho = sigma_fixed, rho_sampled, rho
        self.k = coords.ndim
        self.evals = 0

    def __call__(self, xf: np.ndarray) -> np.ndarray:
        k = self.k
        with np.errstate(all="ignore"):
            P, logj = self.coords.to_params(xf[:, :k])
            lp = self.prior.logpdf(P[:, 0], P[:, 1], P[:, 2], P[:, 3], P[:, 4]) + logj
            if self.rho_sampled:
                r = xf[:, k]
                lp[(r < 0) | (r > RHO_MAX) | ~np.isfinite(r)] = -np.inf
        ok = np.isfinite(lp)
        lp[~ok] = -np.inf
        if ok.any():
            r_ok = xf[ok, k] if self.rho_sampled else None
            Q = self.lik.sse(P[ok], rho=r_ok)
            self.evals += int(ok.sum())
            if self.sigma_fixed is None:
                lp[ok] += -0.5 * self.lik.N * np.log(Q)
            else:
                lp[ok] += -0.5 * Q / self.sigma_fixed**2
            if self.rho_sampled:
                lp[ok] -= self.lik.half_logdet(r_ok)
        return lp

    def at_rho(self, xf: np.ndarray) -> np.ndarray:
        """The density of the free parameters with a sampled rho held at its estimate."""
        if not self.rho_sampled:
            return self(xf)
        return self(np.column_stack([xf, np.full(xf.shape[0], self.rho)]))


def start_walkers(
    x0: np.ndarray,
    coords: SamplerCoordinates,
    target: LogPosterior,
    lik: Likelihood,
    prior_draws: np.ndarray,
    nwalkers: int,
    rng: np.random.Generator,
    notes: list[str],
) -> tuple[np.ndarray, list[str]]:
    """Initial walkers (Laplace approximation at the best fit) and the coordinate names."""
    x_hat = coords.from_params(x0[None, :])[0]
    if not np.isfinite(target.at_rho(x_hat[None, :])[0]):
        # the start lies outside the prior's support (e.g. a given start): use the prior median
        x_hat = np.median(coords.from_params(prior_draws), axis=0)
        notes.append("start outside the prior's support; walkers started around the prior median")
    walkers = _initial_ensemble(
        x_hat, coords, lik, target.at_rho, prior_draws, nwalkers, rng, target.sigma_fixed
    )
    names = list(coords.names)
    if target.rho_sampled:
        r0 = np.clip(target.rho + 0.1 * rng.standard_normal(nwalkers), 0.005, RHO_MAX - 0.005)
        walkers = np.column_stack([walkers, r0])
        names.append("rho")
    return walkers, names


def _moves() -> list:
    """Differential-evolution moves (80%) mixed with stretch moves (20%): DE roughly halves
    the autocorrelation time of stretch moves alone here (20-30 steps, not 50-70)."""
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]


def _initial_ensemble(x_hat, coords, lik, log_prob, prior_draws, nwalkers, rng, sigma_fixed):
    """Walkers from the Laplace approximation at x_hat, inside the support."""
    k = coords.ndim
    xp = coords.from_params(prior_draws)
    pvar = np.var(xp, axis=0)
    pvar = np.where(pvar > 0, pvar, 1.0)
    # central differences of the whitened residuals
    h = 1e-4 * np.maximum(np.abs(x_hat), 1e-2 * np.sqrt(pvar))
    Xs = np.concatenate([x_hat + np.diag(h), x_hat - np.diag(h), x_hat[None, :]])
    P, _ = coords.to_params(Xs)
    with np.errstate(all="ignore"):
        r = lik.residuals(*(P[:, j] for j in range(5)))
    J = (r[:k] - r[k : 2 * k]).T / (2 * h)  # (Z, k)
    sse = float(r[-1] @ r[-1])
    s2 = sigma_fixed**2 if sigma_fixed is not None else max(sse / max(lik.N - k, 1), 1e-300)
    F = J.T @ J / s2 + np.diag(1.0 / pvar)
    F = 0.5 * (F + F.T)
    try:
        cov = np.linalg.inv(F)
        cov = 0.5 * (cov + cov.T)
        L = np.linalg.cholesky(cov + 1e-12 * np.diag(np.diag(cov)))
    except np.linalg.LinAlgError:
        L = np.diag(np.sqrt(pvar) * 1e-3)
    if not np.all(np.isfinite(L)):
        L = np.diag(np.sqrt(pvar) * 1e-3)
    good = np.empty((0, k))
    for scale in (1.0, 1.0, 0.3, 0.1, 0.03, 0.01, 1e-3) + (None,) * 100:
        u = rng.standard_normal((4 * nwalkers, k))
        # the Laplace spread, narrowing; last resort (None): a tiny jitter, kept where inside
        cand = x_hat + (1e-6 * (np.abs(x_hat) + 1e-3) * u if scale is None else scale * u @ L.T)
        good = np.concatenate([good, cand[np.isfinite(log_prob(cand))]])
        if good.shape[0] >= nwalkers:
            return good[:nwalkers]
    raise ValueError("could not place the walkers inside the prior's support")


def run_chain(
    target: LogPosterior, walkers: np.ndarray, burn: int, steps: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """emcee run: the kept chain (steps, walkers, ndim) and the acceptance fractions."""
    nwalkers, ndim = walkers.shape
    sampler = emcee.EnsembleSampler(nwalkers, ndim, target, vectorize=True, moves=_moves())
    sampler.random_state = np.random.RandomState(int(rng.integers(2**32 - 1))).get_state()
    sampler.run_mcmc(walkers, burn + steps, progress=False, skip_initial_state_check=True)
    return sampler.get_chain(discard=burn), sampler.acceptance_fraction


def integrated_time(chain: np.ndarray, c: float = 5.0) -> np.ndarray:
    """Integrated autocorrelation time of an ensemble chain, per parameter.

    The estimator of ``emcee.autocorr.integrated_time`` [2]_ (the
    walker-averaged normalised autocorrelation function, summed up to
    Sokal's automatic window, the first lag M with M >= c tau(M)), computed
    with one FFT over all walkers and parameters instead of one per walker.

    Parameters
    ----------
    chain : ndarray, shape (steps, walkers, ndim)
    c : float
        Window constant [-].

    Returns
    -------
    ndarray, shape (ndim,)
        tau [steps]; nan for a coordinate that never moves.
    """
    x = np.asarray(chain, dtype=float)
    T = x.shape[0]
    nfft = 2 * (1 << max(T - 1, 0).bit_length())
    f = np.fft.fft(x - x.mean(axis=0), n=nfft, axis=0)
    acf = np.fft.ifft(f * np.conjugate(f), axis=0)[:T].real
    with np.errstate(invalid="ignore", divide="ignore"):
        acf = (acf / acf[0]).mean(axis=1)  # (T, ndim)
    taus = 2.0 * np.cumsum(acf, axis=0) - 1.0
    small = np.arange(T)[:, None] < c * taus
    window = np.where(small.any(axis=0), np.argmin(small, axis=0), T - 1)
    return taus[window, np.arange(taus.shape[1])]


def chain_diagnostics(
    chain: np.ndarray, names: list[str], acc: np.ndarray, draws: int, notes: list[str]
) -> tuple[dict[str, float], bool, float]:
    """Autocorrelation times, reliability and effective sample size of a kept chain."""
    steps, nwalkers = chain.shape[:2]
    tau = integrated_time(chain)
    tau_d = {name: float(t) for name, t in zip(names, tau)}
    finite = tau[np.isfinite(tau)]
    tmax = float(np.max(finite)) if finite.size else float("nan")
    reliable = bool(np.isfinite(tmax) and steps > 50 * tmax)
    neff = float(nwalkers * steps / tmax) if np.isfinite(tmax) and tmax > 0 else float("nan")
    if float(np.mean(acc)) < 0.15:
        notes.append(f"low acceptance fraction {np.mean(acc):.2f}: the posterior may be multimodal")
    if np.isfinite(neff) and neff < 0.25 * draws:
        notes.append(
            f"effective sample size {neff:.0f} is small against {draws} draws: "
            "the interval ends are noisy (raise draws or thin)"
        )
    return tau_d, reliable, neff

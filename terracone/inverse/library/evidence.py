"""The evidence of a CI profile under a stored calibration, and the posterior it implies.

A candidate calibration's held problem fixes phic, cc, kc/kphi = q and the
pressure law; kphi and n are free.  With fully mobilised shear the model CI
of eq. (2-7) is, with eq. (2-6),

    m(kphi, n) = kphi s (q A(n) + B(n)) + cc C(n),   s = 1 + tan(phic) / tan(half angle),

A, B, C the basis columns of :func:`~terracone.physics.cone.cone_index_basis`.
The CI error is the posterior's (:mod:`terracone.inverse.uncertainty.noise`):
Gaussian, standard deviation sigma w_i with relative weights w_i (from the
profile's uncalibrated fit, the same for every candidate), AR(1) along depth
with coefficient rho, sigma marginalised under p(sigma) ~ 1/sigma:

    p(y | kphi, n, rho) = Gamma(N/2) / (2 pi^(N/2) |W| |R(rho)|^(1/2)) Q^(-N/2),

Q the whitened sum of squares.  The evidence integrates kphi, n and rho
under their priors: u = log kphi uniform over the held box (scale-free, so a
candidate is not favoured for the size of the kphi it needs; kc = q kphi in
its box too), n uniform over its box, rho uniform on [0, 0.95] (as the
posterior's sampled rho; a misfit could be correlated noise, and a rho
estimated from the uncalibrated fit would make the weights overconfident).
For fixed (n, rho), Q is quadratic in kphi, ``Q = Qmin + a (kphi - k)^2``, so
the integral over u costs no pass over the depths; n and rho are integrated
on grids refined around the posterior mass (:func:`held_posterior`).  The
same grids give the candidate's posterior of (kphi, n, rho)
(:meth:`HeldPosterior.draw`).  The Laplace approximation at the held optimum
(:func:`laplace_log_evidence`) is kept beside it as a check
(``docs/library.md``).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-5) to (2-7).
.. [2] Kass, R.E., Raftery, A.E. (1995). Bayes factors. J. Am. Stat. Assoc.
   90(430), 773-795 (the Laplace approximation of the evidence, eq. (4)).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.problem import Problem
from terracone.inverse.solver.columns import bounds_arrays
from terracone.inverse.uncertainty.noise import RHO_MAX, noise_setup
from terracone.physics.cone import Cone, cone_index_basis
from terracone.physics.plate import PressureLaw

__all__ = [
    "EVIDENCE_METHOD",
    "NOISE_FLOOR",
    "Candidate",
    "HeldPosterior",
    "ProfileNoise",
    "color_ar1",
    "held_columns",
    "held_posterior",
    "laplace_log_evidence",
    "n_nodes",
    "pooled_noise",
    "profile_noise",
    "whiten",
]

#: How the evidence is computed, in the words results carry.
EVIDENCE_METHOD = (
    "quadrature: log kphi, n and the AR(1) rho integrated on grids refined around the "
    "posterior mass (log kphi uniform, n uniform, rho uniform on [0, 0.95]), sigma "
    "marginalised under 1/sigma"
)
#: Additive floor of the relative noise weights, a fraction of the largest model CI (as the
#: posterior's default, :class:`terracone.inverse.uncertainty.posterior.PosteriorOptions`).
NOISE_FLOOR = 0.05
#: Nodes of each level of the n grid and of the rho grid; levels of refinement at most.
_NODES = 129
_RHO_NODES = 17
_LEVELS = 4
#: log-density below the maximum that a refined grid leaves out (e^-40 of the peak).
_DROP = 40.0
#: Nodes of the three segments of the grid in log kphi (below, over and above the peak),
#: the half-width of the peak's segment in posterior scales; the lowest kphi of its prior,
#: a fraction of the upper bound of kphi.
_U_NODES = (9, 25, 9)
_PEAK = 8.0
_KPHI_FLOOR = 1e-4


def whiten(v: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Whiten AR(1) series along the last axis, one set of coefficients per rho.

    ``v`` (..., Z), ``phi`` (R, Z - 1): returns (R, ..., Z) with
    ``u_1 = v_1``, ``u_i = (v_i - phi_i v_(i-1)) / sqrt(1 - phi_i^2)``
    (:func:`terracone.inverse.uncertainty.noise.whiten_ar1` for many rho).
    """
    v = np.asarray(v, dtype=float)
    phi = np.asarray(phi, dtype=float).reshape((phi.shape[0],) + (1,) * (v.ndim - 1) + (-1,))
    out = np.empty(phi.shape[:1] + v.shape)
    out[..., 0] = v[..., 0]
    out[..., 1:] = (v[..., 1:] - phi * v[..., :-1]) / np.sqrt(1.0 - phi * phi)
    return out


def color_ar1(u: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The inverse of :func:`whiten` for one row of coefficients: white (..., Z) -> AR(1)."""
    out = np.array(u, dtype=float, copy=True)
    c = np.sqrt(1.0 - phi * phi)
    for i in range(1, out.shape[-1]):
        out[..., i] = phi[i - 1] * out[..., i - 1] + c[i - 1] * u[..., i]
    return out


@dataclass
class ProfileNoise:
    """The CI error model of one profile (or a site's pushes), the same for every candidate.

    Attributes
    ----------
    z, y : ndarray
        Depths [m] and measured CI [kPa].
    cone : Cone
    w : ndarray
        Relative noise weights, RMS 1 [-].
    lag : ndarray
        Spacing of neighbouring readings over the reference spacing [-]
        (inf between two pushes of a site: independent).
    rho : float
        AR(1) coefficient estimated from the uncalibrated fit [-] (the
        discrepancy of :mod:`.check` whitens with it).
    w_rms : float
        RMS of the raw weights [kPa] (the scale :func:`pooled_noise` needs).
    """

    z: np.ndarray
    y: np.ndarray
    cone: Cone
    w: np.ndarray
    lag: np.ndarray
    rho: float = 0.0
    w_rms: float = 1.0

    def __post_init__(self) -> None:
        if self.y.size < 4:
            raise ValueError(f"the evidence needs at least 4 readings (got {self.y.size})")
        self.v = self.y / self.w

    @property
    def N(self) -> int:
        """Number of readings."""
        return int(self.y.size)

    def phi(self, rho: np.ndarray | float) -> np.ndarray:
        """AR(1) coefficients between neighbours (R, Z - 1) at each rho (R,)."""
        r = np.atleast_1d(np.asarray(rho, dtype=float))[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(r > 0, np.abs(r) ** self.lag[None, :], 0.0)

    def log_const(self, rho: np.ndarray | float) -> np.ndarray:
        """log Gamma(N/2) / (2 pi^(N/2) |W| |R(rho)|^(1/2)) at each rho (R,)."""
        N, phi = self.N, self.phi(rho)
        c = math.lgamma(N / 2) - math.log(2.0) - 0.5 * N * math.log(math.pi)
        return c - float(np.sum(np.log(self.w))) - 0.5 * np.sum(np.log1p(-phi * phi), axis=1)

    def raw_columns(
        self, law: PressureLaw, n: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A, B, C of eq. (2-7) at phic = 0, divided by the weights, each (G, Z), at n (G,)."""
        n = np.asarray(n, dtype=float)
        A, B, C = cone_index_basis(self.z, n=n[:, None], phic_deg=0.0, law=law, cone=self.cone)
        shape = (n.size, self.z.size)
        return tuple(np.broadcast_to(c, shape) / self.w for c in (A, B, C))


def profile_noise(profile: CIProfile, fit: TerrainParameters, problem: Problem) -> ProfileNoise:
    """The noise model of a profile from its uncalibrated fit (weights, AR(1) estimate).

    Parameters
    ----------
    profile : CIProfile
    fit : TerrainParameters
        The profile's fit under ``problem`` (its model CI sets the relative
        weights, its residuals the AR(1) estimate).
    problem : Problem
        The uncalibrated problem of the fit (law, bounds).
    """
    ns = noise_setup(
        profile, fit, problem.law, None, problem.fit_bounds, problem.ratio, "relative",
        NOISE_FLOOR, "estimate",
    )  # fmt: skip
    dz = np.diff(profile.depth)
    lag = dz / ns.dz0 if ns.dz0 > 0 else np.ones_like(dz)
    return ProfileNoise(profile.depth, profile.ci, profile.cone, ns.w, lag, ns.rho, ns.w_rms)


def pooled_noise(noises: Sequence[ProfileNoise]) -> ProfileNoise:
    """A site's pushes as one profile of its site terrain: each push over its strength factor.

    The site pooling's site terrain (:func:`terracone.inverse.sites.statistics.site_terrain`):
    push j is divided by g_j, its mean CI over the geometric mean of the
    pushes', so that the pushes share one (kphi, n), one sigma and one rho;
    each keeps its own noise weights (divided by g_j), and pushes are
    independent of each other.
    """
    if len(noises) == 1:
        return noises[0]
    cm = np.array([float(np.mean(nz.y)) for nz in noises])
    g = cm / math.exp(float(np.mean(np.log(cm))))
    w = np.concatenate([nz.w * nz.w_rms / gj for nz, gj in zip(noises, g)])
    rms = float(np.sqrt(np.mean(w * w)))
    lag = np.concatenate([np.concatenate([nz.lag, [np.inf]]) for nz in noises])[:-1]
    return ProfileNoise(
        np.concatenate([nz.z for nz in noises]),
        np.concatenate([nz.y / gj for nz, gj in zip(noises, g)]),
        noises[0].cone,
        w / rms,
        lag,
        float(np.mean([nz.rho for nz in noises])),
        rms,
    )


@dataclass(frozen=True)
class Candidate:
    """A candidate calibration as the evidence sees it: its held values (SI).

    Attributes
    ----------
    name : str
    law : PressureLaw
    ratio : float
        kc/kphi held [m].
    phic_deg, cc : float
        Held phic [deg] and cc [kPa].
    bounds : Bounds
        The held problem's box (its n range is the prior of n).
    """

    name: str
    law: PressureLaw
    ratio: float
    phic_deg: float
    cc: float
    bounds: Bounds

    @classmethod
    def of(cls, name: str, held: Problem) -> Candidate:
        """The candidate of a held problem (:meth:`Problem.held_problem`)."""
        if held.ratio is None or held.calibration is None:
            raise ValueError(f"candidate {name!r}: its problem holds no kc/kphi")
        b = held.fit_bounds
        return cls(name, held.law, float(held.ratio), b.phic_deg[0], b.cc[0], b)

    def scale(self, cone: Cone) -> float:
        """s = 1 + tan(phic) / tan(half angle), eq. (2-6)."""
        return 1.0 + math.tan(math.radians(self.phic_deg)) / math.tan(cone.half_angle)


@dataclass
class _Terms:
    """The held model on a grid of (rho, n), shape (R, G): the whitened kphi column D and
    cc part e (R, G, Z), Q = qmin + a (kphi - khat)^2, and the grid of u = log kphi of each
    node (R, G, 3M) with the integrand's cumulative trapezoid; ``raw`` the columns A, B, C
    over the weights at the n nodes (G, Z), unwhitened."""

    n: np.ndarray
    rho: np.ndarray
    khat: np.ndarray
    a: np.ndarray
    qmin: np.ndarray
    u: np.ndarray
    cum: np.ndarray
    log_f: np.ndarray
    raw: tuple[np.ndarray, np.ndarray, np.ndarray]


def _u_grid(khat, scale, u_lo, u_hi) -> np.ndarray:
    """Nodes (..., 43) in u = log kphi: three equally spaced segments, below the peak (9),
    over it (25, +- 8 posterior scales) and above it (9)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = np.log(np.maximum(khat - _PEAK * scale, np.exp(u_lo)))
        b = np.log(np.maximum(khat + _PEAK * scale, np.exp(u_lo)))
    a = np.clip(np.nan_to_num(a, nan=-np.inf, neginf=-np.inf), u_lo, u_hi)
    b = np.clip(np.nan_to_num(b, nan=-np.inf, neginf=-np.inf), a, u_hi)
    ends = [(u_lo, a), (a, b), (b, u_hi)]
    return np.concatenate(
        [lo[..., None] + (hi - lo)[..., None] * np.linspace(0.0, 1.0, m)
         for (lo, hi), m in zip(ends, _U_NODES)], axis=-1,
    )  # fmt: skip


def held_columns(noise: ProfileNoise, cand: Candidate, raw) -> tuple[np.ndarray, np.ndarray]:
    """The held model's kphi column and cc part over the weights (G, Z), unwhitened."""
    A, B, C = raw
    return cand.scale(noise.cone) * (cand.ratio * A + B), cand.cc * C  # eqs. (2-6), (2-7)


def _terms(
    noise: ProfileNoise, cand: Candidate, n: np.ndarray, rho: np.ndarray, raw=None,
    exact: bool = True,
) -> _Terms:  # fmt: skip
    """The held model on the (rho, n) grid and its integral over u = log kphi.

    ``log_f[r, g]`` is log of ``int p(y | kphi, n, rho) p(u) du``: p(u)
    uniform on [log k_floor, log k_hi], k_hi the kphi box at n (kc = q kphi
    in its box too), k_floor 1e-4 of the kphi bound.  Q(kphi) is quadratic,
    so the integrand costs no pass over the depths: trapezoids on a grid in u
    of three equally spaced segments (below, over and above the peak, +- 8
    posterior scales).  ``exact=False`` (to find where the mass is) takes
    the integral as the Student-t integral over kphi times 1/kphi at its mode.
    """
    raw = noise.raw_columns(cand.law, n) if raw is None else raw
    D0, e0 = held_columns(noise, cand, raw)
    phi = noise.phi(rho)
    D, r = whiten(D0, phi), whiten(noise.v - e0, phi)  # (R, G, Z)
    a = np.einsum("rgz,rgz->rg", D, D)
    b = np.einsum("rgz,rgz->rg", D, r)
    rr = np.einsum("rgz,rgz->rg", r, r)
    N = noise.N
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        khat = b / a
        qmin = np.maximum(rr - b * khat, 1e-300 * np.maximum(rr, 1e-300))
        scale = np.sqrt(qmin / (a * max(N - 3.0, 1.0)))  # posterior sd of kphi
        box = bounds_arrays(cand.bounds, n, cand.ratio)
        k_hi = np.broadcast_to(box[1][:, 1], a.shape)
        k_floor = np.maximum(box[0][:, 1], _KPHI_FLOOR * cand.bounds.kphi_si(n)[1])
        k_floor = np.broadcast_to(k_floor, a.shape)
        ok = (k_hi > k_floor) & np.isfinite(khat) & (a > 0)
        u_lo, u_hi = np.where(ok, np.log(k_floor), 0.0), np.where(ok, np.log(k_hi), 1.0)
        if not exact:
            log_f = (
                noise.log_const(rho)[:, None] - 0.5 * (N - 1) * np.log(qmin) - 0.5 * np.log(a)
                + special.betaln(0.5, 0.5 * (N - 1)) - np.log(np.clip(khat, k_floor, k_hi))
                - np.log(u_hi - u_lo)
            )  # fmt: skip
            log_f = np.where(ok & np.isfinite(log_f), log_f, -np.inf)
            return _Terms(np.asarray(n, float), np.atleast_1d(rho), khat, a, qmin, None, None,
                          log_f, raw)  # fmt: skip
        u = _u_grid(khat, scale, u_lo, u_hi)
        x = (np.exp(u) - khat[..., None]) ** 2 * (a / qmin)[..., None]
        g = np.exp(-0.5 * N * np.log1p(x))  # Q^(-N/2) / qmin^(-N/2), <= 1
        steps = 0.5 * (g[..., 1:] + g[..., :-1]) * np.diff(u, axis=-1)
        cum = np.concatenate([np.zeros(a.shape + (1,)), np.cumsum(steps, axis=-1)], axis=-1)
        log_f = (
            noise.log_const(rho)[:, None] - 0.5 * N * np.log(qmin) + np.log(cum[..., -1])
            - np.log(u_hi - u_lo)
        )  # fmt: skip
    log_f = np.where(ok & np.isfinite(log_f), log_f, -np.inf)
    return _Terms(np.asarray(n, float), np.atleast_1d(rho), khat, a, qmin, u, cum, log_f, raw)


def n_nodes(bounds: Bounds) -> np.ndarray:
    """The coarse grid of n over a box (one node when n is pinned)."""
    lo, hi = (float(v) for v in bounds.n)
    return np.array([lo]) if hi <= lo else np.linspace(lo, hi, _NODES)


def _weights(x: np.ndarray) -> np.ndarray:
    """Trapezoidal weights of the nodes x (1 for a single node)."""
    if x.size == 1:
        return np.ones(1)
    h = np.diff(x)
    w = np.zeros(x.size)
    w[:-1] += 0.5 * h
    w[1:] += 0.5 * h
    return w


@dataclass
class HeldPosterior:
    """A profile's evidence under one candidate and the posterior of (kphi, n, rho) it implies.

    Attributes
    ----------
    candidate : Candidate
    log_evidence : float
        log p(y | candidate) (:data:`EVIDENCE_METHOD`).
    log_mass : ndarray, shape (R, G)
        log posterior mass of each (rho, n) node, normalised.
    terms : _Terms
        The held model on the final grid.
    coarse_raw : tuple of ndarray
        The columns on the coarse n grid over the whole box (for the check).
    coarse_n : ndarray
    """

    candidate: Candidate
    log_evidence: float
    log_mass: np.ndarray
    terms: _Terms
    coarse_n: np.ndarray
    coarse_raw: tuple[np.ndarray, np.ndarray, np.ndarray]

    @property
    def n(self) -> np.ndarray:
        """The n nodes of the final grid [-]."""
        return self.terms.n

    def draw(
        self, rng: np.random.Generator, size: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Posterior draws: rho index, n index and kphi [kN/m^(n+2)], each (size,).

        The (rho, n) node from the nodes' masses, u = log kphi from the
        node's piecewise-linear cumulative integrand.
        """
        p = np.exp(self.log_mass - np.max(self.log_mass)).ravel()
        flat = rng.choice(p.size, size=size, p=p / p.sum())
        ri, gi = np.unravel_index(flat, self.log_mass.shape)
        t = self.terms
        v = rng.uniform(size=size)
        u = np.empty(size)
        for f in np.unique(flat):
            sel = flat == f
            r, g = np.unravel_index(f, self.log_mass.shape)
            u[sel] = np.interp(v[sel] * t.cum[r, g, -1], t.cum[r, g], t.u[r, g])
        return ri, gi, np.exp(u)


def _span(x: np.ndarray, lf: np.ndarray, lo: float, hi: float) -> tuple[float, float] | None:
    """The span of nodes x whose lf is within e^-40 of the maximum, widened by a step; None
    when the peak is resolved (neighbours within 1 in lf) or the span is the grid's."""
    if x.size < 2 or not np.isfinite(lf).any():
        return None
    m = int(np.argmax(lf))
    keep = np.flatnonzero(lf > lf[m] - _DROP)
    step = x[1] - x[0]
    a, b = max(lo, x[keep[0]] - step), min(hi, x[keep[-1]] + step)
    jump = np.abs(np.diff(lf[max(m - 1, 0) : m + 2]))
    if (jump.size and np.max(jump) < 1.0) or b - a > 0.99 * (x[-1] - x[0]):
        return None
    return a, b


def held_posterior(
    noise: ProfileNoise, cand: Candidate, coarse_raw=None, rho: float | None = None
) -> HeldPosterior:
    """The evidence of a profile under a candidate, and the candidate's posterior.

    n (uniform on the candidate's box): 129 nodes over the box, then 129
    over the span within e^-40 of the maximum (widened by a step), and again,
    up to four levels, until neighbouring nodes near the peak differ by less
    than 1 in log density (the kphi integral approximated at its mode while
    searching); rho (uniform on [0, 0.95]) on 17 nodes, refined likewise.  Trapezoids in n and rho; ``docs/library.md`` gives their
    accuracy against brute-force integrals.

    Parameters
    ----------
    noise : ProfileNoise
    cand : Candidate
    coarse_raw : tuple of ndarray, optional
        The columns on the coarse n grid of this candidate's law
        (:meth:`ProfileNoise.raw_columns`; shared between candidates of one law).
    rho : float, optional
        Hold rho at this value instead of integrating it (checks).
    """
    lo, hi = (float(v) for v in cand.bounds.n)
    rhos = np.array([rho]) if rho is not None else np.linspace(0.0, RHO_MAX, _RHO_NODES)
    nodes = n_nodes(cand.bounds)
    if coarse_raw is None or hi <= lo:
        coarse_raw = noise.raw_columns(cand.law, nodes)
    coarse_n = nodes
    few = rhos[:: (_RHO_NODES - 1) // 4] if rho is None else rhos  # the n span, cheaply
    t = _terms(noise, cand, nodes, few, coarse_raw, exact=False)
    for _ in range(_LEVELS):  # n: refine around the mass (over every rho)
        span = _span(t.n, np.max(t.log_f, axis=0), lo, hi)
        if span is None:
            break
        t = _terms(noise, cand, np.linspace(*span, _NODES), few, exact=False)
    t = _terms(noise, cand, t.n, rhos, t.raw)
    for _ in range(_LEVELS if rho is None else 0):  # rho: refine around the mass
        lr = special.logsumexp(t.log_f + np.log(_weights(t.n))[None, :], axis=1)
        span = _span(t.rho, lr, 0.0, RHO_MAX)
        if span is None:
            break
        t = _terms(noise, cand, t.n, np.linspace(*span, _RHO_NODES), t.raw)
    w = np.log(_weights(t.rho))[:, None] + np.log(_weights(t.n))[None, :]
    total = float(special.logsumexp(t.log_f + w))
    prior = (math.log(hi - lo) if hi > lo else 0.0) + (math.log(RHO_MAX) if rho is None else 0.0)
    return HeldPosterior(cand, total - prior, t.log_f + w - total, t, coarse_n, coarse_raw)


def _log_joint(noise: ProfileNoise, cand: Candidate, u: float, n: float, rho: float) -> float:
    """log p(y | kphi, n, rho) + log prior(u, n), u = log kphi, at a fixed rho (Laplace's target)."""
    t = _terms(noise, cand, np.array([n]), np.array([rho]))
    lo, hi = cand.bounds.n
    u_lo, u_hi = t.u[0, 0, 0], t.u[0, 0, -1]
    if not (u_lo <= u <= u_hi and lo <= n <= hi):
        return -math.inf
    q = t.qmin[0, 0] + t.a[0, 0] * (math.exp(u) - t.khat[0, 0]) ** 2
    lc = float(noise.log_const(rho)[0])
    return lc - 0.5 * noise.N * math.log(q) - math.log((u_hi - u_lo) * (hi - lo))


def laplace_log_evidence(noise: ProfileNoise, cand: Candidate, rho: float) -> float:
    """The Laplace approximation of log p(y | candidate, rho) at the held optimum (eq. (4) of [2]_).

    ``log p(y, theta*) + log(2 pi) - 0.5 log det H``, H the Hessian of
    -log p(y, theta) in (u = log kphi, n) at the mode theta* (central
    differences) at a fixed rho.  It ignores the bounds (a mode at a bound
    of kphi or n is approximated as an interior one) and the skew of the
    posterior in n; :func:`held_posterior` (with ``rho=``) is the estimator,
    this its check (``docs/library.md``).
    """
    from scipy.optimize import minimize_scalar

    post = held_posterior(noise, cand, rho=rho)
    t = post.terms
    m = int(np.argmax(t.log_f[0]))
    h0 = float(t.n[1] - t.n[0]) if t.n.size > 1 else 1e-3

    def best_u(n: float) -> float:  # the mode in u at n: kphi = khat (in the prior's range)
        tt = _terms(noise, cand, np.array([n]), np.array([rho]))
        return float(np.clip(np.log(max(tt.khat[0, 0], 1e-300)), tt.u[0, 0, 0], tt.u[0, 0, -1]))

    lo, hi = cand.bounds.n
    a, b = max(lo, t.n[m] - h0), min(hi, t.n[m] + h0)
    res = minimize_scalar(lambda n: -_log_joint(noise, cand, best_u(n), n, rho), bounds=(a, b),
                          method="bounded", options={"xatol": 1e-10})  # fmt: skip
    n0 = float(res.x)
    u0 = best_u(n0)
    g0 = _log_joint(noise, cand, u0, n0, rho)
    hu, hn = 1e-4, 1e-4
    f = lambda du, dn: _log_joint(noise, cand, u0 + du, n0 + dn, rho)  # noqa: E731
    guu = (f(hu, 0) - 2 * g0 + f(-hu, 0)) / hu**2
    gnn = (f(0, hn) - 2 * g0 + f(0, -hn)) / hn**2
    gun = (f(hu, hn) - f(hu, -hn) - f(-hu, hn) + f(-hu, -hn)) / (4 * hu * hn)
    det = guu * gnn - gun * gun
    if not (det > 0 and guu < 0):
        return math.nan
    return g0 + math.log(2 * math.pi) - 0.5 * math.log(det)

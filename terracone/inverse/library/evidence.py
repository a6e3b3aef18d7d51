"""The evidence of a CI profile under a stored calibration, and the posterior it implies.

A candidate calibration's held problem fixes phic, cc, kc/kphi = q and the
pressure law; kphi and n are free.  With fully mobilised shear the model CI
of eq. (2-7) is, with eq. (2-6),

    m(kphi, n) = kphi s (q A(n) + B(n)) + cc C(n),   s = 1 + tan(phic) / tan(half angle),

A, B, C the basis columns of :func:`~terracone.physics.cone.cone_index_basis`.
The CI error is the posterior's (:mod:`terracone.inverse.uncertainty.noise`):
Gaussian, standard deviation sigma w_i with relative weights w_i, AR(1) along
depth, sigma marginalised under p(sigma) ~ 1/sigma.  One noise model per
profile (weights and rho from its uncalibrated fit) serves every candidate,
so that the candidates are compared on the same likelihood.  Then

    p(y | kphi, n) = Gamma(N/2) / (2 pi^(N/2) |W| |R|^(1/2)) Q(kphi, n)^(-N/2),

Q the whitened sum of squares.  For fixed n, Q is quadratic in kphi,
``Q = Qmin + a (kphi - k)^2``, and the integral over kphi (uniform prior on
its box, kc = q kphi in its own) is a truncated Student-t integral with N - 1
degrees of freedom, in closed form:

    int Q^(-N/2) dkphi = Qmin^(-(N-1)/2) a^(-1/2) B(1/2, (N-1)/2) [F(t_hi) - F(t_lo)].

n (uniform on its box) is integrated by the trapezoidal rule on a grid refined
around the posterior mass (:func:`held_posterior`).  The same grid gives the
candidate's posterior of (kphi, n) exactly (:meth:`HeldPosterior.draw`): n
from the nodes' masses, kphi from the truncated t.  The Laplace approximation
at the held optimum (:func:`laplace_log_evidence`) is kept beside it for
comparison (``docs/library.md``).

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
from dataclasses import dataclass

import numpy as np
from scipy import special

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.problem import Problem
from terracone.inverse.solver.columns import bounds_arrays
from terracone.inverse.uncertainty.noise import noise_setup, whiten_ar1
from terracone.physics.cone import Cone, cone_index_basis
from terracone.physics.plate import PressureLaw

__all__ = [
    "EVIDENCE_METHOD",
    "NOISE_FLOOR",
    "Candidate",
    "HeldPosterior",
    "ProfileNoise",
    "held_posterior",
    "laplace_log_evidence",
    "profile_noise",
]

#: How the evidence is computed, in the words results carry.
EVIDENCE_METHOD = (
    "quadrature: kphi integrated in closed form (truncated Student-t, sigma marginalised "
    "under 1/sigma), n by the trapezoidal rule on a grid refined around the posterior mass"
)
#: Additive floor of the relative noise weights, a fraction of the largest model CI (as the
#: posterior's default, :class:`terracone.inverse.uncertainty.posterior.PosteriorOptions`).
NOISE_FLOOR = 0.05
#: Nodes of each level of the n grid; levels of refinement at most.
_NODES = 129
_LEVELS = 4
#: log-density below the maximum that the refined grid leaves out (e^-40 of the peak).
_DROP = 40.0
#: Nodes of each part of the grid in log kphi; the lowest kphi of its prior, a fraction
#: of the upper bound of kphi.
_U_NODES = 33
_KPHI_FLOOR = 1e-4


@dataclass
class ProfileNoise:
    """The CI error model of one profile, the same for every candidate.

    Attributes
    ----------
    z, y : ndarray
        Depths [m] and measured CI [kPa].
    cone : Cone
    w : ndarray
        Relative noise weights, RMS 1 [-].
    phi : ndarray
        AR(1) coefficients between neighbouring readings [-].
    rho : float
        AR(1) coefficient at the median spacing [-].
    """

    z: np.ndarray
    y: np.ndarray
    cone: Cone
    w: np.ndarray
    phi: np.ndarray
    rho: float = 0.0

    def __post_init__(self) -> None:
        if self.y.size < 4:
            raise ValueError(f"the evidence needs at least 4 readings (got {self.y.size})")
        self.yw = whiten_ar1(self.y / self.w, self.phi)

    @property
    def N(self) -> int:
        """Number of readings."""
        return int(self.y.size)

    @property
    def log_const(self) -> float:
        """log of Gamma(N/2) / (2 pi^(N/2) |W| |R|^(1/2)): p(y | theta) = exp(this) Q^(-N/2)."""
        N = self.N
        half_logdet_r = 0.5 * float(np.sum(np.log1p(-self.phi * self.phi)))
        return (
            math.lgamma(N / 2) - math.log(2.0) - 0.5 * N * math.log(math.pi)
            - float(np.sum(np.log(self.w))) - half_logdet_r
        )  # fmt: skip

    def whiten(self, cols: np.ndarray) -> np.ndarray:
        """Columns (..., Z) divided by the weights and whitened along depth."""
        return whiten_ar1(np.asarray(cols, dtype=float) / self.w, self.phi)

    def columns(self, law: PressureLaw, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Whitened A, B, C of eq. (2-7) at phic = 0, each (G, Z), at the n nodes (G,)."""
        n = np.asarray(n, dtype=float)
        A, B, C = cone_index_basis(self.z, n=n[:, None], phic_deg=0.0, law=law, cone=self.cone)
        shape = (n.size, self.z.size)
        return tuple(self.whiten(np.broadcast_to(c, shape)) for c in (A, B, C))


def profile_noise(profile: CIProfile, fit: TerrainParameters, problem: Problem) -> ProfileNoise:
    """The noise model of a profile from its uncalibrated fit (weights, AR(1) estimate).

    Parameters
    ----------
    profile : CIProfile
    fit : TerrainParameters
        The profile's fit under ``problem`` (its model CI sets the relative
        weights, its residuals the AR(1) coefficient).
    problem : Problem
        The uncalibrated problem of the fit (law, bounds).
    """
    ns = noise_setup(
        profile, fit, problem.law, None, problem.fit_bounds, problem.ratio, "relative",
        NOISE_FLOOR, "estimate",
    )  # fmt: skip
    return ProfileNoise(profile.depth, profile.ci, profile.cone, ns.w, ns.phi, ns.rho)


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
    """The held model at n nodes: kphi column D, cc part e (whitened, (G, Z)), the
    quantities of Q = qmin + a (kphi - khat)^2 (G,), and the grid of u = log kphi of
    each node with the integrand's cumulative trapezoid (G, M)."""

    n: np.ndarray
    D: np.ndarray
    e: np.ndarray
    khat: np.ndarray
    a: np.ndarray
    qmin: np.ndarray
    u: np.ndarray
    cum: np.ndarray
    log_f: np.ndarray
    cols: tuple[np.ndarray, np.ndarray, np.ndarray]


def _simpson(m: int) -> np.ndarray:
    """Composite Simpson weights of m (odd) equally spaced nodes over [0, 1]."""
    w = np.ones(m)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    return w / (3.0 * (m - 1))


def _u_grid(khat, scale, u_lo, u_hi) -> np.ndarray:
    """Nodes (G, 3M) in u = log kphi: three equally spaced segments, below the peak, over
    it (+- 12 posterior scales) and above it (trapezoids on each are accurate to ~1e-9)."""
    f = np.linspace(0.0, 1.0, _U_NODES)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.log(np.maximum(khat - 12.0 * scale, np.exp(u_lo)))
        b = np.log(np.maximum(khat + 12.0 * scale, np.exp(u_lo)))
    a = np.clip(np.nan_to_num(a, nan=-np.inf, neginf=-np.inf), u_lo, u_hi)
    b = np.clip(np.nan_to_num(b, nan=-np.inf, neginf=-np.inf), a, u_hi)
    ends = [(u_lo, a), (a, b), (b, u_hi)]
    return np.concatenate([lo[:, None] + (hi - lo)[:, None] * f for lo, hi in ends], axis=1)


def _terms(noise: ProfileNoise, cand: Candidate, n: np.ndarray, cols=None) -> _Terms:
    """The held model at the n nodes and its integral over u = log kphi (log-uniform prior).

    ``log_f`` is log of ``int p(y | kphi, n) p(u) du`` without the constant
    :attr:`ProfileNoise.log_const`: p(u) uniform on [log k_floor, log k_hi],
    k_hi the kphi box at n (kc = q kphi in its box too), k_floor 1e-4 of the
    kphi bound.  Q(kphi) is quadratic, so the integrand costs no pass over
    the depths: trapezoids on a grid in u of three equally spaced segments
    (below, over and above the peak, +- 12 posterior scales).
    """
    A, B, C = noise.columns(cand.law, n) if cols is None else cols
    D = cand.scale(noise.cone) * (cand.ratio * A + B)  # eqs. (2-6), (2-7): kc = q kphi
    e = cand.cc * C
    r = noise.yw[None, :] - e
    a = np.einsum("gz,gz->g", D, D)
    b = np.einsum("gz,gz->g", D, r)
    rr = np.einsum("gz,gz->g", r, r)
    N = noise.N
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        khat = b / a
        qmin = np.maximum(rr - b * khat, 1e-300 * np.maximum(rr, 1e-300))
        scale = np.sqrt(qmin / (a * max(N - 3.0, 1.0)))  # posterior sd of kphi at n
        box = bounds_arrays(cand.bounds, n, cand.ratio)
        k_hi = box[1][:, 1]
        k_floor = np.maximum(box[0][:, 1], _KPHI_FLOOR * cand.bounds.kphi_si(n)[1])
        u_lo, u_hi = np.log(k_floor), np.log(k_hi)
        ok = (k_hi > k_floor) & np.isfinite(khat) & (a > 0)
        u_lo, u_hi = np.where(ok, u_lo, 0.0), np.where(ok, u_hi, 1.0)
        u = _u_grid(khat, scale, u_lo, u_hi)
        x = (np.exp(u) - khat[:, None]) ** 2 * (a / qmin)[:, None]
        g = np.exp(-0.5 * N * np.log1p(x))  # Q^(-N/2) / qmin^(-N/2), <= 1
        cum = np.concatenate(
            [np.zeros((n.size, 1)), np.cumsum(0.5 * (g[:, 1:] + g[:, :-1]) * np.diff(u), 1)], 1
        )
        log_f = -0.5 * N * np.log(qmin) + np.log(cum[:, -1]) - np.log(u_hi - u_lo)
    log_f = np.where(ok & np.isfinite(log_f), log_f, -np.inf)
    return _Terms(n, D, e, khat, a, qmin, u, cum, log_f, (A, B, C))


@dataclass
class HeldPosterior:
    """A profile's evidence under one candidate and the posterior of (kphi, n) it implies.

    Attributes
    ----------
    candidate : Candidate
    log_evidence : float
        log p(y | candidate) (:data:`EVIDENCE_METHOD`), with the constants of
        :attr:`ProfileNoise.log_const`.
    n : ndarray
        Nodes of the finest grid of n [-].
    log_mass : ndarray
        log posterior mass of each node (trapezoidal weights), normalised.
    terms : _Terms
        The held model at the nodes.
    coarse : _Terms
        The held model on the coarse grid over the whole box (for the check).
    """

    candidate: Candidate
    log_evidence: float
    n: np.ndarray
    log_mass: np.ndarray
    terms: _Terms
    coarse: _Terms

    def draw(self, rng: np.random.Generator, size: int) -> tuple[np.ndarray, np.ndarray]:
        """Posterior draws: node index (size,) and kphi [kN/m^(n+2)] (size,).

        The node from the nodes' masses, u = log kphi from the node's
        piecewise-linear cumulative integrand.
        """
        p = np.exp(self.log_mass - np.max(self.log_mass))
        idx = rng.choice(p.size, size=size, p=p / p.sum())
        t = self.terms
        v = rng.uniform(size=size)
        u = np.empty(size)
        for i in np.unique(idx):
            sel = idx == i
            u[sel] = np.interp(v[sel] * t.cum[i, -1], t.cum[i], t.u[i])
        return idx, np.exp(u)


def _simpson_log(n: np.ndarray, log_f: np.ndarray) -> tuple[float, np.ndarray]:
    """log of the composite Simpson integral of exp(log_f) over equally spaced n (odd count),
    and each node's log share."""
    if n.size == 1:
        return float(log_f[0]), np.zeros(1)
    lw = np.log(_simpson(n.size) * (n[-1] - n[0])) + log_f
    total = float(special.logsumexp(lw))
    return total, lw - total


def held_posterior(noise: ProfileNoise, cand: Candidate, coarse_cols=None) -> HeldPosterior:
    """The evidence of a profile under a candidate, and the candidate's posterior of (kphi, n).

    n is uniform on the candidate's box.  A grid of 129 nodes over the box
    finds where exp(log f(n)) is within e^-40 of its maximum; that span
    (widened by one step) gets 129 nodes of its own, and again, up to four
    levels, until neighbouring nodes near the peak differ by less than 1 in
    log f (the trapezoidal rule is then far more accurate than the sampled
    posterior needs: ``docs/library.md``).

    Parameters
    ----------
    noise : ProfileNoise
    cand : Candidate
    coarse_cols : tuple of ndarray, optional
        Whitened columns on the coarse grid of this candidate's law (shared
        between candidates of one law).

    Returns
    -------
    HeldPosterior
    """
    lo, hi = (float(v) for v in cand.bounds.n)
    if hi <= lo:  # n pinned: a point prior
        t = _terms(noise, cand, np.array([lo]))
        return HeldPosterior(cand, float(t.log_f[0]) + noise.log_const, t.n, np.zeros(1), t, t)
    nodes = np.linspace(lo, hi, _NODES)
    coarse = _terms(noise, cand, nodes, coarse_cols)
    t = coarse
    for _ in range(_LEVELS):
        if not np.isfinite(t.log_f).any():
            break
        m = int(np.argmax(t.log_f))
        jump = np.abs(np.diff(t.log_f[max(m - 1, 0) : m + 2]))
        if t is not coarse and (jump.size == 0 or np.max(jump) < 1.0):
            break
        keep = np.flatnonzero(t.log_f > t.log_f[m] - _DROP)
        step = t.n[1] - t.n[0]
        a, b = max(lo, t.n[keep[0]] - step), min(hi, t.n[keep[-1]] + step)
        if b - a > 0.99 * (t.n[-1] - t.n[0]):  # the mass spans the grid: it resolves it
            break
        t = _terms(noise, cand, np.linspace(a, b, _NODES))
    total, log_mass = _simpson_log(t.n, t.log_f)
    log_ev = total - math.log(hi - lo) + noise.log_const
    return HeldPosterior(cand, log_ev, t.n, log_mass, t, coarse)


def _log_joint(noise: ProfileNoise, cand: Candidate, u: float, n: float) -> float:
    """log p(y | kphi, n) + log prior(u, n), u = log kphi, under the candidate (the Laplace target)."""
    t = _terms(noise, cand, np.array([n]))
    lo, hi = cand.bounds.n
    u_lo, u_hi = t.u[0, 0], t.u[0, -1]
    if not (u_lo <= u <= u_hi and lo <= n <= hi):
        return -math.inf
    q = t.qmin[0] + t.a[0] * (math.exp(u) - t.khat[0]) ** 2
    return noise.log_const - 0.5 * noise.N * math.log(q) - math.log((u_hi - u_lo) * (hi - lo))


def laplace_log_evidence(noise: ProfileNoise, cand: Candidate, post: HeldPosterior) -> float:
    """The Laplace approximation of log p(y | candidate) at the held optimum (eq. (4) of [2]_).

    ``log p(y, theta*) + log(2 pi) - 0.5 log det H``, H the Hessian of
    -log p(y, theta) in (u = log kphi, n) at the mode theta* (central
    differences), the mode polished from the best node of ``post``.  It
    ignores the bounds (a mode at a bound of kphi or n is approximated as an
    interior one) and the skew of the posterior in n; :func:`held_posterior`
    is the estimator used, this is its check (``docs/library.md``).
    """
    from scipy.optimize import minimize_scalar

    t = post.terms
    m = int(np.argmax(t.log_f))
    h0 = float(t.n[1] - t.n[0]) if t.n.size > 1 else 1e-3

    def best_u(n: float) -> float:
        tt = _terms(noise, cand, np.array([n]))
        # the mode in u of -N/2 log Q(e^u): kphi = khat (clipped to the prior's range)
        return float(np.clip(np.log(max(tt.khat[0], 1e-300)), tt.u[0, 0], tt.u[0, -1]))

    lo, hi = cand.bounds.n
    a, b = max(lo, t.n[m] - h0), min(hi, t.n[m] + h0)
    res = minimize_scalar(lambda n: -_log_joint(noise, cand, best_u(n), n), bounds=(a, b),
                          method="bounded", options={"xatol": 1e-10})  # fmt: skip
    n0 = float(res.x)
    u0 = best_u(n0)
    g0 = _log_joint(noise, cand, u0, n0)
    hu, hn = 1e-4, 1e-4
    f = lambda du, dn: _log_joint(noise, cand, u0 + du, n0 + dn)  # noqa: E731
    guu = (f(hu, 0) - 2 * g0 + f(-hu, 0)) / hu**2
    gnn = (f(0, hn) - 2 * g0 + f(0, -hn)) / hn**2
    gun = (f(hu, hn) - f(hu, -hn) - f(-hu, hn) + f(-hu, -hn)) / (4 * hu * hn)
    det = guu * gnn - gun * gun
    if not (det > 0 and guu < 0):
        return math.nan
    return g0 + math.log(2 * math.pi) - 0.5 * math.log(det)

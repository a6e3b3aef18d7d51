"""Is a profile outside the library?  A posterior predictive check per candidate.

The discrepancy of a profile y under a candidate is

    T(y) = log min_n Q_held(y, n) - log min_n Q_free(y, n),

Q the whitened sum of squares of :mod:`.evidence` (the profile's own noise
model): Q_held of the candidate's held model (kphi free, its kc/kphi, phic and
cc held, eqs. (2-6), (2-7)), Q_free of the same pressure law with kc', kphi'
and cc free (phic absorbed in kc' and kphi', eq. (2-6)); both linear parts by
unconstrained least squares, both minima over the candidate's grid of n.  T
is >= 0: how much worse the calibration's held values fit than free ones.
Its reference distribution is simulated from the candidate's posterior
predictive: (kphi, n) drawn from the candidate's posterior
(:meth:`~terracone.inverse.library.evidence.HeldPosterior.draw`), sigma^2
from Q / chi^2_N, and AR(1) noise on the profile's weights with the rho
estimated from its uncalibrated fit.
The p-value is the share of replicates with T at least the observed one
(Gelman, Meng and Stern [1]_); a site is checked as its pushes under the site
terrain (:func:`~terracone.inverse.library.evidence.pooled_noise`).  A profile (site)
whose p-value is below the level for every candidate is outside the library.

References
----------
.. [1] Gelman, A., Meng, X.-L., Stern, H. (1996). Posterior predictive
   assessment of model fitness via realized discrepancies. Statistica Sinica
   6, 733-807.
.. [2] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-6), (2-7).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from terracone.inverse.library.evidence import (
    HeldPosterior,
    ProfileNoise,
    color_ar1,
    held_columns,
    whiten,
)

__all__ = ["CHECK_METHOD", "check_p_value", "discrepancy", "replicate_discrepancy"]

#: What the check is, in the words results carry.
CHECK_METHOD = (
    "posterior predictive check: T = log(min SSE of the calibration's held values / min SSE "
    "with kc', kphi', cc free), reference distribution simulated from the calibration's "
    "posterior predictive"
)


def _grid(noise: ProfileNoise, post: HeldPosterior) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The held kphi column D, cc part e and the free basis U at the check's n nodes (coarse
    and fine), whitened with the profile's estimated rho."""
    phi = noise.phi(noise.rho)
    parts = [post.coarse_raw, post.terms.raw]
    raw = [np.concatenate([p[k] for p in parts]) for k in range(3)]
    D0, e0 = held_columns(noise, post.candidate, raw)
    D, e = whiten(D0, phi)[0], whiten(e0, phi)[0]
    free = whiten(np.stack(raw, axis=0), phi)[0]  # (3, G, Z)
    U = np.linalg.qr(np.moveaxis(free, 0, -1))[0]  # an orthonormal basis of each node's columns
    return D, e, U


def discrepancy(Y: np.ndarray, grid: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """T of whitened profiles Y (R, Z) on the check's grid (:func:`_grid`) (R,)."""
    D, e, U = grid
    Y = np.atleast_2d(Y)
    d = D / np.maximum(np.linalg.norm(D, axis=1, keepdims=True), 1e-300)
    yy = np.einsum("rz,rz->r", Y, Y)[:, None]
    ye, yd = Y @ e.T, Y @ d.T
    ee = np.einsum("gz,gz->g", e, e)[None, :]
    ed = np.einsum("gz,gz->g", e, d)[None, :]
    q_held = yy - 2.0 * ye + ee - (yd - ed) ** 2  # |y - e|^2 - (d.(y - e))^2
    G, Z, K = U.shape
    proj = Y @ np.ascontiguousarray(U.transpose(1, 0, 2).reshape(Z, G * K))  # (R, G K)
    q_free = yy - np.add.reduce((proj * proj).reshape(-1, G, K), axis=2)
    tiny = 1e-12 * yy[:, 0]
    best_held = np.maximum(np.min(q_held, axis=1), tiny)
    best_free = np.maximum(np.min(q_free, axis=1), tiny)
    return np.maximum(np.log(best_held) - np.log(best_free), 0.0)


def replicate_discrepancy(
    noise: ProfileNoise, post: HeldPosterior, rng: np.random.Generator, replicates: int
) -> tuple[float, np.ndarray]:
    """Observed T and T of ``replicates`` profiles from the candidate's posterior predictive.

    (kphi, n) from the candidate's posterior, sigma^2 | theta from
    Q / chi^2_N, AR(1) noise on the profile's weights with the rho
    estimated from its uncalibrated fit (a rho drawn from the candidate's
    posterior would grow to absorb the candidate's misfit, and the check
    would lose its power).
    """
    grid = _grid(noise, post)
    phi_hat = noise.phi(noise.rho)
    observed = float(discrepancy(whiten(noise.v, phi_hat)[0], grid)[0])
    ri, gi, kphi = post.draw(rng, replicates)
    t = post.terms
    D0, e0 = held_columns(noise, post.candidate, t.raw)
    mean = kphi[:, None] * D0[gi] + e0[gi]  # eq. (2-7), over the weights
    q = t.qmin[ri, gi] + t.a[ri, gi] * (kphi - t.khat[ri, gi]) ** 2
    sigma = np.sqrt(q / rng.chisquare(noise.N, size=replicates))  # sigma^2 | theta ~ Q / chi2_N
    eps = color_ar1(rng.standard_normal(mean.shape), phi_hat[0])  # the estimated rho's noise
    Y = whiten(mean + sigma[:, None] * eps, phi_hat)[0]
    return observed, discrepancy(Y, grid)


def check_p_value(
    noises: Sequence[ProfileNoise],
    posts: Sequence[HeldPosterior],
    rng: np.random.Generator,
    replicates: int,
) -> tuple[float, float]:
    """The p-value of a candidate for one profile or a site's pushes, and the observed T.

    The pushes' T add up; so do their replicates' (independent across pushes).
    p = (1 + #(T_rep >= T_obs)) / (1 + replicates).
    """
    total, reps = 0.0, np.zeros(replicates)
    for noise, post in zip(noises, posts):
        obs, rep = replicate_discrepancy(noise, post, rng, replicates)
        total += obs
        reps += rep
    return float((1 + np.sum(reps >= total - 1e-12)) / (1 + replicates)), total

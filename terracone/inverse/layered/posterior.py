"""Posterior of a layered fit (:func:`layered_posterior`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import emcee
import numpy as np

from terracone.data import CIProfile
from terracone.inverse.bounds import Bounds
from terracone.inverse.uncertainty.posterior import LABELS, identifiability_label
from terracone.physics import units as u
from terracone.physics.cone import normal_integrals
from terracone.physics.plate import pressure_law

__all__ = ["LayeredPosterior", "layered_posterior"]


@dataclass
class LayeredPosterior:
    """Posterior of a layered fit: per layer kc, kphi, n, cc, and the interfaces (SI).

    Attributes
    ----------
    names : list of str
        ``kc_1, kphi_1, n_1, cc_1, kc_2, ..., interface_1, ...``.
    samples : ndarray
        (draws, len(names)).
    intervals, medians : dict
        90% equal-tailed intervals and medians per name.
    identifiability : dict
        Label per name from the posterior/prior 90% width ratio.
    phic_deg : float
        The common phic held at the fit's value (it trades exactly with the
        scale of each layer's kc and kphi; labelled "set by prior").
    acceptance : float
    """

    names: list[str]
    samples: np.ndarray = field(repr=False)
    intervals: dict[str, tuple[float, float]]
    medians: dict[str, float]
    identifiability: dict[str, str]
    phic_deg: float
    acceptance: float

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        def conv(name: str, v: float, n: float) -> float:
            if name.startswith("kc_"):
                return float(u.kc_from_si(v, n, units))
            if name.startswith("kphi_"):
                return float(u.kphi_from_si(v, n, units))
            if name.startswith("cc_"):
                return float(u.pressure_from_si(v, units))
            if name.startswith("interface_"):
                return float(u.length_from_si(v, units))
            return float(v)

        iv, med = {}, {}
        for k, name in enumerate(self.names):
            if name.startswith(("kc_", "kphi_")):  # convert each draw with its own n
                j = name.split("_")[1]
                nn = self.samples[:, self.names.index(f"n_{j}")]
                col = (u.kc_from_si if name.startswith("kc_") else u.kphi_from_si)(
                    self.samples[:, k], nn, units
                )
                lo, mid, hi = np.quantile(col, [0.05, 0.5, 0.95])
                iv[name], med[name] = [float(lo), float(hi)], float(mid)
            else:
                lo, hi = self.intervals[name]
                iv[name] = [conv(name, lo, 1.0), conv(name, hi, 1.0)]
                med[name] = conv(name, self.medians[name], 1.0)
        labels = dict(self.identifiability)
        labels["phic_deg"] = LABELS[2]
        return {
            "intervals": iv,
            "medians": med,
            "identifiability": labels,
            "phic_deg": self.phic_deg,
            "acceptance": self.acceptance,
            "units": units,
        }


def layered_posterior(
    profile: CIProfile,
    fit: Any,
    *,
    bounds: Bounds | None = None,
    draws: int = 2000,
    seed: int | None = None,
    law: Any = None,
    nwalkers: int = 48,
    burn: int = 400,
) -> LayeredPosterior:
    """Posterior of a layered fit (:func:`fit_layered`) with emcee.

    Priors uniform over the bounds of each layer's kc, kphi, n, cc and over
    the interface depths (ordered, within the profile); the common phic is
    held at the fit's value.  Residuals are independent Gaussian with an
    unknown sigma integrated out (1/sigma prior), so the log-likelihood is
    -N/2 log(SSE).  The forward model is :func:`terracone.physics.layers.layered_basis`
    evaluated for all walkers at once.

    Parameters
    ----------
    profile : CIProfile
        The profile ``fit`` was fitted to.
    fit : LayeredResult
        An ``ok`` layered fit; the walkers start around it.
    bounds : Bounds, optional
    draws : int
    seed : int, optional
        The same seed gives the same draws.
    law : PressureLaw, optional
        Default: the fit's model and r_min.
    nwalkers, burn : int

    Returns
    -------
    LayeredPosterior

    References
    ----------
    .. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013). emcee:
       the MCMC hammer. PASP 125, 306-312.
    """
    bounds = bounds or Bounds()
    law = law or pressure_law(fit.layers[0].model or "rm0", r_min=fit.layers[0].r_min)
    z, y = profile.depth, profile.ci
    phic = fit.layers[0].phic_deg
    names, lo, hi = _layered_box(fit, bounds, float(z[0]), float(z[-1]))
    span = np.where(hi > lo, hi - lo, 1.0)
    log_prob = _LayeredLogPosterior(z, y, profile.cone, law, len(fit.layers), phic, lo, hi)
    x0 = []
    for p in fit.layers:
        x0 += [p.kc, p.kphi, p.n, p.cc]
    x0 += list(fit.interfaces)
    x0 = np.clip(np.array(x0), lo, hi)
    rng = np.random.default_rng(seed)
    p0 = np.clip(x0 + 1e-3 * span * rng.standard_normal((nwalkers, x0.size)), lo, hi)
    sampler = emcee.EnsembleSampler(
        nwalkers,
        x0.size,
        log_prob,
        vectorize=True,
        moves=[(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)],
    )
    sampler.random_state = np.random.RandomState(rng.integers(2**31)).get_state()
    steps = burn + int(math.ceil(draws / nwalkers)) * 5
    sampler.run_mcmc(p0, steps, progress=False)
    chain = sampler.get_chain(discard=burn, thin=5, flat=True)[-draws:]
    intervals, medians, labels = {}, {}, {}
    for k, name in enumerate(names):
        q05, q50, q95 = np.quantile(chain[:, k], [0.05, 0.5, 0.95])
        intervals[name] = (float(q05), float(q95))
        medians[name] = float(q50)
        labels[name] = identifiability_label((q95 - q05) / (0.9 * span[k]))
    return LayeredPosterior(
        names, chain, intervals, medians, labels, phic, float(np.mean(sampler.acceptance_fraction))
    )


def _layered_box(
    fit: Any, bounds: Bounds, d_lo: float, d_hi: float
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Names and prior box of (kc_j, kphi_j, n_j, cc_j per layer, then the interfaces).

    kc and kphi bounds are converted to SI at each layer's fitted n; the
    interfaces lie between the first and last measured depths [m].
    """
    L = len(fit.layers)
    names, lo, hi = [], [], []
    for j in range(1, L + 1):
        n_mid = fit.layers[j - 1].n
        for nm, (a, b) in (
            ("kc", tuple(float(v) for v in bounds.kc_si(n_mid))),
            ("kphi", tuple(float(v) for v in bounds.kphi_si(n_mid))),
            ("n", bounds.n),
            ("cc", bounds.cc),
        ):
            names.append(f"{nm}_{j}")
            lo.append(a)
            hi.append(b)
    for j in range(1, L):
        names.append(f"interface_{j}")
        lo.append(d_lo)
        hi.append(d_hi)
    return names, np.array(lo), np.array(hi)


class _LayeredLogPosterior:
    """log p(theta | CI) of :func:`layered_posterior`, vectorised over walkers (W, D).

    Uniform prior inside ``lo <= theta <= hi``; sigma marginalised (1/sigma
    prior): ``-N/2 log SSE``.  The model CI is eq. (2-7) with eq. (2-6) fully
    mobilised, layer by layer (:func:`terracone.physics.layers.layered_basis`).
    """

    def __init__(self, z, y, cone, law, L, phic, lo, hi) -> None:
        self.z, self.y, self.law, self.L, self.lo, self.hi = z, y, law, L, lo, hi
        self.R, H = cone.radius, cone.height
        self.t = self.R / H
        self.s = 1.0 + math.tan(math.radians(phic)) / self.t
        self.u1 = z + H
        self.Lemb = np.where(z >= 0.0, H, self.u1)
        self.u1s = np.where(self.u1 > 0, self.u1, 1.0)

    def model(self, theta: np.ndarray) -> np.ndarray:
        """Model CI (W, Z) [kPa] of parameter rows (W, D)."""
        L, z, R, t, s = self.L, self.z, self.R, self.t, self.s
        W = theta.shape[0]
        D = np.concatenate(
            [np.zeros((W, 1)), np.sort(theta[:, 4 * L :], axis=1), np.full((W, 1), np.inf)], axis=1
        )
        ci = np.zeros((W, z.size))
        for j in range(L):
            kc, kphi, n, cc = (theta[:, 4 * j + q][:, None] for q in range(4))
            a = np.clip(self.u1[None, :] - D[:, j + 1][:, None], 0.0, self.Lemb[None, :])
            b = np.clip(self.u1[None, :] - D[:, j][:, None], 0.0, self.Lemb[None, :])
            Ic, Ip, Icc = normal_integrals(self.u1s[None, :], a, b, n, self.law, t)
            ci += 2.0 / (R * R) * (t * s * (kc * Ic + kphi * Ip) + cc * Icc)  # eq. (2-7)
        return ci

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(theta)
        ok = np.all((theta >= self.lo) & (theta <= self.hi), axis=1)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():
            r = self.model(theta[ok]) - self.y[None, :]
            sse = np.einsum("wz,wz->w", r, r)
            out[ok] = -0.5 * self.y.size * np.log(np.maximum(sse, 1e-300))
        return out

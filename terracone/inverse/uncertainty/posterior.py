"""Posterior uncertainty of the prediction process: how well does one CI profile fix the parameters?

:func:`terracone.inverse.predict` returns one best fit.  Many parameter sets
fit a CI profile almost equally well (section 2 of [1]_: phic trades exactly
against a common scale of kc and kphi under fully mobilised shear, and the
kc, kphi and cc columns of eq. (2-7) are nearly collinear), and they predict
quite different plate pressures.  :func:`posterior` samples the Bayesian
posterior of (kc, kphi, n, cc, phic) given one profile and reports

* 90% credible intervals of the parameters,
* an identifiability label per parameter, from the ratio of its posterior to
  its prior 90% width,
* 90% bands of the predicted plate pressure against sinkage.

The model of the CI error is in :mod:`terracone.inverse.uncertainty.noise`,
the priors in :mod:`~terracone.inverse.uncertainty.priors`, the tabulated
likelihood in :mod:`~terracone.inverse.uncertainty.likelihood` and the emcee
set-up in :mod:`~terracone.inverse.uncertainty.sampler`.  Identifiability:
``ratio = (posterior 90% width) / (prior 90% width)`` per parameter, below
0.25 "determined", below 0.75 "weakly determined", else "set by prior" (a
parameter held fixed is "set by prior"); ``docs/uncertainty.md`` explains
the labels and the phic ridge.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 2 and 3.
.. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013). emcee:
   the MCMC hammer. PASP 125, 306-312.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.predict import predict
from terracone.inverse.problem import Problem
from terracone.inverse.uncertainty.likelihood import Likelihood
from terracone.inverse.uncertainty.noise import NoiseModel, NoiseSetup, noise_setup
from terracone.inverse.uncertainty.priors import PARAM_NAMES, Prior
from terracone.inverse.uncertainty.sampler import (
    LogPosterior,
    SamplerCoordinates,
    chain_diagnostics,
    run_chain,
    start_walkers,
)
from terracone.physics import units as u
from terracone.physics.plate import PressureLaw, plate_basis, pressure_law
from terracone.result import PosteriorSummary, PredictionResult, finite_or_none
from terracone.resultunits import Written, output, quantity

__all__ = [
    "LABELS",
    "DETERMINED_BELOW",
    "WEAKLY_BELOW",
    "DEFAULT_PLATES",
    "DEFAULT_SINKAGES",
    "PlateBand",
    "SamplerDiagnostics",
    "PosteriorResult",
    "PosteriorOptions",
    "identifiability_label",
    "plate_bands",
    "posterior",
]

#: Identifiability labels, from best to worst determined.
LABELS = ("determined", "weakly determined", "set by prior")


#: Width ratio (posterior / prior 90% width) below which a parameter is "determined".
DETERMINED_BELOW = 0.25


#: Width ratio below which a parameter is "weakly determined" (else "set by prior").
WEAKLY_BELOW = 0.75


#: Default plate radii of the bands [m]: the LETE pair of the paper (1.5 in, 2 in nominal).
DEFAULT_PLATES = (0.0375, 0.05)


#: Default sinkages of the bands [m]: 0 to 10 cm every 5 mm.
DEFAULT_SINKAGES = tuple(np.round(np.linspace(0.0, 0.10, 21), 6))


_N_PRIOR_DRAWS = 8000


def identifiability_label(ratio: float) -> str:
    """Label of a posterior/prior 90% width ratio (thresholds 0.25 and 0.75)."""
    if not math.isfinite(ratio) or ratio >= WEAKLY_BELOW:
        return LABELS[2]
    return LABELS[0] if ratio < DETERMINED_BELOW else LABELS[1]


@dataclass
class PlateBand(Written):
    """Band of predicted plate pressure against sinkage.

    Attributes
    ----------
    radius : float
        Plate radius (Bekker size b) [m].
    sinkage : ndarray
        [m]
    median, lo, hi : ndarray
        Posterior median and the equal-tailed interval (90% by default) of
        the pressure at each sinkage [kPa].
    """

    radius: float = quantity("length")
    sinkage: np.ndarray = quantity("length")
    median: np.ndarray = quantity("pressure")
    lo: np.ndarray = quantity("pressure")
    hi: np.ndarray = quantity("pressure")


@dataclass
class SamplerDiagnostics:
    """Diagnostics of the MCMC run.

    Attributes
    ----------
    nwalkers, burn, steps, thin : int
        Walkers, discarded burn-in steps, kept steps (after burn-in, before
        thinning) and the thinning factor.
    draws : int
        Number of posterior samples returned.
    acceptance : float
        Mean acceptance fraction of the walkers [-] (0.2-0.5 is healthy).
    acceptance_min : float
    autocorr_time : dict or None
        Integrated autocorrelation time per sampled coordinate [steps].
    autocorr_reliable : bool
        Whether the kept chain is longer than 50 autocorrelation times (the
        estimate of tau itself is then reliable).
    effective_samples : float
        nwalkers * steps / max(tau).
    log_prob_evals : int
    time_s : float
        Wall time of :func:`posterior` [s].
    cpu_s : float
        CPU time of the calling process during :func:`posterior` [s].
    coordinates : str
        "scaled" ((s kc, s kphi, n, cc, phic), fully mobilised) or "plain".
    """

    nwalkers: int
    burn: int
    steps: int
    thin: int
    draws: int
    acceptance: float
    acceptance_min: float
    autocorr_time: dict[str, float] | None
    autocorr_reliable: bool
    effective_samples: float
    log_prob_evals: int
    time_s: float
    coordinates: str
    cpu_s: float = float("nan")

    def as_dict(self) -> dict[str, Any]:
        return {
            "nwalkers": self.nwalkers,
            "burn": self.burn,
            "steps": self.steps,
            "thin": self.thin,
            "draws": self.draws,
            "acceptance": self.acceptance,
            "acceptance_min": self.acceptance_min,
            "autocorr_time": None
            if self.autocorr_time is None
            else {k: finite_or_none(v) for k, v in self.autocorr_time.items()},
            "autocorr_reliable": self.autocorr_reliable,
            "effective_samples": finite_or_none(self.effective_samples),
            "log_prob_evals": self.log_prob_evals,
            "time_s": self.time_s,
            "cpu_s": finite_or_none(self.cpu_s),
            "coordinates": self.coordinates,
        }


@dataclass(kw_only=True)
class PosteriorResult(PosteriorSummary):
    """Posterior of (kc, kphi, n, cc, phic) given one CI profile (SI inside).

    A :class:`~terracone.result.PosteriorSummary` (``samples``, ``names`` =
    :data:`PARAM_NAMES`, ``intervals``, ``medians``, ``identifiability``,
    ``prior`` "bounds" or "calibration:<terrain>", ``level``, ``notes``) with
    the run's details.

    Attributes
    ----------
    id : str
        Profile id.
    prior_intervals : dict
        The prior's interval at ``level`` per parameter (SI).
    prior_widths, posterior_widths : dict
        hi - lo of the prior and posterior intervals (SI).
    width_ratio : dict
        posterior / prior width [-] (1 for parameters held fixed).
    plate_bands : list of PlateBand
    noise : NoiseModel
    diagnostics : SamplerDiagnostics
    model : {"rm0", "rm1"}
    r_min : float or None
        [m]
    K_cone : float or None
        [m]
    best_fit : TerrainParameters
        The exact solver's optimum the walkers started from.
    prior_samples : ndarray, shape (2000, 5)
        Prior draws (SI), for the prior intervals in US units.
    """

    id: str
    prior_intervals: dict[str, tuple[float, float]]
    prior_widths: dict[str, float]
    posterior_widths: dict[str, float]
    width_ratio: dict[str, float]
    plate_bands: list[PlateBand]
    noise: NoiseModel
    diagnostics: SamplerDiagnostics
    model: str
    r_min: float | None = quantity("length")
    K_cone: float | None = quantity("length", key="Kc")
    best_fit: TerrainParameters
    prior_samples: np.ndarray | None = field(default=None, repr=False)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """JSON-ready dict in a unit system.

        Keys: ``intervals`` ({name: [lo, hi]}), ``medians``,
        ``identifiability``, ``plate_bands`` (list of {radius, sinkage,
        median, lo, hi}) and ``posterior`` (level, prior, width ratios,
        prior intervals, noise, sampler diagnostics, notes).  kc and kphi
        are converted sample by sample with each sample's own n before the
        quantiles are taken, so US intervals are quantiles of US values.
        """
        units = u.check_system(units)
        q = self.quantiles(units)
        d: dict[str, Any] = {
            "intervals": {k: [v[0], v[2]] for k, v in q.items()},
            "medians": {k: v[1] for k, v in q.items()},
            "identifiability": dict(self.identifiability),
            "plate_bands": [b.as_dict(units) for b in self.plate_bands],
        }
        if units == "si":
            prior_iv = {k: [float(v[0]), float(v[1])] for k, v in self.prior_intervals.items()}
        elif self.prior_samples is not None:
            prior = PosteriorSummary(intervals={}, samples=self.prior_samples, level=self.level)
            prior_iv = {k: [v[0], v[2]] for k, v in prior.quantiles(units).items()}
        else:
            prior_iv = None
        d["posterior"] = {
            **output(self, units, fields=("level", "prior", "model", "r_min", "K_cone")),
            "width_ratio": {k: finite_or_none(v) for k, v in self.width_ratio.items()},
            "thresholds": {"determined": DETERMINED_BELOW, "weakly determined": WEAKLY_BELOW},
            "prior_intervals": prior_iv,
            "noise": self.noise.as_dict(units),
            "sampler": self.diagnostics.as_dict(),
            "notes": list(self.notes),
            "units": units,
        }
        return d


def _start_params(start: Any) -> TerrainParameters:
    if isinstance(start, PredictionResult):
        if not start.ok or start.params is None:
            raise ValueError(f"profile {start.id}: prediction failed: {start.error}")
        return start.params
    if isinstance(start, TerrainParameters):
        return start
    raise TypeError("start must be a PredictionResult or TerrainParameters")


@dataclass(frozen=True)
class PosteriorOptions:
    """How :func:`posterior` models the CI error and runs the sampler (``docs/uncertainty.md``).

    Attributes
    ----------
    noise : float, optional
        Noise standard deviation [kPa] (RMS over the profile); marginalised when None.
    correlation : "estimate", "sample", "none" or float
        AR(1) coefficient of the noise at the median spacing [-]: plug-in
        estimate, sampled (uniform on [0, 0.95]), 0, or the value given.
    noise_model, noise_floor
        "relative" or "absolute"; floor of the relative model, a fraction of
        the largest model CI [-] (:mod:`terracone.inverse.uncertainty.noise`).
    nwalkers, burn, thin : int
        Walkers, burn-in steps discarded and thinning of the kept chain.
    level : float
        Credibility of the intervals and bands [-].
    n_prior : {"uniform", "reference"}
        Under the bounds prior, "reference" weights the box by sqrt(det G(n))
        (:meth:`Prior.set_reference`; not the default, docs/uncertainty.md).
    """

    noise: float | None = None
    correlation: str | float = "estimate"
    noise_model: str = "relative"
    noise_floor: float = 0.05
    nwalkers: int = 128
    burn: int = 80
    thin: int = 6
    level: float = 0.9
    n_prior: str = "uniform"

    def __post_init__(self) -> None:
        if not 0 < self.level < 1:
            raise ValueError(f"level must be in (0, 1) (got {self.level})")
        if self.nwalkers < 8 or self.nwalkers % 2:
            raise ValueError(f"nwalkers must be even and >= 8 (got {self.nwalkers})")
        if self.burn < 0 or self.thin < 1:
            raise ValueError("burn must be >= 0 and thin >= 1")
        if self.noise_model not in ("relative", "absolute"):
            raise ValueError(
                f"noise_model must be 'relative' or 'absolute' (got {self.noise_model!r})"
            )
        if self.noise is not None and not (self.noise > 0 and math.isfinite(self.noise)):
            raise ValueError(f"noise must be > 0 [kPa] (got {self.noise})")
        if not 0 <= self.noise_floor < 10:
            raise ValueError(f"noise_floor must be >= 0 (got {self.noise_floor})")
        if self.n_prior not in ("reference", "uniform"):
            raise ValueError(f"n_prior must be 'reference' or 'uniform' (got {self.n_prior!r})")


def posterior(
    profile: CIProfile,
    problem: Problem | None = None,
    *,
    start: PredictionResult | TerrainParameters | None = None,
    draws: int = 2000,
    seed: int | None = None,
    plates: Sequence[float] | None = None,
    plate_sinkages: ArrayLike | None = None,
    options: PosteriorOptions | None = None,
) -> PosteriorResult:
    """Sample the posterior of (kc, kphi, n, cc, phic) given one CI profile.

    Parameters
    ----------
    profile : CIProfile
        Depths [m] and cone index [kPa].
    problem : Problem, optional
        What is fitted: the pressure law, ``K_cone`` [m] (None: fully
        mobilised), the bounds (the support of the prior), the values a
        calibration holds (held in every draw) or a calibration as the
        prior's centre (:mod:`terracone.inverse.uncertainty.priors`).
    start : PredictionResult or TerrainParameters, optional
        Best fit under ``problem`` to start from; :func:`terracone.inverse.predict`
        runs when None.
    draws : int
        Samples returned.
    seed : int, optional
        The same seed gives the same samples bit for bit.
    plates, plate_sinkages : optional
        Plate radii [m] (default: the problem's plate pair, else 3.75 and 5
        cm) and sinkages [m] (0 to 10 cm every 5 mm) of the bands.
    options : PosteriorOptions, optional
        The noise model and the sampler.

    Returns
    -------
    PosteriorResult

    Raises
    ------
    ValueError
        Bad input or a profile that cannot be fitted.

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.
       Predicting terrain parameters for physics-based vehicle mobility
       models from cone index data. Sections 2, 3.2, 3.3.2.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    problem, o = problem or Problem(), options or PosteriorOptions()
    problem.require_single("posterior")
    if draws < 10:
        raise ValueError(f"draws must be >= 10 (got {draws})")
    st = _prepare(profile, problem, o, start, seed)
    samples, rho_draws, diag = _draw(st, draws, o)
    noise_out = _noise_summary(st.noise, st.lik, samples, rho_draws, o, st.rng)
    summary = _summaries(samples, st.prior_draws, st.prior, o.level)
    radii = DEFAULT_PLATES if problem.plate_pair is None else tuple(problem.plate_pair)
    radii = radii if plates is None else tuple(plates)
    sink = np.asarray(DEFAULT_SINKAGES if plate_sinkages is None else plate_sinkages, float)
    bands = plate_bands(samples, radii, sink, law=problem.law, level=o.level)
    diag.time_s, diag.cpu_s = time.perf_counter() - t0, time.process_time() - c0
    return _result(profile, st, samples, summary, bands, noise_out, diag, o.level)


@dataclass
class _Setup:
    """Everything :func:`posterior` samples with: law, start, noise, prior, likelihood, target."""

    problem: Problem
    start: TerrainParameters
    noise: NoiseSetup
    prior: Prior
    lik: Likelihood
    x0: np.ndarray
    coords: SamplerCoordinates
    target: LogPosterior
    prior_draws: np.ndarray
    rng: np.random.Generator
    notes: list[str]


def _result(
    profile: CIProfile,
    st: _Setup,
    samples: np.ndarray,
    summary: dict[str, dict],
    bands: list[PlateBand],
    noise_out: NoiseModel,
    diag: SamplerDiagnostics,
    level: float,
) -> PosteriorResult:
    """The :class:`PosteriorResult` of a run of :func:`posterior`."""
    return PosteriorResult(
        id=profile.id,
        samples=samples,
        **summary,
        plate_bands=bands,
        noise=noise_out,
        diagnostics=diag,
        prior=st.problem.prior_label(),
        model=st.problem.model,
        r_min=st.problem.r_min,
        K_cone=st.problem.K_cone,
        level=level,
        best_fit=st.start,
        notes=st.notes,
        prior_samples=st.prior_draws[:2000],
    )


def _prepare(
    profile: CIProfile, pb: Problem, o: PosteriorOptions, start: Any, seed: int | None
) -> _Setup:
    """The best fit, noise model, prior, likelihood and target of :func:`posterior`."""
    profile.validate()
    rng = np.random.default_rng(seed)
    p0 = _start_params(predict(profile, pb) if start is None else start)
    ns = noise_setup(
        profile, p0, pb.law, pb.K_cone, pb.fit_bounds, pb.ratio, o.noise_model, o.noise_floor,
        o.correlation,
    )  # fmt: skip
    pri = Prior.of(pb)
    lik = Likelihood(
        profile.depth,
        profile.ci,
        cone=profile.cone,
        law=pb.law,
        K_cone=pb.K_cone,
        n_range=pri.b.n,
        weights=ns.w,
        phi=None if ns.rho_sampled else ns.phi,
        spacing=ns.dz0 or None,
    )
    if o.n_prior == "reference":
        free = (not pri.kc_fixed, not pri.kphi_fixed, not pri.cc_fixed)
        pri.set_reference(lik.grid, lik.gram_half_logdet(free, p0.phic_deg))
    x0, coords = _start_and_coordinates(p0, pri, profile.cone, pb.K_cone)
    if coords.ndim == 0:
        raise ValueError("all parameters are fixed: nothing to sample")
    target = LogPosterior(coords, pri, lik, o.noise, ns.rho_sampled, ns.rho)
    prior_draws = pri.sample(rng, _N_PRIOR_DRAWS)
    return _Setup(
        problem=pb,
        start=p0,
        noise=ns,
        prior=pri,
        lik=lik,
        x0=x0,
        coords=coords,
        target=target,
        prior_draws=prior_draws,
        rng=rng,
        notes=list(ns.notes),
    )


def _draw(
    st: _Setup, draws: int, o: PosteriorOptions
) -> tuple[np.ndarray, np.ndarray | None, SamplerDiagnostics]:
    """Run the sampler: parameter draws (SI), rho draws (or None) and the diagnostics.

    The diagnostics' ``time_s`` and ``cpu_s`` are left for the caller to fill in.
    """
    coords, nwalkers, burn, thin = st.coords, o.nwalkers, o.burn, o.thin
    walkers, names = start_walkers(
        st.x0, coords, st.target, st.lik, st.prior_draws, nwalkers, st.rng, st.notes
    )
    steps = int(math.ceil(draws * thin / nwalkers))
    chain, acc = run_chain(st.target, walkers, burn, steps, st.rng)
    flat = chain[::-1][::thin][::-1].reshape(-1, chain.shape[2])[-draws:]
    samples, _ = coords.to_params(flat[:, : coords.ndim])
    rho_draws = flat[:, coords.ndim] if st.noise.rho_sampled else None
    tau_d, reliable, neff = chain_diagnostics(chain, names, acc, draws, st.notes)
    diag = SamplerDiagnostics(
        nwalkers=nwalkers,
        burn=burn,
        steps=steps,
        thin=thin,
        draws=int(samples.shape[0]),
        acceptance=float(np.mean(acc)),
        acceptance_min=float(np.min(acc)),
        autocorr_time=tau_d,
        autocorr_reliable=reliable,
        effective_samples=neff,
        log_prob_evals=st.target.evals,
        time_s=float("nan"),
        coordinates="scaled" if coords.scaled else "plain",
    )
    return samples, rho_draws, diag


def _start_and_coordinates(p0, pri: Prior, cone, K_cone):
    """The best fit clipped to the prior's box (5,) and the sampler's coordinates."""
    bounds = pri.b
    x0 = np.array([p0.kc, p0.kphi, p0.n, p0.cc, p0.phic_deg], dtype=float)
    for j, (lo, hi) in ((2, bounds.n), (3, bounds.cc), (4, bounds.phic_deg)):
        x0[j] = np.clip(x0[j], lo, hi)
    fixed_vals = x0.copy()
    if pri.n_fixed:
        fixed_vals[2] = bounds.n[0]
    if pri.cc_fixed:
        fixed_vals[3] = pri.cc_value
    if pri.phic_fixed:
        fixed_vals[4] = pri.phic_value
    return x0, SamplerCoordinates(pri, cone, K_cone, fixed_vals)


def _noise_summary(ns, lik, samples, rho_draws, o: PosteriorOptions, rng):
    """The :class:`NoiseModel` reported: sigma from sigma^2 | theta ~ Q / chi^2_N."""
    sigma_fixed, noise_model, floor, level = o.noise, o.noise_model, o.noise_floor, o.level
    q = [(1 - level) / 2, 0.5, (1 + level) / 2]
    if sigma_fixed is None:
        Q = lik.sse(samples, rho=rho_draws)
        sig = np.sqrt(Q / rng.chisquare(lik.N, size=Q.size))
        s_lo, s_med, s_hi = np.quantile(sig, q)
        sigma, sigma_iv = float(s_med), (float(s_lo), float(s_hi))
    else:
        sigma, sigma_iv = float(sigma_fixed), None
    rho, rho_iv = ns.rho, None
    if rho_draws is not None:
        r_lo, r_med, r_hi = np.quantile(rho_draws, q)
        rho, rho_iv = float(r_med), (float(r_lo), float(r_hi))
    return NoiseModel(
        kind=noise_model,
        sigma=sigma,
        sigma_interval=sigma_iv,
        sigma_rel=(sigma / ns.w_rms) if noise_model == "relative" else None,
        rho=float(rho),
        spacing=ns.dz0,
        floor=float(floor) if noise_model == "relative" else 0.0,
        sigma_estimated=sigma_fixed is None,
        rho_estimated=ns.rho_est,
        rho_raw=ns.rho_raw,
        weights=ns.w,
        rho_interval=rho_iv,
        rho_sampled=rho_draws is not None,
    )


def _summaries(samples, prior_draws, pri, level) -> dict[str, dict]:
    """Medians, intervals, prior intervals, widths, width ratios and labels per parameter."""
    qs = [(1 - level) / 2, 0.5, (1 + level) / 2]
    post_q = np.quantile(samples, qs, axis=0)
    prior_q = np.quantile(prior_draws, qs, axis=0)
    # kc held to kphi by a ratio is as determined as kphi
    kc_free = not pri.kc_fixed or pri.held_ratio is not None
    free = [kc_free, not pri.kphi_fixed, not pri.n_fixed, not pri.cc_fixed, not pri.phic_fixed]
    out: dict[str, dict] = {
        k: {}
        for k in (
            "medians",
            "intervals",
            "prior_intervals",
            "prior_widths",
            "posterior_widths",
            "width_ratio",
            "identifiability",
        )
    }
    for j, name in enumerate(PARAM_NAMES):
        out["medians"][name] = float(post_q[1, j])
        iv = (float(post_q[0, j]), float(post_q[2, j]))
        piv = (float(prior_q[0, j]), float(prior_q[2, j]))
        out["intervals"][name], out["prior_intervals"][name] = iv, piv
        qw, pw = iv[1] - iv[0], piv[1] - piv[0]
        out["posterior_widths"][name], out["prior_widths"][name] = qw, pw
        ratio = qw / pw if free[j] and pw > 0 else 1.0
        out["width_ratio"][name] = ratio
        out["identifiability"][name] = identifiability_label(ratio)
    return out


def plate_bands(
    samples: np.ndarray,
    radii: Sequence[float],
    sinkage: ArrayLike,
    *,
    law: PressureLaw | None = None,
    level: float = 0.9,
) -> list[PlateBand]:
    """Bands of plate pressure from posterior samples.

    Parameters
    ----------
    samples : ndarray, shape (S, 5)
        kc, kphi, n, cc, phic (SI).
    radii : sequence of float
        Plate radii [m].
    sinkage : array_like
        Sinkages [m], >= 0.
    law : PressureLaw, optional
        RM0 (default) or RM1 (the plate's own pressure law).
    level : float
        Credibility [-].

    Returns
    -------
    list of PlateBand
        Pointwise quantiles; every sample's curve increases with sinkage, so
        the median and the band ends do too.
    """
    law = law or pressure_law("rm0")
    sink = np.asarray(sinkage, dtype=float)
    if np.any(sink < 0) or not np.all(np.isfinite(sink)):
        raise ValueError("plate sinkages must be finite and >= 0")
    out = []
    qs = [(1 - level) / 2, 0.5, (1 + level) / 2]
    for r in radii:
        r = float(r)
        if not r > 0:
            raise ValueError(f"plate radius must be > 0 (got {r})")
        A, B = plate_basis(sink[None, :], n=samples[:, 2:3], b=r, law=law)
        p = samples[:, 0:1] * A + samples[:, 1:2] * B
        lo, med, hi = np.quantile(p, qs, axis=0)
        out.append(PlateBand(r, sink.copy(), med, lo, hi))
    return out

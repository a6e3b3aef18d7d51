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

Noise model
-----------
The CI error at depth z_i is Gaussian with standard deviation
``sigma * w_i`` and an AR(1) correlation along depth:

* ``noise_model="relative"`` (default): ``w_i`` is proportional to
  ``sqrt(m_i^2 + (floor * max m)^2)`` with ``m`` the best-fit model CI and
  ``floor = noise_floor`` (5% by default; an additive part that stands for
  the instrument resolution and keeps the surface readings from getting
  infinite weight); ``"absolute"``: ``w_i = 1``.  The weights are normalised
  to a root mean square of 1, so ``sigma`` [kPa] is the RMS noise standard
  deviation over the profile.  They are computed once from the best fit
  (plug-in weights), which keeps the likelihood a weighted least-squares
  form.
* Correlation: readings Delta apart correlate with ``rho**(Delta / dz0)``,
  ``dz0`` the median spacing (a discretely sampled Ornstein-Uhlenbeck
  process: AR(1) with lag-1 coefficient ``rho`` at the median spacing, and
  exact for irregular spacing too).  Its inverse covariance is tridiagonal,
  so the exact likelihood costs O(N): the residuals are whitened by
  ``u_1 = e_1``, ``u_i = (e_i - phi_i e_{i-1}) / sqrt(1 - phi_i^2)``.
  Unless given, ``rho`` is estimated from the best-fit residuals: their
  lag-1 autocorrelation, corrected for what the fit absorbs of a correlated
  error, at the actual depths (see :func:`estimate_correlation`), clipped to
  [0, 0.95] and plugged in.  ``correlation="sample"`` samples rho instead
  (uniform prior on [0, 0.95]; exact AR(1) likelihood including its
  log-determinant), which carries its uncertainty into the intervals.
* ``sigma`` is marginalised analytically under the scale-invariant prior
  p(sigma) ~ 1/sigma: the marginal likelihood is ``Q(theta)^(-N/2)`` with
  ``Q`` the whitened sum of squares (a multivariate Student t); a given
  ``noise`` fixes it.  Draws of sigma are reported from its conditional
  posterior ``sigma^2 | theta ~ Q / chi^2_N``.

Priors
------
* ``"bounds"``: uniform over the search box of :class:`Bounds` (in the units
  the bounds were given in, so with US bounds the SI density of kc and kphi
  depends on n).
* a :class:`~terracone.inverse.learn.Calibration` (or a
  :class:`CalibrationPrior` to change the widths): model, r_min and the plate
  pair are fixed to the calibration's; phic ~ Normal(phic_cal, 2 deg) and
  cc ~ Normal(cc_cal, max(2 kPa, 0.25 cc_cal)), truncated to the bounds;
  ln(kc/kphi) ~ Normal(ln(kc_cal/kphi_cal), 0.25) (a factor 1.5 either side
  at 90%), with kphi uniform within its bounds and kc within its bounds; n
  uniform within its bounds (the profile, not the calibration, sets n).
  A calibration with kc = 0 fixes kc = 0.

Sampler
-------
emcee's ensemble sampler [2]_ with differential-evolution moves (80%) and
the affine-invariant stretch move [3]_ (20%), vectorised: one call of the
log posterior evaluates all walkers of a half-ensemble.  The
CI basis columns of eq. (2-7) (kc, kphi and cc coefficients, with and without
the tan(phic) shear part) are tabulated once per profile on a grid of n
(step <= 0.02) and interpolated by cubic splines (relative error ~1e-7), so
finite Kc costs the same as fully mobilised shear.  With fully mobilised
shear the sampler moves in ``(s kc, s kphi, n, cc, phic)``, ``s = 1 +
tan(phic)/tan(15 deg)``, in which the exact phic ridge is a straight
coordinate direction (the Jacobian ``s^-2`` is part of the target density).
Walkers (128) start from a Laplace (Gauss-Newton) approximation around the
exact solver's optimum, regularised by the prior's variances and truncated
to the prior's support; 80 burn-in steps are discarded and the chain is
thinned by 6, so ``draws`` = 2000 takes 94 more steps (defaults).  emcee's
own bookkeeping costs about half a millisecond per step whatever the number
of walkers, so many walkers and few steps are cheaper than the reverse for
the same number of effective samples; the integrated autocorrelation time
is about 15-20 steps, so 2000 draws are worth roughly 600-800 independent
ones, and the interval ends move by about 1% of the interval's width
against a 20000-draw run.  Acceptance fraction and autocorrelation times
are reported, not enforced.

The whitened sum of squares of all walkers is one compiled kernel
(:func:`spline_sse_compiled`, numba; its numpy twin :func:`spline_sse` is
the tested reference and is used when TERRACONE_NUMBA=0).

Identifiability
---------------
``ratio = (posterior 90% width) / (prior 90% width)`` per parameter (the
prior's width from 8000 prior draws, so it is exact for the n-dependent US
bounds and the calibration prior too): ``< 0.25`` "determined", ``< 0.75``
"weakly determined", otherwise "set by prior".  A parameter held fixed
(bounds LO = HI, or kc = 0 from a calibration) is "set by prior".  The
labels are relative to the prior: with the default bounds "determined" kc
may still span a factor of ten.  Under fully mobilised shear with the bounds prior, phic's
posterior is its prior reweighted by ``s^-2`` (the prior volume of the
(kc, kphi) pairs on the ridge), whose 90% width is 0.86 of the prior's: "set
by prior", as it must be.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 2 and 3.
.. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013). emcee:
   the MCMC hammer. PASP 125, 306-312.
.. [3] Goodman, J., Weare, J. (2010). Ensemble samplers with affine
   invariance. Comm. App. Math. Comp. Sci. 5(1), 65-80.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import emcee
import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from . import units as u
from .cone import Cone, cone_index_basis
from .data import CIProfile, TerrainParameters
from .inverse.bounds import Bounds
from .inverse.learn import Calibration
from .inverse.predict import PredictionResult, predict
from .jit import ENABLED as JIT_ENABLED
from .jit import njit
from .plate import PressureLaw, plate_basis, pressure_law

__all__ = [
    "PARAM_NAMES",
    "LABELS",
    "DETERMINED_BELOW",
    "WEAKLY_BELOW",
    "CalibrationPrior",
    "NoiseModel",
    "PlateBand",
    "SamplerDiagnostics",
    "PosteriorResult",
    "posterior",
    "posterior_for_result",
    "estimate_correlation",
    "ar1_coefficients",
    "ar1_noise",
    "identifiability_label",
    "plate_bands",
    "integrated_time",
    "Likelihood",
    "spline_sse",
    "spline_sse_compiled",
]

#: Order of the columns of :attr:`PosteriorResult.samples` (SI).
PARAM_NAMES = ("kc", "kphi", "n", "cc", "phic_deg")
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
#: Largest AR(1) coefficient used.
RHO_MAX = 0.95

_N_PRIOR_DRAWS = 8000


def identifiability_label(ratio: float) -> str:
    """Label of a posterior/prior 90% width ratio (thresholds 0.25 and 0.75)."""
    if not math.isfinite(ratio) or ratio >= WEAKLY_BELOW:
        return LABELS[2]
    return LABELS[0] if ratio < DETERMINED_BELOW else LABELS[1]


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------


@dataclass
class PlateBand:
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

    radius: float
    sinkage: np.ndarray
    median: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """JSON-ready dict (lengths in m or in, pressures in kPa or psi)."""
        units = u.check_system(units)

        def p(a):
            return [float(v) for v in u.pressure_from_si(a, units)]

        return {
            "radius": float(u.length_from_si(self.radius, units)),
            "sinkage": [float(v) for v in u.length_from_si(self.sinkage, units)],
            "median": p(self.median),
            "lo": p(self.lo),
            "hi": p(self.hi),
        }


@dataclass
class NoiseModel:
    """The CI error model used (see the module docstring).

    Attributes
    ----------
    kind : {"relative", "absolute"}
    sigma : float
        RMS noise standard deviation over the profile [kPa]: the given value,
        or the posterior median when estimated.
    sigma_interval : (float, float) or None
        90% interval of sigma [kPa] when estimated.
    sigma_rel : float or None
        With relative noise, sigma relative to the model CI where the floor
        does not matter [-].
    rho : float
        AR(1) coefficient at the reference spacing [-] (the posterior median
        when sampled).
    spacing : float
        Reference (median) spacing dz0 [m].
    floor : float
        Additive floor of the relative model, as a fraction of the largest
        model CI [-].
    sigma_estimated, rho_estimated : bool
    rho_raw : float or None
        Lag-1 autocorrelation of the best-fit residuals before the
        small-sample correction [-].
    weights : ndarray
        w_i, RMS 1 [-].
    rho_interval : (float, float) or None
        90% interval of rho when sampled.
    rho_sampled : bool
        Whether rho was a sampled parameter (``correlation="sample"``).
    """

    kind: str
    sigma: float
    sigma_interval: tuple[float, float] | None
    sigma_rel: float | None
    rho: float
    spacing: float
    floor: float
    sigma_estimated: bool
    rho_estimated: bool
    rho_raw: float | None = None
    weights: np.ndarray | None = None
    rho_interval: tuple[float, float] | None = None
    rho_sampled: bool = False

    @property
    def correlation_length(self) -> float:
        """Depth over which the correlation falls by 1/e, -dz0 / ln(rho) [m] (0 if rho = 0)."""
        if self.rho <= 0:
            return 0.0
        return -self.spacing / math.log(self.rho)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        units = u.check_system(units)

        def p(v):
            return float(u.pressure_from_si(v, units))

        return {
            "model": self.kind,
            "sigma": p(self.sigma),
            "sigma_interval": None
            if self.sigma_interval is None
            else [p(v) for v in self.sigma_interval],
            "sigma_rel": self.sigma_rel,
            "sigma_estimated": self.sigma_estimated,
            "rho": self.rho,
            "rho_estimated": self.rho_estimated,
            "rho_sampled": self.rho_sampled,
            "rho_interval": None if self.rho_interval is None else list(self.rho_interval),
            "rho_raw": self.rho_raw,
            "spacing": float(u.length_from_si(self.spacing, units)),
            "correlation_length": float(u.length_from_si(self.correlation_length, units)),
            "floor": self.floor,
        }


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
            else {k: _num(v) for k, v in self.autocorr_time.items()},
            "autocorr_reliable": self.autocorr_reliable,
            "effective_samples": _num(self.effective_samples),
            "log_prob_evals": self.log_prob_evals,
            "time_s": self.time_s,
            "cpu_s": _num(self.cpu_s),
            "coordinates": self.coordinates,
        }


@dataclass
class PosteriorResult:
    """Posterior of (kc, kphi, n, cc, phic) given one CI profile (SI inside).

    Attributes
    ----------
    id : str
        Profile id.
    samples : ndarray, shape (draws, 5)
        Posterior draws of kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-],
        cc [kPa], phic [deg] (:data:`PARAM_NAMES`).
    medians : dict
        Posterior median per parameter (SI).
    intervals : dict
        Equal-tailed credible interval (lo, hi) per parameter (SI), at
        ``level``.
    prior_intervals : dict
        The same interval of the prior (SI).
    prior_widths, posterior_widths : dict
        hi - lo of the prior and posterior intervals (SI).
    width_ratio : dict
        posterior / prior width [-] (1 for parameters held fixed).
    identifiability : dict
        "determined" (ratio < 0.25), "weakly determined" (< 0.75) or "set
        by prior".
    plate_bands : list of PlateBand
    noise : NoiseModel
    diagnostics : SamplerDiagnostics
    prior : str
        "bounds" or "calibration:<terrain>".
    model : {"rm0", "rm1"}
    r_min : float or None
        [m]
    Kc : float or None
        [m]
    level : float
        Credibility level of the intervals and bands [-].
    best_fit : TerrainParameters
        The exact solver's optimum the walkers started from.
    notes : list of str
        Warnings of the run (low acceptance, few effective samples, ...).
    prior_samples : ndarray, shape (2000, 5)
        Prior draws (SI), for the prior intervals in US units.
    """

    id: str
    samples: np.ndarray
    medians: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    prior_intervals: dict[str, tuple[float, float]]
    prior_widths: dict[str, float]
    posterior_widths: dict[str, float]
    width_ratio: dict[str, float]
    identifiability: dict[str, str]
    plate_bands: list[PlateBand]
    noise: NoiseModel
    diagnostics: SamplerDiagnostics
    prior: str
    model: str
    r_min: float | None
    Kc: float | None
    level: float
    best_fit: TerrainParameters
    notes: list[str] = field(default_factory=list)
    prior_samples: np.ndarray | None = field(default=None, repr=False)

    def _quantiles(self, samples: np.ndarray, units: str) -> dict[str, tuple[float, float, float]]:
        """(lo, median, hi) per parameter, each sample converted with its own n."""
        conv = _convert_samples(samples, units)
        q = [(1 - self.level) / 2, 0.5, (1 + self.level) / 2]
        out = {}
        for j, name in enumerate(PARAM_NAMES):
            lo, med, hi = np.quantile(conv[:, j], q)
            out[name] = (float(lo), float(med), float(hi))
        return out

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
        q = self._quantiles(self.samples, units)
        d: dict[str, Any] = {
            "intervals": {k: [v[0], v[2]] for k, v in q.items()},
            "medians": {k: v[1] for k, v in q.items()},
            "identifiability": dict(self.identifiability),
            "plate_bands": [b.as_dict(units) for b in self.plate_bands],
        }
        if units == "si":
            prior_iv = {k: [float(v[0]), float(v[1])] for k, v in self.prior_intervals.items()}
        elif self.prior_samples is not None:
            qp = self._quantiles(self.prior_samples, units)
            prior_iv = {k: [v[0], v[2]] for k, v in qp.items()}
        else:
            prior_iv = None
        d["posterior"] = {
            "level": self.level,
            "prior": self.prior,
            "model": self.model,
            "r_min": None if self.r_min is None else float(u.length_from_si(self.r_min, units)),
            "Kc": None if self.Kc is None else float(u.length_from_si(self.Kc, units)),
            "width_ratio": {k: _num(v) for k, v in self.width_ratio.items()},
            "thresholds": {"determined": DETERMINED_BELOW, "weakly determined": WEAKLY_BELOW},
            "prior_intervals": prior_iv,
            "noise": self.noise.as_dict(units),
            "sampler": self.diagnostics.as_dict(),
            "notes": list(self.notes),
            "units": units,
        }
        return d

    def samples_dict(self, units: str = "si") -> dict[str, Any]:
        """The posterior draws for JSON: ``{"names", "units", "values"}``.

        ``values`` is a list of rows (kc, kphi, n, cc, phic_deg), each draw
        converted with its own n; the key ``samples`` of ``predict
        --uncertainty --json``, read back by :func:`terracone.export.load_results`.
        """
        units = u.check_system(units)
        return {
            "names": list(PARAM_NAMES),
            "units": units,
            "values": _convert_samples(self.samples, units).tolist(),
        }

    def params_at(self, index: int) -> TerrainParameters:
        """One posterior draw as :class:`TerrainParameters`."""
        kc, kphi, n, cc, phic = (float(v) for v in self.samples[index])
        return TerrainParameters(kc, kphi, n, cc, phic, self.Kc, self.model, self.r_min)


def _num(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _convert_samples(samples: np.ndarray, units: str) -> np.ndarray:
    units = u.check_system(units)
    out = np.array(samples, dtype=float, copy=True)
    if units == "si":
        return out
    n = out[:, 2]
    out[:, 0] = u.kc_from_si(out[:, 0], n, units)
    out[:, 1] = u.kphi_from_si(out[:, 1], n, units)
    out[:, 3] = u.pressure_from_si(out[:, 3], units)
    return out


# ---------------------------------------------------------------------------
# priors
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class CalibrationPrior:
    """Prior centred on a learned calibration (section 3.3.1 of [1]_).

    Attributes
    ----------
    calibration : Calibration
        Fixes model, r_min and the plate pair.
    phic_sd : float
        Standard deviation of the normal prior of phic around the
        calibration's value [deg] (Table 4-1 of [1]_ spreads 10-12.5 deg
        over four LETE profiles).
    cc_sd : float or None
        Standard deviation of the normal prior of cc [kPa]; None:
        max(2 kPa, 0.25 * cc_cal).
    ratio_log_sd : float
        Standard deviation of ln(kc/kphi) around the calibration's ratio
        [-] (0.25: a factor 1.5 either way at 90%; the LETE profiles of
        Table 4-1 span 0.017-0.026 m).
    """

    calibration: Calibration
    phic_sd: float = 2.0
    cc_sd: float | None = None
    ratio_log_sd: float = 0.25

    def __post_init__(self) -> None:
        if not (self.phic_sd >= 0 and self.ratio_log_sd > 0):
            raise ValueError("phic_sd must be >= 0 and ratio_log_sd > 0")
        if self.cc_sd is not None and self.cc_sd < 0:
            raise ValueError("cc_sd must be >= 0")

    @property
    def cc_width(self) -> float:
        """The standard deviation of cc actually used [kPa]."""
        if self.cc_sd is not None:
            return float(self.cc_sd)
        return max(2.0, 0.25 * float(self.calibration.cc))


class _Prior:
    """Prior density and sampler over (kc, kphi, n, cc, phic), SI."""

    def __init__(self, bounds: Bounds, cal: CalibrationPrior | None) -> None:
        self.b = bounds
        self.cal = cal
        self._si = bounds.kc_units == "si" and bounds.kphi_units == "si"
        c = cal.calibration if cal is not None else None
        self.kc_fixed = bounds.kc[0] == bounds.kc[1] or (c is not None and c.kc <= 0)
        self.kphi_fixed = bounds.kphi[0] == bounds.kphi[1] or (c is not None and c.kphi <= 0)
        self.n_fixed = bounds.n[0] == bounds.n[1]
        self.cc_fixed = bounds.cc[0] == bounds.cc[1] or (cal is not None and cal.cc_width == 0)
        self.phic_fixed = bounds.phic[0] == bounds.phic[1] or (cal is not None and cal.phic_sd == 0)
        self.ratio = (
            c is not None and not self.kc_fixed and not self.kphi_fixed and c.kc > 0 and c.kphi > 0
        )
        if self.ratio:
            self.log_q0 = math.log(c.kc / c.kphi)
        if c is not None:
            if self.cc_fixed and bounds.cc[0] != bounds.cc[1]:
                self.cc_value = float(np.clip(c.cc, *bounds.cc))
            else:
                self.cc_value = float(bounds.cc[0])
            if self.phic_fixed and bounds.phic[0] != bounds.phic[1]:
                self.phic_value = float(np.clip(c.phic_deg, *bounds.phic))
            else:
                self.phic_value = float(bounds.phic[0])
        else:
            self.cc_value = float(bounds.cc[0])
            self.phic_value = float(bounds.phic[0])
        self.n_grid: np.ndarray | None = None
        self.n_logw: np.ndarray | None = None
        if c is not None and c.kc <= 0 and bounds.kc[0] > 0:
            raise ValueError("the calibration has kc = 0 but the kc bounds exclude 0")
        if c is not None and c.kphi <= 0 and bounds.kphi[0] > 0:
            raise ValueError("the calibration has kphi = 0 but the kphi bounds exclude 0")

    def describe(self) -> str:
        if self.cal is None:
            return "bounds"
        return f"calibration:{self.cal.calibration.terrain}"

    def set_reference(self, grid: np.ndarray, logw: np.ndarray) -> None:
        """Weight the bounds prior by sqrt(det G(n)) (``logw`` on ``grid``; module docstring).

        The joint density becomes sqrt(det G(n)) in SI (kc, kphi) inside the
        box (no longer normalised per n), which does not depend on the
        units the bounds were given in.
        """
        if self.cal is not None or self.n_fixed:
            return
        ok = np.isfinite(logw)
        if not ok.any():
            return
        self.n_grid = np.asarray(grid, float)
        self.n_logw = np.where(ok, logw, np.min(logw[ok]) - 50.0) - np.max(logw[ok])

    def n_log_weight(self, n: np.ndarray) -> np.ndarray:
        """log sqrt(det G(n)) up to a constant (0 without the reference weight)."""
        if self.n_logw is None:
            return np.zeros(np.shape(n))
        return np.interp(n, self.n_grid, self.n_logw)

    def _sample_n(self, rng: np.random.Generator, m: int) -> np.ndarray:
        b = self.b
        if self.n_logw is None:
            return rng.uniform(*b.n, m)
        g = np.linspace(b.n[0], b.n[1], 2001)
        d = np.exp(self.n_log_weight(g))
        if not self.kc_fixed:
            lo, hi = b.kc_si(g)
            d = d * (hi - lo)
        if not self.kphi_fixed:
            lo, hi = b.kphi_si(g)
            d = d * (hi - lo)
        cdf = np.concatenate([[0.0], np.cumsum(0.5 * (d[1:] + d[:-1]) * np.diff(g))])
        return np.interp(rng.uniform(0, cdf[-1], m), cdf, g)

    def kc_fixed_value(self, n: np.ndarray) -> np.ndarray:
        if self.cal is not None and self.cal.calibration.kc <= 0:
            return np.zeros_like(n)
        return self.b.kc_si(n)[0]

    def kphi_fixed_value(self, n: np.ndarray) -> np.ndarray:
        if self.cal is not None and self.cal.calibration.kphi <= 0:
            return np.zeros_like(n)
        return self.b.kphi_si(n)[0]

    def logpdf(self, kc, kphi, n, cc, phic) -> np.ndarray:
        """Log prior density (up to a constant) of arrays of parameters."""
        b = self.b
        lp = np.zeros(np.shape(n))
        inside = np.ones(np.shape(n), bool)
        if not self.n_fixed:
            inside &= (n >= b.n[0]) & (n <= b.n[1])
        if self._si:
            kc_lo, kc_hi = b.kc
            kp_lo, kp_hi = b.kphi
        else:
            nn = np.clip(n, b.n[0], b.n[1])
            kc_lo, kc_hi = b.kc_si(nn)
            kp_lo, kp_hi = b.kphi_si(nn)
        if not self.kc_fixed:
            inside &= (kc >= kc_lo) & (kc <= kc_hi)
        ref = self.n_logw is not None
        if ref:
            lp = lp + self.n_log_weight(n)
        if not self.kphi_fixed:
            inside &= (kphi >= kp_lo) & (kphi <= kp_hi)
            if not ref:
                lp = lp - np.log(kp_hi - kp_lo)
        if not self.cc_fixed:
            inside &= (cc >= b.cc[0]) & (cc <= b.cc[1])
        if not self.phic_fixed:
            inside &= (phic >= b.phic[0]) & (phic <= b.phic[1])
        if self.cal is None:
            if not self.kc_fixed and not ref:
                lp = lp - np.log(kc_hi - kc_lo)
        else:
            c = self.cal
            if self.ratio:
                with np.errstate(divide="ignore", invalid="ignore"):
                    z = (np.log(kc) - np.log(kphi) - self.log_q0) / c.ratio_log_sd
                    lp += -0.5 * z * z - np.log(kc)
                inside &= (kc > 0) & (kphi > 0)
            elif not self.kc_fixed:
                lp = lp - np.log(kc_hi - kc_lo)
            if not self.cc_fixed:
                z = (cc - c.calibration.cc) / c.cc_width
                lp += -0.5 * z * z
            if not self.phic_fixed:
                z = (phic - c.calibration.phic_deg) / c.phic_sd
                lp += -0.5 * z * z
        lp = np.where(inside & np.isfinite(lp), lp, -np.inf)
        return lp

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """Draws (size, 5) from the prior, SI."""
        b = self.b
        out = np.empty((0, 5))
        for _ in range(200):
            m = 2 * size
            n = np.full(m, b.n[0]) if self.n_fixed else self._sample_n(rng, m)
            kp_lo, kp_hi = b.kphi_si(n)
            kc_lo, kc_hi = b.kc_si(n)
            kphi = self.kphi_fixed_value(n) if self.kphi_fixed else rng.uniform(kp_lo, kp_hi)
            if self.ratio:
                q = np.exp(self.log_q0 + self.cal.ratio_log_sd * rng.standard_normal(m))
                kc = q * kphi
            elif self.kc_fixed:
                kc = self.kc_fixed_value(n)
            else:
                kc = rng.uniform(kc_lo, kc_hi)
            if self.cc_fixed:
                cc = np.full(m, self.cc_value)
            elif self.cal is None:
                cc = rng.uniform(*b.cc, m)
            else:
                cc = self.cal.calibration.cc + self.cal.cc_width * rng.standard_normal(m)
            if self.phic_fixed:
                phic = np.full(m, self.phic_value)
            elif self.cal is None:
                phic = rng.uniform(*b.phic, m)
            else:
                phic = self.cal.calibration.phic_deg + self.cal.phic_sd * rng.standard_normal(m)
            x = np.stack([kc, kphi, n, cc, phic], axis=1)
            ok = np.isfinite(self.logpdf(kc, kphi, n, cc, phic))
            out = np.concatenate([out, x[ok]])
            if out.shape[0] >= size:
                return out[:size]
        raise ValueError("the prior has (almost) no mass inside the bounds")


def _as_cal_prior(prior: Any) -> CalibrationPrior | None:
    if isinstance(prior, str):
        if prior != "bounds":
            raise ValueError(
                f"prior must be 'bounds', a Calibration or a CalibrationPrior (got {prior!r})"
            )
        return None
    if prior is None:
        return None
    if isinstance(prior, CalibrationPrior):
        return prior
    if isinstance(prior, Calibration):
        return CalibrationPrior(prior)
    raise TypeError(f"prior must be 'bounds', a Calibration or a CalibrationPrior (got {prior!r})")


# ---------------------------------------------------------------------------
# noise: weights and AR(1)
# ---------------------------------------------------------------------------


def ar1_coefficients(depth: ArrayLike, rho: float, spacing: float | None = None) -> np.ndarray:
    """Lag-1 coefficients phi_i = rho**(Delta_i / dz0) between neighbouring readings.

    Parameters
    ----------
    depth : array_like
        Increasing depths [m].
    rho : float
        Correlation at the reference spacing [-], 0 <= rho < 1.
    spacing : float, optional
        Reference spacing dz0 [m]; the median spacing by default.

    Returns
    -------
    ndarray, shape (N - 1,)
    """
    z = np.asarray(depth, dtype=float)
    dz = np.diff(z)
    if dz.size == 0:
        return dz
    dz0 = float(np.median(dz)) if spacing is None else float(spacing)
    if not 0 <= rho < 1:
        raise ValueError(f"rho must satisfy 0 <= rho < 1 (got {rho})")
    if rho == 0:
        return np.zeros_like(dz)
    return rho ** (dz / dz0)


def ar1_noise(
    depth: ArrayLike,
    rho: float,
    rng: np.random.Generator,
    *,
    spacing: float | None = None,
    size: int | None = None,
) -> np.ndarray:
    """Standard-normal AR(1) noise along depth, the correlation model of :func:`posterior`.

    Parameters
    ----------
    depth : array_like
        Increasing depths [m].
    rho : float
        Correlation of neighbours at the reference spacing [-].
    rng : numpy.random.Generator
    spacing : float, optional
        Reference spacing [m]; the median spacing by default.
    size : int, optional
        Number of independent series (rows); one 1-D series when None.

    Returns
    -------
    ndarray
        Unit-variance series with corr(e_i, e_j) = rho**(|z_i - z_j| / dz0).
    """
    z = np.asarray(depth, dtype=float)
    phi = ar1_coefficients(z, rho, spacing)
    m = 1 if size is None else int(size)
    w = rng.standard_normal((m, z.size))
    e = np.empty_like(w)
    e[:, 0] = w[:, 0]
    c = np.sqrt(1.0 - phi * phi)
    for i in range(1, z.size):
        e[:, i] = phi[i - 1] * e[:, i - 1] + c[i - 1] * w[:, i]
    return e[0] if size is None else e


def _whiten(v: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Whitening of AR(1) along the last axis: u_1 = v_1, u_i = (v_i - phi v_{i-1})/sqrt(1-phi^2)."""
    if not np.any(phi):
        return np.array(v, dtype=float, copy=True)
    out = np.empty(np.shape(v))
    out[..., 0] = v[..., 0]
    out[..., 1:] = (v[..., 1:] - phi * v[..., :-1]) / np.sqrt(1.0 - phi * phi)
    return out


def estimate_correlation(
    residuals: ArrayLike,
    depth: ArrayLike,
    *,
    design: np.ndarray | None = None,
    n_params: int = 4,
) -> tuple[float, float]:
    """AR(1) coefficient of the CI error from best-fit (weighted) residuals.

    The lag-1 autocorrelation of the (mean-removed) residuals,
    ``r1 = sum e_i e_(i-1) / sum e_i^2``, underestimates the correlation of
    the errors: the fit absorbs the smooth part of a correlated error (a
    correlated error looks like a slightly different terrain).  The
    correction inverts the expected r1 of the fitted residuals,

        f(rho) = tr(D M S(rho) M) / tr(M S(rho) M),

    with ``S(rho)_ij = rho**(|z_i - z_j| / dz0)`` the AR(1) correlation at the
    actual depths (so irregular spacing is accounted for), ``M = I - P`` the
    residual maker of the linearised fit (``P`` the projector on the columns
    of ``design`` and a constant) and ``D`` the lag-1 neighbour matrix
    (1/2 on both off-diagonals): ``rho = f^-1(r1)``, clipped to [0, 0.95].
    Without ``design`` the fallback ``r1 + (1 + (3 + 2 n_params) r1+) / N``
    (small-sample bias plus absorption, calibrated on 31-61 point profiles)
    is used.

    Parameters
    ----------
    residuals : array_like
        Residuals divided by their noise weights, in depth order [-].
    depth : array_like
        Depths of the readings [m].
    design : ndarray, shape (N, p), optional
        Weighted Jacobian of the model at the fit with respect to the
        parameters that are free there (not at a bound).
    n_params : int
        Number of fitted parameters for the fallback.

    Returns
    -------
    rho, r1 : float
        The estimate at the median spacing dz0 and the raw lag-1
        autocorrelation.
    """
    e = np.asarray(residuals, dtype=float)
    z = np.asarray(depth, dtype=float)
    N = e.size
    if N < 6:
        return 0.0, float("nan")
    e = e - e.mean()
    den = float(e @ e)
    if den <= 0:
        return 0.0, float("nan")
    r1 = float(e[1:] @ e[:-1]) / den
    dz0 = float(np.median(np.diff(z)))
    if design is None or dz0 <= 0:
        rho = r1 + (1.0 + (3.0 + 2.0 * n_params) * max(r1, 0.0)) / N
        return float(np.clip(rho, 0.0, RHO_MAX)), r1
    X = np.column_stack([np.ones(N), np.asarray(design, dtype=float).reshape(N, -1)])
    X = X / np.maximum(np.linalg.norm(X, axis=0), 1e-300)
    U, sv, _ = np.linalg.svd(X, full_matrices=False)
    Uq = U[:, sv > 1e-8 * sv[0]]
    M = np.eye(N) - Uq @ Uq.T
    grid = np.linspace(0.0, RHO_MAX, 96)
    lag = np.abs(z[:, None] - z[None, :]) / dz0
    f = np.empty(grid.size)
    for k, rho in enumerate(grid):
        S = rho**lag if rho > 0 else np.eye(N)
        MSM = M @ S @ M
        f[k] = np.trace(MSM, offset=1) / np.trace(MSM)
    f = np.maximum.accumulate(f)  # monotone (it is, up to rounding)
    if r1 <= f[0]:
        return 0.0, r1
    if r1 >= f[-1]:
        return RHO_MAX, r1
    return float(np.interp(r1, f, grid)), r1


# ---------------------------------------------------------------------------
# the likelihood: tabulated, whitened basis columns
# ---------------------------------------------------------------------------


def spline_sse(
    coef: np.ndarray,
    n0: float,
    h: float,
    wy: np.ndarray,
    params: np.ndarray,
    t: float,
    rho: np.ndarray,
    dzr: np.ndarray,
) -> np.ndarray:
    """Whitened sum of squares of parameter rows against tabulated basis columns (numpy).

    The reference implementation of :func:`spline_sse_compiled` (the
    log-likelihood kernel of :func:`posterior`).  The model CI of eq. (2-7)
    is ``s (kc A + kphi B) + cc C`` with ``s = 1 + tan(phic)/t`` (fully
    mobilised shear, eq. (2-6); K = 3 columns) or ``kc (A_p + tan(phic)
    A_s) + kphi (B_p + tan(phic) B_s) + cc C`` (finite Kc; K = 5), with
    every column already divided by the noise weights and whitened, and
    tabulated over n as a cubic spline.

    Parameters
    ----------
    coef : ndarray, shape (4, G, Z, K)
        Spline coefficients on the uniform grid ``n0 + h * i`` (highest
        power first, as :class:`scipy.interpolate.CubicSpline` stores them)
        [kPa per unit parameter].
    n0, h : float
        First grid node and step of n [-].
    wy : ndarray, shape (Z,)
        Whitened, weighted measured CI [kPa].
    params : ndarray, shape (P, 5)
        kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-], cc [kPa], phic [deg].
    t : float
        tan of the cone half angle [-].
    rho : ndarray, shape (P,) or (0,)
        AR(1) coefficient per row when it is sampled (the whitening of the
        columns then happens here, row by row); empty otherwise.
    dzr : ndarray, shape (Z - 1,)
        Spacings over the reference spacing [-].

    Returns
    -------
    ndarray, shape (P,)
        Sum of squared whitened residuals [kPa^2].

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.
       Predicting terrain parameters for physics-based vehicle mobility
       models from cone index data. Eqs. (2-6), (2-7).
    """
    kc, kphi, n, cc, phic = (params[:, j] for j in range(5))
    i = np.clip(((n - n0) / h).astype(np.int64), 0, coef.shape[1] - 1)
    dx = (n - (n0 + i * h))[:, None, None]
    c = coef[:, i]  # (4, P, Z, K)
    col = ((c[0] * dx + c[1]) * dx + c[2]) * dx + c[3]
    tau = np.tan(phic * (math.pi / 180.0))[:, None]
    if coef.shape[3] == 3:  # eq. (2-6): the shear part is the normal part / t
        s = 1.0 + tau / t
        r = (s * kc[:, None]) * col[..., 0] + (s * kphi[:, None]) * col[..., 1]
        r = r + cc[:, None] * col[..., 2] - wy
    else:  # eq. (2-7)
        r = (
            kc[:, None] * (col[..., 0] + tau * col[..., 1])
            + kphi[:, None] * (col[..., 2] + tau * col[..., 3])
            + cc[:, None] * col[..., 4]
        ) - wy
    if rho.size and wy.size > 1:
        phi = rho[:, None] ** dzr
        r[:, 1:] = (r[:, 1:] - phi * r[:, :-1]) / np.sqrt(1.0 - phi * phi)
    return np.sum(r * r, axis=1)


@njit
def spline_sse_compiled(coef, n0, h, wy, params, t, rho, dzr):  # pragma: no cover - numba
    """:func:`spline_sse` compiled with numba (one pass per row, no temporaries).

    Agrees with :func:`spline_sse` to rounding (tests: 1e-12 relative).
    With TERRACONE_NUMBA=0 this is plain Python; :func:`posterior` then
    calls :func:`spline_sse` instead.
    """
    P = params.shape[0]
    G = coef.shape[1]
    Z = wy.shape[0]
    K = coef.shape[3]
    out = np.empty(P)
    col = np.empty(K)
    for p in range(P):
        kc, kphi, n, cc, phic = params[p, 0], params[p, 1], params[p, 2], params[p, 3], params[p, 4]
        i = int((n - n0) / h)
        i = min(max(i, 0), G - 1)
        dx = n - (n0 + i * h)
        tau = math.tan(phic * (math.pi / 180.0))
        s = 1.0 + tau / t
        acc = 0.0
        prev = 0.0
        for z in range(Z):
            for k in range(K):
                col[k] = ((coef[0, i, z, k] * dx + coef[1, i, z, k]) * dx + coef[2, i, z, k]) * dx
                col[k] += coef[3, i, z, k]
            if K == 3:  # eq. (2-6)
                r = (s * kc) * col[0] + (s * kphi) * col[1]
                r = r + cc * col[2] - wy[z]
            else:  # eq. (2-7)
                r = kc * (col[0] + tau * col[1]) + kphi * (col[2] + tau * col[3]) + cc * col[4]
                r = r - wy[z]
            if rho.shape[0] > 0 and z > 0:
                phi = rho[p] ** dzr[z - 1]
                u = (r - phi * prev) / math.sqrt(1.0 - phi * phi)
            else:
                u = r
            prev = r
            acc += u * u
        out[p] = acc
    return out


class Likelihood:
    """Whitened residuals of arrays of parameter sets against one profile.

    CI = kc (A_p + tan(phic) A_s) + kphi (B_p + tan(phic) B_s) + cc C, eq.
    (2-7), where _p is the normal-pressure and _s the shear part; the
    columns are whitened (divided by w, AR(1)) and tabulated over n.  With
    fully mobilised shear A_s = A_p / tan(half angle) (likewise B), so three
    columns are kept and CI = s (kc A_p + kphi B_p) + cc C.

    Parameters
    ----------
    z, y : ndarray
        Depths [m] and measured CI [kPa].
    cone : Cone
    law : PressureLaw
    Kc : float or None
        Cone-terrain shear deformation parameter [m]; None: fully mobilised.
    n_range : (float, float)
        Range of n tabulated [-] (one value: n fixed).
    weights : ndarray
        Noise weights w_i, RMS 1 [-].
    phi : ndarray or None
        AR(1) lag-1 coefficients between neighbours (N - 1,); None when rho
        is sampled (whitening per parameter row in :meth:`sse`).
    spacing : float, optional
        Reference spacing dz0 [m] of a sampled rho.

    Attributes
    ----------
    coef : ndarray, shape (4, G, Z, K)
        Spline coefficients of the whitened columns over n (for
        :func:`spline_sse`); ``n0``, ``h`` its grid.
    wy : ndarray
        Whitened, weighted CI [kPa].

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.
       Predicting terrain parameters for physics-based vehicle mobility
       models from cone index data. Eqs. (2-6), (2-7).
    """

    def __init__(
        self,
        z: np.ndarray,
        y: np.ndarray,
        *,
        cone: Cone,
        law: PressureLaw,
        Kc: float | None,
        n_range: tuple[float, float],
        weights: np.ndarray,
        phi: np.ndarray | None,
        spacing: float | None = None,
    ) -> None:
        self.z, self.y, self.cone, self.law, self.Kc = z, y, cone, law, Kc
        self.t = math.tan(cone.half_angle)
        self.w = weights
        self.N = y.size
        # phi None: rho varies per parameter set (sampled), whiten per row
        self.per_row = phi is None
        dz = np.diff(z)
        self.dzr = dz / (float(np.median(dz)) if spacing is None else spacing) if dz.size else dz
        if phi is None:
            phi = np.zeros(max(self.N - 1, 0))
        self.phi = phi
        self.fixed_n = n_range[0] == n_range[1]
        if self.fixed_n:
            grid = np.array([n_range[0]])
        else:
            k = max(33, int(math.ceil((n_range[1] - n_range[0]) / 0.02)) + 1)
            grid = np.linspace(n_range[0], n_range[1], k)
        cols = self._columns(grid)  # (G, Z, K), K = 3 or 5
        wcols = _whiten(np.moveaxis(cols / weights[None, :, None], 1, -1), phi)  # (G, K, Z)
        wcols = np.moveaxis(wcols, -1, 1)  # (G, Z, K)
        self.wy = _whiten(y / weights, phi)
        self.grid, self.wcols = grid, wcols
        if self.fixed_n:  # a constant "spline": only the last coefficient
            self.coef = np.zeros((4, 1) + wcols.shape[1:])
            self.coef[3, 0] = wcols[0]
            self.n0, self.h = float(grid[0]), 1.0
        else:
            # cubic spline on the uniform grid, evaluated by Horner's rule on gathered coefficients
            self.coef = np.ascontiguousarray(CubicSpline(grid, wcols, axis=0).c)  # (4, G-1, Z, K)
            self.n0, self.h = float(grid[0]), float(grid[1] - grid[0])
        self.dzr = np.ascontiguousarray(self.dzr, dtype=float)
        self.wy = np.ascontiguousarray(self.wy, dtype=float)

    def _columns(self, n: np.ndarray) -> np.ndarray:
        nn = np.asarray(n, dtype=float)[:, None]
        kw = dict(n=nn, Kc=self.Kc, law=self.law, cone=self.cone)
        A0, B0, C0 = cone_index_basis(self.z, phic=0.0, **kw)
        if self.Kc is None:
            # fully mobilised: the shear part is the normal part / tan(half angle), eq. (2-6)
            A0, B0, C0 = np.broadcast_arrays(A0, B0, C0)
            return np.stack([A0, B0, C0], axis=-1)
        A1, B1, _ = cone_index_basis(self.z, phic=45.0, **kw)  # tan 45 deg = 1
        A0, B0, C0, A1, B1 = np.broadcast_arrays(A0, B0, C0, A1, B1)
        return np.stack([A0, A1 - A0, B0, B1 - B0, C0], axis=-1)

    def columns(self, n: np.ndarray) -> np.ndarray:
        """Whitened columns at n, (P, Z, K)."""
        n = np.asarray(n, dtype=float)
        i = np.clip(((n - self.n0) / self.h).astype(np.int64), 0, self.coef.shape[1] - 1)
        dx = (n - (self.n0 + i * self.h))[:, None, None]
        c = self.coef[:, i]  # (4, P, Z, K)
        return ((c[0] * dx + c[1]) * dx + c[2]) * dx + c[3]

    def residuals(self, kc, kphi, n, cc, phic, rho=None) -> np.ndarray:
        """Whitened residuals u (P, Z) of parameter arrays (P,) (and rho (P,) if sampled)."""
        c = self.columns(n)
        tau = np.tan(np.radians(phic))[:, None]
        if self.Kc is None:
            s = 1.0 + tau / self.t
            m = (s * kc[:, None]) * c[..., 0] + (s * kphi[:, None]) * c[..., 1]
            r = m + cc[:, None] * c[..., 2] - self.wy
        else:
            m = (
                kc[:, None] * (c[..., 0] + tau * c[..., 1])
                + kphi[:, None] * (c[..., 2] + tau * c[..., 3])
                + cc[:, None] * c[..., 4]
            )
            r = m - self.wy
        if self.per_row and rho is not None and self.N > 1:
            phi = np.asarray(rho, dtype=float)[:, None] ** self.dzr
            r[:, 1:] = (r[:, 1:] - phi * r[:, :-1]) / np.sqrt(1.0 - phi * phi)
        return r

    def sse(self, params: np.ndarray, rho: np.ndarray | None = None) -> np.ndarray:
        """Whitened sum of squares Q of parameter rows (P, 5) (and rho (P,) if sampled)."""
        params = np.ascontiguousarray(params, dtype=float)
        r = np.zeros(0) if rho is None or not self.per_row else np.asarray(rho, dtype=float)
        kernel = spline_sse_compiled if JIT_ENABLED else spline_sse
        return kernel(self.coef, self.n0, self.h, self.wy, params, self.t, r, self.dzr)

    def gram_half_logdet(self, free: Sequence[bool], phic_deg: float = 0.0) -> np.ndarray:
        """0.5 log det G(n) on the n grid (G,), G the Gram matrix of the free linear columns.

        ``free`` flags kc, kphi, cc.  Fully mobilised shear: the columns of
        (s kc, s kphi, cc) (s does not depend on n); finite Kc: those of (kc,
        kphi, cc) at ``phic_deg``.  sqrt(det G(n)) is the Jeffreys prior of
        the linear parameters given n (invariant to n-dependent unit
        changes of kc and kphi); with it, the marginal posterior of n under
        flat linear parameters is the profile likelihood of n (the
        det G^(-1/2) of the Gaussian integral cancels).
        """
        c = self.wcols
        if self.Kc is not None:
            tau = math.tan(math.radians(phic_deg))
            c = np.stack([c[..., 0] + tau * c[..., 1], c[..., 2] + tau * c[..., 3], c[..., 4]], -1)
        c = c[..., np.asarray(free, bool)]
        if c.shape[-1] == 0:
            return np.zeros(self.grid.size)
        G = np.einsum("gzk,gzl->gkl", c, c)
        sign, logdet = np.linalg.slogdet(G)
        return np.where(sign > 0, 0.5 * logdet, -np.inf)

    def half_logdet(self, rho: np.ndarray) -> np.ndarray:
        """0.5 log det of the AR(1) correlation matrix at rho (P,): 0.5 sum log(1 - phi^2)."""
        if self.N < 2:
            return np.zeros(np.shape(rho))
        phi = np.asarray(rho, dtype=float)[:, None] ** self.dzr
        return 0.5 * np.sum(np.log1p(-phi * phi), axis=1)


# ---------------------------------------------------------------------------
# the sampling coordinates
# ---------------------------------------------------------------------------


class _Coordinates:
    """Map between sampler coordinates x (free subset) and parameters (SI).

    Scaled coordinates (fully mobilised shear, phic free): x = (s kc, s kphi,
    n, cc, phic), s = 1 + tan(phic)/tan(half angle), in which the exact phic
    ridge is a coordinate direction; plain (kc, kphi, n, cc, phic) otherwise.
    (Whitening the linear coordinates conditionally on n was tried and did
    not shorten the autocorrelation: the posterior is mostly bounded by the
    prior box in the directions the data leave free.)
    """

    def __init__(self, prior: _Prior, cone: Cone, Kc: float | None, fixed_values: np.ndarray):
        self.prior = prior
        self.t = math.tan(cone.half_angle)
        nb = np.array(prior.b.n, dtype=float)
        kc_nonzero_fixed = prior.kc_fixed and not np.all(prior.kc_fixed_value(nb) == 0)
        kphi_nonzero_fixed = prior.kphi_fixed and not np.all(prior.kphi_fixed_value(nb) == 0)
        self.scaled = (
            Kc is None and not prior.phic_fixed and not kc_nonzero_fixed and not kphi_nonzero_fixed
        )
        self.free = np.array(
            [
                not prior.kc_fixed,
                not prior.kphi_fixed,
                not prior.n_fixed,
                not prior.cc_fixed,
                not prior.phic_fixed,
            ]
        )
        self.nscale = int(self.free[0]) + int(self.free[1])
        self.fixed_values = np.asarray(fixed_values, dtype=float)
        self.names = [
            (("s*" if self.scaled and i < 2 else "") + PARAM_NAMES[i])
            for i in range(5)
            if self.free[i]
        ]

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
            P[:, 0] /= s
            P[:, 1] /= s
            logj = -self.nscale * np.log(s)
        if self.prior.kc_fixed:
            P[:, 0] = self.prior.kc_fixed_value(P[:, 2])
        if self.prior.kphi_fixed:
            P[:, 1] = self.prior.kphi_fixed_value(P[:, 2])
        return P, logj

    def from_params(self, params: np.ndarray) -> np.ndarray:
        """Free coordinates of parameter rows (P, 5)."""
        X = np.array(np.atleast_2d(params), dtype=float, copy=True)
        if self.scaled:
            s = 1.0 + np.tan(np.radians(X[:, 4])) / self.t
            X[:, 0] *= s
            X[:, 1] *= s
        return X[:, self.free]


# ---------------------------------------------------------------------------
# posterior
# ---------------------------------------------------------------------------


def _fit_design(
    z: np.ndarray,
    p0: TerrainParameters,
    bounds: Bounds,
    cal: Calibration | None,
    law: PressureLaw,
    Kc: float | None,
    cone: Cone,
) -> np.ndarray:
    """Jacobian (N, p) of the model CI at the best fit w.r.t. the parameters the fit moved.

    Linear parameters at a bound, and those a calibration fixes, are left
    out; with a calibration kc and kphi move together (fixed ratio).
    """
    kw = dict(phic=p0.phic_deg, Kc=Kc, law=law, cone=cone)
    A, B, C = (np.broadcast_to(c, z.shape) for c in cone_index_basis(z, n=p0.n, **kw))
    cols = []

    def inside(v, lo, hi):
        tol = 1e-9 * max(abs(lo), abs(hi), 1.0)
        return lo + tol < v < hi - tol

    kc_lo, kc_hi = (float(v) for v in bounds.kc_si(p0.n))
    kp_lo, kp_hi = (float(v) for v in bounds.kphi_si(p0.n))
    if cal is not None and cal.kphi > 0 and cal.kc > 0:
        if inside(p0.kphi, kp_lo, kp_hi):
            cols.append((cal.kc / cal.kphi) * A + B)
    else:
        if inside(p0.kc, kc_lo, kc_hi):
            cols.append(A)
        if inside(p0.kphi, kp_lo, kp_hi):
            cols.append(B)
        if cal is None and inside(p0.cc, *bounds.cc):
            cols.append(C)
    if inside(p0.n, *bounds.n):
        h = 1e-5
        mm = [
            p0.kc * a + p0.kphi * b + p0.cc * c
            for a, b, c in (cone_index_basis(z, n=p0.n + d, **kw) for d in (h, -h))
        ]
        cols.append((mm[0] - mm[1]) / (2 * h))
    return np.column_stack(cols) if cols else np.zeros((z.size, 0))


def _start_params(start: Any) -> TerrainParameters:
    if isinstance(start, PredictionResult):
        if not start.ok or start.params is None:
            raise ValueError(f"profile {start.id}: prediction failed: {start.error}")
        return start.params
    if isinstance(start, TerrainParameters):
        return start
    raise TypeError("start must be a PredictionResult or TerrainParameters")


def posterior(
    profile: CIProfile,
    *,
    model: str = "rm0",
    r_min: float | None = None,
    plate_pair: tuple[float, float] | None = None,
    bounds: Bounds | None = None,
    prior: str | Calibration | CalibrationPrior = "bounds",
    noise: float | None = None,
    correlation: str | float = "estimate",
    noise_model: str = "relative",
    noise_floor: float = 0.05,
    Kc: float | None = None,
    draws: int = 2000,
    seed: int | None = None,
    plates: Sequence[float] | None = None,
    plate_sinkages: ArrayLike | None = None,
    start: PredictionResult | TerrainParameters | None = None,
    nwalkers: int = 128,
    burn: int = 80,
    thin: int = 6,
    level: float = 0.9,
    n_prior: str = "uniform",
) -> PosteriorResult:
    """Sample the posterior of (kc, kphi, n, cc, phic) given one CI profile.

    Parameters
    ----------
    profile : CIProfile
        Depths [m] and cone index [kPa].
    model : {"rm0", "rm1"}
        Pressure law (section 3.2 of [1]_); taken from the calibration when
        ``prior`` is one.
    r_min : float, optional
        RM1 transition radius [m].
    plate_pair : (float, float), optional
        Plate radii [m] of the RM1 secant.
    bounds : Bounds, optional
        Support of the prior (defaults: kc 0-1000 kN/m^(n+1), kphi 0-20000
        kN/m^(n+2), n 0.05-2, cc 0-100 kPa, phic 0-45 deg).
    prior : "bounds", Calibration or CalibrationPrior
        Uniform over the bounds, or centred on a calibration (module
        docstring).
    noise : float, optional
        Noise standard deviation [kPa] (RMS over the profile with relative
        noise); estimated (marginalised) when None.
    correlation : "estimate", "sample", "none" or float
        AR(1) coefficient of the noise at the median depth spacing [-]:
        estimated from the best-fit residuals (plug-in), sampled as a sixth
        parameter (uniform prior on [0, 0.95]; its uncertainty then widens
        the intervals), 0, or the value given.
    noise_model : {"relative", "absolute"}
        Noise proportional to the CI (with a floor) or constant.
    noise_floor : float
        Additive floor of the relative model as a fraction of the largest
        model CI [-].
    Kc : float, optional
        Fixed cone-terrain shear deformation parameter [m]; None: fully
        mobilised shear.
    draws : int
        Number of posterior samples returned.
    seed : int, optional
        Seed: the same seed gives the same samples bit for bit.
    plates : sequence of float, optional
        Plate radii [m] of the pressure bands; the calibration's plate pair,
        else ``plate_pair``, else 3.75 and 5 cm.
    plate_sinkages : array_like, optional
        Sinkages of the bands [m]; 0 to 10 cm every 5 mm by default.
    start : PredictionResult or TerrainParameters, optional
        Best fit to start from; :func:`terracone.inverse.predict` is run
        when None.
    nwalkers, burn, thin : int
        Walkers, burn-in steps discarded and thinning of the kept chain.
    level : float
        Credibility of the intervals and bands [-].
    n_prior : {"uniform", "reference"}
        Under the bounds prior: "uniform" is the plain box; "reference"
        weights it by sqrt(det G(n)), G the Gram matrix of the whitened
        linear columns (the Jeffreys prior of kc, kphi, cc given n, which
        does not depend on the units of kc and kphi).  The reference weight
        removes about 40% of the upward drift of n's posterior median but
        did not bring the coverage of n closer to 90% (docs/uncertainty.md),
        so it is not the default.  A calibration prior keeps n uniform
        either way.

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
    _check_options(level, draws, nwalkers, burn, thin, noise_model, noise, noise_floor)
    bounds = bounds or Bounds()
    cal_prior = _as_cal_prior(prior)
    cal = cal_prior.calibration if cal_prior is not None else None
    if cal is not None:
        model, r_min, plate_pair = cal.model, cal.r_min, cal.plate_pair
    law = pressure_law(model, r_min=r_min, plate_pair=plate_pair)
    profile.validate()
    rng = np.random.default_rng(seed)
    if start is None:
        start = predict(
            profile,
            model=model,
            r_min=r_min,
            plate_pair=plate_pair,
            calibration=cal,
            bounds=bounds,
            Kc=Kc,
        )
    p0 = _start_params(start)
    ns = _noise_setup(profile, p0, law, Kc, bounds, cal, noise_model, noise_floor, correlation)
    notes = list(ns.notes)
    pri = _Prior(bounds, cal_prior)
    lik = Likelihood(
        profile.depth,
        profile.ci,
        cone=profile.cone,
        law=law,
        Kc=Kc,
        n_range=bounds.n,
        weights=ns.w,
        phi=None if ns.rho_sampled else ns.phi,
        spacing=ns.dz0 or None,
    )
    if n_prior not in ("reference", "uniform"):
        raise ValueError(f"n_prior must be 'reference' or 'uniform' (got {n_prior!r})")
    if n_prior == "reference":
        free = (not pri.kc_fixed, not pri.kphi_fixed, not pri.cc_fixed)
        pri.set_reference(lik.grid, lik.gram_half_logdet(free, p0.phic_deg))
    x0, coords = _start_and_coordinates(p0, bounds, pri, profile.cone, Kc)
    if coords.ndim == 0:
        raise ValueError("all parameters are fixed: nothing to sample")
    target = _Target(coords, pri, lik, noise, ns.rho_sampled, ns.rho)
    prior_draws = pri.sample(rng, _N_PRIOR_DRAWS)

    walkers, names = _start_walkers(x0, pri, coords, target, lik, prior_draws, nwalkers, rng, notes)
    steps = int(math.ceil(draws * thin / nwalkers))
    chain, acc = _run_chain(target, walkers, burn, steps, rng)
    flat = chain[::-1][::thin][::-1].reshape(-1, chain.shape[2])[-draws:]
    samples, _ = coords.to_params(flat[:, : coords.ndim])
    rho_draws = flat[:, coords.ndim] if ns.rho_sampled else None
    tau_d, reliable, neff = _chain_diagnostics(chain, names, acc, draws, notes)
    noise_out = _noise_summary(
        ns, lik, samples, rho_draws, noise, noise_model, noise_floor, level, rng
    )
    summary = _summaries(samples, prior_draws, pri, level)
    radii = DEFAULT_PLATES if plate_pair is None else tuple(plate_pair)
    radii = radii if plates is None else tuple(plates)
    sink = np.asarray(DEFAULT_SINKAGES if plate_sinkages is None else plate_sinkages, float)
    bands = plate_bands(samples, radii, sink, law=law, level=level)
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
        log_prob_evals=target.evals,
        time_s=time.perf_counter() - t0,
        coordinates="scaled" if coords.scaled else "plain",
        cpu_s=time.process_time() - c0,
    )
    return PosteriorResult(
        id=profile.id,
        samples=samples,
        **summary,
        plate_bands=bands,
        noise=noise_out,
        diagnostics=diag,
        prior=pri.describe(),
        model=model,
        r_min=r_min,
        Kc=Kc,
        level=level,
        best_fit=p0,
        notes=notes,
        prior_samples=prior_draws[:2000],
    )


def _start_and_coordinates(p0, bounds, pri, cone, Kc):
    """The best fit clipped to the bounds (5,) and the sampler's coordinates."""
    x0 = np.array([p0.kc, p0.kphi, p0.n, p0.cc, p0.phic_deg], dtype=float)
    for j, (lo, hi) in ((2, bounds.n), (3, bounds.cc), (4, bounds.phic)):
        x0[j] = np.clip(x0[j], lo, hi)
    fixed_vals = x0.copy()
    if pri.n_fixed:
        fixed_vals[2] = bounds.n[0]
    if pri.cc_fixed:
        fixed_vals[3] = pri.cc_value
    if pri.phic_fixed:
        fixed_vals[4] = pri.phic_value
    return x0, _Coordinates(pri, cone, Kc, fixed_vals)


def _check_options(level, draws, nwalkers, burn, thin, noise_model, noise, noise_floor) -> None:
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1) (got {level})")
    if draws < 10:
        raise ValueError(f"draws must be >= 10 (got {draws})")
    if nwalkers < 8 or nwalkers % 2:
        raise ValueError(f"nwalkers must be even and >= 8 (got {nwalkers})")
    if burn < 0 or thin < 1:
        raise ValueError("burn must be >= 0 and thin >= 1")
    if noise_model not in ("relative", "absolute"):
        raise ValueError(f"noise_model must be 'relative' or 'absolute' (got {noise_model!r})")
    if noise is not None and not (noise > 0 and math.isfinite(noise)):
        raise ValueError(f"noise must be > 0 [kPa] (got {noise})")
    if not 0 <= noise_floor < 10:
        raise ValueError(f"noise_floor must be >= 0 (got {noise_floor})")


@dataclass
class _NoiseSetup:
    """Weights and AR(1) coefficient of the CI error, from the best fit."""

    w: np.ndarray
    w_rms: float
    rho: float
    rho_raw: float | None
    rho_est: bool
    rho_sampled: bool
    phi: np.ndarray
    dz0: float
    notes: list[str]


def _noise_setup(profile, p0, law, Kc, bounds, cal, noise_model, noise_floor, correlation):
    """Plug-in noise weights and the AR(1) coefficient (module docstring, "Noise model")."""
    z, y = profile.depth, profile.ci
    N = y.size
    notes = []
    A, B, C = cone_index_basis(z, n=p0.n, phic=p0.phic_deg, Kc=Kc, law=law, cone=profile.cone)
    m0 = p0.kc * A + p0.kphi * B + p0.cc * C  # eq. (2-7)
    w_raw = np.ones(N)
    if noise_model == "relative":
        scale_ci = float(np.max(np.abs(m0))) or float(np.max(np.abs(y))) or 1.0
        w_raw = np.sqrt(m0 * m0 + (noise_floor * scale_ci) ** 2)
        if not np.all(w_raw > 0):
            w_raw = np.ones(N)
            notes.append("relative noise weights degenerate (zero CI): constant weights used")
    w_rms = float(np.sqrt(np.mean(w_raw * w_raw)))
    w = w_raw / w_rms
    dz = np.diff(z)
    dz0 = float(np.median(dz)) if dz.size else 0.0
    rho_raw, rho_sampled = None, False
    if isinstance(correlation, str):
        if correlation in ("estimate", "sample"):
            X = _fit_design(z, p0, bounds, cal, law, Kc, profile.cone) / w[:, None]
            rho, rho_raw = estimate_correlation((y - m0) / w, z, design=X)
            rho_est = True
            rho_sampled = correlation == "sample" and N > 2
        elif correlation == "none":
            rho, rho_est = 0.0, False
        else:
            raise ValueError(
                "correlation must be 'estimate', 'sample', 'none' or a number "
                f"(got {correlation!r})"
            )
    else:
        rho = float(correlation)
        if not 0 <= rho <= RHO_MAX:
            raise ValueError(f"correlation must lie in [0, {RHO_MAX}] (got {rho})")
        rho_est = False
    phi = ar1_coefficients(z, rho, dz0) if N > 1 else np.zeros(0)
    if rho_raw is not None and not math.isfinite(rho_raw):
        rho_raw = None
    return _NoiseSetup(w, w_rms, float(rho), rho_raw, rho_est, rho_sampled, phi, dz0, notes)


class _Target:
    """Log posterior density in the sampler's coordinates, vectorised over walkers.

    Columns: the free parameters (:class:`_Coordinates`), then rho when it
    is sampled.  sigma is marginalised (``-N/2 log Q``) unless fixed.
    """

    def __init__(self, coords, prior, lik, sigma_fixed, rho_sampled, rho):
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


def _start_walkers(x0, pri, coords, target, lik, prior_draws, nwalkers, rng, notes):
    """Initial walkers (Laplace approximation at the best fit) and the coordinate names."""
    P0 = x0.copy()
    if pri.kc_fixed:
        P0[0] = float(pri.kc_fixed_value(np.array([P0[2]]))[0])
    if pri.kphi_fixed:
        P0[1] = float(pri.kphi_fixed_value(np.array([P0[2]]))[0])
    x_hat = coords.from_params(P0[None, :])[0]
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


def _run_chain(target, walkers, burn, steps, rng):
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

    References
    ----------
    .. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013).
       emcee: the MCMC hammer. PASP 125, 306-312.
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


def _chain_diagnostics(chain, names, acc, draws, notes):
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


def _noise_summary(ns, lik, samples, rho_draws, sigma_fixed, noise_model, floor, level, rng):
    """The :class:`NoiseModel` reported: sigma from sigma^2 | theta ~ Q / chi^2_N."""
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
    free = [not pri.kc_fixed, not pri.kphi_fixed, not pri.n_fixed, not pri.cc_fixed]
    free.append(not pri.phic_fixed)
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


def _moves() -> list:
    """Differential-evolution moves (80%) mixed with stretch moves (20%).

    On these posteriors (flat in the directions the data leave free, cut by
    the prior box) DE roughly halves the integrated autocorrelation time of
    the stretch move alone (about 20-30 steps instead of 50-70 for 64
    walkers).
    """
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
    for scale in (1.0, 1.0, 0.3, 0.1, 0.03, 0.01, 1e-3):
        cand = x_hat + scale * rng.standard_normal((4 * nwalkers, k)) @ L.T
        lp = log_prob(cand)
        good = np.concatenate([good, cand[np.isfinite(lp)]])
        if good.shape[0] >= nwalkers:
            return good[:nwalkers]
    # last resort: tiny jitter, reflected into the support by trial
    for _ in range(100):
        cand = x_hat + 1e-6 * (np.abs(x_hat) + 1e-3) * rng.standard_normal((4 * nwalkers, k))
        lp = log_prob(cand)
        good = np.concatenate([good, cand[np.isfinite(lp)]])
        if good.shape[0] >= nwalkers:
            return good[:nwalkers]
    raise ValueError("could not place the walkers inside the prior's support")


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


def posterior_for_result(
    profile: CIProfile,
    result: PredictionResult,
    *,
    prior: str | Calibration | CalibrationPrior = "bounds",
    draws: int = 2000,
    seed: int | None = None,
    plates: Sequence[float] | None = None,
    bounds: Bounds | None = None,
    plate_pair: tuple[float, float] | None = None,
    **kwargs: Any,
) -> PosteriorResult:
    """:func:`posterior` for a profile already fitted by :func:`~terracone.inverse.predict`.

    The CLI calls this once per profile: model, r_min and Kc are taken from
    ``result.params`` (or from the calibration when ``prior`` is one), and
    the walkers start at the result's optimum.  When the prior is a
    calibration and the result was not fitted with it (its phic lies more
    than 3 prior standard deviations from the calibration's), the profile is
    re-fitted with the calibration first.

    Parameters
    ----------
    profile : CIProfile
        The profile ``result`` was fitted to.
    result : PredictionResult
        Must be ``ok``.
    prior : "bounds", Calibration or CalibrationPrior
    draws : int
    seed : int, optional
    plates : sequence of float, optional
        Plate radii of the bands [m].
    bounds : Bounds, optional
        The bounds the prediction used.
    plate_pair : (float, float), optional
        RM1 plate pair [m] (without a calibration).
    **kwargs
        Passed to :func:`posterior` (noise, correlation, noise_model, ...).
    """
    if not result.ok or result.params is None:
        raise ValueError(f"profile {result.id}: prediction failed: {result.error}")
    p = result.params
    cal_prior = _as_cal_prior(prior)
    start: PredictionResult | None = result
    if cal_prior is not None:
        c = cal_prior.calibration
        tol = 3.0 * max(cal_prior.phic_sd, 1e-9)
        if abs(p.phic_deg - c.phic_deg) > tol or p.model != c.model:
            start = None
    return posterior(
        profile,
        model=p.model,
        r_min=p.r_min,
        plate_pair=plate_pair,
        bounds=bounds,
        prior=cal_prior if cal_prior is not None else "bounds",
        Kc=p.Kc,
        draws=draws,
        seed=seed,
        plates=plates,
        start=start,
        **kwargs,
    )


# ---------------------------------------------------------------------------
# layered terrain (terracone.layers)
# ---------------------------------------------------------------------------


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
    """Posterior of a layered fit (:func:`terracone.layers.fit_layered`) with emcee.

    Priors uniform over the bounds of each layer's kc, kphi, n, cc and over
    the interface depths (ordered, within the profile); the common phic is
    held at the fit's value.  Residuals are independent Gaussian with an
    unknown sigma integrated out (1/sigma prior), so the log-likelihood is
    -N/2 log(SSE).  The forward model is :func:`terracone.layers.layered_basis`
    evaluated for all walkers at once.
    """
    from .cone import normal_integrals
    from .plate import pressure_law as _pl

    bounds = bounds or Bounds()
    law = law or _pl(fit.layers[0].model or "rm0", r_min=fit.layers[0].r_min)
    z, y = profile.depth, profile.ci
    cone = profile.cone
    L = len(fit.layers)
    R, H = cone.radius, cone.height
    t = R / H
    phic = fit.layers[0].phic_deg
    s = 1.0 + math.tan(math.radians(phic)) / t
    u1 = z + H
    Lemb = np.where(z >= 0.0, H, u1)
    u1s = np.where(u1 > 0, u1, 1.0)
    d_lo, d_hi = float(z[0]), float(z[-1])

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
    lo, hi = np.array(lo), np.array(hi)
    span = np.where(hi > lo, hi - lo, 1.0)

    def model(theta: np.ndarray) -> np.ndarray:  # (W, D) -> (W, Z)
        W = theta.shape[0]
        D = np.concatenate(
            [np.zeros((W, 1)), np.sort(theta[:, 4 * L :], axis=1), np.full((W, 1), np.inf)], axis=1
        )
        ci = np.zeros((W, z.size))
        for j in range(L):
            kc, kphi, n, cc = (theta[:, 4 * j + q][:, None] for q in range(4))
            a = np.clip(u1[None, :] - D[:, j + 1][:, None], 0.0, Lemb[None, :])
            b = np.clip(u1[None, :] - D[:, j][:, None], 0.0, Lemb[None, :])
            Ic, Ip, Icc = normal_integrals(u1s[None, :], a, b, n, law, t)
            ci += 2.0 / (R * R) * (t * s * (kc * Ic + kphi * Ip) + cc * Icc)
        return ci

    def log_prob(theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(theta)
        ok = np.all((theta >= lo) & (theta <= hi), axis=1)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():
            r = model(theta[ok]) - y[None, :]
            sse = np.einsum("wz,wz->w", r, r)
            out[ok] = -0.5 * y.size * np.log(np.maximum(sse, 1e-300))
        return out

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

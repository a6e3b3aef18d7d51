"""Coverage of the 90% intervals of :func:`terracone.inverse.uncertainty.posterior.posterior`.

Usage::

    python benchmarks/posterior_coverage.py [--profiles 200] [--draws 2000] [--seed 2024]
        [--correlation estimate|sample|none|RHO] [--n-prior uniform|reference]
        [--priors bounds,calibration]

For each case a terrain with known parameters is drawn, a CI profile is
generated with the improved model (eq. (2-7) of Huang et al., RM0, fully
mobilised shear, asabe-large cone, cone-base depths 0-30 cm every 1 cm) and
multiplied by (1 + s e), s ~ U(3%, 5%) and e either independent standard
normal or AR(1) along depth with rho ~ U(0.6, 0.8); then the posterior is
sampled and we record whether the 90% intervals contain the truth:

* n;
* the pressure under a 5 cm radius plate at 2.5 cm sinkage (Bekker, RM0).

Two priors:

``bounds``
    Terrains around LETE sand / Table 4-1 (kc ~ U(60, 110) kN/m^(n+1),
    kphi ~ U(2500, 5500) kN/m^(n+2), n ~ U(0.5, 1.1), cc ~ U(0, 2) kPa,
    phic ~ U(8, 14) deg) with the uniform prior over the default bounds.
    phic trades exactly against the scale of kc and kphi, so the plate
    pressure is set by the prior there (its band is wide and "covers" for
    that reason).
``calibration``
    A LETE calibration (kc = 102, kphi = 5301, n = 0.79, cc = 1 kPa,
    phic = 11 deg, RM0) as prior: phic ~ N(11, 2) deg, cc ~ N(1, 2) kPa
    (>= 0), ln(kc/kphi) ~ N(ln(102/5301), 0.25); truths are drawn from that
    prior (kphi ~ U(2500, 6000), n ~ U(0.5, 1.1)), which is what calibrated
    credible intervals promise to cover.

Prints the coverage rates with their binomial standard errors, whether
each lies in the claimed 85-95% (docs/uncertainty.md; under the bounds
prior only n is claimed), the median interval widths, the estimated rho and
the time per profile.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from terracone.data import CIProfile
from terracone.inverse.problem import Calibration, CalibrationPrior, Problem
from terracone.inverse.uncertainty.noise import ar1_noise
from terracone.inverse.uncertainty.posterior import PosteriorOptions, posterior
from terracone.physics.cone import cone_index_huang

DEPTH = np.round(np.arange(0.0, 0.3001, 0.01), 6)
PLATE_RADIUS = 0.05  # m
PLATE_SINKAGE = 0.025  # m
LETE = Calibration("LETE sand (synthetic)", "rm0", None, None, 11.0, 1.0, 102.0, 5301.0, 0.79)


@dataclass
class Truth:
    kc: float
    kphi: float
    n: float
    cc: float
    phic: float

    def plate(self, radius: float = PLATE_RADIUS, sinkage: float = PLATE_SINKAGE) -> float:
        """Bekker pressure [kPa] under a circular plate."""
        return (self.kc / radius + self.kphi) * sinkage**self.n


def truth_bounds(rng: np.random.Generator) -> Truth:
    """Terrain around LETE sand and Table 4-1."""
    return Truth(
        kc=rng.uniform(60, 110),
        kphi=rng.uniform(2500, 5500),
        n=rng.uniform(0.5, 1.1),
        cc=rng.uniform(0, 2),
        phic=rng.uniform(8, 14),
    )


def truth_calibration(rng: np.random.Generator, prior: CalibrationPrior) -> Truth:
    """Terrain drawn from the calibration prior (kphi and n from ranges)."""
    c = prior.calibration
    kphi = rng.uniform(2500, 6000)
    q = math.exp(math.log(c.kc / c.kphi) + prior.ratio_log_sd * rng.standard_normal())
    while True:
        cc = c.cc + prior.cc_width * rng.standard_normal()
        if 0 <= cc <= 100:
            break
    phic = float(np.clip(c.phic_deg + prior.phic_sd * rng.standard_normal(), 0, 45))
    return Truth(kc=q * kphi, kphi=kphi, n=rng.uniform(0.5, 1.1), cc=cc, phic=phic)


def make_profile(
    truth: Truth, rng: np.random.Generator, *, correlated: bool, depth: np.ndarray = DEPTH
) -> tuple[CIProfile, float, float]:
    """Noisy synthetic profile; returns (profile, noise level s, rho)."""
    m = cone_index_huang(
        depth, kc=truth.kc, kphi=truth.kphi, n=truth.n, cc=truth.cc, phic_deg=truth.phic
    )
    s = rng.uniform(0.03, 0.05)
    rho = rng.uniform(0.6, 0.8) if correlated else 0.0
    e = ar1_noise(depth, rho, rng) if correlated else rng.standard_normal(depth.size)
    return CIProfile("synthetic", depth, m * (1.0 + s * e)), s, rho


def run(
    n_profiles: int,
    *,
    prior: str,
    correlated: bool,
    draws: int,
    seed: int,
    correlation: str | float = "estimate",
    **kwargs,
) -> dict:
    """Coverage of n and of the plate pressure over ``n_profiles`` cases."""
    rng = np.random.default_rng(seed)
    cal_prior = CalibrationPrior(LETE)
    hits_n = hits_p = below_n = above_n = 0
    z_n = []
    widths_n, widths_p, rel_p, rhos, times = [], [], [], [], []
    for i in range(n_profiles):
        truth = truth_bounds(rng) if prior == "bounds" else truth_calibration(rng, cal_prior)
        prof, _, rho = make_profile(truth, rng, correlated=correlated)
        t0 = time.perf_counter()
        res = posterior(
            prof,
            Problem(prior="bounds" if prior == "bounds" else cal_prior),
            draws=draws,
            seed=seed * 1000 + i,
            plates=(PLATE_RADIUS,),
            plate_sinkages=(0.0, PLATE_SINKAGE),
            options=PosteriorOptions(correlation=correlation, **kwargs),
        )
        times.append(time.perf_counter() - t0)
        lo, hi = res.intervals["n"]
        hits_n += lo <= truth.n <= hi
        below_n += truth.n < lo
        above_n += truth.n > hi
        z_n.append((res.medians["n"] - truth.n) / (hi - lo))
        widths_n.append(hi - lo)
        band = res.plate_bands[0]
        plo, phi = float(band.lo[1]), float(band.hi[1])
        p_true = truth.plate()
        hits_p += plo <= p_true <= phi
        widths_p.append(phi - plo)
        rel_p.append((phi - plo) / p_true)
        rhos.append(res.noise.rho)
    N = n_profiles
    return {
        "prior": prior,
        "noise": "AR(1) rho 0.6-0.8" if correlated else "independent",
        "profiles": N,
        "coverage_n": hits_n / N,
        "coverage_plate": hits_p / N,
        "se": math.sqrt(0.09 / N),
        "misses_n_below_above": (below_n, above_n),
        "n_error_mean_sd": (float(np.mean(z_n)), float(np.std(z_n))),
        "median_width_n": float(np.median(widths_n)),
        "median_rel_width_plate": float(np.median(rel_p)),
        "median_rho": float(np.median(rhos)),
        "time_s": float(np.median(times)),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--profiles", type=int, default=200)
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--correlation", default="estimate", help="estimate, sample, none or a number")
    ap.add_argument("--n-prior", default="uniform", help="uniform or reference (bounds prior)")
    ap.add_argument("--priors", default="bounds,calibration", help="rows to run")
    args = ap.parse_args(argv)
    corr: str | float = args.correlation
    if corr not in ("estimate", "sample", "none"):
        corr = float(corr)
    rows = []
    for k, (prior, correlated) in enumerate(
        [("bounds", False), ("bounds", True), ("calibration", False), ("calibration", True)]
    ):
        if prior not in args.priors.split(","):
            continue
        r = run(
            args.profiles,
            prior=prior,
            correlated=correlated,
            draws=args.draws,
            seed=args.seed + k,
            correlation=corr,
            n_prior=args.n_prior,
        )
        rows.append(r)
        print(
            f"{r['prior']:12s} {r['noise']:20s} N={r['profiles']:4d}  "
            f"n: {100 * r['coverage_n']:5.1f}%  plate p(2.5 cm, r=5 cm): "
            f"{100 * r['coverage_plate']:5.1f}%  (+-{100 * r['se']:.1f}%)  "
            f"width n {r['median_width_n']:.3f}  rel. width p {r['median_rel_width_plate']:.2f}  "
            f"rho {r['median_rho']:.2f}  {r['time_s']:.2f} s/profile  "
            f"n misses below/above {r['misses_n_below_above']}, "
            f"(median-truth)/width mean {r['n_error_mean_sd'][0]:+.3f} sd "
            f"{r['n_error_mean_sd'][1]:.3f}",
            flush=True,
        )
        claimed = [("n", r["coverage_n"])]
        if prior == "calibration":
            claimed.append(("plate", r["coverage_plate"]))
        for name, rate in claimed:
            verdict = "inside" if 0.85 <= rate <= 0.95 else "OUTSIDE"
            print(f"    {name}: {100 * rate:.1f}% {verdict} the claimed 85-95%")
    return 0


if __name__ == "__main__":
    sys.exit(main())

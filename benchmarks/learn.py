"""Learning process: terracone learn against scipy's differential_evolution, per site.

Each site is one CI profile and two plate tests (radii 3.75 cm and 5 cm)
generated from a known terrain with terracone's forward models, noise-free or
with 3% CI and 2% plate noise (relative, Gaussian).  Both methods minimise the
same objective, J = sum over data sets of RMSD / mean, over the same bounds of
(kc, kphi, n, cc, phic, r_min); J is evaluated for both from the forward
models (cone_index, plate_pressure), independently of learn's own code.

Run:  .venv/bin/python benchmarks/learn.py [--de-maxiter K] [--seed S]
Prints one line per site and the median time ratio.  Timings on a shared
machine are noisy; the ratio is measured in one process, site by site.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import differential_evolution

from terracone import CIProfile, PlateTest, cone_index, plate_pressure
from terracone.inverse import Bounds
from terracone.inverse.learn import learn

Z = np.round(np.arange(0.0, 0.3001, 0.01), 10)
SINKAGE = np.linspace(0.005, 0.1, 20)
PAIR = (0.0375, 0.05)


def site(rng, model: str, r_min: float | None, noisy: bool):
    t = dict(kc=102.0, kphi=5301.0, n=0.79, cc=1.5, phic=12.0)
    pair = PAIR if model == "rm1" else None
    ci = cone_index(Z, **t, model=model, r_min=r_min, plate_pair=pair)
    if noisy:
        ci = ci * (1 + 0.03 * rng.standard_normal(ci.size))
    plates = []
    for r in PAIR:
        p = plate_pressure(
            SINKAGE,
            kc=t["kc"],
            kphi=t["kphi"],
            n=t["n"],
            radius=r,
            model=model,
            r_min=r_min,
            plate_pair=pair,
        )
        if noisy:
            p = p * (1 + 0.02 * rng.standard_normal(p.size))
        plates.append(PlateTest(f"plate-{r}", r, "circular", SINKAGE, p))
    return [CIProfile("ci", Z, ci)], plates


def objective(profiles, plates, model: str):
    """J(kc, kphi, n, cc, phic, log r_min) from the forward models."""
    pair = PAIR if model == "rm1" else None

    def J(v):
        kc, kphi, n, cc, phic, lr = v
        rm = math.exp(lr) if model == "rm1" else None
        tot = 0.0
        for p in profiles:
            m = cone_index(
                p.depth,
                kc=kc,
                kphi=kphi,
                n=n,
                cc=cc,
                phic=phic,
                model=model,
                r_min=rm,
                plate_pair=pair,
            )
            tot += math.sqrt(np.mean((m - p.ci) ** 2)) / np.mean(p.ci)
        for b in plates:
            m = plate_pressure(
                b.sinkage,
                kc=kc,
                kphi=kphi,
                n=n,
                radius=b.b,
                model=model,
                r_min=rm,
                plate_pair=pair,
            )
            tot += math.sqrt(np.mean((m - b.pressure) ** 2)) / np.mean(b.pressure)
        return tot

    return J


def de_bounds(model: str, b: Bounds):
    rb = (math.log(5e-4), math.log(3 * PAIR[1])) if model == "rm1" else (0.0, 0.0)
    return [b.kc, b.kphi, b.n, b.cc, b.phic, rb]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--de-maxiter", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    cases = [
        ("rm0", None),
        ("rm1", 0.006),
        ("rm1", 0.02),
        ("rm1", 0.08),
    ]
    b = Bounds()
    print(f"{'site':<22}{'learn s':>9}{'DE s':>9}{'ratio':>8}{'J learn':>13}{'J DE':>13}")
    ratios = []
    for noisy in (False, True):
        for model, rm in cases:
            profiles, plates = site(rng, model, rm, noisy)
            J = objective(profiles, plates, model)
            t0 = time.perf_counter()
            res = learn(profiles, plates, model=model)
            t_l = time.perf_counter() - t0
            p = res.params
            v = [p.kc, p.kphi, p.n, p.cc, p.phic_deg, math.log(p.r_min) if p.r_min else 0.0]
            t0 = time.perf_counter()
            de = differential_evolution(
                J, de_bounds(model, b), seed=args.seed, maxiter=args.de_maxiter, tol=1e-10
            )
            t_de = time.perf_counter() - t0
            ratios.append(t_de / t_l)
            name = f"{model} r_min={rm} {'noisy' if noisy else 'exact'}"
            print(f"{name:<22}{t_l:9.3f}{t_de:9.2f}{t_de / t_l:8.1f}{J(v):13.4e}{de.fun:13.4e}")
    print(f"median ratio DE/learn: {np.median(ratios):.1f}  (min {min(ratios):.1f})")


if __name__ == "__main__":
    main()

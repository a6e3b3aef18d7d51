"""Learning process: terracone learn against scipy's differential_evolution, per site.

Each site is one CI profile and two plate tests (radii 3.75 cm and 5 cm)
generated from a known terrain with terracone's forward models, noise-free or
with 3% CI and 2% plate noise (relative, Gaussian).  Both methods minimise the
same objective, J = sum over data sets of RMSD / mean, over the same bounds of
(kc, kphi, n, cc, phic, r_min); J is evaluated for both from the forward
models (cone_index, plate_pressure), independently of learn's own code.

Run:  .venv/bin/python benchmarks/learn.py [--de-maxiter K] [--seed S]
Prints one line per site: learn's time, DE's time (plain, as scipy runs it by
default, and vectorised: all of a generation's points in one numpy call), the
ratios, J of each, learn's certificate gap (absolute and relative to J), and
learn's time without the branch and bound of the certificate (certify_levels=0,
the bound then trivial on noisy data); then the median ratios.  Timings on a shared
machine are noisy; the ratio is measured in one process, site by site.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution

from terracone import CIProfile, PlateTest, cone_index, plate_pressure
from terracone.inverse import Bounds
from terracone.inverse.learning.learn import learn

# run as a script, benchmarks/ heads sys.path: keep it off, so no script here can shadow an
# installed package (a benchmark named coverage.py once hid the one numba probes, silently
# turning the compiled kernels off)
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).parent.resolve()]

Z = np.round(np.arange(0.0, 0.3001, 0.01), 10)
SINKAGE = np.linspace(0.005, 0.1, 20)
PAIR = (0.0375, 0.05)


def site(rng, model: str, r_min: float | None, noisy: bool):
    t = dict(kc=102.0, kphi=5301.0, n=0.79, cc=1.5, phic_deg=12.0)
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
    """J(v), v = (kc, kphi, n, cc, phic, log r_min), from the forward models.

    v may be (6,) or (6, S) (scipy's ``vectorized=True``): J for S points at once.
    """
    pair = PAIR if model == "rm1" else None

    def J(v):
        kc, kphi, n, cc, phic, lr = (np.asarray(a, float)[..., None] for a in v)
        rm = np.exp(lr) if model == "rm1" else None
        tot = 0.0
        for p in profiles:
            m = cone_index(
                p.depth,
                kc=kc,
                kphi=kphi,
                n=n,
                cc=cc,
                phic_deg=phic,
                model=model,
                r_min=rm,
                plate_pair=pair,
            )
            tot = tot + np.sqrt(np.mean((m - p.ci) ** 2, axis=-1)) / np.mean(p.ci)
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
            tot = tot + np.sqrt(np.mean((m - b.pressure) ** 2, axis=-1)) / np.mean(b.pressure)
        return tot

    return J


def de_bounds(model: str, b: Bounds):
    rb = (math.log(5e-4), math.log(3 * PAIR[1])) if model == "rm1" else (0.0, 0.0)
    return [b.kc, b.kphi, b.n, b.cc, b.phic_deg, rb]


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
    print(
        f"{'site':<22}{'learn s':>9}{'DE s':>8}{'ratio':>7}{'DEvec s':>9}{'ratio':>7}"
        f"{'J learn':>12}{'J DE':>12}{'J DEvec':>12}{'gap':>10}{'gap/J':>7}"
        f"{'no-cert s':>10}{'ratio':>7}"
    )
    ratios, ratios_v, ratios_0 = [], [], []
    learn(*site(np.random.default_rng(0), "rm0", None, True), model="rm0")  # first-call warm-up
    for noisy in (False, True):
        for model, rm in cases:
            profiles, plates = site(rng, model, rm, noisy)
            J = objective(profiles, plates, model)
            t0 = time.perf_counter()
            res = learn(profiles, plates, model=model)
            t_l = time.perf_counter() - t0
            t0 = time.perf_counter()
            learn(profiles, plates, model=model, certify_levels=0)  # no branch and bound
            t_0 = time.perf_counter() - t0
            p = res.params
            v = [p.kc, p.kphi, p.n, p.cc, p.phic_deg, math.log(p.r_min) if p.r_min else 0.0]
            runs = []
            for vec in (False, True):
                t0 = time.perf_counter()
                de = differential_evolution(
                    J,
                    de_bounds(model, b),
                    seed=args.seed,
                    maxiter=args.de_maxiter,
                    tol=1e-10,
                    vectorized=vec,
                    updating="deferred" if vec else "immediate",
                )
                runs.append((time.perf_counter() - t0, float(de.fun)))
            (t_de, J_de), (t_dv, J_dv) = runs
            ratios.append(t_de / t_l)
            ratios_v.append(t_dv / t_l)
            ratios_0.append(t_de / t_0)
            gap = res.certificate["gap"] / max(res.objective, 1e-300)
            name = f"{model} r_min={rm} {'noisy' if noisy else 'exact'}"
            print(
                f"{name:<22}{t_l:9.3f}{t_de:8.2f}{t_de / t_l:7.1f}{t_dv:9.2f}{t_dv / t_l:7.1f}"
                f"{float(J(v)):12.4e}{J_de:12.4e}{J_dv:12.4e}{res.certificate['gap']:10.2e}"
                f"{gap:7.3f}{t_0:10.3f}{t_de / t_0:7.1f}",
                flush=True,
            )
    print(
        f"median time ratio: DE/learn {np.median(ratios):.1f} (min {min(ratios):.1f}), "
        f"vectorised DE/learn {np.median(ratios_v):.1f} (min {min(ratios_v):.1f}); "
        f"without the branch and bound (certify_levels=0): DE/learn {np.median(ratios_0):.1f} "
        f"(min {min(ratios_0):.1f})"
    )


if __name__ == "__main__":
    main()

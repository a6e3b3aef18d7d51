"""Benchmark of ``predict --uncertainty`` (the posterior) against pyswarms fits.

    python benchmarks/uncertainty.py [--profiles 12] [--draws 2000]

Issue 14's target: sampling the posterior with 2000 draws costs at most the
time of 3 pyswarms GlobalBestPSO fits (64 particles x 300 iterations, c1 =
c2 = 1.49618, w = 0.7298) per profile, on the same objective (the RMSD of
the improved cone model, RM0, fully mobilised shear,
``terracone.inverse.predict.rmsd_objective``) and the same bounds
(terracone's defaults).  pyswarms is a benchmark peer only.

Profiles are generated as in benchmarks/posterior_coverage.py: a terrain around LETE
sand (kc 60-110 kN/m^(n+1), kphi 2500-5500 kN/m^(n+2), n 0.5-1.1, cc 0-2
kPa, phic 8-14 deg), cone-base depths 0-30 cm every 1 cm, multiplicative
noise of 3-5%, every other profile with AR(1) noise (rho 0.6-0.8).  Half
the posteriors use the uniform prior over the bounds, half a LETE
calibration prior.

Timed per profile, all in this process (wall clock, ``time.perf_counter``,
the shortest of ``--repeats`` runs except for ``before``, run once):

* ``pyswarms``: one GlobalBestPSO fit;
* ``posterior``: what ``--uncertainty`` adds, i.e.
  :func:`terracone.inverse.uncertainty.posterior.posterior` started at the profile's fit
  with the default sampler settings;
* ``predict+posterior``: the same including the exact fit itself;
* ``before``: the sampler settings and likelihood before issue 14 (64
  walkers, 250 burn-in steps, thinning 15, the numpy likelihood), for the
  before/after figures.

Printed: the median times and the ratios posterior / pyswarms (target
<= 3) and before / pyswarms, the first call of the compiled kernel (the
numba cache load, or the compilation when the cache is cold) and the
time of ``import terracone.inverse.uncertainty.posterior`` in a fresh interpreter.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from terracone import jit
from terracone.data import CIProfile
from terracone.inverse import Bounds, Problem, predict
from terracone.inverse.predict import rmsd_objective
from terracone.inverse.problem import Calibration
from terracone.inverse.uncertainty.noise import ar1_noise
from terracone.inverse.uncertainty.posterior import PosteriorOptions, posterior
from terracone.physics.cone import cone_index_huang
from terracone.physics.plate import pressure_law

DEPTH = np.round(np.arange(0.0, 0.3001, 0.01), 6)
LETE = Calibration("LETE sand (synthetic)", "rm0", None, None, 11.0, 1.0, 102.0, 5301.0, 0.79)
PYSWARMS_OPTIONS = {"c1": 1.49618, "c2": 1.49618, "w": 0.7298}
BEFORE = dict(options=PosteriorOptions(nwalkers=64, burn=250, thin=15))


def make_profiles(count: int, seed: int) -> list[CIProfile]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        t = dict(
            kc=rng.uniform(60, 110),
            kphi=rng.uniform(2500, 5500),
            n=rng.uniform(0.5, 1.1),
            cc=rng.uniform(0, 2),
            phic_deg=rng.uniform(8, 14),
        )
        m = cone_index_huang(DEPTH, **t)
        s = rng.uniform(0.03, 0.05)
        if i % 2:
            e = ar1_noise(DEPTH, rng.uniform(0.6, 0.8), rng)
        else:
            e = rng.standard_normal(DEPTH.size)
        out.append(CIProfile(f"p{i}", DEPTH, m * (1.0 + s * e)))
    return out


@contextlib.contextmanager
def _in_tempdir():
    """pyswarms' Reporter writes report.log into the working directory."""
    old = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        try:
            yield
        finally:
            os.chdir(old)


def run_pyswarms(profile: CIProfile, bounds: Bounds, seed: int) -> np.ndarray:
    f = rmsd_objective(profile, pressure_law("rm0"), bounds)
    lo = np.array([bounds.kc[0], bounds.kphi[0], bounds.n[0], bounds.cc[0], bounds.phic_deg[0]])
    hi = np.array([bounds.kc[1], bounds.kphi[1], bounds.n[1], bounds.cc[1], bounds.phic_deg[1]])
    with _in_tempdir():
        import pyswarms as ps

        logging.disable(logging.INFO)
        try:
            np.random.seed(seed)
            opt = ps.single.GlobalBestPSO(
                n_particles=64, dimensions=5, options=dict(PYSWARMS_OPTIONS), bounds=(lo, hi)
            )
            _, pos = opt.optimize(f, iters=300, verbose=False)
        finally:
            logging.disable(logging.NOTSET)
    return np.asarray(pos, float)


def timed(fn, *args, repeats: int = 1, **kwargs):
    """Result and the shortest wall time over ``repeats`` calls (the machine may be shared)."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn(*args, **kwargs)
        best = min(best, time.perf_counter() - t)
    return out, best


def import_time() -> float:
    code = "import time; t = time.perf_counter(); import terracone.inverse.uncertainty.posterior; "
    code += "print(time.perf_counter() - t)"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(res.stdout.strip())


def first_call() -> float:
    """The first call of the compiled kernel in a fresh interpreter (cache load or compile)."""
    code = (
        "import time, numpy as np; from terracone.inverse.uncertainty.likelihood import spline_sse_compiled as f; "
        "c = np.zeros((4, 2, 3, 3)); t = time.perf_counter(); "
        "f(c, 0.0, 1.0, np.zeros(3), np.ones((2, 5)), 0.27, np.zeros(0), np.ones(2)); "
        "print(time.perf_counter() - t)"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(res.stdout.strip())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--profiles", type=int, default=12)
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=14)
    ap.add_argument("--repeats", type=int, default=3, help="timings: the minimum of R runs")
    args = ap.parse_args(argv)
    bounds = Bounds()
    profiles = make_profiles(args.profiles, args.seed)
    print(f"numba kernels: {'on' if jit.enabled() else 'off (TERRACONE_NUMBA=0 or not cached)'}")
    print(
        f"import terracone.inverse.uncertainty.posterior (fresh interpreter): {import_time():.2f} s"
    )
    print(f"first call of the compiled log-likelihood (fresh interpreter): {first_call():.3f} s")
    # warm up: imports, the kernel, pyswarms
    posterior(profiles[0], draws=100, seed=0)
    run_pyswarms(profiles[0], bounds, 0)
    rows = []
    for i, prof in enumerate(profiles):
        prior = LETE if i % 4 >= 2 else "bounds"
        _, t_pso = timed(run_pyswarms, prof, bounds, i, repeats=args.repeats)
        pb = Problem(prior=prior)  # LETE as the prior: the fit at its values, draws around
        fit, t_fit = timed(predict, prof, pb, repeats=args.repeats)
        kw = dict(start=fit, draws=args.draws, seed=i)
        _, t_post = timed(posterior, prof, pb, repeats=args.repeats, **kw)
        with jit.disabled():  # the numpy likelihood, as before issue 14
            _, t_before = timed(posterior, prof, pb, **kw, **BEFORE)
        rows.append((t_pso, t_post, t_fit + t_post, t_before))
        print(
            f"{prof.id:4s} prior {'bounds' if prior == 'bounds' else 'LETE':6s} "
            f"pyswarms {t_pso:.3f} s  posterior {t_post:.3f} s  predict+posterior "
            f"{t_fit + t_post:.3f} s  before {t_before:.3f} s",
            flush=True,
        )
    med = [statistics.median(c) for c in zip(*rows)]
    ratios = [r[1] / r[0] for r in rows]
    ratios_all = [r[2] / r[0] for r in rows]
    ratios_before = [r[3] / r[0] for r in rows]
    print(
        f"\nmedian per profile ({args.draws} draws): pyswarms {med[0]:.3f} s, posterior "
        f"{med[1]:.3f} s, predict+posterior {med[2]:.3f} s, before {med[3]:.3f} s"
    )
    print(
        "posterior / pyswarms fit: median "
        f"{statistics.median(ratios):.2f}, max {max(ratios):.2f} (target <= 3); "
        f"predict+posterior / pyswarms: median {statistics.median(ratios_all):.2f}; "
        f"before / pyswarms: median {statistics.median(ratios_before):.2f}"
    )
    print(f"speed-up over before: {statistics.median(r[3] / r[1] for r in rows):.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())

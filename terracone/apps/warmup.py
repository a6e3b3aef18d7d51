"""Fill numba's cache with every compiled kernel: ``python -m terracone.apps.warmup``.

:mod:`terracone.jit` starts this module in a detached background process the
first time a run finds the cache cold (the run itself takes the numpy paths),
so that later runs load the kernels instead of compiling them.  It compiles by
running what the commands run, on small generated data: the demo (learning
and prediction with and without a calibration, RM1), ``predict`` of one
profile with the posterior and with a layered fit, and batch's warm-up (vectorised sets of one and of
many profiles, the fit checks), plus a box on phic (its grid refinement), so
that numba sees every argument type the commands pass.  Then it writes the
marker of :func:`terracone.jit.ready`.

One at a time: it holds :func:`terracone.jit.warmup_lock` and leaves at once
when another warm-up holds it or the marker is there.  It runs at low
priority (``nice`` 10), so it takes what the foreground leaves.
"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from terracone import jit

__all__ = ["workload", "main"]


def workload() -> None:
    """Run every compiled kernel the commands reach, on small generated data."""
    from terracone.apps.batch import warm_kernels
    from terracone.apps.example import example_dir, run_demo
    from terracone.apps.workflow import predict_profiles
    from terracone.inverse.bounds import Bounds
    from terracone.inverse.predict import RunSettings, predict_many
    from terracone.inverse.problem import Problem
    from terracone.io import read_ci_profiles

    run_demo()
    profiles = read_ci_profiles(example_dir() / "lete_sand_synthetic_ci.csv")
    posterior = RunSettings(uncertainty=True, draws=64)
    predict_profiles(profiles[:1], settings=posterior, plates=[0.05])
    # the layered sampler too
    predict_profiles(profiles[:1], settings=RunSettings(layers=2, uncertainty=True, draws=64))
    warm_kernels()
    many = profiles * 12  # a set of 36 (the many-profile refinements)
    for bounds in (Bounds(), Bounds(kc=(1.0, 500.0), phic_deg=(5.0, 30.0))):
        predict_many(many, Problem(bounds=bounds), RunSettings(detail="summary"))
        predict_many(profiles[:1], Problem(bounds=bounds))
    z = np.linspace(0.0, 0.3, 7)
    predict_many([profiles[0].window(0.0, float(z[-1]))], Problem(model="rm1", r_min=0.01))


def main() -> int:
    """Compile the kernels unless another warm-up does or they are there; 0 on success."""
    if jit.mode() == "off":
        return 0
    with jit.warmup_lock() as free:
        if not free or jit.ready():
            return 0
        with contextlib.suppress(AttributeError, OSError):
            os.nice(10)
        workload()
        jit.mark_ready()
    return 0


if __name__ == "__main__":  # pragma: no cover - run by terracone.jit.start_warmup
    raise SystemExit(main())

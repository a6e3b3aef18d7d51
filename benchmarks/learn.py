"""Learning process: terracone learn against scipy's differential_evolution, per site.

The case of issue 29: sites of all four r_min regimes of RM1 (below the
cone's base radius, between the cone and the smaller plate, between the two
plates, above the larger plate), in US-unit and in SI-unit files, noise-free
and noisy, default bounds.

Each site is one CI profile (asabe-large cone, 25 depths) and a plate pair
(30 sinkages each) made from a known terrain with terracone's own forward
models (``cone_index``, ``plate_pressure``, RM1):

* US files: depths 0-6 in, plates of radius 1.5 and 2.5 in, sinkage 0.1-3 in
  (the site of issue 29); columns ``depth_in``, ``ci_psi``;
  ``plate_radius_in``, ``sinkage_in``, ``pressure_psi``;
* SI files: depths 0-0.3 m, plates of radius 3.5 and 6 cm, sinkage
  2.5-75 mm; columns ``depth_m``, ``ci_kpa``; ``plate_radius_m``,
  ``sinkage_m``, ``pressure_kpa``.

The terrain is drawn at random (kc 50-300 kN/m^(n+1), kphi 1500-6000
kN/m^(n+2), n 0.55-0.95, cc 0-4 kPa, phic 6-16 deg) and r_min log-uniformly
inside its regime (0.2-0.9 of the cone's base radius; 1.1 of it to 0.9 of
the smaller plate; 1.05 of the smaller plate to 0.95 of the larger; 1.1 to
2.8 times the larger plate, learn's default range ending at 3 times it).
Noise-free files hold the values to full precision; noisy ones carry 3% CI
and 2% plate noise (relative, Gaussian) and are rounded as an instrument
export would be.  The files are read back through the readers ``terracone
learn`` uses.

``learn`` runs as the CLI runs it (default bounds, default certificate);
scipy's ``differential_evolution`` minimises the same J = sum over data sets
of RMSD / mean over the same bounds of (kc, kphi, n, cc, phic, log r_min),
with the seed of the site, polish on, maxiter 300 and tol 1e-10, J evaluated
from the public forward models, independently of learn's code.  Per site the
order is learn, DE, learn (learn's time is the mean of its two runs around
DE's), so load on the shared machine falls on both alike; the machine's load
average is printed before and after.

Run:  python benchmarks/learn.py [--sites K] [--seed S] [--json OUT]
Prints one line per site (regime, units, noise, truth r_min, learn's time,
DE's, their ratio, J of each by the forward models, learn's certificate gap,
absolute and relative to J on noisy sites, and on noise-free sites the largest
error of the learned parameters against the truth, :func:`truth_error`) and
the median ratio, overall and per group.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution

# run as a script, benchmarks/ heads sys.path: keep it off, so no script here can shadow an
# installed package (a benchmark named coverage.py once hid the one numba probes, silently
# turning the compiled kernels off)
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).parent.resolve()]

from terracone import cone_index, plate_pressure  # noqa: E402
from terracone.inverse import Bounds  # noqa: E402
from terracone.inverse.learning.learn import learn  # noqa: E402
from terracone.io import read_ci_profiles, read_plate_tests  # noqa: E402
from terracone.physics import units as u  # noqa: E402
from terracone.physics.cone import get_cone  # noqa: E402

CONE_RADIUS = get_cone("asabe-large").radius  # [m]
# file geometry per unit system: depths, sinkages [m], plate radii [m], unit suffixes, scales
GEOMETRY = {
    "us": dict(
        depth=np.linspace(0.0, 6.0, 25) * u.INCH,
        sinkage=np.linspace(0.1, 3.0, 30) * u.INCH,
        pair=(1.5 * u.INCH, 2.5 * u.INCH),
        length=("in", u.INCH),
        pressure=("psi", u.PSI),
    ),
    "si": dict(
        depth=np.linspace(0.0, 0.3, 25),
        sinkage=np.linspace(0.0025, 0.075, 30),
        pair=(0.035, 0.06),
        length=("m", 1.0),
        pressure=("kpa", 1.0),
    ),
}
REGIMES = ("below cone", "cone-plate", "between", "above")


def r_min_range(regime: str, pair: tuple[float, float]) -> tuple[float, float]:
    """The regime's r_min interval [m]."""
    r1, r2 = pair
    return {
        "below cone": (0.2 * CONE_RADIUS, 0.9 * CONE_RADIUS),
        "cone-plate": (1.1 * CONE_RADIUS, 0.9 * r1),
        "between": (1.05 * r1, 0.95 * r2),
        "above": (1.1 * r2, 2.8 * r2),
    }[regime]


def truth(rng: np.random.Generator, regime: str, pair) -> dict[str, float]:
    lo, hi = r_min_range(regime, pair)
    return dict(
        kc=rng.uniform(50, 300),
        kphi=rng.uniform(1500, 6000),
        n=rng.uniform(0.55, 0.95),
        cc=rng.uniform(0.0, 4.0),
        phic_deg=rng.uniform(6.0, 16.0),
        r_min=math.exp(rng.uniform(math.log(lo), math.log(hi))),
    )


def _fmt(v: float, noisy: bool, digits: int) -> str:
    return f"{v:.{digits}f}" if noisy else repr(float(v))


def write_site(folder: Path, name: str, t: dict, units: str, rng, noisy: bool):
    """The site's CI and plate files (SI truth, optional noise and rounding): two paths."""
    g = GEOMETRY[units]
    (lu, L), (pu, P) = g["length"], g["pressure"]
    law = dict(kc=t["kc"], kphi=t["kphi"], n=t["n"], model="rm1", r_min=t["r_min"])
    pair = g["pair"]
    ci = cone_index(g["depth"], cc=t["cc"], phic_deg=t["phic_deg"], plate_pair=pair, **law)
    if noisy:
        ci = ci * (1 + 0.03 * rng.standard_normal(ci.size))
    lines = [f"profile,cone,depth_{lu},ci_{pu}"]
    lines += [
        f"{name},asabe-large,{_fmt(d / L, noisy, 4)},{_fmt(c / P, noisy, 2)}"
        for d, c in zip(g["depth"], ci)
    ]
    ci_path = folder / f"{name}_ci.csv"
    ci_path.write_text("\n".join(lines) + "\n")
    lines = [f"test,plate_radius_{lu},sinkage_{lu},pressure_{pu}"]
    for r in pair:
        p = plate_pressure(g["sinkage"], radius=r, plate_pair=pair, **law)
        if noisy:
            p = p * (1 + 0.02 * rng.standard_normal(p.size))
        lines += [
            f"plate-{r / L:g},{repr(float(r / L))},{_fmt(s / L, noisy, 5)},{_fmt(q / P, noisy, 2)}"
            for s, q in zip(g["sinkage"], p)
        ]
    plates_path = folder / f"{name}_plates.csv"
    plates_path.write_text("\n".join(lines) + "\n")
    return ci_path, plates_path


def objective(profiles, plates, pair):
    """J(v), v = (kc, kphi, n, cc, phic, log r_min), from the public forward models."""

    def J(v):
        kc, kphi, n, cc, phic, lr = (float(a) for a in v)
        law = dict(kc=kc, kphi=kphi, n=n, model="rm1", r_min=math.exp(lr), plate_pair=pair)
        tot = 0.0
        for p in profiles:
            m = cone_index(p.depth, cc=cc, phic_deg=phic, cone=p.cone, **law)
            tot += math.sqrt(float(np.mean((m - p.ci) ** 2))) / float(np.mean(p.ci))
        for b in plates:
            m = plate_pressure(b.sinkage, radius=b.b, **law)
            tot += math.sqrt(float(np.mean((m - b.pressure) ** 2))) / float(np.mean(b.pressure))
        return tot

    return J


def run_site(ci_path: Path, plates_path: Path, units: str, seed: int) -> dict:
    # read as `terracone learn --units U` reads (readers, default bounds in --units U)
    profiles = read_ci_profiles(ci_path, on_error="raise")
    plates = read_plate_tests(plates_path)
    bounds = Bounds.parse(None, units)
    branches = [b.loading_branch() for b in plates]
    pair = (min(b.b for b in branches), max(b.b for b in branches))
    J = objective(profiles, branches, pair)
    n_mid = 0.5 * sum(bounds.n)
    box = [
        tuple(float(v) for v in bounds.kc_si(n_mid)),
        tuple(float(v) for v in bounds.kphi_si(n_mid)),
    ]
    box += [bounds.n, bounds.cc, bounds.phic_deg]
    box.append((math.log(5e-4), math.log(3 * pair[1])))  # learn's default r_min range

    t0 = time.perf_counter()
    res = learn(profiles, plates, model="rm1", bounds=bounds)
    t_l1 = time.perf_counter() - t0
    t0 = time.perf_counter()
    de = differential_evolution(J, box, seed=seed, maxiter=300, tol=1e-10)
    t_de = time.perf_counter() - t0
    t0 = time.perf_counter()
    res2 = learn(profiles, plates, model="rm1", bounds=bounds)
    t_l2 = time.perf_counter() - t0
    p = res.params
    v = [p.kc, p.kphi, p.n, p.cc, p.phic_deg, math.log(p.r_min)]
    assert res2.params == p, "learn gave two answers on one site"
    c = res.certificate
    return dict(
        learn_s=0.5 * (t_l1 + t_l2),
        de_s=t_de,
        J_learn=J(v),
        J_de=float(de.fun),
        objective=res.objective,
        lower_bound=c["lower_bound"],
        gap=c["gap"],
        cells_not_excluded=c["cells_not_excluded"],
        params=v,
        flat=bool(p.r_min > pair[1]),  # the secant branch: J does not depend on r_min
        undetermined=res.undetermined,
        nfev=res.nfev,
    )


def truth_error(r: dict) -> float:
    """Largest error of the learned parameters against the truth: relative for kc, kphi, n and
    r_min (r_min left out on its flat set above the larger plate), in units of 1 kPa for cc and
    1 deg for phic."""
    t, (kc, kphi, n, cc, phic, lr) = r["truth"], r["params"]
    err = [abs(kc / t["kc"] - 1), abs(kphi / t["kphi"] - 1), abs(n / t["n"] - 1)]
    err += [abs(cc - t["cc"]), abs(phic - t["phic_deg"])]
    if not r["flat"]:
        err.append(abs(math.exp(lr) / t["r_min"] - 1))
    return max(err)


def _line(r: dict) -> str:
    t = r["truth"]
    if r["noise"] == "free":
        tail = f"{r['gap']:10.1e}{'-':>7}{truth_error(r):9.1e}"
    else:
        tail = f"{r['gap']:10.1e}{r['gap'] / r['objective']:7.3f}{'-':>9}"
    return (
        f"{r['site']:<5}{r['regime']:<11}{r['units']:<6}{r['noise']:<6}{t['r_min'] * 1e3:9.2f}"
        f"{r['learn_s']:9.3f}{r['de_s']:7.2f}{r['de_s'] / r['learn_s']:7.1f}"
        f"{r['J_learn']:11.3e}{r['J_de']:11.3e}" + tail
    )


def _medians(rows: list[dict]) -> str:
    def med(sel):
        r = [x["de_s"] / x["learn_s"] for x in rows if sel(x)]
        return f"{np.median(r):.1f} ({len(r)})" if r else "-"

    parts = [f"all {med(lambda x: True)}"]
    parts += [f"{k} {med(lambda x, k=k: x['noise'] == k)}" for k in ("free", "noisy")]
    parts += [f"{k} {med(lambda x, k=k: x['units'] == k)}" for k in ("us", "si")]
    parts += [f"{k} {med(lambda x, k=k: x['regime'] == k)}" for k in REGIMES]
    return "median ratio DE/learn (sites): " + ", ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", type=int, default=1, help="sites per regime, units and noise")
    ap.add_argument("--seed", type=int, default=29)
    ap.add_argument("--json", default=None, help="write the per-site figures here")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    rows = []
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        # first-call warm-up (imports, numba): a site of its own, not timed
        w_rng = np.random.default_rng(0)
        warm = write_site(
            folder, "warm", truth(w_rng, "between", GEOMETRY["si"]["pair"]), "si", w_rng, True
        )
        learn(read_ci_profiles(warm[0], on_error="raise"), read_plate_tests(warm[1]))
        print(
            f"{'site':<5}{'regime':<11}{'units':<6}{'noise':<6}{'r_min mm':>9}{'learn s':>9}"
            f"{'DE s':>7}{'ratio':>7}{'J learn':>11}{'J DE':>11}{'gap':>10}{'gap/J':>7}"
            f"{'truth err':>9}"
        )
        sites = [
            (reg, units, noise)
            for _ in range(args.sites)
            for noise in ("free", "noisy")
            for units in ("us", "si")
            for reg in REGIMES
        ]
        for i, (regime, units, noise) in enumerate(sites):
            t = truth(rng, regime, GEOMETRY[units]["pair"])
            paths = write_site(folder, f"s{i}", t, units, rng, noise == "noisy")
            r = run_site(*paths, units, seed=args.seed + i)
            r.update(site=f"s{i}", regime=regime, units=units, noise=noise, truth=t)
            rows.append(r)
            print(_line(r), flush=True)
    print(_medians(rows))
    ratios = np.array([r["de_s"] / r["learn_s"] for r in rows])
    worse = [r["site"] for r in rows if r["J_learn"] > r["J_de"] * (1 + 1e-9) + 1e-12]
    print(
        f"min ratio {ratios.min():.1f}, max {ratios.max():.1f}; learn's J above DE's "
        f"(1e-9 relative, 1e-12 absolute) on: {worse or 'none'}"
    )
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()

"""The library as a prior (issue 32): a coverage study with known truth, and its cost.

Usage::

    python benchmarks/library_prior.py [--sites 120] [--outside 5] [--pushes 3] [--seed 32]
        [--cost-profiles 40] [--skip-cost]

A library of four calibrations that differ in kc/kphi, phic, cc and r_min
(:data:`LIBRARY`) is generated; each in-library site draws one of them in
turn, a site strength g_s ~ logN(0, 0.35) (kc and kphi times g_s) and
n_s = n + N(0, 0.08); each of its pushes has its own strength
g_s exp(0.05 e) and CI from the improved model (eq. (2-7) of Huang et al.,
the calibration's law, fully mobilised shear, asabe-large cone, base depths
2-40 cm every 2 cm, or from -3 cm with ``--from-surface``) times (1 + 0.03 e) with e AR(1) along depth (rho 0.4).
Outside sites draw from a soil outside the library (:data:`OUTSIDE`).  The
truth of a site is the plate pressure of its terrain (kc_s, kphi_s, n_s) on a
5 cm radius plate at 2.5 cm sinkage (Bekker's eq. (2-2) or RM1).

Prints, for the in-library sites: how often the true calibration carries
the largest weight; the coverage of the 90% interval of the site's plate
pressure with the library (and its binomial standard error), with the true
calibration given and without any (prior only); the median interval width
(hi/lo) of each; the site medians against the truth (median and 5-95% range
of median/truth) before (prior only) and after (library); the sites flagged
outside the library (false flags in the library, flags outside it).  Then
the cost per profile of ``predict_many`` with a library of ten calibrations
against one calibrated prediction, from alternating runs in this process
(ratios only; the machine's load is not controlled).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from terracone.data import CIProfile
from terracone.inverse.predict import RunSettings, predict_many
from terracone.inverse.problem import Calibration, LibraryPrior, Problem
from terracone.inverse.sites.statistics import fit_sites, group_profiles
from terracone.inverse.uncertainty.noise import ar1_noise
from terracone.physics.cone import cone_index_huang
from terracone.physics.plate import plate_pressure, pressure_law

DEPTH = np.round(np.arange(0.02, 0.4001, 0.02), 6)
PLATE, SINKAGE = 0.05, 0.025  # m
SINKAGES = np.array([0.01, SINKAGE, 0.05])
NOISE, RHO = 0.03, 0.4


def _cal(name, model, r_min, phic, cc, kc, kphi, n) -> Calibration:
    return Calibration(name, model, r_min, None, phic, cc, kc, kphi, n)


#: The generated library: kc/kphi 0.004-0.15 m, phic 8-20 deg, cc 0-12 kPa, r_min 5-25 mm.
LIBRARY = (
    _cal("sand", "rm1", 0.005, 11.0, 0.0, 90.0, 4500.0, 0.70),
    _cal("loam", "rm1", 0.012, 15.0, 4.0, 60.0, 1000.0, 0.80),
    _cal("clay", "rm0", None, 8.0, 12.0, 150.0, 1000.0, 0.50),
    _cal("silt", "rm1", 0.025, 20.0, 1.0, 8.0, 2000.0, 0.60),
)
#: A soil outside the library: soft and cohesive (cc makes about half of its CI).
OUTSIDE = _cal("outside", "rm0", None, 10.0, 80.0, 10.0, 400.0, 1.00)


def law_of(cal: Calibration):
    return pressure_law(cal.model, r_min=cal.r_min) if cal.model == "rm1" else None


def make_sites(n_in: int, n_out: int, pushes: int, seed: int):
    """Profiles (site in metadata) and per site: (truth plate pressure, calibration, in library)."""
    rng = np.random.default_rng(seed)
    profiles, truth = [], {}
    specs = [LIBRARY[i % len(LIBRARY)] for i in range(n_in)] + [OUTSIDE] * n_out
    for s, cal in enumerate(specs):
        g, n = float(np.exp(0.35 * rng.standard_normal())), cal.n + 0.08 * rng.standard_normal()
        n = float(np.clip(n, 0.3, 1.2))
        name = f"site{s:03d}"
        kc, kphi = cal.kc * g, cal.kphi * g
        p = plate_pressure(SINKAGE, kc=kc, kphi=kphi, n=n, radius=PLATE, model=cal.model,
                           r_min=cal.r_min)  # fmt: skip
        truth[name] = (float(p), cal.terrain, cal is not OUTSIDE)
        for j in range(pushes):
            gj = g * float(np.exp(0.05 * rng.standard_normal()))
            m = cone_index_huang(DEPTH, kc=cal.kc * gj, kphi=cal.kphi * gj, n=n, cc=cal.cc,
                                 phic_deg=cal.phic_deg, law=law_of(cal))  # fmt: skip
            y = m * (1 + NOISE * ar1_noise(DEPTH, RHO, rng))
            profiles.append(CIProfile(f"{name}-{j}", DEPTH, y, metadata={"site": name}))
    return profiles, truth


def site_table(profiles, problem, seed):
    grouping = group_profiles(profiles, by="site")
    sites = fit_sites(profiles, grouping, problem, plates=[PLATE], sinkage=SINKAGES, seed=seed)
    return {s.site: s for s in sites}


def _row(site):
    pl = site.plate_pressure[0]
    return float(pl.median[1]), float(pl.lo[1]), float(pl.hi[1])


def study(n_in: int, n_out: int, pushes: int, seed: int) -> dict:
    """The coverage study: per site its truth and the three answers; the summary figures."""
    profiles, truth = make_sites(n_in, n_out, pushes, seed)
    t0 = time.perf_counter()
    lib = site_table(profiles, Problem(library=LibraryPrior(LIBRARY)), seed)
    t_lib = time.perf_counter() - t0
    free = site_table(profiles, Problem(), seed)
    true_cal = {}
    for cal in LIBRARY:
        mine = [p for p in profiles if truth[p.metadata["site"]][1] == cal.terrain]
        true_cal.update(site_table(mine, Problem(calibration=cal), seed))
    rows = []
    for name, (p_true, cname, inside) in truth.items():
        s = lib[name]
        top = max(s.library.weights, key=s.library.weights.get) if s.library.weights else None
        rows.append(
            dict(
                site=name, truth=p_true, calibration=cname, inside=inside, top=top,
                flagged=s.library.outside, lib=_row(s), free=_row(free[name]),
                true_cal=_row(true_cal[name]) if name in true_cal else None,
            )
        )  # fmt: skip
    return {"rows": rows, "time_lib": t_lib, "profiles": len(profiles)}


def _cover(rows, key):
    hit = [r[key][1] <= r["truth"] <= r[key][2] for r in rows]
    k = float(np.mean(hit))
    return k, float(np.sqrt(k * (1 - k) / len(hit)))


def summary(res: dict) -> dict:
    inside = [r for r in res["rows"] if r["inside"]]
    outside = [r for r in res["rows"] if not r["inside"]]
    out = {
        "sites_in": len(inside),
        "sites_out": len(outside),
        "top_is_truth": float(np.mean([r["top"] == r["calibration"] for r in inside])),
        "false_flags": sum(r["flagged"] for r in inside),
        "flagged_outside": sum(r["flagged"] for r in outside),
    }
    for key in ("lib", "true_cal", "free"):
        out[f"coverage_{key}"] = _cover(inside, key)
        out[f"width_{key}"] = float(np.median([r[key][2] / r[key][1] for r in inside]))
        ratio = np.array([r[key][0] / r["truth"] for r in inside])
        out[f"ratio_{key}"] = tuple(float(v) for v in np.quantile(ratio, [0.05, 0.5, 0.95]))
        out[f"logerr_{key}"] = float(np.median(np.abs(np.log(ratio))))
    lib_in = [r for r in inside if not r["flagged"]]
    out["coverage_lib_unflagged"] = _cover(lib_in, "lib") if lib_in else (float("nan"), 0.0)
    return out


def cost(profiles: int, seed: int, repeats: int = 3) -> tuple[float, float, float]:
    """Seconds per profile: library of 10 calibrations, one calibration; their ratio."""
    rng = np.random.default_rng(seed)
    ten = [
        _cal(f"c{i}", "rm1" if i % 2 else "rm0", 0.004 + 0.004 * i if i % 2 else None,
             5.0 + 2.0 * i, float(i), 10.0 + 20.0 * i, 1000.0 + 400.0 * i, 0.5 + 0.04 * i)
        for i in range(10)
    ]  # fmt: skip
    profs, _ = make_sites(profiles, 0, 1, seed)
    lib_pb, cal_pb = Problem(library=LibraryPrior(tuple(ten))), Problem(calibration=ten[3])
    settings = RunSettings()
    predict_many(profs[:2], lib_pb, settings)  # compile and warm
    predict_many(profs[:2], cal_pb, settings)
    t_lib, t_cal = [], []
    for _ in range(repeats):  # alternate, so that load changes hit both
        t = time.perf_counter()
        predict_many(profs, lib_pb, settings)
        t_lib.append(time.perf_counter() - t)
        t = time.perf_counter()
        predict_many(profs, cal_pb, settings)
        t_cal.append(time.perf_counter() - t)
    del rng
    a, b = min(t_lib) / len(profs), min(t_cal) / len(profs)
    return a, b, a / b


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", type=int, default=120)
    ap.add_argument("--outside", type=int, default=5)
    ap.add_argument("--pushes", type=int, default=3)
    ap.add_argument("--seed", type=int, default=32)
    ap.add_argument("--cost-profiles", type=int, default=40)
    ap.add_argument("--skip-cost", action="store_true")
    ap.add_argument(
        "--from-surface",
        action="store_true",
        help="profiles from the surface (cone-base depths from -3 cm: the tip entering)",
    )
    a = ap.parse_args(argv)
    global DEPTH
    if a.from_surface:
        DEPTH = np.round(np.arange(-0.03, 0.4001, 0.02), 6)
    res = study(a.sites, a.outside, a.pushes, a.seed)
    s = summary(res)
    print(f"library: {', '.join(c.terrain for c in LIBRARY)}; outside soil: {OUTSIDE.terrain}")
    print(f"{s['sites_in']} sites in the library, {s['sites_out']} outside, {a.pushes} pushes each; "
          f"cone-base depths {DEPTH[0] * 100:g} to {DEPTH[-1] * 100:g} cm")  # fmt: skip
    print(f"true calibration carries the largest weight: {s['top_is_truth']:.0%}")
    print(f"plate pressure, r = {PLATE * 100:g} cm, z = {SINKAGE * 100:g} cm:")
    print(f"{'answer':<28}{'90% coverage':>16}{'width hi/lo':>13}{'median/truth 5-50-95%':>26}"
          f"{'median |log(median/truth)|':>28}")  # fmt: skip
    for key, label in (("lib", "library"), ("true_cal", "true calibration given"),
                       ("free", "no calibration (prior)")):  # fmt: skip
        k, se = s[f"coverage_{key}"]
        r = s[f"ratio_{key}"]
        print(f"{label:<28}{k:>10.1%} +-{se:.1%}{s[f'width_{key}']:>13.2f}"
              f"{r[0]:>10.2f}{r[1]:>8.2f}{r[2]:>8.2f}{s[f'logerr_{key}']:>28.3f}")  # fmt: skip
    k, se = s["coverage_lib_unflagged"]
    print(f"library, sites not flagged: coverage {k:.1%} +-{se:.1%}")
    print(f"flagged outside the library: {s['false_flags']} of {s['sites_in']} in-library "
          f"sites, {s['flagged_outside']} of {s['sites_out']} outside sites")  # fmt: skip
    print(f"library pooling: {res['time_lib'] / res['profiles'] * 1e3:.0f} ms per push")
    if not a.skip_cost:
        t_lib, t_cal, ratio = cost(a.cost_profiles, a.seed)
        print(f"cost per profile, predict_many: library of 10 {t_lib * 1e3:.1f} ms, one "
              f"calibration {t_cal * 1e3:.2f} ms: ratio {ratio:.0f}")  # fmt: skip


if __name__ == "__main__":
    main()

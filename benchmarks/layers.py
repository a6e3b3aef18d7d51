"""Benchmark of the layered fit (issue 24): speed before and after, fits, batch, calibration.

On the Marsden Farm pushes in ../shared (``ci_profiles.csv`` and the SC900
export, the SC900's small cone), in one run:

1. per-push time of the one-layer fit (``predict_many``, what ``terracone
   predict`` runs) and of the layered fit with 1, 2 and 3 layers, after
   (``fit_layered``) and before (the frozen copy of the fit before issue 24,
   ``benchmarks/layered_before.py``, on a subset: it takes 0.3 s a push
   with two layers and 2-7 s with three), with the ratios to the one-layer
   fit measured in the same run;
2. the RMSD and BIC of every push against the fits recorded before issue 24
   (``tests/data/layered_rmsd_before.csv``): better, equal, worse; and how
   often two or three layers win by BIC, with the median R^2;
3. the efficiency of ``terracone batch --layers 2`` beside one layer's
   (``run_batch``), from alternating runs on the same warmed cluster:
   profiles per second end to end on W local workers divided by W times the
   per-core rate of the same work (``predict_many`` with ``detail="summary"``
   and ``fit_layered`` on a chunk of the same file, in this process);
4. with ``--coverage N``, the coverage table of the layered posterior's 90%
   intervals over N profiles drawn from its prior (the test's generator);
5. the cost of the layered posterior per push (2 and 3 layers) in one-layer
   posteriors on the same SC900 pushes, CPU time, alternating runs;
6. the cost of ``terracone predict FILE --layers 2 --json`` per push in
   ``terracone predict FILE --json`` per push, through the real CLI (issue 29):
   alternating runs on 10 copies of the SC900 export's pushes and on a file of
   its first fitted push, the per-push cost being (many - one) / (pushes - 1)
   (start-up removed), in CPU time of the child (steadier on a shared machine)
   and wall-clock; the start-up that ``--layers 2`` adds (the one-push runs)
   beside it.

Wall-clock figures on a shared machine are noisy; the ratios are measured in
one run.  Usage::

    python benchmarks/layers.py                      # all of it, modest sizes
    python benchmarks/layers.py --before 40 --copies 20 --coverage 200
    python benchmarks/layers.py --skip speed fits batch posterior --cli 7   # section 6
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]  # no shadowing

import numpy as np  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "marsden-penetrometer"
FILES = ("ci_profiles.csv", "sc900_export_2019-06-11.txt")
RECORD = ROOT / "tests" / "data" / "layered_rmsd_before.csv"


def before_module():
    """benchmarks/layered_before.py, imported by path (benchmarks/ is kept off sys.path)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("layered_before", HERE / "layered_before.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def pushes() -> dict[str, list]:
    from terracone.io import read_ci_profiles

    out = {}
    for name in FILES:
        items = read_ci_profiles(DATA / name, cone="asabe-small", on_error="collect")
        out[name] = [p for p in items if hasattr(p, "depth")]
    return out


def per_push(fn, items) -> float:
    t0 = time.perf_counter()
    for p in items:
        fn(p)
    return (time.perf_counter() - t0) / len(items)


def speed(data: dict[str, list], n_before: int) -> None:
    """Section 1: per-push times and ratios to the one-layer fit, before and after."""
    from terracone.inverse import predict_many
    from terracone.inverse.layered import fit_layered

    before = before_module()
    print("== 1. per-push time on the Marsden pushes (ms; ratio to the one-layer fit)")
    for name, items in data.items():
        fit_layered(items[-1], layers=3)  # kernels loaded, not timed
        predict_many(items[:3])
        t1 = []
        for _ in range(3):  # the one-layer fit of the whole file, three times: its best
            t0 = time.perf_counter()
            predict_many(items)
            t1.append((time.perf_counter() - t0) / len(items))
        one = min(t1)
        ok = {L: [p for p in items if p.depth.size >= 5 * L] for L in (1, 2, 3)}
        after = {L: per_push(lambda p, L=L: fit_layered(p, layers=L), ok[L]) for L in (1, 2, 3)}
        sub = {L: ok[L][:: max(1, len(ok[L]) // n_before)][:n_before] for L in (2, 3)}
        old = {L: per_push(lambda p, L=L: before.fit_before(p, layers=L), sub[L]) for L in (2, 3)}
        print(f"{name}: {len(items)} pushes; one layer (predict_many) {one * 1e3:.2f} ms")
        for L in (1, 2, 3):
            line = f"  {L} layer(s): after {after[L] * 1e3:8.2f} ms  {after[L] / one:6.1f}x"
            if L > 1:
                line += (
                    f"   before {old[L] * 1e3:8.1f} ms  {old[L] / one:7.0f}x"
                    f" ({len(sub[L])} pushes)   speed-up {old[L] / after[L]:5.0f}x"
                )
            print(line)


def fits(data: dict[str, list]) -> None:
    """Section 2: RMSD and BIC against the fits recorded before issue 24."""
    from terracone.inverse.layered import fit_layered

    with open(RECORD, newline="") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    by_id = {(n, p.id): p for n, items in data.items() for p in items}
    print("\n== 2. RMSD and BIC against the fits before issue 24 (every recorded push)")
    for L in (2, 3):
        sel = [r for r in rows if int(r["layers"]) == L and r["status"] == "ok"]
        new, old, wins, r2_1, r2_L, gaps = [], [], [], [], [], []
        for r in sel:
            res = fit_layered(by_id[(r["file"], r["profile"])], layers=L)
            new.append(res.rmsd)
            old.append(float(r["rmsd_kpa"]))
            wins.append(res.preferred_layers == L)
            r2_L.append(res.r2_ci)
            y, m1 = res.ci, res.ci_model_single
            r2_1.append(1 - np.sum((m1 - y) ** 2) / np.sum((y - y.mean()) ** 2))
            gaps.append(res.certificate["gap"])
        new, old = np.array(new), np.array(old)
        better = int(np.sum(new < old * (1 - 1e-6)))
        worse = int(np.sum(new > old * (1 + 1e-6) + 1e-6))
        rel = (new - old) / old
        n = len(sel)
        # BIC changes by N ln(SSE_new / SSE_old) = 2 N ln(RMSD_new / RMSD_old)
        print(
            f"{L} layers, {n} pushes: RMSD better {better}, equal {n - better - worse}, worse"
            f" {worse}; change median {np.median(rel):+.2%}, best {rel.min():+.1%};"
            f" BIC change median {np.median(2 * np.log(new / old)):+.3f} per point"
        )
        print(
            f"   {L} layers win by BIC on {np.mean(wins):.0%}; median R2 one layer"
            f" {np.median(r2_1):.2f}, {L} layers {np.median(r2_L):.2f}; certificate gap"
            f" median {np.median(gaps):.2%}, 90th percentile {np.quantile(gaps, 0.9):.1%}"
        )


def batch(data: dict[str, list], copies: int, workers: tuple[int, ...], rounds: int = 2) -> None:
    """Section 3: batch efficiency with --layers 2 beside one layer, from alternating runs.

    Efficiency = profiles/s of ``run_batch`` on W local workers (the cluster that
    ``terracone batch --workers W`` starts), end to end with its start-up removed
    (``wall_s - startup_s``: cluster start and kernel loading, as issue 20 measures
    it), divided by W x the per-core rate of the same work in this process
    (``predict_many`` with ``detail="summary"`` and, with layers, ``fit_layered`` per
    profile, on a chunk of the same file and of the batch's chunk size).  The runs alternate, one layer, two
    layers, ``rounds`` times, and each setting keeps its best run (the per-core rates
    likewise alternate, best of three).  The one-layer runs use 20 times more copies
    and chunks 20 times larger (their work per profile is about 20 times less): the
    same number of chunks, of about the same duration.
    """
    import pandas as pd

    from terracone.apps.batch import run_batch
    from terracone.apps.workflow import Reading
    from terracone.inverse import RunSettings, predict_many
    from terracone.inverse.layered import fit_layered

    src = pd.read_csv(DATA / "ci_profiles.csv")
    print("\n== 3. batch efficiency (copies of ci_profiles.csv, cone asabe-small)")
    chunk = data["ci_profiles.csv"]  # the file's 224 profiles: the batch fits copies of them
    settings = (1, 2)

    def work(items, layers):
        predict_many(items, settings=RunSettings(detail="summary"))
        if layers > 1:
            for p in items:
                fit_layered(p, layers=layers)

    with tempfile.TemporaryDirectory() as tmp:

        def copy_file(n: int) -> Path:
            path = Path(tmp) / f"many{n}.csv"
            parts = [src.assign(profile=src["profile"] + f"#{k}") for k in range(n)]
            pd.concat(parts).to_csv(path, index=False)
            return path

        files = {1: copy_file(20 * copies), 2: copy_file(copies)}
        chunk_size = {1: 2000, 2: 100}  # as many chunks for either (22 at 10 copies)
        reading = Reading(cone="asabe-small")
        best = dict.fromkeys(settings, math.inf)
        # a chunk of the batch's size (copies of the file's profiles, as the batch fits them)
        first = {
            L: (chunk * math.ceil(chunk_size[L] / len(chunk)))[: chunk_size[L]] for L in settings
        }
        for layers in settings:
            work(chunk[:5], layers)
        for _ in range(3):  # the per-core rates, alternating: the best of three passes
            for layers in settings:
                t0 = time.perf_counter()
                work(first[layers], layers)
                best[layers] = min(best[layers], time.perf_counter() - t0)
        rate = {L: len(first[L]) / best[L] for L in settings}
        print("   per-core rate: " + ", ".join(f"--layers {L} {rate[L]:.1f}/s" for L in settings))
        for W in workers:
            effs: dict[int, list[float]] = {L: [] for L in settings}
            for r in range(rounds):
                for layers in settings:
                    s = run_batch(
                        files[layers], Path(tmp) / f"out{layers}_{W}_{r}",
                        settings=RunSettings(layers=layers), workers=W,
                        chunk_size=chunk_size[layers], reading=reading, progress=False,
                    )  # fmt: skip
                    effs[layers].append(s.profiles / (s.wall_s - s.startup_s) / (W * rate[layers]))
            line = f"   {W} worker(s):"
            for L in settings:
                runs = ", ".join(f"{e:.2f}" for e in effs[L])
                line += f" --layers {L} efficiency {max(effs[L]):.2f} (runs {runs});"
            print(line + f" ratio {max(effs[2]) / max(effs[1]):.2f}", flush=True)


def coverage(count: int) -> None:
    """Section 4: coverage of the layered posterior's 90% intervals (the test's generator)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from scipy.stats import binom
    from test_layered_uncertainty import coverage_run

    t0 = time.perf_counter()
    hits = coverage_run(count)
    lo, hi = binom.ppf([0.001, 0.999], count, 0.9)
    print(f"\n== 4. coverage of the 90% intervals, {count} two-layer profiles from the prior")
    print(f"   (central 99.8% of Binomial({count}, 0.9): {lo:.0f} to {hi:.0f})")
    for name, v in hits.items():
        print(f"   {name:12s} {int(v.sum()):4d} / {count}  {v.mean():.3f}")
    print(f"   {(time.perf_counter() - t0) / count:.2f} s a profile (fit and posterior)")


def posterior_cost(data: dict[str, list], count: int) -> None:
    """Section 5: cost of the layered posterior per push in one-layer posteriors.

    On ``count`` pushes of the SC900 export (15 depths or more), alternating twice:
    the one-layer posterior (``posterior`` started at the fit, what ``predict --uncertainty``
    adds) and the layered posterior (``layered_posterior``, what ``--layers N`` adds to
    it) with 2 and 3 layers, default settings, fits done beforehand; CPU seconds of
    this process (steadier than wall-clock on a shared machine), each setting's best.
    """
    from terracone.inverse import predict_many
    from terracone.inverse.layered import fit_layered, layered_posterior
    from terracone.inverse.uncertainty.posterior import posterior

    items = [p for p in data["sc900_export_2019-06-11.txt"] if p.depth.size >= 15]
    items = items[:: max(1, len(items) // count)][:count]
    one = predict_many(items)
    fits = {L: [fit_layered(p, layers=L) for p in items] for L in (2, 3)}
    posterior(items[0], start=one[0], seed=1)  # kernels loaded, not timed
    for L in (2, 3):
        layered_posterior(items[0], fits[L][0], seed=1)

    def cost(L: int) -> float:
        t0 = time.process_time()
        for j, p in enumerate(items):
            if L == 1:
                posterior(p, start=one[j], seed=1)
            elif fits[L][j].ok:
                layered_posterior(p, fits[L][j], seed=1)
        return (time.process_time() - t0) / len(items)

    best = {1: math.inf, 2: math.inf, 3: math.inf}
    for _ in range(2):
        for L in (1, 2, 3):
            best[L] = min(best[L], cost(L))
    print(
        f"\n== 5. posterior cost per push, {len(items)} SC900 pushes (CPU ms; in one-layer posteriors)"
    )
    print(
        f"   one layer {best[1] * 1e3:.0f} ms; "
        + "; ".join(f"{L} layers {best[L] * 1e3:.0f} ms = {best[L] / best[1]:.2f}" for L in (2, 3))
    )


def cli_cost(rounds: int, copies: int = 10) -> None:
    """Section 6: ``predict --layers 2`` per push through the CLI, in one-layer predicts per push.

    The real command (``terracone predict FILE --cone asabe-small --json``, with
    and without ``--layers 2``) on the SC900 export's pushes repeated ``copies``
    times (one file: a per-push signal well above the start-up's scatter) and on
    a file of its first push that both settings fit; the runs alternate (one
    layer, two layers; many pushes, one push) ``rounds`` times.  Per push: the
    median over the rounds of (many - one) / (pushes - 1), which removes the
    start-up (interpreter, imports, kernels loaded from the cache, reading); CPU
    seconds of the child process (user + system, ``os.wait4``) and wall-clock.
    """
    import subprocess

    src = DATA / "sc900_export_2019-06-11.txt"
    lines = src.read_text().splitlines(keepends=True)
    pushes_ = [ln for ln in lines if ln.startswith(",,N=")]
    head = [ln for ln in lines[:5] if not ln.startswith(",,")]

    def depths(ln: str) -> int:
        return sum(v.strip() not in ("", "0") for v in ln.split(",")[3:-1])

    first = next(ln for ln in pushes_ if depths(ln) >= 10)  # two layers need 10 depths

    def run(path: Path, layers: int) -> tuple[float, float]:
        cmd = ["terracone", "predict", str(path), "--cone", "asabe-small", "--json"]
        cmd += ["--layers", str(layers)] if layers > 1 else []
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _, status, ru = os.wait4(p.pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            raise SystemExit(f"{' '.join(cmd)} failed")
        return ru.ru_utime + ru.ru_stime, time.perf_counter() - t0

    N = copies * len(pushes_)
    per: dict[tuple[int, int], list[float]] = {(L, k): [] for L in (1, 2) for k in (0, 1)}
    start: dict[tuple[int, int], list[float]] = {(L, k): [] for L in (1, 2) for k in (0, 1)}
    with tempfile.TemporaryDirectory() as tmp:
        one, many = Path(tmp) / "one_push.txt", Path(tmp) / "many_pushes.txt"
        one.write_text("".join(head + [first]))
        many.write_text("".join(head + pushes_ * copies))
        for _ in range(rounds):
            for L in (1, 2):
                t_one, t_many = run(one, L), run(many, L)
                for k in (0, 1):
                    per[(L, k)].append((t_many[k] - t_one[k]) / (N - 1))
                    start[(L, k)].append(t_one[k])
    print(
        f"\n== 6. predict through the CLI: {copies} copies of the SC900 export ({N} pushes)"
        f" against one push, median of {rounds} alternating rounds"
    )
    for k, what in ((0, "CPU"), (1, "wall")):
        pp = {L: float(np.median(per[(L, k)])) for L in (1, 2)}
        st = {L: float(np.median(start[(L, k)])) for L in (1, 2)}
        print(
            f"   {what:4s}: per push one layer {pp[1] * 1e3:6.2f} ms, --layers 2 {pp[2] * 1e3:6.2f}"
            f" ms = {pp[2] / pp[1]:5.1f}x;  start-up (one push) {st[1]:.2f} s and"
            f" {st[2]:.2f} s (+{st[2] - st[1]:.2f} s)"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=int, default=12, help="pushes timed with the old fit")
    ap.add_argument("--copies", type=int, default=10, help="copies of the CSV for the batch")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rounds", type=int, default=2, help="alternating batch runs per setting")
    ap.add_argument("--coverage", type=int, default=0, help="profiles of the coverage table")
    ap.add_argument("--posterior", type=int, default=20, help="pushes of the posterior cost")
    ap.add_argument("--cli", type=int, default=5, help="alternating rounds of the CLI cost")
    ap.add_argument(
        "--skip", nargs="*", default=[], choices=["speed", "fits", "batch", "posterior", "cli"]
    )
    args = ap.parse_args()
    if not DATA.exists():
        sys.exit(f"{DATA} not found: the Marsden pushes live in ../shared beside the repository")
    data = pushes()
    if "speed" not in args.skip:
        speed(data, args.before)
    if "fits" not in args.skip:
        fits(data)
    if "batch" not in args.skip:
        batch(data, args.copies, tuple(args.workers), args.rounds)
    if "posterior" not in args.skip:
        posterior_cost(data, args.posterior)
    if "cli" not in args.skip:
        cli_cost(args.cli)
    if args.coverage:
        coverage(args.coverage)
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    print(f"\n(load average of the machine at the end: {load})")


if __name__ == "__main__":
    main()

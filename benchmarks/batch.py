"""Benchmark of ``terracone batch`` (terracone.apps.batch.run_batch).

Measures:

0. efficiency on field-like CSV (noisy profiles, a quarter of them bad in five
   ways, metadata columns site/lat/lon): the batch rate on W local workers
   against W x the per-core fit rate of ``predict_many`` (``detail="summary"``) on
   a chunk of the same file, from alternating runs (each one's best kept),
   with the peak memory of client and workers;

and on generated noise-free profiles (25-60 depths each, known truth, written
as Parquet by streaming so that generation itself stays flat in memory):

1. throughput end to end (cluster start, reading, fitting, writing, final
   check) with 1 and 2 local workers, and how the time splits between
   reading, fitting and writing;
2. peak memory (max RSS) of the client process (which also hosts the
   scheduler, as in ``run_batch``'s local mode) and of each worker, for
   several input sizes, to show that memory does not grow with the number
   of profiles.

Every measured run is a fresh Python process.  Usage::

    python benchmarks/batch.py --only-efficiency    # the efficiency on field-like CSV
    python benchmarks/batch.py                      # all; memory at 1e4, 1e5
    python benchmarks/batch.py --million            # also memory at 1e6 (minutes)
    python benchmarks/batch.py --profiles 5000 --memory 10000   # quick
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# run as a script, benchmarks/ heads sys.path: keep it off, so no script here can shadow an
# installed package (a benchmark named coverage.py once hid the one numba probes, silently
# turning the compiled kernels off)
_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402

BATCH = 5000  # profiles generated per write


def generate(path: Path, n_profiles: int, seed: int = 0) -> None:
    """Write n_profiles noise-free CI profiles (25-60 depths) to a Parquet file, streaming."""
    from terracone import cone_index

    rng = np.random.default_rng(seed)
    schema = pa.schema(
        [
            ("profile", pa.string()),
            ("site", pa.string()),
            ("lat", pa.float64()),
            ("lon", pa.float64()),
            ("depth_m", pa.float64()),
            ("ci_kpa", pa.float64()),
        ]
    )
    tmp = path.with_suffix(".tmp")
    with pq.ParquetWriter(tmp, schema) as writer:
        for start in range(0, n_profiles, BATCH):
            B = min(BATCH, n_profiles - start)
            nz = rng.integers(25, 61, B)
            zmax = rng.uniform(0.3, 0.6, B)
            Z = int(nz.max())
            frac = np.arange(Z) / (nz[:, None] - 1)
            depth = np.minimum(frac, 1.0) * zmax[:, None]  # (B, Z), padded rows repeat zmax
            ci = cone_index(
                depth,
                kc=rng.uniform(0, 50, B)[:, None],
                kphi=rng.uniform(200, 3000, B)[:, None],
                n=rng.uniform(0.3, 1.3, B)[:, None],
                cc=rng.uniform(0, 10, B)[:, None],
                phic_deg=rng.uniform(0, 30, B)[:, None],
            )
            keep = np.arange(Z)[None, :] < nz[:, None]
            ids = np.array([f"p{start + i:08d}" for i in range(B)], dtype=object)
            site = rng.choice(np.array(["north", "south", "east"], dtype=object), B)
            table = pa.table(
                {
                    "profile": np.repeat(ids, nz),
                    "site": np.repeat(site, nz),
                    "lat": np.repeat(rng.uniform(40, 41, B), nz),
                    "lon": np.repeat(rng.uniform(-80, -79, B), nz),
                    "depth_m": depth[keep],
                    "ci_kpa": ci[keep],
                },
                schema=schema,
            )
            writer.write_table(table, row_group_size=1 << 17)
    os.replace(tmp, path)


#: The five kinds of bad profile of field-like input (a quarter of the profiles in all).
BAD_KINDS = ("nan", "text", "negative", "unordered", "short")


def generate_field_csv(path: Path, n_profiles: int, bad: float = 0.25, seed: int = 0) -> None:
    """Write field-like CI profiles to CSV, streaming: noisy readings (3%), 10-46 depths in
    cm, the metadata columns site, lat and lon, and a fraction ``bad`` of bad profiles,
    evenly of :data:`BAD_KINDS` (a NaN reading, a text cell, a negative CI, two depths out
    of order, two points only), each at a random point of its profile."""
    from terracone import cone_index

    rng = np.random.default_rng(seed)
    tmp = path.with_suffix(".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write("profile,site,lat,lon,depth_cm,ci_kpa\n")
        for start in range(0, n_profiles, BATCH):
            B = min(BATCH, n_profiles - start)
            nz = rng.integers(10, 47, B)
            Z = int(nz.max())
            depth = np.minimum(np.arange(Z)[None, :], nz[:, None] - 1) * 1.0  # cm, 1 cm steps
            ci = cone_index(
                depth / 100,
                kc=rng.uniform(0, 50, B)[:, None],
                kphi=rng.uniform(200, 3000, B)[:, None],
                n=rng.uniform(0.3, 1.3, B)[:, None],
                cc=rng.uniform(0, 10, B)[:, None],
                phic_deg=rng.uniform(0, 30, B)[:, None],
            )
            ci = ci * (1 + 0.03 * rng.standard_normal(ci.shape))
            dz = np.char.mod("%g", depth).astype(object)
            cz = np.char.mod("%.2f", ci).astype(object)
            kind = np.where(rng.uniform(size=B) < bad, rng.integers(0, len(BAD_KINDS), B), -1)
            at = (rng.uniform(size=B) * (nz - 1)).astype(int) + 1  # a point after the first
            rows = np.arange(B)
            for k, name in enumerate(BAD_KINDS):
                sel = rows[kind == k]
                if name == "nan":
                    cz[sel, at[sel]] = "NaN"
                elif name == "text":
                    cz[sel, at[sel]] = "n/a"
                elif name == "negative":
                    cz[sel, at[sel]] = "-12.5"
                elif name == "unordered":
                    dz[sel, at[sel]] = np.char.mod("%g", depth[sel, at[sel]] - 1.5).astype(object)
                else:
                    nz[sel] = 2
            site = rng.choice(np.array(["north", "south", "east", "west"], dtype=object), B)
            lat, lon = rng.uniform(40, 41, B), rng.uniform(-80, -79, B)
            head = [f"p{start + i:08d},{site[i]},{lat[i]:.6f},{lon[i]:.6f}," for i in range(B)]
            lines = [
                "".join(f"{head[i]}{dz[i, j]},{cz[i, j]}\n" for j in range(int(nz[i])))
                for i in range(B)
            ]
            f.write("".join(lines))
    os.replace(tmp, path)


def per_core_child(args: argparse.Namespace) -> None:
    """The per-core fit rate (in its own process): ``predict_many`` with ``detail="summary"``
    on the first chunk of ``chunk_size`` profiles of the input, as a batch worker gets it
    (the profiles the reader refused as the set's errors, the others unscreened), best of
    3 after one warm-up call, wall and CPU time: with predict_many's defaults (the issue's
    measure: a grid of 97 points over n) and with the batch's settings (41 points, the work
    a batch worker does); prints a JSON line."""
    from terracone.inverse.predict import RunSettings, predict_many
    from terracone.io.scan import input_files, scan_inputs
    from terracone.io.stream import ConeCache, iter_chunks
    from terracone.physics.cone import get_cone

    plan = scan_inputs(input_files(args.input))
    cones = ConeCache(get_cone("asabe-large"))
    _, chunk, n = next(iter_chunks(plan, args.chunk_size, cones, set()))
    pset = chunk.task
    pset.errors = [e for e in chunk.problems if e is not None]
    out: dict[str, float] = {"profiles": n}
    for label, extra in (("", {}), ("same_", {"n_grid": args.n_grid})):
        kw = {"settings": RunSettings(detail="summary", **extra), "chunk_size": n}
        predict_many(pset, **kw)
        best = best_cpu = float("inf")
        for _ in range(3):
            fresh = dataclasses.replace(pset)  # a new set: screened again, as a worker's is
            t, c = time.perf_counter(), time.process_time()
            res = predict_many(fresh, **kw)
            best = min(best, time.perf_counter() - t)
            best_cpu = min(best_cpu, time.process_time() - c)
        assert len(res) == n
        out.update(
            {f"{label}best_s": best, f"{label}rate": n / best, f"{label}cpu_rate": n / best_cpu}
        )
    print(json.dumps({**out, **costs(chunk, args.n_grid)}))


def costs(chunk, n_grid: int) -> dict[str, float]:
    """Cost per profile [us] in predict_many (detail="summary") of a fit, of a refusal (a
    profile its screen refuses; one the reader refused) and of carrying the chunk's
    metadata columns, on the profiles of one chunk (best of 4 each)."""
    import pyarrow as pa

    from terracone.inverse.predict import RunSettings, predict_many

    task = chunk.task
    task.errors = []
    bad = task.screen()
    good = np.array([j for j in range(len(task)) if j not in bad])
    fit_idx = np.flatnonzero(chunk.fit)[good]
    meta = pa.table({k: v.take(pa.array(fit_idx)) for k, v in chunk.meta.items()})
    sets = {
        "fit_us": task.take(good),
        "refused_us": task.take(np.array(sorted(bad))),
        "reader_refused_us": dataclasses.replace(
            task.take(np.arange(0)), errors=[e for e in chunk.problems if e is not None]
        ),
    }
    sets["metadata_us"] = dataclasses.replace(sets["fit_us"], metadata=meta)
    out = {}
    for name, pset in sets.items():
        count = len(pset) + len(pset.errors)
        best = float("inf")
        for _ in range(4):
            fresh = dataclasses.replace(pset)  # screened again
            t = time.perf_counter()
            run = RunSettings(detail="summary", n_grid=n_grid)
            predict_many(fresh, settings=run, chunk_size=max(count, 1))
            best = min(best, time.perf_counter() - t)
        out[name] = 1e6 * best / max(count, 1)
    out["metadata_us"] -= out["fit_us"]  # what the columns add to a fit
    return out


def _cpu_s() -> float:
    """CPU seconds of this process so far (a worker's, asked with client.run)."""
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def child(args: argparse.Namespace) -> None:
    """One measured run (in its own process); prints a JSON line."""
    import logging

    from terracone.apps.batch import run_batch

    if args.mode == "per-core":
        per_core_child(args)
        return
    t0 = time.perf_counter()
    batch_cpu = client_cpu = None
    if args.mode == "local":
        summary = run_batch(
            args.input, args.out, workers=args.workers, chunk_size=args.chunk_size, progress=False
        )
        workers_rss = None
    else:  # memory: our own cluster, so that the workers can be asked for their peak RSS
        import distributed

        from terracone.apps.batch import WORKER_MALLOC_ENV, _worker_environ

        with _worker_environ(WORKER_MALLOC_ENV):  # the workers run_batch would start
            cluster = distributed.LocalCluster(
                n_workers=args.workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                silence_logs=logging.ERROR,
            )
        with distributed.Client(cluster) as client:
            from terracone.apps.batch import warm_kernels

            client.run(warm_kernels)  # start-up: not counted in the CPU of the batch
            w0 = sum(client.run(_cpu_s).values())
            c0 = time.process_time()
            summary = run_batch(
                args.input,
                args.out,
                scheduler=cluster.scheduler_address,
                chunk_size=args.chunk_size,
                progress=False,
            )
            client_cpu = time.process_time() - c0
            batch_cpu = client_cpu + sum(client.run(_cpu_s).values()) - w0
            workers_rss = sorted(
                v / 1024
                for v in client.run(
                    lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
                ).values()
            )
        cluster.close()
    wall = time.perf_counter() - t0
    ru = resource.getrusage(resource.RUSAGE_SELF)
    print(
        json.dumps(
            {
                "summary": summary.as_dict(),
                "wall": wall,
                "client_rss_mb": ru.ru_maxrss / 1024,
                "client_cpu_s": ru.ru_utime + ru.ru_stime,
                "workers_rss_mb": workers_rss,
                "batch_cpu_s": batch_cpu,
                "batch_client_cpu_s": client_cpu,
            }
        )
    )


def run_child(
    mode: str,
    input: Path,
    out: Path,
    workers: int,
    chunk_size: int,
    env: dict | None = None,
    n_grid: int = 41,
) -> dict:
    cmd = [
        sys.executable,
        __file__,
        "--child",
        mode,
        "--input",
        str(input),
        "--out",
        str(out),
        "--workers",
        str(workers),
        "--chunk-size",
        str(chunk_size),
        "--n-grid",
        str(n_grid),
    ]
    full = {k: v for k, v in os.environ.items() if k not in ("TERRACONE_NUMBA", "NUMBA_CACHE_DIR")}
    full.update(env or {})
    res = subprocess.run(cmd, capture_output=True, text=True, env=full)
    if res.returncode:
        raise RuntimeError(res.stderr[-3000:])
    return json.loads(res.stdout.strip().splitlines()[-1])


def input_file(work: Path, n: int) -> Path:
    """The generated Parquet input of n profiles in ``work`` (made once)."""
    path = work / f"profiles-{n}.parquet"
    if not path.exists():
        t = time.perf_counter()
        generate(path, n)
        size = path.stat().st_size / 1e6
        print(
            f"generated {n:,} profiles -> {path.name} ({size:.1f} MB) in {time.perf_counter() - t:.1f} s"
        )
    return path


def throughput(args: argparse.Namespace, work: Path, data, counts: list[int]) -> None:
    """Throughput end to end on 1 and 2 workers, with how the time splits."""
    print(f"\nThroughput, {args.profiles:,} profiles (Parquet), local cluster, end to end:")
    print(
        f"{'run':>7} {'wall s':>7} {'prof/s':>7} {'start s':>7} {'- start':>7} {'scan s':>6} {'read s':>6} "
        f"{'fit s':>6} {'fit cpu':>7} {'write s':>7} {'check s':>7} {'client cpu':>10} "
        f"{'fit/cpu-s':>9} {'load':>5}"
    )
    src = data(args.profiles)
    runs = [(w, "compiled", {}) for w in counts]
    if not args.no_numpy:  # the same with the numpy kernels: the figure before compilation
        runs.append((max(counts), "numpy", {"TERRACONE_NUMBA": "0"}))
    fit_rate = {}
    for w, kind, env in runs:
        out = work / f"out-tp-{w}-{time.time_ns()}"
        r = run_child("local", src, out, w, args.chunk_size, env)
        s = r["summary"]
        assert s["profiles"] == args.profiles and s["success"], s["problems"]
        per_cpu = args.profiles / s["fit_cpu_s"] if s["fit_cpu_s"] else float("nan")
        warm = args.profiles / (s["wall_s"] - s["startup_s"])  # the measure
        fit_rate[(w, kind)] = (s["profiles_per_s"], per_cpu, warm)
        print(
            f"{w:>3} {kind[:3]} {s['wall_s']:>7.1f} {s['profiles_per_s']:>7.0f} {s['startup_s']:>7.1f} "
            f"{warm:>7.0f} "
            f"{s['scan_s']:>6.2f} {s['read_s']:>6.2f} {s['fit_s']:>6.1f} {s['fit_cpu_s']:>7.1f} "
            f"{s['write_s']:>7.2f} {s['verify_s']:>7.2f} {r['client_cpu_s']:>10.1f} "
            f"{per_cpu:>9.0f} {os.getloadavg()[0]:>5.1f}"
        )
    print(
        "  wall s: whole run_batch call (prof/s = profiles / wall s); start s: local cluster start;\n"
        "  - start: profiles / (wall s - start s), end to end with the start-up removed;\n"
        "  scan s: first pass over the input; read s / write s: client time reading chunks /\n"
        "  writing part files; fit s: worker time in the fit tasks (summed over chunks, wall);\n"
        "  fit cpu: their CPU seconds; client cpu: CPU seconds of the client process (reading,\n"
        "  writing, the in-process scheduler, start-up); fit/cpu-s: profiles fitted per CPU-second;\n"
        "  load: 1-minute load average after the run (2 CPUs: > 2 means other work competed);\n"
        "  com/num: compiled kernels (warm cache) or numpy kernels (TERRACONE_NUMBA=0)"
    )
    w2 = max(counts)
    if (w2, "numpy") in fit_rate:
        c, n = fit_rate[(w2, "compiled")], fit_rate[(w2, "numpy")]
        print(
            f"  compiled / numpy on {w2} workers: {c[0] / n[0]:.1f}x end to end, "
            f"{c[1] / n[1]:.1f}x per fit CPU-second"
        )
    rate, per_cpu, warm = fit_rate[(w2, "compiled")]
    print(
        f"  target >= 8,000 profiles/s on 2 workers end to end, start-up removed: "
        f"{'MET' if w2 == 2 and warm >= 8000 else 'NOT MET'} ({warm:,.0f}/s; "
        f"{rate:,.0f}/s with the cluster start); per fit CPU-second {per_cpu:,.0f} profiles"
    )


def efficiency(args: argparse.Namespace, work: Path) -> None:
    """Batch on field-like CSV against the per-core fit rate on a chunk of the same file.

    Alternating runs (batch, per-core rate, batch, per-core rate, ...), each one's best
    kept: the batch rate end to end with the start-up (cluster start, kernel loading)
    removed, against ``workers x`` the per-core rate of ``predict_many`` (``detail="summary"``)
    on the file's first chunk.  Peak memory of the client and the workers as well.
    """
    n, W = args.field_profiles, args.field_workers
    src = work / f"field-{n}.csv"
    if not src.exists():
        t = time.perf_counter()
        generate_field_csv(src, n)
        mb = src.stat().st_size / 1e6
        print(f"\ngenerated {n:,} field-like profiles -> {src.name} ({mb:.0f} MB) in "
              f"{time.perf_counter() - t:.1f} s")  # fmt: skip
    print(
        f"\nEfficiency on field-like CSV ({n:,} profiles, {int(100 * 0.25)}% bad of "
        f"{len(BAD_KINDS)} kinds, site/lat/lon columns), {W} local workers, chunk_size "
        f"{args.chunk_size}:"
    )
    print(f"{'run':>12} {'profiles/s':>11} {'wall s':>7} {'start s':>7} {'scan s':>7} {'read s':>7} "
          f"{'fit cpu':>8} {'write s':>7} {'client MB':>9} {'workers MB':>12} {'load':>5}")  # fmt: skip
    best_b, cpu_b, cpu_client = 0.0, float("inf"), 0.0
    best_c = {"": 0.0, "same_": 0.0}
    cpu_c = {"": 0.0, "same_": 0.0}
    for _ in range(args.rounds):
        out = work / f"out-eff-{time.time_ns()}"
        r = run_child("memory", src, out, W, args.chunk_size)
        s = r["summary"]
        assert s["profiles"] == n and s["success"], s["problems"]
        rate = n / (s["wall_s"] - s["startup_s"])
        best_b = max(best_b, rate)
        if r["batch_cpu_s"] < cpu_b:
            cpu_b, cpu_client = r["batch_cpu_s"], r["batch_client_cpu_s"]
        wr = ", ".join(f"{v:.0f}" for v in r["workers_rss_mb"])
        print(
            f"{'batch':>12} {rate:>11,.0f} {s['wall_s']:>7.1f} {s['startup_s']:>7.1f} "
            f"{s['scan_s']:>7.2f} {s['read_s']:>7.1f} {s['fit_cpu_s']:>8.1f} {s['write_s']:>7.1f} "
            f"{r['client_rss_mb']:>9.0f} {wr:>12} {os.getloadavg()[0]:>5.1f}"
        )
        n_grid = json.loads((out / "_run.json").read_text())["settings"]["n_grid"]
        c = run_child("per-core", src, out, 1, args.chunk_size, n_grid=n_grid)
        for k in best_c:
            best_c[k] = max(best_c[k], c[f"{k}rate"])
            cpu_c[k] = max(cpu_c[k], c[f"{k}cpu_rate"])
            name = "per core" if not k else "  (n 41)"
            print(f"{name:>12} {c[f'{k}rate']:>11,.0f} {'':>7} {'':>7} {'':>7} {'':>7} "
                  f"{c[f'{k}best_s']:>8.2f} {'':>7} {'':>9} {'':>12} {os.getloadavg()[0]:>5.1f}")  # fmt: skip
    print(
        f"  cost per profile in predict_many (last per-core run): a fit {c['fit_us']:.0f} us, "
        f"a refusal {c['refused_us']:.0f} us (by the screen) or {c['reader_refused_us']:.0f} us "
        f"(by the reader), the site/lat/lon columns {c['metadata_us']:+.0f} us"
    )
    for k, what in (
        ("", "predict_many's defaults, the issue's measure"),
        ("same_", "41 points over n as batch"),
    ):
        eff = best_b / (W * best_c[k])
        print(
            f"  per-core rate with {what}: best {best_c[k]:,.0f} profiles/s, batch best "
            f"{best_b:,.0f}/s: efficiency {eff:.2f} of {W} x per-core "
            f"(>= 0.8: {'MET' if eff >= 0.8 else 'NOT MET'}); in CPU time "
            f"{n / cpu_c[k] / cpu_b:.2f} ({cpu_c[k]:,.0f} profiles per CPU-s)"
        )
    print(
        f"  CPU time of the batch: {cpu_b:.1f} s ({cpu_client:.1f} s in the client: scan, reading,\n"
        "  writing, scheduler), kernel loading excluded; CPU time is disturbed less than wall\n"
        "  clock by other jobs on a shared machine"
    )
    print(
        "  batch: profiles / (wall - start), start = cluster start and kernel loading; per core:\n"
        "  predict_many with RunSettings(detail='summary') on the file's first chunk, best of 3, one process;\n"
        "  fit cpu: CPU seconds of the fit tasks (per-core row: its best time); load: 1-minute\n"
        "  load average after the run (2 CPUs: above 2, other work competed)"
    )


def startup(args: argparse.Namespace, work: Path, data) -> None:
    """Start-up: workers compiling into an empty numba cache, then loading from it."""
    src_s = data(args.startup_profiles)
    print(f"\nStart-up, {args.startup_profiles:,} profiles, 2 workers (fresh processes):")
    print(f"{'kernels':>22} {'wall s':>7} {'start s':>7} {'fit s':>6}")
    with tempfile.TemporaryDirectory() as cache:
        for label, env in (
            ("cold (empty cache)", {"NUMBA_CACHE_DIR": cache}),
            ("warm (cached)", {"NUMBA_CACHE_DIR": cache}),
            ("numpy (numba off)", {"TERRACONE_NUMBA": "0"}),
        ):
            out = work / f"out-st-{time.time_ns()}"
            r = run_child("local", src_s, out, 2, args.chunk_size, env)
            s = r["summary"]
            print(f"{label:>22} {s['wall_s']:>7.1f} {s['startup_s']:>7.1f} {s['fit_s']:>6.1f}")
    print("  start s includes each worker loading (or compiling) the kernels once")


def memory(args: argparse.Namespace, work: Path, data) -> None:
    """Peak memory of the client and the workers for several input sizes."""
    sizes = [int(v) for v in args.memory.split(",") if v]
    if args.million:
        sizes.append(1_000_000)
    if sizes:
        print("\nPeak memory (max RSS), 2 workers:")
        print(
            f"{'profiles':>10} {'wall s':>7} {'prof/s':>7} {'client MB':>9} {'workers MB':>14} "
            f"{'client cpu':>10} {'fit cpu':>8} {'load':>5}"
        )
    for n in sizes:
        src = data(n)
        out = work / f"out-mem-{n}-{time.time_ns()}"
        r = run_child("memory", src, out, 2, args.chunk_size)
        s = r["summary"]
        assert s["profiles"] == n and s["success"], s["problems"]
        wr = ", ".join(f"{v:.0f}" for v in r["workers_rss_mb"])
        print(
            f"{n:>10,} {s['wall_s']:>7.1f} {s['profiles_per_s']:>7.0f} {r['client_rss_mb']:>9.0f} "
            f"{wr:>14} {r['client_cpu_s']:>10.1f} {s['fit_cpu_s']:>8.1f} {os.getloadavg()[0]:>5.1f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--profiles", type=int, default=40000, help="profiles of the throughput runs")
    ap.add_argument(
        "--no-numpy",
        action="store_true",
        help="skip the run with numpy kernels (TERRACONE_NUMBA=0)",
    )
    ap.add_argument(
        "--startup-profiles", type=int, default=2000, help="input of the cold/warm start-up runs"
    )
    ap.add_argument(
        "--workers", default="1,2", help='worker counts of the throughput runs ("" to skip them)'
    )
    ap.add_argument("--chunk-size", type=int, default=2000)
    ap.add_argument("--n-grid", type=int, default=41, help=argparse.SUPPRESS)
    ap.add_argument("--memory", default="10000,100000", help="input sizes of the memory runs")
    ap.add_argument("--million", action="store_true", help="add a memory run at 1,000,000")
    ap.add_argument(
        "--field-profiles", type=int, default=60000, help="field-like CSV of the efficiency runs"
    )
    ap.add_argument("--field-workers", type=int, default=2, help="workers of the efficiency runs")
    ap.add_argument(
        "--rounds", type=int, default=2, help="alternating rounds of the efficiency runs"
    )
    ap.add_argument("--only-efficiency", action="store_true", help="skip the other measurements")
    ap.add_argument("--dir", default=None, help="work directory (default: a temporary one)")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--input", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        args.mode = args.child
        args.workers = int(args.workers)
        child(args)
        return

    import terracone

    work = Path(args.dir or tempfile.mkdtemp(prefix="terracone-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    print(
        f"terracone {terracone.__version__}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}, chunk_size {args.chunk_size}"
    )

    data = functools.partial(input_file, work)
    efficiency(args, work)
    if args.only_efficiency:
        print(f"\n(work directory: {work})")
        return
    counts = [int(v) for v in args.workers.split(",") if v.strip()]
    if counts:
        throughput(args, work, data, counts)
        startup(args, work, data)
    memory(args, work, data)
    print(f"\n(work directory: {work})")


if __name__ == "__main__":
    main()

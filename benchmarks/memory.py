"""Peak memory of ``terracone predict`` on long profiles (issue 33): resident set size per run.

Each case is one ``terracone predict FILE --json`` in its own process (its
peak resident set size from ``os.wait4``), on a generated profile of N
readings (a two-layer terrain to 0.6 m with 3 % noise, long CSV): plain
(one layer), ``--layers 2``, ``--layers 3`` and ``--uncertainty``, at N =
1,000, 10,000 and 100,000 by default.  Every run is capped (address space,
``--cap`` GB) so that a regression fails its run instead of taking the
machine.  The table gives the peak and what each option adds to the plain
run of the same file; the bound is stated in docs/layers.md and
docs/uncertainty.md (a long profile is fitted and sampled on bins).

Usage::

    python benchmarks/memory.py                       # 1k, 10k, 100k
    python benchmarks/memory.py --sizes 1000 100000 --cap 6
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CASES = {"plain": [], "--layers 2": ["--layers", "2"], "--layers 3": ["--layers", "3"],
         "--uncertainty": ["--uncertainty"]}  # fmt: skip


def write_profile(path: Path, N: int) -> None:
    """A two-layer terrain of N readings to 0.6 m (interface 0.2 m), 3 % noise, long CSV."""
    z = np.linspace(0.0, 0.6, N)
    ci = np.where(z < 0.2, 300 + 4000 * z, 1100 + 1500 * (z - 0.2))
    ci = ci * (1 + 0.03 * np.random.default_rng(1).standard_normal(N))
    with open(path, "w") as fh:
        fh.write("profile,depth_m,ci_kpa\n")
        fh.writelines(f"long,{a:.8f},{b:.4f}\n" for a, b in zip(z, ci))


def run(path: Path, extra: list[str], cap_gb: float) -> tuple[float, float, int, str]:
    """(peak RSS [MB], wall [s], exit code, what the document says) of one predict run."""
    cap = int(cap_gb * 2**30)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    cmd = ["terracone", "predict", str(path), "--cone", "asabe-small", "--json", *extra]
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.PIPE, preexec_fn=limit)
        err = p.stderr.read()
        _, status, ru = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        out.seek(0)
        try:
            prof = json.load(out)["profiles"][0]
        except ValueError:
            return ru.ru_maxrss / 1024, wall, p.returncode, err.decode()[-300:]
    lay = prof.get("layered") or {}
    post = prof.get("posterior") or {}
    said = "; ".join(lay.get("notes", []) + post.get("notes", []))
    if prof.get("lack_of_fit") and "posterior failed" in prof["lack_of_fit"]:
        said += prof["lack_of_fit"]
    return ru.ru_maxrss / 1024, wall, p.returncode, said


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10_000, 100_000])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--cap", type=float, default=8.0, help="address-space cap per run [GB]")
    args = ap.parse_args()
    print(f"peak resident set size of terracone predict (capped at {args.cap:g} GB a run)")
    print(f"{'readings':>9} {'case':>14} {'peak MB':>8} {'added MB':>9} {'wall s':>7}  exit  notes")
    with tempfile.TemporaryDirectory() as tmp:
        for N in args.sizes:
            path = Path(tmp) / f"long{N}.csv"
            write_profile(path, N)
            base = None
            for name in ["plain", *(c for c in args.cases if c != "plain")]:
                rss, wall, code, said = run(path, CASES[name], args.cap)
                base = rss if name == "plain" else base
                added = "" if name == "plain" else f"{rss - base:9.0f}"
                print(f"{N:9d} {name:>14} {rss:8.0f} {added:>9} {wall:7.1f}  {code:4d}  {said[:110]}",
                      flush=True)  # fmt: skip
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    print(f"(load average of the machine at the end: {load})")


if __name__ == "__main__":
    sys.exit(main())

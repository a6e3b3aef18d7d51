"""Benchmark of the soil callback of ``terracone export --format pychrono``.

Chrono's SCM calls the module's ``SoilParametersCallback.Set`` for grid
nodes under the wheels, step after step.  The module finds the nearest site
with a grid of buckets and a cache; this script measures, in one run, the
time per first call (no cache) and per repeated call against a plain loop
over all sites, for several numbers of sites (profiles or map cells), and
prints the ratios.  The module runs against the stand-in of
``tests/pychrono_standin.py`` (PyChrono is conda-only).

Usage::

    python benchmarks/chrono_callback.py               # 100, 1,000, 10,000 sites
    python benchmarks/chrono_callback.py --sites 300   # one size
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from pychrono_standin import DoublePtr, SCMTerrain, Vector  # noqa: E402

from terracone.apps.chrono import LocatedSoil, pychrono_module, scm_settings  # noqa: E402


class _Patch:
    """Enough of pytest's monkeypatch for :func:`pychrono_standin.install`."""

    def setitem(self, mapping, key, value):
        mapping[key] = value


def module_with(n_sites: int, folder: Path):
    import pychrono_standin

    rng = np.random.default_rng(1)
    lat = -34.5 + rng.uniform(-0.02, 0.02, n_sites)
    lon = 19.25 + rng.uniform(-0.02, 0.02, n_sites)
    soil = {"kc": 1.0, "kphi": 100.0, "n": 1.0, "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.01}
    soils = [
        LocatedSoil(f"s{k}", soil, float(a), float(b)) for k, (a, b) in enumerate(zip(lat, lon))
    ]
    path = folder / f"soil_{n_sites}.py"
    path.write_text(pychrono_module(soils, scm_settings()))
    pychrono_standin.install(_Patch())
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def brute(xy, x, y):
    d = [(px - x) ** 2 + (py - y) ** 2 for px, py in xy]
    return d.index(min(d))


def measure(n_sites: int, n_queries: int, folder: Path) -> None:
    m = module_with(n_sites, folder)
    terrain = SCMTerrain(system=None)
    cb = m.apply(terrain)
    xy = [m.to_local(lat, lon) for _, lat, lon in m.SITES]
    rng = np.random.default_rng(2)
    pts = [(float(x), float(y)) for x, y in rng.uniform(-2000, 2000, (n_queries, 2))]
    ptrs = [DoublePtr() for _ in range(8)]
    locs = [Vector(x, y, 0.0) for x, y in pts]
    t0 = time.perf_counter()
    for loc in locs:
        cb.Set(loc, *ptrs)
    first = (time.perf_counter() - t0) / n_queries
    t0 = time.perf_counter()
    for loc in locs:
        cb.Set(loc, *ptrs)
    again = (time.perf_counter() - t0) / n_queries
    k = max(1, n_queries // 10)
    t0 = time.perf_counter()
    for x, y in pts[:k]:
        brute(xy, x, y)
    plain = (time.perf_counter() - t0) / k
    print(
        f"{n_sites:7d} sites: Set {first * 1e6:8.1f} us first, {again * 1e6:6.1f} us cached; "
        f"plain loop {plain * 1e6:9.1f} us: {plain / first:6.1f}x, {plain / again:7.1f}x"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", type=int, nargs="*", default=[100, 1000, 10000])
    ap.add_argument("--queries", type=int, default=5000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sites:
            measure(n, args.queries, Path(tmp))


if __name__ == "__main__":
    main()

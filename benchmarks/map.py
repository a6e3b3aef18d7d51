"""Kriging benchmark of ``terracone map``: 1,000 and 10,000 pushes at the default resolution.

Run as ``python benchmarks/map.py`` (``--quick``: skip the global/local comparison).

The pushes lie at random on a square whose side grows with their number
(about 30 m between neighbours, as a dense field survey), with values drawn
from a gstools Gaussian random field (sd 0.35, length scale 150 m) plus a
nugget (sd 0.1): the log of a plate pressure, say.  Timed with
time.perf_counter, once each (the machine is shared: read the ratios):

* the variogram fit (gstools' binned fit, then restricted maximum likelihood
  on at most 600 pushes), the kriging of every cell of the default grid and
  the leave-one-out cross-validation, at 1,000 and 10,000 pushes;
* at 500 and 1,000 pushes on 20 m cells, global kriging (every push for
  every cell, what ``map`` does up to 250 pushes) against local
  neighbourhoods (250 nearest pushes per block of cells), with the largest
  difference of the estimates in kriging standard deviations, and how the
  global cost grows with the pushes (gstools' kriging variance costs cells x
  pushes^2: the reason for local neighbourhoods).

Printed: cells, seconds per step, the ratio 10,000 / 1,000 of the total
(10x the pushes and about 10x the cells: local kriging keeps it near 10),
and the global/local comparison.

``--pgo`` (issue 31): one P(GO) map of 10,000 pushes at 5 m cells over 4 km^2
(2 km x 2 km, 161,604 cells), ``terracone mobility MAPDIR``'s computation
(:func:`terracone.apps.go_map.go_map`: 100 conditional simulations of the
critical layer's CI, the strength and n, P(GO), the areas and the wheel
sinkage).  The pushes' values come from gstools fields (log kphi: sd 0.35,
length scale 250 m, push-to-push sd 0.2; n: sd 0.12, push-to-push sd 0.05)
with each push's parameters taken as its fit (no inverse step: the
benchmark is of the map and the simulations).  Printed: the map's time, the
wall time of the P(GO) map in this process and on a pool of 2 processes
(alternating runs, and their ratio), the simulated cell values per second,
and the simulations' check against the exact P(GO).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import gstools as gs  # noqa: E402
import numpy as np  # noqa: E402

from terracone.apps.maps.geostat import fit_variogram, krige, leave_one_out  # noqa: E402
from terracone.apps.maps.grid import choose_grid  # noqa: E402

SPACING = 30.0  # m between neighbouring pushes, about


def pushes(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    side = SPACING * np.sqrt(n)
    x, y = rng.uniform(0, side, n), rng.uniform(0, side, n)
    srf = gs.SRF(gs.Gaussian(dim=2, var=0.35**2, len_scale=150.0), seed=seed)
    z = srf((x, y), mesh_type="unstructured") + rng.normal(0, 0.1, n)
    return x, y, z


def timed(f, *args, **kwargs):
    t = time.perf_counter()
    out = f(*args, **kwargs)
    return out, time.perf_counter() - t


def run(n: int) -> dict[str, float]:
    x, y, z = pushes(n)
    grid, note = choose_grid(x, y)
    gx, gy = (a.ravel() for a in grid.centres())
    vg, t_fit = timed(fit_variogram, x, y, z)
    (m, v), t_krige = timed(krige, vg, x, y, z, gx, gy)
    cv, t_loo = timed(leave_one_out, vg, x, y, z)
    s = cv.summary(log=False)
    print(
        f"{n:>6} pushes  {gx.size:>7} cells of {grid.resolution:g} m  fit {t_fit:6.2f} s  "
        f"krige {t_krige:6.2f} s  LOO {t_loo:6.2f} s  (LOO 90% coverage {s['coverage_90']:.3f}, "
        f"nugget {vg.nugget:.4f} for 0.0100, range {vg.range:.0f} m)"
    )
    return {"fit": t_fit, "krige": t_krige, "loo": t_loo, "cells": gx.size}


def compare_global_local(n: int = 1000, resolution: float = 20.0) -> tuple[float, int]:
    """Global against local kriging of ``n`` pushes on a grid of ``resolution`` m cells."""
    x, y, z = pushes(n)
    grid, _ = choose_grid(x, y, resolution)
    gx, gy = (a.ravel() for a in grid.centres())
    vg = fit_variogram(x, y, z)
    (mg, vgl), tg = timed(krige, vg, x, y, z, gx, gy, neighbourhood="global")
    (ml, vl), tl = timed(krige, vg, x, y, z, gx, gy, neighbourhood="local")
    d = np.max(np.abs(mg - ml) / np.sqrt(vgl + vg.nugget))
    print(
        f"{n} pushes, {gx.size} cells of {resolution:g} m: global {tg:.2f} s, local {tl:.2f} s "
        f"(global/local {tg / tl:.1f}); largest difference {d:.3f} kriging sd (a new push's), "
        f"median variance ratio local/global {np.median(vl / np.maximum(vgl, 1e-300)):.3f}"
    )
    return tg, gx.size


def located_results(n: int, side: float, seed: int = 1):
    """``n`` located pushes on a 'side' m square with their parameters taken as fitted."""
    import math

    from pyproj import Transformer

    from terracone.data import TerrainParameters
    from terracone.physics.cone import cone_index_huang
    from terracone.result import PredictionResult, PredictionResults

    rng = np.random.default_rng(seed)
    x, y = 500000.0 + rng.uniform(0, side, n), 7150000.0 + rng.uniform(0, side, n)
    mesh = {"mesh_type": "unstructured"}
    model = gs.Gaussian(dim=2, var=0.35**2, len_scale=250.0)
    lk = gs.SRF(model, mean=math.log(1500.0), seed=seed)((x, y), **mesh)
    nn = gs.SRF(gs.Gaussian(dim=2, var=0.12**2, len_scale=250.0), mean=0.9, seed=seed + 1)(
        (x, y), **mesh
    )
    kphi = np.exp(lk + rng.normal(0, 0.2, n))
    nn = nn + rng.normal(0, 0.05, n)
    kc = kphi * 11.0 / 1500.0
    depth = np.arange(0.0, 0.451, 0.025)
    ci = cone_index_huang(depth[None, :], kc=kc[:, None], kphi=kphi[:, None], n=nn[:, None],
                          cc=5.0, phic_deg=50.0)  # fmt: skip
    ci *= 1 + 0.05 * rng.standard_normal(ci.shape)
    lon, lat = Transformer.from_crs("EPSG:32735", "EPSG:4326", always_xy=True).transform(x, y)
    res = [
        PredictionResult(f"p{i}", "ok", params=TerrainParameters(kc[i], kphi[i], nn[i], 5.0, 50.0),
                         depth=depth, ci=ci[i], metadata={"lat": lat[i], "lon": lon[i]})
        for i in range(n)
    ]  # fmt: skip
    return PredictionResults(res, {"calibration": "generated"})


def pgo(n: int = 10000, side: float = 2000.0, simulations: int = 100) -> None:
    """One P(GO) map of ``n`` pushes at 5 m cells, here and on 2 processes, alternating."""
    import tempfile
    from concurrent.futures import ProcessPoolExecutor

    from terracone.apps.go_map import go_map, go_map_document
    from terracone.apps.maps import map_survey, write_map
    from terracone.apps.vehicles import vehicle_from_dict

    wheel = {"load": "20 kN", "diameter": "1 m", "width": "0.3 m"}
    vehicle = vehicle_from_dict({"name": "truck", "kind": "wheeled", "mobility_index": 60,
                                 "drive": "all", "wheel": wheel})  # fmt: skip
    res = located_results(n, side)
    layer = (6 * 0.0254, 12 * 0.0254)  # the critical layer of a wheeled vehicle, one pass
    m, t_map = timed(map_survey, res, layers=[layer], resolution=5.0)
    cells = m.grid.width * m.grid.height
    ci = m[next(q.name for q in m.quantities if q.name.startswith("ci_"))]
    ri = vehicle.vci(1) / float(np.median(ci.values))  # the field's median point at the VCI
    print(f"P(GO) map: {n:,} pushes, {cells:,} cells of 5 m; the map itself {t_map:.1f} s")
    with tempfile.TemporaryDirectory() as tmp:
        write_map(m, tmp)
        times: dict[str, list[float]] = {"here": [], "2 processes": []}
        with ProcessPoolExecutor(2) as pool:
            for _ in range(2):
                for name, p in (("here", None), ("2 processes", pool)):
                    g, t = timed(go_map, tmp, vehicle, remolding_index=ri,
                                 simulations=simulations, pool=p)  # fmt: skip
                    times[name].append(t)
                    print(f"  {name:>12}: {t:6.1f} s")
        doc = go_map_document(g)
    here, two = min(times["here"]), min(times["2 processes"])
    values = 3 * cells * simulations
    mc = doc["p_go"]["monte_carlo"]
    print(
        f"P(GO) map of {n:,} pushes, {cells:,} cells x {simulations} simulations x 3 fields: "
        f"{here:.1f} s here, {two:.1f} s on 2 processes (ratio {here / two:.2f}); "
        f"{values / two / 1e6:.2f} million simulated cell values per second; simulations' GO "
        f"frequency against P(GO): rms standardised difference "
        f"{mc['rms_standardised_difference']:.3f} (1 expected)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the global/local comparison")
    ap.add_argument("--pgo", action="store_true", help="only the 10,000-push P(GO) map")
    args = ap.parse_args()
    if args.pgo:
        pgo()
        return
    small, large = run(1000), run(10000)
    t1 = small["fit"] + small["krige"] + small["loo"]
    t10 = large["fit"] + large["krige"] + large["loo"]
    print(
        f"10,000 / 1,000 pushes: {t10 / t1:.1f}x the time for {large['cells'] / small['cells']:.1f}x "
        f"the cells (kriging alone {large['krige'] / small['krige']:.1f}x)"
    )
    if not args.quick:
        t500, c500 = compare_global_local(500)
        t1000, c1000 = compare_global_local(1000)
        print(
            f"global kriging, 1,000 / 500 pushes ({c1000 / c500:.1f}x the cells): "
            f"{t1000 / t500:.1f}x the time"
        )


if __name__ == "__main__":
    main()

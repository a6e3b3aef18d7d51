"""Probability-of-GO maps: ``terracone mobility MAPDIR --vehicle V.json``.

Where will this vehicle get through a surveyed area, and how sure are we?
From a ``terracone map`` directory (:mod:`terracone.apps.maps`) and a vehicle
(:func:`terracone.apps.vehicles.load_vehicle`):

* **P(GO)** at every cell: the probability that the rating cone index of the
  critical layer at a point of the cell reaches the vehicle cone index,
  P(RCI >= VCI) with RCI = CI x RI (NRMM, fine-grained soils [1]_; the
  soil class, the critical layer and VCI as :mod:`terracone.apps.mobility`
  chooses them).  The mean CI of the critical layer is the map's CI layer
  over it, kriged in log space; the value at a point is the smooth field
  plus the nugget, so log CI at a point is normal with the map's kriged
  median and the variance of its point band, kriging variance plus nugget
  (a t distribution for a field without spatial structure), and
  ``P(GO) = 1 - Phi((log(VCI / RI) - m) / s)`` exactly.  This is the limit
  of the GO frequency of the conditional simulations
  (:mod:`terracone.apps.maps.simulation`), whose frequency is compared with
  it (``p_go.monte_carlo``);
* **areas**: GO at 90% confidence (P(GO) >= 0.9), NO-GO at 90% (P(GO) <=
  0.1), uncertain between, the expected GO area (the sum of P(GO) times the
  cell area) and, from the simulations, the distribution of the GO area of
  one realisation of the whole field (its median and 90% band), which needs
  the cells jointly;
* **wheel sinkage** (Bekker [2]_ [3]_) at every cell, from simulated
  strength kc/b + kphi and n (the map's two kriged fields, simulated
  independently as the map kriges them), split into kc and kphi as the map
  splits them: the median and the 90% band over the simulations.

A coarse-grained soil has no RCI and no VCI here (COARSE_NOTE of
:mod:`terracone.apps.mobility`): it gets no P(GO), and the answer says why.

References
----------
.. [1] Priddy, J.D., Willoughby, W.E. (2006). Clarification of vehicle cone
   index with reference to mean maximum pressure. J. Terramechanics 43(2), 85-96.
.. [2] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
.. [3] Wong, J.Y. (2008). Theory of Ground Vehicles, 4th ed., ch. 2.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from terracone.apps.maps.directory import MapDirectory, read_map_directory
from terracone.apps.maps.simulation import Simulation, simulate
from terracone.apps.mobility import COARSE_NOTE, NO_CALIBRATION_NOTE, LayerChoice
from terracone.apps.trafficability import critical_layer_rule
from terracone.apps.vehicles import Vehicle, load_vehicle
from terracone.inverse.bounds import Bounds
from terracone.physics import units as u
from terracone.physics import vehicle as phys
from terracone.resultunits import convert_array, from_si

__all__ = [
    "SCHEMA",
    "CONFIDENCE",
    "DEFAULT_SIMULATIONS",
    "GoMap",
    "GoMapRun",
    "go_map",
    "go_map_document",
    "run_go_map",
    "simulation_pool",
    "write_go_map",
]

#: Name and version of the document of ``terracone mobility MAPDIR``.
SCHEMA = "terracone.mobility-map/1"
#: GO at this confidence: P(GO) >= CONFIDENCE; NO-GO: P(GO) <= 1 - CONFIDENCE.
CONFIDENCE = 0.9
#: Conditional simulations by default.
DEFAULT_SIMULATIONS = 100
#: Level of the sinkage band and of the simulated GO area's band.
LEVEL = 0.9
ASSUMED_SOIL_NOTE = (
    "soil class not given (--soil): assumed fine-grained (RCI = CI x RI); a map keeps no "
    "soil class of its pushes"
)
LAYER_TOLERANCE = 1e-4  # m: a map's CI layer matches the critical layer within 0.1 mm


@dataclass
class GoMap:
    """A P(GO) map and the wheel sinkage of a vehicle over a map's cells (SI inside).

    Attributes
    ----------
    directory : MapDirectory
    vehicle : Vehicle
    passes : int
    soil : {"fine", "coarse"}
    assumed : bool
        The soil class was assumed.
    layer : (top, bottom, rule, source) or None
        The critical layer [m] and what chose it.
    quantity : str or None
        The map's CI layer used.
    ri, vci, threshold : float or None
        Remolding index [-], VCI [kPa], and the CI a point needs, VCI / RI [kPa].
    p_go : ndarray or None
        P(GO) of every cell (NaN where the map is masked); None with ``p_go_reason``.
    frequency : ndarray or None
        The simulations' GO frequency of every cell.
    go_area : ndarray or None
        The GO area of each simulation [m^2].
    sinkage : (median, lo, hi) of ndarray or None
        Wheel sinkage [m]; None with ``sinkage_reason``.
    simulations, seed : int
    clipped : dict
        Share of each simulated field's circulant eigenvalues set to 0.
    notes : list of str
    """

    directory: MapDirectory
    vehicle: Vehicle
    passes: int
    soil: str
    assumed: bool
    simulations: int
    seed: int
    layer: tuple[float, float, str, str] | None = None
    quantity: str | None = None
    ri: float | None = None
    vci: float | None = None
    threshold: float | None = None
    p_go: np.ndarray | None = None
    p_go_reason: str | None = None
    frequency: np.ndarray | None = None
    go_area: np.ndarray | None = None
    sinkage: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    sinkage_reason: str | None = None
    clipped: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def cell_area(self) -> float:
        """Area of one cell [m^2 of the map CRS]."""
        return self.directory.grid.resolution**2

    @property
    def evaluated_any(self) -> bool:
        """Whether a P(GO) map or a sinkage map was made."""
        return self.p_go is not None or self.sinkage is not None


def _layer(
    d: MapDirectory, soil: str, vehicle: Vehicle, passes: int, choice: LayerChoice
) -> tuple[tuple[float, float, str, str], str]:
    """The critical layer and the map's CI layer over it (or a ValueError saying what to do)."""
    if choice.mode == "weakest":
        raise ValueError(
            "--critical-layer weakest: a map holds the mean CI over fixed layers, not the "
            "profiles; give the rule (the default) or --layer with one of the map's layers"
        )
    if choice.mode == "layer":
        top, bottom = choice.layer
        layer = (top, bottom, "--layer", "the --layer option")
    else:
        rule = critical_layer_rule(soil, vehicle.kind, passes)
        layer = (rule.top, rule.bottom, rule.rule, rule.source)
    layers = d.ci_layers()
    for name, (lo, hi) in layers.items():
        if abs(lo - layer[0]) <= LAYER_TOLERANCE and abs(hi - layer[1]) <= LAYER_TOLERANCE:
            return layer, name
    cm = f"{layer[0] * 100:.4g}:{layer[1] * 100:.4g}cm"
    have = ", ".join(layers) or "none"
    raise ValueError(
        f"{d.path}: the map has no CI layer over the critical layer {layer[0]:.4g}-"
        f"{layer[1]:.4g} m ({layer[2]}: {layer[3]}); its CI layers: {have}. Make the map "
        f"with --layers-ci {cm} (or give --layer with one of its layers)"
    )


def _p_go(out: GoMap, sim: Simulation) -> None:
    """P(GO), the simulations' GO frequency and GO area, in place."""
    t = math.log(out.threshold)
    out.p_go = sim.exceedance(t)
    go = sim.realisations >= np.float32(t)
    out.frequency = np.where(np.isfinite(sim.mean), go.mean(axis=0), np.nan)
    out.go_area = go.reshape(sim.count, -1).sum(axis=1) * out.cell_area
    if sim.clipped > 0:
        out.clipped[out.quantity] = sim.clipped


def _sinkage(out: GoMap, d: MapDirectory, pool: Any, progress: Any) -> None:
    """The wheel sinkage's median and band from simulated strength and n, in place."""
    wheel, s_q = out.vehicle.wheel, d.strength()
    if wheel is None:
        out.sinkage_reason = "the vehicle file gives no wheel: no Bekker sinkage"
        return
    if s_q is None:
        out.sinkage_reason = (
            "the map records no strength kc/b + kphi (made before issue 31): remake it with "
            "terracone map for the wheel sinkage"
        )
        return
    if d.doc["quantities"].get("n", {}).get("skipped"):
        out.sinkage_reason = f"the map has no n: {d.doc['quantities']['n']['skipped']}"
        return
    n_q = d.quantity("n")
    seeds = np.random.SeedSequence([out.seed, 1]).spawn(2)
    sims = []
    for q, seed in zip((s_q, n_q), seeds):
        sim = simulate(q.variogram, q.x, q.y, q.z, d.grid, out.simulations, seed=seed, pool=pool,
                       progress=progress)  # fmt: skip
        if sim.clipped > 0:
            out.clipped[q.name] = sim.clipped
        sims.append(sim.realisations.reshape(out.simulations, -1))
    p = d.doc["parameters"]
    share, b = float(p["kc_share"]), float(p["reference_size_m"])
    lo_n, hi_n = Bounds().n
    ok = np.flatnonzero(np.all(np.isfinite(sims[0]), 0) & np.all(np.isfinite(sims[1]), 0))
    bands = np.full((3, sims[0].shape[1]), np.nan)
    clipped_n = 0
    for part in np.array_split(ok, max(1, ok.size // 20000)):
        strength = np.exp(sims[0][:, part].astype(float))
        n = sims[1][:, part].astype(float)
        clipped_n += int(np.sum((n < lo_n) | (n > hi_n)))
        z = phys.sinkage_rigid_wheel_bekker(
            wheel.load, diameter=wheel.diameter, width=wheel.width, kc=share * strength * b,
            kphi=(1.0 - share) * strength, n=np.clip(n, lo_n, hi_n),
        )  # fmt: skip
        bands[:, part] = np.quantile(z, [0.5, (1 - LEVEL) / 2, (1 + LEVEL) / 2], axis=0)
    shape = (d.grid.height, d.grid.width)
    out.sinkage = tuple(a.reshape(shape) for a in bands)
    if clipped_n:
        out.notes.append(
            f"{clipped_n / max(ok.size * out.simulations, 1):.2%} of the simulated n fell "
            f"outside the fit's bounds [{lo_n:g}, {hi_n:g}] and were held at them for the sinkage"
        )
    if not d.doc.get("calibrated"):
        out.notes.append(NO_CALIBRATION_NOTE)


def go_map(
    directory: str | os.PathLike[str] | MapDirectory,
    vehicle: Vehicle,
    *,
    passes: int = 1,
    soil: str | None = None,
    choice: LayerChoice | None = None,
    remolding_index: float | None = None,
    simulations: int = DEFAULT_SIMULATIONS,
    seed: int = 0,
    pool: Any = None,
    progress: Any = None,
) -> GoMap:
    """P(GO) of every cell of a map for a vehicle, the areas, and the wheel sinkage.

    Parameters
    ----------
    directory : path or MapDirectory
        A ``terracone map`` output directory.
    vehicle : Vehicle
    passes : {1, 50}
    soil : {"fine", "coarse"}, optional
        Soil class of the area; default fine-grained, assumed and said.
    choice : LayerChoice, optional
        The critical layer: by rule (default) or ``--layer`` (a layer the map has).
    remolding_index : float, optional
        RI in (0, 2]; needed for the P(GO) of a fine-grained soil.
    simulations : int
        Conditional simulations (>= 2).
    seed : int
        Seed of the simulations.
    pool : object with ``map``, optional
        Runs the conditioning of blocks of cells (a process pool, a Dask client).
    progress : callable, optional
        ``progress(k)`` after every ``k`` cells simulated (three fields: CI, strength, n).

    Returns
    -------
    GoMap

    Raises
    ------
    ValueError
        Not a map directory; RI outside (0, 2] or missing for a fine-grained
        soil; a critical layer the map has no CI layer over; ``passes`` not 1
        or 50; fewer than 2 simulations.
    """
    d = directory if isinstance(directory, MapDirectory) else read_map_directory(directory)
    if passes not in (1, 50):
        raise ValueError(f"passes must be 1 or 50, got {passes!r}")
    if simulations < 2:
        raise ValueError(f"--simulations must be >= 2 (got {simulations})")
    if remolding_index is not None and not 0 < remolding_index <= 2:
        raise ValueError(f"--remolding-index: {remolding_index:g} outside (0, 2]")
    if soil is not None and soil not in ("fine", "coarse"):
        raise ValueError(f"--soil: 'fine' or 'coarse', got {soil!r}")
    out = GoMap(d, vehicle, passes, soil or "fine", soil is None, simulations, seed)
    out.notes += list(vehicle.notes) + ([ASSUMED_SOIL_NOTE] if soil is None else [])
    if out.soil == "coarse":
        out.p_go_reason = COARSE_NOTE
    else:
        out.vci, why = vehicle.vci_of(passes)
        if out.vci is None:
            out.p_go_reason = f"{why}: no P(GO)"
    if out.p_go_reason is None:
        if remolding_index is None:
            raise ValueError(
                "--remolding-index: a P(GO) map of a fine-grained soil needs the remolding "
                "index RI (RCI = CI x RI); a map keeps none"
            )
        out.layer, out.quantity = _layer(d, out.soil, vehicle, passes, choice or LayerChoice())
        out.ri = float(remolding_index)
        out.threshold = out.vci / out.ri  # RCI = CI x RI >= VCI  <=>  CI >= VCI / RI
        q = d.quantity(out.quantity)
        sim = simulate(q.variogram, q.x, q.y, q.z, d.grid, simulations,
                       seed=np.random.SeedSequence([seed, 0]), pool=pool, progress=progress)  # fmt: skip
        _p_go(out, sim)
        del sim
        if "keeps no measured CI" in str(d.doc["quantities"][out.quantity].get("source")):
            out.notes.append(
                f"{out.quantity}: the map's CI comes from each push's fitted model (the results "
                "kept no measured CI), so P(GO) rests on the fits"
            )
    _sinkage(out, d, pool, progress)
    return out


def _area(out: GoMap) -> dict[str, Any]:
    a = out.cell_area
    total = float(out.directory.grid.width * out.directory.grid.height * a)
    if out.p_go is None:
        return {"go_90": None, "no_go_90": None, "uncertain": None, "expected_go": None,
                "masked": None, "total": total, "go_simulated": None}  # fmt: skip
    p = out.p_go[np.isfinite(out.p_go)]
    lo, hi = 1 - CONFIDENCE, CONFIDENCE
    sim = np.quantile(out.go_area, [0.5, (1 - LEVEL) / 2, (1 + LEVEL) / 2])
    return {
        "go_90": float(np.sum(p >= hi) * a),
        "no_go_90": float(np.sum(p <= lo) * a),
        "uncertain": float(np.sum((p > lo) & (p < hi)) * a),
        "expected_go": float(p.sum() * a),
        "masked": float((out.p_go.size - p.size) * a),
        "total": total,
        "go_simulated": {
            "median": float(sim[0]),
            "lo": float(sim[1]),
            "hi": float(sim[2]),
            "level": LEVEL,
        },  # fmt: skip
    }


def _monte_carlo(out: GoMap) -> dict[str, Any] | None:
    """How the simulations' GO frequency compares with P(GO) (binomial standard error)."""
    if out.p_go is None:
        return None
    ok = np.isfinite(out.p_go)
    p, f = out.p_go[ok], out.frequency[ok]
    inner = (p > 1e-9) & (p < 1 - 1e-9)
    se = np.sqrt(p[inner] * (1 - p[inner]) / out.simulations)
    return {
        "simulations": out.simulations,
        "standard_error_at_0.5": math.sqrt(0.25 / out.simulations),
        "mean_abs_difference": float(np.mean(np.abs(f - p))) if p.size else None,
        "rms_standardised_difference": (
            float(np.sqrt(np.mean(((f[inner] - p[inner]) / se) ** 2))) if inner.any() else None
        ),
        "note": "P(GO) is exact under the map's model; the simulations' frequency estimates it "
        "with the standard error sqrt(p (1 - p) / N); its standardised difference should have "
        "an rms near 1 (neighbouring cells share their errors)",
    }


SIMULATION_METHOD = (
    "conditioning by kriging on the map's grid: the map's kriging weights and neighbourhoods, "
    "an unconditional field of the fitted covariance by circulant embedding (FFT), each push's "
    "error and each point's variation drawn from the nugget (terracone.apps.maps.simulation)"
)
P_GO_METHOD = (
    "P(RCI >= VCI) at a point of each cell, RCI = CI x RI: log CI at a point is normal with the "
    "map's kriged median and the variance of its point band (kriging variance plus nugget; "
    "Student's t for a field without spatial structure), the limit of the simulations' GO "
    "frequency"
)


def _length(v: float | None, units: str) -> float | None:
    return from_si(v, "length", units)


def _pressure(v: float | None, units: str) -> float | None:
    return from_si(v, "pressure", units)


def go_map_document(result: GoMap, units: str = "si", *, input: str | None = None) -> dict:
    """The JSON document (schema :data:`SCHEMA`, docs/mobility.md) of a P(GO) map, in ``units``.

    Pressures in kPa or psi, lengths in m or in; areas always in m^2 of the map's CRS.
    """
    from terracone import __version__

    units = u.check_system(units)
    r, d = result, result.directory
    lay = r.layer
    sink = None
    if r.sinkage is not None:
        sink = float(np.nanmedian(r.sinkage[0])) if np.isfinite(r.sinkage[0]).any() else None
    return {
        "schema": SCHEMA,
        "terracone": __version__,
        "command": "mobility",
        "input": input if input is not None else str(d.path),
        "units": units,
        "map": {
            "directory": str(d.path),
            "crs": d.crs,
            "resolution": d.grid.resolution,
            "grid": d.doc.get("grid"),
            "calibrated": d.doc.get("calibrated"),
        },
        "vehicle": r.vehicle.as_dict(units, r.passes),
        "passes": r.passes,
        "vci": _pressure(r.vci, units),
        "soil_class": r.soil,
        "assumed": r.assumed,
        "critical_layer": {
            "top": _length(lay[0] if lay else None, units),
            "bottom": _length(lay[1] if lay else None, units),
            "rule": lay[2] if lay else None,
            "source": lay[3] if lay else None,
            "quantity": r.quantity,
        },
        "remolding_index": r.ri,
        "threshold_ci": _pressure(r.threshold, units),
        "p_go": {
            "file": None if r.p_go is None else "p_go.tif",
            "reason": r.p_go_reason,
            "method": None if r.p_go is None else P_GO_METHOD,
            "confidence": CONFIDENCE,
            "monte_carlo": _monte_carlo(r),
        },
        "area_m2": _area(r),
        "simulations": r.simulations,
        "seed": r.seed,
        "simulation": {"method": SIMULATION_METHOD, "embedding_clipped": dict(r.clipped)},
        "sinkage": {
            "file": None if r.sinkage is None else "sinkage.tif",
            "reason": r.sinkage_reason,
            "units": u.length_unit(units),
            "bands": ["median", "lo", "hi"],
            "level": LEVEL,
            "median_of_cells": _length(sink, units),
        },
        "notes": list(dict.fromkeys(r.notes)),
    }


def _write_raster(path: Path, bands, names, meanings, unit: str, d: MapDirectory, **tags) -> None:
    """A GeoTIFF on the map's grid: each band described by its name, its meaning in the band's
    ``meaning`` tag (as :func:`terracone.apps.maps.writers.band_description` words it)."""
    import rasterio
    from rasterio.crs import CRS
    from rasterio.transform import Affine

    g = d.grid
    with rasterio.open(
        path, "w", driver="GTiff", width=g.width, height=g.height, count=len(bands),
        dtype="float32", crs=CRS.from_user_input(d.crs), transform=Affine(*g.transform),
        nodata=float("nan"), compress="deflate",
    ) as dst:  # fmt: skip
        dst.write(np.stack(bands).astype("float32"))
        for i, (name, meaning) in enumerate(zip(names, meanings), 1):
            dst.set_band_description(i, name)
            dst.update_tags(i, meaning=meaning)
        dst.units = (unit,) * len(bands)
        dst.update_tags(software="terracone", **tags)


def write_go_map(
    result: GoMap, directory: str | os.PathLike[str], units: str = "si", *, input: str | None = None
) -> tuple[dict[str, Path], dict[str, Any]]:
    """Write ``p_go.tif``, ``sinkage.tif`` and ``mobility.json`` to ``directory`` (created).

    ``p_go.tif``: one band, P(GO) in [0, 1]; ``sinkage.tif``: bands median,
    lo (5%) and hi (95%) of the wheel sinkage at a point [m or in]; both on
    the map's grid and CRS, NaN where the map is masked.  Returns the files
    by name and the document.
    """
    units = u.check_system(units)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    doc = go_map_document(result, units, input=input)
    files: dict[str, Path] = {}
    d = result.directory
    if result.p_go is not None:
        files["p_go"] = out / "p_go.tif"
        _write_raster(files["p_go"], [result.p_go], ["p_go"], ["P(RCI >= VCI) at a point [-]"],
                      "-", d, quantity="p_go", vehicle=result.vehicle.name,
                      vci=f"{doc['vci']} {u.pressure_unit(units)}",
                      critical_layer=str(result.quantity))  # fmt: skip
    if result.sinkage is not None:
        files["sinkage"] = out / "sinkage.tif"
        lu = u.length_unit(units)
        meanings = [f"median [{lu}]", f"5%, value at a point [{lu}]",
                    f"95%, value at a point [{lu}]"]  # fmt: skip
        _write_raster(files["sinkage"], [convert_array(a, "length", units) for a in result.sinkage],
                      ["median", "lo", "hi"], meanings, lu, d, quantity="wheel sinkage",
                      vehicle=result.vehicle.name, band_names="median,lo,hi")  # fmt: skip
    files["json"] = out / "mobility.json"
    from terracone.result import dumps

    files["json"].write_text(dumps(doc) + "\n")
    return files, doc


@contextmanager
def simulation_pool(workers: int | None = None, scheduler: str | None = None) -> Iterator[Any]:
    """The pool that conditions a map's simulations: None (this process), a process pool of
    ``workers``, or a client of the Dask scheduler at ``scheduler``; closed after.

    Raises
    ------
    ValueError
        Both given, ``workers`` < 1, or a scheduler that cannot be reached.
    """
    if workers is not None and scheduler is not None:
        raise ValueError("give workers or a scheduler, not both")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if scheduler is not None:
        from distributed import Client

        try:
            client = Client(scheduler, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from None
        with client:
            yield client
        return
    if workers is None or workers <= 1:
        yield None
        return
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=workers) as pool:
        yield pool


@dataclass
class GoMapRun:
    """What :func:`run_go_map` computed and wrote.

    ``result``: the P(GO) and sinkage map; ``files``: the files written, by
    name; ``document``: ``mobility.json`` (the command's JSON document).
    """

    result: GoMap
    files: dict[str, Path]
    document: dict[str, Any]

    @property
    def evaluated_any(self) -> bool:
        """Whether a P(GO) map or a sinkage map was made."""
        return self.result.evaluated_any


def run_go_map(
    directory: str | os.PathLike[str] | MapDirectory,
    vehicle: Vehicle | str | os.PathLike[str],
    out: str | os.PathLike[str],
    units: str = "si",
    *,
    passes: int = 1,
    soil: str | None = None,
    choice: LayerChoice | None = None,
    remolding_index: float | None = None,
    simulations: int | None = None,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[int], Any] | None = None,
) -> GoMapRun:
    """What ``terracone mobility MAPDIR`` computes: :func:`go_map` on a pool, then written.

    Parameters
    ----------
    directory : path or MapDirectory
        A ``terracone map`` output directory.
    vehicle : Vehicle or path
        A vehicle, or its file (:func:`~terracone.apps.vehicles.load_vehicle`).
    out : path
        The directory written (:func:`write_go_map`).
    units : {"si", "us"}
        Units of the files and the document.
    passes, soil, choice, remolding_index, seed
        As :func:`go_map` takes them.
    simulations : int, optional
        Conditional simulations (default :data:`DEFAULT_SIMULATIONS`).
    workers, scheduler : optional
        The pool of the conditioning (:func:`simulation_pool`).
    progress : callable, optional
        ``progress(k)`` after every ``k`` cells simulated (default: a tqdm
        bar on a terminal).

    Returns
    -------
    GoMapRun
    """
    from tqdm import tqdm

    veh = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle)
    d = directory if isinstance(directory, MapDirectory) else read_map_directory(directory)
    n = DEFAULT_SIMULATIONS if simulations is None else simulations
    cells = d.grid.width * d.grid.height
    with (
        simulation_pool(workers, scheduler) as pool,
        tqdm(
            total=3 * cells,
            desc="simulating cells",
            unit="cell",
            leave=False,
            disable=None if progress is None else True,
        ) as bar,
    ):
        result = go_map(d, veh, passes=passes, soil=soil, choice=choice,
                        remolding_index=remolding_index, simulations=n, seed=seed, pool=pool,
                        progress=bar.update if progress is None else progress)  # fmt: skip
    given = None if isinstance(directory, MapDirectory) else str(directory)
    files, doc = write_go_map(result, out, units, input=given)
    return GoMapRun(result, files, doc)

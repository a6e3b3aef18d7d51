"""The files of a map: GeoTIFF rasters, GeoParquet pushes, the cells' table and ``map.json``.

In the output directory:

* ``<quantity>.tif``: one GeoTIFF per quantity (rasterio), float32, five
  bands (:data:`~terracone.apps.maps.workflow.BANDS`): median, lo (5%) and
  hi (95%) of the local mean, point_lo (5%) and point_hi (95%) of the value
  at a point, in the map's unit system; the CRS set, NaN as nodata (cells
  beyond the variogram's range), each band's description (its name first,
  then which interval it bounds, then its unit: ``point_lo (5%, value at a
  point) [kPa]``) and unit, the quantity and its variogram in the tags;
* ``points.parquet``: the located pushes as GeoParquet (geopandas), points
  in the map CRS with lat, lon, x, y, each push's value of each quantity
  and its ``strength`` kc/b + kphi [SI], from which the cells' kc and kphi
  are kriged;
* ``cells.parquet``: one row per cell that has a value (plain Parquet, SI):
  the centre (x, y in the map CRS, lat, lon), each quantity's median, lo,
  hi, point_lo and point_hi, and the cell's kc, kphi, n, cc, phic_deg for
  simulators (:func:`read_map_cells`);
* ``map.json``: :func:`map_document`.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from terracone.apps.maps.workflow import BANDS, LEVEL, QuantityMap, TerrainMap
from terracone.data import TerrainParameters
from terracone.physics import units as u
from terracone.resultunits import from_si

__all__ = [
    "MAP_SCHEMA",
    "LocatedParameters",
    "is_map_directory",
    "band_description",
    "map_document",
    "read_map_cells",
    "write_map",
]

PathLike = str | os.PathLike[str]
#: Name and version of ``map.json`` (also in the Arrow metadata of ``cells.parquet``).
MAP_SCHEMA = "terracone.map/1"
_CELLS_KEY = b"terracone.map"


class LocatedParameters(NamedTuple):
    """The terrain parameters of one map cell at its centre (WGS 84 degrees)."""

    lat: float
    lon: float
    params: TerrainParameters


def _f(v: Any) -> float | None:
    return None if v is None or not math.isfinite(float(v)) else float(v)


def _quantity_dict(m: QuantityMap, units: str) -> dict[str, Any]:
    q = m.quantity
    d: dict[str, Any] = {
        "file": None if m.skipped else f"{q.name}.tif",
        "units": q.unit(units),
        "description": q.label,
        "source": q.source,
        "space": "log" if q.log else "linear",
        "pushes": int(np.isfinite(m.values).sum()),
        "excluded": [{"id": i, "reason": r} for i, r in m.excluded],
    }
    if q.plate is not None:
        d["plate_radius"], d["sinkage"] = from_si(q.plate, "length", units)
    if q.layer is not None:
        d["layer"] = from_si(q.layer, "length", units)
    if m.skipped:
        d["skipped"] = m.skipped
        return d
    vg = m.variogram.as_dict()
    vg["estimation_variance"] = _f(m.estimation_variance)
    vg["push_to_push_variance"] = (
        None
        if not math.isfinite(m.estimation_variance)
        else max(vg["nugget"] - m.estimation_variance, 0.0)
    )
    d["variogram"] = vg
    cv = m.cross_validation.summary(q.log)
    cv["rmse"] = float(q.from_si(cv["rmse"], units))
    d["cross_validation"] = cv
    d["point_cross_validation"] = m.cross_validation.point_summary()
    d["bands"] = dict(BANDS)
    d["pooled"] = (
        None
        if m.pooled is None
        else dict(zip(BANDS, (float(v) for v in q.from_si(m.pooled, units))))
    )
    d["cells"] = {"total": int(m.median.size), "masked": m.masked}
    d["message"] = m.message()
    return d


def _strength_dict(m: QuantityMap | None) -> dict[str, Any] | None:
    """The strength kc/b + kphi the cells' kc and kphi come from: its variogram (log space),
    for the conditional simulations of ``terracone mobility MAPDIR``."""
    if m is None or m.skipped:
        return None
    return {
        "description": m.quantity.label,
        "units": "kN/m^(n+2) (SI always; points.parquet column strength)",
        "space": "log",
        "pushes": int(np.isfinite(m.values).sum()),
        "variogram": {k: v for k, v in m.variogram.as_dict().items() if k != "empirical"},
    }


def map_document(result: TerrainMap, units: str = "si") -> dict[str, Any]:
    """``map.json``: the CRS, the grid, the pushes and each quantity's variogram and cross-validation.

    Values in ``units`` (pressures kPa or psi); lengths of the map (grid,
    variogram ranges) in metres of the CRS; variogram sills in the kriged
    space (log or linear).
    """
    from terracone import __version__

    units = u.check_system(units)
    s, g = result.survey, result.grid
    crs = s.crs
    epsg = crs.to_epsg()
    p = result.parameters
    return {
        "schema": MAP_SCHEMA,
        "terracone": __version__,
        "crs": f"EPSG:{epsg}" if epsg else crs.to_wkt(),
        "crs_name": crs.name,
        "crs_note": s.crs_note,
        "crs_units": "m",
        "crs_fit": dict(s.crs_fit),
        "units": units,
        "level": LEVEL,
        "resolution": g.resolution,
        "resolution_note": result.grid_note,
        "grid": {
            "width": g.width,
            "height": g.height,
            "transform": list(g.transform),
            "bounds": list(g.bounds),
        },
        "calibrated": result.calibrated,
        "calibration": (
            s.calibration.get("terrain", "recorded")
            if isinstance(s.calibration, dict)
            else s.calibration
        ),
        "pushes": {
            "located": len(s.results),
            "unlocated": list(s.unlocated),
            "not_fitted": [{"id": i, "reason": r} for i, r in s.not_fitted],
        },
        "layer_note": result.layer_note,
        "quantities": {m.name: _quantity_dict(m, units) for m in result.quantities},
        "parameters": {
            "method": p["method"],
            "reference_size_m": p["reference_size"],
            "kc_share": p["kc_share"],
            "model": p["model"],
            "r_min_m": p["r_min"],
            "strength": _strength_dict(p.get("strength")),
        },
        "points": "points.parquet",
        "cells": "cells.parquet",
        "notes": list(result.notes),
    }


def band_description(name: str, unit: str) -> str:
    """The description of a map raster's band: its name, which interval it bounds, its unit.

    ``median [kPa]``, ``lo (5%, local mean) [kPa]``, ``point_hi (95%, value at a point) [kPa]``.
    """
    if name == "median":
        return f"median [{unit}]"
    q = (1 - LEVEL) / 2 if name.endswith("lo") else (1 + LEVEL) / 2
    what = "value at a point" if name.startswith("point") else "local mean"
    return f"{name} ({q:.0%}, {what}) [{unit}]"


def _write_tif(path: Path, m: QuantityMap, result: TerrainMap, units: str) -> None:
    import rasterio
    from rasterio.crs import CRS
    from rasterio.transform import Affine

    g = result.grid
    unit = m.quantity.unit(units)
    bands = np.stack([m.quantity.from_si(getattr(m, k), units) for k in BANDS])
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=g.width,
        height=g.height,
        count=len(BANDS),
        dtype="float32",
        crs=CRS.from_wkt(result.survey.crs.to_wkt()),
        transform=Affine(*g.transform),
        nodata=float("nan"),
        compress="deflate",
    ) as dst:
        dst.write(bands.astype("float32"))
        for i, name in enumerate(BANDS, 1):  # the name as the description, its meaning as a tag
            dst.set_band_description(i, name)
            dst.update_tags(i, meaning=band_description(name, unit))
        dst.units = (unit,) * len(BANDS)
        dst.update_tags(
            quantity=m.name,
            description=m.quantity.label,
            units=unit,
            level=str(LEVEL),
            bands=",".join(BANDS),
            variogram=json.dumps(
                {k: v for k, v in m.variogram.as_dict().items() if k != "empirical"}
            ),
            software="terracone",
        )


def _write_points(path: Path, result: TerrainMap, units: str) -> None:
    import geopandas as gpd

    s = result.survey
    cols: dict[str, Any] = {
        "profile": s.ids,
        "lat": s.lat,
        "lon": s.lon,
        "x": s.x,
        "y": s.y,
    }
    for m in result.quantities:
        cols[m.name] = m.quantity.from_si(m.values, units)
    strength = result.parameters.get("strength")
    if strength is not None:
        cols["strength"] = np.asarray(strength.values, dtype=float)  # SI, kN/m^(n+2)
    cols["lack_of_fit"] = [r.lack_of_fit for r in s.results]
    gdf = gpd.GeoDataFrame(cols, geometry=gpd.points_from_xy(s.x, s.y), crs=s.crs)
    gdf.to_parquet(path)


def _write_cells(path: Path, result: TerrainMap) -> None:
    from pyproj import Transformer

    g, p = result.grid, result.parameters
    gx, gy = g.centres()
    cols: dict[str, np.ndarray] = {"x": gx.ravel(), "y": gy.ravel()}
    keep = np.zeros(gx.size, dtype=bool)
    for m in result.quantities:
        if m.median is None:
            continue
        for k in BANDS:
            cols[f"{m.name}_{k}"] = getattr(m, k).ravel()
        keep |= np.isfinite(cols[f"{m.name}_median"])
    for k in ("kc", "kphi", "n", "cc", "phic_deg"):
        cols[k] = np.broadcast_to(np.asarray(p[k], dtype=float), gx.shape).ravel()
    cols = {k: v[keep] for k, v in cols.items()}
    tr = Transformer.from_crs(result.survey.crs, "EPSG:4326", always_xy=True)
    lon, lat = tr.transform(cols["x"], cols["y"])
    cols = {"x": cols["x"], "y": cols["y"], "lat": np.asarray(lat), "lon": np.asarray(lon), **{
        k: v for k, v in cols.items() if k not in ("x", "y")}}  # fmt: skip
    meta = {
        "schema": MAP_SCHEMA,
        "units": "si",
        "crs": result.survey.crs.to_wkt(),
        "model": p["model"],
        "r_min_m": p["r_min"],
        "parameters": p["method"],
    }
    table = pa.table({k: pa.array(np.asarray(v, dtype=float)) for k, v in cols.items()})
    pq.write_table(table.replace_schema_metadata({_CELLS_KEY: json.dumps(meta).encode()}), path)


def write_map(
    result: TerrainMap, directory: PathLike, units: str = "si", *, force: bool = False
) -> dict[str, Path]:
    """Write a map's rasters, ``points.parquet``, ``cells.parquet`` and ``map.json`` to ``directory``.

    The directory then holds this map and nothing else: the files are
    written into a new directory beside it that takes its place whole
    (:func:`terracone.io.outputs.run_directory`).  An earlier map there is
    replaced; a directory holding anything else is refused (ValueError)
    unless ``force``.  Returns the written files by name (quantities by their
    name, then ``points``, ``cells``, ``map``).
    """
    from terracone.io.outputs import run_directory
    from terracone.result import dumps

    units = u.check_system(units)
    out = Path(directory).expanduser().resolve()
    names: dict[str, str] = {m.name: f"{m.name}.tif" for m in result.quantities if not m.skipped}
    names.update(points="points.parquet", cells="cells.parquet", map="map.json")
    with run_directory(out, what="terracone map", is_run=is_map_directory, force=force) as stage:
        for m in result.quantities:
            if not m.skipped:
                _write_tif(stage / names[m.name], m, result, units)
        _write_points(stage / names["points"], result, units)
        _write_cells(stage / names["cells"], result)
        (stage / names["map"]).write_text(dumps(map_document(result, units)) + "\n")
    return {k: out / v for k, v in names.items()}


def is_map_directory(directory: PathLike) -> bool:
    """Whether a directory holds one map of :func:`write_map` and nothing else.

    Its ``map.json`` is a map's (schema :data:`MAP_SCHEMA`) and every entry is
    a file that ``map.json`` names: the quantities' GeoTIFFs, ``points.parquet``,
    ``cells.parquet``.
    """
    d = Path(directory)
    try:
        doc = json.loads((d / "map.json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False
    if not isinstance(doc, dict) or doc.get("schema") != MAP_SCHEMA:
        return False
    quantities = doc.get("quantities")
    files = {"map.json", str(doc.get("points")), str(doc.get("cells"))}
    if isinstance(quantities, dict):
        files |= {str(q.get("file")) for q in quantities.values() if isinstance(q, dict)}
    return all(e.is_file() and e.name in files for e in d.iterdir())


def read_map_cells(directory: PathLike) -> list[LocatedParameters]:
    """The terrain parameters of every cell of a map (``cells.parquet``), for simulators.

    Parameters
    ----------
    directory : str or path-like
        The output directory of ``terracone map`` (or :func:`write_map`).

    Returns
    -------
    list of LocatedParameters
        ``(lat, lon, params)`` per cell with a value of kc, kphi and n, at
        the cell centre; ``params`` in SI (kc [kN/m^(n+1)], kphi
        [kN/m^(n+2)], n, cc [kPa], phic_deg [deg], model, r_min [m]).

    Raises
    ------
    ValueError
        The directory holds no ``cells.parquet`` written by terracone.
    """
    path = Path(directory) / "cells.parquet"
    if not path.is_file():
        raise ValueError(f"{directory}: no cells.parquet (not a terracone map directory)")
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowInvalid) as exc:
        raise ValueError(f"file {path}: cannot read Parquet ({exc})") from exc
    raw = (table.schema.metadata or {}).get(_CELLS_KEY)
    if raw is None:
        raise ValueError(f"file {path}: not a terracone map's cells (no {_CELLS_KEY.decode()})")
    meta = json.loads(raw)
    cols = table.to_pydict()
    out = []
    for i in range(table.num_rows):
        v = {k: cols[k][i] for k in ("lat", "lon", "kc", "kphi", "n", "cc", "phic_deg")}
        if not all(x is not None and math.isfinite(x) for x in v.values()):
            continue
        params = TerrainParameters(
            v["kc"], v["kphi"], v["n"], v["cc"], v["phic_deg"],
            model=meta.get("model", "rm0"), r_min=meta.get("r_min_m"),
        )  # fmt: skip
        out.append(LocatedParameters(v["lat"], v["lon"], params))
    return out

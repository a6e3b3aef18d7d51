"""A map directory read back: the grid, the pushes and the variograms that ``terracone map`` wrote.

:func:`read_map_directory` reads ``map.json`` and ``points.parquet`` of a
``terracone map`` output directory; :meth:`MapDirectory.quantity` gives one
quantity as it was kriged (the pushes with a value, their values in the
kriged space, SI, and the fitted variogram rebuilt from ``map.json``), so
that :func:`terracone.apps.maps.simulation.simulate` repeats the map's
kriging exactly.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from terracone.apps.maps.geostat import Variogram, variogram_from_dict
from terracone.apps.maps.grid import Grid
from terracone.apps.maps.writers import MAP_SCHEMA
from terracone.io.jsonkeys import read_json
from terracone.physics import units as u

__all__ = [
    "MapDirectory",
    "StoredQuantity",
    "check_map_document",
    "is_map_directory",
    "read_map_directory",
]

PathLike = str | os.PathLike[str]


@dataclass
class StoredQuantity:
    """One quantity of a map as it was kriged.

    Attributes
    ----------
    name : str
    log : bool
        Kriged in log space.
    x, y : ndarray
        The pushes with a value [m, map CRS].
    z : ndarray
        Their values in the kriged space (log of SI, or SI).
    variogram : Variogram
    layer : (float, float) or None
        Depth layer [m] of a mean-CI quantity.
    """

    name: str
    log: bool
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    variogram: Variogram
    layer: tuple[float, float] | None = None


@dataclass
class MapDirectory:
    """A ``terracone map`` output directory.

    Attributes
    ----------
    path : Path
    doc : dict
        ``map.json``.
    grid : Grid
    points : dict of ndarray
        The columns of ``points.parquet``.
    """

    path: Path
    doc: dict[str, Any]
    grid: Grid
    points: dict[str, np.ndarray]

    @property
    def units(self) -> str:
        return str(self.doc.get("units", "si"))

    @property
    def crs(self) -> str:
        """The map's CRS as ``map.json`` records it (EPSG code or WKT)."""
        return str(self.doc["crs"])

    def ci_layers(self) -> dict[str, tuple[float, float]]:
        """The mean-CI quantities that were mapped, by name: their layer [m]."""
        out = {}
        for name, q in self.doc["quantities"].items():
            if q.get("layer") is not None and not q.get("skipped"):
                lo, hi = (float(u.length_to_si(v, self.units)) for v in q["layer"])
                out[name] = (lo, hi)
        return out

    def _stored(self, name: str, column: Any, log: bool, vg: dict, kind: str) -> StoredQuantity:
        v = np.asarray(column, dtype=float)
        if kind == "pressure":
            v = u.pressure_to_si(v, self.units)
        ok = np.isfinite(v) & ((v > 0) if log else True)
        z = np.log(v[ok]) if log else v[ok]
        try:
            variogram = variogram_from_dict(vg)
        except (TypeError, ValueError, AttributeError) as exc:
            raise ValueError(
                f"file {self.path / 'map.json'}, variogram of {name}: not as terracone map "
                f"writes it ({exc})"
            ) from None
        return StoredQuantity(name, log, self.points["x"][ok], self.points["y"][ok], z, variogram)

    def quantity(self, name: str) -> StoredQuantity:
        """A mapped quantity (``n``, ``plate_pressure``, ``ci_...``) as it was kriged."""
        q = self.doc["quantities"].get(name)
        if q is None or q.get("skipped") or name not in self.points:
            raise ValueError(f"{self.path}: the map has no quantity {name!r}")
        kind = "dimensionless" if q.get("units") == "-" else "pressure"
        out = self._stored(name, self.points[name], q["space"] == "log", q["variogram"], kind)
        out.layer = self.ci_layers().get(name)
        return out

    def strength(self) -> StoredQuantity | None:
        """The strength kc/b + kphi (SI, log space) the cells' kc and kphi come from; None when
        the map does not record it (made before issue 31)."""
        s = (self.doc.get("parameters") or {}).get("strength")
        if s is None or "strength" not in self.points:
            return None
        return self._stored("strength", self.points["strength"], True, s["variogram"], "si")


def is_map_directory(path: PathLike) -> bool:
    """Whether ``path`` is a directory holding ``map.json``."""
    p = Path(path)
    return p.is_dir() and (p / "map.json").is_file()


#: The keys of ``map.json`` that readers use, with their JSON type (others are not read).
_MAP_KEYS: dict[str, tuple[type, ...]] = {
    "grid": (dict,),
    "points": (str,),
    "cells": (str,),
    "pushes": (dict,),
    "quantities": (dict,),
    "parameters": (dict,),
    "notes": (list,),
    "calibration": (str, dict),
}


#: The keys of each quantity of ``map.json`` that readers use, with their JSON type.
_QUANTITY_KEYS: dict[str, tuple[type, ...]] = {
    "file": (str,),
    "units": (str,),
    "description": (str,),
    "message": (str,),
    "space": (str,),
    "variogram": (dict,),
    "cross_validation": (dict,),
    "point_cross_validation": (dict,),
    "bands": (dict,),
    "pooled": (dict,),
    "cells": (dict,),
    "layer": (list,),
    "excluded": (list,),
}


def _json_type(value: Any) -> str:
    names = {dict: "an object", list: "an array", str: "text", bool: "true or false"}
    return next((w for t, w in names.items() if isinstance(value, t)), "a number")


def check_map_document(doc: Any, file: PathLike) -> dict[str, Any]:
    """``map.json`` as written by ``terracone map``, or ValueError naming the file and key.

    Checks the schema and the JSON type of every key a reader uses (the grid's
    size and transform, the file names, each quantity an object); a hand-edited
    or corrupt file is refused here rather than failing inside a reader.
    """
    where = f"file {file}"
    if not isinstance(doc, dict) or doc.get("schema") != MAP_SCHEMA:
        got = doc.get("schema") if isinstance(doc, dict) else None
        raise ValueError(f"{where}: not a terracone map (schema {got!r}, expected {MAP_SCHEMA!r})")
    for key, types in _MAP_KEYS.items():
        value = doc.get(key)
        if value is not None and not isinstance(value, types):
            want = " or ".join(_json_type(t()) for t in types)
            raise ValueError(f"{where}, key {key}: expected {want} (got {_json_type(value)})")
    g = doc.get("grid")
    t = g.get("transform") if isinstance(g, dict) else None
    ok = (
        isinstance(t, list) and len(t) == 6
        and all(isinstance(v, int | float) and math.isfinite(v) for v in t)
        and all(isinstance(g.get(k), int) and g[k] > 0 for k in ("width", "height"))
    )  # fmt: skip
    if not ok:
        raise ValueError(f"{where}, key grid: expected width, height (> 0) and a transform of "
                         "6 numbers, as terracone map writes them")  # fmt: skip
    for name, q in (doc.get("quantities") or {}).items():
        if not isinstance(q, dict):
            raise ValueError(f"{where}, key quantities.{name}: expected an object")
        for key, types in _QUANTITY_KEYS.items():
            value = q.get(key)
            if value is not None and not isinstance(value, types):
                want = " or ".join(_json_type(t()) for t in types)
                got = _json_type(value)
                raise ValueError(
                    f"{where}, key quantities.{name}.{key}: expected {want} (got {got})"
                )
    if not all(isinstance(n, str) for n in doc.get("notes") or []):
        raise ValueError(f"{where}, key notes: expected an array of text")
    return doc


def read_map_directory(path: PathLike) -> MapDirectory:
    """Read ``map.json`` and ``points.parquet`` of a ``terracone map`` output directory.

    Raises
    ------
    ValueError
        No such directory, no ``map.json``, a ``map.json`` of another schema
        or one that cannot be read, no ``points.parquet``.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = Path(path)
    if not p.is_dir():
        raise ValueError(f"{p}: not a directory (a terracone map directory holds map.json)")
    f = p / "map.json"
    if not f.is_file():
        raise ValueError(f"{p}: no map.json (not a terracone map directory: make one with "
                         "terracone map RESULTS --out DIR)")  # fmt: skip
    doc = check_map_document(read_json(f), f)
    pts = p / (doc.get("points") or "points.parquet")
    try:
        table = pq.read_table(pts)
    except (OSError, pa.ArrowInvalid) as exc:
        raise ValueError(f"file {pts}: cannot read the map's pushes ({exc})") from None
    points = {k: np.asarray(table[k].to_numpy(zero_copy_only=False)) for k in table.column_names
              if k != "geometry"}  # fmt: skip
    g = doc["grid"]
    t = g["transform"]
    grid = Grid(float(t[2]), float(t[5]), float(t[0]), g["width"], g["height"])
    if not math.isclose(-float(t[4]), grid.resolution):
        raise ValueError(f"file {f}: the grid's cells are not square ({t})")
    return MapDirectory(p, doc, grid, points)

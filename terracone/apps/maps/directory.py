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

__all__ = ["MapDirectory", "StoredQuantity", "is_map_directory", "read_map_directory"]

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
        return StoredQuantity(
            name, log, self.points["x"][ok], self.points["y"][ok], z, variogram_from_dict(vg)
        )

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
    doc = read_json(f)
    if not isinstance(doc, dict) or doc.get("schema") != MAP_SCHEMA:
        got = doc.get("schema") if isinstance(doc, dict) else None
        raise ValueError(f"file {f}: not a terracone map (schema {got!r}, expected {MAP_SCHEMA!r})")
    pts = p / str(doc.get("points") or "points.parquet")
    try:
        table = pq.read_table(pts)
    except (OSError, pa.ArrowInvalid) as exc:
        raise ValueError(f"file {pts}: cannot read the map's pushes ({exc})") from None
    points = {k: np.asarray(table[k].to_numpy(zero_copy_only=False)) for k in table.column_names
              if k != "geometry"}  # fmt: skip
    g = doc["grid"]
    t = g["transform"]
    grid = Grid(float(t[2]), float(t[5]), float(t[0]), int(g["width"]), int(g["height"]))
    if not math.isclose(-float(t[4]), grid.resolution):
        raise ValueError(f"file {f}: the grid's cells are not square ({t})")
    return MapDirectory(p, doc, grid, points)

"""Terrain maps from located pushes: kriged plate pressure, n and mean CI with 90% intervals.

``terracone map RESULTS --out DIR`` is :func:`run_map`: :func:`map_survey` then
:func:`write_map`:

* :mod:`~terracone.apps.maps.survey`: located pushes, their projection (pyproj) and
  each push's value of each quantity;
* :mod:`~terracone.apps.maps.grid`: the raster grid;
* :mod:`~terracone.apps.maps.geostat`: variograms, ordinary kriging (gstools) and
  leave-one-out cross-validation;
* :mod:`~terracone.apps.maps.workflow`: one quantity's map, the cells' parameters;
* :mod:`~terracone.apps.maps.writers`: GeoTIFF, GeoParquet, ``cells.parquet``,
  ``map.json`` and :func:`read_map_cells` for simulators;
* :mod:`~terracone.apps.maps.run`: :func:`run_map`, results read, mapped and written.
"""

from terracone.apps.maps.run import MapRun, run_map
from terracone.apps.maps.survey import MIN_PUSHES, Quantity, Survey, locate
from terracone.apps.maps.workflow import QuantityMap, TerrainMap, map_survey
from terracone.apps.maps.writers import (
    MAP_SCHEMA,
    LocatedParameters,
    is_map_directory,
    map_document,
    read_map_cells,
    write_map,
)

__all__ = [
    "MAP_SCHEMA",
    "MIN_PUSHES",
    "LocatedParameters",
    "MapRun",
    "TerrainMap",
    "Quantity",
    "QuantityMap",
    "Survey",
    "is_map_directory",
    "locate",
    "map_document",
    "map_survey",
    "read_map_cells",
    "run_map",
    "write_map",
]

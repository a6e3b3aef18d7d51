"""Read and write cone index, plate sinkage and shear files.

Every reader returns the objects of :mod:`terracone.data` in SI (m, kPa)
whatever the units of the file, and locates every problem it finds with an
:class:`~terracone.data.InputError` naming the file, the profile (or test),
the row (1-based line number in the file) and the column.

CSV conventions
---------------
* The unit is part of every column name: ``depth_cm``, ``ci_kpa``,
  ``sinkage_mm``, ``pressure_psi``, ...  Headers are case-insensitive.
  Length units: ``m``, ``cm``, ``mm``, ``in``; pressure units: ``kpa``,
  ``mpa``, ``psi`` (and ``pa``), see :data:`terracone.physics.units.LENGTH_UNITS`
  and :data:`terracone.physics.units.PRESSURE_UNITS`.
* Lines starting with ``#`` are comments and may appear anywhere (before
  the header too); blank lines are ignored.  Both still count in the line
  numbers reported in errors and stored in ``rows``.
* CI profiles: ``depth_<u>``, ``ci_<u>``, optional ``profile`` (the id;
  several profiles per file; without it the whole file is one profile
  whose id is the file stem) and optional ``cone`` (a name accepted by
  :func:`terracone.physics.cone.get_cone`; it overrides the ``cone`` argument).
* Plate tests: optional ``test``, exactly one of ``plate_radius_<u>``,
  ``plate_diameter_<u>`` (circular plate, b = radius) or
  ``plate_width_<u>`` (rectangular plate, b = width), ``sinkage_<u>`` and
  ``pressure_<u>``.
* Shear tests: optional ``test``, ``normal_pressure_<u>``,
  ``shear_displacement_<u>`` and ``shear_stress_<u>``.
* Any other column is metadata: each profile or test keeps the values of
  its first row, in column order, as floats when they read as decimal
  numbers and as strings otherwise.

FieldScout SC900 exports
------------------------
The text export of the Spectrum FieldScout SC900 logger (a few header lines
with the logger name, serial number, datum and the pressure unit, a column
line ``Longitude,Latitude,Number,0.0 cm,2.5 cm,...,Cone Size``, "Logger
Started" lines and one ``N= k , ...`` line per push) is read by
:func:`read_ci_profiles` too; see there.

Wide tables
-----------
One row per push and one column per depth (Penetrologger exports opened in
a spreadsheet, published tables): :func:`read_wide_ci`, or
:func:`read_ci_profiles` with ``format="wide"`` (detected by
:func:`detect_format`).  Depth and cone index units are never guessed.

Profile sets and streaming
--------------------------
:func:`read_profile_set` reads any CI file (long CSV, Parquet, SC900 export,
wide table) into one :class:`~terracone.data.ProfileSet`;
:func:`iter_profile_sets` streams long CSV and Parquet files (or a directory
of them) chunk by chunk through pyarrow's readers, for inputs larger than
memory.  :func:`terracone.apps.batch.run_batch` reads through the same stream.

Modules
-------
:mod:`~terracone.io.tables` (CSV tables, schemas, cells),
:mod:`~terracone.io.profiles` (CI files, format detection),
:mod:`~terracone.io.sc900`, :mod:`~terracone.io.wide` (instrument files),
:mod:`~terracone.io.stream` (streaming profile sets),
:mod:`~terracone.io.bevameter` (plate and shear tests),
:mod:`~terracone.io.writers` (CSV writers),
:mod:`~terracone.io.jsonkeys` (the keys of calibration and library JSON, checked on load).
"""

from terracone.io.bevameter import read_plate_tests, read_shear_tests
from terracone.io.profiles import detect_format, read_ci_profiles, read_profile_set
from terracone.io.sc900 import SC900_CONES, read_sc900
from terracone.io.tables import (
    CI_SCHEMA,
    DECIMAL,
    SPECIAL_FLOAT,
    OnError,
    PathLike,
    Table,
    column_layout,
    to_numbers,
)
from terracone.io.wide import (
    WIDE_CI_UNITS,
    WIDE_ID_COLUMNS,
    WIDE_LAT_COLUMNS,
    WIDE_LON_COLUMNS,
    parse_coordinate,
    read_wide_ci,
    wide_depth_header,
)
from terracone.io.writers import (
    json_default,
    write_ci_profiles,
    write_plate_tests,
    write_shear_tests,
)

__all__ = [
    "detect_format",
    "parse_coordinate",
    "read_ci_profiles",
    "read_profile_set",
    "iter_profile_sets",
    "read_sc900",
    "read_wide_ci",
    "wide_depth_header",
    "WIDE_ID_COLUMNS",
    "WIDE_LAT_COLUMNS",
    "WIDE_LON_COLUMNS",
    "read_plate_tests",
    "read_shear_tests",
    "write_ci_profiles",
    "write_plate_tests",
    "write_shear_tests",
    "SC900_CONES",
    # shared with other modules (batch, cli, reproduce)
    "CI_SCHEMA",
    "DECIMAL",
    "SPECIAL_FLOAT",
    "OnError",
    "PathLike",
    "Table",
    "column_layout",
    "to_numbers",
    "WIDE_CI_UNITS",
    "json_default",
    # the writers and reader of prediction results (terracone.result)
    "read_results_json",
    "write_results_json",
    "write_results_parquet",
]

_RESULTS = {
    "read_results_json": "read_json",
    "write_results_json": "write_json",
    "write_results_parquet": "write_parquet",
}


def __getattr__(name: str) -> object:
    # the streaming reader needs pyarrow and pandas: imported on first use, so that
    # importing terracone.io (the CLI's start-up) stays light
    if name == "iter_profile_sets":
        from terracone.io.stream import iter_profile_sets

        return iter_profile_sets
    if name in _RESULTS:  # pyarrow too: on first use
        from terracone import result

        return getattr(result, _RESULTS[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

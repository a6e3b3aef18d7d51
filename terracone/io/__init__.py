"""Read and write cone index, plate sinkage and shear files.

Every reader returns the objects of :mod:`terracone.data` in SI (m, kPa)
whatever the units of the file, and locates every problem with an
:class:`~terracone.data.InputError` naming the file, the profile (or test),
the row (1-based file line) and the column.  CSV columns carry their unit in
their name (``depth_cm``, ``ci_kpa``, ``pressure_psi``); ``#`` lines are
comments; any other column is metadata.  :func:`read_ci_profiles` reads long
CSV, FieldScout SC900 exports and wide tables (:func:`detect_format`);
:func:`read_profile_set` reads any of them, Parquet included, into one
:class:`~terracone.data.ProfileSet`; :func:`iter_profile_sets` streams them in
chunks.  The formats: ``docs/instruments.md``.

Modules: :mod:`~terracone.io.tables` (CSV tables, schemas, cells),
:mod:`~terracone.io.profiles` (CI files, format detection, the readers of
every format), :mod:`~terracone.io.sc900`, :mod:`~terracone.io.wide`
(instrument files), :mod:`~terracone.io.scan` and :mod:`~terracone.io.stream`
(the streaming core), :mod:`~terracone.io.bevameter` (plate and shear tests),
:mod:`~terracone.io.writers` (CSV writers), :mod:`~terracone.io.jsonkeys` (the keys of
calibration and library JSON, checked on load).
"""

from terracone.io.bevameter import read_plate_tests, read_shear_tests
from terracone.io.profiles import (
    detect_format,
    instrument_to_parquet,
    iter_profile_sets,
    read_ci_profiles,
    read_profile_set,
)
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
    "instrument_to_parquet",
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
]

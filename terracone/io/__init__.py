"""Read and write cone index, plate sinkage and shear files (SI out: m, kPa).

The formats and their errors: ``docs/instruments.md``.  Modules:
:mod:`~terracone.io.tables` (CSV tables, schemas, cells),
:mod:`~terracone.io.profiles` (CI files of every format),
:mod:`~terracone.io.sc900`, :mod:`~terracone.io.wide` (instrument files),
:mod:`~terracone.io.scan` and :mod:`~terracone.io.stream` (streaming),
:mod:`~terracone.io.bevameter` (plate and shear tests),
:mod:`~terracone.io.writers` (CSV writers),
:mod:`~terracone.io.jsonkeys` (calibration and library JSON keys, checked on load).
"""

from terracone.io.bevameter import read_plate_tests, read_shear_tests
from terracone.io.profiles import (
    detect_format,
    instrument_to_parquet,
    iter_profile_sets,
    read_ci_profiles,
    read_profile_set,
)
from terracone.io.sc900 import read_sc900
from terracone.io.wide import parse_coordinate, read_wide_ci
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
    "read_plate_tests",
    "read_shear_tests",
    "write_ci_profiles",
    "write_plate_tests",
    "write_shear_tests",
    "json_default",
]

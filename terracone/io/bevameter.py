"""Plate sinkage and shear test files (bevameter data)."""

from __future__ import annotations

import os

import numpy as np

from terracone.data import CI_MAX_KPA, DEPTH_MAX_M, InputError, PlateTest, ShearTest
from terracone.io.tables import (
    PLATE_SCHEMA,
    SHEAR_SCHEMA,
    Column,
    Numbers,
    OnError,
    PathLike,
    Table,
    check_group,
    check_options,
    collect,
    column_layout,
    read_table,
    row_metadata,
    table_groups,
    to_numbers,
)


def read_plate_tests(
    path: PathLike, *, on_error: OnError = "raise"
) -> list[PlateTest | InputError]:
    """Read plate pressure-sinkage tests from a CSV file.

    Parameters
    ----------
    path : str or path-like
        CSV with an optional ``test`` column (test id; without it the file
        is one test whose id is the file stem), exactly one of
        ``plate_radius_<u>``, ``plate_diameter_<u>`` (circular plate, b =
        radius) or ``plate_width_<u>`` (rectangular, b = width),
        ``sinkage_<u>`` and ``pressure_<u>``; other columns are metadata.
    on_error : {"raise", "collect"}
        As in :func:`read_ci_profiles`.

    Returns
    -------
    list of PlateTest or InputError
        In order of first appearance of the test ids; b and sinkage in m,
        pressure in kPa, ``rows`` the file line numbers.

    Notes
    -----
    Raw bevameter data are kept as they are: negative sinkages and
    pressures (zero drift) and unloading are legal.  Errors are a
    non-numeric, NaN or empty cell, a plate size that changes within a
    test or is not > 0, and the file-level problems of
    :func:`read_ci_profiles`.
    """
    check_options(on_error)
    source = os.fspath(path)
    table = read_table(source)
    layout = column_layout(source, table.header, table.header_line, PLATE_SCHEMA)
    scol, zcol, pcol = (layout.groups[g] for g in ("size", "sinkage", "pressure"))
    size, sink, pres = (to_numbers(table.columns[c.index]) for c in (scol, zcol, pcol))
    circular = scol.field is not None and scol.field.name != "plate_width"
    halve = scol.field is not None and scol.field.name == "plate_diameter"

    def build(group: tuple[str, np.ndarray]) -> PlateTest:
        tid, idx = group
        check_group(table, layout, tid, idx, [(scol, size), (zcol, sink), (pcol, pres)], "test")
        b = _constant(tid, table, idx, scol, size, "plate size") * scol.factor
        if halve:
            b /= 2.0
        if not b > 0:
            raise _error("plate size must be > 0", table, tid, int(idx[0]), scol.name)
        _check_within(np.array([b]), idx[:1], DEPTH_MAX_M, "plate size", "m", table, tid, scol)
        z = sink.values[idx] * zcol.factor
        p = pres.values[idx] * pcol.factor
        _check_within(z, idx, DEPTH_MAX_M, "sinkage", "m", table, tid, zcol)
        _check_within(p, idx, CI_MAX_KPA, "pressure", "kPa", table, tid, pcol)
        return PlateTest(
            id=tid,
            b=b,
            shape="circular" if circular else "rectangular",
            sinkage=z,
            pressure=p,
            metadata=row_metadata(table, layout, int(idx[0])),
            source=source,
            rows=table.lines[idx].copy(),
        )

    return collect(table_groups(table, layout.id_col), build, on_error)


def read_shear_tests(
    path: PathLike, *, on_error: OnError = "raise"
) -> list[ShearTest | InputError]:
    """Read shear stress-displacement tests from a CSV file.

    Parameters
    ----------
    path : str or path-like
        CSV with an optional ``test`` column, ``normal_pressure_<u>``
        (constant within a test), ``shear_displacement_<u>`` and
        ``shear_stress_<u>``; other columns are metadata.
    on_error : {"raise", "collect"}
        As in :func:`read_ci_profiles`.

    Returns
    -------
    list of ShearTest or InputError
        In order of first appearance of the test ids; normal pressure and
        stress in kPa, displacement in m.

    Notes
    -----
    Negative displacements and stresses (zero drift) are legal; errors are
    a non-numeric, NaN or empty cell, a normal pressure that changes
    within a test and the file-level problems of :func:`read_ci_profiles`.
    """
    check_options(on_error)
    source = os.fspath(path)
    table = read_table(source)
    layout = column_layout(source, table.header, table.header_line, SHEAR_SCHEMA)
    ncol, jcol, tcol = (layout.groups[g] for g in ("normal_pressure", "displacement", "stress"))
    normal, disp, stress = (to_numbers(table.columns[c.index]) for c in (ncol, jcol, tcol))

    def build(group: tuple[str, np.ndarray]) -> ShearTest:
        tid, idx = group
        check_group(table, layout, tid, idx, [(ncol, normal), (jcol, disp), (tcol, stress)], "test")
        sigma = _constant(tid, table, idx, ncol, normal, "normal pressure") * ncol.factor
        j = disp.values[idx] * jcol.factor
        tau = stress.values[idx] * tcol.factor
        _check_within(np.array([sigma]), idx[:1], CI_MAX_KPA, "normal pressure", "kPa", table,
                      tid, ncol)  # fmt: skip
        _check_within(j, idx, DEPTH_MAX_M, "shear displacement", "m", table, tid, jcol)
        _check_within(tau, idx, CI_MAX_KPA, "shear stress", "kPa", table, tid, tcol)
        return ShearTest(
            id=tid,
            normal_pressure=sigma,
            displacement=j,
            stress=tau,
            metadata=row_metadata(table, layout, int(idx[0])),
            source=source,
            rows=table.lines[idx].copy(),
        )

    return collect(table_groups(table, layout.id_col), build, on_error)


def _error(why: str, table: Table, tid: str, i: int, column: str) -> InputError:
    line = int(table.lines[i])
    return InputError(why, file=table.path, profile=tid, item="test", row=line, column=column)


def _check_within(
    values: np.ndarray,
    idx: np.ndarray,
    limit: float,
    what: str,
    unit: str,
    table: Table,
    tid: str,
    col: Column,
) -> None:
    """Refuse the first value beyond +-limit (SI): a unit error or a corrupt cell, not soil."""
    big = np.flatnonzero(np.abs(values) > limit)
    if big.size:
        i = int(idx[big[0]])
        why = (
            f"{what} {values[big[0]]:g} {unit} is beyond {limit:g} {unit}, which no bevameter "
            "test reaches (a unit error or a corrupt cell?)"
        )
        raise _error(why, table, tid, i, col.name)


def _constant(
    tid: str, table: Table, idx: np.ndarray, col: Column, num: Numbers, what: str
) -> float:
    """The value of a column that must not change within a test."""
    vals = num.values[idx]
    diff = np.flatnonzero(vals != vals[0])
    if diff.size:
        i = int(idx[diff[0]])
        cells = table.columns[col.index]
        why = (
            f"{what} changes within the test ({cells[i].strip()} here, "
            f"{cells[int(idx[0])].strip()} on line {int(table.lines[idx[0]])})"
        )
        raise _error(why, table, tid, i, col.name)
    return float(vals[0])

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
  ``mpa``, ``psi`` (and ``pa``), see :data:`terracone.units.LENGTH_UNITS`
  and :data:`terracone.units.PRESSURE_UNITS`.
* Lines starting with ``#`` are comments and may appear anywhere (before
  the header too); blank lines are ignored.  Both still count in the line
  numbers reported in errors and stored in ``rows``.
* CI profiles: ``depth_<u>``, ``ci_<u>``, optional ``profile`` (the id;
  several profiles per file; without it the whole file is one profile
  whose id is the file stem) and optional ``cone`` (a name accepted by
  :func:`terracone.cone.get_cone`; it overrides the ``cone`` argument).
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
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal, TextIO

import numpy as np

from . import units as u
from .cone import CONES, Cone, get_cone
from .data import CIProfile, InputError, PlateTest, ShearTest

__all__ = [
    "detect_format",
    "parse_coordinate",
    "read_ci_profiles",
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
    "read_results_json",
    "write_results_json",
    "write_results_parquet",
]

PathLike = str | os.PathLike[str]
OnError = Literal["raise", "collect"]

#: Cone sizes of the SC900 export (normalised to lower case) and their cones.
SC900_CONES: dict[str, str] = {"1/2 inch": "asabe-small", "3/4 inch": "asabe-large"}

_LENGTH = "length"
_PRESSURE = "pressure"
_UNIT_TABLES: dict[str, dict[str, float]] = {
    _LENGTH: u.LENGTH_UNITS,
    _PRESSURE: u.PRESSURE_UNITS,
}

# decimal numbers only: float() would also take "2018_13" (a plot id) as 201813
DECIMAL = re.compile(r"^\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\s*$")
SPECIAL_FLOAT = re.compile(r"^\s*[+-]?(?:nan|inf|infinity)\s*$", re.IGNORECASE)


# ---------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------


def _check_on_error(on_error: str) -> None:
    if on_error not in ("raise", "collect"):
        raise ValueError(f"on_error must be 'raise' or 'collect' (got {on_error!r})")


def _metadata_value(cell: str) -> float | str:
    """A metadata cell: float when it reads as a number, else the stripped text."""
    if DECIMAL.match(cell) or SPECIAL_FLOAT.match(cell):
        return float(cell)
    return cell.strip()


@dataclass
class _Numbers:
    """A column of cells converted to float; ``bad`` marks unusable cells."""

    values: np.ndarray
    bad: np.ndarray
    reasons: dict[int, str]


def _cell_problem(cell: str) -> str | None:
    """Why a cell is not a finite number, or None if it is one."""
    if not cell.strip():
        return "empty cell"
    if DECIMAL.match(cell):
        return None
    if SPECIAL_FLOAT.match(cell):
        return f"not a finite number: {cell.strip()!r}"
    return f"not a number: {cell.strip()!r}"


def to_numbers(cells: Sequence[str]) -> _Numbers:
    """Convert cells to floats (vectorised when every cell is a plain number)."""
    n = len(cells)
    joined = "".join(cells)
    values: np.ndarray | None = None
    if joined.isascii() and "_" not in joined:
        try:
            values = np.array(cells, dtype=float).reshape(n)
        except ValueError:
            values = None
    if values is not None:
        bad = ~np.isfinite(values)
        reasons = {int(i): _cell_problem(cells[i]) or "bad cell" for i in np.flatnonzero(bad)}
        return _Numbers(values, bad, reasons)
    values = np.full(n, np.nan)
    bad = np.zeros(n, dtype=bool)
    reasons: dict[int, str] = {}
    for i, cell in enumerate(cells):
        why = _cell_problem(cell)
        if why is None:
            values[i] = float(cell)
        else:
            bad[i] = True
            reasons[i] = why
    return _Numbers(values, bad, reasons)


def _open_text(path: str) -> TextIO:
    try:
        return open(path, encoding="utf-8-sig", newline="")  # noqa: SIM115
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a file", file=path) from None
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror or exc}", file=path) from None


def _read_lines(path: str) -> list[str]:
    with _open_text(path) as f:
        try:
            return f.read().splitlines()
        except UnicodeDecodeError as exc:
            raise InputError(f"not a UTF-8 text file ({exc.reason})", file=path) from None


# ---------------------------------------------------------------------------
# CSV tables
# ---------------------------------------------------------------------------


@dataclass
class Table:
    """A CSV table as read: header, its file line, columns of cells and the file line of
    each data row (shared by the readers here and by batch's streaming reader)."""

    path: str
    header: list[str]
    header_line: int
    columns: list[list[str]]
    lines: np.ndarray  # file line number of each data row

    @property
    def n_rows(self) -> int:
        return int(self.lines.size)


def _read_table(path: str) -> Table:
    """Read a CSV file: header, cells by column and the line of every record.

    A line is a comment (skipped) when it starts with ``#`` at the start of a
    record; blank lines are skipped.  Line numbers count every physical line.
    """
    first_line: list[int | None] = [None]

    def lines(f: TextIO) -> Iterator[str]:
        for lineno, line in enumerate(f, 1):
            if first_line[0] is None:  # at the start of a record
                stripped = line.strip()
                if not stripped or stripped.startswith("#"):
                    continue
                first_line[0] = lineno
            yield line

    records: list[list[str]] = []
    starts: list[int] = []
    with _open_text(path) as f:
        try:
            for record in csv.reader(lines(f)):
                starts.append(first_line[0] or 0)
                first_line[0] = None
                records.append(record)
        except UnicodeDecodeError as exc:
            raise InputError(f"not a UTF-8 text file ({exc.reason})", file=path) from None
        except csv.Error as exc:
            raise InputError(f"bad CSV: {exc}", file=path, row=first_line[0]) from None
    if not records:
        raise InputError("no header line (the file is empty or all comments)", file=path)
    header = [h.strip() for h in records[0]]
    while header and not header[-1]:  # trailing separators
        header.pop()
    width = len(header)
    for j, name in enumerate(header):
        if not name:
            raise InputError(f"column {j + 1} has no name", file=path, row=starts[0])
    body = records[1:]
    if not body:
        raise InputError("no data rows", file=path, row=starts[0])
    for rec, line in zip(body, starts[1:]):
        if len(rec) < width:
            rec.extend([""] * (width - len(rec)))
        elif len(rec) > width:
            if any(c.strip() for c in rec[width:]):
                raise InputError(
                    f"{len(rec)} fields but the header has {width}", file=path, row=line
                )
            del rec[width:]
    columns = [list(col) for col in zip(*body)]
    return Table(path, header, starts[0], columns, np.asarray(starts[1:], dtype=int))


@dataclass(frozen=True)
class _Field:
    """A quantity column of a schema: ``<name>_<unit>``."""

    name: str  # column prefix, e.g. "plate_radius"
    kind: str  # _LENGTH or _PRESSURE
    group: str  # alternatives share a group, e.g. "size"


@dataclass(frozen=True)
class _Schema:
    id_column: str
    fields: tuple[_Field, ...]
    required: tuple[str, ...]  # groups
    extra: tuple[str, ...] = ()  # other reserved plain columns (e.g. "cone")


CI_SCHEMA = _Schema(
    "profile",
    (_Field("depth", _LENGTH, "depth"), _Field("ci", _PRESSURE, "ci")),
    ("depth", "ci"),
    ("cone",),
)
_PLATE_SCHEMA = _Schema(
    "test",
    (
        _Field("plate_radius", _LENGTH, "size"),
        _Field("plate_diameter", _LENGTH, "size"),
        _Field("plate_width", _LENGTH, "size"),
        _Field("sinkage", _LENGTH, "sinkage"),
        _Field("pressure", _PRESSURE, "pressure"),
    ),
    ("size", "sinkage", "pressure"),
)
_SHEAR_SCHEMA = _Schema(
    "test",
    (
        _Field("normal_pressure", _PRESSURE, "normal_pressure"),
        _Field("shear_displacement", _LENGTH, "displacement"),
        _Field("shear_stress", _PRESSURE, "stress"),
    ),
    ("normal_pressure", "displacement", "stress"),
)


@dataclass
class _Column:
    index: int
    name: str  # as written in the header
    field: _Field | None = None
    factor: float = 1.0  # to SI


@dataclass
class _Layout:
    """Where a schema's columns are in a table."""

    groups: dict[str, _Column]
    id_col: _Column | None
    extra: dict[str, _Column]
    metadata: list[_Column]


def _match_field(lower: str, schema: _Schema) -> tuple[_Field, str | None] | None:
    """The field a lower-case column name belongs to and its unit suffix."""
    for fld in schema.fields:
        if lower == fld.name:
            return fld, None
        if lower.startswith(fld.name + "_"):
            return fld, lower[len(fld.name) + 1 :]
    return None


def _unit_choices(kind: str) -> str:
    return "|".join(_UNIT_TABLES[kind])


def column_layout(table: Table, schema: _Schema, units: str | None = None) -> _Layout:
    """Classify the header of a table; raise InputError for header problems."""
    path, row = table.path, table.header_line
    seen: dict[str, str] = {}
    groups: dict[str, _Column] = {}
    id_col: _Column | None = None
    extra: dict[str, _Column] = {}
    metadata: list[_Column] = []
    for j, name in enumerate(table.header):
        lower = name.lower()
        if lower in seen:
            raise InputError(
                f"duplicate column name ({seen[lower]} is already a column)",
                file=path,
                row=row,
                column=name,
            )
        seen[lower] = name
        if lower == schema.id_column:
            id_col = _Column(j, name)
            continue
        if lower in schema.extra:
            extra[lower] = _Column(j, name)
            continue
        match = _match_field(lower, schema)
        if match is None:
            metadata.append(_Column(j, name))
            continue
        fld, unit = match
        table_units = _UNIT_TABLES[fld.kind]
        if unit is None:
            if units is None:
                raise InputError(
                    f"no unit in the column name: write {fld.name}_<{_unit_choices(fld.kind)}>",
                    file=path,
                    row=row,
                    column=name,
                )
            sys_unit = u.length_unit(units) if fld.kind == _LENGTH else u.pressure_unit(units)
            unit = sys_unit.lower()
        if unit not in table_units:
            raise InputError(
                f"unknown {fld.kind} unit {unit!r} (use {fld.name}_<{_unit_choices(fld.kind)}>)",
                file=path,
                row=row,
                column=name,
            )
        if fld.group in groups:
            other = groups[fld.group].name
            raise InputError(
                f"more than one {fld.group} column ({other} is already one)",
                file=path,
                row=row,
                column=name,
            )
        groups[fld.group] = _Column(j, name, fld, table_units[unit])
    for group in schema.required:
        if group not in groups:
            names = " or ".join(
                f"{f.name}_<{_unit_choices(f.kind)}>" for f in schema.fields if f.group == group
            )
            raise InputError(f"missing required column {names}", file=path, row=row, column=names)
    return _Layout(groups, id_col, extra, metadata)


def _groups(table: Table, id_col: _Column | None) -> list[tuple[str, np.ndarray]]:
    """(id, row indices) of each profile or test, in order of first appearance."""
    if id_col is None:
        return [(Path(table.path).stem, np.arange(table.n_rows))]
    index: dict[str, list[int]] = {}
    for i, cell in enumerate(table.columns[id_col.index]):
        index.setdefault(cell.strip(), []).append(i)
    return [(key, np.asarray(rows, dtype=int)) for key, rows in index.items()]


def _first_bad(
    idx: np.ndarray, checks: Sequence[tuple[_Column, _Numbers]]
) -> tuple[int, _Column, str] | None:
    """The earliest unusable cell of a group (row order, then column order)."""
    best: tuple[tuple[int, int], _Column, str] | None = None
    for order, (col, num) in enumerate(checks):
        hits = np.flatnonzero(num.bad[idx])
        if hits.size:
            key = (int(hits[0]), order)
            if best is None or key < best[0]:
                i = int(idx[hits[0]])
                best = (key, col, num.reasons[i])
    if best is None:
        return None
    (k, _), col, why = best
    return int(idx[k]), col, why


def _metadata(table: Table, layout: _Layout, i: int) -> dict[str, Any]:
    return {c.name: _metadata_value(table.columns[c.index][i]) for c in layout.metadata}


def _collect(items: Sequence[Any], build: Callable[[Any], Any], on_error: str) -> list[Any]:
    """Build each item; on InputError raise or keep the error in its place."""
    out: list[Any] = []
    for item in items:
        try:
            out.append(build(item))
        except InputError as exc:
            if on_error == "raise":
                raise
            out.append(exc)
    return out


def _check_constant(
    path: str, gid: str, table: Table, idx: np.ndarray, col: _Column, num: _Numbers, what: str
) -> float:
    """The value of a column that must not change within a test."""
    vals = num.values[idx]
    diff = np.flatnonzero(vals != vals[0])
    if diff.size:
        i = int(idx[diff[0]])
        first = table.columns[col.index][int(idx[0])].strip()
        raise InputError(
            f"{what} changes within the test ({table.columns[col.index][i].strip()} "
            f"here, {first} on line {int(table.lines[idx[0]])})",
            file=path,
            profile=gid,
            item="test",
            row=int(table.lines[i]),
            column=col.name,
        )
    return float(vals[0])


# ---------------------------------------------------------------------------
# CI profiles
# ---------------------------------------------------------------------------


def _validated(
    profile: CIProfile,
    locate: Callable[[int | None, str | None], tuple[int | None, str | None, str]],
) -> CIProfile:
    """Run :meth:`CIProfile.validate` and relocate its error in the file.

    ``locate(index, column)`` maps the point index and the model's column
    name (``"depth"``, ``"ci"`` or None) to (file row, file column, extra
    text for the message).
    """
    probe = replace(profile, rows=np.arange(len(profile)))
    try:
        probe.validate()
    except InputError as exc:
        row, column, more = locate(exc.row, exc.column)
        raise InputError(
            exc.reason + more,
            file=profile.source,
            profile=profile.id,
            row=row,
            column=column,
        ) from None
    return profile


def _sniff_format(path: str) -> str:
    """``"sc900"`` if the file starts like a FieldScout SC900 export, else ``"csv"``."""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            head = [f.readline() for _ in range(12)]
    except OSError:
        return "csv"  # the CSV reader reports the problem
    lines = [ln.strip() for ln in head if ln.strip()]
    if lines and re.match(r"^Name\s*:", lines[0], re.IGNORECASE):
        return "sc900"
    if any(re.match(r"^Longitude\s*,\s*Latitude\s*,\s*Number\s*,", ln, re.I) for ln in lines):
        return "sc900"
    return "csv"


def detect_format(path: PathLike) -> Literal["csv", "sc900", "wide"]:
    """The format of a cone index file: ``"sc900"``, ``"wide"`` or ``"csv"``.

    An SC900 export is recognised by its first lines; a wide table when its
    first line of 3 or more cells (after blank, comment and short preamble
    lines of at most 2 cells) has 3 or more depth headers
    (:func:`wide_depth_header`) and no ``depth_<unit>`` or ``ci_<unit>``
    column; anything else is read as a long CSV file, whose reader reports
    what is wrong.
    """
    source = os.fspath(path)
    if _sniff_format(source) == "sc900":
        return "sc900"
    try:
        with open(source, encoding="utf-8-sig", errors="replace") as f:
            head = [f.readline() for _ in range(50)]
    except OSError:
        return "csv"
    for raw in head:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        delim = "\t" if "\t" in line else ";" if ";" in line else ","
        cells = [c.strip().lower() for c in next(csv.reader([raw], delimiter=delim))]
        if any(_match_field(c, CI_SCHEMA) and wide_depth_header(c) is None for c in cells):
            return "csv"
        if sum(wide_depth_header(c) is not None for c in cells) >= 3:
            return "wide"
        if sum(bool(c) for c in cells) >= 3:  # a header that is not wide
            return "csv"
        # short preamble lines ("Unit: MPa", "Date;2019-06-11") may precede the header
    return "csv"


def read_ci_profiles(
    path: PathLike,
    *,
    cone: str | Cone = "asabe-large",
    depth_ref: Literal["base", "tip"] = "base",
    units: str | None = None,
    on_error: OnError = "raise",
    format: Literal["csv", "sc900", "wide"] | None = None,
    depth_unit: str | None = None,
    ci_unit: str | None = None,
) -> list[CIProfile | InputError]:
    """Read cone index profiles from a CSV file, an SC900 export or a wide table.

    Parameters
    ----------
    path : str or path-like
        The file.
    cone : str or Cone
        Cone of profiles whose file does not say (no ``cone`` column).  A
        ``cone`` column of a CSV file, and the ``Cone Size`` of an SC900
        export, take precedence.
    depth_ref : {"base", "tip"}
        What the file's depths measure: the depth of the cone base
        (``"base"``, the model's depth) or of the cone tip (``"tip"``, then
        base depth = tip depth - H with H the cone height, so the first
        readings may be partial penetrations, -H <= base depth < 0).
    units : {"si", "us"} or None
        Unit system assumed for CSV columns written without a unit suffix
        (``depth``, ``ci``) and for an SC900 export without a unit line.
        None (default) requires the units to be stated in the file.
    on_error : {"raise", "collect"}
        ``"raise"``: the first bad profile raises :class:`InputError`.
        ``"collect"``: a bad profile becomes an :class:`InputError` item of
        the returned list (with ``.profile`` set), in file order; the good
        ones are returned as :class:`CIProfile`.  Problems with the file
        itself (missing, bad header) raise in both modes.
    format : {"csv", "sc900", "wide"} or None
        File format; None detects it (:func:`detect_format`).  ``"wide"``:
        one row per push, one column per depth, read by :func:`read_wide_ci`.
    depth_unit, ci_unit : str, optional
        Units of a wide table (see :func:`read_wide_ci`); not used otherwise.

    Returns
    -------
    list of CIProfile or InputError
        One item per profile (CSV) or push (SC900), in file order.  Depths
        in m (cone base), CI in kPa; ``rows`` holds the file line number of
        every point and ``source`` the path.

    Raises
    ------
    InputError
        Naming the file, profile, row (line number) and column of the
        problem: missing file or column, unknown unit suffix, two columns
        for one quantity; and, per profile, a non-numeric, NaN or empty
        cell, a negative CI, depths not strictly increasing, fewer than 3
        points or a base depth above -H.

    Notes
    -----
    SC900 exports give one profile per push with id
    ``"{file stem}/{ordinal:04d}-N{push}"`` (ordinal: 1-based count of push
    lines in the file, as push numbers restart after each "Logger Started"
    line).  Trailing zero readings mean that the push stopped; they are
    dropped and recorded in ``notes`` and in ``metadata["trailing_zeros_dropped"]``.
    The cone comes from the ``Cone Size`` column (``SC900_CONES``), the
    pressure unit from the "... In KPa" / "... In PSI" line, the depths from
    the depth column labels; every point of a push has the push line as
    its row.  Metadata: ``logger``, ``serial``, ``datum``, ``push``,
    ``line``, ``longitude`` and ``latitude`` (when present),
    ``pressure_unit`` and ``length_unit`` (the file's CI and depth units)
    and ``trailing_zeros_dropped``; none of these names reads as a data
    column, so :func:`write_ci_profiles` can write the profiles to CSV.

    Examples
    --------
    >>> profiles = read_ci_profiles("site.csv", cone="asabe-small")  # doctest: +SKIP
    """
    _check_on_error(on_error)
    if depth_ref not in ("base", "tip"):
        raise ValueError(f"depth_ref must be 'base' or 'tip' (got {depth_ref!r})")
    if units is not None:
        u.check_system(units)
    default_cone = get_cone(cone)
    source = os.fspath(path)
    if format is None:
        format = detect_format(source)
    if format == "csv":
        return _read_ci_csv(source, default_cone, depth_ref, units, on_error)
    if format == "sc900":
        return _read_sc900(source, depth_ref, units, on_error)
    if format == "wide":
        return read_wide_ci(
            source,
            depth_unit=depth_unit,
            ci_unit=ci_unit,
            cone=default_cone,
            depth_ref=depth_ref,
            on_error=on_error,
        )
    raise ValueError(f"format must be 'csv', 'sc900', 'wide' or None (got {format!r})")


def _read_ci_csv(
    path: str, default_cone: Cone, depth_ref: str, units: str | None, on_error: str
) -> list[CIProfile | InputError]:
    table = _read_table(path)
    layout = column_layout(table, CI_SCHEMA, units)
    dcol, ccol = layout.groups["depth"], layout.groups["ci"]
    depth = to_numbers(table.columns[dcol.index])
    ci = to_numbers(table.columns[ccol.index])
    cone_col = layout.extra.get("cone")
    lines = table.lines

    def build(group: tuple[str, np.ndarray]) -> CIProfile:
        pid, idx = group

        def fail(msg: str, i: int, column: str | None) -> InputError:
            return InputError(msg, file=path, profile=pid, row=int(lines[i]), column=column)

        if layout.id_col is not None and not pid:
            raise fail("empty profile id", int(idx[0]), layout.id_col.name)
        bad = _first_bad(idx, [(dcol, depth), (ccol, ci)])
        if bad is not None:
            i, col, why = bad
            raise fail(why, i, col.name)
        prof_cone = default_cone
        if cone_col is not None:
            cells = table.columns[cone_col.index]
            name = cells[int(idx[0])].strip()
            try:
                prof_cone = get_cone(name)
            except ValueError as exc:
                why = "empty cell" if not name else str(exc)
                raise fail(why, int(idx[0]), cone_col.name) from None
            for i in idx[1:]:
                if cells[int(i)].strip() != name:
                    raise fail(
                        f"cone changes within the profile ({cells[int(i)].strip()!r} here, "
                        f"{name!r} on line {int(lines[idx[0]])})",
                        int(i),
                        cone_col.name,
                    )
        z = depth.values[idx] * dcol.factor
        if depth_ref == "tip":
            z = z - prof_cone.height
        profile = CIProfile(
            id=pid,
            depth=z,
            ci=ci.values[idx] * ccol.factor,
            cone=prof_cone,
            metadata=_metadata(table, layout, int(idx[0])),
            source=path,
            rows=lines[idx].copy(),
        )

        def locate(k: int | None, column: str | None) -> tuple[int | None, str | None, str]:
            col = dcol if column == "depth" else ccol
            if k is None:  # too few points
                span = f"line {int(lines[idx[0]])}"
                if idx.size > 1:
                    span = f"lines {int(lines[idx[0]])}-{int(lines[idx[-1]])}"
                return int(lines[idx[0]]), col.name, f" (the profile is on {span})"
            i = int(idx[k])
            more = f" (cell {table.columns[col.index][i].strip()!r}"
            if column == "depth" and depth_ref == "tip":
                more += f", a tip depth; base depth = tip depth - H, H = {prof_cone.height:.4g} m"
            if column == "depth" and k > 0:
                prev = int(idx[k - 1])
                more += f"; previous depth {table.columns[col.index][prev].strip()!r} on line {int(lines[prev])}"
            return int(lines[i]), col.name, more + ")"

        return _validated(profile, locate)

    return _collect(_groups(table, layout.id_col), build, on_error)


# ---------------------------------------------------------------------------
# FieldScout SC900 export
# ---------------------------------------------------------------------------

_SC900_DEPTH = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+))\s*([a-zA-Z]+)\s*$")
_SC900_UNIT = re.compile(r"\bIn\s+(KPa|PSI)\s*$", re.IGNORECASE)
_SC900_PUSH = re.compile(r"^N\s*=\s*(\d+)$", re.IGNORECASE)


@dataclass
class _Push:
    ordinal: int
    line: int
    fields: list[str]


def _read_sc900(
    path: str, depth_ref: str, units: str | None, on_error: str
) -> list[CIProfile | InputError]:
    text = _read_lines(path)
    stem = Path(path).stem
    header: dict[str, Any] = {}
    ci_unit: str | None = None
    labels: list[str] | None = None
    column_line = 0
    pushes: list[_Push] = []
    for lineno, raw in enumerate(text, 1):
        line = raw.strip()
        if not line:
            continue
        if labels is None:
            m = re.match(r"^(Name|Serial\s*#?|Datum)\s*:\s*(.*)$", line, re.IGNORECASE)
            if m:
                key = m.group(1).lower()
                key = "logger" if key == "name" else "serial" if key.startswith("serial") else key
                header[key] = m.group(2).strip()
                continue
            m = _SC900_UNIT.search(line)
            if m:
                ci_unit = m.group(1).lower()
                continue
            if re.match(r"^Longitude\s*,\s*Latitude\s*,\s*Number\s*,", line, re.IGNORECASE):
                labels = [c.strip() for c in line.split(",")[3:]]
                column_line = lineno
                continue
            continue  # other header text carries nothing we use
        fields = [c.strip() for c in line.split(",")]
        if len(fields) >= 3 and fields[2].lower() == "logger started":
            continue
        if len(fields) >= 3 and fields[2].upper().startswith("N="):
            pushes.append(_Push(len(pushes) + 1, lineno, fields))
            continue
        raise InputError(
            "not a push line (expected 'lon,lat,N= k , readings..., cone size') "
            "nor a 'Logger Started' line",
            file=path,
            row=lineno,
        )
    if labels is None:
        raise InputError(
            "no column line 'Longitude,Latitude,Number,<depths>,Cone Size' (not an SC900 export?)",
            file=path,
        )
    if not labels or labels[-1].lower() != "cone size":
        raise InputError(
            "the column line does not end with 'Cone Size'",
            file=path,
            row=column_line,
            column=labels[-1] if labels else None,
        )
    labels = labels[:-1]
    depths = np.empty(len(labels))
    depth_units: list[str] = []
    for k, label in enumerate(labels):
        m = _SC900_DEPTH.match(label)
        unit = m.group(2).lower() if m else None
        if m is None or unit not in u.LENGTH_UNITS:
            raise InputError(
                f"not a depth label like '2.5 cm' (units {', '.join(u.LENGTH_UNITS)})",
                file=path,
                row=column_line,
                column=label,
            )
        depths[k] = float(m.group(1)) * u.LENGTH_UNITS[unit]
        if unit not in depth_units:
            depth_units.append(unit)
    if ci_unit is None:
        if units is None:
            raise InputError(
                "no unit line (e.g. 'Soil Compation In KPa'); state the unit system (units='si' or 'us' in Python, --file-units on the command line)",
                file=path,
            )
        ci_unit = u.pressure_unit(units).lower()
    factor = u.PRESSURE_UNITS[ci_unit]
    nd = len(labels)

    def build(push: _Push) -> CIProfile:
        f = push.fields
        m = _SC900_PUSH.match(f[2].replace(" ", ""))
        number = int(m.group(1)) if m else None
        pid = f"{stem}/{push.ordinal:04d}-N{number if number is not None else '?'}"

        def fail(msg: str, column: str | None) -> InputError:
            return InputError(msg, file=path, profile=pid, row=push.line, column=column)

        if number is None:
            raise fail(f"push number {f[2]!r} is not 'N= <integer>'", "Number")
        if len(f) != nd + 4:
            got = len(f) - 4
            column = labels[got] if got < nd else "Cone Size"
            raise fail(f"{max(got, 0)} readings but the column line has {nd} depths", column)
        size = f[-1]
        cone_name = SC900_CONES.get(" ".join(size.lower().split()))
        if cone_name is None:
            known = ", ".join(repr(s.title()) for s in SC900_CONES)
            raise fail(f"unknown cone size {size!r} (known: {known})", "Cone Size")
        push_cone = CONES[cone_name]
        metadata: dict[str, Any] = dict(header)
        metadata["push"] = number
        metadata["line"] = push.line
        for k, key in ((0, "longitude"), (1, "latitude")):
            if f[k]:
                if _cell_problem(f[k]) is not None:
                    raise fail(f"{key} {f[k]!r} is not a number", key.title())
                metadata[key] = float(f[k])
        readings = to_numbers(f[3 : 3 + nd])
        if readings.bad.any():
            k = int(np.flatnonzero(readings.bad)[0])
            raise fail(readings.reasons[k], labels[k])
        metadata["pressure_unit"] = ci_unit
        metadata["length_unit"] = depth_units[0] if len(depth_units) == 1 else ",".join(depth_units)
        profile, keep, dropped = _push_profile(
            pid,
            depths,
            readings.values * factor,
            push_cone,
            depth_ref,
            metadata,
            path,
            push.line,
            [],
            lambda k: str(labels[k]),
        )

        def locate(k: int | None, column: str | None) -> tuple[int | None, str | None, str]:
            if k is None:  # too few points
                more = f" after dropping {dropped} trailing zero readings" if dropped else ""
                return push.line, labels[keep] if dropped else labels[0], more
            more = f" (reading {f[3 + k]!r})"
            if column == "depth" and depth_ref == "tip":
                more = f" (a tip depth; base depth = tip depth - H, H = {push_cone.height:.4g} m)"
            return push.line, labels[k], more

        return _validated(profile, locate)

    return _collect(pushes, build, on_error)


# ---------------------------------------------------------------------------
# wide tables: one row per push, one column per depth
# ---------------------------------------------------------------------------

#: Header cells that name the push (lower case, in order of preference).
WIDE_ID_COLUMNS = ("profile", "id", "point", "number", "push", "name", "no", "nr", "label")
#: Header cells holding latitude / longitude (lower case).
WIDE_LAT_COLUMNS = ("lat", "latitude", "coord_y", "y_coord", "gps_lat", "lat_deg")
WIDE_LON_COLUMNS = ("lon", "long", "lng", "longitude", "coord_x", "x_coord", "gps_lon", "lon_deg")
#: Pressure units of ``ci_unit`` (wide tables).
WIDE_CI_UNITS = ("kpa", "mpa", "psi")

_WIDE_DEPTH = re.compile(
    r"^(?:depth[ _-]?)?([0-9]+(?:[.,][0-9]*)?|[.,][0-9]+)\s*(m|cm|mm|in)?$", re.IGNORECASE
)
_WIDE_UNIT_STATED = re.compile(
    r"(?:\bci[ _-]?unit\s*[:=]\s*|\bunit\s*[:=]\s*|\bin\s+|\[)(kpa|mpa|psi)\b", re.IGNORECASE
)
_COORD = re.compile(
    r"^\s*([NSEW])?\s*([+-]?\d+(?:\.\d+)?)\s*(?:°|deg|d|\s)?\s*"
    r"(?:(\d+(?:\.\d+)?)\s*(?:'|′|m|\s)?\s*)?"
    r"(?:(\d+(?:\.\d+)?)\s*(?:\"|″|''|s)?\s*)?([NSEW])?\s*$",
    re.IGNORECASE,
)


@dataclass
class _WideHeader:
    delimiter: str
    line: int  # file line of the header
    cells: list[str]
    depth_cols: list[int]
    depth_labels: list[str]
    depth_values: list[float]
    depth_units: list[str | None]
    stated_ci_unit: str | None
    stated_line: int | None


def wide_depth_header(cell: str) -> tuple[float, str | None] | None:
    """(value, unit or None) of a wide-table depth header, else None.

    ``"5"``, ``"5cm"``, ``"2.5 in"``, ``"depth_5cm"``, ``"2,5 cm"`` are depth
    headers; the unit is ``m``, ``cm``, ``mm`` or ``in`` (None when bare).
    """
    m = _WIDE_DEPTH.match(cell.strip())
    if m is None:
        return None
    unit = m.group(2).lower() if m.group(2) else None
    return float(m.group(1).replace(",", ".")), unit


def parse_coordinate(text: str, axis: Literal["lat", "lon"]) -> float | None:
    """Decimal degrees of a latitude or longitude cell; None when empty.

    Accepts decimal degrees (``-34.38201``, ``34,38201`` with a decimal
    comma), degrees and decimal minutes (``34°22.92106S``, ``S 34 22.921``),
    and degrees, minutes and seconds (``34°22'55.26"S``), the hemisphere
    letter before or after (S and W negative).  Raises ValueError with the
    reason when the cell is not a coordinate of that axis.
    """
    cell = text.strip().replace(",", ".")
    if not cell:
        return None
    m = _COORD.match(cell)
    if m is None:
        raise ValueError(f"not a coordinate: {text.strip()!r}")
    pre, deg, minutes, seconds, post = m.groups()
    if pre and post:
        raise ValueError(f"two hemisphere letters in {text.strip()!r}")
    hemi = (pre or post or "").upper()
    allowed = "NS" if axis == "lat" else "EW"
    if hemi and hemi not in allowed:
        raise ValueError(
            f"hemisphere {hemi!r} in a {axis} cell {text.strip()!r} (use {allowed[0]}/{allowed[1]})"
        )
    d = float(deg)
    if hemi and d < 0:
        raise ValueError(f"a sign and a hemisphere letter in {text.strip()!r}")
    mins = float(minutes) if minutes else 0.0
    secs = float(seconds) if seconds else 0.0
    if mins >= 60 or secs >= 60:
        raise ValueError(f"minutes and seconds must be below 60 in {text.strip()!r}")
    if (minutes or seconds) and d != int(d):
        raise ValueError(f"fractional degrees with minutes in {text.strip()!r}")
    value = abs(d) + mins / 60.0 + secs / 3600.0
    if d < 0 or deg.startswith("-") or hemi in ("S", "W"):
        value = -value
    limit = 90.0 if axis == "lat" else 180.0
    if abs(value) > limit:
        raise ValueError(f"{axis} {value:g} is outside [-{limit:g}, {limit:g}]")
    return value


def _wide_header(path: str, text: list[str], delimiter: str | None) -> _WideHeader:
    """Find the header line of a wide table (the first with depth headers)."""
    stated: str | None = None
    stated_line: int | None = None
    for lineno, raw in enumerate(text, 1):
        line = raw.strip()
        if not line:
            continue
        delim = delimiter or ("\t" if "\t" in line else ";" if ";" in line else ",")
        cells = [c.strip() for c in next(csv.reader([raw], delimiter=delim))]
        found = [(j, wide_depth_header(c)) for j, c in enumerate(cells)]
        found = [(j, d) for j, d in found if d is not None]
        if not line.startswith("#") and len(found) >= 3:
            while cells and not cells[-1]:  # trailing separators (spreadsheet exports)
                cells.pop()
            cells = [c or f"column{j + 1}" for j, c in enumerate(cells)]  # unnamed columns
            return _WideHeader(
                delim,
                lineno,
                cells,
                [j for j, _ in found],
                [cells[j] for j, _ in found],
                [d[0] for _, d in found],
                [d[1] for _, d in found],
                stated,
                stated_line,
            )
        m = _WIDE_UNIT_STATED.search(line)
        if m:
            unit = m.group(1).lower()
            if stated is not None and unit != stated:
                raise InputError(
                    f"the file states two cone index units ({stated} on line {stated_line}, {unit} here)",
                    file=path,
                    row=lineno,
                )
            stated, stated_line = unit, lineno
    raise InputError(
        "no header line with at least 3 depth columns (e.g. '0;5;10' or '0 cm,2.5 cm,5 cm'): "
        "not a wide table",
        file=path,
    )


def _wide_units(
    path: str, head: _WideHeader, depth_unit: str | None, ci_unit: str | None
) -> tuple[np.ndarray, str, list[str]]:
    """Depths [m] of the depth columns, the CI unit and the depth units used."""
    missing = []
    bare = [lab for lab, un in zip(head.depth_labels, head.depth_units) if un is None]
    if bare and depth_unit is None:
        missing.append(
            f"--depth-unit {'|'.join(u.LENGTH_UNITS)} (depth_unit= in Python): "
            f"the depth columns {bare[0]!r}, ... have no unit"
        )
    stated = head.stated_ci_unit
    if stated is None and ci_unit is None:
        missing.append(
            f"--ci-unit {'|'.join(WIDE_CI_UNITS)} (ci_unit= in Python): "
            "the file does not state the unit of its readings"
        )
    if missing:
        raise InputError(
            "refusing to guess units; give " + " and ".join(missing), file=path, row=head.line
        )
    if depth_unit is not None and depth_unit.lower() not in u.LENGTH_UNITS:
        raise ValueError(
            f"depth_unit must be one of {', '.join(u.LENGTH_UNITS)} (got {depth_unit!r})"
        )
    if ci_unit is not None and ci_unit.lower() not in WIDE_CI_UNITS:
        raise ValueError(f"ci_unit must be one of {', '.join(WIDE_CI_UNITS)} (got {ci_unit!r})")
    if stated is not None and ci_unit is not None and ci_unit.lower() != stated:
        raise InputError(
            f"the file states cone index in {stated} but ci_unit (--ci-unit) is {ci_unit.lower()}",
            file=path,
            row=head.stated_line,
        )
    units = [(un or depth_unit.lower()) for un in head.depth_units]  # type: ignore[union-attr]
    depths = np.array([v * u.LENGTH_UNITS[un] for v, un in zip(head.depth_values, units)])
    bad = np.flatnonzero(np.diff(depths) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(
            f"depth columns are not strictly increasing ({head.depth_labels[k - 1]!r} before this one)",
            file=path,
            row=head.line,
            column=head.depth_labels[k],
        )
    used = list(dict.fromkeys(units))
    return depths, stated or ci_unit.lower(), used  # type: ignore[union-attr]


def _wide_number(cell: str, comma: bool) -> str:
    return cell.strip().replace(",", ".") if comma else cell.strip()


def read_wide_ci(
    path: PathLike,
    *,
    depth_unit: str | None = None,
    ci_unit: str | None = None,
    cone: str | Cone = "asabe-large",
    depth_ref: Literal["base", "tip"] = "base",
    on_error: OnError = "raise",
    delimiter: str | None = None,
) -> list[CIProfile | InputError]:
    """Read a wide table of cone index pushes: one row per push, one column per depth.

    Parameters
    ----------
    path : str or path-like
        The file (UTF-8, a byte-order mark is accepted).
    depth_unit : {"m", "cm", "mm", "in"}, optional
        Unit of depth headers written as bare numbers (``5``, ``10``).  Required
        when there are any; headers with a unit (``5cm``, ``2.5 in``,
        ``depth_5cm``) carry their own.
    ci_unit : {"kpa", "mpa", "psi"}, optional
        Unit of the readings, unless the file states it on a line before the
        header (``# ci unit: MPa``, ``Unit: kPa``, ``... In KPa`` or ``[MPa]``).
        Required otherwise; a value that contradicts the file is an error.
    cone : str or Cone
        Cone of the pushes without a ``cone`` column (a name of
        :func:`terracone.cone.get_cone`, e.g. ``"penetrologger-1cm2"``).
    depth_ref : {"base", "tip"}
        As in :func:`read_ci_profiles`.
    on_error : {"raise", "collect"}
        As in :func:`read_ci_profiles`.
    delimiter : str, optional
        Field separator; by default detected from the header line: a tab if it
        has one, else ``;`` if it has one, else ``,``.  With ``;`` a decimal
        comma is accepted (``1,25``) in readings, depths and coordinates.

    Returns
    -------
    list of CIProfile or InputError
        One item per data row, in file order; depths in m, CI in kPa, ``rows``
        the file line of the push (every point), ``source`` the path.

    Raises
    ------
    InputError
        File-level problems: no header with 3 or more depth columns, a depth
        unit or CI unit that is neither stated nor given (the message names the
        missing option), depths not increasing.  Per push (raised, or
        collected): a non-numeric reading, an empty cell between readings, a bad
        coordinate, a duplicate id, and the checks of :meth:`CIProfile.validate`.

    Notes
    -----
    * The push id is the cell of the first id column found among
      :data:`WIDE_ID_COLUMNS` (``profile``, ``id``, ``point``, ``number``, ...,
      case-insensitive), else ``"{file stem}/{k}"`` with k the 1-based data row.
    * Latitude and longitude columns (:data:`WIDE_LAT_COLUMNS`,
      :data:`WIDE_LON_COLUMNS`: ``lat``/``lon``, ``latitude``/``longitude``,
      ``COORD_Y``/``COORD_X``, ...) are read by :func:`parse_coordinate` into
      ``metadata["lat"]`` and ``metadata["lon"]`` (decimal degrees).
    * The readings of a push run from its first to its last non-empty depth
      cell: empty cells after the last reading end the push (as do empty
      cells before the first, noted); an empty cell between two readings is an
      error naming its column.  Trailing zero readings mean the push stopped:
      they are dropped, noted in ``notes`` and counted in
      ``metadata["trailing_zeros_dropped"]``, as for SC900 exports.
    * Any other column is metadata (numbers as floats).  Metadata also holds
      ``pressure_unit``, ``length_unit`` and ``line``.

    Examples
    --------
    >>> read_wide_ci("pushes.csv", depth_unit="cm", ci_unit="mpa")  # doctest: +SKIP
    """
    _check_on_error(on_error)
    if depth_ref not in ("base", "tip"):
        raise ValueError(f"depth_ref must be 'base' or 'tip' (got {depth_ref!r})")
    source = os.fspath(path)
    default_cone = get_cone(cone)
    text = _read_lines(source)
    head = _wide_header(source, text, delimiter)
    depths, ci_u, depth_units = _wide_units(source, head, depth_unit, ci_unit)
    factor = u.PRESSURE_UNITS[ci_u]
    comma = head.delimiter in (";", "\t")
    lower = [c.lower() for c in head.cells]
    depth_set = set(head.depth_cols)

    def first(names: Sequence[str]) -> int | None:
        for name in names:
            if name in lower and lower.index(name) not in depth_set:
                return lower.index(name)
        return None

    id_j, lat_j, lon_j = first(WIDE_ID_COLUMNS), first(WIDE_LAT_COLUMNS), first(WIDE_LON_COLUMNS)
    cone_j = first(("cone",))
    special = {j for j in (id_j, lat_j, lon_j, cone_j) if j is not None}
    meta_cols = [j for j in range(len(head.cells)) if j not in depth_set and j not in special]
    stem = Path(source).stem
    rows: list[tuple[int, list[str]]] = []
    for lineno in range(head.line + 1, len(text) + 1):
        raw = text[lineno - 1]
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        cells = next(csv.reader([raw], delimiter=head.delimiter))
        if len(cells) > len(head.cells) and any(c.strip() for c in cells[len(head.cells) :]):
            raise InputError(
                f"{len(cells)} fields but the header has {len(head.cells)}", file=source, row=lineno
            )
        rows.append((lineno, cells + [""] * (len(head.cells) - len(cells))))
    if not rows:
        raise InputError("no data rows", file=source, row=head.line)
    seen: dict[str, int] = {}
    common = {"pressure_unit": ci_u, "length_unit": ",".join(depth_units)}

    def build(item: tuple[int, tuple[int, list[str]]]) -> CIProfile:
        k, (line, cells) = item
        pid = cells[id_j].strip() if id_j is not None else f"{stem}/{k}"

        def fail(msg: str, j: int | None) -> InputError:
            column = head.cells[j] if j is not None else None
            return InputError(msg, file=source, profile=pid, row=line, column=column)

        if id_j is not None:
            if not pid:
                raise fail("empty id", id_j)
            if pid in seen:
                raise fail(f"duplicate id (also on line {seen[pid]})", id_j)
        seen.setdefault(pid, line)
        metadata: dict[str, Any] = {}
        for j in meta_cols:
            cell = cells[j]
            num = _wide_number(cell, comma)
            metadata[head.cells[j]] = float(num) if DECIMAL.match(num) else cell.strip()
        for j, key in ((lat_j, "lat"), (lon_j, "lon")):
            if j is not None:
                try:
                    value = parse_coordinate(cells[j], key)  # type: ignore[arg-type]
                except ValueError as exc:
                    raise fail(str(exc), j) from None
                if value is not None:
                    metadata[key] = value
        push_cone = default_cone
        if cone_j is not None and cells[cone_j].strip():
            try:
                push_cone = get_cone(cells[cone_j].strip())
            except ValueError as exc:
                raise fail(str(exc), cone_j) from None
        return _wide_push(
            source,
            pid,
            line,
            cells,
            head,
            depths,
            factor,
            comma,
            push_cone,
            depth_ref,
            {**metadata, **common, "line": line},
            fail,
        )

    return _collect(list(enumerate(rows, 1)), build, on_error)


def _push_profile(
    pid: str,
    depth: np.ndarray,
    ci: np.ndarray,
    cone: Cone,
    depth_ref: str,
    metadata: dict[str, Any],
    source: str,
    line: int,
    notes: list[str],
    stop_label: Callable[[int], str],
) -> tuple[CIProfile, int, int]:
    """One instrument push (a row of an SC900 export or a wide table) as a CIProfile.

    ``depth`` [m] and ``ci`` [kPa] are the push's readings in depth order.  Trailing
    zero readings mean the push stopped: they are dropped, noted (``stop_label(k)``
    names where the k-th reading stood) and counted in
    ``metadata["trailing_zeros_dropped"]``; with ``depth_ref="tip"`` the cone base is
    H above the tip.  Returns the profile, the readings kept and the readings dropped.
    """
    nonzero = np.flatnonzero(ci != 0)
    keep = int(nonzero[-1]) + 1 if nonzero.size else 0
    dropped = ci.size - keep
    if dropped:
        s = "" if dropped == 1 else "s"
        notes.append(
            f"dropped {dropped} trailing zero reading{s} (push stopped at {stop_label(keep)})"
        )
    metadata["trailing_zeros_dropped"] = dropped
    z = depth[:keep] - cone.height if depth_ref == "tip" else depth[:keep]
    profile = CIProfile(
        id=pid,
        depth=z,
        ci=ci[:keep],
        cone=cone,
        metadata=metadata,
        source=source,
        notes=notes,
        rows=np.full(keep, line, dtype=int),
    )
    return profile, keep, dropped


def _wide_push(
    source: str,
    pid: str,
    line: int,
    cells: list[str],
    head: _WideHeader,
    depths: np.ndarray,
    factor: float,
    comma: bool,
    push_cone: Cone,
    depth_ref: str,
    metadata: dict[str, Any],
    fail: Callable[[str, int | None], InputError],
) -> CIProfile:
    """One push of a wide table: readings, empty cells, trailing zeros."""
    raw = [_wide_number(cells[j], comma) for j in head.depth_cols]
    filled = np.flatnonzero([bool(c) for c in raw])
    if not filled.size:
        raise fail("no readings (every depth cell is empty)", head.depth_cols[0])
    a, b = int(filled[0]), int(filled[-1]) + 1
    for k in range(a, b):
        if not raw[k]:
            raise fail(
                f"empty cell between readings ({head.depth_labels[k - 1]!r} and "
                f"{head.depth_labels[int(filled[filled > k][0])]!r} have readings)",
                head.depth_cols[k],
            )
    readings = to_numbers(raw[a:b])
    if readings.bad.any():
        k = int(np.flatnonzero(readings.bad)[0])
        raise fail(readings.reasons[k], head.depth_cols[a + k])
    notes = []
    if a:
        notes.append(f"first reading at {head.depth_labels[a]} (the cells before it are empty)")
    profile, keep, dropped = _push_profile(
        pid,
        depths[a:b],
        readings.values * factor,
        push_cone,
        depth_ref,
        metadata,
        source,
        line,
        notes,
        lambda k: f"depth column {head.depth_labels[a + k]!r}",
    )

    def locate(k: int | None, column: str | None) -> tuple[int | None, str | None, str]:
        if k is None:
            more = f" after dropping {dropped} trailing zero readings" if dropped else ""
            return line, head.depth_labels[a + keep] if dropped else head.depth_labels[a], more
        more = f" (reading {raw[a + k]!r})"
        if column == "depth" and depth_ref == "tip":
            more = f" (a tip depth; base depth = tip depth - H, H = {push_cone.height:.4g} m)"
        return line, head.depth_labels[a + k], more

    return _validated(profile, locate)


# ---------------------------------------------------------------------------
# plate and shear tests
# ---------------------------------------------------------------------------


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
    _check_on_error(on_error)
    source = os.fspath(path)
    table = _read_table(source)
    layout = column_layout(table, _PLATE_SCHEMA)
    scol, zcol, pcol = (layout.groups[g] for g in ("size", "sinkage", "pressure"))
    size, sink, pres = (to_numbers(table.columns[c.index]) for c in (scol, zcol, pcol))
    circular = scol.field is not None and scol.field.name != "plate_width"
    halve = scol.field is not None and scol.field.name == "plate_diameter"

    def build(group: tuple[str, np.ndarray]) -> PlateTest:
        tid, idx = group
        if layout.id_col is not None and not tid:
            raise InputError(
                "empty test id",
                file=source,
                profile=tid,
                item="test",
                row=int(table.lines[idx[0]]),
                column=layout.id_col.name,
            )
        bad = _first_bad(idx, [(scol, size), (zcol, sink), (pcol, pres)])
        if bad is not None:
            i, col, why = bad
            raise InputError(
                why, file=source, profile=tid, item="test", row=int(table.lines[i]), column=col.name
            )
        b = _check_constant(source, tid, table, idx, scol, size, "plate size") * scol.factor
        if halve:
            b /= 2.0
        if not b > 0:
            raise InputError(
                "plate size must be > 0",
                file=source,
                profile=tid,
                item="test",
                row=int(table.lines[idx[0]]),
                column=scol.name,
            )
        return PlateTest(
            id=tid,
            b=b,
            shape="circular" if circular else "rectangular",
            sinkage=sink.values[idx] * zcol.factor,
            pressure=pres.values[idx] * pcol.factor,
            metadata=_metadata(table, layout, int(idx[0])),
            source=source,
            rows=table.lines[idx].copy(),
        )

    return _collect(_groups(table, layout.id_col), build, on_error)


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
    _check_on_error(on_error)
    source = os.fspath(path)
    table = _read_table(source)
    layout = column_layout(table, _SHEAR_SCHEMA)
    ncol, jcol, tcol = (layout.groups[g] for g in ("normal_pressure", "displacement", "stress"))
    normal, disp, stress = (to_numbers(table.columns[c.index]) for c in (ncol, jcol, tcol))

    def build(group: tuple[str, np.ndarray]) -> ShearTest:
        tid, idx = group
        if layout.id_col is not None and not tid:
            raise InputError(
                "empty test id",
                file=source,
                profile=tid,
                item="test",
                row=int(table.lines[idx[0]]),
                column=layout.id_col.name,
            )
        bad = _first_bad(idx, [(ncol, normal), (jcol, disp), (tcol, stress)])
        if bad is not None:
            i, col, why = bad
            raise InputError(
                why, file=source, profile=tid, item="test", row=int(table.lines[i]), column=col.name
            )
        sigma = _check_constant(source, tid, table, idx, ncol, normal, "normal pressure")
        return ShearTest(
            id=tid,
            normal_pressure=sigma * ncol.factor,
            displacement=disp.values[idx] * jcol.factor,
            stress=stress.values[idx] * tcol.factor,
            metadata=_metadata(table, layout, int(idx[0])),
            source=source,
            rows=table.lines[idx].copy(),
        )

    return _collect(_groups(table, layout.id_col), build, on_error)


# ---------------------------------------------------------------------------
# writers
# ---------------------------------------------------------------------------


def _unit(name: str, kind: str) -> tuple[str, float]:
    key = str(name).lower()
    table = _UNIT_TABLES[kind]
    if key not in table:
        raise ValueError(f"{kind} unit must be one of {', '.join(table)} (got {name!r})")
    return key, table[key]


def _fmt(value: Any) -> str:
    """A cell: floats with repr (round-trips exactly), None as empty."""
    if value is None:
        return ""
    if isinstance(value, float | np.floating):
        return repr(float(value))
    return str(value)


def _numbers(values: np.ndarray, factor: float) -> list[str]:
    return [repr(v) for v in (np.asarray(values, dtype=float) / factor).tolist()]


def _metadata_columns(items: Sequence[Any], schema: _Schema, reserved: Sequence[str]) -> list[str]:
    """Union of the metadata keys of the items, in order of first appearance."""
    keys: dict[str, str] = {}
    for item in items:
        for key in item.metadata:
            name = str(key)
            lower = name.strip().lower()
            if name != name.strip() or not name:
                raise ValueError(f"metadata key {name!r} cannot be a column name")
            if lower in reserved or _match_field(lower, schema) is not None:
                raise ValueError(
                    f"metadata key {name!r} would be read back as a data column; rename it"
                )
            if lower in keys and keys[lower] != name:
                raise ValueError(f"metadata keys {keys[lower]!r} and {name!r} differ only in case")
            keys[lower] = name
    return list(keys.values())


def _write_rows(
    path: PathLike,
    header: list[str],
    rows: Iterator[list[str]],
    comment: str | Sequence[str] | None,
) -> None:
    with open(os.fspath(path), "w", encoding="utf-8", newline="") as f:
        if comment is not None:
            lines = comment.splitlines() if isinstance(comment, str) else list(comment)
            for line in lines:
                f.write(f"# {line}\n" if line else "#\n")
        plain = csv.writer(f, lineterminator="\n")
        quoted = csv.writer(f, lineterminator="\n", quoting=csv.QUOTE_ALL)
        plain.writerow(header)
        for row in rows:
            # a record starting with '#' would read back as a comment: quote it
            (quoted if row and row[0].lstrip().startswith("#") else plain).writerow(row)


def _check_unique_ids(items: Sequence[Any], what: str) -> None:
    seen: set[str] = set()
    for item in items:
        if item.id in seen:
            raise ValueError(f"duplicate {what} id {item.id!r}: they would merge on reading")
        seen.add(item.id)


def _cone_spec(cone: Cone) -> str:
    """A string that :func:`get_cone` turns back into ``cone``."""
    try:
        if get_cone(cone.name) == cone:
            return cone.name
    except ValueError:
        pass
    return f"{2.0 * cone.radius!r}m:{cone.angle_deg!r}"


def write_ci_profiles(
    path: PathLike,
    profiles: Sequence[CIProfile],
    *,
    length_unit: str = "m",
    pressure_unit: str = "kpa",
    comment: str | Sequence[str] | None = None,
) -> None:
    """Write CI profiles to a CSV file that :func:`read_ci_profiles` reads back.

    Parameters
    ----------
    path : str or path-like
        Output file (overwritten).
    profiles : sequence of CIProfile
        Profiles with unique ids.
    length_unit : {"m", "cm", "mm", "in"}
        Unit of the ``depth_<unit>`` column (base depths).
    pressure_unit : {"kpa", "mpa", "psi", "pa"}
        Unit of the ``ci_<unit>`` column.
    comment : str or sequence of str, optional
        Written first, one ``# `` line per line.

    Notes
    -----
    Columns: ``profile``, ``cone``, the metadata keys (union over the
    profiles, in order of first appearance; empty where a profile lacks
    one), ``depth_<unit>``, ``ci_<unit>``.  Floats are written with
    ``repr``, so in m and kPa the numbers read back bit for bit.  Notes,
    rows and source are not written.  A cone that is not a named cone is
    written as ``"<diameter>m:<angle>"``.
    """
    lu, lf = _unit(length_unit, _LENGTH)
    pu, pf = _unit(pressure_unit, _PRESSURE)
    _check_unique_ids(profiles, "profile")
    meta = _metadata_columns(profiles, CI_SCHEMA, ("profile", "cone"))
    header = ["profile", "cone", *meta, f"depth_{lu}", f"ci_{pu}"]

    def rows() -> Iterator[list[str]]:
        for p in profiles:
            fixed = [str(p.id), _cone_spec(p.cone)] + [_fmt(p.metadata.get(k)) for k in meta]
            for z, c in zip(_numbers(p.depth, lf), _numbers(p.ci, pf)):
                yield [*fixed, z, c]

    _write_rows(path, header, rows(), comment)


def write_plate_tests(
    path: PathLike,
    tests: Sequence[PlateTest],
    *,
    length_unit: str = "m",
    pressure_unit: str = "kpa",
    comment: str | Sequence[str] | None = None,
) -> None:
    """Write plate tests to a CSV file that :func:`read_plate_tests` reads back.

    Parameters
    ----------
    path : str or path-like
        Output file (overwritten).
    tests : sequence of PlateTest
        Tests with unique ids, all circular (written as ``plate_radius``)
        or all rectangular (``plate_width``).
    length_unit : {"m", "cm", "mm", "in"}
        Unit of the plate size and sinkage columns.
    pressure_unit : {"kpa", "mpa", "psi", "pa"}
        Unit of the pressure column.
    comment : str or sequence of str, optional
        Written first, one ``# `` line per line.
    """
    lu, lf = _unit(length_unit, _LENGTH)
    pu, pf = _unit(pressure_unit, _PRESSURE)
    _check_unique_ids(tests, "test")
    shapes = {t.shape for t in tests}
    if len(shapes) > 1:
        raise ValueError("circular and rectangular plates cannot share a file (one size column)")
    size_col = "plate_width" if shapes == {"rectangular"} else "plate_radius"
    meta = _metadata_columns(tests, _PLATE_SCHEMA, ("test",))
    header = ["test", f"{size_col}_{lu}", *meta, f"sinkage_{lu}", f"pressure_{pu}"]

    def rows() -> Iterator[list[str]]:
        for t in tests:
            fixed = [str(t.id), repr(float(t.b) / lf)] + [_fmt(t.metadata.get(k)) for k in meta]
            for z, p in zip(_numbers(t.sinkage, lf), _numbers(t.pressure, pf)):
                yield [*fixed, z, p]

    _write_rows(path, header, rows(), comment)


def write_shear_tests(
    path: PathLike,
    tests: Sequence[ShearTest],
    *,
    length_unit: str = "m",
    pressure_unit: str = "kpa",
    comment: str | Sequence[str] | None = None,
) -> None:
    """Write shear tests to a CSV file that :func:`read_shear_tests` reads back.

    Parameters
    ----------
    path : str or path-like
        Output file (overwritten).
    tests : sequence of ShearTest
        Tests with unique ids.
    length_unit : {"m", "cm", "mm", "in"}
        Unit of the shear displacement column.
    pressure_unit : {"kpa", "mpa", "psi", "pa"}
        Unit of the normal pressure and shear stress columns.
    comment : str or sequence of str, optional
        Written first, one ``# `` line per line.
    """
    lu, lf = _unit(length_unit, _LENGTH)
    pu, pf = _unit(pressure_unit, _PRESSURE)
    _check_unique_ids(tests, "test")
    meta = _metadata_columns(tests, _SHEAR_SCHEMA, ("test",))
    header = [
        "test",
        f"normal_pressure_{pu}",
        *meta,
        f"shear_displacement_{lu}",
        f"shear_stress_{pu}",
    ]

    def rows() -> Iterator[list[str]]:
        for t in tests:
            fixed = [str(t.id), repr(float(t.normal_pressure) / pf)]
            fixed += [_fmt(t.metadata.get(k)) for k in meta]
            for j, s in zip(_numbers(t.displacement, lf), _numbers(t.stress, pf)):
                yield [*fixed, j, s]

    _write_rows(path, header, rows(), comment)


def json_default(o: Any) -> Any:
    """``default=`` for :func:`json.dumps` of terracone results (numpy, tuples, paths)."""
    if isinstance(o, np.floating | np.integer):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    if isinstance(o, os.PathLike):
        return os.fspath(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


# the writers and reader of prediction results (terracone.result), with the other readers
from .result import read_json as read_results_json  # noqa: E402
from .result import write_json as write_results_json  # noqa: E402
from .result import write_parquet as write_results_parquet  # noqa: E402

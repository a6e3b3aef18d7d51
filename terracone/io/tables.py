"""CSV tables, column schemas and cell conversion: what every reader of :mod:`terracone.io` shares.

Depths are those of the cone base (eq. (2-3)); the formats: ``docs/instruments.md``.
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

from terracone.data import CIProfile, InputError
from terracone.physics import units as u
from terracone.physics.cone import Cone

PathLike = str | os.PathLike[str]
OnError = Literal["raise", "collect"]

LENGTH = "length"
PRESSURE = "pressure"
UNIT_TABLES: dict[str, dict[str, float]] = {
    LENGTH: u.LENGTH_UNITS,
    PRESSURE: u.PRESSURE_UNITS,
}

# decimal numbers only: float() would also take "2018_13" (a plot id) as 201813
DECIMAL = re.compile(r"^\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\s*$")
SPECIAL_FLOAT = re.compile(r"^\s*[+-]?(?:nan|inf|infinity)\s*$", re.IGNORECASE)

#: First characters that make a spreadsheet read a cell as a formula: OWASP's list
#: against CSV injection (https://owasp.org/www-community/attacks/CSV_Injection).
FORMULA_START = "=+-@\t\r"
_PLAIN_NUMBER = re.compile(r"^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")
_GUARDED = re.compile(r"^'+[=+\-@\t\r]")


def guard_formula(cell: Any) -> str:
    """A text cell that a spreadsheet shows as text, never runs as a formula (CSV injection).

    As OWASP recommends, a cell that begins with ``=``, ``+``, ``-``, ``@``, a
    tab or a carriage return gets a leading single quote, which spreadsheets
    take as "this is text" and do not show.  A number (``-1.5``, ``+2e3``) is
    left as it is.  A cell that already begins with quotes before one of those
    characters gets one more, so that :func:`unguard_formula` (which the CSV
    readers apply to ids and text metadata) gives every cell back unchanged.
    """
    text = "" if cell is None else str(cell)
    first = text.lstrip("'")[:1]
    if first and first in FORMULA_START and not _PLAIN_NUMBER.match(text):
        return "'" + text
    return text


def unguard_formula(cell: str) -> str:
    """A text cell without the guard quote of :func:`guard_formula` (as a spreadsheet reads it).

    One leading single quote is dropped when quotes are followed by ``=``,
    ``+``, ``-``, ``@``, a tab or a carriage return; other cells are unchanged.
    """
    return cell[1:] if _GUARDED.match(cell) else cell


def check_options(on_error: str, depth_ref: str = "base", units: str | None = None) -> None:
    """Refuse bad reader options (ValueError naming the option)."""
    if on_error not in ("raise", "collect"):
        raise ValueError(f"on_error must be 'raise' or 'collect' (got {on_error!r})")
    if depth_ref not in ("base", "tip"):
        raise ValueError(f"depth_ref must be 'base' or 'tip' (got {depth_ref!r})")
    if units is not None:
        u.check_system(units)


@dataclass
class Numbers:
    """A column of cells converted to float; ``bad`` marks unusable cells."""

    values: np.ndarray
    bad: np.ndarray
    reasons: dict[int, str]


def cell_problem(cell: str) -> str | None:
    """Why a cell is not a finite number, or None if it is one."""
    if not cell.strip():
        return "empty cell"
    if DECIMAL.match(cell):
        return None
    if SPECIAL_FLOAT.match(cell):
        return f"not a finite number: {cell.strip()!r}"
    return f"not a number: {cell.strip()!r}"


def to_numbers(cells: Sequence[str]) -> Numbers:
    """Convert cells to floats (vectorised when every cell is a plain number)."""
    n = len(cells)
    joined = "".join(cells)
    if joined.isascii() and "_" not in joined:
        try:
            values = np.array(cells, dtype=float).reshape(n)
        except ValueError:
            pass
        else:
            bad = ~np.isfinite(values)
            reasons = {int(i): cell_problem(cells[i]) or "bad cell" for i in np.flatnonzero(bad)}
            return Numbers(values, bad, reasons)
    reasons = {i: why for i, cell in enumerate(cells) if (why := cell_problem(cell)) is not None}
    values = np.array([np.nan if i in reasons else float(c) for i, c in enumerate(cells)])
    return Numbers(values.reshape(n), np.isin(np.arange(n), list(reasons)), reasons)


def is_parquet(path: PathLike) -> bool:
    """Whether a file is Parquet: a ``.parquet`` / ``.pq`` name or the ``PAR1`` magic number."""
    name = os.fspath(path).lower()
    if name.endswith((".parquet", ".pq")):
        return True
    try:
        with open(path, "rb") as f:
            return f.read(4) == b"PAR1"
    except OSError:
        return False


def open_text(path: str) -> TextIO:
    """Open a text file (UTF-8, byte order mark accepted); a located InputError if it cannot be."""
    try:
        return open(path, encoding="utf-8-sig", newline="")  # noqa: SIM115
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a file", file=path) from None
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror or exc}", file=path) from None


def read_lines(path: str) -> list[str]:
    """The lines of a UTF-8 text file (a located InputError if it is not text)."""
    with open_text(path) as f:
        try:
            return f.read().splitlines()
        except UnicodeDecodeError as exc:
            raise InputError(f"not a UTF-8 text file ({exc.reason})", file=path) from None


def check_separator(path: str, header: Sequence[str], row: int | None) -> None:
    """Refuse a header of one column that another separator splits (``;`` or tab): a
    semicolon-separated export of a spreadsheet is not read as a broken comma file."""
    if len(header) != 1:
        return
    for sep, name in ((";", "semicolons (;)"), ("\t", "tabs")):
        if sep in header[0]:
            raise InputError(
                f"the columns are separated by {name}, not commas: terracone reads "
                "comma-separated files with '.' decimals; save the file as CSV with commas "
                "(a wide table, one row per push, may use ';' and ',' decimals: --format wide)",
                file=path,
                row=row,
            )


@dataclass
class Table:
    """A CSV table as read: header, its file line, columns of cells and the file line of
    each data row (shared by the readers here and by batch's streaming reader)."""

    path: str
    header: list[str]
    header_line: int
    columns: list[list[str]]
    lines: np.ndarray  # file line number of each data row


def read_table(path: str) -> Table:
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
    with open_text(path) as f:
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
    header = [unguard_formula(h).strip() for h in records[0]]
    while header and not header[-1]:  # trailing separators
        header.pop()
    check_separator(path, header, starts[0])
    width = len(header)
    for j, name in enumerate(header):
        if not name:
            raise InputError(f"column {j + 1} has no name", file=path, row=starts[0])
    body = records[1:]
    if not body:
        raise InputError("no data rows", file=path, row=starts[0])
    for rec, line in zip(body, starts[1:]):
        if any(c.strip() for c in rec[width:]):
            raise InputError(f"{len(rec)} fields but the header has {width}", file=path, row=line)
        rec[width:] = [""] * (width - len(rec))  # pad short rows, cut empty extra fields
    columns = [list(col) for col in zip(*body)]
    return Table(path, header, starts[0], columns, np.asarray(starts[1:], dtype=int))


@dataclass(frozen=True)
class Field:
    """A quantity column of a schema: ``<name>_<unit>``."""

    name: str  # column prefix, e.g. "plate_radius"
    kind: str  # LENGTH or PRESSURE
    group: str  # alternatives share a group, e.g. "size"


@dataclass(frozen=True)
class Schema:
    """The columns of a file type: its id column and quantity fields (one of each group required)."""

    id_column: str
    fields: tuple[Field, ...]
    extra: tuple[str, ...] = ()  # other reserved plain columns (e.g. "cone")


CI_SCHEMA = Schema(
    "profile", (Field("depth", LENGTH, "depth"), Field("ci", PRESSURE, "ci")), ("cone",)
)
PLATE_SCHEMA = Schema(
    "test",
    (
        Field("plate_radius", LENGTH, "size"),
        Field("plate_diameter", LENGTH, "size"),
        Field("plate_width", LENGTH, "size"),
        Field("sinkage", LENGTH, "sinkage"),
        Field("pressure", PRESSURE, "pressure"),
    ),
)
SHEAR_SCHEMA = Schema(
    "test",
    (
        Field("normal_pressure", PRESSURE, "normal_pressure"),
        Field("shear_displacement", LENGTH, "displacement"),
        Field("shear_stress", PRESSURE, "stress"),
    ),
)


@dataclass
class Column:
    """A column of a table: position, header name, its field and the factor to SI."""

    index: int
    name: str  # as written in the header
    field: Field | None = None
    factor: float = 1.0  # to SI


@dataclass
class Layout:
    """Where a schema's columns are in a table."""

    groups: dict[str, Column]
    id_col: Column | None
    extra: dict[str, Column]
    metadata: list[Column]


def match_field(lower: str, schema: Schema) -> tuple[Field, str | None] | None:
    """The field a lower-case column name belongs to and its unit suffix."""
    for fld in schema.fields:
        if lower == fld.name:
            return fld, None
        if lower.startswith(fld.name + "_"):
            return fld, lower[len(fld.name) + 1 :]
    return None


def spelled(fld: Field) -> str:
    """A field's column name with its unit choices, as ``depth_<m|cm|mm|in>``."""
    return f"{fld.name}_<{'|'.join(UNIT_TABLES[fld.kind])}>"


def column_layout(
    path: str, header: list[str], row: int | None, schema: Schema, units: str | None = None
) -> Layout:
    """Classify a header (the file's line ``row``); raise InputError for header problems."""
    seen: dict[str, str] = {}
    groups: dict[str, Column] = {}
    id_col: Column | None = None
    extra: dict[str, Column] = {}
    metadata: list[Column] = []

    def fail(why: str, column: str) -> InputError:
        return InputError(why, file=path, row=row, column=column)

    for j, name in enumerate(header):
        lower = name.lower()
        if lower in seen:
            raise fail(f"duplicate column name ({seen[lower]} is already a column)", name)
        seen[lower] = name
        if lower == schema.id_column:
            id_col = Column(j, name)
            continue
        if lower in schema.extra:
            extra[lower] = Column(j, name)
            continue
        match = match_field(lower, schema)
        if match is None:
            metadata.append(Column(j, name))
            continue
        fld, unit = match
        if unit is None:
            if units is None:
                raise fail(f"no unit in the column name: write {spelled(fld)}", name)
            sys_unit = u.length_unit(units) if fld.kind == LENGTH else u.pressure_unit(units)
            unit = sys_unit.lower()
        if unit not in UNIT_TABLES[fld.kind]:
            raise fail(f"unknown {fld.kind} unit {unit!r} (use {spelled(fld)})", name)
        if fld.group in groups:
            other = groups[fld.group].name
            raise fail(f"more than one {fld.group} column ({other} is already one)", name)
        groups[fld.group] = Column(j, name, fld, UNIT_TABLES[fld.kind][unit])
    for group in dict.fromkeys(f.group for f in schema.fields):
        if group not in groups:
            names = " or ".join(spelled(f) for f in schema.fields if f.group == group)
            raise fail(f"missing required column {names}", names)
    return Layout(groups, id_col, extra, metadata)


def table_groups(table: Table, id_col: Column | None) -> list[tuple[str, np.ndarray]]:
    """(id, row indices) of each profile or test, in order of first appearance."""
    if id_col is None:
        return [(Path(table.path).stem, np.arange(table.lines.size))]
    index: dict[str, list[int]] = {}
    for i, cell in enumerate(table.columns[id_col.index]):
        index.setdefault(unguard_formula(cell).strip(), []).append(i)
    return [(key, np.asarray(rows, dtype=int)) for key, rows in index.items()]


def check_group(
    table: Table,
    layout: Layout,
    gid: str,
    idx: np.ndarray,
    checks: Sequence[tuple[Column, Numbers]],
    item: str = "profile",
) -> None:
    """Raise the located InputError of a group's empty id or earliest unusable cell
    (row order, then column order)."""

    def fail(why: str, i: int, column: str) -> InputError:
        row = int(table.lines[i])
        return InputError(why, file=table.path, profile=gid, item=item, row=row, column=column)

    if layout.id_col is not None and not gid:
        raise fail(f"empty {item} id", int(idx[0]), layout.id_col.name)
    hits = [(np.flatnonzero(num.bad[idx]), k) for k, (_, num) in enumerate(checks)]
    found = [(int(h[0]), k) for h, k in hits if h.size]
    if found:
        r, k = min(found)
        col, num = checks[k]
        raise fail(num.reasons[int(idx[r])], int(idx[r]), col.name)


def row_metadata(table: Table, layout: Layout, i: int) -> dict[str, Any]:
    """The metadata cells of table row ``i``: floats when they read as numbers, else stripped
    text (without the guard quote of :func:`guard_formula`)."""
    cells = {c.name: table.columns[c.index][i] for c in layout.metadata}
    number = DECIMAL.match, SPECIAL_FLOAT.match
    return {
        k: float(v) if any(m(v) for m in number) else unguard_formula(v).strip()
        for k, v in cells.items()
    }


def collect(items: Sequence[Any], build: Callable[[Any], Any], on_error: str) -> list[Any]:
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


def validated(
    profile: CIProfile,
    locate: Callable[[int | None, str | None], tuple[int | None, str | None, str]],
) -> CIProfile:
    """Run :meth:`CIProfile.validate` and relocate its error in the file: ``locate(index,
    column)`` maps a point and a model column to (file row, file column, text to add)."""
    probe = replace(profile, rows=np.arange(len(profile)))
    try:
        probe.validate()
    except InputError as exc:
        row, column, more = locate(exc.row, exc.column)
        where = dict(file=profile.source, profile=profile.id, row=row, column=column)
        raise InputError(exc.reason + more, **where) from None
    return profile


def push_profile(
    pid: str,
    labels: Sequence[str],
    cells: Sequence[str],
    depth: np.ndarray,
    factor: float,
    cone: Cone,
    depth_ref: str,
    metadata: dict[str, Any],
    source: str,
    line: int,
    notes: list[str],
    stop_format: str = "{}",
) -> CIProfile:
    """One instrument push (a row of an SC900 export or a wide table) as a validated CIProfile.

    ``cells``: the readings as text (``factor`` to kPa), ``labels`` their columns,
    ``depth`` [m]; trailing zeros are dropped and noted (``stop_format`` words the label
    where the push stopped).  Every point has the push's file ``line`` as its row.
    """
    readings = to_numbers(cells)
    if readings.bad.any():
        k = int(np.flatnonzero(readings.bad)[0])
        raise InputError(readings.reasons[k], file=source, profile=pid, row=line, column=labels[k])
    ci = readings.values * factor
    nonzero = np.flatnonzero(ci != 0)
    keep = int(nonzero[-1]) + 1 if nonzero.size else 0
    dropped = ci.size - keep
    if dropped:
        s = "" if dropped == 1 else "s"
        stop = stop_format.format(labels[keep])
        notes.append(f"dropped {dropped} trailing zero reading{s} (push stopped at {stop})")
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

    def locate(k: int | None, column: str | None) -> tuple[int | None, str | None, str]:
        if k is None:  # too few points
            more = f" after dropping {dropped} trailing zero readings" if dropped else ""
            return line, labels[keep] if dropped else labels[0], more
        more = f" (reading {cells[k]!r})"
        if column == "depth" and depth_ref == "tip":
            more = f" (a tip depth; base depth = tip depth - H, H = {cone.height:.4g} m)"
        return line, labels[k], more

    return validated(profile, locate)

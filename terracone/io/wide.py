"""Wide tables of cone index: one row per push, one column per depth (``docs/instruments.md``)."""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from terracone.data import CIProfile, InputError
from terracone.io.tables import (
    DECIMAL,
    OnError,
    PathLike,
    check_options,
    collect,
    push_profile,
    read_lines,
    unguard_formula,
)
from terracone.physics import units as u
from terracone.physics.cone import Cone, get_cone

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
    depths: list[tuple[float, str | None]]  # (value, unit or None) of each depth column
    stated_ci_unit: str | None
    stated_line: int | None

    @property
    def depth_labels(self) -> list[str]:
        return [self.cells[j] for j in self.depth_cols]


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
            cols, depths = [j for j, _ in found], [d for _, d in found]
            return _WideHeader(delim, lineno, cells, cols, depths, stated, stated_line)
        m = _WIDE_UNIT_STATED.search(line)
        if m:
            unit = m.group(1).lower()
            if stated is not None and unit != stated:
                why = f"the file states two cone index units ({stated} on line {stated_line}, {unit} here)"
                raise InputError(why, file=path, row=lineno)
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
    bare = [lab for lab, (_, un) in zip(head.depth_labels, head.depths) if un is None]
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
        why = f"the file states cone index in {stated} but ci_unit (--ci-unit) is {ci_unit.lower()}"
        raise InputError(why, file=path, row=head.stated_line)
    units = [(un or depth_unit.lower()) for _, un in head.depths]  # type: ignore[union-attr]
    depths = np.array([v * u.LENGTH_UNITS[un] for (v, _), un in zip(head.depths, units)])
    bad = np.flatnonzero(np.diff(depths) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        labels = head.depth_labels
        why = f"depth columns are not strictly increasing ({labels[k - 1]!r} before this one)"
        raise InputError(why, file=path, row=head.line, column=labels[k])
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
        :func:`terracone.physics.cone.get_cone`, e.g. ``"penetrologger-1cm2"``).
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
        No header with 3 or more depth columns, units neither stated nor given
        (the message names the option), depths not increasing; per push (raised
        or collected) the problems of ``docs/instruments.md``.

    Notes
    -----
    The push id (:data:`WIDE_ID_COLUMNS`, else ``"{file stem}/{k}"``), the
    coordinates (:data:`WIDE_LAT_COLUMNS`, :data:`WIDE_LON_COLUMNS`, read by
    :func:`parse_coordinate` into ``metadata["lat"]``, ``["lon"]``), empty
    cells, trailing zeros and the metadata: ``docs/instruments.md``.

    Examples
    --------
    >>> read_wide_ci("pushes.csv", depth_unit="cm", ci_unit="mpa")  # doctest: +SKIP
    """
    check_options(on_error, depth_ref)
    source = os.fspath(path)
    default_cone = get_cone(cone)
    text = read_lines(source)
    head = _wide_header(source, text, delimiter)
    depths, ci_u, depth_units = _wide_units(source, head, depth_unit, ci_unit)
    one = _push_reader(source, head, depths, ci_u, depth_units, default_cone, depth_ref)
    return collect(list(enumerate(_wide_rows(source, text, head), 1)), one, on_error)


def _push_reader(
    source: str,
    head: _WideHeader,
    depths: np.ndarray,
    ci_u: str,
    depth_units: list[str],
    default_cone: Cone,
    depth_ref: str,
) -> Callable[[tuple[int, tuple[int, list[str]]]], CIProfile]:
    """What reads a data row of a wide table: its roles of columns found once."""
    factor = u.PRESSURE_UNITS[ci_u]
    common = {"pressure_unit": ci_u, "length_unit": ",".join(depth_units)}
    lower = [c.lower() for c in head.cells]

    def first(names: Sequence[str]) -> int | None:
        for name in names:
            if name in lower and lower.index(name) not in head.depth_cols:
                return lower.index(name)
        return None

    id_j, lat_j, lon_j = first(WIDE_ID_COLUMNS), first(WIDE_LAT_COLUMNS), first(WIDE_LON_COLUMNS)
    cone_j = first(("cone",))
    special = {*head.depth_cols, *(j for j in (id_j, lat_j, lon_j, cone_j) if j is not None)}
    meta_cols = [j for j in range(len(head.cells)) if j not in special]
    comma = head.delimiter in (";", "\t")
    seen: dict[str, int] = {}

    def one(item: tuple[int, tuple[int, list[str]]]) -> CIProfile:
        """The k-th data row (1-based) as a validated profile."""
        k, (line, cells) = item
        pid = (
            unguard_formula(cells[id_j]).strip() if id_j is not None else f"{Path(source).stem}/{k}"
        )

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
            num = _wide_number(cells[j], comma)
            text = unguard_formula(cells[j]).strip()
            metadata[head.cells[j]] = float(num) if DECIMAL.match(num) else text
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
        notes = []
        if a:
            notes.append(f"first reading at {head.depth_labels[a]} (the cells before it are empty)")
        return push_profile(
            pid,
            head.depth_labels[a:b],
            raw[a:b],
            depths[a:b],
            factor,
            push_cone,
            depth_ref,
            {**metadata, **common, "line": line},
            source,
            line,
            notes,
            "depth column {!r}",
        )

    return one


def _wide_rows(source: str, text: list[str], head: _WideHeader) -> list[tuple[int, list[str]]]:
    """(file line, cells) of every data row, padded to the header's width."""
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
    return rows

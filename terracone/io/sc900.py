"""FieldScout SC900 exports: one cone index profile per push (``docs/instruments.md``)."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from terracone.data import CIProfile, InputError
from terracone.io.tables import (
    OnError,
    PathLike,
    cell_problem,
    check_options,
    collect,
    push_profile,
    read_lines,
)
from terracone.physics import units as u
from terracone.physics.cone import CONES

#: Cone sizes of the SC900 export (normalised to lower case) and their cones.
SC900_CONES: dict[str, str] = {"1/2 inch": "asabe-small", "3/4 inch": "asabe-large"}

_SC900_DEPTH = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+))\s*([a-zA-Z]+)\s*$")
_SC900_UNIT = re.compile(r"\bIn\s+(KPa|PSI)\s*$", re.IGNORECASE)
_SC900_PUSH = re.compile(r"^N\s*=\s*(\d+)$", re.IGNORECASE)


@dataclass
class _Export:
    """What the lines of an SC900 export hold, before the pushes are read."""

    header: dict[str, Any]  # logger, serial, datum
    ci_unit: str | None  # "kpa" or "psi" from the unit line
    labels: list[str] | None  # the column line's cells after Longitude,Latitude,Number
    column_line: int
    pushes: list[tuple[int, int, list[str]]]  # (ordinal, file line, fields)


def _export_lines(path: str, text: list[str]) -> _Export:
    """Sort the lines of an export: header, unit line, column line and push lines."""
    ex = _Export({}, None, None, 0, [])
    for lineno, raw in enumerate(text, 1):
        line = raw.strip()
        if not line:
            continue
        if ex.labels is None:
            m = re.match(r"^(Name|Serial\s*#?|Datum)\s*:\s*(.*)$", line, re.IGNORECASE)
            if m:
                key = m.group(1).lower()
                key = "logger" if key == "name" else "serial" if key.startswith("serial") else key
                ex.header[key] = m.group(2).strip()
                continue
            m = _SC900_UNIT.search(line)
            if m:
                ex.ci_unit = m.group(1).lower()
                continue
            if re.match(r"^Longitude\s*,\s*Latitude\s*,\s*Number\s*,", line, re.IGNORECASE):
                ex.labels = [c.strip() for c in line.split(",")[3:]]
                ex.column_line = lineno
            continue  # other header text carries nothing we use
        fields = [c.strip() for c in line.split(",")]
        if len(fields) >= 3 and fields[2].lower() == "logger started":
            continue
        if len(fields) >= 3 and fields[2].upper().startswith("N="):
            ex.pushes.append((len(ex.pushes) + 1, lineno, fields))
            continue
        raise InputError(
            "not a push line (expected 'lon,lat,N= k , readings..., cone size') "
            "nor a 'Logger Started' line",
            file=path,
            row=lineno,
        )
    return ex


def _export_depths(path: str, ex: _Export) -> tuple[list[str], np.ndarray, list[str]]:
    """Depth labels, depths [m] and the depth units used, from the column line."""
    labels = ex.labels
    if labels is None:
        raise InputError(
            "no column line 'Longitude,Latitude,Number,<depths>,Cone Size' (not an SC900 export?)",
            file=path,
        )
    where = dict(file=path, row=ex.column_line)
    if not labels or labels[-1].lower() != "cone size":
        column = labels[-1] if labels else None
        raise InputError("the column line does not end with 'Cone Size'", column=column, **where)
    labels = labels[:-1]
    depths = np.empty(len(labels))
    units: list[str] = []
    for k, label in enumerate(labels):
        m = _SC900_DEPTH.match(label)
        unit = m.group(2).lower() if m else ""
        if m is None or unit not in u.LENGTH_UNITS:
            why = f"not a depth label like '2.5 cm' (units {', '.join(u.LENGTH_UNITS)})"
            raise InputError(why, column=label, **where)
        depths[k] = float(m.group(1)) * u.LENGTH_UNITS[unit]
        units.append(unit)
    return labels, depths, list(dict.fromkeys(units))


def read_sc900(
    path: PathLike,
    *,
    depth_ref: Literal["base", "tip"] = "base",
    units: str | None = None,
    on_error: OnError = "raise",
) -> list[CIProfile | InputError]:
    """Read a FieldScout SC900 export: one profile per push.

    Parameters
    ----------
    path : str or path-like
        The export (text).
    depth_ref : {"base", "tip"}
        As in :func:`terracone.io.read_ci_profiles`.
    units : {"si", "us"} or None
        Unit system of an export without a unit line ("... In KPa").
    on_error : {"raise", "collect"}
        As in :func:`terracone.io.read_ci_profiles`.

    Returns
    -------
    list of CIProfile or InputError
        One item per push, in file order (ids, cones and metadata:
        ``docs/instruments.md``).

    References
    ----------
    Spectrum Technologies, FieldScout SC900 Soil Compaction Meter, product
    manual (the text export).
    """
    check_options(on_error)
    source = os.fspath(path)
    ex = _export_lines(source, read_lines(source))
    labels, depths, depth_units = _export_depths(source, ex)
    ci_unit = ex.ci_unit
    if ci_unit is None:
        if units is None:
            raise InputError(
                "no unit line (e.g. 'Soil Compation In KPa'); state the unit system (units='si' or 'us' in Python, --file-units on the command line)",
                file=source,
            )
        ci_unit = u.pressure_unit(units).lower()
    stem = Path(source).stem
    length_unit = ",".join(depth_units)

    def one(push: tuple[int, int, list[str]]) -> CIProfile:
        """One push line as a validated profile (raises a located InputError)."""
        ordinal, line, f = push
        nd = len(labels)
        m = _SC900_PUSH.match(f[2].replace(" ", ""))
        number = int(m.group(1)) if m else None
        pid = f"{stem}/{ordinal:04d}-N{number if number is not None else '?'}"

        def fail(msg: str, column: str | None) -> InputError:
            return InputError(msg, file=source, profile=pid, row=line, column=column)

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
        metadata: dict[str, Any] = {**ex.header, "push": number, "line": line}
        for k, key in ((0, "longitude"), (1, "latitude")):
            if f[k]:
                if cell_problem(f[k]) is not None:
                    raise fail(f"{key} {f[k]!r} is not a number", key.title())
                metadata[key] = float(f[k])
        metadata["pressure_unit"] = ci_unit
        metadata["length_unit"] = length_unit
        return push_profile(
            pid,
            labels,
            f[3 : 3 + nd],
            depths,
            u.PRESSURE_UNITS[ci_unit],
            push_cone,
            depth_ref,
            metadata,
            source,
            line,
            [],
        )

    return collect(ex.pushes, one, on_error)

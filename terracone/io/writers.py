"""Writers of cone index, plate and shear CSV files (read back by the readers)."""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from terracone.data import CIProfile, PlateTest, ShearTest
from terracone.io.tables import (
    CI_SCHEMA,
    LENGTH,
    PLATE_SCHEMA,
    PRESSURE,
    SHEAR_SCHEMA,
    UNIT_TABLES,
    PathLike,
    Schema,
    guard_formula,
    match_field,
)
from terracone.physics.cone import Cone, get_cone


def _unit(name: str, kind: str) -> tuple[str, float]:
    key = str(name).lower()
    table = UNIT_TABLES[kind]
    if key not in table:
        raise ValueError(f"{kind} unit must be one of {', '.join(table)} (got {name!r})")
    return key, table[key]


def _fmt(value: Any) -> str:
    """A cell: floats with repr (round-trips exactly), None as empty, text guarded
    against formula injection (:func:`~terracone.io.tables.guard_formula`)."""
    if value is None:
        return ""
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, bool | int | np.integer):
        return str(value)
    return guard_formula(value)


def _metadata_columns(items: Sequence[Any], schema: Schema, reserved: Sequence[str]) -> list[str]:
    """Union of the metadata keys of the items, in order of first appearance."""
    keys: dict[str, str] = {}
    for item in items:
        for key in item.metadata:
            name = str(key)
            lower = name.strip().lower()
            if name != name.strip() or not name:
                raise ValueError(f"metadata key {name!r} cannot be a column name")
            if lower in reserved or match_field(lower, schema) is not None:
                raise ValueError(
                    f"metadata key {name!r} would be read back as a data column; rename it"
                )
            if lower in keys and keys[lower] != name:
                raise ValueError(f"metadata keys {keys[lower]!r} and {name!r} differ only in case")
            keys[lower] = name
    return list(keys.values())


def _write_items(
    path: PathLike,
    items: Sequence[Any],
    schema: Schema,
    head: Sequence[str],
    lead: Callable[[Any, float, float], list[str]],
    series: tuple[str, str],
    units: tuple[str, str],
    comment: str | Sequence[str] | None,
) -> None:
    """One row per point of the ``series`` (a length, a pressure) of items with unique ids.

    ``head``: the columns but metadata, ``{lu}``/``{pu}`` the units; ``lead``: the leading cells.
    """
    (lu, lf), (pu, pf) = _unit(units[0], LENGTH), _unit(units[1], PRESSURE)
    seen: set[str] = set()
    for item in items:
        if item.id in seen:
            raise ValueError(
                f"duplicate {schema.id_column} id {item.id!r}: they would merge on reading"
            )
        seen.add(item.id)
    meta = _metadata_columns(items, schema, (schema.id_column, *schema.extra))
    names = [h.format(lu=lu, pu=pu) for h in head]
    with open(os.fspath(path), "w", encoding="utf-8", newline="") as f:
        if comment is not None:
            lines = comment.splitlines() if isinstance(comment, str) else list(comment)
            for line in lines:
                f.write(f"# {line}\n" if line else "#\n")
        plain = csv.writer(f, lineterminator="\n")
        quoted = csv.writer(f, lineterminator="\n", quoting=csv.QUOTE_ALL)
        plain.writerow([*names[:-2], *map(guard_formula, meta), *names[-2:]])
        for item in items:
            fixed = lead(item, lf, pf) + [_fmt(item.metadata.get(k)) for k in meta]
            x, y = (np.asarray(getattr(item, a), dtype=float) / f for a, f in zip(series, (lf, pf)))
            for row in zip(map(repr, x.tolist()), map(repr, y.tolist())):
                # a record starting with '#' would read back as a comment: quote it
                (quoted if fixed[0].lstrip().startswith("#") else plain).writerow([*fixed, *row])


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
    written as ``"<diameter>m:<angle>"``.  Text cells (ids, text metadata)
    that a spreadsheet would run as a formula (``=``, ``+``, ``-``, ``@``, tab,
    carriage return first) get a leading ``'`` (OWASP), which the readers drop
    again: the file still reads back exactly.
    """
    _write_items(
        path,
        profiles,
        CI_SCHEMA,
        ["profile", "cone", "depth_{lu}", "ci_{pu}"],
        lambda p, lf, pf: [guard_formula(p.id), guard_formula(_cone_spec(p.cone))],
        ("depth", "ci"),
        (length_unit, pressure_unit),
        comment,
    )


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
    length_unit, pressure_unit, comment
        As in :func:`write_ci_profiles` (the unit of the plate size and sinkage
        columns, of the pressure column).
    """
    shapes = {t.shape for t in tests}
    if len(shapes) > 1:
        raise ValueError("circular and rectangular plates cannot share a file (one size column)")
    size_col = "plate_width" if shapes == {"rectangular"} else "plate_radius"
    _write_items(
        path,
        tests,
        PLATE_SCHEMA,
        ["test", size_col + "_{lu}", "sinkage_{lu}", "pressure_{pu}"],
        lambda t, lf, pf: [guard_formula(t.id), repr(float(t.b) / lf)],
        ("sinkage", "pressure"),
        (length_unit, pressure_unit),
        comment,
    )


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
    length_unit, pressure_unit, comment
        As in :func:`write_ci_profiles` (the unit of the shear displacement
        column, of the normal pressure and shear stress columns).
    """
    _write_items(
        path,
        tests,
        SHEAR_SCHEMA,
        ["test", "normal_pressure_{pu}", "shear_displacement_{lu}", "shear_stress_{pu}"],
        lambda t, lf, pf: [guard_formula(t.id), repr(float(t.normal_pressure) / pf)],
        ("displacement", "stress"),
        (length_unit, pressure_unit),
        comment,
    )


def json_default(o: Any) -> Any:
    """``default=`` for :func:`json.dumps` of terracone results (numpy, tuples, paths)."""
    if isinstance(o, np.floating | np.integer | np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    if isinstance(o, os.PathLike):
        return os.fspath(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")

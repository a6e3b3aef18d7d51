"""Cone index profiles from a file: format detection, long CSV files, profile sets.

pyarrow and pandas (:mod:`terracone.io.stream`) are imported on first use.
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from terracone.data import CIProfile, InputError, ProfileSet
from terracone.io.sc900 import read_sc900
from terracone.io.tables import (
    CI_SCHEMA,
    OnError,
    PathLike,
    check_group,
    check_options,
    collect,
    column_layout,
    is_parquet,
    match_field,
    read_table,
    row_metadata,
    table_groups,
    to_numbers,
    validated,
)
from terracone.io.wide import read_wide_ci, wide_depth_header
from terracone.physics.cone import Cone, get_cone


def detect_format(path: PathLike) -> Literal["csv", "sc900", "wide"]:
    """The format of a cone index file: ``"sc900"``, ``"wide"`` or ``"csv"``.

    An SC900 export is recognised by its first lines; a wide table when its
    first line of 3 or more cells (after blank, comment and short preamble
    lines of at most 2 cells) has 3 or more depth headers
    (:func:`wide_depth_header`) and no ``depth_<unit>`` or ``ci_<unit>``
    column; anything else is read as a long CSV file, whose reader reports
    what is wrong.
    """
    try:
        with open(os.fspath(path), encoding="utf-8-sig", errors="replace") as f:
            head = [f.readline() for _ in range(50)]
    except OSError:
        return "csv"  # the CSV reader reports the problem
    lines = [ln.strip() for ln in head[:12] if ln.strip()]
    column_line = re.compile(r"^Longitude\s*,\s*Latitude\s*,\s*Number\s*,", re.I)
    if (lines and re.match(r"^Name\s*:", lines[0], re.I)) or any(map(column_line.match, lines)):
        return "sc900"
    for raw in head:
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        delim = "\t" if "\t" in line else ";" if ";" in line else ","
        cells = [c.strip().lower() for c in next(csv.reader([raw], delimiter=delim))]
        if any(match_field(c, CI_SCHEMA) and wide_depth_header(c) is None for c in cells):
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
    SC900 exports and wide tables (ids, cones, trailing zeros, metadata):
    ``docs/instruments.md``.  The metadata of neither reads back as a data
    column, so :func:`write_ci_profiles` can write the profiles to CSV.

    Examples
    --------
    >>> profiles = read_ci_profiles("site.csv", cone="asabe-small")  # doctest: +SKIP
    """
    check_options(on_error, depth_ref, units)
    default_cone = get_cone(cone)
    source = os.fspath(path)
    if format is None:
        format = detect_format(source)
    if format == "csv":
        return _read_ci_csv(source, default_cone, depth_ref, units, on_error)
    if format == "sc900":
        return read_sc900(source, depth_ref=depth_ref, units=units, on_error=on_error)
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
    table = read_table(path)
    layout = column_layout(path, table.header, table.header_line, CI_SCHEMA, units)
    dcol, ccol = layout.groups["depth"], layout.groups["ci"]
    depth = to_numbers(table.columns[dcol.index])
    ci = to_numbers(table.columns[ccol.index])
    cone_col = layout.extra.get("cone")
    lines = table.lines

    def build(group: tuple[str, np.ndarray]) -> CIProfile:
        pid, idx = group

        def fail(msg: str, i: int, column: str | None) -> InputError:
            return InputError(msg, file=path, profile=pid, row=int(lines[i]), column=column)

        check_group(table, layout, pid, idx, [(dcol, depth), (ccol, ci)])
        prof_cone = default_cone
        if cone_col is not None:
            cells = table.columns[cone_col.index]
            name = cells[int(idx[0])].strip()
            try:
                prof_cone = get_cone(name)
            except ValueError as exc:
                why = "empty cell" if not name else str(exc)
                raise fail(why, int(idx[0]), cone_col.name) from None
            other = next((int(i) for i in idx[1:] if cells[int(i)].strip() != name), None)
            if other is not None:
                why = f"{cells[other].strip()!r} here, {name!r} on line {int(lines[idx[0]])}"
                raise fail(f"cone changes within the profile ({why})", other, cone_col.name)
        z = depth.values[idx] * dcol.factor
        if depth_ref == "tip":
            z = z - prof_cone.height
        profile = CIProfile(
            id=pid,
            depth=z,
            ci=ci.values[idx] * ccol.factor,
            cone=prof_cone,
            metadata=row_metadata(table, layout, int(idx[0])),
            source=path,
            rows=lines[idx].copy(),
        )

        def locate(k: int | None, column: str | None) -> tuple[int | None, str | None, str]:
            col = dcol if column == "depth" else ccol
            if k is None:  # too few points
                first, last = int(lines[idx[0]]), int(lines[idx[-1]])
                span = f"lines {first}-{last}" if idx.size > 1 else f"line {first}"
                return int(lines[idx[0]]), col.name, f" (the profile is on {span})"
            i = int(idx[k])
            more = f" (cell {table.columns[col.index][i].strip()!r}"
            if column == "depth" and depth_ref == "tip":
                more += f", a tip depth; base depth = tip depth - H, H = {prof_cone.height:.4g} m"
            if column == "depth" and k > 0:
                prev = int(idx[k - 1])
                more += f"; previous depth {table.columns[col.index][prev].strip()!r} on line {int(lines[prev])}"
            return int(lines[i]), col.name, more + ")"

        return validated(profile, locate)

    return collect(table_groups(table, layout.id_col), build, on_error)


def read_profile_set(
    path: PathLike,
    *,
    cone: str | Cone = "asabe-large",
    depth_ref: Literal["base", "tip"] = "base",
    units: str | None = None,
    on_error: OnError = "collect",
    format: Literal["csv", "sc900", "wide", "parquet"] | None = None,
    depth_unit: str | None = None,
    ci_unit: str | None = None,
) -> ProfileSet:
    """Read every cone index profile of a file into one :class:`~terracone.data.ProfileSet`.

    Parameters
    ----------
    path : str or path-like
        A long CSV file, a FieldScout SC900 export, a wide table or a Parquet
        file (columns as in a long CSV file).
    cone, depth_ref, units, depth_unit, ci_unit
        As in :func:`read_ci_profiles`.
    on_error : {"collect", "raise"}
        ``"collect"`` (default): a profile the reader refuses goes to the
        set's ``errors`` as a located :class:`~terracone.data.InputError`;
        ``"raise"``: the first one raises.  Problems with the file itself
        raise in both modes.
    format : {"csv", "sc900", "wide", "parquet"} or None
        None detects it: ``"parquet"`` by the file's magic number or a
        ``.parquet`` / ``.pq`` name, else :func:`detect_format`.

    Returns
    -------
    ProfileSet
        Profiles in file order (depths in m of the cone base, CI in kPa),
        ``rows`` the file line of every point (the record for Parquet),
        ``metadata`` one row per profile, ``errors`` the refused profiles.

    Notes
    -----
    Text formats go through :func:`read_ci_profiles`, Parquet through
    :func:`iter_profile_sets` in one chunk (``docs/instruments.md``).

    References
    ----------
    Huang, Wong, Preston-Thomas, Jayakumar: the cone index profile, eq. (2-3).

    Examples
    --------
    >>> profiles = read_profile_set("site.csv", cone="asabe-small")  # doctest: +SKIP
    >>> profiles[0].depth, profiles.errors  # doctest: +SKIP
    """
    source = os.fspath(path)
    options: dict[str, Any] = dict(cone=cone, depth_ref=depth_ref, units=units, on_error=on_error)
    if format is None:
        format = "parquet" if is_parquet(source) else detect_format(source)
    if format == "parquet":
        return ProfileSet.concat(list(iter_profile_sets([source], chunk_size=None, **options)))
    wide = dict(depth_unit=depth_unit, ci_unit=ci_unit)
    return gather_profiles(read_ci_profiles(source, format=format, **wide, **options))


def gather_profiles(items: Sequence[CIProfile | InputError]) -> ProfileSet:
    """:meth:`ProfileSet.from_profiles`, with metadata columns mixing numbers and text as text."""
    import pyarrow as pa

    try:
        return ProfileSet.from_profiles(items)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        pass
    profs = [p for p in items if isinstance(p, CIProfile)]
    bare = [p if isinstance(p, InputError) else replace(p, metadata={}) for p in items]
    keys = list(dict.fromkeys(k for p in profs for k in p.metadata))
    columns = {}
    for k in keys:
        vals = [p.metadata.get(k) for p in profs]
        try:
            columns[k] = pa.array(vals)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            columns[k] = pa.array([None if v is None else str(v) for v in vals], pa.string())
    return replace(ProfileSet.from_profiles(bare), metadata=pa.table(columns))


def iter_profile_sets(
    paths: PathLike | Sequence[PathLike],
    *,
    chunk_size: int | None = 10_000,
    cone: str | Cone = "asabe-large",
    depth_ref: Literal["base", "tip"] = "base",
    units: str | None = None,
    on_error: OnError = "collect",
    format: Literal["csv", "sc900", "wide", "parquet"] | None = None,
    depth_unit: str | None = None,
    ci_unit: str | None = None,
) -> Iterator[ProfileSet]:
    """Stream cone index profiles as :class:`~terracone.data.ProfileSet` chunks.

    Parameters
    ----------
    paths : path, directory or sequence of paths
        Long CSV (``.csv``, ``.csv.gz``) and Parquet (``.parquet``, ``.pq``)
        files, streamed block by block; a directory stands for its CSV and
        Parquet files in name order (names starting with ``.`` or ``_`` are
        ignored).  An SC900 export or a wide table (:func:`detect_format`) is
        read whole (instrument files are small) and cut into chunks.
    chunk_size : int or None
        Profiles per chunk, counting the refused ones (a chunk holds
        ``len(chunk) + len(chunk.errors) == chunk_size`` profiles, the last
        one fewer); chunks do not span a file of another format.  None: one
        chunk per group of files.
    cone, depth_ref, units, format, depth_unit, ci_unit
        As in :func:`terracone.io.read_ci_profiles` (``format`` for a single file).
    on_error : {"collect", "raise"}
        ``"collect"``: refused profiles go to each chunk's ``errors``, each a
        located :class:`~terracone.data.InputError`; ``"raise"``: the first
        one raises.

    Yields
    ------
    ProfileSet
        Profiles in input order: depths [m] of the cone base, CI [kPa],
        ``rows`` the file line of every point (1-based record for Parquet),
        ``metadata`` (one type per column, fixed by a first pass over the input).

    Raises
    ------
    InputError
        A file-level problem (missing file or column, unknown unit, bad CSV
        structure), found by the first pass before any chunk is yielded.

    Notes
    -----
    The rows of a profile must be contiguous (a profile id seen again later
    is a second profile); the errors: ``docs/instruments.md``.

    References
    ----------
    Huang, Wong, Preston-Thomas, Jayakumar: the cone index profile, eq. (2-3).

    Examples
    --------
    >>> for chunk in iter_profile_sets("big.csv", chunk_size=5000):  # doctest: +SKIP
    ...     print(len(chunk), len(chunk.errors))
    """
    check_options(on_error, depth_ref, units)
    if chunk_size is not None and chunk_size < 1:
        raise ValueError(f"chunk_size must be >= 1 (got {chunk_size})")
    from terracone.io.scan import scan_inputs  # pyarrow and pandas: on first use
    from terracone.io.stream import ConeCache, chunk_set, iter_chunks

    default = get_cone(cone)
    options: dict[str, Any] = dict(depth_ref=depth_ref, units=units)
    wide = dict(depth_unit=depth_unit, ci_unit=ci_unit)
    for group, kind in _file_groups(paths, format):
        if kind in ("sc900", "wide"):
            one = read_profile_set(group[0][0], cone=default, format=kind, **options, **wide)
            sets: Iterable[ProfileSet] = _cut(one, chunk_size)
        else:
            plan = scan_inputs(group, units=units)
            size = chunk_size or max(plan.profiles, 1)
            chunks = iter_chunks(plan, size, ConeCache(default), set())
            sets = (chunk_set(c, plan, depth_ref) for _, c, _ in chunks if c is not None)
        for s in sets:
            if on_error == "raise" and s.errors:
                raise s.errors[0]
            yield s


def _file_groups(
    paths: PathLike | Sequence[PathLike], format: str | None
) -> Iterator[tuple[list[tuple[Path, str]], str]]:
    """Runs of input files read together: (files, "stream") or ([file], instrument format)."""
    from terracone.io.scan import input_files

    items = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    run: list[tuple[Path, str]] = []
    for item in items:
        for path, kind in input_files(item):
            fmt = format
            if fmt is None and kind == "csv":
                fmt = detect_format(path)
            if fmt in ("sc900", "wide"):
                if run:
                    yield run, "stream"
                    run = []
                yield [(path, kind)], fmt
            else:
                run.append((path, "parquet" if fmt == "parquet" else kind))
    if run:
        yield run, "stream"


def _cut(profiles: ProfileSet, chunk_size: int | None) -> Iterator[ProfileSet]:
    """A whole-file set cut into chunks of ``chunk_size`` profiles (errors counted, in place)."""
    errors = profiles.errors
    # place each error by its row: refused profiles count where they stood in the file
    order = sorted(
        [
            (int(profiles.rows[profiles.offsets[i]]) if profiles.counts[i] else -1, 0, i)
            for i in range(len(profiles))
        ]
        + [(e.row if e.row is not None else -1, 1, k) for k, e in enumerate(errors)]
    )
    size = chunk_size or max(len(order), 1)
    for a in range(0, max(len(order), 1), size):
        part = order[a : a + size]
        s = profiles.take([i for _, kind, i in part if kind == 0])
        s.errors = [errors[k] for _, kind, k in part if kind == 1]
        yield s


def instrument_to_parquet(path: Path, out: Path, cone: Cone, **reader: Any) -> Path:
    """An SC900 export or wide table as terracone Parquet in OUT_DIR/_input (kept for --resume).

    ``reader`` are keywords of :func:`terracone.io.read_ci_profiles` (format
    "sc900" by default; "wide" with its depth_unit and ci_unit).
    """
    import pyarrow as pa  # on first use: importing terracone.io stays light
    import pyarrow.parquet as pq

    target = out / "_input" / (path.stem + ".parquet")
    if target.exists():
        return target
    reader.setdefault("format", "sc900")
    items = read_ci_profiles(path, on_error="collect", cone=cone, **reader)
    target.parent.mkdir(parents=True, exist_ok=True)  # after the file-level checks
    fixed = ("profile", "cone", "reader_error", "reader_error_row", "reader_error_column")
    rows: dict[str, list] = {k: [] for k in (*fixed, "depth_m", "ci_kpa")}
    keys = dict.fromkeys(k for it in items if isinstance(it, CIProfile) for k in it.metadata)
    meta_keys = [k for k in keys if k not in rows]
    rows.update((k, []) for k in meta_keys)
    for it in items:
        if isinstance(it, CIProfile):
            n, depth, ci = len(it), list(it.depth), list(it.ci)
            lead = [it.id, it.cone.name, None, None, None]
            meta = [None if (v := it.metadata.get(k)) is None else str(v) for k in meta_keys]
        else:  # rejected by the reader: one row without a reading, the reason alongside
            n, depth, ci = 1, [float("nan")], [float("nan")]
            lead = [str(it.profile), cone.name, str(it), it.row, it.column]
            meta = [None] * len(meta_keys)
        for k, v in zip((*fixed, *meta_keys), lead + meta):
            rows[k] += [v] * n
        rows["depth_m"] += depth
        rows["ci_kpa"] += ci
    tmp = target.with_name("." + target.name + ".tmp")
    pq.write_table(pa.table(rows), tmp)
    os.replace(tmp, target)
    return target

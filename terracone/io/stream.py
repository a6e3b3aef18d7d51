"""Streaming profile sets: long CSV and Parquet inputs larger than memory.

After the first pass (:func:`terracone.io.scan.scan_inputs`), :func:`iter_chunks`
reads the files block by block through pyarrow into :class:`Chunk` objects, whose
fittable profiles :func:`chunk_set` gives as a ProfileSet (eq. (2-3)); a profile's
rows must be contiguous and are never split (``docs/instruments.md``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from terracone.data import InputError, ProfileSet, SourceFile
from terracone.io import scan as io_scan
from terracone.io.scan import (
    CsvLines,
    FileInfo,
    ScanPlan,
    arrow_text,
    block_cells,
    csv_blocks,
    csv_text,
    parquet_file,
    plain_type,
    profile_starts,
    strip_text,
    text_starts,
)
from terracone.io.tables import to_numbers, unguard_formula
from terracone.physics.cone import Cone, get_cone

__all__ = ["iter_chunks", "chunk_set", "Chunk", "ConeCache"]


# ---------------------------------------------------------------------------
# reading rows
# ---------------------------------------------------------------------------


@dataclass
class Rows:
    """A block of input rows of one file, numbers already in SI."""

    file: int
    ids: np.ndarray | pa.Array  # per row: object (str), or CSV's raw text cells in Arrow
    depth: np.ndarray
    ci: np.ndarray
    depth_why: np.ndarray | None  # object: why a cell is unusable (None where fine)
    ci_why: np.ndarray | None
    cone: np.ndarray | None  # object (CSV: raw cells), None without a cone column
    lines: np.ndarray  # int64: file line (CSV) or 1-based data row (Parquet)
    meta: dict[str, Any]  # input name -> ndarray (CSV text) or pa.Array (Parquet)

    def __len__(self) -> int:
        return len(self.ids)

    def slice(self, a: int, b: int) -> Rows:
        def cut(x: Any) -> Any:
            if x is None:
                return None
            if isinstance(x, pa.Array):
                return x.slice(a, b - a)
            return x[a:b]

        return Rows(
            self.file,
            cut(self.ids),
            self.depth[a:b],
            self.ci[a:b],
            cut(self.depth_why),
            cut(self.ci_why),
            cut(self.cone),
            self.lines[a:b],
            {k: cut(v) for k, v in self.meta.items()},
        )

    @staticmethod
    def concat(parts: list[Rows]) -> Rows:
        if len(parts) == 1:
            return parts[0]

        def why(name: str) -> np.ndarray | None:
            arrs = [getattr(p, name) for p in parts]
            if all(a is None for a in arrs):
                return None
            return np.concatenate(
                [
                    np.full(len(p), None, dtype=object) if a is None else a
                    for p, a in zip(parts, arrs)
                ]
            )

        def join(xs: list[Any]) -> Any:
            if isinstance(xs[0], pa.Array):
                return pa.concat_arrays(xs)
            return np.concatenate(xs)

        first = parts[0]
        return Rows(
            first.file,
            join([p.ids for p in parts]),
            np.concatenate([p.depth for p in parts]),
            np.concatenate([p.ci for p in parts]),
            why("depth_why"),
            why("ci_why"),
            None if first.cone is None else np.concatenate([p.cone for p in parts]),
            np.concatenate([p.lines for p in parts]),
            {k: join([p.meta[k] for p in parts]) for k in first.meta},
        )


def text_numbers(cells: np.ndarray, factor: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Text cells as numbers [SI] and why a cell is unusable (None when every cell is fine)."""
    num = to_numbers(cells)
    why = None
    if num.bad.any():
        why = np.full(len(cells), None, dtype=object)
        for i, reason in num.reasons.items():
            why[i] = reason
    return num.values * factor, why


#: :data:`terracone.io.tables.DECIMAL` for pyarrow (RE2 accepts no more than Python's re)
_DECIMAL_RE2 = r"^\s*[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\s*$"


def csv_numbers(cells: pa.Array, factor: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Text cells of a CSV column as numbers [SI] and why a cell is unusable (or None).

    Converts like :func:`terracone.io.tables.to_numbers`: pyarrow casts the
    cells that are plain decimal numbers (a correctly rounded parse, as
    Python's float), all at once; only the others (a bad cell, or a number
    Arrow does not cast) go cell by cell through :func:`to_numbers`, so a
    block with a few bad cells costs hardly more than a clean one.
    """
    plain = pc.match_substring_regex(cells, _DECIMAL_RE2)
    if pc.all(plain).as_py() is not False:
        try:
            vals = pc.cast(cells, pa.float64()).to_numpy(zero_copy_only=False)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            pass  # blanks around a number: to_numbers takes them
        else:
            return vals * factor, None
        return text_numbers(cells.to_numpy(zero_copy_only=False), factor)
    ok = plain.to_numpy(zero_copy_only=False)
    vals = np.empty(len(cells))
    try:
        vals[ok] = pc.cast(pc.filter(cells, plain), pa.float64()).to_numpy(zero_copy_only=False)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return text_numbers(cells.to_numpy(zero_copy_only=False), factor)
    rest = np.flatnonzero(~ok)
    num = to_numbers(pc.take(cells, pa.array(rest)).to_numpy(zero_copy_only=False))
    vals[rest] = num.values
    why = None
    if num.bad.any():
        why = np.full(len(cells), None, dtype=object)
        for i, reason in num.reasons.items():
            why[rest[i]] = reason
    return vals * factor, why


def arrow_numbers(arr: pa.Array, factor: float) -> tuple[np.ndarray, np.ndarray | None]:
    """A Parquet column as numbers [SI] and why a cell is unusable (None when every cell is fine)."""
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    t = plain_type(arr.type)
    if t is not None and pa.types.is_string(t):
        cells = np.array(["" if c is None else c for c in arr.to_pylist()], dtype=object)
        return text_numbers(cells, factor)
    if t is None:
        vals = np.full(len(arr), np.nan)
        nulls = np.ones(len(arr), dtype=bool)
    else:
        vals = pc.cast(arr, pa.float64()).to_numpy(zero_copy_only=False).astype(float)
        nulls = arr.is_null().to_numpy(zero_copy_only=False)
    bad = nulls | ~np.isfinite(vals)
    why = None
    if bad.any():
        why = np.full(len(arr), None, dtype=object)
        for i in np.flatnonzero(bad):
            why[i] = "empty cell" if nulls[i] else f"not a finite number: {str(vals[i])!r}"
    return vals * factor, why


def read_file(k: int, info: FileInfo) -> Iterator[Rows]:
    """Blocks of rows of one input file."""
    if info.kind == "csv":
        with CsvLines(info.path) as stream:
            header = stream.header()
            if len(header) != info.width or stream.header_fields != info.fields:
                raise InputError("the header changed since the scan", file=info.path)
            col = info.col_index
            for block, row0 in csv_blocks(stream, info.width, info.fields):
                n = block.num_rows
                if info.id_col is None:
                    ids = np.full(n, info.stem, dtype=object)
                else:
                    ids = block.column(f"c{col[info.id_col]}")  # raw: stripped per profile
                depth, dwhy = csv_numbers(block.column(col[info.depth_col]), info.depth_factor)
                ci, cwhy = csv_numbers(block.column(col[info.ci_col]), info.ci_factor)
                cone = None if info.cone_col is None else block_cells(block, col[info.cone_col])
                meta = {m: block.column(col[m]) for m in info.meta_cols}  # text, taken per profile
                yield Rows(k, ids, depth, ci, dwhy, cwhy, cone, stream.lines(row0, n), meta)
    else:
        pf = parquet_file(info.path)
        row0 = 0
        if info.id_col is None and pf.metadata.num_rows == 0:
            return
        for batch in pf.iter_batches(batch_size=io_scan.PARQUET_BLOCK_ROWS):
            n = batch.num_rows
            if n == 0:
                continue
            if info.id_col is None:
                ids = np.full(n, info.stem, dtype=object)
            else:
                ids = arrow_text(batch.column(info.id_col)).to_numpy(zero_copy_only=False)
                ids = ids.astype(object)
            depth, dwhy = arrow_numbers(batch.column(info.depth_col), info.depth_factor)
            ci, cwhy = arrow_numbers(batch.column(info.ci_col), info.ci_factor)
            cone = None
            if info.cone_col is not None:
                cone = arrow_text(batch.column(info.cone_col)).to_numpy(zero_copy_only=False)
                cone = cone.astype(object)
            meta = {m: batch.column(m) for m in info.meta_cols}
            lines = np.arange(row0 + 1, row0 + 1 + n, dtype=np.int64)
            yield Rows(k, ids, depth, ci, dwhy, cwhy, cone, lines, meta)
            row0 += n


def _cells_at(ids: np.ndarray | pa.Array, at: np.ndarray) -> np.ndarray:
    """The id cells at rows ``at`` as an object array of str."""
    if isinstance(ids, pa.Array):
        return ids.take(pa.array(at, pa.int64())).to_numpy(zero_copy_only=False).astype(object)
    return ids[at]


def _any_other(ids: np.ndarray | pa.Array, tail_ids: np.ndarray | pa.Array) -> bool:
    """Whether any id cell differs from the first of ``tail_ids`` (raw cells)."""
    first = _cells_at(tail_ids, np.zeros(1, dtype=np.int64))[0]
    if isinstance(ids, pa.Array):
        return bool(pc.any(pc.not_equal(ids, pa.scalar(first, ids.type))).as_py())
    return bool(np.any(ids != first))


def profile_blocks(plan: ScanPlan) -> Iterator[tuple[Rows, np.ndarray]]:
    """(rows, profile starts) holding complete profiles only, in input order.

    The last profile of a block may continue in the next block: its rows are
    carried over, so a profile is never split.  A file ends all its profiles.
    """
    for k, info in enumerate(plan.files):
        tail: list[Rows] = []
        for rows in read_file(k, info):
            if tail:
                if not _any_other(rows.ids, tail[0].ids):  # all rows continue the tail
                    tail.append(rows)
                    continue
                rows = Rows.concat([*tail, rows])
                tail = []
            st = (
                text_starts(rows.ids)
                if isinstance(rows.ids, pa.Array)
                else profile_starts(rows.ids)
            )
            last = int(st[-1])
            if last > 0:
                yield rows.slice(0, last), st[:-1]
            tail = [rows.slice(last, len(rows))]
        if tail:
            rows = Rows.concat(tail)
            yield rows, np.zeros(1, dtype=np.int64)


# ---------------------------------------------------------------------------
# chunks: client side
# ---------------------------------------------------------------------------


@dataclass
class Chunk:
    """Everything about one chunk that the client keeps while it is fitted."""

    index: int
    ids: np.ndarray  # object (P,)
    counts: np.ndarray
    first_row: np.ndarray
    source: np.ndarray  # object (P,)
    cone: np.ndarray  # object (P,)
    error: np.ndarray  # object (P,) message or None (problems found while reading)
    error_row: np.ndarray  # int64, -1 = none
    error_column: np.ndarray  # object
    fit: np.ndarray  # bool (P,): sent to the workers
    meta: dict[str, pa.Array]
    task: ProfileSet | None  # the profiles to fit (no metadata), None when there are none
    problems: np.ndarray | None = None  # object (P,): the located InputError, or None


class ConeCache:
    """Cones by the name written in a ``cone`` column (or why the name is not a cone), looked up once."""

    def __init__(self, default: Cone) -> None:
        self.default = default
        self._by_name: dict[str, Cone | str] = {}

    def get(self, name: str) -> Cone | str:
        """The cone, or why the name is not one."""
        hit = self._by_name.get(name)
        if hit is None:
            if not name:
                hit = "empty cell"
            else:
                try:
                    hit = get_cone(name)
                except ValueError as exc:
                    hit = str(exc)
            self._by_name[name] = hit
        return hit


#: :func:`~terracone.io.tables.unguard_formula` for Arrow (RE2): the guard quote, dropped.
_GUARD_RE2 = r"^'('*[=+\-@\t\r])"


def _meta_array(values: Any, t: pa.DataType, from_csv: bool) -> pa.Array:
    """Per-profile metadata values as an Arrow array of the output type (CSV: text cells)."""
    if from_csv and isinstance(values, pa.Array):  # without guard_formula's quote, stripped
        text = pc.utf8_trim_whitespace(pc.replace_substring_regex(values, _GUARD_RE2, r"\1"))
        if not (pa.types.is_floating(t) or pa.types.is_integer(t)):
            return text.cast(t)
        try:  # blank cells are missing values
            nums = pc.cast(
                pc.if_else(pc.equal(text, ""), pa.scalar(None, pa.string()), text), pa.float64()
            )
            return nums.cast(t)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            values = text.to_pylist()  # what Arrow does not cast (e.g. "Infinity"): as Python
    if from_csv:
        text = [unguard_formula(str(v)).strip() for v in values]
        if pa.types.is_floating(t) or pa.types.is_integer(t):
            nums = [None if not v else float(v) for v in text]
            return pa.array(nums, type=pa.float64()).cast(t)
        return pa.array(text, type=t)
    arr = values
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    if arr.type != t:
        arr = pc.cast(arr, t) if plain_type(arr.type) is not None else pa.nulls(len(arr), t)
    return arr


@dataclass
class Piece:
    """Complete profiles of one file inside a chunk: per-profile facts and the rows they came from."""

    n: int
    ids: np.ndarray
    counts: np.ndarray
    first_row: np.ndarray
    source: str
    cone_name: np.ndarray
    cone_obj: list[Cone | None]
    error: np.ndarray
    error_row: np.ndarray
    error_column: np.ndarray
    fit: np.ndarray
    rows: Rows
    starts: np.ndarray
    meta: dict[str, pa.Array]
    problems: np.ndarray  # object (P,): the located InputError of a profile, or None


def _reader_errors(
    rows: Rows,
    starts: np.ndarray,
    error: np.ndarray,
    error_row: np.ndarray,
    error_column: np.ndarray,
    flagged: np.ndarray,
) -> None:
    """Errors kept by :func:`instrument_to_parquet` (with the file's row and column)."""

    def cells(name: str) -> list[Any]:
        col = rows.meta.get(name)
        if col is None:
            return [None] * int(starts.size)
        vals = col[starts] if isinstance(col, np.ndarray) else col.take(pa.array(starts))
        return list(vals) if isinstance(vals, np.ndarray) else vals.to_pylist()

    for i, (why, row, column) in enumerate(
        zip(cells("reader_error"), cells("reader_error_row"), cells("reader_error_column"))
    ):
        if why is None or (isinstance(why, str) and not why):
            continue
        error[i] = str(why)
        error_row[i] = -1 if row in (None, "") else int(float(row))
        error_column[i] = None if column in (None, "") else str(column)
        flagged[i] = True


def _located(message: str, path: str, pid: str, row: int) -> InputError:
    """An InputError whose message is already located (an instrument reader's)."""
    exc = InputError(message)
    exc.file, exc.profile, exc.row = path, pid or None, None if row < 0 else int(row)
    return exc


def make_piece(rows: Rows, starts: np.ndarray, plan: ScanPlan, cones: ConeCache) -> Piece:
    """Per-profile view of complete profiles of one file; problems found while reading."""
    info = plan.files[rows.file]
    n = len(rows)
    P = int(starts.size)
    ends = np.append(starts[1:], n)
    counts = ends - starts
    raw_ids = _cells_at(rows.ids, starts)
    ids = csv_text(raw_ids) if isinstance(rows.ids, pa.Array) else strip_text(raw_ids)
    first = rows.lines[starts]
    flagged = np.zeros(P, dtype=bool)
    if info.id_col is not None:
        flagged |= ids == ""
    bad_row = np.zeros(n, dtype=bool)
    if rows.depth_why is not None:
        bad_row |= np.not_equal(rows.depth_why, None)
    if rows.ci_why is not None:
        bad_row |= np.not_equal(rows.ci_why, None)
    if bad_row.any():
        flagged |= np.logical_or.reduceat(bad_row, starts)
    if rows.cone is None:
        cone_name = np.full(P, cones.default.name, dtype=object)
        cone_obj: list[Cone | str] = [cones.default] * P
    else:
        raw_first = rows.cone[starts]
        cone_name = strip_text(raw_first)
        cone_obj = [cones.get(c) for c in cone_name]
        flagged |= np.array([not isinstance(c, Cone) for c in cone_obj], dtype=bool)
        changes = rows.cone != np.repeat(raw_first, counts)
        if changes.any():  # compare the differing cells again, stripped
            at = np.flatnonzero(changes)
            owner = np.searchsorted(starts, at, side="right") - 1
            changes[at] = strip_text(rows.cone[at]) != cone_name[owner]
            flagged |= np.logical_or.reduceat(changes, starts)
    error = np.full(P, None, dtype=object)
    error_row = np.full(P, -1, dtype=np.int64)
    error_column = np.full(P, None, dtype=object)
    problems = np.full(P, None, dtype=object)
    word = info.row_word
    for i in np.flatnonzero(flagged):
        s, e = int(starts[i]), int(ends[i])
        pid = str(ids[i])
        reason = row = column = None
        if info.id_col is not None and pid == "":
            reason, row, column = "empty profile id", rows.lines[s], info.id_col
        elif bad_row[s:e].any():
            r = s + int(np.flatnonzero(bad_row[s:e])[0])
            if rows.depth_why is not None and rows.depth_why[r] is not None:
                reason, column = rows.depth_why[r], info.depth_col
            else:
                reason, column = rows.ci_why[r], info.ci_col
            row = rows.lines[r]
        elif not isinstance(cone_obj[i], Cone):
            reason, row, column = cone_obj[i], rows.lines[s], info.cone_col
        else:
            r = s + int(np.flatnonzero(changes[s:e])[0])
            reason = (
                f"cone changes within the profile ({rows.cone[r].strip()!r} here, "
                f"{cone_name[i]!r} on {word} {int(rows.lines[s])})"
            )
            row, column = rows.lines[r], info.cone_col
        where = dict(file=info.path, profile=pid or None, row=int(row), column=column)
        problems[i] = InputError(reason, **where)
        error[i] = str(problems[i])
        error_row[i] = int(row)
        error_column[i] = column
    if "reader_error" in rows.meta:  # an instrument file's push rejected by its reader
        _reader_errors(rows, starts, error, error_row, error_column, flagged)
        for i in np.flatnonzero(flagged):
            if problems[i] is None or str(problems[i]) != error[i]:
                problems[i] = _located(str(error[i]), info.path, str(ids[i]), error_row[i])
                problems[i].column = error_column[i]
    meta: dict[str, pa.Array] = {}
    for out, name, t in plan.meta:
        if name in rows.meta:
            col = rows.meta[name]
            vals = col[starts] if isinstance(col, np.ndarray) else col.take(pa.array(starts))
            meta[out] = _meta_array(vals, t, info.kind == "csv")
        else:
            meta[out] = pa.nulls(P, t)
    return Piece(
        P,
        ids,
        counts,
        first,
        info.path,
        cone_name,
        [c if isinstance(c, Cone) else None for c in cone_obj],
        error,
        error_row,
        error_column,
        ~flagged,
        rows,
        starts,
        meta,
        problems,
    )


def make_chunk(index: int, pieces: list[Piece], plan: ScanPlan) -> Chunk:
    """Join the pieces of a chunk; the fittable profiles become its ProfileSet (``task``)."""
    cat = np.concatenate
    fit = cat([p.fit for p in pieces])
    cone_list: list[Cone] = []
    cone_pos: dict[Cone, int] = {}
    files: list[SourceFile] = []
    file_pos: dict[str, int] = {}
    t_ids: list[np.ndarray] = []
    t_counts: list[np.ndarray] = []
    t_depth: list[np.ndarray] = []
    t_ci: list[np.ndarray] = []
    t_lines: list[np.ndarray] = []
    t_cone: list[np.ndarray] = []
    t_file: list[np.ndarray] = []
    for p in pieces:
        if not p.fit.any():
            continue
        info = plan.files[p.rows.file]
        if info.path not in file_pos:
            file_pos[info.path] = len(files)
            files.append(SourceFile(info.path, info.depth_col, info.ci_col, info.row_word))
        keep_rows = np.repeat(p.fit, p.counts)
        t_depth.append(p.rows.depth[keep_rows])
        t_ci.append(p.rows.ci[keep_rows])
        t_lines.append(p.rows.lines[keep_rows])
        t_counts.append(p.counts[p.fit])
        sel = np.flatnonzero(p.fit)
        # cones by object (ConeCache gives one object per name): hashed once per cone, not per profile
        local: dict[int, int] = {}
        codes = np.empty(sel.size, dtype=np.intp)
        for k, i in enumerate(sel.tolist()):
            c = p.cone_obj[i]
            pos = local.get(id(c))
            if pos is None:
                if c not in cone_pos:
                    cone_pos[c] = len(cone_list)
                    cone_list.append(c)
                pos = local[id(c)] = cone_pos[c]
            codes[k] = pos
        t_cone.append(codes)
        t_ids.append(p.ids[sel])
        t_file.append(np.full(sel.size, file_pos[info.path], dtype=np.intp))
    task = None
    if t_ids:
        counts = cat(t_counts)
        task = ProfileSet(
            ids=cat(t_ids).astype(object),
            offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            depth=cat(t_depth),
            ci=cat(t_ci),
            cone_idx=cat(t_cone),
            cones=cone_list,
            rows=cat(t_lines),
            file_idx=cat(t_file),
            files=files,
        )
    meta = {out: pa.concat_arrays([p.meta[out] for p in pieces]) for out, _, _ in plan.meta}
    return Chunk(
        index=index,
        ids=cat([p.ids for p in pieces]),
        counts=cat([p.counts for p in pieces]),
        first_row=cat([p.first_row for p in pieces]),
        source=cat([np.full(p.n, p.source, dtype=object) for p in pieces]),
        cone=cat([p.cone_name for p in pieces]),
        error=cat([p.error for p in pieces]),
        error_row=cat([p.error_row for p in pieces]),
        error_column=cat([p.error_column for p in pieces]),
        fit=fit,
        meta=meta,
        task=task,
        problems=cat([p.problems for p in pieces]),
    )


def iter_chunks(
    plan: ScanPlan, chunk_size: int, cones: ConeCache, skip: set[int]
) -> Iterator[tuple[int, Chunk | None, int]]:
    """(index, chunk or None when skipped, profiles) in input order."""
    pieces: list[Piece] = []
    have = 0
    index = 0
    for rows, starts in profile_blocks(plan):
        i = 0
        P = int(starts.size)
        n = len(rows)
        while i < P:
            take = min(chunk_size - have, P - i)
            if index not in skip:
                a = int(starts[i])
                b = int(starts[i + take]) if i + take < P else n
                sub = rows.slice(a, b)
                pieces.append(make_piece(sub, starts[i : i + take] - a, plan, cones))
            have += take
            i += take
            if have == chunk_size:
                yield index, (None if index in skip else make_chunk(index, pieces, plan)), have
                pieces, have = [], 0
                index += 1
    if have:
        yield index, (None if index in skip else make_chunk(index, pieces, plan)), have


# ---------------------------------------------------------------------------
# profile sets
# ---------------------------------------------------------------------------


def chunk_set(chunk: Chunk, plan: ScanPlan, depth_ref: str = "base") -> ProfileSet:
    """A chunk as a validated :class:`ProfileSet` with its metadata (input column
    names) and the refused profiles in ``errors``, in input order."""
    fit = np.flatnonzero(chunk.fit)
    task = chunk.task
    if task is None:
        task = ProfileSet([], [0], [], [], [], [], rows=np.zeros(0, np.int64), files=[])
    if depth_ref == "tip":
        task = replace(task, depth=task.depth - np.repeat(task.heights(), task.counts))
    take = pa.array(fit, pa.int64())
    meta = {name: chunk.meta[out].take(take) for out, name, _ in plan.meta}
    task = replace(
        task,
        metadata=pa.table(meta) if meta else None,
        notes=[[] for _ in range(len(task))],
    )
    bad = task.screen()
    where = {int(i): chunk.problems[i] for i in np.flatnonzero(~chunk.fit)}
    where.update({int(fit[j]): exc for j, exc in bad.items()})
    out = task.take([j for j in range(len(task)) if j not in bad]) if bad else task
    out.errors = [where[i] for i in sorted(where)]
    return out

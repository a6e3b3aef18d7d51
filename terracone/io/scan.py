"""Scanning cone index inputs before they are streamed (batch's first pass, eq. (2-3)).

:func:`scan_inputs` checks every CSV or Parquet header, counts the profiles and
fixes the type of every metadata column before anything is computed;
:class:`CsvLines` and :func:`csv_blocks` read CSV through pyarrow, keeping the
file line of every row.  :mod:`terracone.io.stream` reads the rows.
"""

from __future__ import annotations

import csv
import gzip
import io
import re
from array import array
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from terracone.data import InputError
from terracone.io.tables import (
    CI_SCHEMA,
    DECIMAL,
    SPECIAL_FLOAT,
    PathLike,
    check_separator,
    column_layout,
    is_parquet,
    unguard_formula,
)

#: Rows read per block (CSV / Parquet); memory per block, not per profile.
CSV_BLOCK_BYTES = 1 << 22
PARQUET_BLOCK_ROWS = 1 << 16
#: Rows per block of the standard-library CSV path (ragged rows).
CSV_BLOCK_ROWS = 1 << 15


# ---------------------------------------------------------------------------
# input files
# ---------------------------------------------------------------------------


def kind_of(path: Path, strict: bool) -> str | None:
    """The kind of an input file by its name (``csv`` or ``parquet``); None when ``strict`` and neither."""
    name = path.name.lower()
    if name.endswith((".csv", ".csv.gz")):
        return "csv"
    if strict and not name.endswith((".parquet", ".pq")):
        return None
    return "parquet" if is_parquet(path) else "csv"  # another name: the magic number


def input_files(input: PathLike) -> list[tuple[Path, str]]:
    """(absolute path, kind) of the input files, in processing order."""
    p = Path(input)
    if p.is_dir():
        files = []
        for f in sorted(p.iterdir(), key=lambda x: x.name):
            if f.name.startswith((".", "_")) or not f.is_file():
                continue
            kind = kind_of(f, strict=True)
            if kind is not None:
                files.append((f.resolve(), kind))
        if not files:
            raise InputError(
                "no input files (*.csv, *.csv.gz, *.parquet, *.pq) in the directory", file=str(p)
            )
        return files
    if p.is_file():
        return [(p.resolve(), kind_of(p, strict=False) or "csv")]
    raise InputError("file or directory not found", file=str(p))


def fingerprint(input: PathLike, files: list[tuple[Path, str]]) -> dict[str, Any]:
    """Path, size and modification time of every input file (a resumed run checks it)."""
    out = []
    for f, kind in files:
        st = f.stat()
        out.append({"path": str(f), "kind": kind, "size": st.st_size, "mtime_ns": st.st_mtime_ns})
    return {"path": str(Path(input).resolve()), "files": out}


# ---------------------------------------------------------------------------
# CSV streaming without comment lines
# ---------------------------------------------------------------------------

# a "\n" followed by a comment or blank line (literal prefix: fast to search)
_SKIP_NEXT = re.compile(rb"\n(?=[ \t\r\f\v]*[#\n])")
_SKIP_FIRST = re.compile(rb"[ \t\r\f\v]*[#\n]")


class CsvLines(io.RawIOBase):
    """Binary, read-only file object: a CSV file without comment and blank lines.

    The dropped lines' numbers are kept until no longer needed, so every data row
    maps back to its file line (exact unless a quoted field holds a line break).
    Handles ``.gz`` files and a UTF-8 byte order mark.
    """

    BLOCK = 1 << 20

    def __init__(self, path: str) -> None:
        super().__init__()
        self.path = path
        self.header_fields = 0
        try:
            opener = gzip.open if path.lower().endswith(".gz") else open
            self._f = opener(path, "rb")
        except OSError as exc:
            raise InputError(f"cannot open: {exc.strerror or exc}", file=path) from None
        self._pending = b""
        self._out = bytearray()
        self._line = 0  # physical lines consumed
        self._dropped = array("q")  # dropped lines not yet accounted in _drop_base
        self._drop_base = 0  # dropped lines before the rows already numbered
        self._eof = False
        self._first = True
        self.header_line: int | None = None

    def close(self) -> None:
        self._f.close()
        super().close()

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        data = self.read(len(buffer))
        buffer[: len(data)] = data
        return len(data)

    def __enter__(self) -> CsvLines:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _fill(self) -> None:
        raw = self._f.read(self.BLOCK)
        if self._first:
            self._first = False
            if raw.startswith(b"\xef\xbb\xbf"):
                raw = raw[3:]
        if not raw:
            self._eof = True
            data, self._pending = self._pending, b""
            if data:
                self._filter(data + b"\n")
            return
        data = self._pending + raw
        cut = data.rfind(b"\n")
        if cut < 0:
            self._pending = data
            return
        self._pending = data[cut + 1 :]
        self._filter(data[: cut + 1])

    def _filter(self, data: bytes) -> None:
        """Append the kept lines of ``data`` (whole lines) to the output buffer."""
        base = self._line
        out = self._out
        starts = [m.start() + 1 for m in _SKIP_NEXT.finditer(data)]  # dropped line starts
        if _SKIP_FIRST.match(data):
            starts.insert(0, 0)
        keep_from = 0
        pos = 0
        nl_before = 0
        for s in starts:
            nl_before += data.count(b"\n", pos, s)
            pos = s
            out += data[keep_from:s]
            keep_from = data.index(b"\n", s) + 1
            self._dropped.append(base + 1 + nl_before)
        out += data[keep_from:]
        self._line = base + data.count(b"\n")

    def read(self, n: int | None = -1) -> bytes:
        while not self._eof and (n is None or n < 0 or len(self._out) < n):
            self._fill()
        if n is None or n < 0:
            n = len(self._out)
        chunk = bytes(self._out[:n])
        del self._out[:n]
        return chunk

    def header(self) -> list[str]:
        """Read the header line (the first kept line) and return its cells."""
        while b"\n" not in self._out and not self._eof:
            self._fill()
        if not self._out:
            raise InputError("no header line (the file is empty or all comments)", file=self.path)
        cut = self._out.find(b"\n")
        raw = bytes(self._out[:cut]) if cut >= 0 else bytes(self._out)
        del self._out[: cut + 1 if cut >= 0 else len(self._out)]
        self.header_line = int(self.lines(-1, 1)[0])
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError(
                f"not a UTF-8 text file ({exc.reason})", file=self.path, row=self.header_line
            ) from None
        cells = next(csv.reader([text.rstrip("\r")]), [])
        cells = [unguard_formula(c).strip() for c in cells]
        self.header_fields = len(cells)
        while cells and not cells[-1]:
            cells.pop()
        check_separator(self.path, cells, self.header_line)
        return cells

    def lines(self, first_row: int, n: int) -> np.ndarray:
        """File line numbers of data rows ``first_row`` .. ``first_row + n - 1``.

        Rows count from 0 after the header (``first_row = -1`` is the header);
        must be called with increasing ``first_row``.
        """
        p = np.arange(first_row + 1, first_row + 1 + n, dtype=np.int64)  # kept-line index
        d = np.frombuffer(self._dropped.tobytes(), dtype=np.int64)
        key = d - (self._drop_base + np.arange(d.size, dtype=np.int64))
        k = self._drop_base + np.searchsorted(key, p + 1, side="right")
        out = p + 1 + k
        if n and d.size:  # forget the dropped lines before the last numbered row
            done = int(np.searchsorted(d, out[-1]))
            if done:
                del self._dropped[:done]
                self._drop_base += done
        return out


def csv_blocks(
    stream: CsvLines, width: int, fields: int, columns: Sequence[int] | None = None
) -> Iterator[tuple[pa.RecordBatch, int]]:
    """Blocks of a CSV body (after :meth:`CsvLines.header`), every cell as text.

    Yields (batch, index of its first data row); the batch has the header's
    ``width`` columns ``c0..`` (only ``columns``, by position, when given:
    Arrow then converts no others; read them by name, :func:`block_cells`).
    ``fields`` is the number of fields of the header line (trailing empty
    ones included).  pyarrow parses the body;
    when a row has another number of fields, or a block is not UTF-8, the
    file is read again from the current block with :mod:`csv`
    (:func:`_csv_module_blocks`), which pads short rows, checks extra fields
    and names the bad byte.
    """
    path = stream.path
    names = [f"c{j}" for j in range(fields)]
    ragged: list[str] = []

    def on_invalid(row: Any) -> str:
        ragged.append(row.text)
        return "skip"

    try:
        reader = pacsv.open_csv(
            stream,
            read_options=pacsv.ReadOptions(column_names=names, block_size=CSV_BLOCK_BYTES),
            parse_options=pacsv.ParseOptions(
                newlines_in_values=True, ignore_empty_lines=False, invalid_row_handler=on_invalid
            ),
            convert_options=pacsv.ConvertOptions(
                column_types={n: pa.string() for n in names},
                include_columns=names[:width] if columns is None else [names[j] for j in columns],
                strings_can_be_null=False,
                quoted_strings_can_be_null=False,
            ),
        )
    except pa.ArrowInvalid as exc:
        if "Empty CSV file" in str(exc):
            return
        if not _not_utf8(exc):
            raise _csv_error(path, exc) from None
        reader = None
    row0 = 0
    while reader is not None:
        try:
            batch = reader.read_next_batch()
        except StopIteration:
            return
        except pa.ArrowInvalid as exc:
            if not _not_utf8(exc):
                raise _csv_error(path, exc) from None
            break  # the csv module names the bad byte
        if ragged:
            break
        if batch.num_rows:
            yield batch, row0
            row0 += batch.num_rows
    yield from _csv_module_blocks(path, width, row0)


def _not_utf8(exc: Exception) -> bool:
    return "UTF8" in str(exc) or "UTF-8" in str(exc)


def _csv_error(path: str, exc: Exception) -> InputError:
    return InputError(f"bad CSV: {exc}", file=path)


def _csv_module_blocks(path: str, width: int, row0: int) -> Iterator[tuple[pa.RecordBatch, int]]:
    """Blocks from data row ``row0`` on, parsed by :mod:`csv` (rows of any length)."""
    with CsvLines(path) as stream:
        stream.header()
        text = io.TextIOWrapper(stream, encoding="utf-8", newline="")
        records = csv.reader(text)
        rows: list[list[str]] = []
        i = 0
        try:
            for rec in records:
                if i >= row0:
                    if len(rec) < width:
                        rec.extend([""] * (width - len(rec)))
                    elif len(rec) > width:
                        if any(c.strip() for c in rec[width:]):
                            raise InputError(
                                f"more fields than the header ({width}) and the extra ones "
                                "are not empty",
                                file=path,
                                row=int(stream.lines(i, 1)[0]),
                            )
                        del rec[width:]
                    rows.append(rec)
                    if len(rows) == CSV_BLOCK_ROWS:
                        yield _text_batch(rows, width), i + 1 - len(rows)
                        rows = []
                i += 1
        except UnicodeDecodeError as exc:
            raise InputError(f"not a UTF-8 text file ({exc.reason})", file=path) from None
        except csv.Error as exc:
            raise InputError(f"bad CSV: {exc}", file=path, row=int(stream.lines(i, 1)[0])) from None
        if rows:
            yield _text_batch(rows, width), i - len(rows)


def _text_batch(rows: list[list[str]], width: int) -> pa.RecordBatch:
    cols = list(zip(*rows)) if rows else [() for _ in range(width)]
    return pa.record_batch(
        [pa.array(list(c), pa.string()) for c in cols], names=[f"c{j}" for j in range(width)]
    )


@dataclass
class FileInfo:
    """One input file as the scan saw it: its columns, their SI factors and its profile count."""

    path: str
    kind: str  # "csv" or "parquet"
    id_col: str | None
    depth_col: str
    ci_col: str
    cone_col: str | None
    depth_factor: float
    ci_factor: float
    meta_cols: list[str]
    width: int = 0  # CSV: header fields (trailing empty ones dropped)
    fields: int = 0  # CSV: fields of the header line
    col_index: dict[str, int] = field(default_factory=dict)  # CSV: name -> position
    profiles: int = 0

    @property
    def row_word(self) -> str:
        return "line" if self.kind == "csv" else "row"

    @property
    def stem(self) -> str:
        name = Path(self.path).name
        for suffix in (".csv.gz", ".csv", ".parquet", ".pq"):
            if name.lower().endswith(suffix):
                return name[: -len(suffix)]
        return Path(self.path).stem


@dataclass
class ScanPlan:
    """What the scan found: the files, the profile count and the metadata columns."""

    files: list[FileInfo]
    profiles: int
    id_hash: int  # sum of the uint64 hashes of the profile ids (mod 2**64)
    meta: list[tuple[str, str, pa.DataType]]  # (output name, input name, type)
    leading: Sequence[tuple[str, pa.DataType]] = ()  # output columns before the metadata

    @property
    def schema(self) -> pa.Schema:
        """The leading columns, then the metadata columns (output names)."""
        fields = [pa.field(n, t) for n, t in self.leading]
        fields += [pa.field(out, t) for out, _, t in self.meta]
        return pa.schema(fields)


def file_layout(
    path: str, kind: str, header: list[str], line: int | None, units: str | None = None
) -> FileInfo:
    """The columns of a CI file from its header (raises a located InputError)."""
    layout = column_layout(path, header, line, CI_SCHEMA, units)
    d, c = layout.groups["depth"], layout.groups["ci"]
    cone = layout.extra.get("cone")
    return FileInfo(
        path=path,
        kind=kind,
        id_col=None if layout.id_col is None else layout.id_col.name,
        depth_col=d.name,
        ci_col=c.name,
        cone_col=None if cone is None else cone.name,
        depth_factor=d.factor,
        ci_factor=c.factor,
        meta_cols=[m.name for m in layout.metadata],
        width=len(header),
        col_index={name: j for j, name in enumerate(header)},
    )


def hash_ids(ids: np.ndarray) -> np.ndarray:
    """Deterministic uint64 hash of each id (pandas' SipHash with a fixed key)."""
    if ids.size == 0:
        return np.empty(0, dtype=np.uint64)
    return pd.util.hash_array(np.asarray(ids, dtype=object), categorize=False)


def profile_starts(ids: np.ndarray) -> np.ndarray:
    """Indices where a new profile starts (0 included).

    ``ids`` are the raw cells: a profile is a run of rows whose ids are equal
    once stripped of surrounding blanks (only the first cell of each run of
    equal raw cells is stripped, so the cost is per profile, not per row).
    """
    if ids.size == 0:
        return np.empty(0, dtype=np.int64)
    st = np.concatenate([[0], np.flatnonzero(ids[1:] != ids[:-1]) + 1]).astype(np.int64)
    if st.size > 1:
        first = strip_text(ids[st])
        keep = np.ones(st.size, dtype=bool)
        keep[1:] = first[1:] != first[:-1]
        st = st[keep]
    return st


def strip_text(values: np.ndarray) -> np.ndarray:
    """Each cell of an object array of str without its surrounding white space."""
    return np.array([v.strip() for v in values.tolist()], dtype=object).reshape(len(values))


def csv_text(values: np.ndarray) -> np.ndarray:
    """:func:`strip_text` of CSV cells, each first without the guard quote of
    :func:`~terracone.io.tables.guard_formula` (as the table readers read them)."""
    cells = [unguard_formula(v).strip() for v in values.tolist()]
    return np.array(cells, dtype=object).reshape(len(values))


def _is_number_text(v: str) -> bool:
    return not v.strip() or bool(DECIMAL.match(v) or SPECIAL_FLOAT.match(v))


def _scan_csv(path: str, units: str | None) -> tuple[FileInfo, int, int, dict[str, bool]]:
    with CsvLines(path) as stream:
        header = stream.header()
        info = file_layout(path, "csv", header, stream.header_line, units)
        info.fields = stream.header_fields
        numeric = {m: True for m in info.meta_cols}
        count = 0
        hsum = np.uint64(0)
        prev: str | None = None
        ci = info.col_index
        wanted = [ci[m] for m in ([info.id_col] if info.id_col else []) + info.meta_cols]
        for block, _ in csv_blocks(stream, info.width, info.fields, wanted):
            if info.id_col is None:
                st = np.zeros(min(block.num_rows, 1), dtype=np.int64)
                first = np.full(st.size, info.stem, dtype=object)
            else:
                cells = block.column(f"c{ci[info.id_col]}")
                st = text_starts(cells)
                first = csv_text(cells.take(pa.array(st)).to_numpy(zero_copy_only=False))
            if st.size and prev is not None and first[0] == prev:
                st, first = st[1:], first[1:]
            if first.size:
                prev = first[-1]
            count += int(st.size)
            with np.errstate(over="ignore"):
                hsum += hash_ids(first).sum(dtype=np.uint64)
            for m in info.meta_cols:
                if numeric[m]:
                    numeric[m] = _all_number_text(block.column(f"c{ci[m]}").take(pa.array(st)))
    info.profiles = count
    return info, count, int(hsum), numeric


def arrow_text(arr: pa.Array | pa.ChunkedArray) -> pa.Array:
    """A column as stripped strings (nulls as "")."""
    if isinstance(arr, pa.ChunkedArray):
        arr = arr.combine_chunks()
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    if not pa.types.is_string(arr.type):
        arr = pc.cast(arr, pa.string())
    return pc.utf8_trim_whitespace(pc.fill_null(arr, ""))


def plain_type(t: pa.DataType) -> pa.DataType | None:
    """The value type of an Arrow column (dictionaries decoded, large strings as strings); None for null."""
    if pa.types.is_dictionary(t):
        t = t.value_type
    if pa.types.is_large_string(t) or pa.types.is_string_view(t):
        return pa.string()
    if pa.types.is_null(t):
        return None
    return t


def _number_column_ok(t: pa.DataType) -> bool:
    t = plain_type(t)  # None: a null column
    kinds = (pa.types.is_integer, pa.types.is_floating, pa.types.is_decimal, pa.types.is_string)
    return t is None or any(is_kind(t) for is_kind in kinds)


def parquet_file(path: str) -> pq.ParquetFile:
    """A Parquet reader whose memory stays flat while iterating over the file.

    With pre-buffering (pyarrow's default) ``iter_batches`` keeps the column
    chunks it has read: memory grows with the file (0.7 GB for a 0.8 GB file).
    """
    return pq.ParquetFile(path, pre_buffer=False)


def block_cells(block: pa.RecordBatch, j: int) -> np.ndarray:
    """Column ``c<j>`` of a CSV block as an object array of str."""
    return block.column(f"c{j}").to_numpy(zero_copy_only=False).astype(object, copy=False)


def text_starts(cells: pa.Array) -> np.ndarray:
    """:func:`profile_starts` of a column of CSV cells (:func:`csv_text`), compared in Arrow:
    only the first cell of each run of equal cells becomes a Python str."""
    n = len(cells)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    change = pc.not_equal(cells.slice(1), cells.slice(0, n - 1)).to_numpy(zero_copy_only=False)
    st = np.concatenate([[0], np.flatnonzero(change) + 1]).astype(np.int64)
    if st.size > 1:
        first = csv_text(cells.take(pa.array(st)).to_numpy(zero_copy_only=False).astype(object))
        keep = np.ones(st.size, dtype=bool)
        keep[1:] = first[1:] != first[:-1]
        st = st[keep]
    return st


#: A metadata cell that reads as a number (or is blank), for Arrow (RE2): DECIMAL or
#: SPECIAL_FLOAT of terracone.io.tables
_NUMBER_TEXT_RE2 = (
    r"^\s*$|^\s*[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\s*$"
    r"|^\s*[+-]?(?i:nan|inf|infinity)\s*$"
)


def _all_number_text(cells: pa.Array) -> bool:
    """Whether every cell reads as a number or is blank (:func:`_is_number_text` of each)."""
    if pc.all(pc.match_substring_regex(cells, _NUMBER_TEXT_RE2)).as_py() is not False:
        return True
    # RE2 knows ASCII digits only: ask Python about the others (never more than a block)
    return all(_is_number_text(v) for v in cells.to_pylist())


def _scan_parquet(
    path: str, units: str | None
) -> tuple[FileInfo, int, int, dict[str, pa.DataType | None]]:
    try:
        pf = parquet_file(path)
    except (OSError, pa.ArrowException) as exc:
        raise InputError(f"cannot read as Parquet: {exc}", file=path) from None
    schema = pf.schema_arrow
    info = file_layout(path, "parquet", list(schema.names), None, units)
    for col in (info.depth_col, info.ci_col):
        t = schema.field(col).type
        if not _number_column_ok(t):
            raise InputError(f"column type {t} cannot hold numbers", file=path, column=col)
    types = {m: plain_type(schema.field(m).type) for m in info.meta_cols}
    count = 0
    hsum = np.uint64(0)
    if info.id_col is None:
        if pf.metadata.num_rows:
            count = 1
            hsum = hash_ids(np.array([info.stem], dtype=object))[0]
    else:
        prev: str | None = None
        for batch in pf.iter_batches(batch_size=PARQUET_BLOCK_ROWS, columns=[info.id_col]):
            ids = arrow_text(batch.column(0))
            n = len(ids)
            if n == 0:
                continue
            change = pc.not_equal(ids.slice(1), ids.slice(0, n - 1)).to_numpy(zero_copy_only=False)
            st = np.concatenate([[0], np.flatnonzero(change) + 1]).astype(np.int64)
            first = ids.take(pa.array(st)).to_numpy(zero_copy_only=False)
            if prev is not None and first[0] == prev:
                st, first = st[1:], first[1:]
            prev = ids[n - 1].as_py()
            count += int(st.size)
            with np.errstate(over="ignore"):
                hsum += hash_ids(first).sum(dtype=np.uint64)
    info.profiles = count
    return info, count, int(hsum), types


def _unify(types: list[pa.DataType]) -> pa.DataType:
    known = [t for t in types if t is not None]
    if not known:
        return pa.string()
    if all(t == known[0] for t in known):
        return known[0]
    if all(pa.types.is_integer(t) for t in known):
        return pa.int64()
    if all(pa.types.is_integer(t) or pa.types.is_floating(t) for t in known):
        return pa.float64()
    return pa.string()


def scan_inputs(
    files: list[tuple[Path, str]],
    leading: Sequence[tuple[str, pa.DataType]] = (),
    units: str | None = None,
) -> ScanPlan:
    """The first, cheap pass over the input: headers, profile count and id checksum,
    and one type per metadata column (a name taken by a ``leading`` output column
    is prefixed ``meta_``).  Raises a located InputError for file-level problems."""
    infos: list[FileInfo] = []
    total = 0
    hsum = 0
    meta_types: dict[str, list[pa.DataType | None]] = {}
    for path, kind in files:
        if kind == "csv":
            info, count, h, numeric = _scan_csv(str(path), units)
            typed = {m: (pa.float64() if ok else pa.string()) for m, ok in numeric.items()}
        else:
            info, count, h, typed = _scan_parquet(str(path), units)
        infos.append(info)
        total += count
        hsum = (hsum + h) % (1 << 64)
        for m, t in typed.items():
            meta_types.setdefault(m, []).append(t)
    reserved = {name.lower() for name, _ in leading}
    meta: list[tuple[str, str, pa.DataType]] = []
    taken = set(reserved)
    for name, ts in meta_types.items():
        out = name
        while out.lower() in taken:
            out = "meta_" + out
        taken.add(out.lower())
        meta.append((out, name, _unify(ts)))
    return ScanPlan(infos, total, hsum, meta, tuple(leading))

"""Batch prediction: many CI profiles -> one Parquet data set, computed with Dask.

:func:`run_batch` streams cone index profiles from a CSV or Parquet file (or
a directory of them), fits the improved cone model to every profile with the
vectorised exact solver (:func:`terracone.inverse.many.solve_exact_many`) on
a Dask cluster, and writes one row per profile to Parquet part files.

Design
------
* **One execution path.**  Work always runs on ``dask.distributed``: a
  :class:`~distributed.LocalCluster` of ``workers`` processes (one thread
  each) started and stopped by :func:`run_batch`, or an existing scheduler
  (``scheduler="tcp://HOST:PORT"``).
* **Chunks, not profiles.**  The input stream is cut into chunks of
  ``chunk_size`` profiles: chunk *i* holds profiles ``i*chunk_size`` to
  ``(i+1)*chunk_size - 1`` in input order (files in name order).  One Dask
  task fits one chunk, with one ``solve_exact_many`` call per cone.  At most
  ``2 x worker threads`` chunks are in flight, and the reader only reads
  ahead when a slot is free, so memory stays flat whatever the input size.
* **Streaming input.**  CSV is read in blocks with ``pandas.read_csv``
  (every cell as text, converted like :func:`terracone.io.read_ci_profiles`
  does), Parquet with ``ParquetFile.iter_batches``.  The last, possibly
  incomplete, profile of a block is carried over to the next block.  The
  rows of a profile must be contiguous.  A first, cheap pass over the input
  (the *scan*) counts the profiles, checks every file's header and fixes the
  type of every metadata column before anything is computed.
* **Atomic output.**  The client writes ``part-000000.parquet``,
  ``part-000001.parquet``, ... (one per chunk) to a temporary name in
  ``out_dir`` and renames it (``os.replace``) when complete, so a part file
  is either absent or whole.  ``_run.json`` records the settings and the
  input fingerprint, ``_summary.json`` the counts and timings.
* **Nothing lost.**  Every input profile gives exactly one output row;
  problems with a profile make *its* row ``status="error"`` with a located
  reason.  At the end the output is checked against the scan: the number of
  rows, a checksum of the profile ids and duplicate ids.

See ``docs/batch.md`` for the user guide.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import gzip
import hashlib
import json
import logging
import os
import re
import sys
import time
import uuid
import warnings
from array import array
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from . import __version__
from . import units as u
from .cone import Cone, get_cone
from .data import CIProfile, InputError, ProfileSet, SourceFile
from .inverse.bounds import Bounds
from .inverse.learn import Calibration
from .inverse.many import solve_exact_many
from .inverse.predict import predict_many, screen
from .io import (
    CI_SCHEMA,
    DECIMAL,
    SPECIAL_FLOAT,
    Table,
    column_layout,
    detect_format,
    json_default,
    to_numbers,
)
from .jit import enabled
from .metrics import check_fit_fast
from .plate import pressure_law

__all__ = ["BatchSummary", "run_batch", "OUTPUT_COLUMNS"]

PathLike = str | os.PathLike[str]

#: Rows read per block (CSV / Parquet); memory per block, not per profile.
_CSV_BLOCK_ROWS = 1 << 15
_PARQUET_BLOCK_ROWS = 1 << 16
#: Spare columns given to the CSV parser so that rows with a few extra
#: (empty) fields parse; non-empty extra fields are an error.
_SPARE = 4
#: Seconds to wait for a worker to join an external scheduler.
_WAIT_WORKERS_S = 60.0
#: Grid over n of solve_exact_many (its default) and the noise floor of predict.
_N_GRID = 41
_NOISE_FLOOR = 0.01
#: glibc malloc settings of the local cluster's worker processes.  Dask's
#: default (MALLOC_TRIM_THRESHOLD_=65536) switches off glibc's dynamic mmap
#: threshold, so every large numpy temporary of the solver is mmapped and
#: page-faulted afresh: the fit runs at half speed.  Serving everything from
#: the heap and keeping freed memory for the next chunk restores it.
WORKER_MALLOC_ENV = {"MALLOC_MMAP_MAX_": "0", "MALLOC_TRIM_THRESHOLD_": str(1 << 30)}

_PART = re.compile(r"^part-(\d{6,})\.parquet$")
_TMP_PREFIX = ".part-"
_PART_META_KEY = b"terracone_batch"

#: parameters with posterior intervals and identifiability labels (``uncertainty=True``)
_UQ_PARAMS = ("kc", "kphi", "n", "cc", "phic_deg")

#: Output columns before the metadata columns, with their Arrow types.
OUTPUT_COLUMNS: tuple[tuple[str, pa.DataType], ...] = (
    ("profile", pa.string()),
    ("status", pa.string()),
    ("error", pa.string()),
    ("error_row", pa.int64()),
    ("error_column", pa.string()),
    ("kc", pa.float64()),
    ("kphi", pa.float64()),
    ("n", pa.float64()),
    ("cc", pa.float64()),
    ("phic_deg", pa.float64()),
    ("phic_lo", pa.float64()),
    ("phic_hi", pa.float64()),
    ("n_lo", pa.float64()),
    ("n_hi", pa.float64()),
    ("rmsd", pa.float64()),
    ("r2_ci", pa.float64()),
    ("longest_run", pa.float64()),
    ("lack_of_fit", pa.string()),
    *[(f"{p}_{q}", pa.float64()) for p in _UQ_PARAMS for q in ("q05", "q95")],
    *[(f"ident_{p}", pa.string()) for p in _UQ_PARAMS],
    ("bic_single", pa.float64()),
    ("bic_layered", pa.float64()),
    ("preferred_layers", pa.float64()),
    ("r2_layered", pa.float64()),
    ("interfaces", pa.string()),
    ("n_layers", pa.string()),
    ("lack_of_fit_layered", pa.string()),
    ("n_points", pa.int64()),
    ("undetermined", pa.string()),
    ("model", pa.string()),
    ("r_min", pa.float64()),
    ("units", pa.string()),
    ("cone", pa.string()),
    ("source", pa.string()),
    ("source_row", pa.int64()),
    ("chunk", pa.int64()),
    ("fit_time_s", pa.float64()),
)
_FLOAT_RESULTS = (
    "kc",
    "kphi",
    "n",
    "cc",
    "phic_deg",
    "phic_lo",
    "phic_hi",
    "n_lo",
    "n_hi",
    "rmsd",
    "r2_ci",
    "longest_run",
    *[f"{p}_{q}" for p in _UQ_PARAMS for q in ("q05", "q95")],
    "bic_single",
    "bic_layered",
    "preferred_layers",
    "r2_layered",
)
_TEXT_RESULTS = (
    "lack_of_fit",
    *[f"ident_{p}" for p in _UQ_PARAMS],
    "interfaces",
    "n_layers",
    "lack_of_fit_layered",
)
#: every per-profile result: the floats and the texts (None or text)
_RESULT_KEYS = _FLOAT_RESULTS + _TEXT_RESULTS


def _empty_results(P: int) -> dict[str, np.ndarray]:
    res: dict[str, np.ndarray] = {k: np.full(P, np.nan) for k in _FLOAT_RESULTS}
    for k in _TEXT_RESULTS:
        res[k] = np.full(P, None, dtype=object)
    return res


# ---------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------


@dataclass
class BatchSummary:
    """What :func:`run_batch` did (also written to ``OUT_DIR/_summary.json``).

    Attributes
    ----------
    out_dir : str
    profiles, profiles_ok, profiles_error : int
        Rows in the output (one per input profile) and their status counts,
        over all part files (including chunks done by an earlier run).
    chunks : int
        Part files of the complete output.
    chunks_run : int
        Chunks computed by this call.
    chunks_skipped : int
        Chunks found complete in ``out_dir`` (``resume=True``) and not recomputed.
    chunks_failed : int
        Chunks whose task failed on the cluster; their profiles are written
        with status "error" and a later ``resume=True`` run recomputes them.
    duplicate_ids : dict
        Profile ids that occur more than once in the output -> count (at
        most 100 listed); ``n_duplicate_ids`` counts them all.
    problems : list of str
        Run-level problems (duplicate ids, failed chunks, a changed input,
        output that does not match the input).  Empty when all is well.
    workers : int
        Worker threads of the cluster.
    scheduler : str or None
        Address of the external scheduler; None for the local cluster.
    scan_s, startup_s, read_s, fit_s, fit_cpu_s, write_s, verify_s, wall_s : float
        Seconds: first pass over the input; cluster start or connection;
        reading and parsing chunks (client); fitting (sum over chunks of
        the time in the worker task, i.e. worker-seconds, and of its CPU
        time: they differ when the machine is busy); writing part files
        (client); final check of the output; whole call.
    profiles_per_s : float
        Profiles of the chunks computed by this call per second of wall time.
    """

    out_dir: str
    profiles: int = 0
    profiles_ok: int = 0
    profiles_error: int = 0
    chunks: int = 0
    chunks_run: int = 0
    chunks_skipped: int = 0
    chunks_failed: int = 0
    duplicate_ids: dict[str, int] = field(default_factory=dict)
    n_duplicate_ids: int = 0
    problems: list[str] = field(default_factory=list)
    workers: int = 0
    scheduler: str | None = None
    scan_s: float = 0.0
    startup_s: float = 0.0
    read_s: float = 0.0
    fit_s: float = 0.0
    fit_cpu_s: float = 0.0
    write_s: float = 0.0
    verify_s: float = 0.0
    wall_s: float = 0.0
    profiles_per_s: float = 0.0

    @property
    def success(self) -> bool:
        """True when the run has no run-level problem (error profiles are normal)."""
        return not self.problems

    def _repr_html_(self) -> str:
        """A table of the run's counts, for Jupyter."""
        from .report.notebook import batch_html

        return batch_html(self)

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["success"] = self.success
        return d


# ---------------------------------------------------------------------------
# input files
# ---------------------------------------------------------------------------


def _kind_of(path: Path, strict: bool) -> str | None:
    name = path.name.lower()
    if name.endswith((".csv", ".csv.gz")):
        return "csv"
    if name.endswith((".parquet", ".pq")):
        return "parquet"
    if strict:
        return None
    try:  # a single file with another name: sniff the Parquet magic number
        with open(path, "rb") as f:
            return "parquet" if f.read(4) == b"PAR1" else "csv"
    except OSError:
        return "csv"


def _input_files(input: PathLike) -> list[tuple[Path, str]]:
    """(absolute path, kind) of the input files, in processing order."""
    p = Path(input)
    if p.is_dir():
        files = []
        for f in sorted(p.iterdir(), key=lambda x: x.name):
            if f.name.startswith((".", "_")) or not f.is_file():
                continue
            kind = _kind_of(f, strict=True)
            if kind is not None:
                files.append((f.resolve(), kind))
        if not files:
            raise InputError(
                "no input files (*.csv, *.csv.gz, *.parquet, *.pq) in the directory", file=str(p)
            )
        return files
    if p.is_file():
        return [(p.resolve(), _kind_of(p, strict=False) or "csv")]
    raise InputError("file or directory not found", file=str(p))


def _sc900_to_parquet(path: Path, out: Path, cone: Cone, **reader: Any) -> Path:
    """An SC900 export or wide table as terracone Parquet in OUT_DIR/_input (kept for --resume).

    ``reader`` are keywords of :func:`terracone.io.read_ci_profiles` (format
    "sc900" by default; "wide" with its depth_unit and ci_unit).
    """
    from .io import read_ci_profiles

    target = out / "_input" / (path.stem + ".parquet")
    if target.exists():
        return target
    reader.setdefault("format", "sc900")
    items = read_ci_profiles(path, on_error="collect", cone=cone, **reader)
    target.parent.mkdir(parents=True, exist_ok=True)  # after the file-level checks
    rows: dict[str, list] = {
        "profile": [],
        "cone": [],
        "reader_error": [],
        "reader_error_row": [],
        "reader_error_column": [],
        "depth_m": [],
        "ci_kpa": [],
    }
    meta_keys: list[str] = []
    for it in items:
        if isinstance(it, CIProfile):
            for k in it.metadata:
                if k not in meta_keys and k not in rows:
                    meta_keys.append(k)
    for k in meta_keys:
        rows[k] = []
    for it in items:
        if isinstance(it, CIProfile):
            k = len(it)
            rows["profile"] += [it.id] * k
            rows["cone"] += [it.cone.name] * k
            rows["reader_error"] += [None] * k
            rows["reader_error_row"] += [None] * k
            rows["reader_error_column"] += [None] * k
            rows["depth_m"] += list(it.depth)
            rows["ci_kpa"] += list(it.ci)
            for mk in meta_keys:
                v = it.metadata.get(mk)
                rows[mk] += [None if v is None else str(v)] * k
        else:  # rejected by the reader: one row without a reading, the reason alongside
            rows["profile"].append(str(it.profile))
            rows["cone"].append(cone.name)
            rows["reader_error"].append(str(it))
            rows["reader_error_row"].append(it.row)
            rows["reader_error_column"].append(it.column)
            rows["depth_m"].append(float("nan"))
            rows["ci_kpa"].append(float("nan"))
            for mk in meta_keys:
                rows[mk].append(None)
    tmp = target.with_name("." + target.name + ".tmp")
    pq.write_table(pa.table(rows), tmp)
    os.replace(tmp, target)
    return target


def _fingerprint(input: PathLike, files: list[tuple[Path, str]]) -> dict[str, Any]:
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


class _CsvLines:
    """Binary, read-only file object: a CSV file without comment and blank lines.

    Follows the conventions of :mod:`terracone.io`: a line whose first
    non-blank character is ``#`` is a comment, blank lines are skipped.  The
    physical line numbers of the dropped lines are kept (only those not yet
    needed to number the rows already handed out), so every data row maps
    back to its line in the file (exact as long as no quoted field holds a
    line break).  Handles ``.gz`` files and a UTF-8 byte order mark.
    """

    BLOCK = 1 << 20

    def __init__(self, path: str) -> None:
        self.path = path
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

    def __enter__(self) -> _CsvLines:
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

    def read(self, n: int = -1) -> bytes:
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
        cells = [c.strip() for c in cells]
        while cells and not cells[-1]:
            cells.pop()
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


def _csv_blocks(stream: _CsvLines, width: int) -> Iterator[tuple[pd.DataFrame, int]]:
    """Blocks of a CSV body (after :meth:`_CsvLines.header`), every cell as text.

    Yields (frame, index of its first data row).  Columns ``c0..`` are the
    header's, ``x0..`` spare ones; rows with more non-empty fields than the
    header raise :class:`InputError`.
    """
    names = [f"c{j}" for j in range(width)] + [f"x{j}" for j in range(_SPARE)]
    path = stream.path

    def located(exc: Exception) -> InputError:
        msg = str(exc).strip().replace("Error tokenizing data. C error: ", "")
        m = re.search(r"line (\d+)", msg)
        row = int(stream.lines(int(m.group(1)) - 1, 1)[0]) if m else None
        msg = re.sub(r" in line \d+", "", msg)
        return InputError(f"bad CSV: {msg} (the header has {width})", file=path, row=row)

    try:
        reader = pd.read_csv(
            stream,
            header=None,
            names=names,
            dtype=object,  # Python str cells (dtype=str is Arrow-backed in pandas 3)
            na_filter=False,
            keep_default_na=False,
            index_col=False,
            chunksize=_CSV_BLOCK_ROWS,
            engine="c",
            encoding="utf-8",
        )
    except pd.errors.EmptyDataError:
        return
    row0 = 0
    while True:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", pd.errors.ParserWarning)
            try:
                df = next(reader)
            except StopIteration:
                break
            except pd.errors.EmptyDataError:
                break
            except pd.errors.ParserError as exc:
                raise located(exc) from None
            except UnicodeDecodeError as exc:
                raise InputError(f"not a UTF-8 text file ({exc.reason})", file=path) from None
        if any(issubclass(w.category, pd.errors.ParserWarning) for w in caught):
            raise InputError(
                f"a row near line {int(stream.lines(row0, 1)[0])} has more fields "
                f"than the header ({width})",
                file=path,
            )
        extra = np.zeros(len(df), dtype=bool)
        for j in range(_SPARE):
            extra |= df[f"x{j}"].to_numpy() != ""
        if extra.any():
            i = int(np.flatnonzero(extra)[0])
            line = int(stream.lines(row0 + i, 1)[0])
            raise InputError(
                f"more fields than the header ({width}) and the extra ones are not empty",
                file=path,
                row=line,
            )
        yield df, row0
        row0 += len(df)


# ---------------------------------------------------------------------------
# the scan: headers, profile count, metadata types
# ---------------------------------------------------------------------------


@dataclass
class _FileInfo:
    path: str
    kind: str  # "csv" or "parquet"
    id_col: str | None
    depth_col: str
    ci_col: str
    cone_col: str | None
    depth_factor: float
    ci_factor: float
    meta_cols: list[str]
    width: int = 0  # CSV: header fields
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
class _Plan:
    files: list[_FileInfo]
    profiles: int
    id_hash: int  # sum of the uint64 hashes of the profile ids (mod 2**64)
    meta: list[tuple[str, str, pa.DataType]]  # (output name, input name, type)

    @property
    def schema(self) -> pa.Schema:
        fields = [pa.field(n, t) for n, t in OUTPUT_COLUMNS]
        fields += [pa.field(out, t) for out, _, t in self.meta]
        return pa.schema(fields)


def _fake_table(path: str, header: list[str], line: int | None) -> Table:
    return Table(path, header, line, [], np.empty(0, dtype=int))  # type: ignore[arg-type]


def _layout_info(path: str, kind: str, header: list[str], line: int | None) -> _FileInfo:
    layout = column_layout(_fake_table(path, header, line), CI_SCHEMA, None)
    d, c = layout.groups["depth"], layout.groups["ci"]
    cone = layout.extra.get("cone")
    return _FileInfo(
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


def _hash_ids(ids: np.ndarray) -> np.ndarray:
    """Deterministic uint64 hash of each id (pandas' SipHash with a fixed key)."""
    if ids.size == 0:
        return np.empty(0, dtype=np.uint64)
    return pd.util.hash_array(np.asarray(ids, dtype=object), categorize=False)


def _starts(ids: np.ndarray) -> np.ndarray:
    """Indices where a new profile starts (0 included).

    ``ids`` are the raw cells: a profile is a run of rows whose ids are equal
    once stripped of surrounding blanks (only the first cell of each run of
    equal raw cells is stripped, so the cost is per profile, not per row).
    """
    if ids.size == 0:
        return np.empty(0, dtype=np.int64)
    st = np.concatenate([[0], np.flatnonzero(ids[1:] != ids[:-1]) + 1]).astype(np.int64)
    if st.size > 1:
        first = _strip(ids[st])
        keep = np.ones(st.size, dtype=bool)
        keep[1:] = first[1:] != first[:-1]
        st = st[keep]
    return st


def _strip(values: np.ndarray) -> np.ndarray:
    return np.array([v.strip() for v in values.tolist()], dtype=object).reshape(len(values))


def _is_number_text(v: str) -> bool:
    return not v.strip() or bool(DECIMAL.match(v) or SPECIAL_FLOAT.match(v))


def _scan_csv(path: str) -> tuple[_FileInfo, int, int, dict[str, bool]]:
    with _CsvLines(path) as stream:
        header = stream.header()
        info = _layout_info(path, "csv", header, stream.header_line)
        numeric = {m: True for m in info.meta_cols}
        count = 0
        hsum = np.uint64(0)
        prev: str | None = None
        for df, _ in _csv_blocks(stream, info.width):
            if info.id_col is None:
                ids = np.full(len(df), info.stem, dtype=object)
            else:
                ids = df[f"c{info.col_index[info.id_col]}"].to_numpy()
            st = _starts(ids)
            first = _strip(ids[st])
            if st.size and prev is not None and first[0] == prev:
                st, first = st[1:], first[1:]
            if first.size:
                prev = first[-1]
            count += int(st.size)
            with np.errstate(over="ignore"):
                hsum += _hash_ids(first).sum(dtype=np.uint64)
            for m in info.meta_cols:
                if numeric[m]:
                    vals = df[f"c{info.col_index[m]}"].to_numpy()[st]
                    numeric[m] = all(_is_number_text(v) for v in vals)
    info.profiles = count
    return info, count, int(hsum), numeric


def _arrow_text(arr: pa.Array | pa.ChunkedArray) -> pa.Array:
    """A column as stripped strings (nulls as "")."""
    if isinstance(arr, pa.ChunkedArray):
        arr = arr.combine_chunks()
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    if not pa.types.is_string(arr.type):
        arr = pc.cast(arr, pa.string())
    return pc.utf8_trim_whitespace(pc.fill_null(arr, ""))


def _plain_type(t: pa.DataType) -> pa.DataType | None:
    if pa.types.is_dictionary(t):
        t = t.value_type
    if pa.types.is_large_string(t) or pa.types.is_string_view(t):
        return pa.string()
    if pa.types.is_null(t):
        return None
    return t


def _number_column_ok(t: pa.DataType) -> bool:
    t = _plain_type(t) or pa.null()
    return (
        pa.types.is_integer(t)
        or pa.types.is_floating(t)
        or pa.types.is_decimal(t)
        or pa.types.is_string(t)
        or pa.types.is_null(t)
    )


def _parquet_file(path: str) -> pq.ParquetFile:
    """A Parquet reader whose memory stays flat while iterating over the file.

    With pre-buffering (pyarrow's default) ``iter_batches`` keeps the column
    chunks it has read: memory grows with the file (0.7 GB for a 0.8 GB file).
    """
    return pq.ParquetFile(path, pre_buffer=False)


def _scan_parquet(path: str) -> tuple[_FileInfo, int, int, dict[str, pa.DataType | None]]:
    try:
        pf = _parquet_file(path)
    except (OSError, pa.ArrowException) as exc:
        raise InputError(f"cannot read as Parquet: {exc}", file=path) from None
    schema = pf.schema_arrow
    info = _layout_info(path, "parquet", list(schema.names), None)
    for col in (info.depth_col, info.ci_col):
        t = schema.field(col).type
        if not _number_column_ok(t):
            raise InputError(f"column type {t} cannot hold numbers", file=path, column=col)
    types = {m: _plain_type(schema.field(m).type) for m in info.meta_cols}
    count = 0
    hsum = np.uint64(0)
    if info.id_col is None:
        if pf.metadata.num_rows:
            count = 1
            hsum = _hash_ids(np.array([info.stem], dtype=object))[0]
    else:
        prev: str | None = None
        for batch in pf.iter_batches(batch_size=_PARQUET_BLOCK_ROWS, columns=[info.id_col]):
            ids = _arrow_text(batch.column(0))
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
                hsum += _hash_ids(first).sum(dtype=np.uint64)
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


def _scan(files: list[tuple[Path, str]]) -> _Plan:
    infos: list[_FileInfo] = []
    total = 0
    hsum = 0
    meta_types: dict[str, list[pa.DataType | None]] = {}
    for path, kind in files:
        if kind == "csv":
            info, count, h, numeric = _scan_csv(str(path))
            typed = {m: (pa.float64() if ok else pa.string()) for m, ok in numeric.items()}
        else:
            info, count, h, typed = _scan_parquet(str(path))
        infos.append(info)
        total += count
        hsum = (hsum + h) % (1 << 64)
        for m, t in typed.items():
            meta_types.setdefault(m, []).append(t)
    reserved = {name for name, _ in OUTPUT_COLUMNS}
    meta: list[tuple[str, str, pa.DataType]] = []
    taken = set(reserved)
    for name, ts in meta_types.items():
        out = name
        while out.lower() in taken:
            out = "meta_" + out
        taken.add(out.lower())
        meta.append((out, name, _unify(ts)))
    return _Plan(infos, total, hsum, meta)


# ---------------------------------------------------------------------------
# reading rows
# ---------------------------------------------------------------------------


@dataclass
class _Rows:
    """A block of input rows of one file, numbers already in SI."""

    file: int
    ids: np.ndarray  # object (str), per row; CSV: raw cells (see _starts)
    depth: np.ndarray
    ci: np.ndarray
    depth_why: np.ndarray | None  # object: why a cell is unusable (None where fine)
    ci_why: np.ndarray | None
    cone: np.ndarray | None  # object (CSV: raw cells), None without a cone column
    lines: np.ndarray  # int64: file line (CSV) or 1-based data row (Parquet)
    meta: dict[str, Any]  # input name -> ndarray (CSV text) or pa.Array (Parquet)

    def __len__(self) -> int:
        return int(self.ids.size)

    def slice(self, a: int, b: int) -> _Rows:
        def cut(x: Any) -> Any:
            if x is None:
                return None
            if isinstance(x, pa.Array):
                return x.slice(a, b - a)
            return x[a:b]

        return _Rows(
            self.file,
            self.ids[a:b],
            self.depth[a:b],
            self.ci[a:b],
            cut(self.depth_why),
            cut(self.ci_why),
            cut(self.cone),
            self.lines[a:b],
            {k: cut(v) for k, v in self.meta.items()},
        )

    @staticmethod
    def concat(parts: list[_Rows]) -> _Rows:
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
        return _Rows(
            first.file,
            np.concatenate([p.ids for p in parts]),
            np.concatenate([p.depth for p in parts]),
            np.concatenate([p.ci for p in parts]),
            why("depth_why"),
            why("ci_why"),
            None if first.cone is None else np.concatenate([p.cone for p in parts]),
            np.concatenate([p.lines for p in parts]),
            {k: join([p.meta[k] for p in parts]) for k in first.meta},
        )


def _text_numbers(cells: np.ndarray, factor: float) -> tuple[np.ndarray, np.ndarray | None]:
    num = to_numbers(cells)
    why = None
    if num.bad.any():
        why = np.full(len(cells), None, dtype=object)
        for i, reason in num.reasons.items():
            why[i] = reason
    return num.values * factor, why


def _arrow_numbers(arr: pa.Array, factor: float) -> tuple[np.ndarray, np.ndarray | None]:
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    t = _plain_type(arr.type)
    if t is not None and pa.types.is_string(t):
        cells = np.array(["" if c is None else c for c in arr.to_pylist()], dtype=object)
        return _text_numbers(cells, factor)
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


def _read_file(k: int, info: _FileInfo) -> Iterator[_Rows]:
    """Blocks of rows of one input file."""
    if info.kind == "csv":
        with _CsvLines(info.path) as stream:
            header = stream.header()
            if len(header) != info.width:
                raise InputError("the header changed since the scan", file=info.path)
            col = {name: f"c{j}" for name, j in info.col_index.items()}
            for df, row0 in _csv_blocks(stream, info.width):
                n = len(df)
                if info.id_col is None:
                    ids = np.full(n, info.stem, dtype=object)
                else:
                    ids = df[col[info.id_col]].to_numpy()  # raw: stripped per profile
                depth, dwhy = _text_numbers(df[col[info.depth_col]].to_numpy(), info.depth_factor)
                ci, cwhy = _text_numbers(df[col[info.ci_col]].to_numpy(), info.ci_factor)
                cone = None if info.cone_col is None else df[col[info.cone_col]].to_numpy()
                meta = {m: df[col[m]].to_numpy() for m in info.meta_cols}
                yield _Rows(k, ids, depth, ci, dwhy, cwhy, cone, stream.lines(row0, n), meta)
    else:
        pf = _parquet_file(info.path)
        row0 = 0
        if info.id_col is None and pf.metadata.num_rows == 0:
            return
        for batch in pf.iter_batches(batch_size=_PARQUET_BLOCK_ROWS):
            n = batch.num_rows
            if n == 0:
                continue
            if info.id_col is None:
                ids = np.full(n, info.stem, dtype=object)
            else:
                ids = _arrow_text(batch.column(info.id_col)).to_numpy(zero_copy_only=False)
                ids = ids.astype(object)
            depth, dwhy = _arrow_numbers(batch.column(info.depth_col), info.depth_factor)
            ci, cwhy = _arrow_numbers(batch.column(info.ci_col), info.ci_factor)
            cone = None
            if info.cone_col is not None:
                cone = _arrow_text(batch.column(info.cone_col)).to_numpy(zero_copy_only=False)
                cone = cone.astype(object)
            meta = {m: batch.column(m) for m in info.meta_cols}
            lines = np.arange(row0 + 1, row0 + 1 + n, dtype=np.int64)
            yield _Rows(k, ids, depth, ci, dwhy, cwhy, cone, lines, meta)
            row0 += n


def _profile_blocks(plan: _Plan) -> Iterator[tuple[_Rows, np.ndarray]]:
    """(rows, profile starts) holding complete profiles only, in input order.

    The last profile of a block may continue in the next block: its rows are
    carried over, so a profile is never split.  A file ends all its profiles.
    """
    for k, info in enumerate(plan.files):
        tail: list[_Rows] = []
        for rows in _read_file(k, info):
            if tail:
                if not np.any(rows.ids != tail[0].ids[0]):  # all rows continue the tail
                    tail.append(rows)
                    continue
                rows = _Rows.concat([*tail, rows])
                tail = []
            st = _starts(rows.ids)
            last = int(st[-1])
            if last > 0:
                yield rows.slice(0, last), st[:-1]
            tail = [rows.slice(last, len(rows))]
        if tail:
            rows = _Rows.concat(tail)
            yield rows, np.zeros(1, dtype=np.int64)


# ---------------------------------------------------------------------------
# chunks: client side
# ---------------------------------------------------------------------------


@dataclass
class _Task:
    """What a worker needs to fit the fittable profiles of one chunk."""

    index: int
    ids: list[str]
    offsets: np.ndarray  # (P+1,) row offsets
    depth: np.ndarray
    ci: np.ndarray
    lines: np.ndarray
    cone_idx: np.ndarray  # (P,) index into cones
    cones: list[Cone]
    file_idx: np.ndarray  # (P,) index into files
    files: list[tuple[str, str, str, str]]  # (path, depth column, ci column, row word)


@dataclass
class _Chunk:
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
    task: _Task | None


class _ConeCache:
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


def _meta_array(values: Any, t: pa.DataType, from_csv: bool) -> pa.Array:
    """Per-profile metadata values as an Arrow array of the output type."""
    if from_csv:
        text = [str(v).strip() for v in values]
        if pa.types.is_floating(t) or pa.types.is_integer(t):
            nums = [None if not v else float(v) for v in text]
            return pa.array(nums, type=pa.float64()).cast(t)
        return pa.array(text, type=t)
    arr = values
    if pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_decode()
    if arr.type != t:
        arr = pc.cast(arr, t) if _plain_type(arr.type) is not None else pa.nulls(len(arr), t)
    return arr


@dataclass
class _Piece:
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
    rows: _Rows
    starts: np.ndarray
    meta: dict[str, pa.Array]


def _reader_errors(
    rows: _Rows,
    starts: np.ndarray,
    error: np.ndarray,
    error_row: np.ndarray,
    error_column: np.ndarray,
    flagged: np.ndarray,
) -> None:
    """Errors kept by :func:`_sc900_to_parquet` (with the file's row and column)."""

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


def _piece(rows: _Rows, starts: np.ndarray, plan: _Plan, cones: _ConeCache) -> _Piece:
    """Per-profile view of complete profiles of one file; problems found while reading."""
    info = plan.files[rows.file]
    n = len(rows)
    P = int(starts.size)
    ends = np.append(starts[1:], n)
    counts = ends - starts
    ids = _strip(rows.ids[starts])
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
        cone_name = _strip(raw_first)
        cone_obj = [cones.get(c) for c in cone_name]
        flagged |= np.array([not isinstance(c, Cone) for c in cone_obj], dtype=bool)
        changes = rows.cone != np.repeat(raw_first, counts)
        if changes.any():  # compare the differing cells again, stripped
            at = np.flatnonzero(changes)
            owner = np.searchsorted(starts, at, side="right") - 1
            changes[at] = _strip(rows.cone[at]) != cone_name[owner]
            flagged |= np.logical_or.reduceat(changes, starts)
    error = np.full(P, None, dtype=object)
    error_row = np.full(P, -1, dtype=np.int64)
    error_column = np.full(P, None, dtype=object)
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
        error[i] = str(InputError(reason, **where))
        error_row[i] = int(row)
        error_column[i] = column
    if "reader_error" in rows.meta:  # an instrument file's push rejected by its reader
        _reader_errors(rows, starts, error, error_row, error_column, flagged)
    meta: dict[str, pa.Array] = {}
    for out, name, t in plan.meta:
        if name in rows.meta:
            col = rows.meta[name]
            vals = col[starts] if isinstance(col, np.ndarray) else col.take(pa.array(starts))
            meta[out] = _meta_array(vals, t, info.kind == "csv")
        else:
            meta[out] = pa.nulls(P, t)
    return _Piece(
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
    )


def _make_chunk(index: int, pieces: list[_Piece], plan: _Plan) -> _Chunk:
    cat = np.concatenate
    fit = cat([p.fit for p in pieces])
    cone_list: list[Cone] = []
    cone_pos: dict[Cone, int] = {}
    files: list[tuple[str, str, str, str]] = []
    file_pos: dict[str, int] = {}
    t_ids: list[str] = []
    t_counts: list[np.ndarray] = []
    t_depth: list[np.ndarray] = []
    t_ci: list[np.ndarray] = []
    t_lines: list[np.ndarray] = []
    t_cone: list[int] = []
    t_file: list[int] = []
    for p in pieces:
        if not p.fit.any():
            continue
        info = plan.files[p.rows.file]
        if info.path not in file_pos:
            file_pos[info.path] = len(files)
            files.append((info.path, info.depth_col, info.ci_col, info.row_word))
        keep_rows = np.repeat(p.fit, p.counts)
        t_depth.append(p.rows.depth[keep_rows])
        t_ci.append(p.rows.ci[keep_rows])
        t_lines.append(p.rows.lines[keep_rows])
        t_counts.append(p.counts[p.fit])
        for i in np.flatnonzero(p.fit):
            c = p.cone_obj[i]
            if c not in cone_pos:
                cone_pos[c] = len(cone_list)
                cone_list.append(c)
            t_cone.append(cone_pos[c])
            t_ids.append(str(p.ids[i]))
            t_file.append(file_pos[info.path])
    task = None
    if t_ids:
        counts = cat(t_counts)
        task = _Task(
            index=index,
            ids=t_ids,
            offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            depth=cat(t_depth),
            ci=cat(t_ci),
            lines=cat(t_lines),
            cone_idx=np.asarray(t_cone, dtype=np.int64),
            cones=cone_list,
            file_idx=np.asarray(t_file, dtype=np.int64),
            files=files,
        )
    meta = {out: pa.concat_arrays([p.meta[out] for p in pieces]) for out, _, _ in plan.meta}
    return _Chunk(
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
    )


def _chunks(
    plan: _Plan, chunk_size: int, cones: _ConeCache, skip: set[int]
) -> Iterator[tuple[int, _Chunk | None, int]]:
    """(index, chunk or None when skipped, profiles) in input order."""
    pieces: list[_Piece] = []
    have = 0
    index = 0
    for rows, starts in _profile_blocks(plan):
        i = 0
        P = int(starts.size)
        n = len(rows)
        while i < P:
            take = min(chunk_size - have, P - i)
            if index not in skip:
                a = int(starts[i])
                b = int(starts[i + take]) if i + take < P else n
                sub = rows.slice(a, b)
                pieces.append(_piece(sub, starts[i : i + take] - a, plan, cones))
            have += take
            i += take
            if have == chunk_size:
                yield index, (None if index in skip else _make_chunk(index, pieces, plan)), have
                pieces, have = [], 0
                index += 1
    if have:
        yield index, (None if index in skip else _make_chunk(index, pieces, plan)), have


# ---------------------------------------------------------------------------
# fitting: worker side
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _FitSettings:
    model: str
    r_min: float | None
    plate_pair: tuple[float, float] | None
    bounds: Bounds
    ratio: float | None  # kc/kphi held fixed (calibration), else None
    units: str
    noise_floor: float = _NOISE_FLOOR
    n_grid: int = _N_GRID
    uncertainty: bool = False
    draws: int = 1000
    prior: Any = "bounds"  # "bounds" or a Calibration
    seed: int = 0
    layers: int = 1  # > 1: also fit a layered terrain per profile (terracone.layers)
    depth_ref: str = "base"  # "tip": file depths are tip depths, base = tip - H
    depth_range: tuple[float | None, float | None] = (None, None)  # base-depth window [m]


def _task_set(task: _Task | ProfileSet) -> ProfileSet:
    """A chunk's _Task as a ProfileSet (adapter until the reader makes ProfileSets; drop at merge)."""
    return (
        task
        if isinstance(task, ProfileSet)
        else ProfileSet(
            np.array(task.ids, dtype=object),
            task.offsets,
            task.depth,
            task.ci,
            task.cone_idx,
            task.cones,
            task.lines,
            task.file_idx,
            [SourceFile(*f) for f in task.files],
        )
    )  # noqa: E501


def check_fits(
    zz: np.ndarray, yy: np.ndarray, model: np.ndarray, npts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`terracone.metrics.check_fit` of each padded profile: (longest run, lack of fit).

    Through :func:`terracone.metrics.check_fit_fast` (a compiled screen,
    check_fit itself only for the profiles it may flag).
    """
    P = zz.shape[0]
    runs = np.empty(P)
    lof = np.full(P, None, dtype=object)
    for i in range(P):
        k = int(npts[i])
        chk = check_fit_fast(zz[i, :k], yy[i, :k], model[i, :k])
        runs[i] = chk.longest_run
        lof[i] = chk.lack_of_fit
    return runs, lof


def _layered_columns(out, pset: ProfileSet, results, fit: _FitSettings) -> None:
    """A layered fit per fitted profile (terracone.layers): BIC against one layer, interfaces, n's."""
    from .layers import fit_layered

    for j, res in enumerate(results):
        if not res.ok:
            continue
        prof = CIProfile(res.id, res.depth, res.ci, cone=pset.cones[int(pset.cone_idx[j])])
        try:
            lr = fit_layered(
                prof, layers=fit.layers, model=fit.model, r_min=fit.r_min, bounds=fit.bounds
            )
        except Exception as exc:  # noqa: BLE001 - recorded per profile, the rest goes on
            out["lack_of_fit_layered"][j] = f"layered fit failed: {exc}"
            continue
        if not lr.ok:
            out["lack_of_fit_layered"][j] = f"layered fit not possible: {lr.error}"
            continue
        out["bic_single"][j] = lr.bic_single
        out["bic_layered"][j] = lr.bic
        out["preferred_layers"][j] = lr.preferred_layers
        out["r2_layered"][j] = lr.r2_ci
        out["interfaces"][j] = ",".join(
            f"{float(u.length_from_si(d, fit.units)):.6g}" for d in lr.interfaces
        )
        out["n_layers"][j] = ",".join(f"{p.n:.6g}" for p in lr.layers)
        out["lack_of_fit_layered"][j] = lr.lack_of_fit


def _posterior_columns(out, pset: ProfileSet, results, fit: _FitSettings) -> None:
    """Posterior 90% intervals and identifiability labels, profile by profile (emcee)."""
    from .uncertainty import posterior_for_result

    for j, res in enumerate(results):
        if not res.ok:
            continue
        prof = CIProfile(res.id, res.depth, res.ci, cone=pset.cones[int(pset.cone_idx[j])])
        try:
            post = posterior_for_result(
                prof,
                res,
                prior=fit.prior,
                draws=fit.draws,
                seed=fit.seed,
                bounds=fit.bounds,
                plate_pair=fit.plate_pair,
            )
        except Exception as exc:  # noqa: BLE001 - recorded per profile, the rest goes on
            prev = out["lack_of_fit"][j]
            out["lack_of_fit"][j] = (prev + "; " if prev else "") + f"posterior failed: {exc}"
            continue
        d = post.as_dict(fit.units)
        for p in _UQ_PARAMS:
            lo, hi = d["intervals"][p]
            out[f"{p}_q05"][j] = lo
            out[f"{p}_q95"][j] = hi
            out[f"ident_{p}"][j] = d["identifiability"].get(p)


def _base_depths(pset: ProfileSet, fit: _FitSettings) -> ProfileSet:
    """--depth-ref tip (base = tip - H of each profile's cone), then --depth-range."""
    if fit.depth_ref == "tip":
        pset = dataclasses.replace(pset, depth=pset.depth - np.repeat(pset.heights(), pset.counts))
    lo, hi = fit.depth_range
    return pset if lo is None and hi is None else pset.window(lo, hi)


def _result_columns(results: list, fit: _FitSettings) -> dict[str, Any]:
    """The per-profile results of predict_many as batch's columns, in the output units."""
    P = len(results)
    out: dict[str, Any] = _empty_results(P)
    ok = np.array([r.ok for r in results], dtype=bool)
    good = [r for r in results if r.ok]
    n = np.array([r.params.n for r in good])
    cols = {
        "kc": u.kc_from_si(np.array([r.params.kc for r in good]), n, fit.units),
        "kphi": u.kphi_from_si(np.array([r.params.kphi for r in good]), n, fit.units),
        "n": n,
        "cc": u.pressure_from_si(np.array([r.params.cc for r in good]), fit.units),
        "phic_deg": np.array([r.params.phic_deg for r in good]),
        "phic_lo": np.array([r.phic_range[0] for r in good]),
        "phic_hi": np.array([r.phic_range[1] for r in good]),
        "n_lo": np.array([r.profile_intervals["n"][0] for r in good]),
        "n_hi": np.array([r.profile_intervals["n"][1] for r in good]),
        "rmsd": u.pressure_from_si(np.array([r.rmsd for r in good]), fit.units),
        "r2_ci": np.array([r.r2_ci for r in good]),
        "longest_run": np.array([r.longest_run for r in good], dtype=float),
        "lack_of_fit": np.array([r.lack_of_fit for r in good] + [None], dtype=object)[:-1],
    }
    for k, v in cols.items():
        out[k][ok] = v
    out["status"] = np.array([r.status for r in results] + [None], dtype=object)[:-1]
    out["error"] = np.array([r.error for r in results] + [None], dtype=object)[:-1]
    und = [";".join(r.undetermined) if r.ok else None for r in results]
    out["undetermined"] = np.array(und + [None], dtype=object)[:-1]
    return out


def _fit_chunk(task: _Task | ProfileSet, fit: _FitSettings) -> dict[str, Any]:
    """Validate and fit the profiles of a chunk (runs on a Dask worker): predict_many.

    Returns per-profile arrays in the output units: status, error,
    error_row (-1 = none), error_column, the parameters, rmsd, r2_ci,
    undetermined; and fit_time_s for the chunk.
    """
    t0 = time.perf_counter()
    c0 = time.process_time()
    pset = _base_depths(_task_set(task), fit)
    results = predict_many(
        pset,
        detail="summary",
        model=fit.model,
        r_min=fit.r_min,
        plate_pair=fit.plate_pair,
        bounds=fit.bounds,
        kc_over_kphi=fit.ratio,
        noise_floor=fit.noise_floor,
        n_grid=fit.n_grid,
        solve_many=solve_exact_many,  # looked up here: tests replace it
        chunk_size=max(len(pset), 1),
    )
    out = _result_columns(results, fit)
    error_row = np.full(len(pset), -1, dtype=np.int64)
    error_column = np.full(len(pset), None, dtype=object)
    for j, exc in screen(pset).items():  # where predict_many's invalid profiles are wrong
        error_row[j] = -1 if exc.row is None else exc.row
        error_column[j] = exc.column
    with np.errstate(all="ignore"):
        if fit.uncertainty:
            _posterior_columns(out, pset, results, fit)
        if fit.layers > 1:
            _layered_columns(out, pset, results, fit)
    lo, hi = fit.depth_range
    for j in np.flatnonzero(pset.counts == 0):  # emptied by the depth window
        out["error"][j] = str(
            InputError(
                f"no points in the depth window {lo}:{hi} m",
                file=pset.source(j).path,
                profile=pset.ids[j],
            )  # noqa: E501
        )
        error_row[j], error_column[j] = -1, None
    out.update(
        error_row=error_row,
        error_column=error_column,
        fit_time_s=time.perf_counter() - t0,
        fit_cpu_s=time.process_time() - c0,
    )
    return out


# ---------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------


def _part_name(i: int) -> str:
    return f"part-{i:06d}.parquet"


def _table(
    chunk: _Chunk,
    res: dict[str, Any] | None,
    failure: str | None,
    run_key: str,
    plan: _Plan,
    fit: _FitSettings,
) -> pa.Table:
    """The output rows of a chunk (``res``: worker results of its fitted profiles)."""
    P = int(chunk.ids.size)
    status = np.where(np.equal(chunk.error, None), "ok", "error").astype(object)
    error = chunk.error.copy()
    error_row = chunk.error_row.copy()
    error_column = chunk.error_column.copy()
    floats = _empty_results(P)
    undetermined = np.full(P, None, dtype=object)
    fit_time = 0.0
    idx = np.flatnonzero(chunk.fit)
    if failure is not None:
        for i in idx:
            status[i] = "error"
            error[i] = str(
                InputError(
                    f"chunk {chunk.index} failed on the cluster ({failure}); "
                    "rerun with resume to recompute it",
                    file=chunk.source[i],
                    profile=str(chunk.ids[i]),
                )
            )
    elif res is not None and idx.size:
        status[idx] = res["status"]
        error[idx] = res["error"]
        error_row[idx] = res["error_row"]
        error_column[idx] = res["error_column"]
        undetermined[idx] = res["undetermined"]
        for k in _RESULT_KEYS:
            floats[k][idx] = res[k]
        fit_time = float(res["fit_time_s"])
    r_min = fit.r_min
    r_min_out = None if r_min is None else float(u.length_from_si(r_min, fit.units))
    cols: dict[str, pa.Array] = {
        "profile": pa.array(chunk.ids.tolist(), pa.string()),
        "status": pa.array(status.tolist(), pa.string()),
        "error": pa.array(error.tolist(), pa.string()),
        "error_row": pa.array(error_row, pa.int64(), mask=error_row < 0),
        "error_column": pa.array(error_column.tolist(), pa.string()),
        "n_points": pa.array(chunk.counts, pa.int64()),
        "undetermined": pa.array(undetermined.tolist(), pa.string()),
        "model": pa.array([fit.model] * P, pa.string()),
        "r_min": pa.array([r_min_out] * P, pa.float64()),
        "units": pa.array([fit.units] * P, pa.string()),
        "cone": pa.array(chunk.cone.tolist(), pa.string()),
        "source": pa.array(chunk.source.tolist(), pa.string()),
        "source_row": pa.array(chunk.first_row, pa.int64()),
        "chunk": pa.array(np.full(P, chunk.index, dtype=np.int64), pa.int64()),
        "fit_time_s": pa.array(np.full(P, fit_time), pa.float64()),
    }
    for k in _FLOAT_RESULTS:
        cols[k] = pa.array(floats[k], pa.float64(), from_pandas=True)
    for k in _TEXT_RESULTS:
        cols[k] = pa.array(floats[k].tolist(), pa.string())
    schema = plan.schema
    arrays = [cols[name] for name, _ in OUTPUT_COLUMNS] + [chunk.meta[o] for o, _, _ in plan.meta]
    meta = {
        "chunk": chunk.index,
        "profiles": P,
        "failed": failure is not None,
        "run_key": run_key,
    }
    schema = schema.with_metadata({_PART_META_KEY: json.dumps(meta).encode()})
    return pa.Table.from_arrays(arrays, schema=schema)


def _write_atomic(out_dir: Path, name: str, write: Callable[[Any], None]) -> None:
    tmp = out_dir / f"{_TMP_PREFIX}{name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, out_dir / name)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _write_json(out_dir: Path, name: str, obj: Any) -> None:
    data = (json.dumps(obj, indent=2, default=json_default) + "\n").encode()
    _write_atomic(out_dir, name, lambda f: f.write(data))


def _part_meta(path: Path) -> dict[str, Any] | None:
    """The terracone metadata of a part file, or None if it is not a whole Parquet file."""
    try:
        md = pq.read_metadata(path)
        raw = (md.metadata or {}).get(_PART_META_KEY)
        if raw is None:
            return None
        meta = json.loads(raw)
        meta["num_rows"] = md.num_rows
        return meta
    except Exception:  # noqa: BLE001 - anything unreadable is "not done"
        return None


# ---------------------------------------------------------------------------
# settings, output directory, resume
# ---------------------------------------------------------------------------


def _settings(
    *,
    model: str,
    r_min: float | None,
    calibration: Calibration | None,
    bounds: Bounds,
    units: str,
    cone: Cone,
    chunk_size: int,
    uncertainty: bool = False,
    draws: int = 1000,
    prior: Any = "bounds",
    depth_ref: str = "base",
    depth_range: tuple[float | None, float | None] = (None, None),
    layers: int = 1,
) -> tuple[dict[str, Any], _FitSettings]:
    plate_pair = None
    ratio = None
    if calibration is not None:
        model = calibration.model
        r_min = calibration.r_min
        plate_pair = calibration.plate_pair
        bounds = bounds.fixed(phic=calibration.phic_deg, cc=calibration.cc)
        if calibration.kphi > 0:
            ratio = calibration.kc / calibration.kphi
    pressure_law(model, r_min=r_min, plate_pair=plate_pair)  # raises on bad settings
    prior_cal = None
    if uncertainty and prior not in (None, "bounds"):
        prior_cal = prior if isinstance(prior, Calibration) else calibration
        if prior_cal is None:
            raise ValueError("prior: give 'bounds' or a Calibration")
    fit = _FitSettings(
        model,
        r_min,
        plate_pair,
        bounds,
        ratio,
        units,
        uncertainty=uncertainty,
        draws=int(draws),
        prior=prior_cal if prior_cal is not None else "bounds",
        depth_ref=depth_ref,
        depth_range=tuple(depth_range),
        layers=int(layers),
    )
    settings = {
        "model": model,
        "r_min_m": r_min,
        "plate_pair_m": None if plate_pair is None else list(plate_pair),
        "bounds": json.loads(json.dumps(dataclasses.asdict(bounds))),
        "calibration": None if calibration is None else calibration.to_json(),
        "kc_over_kphi": ratio,
        "units": units,
        "cone": {"name": cone.name, "base_area_m2": cone.base_area, "angle_deg": cone.angle_deg},
        "chunk_size": chunk_size,
        "solver": "exact_many" + (" (kc/kphi ratio fixed)" if ratio else ""),
        "uncertainty": {
            "draws": draws,
            "prior": "calibration" if prior_cal is not None else "bounds",
        }
        if uncertainty
        else None,
        "n_grid": fit.n_grid,
        "noise_floor": fit.noise_floor,
        "terracone_version": __version__,
    }
    return json.loads(json.dumps(settings)), fit


def _diff(old: Any, new: Any, where: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for k in sorted(set(old) | set(new), key=str):
            out += _diff(old.get(k), new.get(k), f"{where}.{k}" if where else str(k))
        return out
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        out = []
        for k, (a, b) in enumerate(zip(old, new)):
            out += _diff(a, b, f"{where}[{k}]")
        return out
    if old != new:
        return [f"{where}: {old!r} -> {new!r}"]
    return []


@contextlib.contextmanager
def _lock(out_dir: Path) -> Iterator[None]:
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    path = out_dir / "_lock"
    with open(path, "a+") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError(
                f"another terracone batch is writing to {out_dir} (it holds {path})"
            ) from None
        try:
            yield
        finally:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def _is_leftover(entry: Path) -> bool:
    """A stale lock or temporary file of an interrupted run."""
    name = entry.name
    return name == "_lock" or (name.startswith(_TMP_PREFIX) and name.endswith(".tmp"))


def _prepare_out_dir(
    out_dir: Path, resume: bool, run: dict[str, Any], input_dir: Path | None
) -> bool:
    """Check OUT_DIR; returns True when resuming an earlier run."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"output {out_dir} exists and is not a directory")
    if input_dir is not None and out_dir.resolve() == input_dir.resolve():
        raise ValueError("the output directory cannot be the input directory")
    entries = list(out_dir.iterdir()) if out_dir.exists() else []
    if all(_is_leftover(e) for e in entries):  # empty, or only what a killed run leaves
        out_dir.mkdir(parents=True, exist_ok=True)
        return False
    run_file = out_dir / "_run.json"
    if not resume:
        hint = (
            "pass --resume (resume=True) to continue the run it holds"
            if run_file.exists()
            else "choose an empty or new directory"
        )
        raise ValueError(f"output directory {out_dir} is not empty; {hint}")
    if not run_file.exists():
        raise ValueError(
            f"cannot resume into {out_dir}: it is not empty and has no _run.json "
            "(not the output of terracone batch); choose an empty or new directory"
        )
    try:
        old = json.loads(run_file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"cannot resume: {run_file} is unreadable ({exc})") from exc
    problems = _diff(old.get("settings"), run["settings"], "settings")
    problems += _diff(old.get("input"), run["input"], "input")
    if problems:
        shown = "; ".join(problems[:8]) + ("; ..." if len(problems) > 8 else "")
        raise ValueError(
            f"cannot resume into {out_dir}: it holds a run with different settings or "
            f"input ({shown}); use the original settings and input, or a new directory"
        )
    return True


def _done_chunks(out_dir: Path, run_key: str, expected: dict[int, int]) -> set[int]:
    """Chunks whose part file is whole and belongs to this run; clean the rest."""
    done: set[int] = set()
    for f in out_dir.iterdir():
        if f.name.startswith(_TMP_PREFIX) and f.name.endswith(".tmp"):
            with contextlib.suppress(FileNotFoundError):
                f.unlink()  # an interrupted write
            continue
        m = _PART.match(f.name)
        if not m:
            continue
        i = int(m.group(1))
        meta = _part_meta(f)
        ok = (
            meta is not None
            and i in expected
            and meta.get("chunk") == i
            and meta.get("run_key") == run_key
            and meta.get("num_rows") == expected[i]
            and meta.get("profiles") == expected[i]
            and not meta.get("failed")
        )
        if ok:
            done.add(i)
        elif i not in expected:
            raise ValueError(
                f"cannot resume: {f} is not a chunk of this run (it has "
                f"{len(expected)} chunks); remove it or use a new directory"
            )
    return done


# ---------------------------------------------------------------------------
# the final check
# ---------------------------------------------------------------------------


def _verify(out_dir: Path, plan: _Plan, n_chunks: int, summary: BatchSummary) -> None:
    hashes = np.empty(plan.profiles, dtype=np.uint64)
    filled = 0
    ok = err = 0
    failed: list[int] = []
    missing: list[int] = []
    overflow = False
    for i in range(n_chunks):
        path = out_dir / _part_name(i)
        meta = _part_meta(path)
        if meta is None:
            missing.append(i)
            continue
        if meta.get("failed"):
            failed.append(i)
        t = pq.read_table(path, columns=["profile", "status"])
        ids = t.column("profile").to_numpy(zero_copy_only=False)
        st = t.column("status").to_numpy(zero_copy_only=False)
        ok += int(np.count_nonzero(st == "ok"))
        err += int(np.count_nonzero(st != "ok"))
        h = _hash_ids(ids)
        if filled + h.size > hashes.size:
            overflow = True
            h = h[: max(hashes.size - filled, 0)]
        hashes[filled : filled + h.size] = h
        filled += h.size
    summary.profiles_ok, summary.profiles_error = ok, err
    summary.profiles = ok + err
    summary.chunks = n_chunks
    summary.chunks_failed = len(failed)
    if missing:
        summary.problems.append(
            f"{len(missing)} chunk(s) missing from the output (first: {missing[:5]}); "
            "rerun with resume"
        )
    if failed:
        summary.problems.append(
            f"{len(failed)} chunk(s) failed on the cluster (first: {failed[:5]}); their "
            "profiles have status error; rerun with resume to recompute them"
        )
    if overflow or summary.profiles != plan.profiles:
        summary.problems.append(
            f"the output has {summary.profiles} rows but the input has {plan.profiles} profiles"
        )
    h = hashes[:filled]
    with np.errstate(over="ignore"):
        hsum = int(h.sum(dtype=np.uint64))
    if not missing and not overflow and hsum != plan.id_hash:
        summary.problems.append("the profile ids of the output differ from those of the input")
    srt = np.sort(h)
    dup_h = np.unique(srt[1:][srt[1:] == srt[:-1]])
    if dup_h.size:
        counter: Counter[str] = Counter()
        for i in range(n_chunks):
            path = out_dir / _part_name(i)
            if i in missing:
                continue
            ids = pq.read_table(path, columns=["profile"]).column(0).to_numpy(zero_copy_only=False)
            sel = np.isin(_hash_ids(ids), dup_h)
            counter.update(str(v) for v in ids[sel])
        dups = {k: c for k, c in counter.items() if c > 1}
        if dups:
            summary.n_duplicate_ids = len(dups)
            summary.duplicate_ids = dict(sorted(dups.items())[:100])
            shown = ", ".join(repr(k) for k in list(summary.duplicate_ids)[:5])
            summary.problems.append(
                f"{len(dups)} profile id(s) occur more than once in the output ({shown}"
                f"{', ...' if len(dups) > 5 else ''}): the rows of a profile must be "
                "contiguous and ids unique across files"
            )


# ---------------------------------------------------------------------------
# Dask
# ---------------------------------------------------------------------------


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def warm_kernels() -> bool:
    """Load the compiled kernels of the batch solver in this process (a Dask worker).

    Fits two tiny generated profiles, once as a small and once as a large
    group (the two refinements of :func:`~terracone.inverse.many.solve_exact_many`),
    so that numba loads the kernels from its cache (or compiles them, once
    per worker, when the cache is cold) before the first chunk.  Returns
    whether compiled kernels are in use.
    """

    if not enabled():
        return False
    from .cone import cone_index

    z = np.linspace(0.0, 0.3, 7)
    y = cone_index(z, kc=10.0, kphi=1000.0, n=0.8)
    cone, law = get_cone("asabe-large"), pressure_law("rm0")
    for P in (1, 32):
        solve_exact_many([z] * P, [y] * P, cone=cone, law=law, bounds=Bounds())
    check_fits(z[None], y[None], y[None], np.array([z.size]))
    return True


def _worker_version() -> str:
    import terracone

    return terracone.__version__


@contextlib.contextmanager
def _worker_environ(env: dict[str, str]) -> Iterator[None]:
    """Spawn local workers with ``env``: the nanny's pre-spawn environment, where
    variables already in ``os.environ`` win over the Dask configuration; the
    client's own environment is restored afterwards."""
    import dask

    saved = {k: os.environ.get(k) for k in env}
    pre = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    pre.update(env)
    try:
        os.environ.update(env)
        with dask.config.set({"distributed.nanny.pre-spawn-environ": pre}):
            yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def _dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise RuntimeError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from exc
        try:
            try:
                client.wait_for_workers(1, timeout=_WAIT_WORKERS_S)
            except TimeoutError:
                raise RuntimeError(
                    f"no Dask worker joined the scheduler {scheduler} within {_WAIT_WORKERS_S:g} s"
                ) from None
            versions = client.run(_worker_version)
            wrong = {w: v for w, v in versions.items() if v != __version__}
            if wrong:
                raise RuntimeError(
                    f"Dask workers run another terracone version than this client "
                    f"({__version__}): {wrong}"
                )
            yield client
        finally:
            client.close()
        return
    n = workers or _cpu_count()
    with _worker_environ(WORKER_MALLOC_ENV):
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},  # no warning if 8787 is taken
            silence_logs=logging.ERROR,
        )
    try:
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


# ---------------------------------------------------------------------------
# run_batch
# ---------------------------------------------------------------------------


def _resolve_calibration(calibration: Any) -> Calibration | None:
    if calibration is None or isinstance(calibration, Calibration):
        return calibration
    return Calibration.load(calibration)


def run_batch(
    input: PathLike,
    out_dir: PathLike,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    quiet: bool = False,
    model: str = "rm0",
    r_min: float | None = None,
    calibration: Calibration | PathLike | None = None,
    bounds: Bounds | str | None = None,
    units: str = "si",
    cone: str | Cone = "asabe-large",
    chunk_size: int = 2000,
    progress: bool | Callable[[int, int], None] | None = None,
    uncertainty: bool = False,
    draws: int = 1000,
    prior: str | Calibration | None = "bounds",
    depth_ref: str = "base",
    depth_range: tuple[float | None, float | None] = (None, None),
    layers: int = 1,
    format: str | None = None,
    depth_unit: str | None = None,
    ci_unit: str | None = None,
) -> BatchSummary:
    """Fit every CI profile of a file or directory; write Parquet results.

    Parameters
    ----------
    input : path
        A CSV (``.csv``, ``.csv.gz``) or Parquet (``.parquet``, ``.pq``)
        file, or a directory of them (processed in name order; names
        starting with ``.`` or ``_`` are ignored).  Columns as in
        :func:`terracone.io.read_ci_profiles`: ``depth_<m|cm|mm|in>`` (base
        depth), ``ci_<kpa|mpa|psi|pa>``, optional ``profile`` (without it a
        file is one profile named after the file), optional ``cone``; any
        other column is metadata, carried to the output (first row of each
        profile).  The rows of a profile must be contiguous.
    out_dir : path
        Output directory: new or empty, or (``resume=True``) one written by
        an earlier run with the same settings and input.
    workers : int, optional
        Worker processes of the local Dask cluster (default: all cores).
        Not allowed with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (``"tcp://HOST:PORT"``); its
        workers need this version of terracone.
    resume : bool
        Continue an interrupted run: chunks whose part file is whole are
        kept, the others are computed.
    quiet : bool
        No progress bar.
    model : {"rm0", "rm1"}
    r_min : float, optional
        RM1 transition radius [m] (SI, whatever ``units``).
    calibration : Calibration or path, optional
        Fixes model, r_min, plate pair, phic and cc, and holds kc/kphi at
        the calibrated ratio, as :func:`terracone.inverse.predict` does.
    bounds : Bounds or str, optional
        Search bounds; a string is parsed by :meth:`Bounds.parse` in ``units``.
    units : {"si", "us"}
        Units of the output parameters (and of a bounds string).
    cone : str or Cone
        Cone of the profiles of files without a ``cone`` column.
    chunk_size : int
        Profiles per chunk (one task, one part file).
    progress : bool or callable, optional
        None: a tqdm bar on stderr when it is a terminal (and not ``quiet``);
        True / False: force the bar on / off; a callable is called as
        ``progress(profiles_done, profiles_total)`` after every chunk.
    uncertainty : bool
        Also sample each fitted profile's posterior (:mod:`terracone.uncertainty`,
        about a second per profile): columns ``<p>_q05``, ``<p>_q95`` (90%
        interval, output units) and ``ident_<p>`` (identifiability label) for
        p in kc, kphi, n, cc, phic_deg.
    draws : int
        Posterior draws per profile.
    prior : "bounds" or Calibration
        Prior of the posterior; with a ``calibration`` and any other value
        than "bounds", the calibration.
    depth_ref : {"base", "tip"}
        What the input's depths measure; with "tip", base depth = tip
        depth - H of the profile's cone.
    depth_range : (lo, hi)
        Fit only base depths in [lo, hi] [m] (either may be None).
    format : {"csv", "sc900", "wide"} or None
        Input format of a single file; None detects a FieldScout SC900
        export or a wide table (:func:`terracone.io.detect_format`), each
        converted once to ``OUT_DIR/_input/<stem>.parquet``, one profile per
        push, pushes the reader rejects kept as error rows.
    depth_unit, ci_unit : str, optional
        Units of a wide table (:func:`terracone.io.read_wide_ci`); part of the
        run's settings, so a resumed run must give the same.
    layers : int
        With 2 or more, also fit a layered terrain per profile
        (:func:`terracone.layers.fit_layered`, a second or two each): columns
        ``bic_single``, ``bic_layered``, ``preferred_layers``, ``r2_layered``,
        ``interfaces`` (in the output length unit), ``n_layers``,
        ``lack_of_fit_layered``.

    Returns
    -------
    BatchSummary

    Raises
    ------
    InputError
        A file-level problem (missing file or column, unknown unit, bad CSV
        structure), found by the scan before anything is computed.
    ValueError
        Bad settings, or an output directory that cannot be used (not
        empty without ``resume``, or holding another run).
    RuntimeError
        The Dask cluster cannot be used or was lost (rerun with ``resume``).

    Notes
    -----
    With the default (local) cluster, call this from a script under
    ``if __name__ == "__main__":``: the worker processes are started with
    the ``spawn`` method, which imports the main module.
    """
    t_start = time.perf_counter()
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be >= 1 (got {chunk_size})")
    if workers is not None and scheduler:
        raise ValueError("workers applies to the local cluster; not allowed with scheduler")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1 (got {workers})")
    units = u.check_system(units)
    default_cone = get_cone(cone)
    cal = _resolve_calibration(calibration)
    if isinstance(bounds, str):
        bounds = Bounds.parse(bounds, units)
    bounds = bounds or Bounds()
    settings, fit = _settings(
        model=model,
        r_min=r_min,
        calibration=cal,
        bounds=bounds,
        units=units,
        cone=default_cone,
        chunk_size=chunk_size,
        uncertainty=uncertainty,
        draws=draws,
        prior=prior,
        depth_ref=depth_ref,
        depth_range=depth_range,
        layers=layers,
    )
    if depth_unit is not None or ci_unit is not None:  # only then: older runs keep their key
        settings["wide_units"] = {"depth_unit": depth_unit, "ci_unit": ci_unit}
    files = _input_files(input)
    fingerprint = _fingerprint(input, files)
    original_files = files
    run = _run_record(settings, fingerprint)
    run_key = run["run_key"]
    out = Path(out_dir)
    in_dir = Path(input) if Path(input).is_dir() else None
    resuming = _prepare_out_dir(out, resume, run, in_dir)
    kind = format
    if in_dir is None and format is None and files[0][1] == "csv":
        kind = detect_format(files[0][0])
    if in_dir is None and kind in ("sc900", "wide"):
        reader = {"format": kind}
        if kind == "wide":
            reader.update(depth_unit=depth_unit, ci_unit=ci_unit, depth_ref="base")
        files = [(_sc900_to_parquet(files[0][0], out, default_cone, **reader), "parquet")]
    summary = BatchSummary(out_dir=str(out), scheduler=scheduler)
    with _lock(out):
        _remove_leftovers(out)
        t0 = time.perf_counter()
        plan = _scan(files)
        summary.scan_s = time.perf_counter() - t0
        n_chunks = -(-plan.profiles // chunk_size)
        expected = {i: min(chunk_size, plan.profiles - i * chunk_size) for i in range(n_chunks)}
        run.update(profiles=plan.profiles, chunks=n_chunks)
        run["output_columns"] = plan.schema.names
        done: set[int] = set()
        if resuming:
            done = _done_chunks(out, run_key, expected)
            with contextlib.suppress(FileNotFoundError):
                (out / "_summary.json").unlink()
        else:
            run["created"] = datetime.now(UTC).isoformat(timespec="seconds")
            _write_json(out, "_run.json", run)
        summary.chunks_skipped = len(done)
        _process(
            out,
            plan,
            fit,
            run_key,
            default_cone,
            chunk_size,
            done,
            expected,
            summary,
            workers,
            scheduler,
            quiet,
            progress,
        )
        t0 = time.perf_counter()
        _verify(out, plan, n_chunks, summary)
        if _fingerprint(input, original_files) != fingerprint:
            summary.problems.append("the input files changed during the run")
        summary.verify_s = time.perf_counter() - t0
        summary.wall_s = time.perf_counter() - t_start
        computed = sum(expected[i] for i in range(n_chunks) if i not in done)
        summary.profiles_per_s = computed / summary.wall_s if summary.wall_s > 0 else 0.0
        _write_summary(out, summary, run, units)
    return summary


def _run_record(settings: dict[str, Any], fingerprint: dict[str, Any]) -> dict[str, Any]:
    """The run's identity (``_run.json``): settings and input, keyed by their hash."""
    run_key = hashlib.sha256(
        json.dumps({"settings": settings, "input": fingerprint}, sort_keys=True).encode()
    ).hexdigest()[:16]
    return {
        "terracone_batch": 1,
        "terracone_version": __version__,
        "run_key": run_key,
        "settings": settings,
        "input": fingerprint,
    }


def _remove_leftovers(out: Path) -> None:
    """Remove the temporary files of an interrupted write."""
    for e in out.iterdir():
        if e.name != "_lock" and _is_leftover(e):
            with contextlib.suppress(FileNotFoundError):
                e.unlink()


def _write_summary(out: Path, summary: BatchSummary, run: dict[str, Any], units: str) -> None:
    """``_summary.json``: the summary, the run's key, units and settings (read by report)."""
    doc = summary.as_dict()
    doc["finished"] = datetime.now(UTC).isoformat(timespec="seconds")
    doc["run_key"] = run["run_key"]
    doc["units"] = units  # read by terracone report
    doc["settings"] = run["settings"]
    doc["input"] = run["input"]["path"]
    _write_json(out, "_summary.json", doc)


def _make_bar(
    progress: bool | Callable[[int, int], None] | None, quiet: bool, total: int, initial: int
) -> tuple[Any, Callable[[int, int], None] | None]:
    if callable(progress):
        return None, progress
    show = (not quiet) and (progress if progress is not None else sys.stderr.isatty())
    if not show:
        return None, None
    from tqdm.auto import tqdm

    bar = tqdm(
        total=total,
        initial=initial,
        unit="profile",
        unit_scale=True,
        smoothing=0.1,
        dynamic_ncols=True,
        file=sys.stderr,
        desc="terracone batch",
    )
    return bar, None


def _process(
    out: Path,
    plan: _Plan,
    fit: _FitSettings,
    run_key: str,
    default_cone: Cone,
    chunk_size: int,
    done: set[int],
    expected: dict[int, int],
    summary: BatchSummary,
    workers: int | None,
    scheduler: str | None,
    quiet: bool,
    progress: bool | Callable[[int, int], None] | None,
) -> None:
    """Stream the chunks through the cluster and write the part files."""
    todo = [i for i in expected if i not in done]
    profiles_done = sum(expected[i] for i in done)
    bar, callback = _make_bar(progress, quiet, plan.profiles, profiles_done)
    if callback is not None:
        callback(profiles_done, plan.profiles)
    try:
        if not todo:
            return
        t0 = time.perf_counter()
        with _dask_client(workers, scheduler) as client:
            from distributed import as_completed

            # each worker loads (or, with a cold cache, compiles) the solver's kernels once,
            # here, counted as start-up rather than in its first chunk
            client.run(warm_kernels)
            summary.startup_s = time.perf_counter() - t0
            nthreads = sum(client.nthreads().values())
            summary.workers = nthreads
            limit = max(2, 2 * nthreads)
            token = uuid.uuid4().hex[:8]
            inflight: dict[Any, _Chunk] = {}
            ac = as_completed(loop=client.loop)

            def write(chunk: _Chunk, res: dict[str, Any] | None, failure: str | None) -> None:
                nonlocal profiles_done
                t = time.perf_counter()
                table = _table(chunk, res, failure, run_key, plan, fit)
                _write_atomic(out, _part_name(chunk.index), lambda f: pq.write_table(table, f))
                summary.write_s += time.perf_counter() - t
                summary.chunks_run += 1
                if res is not None:
                    summary.fit_s += float(res["fit_time_s"])
                    summary.fit_cpu_s += float(res["fit_cpu_s"])
                profiles_done += int(chunk.ids.size)
                if bar is not None:
                    bar.update(int(chunk.ids.size))
                if callback is not None:
                    callback(profiles_done, plan.profiles)

            def collect(fut: Any) -> None:
                chunk = inflight.pop(fut)
                if fut.status == "finished":
                    res, failure = fut.result(), None
                elif fut.status == "error":
                    exc = fut.exception()
                    res, failure = None, f"{type(exc).__name__}: {exc}"
                else:
                    raise RuntimeError(
                        f"lost the Dask cluster (chunk {chunk.index} is {fut.status}); "
                        "rerun with resume to finish"
                    )
                fut.release()
                write(chunk, res, failure)

            gen = _chunks(plan, chunk_size, _ConeCache(default_cone), done)
            while True:
                t = time.perf_counter()
                item = next(gen, None)
                summary.read_s += time.perf_counter() - t
                if item is None:
                    break
                index, chunk, _ = item
                if chunk is None:
                    continue
                if chunk.task is None:  # nothing to fit: every profile failed reading
                    write(chunk, None, None)
                    continue
                while len(inflight) >= limit:
                    collect(next(ac))
                fut = client.submit(
                    _fit_chunk,
                    chunk.task,
                    fit,
                    key=f"terracone-batch-{token}-{index:06d}",
                    pure=False,
                    retries=1,
                )
                chunk.task = None  # the worker has it; keep only what the output needs
                inflight[fut] = chunk
                ac.add(fut)
            while inflight:
                collect(next(ac))
    finally:
        if bar is not None:
            bar.close()

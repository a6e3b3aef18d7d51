"""Batch prediction: many CI profiles -> one Parquet data set, on Dask or any pool.

:func:`run_batch` scans the input (a CSV or Parquet file, an instrument
export, or a directory of them), cuts it into chunks of ``chunk_size``
profiles, fits each chunk on a worker with
:func:`terracone.inverse.predict_many` (``detail="summary"``) and
:func:`terracone.apps.workflow.attach_fits` under one
:class:`~terracone.inverse.problem.Problem` and run settings, and writes one Parquet
part file per chunk with :func:`terracone.result.result_columns` and
:func:`terracone.result.arrow_table` (the table of ``predict --parquet``).
Part files are written atomically; ``_run.json`` records the settings and the
input, ``_summary.json`` the counts and timings; every input profile gives
one row; ``resume`` finishes an interrupted run.

With the default (local) cluster, call :func:`run_batch` from a script under
``if __name__ == "__main__":`` (the workers are spawned).  The design
(chunks, streaming, atomic output, the final check) is in ``docs/batch.md``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import gc
import hashlib
import itertools
import json
import logging
import os
import re
import sys
import time
import uuid
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from terracone import __version__
from terracone.apps.workflow import Reading, attach_fits
from terracone.data import CIProfile, InputError, ProfileSet
from terracone.inverse.bounds import Bounds
from terracone.inverse.predict import RunSettings, predict_many, vectorised
from terracone.inverse.problem import Problem
from terracone.inverse.solver.many import solve_exact_many
from terracone.io import detect_format, instrument_to_parquet
from terracone.io.scan import ScanPlan, fingerprint, hash_ids, input_files, scan_inputs
from terracone.io.stream import Chunk, ConeCache, iter_chunks
from terracone.jit import enabled, warm_up_if_cold
from terracone.physics import units as u
from terracone.physics.cone import Cone, get_cone
from terracone.physics.metrics import check_fit_fast
from terracone.physics.plate import pressure_law
from terracone.result import (
    PARQUET_COLUMNS,
    RESULT_COLUMNS,
    arrow_table,
    dumps,
    empty_columns,
    result_columns,
)
from terracone.resultunits import from_si

__all__ = ["BatchSummary", "run_batch"]

PathLike = str | os.PathLike[str]

#: Seconds to wait for a worker to join an external scheduler.
_WAIT_WORKERS_S = 60.0
#: Grid over n of batch's fits (predict's is finer: N_GRID of terracone.inverse.predict).
N_GRID = 41
#: glibc malloc settings of the local cluster's worker processes.  Dask's
#: default (MALLOC_TRIM_THRESHOLD_=65536) switches off glibc's dynamic mmap
#: threshold, so every large numpy temporary of the solver is mmapped and
#: page-faulted afresh: the fit runs at half speed.  Serving everything from
#: the heap and keeping freed memory for the next chunk restores it.
WORKER_MALLOC_ENV = {"MALLOC_MMAP_MAX_": "0", "MALLOC_TRIM_THRESHOLD_": str(1 << 30)}

_PART = re.compile(r"^part-(\d{6,})\.parquet$")
_TMP_PREFIX = ".part-"
_PART_META_KEY = b"terracone_batch"
#: What a worker returns per profile: the fit columns of terracone.result.
WORKER_COLUMNS = ("status", "error", "error_row", "error_column", "undetermined", *RESULT_COLUMNS)


# ---------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------


@dataclass
class BatchSummary:
    """What :func:`run_batch` did (also written to ``OUT_DIR/_summary.json``; ``docs/batch.md``).

    Counts are over all part files (chunks of an earlier run included):
    ``profiles`` (one row each), ``profiles_ok``, ``profiles_error``,
    ``chunks``; ``chunks_run`` by this call, ``chunks_skipped`` (found whole
    on resume), ``chunks_failed`` (their profiles are error rows; resume
    recomputes them); ``duplicate_ids`` (id -> count, at most 100 listed;
    ``n_duplicate_ids`` counts all); ``problems``: run-level problems, empty
    when all is well; ``notes``: what the run left aside without a problem
    (an input file of a directory that holds no profile).  ``workers`` (threads) and ``scheduler`` (None: local
    cluster).  Seconds: ``scan_s``, ``startup_s``, ``read_s`` and
    ``write_s`` (client), ``fit_s`` and ``fit_cpu_s`` (worker-seconds and
    their CPU time, summed over chunks), ``verify_s``, ``wall_s``;
    ``profiles_per_s``: profiles computed by this call per wall second.
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
    notes: list[str] = field(default_factory=list)
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
        from terracone.notebook import batch_html

        return batch_html(self)

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["success"] = self.success
        return d


# ---------------------------------------------------------------------------
# fitting: worker side
# ---------------------------------------------------------------------------


def check_fits(
    zz: np.ndarray, yy: np.ndarray, model: np.ndarray, npts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`terracone.physics.metrics.check_fit` of each padded profile: (longest run, lack of fit).

    Through :func:`terracone.physics.metrics.check_fit_fast` (a compiled screen,
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


def _fit_chunk(
    task: ProfileSet, problem: Problem, settings: RunSettings, reading: Reading, units: str
) -> dict[str, Any]:
    """Fit the profiles of a chunk (on a worker): :data:`WORKER_COLUMNS` in ``units``.

    :func:`predict_many`, :func:`attach_fits` and
    :func:`terracone.result.result_columns`, after the depth reference and
    window of ``reading``; also ``fit_time_s`` and ``fit_cpu_s`` of the chunk.
    """
    # the fit makes ~15 objects a profile and no cycles: the cyclic collector would only
    # cost time (its passes fell at random chunks); posteriors and layered fits keep it on
    plain = not settings.uncertainty and settings.layers < 2
    with _no_gc() if plain else contextlib.nullcontext():
        return _fit_columns(task, problem, settings, reading, units)


@contextlib.contextmanager
def _no_gc() -> Iterator[None]:
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _fit_columns(
    task: ProfileSet, problem: Problem, settings: RunSettings, reading: Reading, units: str
) -> dict[str, Any]:
    t0, c0 = time.perf_counter(), time.process_time()
    pset = task
    if reading.depth_ref == "tip":
        pset = dataclasses.replace(pset, depth=pset.depth - np.repeat(pset.heights(), pset.counts))
    lo, hi = reading.depth_range
    if lo is not None or hi is not None:
        pset = pset.window(lo, hi)
    results = predict_many(pset, problem, settings, chunk_size=max(len(pset), 1))
    # the table has no columns of the layered posterior
    attach_fits(results, pset, problem, settings, layered_posterior=False)
    cols = result_columns(results, units)
    out = {k: cols[k] for k in WORKER_COLUMNS}
    for j in np.flatnonzero(pset.counts == 0):  # emptied by the depth window
        why = f"no points in the depth window {lo}:{hi} m"
        out["error"][j] = str(InputError(why, file=pset.source(j).path, profile=pset.ids[j]))
        out["error_row"][j] = out["error_column"][j] = None
    out.update(fit_time_s=time.perf_counter() - t0, fit_cpu_s=time.process_time() - c0)
    return out


# ---------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------


def _part_name(i: int) -> str:
    return f"part-{i:06d}.parquet"


def _table(chunk: Chunk, res: dict[str, Any] | None, failure: str | None, sink: _Sink) -> pa.Table:
    """The output rows of a chunk (``res``: worker results of its fitted profiles)."""
    P = int(chunk.ids.size)
    cols: dict[str, Any] = empty_columns(P)
    error_row = chunk.error_row.astype(object)
    error_row[chunk.error_row < 0] = None
    cols.update(
        status=np.where(np.equal(chunk.error, None), "ok", "error").astype(object),
        error=chunk.error.copy(),
        error_row=error_row,
        error_column=chunk.error_column.copy(),
        undetermined=np.full(P, None, dtype=object),
    )
    fit_time = 0.0
    idx = np.flatnonzero(chunk.fit)
    if failure is not None:
        for i in idx:
            cols["status"][i] = "error"
            cols["error"][i] = str(
                InputError(
                    f"chunk {chunk.index} failed on the cluster ({failure}); "
                    "rerun with resume to recompute it",
                    file=chunk.source[i],
                    profile=str(chunk.ids[i]),
                )
            )
    elif res is not None and idx.size:
        for k in WORKER_COLUMNS:
            cols[k][idx] = res[k]
        fit_time = float(res["fit_time_s"])
    pb, units = sink.job["problem"], sink.job["units"]
    r_min = from_si(pb.r_min, "length", units)
    cols.update(
        profile=pa.array(chunk.ids.tolist(), pa.string()),
        n_points=pa.array(chunk.counts, pa.int64()),
        model=[pb.model] * P,
        r_min=[r_min] * P,
        units=[units] * P,
        cone=chunk.cone,
        source=chunk.source,
        source_row=pa.array(chunk.first_row, pa.int64()),
        chunk=np.full(P, chunk.index, dtype=np.int64),
        fit_time_s=np.full(P, fit_time),
    )
    meta = {"chunk": chunk.index, "profiles": P, "failed": failure is not None}
    meta["run_key"] = sink.run_key
    return arrow_table(
        cols,
        [(o, chunk.meta[o]) for o, _, _ in sink.plan.meta],
        schema=sink.plan.schema,
        metadata={_PART_META_KEY: json.dumps(meta).encode()},
    )


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
    data = (dumps(obj) + "\n").encode()
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


def _batch_settings(problem: Problem, settings: RunSettings) -> RunSettings:
    """The settings as batch fits them: summary detail, its n grid, seeded posteriors."""
    if not vectorised(problem, settings):
        raise ValueError("batch fits with the vectorised exact solver: solver 'exact' and no Kc")
    seed = 0 if settings.seed is None else settings.seed
    return dataclasses.replace(settings, detail="summary", n_grid=N_GRID, seed=seed)


def _run_settings(
    pb: Problem, s: RunSettings, reading: Reading, units: str, cone: Cone, chunk_size: int
) -> dict[str, Any]:
    """The run's settings as ``_run.json`` records them (and resume compares them)."""
    cal = pb.anchor
    record = {
        "model": pb.model,
        "r_min_m": pb.r_min,
        "plate_pair_m": None if pb.plate_pair is None else list(pb.plate_pair),
        "bounds": dataclasses.asdict(pb.fit_bounds),
        "calibration": None if cal is None else cal.to_json(),
        "kc_over_kphi": pb.ratio,
        "units": units,
        "cone": {"name": cone.name, "base_area_m2": cone.base_area, "angle_deg": cone.angle_deg},
        "chunk_size": chunk_size,
        "solver": "exact_many" + (" (kc/kphi ratio fixed)" if pb.ratio else ""),
        "uncertainty": None,
        "n_grid": s.n_grid,
        "noise_floor": pb.noise_floor,
        "terracone_version": __version__,
    }
    if s.uncertainty:
        prior = "calibration" if pb.calibrated else "bounds"
        record["uncertainty"] = {"draws": s.draws, "prior": prior}
    # recorded only when set, so that runs written before these keys existed still resume
    wide = {"depth_unit": reading.depth_unit, "ci_unit": reading.ci_unit}
    if any(v is not None for v in wide.values()):
        record["wide_units"] = wide
    if reading.depth_ref != "base":
        record["depth_ref"] = reading.depth_ref
    if any(v is not None for v in reading.depth_range):
        record["depth_range_m"] = list(reading.depth_range)
    if s.layers > 1:
        record["layers"] = int(s.layers)
    if s.seed:
        record["seed"] = s.seed
    return json.loads(json.dumps(record))


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


def _verify(out_dir: Path, plan: ScanPlan, n_chunks: int, summary: BatchSummary) -> None:
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
        h = hash_ids(ids)
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
            sel = np.isin(hash_ids(ids), dup_h)
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


def warm_kernels(layers: int = 1) -> bool:
    """Load the compiled kernels of the batch solver in this process (a Dask worker).

    Fits two tiny generated profiles, once as a small and once as a large
    group (the two refinements of :func:`~terracone.inverse.solver.many.solve_exact_many`),
    so that numba loads the kernels from its cache before the first chunk
    (with a cold cache the worker takes the numpy paths, :mod:`terracone.jit`);
    with ``layers`` > 1 also a layered fit of that many layers (its kernels take
    about 0.6 s to load, which the first chunk of every worker would pay).
    Then moves everything loaded so far (modules, kernels) out of the cyclic
    garbage collector's way (:func:`gc.freeze`): its full collections would
    otherwise walk them every few chunks, about 50 ms each (12% of a worker's
    time at 2000 profiles per chunk).  Returns whether compiled kernels are in use.
    """
    compiled = enabled()
    if compiled:
        from terracone.physics.cone import cone_index

        z = np.linspace(0.0, 0.3, 7)
        y = cone_index(z, kc=10.0, kphi=1000.0, n=0.8)
        cone, law = get_cone("asabe-large"), pressure_law("rm0")
        for P in (1, 32):
            solve_exact_many([z] * P, [y] * P, cone=cone, law=law, bounds=Bounds())
        check_fits(z[None], y[None], y[None], np.array([z.size]))
        if layers > 1:
            from terracone.inverse.layered import fit_layered

            zl = np.linspace(0.0, 0.3, 5 * layers + 3)  # enough depths for the layers
            yl = cone_index(zl, kc=10.0, kphi=1000.0, n=0.8)
            fit_layered(CIProfile("warm", zl, yl, cone=cone), Problem(), layers=layers)
    gc.collect()
    gc.freeze()
    return compiled


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


def _check_workers(client: Any, where: str) -> None:
    """Wait for a worker of ``client`` and check that all run this terracone version."""
    try:
        client.wait_for_workers(1, timeout=_WAIT_WORKERS_S)
    except TimeoutError:
        raise RuntimeError(
            f"no Dask worker joined the scheduler {where} within {_WAIT_WORKERS_S:g} s"
        ) from None
    versions = client.run(_worker_version)
    wrong = {w: v for w, v in versions.items() if v != __version__}
    if wrong:
        raise RuntimeError(
            f"Dask workers run another terracone version than this client ({__version__}): {wrong}"
        )


@contextlib.contextmanager
def _dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A client of the scheduler at ``scheduler``, or of a local cluster of ``workers``."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise RuntimeError(f"cannot connect to the Dask scheduler {scheduler}: {exc}") from exc
        try:
            _check_workers(client, scheduler)
            yield client
        finally:
            client.close()
        return
    import dask

    # no statistical profiler in the workers: nobody reads it (no dashboard), it costs ~3%
    no_profile = dask.config.set({"distributed.worker.profile.enabled": False})
    with _worker_environ(WORKER_MALLOC_ENV), no_profile:
        cluster = LocalCluster(
            n_workers=workers or _cpu_count(),
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},  # no warning if 8787 is taken
            # the workers' own log: a worker's heartbeat racing the scheduler's close logs a
            # traceback at ERROR (seen on a loaded machine); chunk failures come back through
            # their futures, with their reason, so nothing below CRITICAL needs to reach a user
            silence_logs=logging.CRITICAL,
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
# pools: a Dask client, a concurrent.futures executor, or anything with map
# ---------------------------------------------------------------------------


def _is_dask_client(pool: Any) -> bool:
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - a required dependency
        return False
    return isinstance(pool, Client)


def _pool_size(pool: Any) -> int:
    """Workers of a pool: an executor's or multiprocessing pool's size, else 1."""
    for name in ("_max_workers", "_processes"):  # concurrent.futures, multiprocessing
        n = getattr(pool, name, None)
        if isinstance(n, int) and n > 0:
            return n
    return 1


def _fit_chunk_or_failure(task: Any, **job: Any) -> tuple[dict[str, Any] | None, str | None]:
    """Fit one chunk on a worker: ``(results, None)``, or ``(None, reason)`` when it fails.

    The task function of executor and ``map`` pools: a failure stays with its
    chunk (its profiles become error rows) instead of ending the whole map.
    """
    try:
        return _fit_chunk(task, **job), None
    except Exception as exc:  # noqa: BLE001 - reported in the chunk's rows
        return None, f"{type(exc).__name__}: {exc}"


@dataclass
class _Sink:
    """Writes the part file of each finished chunk and keeps the counts and the progress."""

    out: Path
    plan: ScanPlan
    job: dict[str, Any]  # the worker's settings, reading and units
    run_key: str
    summary: BatchSummary
    profiles_done: int
    bar: Any = None
    callback: Callable[[int, int], None] | None = None

    def write(self, chunk: Chunk, res: dict[str, Any] | None, failure: str | None) -> None:
        t = time.perf_counter()
        table = _table(chunk, res, failure, self)
        _write_atomic(self.out, _part_name(chunk.index), lambda f: pq.write_table(table, f))
        s = self.summary
        s.write_s += time.perf_counter() - t
        s.chunks_run += 1
        if res is not None:
            s.fit_s += float(res["fit_time_s"])
            s.fit_cpu_s += float(res["fit_cpu_s"])
        self.profiles_done += int(chunk.ids.size)
        if self.bar is not None:
            self.bar.update(int(chunk.ids.size))
        if self.callback is not None:
            self.callback(self.profiles_done, self.plan.profiles)


def _to_fit(chunks: Iterator[tuple[int, Chunk | None, int]], sink: _Sink) -> Iterator[Chunk]:
    """The chunks to fit, read lazily; chunks with nothing to fit are written at once."""
    while True:
        t = time.perf_counter()
        item = next(chunks, None)
        sink.summary.read_s += time.perf_counter() - t
        if item is None:
            return
        chunk = item[1]
        if chunk is None:  # done by an earlier run
            continue
        if chunk.task is None:  # nothing to fit: every profile failed reading
            sink.write(chunk, None, None)
            continue
        yield chunk


def _on_dask(client: Any, chunks: Iterator[Chunk], sink: _Sink) -> None:
    """Submit the chunks to a Dask client, at most 2 per worker thread in flight."""
    from distributed import as_completed

    t0 = time.perf_counter()
    # each worker loads (or, with a cold cache, compiles) the solver's kernels once,
    # here, counted as start-up rather than in its first chunk
    client.run(warm_kernels, sink.job["settings"].layers)
    sink.summary.startup_s += time.perf_counter() - t0
    sink.summary.workers = sum(client.nthreads().values())
    limit = max(2, 2 * sink.summary.workers)
    token = uuid.uuid4().hex[:8]
    inflight: dict[Any, Chunk] = {}
    ac = as_completed(loop=client.loop)

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
        sink.write(chunk, res, failure)

    for chunk in chunks:
        while len(inflight) >= limit:
            collect(next(ac))
        key = f"terracone-batch-{token}-{chunk.index:06d}"
        fut = client.submit(_fit_chunk, chunk.task, **sink.job, key=key, pure=False, retries=1)
        chunk.task = None  # the worker has it; keep only what the output needs
        inflight[fut] = chunk
        ac.add(fut)
    while inflight:
        collect(next(ac))


def _on_executor(executor: Executor, chunks: Iterator[Chunk], sink: _Sink) -> None:
    """Submit the chunks to a concurrent.futures executor, 2 per worker in flight."""
    sink.summary.workers = _pool_size(executor)
    limit = max(2, 2 * sink.summary.workers)
    inflight: dict[Future, Chunk] = {}

    def drain(keep: int) -> None:
        while len(inflight) > keep:
            finished, _ = wait(inflight, return_when=FIRST_COMPLETED)
            for fut in finished:
                sink.write(inflight.pop(fut), *fut.result())

    for chunk in chunks:
        drain(limit - 1)
        inflight[executor.submit(_fit_chunk_or_failure, chunk.task, **sink.job)] = chunk
        chunk.task = None
    drain(0)


def _on_map(pool: Any, chunks: Iterator[Chunk], sink: _Sink) -> None:
    """Map the chunks with ``pool.map`` (or ``pool`` itself, e.g. the built-in ``map``)
    in windows of 2 per worker, so only a window of chunks is in memory."""
    mapper = pool.map if hasattr(pool, "map") else pool
    sink.summary.workers = _pool_size(pool)
    task = functools.partial(_fit_chunk_or_failure, **sink.job)
    size = max(2, 2 * sink.summary.workers)
    while window := list(itertools.islice(chunks, size)):
        tasks = [c.task for c in window]
        for c in window:
            c.task = None
        for chunk, (res, failure) in zip(window, mapper(task, tasks), strict=True):
            sink.write(chunk, res, failure)


def _run_on(pool: Any, chunks: Iterator[Chunk], sink: _Sink) -> None:
    """Fit the chunks on the pool: the one place that knows the kinds of pool."""
    if _is_dask_client(pool):
        sink.summary.scheduler = sink.summary.scheduler or getattr(pool.scheduler, "address", None)
        _check_workers(pool, str(sink.summary.scheduler))
        _on_dask(pool, chunks, sink)
    elif isinstance(pool, Executor):
        _on_executor(pool, chunks, sink)
    else:
        _on_map(pool, chunks, sink)


# ---------------------------------------------------------------------------
# run_batch
# ---------------------------------------------------------------------------


def _check_args(chunk_size: int, workers: int | None, scheduler: str | None, pool: Any) -> None:
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be >= 1 (got {chunk_size})")
    if workers is not None and scheduler:
        raise ValueError("workers applies to the local cluster; not allowed with scheduler")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1 (got {workers})")
    if pool is not None and (workers is not None or scheduler):
        raise ValueError("give a pool, or workers / scheduler for run_batch's Dask cluster")
    if pool is not None and not (hasattr(pool, "map") or callable(pool)):
        raise ValueError(f"pool must have a map method (got {type(pool).__name__})")


def run_batch(
    input: PathLike,
    out_dir: PathLike,
    problem: Problem | None = None,
    settings: RunSettings | None = None,
    *,
    reading: Reading | None = None,
    units: str = "si",
    chunk_size: int = 2000,
    resume: bool = False,
    pool: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | Callable[[int, int], None] | None = None,
) -> BatchSummary:
    """Fit every CI profile of a file or directory; write Parquet results (``docs/batch.md``).

    Parameters
    ----------
    input : path
        A CSV (``.csv``, ``.csv.gz``) or Parquet file, an instrument export, or
        a directory of CSV and Parquet files (name order; ``.``/``_`` names
        ignored); a profile's rows contiguous.
    out_dir : path
        New or empty, or (``resume``) written by an earlier run of the same settings.
    problem : Problem, optional
        What to fit (model, r_min [m], calibration, bounds, prior); each
        worker receives it as it is.
    settings : RunSettings, optional
        What to attach (``uncertainty``, ``draws``, ``layers``).  Batch fits
        with ``detail="summary"``, a grid of :data:`N_GRID` over n and seed 0
        unless given.
    reading : Reading, optional
        The cone of files without a ``cone`` column, a single file's format,
        a wide table's units, the depth reference and window.
    units, chunk_size
        Units of the output; profiles per chunk (one task, one part file).
    resume : bool
        Keep the chunks whose part file is whole and compute the others.
    pool, workers, scheduler : optional
        Fit the chunks on ``pool`` (a Dask ``Client``, an executor, anything
        with ``map``, or ``map``; the caller closes it), or on a local Dask
        cluster of ``workers`` processes (default: all cores), or on the
        scheduler at ``scheduler`` (``"tcp://HOST:PORT"``); one of them.
    progress : bool or callable, optional
        None: a tqdm bar on a terminal; True/False: force it; a callable gets
        ``progress(profiles_done, profiles_total)`` per chunk.

    Returns
    -------
    BatchSummary

    Raises
    ------
    InputError
        A file-level problem, found by the scan before anything is computed.
    ValueError, RuntimeError
        Bad settings or an unusable output directory; a lost Dask cluster (resume).
    """
    t_start = time.perf_counter()
    _check_args(chunk_size, workers, scheduler, pool)
    units, reading = u.check_system(units), reading or Reading()
    problem = problem or Problem()
    settings = _batch_settings(problem, settings or RunSettings())
    default_cone = get_cone(reading.cone)
    files = input_files(input)
    source = fingerprint(input, files)
    record = _run_settings(problem, settings, reading, units, default_cone, chunk_size)
    run = _run_record(record, source)
    out = Path(out_dir)
    in_dir = Path(input) if Path(input).is_dir() else None
    resuming = _prepare_out_dir(out, resume, run, in_dir)
    readable = files if in_dir else _readable(files, out, reading, default_cone)
    summary = BatchSummary(out_dir=str(out), scheduler=scheduler)
    with _lock(out):
        _remove_leftovers(out)
        plan, expected, done = _begin(out, readable, run, resuming, chunk_size, summary)
        job = {"problem": problem, "settings": settings, "reading": reading, "units": units}
        sink = _Sink(out, plan, job, run["run_key"], summary, sum(expected[i] for i in done))
        chunks = iter_chunks(plan, chunk_size, ConeCache(default_cone), done)
        where = {"pool": pool, "workers": workers, "scheduler": scheduler}
        _process(sink, chunks, len(done) < len(expected), where, progress)
        changed = fingerprint(input, files) != source
        _finish(sink, expected, done, run, units, t_start, changed)
    return summary


def _readable(
    files: list[tuple[Path, str]], out: Path, reading: Reading, cone: Cone
) -> list[tuple[Path, str]]:
    """The files to read: a single SC900 export or wide table becomes Parquet once."""
    kind = reading.format
    if kind is None and files[0][1] == "csv":
        kind = detect_format(files[0][0])
    if kind not in ("sc900", "wide"):
        return files
    reader: dict[str, Any] = {"format": kind}
    if kind == "wide":
        reader.update(depth_unit=reading.depth_unit, ci_unit=reading.ci_unit, depth_ref="base")
    return [(instrument_to_parquet(files[0][0], out, cone, **reader), "parquet")]


def _begin(
    out: Path,
    files: list[tuple[Path, str]],
    run: dict[str, Any],
    resuming: bool,
    chunk_size: int,
    summary: BatchSummary,
) -> tuple[ScanPlan, dict[int, int], set[int]]:
    """Scan the input; write ``_run.json``, or find the chunks an earlier run finished.

    Returns the plan, the profiles expected per chunk and the chunks already done.
    """
    t0 = time.perf_counter()
    plan = scan_inputs(files, leading=PARQUET_COLUMNS)  # output columns first
    summary.scan_s = time.perf_counter() - t0
    if plan.profiles == 0:  # as predict: a file of a header and no data is refused
        where = files[0][0] if len(files) == 1 else files[0][0].parent
        raise InputError("no data rows: the input holds no profile", file=str(where))
    summary.notes += [f"file {f.path}: no data rows" for f in plan.files if not f.profiles]
    n_chunks = -(-plan.profiles // chunk_size)
    expected = {i: min(chunk_size, plan.profiles - i * chunk_size) for i in range(n_chunks)}
    run.update(profiles=plan.profiles, chunks=n_chunks)
    run["output_columns"] = plan.schema.names
    done: set[int] = set()
    if resuming:
        done = _done_chunks(out, run["run_key"], expected)
        with contextlib.suppress(FileNotFoundError):
            (out / "_summary.json").unlink()
    else:
        run["created"] = datetime.now(UTC).isoformat(timespec="seconds")
        _write_json(out, "_run.json", run)
    summary.chunks_skipped = len(done)
    return plan, expected, done


def _finish(
    sink: _Sink,
    expected: dict[int, int],
    done: set[int],
    run: dict[str, Any],
    units: str,
    t_start: float,
    input_changed: bool,
) -> None:
    """Check the output against the scan, time the run and write ``_summary.json``."""
    summary = sink.summary
    t0 = time.perf_counter()
    _verify(sink.out, sink.plan, len(expected), summary)
    if input_changed:
        summary.problems.append("the input files changed during the run")
    summary.verify_s = time.perf_counter() - t0
    summary.wall_s = time.perf_counter() - t_start
    computed = sum(n for i, n in expected.items() if i not in done)
    summary.profiles_per_s = computed / summary.wall_s if summary.wall_s > 0 else 0.0
    _write_summary(sink.out, summary, run, units)


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
    progress: bool | Callable[[int, int], None] | None, total: int, initial: int
) -> tuple[Any, Callable[[int, int], None] | None]:
    if callable(progress):
        return None, progress
    show = progress if progress is not None else sys.stderr.isatty()
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
    sink: _Sink,
    chunks: Iterator[tuple[int, Chunk | None, int]],
    todo: bool,
    where: dict[str, Any],
    progress: bool | Callable[[int, int], None] | None,
) -> None:
    """Stream the chunks through the pool (``where["pool"]``, or a Dask cluster of
    ``where["workers"]`` or at ``where["scheduler"]``) and write the part files."""
    total = sink.plan.profiles
    sink.bar, sink.callback = _make_bar(progress, total, sink.profiles_done)
    if sink.callback is not None:
        sink.callback(sink.profiles_done, total)
    try:
        if not todo:
            return
        # with a cold kernel cache this starts the one background warm-up (terracone.jit),
        # here rather than in every worker; the workers use numpy until it is done
        warm_up_if_cold()
        if where["pool"] is not None:
            _run_on(where["pool"], _to_fit(chunks, sink), sink)
            return
        t0 = time.perf_counter()
        with _dask_client(where["workers"], where["scheduler"]) as client:
            sink.summary.startup_s = time.perf_counter() - t0
            _on_dask(client, _to_fit(chunks, sink), sink)
    finally:
        if sink.bar is not None:
            sink.bar.close()

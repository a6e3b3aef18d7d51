"""Tests of terracone.apps.batch: streaming, Dask execution, errors, resume.

A real dask.distributed cluster (a scheduler and two worker processes on
127.0.0.1) is started once for the module; most runs use it through
``scheduler=``, one run starts its own local cluster (``workers=1``) and the
kill test runs the batch in a subprocess with its own cluster.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import distributed  # a required dependency: a broken install fails here
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from terracone import cone_index, get_cone
from terracone.apps.batch import run_batch
from terracone.apps.workflow import Reading
from terracone.data import CIProfile
from terracone.inverse.bounds import Bounds
from terracone.inverse.predict import RunSettings
from terracone.inverse.problem import Problem
from terracone.io import write_ci_profiles
from terracone.io.scan import CsvLines
from terracone.physics import units as u

H = get_cone("asabe-large").height
#: The part-file columns before the metadata, as docs/results.md lists them (a file format:
#: written out here, not taken from the code).
_Q = [f"{p}_{q}" for p in ("kc", "kphi", "n", "cc", "phic_deg") for q in ("q05", "q95")]
PART_COLUMNS = [
    *[("profile", "string"), ("status", "string"), ("error", "string")],
    *[("error_row", "int64"), ("error_column", "string")],
    *[(c, "double") for c in ("kc", "kphi", "n", "cc", "phic_deg", "phic_lo", "phic_hi")],
    *[(c, "double") for c in ("n_lo", "n_hi", "rmsd", "r2_ci", "longest_run")],
    ("lack_of_fit", "string"),
    *[(c, "double") for c in _Q],
    *[(f"ident_{p}", "string") for p in ("kc", "kphi", "n", "cc", "phic_deg")],
    *[(c, "double") for c in ("bic_single", "bic_layered", "preferred_layers", "r2_layered")],
    *[(c, "string") for c in ("interfaces", "n_layers", "lack_of_fit_layered")],
    *[("n_points", "int64"), ("undetermined", "string"), ("model", "string")],
    *[("r_min", "double"), ("units", "string"), ("cone", "string"), ("source", "string")],
    *[("source_row", "int64"), ("chunk", "int64"), ("fit_time_s", "double")],
]
#: Columns that legitimately differ between two runs of the same input.
TIMING = ["fit_time_s"]


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------


def make_profiles(n: int, seed: int = 0, prefix: str = "p") -> list[CIProfile]:
    """Noise-free profiles of known parameters, 25-60 depths, with metadata."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        nz = int(rng.integers(25, 61))
        z = np.linspace(0.0, float(rng.uniform(0.3, 0.6)), nz)
        truth = dict(
            kc=float(rng.uniform(0, 50)),
            kphi=float(rng.uniform(200, 3000)),
            n=float(rng.uniform(0.3, 1.3)),
            cc=float(rng.uniform(0, 10)),
            phic_deg=float(rng.uniform(0, 30)),
        )
        ci = cone_index(z, **truth)
        meta = {
            "site": str(rng.choice(["north", "south"])),
            "lat": round(float(rng.uniform(40, 41)), 6),
            "lon": round(float(rng.uniform(-80, -79)), 6),
            "plot": f"2018_{i}",
            "true_n": truth["n"],
        }
        out.append(CIProfile(f"{prefix}{i:04d}", z, ci, metadata=meta))
    return out


def to_frame(profiles: list[CIProfile]) -> pd.DataFrame:
    parts = []
    for p in profiles:
        d = {"profile": p.id, "cone": p.cone.name}
        d.update(p.metadata)
        df = pd.DataFrame({"depth_m": p.depth, "ci_kpa": p.ci})
        for k, v in reversed(d.items()):
            df.insert(0, k, v)
        parts.append(df)
    return pd.concat(parts, ignore_index=True)


def read_out(path: Path) -> pd.DataFrame:
    df = pd.read_parquet(path)
    return df.sort_values("profile", kind="stable").reset_index(drop=True)


def same_results(a: pd.DataFrame, b: pd.DataFrame, ignore=()) -> None:
    drop = [*TIMING, *ignore]
    pd.testing.assert_frame_equal(
        a.drop(columns=drop), b.drop(columns=drop), check_exact=True, check_like=False
    )


@pytest.fixture(scope="module")
def cluster():
    """A scheduler and two single-threaded worker processes on 127.0.0.1."""
    c = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        host="127.0.0.1",
        processes=True,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},  # no warning if 8787 is taken
        silence_logs=logging.ERROR,
    )
    try:
        yield c.scheduler_address
    finally:
        c.close()


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """80 good profiles as CSV (with comments), Parquet and a mixed directory."""
    d = tmp_path_factory.mktemp("batch_data")
    profiles = make_profiles(80)
    csv = d / "all.csv"
    write_ci_profiles(csv, profiles, comment="generated by test_batch\nknown truth")
    frame = to_frame(profiles)
    parquet = d / "all.parquet"
    frame.to_parquet(parquet, row_group_size=700)  # row groups cut through profiles
    folder = d / "folder"
    folder.mkdir()
    write_ci_profiles(folder / "a.csv", profiles[:30])
    to_frame(profiles[30:55]).to_parquet(folder / "b.parquet")
    write_ci_profiles(folder / "c.csv", profiles[55:], length_unit="cm", pressure_unit="mpa")
    (folder / "notes.txt").write_text("not an input file\n")
    return {"profiles": profiles, "csv": csv, "parquet": parquet, "folder": folder}


@pytest.fixture(scope="module")
def reference(cluster, data, tmp_path_factory):
    """The Parquet input run on the shared cluster, chunk_size 16."""
    out = tmp_path_factory.mktemp("ref") / "out"
    summary = run_batch(data["parquet"], out, scheduler=cluster, chunk_size=16, progress=False)
    return summary, out


# ---------------------------------------------------------------------------
# local cluster vs external scheduler
# ---------------------------------------------------------------------------


def test_scheduler_equals_local_run(cluster, data, reference, tmp_path):
    ref_summary, ref_out = reference
    local = run_batch(data["parquet"], tmp_path / "local", workers=1, chunk_size=16, progress=False)
    assert local.scheduler is None and local.workers == 1
    assert ref_summary.scheduler == cluster and ref_summary.workers == 2
    a, b = read_out(ref_out), read_out(tmp_path / "local")
    same_results(a, b)
    for s in (local, ref_summary):
        assert s.success, s.problems
        assert (s.profiles, s.profiles_ok, s.profiles_error) == (80, 80, 0)
        assert s.chunks == 5 and s.chunks_run == 5 and s.chunks_skipped == 0
    # one part file per chunk, whole Parquet, run files present
    parts = sorted(p.name for p in (tmp_path / "local").glob("part-*.parquet"))
    assert parts == [f"part-{i:06d}.parquet" for i in range(5)]
    run = json.loads((tmp_path / "local" / "_run.json").read_text())
    assert run["settings"]["chunk_size"] == 16 and run["profiles"] == 80
    assert {f["path"] for f in run["input"]["files"]} == {str(data["parquet"].resolve())}
    summ = json.loads((tmp_path / "local" / "_summary.json").read_text())
    assert summ["profiles"] == 80 and summ["success"] is True
    assert summ["units"] == "si" and summ["settings"] == run["settings"]
    for key in ("read_s", "fit_s", "write_s", "wall_s", "profiles_per_s"):
        assert summ[key] >= 0
    # the fits are right: noise-free data, n recovered, zero residual
    schema = pq.read_schema(tmp_path / "local" / "part-000000.parquet")
    got = [(f.name, str(f.type)) for f in schema]
    assert got[: len(PART_COLUMNS)] == PART_COLUMNS
    meta = [("site", "string"), ("lat", "double"), ("lon", "double"), ("plot", "string")]
    assert got[len(PART_COLUMNS) :] == [*meta, ("true_n", "double")]
    assert (a["status"] == "ok").all()
    np.testing.assert_allclose(a["n"], a["true_n"], rtol=0, atol=2e-3)
    assert (a["rmsd"] < 0.05).all() and (a["r2_ci"] > 0.999999).all()
    assert (a["n_lo"] <= a["n"]).all() and (a["n"] <= a["n_hi"]).all()
    assert (a["phic_lo"] <= a["phic_deg"]).all() and (a["phic_deg"] <= a["phic_hi"]).all()
    assert a["undetermined"].str.startswith("phic").all()
    assert (a["chunk"] == np.repeat(np.arange(5), 16)).all()


# ---------------------------------------------------------------------------
# any pool with map (emcee's pattern)
# ---------------------------------------------------------------------------


class PlainMap:
    """A pool that only has ``map`` (the built-in one); records the size of each call."""

    def __init__(self):
        self.calls = []

    def map(self, function, iterable):
        items = list(iterable)
        self.calls.append(len(items))
        return map(function, items)


def same_parts(a: Path, b: Path) -> None:
    """The same part files, row for row (timings aside), with the same run metadata."""
    names = sorted(p.name for p in a.glob("part-*.parquet"))
    assert names == sorted(p.name for p in b.glob("part-*.parquet")) and names
    for name in names:
        same_results(pd.read_parquet(a / name), pd.read_parquet(b / name))
        assert pq.read_schema(a / name).metadata == pq.read_schema(b / name).metadata


@pytest.mark.parametrize("kind", ["map", "threads", "client"])
def test_any_pool_gives_the_output_of_the_dask_run(cluster, data, reference, tmp_path, kind):
    from concurrent.futures import ThreadPoolExecutor

    ref_summary, ref_out = reference
    out = tmp_path / kind
    if kind == "client":  # a Dask client of the caller's, left open
        with distributed.Client(cluster, set_as_default=False) as client:
            s = run_batch(data["parquet"], out, pool=client, chunk_size=16, progress=False)
            assert client.status == "running"
        assert s.workers == 2 and s.scheduler == cluster
    elif kind == "map":
        pool = PlainMap()
        s = run_batch(data["parquet"], out, pool=pool, chunk_size=16, progress=False)
        # 5 chunks of a one-worker pool, mapped lazily in windows of 2 (memory stays flat)
        assert pool.calls == [2, 2, 1] and s.workers == 1 and s.scheduler is None
    else:
        with ThreadPoolExecutor(2) as ex:
            s = run_batch(data["parquet"], out, pool=ex, chunk_size=16, progress=False)
        assert s.workers == 2
    same_parts(ref_out, out)
    assert s.success, s.problems
    assert (s.profiles, s.profiles_ok, s.chunks_run) == (80, ref_summary.profiles_ok, 5)
    assert ref_summary.profiles_ok == 80
    run = json.loads((out / "_run.json").read_text())
    assert run["run_key"] == json.loads((ref_out / "_run.json").read_text())["run_key"]


def test_a_failing_chunk_on_a_map_pool_becomes_error_rows(data, tmp_path, monkeypatch):
    import terracone.apps.batch as batch

    second = {p.id for p in data["profiles"][16:32]}  # chunk 1 at 16 profiles a chunk

    def broken(task, **job):
        if set(task.ids) & second:
            raise MemoryError("synthetic")
        return real(task, **job)

    real = batch._fit_chunk
    monkeypatch.setattr(batch, "_fit_chunk", broken)
    s = run_batch(data["parquet"], tmp_path / "o", pool=map, chunk_size=16, progress=False)
    df = read_out(tmp_path / "o")
    bad = df["chunk"] == 1
    assert (df.loc[bad, "status"] == "error").all() and (df.loc[~bad, "status"] == "ok").all()
    assert df.loc[bad, "error"].str.contains(r"chunk 1 failed .*MemoryError: synthetic").all()
    assert s.chunks_failed == 1 and (s.profiles_ok, s.profiles_error) == (64, 16)
    assert not s.success and "rerun with resume" in s.problems[0]


def test_pool_settings_are_checked(data, tmp_path):
    with pytest.raises(ValueError, match="give a pool, or workers / scheduler"):
        run_batch(data["parquet"], tmp_path / "o", pool=map, workers=2)
    with pytest.raises(ValueError, match="pool must have a map method \\(got int\\)"):
        run_batch(data["parquet"], tmp_path / "o", pool=3)


# ---------------------------------------------------------------------------
# formats, metadata, units
# ---------------------------------------------------------------------------


def test_csv_parquet_and_directory_inputs_agree(cluster, data, reference, tmp_path):
    _, ref_out = reference
    ref = read_out(ref_out)
    s_csv = run_batch(
        data["csv"], tmp_path / "csv", scheduler=cluster, chunk_size=16, progress=False
    )
    s_dir = run_batch(
        data["folder"], tmp_path / "dir", scheduler=cluster, chunk_size=16, progress=False
    )
    assert s_csv.success and s_dir.success
    csv_out, dir_out = read_out(tmp_path / "csv"), read_out(tmp_path / "dir")
    # the numbers read back bit for bit, so the fits are identical
    same_results(ref, csv_out, ignore=["source", "source_row"])
    # a.csv and b.parquet hold the same numbers: identical fits.  c.csv is in cm
    # and MPa, so its SI values differ in the last bit, and on noise-free data
    # the optimum is flat (phic, kc, kphi trade), so only the fit quality and
    # n (identifiable) are compared there.
    same = dir_out["profile"] < "p0055"
    same_results(ref[same], dir_out[same], ignore=["source", "source_row"])
    other = dir_out[~same]
    assert (other["status"] == "ok").all() and (other["rmsd"] < 0.05).all()
    np.testing.assert_allclose(other["n"], other["true_n"], atol=2e-3)
    # source and row: CSV rows are file lines (the comment lines count), Parquet data rows
    first = csv_out.iloc[0]
    assert first["source"] == str(data["csv"].resolve()) and first["source_row"] == 4
    assert ref.iloc[0]["source_row"] == 1
    srcs = dir_out.groupby("source")["profile"].count().to_dict()
    assert {Path(k).name: v for k, v in srcs.items()} == {"a.csv": 30, "b.parquet": 25, "c.csv": 25}
    # metadata carried through, typed
    truth = {p.id: p.metadata for p in data["profiles"]}
    for out in (ref, csv_out, dir_out):
        assert out["site"].tolist() == [truth[i]["site"] for i in out["profile"]]
        assert out["plot"].tolist() == [truth[i]["plot"] for i in out["profile"]]
        np.testing.assert_array_equal(out["lat"], [truth[i]["lat"] for i in out["profile"]])
        assert out["lon"].dtype == np.float64 and pd.api.types.is_string_dtype(out["plot"])


def test_us_units(cluster, data, reference, tmp_path):
    _, ref_out = reference
    si = read_out(ref_out)
    s = run_batch(
        data["parquet"],
        tmp_path / "us",
        scheduler=cluster,
        chunk_size=16,
        units="us",
        progress=False,
    )
    assert s.success
    us = read_out(tmp_path / "us")
    assert (us["units"] == "us").all() and (si["units"] == "si").all()
    n = si["n"].to_numpy()
    np.testing.assert_allclose(us["n"], n, rtol=1e-12)
    np.testing.assert_allclose(us["kc"], u.kc_from_si(si["kc"], n, "us"), rtol=1e-9)
    np.testing.assert_allclose(us["kphi"], u.kphi_from_si(si["kphi"], n, "us"), rtol=1e-9)
    np.testing.assert_allclose(us["cc"], u.pressure_from_si(si["cc"], "us"), rtol=1e-9)
    np.testing.assert_allclose(
        us["rmsd"], u.pressure_from_si(si["rmsd"], "us"), rtol=1e-6, atol=1e-9
    )
    np.testing.assert_allclose(us["phic_deg"], si["phic_deg"], rtol=1e-12)


# ---------------------------------------------------------------------------
# corrupted input: every profile accounted for, with the right reason
# ---------------------------------------------------------------------------


def corrupted_csv(path: Path, profiles: list[CIProfile]) -> tuple[dict, set[str]]:
    """Write a CSV with bad profiles.

    Returns id -> (line, column, reason) of each bad profile, and the ids written.
    """
    header = "profile,cone,site,depth_m,ci_kpa"
    lines = ["# corrupted test input", "", header]
    expected: dict[str, tuple[int | None, str | None, str]] = {}
    written: set[str] = set()
    bad_kinds = [
        "non_numeric",
        "nan",
        "empty",
        "negative",
        "too_few",
        "not_increasing",
        "above_H",
        "unknown_cone",
        "cone_change",
        "solver",
        "empty_id",
        "infinite",
    ]
    kinds = {i * 7 + 3: k for i, k in enumerate(bad_kinds)}  # spread over the file
    for i, p in enumerate(profiles):
        kind = kinds.get(i)
        pid = "" if kind == "empty_id" else p.id
        written.add(pid)
        cone = "bogus-cone" if kind == "unknown_cone" else "asabe-large"
        z = [repr(v) for v in p.depth.tolist()]
        c = [repr(v) for v in p.ci.tolist()]
        cones = [cone] * len(z)
        k = 5  # the point that is made bad
        col, why = "ci_kpa", None
        if kind == "non_numeric":  # a quoted cell holding the separator
            c[k], why = '"12,5x"', "not a number: '12,5x'"
        elif kind == "nan":
            z[k], col, why = "nan", "depth_m", "not a finite number: 'nan'"
        elif kind == "infinite":
            c[k], why = "-inf", "not a finite number: '-inf'"
        elif kind == "empty":
            c[k], why = "", "empty cell"
        elif kind == "negative":
            c[k], why = "-5", "negative cone index -5"
        elif kind == "too_few":
            z, c, cones = z[:2], c[:2], cones[:2]
            k, why = 0, "2 points; at least 3 are needed"
        elif kind == "not_increasing":
            z[k] = z[k - 2]
            col, why = "depth_m", "depth is not strictly increasing"
        elif kind == "above_H":
            z[0] = repr(-1.5 * H)
            k, col, why = 0, "depth_m", "is above -H"
        elif kind == "unknown_cone":
            k, col, why = 0, "cone", "cone must be one of"
        elif kind == "cone_change":
            cones[k:] = ["asabe-small"] * (len(cones) - k)
            col, why = "cone", "cone changes within the profile"
        elif kind == "solver":
            # passes validate() (tolerance 1e-9) but not the cone model (1e-12)
            z[0] = repr(-H * (1 + 1e-10))
            k, col, why = 0, None, "solver failed"
        elif kind == "empty_id":
            k, col, why = 0, "profile", "empty profile id"
        for j in range(len(z)):
            if i == 10 and j == 3:
                lines.append("# a comment inside a profile")
            if i == 20 and j == 0:
                lines.append("   ")
            lines.append(f"{pid},{cones[j]},{p.metadata['site']},{z[j]},{c[j]}")
            if kind is not None and j == k:
                expected[pid] = (len(lines) if col is not None else None, col, why)
    path.write_text("\n".join(lines) + "\n")
    return expected, written


def test_corrupted_input_accounted_for(cluster, tmp_path):
    profiles = make_profiles(90, seed=3)
    src = tmp_path / "bad.csv"
    expected, ids_in = corrupted_csv(src, profiles)
    assert len(expected) >= 0.05 * len(profiles)
    s = run_batch(src, tmp_path / "out", scheduler=cluster, chunk_size=20, progress=False)
    out = pd.read_parquet(tmp_path / "out")
    assert len(out) == len(profiles) and set(out["profile"]) == ids_in
    assert s.success, s.problems
    assert (s.profiles, s.profiles_error) == (90, len(expected))
    bad = out[out["status"] == "error"].set_index("profile")
    assert set(bad.index) == set(expected)
    for pid, (line, col, why) in expected.items():
        row = bad.loc[pid]
        msg = row["error"]
        assert why in msg, (pid, msg)
        assert f"file {src.resolve()}" in msg, msg
        if pid:
            assert f"profile {pid}" in msg, msg
        if line is not None:
            assert f"row {line}" in msg, (pid, line, msg)
            assert row["error_row"] == line
        if col is not None:
            assert f"column {col}" in msg, msg
            assert row["error_column"] == col
        assert np.isnan(row["kc"]) and pd.isna(row["undetermined"])
    good = out[out["status"] == "ok"]
    assert good["error"].isna().all()
    truth = {p.id: p.metadata["true_n"] for p in profiles}
    np.testing.assert_allclose(good["n"], [truth[i] for i in good["profile"]], atol=2e-3)


def test_non_contiguous_ids_reported(cluster, tmp_path):
    profiles = make_profiles(6, seed=5)
    frame = to_frame(profiles)
    frame.loc[frame["profile"] == "p0004", "profile"] = "p0001"  # p0001 again, later
    frame.to_parquet(tmp_path / "dup.parquet")
    s = run_batch(tmp_path / "dup.parquet", tmp_path / "out", scheduler=cluster, progress=False)
    assert not s.success
    assert s.duplicate_ids == {"p0001": 2} and s.n_duplicate_ids == 1
    assert any("more than once" in p and "p0001" in p for p in s.problems)
    summ = json.loads((tmp_path / "out" / "_summary.json").read_text())
    assert summ["success"] is False and summ["duplicate_ids"] == {"p0001": 2}
    assert len(pd.read_parquet(tmp_path / "out")) == 6


def test_a_solver_failure_is_isolated_in_its_chunk(tmp_path):
    """One profile that breaks the vectorised solver does not take its chunk down."""
    from terracone.inverse.solver.many import solve_exact_many

    profiles = make_profiles(9, seed=7)
    to_frame(profiles).to_parquet(tmp_path / "in.parquet")

    def flaky(depths, cis, **kw):
        if any(d.size == profiles[4].depth.size and np.all(d == profiles[4].depth) for d in depths):
            raise FloatingPointError("synthetic failure")
        return solve_exact_many(depths, cis, **kw)

    s = run_batch(
        tmp_path / "in.parquet",
        tmp_path / "o",
        settings=RunSettings(solve_many=flaky),
        pool=map,
        progress=False,
    )
    res = read_out(tmp_path / "o")
    assert list(res["status"]) == ["ok"] * 4 + ["error"] + ["ok"] * 4
    assert "synthetic failure" in res["error"][4] and "profile p0004" in res["error"][4]
    assert s.profiles_error == 1 and s.success
    ok = np.arange(9) != 4
    np.testing.assert_allclose(res["n"][ok], res["true_n"][ok], atol=2e-3)


# ---------------------------------------------------------------------------
# kill -9 and resume
# ---------------------------------------------------------------------------


def test_kill_and_resume_equals_uninterrupted(cluster, data, tmp_path):
    out = tmp_path / "out"
    script = textwrap.dedent(
        f"""
        import time
        from terracone.apps.batch import run_batch

        def slow(done, total):
            time.sleep(0.4)  # give the test time to kill us between chunks

        if __name__ == "__main__":
            run_batch({str(data["parquet"])!r}, {str(out)!r}, workers=1, chunk_size=8,
                      progress=slow)
        """
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            parts = list(out.glob("part-*.parquet")) if out.exists() else []
            if len(parts) >= 3 or proc.poll() is not None:
                break
            time.sleep(0.02)
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
        proc.stderr.close()
        # the cluster processes of the killed run exit with it; make sure
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    parts = sorted(out.glob("part-*.parquet"))
    assert 3 <= len(parts) < 10, parts
    assert not (out / "_summary.json").exists()
    # an interrupted write and a truncated part file, as a crash may leave them
    (out / ".part-part-000009.parquet.123.abc.tmp").write_bytes(b"PAR1 half written")
    victim = parts[1]
    victim.write_bytes(victim.read_bytes()[:100])

    # refusals: without resume, with other settings, with a changed input
    with pytest.raises(ValueError, match="resume"):
        run_batch(data["parquet"], out, scheduler=cluster, chunk_size=8, progress=False)
    with pytest.raises(ValueError, match="chunk_size"):
        run_batch(
            data["parquet"], out, scheduler=cluster, chunk_size=9, resume=True, progress=False
        )
    with pytest.raises(ValueError, match="units"):
        run_batch(
            data["parquet"],
            out,
            scheduler=cluster,
            chunk_size=8,
            units="us",
            resume=True,
            progress=False,
        )

    s = run_batch(
        data["parquet"], out, scheduler=cluster, chunk_size=8, resume=True, progress=False
    )
    assert s.success, s.problems
    assert s.chunks == 10 and s.chunks_skipped == len(parts) - 1
    assert s.chunks_run == 10 - s.chunks_skipped
    assert not list(out.glob(".part-*"))
    resumed = read_out(out)
    full = tmp_path / "full"
    run_batch(data["parquet"], full, scheduler=cluster, chunk_size=8, progress=False)
    same_results(resumed, read_out(full))
    # a finished run resumes to itself without computing anything
    again = run_batch(
        data["parquet"], out, scheduler=cluster, chunk_size=8, resume=True, progress=False
    )
    assert again.chunks_run == 0 and again.chunks_skipped == 10 and again.profiles == 80

    # an input touched since the run is refused
    copy = tmp_path / "copy.parquet"
    copy.write_bytes(data["parquet"].read_bytes())
    o2 = tmp_path / "o2"
    run_batch(copy, o2, scheduler=cluster, chunk_size=40, progress=False)
    os.utime(copy, ns=(time.time_ns(), time.time_ns() + 10**9))
    with pytest.raises(ValueError, match="mtime_ns"):
        run_batch(copy, o2, scheduler=cluster, chunk_size=40, resume=True, progress=False)


# ---------------------------------------------------------------------------
# pieces
# ---------------------------------------------------------------------------


def test_csv_lines_keeps_file_line_numbers(tmp_path):
    text = "# c1\n\nprofile,depth_m\n  # c2\na,1\n\nb,2\r\n#c3\nc,3"
    p = tmp_path / "t.csv"
    p.write_bytes("\ufeff".encode() + text.encode())
    with CsvLines(str(p)) as s:
        assert s.header() == ["profile", "depth_m"] and s.header_line == 3
        body = s.read()
        assert body == b"a,1\nb,2\r\nc,3\n"
        np.testing.assert_array_equal(s.lines(0, 3), [5, 7, 9])


def test_bad_settings_and_inputs_are_refused(tmp_path, data):
    with pytest.raises(ValueError, match="r_min"):
        run_batch(data["parquet"], tmp_path / "o", Problem(model="rm1"), progress=False)
    with pytest.raises(ValueError, match="chunk_size"):
        run_batch(data["parquet"], tmp_path / "o", chunk_size=0)
    with pytest.raises(ValueError, match="units"):
        run_batch(data["parquet"], tmp_path / "o", units="imperial")
    with pytest.raises(ValueError, match="cone"):
        run_batch(data["parquet"], tmp_path / "o", reading=Reading(cone="nope"))
    with pytest.raises(ValueError, match="scheduler"):
        run_batch(data["parquet"], tmp_path / "o", workers=2, scheduler="tcp://127.0.0.1:1")
    bad = tmp_path / "bad.csv"
    bad.write_text("profile,depth_m,ci\np,0,1\n")
    with pytest.raises(ValueError, match="no unit in the column name"):
        run_batch(bad, tmp_path / "o2")
    assert not any((tmp_path / "o2").iterdir())  # nothing written: a later run may use it
    wide = tmp_path / "wide.csv"
    wide.write_text("profile,depth_m,ci_kpa\np,0,1\np,1,2,,\np,2,3,9\n")
    with pytest.raises(ValueError, match="row 4"):
        run_batch(wide, tmp_path / "o3")
    full = tmp_path / "full"
    full.mkdir()
    (full / "x").write_text("")
    with pytest.raises(ValueError, match="not empty"):
        run_batch(data["parquet"], full)
    # what a run killed before its first part leaves does not count as content
    left = tmp_path / "left"
    left.mkdir()
    (left / "_lock").write_text("")
    (left / ".part-_run.json.123.abc.tmp").write_text("{")
    with pytest.raises(ValueError, match="no unit in the column name"):  # fails in the scan
        run_batch(bad, left)
    assert not any(left.iterdir())  # the leftovers were cleaned up


def test_calibration_and_rm1_match_predict(cluster, tmp_path):
    """With a calibration batch equals the single-profile predict (same solver path)."""
    from terracone.inverse.predict import predict
    from terracone.inverse.problem import Calibration

    profiles = make_profiles(5, seed=13)
    to_frame(profiles).to_parquet(tmp_path / "in.parquet")
    cal = Calibration("test", "rm1", 0.03, (0.05, 0.1), 12.0, 2.0, 20.0, 1000.0, 0.8)
    cal_file = tmp_path / "cal.json"
    cal.save(cal_file)
    s = run_batch(
        tmp_path / "in.parquet",
        tmp_path / "cal",
        Problem(calibration=cal_file),
        scheduler=cluster,
        progress=False,
    )
    assert s.success and s.profiles_ok == 5
    out = read_out(tmp_path / "cal")
    assert (out["model"] == "rm1").all() and np.allclose(out["r_min"], 0.03)
    run = json.loads((tmp_path / "cal" / "_run.json").read_text())
    assert run["settings"]["calibration"]["terrain"] == "test"
    for p, row in zip(profiles, out.itertuples()):
        # batch runs the vectorised solver without predict's final BVLS polish and
        # without its profile intervals of kc, kphi, cc: equal to 1e-6, and no worse
        ref = predict(p, Problem(calibration=cal)).as_dict()
        for k in ("kc", "kphi", "n", "cc", "phic_deg"):
            assert getattr(row, k) == pytest.approx(ref[k], rel=1e-6, abs=1e-9), k
        assert row.rmsd == pytest.approx(ref["rmsd"], rel=1e-6, abs=1e-12)
        assert row.kc / row.kphi == pytest.approx(cal.kc / cal.kphi, rel=1e-12)
        batch_und = set(filter(None, (row.undetermined or "").split(";")))
        assert batch_und <= set(ref["undetermined"])
        assert (row.lack_of_fit is None) == (ref["lack_of_fit"] is None)
    # RM1 without a calibration: r_min [m] reported in the output units
    s = run_batch(
        tmp_path / "in.parquet",
        tmp_path / "rm1",
        Problem(model="rm1", r_min=0.0254, bounds=Bounds.parse("n=0.2:1.5", "us")),
        scheduler=cluster,
        units="us",
        progress=False,
    )
    out = read_out(tmp_path / "rm1")
    assert s.success and (out["model"] == "rm1").all()
    np.testing.assert_allclose(out["r_min"], 1.0)  # inches
    assert (out["n"] >= 0.2).all() and (out["n"] <= 1.5).all()
    assert np.isfinite(out["rmsd"]).all()  # RM0 data: RM1 need not fit them exactly


def test_a_calibration_is_held_in_batch_posteriors_whatever_the_prior(tmp_path):
    """Issue 28: with --calibration, --prior calibration and --prior bounds sample the same
    posterior (the calibration's phic, cc and kc/kphi held in every draw) and _run.json
    records the prior as "calibration" in both."""
    from terracone.inverse.problem import Calibration

    cal = Calibration("test", "rm0", None, None, 12.0, 2.0, 20.0, 1000.0, 0.8)
    z = np.linspace(0.0, 0.4, 21)
    rng = np.random.default_rng(3)
    profiles = []
    for i, kphi in enumerate((800.0, 2500.0)):
        ci = cone_index(z, kc=0.02 * kphi, kphi=kphi, n=0.7 + 0.3 * i, cc=2.0, phic_deg=12.0)
        profiles.append(CIProfile(f"c{i}", z, ci * (1 + 0.03 * rng.standard_normal(z.size))))
    to_frame(profiles).to_parquet(tmp_path / "in.parquet")
    run = RunSettings(uncertainty=True, draws=100)
    outs = {}
    for prior in ("bounds", "calibration"):
        pb = Problem(calibration=cal, prior=prior)
        s = run_batch(tmp_path / "in.parquet", tmp_path / prior, pb, run, pool=map, progress=False)
        assert s.success and s.profiles_ok == 2
        rec = json.loads((tmp_path / prior / "_run.json").read_text())["settings"]
        assert rec["uncertainty"] == {"draws": 100, "prior": "calibration"}
        outs[prior] = read_out(tmp_path / prior)
    same_results(outs["bounds"], outs["calibration"])
    out = outs["bounds"]
    assert (out["phic_deg_q05"] == 12.0).all() and (out["phic_deg_q95"] == 12.0).all()
    assert (out["cc_q05"] == 2.0).all() and (out["cc_q95"] == 2.0).all()
    np.testing.assert_allclose(out["kc_q05"], 0.02 * out["kphi_q05"], rtol=1e-9)
    np.testing.assert_allclose(out["kc_q95"], 0.02 * out["kphi_q95"], rtol=1e-9)


def test_parquet_types_and_nulls(cluster, tmp_path):
    profiles = make_profiles(5, seed=11)
    frame = to_frame(profiles)
    frame["depth_m"] = frame["depth_m"].astype(object)
    frame.loc[3, "depth_m"] = None  # profile p0000, data row 4
    frame["depth_m"] = frame["depth_m"].astype(float)
    frame["plot_no"] = np.arange(len(frame))
    frame["profile"] = frame["profile"].astype("category")
    t = pa.Table.from_pandas(frame, preserve_index=False)
    pq.write_table(t, tmp_path / "t.parquet", row_group_size=17)
    s = run_batch(tmp_path / "t.parquet", tmp_path / "o", scheduler=cluster, progress=False)
    out = read_out(tmp_path / "o")
    assert s.profiles == 5 and s.profiles_error == 1
    err = out.set_index("profile").loc["p0000"]
    assert err["error_row"] == 4 and err["error_column"] == "depth_m"
    assert "not a finite number: 'nan'" in err["error"] or "empty cell" in err["error"]
    assert out["plot_no"].dtype == np.int64


def test_uncertainty_columns_and_lack_of_fit(tmp_path):
    """--uncertainty adds 90% intervals and labels; every row says whether the model fits.

    Over 100 generated profiles (3% independent noise, uniform prior over
    the bounds) n's 90% interval covers the truth at a rate inside the
    central 99.8% window of Binomial(100, 0.9) / 100, [0.80, 0.98] (88 at this
    seed): too narrow and too wide both fail.
    """
    from scipy.stats import binom

    rng = np.random.default_rng(8)
    N = 100
    profiles = make_profiles(N, seed=8)
    for p in profiles:  # 3% noise so the posterior has something to say
        p.ci = p.ci * (1.0 + 0.03 * rng.standard_normal(p.ci.size))
    to_frame(profiles).to_parquet(tmp_path / "in.parquet")
    s = run_batch(
        tmp_path / "in.parquet",
        tmp_path / "out",
        settings=RunSettings(uncertainty=True, draws=1000),
        workers=1,
        progress=False,
    )
    assert s.success and s.profiles_ok == N
    out = read_out(tmp_path / "out")
    labels = {"determined", "weakly determined", "set by prior"}
    for row in out.itertuples():
        for p in ("kc", "kphi", "n", "cc", "phic_deg"):
            lo, hi = getattr(row, f"{p}_q05"), getattr(row, f"{p}_q95")
            assert np.isfinite(lo) and np.isfinite(hi) and lo <= hi
            assert getattr(row, f"ident_{p}") in labels
        assert np.isfinite(row.longest_run)
    # phic trades exactly against the scale of kc and kphi: the data cannot set it.  Its
    # posterior/prior width ratio is 0.86 in expectation (docs/uncertainty.md), near the 0.75
    # threshold, and estimated from 1000 draws, so a few labels may read "weakly determined"
    assert (out["ident_phic_deg"] == "set by prior").mean() >= 0.95
    assert (out["ident_phic_deg"] != "determined").all()
    lo, hi = binom.ppf(0.001, N, 0.9) / N, binom.isf(0.001, N, 0.9) / N
    assert (lo, hi) == pytest.approx((0.80, 0.98))
    covered = ((out["n_q05"] <= out["true_n"]) & (out["true_n"] <= out["n_q95"])).mean()
    assert lo <= covered <= hi, covered
    # a profile that rises then falls (a tillage pan) is flagged, with its reason
    z = np.linspace(0.0, 0.4, 21)
    ci = np.where(z < 0.15, 3000 * z / 0.15 + 100, 1200.0)
    pd.DataFrame({"profile": "pan", "depth_m": z, "ci_kpa": ci}).to_csv(
        tmp_path / "pan.csv", index=False
    )
    s = run_batch(tmp_path / "pan.csv", tmp_path / "pan", workers=1, progress=False)
    row = read_out(tmp_path / "pan").iloc[0]
    assert row.status == "ok" and "CI falls with depth" in row.lack_of_fit


def test_depth_reference_and_window(tmp_path):
    """--depth-ref tip and --depth-range act in batch as in predict (known truth)."""
    H = get_cone("asabe-large").height
    z = np.linspace(0.0, 0.4, 41)
    ci = cone_index(z, kc=30.0, kphi=3000.0, n=0.8, cc=1.0, phic_deg=12.0)
    loose = np.where(z < 0.1, 0.3 * ci, ci)  # a loose top above 10 cm
    rows = [
        pd.DataFrame({"profile": "tip", "depth_m": z + H, "ci_kpa": ci}),
        pd.DataFrame({"profile": "loose", "depth_m": z + H, "ci_kpa": loose}),
    ]
    pd.concat(rows).to_csv(tmp_path / "in.csv", index=False)
    tip = Reading(depth_ref="tip")
    run_batch(tmp_path / "in.csv", tmp_path / "tip", workers=1, progress=False, reading=tip)
    run_batch(tmp_path / "in.csv", tmp_path / "base", workers=1, progress=False)
    run_batch(
        tmp_path / "in.csv",
        tmp_path / "win",
        workers=1,
        progress=False,
        reading=Reading(depth_ref="tip", depth_range=(0.1, 0.4)),
    )
    tip, base, win = (read_out(tmp_path / d).set_index("profile") for d in ("tip", "base", "win"))
    assert tip.loc["tip", "n"] == pytest.approx(0.8, abs=1e-4)
    assert abs(base.loc["tip", "n"] - 0.8) > 0.05  # tip depths read as base depths: biased
    assert not pd.isna(tip.loc["loose", "lack_of_fit"])  # the loose top cannot be followed
    assert win.loc["loose", "n"] == pytest.approx(0.8, abs=1e-4)  # the window drops it
    assert pd.isna(win.loc["loose", "lack_of_fit"])
    far = Reading(depth_range=(2.0, 3.0))
    run_batch(tmp_path / "in.csv", tmp_path / "none", workers=1, progress=False, reading=far)
    none = read_out(tmp_path / "none")
    assert (none["status"] == "error").all()
    assert none["error"].str.contains("no points in the depth window").all()


def test_layers_columns(tmp_path):
    """--layers 2 in batch: a generated tillage-pan profile prefers two layers."""
    from terracone.data import TerrainParameters
    from terracone.physics.layers import layered_cone_index

    z = np.linspace(0.0, 0.45, 19)
    top = TerrainParameters(50.0, 8000.0, 0.4, 5.0, 12.0)
    below = TerrainParameters(20.0, 1500.0, 1.0, 0.0, 12.0)
    ci = layered_cone_index(z, [top, below], [0.15], cone=get_cone("asabe-large"))
    pd.DataFrame({"profile": "pan", "depth_m": z, "ci_kpa": ci}).to_csv(
        tmp_path / "in.csv", index=False
    )
    s = run_batch(
        tmp_path / "in.csv",
        tmp_path / "out",
        settings=RunSettings(layers=2),
        workers=1,
        progress=False,
    )
    assert s.success
    row = read_out(tmp_path / "out").iloc[0]
    assert row.preferred_layers == 2 and row.bic_layered < row.bic_single
    assert float(row.interfaces) == pytest.approx(0.15, abs=0.025)
    n1, n2 = (float(v) for v in row.n_layers.split(","))
    assert n1 == pytest.approx(0.4, abs=0.05) and n2 == pytest.approx(1.0, abs=0.05)
    assert not pd.isna(row.lack_of_fit) and pd.isna(row.lack_of_fit_layered)


def test_sc900_export_in_batch(tmp_path):
    """An SC900 export is detected and every push is accounted for (83 pushes, by hand)."""
    from conftest import require_shared

    path = require_shared("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")
    window = Reading(depth_range=(0.15, 0.45))
    s = run_batch(path, tmp_path / "out", workers=1, progress=False, reading=window)
    out = read_out(tmp_path / "out")
    assert len(out) == 83 and out["profile"].is_unique
    # two pushes stopped (trailing zeros) too shallow to leave 3 readings from 15 cm down
    bad = set(out.loc[out.status == "error", "profile"])
    assert bad == {"sc900_export_2019-06-11/0001-N1", "sc900_export_2019-06-11/0009-N7"}
    assert s.profiles_ok == 81 and (out["cone"] == "asabe-small").all()
    assert (tmp_path / "out" / "_input" / "sc900_export_2019-06-11.parquet").exists()


def test_resume_refuses_other_depth_options(data, tmp_path):
    # a resumed run must fit with the depth window, reference and layers of the first one
    out = tmp_path / "o"
    kw = dict(pool=map, chunk_size=40, progress=False)
    run_batch(data["parquet"], out, reading=Reading(depth_range=(0.0, 0.3)), **kw)
    run = json.loads((out / "_run.json").read_text())
    assert run["settings"]["depth_range_m"] == [0.0, 0.3]
    assert "depth_ref" not in run["settings"] and "layers" not in run["settings"]
    with pytest.raises(ValueError, match="depth_range_m"):
        run_batch(data["parquet"], out, reading=Reading(depth_range=(0.0, 0.2)), resume=True, **kw)
    with pytest.raises(ValueError, match="depth_ref"):
        tip = Reading(depth_range=(0.0, 0.3), depth_ref="tip")
        run_batch(data["parquet"], out, reading=tip, resume=True, **kw)
    s = run_batch(data["parquet"], out, reading=Reading(depth_range=(0.0, 0.3)), resume=True, **kw)
    assert s.profiles == 80

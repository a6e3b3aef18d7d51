"""Commands end to end through the command line: batch, report, library import/export.

Each test runs ``terracone ...`` (click's CliRunner, in process) on files
generated here with known truth and checks what the command wrote: Parquet
rows, HTML tables, JSON exports, exit statuses and messages.
"""

from __future__ import annotations

import json
import logging
import re
from html.parser import HTMLParser
from pathlib import Path

import distributed
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.physics.cone import cone_index

Z_CM = np.arange(0.0, 31.0, 2.0)  # 16 readings a profile
TRUTH = {  # noise-free profiles: n is recovered to the solver's precision
    "P0": dict(kc=20.0, kphi=3000.0, n=0.6, cc=2.0, phic_deg=15.0),
    "P1": dict(kc=40.0, kphi=1500.0, n=0.9, cc=1.0, phic_deg=20.0),
    "P2": dict(kc=10.0, kphi=5000.0, n=0.7, cc=3.0, phic_deg=10.0),
    "P3": dict(kc=60.0, kphi=2500.0, n=1.1, cc=0.5, phic_deg=25.0),
    "P4": dict(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=18.0),
}


def run(*args, env=None):
    return CliRunner().invoke(cli, [str(a) for a in args], env=env)


def profile_lines(pid: str) -> list[str]:
    ci = cone_index(Z_CM * 0.01, **TRUTH[pid])
    return [f"{pid},{z:g},{float(c)!r}" for z, c in zip(Z_CM, ci)]


def write_profiles(path: Path, ids, *, bad_line: int | None = None) -> Path:
    """Profiles in file order; ``bad_line`` (1-based file line) gets ci 'x!'."""
    lines = ["profile,depth_cm,ci_kpa"]
    for pid in ids:
        lines += profile_lines(pid)
    if bad_line is not None:
        pid, z, _ = lines[bad_line - 1].split(",")
        lines[bad_line - 1] = f"{pid},{z},x!"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def scheduler():
    """One single-threaded Dask worker process, shared by the batch runs here."""
    c = distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        host="127.0.0.1",
        processes=True,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
        silence_logs=logging.ERROR,
    )
    try:
        yield c.scheduler_address
    finally:
        c.close()


def read_out(out: Path) -> pd.DataFrame:
    return pd.read_parquet(out).sort_values("profile").reset_index(drop=True)


SUMMARY = re.compile(
    r"(\d+) profiles: (\d+) fitted, (\d+) with errors \(\d+ profiles/s, [0-9.]+ s\); results in (.+)"
)


# ---------------------------------------------------------------------------
# batch
# ---------------------------------------------------------------------------


def test_batch_with_a_bad_profile_then_resume(tmp_path, scheduler):
    # P2's 16 rows are file lines 34-49; line 37 (its depth 6 cm) is not a number
    src = write_profiles(tmp_path / "five.csv", list(TRUTH), bad_line=37)
    out = tmp_path / "out"
    args = ["batch", src, "--out", out, "--scheduler", scheduler, "--chunk-size", "2", "--quiet"]
    r = run(*args)
    # error profiles are normal: the run succeeds, and says how many failed
    assert r.exit_code == 0, r.output
    m = SUMMARY.fullmatch(r.stdout.strip())
    assert m and m.groups() == ("5", "4", "1", str(out)), r.stdout
    assert r.stderr == ""
    df = read_out(out)
    assert list(df["profile"]) == list(TRUTH)
    assert list(df["status"]) == ["ok", "ok", "error", "ok", "ok"]
    bad = df.iloc[2]
    assert (
        bad["error"]
        == f"file {src.resolve()}, profile P2, row 37, column ci_kpa: not a number: 'x!'"
    )
    assert bad["error_row"] == 37 and bad["error_column"] == "ci_kpa"
    assert np.isnan(bad["n"])
    for _, row in df[df["status"] == "ok"].iterrows():
        t = TRUTH[row["profile"]]
        assert row["n"] == pytest.approx(t["n"], abs=1e-3), row["profile"]
        assert row["rmsd"] < 1e-3 * float(np.mean(cone_index(Z_CM * 0.01, **t)))
        assert row["n_points"] == 16 and row["units"] == "si"
    summary = json.loads((out / "_summary.json").read_text())
    assert (summary["profiles"], summary["profiles_ok"], summary["profiles_error"]) == (5, 4, 1)
    assert summary["chunks"] == 3 and summary["success"] is True
    first = df

    # the same command again is refused: the directory is not empty
    r = run(*args)
    assert r.exit_code == 1
    assert f"Error: output directory {out} is not empty" in r.output

    # a lost part file: --resume recomputes that chunk only, with the same result
    (out / "part-000001.parquet").unlink()
    r = run(*args, "--resume")
    assert r.exit_code == 0, r.output
    assert SUMMARY.fullmatch(r.stdout.strip()).groups() == ("5", "4", "1", str(out))
    summary = json.loads((out / "_summary.json").read_text())
    assert (summary["chunks_skipped"], summary["chunks_run"]) == (2, 1)
    again = read_out(out)
    pd.testing.assert_frame_equal(
        again.drop(columns=["fit_time_s"]), first.drop(columns=["fit_time_s"]), check_exact=True
    )
    # a resume with other settings is refused, naming what differs
    r = run(*args, "--resume", "--units", "us")
    assert r.exit_code == 1 and "units" in r.output and "internal error" not in r.output


def test_batch_exit_status_when_nothing_is_fitted(tmp_path, scheduler):
    src = write_profiles(tmp_path / "one.csv", ["P0"], bad_line=5)
    out = tmp_path / "out"
    r = run("batch", src, "--out", out, "--scheduler", scheduler, "--quiet")
    assert r.exit_code == 1
    assert SUMMARY.fullmatch(r.stdout.strip()).groups() == ("1", "0", "1", str(out))
    assert r.stderr.strip() == "terracone: no profile could be fitted (see the error column)"
    assert read_out(out)["error"][0].endswith(
        "profile P0, row 5, column ci_kpa: not a number: 'x!'"
    )


def test_batch_exit_status_with_a_run_level_problem(tmp_path, scheduler):
    # P0's rows are not contiguous (P0, P1, P0): two profiles P0 in the output
    src = tmp_path / "split.csv"
    lines = ["profile,depth_cm,ci_kpa"] + profile_lines("P0")[:8] + profile_lines("P1")
    lines += profile_lines("P0")[8:]
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    r = run("batch", src, "--out", out, "--scheduler", scheduler, "--quiet")
    assert r.exit_code == 1
    assert r.stderr.startswith(
        "terracone: 1 profile id(s) occur more than once in the output ('P0'): "
        "the rows of a profile must be contiguous"
    ), r.stderr
    assert json.loads((out / "_summary.json").read_text())["duplicate_ids"] == {"P0": 2}


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------


class _Tables(HTMLParser):
    """Rows (lists of cell texts) of each table, by the id of its block."""

    def __init__(self):
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self._block = None
        self._row = None
        self._cell = None
        self.external: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for key in ("src", "href"):
            v = a.get(key)
            if v and not v.startswith(("data:", "#")):
                self.external.append(v)
        if tag == "div" and (a.get("id") or "").startswith("tbl-"):
            self._block = a["id"][4:]
            self.tables[self._block] = []
        elif tag == "tr" and self._block:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = ""

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables[self._block].append(self._row)
            self._row = None
        elif tag == "table":
            self._block = None


def parse_html(path: Path) -> _Tables:
    p = _Tables()
    p.feed(path.read_text())
    return p


def test_report_of_a_predict_run(tmp_path):
    src = write_profiles(tmp_path / "two.csv", ["P1", "P3"])
    pj = tmp_path / "predict.json"
    r = run("predict", src, "--json", "--out", pj)
    assert r.exit_code == 0, r.output
    html = tmp_path / "report.html"
    r = run("report", pj, "--out", html)
    assert r.exit_code == 0, r.output
    assert r.output.strip() == f"wrote {html}"
    doc = parse_html(html)
    assert doc.external == []  # self-contained
    rows = {row[0]: row for row in doc.tables["parameters"] if row and row[0] in ("P1", "P3")}
    assert sorted(rows) == ["P1", "P3"]
    for p in json.loads(pj.read_text())["profiles"]:
        cells = rows[p["id"]]
        # Profile, kc [SI, US], kphi [SI, US], n, cc [SI, US], phic: five significant digits
        for cell, key in zip(
            [cells[1], cells[3], cells[5], cells[6], cells[8]],
            ["kc", "kphi", "n", "cc", "phic_deg"],
        ):
            assert float(cell) == pytest.approx(p[key], rel=1e-4, abs=1e-9), (p["id"], key)
    assert "<img" in html.read_text()


def test_report_of_a_batch_directory(tmp_path, scheduler):
    src = write_profiles(tmp_path / "three.csv", ["P0", "P1", "P4"], bad_line=20)
    out = tmp_path / "out"
    assert run("batch", src, "--out", out, "--scheduler", scheduler, "--quiet").exit_code == 0
    html = tmp_path / "batch.html"
    r = run("report", out, "--out", html)
    assert r.exit_code == 0, r.output
    text = html.read_text()
    assert "terracone report: batch prediction" in text
    doc = parse_html(html)
    assert doc.external == []
    cells = {c for rows in doc.tables.values() for row in rows for c in row}
    df = read_out(out)
    for _, row in df.iterrows():
        assert row["profile"] in cells
    assert "P1" in df.loc[df["status"] == "error", "profile"].tolist()  # line 20 is P1's


# ---------------------------------------------------------------------------
# library export and import
# ---------------------------------------------------------------------------


def test_library_export_then_import_elsewhere(tmp_path):
    one, two = tmp_path / "one.sqlite", tmp_path / "two.sqlite"
    r = run(
        "library", "--library", one, "add", "site-A", "--param", "kc=12.5", "--param", "kphi=800",
        "--param", "n=0.9", "--source", "survey 2024",
    )  # fmt: skip
    assert r.exit_code == 0 and r.output.strip() == "added 'site-A' (user)"
    r = run(
        "library", "--library", one, "add", "site-B", "--kind", "calibration", "--param", "n=1.1"
    )
    assert r.exit_code == 0, r.output
    dump = tmp_path / "mine.json"
    r = run("library", "--library", one, "export", dump)
    assert r.exit_code == 0 and r.output.strip() == f"exported 2 terrains to {dump}"
    recs = {d["name"]: d for d in json.loads(dump.read_text())}
    assert sorted(recs) == ["site-A", "site-B"]
    assert recs["site-A"]["params"] == {"kc": 12.5, "kphi": 800.0, "n": 0.9}
    assert recs["site-A"]["kind"] == "user" and recs["site-B"]["kind"] == "calibration"
    # into another library: both arrive with their values, kinds and provenance
    r = run("library", "--library", two, "import", dump)
    assert r.exit_code == 0 and r.stdout.strip() == "imported 2, skipped 0"
    for name in ("site-A", "site-B"):
        r = run("library", "--library", two, "show", name)
        assert r.exit_code == 0, r.output
        shown = json.loads(r.stdout)
        for key in ("name", "kind", "params", "provenance", "notes"):
            assert shown[key] == recs[name][key], (name, key)
    # the same file again: identical records are skipped, each with its reason
    r = run("library", "--library", two, "import", dump)
    assert r.exit_code == 0 and r.stdout.strip() == "imported 0, skipped 2"
    assert r.stderr.count("skipped") == 2
    # an export with the packaged references: those are skipped on import
    full = tmp_path / "full.json"
    r = run("library", "--library", one, "export", full, "--include-builtin")
    n_all = len(json.loads(full.read_text()))
    assert r.exit_code == 0 and r.output.strip() == f"exported {n_all} terrains to {full}"
    assert n_all == 2 + 21  # the 21 rows of Wong's table
    three = tmp_path / "three.sqlite"
    r = run("library", "--library", three, "import", full)
    assert r.exit_code == 0 and r.stdout.strip() == "imported 2, skipped 21"
    assert r.stderr.count("packaged reference terrain") == 21
    # a record of a taken name with other values is refused unless --replace
    recs["site-A"]["params"]["kc"] = 99.0
    changed = tmp_path / "changed.json"
    changed.write_text(json.dumps([recs["site-A"]]))
    r = run("library", "--library", two, "import", changed)
    assert r.exit_code == 1 and "site-A" in r.output and "internal error" not in r.output
    r = run("library", "--library", two, "import", changed, "--replace")
    assert r.exit_code == 0 and r.stdout.strip() == "imported 1, skipped 0"
    r = run("library", "--library", two, "show", "site-A")
    assert json.loads(r.stdout)["params"]["kc"] == 99.0

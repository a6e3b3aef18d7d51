"""`terracone reproduce --quick`: the paper's case studies on synthetic data, end to end."""

from __future__ import annotations

import json
import math
import re
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest
from chromium import browser_check
from click.testing import CliRunner
from conftest import require_chromium
from PIL import Image

from terracone.apps.reproduce import KRC_FORCE_LIMIT, WONG_LETE, reproduce
from terracone.apps.reproduce.paper import published_agreement, published_parameters
from terracone.apps.reproduce.run import DATA_HEADER, prepare_output
from terracone.cli import cli
from terracone.io import read_ci_profiles, read_plate_tests
from terracone.physics import units as u
from terracone.report import build_report


@pytest.fixture(scope="module")
def pool():
    """Records the ``map`` calls of the process pool that `terracone reproduce` opens."""
    recorder = SimpleNamespace(calls=[])

    class Executor(ProcessPoolExecutor):
        def map(self, fn, *iterables, **kwargs):
            tasks = list(iterables[0])
            recorder.calls.append(len(tasks))
            return super().map(fn, tasks, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("terracone.apps.reproduce.pool.ProcessPoolExecutor", Executor)
        yield recorder


@pytest.fixture(scope="module")
def run(tmp_path_factory, pool):
    """`terracone reproduce --quick --out DIR`, through the command line, and what it wrote."""
    out = tmp_path_factory.mktemp("reproduce") / "run"
    r = CliRunner().invoke(cli, ["reproduce", "--quick", "--workers", "2", "--out", str(out)])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0] == f"report: {out / 'report.html'}"
    assert re.fullmatch(rf"figures and tables in {re.escape(str(out))} \(\d+ s\)", lines[1])
    assert len(lines) == 2, r.output
    results = out / "results"
    return SimpleNamespace(
        out_dir=out,
        report=out / "report.html",
        manifest=json.loads((out / "reproduce.json").read_text()),
        lete_learned=json.loads((results / "lete_calibration.json").read_text()),
        krc_learned={
            p.stem.removeprefix("krc_calibration_"): json.loads(p.read_text())
            for p in sorted(results.glob("krc_calibration_*.json"))
        },
    )


EXPECTED_FIGURES = [
    "fig_2_1_lete_janosi",
    "fig_4_1_lete_ci",
    "fig_4_2_lete_plates",
    "fig_4_2_lete_plates_ci_only",
    "ridge_lete_LS_1",
    "fig_4_3_krc_1",
    "fig_4_5_krc_3",
]
EXPECTED_TABLES = [
    "table_4_1_lete_parameters",
    "table_4_1_lete_vs_published",
    "table_4_2_lete_agreement",
    "table_4_2_lete_vs_published",
    "table_4_2_lete_ci_only",
    "table_4_3_krc_parameters",
    "table_4_3_krc_vs_published",
    "table_4_4_krc_agreement",
    "table_4_4_krc_vs_published",
    "lete_identifiability",
    "krc_identifiability",
    "summary_ours_vs_published",
]


def test_writes_figures_tables_report_all_labelled_synthetic(run):
    root = run.out_dir
    assert run.report == root / "report.html" and run.report.exists()
    for key in EXPECTED_FIGURES:
        png, svg = root / "figures" / f"{key}.png", root / "figures" / f"{key}.svg"
        assert png.exists() and svg.exists(), key
        with Image.open(png) as im:
            assert im.size[0] > 400
            assert "SYNTHETIC" in im.info.get("Title", "")
        assert "SYNTHETIC" in svg.read_text()
    for key in EXPECTED_TABLES:
        csv = root / "tables" / f"{key}.csv"
        assert csv.exists(), key
        text = csv.read_text()
        assert text.startswith("# SYNTHETIC"), key
        assert len(pd.read_csv(csv, comment="#")) >= 1
        assert "SYNTHETIC" in (root / "tables" / f"{key}.html").read_text()
    for f in (root / "data").glob("*.csv"):
        assert "SYNTHETIC" in f.read_text().splitlines()[0]
    for f in (root / "results").glob("*.json"):
        d = json.loads(f.read_text())
        assert d.get("synthetic") is True or "SYNTHETIC" in json.dumps(d), f
    html = run.report.read_text()
    assert "SYNTHETIC DATA" in html
    assert run.manifest["kind"] == "terracone-reproduce"
    assert run.manifest["quick"] is True and run.manifest["synthetic"] is True
    assert sorted(run.krc_learned) == ["KRC_1", "KRC_3"]  # quick: two KRC sites


def test_lete_learning_recovers_n(run):
    # the plates were generated with Wong's n = 0.79; the CI from Table 4-1 (n 0.56-0.74)
    assert run.lete_learned["n"] == pytest.approx(WONG_LETE["n"], abs=0.05)
    assert run.lete_learned["kphi"] == pytest.approx(WONG_LETE["kphi"], rel=0.25)
    # KRC: CI and plates from one parameter set, so learning recovers it
    pub = {p["id"]: p for p in published_parameters("4-3")}
    for site, p in run.krc_learned.items():
        assert p["n"] == pytest.approx(pub[site]["n"], abs=0.03), site


def test_synthetic_inputs_follow_the_stated_design(run):
    root = run.out_dir
    profiles = read_ci_profiles(root / "data" / "lete_sand_synthetic_ci.csv")
    assert [p.id for p in profiles] == ["LS_1", "LS_2"]
    plates = read_plate_tests(root / "data" / "krc_synthetic_plates.csv")
    for t in plates:
        limit = KRC_FORCE_LIMIT / (math.pi * t.b**2) / 1000.0
        assert t.pressure.max() <= limit * 1.1  # the test stopped at 1,500 lbf (2% noise)
    radii = sorted({round(t.b / u.INCH * 2, 6) for t in plates})
    assert radii == [4.0, 6.0]  # 4 in and 6 in diameter


def test_side_by_side_holds_the_published_values(run):
    root = run.out_dir
    df = pd.read_csv(root / "tables" / "table_4_2_lete_vs_published.csv", comment="#")
    pub = {(r["prediction"], r["pair"], r["plate"]): r for r in published_agreement("4-2")}
    assert len(df) == 2 * 3 * 2  # quick: LS_1, LS_2 x LS_A..LS_C x two plates
    for _, row in df.iterrows():
        p = pub[(row["CI data"], row["P-S data"], row["Plate"])]
        assert row["R2 [paper]"] == pytest.approx(p["R2"])
        assert row["CV [paper]"] == pytest.approx(p["CV"])
        assert 0.9 < row["R2 [ours]"] <= 1.0
    html = run.report.read_text()
    assert "where and why they differ" in html
    assert "never published" in html


def test_report_rebuilds_from_the_output_directory(run, tmp_path):
    out = build_report(run.out_dir, tmp_path / "again.html")
    text = out.read_text()
    assert "terracone reproduce" in text and "SYNTHETIC DATA" in text
    assert text.count("<img ") == run.report.read_text().count("<img ")
    assert "http://" not in text and "https://" not in text
    # a results file of the run makes its own report too
    out2 = build_report(run.out_dir / "results" / "lete_predict.json", tmp_path / "p.html")
    assert "SYNTHETIC" in out2.read_text()


def test_reproduce_report_renders_in_chromium(run):
    require_chromium()
    chk = browser_check(Path(run.report))
    assert chk.images_total == len(EXPECTED_FIGURES), chk.page_error_text
    assert chk.images_ok == chk.images_total
    assert chk.page_errors == 0 and chk.console == [], (chk.page_error_text, chk.console)


def test_the_given_pool_runs_learning_prediction_and_figures(run, pool):
    # quick run: learning on LETE (one run) and on KRC_1, KRC_3 (one per site); then
    # LS_1, LS_2, KRC_1, KRC_3 predicted; then every figure drawn
    assert pool.calls == [1 + 2, 2 + 2, len(EXPECTED_FIGURES)]


def test_refuses_a_folder_it_did_not_write(tmp_path):
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "precious.csv").write_text("x\n")
    with pytest.raises(ValueError, match="not written by terracone reproduce"):
        reproduce(tmp_path, quick=True)
    assert (tmp_path / "data" / "precious.csv").exists()


def test_a_folder_that_reproduce_alone_wrote_is_written_again(run, tmp_path):
    # the data files of a run start with the header that marks a folder as ours
    for f in (run.out_dir / "data").iterdir():
        assert f.read_text().splitlines()[0] == f"# {DATA_HEADER}", f
    # terracone.apps.reproduce.reproduce alone writes data/ and results/, no reproduce.json
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "lete_sand_synthetic_ci.csv").write_text(f"# {DATA_HEADER}\nx\n")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "lete_learn.json").write_text("{}\n")
    assert prepare_output(tmp_path) == tmp_path
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "figures", "results", "tables"]
    assert not any(any(p.iterdir()) for p in tmp_path.iterdir())
    # one file of data/ without the header: someone else's folder
    (tmp_path / "data" / "lete_sand_synthetic_ci.csv").write_text(f"# {DATA_HEADER}\nx\n")
    (tmp_path / "data" / "precious.csv").write_text("x\n")
    with pytest.raises(ValueError, match="not written by terracone reproduce"):
        prepare_output(tmp_path)
    assert (tmp_path / "data" / "precious.csv").exists()

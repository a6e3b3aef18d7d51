"""Reports: figures, tables, the self-contained HTML file, and a real browser.

The browser tests use headless Chromium from Debian's ``chromium`` package
(``.ci/run`` installs it).  Tests change nothing on the system: without a
browser they skip with the reason.  Screenshots are written to the test's tmp
folder, or to $TERRACONE_SCREENSHOTS when set (to look at them).
"""

from __future__ import annotations

import base64
import json
import os
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from chromium import browser_check, screenshot
from click.testing import CliRunner
from conftest import require_chromium

import terracone
from terracone.apps.example import CI_FILE, PLATES_FILE, example_dir
from terracone.apps.reproduce.paper import (
    published_agreement,
    published_parameters,
    us_column_check,
)
from terracone.cli import cli
from terracone.data import TerrainParameters
from terracone.inverse.evaluate import cross_table
from terracone.inverse.learning.learn import LearnResult
from terracone.inverse.solver.ridge import ridge_profile
from terracone.io import read_plate_tests
from terracone.physics import units as u
from terracone.report import build_report, result_kind
from terracone.report import figures as F
from terracone.report.tables import (
    Table,
    agreement_table,
    fmt_value,
    identifiability_table,
    parameters_table,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------------
# fixtures
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def predict_json(tmp_path_factory) -> Path:
    """The JSON of `terracone predict EXAMPLE --json --out FILE --plates 3.75cm,5cm`."""
    out = tmp_path_factory.mktemp("predict") / "predict.json"
    res = CliRunner().invoke(
        cli,
        [
            "predict",
            str(example_dir() / CI_FILE),
            "--json",
            "--out",
            str(out),
            "--plates",
            "3.75cm,5cm",
        ],
    )
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def report_html(predict_json, tmp_path_factory) -> Path:
    return build_report(predict_json, tmp_path_factory.mktemp("report") / "report.html")


class _Refs(HTMLParser):
    """Every URL-bearing attribute, and the tags that could load something."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[tuple[str, str, str]] = []
        self.tags: list[tuple[str, dict]] = []

    def handle_starttag(self, tag, attrs):
        d = dict(attrs)
        self.tags.append((tag, d))
        for k in ("src", "href", "srcset", "data", "poster", "action", "formaction"):
            if d.get(k):
                self.urls.append((tag, k, d[k]))


def _refs(path: Path) -> _Refs:
    p = _Refs()
    p.feed(path.read_text(encoding="utf-8"))
    return p


def _assert_self_contained(path: Path) -> list[bytes]:
    """No reference to another host; every image a decodable PNG data URI."""
    text = path.read_text(encoding="utf-8")
    refs = _refs(path)
    for tag, attr, url in refs.urls:
        low = url.strip().lower()
        assert not low.startswith(("http:", "https:", "//", "ftp:", "file:")), (tag, attr, url)
        if tag == "img":
            assert low.startswith("data:image/png;base64,"), url[:60]
        elif attr == "href":
            assert low.startswith("#"), url[:60]  # in-page links only
    # no stylesheet, script or font loaded from anywhere
    for tag, d in refs.tags:
        assert tag not in ("link", "iframe", "object", "embed", "base"), tag
        if tag == "script":
            assert "src" not in d
    # nothing in CSS either
    assert not re.search(r"url\(\s*['\"]?(https?:)?//", text, re.I)
    assert not re.search(r"@import", text, re.I)
    assert "Content-Security-Policy" in text and "default-src 'none'" in text
    pngs = []
    for tag, _attr, url in refs.urls:
        if tag == "img":
            data = base64.b64decode(url.split(",", 1)[1], validate=True)
            assert data.startswith(PNG_MAGIC)
            pngs.append(data)
    return pngs


# ---------------------------------------------------------------------------
# the report of a predict JSON
# ---------------------------------------------------------------------------


def test_predict_report_is_self_contained(report_html):
    pngs = _assert_self_contained(report_html)
    assert len(pngs) >= 4  # CI fit, Janosi, plates, ridge
    text = report_html.read_text()
    assert f"terracone {terracone.__version__}" in text
    for needle in ("Inputs", "Settings", "Parameters", "Identifiability", "Figures"):
        assert f">{needle}</h2>" in text
    assert 'name="viewport"' in text and "max-width: 100%" in text and "overflow-x: auto" in text
    assert "LS_syn_1" in text and "lb/in^(n+1)" in text and "kN/m^(n+2)" in text


def test_predict_report_tables_hold_all_profiles_and_units(predict_json, report_html):
    doc = json.loads(predict_json.read_text())
    assert result_kind(doc) == "predict"
    text = report_html.read_text()
    for p in doc["profiles"]:
        assert p["id"] in text
        # the US column of kc is the SI value converted with the profile's n
        kc_us = float(u.kc_from_si(p["kc"], p["n"], "us"))
        assert f">{fmt_value(kc_us)}<" in text


def test_report_draws_plate_bands_when_present(predict_json, tmp_path):
    doc = json.loads(predict_json.read_text())
    p = doc["profiles"][0]
    curve = p["plates"][0]
    pr = np.asarray(curve["pressure"])
    p["plate_bands"] = [
        {
            "radius": curve["radius"],
            "sinkage": curve["sinkage"],
            "median": list(pr),
            "lo": list(0.8 * pr),
            "hi": list(1.2 * pr),
        }
    ]
    p["identifiability"] = {
        "kc": "determined",
        "kphi": "weakly determined",
        "n": "determined",
        "cc": "set by prior",
        "phic_deg": "set by prior",
    }
    f = tmp_path / "with_bands.json"
    f.write_text(json.dumps(doc))
    out = build_report(f, tmp_path / "r.html")
    text = out.read_text()
    assert "posterior band" in text
    assert "weakly determined" in text and "set by prior" in text
    _assert_self_contained(out)


def test_learn_evaluate_batch_and_directory_reports(tmp_path):
    plates = read_plate_tests(example_dir() / PLATES_FILE)
    params = TerrainParameters(96.2, 5155.0, 0.772, 0.0, 11.9, None, "rm1", 0.0086)
    lr = LearnResult(
        params=params,
        plate_pair=(0.0375, 0.05),
        objective=0.3,
        rmsd_ci=230.0,
        rmsd_plates=20.0,
        datasets=[
            {"kind": "ci", "id": "LS_syn_1", "rmsd": 230.0, "cv": 0.03},
            {"kind": "plate", "id": "A_r3.75cm", "b": 0.0375, "rmsd": 20.0, "cv": 0.02},
        ],
        undetermined=["r_min", "cc"],
        criteria={"max_cv": 0.25, "worst_cv": 0.03, "satisfied": True},
        nfev=1,
        time_s=0.1,
        intervals={"n": (0.76, 0.79), "r_min": (0.001, 0.15)},
    )
    learn_doc = {**lr.as_dict("us"), "terrain": "LETE", "command": "learn", "terracone": "x"}
    (tmp_path / "learn.json").write_text(json.dumps(learn_doc))
    rows = cross_table([("LS_syn_1", params)], plates, plate_pair=(0.0375, 0.05))
    ev = {"plates": [r.as_dict("si") for r in rows], "units": "si"}
    (tmp_path / "evaluate.json").write_text(json.dumps(ev))
    for name, kind in (("learn.json", "learn"), ("evaluate.json", "evaluate")):
        assert result_kind(json.loads((tmp_path / name).read_text())) == kind
        out = build_report(tmp_path / name, tmp_path / f"{kind}.html")
        _assert_self_contained(out)
    text = (tmp_path / "learn.html").read_text()
    assert "undetermined" in text and "LETE" in text
    # the learn JSON was in US units: the SI column holds the SI value
    assert "96.2" in text
    assert (
        "A_r3.75cm" in (tmp_path / "evaluate.html").read_text()
        or "LS_syn_A" in (tmp_path / "evaluate.html").read_text()
    )
    # a directory of results: one report with a part per file
    out = build_report(tmp_path, tmp_path / "all.html")
    text = out.read_text()
    assert "learn.json: " in text and "evaluate.json: " in text

    # a batch output directory
    bdir = tmp_path / "batch"
    bdir.mkdir()
    df = pd.DataFrame(
        {
            "profile": ["a", "b", "c"],
            "status": ["ok", "ok", "error"],
            "error": [None, None, "depth is not strictly increasing"],
            "kc": [10.0, 20.0, np.nan],
            "kphi": [1000.0, 1500.0, np.nan],
            "n": [0.7, 0.8, np.nan],
            "cc": [0.0, 1.0, np.nan],
            "phic_deg": [10.0, 12.0, np.nan],
            "rmsd": [100.0, 120.0, np.nan],
            "r2_ci": [0.99, 0.98, np.nan],
            "phic_lo": [0.0, 0.0, np.nan],
            "phic_hi": [45.0, 45.0, np.nan],
            "n_lo": [0.65, 0.7, np.nan],
            "n_hi": [0.75, 0.9, np.nan],
            "undetermined": ["phic;phic~scale(kc,kphi)", "phic;n;phic~scale(kc,kphi)", None],
            "units": ["si", "si", "si"],
        }
    )
    df.iloc[:2].to_parquet(bdir / "part-00000.parquet")
    df.iloc[2:].to_parquet(bdir / "part-00001.parquet")
    (bdir / "_summary.json").write_text(json.dumps({"units": "si", "profiles": 3, "ok": 2}))
    out = build_report(bdir, tmp_path / "batch.html")
    _assert_self_contained(out)
    text = out.read_text()
    assert "depth is not strictly increasing" in text and "2 part file(s)" in text
    assert "phic~scale(kc,kphi)" in text and "0.65 to 0.75" in text


def test_build_report_rejects_what_it_cannot_read(tmp_path):
    (tmp_path / "x.json").write_text('{"hello": 1}')
    with pytest.raises(ValueError, match="not a terracone result"):
        build_report(tmp_path / "x.json", tmp_path / "x.html")
    with pytest.raises(ValueError, match="no such file"):
        build_report(tmp_path / "missing.json", tmp_path / "x.html")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match="no terracone results"):
        build_report(empty, tmp_path / "y.html")


# ---------------------------------------------------------------------------
# figures and tables
# ---------------------------------------------------------------------------


def test_figures_write_png_and_svg_with_units(tmp_path):
    z = np.linspace(0, 0.3, 31)
    ci = terracone.cone_index(z, kc=80, kphi=4700, n=0.74, phic_deg=12.5)
    prof = {"id": "P", "depth": z, "ci": ci * 1.01, "ci_model": ci}
    fig = F.fig_ci_fit([prof], units="us", synthetic=True)
    ax = fig.axes[0]
    assert "[in]" in ax.get_xlabel() and "[psi]" in ax.get_ylabel()
    assert ax.get_legend() is not None
    styles = {ln.get_linestyle() for ln in ax.get_lines()}
    assert {"--", "-"} <= styles  # measured and predicted differ without colour
    paths = F.save_figure(fig, tmp_path, "ci")
    assert paths["png"].read_bytes().startswith(PNG_MAGIC)
    svg = paths["svg"].read_text()
    assert "<svg" in svg and "SYNTHETIC" in svg
    s = np.linspace(0, 0.1, 21)
    curves = [
        {"id": "P", "radius": r, "sinkage": s, "pressure": (80 / r + 4700) * s**0.74}
        for r in (0.0375, 0.05)
    ]
    bands = [{**curves[0], "lo": curves[0]["pressure"] * 0.9, "hi": curves[0]["pressure"] * 1.1}]
    fig = F.fig_plate_fit(curves, curves, bands)
    assert len(fig.axes) == 2 and all(a.get_legend() is not None for a in fig.axes)
    assert "[kPa]" in fig.axes[0].get_ylabel() and "[cm]" in fig.axes[0].get_xlabel()
    fig = F.fig_janosi([prof], {"kc": 102, "kphi": 5301, "n": 0.79})
    assert fig.axes[0].get_legend() is not None


def test_ridge_is_flat_in_phic_and_fixes_n():
    z = np.linspace(0, 0.3, 31)
    ci = terracone.cone_index(z, kc=80.14, kphi=4727.2, n=0.74, phic_deg=12.5)
    r = ridge_profile(z, ci)
    prof_phic = r["rmsd"].min(axis=0)
    assert np.ptp(prof_phic) <= 1e-6 * max(1.0, prof_phic.max())  # exact ridge
    assert abs(r["best"]["n"] - 0.74) < 0.02
    # along scale * (1 + tan(phic)/tan(15 deg)) = const the fit does not change
    i = int(np.argmin(np.abs(r["scale"] - 1.0)))
    assert r["rmsd_scale"][i].min() < 1e-3 * ci.mean()  # grid steps only


def test_parameters_table_us_columns_and_csv(tmp_path):
    rows = published_parameters("4-1")
    t = parameters_table(rows, key="t41", title="T", synthetic=True)
    for r, cells in zip(rows, t.rows):
        assert cells[2] == pytest.approx(r["kc_us_printed"], rel=5e-3)
        assert cells[4] == pytest.approx(r["kphi_us_printed"], rel=5e-3)
    text = t.to_csv(tmp_path / "t.csv")
    assert text.startswith("# SYNTHETIC - T\n")
    df = pd.read_csv(tmp_path / "t.csv", comment="#")
    assert list(df.columns[:3]) == ["Data set", "kc [kN/m^(n+1)]", "kc [lb/in^(n+1)]"]
    html = t.to_html()
    assert 'colspan="2"' in html and "SYNTHETIC" in html and "table-wrap" in html
    assert Table.from_dict(json.loads(json.dumps(t.to_dict()))).rows == t.rows


def test_agreement_table_layout_matches_the_paper():
    rows = published_agreement("4-2")
    t = agreement_table(rows, plates=["r=3.75cm", "r=5cm"], key="t42", title="T")
    assert len(t.rows) == 20 and len(t.columns) == 2 + 2 * 5
    first = t.rows[0]
    assert first[:2] == ["LS_1", "LS_A"]
    assert first[2:7] == pytest.approx([0.9874, 0.975, 102.5, 14.87, 0.1457], rel=2e-3)
    t4 = agreement_table(
        published_agreement("4-4"), plates=["D=10cm", "D=15cm"], key="t", title="T", same_site=True
    )
    assert len(t4.rows) == 8 and t4.rows[5][0] == "KRC_9"


def test_identifiability_table_reads_both_sources():
    profiles = [
        {"id": "a", "status": "ok", "undetermined": ["phic", "kphi", "phic~scale(kc,kphi)"]},
        {
            "id": "b",
            "status": "ok",
            "undetermined": [],
            "identifiability": {"kc": "determined", "phic_deg": "set by prior"},
        },
        {"id": "c", "status": "error"},
    ]
    t = identifiability_table(profiles, key="i", title="I", fixed=("cc",))
    a, b, c = t.rows
    assert a[1:6] == [
        "determined",
        "undetermined",
        "determined",
        "fixed by calibration",
        "undetermined",
    ]
    assert a[6] == "phic~scale(kc,kphi)"
    assert b[1] == "determined" and b[5] == "set by prior"
    assert c[1] == "(not fitted)"


def test_published_tables_are_consistent():
    assert len(published_parameters("4-1")) == 4 and len(published_parameters("4-3")) == 8
    assert len(published_agreement("4-2")) == 40 and len(published_agreement("4-4")) == 16
    for r in published_agreement("4-2") + published_agreement("4-4"):
        assert r["R2"] == pytest.approx(r["R"] ** 2, abs=6e-4)
        assert r["RMSD_psi"] == pytest.approx(float(u.pressure_from_si(r["RMSD"], "us")), rel=6e-3)
    assert us_column_check() == []


# ---------------------------------------------------------------------------
# a real browser
# ---------------------------------------------------------------------------


@pytest.fixture(scope="session")
def chromium() -> str:
    return require_chromium()


def _shots_dir(tmp_path: Path) -> Path:
    d = os.environ.get("TERRACONE_SCREENSHOTS")
    return Path(d) if d else tmp_path


def test_browser_capture_sees_errors(chromium, tmp_path):
    """The checks below are only worth something if they can fail: a page with errors."""
    bad = tmp_path / "bad.html"
    bad.write_text(
        "<!DOCTYPE html><html><head><meta charset='utf-8'></head><body>"
        "<p id='tc-selfcheck'></p><img src='data:image/png;base64,AAAA'>"
        "<script>window.addEventListener('load', function () {"
        "var i = document.images[0], el = document.getElementById('tc-selfcheck');"
        "el.setAttribute('data-images-ok', i.naturalWidth > 0 ? '1' : '0');"
        "el.setAttribute('data-images-total', '1'); el.setAttribute('data-errors', '0');});"
        "console.error('tc-sentinel');</script></body></html>"
    )
    chk = browser_check(bad)
    assert chk.images_total == 1 and chk.images_ok == 0
    assert any("tc-sentinel" in m for m in chk.console)
    assert not chk.ok


def test_report_renders_in_chromium(chromium, report_html, tmp_path):
    chk = browser_check(report_html)
    assert chk.returncode == 0, chk.stderr[-2000:]
    assert chk.images_total is not None and chk.images_total >= 4, chk.page_error_text
    assert chk.images_ok == chk.images_total, chk.page_error_text
    assert chk.page_errors == 0, chk.page_error_text
    assert chk.console == [], chk.console
    shots = _shots_dir(tmp_path)
    from PIL import Image

    for name, (w, h) in {"laptop": (1280, 2000), "phone": (390, 1600)}.items():
        png = screenshot(report_html, shots / f"predict_report_{name}.png", width=w, height=h)
        with Image.open(png) as im:
            assert im.size == (w, h)
            # not a blank page: the heading and the tables put dark pixels on it
            grey = np.asarray(im.convert("L"))
            assert (grey < 128).mean() > 0.005

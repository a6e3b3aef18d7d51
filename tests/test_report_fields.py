"""The report of real fields (summary, map, small multiples, sortable table) and Jupyter tables.

Real data: the Marsden Farm SC900 export (83 pushes) in ../shared; the tests
that need it skip when it is absent.  The browser tests drive Debian's
headless Chromium over the DevTools pipe (tests/chromium.py) and skip
when no Chromium is installed (they never install it).  Screenshots go to
the test's tmp folder, or to $TERRACONE_SCREENSHOTS when set.
"""

from __future__ import annotations

import json
import math
import os
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from chromium import BrowserSession
from click.testing import CliRunner
from conftest import require_chromium, require_shared

import terracone
from terracone.apps.batch import BatchSummary
from terracone.cli import cli
from terracone.data import TerrainParameters
from terracone.inverse import predict_many
from terracone.inverse.layered import LayeredResult
from terracone.inverse.learning.learn import LearnResult
from terracone.notebook import fmt_value
from terracone.report import build_report
from terracone.report import fields as FL
from terracone.report import figures as F
from terracone.result import PredictionResults, from_table, read_results

REAL = ("data", "marsden-penetrometer", "sc900_export_2019-06-11.txt")  # under ../shared
N_REAL = 83  # pushes in the export (its README and the file's "N=" lines)

# independent unit factors (NIST): 1 lbf = 4.4482216152605 N, 1 in = 0.0254 m
LBF_KN = 4.4482216152605e-3
INCH = 0.0254
PSI_KPA = LBF_KN / INCH**2


def _need_real() -> Path:
    return require_shared(*REAL)


def _predict(args: list[str], out: Path) -> dict:
    res = CliRunner().invoke(cli, ["predict", *args, "--json", "--out", str(out)])
    assert res.exit_code == 0, res.output
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def real_json(tmp_path_factory) -> Path:
    """`terracone predict` over all 83 pushes of the real export (one layer)."""
    src = _need_real()
    out = tmp_path_factory.mktemp("real") / "predict.json"
    _predict([str(src)], out)
    return out


@pytest.fixture(scope="module")
def layered_json(tmp_path_factory) -> Path:
    """`predict --layers 2` over the first 10 pushes of the real export (a copy cut in tmp)."""
    src = _need_real()
    d = tmp_path_factory.mktemp("layered")
    lines = src.read_text(encoding="latin-1").splitlines(keepends=True)
    push = [k for k, ln in enumerate(lines) if "N=" in ln]
    cut = d / "sc900_first10.txt"
    cut.write_text("".join(lines[: push[9] + 1]), encoding="latin-1")
    out = d / "predict.json"
    _predict([str(cut), "--layers", "2"], out)
    return out


@pytest.fixture(scope="module")
def real_report(real_json, tmp_path_factory) -> Path:
    return build_report(real_json, tmp_path_factory.mktemp("rep") / "real.html")


@pytest.fixture(scope="module")
def layered_report(layered_json, tmp_path_factory) -> Path:
    return build_report(layered_json, tmp_path_factory.mktemp("rep") / "layered.html")


@pytest.fixture(scope="module")
def located_json(tmp_path_factory) -> tuple[Path, list[dict]]:
    """Generated profiles with known positions and n (SYNTHETIC), as a long CSV with lat/lon."""
    d = tmp_path_factory.mktemp("located")
    z = np.arange(0.0, 0.301, 0.025)
    truth, rows = [], ["profile,depth_cm,ci_kpa,lat,lon"]
    for k in range(6):
        lat, lon, n = 42.0100 + 0.0004 * (k % 3), -93.7900 + 0.0006 * (k // 3), 0.4 + 0.08 * k
        ci = terracone.cone_index(z, kc=20.0, kphi=1500.0, n=n, phic_deg=15.0)
        truth.append({"id": f"G{k}", "lat": lat, "lon": lon, "n": n})
        rows += [f"G{k},{zi * 100:.2f},{c:.4f},{lat},{lon}" for zi, c in zip(z, ci, strict=True)]
    (d / "located.csv").write_text("\n".join(rows) + "\n")
    out = d / "predict.json"
    _predict([str(d / "located.csv")], out)
    return out, truth


class _Sections(HTMLParser):
    """Section ids in order, images (alt) per section, and the profiles table's rows."""

    def __init__(self) -> None:
        super().__init__()
        self.sections: list[str] = []
        self.alts: dict[str, list[str]] = {}
        self.table_rows = 0
        self._in_profiles = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section":
            self.sections.append(a.get("id", ""))
        if tag == "img":
            self.alts.setdefault(self.sections[-1] if self.sections else "", []).append(
                a.get("alt", "")
            )
        if tag == "div" and a.get("id") == "tbl-profiles":
            self._in_profiles = True
        if tag == "tr" and self._in_profiles:
            self.table_rows += 1

    def handle_endtag(self, tag):
        if tag == "table":
            self._in_profiles = False


def _sections(path: Path) -> _Sections:
    p = _Sections()
    p.feed(path.read_text(encoding="utf-8"))
    return p


def _section_text(text: str, sid: str) -> str:
    m = re.search(rf'<section id="{sid}">(.*?)</section>', text, re.S)
    assert m, f"no section {sid}"
    return m.group(1)


# ---------------------------------------------------------------------------
# the report of the real field
# ---------------------------------------------------------------------------


def test_real_report_summary_first_and_counts(real_json, real_report):
    doc = json.loads(real_json.read_text())
    profiles = doc["profiles"]
    assert len(profiles) == N_REAL
    s = _sections(real_report)
    assert s.sections[0] == "summary"
    assert {"summary", "profiles", "multiples"} <= set(s.sections)
    assert "map" not in s.sections  # the export carries no coordinates
    text = real_report.read_text()
    summ = _section_text(text, "summary")
    ok = [p for p in profiles if p["status"] == "ok"]
    flagged = sum(1 for p in ok if p["lack_of_fit"])
    assert 0 < flagged < len(ok)  # the real field: many, not all, profiles lack fit
    share = f"{flagged} of {len(ok)} ({100 * flagged / len(ok):.0f}%)"
    assert f"<dt>flagged for lack of fit</dt><dd>{share}</dd>" in summ
    assert f"<dd>0 of {N_REAL} (0%)</dd>" in summ  # located
    assert "run predict or batch with --layers 2" in summ
    # the distribution table: quartiles from numpy over the JSON's n
    n = np.array([p["n"] for p in ok])
    for q in np.quantile(n, [0.0, 0.25, 0.5, 0.75, 1.0]):
        assert f">{fmt_value(float(q))}<" in summ


def test_real_report_draws_and_lists_every_profile(real_json, real_report):
    ids = [p["id"].rsplit("/", 1)[1] for p in json.loads(real_json.read_text())["profiles"]]
    s = _sections(real_report)
    assert s.table_rows == 1 + N_REAL  # heading row and one row per profile
    alts = s.alts["multiples"]
    k = FL.PANELS_PER_FIGURE
    assert len(alts) == math.ceil(N_REAL / k) == 3
    for j, alt in enumerate(alts):
        chunk = ids[j * k : (j + 1) * k]
        assert alt == f"Small multiples of CI profiles {chunk[0]} to {chunk[-1]}"
    text = real_report.read_text()
    assert "first 24" not in text and "Figures show the first" not in text
    # a few compact PNGs, not one per profile: the whole file stays small
    assert real_report.stat().st_size < 2_500_000


def test_layered_fit_is_drawn_exactly_where_it_wins(layered_json):
    profiles = json.loads(layered_json.read_text())["profiles"]
    wins = [(p.get("layered") or {}).get("preferred_layers") == 2 for p in profiles]
    assert any(wins) and not all(wins)  # the first 10 real pushes have both cases
    recs = FL.records_from_predict(profiles)
    panels = [FL.panel_of(r) for r in recs]
    fig = F.fig_ci_multiples(panels)
    for p, win, panel, ax in zip(profiles, wins, panels, fig.axes, strict=False):
        dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
        dotted = [ln for ln in ax.get_lines() if ln.get_linestyle() == ":"]
        if win:
            lay = p["layered"]
            assert len(dashed) == 1 and len(dotted) == len(lay["interfaces"])
            np.testing.assert_allclose(dashed[0].get_xdata(), lay["ci_model"])
            np.testing.assert_allclose(dashed[0].get_ydata(), np.asarray(lay["depth"]) * 100)
            np.testing.assert_allclose(
                [ln.get_ydata()[0] for ln in dotted], np.asarray(lay["interfaces"]) * 100
            )
        else:
            assert dashed == [] and dotted == [] and "ci_layered" not in panel
        solid = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
        if p["status"] == "ok":  # the one-layer fit, always
            np.testing.assert_allclose(solid[0].get_xdata(), p["ci_model"])


def test_layered_report_summary_counts_layers(layered_json, layered_report):
    profiles = json.loads(layered_json.read_text())["profiles"]
    done = [p["layered"] for p in profiles if (p.get("layered") or {}).get("status") == "ok"]
    two = sum(1 for lay in done if lay["preferred_layers"] >= 2)
    bad = sum(1 for p in profiles if (p.get("layered") or {}).get("status") not in (None, "ok"))
    summ = _section_text(layered_report.read_text(), "summary")
    share = f"{two} of {len(done)} ({100 * two / len(done):.0f}%)"
    assert f"<dt>two or more layers win (BIC)</dt><dd>{share}</dd>" in summ
    assert f"<dt>layered fit not possible</dt><dd>{bad}</dd>" in summ


def test_map_only_when_located(located_json, tmp_path):
    path, truth = located_json
    out = build_report(path, tmp_path / "located.html", map_by="n")
    s = _sections(out)
    assert s.sections[:2] == ["summary", "map"] and len(s.alts["map"]) == 1
    recs = FL.records_from_predict(json.loads(path.read_text())["profiles"])
    assert [(r["lon"], r["lat"]) for r in recs] == [(t["lon"], t["lat"]) for t in truth]
    fig = F.fig_map(
        [r["lon"] for r in recs],
        [r["lat"] for r in recs],
        [r["n"] for r in recs],
        label="n [-]",
    )
    sc = fig.axes[0].collections[0]
    np.testing.assert_allclose(sc.get_offsets(), [[t["lon"], t["lat"]] for t in truth])
    # noise-free CI fixes n: the colours carry the generating n
    np.testing.assert_allclose(sc.get_array(), [t["n"] for t in truth], atol=1e-3)
    # a metre east is as long as a metre north at the mean latitude
    lat0 = np.mean([t["lat"] for t in truth])
    assert fig.axes[0].get_aspect() == pytest.approx(1 / math.cos(math.radians(lat0)))


@pytest.mark.parametrize(
    ("meta", "expected"),
    [
        ({"lat": 42.01, "lon": -93.79}, (-93.79, 42.01)),
        ({"latitude": "-34.38", "longitude": "150.9"}, (150.9, -34.38)),
        ({"lat": 0.0, "lon": 0.0}, None),  # an instrument without a fix
        ({"lat": 95.0, "lon": 10.0}, None),
        ({"lat": 42.0}, None),
        (None, None),
    ],
)
def test_coordinates_from_metadata(meta, expected):
    assert FL.coordinates(meta) == expected


def test_batch_directory_report_of_the_real_field(real_json, tmp_path):
    from terracone.apps.batch import run_batch

    s = run_batch(_need_real(), tmp_path / "b", workers=1, progress=False)
    assert s.profiles == N_REAL
    out = build_report(tmp_path / "b", tmp_path / "batch.html")
    sec = _sections(out)
    assert sec.sections[0] == "summary" and sec.table_rows == 1 + N_REAL
    assert len(sec.alts["multiples"]) == math.ceil(N_REAL / FL.PANELS_PER_FIGURE)
    # the batch curves (measured points from _input, model CI from the parameters via
    # cone_index) agree with predict's own curves for the same pushes
    results = read_results(tmp_path / "b")
    recs = FL.records_from_table(results, results.settings)
    pred = {p["id"].rsplit("/", 1)[1]: p for p in json.loads(real_json.read_text())["profiles"]}
    for r in recs[::10]:
        p = pred[r["label"]]
        np.testing.assert_allclose(r["depth"], p["depth"])
        np.testing.assert_allclose(r["ci"], p["ci"])
        np.testing.assert_allclose(r["ci_model"], p["ci_model"], rtol=1e-5, atol=1e-6)


def test_sortable_table_markup():
    recs = [
        {"id": "a", "label": "a", "status": "ok", "n": 0.5, "kc": 1.0},
        {"id": "b", "label": "b", "status": "error", "error": "x"},
    ]
    frag = FL.profiles_table(recs).to_html(sortable=True)
    heads = re.findall(
        r'<th scope="col" data-col="(\d+)"><button type="button" class="sort">', frag
    )
    assert heads == [str(j) for j in range(15)]
    assert 'data-v="0.5"' in frag and 'data-v=""' in frag  # raw numbers, blanks for none
    assert 'class="sortable"' in frag


# ---------------------------------------------------------------------------
# in a real browser
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def browser():
    require_chromium()
    with BrowserSession(width=1280, height=900) as b:
        yield b


def _shots(tmp_path: Path) -> Path:
    d = os.environ.get("TERRACONE_SCREENSHOTS")
    return Path(d) if d else tmp_path


_COL_N = 4  # "n [-]" in the profiles table


def _column(b: BrowserSession, col: int) -> list[str]:
    return b.evaluate(
        "Array.from(document.querySelectorAll('#tbl-profiles tbody tr'))"
        f".map(function (r) {{ return r.cells[{col}].getAttribute('data-v'); }})"
    )


@pytest.mark.parametrize(("width", "height"), [(1280, 900), (390, 844)])
def test_real_report_in_chromium(browser, real_json, real_report, tmp_path, width, height):
    b = browser
    b.console.clear()
    b.set_viewport(width, height)
    b.open(real_report)
    n_img = real_report.read_text().count("<img ")
    state = b.evaluate(
        "({page: document.documentElement.scrollWidth, view: document.documentElement.clientWidth,"
        " imgs: Array.from(document.images).filter(function (i) {"
        "   return i.complete && i.naturalWidth > 0; }).length,"
        " total: document.images.length,"
        " first: document.querySelector('main section').id,"
        " ids: Array.from(document.querySelectorAll('section')).map(function (s) { return s.id; }),"
        " wrap: (function () { var w = document.querySelector('#tbl-profiles .table-wrap');"
        "   return [w.scrollWidth, w.clientWidth, w.scrollHeight, w.clientHeight]; })(),"
        " self: document.getElementById('tc-selfcheck').getAttribute('data-errors')})"
    )
    assert state["page"] <= state["view"] == width, state  # never scrolls sideways
    assert state["total"] == n_img >= 4 and state["imgs"] == n_img, state
    assert state["first"] == "summary" and {"profiles", "multiples"} <= set(state["ids"])
    wrap = state["wrap"]
    assert wrap[2] > wrap[3]  # 83 rows scroll inside the table's own box
    if width < 640:
        assert wrap[0] > wrap[1]  # and sideways inside it on a phone
    assert state["self"] == "0"
    # sort by n: a real click on the heading, then check the order against the JSON
    n_json = sorted(p["n"] for p in json.loads(real_json.read_text())["profiles"])
    b.click_selector(f"#tbl-profiles th[data-col='{_COL_N}'] button")
    up = [float(v) for v in _column(b, _COL_N)]
    assert up == pytest.approx(n_json, rel=1e-12)
    assert b.evaluate(f"document.querySelector('#tbl-profiles th[data-col=\"{_COL_N}\"]')"
                      ".getAttribute('aria-sort')") == "ascending"  # fmt: skip
    b.click_selector(f"#tbl-profiles th[data-col='{_COL_N}'] button")
    assert [float(v) for v in _column(b, _COL_N)] == pytest.approx(n_json[::-1], rel=1e-12)
    b.click_selector("#tbl-profiles th[data-col='0'] button")
    labels = _column(b, 0)
    assert labels == sorted(labels)  # zero-padded push numbers sort as text
    assert b.console == [], b.console
    from PIL import Image

    shots = _shots(tmp_path)
    b.evaluate("window.scrollTo(0, 0)")
    top = b.screenshot(shots / f"real_field_{width}_top.png")
    b.evaluate("document.getElementById('multiples').scrollIntoView()")
    mult = b.screenshot(shots / f"real_field_{width}_multiples.png")
    for png in (top, mult):
        with Image.open(png) as im:
            assert im.size == (width, height)
            assert (np.asarray(im.convert("L")) < 128).mean() > 0.005  # not blank


def test_layered_and_located_reports_in_chromium(browser, layered_report, located_json, tmp_path):
    b = browser
    located = build_report(located_json[0], tmp_path / "located.html")
    for page, must in ((layered_report, "multiples"), (located, "map")):
        b.console.clear()
        b.set_viewport(1280, 900)
        b.open(page)
        st = b.evaluate(
            "[document.documentElement.scrollWidth, document.images.length,"
            " Array.from(document.images).filter(function (i) { return i.naturalWidth > 0; })"
            ".length, !!document.getElementById('" + must + "')]"
        )
        assert st[0] <= 1280 and st[1] == st[2] >= 3 and st[3], st
        assert b.console == [], b.console


def test_browser_session_sees_errors_and_layout(browser, tmp_path):
    """The checks above can fail: a page that scrolls sideways, has a broken image and errors."""
    bad = tmp_path / "bad.html"
    bad.write_text(
        "<!DOCTYPE html><html><head><meta name='viewport' content='width=device-width'></head>"
        "<body><div style='width:2000px'>wide</div><img src='data:image/png;base64,AAAA'>"
        "<script>console.error('tc-sentinel'); undefinedFunction();</script></body></html>"
    )
    browser.console.clear()
    browser.set_viewport(390, 600)
    browser.open(bad)
    page, view, ok = browser.evaluate(
        "[document.documentElement.scrollWidth, document.documentElement.clientWidth,"
        " document.images[0].naturalWidth]"
    )
    assert page > view and ok == 0
    assert any("tc-sentinel" in m for m in browser.console)
    assert any("undefinedFunction" in m for m in browser.console)


# ---------------------------------------------------------------------------
# Jupyter
# ---------------------------------------------------------------------------


class _Cells(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[str]] = []
        self.tables = 0
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables += 1
        if tag == "tr":
            self.rows.append([])
        if tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _cells(text: str) -> tuple[int, dict[str, list[str]]]:
    p = _Cells()
    p.feed(text)
    return p.tables, {r[0]: r[1:] for r in p.rows if r}


def _params(kc=80.0, kphi=4700.0, n=0.74, cc=2.0, phic=12.5) -> TerrainParameters:
    return TerrainParameters(kc, kphi, n, cc, phic, None, "rm0", None)


def _check_param_rows(rows: dict[str, list[str]], p: TerrainParameters) -> None:
    # SI as given; US by hand: kN -> lbf and m -> in with the exponent n+1 or n+2
    kc_us = p.kc / LBF_KN * INCH ** (p.n + 1)
    kphi_us = p.kphi / LBF_KN * INCH ** (p.n + 2)
    assert rows["kc"] == [fmt_value(p.kc), "kN/m^(n+1)", fmt_value(kc_us), "lb/in^(n+1)"]
    assert rows["kphi"] == [fmt_value(p.kphi), "kN/m^(n+2)", fmt_value(kphi_us), "lb/in^(n+2)"]
    assert rows["n"][:2] == [fmt_value(p.n), "-"]
    assert rows["cc"] == [fmt_value(p.cc), "kPa", fmt_value(p.cc / PSI_KPA), "psi"]
    assert rows["phic"][:2] == [fmt_value(p.phic_deg), "deg"]


def test_repr_html_of_prediction_and_predictions():
    z = np.arange(0.0, 0.301, 0.02)
    profiles = [
        terracone.CIProfile(
            f"P{k}", z, terracone.cone_index(z, kc=30.0, kphi=2000.0, n=n, phic_deg=10.0)
        )
        for k, n in enumerate((0.6, 0.9))
    ]
    res = predict_many(profiles)
    assert isinstance(res, PredictionResults) and isinstance(res, list)
    n_tables, rows = _cells(res[0]._repr_html_())
    assert n_tables == 1
    _check_param_rows(rows, res[0].params)
    assert rows["RMSD of CI"][1] == "kPa" and rows["R2 of CI"][0] == fmt_value(res[0].r2_ci)
    n_tables, rows = _cells(res._repr_html_())
    assert n_tables == 1 and "n [-]" in rows["Profile"]
    col = rows["Profile"].index("n [-]")
    for r, n_true in zip(res, (0.6, 0.9), strict=True):
        assert rows[r.id][col] == fmt_value(r.params.n)
        assert r.params.n == pytest.approx(n_true, abs=1e-3)  # noise-free CI fixes n


def test_repr_html_of_learn_layered_batch_and_parameters():
    p = _params()
    lr = LearnResult(
        params=p,
        plate_pair=(0.0375, 0.05),
        objective=0.3,
        rmsd_ci=230.0,
        rmsd_plates=20.0,
        datasets=[],
        undetermined=["cc"],
        criteria={"max_cv": 0.25, "worst_cv": 0.03, "satisfied": True},
        nfev=1,
        time_s=0.1,
    )
    n_tables, rows = _cells(lr._repr_html_())
    assert n_tables == 1
    _check_param_rows(rows, p)
    assert rows["plate radii"] == ["3.75, 5", "cm", "1.476, 1.969", "in"]
    assert rows["RMSD of plates"] == ["20", "kPa", fmt_value(20.0 / PSI_KPA), "psi"]
    _check_param_rows(_cells(p._repr_html_())[1], p)
    lay = LayeredResult(
        id="L",
        status="ok",
        layers=[p, _params(n=1.1)],
        interfaces=[0.125],
        rmsd=50.0,
        bic=10.0,
        bic_single=20.0,
        preferred_layers=2,
    )
    n_tables, rows = _cells(lay._repr_html_())
    assert n_tables == 1
    assert rows["1"][:2] == ["0", fmt_value(p.kc)] and rows["2"][0] == "12.5"  # top [cm]
    assert rows["2"][3] == "1.1"  # n of the second layer
    bs = BatchSummary(out_dir="/x", profiles=83, profiles_ok=80, profiles_error=3)
    rows = _cells(bs._repr_html_())[1]
    assert rows["profiles"] == ["83"] and rows["not fitted"] == ["3"]


def test_cli_report_map_by_and_errors(located_json, tmp_path):
    out = tmp_path / "by_phic.html"
    res = CliRunner().invoke(
        cli, ["report", str(located_json[0]), "--out", str(out), "--map-by", "phic"]
    )
    assert res.exit_code == 0, res.output
    assert "coloured by phic [deg]" in _section_text(out.read_text(), "map")
    res = CliRunner().invoke(
        cli, ["report", str(located_json[0]), "--out", str(out), "--map-by", "x"]
    )
    assert res.exit_code == 2 and "'x' is not one of" in res.output
    bad = tmp_path / "bad.json"
    bad.write_text('{"hello": 1}')
    res = CliRunner().invoke(cli, ["report", str(bad), "--out", str(out)])
    assert res.exit_code != 0 and f"file {bad}: not a terracone result" in res.output
    assert "Traceback" not in res.output
    with pytest.raises(ValueError, match="map_by must be one of n, kc, kphi"):
        FL.field_sections([], map_by="sand")


def test_batch_records_read_layers_and_units():
    import pandas as pd

    df = pd.DataFrame(
        {
            "profile": ["f/1", "f/2", "f/3"],
            "status": ["ok", "ok", "error"],
            "error": [None, None, "depth is not strictly increasing"],
            "kc": [2.0, 3.0, np.nan],  # lb/in^(n+1)
            "kphi": [10.0, 12.0, np.nan],
            "n": [0.8, 1.0, np.nan],
            "cc": [1.0, 0.0, np.nan],  # psi
            "phic_deg": [10.0, 20.0, np.nan],
            "rmsd": [5.0, 6.0, np.nan],  # psi
            "lack_of_fit": [None, "R2 of the CI fit is 0.5 (below 0.8)", None],
            "preferred_layers": [2.0, 1.0, np.nan],
            "interfaces": ["4,10", "3", None],  # in
            "lat": [41.5, np.nan, 41.6],
            "lon": [-93.1, np.nan, -93.2],
            "units": ["us"] * 3,
        }
    )
    recs = FL.records_from_table(from_table(pa.Table.from_pandas(df)), {"units": "us"})
    assert [r["label"] for r in recs] == ["1", "2", "3"]
    np.testing.assert_allclose(recs[0]["interfaces"], [4 * INCH, 10 * INCH])
    assert recs[0]["layers_preferred"] == 2 and recs[1]["layers_preferred"] == 1
    assert FL.panel_of({**recs[0], "depth": [0.1], "ci": [1.0]})["interfaces"] == pytest.approx(
        [4 * INCH, 10 * INCH]
    )
    assert "interfaces" not in FL.panel_of({**recs[1], "depth": [0.1], "ci": [1.0]})
    # US to SI by hand: kc [lb/in^(n+1)] -> [kN/m^(n+1)], psi -> kPa
    assert recs[0]["kc"] == pytest.approx(2.0 * LBF_KN / INCH ** (0.8 + 1), rel=1e-9)
    assert recs[0]["kphi"] == pytest.approx(10.0 * LBF_KN / INCH ** (0.8 + 2), rel=1e-9)
    assert recs[0]["cc"] == pytest.approx(PSI_KPA, rel=1e-9)
    assert recs[1]["rmsd"] == pytest.approx(6.0 * PSI_KPA, rel=1e-9)
    assert [r["flagged"] for r in recs] == [False, True, False]
    assert (recs[0]["lon"], recs[0]["lat"]) == (-93.1, 41.5) and recs[1]["lon"] is None
    assert recs[2]["status"] == "error" and recs[2].get("n") is None
    sec = FL.summary_section(recs)
    pairs = sec["parts"][0]["pairs"]
    assert pairs["two or more layers win (BIC)"] == "1 of 2 (50%)"
    assert pairs["flagged for lack of fit"] == "1 of 2 (50%)"
    assert pairs["located (lon/lat)"] == "2 of 3 (67%)"

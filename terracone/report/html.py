"""Self-contained HTML reports of terracone results.

One file, no request to any other host (PNG data URIs, inline CSS and script,
a Content-Security-Policy; the layout: ``docs/report.md``).

A report is a *document*: a title, metadata and sections, each a list of
parts (``text``, ``list``, ``kv``, ``figure``, ``table``, ``html``).  The
renderers here turn the JSON documents of ``terracone predict``, ``learn``
and ``evaluate``, and the output directory of ``terracone batch``, into such
documents; :mod:`terracone.report.reproduce` stores its own in ``reproduce.json``.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from terracone import __version__
from terracone.data import TerrainParameters
from terracone.physics import units as u
from terracone.report import fields as FL
from terracone.report import figures as F
from terracone.report.parts import figure_part, kv_part, list_part, table_part, text_part
from terracone.report.tables import (
    Table,
    flat_agreement_table,
    fmt_value,
    identifiability_table,
    mark_bounds,
    parameters_table,
)
from terracone.resultunits import from_si

__all__ = [
    "render_document",
    "predict_document",
    "learn_document",
    "evaluate_document",
    "batch_document",
    "MAX_FIGURE_PROFILES",
]

#: At most this many profiles get predicted plate curves (in figures of 8); every profile
#: gets a small-multiples panel (:mod:`terracone.report.fields`) and a table row.
MAX_FIGURE_PROFILES = 24
_PER_FIGURE = 8

_CSP = (
    "default-src 'none'; img-src data:; style-src 'unsafe-inline'; "
    "script-src 'unsafe-inline'; base-uri 'none'; form-action 'none'"
)

_CSS = """
:root { color-scheme: light; --ink: #1b1b1b; --muted: #555; --line: #c8c8c8; --accent: #0b5394; }
* { box-sizing: border-box; }
html { -webkit-text-size-adjust: 100%; text-size-adjust: 100%; }
body { margin: 0; color: var(--ink); background: #fff; line-height: 1.5;
  font: 16px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
header.top, main, footer { max-width: 84rem; margin: 0 auto; padding: 0 clamp(0.75rem, 3vw, 2rem); }
header.top { padding-top: 1rem; border-bottom: 3px solid var(--accent); }
h1 { font-size: clamp(1.35rem, 4vw, 2rem); margin: 0.2rem 0 0.4rem; line-height: 1.2; }
h2 { font-size: clamp(1.15rem, 3vw, 1.5rem); margin-top: 2.2rem; border-bottom: 1px solid var(--line); }
h3 { font-size: 1.1rem; margin-top: 1.6rem; }
p, li { max-width: 52rem; overflow-wrap: anywhere; }
.subtitle { color: var(--muted); margin: 0 0 0.8rem; }
.banner { border: 2px solid #b58100; background: #fff4d6; padding: 0.6rem 0.9rem; margin: 1rem 0;
  font-weight: 600; }
.tag.synthetic { display: inline-block; margin: 0.2rem 0; padding: 0.05rem 0.45rem; font-size: 0.75rem;
  font-weight: 700; letter-spacing: 0.04em; color: #5c3d00; background: #ffe7a6; border: 1px solid #b58100; }
nav.toc { background: #f4f6f9; border: 1px solid var(--line); padding: 0.5rem 1rem; margin: 1rem 0; }
nav.toc ol { margin: 0.3rem 0; padding-left: 1.3rem; }
figure { margin: 1.2rem 0 1.8rem; max-width: 100%; }
figure img { display: block; max-width: 100%; height: auto; border: 1px solid #e2e2e2; }
figcaption { font-size: 0.92rem; color: #333; margin-top: 0.35rem; max-width: 52rem; }
.table-block { margin: 1rem 0 1.6rem; }
.table-wrap { overflow-x: auto; -webkit-overflow-scrolling: touch; max-width: 100%;
  border: 1px solid var(--line); }
table { border-collapse: collapse; font-size: 0.86rem; font-variant-numeric: tabular-nums;
  min-width: 100%; }
.table-title { font-weight: 600; margin: 0.3rem 0 0.35rem; max-width: 60rem; }
td.t { text-align: left; }
th, td { border: 1px solid var(--line); padding: 0.22rem 0.5rem; white-space: nowrap; text-align: right; }
thead th { background: #e9eef5; text-align: center; }
tbody th { text-align: left; font-weight: 600; background: #fafafa; }
td.hl, th.hl { background: #ffe7a6; font-weight: 700; }
tbody tr:nth-child(even) td { background: #fbfbfb; }
ul.notes { font-size: 0.86rem; color: var(--muted); margin: 0.4rem 0 0; }
dl.kv { display: grid; grid-template-columns: minmax(8rem, max-content) 1fr; gap: 0.15rem 1rem;
  margin: 0.5rem 0 1rem; }
dl.kv dt { font-weight: 600; }
dl.kv dd { margin: 0; overflow-wrap: anywhere; font-family: ui-monospace, SFMono-Regular, Menlo, monospace;
  font-size: 0.88rem; }
code { font-family: ui-monospace, SFMono-Regular, Menlo, monospace; font-size: 0.9em; }
footer { color: var(--muted); font-size: 0.85rem; border-top: 1px solid var(--line); margin-top: 2.5rem;
  padding-top: 0.8rem; padding-bottom: 2rem; }
th button.sort { font: inherit; font-weight: 600; color: inherit; background: none; border: 0;
  padding: 0; margin: 0; cursor: pointer; white-space: nowrap; text-align: inherit; }
th button.sort::after { content: " \\2195"; color: #8a8a8a; font-weight: 400; }
th[aria-sort="ascending"] button.sort::after { content: " \\25B2"; color: var(--accent); }
th[aria-sort="descending"] button.sort::after { content: " \\25BC"; color: var(--accent); }
th button.sort:focus-visible { outline: 2px solid var(--accent); outline-offset: 1px; }
.table-wrap:focus-visible { outline: 2px solid var(--accent); }
.table-wrap.tall { max-height: 70vh; overflow: auto; }
.table-wrap.tall thead th { position: sticky; top: 0; z-index: 1; }
.table-wrap.tall tbody th { position: sticky; left: 0; z-index: 1; }
.table-wrap.tall thead th:first-child { left: 0; z-index: 2; }
.fig-scroll { overflow-x: auto; max-width: 100%; -webkit-overflow-scrolling: touch; }
details.reasons { font-size: 0.88rem; margin: 0.4rem 0 1.2rem; max-width: 60rem; }
details.reasons summary { cursor: pointer; font-weight: 600; }
details.reasons li { overflow-wrap: anywhere; }
@media (max-width: 640px) {
  body { font-size: 15px; }
  dl.kv { grid-template-columns: 1fr; }
  dl.kv dd { margin-bottom: 0.4rem; }
  table { font-size: 0.78rem; }
  nav.toc { padding: 0.4rem 0.7rem; }
  figure.wide img { max-width: none; width: 720px; }
}
@media print { nav.toc { display: none; } .table-wrap { overflow: visible; } }
"""

# Runs after load: counts decoded images and errors into #tc-selfcheck, so a
# headless browser (--dump-dom) or a reader can see that the file is whole.
_HEAD_SCRIPT = """
window.__tcErrors = [];
window.addEventListener('error', function (e) {
  window.__tcErrors.push(String(e.message || (e.target && e.target.tagName) || 'error'));
}, true);
document.addEventListener('securitypolicyviolation', function (e) {
  window.__tcErrors.push('blocked by the content security policy: ' + e.blockedURI);
});
// Sortable tables: a click on a column heading's button sorts the body rows
// by that column (numbers as numbers, empty cells last); a second click
// reverses the order.
function tcSortKey(row, col) {
  var c = row.cells[col], v = c ? c.getAttribute('data-v') : null;
  if (v === null && c) { v = c.textContent; }
  if (v === null || v === '' || v === '-') { return {k: 2, v: 0}; }
  var x = Number(v);
  return isFinite(x) ? {k: 0, v: x} : {k: 1, v: String(v)};
}
function tcSort(th) {
  var table = th.closest('table'), col = Number(th.getAttribute('data-col'));
  var dir = th.getAttribute('aria-sort') === 'ascending' ? 'descending' : 'ascending';
  var heads = table.querySelectorAll('th[aria-sort]');
  for (var i = 0; i < heads.length; i++) { heads[i].removeAttribute('aria-sort'); }
  th.setAttribute('aria-sort', dir);
  var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
  var keyed = rows.map(function (r, i) { return {r: r, i: i, s: tcSortKey(r, col)}; });
  var sign = dir === 'ascending' ? 1 : -1;
  keyed.sort(function (a, b) {
    if (a.s.k !== b.s.k) { return a.s.k - b.s.k; }
    if (a.s.k === 2) { return a.i - b.i; }
    var d = a.s.k === 0 ? a.s.v - b.s.v : a.s.v.localeCompare(b.s.v, undefined, {numeric: true});
    return d === 0 ? a.i - b.i : sign * d;
  });
  for (var j = 0; j < keyed.length; j++) { body.appendChild(keyed[j].r); }
}
document.addEventListener('click', function (e) {
  var b = e.target && e.target.closest ? e.target.closest('table.sortable th[data-col] button') : null;
  if (b) { tcSort(b.closest('th')); }
});
window.addEventListener('load', function () {
  var imgs = document.images, ok = 0;
  for (var i = 0; i < imgs.length; i++) {
    if (imgs[i].complete && imgs[i].naturalWidth > 0) { ok++; }
  }
  var el = document.getElementById('tc-selfcheck');
  if (!el) { return; }
  el.setAttribute('data-images-ok', String(ok));
  el.setAttribute('data-images-total', String(imgs.length));
  el.setAttribute('data-errors', String(window.__tcErrors.length));
  el.setAttribute('data-page-width', String(document.documentElement.scrollWidth));
  el.setAttribute('data-view-width', String(document.documentElement.clientWidth));
  el.textContent = 'Browser self-check: ' + ok + ' of ' + imgs.length + ' figures decoded, ' +
    window.__tcErrors.length + ' errors' +
    (window.__tcErrors.length ? ' (' + window.__tcErrors.join('; ') + ')' : '') + '.';
});
"""


def _kv_value(v: Any) -> str:
    if isinstance(v, float):
        return fmt_value(v, 6)
    if isinstance(v, dict | list):
        return json.dumps(v, default=str)
    return "-" if v is None else str(v)


def _render_part(p: Mapping[str, Any], base: Path | None, counters: dict[str, int]) -> str:
    e = html.escape
    t = p["type"]
    if t == "text":
        return f"<p>{e(p['text'])}</p>"
    if t == "list":
        return "<ul>" + "".join(f"<li>{e(x)}</li>" for x in p["items"]) + "</ul>"
    if t == "kv":
        rows = "".join(f"<dt>{e(k)}</dt><dd>{e(_kv_value(v))}</dd>" for k, v in p["pairs"].items())
        return f'<dl class="kv">{rows}</dl>'
    if t == "html":
        return str(p["html"])
    if t == "figure":
        data = p.get("png_bytes")
        if data is None and p.get("png") and base is not None:
            f = base / p["png"]
            data = f.read_bytes() if f.exists() else None
        counters["figure"] += 1
        k = counters["figure"]
        cap = f"Figure {k}. {p.get('caption', '')}"
        if data is None:
            return f'<p class="notes">{e(cap)} (figure file {e(str(p.get("png")))} missing)</p>'
        b64 = base64.b64encode(data).decode("ascii")
        alt = p.get("alt") or p.get("caption", "figure")
        names = [x for x in (p.get("png"), p.get("svg")) if x]
        links = " Files: " + ", ".join(f"<code>{e(x)}</code>" for x in names) + "." if names else ""
        img = (
            f'<img src="data:image/png;base64,{b64}" alt="{e(alt)}" loading="eager" '
            'decoding="sync">'
        )
        if p.get("wide"):  # the image scrolls sideways in its own box on a phone
            img = f'<div class="fig-scroll" tabindex="0">{img}</div>'
        wide = ' class="wide"' if p.get("wide") else ""
        return f'<figure id="fig-{k}"{wide}>{img}<figcaption>{e(cap)}{links}</figcaption></figure>'
    if t == "table":
        tab = p["table"]
        if not isinstance(tab, Table):
            tab = Table.from_dict(tab)
        counters["table"] += 1
        sortable = len(tab.rows) >= 3 if p.get("sortable") is None else bool(p["sortable"])
        frag = tab.to_html(max_rows=p.get("max_rows"), sortable=sortable)
        if p.get("tall"):
            frag = frag.replace('class="table-wrap"', 'class="table-wrap tall"', 1)
        label = f"Table {counters['table']}. "
        return frag.replace('<p class="table-title">', f'<p class="table-title">{e(label)}', 1)
    raise ValueError(f"unknown report part {t!r}")


def render_document(doc: Mapping[str, Any], base_dir: str | Path | None = None) -> str:
    """HTML text of a report document.

    ``doc``: ``title``, optional ``subtitle``, ``synthetic`` (bool: a banner
    on top), ``meta`` (key-value pairs shown under the title) and
    ``sections`` (each ``id``, ``heading``, ``parts``).  Figure parts carry
    ``png_bytes`` or a ``png`` path relative to ``base_dir``.
    """
    e = html.escape
    base = Path(base_dir) if base_dir is not None else None
    counters = {"figure": 0, "table": 0}
    title = str(doc.get("title", "terracone report"))
    body = ['<header class="top">', f"<h1>{e(title)}</h1>"]
    if doc.get("subtitle"):
        body.append(f'<p class="subtitle">{e(doc["subtitle"])}</p>')
    body.append("</header><main>")
    if doc.get("synthetic"):
        default = "The data in this report were generated by terracone; they are not measurements."
        banner = e(str(doc.get("synthetic_text", default)))
        body.append(f'<p class="banner">SYNTHETIC DATA. {banner}</p>')
    meta = dict(doc.get("meta", {}))
    meta.setdefault("report written by", f"terracone {__version__}")
    meta.setdefault("written", datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"))
    body.append(_render_part(kv_part(meta), base, counters))
    sections = list(doc.get("sections", []))
    if len(sections) > 2:
        body.append('<nav class="toc" aria-label="Contents"><strong>Contents</strong><ol>')
        for s in sections:
            body.append(f'<li><a href="#{e(s["id"])}">{e(s["heading"])}</a></li>')
        body.append("</ol></nav>")
    for s in sections:
        body.append(f'<section id="{e(s["id"])}"><h2>{e(s["heading"])}</h2>')
        for p in s.get("parts", []):
            body.append(_render_part(p, base, counters))
        body.append("</section>")
    body.append("</main>")
    body.append(
        "<footer>"
        f"<p>Generated by terracone {e(__version__)}: Bekker-Wong terrain parameters from cone "
        "penetrometer data, after Huang, Wong, Preston-Thomas and Jayakumar, "
        "&ldquo;Predicting terrain parameters for physics-based vehicle mobility models from "
        "cone index data&rdquo;. This file is self-contained: it loads nothing from any "
        "host.</p>"
        '<p id="tc-selfcheck" data-images-ok="" data-images-total="" data-errors="">'
        "Browser self-check: not run (scripts disabled).</p>"
        "</footer>"
    )
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">'
        f'<meta name="generator" content="terracone {e(__version__)}">'
        f"<title>{e(title)}</title>"
        f"<style>{_CSS}</style><script>{_HEAD_SCRIPT}</script></head>\n<body>\n"
        + "\n".join(body)
        + "\n</body></html>\n"
    )


# ---------------------------------------------------------------------------
# helpers for the JSON documents of the CLI
# ---------------------------------------------------------------------------


def _units_of(doc: Mapping[str, Any], default: str = "si") -> str:
    un = (doc.get("settings") or {}).get("units") or doc.get("units") or default
    return un if un in ("si", "us") else default


def _synthetic(doc: Mapping[str, Any]) -> dict[str, Any]:
    """Banner keys for results that say they come from synthetic data."""
    if not doc.get("synthetic"):
        return {}
    out: dict[str, Any] = {"synthetic": True}
    if doc.get("note"):
        out["synthetic_text"] = str(doc["note"])
    return out


def _mark_settings_bounds(tab, rows, settings: Mapping[str, Any], units: str) -> None:
    """Highlight parameters on the bounds recorded in the settings (defaults otherwise)."""
    from terracone.inverse.bounds import Bounds

    b = settings.get("bounds") or {}
    d = Bounds()
    cc = b.get("cc")
    cc_si = tuple(float(v) for v in u.pressure_to_si(cc, units)) if cc else d.cc
    phic = tuple(b.get("phic_deg") or b.get("phic") or d.phic_deg)
    n = tuple(b.get("n") or d.n)
    if settings.get("calibration"):
        cc_si, phic = None, None  # fixed by the calibration
    mark_bounds(tab, rows, cc=cc_si, phic_deg=phic, n=n)


def _settings_pairs(settings: Mapping[str, Any]) -> dict[str, Any]:
    """Settings flattened one level: a nested ``{"bounds": {"n": ...}}`` becomes ``bounds.n``."""
    out: dict[str, Any] = {}
    for k, v in settings.items():
        out.update({f"{k}.{k2}": v2 for k2, v2 in v.items()} if isinstance(v, Mapping) else {k: v})
    return out


def _mm(r: Mapping[str, Any]) -> float | None:
    return None if r.get("r_min") is None else r["r_min"] * 1000.0


_FIT_EXTRA = (
    ("RMSD of CI", "kPa", lambda r: r.get("rmsd")),
    (
        "RMSD of CI",
        "psi",
        lambda r: from_si(r.get("rmsd"), "pressure", "us"),
    ),
    ("R2 of CI", "", lambda r: r.get("r2_ci")),
    ("model", "", lambda r: r.get("model")),
    ("r_min", "mm", _mm),
)


# ---------------------------------------------------------------------------
# predict
# ---------------------------------------------------------------------------


def predict_document(
    doc: Mapping[str, Any], *, source: str | None = None, map_by: str = "n"
) -> dict[str, Any]:
    """Report document of a ``terracone predict --json`` result.

    ``map_by``: the parameter that colours the map of located profiles
    (:data:`terracone.report.fields.MAP_BY`).
    """
    units = _units_of(doc)
    profiles = list(doc.get("profiles") or [])
    settings = dict(doc.get("settings") or {})
    recs = FL.records_from_predict(profiles, units)
    sections = FL.field_sections(recs, units=units, map_by=map_by)
    sections += _predict_input_sections(doc, profiles, settings, units, source)
    sections += _predict_table_sections(profiles, recs, settings, units)
    # fitted profiles with measured points, as field records (SI) beside their JSON
    drawn = [(r, p) for r, p in zip(recs, profiles) if r["status"] == "ok" and "depth" in r]
    figs = _predict_ci_figures([r for r, _ in drawn])
    figs += _predict_plate_figures([p for p in profiles if p.get("status", "ok") == "ok"], units)
    figs += _predict_ridge_figure(drawn[0] if drawn else None)
    sections.append({"id": "figures", "heading": "Figures", "parts": figs})
    return {
        "title": "terracone report: prediction from cone index",
        **_synthetic(doc),
        "subtitle": f"{len(profiles)} CI profile(s) from {doc.get('input', '?')}",
        "meta": {"results": source, "command": doc.get("command", "predict")},
        "sections": sections,
    }


def _predict_input_sections(
    doc: Mapping[str, Any],
    profiles: list[Any],
    settings: dict[str, Any],
    units: str,
    source: str | None,
) -> list[dict[str, Any]]:
    """The Inputs and Settings sections of :func:`predict_document`."""
    bad = [p for p in profiles if p.get("status", "ok") != "ok"]
    inputs = {
        "results file": source,
        "CI input": doc.get("input"),
        "profiles": len(profiles),
        "fitted": len(profiles) - len(bad),
        "not fitted": len(bad),
        "results written by": f"terracone {doc.get('terracone', '?')}",
    }
    parts: list[dict[str, Any]] = [kv_part(inputs)]
    if bad:
        parts.append(text_part("Profiles that could not be fitted:"))
        parts.append(list_part([f"{p.get('id')}: {p.get('error')}" for p in bad]))
    settings_parts = [
        kv_part(_settings_pairs(settings) or {"settings": "(none recorded)"}),
        text_part(
            "Units of the results file: "
            + units
            + ". Tables below give SI and US customary columns; kc and kphi convert "
            "with n (their units carry n)."
        ),
    ]
    return [
        {"id": "inputs", "heading": "Inputs", "parts": parts},
        {"id": "settings", "heading": "Settings", "parts": settings_parts},
    ]


def _predict_table_sections(
    profiles: list[Any], recs: list[dict[str, Any]], settings: dict[str, Any], units: str
) -> list[dict[str, Any]]:
    """The Parameters and Identifiability sections of :func:`predict_document`."""
    fitted = [r for r in recs if r.get("n") is not None]
    tab = parameters_table(
        fitted,
        key="parameters",
        title="Predicted Bekker P-S and cone-terrain shear parameters (as Tables 4-1, 4-3)",
        first="Profile",
        extra=_FIT_EXTRA,
        notes=[
            "Prediction process (section 3.3.2): improved cone model, eqs. (2-2) to (2-7).",
            "With fully mobilised shear phic trades exactly against a common scale of kc and "
            "kphi; without a calibration the reported phic is the middle of the interval that "
            "fits equally well (see the identifiability table and the ridge figure).",
        ],
    )
    _mark_settings_bounds(tab, fitted, settings, units)
    ident = identifiability_table(
        profiles,
        key="identifiability",
        title="What each CI profile determines",
        fixed=("phic", "cc") if settings.get("calibration") else (),
        notes=[
            '"undetermined": the approximate 95% profile interval covers half the search '
            'range or more (from "undetermined"); "determined", "weakly determined", "set by '
            'prior": from the posterior when predict ran with --uncertainty.',
            "phic~scale(kc,kphi): phic and the common scale of kc and kphi trade exactly.",
        ],
    )
    return [
        {"id": "parameters", "heading": "Parameters", "parts": [table_part(tab, max_rows=500)]},
        {
            "id": "identifiability",
            "heading": "Identifiability",
            "parts": [table_part(ident, max_rows=500)],
        },
    ]


def _predict_ci_figures(curves: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """CI fits (Figure 4-1) and the Janosi comparison (Figure 2-1) of the first profile.

    ``curves``: field records of the fitted profiles with measured points.
    """
    figs: list[dict[str, Any]] = []
    if 0 < len(curves) <= _PER_FIGURE:
        fig = F.fig_ci_fit(curves, title="Measured and predicted CI-sinkage curves")
        figs.append(
            figure_part(
                fig,
                "Measured (dashed, open markers) and predicted (solid) cone index against "
                "cone-base depth, as Figure 4-1 of the paper.",
            )
        )
    elif curves:
        figs.append(
            text_part(
                f"The {len(curves)} fitted profiles are drawn one to a panel under 'Every "
                "profile' (one overlay of Figure 4-1 is drawn for at most "
                f"{_PER_FIGURE} profiles)."
            )
        )
    c = curves[0] if curves else None
    zpos = None if c is None else c["depth"] >= 0
    if c is not None and c.get("n") is not None and zpos.sum() >= 2:
        fig = F.fig_janosi(
            [{"id": c["id"], "depth": c["depth"][zpos], "ci": c["ci"][zpos]}],
            c,
            improved_params={**c, "label": "improved model eq. (2-7), predicted parameters"},
            params_label="predicted kc, kphi, n",
            title=f"{c['id']}: measured CI and the Janosi equation (2-1)",
        )
        figs.append(
            figure_part(
                fig,
                f"As Figure 2-1 of the paper: measured CI of {c['id']} against the Janosi "
                "equation (2-1) evaluated with the kc, kphi and n predicted by the improved "
                "model. The gap is what the improved model adds: shear on the cone "
                "surface and kc over the local radius rather than the base diameter.",
            )
        )
    return figs


def _si_plate(pid: str, c: Mapping[str, Any], un: str, pressures: Sequence[str]) -> dict:
    """A plate curve or band of a predict JSON profile in SI (radius, sinkage [m]; kPa)."""
    out = {"id": pid, "radius": float(u.length_to_si(c["radius"], un))}
    out["sinkage"] = u.length_to_si(c["sinkage"], un)
    out.update({k: None if c.get(k) is None else u.pressure_to_si(c[k], un) for k in pressures})
    return out


def _predict_plate_figures(ok: list[Any], units: str) -> list[dict[str, Any]]:
    """Predicted plate curves and posterior bands (Figures 4-2, 4-3(b))."""
    plate_pred, plate_bands = [], []
    for p in ok[:MAX_FIGURE_PROFILES]:
        pid, un = str(p.get("id")), p.get("units") or units
        plate_pred += [_si_plate(pid, pl, un, ["pressure"]) for pl in p.get("plates") or []]
        for b in p.get("plate_bands") or []:
            band = _si_plate(pid, b, un, ["lo", "hi", "median"])
            plate_bands.append({**band, "label": f"{p.get('id')} band"})
    if not (plate_pred or plate_bands):
        return [
            text_part(
                "No plate curves in the results: run predict with --plates R1,R2 (and "
                "--uncertainty for bands) to draw them."
            )
        ]
    figs: list[dict[str, Any]] = []
    ids = list(dict.fromkeys(s["id"] for s in plate_pred + plate_bands))
    for k in range(0, len(ids), _PER_FIGURE):
        sel = set(ids[k : k + _PER_FIGURE])
        fig = F.fig_plate_fit(
            [],
            [s for s in plate_pred if s["id"] in sel],
            [b for b in plate_bands if b["id"] in sel],
            title="Predicted plate pressure-sinkage curves"
            + (f" ({k // _PER_FIGURE + 1})" if len(ids) > _PER_FIGURE else ""),
        )
        figs.append(
            figure_part(
                fig,
                "Plate pressure-sinkage curves predicted from the parameters (Bekker "
                "equation, or RM1 below r_min), one panel per plate size, as Figures 4-2 "
                "and 4-3(b) of the paper"
                + ("; hatched: the posterior band of predict --uncertainty" if plate_bands else "")
                + ". The results file holds no measured plate curves.",
            )
        )
    return figs


def _predict_ridge_figure(first: tuple[dict[str, Any], Any] | None) -> list[dict[str, Any]]:
    """The ridge of equally good fits of the first drawable profile (its record and JSON)."""
    if first is None:
        return []
    c, profile = first
    try:
        fig = F.fig_ridge(
            c["depth"],
            c["ci"],
            profile_id=c["id"],
            cone=str(profile.get("cone") or "asabe-large"),
            model=c.get("model") or "rm0",
            r_min=c.get("r_min"),
            reference={"n": c.get("n"), "phic_deg": c.get("phic_deg")},
            reference_label="reported",
        )
    except (ValueError, FloatingPointError) as exc:  # pragma: no cover - defensive
        return [text_part(f"Ridge figure not drawn: {exc}")]
    return [
        figure_part(
            fig,
            f"The ridge of equally good fits for {c['id']} (not in the paper): with "
            "fully mobilised shear, phic and a common scale of kc and kphi trade "
            "exactly, so the CI alone fixes n but not phic. Contours give the RMSD as "
            "a multiple of its minimum; kc, kphi and cc are re-fitted exactly at each "
            "point (bounded least squares). Default search bounds.",
        )
    ]


# ---------------------------------------------------------------------------
# learn
# ---------------------------------------------------------------------------


def learn_document(doc: Mapping[str, Any], *, source: str | None = None) -> dict[str, Any]:
    """Report document of a ``terracone learn --json`` result."""
    units = _units_of(doc)
    tp = None
    if doc.get("n") is not None:
        tp = replace(TerrainParameters.from_dict(doc, units=doc.get("units") or units), K_cone=None)
    sp = {"id": doc.get("terrain", "learned"), **(asdict(tp) if tp else {})}
    crit = doc.get("criteria") or {}
    inputs = {
        "results file": source,
        "terrain": doc.get("terrain"),
        "model": doc.get("model"),
        "units of the file": units,
        "plate pair": doc.get("plate_pair"),
        "calibration saved to": doc.get("saved"),
        "library name": doc.get("saved_as"),
        "results written by": f"terracone {doc.get('terracone', '?')}",
        "fit criterion": f"every CV <= {crit.get('max_cv')}: "
        + ("satisfied" if crit.get("satisfied") else "NOT satisfied")
        + f" (worst {fmt_value(crit.get('worst_cv'))})",
    }
    parts = [table_part(t) for t in _learn_tables(doc, sp, units)]
    parts += _learn_figures(doc, tp, units)
    return {
        "title": "terracone report: learning from cone and plate tests",
        **_synthetic(doc),
        "subtitle": f"terrain {doc.get('terrain', '?')}",
        "meta": {"results": source, "command": "learn"},
        "sections": [
            {"id": "inputs", "heading": "Inputs and settings", "parts": [kv_part(inputs)]},
            {"id": "results", "heading": "Results", "parts": parts},
        ],
    }


def _learn_tables(doc: Mapping[str, Any], sp: dict[str, Any], units: str) -> list[Table]:
    """The learned parameters, what the data determine, and the fit per data set."""
    tab = parameters_table(
        [sp],
        key="learned",
        title="Learned parameters (learning process, section 3.3.1)",
        first="Terrain",
        extra=_FIT_EXTRA[3:],
    )
    und = list(doc.get("undetermined") or [])
    iv = doc.get("profile_intervals") or {}
    ident_rows = []
    for name in ("kc", "kphi", "n", "cc", "phic_deg", "r_min"):
        status = "undetermined" if name in und else "determined"
        rng = iv.get(name)
        ident_rows.append([name, status, None if not rng else f"{rng[0]:.4g} to {rng[1]:.4g}"])
    ident = Table(
        "identifiability",
        "What the learning data determine",
        [("Parameter", ""), ("Status", ""), ("Approx. 95% interval (file units)", "")],
        ident_rows,
        notes=[
            "undetermined: the profile interval covers half the search range or more. kc and "
            "kphi are not profiled by learn; they follow n and the plates."
        ],
    )
    ds_rows = []
    for x in doc.get("datasets") or []:
        rm, b = x.get("rmsd"), x.get("b")
        rm_si = None if rm is None else float(u.pressure_to_si(rm, units))
        rm_us = from_si(rm_si, "pressure", "us")
        b_cm = None if b is None else float(b) * 100
        ds_rows.append([x.get("id"), x.get("kind"), b_cm, rm_si, rm_us, x.get("cv")])
    ds_tab = Table(
        "datasets",
        "Fit per data set",
        [("Data set", ""), ("Kind", ""), ("Plate size b", "cm")]
        + [("RMSD", "kPa"), ("RMSD", "psi"), ("CV", "")],
        ds_rows,
        notes=["CV = RMSD / mean measured value; the objective sums it over the data sets."],
    )
    return [tab, ident, ds_tab]


def _learn_figures(
    doc: Mapping[str, Any], params: TerrainParameters | None, units: str
) -> list[dict[str, Any]]:
    """The CV per data set, and the plate curves of the learned parameters."""
    ds = list(doc.get("datasets") or [])
    crit = doc.get("criteria") or {}
    parts = []
    if ds:
        fig = F.fig_bars(
            [str(x.get("id")) for x in ds],
            {"CV of the fit": [float(x.get("cv") or 0.0) for x in ds]},
            ylabel="CV = RMSD / mean [-]",
            title="Fit of the learned parameters per data set",
            hline=crit.get("max_cv"),
            hline_label="fit criterion",
        )
        parts.append(
            figure_part(fig, "CV of each CI profile and plate test at the learned parameters.")
        )
    if params is not None:
        pair = doc.get("plate_pair")
        radii = [float(v) for v in u.length_to_si(pair, units)] if pair else [0.0375, 0.05]
        from terracone.inverse.evaluate import predicted_plate_pressure

        s = np.linspace(0.0, 0.1, 41)
        pred = [
            {
                "id": str(doc.get("terrain", "learned")),
                "radius": r,
                "sinkage": s,
                "pressure": predicted_plate_pressure(params, s, r, tuple(radii) if pair else None),
            }
            for r in radii
        ]
        fig = F.fig_plate_fit(
            [], pred, one_panel=True, title="Plate P-S curves of the learned parameters"
        )
        parts.append(
            figure_part(
                fig,
                "Plate pressure-sinkage curves of the learned parameters for the plate sizes of "
                "the learning data (the learn JSON holds no measured curves).",
            )
        )
    return parts


# ---------------------------------------------------------------------------
# evaluate
# ---------------------------------------------------------------------------


def evaluate_document(doc: Mapping[str, Any], *, source: str | None = None) -> dict[str, Any]:
    """Report document of a ``terracone evaluate --json`` result."""
    units = _units_of(doc)
    rows = list(doc.get("plates") or [])
    tab = flat_agreement_table(
        rows,
        key="agreement",
        title="Predicted against measured plate P-S curves (as Tables 4-2, 4-4)",
        units=units,
        notes=["R: Pearson correlation; R2 = R^2; CV = RMSD / mean measured pressure."],
    )
    parts: list[dict[str, Any]] = [
        kv_part(
            {
                "results file": source,
                "comparisons": len(rows),
                "predictions": len({r.get("prediction") for r in rows}),
                "plate tests": len({r.get("test") for r in rows}),
                "units of the file": units,
            }
        ),
        table_part(tab, max_rows=500),
    ]
    if rows:
        labels = [f"{r.get('prediction')} / {r.get('test')}" for r in rows[:40]]
        fig = F.fig_bars(
            labels,
            {k: [float(r.get(k) or 0.0) for r in rows[:40]] for k in ("R2", "CV")},
            ylabel="R2 and CV [-]",
            title="Agreement of predicted and measured plate curves",
        )
        parts.append(
            figure_part(
                fig,
                "R2 (higher is better) and CV (lower is better) of each prediction against each "
                "plate test" + (" (first 40)" if len(rows) > 40 else "") + ".",
            )
        )
    return {
        "title": "terracone report: evaluation against plate tests",
        **_synthetic(doc),
        "meta": {"results": source, "command": "evaluate"},
        "sections": [{"id": "agreement", "heading": "Agreement", "parts": parts}],
    }


# ---------------------------------------------------------------------------
# batch
# ---------------------------------------------------------------------------


def batch_document(results: Any, path: str | Path, *, map_by: str = "n") -> dict[str, Any]:
    """Report document of a prediction table: a ``terracone batch`` directory or ``predict --parquet``.

    ``results``: :func:`terracone.result.read_results` of ``path`` (SI).
    """
    d = Path(path)
    summary = _batch_summary(d) if d.is_dir() else {}
    n_parts = len(list(d.glob("part-*.parquet"))) if d.is_dir() else 1
    settings = {"units": _units_of(summary), **results.settings}
    n_total = len(results)
    ok = [r for r in results if r.ok]
    recs = FL.records_from_table(results, settings) if n_total else []
    sections = FL.field_sections(recs, units=settings["units"], map_by=map_by) if n_total else []
    meta_pairs = {
        "directory" if d.is_dir() else "file": str(d),
        "part files": n_parts,
        "profiles": n_total,
        "fitted": len(ok),
        "not fitted": n_total - len(ok),
    }
    parts = [kv_part(meta_pairs)]
    if summary.get("problems"):
        parts.append(text_part("Problems reported by the run:"))
        parts.append(list_part([str(x) for x in summary["problems"]]))
    if summary:
        parts.append(text_part("From _summary.json:"))
        parts.append(kv_part(_settings_pairs(summary)))
    sections.append({"id": "inputs", "heading": "Inputs and settings", "parts": parts})
    fitted = [x for x in recs if x.get("n") is not None]
    tab = parameters_table(
        fitted,
        key="parameters",
        title="Predicted parameters per profile (as Tables 4-1, 4-3)",
        first="Profile",
        extra=_FIT_EXTRA[:3],
    )
    _mark_settings_bounds(tab, fitted, summary.get("settings") or {}, _units_of(summary))
    tparts = [table_part(tab, max_rows=200)]
    errs = [r for r in results if not r.ok]
    if errs:
        tparts.append(text_part("Profiles not fitted (first 50):"))
        tparts.append(list_part([f"{r.id}: {r.error}" for r in errs[:50]]))
    sections.append({"id": "parameters", "heading": "Parameters", "parts": tparts})
    if n_total:
        sections.append(_table_identifiability(results, settings))
    kind = "batch prediction" if d.is_dir() else "prediction table"
    return {
        "title": f"terracone report: {kind}",
        "subtitle": f"{n_total} profiles in {n_parts} part file(s)",
        "meta": {"results": str(d), "command": "batch" if d.is_dir() else "predict"},
        "sections": sections,
    }


def _batch_summary(directory: Path) -> dict[str, Any]:
    """``_summary.json`` of a batch directory; empty when missing or unreadable."""
    try:
        return json.loads((directory / "_summary.json").read_text())
    except (OSError, json.JSONDecodeError):
        return {}


def _table_identifiability(results: Any, settings: Mapping[str, Any]) -> dict[str, Any]:
    """The identifiability section of a prediction table's report (first 200 profiles)."""
    ident_rows = [
        {
            "id": r.id,
            "status": r.status,
            "undetermined": list(r.undetermined),
            "phic_range_deg": None if r.phic_range is None else list(r.phic_range),
            "intervals": {k: list(v) for k, v in r.profile_intervals.items() if k == "n"},
        }
        for r in results[:200]
    ]
    fixed = ("phic", "cc") if settings.get("calibration") else ()
    ident = identifiability_table(
        ident_rows,
        key="identifiability",
        title="What each CI profile determines (first 200 profiles)",
        fixed=fixed,
        assessed=("n", "phic"),
        notes=[
            "From the batch output's undetermined, phic_lo/hi and n_lo/hi columns; the "
            "batch profiles only n and phic."
        ],
    )
    return {"id": "identifiability", "heading": "Identifiability", "parts": [table_part(ident)]}

"""Reports of real fields: many CI profiles at once.

A summary of the field (each parameter's distribution, lack of fit, how
often layers win by BIC), a map when the profiles carry coordinates (plain
matplotlib axes, no tiles, no network), small multiples of every profile and
one sortable table of every profile (``docs/report.md``).  The builders take
*field records*, one plain mapping per profile in SI
(:func:`records_from_predict`, :func:`records_from_table`), and return report
sections of :mod:`terracone.report.parts`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3.2 (prediction process).
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from terracone.data import TerrainParameters
from terracone.notebook import fmt_value
from terracone.physics import units as u
from terracone.report import figures as F
from terracone.report.parts import figure_part, kv_part, table_part, text_part
from terracone.report.tables import Table, num_or_none

__all__ = [
    "MAX_MULTIPLES",
    "MAX_TABLE_ROWS",
    "PANELS_PER_FIGURE",
    "coordinates",
    "records_from_predict",
    "records_from_table",
    "summary_section",
    "map_section",
    "multiples_section",
    "profiles_table",
    "reasons_html",
    "panel_of",
    "profiles_section",
    "field_sections",
    "MAP_BY",
]

#: At most this many profiles are drawn as small multiples (tables hold all).
MAX_MULTIPLES = 1200
#: At most this many rows in the sortable table (the results file holds all).
MAX_TABLE_ROWS = 5000
#: Panels per small-multiples PNG (6 columns of 5 rows).
PANELS_PER_FIGURE = 30
_NCOLS = 6

_PARAMS = (
    ("kc", "kc", "kN/m^(n+1)"),
    ("kphi", "kphi", "kN/m^(n+2)"),
    ("n", "n", "-"),
    ("cc", "cc", "kPa"),
    ("phic_deg", "phic", "deg"),
    ("rmsd", "RMSD of CI", "kPa"),
    ("r2_ci", "R2 of CI", "-"),
)
#: Axis and colour-bar labels of the record keys, with units ("n [-]", "phic [deg]").
_LABELS = {k: f"{name} [{unit}]" for k, name, unit in _PARAMS}


def coordinates(meta: Mapping[str, Any] | None) -> tuple[float, float] | None:
    """(lon, lat) [deg] of a profile's metadata, or None when it has none.

    Reads ``lon``/``lat`` (the wide-table reader) or ``longitude``/``latitude``
    (the SC900 reader); values outside [-180, 180] x [-90, 90] or (0, 0)
    (an instrument without a fix) count as no position.
    """
    if not meta:
        return None
    lon = num_or_none(meta.get("lon", meta.get("longitude")))
    lat = num_or_none(meta.get("lat", meta.get("latitude")))
    if lon is None or lat is None or abs(lon) > 180 or abs(lat) > 90 or lon == lat == 0:
        return None
    return lon, lat


def _short(ids: Sequence[str]) -> list[str]:
    """Profile labels without the prefix they all share (``file/0001-N1`` -> ``0001-N1``)."""
    ids = [str(i) for i in ids]
    if len(ids) > 1 and all("/" in i for i in ids):
        heads = {i.rsplit("/", 1)[0] for i in ids}
        if len(heads) == 1:
            return [i.rsplit("/", 1)[1] for i in ids]
    return ids


def _layered_si(lay: Mapping[str, Any] | None, units: str) -> dict[str, Any]:
    """Layered-fit fields of a record from the ``layered`` dict of predict JSON."""
    if not lay:
        return {"layers_preferred": None, "layered_status": None}
    un = lay.get("units") or units
    out: dict[str, Any] = {
        "layered_status": lay.get("status", "ok"),
        "layers_preferred": None,
        "layered_error": lay.get("error"),
    }
    if lay.get("status", "ok") != "ok":
        return out
    out["layers_preferred"] = int(lay["preferred_layers"]) if lay.get("preferred_layers") else None
    out["n_layers"] = len(lay.get("layers") or [])
    out["interfaces"] = [float(x) for x in u.length_to_si(lay.get("interfaces") or [], un)]
    out["r2_layered"] = num_or_none(lay.get("r2_ci"))
    out["layered_lack_of_fit"] = lay.get("lack_of_fit")
    out["layer_n"] = [num_or_none(p.get("n")) for p in lay.get("layers") or []]
    if lay.get("depth") and lay.get("ci_model"):
        out["depth_layered"] = u.length_to_si(lay["depth"], un)
        out["ci_layered"] = u.pressure_to_si(lay["ci_model"], un)
    return out


def records_from_predict(
    profiles: Sequence[Mapping[str, Any]], units: str = "si"
) -> list[dict[str, Any]]:
    """Field records (SI) of the ``profiles`` of ``terracone predict --json``.

    Each record: ``id``, ``label``, ``status``, ``error``, ``kc``
    [kN/m^(n+1)], ``kphi`` [kN/m^(n+2)], ``n`` [-], ``cc`` [kPa],
    ``phic_deg`` [deg], ``model``, ``r_min`` [m], ``rmsd`` [kPa], ``r2_ci`` [-], ``flagged``,
    ``lack_of_fit`` (text), ``lon``/``lat`` [deg] or None, ``depth`` [m],
    ``ci``, ``ci_model`` [kPa], and the layered fit where predict ran with
    ``--layers``: ``layers_preferred``, ``interfaces`` [m], ``r2_layered``,
    ``depth_layered`` [m], ``ci_layered`` [kPa].
    """
    labels = _short([p.get("id", k) for k, p in enumerate(profiles)])
    out = []
    for p, label in zip(profiles, labels, strict=True):
        un = p.get("units") or units
        rec: dict[str, Any] = {
            "id": str(p.get("id")),
            "label": label,
            "status": p.get("status", "ok"),
            "error": p.get("error"),
        }
        if rec["status"] == "ok" and p.get("n") is not None:
            tp = TerrainParameters.from_dict(p, units=un)
            rec.update(kc=tp.kc, kphi=tp.kphi, n=tp.n, cc=tp.cc, phic_deg=tp.phic_deg)
            rec.update(model=tp.model, r_min=tp.r_min)
        rm = num_or_none(p.get("rmsd"))
        rec["rmsd"] = None if rm is None else float(u.pressure_to_si(rm, un))
        rec["r2_ci"] = num_or_none(p.get("r2_ci"))
        rec["lack_of_fit"] = p.get("lack_of_fit") or None
        rec["flagged"] = bool(p.get("lack_of_fit"))
        xy = coordinates(p.get("metadata"))
        rec["lon"], rec["lat"] = xy if xy else (None, None)
        if p.get("depth") and p.get("ci"):
            rec["depth"] = u.length_to_si(p["depth"], un)
            rec["ci"] = u.pressure_to_si(p["ci"], un)
            if p.get("ci_model") is not None and rec["status"] == "ok":
                rec["ci_model"] = u.pressure_to_si(p["ci_model"], un)
        rec.update(_layered_si(p.get("layered"), un))
        out.append(rec)
    return out


_DEPTH_COLS = {"depth_m": 1.0, "depth_cm": 0.01, "depth_mm": 0.001, "depth_in": u.INCH}
_CI_COLS = {"ci_kpa": 1.0, "ci_mpa": 1000.0, "ci_psi": u.PSI}


def _curves_from_source(source: str, ids: set[str], units: str) -> dict[str, tuple]:
    """Measured (depth [m], CI [kPa], cone) of the given profiles in a batch input file."""
    import pandas as pd

    from terracone.io import read_ci_profiles

    path = Path(source)
    if not path.exists():
        return {}
    out: dict[str, tuple] = {}
    if path.suffix.lower() in (".parquet", ".pq"):
        import pyarrow.parquet as pq

        names = pq.ParquetFile(path).schema_arrow.names
        dcol = next((c for c in _DEPTH_COLS if c in names), None)
        ccol = next((c for c in _CI_COLS if c in names), None)
        idcol = next((c for c in ("profile", "id") if c in names), None)
        if not (dcol and ccol and idcol):
            return {}
        df = pd.read_parquet(path, columns=[idcol, dcol, ccol])
        df = df[df[idcol].astype(str).isin(ids)]
        for pid, g in df.groupby(idcol, sort=False):
            z = g[dcol].to_numpy(float) * _DEPTH_COLS[dcol]
            y = g[ccol].to_numpy(float) * _CI_COLS[ccol]
            ok = np.isfinite(z) & np.isfinite(y)
            out[str(pid)] = (z[ok], y[ok], None)
        return out
    try:
        items = read_ci_profiles(path, units=units, on_error="collect")
    except (ValueError, OSError):
        return {}
    for it in items:
        if getattr(it, "id", None) in ids and hasattr(it, "depth"):
            out[str(it.id)] = (np.asarray(it.depth), np.asarray(it.ci), getattr(it, "cone", None))
    return out


def _table_curves(recs: list[dict[str, Any]], results: Sequence[Any], settings: Mapping) -> int:
    """Attach measured points and the one-layer model CI to table records; profiles drawn."""
    from terracone.physics.cone import cone_index, get_cone

    tip = settings.get("depth_ref") == "tip"
    by_source: dict[str, set[str]] = {}
    for r in results:
        if isinstance(r.source, str):
            by_source.setdefault(r.source, set()).add(str(r.id))
    curves: dict[str, tuple] = {}
    for src, ids in by_source.items():
        curves.update(_curves_from_source(src, ids, settings.get("units") or "si"))
    drawn = 0
    for rec, r in zip(recs, results, strict=True):
        c = curves.get(rec["id"])
        if c is None or c[0].size == 0:
            continue
        z, y, cone = c
        cone = cone or get_cone(r.cone or "asabe-large")
        if tip:
            z = z - cone.height
        rec["depth"], rec["ci"] = z, y
        drawn += 1
        if rec.get("n") is not None:
            try:
                rec["ci_model"] = cone_index(
                    np.maximum(z, -cone.height),
                    kc=rec["kc"],
                    kphi=rec["kphi"],
                    n=rec["n"],
                    cc=rec["cc"],
                    phic_deg=rec["phic_deg"],
                    model=rec.get("model") or "rm0",
                    r_min=rec.get("r_min"),
                    cone=cone,
                )
            except ValueError:
                pass
    return drawn


def records_from_table(results: Sequence[Any], settings: Mapping[str, Any]) -> list[dict]:
    """Field records (SI) of a prediction table (as :func:`records_from_predict`).

    ``results``: :func:`terracone.result.read_results` of a ``terracone batch``
    directory or a ``predict --parquet`` file; ``settings``: the run's
    (``depth_ref``, ``units``).  Measured points come from each profile's
    input file (``source``: the converted ``_input/*.parquet`` of an SC900
    export, or the CSV); the one-layer curve is the model CI of the fitted
    parameters (eq. (2-7)).  A table keeps the layered fit's interfaces and n
    per layer but not its other parameters, so the layered curve is not
    drawn; its interfaces are.
    """
    recs = []
    for r, label in zip(results, _short([str(r.id) for r in results]), strict=True):
        rec: dict[str, Any] = {"id": str(r.id), "label": label, "status": r.status}
        rec["error"] = r.error
        if r.ok and r.params is not None:
            p = r.params
            rec.update(kc=p.kc, kphi=p.kphi, n=p.n, cc=p.cc, phic_deg=p.phic_deg)
            rec.update(model=p.model, r_min=p.r_min)
        rec["rmsd"], rec["r2_ci"] = num_or_none(r.rmsd), num_or_none(r.r2_ci)
        rec["lack_of_fit"] = r.lack_of_fit or None
        rec["flagged"] = rec["lack_of_fit"] is not None
        xy = coordinates(r.metadata)
        rec["lon"], rec["lat"] = xy if xy else (None, None)
        lay = r.layered
        rec["layers_preferred"] = lay.preferred_layers if lay is not None and lay.ok else None
        rec["layered_status"] = None if lay is None else lay.status
        if lay is not None and not lay.ok:
            rec["layered_error"] = f"layered fit not possible: {lay.error}"
        if lay is not None and lay.ok and lay.interfaces:
            rec["interfaces"] = list(lay.interfaces)
        rec["r2_layered"] = num_or_none(lay.r2_ci) if lay is not None and lay.ok else None
        recs.append(rec)
    _table_curves(recs, results, settings)
    return recs


# ---------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------


def _pct(k: int, n: int) -> str:
    return f"{k} of {n} ({100.0 * k / n:.0f}%)" if n else "0 of 0"


def _distribution_table(recs: Sequence[Mapping[str, Any]]) -> Table:
    rows = []
    for key, name, unit in _PARAMS:
        v = np.array([x for x in (num_or_none(r.get(key)) for r in recs) if x is not None], float)
        if v.size == 0:
            rows.append([name, unit, 0, None, None, None, None, None])
            continue
        q = np.quantile(v, [0.0, 0.25, 0.5, 0.75, 1.0])
        rows.append([name, unit, int(v.size), *(float(x) for x in q)])
    return Table(
        "distribution",
        "Distribution of each parameter over the fitted profiles (one-layer fits, SI)",
        [(h, "") for h in ("Parameter", "Unit", "Profiles", "min", "25%", "median", "75%", "max")],
        rows,
        notes=[
            "The units of kc and kphi carry n, so their spread mixes units when n varies.",
            "From the CI alone phic and a common scale of kc and kphi trade exactly (the ridge): "
            "their spread says more about that valley than about the field.",
        ],
    )


def summary_section(recs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Section ``summary``: counts, lack of fit, layers, and each parameter's distribution."""
    n = len(recs)
    ok = [r for r in recs if r.get("status") == "ok" and r.get("n") is not None]
    flagged = [r for r in ok if r.get("flagged")]
    lay = [r for r in recs if r.get("layers_preferred") is not None]
    lay_bad = [r for r in recs if r.get("layered_status") not in (None, "ok")]
    two = [r for r in lay if r["layers_preferred"] >= 2]
    located = [r for r in recs if r.get("lon") is not None]
    pairs: dict[str, Any] = {
        "profiles": n,
        "fitted": _pct(len(ok), n),
        "not fitted": len(recs) - len(ok),
        "flagged for lack of fit": _pct(len(flagged), len(ok)),
    }
    if lay or lay_bad:
        pairs["two or more layers win (BIC)"] = _pct(len(two), len(lay))
        pairs["layered fit not possible"] = len(lay_bad)
    else:
        pairs["layered fits"] = "none (run predict or batch with --layers 2)"
    pairs["located (lon/lat)"] = _pct(len(located), n)
    parts: list[dict[str, Any]] = [kv_part(pairs)]
    if flagged:
        parts.append(
            text_part(
                "Lack of fit: R2 of the CI fit below 0.8, residuals that keep one sign, or CI "
                "falling with depth (a layer the homogeneous model cannot follow). The table "
                "below lists the reason for each flagged profile."
            )
        )
    if not located:
        parts.append(
            text_part(
                "No map: none of the profiles carries coordinates (lat/lon or "
                "latitude/longitude in its metadata)."
            )
        )
    parts.append(table_part(_distribution_table(ok), sortable=False))
    if len(ok) >= 3:
        keys = ("n", "kc", "kphi", "phic_deg", "rmsd", "r2_ci")
        cols = {_LABELS[k]: [r[k] for r in ok if r.get(k) is not None] for k in keys}
        fig = F.fig_histograms(cols, title="Distribution over the field")
        parts.append(
            figure_part(
                fig,
                f"Histograms of the one-layer parameters and fit statistics over the {len(ok)} "
                "fitted profiles.",
            )
        )
    return {"id": "summary", "heading": "Summary of the field", "parts": parts}


# ---------------------------------------------------------------------------
# map
# ---------------------------------------------------------------------------


def map_section(recs: Sequence[Mapping[str, Any]], *, colour_by: str = "n") -> dict | None:
    """Section ``map`` (None when no profile is located): profiles at lon/lat by a parameter."""
    loc = [r for r in recs if r.get("lon") is not None and r.get("lat") is not None]
    if not loc:
        return None
    name = _LABELS[colour_by]
    fig = F.fig_map(
        [r["lon"] for r in loc],
        [r["lat"] for r in loc],
        [np.nan if num_or_none(r.get(colour_by)) is None else r[colour_by] for r in loc],
        label=name,
        layered=[(r.get("layers_preferred") or 1) >= 2 for r in loc],
        flagged=[bool(r.get("flagged")) for r in loc],
        names=[r["label"] for r in loc],
        title=f"Profiles by position, coloured by {name}",
    )
    parts = [
        figure_part(
            fig,
            f"Each located profile at its longitude and latitude (WGS 84 degrees, equal "
            f"distances east and north), coloured by {name}. Squares: two layers win by BIC; "
            "red rings: lack of fit flagged. No map tiles: the background is empty.",
        )
    ]
    if len(loc) < len(recs):
        parts.append(text_part(f"{len(recs) - len(loc)} profile(s) carry no coordinates."))
    return {"id": "map", "heading": "Map", "parts": parts}


# ---------------------------------------------------------------------------
# small multiples
# ---------------------------------------------------------------------------


def panel_of(r: Mapping[str, Any]) -> dict[str, Any]:
    """The small-multiples panel of a field record (layered curve only where it wins)."""
    p = {
        "id": r["id"],
        "label": r["label"],
        "depth": r["depth"],
        "ci": r["ci"],
        "ci_model": r.get("ci_model"),
        "flagged": r.get("flagged"),
    }
    if (r.get("layers_preferred") or 1) >= 2:
        p["interfaces"] = r.get("interfaces") or []
        if r.get("ci_layered") is not None:
            p["ci_layered"] = r["ci_layered"]
            p["depth_layered"] = r.get("depth_layered", r["depth"])
    return p


def multiples_section(recs: Sequence[Mapping[str, Any]], *, units: str = "si") -> dict | None:
    """Section ``multiples``: a compact panel per profile, several PNGs of 30 panels."""
    drawable = [r for r in recs if r.get("depth") is not None and len(r["depth"])]
    if not drawable:
        return None
    shown = drawable[:MAX_MULTIPLES]
    parts: list[dict[str, Any]] = [
        text_part(
            f"Every profile with measured points ({len(shown)} of {len(recs)}), "
            f"{PANELS_PER_FIGURE} to a figure, in the order of the results. Open circles: "
            "measured CI; solid: the one-layer fit; dashed, with dotted interfaces: the layered "
            "fit where it wins by BIC. A red title with '!' marks lack of fit. Panels of a "
            "figure share their axes."
        )
    ]
    n_fig = math.ceil(len(shown) / PANELS_PER_FIGURE)
    for k in range(n_fig):
        chunk = shown[k * PANELS_PER_FIGURE : (k + 1) * PANELS_PER_FIGURE]
        first, last = chunk[0]["label"], chunk[-1]["label"]
        fig = F.fig_ci_multiples(
            [panel_of(r) for r in chunk],
            ncols=_NCOLS,
            units=units,
            title=f"CI profiles {k * PANELS_PER_FIGURE + 1} to "
            f"{k * PANELS_PER_FIGURE + len(chunk)} ({first} to {last})",
        )
        parts.append(
            figure_part(
                fig,
                f"Profiles {first} to {last}: measured CI and fits against cone-base depth.",
                alt=f"Small multiples of CI profiles {first} to {last}",
                wide=True,
            )
        )
    if len(drawable) > len(shown):
        parts.append(
            text_part(
                f"Drawn: the first {len(shown)} of {len(drawable)} profiles (a report caps "
                f"small multiples at {MAX_MULTIPLES}); the table holds them all."
            )
        )
    return {"id": "multiples", "heading": "Every profile", "parts": parts}


# ---------------------------------------------------------------------------
# the sortable table
# ---------------------------------------------------------------------------


def profiles_table(recs: Sequence[Mapping[str, Any]], *, units: str = "si") -> Table:
    """One row per profile (SI), for the sortable, scrolling table of a field report."""
    heads = ["Profile", "Status", "kc [kN/m^(n+1)]", "kphi [kN/m^(n+2)]", "n [-]", "cc [kPa]"]
    heads += ["phic [deg]", "RMSD [kPa]", "R2 [-]", "Lack of fit", "Layers (BIC)"]
    heads += ["Interfaces [cm]", "R2 layered [-]", "lon [deg]", "lat [deg]"]
    rows = []
    for r in recs:
        iface = r.get("interfaces") if (r.get("layers_preferred") or 1) >= 2 else None
        fit = ("yes" if r.get("flagged") else "no") if r.get("status") == "ok" else None
        rows.append(
            [r["label"], *(r.get(k) for k in ("status", "kc", "kphi", "n", "cc", "phic_deg"))]
            + [r.get("rmsd"), r.get("r2_ci"), fit, r.get("layers_preferred")]
            + [", ".join(fmt_value(100.0 * z, 3) for z in iface) if iface else None]
            + [r.get("r2_layered"), r.get("lon"), r.get("lat")]
        )
    return Table(
        "profiles",
        f"Every profile ({len(rows)}): click a column heading to sort",
        [(h, "") for h in heads],
        rows,
        notes=[
            "One-layer parameters in SI; 'Layers (BIC)': the number of layers the Bayesian "
            "information criterion prefers (blank: no layered fit); interfaces of the "
            "preferred layered fit."
        ],
    )


def reasons_html(recs: Sequence[Mapping[str, Any]]) -> str:
    """A folded list of the lack-of-fit reasons and errors, one line per profile."""
    e = html.escape
    lines = [
        f"<li><strong>{e(r['label'])}</strong>: {e(str(r['lack_of_fit']))}</li>"
        for r in recs
        if r.get("flagged")
    ]
    lines += [
        f"<li><strong>{e(r['label'])}</strong>: not fitted: {e(str(r.get('error')))}</li>"
        for r in recs
        if r.get("status") != "ok"
    ]
    lines += [
        f"<li><strong>{e(r['label'])}</strong>: layered fit not possible: "
        f"{e(str(r.get('layered_error')))}</li>"
        for r in recs
        if r.get("layered_status") not in (None, "ok")
    ]
    if not lines:
        return ""
    return (
        f'<details class="reasons"><summary>Reasons: {len(lines)} profile notes (lack of fit, '
        f"errors)</summary><ul>{''.join(lines)}</ul></details>"
    )


def profiles_section(recs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Section ``profiles``: the sortable table of every profile, and the reasons."""
    parts: list[dict[str, Any]] = [
        table_part(profiles_table(recs), sortable=True, tall=True, max_rows=MAX_TABLE_ROWS)
    ]
    reasons = reasons_html(recs)
    if reasons:
        parts.append({"type": "html", "html": reasons})
    return {"id": "profiles", "heading": "Every profile: table", "parts": parts}


#: ``--map-by`` choices and the record key each colours the map by.
MAP_BY = dict(n="n", kc="kc", kphi="kphi", cc="cc", phic="phic_deg", rmsd="rmsd", r2="r2_ci")


def field_sections(
    recs: Sequence[Mapping[str, Any]], *, units: str = "si", map_by: str = "n"
) -> list[dict]:
    """Summary, map (when located), table and small multiples of a field, in that order.

    ``map_by``: the parameter that colours the map, a key of :data:`MAP_BY`.
    """
    if map_by not in MAP_BY:
        raise ValueError(f"map_by must be one of {', '.join(MAP_BY)}, not {map_by!r}")
    out = [summary_section(recs)]
    m = map_section(recs, colour_by=MAP_BY[map_by])
    if m is not None:
        out.append(m)
    out.append(profiles_section(recs))
    mm = multiples_section(recs, units=units)
    if mm is not None:
        out.append(mm)
    return out

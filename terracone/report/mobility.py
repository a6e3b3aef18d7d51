"""Text and report section of ``terracone mobility``: GO/NO-GO, margins, wheel sinkage, a map.

:func:`mobility_text` is the table the command prints; :func:`mobility_document`
the HTML report section of a ``terracone mobility --json`` document (schema
``terracone.mobility/1``, docs/mobility.md): the vehicle, a table of the
profiles and of the sites, a map of GO and NO-GO where the profiles are
located, and the notes.  :func:`go_map_text` and :func:`go_map_document` do the
same for a P(GO) map (``terracone mobility MAPDIR``, schema
``terracone.mobility-map/1``), drawing ``p_go.tif`` and ``sinkage.tif``.  Nothing is computed here; the numbers are those of
:mod:`terracone.apps.mobility`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from terracone.physics import units as u
from terracone.report.fields import coordinates
from terracone.report.html import figure_part, kv_part, list_part, table_part, text_part
from terracone.report.tables import Table
from terracone.report.text import table

__all__ = [
    "mobility_text",
    "mobility_document",
    "go_map_text",
    "go_map_document",
    "p_go_figure",
    "verdict",
    "go_map_figure",
    "profile_notes",
    "vehicle_line",
    "layer_line",
]


def verdict(go: bool | None) -> str:
    """ "GO", "NO-GO" or "-" (undecided: no RCI)."""
    return "-" if go is None else ("GO" if go else "NO-GO")


def _band(w: Mapping[str, Any], key: str) -> tuple[Any, Any]:
    lo, hi = w.get("lo"), w.get("hi")
    return (lo[key], hi[key]) if lo and hi else (None, None)


def _layer_text(cl: Mapping[str, Any]) -> str:
    top, bottom = cl.get("top"), cl.get("bottom")
    return "-" if top is None or bottom is None else f"{top:.3g}-{bottom:.3g}"


def _soil_text(d: Mapping[str, Any]) -> str:
    soil = d.get("soil_class") or "-"
    return f"{soil}*" if d.get("assumed") else soil


def _row(d: Mapping[str, Any], name_key: str) -> list[Any]:
    cl, w = d["critical_layer"], d["wheel"]
    zlo, zhi = _band(w, "sinkage")
    rlo, rhi = _band(w, "resistance")
    return [
        d[name_key], _soil_text(d), _layer_text(cl), cl["ci"], cl.get("ri"), cl["rci"], d["vci"],
        verdict(d["go"]), d["margin"], w["sinkage"], zlo, zhi, w["resistance"], rlo, rhi,
    ]  # fmt: skip


def _headers(units: str, first: str) -> list[str]:
    pu, lu, fu = u.pressure_unit(units), u.length_unit(units), u.force_unit(units)
    return [
        first, "soil", f"layer [{lu}]", f"CI [{pu}]", "RI", f"RCI [{pu}]", f"VCI [{pu}]", "GO",
        f"margin [{pu}]", f"sinkage [{lu}]", "5%", "95%", f"resistance [{fu}]", "5%", "95%",
    ]  # fmt: skip


def vehicle_line(doc: Mapping[str, Any]) -> str:
    """The vehicle, its mobility index and its VCI (or why none applies), in one line."""
    units, v = doc["units"], doc["vehicle"]
    drive = f", drive {v['drive']}" if v.get("drive") else ""
    tyre = (
        f", delta/h {v['tire_deflection_ratio']:g} (DCF {v['dcf']:.4g})"
        if v.get("tire_deflection_ratio") is not None
        else ""
    )
    vci = (
        f"VCI_{v['passes']} {v['vci']:.4g} {u.pressure_unit(units)} (fine-grained soils)"
        if v.get("vci") is not None
        else f"VCI_{v['passes']}: none ({v.get('vci_note')})"
    )
    return (
        f"vehicle {v['name']} ({v['kind']}{drive}): MI {v['mobility_index']:.4g} "
        f"({v['mobility_index_from']}){tyre}, {vci}"
    )


def layer_line(doc: Mapping[str, Any]) -> str:
    """How the critical layer was chosen, and the wheel of Bekker's sinkage."""
    units, st, v = doc["units"], doc["settings"], doc["vehicle"]
    lu = u.length_unit(units)
    cl = st.get("critical_layer") or {"mode": "layer", **st["layer"]}  # documents before issue 30
    rules = sorted({p["critical_layer"].get("rule") or "-" for p in doc["profiles"]})
    if cl["mode"] == "layer":
        how = f"critical layer {cl['top']:.4g}-{cl['bottom']:.4g} {lu} (--layer)"
    elif cl["mode"] == "weakest":
        w = cl["window"]
        how = (f"critical layer: the weakest {cl['thickness']:.4g} {lu} within "
               f"{w[0]:.4g}-{w[1]:.4g} {lu} of each profile")  # fmt: skip
    else:
        how = f"critical layer by rule: {', '.join(rules)}"
    wheel = v.get("wheel")
    if wheel is None:
        return f"{how}; no wheel"
    return (
        f"{how}; wheel {wheel['load']:.4g} {u.force_unit(units)}, D {wheel['diameter']:.4g} {lu}, "
        f"b {wheel['width']:.4g} {lu}"
    )


def profile_notes(profiles: Sequence[Mapping[str, Any]], shown: int = 3) -> list[str]:
    """The profiles' notes, each said once: "id: note", "k profiles (ids): note" or
    "every profile: note"."""
    by_note: dict[str, list[str]] = {}
    for p in profiles:
        for n in dict.fromkeys(p["notes"]):
            by_note.setdefault(n, []).append(str(p["id"]))
    out = []
    for n, ids in by_note.items():
        if len(ids) == 1:
            out.append(f"{ids[0]}: {n}")
        elif len(ids) == len(profiles):
            out.append(f"every profile: {n}")
        else:
            more = ", ..." if len(ids) > shown else ""
            out.append(f"{len(ids)} profiles ({', '.join(ids[:shown])}{more}): {n}")
    return out


def mobility_text(doc: Mapping[str, Any]) -> str:
    """The plain-text tables of a mobility document (what ``terracone mobility`` prints)."""
    units = doc["units"]
    lines = [
        vehicle_line(doc),
        layer_line(doc),
        "",
        table(_headers(units, "profile"), [_row(p, "id") for p in doc["profiles"]]),
    ]
    if doc.get("sites"):
        lines += ["", table(_headers(units, "site"), [_row(s, "site") for s in doc["sites"]])]
    notes = list(doc.get("notes", [])) + profile_notes(doc["profiles"])
    if any(p.get("assumed") for p in doc["profiles"]):
        notes.append("soil*: soil class assumed (not given)")
    if notes:
        lines += [""] + notes
    return "\n".join(lines)


def _table(rows: Sequence[Mapping[str, Any]], units: str, site: bool) -> Table:
    hs = _headers(units, "site" if site else "profile")
    columns = [(h.split(" [")[0], h.split(" [")[1].rstrip("]") if " [" in h else "") for h in hs]
    columns[10], columns[11] = ("sinkage", "5%"), ("sinkage", "95%")
    columns[13], columns[14] = ("resistance", "5%"), ("resistance", "95%")
    body = [_row(r, "site" if site else "id") for r in rows]
    if site:
        columns.append(("GO share", "of profiles"))
        for b, r in zip(body, rows):
            b.append(r.get("go_fraction"))
    return Table(
        key="mobility-sites" if site else "mobility",
        title=("Sites: " if site else "Profiles: ")
        + "critical-layer CI, RCI against VCI, and the wheel",
        columns=columns,
        rows=body,
        notes=[
            "GO when RCI >= VCI (Priddy and Willoughby 2006); margin = RCI - VCI; '-' where "
            "there is no RCI or no VCI (no remolding index, no CI over the critical layer, a "
            "coarse-grained soil, or a vehicle outside the VCI relation's domain); soil*: "
            "assumed.",
            "sinkage and compaction resistance of the vehicle's rigid wheel (Bekker 1969); "
            "5%/95%: band of the posterior draws where the results keep them.",
        ],
    )


def go_map_figure(doc: Mapping[str, Any]) -> Figure | None:
    """GO and NO-GO of the located profiles on longitude and latitude; None when none is located."""
    pts = []
    for p in doc["profiles"]:
        xy = coordinates(p.get("metadata"))
        if xy is not None:
            pts.append((xy[0], xy[1], p["go"]))
    if not pts:
        return None
    fig = Figure(figsize=(7.2, 5.6))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for go, colour, marker, label in (
        (True, "#1a7f37", "o", "GO"),
        (False, "#c00000", "X", "NO-GO"),
        (None, "#bbbbbb", "o", "undecided (no RCI)"),
    ):
        sel = [(x, y) for x, y, g in pts if g is go]
        if sel:
            xs, ys = zip(*sel, strict=True)
            ax.scatter(xs, ys, c=colour, marker=marker, s=50, label=f"{label} ({len(sel)})",
                       edgecolors="black", linewidths=0.4)  # fmt: skip
    mean_lat = sum(y for _, y, _ in pts) / len(pts)
    ax.set_aspect(1.0 / max(0.05, math.cos(math.radians(mean_lat))))
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.legend(fontsize=8, loc="best")
    v = doc["vehicle"]
    ax.set_title(f"{v['name']}: RCI against VCI_{v['passes']}", fontsize=10)
    fig.tight_layout()
    return fig


def mobility_document(doc: Mapping[str, Any], *, source: str | None = None) -> dict[str, Any]:
    """Report document of a ``terracone mobility --json`` result."""
    units = str(doc.get("units", "si"))
    v, st = doc["vehicle"], doc["settings"]
    profiles, sites = list(doc.get("profiles") or []), list(doc.get("sites") or [])
    decided = [p["go"] for p in profiles if p["go"] is not None]
    parts: list[dict[str, Any]] = [
        kv_part(
            {
                "results file": source,
                "input": doc.get("input"),
                "vehicle": f"{v['name']} ({v['kind']})",
                "mobility index": v["mobility_index"],
                f"VCI_{v['passes']} [{u.pressure_unit(units)}]": (
                    v["vci"] if v["vci"] is not None else f"none ({v.get('vci_note')})"
                ),
                "critical layer": layer_line(doc).split(";")[0],
                "remolding index": st.get("remolding_index") or "from metadata",
                "profiles": len(profiles),
                "GO / NO-GO / undecided": (
                    f"{sum(decided)} / {len(decided) - sum(decided)} / {len(profiles) - len(decided)}"
                ),
                "prior": st.get("prior"),
            }
        ),
        text_part(
            "NRMM: the mean CI of the critical layer times the remolding index (RCI) against "
            "the vehicle cone index of the vehicle's mobility index; Bekker-Wong: the sinkage "
            "and compaction resistance of the vehicle's wheel from each profile's kc, kphi and n."
        ),
        table_part(_table(profiles, units, site=False), max_rows=2000, tall=len(profiles) > 30),
    ]
    if sites:
        parts.append(table_part(_table(sites, units, site=True), max_rows=2000))
    fig = go_map_figure(doc)
    if fig is not None:
        parts.append(figure_part(fig, "GO and NO-GO of the located profiles (plain degrees)."))
    notes = list(doc.get("notes", [])) + profile_notes(profiles)
    if notes:
        parts.append(list_part(notes))
    return {
        "title": f"terracone report: mobility of {v['name']}",
        "meta": {"results": source, "command": "mobility"},
        "sections": [{"id": "mobility", "heading": "Vehicle mobility", "parts": parts}],
    }


# ---------------------------------------------------------------------------
# P(GO) maps: terracone mobility MAPDIR
# ---------------------------------------------------------------------------


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.3g}"


def _km2(v: float | None) -> str:
    return "-" if v is None else f"{v / 1e6:.4g} km²"


def go_map_text(doc: Mapping[str, Any], out: str | None = None) -> str:
    """The plain-text summary of a P(GO) map document (what ``terracone mobility MAPDIR`` prints)."""
    units = doc["units"]
    pu, lu = u.pressure_unit(units), u.length_unit(units)
    cl, a, pg, sk = doc["critical_layer"], doc["area_m2"], doc["p_go"], doc["sinkage"]
    g = doc["map"]["grid"] or {}
    lines = [vehicle_line(doc)]
    if pg["file"] is None:
        lines.append(f"P(GO): not computed: {pg['reason']}")
    else:
        mc = pg["monte_carlo"] or {}
        lines += [
            f"critical layer {cl['top']:.4g}-{cl['bottom']:.4g} {lu} ({cl['rule']}), map layer "
            f"{cl['quantity']}; RI {doc['remolding_index']:g}: a point needs CI >= "
            f"{doc['threshold_ci']:.4g} {pu} (RCI >= VCI {doc['vci']:.4g} {pu})",
            f"P(GO) of {g.get('width', 0) * g.get('height', 0):,} cells of "
            f"{doc['map']['resolution']:g} m: GO at 90% confidence {_km2(a['go_90'])}, NO-GO at "
            f"90% {_km2(a['no_go_90'])}, uncertain {_km2(a['uncertain'])}, masked "
            f"{_km2(a['masked'])}",
            f"expected GO area {_km2(a['expected_go'])}; in one realisation of the field "
            f"{_km2(a['go_simulated']['lo'])} to {_km2(a['go_simulated']['hi'])} (90%)",
            f"{doc['simulations']} conditional simulations: their GO frequency against P(GO), "
            f"rms standardised difference {_num(mc.get('rms_standardised_difference'))} "
            f"(standard error at P = 0.5: {_num(mc.get('standard_error_at_0.5'))}; 1 expected, "
            "- where every P(GO) is 0 or 1)",
        ]
    if sk["file"] is None:
        lines.append(f"wheel sinkage: not computed: {sk['reason']}")
    else:
        lines.append(f"wheel sinkage: median over the cells {sk['median_of_cells']:.4g} {lu} "
                     "(sinkage.tif: median, 5% and 95% at a point)")  # fmt: skip
    files = [f for f in (pg["file"], sk["file"]) if f] + ["mobility.json"]
    if out is not None:
        lines.append(f"wrote {out}: {', '.join(files)}")
    return "\n".join(lines)


def p_go_figure(directory: str | Path, doc: Mapping[str, Any]) -> Figure | None:
    """P(GO) of every cell (p_go.tif) and the median wheel sinkage (sinkage.tif), with the
    map's pushes; None when neither raster was written."""
    from terracone.report.maps import read_raster

    d = Path(directory)
    panels = []
    if doc["p_go"]["file"] and (d / doc["p_go"]["file"]).exists():
        bands, extent = read_raster(d / doc["p_go"]["file"])
        panels.append((bands[0], extent, "P(GO) [-]", "RdYlGn", (0.0, 1.0)))
    if doc["sinkage"]["file"] and (d / doc["sinkage"]["file"]).exists():
        bands, extent = read_raster(d / doc["sinkage"]["file"])
        panels.append((bands[0], extent, f"median wheel sinkage [{doc['sinkage']['units']}]",
                       "viridis", (None, None)))  # fmt: skip
    if not panels:
        return None
    points = _map_points(doc)
    fig = Figure(figsize=(4.6 * len(panels), 4.2))
    FigureCanvasAgg(fig)
    for k, (img, extent, label, cmap, (vmin, vmax)) in enumerate(panels, 1):
        ax = fig.add_subplot(1, len(panels), k)
        x0, y0 = extent[0], extent[2]
        ext = (0.0, extent[1] - x0, 0.0, extent[3] - y0)
        im = ax.imshow(np.ma.masked_invalid(img), extent=ext, origin="upper", cmap=cmap,
                       vmin=vmin, vmax=vmax)  # fmt: skip
        if k == 1 and doc["p_go"]["file"]:
            ax.contour(np.ma.masked_invalid(img), levels=[0.1, 0.9], colors="k", linewidths=0.6,
                       extent=ext, origin="upper")  # fmt: skip
        if points is not None:
            ax.plot(points[:, 0] - x0, points[:, 1] - y0, "k.", ms=1.5)
        ax.set_aspect("equal")
        ax.set_xlabel(f"east of {x0:.0f} [m]")
        ax.set_ylabel(f"north of {y0:.0f} [m]")
        ax.set_title(label, fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.8)
    v = doc["vehicle"]
    fig.suptitle(f"{v['name']}: P(RCI >= VCI_{v['passes']}) at a point", fontsize=10)
    fig.tight_layout()
    return fig


def _map_points(doc: Mapping[str, Any]) -> Any:
    """The map's pushes (x, y) [m], when its directory is still there; else None."""
    d = Path(str(doc["map"]["directory"]))
    try:
        import pyarrow.parquet as pq

        pts = pq.read_table(d / "points.parquet", columns=["x", "y"])
    except (OSError, ValueError):
        return None
    return np.column_stack([pts["x"].to_numpy(), pts["y"].to_numpy()])


def go_map_document(doc: Mapping[str, Any], directory: str | Path) -> dict[str, Any]:
    """Report document of a ``terracone mobility MAPDIR`` output directory (``mobility.json``)."""
    units = str(doc.get("units", "si"))
    v, a, pg = doc["vehicle"], doc["area_m2"], doc["p_go"]
    cl = doc["critical_layer"]
    parts: list[dict[str, Any]] = [
        kv_part(
            {
                "map": doc["map"]["directory"],
                "vehicle": f"{v['name']} ({v['kind']})",
                f"VCI_{v['passes']} [{u.pressure_unit(units)}]": (
                    doc["vci"] if doc["vci"] is not None else f"none ({v.get('vci_note')})"
                ),
                "soil class": doc["soil_class"] + (" (assumed)" if doc["assumed"] else ""),
                "critical layer": cl["quantity"] or "-",
                "remolding index": doc["remolding_index"],
                "GO at 90% confidence": _km2(a["go_90"]),
                "NO-GO at 90% confidence": _km2(a["no_go_90"]),
                "uncertain (0.1 < P < 0.9)": _km2(a["uncertain"]),
                "expected GO area": _km2(a["expected_go"]),
                "simulations": doc["simulations"],
            }
        ),
        text_part(
            "P(GO) is the probability that the rating cone index RCI = CI x RI of the critical "
            "layer at a point of the cell reaches the vehicle cone index: the map's kriged "
            "median of the layer's CI with the variance of a point (kriging variance plus "
            "nugget). Contours at P = 0.1 and 0.9 bound the uncertain area. The wheel sinkage "
            "comes from conditional simulations of the map's strength and n."
        ),
    ]
    if pg["file"] is None:
        parts.append(text_part(f"No P(GO): {pg['reason']}"))
    fig = p_go_figure(directory, doc)
    if fig is not None:
        parts.append(figure_part(fig, "P(GO) of every cell and the median wheel sinkage; dots "
                                      "are the map's pushes.", alt="P(GO) map"))  # fmt: skip
    if doc.get("notes"):
        parts.append(list_part(list(doc["notes"])))
    return {
        "title": f"terracone report: P(GO) map of {v['name']}",
        "meta": {"map": doc["map"]["directory"], "command": "mobility"},
        "sections": [{"id": "p-go", "heading": "Probability of GO", "parts": parts}],
    }

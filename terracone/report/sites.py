"""Report section of ``terracone sites --json``: site terrain, push-to-push CV, pushes needed.

One table of the sites (median plate pressure at the middle sinkage with its
90% interval, the push-to-push CV with its 90% interval beside the plain
sample CV and the CV of the CI itself, the pushes needed for the target CV
and the lack of fit), one figure of the site P-S curves with their 90%
bands, and every site's notes.  The statistics are those of
:mod:`terracone.inverse.sites.statistics`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-2); section 5.2, recommendation E.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from terracone.physics import units as u
from terracone.report.parts import figure_part, kv_part, list_part, table_part, text_part
from terracone.report.tables import Table

__all__ = ["sites_document"]


#: Values of a site's plate pressure at the middle sinkage, in the table's column order.
_AT_MID = ("median", "lo", "hi", "between_cv", "between_cv_lo", "between_cv_hi", "naive_cv")


def _mid(pl: Mapping[str, Any]) -> int:
    return len(pl["sinkage"]) // 2


def _sites_table(sites: list[Mapping[str, Any]], units: str) -> Table:
    pu = u.pressure_unit(units)
    rows = []
    for s in sites:
        pl = s["plate_pressure"][0] if s["plate_pressure"] else None
        at = {key: pl[key][_mid(pl)] for key in pl if isinstance(pl[key], list)} if pl else {}
        mid = [at.get(k) for k in _AT_MID]
        needed = [s["profiles_needed"], s.get("profiles_needed_hi")]
        fit = "lack of fit" if s["lack_of_fit"] else "ok"
        ci_cv = s.get("between", {}).get("ci_cv")
        rows.append([s["site"], s["n_profiles"], s["params"].get("n"), *mid, ci_cv, *needed, fit])
    cols = [("site", ""), ("pushes", ""), ("n", "site median")]
    cols += [("p", f"{q} [{pu}]") for q in ("median", "5%", "95%")]
    cols += [("between-push CV", q) for q in ("estimate", "5%", "95%")]
    cols += [("naive CV", "incl. estimation noise"), ("CI CV", "mean CI per push")]
    cols += [("pushes needed", "estimate"), ("pushes needed", "at CV 95%"), ("fit", "")]
    return Table(
        key="sites",
        title="Site plate pressure at the middle sinkage and push-to-push variation",
        columns=cols,
        rows=rows,
        notes=[
            "between-push CV: random-effects (Paule-Mandel) estimate, estimation noise removed; "
            "90% Q-profile interval.",
            "naive CV: plain sample CV of the per-push predictions (estimation noise counted as "
            "variability).",
            "pushes needed = ceil((between CV / target CV)^2), at least 1.",
        ],
    )


def _curves_figure(sites: list[Mapping[str, Any]], units: str) -> Figure:
    fig = Figure(figsize=(7.2, 4.6))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for i, s in enumerate(sites[:12]):
        if not s["plate_pressure"]:
            continue
        pl = s["plate_pressure"][0]
        c = f"C{i % 10}"
        ax.plot(pl["sinkage"], pl["median"], color=c, label=str(s["site"]))
        ax.fill_between(pl["sinkage"], pl["lo"], pl["hi"], color=c, alpha=0.12, linewidth=0)
    ax.set_xlabel(f"sinkage [{u.length_unit(units)}]")
    ax.set_ylabel(f"pressure [{u.pressure_unit(units)}]")
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Site median P-S curves and 90% bands (eq. (2-2))")
    fig.tight_layout()
    return fig


def sites_document(doc: Mapping[str, Any], *, source: str | None = None) -> dict[str, Any]:
    """Report document of a ``terracone sites --json`` result."""
    units = str(doc.get("settings", {}).get("units", "si"))
    sites = list(doc.get("sites") or [])
    st = doc.get("settings", {})
    parts: list[dict[str, Any]] = [
        kv_part(
            {
                "results file": source,
                "input": doc.get("input"),
                "grouped by": st.get("by") or f"radius {st.get('radius')}",
                "sites": len(sites),
                "pushes": sum(int(s["n_profiles"]) for s in sites),
                "calibration": st.get("calibration") or "none (bounds)",
                "target CV": st.get("target_cv"),
            }
        ),
        text_part(
            "Each push is fitted alone; a random-effects model then separates the site "
            "terrain, the push-to-push variation and each push's estimation noise. "
            "A site whose pushes do not follow the one-layer model is marked: its terrain "
            "averages a misfit and its intervals carry it."
        ),
        table_part(_sites_table(sites, units), max_rows=500),
    ]
    if any(s["plate_pressure"] for s in sites):
        parts.append(
            figure_part(
                _curves_figure(sites, units),
                "Site median plate pressure against sinkage with the 90% interval of the site "
                "median (first plate" + (", first 12 sites" if len(sites) > 12 else "") + ").",
            )
        )
    notes = [
        f"{s['site']}: {n}"
        for s in sites
        for n in ([s["lack_of_fit"]] if s["lack_of_fit"] else []) + list(s.get("notes", []))
    ]
    notes += [f"not in a site: {d['id']}: {d['reason']}" for d in doc.get("unassigned", [])]
    notes += [f"not read: {e}" for e in doc.get("errors", [])]
    if notes:
        parts.append(list_part(notes))
    return {
        "title": "terracone report: site statistics",
        "meta": {"results": source, "command": "sites"},
        "sections": [{"id": "sites", "heading": "Sites", "parts": parts}],
    }

"""HTML tables of result objects, for Jupyter (``_repr_html_``).

The result classes' ``_repr_html_`` delegate here: each shows as a small
table with the parameters in SI and US customary units.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Tables 4-1 and 4-3 (the layout of the parameters).
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from terracone.physics import units as u
from terracone.resultunits import from_si

__all__ = [
    "parameters_html",
    "prediction_html",
    "predictions_html",
    "learn_html",
    "layered_html",
    "batch_html",
    "fmt_value",
]


def fmt_value(v: Any, digits: int = 5) -> str:
    """Human formatting: 5 significant digits (the paper prints up to 5), "-" for none."""
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return "-"
        if v == 0:
            return "0"
        if 1e-3 <= abs(v) < 1e6:
            s = f"{v:.{digits}g}"
            return f"{v:.0f}" if "e" in s else s  # e.g. 1.235e+05 -> plain
        return f"{v:.{digits - 1}e}"
    return str(v)


_STYLE = (
    "border-collapse:collapse;font-variant-numeric:tabular-nums;"
    "font-family:system-ui,sans-serif;font-size:0.9em"
)
_CELL = "border:1px solid #ccc;padding:2px 8px;"


def _table(caption: str, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    e = html.escape
    th = "".join(f'<th style="{_CELL}background:#e9eef5">{e(h)}</th>' for h in header)
    body = []
    for r in rows:
        cells = []
        for j, v in enumerate(r):
            align = "left" if j == 0 or isinstance(v, str) else "right"
            tag = "th" if j == 0 else "td"
            cells.append(f'<{tag} style="{_CELL}text-align:{align}">{e(fmt_value(v))}</{tag}>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (
        f'<table class="terracone" style="{_STYLE}"><caption style="text-align:left;'
        f'font-weight:600;padding:2px 0">{e(caption)}</caption><thead><tr>{th}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table>"
    )


def _f(v: Any) -> float | None:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _kpa_row(name: str, v: float) -> list[Any]:
    """A row of a pressure [kPa] with its value in psi."""
    return [name, _f(v), "kPa", _f(from_si(v, "pressure", "us")), "psi"]


def _param_rows(p: Any) -> list[list[Any]]:
    """kc, kphi, n, cc, phic (and r_min) rows: name, SI value, SI unit, US value, US unit."""
    moduli = (("kc", u.kc_unit), ("kphi", u.kphi_unit))
    rows = [
        [k, getattr(p, k), unit("si"), from_si(getattr(p, k), k, "us", p.n), unit("us")]
        for k, unit in moduli
    ]
    rows += [
        ["n", p.n, "-", p.n, "-"],
        _kpa_row("cc", p.cc),
        ["phic", p.phic_deg, "deg", p.phic_deg, "deg"],
    ]
    if getattr(p, "r_min", None) is not None:
        rows.append(["r_min", p.r_min * 1000.0, "mm", p.r_min / u.INCH, "in"])
    return rows


_HEAD = ["Parameter", "SI", "unit", "US", "unit"]
#: Columns of the parameters in tables of one row per profile or layer (SI).
_PARAM_COLUMNS = ["kc [kN/m^(n+1)]", "kphi [kN/m^(n+2)]", "n [-]", "cc [kPa]", "phic [deg]"]


def parameters_html(params: Any, caption: str = "Terrain parameters") -> str:
    """Table of a :class:`terracone.TerrainParameters` (SI and US columns)."""
    return _table(f"{caption} (model {params.model})", _HEAD, _param_rows(params))


def prediction_html(res: Any) -> str:
    """Table of a :class:`terracone.inverse.PredictionResult`."""
    if not res.ok or res.params is None:
        return _table(
            f"Prediction {res.id}: not fitted", ["Profile", "error"], [[res.id, res.error]]
        )
    rows = _param_rows(res.params) + [
        _kpa_row("RMSD of CI", res.rmsd),
        ["R2 of CI", _f(res.r2_ci), "-", _f(res.r2_ci), "-"],
        ["lack of fit", res.lack_of_fit or "none found", "", "", ""],
    ]
    if res.undetermined:
        rows.append(["undetermined", ", ".join(res.undetermined), "", "", ""])
    return _table(f"Prediction {res.id} (cone {res.cone})", _HEAD, rows)


def predictions_html(results: Sequence[Any]) -> str:
    """One row per profile of a list of :class:`PredictionResult` (SI)."""
    header = ["Profile", "status", *_PARAM_COLUMNS, "RMSD [kPa]", "R2 [-]", "lack of fit"]
    rows = []
    for r in results:
        if r.ok:
            p, fit = r.params, "yes" if r.lack_of_fit else "no"
            cells = [p.kc, p.kphi, p.n, p.cc, p.phic_deg, _f(r.rmsd), _f(r.r2_ci), fit]
        else:
            cells = [None] * 7 + [r.error]
        rows.append([r.id, r.status, *cells])
    n_ok = sum(1 for r in results if r.ok)
    return _table(f"{len(rows)} predictions ({n_ok} fitted)", header, rows)


def learn_html(res: Any) -> str:
    """Table of a :class:`terracone.inverse.LearnResult`."""
    rows = _param_rows(res.params)
    rows += [_kpa_row("RMSD of CI", res.rmsd_ci), _kpa_row("RMSD of plates", res.rmsd_plates)]
    if res.plate_pair:
        cm = ", ".join(fmt_value(r * 100.0, 4) for r in res.plate_pair)
        inch = ", ".join(fmt_value(r / u.INCH, 4) for r in res.plate_pair)
        rows.append(["plate radii", cm, "cm", inch, "in"])
    if res.undetermined:
        rows.append(["undetermined", ", ".join(res.undetermined), "", "", ""])
    crit: Mapping[str, Any] = res.criteria or {}
    if crit:
        ok = "satisfied" if crit.get("satisfied") else "NOT satisfied"
        rows.append(["fit criterion", f"CV <= {crit.get('max_cv')}: {ok}", "", "", ""])
    return _table(f"Learned parameters (model {res.params.model})", _HEAD, rows)


def layered_html(res: Any) -> str:
    """Table of a :class:`terracone.inverse.layered.LayeredResult`: one row per layer (SI)."""
    if not res.ok:
        return _table(
            f"Layered fit {res.id}: not fitted", ["Profile", "error"], [[res.id, res.error]]
        )
    header = ["Layer", "top [cm]", *_PARAM_COLUMNS]
    tops = [0.0, *res.interfaces]
    rows = [
        [str(k + 1), tops[k] * 100.0, p.kc, p.kphi, p.n, p.cc, p.phic_deg]
        for k, p in enumerate(res.layers)
    ]
    cap = (
        f"Layered fit {res.id}: {len(res.layers)} layers, RMSD {fmt_value(res.rmsd, 4)} kPa, "
        f"BIC {fmt_value(res.bic, 5)} against {fmt_value(res.bic_single, 5)} for one layer: "
        f"{res.preferred_layers} preferred"
    )
    return _table(cap, header, rows)


def batch_html(summary: Any) -> str:
    """Table of a :class:`terracone.apps.batch.BatchSummary`."""
    rows = [
        ["output directory", summary.out_dir],
        ["profiles", summary.profiles],
        ["fitted", summary.profiles_ok],
        ["not fitted", summary.profiles_error],
        ["part files", summary.chunks],
        ["wall time [s]", summary.wall_s],
        ["profiles per second", summary.profiles_per_s],
        ["problems", "; ".join(summary.problems) or "none"],
    ]
    return _table("Batch run (see terracone report OUT_DIR)", ["", ""], rows)

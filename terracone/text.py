"""Plain-text tables of terracone results, as the command line and the demo print them.

Every function here takes results already computed (in SI inside the
result objects) and a unit system, converts at the edge and returns text;
none computes anything.  :mod:`terracone.cli` prints them and
:func:`terracone.example.run_demo` builds its transcript from them, so the
library never imports the command line.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from . import units as u

if TYPE_CHECKING:  # pragma: no cover - annotations only
    from .inverse.evaluate import PlateEvaluation
    from .inverse.predict import PredictionResult

__all__ = ["evaluate_text", "format_value", "learn_text", "predict_text", "table"]

PHIC_UNDETERMINED = (
    "\n\nphic is undetermined: with fully mobilised shear it trades exactly against a common"
    "\nscale of kc and kphi (shown at the middle of the phic interval that fits equally well)."
    "\nUse --calibration or --terrain from a learning run to fix it."
)


def format_value(v: Any, digits: int = 4) -> str:
    """One table cell: ``digits`` significant digits for floats, "-" for None and non-finite."""
    if v is None:
        return "-"
    if isinstance(v, float | np.floating):
        if not np.isfinite(v):
            return "-"
        return f"{v:.{digits}g}"
    return str(v)


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A fixed-width table: first column left-aligned, the others right-aligned.

    Parameters
    ----------
    headers : sequence of str
        Column headings (units in brackets, as the caller writes them).
    rows : sequence of sequences
        Cells, formatted with :func:`format_value`.

    Returns
    -------
    str
        The heading line, a rule of dashes, then one line per row.
    """
    cells = [[str(h) for h in headers]] + [[format_value(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = [
        "  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths)))
        for r in cells
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def predict_text(results: Sequence[PredictionResult], units: str) -> str:
    """The table ``terracone predict`` prints, with its lack-of-fit, error and phic notes.

    Parameters
    ----------
    results : sequence of PredictionResult
        One per profile, fitted or not.
    units : {"si", "us"}
        Units of the printed kc, kphi, cc and RMSD.

    Returns
    -------
    str
    """
    rows = []
    for r in results:
        d = r.as_dict(units, curves=False)
        fit = ("LACK OF FIT" if d.get("lack_of_fit") else "ok") if d["status"] == "ok" else "-"
        rows.append(
            [d["id"], d["status"], d["kc"], d["kphi"], d["n"], d["cc"], d["phic_deg"]]
            + [d["rmsd"], d["r2_ci"], ",".join(d["undetermined"]) or "-", fit]
        )
    heads = [
        "profile",
        "status",
        f"kc [{u.kc_unit(units)}]",
        f"kphi [{u.kphi_unit(units)}]",
        "n",
        f"cc [{u.pressure_unit(units)}]",
        "phic [deg]",
        f"RMSD [{u.pressure_unit(units)}]",
        "R2 CI",
        "undetermined",
        "fit",
    ]
    text = table(heads, rows)
    lof = [r for r in results if r.ok and r.lack_of_fit]
    if lof:
        text += "\n\nLack of fit (these parameters are not the terrain's; try --depth-range or a layered model):"
        text += "".join(f"\n  {r.id}: {r.lack_of_fit}" for r in lof)
    errs = [r for r in results if not r.ok]
    if errs:
        text += "\n\nProfiles not fitted:\n" + "\n".join(f"  {r.id}: {r.error}" for r in errs)
    if any("phic" in r.undetermined for r in results if r.ok):
        text += PHIC_UNDETERMINED
    return text


def learn_text(d: Mapping[str, Any], units: str) -> str:
    """The report ``terracone learn`` prints.

    Parameters
    ----------
    d : mapping
        ``LearnResult.as_dict(units)`` with ``terrain`` added, and optionally
        ``saved`` (a calibration file) and ``saved_as`` (a library name).
    units : {"si", "us"}
        The units ``d`` is in.

    Returns
    -------
    str
    """
    rows = [
        ["kc", d["kc"], u.kc_unit(units)],
        ["kphi", d["kphi"], u.kphi_unit(units)],
        ["n", d["n"], "-"],
        ["cc", d["cc"], u.pressure_unit(units)],
        ["phic", d["phic_deg"], "deg"],
        ["r_min", d["r_min"], u.length_unit(units)],
        ["RMSD CI", d["rmsd_ci"], u.pressure_unit(units)],
        ["RMSD plates", d["rmsd_plates"], u.pressure_unit(units)],
    ]
    text = f"Learned calibration for {d['terrain']!r} ({d['model']}):\n" + table(
        ["parameter", "value", "unit"], rows
    )
    ds = [[x["kind"], x["id"], x["rmsd"], x["cv"]] for x in d["datasets"]]
    text += "\n\nPer data set:\n" + table(
        ["kind", "id", f"RMSD [{u.pressure_unit(units)}]", "CV"], ds
    )
    c = d["criteria"]
    text += f"\n\nFit criterion CV <= {c['max_cv']:g}: {'satisfied' if c['satisfied'] else 'NOT satisfied'} (worst {c['worst_cv']:.3g})"
    cert = d.get("certificate") or {}
    if cert:
        text += (
            f"\nObjective J = {d['objective']:.6g}; global-minimum bound {cert['lower_bound']:.6g} "
            f"(gap {cert['gap']:.3g}; inner gap {cert['inner_gap']:.2g})"
        )
    if d["undetermined"]:
        text += f"\nLeft free by the data: {', '.join(d['undetermined'])}"
    if c.get("at_bounds"):
        text += (
            f"\nOn a search bound (the bound, not the data, set it): {'; '.join(c['at_bounds'])}"
        )
    if d.get("saved"):
        text += f"\nCalibration saved to {d['saved']}"
    if d.get("saved_as"):
        text += f"\nCalibration stored in the terrain library as {d['saved_as']!r}"
    return text


def evaluate_text(rows: Sequence[PlateEvaluation], units: str) -> str:
    """The agreement table ``terracone evaluate`` prints (R, R2, RMSD, CV; Tables 4-2, 4-4).

    Parameters
    ----------
    rows : sequence of PlateEvaluation
        From :func:`terracone.inverse.evaluate.cross_table`.
    units : {"si", "us"}
        Units of the plate size b and the RMSD.

    Returns
    -------
    str
    """
    tab = [
        [
            r.prediction,
            r.test,
            float(u.length_from_si(r.b, units)),
            r.agreement.R,
            r.agreement.R2,
            float(u.pressure_from_si(r.agreement.RMSD, units)),
            r.agreement.CV,
        ]
        for r in rows
    ]
    heads = [
        "prediction",
        "plate test",
        f"b [{u.length_unit(units)}]",
        "R",
        "R2",
        f"RMSD [{u.pressure_unit(units)}]",
        "CV",
    ]
    return table(heads, tab)

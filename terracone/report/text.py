"""Plain-text tables of terracone results, as the command line and the demo print them.

Every function here takes results already computed (in SI inside the
result objects) and a unit system, converts at the edge and returns text;
none computes anything.  :mod:`terracone.cli` prints them (the demo's
transcript is :func:`demo_text` of :func:`terracone.apps.example.run_demo`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from terracone.physics import units as u
from terracone.resultunits import from_si

if TYPE_CHECKING:  # pragma: no cover - annotations only
    from terracone.apps.example import Demo
    from terracone.inverse.evaluate import PlateEvaluation
    from terracone.result import PredictionResult

__all__ = [
    "curve_text",
    "demo_text",
    "design_text",
    "evaluate_text",
    "format_value",
    "layered_text",
    "learn_text",
    "library_prior_text",
    "library_text",
    "match_text",
    "plate_fit_text",
    "posterior_text",
    "predict_text",
    "shear_fit_text",
    "sites_text",
    "table",
]

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


def curve_text(headers: Sequence[str], x: Any, y: Any) -> str:
    """A two-column table of a curve (``terracone ci`` and ``terracone plate``).

    Parameters
    ----------
    headers : (str, str)
        Headings of x and y, with their units.
    x, y : array_like
        The curve, already in the output units.

    Returns
    -------
    str
    """
    return table(headers, list(zip(np.asarray(x).tolist(), np.asarray(y).tolist())))


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
    P = u.pressure_unit(units)
    heads = ["profile", "status", f"kc [{u.kc_unit(units)}]", f"kphi [{u.kphi_unit(units)}]", "n"]
    heads += [f"cc [{P}]", "phic [deg]", f"RMSD [{P}]", "R2 CI", "undetermined", "fit"]
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
    if "r_min" in (d.get("flat_sets") or {}):
        lo, hi = d["flat_sets"]["r_min"]
        text += (
            f"\nr_min: every value in ({lo:.6g}, {hi:.6g}] {u.length_unit(units)} fits exactly as "
            "well (above the larger plate the RM1 law is the secant through both plates' "
            "pressures, which does not depend on r_min)"
        )
    for e in d.get("equivalent") or []:
        text += (
            f"\nFits exactly as well: r_min = {e['r_min']:.6g} {u.length_unit(units)} with "
            f"kc = {e['kc']:.6g} {u.kc_unit(units)}, kphi = {e['kphi']:.6g} {u.kphi_unit(units)} "
            "(at the larger plate the tangent is the same line as the secant through both "
            "plates' pressures: the data do not fix kc and kphi)"
        )
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
    tab = []
    for r in rows:
        a, b = r.agreement, from_si(r.b, "length", units)
        tab.append([r.prediction, r.test, b, a.R, a.R2, from_si(a.RMSD, "pressure", units), a.CV])
    heads = ["prediction", "plate test", f"b [{u.length_unit(units)}]", "R", "R2"]
    return table(heads + [f"RMSD [{u.pressure_unit(units)}]", "CV"], tab)


def posterior_text(posts: Mapping[str, Any], units: str) -> str:
    """The posterior section ``terracone predict --uncertainty`` prints.

    Parameters
    ----------
    posts : mapping
        Profile id -> posterior (anything with ``as_dict(units)`` giving
        ``intervals``, ``medians``, ``identifiability`` and ``plate_bands``),
        as :class:`terracone.inverse.uncertainty.posterior.PosteriorResult`.
    units : {"si", "us"}
        Units of the printed intervals and plate bands.

    Returns
    -------
    str
        90% intervals, medians and identifiability labels per parameter, and
        the plate pressure band at the deepest sinkage of each plate.
    """
    lines = ["", "Posterior 90% intervals and identifiability (--uncertainty):"]
    L, P = u.length_unit(units), u.pressure_unit(units)
    for pid, post in posts.items():
        d = post.as_dict(units)
        rows = [
            [k, lo, d["medians"].get(k), hi, d["identifiability"].get(k, "-")]
            for k, (lo, hi) in d["intervals"].items()
        ]
        lines.append(f"{pid}:")
        lines.append(table(["parameter", "5%", "median", "95%", "identifiability"], rows))
        for band in d.get("plate_bands", []):
            i = len(band["sinkage"]) - 1
            lines.append(
                f"  plate r = {band['radius']:.4g} {L}: pressure at "
                f"{band['sinkage'][i]:.3g} {L} sinkage {band['median'][i]:.4g} "
                f"[{band['lo'][i]:.4g}, {band['hi'][i]:.4g}] {P} (90% band)"
            )
    return "\n".join(lines)


def layered_text(layered: Mapping[str, Any], units: str) -> str:
    """The layered-fit table ``terracone predict --layers N`` prints.

    Parameters
    ----------
    layered : mapping
        Profile id -> :class:`terracone.inverse.layered.LayeredResult` (interfaces [m]).
    units : {"si", "us"}
        Unit of the printed interface depths.

    Returns
    -------
    str
    """
    rows = []
    for pid, lr in layered.items():
        if not lr.ok:
            rows.append([pid, "error", lr.error, "-", "-", "-", "-", "-"])
            continue
        iface = ",".join(f"{v:.3g}" for v in from_si(lr.interfaces, "length", units))
        ns = ",".join(f"{p.n:.3g}" for p in lr.layers)
        rows.append([pid, "ok", iface, ns, lr.r2_ci, lr.bic_single, lr.bic, lr.preferred_layers])
    heads = ["profile", "status", f"interfaces [{u.length_unit(units)}]", "n per layer", "R2 CI"]
    heads += ["BIC 1 layer", "BIC layered", "preferred layers"]
    return "\n\nLayered fits (element-wise integration; lower BIC wins):\n" + table(heads, rows)


def plate_fit_text(d: Mapping[str, Any], units: str) -> str:
    """The report ``terracone fit-plates`` prints.

    Parameters
    ----------
    d : mapping
        ``PlatesFit.as_dict(units)`` (:func:`terracone.inverse.bevameter.plates.fit_plates`).
    units : {"si", "us"}
        The units ``d`` is in.

    Returns
    -------
    str
        Per-test b, k, n, points and R2; the common n with its 95% interval,
        kc and kphi, notes and undetermined parameters.
    """
    rows = [[t["test"], t["b"], t["k"], t["n"], t["points_used"], t["r2"]] for t in d["tests"]]
    text = table(
        ["test", f"b [{u.length_unit(units)}]", f"k [{u.kphi_unit(units)}]", "n", "points", "R2"],
        rows,
    )
    text += f"\n\nCommon n = {d['n']:.4g}" + (
        f", 95% interval {d['n_ci'][0]:.3g} to {d['n_ci'][1]:.3g}" if d["n_ci"] else ""
    )
    if d["kc"] is not None:
        text += (
            f"\nkc = {d['kc']:.4g} {u.kc_unit(units)}, kphi = {d['kphi']:.4g} {u.kphi_unit(units)}"
        )
    text += "".join(f"\n{note}" for note in d["notes"])
    if d["undetermined"]:
        text += f"\nUndetermined: {', '.join(d['undetermined'])}"
    return text


def shear_fit_text(d: Mapping[str, Any], units: str) -> str:
    """The report ``terracone fit-shear`` prints (Janosi-Hanamoto fits).

    Parameters
    ----------
    d : mapping
        ``ShearFit.as_dict(units)`` (:func:`terracone.inverse.bevameter.shear.fit_shear`).
    units : {"si", "us"}
        The units ``d`` is in.

    Returns
    -------
    str
    """
    L, Pu = u.length_unit(units), u.pressure_unit(units)
    rows = [
        [t["test"], t["normal_pressure"], t["tau_max"], t["K"], t["points_used"]]
        for t in d["tests"]
    ]
    text = table(["test", f"sigma [{Pu}]", f"tau_max [{Pu}]", f"K [{L}]", "points"], rows)
    text += (
        f"\n\nc = {format_value(d['c'])} {Pu}, phi = {format_value(d['phi_deg'])} deg, "
        f"common K = {format_value(d['K'])} {L}"
    )
    return text + "".join(f"\n{note}" for note in d["notes"])


def library_text(records: Sequence[Any]) -> str:
    """The table ``terracone library list`` prints: name, kind, kc, kphi, n (SI).

    Parameters
    ----------
    records : sequence of TerrainRecord
        From :meth:`terracone.apps.library.Library.list`.

    Returns
    -------
    str
    """
    rows = [
        [r.name, r.kind, r.params.get("kc"), r.params.get("kphi"), r.params.get("n")]
        for r in records
    ]
    return table(["name", "kind", "kc [kN/m^(n+1)]", "kphi [kN/m^(n+2)]", "n"], rows)


def _site_row(d: Mapping[str, Any]) -> list[Any]:
    """A site at the middle sinkage of its first plate: p, its 90% range, CVs, pushes needed."""
    at: list[Any] = [None, "-", None, "-", None]
    if d["plate_pressure"]:
        pl = d["plate_pressure"][0]
        v = {k: x[len(pl["sinkage"]) // 2] for k, x in pl.items() if isinstance(x, list)}
        p90 = f"{format_value(v['lo'])}-{format_value(v['hi'])}"
        cv90 = f"{format_value(v['between_cv_lo'])}-{format_value(v['between_cv_hi'])}"
        at = [v["median"], p90, v["between_cv"], cv90, v["naive_cv"]]
    needed = [d["profiles_needed"], d["profiles_needed_hi"]]
    fit = "LACK OF FIT" if d["lack_of_fit"] else "ok"
    return [d["site"], d["n_profiles"], d["params"].get("n"), *at, *needed, fit]


def sites_text(sites: Sequence[Mapping[str, Any]], units: str) -> str:
    """The site table ``terracone sites`` prints, with each site's notes and failed pushes.

    Parameters
    ----------
    sites : sequence of mapping
        ``SiteResult.as_dict(units)`` per site (:func:`terracone.inverse.sites.statistics.fit_sites`).
    units : {"si", "us"}
        The units the sites are in.

    Returns
    -------
    str
        Plate pressure, its 90% interval, the push-to-push CV with its
        interval, the naive CV and the pushes needed, at the middle sinkage
        of each site's first plate.
    """
    pl0 = next((d["plate_pressure"][0] for d in sites if d["plate_pressure"]), None)
    at = ""
    if pl0:
        k = len(pl0["sinkage"]) // 2
        at = f" at r = {pl0['radius']:.3g} {u.length_unit(units)}, z = {pl0['sinkage'][k]:.3g}"
    heads = [
        "site",
        "pushes",
        "n",
        f"p [{u.pressure_unit(units)}]",
        "p 90%",
        "between CV",
        "CV 90%",
    ]
    heads += ["naive CV", "needed", "needed (CV hi)", "fit"]
    rows = [_site_row(d) for d in sites]
    text = f"Site plate pressure{at} {u.length_unit(units)}:\n" + table(heads, rows)
    for d in sites:
        extra = [d["lack_of_fit"]] if d["lack_of_fit"] else []
        extra += d["notes"] + [f"{f['id']}: {f['error']}" for f in d["failed"]]
        if extra:
            text += f"\n  {d['site']}: " + f"\n  {d['site']}: ".join(extra)
    return text


def design_text(designs: Sequence[Mapping[str, Any]], units: str) -> str:
    """The ranking ``terracone design`` prints: per profile, the candidate tests by value.

    Parameters
    ----------
    designs : sequence of mapping
        ``DesignResult.as_dict(units)`` per profile, or ``{"id", "status", "error"}``
        for a profile that could not be planned.
    units : {"si", "us"}
        The units the designs are in.

    Returns
    -------
    str
    """
    pu = u.pressure_unit(units)
    parts = []
    for d in designs:
        if d["status"] != "ok":
            parts.append(f"{d['id']}: not fitted: {d['error']}")
            continue
        head = (
            f"{d['id']} (prior {d['prior']}): plate pressure at z = {d['sinkage']:.3g} "
            f"{u.length_unit(units)}: "
            + ", ".join(
                f"r = {r:.3g}: {m:.4g} {pu}, 90% width {w:.3g}"
                for r, m, w in zip(d["plates"], d["median"], d["current_width"])
            )
        )
        rows = [
            [c["rank"], c["test"], ", ".join(f"{w:.3g}" for w in c["expected_width"]),
             c["width_ratio"], c["note"]]
            for c in d["candidates"]
        ]  # fmt: skip
        tab = table(["rank", "test", f"expected 90% width [{pu}]", "ratio", "note"], rows)
        if d["lack_of_fit"]:
            tab += f"\n  lack of fit: {d['lack_of_fit']}"
        parts.append(head + "\n" + tab)
    return "\n\n".join(parts)


def demo_text(demo: Demo) -> str:
    """The transcript ``terracone demo`` prints, of :func:`terracone.apps.example.run_demo`."""
    units, t = demo.units, demo.truth
    parts = [
        "terracone demo: SYNTHETIC LETE-sand-like data generated by terracone's forward models",
        f"  CI profiles: {demo.ci_file}",
        f"  plate tests: {demo.plates_file}",
        "",
        "1. Learning process (section 3.3.1): the three CI profiles with the plate pair",
        learn_text(demo.learned, units),
        f"   (truth: kc {t['kc']:g}, kphi {t['kphi']:g}, n {t['n']:g}, cc {t['cc']:g} kPa, "
        f"phic {t['phic_deg']:g} deg, r_min {t['r_min'] * 1000:g} mm, in SI)",
        "",
        "2. Prediction process (section 3.3.2) with that calibration, all profiles",
        predict_text(demo.calibrated, units),
        "",
        "3. Prediction without calibration (phic free): what the CI alone determines",
        predict_text(demo.free, units),
        "",
        "4. Evaluation (Table 4-2 style): calibrated predictions against the plate tests",
        evaluate_text(demo.evaluation, units),
    ]
    if demo.out is not None:
        parts.append(f"\nJSON written to {demo.out}")
    return "\n".join(parts)


def _span(lohi: Sequence[float] | None) -> str:
    return "-" if not lohi else f"{format_value(lohi[0])}-{format_value(lohi[1])}"


def library_prior_text(results: Sequence[PredictionResult], units: str) -> str:
    """What ``terracone predict --library`` adds: the mixture and which calibration carries it.

    Parameters
    ----------
    results : sequence of PredictionResult
        With ``library`` (and, in the library, the mixture as ``posterior``).
    units : {"si", "us"}

    Returns
    -------
    str
        Per profile: the calibration carrying the answer (or the mixture, or
        outside the library), its weight, the 90% intervals of kc, kphi and n
        and the plate pressure band at the deepest sinkage of the first
        plate; then each profile's sentence.
    """
    rows, words, band_at = [], [], ""
    for r in results:
        if r.library is None:
            continue
        d = r.as_dict(units, curves=False, samples=False)
        lib = d["library"]
        top = lib["candidates"][0] if lib["candidates"] else {}
        answer = "outside" if d["outside_library"] else (lib["carried_by"] or "mixture")
        iv = d.get("intervals") or {}
        p = ["-", "-"]
        if lib["plate_bands"] and not d["outside_library"]:
            b = lib["plate_bands"][0]
            i = len(b["sinkage"]) - 1
            band_at = (
                f" (plate r = {b['radius']:.4g}, z = {b['sinkage'][i]:.3g} {u.length_unit(units)})"
            )
            p = [b["median"][i], _span([b["lo"][i], b["hi"][i]])]
        rows.append([d["id"], answer, top.get("terrain", "-"), top.get("weight"),
                     _span(iv.get("kc")), _span(iv.get("kphi")), _span(iv.get("n")), *p])  # fmt: skip
        words += [f"  {d['id']}: {w}" for w in lib["notes"][:1]]
    if not rows:
        return ""
    P = u.pressure_unit(units)
    heads = ["profile", "answer", "heaviest calibration", "weight", "kc 90%", "kphi 90%"]
    heads += ["n 90%", f"p [{P}]", f"p 90% [{P}]"]
    head = f"\nThe library as the prior: mixture medians and 90% intervals{band_at}:\n"
    return head + table(heads, rows) + "\n" + "\n".join(words)


def match_text(doc: Mapping[str, Any]) -> str:
    """The ranking ``terracone match`` prints: per group, its calibrations by weight.

    Parameters
    ----------
    doc : mapping
        :meth:`terracone.apps.matching.MatchRun.as_dict`.

    Returns
    -------
    str
    """
    out = []
    level = doc["settings"]["check_level"]
    for g in doc["groups"]:
        head = f"{g['id']} ({len(g['profiles'])} profile{'s' if len(g['profiles']) != 1 else ''})"
        if g["error"]:
            out.append(f"{head}: not matched: {g['error']}")
            continue
        if g["outside_library"]:
            verdict = f"outside the library: every calibration's check p-value < {level:g}"
        elif g["carried_by"]:
            verdict = f"like {g['carried_by']!r}"
        else:
            verdict = "no single calibration carries it"
        rows = [
            [c["terrain"], c["weight"], c["prior_weight"], c["check_p"]] for c in g["candidates"]
        ]
        out.append(f"{head}: {verdict}")
        out.append(table(["calibration", "weight", "prior weight", "check p"], rows))
    for d in doc.get("unassigned", []):
        out.append(f"not in a site: {d['id']}: {d['reason']}")
    for e in doc.get("errors", []):
        out.append(f"not read: {e}")
    return "\n".join(out)

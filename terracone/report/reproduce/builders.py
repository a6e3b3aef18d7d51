"""The parts of a case study's report: one builder per kind of table or figure.

A builder takes the :class:`Output` of the report, a case study
(:class:`~terracone.apps.reproduce.cases.Case`, as the run filled it in) and
the name of its part, and returns report parts (:mod:`terracone.report.parts`);
its words come from :data:`terracone.report.reproduce.texts.TEXTS`.  Tables are
written at once; figures are queued and drawn later through a pool's ``map``
(:meth:`Output.render`).  :data:`PARTS` maps part names to builders.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from terracone.apps.reproduce.cases import WONG_LETE, Case, si_row
from terracone.apps.reproduce.pool import run_task
from terracone.apps.reproduce.run import OutputFiles
from terracone.inverse.evaluate import predicted_plate_pressure
from terracone.report import figures as F
from terracone.report.parts import text_part
from terracone.report.reproduce.texts import PUBLISHED_LABEL, TEXTS
from terracone.report.tables import (
    Table,
    agreement_table,
    comparison_table,
    identifiability_table,
    mark_bounds,
    parameter_comparison_table,
    parameters_table,
)

__all__ = ["Output", "PARTS"]


def _render(fig: Callable[[], Any], directory: Path, key: str) -> dict[str, Path]:
    """Draw one figure and write its PNG and SVG (runs in a worker)."""
    return F.save_figure(fig(), directory, key)


class Output(OutputFiles):
    """The files, figures and tables of a report; figures render later, in the pool."""

    def __init__(self, root: Path, files: Sequence[Path] = ()) -> None:
        super().__init__(root, files)
        self.tables: dict[str, Path] = {}
        self.figures: dict[str, dict[str, Path]] = {}
        self.pending: list[partial] = []

    def table(self, t: Table, max_rows: int | None = None) -> dict[str, Any]:
        """Write table ``t`` as ``tables/key.csv`` and ``.html``; return its report part."""
        self.tables[t.key] = csv_path = self.file(self.root / "tables" / f"{t.key}.csv")
        t.to_csv(csv_path)
        self.file(self.root / "tables" / f"{t.key}.html").write_text(t.to_html() + "\n")
        return {"type": "table", "table": t.to_dict(), "max_rows": max_rows}

    def figure(self, fig: Callable[[], Any], key: str, caption: str) -> dict[str, Any]:
        """Queue figure ``fig`` (a ``partial``) as ``figures/key.png`` and ``.svg``."""
        self.pending.append(partial(_render, fig, self.root / "figures", key))
        paths = {f: self.root / "figures" / f"{key}.{f}" for f in ("png", "svg")}
        for p in paths.values():
            self.file(p)
        self.figures[key] = paths
        files = {f: self.rel(p) for f, p in paths.items()}
        return {"type": "figure", **files, "caption": caption, "alt": caption.split(".")[0]}

    def render(self, mapper: Callable[..., Any]) -> None:
        """Draw the queued figures with ``mapper`` (a pool's map)."""
        list(mapper(run_task, self.pending))
        self.pending = []


def _texts(case: Case, name: str) -> dict[str, Any]:
    """The words of part ``name`` of ``case``."""
    return TEXTS[case.spec.slug][name]


def _span(ids: Sequence[str]) -> str:
    """ "LS_1" or "LS_1 to LS_4"."""
    ids = list(ids)
    return ids[0] if len(ids) == 1 else f"{ids[0]} to {ids[-1]}"


def _bands(post: dict[str, Any] | None, id_: str) -> list[dict[str, Any]]:
    if not post:
        return []
    return [
        {
            "id": id_,
            "label": f"{id_} 90% band, r = {b['radius'] * 100:.3g} cm",
            "radius": b["radius"],
            **{k: np.asarray(b[k]) for k in ("sinkage", "lo", "hi")},
        }
        for b in post.get("plate_bands", [])
    ]


def _ident_profiles(results, posts):
    """Result dicts (SI) with their posterior's identifiability and intervals, if any."""
    out = [r.as_dict("si", curves=False, samples=False) for r in results]
    for d in out:
        if post := (posts or {}).get(d["id"]):
            d |= {k: post.get(k) for k in ("identifiability", "intervals")}
    return out


def _curve(id_: str, b: float, sinkage, pressure, label: str | None = None) -> dict[str, Any]:
    """A plate curve of the figures: id, radius [m], sinkage [m], pressure [kPa], label."""
    return {"id": id_, "radius": b, "sinkage": sinkage, "pressure": pressure} | (
        {"label": label} if label else {}
    )


def _rmin_mm(r: dict[str, Any]) -> float | None:
    return None if r.get("r_min") is None else r["r_min"] * 1000


def _parameters_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Table 4-1/4-3 analogue: parameters predicted with the calibration."""
    ok = [r for r in case.cal_res if r.ok]
    t = parameters_table(
        [{**si_row(r.params, r.id), "rmsd": r.rmsd, "r2": r.r2_ci} for r in ok],
        extra=(
            ("RMSD of CI", "kPa", lambda r: r["rmsd"]),
            ("R2 of CI", "", lambda r: r["r2"]),
        ),
        synthetic=True,
        **_texts(case, name),
    )
    mark_bounds(t, [si_row(r.params, r.id) for r in ok])
    return [out.table(t)]


def _parameters_vs_published_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Published parameters beside ours, with the calibration and from the CI alone."""
    sets = [
        (PUBLISHED_LABEL[case.spec.slug], [dict(p) for p in case.pub]),
        ("ours, with calibration", [si_row(r.params, r.id) for r in case.cal_res if r.ok]),
        ("ours, CI alone", [si_row(r.params, r.id) for r in case.free_res if r.ok]),
    ]
    tab = case.spec.parameter_table
    title = f"{case.spec.name} parameters: published (Table {tab}) beside ours"
    words = TEXTS[case.spec.slug].get(name, {})
    text = {"key": _vs_published_key(case, tab), "title": title} | words
    return [out.table(parameter_comparison_table(sets, synthetic=True, **text))]


def _identifiability_part(
    out: Output, case: Case, name: str, *, calibrated: bool
) -> list[dict[str, Any]]:
    """What each CI profile determines, with the calibration (posterior) or alone."""
    if calibrated:
        profiles, fixed = _ident_profiles(case.cal_res, case.posts), {"fixed": ("phic", "cc")}
    else:
        profiles, fixed = _ident_profiles(case.free_res, None), {}
    t = identifiability_table(profiles, synthetic=True, **fixed, **_texts(case, name))
    return [out.table(t)]


def _agreement_part(out: Output, case: Case, name: str, *, rows: str) -> list[dict[str, Any]]:
    """Table 4-2/4-4 analogue of the rows ``rows_cal``, ``rows_free`` or ``rows_ctrl``."""
    t = agreement_table(
        getattr(case, rows), plates=list(case.spec.plates), synthetic=True, **_texts(case, name)
    )
    return [out.table(t)]


def _agreement_vs_published_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Our agreement (with the calibration) beside the paper's, row by row."""
    tab = case.spec.agreement_table
    csv = f"terracone/data/paper/table_{tab.replace('-', '_')}.csv"
    t = comparison_table(
        case.rows_cal,
        case.published,
        key=_vs_published_key(case, tab),
        title=f"Table {tab}: ours (with calibration) beside the paper",
        notes=[f"paper: Table {tab} as published (package data {csv})."],
    )
    return [out.table(t)]


def _vs_published_key(case: Case, tab: str) -> str:
    """Key of the table of ours beside the paper's Table ``tab`` ("4-1" .. "4-4")."""
    return f"table_{tab.replace('-', '_')}_{case.spec.slug}_vs_published"


def _ridge_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Not in the paper: the ridge of equally good fits of the first profile."""
    f = _texts(case, name)
    p0, pub0 = case.profiles[0], case.pub[0]
    fig = partial(
        F.fig_ridge,
        p0.depth,
        p0.ci,
        profile_id=p0.id,
        reference={"n": pub0["n"], "phic_deg": pub0["phic_deg"]},
        reference_label=f"Table {case.spec.parameter_table} (generated the data)",
        title=f"{p0.id}: the ridge of equally good fits (RM0, CI alone)",
        synthetic=True,
    )
    key = f["key"].format(id=p0.id, lower=p0.id.lower())
    return [out.figure(fig, key, f["caption"].format(id=p0.id))]


def _lete_learning_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """LETE: the one calibration learned on all data, beside Wong's values."""
    (lr,) = case.learned.values()
    text = dict(_texts(case, name))
    wong = {"id": "Wong's LETE sand values (plates' truth)", **WONG_LETE}
    rows = [si_row(lr.params, "learned (LETE, all data)"), wong | {"cc": None, "phic_deg": None}]
    free = "Left free by the learning data: " + (", ".join(lr.undetermined) or "none")
    t = parameters_table(
        rows,
        extra=(("model", "", lambda r: r.get("model")), ("r_min", "mm", _rmin_mm)),
        notes=[free, *text.pop("notes")],
        synthetic=True,
        **text,
    )
    mark_bounds(t, rows, rmin_col=10, rmin_range=(5e-4, 3 * max(case.spec.plates.values())))
    return [out.table(t)]


def _learning_datasets_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """LETE: the fit of the learned parameters to each CI profile and plate test."""
    (lr,) = case.learned.values()
    rows = [
        [d["id"], d["kind"], None if d.get("b") is None else d["b"] * 100, d["rmsd"], d["cv"]]
        for d in lr.datasets
    ]
    c, text = lr.criteria, _texts(case, name)
    ok = "satisfied" if c["satisfied"] else "NOT satisfied"
    t = Table(
        text["key"],
        text["title"],
        [("Data set", ""), ("Kind", ""), ("Plate radius", "cm"), ("RMSD", "kPa"), ("CV", "")],
        rows,
        notes=[f"Fit criterion CV <= {c['max_cv']:g}: {ok}"],
        synthetic=True,
    )
    return [out.table(t)]


def _site_learning_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """KRC: the calibration learned on each site's CI and plate pair."""
    rows = [si_row(case.learned[p["id"]].params, p["id"]) for p in case.pub]
    t = parameters_table(
        rows,
        extra=(
            ("r_min", "mm", _rmin_mm),
            ("left free", "", lambda r: ", ".join(case.learned[r["id"]].undetermined) or "-"),
        ),
        synthetic=True,
        **_texts(case, name),
    )
    mark_bounds(t, rows, rmin_col=9, rmin_range=(5e-4, 3 * max(case.spec.plates.values())))
    return [out.table(t)]


def _janosi_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Figure 2-1 analogue: the CI against the Janosi equation with Wong's values."""
    f = _texts(case, name)
    (lr,) = case.learned.values()
    (cal,) = case.cals.values()
    learned = {k: getattr(lr.params, k) for k in ("cc", "phic_deg", "model", "r_min")}
    improved = WONG_LETE | learned | {"plate_pair": cal.plate_pair, "label": f["improved_label"]}
    measured = [{"id": p.id, "depth": p.depth, "ci": p.ci} for p in case.profiles]
    fig = partial(
        F.fig_janosi,
        measured,
        WONG_LETE,
        improved_params=improved,
        params_label=f["params_label"],
        title=f["title"],
        synthetic=True,
    )
    return [out.figure(fig, f["key"], f["caption"])]


def _ci_fit_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Figure 4-1 analogue: measured and predicted CI."""
    f = _texts(case, name)
    fitted = [
        {"id": r.id, "depth": r.depth, "ci": r.ci, "ci_model": r.ci_model}
        for r in case.cal_res
        if r.ok
    ]
    fig = partial(F.fig_ci_fit, fitted, title=f["title"], synthetic=True)
    return [out.figure(fig, f["key"], f["caption"])]


def _plates_part(out: Output, case: Case, name: str, *, calibrated: bool) -> list[dict[str, Any]]:
    """Figure 4-2 analogue: every plate test against every profile's prediction."""
    f = _texts(case, name)
    (cal,) = case.cals.values()
    results, pair = (case.cal_res, cal.plate_pair) if calibrated else (case.free_res, None)
    measured = [
        _curve(t.metadata["pair"], t.b, t.sinkage, t.pressure, f"{t.metadata['pair']} measured")
        for t in case.plates
    ]
    s = np.linspace(0.0, 0.1, 41)
    predicted = [
        _curve(r.id, b, s, predicted_plate_pressure(r.params, s, b, pair), f"{r.id} predicted")
        for r in results
        if r.ok
        for b in case.spec.plates.values()
    ]
    # calibrated: the posterior band of the first profile
    bands = [b for r in case.cal_res[:1] for b in _bands(case.posts.get(r.id), r.id)]
    bands = bands if calibrated else []
    fig = partial(F.fig_plate_fit, measured, predicted, bands, title=f["title"], synthetic=True)
    caption = f["caption"].format(
        pairs=_span(sorted({t.metadata["pair"] for t in case.plates})),
        profiles=_span([p.id for p in case.profiles]),
        bands=f["band_note"] if bands else ".",
    )
    return [out.figure(fig, f["key"], caption)]


def _site_figures_part(out: Output, case: Case, name: str) -> list[dict[str, Any]]:
    """Figures 4-3 to 4-10 analogues: each site's CI and plates, measured and predicted."""
    f = _texts(case, name)
    parts = []
    for rc in case.cal_res:
        if not rc.ok:
            parts.append(text_part(f"{rc.id}: not fitted ({rc.error})"))
            continue
        plates, pair = case.group_of(rc.id).plates, case.cal_of(rc.id).plate_pair
        measured = [_curve(t.id, t.b, t.sinkage, t.pressure) for t in plates]
        sinkages = [np.linspace(0.0, float(t.sinkage.max()), 41) for t in plates]
        predicted = [
            _curve(t.id, t.b, sk, predicted_plate_pressure(rc.params, sk, t.b, pair))
            for t, sk in zip(plates, sinkages)
        ]
        number = f["numbers"][rc.id]
        fig = partial(
            F.fig_site,
            {"id": rc.id, "depth": rc.depth, "ci": rc.ci, "ci_model": rc.ci_model},
            measured,
            predicted,
            _bands(case.posts.get(rc.id), rc.id),
            title=f["title"].format(number=number, id=rc.id),
            synthetic=True,
        )
        key = f["key"].format(number=number.replace("-", "_"), lower=rc.id.lower())
        bands = f["band_note"] if case.posts.get(rc.id) else "."
        caption = f["caption"].format(number=number, id=rc.id, bands=bands)
        parts.append(out.figure(fig, key, caption))
    return parts


#: Part name -> builder(out, case, name) -> report parts.  A case study's
#: sections (``texts.SECTIONS``) list part names; the builder takes its text
#: from ``texts.TEXTS[slug][name]``.
PARTS: dict[str, Callable[[Output, Case, str], list[dict[str, Any]]]] = {
    "learning": _lete_learning_part,
    "learning_datasets": _learning_datasets_part,
    "learning_per_site": _site_learning_part,
    "parameters": _parameters_part,
    "parameters_vs_published": _parameters_vs_published_part,
    "identifiability": partial(_identifiability_part, calibrated=True),
    "identifiability_ci_only": partial(_identifiability_part, calibrated=False),
    "agreement": partial(_agreement_part, rows="rows_cal"),
    "agreement_ci_only": partial(_agreement_part, rows="rows_free"),
    "agreement_control": partial(_agreement_part, rows="rows_ctrl"),
    "agreement_vs_published": _agreement_vs_published_part,
    "fig_janosi": _janosi_part,
    "fig_ci": _ci_fit_part,
    "fig_plates": partial(_plates_part, calibrated=True),
    "fig_plates_ci_only": partial(_plates_part, calibrated=False),
    "fig_sites": _site_figures_part,
    "fig_ridge": _ridge_part,
}

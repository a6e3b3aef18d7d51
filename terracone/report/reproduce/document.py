"""The report of a reproduce run: sections, figures, tables, ``report.html`` and ``reproduce.json``.

:func:`reproduce_report` is what ``terracone reproduce`` does: it runs
:func:`terracone.apps.reproduce.reproduce` (the synthetic data, the learning,
prediction, posteriors and evaluation; ``data/`` and ``results/``) and then
:func:`write_reproduce_report`, which draws the figures (in a pool), writes the
tables, the HTML report and ``reproduce.json`` (the document that
``terracone report`` rebuilds the report from).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from terracone import __version__
from terracone.apps.reproduce.cases import NOISE_MODEL, SYNTHETIC_KEYS, SYNTHETIC_TEXT, Case, si_row
from terracone.apps.reproduce.paper import (
    CITATION,
    published_agreement,
    published_parameters,
    us_column_check,
)
from terracone.apps.reproduce.pool import open_pool
from terracone.apps.reproduce.run import Reproduction, reproduce
from terracone.report.html import render_document
from terracone.report.parts import kv_part, list_part, text_part
from terracone.report.reproduce.builders import PARTS, Output
from terracone.report.reproduce.reading import reading
from terracone.report.reproduce.texts import ABOUT, ABOUT_POINTS, SECTIONS
from terracone.report.tables import agreement_table, parameters_table, summary_statistics

__all__ = ["ReproduceSummary", "reproduce_report", "write_reproduce_report"]


@dataclass
class ReproduceSummary:
    """What :func:`reproduce_report` (or :func:`write_reproduce_report`) wrote and found.

    Attributes
    ----------
    out_dir : Path
    report : Path
        The HTML report.
    quick : bool
    seconds : float
        Wall time of the run [s], computation and report.
    files : list of Path
        Every file written.
    lete_learned : dict
        LETE calibration parameters (SI: kc, kphi, n, cc, phic_deg, r_min).
    krc_learned : dict
        Per KRC site, the learned parameters (SI).
    tables : dict
        Table key -> CSV path.
    figures : dict
        Figure key -> {"png": path, "svg": path}.
    notes : list of str
    """

    out_dir: Path
    report: Path
    quick: bool
    seconds: float
    files: list[Path]
    lete_learned: dict[str, Any]
    krc_learned: dict[str, dict[str, Any]]
    tables: dict[str, Path] = field(default_factory=dict)
    figures: dict[str, dict[str, Path]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def reproduce_report(
    out_dir: str | Path,
    *,
    quick: bool = False,
    workers: int | None = None,
    pool: Any | None = None,
) -> ReproduceSummary:
    """Re-create the paper's LETE sand and KRC case studies on synthetic data, and report them.

    Parameters
    ----------
    out_dir : str or Path
        Output folder, laid out as ``docs/report.md`` describes (an earlier
        run's sub-folders are replaced; a folder with other files in
        ``data/``, ``figures/``, ``tables/`` or ``results/`` is refused with
        ValueError).
    quick : bool
        A small run for tests: LETE profiles LS_1, LS_2 and pairs LS_A to
        LS_C, KRC sites KRC_1 and KRC_3, a coarser learning grid, fewer
        posterior draws.
    workers : int, optional
        Worker processes when no ``pool`` is given (default: 2, or 1 on a
        one-core machine; 1: the builtin ``map`` here).  Results do not depend on it.
    pool : object with a ``map`` method, optional
        Runs the learning runs, the posteriors and the figures, as in emcee
        (an executor, a ``multiprocessing`` pool, or ``map``); results in
        order; the caller owns it.  Overrides ``workers``.

    Returns
    -------
    ReproduceSummary
    """
    run = reproduce(out_dir, quick=quick, workers=workers, pool=pool)
    with open_pool(workers, pool) as pm:
        return write_reproduce_report(run, pm.map)


def write_reproduce_report(run: Reproduction, mapper: Callable[..., Any] = map) -> ReproduceSummary:
    """Draw the figures and tables of ``run`` and write ``report.html`` and ``reproduce.json``.

    Parameters
    ----------
    run : Reproduction
        What :func:`terracone.apps.reproduce.reproduce` computed.
    mapper : callable
        A pool's ``map``: draws the figures (default: the builtin ``map``, here).

    Returns
    -------
    ReproduceSummary
    """
    t0 = time.perf_counter()
    out = Output(run.out_dir, run.files)
    sections = _document_sections(out, run.cases, quick=run.quick, notes=run.notes)
    out.render(mapper)
    t_fig = time.perf_counter() - t0
    seconds = run.seconds + time.perf_counter() - t0
    info = {
        "mode": "quick" if run.quick else "full",
        "worker processes": run.workers,
        "learning, prediction, posterior [s]": round(run.seconds_fits, 2),
        "figures and tables [s]": round(t_fig, 2),
        "total until the report [s]": round(seconds, 2),
        "learning grid (n, phic, r_min)": list(run.grid),
        "posterior draws per profile": run.draws,
        "terracone": __version__,
    }
    sections[1]["parts"] += [text_part("Run:"), kv_part(info)]
    report = _write_report(out, sections, quick=run.quick, seconds=seconds)
    lete, krc = run.cases
    return ReproduceSummary(
        out_dir=run.out_dir,
        report=report,
        quick=run.quick,
        seconds=run.seconds + time.perf_counter() - t0,
        files=out.files,
        lete_learned=si_row(lete.learned[lete.spec.name].params, "LETE"),
        krc_learned={k: si_row(v.params, k) for k, v in krc.learned.items()},
        tables=out.tables,
        figures=out.figures,
        notes=run.notes,
    )


def _write_report(
    out: Output, sections: list[dict[str, Any]], *, quick: bool, seconds: float
) -> Path:
    """report.html and reproduce.json (the document ``terracone report`` rebuilds from)."""
    document = {
        "title": "terracone reproduce: the paper's case studies on synthetic data",
        "subtitle": (
            "LETE sand and KRC soils, after Huang, Wong, Preston-Thomas and Jayakumar, Section 4"
            + (" (quick run: a subset)" if quick else "")
        ),
        "synthetic": True,
        "synthetic_text": SYNTHETIC_TEXT,
        "meta": {"output directory": str(out.root), "mode": "quick" if quick else "full"},
        "sections": sections,
    }
    report = out.file(out.root / "report.html")
    report.write_text(render_document(document, out.root), encoding="utf-8")
    manifest = {
        "kind": "terracone-reproduce",
        "terracone": __version__,
        **SYNTHETIC_KEYS,
        "quick": quick,
        "seconds": seconds,
        "noise_model": NOISE_MODEL,
        "document": document,
    }
    out.json(out.root / "reproduce.json", manifest)
    return report


def _document_sections(
    out: Output, cases: Sequence[Case], *, quick: bool, notes: list[str]
) -> list[dict[str, Any]]:
    """The report's sections: about, data, each case study's, then both side by side."""
    sections = [_about_section(), _data_section(cases)]
    for case in cases:
        for sec in SECTIONS[case.spec.slug]:
            if sec.full_only and quick:  # one ridge figure (LETE) is enough for a quick run
                continue
            parts = [p for name in sec.parts.split() for p in PARTS[name](out, case, name)]
            sections.append(_section(sec.id, sec.heading, parts))
    sections.append(_side_by_side_section(out, cases, quick))
    sections.append(_published_section(out))
    if notes:
        sections.append(_section("notes", "Notes from the run", [list_part(notes)]))
    return sections


def _section(id_: str, heading: str, parts: list[dict[str, Any]]) -> dict[str, Any]:
    return {"id": id_, "heading": heading, "parts": parts}


def _about_section() -> dict[str, Any]:
    return _section("about", "What this is", [text_part(ABOUT), list_part(ABOUT_POINTS)])


def _data_section(cases: Sequence[Case]) -> dict[str, Any]:
    files = [f"data/{name}" for case in cases for name in case.spec.files]
    inputs = (
        "Input files (terracone CSV, with the SYNTHETIC label in their header): "
        + ", ".join(files)
        + ". Results as JSON in results/ (learn, predict, evaluate, calibrations); "
        "any of them can be turned into its own report with terracone report."
    )
    return _section(
        "data", "Synthetic data and noise model", [list_part(NOISE_MODEL), text_part(inputs)]
    )


def _side_by_side_section(out: Output, cases: Sequence[Case], quick: bool) -> dict[str, Any]:
    groups = []
    for case in cases:
        s = case.spec.name.split()[0]  # "LETE", "KRC"
        groups += [
            (f"{s} ours, with calibration", case.rows_cal),
            (f"{s} ours, CI alone", case.rows_free),
            (f"{s} control: published parameters vs our plates", case.rows_ctrl),
            (f"{s} paper (Table {case.spec.agreement_table})", case.published),
        ]
    t_sum = summary_statistics(
        groups,
        key="summary_ours_vs_published",
        title="Ours beside the published Tables 4-2 and 4-4: medians and ranges",
        notes=[
            "Quick run: a subset of rows (the paper's rows are all of them)."
            if quick
            else "All rows of each table."
        ],
    )
    parts = [out.table(t_sum)] + [text_part(x) for x in reading(*cases, quick)]
    return _section("side-by-side", "Ours beside the paper: where and why they differ", parts)


def _published_section(out: Output) -> dict[str, Any]:
    def text(tab: str, note: str = "") -> dict[str, Any]:
        return {
            "key": f"published_table_{tab.replace('-', '_')}",
            "title": f"Published Table {tab} (package data)",
            "notes": [f"Source: {CITATION}, Table {tab}.{note}"],
        }

    tables = [parameters_table(published_parameters(tab), **text(tab)) for tab in ("4-1", "4-3")]
    for tab, same_site in (("4-2", False), ("4-4", True)):
        rows = published_agreement(tab)
        plates = list(dict.fromkeys(r["plate"] for r in rows))
        note = " psi columns recomputed from kPa."
        tables.append(agreement_table(rows, plates=plates, same_site=same_site, **text(tab, note)))
    bad = us_column_check()
    check = (
        "The printed US columns of Tables 4-1 and 4-3 agree with the SI columns converted by "
        "terracone.physics.units (kc and kphi with each row's n) to within 2%."
        if not bad
        else "Printed US values that do not follow from the SI ones: "
        + "; ".join(
            f"Table {b['table']} {b['id']} {b['param']}: printed {b['us_printed']}, computed "
            f"{b['us_computed']:.4g}"
            for b in bad
        )
    )
    parts = [text_part(check)] + [out.table(t) for t in tables]
    return _section("published", "The published tables", parts)

"""Re-create the paper's two case studies on synthetic data and report them.

SYNTHETIC DATA: generated from the published parameters (Tables 4-1 and
4-3) with the noise model :data:`NOISE_MODEL`, then learned, predicted and
evaluated beside the published tables; ``docs/report.md`` explains the data
and how to read the comparison.  Each case study is one spec (``_CASES``)
read by one builder per kind of table or figure; the learning runs,
posteriors and figures go through a ``pool`` with a ``map`` method (as in
emcee).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-1 to 4-4, Figures 2-1, 4-1 to 4-10.
"""

from __future__ import annotations

import math
import os
import shutil
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from terracone import __version__
from terracone.apps.workflow import attach_fits, plate_curves
from terracone.data import CIProfile, PlateTest, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.evaluate import PlateEvaluation, cross_table, predicted_plate_pressure
from terracone.inverse.learning.learn import LearnResult, learn
from terracone.inverse.predict import RunSettings, predict_many
from terracone.inverse.problem import Calibration, Problem
from terracone.io import write_ci_profiles, write_plate_tests
from terracone.physics import units as u
from terracone.physics.cone import cone_index
from terracone.physics.plate import plate_pressure
from terracone.report import figures as F
from terracone.report.html import render_document
from terracone.report.paper import (
    CITATION,
    published_agreement,
    published_parameters,
    us_column_check,
)
from terracone.report.tables import (
    Table,
    agreement_table,
    comparison_table,
    identifiability_table,
    mark_bounds,
    parameter_comparison_table,
    parameters_table,
    summary_statistics,
)
from terracone.result import PredictionResult, PredictionResults, dumps, settings_dict, to_document

__all__ = ["ReproduceSummary", "reproduce", "NOISE_MODEL", "WONG_LETE"]

SEED_LETE = 1981
SEED_KRC = 2018
CI_NOISE = 0.03
PLATE_NOISE = 0.02
LETE_PAIR_SPREAD = 0.10
GENERATING_MODEL = "rm0"
CI_DEPTHS = np.round(np.arange(0.0, 0.3001, 0.01), 4)  # cone-base depth [m]
SINKAGES = np.round(np.arange(0.002, 0.1001, 0.002), 4)  # [m]
LETE_PLATES = {"r=3.75cm": 0.0375, "r=5cm": 0.05}  # radius [m]
KRC_PLATES = {"D=10cm": 2.0 * u.INCH, "D=15cm": 3.0 * u.INCH}  # 4 in and 6 in diameter
KRC_FORCE_LIMIT = 1500.0 * u.LBF  # [N]
#: Wong's LETE sand values (section 2 of the paper; Wong, 1981), SI.
WONG_LETE = {"kc": 102.0, "kphi": 5301.0, "n": 0.79}
KRC_FIGURE = {f"KRC_{site}": f"4-{k}" for k, site in enumerate((1, 2, 3, 4, 7, 9, 24, 25), 3)}
LABEL = "SYNTHETIC"
SYNTHETIC_TEXT = (
    "Every curve, table and figure computed here comes from data that terracone generated "
    "from the paper's published parameters (Tables 4-1 and 4-3) and Wong's LETE sand values, "
    "with a stated noise model. They are not the paper's measurements, which were never "
    "published. Columns marked 'paper' are the published values."
)
_SYNTH = {"synthetic": True, "note": SYNTHETIC_TEXT}  # in every JSON document written

NOISE_MODEL = [
    f"CI: each reading x (1 + {CI_NOISE:g} e), e ~ N(0, 1) independent; cone-base depths 0 to "
    "30 cm every 1 cm; standard 30 deg, 0.5 in^2 cone; improved model eq. (2-7), "
    f"{GENERATING_MODEL.upper()} (r_min is not published), fully mobilised shear.",
    f"Plates: each pressure x (1 + {PLATE_NOISE:g} e); sinkage 2 to 100 mm every 2 mm; "
    "Bekker equation (2-2).",
    f"LETE plate pairs LS_A..LS_E: one factor exp({LETE_PAIR_SPREAD:g} g), g ~ N(0, 1), per "
    "pair (spread between tests on one site); radii 3.75 cm and 5 cm; Wong's LETE values "
    "kc 102 kN/m^(n+1), kphi 5301 kN/m^(n+2), n 0.79.",
    "KRC plates: 4 in (10.16 cm) and 6 in (15.24 cm) diameter, from the site's Table 4-3 "
    "parameters (the KRC plate data were never published); each test ends at 1,500 lbf "
    "(6,672 N): 823 kPa on the 4 in plate, 366 kPa on the 6 in plate.",
    f"Random numbers: numpy PCG64, seed {SEED_LETE} (LETE) and {SEED_KRC} (KRC); values "
    "rounded to 0.01 kPa.",
]


@dataclass
class ReproduceSummary:
    """What :func:`reproduce` wrote and found.

    Attributes
    ----------
    out_dir : Path
    report : Path
        The HTML report.
    quick : bool
    seconds : float
        Wall time of the run [s].
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


# ---------------------------------------------------------------------------
# the case studies as data
# ---------------------------------------------------------------------------


class _Group(NamedTuple):
    """One learning run: LETE learns once on all its data, KRC once per site."""

    id: str
    profiles: list[CIProfile]
    plates: list[PlateTest]


class _Section(NamedTuple):
    """One section of the report: anchor, heading and the parts drawn in it, in order."""

    id: str
    heading: str
    parts: str  # names of the parts (keys of ``_PARTS``), separated by spaces
    full_only: bool = False  # left out of a quick run


@dataclass(frozen=True)
class _CaseSpec:
    """What differs between the two case studies (one column of ``_CASE_TABLE``).

    The part builders (``_PARTS``) read it; ``texts[part]`` holds a table's
    keyword arguments (key, title, notes, ...) or a figure's key, title, caption.
    """

    slug: str  # file names and table keys: "lete", "krc"
    name: str  # "LETE sand", "KRC"
    seed: int
    parameter_table: str  # the paper's table of parameters: "4-1", "4-3"
    agreement_table: str  # the paper's table of agreement: "4-2", "4-4"
    quick_ids: tuple[str, ...]  # the profiles of a quick run
    plates: dict[str, float]  # plate label -> radius [m]
    per_site: bool  # learning, calibration files and evaluation rows per site
    generate: Callable[[_CaseSpec, list[dict[str, Any]], bool], _Case]  # the synthetic data
    files: tuple[str, str]  # data/ file names: CI profiles, plate tests
    comments: tuple[str, str]  # what each data file holds (its header)
    published_label: str
    sections: tuple[_Section, ...]
    texts: dict[str, dict[str, Any]]


@dataclass
class _Case:
    """One case study: its spec, synthetic data, and results as the run fills them in."""

    spec: _CaseSpec
    pub: list[dict[str, Any]]  # published parameters of the profiles (generated the CI)
    profiles: list[CIProfile]
    plates: list[PlateTest]
    where: dict[str, tuple[str, str]]  # plate test id -> (pair or site, plate label)
    groups: list[_Group]
    learned: dict[str, LearnResult] = field(default_factory=dict)  # by group id
    cals: dict[str, Calibration] = field(default_factory=dict)  # by group id
    cal_res: list[PredictionResult] = field(default_factory=list)
    free_res: list[PredictionResult] = field(default_factory=list)
    posts: dict[str, dict[str, Any] | None] = field(default_factory=dict)
    evals_cal: list[PlateEvaluation] = field(default_factory=list)
    rows_cal: list[dict[str, Any]] = field(default_factory=list)
    rows_free: list[dict[str, Any]] = field(default_factory=list)
    rows_ctrl: list[dict[str, Any]] = field(default_factory=list)
    published: list[dict[str, Any]] = field(default_factory=list)

    @staticmethod
    def generate(spec: _CaseSpec, quick: bool) -> _Case:
        """The case study's synthetic data (results still empty)."""
        pub = published_parameters(spec.parameter_table)
        if quick:
            pub = [p for p in pub if p["id"] in spec.quick_ids]
        return spec.generate(spec, pub, quick)

    def group_of(self, profile_id: str) -> _Group:
        return next(g for g in self.groups if any(p.id == profile_id for p in g.profiles))

    def cal_of(self, profile_id: str) -> Calibration:
        return self.cals[self.group_of(profile_id).id]


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------


def _ci_profile(site: str, p: dict[str, Any], rng: np.random.Generator, case: str) -> CIProfile:
    params = {k: p[k] for k in ("kc", "kphi", "n", "cc", "phic_deg")}
    ci = cone_index(CI_DEPTHS, **params, model=GENERATING_MODEL)
    ci = ci * (1.0 + CI_NOISE * rng.standard_normal(CI_DEPTHS.size))
    meta = {"case": case, "data": LABEL}
    return CIProfile(site, CI_DEPTHS.copy(), np.round(ci, 2), metadata=meta)


def _plate_test(pair: str, key: str, r: float, sinkage, pressure) -> PlateTest:
    id_, meta = f"{pair}_{key.replace('=', '')}", {"pair": pair, "plate": key, "data": LABEL}
    return PlateTest(id_, r, "circular", sinkage.copy(), np.round(pressure, 2), metadata=meta)


def _lete_data(spec: _CaseSpec, pub: list[dict[str, Any]], quick: bool) -> _Case:
    """CI from Table 4-1, plate pairs from Wong's values; one learning on everything."""
    rng = np.random.default_rng(spec.seed)
    profiles = [_ci_profile(p["id"], p, rng, spec.name) for p in pub]
    pairs = ["LS_A", "LS_B", "LS_C", "LS_D", "LS_E"][: 3 if quick else 5]
    plates, where = [], {}
    for pair in pairs:
        f = math.exp(LETE_PAIR_SPREAD * rng.standard_normal())
        for key, r in spec.plates.items():
            p = plate_pressure(SINKAGES, radius=r, **WONG_LETE)
            p = p * f * (1.0 + PLATE_NOISE * rng.standard_normal(SINKAGES.size))
            plates.append(_plate_test(pair, key, r, SINKAGES, p))
            where[plates[-1].id] = (pair, key)
    return _Case(spec, pub, profiles, plates, where, [_Group(spec.name, profiles, plates)])


def _krc_data(spec: _CaseSpec, pub: list[dict[str, Any]], quick: bool) -> _Case:
    """Per site, CI and a plate pair (ending at 1,500 lbf) from its Table 4-3 row."""
    rng = np.random.default_rng(spec.seed)
    profiles, plates, where, groups = [], [], {}, []
    for p in pub:
        prof = _ci_profile(p["id"], p, rng, spec.name)
        site_plates = []
        for key, r in spec.plates.items():
            clean = plate_pressure(SINKAGES, kc=p["kc"], kphi=p["kphi"], n=p["n"], radius=r)
            limit = KRC_FORCE_LIMIT / (math.pi * r * r) / 1000.0  # [kPa]
            noisy = clean * (1.0 + PLATE_NOISE * rng.standard_normal(SINKAGES.size))
            keep = clean <= limit
            if keep.sum() < 3:  # a very stiff site: keep the first points
                keep[:3] = True
            site_plates.append(_plate_test(p["id"], key, r, SINKAGES[keep], noisy[keep]))
            where[site_plates[-1].id] = (p["id"], key)
        profiles.append(prof)
        plates += site_plates
        groups.append(_Group(p["id"], [prof], site_plates))
    return _Case(spec, pub, profiles, plates, where, groups)


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _si(params: TerrainParameters, id_: str) -> dict[str, Any]:
    return {"id": id_, **params.as_dict("si")}


def _rows(evals: Sequence[PlateEvaluation], where) -> list[dict[str, Any]]:
    """Agreement rows: prediction, plate pair (or site) and plate of the test, R .. n_points."""
    keys = ("R", "R2", "RMSD", "CV", "n_points")
    out = []
    for e in evals:
        pair, plate = where[e.test]
        row = {"prediction": e.prediction, "pair": pair, "plate": plate}
        out.append(row | {k: getattr(e.agreement, k) for k in keys})
    return out


def _predict_doc(
    results: Sequence[PredictionResult],
    *,
    input_file: str,
    radii: Sequence[float],
    cal_of: dict[str, Calibration] | None = None,
    calibration: str | None = None,
    model: str = "rm0",
) -> dict[str, Any]:
    """Prediction document of ``results``, plate curves (0 to 10 cm) attached.

    ``cal_of``: profile id -> its calibration (its plate pair makes the RM1 secant).
    """
    s = np.linspace(0.0, 0.1, 41)
    for r in results:
        c = (cal_of or {}).get(r.id)
        if r.ok and not r.plate_curves:
            r.plate_curves = plate_curves(r.params, radii, s, c.plate_pair if c else None)
    settings = {"model": model, "solver": "exact", "bounds": Bounds(), "calibration": calibration}
    doc_settings = settings_dict(settings, "si")
    return to_document(
        results, "si", input=input_file, settings=doc_settings, samples=False, **_SYNTH
    )


def _learn_doc(res: LearnResult, terrain: str) -> dict[str, Any]:
    d = res.as_dict("si") | {"terrain": terrain, "terracone": __version__, "command": "learn"}
    return d | _SYNTH


def _evaluate_doc(case: _Case) -> dict[str, Any]:
    """evaluate JSON: LETE as ``terracone evaluate`` writes it, KRC as rows per site."""
    if case.spec.per_site:
        plates = [{**r, "test": f"{r['pair']} {r['plate']}", "units": "si"} for r in case.rows_cal]
    else:
        plates = [e.as_dict("si") for e in case.evals_cal]
    return {"command": "evaluate", **_SYNTH, "units": "si", "plates": plates}


def _section(id_: str, heading: str, parts: list[dict[str, Any]]) -> dict[str, Any]:
    return {"id": id_, "heading": heading, "parts": parts}


def _text(s: str) -> dict[str, Any]:
    return {"type": "text", "text": s}


def _list(items: Sequence[str]) -> dict[str, Any]:
    return {"type": "list", "items": list(items)}


# ---------------------------------------------------------------------------
# the pool: anything with a ``map`` (emcee's pattern)
# ---------------------------------------------------------------------------


def _call(task: Callable[[], Any]) -> Any:
    """Run one task, a ``partial`` (in a worker of the pool, or here)."""
    return task()


def _render(fig: Callable[[], Any], directory: Path, key: str) -> dict[str, Path]:
    """Draw one figure and write its PNG and SVG (runs in a worker)."""
    return F.save_figure(fig(), directory, key)


class _Out:
    """Collects the files, figures and tables of a run; figures render later, in the pool."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.files: list[Path] = []
        self.tables: dict[str, Path] = {}
        self.figures: dict[str, dict[str, Path]] = {}
        self.pending: list[partial] = []

    def rel(self, p: Path) -> str:
        return p.relative_to(self.root).as_posix()

    def file(self, p: Path) -> Path:
        self.files.append(p)
        return p

    def json(self, p: Path, obj: Any) -> None:
        self.file(p).write_text(dumps(obj, indent=1) + "\n")

    def table(self, t: Table, max_rows: int | None = None) -> dict[str, Any]:
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
        list(mapper(_call, self.pending))
        self.pending = []


# ---------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------


def reproduce(
    out_dir: str | Path,
    *,
    quick: bool = False,
    workers: int | None = None,
    pool: Any | None = None,
) -> ReproduceSummary:
    """Re-create the paper's LETE sand and KRC case studies on synthetic data.

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
        Runs the learning runs, the predictions and the figures, as in emcee
        (an executor, a ``multiprocessing`` pool, or ``map``); results in
        order; the caller owns it.  Overrides ``workers``.

    Returns
    -------
    ReproduceSummary
    """
    t0 = time.perf_counter()
    root = _prepare_output(Path(out_dir))
    if pool is not None:
        mapper = pool.map if hasattr(pool, "map") else pool  # or the builtin map itself
        return _run(root, quick=quick, mapper=mapper, t0=t0, workers="given pool")
    workers = workers if workers is not None else min(2, os.cpu_count() or 1)
    if workers <= 1:
        return _run(root, quick=quick, mapper=map, t0=t0, workers=workers)
    with ProcessPoolExecutor(max_workers=workers) as executor:
        return _run(root, quick=quick, mapper=executor.map, t0=t0, workers=workers)


def _prepare_output(root: Path) -> Path:
    """Create ``root`` and empty sub-folders; refuse a folder an earlier run did not write."""
    root.mkdir(parents=True, exist_ok=True)
    subs = ("figures", "tables", "data", "results")
    ours = (root / "reproduce.json").exists()
    for sub in subs:
        d = root / sub
        if d.exists() and not ours and (not d.is_dir() or any(d.iterdir())):
            raise ValueError(
                f"{d} exists and {root} holds no reproduce.json: it was not written by "
                "terracone reproduce; give a new or empty folder"
            )
    for sub in subs:
        if (root / sub).is_dir():
            shutil.rmtree(root / sub)  # an earlier run's output (reproduce.json is there)
        (root / sub).mkdir()
    return root


def _run(
    root: Path, *, quick: bool, mapper: Callable[..., Any], t0: float, workers: int | str
) -> ReproduceSummary:
    out = _Out(root)
    notes: list[str] = []
    grid = (13, 7, 6) if quick else (33, 16, 13)
    draws = 400 if quick else 1000
    cases = [_Case.generate(spec, quick) for spec in _CASES]
    ci_files = [_write_inputs(out, case) for case in cases]

    t_comp = time.perf_counter()
    _learn_all(cases, mapper, grid)
    _predict_all(cases, mapper, draws, notes)
    for case in cases:
        _evaluate(case)
    t_comp = time.perf_counter() - t_comp
    for case, ci_file in zip(cases, ci_files):
        _write_results(out, case, ci_file)

    t_fig = time.perf_counter()
    sections = _document_sections(out, cases, quick=quick, notes=notes)
    out.render(mapper)
    t_fig = time.perf_counter() - t_fig
    seconds = time.perf_counter() - t0
    run = {
        "mode": "quick" if quick else "full",
        "worker processes": workers,
        "learning, prediction, posterior [s]": round(t_comp, 2),
        "figures and tables [s]": round(t_fig, 2),
        "total until the report [s]": round(seconds, 2),
        "learning grid (n, phic, r_min)": list(grid),
        "posterior draws per profile": draws,
        "terracone": __version__,
    }
    sections[1]["parts"] += [_text("Run:"), {"type": "kv", "pairs": run}]
    report = _write_report(out, sections, quick=quick, seconds=seconds)
    lete, krc = cases
    return ReproduceSummary(
        out_dir=root,
        report=report,
        quick=quick,
        seconds=time.perf_counter() - t0,
        files=out.files,
        lete_learned=_si(lete.learned[lete.spec.name].params, "LETE"),
        krc_learned={k: _si(v.params, k) for k, v in krc.learned.items()},
        tables=out.tables,
        figures=out.figures,
        notes=notes,
    )


def _write_inputs(out: _Out, case: _Case) -> Path:
    """Write the case's synthetic CI profiles and plate tests; return the CI file."""
    header = [
        f"{LABEL} DATA generated by terracone.apps.reproduce; not measurements.",
        f"From the published parameters of {CITATION}.",
    ]
    data = (write_ci_profiles, case.profiles), (write_plate_tests, case.plates)
    files = [out.file(out.root / "data" / name) for name in case.spec.files]
    for (write, items), path, comment in zip(data, files, case.spec.comments):
        write(path, items, comment=[*header, comment])
    return files[0]


def _learn_all(cases: Sequence[_Case], mapper: Callable[..., Any], grid: tuple) -> None:
    """The learning process (section 3.3.1), one run per group of every case, in the pool."""
    groups = [(case, g) for case in cases for g in case.groups]
    tasks = [partial(learn, g.profiles, g.plates, model="rm1", grid=grid) for _, g in groups]
    for (case, g), lr in zip(groups, mapper(_call, tasks)):
        case.learned[g.id] = lr
        case.cals[g.id] = lr.calibration(f"{g.id} ({LABEL})", data=LABEL)


def _predict_all(
    cases: Sequence[_Case], mapper: Callable[..., Any], draws: int, notes: list[str]
) -> None:
    """Every profile predicted with and without its calibration, then posteriors in the pool.

    Posteriors (prior: the calibration) through :func:`attach_fits`, a seed per profile.
    """
    tasks = []
    for case in cases:
        rf = predict_many(case.profiles)
        radii = list(case.spec.plates.values())
        rc: dict[str, Any] = {}
        for g in case.groups:
            # the group's calibration as the prior: the fit at its values, the posterior around
            pb = Problem(prior=case.cals[g.id])
            mine = [p for p in case.profiles if case.group_of(p.id) is g]
            rc.update((p.id, (r, pb)) for p, r in zip(mine, predict_many(mine, pb)))
        case.free_res += rf
        for i, p in enumerate(case.profiles):
            r, pb = rc[p.id]
            s = RunSettings(uncertainty=True, draws=draws, seed=case.spec.seed + i)
            tasks.append(partial(attach_fits, PredictionResults([r]), [p], pb, s, plates=radii))
    attached = iter(mapper(_call, tasks))
    for case in cases:
        for p in case.profiles:
            (r,) = next(attached)  # written with the calibrated prediction
            case.cal_res.append(r)
            case.posts[p.id] = None if r.posterior is None else r.posterior.as_dict("si")
            if r.posterior is None:
                notes.append(f"{p.id}: posterior not computed ({r.lack_of_fit})")


def _evaluate(case: _Case) -> None:
    """Each group's predictions against its plates: calibrated, CI alone, published (control)."""
    pub = {p["id"]: TerrainParameters(p["kc"], p["kphi"], p["n"]) for p in case.pub}
    for g in case.groups:
        ids = {p.id for p in g.profiles}
        cal = [(r.id, r.params) for r in case.cal_res if r.id in ids and r.ok]
        free = [(r.id, r.params) for r in case.free_res if r.id in ids and r.ok]
        control = [(p.id, pub[p.id]) for p in g.profiles]
        evals = cross_table(cal, g.plates, case.cals[g.id].plate_pair)
        case.evals_cal += evals
        case.rows_cal += _rows(evals, case.where)
        case.rows_free += _rows(cross_table(free, g.plates), case.where)
        case.rows_ctrl += _rows(cross_table(control, g.plates), case.where)
    case.published = published_agreement(case.spec.agreement_table)


def _write_results(out: _Out, case: _Case, ci_file: Path) -> None:
    """results/: calibrations, and the learn, predict and evaluate JSON of one case."""
    spec, res = case.spec, out.root / "results"
    for gid, cal in case.cals.items():
        name = f"_{gid}" if spec.per_site else ""
        cal.save(out.file(res / f"{spec.slug}_calibration{name}.json"))
    docs = {gid: _learn_doc(lr, f"{gid} ({LABEL})") for gid, lr in case.learned.items()}
    if spec.per_site:
        learn_doc = {**_SYNTH, "sites": docs}
        calibration = "per site (learned on each site's CI and plates)"
    else:
        (learn_doc,) = docs.values()
        (calibration,) = (c.terrain for c in case.cals.values())
    out.json(res / f"{spec.slug}_learn.json", learn_doc)
    common = {"input_file": out.rel(ci_file), "radii": list(spec.plates.values())}
    cal_of = {p.id: case.cal_of(p.id) for p in case.profiles}
    model = next(iter(case.cals.values())).model
    predicted = _predict_doc(
        case.cal_res, cal_of=cal_of, calibration=calibration, model=model, **common
    )
    out.json(res / f"{spec.slug}_predict.json", predicted)
    out.json(res / f"{spec.slug}_predict_ci_only.json", _predict_doc(case.free_res, **common))
    out.json(res / f"{spec.slug}_evaluate.json", _evaluate_doc(case))


def _write_report(out: _Out, sections: list[dict[str, Any]], *, quick: bool, seconds: float):
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
        **_SYNTH,
        "quick": quick,
        "seconds": seconds,
        "noise_model": NOISE_MODEL,
        "document": document,
    }
    out.json(out.root / "reproduce.json", manifest)
    return report


# ---------------------------------------------------------------------------
# the report: sections of the whole run
# ---------------------------------------------------------------------------


def _document_sections(
    out: _Out, cases: Sequence[_Case], *, quick: bool, notes: list[str]
) -> list[dict[str, Any]]:
    """The report's sections: about, data, each case study's spec, then both side by side."""
    sections = [_about_section(), _data_section(cases)]
    for case in cases:
        for sec in case.spec.sections:
            if sec.full_only and quick:  # one ridge figure (LETE) is enough for a quick run
                continue
            parts = [p for name in sec.parts.split() for p in _PARTS[name](out, case, name)]
            sections.append(_section(sec.id, sec.heading, parts))
    sections.append(_side_by_side_section(out, cases, quick))
    sections.append(_published_section(out))
    if notes:
        sections.append(_section("notes", "Notes from the run", [_list(notes)]))
    return sections


def _about_section() -> dict[str, Any]:
    about = (
        "The paper demonstrates its method on two sets of measurements, LETE sand "
        "(1981) and KRC soils (2018). Only the parameters fitted to them (Tables "
        "4-1 and 4-3) and the agreement statistics (Tables 4-2 and 4-4) were "
        "published; the measured CI and plate curves were not. This report "
        "re-creates both case studies on SYNTHETIC data generated from the "
        "published parameters, runs them through terracone's learning, prediction "
        "and evaluation processes, and sets the results beside the published "
        "tables."
    )
    points = [
        "LETE sand: 4 CI profiles (LS_1..LS_4) from Table 4-1; 5 plate pairs "
        "(LS_A..LS_E, radii 3.75 and 5 cm) from Wong's LETE sand values "
        "(kc 102 kN/m^(n+1), kphi 5301 kN/m^(n+2), n 0.79).",
        "KRC: 8 sites, each a CI profile and a 4 in / 6 in plate pair, both "
        "from the site's Table 4-3 parameters (the KRC plate measurements "
        "were never published).",
        "CI generated with the improved model RM0: the paper does not publish "
        "r_min, and RM0 needs no invented value. Learning then searches RM1 "
        "and its r_min, as in the paper.",
        "Tables 4-1 to 4-4 analogues use the predictions made with the learned "
        "calibration (the paper's learning-then-prediction process); the "
        "predictions from the CI alone are shown beside them.",
        "The paper's 10 cm and 15 cm KRC plates are 4 in and 6 in (10.16 and "
        "15.24 cm): its recommendation G gives 1,500 lb as 119 and 53 psi, "
        "which holds for 4 in and 6 in diameters.",
    ]
    return _section("about", "What this is", [_text(about), _list(points)])


def _data_section(cases: Sequence[_Case]) -> dict[str, Any]:
    files = [f"data/{name}" for case in cases for name in case.spec.files]
    inputs = (
        "Input files (terracone CSV, with the SYNTHETIC label in their header): "
        + ", ".join(files)
        + ". Results as JSON in results/ (learn, predict, evaluate, calibrations); "
        "any of them can be turned into its own report with terracone report."
    )
    return _section("data", "Synthetic data and noise model", [_list(NOISE_MODEL), _text(inputs)])


def _side_by_side_section(out: _Out, cases: Sequence[_Case], quick: bool) -> dict[str, Any]:
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
    parts = [out.table(t_sum)] + [_text(x) for x in _reading(*cases, quick)]
    return _section("side-by-side", "Ours beside the paper: where and why they differ", parts)


def _published_section(out: _Out) -> dict[str, Any]:
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
    parts = [_text(check)] + [out.table(t) for t in tables]
    return _section("published", "The published tables", parts)


# ---------------------------------------------------------------------------
# the report: parts of a case study (one builder per table or figure kind)
# ---------------------------------------------------------------------------


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


def _parameters_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """Table 4-1/4-3 analogue: parameters predicted with the calibration."""
    ok = [r for r in case.cal_res if r.ok]
    t = parameters_table(
        [{**_si(r.params, r.id), "rmsd": r.rmsd, "r2": r.r2_ci} for r in ok],
        extra=(
            ("RMSD of CI", "kPa", lambda r: r["rmsd"]),
            ("R2 of CI", "", lambda r: r["r2"]),
        ),
        synthetic=True,
        **case.spec.texts[name],
    )
    mark_bounds(t, [_si(r.params, r.id) for r in ok])
    return [out.table(t)]


def _parameters_vs_published_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """Published parameters beside ours, with the calibration and from the CI alone."""
    sets = [
        (case.spec.published_label, [dict(p) for p in case.pub]),
        ("ours, with calibration", [_si(r.params, r.id) for r in case.cal_res if r.ok]),
        ("ours, CI alone", [_si(r.params, r.id) for r in case.free_res if r.ok]),
    ]
    tab = case.spec.parameter_table
    title = f"{case.spec.name} parameters: published (Table {tab}) beside ours"
    text = {"key": _vs_published_key(case, tab), "title": title} | case.spec.texts.get(name, {})
    return [out.table(parameter_comparison_table(sets, synthetic=True, **text))]


def _identifiability_part(
    out: _Out, case: _Case, name: str, *, calibrated: bool
) -> list[dict[str, Any]]:
    """What each CI profile determines, with the calibration (posterior) or alone."""
    if calibrated:
        profiles, fixed = _ident_profiles(case.cal_res, case.posts), {"fixed": ("phic", "cc")}
    else:
        profiles, fixed = _ident_profiles(case.free_res, None), {}
    t = identifiability_table(profiles, synthetic=True, **fixed, **case.spec.texts[name])
    return [out.table(t)]


def _agreement_part(out: _Out, case: _Case, name: str, *, rows: str) -> list[dict[str, Any]]:
    """Table 4-2/4-4 analogue of the rows ``rows_cal``, ``rows_free`` or ``rows_ctrl``."""
    t = agreement_table(
        getattr(case, rows), plates=list(case.spec.plates), synthetic=True, **case.spec.texts[name]
    )
    return [out.table(t)]


def _agreement_vs_published_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
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


def _vs_published_key(case: _Case, tab: str) -> str:
    """Key of the table of ours beside the paper's Table ``tab`` ("4-1" .. "4-4")."""
    return f"table_{tab.replace('-', '_')}_{case.spec.slug}_vs_published"


def _ridge_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """Not in the paper: the ridge of equally good fits of the first profile."""
    f = case.spec.texts[name]
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


def _lete_learning_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """LETE: the one calibration learned on all data, beside Wong's values."""
    (lr,) = case.learned.values()
    text = dict(case.spec.texts[name])
    wong = {"id": "Wong's LETE sand values (plates' truth)", **WONG_LETE}
    rows = [_si(lr.params, "learned (LETE, all data)"), wong | {"cc": None, "phic_deg": None}]
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


def _learning_datasets_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """LETE: the fit of the learned parameters to each CI profile and plate test."""
    (lr,) = case.learned.values()
    rows = [
        [d["id"], d["kind"], None if d.get("b") is None else d["b"] * 100, d["rmsd"], d["cv"]]
        for d in lr.datasets
    ]
    c, text = lr.criteria, case.spec.texts[name]
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


def _site_learning_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """KRC: the calibration learned on each site's CI and plate pair."""
    rows = [_si(case.learned[p["id"]].params, p["id"]) for p in case.pub]
    t = parameters_table(
        rows,
        extra=(
            ("r_min", "mm", _rmin_mm),
            ("left free", "", lambda r: ", ".join(case.learned[r["id"]].undetermined) or "-"),
        ),
        synthetic=True,
        **case.spec.texts[name],
    )
    mark_bounds(t, rows, rmin_col=9, rmin_range=(5e-4, 3 * max(case.spec.plates.values())))
    return [out.table(t)]


def _janosi_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """Figure 2-1 analogue: the CI against the Janosi equation with Wong's values."""
    f = case.spec.texts[name]
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


def _ci_fit_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """Figure 4-1 analogue: measured and predicted CI."""
    f = case.spec.texts[name]
    fitted = [
        {"id": r.id, "depth": r.depth, "ci": r.ci, "ci_model": r.ci_model}
        for r in case.cal_res
        if r.ok
    ]
    fig = partial(F.fig_ci_fit, fitted, title=f["title"], synthetic=True)
    return [out.figure(fig, f["key"], f["caption"])]


def _plates_part(out: _Out, case: _Case, name: str, *, calibrated: bool) -> list[dict[str, Any]]:
    """Figure 4-2 analogue: every plate test against every profile's prediction."""
    f = case.spec.texts[name]
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


def _site_figures_part(out: _Out, case: _Case, name: str) -> list[dict[str, Any]]:
    """Figures 4-3 to 4-10 analogues: each site's CI and plates, measured and predicted."""
    f = case.spec.texts[name]
    parts = []
    for rc in case.cal_res:
        if not rc.ok:
            parts.append(_text(f"{rc.id}: not fitted ({rc.error})"))
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
#: spec lists part names per section; the builder takes its text from
#: ``spec.texts[name]``.
_PARTS: dict[str, Callable[[_Out, _Case, str], list[dict[str, Any]]]] = {
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


#: LETE sand: the report's sections, each a list of parts (keys of ``_PARTS``).
_LETE_SECTIONS = (
    _Section(
        "lete-learning",
        "LETE sand: learning and Figure 2-1",
        "learning learning_datasets fig_janosi",
    ),
    _Section(
        "lete-prediction",
        "LETE sand: prediction (Table 4-1, Figure 4-1)",
        "parameters parameters_vs_published fig_ci identifiability identifiability_ci_only",
    ),
    _Section(
        "lete-plates",
        "LETE sand: plates (Figure 4-2, Table 4-2)",
        "fig_plates agreement agreement_vs_published agreement_control fig_plates_ci_only "
        "agreement_ci_only",
    ),
    _Section("lete-ridge", "LETE sand: the ridge of equally good fits", "fig_ridge"),
)

#: LETE sand: the text of each part: a table's keyword arguments (key, title, notes, ...).
_LETE_TEXTS: dict[str, dict[str, Any]] = {
    "learning": {
        "key": "lete_learning",
        "title": "LETE sand: learning process (section 3.3.1) on all CI profiles and plate tests",
        "first": "Parameters",
        "notes": [
            "The CI profiles were generated from the Table 4-1 parameters and the plates "
            "from Wong's values: the learning fits both, as the paper's learning fitted "
            "measured CI and plate curves of one terrain.",
        ],
    },
    "learning_datasets": {
        "key": "lete_learning_datasets",
        "title": "LETE sand: fit of the learned parameters per data set",
    },
    "parameters": {
        "key": "table_4_1_lete_parameters",
        "title": "Table 4-1 analogue: parameters predicted from the LETE sand CI (with the "
        "learned calibration)",
        "notes": [
            "Prediction process (section 3.3.2) with the LETE calibration: model RM1, "
            "r_min, phic, cc and kc/kphi fixed by learning; n and the scale of kc, kphi "
            "from each CI.",
        ],
    },
    "parameters_vs_published": {
        "notes": [
            "The published rows are the truth of the synthetic CI; 'CI alone' reports phic "
            "at the middle of the interval that fits equally well.",
            "Published US columns as recomputed by terracone.physics.units from the SI values.",
        ],
    },
    "identifiability": {
        "key": "lete_identifiability",
        "title": "LETE sand: what each CI profile determines (with the calibration)",
        "notes": [
            "From the posterior of terracone.uncertainty (90% width over prior width: "
            "< 0.25 determined, < 0.75 weakly determined, else set by prior) where "
            "computed; otherwise from the profile intervals of the exact solver.",
        ],
    },
    "identifiability_ci_only": {
        "key": "lete_identifiability_ci_only",
        "title": "LETE sand: what each CI profile determines on its own (no calibration)",
    },
    "agreement": {
        "key": "table_4_2_lete_agreement",
        "title": "Table 4-2 analogue: R, R2, RMSD, CV between the LETE sand plate curves "
        "and those predicted from the CI (with the calibration)",
        "notes": ["r=3.75cm: plate radius 3.75 cm (1.5 in); r=5cm: radius 5 cm (1.97 in)."],
    },
    "agreement_control": {
        "key": "table_4_2_lete_published_parameters",
        "title": "Control: the published Table 4-1 parameters against our synthetic plate tests",
        "notes": [
            "No inversion involved: the paper's own parameters evaluated against plates "
            "generated from Wong's values. The nearest analogue of the paper's Table 4-2."
        ],
    },
    "agreement_ci_only": {
        "key": "table_4_2_lete_ci_only",
        "title": "LETE sand, CI alone (no calibration): R, R2, RMSD, CV against the plate tests",
    },
    # figures: key, title and caption
    "fig_janosi": {
        "key": "fig_2_1_lete_janosi",
        "title": "Figure 2-1 analogue: LETE sand CI and the Janosi equation",
        "params_label": "Wong's kc 102, kphi 5301, n 0.79",
        "improved_label": "improved model eq. (2-7), same kc, kphi, n; learned phic, cc, r_min",
        "caption": "Figure 2-1 analogue. SYNTHETIC LETE sand CI profiles (dashed) against "
        "the Janosi equation (2-1) with Wong's plate-derived kc, kphi, n (solid), and the "
        "improved model with the same kc, kphi, n and the learned phic, cc, r_min "
        "(dotted). As in the paper, the Janosi equation falls far below the measured CI.",
    },
    "fig_ci": {
        "key": "fig_4_1_lete_ci",
        "title": "Figure 4-1 analogue: LETE sand CI, measured and predicted",
        "caption": "Figure 4-1 analogue. SYNTHETIC LETE sand CI-sinkage curves (dashed, "
        "open markers) and those predicted with the learned calibration (solid).",
    },
    "fig_plates": {
        "key": "fig_4_2_lete_plates",
        "title": "Figure 4-2 analogue: LETE sand plates, measured and predicted",
        "caption": "Figure 4-2 analogue. (a) 3.75 cm and (b) 5 cm radius plates: SYNTHETIC "
        "measured curves {pairs} (dashed) and curves predicted from {profiles} with the "
        "calibration (solid){bands}",
        "band_note": "; hatched: 90% posterior band of LS_1 (terracone.uncertainty).",
    },
    "fig_plates_ci_only": {
        "key": "fig_4_2_lete_plates_ci_only",
        "title": "LETE sand plates predicted from the CI alone (no calibration)",
        "caption": "The same plates against the curves predicted from each CI profile "
        "alone: without the calibration the CI does not fix how the load splits between "
        "kc and kphi, and the predicted plate pressure drifts.",
    },
    "fig_ridge": {
        "key": "ridge_lete_{id}",
        "caption": "Not in the paper. RMSD of the best fit to the SYNTHETIC {id} CI over "
        "(phic, n) with kc, kphi, cc re-fitted at each point (a), over phic and a common "
        "scale of kc and kphi (b), and its profiles over n (c) and phic (d). The CI fixes "
        "n; it does not fix phic, which trades exactly against the scale of kc and kphi: "
        "the published phic is one point of a flat valley.",
    },
}

#: KRC: the report's sections, each a list of parts (keys of ``_PARTS``).
_KRC_SECTIONS = (
    _Section(
        "krc-prediction",
        "KRC: learning and prediction (Table 4-3)",
        "learning_per_site parameters parameters_vs_published identifiability "
        "identifiability_ci_only",
    ),
    _Section("krc-figures", "KRC: Figures 4-3 to 4-10", "fig_sites"),
    _Section(
        "krc-agreement", "KRC: Table 4-4", "agreement agreement_vs_published agreement_ci_only"
    ),
    _Section("krc-ridge", "KRC: the ridge of equally good fits", "fig_ridge", full_only=True),
)

#: KRC: the text of each part: a table's keyword arguments (key, title, notes, ...).
_KRC_TEXTS: dict[str, dict[str, Any]] = {
    "learning_per_site": {
        "key": "krc_learning",
        "title": "KRC: learning process per site (CI and the site's plate pair)",
    },
    "parameters": {
        "key": "table_4_3_krc_parameters",
        "title": "Table 4-3 analogue: parameters predicted from the KRC CI (with each "
        "site's calibration)",
    },
    "identifiability": {
        "key": "krc_identifiability",
        "title": "KRC: what each CI profile determines (with the site's calibration)",
    },
    "identifiability_ci_only": {
        "key": "krc_identifiability_ci_only",
        "title": "KRC: what each CI profile determines on its own",
    },
    "agreement": {
        "key": "table_4_4_krc_agreement",
        "title": "Table 4-4 analogue: R, R2, RMSD, CV between the KRC plate curves and "
        "those predicted from the CI (with each site's calibration)",
        "same_site": True,
        "notes": ["D=10cm: the 4 in (10.16 cm) plate; D=15cm: the 6 in (15.24 cm) plate."],
    },
    "agreement_ci_only": {
        "key": "table_4_4_krc_ci_only",
        "title": "KRC, CI alone (no calibration): R, R2, RMSD, CV against the site's plates",
        "same_site": True,
    },
    # figures: key, title and caption
    "fig_sites": {
        "numbers": KRC_FIGURE,
        "key": "fig_{number}_{lower}",
        "title": "Figure {number} analogue: {id} measured and predicted",
        "caption": "Figure {number} analogue. {id}: (a) SYNTHETIC CI (dashed) and "
        "predicted CI (solid); (b) SYNTHETIC plate curves of the 4 in and 6 in plates "
        "(dashed, ending at 1,500 lbf) and those predicted with the site's calibration "
        "(solid){bands}",
        "band_note": "; hatched: 90% posterior band.",
    },
    "fig_ridge": {
        "key": "ridge_krc_{lower}",
        "caption": "As the LETE ridge figure, for the SYNTHETIC {id} CI profile.",
    },
}

#: The two case studies side by side: one row per field of ``_CaseSpec``,
#: one column per case study (LETE sand, KRC), in the order of the report.
_CASE_TABLE: dict[str, tuple[Any, Any]] = {
    "slug": ("lete", "krc"),
    "name": ("LETE sand", "KRC"),
    "seed": (SEED_LETE, SEED_KRC),
    "parameter_table": ("4-1", "4-3"),
    "agreement_table": ("4-2", "4-4"),
    "quick_ids": (("LS_1", "LS_2"), ("KRC_1", "KRC_3")),
    "plates": (LETE_PLATES, KRC_PLATES),
    "per_site": (False, True),
    "generate": (_lete_data, _krc_data),
    "files": (
        ("lete_sand_synthetic_ci.csv", "lete_sand_synthetic_plates.csv"),
        ("krc_synthetic_ci.csv", "krc_synthetic_plates.csv"),
    ),
    "comments": (
        (
            "CI from Table 4-1 parameters, improved model RM0. " + NOISE_MODEL[0],
            "Plates from Wong's LETE sand values. " + NOISE_MODEL[2],
        ),
        (
            "CI from Table 4-3 parameters, improved model RM0. " + NOISE_MODEL[0],
            "Plates from the same Table 4-3 parameters. " + NOISE_MODEL[3],
        ),
    ),
    "published_label": (
        "paper (Table 4-1; generated the CI)",
        "paper (Table 4-3; generated CI and plates)",
    ),
    "sections": (_LETE_SECTIONS, _KRC_SECTIONS),
    "texts": (_LETE_TEXTS, _KRC_TEXTS),
}
_CASES = tuple(_CaseSpec(**{name: row[i] for name, row in _CASE_TABLE.items()}) for i in range(2))


# ---------------------------------------------------------------------------
# small helpers of the report
# ---------------------------------------------------------------------------


def _span(ids: Sequence[str]) -> str:
    ids = list(ids)
    return ids[0] if len(ids) == 1 else f"{ids[0]} to {ids[-1]}"


def _fmt(v: float, d: int = 3) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{d}g}"


def _median(rows, key):
    v = [r[key] for r in rows if r[key] is not None]
    return float(np.median(v)) if v else float("nan")


def _corr(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.size < 3 or np.std(a) == 0 or np.std(b) == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def _paired(ours, published, key):
    """Values of ``key`` in ours and in the paper's table, of the rows both have."""
    pub = {(r["prediction"], r["pair"], r["plate"]): r[key] for r in published}
    ids = [(r["prediction"], r["pair"], r["plate"]) for r in ours]
    return [r[key] for r, k in zip(ours, ids) if k in pub], [pub[k] for k in ids if k in pub]


def _reading(lete: _Case, krc: _Case, quick: bool) -> list[str]:
    """Plain-language reading of ours against the paper, with the numbers of this run."""
    out = []
    lc, lf, lk, lp = lete.rows_cal, lete.rows_free, lete.rows_ctrl, lete.published
    kc_, kf, kk, kpub = krc.rows_cal, krc.rows_free, krc.rows_ctrl, krc.published
    a, b = _paired(lk, lp, "CV")

    def med(rows: list[dict[str, Any]], key: str = "CV") -> str:
        return _fmt(_median(rows, key))

    def top(rows: list[dict[str, Any]], key: str = "CV") -> str:
        return _fmt(max((r[key] for r in rows), default=float("nan")))

    out.append(
        f"LETE sand, R and R2. Ours (with calibration) have median R2 {med(lc, 'R2')}, the paper "
        f"{med(lp, 'R2')} (range {_fmt(min(r['R2'] for r in lp))} to {top(lp, 'R2')}). Our "
        "'measured' plate curves are exact Bekker curves with 2% white noise, so any Bekker-shaped "
        "prediction correlates almost perfectly with them; R measures shape, and the real LETE "
        "plate curves departed from the Bekker shape in ways nobody can re-create without the "
        "measurements. R2 is therefore higher in ours by construction, not because the method does "
        "better."
    )
    out.append(
        "LETE sand, RMSD and CV. These measure the level of the predicted curves against the "
        f"plates. Ours: median CV {med(lc, 'CV')} (RMSD {med(lc, 'RMSD')} kPa); paper: median CV "
        f"{med(lp, 'CV')} (RMSD {med(lp, 'RMSD')} kPa). The control row (the paper's own Table 4-1 "
        f"parameters against our synthetic plates, no inversion) has median CV {med(lk, 'CV')}; "
        f"its CVs correlate with the paper's row by row at r = {_fmt(_corr(a, b), 2)}. The "
        "mismatch the paper reports is mostly the gap between the parameters the CI implies (Table "
        "4-1) and those the plates imply (Wong's values), which our synthetic setup carries over "
        "by construction; where ours and the paper differ in level, the cause is the plates: "
        "Wong's Bekker fit to them stands in for the unpublished curves, and our pair-to-pair "
        "spread (10%) is assumed."
    )
    out.append(
        f"LETE sand, CI alone. Without the learned calibration the median CV is {med(lf, 'CV')} "
        f"(up to {top(lf)}): the cone barely separates kc from kphi (their columns in eq. (2-7) "
        "are nearly collinear) and phic trades exactly against their common scale, so a CI profile "
        "alone does not fix the plate pressure. The paper's Table 4-1 phic values (10 to 12.5 deg) "
        "are one point each on a flat valley (ridge figure); the learning with plates is what pins "
        "them."
    )
    out.append(
        "KRC. Our plates were generated from the same Table 4-3 parameters as the CI (the KRC "
        "plate measurements were never published), so our Table 4-4 analogue tests only whether "
        f"the inversion recovers its own truth: median R2 {med(kc_, 'R2')}, median CV "
        f"{med(kc_, 'CV')}, near the 2% plate noise (the published parameters themselves reach "
        f"median CV {med(kk, 'CV')} against these plates). The paper's Table 4-4 (median R2 "
        f"{med(kpub, 'R2')}, CV {med(kpub, 'CV')}, up to {top(kpub)} for KRC_9 with the 15 cm "
        "plate) measures real disagreement between cone and plates: layered soil (KRC_9 is "
        "two-layered), plate curves that are not Bekker-shaped, the 6 in plate stopped at 53 psi. "
        "None of that exists in synthetic data from one parameter set, so the KRC comparison is a "
        "self-consistency check, not a reproduction of the paper's agreement."
    )
    out.append(
        f"KRC, CI alone: median CV {med(kf, 'CV')}, up to {top(kf)}. Even with plates and CI from "
        "one parameter set, the CI alone leaves the kc-kphi split and phic free; the site's plate "
        "pair (through the calibration) fixes them. The paper predicted each KRC site from its CI "
        "with r_min from learning; how it fixed phic on the ridge is not stated."
    )
    out.append(
        "What the data leave undetermined (identifiability tables): from a CI profile alone, phic "
        "and the common scale of kc and kphi (exactly), and usually kphi or cc; with the "
        "calibration, kc, kphi and n are determined and phic and cc are set by the calibration. In "
        "learning, r_min and cc are often left free: a few CI profiles and two plate sizes do not "
        "separate them."
    )
    if quick:
        out.append(
            "Quick run: only a subset of profiles, plates and sites; numbers are indicative."
        )
    return out

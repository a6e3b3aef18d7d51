"""Learning, prediction, posteriors and evaluation of the case studies.

The learning process (section 3.3.1 of [1]_) per group, the prediction process
(section 3.3.2) of every profile with its calibration and from the CI alone, the
posteriors (prior: the calibration), and the agreement with the plate tests, each
written into the :class:`~terracone.apps.reproduce.cases.Case` it belongs to.  The
learning runs and the posteriors go through a pool's ``map``.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3, Tables 4-2 and 4-4.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

from terracone.apps.reproduce.cases import LABEL, Case
from terracone.apps.reproduce.paper import published_agreement
from terracone.apps.reproduce.pool import run_task
from terracone.apps.workflow import attach_fits
from terracone.data import TerrainParameters
from terracone.inverse.evaluate import PlateEvaluation, cross_table
from terracone.inverse.learning.learn import learn
from terracone.inverse.predict import RunSettings, predict_many
from terracone.inverse.problem import Problem
from terracone.result import PredictionResults

__all__ = ["fit_cases", "evaluate"]


def fit_cases(
    cases: Sequence[Case], mapper: Callable[..., Any], grid: tuple, draws: int
) -> list[str]:
    """Learn, predict and sample the posteriors of every case; return the notes of the run.

    The learning process (section 3.3.1), one run per group of every case, in the pool.
    Then every profile predicted with and without its calibration, and posteriors in the
    pool (prior: the calibration) through :func:`attach_fits`, a seed per profile.
    """
    notes: list[str] = []
    groups = [(case, g) for case in cases for g in case.groups]
    tasks = [partial(learn, g.profiles, g.plates, model="rm1", grid=grid) for _, g in groups]
    for (case, g), lr in zip(groups, mapper(run_task, tasks)):
        case.learned[g.id] = lr
        case.cals[g.id] = lr.calibration(f"{g.id} ({LABEL})", data=LABEL)

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
    attached = iter(mapper(run_task, tasks))
    for case in cases:
        for p in case.profiles:
            (r,) = next(attached)  # written with the calibrated prediction
            case.cal_res.append(r)
            case.posts[p.id] = None if r.posterior is None else r.posterior.as_dict("si")
            if r.posterior is None:
                notes.append(f"{p.id}: posterior not computed ({r.lack_of_fit})")
    return notes


def evaluate(case: Case) -> None:
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


def _rows(evals: Sequence[PlateEvaluation], where) -> list[dict[str, Any]]:
    """Agreement rows: prediction, plate pair (or site) and plate of the test, R .. n_points."""
    keys = ("R", "R2", "RMSD", "CV", "n_points")
    out = []
    for e in evals:
        pair, plate = where[e.test]
        row = {"prediction": e.prediction, "pair": pair, "plate": plate}
        out.append(row | {k: getattr(e.agreement, k) for k in keys})
    return out

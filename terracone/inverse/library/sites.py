"""Sites under a library prior: each candidate's site pooling, weighed by the site's evidence.

A site's candidates are weighed by the evidence of its pushes under the site
pooling's site terrain (:func:`rank_groups`,
:func:`~terracone.inverse.library.evidence.pooled_noise`: one kphi and n,
each push scaled by its strength factor) and checked on it (:mod:`.check`).  The
site is pooled under each candidate's held problem (the calibrated site
statistics of :mod:`terracone.inverse.sites.statistics`), and the answer is
their mixture: each candidate's site median and 90% interval of plate
pressure, kc and kphi read as a log-normal (n as a normal) of those quantiles,
mixed with the weights (:func:`~terracone.inverse.library.mixture.component_mixture`);
cc and phic, held by each candidate, mix as point masses.  A site outside the
library gets the uncalibrated pooling.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2), (2-6), (2-7); section 5.2, recommendation E.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from terracone.data import CIProfile
from terracone.inverse.library.evidence import ProfileNoise, pooled_noise, profile_noise
from terracone.inverse.library.mixture import (
    Ranking,
    component_mixture,
    rank_candidates,
    rng_for,
    soil_of,
)
from terracone.inverse.predict import RunSettings, predict_many
from terracone.inverse.problem import Problem
from terracone.result import LibrarySummary

__all__ = ["library_sites", "push_noises", "rank_groups"]


def push_noises(profiles: Sequence[CIProfile], problem: Problem) -> list[ProfileNoise | str]:
    """Each profile's noise model from its uncalibrated fit (or why it has none)."""
    base = problem.without_library()
    fits = predict_many(profiles, base, RunSettings(detail="summary"))
    out: list[ProfileNoise | str] = []
    for p, r in zip(profiles, fits):
        if not r.ok:
            out.append(str(r.error))
            continue
        try:
            out.append(profile_noise(p, r.params, base))
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
            out.append(str(exc))
    return out


def _common_soil(profiles: Sequence[CIProfile]) -> str | None:
    """The soil class every profile of a group names (metadata), else None."""
    soils = {soil_of(p.metadata) for p in profiles}
    return soils.pop() if len(soils) == 1 else None


def rank_groups(
    profiles: Sequence[CIProfile],
    groups: dict[str, list[int]],
    problem: Problem,
    *,
    seed: int | None = 0,
    check_all: bool = False,
    noises: Sequence[ProfileNoise | str] | None = None,
) -> dict[str, Ranking | str]:
    """The ranking of each group of profiles (a site, or one profile): weights and check.

    Parameters
    ----------
    profiles : sequence of CIProfile
    groups : dict of str to list of int
        Group name -> indices of its profiles.
    problem : Problem
        With a ``library``.
    seed : int, optional
        Seed of the check (each group's generator from it and the group's name).
    check_all : bool
        Check every candidate (``terracone match``), not only until one passes.
    noises : sequence, optional
        :func:`push_noises` of ``profiles`` (computed when None).

    Returns
    -------
    dict
        Group name -> its :class:`Ranking`, or why it has none (no fitted
        profile, no calibration of its cone).
    """
    lib = problem.library
    noises = push_noises(profiles, problem) if noises is None else noises
    out: dict[str, Ranking | str] = {}
    for name, members in groups.items():
        ok = [i for i in members if isinstance(noises[i], ProfileNoise)]
        if not ok:
            out[name] = "no profile of this group could be fitted"
            continue
        cone = profiles[ok[0]].cone.name
        cands = problem.candidates(cone, _common_soil([profiles[i] for i in ok]))
        if not cands:
            where = f"library {lib.source}" if lib.source else "the library"
            out[name] = f"{where} holds no calibration learned with the {cone} cone"
            continue
        out[name] = rank_candidates(
            [pooled_noise([noises[i] for i in ok])], [c for c, _, _ in cands],
            [pb for _, pb, _ in cands],
            [w for _, _, w in cands], level=lib.check_level, replicates=lib.replicates,
            rng=rng_for(seed, name), check_all=check_all,
        )  # fmt: skip
    return out


def _discrete(values: np.ndarray, w: np.ndarray, level: float) -> tuple[float, float, float]:
    """Median and ``level`` interval of point masses ``values`` with weights ``w``."""
    o = np.argsort(values, kind="stable")
    v, c = values[o], np.cumsum(w[o]) / np.sum(w)
    q = [0.5, (1 - level) / 2, (1 + level) / 2]
    return tuple(float(v[min(np.searchsorted(c, x - 1e-12), v.size - 1)]) for x in q)


def _mixed(results: list[Any], w: np.ndarray, level: float) -> dict[str, Any]:
    """Params, intervals and plate pressures of the mixture of candidates' site results."""
    params, intervals = {}, {}
    for name in ("kc", "kphi", "n"):
        med = np.array([[r.params[name]] for r in results])
        lo = np.array([[r.intervals[name][0]] for r in results])
        hi = np.array([[r.intervals[name][1]] for r in results])
        log = name != "n" and bool(np.all(lo > 0))
        m, a, b = component_mixture(med, lo, hi, w, log, level)
        params[name], intervals[name] = float(m[0]), (float(a[0]), float(b[0]))
    for name in ("cc", "phic_deg"):
        m, a, b = _discrete(np.array([r.params[name] for r in results]), w, level)
        params[name], intervals[name] = m, (a, b)
    plates = []
    for ir, top_plate in enumerate(results[0].plate_pressure):
        med, lo, hi = (np.array([getattr(r.plate_pressure[ir], k) for r in results])
                       for k in ("median", "lo", "hi"))  # fmt: skip
        m, a, b = component_mixture(med, lo, hi, w, True, level)
        plates.append(replace(top_plate, median=m, lo=a, hi=b))
    return {"params": params, "intervals": intervals, "plate_pressure": plates}


def _site_answer(
    ranking: Ranking, per_cand: dict[str, Any], free: Any, problem: Problem, level: float
) -> Any:
    """One site's result: the candidates' mixture, or (outside) the uncalibrated pooling."""
    lib = problem.library
    words = ranking.words()
    summary = ranking.summary(lib.source, [words])
    if ranking.outside:
        return replace(free, library=summary, calibrated=False, notes=[words] + free.notes)
    order = [i for i in ranking.order if ranking.weights[i] > 0]
    names = [ranking.calibrations[i].terrain for i in order]
    results = [per_cand[n] for n in names]
    top = results[0]
    if not top.profiles:
        return replace(top, library=summary, calibrated="library")
    mixed = _mixed(results, ranking.weights[order], level)
    note = (
        f"{words}; the site's kc, kphi, n, cc, phic and plate pressure mix {len(names)} "
        f"calibrations by weight; the push-to-push variation, pushes needed and pushes are "
        f"those under {names[0]!r}"
    )
    held = f"calibration {names[0]!r}:"  # the held note of the heaviest's pooling: not the answer's
    rest = [n for n in top.notes if not n.startswith(held)]
    return replace(top, **mixed, library=summary, calibrated="library", notes=[note] + rest)


def library_sites(
    profiles: Sequence[CIProfile],
    grouping: Any,
    problem: Problem,
    fit: Callable[..., list[Any]],
    **kw: Any,
) -> list[Any]:
    """Pool every site under a library problem (:func:`terracone.inverse.sites.statistics.fit_sites`).

    ``fit`` is :func:`~terracone.inverse.sites.statistics.fit_sites` (passed
    in: this module sits below it); ``kw`` its keywords (plates, sinkage,
    target_cv, level, bootstrap, seed).  Each site is ranked
    (:func:`rank_groups`), pooled under each of its candidates' held problems
    and mixed; a site outside the library, or of a cone without
    calibrations, gets the pooling without the library, saying why.
    """
    level = kw.get("level", 0.9)
    rankings = rank_groups(profiles, grouping.sites, problem, seed=kw.get("seed", 0))
    need: dict[str, list[str]] = {}  # calibration name -> sites pooled under it
    fallback = []
    for name, rk in rankings.items():
        if isinstance(rk, str) or rk.outside:
            fallback.append(name)
            continue
        for i in rk.order:
            if rk.weights[i] > 0:
                need.setdefault(rk.calibrations[i].terrain, []).append(name)
    cals = {c.terrain: c for c in problem.library.calibrations}
    pooled: dict[str, dict[str, Any]] = {}
    for cname, sites in need.items():
        sub = replace(grouping, sites={s: grouping.sites[s] for s in sites}, unassigned=[])
        held = fit(profiles, sub, problem.held_problem(cals[cname]), **kw)
        for s, r in zip(sites, held):
            pooled.setdefault(s, {})[cname] = r
    free: dict[str, Any] = {}
    if fallback:
        sub = replace(grouping, sites={s: grouping.sites[s] for s in fallback}, unassigned=[])
        free = dict(zip(fallback, fit(profiles, sub, problem.without_library(), **kw)))
    out = []
    for name in grouping.sites:
        rk = rankings[name]
        if isinstance(rk, str):
            r, why = free[name], f"library: {rk}; the uncalibrated pooling"
            summary = LibrarySummary(weights={}, outside=True, source=problem.library.source,
                                     check_level=problem.library.check_level, notes=[why])  # fmt: skip
            out.append(replace(r, calibrated=False, library=summary, notes=[why] + r.notes))
        else:
            out.append(_site_answer(rk, pooled.get(name, {}), free.get(name), problem, level))
    return out

"""Candidates ranked by their evidence, and the mixture a library prior answers with.

A profile's (or a site's) candidates are weighed by ``prior weight x
evidence`` (:mod:`.evidence`; a site's pushes under its site terrain,
:func:`~terracone.inverse.library.evidence.pooled_noise`) and checked
(:mod:`.check`): :func:`rank_candidates` gives a :class:`Ranking`.
The answer of a profile is the mixture of the candidates' posteriors:
:func:`mixture_draws` draws from each candidate in proportion to its weight,
and the medians and 90% intervals of kc, kphi, n and plate pressure are
those of the draws (:func:`mixture_bands`).  :func:`library_fit_set` is what
:func:`terracone.inverse.predict.predict_many` does with a library problem.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2), (2-6), (2-7); section 3.2 (RM0, RM1).
.. [2] Hoeting, J.A., Madigan, D., Raftery, A.E., Volinsky, C.T. (1999).
   Bayesian model averaging: a tutorial. Statistical Science 14(4), 382-417.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import special

from terracone.data import CIProfile, ProfileSet, TerrainParameters
from terracone.inverse.library.check import CHECK_METHOD, check_p_value
from terracone.inverse.library.evidence import (
    EVIDENCE_METHOD,
    Candidate,
    HeldPosterior,
    ProfileNoise,
    held_posterior,
    n_nodes,
    profile_noise,
)
from terracone.inverse.problem import Calibration, Problem
from terracone.physics.plate import PressureLaw, plate_basis, pressure_law
from terracone.result import UQ_PARAMS, LibrarySummary, PosteriorSummary, PredictionResult

__all__ = [
    "BAND_PLATES",
    "component_mixture",
    "BAND_SINKAGES",
    "CARRIES",
    "MixturePosterior",
    "Ranking",
    "library_fit_set",
    "mixture_bands",
    "mixture_draws",
    "rank_candidates",
    "result_bands",
    "rng_for",
    "soil_of",
]

#: Plate radii [m] and sinkages [m] of the default mixture bands: the LETE plate pair of
#: [1]_ (3.75 cm and 5 cm radius), 0 to 10 cm every 5 mm (as the posterior's bands).
BAND_PLATES = (0.0375, 0.05)
BAND_SINKAGES = tuple(np.round(np.linspace(0.0, 0.10, 21), 6))
#: A candidate whose weight is at least this carries the answer.
CARRIES = 0.5


def soil_of(metadata: dict[str, Any] | None) -> str | None:
    """A profile's soil class from its metadata: ``uscs``, else ``soil_class`` (any case)."""
    low = {str(k).lower(): v for k, v in (metadata or {}).items()}
    for key in ("uscs", "soil_class"):
        v = low.get(key)
        if isinstance(v, str) and v.strip():
            return v.strip()
    return None


def rng_for(seed: int | None, key: str) -> np.random.Generator:
    """The generator of one profile or site: from the run's seed and its id (any chunking)."""
    return np.random.default_rng([0 if seed is None else int(seed), zlib.crc32(key.encode())])


@dataclass
class Ranking:
    """The candidates of one profile or site, weighed and checked (library order).

    Attributes
    ----------
    calibrations : list of Calibration
    candidates : list of Candidate
    prior : ndarray
        Prior weights [-] (soil class).
    log_evidence : ndarray
        log p(y | candidate) of the profile, or the sum over a site's pushes.
    weights : ndarray
        Posterior weights [-], summing to 1.
    p_values, discrepancy : ndarray
        The posterior predictive check of each candidate (:mod:`.check`).
    level : float
    posts : list of list of HeldPosterior
        Per candidate, the posterior of each push.
    """

    calibrations: list[Calibration]
    candidates: list[Candidate]
    prior: np.ndarray
    log_evidence: np.ndarray
    weights: np.ndarray
    p_values: np.ndarray
    discrepancy: np.ndarray
    level: float
    posts: list[list[HeldPosterior]] = field(repr=False, default_factory=list)

    @property
    def outside(self) -> bool:
        """True when no candidate passes the check (every p-value below the level)."""
        checked = self.p_values[np.isfinite(self.p_values)]
        return bool(checked.size == len(self.p_values) and np.all(checked < self.level))

    @property
    def order(self) -> list[int]:
        """Candidates by weight, largest first (library order among equals)."""
        return sorted(range(len(self.weights)), key=lambda i: (-self.weights[i], i))

    @property
    def carried_by(self) -> str | None:
        """The candidate carrying the answer (weight >= 0.5), None if none or outside."""
        top = self.order[0]
        if self.outside or self.weights[top] < CARRIES:
            return None
        return self.calibrations[top].terrain

    def rows(self) -> list[dict[str, Any]]:
        """Per candidate, largest weight first: name, weights, evidence, check, held values."""
        out = []
        for i in self.order:
            c = self.calibrations[i]
            out.append(
                {
                    "terrain": c.terrain,
                    "weight": float(self.weights[i]),
                    "prior_weight": float(self.prior[i]),
                    "log_evidence": float(self.log_evidence[i]),
                    "check_p": None if np.isnan(self.p_values[i]) else float(self.p_values[i]),
                    "model": c.model,
                    "r_min": c.r_min,
                    "plate_pair": None if c.plate_pair is None else list(c.plate_pair),
                    "phic_deg": float(c.phic_deg),
                    "cc": float(c.cc),
                    "kc_over_kphi": float(c.kc / c.kphi),
                }
            )
        return out

    def summary(self, source: str | None, notes: Sequence[str] = ()) -> LibrarySummary:
        """The :class:`~terracone.result.LibrarySummary` of this ranking."""
        rows = self.rows()
        return LibrarySummary(
            weights={r["terrain"]: r["weight"] for r in rows},
            outside=self.outside,
            candidates=rows,
            carried_by=self.carried_by,
            source=source,
            check_level=self.level,
            evidence=EVIDENCE_METHOD,
            check=CHECK_METHOD,
            notes=list(notes),
        )

    def words(self) -> str:
        """What the ranking says, in one sentence (results' notes, the CLI's text)."""
        rows = self.rows()
        best_p = max(r["check_p"] for r in rows if r["check_p"] is not None)
        if self.outside:
            return (
                f"outside the library: no calibration explains the CI (largest check p-value "
                f"{best_p:.3g} < {self.level:g}); the uncalibrated answer"
            )
        if self.carried_by is not None:
            return f"library: carried by {self.carried_by!r} (weight {rows[0]['weight']:.2f})"
        top = ", ".join(f"{r['terrain']!r} {r['weight']:.2f}" for r in rows[:3])
        return f"library: no single calibration carries the answer ({top}): the mixture"


def _law_key(law: PressureLaw) -> tuple:
    return (law.model, None if law.r_min is None else float(law.r_min), law.plate_pair)


def rank_candidates(
    noises: Sequence[ProfileNoise],
    calibrations: Sequence[Calibration],
    problems: Sequence[Problem],
    prior: Sequence[float],
    *,
    level: float,
    replicates: int,
    rng: np.random.Generator,
    check_all: bool = False,
) -> Ranking:
    """Weigh and check the candidates of one profile (one noise) or a site's pushes.

    Parameters
    ----------
    noises : sequence of ProfileNoise
        The profile's noise model, or one per push of a site.
    calibrations, problems : sequence
        The candidates and their held problems (:meth:`Problem.candidates`).
    prior : sequence of float
        Prior weights [-].
    level : float
        Level of the check [-].
    replicates : int
        Replicates of the check per candidate.
    rng : numpy.random.Generator
    check_all : bool
        Check every candidate.  By default they are checked heaviest first
        until one passes (then the profile is in the library, and the lighter
        candidates' p-values stay NaN: not needed).

    Returns
    -------
    Ranking
    """
    cands = [Candidate.of(c.terrain, pb) for c, pb in zip(calibrations, problems)]
    K = len(cands)
    log_ev, p_val, disc = np.zeros(K), np.zeros(K), np.zeros(K)
    cache: dict[tuple, list[Any]] = {}
    posts: list[list[HeldPosterior]] = []
    for k, cand in enumerate(cands):
        key = (_law_key(cand.law), cand.bounds.n)
        if key not in cache and cand.bounds.n[1] > cand.bounds.n[0]:
            nodes = n_nodes(cand.bounds)
            cache[key] = [nz.raw_columns(cand.law, nodes) for nz in noises]
        cols = cache.get(key, [None] * len(noises))
        ps = [held_posterior(nz, cand, c) for nz, c in zip(noises, cols)]
        posts.append(ps)
        log_ev[k] = sum(p.log_evidence for p in ps)
    lp = np.log(np.asarray(prior, float)) + log_ev
    lp = np.where(np.isfinite(lp), lp, -np.inf)
    w = np.exp(lp - special.logsumexp(lp)) if np.isfinite(lp).any() else np.full(K, 1.0 / K)
    w = w / w.sum()
    p_val, disc = np.full(K, np.nan), np.full(K, np.nan)
    for k in sorted(range(K), key=lambda i: (-w[i], i)):  # heaviest first, until one passes
        p_val[k], disc[k] = check_p_value(noises, posts[k], rng, replicates)
        if p_val[k] >= level and not check_all:
            break
    return Ranking(list(calibrations), cands, np.asarray(prior, float), log_ev, w, p_val, disc,
                   level, posts)  # fmt: skip


def _allocate(weights: np.ndarray, total: int) -> np.ndarray:
    """Draws per candidate in proportion to its weight (largest remainders), summing to total."""
    raw = weights * total
    counts = np.floor(raw).astype(int)
    rest = total - counts.sum()
    counts[np.argsort(-(raw - counts), kind="stable")[:rest]] += 1
    return counts


def mixture_draws(
    ranking: Ranking, draws: int, rng: np.random.Generator, push: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Equal-weight draws of the mixture: (kc, kphi, n, cc, phic) (S, 5) SI, and their candidate.

    Each candidate gives draws in proportion to its weight, from its
    posterior of (kphi, n) (:meth:`HeldPosterior.draw`) with its kc/kphi,
    cc and phic held.
    """
    rows, which = [], []
    for k, m in enumerate(_allocate(ranking.weights, draws)):
        if m == 0:
            continue
        post, cand = ranking.posts[k][push], ranking.candidates[k]
        _, idx, kphi = post.draw(rng, int(m))
        n = post.n[idx]
        cols = [cand.ratio * kphi, kphi, n, np.full(m, cand.cc), np.full(m, cand.phic_deg)]
        rows.append(np.column_stack(cols))
        which.append(np.full(m, k))
    return np.concatenate(rows), np.concatenate(which)


def mixture_bands(
    samples: np.ndarray,
    which: np.ndarray,
    laws: Sequence[PressureLaw],
    radii: Sequence[float],
    sinkage: Sequence[float],
    level: float = 0.9,
) -> list[dict[str, Any]]:
    """Median and ``level`` band of plate pressure over mixture draws, each with its law.

    Bekker's eq. (2-2), or RM1 below r_min (section 3.2 of [1]_), of each
    draw's candidate.  Returns ``{"radius", "sinkage", "median", "lo", "hi"}``
    per radius (SI).
    """
    sink = np.asarray(sinkage, float)
    qs = [(1 - level) / 2, 0.5, (1 + level) / 2]
    out = []
    for r in radii:
        p = np.empty((samples.shape[0], sink.size))
        for k in np.unique(which):
            sel = which == k
            A, B = plate_basis(sink[None, :], n=samples[sel, 2:3], b=float(r), law=laws[k])
            p[sel] = samples[sel, 0:1] * A + samples[sel, 1:2] * B  # eq. (2-2)
        lo, med, hi = np.quantile(p, qs, axis=0)
        out.append({"radius": float(r), "sinkage": sink.copy(), "median": med, "lo": lo, "hi": hi})
    return out


def result_bands(
    result: PredictionResult, radii: Sequence[float], sinkage: Sequence[float]
) -> list[dict[str, Any]]:
    """The mixture bands of plate pressure of a library result at other plates and sinkages.

    From the result's mixture draws (``posterior.samples``), each with its
    candidate's pressure law (``library.draw_candidate``, ``library.candidates``).
    """
    lib, post = result.library, result.posterior
    if lib is None or post is None or post.samples is None or lib.draw_candidate is None:
        return []
    laws = [
        pressure_law(c["model"], r_min=c.get("r_min"), plate_pair=c.get("plate_pair"))
        for c in lib.candidates
    ]
    return mixture_bands(post.samples, lib.draw_candidate, laws, radii, sinkage, post.level)


@dataclass(kw_only=True)
class MixturePosterior(PosteriorSummary):
    """The mixture over a library's candidates, as a posterior (equal-weight draws, SI)."""

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """``intervals``, ``identifiability`` (empty), ``medians`` and ``posterior`` (level, prior)."""
        q = self.quantiles(units)
        return {
            "intervals": {k: [v[0], v[2]] for k, v in q.items()},
            "identifiability": dict(self.identifiability),
            "medians": {k: v[1] for k, v in q.items()},
            "posterior": {
                "level": self.level,
                "prior": self.prior,
                "notes": list(self.notes),
                "units": units,
            },
        }


def _summarised(
    samples: np.ndarray, prior: str, level: float, notes: list[str]
) -> MixturePosterior:
    qs = np.quantile(samples, [(1 - level) / 2, 0.5, (1 + level) / 2], axis=0)
    return MixturePosterior(
        intervals={k: (float(qs[0, j]), float(qs[2, j])) for j, k in enumerate(UQ_PARAMS)},
        medians={k: float(qs[1, j]) for j, k in enumerate(UQ_PARAMS)},
        samples=samples,
        prior=prior,
        level=level,
        notes=notes,
    )


def _answer(
    free: PredictionResult,
    held: PredictionResult | None,
    ranking: Ranking,
    problem: Problem,
    rng: np.random.Generator,
) -> PredictionResult:
    """The result of one profile: the mixture (or, outside the library, the free fit).

    ``held``: the profile's fit under the heaviest candidate (None outside).
    """
    lib = problem.library
    words = ranking.words()
    summary = ranking.summary(lib.source, [words])
    if ranking.outside or held is None:
        return replace(free, library=summary, notes=list(free.notes) + [words])
    samples, which = mixture_draws(ranking, lib.draws, rng)
    top = ranking.order[0]
    cal = ranking.calibrations[top]
    post = _summarised(samples, lib.describe(), 0.9, [words])
    med = post.medians
    params = TerrainParameters(
        med["kc"], med["kphi"], med["n"], cal.cc, cal.phic_deg, None, cal.model, cal.r_min
    )
    order = {k: j for j, k in enumerate(ranking.order)}
    summary.draw_candidate = np.array([order[k] for k in which])
    laws = [c.law for c in ranking.candidates]
    summary.plate_bands = mixture_bands(samples, which, laws, BAND_PLATES, BAND_SINKAGES)
    note = (
        f"{words}; kc, kphi and n are the medians of the mixture over "
        f"{len(ranking.candidates)} calibrations; cc, phic, model and r_min, the CI model and "
        f"rmsd are those of {cal.terrain!r}"
    )
    base = held if held.ok else free
    return replace(base, params=params, posterior=post, library=summary,
                   notes=list(free.notes) + [note])  # fmt: skip


def _no_candidate(res: PredictionResult, problem: Problem) -> PredictionResult:
    """The error result of a profile whose cone has no calibration in the library."""
    where = f"library {problem.library.source}" if problem.library.source else "the library"
    why = (
        f"{where} holds no calibration learned with the {res.cone} cone (calibrations: "
        f"{', '.join(sorted({c.cone for c in problem.library.calibrations}))})"
    )
    return replace(res, status="error", error=why, message=why, params=None)


def _rank_profile(
    problem: Problem, pset: ProfileSet, j: int, free: PredictionResult, cands: list, meta: dict,
    seed: int | None,
) -> Ranking | str:  # fmt: skip
    """The ranking of profile ``j`` of a set (or why it failed)."""
    lib, base = problem.library, problem.without_library()
    s, e = int(pset.offsets[j]), int(pset.offsets[j + 1])
    cone = pset.cones[int(pset.cone_idx[j])]
    prof = CIProfile(free.id, pset.depth[s:e], pset.ci[s:e], cone=cone)
    soil = soil_of(meta)
    prior = [lib.prior_weight(lib.calibrations.index(cal), soil) for cal, _, _ in cands]
    try:
        noise = profile_noise(prof, free.params, base)
        return rank_candidates(
            [noise], [c for c, _, _ in cands], [pb for _, pb, _ in cands], prior,
            level=lib.check_level, replicates=lib.replicates, rng=rng_for(seed, free.id),
        )  # fmt: skip
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return f"library: {exc}"


def library_fit_set(
    problem: Problem,
    settings: Any,
    pset: ProfileSet,
    fit: Callable[[Problem, Any, ProfileSet], list[PredictionResult]],
) -> list[PredictionResult]:
    """Fit a set under a library problem: the fall-back, the ranking, and the mixture.

    ``fit`` is :func:`terracone.inverse.predict.fit_set` (passed in: this
    module sits below it).  Every profile is fitted under the problem
    without the library (its noise model, and the answer outside the
    library), its candidates (those of its cone, :meth:`Problem.candidates`)
    are ranked (:func:`rank_candidates`), and it is fitted under its
    heaviest candidate's held problem (the CI model shown).  The result is
    the mixture or, outside the library, the uncalibrated fit with the
    ranking.  A profile of a cone without calibrations is an error result
    saying so.
    """
    free = fit(problem.without_library(), settings, pset)
    out = list(free)
    meta = [{}] * len(pset) if pset.metadata is None else pset.metadata.to_pylist()
    seed = getattr(settings, "seed", None)
    ranked: dict[int, tuple[Ranking, list]] = {}
    for j, r in enumerate(free):
        if not r.ok:
            continue
        cands = problem.candidates(pset.cones[int(pset.cone_idx[j])].name)
        got = _rank_profile(problem, pset, j, r, cands, meta[j], seed) if cands else None
        if got is None:
            out[j] = _no_candidate(r, problem)
        elif isinstance(got, str):
            out[j] = replace(r, status="error", error=got, message=got, params=None)
        else:
            ranked[j] = (got, cands)
    by_top: dict[str, list[int]] = {}
    for j, (rk, _) in ranked.items():
        if not rk.outside:
            by_top.setdefault(rk.calibrations[rk.order[0]].terrain, []).append(j)
    held: dict[int, PredictionResult] = {}
    for members in by_top.values():
        rk, cands = ranked[members[0]]
        pb = cands[rk.order[0]][1]
        held.update(zip(members, fit(pb, settings, pset.take(np.array(members)))))
    for j, (rk, _) in ranked.items():
        out[j] = _answer(free[j], held.get(j), rk, problem, rng_for(seed, free[j].id + "/draws"))
    return out


def component_mixture(
    median: np.ndarray, lo: np.ndarray, hi: np.ndarray, weights: np.ndarray, log: bool,
    level: float = 0.9,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Median and ``level`` interval of a mixture of normals (log-normals with ``log``).

    Component k of each column m has the median ``median[k, m]`` and the
    equal-tailed interval ``(lo, hi)[k, m]`` at ``level``; it is read as a
    normal (in log with ``log``) of those quantiles, so a component of weight
    1 gives back its own median and interval.  The mixture's quantiles are
    found by bisection of its CDF.
    """
    tr = np.log if log else (lambda v: np.asarray(v, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        mu, a, b = (
            tr(np.asarray(median, float)),
            tr(np.asarray(lo, float)),
            tr(np.asarray(hi, float)),
        )
    zq = special.ndtri(0.5 + level / 2)
    sd = np.maximum((b - a) / (2 * zq), 0.0)
    w = np.asarray(weights, float)[:, None]
    ok = np.isfinite(mu) & np.isfinite(sd)
    mu, sd = np.where(ok, mu, 0.0), np.where(ok, sd, 0.0)
    w = np.where(ok, w, 0.0)
    w = w / np.maximum(w.sum(axis=0, keepdims=True), 1e-300)
    span = 12 * np.max(sd, axis=0) + 1e-9 * (1 + np.max(np.abs(mu), axis=0))
    left, right = np.min(mu, axis=0) - span, np.max(mu, axis=0) + span

    def cdf(x):
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(sd > 0, (x[None, :] - mu) / np.where(sd > 0, sd, 1.0),
                         np.where(x[None, :] >= mu, np.inf, -np.inf))  # fmt: skip
        return np.sum(w * special.ndtr(z), axis=0)

    out = []
    for q in (0.5, (1 - level) / 2, (1 + level) / 2):
        lo_x, hi_x = left.copy(), right.copy()
        for _ in range(64):
            mid = 0.5 * (lo_x + hi_x)
            below = cdf(mid) < q
            lo_x, hi_x = np.where(below, mid, lo_x), np.where(below, hi_x, mid)
        x = 0.5 * (lo_x + hi_x)
        out.append(np.exp(x) if log else x)
    return out[0], out[1], out[2]

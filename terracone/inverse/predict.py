"""The prediction process (section 3.3.2 of [1]_): CI profile -> parameters.

Two solvers behind :func:`predict`:

* ``"exact"`` (default): global optimum from the linear structure of the
  model (:mod:`terracone.inverse.solver.exact`);
* ``"pso"``: the paper's particle swarm (:mod:`terracone.inverse.solver.pso`) on the
  same objective and bounds.

The objective is the RMSD between measured CI and model CI at the measured
depths.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3.2.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from terracone.data import CIProfile, InputError, ProfileSet, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.library.mixture import library_fit_set
from terracone.inverse.problem import Problem
from terracone.inverse.solver.columns import design
from terracone.inverse.solver.exact import solve_exact
from terracone.inverse.solver.intervals import identification, linear_intervals, n_intervals
from terracone.inverse.solver.many import ManySolution, bounds_params, solve_exact_many
from terracone.inverse.solver.polish import polish_many
from terracone.inverse.solver.pso import pso
from terracone.physics import units as u
from terracone.physics.cone import Cone, cone_index_huang
from terracone.physics.metrics import check_fit_fast
from terracone.physics.plate import PressureLaw
from terracone.result import PredictionResult, PredictionResults

__all__ = [
    "RunSettings",
    "SetFit",
    "predict",
    "predict_many",
    "fit_set",
    "solve_set",
    "rmsd_objective",
    "vectorised",
]

_EXACT_MESSAGE = "global optimum of the bounded linear least squares over the n, phic grid"

#: Points of the global grid over n of the exact solver (solve_exact's default).
N_GRID = 97


def rmsd_objective(
    profile: CIProfile,
    law: PressureLaw,
    bounds: Bounds,
    K_cone: float | None = None,
    ratio: float | None = None,
):
    """RMSD [kPa] of positions (P, 5) = (kc, kphi, n, cc, phic) in the bounds' units.

    With ``bounds`` in US units the kc and kphi coordinates are in
    lb/in^(n+1) and lb/in^(n+2); cc is in kPa and phic in degrees.  With
    ``ratio`` [m] kc = ratio kphi (the kc coordinate is not read) and a kc
    outside its bounds gives inf.
    """
    z, y = profile.depth, profile.ci

    def f(x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(x)
        n = x[:, 2:3]
        kphi = u.kphi_to_si(x[:, 1:2], n, bounds.kphi_units)
        if ratio is None:
            kc = u.kc_to_si(x[:, 0:1], n, bounds.kc_units)
            outside = np.zeros(len(x), bool)
        else:
            kc = ratio * kphi
            lo, hi = bounds.kc_si(n)
            outside = ((kc < lo) | (kc > hi))[:, 0]
        K = x[:, 5:6] if x.shape[1] > 5 else K_cone
        ci = cone_index_huang(
            z,
            kc=kc,
            kphi=kphi,
            n=n,
            cc=x[:, 3:4],
            phic_deg=x[:, 4:5],
            K_cone=K,
            law=law,
            cone=profile.cone,
        )
        r = ci - y
        return np.where(outside, np.inf, np.sqrt(np.mean(r * r, axis=-1)))

    return f


# ---------------------------------------------------------------------------
# how a run is made: one object from the command line (or Python) to the workers
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSettings:
    """How a prediction runs and what it attaches (what it fits is a :class:`Problem`).

    ``solver``: "exact" (default) or "pso" (the paper's swarm; ``seed`` and
    ``pso_options``); ``n_grid``: points of the exact solver's grid over n;
    ``detail``: "full" (profile scans of kc, kphi, cc) or "summary";
    ``solve_many``: a replacement of :func:`solve_exact_many` (tests).
    ``uncertainty``, ``draws`` and ``layers`` ask for what
    :func:`terracone.apps.workflow.attach_fits` adds (posterior, layered
    fit); ``seed`` also seeds the posterior samplers.
    """

    solver: str = "exact"
    seed: int | None = None
    pso_options: dict[str, Any] | None = None
    n_grid: int = N_GRID
    detail: str = "full"
    solve_many: Callable[..., ManySolution] | None = None
    uncertainty: bool = False
    draws: int = 2000
    layers: int = 1

    def __post_init__(self) -> None:
        if self.solver not in ("exact", "pso"):
            raise ValueError(f"solver must be 'exact' or 'pso' (got {self.solver!r})")
        if self.detail not in ("full", "summary"):
            raise ValueError(f"detail must be 'full' or 'summary' (got {self.detail!r})")
        if int(self.layers) < 1:
            raise ValueError(f"layers must be >= 1 (got {self.layers})")
        if self.uncertainty and int(self.draws) < 10:
            raise ValueError(f"draws must be >= 10 (got {self.draws})")


def vectorised(problem: Problem, settings: RunSettings) -> bool:
    """True when the fits go through :func:`solve_exact_many` (exact, fully mobilised)."""
    return settings.solver == "exact" and problem.vectorised


# ---------------------------------------------------------------------------
# the one path: predict_many (predict is predict_many of one profile)
# ---------------------------------------------------------------------------


def predict(
    profile: CIProfile, problem: Problem | None = None, settings: RunSettings | None = None
) -> PredictionResult:
    """Fit the improved cone model to one CI profile (prediction process, section 3.3.2).

    ``predict_many([profile], problem, settings)[0]``: one profile through
    the one solving path.
    """
    return predict_many([profile], problem, settings)[0]


def predict_many(
    profiles: ProfileSet | Iterable[CIProfile | InputError],
    problem: Problem | None = None,
    settings: RunSettings | None = None,
    *,
    pool: Any = None,
    chunk_size: int = 1000,
) -> PredictionResults:
    """Fit the improved cone model to a set of CI profiles through one vectorised path.

    Every profile is validated (a bad one becomes an error result naming
    its file, profile, row and column; reader errors likewise), the valid
    ones are grouped by cone and each group's optima are found by one
    :func:`terracone.inverse.solver.many.solve_exact_many` call, re-solved on
    the design matrix itself (:func:`polish_many`), and given their
    statistics.  The particle swarm and the fits with finite Kc run profile
    by profile inside the same function.

    Parameters
    ----------
    profiles : ProfileSet or iterable of CIProfile and InputError
        The set to fit.  A ProfileSet's ``errors`` come after its profiles.
    problem : Problem, optional
        What to fit: pressure law, bounds, the values a calibration holds
        (default: ``Problem()``, RM0 over the default bounds).
    settings : RunSettings, optional
        How to run: solver, n grid, detail.
    pool : object with ``map``, optional
        Maps the fit over chunks of ``chunk_size`` profiles (emcee's pattern):
        a ``multiprocessing`` pool, a ``concurrent.futures`` executor, a Dask
        client adapter; None: the builtin ``map``.  The results do not
        depend on the pool.
    chunk_size : int
        Profiles per chunk.

    Returns
    -------
    PredictionResults
        One result per input item, in input order.

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.
       Predicting terrain parameters for physics-based vehicle mobility
       models from cone index data. Section 3.3.2.
    """
    problem, settings = problem or Problem(), settings or RunSettings()
    pset, order, errors, originals = _gather(profiles)
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be >= 1 (got {chunk_size})")
    starts = range(0, len(pset), chunk_size)
    if len(pset) <= chunk_size:
        chunks = [pset]
    else:
        chunks = [pset.take(np.arange(a, min(a + chunk_size, len(pset)))) for a in starts]
    mapper = map if pool is None else pool.map
    fit = functools.partial(fit_set, problem, settings)
    fitted = [r for part in mapper(fit, chunks) for r in part]
    out = PredictionResults([None] * (len(fitted) + len(errors)))
    for pos, res, orig in zip(order, fitted, originals):
        if orig is not None:
            res.metadata = dict(orig.metadata)
        out[pos] = res
    for pos, res in errors:
        out[pos] = res
    return out


def _gather(profiles) -> tuple[ProfileSet, list[int], list[tuple[int, PredictionResult]], list]:
    """The input as (set, output position of each set profile, error results, originals).

    Reader errors become error results; so do CI profiles that fail
    :meth:`CIProfile.validate` (worded as it words them).  A ProfileSet's
    profiles are validated later, by :func:`screen`.
    """
    if isinstance(profiles, ProfileSet):
        P = len(profiles)
        errs = [(P + k, _reader_error(e)) for k, e in enumerate(profiles.errors)]
        return profiles, list(range(P)), errs, [None] * P
    order, errs, profs = [], [], []
    for pos, it in enumerate(profiles):
        if isinstance(it, InputError):
            errs.append((pos, _reader_error(it)))
            continue
        try:
            it.validate()
        except InputError as exc:
            errs.append((pos, _profile_error(it, str(exc))))
            continue
        order.append(pos)
        profs.append(it)
    # metadata stays with the originals (any Python values): the set carries only the soil
    # class a library prior reads (text)
    pset = ProfileSet.from_profiles(replace(p, metadata=_soil_keys(p.metadata)) for p in profs)
    return pset, order, errs, profs


def _soil_keys(meta: dict) -> dict:
    """The soil-class keys of a profile's metadata (``uscs``, ``soil_class``) that are text."""
    return {
        k: v
        for k, v in meta.items()
        if str(k).lower() in ("uscs", "soil_class") and isinstance(v, str)
    }


def _reader_error(err: InputError) -> PredictionResult:
    return PredictionResult(id=str(err.profile), status="error", error=str(err), source=err.file)


def _profile_error(profile: CIProfile, reason: str) -> PredictionResult:
    return PredictionResult(
        id=profile.id,
        status="error",
        error=reason,
        cone=profile.cone.name,
        metadata=dict(profile.metadata),
        notes=list(profile.notes),
        source=profile.source,
    )


def fit_set(problem: Problem, settings: RunSettings, pset: ProfileSet) -> list[PredictionResult]:
    """Validate and fit every profile of a set (one chunk of :func:`predict_many`).

    Returns one result per profile, in order.  Module-level so that process
    pools can pickle it.  With a library problem (``problem.library``) the
    result of each profile is the mixture over the library's candidates
    (:func:`terracone.inverse.library.mixture.library_fit_set`).
    """
    if problem.library is not None:
        return library_fit_set(problem, settings, pset, fit_set)
    out: list[PredictionResult | None] = [None] * len(pset)
    meta = [{}] * len(pset) if pset.metadata is None else pset.metadata.to_pylist()
    for j, exc in pset.screen().items():
        out[j] = _error_result(pset, j, exc, meta[j])
    good = np.array([j for j in range(len(pset)) if out[j] is None], dtype=np.intp)
    if vectorised(problem, settings):
        for c in np.unique(pset.cone_idx[good]):
            members = good[pset.cone_idx[good] == c]
            group = pset if members.size == len(pset) else pset.take(members)
            for j, res in zip(members, _fit_group(problem, settings, group)):
                out[j] = res
    else:
        for j in good:
            out[j] = _fit_one(problem, settings, pset, int(j))
    for j in good:
        res = out[j]
        res.metadata = meta[j]
        if res.ok:
            res.notes += problem.notes_for(res.cone)
    return out


def _error_result(
    pset: ProfileSet, j: int, reason: str | InputError, meta: dict
) -> PredictionResult:
    src = pset.source(j)
    return PredictionResult(
        id=str(pset.ids[j]),
        status="error",
        error=reason,
        cone=pset.cones[int(pset.cone_idx[j])].name,
        metadata=meta,
        notes=[] if pset.notes is None else list(pset.notes[j]),
        source=None if src is None else src.path,
    )


def _solver_error(pset: ProfileSet, j: int, why: str) -> PredictionResult:
    src = pset.source(j)
    path = None if src is None else src.path
    msg = str(InputError(why, file=path, profile=str(pset.ids[j])))
    return _error_result(pset, j, msg, {})


# ---------------------------------------------------------------------------
# the vectorised exact path (fully mobilised shear)
# ---------------------------------------------------------------------------


def _fit_group(
    problem: Problem, settings: RunSettings, group: ProfileSet
) -> list[PredictionResult]:
    """One cone's profiles through one vectorised solve; a failing profile is isolated.

    Should the solver raise, the group is halved until the profile that
    breaks it is alone and reported as an error, so the others are fitted.
    """
    t0 = time.perf_counter()
    try:
        with np.errstate(all="ignore"):
            fit = solve_set(problem, settings, group)
    except Exception as exc:  # noqa: BLE001 - isolate the failing profiles by bisection
        P = len(group)
        if P == 1:
            return [_solver_error(group, 0, f"solver failed: {exc}")]
        h = P // 2
        return _fit_group(problem, settings, group.take(np.arange(h))) + _fit_group(
            problem, settings, group.take(np.arange(h, P))
        )
    return _group_results(problem, group, fit, (time.perf_counter() - t0) / len(group))


@dataclass
class SetFit:
    """The optimum of every profile of a one-cone set and its statistics (SI, length P).

    ``x`` holds (kc, kphi, cc); ``model`` the model CI on the padded depths
    (P, Z); ``intervals`` the profile intervals per profile; ``checks`` the
    :class:`terracone.physics.metrics.FitCheck` of each profile.
    """

    x: np.ndarray
    n: np.ndarray
    phic: np.ndarray
    phic_lo: np.ndarray
    phic_hi: np.ndarray
    sse: np.ndarray
    rmsd: np.ndarray
    sigma: np.ndarray
    model: np.ndarray
    undetermined: list[list[str]]
    intervals: list[dict[str, tuple[float, float]]]
    checks: list[Any]
    nfev: int


def solve_set(problem: Problem, settings: RunSettings, group: ProfileSet) -> SetFit:
    """Optima and statistics of a one-cone set (exact solver, fully mobilised shear).

    One :func:`solve_exact_many` call over the set (eqs. (2-5) to (2-7)),
    the linear parameters re-solved on the design matrix
    (:func:`polish_many`), then the n interval, the phic ridge and, with
    ``detail="full"``, the profile scans of kc, kphi and cc.
    """
    from terracone.inverse.solver.kernels import box_grid

    pb, s, b = problem, settings, problem.fit_bounds
    cone = group.cones[int(group.cone_idx[0])]
    bounds_of = list(zip(group.offsets[:-1].tolist(), group.offsets[1:].tolist()))
    zs = [group.depth[a:e] for a, e in bounds_of]
    ys = [group.ci[a:e] for a, e in bounds_of]
    ms = (s.solve_many or solve_exact_many)(
        zs,
        ys,
        cone=cone,
        law=pb.law,
        bounds=b,
        n_grid=s.n_grid,
        noise_floor=pb.noise_floor,
        kc_over_kphi=pb.ratio,
    )
    zz, yy, mask = group.padded()
    # eq. (2-7): CI = X (kc, kphi, cc) at the optimum's n and phic (eq. (2-6), fully mobilised)
    X = design(zz, ms.n[:, None], ms.phic_deg[:, None], cone=cone, law=pb.law, K_cone=None)
    X = X * mask[..., None]
    lo, hi = (
        a[:, 0] for a in box_grid(np.ascontiguousarray(ms.n[:, None]), bounds_params(b, pb.ratio))
    )
    ratio = pb.ratio
    if ratio is None:
        x = polish_many(X, yy, lo, hi, np.stack([ms.kc, ms.kphi, ms.cc], axis=1))
    else:  # kc = ratio kphi: the kc column folds into the kphi column
        Xr = np.stack([np.zeros_like(X[..., 0]), ratio * X[..., 0] + X[..., 1], X[..., 2]], -1)
        xr = polish_many(Xr, yy, lo, hi, np.stack([0 * ms.kc, ms.kphi, ms.cc], axis=1))
        x = np.stack([ratio * xr[:, 1], xr[:, 1], xr[:, 2]], axis=1)
    # the reported model CI from the model itself (eq. (2-7)), as rmsd_objective evaluates it
    n_, p_ = ms.n[:, None], ms.phic_deg[:, None]
    kc, kphi, cc = x[:, 0:1], x[:, 1:2], x[:, 2:3]
    model = cone_index_huang(
        zz, kc=kc, kphi=kphi, n=n_, cc=cc, phic_deg=p_, K_cone=None, law=pb.law, cone=cone
    )
    r = np.where(mask, model - yy, 0.0)
    sse = np.einsum("pz,pz->p", r, r)
    sigma, thr, n_lo, n_hi = n_intervals(ms, sse, yy, mask, b, pb.noise_floor)
    und, intervals = [], []
    counts = group.counts
    for j, k in enumerate(counts):
        linear: tuple[list[str], dict[str, tuple[float, float]]] = ([], {})
        if s.detail == "full":
            args = (zz[j, :k], yy[j, :k], x[j], ms.n[j], ms.phic_deg[j], thr[j], (n_lo[j], n_hi[j]))
            linear = linear_intervals(*args, bounds=b, law=pb.law, cone=cone, ratio=ratio)
        found = identification(b, (n_lo[j], n_hi[j]), (ms.phic_lo[j], ms.phic_hi[j]), linear)
        und.append(found[0])
        intervals.append(found[1])
    checks = [check_fit_fast(zz[j, :k], yy[j, :k], model[j, :k]) for j, k in enumerate(counts)]
    return SetFit(
        x,
        ms.n,
        ms.phic_deg,
        ms.phic_lo,
        ms.phic_hi,
        sse,
        np.sqrt(sse / counts),
        sigma,
        model,
        und,
        intervals,
        checks,
        int(ms.nfev) // len(group),
    )


def _group_results(
    problem: Problem, group: ProfileSet, fit: SetFit, time_s: float
) -> list[PredictionResult]:
    """The results of a vectorised fit, one per profile (arrays read as Python lists once)."""
    starts, counts = group.offsets[:-1].tolist(), group.counts.tolist()
    x, n, phic = fit.x.tolist(), fit.n.tolist(), fit.phic.tolist()
    ranges = list(zip(fit.phic_lo.tolist(), fit.phic_hi.tolist()))
    sigma, rmsd = fit.sigma.tolist(), fit.rmsd.tolist()
    sources = _source_paths(group)
    cone = group.cones[int(group.cone_idx[0])].name
    out = []
    for j, (s, k) in enumerate(zip(starts, counts)):
        kc, kphi, cc = x[j]
        chk = fit.checks[j]
        out.append(
            PredictionResult(
                id=str(group.ids[j]),
                status="ok",
                params=TerrainParameters(
                    kc, kphi, n[j], cc, phic[j], None, problem.model, problem.r_min
                ),
                rmsd=rmsd[j],
                r2_ci=chk.r2,
                longest_run=chk.longest_run,
                lack_of_fit=chk.lack_of_fit,
                depth=group.depth[s : s + k],
                ci=group.ci[s : s + k],
                ci_model=fit.model[j, :k],
                undetermined=fit.undetermined[j],
                phic_range=ranges[j],
                profile_intervals=fit.intervals[j],
                sigma=sigma[j],
                solver="exact",
                nfev=fit.nfev,
                nit=1,
                time_s=time_s,
                converged=True,
                message=_EXACT_MESSAGE,
                cone=cone,
                notes=[] if group.notes is None else list(group.notes[j]),
                source=sources[j],
            )
        )
    return out


def _source_paths(pset: ProfileSet) -> list[str | None]:
    """The file path of each profile of a set (None where it has none)."""
    if pset.file_idx is None:
        return [None] * len(pset)
    paths = [f.path for f in pset.files] + [None]  # file_idx -1: the last entry
    return [paths[i] for i in pset.file_idx.tolist()]


def _ok_result(
    pset: ProfileSet, j: int, params, y, m, rmsd, chk, solver: str, time_s: float, extra: dict
) -> PredictionResult:
    """An ok result: profile j of the set, its parameters, measured y and model m [kPa]."""
    s = int(pset.offsets[j])
    src = pset.source(j)
    return PredictionResult(
        id=str(pset.ids[j]),
        status="ok",
        params=params,
        rmsd=float(rmsd),
        r2_ci=chk.r2,
        longest_run=chk.longest_run,
        lack_of_fit=chk.lack_of_fit,
        depth=pset.depth[s : s + y.size],
        ci=y,
        ci_model=m,
        solver=solver,
        time_s=time_s,
        cone=pset.cones[int(pset.cone_idx[j])].name,
        notes=[] if pset.notes is None else list(pset.notes[j]),
        source=None if src is None else src.path,
        **extra,
    )


# ---------------------------------------------------------------------------
# profile by profile: the particle swarm, finite or fitted Kc
# ---------------------------------------------------------------------------


def _fit_one(problem: Problem, settings: RunSettings, pset: ProfileSet, j: int) -> PredictionResult:
    """One profile through the particle swarm or the exact solver with finite Kc."""
    t0 = time.perf_counter()
    s, e = int(pset.offsets[j]), int(pset.offsets[j + 1])
    z, y = pset.depth[s:e], pset.ci[s:e]
    cone = pset.cones[int(pset.cone_idx[j])]
    try:
        with np.errstate(all="ignore"):
            fit = _exact_one if settings.solver == "exact" else _pso_one
            params, extra = fit(problem, settings, z, y, cone)
            # eq. (2-7), with eq. (2-6) at the fitted Kc
            m = cone_index_huang(
                z,
                kc=params.kc,
                kphi=params.kphi,
                n=params.n,
                cc=params.cc,
                phic_deg=params.phic_deg,
                K_cone=params.K_cone,
                law=problem.law,
                cone=cone,
            )
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return _solver_error(pset, j, f"solver failed: {exc}")
    chk = check_fit_fast(z, y, m)
    rmsd = np.sqrt(np.mean((m - y) ** 2))
    t = time.perf_counter() - t0
    return _ok_result(pset, j, params, y, m, rmsd, chk, settings.solver, t, extra)


def _exact_one(pb: Problem, s: RunSettings, z, y, cone: Cone) -> tuple[TerrainParameters, dict]:
    """:func:`solve_exact` on one profile (finite or fitted Kc)."""
    sol = solve_exact(
        z,
        y,
        cone=cone,
        law=pb.law,
        bounds=pb.fit_bounds,
        K_cone=pb.K_cone,
        fit_K_cone=pb.fit_K_cone,
        n_grid=s.n_grid,
        noise_floor=pb.noise_floor,
        kc_over_kphi=pb.ratio,
    )
    params = TerrainParameters(
        sol.kc, sol.kphi, sol.n, sol.cc, sol.phic_deg, sol.K_cone, pb.model, pb.r_min
    )
    extra = dict(
        undetermined=sol.undetermined,
        phic_range=sol.phic_range,
        profile_intervals=sol.profile_intervals,
        sigma=sol.sigma,
        nfev=sol.nfev,
        nit=sol.nit,
        converged=True,
        message=_EXACT_MESSAGE,
    )
    return params, extra


def _pso_one(pb: Problem, s: RunSettings, z, y, cone: Cone) -> tuple[TerrainParameters, dict]:
    """The paper's particle swarm on the RMSD (section 3.3.2) for one profile."""
    b = pb.fit_bounds
    f = rmsd_objective(CIProfile("", z, y, cone=cone), pb.law, b, pb.K_cone, pb.ratio)
    kc_box = list(b.kc) if pb.ratio is None else [0.0, 0.0]  # a held ratio sets kc
    lo = [kc_box[0], b.kphi[0], b.n[0], b.cc[0], b.phic_deg[0]]
    hi = [kc_box[1], b.kphi[1], b.n[1], b.cc[1], b.phic_deg[1]]
    if pb.fit_K_cone:
        lo, hi = lo + [b.K_cone[0]], hi + [b.K_cone[1]]
    res = pso(f, np.array(lo), np.array(hi), seed=s.seed, **(s.pso_options or {}))
    x = res.x
    n = float(x[2])
    kphi = float(u.kphi_to_si(x[1], n, b.kphi_units))
    kc = kphi * pb.ratio if pb.ratio is not None else float(u.kc_to_si(x[0], n, b.kc_units))
    K = float(x[5]) if pb.fit_K_cone else pb.K_cone
    params = TerrainParameters(kc, kphi, n, float(x[3]), float(x[4]), K, pb.model, pb.r_min)
    free = not pb.fit_K_cone and pb.K_cone is None and b.phic_deg[0] != b.phic_deg[1]
    extra = dict(
        undetermined=["phic", "phic~scale(kc,kphi)"] if free else [],
        nfev=res.nfev,
        nit=res.nit,
        converged=res.converged,
        message=res.message + " (pso does not analyse identifiability beyond phic)",
    )
    return params, extra

"""The learning process (section 3.3.1 of [1]_) and calibrations.

Given CI profiles and plate pressure-sinkage tests of one terrain, find the
RM1 transition radius r_min and kc, kphi, n, cc, phic fitted jointly to all
data, minimising ``J = sum_d RMSD_d / mean_d`` over the data sets d (each CI
profile and each plate test): a certified convex solve in (kc, kphi, cc)
(:mod:`.sumnorm`) on a grid of (n, phic, log r_min), local searches from the
grid's best points in every stretch of r_min between RM1 branch points (least
squares by variable projection, :mod:`.varpro`, then J, :mod:`.search`), and
a branch and bound that bounds how far the answer can be from the global
minimum (:mod:`.search`; ``docs/learn.md``).  The result is
saved as a :class:`Calibration`, the paper's "information library", which
the prediction process uses.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 3.2 and 3.3.1, Figure 3-1.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np

from terracone.data import CIProfile, PlateTest, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.learning.search import (
    GridStage,
    LearnProblem,
    Refined,
    certify,
    flat_set,
    grid_stage,
    jacobians,
    polish,
    refine,
    secant_twin,
    stretch_starts,
)
from terracone.inverse.learning.varpro import descend
from terracone.inverse.problem import Calibration
from terracone.resultunits import convert_parameters, from_si, output, quantity

__all__ = [
    "LearnResult",
    "learn",
    "learn_problem",
    "sandwich_cov",
]


@dataclass
class LearnResult:
    """Result of :func:`learn` (SI inside)."""

    params: TerrainParameters
    plate_pair: tuple[float, float] | None = quantity("length")
    objective: float
    rmsd_ci: float = quantity("pressure")
    rmsd_plates: float = quantity("pressure")
    datasets: list[dict[str, Any]]
    undetermined: list[str]
    criteria: dict[str, Any]
    nfev: int
    time_s: float
    r_min_profile: list[tuple[float, float]] = field(default_factory=list)
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    certificate: dict[str, Any] = field(default_factory=dict)
    flat_sets: dict[str, tuple[float, float]] = field(default_factory=dict)
    equivalent: list[dict[str, float]] = field(default_factory=list)

    def _repr_html_(self) -> str:
        """A table of the learned parameters (SI and US) and the fit, for Jupyter."""
        from terracone.notebook import learn_html

        return learn_html(self)

    def calibration(
        self, terrain: str, cone: str = "asabe-large", **provenance: Any
    ) -> Calibration:
        """The calibration to save for the prediction process."""
        from terracone import __version__

        prov = {
            "created": datetime.now(UTC).isoformat(timespec="seconds"),
            "method": "terracone learn (section 3.3.1)",
            "terracone": __version__,
            **provenance,
        }
        # the calibration holds what prediction uses: not a fixed Kc of the learning
        params = replace(self.params, K_cone=None)
        return Calibration(
            terrain, plate_pair=self.plate_pair, cone=cone, provenance=prov, params=params
        )

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The learned parameters and the fit in a unit system (``terracone learn --json``)."""
        n = self.params.n
        d = self.params.as_dict(units)
        d.update(
            {
                **output(self, units, fields=("rmsd_ci", "rmsd_plates", "objective", "plate_pair")),
                "datasets": [
                    {**ds, "rmsd": from_si(ds["rmsd"], "pressure", units)} for ds in self.datasets
                ],
                "undetermined": self.undetermined,
                "profile_intervals": convert_parameters(self.intervals, units, n),
                "interval_level": 0.95,
                "flat_sets": convert_parameters(self.flat_sets, units, n),
                "equivalent": [convert_parameters(e, units, n) for e in self.equivalent],
                "certificate": self.certificate,
                "criteria": self.criteria,
                "diagnostics": {"nfev": self.nfev, "time_s": self.time_s},
            }
        )
        return d


def _plate_pair(plates: list[PlateTest]) -> tuple[float, float] | None:
    sizes = sorted({round(p.b, 12) for p in plates})
    return (sizes[0], sizes[-1]) if len(sizes) >= 2 else None


def learn_problem(
    profiles: list[CIProfile],
    plates: list[PlateTest],
    model: str,
    bounds: Bounds,
    r_min_bounds: tuple[float, float] | None,
    K_cone: float | None,
) -> LearnProblem:
    """The checked data and search space of :func:`learn` (plates' loading branches only)."""
    if model not in ("rm0", "rm1"):
        raise ValueError(f"model must be 'rm0' or 'rm1' (got {model!r})")
    if not profiles:
        raise ValueError("learning needs at least one CI profile")
    for p in profiles:
        p.validate()
    branches = [p.loading_branch() for p in plates]
    branches = [b for b in branches if b.sinkage.size >= 3]
    if not branches:
        raise ValueError("learning needs at least one plate test with 3 or more loading points")
    rb = None
    if model == "rm1":
        rb = r_min_bounds or (5e-4, 3.0 * max(b.b for b in branches))
        if not (0 < rb[0] <= rb[1] and math.isfinite(rb[1])):
            raise ValueError(f"r_min range: need 0 < LO <= HI (got {rb[0]}:{rb[1]})")
    return LearnProblem(profiles, branches, model, bounds, rb, K_cone, _plate_pair(branches))


def learn(
    profiles: list[CIProfile],
    plates: list[PlateTest],
    *,
    model: str = "rm1",
    bounds: Bounds | None = None,
    r_min_bounds: tuple[float, float] | None = None,
    K_cone: float | None = None,
    grid: tuple[int, int, int] = (17, 10, 12),
    max_cv: float = 0.25,
    noise_floor: float = 0.01,
    starts: int = 3,
    certify_levels: int = 6,
    certify_target: float = 0.04,
) -> LearnResult:
    """Fit kc, kphi, n, cc, phic (and r_min for RM1) to CI and plate data.

    Minimises J = sum_d RMSD_d / mean_d over the data sets d (each CI
    profile and each plate test's loading branch) within the bounds: a
    certified inner solve in (kc, kphi, cc) on a grid of (n, phic,
    log r_min), then, from the best grid points of every stretch of r_min
    between RM1 branch points, least squares by variable projection
    (:mod:`.varpro`; exact on noise-free data) and J itself (:mod:`.search`).

    Parameters
    ----------
    profiles : list of CIProfile
    plates : list of PlateTest
        Only their loading branches are used.
    model : {"rm1", "rm0"}
    bounds : Bounds
    r_min_bounds : (float, float), optional
        Search range of r_min [m]; default 0.5 mm to 3 times the larger plate.
    K_cone : float, optional
        Fixed cone-terrain shear deformation parameter [m] (None: fully
        mobilised).
    grid : (int, int, int)
        Grid sizes for n, phic and r_min.
    max_cv : float
        Fit criterion: every data set's CV = RMSD/mean must be below this.
    noise_floor : float
        Smallest relative noise assumed when judging what the data leave free.
    starts : int
        Most grid points (local minima of the grid's J) per stretch of r_min
        between RM1 branch points that start a local search.
    certify_levels : int
        Rounds of branch and bound on the grid cells for the lower bound of
        the global minimum (0: the grid alone; each round halves, along one
        axis, up to 200 cells whose bound is below J by more than
        ``certify_target``, at 4 certified inner solves per cell).
    certify_target : float
        Relative gap the branch and bound aims at: cells whose bound is
        within this fraction of J are not refined further.

    Returns
    -------
    LearnResult
        With ``certificate`` (J, a lower bound of the global minimum and
        their gap) and 95% ``intervals``.

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Section 3.3.1.
    """
    t0 = time.perf_counter()
    prob = learn_problem(profiles, plates, model, bounds or Bounds(), r_min_bounds, K_cone)
    stage, best, nfev, lower, n_cells = _search(prob, grid, starts, certify_levels, certify_target)
    x, theta = best.x, best.theta
    rm = float(np.exp(theta[2])) if model == "rm1" else None
    params = TerrainParameters(
        float(x[0]), float(x[1]), float(theta[0]), float(x[2]), float(theta[1]), K_cone, model, rm
    )
    final = prob.solve_cells(
        np.array([theta[0]]), np.array([theta[1]]), np.array([theta[2]]), rtol=1e-9
    )
    datasets, J_res = _datasets(prob, x, theta)
    certificate = _certificate(stage, J_res, lower, float(final.gap[0]), n_cells)
    criteria = _criteria(prob, params, datasets, max_cv)
    intervals, und, r_profile = _intervals(prob, stage, x, theta, datasets, noise_floor)
    flat_sets, equivalent = _flat_sets(prob, x, theta, intervals, und)
    res = [np.concatenate(r) for r in _split_residuals(prob, x, theta)]
    return LearnResult(
        params=params,
        plate_pair=prob.pair,
        objective=J_res,
        rmsd_ci=float(np.sqrt(np.mean(res[0] ** 2))),
        rmsd_plates=float(np.sqrt(np.mean(res[1] ** 2))),
        datasets=datasets,
        undetermined=und,
        criteria=criteria,
        nfev=nfev,
        time_s=time.perf_counter() - t0,
        r_min_profile=r_profile,
        intervals=intervals,
        certificate=certificate,
        flat_sets=flat_sets,
        equivalent=equivalent,
    )


def _flat_sets(prob: LearnProblem, x, theta, intervals, und: list[str]):
    """What fits exactly as well as the answer: r_min above the larger plate (the RM1 law
    is then the secant through both plates' pressures, section 3.2, and J does not depend
    on r_min), and at r_min = r2 the tangent twin of the secant (:func:`.search.secant_twin`).

    Returns (flat sets {"r_min": (r2, HI)} [m], the equivalent parameter sets [SI]); r_min
    (and kc, kphi when there is a twin) are then listed in ``und`` and their intervals
    cover the set and the twin (both updated in place).
    """
    twin = secant_twin(prob, x, theta)
    flat = flat_set(prob, float(theta[2]))
    if flat is None and twin is not None:  # at r2: the secant set is as good
        flat = flat_set(prob, float(twin[1][2]))
    if flat is None:
        return {}, []
    lo, hi = math.exp(flat[0]), math.exp(flat[1])
    others = [("r_min", lo, hi)]
    equivalent = []
    if twin is not None:
        (kc, kphi, _), th = twin
        others += [("kc", kc, kc), ("kphi", kphi, kphi)]
        equivalent.append({"kc": float(kc), "kphi": float(kphi), "r_min": math.exp(th[2])})
    for name, a_, b_ in others:
        a, b = intervals.get(name, (a_, b_))
        intervals[name] = (min(a, a_), max(b, b_))
        if name not in und:
            und.append(name)
    return {"r_min": (lo, hi)}, equivalent


def _certificate(
    stage: GridStage, J_res: float, lower: float, inner_gap: float, n_cells: int
) -> dict[str, Any]:
    """The certificate of :func:`learn`: J, a lower bound of the global minimum, how found."""
    return {
        "objective": J_res,
        "lower_bound": min(lower, J_res),
        "gap": max(J_res - lower, 0.0),
        "inner_gap": inner_gap,
        "cells_not_excluded": n_cells,
        "grid": [int(a.size) for a in stage.axes],
        "method": (
            "inner (kc, kphi, cc): convex, solved with a duality-gap certificate (its dual value "
            "is a proven lower bound at each grid point); outer (n, phic, log r_min): each cell's "
            "bound is its smallest corner lower bound less the error of linear interpolation, "
            "sum_k M_k h_k^2 / 8, with the curvature M_k taken as 2 times the largest second "
            "divided difference of J on the cell's sample points (an estimate, not a proof: J "
            "is assumed no more curved inside a cell than twice what its samples show); RM1 "
            "branch points, where J jumps, are cell boundaries; cells below J by more than the "
            "target are halved by branch and bound; J >= 0 certifies a zero-residual fit"
        ),
        "assumption": "curvature of J inside a cell at most 2x its sampled second differences",
    }


def _criteria(
    prob: LearnProblem, params: TerrainParameters, datasets: list[dict[str, Any]], max_cv: float
) -> dict[str, Any]:
    """The fit criterion of :func:`learn` (every data set's CV below ``max_cv``)."""
    worst = max(ds["cv"] for ds in datasets)
    return {
        "max_cv": max_cv,
        "worst_cv": worst,
        "satisfied": bool(worst <= max_cv),
        "at_bounds": _at_bounds(prob, params),
    }


def _search(prob: LearnProblem, grid, starts: int, certify_levels: int, target: float):
    """Grid, local searches from its best points in every r_min stretch, the global bound.

    Least squares first, by variable projection (:func:`.varpro.descend`), from
    up to ``starts`` grid points per stretch of log r_min: on noise-free data
    it reaches a zero residual, which J >= 0 certifies as the global minimum.
    Otherwise J itself is minimised (:func:`.search.refine`) in each stretch
    from its least-squares end point of least J, unless the stretch's least
    squares F says J cannot beat the best there (J >= sqrt(F): the sum of
    a_d ||r_d|| is at least their root sum of squares); the best is polished
    and bounded from below.
    """
    stage = grid_stage(prob, grid)
    nfev = int(stage.cells.J.size)
    zero = 1e-12 * float(sum(a * np.linalg.norm(y) for a, y in zip(prob.a, prob.ys)))
    st = stretch_starts(prob, stage, starts)
    ls = descend(prob, st.theta, st.t_lo, st.t_hi, st.t_free)
    nfev += ls.evaluations
    order = np.lexsort((np.arange(ls.J.size), ls.J))
    k = int(order[0])
    best = Refined(ls.x[k], ls.theta[k], float(prob.objective(ls.x[k], ls.theta[k])), 0)
    if best.J > zero:
        # J in each stretch from its least-squares point of least J, best first; a stretch is
        # left when sqrt(F) there (F its least squares, J >= sqrt(F)) is not below the best J
        seen: set[int] = set()
        for k in order:
            key = id(st.stretch[k])
            if key in seen:
                continue
            seen.add(key)
            F_min = min(f for f, s_ in zip(ls.F, st.stretch) if s_ is st.stretch[k])
            if math.sqrt(F_min) >= best.J:
                continue
            r = refine(prob, ls.x[k], ls.theta[k], st.stretch[k])
            nfev += r.nfev
            if r.J < best.J * (1 - 1e-12) - 1e-300:
                best = r
        best = polish(prob, best.x, best.theta)
    if best.J <= zero:  # J >= 0 certifies an exact fit
        lower, n_cells, n_cert = 0.0, 0, 0
    else:
        lower, n_cells, n_cert = certify(
            prob, stage, best.J, levels=certify_levels, cap=200, target=target, rtol=1e-5
        )
    nfev += n_cert
    return stage, best, nfev, lower, n_cells


def _split_residuals(prob: LearnProblem, x, theta) -> tuple[list, list]:
    r = prob.residuals(x, theta)
    k = len(prob.profiles)
    return r[:k], r[k:]


def _datasets(prob: LearnProblem, x, theta) -> tuple[list[dict[str, Any]], float]:
    """Per data set RMSD and CV, from the residuals; and J re-derived from them."""
    out = []
    items = [("ci", p.id, None) for p in prob.profiles] + [
        ("plate", b.id, b.b) for b in prob.plates
    ]
    for (kind, did, b), r, m in zip(items, prob.residuals(x, theta), prob.means):
        rms = float(np.sqrt(np.mean(r * r)))
        d = {"kind": kind, "id": did, "rmsd": rms, "cv": rms / float(m)}
        if b is not None:
            d = {"kind": kind, "id": did, "b": b, "rmsd": rms, "cv": rms / float(m)}
        out.append(d)
    return out, float(sum(d["cv"] for d in out))


def _at_bounds(prob: LearnProblem, p: TerrainParameters) -> list[str]:
    """Values that ended on a search bound: the bound, not the data, set them."""
    b = prob.bounds
    kc_b, kp_b = b.kc_si(p.n), b.kphi_si(p.n)
    checks = [
        ("kc", p.kc, float(kc_b[0]), float(kc_b[1])),
        ("kphi", p.kphi, float(kp_b[0]), float(kp_b[1])),
        ("n", p.n, *b.n),
        ("cc", p.cc, *b.cc),
        ("phic_deg", p.phic_deg, *b.phic_deg),
    ]
    if prob.r_min_bounds:
        checks.append(("r_min", p.r_min, *prob.r_min_bounds))
    out = []
    for name, v, lo_b, hi_b in checks:
        if lo_b == hi_b:
            continue
        tol = 1e-6 * (hi_b - lo_b)
        if v <= lo_b + tol:
            out.append(f"{name} at its lower bound")
        elif v >= hi_b - tol:
            out.append(f"{name} at its upper bound")
    return out


Z95 = 1.959963984540054  # two-sided 95% quantile of the standard normal


def sandwich_cov(prob: LearnProblem, x, theta, noise_floor: float) -> np.ndarray:
    """Covariance (6, 6) of p = (kc, kphi, cc, n, phic, log r_min), sandwich form.

    The minimiser of J is, at its optimum, a weighted least-squares fit with
    weights w_d = a_d / ||r_d|| (the fixed point of reweighting; ||r_d|| taken
    as at least ``noise_floor`` mean_d sqrt(N_d), the norm of an RMSD at the
    noise floor, so that a data set fitted exactly does not weigh without
    bound), so its
    covariance is H^+ B H^+ with H = sum_d w_d D_d'D_d and
    B = sum_d w_d^2 D_d' diag(r_d^2) D_d (heteroscedasticity-consistent,
    HC3: each squared residual divided by (1 - leverage)^2 and at least
    (``noise_floor`` mean_d)^2); H is the Hessian of J (Gauss-Newton part).  Parameters fixed by their bounds get zero
    variance; parameters that move along a direction in which J is flat (a
    ridge of equally good values) get infinite variance.

    References
    ----------
    .. [1] White, H. (1980). A heteroskedasticity-consistent covariance matrix
       estimator and a direct test for heteroskedasticity. Econometrica 48(4).
    .. [2] Long, J.S., Ervin, L.H. (2000). Using heteroscedasticity consistent
       standard errors in the linear regression model. Am. Stat. 54(3).
    """
    Ds = jacobians(prob, x, theta)
    rs = prob.residuals(x, theta)
    lo, hi = prob.box(np.asarray(theta[0]))
    free = np.concatenate([hi > lo, prob.theta_hi > prob.theta_lo])
    if prob.model == "rm0":
        free[5] = False
    H = np.zeros((6, 6))
    parts = []
    for D, r, a, m in zip(Ds, rs, prob.a, prob.means):
        # ||r_d|| at least the noise floor's (RMSD = noise_floor mean_d): a data set fitted
        # more closely (noise-free data) weighs as one at the floor, not without bound
        nr = max(float(np.linalg.norm(r)), noise_floor * float(m) * math.sqrt(r.size), 1e-300)
        w = a / nr
        g = D.T @ (r / nr)  # Hessian of a_d ||r_d||: w (D'D - g g')
        H += w * (D.T @ D - np.outer(g, g))
        parts.append((w, D - np.outer(r / nr, g)))  # (I - u u') D, u = r / ||r||
    f = np.ix_(free, free)
    sc = np.sqrt(np.maximum(np.diag(H[f]), 1e-300))
    Hi = np.linalg.pinv(H[f] / np.outer(sc, sc), rcond=1e-12) / np.outer(sc, sc)
    B = np.zeros((6, 6))
    for (w, Dp), D, r, m in zip(parts, Ds, rs, prob.means):
        # HC3: squared residuals inflated by their leverage (deep CI points weigh most)
        h = np.clip(w * np.einsum("ij,jk,ik->i", D[:, free], Hi, D[:, free]), 0.0, 0.9)
        r2 = np.maximum(r * r / (1.0 - h) ** 2, (noise_floor * m) ** 2)
        B += w * w * (Dp.T * r2) @ Dp
    V = np.zeros((6, 6))
    V[f] = Hi @ B[f] @ Hi
    # directions along which J is flat (a ridge of equally good values): infinite variance
    Hn = H[f] / np.outer(sc, sc)
    ev, vec = np.linalg.eigh(0.5 * (Hn + Hn.T))
    null = ev <= 1e-10 * max(float(ev.max()), 1e-300)
    if null.any():
        ridge = np.flatnonzero(free)[np.any(np.abs(vec[:, null]) > 1e-3, axis=1)]
        V[ridge, ridge] = np.inf
    return V


def _intervals(prob: LearnProblem, stage: GridStage, x, theta, datasets, noise_floor):
    """95% intervals of all parameters, the undetermined list and the r_min profile.

    Wald intervals from :func:`sandwich_cov`, clipped to the bounds.  For
    phic and r_min (and cc when its interval is wide) they are widened to
    every profiled value whose best J (the other coordinates near the
    optimum) is within dJ of the optimum: values that fit as well as the
    optimum within the noise are equally good.
    dJ = 1.92 max_d sigma_d / (mean_d N_d) is the rise of J that a 95%
    likelihood-ratio step (3.84 sigma_d^2 in SSE_d) causes in the data set
    that tolerates the least.
    """
    V = sandwich_cov(prob, x, theta, noise_floor)
    p = np.concatenate([x, theta])
    half = Z95 * np.sqrt(np.maximum(np.diag(V), 0.0))
    lo_x, hi_x = prob.box(np.asarray(theta[0]))
    lo = np.concatenate([lo_x, prob.theta_lo])
    hi = np.concatenate([hi_x, prob.theta_hi])
    iv = np.stack([np.clip(p - half, lo, hi), np.clip(p + half, lo, hi)], axis=1)
    ridge = ~np.isfinite(half)  # J flat along them: the whole range unless profiled below
    sig = [max(d["rmsd"], noise_floor * m) for d, m in zip(datasets, prob.means)]
    dJ = 1.92 * max(s / (m * y.size) for s, m, y in zip(sig, prob.means, prob.ys))
    thr = float(sum(a_ * np.linalg.norm(r) for a_, r in zip(prob.a, prob.residuals(x, theta))))
    thr += dJ
    steps = np.array([(ax[1] - ax[0]) if ax.size > 1 else 0.0 for ax in stage.axes])
    # one vectorised certified solve for all profiles: phic, log r_min, and cc if wide
    groups = [(k, _profile_values(prob, stage, theta, k)) for k in (1, 2)]
    groups = [(k, v) for k, v in groups if v.size > 1]
    if hi[2] > lo[2] and iv[2, 1] - iv[2, 0] >= 0.25 * (hi[2] - lo[2]):
        groups.append(("cc", np.linspace(*prob.bounds.cc, 11)))
    blocks = [_profile_block(prob, theta, steps, k, v) for k, v in groups]
    for k, _ in groups:  # a profiled ridge parameter: its profile says how far
        row = 2 if k == "cc" else 3 + k
        if ridge[row]:
            iv[row] = (p[row], p[row])
    r_profile: list[tuple[float, float]] = []
    if blocks:
        T = np.concatenate([b[0] for b in blocks])
        pin = np.concatenate([b[1] for b in blocks])
        J = prob.solve_cells(T[:, 0], T[:, 1], T[:, 2], cc_pin=pin, rtol=1e-5, max_iter=40).J
        start = 0
        for (k, vals), (Tb, _) in zip(groups, blocks):
            prof = J[start : start + Tb.shape[0]].reshape(vals.size, -1).min(axis=1)
            start += Tb.shape[0]
            ok = vals[prof <= thr]
            row = 2 if k == "cc" else 3 + k
            if ok.size:
                iv[row] = (min(iv[row, 0], ok.min()), max(iv[row, 1], ok.max()))
            if k == 2:
                r_profile = [(float(np.exp(a_)), float(b_)) for a_, b_ in zip(vals, prof)]
    names = ["kc", "kphi", "cc", "n", "phic_deg", "r_min"]
    intervals: dict[str, tuple[float, float]] = {}
    und: list[str] = []
    for k, name in enumerate(names):
        if hi[k] == lo[k] or (name == "r_min" and prob.model == "rm0"):
            continue
        a, b = float(iv[k, 0]), float(iv[k, 1])
        if b - a >= 0.5 * (hi[k] - lo[k]):
            und.append(name)
        intervals[name] = (math.exp(a), math.exp(b)) if name == "r_min" else (a, b)
    return intervals, und, r_profile


def _neighbourhood(theta, steps, axes_free, offsets):
    """theta plus offsets (fractions of a grid step) along the given axes: (K, 3)."""
    grids = [theta[k] + (offsets * steps[k] if k in axes_free else np.zeros(1)) for k in range(3)]
    return np.stack([g.reshape(-1) for g in np.meshgrid(*grids, indexing="ij")], axis=-1)


def _profile_values(prob: LearnProblem, stage: GridStage, theta, k: int) -> np.ndarray:
    """Values of outer coordinate k to profile: its grid, the optimum, RM1 branch points."""
    if stage.axes[k].size < 2:
        return stage.axes[k]
    vals = np.concatenate([stage.axes[k], [theta[k]]])
    if k == 2:  # where the RM1 law changes branch (section 3.2): cone radii and plates
        br = [p.cone.radius for p in prob.profiles] + list(prob.pair or ())
        br = np.log(np.outer(br, [1 - 1e-9, 1 + 1e-9]).reshape(-1))
        vals = np.concatenate([vals, br[(br > vals.min()) & (br < vals.max())]])
    return np.unique(vals)


def _profile_block(prob: LearnProblem, theta, steps, k, values):
    """Cells (V*K, 3) and cc pins (NaN: free) of one profile.

    For an outer coordinate k the two others range over the optimum plus
    offsets of up to one grid step, so that a valley between them is
    followed; for cc (k == "cc") all three range over a quarter step.  The
    inner minimum over the free linear parameters is certified at each cell.
    """
    theta = np.asarray(theta, float)
    if k == "cc":
        nb = _neighbourhood(theta, steps, [0, 1, 2], np.array([-0.25, 0.0, 0.25]))
        T = np.repeat(nb[None], values.size, axis=0)
        pin = np.repeat(values[:, None], nb.shape[0], axis=1)
    else:
        others = [j for j in range(3) if j != k and steps[j] > 0]
        nb = _neighbourhood(theta, steps, others, np.array([-1.0, -0.25, 0.0, 0.25, 1.0]))
        T = np.repeat(nb[None], values.size, axis=0)
        T[..., k] = values[:, None]
        pin = np.full(T.shape[:2], np.nan)
    T = np.clip(T, prob.theta_lo, prob.theta_hi)
    return T.reshape(-1, 3), pin.reshape(-1)

"""Site statistics: repeat pushes pooled by a hierarchical (random-effects) model.

Recommendation E of [1]_ asks for three or more pushes at each location and
three or more locations per site.  :func:`fit_sites` turns the pushes of each
site into one site terrain (its median over pushes), the push-to-push
variation and the estimation noise of each push, so that estimation noise is
not reported as variability.  The model, step by step, and its checks are in
``docs/sites.md``.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2), (2-6), (2-7); section 5.2, recommendation E.
.. [2] Roever, C., Knapp, G., Friede, T. (2015). Hartung-Knapp-Sidik-Jonkman
   approach and its modification for random-effects meta-analysis with few
   studies. BMC Med. Res. Methodol. 15, 99.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats
from scipy.cluster.hierarchy import fcluster, linkage

from terracone.data import CIProfile, InputError
from terracone.inverse.bounds import Bounds
from terracone.inverse.library.sites import library_sites
from terracone.inverse.problem import Problem
from terracone.inverse.sites.randeff import random_effects
from terracone.inverse.solver.many import solve_exact_many
from terracone.inverse.uncertainty.noise import RHO_MAX, ar1_noise, estimate_correlation
from terracone.physics import units as u
from terracone.physics.cone import cone_index_basis
from terracone.physics.metrics import check_fit
from terracone.physics.plate import PressureLaw, plate_basis
from terracone.result import LibrarySummary, finite_or_none
from terracone.resultunits import Written, convert_parameters, from_si, quantity

__all__ = [
    "PushFits",
    "SitePlate",
    "SiteResult",
    "Grouping",
    "default_sinkages",
    "fit_pushes",
    "fit_sites",
    "group_profiles",
    "bootstrap_pushes",
    "ci_error_covariance",
    "pushes_needed",
    "shape_pushes",
    "site_centers",
    "site_correlation",
    "site_statistics",
    "site_terrain",
    "SiteStatistics",
]

#: Additive floor of the relative CI noise weights, as a fraction of the largest model CI.
NOISE_FLOOR = 0.05
#: Points of the grids of quantiles combining the pooled mean and the phic ridge.
_QGRID = 200
_THETA = ("kc'", "kphi'", "cc", "n")


def default_sinkages(units: str = "si") -> np.ndarray:
    """Sinkages of the site P-S curves [m]: 25 steps to 5 cm (si) or 2 in (us)."""
    top = 2 * u.INCH if u.check_system(units) == "us" else 0.05
    return np.linspace(top / 25, top, 25)


# ---------------------------------------------------------------------------
# grouping
# ---------------------------------------------------------------------------


@dataclass
class Grouping:
    """Profiles grouped into sites.

    Attributes
    ----------
    sites : dict of str to list of int
        Site name -> indices into the profile list, in input order.
    unassigned : list of (str, str)
        (profile id, reason) of profiles that could not be put in a site.
    """

    sites: dict[str, list[int]]
    unassigned: list[tuple[str, str]] = field(default_factory=list)


def _meta(p: CIProfile, names: Sequence[str]) -> Any:
    low = {str(k).lower(): v for k, v in p.metadata.items()}
    for n in names:
        v = low.get(n.lower())
        if v is not None and not (isinstance(v, float) and not math.isfinite(v)) and v != "":
            return v
    return None


def _label(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def group_profiles(
    profiles: Sequence[CIProfile], *, by: str | None = None, radius: float | None = None
) -> Grouping:
    """Group profiles into sites by a metadata column and/or by distance.

    Parameters
    ----------
    profiles : sequence of CIProfile
    by : str, optional
        Metadata column (case-insensitive), or several separated by commas
        (``plot,date``); profiles sharing its value(s) form a site.
    radius : float, optional
        Site radius [m]: profiles carrying ``latitude``/``longitude`` (or
        ``lat``/``lon``) [deg] are clustered by complete linkage so that no
        two profiles of a site are more than ``2 * radius`` apart
        (equirectangular distances on a sphere of radius 6371 km).  With
        ``by`` too, each column group is split by distance.

    Returns
    -------
    Grouping
        Profiles missing the column or the coordinates are listed in
        ``unassigned`` with the reason, never dropped silently.
    """
    if by is None and radius is None:
        raise ValueError("give a metadata column (--by) or a radius (--radius) to group sites")
    if radius is not None and not (radius > 0 and math.isfinite(radius)):
        raise ValueError(f"radius must be > 0 (got {radius})")
    cols = [c.strip() for c in (by or "").split(",") if c.strip()]
    if by is not None and not cols:
        raise ValueError(f"no metadata column in {by!r}")
    groups: dict[str, list[int]] = {}
    unassigned: list[tuple[str, str]] = []
    for i, p in enumerate(profiles):
        key = "all"
        if by is not None:
            vals = [_meta(p, [c]) for c in cols]
            missing = [c for c, v in zip(cols, vals) if v is None]
            if missing:
                unassigned.append((p.id, f"no value in metadata column {missing[0]!r}"))
                continue
            key = "/".join(_label(v) for v in vals)
        groups.setdefault(key, []).append(i)
    if radius is None:
        return Grouping(groups, unassigned)
    out: dict[str, list[int]] = {}
    for key, idx in groups.items():
        pts, keep = [], []
        for i in idx:
            lat = _meta(profiles[i], ["latitude", "lat"])
            lon = _meta(profiles[i], ["longitude", "lon"])
            if not isinstance(lat, float) or not isinstance(lon, float):
                unassigned.append((profiles[i].id, "no latitude/longitude for --radius"))
                continue
            pts.append((lat, lon))
            keep.append(i)
        if not keep:
            continue
        a = np.radians(np.array(pts))
        xy = 6371e3 * np.column_stack([a[:, 1] * np.cos(a[:, 0].mean()), a[:, 0]])
        labels = (
            fcluster(linkage(xy, "complete"), t=2 * radius, criterion="distance")
            if len(keep) > 1
            else np.array([1])
        )
        order = {lab: r + 1 for r, lab in enumerate(dict.fromkeys(labels.tolist()))}
        for i, lab in zip(keep, labels.tolist()):
            name = f"site-{order[lab]}" if by is None else f"{key}/{order[lab]}"
            out.setdefault(name, []).append(i)
    return Grouping(out, unassigned)


# ---------------------------------------------------------------------------
# per-push fits with their sampling covariance
# ---------------------------------------------------------------------------


@dataclass
class PushFits:
    """Per-push fits (arrays of length P, SI).

    Attributes
    ----------
    ids : list of str
    law : PressureLaw
    ok : ndarray of bool
    error, lack_of_fit : list of str or None
    kc, kphi : ndarray
        Fitted kc [kN/m^(n+1)] and kphi [kN/m^(n+2)].
    theta : ndarray, shape (P, 4)
        ``(kc', kphi', cc, n)``: primed kc and kphi (``s`` times kc, kphi).
    cov : ndarray, shape (P, 4, 4)
        Linearised sampling covariance of ``theta`` (sandwich, AR(1)).
    phic_lo, phic_hi : ndarray
        The push's phic ridge [deg].
    rmsd, r2_ci, rho : ndarray
        Fit RMSD [kPa], R^2 of CI and AR(1) coefficient.
    ci_mean, npts : ndarray
        Mean CI [kPa] and number of readings of each push.
    residuals : list of (ndarray, ndarray, ndarray, ndarray) or None
        Per push: weighted residuals, depths, Jacobian of the free
        parameters and noise weights (for :func:`site_correlation`).
    """

    ids: list[str]
    law: PressureLaw
    ok: np.ndarray
    error: list[str | None]
    lack_of_fit: list[str | None]
    residuals: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None]
    theta: np.ndarray
    cov: np.ndarray
    npts: np.ndarray
    kc: np.ndarray
    kphi: np.ndarray
    phic_lo: np.ndarray
    phic_hi: np.ndarray
    rmsd: np.ndarray
    r2_ci: np.ndarray
    rho: np.ndarray
    ci_mean: np.ndarray


def ci_error_covariance(
    z: np.ndarray, y: np.ndarray, m: np.ndarray, J: np.ndarray, rho=None, floor: float = 0.0
) -> tuple[np.ndarray, float, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """CI error covariance ``S = sigma^2 W R W`` of one push at its model CI (docs/sites.md).

    Parameters
    ----------
    z, y, m : ndarray
        Depths [m], measured and model CI [kPa].
    J : ndarray, shape (N, k)
        Jacobian of the free parameters.
    rho : float, optional
        AR(1) coefficient; estimated from the residuals when None.
    floor : float
        Smallest sigma^2 [-].

    Returns
    -------
    S : ndarray, shape (N, N)
        [kPa^2]
    rho : float
    parts : (e, z, J, w)
        Weighted residuals, depths, J and the noise weights (RMS 1).
    """
    w = np.sqrt(m * m + (NOISE_FLOOR * np.max(np.abs(m))) ** 2)
    w = w / math.sqrt(np.mean(w * w)) if np.any(w > 0) else np.ones_like(w)
    e = (y - m) / w
    N, k = J.shape
    sigma2 = max(float(e @ e) / max(N - k, 1), floor)
    if rho is None:
        rho = estimate_correlation(e, z, design=J / w[:, None])[0] if k else 0.0
    dz0 = float(np.median(np.diff(z))) if N > 1 else 1.0
    R = rho ** (np.abs(z[:, None] - z[None, :]) / dz0) if rho > 0 else np.eye(N)
    return sigma2 * w[:, None] * R * w[None, :], rho, (e, z, J, w)


def _push_covariance(p: CIProfile, theta, law, bounds: Bounds, ratio, kc, kphi, rho=None):
    """Sandwich covariance of (kc', kphi', cc, n), the model CI, rho and residual parts."""
    z, y = p.depth, p.ci
    kcp, kpp, cc, n = theta
    h = 1e-4
    cols = [
        cone_index_basis(z, n=nn, phic_deg=0.0, law=law, cone=p.cone) for nn in (n, n - h, n + h)
    ]
    (A, B, C), lo, hi = cols
    m = kcp * A + kpp * B + cc * C  # eq. (2-7) with primed kc, kphi
    dn = sum(t * (c1 - c0) for t, c0, c1 in zip((kcp, kpp, cc), lo, hi)) / (2 * h)

    def inside(v, lo_hi):
        a, b = (float(x) for x in lo_hi)
        return a < b and a + 1e-9 * max(abs(b), 1.0) < v < b - 1e-9 * max(abs(b), 1.0)

    free_n = inside(n, bounds.n)
    free_cc = inside(cc, bounds.cc)
    if ratio is not None:
        J = [ratio * A + B, C, dn]
        T = np.array([[0, ratio, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])[:, [1, 2, 3]]
        free = [inside(kphi, bounds.kphi_si(n)), free_cc, free_n]
    else:
        J = [A, B, C, dn]
        T = np.eye(4)
        free = [inside(kc, bounds.kc_si(n)), inside(kphi, bounds.kphi_si(n)), free_cc, free_n]
    free = np.array(free)
    J = np.column_stack(J)[:, free]
    T = T[:, free]
    S, rho, parts = ci_error_covariance(z, y, m, J, rho)
    cov = np.zeros((4, 4))
    if J.shape[1]:
        sc = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
        Js = J / sc
        Gi = np.linalg.pinv(Js.T @ Js, rcond=1e-12)
        cf = (Gi @ Js.T @ S @ Js @ Gi) / np.outer(sc, sc)
        cov = T @ cf @ T.T
    return cov, m, rho, parts


def fit_pushes(profiles: Sequence[CIProfile], problem: Problem | None = None) -> PushFits:
    """Fit each push (exact solver, vectorised per cone) and its sampling covariance.

    Parameters
    ----------
    profiles : sequence of CIProfile
    problem : Problem, optional
        What is fitted (pressure law, bounds with the held values, kc/kphi
        held); fully mobilised shear.

    Returns
    -------
    PushFits
        A profile that fails validation or the solver is marked not ok with
        its reason.
    """
    problem = problem or Problem()
    law, b, ratio = problem.law, problem.fit_bounds, problem.ratio
    P = len(profiles)
    nans = ("kc", "kphi", "phic_lo", "phic_hi", "rmsd", "r2_ci", "rho", "ci_mean")
    out = PushFits(
        [p.id for p in profiles], law, np.zeros(P, bool), [None] * P, [None] * P, [None] * P,
        np.full((P, 4), np.nan), np.full((P, 4, 4), np.nan), np.zeros(P, int),
        **{k: np.full(P, np.nan) for k in nans},
    )  # fmt: skip
    by_cone: dict[str, list[int]] = {}
    for i, p in enumerate(profiles):
        try:
            p.validate()
        except InputError as exc:
            out.error[i] = str(exc)
            continue
        by_cone.setdefault(p.cone.name, []).append(i)
    for idx in by_cone.values():
        zs, ys = [profiles[i].depth for i in idx], [profiles[i].ci for i in idx]
        try:
            sol, th = _solve_primed(zs, ys, profiles[idx[0]].cone, law, b, ratio)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
            for i in idx:
                out.error[i] = f"solver failed: {exc}"
            continue
        for j, i in enumerate(idx):
            p, theta = profiles[i], th[j]
            cov, m, out.rho[i], out.residuals[i] = _push_covariance(
                p, theta, law, b, ratio, sol.kc[j], sol.kphi[j]
            )
            out.ci_mean[i], out.npts[i] = float(np.mean(p.ci)), p.ci.size
            chk = check_fit(p.depth, p.ci, m)
            out.ok[i] = True
            out.kc[i], out.kphi[i] = sol.kc[j], sol.kphi[j]
            out.theta[i], out.cov[i] = theta, cov
            out.phic_lo[i], out.phic_hi[i] = sol.phic_lo[j], sol.phic_hi[j]
            out.rmsd[i] = math.sqrt(float(np.mean((m - p.ci) ** 2)))
            out.r2_ci[i], out.lack_of_fit[i] = chk.r2, chk.lack_of_fit
    return out


def bootstrap_pushes(
    profiles: Sequence[CIProfile],
    fits: PushFits,
    idx: Sequence[int],
    centers: Sequence[np.ndarray],
    b: Bounds,
    ratio: float | None,
    *,
    replicates: int = 40,
    seed: int = 0,
) -> np.ndarray:
    """Parametric bootstrap of the pushes' estimates (step 2 of docs/sites.md).

    Parameters
    ----------
    profiles, fits, idx
        The pushes and their fits (:func:`fit_pushes`); ``idx`` those to resample.
    centers : sequence of ndarray
        Noise-free CI of each push of ``idx`` [kPa] (:func:`site_centers`).
    b, ratio
        Bounds and kc/kphi [m] (None: free) of the refits.
    replicates, seed : int

    Returns
    -------
    ndarray, shape (len(idx), replicates, 4)
        Replicates of ``theta``: each center plus noise of the push's own
        model (weights, sigma, ``fits.rho``), refitted by the exact solver.
    """
    rng = np.random.default_rng(seed)
    B = int(replicates)
    out = np.full((len(idx), B, 4), np.nan)
    by_cone: dict[str, list[int]] = {}
    for k, i in enumerate(idx):
        by_cone.setdefault(profiles[i].cone.name, []).append(k)
    for ks in by_cone.values():
        cone = profiles[idx[ks[0]]].cone
        zs, ys = [], []
        for k in ks:
            i = idx[k]
            e, z, J, w = fits.residuals[i]
            sigma = math.sqrt(float(e @ e) / max(z.size - J.shape[1], 1))
            u = ar1_noise(z, float(np.clip(fits.rho[i], 0.0, RHO_MAX)), rng, size=B)
            sim = np.maximum(centers[k][None, :] + sigma * w[None, :] * u, 0.0)
            zs += [z] * B
            ys += list(sim)
        out[ks] = _solve_primed(zs, ys, cone, fits.law, b, ratio)[1].reshape(len(ks), B, 4)
    return out


def _solve_primed(zs, ys, cone, law, b, ratio):
    """:func:`solve_exact_many` and its primed ``(s kc, s kphi, cc, n)`` (P, 4), eq. (2-6)."""
    sol = solve_exact_many(zs, ys, cone=cone, law=law, bounds=b, kc_over_kphi=ratio)
    s = 1.0 + np.tan(np.radians(sol.phic_deg)) / math.tan(cone.half_angle)
    return sol, np.stack([sol.kc * s, sol.kphi * s, sol.cc, sol.n], -1)


# ---------------------------------------------------------------------------
# pooling per site
# ---------------------------------------------------------------------------


@dataclass
class SitePlate(Written):
    """Site P-S curve of one plate (SI).

    Attributes
    ----------
    radius : float
        Plate radius [m].
    sinkage : ndarray
        [m]
    median, lo, hi : ndarray
        Site median plate pressure and its 90% interval [kPa].
    between_cv : ndarray
        Push-to-push coefficient of variation of the pressure [-]
        (NaN with fewer than two pushes).
    between_cv_lo, between_cv_hi : ndarray
        90% interval of ``between_cv`` (Q-profile).
    naive_cv : ndarray
        Plain sample CV of the per-push pressures [-] (estimation noise
        included, for comparison).
    estimation_cv : ndarray
        RMS estimation CV of one push [-].
    """

    radius: float = quantity("length")
    sinkage: np.ndarray = quantity("length")
    median: np.ndarray = quantity("pressure", finite=True)
    lo: np.ndarray = quantity("pressure", finite=True)
    hi: np.ndarray = quantity("pressure", finite=True)
    between_cv: np.ndarray = quantity("none", finite=True)
    between_cv_lo: np.ndarray = quantity("none", finite=True)
    between_cv_hi: np.ndarray = quantity("none", finite=True)
    naive_cv: np.ndarray = quantity("none", finite=True)
    estimation_cv: np.ndarray = quantity("none", finite=True)


@dataclass
class SiteResult:
    """Pooled terrain of one site (SI inside).

    Attributes
    ----------
    site : str
    profiles : list of str
        Ids of the pushes pooled.
    failed : list of (str, str)
        Pushes of the site that could not be fitted, with the reason.
    params : dict
        Site median kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n, cc [kPa], phic_deg.
    intervals : dict
        90% intervals of the site parameters.
    between : dict
        Push-to-push CV of kc' and kphi' (when positive), SD of n and cc,
        and ``ci_cv``: the push-to-push CV of the pushes' mean CI (the
        measurement itself, no model), for comparison with the plate CV.
    plate_pressure : list of SitePlate
    profiles_needed : int or None
        ``ceil((between_cv / target_cv)^2)`` at the middle sinkage, >= 1.
    profiles_needed_hi : int or None
        The same from the upper end of the 90% interval of between_cv.
    target_cv : float
    middle_sinkage : float
        Sinkage of ``profiles_needed`` [m].
    pushes : list of dict
        Per push: id, n, r2_ci, rmsd [kPa], rho, lack_of_fit.
    lack_of_fit : str or None
        How many pushes the one-layer model does not follow (then the site
        terrain is an average of a misfit, and its intervals are wide).
    notes : list of str
    calibrated : bool or "library"
        Whether a calibration fixed phic, cc and kc/kphi.  Without one the
        site's plate-pressure intervals are set largely by the prior (the
        phic ridge) and are not calibrated (docs/sites.md), and between_cv
        is that of the pushes' strength and n (:func:`shape_pushes`).
        "library": the mixture over a library's calibrations
        (:mod:`terracone.inverse.library.sites`).
    library : LibrarySummary or None
        With a library prior: the candidates' weights and the check (JSON
        ``calibration_weights``, ``outside_library``, ``library``).
    """

    site: str
    profiles: list[str]
    failed: list[tuple[str, str]]
    params: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    between: dict[str, float]
    plate_pressure: list[SitePlate]
    profiles_needed: int | None
    target_cv: float
    middle_sinkage: float
    pushes: list[dict[str, Any]]
    lack_of_fit: str | None
    notes: list[str] = field(default_factory=list)
    model: str = "rm0"
    profiles_needed_hi: int | None = None
    calibrated: bool | str = True
    library: LibrarySummary | None = None

    @property
    def n_profiles(self) -> int:
        return len(self.profiles)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """JSON-ready dict (the ``sites --json`` contract)."""
        units = u.check_system(units)
        n = self.params.get("n", float("nan"))
        # no finite n: the parameters are written unconverted (kc, kphi have no US value)
        in_units = units if np.isfinite(n) else "si"
        return {
            "site": self.site,
            "profiles": list(self.profiles),
            "n_profiles": self.n_profiles,
            "failed": [{"id": i, "error": e} for i, e in self.failed],
            "params": convert_parameters(self.params, in_units, n, finite=True),
            "intervals": convert_parameters(self.intervals, in_units, n, finite=True),
            "between": {k: finite_or_none(v) for k, v in self.between.items()},
            "plate_pressure": [pl.as_dict(units) for pl in self.plate_pressure],
            "profiles_needed": self.profiles_needed,
            "profiles_needed_hi": self.profiles_needed_hi,
            "target_cv": self.target_cv,
            "middle_sinkage": from_si(self.middle_sinkage, "length", units),
            "lack_of_fit": self.lack_of_fit,
            "pushes": [
                {**d, "rmsd": from_si(d["rmsd"], "pressure", units, finite=True)}
                for d in self.pushes
            ],
            "notes": list(self.notes),
            "calibrated": self.calibrated,
            "model": self.model,
            **({} if self.library is None else self.library.as_dict(units)),
            "units": units,
        }


def _ridge_log_s(fits: PushFits, idx: list[int], bounds: Bounds, tan_a: float, notes: list[str]):
    """Equal-probability points of log s over the site's phic ridge, and its phic quantiles."""
    lo = float(np.max(fits.phic_lo[idx]))
    hi = float(np.min(fits.phic_hi[idx]))
    if bounds.phic_deg[0] == bounds.phic_deg[1] or hi - lo < 1e-9:
        if lo > hi + 1e-9:
            notes.append("the pushes' phic ridges do not overlap; phic set from their union")
            lo, hi = float(np.min(fits.phic_lo[idx])), float(np.max(fits.phic_hi[idx]))
        else:
            phi = 0.5 * (lo + hi)
            s = 1.0 + math.tan(math.radians(phi)) / tan_a
            return np.array([math.log(s)]), (phi, phi, phi)
    grid = np.linspace(lo, hi, 2001)
    s = 1.0 + np.tan(np.radians(grid)) / tan_a  # eq. (2-6)
    dens = s**-2.0  # uniform prior on (kc, kphi, phic) marginalised along the ridge
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(grid))])
    cdf /= cdf[-1]
    q = (np.arange(_QGRID) + 0.5) / _QGRID
    phis = np.interp(q, cdf, grid)
    pq = tuple(float(np.interp(a, cdf, grid)) for a in (0.05, 0.5, 0.95))
    return np.log(1.0 + np.tan(np.radians(phis)) / tan_a), pq


def _combine(re, log_s: np.ndarray, log: bool, level: float = 0.9):
    """Median and interval of exp(mu + se T - log s) (log) or (mu + se T)/s, quantile grids."""
    mu, se, df = np.atleast_1d(re.mu), np.atleast_1d(re.se), np.atleast_1d(re.df)
    a = (1 - level) / 2
    if log_s.size == 1:
        tq = np.where(df > 0, stats.t.ppf(1 - a, np.maximum(df, 1)), stats.norm.ppf(1 - a))
        x = np.stack([mu, mu - tq * se, mu + tq * se])
        x = np.exp(x - log_s[0]) if log else x / math.exp(log_s[0])
        return x[0], x[1], x[2]
    q = (np.arange(_QGRID) + 0.5) / _QGRID
    tq = np.where(
        df[:, None] > 0,
        stats.t.ppf(q[None, :], np.maximum(df, 1)[:, None]),
        stats.norm.ppf(q)[None, :],
    )
    x = (mu[:, None] + se[:, None] * tq)[:, :, None]  # (Q, G, 1)
    v = (x - log_s if log else x / np.exp(log_s)).reshape(x.shape[0], -1)
    qs = [np.quantile(v, p, axis=1) for p in (0.5, a, 1 - a)]
    med, lo, hi = (np.exp(q) for q in qs) if log else qs
    return med, lo, hi


def _site_estimates(fits: PushFits, idx: list[int], radii, sinkage, reps=None, shape=None):
    """Per-push estimates (Q, J) and variances of one site: kc, kphi, n, cc, log CI, log p'.

    With bootstrap replicates ``reps`` (len(idx), B, 4) the variances are
    their spread; otherwise the linearised ones.  ``shape`` (the result of
    :func:`shape_pushes`) replaces the plate rows.
    """
    th = fits.theta[idx]
    cov = fits.cov[idx]
    if reps is not None:
        d = reps - reps.mean(1, keepdims=True)
        cov = np.einsum("pbi,pbj->pij", d, d) / max(reps.shape[1] - 1, 1)
    ys, vs, logs = [], [], []
    for j in range(4):
        y, v = th[:, j], cov[:, j, j]
        use_log = j < 2 and bool(np.all(y > 0))
        if use_log:
            y, v = np.log(y), v / (th[:, j] ** 2)
        ys.append(y)
        vs.append(v)
        logs.append(use_log)
    # the measurement itself: log of the push's mean CI; its noise from the fit residuals
    # (lack of fit included), AR(1)-inflated
    rho = np.clip(fits.rho[idx], 0.0, RHO_MAX)
    cm = fits.ci_mean[idx]
    with np.errstate(divide="ignore", invalid="ignore"):
        ys.append(np.log(cm))
        vs.append((fits.rmsd[idx] / cm) ** 2 / fits.npts[idx] * (1 + rho) / (1 - rho))
    plate_rows = []
    for r in radii:  # log p' and its variance, linearised (eq. (2-2) with primed kc, kphi)
        A, B = plate_basis(sinkage[None, :], n=th[:, 3:4], b=r, law=fits.law)
        p = th[:, 0:1] * A + th[:, 1:2] * B
        with np.errstate(divide="ignore", invalid="ignore"):
            lz = np.broadcast_to(np.log(sinkage), p.shape)
            g = np.stack([A / p, B / p, np.zeros_like(p), lz], -1)
            y, v = np.log(p), np.einsum("pki,pij,pkj->pk", g, cov, g)
        if reps is not None:
            A, Bp = plate_basis(sinkage[None, None, :], n=reps[..., 3:4], b=r, law=fits.law)
            p = reps[..., 0:1] * A + reps[..., 1:2] * Bp  # eq. (2-2), primed
            floor = 1e-3 * np.exp(y)[:, None, :]
            v = np.var(np.log(np.maximum(p, floor)), axis=1, ddof=1)
        plate_rows.append((y, v))
    # the push-to-push variation of the plate pressure: from the shape-constrained fits when
    # given (no calibration), else the same rows again
    for y, v in plate_rows + (plate_rows if shape is None else list(zip(*shape))):
        ys += list(y.T)
        vs += list(v.T)
    return np.array(ys), np.array(vs), logs


def _slice(re, i: int):
    """The random-effects results of problem i (first axis)."""
    return type(re)(**{k: getattr(re, k)[i] for k in re.__dataclass_fields__})


def _site_params(re, logs, log_s, phic_q, level: float):
    params, intervals, between = {}, {}, {}
    for j, name in ((0, "kc"), (1, "kphi")):
        med, lo, hi = _combine(_slice(re, slice(j, j + 1)), log_s, logs[j], level)
        params[name], intervals[name] = float(med[0]), (float(lo[0]), float(hi[0]))
        if logs[j]:
            between[f"{name}_cv"] = float(np.sqrt(np.expm1(re.tau2[j])))
    for j, name in ((3, "n"), (2, "cc")):
        params[name] = float(re.mu[j])
        intervals[name] = (float(re.lo[j]), float(re.hi[j]))
        between[f"{name}_sd"] = float(np.sqrt(re.tau2[j]))
    between["ci_cv"] = float(np.sqrt(np.expm1(re.tau2[4])))
    params["phic_deg"] = phic_q[1]
    intervals["phic_deg"] = (phic_q[0], phic_q[2])
    return params, intervals, between


#: Note of a site fitted without a calibration (JSON ``notes``, the table and the report).
UNCALIBRATED_NOTE = (
    "no calibration: the plate-pressure interval is set largely by the prior (phic trades "
    "against the scale of kc and kphi, and the CI does not fix kc, kphi and cc apart), so it is "
    "not a calibrated 90% interval (on generated sites it covered 73-98%); between_cv is the "
    "push-to-push variation of the strength and n that the CI fixes, with the site's kc/kphi "
    "ratio and cc (a variation of those is not seen); give a calibration for calibrated figures"
)


def _pool_site(
    name, idx, failed, fits, bounds, tan_a, radii, sinkage, target_cv, level, model, pooled,
    calibrated=True,
):  # fmt: skip
    """SiteResult of one site from its pooled estimates ``pooled = (RandomEffects, logs)``."""
    notes: list[str] = [] if calibrated else [UNCALIBRATED_NOTE]
    if not idx:
        return SiteResult(
            name, [], failed, {}, {}, {}, [], None, target_cv, 0.0, [], None,
            ["no push of this site could be fitted"], model, None, calibrated,
        )  # fmt: skip
    if len(idx) == 1:
        notes.append("one push: push-to-push variation cannot be estimated")
    log_s, phic_q = _ridge_log_s(fits, idx, bounds, tan_a, notes)
    if log_s.size > 1:
        notes.append(
            f"phic not fixed: site scale on the phic ridge {phic_q[0]:.3g}-{phic_q[2]:.3g} deg "
            "(90%); give a calibration to fix it"
        )
    re, logs = pooled
    params, intervals, between = _site_params(re, logs, log_s, phic_q, level)
    plates = []
    mid = sinkage.size // 2
    K = sinkage.size
    for ir, r in enumerate(radii):
        rs = _slice(re, slice(5 + ir * K, 5 + (ir + 1) * K))  # one problem per sinkage
        med, lo, hi = _combine(rs, log_s, True, level)
        off = 5 + (len(radii) + ir) * K
        re_r = _slice(re, slice(off, off + K))  # push-to-push variation (docs/sites.md, 5.)
        cvs = (re_r.tau2, re_r.tau2_lo, re_r.tau2_hi, re_r.sample_var, re_r.mean_v)
        plates.append(SitePlate(r, sinkage, med, lo, hi, *(np.sqrt(np.expm1(v)) for v in cvs)))
    needed = needed_hi = None
    cv_mid = plates[0].between_cv[mid] if plates else float("nan")
    if np.isfinite(cv_mid) and cv_mid > 2 * between["ci_cv"] + 0.1:
        notes.append(
            f"the plate-pressure CV ({cv_mid:.2g}) is well above the push-to-push CV of the CI "
            f"itself ({between['ci_cv']:.2g}): the pushes' fits, not only the soil, differ "
            "(parameters the CI does not fix, or lack of fit); profiles_needed is then not a "
            "sampling target"
        )
    if plates and np.isfinite(plates[0].between_cv[mid]):
        needed = pushes_needed(plates[0].between_cv[mid], target_cv)
        needed_hi = pushes_needed(plates[0].between_cv_hi[mid], target_cv)
        if plates[0].estimation_cv[mid] > plates[0].between_cv_hi[mid]:
            notes.append(
                "the estimation noise of one push exceeds the between-push CV it allows: "
                "the push-to-push variation is not resolved (see between_cv_hi)"
            )
    pushes = [
        {
            "id": fits.ids[i],
            "n": float(fits.theta[i, 3]),
            "r2_ci": finite_or_none(fits.r2_ci[i]),
            "rmsd": float(fits.rmsd[i]),
            "rho": float(fits.rho[i]),
            "lack_of_fit": fits.lack_of_fit[i],
        }
        for i in idx
    ]
    bad = [d for d in pushes if d["lack_of_fit"]]
    lof = None
    if bad:
        lof = (
            f"{len(bad)} of {len(idx)} pushes do not follow the one-layer model "
            f"(median R2 of CI {np.nanmedian([d['r2_ci'] or np.nan for d in pushes]):.2f}); "
            "the site terrain averages a misfit and its intervals carry it"
        )
    return SiteResult(
        name, [fits.ids[i] for i in idx], failed, params, intervals, between, plates, needed,
        target_cv, float(sinkage[mid]), pushes, lof, notes, model, needed_hi, calibrated,
    )  # fmt: skip


def site_correlation(
    parts: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
) -> float:
    """AR(1) coefficient of the CI error pooled over the pushes of a site.

    The pooled lag-1 autocorrelation ``r1 = sum_j e_j' D e_j / sum_j e_j' e_j``
    is matched to its expectation
    ``sum_j tr(D M_j S_j(rho) M_j') / sum_j tr(M_j S_j(rho) M_j')``, clipped to
    [0, 0.95], with ``M_j = C W^-1 (I - J J^+) W`` (the correction of
    :func:`terracone.inverse.uncertainty.noise.estimate_correlation`).

    Parameters
    ----------
    parts : sequence of (e, z, J, w)
        Weighted residuals [-], depths [m], Jacobian of the free parameters
        and noise weights [-] per push.
    """
    grid = np.linspace(0.0, 0.95, 96)
    num = den = 0.0
    f_num = np.zeros(grid.size)
    f_den = np.zeros(grid.size)
    for e, z, J, w in parts:
        N = e.size
        if N < 4:
            continue
        e = e - e.mean()
        num += float(e[1:] @ e[:-1])
        den += float(e @ e)
        # e = C W^-1 (I - J J^+) W u with u white: the solver is unweighted least squares
        H = J @ np.linalg.pinv(J, rcond=1e-10) if J.size else np.zeros((N, N))
        M = (np.eye(N) - 1.0 / N) @ ((np.eye(N) - H) * (w[None, :] / w[:, None]))
        lag = np.abs(z[:, None] - z[None, :]) / float(np.median(np.diff(z)))
        S = grid[:, None, None] ** lag[None] + (grid[:, None, None] == 0) * np.eye(N)
        MSM = M[None] @ S @ M.T[None]
        f_num += np.trace(MSM, offset=1, axis1=1, axis2=2)
        f_den += np.trace(MSM, axis1=1, axis2=2)
    if den <= 0:
        return 0.0
    r1 = num / den
    f = np.maximum.accumulate(f_num / f_den)
    if r1 <= f[0]:
        return 0.0
    if r1 >= f[-1]:
        return float(grid[-1])
    return float(np.interp(r1, f, grid))


def pushes_needed(between_cv: float, target_cv: float) -> int | None:
    """Pushes for the site-mean CV to reach the target: ceil((cv / target)^2), at least 1."""
    if not math.isfinite(between_cv):
        return None
    return max(1, math.ceil((between_cv / target_cv) ** 2 - 1e-9))


def site_terrain(
    profiles: Sequence[CIProfile], fits: PushFits, idx: Sequence[int], law, bounds, ratio
) -> tuple[np.ndarray, np.ndarray]:
    """One fit of all the site's pushes together: primed ``(kc', kphi', cc, n)`` and strengths.

    Each push is divided by its strength factor ``g`` (its mean CI over the
    geometric mean of the site's) before the joint fit of eq. (2-7).

    Returns
    -------
    theta : ndarray, shape (4,)
        ``(kc', kphi', cc, n)`` of the site terrain (primed: times ``s``).
    g : ndarray
        The pushes' strength factors [-].
    """
    cm = fits.ci_mean[list(idx)]
    g = cm / np.exp(np.mean(np.log(cm)))
    z = np.concatenate([profiles[i].depth for i in idx])
    y = np.concatenate([profiles[i].ci / gk for i, gk in zip(idx, g)])
    o = np.argsort(z, kind="stable")
    return _solve_primed([z[o]], [y[o]], profiles[idx[0]].cone, law, bounds, ratio)[1][0], g


def site_centers(
    profiles: Sequence[CIProfile],
    idx: Sequence[int],
    law: PressureLaw,
    terrain: tuple[np.ndarray, np.ndarray],
) -> list[np.ndarray]:
    """Each push's CI as the site terrain predicts it, scaled to the push's mean CI.

    Parameters
    ----------
    profiles, idx
        The site's pushes.
    law : PressureLaw
    terrain : (theta, g)
        The site terrain and the pushes' strength factors (:func:`site_terrain`).

    Returns
    -------
    list of ndarray
        The terrain's CI at each push's depths times its strength factor [kPa].
    """
    theta, g = terrain
    cone = profiles[idx[0]].cone
    out = []
    for i, gk in zip(idx, g):
        A, B, C = cone_index_basis(profiles[i].depth, n=theta[3], phic_deg=0.0, law=law, cone=cone)
        out.append(gk * (theta[0] * A + theta[1] * B + theta[2] * C))  # eq. (2-7), primed
    return out


#: Grid of n for the shape-constrained push fits (:func:`shape_pushes`).
_SHAPE_N = np.round(np.arange(0.05, 2.0001, 0.005), 6)


def _shape_fit(M: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of y (R, N) by g M(n) (G, N) over the n grid: (log g, n) per row."""
    Mw, yw = M / w, y / w
    mm = np.einsum("gn,gn->g", Mw, Mw)
    my = yw @ Mw.T  # (R, G)
    sse = np.einsum("rn,rn->r", yw, yw)[:, None] - my * my / mm[None, :]
    k = np.clip(np.argmin(sse, axis=1), 1, _SHAPE_N.size - 2)
    r = np.arange(y.shape[0])
    a, b, c = sse[r, k - 1], sse[r, k], sse[r, k + 1]
    den = a - 2 * b + c
    step = np.where(den > 0, 0.5 * (a - c) / np.where(den > 0, den, 1.0), 0.0)
    step = np.clip(step, -1.0, 1.0)  # parabolic refinement between grid points
    h = _SHAPE_N[1] - _SHAPE_N[0]
    n = _SHAPE_N[k] + step * h
    gg = my / mm[None, :]  # the best g at each n of the grid
    k2 = np.where(step >= 0, k + 1, k - 1)
    g = gg[r, k] + np.abs(step) * (gg[r, k2] - gg[r, k])
    return np.log(np.maximum(g, 1e-12)), n


def shape_pushes(
    profiles: Sequence[CIProfile],
    fits: PushFits,
    idx: Sequence[int],
    theta: np.ndarray,
    radii: Sequence[float],
    sinkage: np.ndarray,
    *,
    replicates: int = 40,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Plate pressures of the pushes from what the CI fixes without a calibration.

    Each push is fitted as ``g M(z; n)``, ``M`` the site terrain's CI
    (``theta``, :func:`site_terrain`), and its primed plate pressure is
    ``g (kc'/b + kphi') z^n`` (eq. (2-2)); the variance is a parametric
    bootstrap of that fit (step 5 of docs/sites.md).

    Parameters
    ----------
    profiles, fits, idx
        The pushes, their fits (:func:`fit_pushes`) and the site's indices.
    theta : ndarray
        The site terrain's primed ``(kc', kphi', cc, n)``.
    radii : sequence of float
        Plate radii [m].
    sinkage : ndarray
        [m]
    replicates : int
    rng : numpy.random.Generator, optional

    Returns
    -------
    y, v : ndarray, shape (len(radii), len(idx), len(sinkage))
        log p' [log kPa] of each push and its estimation variance.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    cone = profiles[idx[0]].cone
    law = fits.law
    R, K = len(radii), sinkage.size
    y, v = np.empty((2, R, len(idx), K))
    pb = [plate_basis(sinkage[None, :], n=_SHAPE_N[:, None], b=r, law=law) for r in radii]
    plate = np.stack([theta[0] * A + theta[1] * B for A, B in pb])  # (R, G, K), eq. (2-2)
    for j, i in enumerate(idx):
        z, ci = profiles[i].depth, profiles[i].ci
        A, B, C = cone_index_basis(z, n=_SHAPE_N[:, None], phic_deg=0.0, law=law, cone=cone)
        M = np.broadcast_to(theta[0] * A + theta[1] * B + theta[2] * C, (_SHAPE_N.size, z.size))
        w = fits.residuals[i][3]
        lg, n = _shape_fit(M, ci[None, :], w)
        m = np.exp(lg[0]) * _interp_rows(M, n)[0]
        e = (ci - m) / w
        sigma = math.sqrt(float(e @ e) / max(z.size - 2, 1))
        u = ar1_noise(z, float(np.clip(fits.rho[i], 0.0, RHO_MAX)), rng, size=replicates)
        lgb, nb = _shape_fit(M, np.maximum(m[None, :] + sigma * w[None, :] * u, 0.0), w)
        for ir in range(R):
            lp = np.log(np.maximum(_interp_rows(plate[ir], np.concatenate([n, nb])), 1e-300))
            lp = lp + np.concatenate([lg, lgb])[:, None]
            y[ir, j], v[ir, j] = lp[0], np.var(lp[1:], axis=0, ddof=1)
    return y, v


def _interp_rows(table: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Linear interpolation of table (G, K) over the n grid at n (P,): (P, K)."""
    h = _SHAPE_N[1] - _SHAPE_N[0]
    k = np.clip(((n - _SHAPE_N[0]) / h).astype(np.int64), 0, _SHAPE_N.size - 2)
    f = ((n - _SHAPE_N[k]) / h)[:, None]
    return table[k] * (1 - f) + table[k + 1] * f


def _pool_all(fits: PushFits, members_ok, reps, plates, sinkage, level, shapes):
    """Per-site estimates and one random-effects call over (site, quantity, push), padded."""
    est = [
        _site_estimates(fits, idx, plates, sinkage, reps[k], shapes[k]) if idx else None
        for k, idx in enumerate(members_ok)
    ]
    Q = 5 + 2 * len(plates) * sinkage.size
    J = max([len(i) for i in members_ok] + [1])
    Y = np.zeros((len(est), Q, J))
    V = np.ones((len(est), Q, J))
    M = np.zeros((len(est), Q, J), bool)
    for k, e in enumerate(est):
        if e is not None:
            n_k = e[0].shape[1]
            Y[k, :, :n_k], V[k, :, :n_k], M[k, :, :n_k] = e[0], e[1], True
    return est, random_effects(Y, V, M, level=level)


def _site_covariances(
    profiles: Sequence[CIProfile], grouping: Grouping, fits: PushFits, b: Bounds, ratio
) -> list[list[int]]:
    """The fitted pushes of each site; sets their covariance under the site's one
    noise correlation (from all its pushes' residuals).  Returns their indices."""
    members_ok = []
    for members in grouping.sites.values():
        idx = [i for i in members if fits.ok[i]]
        if len(idx) > 1:
            rho = site_correlation([fits.residuals[i] for i in idx])
            for i in idx:
                fits.cov[i] = _push_covariance(
                    profiles[i], fits.theta[i], fits.law, b, ratio, fits.kc[i], fits.kphi[i], rho
                )[0]
                fits.rho[i] = rho
        members_ok.append(idx)
    return members_ok


def _bootstrap_sites(
    profiles: Sequence[CIProfile],
    fits: PushFits,
    members_ok: list[list[int]],
    b: Bounds,
    ratio: float | None,
    calibrated: bool,
    plates: list[float],
    sinkage: np.ndarray,
    bootstrap: int,
    seed: int,
) -> tuple[list[np.ndarray | None], list[tuple[np.ndarray, np.ndarray] | None]]:
    """Bootstrap replicates of each site's pushes (``reps``) and, without a
    calibration, the plate rows of what the CI fixes (``shapes``), per site."""
    shapes: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(members_ok)
    rng = np.random.default_rng([seed, 1])
    centers = []
    for k, idx in enumerate(members_ok):
        if len(idx) > 1:
            terrain = site_terrain(profiles, fits, idx, fits.law, b, ratio)
            centers += site_centers(profiles, idx, fits.law, terrain)
            if not calibrated:  # plate rows from what the CI fixes (shape_pushes)
                shapes[k] = shape_pushes(
                    profiles, fits, idx, terrain[0], plates, sinkage, replicates=bootstrap, rng=rng
                )
        elif idx:  # one push: its own fitted CI
            e, _, _, w = fits.residuals[idx[0]]
            centers.append(profiles[idx[0]].ci - e * w)
    flat = [i for idx in members_ok for i in idx]
    allr = bootstrap_pushes(
        profiles, fits, flat, centers, b, ratio, replicates=bootstrap, seed=seed
    )
    ends = np.cumsum([len(idx) for idx in members_ok])
    return [allr[e - len(idx) : e] for e, idx in zip(ends, members_ok)], shapes


def fit_sites(
    profiles: Sequence[CIProfile],
    grouping: Grouping,
    problem: Problem | None = None,
    *,
    plates: Sequence[float] = (0.0375, 0.05),
    sinkage: np.ndarray | None = None,
    target_cv: float = 0.1,
    level: float = 0.9,
    bootstrap: int | None = None,
    seed: int = 0,
) -> list[SiteResult]:
    """Pooled hierarchical fit of every site (see the module docstring).

    Parameters
    ----------
    profiles : sequence of CIProfile
    grouping : Grouping
        From :func:`group_profiles`.
    problem : Problem, optional
        What is fitted, as for :func:`terracone.inverse.predict` (a
        calibration's values held in every push).  With a library
        (:class:`~terracone.inverse.problem.LibraryPrior`) each site is the
        mixture over the library's calibrations, weighed by the site's
        evidence (:func:`terracone.inverse.library.sites.library_sites`).
    plates : sequence of float
        Plate radii of the site P-S curves [m].
    sinkage : ndarray, optional
        Sinkages [m] (> 0); :func:`default_sinkages` by default.
    target_cv : float
        Target CV of the site-mean plate pressure for ``profiles_needed`` [-].
    level : float
        Level of the site intervals (0.9).
    bootstrap : int, optional
        Replicates of the parametric bootstrap of each push's estimation
        noise (:func:`bootstrap_pushes`); 0: the linearised covariance.
        Default: 40 without a calibration (the CI alone leaves kc, kphi, cc
        nearly collinear and at bounds, where the linearisation fails), 0
        with one.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    list of SiteResult
        In the order of the grouping.
    """
    if not (target_cv > 0):
        raise ValueError(f"target CV must be > 0 (got {target_cv})")
    sinkage = default_sinkages() if sinkage is None else np.asarray(sinkage, float)
    if np.any(sinkage <= 0):
        raise ValueError("site sinkages must be > 0")
    problem = problem or Problem()
    if problem.library is not None:  # each candidate's pooling, mixed by the site's evidence
        kw = dict(plates=plates, sinkage=sinkage, target_cv=target_cv, level=level,
                  bootstrap=bootstrap, seed=seed)  # fmt: skip
        return library_sites(profiles, grouping, problem, fit_sites, **kw)
    b, ratio, model = problem.fit_bounds, problem.ratio, problem.model
    fits = fit_pushes(profiles, problem)
    members_ok = _site_covariances(profiles, grouping, fits, b, ratio)
    calibrated = problem.calibrated
    if bootstrap is None:
        bootstrap = 0 if calibrated else 40
    reps: list[np.ndarray | None] = [None] * len(members_ok)
    shapes: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(members_ok)
    if bootstrap:
        reps, shapes = _bootstrap_sites(
            profiles, fits, members_ok, b, ratio, calibrated, list(plates), sinkage, bootstrap, seed
        )
    est, re_all = _pool_all(fits, members_ok, reps, list(plates), sinkage, level, shapes)
    out = []
    for k, (name, members) in enumerate(grouping.sites.items()):
        idx = members_ok[k]
        failed = [(fits.ids[i], str(fits.error[i])) for i in members if not fits.ok[i]]
        tan_a = math.tan(profiles[members[0]].cone.half_angle)
        pooled = (_slice(re_all, k), est[k][2] if est[k] is not None else None)
        site = _pool_site(
            name, idx, failed, fits, b, tan_a, list(plates), sinkage, target_cv, level, model,
            pooled, calibrated,
        )  # fmt: skip
        site.notes[:0] = problem.notes_for(profiles[members[0]].cone.name)
        out.append(site)
    return out


# ---------------------------------------------------------------------------
# the whole workflow of ``terracone sites``
# ---------------------------------------------------------------------------


@dataclass
class SiteStatistics:
    """Profiles read, grouped into sites and pooled per site.

    Attributes
    ----------
    sites : list of SiteResult
        In the order of the grouping.
    grouping : Grouping
        Which profiles make each site, and those that are in none.
    errors : list of InputError
        Profiles the reader could not use (not grouped, not fitted).
    """

    sites: list[SiteResult]
    grouping: Grouping
    errors: list[InputError]

    @property
    def fitted_any(self) -> bool:
        """Whether any site has a fitted push."""
        return any(r.profiles for r in self.sites)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``sites``, ``unassigned`` and ``errors`` of ``terracone sites --json``."""
        return {
            "sites": [r.as_dict(units) for r in self.sites],
            "unassigned": [{"id": i, "reason": why} for i, why in self.grouping.unassigned],
            "errors": [str(e) for e in self.errors],
        }


def site_statistics(
    items: Sequence[CIProfile | InputError],
    problem: Problem | None = None,
    *,
    by: str | None = None,
    radius: float | None = None,
    source: str = "input",
    **fit: Any,
) -> SiteStatistics:
    """Group profiles into sites and pool each site (:func:`group_profiles`, :func:`fit_sites`).

    Parameters
    ----------
    items : sequence of CIProfile or InputError
        As a reader returns them with ``on_error="collect"``; the errors are
        kept, not fitted.
    problem : Problem, optional
        What is fitted (:func:`fit_sites`).
    by, radius
        Site grouping: metadata column(s), or a distance [m].
    source : str
        Name of the input, for the error message.
    **fit
        Keywords of :func:`fit_sites` (plates, sinkage, target_cv, bootstrap,
        seed, level).

    Returns
    -------
    SiteStatistics

    Raises
    ------
    ValueError
        No profile could be put in a site (the first reason is given).
    """
    profiles = [it for it in items if not isinstance(it, InputError)]
    errors = [it for it in items if isinstance(it, InputError)]
    grouping = group_profiles(profiles, by=by, radius=radius)
    if not grouping.sites:
        why = f" ({grouping.unassigned[0][1]})" if grouping.unassigned else ""
        raise ValueError(f"{source}: no profile could be put in a site{why}")
    return SiteStatistics(fit_sites(profiles, grouping, problem, **fit), grouping, errors)

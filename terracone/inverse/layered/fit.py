"""Layered terrain, inverse side: fit a stack of layers to one CI profile.

The forward model (:func:`terracone.physics.layers.layered_basis`,
:func:`terracone.physics.layers.layered_cone_index`) extends eqs. (2-5) and (2-6) of
[1]_ to a stack of layers with their own kc_j, kphi_j, n_j, cc_j and a common
phic.  This module fits it: :func:`fit_layered` searches the layers' n and
the interface depths (the linear parameters by bounded least squares), and
:func:`layered_posterior` samples the posterior of the fit with emcee.

Models with one and two (or more) layers are compared by the Bayesian
information criterion BIC = N ln(SSE/N) + k ln N, with k = 4 per layer (kc,
kphi, n, cc) plus one per interface (phic is not counted: it trades exactly
with the scale of the k's).

These names were in :mod:`terracone.physics.layers` and :mod:`terracone.uncertainty`
before the forward and inverse modules were put apart (issue 13); both still
re-export them.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
.. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013). emcee:
   the MCMC hammer. PASP 125, 306-312.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import emcee
import numpy as np
from scipy.optimize import lsq_linear, minimize, nnls

from terracone.data import CIProfile, InputError, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.exact import design, solve_exact
from terracone.inverse.uncertainty.posterior import LABELS, identifiability_label
from terracone.physics import units as u
from terracone.physics.cone import normal_integrals
from terracone.physics.layers import layered_basis
from terracone.physics.metrics import check_fit
from terracone.physics.plate import PressureLaw, pressure_law

__all__ = ["LayeredPosterior", "LayeredResult", "fit_layered", "layered_posterior"]


@dataclass
class LayeredResult:
    """Fit of a layered model to one profile (SI).

    Attributes
    ----------
    layers : list of TerrainParameters
        Parameters of each layer, top first.
    interfaces : list of float
        Depths of the layer boundaries [m].
    rmsd : float
        [kPa]
    bic : float
        Bayesian information criterion of this fit.
    bic_single : float
        BIC of the one-layer fit of the same data.
    preferred_layers : int
        Number of layers with the lower BIC.
    r2_ci, longest_run, lack_of_fit
        As in :class:`terracone.inverse.PredictionResult`.
    phic_range : (float, float)
        Interval of the common phic that fits equally well [deg].
    """

    id: str
    status: str
    error: str | None = None
    layers: list[TerrainParameters] = field(default_factory=list)
    interfaces: list[float] = field(default_factory=list)
    rmsd: float = float("nan")
    sse: float = float("nan")
    bic: float = float("nan")
    bic_single: float = float("nan")
    preferred_layers: int = 1
    r2_ci: float = float("nan")
    longest_run: int = 0
    lack_of_fit: str | None = None
    phic_range: tuple[float, float] | None = None
    depth: np.ndarray | None = None
    ci: np.ndarray | None = None
    ci_model: np.ndarray | None = None
    ci_model_single: np.ndarray | None = None
    time_s: float = 0.0
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def _repr_html_(self) -> str:
        """A table of the layers (SI) and the BIC comparison, for Jupyter."""
        from terracone.notebook import layered_html

        return layered_html(self)

    def as_dict(self, units: str = "si", *, curves: bool = True) -> dict[str, Any]:
        units = u.check_system(units)
        d: dict[str, Any] = {"id": self.id, "status": self.status, "error": self.error}
        if not self.ok:
            return d
        d.update(
            {
                "layers": [p.as_dict(units) for p in self.layers],
                "interfaces": [float(v) for v in u.length_from_si(self.interfaces, units)],
                "rmsd": float(u.pressure_from_si(self.rmsd, units)),
                "r2_ci": self.r2_ci,
                "longest_run": self.longest_run,
                "lack_of_fit": self.lack_of_fit,
                "bic": self.bic,
                "bic_single": self.bic_single,
                "preferred_layers": self.preferred_layers,
                "phic_range_deg": list(self.phic_range) if self.phic_range else None,
                "units": units,
                "undetermined": ["phic", "phic~scale(kc,kphi)"],
                "metadata": self.metadata,
            }
        )
        if curves:
            d["depth"] = [float(v) for v in u.length_from_si(self.depth, units)]
            d["ci"] = [float(v) for v in u.pressure_from_si(self.ci, units)]
            d["ci_model"] = [float(v) for v in u.pressure_from_si(self.ci_model, units)]
        return d


def _bic(sse: float, N: int, k: int) -> float:
    return N * math.log(max(sse, 1e-300) / N) + k * math.log(N)


def _box_lsq(
    X: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, float]:
    """min |Xx - y|^2 over lo <= x <= hi; NNLS fast path when lo = 0 and hi does not bind."""
    scale = np.sqrt(np.sum(X * X, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    Xs = X / scale
    if np.all(lo == 0):
        x = _nnls_capped(X, Xs, y, hi, scale)
        if x is not None:
            r = X @ x - y
            return x, float(r @ r)
    res = lsq_linear(Xs, y, bounds=(lo * scale, hi * scale), method="bvls")
    x = res.x / scale
    r = X @ x - y
    return x, float(r @ r)


def _nnls_capped(
    X: np.ndarray, Xs: np.ndarray, y: np.ndarray, hi: np.ndarray, scale: np.ndarray
) -> np.ndarray | None:
    """min |Xx - y|^2 over 0 <= x <= hi by NNLS, holding at hi what NNLS pushes above it.

    Each round fixes the variables above their upper bound at it and solves
    NNLS for the rest.  The problem is convex, so the result is its global
    minimum exactly when it satisfies the KKT conditions (gradient zero
    inside, pointing out of the box at held bounds; tolerance 1e-9 |X_i| |r|);
    None when it does not (the caller uses BVLS).
    """
    k = X.shape[1]
    at_hi = np.zeros(k, dtype=bool)
    x = np.zeros(k)
    for _ in range(k + 1):
        free = ~at_hi
        x[at_hi] = hi[at_hi]
        if not free.any():  # every variable at its cap (scipy's nnls aborts on no columns)
            break
        rhs = y - X[:, at_hi] @ hi[at_hi]
        xs, _ = nnls(Xs[:, free], rhs, maxiter=50 * k)
        x[free] = xs / scale[free]
        over = free & (x > hi * (1 + 1e-12))
        if not over.any():
            break
        at_hi |= over
    else:
        return None
    x = np.minimum(x, hi)
    r = X @ x - y
    g = X.T @ r
    tol = 1e-9 * scale * math.sqrt(float(r @ r) + 1e-300)
    inside = (x > 0) & (x < hi)
    kkt = np.all(np.abs(g[inside]) <= tol[inside])
    kkt &= np.all(g[(x <= 0) & ~inside] >= -tol[(x <= 0) & ~inside])
    kkt &= np.all(g[(x >= hi) & ~inside] <= tol[(x >= hi) & ~inside])
    return x if kkt else None


def _layer_box(bounds: Bounds, ns: Any) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of (kc, kphi, cc) of every layer, in SI, for the n's ``ns``."""
    lo, hi = [], []
    for nj in ns:
        klo, khi = bounds.kc_si(nj)
        plo, phi_ = bounds.kphi_si(nj)
        lo += [float(klo), float(plo), bounds.cc[0]]
        hi += [float(khi), float(phi_), bounds.cc[1]]
    return np.array(lo), np.array(hi)


def _search_layers(
    profile: CIProfile,
    layers: int,
    bounds: Bounds,
    law: Any,
    phi: float,
    min_thick: float,
    n_grid: int,
    solve: Any,
) -> tuple[np.ndarray, np.ndarray] | LayeredResult:
    """Each layer's n and the interfaces of the best layered fit (two or more layers).

    Two layers: a grid over (n_1, n_2) and the interface (midpoints between measured
    depths), a bounded linear least squares per cell, then Nelder-Mead from the best
    cell.  More layers: Nelder-Mead from six seeded random starts.  A profile too short
    for the minimum thickness gives an error result.
    """
    z, y, cone = profile.depth, profile.ci, profile.cone
    lo_d, hi_d = z[0] + min_thick, z[-1] - min_thick
    cands = 0.5 * (z[1:] + z[:-1])
    cands = cands[(cands >= lo_d) & (cands <= hi_d)]
    if cands.size == 0:
        return LayeredResult(
            profile.id,
            "error",
            "profile too short for the minimum layer thickness",
            metadata=dict(profile.metadata),
        )
    nlo, nhi = bounds.n
    ng = np.linspace(nlo, nhi, n_grid)

    def objective(v):
        ns = np.clip(v[:layers], nlo, nhi)
        D = np.sort(np.clip(v[layers:], lo_d, hi_d))
        if np.any(np.diff(np.concatenate([[z[0]], D, [z[-1]]])) < min_thick * 0.5):
            return np.inf
        return solve(ns, D)[1]

    starts = []
    if layers == 2:
        best = (np.inf, None)
        # columns of the layer above and below each candidate interface, per n
        cols = {
            (i, k): layered_basis(z, n=[ni, ni], interfaces=[d], phic=phi, law=law, cone=cone)
            for i, ni in enumerate(ng)
            for k, d in enumerate(cands)
        }
        for k, d in enumerate(cands):
            for i, n1 in enumerate(ng):
                for j, n2 in enumerate(ng):
                    X = np.concatenate([cols[i, k][:, :3], cols[j, k][:, 3:]], axis=1)
                    lo, hi = _layer_box(bounds, [n1, n2])
                    f = _box_lsq(X, y, lo, hi)[1]
                    if f < best[0]:
                        best = (f, np.array([n1, n2, d]))
        starts.append(best[1])
    else:
        rng = np.random.default_rng(0)
        for _ in range(6):
            starts.append(
                np.concatenate(
                    [
                        rng.uniform(0.3, 1.2, layers),
                        np.sort(rng.uniform(lo_d, hi_d, layers - 1)),
                    ]
                )
            )
    best_v, best_f = None, np.inf
    for v0 in starts:
        f0 = objective(v0)
        # tolerance relative to the SSE: an absolute one never fires on large SSE values
        res = minimize(
            objective,
            v0,
            method="Nelder-Mead",
            options={"xatol": 1e-6, "fatol": 1e-10 * max(f0, 1e-300), "maxiter": 2000},
        )
        v, f = (res.x, res.fun) if res.fun <= f0 else (v0, f0)
        if f < best_f:
            best_v, best_f = v, f
    return np.clip(best_v[:layers], nlo, nhi), np.sort(np.clip(best_v[layers:], lo_d, hi_d))


def _phic_ridge_layers(
    x: np.ndarray, ns_best: np.ndarray, bounds: Bounds, cone: Any
) -> tuple[float, float, float, float]:
    """The interval of phic that fits equally well over all layers, and its middle.

    The fit is made at phic's upper bound; every layer's scaled kc and kphi must stay in
    its box (the nested-box argument of :mod:`terracone.inverse.solver.many`).  Returns
    (phic_lo, phic_mid, s_hi, s_mid), s = 1 + tan(phic)/tan(alpha) (eqs. (2-6), (2-7)).
    """
    phi = bounds.phic[1]
    # phic ridge over all layers: the scaled k's must fit every layer's box
    tt = math.tan(cone.half_angle)
    s_hi = 1.0 + math.tan(math.radians(phi)) / tt
    need = 1.0 + math.tan(math.radians(bounds.phic[0])) / tt
    for j, nj in enumerate(ns_best):
        khi = float(bounds.kc_si(nj)[1])
        phi_hi = float(bounds.kphi_si(nj)[1])
        kc_p, kp_p = x[3 * j] * s_hi, x[3 * j + 1] * s_hi
        if khi > 0:
            need = max(need, kc_p / khi)
        if phi_hi > 0:
            need = max(need, kp_p / phi_hi)
    ph_lo = float(np.clip(math.degrees(math.atan((need - 1.0) * tt)), bounds.phic[0], phi))
    ph = 0.5 * (ph_lo + phi) if bounds.phic[0] != bounds.phic[1] else phi
    s_mid = 1.0 + math.tan(math.radians(ph)) / tt
    return ph_lo, ph, s_hi, s_mid


def fit_layered(
    profile: CIProfile,
    *,
    layers: int = 2,
    model: str = "rm0",
    r_min: float | None = None,
    bounds: Bounds | None = None,
    n_grid: int = 12,
    min_thickness: float | None = None,
) -> LayeredResult:
    """Fit a model of ``layers`` layers (interfaces fitted) to one CI profile.

    Parameters
    ----------
    profile : CIProfile
    layers : int
        Number of layers (1 gives the homogeneous model, for comparison).
    model, r_min
        Pressure law (section 3.2).
    bounds : Bounds
        Bounds of each layer's kc, kphi, n, cc, and of the common phic.
    n_grid : int
        Grid over each layer's n in the global stage (two layers).
    min_thickness : float, optional
        Smallest layer thickness [m]; default: two depth steps.

    Notes
    -----
    Global stage for two layers: a grid over (n_1, n_2) and the interface
    depth (midpoints between measured depths); for each cell a bounded
    linear least squares in the six linear parameters.  Then Nelder-Mead
    over the n's and interfaces from the best cell.  With more layers,
    Nelder-Mead from several starts.  phic is put at the upper bound and
    its equally good interval reported (the nested-box argument of
    :mod:`terracone.inverse.solver.many`, which needs zero lower bounds of kc and
    kphi).
    """
    t0 = time.perf_counter()
    bounds = bounds or Bounds()
    try:
        profile.validate(min_points=max(3, 4 * layers + layers))
    except InputError as exc:
        return LayeredResult(profile.id, "error", str(exc), metadata=dict(profile.metadata))
    law = pressure_law(model, r_min=r_min)
    cone = profile.cone
    z, y = profile.depth, profile.ci
    phi = bounds.phic[1]
    step = float(np.median(np.diff(z)))
    min_thick = min_thickness if min_thickness is not None else 2 * step

    def solve(ns, D):
        X = layered_basis(z, n=ns, interfaces=D, phic=phi, law=law, cone=cone)
        lo, hi = _layer_box(bounds, ns)
        return _box_lsq(X, y, lo, hi)

    single = solve_exact(z, y, cone=cone, law=law, bounds=bounds, profiles=False)
    if layers == 1:
        ns_best, D_best = np.array([single.n]), np.array([])
    else:
        found = _search_layers(profile, layers, bounds, law, phi, min_thick, n_grid, solve)
        if isinstance(found, LayeredResult):
            return found
        ns_best, D_best = found
    x, sse = solve(ns_best, D_best)
    res = _layered_result(profile, x, sse, ns_best, D_best, single, bounds, law, model, r_min)
    res.time_s = time.perf_counter() - t0
    return res


def _layered_result(
    profile: CIProfile,
    x: np.ndarray,
    sse: float,
    ns_best: np.ndarray,
    D_best: np.ndarray,
    single: Any,
    bounds: Bounds,
    law: PressureLaw,
    model: str,
    r_min: float | None,
) -> LayeredResult:
    """The :class:`LayeredResult` of the best layered fit ``x`` (SSE ``sse``).

    ``x`` holds (kc, kphi, cc) per layer at phic's upper bound; the layers are
    reported at the middle of the equally good phic interval, their k's scaled
    along the ridge (eqs. (2-6), (2-7)).  BIC (k = 4 per layer plus one per
    interface) is compared with that of ``single``, the exact one-layer fit.
    """
    z, y, cone = profile.depth, profile.ci, profile.cone
    N = y.size
    phi = bounds.phic[1]
    ph_lo, ph, s_hi, s_mid = _phic_ridge_layers(x, ns_best, bounds, cone)
    params = [
        TerrainParameters(
            kc=float(x[3 * j] * s_hi / s_mid),
            kphi=float(x[3 * j + 1] * s_hi / s_mid),
            n=float(ns_best[j]),
            cc=float(x[3 * j + 2]),
            phic_deg=ph,
            model=model,
            r_min=r_min,
        )
        for j in range(len(ns_best))
    ]
    X = layered_basis(z, n=ns_best, interfaces=D_best, phic=phi, law=law, cone=cone)
    m = X @ x
    chk = check_fit(z, y, m, monotone_model=len(ns_best) == 1)
    bic = _bic(sse, N, 4 * len(ns_best) + len(D_best))
    bic1 = _bic(single.sse, N, 4)
    kw = dict(cone=cone, law=law, Kc=None)
    m1 = design(z, np.array(single.n), np.array(single.phic_deg), **kw) @ np.array(
        [single.kc, single.kphi, single.cc]
    )
    return LayeredResult(
        id=profile.id,
        status="ok",
        layers=params,
        interfaces=[float(v) for v in D_best],
        rmsd=math.sqrt(sse / N),
        sse=sse,
        bic=bic,
        bic_single=bic1,
        preferred_layers=len(ns_best) if bic < bic1 else 1,
        r2_ci=chk.r2,
        longest_run=chk.longest_run,
        lack_of_fit=chk.lack_of_fit,
        phic_range=(ph_lo, phi),
        depth=z,
        ci=y,
        ci_model=m,
        ci_model_single=m1,
        metadata=dict(profile.metadata),
    )


@dataclass
class LayeredPosterior:
    """Posterior of a layered fit: per layer kc, kphi, n, cc, and the interfaces (SI).

    Attributes
    ----------
    names : list of str
        ``kc_1, kphi_1, n_1, cc_1, kc_2, ..., interface_1, ...``.
    samples : ndarray
        (draws, len(names)).
    intervals, medians : dict
        90% equal-tailed intervals and medians per name.
    identifiability : dict
        Label per name from the posterior/prior 90% width ratio.
    phic_deg : float
        The common phic held at the fit's value (it trades exactly with the
        scale of each layer's kc and kphi; labelled "set by prior").
    acceptance : float
    """

    names: list[str]
    samples: np.ndarray = field(repr=False)
    intervals: dict[str, tuple[float, float]]
    medians: dict[str, float]
    identifiability: dict[str, str]
    phic_deg: float
    acceptance: float

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        def conv(name: str, v: float, n: float) -> float:
            if name.startswith("kc_"):
                return float(u.kc_from_si(v, n, units))
            if name.startswith("kphi_"):
                return float(u.kphi_from_si(v, n, units))
            if name.startswith("cc_"):
                return float(u.pressure_from_si(v, units))
            if name.startswith("interface_"):
                return float(u.length_from_si(v, units))
            return float(v)

        iv, med = {}, {}
        for k, name in enumerate(self.names):
            if name.startswith(("kc_", "kphi_")):  # convert each draw with its own n
                j = name.split("_")[1]
                nn = self.samples[:, self.names.index(f"n_{j}")]
                col = (u.kc_from_si if name.startswith("kc_") else u.kphi_from_si)(
                    self.samples[:, k], nn, units
                )
                lo, mid, hi = np.quantile(col, [0.05, 0.5, 0.95])
                iv[name], med[name] = [float(lo), float(hi)], float(mid)
            else:
                lo, hi = self.intervals[name]
                iv[name] = [conv(name, lo, 1.0), conv(name, hi, 1.0)]
                med[name] = conv(name, self.medians[name], 1.0)
        labels = dict(self.identifiability)
        labels["phic_deg"] = LABELS[2]
        return {
            "intervals": iv,
            "medians": med,
            "identifiability": labels,
            "phic_deg": self.phic_deg,
            "acceptance": self.acceptance,
            "units": units,
        }


def layered_posterior(
    profile: CIProfile,
    fit: Any,
    *,
    bounds: Bounds | None = None,
    draws: int = 2000,
    seed: int | None = None,
    law: Any = None,
    nwalkers: int = 48,
    burn: int = 400,
) -> LayeredPosterior:
    """Posterior of a layered fit (:func:`fit_layered`) with emcee.

    Priors uniform over the bounds of each layer's kc, kphi, n, cc and over
    the interface depths (ordered, within the profile); the common phic is
    held at the fit's value.  Residuals are independent Gaussian with an
    unknown sigma integrated out (1/sigma prior), so the log-likelihood is
    -N/2 log(SSE).  The forward model is :func:`terracone.physics.layers.layered_basis`
    evaluated for all walkers at once.

    Parameters
    ----------
    profile : CIProfile
        The profile ``fit`` was fitted to.
    fit : LayeredResult
        An ``ok`` layered fit; the walkers start around it.
    bounds : Bounds, optional
    draws : int
    seed : int, optional
        The same seed gives the same draws.
    law : PressureLaw, optional
        Default: the fit's model and r_min.
    nwalkers, burn : int

    Returns
    -------
    LayeredPosterior

    References
    ----------
    .. [2] Foreman-Mackey, D., Hogg, D.W., Lang, D., Goodman, J. (2013). emcee:
       the MCMC hammer. PASP 125, 306-312.
    """
    bounds = bounds or Bounds()
    law = law or pressure_law(fit.layers[0].model or "rm0", r_min=fit.layers[0].r_min)
    z, y = profile.depth, profile.ci
    phic = fit.layers[0].phic_deg
    names, lo, hi = _layered_box(fit, bounds, float(z[0]), float(z[-1]))
    span = np.where(hi > lo, hi - lo, 1.0)
    log_prob = _LayeredLogPosterior(z, y, profile.cone, law, len(fit.layers), phic, lo, hi)
    x0 = []
    for p in fit.layers:
        x0 += [p.kc, p.kphi, p.n, p.cc]
    x0 += list(fit.interfaces)
    x0 = np.clip(np.array(x0), lo, hi)
    rng = np.random.default_rng(seed)
    p0 = np.clip(x0 + 1e-3 * span * rng.standard_normal((nwalkers, x0.size)), lo, hi)
    sampler = emcee.EnsembleSampler(
        nwalkers,
        x0.size,
        log_prob,
        vectorize=True,
        moves=[(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)],
    )
    sampler.random_state = np.random.RandomState(rng.integers(2**31)).get_state()
    steps = burn + int(math.ceil(draws / nwalkers)) * 5
    sampler.run_mcmc(p0, steps, progress=False)
    chain = sampler.get_chain(discard=burn, thin=5, flat=True)[-draws:]
    intervals, medians, labels = {}, {}, {}
    for k, name in enumerate(names):
        q05, q50, q95 = np.quantile(chain[:, k], [0.05, 0.5, 0.95])
        intervals[name] = (float(q05), float(q95))
        medians[name] = float(q50)
        labels[name] = identifiability_label((q95 - q05) / (0.9 * span[k]))
    return LayeredPosterior(
        names, chain, intervals, medians, labels, phic, float(np.mean(sampler.acceptance_fraction))
    )


def _layered_box(
    fit: Any, bounds: Bounds, d_lo: float, d_hi: float
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Names and prior box of (kc_j, kphi_j, n_j, cc_j per layer, then the interfaces).

    kc and kphi bounds are converted to SI at each layer's fitted n; the
    interfaces lie between the first and last measured depths [m].
    """
    L = len(fit.layers)
    names, lo, hi = [], [], []
    for j in range(1, L + 1):
        n_mid = fit.layers[j - 1].n
        for nm, (a, b) in (
            ("kc", tuple(float(v) for v in bounds.kc_si(n_mid))),
            ("kphi", tuple(float(v) for v in bounds.kphi_si(n_mid))),
            ("n", bounds.n),
            ("cc", bounds.cc),
        ):
            names.append(f"{nm}_{j}")
            lo.append(a)
            hi.append(b)
    for j in range(1, L):
        names.append(f"interface_{j}")
        lo.append(d_lo)
        hi.append(d_hi)
    return names, np.array(lo), np.array(hi)


class _LayeredLogPosterior:
    """log p(theta | CI) of :func:`layered_posterior`, vectorised over walkers (W, D).

    Uniform prior inside ``lo <= theta <= hi``; sigma marginalised (1/sigma
    prior): ``-N/2 log SSE``.  The model CI is eq. (2-7) with eq. (2-6) fully
    mobilised, layer by layer (:func:`terracone.physics.layers.layered_basis`).
    """

    def __init__(self, z, y, cone, law, L, phic, lo, hi) -> None:
        self.z, self.y, self.law, self.L, self.lo, self.hi = z, y, law, L, lo, hi
        self.R, H = cone.radius, cone.height
        self.t = self.R / H
        self.s = 1.0 + math.tan(math.radians(phic)) / self.t
        self.u1 = z + H
        self.Lemb = np.where(z >= 0.0, H, self.u1)
        self.u1s = np.where(self.u1 > 0, self.u1, 1.0)

    def model(self, theta: np.ndarray) -> np.ndarray:
        """Model CI (W, Z) [kPa] of parameter rows (W, D)."""
        L, z, R, t, s = self.L, self.z, self.R, self.t, self.s
        W = theta.shape[0]
        D = np.concatenate(
            [np.zeros((W, 1)), np.sort(theta[:, 4 * L :], axis=1), np.full((W, 1), np.inf)], axis=1
        )
        ci = np.zeros((W, z.size))
        for j in range(L):
            kc, kphi, n, cc = (theta[:, 4 * j + q][:, None] for q in range(4))
            a = np.clip(self.u1[None, :] - D[:, j + 1][:, None], 0.0, self.Lemb[None, :])
            b = np.clip(self.u1[None, :] - D[:, j][:, None], 0.0, self.Lemb[None, :])
            Ic, Ip, Icc = normal_integrals(self.u1s[None, :], a, b, n, self.law, t)
            ci += 2.0 / (R * R) * (t * s * (kc * Ic + kphi * Ip) + cc * Icc)  # eq. (2-7)
        return ci

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(theta)
        ok = np.all((theta >= self.lo) & (theta <= self.hi), axis=1)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():
            r = self.model(theta[ok]) - self.y[None, :]
            sse = np.einsum("wz,wz->w", r, r)
            out[ok] = -0.5 * self.y.size * np.log(np.maximum(sse, 1e-300))
        return out

"""Layered terrain, inverse side: fit a stack of layers to one CI profile.

The forward model (:func:`terracone.physics.layers.layered_basis`,
:func:`terracone.physics.layers.layered_cone_index`) extends eqs. (2-5) and
(2-6) of [1]_ to a stack of layers with their own kc_j, kphi_j, n_j, cc_j and
a common phic.  :func:`fit_layered` finds the global minimum of the RMSD over
the interfaces, the n's and the linear parameters with the search of
:mod:`terracone.inverse.layered.search` (a grid and branch and bound over the
interfaces and n's, exact bounded least squares inside, compiled kernels with
numpy twins) and reports a lower bound of the SSE over the whole search space
beside the SSE it found (``certificate``).  One layer is the special case of
the same search (no interfaces).

Models with one and more layers are compared by the Bayesian information
criterion BIC = N ln(SSE/N) + k ln N, with k = 4 per layer (kc, kphi, n, cc)
plus one per interface (phic is not counted: it trades exactly with the
scale of the k's).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from terracone.data import CIProfile, InputError, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.layered.search import (
    CURVATURE_SAFETY,
    LayeredProblem,
    SearchResult,
    search_layers,
)
from terracone.inverse.problem import Problem
from terracone.inverse.uncertainty.noise import bin_readings
from terracone.physics import units as u
from terracone.physics.metrics import check_fit
from terracone.result import LayeredSummary
from terracone.resultunits import convert_parameters, from_si, output, quantity

__all__ = ["MAX_DEPTHS", "LayeredResult", "bin_profile", "fit_layered", "max_depths", "phic_scale"]

PHIC_GRID = 19  # phic values searched when the bounds of kc or kphi are not 0 (as predict)

#: Most depths the layered search takes, per number of layers.  The search's cells and
#: tables grow as Z^L in memory (a run of 2,000 depths with two layers took 5.4 GB, 100,000
#: all the machine's memory), so a longer profile is fitted on bins of consecutive readings
#: (:func:`bin_profile`), with a note.  At these sizes a fit takes at most about 300 MB and a
#: few seconds (``benchmarks/memory.py``); more layers than listed: the last entry's half.
MAX_DEPTHS = {1: 400, 2: 400, 3: 200, 4: 60}

CERTIFICATE_METHOD = (
    "interfaces on cells between the depths where an interface meets a cone base or tip, "
    "each layer's n on a grid (41 points, 4 times finer around the best), exact bounded "
    "least squares inside; a cell's bound: the rows an interface may cut relaxed by a "
    "Lagrangian (multipliers: the best fit's residuals) with their parts in each layer taken "
    "at the cell's ends, so that the layers separate, each layer's minimum over n bounded by "
    "its grid values less the interpolation error of a curvature at most "
    f"{CURVATURE_SAFETY:g} times the largest second difference seen; cells within the target "
    "of the best SSE closed, the others halved (branch and bound) and searched locally "
    "(Nelder-Mead)"
)


@dataclass(kw_only=True)
class LayeredResult(LayeredSummary):
    """Fit of a layered model to one profile (SI).

    A :class:`~terracone.result.LayeredSummary` (``status``, ``error``,
    ``layers``, ``interfaces``, ``bic``, ``bic_single``, ``preferred_layers``,
    ``r2_ci``, ``lack_of_fit``) with the fit's details.

    Attributes
    ----------
    id : str
    rmsd : float
        [kPa]
    longest_run, lack_of_fit
        As in :class:`terracone.result.PredictionResult`.
    phic_range : (float, float)
        Interval of the common phic that fits equally well [deg].
    certificate : dict
        ``sse`` [kPa^2], ``lower_bound`` (of the SSE anywhere in the search
        space, up to the stated assumption) and ``gap`` = (sse -
        lower_bound) / sse, with how they were found.
    profile_intervals : dict
        Outer approximation of the 95% profile interval of each interface
        [m] (``interface_1`` ...) and each n (``n_1`` ...).
    undetermined : list of str
        What the data leave free: ``phic`` and ``phic~scale(kc,kphi)``
        (eq. (2-6)) unless a calibration holds phic, and each
        ``interface_i`` or ``n_j`` whose profile interval covers half its
        range or more (a weak contrast).
    notes : list of str
        What the fit held (a calibration's values), as the one-layer fit says,
        and what it did to the data: a long profile fitted on bins
        (:data:`MAX_DEPTHS`; ``depth``, ``ci`` and ``ci_model`` are then
        those of the bins).
    """

    id: str
    rmsd: float = quantity("pressure", default=float("nan"))
    sse: float = float("nan")
    longest_run: int = 0
    phic_range: tuple[float, float] | None = None
    depth: np.ndarray | None = quantity("length", default=None)
    ci: np.ndarray | None = quantity("pressure", default=None)
    ci_model: np.ndarray | None = quantity("pressure", default=None)
    ci_model_single: np.ndarray | None = None
    time_s: float = 0.0
    metadata: dict[str, Any] = field(default_factory=dict)
    certificate: dict[str, Any] = field(default_factory=dict)
    profile_intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    undetermined: list[str] = field(default_factory=list)
    nfev: int = 0
    notes: list[str] = field(default_factory=list)

    def _repr_html_(self) -> str:
        """A table of the layers (SI) and the BIC comparison, for Jupyter."""
        from terracone.notebook import layered_html

        return layered_html(self)

    def as_dict(self, units: str = "si", *, curves: bool = True) -> dict[str, Any]:
        """The ``layered`` block of a profile in ``terracone predict --json`` (``units``)."""
        units = u.check_system(units)
        d: dict[str, Any] = {"id": self.id, "status": self.status, "error": self.error}
        if not self.ok:
            return d
        cert = dict(self.certificate)
        for k in ("sse", "lower_bound"):
            if k in cert:  # kPa^2 -> the unit of pressure squared
                cert[k] = from_si(cert[k], "pressure2", units)
        d.update(
            {
                **output(self, units, fields=("layers", "interfaces", "rmsd")),
                "r2_ci": self.r2_ci,
                "longest_run": self.longest_run,
                "lack_of_fit": self.lack_of_fit,
                "bic": self.bic,
                "bic_single": self.bic_single,
                "preferred_layers": self.preferred_layers,
                "phic_range_deg": list(self.phic_range) if self.phic_range else None,
                "units": units,
                "undetermined": list(self.undetermined),
                "profile_intervals": convert_parameters(self.profile_intervals, units),
                "certificate": cert,
                "metadata": self.metadata,
                "notes": list(self.notes),
            }
        )
        if curves:
            d.update(output(self, units, fields=("depth", "ci", "ci_model")))
        return d


def max_depths(layers: int) -> int:
    """Most depths the layered search takes with ``layers`` layers (:data:`MAX_DEPTHS`)."""
    return MAX_DEPTHS.get(int(layers), MAX_DEPTHS[max(MAX_DEPTHS)] // 2)


def bin_profile(profile: CIProfile, most: int) -> tuple[CIProfile, str | None]:
    """The profile on at most ``most`` depths: bins of k consecutive readings, and a note.

    A profile of N <= ``most`` readings comes back as it is (note None).  A
    longer one becomes the means of depth and CI over bins of k =
    ceil(N / most) consecutive readings (the last bin may hold fewer), each
    at its mean depth (:func:`~terracone.inverse.uncertainty.noise.bin_readings`,
    as the posterior bins): a least-squares fit to the bin means is the fit to
    the readings up to the model's curvature within a bin (eq. (2-7) is
    smooth in depth; an interface is placed to about a bin).
    """
    N = profile.depth.size
    z, y, k = bin_readings(profile.depth, profile.ci, most)
    if k == 1:
        return profile, None
    binned = CIProfile(profile.id, z, y, cone=profile.cone, metadata=profile.metadata,
                       source=profile.source)  # fmt: skip
    width = float(np.median(np.diff(z))) if z.size > 1 else 0.0
    note = (
        f"fitted on {z.size} depth bins of the {N} readings (means of {k} consecutive "
        f"readings, about {width * 1000:.3g} mm apart): at most {most} depths are searched"
    )
    return binned, note


def _bic(sse: float, N: int, k: int) -> float:
    return N * math.log(max(sse, 1e-300) / N) + k * math.log(N)


def phic_scale(phic_deg: float | np.ndarray, cone: Any) -> float | np.ndarray:
    """s = 1 + tan(phic)/tan(alpha): the factor of the kc and kphi columns (eqs. (2-6), (2-7))."""
    return 1.0 + np.tan(np.radians(phic_deg)) / (cone.radius / cone.height)


def _phic_values(bounds: Bounds) -> np.ndarray:
    """phic [deg] searched: the upper bound when the boxes nest (kc and kphi from 0), else a grid."""
    lo, hi = bounds.phic_deg
    if lo == hi or (bounds.kc[0] == 0.0 and bounds.kphi[0] == 0.0):
        return np.array([float(hi)])
    return np.linspace(lo, hi, PHIC_GRID)


def _hull(bounds: Bounds, cone: Any) -> Bounds:
    """The bounds of the relaxation over phic: kc and kphi as if scaled at phic's upper bound.

    The data fix s kc and s kphi (eq. (2-6)); over s in [s_lo, s_hi] they
    range over [s_lo kc_lo, s_hi kc_hi] (likewise kphi), which at s = s_hi
    are the kc in [kc_lo s_lo / s_hi, kc_hi].  Its boxes hold every phic's.
    """
    r = float(phic_scale(bounds.phic_deg[0], cone) / phic_scale(bounds.phic_deg[1], cone))
    kc, kphi, hi = bounds.kc, bounds.kphi, bounds.phic_deg[1]
    return replace(bounds, kc=(kc[0] * r, kc[1]), kphi=(kphi[0] * r, kphi[1]), phic_deg=(hi, hi))


def _search(
    profile, layers, problem: Problem, bounds, min_thick, n_grid, search_kw, ph
) -> SearchResult:
    """One search at phic ``ph`` over ``bounds``; with a held kc/kphi the result's kc entries
    are ratio kphi (the search folds kc's column into kphi's and reports kc 0)."""
    pb = LayeredProblem(
        profile.depth, profile.ci, profile.cone, problem.law, bounds, layers, min_thick,
        float(phic_scale(ph, profile.cone)), n_grid, ratio=problem.ratio,
    )  # fmt: skip
    res = search_layers(pb, **search_kw)
    if problem.ratio is not None:
        res.x[0::3] = problem.ratio * res.x[1::3]
    return res


def _solve(
    profile, layers, problem: Problem, min_thick, n_grid, search_kw
) -> tuple[SearchResult, float]:
    """The best search over phic: (result, phic [deg]).

    Nested boxes (kc and kphi from 0): one search at phic's upper bound.
    Otherwise first one search of the relaxation (:func:`_hull`): where
    some phic holds every layer's kc and kphi in its box
    (:func:`_scale_range` not empty) its optimum is the optimum over every
    phic.  Only where it is not (a layer pressing on a box that another
    layer's wants the other way), a search at each of :data:`PHIC_GRID`
    values of phic, as before; the bound is the relaxation's then.
    """
    cone, bounds = profile.cone, problem.fit_bounds
    hi = float(bounds.phic_deg[1])
    values = _phic_values(bounds)
    args = (profile, layers, problem)
    if values.size == 1:
        return _search(*args, bounds, min_thick, n_grid, search_kw, hi), hi
    relaxed = _search(*args, _hull(bounds, cone), min_thick, n_grid, search_kw, hi)
    s_lo, s_hi = _scale_range(relaxed.x, relaxed.n, hi, bounds, cone)
    if s_lo <= s_hi:  # the relaxation's optimum is feasible: the optimum over every phic
        return relaxed, hi
    best: tuple[SearchResult, float] | None = None
    nfev = relaxed.nfev
    for ph in values:
        res = _search(*args, bounds, min_thick, n_grid, search_kw, float(ph))
        nfev += res.nfev
        if best is None or res.sse < best[0].sse:
            best = (res, float(ph))
    assert best is not None
    best[0].lower, best[0].nfev = min(relaxed.lower, best[0].sse), nfev
    return best


def fit_layered(
    profile: CIProfile,
    problem: Problem | None = None,
    *,
    layers: int = 2,
    n_grid: int = 41,
    min_thickness: float | None = None,
    target: float = 0.02,
    levels: int = 24,
) -> LayeredResult:
    """Fit a model of ``layers`` layers (interfaces fitted) to one CI profile.

    Parameters
    ----------
    profile : CIProfile
    problem : Problem, optional
        What is fitted: the pressure law (section 3.2), the bounds of each
        layer's kc, kphi, n, cc and of the common phic, and the values a
        calibration holds in every layer (phic, cc, kc/kphi); its noise
        floor sets the profile intervals.
    layers : int
        Number of layers (1 gives the homogeneous model through the same search).
    n_grid : int
        Grid over each layer's n (a 4 times finer one around each best).
    min_thickness : float, optional
        The first interface at least this far below the first measured
        depth and the last this far above the last one, interfaces at least
        half of it apart [m]; default: two depth steps.
    target : float
        Relative gap between the SSE found and its lower bound that the
        branch and bound aims at.
    levels : int
        Rounds of branch and bound.

    Returns
    -------
    LayeredResult
        With ``certificate`` (the SSE, a lower bound of the global minimum
        and their gap), ``profile_intervals`` and ``undetermined``; a
        profile that cannot be fitted gives ``status="error"``.

    Notes
    -----
    A profile of more than :func:`max_depths` readings (400 with one or
    two layers, 200 with three, 60 with four) is fitted on bins of
    consecutive readings (:func:`bin_profile`) and says so in ``notes``:
    the search's memory and time grow as the number of depths to the power
    of the layers.  phic is fitted at its upper bound when the lower bounds of kc and kphi
    are 0 (the boxes of the scaled k's are nested, as in
    :mod:`terracone.inverse.solver.many`), else on a grid of 19 values; its
    equally good interval is reported (``phic_range``) and the layers at its
    middle.  See :mod:`terracone.inverse.layered.search` for the search and
    its bound.
    """
    t0 = time.perf_counter()
    problem = problem or Problem()
    problem.require_single("fit_layered")
    if int(layers) < 1:
        raise ValueError(f"layers must be at least 1 (got {layers})")
    try:
        profile.validate(min_points=max(3, 4 * layers + layers))
    except InputError as exc:
        return LayeredResult(
            id=profile.id, status="error", error=str(exc), metadata=dict(profile.metadata)
        )
    profile, note = bin_profile(profile, max_depths(layers))
    z = profile.depth
    step = float(np.median(np.diff(z)))
    min_thick = min_thickness if min_thickness is not None else 2 * step
    kw = dict(target=target, levels=levels, noise_floor=problem.noise_floor)
    single, ph1 = _solve(profile, 1, problem, min_thick, n_grid, dict(kw, intervals=layers == 1))
    if layers == 1:
        found, ph = single, ph1
    else:
        if z[-1] - z[0] - 2 * min_thick < 0.5 * min_thick * (layers - 2):
            msg = "profile too short for the minimum layer thickness"
            return LayeredResult(
                id=profile.id, status="error", error=msg, metadata=dict(profile.metadata)
            )
        found, ph = _solve(profile, layers, problem, min_thick, n_grid, kw)
    res = _layered_result(profile, found, ph, single, ph1, problem)
    res.notes += [note] if note else []
    res.time_s = time.perf_counter() - t0
    return res


def _scale_range(x: np.ndarray, ns: np.ndarray, ph: float, bounds: Bounds, cone: Any):
    """(s_lo, s_hi): the phic scales s that hold every layer's kc and kphi in its box.

    x holds (kc, kphi, cc) per layer with the kc and kphi columns scaled at
    ``ph``; the products s kc and s kphi are what the data fix (eq. (2-6)).
    Empty (s_lo > s_hi, beyond a relative 1e-12) when no phic in the bounds does.
    """
    s_fit = float(phic_scale(ph, cone))
    need, room = (
        float(phic_scale(bounds.phic_deg[0], cone)),
        float(phic_scale(bounds.phic_deg[1], cone)),
    )
    for j, nj in enumerate(ns):
        for k, (lo, hi) in enumerate((bounds.kc_si(nj), bounds.kphi_si(nj))):
            v = x[3 * j + k] * s_fit  # the product the data fix
            if float(hi) > 0:
                need = max(need, v / float(hi))
            if float(lo) > 0:
                room = min(room, v / float(lo))
    if need > room and need <= room * (1 + 1e-12):
        need = room  # rounding
    return need, room


def _phic_ridge(x: np.ndarray, ns: np.ndarray, ph: float, bounds: Bounds, cone: Any):
    """The interval of phic [deg] that fits as well as ``ph`` over all layers, and its middle.

    Every s of :func:`_scale_range` fits equally well (the nested-box
    argument of :mod:`terracone.inverse.solver.many`); ``ph`` itself when
    the range is empty (it is not for a fit :func:`_solve` returns).
    Returns (phic_lo, phic_hi, phic_mid, s_fit / s_mid).
    """
    s_fit = float(phic_scale(ph, cone))
    s_lo, s_hi = _scale_range(x, ns, ph, bounds, cone)
    if s_lo > s_hi:
        s_lo = s_hi = s_fit
    tt = cone.radius / cone.height
    ph_lo = float(np.clip(math.degrees(math.atan((s_lo - 1.0) * tt)), *bounds.phic_deg))
    ph_hi = float(np.clip(math.degrees(math.atan((s_hi - 1.0) * tt)), *bounds.phic_deg))
    mid = 0.5 * (ph_lo + ph_hi)
    return ph_lo, ph_hi, mid, s_fit / float(phic_scale(mid, cone))


def _layered_result(
    profile, found: SearchResult, ph, single: SearchResult, ph1, problem: Problem
) -> LayeredResult:
    """The :class:`LayeredResult` of the best layered fit ``found`` (at phic ``ph``).

    The layers are reported at the middle of the equally good phic interval,
    their k's scaled along the ridge (eqs. (2-6), (2-7)).  BIC (k = 4 per
    layer plus one per interface) is compared with that of ``single``, the
    one-layer fit by the same search.
    """
    z, y, cone = profile.depth, profile.ci, profile.cone
    N, L = y.size, found.n.size
    x, ns, bounds = found.x, found.n, problem.fit_bounds
    ph_lo, ph_hi, mid, scale = _phic_ridge(x, ns, ph, bounds, cone)
    params = [
        TerrainParameters(
            kc=float(x[3 * j] * scale),  # ratio kphi where the problem holds kc/kphi
            kphi=float(x[3 * j + 1] * scale),
            n=float(ns[j]),
            cc=float(x[3 * j + 2]),
            phic_deg=mid,
            model=problem.model,
            r_min=problem.r_min,
        )  # fmt: skip
        for j in range(L)
    ]
    m, m1 = y + found.residuals, y + single.residuals
    chk = check_fit(z, y, m, monotone_model=L == 1)
    bic = _bic(found.sse, N, 4 * L + (L - 1))
    bic1 = _bic(single.sse, N, 4)
    und = _undetermined(found, bounds, ph_lo, ph_hi)
    cert = {
        "sse": found.sse,
        "lower_bound": found.lower,
        # relative; an SSE within rounding of 0 (1e-12 y'y: a noise-free fit) has none
        "gap": (found.sse - found.lower) / found.sse if found.sse > 1e-12 * float(y @ y) else 0.0,
        "cells_open": found.cells_open,
        "method": CERTIFICATE_METHOD,
    }
    return LayeredResult(
        id=profile.id, status="ok", layers=params, interfaces=[float(v) for v in found.D],
        rmsd=math.sqrt(found.sse / N), sse=found.sse, bic=bic, bic_single=bic1,
        preferred_layers=L if bic < bic1 else 1, r2_ci=chk.r2, longest_run=chk.longest_run,
        lack_of_fit=chk.lack_of_fit, phic_range=(ph_lo, ph_hi), depth=z, ci=y, ci_model=m,
        ci_model_single=m1, metadata=dict(profile.metadata), certificate=cert,
        profile_intervals=dict(found.intervals), undetermined=und, nfev=found.nfev,
        notes=problem.notes_for(cone.name),
    )  # fmt: skip


def _undetermined(found: SearchResult, bounds: Bounds, ph_lo: float, ph_hi: float) -> list[str]:
    """Interfaces and n's whose profile interval covers half their range or more, and phic."""
    out = []
    iv = found.intervals
    span_n = bounds.n[1] - bounds.n[0]
    for i in range(found.D.size):
        lo, hi = iv.get(f"interface_{i + 1}", (0.0, 0.0))
        rng = found.d_range[1] - found.d_range[0]
        if hi - lo >= 0.5 * rng:
            out.append(f"interface_{i + 1}")
    for j in range(found.n.size):
        lo, hi = iv.get(f"n_{j + 1}", (0.0, 0.0))
        if span_n > 0 and hi - lo >= 0.5 * span_n:
            out.append(f"n_{j + 1}")
    if ph_hi - ph_lo > 1e-9 or bounds.phic_deg[0] != bounds.phic_deg[1]:
        out = ["phic", *out, "phic~scale(kc,kphi)"]
    return out

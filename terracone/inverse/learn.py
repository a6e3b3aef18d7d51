"""The learning process (section 3.3.1 of [1]_) and calibrations.

Given CI profiles and plate pressure-sinkage tests of one terrain, find the
RM1 transition radius r_min (outer search) and the five parameters kc, kphi,
n, cc, phic fitted jointly to all data (inner search).

Objective (default weighting): the sum over data sets (each CI profile and
each plate test) of the data set's RMSD divided by its mean measured value,

    J = sum_d RMSD_d / mean_d.

For fixed (n, phic, r_min) every model value is linear in (kc, kphi, cc)
(eqs. (2-5) to (2-7) for the cone, eq. (2-2) and section 3.2 for the
plates), so J is convex in them; its global minimum over the bounds is found
by iteratively reweighted bounded least squares (a majorise-minimise scheme
that decreases J at every step).  (n, phic, r_min) are searched on a grid
and refined with Nelder-Mead.

The result can be saved as a :class:`Calibration`, the paper's "information
library", and used by the prediction process.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 3.2 and 3.3.1, Figure 3-1.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize

from .. import units as u
from ..cone import improved
from ..data import CIProfile, PlateTest, TerrainParameters
from ..plate import plate_basis, pressure_law
from .bounds import Bounds
from .boxlsq import box_lsq3, gram
from .exact import design

__all__ = ["Calibration", "LearnResult", "learn"]


@dataclass
class Calibration:
    """A learned calibration: what prediction takes from the learning process.

    Attributes
    ----------
    terrain : str
        Terrain or site label.
    model : {"rm0", "rm1"}
    r_min : float or None
        [m]
    plate_pair : (float, float) or None
        Plate radii [m] of the learning data (RM1 secant when r_min > r2).
    phic_deg : float
        [deg]
    cc : float
        [kPa]
    kc, kphi, n : float
        The calibrated terrain's P-S parameters (SI).
    cone : str
    provenance : dict
    """

    terrain: str
    model: str
    r_min: float | None
    plate_pair: tuple[float, float] | None
    phic_deg: float
    cc: float
    kc: float
    kphi: float
    n: float
    cone: str = "asabe-large"
    provenance: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["plate_pair"] = list(self.plate_pair) if self.plate_pair else None
        return {"terracone_calibration": 1, "units": "si", **d}

    def save(self, path: str | Path) -> None:
        """Write the calibration as JSON (SI units)."""
        Path(path).write_text(json.dumps(self.to_json(), indent=2) + "\n")

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Calibration:
        if d.get("terracone_calibration") != 1:
            raise ValueError("not a terracone calibration (key 'terracone_calibration' missing)")
        if d.get("units", "si") != "si":
            raise ValueError("calibration files are stored in SI")
        pp = d.get("plate_pair")
        return cls(
            terrain=str(d["terrain"]),
            model=str(d["model"]),
            r_min=None if d.get("r_min") is None else float(d["r_min"]),
            plate_pair=None if not pp else (float(pp[0]), float(pp[1])),
            phic_deg=float(d["phic_deg"]),
            cc=float(d["cc"]),
            kc=float(d["kc"]),
            kphi=float(d["kphi"]),
            n=float(d["n"]),
            cone=str(d.get("cone", "asabe-large")),
            provenance=dict(d.get("provenance", {})),
        )

    def library_params(self) -> dict[str, Any]:
        """Parameters to store in the terrain library (SI keys)."""
        d = {
            "kc": self.kc,
            "kphi": self.kphi,
            "n": self.n,
            "cc": self.cc,
            "phic_deg": self.phic_deg,
            "model": self.model,
            "r_min": self.r_min,
            "plate_pair": list(self.plate_pair) if self.plate_pair else None,
            "cone": self.cone,
        }
        return {k: v for k, v in d.items() if v is not None}

    @classmethod
    def from_library_record(cls, rec: Any) -> Calibration:
        """Calibration from a terrain-library record of kind "calibration"."""
        if rec.kind != "calibration":
            raise ValueError(
                f"terrain {rec.name!r} is a {rec.kind!r} record, not a calibration from "
                "`terracone learn --save-as`: it has no learned phic, cc and r_min"
            )
        d = dict(rec.params)
        d.update({"terracone_calibration": 1, "units": "si", "terrain": rec.name})
        d["provenance"] = dict(rec.provenance or {})
        d.setdefault("cc", 0.0)
        return cls.from_json(d)

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration written by :meth:`save`."""
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"calibration {path}: cannot read ({exc})") from exc
        try:
            return cls.from_json(d)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"calibration {path}: {exc}") from exc


@dataclass
class LearnResult:
    """Result of :func:`learn` (SI inside)."""

    params: TerrainParameters
    plate_pair: tuple[float, float] | None
    objective: float
    rmsd_ci: float
    rmsd_plates: float
    datasets: list[dict[str, Any]]
    undetermined: list[str]
    criteria: dict[str, Any]
    nfev: int
    time_s: float
    r_min_profile: list[tuple[float, float]] = field(default_factory=list)
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)

    def _repr_html_(self) -> str:
        """A table of the learned parameters (SI and US) and the fit, for Jupyter."""
        from ..report.notebook import learn_html

        return learn_html(self)

    def calibration(
        self, terrain: str, cone: str = "asabe-large", **provenance: Any
    ) -> Calibration:
        """The calibration to save for the prediction process."""
        from .. import __version__

        prov = {
            "created": datetime.now(UTC).isoformat(timespec="seconds"),
            "method": "terracone learn (section 3.3.1)",
            "terracone": __version__,
            **provenance,
        }
        p = self.params
        return Calibration(
            terrain,
            p.model,
            p.r_min,
            self.plate_pair,
            p.phic_deg,
            p.cc,
            p.kc,
            p.kphi,
            p.n,
            cone,
            prov,
        )

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        d = self.params.as_dict(units)
        d.update(
            {
                "rmsd_ci": float(u.pressure_from_si(self.rmsd_ci, units)),
                "rmsd_plates": float(u.pressure_from_si(self.rmsd_plates, units)),
                "objective": self.objective,
                "plate_pair": None
                if self.plate_pair is None
                else [float(v) for v in u.length_from_si(self.plate_pair, units)],
                "datasets": [
                    {**ds, "rmsd": float(u.pressure_from_si(ds["rmsd"], units))}
                    for ds in self.datasets
                ],
                "undetermined": self.undetermined,
                "profile_intervals": {
                    k: [
                        float(v)
                        for v in (
                            u.length_from_si(iv, units)
                            if k == "r_min"
                            else u.pressure_from_si(iv, units)
                            if k == "cc"
                            else iv
                        )
                    ]
                    for k, iv in self.intervals.items()
                },
                "criteria": self.criteria,
                "diagnostics": {"nfev": self.nfev, "time_s": self.time_s},
            }
        )
        return d


def _plate_pair(plates: list[PlateTest]) -> tuple[float, float] | None:
    sizes = sorted({round(p.b, 12) for p in plates})
    return (sizes[0], sizes[-1]) if len(sizes) >= 2 else None


def learn(
    profiles: list[CIProfile],
    plates: list[PlateTest],
    *,
    model: str = "rm1",
    bounds: Bounds | None = None,
    r_min_bounds: tuple[float, float] | None = None,
    Kc: float | None = None,
    grid: tuple[int, int, int] = (33, 16, 13),
    max_cv: float = 0.25,
    noise_floor: float = 0.01,
) -> LearnResult:
    """Fit kc, kphi, n, cc, phic (and r_min for RM1) to CI and plate data.

    Parameters
    ----------
    profiles : list of CIProfile
    plates : list of PlateTest
        Only their loading branches are used.
    model : {"rm1", "rm0"}
    bounds : Bounds
    r_min_bounds : (float, float), optional
        Search range of r_min [m]; default 0.5 mm to 3 times the larger plate.
    Kc : float, optional
        Fixed shear deformation parameter [m] (None: fully mobilised).
    grid : (int, int, int)
        Grid sizes for n, phic and r_min.
    max_cv : float
        Fit criterion: every data set's CV = RMSD/mean must be below this.
    noise_floor : float
        Smallest relative noise assumed when judging what the data leave free.
    """
    t0 = time.perf_counter()
    bounds = bounds or Bounds()
    if not profiles:
        raise ValueError("learning needs at least one CI profile")
    for p in profiles:
        p.validate()
    branches = [p.loading_branch() for p in plates]
    branches = [b for b in branches if b.sinkage.size >= 3]
    if not branches:
        raise ValueError("learning needs at least one plate test with 3 or more loading points")
    pair = _plate_pair(branches)
    if model == "rm1":
        big = max(b.b for b in branches)
        rb = r_min_bounds or (5e-4, 3.0 * big)
        r_grid = np.exp(np.linspace(math.log(rb[0]), math.log(rb[1]), grid[2]))
    else:
        rb = None
        r_grid = np.array([np.nan])
    n_grid = (
        np.linspace(*bounds.n, grid[0]) if bounds.n[0] != bounds.n[1] else np.array([bounds.n[0]])
    )
    phi_grid = (
        np.linspace(*bounds.phic, grid[1])
        if bounds.phic[0] != bounds.phic[1]
        else np.array([bounds.phic[0]])
    )

    ys = [p.ci for p in profiles] + [b.pressure for b in branches]
    a_d = np.array([1.0 / (np.mean(y) * math.sqrt(y.size)) for y in ys])  # J = sum a_d sqrt(SSE_d)

    def grams(n, phi, rm):
        """Per-data-set Gram terms for arrays n, phi, rm of one shape S -> (D, S, ...)."""
        law = (
            pressure_law(model, r_min=rm[..., None], plate_pair=pair)
            if model == "rm1"
            else pressure_law("rm0")
        )
        Gs, gs, yys = [], [], []
        for p in profiles:
            X = design(p.depth, n[..., None], phi[..., None], cone=p.cone, law=law, Kc=Kc)
            G, g, yy = gram(X, np.broadcast_to(p.ci, X.shape[:-1]))
            Gs.append(G)
            gs.append(g)
            yys.append(yy)
        for b in branches:
            A, B = plate_basis(b.sinkage, n=n[..., None], b=b.b, law=law)
            A, B = np.broadcast_arrays(A, B)
            X = np.stack([A, B, np.zeros_like(A)], axis=-1)
            G, g, yy = gram(X, np.broadcast_to(b.pressure, X.shape[:-1]))
            Gs.append(np.broadcast_to(G, np.shape(n) + (3, 3)))
            gs.append(np.broadcast_to(g, np.shape(n) + (3,)))
            yys.append(np.broadcast_to(yy, np.shape(n)))
        return np.stack(Gs), np.stack(gs), np.stack(yys)

    def solve(n, phi, rm, iters=25, cc_pin=None):
        Gd, gd, yyd = grams(n, phi, rm)
        lo_kc, hi_kc = bounds.kc_si(n)
        lo_kp, hi_kp = bounds.kphi_si(n)
        cc_lo = np.full(np.shape(n), bounds.cc[0]) if cc_pin is None else cc_pin
        cc_hi = np.full(np.shape(n), bounds.cc[1]) if cc_pin is None else cc_pin
        lo = np.stack([lo_kc, lo_kp, cc_lo], axis=-1)
        hi = np.stack([hi_kc, hi_kp, cc_hi], axis=-1)
        shp = (-1,) + (1,) * np.ndim(n)
        J_floor = 1e-12 * float(np.sum(a_d * np.sqrt(np.max(yyd.reshape(len(a_d), -1), axis=1))))
        w = (a_d**2).reshape(shp) * np.ones(np.shape(n))
        x = None
        J = None
        for _ in range(iters):
            G = np.einsum("d...,d...ij->...ij", w, Gd)
            g = np.einsum("d...,d...i->...i", w, gd)
            yy = np.einsum("d...,d...->...", w, yyd)
            x, _ = box_lsq3(G, g, yy, lo, hi)
            sse_d = (
                np.einsum("...i,d...ij,...j->d...", x, Gd, x)
                - 2 * np.einsum("d...i,...i->d...", gd, x)
                + yyd
            )
            # floor at rounding level of each data set: near a perfect fit the weights
            # 1/sqrt(SSE) would otherwise chase noise
            sse_d = np.maximum(sse_d, 1e-24 * yyd + 1e-300)
            J_new = np.einsum("d,d...->...", a_d, np.sqrt(sse_d))
            # majorise sqrt(SSE) by its tangent: weights a_d / (2 sqrt(SSE_d))
            w = a_d.reshape(shp) / (2.0 * np.sqrt(sse_d))
            if J is not None and np.all(np.abs(J - J_new) <= 1e-10 * np.abs(J_new) + J_floor):
                J = J_new
                break
            J = J_new
        return x, J, sse_d

    N, P, Rm = np.meshgrid(n_grid, phi_grid, r_grid, indexing="ij")
    x_grid, J_grid, _ = solve(N, P, Rm)
    nfev = J_grid.size
    i, j, k = np.unravel_index(np.argmin(J_grid), J_grid.shape)

    # local refinement in (n, phic, log r_min)
    def pack(v):
        n = float(np.clip(v[0], *bounds.n))
        phi = float(np.clip(v[1], *bounds.phic))
        rm = float(np.exp(np.clip(v[2], math.log(rb[0]), math.log(rb[1])))) if rb else np.nan
        return n, phi, rm

    def obj(v):
        n, phi, rm = pack(v)
        _, J, _ = solve(np.array([n]), np.array([phi]), np.array([rm]))
        return float(J[0])

    v0 = [n_grid[i], phi_grid[j], math.log(r_grid[k]) if rb else 0.0]
    best_v, best_J = v0, float(J_grid[i, j, k])
    J0 = best_J
    # Nelder-Mead restarted from its own answer until it stops improving: the
    # valley between r_min, phic and cc is long and narrow
    for _ in range(4):
        res = minimize(
            obj,
            best_v,
            method="Nelder-Mead",
            options={"xatol": 1e-6, "fatol": 1e-9 * J0, "maxiter": 500, "adaptive": True},
        )
        nfev += int(res.nfev)
        if res.fun < best_J * (1 - 1e-6) and res.fun > 1e-9 * J0:
            best_v, best_J = list(res.x), float(res.fun)
        else:
            if res.fun < best_J:
                best_v, best_J = list(res.x), float(res.fun)
            break
    n, phi, rm = pack(best_v)
    x, J, sse_d = solve(np.array([n]), np.array([phi]), np.array([rm]))
    x = x[0]
    params = TerrainParameters(
        float(x[0]), float(x[1]), n, float(x[2]), phi, Kc, model, None if model == "rm0" else rm
    )

    # data-set diagnostics, from residuals
    law = (
        pressure_law(model, r_min=params.r_min, plate_pair=pair)
        if model == "rm1"
        else pressure_law("rm0")
    )
    datasets = []
    ci_res, pl_res = [], []
    for p in profiles:
        m = improved(
            p.depth, kc=x[0], kphi=x[1], n=n, cc=x[2], phic=phi, Kc=Kc, law=law, cone=p.cone
        )
        r = m - p.ci
        ci_res.append(r)
        rms = float(np.sqrt(np.mean(r * r)))
        datasets.append({"kind": "ci", "id": p.id, "rmsd": rms, "cv": rms / float(np.mean(p.ci))})
    for b in branches:
        A, B = plate_basis(b.sinkage, n=n, b=b.b, law=law)
        r = x[0] * A + x[1] * B - b.pressure
        pl_res.append(r)
        rms = float(np.sqrt(np.mean(r * r)))
        datasets.append(
            {
                "kind": "plate",
                "id": b.id,
                "b": b.b,
                "rmsd": rms,
                "cv": rms / float(np.mean(b.pressure)),
            }
        )
    ci_all = np.concatenate(ci_res)
    pl_all = np.concatenate(pl_res)
    worst = max(ds["cv"] for ds in datasets)
    # the objective from the residuals themselves (the Gram form cancels near zero)
    best_J = float(sum(ds["rmsd"] / m for ds, m in zip(datasets, [float(np.mean(y)) for y in ys])))
    # values that ended on a search bound: the bound, not the data, set them
    at_bounds = []
    kc_b, kp_b = bounds.kc_si(n), bounds.kphi_si(n)
    checks = [
        ("kc", params.kc, float(kc_b[0]), float(kc_b[1])),
        ("kphi", params.kphi, float(kp_b[0]), float(kp_b[1])),
        ("n", n, *bounds.n),
        ("cc", params.cc, *bounds.cc),
        ("phic_deg", phi, *bounds.phic),
    ]
    if rb:
        checks.append(("r_min", rm, *rb))
    for name, v, lo_b, hi_b in checks:
        if lo_b == hi_b:
            continue
        tol = 1e-6 * (hi_b - lo_b)
        if v <= lo_b + tol:
            at_bounds.append(f"{name} at its lower bound")
        elif v >= hi_b - tol:
            at_bounds.append(f"{name} at its upper bound")
    criteria = {
        "max_cv": max_cv,
        "worst_cv": worst,
        "satisfied": bool(worst <= max_cv),
        "at_bounds": at_bounds,
    }

    # Identifiability: approximate 95% profile intervals.  A change of SSE_d by
    # 3.84 sigma_d^2 moves RMSD_d/mean_d by about 1.92 CV_d / N_d, so J may rise by
    # dJ = sum_d 1.92 max(CV_d, noise_floor) / N_d before a value is rejected.
    dJ = float(sum(1.92 * max(ds["cv"], noise_floor) / y.size for ds, y in zip(datasets, ys)))
    # the grid profiles are compared with the grid's own best: a coarse grid sits above
    # the refined optimum everywhere, and a flat direction must still show as flat
    thr_grid = float(J_grid.min()) + dJ
    und: list[str] = []
    intervals: dict[str, tuple[float, float]] = {}

    def grid_interval(name, values, prof, at, log=False, thr=thr_grid):
        ok = prof <= thr
        if values.size < 2:
            return
        if ok.any():
            lo_v, hi_v = float(values[ok].min()), float(values[ok].max())
        else:
            lo_v = hi_v = at
        intervals[name] = (min(lo_v, at), max(hi_v, at))
        span = (np.log(values[-1]) - np.log(values[0])) if log else (values[-1] - values[0])
        width = (
            (np.log(intervals[name][1]) - np.log(intervals[name][0]))
            if log
            else (intervals[name][1] - intervals[name][0])
        )
        if width >= 0.5 * span:
            und.append(name)

    def refined_profile(axis: int, values: np.ndarray) -> np.ndarray:
        """J minimised over the two other coordinates, for each grid value of one."""
        out = np.empty(values.size)
        for kk, val in enumerate(values):
            sl = np.take(J_grid, kk, axis=axis)
            a0, b0 = np.unravel_index(np.argmin(sl), sl.shape)
            start = [n_grid, phi_grid, np.log(r_grid) if rb else np.zeros(1)]
            full = [None, None, None]
            others = [q for q in range(3) if q != axis]
            full[others[0]] = start[others[0]][a0]
            full[others[1]] = start[others[1]][b0]
            fixed = math.log(val) if axis == 2 else val

            def f2(w, fixed=fixed, full=full, others=others):
                v = list(full)
                v[axis] = fixed
                v[others[0]], v[others[1]] = w
                return obj(v)

            w0 = [full[others[0]], full[others[1]]]
            r = minimize(
                f2,
                w0,
                method="Nelder-Mead",
                options={"xatol": 1e-4, "fatol": 1e-6 * J0, "maxiter": 150},
            )
            out[kk] = min(r.fun, float(sl.min()))
        return out

    r_profile: list[tuple[float, float]] = []
    grid_interval("n", n_grid, J_grid.min(axis=(1, 2)), n)
    if phi_grid.size > 1:
        grid_interval("phic_deg", phi_grid, refined_profile(1, phi_grid), phi, thr=best_J + dJ)
    if rb:
        Jr = refined_profile(2, r_grid)
        r_profile = [(float(a), float(b)) for a, b in zip(r_grid, Jr)]
        grid_interval("r_min", r_grid, Jr, rm, log=True, thr=best_J + dJ)
    if bounds.cc[0] != bounds.cc[1]:
        cc_vals = np.linspace(bounds.cc[0], bounds.cc[1], 41)
        ones = np.ones_like(cc_vals)
        _, Jcc, _ = solve(n * ones, phi * ones, rm * ones, cc_pin=cc_vals)
        grid_interval("cc", cc_vals, Jcc, float(x[2]), thr=best_J + dJ)
    return LearnResult(
        params=params,
        plate_pair=pair,
        objective=best_J,
        rmsd_ci=float(np.sqrt(np.mean(ci_all**2))),
        rmsd_plates=float(np.sqrt(np.mean(pl_all**2))),
        datasets=datasets,
        undetermined=und,
        criteria=criteria,
        nfev=nfev,
        time_s=time.perf_counter() - t0,
        r_min_profile=r_profile,
        intervals=intervals,
    )

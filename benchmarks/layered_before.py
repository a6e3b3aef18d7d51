"""The layered fit as it was before issue 24, frozen for the benchmark and the no-regression record.

A copy of the search of ``terracone.inverse.layered.fit_layered`` at commit
8775439 (Python around scipy: a grid over (n_1, n_2) and the interface with
an NNLS/BVLS box solve per cell then Nelder-Mead for two layers, Nelder-Mead
from six seeded random starts for more), with its own copy of the forward
basis, so that ``benchmarks/layers.py`` can time "before" against "after" in
one run and ``tests/data/layered_rmsd_before.csv`` can be re-made:

    python benchmarks/layered_before.py tests/data/layered_rmsd_before.csv

Only the search and the RMSD/BIC are kept (no phic ridge, no result object).
Not part of the package; nothing in terracone imports it.
"""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear, minimize, nnls

from terracone.inverse.bounds import Bounds
from terracone.physics.cone import normal_integrals
from terracone.physics.plate import pressure_law

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "marsden-penetrometer"
# the two Marsden files; the CSV does not name its cone: the SC900's small cone (README of the data)
FILES = {"ci_profiles.csv": "asabe-small", "sc900_export_2019-06-11.txt": "asabe-small"}


def basis(z, n, interfaces, phic, law, cone):
    """Columns (Z, 3L) of the layered model (copy of physics.layers.layered_basis, 8775439)."""
    n = np.atleast_1d(np.asarray(n, float))
    D = np.concatenate([[0.0], np.atleast_1d(np.asarray(interfaces, float)), [np.inf]])
    R, H = cone.radius, cone.height
    t = R / H
    s = 1.0 + math.tan(math.radians(phic)) / t
    u1 = z + H
    L = np.where(z >= 0.0, H, u1)
    live = u1 > 0
    u1s = np.where(live, u1, 1.0)
    cols = []
    for j in range(n.size):
        a = np.clip(u1 - D[j + 1], 0.0, L)
        b = np.clip(u1 - D[j], 0.0, L)
        Ic, Ip, Icc = normal_integrals(u1s, a, b, n[j], law, t)
        cols += [
            np.where(live, 2.0 * t * s * Ic / (R * R), 0.0),
            np.where(live, 2.0 * t * s * Ip / (R * R), 0.0),
            np.where(live, 2.0 * Icc / (R * R), 0.0),
        ]
    return np.stack(cols, axis=-1)


def box_lsq(X, y, lo, hi):
    scale = np.sqrt(np.sum(X * X, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    Xs = X / scale
    if np.all(lo == 0):
        x = nnls_capped(X, Xs, y, hi, scale)
        if x is not None:
            r = X @ x - y
            return x, float(r @ r)
    res = lsq_linear(Xs, y, bounds=(lo * scale, hi * scale), method="bvls")
    x = res.x / scale
    r = X @ x - y
    return x, float(r @ r)


def nnls_capped(X, Xs, y, hi, scale):
    k = X.shape[1]
    at_hi = np.zeros(k, dtype=bool)
    x = np.zeros(k)
    for _ in range(k + 1):
        free = ~at_hi
        x[at_hi] = hi[at_hi]
        if not free.any():
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


def layer_box(bounds, ns):
    lo, hi = [], []
    for nj in ns:
        klo, khi = bounds.kc_si(nj)
        plo, phi_ = bounds.kphi_si(nj)
        lo += [float(klo), float(plo), bounds.cc[0]]
        hi += [float(khi), float(phi_), bounds.cc[1]]
    return np.array(lo), np.array(hi)


def fit_before(profile, layers=2, model="rm0", r_min=None, bounds=None, n_grid=12):
    """(n's, interfaces, SSE) of the layered search before issue 24, or None where that fit
    gave an error (fewer than 5 points per layer, or no room for an interface)."""
    bounds = bounds or Bounds()
    if profile.depth.size < max(3, 5 * layers):  # fit_layered's validate(min_points=...)
        return None
    law = pressure_law(model, r_min=r_min)
    z, y, cone = profile.depth, profile.ci, profile.cone
    phi = bounds.phic_deg[1]
    min_thick = 2 * float(np.median(np.diff(z)))

    def solve(ns, D):
        X = basis(z, ns, D, phi, law, cone)
        lo, hi = layer_box(bounds, ns)
        return box_lsq(X, y, lo, hi)

    lo_d, hi_d = z[0] + min_thick, z[-1] - min_thick
    cands = 0.5 * (z[1:] + z[:-1])
    cands = cands[(cands >= lo_d) & (cands <= hi_d)]
    if cands.size == 0:
        return None
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
        cols = {
            (i, k): basis(z, [ni, ni], [d], phi, law, cone)
            for i, ni in enumerate(ng)
            for k, d in enumerate(cands)
        }
        for k, d in enumerate(cands):
            for i, n1 in enumerate(ng):
                for j, n2 in enumerate(ng):
                    X = np.concatenate([cols[i, k][:, :3], cols[j, k][:, 3:]], axis=1)
                    lo, hi = layer_box(bounds, [n1, n2])
                    f = box_lsq(X, y, lo, hi)[1]
                    if f < best[0]:
                        best = (f, np.array([n1, n2, d]))
        starts.append(best[1])
    else:
        rng = np.random.default_rng(0)
        for _ in range(6):
            starts.append(
                np.concatenate(
                    [
                        rng.uniform(nlo, nhi, layers),
                        np.sort(rng.choice(cands, layers - 1, replace=False)),
                    ]
                )
            )
    best_v, best_f = None, np.inf
    for v0 in starts:
        f0 = objective(v0)
        res = minimize(
            objective,
            v0,
            method="Nelder-Mead",
            options={"xatol": 1e-6, "fatol": 1e-10 * max(f0, 1e-300), "maxiter": 2000},
        )
        v, f = (res.x, res.fun) if res.fun <= f0 else (v0, f0)
        if f < best_f:
            best_v, best_f = v, f
    ns = np.clip(best_v[:layers], nlo, nhi)
    D = np.sort(np.clip(best_v[layers:], lo_d, hi_d))
    return ns, D, solve(ns, D)[1]


def marsden_profiles():
    """(file, CIProfile) of every readable Marsden push (both files), in file order."""
    from terracone.io import read_ci_profiles

    out = []
    for name, cone in FILES.items():
        for p in read_ci_profiles(DATA / name, cone=cone, on_error="collect"):
            if hasattr(p, "depth"):
                out.append((name, p))
    return out


HEADER = (
    "# layered RMSD of the fit before issue 24 (terracone 8775439), our own fits of the\n"
    "# Marsden pushes in ../shared (not the data): made by\n"
    "#   python benchmarks/layered_before.py tests/data/layered_rmsd_before.csv\n"
    "# 2 and 3 layers: every readable push of both files (cone: asabe-small, the SC900 small\n"
    "# cone); status 'refused: ...' where that fit gave an error (no RMSD then)\n"
)
COLUMNS = [
    "file",
    "profile",
    "layers",
    "points",
    "rmsd_kpa",
    "interfaces_m",
    "n",
    "time_s",
    "status",
]


def refusal(profile, layers: int) -> str:
    """Why :func:`fit_before` gave no fit (its own two checks, in its order)."""
    N, need = profile.depth.size, max(3, 5 * layers)
    if N < need:
        return f"refused: {N} points; at least {need} are needed"
    return "refused: no interface fits the profile with the minimum layer thickness"


def record_row(name: str, p, layers: int) -> list:
    """The record's row of one push: the old fit's RMSD, interfaces and n's, or its refusal."""
    t0 = time.perf_counter()
    got = fit_before(p, layers=layers)
    dt = f"{time.perf_counter() - t0:.3f}"
    if got is None:
        return [name, p.id, layers, p.depth.size, "", "", "", dt, refusal(p, layers)]
    ns, D, sse = got
    return [
        name,
        p.id,
        layers,
        p.depth.size,
        f"{math.sqrt(sse / p.depth.size):.9g}",
        ";".join(f"{v:.9g}" for v in D),
        ";".join(f"{v:.9g}" for v in ns),
        dt,
        "ok",
    ]


def record(path: Path, keep: bool = True) -> None:
    """The old fit of every readable Marsden push with 2 and 3 layers, into ``path``.

    With ``keep``, rows already in ``path`` (same file, profile, layers and
    points) are kept as they are and only the missing pushes are fitted (a
    row without a status column was an ``ok`` fit); rows of pushes no longer
    read are dropped.  The rows follow the file order of the pushes.
    """
    old = {}
    if keep and path.exists():
        with open(path, newline="") as fh:
            for r in csv.DictReader(line for line in fh if not line.startswith("#")):
                r.setdefault("status", "ok")
                r["status"] = r["status"] or "ok"
                old[(r["file"], r["profile"], r["layers"], r["points"])] = [r[c] for c in COLUMNS]
    items = marsden_profiles()
    rows = []
    for layers in (2, 3):
        for name, p in items:
            key = (name, p.id, str(layers), str(p.depth.size))
            rows.append(old[key] if key in old else record_row(name, p, layers))
    with open(path, "w", newline="") as fh:
        fh.write(HEADER)
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        w.writerows(rows)


if __name__ == "__main__":
    record(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "tests/data/layered_rmsd_before.csv")

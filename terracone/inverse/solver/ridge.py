"""The ridge of equally good fits of one CI profile, computed on the exact solver.

For fixed n and phic the improved cone model (eqs. (2-5) to (2-7) of [1]_) is
linear in (kc, kphi, cc), so the best fit at every point of a (n, phic) grid is
one bounded linear least-squares solve.  The RMSD over that grid shows which
directions the data leave free: under fully mobilised shear it is flat along
phic, and along the common scale of kc and kphi it follows
scale * (1 + tan(phic)/tan(alpha)) = const.  Not in the paper.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.boxlsq import box_lsq3, gram
from terracone.inverse.solver.columns import bounds_arrays, design
from terracone.inverse.solver.intervals import CHI2_1_95
from terracone.physics.cone import get_cone
from terracone.physics.plate import pressure_law

__all__ = ["ridge_profile"]


def ridge_profile(
    depth: Any,
    ci: Any,
    *,
    cone: str = "asabe-large",
    model: str = "rm0",
    r_min: float | None = None,
    plate_pair: tuple[float, float] | None = None,
    bounds: Bounds | None = None,
    n_points: int = 79,
    phic_points: int = 46,
    scale_points: int = 81,
    noise_floor: float = 0.01,
    n_window: float = 0.45,
) -> dict[str, Any]:
    """RMSD of the best fit over a grid of (n, phic), and over (phic, scale).

    For fixed n and phic the improved model is linear in (kc, kphi, cc)
    (:func:`terracone.inverse.solver.columns.design`), so the best RMSD at each grid
    point is an exact bounded least-squares solve
    (:func:`terracone.inverse.solver.boxlsq.box_lsq3`), all points in one call.

    Returns
    -------
    dict
        ``n`` (Nn,), ``phic`` (Np,), ``rmsd`` (Nn, Np) [kPa] with kc, kphi and
        cc re-fitted at each point; ``best`` (n, phic, kc, kphi, cc, rmsd);
        ``scale`` (Ns,) and ``rmsd_scale`` (Ns, Np): RMSD when kc and kphi
        are the best fit's times ``scale`` at the best n and cc;
        ``threshold`` [kPa]: the RMSD below which a value lies inside the
        approximate 95% profile interval (sum of squares within
        3.84 sigma^2 of the optimum, sigma floored at ``noise_floor`` times
        the mean CI, as :mod:`terracone.inverse.solver.exact` does).

    The n grid spans ``n_window`` either side of the best n of a coarse
    pass (within the bounds), where the detail is.  Drawn by
    :func:`terracone.report.figures.fig_ridge`.
    """
    z = np.asarray(depth, dtype=float)
    y = np.asarray(ci, dtype=float)
    cone_obj = get_cone(cone)
    bounds = bounds or Bounds()
    law = pressure_law(model, r_min=r_min, plate_pair=plate_pair)
    phis = np.linspace(*bounds.phic_deg, phic_points)
    ns = _n_window(z, y, cone_obj, law, bounds, phis, n_points, n_window)
    X = design(z, ns[:, None, None], phis[None, :, None], cone=cone_obj, law=law, K_cone=None)
    G, g, yy = gram(X, np.broadcast_to(y, X.shape[:-1]))
    lo, hi = bounds_arrays(bounds, ns)
    x, sse = box_lsq3(G, g, yy, lo[:, None, :], hi[:, None, :])
    Z = y.size
    rmsd = np.sqrt(sse / Z)
    i, j = np.unravel_index(np.argmin(sse), sse.shape)
    # where the optimum is flat in phic, report the middle of the flat part
    smin = float(sse[i].min())
    flat = np.flatnonzero(sse[i] <= smin * (1 + 1e-9) + 1e-12 * float(y @ y))
    j = int(flat[len(flat) // 2])
    kc, kphi, cc = (float(v) for v in x[i, j])
    best = dict(
        n=float(ns[i]), phic=float(phis[j]), kc=kc, kphi=kphi, cc=cc, rmsd=float(rmsd[i, j])
    )
    # (phic, scale) at the best n: kc, kphi = scale * best, cc held
    scales = np.exp(np.linspace(math.log(0.4), math.log(2.5), scale_points))
    Xn = design(z, np.array(ns[i]), phis[:, None], cone=cone_obj, law=law, K_cone=None)
    base = Xn[..., 0] * kc + Xn[..., 1] * kphi  # (Np, Z)
    model_ci = scales[:, None, None] * base[None] + (Xn[..., 2] * cc)[None]
    rmsd_scale = np.sqrt(np.mean((model_ci - y) ** 2, axis=-1))  # (Ns, Np)
    dof = max(Z - 5, 1)
    sigma2 = max(smin / dof, (noise_floor * float(np.mean(np.abs(y)))) ** 2)
    threshold = math.sqrt((smin + CHI2_1_95 * sigma2) / Z)
    return {
        "n": ns,
        "phic": phis,
        "rmsd": rmsd,
        "best": best,
        "scale": scales,
        "rmsd_scale": rmsd_scale,
        "threshold": threshold,
        "half_angle": cone_obj.half_angle,
    }


def _n_window(z, y, cone, law, bounds, phis, n_points, half) -> np.ndarray:
    """n grid around the best n of a coarse pass at the middle phic."""
    coarse = np.linspace(*bounds.n, 40)
    X = design(z, coarse[:, None], np.array(phis[len(phis) // 2]), cone=cone, law=law, K_cone=None)
    G, g, yy = gram(X, np.broadcast_to(y, X.shape[:-1]))
    lo, hi = bounds_arrays(bounds, coarse)
    _, sse = box_lsq3(G, g, yy, lo, hi)
    nb = float(coarse[int(np.argmin(sse))])
    a, b = max(bounds.n[0], nb - half), min(bounds.n[1], nb + half)
    return np.linspace(a, b, n_points)

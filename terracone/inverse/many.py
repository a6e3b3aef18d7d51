"""The exact solver vectorised over many profiles at once (batch work).

Same problem as :mod:`terracone.inverse.exact` (fully mobilised shear):
minimise the RMSD of CI over kc, kphi, cc, n, phic within bounds.  Profiles
of different lengths are padded and masked; everything runs as a few numpy
calls over (profile, n) cells:

1. a grid over n; for each cell the bounded linear least squares in
   (kc', kphi', cc) with kc' = s kc, kphi' = s kphi and
   s = 1 + tan(phic)/tan(a) (eq. (2-6) with fully mobilised shear, so phic
   only scales the kc and kphi columns);
2. phic: when the lower bounds of kc and kphi are 0 the feasible boxes for
   increasing s are nested, so the optimum over phic is attained at the
   upper bound of phic and on the whole interval [phic*, phic_hi] where the
   scaled solution still fits in the box; the middle of that interval is
   reported (the exact ridge of section 2, never hidden).  Otherwise phic
   is put on a grid;
3. a golden-section refinement of n around each profile's best grid cell,
   vectorised across profiles.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-5) to (2-7), section 3.3.2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cone import Cone, cone_index_basis
from ..plate import PressureLaw
from .bounds import Bounds
from .boxlsq import box_lsq3

__all__ = ["ManySolution", "solve_exact_many"]

_GOLD = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass
class ManySolution:
    """Per-profile arrays (length P), SI."""

    kc: np.ndarray
    kphi: np.ndarray
    n: np.ndarray
    cc: np.ndarray
    phic_deg: np.ndarray
    phic_lo: np.ndarray
    phic_hi: np.ndarray
    sse: np.ndarray
    n_lo: np.ndarray
    n_hi: np.ndarray
    nfev: int


def _pad(depths: list[np.ndarray], cis: list[np.ndarray]):
    P = len(depths)
    Z = max(d.size for d in depths)
    zz = np.zeros((P, Z))
    yy = np.zeros((P, Z))
    w = np.zeros((P, Z))
    for i, (d, c) in enumerate(zip(depths, cis)):
        k = d.size
        zz[i, :k] = d
        zz[i, k:] = d[-1]
        yy[i, :k] = c
        w[i, :k] = 1.0
    return zz, yy, w


def solve_exact_many(
    depths: list[np.ndarray],
    cis: list[np.ndarray],
    *,
    cone: Cone,
    law: PressureLaw,
    bounds: Bounds,
    n_grid: int = 41,
    refine_iter: int = 28,
    noise_floor: float = 0.01,
) -> ManySolution:
    """Fit the improved model (fully mobilised shear) to many profiles.

    Parameters
    ----------
    depths, cis : list of (Z_i,) ndarray
        Base depths [m] and CI [kPa] of each profile (one cone).
    cone, law, bounds
        Cone, pressure law and search bounds (as in :func:`solve_exact`).
    n_grid : int
        Points of the global grid over n.
    refine_iter : int
        Golden-section iterations of the refinement of n.
    noise_floor : float
        Relative noise floor for the n interval (see :mod:`exact`).
    """
    zz, yy, w = _pad(depths, cis)
    P = zz.shape[0]
    t = math.tan(cone.half_angle)
    s_of = lambda phi: 1.0 + np.tan(np.radians(phi)) / t  # noqa: E731
    phi_lo, phi_hi = bounds.phic
    nested = bounds.kc[0] == 0.0 and bounds.kphi[0] == 0.0
    if phi_lo == phi_hi or nested:
        phis = np.array([phi_hi])
    else:
        phis = np.linspace(phi_lo, phi_hi, 19)
    svals = s_of(phis)  # (F,)
    yty = np.einsum("pz,pz->p", w * yy, yy)
    nfev = 0

    def cells(n: np.ndarray):
        """SSE and x for n of shape (P, K) and every phi: returns (P, K, F) arrays."""
        A, B, C = cone_index_basis(zz[:, None, :], n=n[..., None], phic=0.0, law=law, cone=cone)
        Aw, Bw = A * w[:, None, :], B * w[:, None, :]
        Cw = np.broadcast_to(C * w[:, None, :], Aw.shape)
        ab = (Aw * B).sum(-1)
        ac = (Aw * C).sum(-1)
        bc = (Bw * C).sum(-1)
        G = np.stack(
            [
                np.stack([(Aw * A).sum(-1), ab, ac], -1),
                np.stack([ab, (Bw * B).sum(-1), bc], -1),
                np.stack([ac, bc, (Cw * C).sum(-1)], -1),
            ],
            -2,
        )
        yk = yy[:, None, :]
        g = np.stack([(Aw * yk).sum(-1), (Bw * yk).sum(-1), (Cw * yk).sum(-1)], -1)
        # phic scales the kc and kphi columns by s
        D = np.ones((svals.size, 3))
        D[:, 0] = svals
        D[:, 1] = svals
        Gs = G[:, :, None] * D[None, None, :, :, None] * D[None, None, :, None, :]
        gs = g[:, :, None] * D[None, None]
        kc_lo, kc_hi = bounds.kc_si(n)
        kp_lo, kp_hi = bounds.kphi_si(n)
        lo = np.stack(np.broadcast_arrays(kc_lo, kp_lo, bounds.cc[0]), axis=-1)[:, :, None] + 0 * D
        hi = np.stack(np.broadcast_arrays(kc_hi, kp_hi, bounds.cc[1]), axis=-1)[:, :, None] + 0 * D
        x, sse = box_lsq3(Gs, gs, yty[:, None, None], lo, hi)
        return x * D, sse  # x in (kc', kphi', cc) -> multiply by s to get primed values

    ns = np.linspace(*bounds.n, n_grid) if bounds.n[0] != bounds.n[1] else np.array([bounds.n[0]])
    N = np.broadcast_to(ns, (P, ns.size))
    xg, sseg = cells(N)  # (P, Nn, F)
    nfev += sseg.size
    flat = sseg.reshape(P, -1)
    k = np.argmin(flat, axis=1)
    i_n, i_f = np.unravel_index(k, sseg.shape[1:])
    sse_n = sseg.min(axis=2)  # (P, Nn)

    n_best = ns[i_n]
    if ns.size > 1:
        step = ns[1] - ns[0]
        a = np.clip(n_best - step, *bounds.n)
        b = np.clip(n_best + step, *bounds.n)
        phi_idx = i_f

        def f(nv):
            _, s = cells(nv[:, None])
            return s[np.arange(P), 0, phi_idx]

        c = b - _GOLD * (b - a)
        d = a + _GOLD * (b - a)
        fc, fd = f(c), f(d)
        for _ in range(refine_iter):
            left = fc < fd
            b = np.where(left, d, b)
            a = np.where(left, a, c)
            d_new = np.where(left, c, a + _GOLD * (b - a))
            c_new = np.where(left, b - _GOLD * (b - a), d)
            fd_new = np.where(left, fc, np.nan)
            fc_new = np.where(left, np.nan, fd)
            # evaluate the one new point per profile
            new_pt = np.where(left, c_new, d_new)
            fnew = f(new_pt)
            fc = np.where(left, fnew, fc_new)
            fd = np.where(left, fd_new, fnew)
            c, d = c_new, d_new
            nfev += P
        n_ref = np.where(fc < fd, c, d)
        f_ref = np.minimum(fc, fd)
        grid_best = flat[np.arange(P), k]
        n_best = np.where(f_ref <= grid_best, n_ref, n_best)

    x, sse = cells(n_best[:, None])
    x = x[np.arange(P), 0, i_f]  # primed values (kc', kphi', cc)
    sse = sse[np.arange(P), 0, i_f]
    nfev += P

    # phic ridge: the interval of phic whose box still holds (kc', kphi')
    if phi_lo == phi_hi:
        ph_lo = ph_hi = ph = np.full(P, phi_lo)
    elif nested:
        kc_hi = bounds.kc_si(n_best)[1]
        kp_hi = bounds.kphi_si(n_best)[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            s_need = np.maximum(
                np.where(kc_hi > 0, x[:, 0] / kc_hi, 0.0), np.where(kp_hi > 0, x[:, 1] / kp_hi, 0.0)
            )
        s_need = np.maximum(s_need, s_of(phi_lo))
        ph_lo = np.degrees(np.arctan((s_need - 1.0) * t))
        ph_lo = np.clip(ph_lo, phi_lo, phi_hi)
        ph_hi = np.full(P, phi_hi)
        ph = 0.5 * (ph_lo + ph_hi)
    else:
        ph = phis[i_f]
        ph_lo = ph_hi = ph
    s = s_of(ph)
    kc = x[:, 0] / s
    kphi = x[:, 1] / s

    # n interval from the grid profile (95% profile likelihood, noise floor)
    npts = w.sum(axis=1)
    mean_y = np.einsum("pz,pz->p", w, np.abs(yy)) / npts
    sigma2 = np.maximum(sse / np.maximum(npts - 5, 1), (noise_floor * mean_y) ** 2)
    thr = sse + 3.841458820694124 * sigma2
    ok = sse_n <= thr[:, None]
    big = np.where(ok, ns[None, :], -np.inf).max(axis=1)
    small = np.where(ok, ns[None, :], np.inf).min(axis=1)
    n_lo = np.minimum(np.where(np.isfinite(small), small, n_best), n_best)
    n_hi = np.maximum(np.where(np.isfinite(big), big, n_best), n_best)
    return ManySolution(kc, kphi, n_best, x[:, 2], ph, ph_lo, ph_hi, sse, n_lo, n_hi, nfev)

"""The likelihood of the posterior: whitened basis columns of eq. (2-7), tabulated over n.

The CI basis columns of eq. (2-7) (kc, kphi and cc coefficients, with and
without the tan(phic) shear part) are tabulated once per profile on a grid of
n (step <= 0.02) and interpolated by cubic splines (relative error ~1e-7), so
finite Kc costs the same as fully mobilised shear.  The whitened sum of
squares of all walkers is one compiled kernel (:func:`spline_sse_compiled`,
numba; its numpy twin :func:`spline_sse` is the tested reference and is used
when TERRACONE_NUMBA=0).

The likelihood of :func:`terracone.inverse.uncertainty.posterior.posterior`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-6), (2-7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.interpolate import CubicSpline

from terracone.inverse.uncertainty.noise import POSTERIOR_MAX_POINTS, bin_readings, whiten_ar1
from terracone.jit import enabled, njit
from terracone.physics.cone import Cone, cone_index_basis
from terracone.physics.plate import PressureLaw

__all__ = [
    "Likelihood",
    "spline_sse",
    "spline_sse_compiled",
]


def spline_sse(
    coef: np.ndarray,
    n0: float,
    h: float,
    wy: np.ndarray,
    params: np.ndarray,
    t: float,
    rho: np.ndarray,
    dzr: np.ndarray,
) -> np.ndarray:
    """Whitened sum of squares of parameter rows against tabulated basis columns (numpy).

    The reference implementation of :func:`spline_sse_compiled` (the
    log-likelihood kernel of :func:`~terracone.inverse.uncertainty.posterior.posterior`).
    The model CI of eq. (2-7) is ``s (kc A + kphi B) + cc C`` with ``s = 1 + tan(phic)/t`` (fully
    mobilised shear, eq. (2-6); K = 3 columns) or ``kc (A_p + tan(phic)
    A_s) + kphi (B_p + tan(phic) B_s) + cc C`` (finite Kc; K = 5), with
    every column already divided by the noise weights and whitened, and
    tabulated over n as a cubic spline.

    Parameters
    ----------
    coef : ndarray, shape (4, G, Z, K)
        Spline coefficients on the uniform grid ``n0 + h * i`` (highest
        power first, as :class:`scipy.interpolate.CubicSpline` stores them)
        [kPa per unit parameter].
    n0, h : float
        First grid node and step of n [-].
    wy : ndarray, shape (Z,)
        Whitened, weighted measured CI [kPa].
    params : ndarray, shape (P, 5)
        kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-], cc [kPa], phic [deg].
    t : float
        tan of the cone half angle [-].
    rho : ndarray, shape (P,) or (0,)
        AR(1) coefficient per row when it is sampled (the whitening of the
        columns then happens here, row by row); empty otherwise.
    dzr : ndarray, shape (Z - 1,)
        Spacings over the reference spacing [-].

    Returns
    -------
    ndarray, shape (P,)
        Sum of squared whitened residuals [kPa^2].

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.
       Predicting terrain parameters for physics-based vehicle mobility
       models from cone index data. Eqs. (2-6), (2-7).
    """
    kc, kphi, n, cc, phic = (params[:, j] for j in range(5))
    i = np.clip(((n - n0) / h).astype(np.int64), 0, coef.shape[1] - 1)
    dx = (n - (n0 + i * h))[:, None, None]
    c = coef[:, i]  # (4, P, Z, K)
    col = ((c[0] * dx + c[1]) * dx + c[2]) * dx + c[3]
    tau = np.tan(phic * (math.pi / 180.0))[:, None]
    if coef.shape[3] == 3:  # eq. (2-6): the shear part is the normal part / t
        s = 1.0 + tau / t
        r = (s * kc[:, None]) * col[..., 0] + (s * kphi[:, None]) * col[..., 1]
        r = r + cc[:, None] * col[..., 2] - wy
    else:  # eq. (2-7)
        r = (
            kc[:, None] * (col[..., 0] + tau * col[..., 1])
            + kphi[:, None] * (col[..., 2] + tau * col[..., 3])
            + cc[:, None] * col[..., 4]
        ) - wy
    if rho.size and wy.size > 1:
        phi = rho[:, None] ** dzr
        r[:, 1:] = (r[:, 1:] - phi * r[:, :-1]) / np.sqrt(1.0 - phi * phi)
    return np.sum(r * r, axis=1)


@njit
def spline_sse_compiled(coef, n0, h, wy, params, t, rho, dzr):  # pragma: no cover - numba
    """:func:`spline_sse` compiled with numba (one pass per row, no temporaries).

    Agrees with :func:`spline_sse` to rounding (tests: 1e-12 relative).
    With TERRACONE_NUMBA=0 this is plain Python; the posterior then
    calls :func:`spline_sse` instead.
    """
    P = params.shape[0]
    G = coef.shape[1]
    Z = wy.shape[0]
    K = coef.shape[3]
    out = np.empty(P)
    col = np.empty(K)
    for p in range(P):
        kc, kphi, n, cc, phic = params[p, 0], params[p, 1], params[p, 2], params[p, 3], params[p, 4]
        i = int((n - n0) / h)
        i = min(max(i, 0), G - 1)
        dx = n - (n0 + i * h)
        tau = math.tan(phic * (math.pi / 180.0))
        s = 1.0 + tau / t
        acc = 0.0
        prev = 0.0
        for z in range(Z):
            for k in range(K):
                col[k] = ((coef[0, i, z, k] * dx + coef[1, i, z, k]) * dx + coef[2, i, z, k]) * dx
                col[k] += coef[3, i, z, k]
            if K == 3:  # eq. (2-6)
                r = (s * kc) * col[0] + (s * kphi) * col[1]
                r = r + cc * col[2] - wy[z]
            else:  # eq. (2-7)
                r = kc * (col[0] + tau * col[1]) + kphi * (col[2] + tau * col[3]) + cc * col[4]
                r = r - wy[z]
            if rho.shape[0] > 0 and z > 0:
                phi = rho[p] ** dzr[z - 1]
                u = (r - phi * prev) / math.sqrt(1.0 - phi * phi)
            else:
                u = r
            prev = r
            acc += u * u
        out[p] = acc
    return out


class Likelihood:
    """Whitened residuals of arrays of parameter sets against one profile.

    CI = kc (A_p + tan(phic) A_s) + kphi (B_p + tan(phic) B_s) + cc C, eq.
    (2-7), where _p is the normal-pressure and _s the shear part; the
    columns are whitened (divided by w, AR(1)) and tabulated over n.  With
    fully mobilised shear A_s = A_p / tan(half angle) (likewise B), so three
    columns are kept and CI = s (kc A_p + kphi B_p) + cc C.

    Parameters
    ----------
    z, y : ndarray
        Depths [m] and measured CI [kPa]; more than
        :data:`~terracone.inverse.uncertainty.noise.POSTERIOR_MAX_POINTS` readings
        are binned as :func:`~terracone.inverse.uncertainty.noise.noise_setup` bins them.
    cone : Cone
    law : PressureLaw
    K_cone : float or None
        Cone-terrain shear deformation parameter [m]; None: fully mobilised.
    n_range : (float, float)
        Range of n tabulated [-] (one value: n fixed).
    weights : ndarray
        Noise weights w_i, RMS 1 [-].
    phi : ndarray or None
        AR(1) lag-1 coefficients between neighbours (N - 1,); None when rho
        is sampled (whitening per parameter row in :meth:`sse`).
    spacing : float, optional
        Reference spacing dz0 [m] of a sampled rho.

    Attributes
    ----------
    coef : ndarray, shape (4, G, Z, K)
        Spline coefficients of the whitened columns over n (for
        :func:`spline_sse`); ``n0``, ``h`` its grid.
    wy : ndarray
        Whitened, weighted CI [kPa].

    References
    ----------
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.
       Predicting terrain parameters for physics-based vehicle mobility
       models from cone index data. Eqs. (2-6), (2-7).
    """

    def __init__(
        self,
        z: np.ndarray,
        y: np.ndarray,
        *,
        cone: Cone,
        law: PressureLaw,
        K_cone: float | None,
        n_range: tuple[float, float],
        weights: np.ndarray,
        phi: np.ndarray | None,
        spacing: float | None = None,
    ) -> None:
        # a long profile: its bins, as noise_setup takes them (the weights are the bins')
        z, y, _ = bin_readings(z, y, POSTERIOR_MAX_POINTS)
        if np.shape(weights) != y.shape:
            raise ValueError(
                f"{np.size(weights)} noise weights for {y.size} readings (noise_setup's weights?)"
            )
        self.z, self.y, self.cone, self.law, self.K_cone = z, y, cone, law, K_cone
        self.t = math.tan(cone.half_angle)
        self.w = weights
        self.N = y.size
        # phi None: rho varies per parameter set (sampled), whiten per row
        self.per_row = phi is None
        dz = np.diff(z)
        self.dzr = dz / (float(np.median(dz)) if spacing is None else spacing) if dz.size else dz
        if phi is None:
            phi = np.zeros(max(self.N - 1, 0))
        self.phi = phi
        self.fixed_n = n_range[0] == n_range[1]
        if self.fixed_n:
            grid = np.array([n_range[0]])
        else:
            k = max(33, int(math.ceil((n_range[1] - n_range[0]) / 0.02)) + 1)
            grid = np.linspace(n_range[0], n_range[1], k)
        cols = self._columns(grid)  # (G, Z, K), K = 3 or 5
        wcols = whiten_ar1(np.moveaxis(cols / weights[None, :, None], 1, -1), phi)  # (G, K, Z)
        wcols = np.moveaxis(wcols, -1, 1)  # (G, Z, K)
        self.wy = whiten_ar1(y / weights, phi)
        self.grid, self.wcols = grid, wcols
        if self.fixed_n:  # a constant "spline": only the last coefficient
            self.coef = np.zeros((4, 1) + wcols.shape[1:])
            self.coef[3, 0] = wcols[0]
            self.n0, self.h = float(grid[0]), 1.0
        else:
            # cubic spline on the uniform grid, evaluated by Horner's rule on gathered coefficients
            self.coef = np.ascontiguousarray(CubicSpline(grid, wcols, axis=0).c)  # (4, G-1, Z, K)
            self.n0, self.h = float(grid[0]), float(grid[1] - grid[0])
        self.dzr = np.ascontiguousarray(self.dzr, dtype=float)
        self.wy = np.ascontiguousarray(self.wy, dtype=float)

    def _columns(self, n: np.ndarray) -> np.ndarray:
        nn = np.asarray(n, dtype=float)[:, None]
        kw = dict(n=nn, K_cone=self.K_cone, law=self.law, cone=self.cone)
        A0, B0, C0 = cone_index_basis(self.z, phic_deg=0.0, **kw)
        if self.K_cone is None:
            # fully mobilised: the shear part is the normal part / tan(half angle), eq. (2-6)
            A0, B0, C0 = np.broadcast_arrays(A0, B0, C0)
            return np.stack([A0, B0, C0], axis=-1)
        A1, B1, _ = cone_index_basis(self.z, phic_deg=45.0, **kw)  # tan 45 deg = 1
        A0, B0, C0, A1, B1 = np.broadcast_arrays(A0, B0, C0, A1, B1)
        return np.stack([A0, A1 - A0, B0, B1 - B0, C0], axis=-1)

    def columns(self, n: np.ndarray) -> np.ndarray:
        """Whitened columns at n, (P, Z, K)."""
        n = np.asarray(n, dtype=float)
        i = np.clip(((n - self.n0) / self.h).astype(np.int64), 0, self.coef.shape[1] - 1)
        dx = (n - (self.n0 + i * self.h))[:, None, None]
        c = self.coef[:, i]  # (4, P, Z, K)
        return ((c[0] * dx + c[1]) * dx + c[2]) * dx + c[3]

    def residuals(self, kc, kphi, n, cc, phic_deg, rho=None) -> np.ndarray:
        """Whitened residuals u (P, Z) of parameter arrays (P,) (and rho (P,) if sampled)."""
        c = self.columns(n)
        tau = np.tan(np.radians(phic_deg))[:, None]
        if self.K_cone is None:
            s = 1.0 + tau / self.t
            m = (s * kc[:, None]) * c[..., 0] + (s * kphi[:, None]) * c[..., 1]
            r = m + cc[:, None] * c[..., 2] - self.wy
        else:
            m = (
                kc[:, None] * (c[..., 0] + tau * c[..., 1])
                + kphi[:, None] * (c[..., 2] + tau * c[..., 3])
                + cc[:, None] * c[..., 4]
            )
            r = m - self.wy
        if self.per_row and rho is not None and self.N > 1:
            phi = np.asarray(rho, dtype=float)[:, None] ** self.dzr
            r[:, 1:] = (r[:, 1:] - phi * r[:, :-1]) / np.sqrt(1.0 - phi * phi)
        return r

    def sse(self, params: np.ndarray, rho: np.ndarray | None = None) -> np.ndarray:
        """Whitened sum of squares Q of parameter rows (P, 5) (and rho (P,) if sampled)."""
        params = np.ascontiguousarray(params, dtype=float)
        r = np.zeros(0) if rho is None or not self.per_row else np.asarray(rho, dtype=float)
        kernel = spline_sse_compiled if enabled() else spline_sse
        return kernel(self.coef, self.n0, self.h, self.wy, params, self.t, r, self.dzr)

    def gram_half_logdet(self, free: Sequence[bool], phic_deg: float = 0.0) -> np.ndarray:
        """0.5 log det G(n) on the n grid (G,), G the Gram matrix of the free linear columns.

        ``free`` flags kc, kphi, cc.  Fully mobilised shear: the columns of
        (s kc, s kphi, cc) (s does not depend on n); finite Kc: those of (kc,
        kphi, cc) at ``phic_deg``.  sqrt(det G(n)) is the Jeffreys prior of
        the linear parameters given n (invariant to n-dependent unit
        changes of kc and kphi); with it, the marginal posterior of n under
        flat linear parameters is the profile likelihood of n (the
        det G^(-1/2) of the Gaussian integral cancels).
        """
        c = self.wcols
        if self.K_cone is not None:
            tau = math.tan(math.radians(phic_deg))
            c = np.stack([c[..., 0] + tau * c[..., 1], c[..., 2] + tau * c[..., 3], c[..., 4]], -1)
        c = c[..., np.asarray(free, bool)]
        if c.shape[-1] == 0:
            return np.zeros(self.grid.size)
        G = np.einsum("gzk,gzl->gkl", c, c)
        sign, logdet = np.linalg.slogdet(G)
        return np.where(sign > 0, 0.5 * logdet, -np.inf)

    def half_logdet(self, rho: np.ndarray) -> np.ndarray:
        """0.5 log det of the AR(1) correlation matrix at rho (P,): 0.5 sum log(1 - phi^2)."""
        if self.N < 2:
            return np.zeros(np.shape(rho))
        phi = np.asarray(rho, dtype=float)[:, None] ** self.dzr
        return 0.5 * np.sum(np.log1p(-phi * phi), axis=1)

"""The columns of the improved model's linear structure, for the solvers.

For fixed n, phic and K_cone the improved model (eq. (2-7) in [1]_) is linear
in kc, kphi and cc: CI = X @ (kc, kphi, cc).  :func:`design` builds X, and
:func:`bounds_arrays` the box of (kc, kphi, cc) at each n.  The exact solver
(:mod:`.exact`), the identifiability scans (:mod:`.intervals`), the ridge
(:mod:`.ridge`) and the learning process share them.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-5) to (2-7).
"""

from __future__ import annotations

import math

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.solver.kernels import basis_columns, basis_rows
from terracone.jit import enabled
from terracone.physics.cone import Cone, cone_index_basis
from terracone.physics.plate import PressureLaw

__all__ = ["design", "basis_mobilised", "bounds_arrays"]


def design(
    z: np.ndarray,
    n: np.ndarray,
    phic_deg: np.ndarray,
    *,
    cone: Cone,
    law: PressureLaw,
    K_cone: np.ndarray | float | None,
    ratio: float | None = None,
) -> np.ndarray:
    """Design matrix X (..., Z, 3) with CI = X @ (kc, kphi, cc); n, phic broadcast.

    With ``ratio`` (kc/kphi [m] held fixed) the kc column is folded into the
    kphi column, CI = X @ (0, kphi, cc), and kc = ratio * kphi.
    """
    if K_cone is None:
        # eq. (2-6) fully mobilised: phic only scales the kc and kphi columns
        A, B, C = basis_mobilised(z, n, law, cone)
        s = 1.0 + np.tan(np.radians(phic_deg)) / math.tan(cone.half_angle)
        A, B = s * A, s * B
    else:
        A, B, C = cone_index_basis(z, n=n, phic_deg=phic_deg, K_cone=K_cone, law=law, cone=cone)
    A, B, C = np.broadcast_arrays(A, B, C)
    if ratio is not None:
        return np.stack([np.zeros_like(A), ratio * A + B, C], axis=-1)
    return np.stack([A, B, C], axis=-1)


def basis_mobilised(z, n, law: PressureLaw, cone: Cone):
    """cone_index_basis at phic = 0.

    Compiled (:func:`terracone.inverse.solver.kernels.basis_columns`, equal to it to
    1e-12) for one profile and one n, and :func:`~terracone.inverse.solver.kernels.basis_rows`
    for profiles (P, Z) with one n each (P, 1), as predict_many's polish asks;
    else the numpy basis.
    """
    n = np.asarray(n, dtype=float)
    z = np.asarray(z, dtype=float)
    one = n.ndim == 0 and z.ndim == 1
    rows = z.ndim == 2 and n.shape == (z.shape[0], 1)
    if (one or rows) and enabled():
        coef = [np.asarray(c, dtype=float) for c in law.coefficients()]
        if all(c.size == 1 for c in coef):
            args = (cone.height, cone.radius, not law.is_rm0, *(float(c.item()) for c in coef))
            if one:
                A, B, C = basis_columns(np.ascontiguousarray(z), n.reshape(1), *args)
                return A[0], B[0], C[0]
            return basis_rows(np.ascontiguousarray(z), np.ascontiguousarray(n[:, 0]), *args)
    return cone_index_basis(z, n=n, phic_deg=0.0, law=law, cone=cone)


def bounds_arrays(bounds: Bounds, n: np.ndarray, ratio: float | None = None):
    """The box (lo, hi) of (kc, kphi, cc) [SI] at each n, shape (..., 3); kc folded with ``ratio``."""
    kc_lo, kc_hi = bounds.kc_si(n)
    kp_lo, kp_hi = bounds.kphi_si(n)
    if ratio is not None:
        # kc = ratio * kphi: both bounds apply to kphi, kc is pinned at 0 in the solve
        kp_lo = np.maximum(kp_lo, kc_lo / ratio) if ratio > 0 else kp_lo
        kp_hi = np.minimum(kp_hi, kc_hi / ratio) if ratio > 0 else kp_hi
        kp_hi = np.maximum(kp_hi, kp_lo)
        kc_lo = kc_hi = np.zeros(np.shape(n))
    lo = np.stack([kc_lo, kp_lo, np.full(np.shape(n), bounds.cc[0])], axis=-1)
    hi = np.stack([kc_hi, kp_hi, np.full(np.shape(n), bounds.cc[1])], axis=-1)
    return lo, hi

"""Layered terrain: the improved cone model with depth-dependent parameters.

Eqs. (2-5) and (2-6) of [1]_ integrated element by element with the kc_j,
kphi_j, n_j, cc_j of the layer at each element's depth (phic common to all);
``docs/instruments.md`` ("Layered fits") states the model and its limits.
The fit lives in :mod:`terracone.inverse.layered`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from terracone.physics.cone import Cone, check_depth, normal_integrals
from terracone.physics.plate import PressureLaw, pressure_law

__all__ = ["Layer", "layered_basis", "layered_cone_index"]


class Layer(Protocol):
    """What a layer needs: :class:`terracone.data.TerrainParameters` is one (SI)."""

    kc: float  # [kN/m^(n+1)]
    kphi: float  # [kN/m^(n+2)]
    n: float  # [-]
    cc: float  # [kPa]
    phic_deg: float  # [deg]


def layered_basis(
    depth: np.ndarray,
    *,
    n: np.ndarray,
    interfaces: np.ndarray,
    phic_deg: float = 0.0,
    law: PressureLaw | None = None,
    cone: Cone,
) -> np.ndarray:
    """Columns of the layered model: CI = X @ (kc_1, kphi_1, cc_1, kc_2, ...).

    Parameters
    ----------
    depth : (Z,) array_like
        Cone-base depths [m].
    n : (L,) array_like
        Exponent of each layer.
    interfaces : (L-1,) array_like
        Depths of the layer boundaries [m], increasing.
    phic_deg : float
        Common cone-metal friction angle [deg] (fully mobilised shear).
    law : PressureLaw
        RM0 or RM1 (section 3.2).
    cone : Cone

    Returns
    -------
    (Z, 3L) ndarray
    """
    law = law or pressure_law("rm0")
    z = check_depth(depth, cone)
    n = np.atleast_1d(np.asarray(n, float))
    D = np.concatenate([[0.0], np.atleast_1d(np.asarray(interfaces, float)), [np.inf]])
    if n.size != D.size - 1:
        raise ValueError("need one n per layer (len(interfaces) + 1)")
    R, H = cone.radius, cone.height
    t = R / H
    s = 1.0 + math.tan(math.radians(phic_deg)) / t
    u1 = z + H
    L = np.where(z >= 0.0, H, u1)
    live = u1 > 0
    u1s = np.where(live, u1, 1.0)
    cols = []
    for j in range(n.size):
        # layer j spans depths [D_j, D_(j+1)): distances from the tip [u1 - D_(j+1), u1 - D_j]
        a = np.clip(u1 - D[j + 1], 0.0, L)
        b = np.clip(u1 - D[j], 0.0, L)
        Ic, Ip, Icc = normal_integrals(u1s, a, b, n[j], law, t)
        # eq. (2-7) with eq. (2-6) fully mobilised: CI = [2 (t + tan phic) I + 2 cc I_cc] / R^2
        cols += [
            np.where(live, v / (R * R), 0.0) for v in (2 * t * s * Ic, 2 * t * s * Ip, 2 * Icc)
        ]
    return np.stack(cols, axis=-1)


def layered_cone_index(
    depth: np.ndarray,
    layers: Sequence[Layer],
    interfaces: Sequence[float],
    *,
    cone: Cone,
    law: PressureLaw | None = None,
) -> np.ndarray:
    """CI [kPa] of a layered terrain (SI; phic taken from the first layer).

    Parameters
    ----------
    depth : (Z,) array_like
        Cone-base depths [m].
    layers : sequence of TerrainParameters (or any :class:`Layer`)
        Each layer's kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-] and cc [kPa],
        top first; phic [deg] of the first layer is common to all.
    interfaces : list of float
        Depths of the layer boundaries [m], increasing (one fewer than layers).
    cone : Cone
    law : PressureLaw, optional
        RM0 (default) or RM1 (section 3.2).

    Returns
    -------
    (Z,) ndarray
        Cone index [kPa].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eqs. (2-5) to (2-7).
    """
    X = layered_basis(
        depth,
        n=[p.n for p in layers],
        interfaces=interfaces,
        phic_deg=layers[0].phic_deg,
        law=law,
        cone=cone,
    )
    x = np.concatenate([[p.kc, p.kphi, p.cc] for p in layers])
    return X @ x  # eq. (2-7), layer by layer

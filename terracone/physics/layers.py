"""Layered terrain: the improved cone model with depth-dependent parameters.

Real soils are layered (tillage pans, crusts, wet subsoils); the paper's
model assumes a homogeneous terrain over the fitted depths (assumption (a),
section 2 of [1]_).  This module extends eqs. (2-5) and (2-6) in the plainest
consistent way: the terrain is a stack of layers, layer j between depths
D_(j-1) and D_j (D_0 = 0, the last layer unbounded below), each with its own
Bekker parameters kc_j, kphi_j, n_j and cone-metal adhesion cc_j; the
cone-metal friction phic is common to all layers.  The cone's load is
integrated element by element with the parameters of the layer at each
element's depth, i.e. eq. (2-2) becomes p = (kc_j/r + kphi_j) u^(n_j) at
depth u in layer j, with u still measured from the terrain surface.

Limits of the assumption: a layer does not "feel" the layers below or above
(no load spreading, no interface effect); the pressure in a layer grows with
depth from the surface, not from the layer top; the shear is fully
mobilised.  It is a description of the CI curve, not a soil-mechanics model
of the interface.

This module is the forward model.  The fit
(:func:`~terracone.inverse.layered.fit_layered`, compared with the one-layer
fit by BIC) lives in :mod:`terracone.inverse.layered`.

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
            np.where(live, 2.0 * t * s * Ic / (R * R), 0.0),
            np.where(live, 2.0 * t * s * Ip / (R * R), 0.0),
            np.where(live, 2.0 * Icc / (R * R), 0.0),
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
    .. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
       terrain parameters for physics-based vehicle mobility models from cone
       index data. Eqs. (2-5) to (2-7).
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

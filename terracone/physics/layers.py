"""Layered terrain: the improved cone model with depth-dependent parameters.

Eqs. (2-5) and (2-6) of [1]_ integrated element by element with the kc_j,
kphi_j, n_j, cc_j of the layer at each element's depth (phic common to all);
``docs/instruments.md`` ("Layered fits") states the model and its limits.
The fit lives in :mod:`terracone.inverse.layered`.  The same model's plate
pressure-sinkage relation is :func:`layered_plate` (:class:`LayeredPlate`).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from terracone.physics.cone import Cone, check_depth, normal_integrals
from terracone.physics.plate import PressureLaw, pressure_law

__all__ = [
    "Layer",
    "LayeredPlate",
    "layered_basis",
    "layered_cone_index",
    "layered_plate",
    "layered_plate_pressure",
]


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


@dataclass(frozen=True)
class LayeredPlate:
    """The pressure-sinkage of a plate of one size b on a layered terrain (SI).

    p(z) = k_j z^(n_j) for D_(j-1) <= z < D_j (D_0 = 0, the last layer
    unbounded below): a depth on an interface belongs to the layer below.
    One layer is Bekker's plate, p = k z^n.

    Attributes
    ----------
    k : tuple of float
        Each layer's modulus at this plate size, k_j = kc_j f(b) + kphi_j
        [kN/m^(n_j + 2)] (f(b) = 1/b with RM0), top first, each >= 0.
    n : tuple of float
        Each layer's exponent [-], > 0.
    interfaces : tuple of float
        Depths D_1 < D_2 < ... of the layer boundaries [m], > 0.
    width : float
        Plate size b [m].
    """

    k: tuple[float, ...]
    n: tuple[float, ...]
    interfaces: tuple[float, ...] = ()
    width: float = 1.0

    def __post_init__(self) -> None:
        k, n, D = (tuple(float(v) for v in a) for a in (self.k, self.n, self.interfaces))
        object.__setattr__(self, "k", k)
        object.__setattr__(self, "n", n)
        object.__setattr__(self, "interfaces", D)
        if not (len(k) == len(n) == len(D) + 1):
            raise ValueError("need one k and one n per layer, and one interface fewer")
        if not all(math.isfinite(v) and v >= 0 for v in k):
            raise ValueError(f"each layer's k must be finite and >= 0 (got {list(k)})")
        if not all(math.isfinite(v) and v > 0 for v in n):
            raise ValueError(f"each layer's n must be finite and > 0 (got {list(n)})")
        if any(not (v > 0 and math.isfinite(v)) for v in D) or any(
            b <= a for a, b in zip(D, D[1:])
        ):
            raise ValueError(f"interfaces must be positive and increase (got {list(D)})")
        if not (math.isfinite(self.width) and self.width > 0):
            raise ValueError(f"plate size must be > 0 m (got {self.width!r})")

    @property
    def bounds(self) -> tuple[float, ...]:
        """Layer boundaries (0, D_1, ..., inf) [m]."""
        return (0.0, *self.interfaces, math.inf)

    def layer_of(self, sinkage: np.ndarray) -> np.ndarray:
        """Index of the layer that holds each depth [m] (the one below on an interface)."""
        return np.searchsorted(np.asarray(self.interfaces), np.asarray(sinkage, float), "right")

    def pressure(self, sinkage: np.ndarray) -> np.ndarray:
        """p [kPa] at sinkages z >= 0 [m]: eq. (2-2) of the layer at depth z."""
        z = np.asarray(sinkage, dtype=float)
        j = self.layer_of(z)
        k, n = np.asarray(self.k)[j], np.asarray(self.n)[j]
        return k * np.where(z > 0, np.abs(z), 0.0) ** n  # eq. (2-2) of layer j


def layered_plate(
    layers: Sequence[Layer],
    interfaces: Sequence[float],
    *,
    width: float,
    law: PressureLaw | None = None,
) -> LayeredPlate:
    """The plate pressure-sinkage p(z; b) of a layered terrain: the layer at the plate's depth.

    A plate of size b at sinkage z bears with the law of the layer that holds
    depth z: p = [kc_j f(b) + kphi_j] z^(n_j) for D_(j-1) <= z < D_j, with
    f(b) = 1/b (eq. (2-2), RM0) or RM1's alpha - beta b below its transition
    radius (section 3.2 in [1]_), z measured from the surface.  It is the
    pressure the layered cone model (:func:`layered_basis`) puts on each
    element of the cone, here on a plate: the model the layers were fitted
    with.  Its assumptions are that model's: a layer does not feel the layers
    above or below it (no load spreading: the plate feels a layer only once
    it reaches it), and the pressure in a layer grows with the depth from the
    surface.  So p jumps at an interface, up onto a harder layer and down onto
    a softer one; a wheel integrates it, and its load stays continuous in its
    sinkage (``docs/export.md``, "Effective soil").  A stack of identical
    layers is Bekker's homogeneous plate.

    Parameters
    ----------
    layers : sequence of TerrainParameters (or any :class:`Layer`)
        kc [kN/m^(n+1)], kphi [kN/m^(n+2)] and n [-] of each layer, top first.
    interfaces : sequence of float
        Depths of the layer boundaries [m], increasing (one fewer than layers).
    width : float
        Plate size b [m]: the smaller side of a rectangle (a wheel's or a
        track's width), the radius of a circle.
    law : PressureLaw, optional
        RM0 (default) or RM1 (section 3.2 in [1]_).

    Returns
    -------
    LayeredPlate

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eq. (2-2) and section 3.2.
    """
    law = law or pressure_law("rm0")
    if not (math.isfinite(width) and width > 0):
        raise ValueError(f"width must be > 0 m (got {width!r})")
    f = float(law.kc_factor(width))  # 1/b (RM0) or alpha - beta b (RM1), section 3.2
    k = [p.kc * f + p.kphi for p in layers]  # eq. (2-2): p / z^n of each layer
    return LayeredPlate(tuple(k), tuple(p.n for p in layers), tuple(interfaces), float(width))


def layered_plate_pressure(
    sinkage: np.ndarray,
    layers: Sequence[Layer],
    interfaces: Sequence[float],
    *,
    width: float,
    law: PressureLaw | None = None,
) -> np.ndarray:
    """Plate pressure p(z; b) [kPa] of a layered terrain at sinkages z [m].

    :func:`layered_plate` (the model, its assumptions) evaluated at ``sinkage``.

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eq. (2-2) and section 3.2.
    """
    return layered_plate(layers, interfaces, width=width, law=law).pressure(sinkage)

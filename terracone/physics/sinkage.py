"""Sinkage of a rigid wheel and of a track on a (layered) plate pressure-sinkage law.

Bekker's analysis of a rigid wheel [1]_ [2]_: the terrain under a point of the
rim at the local sinkage z pushes as a plate of the wheel's width b at that
sinkage, p(z; b), vertically on the horizontal projection of the contact; the
contact is the front arc from the bottom (sinkage z0) to the surface, the rear
being unloaded.  The vertical equilibrium with the load W is

    W = b int_0^theta0 p(z(theta)) r cos(theta) dtheta = b int_0^x0 p dx,
    z(theta) = r (cos(theta) - cos(theta0)),  cos(theta0) = 1 - z0 / r,

with r = D / 2 and x = r sin(theta) the horizontal distance from the bottom.
:func:`wheel_load` evaluates it for a plate law p = k_j z^(n_j) that may change
with depth (:class:`~terracone.physics.layers.LayeredPlate`; one layer is
Bekker's homogeneous terrain) and :func:`sinkage_rigid_wheel` solves it for
z0.  With one layer and the shallow-contact approximation x^2 = (D - h) h ~ D h
(h = z0 - z the height above the bottom) [2]_ the load is
W = b k sqrt(D) z0^(n + 1/2) B(n + 1, 1/2) / 2, B the beta function; the
closed form :func:`terracone.physics.vehicle.sinkage_rigid_wheel_bekker`
has (3 - n)/3 in place of B(n + 1, 1/2)/2, equal to it at n = 0 and n = 1
only (6% above it at n = 0.5, 4% above at n = 0.8, 15% below at n = 1.5).

A track of width b and contact length L under the load W presses with the
uniform pressure q = W / (b L) and sinks to the least z with p(z; b) >= q
(Bekker's track, z0 = (q / k)^(1/n) on a homogeneous terrain [2]_):
:func:`sinkage_track`.

References
----------
.. [1] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
   University of Michigan Press.
.. [2] Wong, J.Y. (2008). Theory of Ground Vehicles, 4th ed. Wiley; chapter 2:
   sinkage of a rigid wheel, of a track with uniform pressure.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy import optimize
from scipy.special import roots_jacobi

from terracone.physics.layers import LayeredPlate

__all__ = ["GEOMETRIES", "GAUSS_POINTS", "sinkage_rigid_wheel", "sinkage_track", "wheel_load"]

#: Contact geometries of :func:`wheel_load`: the circle, or Bekker's shallow approximation.
GEOMETRIES = ("arc", "shallow")
#: Gauss-Jacobi points per layer in the contact (:func:`wheel_load`).
GAUSS_POINTS = 48
#: Steps of the scan over (0, D/2] that brackets a wheel's first equilibrium.
SCAN_POINTS = 96


@lru_cache(maxsize=512)
def _jacobi(points: int, alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Jacobi nodes and weights on [-1, 1] for the weight (1 - u)^alpha (1 + u)^beta."""
    return roots_jacobi(points, alpha, beta)


def _check_wheel(diameter: float, plate: LayeredPlate) -> float:
    if not (math.isfinite(diameter) and diameter > 0):
        raise ValueError(f"wheel diameter must be > 0 m (got {diameter!r})")
    if not isinstance(plate, LayeredPlate):
        raise TypeError(f"plate must be a LayeredPlate (got {type(plate).__name__})")
    return 0.5 * float(diameter)


def wheel_load(
    sinkage: float,
    *,
    diameter: float,
    plate: LayeredPlate,
    geometry: str = "arc",
    points: int = GAUSS_POINTS,
) -> float:
    """Vertical load [N] a rigid wheel of the plate's width carries at the sinkage z0.

    W = b int_0^x0 p dx (Bekker's assumptions [1]_ [2]_) written over the
    sinkage, W = b int_0^z0 p(z) (dx/dh) dz with h = z0 - z:

    * ``"arc"``, the circle: x^2 = (D - h) h, dx/dh = (D - 2h) / (2 sqrt(h (D - h))),
      z0 <= D/2;
    * ``"shallow"``, Bekker's approximation: x^2 = D h, dx/dh = sqrt(D) / (2 sqrt(h)).

    Each layer in the contact is one Gauss-Jacobi rule whose weight carries
    the integrand's end singularities, z^n at the surface and h^(-1/2) at the
    bottom of the wheel, so the sum converges as for a smooth function.

    Parameters
    ----------
    sinkage : float
        z0 [m], >= 0 (at most D/2 with ``"arc"``).
    diameter : float
        Wheel diameter D [m]; its width b is ``plate.width``.
    plate : LayeredPlate
        p(z) at the wheel's width (:func:`terracone.physics.layers.layered_plate`).
    geometry : {"arc", "shallow"}
    points : int
        Gauss-Jacobi points per layer.

    Returns
    -------
    float
        W [N] (kPa times m^2 times 1000).

    References
    ----------
    .. [1] Bekker (1969).
    .. [2] Wong (2008), chapter 2, sinkage of a rigid wheel.
    """
    r = _check_wheel(diameter, plate)
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry must be one of {GEOMETRIES} (got {geometry!r})")
    z0 = float(sinkage)
    if not (math.isfinite(z0) and z0 >= 0):
        raise ValueError(f"sinkage must be >= 0 m (got {sinkage!r})")
    if geometry == "arc" and z0 > r * (1 + 1e-12):
        raise ValueError(f"sinkage {z0:g} m is beyond the wheel's radius {r:g} m")
    D, total, bounds = float(diameter), 0.0, plate.bounds
    for j, (k, n) in enumerate(zip(plate.k, plate.n)):
        a, c = bounds[j], min(bounds[j + 1], z0)
        if a >= z0 or k == 0:
            continue
        alpha = -0.5 if c == z0 else 0.0  # h^(-1/2) at the bottom of the wheel
        beta = n if a == 0 else 0.0  # z^n at the surface
        u, w = _jacobi(int(points), alpha, beta)
        z = a + 0.5 * (c - a) * (1.0 + u)
        h = z0 - z
        if geometry == "arc":
            dx = (D - 2 * h) / (2 * np.sqrt(h * (D - h)))  # x^2 = (D - h) h
        else:
            dx = math.sqrt(D) / (2 * np.sqrt(h))  # x^2 = D h, Bekker's approximation
        g = k * z**n * dx  # p dx/dh: eq. (2-2) of layer j on the rim
        g = g / ((1.0 - u) ** alpha * (1.0 + u) ** beta)  # the rule's weight carries these
        total += 0.5 * (c - a) * float(w @ g)
    return 1000.0 * plate.width * total  # b int p dx, kPa m^2 -> N


def sinkage_rigid_wheel(
    load: float,
    *,
    diameter: float,
    plate: LayeredPlate,
    geometry: str = "arc",
    points: int = GAUSS_POINTS,
) -> float:
    """Sinkage z0 [m] of a rigid wheel in equilibrium with its load (Bekker's assumptions).

    Solves W = :func:`wheel_load` (z0) for z0 with Brent's method on the
    first bracket of a scan over (0, D/2] in SCAN_POINTS steps, with the
    interfaces added: the least z0 that carries the load, the equilibrium a
    wheel loaded from zero reaches first.  W(z0) is continuous however p
    jumps (an integral of p) and grows with z0 while p does not fall with z;
    past an interface onto a softer layer it may fall, and of two roots
    closer than a scan step the first can be missed.

    Parameters
    ----------
    load : float
        W [N], > 0.
    diameter, plate, geometry, points
        As :func:`wheel_load` (the wheel's width is ``plate.width``).

    Returns
    -------
    float
        z0 [m]; NaN when even z0 = D/2 does not carry the load (the wheel
        would sink past its axle, outside Bekker's model).

    References
    ----------
    .. [1] Bekker (1969); Wong (2008), chapter 2 (as :mod:`terracone.physics.sinkage`).
    """
    r = _check_wheel(diameter, plate)
    if not (math.isfinite(load) and load > 0):
        raise ValueError(f"load must be > 0 N (got {load!r})")

    def excess(z: float) -> float:
        return (
            wheel_load(z, diameter=diameter, plate=plate, geometry=geometry, points=points) - load
        )

    grid = np.linspace(0.0, r, SCAN_POINTS + 1)[1:]
    grid = np.unique(np.concatenate([grid, [d for d in plate.interfaces if d < r]]))
    lo = 0.0
    for z in grid:
        if excess(float(z)) >= 0:
            return float(optimize.brentq(excess, lo, float(z), xtol=1e-14, rtol=1e-13))
        lo = float(z)
    return math.nan


def sinkage_track(pressure_on_track: float, *, plate: LayeredPlate) -> float:
    """Sinkage z0 [m] of a track with a uniform pressure q: the least z with p(z) >= q.

    Bekker's track [1]_ [2]_: z0 = (q / k)^(1/n) in a homogeneous terrain.
    Layer by layer from the top, z0 = (q / k_j)^(1/n_j) when it lies in
    layer j; where p jumps past q at an interface, the track rests on it.

    Parameters
    ----------
    pressure_on_track : float
        q = W / (b L) [kPa], > 0: the load on one track over its width b
        (``plate.width``) and contact length L.
    plate : LayeredPlate
        p(z) at the track's width.

    Returns
    -------
    float
        z0 [m]; NaN where no layer carries q (k = 0 to the bottom).

    References
    ----------
    .. [1] Bekker (1969).
    .. [2] Wong (2008), chapter 2, sinkage of a track with uniform pressure.
    """
    q = float(pressure_on_track)
    if not (math.isfinite(q) and q > 0):
        raise ValueError(f"pressure on the track must be > 0 kPa (got {pressure_on_track!r})")
    bounds = plate.bounds
    for j, (k, n) in enumerate(zip(plate.k, plate.n)):
        if k == 0:
            continue
        z = (q / k) ** (1.0 / n)  # Bekker's track in layer j's law
        if z < bounds[j]:
            return bounds[j]  # p jumps past q at the top of layer j
        if z < bounds[j + 1]:
            return z
    return math.nan

"""Terrain internal shear: the Janosi-Hanamoto shear stress-displacement curve.

The shear stress-displacement relationship of the terrain is described by the
Janosi-Hanamoto equation [1]_ (the form used on the cone-metal interface in
eq. (2-4) of [2]_; here it is the *internal* shear of the terrain measured
with a shear ring or shear plate, not the cone-metal cc, phic):

.. math:: \\tau = (c + \\sigma \\tan\\phi)(1 - e^{-j/K}) = \\tau_{max} (1 - e^{-j/K})

with tau the shear stress [kPa], sigma the normal pressure [kPa], j the shear
displacement [m], c the cohesion [kPa], phi the angle of internal friction
and K the shear deformation modulus [m].

This module is the forward model only.  The fits of shear tests
(:func:`fit_shear`, :func:`fit_shear_test`, :class:`ShearFit`,
:class:`ShearTestFit`) live in :mod:`terracone.inverse.shear`; they are
re-exported here under their old names (a documented alias, resolved on
first use so that the two modules do not import each other at load time).

References
----------
.. [1] Janosi, Z., Hanamoto, B. (1961). The analytical determination of
   drawbar pull as a function of slip for tracked vehicles in deformable
   soils. Proc. 1st Int. Conf. on Terrain-Vehicle Systems, Turin.
.. [2] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-4).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the fits, for type checkers; at run time see __getattr__ below
    from .inverse.shear import ShearFit, ShearTestFit, fit_shear, fit_shear_test

__all__ = [
    "ShearTestFit",
    "ShearFit",
    "fit_shear",
    "fit_shear_test",
    "shear_stress_janosi_hanamoto",
    "janosi_hanamoto",
]


def shear_stress_janosi_hanamoto(displacement: Any, tau_max: Any, K: Any) -> np.ndarray:
    """Janosi-Hanamoto shear stress tau = tau_max (1 - exp(-j/K)).

    ``janosi_hanamoto`` is the old name of this function (the same object).

    Parameters
    ----------
    displacement : array_like
        Shear displacement j [m].
    tau_max : array_like
        Shear strength c + sigma tan(phi) [kPa] (cc + p tan(phic) on the
        cone-metal interface).
    K : array_like
        Shear deformation modulus [m] (Kc on the cone-metal interface).

    Returns
    -------
    ndarray
        Shear stress [kPa].

    References
    ----------
    .. [1] Janosi and Hanamoto (1961).
    .. [2] Huang, Wong, Preston-Thomas, Jayakumar, eq. (2-4).
    """
    j = np.asarray(displacement, dtype=float)
    # eq. (2-4): s = (c + p tan phi)(1 - exp(-j/K))
    return tau_max * -np.expm1(-j / K)


#: Old name of :func:`shear_stress_janosi_hanamoto` (the same function).
janosi_hanamoto = shear_stress_janosi_hanamoto

#: Names of :mod:`terracone.inverse.shear` that this module re-exports.
MOVED_TO_INVERSE = ("ShearTestFit", "ShearFit", "fit_shear", "fit_shear_test")


def __getattr__(name: str) -> Any:
    """The shear fits, from :mod:`terracone.inverse.shear` (their home since issue 13)."""
    if name in MOVED_TO_INVERSE:
        from .inverse import shear as fits

        return getattr(fits, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(MOVED_TO_INVERSE))

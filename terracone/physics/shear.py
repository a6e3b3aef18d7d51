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
(:func:`~terracone.inverse.bevameter.shear.fit_shear` and
:func:`~terracone.inverse.bevameter.shear.fit_shear_test`) live in
:mod:`terracone.inverse.bevameter.shear`.

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

from typing import Any

import numpy as np

__all__ = ["shear_stress_janosi_hanamoto"]


def shear_stress_janosi_hanamoto(displacement: Any, tau_max: Any, K: Any) -> np.ndarray:
    """Janosi-Hanamoto shear stress tau = tau_max (1 - exp(-j/K)).


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

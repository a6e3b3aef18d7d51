"""Terrain internal shear: the Janosi-Hanamoto curve tau = (c + sigma tan phi)(1 - exp(-j/K)).

The form of eq. (2-4) of [2]_, here for the terrain's *internal* shear (shear
ring or plate), not the cone-metal cc, phic.  The fits live in
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

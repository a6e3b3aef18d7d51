"""Alias of :mod:`terracone.inverse.plates` (plate pressure-sinkage fits).

The plate fits moved to :mod:`terracone.inverse.plates` when the forward
models and the fits were put apart (issue 13); this module re-exports their
public names so that ``from terracone.bevameter import fit_plates`` keeps
working.  New code should import from :mod:`terracone.inverse` or
:mod:`terracone.inverse.plates`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-2).
"""

from __future__ import annotations

from .inverse.plates import METHODS, PlateFit, PlatesFit, fit_plate_test, fit_plates

__all__ = ["METHODS", "PlateFit", "PlatesFit", "fit_plate_test", "fit_plates"]

"""Layered terrain, inverse side: the fit (:mod:`.fit`), its search (:mod:`.search`) and its
posterior (:mod:`.posterior`).

The forward model is :mod:`terracone.physics.layers`.
"""

from terracone.inverse.layered.fit import LayeredResult, fit_layered
from terracone.inverse.layered.posterior import LayeredPosterior, layered_posterior

__all__ = ["LayeredPosterior", "LayeredResult", "fit_layered", "layered_posterior"]

"""Alias of the posterior modules under :mod:`terracone.inverse` (issue 13).

The posterior of the prediction process moved when the forward models and
the fits were put apart:

* :mod:`terracone.inverse.uncertainty`: :func:`posterior`,
  :func:`posterior_for_result`, :class:`PosteriorResult`, the plate bands and
  the identifiability labels;
* :mod:`terracone.inverse.noise`: the CI error model (weights, AR(1));
* :mod:`terracone.inverse.priors`: :class:`CalibrationPrior` and the bounds prior;
* :mod:`terracone.inverse.likelihood`: :class:`Likelihood` and its kernel;
* :mod:`terracone.inverse.sampler`: the emcee set-up and :func:`integrated_time`;
* :mod:`terracone.inverse.layered`: :func:`layered_posterior`.

This module re-exports every public name it defined before, so that
``from terracone.uncertainty import posterior`` keeps working; they are the
same objects.  ``JIT_ENABLED`` (the switch between the compiled likelihood
kernel and its numpy twin) and ``spline_sse_compiled`` are read from, and
``JIT_ENABLED`` is written to, :mod:`terracone.inverse.likelihood`, so
``terracone.uncertainty.JIT_ENABLED = False`` still selects the numpy kernel.
New code should import from :mod:`terracone.inverse`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 2 and 3.
"""

from __future__ import annotations

import sys
import types
from typing import TYPE_CHECKING, Any

from .inverse import likelihood
from .inverse.layered import LayeredPosterior, layered_posterior
from .inverse.likelihood import Likelihood, spline_sse
from .inverse.noise import (
    RHO_MAX,
    NoiseModel,
    ar1_coefficients,
    ar1_noise,
    estimate_correlation,
)
from .inverse.priors import PARAM_NAMES, CalibrationPrior
from .inverse.sampler import integrated_time
from .inverse.uncertainty import (
    DEFAULT_PLATES,
    DEFAULT_SINKAGES,
    DETERMINED_BELOW,
    LABELS,
    WEAKLY_BELOW,
    PlateBand,
    PosteriorResult,
    SamplerDiagnostics,
    identifiability_label,
    plate_bands,
    posterior,
    posterior_for_result,
)

if TYPE_CHECKING:  # read from the likelihood module at each access, see __getattr__
    from .inverse.likelihood import spline_sse_compiled

__all__ = [
    "PARAM_NAMES",
    "LABELS",
    "DETERMINED_BELOW",
    "WEAKLY_BELOW",
    "DEFAULT_PLATES",
    "DEFAULT_SINKAGES",
    "RHO_MAX",
    "CalibrationPrior",
    "NoiseModel",
    "PlateBand",
    "SamplerDiagnostics",
    "PosteriorResult",
    "LayeredPosterior",
    "posterior",
    "posterior_for_result",
    "layered_posterior",
    "estimate_correlation",
    "ar1_coefficients",
    "ar1_noise",
    "identifiability_label",
    "plate_bands",
    "integrated_time",
    "Likelihood",
    "spline_sse",
    "spline_sse_compiled",
]


#: Names read from and written to :mod:`terracone.inverse.likelihood` at each access.
FORWARDED = ("JIT_ENABLED", "spline_sse_compiled")


def __getattr__(name: str) -> Any:
    """``JIT_ENABLED`` and ``spline_sse_compiled``, from :mod:`terracone.inverse.likelihood`.

    The lazy numba kernel replaces itself there by its dispatcher on first
    use; reading it through this alias then gives that same object.
    """
    if name in FORWARDED:
        return getattr(likelihood, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _AliasModule(types.ModuleType):
    """This module's type: assignments to :data:`FORWARDED` names go to the likelihood module."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in FORWARDED:
            setattr(likelihood, name, value)
        else:
            super().__setattr__(name, value)


sys.modules[__name__].__class__ = _AliasModule

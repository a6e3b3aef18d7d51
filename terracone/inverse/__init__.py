"""Inverse problems: the prediction and learning processes of the paper.

* :func:`predict` fits kc, kphi, n, cc, phic to a CI profile (section 3.3.2);
* :func:`learn` fits them jointly to CI profiles and plate tests and finds
  the RM1 transition radius r_min (section 3.3.1);
* :func:`evaluate` compares predicted and measured plate pressure-sinkage
  curves (Tables 4-2 and 4-4);
* :func:`posterior` samples the posterior of one profile's parameters
  (:mod:`.uncertainty`, with :mod:`.noise`, :mod:`.priors`, :mod:`.likelihood`,
  :mod:`.sampler`);
* :func:`fit_layered` and :func:`layered_posterior` fit a layered terrain
  (:mod:`.layered`; the forward model is :mod:`terracone.physics.layers`);
* :func:`fit_plates` / :func:`fit_plate_test` fit bevameter plate tests
  (:mod:`.plates`) and :func:`fit_shear` / :func:`fit_shear_test` shear tests
  (:mod:`.shear`).

The fits are loaded on first use of their name (emcee and scipy.stats are
not needed to predict), so ``import terracone.inverse`` stays as light as it was.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from terracone.inverse.bounds import Bounds
from terracone.inverse.predict import PredictionResult, PredictionResults, predict, predict_many
from terracone.inverse.solver.pso import PSOResult, pso

if TYPE_CHECKING:  # loaded on first use, see __getattr__
    from terracone.inverse.bevameter.plates import PlateFit, PlatesFit, fit_plate_test, fit_plates
    from terracone.inverse.bevameter.shear import ShearFit, ShearTestFit, fit_shear, fit_shear_test
    from terracone.inverse.layered import (
        LayeredPosterior,
        LayeredResult,
        fit_layered,
        layered_posterior,
    )
    from terracone.inverse.uncertainty.posterior import (
        PosteriorResult,
        posterior,
        posterior_for_result,
    )

#: Names exported from submodules loaded on first use, and their submodule.
LAZY = {
    **dict.fromkeys(
        ["LayeredPosterior", "LayeredResult", "fit_layered", "layered_posterior"], "layered"
    ),
    **dict.fromkeys(["PlateFit", "PlatesFit", "fit_plate_test", "fit_plates"], "bevameter.plates"),
    **dict.fromkeys(["ShearFit", "ShearTestFit", "fit_shear", "fit_shear_test"], "bevameter.shear"),
    **dict.fromkeys(
        ["PosteriorResult", "posterior", "posterior_for_result"], "uncertainty.posterior"
    ),
}

__all__ = [
    "Bounds",
    "PSOResult",
    "PredictionResult",
    "PredictionResults",
    "predict",
    "predict_many",
    "pso",
    # fits moved from layers, bevameter, shear and uncertainty (issue 13)
    "LayeredPosterior",
    "LayeredResult",
    "PlateFit",
    "PlatesFit",
    "PosteriorResult",
    "ShearFit",
    "ShearTestFit",
    "fit_layered",
    "fit_plate_test",
    "fit_plates",
    "fit_shear",
    "fit_shear_test",
    "layered_posterior",
    "posterior",
    "posterior_for_result",
]


def __getattr__(name: str) -> Any:
    """The fits of :data:`LAZY`, imported from their submodule on first use."""
    if name in LAZY:
        value = getattr(import_module(f".{LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(LAZY))

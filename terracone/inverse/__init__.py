"""Inverse problems: the prediction and learning processes of the paper.

* :func:`predict` fits kc, kphi, n, cc, phic to a CI profile (section 3.3.2);
* :func:`learn` fits them jointly to CI profiles and plate tests and finds
  the RM1 transition radius r_min (section 3.3.1);
* :func:`evaluate` compares predicted and measured plate pressure-sinkage
  curves (Tables 4-2 and 4-4);
* :func:`posterior` samples the posterior of one profile's parameters
  (:mod:`.posterior`, with :mod:`.noise`, :mod:`.priors`, :mod:`.likelihood`,
  :mod:`.sampler`);
* :func:`fit_layered` and :func:`layered_posterior` fit a layered terrain
  (:mod:`.layered`; the forward model is :mod:`terracone.layers`);
* :func:`fit_plates` / :func:`fit_plate_test` fit bevameter plate tests
  (:mod:`.plates`) and :func:`fit_shear` / :func:`fit_shear_test` shear tests
  (:mod:`.shear`).
"""

from .bounds import Bounds
from .layered import LayeredPosterior, LayeredResult, fit_layered, layered_posterior
from .plates import PlateFit, PlatesFit, fit_plate_test, fit_plates
from .posterior import PosteriorResult, posterior, posterior_for_result
from .predict import PredictionResult, PredictionResults, predict, predict_many
from .pso import PSOResult, pso
from .shear import ShearFit, ShearTestFit, fit_shear, fit_shear_test

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

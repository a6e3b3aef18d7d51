"""Inverse problems: the prediction and learning processes of the paper.

* :func:`predict` fits kc, kphi, n, cc, phic to a CI profile (section 3.3.2);
* :func:`learn` fits them jointly to CI profiles and plate tests and finds
  the RM1 transition radius r_min (section 3.3.1);
* :func:`evaluate` compares predicted and measured plate pressure-sinkage
  curves (Tables 4-2 and 4-4).
"""

from .bounds import Bounds
from .predict import PredictionResult, PredictionResults, predict, predict_many
from .pso import PSOResult, pso

__all__ = [
    "Bounds",
    "PSOResult",
    "PredictionResult",
    "PredictionResults",
    "predict",
    "predict_many",
    "pso",
]

"""Inverse problems: the prediction and learning processes of the paper.

* :class:`Problem` states what a fit fits, once: the pressure law, the bounds,
  the values a :class:`Calibration` holds and the prior (:mod:`.problem`);
  every entry point below takes it;
* :func:`predict` / :func:`predict_many` fit kc, kphi, n, cc, phic_deg to CI
  profiles (section 3.3.2; :mod:`.predict`, solvers in :mod:`.solver`);
  :class:`RunSettings` says how (solver, detail) and what to attach;
* :func:`learn` fits them jointly to CI profiles and plate tests and finds
  the RM1 transition radius r_min (section 3.3.1; :mod:`.learning`);
* :func:`evaluate` compares predicted and measured plate pressure-sinkage
  curves (Tables 4-2 and 4-4; :mod:`.evaluate`);
* :func:`posterior` samples the posterior of one profile's parameters
  (:mod:`.uncertainty`);
* :func:`fit_layered` and :func:`layered_posterior` fit a layered terrain
  (:mod:`.layered`; the forward model is :mod:`terracone.physics.layers`);
* :func:`fit_plates` / :func:`fit_plate_test` fit bevameter plate tests and
  :func:`fit_shear` / :func:`fit_shear_test` shear tests (:mod:`.bevameter`);
* site statistics and the value of a test are in :mod:`.sites`.

Everything but :class:`Bounds`, :class:`Problem`, :class:`Calibration`,
:class:`RunSettings`, :func:`predict`, :func:`predict_many` and :func:`pso` is
loaded on first use of its name (emcee and scipy.stats are not
needed to predict).  The result types are in :mod:`terracone.result`.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from terracone.inverse.bounds import Bounds
from terracone.inverse.predict import RunSettings, predict, predict_many
from terracone.inverse.problem import Calibration, Problem
from terracone.inverse.solver.pso import PSOResult, pso

if TYPE_CHECKING:  # loaded on first use, see __getattr__
    from terracone.inverse.bevameter.plates import PlateFit, PlatesFit, fit_plate_test, fit_plates
    from terracone.inverse.bevameter.shear import ShearFit, ShearTestFit, fit_shear, fit_shear_test
    from terracone.inverse.evaluate import PlateEvaluation, evaluate
    from terracone.inverse.layered import (
        LayeredPosterior,
        LayeredResult,
        fit_layered,
        layered_posterior,
    )
    from terracone.inverse.learning.learn import LearnResult, learn
    from terracone.inverse.uncertainty.posterior import PosteriorResult, posterior

#: Names exported from submodules loaded on first use, and their submodule.
LAZY = {
    **dict.fromkeys(["PlateFit", "PlatesFit", "fit_plate_test", "fit_plates"], "bevameter.plates"),
    **dict.fromkeys(["ShearFit", "ShearTestFit", "fit_shear", "fit_shear_test"], "bevameter.shear"),
    **dict.fromkeys(["PlateEvaluation", "evaluate"], "evaluate"),
    **dict.fromkeys(
        ["LayeredPosterior", "LayeredResult", "fit_layered", "layered_posterior"], "layered"
    ),
    **dict.fromkeys(["LearnResult", "learn"], "learning.learn"),
    **dict.fromkeys(["PosteriorResult", "posterior"], "uncertainty.posterior"),
}

__all__ = [
    "Bounds",
    "Calibration",
    "Problem",
    "RunSettings",
    "PSOResult",
    "predict",
    "predict_many",
    "pso",
    "PlateFit",
    "PlatesFit",
    "fit_plate_test",
    "fit_plates",
    "ShearFit",
    "ShearTestFit",
    "fit_shear",
    "fit_shear_test",
    "PlateEvaluation",
    "evaluate",
    "LayeredPosterior",
    "LayeredResult",
    "fit_layered",
    "layered_posterior",
    "LearnResult",
    "learn",
    "PosteriorResult",
    "posterior",
]


def __getattr__(name: str) -> Any:
    """The names of :data:`LAZY`, imported from their submodule on first use."""
    if name in LAZY:
        value = getattr(import_module(f".{LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(LAZY))

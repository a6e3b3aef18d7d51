"""What ``terracone fit-plates``, ``fit-shear`` and ``evaluate`` compute, each as one call.

:func:`fit_plate_file` fits p = k z^n to each plate test of a file and kc,
kphi from k = kc/b + kphi (:func:`terracone.inverse.bevameter.plates.fit_plates`);
:func:`fit_shear_file` fits Janosi-Hanamoto's tau = (c + sigma tan phi)(1 -
exp(-j/K)) to shear tests (:func:`terracone.inverse.bevameter.shear.fit_shear`);
either fit is stored in the terrain library when asked.  :func:`evaluate_plates`
compares predicted with measured plate curves by R, R^2, RMSD and CV (Tables
4-2 and 4-4 of [1]_, :func:`terracone.inverse.evaluate.cross_table`).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-2 and 4-4.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from terracone.apps.library import Library, make_provenance
from terracone.data import PlateTest, TerrainParameters
from terracone.inverse.bevameter.plates import PlatesFit, fit_plates
from terracone.inverse.bevameter.shear import ShearFit, fit_shear
from terracone.inverse.evaluate import PlateEvaluation, cross_table, parameters_from_json
from terracone.io import read_plate_tests, read_shear_tests

__all__ = [
    "BevameterRun",
    "EvaluationRun",
    "evaluate_plates",
    "fit_plate_file",
    "fit_shear_file",
]

PathLike = str | os.PathLike[str]


@dataclass
class BevameterRun:
    """A bevameter fit and the library name it was stored under (or None)."""

    fit: PlatesFit | ShearFit
    saved_as: str | None = None

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``terracone fit-plates --json`` or ``fit-shear --json`` document."""
        d = self.fit.as_dict(units)
        d["saved_as"] = self.saved_as
        return d


def _store(
    fit: PlatesFit | ShearFit,
    source: PathLike,
    method: str,
    save_as: str | None,
    library: PathLike | None,
) -> BevameterRun:
    """Store ``fit`` in the library as kind "bevameter-fit" when ``save_as`` names it."""
    if save_as:
        provenance = make_provenance(source=str(source), method=method)
        with Library(library) as lib:
            lib.add(save_as, "bevameter-fit", fit.params(), provenance, replace=True)
    return BevameterRun(fit, save_as)


def fit_plate_file(
    path: PathLike,
    method: str = "wong",
    *,
    save_as: str | None = None,
    library: PathLike | None = None,
) -> BevameterRun:
    """Fit the plate tests of a file (:func:`terracone.io.read_plate_tests`) and keep the fit.

    Parameters
    ----------
    path : path
        Plate tests (CSV, units in the column names).
    method : {"wong", "loglog", "nonlinear"}
        How each test's k and n are fitted.
    save_as : str, optional
        Store the fit in the terrain library under this name (replacing one
        of the same name).
    library : path, optional
        The library (default: ``$TERRACONE_LIBRARY`` or the user data dir).

    Returns
    -------
    BevameterRun
    """
    fit = fit_plates(read_plate_tests(path), method=method)
    return _store(fit, path, f"fit-plates ({method})", save_as, library)


def fit_shear_file(
    path: PathLike, *, save_as: str | None = None, library: PathLike | None = None
) -> BevameterRun:
    """Fit the shear tests of a file (:func:`terracone.io.read_shear_tests`) and keep the fit.

    ``save_as`` and ``library`` as :func:`fit_plate_file` takes them.
    """
    fit = fit_shear(read_shear_tests(path))
    return _store(fit, path, "fit-shear", save_as, library)


@dataclass
class EvaluationRun:
    """Every prediction against every plate test (``rows``), as :func:`evaluate_plates` made them."""

    rows: list[PlateEvaluation]

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``terracone evaluate --json`` document."""
        return {"plates": [r.as_dict(units) for r in self.rows], "units": units}


def evaluate_plates(
    plates: PathLike | Sequence[PlateTest],
    predictions: PathLike | Sequence[tuple[str, TerrainParameters]],
) -> EvaluationRun:
    """R, R^2, RMSD and CV of predicted against measured plate curves (Tables 4-2, 4-4 of [1]_).

    Parameters
    ----------
    plates : path or sequence of PlateTest
        Plate tests, or their file.
    predictions : path or sequence of (str, TerrainParameters)
        Labelled parameter sets, or a ``predict --json`` or ``learn --json``
        file (:func:`~terracone.inverse.evaluate.parameters_from_json`).

    Returns
    -------
    EvaluationRun
    """
    if isinstance(predictions, str | os.PathLike):
        predictions = parameters_from_json(predictions)
    if isinstance(plates, str | os.PathLike):
        plates = read_plate_tests(plates)
    return EvaluationRun(cross_table(list(predictions), list(plates)))

"""Evaluation: predicted against measured plate pressure-sinkage curves.

For each plate test, the pressure predicted from a parameter set at the
measured sinkages (loading branch) is compared with the measured pressure by
R, R^2, RMSD and CV, as in Tables 4-2 and 4-4 of [1]_.  With several
predictions and several plate tests, every prediction is compared with every
test (the cross table of Table 4-2).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-2 and 4-4.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from terracone.data import PlateTest, TerrainParameters
from terracone.io.jsonkeys import read_json
from terracone.physics.metrics import Agreement, agreement
from terracone.physics.plate import plate_basis, pressure_law
from terracone.result import from_document
from terracone.resultunits import from_si

__all__ = [
    "PlateEvaluation",
    "evaluate",
    "cross_table",
    "parameters_from_json",
    "predicted_plate_pressure",
]


@dataclass(frozen=True)
class PlateEvaluation:
    """Agreement of one prediction with one plate test.

    Attributes
    ----------
    prediction : str
        Id of the parameter set (CI profile or label).
    test : str
        Plate test id.
    b : float
        Plate size [m] (radius of a circular plate).
    shape : str
    agreement : Agreement
        R, R2, RMSD [kPa], CV.
    """

    prediction: str
    test: str
    b: float
    shape: str
    agreement: Agreement

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        a = self.agreement
        key = "plate_radius" if self.shape == "circular" else "plate_width"
        return {
            "prediction": self.prediction,
            "test": self.test,
            key: from_si(self.b, "length", units),
            "R": a.R,
            "R2": a.R2,
            "RMSD": from_si(a.RMSD, "pressure", units),
            "CV": a.CV,
            "n_points": a.n_points,
            "units": units,
        }


def predicted_plate_pressure(
    params: TerrainParameters,
    sinkage: np.ndarray,
    b: float,
    plate_pair: tuple[float, float] | None = None,
) -> np.ndarray:
    """Pressure [kPa] under a plate of size b [m] at sinkages [m] (eq. (2-2), section 3.2)."""
    law = (
        pressure_law("rm1", r_min=params.r_min, plate_pair=plate_pair)
        if params.model == "rm1" and params.r_min is not None
        else pressure_law("rm0")
    )
    A, B = plate_basis(sinkage, n=params.n, b=b, law=law)
    return params.kc * A + params.kphi * B


def evaluate(
    params: TerrainParameters,
    plates: list[PlateTest],
    *,
    label: str = "prediction",
    plate_pair: tuple[float, float] | None = None,
) -> list[PlateEvaluation]:
    """Compare the P-S curves predicted from ``params`` with each plate test."""
    out = []
    for t in plates:
        br = t.loading_branch()
        if br.sinkage.size < 2:
            raise ValueError(f"plate test {t.id}: fewer than 2 loading points with sinkage > 0")
        pred = predicted_plate_pressure(params, br.sinkage, br.b, plate_pair)
        out.append(PlateEvaluation(label, t.id, t.b, t.shape, agreement(br.pressure, pred)))
    return out


def cross_table(
    predictions: list[tuple[str, TerrainParameters]],
    plates: list[PlateTest],
    plate_pair: tuple[float, float] | None = None,
) -> list[PlateEvaluation]:
    """Every prediction against every plate test (Table 4-2 of [1]_)."""
    return [
        row
        for label, params in predictions
        for row in evaluate(params, plates, label=label, plate_pair=plate_pair)
    ]


def parameters_from_json(path: str | os.PathLike[str]) -> list[tuple[str, TerrainParameters]]:
    """The fitted parameter sets of a ``predict --json`` or ``learn --json`` file.

    Parameters
    ----------
    path : path
        A predict document (its profiles with status "ok", named by their
        id) or a learn document (one set, named by its terrain).

    Returns
    -------
    list of (str, TerrainParameters)
        Label and parameters, as :func:`cross_table` takes them.

    Raises
    ------
    ValueError
        The file cannot be read as JSON, a parameter set lacks a key or has
        a bad value (naming the file and the profile or terrain), or the
        file holds no fitted parameters.
    """
    doc = read_json(path)

    def params(d: dict, where: str) -> TerrainParameters:
        try:
            return TerrainParameters.from_dict(d)
        except KeyError as exc:
            raise ValueError(f"file {path}, {where}: missing key {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"file {path}, {where}: {exc}") from None

    out = []
    if isinstance(doc, dict) and "profiles" in doc:
        results = from_document(doc, source=f"file {path}")
        out = [(r.id, r.params) for r in results if r.status == "ok" and r.params is not None]
    elif isinstance(doc, dict) and "kc" in doc:
        name = str(doc.get("terrain", Path(path).stem))
        out.append((name, params(doc, f"terrain {name}")))
    if not out:
        raise ValueError(
            f"file {path}: no fitted parameters found (expected predict or learn JSON)"
        )
    return out

"""What ``terracone predict`` computes, as one library call.

:func:`predict_profiles` chains the prediction process (section 3.3.2 of [1]_)
over a set of CI profiles with what the command adds on request: predicted
plate pressure-sinkage curves (eq. (2-2), RM1 of section 3.2), the posterior of
each fit (:mod:`terracone.inverse.uncertainty.posterior`) and layered fits
(:mod:`terracone.physics.layers`), attached to each
:class:`~terracone.result.PredictionResult`.  The result, :class:`PredictRun`,
writes the same JSON document as ``terracone predict --json``
(:meth:`PredictRun.as_dict`) and the same table as ``--parquet``
(:meth:`PredictRun.to_table`), through :mod:`terracone.result`, so a Python
user gets what the command writes without reaching into the CLI.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa

from terracone.data import CIProfile, InputError, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.evaluate import predicted_plate_pressure
from terracone.inverse.learning.learn import Calibration
from terracone.inverse.predict import predict_many
from terracone.physics import units as u
from terracone.result import (
    PlateCurve,
    PredictionResult,
    PredictionResults,
    settings_dict,
    to_document,
    to_table,
)

__all__ = ["PredictRun", "plate_curves", "predict_profiles", "sinkage_grid"]


def sinkage_grid(units: str = "si", points: int = 26) -> np.ndarray:
    """Sinkages [m] of predicted plate curves: 0 to 5 cm, or 0 to 2 in with ``units="us"``."""
    s_max = 2 * u.INCH if units == "us" else 0.05
    return np.linspace(0.0, s_max, points)


def plate_curves(
    params: TerrainParameters,
    radii: Sequence[float],
    sinkage: np.ndarray,
    plate_pair: tuple[float, float] | None = None,
) -> list[PlateCurve]:
    """Predicted plate pressure [kPa] at ``sinkage`` [m] for each plate radius [m] (SI).

    Bekker's equation (2-2), or RM1 below r_min (section 3.2 of [1]_), with the
    secant through ``plate_pair`` when r_min is above the larger plate.
    """
    s = np.asarray(sinkage, dtype=float)
    return [
        # eq. (2-2), RM1 of section 3.2
        PlateCurve(float(r), s, predicted_plate_pressure(params, s, r, plate_pair))
        for r in radii
    ]


@dataclass
class PredictRun:
    """Result of :func:`predict_profiles` (SI inside).

    Attributes
    ----------
    results : PredictionResults
        One :class:`~terracone.result.PredictionResult` per input item, in
        input order (bad profiles carry their error), with the plate curves,
        posterior and layered fit attached (``plate_curves``, ``posterior``,
        ``layered``, ``layered_posterior``).
    settings : dict
        What the run was asked (SI; converted by :meth:`as_dict`).

    ``plates``, ``posteriors``, ``layered`` and ``layered_posteriors`` map
    profile ids to what is attached to the results (kept from before the
    result model).
    """

    results: PredictionResults
    settings: dict[str, Any] = field(default_factory=dict)

    def _attached(self, name: str) -> dict[str, Any]:
        out = {}
        for r in self.results:
            v = getattr(r, name)
            if v is not None and (not isinstance(v, list) or v):
                out[r.id] = v
        return out

    @property
    def plates(self) -> dict[str, list[PlateCurve]]:
        """Profile id to its predicted plate curves."""
        return self._attached("plate_curves")

    @property
    def posteriors(self) -> dict[str, Any]:
        """Profile id to its :class:`terracone.inverse.uncertainty.posterior.PosteriorResult`."""
        return self._attached("posterior")

    @property
    def layered(self) -> dict[str, Any]:
        """Profile id to its :class:`terracone.physics.layers.LayeredResult`."""
        return self._attached("layered")

    @property
    def layered_posteriors(self) -> dict[str, Any]:
        """Profile id to the posterior of its layered fit."""
        return self._attached("layered_posterior")

    def profile_dict(self, r: PredictionResult, units: str = "si") -> dict[str, Any]:
        """One profile of the ``terracone predict --json`` document."""
        return r.as_dict(units)

    def as_dict(
        self, units: str = "si", *, input: str | None = None, **settings: Any
    ) -> dict[str, Any]:
        """The ``terracone predict --json`` document; ``settings`` are recorded as given."""
        return to_document(
            self.results,
            units,
            input=input,
            settings=settings_dict(self.settings, units, **settings),
        )

    def to_table(self, units: str = "si") -> pa.Table:
        """The ``terracone predict --parquet`` table (batch's part-file columns)."""
        return to_table(self.results, units)


def predict_profiles(
    items: Sequence[CIProfile | InputError],
    *,
    model: str = "rm0",
    r_min: float | None = None,
    calibration: Calibration | None = None,
    solver: str = "exact",
    bounds: Bounds | None = None,
    seed: int | None = None,
    plates: Sequence[float] = (),
    sinkage: np.ndarray | None = None,
    uncertainty: bool = False,
    prior: str | Calibration = "bounds",
    draws: int = 2000,
    band_sinkage: np.ndarray | None = None,
    layers: int = 1,
) -> PredictRun:
    """Predict terrain parameters for a set of CI profiles, with what predict adds on request.

    Parameters
    ----------
    items : sequence of CIProfile or InputError
        As readers return them; an :class:`InputError` is reported as that
        profile's error and the others are fitted.
    model, r_min, calibration, solver, bounds, seed
        As :func:`terracone.inverse.predict_many`.  r_min [m].
    plates : sequence of float
        Plate radii [m] of predicted plate curves (and posterior bands).
    sinkage : ndarray, optional
        Sinkages [m] of the plate curves (default :func:`sinkage_grid`).
    uncertainty : bool
        Sample each fit's posterior (:func:`terracone.inverse.uncertainty.posterior.posterior_for_result`).
    prior : "bounds" or Calibration
        Prior of the posterior.
    draws : int
        Posterior draws.
    band_sinkage : ndarray, optional
        Sinkages [m] of the posterior plate bands (default 21 points to 5 cm).
    layers : int
        Above 1: also a layered fit of each profile (and its posterior with
        ``uncertainty``).
    """
    bounds = bounds or Bounds()
    results = predict_many(
        items,
        model=model,
        r_min=r_min,
        calibration=calibration,
        solver=solver,
        bounds=bounds,
        seed=seed,
    )
    for it, r in zip(items, results):  # a reader's error: its row and column for the table
        if isinstance(it, InputError) and r.error_row is None and r.error_column is None:
            r.error_row, r.error_column = it.row, it.column
    pair = calibration.plate_pair if calibration else None
    run = PredictRun(
        PredictionResults(results),
        settings={
            "model": calibration.model if calibration else model,
            "r_min": calibration.r_min if calibration else r_min,
            "solver": solver,
            "seed": seed,
            "bounds": bounds,
            "calibration": calibration.terrain if calibration else None,
        },
    )
    by_id = {it.id: it for it in items if not isinstance(it, InputError)}
    s = sinkage_grid() if sinkage is None else sinkage
    for r in results:
        if not r.ok:
            continue
        if plates:
            r.plate_curves = plate_curves(r.params, plates, s, pair)
        if uncertainty:
            r.posterior = _posterior(
                by_id[r.id], r, prior, draws, seed, plates, band_sinkage, bounds, pair
            )
        if layers > 1:
            _layered(r, by_id[r.id], layers, model, r_min, bounds, uncertainty, draws, seed)
    return run


def _posterior(profile, result, prior, draws, seed, plates, band_sinkage, bounds, pair):
    from terracone.inverse.uncertainty.posterior import posterior_for_result

    return posterior_for_result(
        profile,
        result,
        prior=prior,
        draws=draws,
        seed=seed,
        plates=list(plates) or None,
        plate_sinkages=np.linspace(0.0, 0.05, 21) if band_sinkage is None else band_sinkage,
        bounds=bounds,
        plate_pair=pair,
    )


def _layered(result, profile, layers, model, r_min, bounds, uncertainty, draws, seed) -> None:
    """Attach a layered fit (and its posterior) to ``result``."""
    from terracone.inverse.layered import fit_layered

    lr = fit_layered(profile, layers=layers, model=model, r_min=r_min, bounds=bounds)
    result.layered = lr
    if uncertainty and lr.ok:
        from terracone.inverse.layered import layered_posterior

        result.layered_posterior = layered_posterior(
            profile, lr, bounds=bounds, draws=draws, seed=seed
        )

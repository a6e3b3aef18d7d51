"""What ``terracone predict`` computes, as one library call, and what it adds to a fit.

:func:`predict_profiles` fits CI profiles (section 3.3.2 of [1]_) as one
:class:`~terracone.inverse.problem.Problem` states and one
:class:`~terracone.inverse.predict.RunSettings` asks, and attaches predicted
plate curves (eq. (2-2), RM1 of section 3.2) and, through :func:`attach_fits`
(shared with ``batch`` and ``reproduce``), posteriors and layered fits.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from terracone.data import CIProfile, InputError, ProfileSet, TerrainParameters
from terracone.inverse.evaluate import predicted_plate_pressure
from terracone.inverse.library.mixture import result_bands
from terracone.inverse.predict import RunSettings, predict_many
from terracone.inverse.problem import Problem
from terracone.io import read_ci_profiles
from terracone.physics import units as u
from terracone.physics.cone import Cone
from terracone.result import (
    PlateCurve,
    PredictionResults,
    settings_dict,
    to_document,
    to_table,
)
from terracone.resultunits import from_si

__all__ = [
    "PredictRun",
    "Reading",
    "attach_fits",
    "repredict",
    "plate_curves",
    "predict_profiles",
    "sinkage_grid",
]


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


@dataclass(frozen=True)
class Reading:
    """How the commands read CI files (:func:`terracone.io.read_ci_profiles`).

    ``cone``: the cone of files that name none; ``format``: "csv", "sc900",
    "wide" or None (detected); ``depth_ref``: "tip" when the file's depths
    are the tip's (base = tip - H); ``depth_range``: base depths (lo, hi)
    [m] to fit, either None; ``depth_unit``, ``ci_unit``: units of a wide
    table; ``file_units``: unit system of a file that does not state it.
    """

    cone: str | Cone = "asabe-large"
    format: str | None = None
    depth_ref: str = "base"
    depth_range: tuple[float | None, float | None] = (None, None)
    depth_unit: str | None = None
    ci_unit: str | None = None
    file_units: str | None = None

    def read(
        self, path: str | os.PathLike[str], units: str = "si", on_error: str = "collect"
    ) -> list[Any]:
        """The profiles of ``path`` cut to ``depth_range`` (with a note; bad ones as InputError).

        ``units`` is the unit system of the notes.
        """
        how = {
            k: getattr(self, k) for k in ("cone", "depth_ref", "format", "depth_unit", "ci_unit")
        }
        items = read_ci_profiles(path, on_error=on_error, units=self.file_units, **how)
        lo, hi = self.depth_range
        if lo is None and hi is None:
            return items
        a, b = ("-" if x is None else f"{from_si(x, 'length', units):g}" for x in (lo, hi))
        span = f"depth window {a}:{b} {u.length_unit(units)}"
        out = []
        for it in items:  # the package's one depth window (terracone.data.depth_window)
            if not isinstance(it, InputError):
                w = it.window(lo, hi)
                w.notes = list(it.notes) + [f"{span}: {len(w)} of {len(it)} points"]
                it = w
            out.append(it)
        return out


@dataclass
class PredictRun:
    """Result of :func:`predict_profiles` (SI inside).

    ``results``: one :class:`~terracone.result.PredictionResult` per input
    item, in input order, with what was asked attached (``plate_curves``,
    ``posterior``, ``layered``, ``layered_posterior``); ``problem``: what
    was fitted; ``settings``: how.
    """

    results: PredictionResults
    problem: Problem
    settings: RunSettings

    def as_dict(
        self, units: str = "si", *, input: str | None = None, **extra: Any
    ) -> dict[str, Any]:
        """The ``terracone predict --json`` document; ``extra`` settings are recorded as given."""
        pb, s = self.problem, self.settings
        recorded = {"model": pb.model, "r_min": pb.r_min, "solver": s.solver, "seed": s.seed}
        recorded.update(bounds=pb.bounds, calibration=pb.record()["calibration"])
        if pb.library is not None:
            recorded.update(prior=pb.prior_label(), library=pb.library.source)
        doc_settings = settings_dict(recorded, units, **extra)
        return to_document(self.results, units, input=input, settings=doc_settings)

    def to_table(self, units: str = "si") -> pa.Table:
        """The ``terracone predict --parquet`` table (batch's part-file columns)."""
        return to_table(self.results, units)


def predict_profiles(
    items: Sequence[CIProfile | InputError],
    problem: Problem | None = None,
    settings: RunSettings | None = None,
    *,
    plates: Sequence[float] = (),
    sinkage: np.ndarray | None = None,
    band_sinkage: np.ndarray | None = None,
) -> PredictRun:
    """Predict terrain parameters for a set of CI profiles, with what predict adds on request.

    Parameters
    ----------
    items : sequence of CIProfile or InputError
        As readers return them; an :class:`InputError` is reported as that
        profile's error and the others are fitted.
    problem : Problem, optional
        What to fit (pressure law, bounds, a calibration's held values).
    settings : RunSettings, optional
        How to run, and what to attach (posterior with ``uncertainty``,
        layered fit with ``layers`` > 1).
    plates : sequence of float
        Plate radii [m] of predicted plate curves (and posterior bands).
    sinkage, band_sinkage : ndarray, optional
        Sinkages [m] of the plate curves (default :func:`sinkage_grid`) and
        of the posterior bands (default 21 points to 5 cm).
    """
    problem, settings = problem or Problem(), settings or RunSettings()
    results = predict_many(items, problem, settings)
    for it, r in zip(items, results):  # a reader's error: its row and column for the table
        if isinstance(it, InputError) and r.error_row is None and r.error_column is None:
            r.error_row, r.error_column = it.row, it.column
    s = sinkage_grid() if sinkage is None else sinkage
    for r in results:
        if r.ok and plates:
            r.plate_curves = plate_curves(r.params, plates, s, problem.plate_pair)
    bands = np.linspace(0.0, 0.05, 21) if band_sinkage is None else band_sinkage
    if problem.library is not None and plates:  # the mixture's bands at the plates asked
        for r in results:
            if r.ok and r.library is not None:
                r.library.plate_bands = result_bands(r, plates, bands)
    attach_fits(results, items, problem, settings, plates=list(plates) or None, band_sinkage=bands)
    return PredictRun(results, problem, settings)


def _cone_of(profiles: ProfileSet | Sequence[Any], j: int) -> Cone:
    if isinstance(profiles, ProfileSet):
        return profiles.cones[int(profiles.cone_idx[j])]
    return profiles[j].cone


def attach_fits(
    results: PredictionResults,
    profiles: ProfileSet | Sequence[CIProfile | InputError],
    problem: Problem,
    settings: RunSettings,
    *,
    plates: Sequence[float] | None = None,
    band_sinkage: np.ndarray | None = None,
    layered_posterior: bool = True,
) -> PredictionResults:
    """Attach to each fitted result its posterior and layered fit, as ``settings`` ask.

    The one place where ``predict``, ``batch`` and ``reproduce`` add them,
    each under the same ``problem`` as the fit: with ``settings.uncertainty``
    the posterior of the fit (:func:`terracone.inverse.uncertainty.posterior.posterior`,
    started at the fit; ``draws``, ``seed``; plate bands at ``plates`` [m]
    and ``band_sinkage`` [m]); with ``settings.layers`` > 1 a layered fit
    (:func:`terracone.inverse.layered.fit_layered`) and, with
    ``uncertainty`` and ``layered_posterior``, its posterior.  A profile
    whose posterior fails keeps its fit and says why in ``lack_of_fit``; a
    layered fit that fails is an error LayeredResult with the reason.

    ``profiles`` are the profiles fitted, aligned with ``results`` (their
    cones are used; depths and CI come from the results).  Returns
    ``results``, changed in place.
    """
    if not settings.uncertainty and settings.layers < 2:
        return results
    if settings.uncertainty:  # emcee and scipy.stats: imported only for a posterior
        from terracone.inverse.uncertainty.posterior import posterior

    s = settings
    for j, r in enumerate(results):
        if not r.ok:
            continue
        prof = CIProfile(r.id, r.depth, r.ci, cone=_cone_of(profiles, j), metadata=r.metadata)
        with np.errstate(all="ignore"):
            if s.uncertainty:
                try:
                    r.posterior = posterior(
                        prof, problem, start=r, draws=s.draws, seed=s.seed, plates=plates,
                        plate_sinkages=band_sinkage,
                    )  # fmt: skip
                except Exception as exc:  # noqa: BLE001 - recorded per profile, the rest goes on
                    r.lack_of_fit = "; ".join(
                        filter(None, [r.lack_of_fit, f"posterior failed: {exc}"])
                    )
            if s.layers > 1:
                r.layered, r.layered_posterior = _layered(prof, problem, s, layered_posterior)
    return results


def _layered(prof: CIProfile, problem: Problem, s: RunSettings, sample: bool) -> tuple[Any, Any]:
    """The layered fit of a profile (an error result if it fails) and, if asked, its posterior."""
    from terracone.inverse.layered import LayeredResult, fit_layered, layered_posterior

    try:
        lr = fit_layered(prof, problem, layers=s.layers)
    except Exception as exc:  # noqa: BLE001 - recorded per profile, the rest goes on
        why = f"{type(exc).__name__}: {exc}"
        return LayeredResult(id=prof.id, status="error", error=why), None
    if not (sample and s.uncertainty and lr.ok):
        return lr, None
    return lr, layered_posterior(prof, lr, problem, draws=s.draws, seed=s.seed)


def repredict(
    results: PredictionResults,
    problem: Problem,
    ci_profiles: Any = None,
) -> PredictionResults:
    """Predict again the profiles of a results file under ``problem`` (``--library`` of map, mobility).

    Each result's CI comes from the result (a predict JSON keeps it) or
    from ``ci_profiles`` (a mapping id -> CIProfile); a result with neither
    stays an error saying so.  Cones and metadata are the results'.
    """
    items: list[Any] = []
    for r in results:
        if r.depth is not None and r.ci is not None and len(r.depth):
            items.append(CIProfile(r.id, r.depth, r.ci, cone=r.cone, metadata=dict(r.metadata)))
        elif ci_profiles is not None and r.id in ci_profiles:
            items.append(ci_profiles[r.id])
        else:
            why = "no CI in the results to weigh the library's calibrations by"
            items.append(InputError(f"{why} (use predict --json, or --ci FILE)", profile=r.id))
    out = predict_many(items, problem)
    out.settings = {**results.settings, **problem.record()}
    out.header = dict(results.header)
    return out

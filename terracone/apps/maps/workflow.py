"""Terrain maps from located pushes: what ``terracone map`` computes.

:func:`map_survey` takes fitted, located pushes (:func:`terracone.result.read_results`)
to a :class:`TerrainMap`: for each quantity (plate pressure, n, mean CI over
depth layers) a fitted variogram, the kriged median and 90% interval of
every cell, the cells beyond the variogram's range masked, and the
leave-one-out cross-validation (:mod:`terracone.apps.maps.geostat`).  The
cells' kc, kphi and n for simulators come from the same kriging
(:func:`cell_parameters`).  :mod:`terracone.apps.maps.writers` writes it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from terracone.apps.maps.geostat import (
    CrossValidation,
    Variogram,
    fit_variogram,
    krige,
    leave_one_out,
    pooled,
)
from terracone.apps.maps.grid import Grid, choose_grid
from terracone.apps.maps.survey import (
    MIN_PUSHES,
    Quantity,
    Survey,
    ci_quantity,
    default_layer,
    locate,
    push_values,
)
from terracone.physics import units as u
from terracone.physics.metrics import finite_median
from terracone.result import PredictionResult
from terracone.resultunits import from_si

__all__ = [
    "LEVEL",
    "REFERENCE_SIZE",
    "UNCALIBRATED_MAP_NOTE",
    "BANDS",
    "TerrainMap",
    "QuantityMap",
    "beyond_range",
    "cell_parameters",
    "map_quantity",
    "map_survey",
]

#: Level of every interval of a map.
LEVEL = 0.9
Z90 = 1.6448536269514722  # Phi^-1(0.95)
#: The bands of a quantity's raster, in order, and what each is.
BANDS = {
    "median": "median of the local mean (the kriged smooth field)",
    "lo": "5% bound of the local mean: kriging variance of the smooth field, nugget excluded",
    "hi": "95% bound of the local mean: kriging variance of the smooth field, nugget excluded",
    "point_lo": "5% bound of the value at a point: kriging variance plus the nugget",
    "point_hi": "95% bound of the value at a point: kriging variance plus the nugget",
}
#: Plate size b [m] of the strength kc/b + kphi from which the cells' kc and kphi are
#: derived when no --plate is given.
REFERENCE_SIZE = 0.1

UNCALIBRATED_MAP_NOTE = (
    "no calibration: plate pressure from CI alone is set largely by the prior (phic trades "
    "against the scale of kc and kphi, and the CI does not fix kc, kphi and cc apart), so the "
    "plate_pressure map and the cells' kc/kphi split are not calibrated and its intervals are "
    "not calibrated 90% intervals; give predict --calibration for calibrated figures"
)


@dataclass
class QuantityMap:
    """The map of one quantity.

    Attributes
    ----------
    quantity : Quantity
    values : ndarray
        Each located push's value [SI] (NaN where it has none).
    excluded : list of (id, reason)
        Pushes without a value.
    variogram : Variogram or None
        None when too few pushes have a value (``skipped`` says why).
    cross_validation : CrossValidation or None
    median, lo, hi : ndarray, shape (height, width)
        The cells' median and 90% interval of the local mean (the smooth
        field) [SI]; NaN where masked.
    point_lo, point_hi : ndarray, shape (height, width)
        The 90% interval of the value at a point of the cell (the smooth
        field plus the nugget: what one push there, or a wheel, meets) [SI].
    estimation_variance : float
        Mean estimation variance of the pushes in the kriged space (NaN
        when the results do not tell it).
    pooled : (median, lo, hi, point_lo, point_hi) or None
        The field's pooled estimate [SI] when the variogram is a pure nugget.
    skipped : str or None
        Why no map was made.
    """

    quantity: Quantity
    values: np.ndarray
    excluded: list[tuple[str, str]]
    variogram: Variogram | None = None
    cross_validation: CrossValidation | None = None
    median: np.ndarray | None = None
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    point_lo: np.ndarray | None = None
    point_hi: np.ndarray | None = None
    estimation_variance: float = math.nan
    pooled: tuple[float, ...] | None = None
    skipped: str | None = None

    @property
    def name(self) -> str:
        return self.quantity.name

    @property
    def masked(self) -> int:
        return 0 if self.median is None else int(np.isnan(self.median).sum())

    def message(self) -> str | None:
        """The map's one-line caveat: skipped, or no spatial structure."""
        if self.skipped:
            return f"{self.name}: not mapped: {self.skipped}"
        vg = self.variogram
        if vg is not None and not vg.structure:
            return (
                f"{self.name}: no spatial structure (the variogram is a pure nugget; "
                f"permutation test p = {vg.p_value:.2g}): every cell has the field's pooled "
                f"estimate and its {LEVEL:.0%} interval"
            )
        return None


@dataclass
class TerrainMap:
    """A survey's maps: the grid, each quantity, the cells' parameters and the notes.

    Attributes
    ----------
    survey : Survey
    grid : Grid
    grid_note : str
        How the cell size was chosen.
    quantities : list of QuantityMap
    parameters : dict
        The cells' kc, kphi, n, cc, phic_deg [SI] (arrays of the grid's
        shape or scalars) and ``method`` (how they were derived).
    calibrated : bool
        Whether a calibration fixed kc/kphi, phic and cc.
    layer_note : str or None
        How the default CI layer was chosen.
    notes : list of str
    """

    survey: Survey
    grid: Grid
    grid_note: str
    quantities: list[QuantityMap]
    parameters: dict[str, Any]
    calibrated: bool
    layer_note: str | None = None
    notes: list[str] = field(default_factory=list)

    def __getitem__(self, name: str) -> QuantityMap:
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"no quantity {name!r} in this map")


def map_quantity(survey: Survey, q: Quantity, grid: Grid, *, progress: Any = None) -> QuantityMap:
    """Krige one quantity over the grid (see :mod:`terracone.apps.maps.geostat`)."""
    vals, evar, excluded = push_values(survey, q)
    ok = np.isfinite(vals)
    out = QuantityMap(q, vals, excluded)
    if ok.sum() < MIN_PUSHES:
        out.skipped = f"{int(ok.sum())} pushes have a value; a map needs at least {MIN_PUSHES}"
        return out
    z = np.log(vals[ok]) if q.log else vals[ok]
    px, py = survey.x[ok], survey.y[ok]
    vg = fit_variogram(px, py, z)
    out.variogram = vg
    out.cross_validation = leave_one_out(vg, px, py, z)
    ev = evar[ok]
    out.estimation_variance = float(np.mean(ev)) if np.all(np.isfinite(ev)) else math.nan
    gx, gy = grid.centres()
    if vg.structure:
        m, v = krige(vg, px, py, z, gx.ravel(), gy.ravel(), progress=progress)
        s, sp = np.sqrt(v), np.sqrt(v + vg.nugget)  # the local mean's; a point's (nugget in)
        far = beyond_range(vg, px, py, gx.ravel(), gy.ravel())
        bands = (m, m - Z90 * s, m + Z90 * s, m - Z90 * sp, m + Z90 * sp)
        cols = [np.where(far, np.nan, a).reshape(gx.shape) for a in bands]
    else:
        cols = [np.full(gx.shape, a) for a in pooled(z, LEVEL)]
        if progress:
            progress(gx.size)
    if q.log:
        cols = [np.exp(a) for a in cols]
    out.median, out.lo, out.hi, out.point_lo, out.point_hi = cols
    if not vg.structure:
        out.pooled = tuple(float(a.flat[0]) for a in cols)
    return out


def beyond_range(
    vg: Variogram, px: np.ndarray, py: np.ndarray, gx: np.ndarray, gy: np.ndarray
) -> np.ndarray:
    """Whether each place (gx, gy) lies farther than the variogram's range from every push
    (the masked cells of a map)."""
    d, _ = cKDTree(np.column_stack([px, py])).query(np.column_stack([gx, gy]))
    return d > vg.range


def _quantities(
    survey: Survey,
    plate: tuple[float, float] | None,
    layers: Sequence[tuple[float, float]] | None,
    units: str,
) -> tuple[list[Quantity], str | None]:
    out = []
    if plate is not None:
        b, z = plate
        bu, zu = (f"{v:g}" for v in from_si(plate, "length", units))
        unit = u.length_unit(units)
        out.append(
            Quantity(
                "plate_pressure",
                "pressure",
                True,
                f"plate pressure at {zu} {unit} sinkage under a plate of radius {bu} {unit}",
                "eq. (2-2) (RM1 of section 3.2 where the fit used it) with each push's kc, kphi, n",
                plate=(b, z),
            )
        )
    out.append(Quantity("n", "dimensionless", False, "sinkage exponent n", "each push's fit"))
    note = None
    if not layers:
        layer, why = default_layer(survey.results)
        layers, note = [layer], why
    measured = all(r.depth is not None and r.ci is not None for r in survey.results)
    out += [ci_quantity(lo, hi, units, measured) for lo, hi in layers]
    names = [q.name for q in out]
    if len(set(names)) < len(names):
        raise ValueError(f"--layers-ci: two layers have the same name ({', '.join(names)})")
    return out, note


def cell_parameters(
    survey: Survey, grid: Grid, n_map: QuantityMap, b: float, calibrated: bool
) -> tuple[dict[str, Any], QuantityMap]:
    """The cells' kc, kphi, n, cc, phic_deg [SI] and how they were derived.

    ``n`` is the n map's median.  The strength kc/b + kphi at plate size ``b``
    is kriged in log space like the other quantities, and split by the
    pushes' median share of kc/b in it: with a calibration that share is the
    calibration's (kc/kphi fixed), so kc and kphi are each kriged exactly;
    without one the split is the prior's.  cc and phic_deg are the pushes'
    medians (the calibration's values when there is one).
    """
    strength = Quantity(
        "strength", "pressure", True, f"kc/b + kphi at b = {b:g} m", "each push's fit", (b, 0.0)
    )
    s_map = map_quantity(survey, strength, grid)
    kc = np.array([r.params.kc for r in survey.results])
    kphi = np.array([r.params.kphi for r in survey.results])
    share = float(np.median((kc / b) / (kc / b + kphi)))
    s = s_map.median if s_map.median is not None else np.full((grid.height, grid.width), np.nan)
    how = (
        "n: the n map's median; kphi = (1 - f) S and kc = f S b, with S the kriged median of "
        f"the strength kc/b + kphi at b = {b:g} m (log space) and f = {share:.4g} the "
        + (
            "calibration's share of kc/b in it (kc/kphi fixed by the calibration)"
            if calibrated
            else "pushes' median share of kc/b in it (no calibration: the split is the prior's)"
        )
        + "; cc and phic_deg: the pushes' medians"
    )
    params = {
        "kc": share * s * b,
        "kphi": (1.0 - share) * s,
        "n": n_map.median,
        "cc": finite_median(r.params.cc for r in survey.results),
        "phic_deg": finite_median(r.params.phic_deg for r in survey.results),
        "model": survey.results[0].params.model,
        "r_min": survey.results[0].params.r_min,
        "reference_size": b,
        "kc_share": share,
        "method": how,
    }
    return params, s_map


#: Note of a map of results whose prior was a library of calibrations (predict --library).
LIBRARY_MAP_NOTE = (
    "the library as the prior: each push's kc, kphi and n are the medians of the mixture over "
    "the library's calibrations (docs/library.md), and the maps' intervals carry the mixture's "
    "spread, not one calibration's"
)


def _notes(survey: Survey, maps: Sequence[QuantityMap], calibrated: bool) -> list[str]:
    notes = list(survey.crs_warnings)
    if not calibrated and str(survey.settings.get("prior") or "").startswith("library:"):
        notes.append(LIBRARY_MAP_NOTE)
    elif not calibrated:
        notes.append(UNCALIBRATED_MAP_NOTE)
    if survey.unlocated:
        notes.append(
            f"{len(survey.unlocated)} fitted profiles have no coordinates and are not mapped: "
            + ", ".join(survey.unlocated)
        )
    for pid, why in survey.not_fitted:
        notes.append(f"not fitted, not mapped: {pid}: {why}")
    lack = [r.id for r in survey.results if r.lack_of_fit]
    if lack:
        notes.append(
            f"{len(lack)} of {len(survey.results)} mapped pushes are flagged for lack of fit "
            "(their parameters average a misfit): " + ", ".join(lack)
        )
    for m in maps:
        if m.message():
            notes.append(m.message())
        notes += [f"{m.name}: push {pid} left out: {why}" for pid, why in m.excluded]
    return notes


def map_survey(
    results: Sequence[PredictionResult],
    *,
    plate: tuple[float, float] | None = None,
    layers: Sequence[tuple[float, float]] | None = None,
    resolution: float | None = None,
    crs: str | None = None,
    units: str = "si",
    progress: Any = None,
) -> TerrainMap:
    """Maps of plate pressure, n and mean CI from located, fitted pushes.

    Parameters
    ----------
    results : PredictionResults
        From :func:`terracone.result.read_results` (its ``settings`` tell
        whether a calibration fixed kc/kphi, phic and cc).
    plate : (radius, sinkage), optional
        Plate radius and sinkage [m] of the ``plate_pressure`` map.
    layers : sequence of (lo, hi), optional
        Depth layers [m] of mean CI maps; default one layer over the depths
        every push reaches (:func:`~terracone.apps.maps.survey.default_layer`).
    resolution : float, optional
        Cell size [m]; default from the pushes' spacing (:func:`~terracone.apps.maps.grid.choose_grid`).
    crs : str, optional
        Projected CRS in metres; default the UTM zone of the pushes.
    units : {"si", "us"}
        Unit system of the names of CI layers (the maps themselves are SI).
    progress : callable, optional
        ``progress(k)`` after every ``k`` cells kriged (a progress bar's update).

    Returns
    -------
    TerrainMap

    Raises
    ------
    ValueError
        Fewer than 10 located pushes, all at one point, mixed coordinate
        systems (:func:`~terracone.apps.maps.survey.locate`); a bad resolution.
    """
    units = u.check_system(units)
    survey = locate(results, crs=crs)
    grid, grid_note = choose_grid(survey.x, survey.y, resolution)
    calibrated = survey.calibration is not None
    quantities, layer_note = _quantities(survey, plate, layers, units)
    maps = [map_quantity(survey, q, grid, progress=progress) for q in quantities]
    b = plate[0] if plate is not None else REFERENCE_SIZE
    n_map = next(m for m in maps if m.name == "n")
    params, s_map = cell_parameters(survey, grid, n_map, b, calibrated)
    params["strength"] = s_map
    return TerrainMap(
        survey,
        grid,
        grid_note,
        maps,
        params,
        calibrated,
        layer_note,
        _notes(survey, maps, calibrated),
    )

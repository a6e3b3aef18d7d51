"""Located pushes of a survey: coordinates, their projection and the quantities to map.

A survey is the fitted profiles of one results file (``predict --json``,
``predict --parquet`` or a ``batch`` directory, read by
:func:`terracone.result.read_results`) that carry a latitude and a
longitude in their metadata.  Coordinates are checked (one system, inside
the range of degrees, not all at one point) and projected to a metric CRS
with pyproj, by default the UTM zone of the pushes' centre.

Each push then gives one value per quantity (:class:`Quantity`):

* ``plate_pressure``: eq. (2-2) of [1]_ (RM1 of section 3.2 where the fit
  used it) at a plate radius and sinkage, from the push's kc, kphi, n;
* ``n``: the fitted sinkage exponent;
* ``ci_<lo>-<hi><unit>``: the mean cone index over a depth layer, from the
  push's measured CI (JSON results) or, where the file keeps no CI (Parquet
  and batch results), from the CI of its fitted model (eqs. (2-2) to (2-7));
* ``strength``: kc/b + kphi at the reference plate size b, from which the
  cells' kc and kphi are derived (not written as a raster).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) to (2-7), section 3.2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import trapezoid
from scipy.stats import norm

from terracone.data import TerrainParameters
from terracone.io.wide import WIDE_LAT_COLUMNS, WIDE_LON_COLUMNS, parse_coordinate
from terracone.physics import units as u
from terracone.physics.cone import cone_index_huang
from terracone.physics.plate import plate_pressure, pressure_law
from terracone.result import PredictionResult
from terracone.resultunits import convert_array, from_si

__all__ = [
    "CRS_SCALE_LIMIT",
    "CRS_SCALE_NOTE",
    "MIN_PUSHES",
    "Quantity",
    "Survey",
    "ci_quantity",
    "coordinates",
    "crs_fit",
    "default_layer",
    "layer_name",
    "locate",
    "metric_crs",
    "push_values",
]

#: Fewest located pushes a map is made from (a variogram needs pairs at several distances).
MIN_PUSHES = 10
#: Metadata keys other than lat/lon that hold projected coordinates (a mixed file).
PROJECTED_KEYS = ("x", "y", "easting", "northing", "utm_x", "utm_y")
#: Phi^-1(0.975): the half-width of a 95% profile interval in standard deviations.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Quantity:
    """One mapped quantity.

    Attributes
    ----------
    name : str
        Key in ``map.json`` and raster file stem (``plate_pressure``, ``n``, ``ci_0-15cm``).
    kind : {"pressure", "dimensionless"}
        Pressures are in kPa (SI) or psi (US) in files; n has no unit.
    log : bool
        Kriged in log space (positive quantities whose spread scales with size).
    label : str
        What it is, in words.
    source : str
        Where each push's value comes from.
    plate : (radius, sinkage) or None
        Plate radius and sinkage [m] of ``plate_pressure``; the reference size
        [m] (and None) of ``strength``.
    layer : (lo, hi) or None
        Depth layer [m] of a mean CI.
    """

    name: str
    kind: str
    log: bool
    label: str
    source: str = ""
    plate: tuple[float, float] | None = None
    layer: tuple[float, float] | None = None

    def unit(self, units: str) -> str:
        """The unit of the quantity's values in a unit system ("-" for n)."""
        return u.pressure_unit(units) if self.kind == "pressure" else "-"

    def from_si(self, values: Any, units: str) -> np.ndarray:
        """Values [SI] in ``units``."""
        return convert_array(values, "pressure" if self.kind == "pressure" else "none", units)


@dataclass
class Survey:
    """The located, fitted pushes of a results file, projected to a metric CRS.

    Attributes
    ----------
    results : list of PredictionResult
        The located pushes that were fitted, in file order.
    lat, lon : ndarray
        Decimal degrees (WGS 84) of each push.
    x, y : ndarray
        Coordinates [m] in ``crs`` (east, north).
    crs : pyproj.CRS
        The map's projected CRS.
    crs_note : str
        How the CRS was chosen.
    crs_fit : dict
        How the CRS fits the pushes (:func:`crs_fit`): its area of use, the
        pushes outside it, the largest distance error at a push.
    crs_warnings : list of str
        What the map's notes say about the CRS (pushes outside its area of use,
        distances off by more than 1 %).
    unlocated : list of str
        Fitted profiles without coordinates (not mapped).
    not_fitted : list of (id, reason)
        Profiles whose fit failed (not mapped).
    settings : dict
        The run's settings as the results file records them.
    """

    results: list[PredictionResult]
    lat: np.ndarray
    lon: np.ndarray
    x: np.ndarray
    y: np.ndarray
    crs: Any
    crs_note: str
    unlocated: list[str] = field(default_factory=list)
    not_fitted: list[tuple[str, str]] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)
    crs_fit: dict[str, Any] = field(default_factory=dict)
    crs_warnings: list[str] = field(default_factory=list)

    @property
    def ids(self) -> list[str]:
        return [r.id for r in self.results]

    @property
    def calibration(self) -> Any:
        """The calibration that fixed kc/kphi, phic and cc (its name or record), or None."""
        return self.settings.get("calibration") or None

    def plate_pair(self) -> tuple[float, float] | None:
        """Plate radii [m] of the calibration's RM1 secant, when the results record them."""
        pair = self.settings.get("plate_pair_m")
        cal = self.settings.get("calibration")
        if pair is None and isinstance(cal, Mapping):
            pair = cal.get("plate_pair")
        return None if not pair else (float(pair[0]), float(pair[1]))


# ---------------------------------------------------------------------------
# coordinates
# ---------------------------------------------------------------------------


def _lookup(meta: Mapping[str, Any], keys: Sequence[str]) -> tuple[str, Any] | None:
    lower = {str(k).strip().lower(): (k, v) for k, v in meta.items()}
    for k in keys:
        if k in lower:
            key, v = lower[k]
            if v is None or (isinstance(v, float) and math.isnan(v)):
                continue
            if isinstance(v, str) and not v.strip():
                continue
            return key, v
    return None


def _degrees(rid: str, key: str, value: Any, axis: str) -> float:
    """Decimal degrees of one metadata value: a number, or text such as 34°22.92106S."""
    if isinstance(value, int | float | np.number) and not isinstance(value, bool):
        return float(value)
    try:
        out = parse_coordinate(str(value), axis)  # type: ignore[arg-type]
    except ValueError as exc:
        raise ValueError(f"profile {rid}: metadata {key} {value!r}: {exc}") from None
    if out is None:
        raise ValueError(f"profile {rid}: metadata {key} is empty")
    return out


def coordinates(results: Sequence[PredictionResult]) -> tuple[list[int], np.ndarray, np.ndarray]:
    """Indices of the results with a latitude and a longitude, and those (degrees).

    Keys ``lat``/``latitude`` (and the wide-table names such as ``gps_lat``)
    and ``lon``/``longitude``/``long``/``lng``, any case; numbers or text in
    degrees (decimal, degrees and minutes, degrees minutes seconds).

    Raises
    ------
    ValueError
        A value that is not a coordinate; a file that mixes lat/lon with
        projected coordinates (x/y, easting/northing) or gives values outside
        [-90, 90] x [-180, 180]; each names the profiles.
    """
    idx, lat, lon, projected = [], [], [], []
    for i, r in enumerate(results):
        la = _lookup(r.metadata, WIDE_LAT_COLUMNS)
        lo = _lookup(r.metadata, WIDE_LON_COLUMNS)
        if la is None or lo is None:
            if _lookup(r.metadata, PROJECTED_KEYS) is not None:
                projected.append(r.id)
            continue
        idx.append(i)
        lat.append(_degrees(r.id, la[0], la[1], "lat"))
        lon.append(_degrees(r.id, lo[0], lo[1], "lon"))
    lat_a, lon_a = np.array(lat, dtype=float), np.array(lon, dtype=float)
    if idx and projected:
        raise ValueError(
            f"mixed coordinate systems: {len(idx)} profiles have lat/lon, {len(projected)} "
            f"have projected coordinates only (x/y or easting/northing: {_names(projected)}); "
            "give every profile lat/lon in degrees"
        )
    bad = ~((np.abs(lat_a) <= 90.0) & (np.abs(lon_a) <= 180.0))
    if bad.any():
        ids = [results[idx[k]].id for k in np.flatnonzero(bad)]
        k = int(np.flatnonzero(bad)[0])
        what = (
            "no coordinate is in degrees (projected metres?)"
            if bad.all()
            else f"mixed coordinate systems: {int(bad.sum())} of {len(idx)} profiles"
        )
        raise ValueError(
            f"{what}: lat/lon outside [-90, 90] x [-180, 180] in {_names(ids)} (profile "
            f"{ids[0]}: lat {lat_a[k]:g}, lon {lon_a[k]:g}); give lat/lon in decimal degrees"
        )
    return idx, lat_a, lon_a


def _names(ids: Sequence[str], most: int = 8) -> str:
    shown = ", ".join(ids[:most])
    return shown + (f" and {len(ids) - most} more" if len(ids) > most else "")


def metric_crs(lat: np.ndarray, lon: np.ndarray, crs: str | None = None) -> tuple[Any, str]:
    """The projected CRS of a map and how it was chosen.

    ``crs`` (anything pyproj reads, e.g. ``EPSG:32615``) must be projected
    in metres; by default the WGS 84 UTM zone of the pushes' centre.
    """
    from pyproj import CRS
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    if crs is not None:
        try:
            out = CRS.from_user_input(crs)
        except Exception as exc:  # pyproj.exceptions.CRSError
            raise ValueError(f"--crs {crs!r}: not a coordinate reference system ({exc})") from None
        units = {a.unit_name for a in out.axis_info}
        if not out.is_projected or units - {"metre"}:
            raise ValueError(
                f"--crs {crs!r}: a map needs a projected CRS in metres (got {out.name}, "
                f"axes in {', '.join(sorted(units)) or 'no unit'})"
            )
        return out, "given with --crs"
    span = float(np.ptp(lon))
    if span > 6.0:
        raise ValueError(
            f"the pushes span {span:.3g} degrees of longitude, more than one UTM zone (6 "
            "degrees): mixed coordinate systems or signs? For a regional map give --crs"
        )
    clat, clon = float(np.mean(lat)), float(np.mean(lon))
    info = query_utm_crs_info(
        datum_name="WGS 84",
        area_of_interest=AreaOfInterest(clon, clat, clon, clat),
    )
    if not info:  # pragma: no cover - every point on Earth has a UTM zone
        raise ValueError(f"no UTM zone found for lat {clat:g}, lon {clon:g}; give --crs")
    out = CRS.from_epsg(int(info[0].code))
    return out, "the WGS 84 UTM zone of the pushes' centre (default; --crs to change)"


#: Largest distance error of a map's CRS (its scale factor's distance from 1) at a push
#: outside the CRS's area of use: beyond it the push is far outside and the map is
#: refused.  Above :data:`CRS_SCALE_NOTE` anywhere the map notes it.  Within its zone a
#: UTM projection is off by at most about 0.1 %.
CRS_SCALE_LIMIT = 0.05
CRS_SCALE_NOTE = 0.01


def _scale_error(crs: Any, lat: np.ndarray, lon: np.ndarray) -> np.ndarray | None:
    """|scale factor - 1| at each point (the larger of the meridional and parallel scale;
    inf where the projection folds or fails); None when pyproj cannot tell."""
    from pyproj import Proj

    try:
        f = Proj(crs).get_factors(lon, lat, errcheck=False)
    except Exception:  # pyproj.exceptions.ProjError and friends: no factors for this CRS
        return None
    h, k, areal = (
        np.asarray(v, dtype=float).reshape(lat.shape)
        for v in (f.meridional_scale, f.parallel_scale, f.areal_scale)
    )
    err = np.maximum(np.abs(h - 1.0), np.abs(k - 1.0))
    return np.where(np.isfinite(err) & (areal > 0), err, np.inf)


def crs_fit(
    crs: Any, lat: np.ndarray, lon: np.ndarray, ids: Sequence[str], given: bool
) -> tuple[dict[str, Any], list[str]]:
    """How a projected CRS fits the pushes: its area of use and its distance error there.

    Parameters
    ----------
    crs : pyproj.CRS
    lat, lon : ndarray
        The pushes [deg].
    ids : sequence of str
        Their ids, for messages.
    given : bool
        Whether the user chose the CRS (--crs), for messages.

    Returns
    -------
    dict
        ``area_of_use`` (name), ``bounds`` [west, south, east, north] [deg],
        ``pushes_outside``, ``scale_error`` (largest |scale factor - 1| at a
        push, None when pyproj gives no factors).
    list of str
        Warnings: pushes outside the area of use; distances off by more than
        :data:`CRS_SCALE_NOTE`.

    Raises
    ------
    ValueError
        A push far outside the area of use (distances off by more than
        :data:`CRS_SCALE_LIMIT` there), or a projection that fails or folds at a
        push (the message names the push and the area of use).
    """
    aou = crs.area_of_use
    outside = np.zeros(lat.size, dtype=bool)
    info: dict[str, Any] = {"area_of_use": None, "bounds": None}
    where = ""
    if aou is not None:
        w, s, e, n = (float(v) for v in aou.bounds)
        in_lon = (lon >= w) & (lon <= e) if w <= e else (lon >= w) | (lon <= e)
        outside = ~(in_lon & (lat >= s) & (lat <= n))
        info.update(area_of_use=aou.name, bounds=[w, s, e, n])
        name = aou.name.rstrip(".")
        name = name if len(name) <= 60 else name[:57].rstrip(" ,.") + "..."
        where = f"{name} (lon {w:g} to {e:g}, lat {s:g} to {n:g})"
    err = _scale_error(crs, lat, lon)
    finite = err is not None and bool(np.all(np.isfinite(err)))
    info.update(
        pushes_outside=int(outside.sum()),
        scale_error=float(np.max(err)) if finite else None,
    )
    label = f"{'--crs ' if given else ''}{crs.name}"
    far = (
        None
        if err is None
        else np.flatnonzero(~np.isfinite(err) | (outside & (err > CRS_SCALE_LIMIT)))
    )
    if far is not None and far.size:
        i = int(far[np.argmax(err[far])])
        off = "cannot measure distances" if not np.isfinite(err[i]) else (
            f"measures distances {err[i]:.0%} wrong"
        )  # fmt: skip
        area = f"; its area of use is {where}" if where else ""
        raise ValueError(
            f"{label} {off} at push {ids[i]} (lat {lat[i]:.6g}, lon {lon[i]:.6g}; "
            f"{int(outside.sum())} of {lat.size} pushes lie outside its area of use){area}: "
            "a map in it would be wrong; give a CRS made for the pushes' area (without --crs "
            "the map uses their UTM zone)"
        )
    notes = []
    if outside.any():
        notes.append(
            f"{int(outside.sum())} of {lat.size} pushes lie outside the area of use of {label}, "
            f"{where}: " + ", ".join(str(ids[i]) for i in np.flatnonzero(outside)[:8])
        )
    if info["scale_error"] is not None and info["scale_error"] > CRS_SCALE_NOTE:
        notes.append(
            f"distances in {label} are off by up to {info['scale_error']:.1%} at the pushes"
        )
    return info, notes


def locate(results: Sequence[PredictionResult], *, crs: str | None = None) -> Survey:
    """The survey of a set of results: located, fitted pushes projected to a metric CRS.

    Parameters
    ----------
    results : PredictionResults
        As :func:`terracone.result.read_results` returns them (``settings`` is kept).
    crs : str, optional
        Projected CRS in metres; default the UTM zone (:func:`metric_crs`).

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_PUSHES` located, fitted pushes; all of them at
        one point; mixed or out-of-range coordinates (:func:`coordinates`).
    """
    from pyproj import Transformer

    settings = dict(getattr(results, "settings", {}) or {})
    results = list(results)
    idx, lat, lon = coordinates(results)
    located = set(idx)
    not_fitted = [(r.id, r.error or r.message or r.status) for r in results if not r.ok]
    unlocated = [r.id for i, r in enumerate(results) if i not in located and r.ok]
    keep = [k for k, i in enumerate(idx) if results[i].ok and results[i].params is not None]
    if len(keep) < MIN_PUSHES:
        raise ValueError(
            f"a map needs at least {MIN_PUSHES} located, fitted pushes; got {len(keep)} "
            f"({len(results)} profiles: {len(unlocated)} fitted without coordinates, "
            f"{len(not_fitted)} not fitted)"
        )
    lat, lon = lat[keep], lon[keep]
    pushes = [results[idx[k]] for k in keep]
    out_crs, note = metric_crs(lat, lon, crs)
    tr = Transformer.from_crs("EPSG:4326", out_crs, always_xy=True)
    x, y = (np.asarray(v, dtype=float) for v in tr.transform(lon, lat))
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError(f"the pushes cannot be projected to {out_crs.name}; give another --crs")
    if len({(round(a, 3), round(b, 3)) for a, b in zip(x, y)}) < 3:
        raise ValueError(
            f"the {len(pushes)} located pushes lie at fewer than 3 distinct points (lat "
            f"{lat[0]:.6f}, lon {lon[0]:.6f}): a map needs pushes spread over the field"
        )
    fit, warnings = crs_fit(out_crs, lat, lon, [r.id for r in pushes], given=crs is not None)
    return Survey(
        pushes, lat, lon, x, y, out_crs, note, unlocated, not_fitted, settings, fit, warnings
    )


# ---------------------------------------------------------------------------
# the quantities of each push
# ---------------------------------------------------------------------------


def layer_name(lo: float, hi: float, units: str) -> str:
    """File-safe name of a CI layer: ``ci_0-15cm`` (SI) or ``ci_0-6in`` (US)."""
    f, unit = (100.0, "cm") if units == "si" else (1.0 / u.INCH, "in")
    return f"ci_{lo * f:.4g}-{hi * f:.4g}{unit}"


def ci_quantity(lo: float, hi: float, units: str, measured: bool) -> Quantity:
    """The mean-CI quantity of the layer lo-hi [m]."""
    unit = u.length_unit(units)
    a, b = from_si((lo, hi), "length", units)
    source = (
        "each push's measured CI, averaged over the layer (trapezoids)"
        if measured
        else "the CI of each push's fitted model (eqs. (2-2) to (2-7)), averaged over the layer: "
        "the results file keeps no measured CI (Parquet and batch results)"
    )
    return Quantity(
        layer_name(lo, hi, units),
        "pressure",
        True,
        f"mean cone index from {a:g} to {b:g} {unit} depth",
        source,
        layer=(lo, hi),
    )


def default_layer(results: Sequence[PredictionResult]) -> tuple[tuple[float, float], str]:
    """The default CI layer [m]: the depths every push reaches, and why.

    When that is under half the median push's depth range, the depths that
    90% of the pushes reach (the shallower pushes are then left out of the
    CI map, each named).
    """
    spans = [(float(r.depth[0]), float(r.depth[-1])) for r in results if _has_ci(r)]
    if not spans:  # model CI: the fits carry no depths, use the pushes' fitted range
        return (0.0, 0.3), "0-30 cm (the results keep no depths)"
    first = np.array([s[0] for s in spans])
    last = np.array([s[1] for s in spans])
    lo, hi = float(first.max()), float(last.min())
    if hi - lo >= 0.5 * float(np.median(last - first)):
        return (lo, hi), "the depths every push reaches"
    lo, hi = float(np.quantile(first, 0.9)), float(np.quantile(last, 0.1))
    return (lo, hi), "the depths 90% of the pushes reach (every push reaches too little)"


def _has_ci(r: PredictionResult) -> bool:
    return r.depth is not None and r.ci is not None and len(r.depth) >= 2


def _mean_ci(r: PredictionResult, lo: float, hi: float) -> tuple[float, str | None]:
    """Mean CI [kPa] over lo-hi of one push (measured when kept, else its model), or a reason."""
    if _has_ci(r):
        z, ci = np.asarray(r.depth, dtype=float), np.asarray(r.ci, dtype=float)
        tol = 1e-6
        if z[0] > lo + tol or z[-1] < hi - tol:
            return math.nan, f"its CI covers {z[0]:.4g}-{z[-1]:.4g} m, not the layer"
        inside = (z > lo) & (z < hi)
        zz = np.concatenate([[lo], z[inside], [hi]])
        cc = np.concatenate([[np.interp(lo, z, ci)], ci[inside], [np.interp(hi, z, ci)]])
        return float(trapezoid(cc, zz) / (hi - lo)), None
    p = r.params
    zz = np.linspace(lo, hi, 41)
    law = pressure_law(p.model, r_min=p.r_min) if p.model == "rm1" else None
    ci = cone_index_huang(
        zz, kc=p.kc, kphi=p.kphi, n=p.n, cc=p.cc, phic_deg=p.phic_deg, law=law, cone=r.cone
    )
    return float(trapezoid(ci, zz) / (hi - lo)), None


def _plate(p: TerrainParameters, radius: float, sinkage: float, pair: Any) -> float:
    return float(
        plate_pressure(
            sinkage,
            kc=p.kc,
            kphi=p.kphi,
            n=p.n,
            radius=radius,
            model=p.model,
            r_min=p.r_min if p.model == "rm1" else None,
            plate_pair=pair if p.model == "rm1" else None,
        )
    )


def _posterior(r: PredictionResult, calibrated: bool) -> Any:
    """The push's posterior when its prior is that of the fit (a calibration's, or the bounds').

    A posterior under the bounds prior of a calibrated fit describes another
    estimate (kc/kphi, phic and cc free): its spread is not the fit's.
    """
    post = r.posterior
    prior = "" if post is None else str(post.prior or "")
    if post is None or calibrated != prior.startswith("calibration"):
        return None
    return post


def _draws_variance(r: PredictionResult, q: Quantity, pair: Any, calibrated: bool) -> float:
    """Variance over the posterior draws of the kriged value (log or linear), NaN without draws."""
    post = _posterior(r, calibrated)
    s = None if post is None else post.samples
    if s is None or len(s) < 2:
        return math.nan
    s = np.asarray(s, dtype=float)
    if q.name == "n":
        return float(np.var(s[:, 2], ddof=1))
    if q.plate is None or q.layer is not None:
        return math.nan
    radius, z = q.plate
    ok = (s[:, 0] >= 0) & (s[:, 1] >= 0) & (s[:, 2] > 0) & (s[:, 2] <= 3)
    if q.name == "strength":
        v = s[ok, 0] / radius + s[ok, 1]
    else:
        p = r.params
        v = plate_pressure(
            z, kc=s[ok, 0], kphi=s[ok, 1], n=s[ok, 2], radius=radius, model=p.model,
            r_min=p.r_min if p.model == "rm1" else None, plate_pair=pair if p.model == "rm1" else None,
        )  # fmt: skip
    v = v[v > 0]
    return float(np.var(np.log(v), ddof=1)) if v.size > 1 else math.nan


def _n_variance(r: PredictionResult, calibrated: bool) -> float:
    """Estimation variance of n from its interval (posterior 90%, else profile 95%)."""
    post = _posterior(r, calibrated)
    if post is not None and "n" in post.intervals:
        lo, hi = post.intervals["n"]
        z = float(norm.ppf(0.5 + 0.5 * float(post.level)))
        return ((hi - lo) / (2 * z)) ** 2
    if "n" in r.profile_intervals:
        lo, hi = r.profile_intervals["n"]
        return ((hi - lo) / (2 * Z95)) ** 2
    return math.nan


def push_values(
    survey: Survey, q: Quantity
) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str]]]:
    """Each push's value of ``q`` [SI], its estimation variance in the kriged space, exclusions.

    The estimation variance is NaN where the results do not tell it (it is
    then only part of the fitted nugget).  A push without a usable value is
    NaN and listed with the reason.
    """
    pair = survey.plate_pair()
    vals, evar, excluded = [], [], []
    for r in survey.results:
        p = r.params
        why = None
        if q.name == "n":
            v = p.n
        elif q.layer is not None:
            v, why = _mean_ci(r, *q.layer)
        elif q.name == "strength":
            v = p.kc / q.plate[0] + p.kphi
        else:
            v = _plate(p, q.plate[0], q.plate[1], pair)
        if why is None and q.log and not v > 0:
            why = f"{q.name} {v:g} is not positive (kriged in log space)"
        if why is None and not math.isfinite(v):
            why = f"{q.name} is not a number"
        if why is not None:
            excluded.append((r.id, why))
            v = math.nan
        vals.append(v)
        cal = survey.calibration is not None
        evar.append(_n_variance(r, cal) if q.name == "n" else _draws_variance(r, q, pair, cal))
    return np.array(vals, dtype=float), np.array(evar, dtype=float), excluded

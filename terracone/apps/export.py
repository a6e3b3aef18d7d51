"""Export terrains and results: plain Bekker-Wong tables, GeoJSON, and Chrono's SCM inputs.

Plain export (:func:`to_plain`, :func:`write_plain_csv`,
:func:`export_terrain`): kc, kphi, n, c, phi_deg, K, cc, phic_deg, Kc,
model, r_min, moisture_pct in SI (kN/m^(n+1), kN/m^(n+2), kPa, m) or US
customary (lb/in^(n+1), lb/in^(n+2), psi, in), via
:mod:`terracone.physics.units`.

Results of ``predict`` and ``batch`` are read by
:func:`terracone.result.read_results` (SI); here they are picked
(:func:`pick_profile`), located (:func:`location`: metadata ``lat``/``latitude``
and ``lon``/``longitude``/``long``/``lng``, any case), sampled
(:func:`draw_samples`: posterior draws) and placed on a map (:func:`geojson`).

For Project Chrono (:mod:`terracone.apps.chrono`) the cone's kc, kphi and n
are joined with the terrain's own shear strength and Janosi modulus, from a
``fit-shear --json`` file, a library terrain or explicit values
(:func:`shear_of`, :func:`merge_shear`), into
:class:`~terracone.apps.chrono.LocatedSoil` (:func:`terrain_soil`,
:func:`result_soils`).  The cone (metal)-terrain adhesion and friction cc,
phic of the paper are *not* the terrain's internal cohesion and friction and
are never used as Mohr parameters.

With a vehicle (:func:`running_gear`), a profile's layered fit
(:func:`layered_ground`) is replaced by its effective one-layer soil for the
vehicle's wheel or track (:func:`effective_soils`,
:func:`terracone.physics.effective.effective_soil`).
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from terracone.apps.chrono import SHEAR_KEYS, LocatedSoil
from terracone.apps.library import Library, TerrainRecord, check_params, record_params
from terracone.data import TerrainParameters, TerrainShear
from terracone.io.jsonkeys import FileKeyError, read_json
from terracone.io.tables import guard_formula
from terracone.physics import units as u
from terracone.result import UQ_PARAMS, PredictionResult, PredictionResults
from terracone.resultunits import from_si

__all__ = [
    "FORMATS",
    "PLAIN_FIELDS",
    "RunningGear",
    "draw_samples",
    "effective_soils",
    "export_terrain",
    "geojson",
    "layered_ground",
    "location",
    "map_soils",
    "merge_shear",
    "pick_profile",
    "plain_units",
    "result_soils",
    "running_gear",
    "shear_of",
    "terrain_soil",
    "to_plain",
    "write_geojson",
    "write_plain_csv",
]

#: Fields of the plain export, in column order.
PLAIN_FIELDS = (
    "kc",
    "kphi",
    "n",
    "c",
    "phi_deg",
    "K",
    "cc",
    "phic_deg",
    "Kc",
    "model",
    "r_min",
    "moisture_pct",
)

#: Each plain field's library key (SI) and quantity (None: written as stored).
_PLAIN_FROM = {
    "kc": ("kc", "kc"),
    "kphi": ("kphi", "kphi"),
    "n": ("n", None),
    "c": ("c_kpa", "pressure"),
    "phi_deg": ("phi_deg", None),
    "K": ("K_m", "length"),
    "cc": ("cc", "pressure"),
    "phic_deg": ("phic_deg", None),
    "Kc": ("Kc", "length"),
    "model": ("model", None),
    "r_min": ("r_min", "length"),
    "moisture_pct": ("moisture_pct", None),
}

#: Formats of :func:`export_terrain` (plain parameters).
FORMATS = ("json", "csv")


def _params_of(
    obj: TerrainRecord | TerrainParameters | TerrainShear | Mapping[str, Any],
) -> dict[str, Any]:
    """SI parameter dict (library keys) of a record, TerrainParameters, TerrainShear or dict."""
    if isinstance(obj, TerrainRecord):
        return check_params(obj.params)
    if isinstance(obj, TerrainParameters | TerrainShear):
        return record_params(obj)
    if isinstance(obj, Mapping):
        d = dict(obj)
        units = d.pop("units", "si")
        if units != "si":
            raise ValueError("parameter dicts must be in SI (library keys); got units=" + units)
        return check_params(d)
    raise TypeError(
        "expected a TerrainRecord, TerrainParameters, TerrainShear or dict "
        f"(got {type(obj).__name__})"
    )


def _name_of(obj: Any, name: str | None) -> str:
    if name:
        return str(name)
    if isinstance(obj, TerrainRecord):
        return obj.name
    raise ValueError("a name is needed for a terrain that is not a library record")


def plain_units(units: str = "si") -> dict[str, str]:
    """Unit of each plain field in a unit system."""
    units = u.check_system(units)
    L, P = u.length_unit(units), u.pressure_unit(units)
    return {
        "kc": u.kc_unit(units),
        "kphi": u.kphi_unit(units),
        "n": "-",
        "c": P,
        "phi_deg": "deg",
        "K": L,
        "cc": P,
        "phic_deg": "deg",
        "Kc": L,
        "model": "-",
        "r_min": L,
        "moisture_pct": "%",
    }


def to_plain(
    record_or_params: TerrainRecord | TerrainParameters | Mapping[str, Any],
    units: str = "si",
) -> dict[str, Any]:
    """Plain Bekker-Wong parameters in a unit system.

    Parameters
    ----------
    record_or_params : TerrainRecord, TerrainParameters or dict
        The terrain, SI.
    units : {"si", "us"}
        SI: kc [kN/m^(n+1)], kphi [kN/m^(n+2)], c, cc [kPa], K, Kc, r_min [m];
        US: [lb/in^(n+1)], [lb/in^(n+2)], [psi], [in].

    Returns
    -------
    dict
        Every key of :data:`PLAIN_FIELDS` (None where the terrain lacks it),
        plus ``"units"``; ``"name"`` first for a library record.
    """
    units = u.check_system(units)
    p = _params_of(record_or_params)
    n = p.get("n")
    if n is None and units != "si" and ("kc" in p or "kphi" in p):
        raise ValueError("kc and kphi cannot be converted to US units without n")

    def get(name: str) -> Any:
        key, quantity = _PLAIN_FROM[name]
        if key not in p:
            return None
        return p[key] if quantity is None else from_si(p[key], quantity, units, n)

    out: dict[str, Any] = {}
    if isinstance(record_or_params, TerrainRecord):
        out["name"] = record_or_params.name
    out.update({name: get(name) for name in PLAIN_FIELDS})
    out["units"] = units
    return out


def write_plain_csv(
    path: str | os.PathLike,
    terrains: Iterable[TerrainRecord | tuple[str, Any]],
    units: str = "si",
) -> None:
    """CSV of plain parameters, one row per terrain.

    ``terrains`` holds library records or ``(name, params)`` pairs.  The
    header names each column's unit, e.g. ``kc [kN/m^(n+1)]``; empty cells
    are parameters the terrain lacks.  A name or text value that begins with
    ``=``, ``+``, ``-``, ``@``, a tab or a carriage return is written after a
    single quote, so that a spreadsheet shows it as text instead of running it
    as a formula (OWASP's advice against CSV injection); numbers are numbers.
    """
    units = u.check_system(units)
    labels = plain_units(units)
    header = ["name"] + [f"{f} [{labels[f]}]" if labels[f] != "-" else f for f in PLAIN_FIELDS]
    rows = []
    for t in terrains:
        if isinstance(t, TerrainRecord):
            name, obj = t.name, t
        else:
            name, obj = t
        d = to_plain(obj, units)
        cells = ["" if d[f] is None else d[f] for f in PLAIN_FIELDS]
        rows.append([guard_formula(name)] + [_cell(v) for v in cells])
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def _cell(v: Any) -> Any:
    """A CSV cell: numbers as they are, text guarded (:func:`guard_formula`)."""
    return v if isinstance(v, int | float) else guard_formula(v)


def export_terrain(
    record_or_params: TerrainRecord | TerrainParameters | Mapping[str, Any],
    fmt: str,
    path: str | os.PathLike,
    *,
    name: str | None = None,
    units: str = "si",
) -> list[str]:
    """Write a terrain's plain parameters as ``"json"`` or ``"csv"``; returns what it lacks.

    ``"json"``: :func:`to_plain` as a JSON object (with ``name`` and
    ``unit_labels``); ``"csv"``: one-row :func:`write_plain_csv`.  The
    returned list names the Bekker-Wong fields (kc, kphi, n, c, phi_deg, K)
    the terrain lacks.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)} (got {fmt!r})")
    nm = _name_of(record_or_params, name)
    d = to_plain(record_or_params, units)
    missing = [f for f in ("kc", "kphi", "n", "c", "phi_deg", "K") if d[f] is None]
    if fmt == "json":
        d = {"name": nm, **{k: v for k, v in d.items() if k != "name"}}
        d["unit_labels"] = plain_units(units)
        Path(path).write_text(json.dumps(d, indent=2) + "\n", encoding="utf-8")
    else:
        write_plain_csv(path, [(nm, record_or_params)], units)
    return missing


# ---------------------------------------------------------------------------
# results of predict and batch (read by terracone.result.read_results)
# ---------------------------------------------------------------------------

_LAT_KEYS = ("lat", "latitude")
_LON_KEYS = ("lon", "longitude", "long", "lng")


def _degrees(metadata: Mapping[str, Any], keys: tuple[str, ...], limit: float) -> float | None:
    lower = {str(k).strip().lower(): v for k, v in metadata.items()}
    for k in keys:
        v = lower.get(k)
        if v is None or isinstance(v, bool) or (isinstance(v, str) and not v.strip()):
            continue
        try:
            x = float(v)
        except (TypeError, ValueError):
            continue
        if math.isfinite(x) and -limit <= x <= limit:
            return x
    return None


def location(result: PredictionResult) -> tuple[float, float] | None:
    """(lat, lon) [decimal degrees] of a result, from its metadata; None when not located.

    Keys ``lat``/``latitude`` and ``lon``/``longitude``/``long``/``lng`` in
    any case; numbers or numeric text; a value outside [-90, 90] or
    [-180, 180] does not count.
    """
    lat = _degrees(result.metadata, _LAT_KEYS, 90.0)
    lon = _degrees(result.metadata, _LON_KEYS, 180.0)
    return None if lat is None or lon is None else (lat, lon)


def _shown(ids: Sequence[str]) -> str:
    return ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")


def pick_profile(
    results: Sequence[PredictionResult], profile: str | None, source: str
) -> PredictionResult:
    """The profile named ``profile``, or the only fitted one; ValueError otherwise."""
    if profile is not None:
        hits = [r for r in results if r.id == profile]
        if not hits:
            raise ValueError(
                f"{source}: no profile {profile!r} (it has {_shown([r.id for r in results])})"
            )
        r = hits[0]
    else:
        ok = [r for r in results if r.ok]
        if len(ok) != 1:
            raise ValueError(
                f"{source}: {len(ok)} fitted profiles; choose one with --profile ID "
                f"({_shown([r.id for r in ok])})"
            )
        r = ok[0]
    if r.params is None or not r.ok:
        raise ValueError(f"{source}: profile {r.id!r} was not fitted ({r.error or r.status})")
    return r


def draw_samples(
    result: PredictionResult, count: int, seed: int | np.random.Generator | None = None
) -> np.ndarray:
    """``count`` posterior draws of a profile (rows of kc, kphi, n, cc, phic_deg; SI).

    Drawn without replacement from the draws stored by ``predict
    --uncertainty --json`` (its key ``samples``), read back by
    :func:`~terracone.result.read_results`.  Raises ValueError when the
    result holds no draws (Parquet and batch directories keep only the 90%
    intervals) or fewer than ``count``.
    """
    post = result.posterior
    samples = None if post is None else post.samples
    if samples is None:
        raise ValueError(
            f"profile {result.id!r} has no posterior draws: --samples needs the JSON of "
            "`terracone predict --uncertainty --json` (a batch directory, a Parquet file and "
            "predict without --uncertainty hold no draws)"
        )
    stored = samples.shape[0]
    if not 1 <= count <= stored:
        raise ValueError(f"--samples must be between 1 and {stored} (the stored draws)")
    rng = np.random.default_rng(seed)
    return samples[np.sort(rng.choice(stored, size=count, replace=False))]


def geojson(
    results: Iterable[PredictionResult], units: str = "si"
) -> tuple[dict[str, Any], list[str]]:
    """A GeoJSON FeatureCollection of the located profiles, and the ids without coordinates.

    One Point Feature per profile with a :func:`location`, coordinates
    [lon, lat] (RFC 7946), properties ``id``, ``status``, ``kc``, ``kphi``,
    ``n``, ``cc``, ``phic_deg`` (in ``units``), ``r2_ci``, ``lack_of_fit``,
    ``units``, ``error`` and, when the run had them, ``intervals`` (posterior,
    in ``units``) and ``layered`` (the layered fit as the file stores it,
    without its curves).
    """
    units = u.check_system(units)
    features, unlocated = [], []
    for r in results:
        where = location(r)
        if where is None:
            unlocated.append(r.id)
            continue
        p = r.params.as_dict(units) if r.params is not None else {}
        props: dict[str, Any] = {"id": r.id, "status": r.status}
        props.update({k: p.get(k) for k in UQ_PARAMS})
        props["r2_ci"] = r.r2_ci if r.ok and math.isfinite(r.r2_ci) else None
        props.update(lack_of_fit=r.lack_of_fit, units=units, error=r.error)
        if r.posterior is not None:
            props["intervals"] = r.posterior.as_dict(units)["intervals"]
        layered = r.extra.get("layered")
        if isinstance(layered, Mapping):
            drop = ("depth", "ci", "ci_model", "metadata")
            props["layered"] = {k: v for k, v in layered.items() if k not in drop}
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [where[1], where[0]]},
                "properties": props,
            }
        )
    return {"type": "FeatureCollection", "features": features}, unlocated


def write_geojson(
    results: Iterable[PredictionResult], out: str | os.PathLike, units: str = "si"
) -> list[str]:
    """Write :func:`geojson` of ``results`` to ``out``; returns the ids without coordinates."""
    from terracone.io import json_default

    doc, unlocated = geojson(results, units)
    Path(out).write_text(json.dumps(doc, indent=1, default=json_default) + "\n")
    return unlocated


# ---------------------------------------------------------------------------
# soil for Chrono: the cone's Bekker values with the terrain's shear values
# ---------------------------------------------------------------------------


def shear_of(text: str, library: str | os.PathLike | None = None) -> tuple[dict[str, float], str]:
    """The terrain's shear values named by ``--shear``, and where they come from.

    Parameters
    ----------
    text : str
        A JSON file written by ``terracone fit-shear --json`` (``c``,
        ``phi_deg``, ``K``, ``units``), or else the name of a library terrain.
    library : path, optional
        The terrain library (default: :func:`~terracone.apps.library.default_library_path`).

    Returns
    -------
    dict
        c_kpa [kPa], phi_deg [deg], K_m [m]: those the source has (a fit on
        one normal pressure has no c and phi).
    str
        The source, e.g. ``shear fit fit.json`` or ``library terrain 'LETE sand'``.

    Raises
    ------
    ValueError
        Neither a readable fit-shear file nor a library terrain.
    """
    path = Path(text)
    if path.is_file():
        try:
            doc = read_json(path)
        except FileKeyError as exc:
            raise ValueError(f"--shear {text}: {exc.reason}") from None
        if not isinstance(doc, Mapping) or "K" not in doc or "phi_deg" not in doc:
            raise ValueError(
                f"--shear {text}: not the output of `terracone fit-shear --json` "
                "(keys c, phi_deg, K, units)"
            )
        shear = TerrainShear.from_dict(dict(doc))
        values = {"c_kpa": shear.c, "phi_deg": shear.phi_deg, "K_m": shear.K}
        return {k: float(v) for k, v in values.items() if v is not None}, f"shear fit {text}"
    with Library(library) as lib:
        if text not in lib:
            raise ValueError(f"--shear {text}: no such file, and no terrain {text!r} in {lib.path}")
        rec = lib.get(text)
    values = {k: float(rec.params[k]) for k in SHEAR_KEYS if k in rec.params}
    return values, f"library terrain {text!r}"


def merge_shear(
    layers: Iterable[tuple[str, Mapping[str, Any]]],
) -> tuple[dict[str, float], dict[str, str]]:
    """Shear values from several sources, later ones overriding earlier ones.

    ``layers`` are (source, values) pairs with keys of
    :data:`~terracone.apps.chrono.SHEAR_KEYS` (None values skipped).
    Returns the values and, per key, its source.
    """
    values: dict[str, float] = {}
    sources: dict[str, str] = {}
    for source, layer in layers:
        for k in SHEAR_KEYS:
            if layer.get(k) is not None:
                values[k] = float(layer[k])
                sources[k] = source
    return values, sources


def terrain_soil(record: TerrainRecord, shear: Mapping[str, float]) -> LocatedSoil:
    """A library terrain as a :class:`~terracone.apps.chrono.LocatedSoil` (shear values override)."""
    return LocatedSoil(record.name, {**check_params(record.params), **shear})


def _soil(r: PredictionResult, shear: Mapping[str, float], draws: np.ndarray | None) -> LocatedSoil:
    where = location(r) or (None, None)
    rows = () if draws is None else tuple({**dict(zip(UQ_PARAMS, d)), **shear} for d in draws)
    return LocatedSoil(r.id, {**record_params(r.params), **shear}, where[0], where[1], rows)


def map_soils(directory: str | os.PathLike[str], shear: Mapping[str, float]) -> list[LocatedSoil]:
    """The cells of a terrain map (``terracone map``) as located soils for Chrono.

    Parameters
    ----------
    directory : str or path-like
        The output directory of ``terracone map``
        (:func:`terracone.apps.maps.read_map_cells`).
    shear : mapping
        c_kpa [kPa], phi_deg [deg], K_m [m]: the terrain's shear values, the
        same in every cell (a map holds the cone's parameters only).

    Returns
    -------
    list of LocatedSoil
        One soil per cell with kc, kphi and n, named ``cell-<i>``, at the
        cell centre.
    """
    from terracone.apps.maps import read_map_cells

    return [
        LocatedSoil(f"cell-{i}", {**record_params(c.params), **shear}, c.lat, c.lon)
        for i, c in enumerate(read_map_cells(directory))
    ]


def result_soils(
    results: PredictionResults,
    shear: Mapping[str, float],
    *,
    profile: str | None = None,
    several: bool = False,
    source: str = "results",
    samples: int | None = None,
    seed: int | None = None,
) -> tuple[list[LocatedSoil], list[str]]:
    """The profiles of results as soils for Chrono, and those left out (with why).

    One profile (``profile``, or the only fitted one), or with ``several``
    every fitted and located profile (unless only one is fitted).  With
    ``samples``, each soil carries that many posterior draws
    (:func:`draw_samples`).  Left out: profiles not fitted and, with
    ``several``, those without lat/lon, as ``"id (why)"``.  Raises
    ValueError when no profile can be exported.
    """
    ok = [r for r in results if r.ok and r.params is not None]
    left: list[str] = []
    if profile is not None or not several:
        picked = [pick_profile(results, profile, source)]
    else:
        fitted = {id(r) for r in ok}
        left = [
            f"{r.id} (not fitted: {r.error or r.status})" for r in results if id(r) not in fitted
        ]
        if len(ok) <= 1:
            picked = [pick_profile(results, None, source)]
        else:
            picked = [r for r in ok if location(r) is not None]
            left += [f"{r.id} (no lat/lon)" for r in ok if location(r) is None]
        if not picked:
            raise ValueError(
                f"{source}: {len(ok)} fitted profiles, none located (no lat/lon in their "
                "metadata): choose one with --profile ID"
            )
    rng = np.random.default_rng(seed)
    soils = [
        _soil(r, shear, None if samples is None else draw_samples(r, samples, rng)) for r in picked
    ]
    return soils, left


# ---------------------------------------------------------------------------
# the effective one-layer soil of a layered fit, for a vehicle
# ---------------------------------------------------------------------------

LAYERED_HOW = "run `terracone predict FILE --layers 2 --json` and export its JSON"


@dataclass(frozen=True)
class RunningGear:
    """What presses on the ground (SI): one wheel, or one track.

    Attributes
    ----------
    kind : {"wheel", "track"}
    width : float
        Wheel or track width b [m].
    load : float
        Load on the wheel, or on one track (gross weight / tracks) [N].
    diameter : float or None
        Wheel diameter D [m].
    contact_length : float or None
        Track contact length L [m].
    vehicle : str
        The vehicle's name.
    """

    kind: str
    width: float
    load: float
    diameter: float | None = None
    contact_length: float | None = None
    vehicle: str = ""

    def describe(self) -> str:
        """One line: which running gear, its width and load."""
        if self.kind == "wheel":
            return (f"{self.vehicle}'s wheel: width {self.width:g} m, diameter "
                    f"{self.diameter:g} m, load {self.load:g} N")  # fmt: skip
        return (f"{self.vehicle}'s track: width {self.width:g} m, contact length "
                f"{self.contact_length:g} m, load {self.load:g} N on one track")  # fmt: skip


def running_gear(path: str | os.PathLike) -> RunningGear:
    """The running gear of a vehicle file (:func:`terracone.apps.vehicles.load_vehicle`).

    A wheeled vehicle: its ``wheel`` (load, diameter, width).  A tracked
    vehicle: one track, its ``mobility_index_inputs`` track_width and
    track_contact_length, loaded with gross_weight / tracks (a track presses
    with the uniform pressure load / (width x contact length), Bekker's track);
    a ``wheel`` block of a tracked vehicle is not used.

    Raises
    ------
    ValueError
        A bad vehicle file, or one without the width and load needed (the
        message names the keys).
    """
    from terracone.apps.vehicles import load_vehicle, vehicle_from_dict

    vehicle = load_vehicle(path)
    where = f"vehicle file {path}"
    if vehicle.kind == "wheeled":
        w = vehicle.wheel  # required of a wheeled vehicle by load_vehicle
        return RunningGear("wheel", w.width, w.load, diameter=w.diameter, vehicle=vehicle.name)
    raw = read_json(path)  # readable: load_vehicle read it
    inputs = raw.get("mobility_index_inputs")
    if not isinstance(inputs, Mapping):
        raise ValueError(
            f"{where}: a tracked vehicle's effective soil needs its track: give "
            "'mobility_index_inputs' with gross_weight, track_width, track_contact_length and "
            "tracks (the file gives only 'mobility_index')"
        )
    # the inputs checked even where the file also gives the mobility index
    vehicle_from_dict({k: v for k, v in raw.items() if k != "mobility_index"}, str(path))
    width = u.quantity_to_si(inputs["track_width"], "length")
    length = u.quantity_to_si(inputs["track_contact_length"], "length")
    load = u.quantity_to_si(inputs["gross_weight"], "force") / int(inputs["tracks"])
    return RunningGear("track", width, load, contact_length=length, vehicle=vehicle.name)


def layered_ground(result: PredictionResult, settings: Mapping[str, Any] | None = None):
    """(layers, interfaces [m], pressure law) of a profile's layered fit, SI.

    From the ``layered`` block of ``predict --layers N --json``, read back by
    :func:`~terracone.result.read_results` into ``result.extra``.  The law is
    each layer's model and r_min, with the run's plate pair (``settings``).

    Raises
    ------
    ValueError
        No layered fit, a failed one, or one read from a Parquet table (which
        keeps each layer's n only); the message says what to run.
    """
    from terracone.physics.plate import pressure_law

    block = result.extra.get("layered")
    if not isinstance(block, Mapping):
        if result.layered is not None and result.layered.ok:
            raise ValueError(
                f"profile {result.id!r}: a Parquet table or batch directory keeps only each "
                f"layer's n, not its kc and kphi: {LAYERED_HOW}"
            )
        raise ValueError(f"profile {result.id!r} has no layered fit: {LAYERED_HOW}")
    if block.get("status") != "ok":
        raise ValueError(
            f"profile {result.id!r}: its layered fit failed ({block.get('error')}): no layered "
            "ground to make an effective soil of"
        )
    units = block.get("units") or "si"
    layers = [TerrainParameters.from_dict(dict(p), units) for p in block["layers"]]
    interfaces = [float(v) for v in u.length_to_si(block["interfaces"], units)]
    settings = settings or {}
    cal = settings.get("calibration")
    pair = settings.get("plate_pair") or (
        cal.get("plate_pair") if isinstance(cal, Mapping) else None
    )
    top = layers[0]
    law = pressure_law(top.model, r_min=top.r_min, plate_pair=tuple(pair) if pair else None)
    return layers, interfaces, law


def _effective_block(result: PredictionResult, gear: RunningGear, settings) -> dict[str, Any]:
    """The effective soil of one profile for ``gear``: SI params and the ``effective`` block."""
    from terracone.physics.effective import effective_soil
    from terracone.physics.layers import layered_plate

    layers, interfaces, law = layered_ground(result, settings)
    plate = layered_plate(layers, interfaces, width=gear.width, law=law)
    try:
        eff = effective_soil(plate, load=gear.load, diameter=gear.diameter,
                             contact_length=gear.contact_length)  # fmt: skip
    except ValueError as exc:
        raise ValueError(f"profile {result.id!r}: {exc}") from None
    block = eff.as_dict()
    block.update(
        vehicle=gear.vehicle,
        fitted_to={"layers": [{k: getattr(p, k) for k in ("kc", "kphi", "n")} for p in layers],
                   "interfaces_m": interfaces, "model": law.model},
        split="kc = 0, kphi = k at the vehicle's width (Chrono's SCM takes its own width)",
    )  # fmt: skip
    layered = result.extra["layered"]
    block["preferred_layers"] = layered.get("preferred_layers")
    block["warnings"] = _warnings(eff, gear, layered)
    return block


def _warnings(eff: Any, gear: RunningGear, layered: Mapping[str, Any]) -> list[str]:
    """What the user should know of an effective soil: its sinkage against its ranges."""
    said = []
    if gear.kind == "wheel" and eff.sinkage > gear.diameter / 6:
        said.append(f"sinkage {eff.sinkage:.3g} m beyond D/6 = {gear.diameter / 6:.3g} m, the "
                    "range in which Bekker's wheel analysis is held acceptable (Wong 2008)")  # fmt: skip
    depth = layered.get("depth")
    if depth:
        deepest = float(u.length_to_si(max(depth), layered.get("units") or "si"))
        if eff.sinkage > deepest:
            said.append(f"sinkage {eff.sinkage:.3g} m below the deepest reading {deepest:.3g} m: "
                        "the bottom layer is extrapolated")  # fmt: skip
    if eff.at_bound:
        said.append(f"n = {eff.n:g} at an end of its range: the layered curve is steeper or "
                    "flatter than any power law allowed")  # fmt: skip
    return said


def effective_soils(
    results: PredictionResults,
    soils: Sequence[LocatedSoil],
    gear: RunningGear,
    source: str = "results",
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> tuple[list[LocatedSoil], list[str]]:
    """The soils with each profile's layered fit replaced by its effective soil for ``gear``.

    kc = 0, kphi = k, n = m of :func:`terracone.physics.effective.effective_soil`
    (the shear values kept), and the soil's ``effective`` block.  One soil:
    a profile without an effective soil raises.  Several: it is left out,
    ``"id (why)"``, and the others go on; none left raises.  ``progress``
    wraps the loop over the soils (a tqdm bar, say).
    """
    by_id = {r.id: r for r in results}
    out, left = [], []
    for s in (progress or iter)(soils):
        try:
            block = _effective_block(by_id[s.id], gear, results.settings)
        except ValueError as exc:
            if len(soils) == 1:
                raise
            left.append(f"{s.id} ({exc})")
            continue
        params = {**s.params, "kc": 0.0, "kphi": block["kphi"], "n": block["n"]}
        out.append(replace(s, params=params, effective=block))
    if not out:
        raise ValueError(f"{source}: no profile has an effective soil for {gear.describe()}: "
                         f"{'; '.join(left[:3])}")  # fmt: skip
    return out, left

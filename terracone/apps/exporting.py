"""What ``terracone export`` computes and writes, one call per kind of output.

:func:`export_plain` writes a library terrain or a fitted profile as plain
Bekker-Wong parameters (JSON, CSV); :func:`export_geojson` the located
profiles of a results file as GeoJSON points; :func:`export_mavs` a profile's
or a site's MAVS surface entry; :func:`export_chrono` the soils Project
Chrono's SCM reads (a co-simulation spec, an ensemble of specs, or a PyChrono
module): the cone's kc, kphi and n of a library terrain, of fitted profiles
(with posterior draws) or of a terrain map's cells, joined with the terrain's
shear values, or a layered fit's effective soil for a vehicle.  Each takes
parsed values (SI, paths) and returns what it wrote and what is to be said of
it; the building blocks are in :mod:`terracone.apps.export`,
:mod:`terracone.apps.chrono` and :mod:`terracone.apps.mavs`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from terracone.apps.chrono import (
    SPEC_SOIL_KEYS,
    LocatedSoil,
    SCMSettings,
    scm_settings,
    write_pychrono,
    write_scm_spec,
    write_scm_specs,
)
from terracone.apps.export import (
    effective_soils,
    export_terrain,
    map_soils,
    merge_shear,
    pick_profile,
    result_soils,
    running_gear,
    shear_of,
    terrain_soil,
    write_geojson,
)
from terracone.apps.library import Library
from terracone.apps.mavs import write_mavs
from terracone.result import PredictionResults, read_results

__all__ = [
    "ChronoExport",
    "GeoJSONExport",
    "MavsExport",
    "OptionError",
    "PlainExport",
    "export_chrono",
    "export_geojson",
    "export_mavs",
    "export_plain",
]

PathLike = str | os.PathLike[str]
#: Effective soils of at least this many profiles show a progress bar on a terminal.
PROGRESS_FROM = 200


class OptionError(ValueError):
    """An option that does not apply to what the inputs hold (``--origin`` with one soil).

    The command line reports it as a usage error.
    """


def _results(results: PredictionResults | PathLike) -> tuple[PredictionResults, str]:
    """The results (read when a path) and their name for messages."""
    if isinstance(results, PredictionResults):
        return results, "results"
    return read_results(results), str(results)


@dataclass(frozen=True)
class PlainExport:
    """What :func:`export_plain` wrote: the terrain's ``name``, the file ``out``, and the
    Bekker-Wong fields the terrain lacks (``missing``, left out of the file)."""

    name: str
    out: str
    missing: list[str]


def export_plain(
    out: PathLike,
    fmt: str,
    *,
    terrain: str | None = None,
    results: PredictionResults | PathLike | None = None,
    profile: str | None = None,
    units: str = "si",
    library: PathLike | None = None,
) -> PlainExport:
    """Write a library terrain, or one fitted profile, as plain parameters (``json``, ``csv``).

    Parameters
    ----------
    out : path
        The file written.
    fmt : {"json", "csv"}
    terrain : str, optional
        A terrain of the library (give it or ``results``).
    results : PredictionResults or path, optional
        A predict JSON or Parquet file, a batch directory, or results read.
    profile : str, optional
        The profile of ``results`` (default: the only fitted one).
    units : {"si", "us"}
        Units of the values written.
    library : path, optional
        The terrain library (default: ``$TERRACONE_LIBRARY`` or the user data dir).

    Returns
    -------
    PlainExport
    """
    if terrain is not None:
        with Library(library) as lib:
            name, params = terrain, lib.get(terrain)
    else:
        res, source = _results(results)
        picked = pick_profile(res, profile, source)
        name, params = picked.id, picked.params
    missing = export_terrain(params, fmt, out, units=units, name=name)
    return PlainExport(name, str(out), missing)


@dataclass(frozen=True)
class GeoJSONExport:
    """What :func:`export_geojson` wrote: ``out``, the ``units`` of its values, the number
    of profiles read (``count``) and the ids of those without coordinates (``unlocated``)."""

    out: str
    units: str
    count: int
    unlocated: list[str]

    @property
    def located(self) -> int:
        """Profiles written (located)."""
        return self.count - len(self.unlocated)


def export_geojson(
    results: PredictionResults | PathLike, out: PathLike, units: str | None = None
) -> GeoJSONExport:
    """Write the located profiles of results as GeoJSON points
    (:func:`terracone.apps.export.geojson`).

    ``units``: of the values written; default the run's (its settings), else SI.
    """
    res, _ = _results(results)
    units = units or res.settings.get("units") or "si"
    unlocated = write_geojson(res, out, units)
    return GeoJSONExport(str(out), units, len(res), unlocated)


@dataclass(frozen=True)
class MavsExport:
    """What :func:`export_mavs` wrote: the scene fragment (``document``), the file ``out``
    and the notes for the user."""

    document: dict[str, Any]
    out: str
    notes: list[str]

    def as_dict(self) -> dict[str, Any]:
        """The ``terracone export --format mavs --json`` document: the fragment written, the
        values of MAVS's two SetTerrainProperties calls, and the file."""
        stp = self.document["terracone"]["set_terrain_properties"]
        return {**self.document, "set_terrain_properties": stp, "out": self.out}


def export_mavs(
    results: PredictionResults | PathLike,
    out: PathLike,
    *,
    material: str,
    profile: str | None = None,
) -> MavsExport:
    """Write the MAVS surface entry of a profile or a site (:func:`terracone.apps.mavs.write_mavs`).

    Parameters
    ----------
    results : PredictionResults or path
    out : path
    material : {"sand", "clay"}
        MAVS's soil type of the surface.
    profile : str, optional
        A profile id, or a value of the profiles' ``site`` metadata.

    Returns
    -------
    MavsExport
    """
    res, source = _results(results)
    doc, notes = write_mavs(res, out, material=material, profile=profile, source=source)
    return MavsExport(doc, str(out), notes)


@dataclass
class ChronoExport:
    """What :func:`export_chrono` wrote, and what is to be said of it.

    Attributes
    ----------
    soils : list of LocatedSoil
        The soils written (SI).
    notes : list of str
        Where each value comes from (also written into the file).
    left : list of str
        Profiles left out, as ``"id (why)"``.
    settings : SCMSettings
        SCM's values beyond the soil's, and which are defaults.
    written : str
        What was written, in words (e.g. ``the Chrono SCM spec of 'P1'``).
    spec : bool
        A co-simulation spec (True) or a PyChrono module (False).
    """

    soils: list[LocatedSoil]
    notes: list[str]
    left: list[str] = field(default_factory=list)
    settings: SCMSettings = field(default_factory=SCMSettings)
    written: str = ""
    spec: bool = True

    @property
    def defaults_text(self) -> str:
        """Which SCM values are defaults rather than data, as a sentence (empty if none)."""
        return self.settings.defaults_text(spec=self.spec)


@dataclass(frozen=True)
class _Source:
    """Where the soils come from: one of terrain, results and map_dir."""

    terrain: str | None
    results: PredictionResults | PathLike | None
    map_dir: PathLike | None
    library: PathLike | None

    @property
    def name(self) -> str:
        """The input's name (a PyChrono module's SOURCE)."""
        if isinstance(self.results, PredictionResults):
            return "results"
        return str(self.terrain or self.results or self.map_dir)


def _shear(
    shear: str | None,
    given: Iterable[tuple[str, Mapping[str, float]]],
    library: PathLike | None,
    base: tuple[str, Mapping[str, Any]] | None,
) -> tuple[dict[str, float], dict[str, str]]:
    """(values, sources) of the terrain's shear values: terrain, then ``shear``, then ``given``."""
    layers: list[tuple[str, Mapping[str, Any]]] = [base] if base else []
    if shear is not None:
        values, source = shear_of(shear, library)
        layers.append((source, values))
    layers += list(given)
    return merge_shear(layers)


def _soils(
    src: _Source, shear_sources: tuple[str | None, Sequence[tuple[str, Mapping[str, float]]]],
    *, profile: str | None, several: bool, samples: int | None, seed: int | None,
) -> tuple[list[LocatedSoil], list[str], list[str], tuple[PredictionResults, str] | None]:  # fmt: skip
    """The soils to write, where their values come from, the profiles left out, and the
    results read with their name (None for a terrain or a map)."""
    bekker = ", ".join(SPEC_SOIL_KEYS[:3])
    source = src.name if src.map_dir is None else f"map {src.map_dir}"
    origin = f"library terrain {src.terrain!r}" if src.terrain else f"the cone ({source})"
    notes, base, record = [f"{bekker} from {origin}"], None, None
    if src.terrain is not None:
        with Library(src.library) as lib:
            record = lib.get(src.terrain)
        base = (f"library terrain {src.terrain!r}", record.params)
    shear, sources = _shear(*shear_sources, src.library, base)
    keys = dict(zip(("c_kpa", "phi_deg", "K_m"), SPEC_SOIL_KEYS[3:6]))
    by_source: dict[str, list[str]] = {}
    for k, s in sources.items():
        by_source.setdefault(s, []).append(keys[k])
    notes += [f"{', '.join(ks)} from {s}" for s, ks in by_source.items()]
    if record is not None or src.map_dir is not None:
        if samples is not None:
            raise OptionError("--samples needs --results with posterior draws")
        if record is not None:
            return [terrain_soil(record, shear)], notes, [], None
        return map_soils(src.map_dir, shear), notes, [], None
    res, name = _results(src.results)
    soils, left = result_soils(
        res, shear, profile=profile, several=several, source=name, samples=samples, seed=seed
    )
    return soils, notes, left, (res, name)


def _progress(count: int) -> Callable[[Iterable[Any]], Iterable[Any]] | None:
    """tqdm over the profiles when there are many and stderr is a terminal."""
    if count < PROGRESS_FROM or not sys.stderr.isatty():
        return None
    from tqdm.auto import tqdm

    def bar(it):
        return tqdm(it, total=count, desc="terracone export: effective soils", unit="profile",
                    file=sys.stderr)  # fmt: skip

    return bar


def _effective(results, source, soils, notes, vehicle, progress):
    """The soils replaced by their effective soils for the vehicle, what is said of them, and
    the profiles left out."""
    gear = running_gear(vehicle)
    bar = _progress(len(soils)) if progress is None else progress
    soils, more = effective_soils(results, soils, gear, source, bar)
    rms = [s.effective["error"]["pressure_rms"] for s in soils]
    worst = max((v for v in rms if v is not None), default=float("nan"))
    notes = [
        notes[0].replace(
            "from the cone",
            f"of the effective soil (kc = 0, kphi = k at the width) for {gear.describe()}, "
            f"fitted to the layered fit of the cone",
        ),
        *notes[1:],
        f"effective soil: sinkage as the layered ground's; pressure error (relative RMS over the "
        f"sinkage) at most {worst:.3g}; per profile in the notes' 'effective'",
    ]
    return soils, notes, more


def _write(
    soils: list[LocatedSoil], fmt: str, out: PathLike, settings: SCMSettings, how: dict[str, Any]
) -> str:
    """Write the Chrono output; returns what was written, in words."""
    if fmt == "pychrono":
        write_pychrono(out, soils, settings, origin=how["origin"], source=how["source"],
                       notes=how["notes"])  # fmt: skip
        what = f"{len(soils)} located soils" if len(soils) > 1 else f"the soil of {soils[0].id!r}"
        if how["samples"]:
            what += f" with {how['samples']} posterior draws"
        return what
    if how["samples"] is not None:
        write_scm_specs(out, soils[0], settings, force=how["force"])
        return f"{how['samples']} Chrono SCM specs and draws.csv of {soils[0].id!r}"
    effective = soils[0].effective
    spec_notes = (
        None
        if effective is None
        else {
            "profile": soils[0].id,
            "source": how["source"],
            "notes": list(how["notes"]),
            "effective": dict(effective),
        }  # fmt: skip
    )
    write_scm_spec(out, soils[0].params, settings, repr(soils[0].id), spec_notes)
    return f"the Chrono SCM spec of {soils[0].id!r}"


def export_chrono(
    out: PathLike,
    fmt: str = "chrono-scm",
    *,
    terrain: str | None = None,
    results: PredictionResults | PathLike | None = None,
    map_dir: PathLike | None = None,
    profile: str | None = None,
    library: PathLike | None = None,
    shear: str | None = None,
    shear_given: Sequence[tuple[str, Mapping[str, float]]] = (),
    elastic_k: float | None = None,
    damping_r: float | None = None,
    patch: tuple[float, float] | None = None,
    grid_spacing: float | None = None,
    vehicle: PathLike | None = None,
    samples: int | None = None,
    seed: int | None = None,
    origin: tuple[float, float] | None = None,
    force: bool = False,
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> ChronoExport:
    """Write the soils of a terrain, of results or of a map's cells for Chrono's SCM.

    Parameters
    ----------
    out : path
        The spec or module written; with ``samples`` and ``"chrono-scm"``, a
        directory of specs and ``draws.csv``
        (:func:`~terracone.apps.chrono.write_scm_specs`).
    fmt : {"chrono-scm", "pychrono"}
        A co-simulation spec (one soil) or a PyChrono module (every located
        profile, or every cell of a map).
    terrain, results, map_dir
        Exactly one: a library terrain, results (predict JSON or Parquet, a
        batch directory, or read), a terrain map directory.
    profile : str, optional
        The profile of ``results``.
    library : path, optional
        The terrain library of ``terrain`` and of ``shear`` naming a terrain.
    shear : str, optional
        A ``fit-shear --json`` file or a library terrain: the terrain's
        cohesion, friction and Janosi K (:func:`~terracone.apps.export.shear_of`).
    shear_given : sequence of (str, mapping)
        Explicit shear values, each with its source, e.g.
        ``("--cohesion", {"c_kpa": 1.3})`` (c_kpa [kPa], phi_deg [deg], K_m
        [m]); they override ``shear`` and the terrain's, later over earlier.
    elastic_k, damping_r, patch, grid_spacing : optional
        SCM's values [Pa/m], [Pa s/m], (length, width) [m], [m]
        (:func:`~terracone.apps.chrono.scm_settings`; defaults said).
    vehicle : path, optional
        A vehicle file: each profile's layered fit is replaced by its
        effective soil for the vehicle's wheel or track.
    samples, seed : int, optional
        Posterior draws per soil, and the seed of their choice.
    origin : (float, float), optional
        The PyChrono module's frame origin (lat, lon) [deg]; several soils only.
    force : bool
        Replace a ``samples`` directory that holds other files.
    progress : callable, optional
        Wraps the loop over the effective soils (default: a tqdm bar on a
        terminal from 200 profiles).

    Returns
    -------
    ChronoExport

    Raises
    ------
    OptionError
        ``origin`` with fewer than two soils, or not with ``"pychrono"``.
    ValueError
        What cannot be exported (the message says what was found).
    """
    settings = scm_settings(elastic_k=elastic_k, damping_r=damping_r, patch=patch,
                            grid_spacing=grid_spacing)  # fmt: skip
    src = _Source(terrain, results, map_dir, library)
    soils, notes, left, read = _soils(src, (shear, shear_given), profile=profile,
                                     several=fmt == "pychrono", samples=samples, seed=seed)  # fmt: skip
    if vehicle is not None:
        if read is None:
            raise OptionError("a vehicle's effective soil is made of a profile's layered fit: "
                              "give results (the JSON of predict --layers 2 --json)")  # fmt: skip
        soils, notes, more = _effective(*read, soils, notes, vehicle, progress)
        left = left + more
    if origin is not None and (fmt != "pychrono" or len(soils) < 2):
        raise OptionError("--origin: only with --format pychrono and several located profiles")
    how = {"origin": origin, "source": src.name, "notes": notes, "samples": samples,
           "force": force}  # fmt: skip
    try:
        written = _write(soils, fmt, out, settings, how)
    except ValueError as exc:
        found = f" (found: {'; '.join(notes)})" if notes else ""
        raise ValueError(f"{exc}{found}") from None
    return ChronoExport(soils, notes, left, settings, written, spec=fmt == "chrono-scm")

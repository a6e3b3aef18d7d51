"""Export terrains: Project Chrono SCM soil JSON and plain Bekker-Wong tables.

Chrono SCM (Soil Contact Model) [1]_ computes the normal pressure with
Bekker's equation ``p = (Kc/b + Kphi) z^n`` [2]_ in base SI units (Pa, m) and
the shear with Mohr-Coulomb and Janosi-Hanamoto [3]_.  The conversion from
terracone's SI (kPa, m) is a factor 1000 on the moduli:

=====================  ===============  =========================================
Chrono key             unit             from
=====================  ===============  =========================================
Bekker Kphi            Pa/m^n           kphi [kN/m^(n+2)] * 1000
Bekker Kc              Pa/m^(n-1)       kc [kN/m^(n+1)] * 1000
Bekker n               -                n
Mohr Cohesion          Pa               c_kpa [kPa] * 1000 (terrain internal c)
Mohr Friction          deg              phi_deg (terrain internal phi)
Janosi Shear           m                K_m (terrain shear deformation modulus)
Elastic K              Pa/m             ``elastic_k=``; :func:`chrono_scm`: 4e8 default
Dampening R            Pa s/m           ``damping_r=``; :func:`chrono_scm`: 3e4 default
=====================  ===============  =========================================

(kN/m^(n+2) times m^n is kN/m^2 = kPa; times 1000 gives Pa.)  Values the
terrain lacks are left out of the file and returned in ``missing``.
:func:`chrono_scm` writes all eight keys of Chrono's own soil files: the SCM
Elastic K and Dampening R from documented defaults (flagged, not from data)
unless given, and Mohr / Janosi values given explicitly for terrains that lack
them.  :func:`load_results` reads ``predict --json`` files and batch
directories, :func:`geojson` places their located profiles on a map.  The
cone (metal)-terrain adhesion and friction cc, phic of [2]_ are *not* the
terrain's internal cohesion and friction and are never written as Mohr
parameters.

Plain export (:func:`to_plain`, :func:`write_plain_csv`): kc, kphi, n, c,
phi_deg, K, cc, phic_deg, Kc, model, r_min, moisture_pct in SI
(kN/m^(n+1), kN/m^(n+2), kPa, m) or US customary (lb/in^(n+1),
lb/in^(n+2), psi, in), via :mod:`terracone.physics.units`.

References
----------
.. [1] Project Chrono, Chrono::Vehicle SCM deformable terrain
   (``SCMTerrain``); soil parameters Bekker Kphi, Kc, n, Mohr cohesion and
   friction, Janosi shear, elastic stiffness, damping.
.. [2] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eqs. (2-2) and (2-4).
.. [3] Janosi, Z., Hanamoto, B. (1961). The analytical determination of
   drawbar pull as a function of slip for tracked vehicles in deformable
   soils. Proc. 1st Int. Conf. on Terrain-Vehicle Systems, Turin.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from terracone.apps.library import TerrainRecord, check_params, record_params
from terracone.data import TerrainParameters, TerrainShear
from terracone.physics import units as u

__all__ = [
    "CHRONO_KEYS",
    "DEFAULT_DAMPING_R",
    "DEFAULT_ELASTIC_K",
    "ChronoSCM",
    "chrono_scm",
    "FORMATS",
    "PLAIN_FIELDS",
    "export_terrain",
    "plain_units",
    "to_chrono_scm",
    "to_plain",
    "write_chrono_scm",
    "write_geojson",
    "write_plain_csv",
    "write_scm_samples",
]

#: Keys of "Soil Parameters" in a Chrono SCM soil file, in file order.
CHRONO_KEYS = (
    "Bekker Kphi",
    "Bekker Kc",
    "Bekker n",
    "Mohr Cohesion",
    "Mohr Friction",
    "Janosi Shear",
    "Elastic K",
    "Dampening R",
)

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

#: Formats of :func:`export_terrain` (the CLI's ``--format``).
FORMATS = ("chrono-scm", "json", "csv")


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


def to_chrono_scm(
    record_or_params: TerrainRecord | TerrainParameters | Mapping[str, Any],
    name: str | None = None,
    *,
    elastic_k: float | None = None,
    damping_r: float | None = None,
) -> tuple[dict[str, Any], list[str]]:
    """Chrono SCM soil parameters of a terrain.

    Parameters
    ----------
    record_or_params : TerrainRecord, TerrainParameters or dict
        The terrain, SI (library keys for a dict: kc [kN/m^(n+1)],
        kphi [kN/m^(n+2)], n, c_kpa [kPa], phi_deg [deg], K_m [m]).
    name : str, optional
        "Name" of the file; defaults to the record's name.
    elastic_k : float, optional
        SCM elastic stiffness [Pa/m] (not a Bekker-Wong parameter).
    damping_r : float, optional
        SCM damping [Pa s/m].

    Returns
    -------
    dict
        ``{"Name", "Type": "Terrain Properties", "Template": "SCM Soil
        Parameters", "Soil Parameters": {...}}`` in Pa, m, deg.
    missing : list of str
        Chrono keys left out because the terrain lacks them.

    Notes
    -----
    Mohr Cohesion and Mohr Friction come only from the terrain's internal
    c_kpa and phi_deg, never from the cone-metal cc and phic_deg.

    References
    ----------
    .. [1] Project Chrono, Chrono::Vehicle SCM deformable terrain.
    """
    p = _params_of(record_or_params)
    soil: dict[str, float] = {}
    if "kphi" in p:
        soil["Bekker Kphi"] = p["kphi"] * 1000.0  # kN/m^(n+2) -> Pa/m^n
    if "kc" in p:
        soil["Bekker Kc"] = p["kc"] * 1000.0  # kN/m^(n+1) -> Pa/m^(n-1)
    if "n" in p:
        soil["Bekker n"] = p["n"]
    # internal shear of the terrain only (Mohr-Coulomb, Janosi-Hanamoto);
    # cc / phic_deg / Kc are cone-metal values and must not be used here
    if "c_kpa" in p:
        soil["Mohr Cohesion"] = p["c_kpa"] * 1000.0  # kPa -> Pa
    if "phi_deg" in p:
        soil["Mohr Friction"] = p["phi_deg"]  # deg
    if "K_m" in p:
        soil["Janosi Shear"] = p["K_m"]  # m
    if elastic_k is not None:
        soil["Elastic K"] = float(elastic_k)
    if damping_r is not None:
        soil["Dampening R"] = float(damping_r)
    ordered = {k: soil[k] for k in CHRONO_KEYS if k in soil}
    missing = [k for k in CHRONO_KEYS if k not in soil]
    doc = {
        "Name": _name_of(record_or_params, name),
        "Type": "Terrain Properties",
        "Template": "SCM Soil Parameters",
        "Soil Parameters": ordered,
    }
    return doc, missing


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

    def get(key, conv=None):
        if key not in p:
            return None
        v = p[key]
        return float(conv(v)) if conv is not None else v

    out: dict[str, Any] = {}
    if isinstance(record_or_params, TerrainRecord):
        out["name"] = record_or_params.name
    out.update(
        {
            "kc": get("kc", lambda v: u.kc_from_si(v, n, units)),
            "kphi": get("kphi", lambda v: u.kphi_from_si(v, n, units)),
            "n": get("n"),
            "c": get("c_kpa", lambda v: u.pressure_from_si(v, units)),
            "phi_deg": get("phi_deg"),
            "K": get("K_m", lambda v: u.length_from_si(v, units)),
            "cc": get("cc", lambda v: u.pressure_from_si(v, units)),
            "phic_deg": get("phic_deg"),
            "Kc": get("Kc", lambda v: u.length_from_si(v, units)),
            "model": get("model"),
            "r_min": get("r_min", lambda v: u.length_from_si(v, units)),
            "moisture_pct": get("moisture_pct"),
            "units": units,
        }
    )
    return out


def write_plain_csv(
    path: str | os.PathLike,
    terrains: Iterable[TerrainRecord | tuple[str, Any]],
    units: str = "si",
) -> None:
    """CSV of plain parameters, one row per terrain.

    ``terrains`` holds library records or ``(name, params)`` pairs.  The
    header names each column's unit, e.g. ``kc [kN/m^(n+1)]``; empty cells
    are parameters the terrain lacks.
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
        rows.append([name] + ["" if d[f] is None else d[f] for f in PLAIN_FIELDS])
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def write_chrono_scm(
    path: str | os.PathLike,
    record_or_params: TerrainRecord | TerrainParameters | Mapping[str, Any],
    name: str | None = None,
    **kw: Any,
) -> list[str]:
    """Write :func:`to_chrono_scm` to a JSON file; returns the missing keys."""
    doc, missing = to_chrono_scm(record_or_params, name, **kw)
    Path(path).write_text(json.dumps(doc, indent=4) + "\n", encoding="utf-8")
    return missing


def export_terrain(
    record_or_params: TerrainRecord | TerrainParameters | Mapping[str, Any],
    fmt: str,
    path: str | os.PathLike,
    *,
    name: str | None = None,
    units: str = "si",
) -> list[str]:
    """Write a terrain in a format of :data:`FORMATS`; returns what is missing.

    ``"chrono-scm"``: :func:`to_chrono_scm` (missing Chrono keys returned);
    ``"json"``: :func:`to_plain` as a JSON object; ``"csv"``: one-row
    :func:`write_plain_csv`.  For json/csv the returned list names the
    Bekker-Wong fields (kc, kphi, n, c, phi_deg, K) the terrain lacks.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)} (got {fmt!r})")
    if fmt == "chrono-scm":
        return write_chrono_scm(path, record_or_params, name)
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
# complete Chrono SCM soil files
# ---------------------------------------------------------------------------

#: Default SCM elastic stiffness [Pa/m]: the value of Chrono's own
#: ``data/vehicle/terrain/scm_soil_parameters/scm_hard.json`` and of the Wong
#: soils of its SCM demos.  Not a Bekker-Wong value and never from data.
DEFAULT_ELASTIC_K = 4e8
#: Default SCM vertical damping [Pa s/m]: the value of all three of Chrono's
#: own SCM soil files (soft, medium, hard).  Never from data.
DEFAULT_DAMPING_R = 3e4


@dataclass
class ChronoSCM:
    """A Chrono SCM soil-parameter file and where each value came from.

    Attributes
    ----------
    doc : dict
        ``{"Name", "Type", "Template", "Soil Parameters"}`` as in Chrono's own
        files, values in Pa, m, deg.
    missing : list of str
        Chrono keys left out (the terrain lacks them and no value was given).
    defaulted : list of str
        Keys filled with a documented default (:data:`DEFAULT_ELASTIC_K`,
        :data:`DEFAULT_DAMPING_R`): not from data.
    given : list of str
        Keys given explicitly (``elastic_k=``, ``cohesion_kpa=``, ...).
    """

    doc: dict[str, Any]
    missing: list[str] = field(default_factory=list)
    defaulted: list[str] = field(default_factory=list)
    given: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        """True when all eight keys of Chrono's soil files are present."""
        return not self.missing

    def write(self, path: str | os.PathLike) -> None:
        """Write the JSON file (4-space indent, as Chrono's own files)."""
        Path(path).write_text(json.dumps(self.doc, indent=4) + "\n", encoding="utf-8")

    def provenance_text(self) -> str:
        """One line saying which values are not from data (empty when all are)."""
        parts = []
        if self.defaulted:
            soil = self.doc["Soil Parameters"]
            vals = ", ".join(f"{k} = {soil[k]:g}" for k in self.defaulted)
            parts.append(f"{vals}: documented defaults, not from data")
        if self.given:
            parts.append(f"{', '.join(self.given)}: as given, not from the cone data")
        if self.missing:
            parts.append(
                f"{', '.join(self.missing)}: missing (give --cohesion, --friction, --janosi)"
            )
        return "; ".join(parts)


def chrono_scm(
    record_or_params: TerrainRecord | TerrainParameters | Mapping[str, Any],
    name: str | None = None,
    *,
    elastic_k: float | None = None,
    damping_r: float | None = None,
    cohesion_kpa: float | None = None,
    friction_deg: float | None = None,
    janosi_m: float | None = None,
    defaults: bool = True,
) -> ChronoSCM:
    """Chrono SCM soil parameters with all eight keys where possible.

    Parameters
    ----------
    record_or_params : TerrainRecord, TerrainParameters or dict
        The terrain, SI (as :func:`to_chrono_scm`).
    name : str, optional
        "Name" of the file; defaults to the record's name.
    elastic_k : float, optional
        SCM elastic stiffness K [Pa/m]; must exceed Bekker Kphi (Chrono's
        ``SetSoilParameters`` raises it to at least Kphi).  Default
        :data:`DEFAULT_ELASTIC_K` when ``defaults``.
    damping_r : float, optional
        SCM vertical damping R [Pa s/m] >= 0; default :data:`DEFAULT_DAMPING_R`.
    cohesion_kpa, friction_deg, janosi_m : float, optional
        Internal cohesion [kPa], friction angle [deg] and Janosi-Hanamoto
        shear deformation modulus [m] of the terrain, for terrains that lack
        them (a cone prediction has only the cone-metal cc and phic); a value
        the terrain has is overridden.
    defaults : bool
        Fill Elastic K and Dampening R with the defaults when not given.

    Returns
    -------
    ChronoSCM

    Raises
    ------
    ValueError
        Elastic K not above Bekker Kphi, a negative damping, cohesion or
        Janosi modulus, or a friction angle outside [0, 90).

    References
    ----------
    .. [1] Project Chrono, ``SCMTerrain::SetSoilParameters`` (Bekker Kphi, Kc,
       n, Mohr cohesion [Pa], friction [deg], Janosi shear [m], elastic K
       [Pa/m] "must be larger than Kphi", damping R [Pa s/m]) and the soil
       files ``data/vehicle/terrain/scm_soil_parameters/scm_*.json``.
    """
    p = dict(_params_of(record_or_params))
    given = []
    for key, value, chrono in (
        ("c_kpa", cohesion_kpa, "Mohr Cohesion"),
        ("phi_deg", friction_deg, "Mohr Friction"),
        ("K_m", janosi_m, "Janosi Shear"),
    ):
        if value is not None:
            p[key] = float(value)
            given.append(chrono)
    _check_shear(p)
    defaulted = []
    if elastic_k is None and defaults:
        elastic_k = DEFAULT_ELASTIC_K
        defaulted.append("Elastic K")
    elif elastic_k is not None:
        given.append("Elastic K")
    if damping_r is None and defaults:
        damping_r = DEFAULT_DAMPING_R
        defaulted.append("Dampening R")
    elif damping_r is not None:
        given.append("Dampening R")
    if damping_r is not None and not damping_r >= 0:
        raise ValueError(f"Dampening R must be >= 0 Pa s/m (got {damping_r:g})")
    named = name if name else _name_of(record_or_params, name)
    doc, missing = to_chrono_scm(p, named, elastic_k=elastic_k, damping_r=damping_r)
    soil = doc["Soil Parameters"]
    if (
        "Elastic K" in soil
        and "Bekker Kphi" in soil
        and not soil["Elastic K"] > soil["Bekker Kphi"]
    ):
        where = "the default " if "Elastic K" in defaulted else ""
        raise ValueError(
            f"Elastic K must exceed Bekker Kphi: {where}Elastic K = {soil['Elastic K']:g} Pa/m, "
            f"Bekker Kphi = {soil['Bekker Kphi']:g} Pa/m^n; give a larger --elastic-k (elastic_k=)"
        )
    return ChronoSCM(doc, missing, defaulted, given)


def _check_shear(p: Mapping[str, Any]) -> None:
    if "c_kpa" in p and not p["c_kpa"] >= 0:
        raise ValueError(f"cohesion must be >= 0 kPa (got {p['c_kpa']:g})")
    if "phi_deg" in p and not 0 <= p["phi_deg"] < 90:
        raise ValueError(f"friction angle must be in [0, 90) deg (got {p['phi_deg']:g})")
    if "K_m" in p and not p["K_m"] > 0:
        raise ValueError(f"Janosi shear modulus must be > 0 m (got {p['K_m']:g})")


# ---------------------------------------------------------------------------
# results of predict and batch
# ---------------------------------------------------------------------------

_LAT_KEYS = ("lat", "latitude")
_LON_KEYS = ("lon", "longitude", "long", "lng")
_PARAMS = ("kc", "kphi", "n", "cc", "phic_deg")


@dataclass
class ProfileResult:
    """One profile of a result file (``predict --json`` or a batch directory).

    Attributes
    ----------
    id, status : str
    params : dict or None
        kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n, cc [kPa], phic_deg [deg] in SI
        (None unless status is "ok").
    values : dict
        The same five, r2_ci and lack_of_fit as the file holds them (in ``units``).
    units : str
        Unit system of ``values``, ``intervals`` and ``layered``.
    lat, lon : float or None
        Decimal degrees, from the metadata (``lat``/``lon`` or
        ``latitude``/``longitude``, any case).
    intervals : dict or None
        Posterior 90% intervals {name: [lo, hi]} when the run had them.
    layered : dict or None
        The layered fit when the run had one.
    samples : ndarray or None, shape (draws, 5)
        Posterior draws of kc, kphi, n, cc, phic_deg in SI (``predict
        --uncertainty`` JSON only).
    error : str or None
    metadata : dict
    """

    id: str
    status: str
    params: dict[str, float] | None
    values: dict[str, Any]
    units: str
    lat: float | None = None
    lon: float | None = None
    intervals: dict[str, Any] | None = None
    layered: dict[str, Any] | None = None
    samples: Any = None
    error: str | None = None
    metadata: dict[str, Any] = field(default_factory=dict)


def _degrees(metadata: Mapping[str, Any], keys: tuple[str, ...]) -> float | None:
    lower = {str(k).strip().lower(): v for k, v in metadata.items()}
    for k in keys:
        v = lower.get(k)
        if v is None or (isinstance(v, str) and not v.strip()):
            continue
        try:
            x = float(v)
        except (TypeError, ValueError):
            continue
        if x == x:  # not NaN
            return x
    return None


def _si_params(v: Mapping[str, Any], units: str) -> dict[str, float] | None:
    if any(v.get(k) is None for k in _PARAMS):
        return None
    n = float(v["n"])
    return {
        "kc": float(u.kc_to_si(v["kc"], n, units)),
        "kphi": float(u.kphi_to_si(v["kphi"], n, units)),
        "n": n,
        "cc": float(u.pressure_to_si(v["cc"], units)),
        "phic_deg": float(v["phic_deg"]),
    }


def _samples_si(block: Mapping[str, Any]) -> Any:
    import numpy as np

    names = list(block.get("names", []))
    if names != list(_PARAMS):
        raise ValueError(f"samples: expected columns {list(_PARAMS)} (got {names})")
    s = np.array(block["values"], dtype=float).reshape(-1, len(_PARAMS))
    units = block.get("units", "si")
    if units != "si":
        n = s[:, 2]
        s[:, 0] = u.kc_to_si(s[:, 0], n, units)
        s[:, 1] = u.kphi_to_si(s[:, 1], n, units)
        s[:, 3] = u.pressure_to_si(s[:, 3], units)
    return s


def _from_predict(d: Mapping[str, Any], default_units: str) -> ProfileResult:
    units = d.get("units") or default_units
    meta = d.get("metadata") or {}
    values = {k: d.get(k) for k in (*_PARAMS, "r2_ci", "lack_of_fit")}
    layered = d.get("layered")
    if isinstance(layered, Mapping):
        drop = ("depth", "ci", "ci_model", "metadata")
        layered = {k: v for k, v in layered.items() if k not in drop}
    return ProfileResult(
        id=str(d.get("id")),
        status=str(d.get("status")),
        params=_si_params(values, units) if d.get("status") == "ok" else None,
        values=values,
        units=units,
        lat=_degrees(meta, _LAT_KEYS),
        lon=_degrees(meta, _LON_KEYS),
        intervals=d.get("intervals"),
        layered=layered,
        samples=_samples_si(d["samples"]) if d.get("samples") else None,
        error=d.get("error"),
        metadata=dict(meta),
    )


def _from_batch_row(row: Mapping[str, Any], known: set[str]) -> ProfileResult:
    def val(k: str) -> Any:
        v = row.get(k)
        return None if (isinstance(v, float) and v != v) else v

    units = val("units") or "si"
    values = {k: val(k) for k in (*_PARAMS, "r2_ci", "lack_of_fit")}
    meta = {k: v for k, v in row.items() if k not in known and v is not None}
    iv = {p: [val(f"{p}_q05"), val(f"{p}_q95")] for p in _PARAMS if val(f"{p}_q05") is not None}
    layered = None
    if val("bic_layered") is not None:
        keys = ("n_layers", "interfaces", "r2_layered", "bic_single", "bic_layered")
        layered = {k: val(k) for k in (*keys, "preferred_layers", "lack_of_fit_layered")}
    return ProfileResult(
        id=str(row.get("profile")),
        status=str(val("status")),
        params=_si_params(values, units) if val("status") == "ok" else None,
        values=values,
        units=units,
        lat=_degrees(meta, _LAT_KEYS),
        lon=_degrees(meta, _LON_KEYS),
        intervals=iv or None,
        layered=layered,
        error=val("error"),
        metadata=meta,
    )


def load_results(path: str | os.PathLike) -> list[ProfileResult]:
    """The profiles of a ``predict --json`` file or a ``terracone batch`` directory.

    Parameters
    ----------
    path : str or path-like
        A JSON file written by ``terracone predict --json`` (or ``--out``), or
        the output directory of ``terracone batch`` (``part-*.parquet``).

    Returns
    -------
    list of ProfileResult
        In file (batch: chunk) order.

    Raises
    ------
    ValueError
        The path holds no terracone prediction results.
    """
    p = Path(path)
    if p.is_dir():
        import pyarrow.parquet as pq

        from terracone.apps.batch import OUTPUT_COLUMNS

        parts = sorted(p.glob("part-*.parquet"))
        if not parts:
            raise ValueError(f"{p}: no part-*.parquet files (not a terracone batch directory)")
        known = {name for name, _ in OUTPUT_COLUMNS} | {"reader_error"}
        return [_from_batch_row(row, known) for f in parts for row in pq.read_table(f).to_pylist()]
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{p}: file not found") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{p}: not a JSON file of terracone results ({exc})") from None
    if not isinstance(doc, Mapping) or not isinstance(doc.get("profiles"), list):
        raise ValueError(
            f"{p}: not the JSON of terracone predict (no 'profiles' list); "
            "give predict --json output or a batch output directory"
        )
    units = (doc.get("settings") or {}).get("units", "si")
    return [_from_predict(d, units) for d in doc["profiles"]]


def pick_profile(results: list[ProfileResult], profile: str | None, source: str) -> ProfileResult:
    """The profile named ``profile``, or the only fitted one; ValueError otherwise."""
    if profile is not None:
        hits = [r for r in results if r.id == profile]
        if not hits:
            shown = ", ".join(r.id for r in results[:5]) + (", ..." if len(results) > 5 else "")
            raise ValueError(f"{source}: no profile {profile!r} (it has {shown})")
        r = hits[0]
    else:
        ok = [r for r in results if r.status == "ok"]
        if len(ok) != 1:
            shown = ", ".join(r.id for r in ok[:5]) + (", ..." if len(ok) > 5 else "")
            raise ValueError(
                f"{source}: {len(ok)} fitted profiles; choose one with --profile ID ({shown})"
            )
        r = ok[0]
    if r.params is None:
        raise ValueError(f"{source}: profile {r.id!r} was not fitted ({r.error or r.status})")
    return r


def draw_samples(result: ProfileResult, count: int, seed: int | None = None) -> Any:
    """``count`` posterior draws of a profile (rows of kc, kphi, n, cc, phic_deg; SI).

    Drawn without replacement from the posterior draws stored by ``predict
    --uncertainty`` (its JSON key ``samples``).  Raises ValueError when the
    result holds no draws (a batch directory stores only 90% intervals) or
    fewer than ``count``.
    """
    import numpy as np

    if result.samples is None:
        raise ValueError(
            f"profile {result.id!r} has no posterior draws: --samples needs the JSON of "
            "`terracone predict --uncertainty --json` (a batch directory and predict without "
            "--uncertainty hold no draws)"
        )
    stored = result.samples.shape[0]
    if not 1 <= count <= stored:
        raise ValueError(f"--samples must be between 1 and {stored} (the stored draws)")
    rng = np.random.default_rng(seed)
    return result.samples[np.sort(rng.choice(stored, size=count, replace=False))]


def geojson(results: Iterable[ProfileResult]) -> tuple[dict[str, Any], list[str]]:
    """A GeoJSON FeatureCollection of the located profiles, and the ids without coordinates.

    One Point Feature per profile with both lat and lon, coordinates [lon,
    lat] (RFC 7946), properties ``id``, ``status``, ``kc``, ``kphi``, ``n``,
    ``cc``, ``phic_deg``, ``r2_ci``, ``lack_of_fit``, ``units``, ``error``
    and, when the run had them, ``intervals`` and ``layered``.
    """
    features, unlocated = [], []
    for r in results:
        if r.lat is None or r.lon is None:
            unlocated.append(r.id)
            continue
        props: dict[str, Any] = {"id": r.id, "status": r.status, **r.values, "units": r.units}
        props["error"] = r.error
        if r.intervals:
            props["intervals"] = r.intervals
        if r.layered:
            props["layered"] = r.layered
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [r.lon, r.lat]},
                "properties": props,
            }
        )
    return {"type": "FeatureCollection", "features": features}, unlocated


def write_geojson(results: Iterable[ProfileResult], out: str | os.PathLike) -> list[str]:
    """Write :func:`geojson` of ``results`` to ``out``; returns the ids without coordinates."""
    import json

    from terracone.io import json_default

    doc, unlocated = geojson(results)
    Path(out).write_text(json.dumps(doc, indent=1, default=json_default) + "\n")
    return unlocated


def write_scm_samples(
    result: ProfileResult,
    count: int,
    folder: str | os.PathLike,
    *,
    seed: int | None = None,
    **scm: Any,
) -> list[ChronoSCM]:
    """Chrono SCM files of ``count`` posterior draws of one profile, and ``draws.csv``.

    Files ``<id>-draw-0001.json``, ... in ``folder`` (created), one per draw
    of :func:`draw_samples`, each built by :func:`chrono_scm` with the
    keywords ``scm``; ``draws.csv`` lists file, kc [kN/m^(n+1)], kphi
    [kN/m^(n+2)], n, cc [kPa] and phic_deg of each.  Raises ValueError
    naming the draw that cannot be exported.
    """
    import csv
    import re

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", result.id).strip("_") or "profile"
    rows, written = [], []
    for k, row in enumerate(draw_samples(result, count, seed), 1):
        params = dict(zip(("kc", "kphi", "n", "cc", "phic_deg"), (float(v) for v in row)))
        try:
            scm_file = chrono_scm(params, f"{result.id} posterior draw {k}", **scm)
        except ValueError as exc:
            raise ValueError(f"draw {k}: {exc}") from None
        name = f"{safe}-draw-{k:04d}.json"
        scm_file.write(folder / name)
        written.append(scm_file)
        rows.append([name, *params.values()])
    with open(folder / "draws.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["file", "kc [kN/m^(n+1)]", "kphi [kN/m^(n+2)]", "n", "cc [kPa]", "phic_deg"])
        w.writerows(rows)
    return written

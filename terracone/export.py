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
Elastic K              Pa/m             only if given (``elastic_k=``)
Dampening R            Pa s/m           only if given (``damping_r=``)
=====================  ===============  =========================================

(kN/m^(n+2) times m^n is kN/m^2 = kPa; times 1000 gives Pa.)  Values the
terrain lacks are left out of the file and returned in ``missing``.  The
cone (metal)-terrain adhesion and friction cc, phic of [2]_ are *not* the
terrain's internal cohesion and friction and are never written as Mohr
parameters.

Plain export (:func:`to_plain`, :func:`write_plain_csv`): kc, kphi, n, c,
phi_deg, K, cc, phic_deg, Kc, model, r_min, moisture_pct in SI
(kN/m^(n+1), kN/m^(n+2), kPa, m) or US customary (lb/in^(n+1),
lb/in^(n+2), psi, in), via :mod:`terracone.units`.

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
from pathlib import Path
from typing import Any

from . import units as u
from .data import TerrainParameters
from .library import TerrainRecord, check_params

__all__ = [
    "CHRONO_KEYS",
    "FORMATS",
    "PLAIN_FIELDS",
    "export_terrain",
    "plain_units",
    "to_chrono_scm",
    "to_plain",
    "write_chrono_scm",
    "write_plain_csv",
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


def _params_of(obj: TerrainRecord | TerrainParameters | Mapping[str, Any]) -> dict[str, Any]:
    """SI parameter dict (library keys) of a record, TerrainParameters or dict."""
    if isinstance(obj, TerrainRecord):
        return check_params(obj.params)
    if isinstance(obj, TerrainParameters):
        d = {
            "kc": obj.kc,
            "kphi": obj.kphi,
            "n": obj.n,
            "cc": obj.cc,
            "phic_deg": obj.phic_deg,
            "Kc": obj.Kc,
            "model": obj.model,
            "r_min": obj.r_min,
        }
        return check_params(d)
    if isinstance(obj, Mapping):
        d = dict(obj)
        units = d.pop("units", "si")
        if units != "si":
            raise ValueError("parameter dicts must be in SI (library keys); got units=" + units)
        return check_params(d)
    raise TypeError(
        f"expected a TerrainRecord, TerrainParameters or dict (got {type(obj).__name__})"
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

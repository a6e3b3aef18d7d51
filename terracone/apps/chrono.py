"""Project Chrono's SCM soil, as Chrono reads it: co-simulation specs and PyChrono modules.

Chrono's SCM (Soil Contact Model) deformable terrain [1]_ takes eight soil
values, all of them required, in base SI units: the normal pressure is
Bekker's ``p = (Kc/b + Kphi) z^n`` [2]_ (p in Pa, b and z in m), the shear
Mohr-Coulomb with Janosi-Hanamoto's shear displacement [3]_.  Chrono reads
them in two ways, and terracone writes both:

* ``SCMTerrain::SetSoilParameters(Kphi, Kc, n, cohesion, friction, janosi,
  K, R)`` from C++ or PyChrono, and for soil that varies with location a
  ``SoilParametersCallback`` whose ``Set(loc, ...)`` writes the eight values
  at each point: :func:`pychrono_module` writes a Python module that does
  either;
* the SCM terrain spec of Chrono's vehicle co-simulation, read by
  ``ChVehicleCosimTerrainNodeSCM::SetFromSpecfile``: :func:`scm_spec`.

=================================  ==================  ==================  ============================
spec key ("Soil parameters")       SetSoilParameters   unit                from (terracone, SI)
=================================  ==================  ==================  ============================
Bekker Kphi                        Bekker_Kphi         Pa/m^n              kphi [kN/m^(n+2)] * 1000
Bekker Kc                          Bekker_Kc           Pa/m^(n-1)          kc [kN/m^(n+1)] * 1000
Bekker n exponent                  Bekker_n            -                   n
Mohr cohesive limit                Mohr_cohesion       Pa                  c_kpa [kPa] * 1000
Mohr friction limit                Mohr_friction       deg                 phi_deg
Janosi shear coefficient           Janosi_shear        m                   K_m
Elastic stiffness                  elastic_K           Pa/m                :class:`SCMSettings`
Damping                            damping_R           Pa s/m              :class:`SCMSettings`
=================================  ==================  ==================  ============================

(kN/m^(n+2) times m^n is kN/m^2 = kPa; times 1000 gives Pa.)  The cone gives
kc, kphi and n; the terrain's internal cohesion c, friction phi and Janosi K
come from a shear fit, a library terrain or the user.  The cone (metal)-soil
values cc and phic of [2]_ are not the terrain's and are never written.  A
value that is missing is refused (:func:`scm_values` raises), never written
as 0, which is what Chrono's release build reads for a missing spec key.

References
----------
.. [1] Project Chrono, Chrono::Vehicle, ``src/chrono_vehicle/terrain/SCMTerrain.h``
   (``SetSoilParameters``, ``SoilParametersCallback``),
   ``src/chrono_vehicle/cosim/terrain/ChVehicleCosimTerrainNodeSCM.cpp``
   (``SetFromSpecfile``), ``data/vehicle/cosim/terrain/scm_soft.json``,
   ``src/demos/python/vehicle/demo_VEH_DeformableSoil.py``.
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
import math
import os
import re
import string
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "DEFAULT_DAMPING_R",
    "DEFAULT_ELASTIC_K",
    "DEFAULT_FIX_PROXIES",
    "DEFAULT_GRID_SPACING",
    "DEFAULT_PATCH",
    "DEFAULT_PROXY_RADIUS",
    "HOW_TO_SUPPLY",
    "LocatedSoil",
    "SCMSettings",
    "SCM_ARGUMENTS",
    "SCM_UNITS",
    "SHEAR_KEYS",
    "SPEC_SOIL_KEYS",
    "DRAWS_HEADER",
    "default_origin",
    "is_ensemble",
    "pychrono_module",
    "scm_settings",
    "scm_spec",
    "scm_values",
    "write_pychrono",
    "write_scm_spec",
    "write_scm_specs",
]

#: Arguments of ``SCMTerrain::SetSoilParameters`` (and of
#: ``SoilParametersCallback::Set`` after ``loc``), in Chrono's order and names.
SCM_ARGUMENTS = (
    "Bekker_Kphi",
    "Bekker_Kc",
    "Bekker_n",
    "Mohr_cohesion",
    "Mohr_friction",
    "Janosi_shear",
    "elastic_K",
    "damping_R",
)
#: Keys of ``"Soil parameters"`` in Chrono's co-simulation SCM spec, same order
#: (``ChVehicleCosimTerrainNodeSCM::SetFromSpecfile``).
SPEC_SOIL_KEYS = (
    "Bekker Kphi",
    "Bekker Kc",
    "Bekker n exponent",
    "Mohr cohesive limit",
    "Mohr friction limit",
    "Janosi shear coefficient",
    "Elastic stiffness",
    "Damping",
)
#: Chrono's unit of each of the eight values, same order.
SCM_UNITS = ("Pa/m^n", "Pa/m^(n-1)", "-", "Pa", "deg", "m", "Pa/m", "Pa s/m")
#: terracone's SI keys of the terrain's shear strength (library keys): cohesion
#: [kPa], friction angle [deg], Janosi-Hanamoto shear deformation modulus [m].
SHEAR_KEYS = ("c_kpa", "phi_deg", "K_m")
#: The header of ``draws.csv`` (:func:`write_scm_specs`).
DRAWS_HEADER = ("file", "kc [kN/m^(n+1)]", "kphi [kN/m^(n+2)]", "n", "cc [kPa]", "phic_deg")

#: Default SCM elastic stiffness [Pa/m]: the value of the LETE-sand branch of
#: PyChrono's SCM demo (``src/demos/python/vehicle/demo_VEH_DeformableSoil.py``);
#: Chrono's co-simulation samples use 4e7 (``data/vehicle/cosim/terrain/scm_soft.json``)
#: and 2e8 (``scm_hard.json``).  Above every Bekker Kphi of Wong's reference soils.
#: Not a Bekker-Wong value: never from data.
DEFAULT_ELASTIC_K = 4e8
#: Default SCM vertical damping [Pa s/m]: the value of every SCM sample of
#: Chrono (``data/vehicle/cosim/terrain/scm_soft.json``, ``scm_hard.json``).
DEFAULT_DAMPING_R = 3e4
#: Default patch (length, width) [m] and grid spacing [m]: Chrono's
#: ``data/vehicle/cosim/terrain/scm_soft.json``.
DEFAULT_PATCH = (4.0, 1.0)
DEFAULT_GRID_SPACING = 0.1
#: Default co-simulation settings [m], [-]: both of Chrono's SCM spec samples.
DEFAULT_PROXY_RADIUS = 0.002
DEFAULT_FIX_PROXIES = True

#: How a user supplies the terrain's shear values (CLI options, Python keys).
HOW_TO_SUPPLY = (
    "give --shear FIT.json (the output of `terracone fit-shear --json`), --shear TERRAIN "
    "(a library terrain that has them), or --cohesion, --friction, --janosi (e.g. "
    "--cohesion 1.3kPa --friction 31deg --janosi 12mm; bare numbers in --units); in Python "
    "add c_kpa [kPa], phi_deg [deg], K_m [m] to the parameters"
)

_OPTIONS = {
    "elastic_k": "--elastic-k",
    "damping_r": "--damping",
    "patch": "--patch",
    "grid_spacing": "--grid-spacing",
}


@dataclass(frozen=True)
class SCMSettings:
    """What Chrono's SCM needs beyond the soil's Bekker-Wong values (SI).

    Attributes
    ----------
    elastic_k : float
        Elastic stiffness K per unit area [Pa/m]; must exceed Bekker Kphi
        (Chrono raises it silently to Kphi; terracone refuses instead).
    damping_r : float
        Vertical damping R per unit area [Pa s/m], >= 0.
    patch : (float, float)
        Patch length and width [m] (spec ``"Patch dimensions"``; the
        PyChrono module's demonstration patch).
    grid_spacing : float
        SCM grid spacing [m].
    proxy_radius : float
        Co-simulation proxy contact radius [m].
    fix_proxies : bool
        Co-simulation ``"Fix proxies"``.
    defaulted : tuple of str
        Names of the attributes left at terracone's defaults (not from data).
    """

    elastic_k: float = DEFAULT_ELASTIC_K
    damping_r: float = DEFAULT_DAMPING_R
    patch: tuple[float, float] = DEFAULT_PATCH
    grid_spacing: float = DEFAULT_GRID_SPACING
    proxy_radius: float = DEFAULT_PROXY_RADIUS
    fix_proxies: bool = DEFAULT_FIX_PROXIES
    defaulted: tuple[str, ...] = ()

    def defaulted_values(self, *, spec: bool = True) -> list[str]:
        """The values left at their defaults, as ``"name = value unit"``.

        ``spec=False`` leaves out the co-simulation settings (not in a
        PyChrono module).
        """
        shown = {
            "elastic_k": f"Elastic stiffness = {self.elastic_k:g} Pa/m",
            "damping_r": f"Damping = {self.damping_r:g} Pa s/m",
            "patch": f"Patch dimensions = {self.patch[0]:g} x {self.patch[1]:g} m",
            "grid_spacing": f"Grid spacing = {self.grid_spacing:g} m",
            "proxy_radius": f"Proxy contact radius = {self.proxy_radius:g} m",
            "fix_proxies": f"Fix proxies = {str(self.fix_proxies).lower()}",
        }
        if not spec:
            shown.pop("proxy_radius")
            shown.pop("fix_proxies")
        return [shown[k] for k in shown if k in self.defaulted]

    def defaults_text(self, *, spec: bool = True) -> str:
        """Which values are defaults rather than data, as a sentence (empty if none)."""
        parts = self.defaulted_values(spec=spec)
        if not parts:
            return ""
        return ", ".join(parts) + ": defaults (Chrono's own samples), not from data"


def scm_settings(
    *,
    elastic_k: float | None = None,
    damping_r: float | None = None,
    patch: tuple[float, float] | None = None,
    grid_spacing: float | None = None,
) -> SCMSettings:
    """:class:`SCMSettings` from the values given, defaults for the others (recorded).

    Parameters
    ----------
    elastic_k : float, optional
        [Pa/m], > 0; default :data:`DEFAULT_ELASTIC_K`.
    damping_r : float, optional
        [Pa s/m], >= 0; default :data:`DEFAULT_DAMPING_R`.
    patch : (float, float), optional
        Length and width [m], > 0; default :data:`DEFAULT_PATCH`.
    grid_spacing : float, optional
        [m], > 0; default :data:`DEFAULT_GRID_SPACING`.

    Raises
    ------
    ValueError
        A value out of range (the message names it).
    """
    given = {
        "elastic_k": elastic_k,
        "damping_r": damping_r,
        "patch": patch,
        "grid_spacing": grid_spacing,
    }
    kw: dict[str, Any] = {}
    for name, v in given.items():
        if v is None:
            continue
        vals = tuple(float(x) for x in (v if name == "patch" else (v,)))
        ok = all(math.isfinite(x) and (x >= 0 if name == "damping_r" else x > 0) for x in vals)
        if not ok or len(vals) != (2 if name == "patch" else 1):
            what = ">= 0" if name == "damping_r" else "> 0"
            raise ValueError(f"{name} ({_OPTIONS[name]}) must be {what} (got {v!r})")
        kw[name] = vals if name == "patch" else vals[0]
    defaulted = tuple(k for k in given if k not in kw) + ("proxy_radius", "fix_proxies")
    return SCMSettings(**kw, defaulted=defaulted)


def _shear_check(p: Mapping[str, Any], where: str) -> None:
    if "c_kpa" in p and not p["c_kpa"] >= 0:
        raise ValueError(f"{where}cohesion must be >= 0 kPa (got {p['c_kpa']:g})")
    if "phi_deg" in p and not 0 <= p["phi_deg"] < 90:
        raise ValueError(f"{where}friction angle must be in [0, 90) deg (got {p['phi_deg']:g})")
    if "K_m" in p and not p["K_m"] > 0:
        raise ValueError(f"{where}Janosi shear modulus must be > 0 m (got {p['K_m']:g})")


def scm_values(
    params: Mapping[str, Any], settings: SCMSettings, name: str = "the terrain"
) -> tuple[float, ...]:
    """The eight SCM soil values of a terrain, in :data:`SCM_ARGUMENTS` order and Chrono's units.

    Parameters
    ----------
    params : mapping
        SI values with terracone's library keys: kc [kN/m^(n+1)], kphi
        [kN/m^(n+2)], n [-], c_kpa [kPa], phi_deg [deg], K_m [m] (others,
        e.g. the cone-metal cc and phic_deg, are ignored).
    settings : SCMSettings
        Elastic stiffness and damping.
    name : str
        The terrain, for messages.

    Returns
    -------
    tuple of float
        Bekker Kphi [Pa/m^n], Bekker Kc [Pa/m^(n-1)], n, Mohr cohesion [Pa],
        Mohr friction [deg], Janosi shear [m], elastic K [Pa/m], damping R
        [Pa s/m].

    Raises
    ------
    ValueError
        A value is missing (the message names the Chrono keys and how to
        supply them), out of range, or the elastic stiffness does not exceed
        Bekker Kphi.
    """
    p = {k: v for k, v in params.items() if v is not None}
    missing = [k for k in ("kphi", "kc", "n", *SHEAR_KEYS) if k not in p]
    if missing:
        keys = dict(zip(("kphi", "kc", "n", *SHEAR_KEYS), SPEC_SOIL_KEYS))
        args = dict(zip(("kphi", "kc", "n", *SHEAR_KEYS), SCM_ARGUMENTS))
        named = ", ".join(f"{keys[k]} ({args[k]})" for k in missing)
        how = (
            HOW_TO_SUPPLY
            if set(missing) <= set(SHEAR_KEYS)
            else "export a terrain with kc, kphi and n (a fitted profile or a library terrain)"
        )
        raise ValueError(
            f"Chrono's SCM needs all eight soil parameters and {name} lacks {named}: {how}. "
            "Chrono would read a missing value as 0; nothing was written"
        )
    _shear_check(p, f"{name}: ")
    values = (
        float(p["kphi"]) * 1000.0,  # kN/m^(n+2) -> Pa/m^n
        float(p["kc"]) * 1000.0,  # kN/m^(n+1) -> Pa/m^(n-1)
        float(p["n"]),
        float(p["c_kpa"]) * 1000.0,  # kPa -> Pa
        float(p["phi_deg"]),  # deg
        float(p["K_m"]),  # m
        float(settings.elastic_k),  # Pa/m
        float(settings.damping_r),  # Pa s/m
    )
    bad = [a for a, v in zip(SCM_ARGUMENTS, values) if not math.isfinite(v)]
    if bad:
        raise ValueError(f"{name}: {', '.join(bad)} not a finite number; nothing was written")
    if not values[6] > values[0]:
        where = "the default " if "elastic_k" in settings.defaulted else ""
        raise ValueError(
            f"{name}: Elastic stiffness must exceed Bekker Kphi (Chrono raises it silently to "
            f"Kphi): {where}Elastic stiffness = {values[6]:g} Pa/m, Bekker Kphi = "
            f"{values[0]:g} Pa/m^n; give a larger --elastic-k (elastic_k=)"
        )
    return values


def scm_spec(
    params: Mapping[str, Any],
    settings: SCMSettings,
    name: str = "the terrain",
    notes: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Chrono's co-simulation SCM terrain spec of a terrain, with exactly Chrono's keys.

    ``{"Type": "SCM", "Patch dimensions": {"Length", "Width"}, "Grid
    spacing", "Soil parameters": {...}, "Simulation settings": {"Proxy
    contact radius", "Fix proxies"}}``, the layout of Chrono's
    ``data/vehicle/cosim/terrain/scm_soft.json``, read by
    ``ChVehicleCosimTerrainNodeSCM::SetFromSpecfile``.  Values as
    :func:`scm_values` (which raises when one is missing).  ``notes``, when
    given, are added as ``"Notes"`` (an effective soil's ``effective`` block,
    say): Chrono reads its keys by name and ignores the others.
    """
    values = scm_values(params, settings, name)
    extra = {} if notes is None else {"Notes": dict(notes)}
    return {
        "Type": "SCM",
        "Patch dimensions": {"Length": settings.patch[0], "Width": settings.patch[1]},
        "Grid spacing": settings.grid_spacing,
        "Soil parameters": dict(zip(SPEC_SOIL_KEYS, values)),
        "Simulation settings": {
            "Proxy contact radius": settings.proxy_radius,
            "Fix proxies": bool(settings.fix_proxies),
        },
        **extra,
    }


def write_scm_spec(
    path: str | os.PathLike,
    params: Mapping[str, Any],
    settings: SCMSettings,
    name: str = "the terrain",
    notes: Mapping[str, Any] | None = None,
) -> Path:
    """Write :func:`scm_spec` to ``path`` (nothing is written when it raises)."""
    text = json.dumps(scm_spec(params, settings, name, notes), indent=4) + "\n"
    p = Path(path)
    p.write_text(text, encoding="utf-8")
    return p


@dataclass(frozen=True)
class LocatedSoil:
    """One terrain for Chrono: SI parameters, where it is, and an ensemble of draws.

    The input of :func:`pychrono_module` and :func:`write_scm_specs`: a
    fitted profile, a library terrain or a cell of a terrain map.

    Attributes
    ----------
    id : str
        Profile, terrain or cell name.
    params : mapping
        SI values with library keys: kc [kN/m^(n+1)], kphi [kN/m^(n+2)], n,
        c_kpa [kPa], phi_deg [deg], K_m [m] (cc, phic_deg may be present
        and are not used).
    lat, lon : float or None
        Decimal degrees (WGS 84), when located.
    draws : tuple of mappings
        Posterior draws, each with the keys of ``params`` (SI).
    effective : mapping or None
        When ``params`` are the effective soil of a layered ground for a
        vehicle (:func:`terracone.physics.effective.effective_soil`), its
        ``effective`` block (width, load, sinkage, error), written with the soil.
    """

    id: str
    params: Mapping[str, Any]
    lat: float | None = None
    lon: float | None = None
    draws: tuple[Mapping[str, Any], ...] = field(default_factory=tuple)
    effective: Mapping[str, Any] | None = None

    @property
    def located(self) -> bool:
        """True when both lat and lon are known."""
        return self.lat is not None and self.lon is not None


def write_scm_specs(
    folder: str | os.PathLike, soil: LocatedSoil, settings: SCMSettings, *, force: bool = False
) -> list[Path]:
    """One co-simulation spec per draw of ``soil`` in ``folder``, and ``draws.csv``.

    Files ``<id>-draw-0001.json``, ...; ``draws.csv`` lists file, kc
    [kN/m^(n+1)], kphi [kN/m^(n+2)], n, cc [kPa] and phic_deg of each draw
    (a file name that a spreadsheet would take for a formula is written after
    a single quote, OWASP's advice against CSV injection).  Every spec is built
    before anything is written: a draw that cannot be exported (named in the
    ValueError) leaves no file and no folder.  The folder then holds these
    files and nothing else: they are written into a new folder that takes its
    place whole (:func:`terracone.io.outputs.run_directory`); an earlier
    ensemble there is replaced, a folder holding anything else is refused
    unless ``force``.
    """
    from terracone.io.outputs import run_directory
    from terracone.io.tables import guard_formula

    if not soil.draws:
        raise ValueError(f"{soil.id!r} has no draws to write")
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", soil.id).strip("_") or "profile"
    docs = []
    for k, draw in enumerate(soil.draws, 1):
        docs.append(scm_spec(draw, settings, f"{soil.id!r} draw {k}"))
    folder = Path(folder).expanduser().resolve()
    names, rows = [], []
    with run_directory(folder, what="Chrono ensemble", is_run=is_ensemble, force=force) as stage:
        for k, (draw, doc) in enumerate(zip(soil.draws, docs), 1):
            name = f"{safe}-draw-{k:04d}.json"
            (stage / name).write_text(json.dumps(doc, indent=4) + "\n", encoding="utf-8")
            names.append(name)
            values = [draw.get(p) for p in ("kc", "kphi", "n", "cc", "phic_deg")]
            rows.append([guard_formula(name), *values])
        with open(stage / "draws.csv", "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(list(DRAWS_HEADER))
            w.writerows(rows)
    return [folder / name for name in names]


def is_ensemble(folder: str | os.PathLike) -> bool:
    """Whether a folder holds one ensemble of :func:`write_scm_specs` and nothing else."""
    from terracone.io.tables import unguard_formula

    d = Path(folder)
    try:
        with open(d / "draws.csv", newline="", encoding="utf-8") as fh:
            table = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error):
        return False
    if not table or tuple(table[0]) != DRAWS_HEADER:
        return False
    files = {"draws.csv"} | {unguard_formula(r[0]) for r in table[1:] if r}
    return all(e.is_file() and e.name in files for e in d.iterdir())


def default_origin(soils: Sequence[LocatedSoil]) -> tuple[float, float]:
    """The middle of the located soils' bounding box (lat, lon) [deg]: the module's ORIGIN."""
    located = [s for s in soils if s.located]
    if not located:
        raise ValueError("no located soil: an origin needs at least one lat/lon")
    lats = [float(s.lat) for s in located]
    lons = [float(s.lon) for s in located]
    return 0.5 * (min(lats) + max(lats)), 0.5 * (min(lons) + max(lons))


def _rows(soil: LocatedSoil, settings: SCMSettings, n_draws: int) -> tuple[Any, list[Any]]:
    values = scm_values(soil.params, settings, repr(soil.id))
    if len(soil.draws) != n_draws:
        raise ValueError(
            f"{soil.id!r} has {len(soil.draws)} draws where the others have {n_draws}: "
            "an ensemble needs the same number for every soil"
        )
    draws = [scm_values(d, settings, f"{soil.id!r} draw {k}") for k, d in enumerate(soil.draws, 1)]
    return values, draws


def _number(v: float | None) -> str:
    """A Python literal of a number (``float('nan')`` and the like where not finite)."""
    if v is None:
        return "None"
    x = float(v)
    return repr(x) if math.isfinite(x) else f"float({str(x)!r})"


def _literal(rows: Sequence[Sequence[float]], indent: str) -> str:
    return "".join(f"{indent}({', '.join(_number(v) for v in r)}),\n" for r in rows)


def _data(v: Any) -> str:
    """A Python literal of JSON-like data (dicts, lists, strings, numbers): data, never code."""
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{str(k)!r}: {_data(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_data(x) for x in v) + "]"
    if v is None or isinstance(v, bool):
        return repr(v)
    if isinstance(v, int | float):
        return _number(v)
    return repr(str(v))


def _strings(lines: Sequence[str]) -> str:
    """A tuple literal of strings, one a line: every string is data (``repr``), never code."""
    return "".join(f"    {str(line)!r},\n" for line in lines)


def pychrono_module(
    soils: Sequence[LocatedSoil],
    settings: SCMSettings,
    *,
    origin: tuple[float, float] | None = None,
    source: str = "",
    notes: Sequence[str] = (),
) -> str:
    """The text of a Python module that gives a PyChrono ``SCMTerrain`` this soil.

    Parameters
    ----------
    soils : sequence of LocatedSoil
        One soil: ``apply(terrain)`` calls ``SetSoilParameters`` with its
        eight values.  Several: all must be located, and ``apply`` registers
        a ``SoilParametersCallback`` that writes, at each point, the values
        of the nearest soil in the module's frame (x east, y north [m] from
        ``ORIGIN``).  With draws (the same number for every soil), ``apply(
        terrain, sample=i)`` uses draw ``i`` (0-based) instead.
    settings : SCMSettings
        Elastic stiffness, damping; patch and grid spacing of the module's
        demonstration (run as a script).
    origin : (float, float), optional
        ORIGIN (lat, lon) [deg] of several soils; default
        :func:`default_origin`.
    source : str
        Where the values come from: the module's ``SOURCE``.
    notes : sequence of str
        The module's ``NOTES`` (e.g. where the shear values came from).

    Returns
    -------
    str
        The module: imports only ``pychrono``, ``pychrono.vehicle`` and the
        standard library.  Every string from the data (ids, ``source``,
        ``notes``) is a ``repr`` literal in an assignment; the docstring holds
        terracone's own text only, so no name or path can end a string early
        or run as code.

    Raises
    ------
    ValueError
        A soil lacks one of the eight values, several soils are not all
        located, or the draws differ in number.
    """
    if not soils:
        raise ValueError("no soil to write")
    n_draws = len(soils[0].draws)
    rows = [_rows(s, settings, n_draws) for s in soils]
    if len(soils) > 1:
        unlocated = [s.id for s in soils if not s.located]
        if unlocated:
            raise ValueError(
                f"soil that varies in space needs every soil located; no lat/lon: {unlocated}"
            )
        origin = default_origin(soils) if origin is None else origin
    else:
        origin = None
    from terracone import __version__

    if origin is not None:
        origin = (float(origin[0]), float(origin[1]))
    frame = _FRAME_DOC.format(origin=origin) if origin is not None else _ONE_DOC
    defaults = settings.defaulted_values(spec=False)
    tail = [
        *notes,
        "Defaults (Chrono's own samples), not from data: " + (", ".join(defaults) or "none") + ".",
    ]
    return string.Template(_MODULE).substitute(
        frame=_wrap(frame),
        version=repr(str(__version__)),
        source=repr(str(source or "terracone")),
        notes=_strings(tail),
        origin=f"({_number(origin[0])}, {_number(origin[1])})" if origin is not None else "None",
        patch=f"({_number(settings.patch[0])}, {_number(settings.patch[1])})",
        spacing=_number(settings.grid_spacing),
        sites="".join(f"    ({str(s.id)!r}, {_number(s.lat)}, {_number(s.lon)}),\n" for s in soils),
        soil=_literal([r[0] for r in rows], "    "),
        samples="".join(
            "    (\n" + _literal([r[1][i] for r in rows], "        ") + "    ),\n"
            for i in range(n_draws)
        ),
        effective="".join(f"    {_data(s.effective)},\n" for s in soils),
    )


def _wrap(text: str) -> str:
    return "\n".join(textwrap.fill(" ".join(par.split()), 88) for par in text.split("\n\n"))


def write_pychrono(
    path: str | os.PathLike, soils: Sequence[LocatedSoil], settings: SCMSettings, **kw: Any
) -> Path:
    """Write :func:`pychrono_module` (keywords as there) to ``path``; nothing when it raises."""
    text = pychrono_module(soils, settings, **kw)
    p = Path(path)
    p.write_text(text, encoding="utf-8")
    return p


_ONE_DOC = """One terrain: apply(terrain) calls terrain.SetSoilParameters with the eight values."""

_FRAME_DOC = """Soil that varies in space: apply(terrain) registers a SoilParametersCallback that
writes, at each point, the values of the nearest site of SITES.  Chrono gives the
point in the SCM frame; this module takes that frame's x as east and y as north, in
metres, from ORIGIN = {origin} (lat, lon in decimal degrees, WGS 84), as with
SCMTerrain's default plane (z up) placed at ORIGIN.  to_local(lat, lon) gives a
point's (x, y) by the local equirectangular (tangent-plane) approximation
x = N0 cos(lat0) dlon, y = M0 dlat, N0 and M0 the WGS 84 radii of curvature at
ORIGIN.  Its position error grows as about tan(lat0) d^2 / (2 x 6.4e6 m) at a
distance d from ORIGIN: at 45 degrees 0.02 m at 500 m, 0.4 m at 2 km, 3 m at 6 km
(against WGS 84 geodesics)."""

_MODULE = '''\
"""Chrono SCM soil written by terracone: where from in SOURCE and NOTES below.

Give a PyChrono SCMTerrain this soil:

    import pychrono.vehicle as veh
    import <this module>
    terrain = veh.SCMTerrain(system)
    terrain.Initialize(length, width, spacing)
    <this module>.apply(terrain)             # the fitted values
    <this module>.apply(terrain, sample=i)   # or posterior draw i, 0 <= i < N_SAMPLES

Run it as a script (python <this file>) to build a small SCM patch (PATCH,
GRID_SPACING) in a Chrono system, press a plate into it and print the sinkage.

$frame

Values: Chrono's SCMTerrain::SetSoilParameters arguments, in its order and units
(NAMES, UNITS): Bekker Kphi [Pa/m^n], Bekker Kc [Pa/m^(n-1)], Bekker n [-],
Mohr cohesion [Pa], Mohr friction [deg], Janosi shear [m], elastic stiffness K
[Pa/m], damping R [Pa s/m].  Bekker Kc, Kphi = kc, kphi [kN/m^(n+1), kN/m^(n+2)] x 1000.
"""

import math

import pychrono as chrono
import pychrono.vehicle as veh

NAMES = (
    "Bekker_Kphi",
    "Bekker_Kc",
    "Bekker_n",
    "Mohr_cohesion",
    "Mohr_friction",
    "Janosi_shear",
    "elastic_K",
    "damping_R",
)
UNITS = ("Pa/m^n", "Pa/m^(n-1)", "-", "Pa", "deg", "m", "Pa/m", "Pa s/m")
# where the values come from: the terracone version, the input, notes
TERRACONE = $version
SOURCE = $source
NOTES = (
$notes)
ORIGIN = $origin
PATCH = $patch  # length, width [m]
GRID_SPACING = $spacing  # [m]
# one row per site: id, lat, lon [deg] (None where not located)
SITES = (
$sites)
# the fitted values, one row per site (NAMES order)
SOIL = (
$soil)
# posterior draws: SAMPLES[i] holds one row per site
SAMPLES = (
$samples)
N_SAMPLES = len(SAMPLES)
# one entry per site: None, or the effective soil of a layered ground for a vehicle
# (terracone export --vehicle): width_m, load_n, sinkage_m, error, ...
EFFECTIVE = (
$effective)

_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3
_KEEP = []  # callbacks registered with Chrono, kept alive here


def to_local(lat, lon):
    """(x east, y north) [m] of a point (decimal degrees) in this module's frame."""
    lat0, lon0 = ORIGIN
    p0 = math.radians(lat0)
    w = math.sqrt(1.0 - _WGS84_E2 * math.sin(p0) ** 2)
    n0, m0 = _WGS84_A / w, _WGS84_A * (1.0 - _WGS84_E2) / w**3
    dlon = (lon - lon0 + 180.0) % 360.0 - 180.0
    return n0 * math.cos(p0) * math.radians(dlon), m0 * math.radians(lat - lat0)


def parameters(sample=None):
    """The eight values of every site: the fitted ones, or those of draw ``sample``."""
    if sample is None:
        return SOIL
    if not 0 <= sample < N_SAMPLES:
        raise IndexError(f"sample must be in 0..{N_SAMPLES - 1} (got {sample})")
    return SAMPLES[sample]


class Nearest:
    """Index of the nearest of some points (x, y), on a grid of buckets."""

    def __init__(self, xy):
        self.xy = list(xy)
        xs, ys = [p[0] for p in self.xy], [p[1] for p in self.xy]
        self.x0, self.y0 = min(xs), min(ys)
        span = max(max(xs) - self.x0, max(ys) - self.y0, 1e-9)
        self.h = span / max(1, math.isqrt(len(self.xy)))
        self.cells = {}
        for k, (x, y) in enumerate(self.xy):
            self.cells.setdefault(self.cell(x, y), []).append(k)
        self.imax = max(i for i, _ in self.cells)
        self.jmax = max(j for _, j in self.cells)
        self.cache = {}

    def cell(self, x, y):
        return math.floor((x - self.x0) / self.h), math.floor((y - self.y0) / self.h)

    def ring(self, i0, j0, r):
        """The points in the cells at Chebyshev distance r from cell (i0, j0)."""
        for i in range(max(i0 - r, 0), min(i0 + r, self.imax) + 1):
            if abs(i - i0) == r:
                js = range(max(j0 - r, 0), min(j0 + r, self.jmax) + 1)
            else:
                js = [j for j in (j0 - r, j0 + r) if 0 <= j <= self.jmax]
            for j in js:
                yield from self.cells.get((i, j), ())

    def __call__(self, x, y):
        """Index of the point nearest to (x, y) (the lowest index on a tie)."""
        hit = self.cache.get((x, y))
        if hit is not None:
            return hit
        i0, j0 = self.cell(x, y)
        start = max(-i0, i0 - self.imax, -j0, j0 - self.jmax, 0)
        stop = max(abs(i0), abs(i0 - self.imax), abs(j0), abs(j0 - self.jmax))
        best = (math.inf, -1)
        for r in range(start, stop + 1):
            for k in self.ring(i0, j0, r):
                px, py = self.xy[k]
                best = min(best, ((px - x) ** 2 + (py - y) ** 2, k))
            if best[1] >= 0 and best[0] <= (r * self.h) ** 2:
                break
        self.cache[(x, y)] = best[1]
        return best[1]


class NearestSoil(veh.SoilParametersCallback):
    """Chrono SCM soil callback: the values of the nearest site at each point."""

    def __init__(self, rows):
        veh.SoilParametersCallback.__init__(self)
        self.rows = rows
        self.nearest = Nearest([to_local(lat, lon) for _, lat, lon in SITES])

    def Set(self, loc, Kphi, Kc, n, coh, mu_angle, shear, K, R):
        v = self.rows[self.nearest(loc.x, loc.y)]
        veh.doublep_assign(Kphi, v[0])
        veh.doublep_assign(Kc, v[1])
        veh.doublep_assign(n, v[2])
        veh.doublep_assign(coh, v[3])
        veh.doublep_assign(mu_angle, v[4])
        veh.doublep_assign(shear, v[5])
        veh.doublep_assign(K, v[6])
        veh.doublep_assign(R, v[7])


def apply(terrain, sample=None):
    """Give ``terrain`` (a pychrono.vehicle.SCMTerrain) this soil; returns the callback, if any."""
    rows = parameters(sample)
    if ORIGIN is None:
        terrain.SetSoilParameters(*rows[0])
        return None
    callback = NearestSoil(rows)
    _KEEP.append(callback)
    terrain.RegisterSoilParametersCallback(callback)
    return callback


def grid_nodes(plate, centre, spacing):
    """The grid nodes SCM's rays find under a square plate: (count, 1/b) of the contact patch.

    SCM casts a ray at every node (i * spacing, j * spacing), gives each node it finds the
    area spacing**2 (Fn = m_area * sigma) and takes 1/b = perimeter / (2 area) of the convex
    hull of those nodes (SCMTerrain.cpp, ComputeInternalForces).
    """
    half, k = plate / 2, int(plate / spacing) + 2
    along = [[i for i in range(-k, k + 1) if abs(i * spacing - c) < half] for c in centre]
    nx, ny = len(along[0]), len(along[1])
    sx, sy = (nx - 1) * spacing, (ny - 1) * spacing
    oob = (sx + sy) / (sx * sy) if sx > 0 and sy > 0 else 0.0  # perimeter / (2 area)
    return nx * ny, oob


def demo(sample=None, plate=0.2, pressure=20e3, seconds=1.0, step=1e-3):
    """Press a square plate (side ``plate`` [m], ``pressure`` [Pa]) into an SCM patch.

    Returns the plate's sinkage [m] after ``seconds``, the static sinkage SCM's grid gives
    (:func:`grid_nodes`: the load on the nodes under the plate, each of area
    GRID_SPACING**2, with SCM's 1/b of their hull) and Bekker's static sinkage of the
    plate itself, (pressure / (Kc / b + Kphi)) ** (1 / n) with b = 2 area / perimeter,
    for the soil at the patch centre.  The plate's centre is shifted by half a grid step
    where its edges would otherwise fall on grid lines (so that no node lies on an edge).
    """
    vec = getattr(chrono, "ChVector3d", None) or chrono.ChVectorD
    system = chrono.ChSystemSMC()
    if hasattr(system, "SetCollisionSystemType"):
        system.SetCollisionSystemType(chrono.ChCollisionSystem.Type_BULLET)
    gravity = getattr(system, "SetGravitationalAcceleration", None) or system.Set_G_acc
    gravity(vec(0, 0, -9.81))  # SCM's default plane: z up
    terrain = veh.SCMTerrain(system)
    terrain.Initialize(PATCH[0], PATCH[1], GRID_SPACING)
    apply(terrain, sample)
    material = getattr(chrono, "ChContactMaterialSMC", None) or chrono.ChMaterialSurfaceSMC
    thick = 0.02
    density = pressure * plate**2 / 9.81 / (plate**2 * thick)
    body = chrono.ChBodyEasyBox(plate, plate, thick, density, True, True, material())
    steps = plate / GRID_SPACING
    on_lines = abs(steps - round(steps)) < 1e-9 and round(steps) % 2 == 0
    c = GRID_SPACING / 2 if on_lines else 0.0
    body.SetPos(vec(c, c, thick / 2 + 0.005))
    system.Add(body)
    t = 0.0
    while t < seconds:
        system.DoStepDynamics(step)
        t += step
    sinkage = thick / 2 - body.GetPos().z
    centre = 0 if ORIGIN is None else Nearest([to_local(a, b) for _, a, b in SITES])(c, c)
    kphi, kc, n = parameters(sample)[centre][:3]
    nodes, oob = grid_nodes(plate, (c, c), GRID_SPACING)
    load = pressure * plate**2
    on_grid = (load / (nodes * GRID_SPACING**2) / (kc * oob + kphi)) ** (1 / n)
    static = (pressure / (kc / (plate / 2) + kphi)) ** (1 / n)
    return sinkage, on_grid, static


if __name__ == "__main__":
    sinkage, on_grid, static = demo()
    soil = f"soil of {SITES[0][0]!r}" if ORIGIN is None else f"{len(SITES)} sites"
    print(f"SCM patch {PATCH[0]:g} x {PATCH[1]:g} m, grid {GRID_SPACING:g} m, {soil}")
    print(f"plate 0.2 m at 20 kPa: sinkage {sinkage:.3g} m after 1 s "
          f"(static on SCM's grid: {on_grid:.3g} m; Bekker, continuous plate: {static:.3g} m)")
'''

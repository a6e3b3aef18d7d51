"""The soil of a profile for MAVS: ``terracone export --format mavs``.

MAVS, the Mississippi State University Autonomous Vehicle Simulator, takes a
soil type and a soil strength in two places, with two units (its public
source [1]_, read here):

* a scene file's ``"Surface Mesh"`` entries: the scene loader
  (``EmbreeTracer::LoadSurfaceMesh``, ``src/raytracers/embree_tracer/embree_tracer.cpp``)
  parses ``"Material"`` and ``"Cone Index"`` (psi, times 6894.76 to Pa).  But
  ``Environment::SetRaytracer`` (``src/mavs_core/environment/environment.cpp``)
  has the two lines that would hand them to the environment commented out, so
  a vehicle never sees them: its tyres (``MavsTire::Update``,
  ``src/vehicles/rp3d_veh/mavs_tire.cpp``) read the soil set on the vehicle,
  else the environment's, which ``Environment()`` sets to ``"dry"`` and
  ``rci_ = 250.0f``;
* :func:`mavs_set_terrain_properties` gives what a MAVS user passes instead, to
  either of MAVS's Python calls (``src/mavs_python/mavs_interface.py``):
  ``MavsEnvironment.SetTerrainProperties(type, strength)``, the strength "in
  Cone-Index (Pascals)", handed unchanged to
  ``Environment::SetGlobalSurfaceProperties(surface_type, RCI)`` ("The cone
  index in pascals"); or ``MavsRp3d.SetTerrainProperties(terrain_type,
  terrain_param1, terrain_param2, soil_type, soil_strength)``, the strength "in
  PSI", which MAVS multiplies by 6894.76 before ``SetRp3dTerrain`` and which
  also replaces the scene's mesh by an analytical surface (``terrain_type``,
  default ``"flat"``).

The strength is that of the critical layer the MAVS tyre model reads: the RCI
for clay (fine-grained), the CI for sand (:func:`write_mavs`).

References
----------
.. [1] Mississippi State University, MAVS, github.com/Mississippi-State-University-OTM/MAVS
   (files as named above).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from terracone.apps.mobility import remolding_index_of
from terracone.apps.trafficability import critical_layer_mean
from terracone.physics import units as u
from terracone.result import PredictionResults
from terracone.resultunits import from_si

__all__ = [
    "MAVS_MATERIALS",
    "MAVS_PSI_TO_PA",
    "MAVS_LAYER",
    "mavs_surface",
    "mavs_set_terrain_properties",
    "write_mavs",
]

PathLike = str | os.PathLike[str]

#: Soil types of MAVS's tyre-terrain model whose strength it reads (clay, sand) [1].
MAVS_MATERIALS = ("sand", "clay")
#: MAVS's own psi-to-Pa factor (``6894.76f`` in the scene loader and ``6894.76`` in
#: ``MavsRp3d.SetTerrainProperties``) [1]; terracone converts with the exact factor.
MAVS_PSI_TO_PA = 6894.76
#: Critical layer of the MAVS export (top, bottom) [m]: 0-6 in.
MAVS_LAYER = (0.0, 6 * u.INCH)
ENV_CALL = "mavs_interface.MavsEnvironment.SetTerrainProperties(type, strength)"
VEH_CALL = (
    "mavs_interface.MavsRp3d.SetTerrainProperties(terrain_type, terrain_param1, "
    "terrain_param2, soil_type, soil_strength)"
)


def _check(cone_index: float, material: str) -> None:
    if material not in MAVS_MATERIALS:
        raise ValueError(f"MAVS material must be one of {MAVS_MATERIALS}, got {material!r}")
    if not (cone_index is not None and math.isfinite(cone_index) and cone_index > 0):
        raise ValueError(f"MAVS cone index must be a positive number, got {cone_index!r}")


def mavs_surface(cone_index: float, material: str) -> dict[str, Any]:
    """The surface entry of a MAVS scene: ``{"Material", "Cone Index"}`` [1]_.

    Parameters
    ----------
    cone_index : float
        The soil strength [kPa]: the RCI of the critical layer for clay, the CI for sand.
    material : {"sand", "clay"}

    Returns
    -------
    dict
        ``{"Material": material, "Cone Index": <psi>}``; MAVS's scene loader
        multiplies the cone index by 6894.76 to get Pa (and, see the module
        docstring, does not pass it on to the vehicle).
    """
    _check(cone_index, material)
    return {"Material": material, "Cone Index": from_si(cone_index, "pressure", "us")}


def mavs_set_terrain_properties(cone_index: float, material: str) -> dict[str, Any]:
    """What to pass to MAVS's two ``SetTerrainProperties`` calls, in each one's unit [1]_.

    Parameters
    ----------
    cone_index : float
        The soil strength [kPa].
    material : {"sand", "clay"}

    Returns
    -------
    dict
        ``{"soil_type", "environment": {"call", "type", "strength", "unit": "Pa"},
        "vehicle": {"call", "soil_type", "soil_strength", "unit": "psi"}}``:
        ``MavsEnvironment.SetTerrainProperties`` takes Pa, ``MavsRp3d.SetTerrainProperties``
        psi (it multiplies by 6894.76).
    """
    _check(cone_index, material)
    pa = float(cone_index) * 1000.0  # kPa -> Pa
    psi = from_si(cone_index, "pressure", "us")
    return {
        "soil_type": material,
        "environment": {"call": ENV_CALL, "type": material, "strength": pa, "unit": "Pa"},
        "vehicle": {"call": VEH_CALL, "soil_type": material, "soil_strength": psi, "unit": "psi"},
    }


def _strength(results, material: str, what: str) -> tuple[float, str, list[str], list[str]]:
    """(strength [kPa], "rci" or "ci", profile ids, notes) of the selected results."""
    cis, rcis, ids, notes = [], [], [], []
    for r in results:
        ids.append(r.id)
        if r.depth is None or r.ci is None or len(r.depth) == 0:
            notes.append(f"{r.id}: the results keep no CI")
            continue
        ci = critical_layer_mean(r.depth, r.ci, *MAVS_LAYER)
        if ci is None:
            notes.append(f"{r.id}: too shallow for the critical layer 0-6 in (not extrapolated)")
            continue
        cis.append(ci)
        try:
            ri = remolding_index_of(r.metadata)
        except ValueError as exc:
            notes.append(f"{r.id}: {exc}")
            ri = None
        if ri is not None:
            rcis.append(ci * ri)
    if not cis:
        raise ValueError(f"{what}: no critical-layer CI ({'; '.join(notes) or 'no CI'})")
    if material == "clay" and len(rcis) == len(cis):
        return float(np.mean(rcis)), "rci", ids, []
    if material == "clay":
        return (
            float(np.mean(cis)),
            "ci",
            ids,
            [f"{what}: no remolding index: the clay's Cone Index is the CI, not the RCI"],
        )
    return float(np.mean(cis)), "ci", ids, []


def _select(results: PredictionResults, profile: str | None, source: str | None):
    ids = [r.id for r in results]
    if profile is None and len(results) != 1:
        raise ValueError(
            f"{source or 'results'}: {len(results)} profiles: name one (or a site) with --profile"
        )
    sel = [r for r in results if profile is None or r.id == profile]
    what = f"profile {sel[0].id}" if sel else f"site {profile}"
    if not sel:
        sel = [r for r in results if str(r.metadata.get("site")) == profile]
    if not sel:
        shown = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
        raise ValueError(f"{source or 'results'}: no profile or site {profile!r} ({shown})")
    return sel, what


def write_mavs(
    results: PredictionResults,
    out: PathLike,
    *,
    material: str,
    profile: str | None = None,
    source: str | None = None,
) -> tuple[dict[str, Any], list[str]]:
    """Write the MAVS surface entry of one profile, or of a site, to ``out``.

    The strength is the 0-6 in critical-layer mean of the profile, or the
    mean over the site's profiles (``profile`` naming a value of their
    ``site`` metadata); for clay the RCI when every profile's metadata give
    a remolding index.  The file is a MAVS scene fragment ``{"Surface Mesh":
    [{"Material", "Cone Index"}], "terracone": {...}}``; the ``terracone``
    block (which MAVS does not read) holds the provenance and
    ``set_terrain_properties`` (:func:`mavs_set_terrain_properties`), the
    values that reach MAVS's tyres.

    Returns
    -------
    (dict, list of str)
        The document written and notes for the user.
    """
    sel, what = _select(results, profile, source)
    strength, kind, ids, notes = _strength(sel, material, what)
    doc = {
        "Surface Mesh": [mavs_surface(strength, material)],
        "terracone": {
            "what": what,
            "profiles": ids,
            "cone_index_of": kind,
            "critical_layer_in": [round(v, 9) for v in from_si(MAVS_LAYER, "length", "us")],
            "set_terrain_properties": {
                **mavs_set_terrain_properties(strength, material),
                "strength_of": kind,
            },
            "source": source,
        },
    }
    Path(out).write_text(json.dumps(doc, indent=2) + "\n")
    return doc, notes

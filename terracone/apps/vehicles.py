"""Vehicle files of ``terracone mobility``: wheeled and tracked vehicles, checked on load.

A vehicle file is a JSON object (docs/mobility.md)::

    {"name": "HMMWV M1152", "kind": "wheeled", "drive": "all",
     "mobility_index_inputs": {"gross_weight": "13450 lb", "axles": 2, ...},
     "tire_deflection_ratio": 0.15,
     "wheel": {"load": "3363 lb", "diameter": "37 in", "width": "12.5 in"}}

    {"name": "M113", "kind": "tracked",
     "mobility_index_inputs": {"gross_weight": "22900 lb", "track_width": "15 in",
                               "track_contact_length": "105 in", "tracks": 2,
                               "bogies": 10, "shoe_area": "90 in2", ...}}

:func:`vehicle_from_dict` refuses every key it does not know (a misspelt
``tire_deflection_ration`` would otherwise be ignored and its default used) and
every quantity outside its physical range (a wheel load of 1e300 N, a wheel
1e-300 m across), with one line naming the file and the key.  The mobility
index is given or computed (:func:`terracone.physics.vehicle.mobility_index_wheeled`,
:func:`~terracone.physics.vehicle.mobility_index_tracked`); :meth:`Vehicle.vci`
says which vehicle cone index applies, and why none does when none does:
VCI_1 of a wheeled vehicle only with every axle powered [1]_, and no VCI_50
of a tracked vehicle (no public source of one could be opened here).

References
----------
.. [1] Priddy, J.D., Willoughby, W.E. (2006). Clarification of vehicle cone
   index with reference to mean maximum pressure. J. Terramechanics 43(2),
   85-96: "The ERDC VCI Prediction Methodology is only applicable to vehicles
   with all axles powered".
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from terracone.io.jsonkeys import FileKeyError, read_json
from terracone.physics import units as u
from terracone.physics import vehicle as phys
from terracone.resultunits import Written, field_value, from_si, quantity

__all__ = [
    "KINDS",
    "DRIVES",
    "QUANTITY_RANGES",
    "Wheel",
    "Vehicle",
    "vehicle_from_dict",
    "load_vehicle",
]

PathLike = str | os.PathLike[str]

#: Vehicle kinds: each has its own mobility index and VCI relations.
KINDS = ("wheeled", "tracked")
#: Drive configurations of a wheeled vehicle: every axle powered, or not.
DRIVES = ("all", "partial")

#: Physical ranges of the quantities of a vehicle file (SI; lo, hi, lo included).
#: Bounds of plausibility, not of a source: 1e7 N (about 1000 t) is above the
#: gross weight of any self-propelled off-road vehicle, 1e7 W above its engine,
#: wheels and tyres lie between 2 cm and 10 m across; a value outside is a unit
#: or typing error.  Each (lo, hi, lo_open).
QUANTITY_RANGES: dict[str, tuple[float, float, bool]] = {
    "gross_weight": (0.0, 1.0e7, True),
    "load": (0.0, 1.0e7, True),
    "engine_power": (0.0, 1.0e7, True),
    "diameter": (0.02, 10.0, False),
    "tire_diameter": (0.02, 10.0, False),
    "width": (0.01, 5.0, False),
    "tire_width": (0.01, 5.0, False),
    "track_width": (0.01, 5.0, False),
    "track_contact_length": (0.05, 50.0, False),
    "shoe_area": (1.0e-4, 10.0, False),
    "grouser_height": (0.0, 1.0, False),
    "ground_clearance": (0.0, 5.0, False),
}
#: Whole numbers of a vehicle file and their ranges.
COUNT_RANGES = {"axles": (1, 20), "tires": (1, 100), "tracks": (1, 16), "bogies": (1, 400)}
#: Mobility index given directly: (0, 1000] (far above any vehicle's).
MI_MAX = 1000.0

_KIND_OF = {
    "gross_weight": "force", "load": "force", "engine_power": "power", "diameter": "length",
    "tire_diameter": "length", "width": "length", "tire_width": "length",
    "track_width": "length", "track_contact_length": "length", "shoe_area": "area",
    "grouser_height": "length", "ground_clearance": "length",
}  # fmt: skip
_SI_UNIT = {"force": "N", "power": "W", "length": "m", "area": "m^2"}

#: Keys of the file, of its wheel and of its mobility-index inputs, per kind (True: required).
TOP_KEYS = {
    "wheeled": {"name": True, "kind": True, "mobility_index": False, "drive": False,
                "mobility_index_inputs": False, "tire_deflection_ratio": False, "wheel": True},
    "tracked": {"name": True, "kind": True, "mobility_index": False,
                "mobility_index_inputs": False, "wheel": False},
}  # fmt: skip
WHEEL_KEYS = {"load": True, "diameter": True, "width": True}
MI_INPUT_KEYS = {
    "wheeled": {"gross_weight": True, "axles": True, "tires": True, "tire_width": True,
                "tire_diameter": True, "ground_clearance": True, "engine_power": True,
                "transmission": False, "chains": False},
    "tracked": {"gross_weight": True, "track_width": True, "track_contact_length": True,
                "tracks": True, "bogies": True, "shoe_area": True, "grouser_height": True,
                "ground_clearance": True, "engine_power": True, "transmission": False},
}  # fmt: skip


class VehicleFileError(ValueError):
    """A bad vehicle file: one line naming the file and the key."""


def _fail(where: str, key: str | None, reason: str) -> VehicleFileError:
    return VehicleFileError(f"{where}: key {key!r}: {reason}" if key else f"{where}: {reason}")


def _check_known(d: Mapping[str, Any], keys: Mapping[str, bool], where: str, prefix: str) -> None:
    """Refuse unknown keys (with the closest known one) and missing required ones."""
    for name in d:
        if name not in keys:
            close = difflib.get_close_matches(str(name), list(keys), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise _fail(where, f"{prefix}{name}",
                        f"unknown key{hint}; known: {', '.join(keys)}")  # fmt: skip
    missing = [k for k, req in keys.items() if req and d.get(k) is None]
    if missing:
        raise _fail(where, f"{prefix}{missing[0]}", "missing")


def _quantity(d: Mapping[str, Any], key: str, where: str, prefix: str) -> float:
    """A quantity with its unit, in SI, within :data:`QUANTITY_RANGES`."""
    kind = _KIND_OF[key]
    try:
        v = u.quantity_to_si(d[key], kind)
    except ValueError as exc:
        raise _fail(where, f"{prefix}{key}", str(exc)) from None
    lo, hi, lo_open = QUANTITY_RANGES[key]
    if (v <= lo if lo_open else v < lo) or v > hi:
        unit = _SI_UNIT[kind]
        span = f"{'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}"
        raise _fail(where, f"{prefix}{key}",
                    f"{d[key]!r} = {v:.4g} {unit} is outside the physical range {span}")  # fmt: skip
    return v


def _count(d: Mapping[str, Any], key: str, where: str, prefix: str) -> int:
    v = d.get(key)
    lo, hi = COUNT_RANGES[key]
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise _fail(where, f"{prefix}{key}", f"expected a whole number in [{lo}, {hi}], got {v!r}")
    return v


def _choice(d: Mapping[str, Any], key: str, choices, default, where: str, prefix: str) -> Any:
    v = d.get(key, default)
    if isinstance(v, bool) != isinstance(default, bool) or v not in choices:
        shown = " or ".join(repr(c) for c in choices)
        raise _fail(where, f"{prefix}{key}", f"expected {shown}, got {v!r}")
    return v


@dataclass(frozen=True)
class Wheel(Written):
    """The wheel of Bekker's sinkage (SI): ``load`` [N], ``diameter`` and ``width`` [m]."""

    load: float = quantity("force")
    diameter: float = quantity("length")
    width: float = quantity("length")


NO_TRACKED_VCI50 = (
    "no VCI_50 for a tracked vehicle: no public source of the tracked-vehicle VCI_50 "
    "relation could be opened (docs/mobility.md, Not done)"
)


@dataclass(frozen=True)
class Vehicle:
    """A vehicle as ``terracone mobility`` reads it (SI).

    Attributes
    ----------
    name : str
    kind : {"wheeled", "tracked"}
    mobility_index : float
        MI [-], given or computed from the inputs of its kind.
    deflection_ratio : float or None
        Tyre deflection over section height, delta/h [-] (wheeled; default 0.15).
    wheel : Wheel or None
        The wheel of Bekker's sinkage (optional for a tracked vehicle).
    mi_from : {"given", "inputs"}
    source : str or None
        The vehicle file.
    drive : {"all", "partial"} or None
        Wheeled: whether every axle is powered (the domain of VCI_1).
    gross_weight : float or None
        Gross weight [N] when the file gives the MI inputs.
    notes : tuple of str
        What was assumed (a default drive).
    """

    name: str
    kind: str
    mobility_index: float
    deflection_ratio: float | None
    wheel: Wheel | None
    mi_from: str = "given"
    source: str | None = None
    drive: str | None = None
    gross_weight: float | None = quantity("force", default=None)
    notes: tuple[str, ...] = field(default_factory=tuple)

    def vci_of(self, passes: int) -> tuple[float | None, str | None]:
        """(VCI [kPa] of the vehicle for ``passes``, None) or (None, why none applies)."""
        mi = self.mobility_index
        if self.kind == "tracked":
            if passes == 1:
                return float(phys.vci1_tracked(mi)), None
            return None, NO_TRACKED_VCI50
        if passes == 1:
            if self.drive != "all":
                return None, (
                    "no VCI_1: the VCI_1 relation of Priddy and Willoughby (2006) applies only "
                    f"to vehicles with all axles powered, and this vehicle's drive is {self.drive!r}"
                )
            return float(phys.vci1_priddy_willoughby(mi, self.deflection_ratio)), None
        return float(phys.vci50_rula_nuttall(mi)), None

    def vci(self, passes: int) -> float | None:
        """VCI [kPa] for ``passes`` (1 or 50), or None outside the relations' domain."""
        return self.vci_of(passes)[0]

    def as_dict(self, units: str = "si", passes: int = 1) -> dict[str, Any]:
        """The ``vehicle`` block of a mobility document."""
        vci, why = self.vci_of(passes)
        ratio = self.deflection_ratio
        return {
            "name": self.name,
            "kind": self.kind,
            "drive": self.drive,
            "mi": self.mobility_index,
            "mobility_index": self.mobility_index,
            "mobility_index_from": self.mi_from,
            "gross_weight": field_value(self, "gross_weight", units),
            "tire_deflection_ratio": ratio,
            "dcf": None if ratio is None else float(phys.deflection_correction_factor(ratio)),
            "passes": passes,
            "vci": from_si(vci, "pressure", units),
            "vci_note": why,
            "wheel": None if self.wheel is None else self.wheel.as_dict(units),
            "notes": list(self.notes),
            "source": self.source,
        }


def _mi_inputs(d: Mapping[str, Any], kind: str, where: str) -> tuple[float, float]:
    """(MI, gross weight [N]) from ``mobility_index_inputs``."""
    inputs = d["mobility_index_inputs"]
    p = "mobility_index_inputs."
    if not isinstance(inputs, Mapping):
        raise _fail(where, p[:-1], f"expected a JSON object, got {inputs!r}")
    _check_known(inputs, MI_INPUT_KEYS[kind], where, p)
    q = {k: _quantity(inputs, k, where, p) for k in MI_INPUT_KEYS[kind] if k in _KIND_OF}
    manual = _choice(inputs, "transmission", ("automatic", "manual"), "automatic", where, p)
    if kind == "wheeled":
        chains = _choice(inputs, "chains", (False, True), False, where, p)
        mi = phys.mobility_index_wheeled(
            q["gross_weight"], axles=_count(inputs, "axles", where, p),
            tires=_count(inputs, "tires", where, p), tire_width=q["tire_width"],
            tire_diameter=q["tire_diameter"], ground_clearance=q["ground_clearance"],
            engine_power=q["engine_power"], manual_transmission=manual == "manual", chains=chains,
        )  # fmt: skip
    else:
        mi = phys.mobility_index_tracked(
            q["gross_weight"], track_width=q["track_width"],
            track_contact_length=q["track_contact_length"],
            tracks=_count(inputs, "tracks", where, p), bogies=_count(inputs, "bogies", where, p),
            shoe_area=q["shoe_area"], grouser_height=q["grouser_height"],
            ground_clearance=q["ground_clearance"], engine_power=q["engine_power"],
            manual_transmission=manual == "manual",
        )  # fmt: skip
    if not (math.isfinite(mi) and 0 < mi <= MI_MAX):
        raise _fail(where, p[:-1], f"the inputs give MI = {mi:.4g}, not a mobility index in "
                                   f"(0, {MI_MAX:g}]")  # fmt: skip
    return mi, q["gross_weight"]


def _mobility_index(d: Mapping[str, Any], kind: str, where: str) -> tuple[float, str, float | None]:
    """(MI, "given" or "inputs", gross weight [N] or None)."""
    if d.get("mobility_index") is not None:
        mi = d["mobility_index"]
        ok = not isinstance(mi, bool) and isinstance(mi, int | float)
        if not (ok and math.isfinite(mi) and 0 < mi <= MI_MAX):
            raise _fail(
                where, "mobility_index", f"expected a number in (0, {MI_MAX:g}], got {mi!r}"
            )
        return float(mi), "given", None
    if d.get("mobility_index_inputs") is None:
        need = ", ".join(k for k, req in MI_INPUT_KEYS[kind].items() if req)
        raise _fail(where, None, f"give 'mobility_index' or 'mobility_index_inputs' ({need})")
    mi, weight = _mi_inputs(d, kind, where)
    return mi, "inputs", weight


def _wheel(d: Mapping[str, Any], where: str) -> Wheel | None:
    wheel = d.get("wheel")
    if wheel is None:
        return None
    if not isinstance(wheel, Mapping):
        raise _fail(where, "wheel", f"expected {{'load', 'diameter', 'width'}}, got {wheel!r}")
    _check_known(wheel, WHEEL_KEYS, where, "wheel.")
    return Wheel(*(_quantity(wheel, k, where, "wheel.") for k in ("load", "diameter", "width")))


def vehicle_from_dict(d: Any, source: str | None = None) -> Vehicle:
    """A :class:`Vehicle` from the JSON object of a vehicle file (docs/mobility.md).

    Keys: ``name``, ``kind`` ("wheeled" or "tracked"), ``mobility_index`` or
    ``mobility_index_inputs`` (of the kind: :data:`MI_INPUT_KEYS`), and for a
    wheeled vehicle ``drive`` ("all", the default, or "partial"),
    ``tire_deflection_ratio`` (default 0.15) and ``wheel`` {``load``,
    ``diameter``, ``width``} (optional for a tracked vehicle).  Quantities are
    strings with a unit (``"10 kN"``, ``"40 in"``, ``"190 hp"``, ``"90 in2"``)
    or bare numbers in SI (N, m, W, m^2), within :data:`QUANTITY_RANGES`.

    Raises
    ------
    ValueError
        An unknown or missing key, a unitless or out-of-range quantity; one
        line naming the file and the key.
    """
    where = f"vehicle file {source}" if source else "vehicle"
    if not isinstance(d, Mapping):
        raise _fail(where, None, "expected a JSON object")
    kind = d.get("kind")
    if kind not in KINDS:
        raise _fail(where, "kind", f"expected 'wheeled' or 'tracked', got {kind!r}")
    _check_known(d, TOP_KEYS[kind], where, "")
    name = d.get("name")
    if not isinstance(name, str) or not name.strip():
        raise _fail(where, "name", f"expected the vehicle's name, got {name!r}")
    mi, mi_from, weight = _mobility_index(d, kind, where)
    wheel, notes = _wheel(d, where), []
    if kind == "tracked":
        return Vehicle(name.strip(), kind, mi, None, wheel, mi_from, source, None, weight)
    ratio = d.get("tire_deflection_ratio", phys.NOMINAL_DEFLECTION)
    if isinstance(ratio, bool) or not isinstance(ratio, int | float) or not 0 < ratio < 1:
        raise _fail(where, "tire_deflection_ratio", f"delta/h in (0, 1) (e.g. 0.15), got {ratio!r}")
    drive = _choice(d, "drive", DRIVES, "all", where, "")
    if "drive" not in d:
        notes.append("drive not given: assumed 'all' (every axle powered, the domain of VCI_1)")
    return Vehicle(name.strip(), kind, mi, float(ratio), wheel, mi_from, source, drive, weight,
                   tuple(notes))  # fmt: skip


def load_vehicle(path: PathLike) -> Vehicle:
    """Read a vehicle file (JSON, :func:`vehicle_from_dict`)."""
    try:
        d = read_json(path)
    except FileKeyError as exc:
        raise VehicleFileError(f"vehicle file {Path(path)}: {exc.reason}") from None
    return vehicle_from_dict(d, str(Path(path)))

"""What the measured terrain means for a vehicle: ``terracone mobility``.

For every profile of a prediction (``predict`` JSON or Parquet, a ``batch``
directory, read by :func:`terracone.result.read_results`) and a vehicle
(:func:`load_vehicle`):

* **NRMM** [1]_ [2]_: the mean CI of the critical layer (0-6 in for one
  pass, 6-12 in for fifty, of fine-grained soils; :func:`critical_layer_mean`,
  the depth average of the profile linearly interpolated between readings),
  the rating cone index RCI = CI x RI when a remolding index is known, the
  vehicle cone index VCI_1 or VCI_50 from the mobility index, and GO when
  RCI >= VCI, with the margin RCI - VCI;
* **Bekker-Wong** [3]_ [4]_: the sinkage and compaction resistance of the
  vehicle's wheel from the profile's kc, kphi and n, with the 90% band of
  the posterior draws when the results keep them (``predict --uncertainty
  --json``).  Under the bounds prior (no calibration) kc and kphi are set by
  the prior, and the band says so.

Profiles are grouped into sites (a metadata column, ``site`` by default, or
the columns given) and each site gets the mean of its profiles' critical-layer
CI and RCI, its own GO/NO-GO and the median wheel sinkage.  A profile that
cannot be evaluated is recorded with the reason; a profile too shallow for the
critical layer is marked, never extrapolated.  :func:`mavs_surface` writes the
surface entry of a MAVS scene (``Material``, ``Cone Index`` in psi) [5]_.

The formulas are in :mod:`terracone.physics.vehicle`; ``docs/mobility.md``
works an example by hand.

References
----------
.. [1] Priddy, J.D., Willoughby, W.E. (2006). Clarification of vehicle cone
   index with reference to mean maximum pressure. J. Terramechanics 43(2),
   85-96, doi:10.1016/j.jterra.2004.10.001.
.. [2] Rula, A.A., Nuttall, C.J. (1971). An analysis of ground mobility
   models (ANAMOB). WES Technical Report M-71-4; as tabulated in [4]_.
.. [3] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
   University of Michigan Press.
.. [4] Wong, J.Y. (2008). Theory of Ground Vehicles, 4th ed. Wiley, ch. 2.
.. [5] Mississippi State University Autonomous Vehicle Simulator (MAVS):
   scene files, ``"Surface Mesh"`` entries read ``"Material"`` (dry, wet,
   ice, snow, clay or sand) and ``"Cone Index"`` in psi.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from terracone.data import CIProfile, InputError
from terracone.physics import units as u
from terracone.physics import vehicle as phys
from terracone.physics.metrics import finite_median
from terracone.result import PredictionResult, PredictionResults

__all__ = [
    "SCHEMA",
    "CRITICAL_LAYERS",
    "MAVS_MATERIALS",
    "Wheel",
    "Vehicle",
    "ProfileMobility",
    "SiteMobility",
    "MobilityRun",
    "vehicle_from_dict",
    "load_vehicle",
    "critical_layer_mean",
    "remolding_index_of",
    "evaluate_profile",
    "evaluate_mobility",
    "mavs_surface",
    "write_mavs",
    "ci_profiles_by_id",
]

PathLike = str | os.PathLike[str]

#: Name and version of the document ``terracone mobility --json`` writes.
SCHEMA = "terracone.mobility/1"
#: Critical layer (top, bottom) [m] of fine-grained soils by passes [1], [4].
CRITICAL_LAYERS = {1: (0.0, 6 * u.INCH), 50: (6 * u.INCH, 12 * u.INCH)}
#: Surface types of MAVS's tyre-terrain model; clay and sand read the cone index [5].
MAVS_MATERIALS = ("sand", "clay")
#: Metadata keys read as the remolding index (case ignored).
RI_KEYS = ("ri", "remolding_index", "remolding index")
#: Wheel diameter [m] and sinkage fraction of D within which [4] finds z0 acceptable.
BEKKER_MIN_DIAMETER = 0.5
BEKKER_MAX_SINKAGE = 1.0 / 6.0
NO_CALIBRATION_NOTE = (
    "no calibration: kc and kphi are set by the bounds prior (phic trades against their scale), "
    "so the wheel-sinkage band is set by the prior, not a calibrated 90% interval; give a "
    "calibration (predict --calibration or --prior terrain:NAME) for calibrated bands"
)


# ---------------------------------------------------------------------------
# the vehicle file
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Wheel:
    """The wheel of Bekker's sinkage (SI): ``load`` [N], ``diameter`` and ``width`` [m]."""

    load: float
    diameter: float
    width: float

    def as_dict(self, units: str = "si") -> dict[str, float]:
        """``{"load", "diameter", "width"}`` in a unit system (N, m or lbf, in)."""
        return {
            "load": float(u.force_from_si(self.load, units)),
            "diameter": float(u.length_from_si(self.diameter, units)),
            "width": float(u.length_from_si(self.width, units)),
        }


@dataclass(frozen=True)
class Vehicle:
    """A vehicle as ``terracone mobility`` reads it (SI).

    Attributes
    ----------
    name : str
    kind : {"wheeled"}
    mobility_index : float
        MI [-], given or computed by :func:`~terracone.physics.vehicle.mobility_index_wheeled`.
    deflection_ratio : float
        Tyre deflection over section height, delta/h [-] (default 0.15).
    wheel : Wheel
    mi_from : {"given", "inputs"}
        Whether MI was given or computed from its inputs.
    source : str or None
        The vehicle file.
    """

    name: str
    kind: str
    mobility_index: float
    deflection_ratio: float
    wheel: Wheel
    mi_from: str = "given"
    source: str | None = None

    def vci(self, passes: int) -> float:
        """VCI_1 (with the DCF) or VCI_50 [kPa] of the vehicle [1]_ [2]_."""
        if passes == 1:
            return float(phys.vci1_priddy_willoughby(self.mobility_index, self.deflection_ratio))
        return float(phys.vci50_rula_nuttall(self.mobility_index))

    def as_dict(self, units: str = "si", passes: int = 1) -> dict[str, Any]:
        """The ``vehicle`` block of a mobility document."""
        return {
            "name": self.name,
            "kind": self.kind,
            "mobility_index": self.mobility_index,
            "mobility_index_from": self.mi_from,
            "tire_deflection_ratio": self.deflection_ratio,
            "dcf": float(phys.deflection_correction_factor(self.deflection_ratio)),
            "passes": passes,
            "vci": float(u.pressure_from_si(self.vci(passes), units)),
            "wheel": self.wheel.as_dict(units),
            "source": self.source,
        }


#: Inputs of the wheeled-vehicle MI formula: key -> (kind, required).
MI_INPUTS = {
    "gross_weight": ("force", True),
    "axles": ("count", True),
    "tires": ("count", True),
    "tire_width": ("length", True),
    "tire_diameter": ("length", True),
    "ground_clearance": ("length", True),
    "engine_power": ("power", True),
    "transmission": ("choice", False),
    "chains": ("flag", False),
}


_EXAMPLES = {"length": "'40 in'", "force": "'10 kN'", "power": "'190 hp'"}


def _quantity(d: Mapping[str, Any], key: str, kind: str, where: str) -> float:
    if key not in d or d[key] is None:
        raise ValueError(f"{where}: missing key {key!r} (a {kind} such as {_EXAMPLES[kind]})")
    try:
        v = u.quantity_to_si(d[key], kind)
    except ValueError as exc:
        raise ValueError(f"{where}: key {key!r}: {exc}") from None
    if not v > 0:
        raise ValueError(f"{where}: key {key!r}: must be > 0, got {d[key]!r}")
    return v


def _count(d: Mapping[str, Any], key: str, where: str) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ValueError(f"{where}: key {key!r}: expected a whole number >= 1, got {v!r}")
    return v


def _mobility_index(d: Mapping[str, Any], where: str) -> tuple[float, str]:
    """MI given (``mobility_index``) or computed from ``mobility_index_inputs``."""
    if d.get("mobility_index") is not None:
        mi = d["mobility_index"]
        if isinstance(mi, bool) or not isinstance(mi, int | float) or not mi > 0:
            raise ValueError(f"{where}: key 'mobility_index': expected a number > 0, got {mi!r}")
        return float(mi), "given"
    inputs = d.get("mobility_index_inputs")
    if not isinstance(inputs, Mapping):
        raise ValueError(
            f"{where}: give 'mobility_index' or 'mobility_index_inputs' "
            f"({', '.join(k for k, (_, req) in MI_INPUTS.items() if req)})"
        )
    w = f"{where}: mobility_index_inputs"
    unknown = sorted(set(inputs) - set(MI_INPUTS))
    if unknown:
        raise ValueError(f"{w}: unknown key(s) {unknown} (known: {', '.join(MI_INPUTS)})")
    missing = [k for k, (_, req) in MI_INPUTS.items() if req and inputs.get(k) is None]
    if missing:
        raise ValueError(f"{w}: missing key(s) {', '.join(repr(k) for k in missing)}")
    trans = inputs.get("transmission", "automatic")
    if trans not in ("automatic", "manual"):
        raise ValueError(f"{w}: key 'transmission': 'automatic' or 'manual', got {trans!r}")
    chains = inputs.get("chains", False)
    if not isinstance(chains, bool):
        raise ValueError(f"{w}: key 'chains': true or false, got {chains!r}")
    q = {k: _quantity(inputs, k, kind, w) for k, (kind, _) in MI_INPUTS.items() if kind in
         ("force", "length", "power") and k != "ground_clearance"}  # fmt: skip
    clearance = inputs.get("ground_clearance")
    q["ground_clearance"] = (
        0.0 if clearance in (0, "0") else _quantity(inputs, "ground_clearance", "length", w)
    )
    mi = phys.mobility_index_wheeled(
        q["gross_weight"], axles=_count(inputs, "axles", w), tires=_count(inputs, "tires", w),
        tire_width=q["tire_width"], tire_diameter=q["tire_diameter"],
        ground_clearance=q["ground_clearance"], engine_power=q["engine_power"],
        manual_transmission=trans == "manual", chains=chains,
    )  # fmt: skip
    if not mi > 0:
        raise ValueError(f"{w}: the inputs give MI = {mi:.3g}, not a positive mobility index")
    return mi, "inputs"


def vehicle_from_dict(d: Any, source: str | None = None) -> Vehicle:
    """A :class:`Vehicle` from the JSON object of a vehicle file.

    Keys: ``name``, ``kind`` ("wheeled"), ``mobility_index`` or
    ``mobility_index_inputs`` (``gross_weight``, ``axles``, ``tires``,
    ``tire_width``, ``tire_diameter``, ``ground_clearance``, ``engine_power``,
    optional ``transmission`` "automatic"/"manual" and ``chains``),
    ``tire_deflection_ratio`` (default 0.15) and ``wheel`` {``load``,
    ``diameter``, ``width``}.  Quantities are strings with a unit (``"10 kN"``,
    ``"40 in"``, ``"190 hp"``) or bare numbers in SI (N, m, W).

    Raises
    ------
    ValueError
        A missing or unitless field, or a value out of range; the message
        names the file and the key.
    """
    where = f"vehicle file {source}" if source else "vehicle"
    if not isinstance(d, Mapping):
        raise ValueError(f"{where}: expected a JSON object")
    name = d.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"{where}: missing key 'name' (the vehicle's name)")
    kind = d.get("kind")
    if kind != "wheeled":
        raise ValueError(
            f"{where}: key 'kind': only 'wheeled' vehicles are supported (got {kind!r}); the "
            "tracked-vehicle MI and VCI formulas are not implemented (docs/mobility.md)"
        )
    mi, mi_from = _mobility_index(d, where)
    ratio = d.get("tire_deflection_ratio", phys.NOMINAL_DEFLECTION)
    if isinstance(ratio, bool) or not isinstance(ratio, int | float) or not 0 < ratio < 1:
        raise ValueError(
            f"{where}: key 'tire_deflection_ratio': delta/h in (0, 1) (e.g. 0.15), got {ratio!r}"
        )
    wheel = d.get("wheel")
    if not isinstance(wheel, Mapping):
        raise ValueError(f"{where}: missing key 'wheel' ({{'load', 'diameter', 'width'}})")
    ww = f"{where}: wheel"
    w = Wheel(
        load=_quantity(wheel, "load", "force", ww),
        diameter=_quantity(wheel, "diameter", "length", ww),
        width=_quantity(wheel, "width", "length", ww),
    )
    return Vehicle(name.strip(), kind, mi, float(ratio), w, mi_from, source)


def load_vehicle(path: PathLike) -> Vehicle:
    """Read a vehicle file (JSON, :func:`vehicle_from_dict`)."""
    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"vehicle file {p}: cannot read JSON ({exc})") from exc
    return vehicle_from_dict(d, str(p))


# ---------------------------------------------------------------------------
# one profile
# ---------------------------------------------------------------------------


def critical_layer_mean(
    depth: Sequence[float], ci: Sequence[float], top: float, bottom: float
) -> float | None:
    """Mean CI of the layer ``top``-``bottom`` [kPa], or None when the profile does not span it.

    The depth average of the profile linearly interpolated between its
    readings: the integral of CI over the layer (trapezoidal rule, with CI
    interpolated at ``top`` and ``bottom``) divided by its thickness.  It
    does not depend on the spacing of the readings.  A profile whose
    readings do not reach from ``top`` to ``bottom`` gives None (too
    shallow; nothing is extrapolated).

    Parameters
    ----------
    depth : sequence of float
        Depths [m], increasing.
    ci : sequence of float
        Cone index [kPa].
    top, bottom : float
        The layer [m], top < bottom.
    """
    z = np.asarray(depth, dtype=float)
    c = np.asarray(ci, dtype=float)
    if not top < bottom:
        raise ValueError(f"critical layer: top must be above bottom, got {top} and {bottom}")
    if z.size < 2 or z[0] > top or z[-1] < bottom:
        return None
    inside = (z > top) & (z < bottom)
    zz = np.concatenate([[top], z[inside], [bottom]])
    cc = np.concatenate([[np.interp(top, z, c)], c[inside], [np.interp(bottom, z, c)]])
    return float(np.trapezoid(cc, zz) / (bottom - top))


def remolding_index_of(metadata: Mapping[str, Any]) -> float | None:
    """The remolding index of a profile's metadata (``RI``, ``remolding_index``), or None.

    Raises
    ------
    ValueError
        A value that is not a number in (0, 2].
    """
    lower = {str(k).strip().lower(): (k, v) for k, v in metadata.items()}
    for key in RI_KEYS:
        if key in lower and lower[key][1] is not None and str(lower[key][1]).strip() != "":
            name, v = lower[key]
            try:
                ri = float(v)
            except (TypeError, ValueError):
                raise ValueError(
                    f"metadata {name!r}: remolding index {v!r} is not a number"
                ) from None
            if not 0 < ri <= 2:
                raise ValueError(f"metadata {name!r}: remolding index {ri:g} outside (0, 2]")
            return ri
    return None


@dataclass
class ProfileMobility:
    """One profile's mobility (SI inside).

    Attributes
    ----------
    id : str
    status : {"ok", "error"}
        "error": the profile was not fitted (``error`` says why); its CI may
        still give an RCI.
    error : str or None
    site : str or None
        The profile's site (the grouping columns), when grouped.
    layer : (float, float)
        Critical layer (top, bottom) [m].
    layer_status : {"ok", "too shallow", "no ci"}
        Whether the critical-layer CI was computed: "too shallow" when the
        readings do not span the layer, "no ci" when the results keep none.
    ci, ri, rci, vci : float or None
        Critical-layer mean CI [kPa], remolding index [-], RCI [kPa], VCI [kPa].
    go : bool or None
        RCI >= VCI; None when RCI is missing (``notes`` says why).
    margin : float or None
        RCI - VCI [kPa].
    sinkage, resistance : float or None
        Wheel sinkage [m] and compaction resistance [N].
    band : dict or None
        ``{"level", "sinkage": (lo, hi), "resistance": (lo, hi), "label"}``
        from the posterior draws; label "posterior" or "set by prior".
    notes : list of str
    metadata : dict
    """

    id: str
    status: str
    error: str | None = None
    site: str | None = None
    layer: tuple[float, float] = (0.0, 0.0)
    layer_status: str = "ok"
    ci: float | None = None
    ri: float | None = None
    rci: float | None = None
    vci: float | None = None
    go: bool | None = None
    margin: float | None = None
    sinkage: float | None = None
    resistance: float | None = None
    band: dict[str, Any] | None = None
    notes: list[str] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)
    draws: np.ndarray | None = field(default=None, repr=False)
    deepest: float | None = field(default=None, repr=False)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """One profile of the mobility document (``--json``), in ``units``."""
        return {
            "id": self.id,
            "status": self.status,
            "error": self.error,
            "site": self.site,
            "critical_layer": {
                **_layer_dict(self.layer, self.ci, self.ri, self.rci, units),
                "status": self.layer_status,
            },
            "vci": _p(self.vci, units),
            "go": self.go,
            "margin": _p(self.margin, units),
            "wheel": _wheel_dict(self.sinkage, self.resistance, self.band, units),
            "notes": list(self.notes),
            "metadata": dict(self.metadata),
        }


def _p(v: float | None, units: str) -> float | None:
    return None if v is None else float(u.pressure_from_si(v, units))


def _layer_dict(layer, ci, ri, rci, units: str) -> dict[str, Any]:
    return {
        "top": float(u.length_from_si(layer[0], units)),
        "bottom": float(u.length_from_si(layer[1], units)),
        "ci": _p(ci, units),
        "ri": ri,
        "rci": _p(rci, units),
    }


def _finite(v: float | None) -> float | None:
    return v if v is not None and math.isfinite(v) else None


def _wheel_dict(sinkage, resistance, band, units: str) -> dict[str, Any]:
    z = _finite(sinkage)
    r = _finite(resistance)
    d: dict[str, Any] = {
        "sinkage": None if z is None else float(u.length_from_si(z, units)),
        "resistance": None if r is None else float(u.force_from_si(r, units)),
    }
    if band is not None:
        for i, end in enumerate(("lo", "hi")):
            d[end] = {
                "sinkage": float(u.length_from_si(band["sinkage"][i], units)),
                "resistance": float(u.force_from_si(band["resistance"][i], units)),
            }
        d["level"] = band["level"]
        d["band"] = band["label"]
    return d


def _wheel(wheel: Wheel, kc, kphi, n) -> tuple[np.ndarray, np.ndarray]:
    z = phys.sinkage_rigid_wheel_bekker(
        wheel.load, diameter=wheel.diameter, width=wheel.width, kc=kc, kphi=kphi, n=n
    )
    return z, phys.compaction_resistance_bekker(z, width=wheel.width, kc=kc, kphi=kphi, n=n)


def _wheel_notes(wheel: Wheel, z: float) -> list[str]:
    notes = []
    if not math.isfinite(z):
        notes.append("kc + b kphi = 0: the terrain bears no wheel (infinite sinkage)")
    elif z > BEKKER_MAX_SINKAGE * wheel.diameter:
        notes.append(
            f"wheel sinkage above D/6 = {BEKKER_MAX_SINKAGE * wheel.diameter:.3g} m: Bekker's "
            "rigid-wheel sinkage is not reliable there (Wong 2008, ch. 2)"
        )
    if wheel.diameter < BEKKER_MIN_DIAMETER:
        notes.append(
            "wheel diameter below 50 cm: Bekker's rigid-wheel sinkage is less reliable "
            "(Wong 2008, ch. 2)"
        )
    return notes


def _band(post: Any, wheel: Wheel, level: float, label: str) -> tuple[dict | None, Any, str]:
    """The wheel band from the posterior draws, the draws, and a note when there is none."""
    samples = None if post is None else post.samples
    if samples is None:
        return (
            None,
            None,
            (
                "the results keep no posterior draws (predict --uncertainty --json writes them): "
                "no band for the wheel"
            ),
        )
    s = np.asarray(samples, dtype=float)
    z, r = _wheel(wheel, s[:, 0], s[:, 1], s[:, 2])
    q = [(1 - level) / 2, (1 + level) / 2]
    zq, rq = np.quantile(z, q), np.quantile(r, q)
    band = {
        "level": level,
        "sinkage": (float(zq[0]), float(zq[1])),
        "resistance": (float(rq[0]), float(rq[1])),
        "label": label,
    }
    return band, np.column_stack([z, r]), ""


def _profile_ci(r: PredictionResult, ci_profiles: Mapping[str, CIProfile] | None):
    if r.depth is not None and r.ci is not None and len(r.depth) > 0:
        return r.depth, r.ci
    if ci_profiles is not None and r.id in ci_profiles:
        p = ci_profiles[r.id]
        return p.depth, p.ci
    return None, None


NO_CI_NOTE = (
    "the results keep no CI (a batch Parquet table): the critical-layer CI is not computed; "
    "give the CI file (--ci)"
)


def _nrmm(
    out: ProfileMobility,
    depth,
    ci,
    ri_option: float | None,
    vci: float,
    no_ci_note: str = NO_CI_NOTE,
) -> None:
    """Critical-layer CI, RI, RCI, GO and margin of one profile, in place."""
    top, bottom = out.layer
    if depth is None:
        out.layer_status = "no ci"
        out.notes.append(no_ci_note)
        return
    out.deepest = float(np.max(depth)) if len(depth) else None
    out.ci = critical_layer_mean(depth, ci, top, bottom)
    if out.ci is None:
        out.layer_status = "too shallow"
        out.notes.append(
            f"too shallow for the critical layer {top:.4g}-{bottom:.4g} m: readings span "
            f"{float(np.min(depth)):.4g}-{float(np.max(depth)):.4g} m (not extrapolated)"
        )
        return
    try:
        ri = ri_option if ri_option is not None else remolding_index_of(out.metadata)
    except ValueError as exc:
        out.notes.append(f"RCI not computed: {exc}")
        return
    if ri is None:
        out.notes.append(
            "no remolding index (--remolding-index or an RI column in the metadata): RCI, "
            "GO/NO-GO and the margin are not computed"
        )
        return
    out.ri = ri
    out.rci = float(phys.rating_cone_index(out.ci, ri))
    out.go = out.rci >= vci
    out.margin = out.rci - vci


def evaluate_profile(
    r: PredictionResult,
    vehicle: Vehicle,
    *,
    passes: int = 1,
    layer: tuple[float, float] | None = None,
    remolding_index: float | None = None,
    ci_profiles: Mapping[str, CIProfile] | None = None,
    level: float = 0.9,
    band_label: str = "posterior",
) -> ProfileMobility:
    """The mobility of one result: NRMM go/no-go and the wheel (SI).

    Parameters
    ----------
    r : PredictionResult
        A result as :func:`terracone.result.read_results` gives it.
    vehicle : Vehicle
    passes : {1, 50}
        One pass (VCI_1, layer 0-6 in) or fifty (VCI_50, layer 6-12 in).
    layer : (float, float), optional
        Critical layer (top, bottom) [m] in place of that of ``passes``.
    remolding_index : float, optional
        RI of every profile; None reads it from the metadata (``RI``).
    ci_profiles : mapping, optional
        CI profiles by id, for results that keep no CI (batch Parquet).
    level : float
        Level of the wheel band [-].
    band_label : {"posterior", "set by prior"}
        How the band is labelled (:func:`evaluate_mobility` sets it from the prior).

    Returns
    -------
    ProfileMobility
    """
    top_bottom = layer or CRITICAL_LAYERS[passes]
    out = ProfileMobility(r.id, r.status, r.error, layer=top_bottom, metadata=dict(r.metadata))
    out.vci = vehicle.vci(passes)
    depth, ci = _profile_ci(r, ci_profiles)
    note = NO_CI_NOTE if ci_profiles is None else "no CI: the profile is not in the CI file (--ci)"
    _nrmm(out, depth, ci, remolding_index, out.vci, note)
    if not r.ok or r.params is None:
        out.notes.append(f"not fitted ({r.error or r.message or 'no parameters'}): no wheel")
        return out
    p = r.params
    z, rc = _wheel(vehicle.wheel, p.kc, p.kphi, p.n)
    out.sinkage, out.resistance = float(z), float(rc)
    out.notes += _wheel_notes(vehicle.wheel, out.sinkage)
    if r.posterior is not None:
        out.band, out.draws, note = _band(r.posterior, vehicle.wheel, level, band_label)
        if note:
            out.notes.append(note)
    return out


# ---------------------------------------------------------------------------
# many profiles and their sites
# ---------------------------------------------------------------------------


@dataclass
class SiteMobility:
    """A site's mobility: its profiles pooled (SI).

    ``ci`` and ``rci`` are the means over the profiles that have them, ``go``
    and ``margin`` compare the site RCI with VCI, ``go_fraction`` is the
    share of the decided profiles that go; ``sinkage`` and ``resistance``
    are the medians of the profiles', ``band`` the quantiles of their pooled
    posterior draws (when every profile has draws).
    """

    site: str
    profiles: list[str]
    layer: tuple[float, float]
    ci: float | None = None
    rci: float | None = None
    vci: float | None = None
    go: bool | None = None
    margin: float | None = None
    go_fraction: float | None = None
    sinkage: float | None = None
    resistance: float | None = None
    band: dict[str, Any] | None = None

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """One site of the mobility document, in ``units``."""
        return {
            "site": self.site,
            "profiles": list(self.profiles),
            "n_profiles": len(self.profiles),
            "critical_layer": _layer_dict(self.layer, self.ci, None, self.rci, units),
            "vci": _p(self.vci, units),
            "go": self.go,
            "margin": _p(self.margin, units),
            "go_fraction": self.go_fraction,
            "wheel": _wheel_dict(self.sinkage, self.resistance, self.band, units),
        }


def _mean(values: Sequence[float | None]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def _site(name: str, members: list[ProfileMobility], vci: float, level: float) -> SiteMobility:
    s = SiteMobility(name, [m.id for m in members], members[0].layer, vci=vci)
    s.ci = _mean([m.ci for m in members])
    s.rci = _mean([m.rci for m in members])
    if s.rci is not None:
        s.go, s.margin = s.rci >= vci, s.rci - vci
    decided = [m.go for m in members if m.go is not None]
    s.go_fraction = sum(decided) / len(decided) if decided else None
    s.sinkage = finite_median([m.sinkage for m in members])
    s.resistance = finite_median([m.resistance for m in members])
    if members and all(m.draws is not None for m in members):
        pooled = np.concatenate([m.draws for m in members])
        q = [(1 - level) / 2, (1 + level) / 2]
        zq, rq = np.quantile(pooled[:, 0], q), np.quantile(pooled[:, 1], q)
        s.band = {
            "level": level,
            "sinkage": (float(zq[0]), float(zq[1])),
            "resistance": (float(rq[0]), float(rq[1])),
            "label": members[0].band["label"] if members[0].band else "posterior",
        }
    return s


def _group_key(metadata: Mapping[str, Any], by: Sequence[str]) -> str | None:
    vals = [metadata.get(k) for k in by]
    if any(v is None or (isinstance(v, float) and v != v) or str(v).strip() == "" for v in vals):
        return None
    return "/".join(str(v) for v in vals)


@dataclass
class MobilityRun:
    """The mobility of many profiles: the document ``terracone mobility`` writes.

    Attributes
    ----------
    vehicle : Vehicle
    passes : int
    layer : (float, float)
        Critical layer [m].
    profiles : list of ProfileMobility
    sites : list of SiteMobility
    by : list of str
        Metadata columns naming the sites (empty: no sites).
    settings : dict
        What was asked (remolding index, level, calibration, prior).
    notes : list of str
    """

    vehicle: Vehicle
    passes: int
    layer: tuple[float, float]
    profiles: list[ProfileMobility]
    sites: list[SiteMobility] = field(default_factory=list)
    by: list[str] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def evaluated_any(self) -> bool:
        """Whether some profile has a GO/NO-GO or a wheel sinkage."""
        return any(p.go is not None or p.sinkage is not None for p in self.profiles)

    def as_dict(self, units: str = "si", *, input: str | None = None) -> dict[str, Any]:
        """The JSON document (schema :data:`SCHEMA`, docs/mobility.md) in ``units``."""
        from terracone import __version__

        units = u.check_system(units)
        top, bottom = self.layer
        settings = {
            **self.settings,
            "passes": self.passes,
            "layer": {
                "top": float(u.length_from_si(top, units)),
                "bottom": float(u.length_from_si(bottom, units)),
            },
            "by": list(self.by),
            "units": units,
        }
        return {
            "schema": SCHEMA,
            "schema_version": 1,
            "terracone": __version__,
            "command": "mobility",
            "input": input,
            "settings": settings,
            "units": units,
            "vehicle": self.vehicle.as_dict(units, self.passes),
            "profiles": [p.as_dict(units) for p in self.profiles],
            "sites": [s.as_dict(units) for s in self.sites],
            "notes": list(self.notes),
        }


def _prior_of(results: PredictionResults) -> tuple[str, str]:
    """(prior, band label): "bounds" without a calibration, then bands are set by the prior."""
    priors = {r.posterior.prior for r in results if r.posterior is not None}
    priors.discard(None)
    if priors:
        prior = "bounds" if "bounds" in priors else sorted(priors)[0]
    else:
        prior = "bounds" if results.settings.get("calibration") is None else "calibration"
    return prior, "set by prior" if prior == "bounds" else "posterior"


def _check_layer(profiles: list[ProfileMobility], layer, source: str | None) -> None:
    """A layer deeper than every profile with CI is an error, not a column of 'too shallow'."""
    with_ci = [p for p in profiles if p.layer_status != "no ci"]
    if with_ci and all(p.layer_status == "too shallow" for p in with_ci):
        where = f"{source}: " if source else ""
        deepest = max(p.deepest for p in with_ci if p.deepest is not None)
        raise ValueError(
            f"{where}critical layer {layer[0]:.4g}-{layer[1]:.4g} m is deeper than every profile "
            f"(the deepest reading is at {deepest:.4g} m)"
        )


def evaluate_mobility(
    results: PredictionResults,
    vehicle: Vehicle,
    *,
    passes: int = 1,
    layer: tuple[float, float] | None = None,
    remolding_index: float | None = None,
    by: Sequence[str] | None = None,
    ci_profiles: Mapping[str, CIProfile] | None = None,
    level: float = 0.9,
    source: str | None = None,
    progress: Any = None,
) -> MobilityRun:
    """The mobility of every profile of ``results`` and of their sites.

    Parameters
    ----------
    results : PredictionResults
        From :func:`terracone.result.read_results` (SI).
    vehicle : Vehicle
    passes : {1, 50}
    layer : (float, float), optional
        Critical layer (top, bottom) [m]; default that of ``passes``.
    remolding_index : float, optional
        RI in (0, 2] for every profile; None reads each profile's metadata.
    by : sequence of str, optional
        Metadata columns naming the sites; None groups by ``site`` when the
        profiles have it, ``[]`` does not group.
    ci_profiles : mapping, optional
        CI profiles by id for results without CI (a batch directory).
    level : float
        Level of the wheel bands.
    source : str, optional
        The results' path, for messages.
    progress : callable, optional
        Wraps the iteration over profiles (e.g. ``tqdm``).

    Returns
    -------
    MobilityRun

    Raises
    ------
    ValueError
        RI outside (0, 2], ``passes`` not 1 or 50, or a critical layer deeper
        than every profile.
    """
    if passes not in CRITICAL_LAYERS:
        raise ValueError(f"passes must be 1 or 50, got {passes!r}")
    if remolding_index is not None and not 0 < remolding_index <= 2:
        raise ValueError(f"--remolding-index: {remolding_index:g} outside (0, 2]")
    lay = layer or CRITICAL_LAYERS[passes]
    if not 0 <= lay[0] < lay[1]:
        raise ValueError(f"critical layer: need 0 <= top < bottom, got {lay[0]}:{lay[1]} m")
    prior, label = _prior_of(results)
    it = progress(results) if progress is not None else results
    profiles = [
        evaluate_profile(r, vehicle, passes=passes, layer=lay, remolding_index=remolding_index,
                         ci_profiles=ci_profiles, level=level, band_label=label)
        for r in it
    ]  # fmt: skip
    _check_layer(profiles, lay, source)
    notes = []
    if prior == "bounds" and any(p.band is not None for p in profiles):
        notes.append(NO_CALIBRATION_NOTE)
    if passes == 50:
        notes.append("VCI_50 carries no deflection correction (Priddy and Willoughby give the DCF "
                     "for VCI_1 only)")  # fmt: skip
    keys = _grouping(profiles, by)
    sites = _sites(profiles, keys, vehicle.vci(passes), level)
    alone = [p.id for p in profiles if keys and p.site is None]
    if alone:
        shown = ", ".join(alone[:3]) + (", ..." if len(alone) > 3 else "")
        notes.append(f"{len(alone)} profile(s) without {'/'.join(keys)} in their metadata are in "
                     f"no site: {shown}")  # fmt: skip
    settings = {"remolding_index": remolding_index, "level": level, "prior": prior,
                "calibration": results.settings.get("calibration")}  # fmt: skip
    return MobilityRun(vehicle, passes, lay, profiles, sites, keys, settings, notes)


def _grouping(profiles: list[ProfileMobility], by: Sequence[str] | None) -> list[str]:
    if by is None:
        return ["site"] if any("site" in p.metadata for p in profiles) else []
    return [k for k in by if k]


def _sites(profiles, keys: list[str], vci: float, level: float) -> list[SiteMobility]:
    if not keys:
        return []
    groups: dict[str, list[ProfileMobility]] = {}
    for p in profiles:
        p.site = _group_key(p.metadata, keys)
        if p.site is not None:
            groups.setdefault(p.site, []).append(p)
    return [_site(name, members, vci, level) for name, members in groups.items()]


# ---------------------------------------------------------------------------
# MAVS
# ---------------------------------------------------------------------------


def mavs_surface(cone_index: float, material: str) -> dict[str, Any]:
    """The surface entry of a MAVS scene: ``{"Material", "Cone Index"}`` [5]_.

    Parameters
    ----------
    cone_index : float
        The soil strength MAVS's tyre model reads [kPa]: the RCI of the
        critical layer for clay, the CI for sand.
    material : {"sand", "clay"}

    Returns
    -------
    dict
        ``{"Material": material, "Cone Index": <psi>}``; MAVS multiplies
        the cone index by 6894.76 to get Pa.
    """
    if material not in MAVS_MATERIALS:
        raise ValueError(f"MAVS material must be one of {MAVS_MATERIALS}, got {material!r}")
    if not (cone_index is not None and math.isfinite(cone_index) and cone_index > 0):
        raise ValueError(f"MAVS cone index must be a positive number, got {cone_index!r}")
    return {"Material": material, "Cone Index": float(u.pressure_from_si(cone_index, "us"))}


def _mavs_strength(
    chosen: list[ProfileMobility], material: str, what: str
) -> tuple[float, str, list[str]]:
    cis = [p.ci for p in chosen if p.ci is not None]
    if not cis:
        why = "; ".join(dict.fromkeys(n for p in chosen for n in p.notes)) or "no CI"
        raise ValueError(f"{what}: no critical-layer CI ({why})")
    rcis = [p.rci for p in chosen if p.rci is not None]
    notes = []
    if material == "clay" and rcis:
        return float(np.mean(rcis)), "rci", notes
    if material == "clay":
        notes.append(f"{what}: no remolding index: the clay's Cone Index is the CI, not the RCI")
    return float(np.mean(cis)), "ci", notes


def write_mavs(
    results: PredictionResults,
    out: PathLike,
    *,
    material: str,
    profile: str | None = None,
    passes: int = 1,
    source: str | None = None,
) -> tuple[dict[str, Any], list[str]]:
    """Write the MAVS surface entry of one profile, or of a site, to ``out``.

    The cone index is the critical-layer mean (one pass: 0-6 in) of the
    profile, or the mean over the site's profiles (``profile`` naming a
    value of their ``site`` metadata); for clay, the RCI when the metadata
    give a remolding index.  The file is a MAVS scene fragment
    ``{"Surface Mesh": [{"Material", "Cone Index"}], "terracone": {...}}``:
    MAVS reads the two keys of each ``Surface Mesh`` entry and ignores the
    provenance block; add the entry's ``"Mesh"`` in the scene.

    Returns
    -------
    (dict, list of str)
        The document written and notes for the user.
    """
    layer = CRITICAL_LAYERS[passes]
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
    chosen = []
    for r in sel:
        m = ProfileMobility(r.id, r.status, layer=layer, metadata=dict(r.metadata))
        depth, ci = _profile_ci(r, None)
        _nrmm(m, depth, ci, None, math.inf)
        chosen.append(m)
    strength, kind, notes = _mavs_strength(chosen, material, what)
    doc = {
        "Surface Mesh": [mavs_surface(strength, material)],
        "terracone": {
            "what": what,
            "profiles": [m.id for m in chosen],
            "cone_index_of": kind,
            "critical_layer_in": [round(layer[0] / u.INCH, 9), round(layer[1] / u.INCH, 9)],
            "source": source,
        },
    }
    Path(out).write_text(json.dumps(doc, indent=2) + "\n")
    return doc, notes


def ci_profiles_by_id(items: Sequence[Any]) -> dict[str, CIProfile]:
    """CI profiles by id from a reader's list (reader errors are left out)."""
    return {p.id: p for p in items if not isinstance(p, InputError)}

"""What the measured terrain means for a vehicle: ``terracone mobility``.

For every profile of a prediction (``predict`` JSON or Parquet, a ``batch``
directory, read by :func:`terracone.result.read_results`) and a vehicle
(:func:`terracone.apps.vehicles.load_vehicle`, wheeled or tracked):

* **NRMM** [1]_ [2]_: the soil class (``--soil``, a USCS group in the
  metadata, or assumed fine-grained and said so), the critical layer (by the
  cited rule of the soil class, vehicle kind and passes, the weakest layer of
  a given thickness, or ``--layer``; :mod:`terracone.apps.trafficability`),
  its mean CI, the rating cone index RCI = CI x RI of a fine-grained soil when
  a remolding index is known, the vehicle cone index VCI_1 or VCI_50 of the
  vehicle's kind where its relation applies, and GO when RCI >= VCI, with the
  margin RCI - VCI.  A coarse-grained soil is rated by its CI; no public
  source of NRMM's coarse-grained VCI relations could be opened, so it gets no
  GO/NO-GO, and the answer says why;
* **Bekker-Wong** [3]_ [4]_: the sinkage and compaction resistance of the
  vehicle's wheel from the profile's kc, kphi and n, with the 90% band of
  the posterior draws when the results keep them (``predict --uncertainty
  --json``).  Under the bounds prior (no calibration) kc and kphi are set by
  the prior, and the band says so.

Profiles are grouped into sites (a metadata column, ``site`` by default, or
the columns given) and each site gets the mean of its profiles' critical-layer
CI and RCI, its own GO/NO-GO and the median wheel sinkage.  A profile that
cannot be evaluated is recorded with the reason; a profile too shallow for the
critical layer is marked, never extrapolated.

The formulas are in :mod:`terracone.physics.vehicle`; ``docs/mobility.md``
works examples by hand.

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
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from terracone.apps.trafficability import (
    TRACKED_EXAMPLE_WEIGHT,
    WEAKEST_WINDOW,
    critical_layer_mean,
    critical_layer_rule,
    soil_class_of,
    weakest_layer,
)
from terracone.apps.vehicles import Vehicle, Wheel, load_vehicle
from terracone.apps.workflow import Reading, repredict
from terracone.data import CIProfile, InputError
from terracone.inverse.problem import Problem
from terracone.physics import units as u
from terracone.physics import vehicle as phys
from terracone.physics.metrics import finite_median
from terracone.result import PredictionResult, PredictionResults, read_results
from terracone.resultunits import from_si

__all__ = [
    "SCHEMA",
    "LayerChoice",
    "ProfileMobility",
    "SiteMobility",
    "MobilityRun",
    "remolding_index_of",
    "evaluate_profile",
    "evaluate_mobility",
    "ci_profiles_by_id",
    "run_mobility",
]

#: Name and version of the document ``terracone mobility --json`` writes.
SCHEMA = "terracone.mobility/1"
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
#: Mobility of at least this many profiles shows a progress bar on a terminal.
PROGRESS_FROM = 500
COARSE_NOTE = (
    "coarse-grained soil: rated by its critical-layer CI (it has no remolding index, so no "
    "RCI); NRMM's coarse-grained VCI relations could not be checked against a public source "
    "here, so no VCI, GO/NO-GO or margin is given (docs/mobility.md)"
)


@dataclass(frozen=True)
class LayerChoice:
    """How the critical layer is chosen.

    Attributes
    ----------
    mode : {"rule", "weakest", "layer"}
        ``"rule"``: :func:`terracone.apps.trafficability.critical_layer_rule` of
        each profile's soil class, the vehicle kind and the passes;
        ``"weakest"``: the weakest layer of ``thickness`` within ``window``
        (:func:`~terracone.apps.trafficability.weakest_layer`); ``"layer"``:
        ``layer`` for every profile (``--layer``).
    layer : (float, float) or None
        [m], mode "layer".
    thickness : float or None
        [m], mode "weakest".
    window : (float, float)
        Depth window [m] of mode "weakest" (default 0-12 in).
    """

    mode: str = "rule"
    layer: tuple[float, float] | None = None
    thickness: float | None = None
    window: tuple[float, float] = WEAKEST_WINDOW

    def __post_init__(self) -> None:
        if self.mode not in ("rule", "weakest", "layer"):
            raise ValueError(f"critical layer: 'rule', 'weakest' or 'layer', got {self.mode!r}")
        if self.mode == "layer" and not (self.layer and 0 <= self.layer[0] < self.layer[1]):
            raise ValueError(f"critical layer: need 0 <= top < bottom, got {self.layer}")
        if self.mode == "weakest":
            t, (w0, w1) = self.thickness, self.window
            if not (t is not None and t > 0 and 0 <= w0 < w1 and t <= w1 - w0):
                raise ValueError(
                    f"weakest layer: need a thickness > 0 within the window {w0:g}-{w1:g} m, "
                    f"got {t}"
                )

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """``{"mode", ...}`` of the settings, lengths in ``units``."""

        if self.mode == "layer":
            top, bottom = from_si(self.layer, "length", units)
            return {"mode": "layer", "top": top, "bottom": bottom}
        if self.mode == "weakest":
            return {"mode": "weakest", "thickness": from_si(self.thickness, "length", units),
                    "window": from_si(self.window, "length", units)}  # fmt: skip
        return {"mode": "rule"}


# ---------------------------------------------------------------------------
# one profile
# ---------------------------------------------------------------------------


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
    layer : (float, float) or None
        Critical layer (top, bottom) [m]; None when none was found (the
        weakest layer of a profile too shallow for it).
    layer_status : {"ok", "too shallow", "no ci"}
        Whether the critical-layer CI was computed: "too shallow" when the
        readings do not span the layer, "no ci" when the results keep none.
    layer_rule, layer_source : str or None
        What chose the layer (a rule id, ``weakest:...`` or ``--layer``) and its source.
    soil_class : {"fine", "coarse"}
    assumed : bool
        The soil class was not given (``notes`` says which was assumed).
    ci, ri, rci, vci : float or None
        Critical-layer mean CI [kPa], remolding index [-], RCI [kPa], VCI [kPa]
        (None where the vehicle's VCI relation does not apply; ``notes`` says why).
    go : bool or None
        RCI >= VCI; None when RCI or VCI is missing (``notes`` says why).
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
    layer: tuple[float, float] | None = None
    layer_status: str = "ok"
    layer_rule: str | None = None
    layer_source: str | None = None
    soil_class: str = "fine"
    assumed: bool = True
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
    library: dict[str, Any] | None = None  # predict --library: weights, outside_library

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """One profile of the mobility document (``--json``), in ``units``."""
        return {
            "id": self.id,
            "status": self.status,
            "error": self.error,
            "site": self.site,
            "soil_class": self.soil_class,
            "assumed": self.assumed,
            "critical_layer": {
                **_layer_dict(self.layer, self.ci, self.ri, self.rci, units),
                "status": self.layer_status,
                "rule": self.layer_rule,
                "source": self.layer_source,
            },
            "vci": _p(self.vci, units),
            "go": self.go,
            "margin": _p(self.margin, units),
            "wheel": _wheel_dict(self.sinkage, self.resistance, self.band, units),
            "notes": list(self.notes),
            "metadata": dict(self.metadata),
            **(self.library or {}),  # calibration_weights, outside_library (predict --library)
        }


def _p(v: float | None, units: str) -> float | None:
    return from_si(v, "pressure", units)


def _layer_dict(layer, ci, ri, rci, units: str) -> dict[str, Any]:
    top, bottom = (None, None) if layer is None else from_si(layer, "length", units)
    return {"top": top, "bottom": bottom, "ci": _p(ci, units), "ri": ri, "rci": _p(rci, units)}


def _finite(v: float | None) -> float | None:
    return v if v is not None and math.isfinite(v) else None


def _wheel_dict(sinkage, resistance, band, units: str) -> dict[str, Any]:
    z = _finite(sinkage)
    r = _finite(resistance)
    d: dict[str, Any] = {
        "sinkage": from_si(z, "length", units),
        "resistance": from_si(r, "force", units),
    }
    if band is not None:
        for i, end in enumerate(("lo", "hi")):
            d[end] = {
                "sinkage": from_si(band["sinkage"][i], "length", units),
                "resistance": from_si(band["resistance"][i], "force", units),
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


def _critical_layer(
    out: ProfileMobility, choice: LayerChoice, kind: str, passes: int, depth, ci
) -> None:
    """The profile's critical layer, what chose it, and its mean CI (None: not spanned), in place."""
    if choice.mode == "layer":
        out.layer, out.layer_rule, out.layer_source = choice.layer, "--layer", "the --layer option"
    elif choice.mode == "rule":
        rule = critical_layer_rule(out.soil_class, kind, passes)
        out.layer, out.layer_rule, out.layer_source = (
            (rule.top, rule.bottom),
            rule.rule,
            rule.source,
        )
    else:
        w0, w1 = choice.window
        out.layer_rule = f"weakest:{choice.thickness:g}m in {w0:g}-{w1:g}m"
        out.layer_source = "the weakest layer of the profile's readings (--critical-layer weakest)"
    if depth is None:
        return
    out.deepest = float(np.max(depth)) if len(depth) else None
    if choice.mode == "weakest":
        found = weakest_layer(depth, ci, choice.thickness, *choice.window)
        if found is not None:
            out.layer, out.ci = (found[0], found[1]), found[2]
        shown = f"a {choice.thickness:.4g} m layer within {w0:.4g}-{w1:.4g} m"
    else:
        out.ci = critical_layer_mean(depth, ci, *out.layer)
        shown = f"the critical layer {out.layer[0]:.4g}-{out.layer[1]:.4g} m"
    if out.ci is None:
        out.layer_status = "too shallow"
        out.notes.append(
            f"too shallow for {shown}: readings span "
            f"{float(np.min(depth)):.4g}-{float(np.max(depth)):.4g} m (not extrapolated)"
        )


def _strength(out: ProfileMobility, ri_option: float | None, vci_note: str | None) -> None:
    """RI, RCI, GO and the margin of a fine-grained profile with a critical-layer CI, in place."""
    if out.soil_class == "coarse":
        out.notes.append(COARSE_NOTE)
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
    if out.vci is None:
        out.notes.append(f"{vci_note}: no GO/NO-GO")
        return
    out.go = out.rci >= out.vci
    out.margin = out.rci - out.vci


def evaluate_profile(
    r: PredictionResult,
    vehicle: Vehicle,
    *,
    passes: int = 1,
    layer: tuple[float, float] | None = None,
    choice: LayerChoice | None = None,
    soil: str | None = None,
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
        One pass (VCI_1) or fifty (VCI_50).
    layer : (float, float), optional
        Critical layer (top, bottom) [m] in place of the rule's (``--layer``).
    choice : LayerChoice, optional
        How the critical layer is chosen (default: by rule); ``layer`` overrides it.
    soil : {"fine", "coarse"}, optional
        Soil class of the profile; None reads the metadata (``uscs``,
        ``soil_class``) or assumes fine-grained, with a note.
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
    choice = LayerChoice("layer", layer=layer) if layer is not None else choice or LayerChoice()
    out = ProfileMobility(r.id, r.status, r.error, metadata=dict(r.metadata))
    if r.library is not None:  # the library as the prior: which calibrations carry the answer
        out.library = {"calibration_weights": dict(r.library.weights),
                       "outside_library": r.library.outside}  # fmt: skip
    out.soil_class, out.assumed, soil_note = soil_class_of(out.metadata, soil)
    if soil_note:
        out.notes.append(soil_note)
    vci_note = COARSE_NOTE
    if out.soil_class == "fine":
        out.vci, vci_note = vehicle.vci_of(passes)
    depth, ci = _profile_ci(r, ci_profiles)
    _critical_layer(out, choice, vehicle.kind, passes, depth, ci)
    if depth is None:
        out.layer_status = "no ci"
        out.notes.append(NO_CI_NOTE if ci_profiles is None else
                         "no CI: the profile is not in the CI file (--ci)")  # fmt: skip
    elif out.ci is not None:
        _strength(out, remolding_index, vci_note)
    if not r.ok or r.params is None:
        out.notes.append(f"not fitted ({r.error or r.message or 'no parameters'}): no wheel")
        return out
    if vehicle.wheel is None:
        out.notes.append("the vehicle file gives no wheel: no Bekker sinkage")
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

    ``ci`` and ``rci`` are the means over the profiles that have them; the
    site has a soil class, a layer and a VCI when its profiles share them
    (else None); ``go`` and ``margin`` compare the site RCI with that VCI,
    ``go_fraction`` is the share of the decided profiles that go;
    ``sinkage`` and ``resistance`` are the medians of the profiles', ``band``
    the quantiles of their pooled posterior draws (when every profile has
    draws).
    """

    site: str
    profiles: list[str]
    layer: tuple[float, float] | None
    ci: float | None = None
    rci: float | None = None
    vci: float | None = None
    go: bool | None = None
    margin: float | None = None
    go_fraction: float | None = None
    sinkage: float | None = None
    resistance: float | None = None
    band: dict[str, Any] | None = None
    soil_class: str | None = None
    layer_rule: str | None = None

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """One site of the mobility document, in ``units``."""
        return {
            "site": self.site,
            "profiles": list(self.profiles),
            "n_profiles": len(self.profiles),
            "soil_class": self.soil_class,
            "critical_layer": {
                **_layer_dict(self.layer, self.ci, None, self.rci, units),
                "rule": self.layer_rule,
            },
            "vci": _p(self.vci, units),
            "go": self.go,
            "margin": _p(self.margin, units),
            "go_fraction": self.go_fraction,
            "wheel": _wheel_dict(self.sinkage, self.resistance, self.band, units),
        }


def _mean(values: Sequence[float | None]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def _common(values: Sequence[Any]) -> Any:
    """The value every item shares, else None."""
    first = values[0] if values else None
    return first if all(v == first for v in values) else None


def _site(name: str, members: list[ProfileMobility], level: float) -> SiteMobility:
    s = SiteMobility(name, [m.id for m in members], _common([m.layer for m in members]))
    s.soil_class = _common([m.soil_class for m in members])
    s.layer_rule = _common([m.layer_rule for m in members])
    s.vci = _common([m.vci for m in members])
    s.ci = _mean([m.ci for m in members])
    s.rci = _mean([m.rci for m in members])
    if s.rci is not None and s.vci is not None and s.soil_class == "fine":
        s.go, s.margin = s.rci >= s.vci, s.rci - s.vci
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
    choice : LayerChoice
        How the critical layers were chosen.
    profiles : list of ProfileMobility
    sites : list of SiteMobility
    by : list of str
        Metadata columns naming the sites (empty: no sites).
    settings : dict
        What was asked (soil, remolding index, level, calibration, prior).
    notes : list of str
    """

    vehicle: Vehicle
    passes: int
    choice: LayerChoice
    profiles: list[ProfileMobility]
    sites: list[SiteMobility] = field(default_factory=list)
    by: list[str] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def layer(self) -> tuple[float, float] | None:
        """The critical layer [m] every profile shares, else None."""
        return _common([p.layer for p in self.profiles])

    @property
    def evaluated_any(self) -> bool:
        """Whether some profile has a critical-layer CI or a wheel sinkage."""
        return any(p.ci is not None or p.sinkage is not None for p in self.profiles)

    def as_dict(self, units: str = "si", *, input: str | None = None) -> dict[str, Any]:
        """The JSON document (schema :data:`SCHEMA`, docs/mobility.md) in ``units``."""
        from terracone import __version__

        units = u.check_system(units)
        layer = _layer_dict(self.layer, None, None, None, units)
        settings = {
            **self.settings,
            "passes": self.passes,
            "layer": {"top": layer["top"], "bottom": layer["bottom"]},
            "critical_layer": self.choice.as_dict(units),
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


def _check_layer(profiles: list[ProfileMobility], source: str | None) -> None:
    """A layer deeper than every profile with CI is an error, not a column of 'too shallow'."""
    with_ci = [p for p in profiles if p.layer_status != "no ci"]
    if with_ci and all(p.layer_status == "too shallow" for p in with_ci):
        where = f"{source}: " if source else ""
        deepest = max(p.deepest for p in with_ci if p.deepest is not None)
        first = with_ci[0]
        what = (f"critical layer {first.layer[0]:.4g}-{first.layer[1]:.4g} m"
                if first.layer is not None else f"critical layer ({first.layer_rule})")  # fmt: skip
        raise ValueError(
            f"{where}{what} is deeper than every profile (the deepest reading is at "
            f"{deepest:.4g} m)"
        )


def _run_notes(vehicle: Vehicle, passes: int, choice: LayerChoice, profiles) -> list[str]:
    """Notes of the whole run: assumptions of the vehicle, the rule's scope, VCI_50's DCF."""
    notes = list(vehicle.notes)
    heavy = vehicle.gross_weight is not None and vehicle.gross_weight > TRACKED_EXAMPLE_WEIGHT
    if vehicle.kind == "tracked" and heavy and choice.mode == "rule":
        notes.append(
            f"the critical-layer rule for tracked vehicles comes from a 46,000-lb vehicle "
            f"(EN5341); this one weighs {from_si(vehicle.gross_weight, 'force', 'us'):,.0f} lb, and the layer "
            "deepens with weight by a table that could not be read here: consider --layer"
        )
    if passes == 50 and vehicle.kind == "wheeled" and any(p.soil_class == "fine" for p in profiles):
        notes.append("VCI_50 carries no deflection correction (Priddy and Willoughby give the DCF "
                     "for VCI_1 only)")  # fmt: skip
    return notes


def evaluate_mobility(
    results: PredictionResults,
    vehicle: Vehicle,
    *,
    passes: int = 1,
    layer: tuple[float, float] | None = None,
    choice: LayerChoice | None = None,
    soil: str | None = None,
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
        Critical layer (top, bottom) [m] of every profile (``--layer``); it
        overrides ``choice``.
    choice : LayerChoice, optional
        How the critical layer is chosen; default by rule.
    soil : {"fine", "coarse"}, optional
        Soil class of every profile; None reads each profile's metadata or
        assumes fine-grained, and says so.
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
        RI outside (0, 2], ``passes`` not 1 or 50, a bad soil class, or a
        critical layer deeper than every profile.
    """
    if passes not in (1, 50):
        raise ValueError(f"passes must be 1 or 50, got {passes!r}")
    if remolding_index is not None and not 0 < remolding_index <= 2:
        raise ValueError(f"--remolding-index: {remolding_index:g} outside (0, 2]")
    if soil is not None and soil not in ("fine", "coarse"):
        raise ValueError(f"--soil: 'fine' or 'coarse', got {soil!r}")
    choice = LayerChoice("layer", layer=layer) if layer is not None else choice or LayerChoice()
    prior, label = _prior_of(results)
    it = progress(results) if progress is not None else results
    profiles = [
        evaluate_profile(r, vehicle, passes=passes, choice=choice, soil=soil,
                         remolding_index=remolding_index, ci_profiles=ci_profiles, level=level,
                         band_label=label)
        for r in it
    ]  # fmt: skip
    _check_layer(profiles, source)
    notes = _run_notes(vehicle, passes, choice, profiles)
    if prior == "bounds" and any(p.band is not None for p in profiles):
        notes.append(NO_CALIBRATION_NOTE)
    keys = _grouping(profiles, by)
    sites = _sites(profiles, keys, level)
    alone = [p.id for p in profiles if keys and p.site is None]
    if alone:
        shown = ", ".join(alone[:3]) + (", ..." if len(alone) > 3 else "")
        notes.append(f"{len(alone)} profile(s) without {'/'.join(keys)} in their metadata are in "
                     f"no site: {shown}")  # fmt: skip
    settings = {"soil": soil, "remolding_index": remolding_index, "level": level, "prior": prior,
                "calibration": results.settings.get("calibration")}  # fmt: skip
    return MobilityRun(vehicle, passes, choice, profiles, sites, keys, settings, notes)


def _grouping(profiles: list[ProfileMobility], by: Sequence[str] | None) -> list[str]:
    if by is None:
        return ["site"] if any("site" in p.metadata for p in profiles) else []
    return [k for k in by if k]


def _sites(profiles, keys: list[str], level: float) -> list[SiteMobility]:
    if not keys:
        return []
    groups: dict[str, list[ProfileMobility]] = {}
    for p in profiles:
        p.site = _group_key(p.metadata, keys)
        if p.site is not None:
            groups.setdefault(p.site, []).append(p)
    return [_site(name, members, level) for name, members in groups.items()]


def ci_profiles_by_id(items: Sequence[Any]) -> dict[str, CIProfile]:
    """CI profiles by id from a reader's list (reader errors are left out)."""
    return {p.id: p for p in items if not isinstance(p, InputError)}


def _progress(count: int) -> Callable[[Iterable[Any]], Iterable[Any]] | None:
    """tqdm over the profiles when there are many and stderr is a terminal."""
    if count < PROGRESS_FROM or not sys.stderr.isatty():
        return None
    from tqdm.auto import tqdm

    return lambda it: tqdm(it, total=count, desc="terracone mobility", unit="profile",
                           file=sys.stderr)  # fmt: skip


def check_results_path(path: str | os.PathLike[str]) -> None:
    """A directory of results must be a batch directory (it holds ``part-*.parquet``).

    Raises
    ------
    ValueError
        A directory that is neither a terrain map nor a batch directory.
    """
    p = Path(path)
    if p.is_dir() and not any(p.glob("part-*.parquet")):
        raise ValueError(
            f"{p}: neither a terracone map directory (no map.json) nor a batch directory "
            "(no part-*.parquet files)"
        )


def run_mobility(
    results: PredictionResults | str | os.PathLike[str],
    vehicle: Vehicle | str | os.PathLike[str],
    *,
    passes: int = 1,
    layer: tuple[float, float] | None = None,
    choice: LayerChoice | None = None,
    soil: str | None = None,
    remolding_index: float | None = None,
    by: Sequence[str] | None = None,
    ci_file: str | os.PathLike[str] | None = None,
    file_units: str | None = None,
    problem: Problem | None = None,
    units: str = "si",
    progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None,
) -> MobilityRun:
    """What ``terracone mobility RESULTS`` computes: read, predict again if asked, evaluate.

    Parameters
    ----------
    results : PredictionResults or path
        A predict JSON or Parquet file, a batch directory, or results read.
    vehicle : Vehicle or path
        A vehicle, or its file (:func:`~terracone.apps.vehicles.load_vehicle`).
    passes, layer, choice, soil, remolding_index, by
        As :func:`evaluate_mobility` takes them.
    ci_file : path, optional
        CI profiles of results that keep none (a batch directory), by id.
    file_units : {"si", "us"}, optional
        Unit system of a ``ci_file`` that states none.
    problem : Problem, optional
        Predict the profiles again under it first (a library as the prior,
        :func:`~terracone.apps.workflow.repredict`), their CI from the
        results or ``ci_file``.
    units : {"si", "us"}
        Units of the reading's notes.
    progress : callable, optional
        Wraps the loop over the profiles (default: a tqdm bar on a terminal
        from 500 profiles).

    Returns
    -------
    MobilityRun
    """
    source = None
    if not isinstance(results, PredictionResults):
        check_results_path(results)
        source = str(results)
    veh = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle)
    res = results if isinstance(results, PredictionResults) else read_results(results)
    ci_profiles = None
    if ci_file:
        ci_profiles = ci_profiles_by_id(Reading(file_units=file_units).read(ci_file, units))
    if problem is not None:
        res = repredict(res, problem, ci_profiles)
    return evaluate_mobility(
        res, veh, passes=passes, layer=layer, choice=choice, soil=soil,
        remolding_index=remolding_index, by=by, ci_profiles=ci_profiles, source=source,
        progress=_progress(len(res)) if progress is None else progress,
    )  # fmt: skip

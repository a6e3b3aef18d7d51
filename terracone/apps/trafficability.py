"""Soil class and critical layer of NRMM's cone-index go/no-go, with their sources.

**Soil class.**  NRMM rates fine-grained soils by the rating cone index RCI =
CI x RI; materials other than fine-grained soils and remoldable sands have no
remolding index, so no RCI can be computed for them [1]_.  A profile's class
comes from ``--soil fine|coarse``, else from its metadata (a USCS group symbol
in ``uscs``: G and S are coarse-grained, M, C, O and Pt fine-grained, the
first symbol of a dual one deciding; or ``soil_class``: fine or coarse),
else it is assumed fine-grained and the answer says so (:func:`soil_class_of`).

**Critical layer.**  "The depth and thickness of the critical layer vary with
the type and weight of the vehicle, the type of soil, and the number of passes
required" [1]_.  :data:`CRITICAL_LAYER_RULES` holds the cases a source opened
here states (:func:`critical_layer_rule`), each with its source:

==========  ========  ======  =========  ==================================================
soil        vehicle   passes  layer      source
==========  ========  ======  =========  ==================================================
fine        tracked   1       0-6 in     [1]_: one pass of a 46,000-lb full-tracked M37
fine        tracked   50      6-12 in    [1]_: fifty passes of the same vehicle
fine        wheeled   1       6-12 in    [2]_: VCI_1 observations (M923 5-ton truck) use
                                         "RCI in the critical layer (6-12 in)"
fine        wheeled   50      6-12 in    [1]_ (the 50-pass layer; no wheeled 50-pass
                                         source was opened)
coarse      any       any     0-6 in     [3]_: "an average CI for the top 15 cm of soil is
                                         standard in mobility applications" (of soils in
                                         general; none specific to coarse soils opened)
==========  ========  ======  =========  ==================================================

The weight of the vehicle is not a threshold of these rules: no source opened
gives one (the table of [1]_ that does could not be read); a tracked vehicle
heavier than the 46,000-lb example gets a note.  :func:`weakest_layer` finds
instead the weakest layer of a given thickness within a depth window, exactly
(the profile linearly interpolated between readings).

References
----------
.. [1] U.S. Army Engineer School, subcourse EN5341, ch. 3 (soil trafficability):
   the critical layer, pp. 3-26 and 3-27 (armyengineer.tpub.com/En5341a/En5341a0111.htm,
   En5341a0112.htm); the RCI of fine-grained soils and remoldable sands (En5341a0121.htm).
.. [2] Priddy, J.D., Willoughby, W.E. (2006). Clarification of vehicle cone
   index with reference to mean maximum pressure. J. Terramechanics 43(2),
   85-96, Fig. 2.
.. [3] Frankenstein, S., Koenig, G. (2004). Fast All-season Soil STrength
   (FASST). ERDC/CRREL SR-04-1, section 5.2
   (coldregionsresearch.tpub.com/SR04-1/SR04-10071.htm).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from terracone.physics import units as u

__all__ = [
    "SOIL_CLASSES",
    "USCS_GROUPS",
    "SOIL_KEYS",
    "LayerRule",
    "CRITICAL_LAYER_RULES",
    "WEAKEST_WINDOW",
    "uscs_class",
    "soil_class_of",
    "critical_layer_rule",
    "critical_layer_mean",
    "weakest_layer",
]

#: Soil classes of the relations: fine-grained (RCI) and coarse-grained (CI).
SOIL_CLASSES = ("fine", "coarse")
#: USCS group symbols and their class (G gravels and S sands coarse-grained;
#: M silts, C clays, O organic soils and Pt peat fine-grained).
USCS_GROUPS = {
    **{g: "coarse" for g in ("GW", "GP", "GM", "GC", "SW", "SP", "SM", "SC")},
    **{g: "fine" for g in ("ML", "CL", "OL", "MH", "CH", "OH", "PT")},
}
#: Metadata keys read for the soil class (case ignored): a USCS symbol, or fine/coarse.
SOIL_KEYS = ("uscs", "soil_class")
ASSUMED_NOTE = (
    "soil class not given (--soil, or a uscs or soil_class metadata column): "
    "assumed fine-grained (RCI = CI x RI)"
)
EN5341 = "EN5341 ch. 3, pp. 3-26 to 3-27 (critical layer of a 46,000-lb full-tracked M37)"


@dataclass(frozen=True)
class LayerRule:
    """A critical layer and what chose it: ``top``, ``bottom`` [m], ``rule`` (an id), ``source``."""

    top: float
    bottom: float
    rule: str
    source: str


def _rule(soil: str, kind: str, passes: int, top_in: float, bottom_in: float, source: str):
    rid = "-".join([soil] + [kind] * (kind != "any") + [f"{passes}pass"] * (passes > 0))
    return (soil, kind, passes), LayerRule(top_in * u.INCH, bottom_in * u.INCH, rid, source)


#: (soil, vehicle kind or "any", passes or 0 for any) -> the cited critical layer.
CRITICAL_LAYER_RULES: dict[tuple[str, str, int], LayerRule] = dict(
    [
        _rule("fine", "tracked", 1, 0, 6, EN5341),
        _rule("fine", "tracked", 50, 6, 12, EN5341),
        _rule("fine", "wheeled", 1, 6, 12,
              "Priddy and Willoughby (2006), Fig. 2: VCI_1 observations use RCI in the "
              "critical layer 6-12 in"),
        _rule("fine", "wheeled", 50, 6, 12,
              EN5341 + "; no source for wheeled vehicles and 50 passes was opened"),
        _rule("coarse", "any", 0, 0, 6,
              "FASST, ERDC/CRREL SR-04-1, section 5.2: the average CI of the top 15 cm is "
              "standard in mobility applications"),
    ]
)  # fmt: skip
#: Weight of the tracked example of [1] [N]: heavier vehicles get a note.
TRACKED_EXAMPLE_WEIGHT = 46_000.0 * u.LBF
#: Depth window of ``weakest:THICKNESS`` when none is given [m]: 0-12 in, the span of
#: the cited critical layers.
WEAKEST_WINDOW = (0.0, 12 * u.INCH)


def uscs_class(symbol: str) -> str:
    """``"fine"`` or ``"coarse"`` of a USCS group symbol (``SM``, ``CL``, dual ``SM-SC``).

    Raises
    ------
    ValueError
        Not a USCS group symbol.
    """
    parts = [p.strip().upper() for p in str(symbol).replace("/", "-").split("-")]
    if not parts or any(p not in USCS_GROUPS for p in parts):
        raise ValueError(
            f"{symbol!r} is not a USCS group symbol ({', '.join(USCS_GROUPS)}, or a dual "
            "symbol such as SM-SC)"
        )
    return USCS_GROUPS[parts[0]]


def soil_class_of(
    metadata: Mapping[str, Any], option: str | None = None
) -> tuple[str, bool, str | None]:
    """(class, assumed, note) of a profile: the option, its metadata, or assumed fine.

    Parameters
    ----------
    metadata : mapping
        The profile's metadata; ``uscs`` (a USCS group symbol) or
        ``soil_class`` (fine, coarse, fine-grained, coarse-grained), case ignored.
    option : {"fine", "coarse"}, optional
        ``--soil``: the class of every profile.

    Returns
    -------
    (str, bool, str or None)
        The class, whether it was assumed, and a note when it was (with the
        reason a metadata value was not read).
    """
    if option is not None:
        if option not in SOIL_CLASSES:
            raise ValueError(f"--soil: 'fine' or 'coarse', got {option!r}")
        return option, False, None
    lower = {str(k).strip().lower(): (k, v) for k, v in metadata.items()}
    for key in SOIL_KEYS:
        if key not in lower or lower[key][1] is None or str(lower[key][1]).strip() == "":
            continue
        name, value = lower[key]
        text = str(value).strip().lower().removesuffix("-grained")
        try:
            cls = uscs_class(value) if key == "uscs" else text
            if cls not in SOIL_CLASSES:
                raise ValueError(f"{value!r} is not 'fine' or 'coarse'")
        except ValueError as exc:
            return "fine", True, f"metadata {name!r}: {exc}; {ASSUMED_NOTE}"
        return cls, False, None
    return "fine", True, ASSUMED_NOTE


def critical_layer_rule(soil: str, kind: str, passes: int) -> LayerRule:
    """The critical layer of :data:`CRITICAL_LAYER_RULES` for a soil class, vehicle kind, passes.

    Parameters
    ----------
    soil : {"fine", "coarse"}
    kind : {"wheeled", "tracked"}
    passes : {1, 50}

    Returns
    -------
    LayerRule
    """
    for key in ((soil, kind, passes), (soil, "any", passes), (soil, "any", 0)):
        if key in CRITICAL_LAYER_RULES:
            return CRITICAL_LAYER_RULES[key]
    raise ValueError(f"no critical-layer rule for {soil}-grained soil, {kind}, {passes} passes")


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


def weakest_layer(
    depth: Sequence[float], ci: Sequence[float], thickness: float, top: float, bottom: float
) -> tuple[float, float, float] | None:
    """The weakest layer of ``thickness`` within ``top``-``bottom``: (top, bottom, mean CI).

    The layer [t, t + thickness] with the least mean CI
    (:func:`critical_layer_mean`), t in [top, bottom - thickness], over the
    part of the window the profile spans.  Its integral F(t) is piecewise
    quadratic in t, with F'(t) = CI(t + thickness) - CI(t): the minimum lies
    at an end, where t or t + thickness meets a reading, or where CI(t) =
    CI(t + thickness) between those; every such t is evaluated.

    Parameters
    ----------
    depth, ci : sequence of float
        Depths [m] (increasing) and cone index [kPa].
    thickness : float
        Layer thickness [m], > 0.
    top, bottom : float
        Depth window [m].

    Returns
    -------
    (float, float, float) or None
        (top [m], bottom [m], mean CI [kPa]); None when the profile does not
        span a layer of ``thickness`` within the window.
    """
    z, c = np.asarray(depth, dtype=float), np.asarray(ci, dtype=float)
    if not thickness > 0:
        raise ValueError(f"weakest layer: thickness must be > 0, got {thickness}")
    if z.size < 2:
        return None
    lo, hi = max(top, float(z[0])), min(bottom, float(z[-1]))
    if hi - lo < thickness * (1 - 1e-12):
        return None
    hi_t = max(lo, hi - thickness)
    cand = np.concatenate([[lo, hi_t], z, z - thickness])
    cand = np.unique(cand[(cand >= lo) & (cand <= hi_t)])
    roots = []
    for a, b in zip(cand[:-1], cand[1:], strict=False):  # F' is linear between candidates
        fa = np.interp(a + thickness, z, c) - np.interp(a, z, c)
        fb = np.interp(b + thickness, z, c) - np.interp(b, z, c)
        if fa < 0 < fb:
            roots.append(a + (b - a) * fa / (fa - fb))
    best = None
    for t in np.concatenate([cand, roots]):
        m = critical_layer_mean(z, c, float(t), min(float(t) + thickness, float(z[-1])))
        if m is not None and (best is None or m < best[2]):
            best = (float(t), float(t) + thickness, m)
    return best

"""What a fit fits, stated once: a calibration, and the problem resolved from it.

A :class:`Calibration` is what the learning process (section 3.3.1 of [1]_)
hands to the prediction process (section 3.3.2): the pressure law of section
3.2 (model, r_min and the plate pair of its RM1 secant), phic, cc and the
kc/kphi ratio of the calibrated terrain.

A :class:`Problem` is built once from (model, r_min, calibration, bounds,
prior, cone) and is the only place where a calibration is applied.  It holds,
resolved:

* ``law``: the pressure law every fit uses (a calibration's, if any);
* ``fit_bounds``: the search box with the values a calibration holds (phic
  and cc pinned);
* ``ratio``: the kc/kphi held [m], or None;
* ``centre``: a calibration given as a *prior* (``prior=`` a Calibration or
  :class:`~terracone.inverse.uncertainty.priors.CalibrationPrior`): the point
  fit is held at its values and the posterior lets phic, cc and kc/kphi vary
  around them with its widths;
* ``noise_floor`` and the cone's shear deformation (``K_cone``, ``fit_K_cone``);
* ``library``: stored calibrations as candidate models of a prior
  (:class:`LibraryPrior`, issue 32): each candidate's *held* problem is
  :meth:`Problem.held_problem` (its phic, cc and kc/kphi held), and
  :meth:`Problem.candidates` gives those of a cone with their prior weights.

Every inverse entry point takes it unchanged: :func:`~terracone.inverse.predict.predict_many`,
:func:`~terracone.inverse.layered.fit_layered`, :func:`~terracone.inverse.uncertainty.posterior.posterior`,
:func:`~terracone.inverse.layered.layered_posterior`, the site fits
(:mod:`terracone.inverse.sites`) and :func:`~terracone.inverse.sites.design.plan_test`;
batch's workers receive it pickled.  A value a calibration holds stays held
in each of them: every layer of a layered fit and every posterior draw.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Sections 3.2, 3.3.1 and 3.3.2.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from terracone.data import TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.io.jsonkeys import TERRAIN_KEYS, FileKeyError, Key, check_keys, read_json
from terracone.physics.cone import get_cone
from terracone.physics.plate import PressureLaw, pressure_law

__all__ = [
    "CALIBRATION_KEYS",
    "Calibration",
    "CalibrationPrior",
    "LibraryPrior",
    "Problem",
    "as_calibration_prior",
    "same_cone",
    "soil_match",
]


_REQUIRED = ("kc", "kphi", "n", "cc", "phic_deg", "model")

#: The keys of a calibration file (format 1, SI): the terrain keys a calibration holds
#: (:data:`terracone.io.jsonkeys.TERRAIN_KEYS`; kc, kphi, n, cc, phic_deg and model
#: required, r_min required with model rm1) and the file's own.
CALIBRATION_KEYS: dict[str, Key] = {
    "terracone_calibration": Key(
        "choice", choices=(1,), meaning="the calibration format this terracone reads"
    ),
    "units": Key("choice", choices=("si",), meaning="calibration files are stored in SI"),
    "terrain": Key("text", required=True, meaning="the terrain or site label"),
    **{
        k: replace(TERRAIN_KEYS[k], required=k in _REQUIRED)
        for k in ("model", "r_min", "plate_pair", "phic_deg", "cc", "kc", "kphi", "n", "Kc")
    },
    "cone": TERRAIN_KEYS["cone"],
    "provenance": Key("object", meaning="where the calibration comes from"),
}


@dataclass(init=False)
class Calibration:
    """A learned calibration: what prediction takes from the learning process.

    Built from a :class:`~terracone.data.TerrainParameters` (``params``); its
    values are also readable flat (``cal.kc``, ``cal.phic_deg``, ...), and the
    old positional form ``Calibration(terrain, model, r_min, plate_pair,
    phic_deg, cc, kc, kphi, n, cone, provenance)`` still builds one.

    Attributes
    ----------
    terrain : str
        Terrain or site label.
    params : TerrainParameters
        kc, kphi, n (the calibrated terrain's P-S parameters), cc, phic_deg,
        model and r_min (SI).
    plate_pair : (float, float) or None
        Plate radii [m] of the learning data (RM1 secant when r_min > r2).
    cone : str
    provenance : dict
    model, r_min, phic_deg, cc, kc, kphi, n : read-only
        The fields of ``params`` ([m], [deg], [kPa], SI moduli).
    kc_over_kphi : float or None
        kc/kphi [m], the ratio prediction can hold.
    """

    terrain: str
    params: TerrainParameters
    plate_pair: tuple[float, float] | None
    cone: str
    provenance: dict[str, Any]

    def __init__(
        self,
        terrain: str,
        model: str | None = None,
        r_min: float | None = None,
        plate_pair: tuple[float, float] | None = None,
        phic_deg: float | None = None,
        cc: float | None = None,
        kc: float | None = None,
        kphi: float | None = None,
        n: float | None = None,
        cone: str = "asabe-large",
        provenance: dict[str, Any] | None = None,
        *,
        params: TerrainParameters | None = None,
    ) -> None:
        flat = dict(model=model, phic_deg=phic_deg, cc=cc, kc=kc, kphi=kphi, n=n)
        if params is None:
            missing = [k for k, v in flat.items() if v is None]
            if missing:
                raise TypeError(f"Calibration needs params= or {', '.join(missing)}")
            params = TerrainParameters(kc, kphi, n, cc, phic_deg, None, model, r_min)
        elif any(v is not None for v in flat.values()) or r_min is not None:
            raise TypeError("give Calibration params= or the flat values, not both")
        self.terrain = terrain
        self.params = params
        self.plate_pair = plate_pair
        self.cone = cone
        self.provenance = dict(provenance or {})

    model = property(lambda self: self.params.model, doc="Pressure law, 'rm0' or 'rm1'.")
    r_min = property(lambda self: self.params.r_min, doc="RM1 transition radius [m] or None.")
    phic_deg = property(lambda self: self.params.phic_deg, doc="Cone-terrain friction [deg].")
    cc = property(lambda self: self.params.cc, doc="Cone-terrain adhesion [kPa].")
    kc = property(lambda self: self.params.kc, doc="kc [kN/m^(n+1)].")
    kphi = property(lambda self: self.params.kphi, doc="kphi [kN/m^(n+2)].")
    n = property(lambda self: self.params.n, doc="Sinkage exponent [-].")
    kc_over_kphi = property(
        lambda self: self.params.kc_over_kphi, doc="kc/kphi [m]; None when kphi is 0."
    )

    def to_json(self) -> dict[str, Any]:
        """The calibration file's content (format 1, SI, flat keys as always)."""
        d: dict[str, Any] = {"terrain": self.terrain, "model": self.model, "r_min": self.r_min}
        d["plate_pair"] = list(self.plate_pair) if self.plate_pair else None
        d.update({k: getattr(self, k) for k in ("phic_deg", "cc", "kc", "kphi", "n")})
        if self.params.K_cone is not None:
            d["Kc"] = self.params.K_cone
        d.update({"cone": self.cone, "provenance": dict(self.provenance)})
        return {"terracone_calibration": 1, "units": "si", **d}

    def save(self, path: str | Path) -> None:
        """Write the calibration as JSON (SI units)."""
        Path(path).write_text(json.dumps(self.to_json(), indent=2) + "\n")

    @classmethod
    def from_json(cls, d: dict[str, Any], *, file: str | Path | None = None) -> Calibration:
        """Calibration from the content of a calibration file, every key checked.

        Raises
        ------
        terracone.io.jsonkeys.FileKeyError
            (a ValueError) naming ``file``, the key and the reason: a key
            missing, unknown, of the wrong type, not finite or out of its
            physical range (:data:`CALIBRATION_KEYS`).
        """
        if isinstance(d, dict) and d.get("terracone_calibration") is None:
            raise FileKeyError(
                "missing: not a terracone calibration file (`terracone learn --save` writes them)",
                file=file,
                key="terracone_calibration",
            )
        c = check_keys(d, CALIBRATION_KEYS, file=file)
        params = TerrainParameters(
            kc=c["kc"],
            kphi=c["kphi"],
            n=c["n"],
            cc=c["cc"],
            phic_deg=c["phic_deg"],
            K_cone=c.get("Kc"),
            model=c["model"],
            r_min=c.get("r_min"),
        )
        pp = c.get("plate_pair")
        return cls(
            terrain=c["terrain"],
            plate_pair=None if not pp else (pp[0], pp[1]),
            cone=c.get("cone", "asabe-large"),
            provenance=c.get("provenance", {}),
            params=params,
        )

    def library_params(self) -> dict[str, Any]:
        """Parameters to store in the terrain library (SI keys, as :mod:`terracone.apps.library` keeps them)."""
        pair = {"plate_pair": list(self.plate_pair)} if self.plate_pair else {}
        return {**self.params.library_params(), **pair, "cone": self.cone}

    @classmethod
    def from_library_record(cls, rec: Any) -> Calibration:
        """Calibration from a terrain-library record of kind "calibration"."""
        if rec.kind != "calibration":
            raise ValueError(
                f"terrain {rec.name!r} is a {rec.kind!r} record, not a calibration from "
                "`terracone learn --save-as`: it has no learned phic, cc and r_min"
            )
        d = {k: v for k, v in rec.params.items() if k in CALIBRATION_KEYS}
        d.update({"terracone_calibration": 1, "units": "si", "terrain": rec.name})
        d["provenance"] = dict(rec.provenance or {})
        d.setdefault("cc", 0.0)
        return cls.from_json(d)

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration written by :meth:`save`, every key checked (:meth:`from_json`)."""
        return cls.from_json(read_json(path), file=path)


@dataclass(frozen=True)
class CalibrationPrior:
    """Prior centred on a learned calibration (section 3.3.1 of [1]_).

    Attributes
    ----------
    calibration : Calibration
        Fixes model, r_min and the plate pair.
    phic_sd : float
        Standard deviation of the normal prior of phic around the
        calibration's value [deg] (Table 4-1 of [1]_ spreads 10-12.5 deg
        over four LETE profiles).
    cc_sd : float or None
        Standard deviation of the normal prior of cc [kPa]; None:
        max(2 kPa, 0.25 * cc_cal).
    ratio_log_sd : float
        Standard deviation of ln(kc/kphi) around the calibration's ratio
        [-] (0.25: a factor 1.5 either way at 90%; the LETE profiles of
        Table 4-1 span 0.017-0.026 m).
    """

    calibration: Calibration
    phic_sd: float = 2.0
    cc_sd: float | None = None
    ratio_log_sd: float = 0.25

    def __post_init__(self) -> None:
        if not (self.phic_sd >= 0 and self.ratio_log_sd > 0):
            raise ValueError("phic_sd must be >= 0 and ratio_log_sd > 0")
        if self.cc_sd is not None and self.cc_sd < 0:
            raise ValueError("cc_sd must be >= 0")

    @property
    def cc_width(self) -> float:
        """The standard deviation of cc actually used [kPa]."""
        if self.cc_sd is not None:
            return float(self.cc_sd)
        return max(2.0, 0.25 * float(self.calibration.cc))


def as_calibration_prior(prior: Any) -> CalibrationPrior | None:
    if prior is None or prior == "bounds":
        return None
    if isinstance(prior, str):
        raise ValueError(
            f"prior must be 'bounds', a Calibration or a CalibrationPrior (got {prior!r})"
        )
    if isinstance(prior, CalibrationPrior):
        return prior
    if isinstance(prior, Calibration):
        return CalibrationPrior(prior)
    raise TypeError(f"prior must be 'bounds', a Calibration or a CalibrationPrior (got {prior!r})")


def same_cone(a: str, b: str) -> bool:
    """Whether two cone names (or specs) are the same cone: base area and angle."""
    ca, cb = get_cone(a), get_cone(b)
    return math.isclose(ca.base_area, cb.base_area, rel_tol=1e-9) and math.isclose(
        ca.angle_deg, cb.angle_deg, rel_tol=1e-9
    )


#: Soil classes the library prior compares: a USCS group symbol (SP, CL, ...) or the
#: class of one, fine or coarse (G and S coarse-grained; M, C, O and Pt fine-grained,
#: the rule of :mod:`terracone.apps.trafficability`).
_COARSE_FIRST = ("G", "S")


def _soil_parts(soil: str | None) -> tuple[str | None, str | None]:
    """(USCS symbol or None, "fine"/"coarse" or None) of a soil class text."""
    if soil is None or not str(soil).strip():
        return None, None
    t = str(soil).strip()
    if t.lower() in ("fine", "coarse"):
        return None, t.lower()
    sym = t.upper().split("-")[0].split("/")[0]
    return sym, "coarse" if sym[:1] in _COARSE_FIRST else "fine"


def soil_match(profile_soil: str | None, candidate_soil: str | None) -> bool | None:
    """Whether a profile's soil class agrees with a candidate calibration's; None if unknown.

    USCS symbols are compared as symbols when both sides give one, else as
    fine or coarse (``SP`` agrees with ``coarse``, not with ``fine``).
    """
    ps, pc = _soil_parts(profile_soil)
    cs, cc = _soil_parts(candidate_soil)
    if pc is None or cc is None:
        return None
    if ps is not None and cs is not None:
        return ps == cs
    return pc == cc


def _provenance_soil(cal: Calibration) -> str | None:
    """A calibration's soil class from its provenance (``soil_class`` or ``uscs``), or None."""
    for key in ("soil_class", "uscs"):
        v = cal.provenance.get(key)
        if isinstance(v, str) and v.strip():
            return v.strip()
    return None


@dataclass(frozen=True)
class LibraryPrior:
    """Stored calibrations as the candidate models of a prior (issue 32).

    Each calibration is a candidate: its held problem
    (:meth:`Problem.held_problem`) fixes its model, r_min, phic, cc and kc/kphi,
    and leaves kphi and n free.  Only the calibrations learned with the
    profile's cone are candidates for it.  A candidate's prior weight is 1,
    or ``mismatch_weight`` where its soil class and the profile's (metadata
    ``uscs`` or ``soil_class``) disagree (:func:`soil_match`).

    Parameters
    ----------
    calibrations : sequence of Calibration
        The candidates (unique terrain names, kphi > 0 so that kc/kphi is held).
    soil_classes : sequence of str or None, optional
        Each candidate's soil class (a USCS symbol, fine or coarse), or None;
        by default its provenance's ``soil_class`` (or ``uscs``).
    source : str, optional
        Where the calibrations come from (the library file), for the record.
    mismatch_weight : float
        Prior weight of a candidate whose soil class disagrees with the
        profile's [-], in (0, 1].
    check_level : float
        A profile (or site) is outside the library when the posterior
        predictive check of every candidate has a p-value below this [-].
    draws : int
        Draws of the mixture posterior of a profile.
    replicates : int
        Replicates of the posterior predictive check per candidate.
    """

    calibrations: tuple[Calibration, ...]
    soil_classes: tuple[str | None, ...] = ()
    source: str | None = None
    mismatch_weight: float = 0.1
    check_level: float = 0.01
    draws: int = 2000
    replicates: int = 200

    def __post_init__(self) -> None:
        put = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen fields
        cals = tuple(self.calibrations)
        where = f"library {self.source}" if self.source else "the library"
        if not cals:
            raise ValueError(
                f"{where} holds no calibration (kind 'calibration'): add one with `terracone "
                "library add --from cal.json` (cal.json from `terracone learn --save`) or "
                "`terracone library seed-paper`"
            )
        names = [c.terrain for c in cals]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"{where}: calibration names repeat: {dup}")
        flat = [c.terrain for c in cals if not c.kphi > 0]
        if flat:
            raise ValueError(
                f"{where}: calibration {flat[0]!r} has kphi = 0, so no kc/kphi to hold"
            )
        soils = tuple(self.soil_classes) or tuple(_provenance_soil(c) for c in cals)
        if len(soils) != len(cals):
            raise ValueError("give one soil class (or None) per calibration")
        if not 0 < self.mismatch_weight <= 1:
            raise ValueError(f"mismatch_weight must be in (0, 1] (got {self.mismatch_weight})")
        if not 0 < self.check_level < 1:
            raise ValueError(f"check_level must be in (0, 1) (got {self.check_level})")
        if self.draws < 10 or self.replicates < 10:
            raise ValueError("draws and replicates must be >= 10")
        put("calibrations", cals)
        put("soil_classes", soils)

    @property
    def names(self) -> list[str]:
        """The candidates' terrain names, in library order."""
        return [c.terrain for c in self.calibrations]

    def of_cone(self, cone: str) -> list[int]:
        """Indices of the calibrations learned with ``cone`` (its name or spec)."""
        return [i for i, c in enumerate(self.calibrations) if same_cone(c.cone, cone)]

    def prior_weight(self, i: int, soil: str | None) -> float:
        """Prior weight of candidate ``i`` for a profile of soil class ``soil`` [-]."""
        return self.mismatch_weight if soil_match(soil, self.soil_classes[i]) is False else 1.0

    def describe(self) -> str:
        """ "library:<source>" (as result files record the prior)."""
        return f"library:{self.source or f'{len(self.calibrations)} calibrations'}"


@dataclass(frozen=True)
class Problem:
    """What a fit fits, resolved once: pressure law, box, held values, prior (SI).

    Parameters
    ----------
    model : {"rm0", "rm1"}
        Pressure law (section 3.2 of [1]_) without a calibration.
    r_min : float, optional
        RM1 transition radius [m] without a calibration.
    plate_pair : (float, float), optional
        Plate radii [m] of the RM1 secant when r_min lies above them.
    calibration : Calibration or path, optional
        Holds its model, r_min, plate pair, phic, cc and (``fix_ratio``)
        kc/kphi in every fit built on this problem.
    bounds : Bounds
        The search box; the support of the posterior's prior.
    prior : "bounds", "calibration", Calibration or CalibrationPrior
        The posterior's prior.  "bounds": uniform over the box with the held
        values; "calibration": the same, named after the calibration (it
        needs one); a Calibration or CalibrationPrior *without* a
        ``calibration``: a calibration as a prior (``centre``).
    K_cone : float, optional
        Shear deformation modulus of the cone [m]; None: fully mobilised.
    fit_K_cone : bool
        Fit K_cone within ``bounds.K_cone`` (exact solver, profile by profile).
    fix_ratio : bool
        Hold a calibration's kc/kphi.
    kc_over_kphi : float, optional
        kc/kphi [m] to hold without a calibration.
    noise_floor : float
        Relative noise floor of the profile intervals [-].
    library : LibraryPrior, optional
        Stored calibrations as the candidates of a prior (not with a
        ``calibration`` or a calibration as the prior): every fit is made
        under each candidate's held problem (:meth:`held_problem`) and the
        answer is their mixture, weighted by each candidate's evidence
        (:mod:`terracone.inverse.library`).  Fully mobilised shear and a
        held kc/kphi (``fix_ratio``) only.

    Attributes
    ----------
    law : PressureLaw
        The pressure law every fit uses.
    fit_bounds : Bounds
        ``bounds`` with the held phic and cc pinned (LO = HI).
    ratio : float or None
        kc/kphi held [m].
    centre : CalibrationPrior or None
        A calibration given as a prior: the point fit at its values, the
        posterior around them.
    note : str or None
        Added to the notes of every profile fitted with a calibration.
    """

    model: str = "rm0"
    r_min: float | None = None
    plate_pair: tuple[float, float] | None = None
    calibration: Calibration | str | os.PathLike[str] | None = None
    bounds: Bounds = field(default_factory=Bounds)
    prior: Any = "bounds"
    K_cone: float | None = None
    fit_K_cone: bool = False
    fix_ratio: bool = True
    kc_over_kphi: float | None = None
    noise_floor: float = 0.01
    library: LibraryPrior | None = None
    law: PressureLaw = field(init=False, repr=False, compare=False)
    fit_bounds: Bounds = field(init=False, repr=False, compare=False)
    ratio: float | None = field(init=False, repr=False, compare=False)
    centre: CalibrationPrior | None = field(init=False, repr=False, compare=False)
    note: str | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        put = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen fields
        if self.model not in ("rm0", "rm1"):
            raise ValueError(f"model must be 'rm0' or 'rm1' (got {self.model!r})")
        if self.bounds is None:
            put("bounds", Bounds())
        if isinstance(self.calibration, str | os.PathLike):
            put("calibration", Calibration.load(self.calibration))
        if self.kc_over_kphi is not None and not self.kc_over_kphi >= 0:
            raise ValueError(f"kc_over_kphi must be >= 0 [m] (got {self.kc_over_kphi})")
        centre = self._centre()
        self._check_library(centre)
        anchor = self.calibration if self.calibration is not None else _calibration_of(centre)
        fit_bounds, ratio, note = self.bounds, self.kc_over_kphi, None
        if anchor is not None:
            put("model", anchor.model)
            put("r_min", anchor.r_min)
            put("plate_pair", anchor.plate_pair)
            fit_bounds = self.bounds.fixed(phic_deg=anchor.phic_deg, cc=anchor.cc)
            if self.fix_ratio and anchor.kphi > 0:
                ratio = anchor.kc / anchor.kphi
            held = " and kc/kphi" if ratio is not None else ""
            if centre is None:
                note = f"calibration {anchor.terrain!r}: model, r_min, phic, cc{held} fixed"
            else:
                note = (
                    f"prior calibration {anchor.terrain!r}: the fit at its model, r_min, phic, "
                    f"cc{held}; the posterior lets phic, cc and kc/kphi vary around them"
                )
        put("law", pressure_law(self.model, r_min=self.r_min, plate_pair=self.plate_pair))
        put("fit_bounds", fit_bounds)
        put("ratio", ratio)
        put("centre", centre)
        put("note", note)

    def _check_library(self, centre: CalibrationPrior | None) -> None:
        """A library prior excludes a calibration (held or as the prior) and finite Kc."""
        if self.library is None:
            return
        if not isinstance(self.library, LibraryPrior):
            raise TypeError(f"library must be a LibraryPrior (got {type(self.library).__name__})")
        if self.calibration is not None or centre is not None:
            raise ValueError(
                "give a calibration or a library as the prior, not both: a calibration holds "
                "its values, a library weighs its calibrations by the data"
            )
        if self.K_cone is not None or self.fit_K_cone:
            raise ValueError("a library prior needs fully mobilised shear (no K_cone)")
        if not self.fix_ratio:
            raise ValueError("a library prior holds each calibration's kc/kphi (fix_ratio=True)")

    def _centre(self) -> CalibrationPrior | None:
        """The calibration given as a prior, or None (checked against ``calibration``)."""
        p = self.prior
        if isinstance(p, str):
            if p not in ("bounds", "calibration"):
                raise ValueError(
                    f"prior must be 'bounds', 'calibration' or a Calibration (got {p!r})"
                )
            if p == "calibration" and self.calibration is None:
                raise ValueError("prior 'calibration' needs a calibration")
            return None
        centre = as_calibration_prior(p)
        if self.calibration is not None:
            if centre is not None and centre.calibration.to_json() != self.calibration.to_json():
                raise ValueError(
                    "give the calibration once: as the calibration (its values held) or as "
                    "the prior (its values the prior's centre), not two different ones"
                )
            return None  # the calibration holds its values: the prior is the held box
        return centre

    @property
    def calibrated(self) -> bool:
        """Whether a calibration (held, or as the prior's centre) sets phic, cc and kc/kphi."""
        return self.calibration is not None or self.centre is not None

    @property
    def anchor(self) -> Calibration | None:
        """The calibration this problem is built on, held or as the prior's centre."""
        return self.calibration if self.calibration is not None else _calibration_of(self.centre)

    @property
    def vectorised(self) -> bool:
        """True when the fits go through the vectorised exact solver (fully mobilised)."""
        return self.K_cone is None and not self.fit_K_cone

    def notes_for(self, cone: str) -> list[str]:
        """What every fit of a profile taken with ``cone`` (its name) says of this problem.

        The calibration's note, and, where the calibration was learned with
        another cone, that it is applied across cones (the model carries the
        cone's geometry, eqs. (2-5) to (2-7); phic and cc were learned at the
        other cone's size).
        """
        out = [self.note] if self.note else []
        cal = self.anchor
        if cal is not None and cal.cone and cal.cone != cone:
            out.append(
                f"calibration {cal.terrain!r} was learned with the {cal.cone} cone; "
                f"applied to the {cone} cone"
            )
        return out

    def held(self) -> dict[str, float]:
        """The values held in every fit *and* every posterior draw (SI): phic, cc, kc/kphi.

        Empty without a calibration; a calibration given as the prior holds
        nothing in the posterior (its draws vary around it).
        """
        cal = self.calibration
        if cal is None:  # a calibration as the prior's centre: its draws vary around it
            return {} if self.ratio is None or self.centre else {"kc_over_kphi": self.ratio}
        out = {"phic_deg": float(cal.phic_deg), "cc": float(cal.cc)}
        if self.ratio is not None:
            out["kc_over_kphi"] = float(self.ratio)
        return out

    def prior_label(self) -> str:
        """ "bounds", "calibration:<terrain>" or "library:<file>" (as result files record it)."""
        if self.library is not None:
            return self.library.describe()
        cal = self.anchor
        return "bounds" if cal is None else f"calibration:{cal.terrain}"

    def record(self) -> dict[str, Any]:
        """What a run fitted, as result documents and batch's ``_run.json`` record it (SI)."""
        cal = self.anchor
        out = {
            "model": self.model,
            "r_min": self.r_min,
            "plate_pair": None if self.plate_pair is None else list(self.plate_pair),
            "calibration": None if cal is None else cal.terrain,
            "prior": self.prior_label(),
            "kc_over_kphi": self.ratio,
        }
        if self.library is not None:
            out.update(library=self.library.source, candidates=self.library.names)
        return out

    def with_bounds(self, bounds: Bounds) -> Problem:
        """The same problem over another search box (the held values pinned again)."""
        return replace(self, bounds=bounds)

    def held_problem(self, calibration: Calibration) -> Problem:
        """One candidate's problem: this one with ``calibration`` held, without the library.

        Its model, r_min, plate pair, phic, cc and kc/kphi are held (as with
        ``calibration=``); the bounds, noise floor and the rest are this
        problem's.
        """
        return replace(self, calibration=calibration, library=None, prior="bounds")

    def without_library(self) -> Problem:
        """This problem without its library: today's uncalibrated problem (the fall-back)."""
        return replace(self, library=None)

    def candidates(
        self, cone: str, soil: str | None = None
    ) -> list[tuple[Calibration, Problem, float]]:
        """The library's candidates for a profile of ``cone``: (calibration, held problem,
        prior weight), in library order; empty without a library or without a calibration
        of that cone.  ``soil``: the profile's soil class (:meth:`LibraryPrior.prior_weight`).
        """
        lib = self.library
        if lib is None:
            return []
        return [
            (lib.calibrations[i], self.held_problem(lib.calibrations[i]), lib.prior_weight(i, soil))
            for i in lib.of_cone(cone)
        ]

    def require_single(self, what: str) -> None:
        """Raise ValueError when this problem has a library (``what`` does not mix candidates)."""
        if self.library is not None:
            raise ValueError(
                f"{what} takes one problem, not a library prior: fit with the library "
                "(predict_many, fit_sites), or give one calibration"
            )


def _calibration_of(centre: Any) -> Calibration | None:
    return None if centre is None else centre.calibration

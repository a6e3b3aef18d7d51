"""The paper's two case studies as data, and their synthetic data.

SYNTHETIC DATA: CI profiles and plate tests generated from the published
parameters (Tables 4-1 and 4-3 of [1]_) and Wong's LETE sand values with the
noise model :data:`NOISE_MODEL`.  Each case study is one :class:`CaseSpec`
(:data:`CASES`); :meth:`Case.generate` makes its data, and the run
(:mod:`terracone.apps.reproduce.fits`) fills in its results.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-1 and 4-3.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from terracone.apps.reproduce.paper import published_parameters
from terracone.data import CIProfile, PlateTest, TerrainParameters
from terracone.inverse.evaluate import PlateEvaluation
from terracone.inverse.learning.learn import LearnResult
from terracone.inverse.problem import Calibration
from terracone.physics import units as u
from terracone.physics.cone import cone_index
from terracone.physics.plate import plate_pressure
from terracone.result import PredictionResult

__all__ = [
    "CASES",
    "Case",
    "CaseSpec",
    "Group",
    "KRC_FORCE_LIMIT",
    "LABEL",
    "NOISE_MODEL",
    "SYNTHETIC_KEYS",
    "SYNTHETIC_TEXT",
    "WONG_LETE",
    "si_row",
]

SEED_LETE = 1981
SEED_KRC = 2018
CI_NOISE = 0.03
PLATE_NOISE = 0.02
LETE_PAIR_SPREAD = 0.10
GENERATING_MODEL = "rm0"
CI_DEPTHS = np.round(np.arange(0.0, 0.3001, 0.01), 4)  # cone-base depth [m]
SINKAGES = np.round(np.arange(0.002, 0.1001, 0.002), 4)  # [m]
LETE_PLATES = {"r=3.75cm": 0.0375, "r=5cm": 0.05}  # radius [m]
KRC_PLATES = {"D=10cm": 2.0 * u.INCH, "D=15cm": 3.0 * u.INCH}  # 4 in and 6 in diameter
KRC_FORCE_LIMIT = 1500.0 * u.LBF  # [N]
#: Wong's LETE sand values (section 2 of the paper; Wong, 1981), SI.
WONG_LETE = {"kc": 102.0, "kphi": 5301.0, "n": 0.79}
LABEL = "SYNTHETIC"
SYNTHETIC_TEXT = (
    "Every curve, table and figure computed here comes from data that terracone generated "
    "from the paper's published parameters (Tables 4-1 and 4-3) and Wong's LETE sand values, "
    "with a stated noise model. They are not the paper's measurements, which were never "
    "published. Columns marked 'paper' are the published values."
)
#: In every JSON document written.
SYNTHETIC_KEYS = {"synthetic": True, "note": SYNTHETIC_TEXT}

NOISE_MODEL = [
    f"CI: each reading x (1 + {CI_NOISE:g} e), e ~ N(0, 1) independent; cone-base depths 0 to "
    "30 cm every 1 cm; standard 30 deg, 0.5 in^2 cone; improved model eq. (2-7), "
    f"{GENERATING_MODEL.upper()} (r_min is not published), fully mobilised shear.",
    f"Plates: each pressure x (1 + {PLATE_NOISE:g} e); sinkage 2 to 100 mm every 2 mm; "
    "Bekker equation (2-2).",
    f"LETE plate pairs LS_A..LS_E: one factor exp({LETE_PAIR_SPREAD:g} g), g ~ N(0, 1), per "
    "pair (spread between tests on one site); radii 3.75 cm and 5 cm; Wong's LETE values "
    "kc 102 kN/m^(n+1), kphi 5301 kN/m^(n+2), n 0.79.",
    "KRC plates: 4 in (10.16 cm) and 6 in (15.24 cm) diameter, from the site's Table 4-3 "
    "parameters (the KRC plate data were never published); each test ends at 1,500 lbf "
    "(6,672 N): 823 kPa on the 4 in plate, 366 kPa on the 6 in plate.",
    f"Random numbers: numpy PCG64, seed {SEED_LETE} (LETE) and {SEED_KRC} (KRC); values "
    "rounded to 0.01 kPa.",
]


class Group(NamedTuple):
    """One learning run: LETE learns once on all its data, KRC once per site."""

    id: str
    profiles: list[CIProfile]
    plates: list[PlateTest]


@dataclass(frozen=True)
class CaseSpec:
    """What differs between the two case studies (one column of ``_CASE_TABLE``)."""

    slug: str  # file names and table keys: "lete", "krc"
    name: str  # "LETE sand", "KRC"
    seed: int
    parameter_table: str  # the paper's table of parameters: "4-1", "4-3"
    agreement_table: str  # the paper's table of agreement: "4-2", "4-4"
    quick_ids: tuple[str, ...]  # the profiles of a quick run
    plates: dict[str, float]  # plate label -> radius [m]
    per_site: bool  # learning, calibration files and evaluation rows per site
    generate: Callable[[CaseSpec, list[dict[str, Any]], bool], Case]  # the synthetic data
    files: tuple[str, str]  # data/ file names: CI profiles, plate tests
    comments: tuple[str, str]  # what each data file holds (its header)


@dataclass
class Case:
    """One case study: its spec, synthetic data, and results as the run fills them in.

    All in SI.  ``learned`` and ``cals`` by group id; ``cal_res`` and ``free_res``:
    each profile predicted with its calibration and from the CI alone; ``posts``:
    the posterior of each profile (``as_dict("si")``, None where not computed);
    ``rows_cal``, ``rows_free``, ``rows_ctrl``: agreement rows of the predictions
    with the calibration, from the CI alone and of the published parameters against
    the plates; ``published``: the paper's agreement table.
    """

    spec: CaseSpec
    pub: list[dict[str, Any]]  # published parameters of the profiles (generated the CI)
    profiles: list[CIProfile]
    plates: list[PlateTest]
    where: dict[str, tuple[str, str]]  # plate test id -> (pair or site, plate label)
    groups: list[Group]
    learned: dict[str, LearnResult] = field(default_factory=dict)  # by group id
    cals: dict[str, Calibration] = field(default_factory=dict)  # by group id
    cal_res: list[PredictionResult] = field(default_factory=list)
    free_res: list[PredictionResult] = field(default_factory=list)
    posts: dict[str, dict[str, Any] | None] = field(default_factory=dict)
    evals_cal: list[PlateEvaluation] = field(default_factory=list)
    rows_cal: list[dict[str, Any]] = field(default_factory=list)
    rows_free: list[dict[str, Any]] = field(default_factory=list)
    rows_ctrl: list[dict[str, Any]] = field(default_factory=list)
    published: list[dict[str, Any]] = field(default_factory=list)

    @staticmethod
    def generate(spec: CaseSpec, quick: bool) -> Case:
        """The case study's synthetic data (results still empty)."""
        pub = published_parameters(spec.parameter_table)
        if quick:
            pub = [p for p in pub if p["id"] in spec.quick_ids]
        return spec.generate(spec, pub, quick)

    def group_of(self, profile_id: str) -> Group:
        """The learning group of profile ``profile_id``."""
        return next(g for g in self.groups if any(p.id == profile_id for p in g.profiles))

    def cal_of(self, profile_id: str) -> Calibration:
        """The calibration learned for profile ``profile_id`` (its group's)."""
        return self.cals[self.group_of(profile_id).id]


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------


def _ci_profile(site: str, p: dict[str, Any], rng: np.random.Generator, case: str) -> CIProfile:
    params = {k: p[k] for k in ("kc", "kphi", "n", "cc", "phic_deg")}
    ci = cone_index(CI_DEPTHS, **params, model=GENERATING_MODEL)
    ci = ci * (1.0 + CI_NOISE * rng.standard_normal(CI_DEPTHS.size))
    meta = {"case": case, "data": LABEL}
    return CIProfile(site, CI_DEPTHS.copy(), np.round(ci, 2), metadata=meta)


def _plate_test(pair: str, key: str, r: float, sinkage, pressure) -> PlateTest:
    id_, meta = f"{pair}_{key.replace('=', '')}", {"pair": pair, "plate": key, "data": LABEL}
    return PlateTest(id_, r, "circular", sinkage.copy(), np.round(pressure, 2), metadata=meta)


def _lete_data(spec: CaseSpec, pub: list[dict[str, Any]], quick: bool) -> Case:
    """CI from Table 4-1, plate pairs from Wong's values; one learning on everything."""
    rng = np.random.default_rng(spec.seed)
    profiles = [_ci_profile(p["id"], p, rng, spec.name) for p in pub]
    pairs = ["LS_A", "LS_B", "LS_C", "LS_D", "LS_E"][: 3 if quick else 5]
    plates, where = [], {}
    for pair in pairs:
        f = math.exp(LETE_PAIR_SPREAD * rng.standard_normal())
        for key, r in spec.plates.items():
            p = plate_pressure(SINKAGES, radius=r, **WONG_LETE)
            p = p * f * (1.0 + PLATE_NOISE * rng.standard_normal(SINKAGES.size))
            plates.append(_plate_test(pair, key, r, SINKAGES, p))
            where[plates[-1].id] = (pair, key)
    return Case(spec, pub, profiles, plates, where, [Group(spec.name, profiles, plates)])


def _krc_data(spec: CaseSpec, pub: list[dict[str, Any]], quick: bool) -> Case:
    """Per site, CI and a plate pair (ending at 1,500 lbf) from its Table 4-3 row."""
    rng = np.random.default_rng(spec.seed)
    profiles, plates, where, groups = [], [], {}, []
    for p in pub:
        prof = _ci_profile(p["id"], p, rng, spec.name)
        site_plates = []
        for key, r in spec.plates.items():
            clean = plate_pressure(SINKAGES, kc=p["kc"], kphi=p["kphi"], n=p["n"], radius=r)
            limit = KRC_FORCE_LIMIT / (math.pi * r * r) / 1000.0  # [kPa]
            noisy = clean * (1.0 + PLATE_NOISE * rng.standard_normal(SINKAGES.size))
            keep = clean <= limit
            if keep.sum() < 3:  # a very stiff site: keep the first points
                keep[:3] = True
            site_plates.append(_plate_test(p["id"], key, r, SINKAGES[keep], noisy[keep]))
            where[site_plates[-1].id] = (p["id"], key)
        profiles.append(prof)
        plates += site_plates
        groups.append(Group(p["id"], [prof], site_plates))
    return Case(spec, pub, profiles, plates, where, groups)


def si_row(params: TerrainParameters, id_: str) -> dict[str, Any]:
    """A table row of ``params``: ``id`` and the parameters in SI."""
    return {"id": id_, **params.as_dict("si")}


#: The two case studies side by side: one row per field of :class:`CaseSpec`,
#: one column per case study (LETE sand, KRC), in the order of the report.
_CASE_TABLE: dict[str, tuple[Any, Any]] = {
    "slug": ("lete", "krc"),
    "name": ("LETE sand", "KRC"),
    "seed": (SEED_LETE, SEED_KRC),
    "parameter_table": ("4-1", "4-3"),
    "agreement_table": ("4-2", "4-4"),
    "quick_ids": (("LS_1", "LS_2"), ("KRC_1", "KRC_3")),
    "plates": (LETE_PLATES, KRC_PLATES),
    "per_site": (False, True),
    "generate": (_lete_data, _krc_data),
    "files": (
        ("lete_sand_synthetic_ci.csv", "lete_sand_synthetic_plates.csv"),
        ("krc_synthetic_ci.csv", "krc_synthetic_plates.csv"),
    ),
    "comments": (
        (
            "CI from Table 4-1 parameters, improved model RM0. " + NOISE_MODEL[0],
            "Plates from Wong's LETE sand values. " + NOISE_MODEL[2],
        ),
        (
            "CI from Table 4-3 parameters, improved model RM0. " + NOISE_MODEL[0],
            "Plates from the same Table 4-3 parameters. " + NOISE_MODEL[3],
        ),
    ),
}
#: The case studies: LETE sand, KRC.
CASES = tuple(CaseSpec(**{name: row[i] for name, row in _CASE_TABLE.items()}) for i in range(2))

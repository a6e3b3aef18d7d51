"""The words of the reproduce report: its sections, and each table's and figure's text.

Each case study's report is a list of :class:`Section` (:data:`SECTIONS`), each a
list of part names; :mod:`terracone.report.reproduce.builders` draws each part
and takes its text from :data:`TEXTS` (a table's keyword arguments: key, title,
notes, ...; a figure's key, title and caption).  The reading of ours against the
paper, with the numbers of a run, is :mod:`terracone.report.reproduce.reading`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

__all__ = [
    "ABOUT",
    "ABOUT_POINTS",
    "KRC_FIGURE",
    "PUBLISHED_LABEL",
    "SECTIONS",
    "TEXTS",
    "Section",
]


class Section(NamedTuple):
    """One section of the report: anchor, heading and the parts drawn in it, in order."""

    id: str
    heading: str
    parts: str  # names of the parts (keys of ``builders.PARTS``), separated by spaces
    full_only: bool = False  # left out of a quick run


#: KRC site -> the number of its figure in the paper (Figures 4-3 to 4-10).
KRC_FIGURE = {f"KRC_{site}": f"4-{k}" for k, site in enumerate((1, 2, 3, 4, 7, 9, 24, 25), 3)}


#: What this is: the first section of the report, a paragraph and a list.
ABOUT = (
    "The paper demonstrates its method on two sets of measurements, LETE sand "
    "(1981) and KRC soils (2018). Only the parameters fitted to them (Tables "
    "4-1 and 4-3) and the agreement statistics (Tables 4-2 and 4-4) were "
    "published; the measured CI and plate curves were not. This report "
    "re-creates both case studies on SYNTHETIC data generated from the "
    "published parameters, runs them through terracone's learning, prediction "
    "and evaluation processes, and sets the results beside the published "
    "tables."
)
ABOUT_POINTS = [
    "LETE sand: 4 CI profiles (LS_1..LS_4) from Table 4-1; 5 plate pairs "
    "(LS_A..LS_E, radii 3.75 and 5 cm) from Wong's LETE sand values "
    "(kc 102 kN/m^(n+1), kphi 5301 kN/m^(n+2), n 0.79).",
    "KRC: 8 sites, each a CI profile and a 4 in / 6 in plate pair, both "
    "from the site's Table 4-3 parameters (the KRC plate measurements "
    "were never published).",
    "CI generated with the improved model RM0: the paper does not publish "
    "r_min, and RM0 needs no invented value. Learning then searches RM1 "
    "and its r_min, as in the paper.",
    "Tables 4-1 to 4-4 analogues use the predictions made with the learned "
    "calibration (the paper's learning-then-prediction process); the "
    "predictions from the CI alone are shown beside them.",
    "The paper's 10 cm and 15 cm KRC plates are 4 in and 6 in (10.16 and "
    "15.24 cm): its recommendation G gives 1,500 lb as 119 and 53 psi, "
    "which holds for 4 in and 6 in diameters.",
]


#: LETE sand: the report's sections, each a list of parts (keys of ``builders.PARTS``).
LETE_SECTIONS = (
    Section(
        "lete-learning",
        "LETE sand: learning and Figure 2-1",
        "learning learning_datasets fig_janosi",
    ),
    Section(
        "lete-prediction",
        "LETE sand: prediction (Table 4-1, Figure 4-1)",
        "parameters parameters_vs_published fig_ci identifiability identifiability_ci_only",
    ),
    Section(
        "lete-plates",
        "LETE sand: plates (Figure 4-2, Table 4-2)",
        "fig_plates agreement agreement_vs_published agreement_control fig_plates_ci_only "
        "agreement_ci_only",
    ),
    Section("lete-ridge", "LETE sand: the ridge of equally good fits", "fig_ridge"),
)

#: LETE sand: the text of each part: a table's keyword arguments (key, title, notes, ...).
LETE_TEXTS: dict[str, dict[str, Any]] = {
    "learning": {
        "key": "lete_learning",
        "title": "LETE sand: learning process (section 3.3.1) on all CI profiles and plate tests",
        "first": "Parameters",
        "notes": [
            "The CI profiles were generated from the Table 4-1 parameters and the plates "
            "from Wong's values: the learning fits both, as the paper's learning fitted "
            "measured CI and plate curves of one terrain.",
        ],
    },
    "learning_datasets": {
        "key": "lete_learning_datasets",
        "title": "LETE sand: fit of the learned parameters per data set",
    },
    "parameters": {
        "key": "table_4_1_lete_parameters",
        "title": "Table 4-1 analogue: parameters predicted from the LETE sand CI (with the "
        "learned calibration)",
        "notes": [
            "Prediction process (section 3.3.2) with the LETE calibration: model RM1, "
            "r_min, phic, cc and kc/kphi fixed by learning; n and the scale of kc, kphi "
            "from each CI.",
        ],
    },
    "parameters_vs_published": {
        "notes": [
            "The published rows are the truth of the synthetic CI; 'CI alone' reports phic "
            "at the middle of the interval that fits equally well.",
            "Published US columns as recomputed by terracone.physics.units from the SI values.",
        ],
    },
    "identifiability": {
        "key": "lete_identifiability",
        "title": "LETE sand: what each CI profile determines (with the calibration)",
        "notes": [
            "From the posterior of terracone.uncertainty (90% width over prior width: "
            "< 0.25 determined, < 0.75 weakly determined, else set by prior) where "
            "computed; otherwise from the profile intervals of the exact solver.",
        ],
    },
    "identifiability_ci_only": {
        "key": "lete_identifiability_ci_only",
        "title": "LETE sand: what each CI profile determines on its own (no calibration)",
    },
    "agreement": {
        "key": "table_4_2_lete_agreement",
        "title": "Table 4-2 analogue: R, R2, RMSD, CV between the LETE sand plate curves "
        "and those predicted from the CI (with the calibration)",
        "notes": ["r=3.75cm: plate radius 3.75 cm (1.5 in); r=5cm: radius 5 cm (1.97 in)."],
    },
    "agreement_control": {
        "key": "table_4_2_lete_published_parameters",
        "title": "Control: the published Table 4-1 parameters against our synthetic plate tests",
        "notes": [
            "No inversion involved: the paper's own parameters evaluated against plates "
            "generated from Wong's values. The nearest analogue of the paper's Table 4-2."
        ],
    },
    "agreement_ci_only": {
        "key": "table_4_2_lete_ci_only",
        "title": "LETE sand, CI alone (no calibration): R, R2, RMSD, CV against the plate tests",
    },
    # figures: key, title and caption
    "fig_janosi": {
        "key": "fig_2_1_lete_janosi",
        "title": "Figure 2-1 analogue: LETE sand CI and the Janosi equation",
        "params_label": "Wong's kc 102, kphi 5301, n 0.79",
        "improved_label": "improved model eq. (2-7), same kc, kphi, n; learned phic, cc, r_min",
        "caption": "Figure 2-1 analogue. SYNTHETIC LETE sand CI profiles (dashed) against "
        "the Janosi equation (2-1) with Wong's plate-derived kc, kphi, n (solid), and the "
        "improved model with the same kc, kphi, n and the learned phic, cc, r_min "
        "(dotted). As in the paper, the Janosi equation falls far below the measured CI.",
    },
    "fig_ci": {
        "key": "fig_4_1_lete_ci",
        "title": "Figure 4-1 analogue: LETE sand CI, measured and predicted",
        "caption": "Figure 4-1 analogue. SYNTHETIC LETE sand CI-sinkage curves (dashed, "
        "open markers) and those predicted with the learned calibration (solid).",
    },
    "fig_plates": {
        "key": "fig_4_2_lete_plates",
        "title": "Figure 4-2 analogue: LETE sand plates, measured and predicted",
        "caption": "Figure 4-2 analogue. (a) 3.75 cm and (b) 5 cm radius plates: SYNTHETIC "
        "measured curves {pairs} (dashed) and curves predicted from {profiles} with the "
        "calibration (solid){bands}",
        "band_note": "; hatched: 90% posterior band of LS_1 (terracone.uncertainty).",
    },
    "fig_plates_ci_only": {
        "key": "fig_4_2_lete_plates_ci_only",
        "title": "LETE sand plates predicted from the CI alone (no calibration)",
        "caption": "The same plates against the curves predicted from each CI profile "
        "alone: without the calibration the CI does not fix how the load splits between "
        "kc and kphi, and the predicted plate pressure drifts.",
    },
    "fig_ridge": {
        "key": "ridge_lete_{id}",
        "caption": "Not in the paper. RMSD of the best fit to the SYNTHETIC {id} CI over "
        "(phic, n) with kc, kphi, cc re-fitted at each point (a), over phic and a common "
        "scale of kc and kphi (b), and its profiles over n (c) and phic (d). The CI fixes "
        "n; it does not fix phic, which trades exactly against the scale of kc and kphi: "
        "the published phic is one point of a flat valley.",
    },
}

#: KRC: the report's sections, each a list of parts (keys of ``builders.PARTS``).
KRC_SECTIONS = (
    Section(
        "krc-prediction",
        "KRC: learning and prediction (Table 4-3)",
        "learning_per_site parameters parameters_vs_published identifiability "
        "identifiability_ci_only",
    ),
    Section("krc-figures", "KRC: Figures 4-3 to 4-10", "fig_sites"),
    Section(
        "krc-agreement", "KRC: Table 4-4", "agreement agreement_vs_published agreement_ci_only"
    ),
    Section("krc-ridge", "KRC: the ridge of equally good fits", "fig_ridge", full_only=True),
)

#: KRC: the text of each part: a table's keyword arguments (key, title, notes, ...).
KRC_TEXTS: dict[str, dict[str, Any]] = {
    "learning_per_site": {
        "key": "krc_learning",
        "title": "KRC: learning process per site (CI and the site's plate pair)",
    },
    "parameters": {
        "key": "table_4_3_krc_parameters",
        "title": "Table 4-3 analogue: parameters predicted from the KRC CI (with each "
        "site's calibration)",
    },
    "identifiability": {
        "key": "krc_identifiability",
        "title": "KRC: what each CI profile determines (with the site's calibration)",
    },
    "identifiability_ci_only": {
        "key": "krc_identifiability_ci_only",
        "title": "KRC: what each CI profile determines on its own",
    },
    "agreement": {
        "key": "table_4_4_krc_agreement",
        "title": "Table 4-4 analogue: R, R2, RMSD, CV between the KRC plate curves and "
        "those predicted from the CI (with each site's calibration)",
        "same_site": True,
        "notes": ["D=10cm: the 4 in (10.16 cm) plate; D=15cm: the 6 in (15.24 cm) plate."],
    },
    "agreement_ci_only": {
        "key": "table_4_4_krc_ci_only",
        "title": "KRC, CI alone (no calibration): R, R2, RMSD, CV against the site's plates",
        "same_site": True,
    },
    # figures: key, title and caption
    "fig_sites": {
        "numbers": KRC_FIGURE,
        "key": "fig_{number}_{lower}",
        "title": "Figure {number} analogue: {id} measured and predicted",
        "caption": "Figure {number} analogue. {id}: (a) SYNTHETIC CI (dashed) and "
        "predicted CI (solid); (b) SYNTHETIC plate curves of the 4 in and 6 in plates "
        "(dashed, ending at 1,500 lbf) and those predicted with the site's calibration "
        "(solid){bands}",
        "band_note": "; hatched: 90% posterior band.",
    },
    "fig_ridge": {
        "key": "ridge_krc_{lower}",
        "caption": "As the LETE ridge figure, for the SYNTHETIC {id} CI profile.",
    },
}


#: Case study (its slug) -> the report's sections.
SECTIONS: dict[str, tuple[Section, ...]] = {"lete": LETE_SECTIONS, "krc": KRC_SECTIONS}
#: Case study -> the text of each part (keys of ``builders.PARTS``).
TEXTS: dict[str, dict[str, dict[str, Any]]] = {"lete": LETE_TEXTS, "krc": KRC_TEXTS}
#: Case study -> the label of the published parameters beside ours.
PUBLISHED_LABEL = {
    "lete": "paper (Table 4-1; generated the CI)",
    "krc": "paper (Table 4-3; generated CI and plates)",
}

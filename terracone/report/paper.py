"""The published values of Tables 4-1 to 4-4, shipped as package data.

``terracone/data/paper/table_4_*.csv`` hold the values as printed in [1]_
(typed in, with the citation in a header comment).  They are used by
:mod:`terracone.apps.reproduce` to generate synthetic data (Tables 4-1 and 4-3)
and to set our results beside the paper's (Tables 4-2 and 4-4).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Tables 4-1 to 4-4.
"""

from __future__ import annotations

import csv
from importlib.resources import files
from pathlib import Path
from typing import Any

from terracone.physics import units as u

__all__ = [
    "CITATION",
    "paper_dir",
    "published_parameters",
    "published_agreement",
    "us_column_check",
]

CITATION = (
    'Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P., "Predicting terrain parameters '
    'for physics-based vehicle mobility models from cone index data"'
)

_PARAM_FILES = {"4-1": "table_4_1.csv", "4-3": "table_4_3.csv"}
_AGREE_FILES = {"4-2": "table_4_2.csv", "4-4": "table_4_4.csv"}


def paper_dir() -> Path:
    """Folder of the published tables."""
    return Path(str(files("terracone") / "data" / "paper"))


def _read(name: str) -> list[dict[str, str]]:
    with open(paper_dir() / name, newline="") as fh:
        lines = [line for line in fh if line.strip() and not line.startswith("#")]
    return list(csv.DictReader(lines))


def published_parameters(table: str) -> list[dict[str, Any]]:
    """Rows of Table 4-1 or 4-3: ``id`` and SI ``kc, kphi, n, cc, phic_deg``.

    The US columns as printed are kept as ``kc_us_printed``,
    ``kphi_us_printed``, ``cc_us_printed``.
    """
    if table not in _PARAM_FILES:
        raise ValueError(f"table must be one of {sorted(_PARAM_FILES)} (got {table!r})")
    out = []
    for r in _read(_PARAM_FILES[table]):
        out.append(
            {
                "id": r["dataset"],
                "kc": float(r["kc_kn_m"]),
                "kphi": float(r["kphi_kn_m"]),
                "n": float(r["n"]),
                "cc": float(r["cc_kpa"]),
                "phic_deg": float(r["phic_deg"]),
                "kc_us_printed": float(r["kc_lb_in"]),
                "kphi_us_printed": float(r["kphi_lb_in"]),
                "cc_us_printed": float(r["cc_psi"]),
            }
        )
    return out


def published_agreement(table: str) -> list[dict[str, Any]]:
    """Rows of Table 4-2 or 4-4, one per (CI data, P-S data, plate).

    Keys: ``prediction``, ``pair``, ``plate`` (``r=3.75cm``, ``r=5cm``,
    ``D=10cm``, ``D=15cm``), ``R``, ``R2``, ``RMSD`` [kPa], ``RMSD_psi``,
    ``CV``.
    """
    if table not in _AGREE_FILES:
        raise ValueError(f"table must be one of {sorted(_AGREE_FILES)} (got {table!r})")
    out = []
    for r in _read(_AGREE_FILES[table]):
        out.append(
            {
                "prediction": r["ci_dataset"],
                "pair": r["ps_dataset"],
                "plate": r["plate"],
                "R": float(r["R"]),
                "R2": float(r["R2"]),
                "RMSD": float(r["RMSD_kpa"]),
                "RMSD_psi": float(r["RMSD_psi"]),
                "CV": float(r["CV"]),
            }
        )
    return out


def us_column_check(tolerance: float = 0.02) -> list[dict[str, Any]]:
    """Do the printed US columns of Tables 4-1 and 4-3 follow from the SI ones?

    For each row, the US values of kc, kphi (which depend on n) and cc are
    recomputed from the SI values with :mod:`terracone.physics.units` and compared
    with the printed ones.  Returns one dict per mismatch larger than
    ``tolerance`` (relative; zero values must match exactly).
    """
    bad = []
    for table in ("4-1", "4-3"):
        for r in published_parameters(table):
            n = r["n"]
            calc = {
                "kc": float(u.kc_from_si(r["kc"], n, "us")),
                "kphi": float(u.kphi_from_si(r["kphi"], n, "us")),
                "cc": float(u.pressure_from_si(r["cc"], "us")),
            }
            for k, v in calc.items():
                printed = r[f"{k}_us_printed"]
                # the paper prints cc = 1 kPa as 0.15 psi: allow rounding to 2 decimals
                tol = max(tolerance * abs(v), 0.006 if k == "cc" else 0.0)
                if abs(printed - v) > tol:
                    bad.append(
                        {
                            "table": table,
                            "id": r["id"],
                            "param": k,
                            "si": r[k],
                            "us_printed": printed,
                            "us_computed": v,
                        }
                    )
    return bad

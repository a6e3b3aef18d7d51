"""The published values of Tables 4-1 to 4-4, shipped as package data.

``terracone/data/paper/table_4_*.csv`` hold the values as printed in [1]_
(typed in, with the citation in a header comment).  :mod:`terracone.apps.reproduce`
generates synthetic data from them (Tables 4-1 and 4-3) and
:mod:`terracone.report.reproduce` sets our results beside them (Tables 4-1 to 4-4).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Tables 4-1 to 4-4.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from importlib.resources import files
from pathlib import Path
from typing import Any

from terracone.resultunits import convert_parameters

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

# key -> CSV column of the parameter tables (4-1, 4-3) and the agreement tables (4-2, 4-4)
_PARAM_COLUMNS = dict(kc="kc_kn_m", kphi="kphi_kn_m", n="n", cc="cc_kpa", phic_deg="phic_deg")
_PARAM_COLUMNS.update(
    kc_us_printed="kc_lb_in", kphi_us_printed="kphi_lb_in", cc_us_printed="cc_psi"
)
_AGREE_COLUMNS = dict(R="R", R2="R2", RMSD="RMSD_kpa", RMSD_psi="RMSD_psi", CV="CV")


def paper_dir() -> Path:
    """Folder of the published tables."""
    return Path(str(files("terracone") / "data" / "paper"))


def _read(
    table: str, tables: Sequence[str], text: Mapping[str, str], numbers: Mapping[str, str]
) -> list[dict[str, Any]]:
    """Rows of ``table_4_N.csv``: ``text`` columns as read, ``numbers`` as floats."""
    if table not in tables:
        raise ValueError(f"table must be one of {sorted(tables)} (got {table!r})")
    with open(paper_dir() / f"table_{table.replace('-', '_')}.csv", newline="") as fh:
        lines = [line for line in fh if line.strip() and not line.startswith("#")]
    return [
        {**{k: r[c] for k, c in text.items()}, **{k: float(r[c]) for k, c in numbers.items()}}
        for r in csv.DictReader(lines)
    ]


def published_parameters(table: str) -> list[dict[str, Any]]:
    """Rows of Table 4-1 or 4-3: ``id`` and SI ``kc, kphi, n, cc, phic_deg``.

    The US columns as printed are kept as ``kc_us_printed``,
    ``kphi_us_printed``, ``cc_us_printed``.
    """
    return _read(table, ("4-1", "4-3"), {"id": "dataset"}, _PARAM_COLUMNS)


def published_agreement(table: str) -> list[dict[str, Any]]:
    """Rows of Table 4-2 or 4-4, one per (CI data, P-S data, plate).

    Keys: ``prediction``, ``pair``, ``plate`` (``r=3.75cm``, ``r=5cm``,
    ``D=10cm``, ``D=15cm``), ``R``, ``R2``, ``RMSD`` [kPa], ``RMSD_psi``,
    ``CV``.
    """
    text = {"prediction": "ci_dataset", "pair": "ps_dataset", "plate": "plate"}
    return _read(table, ("4-2", "4-4"), text, _AGREE_COLUMNS)


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
            calc = convert_parameters({k: r[k] for k in ("kc", "kphi", "cc")}, "us", n)
            for k, v in calc.items():
                printed = r[f"{k}_us_printed"]
                # the paper prints cc = 1 kPa as 0.15 psi: allow rounding to 2 decimals
                tol = max(tolerance * abs(v), 0.006 if k == "cc" else 0.0)
                if abs(printed - v) > tol:
                    row = {"table": table, "id": r["id"], "param": k, "si": r[k]}
                    bad.append({**row, "us_printed": printed, "us_computed": v})
    return bad

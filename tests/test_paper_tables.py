"""The package's copies of the paper's Tables 4-1 to 4-4 against ../shared/reference/.

terracone ships the published tables as package data
(``terracone/data/paper/table_4_*.csv``, read by
:mod:`terracone.apps.reproduce.paper`).  The project's shared folder holds the same
tables, typed in independently (``huang2020_predicted_parameters.csv``,
``huang2020_fit_metrics.csv``).  Every value the two have in common must be
the same number; the tests skip with the reason when ../shared is absent.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from conftest import require_shared

from terracone.apps.reproduce.paper import paper_dir, published_agreement, published_parameters


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(ln for ln in fh if ln.strip() and not ln.startswith("#")))


# package column -> shared column
PARAM_COLUMNS = {
    "kc_kn_m": "kc_si",
    "kc_lb_in": "kc_us",
    "kphi_kn_m": "kphi_si",
    "kphi_lb_in": "kphi_us",
    "n": "n",
    "cc_kpa": "cc_kpa",
    "cc_psi": "cc_psi",
    "phic_deg": "phic_deg",
}
AGREE_COLUMNS = ["R", "R2", "RMSD_kpa", "CV"]


def test_tables_4_1_and_4_3_match_the_shared_reference():
    ref = {
        r["dataset"]: r
        for r in _rows(require_shared("reference", "huang2020_predicted_parameters.csv"))
    }
    ours = _rows(paper_dir() / "table_4_1.csv") + _rows(paper_dir() / "table_4_3.csv")
    assert sorted(r["dataset"] for r in ours) == sorted(ref)  # the same 12 data sets
    assert len(ours) == 12
    for r in ours:
        for mine, theirs in PARAM_COLUMNS.items():
            # the same number, printed alike (tests/test_units.py reads the printed precision)
            assert r[mine] == ref[r["dataset"]][theirs], (r["dataset"], mine)
    # and the package reads them as printed (SI values)
    by_id = {p["id"]: p for p in published_parameters("4-1") + published_parameters("4-3")}
    for k, r in ref.items():
        assert by_id[k]["kc"] == float(r["kc_si"]) and by_id[k]["kphi"] == float(r["kphi_si"])
        assert by_id[k]["n"] == float(r["n"]) and by_id[k]["phic_deg"] == float(r["phic_deg"])


def test_tables_4_2_and_4_4_match_the_shared_reference():
    ref_rows = _rows(require_shared("reference", "huang2020_fit_metrics.csv"))
    ref = {(r["ci_dataset"], r["ps_dataset"], r["plate"]): r for r in ref_rows}
    assert len(ref) == len(ref_rows) == 56
    ours = _rows(paper_dir() / "table_4_2.csv") + _rows(paper_dir() / "table_4_4.csv")
    keys = [(r["ci_dataset"], r["ps_dataset"], r["plate"]) for r in ours]
    assert sorted(keys) == sorted(ref)
    for k, r in zip(keys, ours):
        for col in AGREE_COLUMNS:
            assert float(r[col]) == float(ref[k][col]), (k, col)
    read = published_agreement("4-2") + published_agreement("4-4")
    for p in read:
        r = ref[(p["prediction"], p["pair"], p["plate"])]
        assert (p["R"], p["R2"], p["RMSD"], p["CV"]) == tuple(float(r[c]) for c in AGREE_COLUMNS)


@pytest.mark.parametrize(
    "name", ["table_4_1.csv", "table_4_2.csv", "table_4_3.csv", "table_4_4.csv"]
)
def test_package_tables_cite_the_paper(name):
    text = (paper_dir() / name).read_text()
    assert text.startswith("# Source: Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P.")
    assert "Published values as printed in the paper" in text

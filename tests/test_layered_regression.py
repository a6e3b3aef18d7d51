"""No regression: on every Marsden push the layered RMSD is at most the fit's before issue 24.

``tests/data/layered_rmsd_before.csv`` holds our own fits of the pushes of
``../shared/data/marsden-penetrometer`` (both files, the SC900's small cone)
by the layered fit as it was before issue 24 (Python around scipy: a grid
and Nelder-Mead for two layers, Nelder-Mead from six random starts for
three), made by ``python benchmarks/layered_before.py`` (the frozen copy of
that fit).  A guard beside the independent checks of
``tests/test_layered_bruteforce.py``: the new search must never end above
an optimum the old one found.  Tolerance on the objective: RMSD_new <=
RMSD_old (1 + 1e-6) + 1e-6 kPa.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from conftest import require_shared

from terracone.inverse.layered import fit_layered
from terracone.io import read_ci_profiles

RECORD = Path(__file__).parent / "data" / "layered_rmsd_before.csv"


def records() -> list[dict[str, str]]:
    with open(RECORD, newline="") as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


@pytest.fixture(scope="module")
def pushes() -> dict[tuple[str, str], object]:
    """(file, profile id) -> CIProfile of every Marsden push (the recorded cone)."""
    folder = require_shared("data", "marsden-penetrometer")
    out = {}
    for name in sorted({r["file"] for r in records()}):
        for p in read_ci_profiles(folder / name, cone="asabe-small", on_error="collect"):
            if hasattr(p, "depth"):
                out[(name, p.id)] = p
    return out


def test_the_record_covers_every_push_with_two_and_three_layers():
    rows = records()
    by = {(r["file"], r["layers"]) for r in rows}
    assert by == {(f, L) for f in ("ci_profiles.csv", "sc900_export_2019-06-11.txt") for L in "23"}
    assert sum(r["layers"] == "2" for r in rows) == 303
    assert sum(r["layers"] == "3" for r in rows) == 287


@pytest.mark.parametrize("layers", [2, 3])
def test_never_worse_than_before(pushes, layers):
    worse, better = [], 0
    rows = [r for r in records() if int(r["layers"]) == layers]
    for r in rows:
        p = pushes[(r["file"], r["profile"])]
        assert p.depth.size == int(r["points"])
        res = fit_layered(p, layers=layers)
        assert res.ok, (r["profile"], res.error)
        old = float(r["rmsd_kpa"])
        if res.rmsd > old * (1 + 1e-6) + 1e-6:
            worse.append((r["profile"], res.rmsd, old))
        better += res.rmsd < old * (1 - 1e-6)
        assert 0.0 <= res.certificate["lower_bound"] <= res.sse
    assert not worse, worse
    assert better >= 1  # the old search missed optima (a few per cent of the pushes)

"""No regression: on every Marsden push the layered RMSD is at most the fit's before issue 24.

``tests/data/layered_rmsd_before.csv`` holds our own fits of the pushes of
``../shared/data/marsden-penetrometer`` (both files, the SC900's small cone)
by the layered fit as it was before issue 24 (Python around scipy: a grid
and Nelder-Mead for two layers, Nelder-Mead from six random starts for
three), made by ``python benchmarks/layered_before.py`` (the frozen copy of
that fit).  A guard beside the independent checks of
``tests/test_layered_bruteforce.py``: the new search must never end above
an optimum the old one found.  Tolerance on the objective: RMSD_new <=
RMSD_old (1 + 1e-6) + 1e-6 kPa.  The record holds every push the readers
read, with 2 and 3 layers: the pushes the old fit refused (fewer than 5
points per layer) with its reason, which the new fit must give as well.
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
    """(file, profile id) -> CIProfile of every readable Marsden push (the recorded cone)."""
    folder = require_shared("data", "marsden-penetrometer")
    out = {}
    files = sorted(f.name for f in folder.iterdir() if f.suffix in (".csv", ".txt"))
    assert files == ["ci_profiles.csv", "sc900_export_2019-06-11.txt"], files  # its CI files
    for name in files:
        for p in read_ci_profiles(folder / name, cone="asabe-small", on_error="collect"):
            if hasattr(p, "depth"):
                out[(name, p.id)] = p
    return out


def test_the_record_covers_every_push_read_with_two_and_three_layers(pushes):
    rows = records()
    for L in "23":
        recorded = [(r["file"], r["profile"]) for r in rows if r["layers"] == L]
        assert len(recorded) == len(set(recorded)), L  # each push once
        assert set(recorded) == set(pushes), (L, set(pushes) ^ set(recorded))
    assert {r["layers"] for r in rows} == {"2", "3"}
    for r in rows:
        assert int(r["points"]) == pushes[(r["file"], r["profile"])].depth.size, r["profile"]
        assert r["status"] == "ok" or r["status"].startswith("refused: "), r
        assert (r["rmsd_kpa"] != "") == (r["status"] == "ok"), r


@pytest.mark.parametrize("layers", [2, 3])
def test_never_worse_than_before(pushes, layers):
    worse, better = [], 0
    rows = [r for r in records() if int(r["layers"]) == layers]
    for r in rows:
        p = pushes[(r["file"], r["profile"])]
        res = fit_layered(p, layers=layers)
        if r["status"] != "ok":  # the old fit refused it: the new one says why, too
            assert not res.ok, r["profile"]
            need = max(3, 5 * layers)
            assert res.error.endswith(f"{p.depth.size} points; at least {need} are needed"), (
                r["status"],
                res.error,
            )
            assert r["status"] == f"refused: {p.depth.size} points; at least {need} are needed"
            continue
        assert res.ok, (r["profile"], res.error)
        old = float(r["rmsd_kpa"])
        if res.rmsd > old * (1 + 1e-6) + 1e-6:
            worse.append((r["profile"], res.rmsd, old))
        better += res.rmsd < old * (1 - 1e-6)
        assert 0.0 <= res.certificate["lower_bound"] <= res.sse
    assert not worse, worse
    assert better >= 1  # the old search missed optima (a few per cent of the pushes)

"""Terrain library (terracone.apps.library)."""

from __future__ import annotations

import csv
import json
import multiprocessing as mp
import sqlite3
from pathlib import Path

import pytest
from conftest import require_shared

from terracone.apps.library import (
    REFERENCE_CITATION,
    Library,
    TerrainRecord,
    check_params,
    default_library_path,
    make_provenance,
    reference_records,
)

REFERENCE_CSV = (
    Path(__file__).resolve().parents[1] / "terracone" / "data" / "wong_terrain_values.csv"
)


@pytest.fixture
def lib(tmp_path):
    with Library(tmp_path / "lib.sqlite") as lb:
        yield lb


def test_default_path(monkeypatch, tmp_path):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "env.sqlite"))
    assert default_library_path() == tmp_path / "env.sqlite"
    monkeypatch.delenv("TERRACONE_LIBRARY")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert default_library_path() == tmp_path / "xdg" / "terracone" / "library.sqlite"
    monkeypatch.delenv("XDG_DATA_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_library_path() == (
        tmp_path / "home" / ".local" / "share" / "terracone" / "library.sqlite"
    )


def test_default_library_uses_env(monkeypatch, tmp_path):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "sub" / "env.sqlite"))
    with Library() as lb:
        assert lb.path == tmp_path / "sub" / "env.sqlite"
        lb.add("x", "calibration", {"n": 1.0})
    assert (tmp_path / "sub" / "env.sqlite").exists()
    mode = sqlite3.connect(tmp_path / "sub" / "env.sqlite").execute("PRAGMA journal_mode")
    assert mode.fetchone()[0] == "wal"


def test_reference_values_visible_and_exact(lib):
    lete = lib.get("LETE sand")
    assert lete.kind == "reference" and lete.builtin
    assert lete.params == {
        "kc": 102.0,
        "kphi": 5301.0,
        "n": 0.79,
        "c_kpa": 1.3,
        "phi_deg": 31.1,
        "K_m": pytest.approx(0.012),
    }
    # internal shear values, never stored as cone-metal cc / phic
    for r in reference_records():
        assert "cc" not in r.params and "phic_deg" not in r.params
        assert r.provenance["citation"] == REFERENCE_CITATION
    # repeated names made unique with the moisture; unique names kept exactly
    names = lib.names()
    assert "Sandy loam (Michigan) 11%" in names and "Sandy loam (Michigan) 23%" in names
    assert "Sandy loam (Michigan)" not in names
    assert "Dry sand (Land Locomotion Lab)" in names  # unique: no suffix
    assert "Snow (U.S., Harrison)" in names
    assert len(set(names)) == len(names)
    assert lib.get("Sandy loam (Michigan) 23%").params["kphi"] == 808.96


def _table_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


def _shared_rows(path: Path) -> list[dict[str, str]]:
    """The shared table, whose "Snow (U.S., Harrison)" row is not quoted: any
    extra fields belong to the first column (the terrain's name)."""
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    header = lines[0].split(",")
    out = []
    for ln in lines[1:]:
        f = ln.split(",")
        extra = len(f) - len(header)
        f = [",".join(f[: extra + 1])] + f[extra + 1 :]
        out.append(dict(zip(header, f)))
    return out


def test_reference_csv_cites_and_holds_21_terrains(lib):
    assert REFERENCE_CITATION in REFERENCE_CSV.read_text()
    assert len(_table_rows(REFERENCE_CSV)) == len(reference_records()) == 21


def test_reference_csv_matches_shared(lib):
    src = require_shared("reference", "wong_terrain_values.csv")
    text = REFERENCE_CSV.read_text()
    rows = _table_rows(REFERENCE_CSV)
    # same header comments, the same columns, and row by row the same values
    shared_lines = src.read_text().splitlines()
    ours = text.splitlines()
    for line in shared_lines:
        if line.startswith("#"):
            assert line in ours
    theirs = _shared_rows(src)
    assert list(theirs[0]) == list(rows[0])
    assert len(theirs) == len(rows)
    for mine, ref in zip(rows, theirs):
        assert mine["terrain"] == ref["terrain"]
        for col in ref:
            if col == "terrain":
                continue
            if ref[col].strip() == "":
                assert mine[col].strip() == "", (ref["terrain"], col)
            else:
                assert float(mine[col]) == float(ref[col]), (ref["terrain"], col)
    # and the library's records carry those values (SI, as tabulated)
    by_value = {(r.params["kc"], r.params["kphi"], r.params["n"]) for r in reference_records()}
    for ref in theirs:
        assert (float(ref["kc_si"]), float(ref["kphi_si"]), float(ref["n"])) in by_value


def test_add_get_list_remove(lib):
    prov = make_provenance("plates.csv", method="wong", citation="site survey 2024")
    rec = lib.add("site 3", "bevameter-fit", {"kc": 5.1, "kphi": 812.0, "n": 0.9}, prov)
    assert isinstance(rec, TerrainRecord) and not rec.builtin
    assert rec.provenance["source"] == "plates.csv"
    assert rec.provenance["method"] == "wong"
    assert rec.provenance["terracone_version"]
    assert rec.provenance["date"][:4].isdigit()
    assert lib.get("site 3").params == {"kc": 5.1, "kphi": 812.0, "n": 0.9}
    assert "site 3" in lib
    assert [r.name for r in lib.list(include_builtin=False)] == ["site 3"]
    assert [r.name for r in lib.list(kind="bevameter-fit")] == ["site 3"]
    with pytest.raises(ValueError, match="exists"):
        lib.add("site 3", "calibration", {"n": 1.0})
    new = lib.add("site 3", "calibration", {"n": 1.0}, notes="refit", replace=True)
    assert new.params == {"n": 1.0} and new.notes == "refit" and new.created == rec.created
    lib.remove("site 3")
    assert "site 3" not in lib
    with pytest.raises(KeyError):
        lib.remove("site 3")
    with pytest.raises(KeyError, match="did you mean"):
        lib.get("LETE sandd")


def test_reference_is_read_only(lib):
    with pytest.raises(ValueError, match="reference"):
        lib.add("LETE sand", "calibration", {"n": 1.0})
    with pytest.raises(ValueError, match="reference"):
        lib.remove("LETE sand")


def test_param_validation(lib):
    with pytest.raises(ValueError, match="ambiguous parameter 'c'"):
        lib.add("a", "calibration", {"c": 1.0})
    with pytest.raises(ValueError, match="ambiguous parameter 'phi'"):
        lib.add("a", "calibration", {"phi": 30.0})
    with pytest.raises(ValueError, match="unknown parameter"):
        lib.add("a", "calibration", {"kphii": 1.0})
    with pytest.raises(ValueError, match="finite"):
        lib.add("a", "calibration", {"kc": float("nan")})
    with pytest.raises(ValueError, match="model"):
        lib.add("a", "calibration", {"model": "rm2"})
    with pytest.raises(ValueError, match="name"):
        lib.add("  ", "calibration", {"n": 1.0})
    assert check_params({"kc": 1, "cc": None, "model": "rm1", "r_min": 0.01}) == {
        "kc": 1.0,
        "model": "rm1",
        "r_min": 0.01,
    }
    assert lib.list(include_builtin=False) == []


def test_export_import(tmp_path, lib):
    lib.add("a", "calibration", {"kc": 1.0, "kphi": 2.0, "n": 0.5, "cc": 3.0, "phic_deg": 20.0})
    lib.add("b", "bevameter-fit", {"n": 0.7, "k": 900.0, "b_m": 0.0757}, notes="one plate")
    out = tmp_path / "lib.json"
    assert lib.export(out) == 2
    data = json.loads(out.read_text())
    assert [d["name"] for d in data] == ["a", "b"]
    assert lib.export(tmp_path / "all.json", include_builtin=True) == 2 + len(reference_records())

    with Library(tmp_path / "other.sqlite") as other:
        rep = other.import_(out)
        assert rep.imported == ["a", "b"] and rep.skipped == []
        assert other.get("b").notes == "one plate"
        assert other.get("a").params == lib.get("a").params
        # importing again: identical records skipped
        rep = other.import_(out)
        assert rep.imported == [] and len(rep.skipped) == 2
        # references in a file are skipped, not duplicated
        rep = other.import_(tmp_path / "all.json")
        assert rep.imported == []
        assert ("LETE sand", "packaged reference terrain") in rep.skipped
        # a conflicting record: nothing imported without replace
        other.add("c", "calibration", {"n": 2.0})
        data[0]["params"]["n"] = 0.6
        data.append({"name": "c", "kind": "calibration", "params": {"n": 3.0}})
        out.write_text(json.dumps(data))
        with pytest.raises(ValueError, match="nothing imported"):
            other.import_(out)
        assert other.get("a").params["n"] == 0.5
        assert other.get("c").params["n"] == 2.0
        rep = other.import_(out, replace=True)
        assert sorted(rep.imported) == ["a", "c"]
        assert other.get("a").params["n"] == 0.6


def _writer(path: str, tag: str, count: int, barrier) -> None:
    barrier.wait()  # open the brand-new file and write at the same time
    with Library(path) as lb:
        for i in range(count):
            lb.add(f"{tag}-{i:03d}", "calibration", {"kc": float(i), "kphi": 1.0, "n": 0.5})


def test_two_processes_add_at_once(tmp_path):
    path = str(tmp_path / "shared.sqlite")  # brand-new file: both processes create it
    ctx = mp.get_context("spawn")
    barrier = ctx.Barrier(2)
    procs = [ctx.Process(target=_writer, args=(path, tag, 200, barrier)) for tag in "AB"]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0]
    with Library(path) as lb:
        names = [r.name for r in lb.list(include_builtin=False)]
        assert len(names) == 400
        assert names == sorted(f"{t}-{i:03d}" for t in "AB" for i in range(200))
        assert lb.get("B-199").params["kc"] == 199.0
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    con.close()


def test_calibration_record_keys(lib):
    # the keys of a `terracone learn` calibration (cone-metal cc, phic_deg)
    cal = {
        "model": "rm1",
        "r_min": 0.0086,
        "plate_pair": [0.0375, 0.05],
        "phic_deg": 11.9,
        "cc": 0.0,
        "kc": 99.97,
        "kphi": 5359.0,
        "n": 0.791,
        "cone": "asabe-large",
    }
    rec = lib.add("LETE cal", "calibration", cal, make_provenance(method="terracone learn"))
    assert rec.params == cal
    assert "c_kpa" not in rec.params and "phi_deg" not in rec.params
    with pytest.raises(ValueError, match="plate_pair"):
        lib.add("bad", "calibration", {"plate_pair": [0.05]})

"""Hostile and careless input (issue 33): every finding gets its input and the answer it must get.

References, none of them terracone's own output: the strings as written here
(what a generated module and a CSV must give back, read by Python's importer
and the csv module), OWASP's rule against CSV injection (no cell a
spreadsheet reads as a formula: a text cell that begins with ``=``, ``+``,
``-``, ``@``, tab or carriage return gets a leading ``'``; numbers stay
numbers), the input files' bytes before and after, distances by pyproj's
geodesic on the WGS 84 ellipsoid, and hand-built files with one defect on a
known line.  Generated PyChrono modules are imported in a new interpreter in
an empty folder, with the stand-in of ``tests/pychrono_standin.py``
(PyChrono itself is conda-only).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import re
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st
from pyproj import Geod, Transformer

from terracone.apps.chrono import LocatedSoil, pychrono_module, scm_settings, scm_values
from terracone.apps.library import Library
from terracone.cli import cli
from terracone.data import CIProfile
from terracone.inverse.predict import predict_many
from terracone.inverse.problem import Calibration, Problem
from terracone.io import read_ci_profiles, write_ci_profiles
from terracone.io.outputs import check_outputs, run_directory
from terracone.io.profiles import iter_profile_sets
from terracone.io.tables import FORMULA_START, guard_formula, unguard_formula
from terracone.physics.cone import CONES, cone_index_huang, get_cone
from terracone.result import PredictionResults, write_json

TESTS = Path(__file__).resolve().parent
EXAMPLE = TESTS.parent / "terracone" / "data" / "example"

#: The issue's terrain name, and more strings that end a Python string or docstring early,
#: escape, or split a line.
EVIL = 'evil""" + __import__("os").system("touch PWNED") + """x'
HOSTILE = [
    EVIL,
    "q'''x'''+__import__('os').system('touch PWNED2')+'''",
    "back\\slash \\N{BULLET} C:\\Users\\new",
    "two\nlines\r\nand a tab\t",
    "line\u2028separator and \x00 nul",
    "lone \ud800 surrogate",
    '=HYPERLINK("http://evil.example","click")',
]
#: Profile ids: the strings above that a CSV file and a path can hold, and formulas.
HOSTILE_IDS = [
    'p"""x + __import__("os").system("touch PWNED")',
    "q'''y",
    '=HYPERLINK("http://evil.example","z")',
    "-2+3+cmd|' /C calc'!A0",
    "@SUM(1+1)",
    "+1+1",
    "back\\slash\\N",
    "two\nlines",
]
CAL = Calibration("generated", "rm0", None, None, 11.0, 5.0, 50.0, 1500.0, 0.9)
DEPTH = np.arange(0.0, 0.451, 0.025)


def run(*args, env=None):
    return CliRunner().invoke(cli, [str(a) for a in args], env=env)


def error_line(r, code: int = 1) -> str:
    """The one 'Error: ...' line of a refused run (exit ``code``), without 'Error: '."""
    assert r.exit_code == code, r.output
    assert "internal error" not in r.output and "Traceback" not in r.output, r.output
    errors = [ln for ln in r.output.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1, r.output
    return errors[0][len("Error: ") :]


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def library(tmp_path, monkeypatch):
    monkeypatch.setenv("TERRACONE_LIBRARY", str(tmp_path / "lib.sqlite"))
    return tmp_path / "lib.sqlite"


# ---------------------------------------------------------------------------
# security: generated code is data
# ---------------------------------------------------------------------------

#: Imports a module in a new interpreter (the stand-in as pychrono) and prints what it holds.
IMPORTER = """
import json, sys
sys.path[:0] = [sys.argv[1], "."]
import pychrono_standin

class _Patch:  # what install() needs of pytest's monkeypatch
    def setitem(self, d, k, v):
        d[k] = v

pychrono_standin.install(_Patch())
m = __import__(sys.argv[2])
t = pychrono_standin.SCMTerrain(system=None)
cb = m.apply(t)
values = [list(t.soil_at(*m.to_local(lat, lon))) for _, lat, lon in m.SITES] if cb else [list(t.params)]
print(json.dumps({"source": m.SOURCE, "notes": list(m.NOTES), "sites": [s[0] for s in m.SITES],
                  "doc": m.__doc__, "values": values}))
"""


def import_module(folder: Path, name: str) -> dict:
    """Import ``folder/name.py`` in a new interpreter run in ``folder``; what it holds."""
    before = sorted(p.name for p in folder.iterdir())
    r = subprocess.run(
        [sys.executable, "-c", IMPORTER, str(TESTS), name],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    after = sorted(p.name for p in folder.iterdir() if p.name != "__pycache__")
    assert after == before, "importing the module created files"
    return json.loads(r.stdout)


def soil(pid: str, lat: float | None = None, lon: float | None = None) -> LocatedSoil:
    params = {"kc": 10.0, "kphi": 800.0, "n": 0.9, "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.01}
    return LocatedSoil(pid, params, lat, lon)


def test_module_with_hostile_strings_in_every_field_is_data(tmp_path):
    """Ids, source and notes (every string that enters the module) come back as written."""
    soils = [soil(h, -33.45 + 1e-4 * i, -70.65) for i, h in enumerate(HOSTILE)]
    text = pychrono_module(soils, scm_settings(), source=EVIL, notes=HOSTILE)
    (tmp_path / "hostile_mod.py").write_text(text, encoding="utf-8")
    got = import_module(tmp_path, "hostile_mod")
    assert got["sites"] == HOSTILE and got["source"] == EVIL
    assert got["notes"][: len(HOSTILE)] == HOSTILE
    assert not any(h in got["doc"] for h in HOSTILE)  # the docstring is terracone's text only
    assert got["values"][0] == [800e3, 10e3, 0.9, 1000.0, 30.0, 0.01, 4e8, 3e4]
    # one soil: no SITES callback, SetSoilParameters with the eight values
    (tmp_path / "one_mod.py").write_text(
        pychrono_module([soil(EVIL)], scm_settings(), source=EVIL, notes=[EVIL]), encoding="utf-8"
    )
    got = import_module(tmp_path, "one_mod")
    assert got["sites"] == [EVIL] and got["notes"][0] == EVIL
    assert got["values"] == [[800e3, 10e3, 0.9, 1000.0, 30.0, 0.01, 4e8, 3e4]]


def test_scm_values_refuse_a_value_that_is_not_finite():
    bad = {**soil("x").params, "n": math.nan}
    with pytest.raises(ValueError, match=r"'x': Bekker_n not a finite number; nothing was written"):
        scm_values(bad, scm_settings(), "'x'")


def test_issue_repro_terrain_name_through_shear_runs_nothing(tmp_path, library):
    """The issue's terrain name, used by --shear and by --terrain, exported and imported."""
    r = run("library", "add", EVIL, "--param", "kc=10", "--param", "kphi=800", "--param", "n=0.9",
            "--param", "c_kpa=1", "--param", "phi_deg=30", "--param", "K_m=0.01")  # fmt: skip
    assert r.exit_code == 0, r.output
    folder = tmp_path / "mods"
    folder.mkdir()
    r = run("export", "--format", "pychrono", "--terrain", "LETE sand", "--shear", EVIL,
            "--out", folder / "site3.py")  # fmt: skip
    assert r.exit_code == 0, r.output
    got = import_module(folder, "site3")
    assert any(f"library terrain {EVIL!r}" in note for note in got["notes"])
    assert got["values"][0][3:6] == [1000.0, 30.0, 0.01]  # shear values of the named terrain
    r = run("export", "--format", "pychrono", "--terrain", EVIL, "--out", folder / "site4.py")
    assert r.exit_code == 0, r.output
    got = import_module(folder, "site4")
    assert got["sites"] == [EVIL] and got["source"] == EVIL
    assert not (folder / "PWNED").exists() and not (tmp_path / "PWNED").exists()


def located_profiles(ids, lat0=-33.45, lon0=-70.65, seed=0) -> list[CIProfile]:
    """Profiles of a known terrain (5% noise) at points 30 m apart, with lat/lon metadata."""
    rng = np.random.default_rng(seed)
    out = []
    for i, pid in enumerate(ids):
        kphi = 1500.0 * math.exp(0.1 * rng.standard_normal())
        ci = cone_index_huang(DEPTH, kc=kphi * CAL.kc / CAL.kphi, kphi=kphi, n=0.9, cc=5.0,
                              phic_deg=11.0)  # fmt: skip
        ci = np.maximum(ci * (1 + 0.05 * rng.standard_normal(ci.size)), 0.0)
        meta = {"lat": lat0 + 2.7e-4 * (i % 5), "lon": lon0 + 3.2e-4 * (i // 5), "site": "=1+1"}
        out.append(CIProfile(pid, DEPTH, ci, metadata=meta))
    return out


def test_results_path_and_profile_ids_enter_the_module_as_data(tmp_path, library):
    """A results file named q\"\"\"x.json (the issue: a SyntaxError) and hostile profile ids."""
    folder = tmp_path / "work"
    folder.mkdir()
    write_ci_profiles(folder / "ci.csv", located_profiles(HOSTILE_IDS))
    results = folder / 'q"""x.json'
    r = run("predict", folder / "ci.csv", "--json", "--out", results)
    assert r.exit_code == 0, r.output
    r = run("export", "--results", results, "--format", "pychrono", "--out", folder / "mod.py",
            "--cohesion", "1kPa", "--friction", "30", "--janosi", "10mm")  # fmt: skip
    assert r.exit_code == 0, r.output
    got = import_module(folder, "mod")
    assert got["sites"] == HOSTILE_IDS and got["source"] == str(results)


# ---------------------------------------------------------------------------
# security: CSV formula injection
# ---------------------------------------------------------------------------


def cells(path: Path) -> list[list[str]]:
    lines = [ln for ln in path.read_text().splitlines(keepends=True) if not ln.startswith("#")]
    return list(csv.reader(io.StringIO("".join(lines))))


def no_formula(rows: list[list[str]]) -> None:
    """OWASP: no cell begins with a formula character, unless it is a plain number."""
    for row in rows:
        for c in row:
            if c and c[0] in FORMULA_START:
                float(c)  # a number such as -5.0 is a number, not a formula


def test_guard_by_hand():
    assert guard_formula('=HYPERLINK("http://x","y")') == '\'=HYPERLINK("http://x","y")'
    assert guard_formula("-2+3+cmd|' /C calc'!A0") == "'-2+3+cmd|' /C calc'!A0"
    assert guard_formula("@SUM(1)") == "'@SUM(1)" and guard_formula("+1") == "+1"
    assert guard_formula("\t=1") == "'\t=1" and guard_formula("\r=1") == "'\r=1"
    assert guard_formula("-1.5e3") == "-1.5e3" and guard_formula("-inf") == "'-inf"
    assert guard_formula("'=x") == "''=x" and guard_formula("'abc") == "'abc"
    assert guard_formula("plain") == "plain" and guard_formula("") == ""
    assert unguard_formula("'=x") == "=x" and unguard_formula("''=x") == "'=x"
    assert unguard_formula("'abc") == "'abc" and unguard_formula("'-5") == "-5"


@given(st.text())
def test_guard_reads_back_exactly_and_never_leaves_a_formula(text):
    guarded = guard_formula(text)
    assert unguard_formula(guarded) == text
    if guarded and guarded[0] in FORMULA_START:
        float(guarded)  # only a number may begin so


def test_export_csv_of_hostile_terrain_names_and_ids(tmp_path, library):
    name = '=HYPERLINK("http://evil.example","click")'
    r = run("library", "add", name, "--param", "kc=-5", "--param", "kphi=800", "--param", "n=0.9")
    assert r.exit_code == 0, r.output
    out = tmp_path / "t.csv"
    assert run("export", "--terrain", name, "--format", "csv", "--out", out).exit_code == 0
    rows = cells(out)
    no_formula(rows)
    assert rows[1][0] == "'" + name and rows[1][1] == "-5.0"  # kc: still a number
    write_ci_profiles(tmp_path / "ci.csv", located_profiles(["@SUM(1+1)", "-cmd"]))
    results = tmp_path / "r.json"
    assert run("predict", tmp_path / "ci.csv", "--json", "--out", results).exit_code == 0
    for pid in ("@SUM(1+1)", "-cmd"):
        r = run("export", "--results", results, "--profile", pid, "--format", "csv", "--out", out)
        assert r.exit_code == 0, r.output
        rows = cells(out)
        no_formula(rows)
        assert rows[1][0] == "'" + pid


def test_written_ci_files_are_guarded_and_read_back_exactly(tmp_path):
    """write_ci_profiles guards ids, text metadata and metadata names; predict's reader and
    batch's streaming reader give back every id and value as it was."""
    profiles = located_profiles(HOSTILE_IDS)
    for p in profiles:
        p.metadata.update({"=note": "-cmd|x", "elev": -3.5, "@user": "+1+1"})
    path = tmp_path / "ci.csv"
    write_ci_profiles(path, profiles)
    no_formula(cells(path))
    back = read_ci_profiles(path)
    assert [p.id for p in back] == HOSTILE_IDS
    assert back[0].metadata == {**profiles[0].metadata}
    (streamed,) = iter_profile_sets([path], chunk_size=None)
    assert list(streamed.ids) == HOSTILE_IDS
    meta = streamed.metadata.to_pylist()[0]
    assert meta["=note"] == "-cmd|x" and meta["@user"] == "+1+1" and meta["elev"] == -3.5
    assert meta["site"] == "=1+1"


def test_report_tables_and_draws_csv_are_guarded(tmp_path):
    from terracone.apps.chrono import write_scm_specs
    from terracone.report.tables import Table

    t = Table("k", "title", [("id", ""), ("kc", "kN")], [["=1+2", -1.5], ["@x", 2.0]])
    rows = list(csv.reader(io.StringIO(t.to_csv())))[1:]
    no_formula(rows)
    assert rows[1:] == [["'=1+2", "-1.5"], ["'@x", "2"]]
    draws = tuple({"kc": 10.0, "kphi": 800.0 + k, "n": 0.9, "cc": 1.0, "phic_deg": 10.0,
                   "c_kpa": 1.0, "phi_deg": 30.0, "K_m": 0.01} for k in range(2))  # fmt: skip
    s = LocatedSoil("-cmd", soil("-cmd").params, draws=draws)
    write_scm_specs(tmp_path / "ens", s, scm_settings())
    rows = cells(tmp_path / "ens" / "draws.csv")
    no_formula(rows)
    assert [r[0] for r in rows[1:]] == ["'-cmd-draw-0001.json", "'-cmd-draw-0002.json"]
    assert (tmp_path / "ens" / "-cmd-draw-0001.json").is_file()


# ---------------------------------------------------------------------------
# files lost or left stale
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """A CI file, plate tests, a prediction JSON of them."""
    d = tmp_path_factory.mktemp("ws")
    for name in ("lete_sand_synthetic_ci.csv", "lete_sand_synthetic_plates.csv"):
        (d / name).write_bytes((EXAMPLE / name).read_bytes())
    r = run("predict", d / "lete_sand_synthetic_ci.csv", "--json", "--out", d / "pred.json")
    assert r.exit_code == 0, r.output
    (d / "cal.json").write_text("{}")
    (d / "vehicle.json").write_text("{}")
    return d


#: (arguments with {d} the workspace, the input file that must survive, the message)
OUT_IS_INPUT = [
    ("predict {d}/lete_sand_synthetic_ci.csv --out {d}/lete_sand_synthetic_ci.csv",
     "lete_sand_synthetic_ci.csv", "--out {d}/lete_sand_synthetic_ci.csv is the input CI_FILE"),
    ("predict {d}/lete_sand_synthetic_ci.csv --parquet {d}/./lete_sand_synthetic_ci.csv",
     "lete_sand_synthetic_ci.csv", "--parquet {d}/./lete_sand_synthetic_ci.csv is the input"),
    ("predict {d}/lete_sand_synthetic_ci.csv --calibration {d}/cal.json --out {d}/cal.json",
     "cal.json", "--out {d}/cal.json is the input --calibration {d}/cal.json"),
    ("sites {d}/lete_sand_synthetic_ci.csv --by site --out {d}/lete_sand_synthetic_ci.csv",
     "lete_sand_synthetic_ci.csv", "--out {d}/lete_sand_synthetic_ci.csv is the input CI_FILE"),
    ("learn --ci {d}/lete_sand_synthetic_ci.csv --plates {d}/lete_sand_synthetic_plates.csv "
     "--save {d}/lete_sand_synthetic_plates.csv", "lete_sand_synthetic_plates.csv",
     "--save {d}/lete_sand_synthetic_plates.csv is the input --plates"),
    ("report {d}/pred.json --out {d}/pred.json", "pred.json",
     "--out {d}/pred.json is the input RESULTS {d}/pred.json"),
    ("export --results {d}/pred.json --profile LS_syn_1 --format json --out {d}/pred.json",
     "pred.json", "--out {d}/pred.json is the input --results {d}/pred.json"),
    ("export --results {d}/pred.json --format geojson --out {d}/sub/../pred.json", "pred.json",
     "--out {d}/sub/../pred.json is the input --results {d}/pred.json"),
    ("mobility {d}/pred.json --vehicle {d}/vehicle.json --out {d}/pred.json", "pred.json",
     "--out {d}/pred.json is the input RESULTS {d}/pred.json"),
    ("mobility {d}/pred.json --vehicle {d}/vehicle.json --out {d}/vehicle.json", "vehicle.json",
     "--out {d}/vehicle.json is the input --vehicle {d}/vehicle.json"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "kept", "message"), OUT_IS_INPUT)
def test_an_output_over_an_input_is_refused(workspace, args, kept, message):
    d = workspace
    before = digest(d / kept)
    why = error_line(run(*args.format(d=d).split()))
    assert why.startswith(message.format(d=d)), why
    assert why.endswith("writing it would destroy the input: choose another path")
    assert digest(d / kept) == before


def test_outputs_on_one_path_and_the_library_are_refused(workspace, tmp_path, library):
    d = workspace
    why = error_line(run("predict", d / "lete_sand_synthetic_ci.csv", "--out", tmp_path / "a",
                         "--parquet", tmp_path / "a"))  # fmt: skip
    assert why == (
        f"--out {tmp_path / 'a'} and --parquet {tmp_path / 'a'} are the same file: one would "
        "overwrite the other; give them different paths"
    )
    assert run("library", "add", "mine", "--param", "n=1").exit_code == 0
    before = digest(library)
    why = error_line(run("library", "export", library))
    assert why.startswith(f"PATH {library} is the input --library {library}")
    why = error_line(run("export", "--terrain", "mine", "--format", "json", "--out", library))
    assert why.startswith(f"--out {library} is the input --library {library}")
    assert digest(library) == before


def test_hard_link_and_symlink_are_the_same_file(tmp_path):
    (tmp_path / "a.json").write_text("{}")
    os.link(tmp_path / "a.json", tmp_path / "hard.json")
    os.symlink(tmp_path / "a.json", tmp_path / "soft.json")
    for other in ("hard.json", "soft.json"):
        with pytest.raises(ValueError, match="is the input RESULTS"):
            check_outputs({"--out": tmp_path / other}, {"RESULTS": tmp_path / "a.json"})
    check_outputs({"--out": tmp_path / "b.json"}, {"RESULTS": tmp_path / "a.json"})


def chile_results(path: Path, count: int = 12) -> Path:
    """Results of ``count`` located pushes in a field near Santiago, Chile (UTM zone 19S)."""
    profiles = located_profiles([f"P{i}" for i in range(count)])
    write_json(path, PredictionResults(predict_many(profiles, Problem(calibration=CAL))))
    return path


@pytest.fixture(scope="module")
def chile(tmp_path_factory) -> Path:
    return chile_results(tmp_path_factory.mktemp("chile") / "chile.json")


def listing(d: Path) -> set[str]:
    return {p.name for p in d.iterdir()}


def map_files(d: Path) -> set[str]:
    doc = json.loads((d / "map.json").read_text())
    tifs = {q["file"] for q in doc["quantities"].values() if q["file"]}
    return tifs | {"map.json", doc["points"], doc["cells"]}


def test_map_into_a_used_directory(chile, tmp_path):
    out = tmp_path / "m"
    out.mkdir()
    (out / "map.json").write_text('{"mine": true}')
    (out / "notes.txt").write_text("keep me")
    why = error_line(run("map", chile, "--out", out))
    assert why == (
        f"output directory {out} is not empty and does not hold an earlier terracone map run "
        "(map.json, notes.txt): choose a new or empty directory, or pass --force (force=True) "
        "to replace it whole (its files are deleted)"
    )
    assert (out / "notes.txt").read_text() == "keep me" and listing(out) == {
        "map.json",
        "notes.txt",
    }
    # --force: replaced whole
    r = run("map", chile, "--out", out, "--force")
    assert r.exit_code == 0, r.output
    assert listing(out) == map_files(out) and "notes.txt" not in listing(out)
    # an earlier map with other layers is replaced whole: no stale GeoTIFF
    r = run("map", chile, "--out", out, "--layers-ci", "0:10cm,10:20cm")
    assert r.exit_code == 0, r.output
    assert {"ci_0-10cm.tif", "ci_10-20cm.tif"} <= listing(out) == map_files(out)
    r = run("map", chile, "--out", out)
    assert r.exit_code == 0, r.output
    assert listing(out) == map_files(out) and "ci_0-10cm.tif" not in listing(out)
    assert listing(tmp_path) == {"m"}  # no staging folder left beside it


def test_map_never_replaces_its_input_or_the_current_directory(chile, tmp_path, monkeypatch):
    d = tmp_path / "d"
    d.mkdir()
    (d / "res.json").write_bytes(chile.read_bytes())
    why = error_line(run("map", d / "res.json", "--out", d, "--force"))
    assert why.startswith(f"--out {d} holds the input RESULTS {d / 'res.json'}; the output ")
    assert listing(d) == {"res.json"}
    monkeypatch.chdir(d)
    why = error_line(run("map", chile, "--out", ".", "--force"))
    assert (
        why == f"will not replace {d} whole: it holds the current directory; choose a new directory"
    )


def test_a_failed_write_leaves_the_earlier_map(chile, tmp_path, monkeypatch):
    from terracone.apps.maps import map_survey, write_map
    from terracone.apps.maps import writers as map_writers
    from terracone.result import read_results

    result = map_survey(read_results(chile))
    out = tmp_path / "m"
    write_map(result, out)
    before = {p.name: digest(p) for p in out.iterdir()}

    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(map_writers, "_write_cells", broken)
    with pytest.raises(OSError, match="No space left"):
        write_map(result, out)
    assert {p.name: digest(p) for p in out.iterdir()} == before and listing(tmp_path) == {"m"}


@pytest.fixture(scope="module")
def with_draws(tmp_path_factory):
    d = tmp_path_factory.mktemp("draws")
    write_ci_profiles(d / "ci.csv", located_profiles(["A"]))
    r = run("predict", d / "ci.csv", "--uncertainty", "--draws", "40", "--seed", "1", "--json",
            "--out", d / "pred.json")  # fmt: skip
    assert r.exit_code == 0, r.output
    return d / "pred.json"


def test_export_samples_into_a_used_directory(with_draws, tmp_path, library):
    out = tmp_path / "ens"
    base = ["export", "--results", with_draws, "--format", "chrono-scm", "--out", out,
            "--shear", "LETE sand", "--seed", "1"]  # fmt: skip
    assert run(*base, "--samples", "5").exit_code == 0
    assert len(listing(out)) == 6
    r = run(*base, "--samples", "3")  # an earlier ensemble: replaced whole
    assert r.exit_code == 0, r.output
    assert listing(out) == {"draws.csv", *(f"A-draw-000{k}.json" for k in (1, 2, 3))}
    assert len(cells(out / "draws.csv")) == 4
    (out / "mine.txt").write_text("keep")
    why = error_line(run(*base, "--samples", "2"))
    assert why.startswith(f"output directory {out} is not empty and does not hold an earlier "
                          "Chrono ensemble run (A-draw-0001.json")  # fmt: skip
    assert (out / "mine.txt").read_text() == "keep"
    r = run(*base, "--samples", "2", "--force")
    assert r.exit_code == 0, r.output
    assert listing(out) == {"draws.csv", "A-draw-0001.json", "A-draw-0002.json"}
    why = error_line(run("export", "--terrain", "LETE sand", "--format", "json", "--out",
                         tmp_path / "x.json", "--force"), code=2)  # fmt: skip
    assert why == "--force: only with --format chrono-scm --samples (a directory)"


def test_run_directory_refuses_a_file_and_keeps_nothing_on_failure(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ValueError, match="exists and is not a directory"):
        with run_directory(tmp_path / "f", what="test", is_run=lambda d: True):
            pass
    with pytest.raises(RuntimeError):
        with run_directory(tmp_path / "new", what="test", is_run=lambda d: True) as stage:
            (stage / "half").write_text("written")
            raise RuntimeError("stop")
    assert listing(tmp_path) == {"f"}


# ---------------------------------------------------------------------------
# accepted when it should be refused
# ---------------------------------------------------------------------------


def test_batch_of_a_header_only_file_is_refused(tmp_path):
    path = tmp_path / "head.csv"
    path.write_text("profile,depth_m,ci_kpa\n")
    why = error_line(run("batch", path, "--out", tmp_path / "out", "--quiet"))
    assert why == f"file {path}: no data rows: the input holds no profile"
    assert not any((tmp_path / "out").iterdir())  # nothing written: a later run may use it
    assert error_line(run("predict", path)) == f"file {path}, row 1: no data rows"


def test_batch_notes_a_header_only_file_among_others(tmp_path):
    from terracone.apps.batch import run_batch

    d = tmp_path / "in"
    d.mkdir()
    (d / "a.csv").write_text("profile,depth_m,ci_kpa\n")
    write_ci_profiles(d / "b.csv", located_profiles(["B"]))
    s = run_batch(d, tmp_path / "out", pool=map, progress=False)
    assert s.profiles == 1 and s.success and s.notes == [f"file {d / 'a.csv'}: no data rows"]
    doc = json.loads((tmp_path / "out" / "_summary.json").read_text())
    assert doc["notes"] == s.notes


@pytest.mark.parametrize(
    ("cone", "why"),
    [
        ("20mm:1e-300", "included angle 1e-300 deg is outside the range of penetrometer cones, "
         "10 to 120 deg"),
        ("1e300mm:30", "base diameter 1e+300 mm is outside the range of penetrometer cones, "
         "1 to 150 mm"),
        ("1e300cm2:60", "base diameter 1.128e+151 mm is outside"),
        ("20mm:179", "included angle 179 deg is outside"),
        ("0.5mm:30", "base diameter 0.5 mm is outside"),
    ],
)  # fmt: skip
def test_cone_out_of_range_is_refused_naming_cone(workspace, tmp_path, cone, why):
    ci = workspace / "lete_sand_synthetic_ci.csv"
    for args in (["predict", ci], ["batch", ci, "--out", tmp_path / "o"], ["ci", "--kc", "1",
                 "--kphi", "1", "--n", "1", "--depths", "0.1"]):  # fmt: skip
        line = error_line(run(*args, "--cone", cone), code=2)
        assert line.startswith(f"Invalid value for '--cone': cone {cone!r}: "), line
        assert why in line
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "args, why",
    [
        ("predict {ci} --r-min -1", "--r-min: must be a finite length > 0, got '-1'"),
        ("predict {ci} --model rm1 --r-min 0", "--r-min: must be a finite length > 0, got '0'"),
        ("predict {ci} --r-min 1e999", "--r-min: must be a finite length > 0, got '1e999'"),
        (
            "predict {ci} --r-min nan",
            "--r-min: expected a length such as 0.05, 5cm or 2in, got 'nan'",
        ),
        ("design {ci} --plates -1,5cm", "--plates: must be a finite length > 0, got '-1'"),
        ("sites {ci} --by site --plates 0", "--plates: must be a finite length > 0, got '0'"),
        (
            "predict {ci} --depth-range -1:0.2",
            "--depth-range: must be a finite length >= 0, got '-1'",
        ),
    ],
)
def test_a_length_option_that_is_negative_zero_or_infinite_is_refused(workspace, args, why):
    r = run(*args.format(ci=workspace / "lete_sand_synthetic_ci.csv").split())
    assert error_line(r, code=2) == f"Invalid value: {why}"


def test_cone_range_by_hand_and_in_a_file(tmp_path):
    assert get_cone("20mm:10").angle_deg == 10 and get_cone("20mm:120").angle_deg == 120
    assert get_cone("1mm:30").radius == pytest.approx(5e-4, rel=1e-12)
    assert get_cone("150mm:30").radius == pytest.approx(0.075, rel=1e-12)
    for spec in ("20mm:9.99", "20mm:120.01", "0.99mm:30", "150.1mm:30"):
        with pytest.raises(ValueError, match="outside the range of penetrometer cones"):
            get_cone(spec)
    assert all(get_cone(name) is c for name, c in CONES.items())
    path = tmp_path / "c.csv"
    path.write_text("profile,cone,depth_m,ci_kpa\nA,1e300mm:30,0,100\nA,1e300mm:30,0.05,200\n"
                    "A,1e300mm:30,0.1,300\n")  # fmt: skip
    r = run("predict", path, "--json")
    assert r.exit_code == 1 and "internal error" not in r.output
    (p,) = json.loads(r.stdout)["profiles"]
    assert p["error"].startswith(f"file {path}, profile A, row 2, column cone: ")
    assert "base diameter 1e+300 mm is outside" in p["error"]


def projected_ratio(crs: str, lat, lon) -> float:
    """Projected over geodesic distance (pyproj.Geod, WGS 84) of the two farthest pushes."""
    x, y = Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon, lat)
    i, j = int(np.argmin(lat + lon)), int(np.argmax(lat + lon))
    _, _, d = Geod(ellps="WGS84").inv(lon[i], lat[i], lon[j], lat[j])
    return math.hypot(x[j] - x[i], y[j] - y[i]) / d


def test_map_crs_for_another_part_of_the_world_is_refused(chile, tmp_path):
    lat = np.array([p.metadata["lat"] for p in located_profiles([f"P{i}" for i in range(12)])])
    lon = np.array([p.metadata["lon"] for p in located_profiles([f"P{i}" for i in range(12)])])
    # the Swiss grid in Chile: distances between the pushes off by more than 5% (geodesic)
    assert abs(projected_ratio("EPSG:2056", lat, lon) - 1) > 0.05
    why = error_line(run("map", chile, "--out", tmp_path / "m", "--crs", "EPSG:2056"))
    assert why.startswith("--crs CH1903+ / LV95 ")
    assert "(lat -33.4" in why and "12 of 12 pushes lie outside its area of use" in why
    assert "its area of use is Liechtenstein; Switzerland (lon 5.96 to 10.49, lat 45.82 to " in why
    assert why.endswith("a map in it would be wrong; give a CRS made for the pushes' area "
                        "(without --crs the map uses their UTM zone)")  # fmt: skip
    assert not (tmp_path / "m").exists()
    # UTM zone 33N (Europe), 85 deg of longitude away: refused too
    why = error_line(run("map", chile, "--out", tmp_path / "m", "--crs", "EPSG:32633"))
    assert why.startswith("--crs WGS 84 / UTM zone 33N ")


def test_map_crs_near_its_area_is_noted_not_refused(chile, tmp_path):
    profiles = located_profiles([f"P{i}" for i in range(12)])
    lat = np.array([p.metadata["lat"] for p in profiles])
    lon = np.array([p.metadata["lon"] for p in profiles])
    r = run("map", chile, "--out", tmp_path / "utm", "--json")  # the default: the UTM zone 19S
    assert r.exit_code == 0, r.output
    fit = json.loads(r.stdout)["crs_fit"]
    assert fit["pushes_outside"] == 0 and fit["scale_error"] < 1e-3
    assert fit["bounds"] == [-72.0, -80.0, -66.0, 0.0]
    # the next UTM zone west (18S): outside its area of use, distances 0.16% off: a note
    r = run("map", chile, "--out", tmp_path / "18s", "--crs", "EPSG:32718", "--json")
    assert r.exit_code == 0, r.output
    fit = json.loads(r.stdout)["crs_fit"]
    assert fit["pushes_outside"] == 12
    assert fit["scale_error"] == pytest.approx(
        projected_ratio("EPSG:32718", lat, lon) - 1, abs=2e-5
    )
    assert "note: 12 of 12 pushes lie outside the area of use of --crs WGS 84 / UTM zone 18S" in (
        r.stderr
    )
    # Web Mercator: in its area of use, but distances 20% long at 33 deg S: noted
    r = run("map", chile, "--out", tmp_path / "wm", "--crs", "EPSG:3857")
    assert r.exit_code == 0, r.output
    said = re.search(r"distances in --crs WGS 84 / Pseudo-Mercator are off by up to ([0-9.]+)%",
                     r.stderr)  # fmt: skip
    # within 0.5 point: pyproj's factors take Web Mercator's sphere, the geodesic the ellipsoid
    assert said and float(said[1]) / 100 == pytest.approx(
        projected_ratio("EPSG:3857", lat, lon) - 1, abs=5e-3
    )


def test_fit_plates_says_what_it_leaves_out_and_refuses_a_lost_sign(tmp_path):
    path = tmp_path / "plates.csv"
    # kc = 50, kphi = 1000, n = 0.8: k = 2000 (b = 5 cm) and 1500 (10 cm), p = k z^n
    rows = ["test,plate_radius_m,sinkage_m,pressure_kpa", "A,0.05,0.002,-0.5"]
    rows += [f"A,0.05,{z},{p}" for z, p in ((0.01, 50.2), (0.02, 87.4), (0.03, 120.9), (0.025, 60))]
    rows += [f"B,0.1,{z},{p}" for z, p in ((0.01, 37.7), (0.02, 65.6), (0.03, 90.7))]
    path.write_text("\n".join(rows) + "\n")
    r = run("fit-plates", path, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["notes"] == [
        "test A: 2 of 5 points left out of the fit: 1 at sinkage <= 0 or pressure <= 0 (line 2); "
        "1 after the largest sinkage (unloading)"
    ]
    path.write_text("\n".join(rows).replace("0.02,87.4", "0.02,-87.4") + "\n")
    assert error_line(run("fit-plates", path)) == (
        f"file {path}, test A, row 4, column pressure: pressure -87.4 kPa in the loading branch "
        "is below -10% of the test's largest pressure (120.9 kPa): not zero drift; a lost sign?"
    )


DEEP = "[" * 100_000 + "]" * 100_000
TOO_DEEP = (
    "cannot read JSON (nested too deeply: arrays or objects inside each other too many times)"
)


@pytest.mark.parametrize(
    "args",
    [
        "predict {ci} --calibration {deep}",
        "report {deep} --out {tmp}/r.html",
        "export --results {deep} --format json --out {tmp}/x.json",
        "evaluate --plates {plates} --params {deep}",
        "library import {deep}",
        "map {deep} --out {tmp}/m",
        "export --terrain LETE_sand --format chrono-scm --shear {deep} --out {tmp}/x.json",
        "mobility {deep} --vehicle {deep}",
    ],
)
def test_json_nested_100000_deep_is_refused_naming_the_file(workspace, tmp_path, library, args):
    deep = tmp_path / "deep.json"
    deep.write_text(DEEP)
    words = args.format(ci=workspace / "lete_sand_synthetic_ci.csv", deep=deep, tmp=tmp_path,
                        plates=workspace / "lete_sand_synthetic_plates.csv").split()  # fmt: skip
    why = error_line(run(*[w.replace("LETE_sand", "LETE sand") for w in words]))
    assert str(deep) in why and TOO_DEEP in why, why


@pytest.fixture(scope="module")
def chile_map(chile, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("chile_map") / "m"
    r = run("map", chile, "--out", out)
    assert r.exit_code == 0, r.output
    return out


MAP_EDITS = [
    (("grid",), 5, "key grid: expected an object (got a number)"),
    (("grid", "width"), -3, "key grid: expected width, height (> 0) and a transform of 6 numbers, "
     "as terracone map writes them"),
    (("pushes",), 5, "key pushes: expected an object (got a number)"),
    (("notes",), 5, "key notes: expected an array (got a number)"),
    (("quantities", "n", "variogram"), "x",
     "key quantities.n.variogram: expected an object (got text)"),
]  # fmt: skip


@pytest.mark.parametrize("keys, value, why", MAP_EDITS)
def test_a_hand_edited_map_json_is_refused_naming_the_key(chile_map, tmp_path, keys, value, why):
    d = tmp_path / "m"
    shutil.copytree(chile_map, d)
    doc = json.loads((d / "map.json").read_text())
    node = doc
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    (d / "map.json").write_text(json.dumps(doc))
    vehicle = tmp_path / "v.json"
    vehicle.write_text(json.dumps({"kind": "wheeled", "name": "v", "mobility_index": 50,
                                   "wheel": {"width": "0.3 m", "diameter": "0.9 m",
                                             "load": "10 kN"}}))  # fmt: skip
    for args in (["report", d, "--out", tmp_path / "r.html"],
                 ["mobility", d, "--vehicle", vehicle, "--out", tmp_path / "o"]):  # fmt: skip
        assert error_line(run(*args)) == f"file {d / 'map.json'}, {why}", args


def test_a_map_variogram_with_a_bad_value_is_refused_naming_it(chile_map, tmp_path):
    d = tmp_path / "m"
    shutil.copytree(chile_map, d)
    doc = json.loads((d / "map.json").read_text())
    doc["quantities"]["n"]["variogram"]["nugget"] = "x"
    (d / "map.json").write_text(json.dumps(doc))
    vehicle = tmp_path / "v.json"
    vehicle.write_text(json.dumps({"kind": "wheeled", "name": "v", "mobility_index": 50,
                                   "wheel": {"width": "0.3 m", "diameter": "0.9 m",
                                             "load": "10 kN"}}))  # fmt: skip
    why = error_line(run("mobility", d, "--vehicle", vehicle, "--out", tmp_path / "o",
                         "--remolding-index", "1", "--layer", "0:45cm"))  # fmt: skip
    assert why == (f"file {d / 'map.json'}, variogram of n: not as terracone map writes it "
                   "(could not convert string to float: 'x')")  # fmt: skip


def test_a_map_json_nested_100000_deep_is_refused_naming_the_file(tmp_path):
    (tmp_path / "m").mkdir()
    deep = tmp_path / "m" / "map.json"
    deep.write_text(DEEP)
    vehicle = tmp_path / "v.json"
    vehicle.write_text(json.dumps({"kind": "wheeled", "name": "v", "mobility_index": 50,
                                   "wheel": {"width": "0.3 m", "diameter": "0.9 m",
                                             "load": "10 kN"}}))  # fmt: skip
    for args in (["report", deep.parent, "--out", tmp_path / "r.html"],
                 ["mobility", deep.parent, "--vehicle", vehicle, "--out", tmp_path / "o"]):  # fmt: skip
        assert error_line(run(*args)) == f"file {deep}: {TOO_DEEP}"


@pytest.mark.parametrize(
    "profiles, why",
    [
        ("[null]", "profile 1: not a JSON object (a profile of a prediction document)"),
        ('[{"id": "a"}]', "profile 1 (id 'a'): key 'status': missing"),
        ('[{"id": "a", "status": "ok", "kc": 1}]', "profile 1 (id 'a'): key 'n': missing"),
        (
            '[{"id": "a", "status": "ok", "n": "x"}]',
            "profile 1 (id 'a'): not a profile as terracone writes it "
            "(could not convert string to float: 'x')",
        ),
    ],
)
def test_a_broken_profile_of_a_results_file_is_named_in_every_reader(
    workspace, tmp_path, profiles, why
):
    bad = tmp_path / "bad.json"
    bad.write_text('{"units": "si", "profiles": ' + profiles + "}")
    plates = workspace / "lete_sand_synthetic_plates.csv"
    for args in (["report", bad, "--out", tmp_path / "r.html"],
                 ["export", "--results", bad, "--format", "csv", "--out", tmp_path / "x.csv"],
                 ["map", bad, "--out", tmp_path / "m"],
                 ["evaluate", "--plates", plates, "--params", bad]):  # fmt: skip
        assert error_line(run(*args)) == f"file {bad}, {why}", args


@pytest.mark.parametrize(
    "rows, column, why",
    [
        ("A,0.05,0.01,10\nA,0.05,1e300,20\nA,0.05,0.03,30", "sinkage_m",
         "sinkage 1e+300 m is beyond 5 m"),
        ("A,0.05,0.01,10\nA,0.05,0.02,1e300\nA,0.05,0.03,30", "pressure_kpa",
         "pressure 1e+300 kPa is beyond 100000 kPa"),
        ("A,6,0.01,10\nA,6,0.02,20\nA,6,0.03,30", "plate_radius_m",
         "plate size 6 m is beyond 5 m"),
    ],
)  # fmt: skip
def test_a_plate_value_beyond_any_bevameter_is_refused_naming_the_cell(tmp_path, rows, column, why):
    f = tmp_path / "plates.csv"
    f.write_text("test,plate_radius_m,sinkage_m,pressure_kpa\n" + rows + "\n")
    row = 2 if column == "plate_radius_m" else 3
    assert error_line(run("fit-plates", f)) == (
        f"file {f}, test A, row {row}, column {column}: {why}, which no bevameter test reaches "
        "(a unit error or a corrupt cell?)"
    )


def test_a_broken_row_of_a_results_table_is_named_in_every_reader(workspace, tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    good = tmp_path / "good.parquet"
    r = run("predict", workspace / "lete_sand_synthetic_ci.csv", "--parquet", good)
    assert r.exit_code == 0, r.output
    table = pq.read_table(good)
    text = table.set_column(table.column_names.index("kc"), "kc", pa.array(["x"] * len(table)))
    cases = [
        (text, "row 1 (profile 'LS_syn_1'): not a row as terracone writes it (could not "
               "convert string to float: 'x')"),
        (table.drop_columns(["profile"]), "no column 'profile' (not a terracone prediction)"),
    ]  # fmt: skip
    for t, why in cases:
        bad = tmp_path / "bad.parquet"
        pq.write_table(t.replace_schema_metadata(table.schema.metadata), bad)
        for args in (["report", bad, "--out", tmp_path / "r.html"],
                     ["export", "--results", bad, "--format", "csv", "--out", tmp_path / "x.csv"]):  # fmt: skip
            sep = ", " if why.startswith("row") else ": "
            assert error_line(run(*args)) == f"file {bad}{sep}{why}", args


def test_a_corrupt_or_foreign_library_is_named_and_spares_the_builtin_terrains(tmp_path):
    bad = tmp_path / "bad.sqlite"
    bad.write_bytes(b"this is not a database\n" * 100)
    before = digest(bad)
    why = error_line(run("library", "--library", bad, "list"))
    assert why == (
        f"terrain library {bad}: cannot use it (file is not a database); move the file away or "
        "give another with --library or TERRACONE_LIBRARY (the packaged reference terrains need "
        "no library file)"
    )
    env = {"TERRACONE_LIBRARY": str(bad)}
    r = run("export", "--terrain", "LETE sand", "--format", "json", "--out", tmp_path / "x.json",
            env=env)  # fmt: skip
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "x.json").read_text())["kphi"] == 5301.0
    assert run("library", "show", "LETE sand", env=env).exit_code == 0
    why = error_line(run("library", "show", "mine", env=env))
    assert why.startswith(f"terrain library {bad}: cannot use it (file is not a database)")
    assert digest(bad) == before
    foreign = tmp_path / "photos.sqlite"
    with sqlite3.connect(foreign) as c:
        c.execute("CREATE TABLE photos (id INTEGER)")
    with pytest.raises(ValueError, match=r"photos.sqlite: cannot use it \(an SQLite file of "
                       r"something else, with tables photos\)"):  # fmt: skip
        Library(foreign).list()
    with sqlite3.connect(foreign) as c:
        tables = {r[0] for r in c.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    assert tables == {"photos"}


def test_a_second_writer_of_a_name_is_told_the_cli_flag(tmp_path):
    path = tmp_path / "lib.sqlite"
    with Library(path) as one, Library(path) as two:
        one.add("site", "calibration", {"n": 1.0})
        with pytest.raises(ValueError) as exc:
            two.add("site", "calibration", {"n": 2.0})
    assert str(exc.value) == (
        f"terrain 'site' exists in {path} (it may have just been added by another process): "
        "pass --replace (replace=True in Python) to overwrite it"
    )
    assert run("library", "--library", path, "add", "site", "--param", "n=3").exit_code == 1
    r = run("library", "--library", path, "add", "site", "--param", "n=3", "--replace")
    assert r.exit_code == 0, r.output


def test_a_semicolon_separated_file_is_named_as_such(tmp_path):
    path = tmp_path / "semi.csv"
    path.write_text("profile;depth_m;ci_kpa\nA;0,01;100\nA;0,02;200\nA;0,03;300\n")
    message = (
        f"file {path}, row 1: the columns are separated by semicolons (;), not commas: terracone "
        "reads comma-separated files with '.' decimals; save the file as CSV with commas (a wide "
        "table, one row per push, may use ';' and ',' decimals: --format wide)"
    )
    assert error_line(run("predict", path)) == message
    assert error_line(run("batch", path, "--out", tmp_path / "o")) == message


def test_predict_json_with_every_profile_bad_says_so_on_stderr(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("profile,depth_m,ci_kpa\nA,0.0,100\nA,0.05,x\nA,0.1,300\n")
    r = run("predict", path, "--json")
    assert r.exit_code == 1
    assert json.loads(r.stdout)["profiles"][0]["status"] == "error"
    assert (
        f"terracone: no profile could be fitted (1 read); first, A: file {path}, profile A, "
        "row 3, column ci_kpa: not a number: 'x'\n"
    ) in r.stderr

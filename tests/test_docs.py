"""Every example of the README and the user guide runs (issue 23).

The fenced blocks of README.md and docs/*.md are collected.  Each is marked with its
language: ``python``, ``sh``/``bash``/``console`` blocks are examples and run here;
``text``, ``json`` and the like are shown, not run (output samples, file excerpts,
synopses with placeholders).  A block without a language fails
:func:`test_every_block_is_marked`: nothing is left out silently.

How they run.  Each page gets a folder of its own (a copy of the shared workspace below),
and its blocks run there in page order, so a block may use what an earlier block of its
page wrote; two pages run at a time.  Shell blocks run through bash (``set -e -o
pipefail``) with the installed ``terracone`` first on the PATH; ``console`` blocks run
their ``$ `` lines.  Python blocks run as scripts in a new interpreter.
``TERRACONE_LIBRARY`` points into the page folder: the examples never touch the user's
terrain library.  ``TERRACONE_NUMBA=0``: the examples are small jobs, and the numpy
twins of the kernels (tested against them elsewhere) spare each of the some 80 processes
the loading, or on a cold cache the compiling, of the kernels.  A block that reads
``../shared`` runs when that folder exists (``TERRACONE_SHARED``, see conftest) and is
skipped with the reason otherwise; one that drives a browser likewise needs chromium; in CI
(``CI`` set) either missing fails the example.  PyChrono examples run on the stand-in of
``tests/pychrono_standin.py`` (``tests/standin`` on PYTHONPATH) unless PyChrono is
installed, and a printed plate sinkage must be positive and equal Bekker's static figure
printed beside it.

The workspace holds the files the examples name, all SYNTHETIC, made here from
terracone's forward models (:func:`workspace`):

==================================  ==========================================================
file                                content
==================================  ==========================================================
CI.csv, site.csv, small.csv         the bundled LETE-sand example (3 profiles), with ``plot``,
                                    ``lat`` and ``lon`` columns
OTHER_CI.csv                        2 more pushes of the same terrain (other noise)
PLATES.csv, plates.csv              the bundled plate tests (radii 3.75 and 5 cm)
SHEAR.csv                           shear tests at 3 normal pressures
pushes.csv                          a wide table: 6 located pushes, depths in cm, CI in MPa
                                    ("Unit: MPa"), a Penetrologger 1 cm2 cone
survey.csv, survey.json             the same with 30 pushes on a grid; its prediction with
                                    sand.json (= cal.json)
sc900_export.txt                    PokeMe.txt again
hmmwv.json, m113.json               the vehicle files of docs/mobility.md
PokeMe.txt, field.txt               FieldScout SC900 exports (kPa, 1/2 inch cone), 4 pushes
big.csv, big/, field-data/          200 pushes of LETE sand as a long CSV (big/, field-data/:
                                    split in two files)
profiles.parquet, PROFILES.parquet  CI.csv as Parquet
cal.json                            ``terracone learn --ci CI.csv --plates PLATES.csv --save``
predict.json                        ``terracone predict CI.csv --plates 1.5in,2.5in --json``
pred.json                           ``terracone predict pushes.csv --depth-unit cm
                                    --uncertainty --draws 500 --json``
batch_out/                          :func:`run_batch` of pushes.csv
==================================  ==========================================================

Blocks that install (``python3 -m venv``, ``pip install``) are not run here: each is
listed in :data:`SETUP` with the line of ``.ci/run`` that does the same, and
:func:`test_setup_blocks_are_what_ci_runs` holds the two together.  One command runs in a
shortened form, listed with its reason in :data:`SHORTENED`.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib.util import find_spec
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from chromium import find_chromium
from conftest import missing, shared_dir

from terracone.apps.example import example_dir
from terracone.jit import disabled
from terracone.physics.cone import cone_index

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
RUN = {"python", "sh", "bash", "console"}
SHOWN = {"text", "json", "csv", "yaml", "toml", "cpp"}
TIMEOUT = 300  # seconds for one block

#: Install blocks (not run here) and the line of .ci/run that runs the same.
SETUP = {
    "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && terracone demo": (
        'python -m pip install -q -e ".[test,docs]"',
        "terracone demo > /dev/null",
    ),
    'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && pytest': (
        'python -m pip install -q -e ".[test,docs]"',
        "pytest -q -p no:cacheprovider\n",
    ),
    'pip install -e ".[docs]" && mkdocs build --strict': (
        'python -m pip install -q -e ".[test,docs]"',
        "mkdocs build --strict",
    ),
}

#: Commands run in a shortened form: (as written, as run, why).
SHORTENED = [
    (
        "terracone reproduce --out reproduce/ ",
        "terracone reproduce --out reproduce/ --quick ",
        "the full case studies take minutes of CPU; tests/test_reproduce.py runs them",
    ),
]


@dataclass(frozen=True)
class Block:
    """One fenced block: page, line of its opening fence, language, code (dedented)."""

    page: Path
    line: int
    lang: str
    code: str

    @property
    def name(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


FENCE = re.compile(r"^(\s*)(```+|~~~+)\s*([\w+-]*)\s*$")


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a Markdown page, in order."""
    out: list[Block] = []
    lines = page.read_text().splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.groups()
        j = i + 1
        while j < len(lines) and lines[j].strip() != fence:
            j += 1
        body = [ln[len(indent) :] if ln.startswith(indent) else ln for ln in lines[i + 1 : j]]
        out.append(Block(page, i + 1, lang.lower(), "\n".join(body) + "\n"))
        i = j + 1
    return out


ALL = [b for page in PAGES for b in blocks(page)]
EXAMPLES = [b for b in ALL if b.lang in RUN and b.code.strip() not in SETUP]


def test_the_fences_by_hand(tmp_path):
    page = tmp_path / "p.md"
    page.write_text(
        "text\n```sh\nterracone ci\n```\n\n* item\n\n  ```python\n  x = 1\n  ```\n```\nplain\n```\n"
    )
    assert [(b.line, b.lang, b.code) for b in blocks(page)] == [
        (2, "sh", "terracone ci\n"),
        (8, "python", "x = 1\n"),
        (11, "", "plain\n"),
    ]


def test_every_block_is_marked():
    unmarked = [b.name for b in ALL if b.lang not in RUN | SHOWN]
    assert unmarked == [], f"blocks without a known language (python, sh, text, ...): {unmarked}"
    assert len(EXAMPLES) >= 25  # the collection works: README and guide examples


def test_setup_blocks_are_what_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text()
    setup = [b.code.strip() for b in ALL if b.lang in RUN and b.code.strip() in SETUP]
    assert sorted(setup) == sorted(SETUP), "each install block of SETUP is in the docs once"
    for lines in SETUP.values():
        for line in lines:
            assert line in ci, f".ci/run does not run {line!r}"


# ---------------------------------------------------------------------------
# the workspace: the files the examples name
# ---------------------------------------------------------------------------

LETE = dict(kc=102.0, kphi=5301.0, n=0.79, cc=1.0, phic_deg=11.0, model="rm1", r_min=0.008)


def synthetic_ci(z: np.ndarray, seed: int, cone: str = "asabe-large") -> list[np.ndarray]:
    """LETE-sand CI [kPa] at depths z [m], with 3% multiplicative noise, one per seed."""
    rng = np.random.default_rng(seed)
    p = dict(LETE)
    truth = cone_index(z, cone=cone, plate_pair=(0.0375, 0.05), **p)
    return truth * (1 + 0.03 * rng.standard_normal(z.size))


def write_long_ci(path: Path, pushes: int, seed: int, first: int = 1) -> pd.DataFrame:
    z = np.round(np.arange(0.0, 0.3001, 0.015), 4)
    rows = []
    for k in range(pushes):
        ci = synthetic_ci(z, seed + k)
        rows += [(f"L{first + k}", d, round(c, 2)) for d, c in zip(z, ci)]
    df = pd.DataFrame(rows, columns=["profile", "depth_m", "ci_kpa"])
    path.write_text("# SYNTHETIC DATA: LETE sand (terracone's forward model)\n")
    with path.open("a") as f:
        df.to_csv(f, index=False)
    return df


#: The vehicle file of docs/mobility.md (an HMMWV M1152 from its published data).
HMMWV = {
    "name": "HMMWV M1152",
    "kind": "wheeled",
    "drive": "all",
    "mobility_index_inputs": {
        "gross_weight": "13450 lb", "axles": 2, "tires": 4,
        "tire_width": "12.5 in", "tire_diameter": "37 in",
        "ground_clearance": "17.4 in", "engine_power": "190 hp",
        "transmission": "automatic", "chains": False,
    },
    "tire_deflection_ratio": 0.15,
    "wheel": {"load": "3363 lb", "diameter": "37 in", "width": "12.5 in"},
}  # fmt: skip
#: The tracked vehicle file of docs/mobility.md (an M113 from its published data).
M113 = {
    "name": "M113",
    "kind": "tracked",
    "mobility_index_inputs": {
        "gross_weight": "22900 lb", "track_width": "15 in", "track_contact_length": "105 in",
        "tracks": 2, "bogies": 10, "shoe_area": "90 in2", "grouser_height": "0 in",
        "ground_clearance": "16.1 in", "engine_power": "215 hp", "transmission": "automatic",
    },
}  # fmt: skip


def write_wide(path: Path, pushes: int = 6) -> None:
    """A wide table: one row per push, depths 0-30 cm every 2 cm, CI in MPa; 6 pushes on a
    line, more on a grid of 6 columns about 20 m apart."""
    z_cm = np.arange(0, 31, 2)
    head = ["plot", "point", "lat", "lon"] + [f"{z:g}" for z in z_cm]
    lines = ["# SYNTHETIC DATA: LETE sand, Penetrologger 1 cm2 cone", "Unit: MPa", ",".join(head)]
    for k in range(pushes):
        ci = synthetic_ci(z_cm / 100, 40 + k, cone="penetrologger-1cm2") / 1000
        lat, lon = (
            (-34.38 - 0.001 * k, 19.175)
            if pushes == 6
            else (-34.38 - 0.0002 * (k // 6), 19.175 + 0.0002 * (k % 6))
        )
        where = [("north", "south")[2 * k // pushes], f"P{k + 1}", f"{lat:.4f}", f"{lon:.4f}"]
        lines.append(",".join(where + [f"{c:.4f}" for c in ci]))
    path.write_text("\n".join(lines) + "\n")


def write_sc900(path: Path) -> None:
    """A FieldScout SC900 export: 4 pushes, 0-45 cm every 2.5 cm, kPa, 1/2 inch cone."""
    z_cm = np.arange(0, 45.1, 2.5)
    labels = ",".join(f"{z:.1f} cm" for z in z_cm)
    lines = [
        "Name: SYNTHETIC_LETE",
        "Serial #:  0001",
        "Datum: WGS 84",
        "Soil Compation In KPa",
        f"Longitude,Latitude,Number,{labels},Cone Size",
        ",,Logger Started",
    ]
    for k in range(4):
        ci = synthetic_ci(z_cm / 100, 60 + k, cone="asabe-small")
        cells = " , ".join(f"{c:.0f}" for c in ci)
        lines.append(f"19.175,-34.38{k},N= {k + 1} , {cells} ,1/2 Inch")
    path.write_text("\n".join(lines) + "\n")


def write_shear(path: Path) -> None:
    lines = ["# SYNTHETIC DATA", "test,normal_pressure_kpa,shear_displacement_mm,shear_stress_kpa"]
    for sig in (10.0, 20.0, 40.0):
        for j in np.arange(0.0, 101.0, 5.0):
            tau = (1.3 + sig * np.tan(np.radians(31.1))) * (1 - np.exp(-j / 12.0))
            lines.append(f"s{sig:g},{sig:g},{j:g},{tau:.4f}")
    path.write_text("\n".join(lines) + "\n")


def terracone(*args: str, cwd: Path) -> None:
    exe = Path(sys.executable).with_name("terracone")
    env = {**os.environ, "TERRACONE_NUMBA": "0"}  # as the examples run (see run_block)
    subprocess.run(
        [str(exe), *args], cwd=cwd, env=env, check=True, capture_output=True, timeout=TIMEOUT
    )


@pytest.fixture(scope="session")
def workspace(tmp_path_factory) -> Path:
    """The folder of example files every page starts from (see the module docstring)."""
    ws = tmp_path_factory.mktemp("docs") / "workspace"
    ws.mkdir()
    ex = example_dir()
    ci = pd.read_csv(ex / "lete_sand_synthetic_ci.csv", comment="#")
    plots = {"LS_syn_1": "north", "LS_syn_2": "north", "LS_syn_3": "south"}
    ci["plot"] = ci["profile"].map(plots)
    ci["lat"] = ci["profile"].map({p: -34.38 - 0.001 * k for k, p in enumerate(plots)})
    ci["lon"] = 19.175
    for name in ("CI.csv", "site.csv", "small.csv"):
        ci.to_csv(ws / name, index=False)
    for name in ("profiles.parquet", "PROFILES.parquet"):
        ci.to_parquet(ws / name, index=False)
    for name in ("PLATES.csv", "plates.csv"):
        shutil.copy(ex / "lete_sand_synthetic_plates.csv", ws / name)
    write_long_ci(ws / "OTHER_CI.csv", 2, seed=20)
    write_long_ci(ws / "big.csv", 200, seed=100)
    for folder in ("big", "field-data"):
        (ws / folder).mkdir()
        write_long_ci(ws / folder / "a.csv", 100, seed=100)
        write_long_ci(ws / folder / "b.csv", 100, seed=200, first=101)
    write_shear(ws / "SHEAR.csv")
    write_wide(ws / "pushes.csv")
    write_wide(ws / "survey.csv", 30)
    write_sc900(ws / "PokeMe.txt")
    shutil.copy(ws / "PokeMe.txt", ws / "field.txt")
    shutil.copy(ws / "PokeMe.txt", ws / "sc900_export.txt")
    (ws / "hmmwv.json").write_text(json.dumps(HMMWV, indent=1))
    (ws / "m113.json").write_text(json.dumps(M113, indent=1))
    terracone("learn", "--ci", "CI.csv", "--plates", "PLATES.csv", "--save", "cal.json", cwd=ws)
    shutil.copy(ws / "cal.json", ws / "sand.json")
    survey = ["--format", "wide", "--depth-unit", "cm", "--calibration", "sand.json", "--json"]
    terracone("predict", "survey.csv", *survey, "--out", "survey.json", cwd=ws)
    terracone(
        "predict", "CI.csv", "--plates", "1.5in,2.5in", "--json", "--out", "predict.json", cwd=ws
    )
    pred = ["--depth-unit", "cm", "--uncertainty", "--draws", "500", "--json", "--out", "pred.json"]
    terracone("predict", "pushes.csv", *pred, cwd=ws)
    from terracone.apps.batch import run_batch
    from terracone.apps.workflow import Reading

    reading = Reading(depth_unit="cm", ci_unit="mpa", cone="penetrologger-1cm2")
    with disabled():  # in this process, with the numpy kernels as well
        run_batch(ws / "pushes.csv", ws / "batch_out", reading=reading, progress=False, pool=map)
    return ws


# ---------------------------------------------------------------------------
# running the examples
# ---------------------------------------------------------------------------


def shell_code(block: Block) -> str:
    code = block.code
    if block.lang == "console":
        code = "\n".join(ln[2:] for ln in code.splitlines() if ln.startswith("$ ")) + "\n"
    for written, run, _ in SHORTENED:
        code = code.replace(written, run)
    return code


def needs(block: Block) -> str | None:
    """Why the block cannot run here, or None."""
    if "../shared" in block.code and not shared_dir().exists():
        return f"../shared not found: {shared_dir()} is read by this example"
    if "BrowserSession" in block.code and find_chromium() is None:
        return "chromium not installed: this example drives a browser"
    return None


def run_block(block: Block, folder: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["TERRACONE_LIBRARY"] = str(folder / "library.sqlite")
    env["TERRACONE_NUMBA"] = "0"  # small jobs: no kernel loading, whatever the cache holds
    if "--layers" in block.code or "fit_layered" in block.code:
        # the layered posterior is minutes on the numpy twins, seconds compiled
        env["TERRACONE_NUMBA"] = "1"
    env["MPLBACKEND"] = "Agg"
    # the report page's browser helper, tests/chromium.py; PyChrono's stand-in unless installed;
    # the caller's path kept (a worktree under test is found before an installed terracone, as
    # in the fixture's runs)
    paths = [ROOT / "tests"] + (
        [ROOT / "tests" / "standin"] if find_spec("pychrono") is None else []
    )
    caller = [env["PYTHONPATH"]] if env.get("PYTHONPATH") else []
    env["PYTHONPATH"] = os.pathsep.join([str(p) for p in paths] + caller)
    env.pop("TERRACONE_WHEEL", None)
    if block.lang == "python":
        script = folder / f"example_{block.line}.py"
        script.write_text(block.code)
        cmd = [sys.executable, script.name]
    else:
        cmd = ["bash", "-e", "-o", "pipefail", "-c", shell_code(block)]
    return subprocess.run(cmd, cwd=folder, env=env, capture_output=True, text=True, timeout=TIMEOUT)


def run_page(page: Path, workspace: Path) -> dict[str, subprocess.CompletedProcess | str]:
    """Run the examples of one page in order, in a copy of the workspace.

    Returns block name -> the finished process, or the reason it was not run.
    """
    folder = workspace.parent / page.stem
    shutil.copytree(workspace, folder, symlinks=True)
    out: dict[str, subprocess.CompletedProcess | str] = {}
    for block in EXAMPLES:
        if block.page == page:
            out[block.name] = needs(block) or run_block(block, folder)
    return out


@pytest.fixture(scope="session")
def outcomes(request, workspace) -> dict[str, subprocess.CompletedProcess | str]:
    """The outcome of every selected example: the pages run two at a time (2 cores)."""
    selected = {
        item.callspec.params["block"].page
        for item in request.session.items
        if item.originalname == "test_example_runs"
    }
    link = workspace.parent / "shared"  # ../shared as seen from a page folder
    if shared_dir().exists():
        link.symlink_to(shared_dir())
    order = sorted(selected, key=lambda p: -sum(b.page == p for b in EXAMPLES))
    out: dict[str, subprocess.CompletedProcess | str] = {}
    with ThreadPoolExecutor(2) as pool:
        for result in pool.map(lambda page: run_page(page, workspace), order):
            out.update(result)
    return out


@pytest.mark.parametrize("block", EXAMPLES, ids=[b.name for b in EXAMPLES])
def test_example_runs(block, outcomes):
    r = outcomes[block.name]
    if isinstance(r, str):
        missing(r)
    assert r.returncode == 0, (
        f"{block.name} failed ({r.returncode}):\n{block.code}\n--- stdout\n{r.stdout[-3000:]}"
        f"\n--- stderr\n{r.stderr[-3000:]}"
    )
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    printed = SINKAGE.findall(r.stdout)  # an exported PyChrono module run as a script
    if SCRIPT.search(shell_code(block) if block.lang != "python" else ""):
        assert printed, f"{block.name} runs a PyChrono module but printed no sinkage:\n{r.stdout}"
    for sinkage, static in printed:
        assert 0 < float(sinkage) == float(static), (block.name, sinkage, static)


#: A shell line that runs an exported PyChrono module, and the line that module prints
#: (terracone.apps.chrono): the plate's sinkage and the static sinkage SCM's grid gives.
SCRIPT = re.compile(r"^python3? \S+_soil\.py", re.M)
SINKAGE = re.compile(r"sinkage (\S+) m after [\d.]+ s \(static on SCM's grid: (\S+) m;")


def test_the_docs_run_a_pychrono_module_as_a_script():
    assert any(SCRIPT.search(shell_code(b)) for b in EXAMPLES if b.lang != "python")


def test_shortened_commands_are_in_the_docs():
    text = "\n".join(b.code for b in EXAMPLES)
    for written, _, why in SHORTENED:
        assert written in text, f"{written!r} is no longer in the docs: remove it ({why})"


def test_strict_site_build_checks_links_and_anchors():
    """``mkdocs build --strict`` (.ci/run) fails on a link to a missing page or anchor only
    while mkdocs.yml asks it to warn about them (``validation``, mkdocs >= 1.6, the pin of
    the docs extra); the root README is not part of the site: its links are checked here."""
    config = (ROOT / "mkdocs.yml").read_text()
    validation = config[config.index("\nvalidation:") :].split("\n\n")[0]
    for key in ("omitted_files", "absolute_links", "unrecognized_links", "anchors"):
        assert f"\n  {key}: warn" in validation, key
    assert '"mkdocs>=1.6"' in (ROOT / "pyproject.toml").read_text()
    links = re.findall(r"\]\(([^)#\s]+)(#[^)\s]*)?\)", (ROOT / "README.md").read_text())
    local = [target for target, _ in links if not re.match(r"^[a-z]+:", target)]
    assert local and all((ROOT / t).exists() for t in local), local

"""The release: what a wheel must carry (issue 23).

The static tests read pyproject.toml and the source tree: every file of the package that
is not Python is matched by a ``package-data`` pattern (else the wheel would silently lack
it), and the metadata carries the licence, classifiers and ``py.typed``.

``test_wheel_holds_the_package`` opens a built wheel: the one named by ``TERRACONE_WHEEL``
(``.ci/run`` builds it with ``python -m build`` and sets it), else it is skipped with the
reason.  ``.ci/run`` then installs that wheel into a fresh virtual environment and runs
``terracone demo`` outside the source tree.
"""

from __future__ import annotations

import fnmatch
import os
import tomllib
import zipfile
from email.parser import Parser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "terracone"


def pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def package_files() -> list[str]:
    """Files of the package as paths relative to the repository (no caches)."""
    out = []
    for path in sorted(PACKAGE.rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc":
            out.append(path.relative_to(ROOT).as_posix())
    return out


def matches(rel: str, pattern: str) -> bool:
    """setuptools' package-data glob: ``**`` spans folders, ``*`` stays in one."""
    if "**/" in pattern:
        return matches(rel, pattern.replace("**/", "")) or fnmatch.fnmatch(rel, pattern)
    return fnmatch.fnmatch(rel, pattern) and rel.count("/") == pattern.count("/")


def test_the_glob_by_hand():
    assert matches("data/example/a.csv", "data/**/*.csv")
    assert matches("data/a.csv", "data/**/*.csv")
    assert matches("data/a.csv", "data/*.csv")
    assert not matches("data/example/a.csv", "data/*.csv")
    assert not matches("data/a.json", "data/**/*.csv")


def test_every_data_file_of_the_package_is_package_data():
    patterns = pyproject()["tool"]["setuptools"]["package-data"]["terracone"]
    data = [f[len("terracone/") :] for f in package_files() if not f.endswith(".py")]
    assert "py.typed" in data
    assert any(f.startswith("data/example/") for f in data)
    missing = [f for f in data if not any(matches(f, p) for p in patterns)]
    assert missing == [], f"not in [tool.setuptools.package-data]: {missing}"


def test_metadata_licence_classifiers_typed():
    project = pyproject()["project"]
    assert project["license"] == "MIT"
    assert project["license-files"] == ["LICENSE"]
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License")
    assert "terracone developers" in text.splitlines()[2]
    classifiers = project["classifiers"]
    assert "Typing :: Typed" in classifiers
    assert "Intended Audience :: Science/Research" in classifiers
    # a licence expression and a licence classifier together are refused by setuptools
    assert not any(c.startswith("License ::") for c in classifiers)
    py = [
        c.rsplit(" ", 1)[-1]
        for c in classifiers
        if c.startswith("Programming Language :: Python :: 3.")
    ]
    assert py and min(py) == project["requires-python"].removeprefix(">=")
    assert project["scripts"] == {"terracone": "terracone.cli:main"}


@pytest.fixture(scope="module")
def wheel() -> zipfile.ZipFile:
    path = os.environ.get("TERRACONE_WHEEL")
    if not path:
        pytest.skip("no built wheel: TERRACONE_WHEEL names one (.ci/run builds it)")
    return zipfile.ZipFile(path)


def test_wheel_holds_the_package(wheel):
    names = set(wheel.namelist())
    missing = [f for f in package_files() if f not in names]
    assert missing == [], f"files of the package missing from the wheel: {missing}"
    info = [n for n in names if n.endswith(".dist-info/METADATA")]
    assert len(info) == 1
    meta = Parser().parsestr(wheel.read(info[0]).decode())
    assert meta["License-Expression"] == "MIT"
    assert meta["Name"] == "terracone"
    assert "Typing :: Typed" in meta.get_all("Classifier")
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    entry = [n for n in names if n.endswith(".dist-info/entry_points.txt")]
    assert "terracone = terracone.cli:main" in wheel.read(entry[0]).decode()
    assert not any(n.startswith(("tests/", "docs/", "benchmarks/")) for n in names)

"""Shared test helpers.

``../shared`` (the project's shared folder beside the repository, with the
paper, the reference tables and the real measurements) is read only by the
tests that check real files; ``TERRACONE_SHARED`` names another folder (an
empty one shows what runs without it).  Where a test needs it, or a browser,
and it is absent, the test skips with the reason, except in CI (``CI`` set,
as ``.ci/run`` does), where it fails: CI never passes by skipping.

hypothesis runs with a fixed profile, ``terracone``: derandomised (the same
examples on every run and machine, so a failure reproduces) and without an
example database (tests write nothing outside their tmp folders).  Set
``HYPOTHESIS_PROFILE=random`` to explore with fresh random examples instead.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import NoReturn

import pytest
from hypothesis import settings

# The suite tests the compiled kernels themselves, compiled on demand (TERRACONE_NUMBA=1),
# not the default policy of using them once a background warm-up has cached them, which
# would make the path under test depend on timing (tests/test_jit.py tests that policy);
# CI's second run sets TERRACONE_NUMBA=0.
os.environ.setdefault("TERRACONE_NUMBA", "1")

settings.register_profile("terracone", derandomize=True, database=None, print_blob=True)
settings.register_profile("random", derandomize=False, database=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "terracone"))


def in_ci() -> bool:
    """True in a CI run: the environment variable ``CI`` is set and not ``0``/``false``."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def missing(reason: str) -> NoReturn:
    """A test cannot run for want of ``reason``: skip it, or in CI fail it."""
    if in_ci():
        pytest.fail(f"{reason} (CI: a missing dependency fails)", pytrace=False)
    pytest.skip(reason)


def shared_dir() -> Path:
    """The shared folder: ``$TERRACONE_SHARED``, else ``../shared`` beside the repository
    (may not exist)."""
    env = os.environ.get("TERRACONE_SHARED")
    if env:
        return Path(env).resolve()
    return Path(__file__).resolve().parents[1].parent / "shared"


def require_shared(*parts: str) -> Path:
    """Path of a file or folder under the shared folder; skip the test when absent (fail
    in CI)."""
    path = shared_dir().joinpath(*parts)
    if not path.exists():
        missing(f"../shared not found: {path} is needed by this test")
    return path


@pytest.fixture
def shared() -> Path:
    """The shared folder as a fixture (skips the test when it is absent, fails in CI)."""
    return require_shared()


def require_chromium() -> str:
    """Path of the headless Chromium (see tests/chromium.py); skip when absent (fail in CI)."""
    from chromium import find_chromium

    exe = find_chromium()
    if exe is None:
        missing(
            "headless Chromium not found ($TERRACONE_CHROMIUM, /usr/bin/chromium, or chromium "
            "or chromium-browser on PATH): install Debian's chromium package, as .ci/run does"
        )
    return exe


#: The columns of the package's copies of Tables 4-1 and 4-3 (terracone/data/paper/) under
#: the names of ../shared/reference/huang2020_predicted_parameters.csv.
PAPER_COLUMNS = {
    "kc_kn_m": "kc_si",
    "kc_lb_in": "kc_us",
    "kphi_kn_m": "kphi_si",
    "kphi_lb_in": "kphi_us",
}


def paper_parameter_rows() -> list[dict[str, str]]:
    """Tables 4-1 and 4-3 of Huang et al. as printed (strings), from the package's copies,
    with the shared reference's column names (``dataset, kc_si, kc_us, kphi_si, kphi_us, n,
    cc_kpa, cc_psi, phic_deg``); tests/test_paper_tables.py holds them equal to the
    independently typed ``../shared/reference/huang2020_predicted_parameters.csv``."""
    from terracone.apps.reproduce.paper import paper_dir

    rows = []
    for name in ("table_4_1.csv", "table_4_3.csv"):
        with open(paper_dir() / name, newline="") as fh:
            lines = [ln for ln in fh if ln.strip() and not ln.startswith("#")]
        rows += [{PAPER_COLUMNS.get(k, k): v for k, v in r.items()} for r in csv.DictReader(lines)]
    return rows

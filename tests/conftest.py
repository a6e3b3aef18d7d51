"""Shared test helpers.

``../shared`` (the project's shared folder beside the repository, with the
paper and the reference tables) is optional: tests that need it skip with a
stated reason when it is absent.

hypothesis runs with a fixed profile, ``terracone``: derandomised (the same
examples on every run and machine, so a failure reproduces) and without an
example database (tests write nothing outside their tmp folders).  Set
``HYPOTHESIS_PROFILE=random`` to explore with fresh random examples instead.
"""

from __future__ import annotations

import os
from pathlib import Path

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


def shared_dir() -> Path:
    """Path of ``../shared`` relative to the repository root (may not exist)."""
    return Path(__file__).resolve().parents[1].parent / "shared"


def require_shared(*parts: str) -> Path:
    """Path of a file or folder under ``../shared``; skip the test when absent."""
    path = shared_dir().joinpath(*parts)
    if not path.exists():
        pytest.skip(f"../shared not found: {path} is needed by this test")
    return path


@pytest.fixture
def shared() -> Path:
    """``../shared`` as a fixture (skips the test when the folder is absent)."""
    return require_shared()

"""Shared test helpers.

``../shared`` (the project's shared folder beside the repository, with the
paper and the reference tables) is optional: tests that need it skip with a
stated reason when it is absent.
"""

from __future__ import annotations

from pathlib import Path

import pytest


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

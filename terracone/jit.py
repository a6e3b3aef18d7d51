"""Optional compilation of hot kernels with numba.

Every compiled kernel in terracone has a plain numpy twin that stays the tested
reference.  ``njit`` here is numba's ``njit(cache=True)`` when numba is usable
and compilation is enabled, and the identity otherwise, so the same Python
source runs either way.

Environment
-----------
TERRACONE_NUMBA
    ``0`` disables compilation (the kernels run as plain Python/numpy).  CI
    runs the test suite once more with it set, so results with and without the
    compiled kernels are checked to agree.
NUMBA_CACHE_DIR
    Where compiled kernels are cached.  When it is unset and the package
    directory is not writable (a system or read-only install, or a Dask worker
    with another user), it is set to ``~/.cache/terracone/numba`` (or
    ``$XDG_CACHE_HOME/terracone/numba``) before numba is imported.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["ENABLED", "njit", "cache_dir"]


def cache_dir() -> Path:
    """The user cache directory for compiled kernels."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "terracone" / "numba"


def _setup_cache() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    pkg = Path(__file__).resolve().parent
    if not os.access(pkg, os.W_OK):
        d = cache_dir()
        d.mkdir(parents=True, exist_ok=True)
        os.environ["NUMBA_CACHE_DIR"] = str(d)


def _enabled() -> bool:
    if os.environ.get("TERRACONE_NUMBA", "1").strip() == "0":
        return False
    try:
        _setup_cache()
        import numba  # noqa: F401
    except Exception:  # numba missing or broken: run the numpy/Python twins
        return False
    return True


ENABLED: bool = _enabled()


def njit(*args: Any, **kwargs: Any) -> Callable[..., Any]:
    """``numba.njit(cache=True, ...)`` when enabled, else the identity decorator.

    Use as ``@njit`` or ``@njit(fastmath=False)``.
    """
    if ENABLED:
        import numba

        kwargs.setdefault("cache", True)
        return numba.njit(*args, **kwargs)
    if args and callable(args[0]) and len(args) == 1 and not kwargs:
        return args[0]
    return lambda f: f

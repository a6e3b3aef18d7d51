"""Optional compilation of hot kernels with numba.

``njit`` is numba's ``njit(cache=True)`` when numba is usable and compilation
is enabled, the identity otherwise; every compiled kernel has a plain numpy
twin that stays the tested reference.  numba is imported on a kernel's first
call (importing it costs about 0.4 s), not at import time.

Environment
-----------
TERRACONE_NUMBA
    ``0`` disables compilation (kernels run as plain Python/numpy, solvers
    take their numpy paths).
NUMBA_CACHE_DIR
    Where compiled kernels are cached.  Unset while the package directory is
    not writable: set to ``$XDG_CACHE_HOME/terracone/numba`` (default
    ``~/.cache/terracone/numba``) before numba is imported.
"""

from __future__ import annotations

import contextlib
import functools
import os
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

__all__ = ["njit", "enabled", "disabled"]

_state: dict[str, Any] = {"enabled": None, "forced_off": 0}
_lazy: list[_LazyKernel] = []


def _setup_cache() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    pkg = Path(__file__).resolve().parent
    probe = pkg / "__pycache__"
    if not (os.access(pkg, os.W_OK) and (not probe.exists() or os.access(probe, os.W_OK))):
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        d = Path(base) / "terracone" / "numba"
        d.mkdir(parents=True, exist_ok=True)
        os.environ["NUMBA_CACHE_DIR"] = str(d)


def _switch_on() -> bool:
    return os.environ.get("TERRACONE_NUMBA", "1").strip() != "0"


def _numba_usable() -> bool:
    if _state["enabled"] is None:
        ok = _switch_on()
        if ok:
            try:
                _setup_cache()
                import numba  # noqa: F401
            except Exception as exc:  # numba missing or broken: run the numpy/Python twins
                warnings.warn(
                    f"terracone: numba cannot be imported ({type(exc).__name__}: {exc}); "
                    "running the numpy kernels (set TERRACONE_NUMBA=0 to silence this)",
                    RuntimeWarning,
                    stacklevel=3,
                )
                ok = False
        _state["enabled"] = ok
    return bool(_state["enabled"])


def enabled() -> bool:
    """True when compiled kernels are used (imports numba on the first call).

    False when ``TERRACONE_NUMBA=0``, when numba cannot be imported, or inside
    :func:`disabled`.
    """
    if _state["forced_off"] or not _switch_on():
        return False
    return _numba_usable()


@contextlib.contextmanager
def disabled() -> Iterator[None]:
    """Run the numpy reference paths inside this block (tests and benchmarks)."""
    _state["forced_off"] += 1
    try:
        yield
    finally:
        _state["forced_off"] -= 1


class _LazyKernel:
    """A kernel whose numba dispatcher is built on first use.

    Building one builds all (no compilation yet: numba compiles per signature
    on the first call, or loads it from the cache), and each dispatcher
    replaces the lazy object in its module's globals, so kernels calling
    kernels see numba dispatchers when they are compiled.
    """

    def __init__(self, func: Callable[..., Any], options: dict[str, Any]) -> None:
        self.py_func = func
        self._options = options
        self._dispatcher: Any = None
        functools.update_wrapper(self, func)
        _lazy.append(self)

    def _build(self) -> Callable[..., Any]:
        if self._dispatcher is None:
            if not _numba_usable():
                return self.py_func
            import numba

            for k in list(_lazy):
                if k._dispatcher is None:
                    k._dispatcher = numba.njit(**k._options)(k.py_func)
                    g = k.py_func.__globals__
                    if g.get(k.py_func.__name__) is k:
                        g[k.py_func.__name__] = k._dispatcher
        return self._dispatcher

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self._build()(*args, **kwargs)


def njit(func: Callable[..., Any] | None = None, **options: Any) -> Any:
    """``numba.njit(cache=True, ...)`` when enabled, else the identity decorator.

    Use as ``@njit`` or ``@njit(error_model="numpy")``.  numba is imported on
    the kernel's first call, not here.
    """
    options.setdefault("cache", True)

    def wrap(f: Callable[..., Any]) -> Callable[..., Any]:
        return _LazyKernel(f, options) if _switch_on() else f

    return wrap if func is None else wrap(func)

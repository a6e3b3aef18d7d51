"""Optional compilation of hot kernels with numba.

Every compiled kernel in terracone has a plain numpy twin that stays the tested
reference.  ``njit`` here is numba's ``njit(cache=True)`` when numba is usable
and compilation is enabled, and the identity otherwise, so the same Python
source runs either way.

Nothing here imports numba at import time (importing numba alone costs about
0.4 s): :func:`njit` returns a lazy kernel that imports numba and builds the
dispatcher on its first call, and :func:`enabled` imports numba only when it
is asked.  So ``terracone --help`` or a command that never reaches a kernel
neither imports numba nor compiles anything; the first call of a kernel loads
it from the on-disk cache (or compiles it once, when the cache is cold).

Environment
-----------
TERRACONE_NUMBA
    ``0`` disables compilation (the kernels run as plain Python/numpy and the
    solvers take their numpy paths).  CI runs the kernel and solver tests once
    more with it set, so results with and without the compiled kernels are
    checked to agree.
NUMBA_CACHE_DIR
    Where compiled kernels are cached.  When it is unset and the package
    directory is not writable (a system or read-only install, or a Dask worker
    with another user), it is set to ``~/.cache/terracone/numba`` (or
    ``$XDG_CACHE_HOME/terracone/numba``) before numba is imported.
"""

from __future__ import annotations

import contextlib
import functools
import os
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

__all__ = ["njit", "cache_dir", "enabled", "disabled"]

_state: dict[str, Any] = {"enabled": None, "forced_off": 0}
_lazy: list[_LazyKernel] = []


def cache_dir() -> Path:
    """The user cache directory for compiled kernels."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "terracone" / "numba"


def _setup_cache() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    pkg = Path(__file__).resolve().parent
    probe = pkg / "__pycache__"
    if not (os.access(pkg, os.W_OK) and (not probe.exists() or os.access(probe, os.W_OK))):
        d = cache_dir()
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


def njit(*args: Any, **kwargs: Any) -> Callable[..., Any]:
    """``numba.njit(cache=True, ...)`` when enabled, else the identity decorator.

    Use as ``@njit`` or ``@njit(error_model="numpy")``.  numba is imported on
    the kernel's first call, not here.
    """
    if not _switch_on():
        if args and callable(args[0]) and len(args) == 1 and not kwargs:
            return args[0]
        return lambda f: f
    kwargs.setdefault("cache", True)
    if args and callable(args[0]) and len(args) == 1:
        return _LazyKernel(args[0], dict(kwargs))
    if args:  # explicit signatures: eager, as numba does
        import numba

        _setup_cache()
        return numba.njit(*args, **kwargs)
    return lambda f: _LazyKernel(f, dict(kwargs))

"""Optional compilation of hot kernels with numba, and when to wait for it.

Every compiled kernel in terracone has a plain numpy twin that stays the tested
reference.  ``njit`` here is numba's ``njit(cache=True)`` when compilation is
possible, and the identity otherwise, so the same Python source runs either way.

Nothing here imports numba at import time (importing numba alone costs about
0.4 s): :func:`njit` returns a lazy kernel that imports numba and builds the
dispatcher on its first compiled call, and :func:`enabled` imports numba only
when the compiled kernels are to be used.  So ``terracone --help`` or a command
that never reaches a kernel neither imports numba nor compiles anything.

No silent wait
--------------
Compiling every kernel takes about half a minute of one core, once; loading
them from numba's on-disk cache afterwards takes well under a second.  By
default (``TERRACONE_NUMBA`` unset) a run uses the compiled kernels only when
the cache holds them all (:func:`ready`: a marker that the warm-up writes when
it has compiled them for this terracone, numba and CPU).  While it does not, the
solvers take their numpy paths, which reach the same optima, and the first such
run starts the warm-up (``python -m terracone.apps.warmup``) in a detached
background process at low priority, saying so once on stderr; a run that finds
it compiling leaves it be (a lock file), and a long run switches to the compiled
kernels as soon as the marker appears.

Environment
-----------
TERRACONE_NUMBA
    Unset (or ``auto``): as above.  ``1``: always the compiled kernels,
    compiled in this process when the cache lacks them (saying so once on a
    terminal's stderr, when numba does compile); the test suite runs so.  ``0``: never (the kernels run as plain
    Python/numpy and the solvers take their numpy paths); CI runs the solver
    tests once more so, to check that both paths agree.
NUMBA_CACHE_DIR
    Where compiled kernels (and the marker) are cached.  When it is unset
    they go to ``__pycache__`` beside the sources, or, when the package
    directory is not writable (a system or read-only install, or a Dask worker
    with another user), to ``~/.cache/terracone/numba`` (or
    ``$XDG_CACHE_HOME/terracone/numba``), set before numba is imported.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import platform
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from importlib import metadata, util
from pathlib import Path
from typing import Any

__all__ = [
    "njit",
    "cache_dir",
    "enabled",
    "disabled",
    "mode",
    "ready",
    "mark_ready",
    "marker_path",
    "warmup_lock",
    "start_warmup",
    "warm_up_if_cold",
    "wait_for_warmup",
    "warmup_pid",
    "WARMUP_MODULE",
    "KERNEL_SOURCES",
]

#: The module that fills the cache when run with ``python -m`` (compiles every kernel).
WARMUP_MODULE = "terracone.apps.warmup"
#: The sources that define kernels, relative to the package (their size and time
#: stamp key the marker, as they key numba's own cache).
KERNEL_SOURCES = (
    "inverse/layered/sampler.py",
    "inverse/learning/kernels.py",
    "inverse/solver/kernels.py",
    "inverse/solver/layered_kernels.py",
    "inverse/solver/polish.py",
    "inverse/uncertainty/likelihood.py",
    "physics/metrics.py",
)
#: What the message says the warm-up takes [s of one core] (about 20 s on the 2-core
#: machines terracone is developed on, 60 s on slower ones).
COMPILE_S = 30
_PKG = Path(__file__).resolve().parent

_state: dict[str, Any] = {
    "numba": None,  # numba importable (None: not asked yet)
    "forced_off": 0,
    "ready": False,
    "checked": -1e9,  # monotonic time of the last look for the marker
    "spawned": False,
    "told": False,
    "listening": False,
}
_lazy: list[_LazyKernel] = []


def cache_dir() -> Path:
    """The user cache directory for compiled kernels."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "terracone" / "numba"


def _setup_cache() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    probe = _PKG / "__pycache__"
    if not (os.access(_PKG, os.W_OK) and (not probe.exists() or os.access(probe, os.W_OK))):
        d = cache_dir()
        d.mkdir(parents=True, exist_ok=True)
        os.environ["NUMBA_CACHE_DIR"] = str(d)


def mode() -> str:
    """``"auto"``, ``"on"`` or ``"off"``: the setting of ``TERRACONE_NUMBA`` (unset, 1, 0)."""
    v = os.environ.get("TERRACONE_NUMBA", "auto").strip().lower()
    return {"0": "off", "off": "off", "1": "on", "on": "on"}.get(v, "auto")


def _numba_usable() -> bool:
    if _state["numba"] is None:
        ok = mode() != "off"
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
        _state["numba"] = ok
    return bool(_state["numba"])


def _cpu() -> str:
    """The CPU's model and features (numba compiles for them)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            text = f.read(65536)
    except OSError:
        return platform.processor()
    keep = [ln for ln in text.splitlines() if ln.startswith(("model name", "flags"))][:2]
    return "\n".join(keep)


@functools.lru_cache(maxsize=1)
def _key() -> str:
    """What the compiled kernels depend on: sources, numba and llvmlite, Python, CPU."""
    parts = [str(_PKG), sys.version, platform.machine(), _cpu()]
    for dist in ("numba", "llvmlite"):
        try:
            parts.append(metadata.version(dist))
        except metadata.PackageNotFoundError:
            parts.append("-")
    for rel in KERNEL_SOURCES:
        try:
            st = (_PKG / rel).stat()
        except OSError:  # no source beside the package (a zip): numba caches nothing either
            parts.append(f"{rel} -")
            continue
        parts.append(f"{rel} {st.st_size} {st.st_mtime_ns}")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


def _marker_dir() -> Path:
    with contextlib.suppress(OSError):  # no writable cache anywhere: the marker never appears
        _setup_cache()
    d = os.environ.get("NUMBA_CACHE_DIR")
    return Path(d) if d else _PKG / "__pycache__"


def marker_path() -> Path:
    """The file that says the cache holds every kernel for this terracone, numba and CPU."""
    return _marker_dir() / f"terracone-kernels-{_key()}.ready"


def ready() -> bool:
    """True when the cache holds the compiled kernels (the warm-up finished).

    Looked up at most once a second while false, so a long run notices a
    background warm-up finishing.
    """
    if not _state["ready"]:
        now = time.monotonic()
        if now - _state["checked"] >= 1.0:
            _state["checked"] = now
            _state["ready"] = marker_path().exists()
    return bool(_state["ready"])


def mark_ready() -> None:
    """Write the marker (the warm-up calls this once every kernel is compiled)."""
    path = marker_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_text(f"compiled by terracone {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
    os.replace(tmp, path)
    _state["ready"] = True


#: The environment variable through which a starting run hands its held lock to the warm-up.
_LOCK_FD = "TERRACONE_WARMUP_LOCK_FD"


@contextlib.contextmanager
def warmup_lock(blocking: bool = False) -> Iterator[bool]:
    """Hold the warm-up's lock file (``terracone-kernels.lock`` beside the marker); yields
    False when another process holds it (``blocking=False``).  Released when the block ends
    or the process dies.  The holder writes its process id into the file.  A warm-up that
    :func:`start_warmup` started finds the lock already taken for it (inherited, so no other
    run can slip in between) and keeps it.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock, at worst two compile
        yield True
        return
    inherited = os.environ.pop(_LOCK_FD, None)
    if inherited is not None:
        f = os.fdopen(int(inherited), "r+b")
    else:
        d = _marker_dir()
        d.mkdir(parents=True, exist_ok=True)
        f = open(d / "terracone-kernels.lock", "a+b")  # noqa: SIM115 - closed below
    with f:
        if inherited is None:
            try:
                fcntl.flock(f, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
            except BlockingIOError:
                yield False
                return
        try:
            f.seek(0)
            f.truncate(0)
            f.write(f"{os.getpid()}\n".encode())  # who holds it
            f.flush()
            yield True
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _spawn(cmd: list[str], env: dict[str, str], fd: int | None) -> None:
    """Start ``cmd`` detached: sh starts it in the background and exits (no zombie is left);
    it inherits the descriptor ``fd`` (the held lock)."""
    if os.name == "posix":
        sh = ["/bin/sh", "-c", 'exec "$@" </dev/null >/dev/null 2>&1 &', "sh", *cmd]
        kw: dict[str, Any] = {"pass_fds": (fd,)} if fd is not None else {}
        subprocess.run(sh, env=env, cwd=_PKG.parent, start_new_session=True, check=True, **kw)
    else:  # pragma: no cover
        flags = getattr(subprocess, "DETACHED_PROCESS", 0) | getattr(
            subprocess, "CREATE_NEW_PROCESS_GROUP", 0
        )
        subprocess.Popen(cmd, env=env, cwd=_PKG.parent, creationflags=flags, close_fds=True)


def start_warmup() -> bool:
    """Start the warm-up in a detached background process, unless one runs already.

    Once per process; takes the warm-up's lock and hands it to the new process, so that
    runs starting meanwhile find it taken; says so once on stderr.  Returns whether it
    started one.
    """
    if _state["spawned"]:
        return False
    _state["spawned"] = True
    if util.find_spec("numba") is None:
        return not _numba_usable()  # warns once that numba is missing
    env = dict(os.environ, TERRACONE_NUMBA="1")
    cmd = [sys.executable, "-m", WARMUP_MODULE]
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        fcntl = None
    try:
        d = _marker_dir()
        d.mkdir(parents=True, exist_ok=True)
        f = open(d / "terracone-kernels.lock", "a+b")  # noqa: SIM115 - closed below
    except OSError:  # nowhere to cache: numpy it stays
        return False
    with f:
        fd = None
        if fcntl is not None:
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:  # another process is compiling
                return False
            fd = f.fileno()
            env[_LOCK_FD] = str(fd)
        try:
            _spawn(cmd, env, fd)
        except (OSError, subprocess.CalledProcessError):  # no shell: numpy it stays
            if fcntl is not None:
                fcntl.flock(f, fcntl.LOCK_UN)
            return False
    # closing our descriptor leaves the lock with the warm-up's copy of it
    print(
        f"terracone: compiling the solver kernels in the background for later runs (about "
        f"{COMPILE_S} s of one core, once); this run uses their numpy twins",
        file=sys.stderr,
    )
    return True


def _lock_path(cache: Path | None) -> Path:
    return (_marker_dir() if cache is None else Path(cache)) / "terracone-kernels.lock"


def warmup_pid(cache: Path | None = None) -> int | None:
    """Process id of the warm-up that holds (or last held) the lock of ``cache`` (default:
    this process's cache directory), or None."""
    path = _lock_path(cache)
    text = path.read_text().split() if path.exists() else []
    return int(text[0]) if text else None


def wait_for_warmup(timeout: float, cache: Path | None = None) -> bool:
    """Wait until a background warm-up has written its marker in ``cache`` (default: this
    process's cache directory) and let go of its lock; False after ``timeout`` [s].

    For scripts and tests that want the compiled kernels, or must not leave a warm-up
    behind; :func:`warmup_pid` names the process to end if it overstays.
    """
    import fcntl

    lock = _lock_path(cache)
    t0 = time.monotonic()
    while time.monotonic() - t0 <= timeout:
        if any(lock.parent.glob(f"terracone-kernels-{_key()}.ready")):
            with open(lock, "a+b") as f:
                try:
                    fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    pass  # still finishing
                else:
                    fcntl.flock(f, fcntl.LOCK_UN)
                    return True
        time.sleep(0.2)
    return False


def warm_up_if_cold() -> bool:
    """Start :func:`start_warmup` when the default policy finds the cache cold; True when the
    compiled kernels are cached.  Imports no numba (a batch's client, which fits nothing,
    calls it before starting its workers)."""
    if mode() != "auto" or ready():
        return ready()
    start_warmup()
    return False


def enabled() -> bool:
    """True when compiled kernels are used now (imports numba when they are).

    False when ``TERRACONE_NUMBA=0``, when numba cannot be imported, inside
    :func:`disabled`, and, by default, while the cache does not hold them
    (:func:`ready`; the first such call starts :func:`start_warmup`).
    """
    if _state["forced_off"]:
        return False
    m = mode()
    if m == "off":
        return False
    if m == "auto" and not ready():
        start_warmup()
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


def _tell_compiling() -> None:
    """Say once on a terminal's stderr that kernels are being compiled (numba found one
    missing from its cache), as progress bars do."""
    if _state["told"]:
        return
    _state["told"] = True
    if getattr(sys.stderr, "isatty", lambda: False)():
        print(
            f"terracone: compiling solver kernels (first run, about {COMPILE_S} s; "
            "cached for later runs)",
            file=sys.stderr,
        )


def _listen_for_compiles(numba: Any) -> None:
    """Call :func:`_tell_compiling` when numba compiles (a cache miss), not when it loads."""
    try:
        from numba.core import event
    except ImportError:  # pragma: no cover - numba without its event API
        return

    class _Tell(event.Listener):
        def on_start(self, ev: Any) -> None:
            _tell_compiling()

        def on_end(self, ev: Any) -> None:
            pass

    event.install_listener("numba:compile", _Tell())


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

            if not _state["listening"]:
                _state["listening"] = True
                _listen_for_compiles(numba)
            for k in list(_lazy):
                if k._dispatcher is None:
                    k._dispatcher = numba.njit(**k._options)(k.py_func)
                    g = k.py_func.__globals__
                    if g.get(k.py_func.__name__) is k:
                        g[k.py_func.__name__] = k._dispatcher
        return self._dispatcher

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        if not enabled():  # the numpy path: the kernel as Python
            return self.py_func(*args, **kwargs)
        return self._build()(*args, **kwargs)


def njit(*args: Any, **kwargs: Any) -> Callable[..., Any]:
    """``numba.njit(cache=True, ...)`` when enabled, else the identity decorator.

    Use as ``@njit`` or ``@njit(error_model="numpy")``.  numba is imported on
    the kernel's first call, not here.
    """
    if mode() == "off":
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

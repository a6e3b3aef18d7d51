"""When the compiled kernels are used (terracone.jit): no run waits for compilation.

By default a run with a cold kernel cache takes the numpy paths and starts one
detached background warm-up (``python -m terracone.apps.warmup``), which compiles
every kernel the commands reach and then writes the marker of ``jit.ready()``;
runs after it load the compiled kernels and compile nothing.  Each check runs in
fresh processes with their own empty cache directory (NUMBA_CACHE_DIR under
tmp_path), so nothing outside tmp_path is written; a warm-up a test started is
waited for, or ended by its process id when it overstays.
"""

from __future__ import annotations

import ast
import contextlib
import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from terracone import jit

ROOT = Path(__file__).resolve().parents[1]
COLD_NOTE = "terracone: compiling the solver kernels in the background for later runs"

pytestmark = pytest.mark.skipif(
    os.environ.get("TERRACONE_NUMBA") == "0", reason="kernels switched off (TERRACONE_NUMBA=0)"
)


def run_py(code: str, cache: Path, **env_extra: str) -> subprocess.CompletedProcess:
    """``code`` in a fresh Python with the default policy (TERRACONE_NUMBA unset)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "TERRACONE_N"))}
    env.update(NUMBA_CACHE_DIR=str(cache), **env_extra)
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=900,
    )


def wait_for_warmup(cache: Path, timeout: float = 900.0) -> None:
    """Wait for the background warm-up of ``cache``; end it by its process id (in its lock
    file) and fail if it takes longer than ``timeout``."""
    if not jit.wait_for_warmup(timeout, cache):
        with contextlib.suppress(ProcessLookupError, TypeError):
            os.kill(jit.warmup_pid(cache), signal.SIGTERM)
        pytest.fail(f"the warm-up of {cache} ran longer than {timeout:g} s")


SMALL_JOB = """
    import json, sys
    from terracone import jit
    from terracone.apps.example import example_dir
    from terracone.inverse.predict import predict_many
    from terracone.io import read_ci_profiles
    profiles = read_ci_profiles(example_dir() / "lete_sand_synthetic_ci.csv")
    res = predict_many(profiles[:1])
    print(json.dumps({"enabled": jit.enabled(), "numba": "numba" in sys.modules,
                      "rmsd": res[0].rmsd, "ready": jit.ready()}))
"""

#: What the commands run (tests/test_jit.py's list of them): after the warm-up, none of it
#: may compile.  Counted by numba's own statistics of each dispatcher.
COMMANDS = """
    import json
    from click.testing import CliRunner
    from terracone import jit
    from terracone.apps.example import example_dir
    from terracone.cli import cli
    d = example_dir()
    ci, pl = str(d / "lete_sand_synthetic_ci.csv"), str(d / "lete_sand_synthetic_plates.csv")
    one = {one!r}
    out = {{}}
    for args in (
        ["demo"],
        ["predict", one, "--json"],
        ["predict", one, "--uncertainty", "--draws", "100", "--json"],
        ["predict", one, "--model", "rm1", "--r-min", "1cm", "--plates", "5cm", "--json"],
        ["predict", one, "--bounds", "kc=1:400,phic=5:30", "--units", "us", "--json"],
        ["predict", one, "--layers", "2", "--json"],
        ["predict", ci, "--json"],
        ["learn", "--ci", ci, "--plates", pl, "--units", "us", "--json"],
        ["design", ci, "--plates", "5cm", "--json"],
    ):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 0, (args, r.output)
        if args[:2] == ["predict", one] and len(args) == 3:
            out["rmsd"] = json.loads(r.output)["profiles"][0]["rmsd"]
    from terracone.apps.batch import warm_kernels
    warm_kernels()
    out["enabled"] = jit.enabled()
    out["misses"] = {{
        k.py_func.__name__: sum(k._dispatcher.stats.cache_misses.values())
        for k in jit._lazy
        if k._dispatcher is not None and sum(k._dispatcher.stats.cache_misses.values())
    }}
    out["used"] = sorted(
        k.py_func.__name__ for k in jit._lazy if k._dispatcher is not None and k._dispatcher.signatures
    )
    print(json.dumps(out))
"""


def test_cold_cache_runs_numpy_now_and_compiles_everything_in_the_background(tmp_path):
    """A small job on an empty cache: the numpy path, no numba imported, one note on stderr
    and one background warm-up; afterwards every command loads compiled kernels (none is
    compiled again) and reaches the numpy run's optimum."""
    cache = tmp_path / "nc"
    # three runs at once on the empty cache: one starts the warm-up and says so, the others
    # find it started (the lock passes from the run that took it to the warm-up itself)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "TERRACONE_N"))}
    env["NUMBA_CACHE_DIR"] = str(cache)
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", textwrap.dedent(SMALL_JOB)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=ROOT,
        )
        for _ in range(3)
    ]
    outs = [p.communicate(timeout=900) for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0], outs
    colds = [json.loads(o) for o, _ in outs]
    for cold in colds:
        assert cold == {**cold, "enabled": False, "numba": False, "ready": False}
    assert sum(e.count(COLD_NOTE) for _, e in outs) == 1, outs
    cold = colds[0]
    wait_for_warmup(cache)
    assert len(list(cache.glob("terracone-kernels-*.ready"))) == 1
    one = tmp_path / "one.csv"
    lines = (ROOT / "terracone/data/example/lete_sand_synthetic_ci.csv").read_text().splitlines()
    one.write_text("\n".join(ln for ln in lines if not ln.startswith(("LS_syn_2", "LS_syn_3"))))
    warm = run_py(COMMANDS.format(one=str(one)), cache)
    assert warm.returncode == 0, warm.stderr
    got = json.loads(warm.stdout.strip().splitlines()[-1])
    assert got["enabled"] and got["misses"] == {}, got
    # the kernels the commands call were used, loaded from the cache
    assert set(got["used"]) >= {
        "sum_norm_cells", "brent_refine", "cells_kernel", "fit_stats", "polish_kernel",
        "spline_sse_compiled", "identify_extent", "cell_terms",
    }, got["used"]  # fmt: skip
    assert COLD_NOTE not in warm.stderr
    again = json.loads(run_py(SMALL_JOB, cache).stdout)
    assert again["enabled"] and again["numba"]
    # numpy (cold) and compiled (warm) reach the same optimum of the same profile
    assert again["rmsd"] == pytest.approx(cold["rmsd"], rel=1e-9)


def test_the_lock_admits_one_warmup(tmp_path):
    """While one process holds the warm-up lock, another cannot take it (and a warm-up
    started then leaves at once without compiling)."""
    cache = tmp_path / "nc"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "TERRACONE_N"))}
    env["NUMBA_CACHE_DIR"] = str(cache)
    code = (
        "from terracone import jit\nwith jit.warmup_lock() as f:\n print(f, flush=True)\n input()"
    )
    p = subprocess.Popen(
        [sys.executable, "-c", code],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )
    try:
        assert p.stdout.readline().strip() == "True"
        other = run_py(
            """
            from terracone import jit
            from terracone.apps.warmup import main
            with jit.warmup_lock() as free:
                print(free)
            print(main(), jit.ready())
            """,
            cache,
        )
        assert other.returncode == 0, other.stderr
        assert other.stdout.split() == ["False", "0", "False"]
    finally:
        p.communicate("\n", timeout=60)
    assert p.returncode == 0


def test_mode_follows_the_switch(monkeypatch):
    for value, want in (("0", "off"), ("1", "on"), ("auto", "auto"), ("", "auto")):
        monkeypatch.setenv("TERRACONE_NUMBA", value)
        assert jit.mode() == want
    monkeypatch.delenv("TERRACONE_NUMBA")
    assert jit.mode() == "auto"


def _njit_sources() -> dict[str, int]:
    """Package-relative source -> number of functions decorated with ``njit`` or
    ``jit.njit`` (with or without options), read from the sources' syntax trees."""

    def is_njit(dec: ast.expr) -> bool:
        f = dec.func if isinstance(dec, ast.Call) else dec
        return (isinstance(f, ast.Name) and f.id == "njit") or (
            isinstance(f, ast.Attribute) and f.attr == "njit"
        )

    pkg = Path(jit.__file__).resolve().parent
    out = {}
    for path in sorted(pkg.rglob("*.py")):
        if path.name == "jit.py" and path.parent == pkg:
            continue  # defines njit itself
        tree = ast.parse(path.read_text(), str(path))
        n = sum(
            any(is_njit(d) for d in node.decorator_list)
            for node in ast.walk(tree)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        )
        if n:
            out[path.relative_to(pkg).as_posix()] = n
    return out


def test_every_kernel_module_keys_the_marker(tmp_path):
    """The marker's key covers every source that defines a kernel (numba keys its cache on
    them too), so editing a kernel makes the cache cold again.  Every module of the package
    is imported (pkgutil.walk_packages, in a fresh interpreter, so no earlier import decides
    what is seen); the kernels registered then, and the ``njit`` decorators in the sources,
    must come from exactly jit.KERNEL_SOURCES."""
    r = run_py(
        """
        import importlib, json, pkgutil
        import terracone
        from terracone import jit
        names = [m.name for m in pkgutil.walk_packages(terracone.__path__, "terracone.")]
        for name in names:
            importlib.import_module(name)
        files = sorted({k.py_func.__code__.co_filename for k in jit._lazy})
        print(json.dumps({"modules": names, "files": files, "kernels": len(jit._lazy)}))
        """,
        tmp_path / "nc",
    )
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    pkg = Path(jit.__file__).resolve().parent
    on_disk = {
        ".".join(("terracone", *p.relative_to(pkg).with_suffix("").parts)).removesuffix(".__init__")
        for p in pkg.rglob("*.py")
    } - {"terracone"}
    assert set(got["modules"]) == on_disk  # every module was imported
    keyed = {(pkg / rel).resolve() for rel in jit.KERNEL_SOURCES}
    assert {Path(f).resolve() for f in got["files"]} == keyed
    decorated = _njit_sources()
    assert {(pkg / rel).resolve() for rel in decorated} == keyed
    assert got["kernels"] == sum(decorated.values())

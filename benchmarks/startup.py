"""Start-up cost of terracone commands, cold and warm, for the benchmark scripts.

Each measurement is a fresh Python process (``sys.executable``):

* ``cold``: an empty numba cache directory (NUMBA_CACHE_DIR in a temporary
  directory), so every kernel the snippet reaches is compiled;
* ``warm``: the same directory again, so kernels load from the cache;
* ``numba off``: TERRACONE_NUMBA=0, the numpy paths (nothing compiled).

Printed per case: the wall time of the whole process and the time the
snippet reports for its first call (imports excluded), so that the compile
(cold) or cache-load (warm) cost is visible apart from the work itself.

Used by benchmarks/forward.py, inverse.py and batch.py (loaded by path:
``benchmarks/`` is kept off sys.path, so that no script here can shadow an
installed package).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import textwrap
import time

PRE = """
import time as _t
_t0 = _t.perf_counter()
"""
POST = """
print("FIRST_CALL_S", _t.perf_counter() - _t1)
"""


def _run(code: str, env: dict[str, str]) -> tuple[float, float]:
    t = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=1800
    )
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"start-up snippet failed:\n{p.stderr[-2000:]}")
    first = float("nan")
    for line in p.stdout.splitlines():
        if line.startswith("FIRST_CALL_S"):
            first = float(line.split()[1])
    return wall, first


def measure(setup: str, call: str) -> dict[str, tuple[float, float]]:
    """(process wall [s], first call [s]) for cold, warm and numba-off runs.

    ``setup`` imports and prepares (not timed as the first call); ``call``
    is the first call that reaches the kernels.
    """
    code = (
        textwrap.dedent(setup)
        + "\nimport time as _t\n_t1 = _t.perf_counter()\n"
        + textwrap.dedent(call)
        + POST
    )
    env = {k: v for k, v in os.environ.items() if k not in ("TERRACONE_NUMBA", "NUMBA_CACHE_DIR")}
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env_c = dict(env, NUMBA_CACHE_DIR=cache)
        out["cold"] = _run(code, env_c)
        out["warm"] = _run(code, env_c)
    out["numba off"] = _run(code, dict(env, TERRACONE_NUMBA="0"))
    return out


def report(title: str, res: dict[str, tuple[float, float]]) -> None:
    print(f"  {title}")
    for k, (wall, first) in res.items():
        print(f"    {k:<10} process {wall * 1e3:9.0f} ms   first call {first * 1e3:9.1f} ms")


def cli_help() -> dict[str, tuple[float, float]]:
    """``terracone --help`` (imports the CLI; must not import numba)."""
    return measure(
        "import sys\nfrom click.testing import CliRunner\nfrom terracone.cli import cli",
        "CliRunner().invoke(cli, ['--help'])\n"
        "print('numba imported:', 'numba' in sys.modules, file=sys.stderr)",
    )

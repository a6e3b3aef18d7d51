"""Start-up cost of terracone, cold and warm: ``python benchmarks/startup.py``.

Run as a script, it times whole commands as a user meets them, each a fresh
process, wall clock including Python's start-up:

* ``terracone predict`` of one profile and ``terracone demo``;
* ``cold``: an empty kernel cache (NUMBA_CACHE_DIR in a temporary directory)
  and the default policy: the numpy paths now, the kernels compiled by a
  detached background warm-up (``python -m terracone.apps.warmup``), whose
  own run time is printed apart (it is waited for, not part of the command);
* ``warm``: the same cache after that warm-up, the compiled kernels loaded;
* ``compile here``: an empty cache with TERRACONE_NUMBA=1, the kernels
  compiled inside the command (what every first run did before the warm-up
  existed);
* ``numba off``: TERRACONE_NUMBA=0.

Each figure is the best of ``--repeat`` runs (the machine is shared: the
minimum is the least disturbed).  The functions :func:`measure`,
:func:`report` and :func:`cli_help` serve benchmarks/forward.py, inverse.py
and batch.py (loaded by path: ``benchmarks/`` is kept off sys.path, so that no
script here can shadow an installed package); there ``cold`` compiles inside
the process (TERRACONE_NUMBA=1), to show what compiling costs.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

POST = """
print("FIRST_CALL_S", _t.perf_counter() - _t1)
"""


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("TERRACONE_NUMBA", "NUMBA_CACHE_DIR")}
    env.update(extra)
    return env


def _run(cmd: list[str], env: dict[str, str]) -> tuple[float, str, str]:
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=1800)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"{cmd[:3]} failed:\n{p.stderr[-2000:]}")
    return wall, p.stdout, p.stderr


def _first_call(stdout: str) -> float:
    for line in stdout.splitlines():
        if line.startswith("FIRST_CALL_S"):
            return float(line.split()[1])
    return float("nan")


def measure(setup: str, call: str) -> dict[str, tuple[float, float]]:
    """(process wall [s], first call [s]) for cold (compiled in the process), warm and
    numba-off runs.

    ``setup`` imports and prepares (not timed as the first call); ``call``
    is the first call that reaches the kernels.
    """
    code = (
        textwrap.dedent(setup)
        + "\nimport time as _t\n_t1 = _t.perf_counter()\n"
        + textwrap.dedent(call)
        + POST
    )
    cmd = [sys.executable, "-c", code]
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        for case in ("cold", "warm"):
            wall, stdout, _ = _run(cmd, _env(NUMBA_CACHE_DIR=cache, TERRACONE_NUMBA="1"))
            out[case] = (wall, _first_call(stdout))
    wall, stdout, _ = _run(cmd, _env(TERRACONE_NUMBA="0"))
    out["numba off"] = (wall, _first_call(stdout))
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


def wait_for_warmup(cache: Path, timeout: float = 1800.0) -> float:
    """Wait for the background warm-up of ``cache`` (:func:`terracone.jit.wait_for_warmup`);
    how long it took [s].  Ended by its process id if it takes longer than ``timeout``."""
    from terracone import jit

    t0 = time.perf_counter()
    if not jit.wait_for_warmup(timeout, cache):
        with contextlib.suppress(ProcessLookupError, TypeError):
            os.kill(jit.warmup_pid(cache), signal.SIGTERM)
        raise RuntimeError(f"the warm-up of {cache} took more than {timeout:g} s")
    return time.perf_counter() - t0


def _terracone(*args: str) -> list[str]:
    return [sys.executable, "-c", "from terracone.cli import main; main()", *args]


def commands(repeat: int) -> dict[str, dict[str, float]]:
    """Best wall times [s] of predict (one profile) and demo in each case, and of the
    background warm-ups the cold runs started."""
    from terracone.apps.example import example_dir

    tmp = Path(tempfile.mkdtemp(prefix="terracone-startup-"))
    lines = (example_dir() / "lete_sand_synthetic_ci.csv").read_text().splitlines()
    one = tmp / "one.csv"
    one.write_text("\n".join(ln for ln in lines if not ln.startswith(("LS_syn_2", "LS_syn_3"))))
    cmds = {"predict one profile": _terracone("predict", str(one)), "demo": _terracone("demo")}
    best: dict[str, dict[str, float]] = {name: {} for name in cmds}
    warmups: list[float] = []
    for r in range(repeat):
        for name, cmd in cmds.items():
            cache = tmp / f"cache-{name.split()[0]}-{r}"
            times = {}
            times["cold"] = _run(cmd, _env(NUMBA_CACHE_DIR=str(cache)))[0]
            warmups.append(wait_for_warmup(cache))
            times["warm"] = _run(cmd, _env(NUMBA_CACHE_DIR=str(cache)))[0]
            here = tmp / f"here-{name.split()[0]}-{r}"
            times["compile here"] = _run(cmd, _env(NUMBA_CACHE_DIR=str(here), TERRACONE_NUMBA="1"))[
                0
            ]
            times["numba off"] = _run(cmd, _env(TERRACONE_NUMBA="0"))[0]
            for k, v in times.items():
                best[name][k] = min(best[name].get(k, float("inf")), v)
    best["background warm-up"] = {"shortest": min(warmups), "longest": max(warmups)}
    shutil.rmtree(tmp, ignore_errors=True)  # every warm-up it started has ended
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="runs of each case (best kept)")
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"start-up, wall clock with Python's start, best of {args.repeat} (load {load:.1f})")
    res = commands(args.repeat)
    cases = ("cold", "warm", "compile here", "numba off")
    print(f"  {'':<22}" + "".join(f"{c:>14}" for c in cases))
    for name in ("predict one profile", "demo"):
        print(f"  {name:<22}" + "".join(f"{res[name][c]:>12.1f} s" for c in cases))
    w = res["background warm-up"]
    print(
        f"  background warm-up after a cold run (nice 10, not waited for by the command): "
        f"{w['shortest']:.0f} to {w['longest']:.0f} s"
    )
    print(
        f"  load average at the end: {os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else ""
    )


if __name__ == "__main__":
    main()

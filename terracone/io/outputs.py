"""Where outputs go: never over an input, and an output directory holds exactly one run.

:func:`check_outputs` refuses an output path that is one of the inputs (or, for
an output directory, holds one), and two outputs on one path.
:func:`run_directory` writes a run into a new directory beside the target and
then puts it in the target's place whole: a directory that held an earlier run
of the same kind is replaced (no stale file of the earlier run stays), any
other non-empty directory is refused unless ``force``, and a failed run leaves
the target as it was.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import uuid
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

__all__ = ["check_outputs", "check_run_directory", "run_directory", "same_path"]

PathLike = str | os.PathLike[str]


def same_path(a: PathLike, b: PathLike) -> bool:
    """Whether two paths name one file or directory (links, ``..`` and hard links followed)."""
    pa, pb = Path(a).expanduser(), Path(b).expanduser()
    if pa.exists() and pb.exists():
        with contextlib.suppress(OSError):
            return os.path.samefile(pa, pb)
    return pa.resolve() == pb.resolve()


def _inside(child: PathLike, parent: PathLike) -> bool:
    """Whether ``child`` is ``parent`` or lies below it (after resolving both)."""
    c, p = Path(child).expanduser().resolve(), Path(parent).expanduser().resolve()
    return c == p or p in c.parents


def check_outputs(
    outputs: Mapping[str, PathLike | None],
    inputs: Mapping[str, PathLike | None],
    *,
    directories: tuple[str, ...] = (),
) -> None:
    """Refuse outputs that would write over an input, or over each other.

    Parameters
    ----------
    outputs, inputs : mapping of label to path
        What the command writes and reads, by the option or argument that names
        it (e.g. ``{"--out": "a.json"}``, ``{"CI_FILE": "ci.csv"}``); None
        values are ignored.
    directories : tuple of str
        Labels of ``outputs`` that are directories replaced whole
        (:func:`run_directory`): one that holds an input is refused too.

    Raises
    ------
    ValueError
        ``--out FILE is the input FILE; ...``, naming both.
    """
    outs = [(k, v) for k, v in outputs.items() if v is not None]
    ins = [(k, v) for k, v in inputs.items() if v is not None]
    for i, (ka, a) in enumerate(outs):
        for kb, b in outs[i + 1 :]:
            if same_path(a, b):
                raise ValueError(
                    f"{ka} {a} and {kb} {b} are the same file: one would overwrite the "
                    "other; give them different paths"
                )
    for ko, o in outs:
        for ki, f in ins:
            if same_path(o, f):
                raise ValueError(
                    f"{ko} {o} is the input {ki} {f}; writing it would destroy the input: "
                    "choose another path"
                )
            if ko in directories and _inside(f, o):
                raise ValueError(
                    f"{ko} {o} holds the input {ki} {f}; the output directory is replaced "
                    "whole, which would delete the input: choose another directory"
                )


def _precious(target: Path) -> str | None:
    """Why ``target`` must never be replaced whole, or None."""
    cwd = Path.cwd().resolve()
    if target == Path(target.anchor):
        return "it is the root of the file system"
    if target == Path.home().resolve():
        return "it is your home directory"
    if target == cwd or target in cwd.parents:
        return "it holds the current directory"
    return None


def _listing(entries: list[Path]) -> str:
    names = sorted(e.name + ("/" if e.is_dir() else "") for e in entries)
    return ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")


def _swap(stage: Path, target: Path) -> None:
    """Put ``stage`` in the place of ``target`` (which may exist), then delete the old one."""
    if not target.exists():
        os.rename(stage, target)
        return
    old = target.parent / f".{target.name}.old-{uuid.uuid4().hex[:8]}"
    os.rename(target, old)
    try:
        os.rename(stage, target)
    except BaseException:
        os.rename(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


def check_run_directory(
    path: PathLike, *, what: str, is_run: Callable[[Path], bool], force: bool = False
) -> Path:
    """The resolved output directory, after the checks of :func:`run_directory` (nothing is
    written): call it before a long computation whose result goes there."""
    target = Path(path).expanduser()
    if not (target.exists() or target.is_symlink()):
        return target.resolve()
    if not target.is_dir():
        raise ValueError(f"output {target} exists and is not a directory")
    target = target.resolve()
    why = _precious(target)
    if why is not None:
        raise ValueError(f"will not replace {target} whole: {why}; choose a new directory")
    entries = list(target.iterdir())
    if entries and not force and not is_run(target):
        raise ValueError(
            f"output directory {target} is not empty and does not hold an earlier "
            f"{what} run ({_listing(entries)}): choose a new or empty directory, or pass "
            "--force (force=True) to replace it whole (its files are deleted)"
        )
    return target


@contextlib.contextmanager
def run_directory(
    path: PathLike,
    *,
    what: str,
    is_run: Callable[[Path], bool],
    force: bool = False,
) -> Iterator[Path]:
    """A new, empty directory to write one run into; on success it replaces ``path`` whole.

    Parameters
    ----------
    path : path
        The output directory: absent, empty, an earlier run (``is_run``), or
        anything else with ``force``.
    what : str
        The kind of run, for messages (e.g. ``"terracone map"``).
    is_run : callable
        Whether a non-empty directory holds an earlier run of this kind and
        nothing else (then it is replaced without ``force``).
    force : bool
        Replace any directory whole (its files are deleted).  Never replaced:
        the root of the file system, the home directory and a directory that
        holds the current directory.

    Yields
    ------
    Path
        A directory beside ``path`` (``.<name>.new-<random>``): write the run
        there.  When the block raises, it is deleted and ``path`` is left as
        it was.

    Raises
    ------
    ValueError
        ``path`` is a file, a non-empty directory that is not an earlier run
        (without ``force``), or one that is never replaced
        (:func:`check_run_directory`).
    """
    target = check_run_directory(path, what=what, is_run=is_run, force=force)
    target.parent.mkdir(parents=True, exist_ok=True)
    stage = target.parent / f".{target.name}.new-{uuid.uuid4().hex[:8]}"
    os.mkdir(stage)
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    _swap(stage, target)

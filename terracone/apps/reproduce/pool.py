"""The pool of a reproduce run: anything with a ``map`` method (emcee's pattern).

The learning runs, the posteriors and the figures are tasks (``partial`` objects
of module-level functions) mapped by :func:`run_task` over a pool that
:func:`open_pool` opens, or over the caller's own.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, NamedTuple

__all__ = ["PoolMap", "open_pool", "run_task"]


def run_task(task: Callable[[], Any]) -> Any:
    """Run one task, a ``partial`` (in a worker of the pool, or here)."""
    return task()


class PoolMap(NamedTuple):
    """The ``map`` that runs the tasks, and the worker processes behind it."""

    map: Callable[..., Any]
    workers: int | str  # processes, or "given pool"


@contextmanager
def open_pool(workers: int | None = None, pool: Any | None = None) -> Iterator[PoolMap]:
    """The ``map`` of ``pool``, else of ``workers`` processes opened here and closed after.

    Parameters
    ----------
    workers : int, optional
        Worker processes when no ``pool`` is given (default: 2, or 1 on a
        one-core machine; 1: the builtin ``map`` here).
    pool : object with a ``map`` method, optional
        An executor, a ``multiprocessing`` pool, or ``map`` itself; the caller
        owns it.  Overrides ``workers``.

    Yields
    ------
    PoolMap
    """
    if pool is not None:
        yield PoolMap(pool.map if hasattr(pool, "map") else pool, "given pool")
        return
    workers = workers if workers is not None else min(2, os.cpu_count() or 1)
    if workers <= 1:
        yield PoolMap(map, workers)
        return
    with ProcessPoolExecutor(max_workers=workers) as executor:
        yield PoolMap(executor.map, workers)

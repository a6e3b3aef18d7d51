"""What ``terracone map`` computes and writes, as one call: :func:`run_map`.

Results are read (:func:`terracone.result.read_results`), predicted again
when a problem is given (a library as the prior,
:func:`terracone.apps.workflow.repredict`), mapped
(:func:`~terracone.apps.maps.workflow.map_survey`) and written
(:func:`~terracone.apps.maps.writers.write_map`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from terracone.apps.maps.workflow import TerrainMap, map_survey
from terracone.apps.maps.writers import map_document, write_map
from terracone.apps.workflow import repredict
from terracone.inverse.problem import Problem
from terracone.result import PredictionResults, read_results

__all__ = ["MapRun", "run_map"]


@dataclass
class MapRun:
    """What :func:`run_map` computed and wrote: the ``map`` and ``document`` (``map.json``)."""

    map: TerrainMap
    document: dict[str, Any]

    @property
    def notes(self) -> list[str]:
        """What the user should know of the map."""
        return list(self.map.notes)


def run_map(
    results: PredictionResults | str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    plate: tuple[float, float] | None = None,
    layers: Sequence[tuple[float, float]] | None = None,
    resolution: float | None = None,
    crs: str | None = None,
    units: str = "si",
    problem: Problem | None = None,
    force: bool = False,
    progress: Callable[[int], Any] | None = None,
) -> MapRun:
    """Map located pushes and write the map directory ``out``.

    Parameters
    ----------
    results : PredictionResults or path
        A predict JSON or Parquet file, a batch directory, or results read.
    out : path
        The map directory (:func:`~terracone.apps.maps.writers.write_map`:
        an earlier map is replaced whole; anything else only with ``force``).
    plate, layers, resolution, crs, units
        As :func:`~terracone.apps.maps.workflow.map_survey` takes them;
        ``units`` also of the files written.
    problem : Problem, optional
        Predict the pushes again under it first (a library as the prior),
        from the CI the results keep.
    force : bool
    progress : callable, optional
        ``progress(k)`` after every ``k`` cells kriged (default: a tqdm bar
        on a terminal).

    Returns
    -------
    MapRun
    """
    from tqdm import tqdm

    data = results if isinstance(results, PredictionResults) else read_results(results)
    if problem is not None:
        data = repredict(data, problem)
    with tqdm(desc="kriging cells", unit="cell", leave=False,
              disable=None if progress is None else True) as bar:  # fmt: skip
        result = map_survey(
            data, plate=plate, layers=layers, resolution=resolution, crs=crs, units=units,
            progress=bar.update if progress is None else progress,
        )  # fmt: skip
    write_map(result, out, units, force=force)
    return MapRun(result, map_document(result, units))

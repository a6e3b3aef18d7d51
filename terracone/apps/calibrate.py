"""What ``terracone learn`` computes, as one library call: learn, then keep the calibration.

:func:`learn_calibration` runs the learning process (section 3.3.1 of [1]_,
:func:`terracone.inverse.learning.learn.learn`) on the CI profiles and plate
tests of one terrain, turns the result into the
:class:`~terracone.inverse.problem.Calibration` the prediction process holds,
and saves it as a file and in the terrain library when asked.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3.1.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from terracone import __version__
from terracone.data import CIProfile, PlateTest
from terracone.inverse.bounds import Bounds
from terracone.inverse.learning.learn import LearnResult, learn
from terracone.inverse.problem import Calibration

__all__ = ["LearnRun", "learn_calibration"]


@dataclass
class LearnRun:
    """Result of :func:`learn_calibration` (SI inside).

    ``result``: the learning result; ``calibration``: what prediction holds;
    ``saved``: the calibration file written, or None; ``saved_as``: the
    library name it was stored under, or None.
    """

    result: LearnResult
    calibration: Calibration
    saved: str | None = None
    saved_as: str | None = None

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``terracone learn --json`` document."""
        d = self.result.as_dict(units)
        d.update(
            terrain=self.calibration.terrain,
            terracone=__version__,
            command="learn",
            saved=self.saved,
            saved_as=self.saved_as,
        )
        return d


def learn_calibration(
    profiles: Sequence[CIProfile],
    plates: Sequence[PlateTest],
    *,
    terrain: str,
    model: str = "rm1",
    bounds: Bounds | None = None,
    r_min_bounds: tuple[float, float] | None = None,
    save: str | os.PathLike[str] | None = None,
    save_as: str | None = None,
    library: str | None = None,
    sources: dict[str, str] | None = None,
) -> LearnRun:
    """Learn a calibration from one terrain's CI profiles and plate tests, and keep it.

    Parameters
    ----------
    profiles : sequence of CIProfile
        The terrain's CI profiles (one cone: the first profile's is recorded).
    plates : sequence of PlateTest
        Its plate tests (loading branches).
    terrain : str
        The calibration's label.
    model, bounds, r_min_bounds
        As :func:`terracone.inverse.learning.learn.learn` takes them.
    save : path, optional
        Write the calibration file here.
    save_as : str, optional
        Store the calibration in the terrain library under this name
        (kind "calibration").
    library : str, optional
        The library's path (default: ``$TERRACONE_LIBRARY`` or the user data dir).
    sources : dict, optional
        Provenance of the data (e.g. ``ci_file``, ``plates_file``).

    Returns
    -------
    LearnRun
    """
    if r_min_bounds is not None and model != "rm1":
        raise ValueError("an r_min range is searched only with model rm1")
    res = learn(list(profiles), list(plates), model=model, bounds=bounds, r_min_bounds=r_min_bounds)
    cal = res.calibration(terrain, cone=profiles[0].cone.name, **(sources or {}))
    if save:
        cal.save(save)
    if save_as:
        from terracone.apps.library import Library

        with Library(library) as lib:
            lib.add(save_as, "calibration", cal.library_params(), cal.provenance, replace=True)
    return LearnRun(res, cal, None if save is None else str(save), save_as)

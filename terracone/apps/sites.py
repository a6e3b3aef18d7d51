"""What ``terracone sites`` and ``terracone design`` compute, each as one library call.

:func:`pool_sites` groups CI profiles into sites and pools each site
(:func:`terracone.inverse.sites.statistics.site_statistics`); :func:`plan_tests`
ranks one extra test per profile (:func:`terracone.inverse.sites.design.plan_test`).
Both fit as one :class:`~terracone.inverse.problem.Problem` states, so a
calibration's values are held in every push and every plan, and both return
an object whose ``as_dict(units)`` is the command's JSON document.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from terracone import __version__
from terracone.data import CIProfile, InputError
from terracone.inverse.problem import Problem
from terracone.inverse.sites.design import DesignResult, plan_test
from terracone.inverse.sites.statistics import SiteStatistics, default_sinkages, site_statistics
from terracone.resultunits import from_si

__all__ = ["DesignRun", "SitesRun", "plan_tests", "pool_sites"]

#: Plate radii of the site P-S curves by default [m] (the LETE pair of the paper).
DEFAULT_SITE_PLATES = (0.0375, 0.05)


@dataclass
class SitesRun:
    """Result of :func:`pool_sites` (SI inside): the statistics and what was asked."""

    statistics: SiteStatistics
    problem: Problem
    asked: dict[str, Any] = field(default_factory=dict)

    @property
    def fitted_any(self) -> bool:
        """Whether any site has a fitted push."""
        return self.statistics.fitted_any

    def as_dict(self, units: str = "si", *, input: str | None = None) -> dict[str, Any]:
        """The ``terracone sites --json`` document."""
        a, pb = self.asked, self.problem
        radius = a.get("radius")
        settings = {
            "by": a.get("by"),
            "radius": from_si(radius, "length", units),
            "model": pb.model,
            "calibration": pb.record()["calibration"],
            **({} if pb.library is None else {"library": pb.library.source}),
            "bounds": pb.bounds.as_dict(units),
            "depth_range": a.get("depth_range"),
            "target_cv": a.get("target_cv"),
            "bootstrap": a.get("bootstrap"),
            "seed": a.get("seed"),
            "units": units,
        }
        doc = {"terracone": __version__, "command": "sites", "input": input, "settings": settings}
        doc.update(self.statistics.as_dict(units))
        return doc


def pool_sites(
    items: Sequence[CIProfile | InputError],
    problem: Problem | None = None,
    *,
    by: str | None = None,
    radius: float | None = None,
    plates: Sequence[float] = DEFAULT_SITE_PLATES,
    sinkage: np.ndarray | None = None,
    target_cv: float = 0.1,
    bootstrap: int | None = None,
    seed: int = 0,
    depth_range: Any = None,
    source: str = "input",
) -> SitesRun:
    """Group profiles into sites and pool each site under one problem.

    Parameters
    ----------
    items : sequence of CIProfile or InputError
        As a reader returns them (errors are reported, not fitted).
    problem : Problem, optional
        What each push is fitted with (a calibration's values held).
    by, radius
        Site grouping: metadata column(s), or a distance [m].
    plates : sequence of float
        Plate radii of the site P-S curves [m].
    sinkage : ndarray, optional
        Sinkages [m] (default :func:`default_sinkages`).
    target_cv : float
        Target CV of the site-mean plate pressure [-].
    bootstrap : int, optional
        Bootstrap replicates (default 40 without a calibration, 0 with one).
    seed : int
    depth_range : optional
        The depth window as the command gave it (recorded only).
    source : str
        Name of the input, for messages.

    Returns
    -------
    SitesRun
    """
    problem = problem or Problem()
    if not target_cv > 0:
        raise ValueError(f"target CV must be > 0 (got {target_cv})")
    stats = site_statistics(
        items,
        problem,
        by=by,
        radius=radius,
        source=source,
        plates=list(plates),
        sinkage=default_sinkages() if sinkage is None else sinkage,
        target_cv=target_cv,
        bootstrap=bootstrap,
        seed=seed,
    )
    held = problem.calibrated or problem.library is not None  # a library pools held problems
    boot = bootstrap if bootstrap is not None else (0 if held else 40)
    asked = dict(by=by, radius=radius, target_cv=target_cv, bootstrap=boot, seed=seed)
    return SitesRun(stats, problem, dict(asked, depth_range=depth_range))


@dataclass
class DesignRun:
    """Result of :func:`plan_tests`: one plan per input item (errors as such)."""

    designs: list[DesignResult | InputError]
    asked: dict[str, Any] = field(default_factory=dict)

    @property
    def planned_any(self) -> bool:
        """Whether any profile could be planned."""
        return any(isinstance(d, DesignResult) and d.ok for d in self.designs)

    def as_dict(self, units: str = "si", *, input: str | None = None) -> dict[str, Any]:
        """The ``terracone design --json`` document."""
        designs = [
            {"id": str(d.profile), "status": "error", "error": str(d)}
            if isinstance(d, InputError)
            else d.as_dict(units)
            for d in self.designs
        ]
        settings = {**self.asked, "units": units}
        return {
            "terracone": __version__,
            "command": "design",
            "input": input,
            "settings": settings,
            "designs": designs,
        }


def plan_tests(
    items: Sequence[CIProfile | InputError],
    problem: Problem | None = None,
    *,
    candidates: Sequence[tuple[str, str, float | None]],
    plates: Sequence[float],
    plate_noise: float = 0.05,
    asked: dict[str, Any] | None = None,
) -> DesignRun:
    """Rank the candidate extra tests of each profile (value of information).

    Parameters
    ----------
    items : sequence of CIProfile or InputError
        A reader's error is kept as the profile's error.
    problem : Problem, optional
        What is fitted and the prior (:func:`~terracone.inverse.sites.design.plan_test`).
    candidates : list of (label, kind, radius)
        :func:`~terracone.inverse.sites.design.parse_candidates`.
    plates : sequence of float
        Target plate radii [m].
    plate_noise : float
        Relative error of one plate reading [-].
    asked : dict, optional
        The command's settings as given, recorded in the document.

    Returns
    -------
    DesignRun
    """
    if not plate_noise > 0:
        raise ValueError(f"plate noise must be > 0 (got {plate_noise})")
    problem = problem or Problem()
    designs: list[DesignResult | InputError] = [
        it
        if isinstance(it, InputError)
        else plan_test(it, problem, candidates=candidates, plates=plates, plate_noise=plate_noise)
        for it in items
    ]
    return DesignRun(designs, dict(asked or {}))

"""What ``terracone match`` computes: which stored calibrations a file or a site is like.

:func:`match_profiles` ranks a library's calibrations for each profile of a
file, or for each site (``by``, ``radius``): every candidate's weight (prior
weight x evidence, :mod:`terracone.inverse.library`) and its posterior
predictive check, every candidate checked; a group that no candidate passes
is outside the library.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from terracone import __version__
from terracone.data import CIProfile, InputError
from terracone.inverse.library.check import CHECK_METHOD
from terracone.inverse.library.evidence import EVIDENCE_METHOD
from terracone.inverse.library.mixture import Ranking
from terracone.inverse.library.sites import rank_groups
from terracone.inverse.problem import Problem
from terracone.inverse.sites.statistics import group_profiles
from terracone.physics import units as u
from terracone.resultunits import from_si

__all__ = ["MatchRun", "match_profiles"]


@dataclass
class MatchRun:
    """Result of :func:`match_profiles`: per group its ranking (or why it has none).

    Attributes
    ----------
    groups : list of (str, Ranking or str, list of str)
        Group id, its ranking or the reason it has none, its profile ids.
    problem : Problem
        With the library.
    errors : list of InputError
        Profiles the reader could not use.
    unassigned : list of (str, str)
        Profiles in no site, with the reason.
    asked : dict
    """

    groups: list[tuple[str, Ranking | str, list[str]]]
    problem: Problem
    errors: list[InputError] = field(default_factory=list)
    unassigned: list[tuple[str, str]] = field(default_factory=list)
    asked: dict[str, Any] = field(default_factory=dict)

    @property
    def matched_any(self) -> bool:
        """Whether any group was ranked."""
        return any(isinstance(r, Ranking) for _, r, _ in self.groups)

    def as_dict(self, units: str = "si", *, input: str | None = None) -> dict[str, Any]:
        """The ``terracone match --json`` document: ``{"groups": [{"id", "candidates",
        "outside_library", ...}]}``, candidates by weight, largest first."""
        units = u.check_system(units)
        lib = self.problem.library
        groups = []
        for gid, rk, ids in self.groups:
            if isinstance(rk, str):
                groups.append({"id": gid, "profiles": ids, "candidates": [],
                               "outside_library": True, "carried_by": None, "error": rk})  # fmt: skip
                continue
            d = rk.summary(lib.source).as_dict(units)
            groups.append(
                {
                    "id": gid,
                    "profiles": ids,
                    "candidates": d["library"]["candidates"],
                    "outside_library": d["outside_library"],
                    "carried_by": d["library"]["carried_by"],
                    "error": None,
                }
            )
        radius = self.asked.get("radius")
        settings = {**self.asked, "library": lib.source, "check_level": lib.check_level,
                    "replicates": lib.replicates, "units": units}  # fmt: skip
        if radius is not None:
            settings["radius"] = from_si(radius, "length", units)
        return {
            "terracone": __version__,
            "command": "match",
            "input": input,
            "settings": settings,
            "evidence": EVIDENCE_METHOD,
            "check": CHECK_METHOD,
            "groups": groups,
            "unassigned": [{"id": i, "reason": why} for i, why in self.unassigned],
            "errors": [str(e) for e in self.errors],
        }


def match_profiles(
    items: Sequence[CIProfile | InputError],
    problem: Problem,
    *,
    by: str | None = None,
    radius: float | None = None,
    seed: int = 0,
    source: str = "input",
) -> MatchRun:
    """Rank a library's calibrations for each profile, or each site, of a file.

    Parameters
    ----------
    items : sequence of CIProfile or InputError
        As a reader returns them (errors are reported, not matched).
    problem : Problem
        With a ``library`` (:class:`~terracone.inverse.problem.LibraryPrior`).
    by, radius : optional
        Group the profiles into sites (a metadata column, a distance [m]);
        without them each profile is a group.
    seed : int
        Seed of the check.
    source : str
        Name of the input, for messages.

    Returns
    -------
    MatchRun
    """
    if problem.library is None:
        raise ValueError("match needs a library (--library DB)")
    profiles = [it for it in items if not isinstance(it, InputError)]
    errors = [it for it in items if isinstance(it, InputError)]
    if not profiles:
        raise ValueError(f"{source}: no profile could be read")
    unassigned: list[tuple[str, str]] = []
    if by is None and radius is None:
        groups = {p.id: [i] for i, p in enumerate(profiles)}
    else:
        grouping = group_profiles(profiles, by=by, radius=radius)
        groups, unassigned = grouping.sites, grouping.unassigned
    ranked = rank_groups(profiles, groups, problem, seed=seed, check_all=True)
    out = [(g, ranked[g], [profiles[i].id for i in idx]) for g, idx in groups.items()]
    asked = {"by": by, "radius": radius, "seed": seed}
    return MatchRun(out, problem, errors, unassigned, asked)

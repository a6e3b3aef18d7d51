"""The data model that flows through terracone.

Readers (:mod:`terracone.io`) produce these objects, solvers consume them and
results carry them.  Every quantity is stored in SI (m, kPa) whatever the
unit of the file it came from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from . import units as u
from .cone import Cone, get_cone

__all__ = ["CIProfile", "PlateTest", "ShearTest", "TerrainParameters", "InputError"]


class InputError(ValueError):
    """Bad input, located: file, profile (or test), row and column.

    ``row`` is the 1-based line number in the file (the header is line 1).
    ``profile`` holds the id of the CI profile, or of the plate or shear
    test (then ``item`` is ``"test"``).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        profile: str | None = None,
        row: int | None = None,
        column: str | None = None,
        item: str = "profile",
    ) -> None:
        self.reason = message
        self.item = item
        self.file = file
        self.profile = profile
        self.row = row
        self.column = column
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.file is not None:
            where.append(f"file {self.file}")
        if self.profile is not None:
            where.append(f"{self.item} {self.profile}")
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.column is not None:
            where.append(f"column {self.column}")
        return (", ".join(where) + ": " if where else "") + self.reason


@dataclass
class CIProfile:
    """One cone penetrometer push.

    Attributes
    ----------
    id : str
        Profile id (unique within a source).
    depth : ndarray
        Depth of the cone base below the surface [m], strictly increasing
        (origin where the base is flush; negative while the tip enters).
    ci : ndarray
        Cone index [kPa].
    cone : Cone
    metadata : dict
        Anything else the source carried (site, lat, lon, date, ...).
    source : str or None
        File it was read from.
    notes : list of str
        What the reader did to the data (e.g. trailing zeros dropped).
    rows : ndarray or None
        File line number of each point, for error messages.
    """

    id: str
    depth: np.ndarray
    ci: np.ndarray
    cone: Cone = field(default_factory=lambda: get_cone("asabe-large"))
    metadata: dict[str, Any] = field(default_factory=dict)
    source: str | None = None
    notes: list[str] = field(default_factory=list)
    rows: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.depth = np.asarray(self.depth, dtype=float)
        self.ci = np.asarray(self.ci, dtype=float)
        self.cone = get_cone(self.cone)

    def __len__(self) -> int:
        return int(self.depth.size)

    def validate(self, min_points: int = 3) -> CIProfile:
        """Raise :class:`InputError` if the profile cannot be fitted."""

        def err(msg: str, i: int | None = None, col: str | None = None) -> InputError:
            row = None if (i is None or self.rows is None) else int(self.rows[i])
            return InputError(msg, file=self.source, profile=self.id, row=row, column=col)

        if self.depth.shape != self.ci.shape or self.depth.ndim != 1:
            raise err("depth and ci must be 1-D arrays of one length")
        for name, arr in (("depth", self.depth), ("ci", self.ci)):
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise err(f"{name} is not a finite number", int(bad[0]), name)
        neg = np.flatnonzero(self.ci < 0)
        if neg.size:
            raise err(f"negative cone index {self.ci[neg[0]]:g}", int(neg[0]), "ci")
        dd = np.flatnonzero(np.diff(self.depth) <= 0)
        if dd.size:
            raise err("depth is not strictly increasing", int(dd[0]) + 1, "depth")
        if self.depth.size and self.depth[0] < -self.cone.height * (1 + 1e-9):
            raise err(
                f"depth {self.depth[0]:g} m is above -H = {-self.cone.height:.4g} m "
                "(the tip would be above the surface)",
                0,
                "depth",
            )
        if self.depth.size < min_points:
            raise err(f"{self.depth.size} points; at least {min_points} are needed")
        return self

    def window(self, lo: float | None = None, hi: float | None = None) -> CIProfile:
        """The part of the profile with lo <= depth <= hi [m]."""
        keep = np.ones(self.depth.shape, bool)
        if lo is not None:
            keep &= self.depth >= lo
        if hi is not None:
            keep &= self.depth <= hi
        rows = None if self.rows is None else self.rows[keep]
        return replace(self, depth=self.depth[keep], ci=self.ci[keep], rows=rows)


class _FileRows:
    """Where a test came from in its file (``rows``: 1-based file line numbers)."""

    rows: np.ndarray | None

    def first_row(self) -> int | None:
        """File line of the test's first point, or None when not read from a file."""
        return None if self.rows is None or len(self.rows) == 0 else int(self.rows[0])

    def lines_note(self) -> str:
        """' (the test is on lines A-B)' for error messages, or ''."""
        if self.rows is None or len(self.rows) == 0:
            return ""
        return f" (the test is on lines {int(self.rows[0])}-{int(self.rows[-1])})"


@dataclass
class PlateTest(_FileRows):
    """One plate pressure-sinkage test (loading branch and all).

    Attributes
    ----------
    id : str
    b : float
        Bekker size of the plate [m]: radius of a circular plate or the
        smaller side of a rectangular one.
    shape : {"circular", "rectangular"}
    sinkage : ndarray
        [m]
    pressure : ndarray
        [kPa]
    """

    id: str
    b: float
    shape: str
    sinkage: np.ndarray
    pressure: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)
    source: str | None = None
    rows: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.sinkage = np.asarray(self.sinkage, dtype=float)
        self.pressure = np.asarray(self.pressure, dtype=float)
        if self.shape not in ("circular", "rectangular"):
            raise ValueError(f"plate shape must be circular or rectangular (got {self.shape!r})")
        if not (self.b > 0 and math.isfinite(self.b)):
            raise InputError("plate size must be > 0", file=self.source, profile=self.id)

    @property
    def radius(self) -> float | None:
        """Plate radius [m] (circular plates), else None."""
        return self.b if self.shape == "circular" else None

    def loading_branch(self) -> PlateTest:
        """Points up to the maximum sinkage with sinkage > 0 and pressure > 0."""
        if self.sinkage.size == 0:
            return self
        imax = int(np.argmax(self.sinkage))
        s, p = self.sinkage[: imax + 1], self.pressure[: imax + 1]
        keep = (s > 0) & (p > 0)
        rows = None if self.rows is None else self.rows[: imax + 1][keep]
        return replace(self, sinkage=s[keep], pressure=p[keep], rows=rows)


@dataclass
class ShearTest(_FileRows):
    """One shear stress-displacement test at a normal pressure.

    Attributes
    ----------
    id : str
    normal_pressure : float
        [kPa]
    displacement : ndarray
        Shear displacement j [m].
    stress : ndarray
        Shear stress tau [kPa].
    """

    id: str
    normal_pressure: float
    displacement: np.ndarray
    stress: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)
    source: str | None = None
    rows: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.displacement = np.asarray(self.displacement, dtype=float)
        self.stress = np.asarray(self.stress, dtype=float)


@dataclass
class TerrainParameters:
    """Bekker-Wong pressure-sinkage and cone-terrain shear parameters, SI.

    Attributes
    ----------
    kc : float
        [kN/m^(n+1)]
    kphi : float
        [kN/m^(n+2)]
    n : float
        [-]
    cc : float
        Cone (metal)-terrain adhesion [kPa].
    phic_deg : float
        Cone (metal)-terrain friction angle [deg].
    Kc : float or None
        Cone-terrain shear deformation parameter [m]; None: fully mobilised.
    model : {"rm0", "rm1"}
    r_min : float or None
        RM1 transition radius [m].
    """

    kc: float
    kphi: float
    n: float
    cc: float = 0.0
    phic_deg: float = 0.0
    Kc: float | None = None
    model: str = "rm0"
    r_min: float | None = None

    def _repr_html_(self) -> str:
        """A table with SI and US columns, for Jupyter."""
        from .report.notebook import parameters_html

        return parameters_html(self)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """Parameters in a unit system, with the JSON keys of the CLI."""
        units = u.check_system(units)
        return {
            "kc": float(u.kc_from_si(self.kc, self.n, units)),
            "kphi": float(u.kphi_from_si(self.kphi, self.n, units)),
            "n": float(self.n),
            "cc": float(u.pressure_from_si(self.cc, units)),
            "phic_deg": float(self.phic_deg),
            "Kc": None if self.Kc is None else float(u.length_from_si(self.Kc, units)),
            "model": self.model,
            "r_min": None if self.r_min is None else float(u.length_from_si(self.r_min, units)),
            "units": units,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], units: str | None = None) -> TerrainParameters:
        """Inverse of :meth:`as_dict` (``units`` defaults to ``d["units"]`` or si)."""
        units = u.check_system(units or d.get("units", "si"))
        n = float(d["n"])
        r_min = d.get("r_min")
        Kc = d.get("Kc")
        return cls(
            kc=float(u.kc_to_si(d.get("kc", 0.0) or 0.0, n, units)),
            kphi=float(u.kphi_to_si(d.get("kphi", 0.0) or 0.0, n, units)),
            n=n,
            cc=float(u.pressure_to_si(d.get("cc", 0.0) or 0.0, units)),
            phic_deg=float(d.get("phic_deg", 0.0) or 0.0),
            Kc=None if Kc is None else float(u.length_to_si(Kc, units)),
            model=d.get("model", "rm0") or "rm0",
            r_min=None if r_min is None else float(u.length_to_si(r_min, units)),
        )

"""The data model that flows through terracone.

Readers (:mod:`terracone.io`) produce these objects, solvers consume them and
results carry them.  Every quantity is stored in SI (m, kPa) whatever the
unit of the file it came from.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from terracone.physics import units as u
from terracone.physics.cone import Cone, get_cone
from terracone.resultunits import Written, quantity

__all__ = [
    "CI_MAX_KPA",
    "DEPTH_MAX_M",
    "CIProfile",
    "ProfileSet",
    "depth_window",
    "SourceFile",
    "PlateTest",
    "ShearTest",
    "TerrainParameters",
    "TerrainShear",
    "InputError",
]


#: Cone index above which a reading cannot be soil [kPa]: 100 MPa.  Hand-held cone
#: index penetrometers read to 7 MPa (FieldScout SC900: 0-7,000 kPa) or about 10 MPa, and
#: the soil behaviour type charts of the cone penetration test end at a cone resistance of
#: 100 MPa (q_c / p_a = 1000; Robertson et al. 1986, Robertson 2010), above the densest
#: gravels.  A larger value is a unit error (Pa read as kPa) or a corrupt cell, never terrain.
CI_MAX_KPA = 1.0e5
#: Base depth below which no cone index penetrometer pushes [m]: 5 m.  Hand-held
#: instruments reach 45 cm (SC900) to 80 cm (Eijkelkamp penetrologger), vehicle-mounted
#: ones about 1 to 1.5 m, and a vehicle engages far less; depths in cm or mm read as m
#: land beyond it.
DEPTH_MAX_M = 5.0


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
        where = {"file": self.file, self.item: self.profile, "row": self.row, "column": self.column}
        text = ", ".join(f"{k} {v}" for k, v in where.items() if v is not None)
        return (text + ": " if text else "") + self.reason


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
        big = np.flatnonzero(self.ci > CI_MAX_KPA)
        if big.size:
            raise err(
                f"cone index {self.ci[big[0]]:g} kPa is above {CI_MAX_KPA / 1000:g} MPa, "
                "more than any soil resists (a unit error?)",
                int(big[0]),
                "ci",
            )
        deep = np.flatnonzero(self.depth > DEPTH_MAX_M)
        if deep.size:
            raise err(
                f"depth {self.depth[deep[0]]:g} m is below {DEPTH_MAX_M:g} m, deeper than "
                "any cone index penetrometer pushes (a unit error?)",
                int(deep[0]),
                "depth",
            )
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
        """The part of the profile with lo <= depth <= hi [m] (see :func:`depth_window`)."""
        keep = depth_window(self.depth, lo, hi)
        rows = None if self.rows is None else self.rows[keep]
        return replace(self, depth=self.depth[keep], ci=self.ci[keep], rows=rows)


def depth_window(depth: np.ndarray, lo: float | None, hi: float | None) -> np.ndarray:
    """Boolean mask of the points with lo <= depth <= hi [m]; None: no limit.

    The one depth window of the package: :meth:`CIProfile.window`,
    :meth:`ProfileSet.window` and the CLI's ``--depth-range`` all use it.
    """
    keep = np.ones(np.shape(depth), dtype=bool)
    if lo is not None:
        keep &= depth >= lo
    if hi is not None:
        keep &= depth <= hi
    return keep


@dataclass(frozen=True)
class SourceFile:
    """A file profiles were read from, and how its columns are named (for error messages).

    ``row_word`` is what a location in the file is called: ``"row"`` (file
    line) for text files, ``"record"`` for Parquet.
    """

    path: str
    depth_column: str = "depth"
    ci_column: str = "ci"
    row_word: str = "row"


@dataclass
class ProfileSet:
    """Many CI profiles as flat columns: the package's one profile data model.

    Every reader of :mod:`terracone.io` produces it, the solvers of
    :mod:`terracone.inverse` consume it and :func:`terracone.apps.batch.run_batch`
    streams it chunk by chunk.  Profile ``i`` holds the points
    ``offsets[i]:offsets[i+1]`` of ``depth``, ``ci`` and ``rows``; a
    :class:`CIProfile` is one element (``profiles[i]``).

    Attributes
    ----------
    ids : ndarray of str, shape (P,)
        Profile ids.
    offsets : ndarray of int64, shape (P+1,)
        Start of each profile in the point arrays; ``offsets[-1] == N``.
    depth : ndarray, shape (N,)
        Depth of the cone base [m] (origin where the base is flush).
    ci : ndarray, shape (N,)
        Cone index [kPa].
    cone_idx : ndarray of int, shape (P,)
        Each profile's cone, an index into ``cones``.
    cones : list of Cone
    rows : ndarray of int64, shape (N,), optional
        File line (or record) of each point; -1 where unknown.
    file_idx : ndarray of int, shape (P,), optional
        Each profile's source, an index into ``files``; -1 where none.
    files : list of SourceFile
    metadata : pyarrow.Table, optional
        One row per profile: everything else the source carried (site, lat,
        lon, date, ...).
    notes : list of list of str, optional
        What the reader did to each profile (e.g. trailing zeros dropped).
    errors : list of InputError
        Profiles a reader refused, each located; they are not in the set.
    """

    ids: np.ndarray
    offsets: np.ndarray
    depth: np.ndarray
    ci: np.ndarray
    cone_idx: np.ndarray
    cones: list[Cone]
    rows: np.ndarray | None = None
    file_idx: np.ndarray | None = None
    files: list[SourceFile] = field(default_factory=list)
    metadata: Any = None
    notes: list[list[str]] | None = None
    errors: list[InputError] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.ids = np.asarray(self.ids, dtype=object)
        self.offsets = np.asarray(self.offsets, dtype=np.int64)
        self.depth = np.asarray(self.depth, dtype=float)
        self.ci = np.asarray(self.ci, dtype=float)
        self.cone_idx = np.asarray(self.cone_idx, dtype=np.intp)
        P = self.ids.size
        if self.offsets.shape != (P + 1,) or self.offsets[0] != 0:
            raise ValueError(f"offsets must have {P + 1} entries starting at 0")
        if np.any(np.diff(self.offsets) < 0) or self.offsets[-1] != self.depth.size:
            raise ValueError("offsets must increase to the number of points")
        if self.ci.shape != self.depth.shape or self.cone_idx.shape != (P,):
            raise ValueError("depth and ci need one value per point, cone_idx one per profile")

    def __len__(self) -> int:
        return int(self.ids.size)

    @property
    def counts(self) -> np.ndarray:
        """Number of points of each profile, shape (P,)."""
        return np.diff(self.offsets)

    def source(self, i: int) -> SourceFile | None:
        """The file profile ``i`` was read from, or None."""
        if self.file_idx is None or self.file_idx[i] < 0:
            return None
        return self.files[int(self.file_idx[i])]

    def __getitem__(self, i: int) -> CIProfile:
        if not -len(self) <= i < len(self):
            raise IndexError(f"profile {i} of {len(self)}")
        i = int(i) % len(self)
        s, e = int(self.offsets[i]), int(self.offsets[i + 1])
        src = self.source(i)
        meta = {} if self.metadata is None else self.metadata.slice(i, 1).to_pylist()[0]
        return CIProfile(
            id=str(self.ids[i]),
            depth=self.depth[s:e],
            ci=self.ci[s:e],
            cone=self.cones[int(self.cone_idx[i])],
            metadata=meta,
            source=None if src is None else src.path,
            notes=[] if self.notes is None else list(self.notes[i]),
            rows=None if self.rows is None else self.rows[s:e],
        )

    def __iter__(self) -> Iterator[CIProfile]:
        return (self[i] for i in range(len(self)))

    @classmethod
    def from_profiles(cls, items: Iterable[CIProfile | InputError]) -> ProfileSet:
        """Gather profiles (and reader errors, which go to ``errors``) into one set."""
        profs: list[CIProfile] = []
        errors: list[InputError] = []
        for it in items:
            (errors if isinstance(it, InputError) else profs).append(it)
        cones: list[Cone] = []
        files: list[SourceFile] = []
        cone_idx = [_index_of(cones, p.cone) for p in profs]
        file_idx = [
            -1 if p.source is None else _index_of(files, SourceFile(p.source)) for p in profs
        ]
        counts = [p.depth.size for p in profs]
        rows = [p.rows if p.rows is not None else np.full(p.depth.size, -1) for p in profs]
        metadata = None
        if any(p.metadata for p in profs):
            import pyarrow as pa

            keys = list(dict.fromkeys(k for p in profs for k in p.metadata))
            metadata = pa.table({k: [p.metadata.get(k) for p in profs] for k in keys})
        return cls(
            ids=np.array([p.id for p in profs], dtype=object),
            offsets=np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]),
            depth=np.concatenate([p.depth for p in profs]) if profs else np.zeros(0),
            ci=np.concatenate([p.ci for p in profs]) if profs else np.zeros(0),
            cone_idx=np.array(cone_idx, dtype=np.intp),
            cones=cones,
            rows=np.concatenate(rows).astype(np.int64) if profs else np.zeros(0, np.int64),
            file_idx=np.array(file_idx, dtype=np.intp),
            files=files,
            metadata=metadata,
            notes=[list(p.notes) for p in profs],
            errors=errors,
        )

    def take(self, index: Sequence[int] | np.ndarray) -> ProfileSet:
        """The profiles ``index`` (in that order) as a new set; ``errors`` are kept."""
        index = np.asarray(index, dtype=np.intp)
        counts = self.counts[index]
        pts = _point_index(self.offsets[index], counts)
        return replace(
            self,
            ids=self.ids[index],
            offsets=np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]),
            depth=self.depth[pts],
            ci=self.ci[pts],
            cone_idx=self.cone_idx[index],
            rows=None if self.rows is None else self.rows[pts],
            file_idx=None if self.file_idx is None else self.file_idx[index],
            metadata=None if self.metadata is None else self.metadata.take(index),
            notes=None if self.notes is None else [self.notes[int(i)] for i in index],
        )

    def window(self, lo: float | None = None, hi: float | None = None) -> ProfileSet:
        """Every profile restricted to lo <= depth <= hi [m] (:func:`depth_window`).

        A profile the window empties keeps no points; callers report it.
        """
        keep = depth_window(self.depth, lo, hi)
        per = np.repeat(np.arange(len(self)), self.counts)
        kept = np.bincount(per[keep], minlength=len(self))
        return replace(
            self,
            offsets=np.concatenate([[0], np.cumsum(kept, dtype=np.int64)]),
            depth=self.depth[keep],
            ci=self.ci[keep],
            rows=None if self.rows is None else self.rows[keep],
        )

    def heights(self) -> np.ndarray:
        """Cone height H of each profile [m], shape (P,)."""
        return np.array([c.height for c in self.cones], dtype=float).reshape(-1)[self.cone_idx]

    def screen(self) -> dict[int, InputError]:
        """The profiles of a set that cannot be fitted, each with its located error.

        A vectorised screen (non-finite values, CI negative or above
        :data:`CI_MAX_KPA`, depth below :data:`DEPTH_MAX_M`, non-increasing
        depth, too few points, tip above the surface) picks the suspects;
        :meth:`CIProfile.validate` words each one's reason, and
        :meth:`locate` names its file, row and column.  Found once per set
        (a batch worker asks twice): the arrays of a set are not changed in
        place, a changed set is a new one (``replace``, :meth:`take`, ...).
        """
        used = (self.depth, self.ci, self.offsets, self.cone_idx, self.cones, self.ids, self.rows)
        used += (self.file_idx, self.files)
        cached = self.__dict__.get("_screened")
        if cached is not None and all(a is b for a, b in zip(cached[0], used)):
            return dict(cached[1])
        errors = self._screen()
        self.__dict__["_screened"] = (used, errors)
        return dict(errors)

    def _screen(self) -> dict[int, InputError]:
        off = self.offsets
        P = len(self)
        if P == 0:
            return {}
        starts, counts = off[:-1], self.counts
        z, y = self.depth, self.ci
        with np.errstate(invalid="ignore"):
            # NaN fails every comparison: ~(a <= v <= b) also catches it
            point_bad = ~((y >= 0) & (y <= CI_MAX_KPA)) | ~np.isfinite(z) | ~(z <= DEPTH_MAX_M)
            row_bad = point_bad.copy()
            row_bad[1:] |= ~(z[1:] > z[:-1])
            has = counts > 0
            row_bad[starts[has]] = point_bad[starts[has]]  # no previous depth to compare
            bad = np.ones(P, dtype=bool)
            bad[has] = np.logical_or.reduceat(row_bad, starts[has])
            bad |= counts < 3
            bad[has] |= z[starts[has]] < -self.heights()[has] * (1 + 1e-9)
        errors = {}
        for j in np.flatnonzero(bad):
            try:
                replace(self[j], rows=np.arange(counts[j])).validate()
            except InputError as exc:
                errors[int(j)] = self.locate(int(j), exc)
        return errors

    def locate(self, j: int, exc: InputError) -> InputError:
        """``exc`` (raised by :meth:`CIProfile.validate` with rows = point index) located in its file.

        The row becomes the file line (or record), the column the file's own
        column name (the CI column for a profile with too few points, where
        the reader reports it too), and the reason says where the profile
        lies, or where the previous depth is.  Without file lines (-1) the row
        is left out.
        """
        src = self.source(j)
        path = None if src is None else src.path
        word = "row" if src is None else src.row_word
        s, e = int(self.offsets[j]), int(self.offsets[j + 1])
        lines = np.full(e - s, -1) if self.rows is None else self.rows[s:e]
        known = lines.size > 0 and bool(np.all(lines >= 0))
        if src is None:
            column = exc.column
        else:
            column = src.depth_column if exc.column == "depth" else src.ci_column
        more, row = "", None
        if exc.row is None:  # too few points
            if known:
                row = int(lines[0])
                span = f"{word} {row}" if lines.size == 1 else f"{word}s {row}-{int(lines[-1])}"
                more = f" (the profile is on {span})"
        elif known:
            row = int(lines[exc.row])
            if exc.column == "depth" and exc.row > 0 and "increasing" in exc.reason:
                more = f" (previous depth on {word} {int(lines[exc.row - 1])})"
        return InputError(
            exc.reason + more, file=path, profile=str(self.ids[j]), row=row, column=column
        )

    def padded(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(depth, ci, mask), each (P, Zmax): profiles padded for vectorised solvers.

        Padding repeats a profile's last depth and has ci 0 and mask False.
        """
        P, counts = len(self), self.counts
        Z = int(counts.max()) if P else 0
        col = np.arange(Z)
        mask = col[None, :] < counts[:, None]
        last = np.maximum(self.offsets[1:] - 1, 0)
        idx = np.where(mask, self.offsets[:-1, None] + col[None, :], last[:, None])
        zz = self.depth[idx] if self.depth.size else np.zeros((P, Z))
        yy = np.where(mask, self.ci[idx] if self.ci.size else 0.0, 0.0)
        return zz, yy, mask

    @classmethod
    def concat(cls, sets: Sequence[ProfileSet]) -> ProfileSet:
        """The profiles of several sets, in order, as one set (errors gathered too).

        Cones and files are merged (each listed once); metadata tables are
        concatenated with their schemas unified (a column missing from a set
        is null there).
        """
        import pyarrow as pa

        sets = list(sets)
        if not sets:
            return cls.from_profiles([])
        cones: list[Cone] = []
        files: list[SourceFile] = []
        cone_idx, file_idx, offsets = [], [], [np.zeros(1, np.int64)]
        end = 0
        for s in sets:
            cmap = np.array([_index_of(cones, c) for c in s.cones] or [0], dtype=np.intp)
            cone_idx.append(cmap[s.cone_idx] if len(s) else s.cone_idx)
            fmap = np.array([_index_of(files, f) for f in s.files] + [-1], dtype=np.intp)
            fi = np.full(len(s), -1, np.intp) if s.file_idx is None else s.file_idx
            file_idx.append(fmap[fi])  # -1 maps to the trailing -1
            offsets.append(s.offsets[1:] + end)
            end += int(s.offsets[-1])
        rows = [s.rows if s.rows is not None else np.full(s.depth.size, -1) for s in sets]
        tables = [s.metadata for s in sets if s.metadata is not None and len(s)]
        metadata = None
        if tables:
            schema = pa.unify_schemas([t.schema for t in tables], promote_options="permissive")
            none = {f.name: f.type for f in schema}  # a set without metadata: nulls
            metas = [
                s.metadata
                if s.metadata is not None
                else pa.table({k: pa.nulls(len(s), ty) for k, ty in none.items()})
                for s in sets
                if len(s)
            ]
            metadata = pa.concat_tables(metas, promote_options="permissive")
        return cls(
            ids=np.concatenate([s.ids for s in sets]),
            offsets=np.concatenate(offsets),
            depth=np.concatenate([s.depth for s in sets]),
            ci=np.concatenate([s.ci for s in sets]),
            cone_idx=np.concatenate(cone_idx).astype(np.intp),
            cones=cones,
            rows=np.concatenate(rows).astype(np.int64),
            file_idx=np.concatenate(file_idx).astype(np.intp),
            files=files,
            metadata=metadata,
            notes=[
                list(n)
                for s in sets
                for n in (s.notes if s.notes is not None else [[] for _ in range(len(s))])
            ],
            errors=[e for s in sets for e in s.errors],
        )


def _index_of(items: list[Any], item: Any) -> int:
    """Index of ``item`` in ``items``, appending it when new."""
    for k, x in enumerate(items):
        if x == item:
            return k
    items.append(item)
    return len(items) - 1


def _point_index(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Indices of the points of profiles starting at ``starts`` with ``counts`` points."""
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.intp)
    first = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
    return (first + np.arange(total)).astype(np.intp)


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
class TerrainParameters(Written):
    """Bekker-Wong pressure-sinkage and cone-terrain shear parameters, SI.

    The cone-terrain interaction of eqs. (2-2) to (2-7) in [1]_: the Bekker
    parameters kc, kphi, n (eq. (2-2)) and the cone (metal)-terrain shear
    parameters cc, phic_deg, K_cone (eq. (2-4)).  The terrain's *internal* shear
    strength is a different quantity: :class:`TerrainShear`.

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
    K_cone : float or None
        Cone-terrain shear deformation parameter [m] (JSON key ``Kc``);
        None: fully mobilised.
    model : {"rm0", "rm1"}
    r_min : float or None
        RM1 transition radius [m].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eqs. (2-2) to (2-7), section 3.2.
    """

    kc: float = quantity("kc", n="n")
    kphi: float = quantity("kphi", n="n")
    n: float = quantity("none")
    cc: float = quantity("pressure", default=0.0)
    phic_deg: float = quantity("none", default=0.0)
    K_cone: float | None = quantity("length", key="Kc", default=None)
    model: str = "rm0"
    r_min: float | None = quantity("length", default=None)
    units_key = True  # as_dict(units): the JSON keys of the CLI, then "units"

    @property
    def kc_over_kphi(self) -> float | None:
        """kc/kphi [m], the ratio a calibration can hold in prediction; None if kphi is 0."""
        return self.kc / self.kphi if self.kphi > 0 else None

    def _repr_html_(self) -> str:
        """A table with SI and US columns, for Jupyter."""
        from terracone.notebook import parameters_html

        return parameters_html(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any], units: str | None = None) -> TerrainParameters:
        """Inverse of :meth:`as_dict` (``units`` defaults to ``d["units"]`` or si)."""
        units = u.check_system(units or d.get("units", "si"))
        n = float(d["n"])
        r_min = d.get("r_min")
        K_cone = d.get("Kc")
        return cls(
            kc=float(u.kc_to_si(d.get("kc", 0.0) or 0.0, n, units)),
            kphi=float(u.kphi_to_si(d.get("kphi", 0.0) or 0.0, n, units)),
            n=n,
            cc=float(u.pressure_to_si(d.get("cc", 0.0) or 0.0, units)),
            phic_deg=float(d.get("phic_deg", 0.0) or 0.0),
            K_cone=None if K_cone is None else float(u.length_to_si(K_cone, units)),
            model=d.get("model", "rm0") or "rm0",
            r_min=None if r_min is None else float(u.length_to_si(r_min, units)),
        )

    def library_params(self) -> dict[str, Any]:
        """The terrain-library keys (SI): those of :meth:`as_dict` but units, None dropped."""
        return {k: v for k, v in self.as_dict().items() if v is not None and k != "units"}

    @classmethod
    def from_library_params(cls, params: dict[str, Any]) -> TerrainParameters | None:
        """From terrain-library keys; None without kc, kphi or n (cc, phic_deg 0, model rm0)."""
        if any(params.get(k) is None for k in ("kc", "kphi", "n")):
            return None
        return cls.from_dict(params, "si")


@dataclass(frozen=True)
class TerrainShear(Written):
    """The terrain's internal shear strength and shear deformation, SI.

    Mohr-Coulomb strength and the Janosi-Hanamoto shear deformation
    modulus, tau = (c + sigma tan(phi)) (1 - exp(-j/K)) ([2]_; the same form
    as eq. (2-4) of [1]_, which applies it to the cone-metal interface with
    cc, phic_deg, K_cone: :class:`TerrainParameters`).  Measured with shear rings or
    plates (:func:`terracone.inverse.bevameter.shear.fit_shear`), tabulated for reference
    terrains (:mod:`terracone.apps.library`), exported as Chrono's Mohr and
    Janosi parameters (:mod:`terracone.apps.chrono`).

    Attributes
    ----------
    c : float or None
        Cohesion [kPa]; None where unknown.
    phi_deg : float or None
        Angle of internal friction [deg].
    K : float or None
        Shear deformation modulus [m].

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, eq. (2-4).
    .. [2] Janosi, Z., Hanamoto, B. (1961). The analytical determination of
       drawbar pull as a function of slip for tracked vehicles in deformable
       soils. Proc. 1st Int. Conf. on Terrain-Vehicle Systems, Turin.
    """

    c: float | None = quantity("pressure", default=None)
    phi_deg: float | None = quantity("none", default=None)
    K: float | None = quantity("length", default=None)
    units_key = True  # as_dict(units): c, phi_deg, K (kPa, m or psi, in), then "units"

    def __post_init__(self) -> None:
        for name, lo, hi in (("c", 0.0, math.inf), ("phi_deg", 0.0, 90.0), ("K", 0.0, math.inf)):
            v = getattr(self, name)
            if v is None:
                continue
            if not (math.isfinite(v) and lo <= v < hi) or (name == "K" and v == 0):
                raise ValueError(f"terrain shear {name} out of range (got {v!r})")

    @classmethod
    def from_dict(cls, d: dict[str, Any], units: str | None = None) -> TerrainShear:
        """Inverse of :meth:`as_dict` (``units`` defaults to ``d["units"]`` or si)."""
        units = u.check_system(units or d.get("units", "si"))
        c, phi, K = d.get("c"), d.get("phi_deg"), d.get("K")
        return cls(
            c=None if c is None else float(u.pressure_to_si(c, units)),
            phi_deg=None if phi is None else float(phi),
            K=None if K is None else float(u.length_to_si(K, units)),
        )

    def library_params(self) -> dict[str, float]:
        """The terrain-library keys (SI): ``c_kpa``, ``phi_deg``, ``K_m`` (None dropped)."""
        d = {"c_kpa": self.c, "phi_deg": self.phi_deg, "K_m": self.K}
        return {k: float(v) for k, v in d.items() if v is not None}

    @classmethod
    def from_library_params(cls, params: dict[str, Any]) -> TerrainShear | None:
        """From terrain-library keys; None when none of c_kpa, phi_deg, K_m is there."""
        c, phi, K = params.get("c_kpa"), params.get("phi_deg"), params.get("K_m")
        if c is None and phi is None and K is None:
            return None
        return cls(c=c, phi_deg=phi, K=K)

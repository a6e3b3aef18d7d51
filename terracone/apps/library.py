"""A library of named terrains in SQLite.

Every terrain is a record with a unique name, a kind (``"reference"``,
``"calibration"``, ``"bevameter-fit"`` or any other word), its parameters in
SI under the keys of :data:`PARAM_UNITS` (a file format: they never change),
where they came from (provenance) and free notes.  The terrain's internal
shear (``c_kpa``, ``phi_deg``, ``K_m``) and the cone-metal shear of [1]_
(``cc``, ``phic_deg``, ``Kc``) are different quantities under different keys;
ambiguous keys (``c``, ``phi``) are refused.  Records are built from and read
back as :class:`~terracone.data.TerrainParameters` and
:class:`~terracone.data.TerrainShear` (:func:`record_params`).  Wong's
reference terrains [2]_ ship with the package as a read-only overlay.
``Library()`` opens ``$TERRACONE_LIBRARY`` or
``$XDG_DATA_HOME/terracone/library.sqlite``; writes are single ``BEGIN
IMMEDIATE`` transactions in WAL mode, so processes can share a library.
Keys, locations and formats: ``docs/library.md``.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data.
.. [2] Wong, J.Y. Theory of Ground Vehicles. Wiley (values widely reproduced).
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import functools
import io
import json
import os
import sqlite3
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib import metadata, resources
from pathlib import Path
from typing import Any

from terracone.data import TerrainParameters, TerrainShear
from terracone.io.jsonkeys import TERRAIN_KEYS, FileKeyError, Key, check_keys, read_json

__all__ = [
    "PARAM_UNITS",
    "RECORD_KEYS",
    "REFERENCE_CITATION",
    "ImportReport",
    "Library",
    "TerrainRecord",
    "add_calibration",
    "add_terrain",
    "check_params",
    "record_params",
    "default_library_path",
    "make_provenance",
    "paper_calibrations",
    "reference_records",
    "seed_paper",
    "PAPER_SETS",
]

#: Parameter keys a record may carry, with their SI unit (their ranges:
#: :data:`terracone.io.jsonkeys.TERRAIN_KEYS`).
PARAM_UNITS: dict[str, str] = {k: spec.unit for k, spec in TERRAIN_KEYS.items()}

#: The keys of a record in a library file (:meth:`Library.export`, :meth:`Library.import_`).
RECORD_KEYS: dict[str, Key] = {
    "name": Key("text", required=True, meaning="the terrain's unique name"),
    "kind": Key("text", required=True, meaning="e.g. calibration or bevameter-fit"),
    "params": Key("object", meaning="parameters in SI"),
    "provenance": Key("object", meaning="where the values come from"),
    "notes": Key("string"),
    "created": Key("string", meaning="ISO date"),
    "modified": Key("string", meaning="ISO date"),
    "builtin": Key("flag"),
}

_AMBIGUOUS = {
    "c": "'c_kpa' (terrain internal cohesion) or 'cc' (cone-metal adhesion)",
    "phi": "'phi_deg' (internal friction) or 'phic_deg' (cone-metal friction)",
    "phi_deg_c": "'phic_deg'",
    "K": "'K_m' (terrain shear deformation) or 'Kc' (cone-metal)",
    "kc_si": "'kc'",
    "kphi_si": "'kphi'",
    "K_cm": "'K_m' (in metres)",
}

REFERENCE_CITATION = "J.Y. Wong, Theory of Ground Vehicles (widely reproduced); values as tabulated"
_REFERENCE_FILE = "wong_terrain_values.csv"
_SCHEMA_VERSION = 1


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _version() -> str:
    try:
        return metadata.version("terracone")
    except metadata.PackageNotFoundError:  # pragma: no cover - source tree
        return "0.0.0+unknown"


def default_library_path() -> Path:
    """Path of the default library file.

    ``$TERRACONE_LIBRARY`` if set, else ``$XDG_DATA_HOME/terracone/library.sqlite``,
    else ``~/.local/share/terracone/library.sqlite``.
    """
    env = os.environ.get("TERRACONE_LIBRARY")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_DATA_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".local" / "share"
    return base / "terracone" / "library.sqlite"


def make_provenance(
    source: str | os.PathLike | None = None,
    method: str | None = None,
    citation: str | None = None,
    date: str | None = None,
    **extra: Any,
) -> dict[str, Any]:
    """Provenance dict: source file, ISO date (now), method, terracone version, citation."""
    out: dict[str, Any] = {
        "source": None if source is None else str(source),
        "date": date or _now(),
        "method": method,
        "terracone_version": _version(),
        "citation": citation,
    }
    out.update(extra)
    return {k: v for k, v in out.items() if v is not None}


def check_params(
    params: Mapping[str, Any],
    *,
    file: str | os.PathLike | None = None,
    record: str | None = None,
    prefix: str = "",
) -> dict[str, Any]:
    """Validated copy of a parameter dict (SI keys of :data:`PARAM_UNITS`).

    ``None`` values are dropped; numbers must be finite JSON numbers within
    their physical ranges (:data:`terracone.io.jsonkeys.TERRAIN_KEYS`);
    ``model`` must be ``"rm0"`` or ``"rm1"`` (``"rm1"`` with ``r_min``),
    ``plate_pair`` two different radii > 0, ``cone`` a cone name or spec.

    Raises
    ------
    terracone.io.jsonkeys.FileKeyError
        (a ValueError) naming ``file`` and ``record`` when given, the key
        (``prefix`` + name) and the reason; unknown and ambiguous keys too.
    """
    return check_keys(
        params,
        TERRAIN_KEYS,
        file=file,
        record=record,
        prefix=prefix,
        hints=_AMBIGUOUS,
        what="parameter",
    )


def record_params(
    *parts: TerrainParameters | TerrainShear | Mapping[str, Any], **extra: Any
) -> dict[str, Any]:
    """The stored (SI) parameter dict of a record, from the parameter types.

    Parameters
    ----------
    *parts : TerrainParameters, TerrainShear or mapping
        A :class:`~terracone.data.TerrainParameters` gives kc, kphi, n, cc,
        phic_deg, Kc (its K_cone, when set), model and r_min (when set); a
        :class:`~terracone.data.TerrainShear` gives c_kpa, phi_deg and K_m
        (those it has); a mapping gives its keys as they are.
    **extra
        Further keys (``plate_pair``, ``cone``, ``moisture_pct``, ...).

    Returns
    -------
    dict
        Checked by :func:`check_params` (None values dropped).
    """
    d: dict[str, Any] = {}
    for part in parts:
        if isinstance(part, TerrainParameters | TerrainShear):
            d.update(part.library_params())
        elif isinstance(part, Mapping):
            d.update(part)
        else:
            raise TypeError(
                f"expected TerrainParameters, TerrainShear or a mapping (got {type(part).__name__})"
            )
    d.update(extra)
    return check_params(d)


@dataclass(frozen=True)
class TerrainRecord:
    """One named terrain.

    Attributes
    ----------
    name : str
        Unique name.
    kind : str
        "reference", "calibration", "bevameter-fit" or another word.
    params : dict
        Parameters in SI (keys of :data:`PARAM_UNITS`).
    provenance : dict
        source, date (ISO), method, terracone_version, citation, ...
    notes : str
    created, modified : str or None
        ISO timestamps (UTC) of the library record.
    builtin : bool
        True for the read-only reference terrains shipped with the package.
    """

    name: str
    kind: str
    params: dict[str, Any]
    provenance: dict[str, Any] = field(default_factory=dict)
    notes: str = ""
    created: str | None = None
    modified: str | None = None
    builtin: bool = False

    @property
    def terrain_parameters(self) -> TerrainParameters | None:
        """kc, kphi, n (and cc, phic_deg, Kc, model, r_min where stored), SI.

        None when the record lacks kc, kphi or n.  cc and phic_deg read 0 and
        model "rm0" when the record has none (a plate-only terrain).
        """
        return TerrainParameters.from_library_params(self.params)

    @property
    def terrain_shear(self) -> TerrainShear | None:
        """The terrain's internal c, phi_deg, K (stored c_kpa, phi_deg, K_m); None if none."""
        return TerrainShear.from_library_params(self.params)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the format of :meth:`Library.export`)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "params": dict(self.params),
            "provenance": dict(self.provenance),
            "notes": self.notes,
            "created": self.created,
            "modified": self.modified,
            "builtin": self.builtin,
        }

    @classmethod
    def from_dict(
        cls,
        d: Mapping[str, Any],
        *,
        file: str | os.PathLike | None = None,
        record: str | None = None,
    ) -> TerrainRecord:
        """Record from :meth:`to_dict` output, every key checked (:data:`RECORD_KEYS`).

        Raises
        ------
        terracone.io.jsonkeys.FileKeyError
            (a ValueError) naming ``file``, ``record``, the key and the reason.
        """
        where = {"file": file, "record": record}
        r = check_keys(d, RECORD_KEYS, **where)
        params = check_params(r.get("params", {}), prefix="params.", **where)
        return cls(
            name=r["name"],
            kind=r["kind"],
            params=params,
            provenance=r.get("provenance", {}),
            notes=r.get("notes", ""),
            created=r.get("created"),
            modified=r.get("modified"),
            builtin=False,
        )


@dataclass(frozen=True)
class ImportReport:
    """What :meth:`Library.import_` did: names imported and skipped (with why)."""

    imported: list[str]
    skipped: list[tuple[str, str]]


def _check_name(name: Any) -> str:
    if not isinstance(name, str) or not name.strip():
        raise ValueError("a terrain name must be a non-empty string")
    return name.strip()


def _check_kind(kind: Any) -> str:
    if not isinstance(kind, str) or not kind.strip():
        raise ValueError("kind must be a non-empty string (e.g. 'calibration')")
    return kind.strip()


# --------------------------------------------------------------------------
# reference overlay


def _fmt_number(x: float) -> str:
    return f"{x:g}"


@functools.cache
def _reference_records() -> tuple[TerrainRecord, ...]:
    text = resources.files("terracone").joinpath("data", _REFERENCE_FILE).read_text("utf-8")
    reader = csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#"))
    rows = list(reader)
    for r in rows:
        if None in r or any(v is None for v in r.values()):  # pragma: no cover - data check
            raise RuntimeError(f"{_REFERENCE_FILE}: malformed row {r} (quote names with commas)")
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["terrain"]] = counts.get(r["terrain"], 0) + 1

    def num(v: str) -> float | None:
        v = (v or "").strip()
        return float(v) if v else None

    out = []
    seen: set[str] = set()
    for i, r in enumerate(rows, 1):
        base = r["terrain"].strip()
        moist = num(r["moisture_pct"])
        name = base
        if counts[r["terrain"]] > 1:  # repeated name: append the moisture
            name = f"{base} {_fmt_number(moist)}%" if moist is not None else f"{base} #{i}"
        if name in seen:  # pragma: no cover - the table has no such rows
            name = f"{name} #{i}"
        seen.add(name)
        K_cm = num(r["K_cm"])
        # plate values (kc, kphi, n; no cone-metal cc, phic) and the terrain's internal shear
        shear = TerrainShear(
            c=num(r["c_kpa"]),
            phi_deg=num(r["phi_deg"]),
            K=None if K_cm is None else K_cm / 100.0,  # cm -> m
        )
        plates = {"kc": num(r["kc_si"]), "kphi": num(r["kphi_si"]), "n": num(r["n"])}
        out.append(
            TerrainRecord(
                name=name,
                kind="reference",
                params=record_params(plates, shear, moisture_pct=moist),
                provenance={
                    "source": f"terracone/data/{_REFERENCE_FILE}",
                    "method": "tabulated",
                    "citation": REFERENCE_CITATION,
                    "table_name": base,
                },
                notes="plate (bevameter) and internal shear values; not cone-metal values",
                builtin=True,
            )
        )
    return tuple(out)


def reference_records() -> list[TerrainRecord]:
    """The reference terrains shipped with the package (read-only), in table order."""
    return list(_reference_records())


def _reference_map() -> dict[str, TerrainRecord]:
    return {r.name: r for r in _reference_records()}


# --------------------------------------------------------------------------
# the library


_SCHEMA = """
CREATE TABLE IF NOT EXISTS terrains (
    name TEXT PRIMARY KEY NOT NULL,
    kind TEXT NOT NULL,
    params TEXT NOT NULL,
    provenance TEXT NOT NULL,
    notes TEXT NOT NULL DEFAULT '',
    created TEXT NOT NULL,
    modified TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY NOT NULL, value TEXT NOT NULL);
"""


class Library:
    """A terrain library in an SQLite file.

    Parameters
    ----------
    path : str or Path, optional
        Library file; default :func:`default_library_path`.  Parent folders
        are created.
    timeout : float
        How long a writer waits for another process's lock [s].

    Examples
    --------
    >>> lib = Library("/tmp/terrains.sqlite")           # doctest: +SKIP
    >>> lib.add("site 3", "bevameter-fit", {"kc": 5.1, "kphi": 812.0, "n": 0.9},
    ...         make_provenance("plates.csv", method="wong"))   # doctest: +SKIP
    >>> lib.get("LETE sand").params["kphi"]             # doctest: +SKIP
    5301.0
    """

    def __init__(self, path: str | os.PathLike | None = None, *, timeout: float = 30.0) -> None:
        self.path = Path(path).expanduser() if path is not None else default_library_path()
        self._timeout = float(timeout)
        self._connection: sqlite3.Connection | None = None

    @property
    def _conn(self) -> sqlite3.Connection:
        """The database, opened on first use: the packaged reference terrains need none."""
        if self._connection is None:
            self._connection = self._open()
        return self._connection

    def _open(self) -> sqlite3.Connection:
        """Connect and set up the file; ValueError naming it when it is not a library."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        conn = sqlite3.connect(
            str(self.path), timeout=self._timeout, isolation_level=None, check_same_thread=False
        )
        self._connection = conn
        try:
            conn.execute(f"PRAGMA busy_timeout = {int(self._timeout * 1000)}")
            self._retry(self._setup)
        except sqlite3.DatabaseError as exc:
            self._connection = None
            conn.close()
            raise ValueError(
                f"terrain library {self.path}: cannot use it ({exc}); move the file away or give "
                "another with --library or TERRACONE_LIBRARY (the packaged reference terrains "
                "need no library file)"
            ) from None
        except BaseException:
            self._connection = None
            conn.close()
            raise
        return conn

    # -- plumbing ---------------------------------------------------------

    def _retry(self, fn, *args):
        # the busy handler covers ordinary lock waits; a few operations (the
        # switch to WAL on a brand-new file) can still report "locked" at once
        deadline = time.monotonic() + self._timeout
        delay = 0.005
        while True:
            try:
                return fn(*args)
            except sqlite3.OperationalError as e:
                msg = str(e).lower()
                if ("locked" not in msg and "busy" not in msg) or time.monotonic() > deadline:
                    raise
                time.sleep(delay)
                delay = min(delay * 2, 0.2)

    def _setup(self) -> None:
        tables = {
            r[0] for r in self._conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
        }
        if tables and "terrains" not in tables:
            raise sqlite3.DatabaseError(
                f"an SQLite file of something else, with tables {', '.join(sorted(tables))}"
            )
        mode = self._conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
        if str(mode).lower() != "wal":  # pragma: no cover - e.g. unsupported filesystem
            raise sqlite3.OperationalError(f"could not switch {self.path} to WAL (got {mode})")
        # in WAL mode NORMAL cannot corrupt the file; a power cut may lose the
        # last commits, an application crash loses nothing
        self._conn.execute("PRAGMA synchronous = NORMAL")
        with self._transaction() as c:
            for stmt in _SCHEMA.split(";"):
                if stmt.strip():
                    c.execute(stmt)
            c.execute(
                "INSERT OR IGNORE INTO meta (key, value) VALUES ('schema_version', ?)",
                (str(_SCHEMA_VERSION),),
            )

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (BEGIN IMMEDIATE ... COMMIT, ROLLBACK on error)."""
        c = self._conn
        c.execute("BEGIN IMMEDIATE")
        try:
            yield c
        except BaseException:
            c.execute("ROLLBACK")
            raise
        c.execute("COMMIT")

    def close(self) -> None:
        """Close the database connection (if it was opened)."""
        if self._connection is not None:
            self._connection.close()
            self._connection = None

    def __enter__(self) -> Library:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Library({str(self.path)!r})"

    @staticmethod
    def _row(row: tuple) -> TerrainRecord:
        name, kind, params, prov, notes, created, modified = row
        return TerrainRecord(
            name=name,
            kind=kind,
            params=json.loads(params),
            provenance=json.loads(prov),
            notes=notes,
            created=created,
            modified=modified,
        )

    # -- public API -------------------------------------------------------

    def add(
        self,
        name: str,
        kind: str,
        params: Mapping[str, Any],
        provenance: Mapping[str, Any] | None = None,
        replace: bool = False,
        notes: str = "",
    ) -> TerrainRecord:
        """Add a terrain (or replace one with ``replace=True``).

        Parameters
        ----------
        name : str
            Unique name; the names of the packaged reference terrains are
            taken.
        kind : str
            "reference", "calibration", "bevameter-fit" or another word.
        params : dict
            Parameters in SI (keys of :data:`PARAM_UNITS`; None values
            dropped).
        provenance : dict, optional
            source, method, citation, ...; ``date`` (now, ISO) and
            ``terracone_version`` are filled in when missing.
        replace : bool
            Overwrite an existing record of that name instead of raising.
        notes : str

        Returns
        -------
        TerrainRecord
            The stored record.

        Raises
        ------
        ValueError
            Bad parameters, a taken name (without ``replace``) or a
            reference name.
        """
        name = _check_name(name)
        kind = _check_kind(kind)
        p = check_params(params)
        if name in _reference_map():
            raise ValueError(
                f"{name!r} is a packaged reference terrain (read-only); choose another name"
            )
        prov = dict(provenance or {})
        prov.setdefault("date", _now())
        prov.setdefault("terracone_version", _version())
        now = _now()
        self._retry(self._write, name, kind, p, prov, str(notes or ""), now, replace)
        return self.get(name)

    def _write(self, name, kind, params, prov, notes, now, replace) -> None:
        with self._transaction() as c:
            row = c.execute("SELECT created FROM terrains WHERE name = ?", (name,)).fetchone()
            if row is not None and not replace:
                raise ValueError(
                    f"terrain {name!r} exists in {self.path} (it may have just been added by "
                    "another process): pass --replace (replace=True in Python) to overwrite it"
                )
            created = row[0] if row is not None else now
            c.execute(
                "INSERT OR REPLACE INTO terrains "
                "(name, kind, params, provenance, notes, created, modified) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    name,
                    kind,
                    json.dumps(params, sort_keys=True),
                    json.dumps(prov, sort_keys=True, default=str),
                    notes,
                    created,
                    now,
                ),
            )

    def get(self, name: str) -> TerrainRecord:
        """The terrain called ``name`` (reference or stored); KeyError if none."""
        ref = _reference_map().get(name)
        if ref is not None:
            return ref
        row = self._retry(
            lambda: self._conn.execute(
                "SELECT name, kind, params, provenance, notes, created, modified "
                "FROM terrains WHERE name = ?",
                (name,),
            ).fetchone()
        )
        if row is None:
            close = difflib.get_close_matches(name, self.names(), n=3)
            hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
            raise KeyError(f"no terrain {name!r} in {self.path}{hint}")
        return self._row(row)

    def __contains__(self, name: object) -> bool:
        if not isinstance(name, str):
            return False
        if name in _reference_map():
            return True
        row = self._conn.execute("SELECT 1 FROM terrains WHERE name = ?", (name,)).fetchone()
        return row is not None

    def list(self, kind: str | None = None, *, include_builtin: bool = True) -> list[TerrainRecord]:
        """All terrains: the reference terrains (table order), then stored ones by name."""
        rows = self._retry(
            lambda: self._conn.execute(
                "SELECT name, kind, params, provenance, notes, created, modified "
                "FROM terrains ORDER BY name"
            ).fetchall()
        )
        out = (reference_records() if include_builtin else []) + [self._row(r) for r in rows]
        return [r for r in out if kind is None or r.kind == kind]

    def names(self) -> list[str]:
        """Names of all terrains."""
        return [r.name for r in self.list()]

    def remove(self, name: str) -> None:
        """Remove a stored terrain; KeyError if none, ValueError for a reference terrain."""
        if name in _reference_map():
            raise ValueError(f"{name!r} is a packaged reference terrain and cannot be removed")

        def _rm():
            with self._transaction() as c:
                return c.execute("DELETE FROM terrains WHERE name = ?", (name,)).rowcount

        if not self._retry(_rm):
            raise KeyError(f"no terrain {name!r} in {self.path}")

    def export(self, path: str | os.PathLike, *, include_builtin: bool = False) -> int:
        """Write the stored terrains (and the reference ones if asked) as a JSON list.

        Returns the number of records written.
        """
        recs = [r.to_dict() for r in self.list(include_builtin=include_builtin)]
        path = Path(path)
        tmp = path.with_name(path.name + f".tmp{os.getpid()}")
        tmp.write_text(json.dumps(recs, indent=2, sort_keys=False) + "\n", encoding="utf-8")
        os.replace(tmp, path)
        return len(recs)

    def import_(self, path: str | os.PathLike, *, replace: bool = False) -> ImportReport:
        """Add the records of a JSON file written by :meth:`export`, all or none.

        Records named like a packaged reference terrain, and records identical
        to the stored one of that name, are skipped; another record of a taken
        name raises ValueError (nothing is imported) unless ``replace=True``.
        """
        data = read_json(path)
        if isinstance(data, Mapping):
            data = [data]
        if not isinstance(data, list):
            raise FileKeyError("expected a JSON list of terrain records", file=path)
        recs = []
        for i, d in enumerate(data):
            name = d.get("name") if isinstance(d, Mapping) else None
            label = (
                f"item {i} ({name.strip()})"
                if isinstance(name, str) and name.strip()
                else f"item {i}"
            )
            recs.append(TerrainRecord.from_dict(d, file=path, record=label))
        names = [r.name for r in recs]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise FileKeyError(f"repeated names {sorted(dup)}", file=path)
        refs = _reference_map()
        now = _now()

        def _imp() -> ImportReport:
            imported: list[str] = []
            skipped: list[tuple[str, str]] = []
            with self._transaction() as c:
                for r in recs:
                    if r.name in refs:
                        skipped.append((r.name, "packaged reference terrain"))
                        continue
                    row = c.execute(
                        "SELECT name, kind, params, provenance, notes, created, modified "
                        "FROM terrains WHERE name = ?",
                        (r.name,),
                    ).fetchone()
                    if row is not None:
                        old = self._row(row)
                        same = (old.kind, old.params, old.provenance, old.notes) == (
                            r.kind,
                            r.params,
                            r.provenance,
                            r.notes,
                        )
                        if same:
                            skipped.append((r.name, "identical record exists"))
                            continue
                        if not replace:
                            raise ValueError(
                                f"terrain {r.name!r} exists with other values; nothing "
                                "imported: pass --replace (replace=True in Python) to "
                                "overwrite"
                            )
                    c.execute(
                        "INSERT OR REPLACE INTO terrains "
                        "(name, kind, params, provenance, notes, created, modified) "
                        "VALUES (?, ?, ?, ?, ?, ?, ?)",
                        (
                            r.name,
                            r.kind,
                            json.dumps(r.params, sort_keys=True),
                            json.dumps(r.provenance, sort_keys=True, default=str),
                            r.notes,
                            r.created or now,
                            now,
                        ),
                    )
                    imported.append(r.name)
            return ImportReport(imported, skipped)

        return self._retry(_imp)


# --------------------------------------------------------------------------
# the paper's calibrations (issue 32: a library to try the library as a prior on)

#: The published parameter sets stored by :func:`paper_calibrations`: (table, data set
#: prefix of the name, plate radii of its learning data [m], soil class, what the paper calls
#: the terrain).  LETE sand: 3.75 cm and 5 cm radius plates; KRC: 4 in and 6 in diameter
#: plates (section 4 of [1]_).
PAPER_SETS = (
    ("4-1", "LETE sand", (0.0375, 0.05), "coarse", "LETE sand (a sand: coarse-grained)"),
    ("4-3", "KRC", (0.0508, 0.0762), None, "KRC mineral terrains (soil class not published)"),
)


def paper_calibrations() -> list[TerrainRecord]:
    """The paper's parameter sets as records of kind "calibration" (Tables 4-1 and 4-3 of [1]_).

    Each row of Table 4-1 (LETE sand, LS_1 to LS_4) and Table 4-3 (KRC_1 to
    KRC_25) is the set of kc, kphi, n, cc and phic that the paper's method
    (learning, then prediction, section 3.3) gives for one CI data set,
    read from ``terracone/data/paper/table_4_1.csv`` and ``table_4_3.csv``
    as printed.  The paper does not publish r_min: the records use RM0, the
    Bekker equation with which it draws the plate curves of Figs. 4-2 to
    4-10, and say so; the cone is the standard 30 deg, 0.5 in^2 cone of [1]_
    (``asabe-large``).  Names are "LETE sand LS_1", ..., "KRC KRC_1", ...
    """
    from terracone.apps.reproduce.paper import CITATION, published_parameters

    out = []
    for table, prefix, pair, soil, what in PAPER_SETS:
        for row in published_parameters(table):
            params = record_params(
                {k: row[k] for k in ("kc", "kphi", "n", "cc", "phic_deg")},
                model="rm0",
                plate_pair=list(pair),
                cone="asabe-large",
            )
            prov = {
                "source": f"terracone/data/paper/table_{table.replace('-', '_')}.csv",
                "method": "published parameters of the paper's learning and prediction "
                "processes (section 3.3); r_min not published: stored as RM0",
                "citation": f"{CITATION}, Table {table}, row {row['id']}",
                "table": table,
                "row": row["id"],
                "terrain": what,
                **({"soil_class": soil} if soil else {}),
            }
            out.append(
                TerrainRecord(
                    name=f"{prefix} {row['id']}",
                    kind="calibration",
                    params=params,
                    provenance=prov,
                    notes="seeded by `terracone library seed-paper`",
                )
            )
    return out


def seed_paper(library: Library, replace: bool = False) -> ImportReport:
    """Store :func:`paper_calibrations` in ``library`` (kind "calibration").

    A record of the same name and values is skipped; one with other values
    raises ValueError unless ``replace``.
    """
    imported: list[str] = []
    skipped: list[tuple[str, str]] = []
    for rec in paper_calibrations():
        if rec.name in library:
            old = library.get(rec.name)
            if (old.kind, old.params) == (rec.kind, rec.params):
                skipped.append((rec.name, "identical record exists"))
                continue
            if not replace:
                raise ValueError(
                    f"terrain {rec.name!r} exists with other values (use --replace); "
                    f"nothing more seeded"
                )
        library.add(rec.name, rec.kind, rec.params, rec.provenance, replace=True, notes=rec.notes)
        imported.append(rec.name)
    return ImportReport(imported, skipped)


def add_terrain(
    library: str | os.PathLike | None,
    name: str,
    kind: str = "user",
    params: Mapping[str, Any] | None = None,
    *,
    from_json: str | os.PathLike | None = None,
    source: str | None = None,
    soil_class: str | None = None,
    replace: bool = False,
) -> TerrainRecord:
    """Store a terrain in a library file (``terracone library add NAME``).

    Parameters
    ----------
    library : path, optional
        The library (default: ``$TERRACONE_LIBRARY`` or the user data dir).
    name, kind : str
    params : mapping, optional
        SI values (library keys); they override those of ``from_json``.
    from_json : path, optional
        A JSON object of SI values (checked key by key, :func:`check_params`).
    source : str, optional
        Provenance: where the values come from.
    soil_class : str, optional
        A USCS symbol, or fine or coarse, kept in the provenance (the prior
        weight of the library as a prior).
    replace : bool
        Replace a record of the same name.

    Returns
    -------
    TerrainRecord
    """
    p: dict[str, Any] = {}
    if from_json:
        p.update(check_params(read_json(from_json), file=from_json))
    p.update(params or {})
    soil = {"soil_class": soil_class} if soil_class else {}
    prov = {**make_provenance(source=source, method="library add"), **soil}
    with Library(library) as lib:
        return lib.add(name, kind, p, prov, replace=replace)


def add_calibration(
    library: str | os.PathLike | None,
    path: str | os.PathLike,
    name: str | None = None,
    *,
    source: str | None = None,
    soil_class: str | None = None,
    replace: bool = False,
) -> TerrainRecord:
    """Store a calibration file of ``terracone learn --save`` as kind "calibration".

    Under ``name``, default the calibration's terrain; its provenance kept,
    with ``source`` (default the file) and ``soil_class`` as :func:`add_terrain`
    takes them.

    Returns
    -------
    TerrainRecord
    """
    from terracone.inverse.problem import Calibration

    cal = Calibration.load(path)
    soil = {"soil_class": soil_class} if soil_class else {}
    prov = {**cal.provenance, "source": source or str(path), **soil}
    prov.setdefault("method", "terracone learn")
    with Library(library) as lib:
        return lib.add(name or cal.terrain, "calibration", cal.library_params(), prov,
                       replace=replace)  # fmt: skip

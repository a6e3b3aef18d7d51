"""Keys of terracone's JSON files, checked on load with errors that name the file and the key.

Calibration files (:class:`terracone.inverse.learning.learn.Calibration`) and terrain
library files and records (:mod:`terracone.apps.library`) are JSON objects whose keys are
listed in tables of :class:`Key`: the kind of value, its unit, its physical range, and
whether it is required.  :func:`check_keys` checks an object against such a table and
raises :class:`FileKeyError` at the first defect, naming the file, the record (for files
of several records), the key and the reason::

    file cal.json, key phic_deg: must be a finite number (got NaN)
    file terrains.json, item 2 (site 3), key params.n: must be > 0 (got -0.5)

The terrain parameter keys both formats share (kc, kphi, n, cc, phic_deg, ...; all SI)
are :data:`TERRAIN_KEYS`.  Values are shown as they are spelled in JSON (``NaN``,
``"abc"``).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from terracone.data import CI_MAX_KPA
from terracone.physics.cone import get_cone

__all__ = ["FileKeyError", "Key", "TERRAIN_KEYS", "check_keys", "check_value", "read_json"]

_INF = math.inf


class FileKeyError(ValueError):
    """A bad JSON file or value: the file, the record, the key and the reason.

    Attributes
    ----------
    reason : str
        What is wrong.
    file : str or None
        The file (as given).
    record : str or None
        Which record of a file of several (e.g. ``"item 2 (site 3)"``).
    key : str or None
        The key, dotted for nested objects (``params.kc``).
    """

    def __init__(
        self,
        reason: str,
        *,
        file: str | os.PathLike | None = None,
        record: str | None = None,
        key: str | None = None,
    ) -> None:
        self.reason = reason
        self.file = None if file is None else str(file)
        self.record = record
        self.key = key
        where = [f"file {self.file}"] if self.file is not None else []
        where += [record] if record else []
        where += [f"key {key}"] if key else []
        super().__init__((", ".join(where) + ": " if where else "") + reason)


@dataclass(frozen=True)
class Key:
    """What the value of one key must be.

    Attributes
    ----------
    kind : str
        ``"number"`` (a JSON number, finite, within ``lo``/``hi``),
        ``"text"`` (non-empty), ``"string"`` (any text), ``"choice"`` (one
        of ``choices``), ``"radii"`` (two different radii > 0 [m]),
        ``"cone"`` (a name or spec :func:`terracone.physics.cone.get_cone`
        accepts), ``"object"`` (a JSON object), ``"flag"`` (true or false)
        or ``"any"``.
    unit : str
        Unit of a number (SI), shown in range errors; ``"-"`` for none.
    lo, hi : float
        Bounds of a number; ``lo_open``/``hi_open`` exclude them.
    choices : tuple
        The allowed values of a ``"choice"``.
    required : bool
        The key must be present and not null.
    requires : dict
        Value -> another key that this value needs (``{"rm1": "r_min"}``).
    meaning : str
        What the key holds; told when it is missing or a choice is wrong.
    """

    kind: str
    unit: str = "-"
    lo: float = -_INF
    hi: float = _INF
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[Any, ...] = ()
    required: bool = False
    requires: dict[Any, str] = field(default_factory=dict)
    meaning: str = ""

    def range_text(self) -> str:
        """The allowed range of a number, e.g. ``in [0, 90) deg`` or ``> 0 m``."""
        unit = "" if self.unit == "-" else f" {self.unit}"
        if self.lo > -_INF and self.hi < _INF:
            a, b = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            return f"in {a}{self.lo:g}, {self.hi:g}{b}{unit}"
        if self.lo > -_INF:
            return f"{'>' if self.lo_open else '>='} {self.lo:g}{unit}"
        if self.hi < _INF:
            return f"{'<' if self.hi_open else '<='} {self.hi:g}{unit}"
        return "finite"


def _shown(value: Any) -> str:
    """A value as JSON spells it (NaN, "abc", [1, 2]), cut to 60 characters."""
    try:
        text = json.dumps(value, allow_nan=True)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _number(spec: Key, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"must be a number (got {_shown(value)})")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"must be a finite number (got {_shown(value)})")
    below = x <= spec.lo if spec.lo_open else x < spec.lo
    above = x >= spec.hi if spec.hi_open else x > spec.hi
    if below or above:
        raise ValueError(f"must be {spec.range_text()} (got {x:g})")
    return x


def _radii(value: Any) -> list[float]:
    ok = isinstance(value, list | tuple) and len(value) == 2
    ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    pair = [float(v) for v in value] if ok else []
    if not (ok and all(math.isfinite(v) and v > 0 for v in pair) and pair[0] != pair[1]):
        raise ValueError(f"must be two different plate radii > 0 m (got {_shown(value)})")
    return pair


def check_value(spec: Key, value: Any) -> Any:
    """The checked value (numbers as float, text stripped); ValueError with the reason."""
    kind = spec.kind
    if kind == "number":
        return _number(spec, value)
    if kind == "radii":
        return _radii(value)
    if kind == "string":
        if not isinstance(value, str):
            raise ValueError(f"must be text (got {_shown(value)})")
        return value
    if kind in ("text", "cone"):
        if not isinstance(value, str) or not value.strip():
            raise ValueError(f"must be non-empty text (got {_shown(value)})")
        if kind == "cone":
            get_cone(value.strip())  # ValueError naming the known cones
        return value.strip()
    if kind == "choice":
        if isinstance(value, bool) or value not in spec.choices:
            allowed = " or ".join(_shown(c) for c in spec.choices)
            why = f" ({spec.meaning})" if spec.meaning else ""
            raise ValueError(f"must be {allowed}{why} (got {_shown(value)})")
        return value
    if kind == "object":
        if not isinstance(value, Mapping):
            raise ValueError(f"must be a JSON object (got {_shown(value)})")
        return dict(value)
    if kind == "flag":
        if not isinstance(value, bool):
            raise ValueError(f"must be true or false (got {_shown(value)})")
        return value
    return value


def check_keys(
    doc: Any,
    keys: Mapping[str, Key],
    *,
    file: str | os.PathLike | None = None,
    record: str | None = None,
    prefix: str = "",
    hints: Mapping[str, str] | None = None,
    what: str = "key",
) -> dict[str, Any]:
    """Check a JSON object against a table of keys; the checked copy, nulls dropped.

    Parameters
    ----------
    doc : object
        The parsed JSON object (anything else is refused).
    keys : mapping of str to Key
        Every key the format knows; any other key is refused (a misspelt key
        would otherwise be ignored, or reported missing under its right name).
    file, record : optional
        Where ``doc`` comes from, for the error messages.
    prefix : str
        Dotted path of ``doc`` in the file (``"params."``).
    hints : mapping, optional
        Unknown keys with advice (``{"c": "'c_kpa' or 'cc'"}``).
    what : str
        Word for an unknown key in messages (``"key"``, ``"parameter"``).

    Returns
    -------
    dict
        The values checked by :func:`check_value`, in file order.

    Raises
    ------
    FileKeyError
        At the first defect: not an object, an unknown key, a bad value, a
        required key missing, or a value missing a key it needs.
    """
    where = {"file": file, "record": record}
    if not isinstance(doc, Mapping):
        raise FileKeyError(f"expected a JSON object (got {_shown(doc)})", key=prefix[:-1], **where)
    out: dict[str, Any] = {}
    for name, value in doc.items():
        key = f"{prefix}{name}"
        if hints and name in hints:
            raise FileKeyError(f"ambiguous {what} {name!r}: use {hints[name]}", key=key, **where)
        if name not in keys:
            known = ", ".join(keys)
            raise FileKeyError(f"unknown {what} {name!r}; known: {known}", key=key, **where)
        if value is None:
            continue
        try:
            out[name] = check_value(keys[name], value)
        except ValueError as exc:
            raise FileKeyError(str(exc), key=key, **where) from None
    for name, spec in keys.items():
        if spec.required and name not in out:
            why = f" ({spec.meaning})" if spec.meaning else ""
            raise FileKeyError(f"missing{why}", key=f"{prefix}{name}", **where)
        need = spec.requires.get(out[name]) if spec.kind == "choice" and name in out else None
        if need is not None and need not in out:
            why = f"missing ({name} {_shown(out[name])} needs {need})"
            raise FileKeyError(why, key=f"{prefix}{need}", **where)
    return out


#: Why a JSON file that Python's parser cannot nest into is refused.
JSON_TOO_DEEP = (
    "cannot read JSON (nested too deeply: arrays or objects inside each other too many times)"
)


def read_json(path: str | os.PathLike) -> Any:
    """The parsed content of a JSON file; FileKeyError naming the file when unreadable.

    ``NaN`` and ``Infinity`` are read as floats so that the key holding one is named.
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileKeyError("file not found", file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise FileKeyError(f"cannot read ({exc})", file=path) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileKeyError(f"cannot read JSON ({exc})", file=path) from None
    except RecursionError:
        raise FileKeyError(JSON_TOO_DEEP, file=path) from None


#: The terrain parameter keys of calibrations and library records (all SI).  kc and kphi
#: may be negative (a bevameter fit of k = kc/b + kphi can give one); every value is held
#: to a range far wider than any soil's (Wong's tables, ``data/wong_terrain_values.csv``:
#: n 0.11-1.6, kc up to 102, kphi up to 5,880), so that only a unit error or a corrupt
#: value is refused: |kc|, |kphi| <= 1e9, n <= 5, cc and c <= 100 MPa (the largest cone
#: index of :data:`terracone.data.CI_MAX_KPA`), lengths <= 100 m (learn searches r_min up
#: to 3 times the larger plate).
_MODULUS = 1.0e9
_STRESS = CI_MAX_KPA
_LENGTH = 100.0
TERRAIN_KEYS: dict[str, Key] = {
    "kc": Key("number", "kN/m^(n+1)", -_MODULUS, _MODULUS, meaning="Bekker cohesive modulus"),
    "kphi": Key("number", "kN/m^(n+2)", -_MODULUS, _MODULUS, meaning="Bekker frictional modulus"),
    "n": Key("number", lo=0.0, hi=5.0, lo_open=True, meaning="sinkage exponent"),
    "k": Key("number", "kN/m^(n+2)", 0.0, _MODULUS, lo_open=True, meaning="kc/b + kphi at b_m"),
    "b_m": Key("number", "m", 0.0, _LENGTH, lo_open=True, meaning="plate size of k"),
    "c_kpa": Key("number", "kPa", 0.0, _STRESS, meaning="terrain internal cohesion"),
    "phi_deg": Key("number", "deg", 0.0, 90.0, hi_open=True, meaning="internal friction"),
    "K_m": Key("number", "m", 0.0, _LENGTH, lo_open=True, meaning="shear deformation modulus"),
    "cc": Key("number", "kPa", 0.0, _STRESS, meaning="cone-terrain adhesion"),
    "phic_deg": Key("number", "deg", 0.0, 90.0, hi_open=True, meaning="cone-terrain friction"),
    "Kc": Key("number", "m", 0.0, _LENGTH, lo_open=True, meaning="cone-terrain shear deformation"),
    "model": Key(
        "choice", choices=("rm0", "rm1"), requires={"rm1": "r_min"}, meaning="pressure law"
    ),
    "r_min": Key("number", "m", 0.0, _LENGTH, lo_open=True, meaning="RM1 transition radius"),
    "plate_pair": Key("radii", "m", meaning="plate radii [r1, r2] of an RM1 calibration"),
    "cone": Key("cone", meaning="cone name or spec, e.g. asabe-large"),
    "moisture_pct": Key("number", "%", lo=0.0, meaning="moisture content"),
    "density_kg_m3": Key("number", "kg/m^3", lo=0.0, lo_open=True, meaning="(dry) density"),
}

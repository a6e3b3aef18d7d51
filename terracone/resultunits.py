"""Units of results for output: the one conversion of what terracone writes from SI.

terracone computes and holds every result in SI (m, kPa, kN/m^(n+1), kN/m^(n+2), N) and
writes its documents (JSON, Parquet, text) in the unit system asked for, ``"si"`` or
``"us"`` (:mod:`terracone.physics.units`).  This module is where a result's values are
converted for output, once for every result type:

* :func:`from_si` converts a value of a named quantity (:data:`QUANTITIES`): a
  scalar, an array, a sequence, None, and non-finite values (None where JSON needs it);
* :func:`quantity` declares on a result dataclass's field what the field is (its
  quantity, its JSON key, the field holding its n, whether NaN is written as None);
* :func:`output` writes a result dataclass field by field as its fields declare,
  nested results, lists and dicts included; a result whose document is just that
  inherits ``as_dict(units)`` from :class:`Written`;
* :func:`convert_parameters` converts a mapping keyed by parameter name (intervals,
  a site's parameters), each by the quantity of its name (:data:`PARAMETERS`).

The solvers' result types (``inverse/``) and the applications' (``apps/``) declare their
fields and assemble their documents; they do not convert units themselves.  Reading a
document back to SI stays with each type's reader.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from terracone.physics import units as u

__all__ = [
    "PARAMETERS",
    "QUANTITIES",
    "Written",
    "convert_array",
    "convert_parameters",
    "document_value",
    "field_value",
    "finite_or_none",
    "from_si",
    "output",
    "parameter_quantity",
    "quantity",
]

#: The quantities of output values.  SI and US units: none (a number without a unit),
#: length (m, in), pressure (kPa, psi), pressure2 (kPa^2, psi^2: a sum of squared
#: pressures), kc (kN/m^(n+1), lb/in^(n+1)), kphi (kN/m^(n+2), lb/in^(n+2)), force (N, lbf).
QUANTITIES = ("none", "length", "pressure", "pressure2", "kc", "kphi", "force")

#: The quantity of each parameter name of an intervals or parameters mapping
#: (:func:`convert_parameters`), also with a layer's number (``kc_2``, ``interface_1``);
#: a name not listed (n, phic_deg, ...) is unitless.
PARAMETERS: dict[str, str] = {
    "kc": "kc",
    "kphi": "kphi",
    "cc": "pressure",
    "r_min": "length",
    "Kc": "length",
    "kc_over_kphi": "length",
    "interface": "length",
}


_FROM_SI = {
    "length": u.length_from_si,
    "pressure": u.pressure_from_si,
    "force": u.force_from_si,
    "kc": u.kc_from_si,
    "kphi": u.kphi_from_si,
}
_TO_SI = {
    "length": u.length_to_si,
    "pressure": u.pressure_to_si,
    "force": u.force_to_si,
    "kc": u.kc_to_si,
    "kphi": u.kphi_to_si,
}


def convert_array(
    values: Any, quantity: str, units: str = "si", n: Any = None, *, to_si: bool = False
) -> np.ndarray:
    """An array of a named quantity from SI into ``units`` (or back into SI, ``to_si``).

    The factors are those of :mod:`terracone.physics.units`; kc and kphi are converted
    with ``n`` (a scalar, or an array of each value's n), a ``"pressure2"`` with the
    square of the pressure factor, a ``"none"`` not at all.  :func:`from_si` gives the
    values as a document holds them.
    """
    units = u.check_system(units)
    if quantity not in QUANTITIES:
        raise ValueError(f"unknown quantity {quantity!r} (known: {', '.join(QUANTITIES)})")
    return np.asarray(_convert(values, quantity, units, n, to_si), dtype=float)


def _convert(a: Any, quantity: str, units: str, n: Any, to_si: bool) -> np.ndarray:
    """:func:`convert_array`, the quantity and the unit system checked."""
    if quantity == "none":
        return np.asarray(a, dtype=float)
    if quantity == "pressure2":  # kPa^2: the square of the pressure unit's factor
        f = float(u.pressure_from_si(1.0, units)) ** 2
        a = np.asarray(a, dtype=float)
        return a / f if to_si else a * f
    table = _TO_SI if to_si else _FROM_SI
    if quantity in ("kc", "kphi"):
        if n is None and units != "si":
            raise ValueError(f"{quantity} is converted to US units with its n: give n")
        return table[quantity](a, n, units)
    return table[quantity](a, units)


def finite_or_none(v: Any) -> float | None:
    """``float(v)``, or None where it is NaN or infinite (JSON has no NaN)."""
    v = float(v)
    return v if math.isfinite(v) else None


def _finite(v: Any) -> Any:
    return [_finite(x) for x in v] if isinstance(v, list) else finite_or_none(v)


_SEQUENCES = (list, tuple, np.ndarray)


def _numbers(value: Sequence[Any]) -> bool:
    """Whether a list or tuple holds plain numbers only (no None, no nested sequence)."""
    return all(isinstance(v, int | float | np.number) and not isinstance(v, bool) for v in value)


def from_si(
    value: Any, quantity: str, units: str = "si", n: Any = None, *, finite: bool = False
) -> Any:
    """A value of a named quantity from SI into ``units``, as a document holds it.

    Parameters
    ----------
    value : float, array_like, sequence or None
        The value in SI.  A scalar becomes a float; an array, list or tuple a list
        of floats (converted as one array); a sequence holding None or sequences is
        converted item by item; None stays None.
    quantity : str
        One of :data:`QUANTITIES`: ``"none"`` (a unitless number), ``"length"``
        [m or in], ``"pressure"`` [kPa or psi], ``"pressure2"`` [kPa^2 or psi^2],
        ``"kc"`` [kN/m^(n+1) or lb/in^(n+1)], ``"kphi"`` [kN/m^(n+2) or
        lb/in^(n+2)], ``"force"`` [N or lbf].
    units : {"si", "us"}
    n : float or array_like, optional
        The sinkage exponent of kc and kphi [-] (their US unit depends on it).
    finite : bool
        Write a value that is NaN or infinite as None (JSON has no NaN).

    Returns
    -------
    float, list or None
    """
    units = u.check_system(units)
    if quantity not in QUANTITIES:
        raise ValueError(f"unknown quantity {quantity!r} (known: {', '.join(QUANTITIES)})")
    return _from_si(value, quantity, units, n, finite)


def _from_si(value: Any, quantity: str, units: str, n: Any, finite: bool) -> Any:
    """:func:`from_si`, the quantity and the unit system checked."""
    if value is None:
        return None
    sequence = isinstance(value, _SEQUENCES)
    if sequence and not isinstance(value, np.ndarray) and not _numbers(value):
        return [_from_si(v, quantity, units, n, finite) for v in value]
    if quantity == "none" and not sequence:
        values = float(value)
    else:
        out = _convert(value, quantity, units, n, False)
        values = out.tolist() if sequence and np.ndim(out) > 0 else float(out)
    return _finite(values) if finite else values


def parameter_quantity(name: str) -> str:
    """The quantity of a parameter name (:data:`PARAMETERS`), also of a layer's (``kc_2``,
    ``interface_1``); ``"none"`` for any other name."""
    if name in PARAMETERS:
        return PARAMETERS[name]
    base, _, layer = name.rpartition("_")
    return PARAMETERS.get(base, "none") if layer.isdigit() else "none"


def convert_parameters(
    values: Mapping[str, Any], units: str = "si", n: Any = None, *, finite: bool = False
) -> dict[str, Any]:
    """A mapping keyed by parameter name (values or intervals, SI) in ``units``.

    Each value (a number or a (lo, hi) pair) is converted by the quantity of its
    name (:func:`parameter_quantity`), kc and kphi with ``n``; pairs become lists.
    """
    return {
        k: from_si(v, parameter_quantity(k), units, n, finite=finite) for k, v in values.items()
    }


def quantity(
    kind: str | None = None,
    *,
    key: str | None = None,
    n: str | None = None,
    finite: bool = False,
    **kwargs: Any,
) -> Any:
    """A dataclass field that says what it is in a document (read by :func:`output`).

    Parameters
    ----------
    kind : str, optional
        Its quantity (:data:`QUANTITIES`); None: written as it is (:func:`document_value`).
    key : str, optional
        Its JSON key when it is not the field's name.
    n : str, optional
        The field holding the exponent n of a kc or kphi field.
    finite : bool
        Write a non-finite value as None.
    kwargs
        Passed to :func:`dataclasses.field` (``default``, ``default_factory``, ``repr``).
    """
    meta = {"quantity": kind, "key": key, "n": n, "finite": finite}
    return dataclasses.field(metadata={k: v for k, v in meta.items() if v}, **kwargs)


def document_value(value: Any, units: str = "si") -> Any:
    """A value without a quantity as a document holds it.

    A result (a dataclass with ``as_dict(units)``) becomes its document; lists and
    tuples become lists, item by item; dicts are copied; anything else is returned
    as it is.
    """
    if value is None or isinstance(value, str | bool | int | float):
        return value
    if dataclasses.is_dataclass(value) and hasattr(value, "as_dict"):
        return value.as_dict(units)
    if isinstance(value, list | tuple):
        return [document_value(v, units) for v in value]
    if isinstance(value, dict):
        return dict(value)
    return value


@functools.cache
def _declared(cls: type) -> dict[str, tuple[str, str | None, str | None, bool]]:
    """{field: (JSON key, quantity, field of n, finite)} of a result dataclass, in order."""
    out = {}
    for f in dataclasses.fields(cls):
        kind = f.metadata.get("quantity")
        if kind is not None and kind not in QUANTITIES:
            raise ValueError(f"{cls.__name__}.{f.name}: unknown quantity {kind!r}")
        m = f.metadata
        out[f.name] = (m.get("key") or f.name, kind, m.get("n"), m.get("finite", False))
    return out


def field_value(obj: Any, name: str, units: str = "si") -> Any:
    """One field of a result dataclass as a document holds it (as :func:`output` writes it)."""
    spec = _declared(type(obj)).get(name)
    if spec is None:
        raise ValueError(f"{type(obj).__name__} has no field {name!r}")
    return _field_value(obj, name, spec, u.check_system(units))


def _field_value(obj: Any, name: str, spec: tuple, units: str) -> Any:
    _, kind, n_field, finite = spec
    value = getattr(obj, name)
    if kind is None:
        return document_value(value, units)
    n = None if n_field is None else getattr(obj, n_field)
    return _from_si(value, kind, units, n, finite)


def output(obj: Any, units: str = "si", *, fields: Sequence[str] | None = None) -> dict[str, Any]:
    """A result dataclass as a document: its fields, each as it declares (:func:`quantity`).

    Parameters
    ----------
    obj : dataclass instance
        Values in SI.
    units : {"si", "us"}
    fields : sequence of str, optional
        The fields to write, in this order; by default every field, in the order of
        the class.

    Returns
    -------
    dict
        {JSON key: value} in ``units``: fields with a quantity converted by
        :func:`from_si`, the others by :func:`document_value` (nested results by
        their ``as_dict(units)``).
    """
    units = u.check_system(units)
    declared = _declared(type(obj))
    out: dict[str, Any] = {}
    for name in declared if fields is None else fields:
        spec = declared[name]
        out[spec[0]] = _field_value(obj, name, spec, units)
    return out


class Written:
    """A result dataclass whose document is :func:`output` of it, field by field.

    A subclass declares its fields with :func:`quantity` and inherits ``as_dict``;
    ``units_key = True`` also writes the unit system (key ``"units"``) last.
    """

    units_key: ClassVar[bool] = False

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The result in a unit system, each field as it declares (:func:`output`)."""
        d = output(self, units)
        if self.units_key:
            d["units"] = units
        return d

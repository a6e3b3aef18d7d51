"""The result model of the prediction process and its one versioned schema.

One profile's fit is a :class:`PredictionResult` (the fields of
:class:`scipy.optimize.OptimizeResult` and terracone's own); many are
:class:`PredictionResults`, written by one JSON writer (:func:`to_document`)
and one Parquet writer (:func:`to_table`) following :data:`SCHEMA`.
``docs/results.md`` lists the writers and documents the schema field by field.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from terracone.data import InputError, TerrainParameters
from terracone.physics import units as u
from terracone.resultunits import (
    Written,
    convert_array,
    convert_parameters,
    finite_or_none,
    from_si,
    output,
    parameter_quantity,
    quantity,
)

__all__ = [
    "SCHEMA",
    "SCHEMA_NAME",
    "SCHEMA_VERSION",
    "PARQUET_COLUMNS",
    "FLOAT_COLUMNS",
    "TEXT_COLUMNS",
    "RESULT_COLUMNS",
    "UQ_PARAMS",
    "BAND_QUANTITIES",
    "PlateCurve",
    "PredictionResult",
    "PredictionResults",
    "arrow_table",
    "check_schema",
    "check_table_schema",
    "dumps",
    "empty_columns",
    "from_document",
    "from_table",
    "read_json",
    "read_results",
    "PosteriorSummary",
    "LayeredSummary",
    "LibrarySummary",
    "convert_draws",
    "finite_or_none",
    "result_columns",
    "settings_dict",
    "to_document",
    "to_json",
    "to_table",
    "write_json",
    "write_parquet",
]

PathLike = str | os.PathLike[str]

#: Name and version of the prediction schema (JSON documents and Parquet tables).
SCHEMA_NAME = "terracone.prediction"
SCHEMA_VERSION = 1
SCHEMA = f"{SCHEMA_NAME}/{SCHEMA_VERSION}"
#: Key of the schema in the Arrow metadata of a Parquet table.
PARQUET_SCHEMA_KEY = b"terracone.schema"

#: Parameters with posterior intervals and identifiability labels.
UQ_PARAMS = ("kc", "kphi", "n", "cc", "phic_deg")

#: The keys of a band of plate pressure and their quantities (``plate_bands``).
BAND_QUANTITIES = {
    "radius": "length",
    "sinkage": "length",
    "median": "pressure",
    "lo": "pressure",
    "hi": "pressure",
}

#: Columns of a prediction table (batch part files, ``predict --parquet``),
#: before the metadata columns, with their Arrow types.
PARQUET_COLUMNS: tuple[tuple[str, pa.DataType], ...] = (
    ("profile", pa.string()),
    ("status", pa.string()),
    ("error", pa.string()),
    ("error_row", pa.int64()),
    ("error_column", pa.string()),
    ("kc", pa.float64()),
    ("kphi", pa.float64()),
    ("n", pa.float64()),
    ("cc", pa.float64()),
    ("phic_deg", pa.float64()),
    ("phic_lo", pa.float64()),
    ("phic_hi", pa.float64()),
    ("n_lo", pa.float64()),
    ("n_hi", pa.float64()),
    ("rmsd", pa.float64()),
    ("r2_ci", pa.float64()),
    ("longest_run", pa.float64()),
    ("lack_of_fit", pa.string()),
    *[(f"{p}_{q}", pa.float64()) for p in UQ_PARAMS for q in ("q05", "q95")],
    *[(f"ident_{p}", pa.string()) for p in UQ_PARAMS],
    ("bic_single", pa.float64()),
    ("bic_layered", pa.float64()),
    ("preferred_layers", pa.float64()),
    ("r2_layered", pa.float64()),
    ("interfaces", pa.string()),
    ("n_layers", pa.string()),
    ("lack_of_fit_layered", pa.string()),
    ("n_points", pa.int64()),
    ("undetermined", pa.string()),
    ("model", pa.string()),
    ("r_min", pa.float64()),
    ("units", pa.string()),
    ("cone", pa.string()),
    ("source", pa.string()),
    ("source_row", pa.int64()),
    ("chunk", pa.int64()),
    ("fit_time_s", pa.float64()),
)
_NAMES = [k for k, _ in PARQUET_COLUMNS]
_FIT = PARQUET_COLUMNS[_NAMES.index("kc") : _NAMES.index("n_points")]
#: Per-profile fit results that are floats (NaN = null) and texts (None = null).
FLOAT_COLUMNS = tuple(k for k, t in _FIT if t == pa.float64())
TEXT_COLUMNS = tuple(k for k, t in _FIT if t == pa.string())
#: Every per-profile fit result of the table.
RESULT_COLUMNS = FLOAT_COLUMNS + TEXT_COLUMNS


# ---------------------------------------------------------------------------
# the result model
# ---------------------------------------------------------------------------


@dataclass
class PlateCurve(Written):
    """A predicted plate pressure-sinkage curve (SI).

    Attributes
    ----------
    radius : float
        Plate radius [m].
    sinkage : ndarray
        Sinkages [m].
    pressure : ndarray
        Predicted pressure [kPa]: Bekker's eq. (2-2), or RM1 below r_min
        (section 3.2).

    ``curve["radius"]`` reads a field too (plate curves used to be dicts);
    ``as_dict(units)`` gives ``{"radius", "sinkage", "pressure"}`` (lists of floats).
    """

    radius: float = quantity("length")
    sinkage: np.ndarray = quantity("length")
    pressure: np.ndarray = quantity("pressure")

    def __getitem__(self, key: str) -> Any:
        if key not in ("radius", "sinkage", "pressure"):
            raise KeyError(key)
        return getattr(self, key)


@dataclass(kw_only=True)
class PosteriorSummary:
    """A posterior as results carry it: named parameters, their draws, intervals and labels (SI).

    The one summary type of a posterior: a fitted one-layer posterior
    (:class:`~terracone.inverse.uncertainty.posterior.PosteriorResult`) and a
    layered one (:class:`~terracone.inverse.layered.LayeredPosterior`) are
    this type with their run's details added, and :func:`read_results` gives
    it back from files.  Readers of results use these fields alone.

    Attributes
    ----------
    intervals : dict
        Equal-tailed credible interval (lo, hi) per parameter (SI): kc
        [kN/m^(n+1)], kphi [kN/m^(n+2)], n [-], cc [kPa], phic_deg [deg]
        (a layered posterior: ``kc_1``, ..., ``interface_1`` [m]).
    identifiability : dict
        "determined", "weakly determined" or "set by prior" per parameter.
    samples : ndarray or None, shape (draws, len(names))
        Posterior draws (SI); read from a file only when it kept them
        (``predict --uncertainty --json``).
    names : tuple of str
        The columns of ``samples`` (:data:`UQ_PARAMS` for one layer).
    medians : dict
        Posterior median per parameter (SI), where known.
    prior : str or None
        "bounds" or "calibration:<terrain>", when known.
    level : float
        Credibility level of the intervals [-].
    notes : list of str
        What the run held or found (a calibration's values held, warnings).
    """

    intervals: dict[str, tuple[float, float]]
    identifiability: dict[str, str] = field(default_factory=dict)
    samples: np.ndarray | None = field(default=None, repr=False)
    names: tuple[str, ...] = UQ_PARAMS
    medians: dict[str, float] = field(default_factory=dict)
    prior: str | None = None
    level: float = 0.9
    notes: list[str] = field(default_factory=list)

    def quantiles(self, units: str = "si") -> dict[str, tuple[float, float, float]]:
        """(lo, median, hi) per parameter in ``units``: quantiles of the draws, each converted
        with its own n (:func:`convert_draws`); without draws, the intervals converted with
        the middle of n's interval (the median then NaN)."""
        units = u.check_system(units)
        if self.samples is not None:
            conv = convert_draws(self.names, self.samples, units)
            q = np.quantile(conv, [(1 - self.level) / 2, 0.5, (1 + self.level) / 2], axis=0)
            return {k: (float(q[0, j]), float(q[1, j]), float(q[2, j])) for j, k in
                    enumerate(self.names)}  # fmt: skip
        n = self.intervals.get("n", (1.0, 1.0))
        iv = convert_parameters(self.intervals, units, 0.5 * (n[0] + n[1]))
        return {k: (lo, math.nan, hi) for k, (lo, hi) in iv.items()}

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """``intervals`` and ``identifiability`` of a profile in a prediction document."""
        q = self.quantiles(units)
        return {
            "intervals": {k: [v[0], v[2]] for k, v in q.items()},
            "identifiability": dict(self.identifiability),
        }

    def samples_dict(self, units: str = "si") -> dict[str, Any] | None:
        """The draws as ``{"names", "units", "values"}`` (each converted with its own n)."""
        if self.samples is None:
            return None
        values = convert_draws(self.names, self.samples, units).tolist()
        return {"names": list(self.names), "units": u.check_system(units), "values": values}


@dataclass(kw_only=True)
class LayeredSummary:
    """A layered fit as results carry it (SI): the one type of a layered fit.

    A fitted :class:`~terracone.inverse.layered.LayeredResult` is this type
    with the fit's details added; :func:`read_results` gives it back from a
    prediction table, where each layer's n is known and its kc, kphi, cc and
    phic are not (NaN).

    Attributes
    ----------
    status : {"ok", "error"}
    error : str or None
        Why the layered fit was not possible.
    layers : list of TerrainParameters
        Parameters of each layer, top first.
    interfaces : list of float
        Depths of the layer boundaries [m].
    bic, bic_single : float
        BIC of the layered and of the one-layer fit.
    preferred_layers : int
        Number of layers with the lower BIC.
    r2_ci : float
        R2 of the layered CI fit [-].
    lack_of_fit : str or None
    """

    status: str
    error: str | None = None
    layers: list[TerrainParameters] = field(default_factory=list)
    interfaces: list[float] = quantity("length", default_factory=list)
    bic: float = math.nan
    bic_single: float = math.nan
    preferred_layers: int = 1
    r2_ci: float = math.nan
    lack_of_fit: str | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def layer_n(self) -> list[float]:
        """n of each layer, top first [-]."""
        return [p.n for p in self.layers]

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The ``layered`` of a profile in a prediction document, as far as a table knows it."""
        d: dict[str, Any] = {"status": self.status, "error": self.error}
        if self.ok:
            d.update(
                layers=[{"n": v} for v in self.layer_n],
                interfaces=from_si(self.interfaces, "length", units),
                r2_ci=finite_or_none(self.r2_ci),
                lack_of_fit=self.lack_of_fit,
                bic=finite_or_none(self.bic),
                bic_single=finite_or_none(self.bic_single),
                preferred_layers=self.preferred_layers,
                units=units,
            )
        return d


@dataclass(kw_only=True)
class LibrarySummary:
    """What the library as a prior found for a profile or a site (issue 32), SI inside.

    Attributes
    ----------
    weights : dict
        {terrain name: weight} of the candidate calibrations, summing to 1,
        largest first (JSON ``calibration_weights``).
    outside : bool
        True when the posterior predictive check of every candidate has a
        p-value below ``check_level``: the answer is then the uncalibrated
        one (JSON ``outside_library``).
    candidates : list of dict
        Per candidate, largest weight first: ``terrain``, ``weight``,
        ``prior_weight``, ``log_evidence``, ``check_p``, ``model``, ``r_min``
        [m], ``phic_deg``, ``cc`` [kPa], ``kc_over_kphi`` [m].
    carried_by : str or None
        The candidate whose weight is at least 0.5, when the answer is the
        library's; None when none is (or the profile is outside).
    source : str or None
        The library file.
    check_level : float
        Level of the check [-].
    evidence, check : str
        How the evidence and the check were computed.
    plate_bands : list of dict
        Mixture medians and 90% bands of plate pressure: ``radius`` [m],
        ``sinkage`` [m], ``median``, ``lo``, ``hi`` [kPa].
    draw_candidate : ndarray or None
        Index (into ``candidates``) of the candidate of each mixture draw.
    notes : list of str
    """

    weights: dict[str, float]
    outside: bool
    candidates: list[dict[str, Any]] = field(default_factory=list)
    carried_by: str | None = None
    source: str | None = None
    check_level: float = 0.01
    evidence: str = ""
    check: str = ""
    plate_bands: list[dict[str, Any]] = field(default_factory=list)
    draw_candidate: np.ndarray | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list)

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """``calibration_weights``, ``outside_library`` and the ``library`` details."""
        units = u.check_system(units)
        cands = []
        for c in self.candidates:
            d = dict(c)
            for k in ("r_min", "kc_over_kphi"):  # written, None when unknown
                d[k] = from_si(d.get(k), "length", units)
            if d.get("cc") is not None:
                d["cc"] = from_si(d["cc"], "pressure", units)
            d["log_evidence"] = from_si(d.get("log_evidence", math.nan), "none", finite=True)
            cands.append(d)
        bands = [
            {k: from_si(b[k], q, units) for k, q in BAND_QUANTITIES.items()}
            for b in self.plate_bands
        ]
        return {
            "calibration_weights": dict(self.weights),
            "outside_library": bool(self.outside),
            "library": {
                "source": self.source,
                "candidates": cands,
                "carried_by": self.carried_by,
                "check_level": self.check_level,
                "evidence": self.evidence,
                "check": self.check,
                "plate_bands": bands,
                "notes": list(self.notes),
                "units": units,
            },
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], units: str = "si") -> LibrarySummary:
        """The summary of a profile or site of a document (:meth:`as_dict`), back in SI."""
        lib = d.get("library") if isinstance(d.get("library"), Mapping) else {}
        units = u.check_system(lib.get("units") or units)
        cands = []
        for c in lib.get("candidates") or []:
            c = dict(c)
            for k in ("r_min", "kc_over_kphi"):
                if c.get(k) is not None:
                    c[k] = float(u.length_to_si(c[k], units))
            if c.get("cc") is not None:
                c["cc"] = float(u.pressure_to_si(c["cc"], units))
            cands.append(c)
        bands = [
            {
                "radius": float(u.length_to_si(b["radius"], units)),
                "sinkage": np.asarray(u.length_to_si(b["sinkage"], units), float),
                **{
                    k: np.asarray(u.pressure_to_si(b[k], units), float)
                    for k in ("median", "lo", "hi")
                },
            }
            for b in lib.get("plate_bands") or []
        ]
        return cls(
            weights={str(k): float(v) for k, v in (d.get("calibration_weights") or {}).items()},
            outside=bool(d.get("outside_library")),
            candidates=cands,
            carried_by=lib.get("carried_by"),
            source=lib.get("source"),
            check_level=float(lib.get("check_level", 0.01)),
            evidence=str(lib.get("evidence", "")),
            check=str(lib.get("check", "")),
            plate_bands=bands,
            notes=list(lib.get("notes") or []),
        )


@dataclass
class PredictionResult:
    """Result of the prediction process for one profile (SI inside).

    Fields after :class:`scipy.optimize.OptimizeResult`: ``params`` (the
    optimum, as :class:`~terracone.data.TerrainParameters`; ``x`` is it as
    an array), ``success``, ``status``, ``message``, ``nfev``, ``nit`` and
    ``fun`` (the RMSD).

    Attributes
    ----------
    id : str
        Profile id.
    status : {"ok", "error"}
        "ok": fitted (``success`` is True); "error": not fitted, ``error``
        says why.  A JSON contract; scipy's integer status has no use here.
    error : str or None
        Why the profile could not be fitted (file, profile, row, column).
    error_row, error_column : int or str or None
        The row (file line) and column of a reader's error, when known.
    params : TerrainParameters or None
        kc, kphi, n, cc, phic (and Kc, model, r_min).
    rmsd : float
        RMSD between measured and model CI [kPa].
    r2_ci : float
        Coefficient of determination of the CI fit [-].
    longest_run : int
        Largest number of consecutive residuals of one sign.
    lack_of_fit : str or None
        None, or why the model does not follow the data
        (:func:`terracone.physics.metrics.check_fit`): then the parameters must not
        be taken as the terrain's.
    depth, ci, ci_model : ndarray
        Base depths [m], measured and model CI [kPa].
    undetermined : list of str
        Parameters (or combinations, written ``a~b``) that the data leave
        free within the bounds.
    phic_range : (float, float)
        Interval of phic [deg] attaining the optimum.
    profile_intervals : dict
        Approximate 95% profile-likelihood intervals (SI).
    sigma : float
        Residual standard deviation used by the intervals [kPa].
    solver, nfev, nit, time_s, converged, message
        Diagnostics: ``message`` says why the solver stopped, or for an
        error result, why the profile was not fitted.
    cone, metadata, notes, source, extra
        The profile's cone, its metadata, notes of the readers and the fit,
        its file, and further keys of the JSON document.
    posterior : PosteriorResult or None
        Posterior of the fit (:func:`terracone.inverse.uncertainty.posterior.posterior`).
    layered : LayeredResult or None
        Layered fit of the profile (:func:`terracone.physics.layers.fit_layered`).
    layered_posterior : LayeredPosterior or None
        Posterior of the layered fit.
    plate_curves : list of PlateCurve
        Predicted plate pressure-sinkage curves.
    library : LibrarySummary or None
        What the library as a prior found (candidates' weights, the check);
        then ``params`` kc, kphi and n are the mixture's medians and
        ``posterior`` the mixture (``docs/library.md``).

    References
    ----------
    .. [1] Huang, Wong, Preston-Thomas, Jayakumar, section 3.3.2.
    """

    id: str
    status: str
    error: str | None = None
    params: TerrainParameters | None = None
    rmsd: float = float("nan")
    r2_ci: float = float("nan")
    longest_run: int = 0
    lack_of_fit: str | None = None
    depth: np.ndarray | None = quantity("length", default=None)
    ci: np.ndarray | None = quantity("pressure", default=None)
    ci_model: np.ndarray | None = quantity("pressure", default=None)
    undetermined: list[str] = field(default_factory=list)
    phic_range: tuple[float, float] | None = None
    profile_intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    sigma: float = float("nan")
    solver: str = "exact"
    nfev: int = 0
    nit: int = 0
    time_s: float = 0.0
    converged: bool = False
    message: str = ""
    cone: str = "asabe-large"
    metadata: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    source: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    error_row: int | None = None
    error_column: str | None = None
    posterior: Any = None
    layered: Any = None
    layered_posterior: Any = None
    plate_curves: list[PlateCurve] = field(default_factory=list)
    library: LibrarySummary | None = None

    def __post_init__(self) -> None:
        if isinstance(self.error, InputError):
            exc = self.error
            self.error_row = exc.row if self.error_row is None else self.error_row
            self.error_column = exc.column if self.error_column is None else self.error_column
            self.error = str(exc)
        if self.status != "ok" and not self.message and self.error:
            self.message = str(self.error)

    @property
    def ok(self) -> bool:
        """True when fitted (``status == "ok"``); ``success`` is OptimizeResult's name for it."""
        return self.status == "ok"

    success = ok

    @property
    def fun(self) -> float:
        """OptimizeResult's ``fun``: the objective at the optimum, the RMSD [kPa]."""
        return self.rmsd

    @property
    def x(self) -> np.ndarray:
        """OptimizeResult's ``x``: (kc, kphi, n, cc, phic_deg) in SI, NaN when not fitted."""
        p = self.params
        if p is None:
            return np.full(5, np.nan)
        return np.array([p.kc, p.kphi, p.n, p.cc, p.phic_deg], dtype=float)

    def _repr_html_(self) -> str:
        """A table of the parameters (SI and US) and the fit, for Jupyter."""
        from terracone.notebook import prediction_html

        return prediction_html(self)

    def as_dict(
        self, units: str = "si", *, curves: bool = True, samples: bool = True
    ) -> dict[str, Any]:
        """One profile of a prediction document (the ``predict --json`` contract).

        ``curves``: include depth, CI and model CI; ``samples``: include the
        posterior draws (key ``samples``, read by ``terracone export``).
        """
        units = u.check_system(units)
        d = self._fit_dict(units)
        if curves and self.ok:
            d.update(output(self, units, fields=("depth", "ci", "ci_model")))
        d.update(self.extra)
        if self.plate_curves:
            d["plates"] = [c.as_dict(units) for c in self.plate_curves]
        if self.posterior is not None:
            d.update(self.posterior.as_dict(units))
            draws = self.posterior.samples_dict(units) if samples else None
            if draws is not None:
                d["samples"] = draws
        if self.layered is not None:
            d["layered"] = self.layered.as_dict(units)
            if self.layered_posterior is not None:
                d["layered"]["posterior"] = self.layered_posterior.as_dict(units)
        if self.library is not None:
            d.update(self.library.as_dict(units))
        return d

    def _fit_dict(self, units: str) -> dict[str, Any]:
        d: dict[str, Any] = {"id": self.id, "status": self.status, "error": self.error}
        d["error_row"], d["error_column"] = self.error_row, self.error_column
        keys = ("kc", "kphi", "n", "cc", "phic_deg", "Kc", "model", "r_min")
        if self.params is not None:
            p = self.params.as_dict(units)
            d.update({k: p[k] for k in keys})
        else:
            d.update({k: None for k in keys})
        d["rmsd"] = from_si(self.rmsd, "pressure", units, finite=True) if self.ok else None
        d["r2_ci"] = finite_or_none(self.r2_ci) if self.ok else None
        d["longest_run"] = self.longest_run if self.ok else None
        d["lack_of_fit"] = self.lack_of_fit
        d["units"] = units
        d["undetermined"] = list(self.undetermined)
        d["phic_range_deg"] = list(self.phic_range) if self.phic_range else None
        if self.ok and self.params is not None:
            d["profile_intervals"] = convert_parameters(
                self.profile_intervals, units, self.params.n
            )
        d["solver"] = self.solver
        d["diagnostics"] = {
            "nfev": self.nfev,
            "nit": self.nit,
            "time_s": self.time_s,
            "converged": self.converged,
            "message": self.message,
        }
        d["cone"] = self.cone
        d["metadata"] = self.metadata
        d["notes"] = list(self.notes)
        d["source"] = self.source
        return d


class PredictionResults(list):
    """A list of :class:`PredictionResult` that shows as one table in Jupyter.

    ``settings`` holds the settings of the run that wrote them, as the file
    records them (the ``settings`` of a JSON document, of a batch's
    ``_run.json``), e.g. ``settings.get("calibration")``; empty otherwise.
    ``header`` holds the other top-level keys of a JSON document (``input``,
    ``command``, ``terracone``, ``units``, ``synthetic``, ``note``, ...).
    """

    settings: dict[str, Any]
    header: dict[str, Any]

    def __init__(
        self, results: Iterable[PredictionResult] = (), settings: Any = None, header: Any = None
    ) -> None:
        super().__init__(results)
        self.settings = dict(settings or {})
        self.header = dict(header or {})

    def _repr_html_(self) -> str:
        from terracone.notebook import predictions_html

        return predictions_html(self)


def convert_draws(
    names: Sequence[str], samples: Any, units: str, *, to_si: bool = False
) -> np.ndarray:
    """Posterior draws (S, len(names)) from SI into ``units`` (or back, ``to_si``).

    The one conversion of draws: each column by the quantity of its name
    (:func:`~terracone.resultunits.parameter_quantity`): kc and kphi (``kc``,
    ``kc_1``, ...) each with its own draw's n (``n``, ``n_1``, ...), cc as a
    pressure, interfaces as lengths; n and phic are unitless.
    """
    names = list(names)
    s = np.array(samples, dtype=float, copy=True).reshape(-1, len(names))
    units = u.check_system(units)
    if units == "si":
        return s
    for j, name in enumerate(names):
        q = parameter_quantity(name)
        n = None
        if q in ("kc", "kphi"):
            layer = name.partition("_")[2]
            n = s[:, names.index(f"n_{layer}" if layer else "n")]
        if q != "none":
            s[:, j] = convert_array(s[:, j], q, units, n, to_si=to_si)
    return s


def _intervals_to_si(iv: Mapping[str, Sequence[float]], n: float, units: str) -> dict:
    """Intervals of a document (``units``) back to SI: (lo, hi) per parameter name."""
    out = {}
    for k, lohi in iv.items():
        lo, hi = convert_array(lohi, parameter_quantity(k), units, n, to_si=True).tolist()
        out[k] = (lo, hi)
    return out


# ---------------------------------------------------------------------------
# JSON: one document per set of results
# ---------------------------------------------------------------------------


def settings_dict(settings: Mapping[str, Any], units: str = "si", **extra: Any) -> dict[str, Any]:
    """The ``settings`` of a prediction document, from SI settings.

    ``r_min`` [m] is converted to ``units``, objects with ``as_dict(units)``
    (:class:`~terracone.inverse.Bounds`) become dicts, ``extra`` is recorded
    as given and ``units`` comes last.
    """
    units = u.check_system(units)
    out: dict[str, Any] = {}
    for k, v in settings.items():
        if k == "r_min" and v is not None:
            v = from_si(v, "length", units)
        elif hasattr(v, "as_dict"):
            v = v.as_dict(units)
        out[k] = v
    out.update(extra)
    out["units"] = units
    return out


def to_document(
    results: Iterable[PredictionResult],
    units: str = "si",
    *,
    command: str = "predict",
    input: str | None = None,
    settings: Mapping[str, Any] | None = None,
    samples: bool = True,
    **extra: Any,
) -> dict[str, Any]:
    """The JSON document of predictions (schema :data:`SCHEMA`, ``docs/results.md``).

    Parameters
    ----------
    results : iterable of PredictionResult
    units : {"si", "us"}
        Unit system of every value of the document.
    command : str
        What wrote it ("predict").
    input : str, optional
        The input file.
    settings : mapping, optional
        What the run was asked, already converted (:func:`settings_dict`);
        None leaves ``settings`` out.
    samples : bool
        Include the posterior draws of each profile (key ``samples``).
    extra
        Further top-level keys (e.g. ``synthetic``, ``note``), recorded as given.
    """
    from terracone import __version__

    units = u.check_system(units)
    doc: dict[str, Any] = {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "terracone": __version__,
        "command": command,
        "input": input,
        **extra,
    }
    if settings is not None:
        doc["settings"] = dict(settings)
    doc["units"] = units
    doc["profiles"] = [r.as_dict(units, samples=samples) for r in results]
    return doc


def dumps(obj: Any, indent: int | None = 2) -> str:
    """JSON text of a terracone document (numpy values, tuples and paths allowed)."""
    from terracone.io import json_default

    return json.dumps(obj, indent=indent, default=json_default)


def to_json(results: Iterable[PredictionResult], units: str = "si", **kwargs: Any) -> str:
    """JSON text of :func:`to_document` (``kwargs`` as there)."""
    return dumps(to_document(results, units, **kwargs))


def write_json(
    path: PathLike,
    results: Iterable[PredictionResult] | Mapping[str, Any],
    units: str = "si",
    **kwargs: Any,
) -> Path:
    """Write :func:`to_document` of ``results`` (or a document made by it) to ``path``."""
    doc = results if isinstance(results, Mapping) else to_document(results, units, **kwargs)
    p = Path(path)
    p.write_text(dumps(doc) + "\n")
    return p


def check_schema(doc: Any, source: str | None = None) -> int:
    """Schema version of a prediction document; 0 for one written before schemas.

    Raises
    ------
    ValueError
        When ``doc`` names another schema or a version this terracone cannot
        read (the message names ``source``).
    """
    from terracone import __version__

    where = f"{source}: " if source else ""
    if not isinstance(doc, Mapping):
        raise ValueError(f"{where}not a terracone result: expected a JSON object")
    if "schema" not in doc and "schema_version" not in doc:
        return 0
    name, _, tail = str(doc.get("schema", SCHEMA_NAME)).partition("/")
    if name != SCHEMA_NAME:
        raise ValueError(
            f"{where}unknown schema {doc.get('schema')!r}: terracone {__version__} reads {SCHEMA}"
        )
    raw = doc.get("schema_version", tail)
    try:
        version = int(raw)
    except (TypeError, ValueError):
        version = -1
    if version != SCHEMA_VERSION or (tail and tail != str(raw)):
        raise ValueError(
            f"{where}schema_version {raw!r} of {SCHEMA_NAME} is not supported: terracone "
            f"{__version__} reads version {SCHEMA_VERSION} only (a newer terracone may read it)"
        )
    return version


#: Keys of a document profile that _result_from_dict reads (the others go to ``extra``).
_READ_KEYS = {
    *("id", "status", "error", "kc", "kphi", "n", "cc", "phic_deg", "Kc", "model", "r_min"),
    *("rmsd", "r2_ci", "longest_run", "lack_of_fit", "units", "undetermined"),
    *("phic_range_deg", "profile_intervals", "solver", "diagnostics", "cone", "metadata"),
    *("notes", "source", "depth", "ci", "ci_model", "plates", "error_row", "error_column"),
    *("intervals", "identifiability", "samples"),  # the posterior
    *("calibration_weights", "outside_library", "library"),  # the library as a prior
}


def _samples_to_si(block: Mapping[str, Any]) -> np.ndarray:
    names = list(block.get("names", []))
    if names != list(UQ_PARAMS):
        raise ValueError(f"samples: expected columns {list(UQ_PARAMS)} (got {names})")
    s = np.reshape(block["values"], (-1, len(UQ_PARAMS)))
    return convert_draws(UQ_PARAMS, s, block.get("units", "si"), to_si=True)


def _posterior_from_dict(
    p: Mapping[str, Any], units: str, params: TerrainParameters | None
) -> PosteriorSummary | None:
    """The posterior of one profile of a document, or None when it has none."""
    if not isinstance(p.get("intervals"), Mapping):
        return None
    post = p.get("posterior") if isinstance(p.get("posterior"), Mapping) else {}
    level = float(post.get("level", 0.9))
    samples = _samples_to_si(p["samples"]) if p.get("samples") else None
    if samples is not None:
        q = np.quantile(samples, [(1 - level) / 2, (1 + level) / 2], axis=0)
        iv = {k: (float(q[0, i]), float(q[1, i])) for i, k in enumerate(UQ_PARAMS)}
    else:
        n = params.n if params is not None else 1.0
        iv = _intervals_to_si(p["intervals"], n, units)
    return PosteriorSummary(
        intervals=iv,
        identifiability=dict(p.get("identifiability") or {}),
        samples=samples,
        prior=post.get("prior"),
        level=level,
    )


def _result_from_dict(p: Mapping[str, Any], units: str) -> PredictionResult:
    """One profile of a document back to SI (keys outside the fit kept in ``extra``)."""
    units = u.check_system(p.get("units") or units)
    params = None if p.get("n") is None else TerrainParameters.from_dict(p, units)
    diag = p.get("diagnostics") or {}

    def arr(key: str, to_si: Any) -> np.ndarray | None:
        return None if p.get(key) is None else np.asarray(to_si(p[key], units), dtype=float)

    rng = p.get("phic_range_deg")
    posterior = _posterior_from_dict(p, units, params)
    return PredictionResult(
        id=str(p["id"]),
        status=str(p["status"]),
        error=p.get("error"),
        params=params,
        rmsd=float(u.pressure_to_si(p["rmsd"], units)) if p.get("rmsd") is not None else math.nan,
        r2_ci=math.nan if p.get("r2_ci") is None else float(p["r2_ci"]),
        longest_run=int(p.get("longest_run") or 0),
        lack_of_fit=p.get("lack_of_fit"),
        depth=arr("depth", u.length_to_si),
        ci=arr("ci", u.pressure_to_si),
        ci_model=arr("ci_model", u.pressure_to_si),
        undetermined=list(p.get("undetermined") or []),
        phic_range=None if rng is None else (float(rng[0]), float(rng[1])),
        profile_intervals=(
            {}
            if params is None
            else _intervals_to_si(p.get("profile_intervals") or {}, params.n, units)
        ),
        solver=p.get("solver", "exact"),
        nfev=int(diag.get("nfev", 0)),
        nit=int(diag.get("nit", 0)),
        time_s=float(diag.get("time_s", 0.0)),
        converged=bool(diag.get("converged", False)),
        message=str(diag.get("message", "")),
        cone=p.get("cone", "asabe-large"),
        metadata=dict(p.get("metadata") or {}),
        notes=list(p.get("notes") or []),
        source=p.get("source"),
        extra={k: v for k, v in p.items() if k not in _READ_KEYS},
        error_row=p.get("error_row"),
        posterior=posterior,
        library=LibrarySummary.from_dict(p, units) if "calibration_weights" in p else None,
        error_column=p.get("error_column"),
        plate_curves=[
            PlateCurve(
                float(u.length_to_si(c["radius"], units)),
                np.asarray(u.length_to_si(c["sinkage"], units), dtype=float),
                np.asarray(u.pressure_to_si(c["pressure"], units), dtype=float),
            )
            for c in p.get("plates") or []
        ],
    )


def from_document(doc: Mapping[str, Any], source: str | None = None) -> PredictionResults:
    """The results (SI) of a prediction document, also one written before schemas.

    The fit, its diagnostics and the plate curves are read back in SI; the
    other keys of a profile (posterior, layered fit, ...) stay as written,
    in the document's units, in :attr:`PredictionResult.extra`.
    """
    check_schema(doc, source)
    profiles = doc.get("profiles")
    if not isinstance(profiles, list):
        where = f"{source}: " if source else ""
        raise ValueError(f"{where}not a prediction document: no list 'profiles'")
    units = doc.get("units") or (doc.get("settings") or {}).get("units") or "si"
    header = {k: v for k, v in doc.items() if k not in ("profiles", "settings")}
    results = (_profile_from_document(p, units, i, source) for i, p in enumerate(profiles))
    return PredictionResults(results, doc.get("settings"), header)


def _profile_from_document(p: Any, units: str, index: int, source: str | None) -> PredictionResult:
    """One profile of a document, or ValueError naming the file, the profile and the key."""
    where = f"{source}, profile {index + 1}" if source else f"profile {index + 1}"
    if not isinstance(p, Mapping):
        raise ValueError(f"{where}: not a JSON object (a profile of a prediction document)")
    if "id" in p:
        where += f" (id {p['id']!r})"
    for key in ("id", "status") + (("n",) if p.get("status") == "ok" else ()):
        if p.get(key) is None:
            raise ValueError(f"{where}: key {key!r}: missing")
    try:
        return _result_from_dict(p, units)
    except KeyError as exc:
        raise ValueError(f"{where}: key {exc.args[0]!r}: missing") from None
    except (TypeError, ValueError, AttributeError, IndexError) as exc:
        raise ValueError(f"{where}: not a profile as terracone writes it ({exc})") from None


def read_json(path: PathLike) -> PredictionResults:
    """The results (SI) of a prediction JSON file (:func:`write_json`, ``predict --json``)."""
    from terracone.io.jsonkeys import read_json as read_json_file

    return from_document(read_json_file(path), source=f"file {Path(path)}")


# ---------------------------------------------------------------------------
# Parquet: one row per profile
# ---------------------------------------------------------------------------


def empty_columns(P: int) -> dict[str, np.ndarray]:
    """The fit-result columns of ``P`` profiles, all null (NaN or None)."""
    res: dict[str, np.ndarray] = {k: np.full(P, np.nan) for k in FLOAT_COLUMNS}
    for k in TEXT_COLUMNS:
        res[k] = np.full(P, None, dtype=object)
    return res


def _arrow(values: Any, t: pa.DataType) -> pa.Array:
    if isinstance(values, pa.Array | pa.ChunkedArray):
        return values
    if isinstance(values, np.ndarray):
        if values.dtype.kind in "fiub":
            return pa.array(values, t, from_pandas=True)  # NaN -> null
        return pa.array(values.tolist(), t)
    return pa.array(values if isinstance(values, list) else list(values), t, from_pandas=True)


def arrow_table(
    cols: Mapping[str, Any],
    meta: Sequence[tuple[str, pa.Array]] = (),
    *,
    schema: pa.Schema | None = None,
    metadata: Mapping[bytes, bytes] | None = None,
) -> pa.Table:
    """The prediction table: :data:`PARQUET_COLUMNS` from ``cols``, then ``meta``.

    ``cols`` maps column names to arrays (NumPy float NaN and None are null;
    a missing column is all null); ``meta`` are the metadata columns
    (name, array).  ``schema`` fixes the metadata types (batch's scan).  The
    Arrow metadata records :data:`SCHEMA` under ``terracone.schema``.
    """
    P = len(cols["profile"])
    arrays = [_arrow(cols[k], t) if k in cols else pa.nulls(P, t) for k, t in PARQUET_COLUMNS] + [
        a for _, a in meta
    ]
    if schema is None:
        schema = pa.schema(
            [pa.field(k, t) for k, t in PARQUET_COLUMNS] + [pa.field(n, a.type) for n, a in meta]
        )
    md = dict(schema.metadata or {})
    md[PARQUET_SCHEMA_KEY] = SCHEMA.encode()
    md.update(metadata or {})
    return pa.Table.from_arrays(arrays, schema=schema.with_metadata(md))


def _posterior_row(post: Any, units: str) -> dict[str, Any]:
    d = post.as_dict(units)
    row: dict[str, Any] = {}
    for p in UQ_PARAMS:
        lo, hi = d["intervals"][p]
        row[f"{p}_q05"], row[f"{p}_q95"] = lo, hi
        row[f"ident_{p}"] = d["identifiability"].get(p)
    return row


def _layered_row(lr: LayeredSummary, units: str) -> dict[str, Any]:
    """The layered columns of a layered fit (:class:`LayeredSummary`)."""
    if not lr.ok:
        return {"lack_of_fit_layered": f"layered fit not possible: {lr.error}"}
    ns = lr.layer_n
    return {
        "bic_single": lr.bic_single,
        "bic_layered": lr.bic,
        "preferred_layers": lr.preferred_layers,
        "r2_layered": lr.r2_ci,
        "interfaces": ",".join(f"{d:.6g}" for d in from_si(lr.interfaces, "length", units)),
        "n_layers": ",".join(f"{v:.6g}" for v in ns),
        "lack_of_fit_layered": lr.lack_of_fit,
    }


def _row_layered(row: Mapping[str, Any], units: str) -> LayeredSummary | None:
    """The layered columns of a table row back to SI (the reverse of :func:`_layered_row`)."""
    why = _cell(row, "lack_of_fit_layered")
    if _cell(row, "preferred_layers") is None:
        head = "layered fit not possible: "
        if why is None or not why.startswith(head):
            return None
        return LayeredSummary(status="error", error=why[len(head) :])

    def floats(key: str) -> list[float]:
        return [float(v) for v in (_cell(row, key) or "").split(",") if v.strip()]

    def num(key: str) -> float:
        return math.nan if _cell(row, key) is None else float(row[key])

    nan = math.nan
    return LayeredSummary(
        status="ok",
        bic=num("bic_layered"),
        bic_single=num("bic_single"),
        preferred_layers=int(row["preferred_layers"]),
        r2_ci=num("r2_layered"),
        interfaces=[float(u.length_to_si(v, units)) for v in floats("interfaces")],
        layers=[TerrainParameters(nan, nan, n, nan, nan) for n in floats("n_layers")],
        lack_of_fit=why,
    )


def _objects(values: list) -> np.ndarray:
    """A list as a NumPy object array (of any values, None included)."""
    out = np.empty(len(values), dtype=object)
    out[:] = values
    return out


def result_columns(results: Sequence[PredictionResult], units: str = "si") -> dict[str, Any]:
    """The :data:`PARQUET_COLUMNS` of ``results`` in ``units``, column by column.

    Floats are NumPy arrays (NaN = null), texts and integers object arrays
    (None = null); ``source_row`` and ``chunk`` are left out (null), as
    outside batch.  The one definition of a prediction table's values:
    :func:`to_table` (``predict --parquet``) and ``terracone batch`` write
    through it.  Parameters are converted with vectorised unit conversions,
    so this costs little beside the fit.
    """
    units = u.check_system(units)
    P = len(results)
    cols: dict[str, Any] = empty_columns(P)
    for k in ("status", "error", "error_row", "error_column", "cone", "source"):
        cols[k] = _objects([getattr(r, k) for r in results])
    cols.update(
        profile=_objects([r.id for r in results]),
        n_points=_objects([None if r.depth is None else len(r.depth) for r in results]),
        undetermined=_objects([";".join(r.undetermined) if r.ok else None for r in results]),
        model=_objects([None if r.params is None else r.params.model for r in results]),
        r_min=np.full(P, np.nan),
        units=_objects([units] * P),
        fit_time_s=np.array([r.time_s for r in results], dtype=float),
    )
    fitted = np.array([r.params is not None for r in results], dtype=bool)
    p = [r.params for r in results if r.params is not None]
    n = np.array([q.n for q in p], dtype=float)
    cols["kc"][fitted] = convert_array([q.kc for q in p], "kc", units, n)
    cols["kphi"][fitted] = convert_array([q.kphi for q in p], "kphi", units, n)
    cols["n"][fitted] = n
    cols["cc"][fitted] = convert_array([q.cc for q in p], "pressure", units)
    cols["phic_deg"][fitted] = [q.phic_deg for q in p]
    rm = [np.nan if q.r_min is None else q.r_min for q in p]
    cols["r_min"][fitted] = convert_array(rm, "length", units)
    ok = np.array([r.ok for r in results], dtype=bool)
    good = [r for r in results if r.ok]
    nan2 = (math.nan, math.nan)
    cols["phic_lo"][ok], cols["phic_hi"][ok] = np.array(
        [r.phic_range or nan2 for r in good] or np.empty((0, 2)), dtype=float
    ).T
    cols["n_lo"][ok], cols["n_hi"][ok] = np.array(
        [r.profile_intervals.get("n", nan2) for r in good] or np.empty((0, 2)), dtype=float
    ).T
    cols["rmsd"][ok] = convert_array([r.rmsd for r in good], "pressure", units)
    cols["r2_ci"][ok] = [r.r2_ci for r in good]
    cols["longest_run"][ok] = [r.longest_run for r in good]
    cols["lack_of_fit"][ok] = _objects([r.lack_of_fit for r in good])
    for j, r in enumerate(results):
        if r.ok and r.posterior is not None:
            _put(cols, j, _posterior_row(r.posterior, units))
        if r.ok and r.layered is not None:
            _put(cols, j, _layered_row(r.layered, units))
    return cols


def _put(cols: dict[str, Any], j: int, row: Mapping[str, Any]) -> None:
    for k, v in row.items():
        cols[k][j] = np.nan if v is None and cols[k].dtype.kind == "f" else v


def _metadata_columns(results: Sequence[PredictionResult]) -> list[tuple[str, pa.Array]]:
    """One column per metadata key (first-seen order); a name taken by a column gets ``meta_``."""
    keys: list[str] = []
    for r in results:
        keys += [k for k in r.metadata if k not in keys]
    taken = {k.lower() for k, _ in PARQUET_COLUMNS}
    out = []
    for k in keys:
        name = k
        while name.lower() in taken:
            name = "meta_" + name
        taken.add(name.lower())
        values = [r.metadata.get(k) for r in results]
        try:
            arr = pa.array(values, from_pandas=True)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            arr = pa.array([None if v is None else str(v) for v in values], pa.string())
        out.append((name, arr))
    return out


def to_table(results: Sequence[PredictionResult], units: str = "si") -> pa.Table:
    """The prediction table of ``results``: batch's part-file columns, then the metadata.

    One row per result, parameters in ``units``; ``source_row`` and
    ``chunk`` are null outside batch.  ``docs/results.md`` lists the columns.
    """
    results = list(results)
    return arrow_table(result_columns(results, units), _metadata_columns(results))


def write_parquet(path: PathLike, results: Sequence[PredictionResult], units: str = "si") -> Path:
    """Write :func:`to_table` of ``results`` to a Parquet file at ``path``."""
    p = Path(path)
    pq.write_table(to_table(results, units), p)
    return p


def check_table_schema(path: PathLike) -> int:
    """Schema version of a prediction Parquet file; 0 for one written before schemas.

    Raises
    ------
    ValueError
        When the file records another schema or a version this terracone
        cannot read, or is not a Parquet file.
    """
    try:
        md = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowInvalid) as exc:
        raise ValueError(f"file {path}: cannot read Parquet ({exc})") from exc
    raw = md.get(PARQUET_SCHEMA_KEY)
    if raw is None:
        return 0
    return check_schema({"schema": raw.decode(errors="replace")}, f"file {path}")


# ---------------------------------------------------------------------------
# reading results back: JSON, Parquet, a batch directory
# ---------------------------------------------------------------------------


def _cell(row: Mapping[str, Any], key: str) -> Any:
    v = row.get(key)
    return None if (isinstance(v, float) and v != v) else v


def _row_params(row: Mapping[str, Any], units: str) -> TerrainParameters | None:
    if any(_cell(row, k) is None for k in ("kc", "kphi", "n", "cc", "phic_deg")):
        return None
    keys = ("kc", "kphi", "n", "cc", "phic_deg", "model", "r_min")
    return TerrainParameters.from_dict({k: _cell(row, k) for k in keys}, units)


def _row_posterior(row: Mapping[str, Any], units: str, n: float) -> PosteriorSummary | None:
    iv = {p: [_cell(row, f"{p}_q05"), _cell(row, f"{p}_q95")] for p in UQ_PARAMS}
    iv = {p: lohi for p, lohi in iv.items() if lohi[0] is not None}
    if not iv:
        return None
    ident = {p: _cell(row, f"ident_{p}") for p in UQ_PARAMS if _cell(row, f"ident_{p}")}
    return PosteriorSummary(intervals=_intervals_to_si(iv, n, units), identifiability=ident)


def _result_from_row(row: Mapping[str, Any], meta_names: Mapping[str, str]) -> PredictionResult:
    """One row of a prediction table back to SI (the reverse of :func:`to_table`)."""
    units = u.check_system(_cell(row, "units") or "si")
    params = _row_params(row, units)
    lo, hi = _cell(row, "phic_lo"), _cell(row, "phic_hi")
    iv = {}
    if _cell(row, "n_lo") is not None:
        iv["n"] = (float(row["n_lo"]), float(row["n_hi"]))
    rmsd = _cell(row, "rmsd")
    return PredictionResult(
        id=str(row["profile"]),
        status=str(_cell(row, "status")),
        error=_cell(row, "error"),
        error_row=_cell(row, "error_row"),
        error_column=_cell(row, "error_column"),
        params=params,
        rmsd=math.nan if rmsd is None else float(u.pressure_to_si(rmsd, units)),
        r2_ci=math.nan if _cell(row, "r2_ci") is None else float(row["r2_ci"]),
        longest_run=int(_cell(row, "longest_run") or 0),
        lack_of_fit=_cell(row, "lack_of_fit"),
        undetermined=[t for t in (_cell(row, "undetermined") or "").split(";") if t],
        phic_range=None if lo is None else (float(lo), float(hi)),
        profile_intervals=iv,
        time_s=float(_cell(row, "fit_time_s") or 0.0),
        cone=_cell(row, "cone") or "asabe-large",
        source=_cell(row, "source"),
        metadata={m: row[c] for c, m in meta_names.items() if _cell(row, c) is not None},
        posterior=None if params is None else _row_posterior(row, units, params.n),
        layered=_row_layered(row, units),
    )


def from_table(
    table: pa.Table, settings: Mapping[str, Any] | None = None, source: str | None = None
) -> PredictionResults:
    """The results (SI) of a prediction table (:func:`to_table`, batch part files).

    Columns other than :data:`PARQUET_COLUMNS` are the profiles' metadata
    (a ``meta_`` prefix that :func:`to_table` added to avoid a clash is
    removed).  The layered columns become a :class:`LayeredSummary` (SI).
    A row that cannot be read back raises ValueError naming ``source`` (the
    file or directory), the row and the profile.
    """
    known = {k for k, _ in PARQUET_COLUMNS} | {"reader_error"}
    meta_names = {}
    for c in table.column_names:
        if c in known:
            continue
        name = c
        while name.startswith("meta_") and name[5:].lower() in known | set(meta_names.values()):
            name = name[5:]
        meta_names[c] = name
    if "profile" not in table.column_names:
        raise ValueError(f"{source or 'table'}: no column 'profile' (not a terracone prediction)")
    rows = table.to_pylist()
    results = (_row_from_table(r, i, meta_names, source) for i, r in enumerate(rows))
    return PredictionResults(results, settings)


def _row_from_table(
    row: Mapping[str, Any], index: int, meta_names: Mapping[str, str], source: str | None
) -> PredictionResult:
    try:
        return _result_from_row(row, meta_names)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        where = f"{source or 'table'}, row {index + 1} (profile {row.get('profile')!r})"
        why = f"column {exc.args[0]!r} missing" if isinstance(exc, KeyError) else str(exc)
        raise ValueError(f"{where}: not a row as terracone writes it ({why})") from None


def read_results(path: PathLike) -> PredictionResults:
    """The results (SI) of ``predict --json``, ``predict --parquet`` or a ``batch`` directory.

    Parameters
    ----------
    path : str or path-like
        A prediction JSON document, a prediction Parquet file, or the
        output directory of ``terracone batch`` (``part-*.parquet`` and
        ``_run.json``).

    Returns
    -------
    PredictionResults
        One result per profile, in file order (batch: chunk order), with
        ``settings`` as the file records them.

    Raises
    ------
    ValueError
        The path holds no terracone prediction results; the message names it.
    """
    p = Path(path)
    if p.is_dir():
        parts = sorted(p.glob("part-*.parquet"))
        if not parts:
            raise ValueError(f"{p}: no part-*.parquet files (not a terracone batch directory)")
        run = p / "_run.json"
        settings = {}
        if run.is_file():
            try:
                settings = json.loads(run.read_text()).get("settings") or {}
            except (OSError, ValueError, AttributeError):
                settings = {}
        for f in parts:
            check_table_schema(f)
        table = pa.concat_tables([pq.read_table(f) for f in parts], promote_options="permissive")
        return from_table(table, settings, source=str(p))
    if not p.exists():
        raise ValueError(f"{p}: file not found")
    if p.suffix.lower() in (".parquet", ".pq"):
        check_table_schema(p)
        return from_table(pq.read_table(p), source=f"file {p}")
    return read_json(p)

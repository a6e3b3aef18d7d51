"""Bevameter plate tests: pressure-sinkage fits and the Bekker parameters.

A plate of size b (radius of a circular plate, smaller side of a rectangular
one) follows Bekker's equation, p = (kc/b + kphi) z^n = k z^n (eq. (2-2) in
[1]_).  This module fits ``p = k z^n`` to the loading branch of each test
(``"loglog"``, ``"wong"`` [2]_ or ``"nonlinear"``) and, with two or more plate
sizes, splits k into kc and kphi over the tests; with one plate size kc and
kphi are undetermined (None), not an error.  SI throughout.  The methods and
examples: ``docs/bevameter.md``.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Eq. (2-2).
.. [2] Wong, J.Y. (1980). Data processing methodology in the characterization
   of the mechanical properties of terrain. Journal of Terramechanics 17(1),
   13-41.
.. [3] Bekker, M.G. (1969). Introduction to Terrain-Vehicle Systems.
   University of Michigan Press.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, stats

from terracone.data import InputError, PlateTest
from terracone.physics import units as u
from terracone.resultunits import field_value, output, quantity

__all__ = [
    "DRIFT_LIMIT",
    "METHODS",
    "PlateFit",
    "PlatesFit",
    "fit_plate_test",
    "fit_plates",
    "left_out",
    "line_fit",
    "of_type",
]

#: Fitting methods of :func:`fit_plate_test` and :func:`fit_plates`.
METHODS = ("wong", "loglog", "nonlinear")

_CI_NOTE = "confidence intervals need at least 3 tests over at least 2 plate sizes"

#: The keys of a :class:`PlatesFit` document before its tests, in order.
_PLATES_KEYS = (
    "kc", "kphi", "n", "kc_ci", "kphi_ci", "n_ci", "undetermined", "method", "ci_note", "notes",
)  # fmt: skip


@dataclass(frozen=True)
class PlateFit:
    """Fit of ``p = k z^n`` to the loading branch of one plate test.

    Attributes
    ----------
    test : str
        Test id.
    b : float
        Bekker plate size [m] (radius of a circular plate, smaller side of a
        rectangular one).
    shape : {"circular", "rectangular"}
    radius : float or None
        Plate radius [m] for circular plates, else None.
    k : float
        Sinkage modulus ``kc/b + kphi`` [kN/m^(n+2)].
    n : float
        Sinkage exponent [-].
    points_used : int
        Loading-branch points fitted.
    r2 : float
        Coefficient of determination of the fit on p,
        ``1 - sum (p - k z^n)^2 / sum (p - mean p)^2`` [-].
    rmsd : float
        Root mean square deviation of ``k z^n`` from p [kPa].
    method : str
        Fitting method (one of :data:`METHODS`).
    """

    test: str
    b: float = quantity("length")
    shape: str
    radius: float | None = quantity("length")
    k: float = quantity("kphi", n="n")
    n: float = quantity("none")
    points_used: int
    r2: float = quantity("none")
    rmsd: float = quantity("pressure")
    method: str

    def pressure(self, sinkage: Any) -> np.ndarray:
        """Fitted pressure ``k z^n`` [kPa] at sinkage z [m] (z >= 0)."""
        z = np.asarray(sinkage, dtype=float)
        return self.k * np.where(z > 0, z, 0.0) ** self.n

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The fit in a unit system (k converted with the fit's own n)."""
        plate = output(self, units, fields=("test", "b", "shape", "radius"))
        fit = output(self, units, fields=("k", "n", "points_used", "r2", "rmsd", "method"))
        return {**plate, "plate_radius": plate["radius"], **fit, "units": units}


@dataclass(frozen=True)
class PlatesFit:
    """Bekker parameters from a set of plate tests (:func:`fit_plates`).

    Attributes
    ----------
    kc : float or None
        Cohesive modulus [kN/m^(n+1)]; None with a single plate size.
    kphi : float or None
        Frictional modulus [kN/m^(n+2)]; None with a single plate size.
    n : float
        Common sinkage exponent [-] (common-n fit of all tests).
    kc_ci, kphi_ci, n_ci : (float, float) or None
        95 % confidence intervals [same units]; None when not available
        (see ``ci_note``).
    tests : list of PlateFit
        Independent fit of each test (its own k and n).
    undetermined : list of str
        Parameters the data cannot determine (``["kc", "kphi"]`` with one
        plate size), else empty.
    method : str
        Fitting method (one of :data:`METHODS`).
    k_common : list of float
        k of each test at the common n [kN/m^(n+2)], in the order of
        ``tests``; these are the values regressed on 1/b.
    ci_note : str or None
        Why some intervals are missing, if they are.
    notes : list of str
        Anything worth a warning (e.g. a negative kc).
    """

    kc: float | None = quantity("kc", n="n")
    kphi: float | None = quantity("kphi", n="n")
    n: float = quantity("none")
    kc_ci: tuple[float, float] | None = quantity("kc", n="n")
    kphi_ci: tuple[float, float] | None = quantity("kphi", n="n")
    n_ci: tuple[float, float] | None = quantity("none")
    tests: list[PlateFit]
    undetermined: list[str]
    method: str
    k_common: list[float] = quantity("kphi", n="n", default_factory=list)
    ci_note: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def sizes(self) -> list[float]:
        """Distinct plate sizes b [m], ascending."""
        return sorted({t.b for t in self.tests})

    def params(self) -> dict[str, float]:
        """Determined parameters as library/export keys (SI): kc, kphi, n."""
        out = {"kc": self.kc, "kphi": self.kphi, "n": self.n}
        return {k: float(v) for k, v in out.items() if v is not None}

    def as_dict(self, units: str = "si") -> dict[str, Any]:
        """The result in a unit system, JSON-ready (kc, kphi converted with the common n)."""
        d = output(self, units, fields=_PLATES_KEYS)
        k_common = field_value(self, "k_common", units)
        tests = [{**t.as_dict(units), "k_common": k} for t, k in zip(self.tests, k_common)]
        return {
            **d,
            "tests": tests,
            "units": units,
            "unit_labels": {
                "kc": u.kc_unit(units),
                "kphi": u.kphi_unit(units),
                "k": u.kphi_unit(units),
                "b": u.length_unit(units),
                "rmsd": u.pressure_unit(units),
            },
        }


# --------------------------------------------------------------------------
# fitting kernels: p = k_g z^n with one k per group g and a common n


def _check_method(method: str) -> str:
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)} (got {method!r})")
    return method


def _linear_common_n(
    z: np.ndarray, p: np.ndarray, g: np.ndarray, m: int, weighted: bool
) -> tuple[float, np.ndarray]:
    """(n, k_g) minimising sum w (ln p - ln k_g - n ln z)^2.

    ``w = 1`` ("loglog") or ``w = p^2`` (Wong's weights [2]_); solved as a
    linear least squares problem with rows scaled by sqrt(w).  With one group
    this is exactly Wong's closed form:
    n = [S(w) S(w lnp lnz) - S(w lnp) S(w lnz)] / [S(w) S(w lnz^2) - S(w lnz)^2],
    ln k = [S(w lnp) - n S(w lnz)] / S(w).
    """
    X = np.zeros((z.size, m + 1))
    X[:, 0] = np.log(z)  # slope n
    X[np.arange(z.size), 1 + g] = 1.0  # one intercept ln k_g per group
    y = np.log(p)
    if weighted:
        sw = p / p.max()  # sqrt of the weights p^2 (scale is irrelevant)
        X, y = X * sw[:, None], y * sw
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return float(coef[0]), np.exp(coef[1:])


def _nonlinear_common_n(
    z: np.ndarray, p: np.ndarray, g: np.ndarray, m: int, n0: float, k0: np.ndarray
) -> tuple[float, np.ndarray]:
    """(n, k_g) minimising sum (p - k_g z^n)^2, started from (n0, k0)."""
    lnz = np.log(z)

    def fun(x):
        return np.exp(x[1 + g]) * z ** x[0] - p

    def jac(x):
        q = np.exp(x[1 + g]) * z ** x[0]
        J = np.zeros((z.size, m + 1))
        J[:, 0] = q * lnz  # d/dn of k z^n
        J[np.arange(z.size), 1 + g] = q  # d/d(ln k) of k z^n
        return J

    x0 = np.concatenate([[n0], np.log(k0)])
    res = optimize.least_squares(fun, x0, jac=jac, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    if not np.all(np.isfinite(res.x)):  # pragma: no cover - defensive
        raise RuntimeError("nonlinear pressure-sinkage fit did not converge")
    return float(res.x[0]), np.exp(res.x[1:])


def _fit_groups(
    z: np.ndarray, p: np.ndarray, g: np.ndarray, m: int, method: str
) -> tuple[float, np.ndarray]:
    if method == "loglog":
        return _linear_common_n(z, p, g, m, weighted=False)
    if method == "wong":
        return _linear_common_n(z, p, g, m, weighted=True)
    n0, k0 = _linear_common_n(z, p, g, m, weighted=False)
    return _nonlinear_common_n(z, p, g, m, n0, k0)


def of_type(test: Any, kind: type) -> Any:
    """``test`` if it is a ``kind``; raises it if it is an InputError, else a TypeError."""
    if isinstance(test, InputError):
        raise test
    if not isinstance(test, kind):
        raise TypeError(f"expected a {kind.__name__} (got {type(test).__name__})")
    return test


def line_fit(X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Ordinary least squares ``y ~ X @ coef`` over the tests, with 95% half widths.

    Parameters
    ----------
    X : ndarray, shape (m, 2)
    y : ndarray, shape (m,)

    Returns
    -------
    coef : ndarray, shape (2,)
    half : ndarray, shape (2,) or None
        Half widths of the 95% intervals (t, m - 2 dof); None with fewer than 3 tests.
    """
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    m = y.size
    if m < 3:
        return coef, None
    resid = y - X @ coef
    cov = float(resid @ resid) / (m - 2) * np.linalg.inv(X.T @ X)
    return coef, stats.t.ppf(0.975, m - 2) * np.sqrt(np.diag(cov))


#: A loading-branch pressure below ``-DRIFT_LIMIT`` times the test's largest pressure is
#: refused: the zero drift of a load cell is a small fraction of the load (the drift of
#: the Cullinan sand tests of ../shared is at most 3.5 %), a large negative value a lost sign.
DRIFT_LIMIT = 0.1


def _lines(rows: np.ndarray | None, mask: np.ndarray) -> str:
    """' (lines 3, 4, 9, ...)' of the points in ``mask``, or ''."""
    if rows is None:
        return ""
    at = [str(int(r)) for r in rows[mask]]
    word = "line" if len(at) == 1 else "lines"
    return f" ({word} {', '.join(at[:6])}{', ...' if len(at) > 6 else ''})"


def left_out(test: PlateTest) -> str | None:
    """What the fit leaves out of a test's points and why, in words (None: nothing).

    The fit uses the loading branch (:meth:`PlateTest.loading_branch`): points
    after the largest sinkage (unloading) and points at sinkage <= 0 or
    pressure <= 0 (zero drift) are left out, and said so in the fit's notes.
    Raises a located InputError for a pressure below ``-DRIFT_LIMIT`` times the
    test's largest pressure in the loading branch: not drift but an error.
    """
    z, p, rows = test.sinkage, test.pressure, test.rows
    if z.size == 0:
        return None
    imax = int(np.argmax(z))
    head = np.arange(z.size) <= imax
    peak = float(np.max(p[head], initial=0.0))
    wrong = head & (p < -DRIFT_LIMIT * peak)
    if wrong.any():
        i = int(np.flatnonzero(wrong)[0])
        raise InputError(
            f"pressure {p[i]:.6g} kPa in the loading branch is below -{DRIFT_LIMIT:.0%} of the "
            f"test's largest pressure ({peak:.6g} kPa): not zero drift; a lost sign?",
            file=test.source, profile=test.id, item="test", column="pressure",
            row=None if rows is None else int(rows[i]),
        )  # fmt: skip
    parts = []
    drift = head & ~((z > 0) & (p > 0))
    if drift.any():
        k = int(drift.sum())
        parts.append(f"{k} at sinkage <= 0 or pressure <= 0{_lines(rows, drift)}")
    if (~head).any():
        parts.append(f"{int((~head).sum())} after the largest sinkage (unloading)")
    if not parts:
        return None
    k = int(drift.sum() + (~head).sum())
    return f"test {test.id}: {k} of {z.size} points left out of the fit: {'; '.join(parts)}"


def _branch(test: PlateTest) -> tuple[np.ndarray, np.ndarray]:
    br = of_type(test, PlateTest).loading_branch()
    z, p = br.sinkage, br.pressure
    ok = np.isfinite(z) & np.isfinite(p)
    z, p = z[ok], p[ok]
    if z.size < 2 or np.ptp(z) <= 0:
        raise InputError(
            f"{z.size} usable loading-branch point(s) with distinct sinkage > 0 and "
            f"pressure > 0; at least 2 are needed{test.lines_note()}",
            file=test.source,
            profile=test.id,
            item="test",
            row=test.first_row(),
        )
    return z, p


def _goodness(z: np.ndarray, p: np.ndarray, k: float, n: float) -> tuple[float, float]:
    """(R^2 on p, RMSD [kPa]) of p_hat = k z^n."""
    res = p - k * z**n
    ss_res = float(np.sum(res * res))
    ss_tot = float(np.sum((p - p.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan")
    return r2, math.sqrt(ss_res / p.size)


def fit_plate_test(test: PlateTest, method: str = "wong") -> PlateFit:
    """Fit ``p = k z^n`` to the loading branch of one plate test.

    Parameters
    ----------
    test : PlateTest
        Sinkage [m] and pressure [kPa]; only the loading branch is used:
        points up to the maximum sinkage with sinkage > 0 and pressure > 0
        (:meth:`PlateTest.loading_branch`).
    method : {"wong", "loglog", "nonlinear"}
        ``"wong"``: weighted least squares on ln p with weights p^2 [2]_;
        ``"loglog"``: unweighted regression of ln p on ln z;
        ``"nonlinear"``: least squares on p, started from ``"loglog"``.

    Returns
    -------
    PlateFit
        k [kN/m^(n+2)], n [-], points used, R^2 on p and RMSD [kPa].

    Raises
    ------
    InputError
        Fewer than 2 usable loading-branch points.
    """
    _check_method(method)
    z, p = _branch(test)
    n, k = _fit_groups(z, p, np.zeros(z.size, dtype=int), 1, method)
    r2, rmsd = _goodness(z, p, float(k[0]), n)
    return PlateFit(
        test=test.id,
        b=float(test.b),
        shape=test.shape,
        radius=test.radius,
        k=float(k[0]),
        n=n,
        points_used=int(z.size),
        r2=r2,
        rmsd=rmsd,
        method=method,
    )


def fit_plates(tests: Iterable[PlateTest], method: str = "wong") -> PlatesFit:
    """Bekker kc, kphi and n from plate tests of one terrain.

    Parameters
    ----------
    tests : iterable of PlateTest
        Plate tests, SI (sinkage [m], pressure [kPa], b [m]).  An
        :class:`InputError` in the iterable (from a reader that collects
        errors) is raised.
    method : {"wong", "loglog", "nonlinear"}
        Fitting method for the per-test fits and for the common-n fit (see
        the module docstring).

    Returns
    -------
    PlatesFit
        With two or more plate sizes: kc [kN/m^(n+1)], kphi [kN/m^(n+2)] from
        ``k_i = kc/b_i + kphi`` (eq. (2-2) in [1]_) at a common n, with 95 %
        confidence intervals when there are at least 3 tests.  With one plate
        size: kc and kphi None and listed in ``undetermined``.

    Notes
    -----
    Stage 1 fits one n shared by all tests (one k per test) with the chosen
    method; stage 2 regresses the per-test k on 1/b (ordinary least squares,
    one point per test).  The intervals come from stage 2 (scatter between
    tests) and, for n, from the spread of the per-test exponents.
    """
    _check_method(method)
    tests = list(tests)
    if not tests:
        raise ValueError("no plate tests to fit")
    dropped = [note for t in tests if (note := left_out(of_type(t, PlateTest))) is not None]
    branches = [_branch(t) for t in tests]
    per_test = [fit_plate_test(t, method) for t in tests]
    m = len(tests)

    # Stage 1: common n, one k per test (p_ij = k_i z_ij^n).
    z = np.concatenate([br[0] for br in branches])
    p = np.concatenate([br[1] for br in branches])
    g = np.concatenate([np.full(br[0].size, i) for i, br in enumerate(branches)])
    n, k = _fit_groups(z, p, g, m, method)

    b = np.array([t.b for t in tests], dtype=float)
    # plate sizes equal to 1e-9 relative are one size (values read from files)
    if np.unique(np.round(np.log(b) * 1e9)).size < 2:
        split: dict[str, Any] = dict(
            kc=None, kphi=None, kc_ci=None, kphi_ci=None, undetermined=["kc", "kphi"],
            notes=["one plate size: kc and kphi cannot be separated (k = kc/b + kphi); "
                   "k and n are given per test"],
            ci_note="the interval of n needs at least 3 tests" if m < 3 else None,
        )  # fmt: skip
    else:
        split = _split_k(k, b)
    split["notes"] = [*split["notes"], *dropped]
    return PlatesFit(
        n=n, n_ci=_n_interval(n, per_test), tests=per_test, method=method,
        k_common=[float(v) for v in k], **split,
    )  # fmt: skip


def _n_interval(n: float, per_test: list[PlateFit]) -> tuple[float, float] | None:
    """95 % interval of n from the spread of the per-test exponents (t, m-1 dof; m >= 3)."""
    m = len(per_test)
    if m < 3:
        return None
    n_i = np.array([f.n for f in per_test])
    half = stats.t.ppf(0.975, m - 1) * n_i.std(ddof=1) / math.sqrt(m)
    return (n - half, n + half)


def _split_k(k: np.ndarray, b: np.ndarray) -> dict[str, Any]:
    """Stage 2: k_i = kc (1/b_i) + kphi (eq. (2-2)) by :func:`line_fit`; the PlatesFit fields."""
    coef, half = line_fit(np.column_stack([1.0 / b, np.ones(k.size)]), k)
    kc, kphi = float(coef[0]), float(coef[1])
    out: dict[str, Any] = dict(kc=kc, kphi=kphi, kc_ci=None, kphi_ci=None, undetermined=[])
    if half is not None:
        out["kc_ci"] = (kc - half[0], kc + half[0])
        out["kphi_ci"] = (kphi - half[1], kphi + half[1])
    out["ci_note"] = _CI_NOTE if half is None else None
    out["notes"] = []
    if kc < 0:
        out["notes"].append(f"kc = {kc:.4g} < 0: k grows with plate size in these tests")
    if kphi < 0:
        out["notes"].append(f"kphi = {kphi:.4g} < 0")
    return out

"""Priors of the posterior over (kc, kphi, n, cc, phic): the bounds box or a calibration.

``"bounds"``: uniform over the search box of :class:`Bounds`, with the values a
calibration holds held (phic, cc pinned in the box; kc = ratio kphi); a
calibration as a prior (:class:`~terracone.inverse.problem.CalibrationPrior`):
normal priors of phic, cc and ln(kc/kphi) around the calibration's values, n
uniform.  :meth:`Prior.of` builds the prior a
:class:`~terracone.inverse.problem.Problem` states.  The densities:
``docs/uncertainty.md`` (Priors).  Used by
:func:`terracone.inverse.uncertainty.posterior.posterior`.

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 3.3.1 and Table 4-1.
"""

from __future__ import annotations

import math

import numpy as np

from terracone.inverse.bounds import Bounds
from terracone.inverse.problem import CalibrationPrior, Problem

__all__ = ["PARAM_NAMES", "Prior"]

#: Order of the columns of :attr:`PosteriorResult.samples` (SI).
PARAM_NAMES = ("kc", "kphi", "n", "cc", "phic_deg")


class Prior:
    """Prior density and sampler over (kc, kphi, n, cc, phic), SI.

    Parameters
    ----------
    bounds : Bounds
        The support (a pinned parameter, LO = HI, is held).
    cal : CalibrationPrior, optional
        A calibration as the prior's centre.
    ratio : float, optional
        kc/kphi held [m] (kc = ratio kphi; not with ``cal``).
    """

    def __init__(
        self, bounds: Bounds, cal: CalibrationPrior | None, ratio: float | None = None
    ) -> None:
        if cal is not None and ratio is not None:
            raise ValueError("a held kc/kphi ratio and a calibration prior exclude each other")
        self.b = bounds
        self.cal = cal
        self.held_ratio = None if ratio is None else float(ratio)
        self._si = bounds.kc_units == "si" and bounds.kphi_units == "si"
        c = cal.calibration if cal is not None else None
        self.kc_fixed = (
            bounds.kc[0] == bounds.kc[1] or (c is not None and c.kc <= 0) or ratio is not None
        )
        self.kphi_fixed = bounds.kphi[0] == bounds.kphi[1] or (c is not None and c.kphi <= 0)
        self.n_fixed = bounds.n[0] == bounds.n[1]
        self.cc_fixed = bounds.cc[0] == bounds.cc[1] or (cal is not None and cal.cc_width == 0)
        self.phic_fixed = bounds.phic_deg[0] == bounds.phic_deg[1] or (
            cal is not None and cal.phic_sd == 0
        )
        self.ratio = (
            c is not None and not self.kc_fixed and not self.kphi_fixed and c.kc > 0 and c.kphi > 0
        )
        if self.ratio:
            self.log_q0 = math.log(c.kc / c.kphi)

        def value(fixed: bool, b: tuple[float, float], name: str) -> float:
            """Value of a fixed cc or phic: the calibration's (sd 0) in the bounds, else LO."""
            if c is not None and fixed and b[0] != b[1]:
                return float(np.clip(getattr(c, name), *b))
            return float(b[0])

        self.cc_value = value(self.cc_fixed, bounds.cc, "cc")
        self.phic_value = value(self.phic_fixed, bounds.phic_deg, "phic_deg")
        self.n_grid: np.ndarray | None = None
        self.n_logw: np.ndarray | None = None
        if c is not None and c.kc <= 0 and bounds.kc[0] > 0:
            raise ValueError("the calibration has kc = 0 but the kc bounds exclude 0")
        if c is not None and c.kphi <= 0 and bounds.kphi[0] > 0:
            raise ValueError("the calibration has kphi = 0 but the kphi bounds exclude 0")

    @classmethod
    def of(cls, problem: Problem) -> Prior:
        """The prior ``problem`` states: the held box and ratio, or around its centre."""
        if problem.centre is not None:
            return cls(problem.bounds, problem.centre)
        return cls(problem.fit_bounds, None, ratio=problem.ratio)

    def describe(self) -> str:
        if self.cal is None:
            return "bounds"
        return f"calibration:{self.cal.calibration.terrain}"

    def set_reference(self, grid: np.ndarray, logw: np.ndarray) -> None:
        """Weight the bounds prior by sqrt(det G(n)) (``logw`` on ``grid``; module docstring).

        The joint density becomes sqrt(det G(n)) in SI (kc, kphi) inside the
        box (no longer normalised per n), which does not depend on the
        units the bounds were given in.
        """
        if self.cal is not None or self.n_fixed or self.held_ratio is not None:
            return
        ok = np.isfinite(logw)
        if not ok.any():
            return
        self.n_grid = np.asarray(grid, float)
        self.n_logw = np.where(ok, logw, np.min(logw[ok]) - 50.0) - np.max(logw[ok])

    def n_log_weight(self, n: np.ndarray) -> np.ndarray:
        """log sqrt(det G(n)) up to a constant (0 without the reference weight)."""
        if self.n_logw is None:
            return np.zeros(np.shape(n))
        return np.interp(n, self.n_grid, self.n_logw)

    def _sample_n(self, rng: np.random.Generator, m: int) -> np.ndarray:
        b = self.b
        if self.n_logw is None:
            return rng.uniform(*b.n, m)
        g = np.linspace(b.n[0], b.n[1], 2001)
        d = np.exp(self.n_log_weight(g))
        if not self.kc_fixed:
            lo, hi = b.kc_si(g)
            d = d * (hi - lo)
        if not self.kphi_fixed:
            lo, hi = b.kphi_si(g)
            d = d * (hi - lo)
        cdf = np.concatenate([[0.0], np.cumsum(0.5 * (d[1:] + d[:-1]) * np.diff(g))])
        return np.interp(rng.uniform(0, cdf[-1], m), cdf, g)

    def kphi_range(self, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of kphi [SI] at n; with a held ratio, where kc = ratio kphi is in its box too."""
        lo, hi = self.b.kphi_si(n)
        if self.held_ratio is not None and self.held_ratio > 0:
            kc_lo, kc_hi = self.b.kc_si(n)
            lo = np.maximum(lo, kc_lo / self.held_ratio)
            hi = np.maximum(np.minimum(hi, kc_hi / self.held_ratio), lo)
        return lo, hi

    def fixed_value(self, j: int, n: np.ndarray) -> np.ndarray:
        """kc (j = 0) or kphi (j = 1) where fixed [SI] at n: 0 (a calibration's 0) or LO.

        A kc held by a ratio is not a value of n alone: :class:`SamplerCoordinates`
        sets it from kphi.
        """
        name = ("kc", "kphi")[j]
        if self.cal is not None and getattr(self.cal.calibration, name) <= 0:
            return np.zeros_like(n)
        return getattr(self.b, f"{name}_si")(n)[0]

    def logpdf(self, kc, kphi, n, cc, phic_deg) -> np.ndarray:
        """Log prior density (up to a constant) of arrays of parameters."""
        b = self.b
        lp = np.zeros(np.shape(n))
        inside = np.ones(np.shape(n), bool)
        if not self.n_fixed:
            inside &= (n >= b.n[0]) & (n <= b.n[1])
        if self._si:
            kc_lo, kc_hi = b.kc
            kp_lo, kp_hi = b.kphi
        else:
            nn = np.clip(n, b.n[0], b.n[1])
            kc_lo, kc_hi = b.kc_si(nn)
            kp_lo, kp_hi = b.kphi_si(nn)
        if not self.kc_fixed:
            inside &= (kc >= kc_lo) & (kc <= kc_hi)
        ref = self.n_logw is not None
        if ref:
            lp = lp + self.n_log_weight(n)
        if self.held_ratio is not None:  # kc = ratio kphi: in its box; kphi uniform where both are
            inside &= (kc >= kc_lo) & (kc <= kc_hi)
            kp_lo, kp_hi = self.kphi_range(np.clip(n, b.n[0], b.n[1]))
        if not self.kphi_fixed:
            inside &= (kphi >= kp_lo) & (kphi <= kp_hi)
            if not ref:
                lp = lp - np.log(kp_hi - kp_lo)
        if not self.cc_fixed:
            inside &= (cc >= b.cc[0]) & (cc <= b.cc[1])
        if not self.phic_fixed:
            inside &= (phic_deg >= b.phic_deg[0]) & (phic_deg <= b.phic_deg[1])
        c = self.cal
        if self.ratio:  # a calibration's ratio prior (ref is off with a calibration)
            with np.errstate(divide="ignore", invalid="ignore"):
                z = (np.log(kc) - np.log(kphi) - self.log_q0) / c.ratio_log_sd
                lp += -0.5 * z * z - np.log(kc)
            inside &= (kc > 0) & (kphi > 0)
        elif not self.kc_fixed and not ref:
            lp = lp - np.log(kc_hi - kc_lo)
        if c is not None and not self.cc_fixed:
            z = (cc - c.calibration.cc) / c.cc_width
            lp += -0.5 * z * z
        if c is not None and not self.phic_fixed:
            z = (phic_deg - c.calibration.phic_deg) / c.phic_sd
            lp += -0.5 * z * z
        return np.where(inside & np.isfinite(lp), lp, -np.inf)

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """Draws (size, 5) from the prior, SI."""
        b = self.b
        out = np.empty((0, 5))
        for _ in range(200):
            m = 2 * size
            n = np.full(m, b.n[0]) if self.n_fixed else self._sample_n(rng, m)
            kphi = self.fixed_value(1, n) if self.kphi_fixed else rng.uniform(*self.kphi_range(n))
            if self.held_ratio is not None:
                kc = self.held_ratio * kphi
            elif self.ratio:
                q = np.exp(self.log_q0 + self.cal.ratio_log_sd * rng.standard_normal(m))
                kc = q * kphi
            elif self.kc_fixed:
                kc = self.fixed_value(0, n)
            else:
                kc = rng.uniform(*b.kc_si(n))
            if self.cc_fixed:
                cc = np.full(m, self.cc_value)
            elif self.cal is None:
                cc = rng.uniform(*b.cc, m)
            else:
                cc = self.cal.calibration.cc + self.cal.cc_width * rng.standard_normal(m)
            if self.phic_fixed:
                phic = np.full(m, self.phic_value)
            elif self.cal is None:
                phic = rng.uniform(*b.phic_deg, m)
            else:
                phic = self.cal.calibration.phic_deg + self.cal.phic_sd * rng.standard_normal(m)
            x = np.stack([kc, kphi, n, cc, phic], axis=1)
            ok = np.isfinite(self.logpdf(kc, kphi, n, cc, phic))
            out = np.concatenate([out, x[ok]])
            if out.shape[0] >= size:
                return out[:size]
        raise ValueError("the prior has (almost) no mass inside the bounds")

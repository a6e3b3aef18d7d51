"""Search bounds of the prediction and learning processes.

cc and K_cone bounds are stored in SI.  The SI value of a bound on kc or kphi
depends on n when it was given in US customary units (their units carry n),
so those bounds keep the unit system they were given in and are converted
for each n the solvers visit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from terracone.physics import units as u
from terracone.resultunits import from_si

__all__ = ["Bounds"]

#: Key of ``--bounds`` (a CLI contract) -> field of :class:`Bounds`; the
#: Python names are accepted as keys too.
KEYS = {"kc": "kc", "kphi": "kphi", "n": "n", "cc": "cc", "phic": "phic_deg", "Kc": "K_cone"}
_KEY_OF = {f: k for k, f in KEYS.items()}


@dataclass(frozen=True)
class Bounds:
    """Lower and upper bounds of the searched parameters (defaults in SI).

    Attributes
    ----------
    kc, kphi : (float, float)
        In ``kc_units`` / ``kphi_units`` ([kN/m^(n+1)], [kN/m^(n+2)] for si).
    n : (float, float)
    cc : (float, float)
        [kPa]
    phic_deg : (float, float)
        [deg] (``--bounds`` key ``phic``)
    K_cone : (float, float)
        [m], used only when K_cone is fitted (``--bounds`` key ``Kc``).
    """

    kc: tuple[float, float] = (0.0, 1000.0)
    kphi: tuple[float, float] = (0.0, 20000.0)
    n: tuple[float, float] = (0.05, 2.0)
    cc: tuple[float, float] = (0.0, 100.0)
    phic_deg: tuple[float, float] = (0.0, 45.0)
    K_cone: tuple[float, float] = (1e-4, 0.1)
    kc_units: str = "si"
    kphi_units: str = "si"

    def __post_init__(self) -> None:
        u.check_system(self.kc_units)
        u.check_system(self.kphi_units)
        for key, name in KEYS.items():
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
                raise ValueError(f"bounds of {key}: need LO <= HI (got {lo}:{hi})")
        if self.n[0] <= 0 or self.n[1] > 3:
            raise ValueError("bounds of n must lie in (0, 3]")
        if min(self.kc[0], self.kphi[0], self.cc[0]) < 0:
            raise ValueError("bounds of kc, kphi and cc must be >= 0")
        if self.phic_deg[0] < 0 or self.phic_deg[1] >= 90:
            raise ValueError("bounds of phic must lie in [0, 90) deg")
        if self.K_cone[0] <= 0:
            raise ValueError("bounds of Kc must be > 0")

    @classmethod
    def parse(cls, text: str | None, units: str = "si") -> Bounds:
        """Parse ``"kc=LO:HI,kphi=LO:HI,n=LO:HI,cc=LO:HI,phic=LO:HI,Kc=LO:HI"`` in ``units``.

        The keys are those of the CLI's ``--bounds`` (:data:`KEYS`) or the
        field names.  Parameters not named keep their (SI-defined) defaults.
        """
        units = u.check_system(units)
        values: dict[str, object] = {}
        for part in (text or "").split(","):
            part = part.strip()
            if not part:
                continue
            if "=" not in part or ":" not in part:
                raise ValueError(f"bounds: expected NAME=LO:HI, got {part!r}")
            key, rng = (s.strip() for s in part.split("=", 1))
            name = KEYS.get(key, key)
            if name not in _KEY_OF:
                raise ValueError(f"bounds: unknown parameter {key!r} (use {', '.join(KEYS)})")
            lo_s, hi_s = rng.split(":", 1)
            try:
                lo, hi = float(lo_s), float(hi_s)
            except ValueError as exc:
                raise ValueError(f"bounds: {part!r} is not NAME=LO:HI with numbers") from exc
            if name == "cc":
                lo, hi = (float(v) for v in u.pressure_to_si((lo, hi), units))
            elif name == "K_cone":
                lo, hi = (float(v) for v in u.length_to_si((lo, hi), units))
            elif name in ("kc", "kphi"):
                values[f"{name}_units"] = units
            values[name] = (lo, hi)
        return replace(cls(), **values)

    def kc_si(self, n: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of kc in kN/m^(n+1) at exponent n."""
        n = np.asarray(n, dtype=float)
        return tuple(u.kc_to_si(v + 0 * n, n, self.kc_units) for v in self.kc)

    def kphi_si(self, n: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of kphi in kN/m^(n+2) at exponent n."""
        n = np.asarray(n, dtype=float)
        return tuple(u.kphi_to_si(v + 0 * n, n, self.kphi_units) for v in self.kphi)

    def fixed(self, **values: float) -> Bounds:
        """Copy with some of n, cc [kPa], phic_deg [deg] pinned (LO = HI)."""
        return replace(self, **{k: (float(v), float(v)) for k, v in values.items()})

    def as_dict(self, units: str = "si") -> dict[str, object]:
        """Bounds for reports: cc in ``units``, kc/kphi in the units they were given in."""
        return {
            "kc": list(self.kc),
            "kc_units": u.kc_unit(self.kc_units),
            "kphi": list(self.kphi),
            "kphi_units": u.kphi_unit(self.kphi_units),
            "n": list(self.n),
            "cc": from_si(self.cc, "pressure", units),
            "phic_deg": list(self.phic_deg),
        }

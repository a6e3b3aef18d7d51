"""Agreement between measured and predicted curves (Tables 4-2 and 4-4 of [1]_).

References
----------
.. [1] Huang, W., Wong, J.Y., Preston-Thomas, J., Jayakumar, P. Predicting
   terrain parameters for physics-based vehicle mobility models from cone
   index data. Section 4, Tables 4-2 and 4-4.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Agreement", "agreement", "pearson_r", "rmsd", "cv"]


def pearson_r(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Coefficient of correlation R (Pearson) [-]; NaN if either is constant."""
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    dm, dp = m - m.mean(), p - p.mean()
    den = np.sqrt(np.sum(dm * dm) * np.sum(dp * dp))
    return float(np.sum(dm * dp) / den) if den > 0 else float("nan")


def rmsd(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Root mean square deviation, in the unit of the data."""
    d = np.asarray(predicted, dtype=float) - np.asarray(measured, dtype=float)
    return float(np.sqrt(np.mean(d * d)))


def cv(measured: ArrayLike, predicted: ArrayLike) -> float:
    """Coefficient of variation CV = RMSD / mean(measured) [-]."""
    return rmsd(measured, predicted) / float(np.mean(np.asarray(measured, dtype=float)))


@dataclass(frozen=True)
class Agreement:
    """R, R^2, RMSD and CV of Tables 4-2 and 4-4 (RMSD in the data's unit)."""

    R: float
    R2: float
    RMSD: float
    CV: float
    n_points: int

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def agreement(measured: ArrayLike, predicted: ArrayLike) -> Agreement:
    """R, R^2 = R*R, RMSD and CV between measured and predicted values."""
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    if m.shape != p.shape or m.size < 2:
        raise ValueError("measured and predicted must have one shape and >= 2 points")
    r = pearson_r(m, p)
    return Agreement(R=r, R2=r * r, RMSD=rmsd(m, p), CV=cv(m, p), n_points=int(m.size))

"""R, R^2, RMSD and CV (Tables 4-2 and 4-4) against hand computations."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from terracone import agreement
from terracone.physics.metrics import cv, pearson_r, rmsd


def test_hand_example():
    # measured m = 1, 2, 3, 4 (mean 2.5); predicted p = 1.5, 1.5, 3.5, 4.5 (mean 2.75)
    # dm = -1.5, -0.5, 0.5, 1.5 ; dp = -1.25, -1.25, 0.75, 1.75
    # sum dm dp = 1.875 + 0.625 + 0.375 + 2.625 = 5.5
    # sum dm^2 = 5 ; sum dp^2 = 1.5625 + 1.5625 + 0.5625 + 3.0625 = 6.75
    # R = 5.5 / sqrt(33.75) ; R^2 = 30.25 / 33.75 = 121/135
    # p - m = 0.5, -0.5, 0.5, 0.5 -> RMSD = 0.5 ; CV = 0.5 / 2.5 = 0.2
    a = agreement([1.0, 2.0, 3.0, 4.0], [1.5, 1.5, 3.5, 4.5])
    assert a.R == pytest.approx(5.5 / math.sqrt(33.75), rel=1e-15)
    assert a.R == pytest.approx(0.9467292624062573, rel=1e-15)
    assert a.R2 == pytest.approx(121.0 / 135.0, rel=1e-15)
    assert a.RMSD == pytest.approx(0.5, rel=1e-15)
    assert a.CV == pytest.approx(0.2, rel=1e-15)
    assert a.n_points == 4
    assert a.as_dict()["R2"] == a.R2


def test_perfect_and_anticorrelated():
    m = [10.0, 20.0, 40.0]
    a = agreement(m, m)
    assert a.R == pytest.approx(1.0, rel=1e-15) and a.RMSD == 0.0 and a.CV == 0.0
    # p = 70 - m: R = -1, R^2 = 1; p - m = 50, 30, -10 -> RMSD = sqrt(3500/3)
    b = agreement(m, [60.0, 50.0, 30.0])
    assert b.R == pytest.approx(-1.0, rel=1e-15)
    assert b.R2 == pytest.approx(1.0, rel=1e-15)
    assert b.RMSD == pytest.approx(math.sqrt(3500.0 / 3.0), rel=1e-15)
    assert b.CV == pytest.approx(math.sqrt(3500.0 / 3.0) / (70.0 / 3.0), rel=1e-15)


def test_against_python_statistics():
    # plate pressures (kPa), a realistic-looking pair of curves
    m = [0.0, 105.0, 190.5, 262.0, 331.25, 390.0, 447.5]
    p = [0.0, 120.2, 201.0, 259.9, 318.0, 371.4, 420.6]
    r_ref = statistics.correlation(m, p)
    rmsd_ref = math.sqrt(statistics.fmean((pi - mi) ** 2 for mi, pi in zip(m, p)))
    a = agreement(m, p)
    assert a.R == pytest.approx(r_ref, rel=1e-13)
    assert a.R2 == pytest.approx(r_ref**2, rel=1e-13)
    assert a.RMSD == pytest.approx(rmsd_ref, rel=1e-13)
    assert a.CV == pytest.approx(rmsd_ref / statistics.fmean(m), rel=1e-13)
    assert pearson_r(m, p) == a.R and rmsd(m, p) == a.RMSD and cv(m, p) == a.CV
    # arrays work like lists
    b = agreement(np.array(m), np.array(p))
    assert b == a


def test_constant_series_gives_nan_r():
    a = agreement([3.0, 3.0, 3.0], [1.0, 2.0, 3.0])
    assert math.isnan(a.R) and math.isnan(a.R2)
    # RMSD: differences -2, -1, 0 -> sqrt(5/3); CV = that / 3
    assert a.RMSD == pytest.approx(math.sqrt(5.0 / 3.0), rel=1e-15)
    assert a.CV == pytest.approx(math.sqrt(5.0 / 3.0) / 3.0, rel=1e-15)


@pytest.mark.parametrize(
    "m, p",
    [([1.0, 2.0, 3.0], [1.0, 2.0]), ([1.0], [1.0]), ([], [])],
)
def test_errors(m, p):
    with pytest.raises(ValueError, match="measured and predicted"):
        agreement(m, p)

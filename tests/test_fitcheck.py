"""Lack-of-fit diagnostics (terracone.physics.metrics.check_fit) on hand-built cases.

Every expected value below is counted or computed by hand in the comments:
run lengths, the Wald-Wolfowitz runs statistic, 3-point running medians and
the depths between which the measured CI falls.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from terracone.physics.metrics import FitCheck, check_fit, check_fit_fast


def _rising(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Depths 0, 2.5, ... cm [m] and a steadily rising CI 100, 200, ... kPa."""
    z = np.arange(n) * 0.025
    y = 100.0 * (1.0 + np.arange(n))
    return z, y


def test_perfect_fit_is_not_flagged():
    z, y = _rising(12)
    fc = check_fit(z, y, y.copy())
    assert isinstance(fc, FitCheck)
    assert fc.lack_of_fit is None
    assert fc.r2 == 1.0
    # every residual is zero: no signs, no runs, no runs statistic
    assert fc.longest_run == 0
    assert math.isnan(fc.runs_z)


def test_fit_exact_to_rounding_is_not_flagged():
    z, y = _rising(20)
    # the model equals the data to a few ulps, in two blocks of one sign each
    model = y * (1.0 + 1e-13 * np.array([1] * 10 + [-1] * 10))
    fc = check_fit(z, y, model)
    assert fc.r2 == pytest.approx(1.0, abs=1e-12)
    assert fc.lack_of_fit is None


def test_alternating_residuals_are_not_a_runs_flag():
    z, y = _rising(20)
    # residual model - measured = +5, -5, +5, ... : 20 runs of length 1
    model = y + 5.0 * (-1.0) ** np.arange(20)
    fc = check_fit(z, y, model)
    assert fc.longest_run == 1
    # n+ = n- = 10: mu = 2*10*10/20 + 1 = 11, var = 10*9/19; runs = 20
    assert fc.runs_z == pytest.approx((20 - 11) / math.sqrt(90 / 19), rel=1e-12)
    assert fc.runs_z > 0
    assert fc.lack_of_fit is None


def test_residuals_in_long_blocks_are_flagged_with_the_hand_counted_run():
    z, y = _rising(20)
    # signs: 7 positive, 6 negative, 7 positive (residuals small against the trend)
    signs = np.array([1] * 7 + [-1] * 6 + [1] * 7, dtype=float)
    model = y + 3.0 * signs
    fc = check_fit(z, y, model)
    # longest block: 7 (both + blocks have 7 points)
    assert fc.longest_run == 7
    # runs = 3; n+ = 14, n- = 6, N = 20
    # mu = 2*14*6/20 + 1 = 9.4 ; var = (mu-1)(mu-2)/(N-1) = 8.4*7.4/19
    z_hand = (3 - 9.4) / math.sqrt(8.4 * 7.4 / 19)
    assert z_hand == pytest.approx(-3.538, abs=1e-3)
    assert fc.runs_z == pytest.approx(z_hand, rel=1e-12)
    assert fc.lack_of_fit is not None
    assert "residuals keep one sign over long stretches" in fc.lack_of_fit
    assert "longest run 7 of 20 points" in fc.lack_of_fit
    # R2 stays high (the residuals are small): the only reason is the runs test
    assert fc.r2 > 0.99
    assert "R2 of the CI fit" not in fc.lack_of_fit
    assert "falls with depth" not in fc.lack_of_fit


def test_runs_test_needs_ten_points():
    # 9 points in two blocks (+5, -4): runs = 2, mu = 2*5*4/9 + 1 = 49/9,
    # var = (40/9)(31/9)/8; z = (2 - 49/9)/sqrt(var) = -2.49 (> -3 anyway),
    # and with fewer than 10 points the test is not applied at all
    z, y = _rising(9)
    model = y + 3.0 * np.array([1] * 5 + [-1] * 4, dtype=float)
    fc = check_fit(z, y, model)
    assert fc.longest_run == 5
    mu = 49 / 9
    assert fc.runs_z == pytest.approx((2 - mu) / math.sqrt((mu - 1) * (mu - 2) / 8), rel=1e-12)
    assert fc.lack_of_fit is None


# measured CI that rises to a peak at 12.5-15 cm, then falls (tillage pan above a softer layer)
_Z_FALL = np.arange(13) * 0.025  # 0, 2.5, ..., 30 cm
_Y_FALL = np.array([100, 300, 500, 700, 900, 1000, 950, 800, 700, 650, 700, 750, 800], float)
# 3-point running median (ends kept):
#   100, 300, 500, 700, 900, 950, 950, 800, 700, 700, 700, 750, 800
# running peak: 100, 300, 500, 700, 900, 950 (from index 5 on)
# drop below the peak: index 8 (20 cm) first reaches (950 - 700)/950 = 26.3 %
# the peak of the smoothed curve is first reached at index 5 (12.5 cm)


def test_falling_ci_is_flagged_between_the_hand_found_depths():
    fc = check_fit(_Z_FALL, _Y_FALL, _Y_FALL.copy())  # a perfect model: only the drop flags
    assert fc.lack_of_fit is not None
    assert "CI falls with depth between 12.5 and 20 cm" in fc.lack_of_fit
    assert "(26% below its peak)" in fc.lack_of_fit
    assert "R2" not in fc.lack_of_fit and "residuals" not in fc.lack_of_fit


def test_monotone_model_false_disables_the_falling_check():
    fc = check_fit(_Z_FALL, _Y_FALL, _Y_FALL.copy(), monotone_model=False)
    assert fc.lack_of_fit is None


def test_drop_threshold_and_median_smoothing():
    z = np.arange(10) * 0.025
    # falls by 10 % of its peak (1000 -> 900): below the 15 % threshold
    y = np.array([200, 400, 600, 800, 1000, 1000, 900, 900, 900, 950], float)
    assert check_fit(z, y, y.copy()).lack_of_fit is None
    # the same with max_drop = 5 %: flagged, between 10 cm (first peak) and 15 cm
    # median: 200, 400, 600, 800, 1000, 1000, 900, 900, 900, 950 -> drop 10 % at index 6
    fc = check_fit(z, y, y.copy(), max_drop=0.05)
    assert fc.lack_of_fit is not None
    assert "between 10 and 15 cm" in fc.lack_of_fit
    # a single-reading spike (3000 at 7.5 cm) is removed by the 3-point median:
    # median = 200, 400, 600, 800, 900, 900, 1000, 1100, 1200, 1300: no fall
    spike = np.array([200, 400, 600, 3000, 800, 900, 1000, 1100, 1200, 1300], float)
    assert check_fit(z, spike, spike.copy()).lack_of_fit is None


def test_low_r2_at_noise_level_rmsd_is_not_flagged():
    # a flat profile around 1000 kPa, +-20 kPa alternating, fitted by its mean:
    # SSE = SST, so R2 = 0; but the RMSD is 20 kPa = 2 % of the mean (< 5 %)
    z = np.arange(20) * 0.02
    y = 1000.0 + 20.0 * (-1.0) ** np.arange(20)
    model = np.full(20, 1000.0)
    fc = check_fit(z, y, model)
    assert fc.r2 == pytest.approx(0.0, abs=1e-12)
    assert fc.r2 < 0.8
    assert fc.lack_of_fit is None


def test_low_r2_with_large_rmsd_is_flagged():
    # +-60 kPa around 1000: R2 = 0 and RMSD = 60 kPa = 6 % of the mean (> 5 %);
    # the 3-point median alternates 940/1060, a drop of 120/1060 = 11 % (< 15 %)
    z = np.arange(20) * 0.02
    y = 1000.0 + 60.0 * (-1.0) ** np.arange(20)
    fc = check_fit(z, y, np.full(20, 1000.0))
    assert fc.lack_of_fit is not None
    assert "R2 of the CI fit is 0.00 (below 0.8) with RMSD 6% of the mean CI" in fc.lack_of_fit
    assert "falls with depth" not in fc.lack_of_fit
    assert "residuals keep one sign" not in fc.lack_of_fit
    # raising min_cv above 6 % clears it
    assert check_fit(z, y, np.full(20, 1000.0), min_cv=0.07).lack_of_fit is None


def test_several_reasons_are_joined():
    # the falling profile fitted by a flat line at its mean (688.5 kPa): SSE = SST so
    # R2 = 0, with an RMSD far above 5 % of the mean, and the fall found above
    model = np.full(_Y_FALL.size, _Y_FALL.mean())
    fc = check_fit(_Z_FALL, _Y_FALL, model)
    assert fc.r2 == pytest.approx(0.0, abs=1e-12)
    assert fc.lack_of_fit is not None
    assert "R2 of the CI fit" in fc.lack_of_fit
    assert "CI falls with depth between 12.5 and 20 cm" in fc.lack_of_fit
    assert "; " in fc.lack_of_fit


@pytest.mark.parametrize("seed", range(6))
def test_compiled_screen_equals_check_fit(seed):
    """check_fit_fast (the compiled fit_stats, or check_fit itself with TERRACONE_NUMBA=0)
    gives check_fit's numbers and verdict: good fits, noisy fits, layered and flat profiles."""
    rng = np.random.default_rng(seed)
    z = np.arange(30) * 0.01
    truth = 50.0 + 400.0 * z**0.8
    cases = {
        "good": (truth * (1 + 0.01 * rng.standard_normal(z.size)), truth),
        "runs": (truth + 40.0 * np.sin(z * 20), truth),  # residual signs in long runs
        "layered": (np.where(z < 0.15, truth, 0.5 * truth), truth),  # CI falls by half
        "flat": (np.full(z.size, 100.0) + rng.standard_normal(z.size), np.full(z.size, 100.0)),
    }
    for name, (y, m) in cases.items():
        slow, fast = check_fit(z, y, m), check_fit_fast(z, y, m)
        assert fast.lack_of_fit == slow.lack_of_fit, name
        assert fast.longest_run == slow.longest_run, name
        np.testing.assert_allclose(
            [fast.r2, fast.runs_z], [slow.r2, slow.runs_z], rtol=1e-12, err_msg=name
        )
    assert check_fit(z, *cases["layered"]).lack_of_fit is not None  # the cases can fail
    assert check_fit(z, *cases["good"]).lack_of_fit is None

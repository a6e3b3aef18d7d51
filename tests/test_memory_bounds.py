"""Long profiles never eat the machine (issue 33): each finding, a careless input and its safe output.

Findings, with what a profile of 100,000 readings did before:

* the layered search's tables and cells grow as Z^L (``--layers 2``: 5.4 GB at
  2,000 readings, all 24 GB at 100,000): a profile longer than
  :data:`terracone.inverse.layered.fit.MAX_DEPTHS` is now fitted on bins of
  consecutive readings, with a note, and its posterior samples the same bins;
* the AR(1) estimate of the posterior's noise model built N x N matrices
  ("Unable to allocate 74.5 GiB"): it is now exact in O(N) memory;
* the posterior's likelihood tabulates every reading over n (about 9 kB a
  reading) and visits every reading at each of its ~22,000 evaluations: a
  profile longer than :data:`~terracone.inverse.uncertainty.noise.POSTERIOR_MAX_POINTS`
  is sampled on bins, with a note.

The sizes here run in seconds; ``benchmarks/memory.py`` measures the peak
resident memory of ``predict --layers 2`` and ``--uncertainty`` at 1,000,
10,000 and 100,000 readings.
"""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.layered import fit_layered, layered_posterior
from terracone.inverse.layered.fit import MAX_DEPTHS, bin_profile, max_depths
from terracone.inverse.uncertainty.noise import (
    POSTERIOR_MAX_POINTS,
    RHO_MAX,
    ar1_noise,
    bin_readings,
    estimate_correlation,
)
from terracone.physics.cone import get_cone
from terracone.physics.layers import layered_cone_index

CONE = get_cone("asabe-small")
TOP = TerrainParameters(kc=40.0, kphi=7000.0, n=0.5, cc=3.0, phic_deg=45.0)
BOTTOM = TerrainParameters(kc=5.0, kphi=900.0, n=1.1, cc=1.0, phic_deg=45.0)


def long_profile(N: int, noise: float = 0.03, seed: int = 0) -> CIProfile:
    """N readings of a two-layer terrain (interface at 0.2 m) to 0.5 m, multiplicative noise."""
    z = np.linspace(0.0, 0.5, N)
    y = layered_cone_index(z, [TOP, BOTTOM], [0.2], cone=CONE)
    y = y * (1.0 + noise * np.random.default_rng(seed).standard_normal(N))
    return CIProfile("long", z, y, cone=CONE)


def test_bins_are_means_of_consecutive_readings():
    z, y = np.arange(10.0) / 100, np.arange(10.0) ** 2
    bz, by, k = bin_readings(z, y, 4)  # k = ceil(10 / 4) = 3: bins of 3, 3, 3, 1
    assert k == 3
    np.testing.assert_allclose(bz, [0.01, 0.04, 0.07, 0.09], rtol=1e-15)
    np.testing.assert_allclose(by, [5 / 3, 50 / 3, 149 / 3, 81.0], rtol=1e-15)
    same = bin_readings(z, y, 10)
    assert same[2] == 1 and same[0] is not None and np.array_equal(same[1], y)
    p = CIProfile("p", z, y, cone=CONE)
    assert bin_profile(p, 10) == (p, None)
    bp, note = bin_profile(p, 4)
    np.testing.assert_allclose(bp.depth, bz, rtol=1e-15)
    assert note.startswith("fitted on 4 depth bins of the 10 readings (means of 3 consecutive")


def test_max_depths_per_number_of_layers():
    assert [max_depths(L) for L in (1, 2, 3, 4)] == [400, 400, 200, 60]
    assert max_depths(5) == MAX_DEPTHS[4] // 2


def test_a_long_profile_is_fitted_on_bins_with_a_note():
    """2,000 readings took 5.4 GB with two layers; now the search takes 400 bins of 5."""
    prof = long_profile(2000)
    res = fit_layered(prof, layers=2)
    assert res.ok, res.error
    assert res.depth.size == max_depths(2) == 400 and res.ci_model.size == 400
    assert res.notes == [
        "fitted on 400 depth bins of the 2000 readings (means of 5 consecutive readings, "
        "about 1.25 mm apart): at most 400 depths are searched"
    ]
    assert abs(res.interfaces[0] - 0.2) < 0.01  # the bins still place the interface
    assert res.as_dict()["notes"] == res.notes
    short = fit_layered(long_profile(40), layers=2)
    assert short.ok and short.notes == [] and short.depth.size == 40


def test_the_layered_posterior_samples_the_fits_bins():
    prof = long_profile(1200)
    fit = fit_layered(prof, layers=2)
    post = layered_posterior(prof, fit, draws=200, burn=200, seed=1)
    lo, hi = post.intervals["interface_1"]
    assert lo <= fit.interfaces[0] <= hi  # the posterior around the fit on the same bins
    assert lo >= fit.depth[0] and hi <= fit.depth[-1]


def dense_absorption(Q: np.ndarray, z: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """tr(D M S M) / tr(M S M) with N x N matrices: the formula itself (O(N^2) memory)."""
    N = z.size
    M = np.eye(N) - Q @ Q.T
    lag = np.abs(z[:, None] - z[None, :]) / np.median(np.diff(z))
    out = []
    for rho in grid:
        S = rho**lag if rho > 0 else np.eye(N)
        MSM = M @ S @ M
        out.append(np.trace(MSM, offset=1) / np.trace(MSM))
    return np.array(out)


@pytest.mark.parametrize("N", [6, 25, 120])
def test_the_ar1_correction_equals_the_dense_formula(N):
    from terracone.inverse.uncertainty import noise

    rng = np.random.default_rng(N)
    z = np.sort(rng.uniform(0.0, 0.6, N))  # irregular spacing
    X = np.column_stack([np.ones(N), z, np.sqrt(z), np.exp(-5 * z)])
    Q = np.linalg.qr(X)[0]
    grid = np.linspace(0.0, RHO_MAX, 96)
    got = noise._absorbed_lag1(Q, np.diff(z) / np.median(np.diff(z)), grid)
    np.testing.assert_allclose(got, dense_absorption(Q, z, grid), rtol=0, atol=1e-12)


def test_the_ar1_estimate_takes_linear_memory():
    """20,000 readings: the N x N matrices of before would take 3.2 GB each; now the
    recursions' arrays (a few rho values at a time, 8 MB each) and O(N) vectors."""
    N = 20_000
    z = np.linspace(0.0, 0.5, N)
    e = ar1_noise(z, 0.5, np.random.default_rng(2))
    design = np.column_stack([z, z**2])
    tracemalloc.start()
    try:
        rho, r1 = estimate_correlation(e, z, design=design)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6 + 500 * N, peak  # bytes (the dense formula: 8 N^2 per matrix)
    assert 0.47 < rho < 0.53 and abs(rho - r1) < 0.01  # 3 parameters absorb little of 20,000


def test_a_long_profile_is_sampled_on_bins_with_a_note():
    from terracone.inverse.predict import predict
    from terracone.inverse.uncertainty.posterior import posterior

    N = POSTERIOR_MAX_POINTS + 1
    nb = -(-N // 2)  # bins of 2, the last of 1
    prof = long_profile(N, noise=0.02)
    one = predict(prof)
    post = posterior(prof, start=one, seed=1, draws=400)
    assert post.noise.weights.size == nb
    assert (
        f"posterior from {nb} depth bins of the {N} readings (means of 2 "
        f"consecutive readings; at most {POSTERIOR_MAX_POINTS} are sampled): sigma and rho are "
        "those of a bin's mean"
    ) in post.notes


def test_predict_on_a_long_file_keeps_going_and_says_why(tmp_path):
    """The CLI on a long profile: exit 0, the layered block and the posterior say they binned."""
    prof = long_profile(3000)
    path = tmp_path / "long.csv"
    rows = "\n".join(f"long,{a:.7f},{b:.4f}" for a, b in zip(prof.depth, prof.ci))
    path.write_text("profile,depth_m,ci_kpa\n" + rows + "\n")
    args = ["predict", str(path), "--cone", "asabe-small", "--layers", "3", "--json"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    lay = json.loads(res.output)["profiles"][0]["layered"]
    assert lay["status"] == "ok"
    assert lay["notes"][0].startswith("fitted on 200 depth bins of the 3000 readings (means of 15")
    assert len(lay["depth"]) == 200

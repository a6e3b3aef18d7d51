"""Posterior of a layered fit: the truth inside its intervals, and calibrated 90% intervals.

The coverage test draws 200 two-layer profiles from the posterior's own
prior (simulation-based calibration): a correct posterior's 90% intervals
then hold the truth with probability exactly 0.9, whatever the profile, so
the count of hits of each interface and n must lie in a binomial window
around 180 (both bounds asserted).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.stats import binom

from terracone import CIProfile, TerrainParameters
from terracone.cli import cli
from terracone.data import CI_MAX_KPA
from terracone.inverse.bounds import Bounds
from terracone.inverse.layered import fit_layered, layered_posterior
from terracone.inverse.uncertainty.posterior import LABELS
from terracone.io import write_ci_profiles
from terracone.physics.cone import get_cone
from terracone.physics.layers import layered_cone_index

TOP = TerrainParameters(50.0, 8000.0, 0.4, 5.0, 12.0)  # a strong top (a tillage pan)
BELOW = TerrainParameters(20.0, 1500.0, 1.0, 0.0, 12.0)
Z = np.linspace(0.0, 0.45, 19)


def profile(seed: int) -> CIProfile:
    ci = layered_cone_index(Z, [TOP, BELOW], [0.15], cone=get_cone("asabe-large"))
    noise = 1.0 + 0.03 * np.random.default_rng(seed).standard_normal(Z.size)
    return CIProfile(f"pan{seed}", Z, ci * noise)


@pytest.mark.parametrize("seed", [1, 2])
def test_truth_inside_the_intervals(seed):
    """The generating layers lie inside the posterior's 99% intervals, with no padding.

    One profile cannot check a 90% rate (it would fail one time in ten by
    chance per parameter); the 99% equal-tailed interval of the draws, which
    a calibrated posterior misses one time in a hundred, can.  The 90%
    intervals must lie inside them and be narrow enough to call n and the
    interface "determined".
    """
    p = profile(seed)
    post = layered_posterior(p, fit_layered(p), draws=1500, seed=seed)
    for name, truth in (("interface_1", 0.15), ("n_1", 0.4), ("n_2", 1.0)):
        col = post.samples[:, post.names.index(name)]
        lo99, hi99 = np.quantile(col, [0.005, 0.995])
        lo, hi = post.intervals[name]
        assert lo99 <= lo < hi <= hi99
        assert lo99 <= truth <= hi99, (name, lo99, hi99)
    lo, hi = post.intervals["interface_1"]
    assert hi - lo < 0.05
    for name in ("n_1", "interface_1"):
        assert post.identifiability[name] == "determined"
    # the deep layer's n: 12 points, 3 % noise: determined or weakly (a width near 0.25 of
    # the prior's), never left to the prior
    assert post.identifiability["n_2"] in LABELS[:2]
    assert post.undetermined == []
    assert set(post.identifiability.values()) <= set(LABELS)
    d = post.as_dict("us")
    assert d["identifiability"]["phic_deg"] == "set by prior"
    assert d["intervals"]["interface_1"][0] == pytest.approx(
        post.intervals["interface_1"][0] / 0.0254
    )


def test_cli_layers_with_uncertainty(tmp_path):
    write_ci_profiles(tmp_path / "pan.csv", [profile(3)])
    res = CliRunner().invoke(
        cli,
        [
            "predict",
            str(tmp_path / "pan.csv"),
            "--layers",
            "2",
            "--uncertainty",
            "--draws",
            "600",
            "--seed",
            "1",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    prof = json.loads(res.output)["profiles"][0]
    assert "intervals" in prof and "identifiability" in prof  # the one-layer posterior
    post = prof["layered"]["posterior"]
    assert set(post["intervals"]) >= {"n_1", "n_2", "interface_1"}
    assert prof["layered"]["preferred_layers"] == 2


# --- calibration: coverage of the 90% intervals over profiles drawn from the prior ----------

SMALL = get_cone("asabe-small")
ZC = np.arange(0.0, 0.4001, 0.025)  # an SC900 push to 40 cm
COVERAGE_PROFILES = 200


def generated(i: int) -> tuple[CIProfile, dict[str, float]]:
    """Profile i of the coverage test and its truth, drawn from the posterior's prior.

    Two layers: the interface uniform over the search space (two depth steps
    from the ends), each n uniform on the bounds, kc, kphi and cc uniform in
    the default box (phic 45 deg, held); Gaussian noise of a standard
    deviation log-uniform between 2 % and 10 % of the RMS cone index (the
    1/sigma prior is log-uniform).  A draw with a negative cone index, or one
    above :data:`terracone.data.CI_MAX_KPA` (refused as no soil), is drawn
    again: the event depends on the data only, so the posterior of the
    profiles kept, and its calibration, are unchanged.
    """
    rng = np.random.default_rng(1000 + i)
    b = Bounds()
    h = 0.025
    while True:
        D = rng.uniform(ZC[0] + 2 * h, ZC[-1] - 2 * h)
        layers = []
        for _ in range(2):
            kc, kphi, n, cc = (rng.uniform(*v) for v in (b.kc, b.kphi, b.n, b.cc))
            layers.append(TerrainParameters(kc=kc, kphi=kphi, n=n, cc=cc, phic_deg=45.0))
        ci = layered_cone_index(ZC, layers, [D], cone=SMALL)
        sigma = math.exp(rng.uniform(math.log(0.02), math.log(0.10))) * math.sqrt(np.mean(ci**2))
        y = ci + sigma * rng.standard_normal(ZC.size)
        if np.all(y >= 0) and np.all(y <= CI_MAX_KPA):  # what the reader accepts as soil
            break
    truth = {"interface_1": D, "n_1": layers[0].n, "n_2": layers[1].n}
    return CIProfile(f"gen{i}", ZC, y, cone=SMALL), truth


def coverage_run(count: int) -> dict[str, np.ndarray]:
    """Whether each 90% interval holds the truth, per parameter, for profiles 0..count-1 (the
    fit and posterior with their default settings)."""
    hits: dict[str, list[bool]] = {"interface_1": [], "n_1": [], "n_2": []}
    for i in range(count):
        prof, truth = generated(i)
        fit = fit_layered(prof, layers=2)
        post = layered_posterior(prof, fit, seed=i, phic_deg=45.0)
        for name, v in truth.items():
            lo, hi = post.intervals[name]
            hits[name].append(lo <= v <= hi)
    return {k: np.array(v) for k, v in hits.items()}


@pytest.fixture(scope="module")
def coverage() -> dict[str, np.ndarray]:
    """The heavy part, run once: 200 generated profiles, a fit and a posterior each."""
    return coverage_run(COVERAGE_PROFILES)


@pytest.mark.parametrize("name", ["interface_1", "n_1", "n_2"])
def test_90_percent_intervals_cover_90_percent(coverage, name):
    """Simulation-based calibration: with the truth drawn from the prior, a correct posterior's
    90% intervals hold it with probability 0.9; the count over 200 profiles must lie in the
    central 99.8% of Binomial(200, 0.9) (both bounds)."""
    k = int(coverage[name].sum())
    lo, hi = binom.ppf([0.001, 0.999], COVERAGE_PROFILES, 0.9)
    assert lo <= k <= hi, (name, k, COVERAGE_PROFILES, (lo, hi))

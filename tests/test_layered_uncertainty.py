"""Posterior of a layered fit: the generating layers lie inside the 90% intervals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from terracone import CIProfile, TerrainParameters
from terracone.cli import cli
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
    for name in ("n_1", "n_2", "interface_1"):
        assert post.identifiability[name] == "determined"
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

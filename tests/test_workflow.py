"""terracone.apps.workflow: what `terracone predict` prints, as one library call."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from terracone.apps.workflow import predict_profiles, sinkage_grid
from terracone.cli import cli
from terracone.io import read_ci_profiles

EXAMPLE = (
    Path(__file__).parents[1] / "terracone" / "data" / "example" / "lete_sand_synthetic_ci.csv"
)


def _same(a, b, path=""):
    """Equal documents, floats to 1e-12 relative, timings left out."""
    if isinstance(a, dict):
        keys = [k for k in a if k not in ("time_s", "cpu_s")]
        assert keys == [k for k in b if k not in ("time_s", "cpu_s")], path
        for k in keys:
            _same(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{path}[{i}]")
    elif isinstance(a, float):
        assert b == pytest.approx(a, rel=1e-12, abs=1e-300), path
    else:
        assert a == b, path


def test_the_library_call_writes_what_the_command_prints():
    r = CliRunner().invoke(
        cli, ["predict", str(EXAMPLE), "--plates", "2.5in,1.5in", "--units", "us", "--json"]
    )
    assert r.exit_code == 0, r.output
    printed = json.loads(r.output)
    run = predict_profiles(
        read_ci_profiles(EXAMPLE, on_error="collect"),
        plates=[0.0635, 0.0381],
        sinkage=sinkage_grid("us"),
    )
    doc = run.as_dict(
        "us", input=str(EXAMPLE), depth_ref=printed["settings"]["depth_ref"], depth_range=None
    )
    _same(doc, printed)


def test_plate_curves_are_bekker_by_hand():
    # RM0 plate pressure is Bekker's eq. (2-2): p = (kc / b + kphi) z^n, b the radius
    run = predict_profiles(read_ci_profiles(EXAMPLE)[:1], plates=[0.05])
    res = run.results[0]
    curve = res.plate_curves[0]
    p = res.params
    z = np.linspace(0.0, 0.05, 26)
    np.testing.assert_allclose(curve["sinkage"], z)
    np.testing.assert_allclose(curve["pressure"], (p.kc / 0.05 + p.kphi) * z**p.n, rtol=1e-12)
    assert curve["radius"] == 0.05


def test_a_bad_profile_is_reported_and_the_rest_fitted(tmp_path):
    f = tmp_path / "ci.csv"
    f.write_text("profile,depth_cm,ci_kpa\nA,0,100\nA,5,300\nA,10,500\nA,15,650\nB,0,100\nB,5,-3\n")
    run = predict_profiles(read_ci_profiles(f, on_error="collect"), plates=[0.05])
    status = {r.id: r.ok for r in run.results}
    assert status == {"A": True, "B": False}
    assert [r.id for r in run.results if r.plate_curves] == ["A"]
    err = next(r for r in run.results if r.id == "B").error
    assert "row 7" in str(err) and "ci_kpa" in str(err)


@pytest.mark.parametrize("units, top", [("si", 0.05), ("us", 0.0508)])
def test_sinkage_grid(units, top):
    s = sinkage_grid(units)
    assert s[0] == 0.0 and s[-1] == pytest.approx(top, rel=1e-15) and s.size == 26


def test_a_failing_posterior_is_recorded_on_its_profile_and_the_rest_goes_on():
    """attach_fits: a posterior that cannot run says why in lack_of_fit; the fit stays."""
    from terracone.apps.workflow import attach_fits
    from terracone.inverse import Bounds, predict_many
    from terracone.inverse.predict import RunSettings
    from terracone.inverse.problem import Problem

    profiles = read_ci_profiles(EXAMPLE)[:2]
    fixed = Bounds().fixed(kc=20.0, kphi=1500.0, n=0.8, cc=1.0, phic_deg=10.0)
    pb, s = Problem(bounds=fixed), RunSettings(uncertainty=True, draws=50)
    results = predict_many(profiles, pb, s)
    assert all(r.ok for r in results)
    attach_fits(results, profiles, pb, s)
    for r in results:
        assert r.ok and r.posterior is None
        assert "posterior failed: all parameters are fixed: nothing to sample" in r.lack_of_fit

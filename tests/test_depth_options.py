"""Depth reference (base or tip) and depth windows, on generated data with known truth.

The truth is a homogeneous terrain (kc = 30 kN/m^(n+1), kphi = 4000
kN/m^(n+2), n = 0.8, cc = 2 kPa, phic = 20 deg) and the asabe-large cone
(H = 37.8 mm).  The model's depth is that of the cone base (origin: the base
flush with the surface); a file of tip depths holds base depth + H.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.data import CIProfile
from terracone.inverse.predict import predict
from terracone.io import read_ci_profiles
from terracone.physics.cone import CONES, cone_index

CONE = CONES["asabe-large"]
H = CONE.height
TRUTH = dict(kc=30.0, kphi=4000.0, n=0.8, cc=2.0, phic_deg=20.0)
DATA = Path(__file__).parent / "data"


def _write_csv(path: Path, depth_cm, ci_kpa) -> None:
    lines = ["depth_cm,ci_kpa"]
    lines += [f"{float(d)!r},{float(c)!r}" for d, c in zip(depth_cm, ci_kpa)]
    path.write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------
# (a) depth reference
# ---------------------------------------------------------------------------

TIP_CM = np.arange(1.0, 46.0)  # tip depths 1 to 45 cm, every 1 cm
BASE = TIP_CM * 0.01 - H  # the base depths: the first three are partial penetrations


@pytest.fixture
def tip_file(tmp_path: Path) -> Path:
    ci = cone_index(BASE, cone=CONE, **TRUTH)
    path = tmp_path / "tip_depths.csv"
    _write_csv(path, TIP_CM, ci)
    return path


def test_generated_profile_includes_partial_penetration():
    # the tip is in the soil but the base is not yet: -H < base depth < 0
    partial = BASE[BASE < 0]
    assert partial.size == 3
    assert np.all(partial > -H)
    ci = cone_index(BASE, cone=CONE, **TRUTH)
    assert np.all(ci > 0) and np.all(np.diff(ci) > 0)


def test_depth_ref_tip_recovers_base_depths_and_n(tip_file):
    (prof,) = read_ci_profiles(tip_file, depth_ref="tip")
    np.testing.assert_allclose(prof.depth, BASE, rtol=0, atol=1e-15)
    assert prof.depth[0] == pytest.approx(0.01 - 0.0378174, abs=1e-7)
    res = predict(prof)
    assert res.ok
    assert res.params.n == pytest.approx(TRUTH["n"], abs=1e-4)
    assert res.rmsd < 1e-4
    # kc/kphi is not moved by the phic-scale ambiguity
    assert res.params.kc / res.params.kphi == pytest.approx(30.0 / 4000.0, rel=1e-3)


def test_depth_ref_base_on_a_tip_file_is_biased(tip_file):
    (tip,) = read_ci_profiles(tip_file, depth_ref="tip")
    (base,) = read_ci_profiles(tip_file, depth_ref="base")
    np.testing.assert_allclose(base.depth, tip.depth + H, rtol=0, atol=1e-15)
    good, bad = predict(tip), predict(base)
    assert bad.ok
    # read H too deep, the curve looks like one that starts late: a steeper n
    assert bad.params.n > TRUTH["n"] + 0.1
    assert bad.rmsd > 1e5 * max(good.rmsd, 1e-9)
    assert bad.rmsd > 0.02 * float(np.mean(base.ci))
    assert bad.lack_of_fit is not None


def test_depth_ref_tip_through_the_cli(tip_file):
    runner = CliRunner()
    out = {}
    for ref in ("tip", "base"):
        r = runner.invoke(cli, ["predict", str(tip_file), "--depth-ref", ref, "--json"])
        assert r.exit_code == 0, r.output
        doc = json.loads(r.output)
        assert doc["settings"]["depth_ref"] == ref
        out[ref] = doc["profiles"][0]
    assert out["tip"]["status"] == "ok"
    assert out["tip"]["n"] == pytest.approx(0.8, abs=1e-4)
    assert out["tip"]["depth"][0] == pytest.approx(0.01 - H, abs=1e-12)
    assert out["base"]["depth"][0] == pytest.approx(0.01, abs=1e-12)
    assert out["base"]["n"] > 0.9
    assert out["base"]["rmsd"] > 1e3 * out["tip"]["rmsd"]


def test_depth_ref_tip_sc900_uses_each_push_cone():
    # tests/data/sc900_psi_inch.txt: depth labels 0, 1, 2, 3, 4 in; push 1 is a
    # 3/4 inch cone (asabe-large), push N=2 of the second logger run a 1/2 inch
    # cone (asabe-small, H = 23.9 mm) with a trailing zero
    labels = np.arange(5) * 0.0254
    base = read_ci_profiles(DATA / "sc900_psi_inch.txt", depth_ref="base", on_error="collect")
    tip = read_ci_profiles(DATA / "sc900_psi_inch.txt", depth_ref="tip", on_error="collect")
    by_id = {p.id: p for p in tip if isinstance(p, CIProfile)}
    p1 = by_id["sc900_psi_inch/0001-N1"]
    np.testing.assert_allclose(p1.depth, labels - CONES["asabe-large"].height, atol=1e-15)
    assert next(p for p in base if getattr(p, "id", None) == p1.id).depth[0] == 0.0
    small = [p for p in by_id.values() if p.cone.name == "asabe-small"]
    for p in small:
        h_small = CONES["asabe-small"].height
        assert h_small == pytest.approx(0.0239, abs=1e-4)
        np.testing.assert_allclose(p.depth, labels[: len(p)] - h_small, atol=1e-15)


# ---------------------------------------------------------------------------
# (b) depth window
# ---------------------------------------------------------------------------

Z_CM = np.arange(0, 41)  # 0 to 40 cm, every 1 cm
Z = Z_CM * 0.01
CLEAN = cone_index(Z, cone=CONE, **TRUTH)


def _disturbed(kind: str, noise: float = 0.0, seed: int = 2) -> np.ndarray:
    """The homogeneous CI below 10 cm, a disturbed top above (known truth below)."""
    if kind == "loose":  # a loose tilled surface layer: CI scaled down towards the surface
        top = CLEAN * np.clip(Z / 0.10, 0.15, 1.0)
    else:  # a crust: 5000 kPa down to 4 cm, then the homogeneous soil's CI
        top = np.where(Z < 0.045, np.maximum(CLEAN, 5000.0), CLEAN)
    y = np.where(Z_CM < 10, top, CLEAN)
    if noise:
        y = y * (1.0 + noise * np.random.default_rng(seed).standard_normal(y.size))
    return y


def test_window_selects_the_hand_counted_points():
    prof = CIProfile("w", Z, CLEAN, cone=CONE, rows=np.arange(2, 43))
    w = prof.window(0.10, 0.40)
    assert len(w) == 31  # 10, 11, ..., 40 cm
    assert w.depth[0] == 0.10 and w.depth[-1] == 0.40
    np.testing.assert_array_equal(w.rows, np.arange(12, 43))
    assert len(prof.window(None, 0.05)) == 6  # 0..5 cm
    assert len(prof.window(0.355, None)) == 5  # 36..40 cm
    assert len(prof) == 41  # the original is untouched


@pytest.mark.parametrize("kind", ["loose", "crust"])
def test_window_recovers_n_below_a_disturbed_top_noiseless(kind):
    prof = CIProfile(kind, Z, _disturbed(kind), cone=CONE)
    whole = predict(prof)
    windowed = predict(prof.window(0.10, 0.40))
    assert whole.ok and windowed.ok
    assert windowed.params.n == pytest.approx(TRUTH["n"], abs=1e-3)
    assert abs(whole.params.n - TRUTH["n"]) > 0.03
    if kind == "loose":
        assert whole.params.n > TRUTH["n"] + 0.05  # a loose top steepens the curve
    else:
        # 3-point median of the crust profile: 5000 down to 4 cm (index 4, whose
        # neighbours are 5000, 5000, CLEAN[5]), then med(5000, C5, C6) = C6 at 5 cm,
        # after which it rises; so the fall is from 0 cm to 5 cm, by 1 - C6/5000
        drop = (5000.0 - CLEAN[6]) / 5000.0
        assert 0.15 < drop < 0.5
        assert (
            f"CI falls with depth between 0 and 5 cm ({drop * 100:.0f}% below its peak)"
            in whole.lack_of_fit
        )
    assert windowed.rmsd < 1e-3
    assert whole.rmsd > 1e4 * windowed.rmsd


@pytest.mark.parametrize("kind", ["loose", "crust"])
def test_window_clears_the_lack_of_fit_with_noise(kind):
    prof = CIProfile(kind, Z, _disturbed(kind, noise=0.01), cone=CONE)
    whole = predict(prof)
    windowed = predict(prof.window(0.10, 0.40))
    assert whole.lack_of_fit is not None
    if kind == "crust":
        assert "CI falls with depth between 0 and" in whole.lack_of_fit
    assert windowed.lack_of_fit is None
    assert windowed.params.n == pytest.approx(TRUTH["n"], abs=0.05)
    assert abs(whole.params.n - TRUTH["n"]) > abs(windowed.params.n - TRUTH["n"])


def test_depth_range_through_the_cli(tmp_path: Path):
    path = tmp_path / "loose_top.csv"
    _write_csv(path, Z_CM, _disturbed("loose", noise=0.01))
    runner = CliRunner()
    r_all = runner.invoke(cli, ["predict", str(path), "--json"])
    r_win = runner.invoke(cli, ["predict", str(path), "--depth-range", "10cm:40cm", "--json"])
    assert r_all.exit_code == 0 and r_win.exit_code == 0, r_all.output + r_win.output
    p_all = json.loads(r_all.output)["profiles"][0]
    doc = json.loads(r_win.output)
    p_win = doc["profiles"][0]
    assert doc["settings"]["depth_range"] == "10cm:40cm"
    assert p_all["lack_of_fit"] is not None
    assert p_win["lack_of_fit"] is None
    assert p_win["n"] == pytest.approx(0.8, abs=0.05)
    assert abs(p_all["n"] - 0.8) > abs(p_win["n"] - 0.8)
    assert len(p_win["depth"]) == 31
    assert p_win["depth"][0] == pytest.approx(0.10) and p_win["depth"][-1] == pytest.approx(0.40)
    assert "depth window 0.1:0.4 m: 31 of 41 points" in p_win["notes"]
    assert not any("depth window" in n for n in p_all["notes"])
    # bare numbers are in the --units length unit: 4 in to 16 in = 10.16 to 40.64 cm,
    # i.e. the readings at 11, ..., 40 cm: 30 points
    r_us = runner.invoke(
        cli, ["predict", str(path), "--depth-range", "4:16", "--units", "us", "--json"]
    )
    assert r_us.exit_code == 0, r_us.output
    p_us = json.loads(r_us.output)["profiles"][0]
    assert "depth window 4:16 in: 30 of 41 points" in p_us["notes"]
    assert len(p_us["depth"]) == 30
    assert p_us["depth"][0] == pytest.approx(11 / 2.54)
    # an open side: 10cm: keeps 10..40 cm too
    r_open = runner.invoke(cli, ["predict", str(path), "--depth-range", "10cm:", "--json"])
    assert r_open.exit_code == 0, r_open.output
    assert (
        "depth window 0.1:- m: 31 of 41 points" in json.loads(r_open.output)["profiles"][0]["notes"]
    )


@pytest.mark.parametrize(
    "bad, why",
    [
        ("40cm:10cm", "LO must be below HI, got '40cm:10cm'"),
        ("10cm", "expected LO:HI, got '10cm'"),
        ("ten:20", "expected a length such as 0.05, 5cm or 2in, got 'ten'"),
    ],
)
def test_bad_depth_range_is_one_message(tmp_path: Path, bad, why):
    path = tmp_path / "p.csv"
    _write_csv(path, Z_CM, CLEAN)
    r = CliRunner().invoke(cli, ["predict", str(path), "--depth-range", bad])
    assert r.exit_code == 2, r.output  # a usage error
    errors = [ln for ln in r.output.splitlines() if ln.startswith("Error: ")]
    assert errors == [f"Error: Invalid value: --depth-range: {why}"], r.output

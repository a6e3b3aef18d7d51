"""Test planning: the Fisher preposterior ranking against a brute-force preposterior simulation."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.data import CIProfile
from terracone.inverse import Bounds
from terracone.inverse.problem import Problem
from terracone.inverse.sites.design import parse_candidates, plan_test
from terracone.physics.cone import cone_index, cone_index_basis, get_cone

CONE = get_cone("asabe-large")
Z = np.arange(0.0, 0.451, 0.025)
N, CC, SIGMA = 1.0, 5.0, 80.0  # fixed n and cc; CI noise [kPa]
S_MID = 0.026  # sinkage of the prediction [m]
S_TEST = np.linspace(0.005, 0.05, 10)
BOUNDS = Bounds.parse("kc=0:0,n=1:1,cc=5:5")  # free: kphi and phic (the ridge of section 2)


def _profile(seed: int = 3) -> CIProfile:
    rng = np.random.default_rng(seed)
    ci = cone_index(Z, kc=0.0, kphi=1500.0, n=N, cc=CC, phic_deg=11.0, cone=CONE)
    return CIProfile("one", Z, np.abs(ci + SIGMA * rng.standard_normal(Z.size)), cone=CONE)


def _brute_force(profile: CIProfile, seed: int = 0, outcomes: int = 40) -> dict[str, float]:
    """Exact Bayes on a (kphi, phic) grid under the uniform bounds prior; preposterior by simulation."""
    rng = np.random.default_rng(seed)
    kphi = np.linspace(0.0, 20000.0, 500)[:, None]
    phic = np.linspace(0.0, 45.0, 301)[None, :]
    s = 1.0 + np.tan(np.radians(phic)) / np.tan(CONE.half_angle)  # eq. (2-6)
    _, B, C = cone_index_basis(Z, n=N, phic_deg=0.0, cone=CONE)
    K = (kphi * s).ravel()  # CI = K B + cc C
    ci = K[:, None] * B[None, :] + CC * C[None, :]
    loglik = -0.5 * ((ci - profile.ci) ** 2).sum(1) / SIGMA**2
    w0 = np.exp(loglik - loglik.max())
    w0 /= w0.sum()
    kp = np.broadcast_to(kphi, K.reshape(kphi.size, -1).shape).ravel()
    p_mid = kp * S_MID**N  # plate pressure with kc = 0 (eq. (2-2)), any radius
    p_test = kp[:, None] * S_TEST[None, :] ** N
    i_hat = int(np.argmax(w0))
    sd_plate = 0.05 * p_test[i_hat]

    def width(w):
        o = np.argsort(p_mid)
        c = np.cumsum(w[o])
        return np.interp(0.95, c, p_mid[o]) - np.interp(0.05, c, p_mid[o])

    out = {"current": width(w0), "ci": 0.0, "plate": 0.0}
    for _ in range(outcomes):
        t = rng.choice(w0.size, p=w0)
        y_ci = ci[t] + SIGMA * rng.standard_normal(Z.size)
        y_pl = p_test[t] + sd_plate * rng.standard_normal(S_TEST.size)
        for key, ll in (
            ("ci", -0.5 * ((ci - y_ci) ** 2).sum(1) / SIGMA**2),
            ("plate", -0.5 * (((p_test - y_pl) / sd_plate) ** 2).sum(1)),
        ):
            w = w0 * np.exp(ll - ll.max())
            out[key] += width(w / w.sum()) / outcomes
    return out


def test_fisher_ranking_agrees_with_brute_force_preposterior():
    prof = _profile()
    res = plan_test(
        prof,
        Problem(bounds=BOUNDS),
        candidates="plate:5cm,ci,shear",
        plates=[0.05],
        ci_noise=SIGMA,
        sinkage=S_MID,
        plate_sinkages=S_TEST,
    )
    assert res.ok
    by = {c.test: c for c in res.candidates}
    assert [c.test for c in res.candidates] == ["plate:5cm", "ci", "shear"]
    bf = _brute_force(prof)
    # the brute force ranks the same way: a plate test beats another CI push
    assert bf["plate"] < bf["ci"] <= bf["current"] * 1.02
    # and agrees on the size of the effect: the CI push barely helps, the plate test a lot
    assert bf["ci"] / bf["current"] > 0.8 and by["ci"].width_ratio > 0.8
    assert bf["plate"] / bf["current"] < 0.3 and by["plate:5cm"].width_ratio < 0.3
    assert by["shear"].width_ratio == pytest.approx(1.0)
    # the current width: same order as the exact posterior's
    assert 0.5 < res.current_width[0] / bf["current"] < 2.0


def test_parse_candidates_and_errors():
    assert parse_candidates("plate:5cm,plate:2in,ci,shear") == [
        ("plate:5cm", "plate", 0.05),
        ("plate:2in", "plate", 0.0508),
        ("ci", "ci", None),
        ("shear", "shear", None),
    ]
    with pytest.raises(ValueError, match="expected plate:RADIUS"):
        parse_candidates("plate:big")
    with pytest.raises(ValueError, match="expected plate:RADIUS"):
        parse_candidates("bevameter")


def test_cli_design_ci_only_profile_ranks_plate_above_ci(tmp_path):
    prof = _profile()
    f = tmp_path / "ci.csv"
    f.write_text(
        "depth_m,ci_kpa\n" + "".join(f"{z:.4f},{c:.3f}\n" for z, c in zip(prof.depth, prof.ci))
    )
    args = ["design", str(f), "--plates", "5cm", "--candidates", "plate:5cm,plate:10cm,ci,shear"]
    r = CliRunner().invoke(cli, args + ["--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)["designs"][0]
    ranks = {c["test"]: c["rank"] for c in d["candidates"]}
    assert ranks["plate:5cm"] < ranks["ci"] and ranks["plate:10cm"] < ranks["ci"]
    assert d["best"].startswith("plate:")
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0 and "expected 90% width" in r.output
    r = CliRunner().invoke(cli, ["design", str(f), "--plates", "5cm", "--candidates", "cpt"])
    assert r.exit_code != 0 and "expected plate:RADIUS" in r.output


def test_cli_design_with_calibration(tmp_path):
    from terracone.inverse.problem import Calibration

    cal = Calibration("sand", "rm0", None, None, 11.0, 5.0, 50.0, 1500.0, 0.9)
    cf = tmp_path / "cal.json"
    cal.save(cf)
    rng = np.random.default_rng(2)
    ci = cone_index(Z, kc=50.0, kphi=1500.0, n=0.9, cc=5.0, phic_deg=11.0)
    ci *= 1 + 0.05 * rng.standard_normal(Z.size)
    f = tmp_path / "ci.csv"
    f.write_text("depth_m,ci_kpa\n" + "".join(f"{z:.4f},{c:.3f}\n" for z, c in zip(Z, ci)))
    r = CliRunner().invoke(
        cli, ["design", str(f), "--plates", "5cm", "--calibration", str(cf), "--json"]
    )
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)["designs"][0]
    assert d["prior"] == "calibration:sand"
    widths = {c["test"]: c["width_ratio"] for c in d["candidates"]}
    # with the scale fixed by the calibration the CI already does much: a second push helps
    # (its information doubles, so the width falls by at most 1/sqrt(2)), and never harms
    assert 1 / np.sqrt(2) - 0.01 <= widths["ci"] <= 1.0
    assert widths["shear"] == pytest.approx(1.0)
    r = CliRunner().invoke(
        cli, ["design", str(f), "--plates", "5cm", "--calibration", str(cf), "--prior", "terrain:x"]
    )
    assert r.exit_code != 0 and "give the calibration once" in r.output
    # issue 28: --calibration holds the calibration's phic, cc and kc/kphi (as predict does);
    # holding them is more information than normal priors around them, so the held design's
    # current width is narrower than the one with the calibration given as the prior
    prof = CIProfile("one", Z, np.round(ci, 3), cone=CONE)  # as the file holds it
    held = plan_test(prof, Problem(calibration=cal), plates=[0.05])
    soft = plan_test(prof, Problem(prior=cal), plates=[0.05])
    assert held.prior == soft.prior == "calibration:sand"
    assert d["current_width"][0] == pytest.approx(held.current_width[0], rel=1e-6)
    assert held.current_width[0] < soft.current_width[0]

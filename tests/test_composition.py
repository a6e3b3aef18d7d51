"""Issue 28: every entry point x (no calibration, a calibration) x (si, us).

A calibration holds its phic, cc and kc/kphi in every output built on it: the
one-layer fit, every layer of a layered fit, every posterior draw, every push
and site of ``sites``, every plan of ``design``, every row of ``batch``, every
cell of ``map`` and the fits ``mobility`` reads.  Without a calibration
nothing is held and no output says a calibration was applied.

The calibration is written by hand (its values are the reference, not a
terracone output); the CI profiles are generated from a two-layer terrain that
the calibration does not describe, so that a fit which ignored the calibration
would not land on its values by chance.  US runs read US files (in, psi) and
compare with the SI values converted by hand (1 in = 0.0254 m, 1 psi =
6.894757293168361 kPa).
"""

from __future__ import annotations

import glob
import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from terracone import cone_index
from terracone.cli import cli
from terracone.inverse.problem import Calibration

IN, PSI = 0.0254, 6.894757293168361
PHIC, CC, KC, KPHI = 12.5, 0.2 * PSI, 40.0, 1800.0  # the calibration [deg, kPa, SI moduli]
RATIO = KC / KPHI  # [m]
NAME = "held soil"


def held(units: str) -> dict[str, float]:
    """The calibration's held values in ``units`` (by hand)."""
    if units == "us":
        return {"phic_deg": PHIC, "cc": CC / PSI, "ratio": RATIO / IN}
    return {"phic_deg": PHIC, "cc": CC, "ratio": RATIO}


def _profiles(count: int, seed: int = 1):
    """(id, site, lat, lon, depth [m], CI [kPa]) of ``count`` noisy two-layer pushes."""
    rng = np.random.default_rng(seed)
    z = np.linspace(0.0, 0.375, 16)  # below the 6-12 in critical layer of a wheeled vehicle
    kw = dict(phic_deg=20.0, cc=3.0, model="rm1", r_min=0.01)
    for k in range(count):
        s = 1 + 0.3 * rng.standard_normal()
        top = cone_index(z, kc=30 * s, kphi=900 * s, n=0.8, **kw)
        deep = cone_index(z, kc=80 * s, kphi=4000 * s, n=1.0, **kw)
        ci = np.where(z < 0.12, top, deep) * (1 + 0.03 * rng.standard_normal(z.size))
        lat, lon = -34.38 - 0.0003 * (k // 6), 19.175 + 0.0003 * (k % 6)
        yield f"p{k}", f"s{k % 4}", lat, lon, z, ci


def _write_ci(path: Path, count: int, units: str) -> Path:
    head = "depth_in,ci_psi" if units == "us" else "depth_m,ci_kpa"
    rows = [f"profile,site,lat,lon,{head}"]
    for pid, site, lat, lon, z, ci in _profiles(count):
        zz, cc = (z / IN, ci / PSI) if units == "us" else (z, ci)
        rows += [f"{pid},{site},{lat},{lon},{a:.6f},{b:.6f}" for a, b in zip(zz, cc)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def ws(tmp_path_factory):
    d = tmp_path_factory.mktemp("composition")
    cal = Calibration(
        NAME, model="rm1", r_min=0.01, plate_pair=(0.0375, 0.05), phic_deg=PHIC, cc=CC,
        kc=KC, kphi=KPHI, n=0.9,
    )  # fmt: skip
    cal.save(d / "cal.json")
    vehicle = {
        "name": "test truck",
        "kind": "wheeled",
        "mobility_index": 60,
        "wheel": {"load": "10 kN", "diameter": "1 m", "width": "30 cm"},
    }
    (d / "truck.json").write_text(json.dumps(vehicle))
    for units in ("si", "us"):
        _write_ci(d / f"few_{units}.csv", 3, units)
        _write_ci(d / f"many_{units}.csv", 24, units)
    return d


def run(ws: Path, *args: str) -> dict:
    r = CliRunner().invoke(cli, [*args])
    assert r.exit_code == 0, r.output
    text = r.output
    return json.loads(text[text.index("{") :]) if "{" in text else {}


def _args(ws: Path, units: str, calibrated: bool) -> list[str]:
    return ["--units", units] + (["--calibration", str(ws / "cal.json")] if calibrated else [])


def _check_params(d: dict, units: str, calibrated: bool, where: str) -> None:
    """One set of kc, kphi, cc, phic_deg (a profile, a layer, a site, a cell)."""
    h = held(units)
    ratio = d["kc"] / d["kphi"] if d["kphi"] else np.inf
    got = {"phic_deg": d["phic_deg"], "cc": d["cc"], "ratio": ratio}
    if calibrated:
        assert got == pytest.approx(h, rel=1e-9), where
    else:
        assert got["phic_deg"] != pytest.approx(PHIC, rel=1e-6) or got["ratio"] != pytest.approx(
            h["ratio"], rel=1e-6
        ), where


def _check_notes(notes: list[str], calibrated: bool, where: str) -> None:
    said = [n for n in notes if f"calibration {NAME!r}" in n]
    assert bool(said) == calibrated, (where, notes)
    if calibrated:
        assert "phic, cc and kc/kphi fixed" in said[0], where


UNITS = ["si", "us"]
CAL = [False, True]


@pytest.mark.parametrize("units", UNITS)
@pytest.mark.parametrize("calibrated", CAL)
def test_predict_and_layers(ws, units, calibrated):
    doc = run(
        ws, "predict", str(ws / f"few_{units}.csv"), "--layers", "2", "--json",
        *_args(ws, units, calibrated),
    )  # fmt: skip
    assert doc["settings"]["calibration"] == (NAME if calibrated else None)
    for p in doc["profiles"]:
        assert p["status"] == "ok"
        _check_params(p, units, calibrated, p["id"])
        _check_notes(p["notes"], calibrated, p["id"])
        lay = p["layered"]
        assert lay["status"] == "ok", lay
        for j, layer in enumerate(lay["layers"]):
            _check_params(layer, units, calibrated, f"{p['id']} layer {j + 1}")
        _check_notes(lay["notes"], calibrated, f"{p['id']} layered")
        assert ("phic" in lay["undetermined"]) != calibrated


@pytest.mark.parametrize("units", UNITS)
@pytest.mark.parametrize("calibrated", CAL)
def test_posteriors_hold_every_draw(ws, units, calibrated):
    args = ["--uncertainty", "--draws", "60", "--layers", "2", "--json", "--out"]
    out = ws / f"post_{units}_{calibrated}.json"
    doc = run(
        ws, "predict", str(ws / f"few_{units}.csv"), *args, str(out),
        *_args(ws, units, calibrated),
    )  # fmt: skip
    h = held(units)
    for p in doc["profiles"]:
        s = doc_samples(p)
        phic, cc, ratio = s[:, 4], s[:, 3], s[:, 0] / s[:, 1]
        if calibrated:
            assert np.all(phic == pytest.approx(h["phic_deg"], rel=1e-9))
            assert np.all(cc == pytest.approx(h["cc"], rel=1e-9))
            assert np.all(ratio == pytest.approx(h["ratio"], rel=1e-9))
            assert p["posterior"]["prior"] == f"calibration:{NAME}"
        else:
            assert np.ptp(phic) > 1.0 and np.ptp(ratio) > 0.0
            assert p["posterior"]["prior"] == "bounds"
        _check_notes(p["notes"], calibrated, p["id"])
        lp = p["layered"]["posterior"]
        _check_notes(lp["notes"], calibrated, f"{p['id']} layered posterior")
        iv = lp["intervals"]
        for j in (1, 2):
            if calibrated:  # cc pinned; kc = ratio kphi in every draw, so in its quantiles
                assert iv[f"cc_{j}"] == pytest.approx([h["cc"]] * 2, rel=1e-9)
                kc_iv = np.array(iv[f"kc_{j}"]) / np.array(iv[f"kphi_{j}"])
                assert kc_iv == pytest.approx([h["ratio"]] * 2, rel=1e-6)
            else:
                assert iv[f"cc_{j}"][1] > iv[f"cc_{j}"][0]
        if calibrated:  # the layered posterior holds phic at the fit's: the calibration's
            assert lp["phic_deg"] == pytest.approx(PHIC, rel=1e-12)


def doc_samples(p: dict) -> np.ndarray:
    s = p["samples"]
    assert s["names"] == ["kc", "kphi", "n", "cc", "phic_deg"]
    return np.array(s["values"], dtype=float)


@pytest.mark.parametrize("units", UNITS)
@pytest.mark.parametrize("calibrated", CAL)
def test_sites_and_design(ws, units, calibrated):
    many = str(ws / f"many_{units}.csv")
    doc = run(ws, "sites", many, "--by", "site", "--json", *_args(ws, units, calibrated))
    assert doc["settings"]["calibration"] == (NAME if calibrated else None)
    for site in doc["sites"]:
        assert site["calibrated"] is calibrated
        _check_params(site["params"], units, calibrated, site["site"])
        _check_notes(site["notes"], calibrated, site["site"])
    few = str(ws / f"few_{units}.csv")
    plates = "2in" if units == "us" else "5cm"
    doc = run(ws, "design", few, "--plates", plates, "--json", *_args(ws, units, calibrated))
    for d in doc["designs"]:
        assert d["status"] == "ok"
        assert d["prior"] == (f"calibration:{NAME}" if calibrated else "bounds")
        _check_notes(d["notes"], calibrated, d["id"])


@pytest.mark.parametrize("units", UNITS)
@pytest.mark.parametrize("calibrated", CAL)
def test_batch_map_and_mobility(ws, units, calibrated):
    out = ws / f"batch_{units}_{calibrated}"
    r = CliRunner().invoke(
        cli,
        ["batch", str(ws / f"many_{units}.csv"), "--out", str(out), "--workers", "1", "--quiet"]
        + _args(ws, units, calibrated),
    )
    assert r.exit_code == 0, r.output
    rows = pq.read_table(glob.glob(str(out / "part-*.parquet"))).to_pylist()
    assert len(rows) == 24
    for row in rows:
        _check_params(row, units, calibrated, row["profile"])
    mdir = ws / f"map_{units}_{calibrated}"
    doc = run(ws, "map", str(out), "--out", str(mdir), "--json")
    assert doc["calibrated"] is calibrated
    cells = pq.read_table(mdir / "cells.parquet").to_pandas()
    ratio = (cells["kc"] / cells["kphi"]).to_numpy()
    if calibrated:  # cells.parquet is SI (the simulators' input)
        assert ratio == pytest.approx(RATIO, rel=1e-9)
        assert cells["phic_deg"].to_numpy() == pytest.approx(PHIC, rel=1e-12)
        assert cells["cc"].to_numpy() == pytest.approx(CC, rel=1e-9)
    else:
        assert not np.allclose(ratio, RATIO, rtol=1e-6)
    pred = ws / f"post_{units}_{calibrated}.json"
    if not pred.exists():
        pytest.skip("needs the posterior run of test_posteriors_hold_every_draw")
    truck = str(ws / "truck.json")
    doc = run(ws, "mobility", str(pred), "--vehicle", truck, "--units", units, "--json")
    assert doc["settings"]["calibration"] == (NAME if calibrated else None)
    assert doc["settings"]["prior"] == (f"calibration:{NAME}" if calibrated else "bounds")
    # a batch directory keeps no CI: mobility reads it from the CI file (--ci), by profile id
    ci_file = str(ws / f"many_{units}.csv")
    from_batch = run(
        ws, "mobility", str(out), "--vehicle", truck, "--ci", ci_file, "--units", units, "--json"
    )
    layer = {p["id"]: p["critical_layer"]["ci"] for p in from_batch["profiles"]}
    for p in doc["profiles"]:
        assert layer[p["id"]] == pytest.approx(p["critical_layer"]["ci"], rel=1e-9)
    fits = {p["id"]: p for p in json.loads(pred.read_text())["profiles"]}
    for p in doc["profiles"]:
        fit = fits[p["id"]]
        _check_params(fit, units, calibrated, p["id"])
        z0 = _bekker_sinkage(fit, units)  # the wheel sinkage of the (held) fit, by hand
        got = p["wheel"]["sinkage"] * (IN if units == "us" else 1.0)
        assert got == pytest.approx(z0, rel=1e-6)


def _bekker_sinkage(fit: dict, units: str) -> float:
    """Bekker's rigid-wheel sinkage z0 = (3 W / ((3 - n)(kc + b kphi) sqrt(D)))^(2 / (2n + 1))
    [m] of a fit in ``units`` (Wong, Theory of Ground Vehicles, ch. 2): W 10 kN, D 1 m, b 0.3 m."""
    n = fit["n"]
    kc, kphi = fit["kc"], fit["kphi"]
    if units == "us":  # lb/in^(n+1), lb/in^(n+2) -> kN/m^(n+1), kN/m^(n+2)
        lbf_kn = 4.4482216152605e-3
        kc, kphi = kc * lbf_kn / IN ** (n + 1), kphi * lbf_kn / IN ** (n + 2)
    k = kc + 0.3 * kphi  # [kN/m^(n+1)]
    return (3 * 10.0 / ((3 - n) * k * np.sqrt(1.0))) ** (2 / (2 * n + 1))

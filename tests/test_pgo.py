"""Probability-of-GO maps (issue 31): terracone.apps.go_map and ``terracone mobility MAPDIR``.

References used here, none of them terracone's own output:

* known truth: fields whose log kphi and n are smooth Gaussian random fields
  (gstools, fixed seeds) plus push-to-push variation (the nugget), under a
  calibration (its kc/kphi, cc and phic), sampled by located pushes with 5%
  CI noise.  Each push's parameters are taken as its fit (the fit itself is
  tested in test_predict and test_map; P(GO) rests on the measured CI);
* fresh point truths at every cell centre (unsampled places): the smooth
  fields plus a new push-to-push draw, without measurement noise, their
  critical-layer CI the model's (eqs. (2-2) to (2-7)) by fine trapezoids;
* binomial windows (scipy.stats.binom) and the Brier score of the hard
  GO/NO-GO of the median map; the normal distribution by hand
  (scipy.stats.norm) on the map's own rasters; the ordinary kriging system
  solved by hand with numpy for the joint covariance of two cells;
* the GIS files read back by rasterio.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import gstools as gs
import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from pyproj import Transformer
from scipy import stats
from scipy.integrate import trapezoid

from terracone.apps.go_map import go_map, write_go_map
from terracone.apps.maps import map_survey, write_map
from terracone.apps.maps.directory import read_map_directory
from terracone.apps.maps.geostat import Variogram
from terracone.apps.maps.grid import Grid
from terracone.apps.maps.simulation import simulate
from terracone.apps.vehicles import vehicle_from_dict
from terracone.cli import cli
from terracone.data import TerrainParameters
from terracone.inverse.problem import Calibration
from terracone.physics import units as u
from terracone.physics.cone import cone_index_huang
from terracone.result import PredictionResult, PredictionResults

CAL = Calibration("generated", "rm0", None, None, 11.0, 5.0, 6.0, 20.0, 0.9)
TO_LATLON = Transformer.from_crs("EPSG:32735", "EPSG:4326", always_xy=True)
X0, Y0, SIDE = 500000.0, 7150000.0, 1000.0
DEPTH = np.arange(0.0, 0.451, 0.025)
#: The critical layer of a tracked vehicle, one pass, on a fine-grained soil: 0-6 in (EN5341).
LAYER = (0.0, 6 * u.INCH)
FINE = np.linspace(*LAYER, 61)
TAU = (0.2, 0.05)  # push-to-push sd of log kphi and n: the nugget
TRACKED = {"name": "M113-like", "kind": "tracked", "mobility_index": 60.0}
WHEELED = {"name": "truck", "kind": "wheeled", "mobility_index": 60.0, "drive": "all",
           "wheel": {"load": "20 kN", "diameter": "1 m", "width": "0.3 m"}}  # fmt: skip


def fields(seed: int) -> tuple[gs.SRF, gs.SRF]:
    """Smooth fields of log kphi (sd 0.35) and n (sd 0.12), Gaussian covariance, 250 m."""
    model = gs.Gaussian(dim=2, var=0.35**2, len_scale=250.0)
    log_kphi = gs.SRF(model, mean=math.log(CAL.kphi), seed=seed)
    n = gs.SRF(gs.Gaussian(dim=2, var=0.12**2, len_scale=250.0), mean=0.9, seed=seed + 100_000)
    return log_kphi, n


def draw(seed: int, x: np.ndarray, y: np.ndarray, rng: np.random.Generator):
    """kphi, kc and n at (x, y): the smooth fields plus a push-to-push draw."""
    f = fields(seed)
    kphi = np.exp(f[0]((x, y), mesh_type="unstructured") + rng.normal(0, TAU[0], x.size))
    n = f[1]((x, y), mesh_type="unstructured") + rng.normal(0, TAU[1], x.size)
    return kphi, kphi * CAL.kc / CAL.kphi, n


def pushes(seed: int, count: int) -> PredictionResults:
    """Located pushes with 5% CI noise, each push's parameters taken as its fit."""
    rng = np.random.default_rng(seed)
    x, y = X0 + rng.uniform(0, SIDE, count), Y0 + rng.uniform(0, SIDE, count)
    kphi, kc, n = draw(seed, x, y, rng)
    ci = cone_index_huang(DEPTH[None, :], kc=kc[:, None], kphi=kphi[:, None], n=n[:, None],
                          cc=CAL.cc, phic_deg=CAL.phic_deg)  # fmt: skip
    ci = ci * (1 + 0.05 * rng.standard_normal(ci.shape))
    lon, lat = TO_LATLON.transform(x, y)
    res = [
        PredictionResult(f"p{i}", "ok", params=TerrainParameters(kc[i], kphi[i], n[i], CAL.cc,
                         CAL.phic_deg), depth=DEPTH, ci=ci[i],
                         metadata={"lat": float(lat[i]), "lon": float(lon[i])})
        for i in range(count)
    ]  # fmt: skip
    return PredictionResults(res, {"calibration": CAL.terrain})


def layer_ci(kphi, kc, n) -> np.ndarray:
    """The model's mean CI over the critical layer [kPa] (eqs. (2-2) to (2-7), fine trapezoids)."""
    ci = cone_index_huang(FINE[:, None], kc=kc, kphi=kphi, n=n, cc=CAL.cc, phic_deg=CAL.phic_deg)
    return trapezoid(ci, FINE, axis=0) / (FINE[-1] - FINE[0])


def median_ci() -> float:
    """The critical-layer CI of the fields' median parameters [kPa]."""
    return float(layer_ci(np.array([CAL.kphi]), np.array([CAL.kc]), np.array([0.9]))[0])


TRACKED_VEHICLE = vehicle_from_dict(TRACKED)
#: RI that puts the fields' median point at the VCI: P(GO) spreads over [0, 1].
RI = TRACKED_VEHICLE.vci(1) / median_ci()


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """Four fields of 200 pushes mapped at 50 m; P(GO) for a tracked vehicle; fresh point truths
    at every cell centre: (P(GO), GO truth, GO of the median map)."""
    p_go, truth, hard = [], [], []
    for seed in range(1, 5):
        m = map_survey(pushes(seed, 200), layers=[LAYER], resolution=50.0)
        d = tmp_path_factory.mktemp(f"field{seed}")
        write_map(m, d)
        g = go_map(d, TRACKED_VEHICLE, remolding_index=RI, simulations=4)
        gx, gy = (a.ravel() for a in m.grid.centres())
        ok = np.isfinite(g.p_go.ravel())
        point = layer_ci(*draw(seed, gx[ok], gy[ok], np.random.default_rng(seed + 7))) * RI
        p_go.append(g.p_go.ravel()[ok])
        truth.append(point >= g.vci)
        hard.append(m[g.quantity].median.ravel()[ok] * RI >= g.vci)
    return np.concatenate(p_go), np.concatenate(truth), np.concatenate(hard)


def test_p_go_is_calibrated_against_fresh_point_truths(study):
    """Among points binned by P(GO), the GO frequency lies in each bin's 99.9% binomial window
    (both bounds; the window of the bin's mean P(GO): the GO count of points of unequal P(GO)
    varies less than that binomial)."""
    p, go, _ = study
    assert 0.2 < RI <= 2.0  # a remolding index of the range NRMM uses
    edges = np.linspace(0.0, 1.0, 11)
    rows = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        sel = (p >= a) & ((p < b) | (b == 1.0))
        n = int(sel.sum())
        if n < 10:
            continue
        lo, hi = stats.binom.ppf([0.0005, 0.9995], n, p[sel].mean())
        rows.append((a, n, int(go[sel].sum()), lo, hi))
    assert len(rows) >= 8, rows  # P(GO) spreads over the range
    for a, n, k, lo, hi in rows:
        assert lo <= k <= hi, (a, n, k / n, lo / n, hi / n)


def test_brier_score_beats_the_hard_go_no_go_of_the_median_map(study):
    p, go, hard = study
    brier = float(np.mean((p - go) ** 2))
    brier_hard = float(np.mean((hard.astype(float) - go) ** 2))
    # measured on four such sets of fields: 0.67-0.70 of the hard map's
    assert brier < 0.85 * brier_hard, (brier, brier_hard)


@pytest.fixture(scope="module")
def small_map(tmp_path_factory) -> Path:
    """One field of 120 pushes mapped at 40 m over the critical layers of both vehicles."""
    m = map_survey(pushes(21, 120), layers=[LAYER, (LAYER[1], 2 * LAYER[1])], resolution=40.0)
    d = tmp_path_factory.mktemp("small_map")
    write_map(m, d)
    return d


def test_p_go_is_the_normal_point_distribution_of_the_map_raster(small_map):
    """P(GO) by hand from the map's own GeoTIFF: log CI at a point is normal with the median
    and the point band's sd, (log point_hi - log median) / 1.645."""
    g = go_map(small_map, TRACKED_VEHICLE, remolding_index=RI, simulations=200)
    with rasterio.open(small_map / f"{g.quantity}.tif") as src:
        med, _, _, _, phi = src.read().astype(float)
    sd = (np.log(phi) - np.log(med)) / stats.norm.ppf(0.95)
    want = stats.norm.sf((math.log(g.vci / RI) - np.log(med)) / sd)
    ok = np.isfinite(med)
    assert ok.sum() > 0.9 * med.size
    np.testing.assert_allclose(g.p_go[ok], want[ok], atol=2e-5)  # float32 rasters
    assert np.all(np.isnan(g.p_go[~ok]))
    # the simulations' GO frequency: binomial about P(GO), cell by cell, N = 200
    z = (g.frequency[ok] - g.p_go[ok]) / np.sqrt(g.p_go[ok] * (1 - g.p_go[ok]) / 200 + 1e-12)
    inner = (g.p_go[ok] > 0.05) & (g.p_go[ok] < 0.95)
    assert 0.8 < np.sqrt(np.mean(z[inner] ** 2)) < 1.25
    assert abs(np.mean(z[inner])) < 0.5


def test_simulations_have_the_conditional_covariance_of_two_cells():
    """The joint distribution the cell-by-cell P(GO) cannot give: the covariance of the values
    at two cells given the pushes, against the kriging system solved by hand, and each cell's
    variance, kriging variance plus nugget (1,000 realisations, 4 standard errors)."""
    rng = np.random.default_rng(5)
    x, y = rng.uniform(0, 600, 40), rng.uniform(0, 600, 40)
    model = gs.Gaussian(dim=2, var=0.1, len_scale=150.0, nugget=0.03)
    z = gs.SRF(model, seed=3)((x, y), mesh_type="unstructured")
    vg = Variogram(model, True, 0.0, 0.03, 0.1, 150.0, 2.0, 1e9, 1.0, *(np.zeros(1),) * 3)
    grid = Grid(-20.0, 620.0, 20.0, 32, 32)
    sim = simulate(vg, x, y, z, grid, 1000, seed=11)
    gx, gy = grid.centres()
    cells = [(10, 12), (11, 13), (25, 3)]  # two neighbours 28 m apart, one far
    pts = np.array([(gx[c], gy[c]) for c in cells])
    k = x.size
    kk = model.covariance(np.hypot(x[:, None] - x, y[:, None] - y)) + 0.03 * np.eye(k)
    a = np.block([[kk, np.ones((k, 1))], [np.ones((1, k)), np.zeros((1, 1))]])
    c0 = model.covariance(np.hypot(x[:, None] - pts[:, 0], y[:, None] - pts[:, 1]))
    w = np.linalg.solve(a, np.vstack([c0, np.ones(3)]))[:k]
    cpp = model.covariance(np.hypot(pts[:, None, 0] - pts[:, 0], pts[:, None, 1] - pts[:, 1]))
    want = cpp - w.T @ c0 - c0.T @ w + w.T @ kk @ w + 0.03 * np.eye(3)  # value at a point
    vals = np.array([sim.realisations[:, r, c] for r, c in cells], dtype=float)
    got = np.cov(vals)
    se = np.sqrt((np.outer(np.diag(want), np.diag(want)) + want**2) / 1000)
    assert np.all(np.abs(got - want) < 4 * se), (got, want)
    np.testing.assert_allclose(np.array([sim.mean[c] for c in cells]), w.T @ z, rtol=1e-9)
    np.testing.assert_allclose(np.array([sim.scale[c] for c in cells]) ** 2, np.diag(want),
                               rtol=1e-9)  # fmt: skip
    assert sim.clipped < 1e-3  # the periodic covariance is the covariance to 0.1%


def test_pure_nugget_map_gets_the_t_predictive_p_go():
    """Without spatial structure every cell's value follows Student's t about the pushes' mean
    with scale s sqrt(1 + 1/n); the simulations' frequency agrees."""
    rng = np.random.default_rng(2)
    z = rng.normal(1.0, 0.3, 25)
    vg = Variogram(None, False, 0.5, float(np.var(z, ddof=1)), 0.0, *(math.nan,) * 4,
                   *(np.zeros(1),) * 3)  # fmt: skip
    sim = simulate(vg, rng.uniform(0, 100, 25), rng.uniform(0, 100, 25), z,
                   Grid(0.0, 100.0, 10.0, 10, 10), 4000, seed=1)  # fmt: skip
    s = np.std(z, ddof=1) * math.sqrt(1 + 1 / 25)
    want = stats.t.sf((1.2 - z.mean()) / s, 24)
    np.testing.assert_allclose(sim.exceedance(1.2), want, rtol=1e-12)
    freq = float(np.mean(sim.realisations >= 1.2))
    assert abs(freq - want) < 4 * math.sqrt(want * (1 - want) / 4000) + 0.02  # cells share mu


# ---------------------------------------------------------------------------
# the command line: contract, coarse soil, errors
# ---------------------------------------------------------------------------


def write_csv(path: Path, seed: int, count: int) -> Path:
    """A long CSV (Profile, Lat, Lon, Depth_CM, CI_kPa) of located pushes on a generated field."""
    rng = np.random.default_rng(seed)
    x, y = X0 + rng.uniform(0, SIDE, count), Y0 + rng.uniform(0, SIDE, count)
    kphi, kc, n = draw(seed, x, y, rng)
    lon, lat = TO_LATLON.transform(x, y)
    lines = ["Profile,Lat,Lon,Depth_CM,CI_kPa"]
    for i in range(count):
        ci = cone_index_huang(
            DEPTH, kc=kc[i], kphi=kphi[i], n=n[i], cc=CAL.cc, phic_deg=CAL.phic_deg
        ) * (1 + 0.05 * rng.standard_normal(DEPTH.size))
        lines += [f"P{i},{lat[i]:.7f},{lon[i]:.7f},{z * 100:g},{c:.2f}" for z, c in zip(DEPTH, ci)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def cli_map(tmp_path_factory) -> tuple[Path, Path]:
    """predict -> map --layers-ci 6:12in,0:6in from a CSV of 40 located pushes; a vehicle file."""
    d = tmp_path_factory.mktemp("cli")
    CAL.save(d / "cal.json")
    run = CliRunner().invoke
    r = run(cli, ["predict", str(write_csv(d / "pushes.csv", 31, 40)), "--calibration",
                  str(d / "cal.json"), "--json", "--out", str(d / "res.json")])  # fmt: skip
    assert r.exit_code == 0, r.output
    r = run(cli, ["map", str(d / "res.json"), "--out", str(d / "map"), "--layers-ci",
                  "6:12in,0:6in", "--resolution", "50m"])  # fmt: skip
    assert r.exit_code == 0, r.output
    (d / "truck.json").write_text(json.dumps(WHEELED))
    return d / "map", d / "truck.json"


def test_cli_contract_files_bands_and_json(cli_map, tmp_path):
    mapdir, vehicle = cli_map
    out = tmp_path / "go"
    args = ["mobility", str(mapdir), "--vehicle", str(vehicle), "--out", str(out),
            "--remolding-index", "0.5", "--simulations", "20", "--json"]  # fmt: skip
    r = CliRunner().invoke(cli, args)
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc == json.loads((out / "mobility.json").read_text())
    assert doc["schema"] == "terracone.mobility-map/1" and doc["simulations"] == 20
    assert doc["p_go"]["file"] == "p_go.tif" and doc["sinkage"]["file"] == "sinkage.tif"
    assert doc["critical_layer"]["quantity"] == "ci_15.24-30.48cm"  # wheeled: 6-12 in
    assert doc["critical_layer"]["rule"] == "fine-wheeled-1pass"
    truck = vehicle_from_dict(WHEELED)
    assert doc["vci"] == pytest.approx(truck.vci(1), rel=1e-12)
    assert doc["threshold_ci"] == pytest.approx(truck.vci(1) / 0.5, rel=1e-12)
    with rasterio.open(out / "p_go.tif") as p, rasterio.open(mapdir / "n.tif") as n:
        assert p.count == 1 and p.descriptions == ("p_go",)
        assert p.tags(1)["meaning"] == "P(RCI >= VCI) at a point [-]"
        assert p.crs == n.crs and p.transform == n.transform and p.shape == n.shape
        pg = p.read(1).astype(float)
    ok = np.isfinite(pg)
    assert ok.any() and np.all((pg[ok] >= 0) & (pg[ok] <= 1))
    a, cell = doc["area_m2"], 50.0**2
    assert a["go_90"] == pytest.approx(np.sum(pg[ok] >= 0.9) * cell)
    assert a["no_go_90"] == pytest.approx(np.sum(pg[ok] <= 0.1) * cell)
    assert a["uncertain"] == pytest.approx(np.sum((pg[ok] > 0.1) & (pg[ok] < 0.9)) * cell)
    assert a["go_90"] + a["no_go_90"] + a["uncertain"] + a["masked"] == pytest.approx(a["total"])
    assert a["expected_go"] == pytest.approx(np.sum(pg[ok]) * cell, rel=1e-5)
    with rasterio.open(out / "sinkage.tif") as s:
        assert s.count == 3 and s.units == ("m",) * 3
        assert s.descriptions == ("median", "lo", "hi")
        assert [s.tags(i)["meaning"] for i in (1, 2, 3)] == [
            "median [m]", "5%, value at a point [m]", "95%, value at a point [m]"]  # fmt: skip
        med, lo, hi = s.read().astype(float)
    good = np.isfinite(med)
    assert good.any() and np.all(lo[good] <= med[good]) and np.all(med[good] <= hi[good])
    # the report draws the P(GO) map
    html = tmp_path / "go.html"
    r = CliRunner().invoke(cli, ["report", str(out), "--out", str(html)])
    assert r.exit_code == 0, r.output
    text = html.read_text()
    assert "Probability of GO" in text and text.count("data:image/png;base64,") == 1


def test_cli_units_us_converts_sinkage_and_pressures(cli_map, tmp_path):
    mapdir, vehicle = cli_map
    base = ["mobility", str(mapdir), "--vehicle", str(vehicle), "--remolding-index", "0.5",
            "--simulations", "10", "--json"]  # fmt: skip
    si = json.loads(CliRunner().invoke(cli, base + ["--out", str(tmp_path / "si")]).stdout)
    r = CliRunner().invoke(cli, base + ["--out", str(tmp_path / "us"), "--units", "us"])
    assert r.exit_code == 0, r.output
    us = json.loads(r.stdout)
    assert us["vci"] == pytest.approx(si["vci"] / u.PSI, rel=1e-12)
    assert us["area_m2"] == si["area_m2"]  # areas stay m^2; the same seed, the same cells
    with (
        rasterio.open(tmp_path / "si" / "sinkage.tif") as a,
        rasterio.open(tmp_path / "us" / "sinkage.tif") as b,
    ):
        assert b.units == ("in",) * 3
        np.testing.assert_allclose(b.read(), a.read() / u.INCH, rtol=1e-6)


def test_coarse_soil_gets_no_p_go_and_says_why(cli_map, tmp_path):
    mapdir, vehicle = cli_map
    out = tmp_path / "coarse"
    r = CliRunner().invoke(cli, ["mobility", str(mapdir), "--vehicle", str(vehicle), "--out",
                                 str(out), "--soil", "coarse", "--simulations", "10", "--json"])  # fmt: skip
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["p_go"]["file"] is None and doc["vci"] is None
    assert doc["p_go"]["reason"].startswith("coarse-grained soil: rated by its critical-layer CI")
    assert doc["area_m2"]["go_90"] is None and doc["area_m2"]["uncertain"] is None
    assert not (out / "p_go.tif").exists() and (out / "sinkage.tif").exists()
    assert doc["soil_class"] == "coarse" and doc["assumed"] is False


def test_a_vehicle_outside_the_vci_relation_gets_no_p_go(cli_map, tmp_path):
    mapdir, _ = cli_map
    veh = tmp_path / "partial.json"
    veh.write_text(json.dumps({**WHEELED, "drive": "partial"}))
    r = CliRunner().invoke(cli, ["mobility", str(mapdir), "--vehicle", str(veh), "--out",
                                 str(tmp_path / "o"), "--remolding-index", "0.5", "--json"])  # fmt: skip
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["p_go"]["file"] is None
    assert doc["p_go"]["reason"].startswith("no VCI_1: the VCI_1 relation of Priddy and Willoughby")


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "--remolding-index: a P(GO) map of a fine-grained soil needs the remolding index RI"),
        (["--remolding-index", "3"], "--remolding-index: 3 outside (0, 2]"),
        (
            ["--remolding-index", "0.5", "--passes", "50", "--layer", "0:10cm"],
            "the map has no CI layer over the critical layer 0-0.1 m (--layer: the --layer option); "
            "its CI layers: ci_15.24-30.48cm, ci_0-15.24cm. Make the map with --layers-ci 0:10cm",
        ),
        (
            ["--remolding-index", "0.5", "--critical-layer", "weakest:6in"],
            "--critical-layer weakest: a map holds the mean CI over fixed layers",
        ),
        (["--remolding-index", "0.5", "--simulations", "1"], "--simulations must be >= 2 (got 1)"),
    ],
)
def test_cli_map_errors_name_what_to_do(cli_map, tmp_path, extra, message):
    mapdir, vehicle = cli_map
    r = CliRunner().invoke(cli, ["mobility", str(mapdir), "--vehicle", str(vehicle), "--out",
                                 str(tmp_path / "o"), *extra])  # fmt: skip
    assert r.exit_code == 1, r.output
    assert message in r.output and "Traceback" not in r.output


def test_cli_directory_errors(cli_map, tmp_path):
    mapdir, vehicle = cli_map
    run = CliRunner().invoke
    empty = tmp_path / "empty"
    empty.mkdir()
    r = run(cli, ["mobility", str(empty), "--vehicle", str(vehicle), "--out", str(tmp_path / "o")])
    assert r.exit_code == 1
    assert r.output.strip() == (
        f"Error: {empty}: neither a terracone map directory (no map.json) nor a batch directory "
        "(no part-*.parquet files)"
    )
    r = run(cli, ["mobility", str(mapdir), "--vehicle", str(vehicle), "--remolding-index", "0.5"])
    assert (
        r.exit_code == 2 and "a map directory needs --out DIR (p_go.tif, sinkage.tif)" in r.output
    )
    r = run(cli, ["mobility", str(mapdir), "--vehicle", str(vehicle), "--out", str(tmp_path / "o"),
                  "--by", "site"])  # fmt: skip
    assert r.exit_code == 2 and "--by: not with a map directory" in r.output
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "map.json").write_text('{"schema": "terracone.prediction/1"}')
    r = run(cli, ["mobility", str(bad), "--vehicle", str(vehicle), "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and r.output.strip() == (
        f"Error: file {bad / 'map.json'}: not a terracone map (schema 'terracone.prediction/1', "
        "expected 'terracone.map/1')"
    )
    with pytest.raises(ValueError, match=r"no map.json \(not a terracone map directory"):
        read_map_directory(empty)
    # a map directory's options are refused for a results file
    res = mapdir.parent / "res.json"
    r = run(cli, ["mobility", str(res), "--vehicle", str(vehicle), "--simulations", "5"])
    assert r.exit_code == 2 and "--simulations: only with a map directory (MAPDIR)" in r.output


def test_write_go_map_without_a_wheel_writes_no_sinkage(small_map, tmp_path):
    g = go_map(small_map, TRACKED_VEHICLE, remolding_index=RI, simulations=5)
    assert (
        g.sinkage is None
        and g.sinkage_reason == "the vehicle file gives no wheel: no Bekker sinkage"
    )
    files, doc = write_go_map(g, tmp_path / "o")
    assert set(files) == {"p_go", "json"} and doc["sinkage"]["file"] is None
    assert doc["critical_layer"]["rule"] == "fine-tracked-1pass"


def test_simulations_do_not_depend_on_the_pool(small_map):
    """The blocks of cells conditioned here, on a thread pool and on a Dask client (in-process
    workers): the same realisations, bit for bit (every random number is drawn here)."""
    from concurrent.futures import ThreadPoolExecutor

    from distributed import Client

    q = read_map_directory(small_map).quantity("n")
    grid = read_map_directory(small_map).grid
    assert q.variogram.structure  # blocks of cells to condition
    here = simulate(q.variogram, q.x, q.y, q.z, grid, 6, seed=4).realisations
    with ThreadPoolExecutor(2) as pool:
        threads = simulate(q.variogram, q.x, q.y, q.z, grid, 6, seed=4, pool=pool).realisations
    with Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as c:
        dask = simulate(q.variogram, q.x, q.y, q.z, grid, 6, seed=4, pool=c).realisations
    np.testing.assert_array_equal(threads, here)
    np.testing.assert_array_equal(dask, here)

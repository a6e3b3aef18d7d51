"""The library as a prior (issue 32): evidence, weights, the check, the mixture, the commands.

References are independent of the code under test: the evidence against a
brute-force integral (scipy's adaptive quadrature of the likelihood computed
from eq. (2-7) and the AR(1) covariance matrix itself), the coverage against
sites generated with known truth, the seeded calibrations against the
paper's table in ``../shared``.
"""

from __future__ import annotations

import csv
import json
import math
import sqlite3

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import require_shared
from scipy import integrate, special

from terracone.apps.library import Library, paper_calibrations
from terracone.cli.main import cli
from terracone.data import CIProfile
from terracone.inverse.library.evidence import (
    Candidate,
    held_posterior,
    laplace_log_evidence,
    profile_noise,
)
from terracone.inverse.predict import predict, predict_many
from terracone.inverse.problem import Calibration, LibraryPrior, Problem
from terracone.inverse.sites.statistics import fit_sites, group_profiles
from terracone.inverse.uncertainty.noise import ar1_noise
from terracone.io import write_ci_profiles
from terracone.physics.cone import cone_index_huang
from terracone.physics.plate import plate_pressure, pressure_law


def _cal(name, model, r_min, phic, cc, kc, kphi, n, cone="asabe-large") -> Calibration:
    return Calibration(name, model, r_min, None, phic, cc, kc, kphi, n, cone=cone)


#: Four calibrations that differ in kc/kphi (0.004-0.15 m), phic (8-20 deg), cc (0-12 kPa)
#: and r_min (5-25 mm, or RM0).
LIBRARY = (
    _cal("sand", "rm1", 0.005, 11.0, 0.0, 90.0, 4500.0, 0.70),
    _cal("loam", "rm1", 0.012, 15.0, 4.0, 60.0, 1000.0, 0.80),
    _cal("clay", "rm0", None, 8.0, 12.0, 150.0, 1000.0, 0.50),
    _cal("silt", "rm1", 0.025, 20.0, 1.0, 8.0, 2000.0, 0.60),
)
#: A soil outside the library: soft and cohesive (cc makes about half its CI).
OUTSIDE = _cal("outside", "rm0", None, 10.0, 80.0, 10.0, 400.0, 1.00)
DEPTH = np.round(np.arange(0.02, 0.4001, 0.02), 6)  # cone-base depths [m]
PLATE, SINKAGE = 0.05, 0.025  # the stated plate radius and sinkage [m]


def _law(cal: Calibration):
    return pressure_law(cal.model, r_min=cal.r_min) if cal.model == "rm1" else None


def make_sites(n_in: int, n_out: int, pushes: int, seed: int):
    """Sites drawn from the library in turn (strength g ~ logN(0, 0.35), n + N(0, 0.08)),
    then from the outside soil; pushes vary by exp(0.05 e) in strength; CI x (1 + 0.03 e),
    e AR(1) with rho 0.4.  Returns the profiles and per site (truth, calibration, inside)."""
    rng = np.random.default_rng(seed)
    profiles, truth = [], {}
    for s, cal in enumerate([LIBRARY[i % 4] for i in range(n_in)] + [OUTSIDE] * n_out):
        g = float(np.exp(0.35 * rng.standard_normal()))
        n = float(np.clip(cal.n + 0.08 * rng.standard_normal(), 0.3, 1.2))
        name = f"site{s:03d}"
        p = plate_pressure(SINKAGE, kc=cal.kc * g, kphi=cal.kphi * g, n=n, radius=PLATE,
                           model=cal.model, r_min=cal.r_min)  # fmt: skip
        truth[name] = (float(p), cal.terrain, cal is not OUTSIDE)
        for j in range(pushes):
            gj = g * float(np.exp(0.05 * rng.standard_normal()))
            m = cone_index_huang(DEPTH, kc=cal.kc * gj, kphi=cal.kphi * gj, n=n, cc=cal.cc,
                                 phic_deg=cal.phic_deg, law=_law(cal))  # fmt: skip
            y = m * (1 + 0.03 * ar1_noise(DEPTH, 0.4, rng))
            profiles.append(CIProfile(f"{name}-{j}", DEPTH, y, metadata={"site": name}))
    return profiles, truth


# ---------------------------------------------------------------------------
# the evidence
# ---------------------------------------------------------------------------


def _one_profile(seed=5):
    cal = _cal("x", "rm1", 0.008, 10.0, 3.0, 60.0, 2000.0, 0.6)
    z = np.round(np.arange(0.01, 0.3001, 0.01), 6)
    rng = np.random.default_rng(seed)
    y = cone_index_huang(z, kc=72.0, kphi=2400.0, n=0.65, cc=3.0, phic_deg=10.0, law=_law(cal))
    y = y * (1 + 0.03 * ar1_noise(z, 0.5, rng))
    prof = CIProfile("p", z, y)
    base = Problem()
    noise = profile_noise(prof, predict(prof, base).params, base)
    return prof, cal, noise, Candidate.of("x", base.held_problem(cal))


def _brute_log_evidence(prof, cal, noise, rho):
    """log p(y | calibration, rho) by adaptive quadrature (scipy's quad in log kphi within
    quad in n) of the likelihood: eq. (2-7) evaluated by cone_index_huang, the covariance
    sigma^2 W R W built as a matrix and inverted, sigma integrated analytically."""
    z, y, N = prof.depth, prof.ci, prof.ci.size
    lag = np.abs(z[:, None] - z[None, :]) / np.median(np.diff(z))
    S = noise.w[:, None] * (rho**lag if rho > 0 else np.eye(N)) * noise.w[None, :]
    Si, logdet = np.linalg.inv(S), np.linalg.slogdet(S)[1]
    const = math.lgamma(N / 2) - math.log(2) - N / 2 * math.log(math.pi) - 0.5 * logdet
    q = cal.kc / cal.kphi
    kw = dict(phic_deg=cal.phic_deg, law=_law(cal))

    def quadratic(n):  # Q(kphi) = c0 - 2 c1 kphi + c2 kphi^2 at n: the model is linear in kphi
        D = cone_index_huang(z, kc=q, kphi=1.0, n=n, cc=0.0, **kw)
        r0 = y - cone_index_huang(z, kc=0.0, kphi=0.0, n=n, cc=cal.cc, **kw)
        return r0 @ Si @ r0, D @ Si @ r0, D @ Si @ D

    u_lo, u_hi = math.log(2.0), math.log(20000.0)  # 1e-4 of the kphi bound, and the bound
    n_lo, n_hi = 0.05, 2.0
    fit = predict(prof, Problem(calibration=cal)).params
    um, nm = math.log(fit.kphi), fit.n
    c0, c1, c2 = quadratic(nm)
    g0 = const - N / 2 * math.log(c0 - 2 * c1 * fit.kphi + c2 * fit.kphi**2)

    def inner(n):
        c0, c1, c2 = quadratic(n)

        def f(u):
            k = math.exp(u)
            return math.exp(const - N / 2 * math.log(c0 - 2 * c1 * k + c2 * k * k) - g0)

        pts = [um - 0.3, um, um + 0.3]
        return integrate.quad(f, u_lo, u_hi, points=pts, limit=400, epsabs=0, epsrel=1e-11)[0]

    pts = [nm - 0.05, nm, nm + 0.05]
    val = integrate.quad(inner, n_lo, n_hi, points=pts, limit=400, epsabs=0, epsrel=1e-10)[0]
    return g0 + math.log(val / ((u_hi - u_lo) * (n_hi - n_lo)))


def test_evidence_against_brute_force_and_laplace():
    """At a fixed rho: quadrature within 1e-5 of the brute-force log evidence (relative
    1e-5 in the evidence); the Laplace approximation within 0.15 (15%)."""
    prof, cal, noise, cand = _one_profile()
    rho = noise.rho
    assert 0.2 < rho < 0.9  # an AR(1) case
    brute = _brute_log_evidence(prof, cal, noise, rho)
    quad = held_posterior(noise, cand, rho=rho).log_evidence
    assert abs(quad - brute) < 1e-5
    lap = laplace_log_evidence(noise, cand, rho)
    assert abs(lap - brute) < 0.15


def test_rho_marginal_against_a_dense_rho_grid():
    """The evidence with rho integrated (17 nodes, refined) against trapezoids on 191 nodes
    of the fixed-rho evidence: within 0.01 in log (1%)."""
    _, _, noise, cand = _one_profile()
    rr = np.linspace(0.0, 0.95, 191)
    le = np.array([held_posterior(noise, cand, rho=r).log_evidence for r in rr])
    w = np.full(rr.size, rr[1] - rr[0])
    w[[0, -1]] *= 0.5
    dense = special.logsumexp(le + np.log(w)) - math.log(0.95)
    assert abs(held_posterior(noise, cand).log_evidence - dense) < 0.01


# ---------------------------------------------------------------------------
# the problem and the weights
# ---------------------------------------------------------------------------


def test_problem_holds_each_candidate_and_refuses_two_priors():
    lib = LibraryPrior(LIBRARY)
    pb = Problem(library=lib)
    assert not pb.calibrated and pb.prior_label() == "library:4 calibrations"
    cands = pb.candidates("asabe-large")
    assert [c.terrain for c, _, _ in cands] == ["sand", "loam", "clay", "silt"]
    for cal, held, w in cands:
        assert held.library is None and w == 1.0
        assert held.held() == {"phic_deg": cal.phic_deg, "cc": cal.cc,
                               "kc_over_kphi": cal.kc / cal.kphi}  # fmt: skip
        assert (held.model, held.r_min) == (cal.model, cal.r_min)
    assert pb.candidates("asabe-small") == []
    with pytest.raises(ValueError, match="give a calibration or a library as the prior"):
        Problem(library=lib, calibration=LIBRARY[0])
    with pytest.raises(ValueError, match="holds no calibration"):
        LibraryPrior(())
    with pytest.raises(ValueError, match="posterior takes one problem, not a library prior"):
        pb.require_single("posterior")


def test_single_problem_entry_points_refuse_a_library():
    """A posterior, a layered fit and a test plan take one problem, and say so."""
    from terracone.inverse.layered import fit_layered
    from terracone.inverse.sites.design import plan_test
    from terracone.inverse.uncertainty.posterior import posterior

    prof = make_sites(1, 0, 1, 1)[0][0]
    pb = Problem(library=LibraryPrior(LIBRARY))
    tail = "takes one problem, not a library prior: fit with the library (predict_many, "
    for name, call in (
        ("posterior", lambda: posterior(prof, pb, draws=10)),
        ("fit_layered", lambda: fit_layered(prof, pb, layers=2)),
        ("plan_test", lambda: plan_test(prof, pb, candidates=[], plates=[0.05])),
    ):
        with pytest.raises(ValueError) as err:
            call()
        assert str(err.value).startswith(f"{name} {tail}")


def test_soil_class_is_the_prior_weight():
    sand = _cal("sand", "rm0", None, 11.0, 0.0, 90.0, 4500.0, 0.7)
    sand.provenance["soil_class"] = "SP"
    clay = _cal("clay", "rm0", None, 8.0, 12.0, 150.0, 1000.0, 0.5)
    clay.provenance["soil_class"] = "fine"
    pb = Problem(library=LibraryPrior((sand, clay)))
    assert [w for _, _, w in pb.candidates("asabe-large", "SP")] == [1.0, 0.1]
    assert [w for _, _, w in pb.candidates("asabe-large", "CL")] == [0.1, 1.0]
    assert [w for _, _, w in pb.candidates("asabe-large", "coarse")] == [1.0, 0.1]
    assert [w for _, _, w in pb.candidates("asabe-large", None)] == [1.0, 1.0]


def test_profile_answers_carry_weights_summing_to_one():
    profiles, _ = make_sites(4, 0, 1, 3)
    res = predict_many(profiles, Problem(library=LibraryPrior(LIBRARY)))
    for r in res:
        assert r.ok and r.library is not None
        w = list(r.library.weights.values())
        assert math.isclose(sum(w), 1.0, rel_tol=1e-12)
        assert w == sorted(w, reverse=True)
        assert set(r.library.weights) == {c.terrain for c in LIBRARY}
        med = r.posterior.medians
        assert (r.params.kc, r.params.kphi, r.params.n) == (med["kc"], med["kphi"], med["n"])
        lo, hi = r.posterior.intervals["kphi"]
        assert lo < r.params.kphi < hi


# ---------------------------------------------------------------------------
# the coverage study (benchmarks/library_prior.py runs the larger one)
# ---------------------------------------------------------------------------


def test_coverage_study_with_known_truth():
    """80 sites of 3 pushes from a library of four calibrations, 5 from a soil outside it.

    The site's plate pressure (r = 5 cm, z = 2.5 cm) is in the library's 90% interval for
    85-95% of the in-library sites; the true calibration carries the largest weight more
    often than chance (1/4); the library's site medians are closer to the truth than the
    uncalibrated ones; no in-library site and at least 4 of the 5 outside are flagged.
    """
    profiles, truth = make_sites(80, 5, 3, 32)
    grouping = group_profiles(profiles, by="site")
    kw = dict(plates=[PLATE], sinkage=np.array([0.01, SINKAGE, 0.05]), seed=32)
    lib = {
        s.site: s
        for s in fit_sites(profiles, grouping, Problem(library=LibraryPrior(LIBRARY)), **kw)
    }
    free = {s.site: s for s in fit_sites(profiles, grouping, Problem(), **kw)}
    inside = [k for k, t in truth.items() if t[2]]
    outside = [k for k, t in truth.items() if not t[2]]

    def at(site):
        pl = site.plate_pressure[0]
        return float(pl.median[1]), float(pl.lo[1]), float(pl.hi[1])

    cover = np.mean([at(lib[k])[1] <= truth[k][0] <= at(lib[k])[2] for k in inside])
    assert 0.85 <= cover <= 0.95
    top = np.mean([max(lib[k].library.weights, key=lib[k].library.weights.get) == truth[k][1]
                   for k in inside])  # fmt: skip
    assert 0.3 < top <= 1.0
    err_lib = np.median([abs(math.log(at(lib[k])[0] / truth[k][0])) for k in inside])
    err_free = np.median([abs(math.log(at(free[k])[0] / truth[k][0])) for k in inside])
    assert err_lib < err_free
    assert sum(lib[k].library.outside for k in inside) == 0
    assert sum(lib[k].library.outside for k in outside) >= 4
    assert all(lib[k].calibrated == "library" for k in inside)
    assert all(lib[k].calibrated is False for k in outside if lib[k].library.outside)


# ---------------------------------------------------------------------------
# the commands: contract and errors
# ---------------------------------------------------------------------------


@pytest.fixture
def files(tmp_path):
    profiles, _ = make_sites(3, 1, 2, 7)
    ci = tmp_path / "ci.csv"
    write_ci_profiles(ci, profiles)
    db = tmp_path / "lib.sqlite"
    with Library(db) as lb:
        for cal in LIBRARY:
            lb.add(cal.terrain, "calibration", cal.library_params(), {"source": "test"})
    return {"ci": str(ci), "db": str(db), "tmp": tmp_path}


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def test_predict_and_sites_json_contract(files):
    r = run("predict", files["ci"], "--library", files["db"], "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["settings"]["prior"] == f"library:{files['db']}"
    for p in doc["profiles"]:
        w = p["calibration_weights"]
        assert set(w) == {c.terrain for c in LIBRARY}
        assert math.isclose(sum(w.values()), 1.0, rel_tol=1e-12)
        assert isinstance(p["outside_library"], bool)
    r = run("sites", files["ci"], "--by", "site", "--library", files["db"], "--json")
    assert r.exit_code == 0, r.output
    for s in json.loads(r.stdout)["sites"]:
        assert math.isclose(sum(s["calibration_weights"].values()), 1.0, rel_tol=1e-12)
        assert isinstance(s["outside_library"], bool)
        assert s["calibrated"] == ("library" if not s["outside_library"] else False)
    text = run("predict", files["ci"], "--library", files["db"]).output
    assert "The library as the prior" in text and "library: " in text


def test_match_json_contract(files):
    r = run("match", files["ci"], "--library", files["db"], "--by", "site", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert [g["id"] for g in doc["groups"]] == ["site000", "site001", "site002", "site003"]
    for g in doc["groups"]:
        w = [c["weight"] for c in g["candidates"]]
        assert [c["terrain"] for c in g["candidates"]] and w == sorted(w, reverse=True)
        assert math.isclose(sum(w), 1.0, rel_tol=1e-12)
        assert isinstance(g["outside_library"], bool)
        assert all(c["check_p"] is not None for c in g["candidates"])  # match checks them all
    assert doc["groups"][-1]["outside_library"] is True  # the soft cohesive soil
    r = run("match", files["ci"], "--library", files["db"], "--json")
    assert len(json.loads(r.stdout)["groups"]) == 8  # one per profile without --by


def test_library_without_the_flag_keeps_todays_answer(files, monkeypatch):
    """$TERRACONE_LIBRARY locates --terrain; it is never a prior."""
    monkeypatch.setenv("TERRACONE_LIBRARY", files["db"])
    doc = json.loads(run("predict", files["ci"], "--json").stdout)
    assert doc["settings"]["calibration"] is None and "prior" not in doc["settings"]
    assert all("calibration_weights" not in p for p in doc["profiles"])
    doc = json.loads(run("predict", files["ci"], "--library", files["db"], "--terrain", "sand",
                         "--json").stdout)  # fmt: skip
    assert doc["settings"]["calibration"] == "sand"
    assert all("calibration_weights" not in p for p in doc["profiles"])


def _error(r) -> str:
    assert r.exit_code != 0
    return r.output.strip().splitlines()[-1]


def test_errors_empty_library_no_cone_corrupt_file(files):
    tmp = files["tmp"]
    empty = tmp / "empty.sqlite"
    with Library(empty) as lb:  # a library file opens on first use: this makes it, empty
        assert lb.list("calibration", include_builtin=False) == []
    assert _error(run("predict", files["ci"], "--library", empty)) == (
        f"Error: library {empty} holds no calibration (kind 'calibration'): add one with "
        "`terracone library add --from cal.json` (cal.json from `terracone learn --save`) or "
        "`terracone library seed-paper`"
    )
    small = tmp / "small.sqlite"
    with Library(small) as lb:
        cal = _cal("tiny", "rm0", None, 10.0, 0.0, 10.0, 1000.0, 0.7, cone="asabe-small")
        lb.add("tiny", "calibration", cal.library_params())
    r = run("predict", files["ci"], "--library", small, "--json")
    assert r.exit_code == 1
    errors = {p["error"] for p in json.loads(r.stdout)["profiles"]}
    assert errors == {
        f"library {small} holds no calibration learned with the asabe-large cone "
        "(calibrations: asabe-small)"
    }
    bad = tmp / "bad.sqlite"
    bad.write_bytes(b"this is not a database" * 100)
    assert _error(run("predict", files["ci"], "--library", bad)) == (
        f"Error: terrain library {bad}: cannot use it (file is not a database); move the file "
        "away or give another with --library or TERRACONE_LIBRARY (the packaged reference "
        "terrains need no library file)"
    )
    missing = tmp / "none.sqlite"
    assert _error(run("match", files["ci"], "--library", missing)).startswith(
        f"Error: --library {missing}: no such library file"
    )
    assert not missing.exists()
    assert _error(run("predict", files["ci"], "--library", files["db"], "--uncertainty")) == (
        "Error: --library as the prior answers with the mixture of its calibrations (medians "
        "and 90% intervals); --uncertainty and --layers do not apply to it"
    )


# ---------------------------------------------------------------------------
# the seeded calibrations
# ---------------------------------------------------------------------------


def test_seeded_calibrations_are_the_papers_table():
    """Every row of Tables 4-1 and 4-3 as printed in the paper (../shared's CSV of them)."""
    path = require_shared("reference", "huang2020_predicted_parameters.csv")
    with open(path, newline="") as fh:
        rows = {r["dataset"]: r for r in csv.DictReader(x for x in fh if not x.startswith("#"))}
    recs = {r.provenance["row"]: r for r in paper_calibrations()}
    assert set(recs) == set(rows)
    for key, row in rows.items():
        rec = recs[key]
        assert rec.kind == "calibration" and rec.params["model"] == "rm0"
        for mine, theirs in (("kc", "kc_si"), ("kphi", "kphi_si"), ("n", "n"), ("cc", "cc_kpa"),
                             ("phic_deg", "phic_deg")):  # fmt: skip
            assert rec.params[mine] == float(row[theirs]), (key, mine)
        table = "4-1" if key.startswith("LS") else "4-3"
        assert rec.provenance["citation"].endswith(f"Table {table}, row {key}")
        assert "r_min not published" in rec.provenance["method"]
        cal = Calibration.from_library_record(rec)
        assert cal.cone == "asabe-large" and cal.r_min is None


def test_seed_paper_and_library_add_from_a_calibration_file(tmp_path):
    db = tmp_path / "lib.sqlite"
    r = run("library", "--library", db, "seed-paper")
    assert r.exit_code == 0 and r.output.startswith("seeded 12 calibrations, skipped 0")
    assert run("library", "--library", db, "seed-paper").output.startswith(
        "seeded 0 calibrations, skipped 12"
    )
    cal = tmp_path / "cal.json"
    LIBRARY[0].save(cal)
    r = run("library", "--library", db, "add", "--from", cal, "--soil-class", "SP")
    assert r.exit_code == 0, r.output
    with Library(db) as lb:
        rec = lb.get("sand")
        assert rec.kind == "calibration" and rec.provenance["soil_class"] == "SP"
        back = Calibration.from_library_record(rec)
        assert back.to_json() == {**LIBRARY[0].to_json(), "provenance": back.provenance}
        names = [x.name for x in lb.list("calibration")]
    assert len(names) == 13
    with sqlite3.connect(db) as c:  # kind calibration, as `learn --save-as` stores them
        assert c.execute("SELECT kind FROM terrains WHERE name='sand'").fetchone() == (
            "calibration",
        )


def test_mobility_and_map_read_the_mixture(files):
    """predict --library JSON -> mobility: each profile carries the weights, and its wheel band
    (from the mixture's draws) is a posterior band; map --library predicts again and says so."""
    tmp = files["tmp"]
    vehicle = tmp / "truck.json"
    vehicle.write_text(json.dumps({
        "name": "truck", "kind": "wheeled", "mobility_index": 50.0,
        "wheel": {"load": "15000 N", "diameter": "0.9 m", "width": "0.3 m"},
    }))  # fmt: skip
    pred = tmp / "pred.json"
    assert run("predict", files["ci"], "--library", files["db"], "--out", pred).exit_code == 0
    for extra in ([], ["--library", files["db"]]):
        r = run("mobility", pred, "--vehicle", vehicle, "--layer", "5cm:15cm", "--json", *extra)
        assert r.exit_code == 0, r.output
        for p in json.loads(r.stdout)["profiles"]:
            assert math.isclose(sum(p["calibration_weights"].values()), 1.0, rel_tol=1e-12)
            assert isinstance(p["outside_library"], bool)
            if not p["outside_library"]:
                assert p["wheel"]["band"] == "posterior"
    located = tmp / "located.csv"
    profiles, _ = make_sites(12, 0, 1, 9)
    for i, p in enumerate(profiles):
        p.metadata.update(lat=45.0 + 1e-4 * (i % 4), lon=-80.0 + 1e-4 * (i // 4))
    write_ci_profiles(located, profiles)
    res = tmp / "located.json"
    assert run("predict", located, "--out", res).exit_code == 0
    r = run("map", res, "--out", tmp / "map", "--library", files["db"], "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["notes"][0].startswith("the library as the prior: each push's")

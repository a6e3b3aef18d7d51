"""Input that cannot be soil is refused, located, by one rule (terracone.data).

The limits (:data:`terracone.data.CI_MAX_KPA` = 100 MPa, :data:`terracone.data.DEPTH_MAX_M`
= 5 m) are checked on both sides of the boundary; the vectorised screen of a set
(:meth:`ProfileSet.screen`) is checked against :meth:`CIProfile.validate` profile by
profile on random sets with every kind of defect; and the readers, ``predict`` and the
streaming reader of ``batch`` refuse such profiles with the whole expected message.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from terracone.cli import cli
from terracone.data import CI_MAX_KPA, DEPTH_MAX_M, CIProfile, InputError, ProfileSet
from terracone.inverse.predict import predict_many
from terracone.io import iter_profile_sets, read_ci_profiles
from terracone.physics.cone import cone_index, get_cone

LARGE = get_cone("asabe-large")


def profile(z=None, ci=None, pid="p") -> CIProfile:
    z = np.linspace(0.0, 0.3, 7) if z is None else np.asarray(z, dtype=float)
    ci = cone_index(z, kc=20.0, kphi=2000.0, n=0.8, cc=2.0) if ci is None else ci
    return CIProfile(pid, z, np.asarray(ci, dtype=float), rows=np.arange(z.size) + 2)


def refusal(p: CIProfile) -> str | None:
    try:
        p.validate()
    except InputError as exc:
        return str(exc)
    return None


def test_ci_limit_is_100_mpa_and_refusals_name_row_and_column():
    ci = profile().ci.copy()
    ci[3] = CI_MAX_KPA  # 100 MPa exactly: still a reading
    assert refusal(profile(ci=ci)) is None
    for bad, shown in ((CI_MAX_KPA * (1 + 1e-9), "100000"), (1e300, "1e+300")):
        ci[3] = bad
        assert refusal(profile(ci=ci)) == (
            f"profile p, row 5, column ci: cone index {shown} kPa is above 100 MPa, "
            "more than any soil resists (a unit error?)"
        )
    ci[3] = np.inf
    assert refusal(profile(ci=ci)) == "profile p, row 5, column ci: ci is not a finite number"


def test_depth_limit_is_5_m():
    z = np.linspace(0.0, DEPTH_MAX_M, 7)
    assert refusal(profile(z=z)) is None
    z_mm = np.linspace(0.0, 450.0, 7)  # an SC900 push in mm read as m
    assert refusal(profile(z=z_mm, ci=profile().ci)) == (
        "profile p, row 3, column depth: depth 75 m is below 5 m, deeper than any cone "
        "index penetrometer pushes (a unit error?)"
    )


KINDS = ("ok", "nan_ci", "inf_ci", "huge_ci", "neg_ci", "nan_z", "deep", "unordered", "short")


def defective(kind: str, rng: np.random.Generator, pid: str) -> CIProfile:
    """A valid profile with one defect of ``kind`` at a random point (the first included)."""
    k = int(rng.integers(4, 12))
    z = np.sort(rng.uniform(-0.02, 0.6, k))
    z = np.unique(z) if np.unique(z).size == k else np.linspace(0.0, 0.5, k)
    ci = rng.uniform(0.0, 5000.0, k)
    i = int(rng.integers(0, k))
    if kind == "nan_ci":
        ci[i] = np.nan
    elif kind == "inf_ci":
        ci[i] = np.inf
    elif kind == "huge_ci":
        ci[i] = CI_MAX_KPA * rng.uniform(1.001, 1e6)
    elif kind == "neg_ci":
        ci[i] = -rng.uniform(0.1, 10.0)
    elif kind == "nan_z":
        z[i] = np.nan
    elif kind == "deep":
        z[i:] = DEPTH_MAX_M + 0.1 + np.arange(k - i)
    elif kind == "unordered":
        z[max(i, 1)] = z[max(i, 1) - 1]
    elif kind == "short":
        z, ci = z[:2], ci[:2]
    return CIProfile(pid, z, ci, cone=LARGE)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_screen_of_a_set_equals_validate_one_by_one(seed):
    """The vectorised screen refuses exactly the profiles validate refuses, with its words
    (defects at a profile's first point included, where no previous depth is compared)."""
    rng = np.random.default_rng(seed)
    kinds = rng.choice(KINDS, size=200)
    profs = [defective(str(k), rng, f"q{i}") for i, k in enumerate(kinds)]
    pset = ProfileSet.from_profiles(profs)
    got = {j: exc.reason for j, exc in pset.screen().items()}
    want = {}
    for j, p in enumerate(profs):
        try:
            p.validate()
        except InputError as exc:
            want[j] = exc.reason
    assert got == want
    refused = {str(kinds[j]) for j in want}
    assert refused == set(KINDS) - {"ok"}  # every kind of defect was met and refused
    assert all(kinds[j] == "ok" for j in range(len(profs)) if j not in want)


CSV = "profile,depth_cm,ci_mpa\n"


def csv_text(huge: str = "1e300") -> str:
    z = np.arange(0.0, 31.0, 5.0)
    ci = cone_index(z / 100, kc=30.0, kphi=4000.0, n=0.8, cc=2.0) / 1000
    lines = [f"A,{a:g},{c:.5f}" for a, c in zip(z, ci)]
    lines += [f"B,{a:g},{huge if k == 2 else f'{c:.5f}'}" for k, (a, c) in enumerate(zip(z, ci))]
    return CSV + "\n".join(lines) + "\n"


def test_reader_and_predict_refuse_a_reading_no_soil_gives(tmp_path):
    """A CI of 1e300 MPa in a CSV (file line 11, B's third reading): the reader and predict
    refuse that profile with the located message; the other profile is fitted."""
    f = tmp_path / "site.csv"
    f.write_text(csv_text())
    msg = (
        f"file {f}, profile B, row 11, column ci_mpa: cone index 1e+303 kPa is above "
        "100 MPa, more than any soil resists (a unit error?)"
    )
    with pytest.raises(InputError) as exc:
        read_ci_profiles(f)
    assert str(exc.value) == msg + " (cell '1e300')"
    items = read_ci_profiles(f, on_error="collect")
    assert [type(it).__name__ for it in items] == ["CIProfile", "InputError"]
    assert str(items[1]) == msg + " (cell '1e300')"
    res = predict_many(items)
    assert [r.status for r in res] == ["ok", "error"] and res[1].error == str(items[1])
    out = CliRunner().invoke(cli, ["predict", str(f), "--json"])
    assert out.exit_code == 0, out.output
    doc = json.loads(out.output)
    by_id = {p["id"]: p for p in doc["profiles"]}
    assert by_id["A"]["status"] == "ok" and by_id["B"]["status"] == "error"
    assert by_id["B"]["error"] == msg + " (cell '1e300')"


def test_streaming_reader_refuses_it_too(tmp_path):
    """batch's reader (the vectorised screen of each chunk) gives the same message."""
    f = tmp_path / "site.csv"
    f.write_text(csv_text("2e5"))  # 200 GPa: a value in kPa written in an MPa column
    (chunk,) = iter_profile_sets(f, chunk_size=10)
    assert chunk.ids.tolist() == ["A"]
    assert [str(e) for e in chunk.errors] == [
        f"file {f.resolve()}, profile B, row 11, column ci_mpa: cone index 2e+08 kPa is "
        "above 100 MPa, more than any soil resists (a unit error?)"
    ]

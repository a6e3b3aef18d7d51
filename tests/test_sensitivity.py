"""terracone.apps.sensitivity: Sobol indices of the cone index.

Section 3.3 of Huang et al. remarks that the cone-terrain shear deformation
parameter Kc has little effect and leaves it out of the search.  Over the
search bounds (Kc log-uniform 0.1 mm to 10 cm) its total Sobol index must
be small against that of n, the parameter that matters most.
"""

from __future__ import annotations

import numpy as np
import pytest

from terracone.apps.sensitivity import BOXES, SOBOL_NAMES, sobol_ci


@pytest.fixture(scope="module")
def bounds_result():
    return sobol_ci(box="bounds", n_base=256, seed=1)


def test_kc_total_index_small_against_n(bounds_result):
    r = bounds_result
    assert r.names == SOBOL_NAMES
    for out in r.outputs:
        st = r.ST[out]
        assert st["n"] > 0.3, (out, st)
        assert st["Kc"] < 0.05 * st["n"], (out, st)
        assert st["Kc"] < 0.05
    # cc hardly matters either (its column is a constant ~ 3.7 cc beyond z = 0)
    assert r.ST[r.outputs[0]]["cc"] < 0.01


def test_kc_small_in_the_lete_box_and_in_log_space():
    r = sobol_ci(box="lete", n_base=128, seed=2, log=True, depths=(0.05,))
    for out in r.outputs:
        assert r.ST[out]["Kc"] < 0.1 * r.ST[out]["n"], (out, r.ST[out])


def test_indices_are_sane_and_reproducible(bounds_result):
    r = bounds_result
    for out in r.outputs:
        for nm in SOBOL_NAMES:
            assert -0.1 < r.S1[out][nm] < 1.1
            assert -0.1 < r.ST[out][nm] < 1.5
            assert r.S1[out][nm] <= r.ST[out][nm] + 0.1
        # first-order indices sum to at most ~1
        assert sum(r.S1[out].values()) < 1.1
    assert r.n_evals == 256 * (6 + 2)
    again = sobol_ci(box="bounds", n_base=256, seed=1)
    assert again.ST == r.ST and again.S1 == r.S1
    d = r.as_dict()
    assert d["Kc_distribution"] == "log-uniform"
    assert set(d["ST"]) == set(r.outputs)
    assert "Kc" in r.table()


def test_bad_box():
    box = dict(BOXES["lete"])
    del box["Kc"]
    with pytest.raises(ValueError):
        sobol_ci(box=box, n_base=8)
    box = dict(BOXES["lete"], Kc=(0.0, 0.1))
    with pytest.raises(ValueError):
        sobol_ci(box=box, n_base=8)
    assert np.isfinite(sobol_ci(box="lete", n_base=8, depths=()).ST[r"mean CI 0-30 cm"]["n"])

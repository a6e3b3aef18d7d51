"""The layered fit over phic when the boxes of kc and kphi do not nest (lower bounds above 0).

Then the optimum over phic is not at its upper bound.  The fit searches once
the relaxation whose kc and kphi boxes hold every phic's (the data fix s kc
and s kphi, eq. (2-6)); where some phic holds every layer's kc and kphi in
its box, that optimum is the optimum over all phic, and the search falls
back to a search at each of 19 values of phic only where none does.
References here: the fit at each of 19 fixed values of phic (the grid the
fit searched before issue 29; each is a feasible SSE), and noise-free data
with known truth inside the boxes.  Tolerances on the SSE, relative 1e-6.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import require_shared

from terracone.data import CIProfile, TerrainParameters
from terracone.inverse.bounds import Bounds
from terracone.inverse.layered import fit_layered
from terracone.inverse.problem import Problem
from terracone.io import read_ci_profiles
from terracone.physics.cone import get_cone
from terracone.physics.layers import layered_cone_index

CONE = get_cone("asabe-small")
BOUNDS = Bounds(kc=(1.0, 1000.0), kphi=(50.0, 20000.0))


def grid_best(prof: CIProfile, layers: int) -> float:
    """The smallest SSE of the fits at 19 fixed values of phic in the bounds."""
    out = []
    for ph in np.linspace(*BOUNDS.phic_deg, 19):
        res = fit_layered(prof, Problem(bounds=BOUNDS.fixed(phic_deg=ph)), layers=layers)
        assert res.ok, res.error
        out.append(res.sse)
    return min(out)


def test_noise_free_truth_inside_the_boxes_comes_back():
    top = TerrainParameters(kc=30.0, kphi=5000.0, n=0.6, cc=3.0, phic_deg=30.0)
    bottom = TerrainParameters(kc=8.0, kphi=1200.0, n=1.0, cc=1.0, phic_deg=30.0)
    z = np.arange(0.0, 0.451, 0.025)
    y = layered_cone_index(z, [top, bottom], [0.16], cone=CONE)
    res = fit_layered(CIProfile("clean", z, y, cone=CONE), Problem(bounds=BOUNDS), layers=2)
    assert res.ok, res.error
    assert res.sse <= 1e-12 * float(y @ y)
    lo, hi = res.phic_range
    assert lo <= 30.0 <= hi  # the equally good interval of phic holds the truth
    for got in res.layers:  # reported inside the boxes, at the interval's middle
        assert BOUNDS.kc[0] * (1 - 1e-9) <= got.kc <= BOUNDS.kc[1]
        assert BOUNDS.kphi[0] * (1 - 1e-9) <= got.kphi <= BOUNDS.kphi[1]


@pytest.fixture(scope="module")
def sc900():
    folder = require_shared("data", "marsden-penetrometer")
    items = read_ci_profiles(folder / "sc900_export_2019-06-11.txt", cone="asabe-small")
    return {p.id.rsplit("/", 1)[1]: p for p in items if hasattr(p, "depth")}


# pushes whose relaxation is feasible (0004-N2, 0010-N8) and not (0003-N1, 0023-N11: one
# layer wants kc below its box where another's kphi presses on its top)
@pytest.mark.parametrize("push", ["0004-N2", "0010-N8", "0003-N1", "0023-N11"])
def test_never_above_the_fits_at_fixed_phic(sc900, push):
    prof = sc900[push]
    res = fit_layered(prof, Problem(bounds=BOUNDS), layers=2)
    assert res.ok, res.error
    ref = grid_best(prof, 2)
    assert res.sse <= ref * (1 + 1e-6), (push, res.sse, ref)
    assert 0.0 <= res.certificate["lower_bound"] <= res.sse
    for p in res.layers:
        assert BOUNDS.kc[0] * (1 - 1e-9) <= p.kc <= BOUNDS.kc[1] * (1 + 1e-9), push
        assert BOUNDS.kphi[0] * (1 - 1e-9) <= p.kphi <= BOUNDS.kphi[1] * (1 + 1e-9), push

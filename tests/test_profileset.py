"""ProfileSet: the columnar profile model, checked against hand-built profiles."""

import numpy as np
import pytest

from terracone.data import CIProfile, InputError, ProfileSet, depth_window
from terracone.physics.cone import get_cone


def _profiles():
    big, small = get_cone("asabe-large"), get_cone("asabe-small")
    return [
        CIProfile(
            "a",
            [0.0, 0.1, 0.2],
            [100.0, 200.0, 300.0],
            big,
            {"site": "x"},
            "f.csv",
            rows=np.array([2, 3, 4]),
        ),
        CIProfile("b", [0.05, 0.15], [50.0, 60.0], small, {"site": "y", "lat": 1.5}, "g.csv"),
        CIProfile("c", [0.0, 0.3, 0.6, 0.9], [1.0, 2.0, 3.0, 4.0], big),
    ]


def test_round_trip_and_elements():
    items = _profiles() + [InputError("bad", file="f.csv", profile="z", row=9)]
    ps = ProfileSet.from_profiles(items)
    assert len(ps) == 3
    assert list(ps.counts) == [3, 2, 4]
    assert ps.offsets.tolist() == [0, 3, 5, 9]
    assert [e.profile for e in ps.errors] == ["z"]
    assert len(ps.cones) == 2 and ps.cone_idx.tolist() == [0, 1, 0]
    for a, b in zip(ps, _profiles()):
        assert a.id == b.id and a.cone == b.cone and a.source == b.source
        np.testing.assert_array_equal(a.depth, b.depth)
        np.testing.assert_array_equal(a.ci, b.ci)
    assert ps[0].rows.tolist() == [2, 3, 4]
    assert ps[1].rows.tolist() == [-1, -1]
    assert ps[0].metadata == {"site": "x", "lat": None}
    assert ps[1].metadata == {"site": "y", "lat": 1.5}
    assert ps[-1].id == "c"
    with pytest.raises(IndexError, match="profile 3 of 3"):
        ps[3]


def test_take_window_padded():
    ps = ProfileSet.from_profiles(_profiles())
    t = ps.take([2, 0])
    assert t.ids.tolist() == ["c", "a"]
    np.testing.assert_array_equal(t.ci, [1.0, 2.0, 3.0, 4.0, 100.0, 200.0, 300.0])
    assert t.metadata.column("site").to_pylist() == [None, "x"]
    w = ps.window(0.1, 0.6)
    assert w.counts.tolist() == [2, 1, 2]
    np.testing.assert_array_equal(w.depth, [0.1, 0.2, 0.15, 0.3, 0.6])
    assert w[0].rows.tolist() == [3, 4]
    zz, yy, m = ps.padded()
    assert zz.shape == (3, 4)
    np.testing.assert_array_equal(m.sum(axis=1), [3, 2, 4])
    np.testing.assert_array_equal(zz[1], [0.05, 0.15, 0.15, 0.15])
    np.testing.assert_array_equal(yy[1], [50.0, 60.0, 0.0, 0.0])
    np.testing.assert_allclose(
        ps.heights(), [c.height for c in (ps[0].cone, ps[1].cone, ps[2].cone)]
    )


def test_window_matches_profile_window_and_mask():
    p = _profiles()[2]
    assert depth_window(p.depth, None, 0.3).tolist() == [True, True, False, False]
    np.testing.assert_array_equal(p.window(0.3, None).depth, [0.3, 0.6, 0.9])


def test_bad_offsets_refused():
    with pytest.raises(ValueError, match="offsets must have 3 entries"):
        ProfileSet(["a", "b"], [0, 2], [0.0, 1.0], [1.0, 2.0], [0, 0], [get_cone("asabe-large")])
    with pytest.raises(ValueError, match="offsets must increase"):
        ProfileSet(["a"], [0, 3], [0.0, 1.0], [1.0, 2.0], [0], [get_cone("asabe-large")])

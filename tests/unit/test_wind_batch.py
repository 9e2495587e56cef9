"""Wind profiles made and tabulated at once (bayesdrag.air.wind: ``WindProfile.layered_many``,
``tables_at``; a fit's perturbed trajectories each fly their own profile) give the numbers the
one-at-a-time path gives, bit for bit."""
import numpy as np
import pytest

from bayesdrag.air.wind import WindProfile, same_shape, tables_at

EDGES = (0.0, 400.0, 900.0, 2500.0, 6000.0)


def _rows(rng, p=7, k=4):
    return rng.normal(0, 6, (p, k)), rng.normal(0, 3, (p, k))


@pytest.mark.parametrize("axis", ["altitude", "downrange"])
def test_layered_many_are_the_layered_profiles(axis):
    wx, wy = _rows(np.random.default_rng(3))
    many = WindProfile.layered_many(axis, EDGES, wx, wy)
    one = [WindProfile.layered(axis, EDGES, a, b) for a, b in zip(wx, wy)]
    s = np.linspace(-50.0, 6500.0, 1201)
    for m, o in zip(many, one):
        assert m == o and hash(m) == hash(o)
        assert np.array_equal(m.at(s), o.at(s))
        for x in (-10.0, 395.0, 400.0, 449.9, 3000.0, 7000.0):      # the scalar path reads the steps
            assert m.at_scalar(x) == o.at_scalar(x)


def test_tables_at_is_each_profile_at_the_grid():
    rng = np.random.default_rng(5)
    s = 12.5 + 4.0 * np.arange(1700)
    layered = WindProfile.layered_many("downrange", EDGES, *_rows(rng))
    # profiles with linear pieces and a step (the general constructor), sharing their levels
    levels = (0.0, 800.0, 800.0, 3000.0, 5200.0)
    general = [WindProfile("downrange", levels, tuple(rng.normal(0, 5, 5)), tuple(rng.normal(0, 5, 5)))
               for _ in range(4)]
    flat = [WindProfile("altitude", (10.0,), (float(v),), (1.0,)) for v in rng.normal(0, 5, 3)]
    for group in (layered, general, flat):
        assert all(same_shape(group[0], p) for p in group)
        assert np.array_equal(tables_at(group, s), np.stack([p.at(s) for p in group]))


def test_profiles_of_other_levels_are_not_the_same_shape():
    a = WindProfile.layered("downrange", EDGES, [1, 2, 3, 4], [0, 0, 0, 0])
    b = WindProfile.layered("downrange", (0.0, 400.0, 1000.0, 2500.0, 6000.0), [1, 2, 3, 4], [0, 0, 0, 0])
    c = WindProfile.layered("altitude", EDGES, [1, 2, 3, 4], [0, 0, 0, 0])
    assert not same_shape(a, b) and not same_shape(a, c) and same_shape(a, a)


def test_an_implausible_wind_among_many_is_named():
    wx = np.array([[1.0, 2, 3, 4], [1.0, 2, 300, 4]])
    with pytest.raises(ValueError, match="exceeds the plausible"):
        WindProfile.layered_many("downrange", EDGES, wx, np.zeros_like(wx))


@pytest.mark.parametrize("cross, base", [(False, None), (True, None),
                                         (False, WindProfile("downrange", (0.0, 5000.0), (1.0, -2.0), (0.5, 0.5)))])
def test_wind_layers_make_their_profiles_at_once(cross, base):
    from bayesdrag.effects.wind_layers import WindLayers

    lay = WindLayers("downrange", EDGES, base=base, constant_cross=cross)
    rows = np.random.default_rng(9).normal(0, 4, (6, 12))
    assert lay.profiles(rows) == [lay.profile(r) for r in rows]

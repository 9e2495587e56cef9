"""The wind_profile layers a Scheme 1 fit lays over a flight and the priors that tie them
(issue 29 part B): equal layers over the flown height or downrange distance, the round's wind as
their base, a random walk between neighbours and a declared wind_sd as each layer's prior."""
import numpy as np
import pytest

from bayesdrag.estimate.build.winds import layer_free, wind_layer_priors
from bayesdrag.air.wind import WindProfile
from bayesdrag.effects.wind_layers import PROFILE_LAYERS, WIND_STEP_SD, path_layers

#: a layer edge is rounded to 10 m; its place is checked within this [m]
EDGE_TOL_M = 10.0


def _path():
    x = np.linspace(0.0, 12000.0, 200)
    z = 4000.0 * np.sin(np.pi * x / 12000.0)           # apex 4000 m above the gun at 6 km
    return x, z


def test_layers_span_the_flown_height_and_range():
    x, z = _path()
    up = path_layers("altitude", x, z, 300.0)
    assert up.n == PROFILE_LAYERS and up.edges[0] == 300.0 and abs(up.edges[-1] - 4300.0) < 1.0
    assert np.allclose(np.diff(up.edges), 1000.0, atol=EDGE_TOL_M)
    down = path_layers("downrange", x, z, 300.0)
    assert down.edges[0] == 0.0 and abs(down.edges[-1] - 12000.0) < 1e-6
    assert path_layers("altitude", x, None, 300.0) is None


def test_the_rounds_wind_on_the_other_axis_becomes_the_base_along_the_path():
    x, z = _path()
    by_height = WindProfile("altitude", (300.0, 4300.0), (0.0, -8.0), (2.0, 2.0))
    lay = path_layers("downrange", x, z, 300.0, by_height)
    w = lay.profile(np.zeros(2 * lay.n)).at(np.array([0.0, 6000.0]))
    assert np.allclose(w[:, 0], [0.0, -8.0], atol=0.1) and np.allclose(w[:, 1], 2.0)


def test_random_walk_and_declared_level_priors():
    names = ["c1", "x0"] + [f"wind_profile.{c}_{k}" for k in (1, 2, 3) for c in ("wx", "wy")]
    free = np.ones(len(names), bool)
    free[names.index("wind_profile.wy_3")] = False
    walk = wind_layer_priors(names, free)
    assert [p.name for p in walk] == ["wind_profile.wx_2-wx_1", "wind_profile.wx_3-wx_2", "wind_profile.wy_2-wy_1"]
    assert all(p.sd == WIND_STEP_SD for p in walk)
    th = np.zeros(len(names))
    th[names.index("wind_profile.wx_2")], th[names.index("wind_profile.wx_1")] = 5.0, 2.0
    assert walk[0].fn(th) == pytest.approx(3.0) and np.asarray(walk[0].row) @ th == pytest.approx(3.0)
    both = wind_layer_priors(names, free, level_sd=1.5)
    levels = [p for p in both if p.name.startswith("wind_sd.")]
    assert len(levels) == 5 and all(p.sd == 1.5 and p.mean == 0.0 for p in levels)


def test_a_cross_wind_without_a_y_channel_is_held():
    x, z = _path()
    lay = path_layers("altitude", x, z, 0.0)
    assert layer_free(lay, "wind_profile.wy_2", ("x", "y", "z"))
    assert not layer_free(lay, "wind_profile.wy_2", ("x", "z", "v"))
    assert not layer_free(lay, f"wind_profile.wx_{PROFILE_LAYERS + 1}", ("x", "y", "z"))


# --- the layers at the fit's resolution (the diagnosis's check beside a wind profile) ----------
def test_the_fit_resolution_keeps_span_axis_base_and_cross_wind_rule():
    from dataclasses import replace

    from bayesdrag.estimate.build.winds import FIT_LAYERS, at_fit_resolution

    x, z = _path()
    coarse = replace(path_layers("altitude", x, z, 300.0, WindProfile("altitude", (300.0, 4300.0), (1.0, 2.0),
                                                                      (0.0, 0.0))), constant_cross=True)
    fine = at_fit_resolution(coarse)
    assert fine.n == FIT_LAYERS and fine.edges[0] == coarse.edges[0] and fine.edges[-1] == coarse.edges[-1]
    assert fine.axis == coarse.axis and fine.base == coarse.base and fine.constant_cross
    assert at_fit_resolution(fine) is None and at_fit_resolution(None) is None


#: a BIC price per edge parameter of ln(1000) samples [deviance]
PENALTY_PER_EDGE = float(np.log(1000.0))


def _step_fits(scale, cold_extra=0.0):
    """A fake fit of a wind stepping +6 -> -7 m/s at 3.5 km downrange: each layer's wind is the
    step's value at its centre, and the deviance grows by ``scale`` per metre between the step
    and the nearest edge; a fit from the plain start (``start`` None) lands ``cold_extra`` higher."""
    from types import SimpleNamespace

    def fit(lay, start):
        e = np.asarray(lay.edges)
        centres = 0.5 * (e[1:] + e[:-1])
        wx = np.where(centres < 3500.0, 6.0, -7.0)
        names = [f"wind_profile.{c}_{k}" for k in range(1, lay.n + 1) for c in ("wx", "wy")]
        theta = np.ravel(np.column_stack([wx, np.zeros(lay.n)]))
        d = scale * float(np.min(np.abs(e - 3500.0))) + (cold_extra if start is None else 0.0)
        return d, (None, SimpleNamespace(names=names, theta=theta))
    return fit


def test_an_edge_is_placed_at_a_wind_step_when_the_drop_beats_its_bic_price():
    from bayesdrag.estimate.build.winds import placed_layers

    x = np.linspace(0.0, 10000.0, 200)
    equal = path_layers("downrange", x, 0.0 * x + 100.0, 0.0, n=10)
    score = _step_fits(scale=0.2)
    d0, fit0 = score(equal, "start")
    lay, _ = placed_layers(equal, fit0, d0, score, lambda k: k * PENALTY_PER_EDGE)
    # a quarter layer halved three times: within 1/32 of a layer (31 m) and the 10 m rounding
    assert np.min(np.abs(np.asarray(lay.edges) - 3500.0)) <= 1000.0 / 32 + EDGE_TOL_M
    assert lay.edges[0] == equal.edges[0] and lay.edges[-1] == equal.edges[-1] and lay.n == equal.n


def test_the_equal_grid_stays_when_the_drop_is_within_the_price_or_the_plain_start_disagrees():
    from bayesdrag.estimate.build.winds import placed_layers

    x = np.linspace(0.0, 10000.0, 200)
    equal = path_layers("downrange", x, 0.0 * x + 100.0, 0.0, n=10)
    pen = lambda k: k * PENALTY_PER_EDGE           # noqa: E731
    weak = _step_fits(scale=0.005)                 # 500 m from the step: a drop of 2.5 < ln 1000
    d0, fit0 = weak(equal, "start")
    assert placed_layers(equal, fit0, d0, weak, pen)[0] is equal
    split = _step_fits(scale=0.2, cold_extra=3.0 * PENALTY_PER_EDGE)   # separate optima
    d0, fit0 = split(equal, "start")
    assert placed_layers(equal, fit0, d0, split, pen)[0] is equal


def _placement_fit(d, coef, ok=True):
    """A fake ``(problem, MLResult, extras, effects)`` of one placement: its drag coefficients."""
    from types import SimpleNamespace

    return d, (None, SimpleNamespace(drag_params=np.asarray(coef, float)), (), ("wind_profile",) if ok else ())


def test_the_placements_tried_give_cd_model_error_weighted_by_their_likelihood():
    from bayesdrag.drag import ReferenceScale, ReferenceTable
    from bayesdrag.estimate.build.winds import equivalent_placements, placement_sd

    model = ReferenceScale(reference=ReferenceTable((0.5, 3.0), (0.3, 0.3)))   # Cd = 0.3 x factor
    kept = _placement_fit(100.0, [1.0])
    tried = [kept, _placement_fit(100.0, [1.02]), _placement_fit(100.0 + 2.0 * np.log(4.0), [0.98]),
             _placement_fit(np.inf, [3.0]), _placement_fit(99.0, [5.0], ok=False)]
    found = equivalent_placements(tried, kept[1])
    np.testing.assert_array_equal(found[0], [1.0])
    # the failed try and the one that fitted no wind are left out; deviance 2 ln 4 higher weighs 1/4
    assert sorted(float(a[0]) for a in found[1]) == [0.98, 1.0, 1.02]
    np.testing.assert_allclose(sorted(found[2]), [1.0 / 9.0, 4.0 / 9.0, 4.0 / 9.0], rtol=1e-12)
    sd = placement_sd(model, found, np.array([1.0, 2.0]))
    np.testing.assert_allclose(sd, 0.3 * np.sqrt((4.0 * 0.02**2 + 1.0 * 0.02**2) / 9.0), rtol=1e-12)
    assert equivalent_placements([kept], kept[1]) is None
    np.testing.assert_array_equal(placement_sd(model, None, np.array([1.0, 2.0])), 0.0)

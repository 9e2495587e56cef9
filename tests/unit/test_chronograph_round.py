"""One chronograph shot fitted as a round: the rules that keep its model to what a speed-only
track 0.1 s long can tell (the path angle held by a prior, one factor on the table over a narrow
Mach span) and the campaign nodes a narrow span still gets."""
import math

import numpy as np
import pytest

from bayesdrag.campaign.pooling import NODE_NARROW, NODE_SPACING, mach_nodes
from bayesdrag.estimate.build.launch import FLAT_FIRE_SD_DEG, PATH_ANGLE_TURN_MAX, path_angle_prior
from bayesdrag.estimate.build.model_size import NARROW_SPAN_MACH, narrow_span_model
from bayesdrag.round import Launch, Projectile, Round
from bayesdrag.track import RadarTrack

G = 9.80665


def _track(t_end, v=750.0, channels=("v",)):
    t = np.arange(0.008, t_end, 1e-3)
    speed = v - 300.0 * t
    chans = {"v": speed} if channels == ("v",) else {"x": speed * t, "z": 0 * t + 1.0, "v": speed}
    return RadarTrack(t, chans)


def _round(elevation=None):
    launch = Launch() if elevation is None else Launch(elevation_deg=elevation)
    return Round(Projectile(mass=0.0092, diameter=0.0067), launch=launch)


def test_a_short_speed_only_track_gets_a_flat_fire_path_angle_prior():
    (pri,) = path_angle_prior(_track(0.09), _round(), ("v",), 3)
    assert pri.name == "path_angle" and pri.mean == 0.0 and pri.sd == FLAT_FIRE_SD_DEG
    theta = np.zeros(9)
    theta[3 + 3], theta[3 + 5] = 700.0, 700.0 * math.tan(math.radians(1.5))   # vx, vz after 3 drag params
    assert pri.fn(theta) == pytest.approx(1.5, abs=1e-9)


def test_the_stated_elevation_less_the_gravity_turn_is_the_prior():
    trk = _track(0.09)
    (pri,) = path_angle_prior(trk, _round(elevation=3.0), ("v",), 1)
    turn = math.degrees(G * math.cos(math.radians(3.0)) * trk.t[0] / trk.channels["v"][0])
    assert pri.mean == pytest.approx(3.0 - turn, abs=1e-12)


def test_no_path_angle_prior_when_the_track_sees_it_or_turns():
    assert path_angle_prior(_track(0.09, channels=("x", "z", "v")), _round(), ("x", "z", "v"), 1) == ()
    # a flight that turns more than the limit tells its path angle by the change of g sin(gamma)
    long = _track(8.0, v=2500.0)
    assert G * long.t[-1] / long.channels["v"].min() > PATH_ANGLE_TURN_MAX
    assert path_angle_prior(long, _round(elevation=10.0), ("v",), 1) == ()
    # longer than a chronograph's reach without a stated elevation: not assumed flat
    mid = _track(2.0, v=2500.0)
    assert G * mid.t[-1] / mid.channels["v"].min() < PATH_ANGLE_TURN_MAX
    assert path_angle_prior(mid, _round(), ("v",), 1) == ()


def test_the_default_spline_gives_way_to_one_factor_only_over_a_narrow_span_with_a_table():
    narrow = (2.06, 2.06 + 0.9 * NARROW_SPAN_MACH)
    assert narrow_span_model(narrow, True, "spline", None) == "reference-scale"
    assert narrow_span_model(narrow, False, "spline", None) is None          # no table: the spline
    assert narrow_span_model(narrow, True, "poly2", None) is None            # the user's choice
    assert narrow_span_model(narrow, True, "spline", (2.06, 2.1, 2.15)) is None
    assert narrow_span_model((2.0, 2.0 + 1.1 * NARROW_SPAN_MACH), True, "spline", None) is None


def test_a_narrow_span_gets_campaign_nodes_on_the_fine_lattice():
    m = mach_nodes(0.721, 0.745)            # a pistol bullet: no node of the 0.05 lattice inside
    assert m.size >= 2 and np.allclose(m / NODE_NARROW, np.round(m / NODE_NARROW))
    assert np.all((m >= 0.721) & (m <= 0.745))
    wide = mach_nodes(0.8, 2.4)
    assert np.isclose(wide[-1], 2.4) and np.isclose(wide[1] - wide[0], NODE_SPACING)
    assert mach_nodes(0.7231, 0.7239).size == 0


def test_a_span_holding_no_node_is_refused_with_its_reason():
    from bayesdrag.campaign.pooling import check_input
    doc = {"name": "s1", "mach": [], "cd": [], "cov": [], "cd_crb_sd": [], "reference": None,
           "mach_range": [0.7231, 0.7239], "covariance": "colored", "drag_model": "reference-scale"}
    with pytest.raises(ValueError, match="holds no campaign node"):
        check_input(doc)

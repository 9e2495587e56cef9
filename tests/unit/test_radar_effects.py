"""The radar's biases and site as effects (issue 28): they act on what the radar records, not on
the flight, through the same inputs the declared radar sources use, and exist only where the
track has a channel they act on."""
import math

import numpy as np
import pytest

from bayesdrag.effects import (EFFECTS, EffectContext, RADAR_EFFECT_CHANNELS, check_radar_effects, effect_fn,
                               radar_effect_missing, unabsorbed_fraction)
from bayesdrag.errors import InputError
from bayesdrag.measure import RadarSite, channel_values
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.estimate.model.problem import outputs
from bayesdrag.estimate.build.sources import plan_effects
from bayesdrag.io.drag_tables import load_m101

NATIVE = ("range", "azimuth", "elevation", "range_rate")
#: a shell 3 km out and 1.5 km up, climbing away [m, m/s]
STATE = np.array([3000.0, 40.0, 1500.0, 500.0, 5.0, 300.0])
SITE = RadarSite((-40.0, 25.0, 2.0), math.radians(90.0))
#: agreement of two ways of computing one channel [channel units]
EXACT = 1e-9


def test_the_design_names_with_their_units():
    assert set(RADAR_EFFECT_CHANNELS) == {"range_bias", "azimuth_bias", "elevation_bias", "radar_position"}
    assert [p.name for p in EFFECTS["radar_position"].params] == ["x", "y", "z"]
    assert EFFECTS["range_bias"].units == ("m",)
    assert EFFECTS["azimuth_bias"].units == EFFECTS["elevation_bias"].units == ("rad",)


def test_biases_add_to_their_channel_and_the_site_moves_the_line_of_sight():
    fn = effect_fn([EFFECTS[n] for n in ("range_bias", "elevation_bias", "radar_position")], EffectContext())
    inp = fn(np.array([[5.0, 1e-3, 2.0, -3.0, 1.0]]))
    assert inp.overrides == {} and inp.time_shift is None
    y = outputs(STATE[None, None], NATIVE, SITE, offset=inp.output_offset, site_shift=inp.site_shift)[0, 0]
    moved = RadarSite((-38.0, 22.0, 3.0), SITE.azimuth, range_bias=5.0, elevation_bias=1e-3)
    assert np.max(np.abs(y - channel_values(STATE, NATIVE, moved))) < EXACT


@pytest.mark.parametrize("name, channels, missing", [
    ("range_bias", ("range_rate",), "range"), ("azimuth_bias", ("range", "elevation"), "azimuth"),
    ("elevation_bias", ("x", "y", "z", "v"), "elevation"), ("radar_position", ("x", "y", "z", "v"), "radar-native")])
def test_an_effect_without_its_channel_is_refused_by_name(name, channels, missing):
    assert missing in radar_effect_missing(name, channels)
    with pytest.raises(InputError, match=f"t.csv: effect '{name}' acts on the radar's .* has no {missing}"):
        check_radar_effects([name], channels, "t.csv")


def test_effects_with_their_channel_or_not_of_the_radar_pass():
    assert radar_effect_missing("radar_position", ("range_rate",)) is None
    assert radar_effect_missing("wind", ("x",)) is None
    check_radar_effects(["wind", "range_bias", "elevation_bias"], ("range", "elevation"), "t.csv")


def test_a_declared_source_of_the_same_quantity_is_the_one_fitted():
    rnd = Round(Projectile("p", 42.6, 0.155, load_m101(), None), Launch(45.0, 818.0, azimuth_deg=90.0),
                radar=Radar({"elevation": 1e-3}, elevation_bias_sd=math.radians(0.05)))
    keep, skipped = plan_effects(["elevation_bias", "range_bias"], rnd)
    assert keep == ("range_bias",)
    assert "elevation_bias_sd" in skipped["elevation_bias"]


def test_the_unabsorbed_share_of_a_column():
    nuis = np.array([[1.0], [0.0], [0.0]])
    frac = unabsorbed_fraction(nuis, np.array([[2.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]))
    assert np.allclose(frac, [0.0, math.sqrt(0.5), 0.0], atol=EXACT)

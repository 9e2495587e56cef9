"""Adding an effect, shown (issue 50): the toy effect of tests/support/toy_effect.py -- one module,
no package file edited -- registered for a ``with`` block, is taken by the diagnosis, by the fit's
``--with`` (``with_effects``), by the declared sources' mapping and by the planner's, and is gone
again after the block (docs/architecture.md, "Adding an effect")."""
import numpy as np
import pytest

import bayesdrag
from bayesdrag.diagnosis import diagnose
from bayesdrag.effects import EFFECTS, ExtraParam, get_effect, registered
from bayesdrag.estimate.build.sources import source_fn
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.planning.case import systematic_effect_fn
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round
from support.toy_effect import SPEED_SCALE

SIG = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: the radar's speed scale error put into the track [-]
TRUE_SCALE = 0.004
#: how near the fitted scale must come [-] (its sd on this track is ~4e-4)
SCALE_TOL = 1e-3


@pytest.fixture(scope="module")
def case():
    """A short flat flight (QE 5 deg, 2 s of it at 20 Hz) whose radar speed reads 0.4 % high."""
    rnd = Round(Projectile("155", 42.6, 0.155, load_m101()), Launch(elevation_deg=5.0, velocity=818.0),
                radar=Radar(dict(SIG)))
    tr = simulate_round(rnd, dt=0.05)
    keep = tr.t <= 2.0
    ch = {c: np.asarray(v)[keep] for c, v in tr.channels.items()}
    ch["v"] = ch["v"] * (1.0 + TRUE_SCALE)
    tr = add_noise(bayesdrag.track.RadarTrack(tr.t[keep], ch), SIG, np.random.default_rng(3))
    return tr, rnd


def test_registration_is_undone_after_the_block():
    with registered(SPEED_SCALE):
        assert get_effect("speed_scale") is SPEED_SCALE
    assert "speed_scale" not in EFFECTS
    with pytest.raises(ValueError, match="unknown effect 'speed_scale'"):
        get_effect("speed_scale")
    with pytest.raises(ValueError, match="already in the library"):
        with registered(EFFECTS["wind"]):
            pass


def test_the_diagnosis_finds_the_toy_effect(case):
    tr, rnd = case
    with registered(SPEED_SCALE):
        s = diagnose(tr, rnd, candidates=["wind", "speed_scale"]).record
    assert s["verdict"][:1] == ["speed_scale"]
    row = next(r for r in s["effects"] if r["name"] == "speed_scale")
    assert row["params"]["s"] == pytest.approx(TRUE_SCALE, abs=SCALE_TOL)


def test_the_fit_takes_it_with_with_effects(case):
    tr, rnd = case
    with registered(SPEED_SCALE):
        res = bayesdrag.fit(tr, rnd, with_effects=("speed_scale",), mcmc=False)
    w = res.to_dict()["ml"]["with_effects"]
    assert w["fitted"] == ["speed_scale"]
    assert w["sizes"]["speed_scale.s"]["value"] == pytest.approx(TRUE_SCALE, abs=SCALE_TOL)


def test_the_declared_sources_and_the_planner_map_it_through_its_own_mapping():
    extra = ExtraParam("speed_scale.s", 0.0, -0.1, 0.1, 1e-5)
    with registered(SPEED_SCALE):
        fit_inputs = source_fn((("speed_scale", extra, 0.0, 0.01),), Round(Projectile("155", 42.6, 0.155)),
                               model=None)(np.array([[0.02]]))
        plan_inputs = systematic_effect_fn(Round(Projectile("155", 42.6, 0.155)),
                                           [("speed_scale", extra, 0.01)])(np.array([[0.02]]))
    assert fit_inputs.output_scale["v"] == pytest.approx([1.02])
    assert plan_inputs.output_scale["v"] == pytest.approx([1.02])

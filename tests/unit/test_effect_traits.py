"""An effect's traits say what the package's effect-name tuples said (issue 50, "then traits"):
each set derived from the traits equals, as a set, the tuple of names it will replace. While the
tuples stand, this test keeps the two from drifting apart; when a tuple goes, its line here goes
with it."""
import pytest

from bayesdrag import effects as E
from bayesdrag.diagnosis.found_air import AIR_EFFECTS
from bayesdrag.diagnosis.selection import DRAG_EFFECTS
from bayesdrag.diagnosis.setup import CROSS_RANGE_EFFECTS
from bayesdrag.diagnosis.winds import TRADE_PARTNERS, WIND_FAMILY
from bayesdrag.estimate.build.sources import CONFOUNDED_EFFECTS, EFFECT_SOURCE, TRADES_WITH_CD
from bayesdrag.pipeline.model_check import LEVEL_EFFECTS, NOT_ALTERNATIVES
from bayesdrag.round import SYSTEMATIC_SOURCES


@pytest.mark.parametrize("derived, tuple_today", [
    (E.confounded_with_cd, CONFOUNDED_EFFECTS),
    (E.confounded_with_cd, DRAG_EFFECTS),
    (E.partly_trading_with_cd, TRADES_WITH_CD),
    (E.partly_trading_with_cd, LEVEL_EFFECTS),
    (E.air_effects, AIR_EFFECTS),
    (E.wind_effects, WIND_FAMILY),
    (E.drag_along_the_flight, TRADE_PARTNERS),
    (E.not_alternatives, NOT_ALTERNATIVES),
    (E.cross_range_effects, CROSS_RANGE_EFFECTS),
])
def test_a_trait_derived_set_equals_the_tuple_it_replaces(derived, tuple_today):
    assert set(derived()) == set(tuple_today)


def test_declared_sources_come_from_the_effects():
    assert E.effect_sources(SYSTEMATIC_SOURCES) == EFFECT_SOURCE


def test_every_effect_has_valid_traits():
    for e in E.EFFECTS.values():
        assert e.acts_on in ("air", "drag", "flight", "measurement"), e.name
        assert e.drag_change in (None, "level", "shape", "partly"), e.name
        assert e.seen_by in ("all", "cross_range"), e.name
        assert set(e.needs) <= {"latitude", "reference", "wind_layers", "radar_channels"}, e.name

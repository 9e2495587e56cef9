"""The effect library: every :class:`~.base.Effect` the package knows, in the order of
``diagnosis.json`` (:data:`EFFECTS`), and the questions the rest of the code asks it instead of
testing an effect's name (:func:`effects_where` and the named queries). An effect is added by one
entry in its concept's module and one line here; a test adds one for a while with
:func:`registered` (undone on leaving the ``with`` block)."""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from .air import DENSITY, TEMPERATURE
from .base import EffectContext, effect_fn, static_model
from .drag import DRAG_SCALE, DRAG_SHAPE
from .flight import CORIOLIS, LIFT, WIND, WIND_PROFILE, YAW_DRAG
from .inputs import SimInputs
from .radar import AZIMUTH_BIAS, ELEVATION_BIAS, RADAR_POSITION, RADAR_TIME, RANGE_BIAS

__all__ = ["EFFECTS", "registered", "get_effect", "effects_where", "confounded_with_cd", "partly_trading_with_cd",
           "air_effects", "wind_effects", "drag_along_the_flight", "not_alternatives", "cross_range_effects",
           "drag_level_effects", "air_state_effects", "spanning_effects", "effect_sources", "simulate_with_effects"]

#: the effect library by name (the order of diagnosis.json)
EFFECTS = {e.name: e for e in (WIND, TEMPERATURE, DENSITY, CORIOLIS, YAW_DRAG, LIFT, RADAR_TIME, DRAG_SCALE,
                               WIND_PROFILE, DRAG_SHAPE, RANGE_BIAS, AZIMUTH_BIAS, ELEVATION_BIAS, RADAR_POSITION)}


@contextmanager


def registered(*effects):
    """The library with ``effects`` added for the ``with`` block, and as before after it (a new
    effect tried, or a test's toy effect): the diagnosis, ``--with``, the declared sources and the
    planner all read :data:`EFFECTS` when they run.

    Raises
    ------
    ValueError
        When an effect's name is already in the library.
    """
    taken = [e.name for e in effects if e.name in EFFECTS]
    if taken:
        raise ValueError(f"effects {', '.join(taken)} are already in the library; give a new effect its own name")
    for e in effects:
        EFFECTS[e.name] = e
    try:
        yield EFFECTS
    finally:
        for e in effects:
            EFFECTS.pop(e.name, None)


def effects_where(test):
    """Names of the library's effects for which ``test(effect)`` holds, in the library's order:
    the one way code outside this module asks which effects share a trait, instead of keeping a
    tuple of their names."""
    return tuple(n for n, e in EFFECTS.items() if test(e))


def confounded_with_cd():
    """Effects that *are* Cd when fitted beside it without a declared sd: a constant factor on
    the drag or a change of its shape (``density``, ``drag_scale``, ``drag_shape``)."""
    return effects_where(lambda e: e.drag_change in ("level", "shape"))


def partly_trading_with_cd():
    """Effects fitted beside Cd of which a part trades with it (``temperature``, ``yaw_drag``)."""
    return effects_where(lambda e: e.drag_change == "partly")


def air_effects():
    """Effects on the air the shell flies through (``wind``, ``wind_profile``, ``temperature``,
    ``density``)."""
    return effects_where(lambda e: e.acts_on == "air")


def wind_effects():
    """The winds: air effects that leave the drag law alone (``wind``, ``wind_profile``)."""
    return effects_where(lambda e: e.acts_on == "air" and e.drag_change is None)


def drag_along_the_flight():
    """Effects that change the drag along the whole flight as a wind changing along it does
    (``temperature``, ``density``, ``drag_scale``, ``drag_shape``): a wind profile's partners in
    trade."""
    return effects_where(lambda e: e.drag_change in ("level", "shape")
                         or (e.drag_change == "partly" and e.acts_on == "air"))


def not_alternatives():
    """Effects that never stand as a close alternative to a verdict (their shift is Cd's own or
    is sized apart): those partly trading with Cd and the air's level (``temperature``,
    ``density``, ``yaw_drag``)."""
    return effects_where(lambda e: e.drag_change == "partly" or (e.acts_on == "air" and e.drag_change == "level"))


def cross_range_effects():
    """Effects only a drift across the line of fire shows (``lift``)."""
    return effects_where(lambda e: e.seen_by == "cross_range")


def drag_level_effects():
    """Effects that are a constant factor on the drag (``density``, ``drag_scale``): twins in their
    signature, one stands for both."""
    return effects_where(lambda e: e.drag_change == "level")


def air_state_effects():
    """Effects on the air's state, not its motion (``temperature``, ``density``): what a found air
    is conditional on."""
    return effects_where(lambda e: e.acts_on == "air" and e.drag_change is not None)


def spanning_effects():
    """Effects whose parameters span a family of curves (``wind_profile``'s layers,
    ``drag_shape``'s correction): they contain the drag-like effects they are confounded with."""
    return effects_where(lambda e: e.drag_change == "shape" or "wind_layers" in e.needs)


def effect_sources(stems):
    """``{effect: source stem}`` of the effects that are a declared source among ``stems``."""
    return {n: e.source for n, e in EFFECTS.items() if e.source in stems}


def get_effect(name):
    """The :class:`Effect` called ``name``; raises ValueError naming the allowed ones."""
    try:
        return EFFECTS[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


def param_unit(name):
    """The unit of a fitted parameter called ``<effect>.<param>`` (``"rad"`` for
    ``azimuth_bias.bias``), or ``""`` for any other name (a drag coefficient, the initial state)."""
    stem, _, param = str(name).partition(".")
    e = EFFECTS.get(stem)
    if e is None:
        return ""
    return next((u for p, u in zip(e.params, e.units) if p.name == param), "")


def simulate_with_effects(model, drag_params, state0, t_out, effects=(), values=(), ctx=None,
                          t_start=0.0):
    """One trajectory with effects switched on (the forward model the diagnosis fits).

    Parameters
    ----------
    model : PointMassModel
    drag_params : (P,) array
    state0 : (6,) array, state at ``t_start``
    t_out : (N,) array, s (radar times; ``radar_time`` evaluates the model at t + dt)
    effects : sequence of Effect or names
    values : sequence of float, the effects' parameters side by side (diagnosis.json units, but
        ``yaw_drag`` takes its fitted amplitude ``k delta0^2``)
    ctx : EffectContext

    Returns
    -------
    (N, 6) states and (N,) Mach.
    """
    effects = [get_effect(e) if isinstance(e, str) else e for e in effects]
    ctx = ctx or EffectContext(atmosphere=model.atmosphere)
    model = static_model(model, effects, ctx)
    values = np.asarray(values, dtype=float).reshape(1, -1)
    inp = effect_fn([e for e in effects if e.k], ctx, np.asarray(state0, float))(values) \
        if any(e.k for e in effects) else SimInputs()
    shift = 0.0 if inp.time_shift is None else float(inp.time_shift[0])
    tr = model.simulate_batch(np.asarray(drag_params, float)[None], np.asarray(state0, float)[None],
                              np.asarray(t_out, float) + shift, t_start=t_start,
                              overrides=inp.overrides, atmospheres=inp.atmospheres)
    return tr.state[0], tr.mach[0]

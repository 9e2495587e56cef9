"""Declared systematic sources (the round's ``_sd`` keys, the radar's biases and site, the
launch yaw a fit assumes): how each enters the simulation. A source that is an effect's quantity
(:attr:`Effect.source`: density, temperature, the radar clock, its biases and site) enters through
that effect's own mapping (:attr:`Effect.to_inputs`); the others (mass and diameter, the radar's
scale factors, the launch yaw) through :data:`OWN_SOURCE_INPUTS`. The fit's declared sources
(:func:`bayesdrag.estimate.build.sources.source_fn`) and the planner's simulated ones
(:mod:`bayesdrag.planning.case`) are both :func:`sources_fn`."""
from __future__ import annotations

import math

import numpy as np

from ..dynamics import kernel as K
from .air import temperature_nodes
from .base import EffectContext, add_inputs
from .inputs import SimInputs
from .library import EFFECTS

__all__ = ["sources_fn", "sources_context", "source_effect", "OWN_SOURCE_INPUTS", "LAUNCH_YAW_DECAY", "T_NODE_SDS",
           "T_NODE_MIN"]

# ----------------------------------------------------------------------------------------------
# declared systematic sources: how each enters the simulation
#: decay rate [1/s] of the launch yaw a fit assumes for a spinning shell whose lift the track
#: shows (its amplitude is the ``yaw_drag`` effect's; :func:`bayesdrag.estimate.build.sources.assumed_extras`)
LAUNCH_YAW_DECAY = 0.5


def _drag_constant_inputs(cols, ctx):
    """Mass and diameter: the drag constant ``k = pi d^2 / (8 m)``."""
    B = next(iter(cols.values())).shape[0]
    m = cols["mass"][:, 0] if "mass" in cols else np.full(B, ctx.mass)
    d = cols["diameter"][:, 0] if "diameter" in cols else np.full(B, ctx.diameter)
    return {"overrides": {K.P_KREF: math.pi * d * d / (8.0 * m)}}


def _position_scale_inputs(cols, ctx):
    s = 1.0 + cols["position_scale"][:, 0]
    return {"output_scale": {c: s for c in ("x", "y", "z")}}


def _velocity_scale_inputs(cols, ctx):
    return {"output_scale": {"v": 1.0 + cols["velocity_scale"][:, 0]}}


def _launch_yaw_inputs(cols, ctx):
    a = cols["launch_yaw"][:, 0]
    return EFFECTS["yaw_drag"].to_inputs(np.column_stack([a, np.full(a.shape[0], LAUNCH_YAW_DECAY)]), ctx, None)


#: the declared sources that are no effect's quantity: the stems each reads -> how they enter
#: the simulation (``fn(cols, ctx) -> dict`` as :meth:`Effect.apply`); a source that is an
#: effect's quantity (``Effect.source``) enters through that effect's :attr:`Effect.to_inputs`
OWN_SOURCE_INPUTS = {
    ("mass", "diameter"): _drag_constant_inputs,
    ("position_scale",): _position_scale_inputs,
    ("velocity_scale",): _velocity_scale_inputs,
    ("launch_yaw",): _launch_yaw_inputs,
}


#: a declared temperature's interpolation nodes at +-T_NODE_SDS declared sd ...
T_NODE_SDS = 3.0


#: ... and at least this far [K]
T_NODE_MIN = 0.5


def sources_context(sds, mass, diameter, atmosphere):
    """The :class:`EffectContext` of :func:`sources_fn` for the fit's declared sources ``sds``
    (``{stem: sd}``): the nominal mass [kg] and diameter [m], and a declared temperature's
    nodes (:func:`temperature_nodes` at +-:data:`T_NODE_SDS` sd, at least :data:`T_NODE_MIN`
    K) on the nominal atmosphere ``atmosphere()`` (a callable: asked only then)."""
    T = EFFECTS["temperature"]
    nodes = None
    if T.source in sds:
        nodes = temperature_nodes(atmosphere(), max(T_NODE_SDS * sds[T.source], T_NODE_MIN))
    return EffectContext(mass=mass, diameter=diameter, temperature_nodes=nodes)


def source_effect(stem):
    """The library's effect that is the declared source ``stem`` (None: no effect is)."""
    return next((e for e in EFFECTS.values() if e.source == stem), None)


def sources_fn(stems, ctx, inner=None, n_inner=0):
    """``effect_fn`` of declared sources whose parameters follow ``n_inner`` others: the fit's
    declared sources (after its ``--with`` effects) and the planner's simulated ones alike.

    Parameters
    ----------
    stems : sequence of str
        The source of each parameter in order (``radar_position``: three consecutive ones).
    ctx : EffectContext
        With the nominal mass and diameter when those are declared, and ``temperature_nodes``
        for the temperature as tables.
    inner : callable, optional
        ``effect_fn`` of the first ``n_inner`` parameters.

    Returns
    -------
    callable ``E (B, n_inner + len(stems)) -> SimInputs``: the inner inputs with each source's
    added by field (:func:`add_inputs`).
    """
    groups = {}
    for k, s in enumerate(stems):
        groups.setdefault(s, []).append(n_inner + k)
    steps = []
    done = set()
    for s in groups:
        if s in done:
            continue
        own = next((g for g in OWN_SOURCE_INPUTS if s in g), None)
        if own is not None:
            read = tuple(x for x in own if x in groups)
            done.update(read)
            steps.append((read, OWN_SOURCE_INPUTS[own]))
            continue
        eff = source_effect(s)
        if eff is None or eff.to_inputs is None:
            raise ValueError(f"declared source {s!r}: no effect or source mapping enters it into the simulation")
        done.add(s)
        steps.append(((s,), (lambda cols, c, s=s, eff=eff: eff.to_inputs(cols[s], c, None))))

    def fn(E):
        E = np.atleast_2d(np.asarray(E, float))
        inp = inner(E[:, :n_inner]) if inner is not None else SimInputs()
        for read, f in steps:
            inp = add_inputs(inp, f({s: E[:, groups[s]] for s in read}, ctx), "declared sources and effects")
        return inp

    return fn

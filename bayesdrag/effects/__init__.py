"""The unmodelled-effect library of the sim-to-real gap diagnosis (``diagnosis.json``), the fit's
``--with`` effects, the declared sources and the planner: one concept in one folder.

Modules: :mod:`.base` (the :class:`Effect` value, its context, how effects compose),
:mod:`.air` (temperature, density), :mod:`.flight` (winds, Coriolis, yaw drag, lift),
:mod:`.drag` (drag scale and shape, :class:`ShapedTable`), :mod:`.radar` (clock, biases, site),
:mod:`.library` (:data:`EFFECTS` and the queries on the traits), :mod:`.sources` (how declared
sources enter the simulation), :mod:`.inputs` (the plain values an effect hands the simulation)
and :mod:`.wind_layers` (the wind profile's layers and the model that flies them). Adding an
effect: docs/architecture.md, "Adding an effect".

Each :class:`Effect` is one physical reason a point-mass simulation with the firing-table drag
and the round's atmosphere misses a measured track. It has named parameters (with units,
bounds, finite-difference steps and a "no effect" value), a short physical explanation, and a
mapping of a batch of parameter values (B, k) onto the batched point-mass kernel
(:meth:`PointMassModel.simulate_batch`): kernel override columns, per-trajectory atmospheres or
a radar clock offset. Effects compose: :func:`effect_fn` turns a list of effects into the
``effect_fn`` of :class:`bayesdrag.estimate.model.problem.OutputErrorProblem`, whose extra parameters are
the effects' parameters side by side.

=============  =====================  ========================================================
name           parameters             how it enters the simulation
=============  =====================  ========================================================
wind           wx, wy [m/s]           kernel columns ``P_WX, P_WY`` (air moves toward +x, +y)
wind_profile   wx_k, wy_k [m/s],      layers of constant wind by height or by downrange distance
               k = 1..K               (:class:`WindLayers`, set by the diagnosis), flown through
                                      the kernel's per-trajectory wind tables
                                      (:class:`WindProfileModel`)
temperature    dT [K]                 per-trajectory :class:`Atmosphere` with the profile shifted
                                      by dT at unchanged pressure at the gun (density *and*
                                      speed of sound change)
density        ratio [-]              kernel column ``P_RHO_SCALE`` (speed of sound unchanged)
coriolis       (none)                 the model's Coriolis matrix from ``[launch] latitude`` and
                                      ``azimuth``
yaw_drag       delta0 [rad],          Cd (1 + k delta0^2 exp(-2 decay t)), kernel columns
               decay [1/s]            ``P_YAW_AMP = k delta0^2``, ``P_YAW_DECAY``; k = K_YAW
lift           factor [-]             kernel columns ``P_LIFT = factor * 0.02 * v0`` and
                                      ``P_LIFT_VERT = LIFT_VERTICAL_FRACTION * v0`` (modified
                                      point mass: lift and vertical force on the yaw of repose,
                                      Mach shape, spin decay; :func:`pointmass.lift_parameter`)
radar_time     dt [s]                 the model is evaluated at ``t + dt`` (recorded = true - dt)
drag_scale     factor [-]             kernel column ``P_CD_SCALE``
drag_shape     s1..s8 [-]             the firing table times a smooth correction without a
                                      level (:class:`ShapedTable`, :class:`DragShapeModel`)
range_bias     bias [m]               added to the radar's measured range (``SimInputs.output_offset``)
azimuth_bias   bias [rad]             added to its measured azimuth
elevation_bias bias [rad]             added to its measured elevation
radar_position x, y, z [m]            the radar stands this far from its stated site
                                      (``SimInputs.site_shift``): every native channel is seen
                                      from there
=============  =====================  ========================================================

Decisions (and why):

* ``yaw_drag`` is fitted internally with the *amplitude* ``a = K_YAW delta0^2`` (name
  ``yaw_amp``), not delta0: the trajectory is linear in ``a`` but flat in delta0 at 0, where a
  Gauss-Newton fit that starts at "no effect" would never move. ``a`` may go slightly negative
  (an early drag deficit, unphysical) so that the estimator is regular around the null and the
  significance test is honest; reports give ``delta0 = sqrt(a / K_YAW)`` (signed).
  ``K_YAW = 10 /rad^2`` is C_D_delta2 / C_D0 of a typical shell (3-4 over 0.3-0.4; the 6-DOF
  M107-like table has 2.9-4.0).
* ``radar_time`` shifts the evaluation times; samples that fall before the initial state
  (an *early* radar clock with the state at launch) are extrapolated backwards to second order
  from the initial state (|dt| <= 0.2 s: below 2 mm for a shell).
* ``coriolis`` has no parameters: Earth rotation is known physics once latitude and azimuth
  are; without a latitude the candidate cannot be formed and the diagnosis says so.
* ``lift`` uses the round's launch velocity as the spin-setting speed when given, else the
  speed of the fitted initial state.
* ``drag_shape`` is what a firing table of *another shell* does to a point-mass simulation: its
  Cd(M) has the wrong shape, not just the wrong level. It multiplies the table by
  ``1 + sum_k s_k phi_k(M)``, ``phi_k = B_k - a_k``: cubic B-splines ``B_1..B_K`` on knots over
  the flown Mach span (:func:`drag_shape_knots`: denser where the table itself bends, where
  shells differ most) less constants ``a_k``: their Mach means by default, and in the diagnosis
  the constants that make each shape function move the track orthogonally to a constant drag
  factor (:func:`level_free_offsets`). So the correction carries no level: a constant factor is
  ``drag_scale`` (== ``density``), and the two compose into a full smooth correction without a
  degenerate direction (a zero *Mach* mean alone let an end coefficient carry a level change).
  A table of another shell gets ``drag_shape`` with ``drag_scale`` or its twin ``density``.
  There is no Mach-dependent kernel column, so the effect enters as a drag model:
  :func:`static_model` wraps the model in a :class:`DragShapeModel` whose drag is a
  :class:`ShapedTable` with parameters ``(1, s_1..s_K)`` per trajectory. Its number of
  coefficients depends on the span (at most :data:`DRAG_SHAPE_MAX`); unused ones are held at 0
  (:func:`drag_shape_free`). It needs a reference table: without one the diagnosis' nuisance
  spline *is* the drag shape.
* ``wind_profile`` is horizontal wind in a few layers, each ``(wx_k, wy_k)`` constant over its
  layer (steps spread over 100 m, :data:`bayesdrag.air.wind.WIND_STEP_WIDTH`), the layers either by
  height above the gun (met practice) or along the path by downrange distance (how small-arms
  tools and py-ballisticcalc zone winds). Neighbouring layers are tied by a random-walk prior
  (their difference has sd :data:`WIND_STEP_SD`), so a layer the data hardly see follows its
  neighbours instead of wandering. The layers (axis and edges, :class:`WindLayers`) are the
  context's; their number is at most :data:`WIND_LAYERS_MAX` (unused ones held at 0). The wind
  adds to the round's own (a met profile's): it is what the round did not state.
* The radar's effects act on the measurement, not on the flight: they enter as the fields the
  declared radar sources use (``SimInputs.output_offset``, ``site_shift``), so an effect and a
  source of the same quantity are one model, and exist only where the track has a channel they
  act on (:func:`bayesdrag.measure.geometry.site_error_missing`). Angle biases in rad, as
  ``result.json`` gives the declared ones; ``radar_position``'s coordinates the channels cannot
  see are held at 0 (``EffectContext.radar_axes``: a range rate from a site on the line of fire
  sees no ``y``).
* ``drag_scale`` may go further from 1 than ``density`` (bounds 0.2-5 against 0.5-1.6): a table
  off by a factor two is a table of another shell, not air that thin or thick, so with such a
  gap the two twins no longer tie and the drag is named.
"""
from __future__ import annotations

from dataclasses import dataclass, field  # noqa: F401  (exported by the former bayesdrag/effects.py)

from ..air.atmosphere import Atmosphere  # noqa: F401
from ..drag import DragModel, ReferenceTable, Spline  # noqa: F401
from ..dynamics.forces import LIFT_VERTICAL_FRACTION, coriolis_matrix, lift_parameter  # noqa: F401
from .air import DENSITY, TEMPERATURE, temperature_nodes
from .base import Effect, EffectContext, add_inputs, effect_fn, extra_params, static_model, unabsorbed_fraction
from .drag import DRAG_SCALE, DRAG_SHAPE, DRAG_SHAPE_BOUND, DRAG_SHAPE_KEY, DRAG_SHAPE_MAX, DRAG_SHAPE_RISE_WEIGHT, \
    DRAG_SHAPE_STEP, DragShapeModel, ShapedTable, drag_shape_free, drag_shape_knots, drag_shape_model, \
    level_free_offsets
from .flight import CORIOLIS, K_YAW, LIFT, WIND, WIND_PROFILE, YAW_AMP_MAX, YAW_DECAY_MIN, YAW_DRAG
from .inputs import ExtraParam, SimInputs
from .library import EFFECTS, air_effects, air_state_effects, drag_level_effects, spanning_effects, confounded_with_cd, cross_range_effects, drag_along_the_flight, \
    effect_sources, effects_where, get_effect, not_alternatives, partly_trading_with_cd, registered, \
    param_unit, simulate_with_effects, wind_effects
from .radar import ANGLE_BIAS_MAX, AZIMUTH_BIAS, ELEVATION_BIAS, RADAR_EFFECT_CHANNELS, RADAR_POSITION, RADAR_TIME, \
    RANGE_BIAS, RANGE_BIAS_MAX, SITE_ERRORS, SITE_OFFSET_MAX, SITE_SEEN_FRACTION, check_radar_effects, \
    radar_effect_missing
from .sources import LAUNCH_YAW_DECAY, OWN_SOURCE_INPUTS, T_NODE_MIN, T_NODE_SDS, source_effect, sources_context, \
    sources_fn
from .wind_layers import WIND_LAYERS_MAX, WIND_LEVEL_SD, WIND_PROFILE_KEY, WIND_STEP_SD, WindLayers, \
    WindProfileModel, wind_profile_free

__all__ = [
    # the value, its context, how effects compose
    "Effect", "EffectContext", "ExtraParam", "SimInputs", "add_inputs", "effect_fn", "extra_params", "static_model",
    "unabsorbed_fraction",
    # the library and its queries
    "EFFECTS", "registered", "get_effect", "effects_where", "confounded_with_cd", "partly_trading_with_cd",
    "air_effects", "wind_effects", "drag_along_the_flight", "not_alternatives", "cross_range_effects",
    "effect_sources", "simulate_with_effects", "param_unit", "drag_level_effects", "air_state_effects", "spanning_effects",
    # the effects by concept
    "WIND", "TEMPERATURE", "DENSITY", "CORIOLIS", "YAW_DRAG", "LIFT", "RADAR_TIME", "DRAG_SCALE", "WIND_PROFILE",
    "DRAG_SHAPE", "RANGE_BIAS", "AZIMUTH_BIAS", "ELEVATION_BIAS", "RADAR_POSITION",
    "temperature_nodes", "K_YAW", "YAW_AMP_MAX", "YAW_DECAY_MIN",
    "DRAG_SHAPE_BOUND", "DRAG_SHAPE_KEY", "DRAG_SHAPE_MAX", "DRAG_SHAPE_RISE_WEIGHT", "DRAG_SHAPE_STEP",
    "DragShapeModel", "ShapedTable", "drag_shape_free", "drag_shape_knots", "drag_shape_model", "level_free_offsets",
    "ANGLE_BIAS_MAX", "RADAR_EFFECT_CHANNELS", "RANGE_BIAS_MAX", "SITE_ERRORS", "SITE_OFFSET_MAX",
    "SITE_SEEN_FRACTION", "check_radar_effects", "radar_effect_missing",
    "WIND_LAYERS_MAX", "WIND_LEVEL_SD", "WIND_PROFILE_KEY", "WIND_STEP_SD", "WindLayers", "WindProfileModel",
    "wind_profile_free",
    # declared sources
    "LAUNCH_YAW_DECAY", "OWN_SOURCE_INPUTS", "T_NODE_MIN", "T_NODE_SDS", "source_effect", "sources_context",
    "sources_fn",
]

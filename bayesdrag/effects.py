"""The unmodelled-effect library of the sim-to-real gap diagnosis (``diagnosis.json``).

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

import math
from dataclasses import dataclass, field

import numpy as np

from .air.atmosphere import Atmosphere
from .drag import DragModel, ReferenceTable, Spline
from .dynamics import kernel as K
from .dynamics.forces import LIFT_VERTICAL_FRACTION, coriolis_matrix, lift_parameter
from .effect_inputs import ExtraParam, SimInputs
from .measure.geometry import SITE_ERRORS, check_site_errors as check_radar_effects, \
    site_error_missing as radar_effect_missing
from .wind_layers import WIND_LAYERS_MAX, WIND_LEVEL_SD, WIND_PROFILE_KEY, WIND_STEP_SD, WindLayers, \
    WindProfileModel, wind_profile_free

#: induced-drag factor k in Cd (1 + k delta^2) [1/rad^2] (C_D_delta2 / C_D0 of a typical shell)
K_YAW = 10.0
#: largest yaw amplitude k delta0^2 a yaw_drag fit may take: delta0 = 0.3 rad (17 deg). A stable
#: shell leaves the muzzle with a few degrees; beyond this it tumbles. Without the bound a
#: yaw_drag at 0.4 rad that never damps stood in for a firing table 2.4 times too low
YAW_AMP_MAX = K_YAW * 0.3**2
#: slowest yaw decay [1/s] (amplitude e-folding in 10 s): a launch yaw of a stable shell damps in
#: 1-3 s; a "yaw" that does not damp over the flight is a constant drag factor (drag_scale)
YAW_DECAY_MIN = 0.1
#: largest number of drag_shape coefficients (the cubic B-splines on at most DRAG_SHAPE_MAX - 2
#: knot intervals, less the first, whose place the level -- drag_scale -- takes): enough to follow another shell's
#: drag rise relative to the table, few enough that a fit stays cheap (2 (6 + K) trajectories
#: per sensitivity batch)
DRAG_SHAPE_MAX = 8
#: one knot interval per this much "weighted Mach length" (Mach width plus the table's total
#: log-variation over the span, so a steep rise counts as wide as its change in ln Cd)
DRAG_SHAPE_STEP = 0.4
#: the knots are equidistributed in Mach + ln Cd(table): a rise's change in ln Cd counts this
#: many times its Mach width
DRAG_SHAPE_RISE_WEIGHT = 1.0
#: bound on each drag_shape coefficient (a relative Cd change): the standard tables and M101
#: differ in shape, their best common factor taken out, by at most 0.44 (G7 against the sphere
#: GS over Mach 0.5-2.5; median pair 0.27), and a B-spline coefficient at a sharp rise exceeds
#: the curve it makes (0.74 for an M101 shell against a G1 table). With +-2 an 8-coefficient
#: correction alternating in sign stood in for an 8 % density change on a flight that samples
#: the Mach range unevenly
DRAG_SHAPE_BOUND = 1.0
#: override key of drag_shape's coefficients (not a kernel column: read by DragShapeModel)
DRAG_SHAPE_KEY = "drag_shape"
#: the radar's effects and the channels each acts on (it exists only where the track has one)
RADAR_EFFECT_CHANNELS = SITE_ERRORS
#: bounds of a fitted range bias [m] and angle bias [rad] (0.05 rad = 2.9 deg: a radar that far
#: off its boresight is not tracking this shell) and site offset [m]
RANGE_BIAS_MAX = 200.0
ANGLE_BIAS_MAX = 0.05
SITE_OFFSET_MAX = 500.0
#: a coordinate of ``radar_position`` whose signature the nuisance parameters leave less of than
#: this share is held at 0 (:func:`unabsorbed_fraction`; the diagnosis' identifiability share)
SITE_SEEN_FRACTION = 0.02


@dataclass(frozen=True)
class EffectContext:
    """What an effect needs to know about the round besides its parameters.

    Attributes
    ----------
    atmosphere : Atmosphere
        The round's (nominal) atmosphere.
    wind_layers : WindLayers or None
        The layers of ``wind_profile`` (axis, edges); None: the effect cannot be formed.
    latitude_deg, azimuth_deg : float or None
        Coriolis geometry (None: unknown latitude).
    v0 : float or None, m/s
        Launch velocity (spin-setting speed for ``lift``).
    drag_shape : ShapedTable or None
        The table-times-correction drag of ``drag_shape`` over the flown Mach span
        (:func:`drag_shape_model`); None: the effect cannot be formed (no reference table).
    """

    atmosphere: Atmosphere = field(default_factory=Atmosphere)
    latitude_deg: float | None = None
    azimuth_deg: float = 0.0
    v0: float | None = None
    drag_shape: object = None
    wind_layers: object = None
    #: the coordinates of ``radar_position`` the track's channels see (the others held at 0)
    radar_axes: tuple = ("x", "y", "z")


@dataclass(frozen=True)
class Effect:
    """One unmodelled effect.

    Attributes
    ----------
    name : str
    params : tuple of ExtraParam
        Fitted parameters (their ``start`` is the "no effect" value).
    units : tuple of str
    explanation : str
        One or two sentences of physics for the report.
    acts_on : {"air", "drag", "flight", "measurement"}
        What it changes: the air the shell flies through, its drag, its flight otherwise (forces
        other than drag, Earth rotation), or only what the radar records.
    drag_change : {None, "level", "shape", "partly"}
        How it trades with the Cd a fit estimates: a constant factor on the drag (``"level"``: the
        Cd level itself), a change of the drag's shape in Mach (``"shape"``), a part of it that
        does (``"partly"``: a temperature's density part, a decaying yaw's early drag), or none.
    source : str or None
        The declared systematic source (round key stem ``<source>_sd``) that is the same quantity.
    needs : tuple of str
        What the round or the fit must give for the effect to be formed (``"latitude"``,
        ``"reference"``: a firing table, ``"wind_layers"``, ``"radar_channels"``).
    seen_by : {"all", "cross_range"}
        The channels that see it (``"cross_range"``: only a drift across the line of fire).
    """

    name: str
    params: tuple
    units: tuple
    explanation: str
    acts_on: str = "flight"
    drag_change: str | None = None
    source: str | None = None
    needs: tuple = ()
    seen_by: str = "all"

    @property
    def k(self):
        """Number of parameters."""
        return len(self.params)

    @property
    def null(self):
        """Parameter values meaning "no effect", shape (k,)."""
        return np.array([p.start for p in self.params])

    def apply(self, values, ctx, state0=None):
        """Kernel inputs for a batch of parameter values.

        Parameters
        ----------
        values : (B, k) array
        ctx : EffectContext
        state0 : (B, 6) array, optional
            Initial states (``lift`` without a launch velocity).

        Returns
        -------
        dict with optional keys ``overrides`` (column -> (B,)), ``atmospheres`` (list of B
        Atmosphere), ``time_shift`` ((B,) s), ``output_offset`` (channel -> (B,): a radar's
        bias), ``site_shift`` ((B, 3) m: where the radar stands against its stated site).
        """
        values = np.atleast_2d(values)
        B = values.shape[0]
        n = self.name
        if n == "wind":
            return {"overrides": {K.P_WX: values[:, 0], K.P_WY: values[:, 1]}}
        if n == "density":
            return {"overrides": {K.P_RHO_SCALE: values[:, 0]}}
        if n == "drag_scale":
            return {"overrides": {K.P_CD_SCALE: values[:, 0]}}
        if n == "yaw_drag":
            return {"overrides": {K.P_YAW_AMP: values[:, 0], K.P_YAW_DECAY: values[:, 1]}}
        if n == "temperature":
            a = ctx.atmosphere
            return {"atmospheres": [_shifted_atmosphere(a, float(d)) for d in values[:, 0]]}
        if n == "radar_time":
            return {"time_shift": values[:, 0].copy()}
        if n in ("range_bias", "azimuth_bias", "elevation_bias"):
            return {"output_offset": {RADAR_EFFECT_CHANNELS[n][0]: values[:, 0].copy()}}
        if n == "radar_position":
            return {"site_shift": values[:, :3].copy()}
        if n == "lift":
            v0 = ctx.v0 if ctx.v0 is not None else (
                np.linalg.norm(np.asarray(state0)[:, 3:], axis=1) if state0 is not None else 800.0)
            v0 = np.broadcast_to(np.asarray(v0, dtype=float), (B,))
            return {"overrides": {K.P_LIFT: lift_parameter(values[:, 0], v0),
                                  K.P_LIFT_VERT: LIFT_VERTICAL_FRACTION * v0}}
        if n == "drag_shape":
            return {"overrides": {(DRAG_SHAPE_KEY, i): values[:, i] for i in range(self.k)}}
        if n == "wind_profile":
            if ctx.wind_layers is None:
                raise ValueError("the wind_profile effect needs its layers (EffectContext.wind_layers: axis and "
                                 "edges, laid over the track by the fit or the diagnosis)")
            return {"overrides": {(WIND_PROFILE_KEY, i): values[:, i] for i in range(self.k)}}
        if n == "coriolis":
            if ctx.latitude_deg is None:
                raise ValueError("the coriolis effect needs [launch] latitude")
            C = coriolis_matrix(ctx.latitude_deg, ctx.azimuth_deg).ravel()
            ov = {K.P_COR + i: np.full(B, C[i]) for i in range(9)}
            ov[K.P_HAS_COR] = np.ones(B)
            return {"overrides": ov}
        raise ValueError(f"unknown effect {n!r}; known: {', '.join(EFFECTS)}")

    def report_params(self, values):
        """Parameters as reported in diagnosis.json (names and units of the file format)."""
        values = np.asarray(values, dtype=float)
        if self.name == "yaw_drag":
            a = float(values[0])
            return {"delta0": math.copysign(math.sqrt(abs(a) / K_YAW), a), "decay": float(values[1])}
        return {p.name: float(v) for p, v in zip(self.params, values)}

    def report_sd(self, values, cov):
        """Standard deviations of the reported parameters (delta method for ``yaw_drag``)."""
        sd = np.sqrt(np.clip(np.diag(np.atleast_2d(cov)), 0, None)) if self.k else np.zeros(0)
        if self.name == "yaw_drag":
            a = abs(float(values[0]))
            d0 = math.sqrt(a / K_YAW)
            sd0 = sd[0] / (2 * K_YAW * d0) if d0 > 0 else math.sqrt(sd[0] / K_YAW)
            return {"delta0": float(sd0), "decay": float(sd[1])}
        return {p.name: float(s) for p, s in zip(self.params, sd)}


def _shifted_atmosphere(a, dT):
    """The round's atmosphere with its temperature offset moved by dT [K] (rounded to 1e-6 K so
    the memoised tables are re-used between finite-difference batches)."""
    from dataclasses import replace

    return replace(a, temperature_offset=round(a.temperature_offset + dT, 6))


def _make_effects():
    E = [
        Effect("wind", (ExtraParam("wx", 0.0, -60.0, 60.0, 0.02), ExtraParam("wy", 0.0, -60.0, 60.0, 0.02)),
               ("m/s", "m/s"),
               "A constant horizontal wind changes the airspeed: a headwind (wx < 0) adds drag and "
               "shortens the range, a crosswind (wy) drifts the shell downwind.", acts_on="air"),
        Effect("temperature", (ExtraParam("dT", 0.0, -60.0, 60.0, 0.05),), ("K",),
               "A warmer day (dT > 0) at the same pressure at the gun thins the air (less drag, "
               "longer range) and raises the speed of sound, moving Cd(M) along the flight.",
               acts_on="air", drag_change="partly", source="temperature"),
        Effect("density", (ExtraParam("ratio", 1.0, 0.5, 1.6, 1e-4),), ("-",),
               "Air density differs from the model's by a constant factor (pressure or humidity "
               "error); drag scales with it, the speed of sound does not.",
               acts_on="air", drag_change="level", source="density"),
        Effect("coriolis", (), (),
               "Earth rotation: a Coriolis acceleration -2 Omega x v deflects the shell to the right "
               "in the northern hemisphere and changes range with the firing azimuth.", needs=("latitude",)),
        Effect("yaw_drag", (ExtraParam("yaw_amp", 0.0, -0.5, YAW_AMP_MAX, 1e-3),
                            ExtraParam("decay", 0.5, YAW_DECAY_MIN, 5.0, 1e-3)), ("rad", "1/s"),
               "A launch disturbance leaves the shell yawing; the yaw damps out but adds induced "
               "drag Cd k delta^2 early in the flight, a range loss concentrated after launch.",
               acts_on="drag", drag_change="partly"),
        Effect("lift", (ExtraParam("factor", 0.0, -10.0, 10.0, 0.01),), ("-",),
               "Lift on the yaw of repose of a spinning shell (modified point mass): a drift to the "
               "right for a right-hand twist, growing with time of flight, and a small rise from the "
               "Magnus force on the same yaw; factor 1 is a typical shell.", seen_by="cross_range"),
        Effect("radar_time", (ExtraParam("dt", 0.0, -0.2, 2.0, 1e-4),), ("s",),
               "The radar clock is late by dt: every sample shows the shell where it was dt later, "
               "so the track does not start at the muzzle at t = 0.", acts_on="measurement", source="time_offset"),
        Effect("drag_scale", (ExtraParam("factor", 1.0, 0.2, 5.0, 1e-4),), ("-",),
               "This shell's drag is a constant factor times the firing table (lot, fuze, driving "
               "band or form differences); identical in its signature to a density ratio.",
               acts_on="drag", drag_change="level"),
        Effect("wind_profile", tuple(ExtraParam(f"{c}_{k + 1}", 0.0, -60.0, 60.0, 0.02)
                                     for k in range(WIND_LAYERS_MAX) for c in ("wx", "wy")),
               ("m/s",) * (2 * WIND_LAYERS_MAX),
               "A horizontal wind that changes along the flight, in layers of constant wind by height "
               "or by downrange distance: a wind that turns from tail to head, or strengthens with "
               "height, changes the airspeed differently in each part of the flight.",
               acts_on="air", source="wind_profile", needs=("wind_layers",)),
        Effect("drag_shape", tuple(ExtraParam(f"s{i + 1}", 0.0, -DRAG_SHAPE_BOUND, DRAG_SHAPE_BOUND, 1e-4)
                                   for i in range(DRAG_SHAPE_MAX)),
               ("-",) * DRAG_SHAPE_MAX,
               "The firing table has the wrong shape for this shell (a table of another shell: its "
               "drag rise earlier, later, higher or lower): the table times a smooth correction in "
               "Mach that carries no overall level (the level is drag_scale).",
               acts_on="drag", drag_change="shape", needs=("reference",)),
        Effect("range_bias", (ExtraParam("bias", 0.0, -RANGE_BIAS_MAX, RANGE_BIAS_MAX, 0.01),), ("m",),
               "The radar's range is off by a constant (a calibration or cable delay): every range it "
               "records is the true one plus the bias.", acts_on="measurement", source="range_bias",
               needs=("radar_channels",)),
        Effect("azimuth_bias", (ExtraParam("bias", 0.0, -ANGLE_BIAS_MAX, ANGLE_BIAS_MAX, 1e-6),), ("rad",),
               "The radar's azimuth is off by a constant (its north alignment or encoder): the shell "
               "appears turned sideways by the bias, more metres the further it flies.", acts_on="measurement",
               source="azimuth_bias", needs=("radar_channels",)),
        Effect("elevation_bias", (ExtraParam("bias", 0.0, -ANGLE_BIAS_MAX, ANGLE_BIAS_MAX, 1e-6),), ("rad",),
               "The radar's elevation is off by a constant (levelling or boresight): the shell appears "
               "higher or lower by the bias, more metres the further it flies.", acts_on="measurement",
               source="elevation_bias", needs=("radar_channels",)),
        Effect("radar_position", tuple(ExtraParam(c, 0.0, -SITE_OFFSET_MAX, SITE_OFFSET_MAX, 0.01) for c in "xyz"),
               ("m", "m", "m"),
               "The radar stands elsewhere than the round says (x downrange, y right, z up of its "
               "stated site): its range, angles and range rate are seen from another place, which "
               "the track shows as a start away from the muzzle and lines of sight that turn wrongly.",
               acts_on="measurement", source="radar_position", needs=("radar_channels",)),
    ]
    return {e.name: e for e in E}


#: the effect library by name (the order of diagnosis.json)
EFFECTS = _make_effects()


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


def effect_sources(stems):
    """``{effect: source stem}`` of the effects that are a declared source among ``stems``."""
    return {n: e.source for n, e in EFFECTS.items() if e.source in stems}


def get_effect(name):
    """The :class:`Effect` called ``name``; raises ValueError naming the allowed ones."""
    try:
        return EFFECTS[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


def unabsorbed_fraction(nuisance, cols):
    """Share of each column's norm (k,) that the span of ``nuisance`` (n, q) leaves: how much of an
    effect parameter's signature (weighted output sensitivities, prior rows appended) is more than
    the nuisance parameters can make (:data:`SITE_SEEN_FRACTION`)."""
    Q, _ = np.linalg.qr(nuisance)
    norms = np.linalg.norm(cols, axis=0)
    left = np.linalg.norm(cols - Q @ (Q.T @ cols), axis=0)
    return np.where(norms > 0, left / np.where(norms > 0, norms, 1.0), 0.0)


def extra_params(effects):
    """ExtraParam list for a sequence of effects; parameter names are prefixed with the effect
    name (``wind.wx``) so that several effects can be fitted together."""
    return tuple(ExtraParam(f"{e.name}.{p.name}", p.start, p.lower, p.upper, p.step)
                 for e in effects for p in e.params)


def effect_fn(effects, ctx, base_state0=None):
    """``effect_fn`` for :class:`OutputErrorProblem` combining ``effects``.

    Parameters
    ----------
    effects : sequence of Effect
    ctx : EffectContext
    base_state0 : (6,) array, optional
        Initial state used for ``lift`` when ``ctx.v0`` is None.

    Returns
    -------
    callable ``E (B, sum k) -> SimInputs``. Two effects setting the same kernel column are
    rejected (they would overwrite each other).
    """
    effects = tuple(effects)

    def fn(E):
        E = np.atleast_2d(E)
        B = E.shape[0]
        ov, atm, shift, offset, site = {}, None, None, {}, None
        j = 0
        for e in effects:
            s0 = None if base_state0 is None else np.tile(base_state0, (B, 1))
            out = e.apply(E[:, j:j + e.k] if e.k else np.zeros((B, 0)), ctx, s0)
            j += e.k
            for col, v in out.get("overrides", {}).items():
                if col in ov:
                    raise ValueError(f"effects {', '.join(x.name for x in effects)} set the same kernel column")
                ov[col] = np.asarray(v, float)
            if "atmospheres" in out:
                atm = out["atmospheres"]
            if "time_shift" in out:
                shift = out["time_shift"]
            for c, v in out.get("output_offset", {}).items():
                offset[c] = np.asarray(v, float) + offset.get(c, 0.0)
            if "site_shift" in out:
                site = out["site_shift"] if site is None else site + out["site_shift"]
        return SimInputs(ov, atm, shift, output_offset=offset, site_shift=site)

    return fn


def static_model(model, effects, ctx):
    """Effects that change the model itself folded into it: ``coriolis`` (its Coriolis matrix),
    ``drag_shape`` (a :class:`DragShapeModel` around it, whose drag takes the effect's
    coefficients from the kernel inputs) and ``wind_profile`` (a :class:`WindProfileModel`,
    whose winds take the layers' values from the kernel inputs)."""
    for e in effects:
        if e.name == "coriolis" and e.k == 0:
            if ctx.latitude_deg is None:
                raise ValueError("the coriolis effect needs [launch] latitude")
            model = model.with_(coriolis=(ctx.latitude_deg, ctx.azimuth_deg))
        if e.name == "wind_profile":
            if ctx.wind_layers is None:
                raise ValueError("the wind_profile effect needs its layers (EffectContext.wind_layers: axis and "
                                 "edges, laid over the track by the fit or the diagnosis)")
            model = WindProfileModel(model, ctx.wind_layers)
        if e.name == "drag_shape":
            if ctx.drag_shape is None:
                raise ValueError("the drag_shape effect needs a reference drag table and the flown Mach span "
                                 "(EffectContext.drag_shape from drag_shape_model)")
            if model.drag.n_params != 0:
                raise ValueError(f"the drag_shape effect multiplies a fixed reference table; the model's drag "
                                 f"{model.drag.name!r} has {model.drag.n_params} free coefficients (no table)")
            model = DragShapeModel(model, ctx.drag_shape)
    return model


# ----------------------------------------------------------------------------------------------
# drag_shape: the table times a zero-mean smooth correction
def drag_shape_knots(reference, mach_min, mach_max, max_params=DRAG_SHAPE_MAX, step=DRAG_SHAPE_STEP,
                     rise_weight=DRAG_SHAPE_RISE_WEIGHT):
    """Knots of the ``drag_shape`` correction over the flown Mach span.

    The knots equidistribute ``1 + rise_weight |d ln Cd_table / dM|`` over [mach_min, mach_max]:
    where the table rises or falls steeply (the transonic rise, where shells differ most: a boat
    tail rises later and sharper than a flat base, a sphere earlier) they are closer. Their
    number is one interval per ``step`` of that weighted length, between 1 and
    ``max_params - 2`` (``n`` intervals give ``n + 3`` B-splines, ``n + 2`` zero-mean shape
    functions).

    Parameters
    ----------
    reference : ReferenceTable
    mach_min, mach_max : float
        Flown Mach span.
    max_params, step, rise_weight : see :data:`DRAG_SHAPE_MAX`, :data:`DRAG_SHAPE_STEP`,
        :data:`DRAG_SHAPE_RISE_WEIGHT`.

    Returns
    -------
    (n + 1,) ndarray of Mach numbers, ends included, rounded to 0.01.
    """
    lo, hi = float(mach_min), float(mach_max)
    if not hi > lo:
        raise ValueError(f"drag_shape needs a Mach span with mach_max > mach_min, got [{lo}, {hi}]")
    m = np.linspace(lo, hi, 401)
    f = np.clip(np.asarray(reference.value(m), float), 1e-4, None)
    dens = 1.0 + rise_weight * np.abs(np.gradient(np.log(f), m))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(m))])
    n = int(np.clip(math.ceil(cum[-1] / step - 1e-9), 1, max(max_params - 2, 1)))
    inner = np.interp(np.linspace(0.0, cum[-1], n + 1)[1:-1], cum, m)
    knots = np.unique(np.round(np.concatenate([[lo], inner, [hi]]), 2))
    knots[0], knots[-1] = min(knots[0], lo), max(knots[-1], hi)
    return knots


@dataclass(frozen=True, eq=False)
class ShapedTable(DragModel):
    """Cd(M) = table(M) (c_0 + sum_k c_k phi_k(M)), ``phi_k = B_k - a_k`` (k = 1..K): the drag
    curve of the ``drag_shape`` effect. ``c_0 = 1`` always (the effect's coefficients are
    ``c_1..c_K``); ``B_1..B_K`` are the cubic B-splines on ``knots`` (:class:`bayesdrag.drag.Spline`)
    less the first, and ``a_k`` constants: by default their Mach means over the knot span (a
    correction of zero Mach mean); the diagnosis sets them so that each shape function moves the
    track orthogonally to a constant factor (:func:`level_free_offsets`).

    Attributes
    ----------
    reference : ReferenceTable
    knots : tuple of float
    offsets : tuple of float or None
        ``a_1..a_K`` (None: the Mach means).
    """

    reference: ReferenceTable = None
    knots: tuple = ()
    offsets: tuple | None = None
    name: str = field(default="table-shape", init=False)

    def __post_init__(self):
        if not isinstance(self.reference, ReferenceTable):
            raise ValueError("drag_shape needs a reference drag table (round's projectile.reference_drag)")
        spl = Spline(tuple(self.knots))
        if self.offsets is None:
            m = np.linspace(spl.knots[0], spl.knots[-1], 801)
            off = spl.basis(m).mean(axis=0)[1:]
        else:
            off = np.asarray(self.offsets, float)
            if off.shape != (spl.n_params - 1,) or not np.all(np.isfinite(off)):
                raise ValueError(f"drag_shape offsets must be {spl.n_params - 1} finite numbers, got {self.offsets!r}")
        object.__setattr__(self, "knots", spl.knots)
        object.__setattr__(self, "_spline", spl)
        object.__setattr__(self, "offsets", tuple(float(v) for v in off))
        object.__setattr__(self, "_means", np.concatenate([[0.0], off]))

    @property
    def n_shape(self):
        """Number of shape coefficients K (B-splines less one)."""
        return self._spline.n_params - 1

    @property
    def param_names(self):
        return ("c0",) + tuple(f"s{i + 1}" for i in range(self.n_shape))

    def shape_basis(self, mach):
        """Zero-mean shape functions (N, K) at ``mach``."""
        return self._spline.basis(np.asarray(mach, float))[..., 1:] - self._means[1:]

    def shape_slope(self, mach):
        return self._spline.basis_slope(np.asarray(mach, float))[..., 1:]

    def correction(self, coefs, mach):
        """Relative Cd change ``sum_k s_k phi_k(M)`` for coefficients (K,) at ``mach``."""
        return self.shape_basis(mach) @ np.asarray(coefs, float)

    def basis(self, mach):
        m = np.asarray(mach, dtype=float)
        t = self.reference.value(m)[..., None]
        return np.concatenate([t, t * self.shape_basis(m)], axis=-1)

    def basis_slope(self, mach):
        m = np.asarray(mach, dtype=float)
        t, dt = self.reference.value(m)[..., None], self.reference.slope(m)[..., None]
        phi = self.shape_basis(m)
        return np.concatenate([dt, dt * phi + t * self.shape_slope(m)], axis=-1)

    @property
    def bounds(self):
        P = self.n_params
        return np.full(P, -20.0), np.full(P, 20.0)

    @property
    def fit_range(self):
        return (self.knots[0], self.knots[-1])


def drag_shape_model(reference, mach_span, offsets=None):
    """The :class:`ShapedTable` of ``drag_shape`` for a table and a flown Mach span (lo, hi)."""
    return ShapedTable(reference, tuple(drag_shape_knots(reference, *mach_span)), offsets)


def level_free_offsets(shape, S, A_nuisance=None):
    """Offsets ``a_k`` that make each shape function of ``shape`` move the track orthogonally to
    a constant drag factor, so that ``drag_shape`` cannot mimic ``drag_scale`` (or ``density``)
    to first order: a zero *Mach* mean does not stop a coefficient at a sparsely flown end of the
    span from carrying a level change for the rest of the flight.

    Parameters
    ----------
    shape : ShapedTable
        With its current offsets.
    S : (n, K + 1) array
        Noise-weighted output sensitivities (stacked samples x channels) to ``c_0..c_K`` at the
        baseline: column 0 is the constant factor.
    A_nuisance : (n, q) array, optional
        Sensitivities of the nuisance parameters (the initial state, with the launch priors as
        extra rows in all arrays) projected out first: the level direction is what is left of
        a constant factor once the initial state has taken what it can.

    Returns
    -------
    (K,) ndarray: the new offsets (``shape.offsets`` plus the projections).
    """
    S = np.asarray(S, float)
    if A_nuisance is not None and A_nuisance.size:
        Q, _ = np.linalg.qr(A_nuisance)
        S = S - Q @ (Q.T @ S)
    lev = S[:, 0]
    nn = float(lev @ lev)
    b = (S[:, 1:].T @ lev) / nn if nn > 0 else np.zeros(S.shape[1] - 1)
    return np.asarray(shape.offsets, float) + b


def drag_shape_free(ctx, index):
    """Is drag_shape's coefficient ``index`` (0-based) used on this track? (The span sets how
    many there are; the rest are held at 0.)"""
    return ctx.drag_shape is not None and index < ctx.drag_shape.n_shape


class DragShapeModel:
    """A point-mass model whose drag is ``shape`` (:class:`ShapedTable`) with the coefficients
    ``(1, s_1..s_K)`` read per trajectory from the kernel inputs' ``(DRAG_SHAPE_KEY, k)``
    entries (the ``drag_shape`` effect). Everything else is the wrapped model's; its own drag
    (the fixed table) is what :attr:`drag` reports, so the fit's parameter layout is unchanged.

    Parameters
    ----------
    model : PointMassModel
        With a parameter-free drag (the reference table).
    shape : ShapedTable
    """

    def __init__(self, model, shape):
        self.model = model
        self.shape = shape
        self._shaped = model.with_(drag=shape)

    def __getattr__(self, name):
        return getattr(self.model, name)

    def with_(self, **changes):
        """Copy with some attributes of the wrapped model changed (the shape kept)."""
        return DragShapeModel(self.model.with_(**changes), self.shape)

    def simulate_batch(self, drag_params, state0, t_out, *, overrides=None, **kw):
        """As :meth:`PointMassModel.simulate_batch`; ``overrides`` may hold the shape
        coefficients under ``(DRAG_SHAPE_KEY, k)`` (missing ones are 0)."""
        ov = dict(overrides or {})
        keys = sorted((k for k in ov if isinstance(k, tuple) and k[0] == DRAG_SHAPE_KEY), key=lambda k: k[1])
        B = max(np.atleast_2d(np.asarray(state0, float)).shape[0], np.atleast_2d(drag_params).shape[0])
        coef = np.zeros((B, self.shape.n_params))
        coef[:, 0] = 1.0
        for k in keys:
            v = ov.pop(k)
            if k[1] < self.shape.n_shape:
                coef[:, 1 + k[1]] = np.broadcast_to(np.asarray(v, float), (B,))
        return self._shaped.simulate_batch(coef, state0, t_out, overrides=ov or None, **kw)


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


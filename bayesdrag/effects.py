"""The unmodelled-effect library of the sim-to-real gap diagnosis (DESIGN.md, ``diagnosis.json``).

Each :class:`Effect` is one physical reason a point-mass simulation with the firing-table drag
and the round's atmosphere misses a measured track. It has named parameters (with units,
bounds, finite-difference steps and a "no effect" value), a short physical explanation, and a
mapping of a batch of parameter values (B, k) onto the batched point-mass kernel
(:meth:`PointMassModel.simulate_batch`): kernel override columns, per-trajectory atmospheres or
a radar clock offset. Effects compose: :func:`effect_fn` turns a list of effects into the
``effect_fn`` of :class:`bayesdrag.estimate.problem.OutputErrorProblem`, whose extra parameters are
the effects' parameters side by side.

=============  =====================  ========================================================
name           parameters             how it enters the simulation
=============  =====================  ========================================================
wind           wx, wy [m/s]           kernel columns ``P_WX, P_WY`` (air moves toward +x, +y)
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
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .atmosphere import Atmosphere
from .dynamics import kernel as K
from .dynamics.forces import LIFT_VERTICAL_FRACTION, coriolis_matrix, lift_parameter
from .estimate.problem import ExtraParam, SimInputs

#: induced-drag factor k in Cd (1 + k delta^2) [1/rad^2] (C_D_delta2 / C_D0 of a typical shell)
K_YAW = 10.0


@dataclass(frozen=True)
class EffectContext:
    """What an effect needs to know about the round besides its parameters.

    Attributes
    ----------
    atmosphere : Atmosphere
        The round's (nominal) atmosphere.
    latitude_deg, azimuth_deg : float or None
        Coriolis geometry (None: unknown latitude).
    v0 : float or None, m/s
        Launch velocity (spin-setting speed for ``lift``).
    """

    atmosphere: Atmosphere = field(default_factory=Atmosphere)
    latitude_deg: float | None = None
    azimuth_deg: float = 0.0
    v0: float | None = None


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
    """

    name: str
    params: tuple
    units: tuple
    explanation: str

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
        Atmosphere), ``time_shift`` ((B,) s).
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
        if n == "lift":
            v0 = ctx.v0 if ctx.v0 is not None else (
                np.linalg.norm(np.asarray(state0)[:, 3:], axis=1) if state0 is not None else 800.0)
            v0 = np.broadcast_to(np.asarray(v0, dtype=float), (B,))
            return {"overrides": {K.P_LIFT: lift_parameter(values[:, 0], v0),
                                  K.P_LIFT_VERT: LIFT_VERTICAL_FRACTION * v0}}
        if n == "coriolis":
            if ctx.latitude_deg is None:
                raise ValueError("the coriolis effect needs [launch] latitude")
            C = coriolis_matrix(ctx.latitude_deg, ctx.azimuth_deg).ravel()
            ov = {K.P_COR + i: np.full(B, C[i]) for i in range(9)}
            ov[K.P_HAS_COR] = np.ones(B)
            return {"overrides": ov}
        raise ValueError(f"unknown effect {n!r}; known: {', '.join(EFFECTS)}")

    def report_params(self, values):
        """Parameters as reported in diagnosis.json (DESIGN.md names and units)."""
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
               "shortens the range, a crosswind (wy) drifts the shell downwind."),
        Effect("temperature", (ExtraParam("dT", 0.0, -60.0, 60.0, 0.05),), ("K",),
               "A warmer day (dT > 0) at the same pressure at the gun thins the air (less drag, "
               "longer range) and raises the speed of sound, moving Cd(M) along the flight."),
        Effect("density", (ExtraParam("ratio", 1.0, 0.5, 1.6, 1e-4),), ("-",),
               "Air density differs from the model's by a constant factor (pressure or humidity "
               "error); drag scales with it, the speed of sound does not."),
        Effect("coriolis", (), (),
               "Earth rotation: a Coriolis acceleration -2 Omega x v deflects the shell to the right "
               "in the northern hemisphere and changes range with the firing azimuth."),
        Effect("yaw_drag", (ExtraParam("yaw_amp", 0.0, -0.5, 5.0, 1e-3),
                            ExtraParam("decay", 0.5, 0.02, 5.0, 1e-3)), ("rad", "1/s"),
               "A launch disturbance leaves the shell yawing; the yaw damps out but adds induced "
               "drag Cd k delta^2 early in the flight, a range loss concentrated after launch."),
        Effect("lift", (ExtraParam("factor", 0.0, -10.0, 10.0, 0.01),), ("-",),
               "Lift on the yaw of repose of a spinning shell (modified point mass): a drift to the "
               "right for a right-hand twist, growing with time of flight, and a small rise from the "
               "Magnus force on the same yaw; factor 1 is a typical shell."),
        Effect("radar_time", (ExtraParam("dt", 0.0, -0.2, 2.0, 1e-4),), ("s",),
               "The radar clock is late by dt: every sample shows the shell where it was dt later, "
               "so the track does not start at the muzzle at t = 0."),
        Effect("drag_scale", (ExtraParam("factor", 1.0, 0.5, 1.6, 1e-4),), ("-",),
               "This shell's drag is a constant factor times the firing table (lot, fuze, driving "
               "band or form differences); identical in its signature to a density ratio."),
    ]
    return {e.name: e for e in E}


#: the effect library by name (DESIGN.md order)
EFFECTS = _make_effects()


def get_effect(name):
    """The :class:`Effect` called ``name``; raises ValueError naming the allowed ones."""
    try:
        return EFFECTS[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


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
        ov, atm, shift = {}, None, None
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
        return SimInputs(ov, atm, shift)

    return fn


def static_model(model, effects, ctx):
    """Parameter-free effects (``coriolis``) folded into the model itself (no extra columns)."""
    for e in effects:
        if e.name == "coriolis" and e.k == 0:
            if ctx.latitude_deg is None:
                raise ValueError("the coriolis effect needs [launch] latitude")
            model = model.with_(coriolis=(ctx.latitude_deg, ctx.azimuth_deg))
    return model


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
    values : sequence of float, the effects' parameters side by side (DESIGN.md units, but
        ``yaw_drag`` takes its fitted amplitude ``k delta0^2``)
    ctx : EffectContext

    Returns
    -------
    (N, 6) states and (N,) Mach.
    """
    from .estimate.problem import OutputErrorProblem  # noqa: F401  (same machinery as the fit)

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

"""Effects on the flight besides the drag law and the air's state: the winds (constant and in
layers), Earth rotation, a decaying launch yaw's drag and the lift on the yaw of repose."""
from __future__ import annotations

import math

import numpy as np

from ..dynamics import kernel as K
from ..dynamics.forces import LIFT_VERTICAL_FRACTION, coriolis_matrix, lift_parameter
from .base import Effect
from .inputs import ExtraParam
from .wind_layers import WIND_LAYERS_MAX, WIND_PROFILE_KEY, WindProfileModel

__all__ = ["WIND", "CORIOLIS", "YAW_DRAG", "LIFT", "WIND_PROFILE", "K_YAW", "YAW_AMP_MAX", "YAW_DECAY_MIN"]

#: induced-drag factor k in Cd (1 + k delta^2) [1/rad^2] (C_D_delta2 / C_D0 of a typical shell)
K_YAW = 10.0

#: largest yaw amplitude k delta0^2 a yaw_drag fit may take: delta0 = 0.3 rad (17 deg). A stable
#: shell leaves the muzzle with a few degrees; beyond this it tumbles, and a fitted "yaw" that
#: large stands in for a wrong firing table
YAW_AMP_MAX = K_YAW * 0.3**2

#: slowest yaw decay [1/s] (amplitude e-folding in 10 s): a launch yaw of a stable shell damps in
#: 1-3 s; a "yaw" that does not damp over the flight is a constant drag factor (drag_scale)
YAW_DECAY_MIN = 0.1


# ----------------------------------------------------------------------------------------------
# how each effect's parameters enter the simulation (Effect.to_inputs), and the model changes
# (Effect.wrap_model)


def _wind_inputs(values, ctx, state0):
    return {"overrides": {K.P_WX: values[:, 0], K.P_WY: values[:, 1]}}


def _coriolis_inputs(values, ctx, state0):
    if ctx.latitude_deg is None:
        raise ValueError("the coriolis effect needs [launch] latitude")
    B = values.shape[0]
    C = coriolis_matrix(ctx.latitude_deg, ctx.azimuth_deg).ravel()
    ov = {K.P_COR + i: np.full(B, C[i]) for i in range(9)}
    ov[K.P_HAS_COR] = np.ones(B)
    return {"overrides": ov}


def _coriolis_model(model, ctx):
    if ctx.latitude_deg is None:
        raise ValueError("the coriolis effect needs [launch] latitude")
    return model.with_(coriolis=(ctx.latitude_deg, ctx.azimuth_deg))


def _yaw_drag_inputs(values, ctx, state0):
    return {"overrides": {K.P_YAW_AMP: values[:, 0], K.P_YAW_DECAY: values[:, 1]}}


def _yaw_report(values):
    a = float(values[0])
    return {"delta0": math.copysign(math.sqrt(abs(a) / K_YAW), a), "decay": float(values[1])}


def _yaw_report_sd(values, sd):
    a = abs(float(values[0]))
    d0 = math.sqrt(a / K_YAW)
    sd0 = sd[0] / (2 * K_YAW * d0) if d0 > 0 else math.sqrt(sd[0] / K_YAW)
    return {"delta0": float(sd0), "decay": float(sd[1])}


def _lift_inputs(values, ctx, state0):
    B = values.shape[0]
    v0 = ctx.v0 if ctx.v0 is not None else (
        np.linalg.norm(np.asarray(state0)[:, 3:], axis=1) if state0 is not None else 800.0)
    v0 = np.broadcast_to(np.asarray(v0, dtype=float), (B,))
    return {"overrides": {K.P_LIFT: lift_parameter(values[:, 0], v0), K.P_LIFT_VERT: LIFT_VERTICAL_FRACTION * v0}}

_NO_LAYERS = ("the wind_profile effect needs its layers (EffectContext.wind_layers: axis and edges, laid over "
              "the track by the fit or the diagnosis)")


def _wind_profile_inputs(values, ctx, state0):
    if ctx.wind_layers is None:
        raise ValueError(_NO_LAYERS)
    return {"overrides": {(WIND_PROFILE_KEY, i): values[:, i] for i in range(values.shape[1])}}


def _wind_profile_model(model, ctx):
    if ctx.wind_layers is None:
        raise ValueError(_NO_LAYERS)
    return WindProfileModel(model, ctx.wind_layers)


WIND = Effect("wind", (ExtraParam("wx", 0.0, -60.0, 60.0, 0.02), ExtraParam("wy", 0.0, -60.0, 60.0, 0.02)),
              ("m/s", "m/s"),
              "A constant horizontal wind changes the airspeed: a headwind (wx < 0) adds drag and "
              "shortens the range, a crosswind (wy) drifts the shell downwind.", acts_on="air", to_inputs=_wind_inputs,
              label="a constant horizontal wind")


CORIOLIS = Effect("coriolis", (), (),
                  "Earth rotation: a Coriolis acceleration -2 Omega x v deflects the shell to the right "
                  "in the northern hemisphere and changes range with the firing azimuth.", needs=("latitude",),
                  to_inputs=_coriolis_inputs, wrap_model=_coriolis_model,
                  label="Earth rotation (Coriolis)")


YAW_DRAG = Effect("yaw_drag", (ExtraParam("yaw_amp", 0.0, -0.5, YAW_AMP_MAX, 1e-3),
                               ExtraParam("decay", 0.5, YAW_DECAY_MIN, 5.0, 1e-3)), ("rad", "1/s"),
                  "A launch disturbance leaves the shell yawing; the yaw damps out but adds induced "
                  "drag Cd k delta^2 early in the flight, a range loss concentrated after launch.",
                  acts_on="drag", drag_change="partly", to_inputs=_yaw_drag_inputs,
                  to_report=_yaw_report, to_report_sd=_yaw_report_sd,
                  label="the drag of a launch yaw that damps out")


LIFT = Effect("lift", (ExtraParam("factor", 0.0, -10.0, 10.0, 0.01),), ("-",),
              "Lift on the yaw of repose of a spinning shell (modified point mass): a drift to the "
              "right for a right-hand twist, growing with time of flight, and a small rise from the "
              "Magnus force on the same yaw; factor 1 is a typical shell.", seen_by="cross_range",
              to_inputs=_lift_inputs,
              label="lift on the yaw of repose: the spin drift")


WIND_PROFILE = Effect("wind_profile", tuple(ExtraParam(f"{c}_{k + 1}", 0.0, -60.0, 60.0, 0.02)
                                            for k in range(WIND_LAYERS_MAX) for c in ("wx", "wy")),
                      ("m/s",) * (2 * WIND_LAYERS_MAX),
                      "A horizontal wind that changes along the flight, in layers of constant wind by height "
                      "or by downrange distance: a wind that turns from tail to head, or strengthens with "
                      "height, changes the airspeed differently in each part of the flight.",
                      acts_on="air", source="wind_profile", needs=("wind_layers",),
                      to_inputs=_wind_profile_inputs, wrap_model=_wind_profile_model,
                      label="a wind changing along the flight")

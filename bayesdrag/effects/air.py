"""Effects on the air the shell flies through: its temperature and its density (the winds are
:mod:`.flight`'s)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..dynamics import kernel as K
from ..dynamics.pointmass import atmosphere_table
from .base import Effect
from .inputs import ExtraParam

__all__ = ["TEMPERATURE", "DENSITY", "temperature_nodes"]


def _shifted_atmosphere(a, dT):
    """The round's atmosphere with its temperature offset moved by dT [K] (rounded to 1e-6 K so
    the memoised tables are re-used between finite-difference batches)."""
    return replace(a, temperature_offset=round(a.temperature_offset + dT, 6))


def _temperature_inputs(values, ctx, state0):
    if ctx.temperature_nodes is not None:
        h, (lo, mid, hi) = ctx.temperature_nodes
        x = (values[:, 0] / h)[:, None, None]
        # quadratic Lagrange interpolation through -h, 0, +h
        return {"atmosphere_tables": mid + 0.5 * x * (hi - lo) + 0.5 * x * x * (hi - 2.0 * mid + lo)}
    a = ctx.atmosphere
    return {"atmospheres": [_shifted_atmosphere(a, float(d)) for d in values[:, 0]]}


def temperature_nodes(atm, h):
    """``EffectContext.temperature_nodes`` of ``atm``: the kernel tables of the atmosphere
    shifted by -h, 0, +h K (3, n, 2), on one height grid, with ``h``."""
    tabs = []
    for dT in (-h, 0.0, h):
        a = replace(atm, temperature_offset=round(atm.temperature_offset + dT, 9))
        z0, dz, tab = atmosphere_table(a)
        tabs.append((z0, dz, tab))
    if len({(t[0], t[1], t[2].shape) for t in tabs}) != 1:
        raise ValueError("the shifted atmospheres' tables are on different height grids")
    return h, np.stack([t[2] for t in tabs])


def _density_inputs(values, ctx, state0):
    return {"overrides": {K.P_RHO_SCALE: values[:, 0]}}


TEMPERATURE = Effect("temperature", (ExtraParam("dT", 0.0, -60.0, 60.0, 0.05),), ("K",),
                     "A warmer day (dT > 0) at the same pressure at the gun thins the air (less drag, "
                     "longer range) and raises the speed of sound, moving Cd(M) along the flight.",
                     acts_on="air", drag_change="partly", source="temperature",
                     to_inputs=_temperature_inputs,
                     label="air warmer or colder than stated")


DENSITY = Effect("density", (ExtraParam("ratio", 1.0, 0.5, 1.6, 1e-4),), ("-",),
                 "Air density differs from the model's by a constant factor (pressure or humidity "
                 "error); drag scales with it, the speed of sound does not.",
                 acts_on="air", drag_change="level", source="density", to_inputs=_density_inputs,
                 label="air denser or thinner than stated")

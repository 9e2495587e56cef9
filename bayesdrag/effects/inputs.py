"""What an unmodelled effect hands the simulation: the extra parameters appended after the
initial state (:class:`ExtraParam`) and what a batch of their values does to the point-mass
kernel (:class:`SimInputs`). The effect library (:mod:`bayesdrag.effects`) builds them; the
output-error problem (:mod:`bayesdrag.estimate.model.problem`) fits them. Plain values, no physics.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ExtraParam", "SimInputs"]


@dataclass(frozen=True)
class ExtraParam:
    """An extra (effect) parameter appended after the initial state.

    Attributes
    ----------
    name : str
    start : float
        Starting value (usually the "no effect" value), in the parameter's unit.
    lower, upper : float
        Bounds the fit keeps the parameter inside, in the parameter's unit.
    step : float
        Central finite-difference step for the sensitivities (in the parameter's unit).
    """

    name: str
    start: float
    lower: float = -np.inf
    upper: float = np.inf
    step: float = 1e-3


@dataclass(frozen=True, eq=False)
class SimInputs:
    """What a batch of extra-parameter values does to the simulation.

    Attributes
    ----------
    overrides : dict kernel column -> (B,) array
        Per-trajectory kernel parameters (``dynamics.kernel.P_*``).
    atmospheres : list of Atmosphere (length B) or None
    time_shift : (B,) array or None, s
        Radar clock offset: the model is evaluated at ``track.t + time_shift``.
    output_scale : dict channel -> (B,) array, optional
        Multipliers of the model outputs (a radar's range or speed scale error: the radar
        reports ``(1 + s)`` times the true value).
    atmosphere_tables : (B, n, 2) array or None
        Per-trajectory tabulated density [kg/m^3] and 1 / speed of sound [s/m] on the nominal
        atmosphere's height grid (:meth:`PointMassModel.simulate_batch` ``atmospheres`` given
        as tables: a continuous temperature offset without building an atmosphere per walker).
    output_offset : dict channel -> (B,) array, optional
        Constants added to the model outputs (a radar's range bias [m], angle biases [rad]).
    site_shift : (B, 3) array or None, m
        Where the radar stands against its nominal site (x, y, z in the gun's frame): the
        radar-native channels are seen from the shifted site.
    """

    overrides: dict = field(default_factory=dict)
    atmospheres: list | None = None
    time_shift: np.ndarray | None = None
    output_scale: dict = field(default_factory=dict)
    atmosphere_tables: np.ndarray | None = None
    output_offset: dict = field(default_factory=dict)
    site_shift: np.ndarray | None = None

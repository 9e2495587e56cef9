"""The one trajectory type of the dynamics (:class:`Trajectory`), the state at launch and the
integrator's step and output schedules."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Trajectory", "initial_state", "output_schedule", "check_times",
           "DEFAULT_MAX_STEP", "STEP_DRAG_FRACTION"]

@dataclass(frozen=True)
class Trajectory:
    """States of one or many trajectories at common times.

    Attributes
    ----------
    t : ndarray, shape (N,), s
    state : ndarray, shape (N, 6) or (B, N, 6)
        ``[x, y, z, vx, vy, vz]`` in m and m/s.
    mach : ndarray, shape (N,) or (B, N)
        Mach number (airspeed over local speed of sound).
    success : bool
    message : str
    t_impact : float or None
        Time at which z returned to 0 on descent (scipy backend with ``stop_at_impact``).
    """

    t: np.ndarray
    state: np.ndarray
    mach: np.ndarray
    success: bool = True
    message: str = ""
    t_impact: float | None = None

    @property
    def position(self):
        return self.state[..., :3]

    @property
    def velocity(self):
        return self.state[..., 3:]

    @property
    def speed(self):
        """Ground speed |dr/dt| [m/s] (the radar's ``v`` channel)."""
        return np.linalg.norm(self.state[..., 3:], axis=-1)

    def channel(self, name):
        """One radar channel ``x``, ``y``, ``z`` or ``v`` as an array."""
        idx = {"x": 0, "y": 1, "z": 2}
        if name == "v":
            return self.speed
        return self.state[..., idx[name]]


def initial_state(velocity, elevation_deg, heading_deg=0.0, position=(0.0, 0.0, 0.0)):
    """State vector from muzzle velocity [m/s], elevation [deg] and heading relative to the
    firing azimuth [deg, positive to the right]."""
    el, hd = math.radians(elevation_deg), math.radians(heading_deg)
    v = velocity * np.array([math.cos(el) * math.cos(hd), math.cos(el) * math.sin(hd), math.sin(el)])
    return np.concatenate([np.asarray(position, dtype=float), v])


#: largest default kernel RK4 step [s]
DEFAULT_MAX_STEP = 0.1


#: default step as a fraction of the drag time scale (:meth:`PointMassModel.drag_time_scale`)
STEP_DRAG_FRACTION = 0.008


def output_schedule(t_out, t_start, max_step):
    """Uniform RK4 steps from ``t_start`` to the last output and where each output falls.

    The kernel steps with ``h = (t_out[-1] - t_start) / n_steps`` and interpolates each output
    inside its step with a cubic Hermite polynomial through the states and accelerations at
    both ends (error O(h^4), far below the RK4 error for smooth flight). Decoupling the steps
    from the outputs lets a 0.027 s radar track be integrated with ~0.1 s steps.

    Parameters
    ----------
    t_out : (N,) increasing times [s], all >= ``t_start``.
    t_start : float, s
    max_step : float, s

    Returns
    -------
    h : float, s
    n_steps : int
    out_step : (N,) int64, step holding each output
    out_theta : (N,) float64, position in [0, 1] of each output inside its step
    """
    t_out = check_times(t_out, t_start)
    if not max_step > 0:
        raise ValueError(f"max_step must be positive, got {max_step}")
    span = float(t_out[-1] - t_start)
    if span <= 0.0:
        return 0.0, 1, np.zeros(t_out.size, dtype=np.int64), np.zeros(t_out.size)
    n_steps = max(1, int(math.ceil(span / max_step - 1e-9)))
    h = span / n_steps
    r = (t_out - t_start) / h
    out_step = np.clip(np.floor(r), 0, n_steps - 1).astype(np.int64)
    out_theta = np.clip(r - out_step, 0.0, 1.0)
    return h, n_steps, out_step, out_theta


def check_times(t_out, t_start):
    t_out = np.asarray(t_out, dtype=float)
    if t_out.ndim != 1 or t_out.size == 0:
        raise ValueError("t_out must be a non-empty 1-D array of times")
    if (np.subtract(t_out[1:], t_out[:-1]) <= 0).any():     # np.diff without its wrapper
        raise ValueError("t_out must increase strictly")
    if t_out[0] < t_start - 1e-12:
        raise ValueError(f"output times start at {t_out[0]} s, before the initial state at {t_start} s")
    return t_out

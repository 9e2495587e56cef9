"""What a chronograph radar beside the muzzle reports: the range rate seen from its site,
after its own cosine correction for the offset typed into it (docs/radar.md).

The device sits at ``(x_d, y_d, z_d)`` in the gun frame (x along the line of fire, z up) and
multiplies the radial speed it measures by ``R / sqrt(R^2 - d^2)`` for the offset ``d`` typed into
it (:func:`bayesdrag.measure.geometry.chronograph_factor`). For a bullet in the vertical plane of
fire (``y = 0``) the product is exactly::

    v_reported = ((x - x_d) vx + (z - z_d) vz) / sqrt((x - x_d)^2 + (z - z_d)^2 + q),   q = y_d^2 - d^2

so the device's sideways distance and the typed offset enter the reported speed only through
``q`` (a device whose typed offset equals its true one reports the speed along its line of
sight with the sideways part removed). A session fit estimates ``q`` when the offset is not
known; ``x_d`` (the device ahead of or behind the muzzle) and ``z_d`` are held where the round
puts them.
"""
from __future__ import annotations

import numpy as np

__all__ = ["reported_speed", "offset_term"]


def offset_term(site_y, typed_offset):
    """``q = y_d^2 - d^2`` [m^2] of a device at sideways distance ``site_y`` [m] from the line
    of fire with ``typed_offset`` [m] typed into it (None: no correction, 0)."""
    d = 0.0 if typed_offset is None else float(typed_offset)
    return float(site_y) ** 2 - d * d


def reported_speed(x, z, vx, vz, q, site_x=0.0, site_z=0.0):
    """The speed a chronograph radar reports for a bullet in the vertical plane of fire.

    Parameters
    ----------
    x, z : ndarray, m
        The bullet's position along the line of fire and up, from the muzzle.
    vx, vz : ndarray, m/s
        Its velocity.
    q : float, m^2
        ``y_d^2 - d^2``: the device's squared sideways distance from the line of fire minus the
        squared offset typed into it (module docstring).
    site_x, site_z : float, m
        The device's position along the line of fire and up, from the muzzle.

    Returns
    -------
    ndarray, m/s
        Positive for a bullet flying away from the device.
    """
    dx, dz = np.asarray(x) - site_x, np.asarray(z) - site_z
    return (dx * vx + dz * vz) / np.sqrt(np.maximum(dx * dx + dz * dz + q, 1e-6))

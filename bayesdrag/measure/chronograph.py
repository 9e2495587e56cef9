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

__all__ = ["reported_speed", "offset_term", "chronograph_site", "CHRONOGRAPH_SITE_SD", "CHRONOGRAPH_SITE_Y",
           "NEAR_MUZZLE", "CHRONOGRAPH_REACH"]

#: a range-rate track whose first sample lies closer than this to the muzzle [m] and that ends
#: within CHRONOGRAPH_REACH [s] is a chronograph beside the gun (it sees the first 100 m or so):
#: its sideways distance moves the speed it reports by d^2 / (2 R^2) there. A Doppler radar
#: tracking a shell for seconds is not one: its missing site stays a stated condition
NEAR_MUZZLE, CHRONOGRAPH_REACH = 20.0, 1.0
#: the sd [m] of a chronograph's site per axis when the round does not give it, and the sideways
#: distance [m] the fit starts it at: a device stands 0.2-1 m beside the muzzle, and at 0 the
#: reported speed has no slope in the distance (it enters squared), so the fit could not move it
CHRONOGRAPH_SITE_SD, CHRONOGRAPH_SITE_Y = 1.0, 0.5


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


def chronograph_site(track, rnd, chans):
    """The round for one chronograph shot whose site the round does not give, and a note.

    A track of range rate alone starting within :data:`NEAR_MUZZLE` of the muzzle and ending
    within :data:`CHRONOGRAPH_REACH` comes from a device beside it; when the round gives neither
    ``[radar] position``, ``position_sd`` nor ``device_offset``, the site is fitted (its declared
    ``radar_position``, sd :data:`CHRONOGRAPH_SITE_SD` per axis) instead of being taken at the
    muzzle, which biased the Cd of a real-like shot by 4 of its sd. Without a typed offset the fit assumes the device
    corrected for none: a device that over-corrected (typed more than its true distance) leaves a
    misfit near the muzzle, which the fit's quality reports.

    Returns
    -------
    (Round, str or None)
        The round (unchanged when the rule does not apply) and the note saying what was assumed.
    """
    from dataclasses import replace

    ra = rnd.radar
    if tuple(chans) != ("range_rate",) or any(ra.position) or ra.position_sd is not None \
            or ra.device_offset is not None:
        return rnd, None
    t, v = np.asarray(track.t, float), np.abs(np.asarray(track.channels["range_rate"], float))
    if not t.size or float(t[0]) * float(v[0]) > NEAR_MUZZLE or float(t[-1]) > CHRONOGRAPH_REACH:
        return rnd, None
    note = (f"a chronograph track (range rate from {float(t[0]) * float(v[0]):.1f} m) whose round gives no [radar] "
            f"device_offset or position: the device's site beside the muzzle is fitted (started {CHRONOGRAPH_SITE_Y:g} m "
            f"to the side, sd {CHRONOGRAPH_SITE_SD:g} m per axis) and taken as uncorrected; give device_offset (and "
            f"device_offset_sd) as typed into the device")
    site = replace(ra, position=(0.0, CHRONOGRAPH_SITE_Y, 0.0), position_sd=CHRONOGRAPH_SITE_SD)
    return replace(rnd, radar=site), note

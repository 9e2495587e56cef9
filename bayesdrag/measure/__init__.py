"""Measurement equations: the channels of a track (``x, y, z, v`` in the gun's frame;
``range, azimuth, elevation, range_rate`` seen from the radar's site) computed from the simulated
state, the radar's site and its biases, with their Jacobians and the inverse
(:mod:`bayesdrag.measure.geometry`; docs/radar.md)."""
from .geometry import (EARTH_RADIUS, RadarSite, angle_blind_samples, channel_jacobian, channel_values, gun_equivalent,
                       gun_frame_track, native_only, near_branch, site_of, to_gun_frame, wrap_angle)
from .sample_noise import sample_noise

__all__ = ["RadarSite", "site_of", "wrap_angle", "channel_values", "channel_jacobian", "to_gun_frame",
           "gun_frame_track", "near_branch", "native_only", "gun_equivalent", "EARTH_RADIUS", "sample_noise",
           "angle_blind_samples"]

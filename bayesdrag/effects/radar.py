"""Effects on what the radar records, not on the flight: its clock, its range and angle biases
and where it stands. They act on the track's channels (``SimInputs.time_shift``,
``output_offset``, ``site_shift``: the fields the declared radar sources use, so an effect and a
source of one quantity are one model) and exist only where the track has a channel they act on."""
from __future__ import annotations

from ..errors import InputError
from ..track import NATIVE_CHANNELS
from .base import Effect
from .inputs import ExtraParam

__all__ = ["RADAR_TIME", "RANGE_BIAS", "AZIMUTH_BIAS", "ELEVATION_BIAS", "RADAR_POSITION", "RADAR_EFFECT_CHANNELS",
           "SITE_ERRORS", "RANGE_BIAS_MAX", "ANGLE_BIAS_MAX", "SITE_OFFSET_MAX", "SITE_SEEN_FRACTION",
           "check_radar_effects", "radar_effect_missing"]

#: the radar's effects (the site's biases and its place) and the channels each acts on (it exists
#: only where the track has one): a range bias its range, an angle bias its angle, the place every
#: native channel
RADAR_EFFECT_CHANNELS = {"range_bias": ("range",), "azimuth_bias": ("azimuth",), "elevation_bias": ("elevation",),
                         "radar_position": NATIVE_CHANNELS}


def radar_effect_missing(name, channels):
    """Why the radar's effect ``name`` (:data:`RADAR_EFFECT_CHANNELS`) moves none of ``channels``
    (str), or None when it moves one (or ``name`` is not one of the radar's errors)."""
    need = RADAR_EFFECT_CHANNELS.get(name)
    if need is None or any(c in channels for c in need):
        return None
    what = need[0] if len(need) == 1 else "radar-native (" + ", ".join(need) + ")"
    return f"the track has no {what} channel (its channels: {', '.join(channels)})"


def check_radar_effects(names, channels, where="track"):
    """Raise :class:`InputError` when one of the radar's errors among ``names`` (effects asked
    for) moves none of ``channels``; ``where`` names the track."""
    for n in names:
        why = radar_effect_missing(n, tuple(channels))
        if why is not None:
            raise InputError(f"{where}: effect {n!r} acts on the radar's {' or '.join(RADAR_EFFECT_CHANNELS[n])}, "
                             f"but {why}; drop it or fit a track that has the channel")


#: (the name the measurement layer gave it before the radar's effects moved here)
SITE_ERRORS = RADAR_EFFECT_CHANNELS

#: bounds of a fitted range bias [m] and angle bias [rad] (0.05 rad = 2.9 deg: a radar that far
#: off its boresight is not tracking this shell) and site offset [m]
RANGE_BIAS_MAX = 200.0
ANGLE_BIAS_MAX = 0.05
SITE_OFFSET_MAX = 500.0

#: a coordinate of ``radar_position`` whose signature the nuisance parameters leave less of than
#: this share is held at 0 (:func:`unabsorbed_fraction`; the diagnosis' identifiability share)
SITE_SEEN_FRACTION = 0.02


def _radar_time_inputs(values, ctx, state0):
    return {"time_shift": values[:, 0].copy()}


def _bias_inputs(channel):
    def to_inputs(values, ctx, state0):
        return {"output_offset": {channel: values[:, 0].copy()}}
    return to_inputs


def _site_inputs(values, ctx, state0):
    return {"site_shift": values[:, :3].copy()}


RADAR_TIME = Effect("radar_time", (ExtraParam("dt", 0.0, -0.2, 2.0, 1e-4),), ("s",),
                    "The radar clock is late by dt: every sample shows the shell where it was dt later, "
                    "so the track does not start at the muzzle at t = 0.", acts_on="measurement", source="time_offset",
                    to_inputs=_radar_time_inputs,
                    label="a radar clock offset")


RANGE_BIAS = Effect("range_bias", (ExtraParam("bias", 0.0, -RANGE_BIAS_MAX, RANGE_BIAS_MAX, 0.01),), ("m",),
                    "The radar's range is off by a constant (a calibration or cable delay): every range it "
                    "records is the true one plus the bias.", acts_on="measurement", source="range_bias",
                    needs=("radar_channels",), to_inputs=_bias_inputs(RADAR_EFFECT_CHANNELS["range_bias"][0]),
                    label="a radar range bias")


AZIMUTH_BIAS = Effect("azimuth_bias", (ExtraParam("bias", 0.0, -ANGLE_BIAS_MAX, ANGLE_BIAS_MAX, 1e-6),), ("rad",),
                      "The radar's azimuth is off by a constant (its north alignment or encoder): the shell "
                      "appears turned sideways by the bias, more metres the further it flies.", acts_on="measurement",
                      source="azimuth_bias", needs=("radar_channels",),
                      to_inputs=_bias_inputs(RADAR_EFFECT_CHANNELS["azimuth_bias"][0]),
                      label="a radar azimuth bias")


ELEVATION_BIAS = Effect("elevation_bias", (ExtraParam("bias", 0.0, -ANGLE_BIAS_MAX, ANGLE_BIAS_MAX, 1e-6),), ("rad",),
                        "The radar's elevation is off by a constant (levelling or boresight): the shell appears "
                        "higher or lower by the bias, more metres the further it flies.", acts_on="measurement",
                        source="elevation_bias", needs=("radar_channels",),
                        to_inputs=_bias_inputs(RADAR_EFFECT_CHANNELS["elevation_bias"][0]),
                        label="a radar elevation bias")


RADAR_POSITION = Effect("radar_position", tuple(ExtraParam(c, 0.0, -SITE_OFFSET_MAX, SITE_OFFSET_MAX, 0.01) for c in "xyz"),
                        ("m", "m", "m"),
                        "The radar stands elsewhere than the round says (x downrange, y right, z up of its "
                        "stated site): its range, angles and range rate are seen from another place, which "
                        "the track shows as a start away from the muzzle and lines of sight that turn wrongly.",
                        acts_on="measurement", source="radar_position", needs=("radar_channels",),
                        to_inputs=_site_inputs,
                        label="a radar site off the stated one")

"""The ``simulate`` verb: a synthetic radar track of a round from launch to impact
(:func:`simulate`, ``bayesdrag.simulate``). The physics is in :mod:`bayesdrag.synthetic`; the
command that reads a round file and writes the track is :mod:`bayesdrag.commands.simulate`."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from ..options import SimulateOptions
from ..round import Round
from ..synthetic import add_noise, recordable, simulate_round
from ..track import GUN_CHANNELS, NATIVE_CHANNELS, RadarTrack

__all__ = ["simulate"]


def simulate(rnd: Round, options: SimulateOptions | None = None, **kwargs: Any) -> RadarTrack:
    """A synthetic radar track of a round from launch to impact.

    Parameters
    ----------
    rnd : Round
        Needs ``reference_drag`` and the launch velocity and elevation.
    options : SimulateOptions, optional
        Keyword arguments (``model="6dof"``, ``dt=0.05``, ``noise=True``, ``seed=1``) override
        single fields.

    Returns
    -------
    RadarTrack
        With noise, only the samples a radar records (:func:`bayesdrag.synthetic.recordable`):
        a noisy slant range below 0 m or an elevation past +-90 deg (a radar at the muzzle at
        launch, a site straight above or below the flight) is left out, and ``notes`` says how
        many; the file it is written to is one :func:`bayesdrag.io.tracks.read_track` reads.
    """
    opts = options if options is not None else SimulateOptions()
    if kwargs:
        opts = SimulateOptions(**{**opts.__dict__, **kwargs})
    chans = NATIVE_CHANNELS if opts.radar == "native" else GUN_CHANNELS
    track = simulate_round(rnd, model=opts.model, dt=opts.dt, clock_offset=opts.clock_offset, channels=chans)
    if opts.noise:
        if not rnd.radar.sigma:
            raise InputError(f"{rnd.path or 'round'}: noise needs [radar] sigma = {{x = ..., z = ..., v = ...}}"
                             if opts.radar == "gun" else f"{rnd.path or 'round'}: noise needs [radar] sigma = "
                             f"{{range = ..., azimuth = ..., elevation = ..., range_rate = ...}} (m, deg, deg, m/s)")
        missing = [c for c in chans if c not in rnd.radar.sigma]
        if opts.radar == "native" and missing:
            raise InputError(f"{rnd.path or 'round'}: --radar native --noise needs [radar] sigma of every native "
                             f"channel; missing: {', '.join(missing)} (range [m], azimuth, elevation [deg], "
                             f"range_rate [m/s])")
        track = add_noise(track, rnd.radar.sigma, np.random.default_rng(opts.seed))
        # a noisy range below 0 or elevation past +-90 deg is no radar's record: left out, noted
        track, _ = recordable(track)
    return track

"""Synthetic radar tracks as a command: :func:`simulate` (Python API) and ``bayesdrag simulate``
(:func:`run_simulate`)."""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.outputs import atomic_write
from ..round import Round
from ..synthetic import add_noise, recordable, simulate_round
from ..track import ANGLE_CHANNELS, GUN_CHANNELS, NATIVE_CHANNELS, RadarTrack
from ..options import SimulateOptions

__all__ = ["simulate", "run_simulate"]


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


def run_simulate(round_path, output, options=None, *, echo=print):
    """``bayesdrag simulate ROUND -o TRACK``: write the synthetic track as CSV. Returns it.

    ``TRACK`` must not be one of the run's inputs (the round file, its reference table or met
    profile): that is refused before any work, never overwritten. The file is written under a
    temporary name and renamed into place (mode ``0666 & ~umask``)."""
    from ..io.rounds import read_round, round_files
    from ..io.tracks import write_track

    opts = options if options is not None else SimulateOptions()
    rnd = read_round(round_path)
    out = Path(output)
    for role, p in round_files(round_path, rnd).items():
        if os.path.lexists(out) and out.exists() and os.path.samefile(out, p):
            what = {"round": "the round file", "reference_drag": "the round's reference_drag table",
                    "met_profile": "the round's met profile"}.get(role, role)
            raise InputError(f"-o {output}: that is {what}, an input of this run; write the track to another file")
    track = simulate(rnd, opts)
    comment = f"synthetic track: {opts.model}, dt = {opts.dt} s, from {round_path}"
    if opts.radar == "native":
        comment += (f"; seen by a radar at {rnd.radar.position} m in the gun's frame, azimuth and elevation "
                    f"in deg")
    if opts.noise:
        sig = {c: (f"{math.degrees(v):g} deg" if c in ANGLE_CHANNELS else f"{v:g}")
               for c, v in rnd.radar.sigma.items() if c in track.channels}
        comment += f"; Gaussian noise {sig}, seed {opts.seed}"
    if track.notes:
        comment += "; " + "; ".join(track.notes)
    atomic_write(output, lambda tmp: write_track(tmp, track, comment=comment))
    echo(f"wrote {output}: {track.n} samples, t = {track.t[0]:g} .. {track.t[-1]:.2f} s, range {track.x[-1]:.0f} m"
         if track.x is not None else
         f"wrote {output}: {track.n} samples, t = {track.t[0]:g} .. {track.t[-1]:.2f} s, last slant range "
         f"{track.channels['range'][-1]:.0f} m" if "range" in track.channels else f"wrote {output}")
    for note in track.notes:
        echo(f"note: {note}")
    return track

"""Synthetic radar tracks as a command, ``bayesdrag simulate`` (:func:`run_simulate`); the Python
API ``bayesdrag.simulate`` is :func:`bayesdrag.pipeline.simulation.simulate`."""
from __future__ import annotations

import math
import os
from pathlib import Path

from ..errors import InputError
from ..io.outputs import atomic_write
from ..track import ANGLE_CHANNELS
from ..options import SimulateOptions
from ..pipeline.simulation import simulate

__all__ = ["simulate", "run_simulate"]




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

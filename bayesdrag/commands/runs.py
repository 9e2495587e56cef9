"""The output run of a command: :func:`output_run` opens the
:class:`~bayesdrag.io.outputs.OutputRun` of a command on one track and round (inputs: the track,
the round file and the files it references, by their bytes), or joins the run a calling command
already holds (the demo writes the fit's outputs into its own run)."""
from __future__ import annotations

import contextlib
import sys
import time

from ..io.outputs import OutputRun
from ..io.rounds import round_files

__all__ = ["output_run", "track_round_inputs", "throttled"]

#: seconds between two progress lines on a stderr that is not a terminal
PROGRESS_EVERY = 10.0


def track_round_inputs(track_path, round_path, rnd):
    """``{"track": ..., "round": ..., "reference_drag": ..., "met_profile": ...}``: the files a
    command on one track and round reads."""
    return {"track": track_path, **round_files(round_path, rnd)}


def _note(msg):
    print(msg, file=sys.stderr, flush=True)


def output_run(out, command, track_path, round_path, rnd, options=None, *, run=None):
    """A context manager giving the :class:`~bayesdrag.io.outputs.OutputRun` to write ``out``:
    ``run`` itself when given (entering and leaving it is then the caller's), else a new one."""
    if run is not None:
        return contextlib.nullcontext(run)
    opts = options.to_dict() if hasattr(options, "to_dict") else options
    return OutputRun(out, command, inputs=track_round_inputs(track_path, round_path, rnd), options=opts,
                     echo=_note)


def throttled(fn, every=PROGRESS_EVERY):
    """``fn`` called at most once per ``every`` seconds (the first call always): progress lines
    of long work on a stderr that is not a terminal (a log file, a CI job) without one line per
    sampler check."""
    last = [-float("inf")]

    def call(msg):
        now = time.monotonic()
        if now - last[0] >= every:
            last[0] = now
            fn(msg)

    return call

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

__all__ = ["output_run", "track_round_inputs", "throttled", "StageProgress"]

#: seconds between two progress lines on a stderr that is not a terminal
PROGRESS_EVERY = 10.0
#: a stage of work (the maximum-likelihood fit) reports its progress once it has run this long
#: [s]: a quick fit stays silent, a slow one (minutes on a dense track) is not
PROGRESS_AFTER = 3.0


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


class StageProgress:
    """Status lines of a long stage of work (the maximum-likelihood fit): ``progress(step)`` with
    a short description of the step it is at prints ``"<what> (<elapsed> s): <step>"`` once the
    stage has run :data:`PROGRESS_AFTER` seconds, then at most every ``every`` seconds, and the
    last step again when it ends after having spoken (:meth:`done`).

    Parameters
    ----------
    echo : callable
        Receives the lines.
    what : str
        The stage's name.
    clock : callable
        Seconds (``time.monotonic``; a test passes its own).
    """

    def __init__(self, echo, what="bayesdrag: maximum likelihood", after=PROGRESS_AFTER, every=PROGRESS_EVERY,
                 clock=time.monotonic):
        self.echo, self.what, self.after, self.every, self.clock = echo, what, after, every, clock
        self.t0 = clock()
        self.last = None
        self.step = None

    def __call__(self, step):
        self.step = step
        now = self.clock()
        if now - self.t0 < self.after or (self.last is not None and now - self.last < self.every):
            return
        self.last = now
        self.echo(f"{self.what} ({now - self.t0:.0f} s): {step}")

    def done(self):
        """Say the stage ended (only when it said anything before)."""
        if self.last is not None:
            self.echo(f"{self.what} done in {self.clock() - self.t0:.0f} s")

"""Stage 1 of a fit, *prepare*: the values a fit starts from, checked once. The track thinned
when it is very dense, the options merged, the channels asked for checked against the track, a
chronograph's site laid out, Scheme 2's windows bounded before any is fitted. Nothing is read
from disk here: the track and the round arrive as values (the commands read the files)."""
from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from ..errors import InputError
from ..measure.chronograph import chronograph_site
from ..options import FitOptions
from ..round import Round
from ..track import RadarTrack, thin_for_fit

__all__ = ["Prepared", "prepare", "watched"]


@dataclass(frozen=True)
class Prepared:
    """What every later stage of a fit reads.

    Attributes
    ----------
    track : RadarTrack
        Thinned when very dense (every k-th sample, with a note).
    rnd : Round
        With a chronograph's site laid out when the track is a chronograph's.
    opts : FitOptions
    chans : tuple of str or None
        The channels asked for (None: all of the track's), each present in the track.
    notes : tuple of str
        Notes the quality record starts with (the chronograph's site).
    """

    track: RadarTrack
    rnd: Round
    opts: FitOptions
    chans: tuple | None
    notes: tuple = ()


def prepare(track: RadarTrack, rnd: Round, options: FitOptions | None = None, **kwargs: Any) -> Prepared:
    """The :class:`Prepared` values of a fit; ``kwargs`` override single fields of ``options``.

    Raises
    ------
    InputError
        A channel asked for that the track lacks; Scheme 2 windows beyond the cap.
    """
    track = thin_for_fit(track)           # a very dense track: every k-th sample, with a note
    opts = options if options is not None else FitOptions()
    if kwargs:
        opts = FitOptions(**{**opts.to_dict(), **kwargs})
    chans = opts.channels
    if chans is not None:
        missing = [c for c in chans if c not in track.names]
        if missing:
            raise InputError(f"{track.source or 'track'}: channel(s) {', '.join(missing)} asked for but not in the "
                             f"track (it has {', '.join(track.names)})")
    rnd, site_note = chronograph_site(track, rnd, chans or track.names)
    if opts.scheme == 2:
        opts.check_windows(track.n)       # a bound on the windows, before any is fitted
    return Prepared(track, rnd, opts, chans, (site_note,) if site_note else ())


def watched():
    """Whether someone watches this process: its stderr is a terminal, or it runs in a Jupyter
    kernel (where tqdm draws a widget)."""
    try:
        if sys.stderr is not None and sys.stderr.isatty():
            return True
    except (AttributeError, ValueError):      # a closed or replaced stderr
        pass
    return "ipykernel" in sys.modules


"""What goes wrong, as types: the exceptions and the warnings.

The CLI turns :class:`InputError` into exit status 2 with its one-line message,
:class:`OutputError` and :class:`FitError` into exit status 1 with theirs, and any other exception
into exit status 1.

A fit's warnings are :class:`FitWarning` records: code tests their ``kind`` (one of
:data:`WARNING_KINDS`), never their words; ``str()`` is the sentence ``result.json`` holds. The
Python API emits them through :mod:`warnings` in the category :class:`BayesdragWarning`, which a
user filters like any other (they stay in ``FitResult.warnings`` either way).
"""
from __future__ import annotations

from dataclasses import dataclass


class InputError(ValueError):
    """Bad user input: a file, a row, a key or an option. The message is one line that names
    the file (and row or key), what was found and what is allowed."""


class FitError(RuntimeError):
    """An estimation that could not produce a trustworthy answer (divergence, singular
    information matrix, an ODE that cannot be integrated)."""


class OutputError(RuntimeError):
    """The output folder could not be written to the end (a full disk, a quota): nothing of
    the run was kept and the earlier outputs are untouched. One line, exit status 1."""


class MissingDataError(LookupError):
    """A result asked for something it does not hold: the posterior of a fit that did not
    sample, or a figure that needs the fit's objects from a result read back from its folder.
    The message says what is missing and how to get it."""


class BayesdragWarning(UserWarning):
    """The category of every warning the Python API emits (``warnings.filterwarnings("ignore",
    category=BayesdragWarning)`` silences them; ``"error"`` makes them raise)."""


#: what a warning can say, kind -> meaning (the kinds code may test; the words may change)
WARNING_KINDS = {
    "no_information": "the track carries no information on a parameter (zero sensitivity)",
    "ill_conditioned": "the information matrix is ill-conditioned: some parameters are not identifiable",
    "singular_information": "the information matrix is singular: no Cramér-Rao bounds",
    "at_bound": "a parameter sits at a bound of its range",
    "sd_exceeds_value": "a parameter's Cramér-Rao sd exceeds its value",
    "correlated": "two parameters are strongly correlated",
    "misfit": "a channel's residuals are larger than its noise: the model misses the track",
    "autocorrelated": "a channel's residuals are autocorrelated: model error, not noise",
    "cd_held_flat": "Cd is held flat beyond the drag model's span",
    "cd_at_bound": "Cd sits at a bound of its model",
    "smoothing_edge": "the smoothing weight is at the flexible end of its grid",
    "rigid_model": "a rigid drag model misses the flexible fit of the same track",
    "launch_conflict": "the track conflicts with a launch value of the round",
    "not_converged": "a fit did not converge",
    "sampler": "the sampler's chain is not trustworthy (r-hat, acceptance)",
    "radar_unused": "a declared radar source nothing in the fit depends on",
    "model_error": "the model check finds an error the model leaves in Cd",
    "air": "the stated air is doubted by the track",
    "clock": "the fit carries a radar clock offset the data determine",
    "recorded": "read back from result.json (its kind is not recorded)",
}


#: kinds that are not raised by default (the console, the report's warning list, the Python API's
#: ``warnings``): they change nothing a user should do or believe. A penalised spline's
#: neighbouring coefficients, and a tracking radar's launch-velocity components, correlate by
#: design; one coefficient's sd beside its value says nothing of Cd's band, which the rows give.
#: ``result.json`` and ``FitResult.warnings`` keep them; ``bayesdrag fit --verbose`` prints them.
QUIET_KINDS = frozenset({"correlated", "sd_exceeds_value"})


@dataclass(frozen=True)
class FitWarning:
    """One warning of a fit.

    Attributes
    ----------
    kind : str
        What it says (a key of :data:`WARNING_KINDS`): what code tests.
    message : str
        The sentence shown to the user and written to ``result.json`` (``str()`` of the record).
    params : tuple of str
        The parameters it names (``("c3",)``, ``("Ux0", "Uz0")``), empty when none.
    """

    kind: str
    message: str
    params: tuple = ()

    def __post_init__(self):
        if self.kind not in WARNING_KINDS:
            raise ValueError(f"warning kind {self.kind!r} is not one of {', '.join(WARNING_KINDS)}")
        object.__setattr__(self, "params", tuple(str(p) for p in self.params))

    def __str__(self):
        return self.message

    @property
    def shown(self):
        """Whether it is raised by default (its kind is not one of :data:`QUIET_KINDS`)."""
        return self.kind not in QUIET_KINDS

    def within(self, prefix):
        """The same warning with ``prefix`` before its sentence (a Scheme 2 window's)."""
        return FitWarning(self.kind, f"{prefix}{self.message}", self.params)


def as_warning(w, kind="recorded"):
    """``w`` as a :class:`FitWarning` (a sentence read back from a file gets ``kind``)."""
    return w if isinstance(w, FitWarning) else FitWarning(kind, str(w))

"""Exception types. The CLI turns :class:`InputError` into exit status 2 with its one-line
message, :class:`OutputError` and :class:`FitError` into exit status 1 with theirs, and any
other exception into exit status 1."""


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

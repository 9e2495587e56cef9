"""Exception types. The CLI turns :class:`InputError` into exit status 2 with its one-line
message, and any other exception into exit status 1."""


class InputError(ValueError):
    """Bad user input: a file, a row, a key or an option. The message is one line that names
    the file (and row or key), what was found and what is allowed."""


class FitError(RuntimeError):
    """An estimation that could not produce a trustworthy answer (divergence, singular
    information matrix, an ODE that cannot be integrated)."""

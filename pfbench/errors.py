"""Error types that the CLI turns into one-line messages (exit code 2)."""


class PfbenchError(Exception):
    """A user-facing error: bad input, bad configuration, unusable data.

    The CLI prints ``error: <message>`` on one line and exits with code 2.
    """


class NumericalError(PfbenchError):
    """Numerical trouble that cannot be recovered from (e.g. a diverging model)."""

"""The error hierarchy. Every failure that the *user* caused (a bad value, name, shape, option or
file) or that the *model or data* caused (a method the model does not support, numerical trouble)
is a :class:`PfbenchError`; the CLI prints such an error as one line ``error: ...`` and exits
with code 2. Any other exception is a bug in pfbench: the CLI shows its traceback and exits 1.

::

    PfbenchError
    ├── InputError (also a ValueError)   a bad argument, option, name or shape
    │   ├── DataError                    an unusable data file, log or store
    │   ├── ModelError                   a mistake in a model's code (its contract)
    │   └── UnknownNameError             a model or task name that is not registered
    ├── UnsupportedError                 the model lacks what the method needs
    └── NumericalError                   numerical trouble that cannot be recovered from
"""


class PfbenchError(Exception):
    """A user-facing error: the CLI prints ``error: <message>`` on one line and exits with code 2."""


class InputError(PfbenchError, ValueError):
    """A bad argument, option value, name or array shape given by the user."""


class DataError(InputError):
    """A data file, log, journal or cache entry that cannot be used as it is."""


class ModelError(InputError):
    """A mistake in a model's code, found by its contract (:mod:`pfbench.models.contract`): a
    function that raises, returns the wrong shape or type, or that numba cannot compile."""


class UnknownNameError(InputError):
    """A model or task name that is not registered (in this process: a worker started afresh lacks
    what its parent registered at run time)."""


class UnsupportedError(PfbenchError):
    """The model does not declare what the method needs (e.g. no linear-Gaussian substructure)."""


class NumericalError(PfbenchError):
    """Numerical trouble that cannot be recovered from (e.g. a diverging model, a DARE without a
    stabilising solution)."""


__all__ = ["PfbenchError", "InputError", "DataError", "ModelError", "UnknownNameError", "UnsupportedError",
           "NumericalError"]

"""pfbench: benchmarking and reproducibility suite for particle filters and Kalman filters.

Stable API::

    import pfbench
    model = pfbench.models.get("ob1")
    traj = model.simulate(1000, seed=1)
    res = pfbench.run_filter(model, traj.y, traj.u, method="bootstrap", n_particles=1000,
                             backend="numba", seed=1)
    pfbench.metrics.armse(res.estimates, traj.x)

Also at the top level: ``Method`` (the method table), ``FilterResult`` (what every filter returns),
``run_mpf`` / ``run_kalman`` / ``run_guided`` (the structured filters, also reachable through
``run_filter(method=...)``), ``kalman`` (KF / EKF / DARE / steady-state KF), ``sweep``
(Monte Carlo sweeps), ``resampling``, ``metrics`` and the error types.
"""
from .errors import DataError, InputError, ModelError, NumericalError, PfbenchError, UnsupportedError

#: what ``__getattr__`` imports on first use, by module
_LAZY_MODULES = ("models", "resampling", "kalman", "metrics", "recipes", "mcu", "filters", "backends", "sweep",
                 "plants", "compare", "tasks")


def __getattr__(name):
    # Lazy imports keep `import pfbench` fast and free of numpy/numba, so the `pfbench` command's
    # entry point (pfbench.__main__) can catch a Ctrl-C while they load.
    if name == "__version__":
        from importlib import metadata

        try:
            return metadata.version("pfbench")
        except metadata.PackageNotFoundError:  # running from a source tree without install
            return "0.0.0+src"
    if name in ("run_filter", "FilterResult", "Method"):
        from . import filters

        return getattr(filters, name)
    if name in ("run_mpf", "run_kalman"):
        from .filters import marginalized

        return getattr(marginalized, name)
    if name == "run_guided":
        from .filters import guided

        return guided.run_guided
    if name in _LAZY_MODULES:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'pfbench' has no attribute {name!r}")


def __dir__():
    """The lazy names too, so a notebook's completion offers ``run_filter``."""
    return sorted(set(globals()) | set(__all__) | set(_LAZY_MODULES))


__all__ = ["models", "run_filter", "FilterResult", "Method", "run_mpf", "run_kalman", "run_guided",
           "kalman", "sweep", "compare", "tasks", "PfbenchError",
           "InputError", "DataError", "ModelError", "UnsupportedError", "NumericalError", "__version__"]

"""Model registry: ``pfbench.models.get(name, **params)`` and ``pfbench.models.names()``.

Every module in this package is imported on first use, so a new model only needs a file
here with a class decorated by :func:`register`.
"""
from __future__ import annotations

import importlib
import pkgutil

from ..errors import PfbenchError
from .base import StateSpaceModel, Trajectory, gaussian_loglik_diag

_REGISTRY: dict[str, type[StateSpaceModel]] = {}
_LOADED = False


def register(name: str):
    """Class decorator: register a :class:`StateSpaceModel` subclass under ``name``."""

    def deco(cls):
        if not (isinstance(cls, type) and issubclass(cls, StateSpaceModel)):
            raise TypeError("register() expects a StateSpaceModel subclass")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def _load_all() -> None:
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    for mod in pkgutil.iter_modules(__path__):
        if mod.name != "base":
            importlib.import_module(f"{__name__}.{mod.name}")


def names() -> list[str]:
    """Names of all registered models."""
    _load_all()
    return sorted(_REGISTRY)


def model_class(name: str) -> type[StateSpaceModel]:
    _load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise PfbenchError(f"unknown model {name!r}; known models: {', '.join(names())}") from None


def get(name: str, **params) -> StateSpaceModel:
    """Instantiate the registered model ``name`` with keyword parameters."""
    cls = model_class(name)
    try:
        return cls(**params)
    except TypeError as exc:
        raise PfbenchError(f"bad parameters for model {name!r}: {exc}") from None


__all__ = ["StateSpaceModel", "Trajectory", "gaussian_loglik_diag", "register", "names", "get",
           "model_class"]

"""Model registry: ``pfbench.models.get(name, **params)``, ``pfbench.models.get_spec("ob3:v4")``
and ``pfbench.models.names()``.

Every module in this package is imported on first use, so a new model only needs a file
here with a class decorated by :func:`register`.

A *model spec* is the text a user types to pick a model: its registry name, optionally followed
by a variant, ``name:vN`` (or ``name:N``), which is the model parameter ``version=N`` (Ob3's
versions 1-5 of [MultiPDF] §4: ``ob3:v4``). :func:`parse_spec` reads it, :func:`get_spec`
instantiates it; every command that takes ``--model`` goes through them.

Models of the user live in their own ``.py`` files (a class decorated by :func:`register`, as in
the README): :func:`load_files` imports them (``pfbench --models my_model.py ...`` on the command
line, or the environment variable ``PFBENCH_MODELS``: paths separated by ``os.pathsep``), after
which their names work everywhere a registered name does.

Registry rules, the same in every process, so that a name means one class everywhere: the
built-in models always load first; a user file that registers a name already taken (by a
built-in or by another file) is an :class:`~pfbench.errors.InputError` naming both files, and
registers nothing; and the workers of :func:`pfbench.procs.process_pool` (sweeps) load exactly
the files their parent loaded (:func:`loaded_files`), whether named by ``--models``,
``PFBENCH_MODELS`` or :func:`load_files`.
"""
from __future__ import annotations

import hashlib

import importlib
import importlib.util
import inspect
import os
import pkgutil
import sys
from pathlib import Path

from ..errors import InputError, ModelError, PfbenchError, UnknownNameError
from ..options import check_known, typed
from .base import StateSpaceModel, Trajectory, gaussian_loglik_diag

_REGISTRY: dict[str, type[StateSpaceModel]] = {}
_LOADED = False
_FILES: dict[str, str] = {}  # resolved path of a loaded user model file -> its module name
_IMPORTING: list[str] = []   # the user model file being imported now (see register)
MODELS_ENV = "PFBENCH_MODELS"


def source_file(cls) -> str:
    """The file that defines model class ``cls`` (for messages)."""
    try:
        return inspect.getfile(cls)
    except (TypeError, OSError):
        return cls.__module__


def register(name: str):
    """Class decorator: register a :class:`StateSpaceModel` subclass under ``name``.

    While a user model file is imported (:func:`load_files`), a name already registered by a
    built-in or another file is an InputError naming both files, as is ``@register`` without a name
    (which would otherwise register nothing and replace the class by the decorator) and a name no
    model spec could name."""
    if not isinstance(name, str) or not name.strip():
        what = f"class {name.__name__}" if isinstance(name, type) else repr(name)
        raise InputError(f"@register needs the model's name as text: write @register(\"my_model\") above "
                         f"the class, got {what}")
    if any(c in name for c in ":,= \t"):  # they separate a model spec's parts (NAME:key=value,...)
        raise InputError(f"@register({name!r}): a model's name cannot hold ':', ',', '=' or spaces, which "
                         "separate the parts of a model spec (NAME:key=value,...)")

    def deco(cls):
        if not (isinstance(cls, type) and issubclass(cls, StateSpaceModel)):
            raise TypeError("register() expects a StateSpaceModel subclass")  # a bug in the model file
        taken = _REGISTRY.get(name)
        if _IMPORTING and taken is not None and taken is not cls:
            raise InputError(f"model file {_IMPORTING[-1]!r} registers the name {name!r}, which "
                             f"{source_file(taken)} already registers: give the model another name")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return deco


def _load_all() -> None:
    """The built-in models, then the files of ``PFBENCH_MODELS`` (once per process)."""
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    for mod in pkgutil.iter_modules(__path__):
        if mod.name != "base":
            importlib.import_module(f"{__name__}.{mod.name}")
    env = os.environ.get(MODELS_ENV, "")
    load_files([p for p in env.split(os.pathsep) if p.strip()])


def load_files(paths) -> list[str]:
    """Import user model files (``.py``) so the models they :func:`register` can be named.

    Each file becomes a module of its own (imported once per process, under a name derived from
    its path, so its classes can be found again by the MCU compiler's worker process), after the
    built-in models. Returns the names registered by the files. A missing file, one that fails
    to import, or one that registers a name already taken is an
    :class:`~pfbench.errors.InputError` naming the file and the first line of the reason; the
    registry is then as it was before that file.
    """
    _load_all()
    added = []
    for raw in paths:
        path = Path(raw).expanduser()
        if path.suffix != ".py" or not path.is_file():
            raise InputError(f"model file {str(raw)!r}: not an existing .py file")
        key = str(path.resolve())
        if key in _FILES:
            continue
        before = dict(_REGISTRY)
        # named by its path, not its place in the list: compiled kernels are cached under the module's
        # name, so `compile --models a.py --models b.py` serves a later `--models b.py` run
        name = f"pfbench_user_models.m{hashlib.sha1(key.encode()).hexdigest()[:10]}_{path.stem}"
        _IMPORTING.append(key)
        try:
            import_path(name, key)
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - the user's code (sys.exit too): one line
            _REGISTRY.clear()
            _REGISTRY.update(before)
            if isinstance(exc, InputError):
                raise
            first = (str(exc).strip().splitlines() or [""])[0]
            raise InputError(f"model file {str(raw)!r} failed to import: "
                             f"{type(exc).__name__}: {first}") from None
        finally:
            _IMPORTING.pop()
        new = sorted(set(_REGISTRY) - set(before))
        if not new:   # not kept in _FILES: worker processes load those files too
            raise InputError(f"model file {str(raw)!r} registers no model: decorate a StateSpaceModel subclass "
                             "with @register(\"my_model\") (see `pfbench.models.base`)")
        _FILES[key] = name
        added += new
    return added


def loaded_files() -> list[str]:
    """The user model files this process has loaded, in order (resolved paths): what
    :func:`pfbench.procs.process_pool` makes every worker load too."""
    return list(_FILES)


def import_path(name: str, path: str):
    """Import the file ``path`` as the module ``name`` (kept in ``sys.modules``, so worker
    processes can find its objects again); on failure the module is removed and the exception
    propagates. User model files and ``py:`` contenders are imported this way. The file's folder is
    put on ``sys.path`` (last, so it shadows nothing), so the file imports its neighbours as it
    does when run as a script."""
    folder = os.path.dirname(os.path.abspath(path))
    if folder not in sys.path:
        sys.path.append(folder)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def names() -> list[str]:
    """Names of all registered models."""
    _load_all()
    return sorted(_REGISTRY)


def model_class(name: str) -> type[StateSpaceModel]:
    _load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise UnknownNameError(f"unknown model {name!r}; known models: {', '.join(names())}") from None


_KINDS = {"float": float, "int": int, "bool": bool, "str": str}


def _kind(param: inspect.Parameter):
    """(type, None allowed) of a constructor parameter from its annotation (``float``,
    ``float | None``) or else its default (``1.0`` -> float); (None, True) when it is anything else
    (tuples, arrays, ...), which the model checks itself."""
    ann = param.annotation
    if isinstance(ann, type):
        ann = ann.__name__
    if isinstance(ann, str) and ann.strip():
        parts = [a.strip() for a in ann.split("|")]
        kinds = [_KINDS.get(a) for a in parts if a != "None"]
        if len(kinds) == 1 and kinds[0] is not None:
            return kinds[0], "None" in parts
        return None, True
    d = param.default
    if d is inspect.Parameter.empty or d is None:
        return None, True
    for k in (bool, int, float, str):
        if type(d) is k:
            return k, False
    return None, True


def check_params(name: str, params: dict, flag: str = "--param") -> dict:
    """``params`` checked against the constructor signature of model ``name`` BEFORE it is
    built: an unknown key is an :class:`~pfbench.errors.InputError` listing the valid keys (with
    a "did you mean" for a close one), and a scalar for a parameter typed (annotation or default)
    as float/int/bool is checked by :func:`pfbench.options.typed` (``q=abc``, ``q=nan``,
    ``version=2.5`` are refused naming ``flag``). Returns the params with those types applied."""
    cls = model_class(name)
    sig = inspect.signature(cls.__init__).parameters
    names_ = [k for k, p in sig.items() if k != "self"
              and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    if any(p.kind is p.VAR_KEYWORD for p in sig.values()):
        return dict(params)
    check_known(params, names_, f"a parameter of model {name!r}", flag)
    out = {}
    for k, v in params.items():
        kind, none_ok = _kind(sig[k])
        plain = v is None or type(v) in (str, int, float, bool)
        many = isinstance(v, (list, tuple, dict))  # e.g. q=[1,2] for a scalar: refused by typed()
        if kind is None or kind is str or (not plain and not many) or (v is None and none_ok):
            out[k] = v
            continue
        text = v if isinstance(v, str) else json_text(v)
        out[k] = typed(v, kind, f"{flag} {k}={text}")
    return out


def json_text(value) -> str:
    import json

    try:
        return json.dumps(value)
    except (TypeError, ValueError):
        return str(value)


def get(name: str, **params) -> StateSpaceModel:
    """Instantiate the registered model ``name`` with keyword parameters.

    The parameters are first checked by :func:`check_params` (unknown keys, badly typed values);
    a parameter the model refuses (its constructor raises TypeError or ValueError) is an
    :class:`~pfbench.errors.InputError` naming the model.
    """
    cls = model_class(name)
    params = check_params(name, params)
    try:
        return cls(**params)
    except (TypeError, ValueError) as exc:
        raise InputError(f"bad parameters for model {name!r}: {exc}") from None
    except PfbenchError:
        raise
    except Exception as exc:  # noqa: BLE001 - the model's constructor (a user's code): one line
        first = (str(exc).strip().splitlines() or [""])[0]
        raise ModelError(f"model {name!r}: __init__ raised {type(exc).__name__}: {first}") from exc


def parse_spec(spec: str, params: dict | None = None) -> tuple[str, dict]:
    """``"ob3:v4"`` -> ``("ob3", {"version": 4})``, merged with ``params``.

    The variant after the colon is ``vN`` or ``N`` (an integer >= 1) and means ``version=N``; the
    model must take a ``version`` parameter. Giving the variant both ways (``ob3:v4`` and
    ``version=2``) is an :class:`~pfbench.errors.InputError`, as is an unknown model name.
    """
    params = dict(params or {})
    text = str(spec).strip()
    name, sep, variant = text.partition(":")
    name = name.strip()
    cls = model_class(name)  # validates the name
    if not sep:
        return name, params
    v = variant.strip()
    digits = v[1:] if v[:1] in ("v", "V") else v
    if not digits.isdigit() or int(digits) < 1:
        raise InputError(f"model {text!r}: the variant after ':' must be vN or N (e.g. {name}:v2)")
    if "version" not in inspect.signature(cls.__init__).parameters:
        raise InputError(f"model {name!r} has no variants (no 'version' parameter), got {text!r}")
    if "version" in params and params["version"] != int(digits):
        raise InputError(f"model {text!r} and version={params['version']!r} disagree: give the "
                         "variant once")
    params["version"] = int(digits)
    return name, params


def format_spec(name: str, params: dict | None = None) -> str:
    """The model as a user would name it, the inverse of :func:`parse_spec`: ``("ob3",
    {"version": 4})`` -> ``"ob3:v4"``; other parameters follow as ``--param`` text, sorted
    (``"ob4 shared_noise=true"``), so that a table of results says which model it holds."""
    params = dict(params or {})
    version = params.pop("version", None)
    text = f"{name}:v{version}" if isinstance(version, int) and not isinstance(version, bool) else name
    if version is not None and text == name:
        params["version"] = version
    return " ".join([text] + [f"{k}={json_text(v)}" for k, v in sorted(params.items())])


def get_spec(spec: str, **params) -> StateSpaceModel:
    """Instantiate a model spec (``"ob1"``, ``"ob3:v4"``) with extra keyword parameters."""
    name, params = parse_spec(spec, params)
    return get(name, **params)


__all__ = ["StateSpaceModel", "Trajectory", "gaussian_loglik_diag", "register", "names", "get",
           "get_spec", "parse_spec", "format_spec", "model_class", "load_files", "loaded_files"]

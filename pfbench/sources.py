"""What a compiled or stored result depends on beyond its own file: the user's code that a
function reaches and the values of the globals it reads.

numba compiles a model function with the functions it calls inlined and the module globals it reads
frozen as constants, so a cache keyed on the model's own file goes stale when a helper in another
file, or a constant imported from one, changes; so does a sweep or comparison that resumes from a
store. :func:`digest` walks the globals that functions name, into the functions they call, and
hashes the source files outside the Python installation and pfbench (the user's code) and the
values of plain constants (numbers, strings, tuples, arrays).
"""
from __future__ import annotations

import functools
import hashlib
import inspect
import os
import sys
import types
from pathlib import Path

import numpy as np

#: files under these folders are the installation's (their versions are in the package
#: fingerprint, :func:`pfbench.backends.cache.package_fingerprint`) or pfbench's own (hashed there)
_NOT_USER = tuple({os.path.realpath(p) + os.sep for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
                  | {os.path.realpath(Path(__file__).resolve().parent) + os.sep})


def file_hash(path: str) -> str:
    """sha256 of a file's bytes, read again only when its modification time or size changes."""
    st = os.stat(path)
    return _hash_cached(path, st.st_mtime_ns, st.st_size)


@functools.cache
def _hash_cached(path: str, mtime_ns: int, size: int) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def user_file(obj) -> str | None:
    """The source file of a module, class or function when it is the user's (see the module
    docstring); else None."""
    try:
        path = inspect.getsourcefile(obj)
    except TypeError:
        return None
    real = os.path.realpath(path) if path else None
    return real if real and os.path.exists(real) and not real.startswith(_NOT_USER) else None


def _names(code: types.CodeType) -> set:
    out = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            out |= _names(c)
    return out


def _constant(value, h) -> None:
    if isinstance(value, np.ndarray):
        h.update(f"{value.dtype}{value.shape}".encode() + np.ascontiguousarray(value).tobytes())
    elif isinstance(value, (tuple, list)):
        for v in value:
            _constant(v, h)
    elif value is None or isinstance(value, (bool, int, float, complex, str, bytes, np.generic)):
        h.update(repr(value).encode())


def digest(funcs) -> str:
    """Hash of what ``funcs`` (functions, static methods or numba dispatchers) depend on outside their
    own file: the user's source files of the modules, classes and functions their globals name
    (functions walked in turn) and the values of the constants they read."""
    h, files, seen = hashlib.sha256(), set(), set()
    stack = list(funcs)
    while stack:
        f = stack.pop()
        f = getattr(getattr(f, "__func__", f), "py_func", getattr(f, "__func__", f))
        if id(f) in seen or not isinstance(getattr(f, "__code__", None), types.CodeType):
            continue
        seen.add(id(f))
        g = f.__globals__
        for name in sorted(_names(f.__code__) & g.keys()):
            value = g[name]
            if isinstance(value, (types.ModuleType, type)) or callable(value):
                path = user_file(getattr(value, "py_func", value))
                if path:
                    files.add(path)
                    stack.append(value)
            else:
                h.update(name.encode() + b"=")
                _constant(value, h)
    for path in sorted(files):
        h.update(path.encode() + b"\0" + file_hash(path).encode())
    return h.hexdigest()


def model_digest(cls: type) -> str:
    """Hash of a model class's module source (its functions' bytecode when it has none) and of what
    its functions depend on (:func:`digest`)."""
    h = hashlib.sha256()
    funcs = [v for k in cls.__mro__ if k is cls or user_file(k) for v in vars(k).values()
             if isinstance(v, (staticmethod, classmethod, types.FunctionType))]
    try:
        h.update(inspect.getsource(sys.modules[cls.__module__]).encode())
    except (OSError, TypeError, KeyError):  # no source file (code run by exec): the functions' bytecode
        for v in (v for k in cls.__mro__ for v in vars(k).values()):
            if isinstance(getattr(v, "__func__", v), types.FunctionType):
                _bytecode(getattr(v, "__func__", v).__code__, h)
    h.update(digest(funcs).encode())
    return h.hexdigest()


def _bytecode(code: types.CodeType, h) -> None:
    """Hash a code object's instructions, the names it reads and its constants, nested functions
    included, the same in every process (a code object's repr holds its address, a frozenset's
    order follows the string hash seed)."""
    h.update(code.co_code + " ".join(code.co_names).encode())
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            _bytecode(c, h)
        else:
            h.update(repr(sorted(c, key=repr) if isinstance(c, frozenset) else c).encode())

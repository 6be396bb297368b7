"""One parser for every ``KEY=VALUE`` option of the CLI (``--param``, ``--option``), so the same
text is typed the same way everywhere.

A value is read as a JSON literal when it is one (``3`` -> int, ``0.5``/``1e-3`` -> float,
``true``/``false`` -> bool, ``null`` -> None, ``[1, 2]`` -> list); anything else is the string
itself (``scheme=systematic`` -> ``"systematic"``). Keys are identifiers; a repeated key, an empty
key or an item without ``=`` is an :class:`~pfbench.errors.InputError` that names the flag.
"""
from __future__ import annotations

import difflib
import enum
import json
import math
from typing import Iterable

from .errors import InputError


class Choice(enum.IntEnum):
    """A table of named choices with integer codes (methods, resampling schemes): the code is what
    compiled kernels branch on, the lower-case name is what users type."""

    @property
    def label(self) -> str:
        return self.name.lower()

    @classmethod
    def labels(cls) -> tuple[str, ...]:
        return tuple(m.label for m in cls)

    @classmethod
    def parse(cls, name):
        """The member called ``name`` (case-insensitive), or an InputError listing the choices."""
        if isinstance(name, cls):
            return name
        try:
            return cls[str(name).strip().upper()]
        except KeyError:
            raise InputError(f"unknown {cls._what} {name!r}; choose one of {', '.join(cls.labels())}") from None


def parse_value(text: str):
    """The typed value of one option text (see the module docstring)."""
    try:
        value = json.loads(text)
    except ValueError:
        return text
    if isinstance(value, float) and not math.isfinite(value):
        return text
    return value


def parse_key_values(items: Iterable[str], flag: str = "--option") -> dict:
    """``["a=1", "b=x"]`` -> ``{"a": 1, "b": "x"}``; errors name ``flag``."""
    out: dict = {}
    for item in items:
        if "=" not in item:
            raise InputError(f"{flag} {item!r}: expected KEY=VALUE")
        key, text = item.split("=", 1)
        key = key.strip()
        if not key.isidentifier():
            raise InputError(f"{flag} {item!r}: the key must be a name such as 'steps'")
        if key in out:
            raise InputError(f"{flag} {key} is given twice")
        out[key] = parse_value(text.strip())
    return out


def did_you_mean(word: str, choices: Iterable[str], bare: bool = False) -> str:
    """``"; did you mean X?"`` (or just ``X`` with ``bare``) when one of ``choices`` is close to
    ``word`` (difflib), else ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1)
    if not close:
        return ""
    return close[0] if bare else f"; did you mean {close[0]}?"


def check_known(options, known: Iterable[str], what: str, flag: str = "--option") -> None:
    """Raise an :class:`InputError` if ``options`` (a mapping or names) has a key not in ``known``:
    ``<flag> <key> (did you mean X?): not <what> (valid keys: ...)``, a hint for every close key."""
    known = sorted(set(known))
    unknown = [k for k in options if k not in known]
    if unknown:
        keys = ", ".join(f"{k} (did you mean {close}?)" if (close := did_you_mean(k, known, bare=True))
                         else str(k) for k in unknown)
        raise InputError(f"{flag} {keys}: not {what} (valid keys: {', '.join(known) or 'none'})")


_TYPE_NAMES = {int: "an integer", float: "a number", bool: "true or false", str: "a text"}


def typed(value, kind, what: str):
    """``value`` (as :func:`parse_value` typed it) checked against ``kind`` (int, float, bool, str
    or None for any), with the parser's rules and no silent rounding: ``2.7`` or ``2.0`` is not an
    int, ``true`` is not a number, NaN and infinities are not numbers, an int is a valid float
    (``3`` -> 3.0), and any scalar is a
    valid str (``30`` -> ``"30"``). A str ``value`` for an int, float or bool is first typed by
    :func:`parse_value` (``"3"`` -> 3, as on the command line), so text typed through the Python
    API agrees with the CLI. Anything else is an InputError starting with ``what``
    (e.g. ``"--option runs=2.7"``). Another callable ``kind`` converts, its TypeError/ValueError
    becoming the InputError."""
    if kind is None:
        return value
    if isinstance(value, str) and kind in (int, float, bool):
        value = parse_value(value.strip())
    is_bool = isinstance(value, bool)
    if kind is bool:
        ok = is_bool
    elif kind is int:
        ok = isinstance(value, int) and not is_bool
    elif kind is float:
        ok = isinstance(value, (int, float)) and not is_bool
        value = float(value) if ok else value
        if ok and not math.isfinite(value):
            raise InputError(f"{what}: expected a finite number, got {value}")
    elif kind is str:
        ok = value is None or isinstance(value, (str, int, float))
        value = value if isinstance(value, str) else json.dumps(value)
    else:
        try:
            return kind(value)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{what}: {exc}") from None
    if not ok:
        name = _TYPE_NAMES.get(kind, getattr(kind, "__name__", str(kind)))
        raise InputError(f"{what}: expected {name}, got {json.dumps(value, default=str)}")
    return value


def comma_list(value, flag: str, allowed: Iterable[str] | None = None) -> list[str]:
    """``"a,b"`` (command line) or ``["a", "b"]`` / ``"a"`` (grid file) -> ``["a", "b"]``, items
    stripped: an empty item (two commas in a row, a comma at either end), an empty list or, with
    ``allowed``, an item not in it is an InputError naming ``flag`` (the one way every
    comma-separated CLI option is split)."""
    items = [str(v).strip() for v in value] if isinstance(value, (list, tuple)) else \
        [v.strip() for v in str(value).split(",")]
    if items == [""] or not items:
        raise InputError(f"{flag} is empty")
    if "" in items:
        raise InputError(f"{flag} {value!r}: an empty item (two commas in a row, or a comma at either end); "
                         "give values such as a,b")
    if allowed is not None:
        allowed = tuple(allowed)
        for v in items:
            if v not in allowed:
                raise InputError(f"{flag} {v!r} is not one of {', '.join(allowed)}{did_you_mean(v, allowed)}")
    return items

"""One parser for every ``KEY=VALUE`` option of the CLI (``--param``, ``--option``), so the same
text is typed the same way everywhere.

A value is read as a JSON literal when it is one (``3`` -> int, ``0.5``/``1e-3`` -> float,
``true``/``false`` -> bool, ``null`` -> None, ``[1, 2]`` -> list); anything else is the string
itself (``scheme=systematic`` -> ``"systematic"``). Keys are identifiers; a repeated key, an empty
key or an item without ``=`` is an :class:`~pfbench.errors.InputError` that names the flag.
"""
from __future__ import annotations

import json
import math
from typing import Iterable

from .errors import InputError


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


def check_known(options: dict, known: Iterable[str], what: str, flag: str = "--option") -> None:
    """Raise an :class:`InputError` listing the valid keys if ``options`` has an unknown one."""
    known = sorted(set(known))
    unknown = sorted(set(options) - set(known))
    if unknown:
        valid = ", ".join(known) if known else "none"
        raise InputError(f"{flag} {', '.join(unknown)}: not an option of {what} (valid: {valid})")

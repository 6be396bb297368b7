"""Declared ranges of option values, checked at the edge.

A recipe option (``@recipe(options={key: (type, help, rule)})``, see :mod:`pfbench.recipes`)
names one rule for its values, so that ``--option Q=-1`` is one ``error:`` line before any work
rather than a NaN or a traceback deep inside the run, and ``pfbench options ID`` can show what is
allowed. Four rules cover every option:

* :class:`Range`: a number within bounds, each inclusive or open (:func:`at_least`, :func:`above`);
* :class:`OneOf`: a text from a fixed list;
* :class:`ModelSpec`: a registered model (``ob1``, ``ob3:v4``, or one of a user's model file);
* :class:`ListOf`: comma-separated items (``10,20`` or a JSON list), each typed and checked by
  another rule, with a number of items in bounds.

Every rule has ``check(value, what) -> value`` (an :class:`~pfbench.errors.InputError` starting
with ``what`` when the value is outside) and ``str(rule)``, the text ``pfbench options`` shows.
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import InputError


def _num(x) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


@dataclass(frozen=True)
class Range:
    """Numbers between ``low`` and ``high`` (None: unbounded); a bound is included unless open."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False

    def contains(self, value) -> bool:
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        return self.high is None or not (value > self.high or (self.high_open and value == self.high))

    def check(self, value, what: str):
        if not self.contains(value):
            raise InputError(f"{what}: must be {self}")
        return value

    def __str__(self) -> str:
        if self.low is not None and self.high is not None:
            return (f"in {'(' if self.low_open else '['}{_num(self.low)}, "
                    f"{_num(self.high)}{')' if self.high_open else ']'}")
        if self.low is not None:
            return f"{'>' if self.low_open else '>='} {_num(self.low)}"
        if self.high is not None:
            return f"{'<' if self.high_open else '<='} {_num(self.high)}"
        return "any finite"


def at_least(low, high=None) -> Range:
    """``low <= value`` (and ``<= high`` if given)."""
    return Range(low, high)


def above(low, high=None) -> Range:
    """``low < value`` (and ``<= high`` if given): e.g. a variance or a duration, ``above(0)``."""
    return Range(low, high, low_open=True)


ANY = Range()            # any finite number (the type check already refuses NaN and infinities)
COUNT = at_least(1)      # particles, steps, runs, repetitions
INDEX = at_least(0)      # a realisation or stream number
POSITIVE = above(0)      # variances, gains, durations, powers


@dataclass(frozen=True)
class OneOf:
    """A text from ``choices``."""

    choices: tuple[str, ...]

    def __init__(self, *choices: str):
        object.__setattr__(self, "choices", tuple(choices))

    def check(self, value, what: str):
        if value not in self.choices:
            from .options import did_you_mean

            raise InputError(f"{what}: must be {self}{did_you_mean(value, self.choices)}")
        return value

    def __str__(self) -> str:
        return "one of " + ", ".join(self.choices)


@dataclass(frozen=True)
class ModelSpec:
    """A registered model spec (the registry is known only at run time: built-ins and the user's
    model files)."""

    def check(self, value, what: str):
        from .models import parse_spec

        try:
            parse_spec(value)
        except InputError as exc:
            raise InputError(f"{what}: {exc}") from None
        return value

    def __str__(self) -> str:
        return "registered models (`pfbench models` lists them)"


@dataclass(frozen=True)
class ListOf:
    """Comma-separated items (text ``"10,20"``, a JSON list, or one scalar), each of type ``item``
    checked by ``rule`` (None: any), between ``min_items`` and ``max_items`` of them, none twice
    (each item is one case of the recipe). The checked value is a Python list."""

    item: type
    rule: object = None
    min_items: int = 1
    max_items: int | None = None

    def check(self, value, what: str) -> list:
        from .options import typed

        if isinstance(value, (list, tuple)):
            items = list(value)
        elif isinstance(value, str):
            items = [v.strip() for v in value.split(",")]
            if "" in items and value.strip():
                raise InputError(f"{what}: an empty item (two commas in a row, or a comma at either end)")
            items = [v for v in items if v]
        else:
            items = [value]
        n = len(items)
        if n < self.min_items or (self.max_items is not None and n > self.max_items):
            raise InputError(f"{what}: must be {self._count()}, got {n}")
        out = [typed(v, self.item, f"{what}: item {v!r}") for v in items]
        if self.rule is not None:
            out = [self.rule.check(v, f"{what}: item {v!r}") for v in out]
        twice = [v for i, v in enumerate(out) if v in out[:i]]
        if twice:
            raise InputError(f"{what}: {twice[0]!r} is given twice")
        return out

    def _count(self) -> str:
        lo, hi = self.min_items, self.max_items
        if hi is None:
            return f"at least {lo} item{'s' if lo != 1 else ''}"
        return f"{lo} item{'s' if lo != 1 else ''}" if lo == hi else f"{lo} to {hi} items"

    def __str__(self) -> str:
        """E.g. ``ints >= 1`` or ``ints >= 0, 2 items`` (the item count when it is not 1 or more)."""
        kind = "texts" if self.item is str else f"{self.item.__name__}s"
        each = f" {self.rule}" if self.rule is not None else ""
        many = "" if (self.min_items, self.max_items) == (1, None) else f", {self._count()}"
        return f"{kind}{each}{many}"

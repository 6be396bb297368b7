"""The shared vocabulary of the command line: option types and shell completion.

Every command takes the same option the same way: a method, backend or scheme is a choice (one,
or with :class:`ChoiceList` a comma-separated list of them) that ``--help`` lists and the shell
completes; ``--model`` completes registered model names and a recipe argument the recipe IDs;
``--out`` is typed :data:`OUT_FILE` where it names a file and :data:`OUT_DIR` where it names a
folder. Completion is click's (README "Shell completion").
"""
from __future__ import annotations

import math

import click
from click.shell_completion import CompletionItem

from .options import comma_list


def _last_item(incomplete: str) -> tuple[str, str]:
    """``"a,b,c"`` -> ``("a,b,", "c")``: what is typed before the item being completed, and the item."""
    head, sep, last = incomplete.rpartition(",")
    return head + sep, last


def _complete_from(values, incomplete: str, *, many: bool = False) -> list[CompletionItem]:
    head, last = _last_item(incomplete) if many else ("", incomplete)
    return [CompletionItem(head + v) for v in values if v.startswith(last)]


class ChoiceList(click.ParamType):
    """One or a comma-separated list of ``choices`` (``--method bootstrap,sir``): checked when the
    command line is read and completed item by item. The value stays the text, split later by
    :func:`pfbench.options.comma_list` (grid files give lists of the same names)."""

    name = "choice_list"

    def __init__(self, choices):
        self.choices = tuple(choices)

    def convert(self, value, param, ctx):
        comma_list(value, getattr(param, "opts", None) and param.opts[0] or "value", self.choices)
        return value

    def shell_complete(self, ctx, param, incomplete):
        return _complete_from(self.choices, incomplete, many=True)


def positive_int(name: str):
    """A click callback: ``--name`` is None or an integer >= 1 (a usage error otherwise)."""
    def cb(ctx, param, value):
        if value is not None and value < 1:
            raise click.BadParameter(f"must be >= 1, got {value}", param_hint=f"'--{name}'")
        return value
    return cb


def positive_float(name: str, allow_zero: bool = False):
    """A click callback: ``--name`` is None or a finite number > 0 (>= 0 with ``allow_zero``); NaN and
    infinities are refused, which click's FloatRange lets through."""
    def cb(ctx, param, value):
        if value is None:
            return value
        if not (math.isfinite(value) and (value >= 0 if allow_zero else value > 0)):
            raise click.BadParameter(f"must be a finite number {'>= 0' if allow_zero else '> 0'}, got {value}",
                                     param_hint=f"'--{name}'")
        return value
    return cb


def complete_models(ctx, param, incomplete):
    """Registered model names (a comma-separated list where the option takes several)."""
    from . import models

    return _complete_from(models.names(), incomplete, many=param.metavar is not None and "," in param.metavar)


def complete_recipes(ctx, param, incomplete):
    """Recipe IDs and aliases (`pfbench list`)."""
    from .recipes import discover

    reg = discover()
    return _complete_from(sorted({*reg, *(a for r in reg.values() for a in r.aliases)}), incomplete)


def complete_papers(ctx, param, incomplete):
    from .recipes import discover

    return _complete_from(sorted({r.paper for r in discover().values()}), incomplete)


def complete_tasks(ctx, param, incomplete):
    from . import tasks

    return _complete_from(tasks.names(), incomplete, many=True)


#: ``--out`` naming a file (created or replaced) and naming a folder (created if missing)
class NonEmptyPath(click.Path):
    """click's path type, refusing an empty name: ``--out ""`` (an unset shell variable) would
    otherwise mean no output at all, or the current folder."""

    def convert(self, value, param, ctx):
        if isinstance(value, str) and not value.strip():
            self.fail("an empty path (an unset shell variable?)", param, ctx)
        return super().convert(value, param, ctx)


OUT_FILE = dict(type=NonEmptyPath(dir_okay=False), metavar="FILE")
OUT_DIR = dict(type=NonEmptyPath(file_okay=False), metavar="DIR")

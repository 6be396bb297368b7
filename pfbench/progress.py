"""Progress bars: tqdm on stderr, drawn only when stderr is a terminal.

Redirected to a file (a batch job's log, ``2> log``), a bar would be a stream of
carriage-return redraws, so there it stays off; ``--quiet`` turns it off everywhere.
"""
from __future__ import annotations

import sys


def progress_bar(iterable=None, *, show: bool = True, **kw):
    """A tqdm bar over ``iterable`` (or a manual one with ``total=``); ``show=False`` hides it."""
    from tqdm.auto import tqdm

    kw.setdefault("file", sys.stderr)
    # disable=None: tqdm draws only if the file is a terminal
    return tqdm(iterable, disable=None if show else True, **kw)

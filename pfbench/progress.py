"""Progress on a terminal: tqdm bars on stderr, and a line when numba compiles; both only when
stderr is a terminal.

Redirected to a file (a batch job's log, ``2> log``), a bar would be a stream of
carriage-return redraws, so there it stays off; ``--quiet`` turns it off everywhere.
"""
from __future__ import annotations

import contextlib
import sys


def progress_bar(iterable=None, *, show: bool = True, **kw):
    """A tqdm bar over ``iterable`` (or a manual one with ``total=``); ``show=False`` hides it."""
    from tqdm.auto import tqdm

    kw.setdefault("file", sys.stderr)
    # disable=None: tqdm draws only if the file is a terminal
    return tqdm(iterable, disable=None if show else True, **kw)


#: the line :func:`compile_notice` prints
COMPILING = ("compiling numba kernels for this run (not in the cache yet; later runs load them from it, "
             "and `pfbench compile` builds them ahead) ...")


@contextlib.contextmanager
def compile_notice(stream=None, *, show: bool = True):
    """Inside the block, print :data:`COMPILING` once to ``stream`` (standard error) when numba starts
    compiling (a miss of its disk cache), if ``stream`` is a terminal: a first run spends seconds
    compiling before it starts, and a silent terminal then looks like a hang. ``show=False``
    (``--quiet``): never."""
    stream = sys.stderr if stream is None else stream
    if not show or not stream.isatty():
        yield
        return
    from numba.core import event

    class Notice(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                print(COMPILING, file=stream, flush=True)

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Notice()):
        yield

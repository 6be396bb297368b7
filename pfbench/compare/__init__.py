"""``pfbench compare``: any filter -- pfbench's, a peer library's, a user's Python function or an
external program -- on the named tasks of :mod:`pfbench.tasks`, with paired statistics and a
leaderboard.

* :mod:`.contenders`: the ``--contender [NAME=]SPEC`` forms, the ``cmd:`` protocol, failures;
* :mod:`.run`: the task x contender grid on the sweep machinery (journal, local or Dask);
* :mod:`.stats`: metrics and paired 95 % intervals against a baseline;
* :mod:`.leaderboard`: leaderboard.md, compare.json and the accuracy-vs-time plots;
* :mod:`.particles_adapter`, :mod:`.filterpy_adapter`: the peer libraries.
"""
__all__ = ["make_spec", "run_compare", "summarize"]


def __getattr__(name):  # lazy: the out-of-process particles adapter needs only pfbench.models
    if name in ("make_spec", "run_compare"):
        from . import run

        return getattr(run, name)
    if name == "summarize":
        from .stats import summarize

        return summarize
    raise AttributeError(name)

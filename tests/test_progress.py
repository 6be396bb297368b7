"""Progress on a terminal: the line a cold numba compile prints."""
import io

import numba

from pfbench.progress import COMPILING, compile_notice


class Terminal(io.StringIO):
    def isatty(self):
        return True


def _fresh_function():
    """A dispatcher no process has compiled (no disk cache): calling it compiles."""
    return numba.njit(lambda a: a + 1)


def test_a_compile_on_a_terminal_is_announced_once():
    """Catches: silence while a cold kernel compiles, or one line per compiled function."""
    out = Terminal()
    with compile_notice(out):
        f, g = _fresh_function(), _fresh_function()
        assert f(1) == 2 and g(2.0) == 3.0
    assert out.getvalue() == COMPILING + "\n"


def test_no_line_without_a_compile_or_off_a_terminal():
    """Catches: the line printed for a function already compiled, into a pipe or a log, or after
    the block."""
    f = _fresh_function()
    f(1)
    out = Terminal()
    with compile_notice(out):
        f(2)
    assert out.getvalue() == ""
    pipe = io.StringIO()
    with compile_notice(pipe):
        _fresh_function()(1)
    assert pipe.getvalue() == ""
    with compile_notice(out):
        pass
    _fresh_function()(1)
    assert out.getvalue() == ""

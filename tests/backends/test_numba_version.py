"""The numba in use is one of the versions pfbench is tested with: the compiled backend relies on
numba internals (its cache classes, intrinsics and LLVM pass settings), which change between
minor versions without notice."""
import re
from pathlib import Path

import numba
import pytest

PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"


def _pin() -> str:
    m = re.search(r'"numba([^"]*)"', PYPROJECT.read_text())
    assert m, "pyproject.toml declares no numba requirement"
    return m.group(1)


def test_numba_is_pinned_to_a_tested_range_and_the_installed_one_is_in_it():
    """Catches an unbounded pin (a new minor version installed untested) and an environment with
    a numba outside the range (a clear message instead of obscure compile errors)."""
    from packaging.specifiers import SpecifierSet
    from packaging.version import Version

    pin = SpecifierSet(_pin())
    assert any(s.operator in ("<", "<=", "~=", "==") for s in pin), f"numba{pin} has no upper bound"
    installed = Version(numba.__version__)
    if installed not in pin:
        pytest.fail(f"numba {installed} is outside the tested range numba{pin}: pfbench's compiled backend "
                    "relies on numba internals; install a tested version or test this one and widen the pin")

"""Ctrl-C at any moment is ``error: interrupted`` and exit code 130, also while the modules load.

A Ctrl-C at a chosen moment, made deterministic: an import hook raises KeyboardInterrupt (what
Python's SIGINT handler raises) when a given module is first imported, in a fresh interpreter that
starts the command as the installed console script does (``from pfbench.__main__ import main``).
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = """
import sys

AT = sys.argv.pop(1)


class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == AT:
            raise KeyboardInterrupt
        return None


sys.meta_path.insert(0, CtrlC())
from pfbench.__main__ import main
sys.exit(main())
"""


@pytest.mark.parametrize("module,args", [
    # loaded by `import pfbench` before the fix (the package imported its models eagerly):
    # catches an eager heavy import in pfbench/__init__.py, before any handler can run
    ("numpy", ["info"]),
    # the CLI module's own imports: catches an entry point without the try around them
    ("click", ["info"]),
    # a subsystem loaded while the command line is parsed: catches the handler in PfbenchGroup.main
    ("pfbench.sweep.cli", ["sweep", "--help"]),
])
def test_ctrl_c_while_modules_load_is_interrupted_130(module, args):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", SCRIPT, module, *args], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 130, (r.returncode, r.stderr)
    assert r.stderr.strip() == "error: interrupted", r.stderr


def test_the_console_script_is_the_guarded_entry_point():
    # Catches: the `pfbench` script pointing at pfbench.cli:main again, whose imports run unguarded.
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["pfbench"] == "pfbench.__main__:main"

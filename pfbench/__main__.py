"""The ``pfbench`` command's entry point (the console script and ``python -m pfbench``).

It loads :mod:`pfbench.cli`, whose imports (click, numpy, numba) take a noticeable time, inside a
``try``: a Ctrl-C while they load is ``error: interrupted`` and exit code 130, as a Ctrl-C at any
later moment is (:meth:`pfbench.cli.PfbenchGroup.main`), not a KeyboardInterrupt traceback. Nothing
heavy may be imported before this runs, which is why ``import pfbench`` loads its subpackages lazily.
"""
import sys


def main() -> None:
    """Run the ``pfbench`` command line."""
    try:
        from .cli import main as cli
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(130)
    cli()


if __name__ == "__main__":
    main()

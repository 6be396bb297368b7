"""Run the pfbench CLI with a fault injected at the N-th ``os.replace`` (every result file of a
recipe is renamed into place by one): ``python _killer.py N kill|hold -- pfbench args...``.

``kill``: SIGKILL this process just before the N-th rename (a real ``kill -9`` at an exact moment).
``hold``: just before the N-th rename, write ``$KILLER_READY`` and sleep (a writer that holds its
output lock until the test kills it).
"""
import os
import signal
import sys
import time

n, mode = int(sys.argv[1]), sys.argv[2]
args = sys.argv[sys.argv.index("--") + 1:]
_real, _count = os.replace, [0]


def _replace(src, dst, *a, **k):
    _count[0] += 1
    if _count[0] == n:
        if mode == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        open(os.environ["KILLER_READY"], "w").close()
        time.sleep(120)
    return _real(src, dst, *a, **k)


os.replace = _replace
from pfbench.cli import main  # noqa: E402

main(args, prog_name="pfbench")

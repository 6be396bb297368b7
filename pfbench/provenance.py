"""Provenance of a run: git SHA, package versions, CPU, threading layer."""
from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

PACKAGES = ("pfbench", "numpy", "numba", "llvmlite", "scipy", "pandas", "pyarrow",
            "matplotlib", "click", "dask", "distributed")


def git_sha() -> str | None:
    """SHA of the checkout pfbench runs from (with ``-dirty`` when modified), or None."""
    root = Path(__file__).resolve().parent.parent
    try:
        sha = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


def package_versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def numba_threading_layer() -> str | None:
    try:
        import numba
        from numba.np.ufunc.parallel import _launch_threads

        _launch_threads()
        return numba.threading_layer()
    except Exception:  # noqa: BLE001 - informational only
        return None


def host_info() -> dict:
    """Machine facts for provenance and ``pfbench info``."""
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "machine": platform.machine(),
        "system": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "load_average": load_average(),
    }


def load_average() -> list[float] | None:
    """The system's 1-, 5- and 15-minute load averages when the record is written (None where the
    OS has none): timings, and the timing claims decided from them, are only as good as the machine
    was quiet."""
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except (AttributeError, OSError):  # pragma: no cover - not on this OS
        return None


def provenance(**extra) -> dict:
    """The provenance record stored beside every result: when, which code and machine, the command
    line, and the user's model files (``--models``) with their sha256."""
    import sys

    from .models import loaded_files
    from .sources import file_hash

    rec = {
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "git_sha": git_sha(),
        "host": host_info(),
        "packages": package_versions(),
        "argv": list(sys.argv[1:]),
        "model_files": {p: file_hash(p) if os.path.exists(p) else None for p in loaded_files()},
    }
    rec.update(extra)
    return rec

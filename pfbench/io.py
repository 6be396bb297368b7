"""Result files: atomic writes with normal permissions, strict JSON, checksums, output locks.

Atomic writes
    Every file is written to a temporary name in the same directory and renamed onto its name, so
    a crash or Ctrl-C never leaves a half-written file under the final name. The file gets the
    permissions of an ordinary new file, ``0o666 & ~umask`` (not the ``0o600`` of temp files).

Strict JSON
    Every JSON text pfbench writes or prints (results, provenance, ``--json`` outputs) is RFC 8259
    JSON, which has no NaN or infinities. The convention, applied by :func:`strict` (and so by
    :func:`to_json` and :func:`write_json`): a non-finite number becomes ``null`` and the object
    that holds it gets a sibling field ``"<key>_nonfinite"`` saying what the value was, e.g.
    ``{"loglik": null, "loglik_nonfinite": "-inf"}``; inside a list the note names the positions,
    ``{"rmse": [0.3, null], "rmse_nonfinite": "nan at [1]"}``. A caller may set the note itself
    with a reason (``"-inf: 3 degenerate steps"``); an existing note is kept. A non-finite number
    outside any object (a bare list at the top) just becomes ``null``. :func:`to_json` then calls
    ``json.dumps(..., allow_nan=False)`` so any regression raises instead of writing ``NaN``.
    :func:`loads` is the matching strict reader (``NaN``/``Infinity`` are a DataError).

Checksums
    :func:`sha256` of a file: the provenance record of a recipe lists one per artefact (see
    :mod:`pfbench.recipes`). One writer per output is :func:`pfbench.procs.exclusive_lock`.

An OSError while writing (read-only file system, a parent that is a file, no permission) is a
:class:`~pfbench.errors.DataError` naming the path and what to do
(:func:`pfbench.resources.path_error`).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .errors import DataError

NONFINITE_SUFFIX = "_nonfinite"


# --------------------------------------------------------------------------- file system faults
def output_error(path, exc: OSError, flag: str = "--out") -> DataError:
    """The one-line DataError for an OSError while writing ``path`` (names it, says what to do)."""
    from .resources import path_error

    return path_error(exc, path, flag)


def _umask() -> int:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    old = os.umask(0o022)   # no /proc: read it by setting it (not thread-safe, rare)
    os.umask(old)
    return old


def file_mode() -> int:
    """The mode of an ordinary new file: ``0o666 & ~umask``."""
    return 0o666 & ~_umask()


def make_dirs(path: str | os.PathLike) -> Path:
    """``mkdir -p path``; an OSError becomes a DataError naming the directory."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(path, exc) from None
    return path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    The file gets the mode of an ordinary new file (``0o666 & ~umask``); the temporary file is
    removed on any error. An OSError (creating the directory, writing, renaming) is a DataError
    naming ``path`` (:func:`output_error`).
    """
    path = Path(path)
    make_dirs(path.parent)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise output_error(path, exc) from None
    tmp_path = Path(tmp)
    try:
        os.fchmod(fd, file_mode())
        os.close(fd)
        yield tmp_path
        os.replace(tmp_path, path)
    except OSError as exc:
        raise output_error(path, exc) from None
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


# --------------------------------------------------------------------------- strict JSON
def _plain(obj: Any) -> Any:
    """NumPy scalars/arrays, paths, tuples, sets -> plain JSON types (recursively)."""
    if isinstance(obj, dict):
        return {str(k) if not isinstance(k, str) else k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (set, frozenset)):
        return [_plain(v) for v in sorted(obj, key=str)]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return obj


def _nonfinite_text(x: float) -> str:
    return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")


def _scrub_list(items: list, where: list, prefix: str) -> list:
    out = []
    for i, v in enumerate(items):
        if isinstance(v, float) and not math.isfinite(v):
            where.append(f"{_nonfinite_text(v)} at [{prefix}{i}]")
            out.append(None)
        elif isinstance(v, list):
            out.append(_scrub_list(v, where, f"{prefix}{i}, "))
        elif isinstance(v, dict):
            out.append(_scrub_dict(v))
        else:
            out.append(v)
    return out


def _scrub_dict(d: dict) -> dict:
    out: dict = {}
    notes: dict = {}
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = None
            notes[k + NONFINITE_SUFFIX] = _nonfinite_text(v)
        elif isinstance(v, list):
            where: list = []
            out[k] = _scrub_list(v, where, "")
            if where:
                shown = "; ".join(where[:5]) + (f"; ... ({len(where)} in all)" if len(where) > 5 else "")
                notes[k + NONFINITE_SUFFIX] = shown
        elif isinstance(v, dict):
            out[k] = _scrub_dict(v)
        else:
            out[k] = v
    for k, note in notes.items():
        if out.get(k) is None:          # a note the caller wrote (with a reason) wins
            out[k] = note
    return out


def strict(obj: Any) -> Any:
    """``obj`` as plain JSON data with every non-finite number replaced by ``null`` and noted in
    a ``"<key>_nonfinite"`` sibling field (see the module docstring)."""
    obj = _plain(obj)
    if isinstance(obj, dict):
        return _scrub_dict(obj)
    if isinstance(obj, list):
        return _scrub_list(obj, [], "")
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _json_default(obj: Any) -> Any:
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def to_json(obj: Any, **kw: Any) -> str:
    """Strict RFC 8259 JSON text of ``obj`` (see :func:`strict`); raises ValueError on a bug that
    would still produce NaN/Infinity. ``default=`` converts other types (e.g. ``str``)."""
    kw.setdefault("default", _json_default)
    return json.dumps(strict(obj), allow_nan=False, **kw)


def _no_constant(name: str):
    raise ValueError(f"{name} is not valid JSON (RFC 8259)")


def loads(text: str, source: str = "JSON text") -> Any:
    """Parse strict JSON (``NaN``/``Infinity`` rejected); a DataError naming ``source``."""
    try:
        return json.loads(text, parse_constant=_no_constant)
    except ValueError as exc:
        raise DataError(f"{source}: not valid JSON ({exc})") from None


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(to_json(obj, indent=2, sort_keys=False) + "\n")
    return Path(path)


def write_text(path: str | os.PathLike, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_csv(path: str | os.PathLike, frame) -> Path:
    """Write a pandas DataFrame as CSV (no index)."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False)
    return Path(path)


def write_parquet(path: str | os.PathLike, frame) -> Path:
    with atomic_path(path) as tmp:
        frame.to_parquet(tmp, index=False)
    return Path(path)


def write_figure(path: str | os.PathLike, fig, dpi: int = 120) -> Path:
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt

    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png", bbox_inches="tight")
    finally:
        plt.close(fig)
    return Path(path)


# --------------------------------------------------------------------------- checksums
def sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()

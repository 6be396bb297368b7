"""CSV logs of the chamber ([Embedded] §3): ``load_log(path, model) -> Trajectory``.

Format: a header line, then one row per sample (comma separated)::

    time_s,y,u1,u2[,t_out][,mode]

``time_s`` seconds (strictly increasing, uniform step: a step more than 1.5x the median step is a
gap), ``y`` indoor temperature (degC), ``u1`` heater %, ``u2`` fan %, optional ``t_out`` outdoor
temperature (required by ``thermal_outdoor``) and ``mode`` (1 heating, 0 cooling; if absent the
thermal models derive it as u1 >= 50 %). Which columns are required depends on the model: always
``time_s`` and ``y`` (or ``y1..y<n_y>``), plus the model's ``log_columns`` (default ``u1..u<n_u>``).
Every problem raises :class:`pfbench.errors.DataError` with one line naming the file line.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..models.base import StateSpaceModel, Trajectory

GAP_FACTOR = 1.5


def _required(model: StateSpaceModel | None) -> tuple[str, ...]:
    if model is None:
        return ("time_s", "y")
    ys = ("y",) if model.n_y == 1 else tuple(f"y{i + 1}" for i in range(model.n_y))
    return ("time_s",) + ys + _input_columns(model)


def _input_columns(model: StateSpaceModel) -> tuple[str, ...]:
    """The log columns of the model's inputs: its ``log_columns``, by default ``u1..u<n_u>``."""
    us = getattr(model, "log_columns", None)
    return tuple(f"u{i + 1}" for i in range(model.n_u)) if us is None else tuple(us)


def _text(path: Path) -> str:
    """The log's text: UTF-8 (a leading byte-order mark, as spreadsheet programs write, is
    dropped); any other encoding is a DataError naming the file, the line and the byte."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataError(f"{path}: cannot read log: {exc.strerror or exc}") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise DataError(f"{path}:{line}: not UTF-8 text (byte 0x{raw[exc.start]:02x}); "
                        "save the log as UTF-8 CSV") from None


def read_log(path, required=("time_s", "y", "u1", "u2"), max_rows: int | None = None) -> dict[str, np.ndarray]:
    """Read and validate a log; returns {column: float64 array} for every column in the header,
    of its first ``max_rows`` data rows (None: all). The rows after them are not parsed into
    numbers nor checked (the file is still decoded as UTF-8 as a whole); gaps in time are judged
    against the median step of the rows read.

    Raises DataError (one line, naming the line) for a missing file or column, text that is not
    UTF-8, an empty log, a short row, a non-numeric or non-finite value, non-increasing time or a
    gap in time.
    """
    path = Path(path)
    reader = csv.reader(io.StringIO(_text(path), newline=""))
    header = None
    for row in reader:
        if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#"):
            header = [c.strip() for c in row]
            break
    if header is None:
        raise DataError(f"{path}: empty log (no header line)")
    hline = reader.line_num
    twice = sorted({c for c in header if header.count(c) > 1})
    if "" in header or twice:
        what = "an empty column name (a trailing comma?)" if "" in header else f"column(s) {', '.join(twice)} twice"
        raise DataError(f"{path}:{hline}: the header has {what}")
    missing = [c for c in required if c not in header]
    if missing:
        raise DataError(f"{path}:{hline}: missing column(s) {', '.join(missing)} in header "
                        f"(have: {', '.join(header)})")
    data: list[list[float]] = []
    lines: list[int] = []
    for row in reader:
        if max_rows is not None and len(data) >= max_rows:
            break
        if not row or not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue
        line = reader.line_num
        if len(row) != len(header):
            raise DataError(f"{path}:{line}: expected {len(header)} values, got {len(row)}")
        vals = []
        for name, cell in zip(header, row):
            try:
                v = float(cell)
            except ValueError:
                raise DataError(f"{path}:{line}: non-numeric value {cell.strip()!r} in column "
                                f"{name!r}") from None
            if not math.isfinite(v):
                raise DataError(f"{path}:{line}: non-finite value {cell.strip()!r} in column {name!r}")
            vals.append(v)
        data.append(vals)
        lines.append(line)
    if not data:
        raise DataError(f"{path}: log has a header but no data rows")
    arr = np.array(data, dtype=np.float64)
    cols = {name: np.ascontiguousarray(arr[:, i]) for i, name in enumerate(header)}
    if "time_s" in cols and len(arr) > 1:
        t = cols["time_s"]
        dt = np.diff(t)
        bad = np.flatnonzero(dt <= 0)
        if bad.size:
            i = bad[0] + 1
            raise DataError(f"{path}:{lines[i]}: time not increasing (time_s {t[i]:g} after {t[i - 1]:g})")
        step = float(np.median(dt))
        gaps = np.flatnonzero(dt > GAP_FACTOR * step)
        if gaps.size:
            i = gaps[0] + 1
            raise DataError(f"{path}:{lines[i]}: gap in time ({dt[i - 1]:g} s between time_s "
                            f"{t[i - 1]:g} and {t[i]:g}; sample step {step:g} s)")
    return cols


def load_log(path, model: StateSpaceModel, max_rows: int | None = None) -> Trajectory:
    """Load a chamber log for ``model``, its first ``max_rows`` data rows (None: all): validated (y, u)
    and NaN true states.

    Models may define ``log_arrays(cols) -> (y, u)`` (e.g. thermal_outdoor uses y - t_out) and
    ``init_from_log(cols)`` (the thermal models initialise the PF from the first measurement
    y(0), [Embedded] §4.2) -- note this sets the model's y0 in place.
    """
    cols = read_log(path, required=_required(model), max_rows=max_rows)
    if hasattr(model, "log_arrays"):
        y, u = model.log_arrays(cols)
    else:
        yn = ("y",) if model.n_y == 1 else tuple(f"y{i + 1}" for i in range(model.n_y))
        y = np.column_stack([cols[c] for c in yn])
        us = _input_columns(model)
        if len(us) != model.n_u:
            from ..errors import ModelError

            raise ModelError(f"model {getattr(model, 'name', type(model).__name__)!r}: log_columns names {len(us)} "
                             f"column(s) for n_u = {model.n_u} inputs; without log_arrays(cols) each input is one "
                             "column, in order")
        u = np.column_stack([cols[c] for c in us]) if model.n_u else None
    if hasattr(model, "init_from_log"):
        model.init_from_log(cols)
    n = y.shape[0]
    return Trajectory(x=np.full((n, model.n_x), np.nan), y=np.ascontiguousarray(y, dtype=np.float64),
                      u=None if u is None else np.ascontiguousarray(u, dtype=np.float64), x0=None)


def write_log(path, run, decimals: int = 4) -> Path:
    """Write a :class:`pfbench.plants.chamber.ChamberRun` as a log CSV (atomically)."""
    from .. import io

    return io.write_csv(path, run.frame().round(decimals))

"""The sweep store: an append-only, crash-safe journal of finished tasks.

Format (JSON lines, UTF-8)::

    {"pfbench_sweep_store": 1, "spec": {...}, "spec_hash": "..."}            # header
    {"crc": <crc32 of "d" as compact sorted JSON>, "d": {record}}            # one per task
    {"crc": ..., "chunk": {"run": r, "n": k, "wall_s": s, "worker": "..."}}  # per work unit

Records are written in batches (one work unit), each batch one ``write`` followed by
``flush`` + ``fsync``: a crash (Ctrl-C, SIGTERM, power loss, killed worker) loses at most the
tasks in flight. On open, a torn *last* line (no trailing newline, e.g. the process died
inside ``write``) is dropped and truncated away; any other unreadable line, a checksum
mismatch or a missing/foreign header is reported as a corrupt or foreign store with its line.

``X.parquet`` as ``--out``: the journal lives in ``X.parquet.journal`` and the Parquet table
(one row per task, sorted by configuration and run) is written atomically when the sweep is
complete; a Parquet file already there is kept until then (a rerun without the journal finds a
complete export of the same sweep and does nothing). ``.jsonl``: the journal is the store. Other suffixes are refused (:func:`check_store_name`).
"""
from __future__ import annotations

import json
import os
import zlib
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import DataError, InputError
from .core import spec_hash

if TYPE_CHECKING:  # pandas loads when a frame is made: a sweep worker, which only appends, never needs it
    import pandas as pd

MAGIC = "pfbench_sweep_store"
FORMAT = 1


#: the suffixes a store may have (``--out``)
SUFFIXES = (".jsonl", ".parquet")


def check_store_name(out) -> Path:
    """``out`` must end in ``.jsonl`` or ``.parquet`` (an InputError naming --out otherwise)."""
    out = Path(out)
    if out.suffix not in SUFFIXES:
        raise InputError(f"--out {out}: a sweep store must end in .jsonl (the journal) or .parquet "
                         f"(table + journal), not {out.suffix or 'no suffix'!r}")
    return out


def journal_path(out) -> Path:
    out = Path(out)
    return out.with_name(out.name + ".journal") if out.suffix == ".parquet" else out


def _dumps(obj) -> str:
    """Strict JSON (non-finite numbers as null + a note, :func:`pfbench.io.strict`) for journal lines."""
    from ..io import to_json

    return to_json(obj, sort_keys=True, separators=(",", ":"))


def _crc(payload) -> int:
    return zlib.crc32(_dumps(payload).encode())


def _line(kind: str, payload) -> str:
    return _dumps({"crc": _crc(payload), kind: payload}) + "\n"


class Store:
    """An open journal: ``records`` (key -> record) and ``chunks`` (wall-time entries)."""

    def __init__(self, path: Path, spec: dict, records: dict, chunks: list):
        self.path, self.spec, self.records, self.chunks = path, spec, records, chunks
        self._fh = None

    # ----- opening ---------------------------------------------------------------------
    @classmethod
    def read(cls, path, *, repair: bool = False) -> "Store":
        """Read a store; ``repair`` truncates a torn last line (only when resuming)."""
        path = Path(path)
        if path.suffix == ".parquet" and not path.is_file() and journal_path(path).is_file():
            path = journal_path(path)
        if path.is_dir():
            raise InputError(f"sweep store {path} is a folder: give the store's file (X.parquet or X.jsonl)")
        if not path.is_file():
            raise InputError(f"sweep store {path} does not exist")
        raw = path.read_bytes()
        if not raw:
            raise DataError(f"{path} is empty: not a pfbench sweep store")
        lines = raw.split(b"\n")
        torn = lines[-1] != b""  # the file does not end in a newline
        body = lines[:-1]
        try:
            header = json.loads(lines[0])
        except (ValueError, UnicodeDecodeError):
            header = None
        if not isinstance(header, dict) or header.get(MAGIC) != FORMAT or "spec" not in header:
            raise DataError(f"{path} is not a pfbench sweep store (no store header on line 1)")
        spec = header["spec"]
        if header.get("spec_hash") != spec_hash(spec):
            raise DataError(f"{path}: corrupt store header (spec checksum mismatch)")
        if torn and len(lines) == 1:
            raise DataError(f"{path}: corrupt store (header line is incomplete)")
        records, chunks = {}, []
        for no, ln in enumerate(body[1:], start=2):
            try:
                obj = json.loads(ln)
                kind = "d" if "d" in obj else "chunk"
                payload = obj[kind]
                ok = obj["crc"] == _crc(payload)
            except (ValueError, KeyError, TypeError, UnicodeDecodeError):
                ok = False
            if not ok:
                raise DataError(f"{path}: corrupt store at line {no} (unreadable record or "
                                "checksum mismatch); move it away and re-run the sweep")
            if kind == "d":
                records[payload["key"]] = payload
            else:
                chunks.append(payload)
        if torn and repair:  # a crash inside write(): drop the partial line
            with open(path, "r+b") as fh:
                fh.truncate(len(raw) - len(lines[-1]))
                fh.flush()
                os.fsync(fh.fileno())
        return cls(path, spec, records, chunks)

    @classmethod
    def open(cls, out, spec: dict, *, overwrite: bool = False) -> "Store":
        """Create the journal for ``spec`` or reopen it to resume (specs must match)."""
        path = journal_path(out)
        if path.exists() and not overwrite:
            st = cls.read(path, repair=True)
            if spec_hash(st.spec) != spec_hash(spec):
                diff = sorted(k for k in set(spec) | set(st.spec) if spec.get(k) != st.spec.get(k))
                what = "comparison" if spec.get("kind") == "compare" else "sweep"
                raise InputError(f"{path} holds a different {what} (differs in: {', '.join(diff)}); "
                                 "use another --out or --overwrite")
            return st
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(_dumps({MAGIC: FORMAT, "spec": spec, "spec_hash": spec_hash(spec)}) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)  # a Parquet export already at ``out`` stays until its replacement is complete
        return cls(path, spec, {}, [])

    # ----- appending -------------------------------------------------------------------
    def append(self, records: list[dict], chunk: dict | None = None) -> None:
        """Durably append a batch of finished tasks (one write + fsync)."""
        text = "".join(_line("d", r) for r in records)
        if chunk is not None:
            text += _line("chunk", chunk)
        try:
            if self._fh is None:
                self._fh = open(self.path, "a", encoding="utf-8")
            self._fh.write(text)
            self._fh.flush()
            os.fsync(self._fh.fileno())
        except OSError as exc:  # e.g. the disk filled up: the records before this batch are kept
            from ..resources import path_error

            self._abandon()
            raise path_error(exc, self.path, "--out") from None
        for r in records:
            self.records[r["key"]] = r
        if chunk is not None:
            self.chunks.append(chunk)

    def _abandon(self) -> None:
        """Close the journal after a failed write. Closing flushes what is still buffered and may fail
        the same way; the batch is lost either way, and a partial last line is dropped on resume."""
        fh, self._fh = self._fh, None
        if fh is not None:
            try:
                fh.close()
            except OSError:
                pass

    def close(self) -> None:
        """Close the journal; an OSError (e.g. a full disk) is a DataError naming it."""
        fh, self._fh = self._fh, None
        if fh is not None:
            try:
                fh.close()
            except OSError as exc:
                from ..resources import path_error

                raise path_error(exc, self.path, "--out") from None

    # ----- views -----------------------------------------------------------------------
    def frame(self) -> pd.DataFrame:
        """One row per finished task, sorted by (config, run); ``model`` is the full model spec
        (:func:`~pfbench.sweep.core.model_label`, e.g. ``ob3:v4``), ``estimate`` the one the task
        ran with (:func:`~pfbench.sweep.core.estimate_for`: ``pre`` for a store written before the
        option existed)."""
        import pandas as pd

        from .core import estimate_for, model_label

        cols = ["config", "run", "method", "n_particles", "n_filters", "armse", "elapsed_s"]
        if not self.records:
            return pd.DataFrame(columns=["model"] + cols[:5] + ["estimate"] + cols[5:])
        label = model_label(self.spec)
        rows = []
        for r in self.records.values():
            row = {"model": label, **{k: r[k] for k in cols[:5]}}
            row["estimate"] = estimate_for(self.spec, r["method"])
            row.update({k: r[k] for k in cols[5:]})
            for k in ("loglik", "invalid_loglik", "seed", "seed_key"):  # older stores lack them
                row[k] = r.get(k)
            for j, v in enumerate(r["rmse"]):
                row[f"rmse_{j + 1}"] = v
            rows.append(row)
        return pd.DataFrame(rows).sort_values(["config", "run"]).reset_index(drop=True)

    @property
    def complete(self) -> bool:
        return len(self.records) >= len(self.spec["configs"]) * self.spec["runs"]


def load_frame(path) -> tuple[pd.DataFrame, dict, list]:
    """(tasks frame, spec, chunk entries) of a store given as journal or Parquet export."""
    path = Path(path)
    if path.suffix == ".parquet" and path.is_file():
        import pyarrow.parquet as pq

        try:
            table = pq.read_table(path)
        except Exception as exc:  # noqa: BLE001 - pyarrow raises several types
            raise DataError(f"{path} is not a readable Parquet file: {exc}") from None
        meta = (table.schema.metadata or {}).get(MAGIC.encode())
        if meta is None:
            raise DataError(f"{path} is not a pfbench sweep store (no sweep metadata)")
        info = json.loads(meta)
        frame = table.to_pandas()
        if "model" not in frame.columns:  # exported before rows carried the model spec
            from .core import model_label

            frame.insert(0, "model", model_label(info["spec"]))
        if "estimate" not in frame.columns:  # exported before the option existed
            from .core import estimate_for

            frame.insert(6, "estimate", [estimate_for(info["spec"], m) for m in frame["method"]])
        return frame, info["spec"], info.get("chunks", [])
    st = Store.read(path)
    return st.frame(), st.spec, st.chunks


def finished_export(out, spec: dict, *, overwrite: bool = False) -> bool:
    """Whether the Parquet store ``out``, found without its journal, already holds the complete
    sweep ``spec`` (then there is nothing to do). A Parquet file of another sweep, or one that is
    not a pfbench sweep, is refused (as a journal of another sweep is) unless ``overwrite``; it is
    never removed here: :func:`export_parquet` replaces it when the new sweep is complete, so a
    rerun that is killed loses no finished result."""
    out = Path(out)
    if overwrite or out.suffix != ".parquet" or journal_path(out).exists() or not out.is_file():
        return False
    from .core import n_tasks

    frame, old, _ = load_frame(out)
    if spec_hash(old) == spec_hash(spec):
        return len(frame) >= n_tasks(spec)
    diff = sorted(k for k in set(spec) | set(old) if spec.get(k) != old.get(k))
    raise InputError(f"{out} holds a different sweep (differs in: {', '.join(diff)}); use another --out "
                     "or --overwrite")


def export_parquet(store: Store, out) -> Path:
    """Write the finished sweep as Parquet (atomic), spec and timings in the metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ..io import atomic_path

    table = pa.Table.from_pandas(store.frame(), preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[MAGIC.encode()] = _dumps({"spec": store.spec, "chunks": store.chunks}).encode()
    table = table.replace_schema_metadata(meta)
    with atomic_path(out) as tmp:
        pq.write_table(table, tmp)
    return Path(out)

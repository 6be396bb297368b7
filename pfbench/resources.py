"""Check before you spend: the memory a filter run needs, the memory this process may still use,
and output locations that must be usable before hours of work go into them.

Memory need
-----------
:func:`filter_memory` estimates the bytes of one filter run as ``fixed + per_particle x N_p``
(it is affine in N_p, so the largest N_p that fits follows directly):

* particle state ``N_p x n_x x itemsize`` (the ``dtype``) plus the kernel scratch per particle --
  the resampling copy of the state, the log-weights, weights, cdf, ancestor index and first-stage
  likelihoods (``run_groups`` and the particle kernels), the ``N_p x n_noise`` standard normals of
  a step, and :data:`TEMPORARIES` full-size float64 temporaries of the model's vectorised
  ``transition``/``log_likelihood`` (twice as many on the NumPy backend, which also keeps its
  own copies);
* ``store_particles``: ``M x N_p x (n_x x itemsize + 8)`` (every step's particles and weights);
* the marginalized PF: nothing per particle when every state is linear (one copy runs); else per particle the nonlinear state, the Kalman means and covariances
  (``d_l`` and ``d_l x d_l``, current and resampled copies) and the batched ``A P A^T``/innovation
  matrices of a step ([Schon2005] eqs. 6-9);
* the guided filter: the particle terms plus the proposal noise and the proposed state;
* fixed: the per-step outputs (N_f x M x n_x estimates and variances, ESS, increments, flags).

It errs on the high side (temporaries are counted as if they all lived at once) and ignores the
interpreter and the compiled kernels, which :func:`memory_limits` counts as already in use.

Memory this process may use
---------------------------
:func:`memory_limits` lists every limit that applies, as bytes still free: the address-space
limit (``RLIMIT_AS`` minus the current ``VmSize``; per process, so each worker has its own), the
cgroup limit (v2 ``memory.max - memory.current`` or v1 ``memory.limit_in_bytes -
memory.usage_in_bytes``) and ``MemAvailable`` of ``/proc/meminfo`` (both shared by all workers).
:func:`check_memory` refuses a run that does not fit in :data:`USABLE_FRACTION` of the tightest
one with an :class:`~pfbench.errors.InputError` giving both numbers and the largest N_p that
fits, as ``pfbench mcu estimate`` does for a microcontroller.
"""
from __future__ import annotations

import errno
import os
import re
import resource
from dataclasses import dataclass
from pathlib import Path

from .errors import DataError, InputError

#: full-size float64 temporaries per particle and state/measurement component assumed for the
#: model's vectorised functions (numba backend; the NumPy backend counts twice as many)
TEMPORARIES = 4
#: the share of the free memory a run may plan to use (the rest is headroom for the interpreter,
#: compiled code and allocator slack)
USABLE_FRACTION = 0.8
_NO_LIMIT = 1 << 60


@dataclass(frozen=True)
class MemoryNeed:
    """``fixed + per_particle * N_p`` bytes."""

    fixed: int
    per_particle: int

    def bytes(self, n_particles: int) -> int:
        return int(self.fixed + self.per_particle * int(n_particles))

    def largest(self, budget: int) -> int:
        """The largest N_p whose need fits in ``budget`` bytes (0 if none)."""
        return max(0, int((budget - self.fixed) // max(self.per_particle, 1)))


@dataclass(frozen=True)
class Limit:
    """``free`` bytes this process may still allocate under one limit."""

    free: int
    source: str
    per_process: bool  # True: each worker process has this much; False: all workers share it


def filter_memory(model, method: str, *, n_filters: int = 1, n_steps: int = 1, dtype: str = "float64",
                  backend: str = "numba", store_particles: bool = False) -> MemoryNeed:
    """The memory of one :func:`pfbench.run_filter` call (see the module docstring)."""
    from .methods import Method

    fam = Method.parse(method).family
    n_x, n_y = int(model.n_x), int(getattr(model, "n_y", 1))
    n_noise = int(getattr(model, "n_noise", n_x) or 0)
    item = 4 if dtype == "float32" else 8
    temps = TEMPORARIES * (2 if backend == "numpy" else 1)
    M, F = max(int(n_steps), 1), max(int(n_filters), 1)
    fixed = F * M * (2 * n_x * 8 + 2 * 8 + 2) * 2 + 8 * M * (n_x + n_y) * 4 + (1 << 20)
    if fam == "kalman":
        return MemoryNeed(fixed + 8 * M * n_x * n_x * 4, 0)
    if backend == "cupy":  # on the host only the initial particles (the GPU memory is checked there)
        return MemoryNeed(int(fixed), n_x * (item + 8))
    per = 2 * n_x * item + 5 * 8 + 8 * n_noise + temps * 8 * (n_x + n_y)
    if store_particles:
        per += M * (n_x * item + 8)
    if fam == "mpf":
        from .models.contract import linear_indices

        d_l = 0 if getattr(model, "linear_states", None) is None else linear_indices(model).size
        d_n = n_x - d_l
        if d_n == 0:  # every state linear: one copy whatever N_p (run_mpf)
            return MemoryNeed(int(fixed + per + 8 * M * n_x * n_x * 4), 0)
        per += 8 * (2 * d_n + 2 * d_l + 2 * d_l * d_l + temps * (d_l * d_l + n_y * n_y + n_y * d_l + d_n * d_l))
    elif fam == "guided":
        n_prop = int(getattr(model, "n_proposal_noise", None) or n_noise)
        per += n_x * item + 8 * n_prop
    return MemoryNeed(int(fixed), int(per))


# --------------------------------------------------------------------------- what may be used
def _read_int(path) -> int | None:
    try:
        text = Path(path).read_text().strip()
    except OSError:
        return None
    if text == "max":
        return None
    try:
        return int(text)
    except ValueError:
        return None


def _vm_size() -> int:
    try:
        m = re.search(r"VmSize:\s+(\d+)\s*kB", Path("/proc/self/status").read_text())
    except OSError:
        return 0
    return int(m.group(1)) * 1024 if m else 0


def _cgroup_limit() -> Limit | None:
    """The tightest cgroup memory limit of this process (v2, else v1) as free bytes."""
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
    except OSError:
        return None
    best = None
    for ln in lines:
        parts = ln.split(":", 2)
        if len(parts) != 3:
            continue
        _, ctrl, rel = parts
        rel = rel.lstrip("/")
        if ctrl == "":
            cands = [(Path("/sys/fs/cgroup") / rel, "memory.max", "memory.current", "cgroup memory.max")]
        elif "memory" in ctrl.split(","):
            cands = [(Path("/sys/fs/cgroup/memory") / rel, "memory.limit_in_bytes",
                      "memory.usage_in_bytes", "cgroup memory.limit_in_bytes")]
        else:
            continue
        for base, lim_name, use_name, label in cands:
            # the process's own cgroup and (inside a container, where that is the root) the mount
            for d in dict.fromkeys((base, base.parents[len(Path(rel).parts) - 1] if rel else base)):
                lim = _read_int(d / lim_name)
                if lim is None or lim >= _NO_LIMIT:
                    continue
                used = _read_int(d / use_name) or 0
                cand = Limit(max(lim - used, 0), f"{label} {fmt_bytes(lim)}, {fmt_bytes(used)} in use", False)
                if best is None or cand.free < best.free:
                    best = cand
    return best


def memory_limits() -> list[Limit]:
    """Every memory limit that applies to this process, as bytes it may still allocate."""
    out = []
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft not in (resource.RLIM_INFINITY, -1) and soft < _NO_LIMIT:
        used = _vm_size()
        out.append(Limit(max(soft - used, 0), f"address-space limit RLIMIT_AS {fmt_bytes(soft)}, "
                                              f"{fmt_bytes(used)} in use", True))
    cg = _cgroup_limit()
    if cg is not None:
        out.append(cg)
    try:
        m = re.search(r"MemAvailable:\s+(\d+)\s*kB", Path("/proc/meminfo").read_text())
    except OSError:
        m = None
    if m:
        out.append(Limit(int(m.group(1)) * 1024, "MemAvailable in /proc/meminfo", False))
    return out


def fmt_bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} PiB"  # pragma: no cover


def check_memory(need: MemoryNeed, n_particles: int, *, what: str, flag: str = "--particles",
                 processes: int = 1, limits: list[Limit] | None = None) -> None:
    """Refuse (InputError) if ``need`` at ``n_particles`` does not fit the tightest limit.

    ``processes`` workers each need ``need``: a per-process limit is compared with one worker's
    need, a shared one with all of theirs. The message gives the need, what is free (and under
    which limit) and the largest N_p that fits.
    """
    limits = memory_limits() if limits is None else limits
    processes = max(int(processes), 1)
    per_proc = need.bytes(n_particles)
    for lim in sorted(limits, key=lambda L: L.free / (1 if L.per_process else processes)):
        share = int(lim.free * USABLE_FRACTION) // (1 if lim.per_process else processes)
        if per_proc <= share:
            continue
        workers = "" if lim.per_process or processes == 1 else f" per worker x {processes} workers"
        biggest = need.largest(share)
        fits = (f"the largest N_p that fits is {biggest}" if biggest >= 1 else
                f"not even N_p = 1 fits: what does not grow with N_p (outputs per step, per filter) needs "
                f"{fmt_bytes(need.bytes(0))}, so fewer steps or filters")
        hint = " (or use fewer --workers)" if workers else ""
        raise InputError(f"{flag} {n_particles}: {what} needs about {fmt_bytes(per_proc)}{workers} but "
                         f"only {fmt_bytes(lim.free)} is free ({lim.source}; a run may plan on "
                         f"{USABLE_FRACTION:.0%} of it); {fits}{hint}")


def check_filter_memory(model, method: str, n_particles: int, *, n_filters: int = 1, n_steps: int = 1,
                        dtype: str = "float64", backend: str = "numba", store_particles: bool = False,
                        flag: str = "--particles", processes: int = 1) -> MemoryNeed:
    """:func:`filter_memory` + :func:`check_memory` for one run; returns the need."""
    from .methods import Method

    need = filter_memory(model, method, n_filters=n_filters, n_steps=n_steps, dtype=dtype,
                         backend=backend, store_particles=store_particles)
    check_memory(need, n_particles, what=f"{Method.parse(method).label} on {getattr(model, 'name', 'the model')} "
                 f"({n_steps} steps)", flag=flag, processes=processes)
    return need


# --------------------------------------------------------------------------- output locations
#: errno values that mean "this path cannot be used" (the user's or the system's doing, not a bug)
PATH_ERRNOS = frozenset({errno.EROFS, errno.EACCES, errno.EPERM, errno.ENOSPC, errno.EDQUOT,
                         errno.ENOTDIR, errno.EISDIR, errno.ENOENT, errno.EEXIST,
                         errno.ENAMETOOLONG, errno.ELOOP, errno.EFBIG, errno.EMFILE, errno.ENFILE,
                         errno.ETXTBSY, errno.EBUSY, errno.EIO})

_ADVICE = {errno.EROFS: "the file system is read-only; choose another {flag}",
           errno.EACCES: "no permission; choose another {flag} or fix the permissions",
           errno.EPERM: "not permitted; choose another {flag} or fix the permissions",
           errno.ENOSPC: "the disk is full; free space or choose another {flag}",
           errno.EDQUOT: "the disk quota is exhausted; free space or choose another {flag}",
           errno.ENOTDIR: "a part of the path is a file, not a directory; choose another {flag}",
           errno.EISDIR: "it is a directory; give a file name as {flag}",
           errno.ENAMETOOLONG: "the name is too long; choose another {flag}",
           errno.EEXIST: "a file is where a directory of the path should be; choose another {flag}",
           errno.ENOENT: "no such file or directory, or a directory that takes no new files; "
                         "choose another {flag}"}


def os_error_message(exc: OSError, path=None, flag: str = "the path") -> str:
    """One line for an OSError on a user-named path: the path, the reason, what to do."""
    path = path if path is not None else exc.filename
    reason = exc.strerror or str(exc)
    if exc.filename is not None and os.fsdecode(exc.filename) != os.fsdecode(path):
        reason = f"{os.fsdecode(exc.filename)}: {reason}"
    advice = _ADVICE.get(exc.errno, "check the path or choose another {flag}").format(flag=flag)
    return f"cannot use {path}: {reason}; {advice}"


def path_error(exc: OSError, path=None, flag: str = "the path") -> DataError:
    """The :class:`~pfbench.errors.DataError` for an OSError on a user-named path."""
    return DataError(os_error_message(exc, path, flag))


def check_writable(path, flag: str = "--out", *, directory: bool = False) -> Path:
    """Make sure ``path`` (a file to write, or a ``directory``) can be written, before any work.

    Creates the missing parent directories and a probe file beside ``path`` (removed again);
    an OSError becomes a :class:`~pfbench.errors.DataError` naming the path and what to do.
    """
    import tempfile

    path = Path(path)
    where = path if directory else path.parent
    try:
        if not directory and path.is_dir():
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
        where.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise path_error(exc, path, flag) from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".pfbench-probe-", dir=where)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:  # the directory exists but takes no new file (name the directory)
        raise path_error(OSError(exc.errno, exc.strerror, str(where)), path, flag) from None
    return path


__all__ = ["MemoryNeed", "Limit", "filter_memory", "memory_limits", "check_memory", "check_filter_memory",
           "fmt_bytes", "check_writable", "path_error", "os_error_message", "PATH_ERRNOS"]

"""The C reference: the project's own Ob1 bootstrap filter (``pfbench/mcu/c/pf_ob1.c``,
[Embedded] Alg. 1 with systematic resampling) built for this host and timed beside the engine.

``pfbench/mcu/c/host_bench.c`` includes ``pf_ob1.c`` unchanged (the filter functions of the
microcontroller build), simulates y(1..M) first and then times the filter loop alone; see its
header for the command line. Two variants differ only in the random number generator:

* ``libc``: pf_ob1.c's own: libc ``rand()`` and Box-Muller with one normal per two uniforms
  (log + sqrt + cos per draw), as on the microcontroller;
* ``fast``: xoshiro256++ and the 256-layer ziggurat (the normal method NumPy uses), so that a
  slow C library generator does not flatter the engine. Ratio targets use the faster of the two.

Builds use the system C compiler (``$CC``, else ``cc``, else ``gcc``) at ``-O3 -march=native`` and
are cached under ``$PFBENCH_CACHE_DIR/c/`` with a hash of the sources, the flags and the
compiler's version in the file name, so an edit or a new compiler rebuilds.
"""
from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import statistics
import subprocess
import tempfile

import numpy as np

from ..backends.cache import cache_root
from ..mcu.toolchain import C_DIR

SOURCES = ("host_bench.c", "pf_ob1.c", "pf_common.h", "pf_model.h")
FLAGS = ("-O3", "-march=native")
#: largest N_p the host build accepts (static arrays of pf_ob1.c: 3 x 8 bytes per particle,
#: only the pages a run touches are ever allocated)
NMAX = 10_000_000
VARIANTS = {"libc": (), "fast": ("-DPF_FAST_RNG",)}
#: what each variant's random numbers are (also printed by the harness itself)
RNG = {"libc": "libc rand() + Box-Muller (1 normal per 2 uniforms)",
       "fast": "xoshiro256++ + ziggurat (256 layers)"}


class CUnavailable(Exception):
    """The C reference cannot run here; ``str(exc)`` is the one-line note for the output."""


def compiler() -> list[str] | None:
    """The C compiler command: ``$CC`` (may carry flags), else ``cc``, else ``gcc``; None if none."""
    cc = os.environ.get("CC", "").strip()
    if cc:
        argv = shlex.split(cc)
        return argv if shutil.which(argv[0]) else None
    for name in ("cc", "gcc"):
        path = shutil.which(name)
        if path:
            return [path]
    return None


def _version(cc: list[str]) -> str:
    try:
        r = subprocess.run([*cc, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CUnavailable(f"not run: C compiler {cc[0]} does not start ({exc})") from None
    return (r.stdout or r.stderr).strip().splitlines()[0] if (r.stdout or r.stderr).strip() else "?"


def _first_error(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    for ln in lines:
        if "error" in ln.lower():
            return ln
    return lines[-1] if lines else "no message"


def build(variant: str) -> dict:
    """Build (or find in the cache) the host harness ``variant``; returns its description
    ``{"variant", "path", "rng", "compiler", "flags"}``. Raises :class:`CUnavailable`."""
    cc = compiler()
    if cc is None:
        raise CUnavailable("not run: no C compiler (set $CC or install cc/gcc)")
    version = _version(cc)
    flags = [*FLAGS, f"-DPF_NMAX={NMAX}", *VARIANTS[variant]]
    h = hashlib.sha256()
    for name in SOURCES:
        h.update(name.encode() + b"\0" + (C_DIR / name).read_bytes() + b"\0")
    h.update("\0".join([*cc, version, *flags]).encode())
    out_dir = cache_root() / "c"
    exe = out_dir / f"host_bench-{variant}-{h.hexdigest()[:16]}"
    info = {"variant": variant, "path": str(exe), "rng": RNG[variant], "compiler": version,
            "flags": " ".join(flags)}
    if exe.is_file() and os.access(exe, os.X_OK):
        return info
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=exe.name + ".", suffix=".tmp", dir=out_dir)
        os.close(fd)
    except OSError as exc:
        raise CUnavailable(f"not run: cannot write the C build to {out_dir} ({exc.strerror})") from None
    try:
        cmd = [*cc, *flags, "-I", str(C_DIR), "-o", tmp, str(C_DIR / "host_bench.c"), "-lm"]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        except (OSError, subprocess.SubprocessError) as exc:
            raise CUnavailable(f"not run: C compiler failed ({exc})") from None
        if r.returncode != 0:
            raise CUnavailable(f"not run: C compiler failed: {_first_error(r.stderr or r.stdout)}")
        os.chmod(tmp, 0o755)
        os.replace(tmp, exe)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return info


def _run(exe: str, args: list[str], timeout: float) -> subprocess.CompletedProcess:
    try:
        r = subprocess.run([exe, *args], capture_output=True, timeout=timeout)
    except (OSError, subprocess.SubprocessError) as exc:
        raise CUnavailable(f"not run: the C harness did not run ({exc})") from None
    if r.returncode != 0:
        raise CUnavailable(f"not run: the C harness failed: {_first_error(r.stderr.decode(errors='replace'))}")
    return r


def filter_ns(variant: str, m: int, n: int, repeats: int, seed: int = 1) -> dict:
    """Time the C filter at (M, N_p): ``{"ns_per_particle_step"`` (median of ``repeats``),
    ``"ns_repeats", "sse", "rng", ...}`` (the build's description too). Raises CUnavailable."""
    if n > NMAX:
        raise CUnavailable(f"not run: N_p = {n} exceeds the host build's {NMAX}")
    info = build(variant)
    r = _run(info["path"], ["filter", str(int(m)), str(int(n)), str(max(int(repeats), 1)), str(int(seed))],
             timeout=3600)
    from ..io import loads

    out = loads(r.stdout.decode().strip().splitlines()[-1], "the C harness output")
    ns = [float(v) for v in out["ns_per_particle_step"]]
    return {**info, "steps": int(m), "particles": int(n), "ns_per_particle_step": statistics.median(ns),
            "ns_repeats": ns, "sse": float(out["sse"]), "sum_x2": float(out["sum_x2"])}


def normals(count: int, seed: int = 1, variant: str = "fast") -> np.ndarray:
    """``count`` standard-normal draws of the harness's generator (for its tests)."""
    info = build(variant)
    r = _run(info["path"], ["normals", str(int(count)), str(int(seed))], timeout=600)
    return np.frombuffer(r.stdout, dtype=np.float64)


def memory_bytes(m: int, n: int) -> int:
    """What one C run touches: three particle arrays and the simulated x, y."""
    return 3 * 8 * int(n) + 2 * 8 * (int(m) + 1)

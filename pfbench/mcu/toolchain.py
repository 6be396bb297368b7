"""Cross-compile the C bootstrap filter (``pfbench/mcu/c/``) for a bare-metal Cortex-M4(F).

Two builds mirror [Embedded], Table 2 (§5.1):

* ``double`` = D(S): double everywhere, plain C library calls, no FPU, ``-O0`` (a "standard"
  IDE debug build; every double operation is a libgcc soft-float call);
* ``float``  = D(O): float only, f-suffixed literals, cosf/logf/sqrtf/expf/powf,
  ``-mfpu=fpv4-sp-d16 -mfloat-abi=hard -Ofast``.

Toolchain: Debian's ``gcc-arm-none-eabi`` + ``libnewlib-arm-none-eabi`` (``make mcu-tools``).
Builds are cached on disk under ``$PFBENCH_CACHE_DIR/mcu/<key>/`` where the key hashes the
sources, the flags and the compiler version, so a second call costs only the hash.
"""
from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError, PfbenchError

C_DIR = Path(__file__).resolve().parent / "c"
SOURCES = ("pf_ob1.c", "startup.c")
LINKER_SCRIPT = "stm32f407.ld"
GCC = "arm-none-eabi-gcc"

_COMMON = ["-mcpu=cortex-m4", "-mthumb", "-g", "-ffunction-sections", "-nostartfiles",
           "-specs=nano.specs", "-specs=nosys.specs"]

#: precision -> (Table 2 label, compiler flags).  ``opt`` replaces the default -O level.
BUILDS = {
    "double": ("D(S)", ["-mfloat-abi=soft"], "-O0"),
    "float": ("D(O)", ["-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-DPF_FLOAT"], "-Ofast"),
}


@dataclass(frozen=True)
class Build:
    """A cached cross-compiled image."""

    precision: str
    label: str
    elf: Path
    bin: Path          # flash image (objcopy -O binary, LMA order, starts at 0x08000000)
    disasm: Path       # arm-none-eabi-objdump -d
    symbols: Path      # arm-none-eabi-nm -n
    user_symbols: Path  # nm of pf_ob1.o: the functions written in our C file
    cflags: tuple


def missing() -> list[str]:
    """Why the toolchain/emulator cannot be used here (empty list when everything is present)."""
    out = []
    tools = [t for t in (GCC, "arm-none-eabi-objdump", "arm-none-eabi-objcopy",
                         "arm-none-eabi-nm") if shutil.which(t) is None]
    if tools:
        out.append(f"{', '.join(tools)} not on PATH (run `make mcu-tools`)")
    if not out:
        lib = _gcc_print("-mcpu=cortex-m4", "-mthumb", "-print-file-name=libc_nano.a")
        if not os.path.isabs(lib) or not os.path.exists(lib):
            out.append("newlib for arm-none-eabi missing (apt-get install libnewlib-arm-none-eabi)")
    try:
        import unicorn  # noqa: F401
    except ImportError:
        out.append("the `unicorn` Python package is missing (pip install unicorn)")
    return out


def available() -> bool:
    """True when the arm-none-eabi toolchain, newlib and the unicorn emulator are all present."""
    return not missing()


def _gcc_print(*args: str) -> str:
    try:
        return subprocess.run([GCC, *args], capture_output=True, text=True, check=True,
                              timeout=60).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


@functools.lru_cache(maxsize=1)
def compiler_version() -> str:
    return _gcc_print("--version").splitlines()[0] if shutil.which(GCC) else "missing"


def cache_root() -> Path:
    base = os.environ.get("PFBENCH_CACHE_DIR") or os.path.join(
        os.path.expanduser("~"), ".cache", "pfbench")
    return Path(base) / "mcu"


def _run(cmd: list[str], cwd: Path, stdout=None) -> None:
    res = subprocess.run(cmd, cwd=cwd, stdout=stdout or subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, timeout=300)
    if res.returncode != 0:
        raise PfbenchError(f"cross-compile failed: {' '.join(cmd[:3])}...: "
                           f"{res.stderr.strip().splitlines()[-1] if res.stderr.strip() else ''}")


def build(precision: str = "float", opt: str | None = None, force: bool = False) -> Build:
    """Build (or fetch from the cache) the D(S) (``double``) or D(O) (``float``) image."""
    if precision not in BUILDS:
        raise InputError(f"precision must be one of {sorted(BUILDS)}, got {precision!r}")
    why = [m for m in missing() if "unicorn" not in m]
    if why:
        raise PfbenchError("; ".join(why))
    label, flags, default_opt = BUILDS[precision]
    cflags = tuple(_COMMON + flags + [opt or default_opt])
    h = hashlib.sha256()
    for name in (*SOURCES, LINKER_SCRIPT):
        h.update(name.encode() + b"\0" + (C_DIR / name).read_bytes())
    h.update("\0".join(cflags).encode() + compiler_version().encode())
    out = cache_root() / f"{precision}-{h.hexdigest()[:16]}"
    files = dict(elf=out / "pf_ob1.elf", bin=out / "pf_ob1.bin", disasm=out / "pf_ob1.dis",
                 symbols=out / "pf_ob1.nm", user_symbols=out / "pf_ob1_user.nm")
    if force or not all(p.exists() for p in files.values()):
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=out.name + ".", dir=out.parent))
        try:
            srcs = [str(C_DIR / s) for s in SOURCES]
            _run([GCC, *cflags, "-T", str(C_DIR / LINKER_SCRIPT), *srcs, "-lm",
                  "-o", "pf_ob1.elf"], tmp)
            _run([GCC, *cflags, "-c", str(C_DIR / "pf_ob1.c"), "-o", "pf_ob1.o"], tmp)
            _run(["arm-none-eabi-objcopy", "-O", "binary", "pf_ob1.elf", "pf_ob1.bin"], tmp)
            with open(tmp / "pf_ob1.dis", "w") as f:
                _run(["arm-none-eabi-objdump", "-d", "pf_ob1.elf"], tmp, stdout=f)
            with open(tmp / "pf_ob1.nm", "w") as f:
                _run(["arm-none-eabi-nm", "-n", "-S", "pf_ob1.elf"], tmp, stdout=f)
            with open(tmp / "pf_ob1_user.nm", "w") as f:
                _run(["arm-none-eabi-nm", "pf_ob1.o"], tmp, stdout=f)
            if force and out.exists():
                shutil.rmtree(out, ignore_errors=True)
            try:
                os.replace(tmp, out)
            except OSError:  # another process finished the same build first: use theirs
                if not all(p.exists() for p in files.values()):
                    raise
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
    return Build(precision=precision, label=label, cflags=cflags, **files)

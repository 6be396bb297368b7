"""Cross-compile the C bootstrap filters (``pfbench/mcu/c/``) for a bare-metal Cortex-M4(F).

* :func:`build`: the hand-written Ob1 port ``pf_ob1.c`` ([Embedded] Table 2 benchmark);
* :func:`build_model`: the generic harness ``pf_model.c`` linked with any model's object
  (``pf_model.h`` ABI; the model's own code compiled by :mod:`pfbench.mcu.modelcode`, or a
  hand-written C model via :func:`compile_c_model`).

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
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError, PfbenchError, UnsupportedError

C_DIR = Path(__file__).resolve().parent / "c"
SOURCES = ("pf_ob1.c", "pf_common.h", "pf_model.h")
LINKER_SCRIPT = "stm32f407.ld"
GCC = "arm-none-eabi-gcc"

#: flags of every bare-metal image (startup.c, no host start files, newlib-nano, no syscalls)
BARE_METAL = ["-g", "-ffunction-sections", "-nostartfiles", "-specs=nano.specs", "-specs=nosys.specs"]
_COMMON = ["-mcpu=cortex-m4", "-mthumb", *BARE_METAL]

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
    user_symbols: Path  # nm of our own objects (pf_ob1.o; harness + model object)
    cflags: tuple
    model: str | None = None   # model builds (build_model): the model and its dimensions
    n_x: int = 0
    n_y: int = 0
    n_u: int = 0
    n_noise: int = 0
    nmax: int = 0              # PF_NMAX (pf_ob1: 1000)
    mmax: int = 0              # PF_MMAX (pf_ob1: unlimited, object simulated inside)
    tile: int = 0              # PF_TILE


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
    """Built images and objects: ``mcu`` in pfbench's cache (:func:`pfbench.backends.cache.cache_root`)."""
    from ..backends.cache import cache_root as pfbench_cache

    return pfbench_cache() / "mcu"


def run_tool(cmd: list[str], cwd: Path, stdout=None) -> None:
    res = subprocess.run(cmd, cwd=cwd, stdout=stdout or subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, timeout=300)
    if res.returncode != 0:
        lines = res.stderr.strip().splitlines()
        overflow = [line for line in lines if "overflowed by" in line]
        if overflow:  # the user's sizes (--configs, a large model) do not fit the emulated image
            raise InputError(f"the emulated image does not fit the chip's memory ({overflow[0].split(': ')[-1]}): "
                             "emulate fewer particles (--configs) or a smaller model")
        raise PfbenchError(f"cross-compile failed: {' '.join(cmd[:3])}...: {lines[-1] if lines else ''}")


def cache_key(parts) -> str:
    """Hash of (name, bytes or text) pairs + the compiler version: the cache key of a build."""
    h = hashlib.sha256()
    for name, data in parts:
        h.update(str(name).encode() + b"\0" + (data if isinstance(data, bytes) else
                                                str(data).encode()) + b"\0")
    h.update(compiler_version().encode())
    return h.hexdigest()[:16]


def cached(out: Path, names: tuple[str, ...], make, force: bool = False) -> dict:
    """``{name: out/name}``; when any is missing (or ``force``), ``make(tmp)`` builds them in a
    fresh directory that then atomically becomes ``out`` (a concurrent identical build wins)."""
    files = {n: out / n for n in names}
    if force or not all(p.exists() for p in files.values()):
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=out.name + ".", dir=out.parent))
        try:
            make(tmp)
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
    return files


def link(tmp: Path, stem: str, cflags, inputs, user_objects) -> None:
    """Link ``inputs`` (sources/objects) with startup.c and the linker script into
    ``stem.elf``; write ``stem.bin`` (flash image), ``stem.dis`` (objdump -d), ``stem.nm``
    (nm -n -S) and ``stem_user.nm`` (nm of ``user_objects``: the code we wrote or compiled)."""
    run_tool([GCC, *cflags, "-T", str(C_DIR / LINKER_SCRIPT), *map(str, inputs),
              str(C_DIR / "startup.c"), "-lm", "-o", f"{stem}.elf"], tmp)
    run_tool(["arm-none-eabi-objcopy", "-O", "binary", f"{stem}.elf", f"{stem}.bin"], tmp)
    with open(tmp / f"{stem}.dis", "w") as f:
        run_tool(["arm-none-eabi-objdump", "-d", f"{stem}.elf"], tmp, stdout=f)
    with open(tmp / f"{stem}.nm", "w") as f:
        run_tool(["arm-none-eabi-nm", "-n", "-S", f"{stem}.elf"], tmp, stdout=f)
    with open(tmp / f"{stem}_user.nm", "w") as f:
        run_tool(["arm-none-eabi-nm", *map(str, user_objects)], tmp, stdout=f)


def check_tools() -> None:
    """A one-line PfbenchError unless the cross toolchain and newlib are present."""
    why = [m for m in missing() if "unicorn" not in m]
    if why:
        raise PfbenchError("; ".join(why))


def image(prefix: str, key_parts, stem: str, precision: str, label: str, cflags: tuple, make,
          force: bool = False, **fields) -> Build:
    """A linked image, cached under ``cache_root()/<prefix>-<key>``: ``make(tmp)`` compiles into
    ``tmp`` and calls :func:`link` with ``stem``. The key covers ``key_parts`` ((name, bytes)
    of the sources), startup.c, the linker script, ``cflags`` and the compiler; ``fields`` go
    to the :class:`Build`."""
    key = cache_key([*key_parts, *((n, (C_DIR / n).read_bytes()) for n in ("startup.c", LINKER_SCRIPT)),
                     ("cflags", "\0".join(cflags))])
    f = cached(cache_root() / f"{prefix}-{key}",
                tuple(stem + ext for ext in (".elf", ".bin", ".dis", ".nm", "_user.nm")), make, force)
    return Build(precision=precision, label=label, cflags=tuple(cflags), elf=f[f"{stem}.elf"],
                 bin=f[f"{stem}.bin"], disasm=f[f"{stem}.dis"], symbols=f[f"{stem}.nm"],
                 user_symbols=f[f"{stem}_user.nm"], **fields)


def build(precision: str = "float", opt: str | None = None, force: bool = False) -> Build:
    """Build (or fetch from the cache) the D(S) (``double``) or D(O) (``float``) image."""
    if precision not in BUILDS:
        raise InputError(f"precision must be one of {sorted(BUILDS)}, got {precision!r}")
    check_tools()
    label, flags, default_opt = BUILDS[precision]
    cflags = tuple(_COMMON + flags + [opt or default_opt])

    def make(tmp):
        run_tool([GCC, *cflags, "-c", str(C_DIR / "pf_ob1.c"), "-o", "pf_ob1.o"], tmp)
        link(tmp, "pf_ob1", cflags, [C_DIR / "pf_ob1.c"], ["pf_ob1.o"])

    return image(precision, [(n, (C_DIR / n).read_bytes()) for n in SOURCES], "pf_ob1", precision,
                 label, cflags, make, force)


# ------------------------------------------------------------------ any model: pf_model.c
HARNESS = "pf_model.c"
NRT_SHIM = "nrt_shim.c"

#: ABI flags of model builds per target cpu.  Both precisions use the M4F hard-float ABI
#: (-mfpu=fpv4-sp-d16 -mfloat-abi=hard), the ABI the model object is compiled for: floats
#: run on the FPU, doubles are libgcc soft-float calls (__aeabi_dmul ...) and the hard-float
#: newlib's double libm, arguments passed in VFP registers.
#: Other cores: no FPU (M0+, M3) = soft-float ABI; M7 double-precision FPv5, M33 single.
MODEL_ABI = {"cortex-m4": ["-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"],
             "cortex-m0plus": ["-mfloat-abi=soft"], "cortex-m3": ["-mfloat-abi=soft"],
             "cortex-m7": ["-mfpu=fpv5-d16", "-mfloat-abi=hard"],
             "cortex-m33": ["-mfpu=fpv5-sp-d16", "-mfloat-abi=hard"]}
#: -O level of the harness per precision: the same as the Ob1 builds (D(O) -Ofast, D(S) -O0),
#: so a model build and the hand-written port differ only in where the model code comes from.
MODEL_OPT = {"float": "-Ofast", "double": "-O0"}


@dataclass(frozen=True)
class CModel:
    """A model written by hand in C against ``pf_model.h`` (same fields as the compiled
    :class:`pfbench.mcu.modelcode.ModelObject` that :func:`build_model` reads)."""

    model: str
    precision: str
    obj: Path
    n_x: int
    n_y: int
    n_u: int
    n_noise: int
    cpu: str = "cortex-m4"
    defines: tuple = ()
    needs_nrt: bool = False
    double_ops: dict = field(default_factory=dict)


def dims_flags(n_x: int, n_y: int, n_u: int, n_noise: int) -> list[str]:
    """The -D flags that give ``pf_model.h`` a model's dimensions."""
    return [f"-DPFM_NX={int(n_x)}", f"-DPFM_NY={int(n_y)}", f"-DPFM_NU={int(n_u)}",
            f"-DPFM_NNOISE={int(n_noise)}"]


def _dims(mo) -> list[str]:
    return dims_flags(mo.n_x, mo.n_y, mo.n_u, mo.n_noise)


def _model_flags(precision: str, cpu: str, opt: str | None, gcc_flags=None) -> list[str]:
    """Flags of a model build: ``gcc_flags`` (the model object's own -mcpu/-mfloat-abi/-mfpu,
    :attr:`pfbench.mcu.modelcode.ModelObject.gcc_flags`) or else :data:`MODEL_ABI` of
    ``cpu``, then -DPF_FLOAT, the -O level (:data:`MODEL_OPT`) and the include path."""
    if precision not in MODEL_OPT:
        raise InputError(f"precision must be 'float' or 'double', got {precision!r}")
    common = [f for f in _COMMON if not f.startswith("-mcpu=")]
    if gcc_flags:
        abi = list(gcc_flags)
    elif cpu in MODEL_ABI:
        abi = [f"-mcpu={cpu}", "-mthumb", *MODEL_ABI[cpu]]
    else:
        raise UnsupportedError(f"model builds support cpu {sorted(MODEL_ABI)}, not {cpu!r}")
    return abi + common + (["-DPF_FLOAT"] if precision == "float" else []) + [
        opt or MODEL_OPT[precision], f"-I{C_DIR}"]


def compile_c_model(source, precision: str, model: str, n_x: int, n_y: int, n_u: int = 0,
                    n_noise: int = 1, opt: str | None = None, cpu: str = "cortex-m4",
                    defines: tuple = ()) -> CModel:
    """Cross-compile a hand-written C model (``pf_model.h`` ABI) to an object (cached);
    ``defines`` are extra -D flags of the model file (default -O level: -O2)."""
    check_tools()
    source = Path(source).resolve()
    mo = CModel(model=model, precision=precision, obj=Path(), n_x=n_x, n_y=n_y, n_u=n_u,
                n_noise=n_noise, cpu=cpu)
    cflags = tuple(_model_flags(precision, cpu, opt or "-O2") + _dims(mo) + list(defines))
    key = cache_key([(source.name, source.read_bytes()),
                     ("pf_model.h", (C_DIR / "pf_model.h").read_bytes()),
                     ("cflags", "\0".join(cflags))])
    out = cache_root() / f"cmodel-{model}-{precision}-{key}"
    f = cached(out, ("model.o",), lambda tmp: run_tool(
        [GCC, *cflags, "-c", str(source), "-o", "model.o"], tmp))
    return CModel(model=model, precision=precision, obj=f["model.o"], n_x=n_x, n_y=n_y, n_u=n_u,
                  n_noise=n_noise, cpu=cpu)


def build_model(model_object, precision: str | None = None, opt: str | None = None,
                nmax: int = 256, mmax: int = 64, tile: int = 32, force: bool = False) -> Build:
    """Link the generic harness ``pf_model.c`` with a model object into an image (cached).

    ``model_object`` is a :class:`pfbench.mcu.modelcode.ModelObject` (the model's own code
    compiled for the target, any cpu it supports: its ``gcc_flags`` are used) or a
    :class:`CModel`: an ARM object defining ``pfm_transition``
    and ``pfm_log_likelihood`` (``pf_model.h``) plus its dimensions; ``needs_nrt`` links
    ``nrt_shim.c`` (numba's allocation calls over malloc).  ``precision`` defaults to the
    object's.  Flags: :data:`MODEL_ABI` of the object's cpu, -O level :data:`MODEL_OPT`;
    ``nmax``/``mmax`` size the static buffers (PF_NMAX particles, PF_MMAX steps) and ``tile``
    the model calls (PF_TILE particles).  The cache key includes the object's bytes.
    """
    precision = precision or model_object.precision
    if precision != model_object.precision:
        raise InputError(f"the model object was compiled for {model_object.precision}, "
                         f"not {precision}")
    for name, v in (("nmax", nmax), ("mmax", mmax), ("tile", tile)):
        if int(v) < 1:
            raise InputError(f"{name} must be >= 1, got {v}")
    check_tools()
    cpu = getattr(model_object, "cpu", "cortex-m4")
    sizes = [f"-DPF_NMAX={int(nmax)}", f"-DPF_MMAX={int(mmax)}", f"-DPF_TILE={int(tile)}"]
    extra = [d for d in getattr(model_object, "defines", ()) if d not in _dims(model_object)]
    cflags = tuple(_model_flags(precision, cpu, opt, getattr(model_object, "gcc_flags", None))
                   + _dims(model_object) + extra + sizes)
    obj = Path(model_object.obj)
    if not obj.exists():
        raise PfbenchError(f"model object {obj} does not exist")
    srcs = [HARNESS, "pf_common.h", "pf_model.h"]
    nrt = bool(getattr(model_object, "needs_nrt", False))
    if nrt:
        if not (C_DIR / NRT_SHIM).exists():
            raise PfbenchError(f"the model needs numba's runtime but {C_DIR / NRT_SHIM} is missing")
        srcs.append(NRT_SHIM)

    def make(tmp):
        run_tool([GCC, *cflags, "-c", str(C_DIR / HARNESS), "-o", "harness.o"], tmp)
        shutil.copy(obj, tmp / "model.o")
        inputs = ["harness.o", "model.o"] + ([str(C_DIR / NRT_SHIM)] if nrt else [])
        link(tmp, "pf_model", cflags, inputs, ["harness.o", "model.o"])

    return image(f"model-{model_object.model.replace(':', '_')}-{precision}",
                 [*((n, (C_DIR / n).read_bytes()) for n in srcs), ("model.o", obj.read_bytes())],
                 "pf_model", precision, f"{model_object.model} ({precision})", cflags, make, force,
                 model=model_object.model, n_x=int(model_object.n_x), n_y=int(model_object.n_y),
                 n_u=int(model_object.n_u), n_noise=int(model_object.n_noise), nmax=int(nmax),
                 mmax=int(mmax), tile=int(tile))

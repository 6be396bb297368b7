"""``pfbench bench --startup``: time to first result, cold and warm, per method.

Each case runs ``pfbench run --model MODEL --method METHOD --steps 100 --particles 1000 --json`` as
a subprocess and takes its wall time (interpreter start, imports, compilation, simulation and
filtering):

* **cold**: with ``NUMBA_CACHE_DIR`` and ``PFBENCH_CACHE_DIR`` pointing at a fresh, empty
  temporary directory (a first run after installation; Python's own bytecode cache and the
  operating system's file cache are as they are);
* **cold, compiled in one process**: the same with ``PFBENCH_COMPILE_HELPER=0``, each right after
  a cold run (what compiling pass A in a helper process on a second core saves,
  :mod:`pfbench.backends.compile_helper`; the same when the helper is off or one core is usable);
* **warm**: the same command again with the cache that the cold run filled (median of
  ``repeats`` runs).

The temporary directories are removed afterwards. Compiled code is keyed on the whole package
source (:mod:`pfbench.backends.cache`): if the package changes during the measurement the warm
runs recompile, which the result flags (``package_changed``).
"""
from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: (method, model, extra arguments): particle methods on Ob1; mpf on Ob5 (three nonlinear states,
#: one linear-Gaussian: a real marginalized PF); guided on the reduced PMSM model, which declares
#: the optimal proposal; kalman on the linear-Gaussian model
CASES = (("bootstrap", "ob1", ()), ("sir", "ob1", ()), ("sis", "ob1", ()), ("asir", "ob1", ()),
         ("multipdf", "ob1", ("--filters", "2")), ("mpf", "ob5", ()),
         ("guided", "pmsm_reduced", ()), ("kalman", "linear_gaussian", ()))
STEPS, PARTICLES = 100, 1000


def pfbench_command() -> list[str]:
    """The ``pfbench`` console script beside this interpreter, else ``python -m pfbench.cli``."""
    script = Path(sys.executable).with_name("pfbench")
    if script.is_file() and os.access(script, os.X_OK):
        return [str(script)]
    return [sys.executable, "-m", "pfbench.cli"]


def command(method: str, model: str, extra=()) -> list[str]:
    return [*pfbench_command(), "run", "--model", model, "--method", method, "--steps", str(STEPS),
            "--particles", str(PARTICLES), *extra, "--json"]


def _timed(cmd: list[str], cache: Path, helper: bool = True) -> tuple[float, str | None]:
    from ..backends import compile_helper

    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache / "numba"), PFBENCH_CACHE_DIR=str(cache / "pfbench"))
    if not helper:
        env[compile_helper.ENV] = "0"
    t0 = time.perf_counter()
    try:
        r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800)
    except (OSError, subprocess.SubprocessError) as exc:
        return time.perf_counter() - t0, str(exc)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines()
        return dt, f"exit {r.returncode}: {lines[-1] if lines else 'no message'}"
    return dt, None


def run_startup(repeats: int = 3, cold_repeats: int = 1, cases=CASES, progress: bool = True) -> dict:
    """Cold and warm wall seconds of every case; ``{"cases": [...], "targets": [...], ...}``."""
    from ..progress import progress_bar

    from .report import check

    stamp0 = _source_stamp()
    out = []
    bar = progress_bar(show=progress, total=len(cases) * (2 * cold_repeats + repeats), desc="bench --startup",
                       leave=False)
    for method, model, extra in cases:
        cmd = command(method, model, extra)
        stamp = _source_stamp()
        cold, serial, warm, errors = [], [], [], []
        for i in range(max(int(cold_repeats), 1)):
            tmp = Path(tempfile.mkdtemp(prefix="pfbench-startup-"))
            try:
                bar.set_postfix_str(f"{method} cold, one process")
                one = Path(tempfile.mkdtemp(prefix="pfbench-startup-"))
                try:
                    dt, err = _timed(cmd, one, helper=False)
                finally:
                    shutil.rmtree(one, ignore_errors=True)
                bar.update()
                (errors.append(err) if err else serial.append(dt))
                bar.set_postfix_str(f"{method} cold")
                dt, err = _timed(cmd, tmp)
                bar.update()
                if err:
                    errors.append(err)
                    continue
                cold.append(dt)
                if i == 0:  # warm runs on the cache the first cold run filled
                    for _ in range(repeats):
                        bar.set_postfix_str(f"{method} warm")
                        dt, err = _timed(cmd, tmp)
                        bar.update()
                        (errors.append(err) if err else warm.append(dt))
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        med = lambda xs: statistics.median(xs) if xs else None  # noqa: E731
        rec = {"method": method, "model": model, "command": " ".join(["pfbench", *cmd[len(pfbench_command()):]]),
               "cold_s": med(cold), "cold_runs_s": cold, "cold_one_process_s": med(serial),
               "cold_one_process_runs_s": serial, "warm_s": med(warm), "warm_runs_s": warm,
               "error": errors[0] if errors else None, "package_changed": _source_stamp() != stamp}
        rec["compile_s"] = rec["cold_s"] - rec["warm_s"] if cold and warm else None
        out.append(rec)
    bar.close()
    targets = [check("cold_start_s", r["cold_s"], label=f"cold start, {r['method']} on {r['model']}")
               for r in out]
    from ..backends import compile_helper

    return {"kind": "bench_startup", "steps": STEPS, "particles": PARTICLES, "repeats": repeats,
            "compile_helper": compile_helper.enabled(), "usable_cores": compile_helper.usable_cores(),
            "cold_repeats": cold_repeats, "cases": out,
            "package_changed": _source_stamp() != stamp0 or any(r["package_changed"] for r in out),
            "targets": targets}


def _source_stamp() -> str:
    """Names, sizes and modification times of the package's .py files (cheap change detector)."""
    import hashlib

    from ..backends.cache import PACKAGE_DIR

    h = hashlib.sha256()
    for p in sorted(PACKAGE_DIR.rglob("*.py")):
        try:
            st = p.stat()
        except OSError:
            continue
        h.update(f"{p.relative_to(PACKAGE_DIR)}|{st.st_size}|{st.st_mtime_ns}\0".encode())
    return h.hexdigest()


def text(res: dict) -> list[str]:
    from .report import fmt

    out = [f"{'method':>10} {'model':>16} {'cold s':>8} {'1 proc s':>8} {'warm s':>8} {'compile s':>10}"]
    f = lambda v: f"{v:>8.2f}" if v is not None else f"{'-':>8}"  # noqa: E731
    for r in res["cases"]:
        line = (f"{r['method']:>10} {r['model']:>16} {f(r['cold_s'])} {f(r.get('cold_one_process_s'))} {f(r['warm_s'])} "
                f"{f(r['compile_s']):>10}")
        if r["error"]:
            line += f"  error: {r['error']}"
        if r["package_changed"]:
            line += "  (package source changed meanwhile)"
        out.append(line)
    out.append(f"(`pfbench run ... --steps {res['steps']} --particles {res['particles']}` as a subprocess, "
               f"wall time; cold = empty NUMBA_CACHE_DIR and PFBENCH_CACHE_DIR, with a compile helper "
               f"process {'on' if res.get('compile_helper') else 'OFF'} ({res.get('usable_cores', '?')} usable "
               f"cores); 1 proc = cold with PFBENCH_COMPILE_HELPER=0; warm = median of "
               f"{res['repeats']} reruns on the filled cache; compile = cold - warm)")
    out.append("(`pfbench compile`, which `make all` runs for every model's default run, pays the compile "
               "ahead: a first run after it is a warm start)")
    if res["package_changed"]:
        out.append("warning: the package source changed during the measurement (marked cases), so their "
                   "warm runs may include recompilation")
    out.extend(fmt(t) for t in res["targets"])
    return out

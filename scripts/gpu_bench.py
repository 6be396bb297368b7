"""GPU measurements of ``backend="cupy"`` (run by ``scripts/gpu_check.sh``; ``--cpu`` tries it here).

Sections, each time-boxed and in its own try/except (an error is printed and recorded, the next
section runs): the GPU and CuPy, which steps are fused, the device-to-device copy bandwidth (the
floor of any pass over the particles), Ob1 bootstrap in ns per particle-step (float32 and float64,
N_p = 10^6..10^8, then float32 at 10^9 if memory allows), numba on all cores at 10^6 and 10^7 for
the ratio. ns per particle-step is the marginal cost: the loop's time over N_p x M (the initial
particles, drawn on the host and copied, are reported apart as ``setup_s``). The JSON is rewritten
after every section, so a run cut short keeps what it measured.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import traceback

import numpy as np

RESULT: dict = {"sections": {}, "errors": {}}


def save(path):
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(RESULT, fh, indent=1, default=str)
    os.replace(tmp, path)


def section(name, path):
    def deco(fn):
        t0 = time.perf_counter()
        try:
            RESULT["sections"][name] = fn()
        except Exception as exc:  # noqa: BLE001 - report and go on
            traceback.print_exc()
            RESULT["errors"][name] = f"{type(exc).__name__}: {exc}"
            print(f"[{name}] FAILED: {type(exc).__name__}: {exc}", flush=True)
        print(f"[{name}] {time.perf_counter() - t0:.1f} s", flush=True)
        save(path)
        return fn
    return deco


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="gpu.json")
    ap.add_argument("--cpu", action="store_true", help="dry run: backend xp-numpy, tiny sizes")
    ap.add_argument("--budget-s", type=float, default=300.0, help="skip what would start after this")
    a = ap.parse_args()
    import pfbench
    from pfbench import models
    from pfbench.backends import cupy_backend

    t_start = time.perf_counter()
    backend = "xp-numpy" if a.cpu else "cupy"
    sizes = [10 ** 3, 10 ** 4] if a.cpu else [10 ** 6, 10 ** 7, 10 ** 8]
    big = 10 ** 5 if a.cpu else 10 ** 9
    model = models.get("ob1")
    from pfbench.provenance import provenance

    # kind, date, git SHA and host as in `pfbench bench`'s files: `pfbench bench --document` shows them
    RESULT.update(provenance(kind="bench_gpu"), backend=backend, python=platform.python_version(),
                  numpy=np.__version__, gpu=cupy_backend.gpu_info(), cpu_cores=os.cpu_count())
    cp = None if a.cpu else cupy_backend.import_cupy()

    def left():
        return a.budget_s - (time.perf_counter() - t_start)

    @section("fused_steps", a.out)
    def _():
        if cp is None:
            return "cpu dry run"
        return {dt: cupy_backend.fused_steps(cp, model, dt).info for dt in ("float32", "float64")}

    @section("d2d_bandwidth", a.out)
    def _():
        if cp is None:
            return None
        bw = cupy_backend.d2d_bandwidth(cp, 1 << 31)
        floor32 = 2 * 4 / bw * 1e9  # one read + one write of a float32 particle, ns
        print(f"device-to-device copy: {bw / 1e9:.0f} GB/s (read+write); one float32 pass over the "
              f"particles costs {floor32:.4f} ns per particle", flush=True)
        return {"bytes_per_s": bw, "ns_per_float32_copy": floor32, "ns_per_float64_copy": 2 * floor32}

    def gpu_ns(n, dtype, steps, repeats=2):
        traj = model.simulate(steps, seed=1)
        pfbench.run_filter(model, traj.y[:2], n_particles=min(n, 10 ** 6), backend=backend, dtype=dtype)
        runs = [pfbench.run_filter(model, traj.y, n_particles=n, backend=backend, dtype=dtype, seed=r)
                for r in range(repeats)]
        loop = [r.info["loop_s"] * 1e9 / (n * steps) for r in runs]
        whole = [r.elapsed_s * 1e9 / (n * steps) for r in runs]
        row = {"particles": n, "steps": steps, "dtype": dtype, "ns_per_particle_step": min(loop),
               "ns_loop_all": loop, "ns_whole_run": min(whole), "setup_s": min(r.info["setup_s"] for r in runs),
               "loglik": runs[0].loglik, "armse": float(pfbench.metrics.armse(runs[0].estimates, traj.x)),
               "gpu_steps": runs[0].info.get("gpu_steps")}
        print(f"cupy {dtype} N_p={n:.0e} M={steps}: {row['ns_per_particle_step']:.4f} ns/particle-step "
              f"(loop; whole run {row['ns_whole_run']:.4f}, setup {row['setup_s']:.2f} s), "
              f"aRMSE {row['armse']:.3f}", flush=True)
        return row

    @section("gpu_ob1_bootstrap", a.out)
    def _():
        rows = []
        for dtype in ("float32", "float64"):
            for n in sizes:
                if left() < 60:
                    rows.append({"particles": n, "dtype": dtype, "skipped": "time budget"})
                    continue
                steps = max(5, min(100, int(3e9 // n))) if not a.cpu else 10
                try:
                    rows.append(gpu_ns(n, dtype, steps))
                except Exception as exc:  # noqa: BLE001
                    print(f"cupy {dtype} N_p={n}: {type(exc).__name__}: {exc}", flush=True)
                    rows.append({"particles": n, "dtype": dtype, "error": f"{type(exc).__name__}: {exc}"})
        return rows

    @section("numba_all_cores", a.out)
    def _():
        rows = []
        for n in ([10 ** 3] if a.cpu else [10 ** 6, 10 ** 7]):
            if left() < 60:
                rows.append({"particles": n, "skipped": "time budget"})
                continue
            steps = 10 if a.cpu else max(5, int(2e8 // n))
            traj = model.simulate(steps, seed=1)
            for dtype in ("float32", "float64"):
                pfbench.run_filter(model, traj.y[:3], n_particles=n, backend="numba", dtype=dtype)  # compile
                t = [pfbench.run_filter(model, traj.y, n_particles=n, backend="numba", dtype=dtype, seed=r).elapsed_s
                     for r in range(2)]
                ns = min(t) * 1e9 / (n * steps)
                print(f"numba {os.cpu_count()} cores {dtype} N_p={n:.0e} M={steps}: {ns:.3f} ns/particle-step "
                      "(whole run)", flush=True)
                rows.append({"particles": n, "steps": steps, "dtype": dtype, "ns_per_particle_step": ns})
        return rows

    @section("gpu_1e9_float32", a.out)
    def _():
        if left() < 90:
            return {"skipped": "time budget"}
        need = cupy_backend.device_memory_need(model, big, 1, "float32", "bootstrap", True)
        free = cp.cuda.Device().mem_info[0] if cp is not None else need * 2
        if need > free * cupy_backend.DEVICE_FRACTION:
            return {"skipped": f"needs {need / 2**30:.1f} GiB, {free / 2**30:.1f} GiB free"}
        return gpu_ns(big, "float32", 5, repeats=1)

    @section("summary", a.out)
    def _():
        g = {(r["dtype"], r["particles"]): r.get("ns_per_particle_step")
             for r in RESULT["sections"].get("gpu_ob1_bootstrap") or [] if isinstance(r, dict)}
        nb = {(r.get("dtype"), r["particles"]): r.get("ns_per_particle_step")
              for r in RESULT["sections"].get("numba_all_cores") or [] if isinstance(r, dict)}
        top = max(sizes)
        s = {"target_ns_f32_1e8": 0.06, "ns_f32_1e8": g.get(("float32", top)),
             "ns_f64_1e8": g.get(("float64", top))}
        best_numba = min((v for v in nb.values() if v), default=None)
        if s["ns_f32_1e8"] and best_numba:
            s["speedup_vs_numba_all_cores"] = best_numba / s["ns_f32_1e8"]
        big_row = RESULT["sections"].get("gpu_1e9_float32") or {}
        s["ns_f32_1e9"] = big_row.get("ns_per_particle_step")
        s["meets_0_06"] = None if s["ns_f32_1e8"] is None else s["ns_f32_1e8"] <= 0.06
        s["meets_10x_numba"] = None if "speedup_vs_numba_all_cores" not in s else s["speedup_vs_numba_all_cores"] >= 10
        print("SUMMARY " + json.dumps(s), flush=True)
        return s

    print(f"wrote {a.out}", flush=True)


if __name__ == "__main__":
    sys.exit(main())

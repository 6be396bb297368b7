"""``backend="cupy"``: the array-namespace kernel (:mod:`pfbench.backends.array_backend`) on a GPU.

CuPy is imported only here, only when the backend is used (:func:`import_cupy`: a missing CuPy
or device is one line). The algorithm is :func:`pfbench.backends.array_backend.run_groups`; on
CuPy three of its steps run as fused kernels (:func:`fused_steps`), each checked once per process
against the namespace step on a small host problem and left out (with the reason in
``FilterResult.info["gpu_steps"]``) if it fails to build or to agree:

* model step: the model's own ``transition`` and ``log_likelihood`` traced into C
  (:mod:`pfbench.backends.trace`) and run as one ``ElementwiseKernel`` per step, with the
  Philox normals drawn inside it: one read and one write of the particles, one write of the
  log-likelihoods. A model the tracer cannot follow runs its functions on CuPy arrays instead
  (NumPy's ufuncs dispatch to CuPy), with the normals from a Philox kernel;
* exp + running sum + moments: one pass per block of :data:`BLOCK` particles (w = exp(a - m),
  the block's running sum in shared memory, its sums of w, w^2, w dx, w dx^2 with dx = x - x_0),
  then the block offsets by ``cupy.cumsum`` over the blocks: the cdf is offset + running sum,
  as the CPU kernels' stream blocks; the variance is the shifted one-pass formula;
* resampling + gather ([Embedded] Alg. 1 step 5): per block of :data:`BLOCK` outputs, two
  threads find the block's first and last ancestors by binary search over the whole cdf, then
  every thread searches only that range and copies its particle into a second buffer.

``backend="xp-numpy"`` runs :func:`run_groups` with NumPy and the namespace steps (the CPU tests).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import array_backend as ab
from .trace import TraceError, trace

#: particles per block of the fused weighting and resampling kernels (threads per CUDA block)
BLOCK = 1024
#: the share of the device's free memory a run may plan on
DEVICE_FRACTION = 0.9
INSTALL_HINT = ("pip install 'pfbench[gpu]' (cupy-cuda12x; for CUDA 13 drivers pip install "
                "cupy-cuda13x)")


def import_cupy():
    """CuPy with a usable CUDA device, or an InputError in one line saying what is missing."""
    try:
        import cupy
    except ImportError:
        raise InputError(f"backend 'cupy' needs CuPy, which is not installed: {INSTALL_HINT}") from None
    try:
        count = cupy.cuda.runtime.getDeviceCount()
    except Exception as exc:  # noqa: BLE001 - CUDARuntimeError or a missing driver library
        raise InputError(f"backend 'cupy' needs a CUDA GPU; CuPy {cupy.__version__} found none "
                         f"({' '.join(str(exc).split())})") from None
    if count < 1:
        raise InputError(f"backend 'cupy' needs a CUDA GPU; CuPy {cupy.__version__} found none")
    return cupy


def gpu_info() -> dict:
    """CuPy's version and the GPU (name, memory, CUDA runtime), for ``pfbench info`` and provenance;
    never raises."""
    try:
        import cupy
    except ImportError:
        return {"cupy": None, "gpu": "CuPy not installed"}
    out = {"cupy": cupy.__version__}
    try:
        props = cupy.cuda.runtime.getDeviceProperties(0)
        name = props["name"]
        out["gpu"] = name.decode() if isinstance(name, bytes) else str(name)
        out["gpu_memory_bytes"] = int(props["totalGlobalMem"])
        out["cuda_runtime"] = int(cupy.cuda.runtime.runtimeGetVersion())
        out["gpu_count"] = int(cupy.cuda.runtime.getDeviceCount())
    except Exception as exc:  # noqa: BLE001 - no driver / no device: say so
        out["gpu"] = f"none ({' '.join(str(exc).split())})"
    return out


def device_memory_need(model, n_particles: int, n_filters: int, dtype: str, method, fused: bool) -> int:
    """Bytes on the device: two particle buffers, log-likelihoods, cdf (and SIR/SIS log-weights);
    the namespace path also its float64 copies, normals and temporaries."""
    item = 4 if dtype == "float32" else 8
    n_x, n_y, n_z = int(model.n_x), int(model.n_y), int(model.n_noise)
    per = 2 * n_x * item + 16 + (16 if method in ("sir", "sis") else 0)
    if not fused:
        from ..resources import TEMPORARIES

        per += 8 * (2 * n_x + 6 * n_z + TEMPORARIES * (n_x + n_y) + 3)
    return int(per * n_particles * n_filters + (64 << 20))


# --------------------------------------------------------------------------- CUDA sources
PHILOX_C = r"""
__device__ __forceinline__ void pf_philox(unsigned long long c[4], unsigned long long k0,
                                          unsigned long long k1) {
  #pragma unroll
  for (int r = 0; r < 10; ++r) {
    if (r) { k0 += 0x9E3779B97F4A7C15ULL; k1 += 0xBB67AE8584CAA73BULL; }
    unsigned long long hi0 = __umul64hi(0xD2E7470EE14C6C93ULL, c[0]), lo0 = 0xD2E7470EE14C6C93ULL * c[0];
    unsigned long long hi1 = __umul64hi(0xCA5A826395121157ULL, c[2]), lo1 = 0xCA5A826395121157ULL * c[2];
    unsigned long long n0 = hi1 ^ c[1] ^ k0, n2 = hi0 ^ c[3] ^ k1;
    c[0] = n0; c[1] = lo1; c[2] = n2; c[3] = lo0;
  }
}
__device__ __forceinline__ double pf_unit(unsigned long long w) {
  return (double)(w >> 11) * 1.1102230246251565e-16;
}
__device__ __forceinline__ void pf_box_muller(unsigned long long w0, unsigned long long w1,
                                              double* z0, double* z1) {
  double r = sqrt(-2.0 * log(pf_unit(w0) + 1.1102230246251565e-16));
  double a = 6.283185307179586 * pf_unit(w1);
  *z0 = r * cos(a);
  *z1 = r * sin(a);
}
"""


def _normals_c(n_noise: int, cast: str, out: str) -> str:
    """C that draws the particle's ``n_noise`` normals (see :func:`array_backend.normals`) into
    ``out``-formatted lvalues, each rounded through ``cast`` (the particle type)."""
    lines = ["unsigned long long pf_c[4]; double pf_a, pf_b;"]
    for k in range(-(-n_noise // 4)):
        lines.append(f"pf_c[0] = (unsigned long long)pf_j; pf_c[1] = (unsigned long long)tt; "
                     f"pf_c[2] = {k}ULL; pf_c[3] = (unsigned long long)pf_f; pf_philox(pf_c, k0, k1);")
        for j in range(0, min(4, n_noise - 4 * k), 2):
            q = 4 * k + j
            lines.append(f"pf_box_muller(pf_c[{j}], pf_c[{j + 1}], &pf_a, &pf_b);")
            lines.append(f"{out.format(q)} = (double)({cast})pf_a;")
            if q + 1 < n_noise:
                lines.append(f"{out.format(q + 1)} = (double)({cast})pf_b;")
    return "\n".join(lines)


SCAN_C = r"""
extern "C" __global__ void pf_exp_scan(const double* __restrict__ a, const PTYPE* __restrict__ x,
    const double* __restrict__ m, double* __restrict__ loc, double* __restrict__ bs,
    long long n, int nb, int nx) {
  const int f = blockIdx.y, b = blockIdx.x, tid = threadIdx.x, lane = tid & 31, warp = tid >> 5;
  const long long base = (long long)f * n, j = (long long)b * 1024 + tid;
  const bool ok = j < n;
  const double w = ok ? exp(a[base + j] - m[f]) : 0.0;
  double s = w, y;
  for (int o = 1; o < 32; o <<= 1) { y = __shfl_up_sync(0xffffffffu, s, o); if (lane >= o) s += y; }
  __shared__ double part[32];
  if (lane == 31) part[warp] = s;
  __syncthreads();
  if (warp == 0) {
    double v = part[lane];
    for (int o = 1; o < 32; o <<= 1) { y = __shfl_up_sync(0xffffffffu, v, o); if (lane >= o) v += y; }
    part[lane] = v;
  }
  __syncthreads();
  if (warp > 0) s += part[warp - 1];
  if (ok) loc[base + j] = s;
  const int S = 2 + 2 * nx;
  double* out = bs + ((long long)f * nb + b) * S;
  const long long last = (n - (long long)b * 1024 < 1024 ? n - (long long)b * 1024 : 1024) - 1;
  if (tid == last) out[0] = s;
  __shared__ double red[32];
  for (int q = 1; q < S; ++q) {
    double v = 0.0;
    if (ok) {
      if (q == 1) v = w * w;
      else {
        const int k = (q - 2) >> 1;
        const double dx = (double)x[(base + j) * nx + k] - (double)x[base * nx + k];
        v = (q & 1) ? w * dx * dx : w * dx;
      }
    }
    for (int o = 16; o > 0; o >>= 1) v += __shfl_down_sync(0xffffffffu, v, o);
    __syncthreads();
    if (lane == 0) red[warp] = v;
    __syncthreads();
    if (warp == 0) {
      v = red[lane];
      for (int o = 16; o > 0; o >>= 1) v += __shfl_down_sync(0xffffffffu, v, o);
      if (lane == 0) out[q] = v;
    }
  }
}
"""

RESAMPLE_C = r"""
__device__ __forceinline__ long long pf_upper(const double* loc, const double* offs, long long lo,
                                              long long hi, double pos) {
  while (lo < hi) {
    const long long mid = (lo + hi) >> 1;
    if (offs[mid >> 10] + loc[mid] > pos) hi = mid; else lo = mid + 1;
  }
  return lo;
}
extern "C" __global__ void pf_resample(const double* __restrict__ loc, const double* __restrict__ offs,
    const double* __restrict__ total, const double* __restrict__ u, int strat,
    const PTYPE* __restrict__ x, PTYPE* __restrict__ xo, long long* __restrict__ idx, int want_idx,
    long long n, int nb, int nx, const int* __restrict__ rows) {
  const int f = rows[blockIdx.y];
  const long long base = (long long)f * n, i0 = (long long)blockIdx.x * 1024;
  const long long i = i0 + threadIdx.x, i1 = (n - i0 < 1024 ? n : i0 + 1024) - 1;
  const double T = total[f];
  const double* ur = u + (strat ? base : (long long)f);
  const double* lr = loc + base;
  const double* orow = offs + (long long)f * nb;
  __shared__ long long bound[2];
  if (threadIdx.x < 2) {
    const long long k = threadIdx.x ? i1 : i0;
    bound[threadIdx.x] = pf_upper(lr, orow, 0, n, ((ur[strat ? k : 0] + (double)k) / (double)n) * T);
  }
  __syncthreads();
  if (i > i1) return;
  long long j = pf_upper(lr, orow, bound[0], bound[1], ((ur[strat ? i : 0] + (double)i) / (double)n) * T);
  if (j > n - 1) j = n - 1;
  if (want_idx) idx[(long long)blockIdx.y * n + i] = j;
  for (int k = 0; k < nx; ++k) xo[(base + i) * nx + k] = x[(base + j) * nx + k];
}
"""


# --------------------------------------------------------------------------- fused steps
class Fused:
    """The fused CuPy steps of one (model, dtype); see the module docstring. ``parts`` names the
    steps that are fused; ``reasons`` says why the others are not."""

    def __init__(self, cp, model, dtype: str):
        self.cp, self.model, self.dtype = cp, model, dtype
        self.ptype = np.float32 if dtype == "float32" else np.float64
        self.ctype = "float" if dtype == "float32" else "double"
        self.n_x, self.n_z = int(model.n_x), int(model.n_noise)
        self.spare = None
        self.parts, self.reasons = [], {}
        opts = ("--fmad=false",)
        src = PHILOX_C + "\n".join(s.replace("PTYPE", self.ctype) for s in (SCAN_C, RESAMPLE_C))
        self.module = cp.RawModule(code=src, options=opts)
        self.normals_kernel = cp.ElementwiseKernel(
            "int64 tt, uint64 k0, uint64 k1, int64 npr, int32 nz", "raw float64 z",
            "const long long pf_f = i / npr, pf_j = i - pf_f * npr;\n"
            + _normals_c(self.n_z, "double", "z[i * nz + {0}]"),
            "pf_normals", preamble=PHILOX_C, options=opts)
        self.model_kernel = None
        try:
            self.model_kernel = self._model_kernel(opts)
        except TraceError as exc:
            self.reasons["model_step"] = f"not traced: {exc}"

    # ----- model step
    def _model_kernel(self, opts):
        m = self.model
        fns, p = m.kernel_functions(), m.params()
        xs = [f"pf_x{k}" for k in range(self.n_x)]
        names = dict(n_x=self.n_x, n_y=int(m.n_y), n_u=int(m.n_u), n_noise=self.n_z, p=p,
                     u_names=[f"uv[{k}]" for k in range(m.n_u)])
        tl, to = trace(fns["transition"], "transition", prefix="pf_a", x_names=xs,
                       z_names=[f"pf_z{k}" for k in range(self.n_z)], **names)
        xn = [f"pf_s{k}" for k in range(self.n_x)]
        ll, lo = trace(fns["log_likelihood"], "log_likelihood", prefix="pf_b", x_names=xn,
                       y_names=[f"yv[{k}]" for k in range(m.n_y)], **names)
        nx = self.n_x
        body = ["const long long pf_f = i / npr, pf_j = i - pf_f * npr;"]
        body += [f"const double pf_x{k} = (double)x[i * {nx} + {k}];" for k in range(nx)]
        body += [f"double pf_z{k};" for k in range(self.n_z)]
        body.append(_normals_c(self.n_z, "X", "pf_z{0}"))
        body += tl
        outs = to if len(to) == nx else to * nx
        for k in range(nx):
            body.append(f"const X pf_o{k} = (X)({outs[k]}); x[i * {nx} + {k}] = pf_o{k}; "
                        f"const double pf_s{k} = (double)pf_o{k};")
        body += ll
        body.append(f"const double pf_L = {lo[0]};")
        body.append("ll = (pf_L == pf_L && pf_L != (1.0 / 0.0)) ? pf_L : -(1.0 / 0.0);")
        self.model_source = "\n".join(body)
        return self.cp.ElementwiseKernel(
            "float64 t, int64 tt, raw float64 yv, raw float64 uv, uint64 k0, uint64 k1, int64 npr",
            "raw X x, float64 ll", self.model_source, "pf_model_step", preamble=PHILOX_C, options=opts)

    def normals(self, xp, key, n_rows, n, t, n_noise):
        z = xp.empty((n_rows * n, n_noise))
        self.normals_kernel(int(t), np.uint64(key[0]), np.uint64(key[1]), int(n), np.int32(n_noise),
                            z.reshape(-1), size=n_rows * n)
        return z

    def model_step(self, xp, fns, p, key, x, yt, ut, t):
        F, n, _ = x.shape
        ll = xp.empty((F, n))
        uu = ut if ut.size else xp.zeros(1)
        self.model_kernel(float(t), int(t), yt, uu, np.uint64(key[0]), np.uint64(key[1]), int(n),
                          x.reshape(-1), ll.reshape(-1))  # 1-D views: raw x[i * n_x + k]
        return ll

    # ----- weighting
    def weigh(self, xp, x, ll, lw):
        a, m, degen = ab.shifted(xp, ll, lw)
        F, n, nx = x.shape
        nb = -(-n // BLOCK)
        S = 2 + 2 * nx
        loc = xp.empty((F, n))
        bs = xp.empty((F, nb, S))
        self.module.get_function("pf_exp_scan")((nb, F), (BLOCK,), (
            xp.ascontiguousarray(a), x, m, loc, bs, np.int64(n), np.int32(nb), np.int32(nx)))
        wb = bs[:, :, 0]
        incl = xp.cumsum(wb, axis=1)
        offs = xp.concatenate([xp.zeros((F, 1)), incl[:, :-1]], axis=1)
        total = xp.ascontiguousarray(incl[:, -1])   # the kernels index total[f]: a strided view would not do
        sums = bs[:, :, 1:].sum(axis=1)
        d = sums[:, 1::2] / total[:, None]
        mean = x[:, 0, :].astype(xp.float64) + d
        var = xp.maximum(sums[:, 2::2] / total[:, None] - d * d, 0.0)
        ess = total * total / sums[:, 0]
        return (loc, xp.ascontiguousarray(offs), total), total, m, mean, var, ess, degen

    # ----- resampling + gather
    def ancestors_and_gather(self, xp, x, cdf, u, rows, want_idx):
        loc, offs, total = cdf
        F, n, nx = x.shape
        rows = list(range(F)) if rows is None else list(rows)
        if self.spare is None or self.spare.shape != x.shape or self.spare.dtype != x.dtype:
            self.spare = xp.empty_like(x)
        xo = self.spare
        if len(rows) < F:
            xo[...] = x
        idx = xp.empty((len(rows), n), dtype=xp.int64) if want_idx else xp.empty(1, dtype=xp.int64)
        strat = int(u.shape[1] > 1)
        nb = -(-n // BLOCK)
        self.module.get_function("pf_resample")((nb, len(rows)), (BLOCK,), (
            loc, offs, total, xp.ascontiguousarray(u), np.int32(strat), x, xo, idx, np.int32(want_idx),
            np.int64(n), np.int32(nb), np.int32(nx), xp.asarray(rows, dtype=xp.int32)))
        self.spare = x
        return xo, idx

    def resample(self, xp, x, cdf, u, rows=None):
        return self.ancestors_and_gather(xp, x, cdf, u, rows, False)[0]


def _check_fused(cp, fz: Fused, model) -> None:
    """Run every fused step once against the namespace step on a small host problem; drop those that
    fail or disagree (their reason goes to ``fz.reasons``)."""
    F, n = 2, 3000
    key = (12345, 678)
    rng = np.random.default_rng(5)
    p = model.params()
    x0 = ab.initial_particles(model, p, np.random.SeedSequence(1), F, n, fz.ptype)
    x0 = x0 + rng.standard_normal(x0.shape).astype(fz.ptype)
    traj = model.simulate(3, seed=2)
    u = model.input_array(traj.u, 3)
    fns = {"transition": model.kernel_functions()["transition"], "n_noise": fz.n_z,
           "log_likelihood": model.kernel_functions()["log_likelihood"]}
    tol = 1e-4 if fz.dtype == "float32" else 1e-9
    # normals
    try:
        z = cp.asnumpy(fz.normals(cp, key, F, n, 2, fz.n_z))
        if not np.allclose(z, ab.normals(np, key, F, n, 2, fz.n_z), rtol=1e-12, atol=1e-12):
            raise ValueError("normals differ from the NumPy Philox normals")
        fz.parts.append("normals")
    except Exception as exc:  # noqa: BLE001
        fz.reasons["normals"] = f"{type(exc).__name__}: {exc}"
    # model step
    if fz.model_kernel is not None:
        try:
            xh = x0.copy()
            llh = ab.model_step(np, fns, p, key, xh, traj.y[1], u[1], 1)
            xd = cp.asarray(x0)
            lld = cp.asnumpy(fz.model_step(cp, fns, None, key, xd, cp.asarray(traj.y[1]), cp.asarray(u[1]), 1))
            if not (np.allclose(cp.asnumpy(xd), xh, rtol=tol, atol=tol)
                    and np.allclose(lld, llh, rtol=tol, atol=tol, equal_nan=True)):
                raise ValueError("differs from the model's functions on NumPy")
            fz.parts.append("model_step")
        except Exception as exc:  # noqa: BLE001
            fz.model_kernel = None
            fz.reasons["model_step"] = f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
    # weighting and resampling
    ll = -0.5 * rng.standard_normal((F, n)) ** 2
    ll[0, :7] = -np.inf
    try:
        c_h, tot_h, m_h, mean_h, var_h, ess_h, _ = ab.weigh(np, x0, ll, None)
        xd = cp.asarray(x0)
        c_d, tot_d, m_d, mean_d, var_d, ess_d, _ = fz.weigh(cp, xd, cp.asarray(ll), None)
        for a, b in ((tot_d, tot_h), (mean_d, mean_h), (var_d, var_h), (ess_d, ess_h)):
            if not np.allclose(cp.asnumpy(a), b, rtol=1e-9, atol=1e-9):
                raise ValueError("weights/moments differ from the NumPy weighting")
        fz.parts.append("weigh")
        for strat in (False, True):
            uu = rng.random((F, n if strat else 1))
            xo, idx = fz.ancestors_and_gather(cp, xd, c_d, cp.asarray(uu), None, True)
            want = np.stack([ab.ancestors(np, c_h, uu, f) for f in range(F)])
            if np.mean(cp.asnumpy(idx) != want) > 1e-3:
                raise ValueError("ancestors differ from searchsorted on the NumPy cdf")
            if not np.array_equal(cp.asnumpy(xo), np.stack([x0[f][cp.asnumpy(idx)[f]] for f in range(F)])):
                raise ValueError("gather differs")
            xd = cp.asarray(x0)
        fz.parts.append("resample")
    except Exception as exc:  # noqa: BLE001
        fz.reasons["weigh/resample"] = f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"


_FUSED: dict = {}


def fused_steps(cp, model, dtype: str) -> ab.Steps:
    """The :class:`~pfbench.backends.array_backend.Steps` of a CuPy run: fused where built and
    checked (:func:`_check_fused`, once per model instance and dtype in a process), else the
    namespace step."""
    key = (id(model), dtype)
    if key not in _FUSED:
        try:
            fz = Fused(cp, model, dtype)
            _check_fused(cp, fz, model)
        except Exception as exc:  # noqa: BLE001 - e.g. NVRTC unavailable: run the namespace steps
            fz = None
            reason = f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
        _FUSED[key] = (model, fz, None if fz else reason)
    _, fz, reason = _FUSED[key]
    if fz is None:
        return ab.Steps(info={"gpu_steps": {"fused": [], "why_not": {"all": reason}}})
    fused = "weigh" in fz.parts and "resample" in fz.parts
    return ab.Steps(model_step=fz.model_step if "model_step" in fz.parts else ab.model_step,
                    weigh=fz.weigh if fused else ab.weigh,
                    resample=fz.resample if fused else ab.resample,
                    normals=fz.normals if "normals" in fz.parts else None,
                    info={"gpu_steps": {"fused": list(fz.parts), "why_not": dict(fz.reasons)}})


def probe(xp, model, pd) -> None:
    """Call the model's ``transition`` and ``log_likelihood`` on 2 particles of namespace ``xp``:
    an InputError naming the function if it fails or does not return an ``xp`` array."""
    fns = model.kernel_functions()
    x = xp.zeros((2, model.n_x))
    u = xp.zeros(model.n_u)
    args = {"transition": lambda: fns["transition"](x, u, 0, xp.zeros((2, model.n_noise)), pd),
            "log_likelihood": lambda: fns["log_likelihood"](xp.zeros(model.n_y), x, u, 0, pd)}
    for name, call in args.items():
        try:
            out = call()
            if not isinstance(out, xp.ndarray):
                raise TypeError(f"returned {type(out).__module__}.{type(out).__name__}, not a device array")
        except Exception as exc:  # noqa: BLE001 - whatever the model's code did on device arrays
            raise InputError(f"model {model.name!r}: {name}() cannot run on {xp.__name__} arrays "
                             f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})") from None


def run_groups(model, y, u, seed_seq, *, backend: str, method, n_per: int, n_filters: int, resampling,
               ess_threshold: float, dtype: str, store_particles: bool = False):
    """Run :func:`pfbench.backends.array_backend.run_groups` for ``backend`` (``cupy`` or
    ``xp-numpy``); returns ``(out, elapsed_s, info)`` (see there)."""
    from ..methods import Method
    from ..resampling import Scheme

    method, scheme = Method.parse(method), Scheme.parse(resampling)
    ab.check_supported(method, scheme, backend)
    if store_particles:
        raise InputError(f"keeping every step's particles (store_particles, which this run or recipe needs) is not "
                         f"available on backend {backend!r}: use backend numba or numpy")
    info = {"rng": "philox4x64-10 (counter-based; not numpy.random.Generator's stream)",
            "array_namespace": "cupy" if backend == "cupy" else "numpy"}
    if backend != "cupy":
        out, elapsed, more = ab.run_groups(np, model, y, u, seed_seq, method=method, n_per=n_per,
                                           n_filters=n_filters, resampling=scheme,
                                           ess_threshold=ess_threshold, dtype=dtype)
        return out, elapsed, {**info, **more}
    cp = import_cupy()
    steps = fused_steps(cp, model, dtype)
    if steps.model_step is ab.model_step:
        probe(cp, model, ab.device_params(cp, model.params()))
    need = device_memory_need(model, n_per, n_filters, dtype, method.label,
                              steps.model_step is not ab.model_step and steps.weigh is not ab.weigh)
    free, total = cp.cuda.Device().mem_info
    if need > free * DEVICE_FRACTION:
        per = need / max(n_per * n_filters, 1)
        raise InputError(f"--particles {n_per * n_filters}: {method.label} on {model.name} needs about "
                         f"{need / 2**30:.1f} GiB of GPU memory but {free / 2**30:.1f} GiB is free "
                         f"(a run may plan on {DEVICE_FRACTION:.0%}); the largest N_p that fits is about "
                         f"{int(free * DEVICE_FRACTION / per):.3g}")
    out, elapsed, more = ab.run_groups(cp, model, y, u, seed_seq, method=method, n_per=n_per,
                                       n_filters=n_filters, resampling=scheme,
                                       ess_threshold=ess_threshold, dtype=dtype, steps=steps)
    return out, elapsed, {**info, **more, "gpu": gpu_info().get("gpu")}


def d2d_bandwidth(cp, n_bytes: int = 1 << 30, repeats: int = 5) -> float:
    """Device-to-device copy bandwidth in bytes/s (read + write counted once each, the median of
    ``repeats`` copies of ``n_bytes``): the floor any pass over the particles pays."""
    import statistics

    a = cp.empty(n_bytes // 8)
    b = cp.empty_like(a)
    b[...] = a
    times = []
    for _ in range(max(repeats, 1)):
        start, stop = cp.cuda.Event(), cp.cuda.Event()
        start.record()
        b[...] = a
        stop.record()
        stop.synchronize()
        times.append(cp.cuda.get_elapsed_time(start, stop) / 1e3)
    return 2 * a.nbytes / statistics.median(times)



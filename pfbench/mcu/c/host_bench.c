/*
 * Host timing harness for the project's Ob1 bootstrap filter (pf_ob1.c, [Embedded] Alg. 1 with
 * systematic resampling), built by `pfbench bench` with the system C compiler at -O3
 * -march=native.  The filter functions are those of pf_ob1.c, compiled in this translation unit
 * (the file is #included; its bare-metal entry point is renamed and never called).
 *
 * Two random number generators (chosen at compile time):
 *   default       pf_ob1.c's own: libc rand() -> uniform, Box-Muller with one normal per two
 *                 uniforms (log + sqrt + cos per draw), exactly as on the microcontroller;
 *   PF_FAST_RNG   xoshiro256++ (64-bit output) -> 53-bit uniforms, and the 256-layer ziggurat of
 *                 Marsaglia & Tsang (2000) for normals -- the method NumPy's Generator uses.
 *
 * Usage (results on stdout):
 *   host_bench filter M N REPEATS SEED   simulate y(1..M) first (untimed), then run the filter
 *                                        1 + REPEATS times (the first untimed: page faults, caches)
 *                                        and print one JSON line with ns per particle-step of each
 *                                        timed repeat, the SSE of the last one, the SSE of the
 *                                        estimate 0 (sum of x^2) and the RNG name;
 *   host_bench normals COUNT SEED        write COUNT standard-normal draws as raw native doubles
 *                                        (for the tests of the generator).
 */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef PF_FAST_RNG
#define PF_HOST_RNG /* pf_ob1.c then leaves rand_uniform/randn to this file */
#define PF_RNG_NAME "xoshiro256++ + ziggurat (256 layers)"
#else
#define PF_RNG_NAME "libc rand() + Box-Muller (1 normal per 2 uniforms)"
#endif

#define main pf_ob1_mcu_main /* the bare-metal entry point; unused here */
#include "pf_ob1.c"
#undef main

/* ------------------------------------------------------------------ fast generator */
#ifdef PF_FAST_RNG
static uint64_t xs_state[4];

static inline uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

/* xoshiro256++ (Blackman & Vigna): every output bit is usable. */
static inline uint64_t next_u64(void)
{
    uint64_t *s = xs_state;
    const uint64_t result = rotl(s[0] + s[3], 23) + s[0];
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* Uniform on [0, 1) with 53 random bits. */
static inline double unif53(void)
{
    return (double)(next_u64() >> 11) * 0x1.0p-53;
}

/* Ziggurat tables: 256 layers of equal area ZIG_V under exp(-x^2/2), rightmost edge ZIG_R. */
#define ZIG_R 3.6541528853610087963519472518
#define ZIG_INV_R 0.27366123732975827203338247596
#define ZIG_V 4.92867323399e-3
static uint64_t zig_k[256]; /* accept x at once when its 52-bit mantissa is below zig_k[layer] */
static double zig_w[256];   /* layer edge / 2^52 */
static double zig_f[256];   /* exp(-edge^2 / 2) */

static void zig_init(void)
{
    const double m1 = 4503599627370496.0; /* 2^52 */
    double dn = ZIG_R, tn = dn, q = ZIG_V / exp(-0.5 * dn * dn);
    zig_k[0] = (uint64_t)((dn / q) * m1);
    zig_k[1] = 0;
    zig_w[0] = q / m1;
    zig_w[255] = dn / m1;
    zig_f[0] = 1.0;
    zig_f[255] = exp(-0.5 * dn * dn);
    for (int i = 254; i >= 1; i--) {
        dn = sqrt(-2.0 * log(ZIG_V / dn + exp(-0.5 * dn * dn)));
        zig_k[i + 1] = (uint64_t)((dn / tn) * m1);
        tn = dn;
        zig_f[i] = exp(-0.5 * dn * dn);
        zig_w[i] = dn / m1;
    }
}

/* Uniform on (0, 1) for the resampling offset. */
static real rand_uniform(void)
{
    return (real)(((double)(next_u64() >> 11) + 0.5) * 0x1.0p-53);
}

/* The ziggurat's rare branch (about 1% of draws): the tail beyond ZIG_R (Marsaglia's exponential
 * method) or the wedge of layer idx under the curve; 0 = reject, draw again. */
static __attribute__((noinline)) int zig_slow(int idx, uint64_t rabs, double x, double *out)
{
    if (idx == 0) {
        for (;;) {
            const double xx = -ZIG_INV_R * log1p(-unif53());
            const double yy = -log1p(-unif53());
            if (yy + yy > xx * xx) {
                *out = ((rabs >> 8) & 1) ? -(ZIG_R + xx) : ZIG_R + xx;
                return 1;
            }
        }
    }
    *out = x;
    return (zig_f[idx - 1] - zig_f[idx]) * unif53() + zig_f[idx] < exp(-0.5 * x * x);
}

/* Standard normal draw by the ziggurat: 8 bits pick the layer, 1 the sign, 52 the abscissa. */
static inline real randn(void)
{
    for (;;) {
        uint64_t r = next_u64();
        const int idx = (int)(r & 0xff);
        r >>= 8;
        const int sign = (int)(r & 1);
        const uint64_t rabs = (r >> 1) & 0x000fffffffffffffULL;
        double x = (double)rabs * zig_w[idx];
        if (sign)
            x = -x;
        if (__builtin_expect(rabs < zig_k[idx], 1))
            return (real)x; /* inside the layer's rectangle: about 99% of draws */
        double out;
        if (zig_slow(idx, rabs, x, &out))
            return (real)out;
    }
}
#endif /* PF_FAST_RNG */

static void host_seed(uint32_t seed)
{
    srand(seed);
#ifdef PF_FAST_RNG
    uint64_t sm = seed;
    for (int i = 0; i < 4; i++)
        xs_state[i] = splitmix64(&sm);
    zig_init();
#endif
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int run_filter(long m, long n, int repeats, uint32_t seed)
{
    if (n < 1 || n > PF_NMAX || m < 1 || repeats < 1) {
        fprintf(stderr, "host_bench: need 1 <= N <= %d, M >= 1, REPEATS >= 1\n", PF_NMAX);
        return 2;
    }
    real *ys = malloc(sizeof(real) * (size_t)(m + 1));
    real *xs = malloc(sizeof(real) * (size_t)(m + 1));
    double *ns = malloc(sizeof(double) * (size_t)repeats);
    if (!ys || !xs || !ns) {
        fprintf(stderr, "host_bench: out of memory for M=%ld\n", m);
        return 3;
    }
    host_seed(seed);
    real x = X0, y = L(0.0);
    for (long k = 1; k <= m; k++) { /* the simulated object, as pf_ob1.c's main, but untimed */
        x = sim_step(x, (int)k, &y);
        xs[k] = x;
        ys[k] = y;
    }
    double sse = 0.0, sum_x2 = 0.0; /* sum_x2: the SSE of the estimate 0, for comparison */
    for (long k = 1; k <= m; k++)
        sum_x2 += (double)(xs[k] * xs[k]);
    for (int r = 0; r <= repeats; r++) {
        for (long i = 0; i < n; i++) /* Alg. 1 step 1 */
            x_part[i] = X0;
        sse = 0.0;
        const double t0 = now_s();
        for (long k = 1; k <= m; k++) { /* the loop of pf_ob1.c's main without sim_step */
            pf_predict((int)n, (int)k);
            pf_weights((int)n, ys[k]);
            pf_normalize((int)n);
            const real est = pf_estimate((int)n);
            pf_resample((int)n);
            sse += (double)((est - xs[k]) * (est - xs[k]));
        }
        const double t1 = now_s();
        if (r > 0)
            ns[r - 1] = (t1 - t0) * 1e9 / ((double)m * (double)n);
    }
    printf("{\"rng\": \"%s\", \"steps\": %ld, \"particles\": %ld, \"sse\": %.17g, \"sum_x2\": %.17g, "
           "\"ns_per_particle_step\": [",
           PF_RNG_NAME, m, n, sse, sum_x2);
    for (int r = 0; r < repeats; r++)
        printf("%s%.6g", r ? ", " : "", ns[r]);
    printf("]}\n");
    free(ys);
    free(xs);
    free(ns);
    return 0;
}

static int write_normals(long count, uint32_t seed)
{
    host_seed(seed);
    double buf[4096];
    while (count > 0) {
        const long k = count < 4096 ? count : 4096;
        for (long i = 0; i < k; i++)
            buf[i] = (double)randn();
        if (fwrite(buf, sizeof(double), (size_t)k, stdout) != (size_t)k)
            return 3;
        count -= k;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 6 && strcmp(argv[1], "filter") == 0)
        return run_filter(atol(argv[2]), atol(argv[3]), atoi(argv[4]), (uint32_t)strtoul(argv[5], 0, 10));
    if (argc == 4 && strcmp(argv[1], "normals") == 0)
        return write_normals(atol(argv[2]), (uint32_t)strtoul(argv[3], 0, 10));
    fprintf(stderr, "usage: host_bench filter M N REPEATS SEED | host_bench normals COUNT SEED\n");
    return 2;
}

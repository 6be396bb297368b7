/*
 * Bootstrap particle filter on Ob1 for a bare-metal Cortex-M4(F) ([Embedded] §5.1).
 *
 * [Embedded], Algorithm 1 (bootstrap PF) with systematic resampling, run on the
 * simulation object of [Embedded] eq. 6 (= [MultiPDF] Ob1), simulated inside the loop
 * exactly as the paper's platform benchmark did (§5.1):
 *
 *     x(k+1) = 0.5 x(k) + 25 x(k) / (1 + x(k)^2) + 8 cos(1.2 k) + v(k),   v ~ N(0, 10)
 *     y(k)   = x(k)^2 / 20 + n(k),                                          n ~ N(0, 1)
 *     x(0)   = 0.1
 *
 * Two builds mirror Table 2:
 *   D(S)  double everywhere, plain C library calls, no FPU (soft double via libgcc);
 *   D(O)  -DPF_FLOAT: float only, f-suffixed literals, cosf/logf/sqrtf/expf/powf,
 *         -mfpu=fpv4-sp-d16 -mfloat-abi=hard -Ofast.
 *
 * The emulator writes the run configuration into `pf_config` before starting and stops
 * when execution reaches `pf_finish`.  Results are left in `pf_result`.
 */
#include <stdint.h>

#include "pf_common.h"

typedef pf_real real;

#ifndef PF_NMAX
#define PF_NMAX 1000 /* largest particle count of Table 2 */
#endif

/* Written by the emulator (or left at these defaults on a board). */
volatile struct {
    int32_t steps;     /* M  */
    int32_t particles; /* Np */
    uint32_t seed;
} pf_config = {10, 100, 1u};

/* [0] sum of squared errors, [1] last estimate, [2] last true state, [3] resamplings */
volatile real pf_result[4];

static real x_part[PF_NMAX]; /* particles */
static real x_new[PF_NMAX];  /* resampled particles */
static real weight[PF_NMAX]; /* weights */

static const real Q = L(10.0);     /* var v(k) */
static const real R_VAR = L(1.0);  /* var n(k) */
static const real X0 = L(0.1);

/* Ob1 state transition without noise, [Embedded] eq. 6. */
static real transition(real x, int k)
{
    return L(0.5) * x + L(25.0) * x / (L(1.0) + x * x) + L(8.0) * COS(L(1.2) * (real)k);
}

/* Simulated object: one step of the true state and its measurement. */
NOINLINE real sim_step(real x, int k, real *y)
{
    real xk = transition(x, k) + SQRT(Q) * randn();
    *y = POW(xk, L(2.0)) / L(20.0) + SQRT(R_VAR) * randn();
    return xk;
}

/* Alg. 1 step 2: draw x_i(k) ~ p(x(k) | x_i(k-1)). */
NOINLINE void pf_predict(int n, int k)
{
    real sq = SQRT(Q);
    for (int i = 0; i < n; i++)
        x_part[i] = transition(x_part[i], k) + sq * randn();
}

/* Alg. 1 step 3: q_i = p(y(k) | x_i(k)), eq. 5 (constant factor dropped). */
NOINLINE void pf_weights(int n, real y)
{
    for (int i = 0; i < n; i++) {
        real e = y - x_part[i] * x_part[i] / L(20.0);
        weight[i] = EXP(-e * e / (L(2.0) * R_VAR));
    }
}

/* Alg. 1 step 4: weights sum to one. */
NOINLINE void pf_normalize(int n)
{
    real s = L(0.0);
    for (int i = 0; i < n; i++)
        s += weight[i];
    if (s <= L(0.0)) { /* total degeneracy: fall back to uniform weights */
        for (int i = 0; i < n; i++)
            weight[i] = L(1.0) / (real)n;
        return;
    }
    for (int i = 0; i < n; i++)
        weight[i] = weight[i] / s;
}

/* Alg. 1 step 6: weighted-mean estimate of x(k). */
NOINLINE real pf_estimate(int n)
{
    real m = L(0.0);
    for (int i = 0; i < n; i++)
        m += weight[i] * x_part[i];
    return m;
}

/* Alg. 1 step 5: systematic resampling (one uniform, N evenly spaced pointers). */
NOINLINE void pf_resample(int n)
{
    real step = L(1.0) / (real)n;
    real u = rand_uniform() * step;
    real c = weight[0];
    int j = 0;
    for (int i = 0; i < n; i++) {
        while (u > c && j < n - 1)
            c += weight[++j];
        x_new[i] = x_part[j];
        u += step;
    }
    for (int i = 0; i < n; i++)
        x_part[i] = x_new[i];
}

int main(void)
{
    int m = pf_config.steps;
    int n = pf_config.particles;
    if (n > PF_NMAX)
        n = PF_NMAX;
    if (n < 1)
        n = 1;
    srand(pf_config.seed);

    real x = X0, y = L(0.0), sse = L(0.0), est = X0;
    for (int i = 0; i < n; i++) /* Alg. 1 step 1: p(x(0)) = delta(x - x0) */
        x_part[i] = X0;

    for (int k = 1; k <= m; k++) {
        x = sim_step(x, k, &y);
        pf_predict(n, k);
        pf_weights(n, y);
        pf_normalize(n);
        est = pf_estimate(n);
        pf_resample(n);
        sse += (est - x) * (est - x);
    }
    pf_result[0] = sse;
    pf_result[1] = est;
    pf_result[2] = x;
    pf_result[3] = (real)m;
    pf_finish();
    for (;;) {
    }
}

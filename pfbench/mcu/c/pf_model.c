/*
 * Generic bootstrap particle filter harness for a bare-metal Cortex-M ([Embedded] Alg. 1).
 *
 * The same algorithm as pf_ob1.c (systematic resampling every step, Box-Muller normals from the
 * C library's rand(), weighted-mean estimate), but the model is not written here: it is called
 * through the ABI of pf_model.h (pfm_transition, pfm_log_likelihood), normally the model's own
 * numba-compiled code retargeted to Cortex-M (pfbench.mcu.modelcode).  The harness owns the
 * loop, the random numbers, the weighting and the resampling, as a deployed filter would.
 *
 * Unlike pf_ob1.c, nothing is simulated on the MCU: the host (pfbench.mcu.emulate) simulates
 * the model, draws the initial particles with the model's `initial`, and writes them, the
 * measurements y (M, PFM_NY), the inputs u (M, PFM_NU) and the true states (M, PFM_NX, only to
 * score the estimate) into the initialised-data image before the run.  Per step t = 0..M-1:
 *
 *   1. draw PFM_NNOISE standard normals per particle (Box-Muller, one value per call);
 *   2. x_t = pfm_transition(x_{t-1}, u[t], t, noise)           (Alg. 1 step 2)
 *   3. l_i = pfm_log_likelihood(y[t], x_t, u[t], t);
 *      w_i = exp(l_i - max_j l_j)                               (step 3, any log-likelihood)
 *   4. normalise (uniform weights if every weight underflowed)  (step 4)
 *   5. estimate = sum_i w_i x_i (every state)                   (step 6)
 *   6. systematic resampling (one uniform, N evenly spaced pointers) (step 5)
 *
 * The model is called on TILES of at most PF_TILE particles (default 32): the model's own
 * temporaries (numba allocates arrays of the tile's size) and the harness's noise buffer stay
 * a few hundred bytes on an MCU with tens of kB of RAM, while the per-call overhead (a few
 * tens of cycles) is spread over 32 particles, well under 1 % of a particle-step.
 *
 * Static buffers are sized by -DPF_NMAX (particles) and -DPF_MMAX (steps).  The emulator stops
 * when execution reaches pf_finish; results are in pf_result.
 */
#include <stdint.h>

#include "pf_common.h"

#ifndef PF_NMAX
#define PF_NMAX 256
#endif
#ifndef PF_MMAX
#define PF_MMAX 64
#endif
#ifndef PF_TILE
#define PF_TILE 32
#endif
#ifndef PFM_NU
#define PFM_NU 0
#endif
#if PFM_NU > 0
#define PF_NU_ALLOC PFM_NU
#else
#define PF_NU_ALLOC 1
#endif

#define INPUT __attribute__((section(".data.pf_inputs"), aligned(8)))

/* Written by the host into the initialised-data image (copied to RAM by Reset_Handler). */
volatile struct {
    int32_t steps;     /* M  <= PF_MMAX */
    int32_t particles; /* Np <= PF_NMAX */
    uint32_t seed;     /* srand() seed */
    int32_t pad;
} pf_config INPUT = {1, 1, 1u, 0};

pf_real pf_x[PF_NMAX * PFM_NX] INPUT = {L(0.0)};        /* particles; host writes x_{-1} */
pf_real pf_y[PF_MMAX * PFM_NY] INPUT = {L(0.0)};        /* measurements */
pf_real pf_u[PF_MMAX * PF_NU_ALLOC] INPUT = {L(0.0)};   /* inputs */
pf_real pf_xtrue[PF_MMAX * PFM_NX] INPUT = {L(0.0)};    /* host's true states (scoring only) */

/* Results, read back by the host. */
volatile struct {
    pf_real sse[PFM_NX];  /* sum over steps of (estimate - true)^2, per state */
    pf_real est[PFM_NX];  /* last estimate */
    int32_t steps;        /* steps run */
    int32_t degenerate;   /* steps whose weights all underflowed (uniform fallback) */
} pf_result;

static pf_real x_prop[PF_NMAX * PFM_NX]; /* propagated particles x_t */
static pf_real weight[PF_NMAX];          /* log-weights, then normalised weights */
static pf_real noise[PF_TILE * PFM_NNOISE];
static pf_real est[PFM_NX];


static const pf_real *input_at(int t)
{
#if PFM_NU > 0
    return pf_u + (long)t * PFM_NU;
#else
    (void)t;
    return (const pf_real *)0;
#endif
}

/* Alg. 1 step 2: x_prop = f(pf_x, u[t], t, noise), tile by tile. */
NOINLINE void pf_predict(int n, int t)
{
    const pf_real *u = input_at(t);
    for (int i0 = 0; i0 < n; i0 += PF_TILE) {
        int m = n - i0 < PF_TILE ? n - i0 : PF_TILE;
        for (int j = 0; j < m * PFM_NNOISE; j++)
            noise[j] = randn();
        pfm_transition(pf_x + (long)i0 * PFM_NX, m, u, t, noise, x_prop + (long)i0 * PFM_NX);
    }
}

/* Alg. 1 step 3: weight[i] = exp(log p(y_t | x_i) - max_j log p(y_t | x_j)).
 * Returns the largest log-likelihood. */
NOINLINE pf_real pf_weights(int n, int t)
{
    const pf_real *u = input_at(t);
    const pf_real *y = pf_y + (long)t * PFM_NY;
    for (int i0 = 0; i0 < n; i0 += PF_TILE) {
        int m = n - i0 < PF_TILE ? n - i0 : PF_TILE;
        pfm_log_likelihood(y, x_prop + (long)i0 * PFM_NX, m, u, t, weight + i0);
    }
    pf_real mx = weight[0];
    for (int i = 1; i < n; i++)
        if (weight[i] > mx)
            mx = weight[i];
    for (int i = 0; i < n; i++)
        weight[i] = EXP(weight[i] - mx);
    return mx;
}

/* Alg. 1 step 4: weights sum to one; uniform weights if they all vanished (returns 1). */
NOINLINE int pf_normalize(int n)
{
    pf_real s = L(0.0);
    for (int i = 0; i < n; i++)
        s += weight[i];
    if (!(s > L(0.0))) {
        for (int i = 0; i < n; i++)
            weight[i] = L(1.0) / (pf_real)n;
        return 1;
    }
    pf_real inv = L(1.0) / s;
    for (int i = 0; i < n; i++)
        weight[i] = weight[i] * inv;
    return 0;
}

/* Alg. 1 step 6: weighted-mean estimate of every state. */
NOINLINE void pf_estimate(int n)
{
    for (int d = 0; d < PFM_NX; d++)
        est[d] = L(0.0);
    for (int i = 0; i < n; i++)
        for (int d = 0; d < PFM_NX; d++)
            est[d] += weight[i] * x_prop[(long)i * PFM_NX + d];
}

/* Alg. 1 step 5: systematic resampling from x_prop into pf_x. */
NOINLINE void pf_resample(int n)
{
    pf_real step = L(1.0) / (pf_real)n;
    pf_real u = rand_uniform() * step;
    pf_real c = weight[0];
    int j = 0;
    for (int i = 0; i < n; i++) {
        while (u > c && j < n - 1)
            c += weight[++j];
        for (int d = 0; d < PFM_NX; d++)
            pf_x[(long)i * PFM_NX + d] = x_prop[(long)j * PFM_NX + d];
        u += step;
    }
}

int main(void)
{
    int m = pf_config.steps;
    int n = pf_config.particles;
    if (m > PF_MMAX)
        m = PF_MMAX;
    if (m < 1)
        m = 1;
    if (n > PF_NMAX)
        n = PF_NMAX;
    if (n < 1)
        n = 1;
    srand(pf_config.seed);

    int degenerate = 0;
    for (int d = 0; d < PFM_NX; d++)
        pf_result.sse[d] = L(0.0);
    for (int t = 0; t < m; t++) {
        pf_predict(n, t);
        pf_weights(n, t);
        degenerate += pf_normalize(n);
        pf_estimate(n);
        pf_resample(n);
        for (int d = 0; d < PFM_NX; d++) {
            pf_real e = est[d] - pf_xtrue[(long)t * PFM_NX + d];
            pf_result.sse[d] += e * e;
        }
    }
    for (int d = 0; d < PFM_NX; d++)
        pf_result.est[d] = est[d];
    pf_result.steps = m;
    pf_result.degenerate = degenerate;
    pf_finish();
    for (;;) {
    }
}

/*
 * The C ABI between the generic filter harness (pf_model.c) and a model's own code compiled
 * for the target (pfbench.mcu.modelcode: the model's numba-compiled functions, retargeted to
 * Cortex-M).  The harness owns the loop, the random numbers, weighting and resampling; the
 * model supplies only its transition and its log-likelihood, over a tile of n particles.
 *
 * Dimensions arrive as -D flags from the build: PFM_NX (n_x), PFM_NY (n_y), PFM_NU (n_u, may
 * be 0) and PFM_NNOISE (standard-normal draws per particle and step).  Arrays are row-major.
 * PF_FLOAT selects single precision (float) for every pf_real; otherwise double.
 */
#ifndef PF_MODEL_H
#define PF_MODEL_H
#include <stdint.h>

#ifdef PF_FLOAT
typedef float pf_real;
#else
typedef double pf_real;
#endif

/* x_out (n, PFM_NX) = transition(x (n, PFM_NX), u (PFM_NU), t, noise (n, PFM_NNOISE)).
 * u may be a null pointer when PFM_NU == 0.  t is the 0-based step index of the model contract
 * (pfbench/models/base.py). */
void pfm_transition(const pf_real *x, int32_t n, const pf_real *u, int32_t t,
                    const pf_real *noise, pf_real *x_out);

/* out (n) = log p(y | x_i) for the n particles x (n, PFM_NX); y has PFM_NY entries. */
void pfm_log_likelihood(const pf_real *y, const pf_real *x, int32_t n, const pf_real *u,
                        int32_t t, pf_real *out);

#endif /* PF_MODEL_H */

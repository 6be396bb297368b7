/*
 * Ob1 ([Embedded] eq. 6 = [MultiPDF] Ob1) written by hand against the model ABI pf_model.h:
 * the reference "what a hand port of the model costs" for the generic harness pf_model.c, and a
 * test of the harness independent of the compiled-model path.  Default parameters of
 * pfbench.models.ob1 (q = 10, r = 1), time index t as in the model contract (0-based):
 *
 *     x_t = 0.5 x + 25 x / (1 + x^2) + 8 cos(1.2 t) + sqrt(q) v,
 *     log p(y | x) = log N(y; x^2 / 20, r)
 *
 * -DOB1_DOUBLE_LITERALS (tests only) keeps unsuffixed literals in a float build: the classic
 * mistake that promotes every operation to (soft-float) double on an M4F.
 */
#include <math.h>

#include "pf_model.h"

#if defined(PF_FLOAT) && !defined(OB1_DOUBLE_LITERALS)
#define L(c) c##f
#define COS cosf
#else
#define L(c) c
#define COS cos
#endif

static const pf_real SQRT_Q = L(3.1622776601683795); /* sqrt(10) */
static const pf_real R = L(1.0);
static const pf_real LOG_NORM = L(0.9189385332046727); /* 0.5 (log 2 pi + log r), r = 1 */

void pfm_transition(const pf_real *x, int32_t n, const pf_real *u, int32_t t,
                    const pf_real *noise, pf_real *x_out)
{
    (void)u;
    pf_real drift = L(8.0) * COS(L(1.2) * (pf_real)t);
    for (int32_t i = 0; i < n; i++) {
        pf_real xi = x[i];
        x_out[i] = L(0.5) * xi + L(25.0) * xi / (L(1.0) + xi * xi) + drift + SQRT_Q * noise[i];
    }
}

void pfm_log_likelihood(const pf_real *y, const pf_real *x, int32_t n, const pf_real *u,
                        int32_t t, pf_real *out)
{
    (void)u;
    (void)t;
    for (int32_t i = 0; i < n; i++) {
        pf_real r = y[0] - x[i] * x[i] / L(20.0);
        out[i] = L(-0.5) * r * r / R - LOG_NORM;
    }
}

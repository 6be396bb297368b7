/*
 * What the two bare-metal bootstrap filters share: pf_ob1.c (the hand port of the [Embedded]
 * Table 2 benchmark) and pf_model.c (the generic harness for any model's compiled code).
 *
 *   - the working precision: pf_real (pf_model.h) is float with -DPF_FLOAT, else double; L(c)
 *     is a literal of that precision and COS/SQRT/LOG/EXP/POW the matching C library calls;
 *   - the random numbers of [Embedded] Alg. 1 on the board: uniforms from the C library's
 *     rand() and standard normals by Box-Muller, one value per call (a host build that brings
 *     its own generator defines PF_HOST_RNG and supplies rand_uniform/randn itself);
 *   - pf_finish, the address at which the emulator stops.
 */
#ifndef PF_COMMON_H
#define PF_COMMON_H
#include <math.h>
#include <stdlib.h>

#include "pf_model.h"

#ifdef PF_FLOAT
#define L(c) c##f /* literal of the working precision */
#define COS cosf
#define SQRT sqrtf
#define LOG logf
#define EXP expf
#define POW powf
#else
#define L(c) c
#define COS cos
#define SQRT sqrt
#define LOG log
#define EXP exp
#define POW pow
#endif

#define NOINLINE __attribute__((noinline))

static const pf_real TWO_PI = L(6.283185307179586);

#ifndef PF_HOST_RNG
/* Uniform on (0, 1) from the C library generator. */
static NOINLINE pf_real rand_uniform(void)
{
    return ((pf_real)rand() + L(1.0)) / ((pf_real)RAND_MAX + L(2.0));
}

/* Standard normal draw, Box-Muller (one value per call). */
NOINLINE pf_real randn(void)
{
    pf_real u1 = rand_uniform();
    pf_real u2 = rand_uniform();
    return SQRT(L(-2.0) * LOG(u1)) * COS(TWO_PI * u2);
}
#else
static pf_real rand_uniform(void); /* defined after this file by the host harness */
static pf_real randn(void);
#endif /* PF_HOST_RNG */

/* The emulator stops when execution reaches this address. */
NOINLINE void pf_finish(void)
{
    __asm__ volatile("nop");
}

#endif /* PF_COMMON_H */

/*
 * numba's runtime (NRT) on a bare-metal Cortex-M: the few entry points a model's compiled code
 * (pfbench.mcu.modelcode) calls when a model function allocates arrays, on newlib's malloc.
 *
 * numba's IR was generated for a 64-bit host, so its "intp"/size_t arguments are 64-bit
 * (int64_t here) and its MemInfo is the LLVM struct {i64 refct, ptr dtor, ptr dtor_info,
 * ptr data, i64 size}; with the ARM data layout (i64 8-aligned, 32-bit pointers) that is the
 * C struct below (data at offset 16).  Reference counting itself (NRT_incref/NRT_decref) is
 * compiled into the model object; its atomic read-modify-writes are lowered to plain loads and
 * stores there, which is correct because the filter is single-threaded and no interrupt
 * handler touches a model's arrays.
 *
 * Also here: numba's BLAS entry points for matrix products (`@`, np.dot) on contiguous float or
 * double arrays, as plain loops (column-major, as numba calls them).  pfbench.mcu.modelcode
 * compiles its own copies of these into the model object (inlined, specialised per call site);
 * these C versions serve objects compiled without them.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef void (*nrt_dtor)(void *ptr, int64_t size, void *info);

typedef struct {
    int64_t refct;
    nrt_dtor dtor;
    void *dtor_info;
    void *data;
    int64_t size;
} NRT_MemInfo;

void *NRT_Allocate(int64_t size) { return malloc((size_t)size); }

void NRT_Free(void *ptr) { free(ptr); }

/* One block: [MemInfo][padding][data aligned to `align`].
 *
 * Freed blocks are kept on a free list and reused for the next request of the same size and
 * alignment instead of going back to malloc/free: a model function allocates the same few
 * temporaries (one per array expression, sized by the tile) on every call, so after the first
 * tile every allocation is a short list search (newlib's malloc + free cost ~140 cycles a pair
 * on a Cortex-M4; this ~20).  The list holds at most NRT_CACHE_MAX blocks (beyond that, free()),
 * so the memory kept is bounded by the peak of live temporaries.  On a free-listed block the
 * MemInfo's dtor_info field links it (a block is reused only if its data pointer has the
 * requested alignment). */
#ifndef NRT_CACHE_MAX
#define NRT_CACHE_MAX 64
#endif
static NRT_MemInfo *nrt_free_list;
static int nrt_free_count;

NRT_MemInfo *NRT_MemInfo_alloc_aligned(int64_t size, uint32_t align)
{
    if (align < 8)
        align = 8;
    NRT_MemInfo **link = &nrt_free_list;
    for (NRT_MemInfo *mi = nrt_free_list; mi; link = (NRT_MemInfo **)&mi->dtor_info,
                     mi = (NRT_MemInfo *)mi->dtor_info) {
        if (mi->size == size && !((uintptr_t)mi->data & (align - 1))) {
            *link = (NRT_MemInfo *)mi->dtor_info;
            nrt_free_count--;
            mi->refct = 1;
            mi->dtor = 0;
            mi->dtor_info = 0;
            return mi; /* data pointer and size unchanged */
        }
    }
    size_t total = sizeof(NRT_MemInfo) + (size_t)size + align;
    char *base = (char *)malloc(total);
    if (!base)
        return 0;
    NRT_MemInfo *mi = (NRT_MemInfo *)base;
    uintptr_t data = (uintptr_t)(base + sizeof(NRT_MemInfo));
    data = (data + align - 1) & ~(uintptr_t)(align - 1);
    mi->refct = 1;
    mi->dtor = 0;
    mi->dtor_info = 0;
    mi->data = (void *)data;
    mi->size = size;
    return mi;
}

NRT_MemInfo *NRT_MemInfo_alloc_safe_aligned(int64_t size, uint32_t align)
{
    return NRT_MemInfo_alloc_aligned(size, align);
}

NRT_MemInfo *NRT_MemInfo_alloc(int64_t size) { return NRT_MemInfo_alloc_aligned(size, 8); }

NRT_MemInfo *NRT_MemInfo_alloc_safe(int64_t size) { return NRT_MemInfo_alloc_aligned(size, 8); }

void NRT_MemInfo_call_dtor(NRT_MemInfo *mi)
{
    if (mi->dtor)
        mi->dtor(mi->data, mi->size, mi->dtor_info);
    if (nrt_free_count >= NRT_CACHE_MAX) {
        free(mi);
        return;
    }
    mi->dtor_info = nrt_free_list;
    nrt_free_list = mi;
    nrt_free_count++;
}

/* numba_xxgemm(kind, transa, transb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc): the
 * column-major BLAS ?gemm, C = alpha op(A) op(B) + beta C, kind 's' (float) or 'd' (double). */
#define GEMM_BODY(T)                                                                          \
    {                                                                                         \
        const T *A = (const T *)a, *B = (const T *)b;                                         \
        T *C = (T *)c, al = *(const T *)alpha, be = *(const T *)beta;                         \
        for (int64_t j = 0; j < n; j++)                                                       \
            for (int64_t i = 0; i < m; i++) {                                                 \
                T s = 0;                                                                      \
                for (int64_t l = 0; l < k; l++) {                                             \
                    T av = (transa == 'n' || transa == 'N') ? A[i + l * lda] : A[l + i * lda]; \
                    T bv = (transb == 'n' || transb == 'N') ? B[l + j * ldb] : B[j + l * ldb]; \
                    s += av * bv;                                                             \
                }                                                                             \
                C[i + j * ldc] = al * s + (be == 0 ? (T)0 : be * C[i + j * ldc]);             \
            }                                                                                 \
    }

int numba_xxgemm(char kind, char transa, char transb, int64_t m, int64_t n, int64_t k,
                 const void *alpha, const void *a, int64_t lda, const void *b, int64_t ldb,
                 const void *beta, void *c, int64_t ldc)
{
    if (kind == 's')
        GEMM_BODY(float)
    else if (kind == 'd')
        GEMM_BODY(double)
    else
        return -1;
    return 0;
}

/* numba_xxgemv(kind, trans, m, n, alpha, a, lda, x, beta, y): column-major ?gemv with unit
 * strides, y = alpha op(A) x + beta y. */
#define GEMV_BODY(T)                                                                          \
    {                                                                                         \
        const T *A = (const T *)a, *X = (const T *)x;                                         \
        T *Y = (T *)y, al = *(const T *)alpha, be = *(const T *)beta;                         \
        int tr = !(trans == 'n' || trans == 'N');                                             \
        int64_t rows = tr ? n : m, cols = tr ? m : n;                                         \
        for (int64_t i = 0; i < rows; i++) {                                                  \
            T s = 0;                                                                          \
            for (int64_t l = 0; l < cols; l++)                                                \
                s += (tr ? A[l + i * lda] : A[i + l * lda]) * X[l];                           \
            Y[i] = al * s + (be == 0 ? (T)0 : be * Y[i]);                                     \
        }                                                                                     \
    }

int numba_xxgemv(char kind, char trans, int64_t m, int64_t n, const void *alpha, const void *a,
                 int64_t lda, const void *x, const void *beta, void *y)
{
    if (kind == 's')
        GEMV_BODY(float)
    else if (kind == 'd')
        GEMV_BODY(double)
    else
        return -1;
    return 0;
}

/* numba_xxdot(kind, conjugate, n, dx, dy, result): *result = dx . dy (unit strides). */
int numba_xxdot(char kind, char conjugate, int64_t n, const void *dx, const void *dy, void *result)
{
    (void)conjugate;
    if (kind == 's') {
        const float *a = (const float *)dx, *b = (const float *)dy;
        float s = 0;
        for (int64_t i = 0; i < n; i++)
            s += a[i] * b[i];
        *(float *)result = s;
    } else if (kind == 'd') {
        const double *a = (const double *)dx, *b = (const double *)dy;
        double s = 0;
        for (int64_t i = 0; i < n; i++)
            s += a[i] * b[i];
        *(double *)result = s;
    } else {
        return -1;
    }
    return 0;
}

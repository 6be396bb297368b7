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
 * Matrix products (`@`, np.dot) call numba's BLAS entry points numba_xxgemm/xxgemv/xxdot:
 * pfbench.mcu.modelcode compiles those into the model object itself (specialised per call
 * site), so they are not here.
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

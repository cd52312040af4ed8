// SPDX-License-Identifier: MIT
#include "btf/util/huge_pages.h"

#include <algorithm>
#include <cstdlib>

#ifdef __linux__
#include <sys/mman.h>
#endif

namespace btf {

void* allocate_table(size_t bytes, size_t alignment) {
    const bool huge = bytes >= kHugePageBytes;
    if (huge) alignment = std::max(alignment, kHugePageBytes);
    if (alignment < kCacheLineBytes) alignment = kCacheLineBytes;
    // aligned_alloc wants a multiple of the alignment.
    const size_t rounded = (bytes + alignment - 1) / alignment * alignment;
    if (rounded < bytes) throw std::bad_alloc();
    void* p = std::aligned_alloc(alignment, rounded == 0 ? alignment : rounded);
    if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (huge) madvise(p, rounded, MADV_HUGEPAGE);  // a hint: its failure changes nothing
#endif
    return p;
}

void free_table(void* p) noexcept {
    std::free(p);
}

}  // namespace btf

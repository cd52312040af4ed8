// SPDX-License-Identifier: MIT
#pragma once
/// Memory for tables that evaluation reads at random: the decoded code-books of mlvq, the factor
/// rows of fmf and UBO2014 materials. A random read into a table of tens of MiB misses the TLB
/// as well as the caches when the table lies on 4 KiB pages (the second-level TLB of a core
/// reaches a few MiB), and a miss costs a page walk before the read, or the prefetch that should
/// have hidden it, can start. Blocks of 2 MiB or more are therefore aligned to 2 MiB and offered
/// to the kernel for transparent huge pages (madvise MADV_HUGEPAGE, which a system with
/// `transparent_hugepage=madvise`, Debian's default, honours): one TLB entry then covers 2 MiB.
/// It is a hint; where the kernel declines, the memory is ordinary memory.

#include <cstddef>
#include <new>

namespace btf {

/// The size from which allocate_table() asks for huge pages (one huge page).
inline constexpr size_t kHugePageBytes = size_t(2) << 20;
/// The least alignment of a table: a cache line, so that a table's 64-byte records lie in
/// one line each.
inline constexpr size_t kCacheLineBytes = 64;

/// `bytes` of uninitialized memory aligned to `alignment` (a power of two; at least
/// kCacheLineBytes) and, from kHugePageBytes on, to kHugePageBytes with huge pages requested;
/// std::bad_alloc when there is none. Freed with free_table(). The first touch of a page is what
/// maps it, so a caller that fills the block right away gets the huge pages then.
void* allocate_table(size_t bytes, size_t alignment = alignof(std::max_align_t));
void free_table(void* p) noexcept;

/// A std::vector allocator over allocate_table().
template <typename T>
struct TableAllocator {
    using value_type = T;
    TableAllocator() = default;
    template <typename U>
    TableAllocator(const TableAllocator<U>&) noexcept {}
    T* allocate(size_t n) {
        if (n > size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
        return static_cast<T*>(allocate_table(n * sizeof(T), alignof(T)));
    }
    void deallocate(T* p, size_t) noexcept { free_table(p); }
    template <typename U>
    bool operator==(const TableAllocator<U>&) const noexcept {
        return true;
    }
};

}  // namespace btf

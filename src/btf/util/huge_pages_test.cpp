// SPDX-License-Identifier: MIT
#include "btf/util/huge_pages.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <numeric>
#include <vector>

namespace btf {
namespace {

uintptr_t address(const void* p) {
    return reinterpret_cast<uintptr_t>(p);
}

struct Free {
    void operator()(void* p) const { free_table(p); }
};

// Small blocks start on a cache line (or the alignment asked for, if larger), blocks of a huge
// page or more on a huge page, and every byte asked for can be written (a sanitizer build checks
// the bounds).
TEST(HugePages, BlocksAreAlignedAndWholeSize) {
    for (const size_t alignment : {size_t(1), size_t(4), size_t(256)}) {
        const std::unique_ptr<void, Free> p(allocate_table(100, alignment));
        EXPECT_EQ(address(p.get()) % std::max(alignment, kCacheLineBytes), 0u) << alignment;
    }
    for (const size_t bytes : {size_t(0), size_t(1), size_t(100), size_t(4096)}) {
        const std::unique_ptr<void, Free> p(allocate_table(bytes, 64));
        ASSERT_NE(p, nullptr) << bytes;
        EXPECT_EQ(address(p.get()) % 64, 0u) << bytes;
        std::memset(p.get(), 0x5a, bytes);
    }
    for (const size_t bytes : {kHugePageBytes, kHugePageBytes + 12345, 3 * kHugePageBytes}) {
        const std::unique_ptr<void, Free> p(allocate_table(bytes, 64));
        ASSERT_NE(p, nullptr) << bytes;
        EXPECT_EQ(address(p.get()) % kHugePageBytes, 0u) << bytes;
        std::memset(p.get(), 0x5a, bytes);
        EXPECT_EQ(static_cast<const unsigned char*>(p.get())[bytes - 1], 0x5a);
    }
}

// A vector over TableAllocator behaves as one over std::allocator: values, growth, copies.
TEST(HugePages, VectorsOverTheAllocatorHoldTheirValues) {
    std::vector<float, TableAllocator<float>> v(kHugePageBytes / sizeof(float) + 7);
    EXPECT_EQ(address(v.data()) % kHugePageBytes, 0u);
    EXPECT_EQ(v.front(), 0.0f);
    EXPECT_EQ(v.back(), 0.0f);
    std::iota(v.begin(), v.end(), 0.0f);
    v.push_back(-1);
    const std::vector<float, TableAllocator<float>> copy = v;
    ASSERT_EQ(copy.size(), kHugePageBytes / sizeof(float) + 8);
    EXPECT_EQ(copy[1000], 1000.0f);
    EXPECT_EQ(copy.back(), -1.0f);
    std::vector<uint64_t, TableAllocator<uint64_t>> small = {1, 2, 3};
    EXPECT_EQ(small[2], 3u);
    EXPECT_EQ(address(small.data()) % kCacheLineBytes, 0u);
}

TEST(HugePages, ImpossibleSizesThrowBadAlloc) {
    EXPECT_THROW(allocate_table(size_t(-1) - 10, 64), std::bad_alloc);
    TableAllocator<double> a;
    EXPECT_THROW(a.allocate(size_t(-1) / 4), std::bad_alloc);
}

}  // namespace
}  // namespace btf

// SPDX-License-Identifier: MIT
#include "btf/util/range_coder.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "btf/testing/support.h"

namespace btf::range {
namespace {

// Worked by hand. No bits: the five flushing shifts each write a 0. One 1-bit at p = 1024 (one
// half): bound = (2³² − 1 >> 11) · 1024 = 0x7FFFFC00 becomes the low end. The flush then writes
// the held byte 00, holds 7F, holds FF (low 0xFFFC0000 could still carry into it), writes 7F FF
// when low 0xFC000000 cannot, and finally FC and 00.
TEST(RangeCoder, GoldenBytesWorkedByHand) {
    EXPECT_EQ(Encoder().finish(), (std::vector<uint8_t>{0, 0, 0, 0, 0}));
    Encoder one;
    uint16_t p = kHalf;
    one.bit(p, 1);
    EXPECT_EQ(p, 1024 - 32);
    const std::vector<uint8_t> bytes = one.finish();
    EXPECT_EQ(bytes, (std::vector<uint8_t>{0x00, 0x7F, 0xFF, 0xFC, 0x00}));
    Decoder d(bytes.data(), bytes.size(), "x");
    uint16_t q = kHalf;
    EXPECT_EQ(d.bit(q), 1);
    EXPECT_EQ(q, p);
    EXPECT_EQ(d.remaining(), 0u);
}

// Integers of every size in several contexts, skewed bits and direct bits: decoded as written,
// every byte read. Long runs of likely bits make the low end carry into held 0xFF bytes.
TEST(RangeCoder, RoundTripsIntegersAndBits) {
    std::mt19937_64 rng(5);
    std::vector<int64_t> values;
    for (int i = 0; i < 20000; ++i) {
        const int bits = int(rng() % 63);
        int64_t v = int64_t(rng() >> (64 - std::max(bits, 1)));
        if (rng() % 3 == 0) v = 0;
        values.push_back(rng() % 2 ? v : -v);
    }
    values.push_back(std::numeric_limits<int64_t>::max());
    values.push_back(-std::numeric_limits<int64_t>::max());
    std::vector<int> skewed;
    for (int i = 0; i < 50000; ++i) skewed.push_back(rng() % 50 == 0);

    Encoder e;
    IntegerModel model(4);
    uint16_t p = kHalf;
    for (size_t i = 0; i < values.size(); ++i) model.put(e, int(i % 4), values[i]);
    for (const int b : skewed) e.bit(p, b);
    e.direct(0x123456789abcdef0ull, 64);
    const std::vector<uint8_t> bytes = e.finish();

    Decoder d(bytes.data(), bytes.size(), "x");
    IntegerModel read(4);
    uint16_t q = kHalf;
    for (size_t i = 0; i < values.size(); ++i) ASSERT_EQ(read.get(d, int(i % 4)), values[i]) << i;
    for (size_t i = 0; i < skewed.size(); ++i) ASSERT_EQ(d.bit(q), skewed[i]) << i;
    EXPECT_EQ(d.direct(64), 0x123456789abcdef0ull);
    EXPECT_EQ(d.remaining(), 0u);
    // Alone, the skewed bits (1 in 50: 0.14 bits of information each) cost far less than a bit.
    Encoder alone;
    uint16_t r = kHalf;
    for (const int b : skewed) alone.bit(r, b);
    EXPECT_LT(alone.finish().size(), skewed.size() / 8 / 4);
}

TEST(RangeCoder, DamagedBytesAreErrors) {
    const std::vector<uint8_t> four = {0, 0, 0, 0};
    EXPECT_EQ(test::error_of([&] { Decoder(four.data(), four.size(), "section 'x'"); }),
              "section 'x': the coded factors end early");
    // All ones: the zero flag and then every unary bit of the class read 1.
    const std::vector<uint8_t> ones(64, 0xff);
    Decoder d(ones.data(), ones.size(), "section 'x'");
    IntegerModel model(1);
    EXPECT_EQ(test::error_of([&] { model.get(d, 0); }),
              "section 'x': a coded value is longer than 64 bits");
}

}  // namespace
}  // namespace btf::range

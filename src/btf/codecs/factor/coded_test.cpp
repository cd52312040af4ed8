#include "btf/codecs/factor/coded.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "btf/testing/support.h"
#include "btf/util/error.h"
#include "btf/util/range_coder.h"

namespace btf::factor::coded {
namespace {

std::vector<uint8_t> encode(const std::vector<float>& a, const std::vector<float>& b, Image image,
                            double step) {
    std::vector<uint8_t> out;
    put_component(out, {a.data(), int64_t(a.size()), 1}, {b.data(), int64_t(b.size()), 1}, image,
                  step);
    return out;
}

void decode(const std::vector<uint8_t>& bytes, std::vector<float>& a, std::vector<float>& b,
            Image image) {
    get_component(bytes.data(), bytes.size(), {a.data(), int64_t(a.size()), 1},
                  {b.data(), int64_t(b.size()), 1}, image, "b0.k0");
}

float step_of(const std::vector<uint8_t>& bytes, int side) {
    float s;
    std::memcpy(&s, bytes.data() + 4 + 4 * side, 4);
    return s;
}

// Worked by hand: b a constant 2 over one 8 × 8 block, a = (1, 1.5, 2.5, 3), Δ = 1.
//   a's step Δ / rms(b) = 0.5, so codes 2, 3, 5, 6; the differences 2, 1, 2, 1 (distance 1: 4
//   rows allow no channel prediction, and the smallest values code shortest).
//   b's step Δ / rms(a) = 1 / √4.625; the block's DCT is 8 · 2 = 16 at DC and 0 elsewhere, so
//   DC codes to ⌊16 √4.625 + 1/3⌋ = 34, and the 63 other bands are zeros.
// The head is format 2, distance 1, DCT texels, 0, then the two steps; the payload is those
// integers through the range coder's model in their streams (a: 0; DC: 3; band k: 4 + its
// zig-zag diagonal), whose own bytes util/range_coder_test.cpp pins.
const std::vector<float> kWorkedA = {1.0f, 1.5f, 2.5f, 3.0f}, kWorkedB(64, 2.0f);
const float kWorkedSteps[2] = {0.5f, float(1.0 / std::sqrt(4.625))};

std::vector<uint8_t> worked_head(uint8_t format) {
    std::vector<uint8_t> head = {format, 1, 1, 0};
    const auto* s = reinterpret_cast<const uint8_t*>(kWorkedSteps);
    head.insert(head.end(), s, s + 8);
    return head;
}

void expect_worked_values(const std::vector<uint8_t>& bytes) {
    std::vector<float> a2(4), b2(64);
    decode(bytes, a2, b2, {8, 8});
    EXPECT_EQ(a2, (std::vector<float>{1.0f, 1.5f, 2.5f, 3.0f}));
    // Decoded values are half floats.
    const double dc = 34 * kWorkedSteps[1] / 8;
    for (const float v : b2) EXPECT_NEAR(v, dc, std::ldexp(dc, -11));
}

TEST(CodedComponent, GoldenBytesOfAWorkedExample) {
    const std::vector<uint8_t> bytes = encode(kWorkedA, kWorkedB, {8, 8}, 1.0);
    std::vector<uint8_t> expected = worked_head(2);
    range::Encoder coder;
    range::IntegerModel model(13);
    for (const int v : {2, 1, 2, 1}) model.put(coder, 0, v);
    model.put(coder, 3, 34);
    const int diagonal_start[8] = {1, 3, 6, 10, 15, 21, 28, 36};
    for (int k = 1; k < 64; ++k) {
        int group = 0;
        while (group < 8 && k >= diagonal_start[group]) ++group;
        model.put(coder, 4 + group, 0);
    }
    const std::vector<uint8_t> payload = coder.finish();
    expected.insert(expected.end(), payload.begin(), payload.end());
    EXPECT_EQ(bytes, expected);
    expect_worked_values(bytes);
}

// Format 1 (varints for the container's zstd), still read: the same example as the first coded
// packages wrote it: the differences 2, 1, 2, 1 as the zig-zag varints 4, 2, 4, 2, DC 34 as 68 =
// 0x44, then 63 zeros.
TEST(CodedComponent, FormatOneIsStillRead) {
    std::vector<uint8_t> bytes = worked_head(1);
    for (const uint8_t v : {4, 2, 4, 2, 0x44}) bytes.push_back(v);
    bytes.resize(bytes.size() + 63, 0);
    expect_worked_values(bytes);
}

// Random factors: a within half its step of the original, b (an image, also one whose sides are
// not multiples of 8, or plain values) within kImageErrorPerStep steps (half a step when plain),
// each plus the rounding to a half float (relative 2⁻¹¹).
TEST(CodedComponent, DecodedFactorsStayWithinTheirSteps) {
    std::mt19937 rng(3);
    std::normal_distribution<float> normal;
    struct Case {
        int64_t rows;
        Image image;
        int64_t texels;
    };
    for (const Case c : {Case{243, {16, 16}, 256}, Case{81, {13, 6}, 78}, Case{30, {}, 57}}) {
        std::vector<float> a(size_t(c.rows)), b(size_t(c.texels));
        for (float& v : a) v = normal(rng);
        // A smooth image plus noise, as eigen-textures are.
        for (int64_t t = 0; t < c.texels; ++t)
            b[size_t(t)] = 3.0f * std::sin(0.3f * float(t)) + 0.2f * normal(rng);
        for (const double step : {0.05, 0.5}) {
            const std::vector<uint8_t> bytes = encode(a, b, c.image, step);
            std::vector<float> a2(a.size()), b2(b.size());
            decode(bytes, a2, b2, c.image);
            const double sa = step_of(bytes, 0), sb = step_of(bytes, 1);
            const double b_bound = (c.image.width > 0 ? kImageErrorPerStep : 0.5) * sb * 1.0001;
            double worst_a = 0, worst_b = 0;
            for (size_t i = 0; i < a.size(); ++i)
                worst_a = std::max(
                    worst_a, std::abs(a2[i] - a[i]) /
                                 (0.5 * sa * 1.0001 + std::ldexp(std::abs(a2[i]), -11) + 3e-8));
            for (size_t i = 0; i < b.size(); ++i)
                worst_b = std::max(worst_b, double(std::abs(b2[i] - b[i])));
            EXPECT_LE(worst_a, 1.0) << c.rows << " " << step;
            double largest = 0;
            for (const float v : b2) largest = std::max(largest, double(std::abs(v)));
            EXPECT_LE(worst_b, b_bound + std::ldexp(largest, -11)) << c.texels << " " << step;
            EXPECT_GT(worst_b, 0.0) << "quantization changed nothing";
        }
    }
}

TEST(CodedComponent, DamagedPayloadsAreErrors) {
    const std::vector<float> a = {1.0f, 1.5f, 2.5f, 3.0f}, b(64, 2.0f);
    const std::vector<uint8_t> good = encode(a, b, {8, 8}, 1.0);
    std::vector<float> a2(4), b2(64);
    auto error = [&](std::vector<uint8_t> bytes, Image image = {8, 8}) {
        return test::error_of([&] { decode(bytes, a2, b2, image); });
    };
    EXPECT_EQ(error({1, 1, 1}), "section 'b0.k0': 3 bytes, shorter than a coded component's head");
    std::vector<uint8_t> bad = good;
    bad[0] = 9;
    EXPECT_EQ(error(bad), "section 'b0.k0': unknown coded format 9");
    bad = good;
    bad[1] = 0;  // channel prediction: a has 4 rows, not rows of 3 channels
    EXPECT_EQ(error(bad), "section 'b0.k0': prediction distance 0");
    bad[1] = 65;
    EXPECT_EQ(error(bad), "section 'b0.k0': prediction distance 65");
    bad = good;
    bad[2] = 5;
    EXPECT_EQ(error(bad), "section 'b0.k0': unknown texel coding 5");
    EXPECT_EQ(error(good, {}),
              "section 'b0.k0': DCT-coded texels, but the block's texels are not an image");
    bad = good;
    const float nan = NAN;
    std::memcpy(bad.data() + 8, &nan, 4);
    EXPECT_EQ(error(bad), "section 'b0.k0': quantization step nan");
    bad = good;
    bad.pop_back();
    EXPECT_EQ(error(bad), "section 'b0.k0': the coded factors end early");
    bad = good;
    bad.push_back(0);
    EXPECT_EQ(error(bad), "section 'b0.k0': 1 bytes after the coded factors");
    // A payload of 0xff bytes: the first value's zero flag and unary class read ones on and on.
    bad = worked_head(2);
    bad.resize(bad.size() + 64, 0xff);
    EXPECT_EQ(error(bad), "section 'b0.k0': a coded value is longer than 64 bits");
    // Format 1's varints keep their own errors.
    bad = worked_head(1);
    bad.insert(bad.end(), 10, 0xff);
    EXPECT_EQ(error(bad), "section 'b0.k0': a coefficient is longer than 64 bits");
    bad = worked_head(1);
    bad[1] = 0;  // no channel prediction in format 1
    bad.insert(bad.end(), 68, 0);
    EXPECT_EQ(error(bad), "section 'b0.k0': prediction distance 0");
}

}  // namespace
}  // namespace btf::factor::coded

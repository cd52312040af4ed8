// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/coded.h"

#include <fmt/format.h>
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

const std::vector<float> kWorkedA = {1.0f, 1.5f, 2.5f, 3.0f}, kWorkedB(64, 2.0f);

// Worked by hand: b a constant 2 over one 8 × 8 block, a = (1, 1.5, 2.5, 3), Δ = 1 / κ
// (kAngularStepScale).
//   a's step κ Δ / rms(b) = 0.5, so codes 2, 3, 5, 6; the differences 2, 1, 2, 1 (distance 1: 4
//   rows allow no channel prediction, and the smallest values code shortest).
//   b's step Δ / rms(a) = 1 / (κ √4.625); the block's DCT is 8 · 2 = 16 at DC and 0 elsewhere, so
//   DC codes to ⌊16 κ √4.625 + 1/3⌋ = ⌊12.04 + 1/3⌋ = 12, and the 63 other bands are zeros.
// The head is format 2, distance 1, DCT texels, 0, then the two steps; the payload is those
// integers through the range coder's model in their streams (a: 0; DC: 3; band k: 4 + its
// zig-zag diagonal), whose own bytes util/range_coder_test.cpp pins.
TEST(CodedComponent, GoldenBytesOfAWorkedExample) {
    const double delta = 1 / kAngularStepScale;
    ASSERT_EQ(kAngularStepScale, 0.35) << "the example's DC code below is worked out for κ = 0.35";
    const std::vector<uint8_t> bytes = encode(kWorkedA, kWorkedB, {8, 8}, delta);
    const float steps[2] = {0.5f, float(delta / std::sqrt(4.625))};
    std::vector<uint8_t> expected = {2, 1, 1, 0};
    const auto* s = reinterpret_cast<const uint8_t*>(steps);
    expected.insert(expected.end(), s, s + 8);
    range::Encoder coder;
    range::IntegerModel model(13);
    for (const int v : {2, 1, 2, 1}) model.put(coder, 0, v);
    model.put(coder, 3, 12);
    const int diagonal_start[8] = {1, 3, 6, 10, 15, 21, 28, 36};
    for (int k = 1; k < 64; ++k) {
        int group = 0;
        while (group < 8 && k >= diagonal_start[group]) ++group;
        model.put(coder, 4 + group, 0);
    }
    const std::vector<uint8_t> payload = coder.finish();
    expected.insert(expected.end(), payload.begin(), payload.end());
    EXPECT_EQ(bytes, expected);
    std::vector<float> a2(4), b2(64);
    decode(bytes, a2, b2, {8, 8});
    EXPECT_EQ(a2, kWorkedA);
    const double dc = 12 * steps[1] / 8;  // decoded values are half floats
    for (const float v : b2) EXPECT_NEAR(v, dc, std::ldexp(dc, -11));
}

// The example as the first coded packages wrote it (a's step Δ / rms(b), Δ = 1: a's steps 0.5, b's
// 1 / √4.625, DC ⌊16 √4.625 + 1/3⌋ = 34), for the readers' tests below.
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
    EXPECT_EQ(a2, kWorkedA);
    // Decoded values are half floats.
    const double dc = 34 * kWorkedSteps[1] / 8;
    for (const float v : b2) EXPECT_NEAR(v, dc, std::ldexp(dc, -11));
}

// Format 1 (varints for the container's zstd), still read: the differences 2, 1, 2, 1 as the
// zig-zag varints 4, 2, 4, 2, DC 34 as 68 = 0x44, then 63 zeros.
TEST(CodedComponent, FormatOneIsStillRead) {
    std::vector<uint8_t> bytes = worked_head(1);
    for (const uint8_t v : {4, 2, 4, 2, 0x44}) bytes.push_back(v);
    bytes.resize(bytes.size() + 63, 0);
    expect_worked_values(bytes);
}

// Prediction by neighbouring directions, worked by hand: a of 2 views × 3 lights × 1 channel with
// step 0.5 and codes (−1, 1, 4; −2, 5, 6); b one plain value, code 3 at step 0.25. Each code is
// predicted by the floor of the mean of the previous light's and the previous view's, or the one
// of them there is: −1 (first pair), 1 − (−1) = 2, 4 − 1 = 3, −2 − (−1) = −1 (first light: the
// view above), 5 − ⌊(−2 + 1) / 2⌋ = 5 − (−1) = 6 (the floor, not the truncation), 6 − ⌊(5 + 4)
// / 2⌋ = 2. The head is format 2, prediction 128, plain texels at distance 1, the steps; a's
// differences go to stream 0, b's to stream 2. web/test/unit.test.mjs reads the same bytes.
const std::vector<uint8_t> kNeighbourExample = {
    0x02, 0x80, 0x00, 0x01, 0x00, 0x00, 0x00, 0x3f, 0x00, 0x00, 0x80, 0x3e,
};

TEST(CodedComponent, PredictionByNeighbouringDirectionsWorkedExample) {
    std::vector<uint8_t> bytes = kNeighbourExample;
    range::Encoder coder;
    range::IntegerModel model(13);
    for (const int v : {-1, 2, 3, -1, 6, 2}) model.put(coder, 0, v);
    model.put(coder, 2, 3);
    const std::vector<uint8_t> payload = coder.finish();
    bytes.insert(bytes.end(), payload.begin(), payload.end());
    std::string hex;
    for (const uint8_t v : payload) hex += fmt::format("{:02x} ", v);
    EXPECT_EQ(hex, "00 d4 ac 12 69 81 a0 40 00 ");  // the bytes the viewer's test reads
    std::vector<float> a(6), b(1);
    get_component(bytes.data(), bytes.size(), {a.data(), 6, 1}, {b.data(), 1, 1}, {}, "b0.k0",
                  {3, 1});
    EXPECT_EQ(a, (std::vector<float>{-0.5f, 0.5f, 2.0f, -1.0f, 2.5f, 3.0f}));
    EXPECT_EQ(b, std::vector<float>{0.75f});
    // The prediction needs the rows' layout, and format 2.
    EXPECT_EQ(test::error_of([&] {
                  get_component(bytes.data(), bytes.size(), {a.data(), 6, 1}, {b.data(), 1, 1}, {},
                                "b0.k0");
              }),
              "section 'b0.k0': prediction by neighbouring directions, but the factor's rows are "
              "not laid out by directions");
    EXPECT_EQ(test::error_of([&] {
                  get_component(bytes.data(), bytes.size(), {a.data(), 6, 1}, {b.data(), 1, 1}, {},
                                "b0.k0", {4, 1});
              }),
              "section 'b0.k0': prediction by neighbouring directions, but the factor's rows are "
              "not laid out by directions");
    bytes[0] = 1;
    EXPECT_EQ(test::error_of([&] {
                  get_component(bytes.data(), bytes.size(), {a.data(), 6, 1}, {b.data(), 1, 1}, {},
                                "b0.k0", {3, 1});
              }),
              "section 'b0.k0': prediction by neighbouring directions in format 1");
}

// An angular factor smooth over views and lights (rgb, 9 × 9 directions) is coded by its
// neighbouring directions when the layout is known, shorter than along the rows alone, and
// decodes within half a step.
// a as images of directions (prediction 129), worked by hand: 8 views × 8 lights × 3 channels,
// c₁ = 0.5, c₀ = 0.75, c₂ = 0 everywhere, s_a = 0.5; b one value 0.75 (plain, distance 1, s_b =
// 0.25). The planes are c₁ = 0.5, c₀ − c₁ = 0.25 and c₂ − c₁ = −0.5, each one 8 × 8 block whose
// orthonormal DCT is 8 × the value at DC and 0 elsewhere: DC codes 8, 4 and −8 (stream 13, as
// differences along the one block), the 63 other bands zeros (stream 14 + the band's zig-zag
// diagonal); then b's code 3 in stream 2.
const std::vector<uint8_t> kDirectionImagesExample = {
    0x02, 0x81, 0x00, 0x01, 0x00, 0x00, 0x00, 0x3f, 0x00, 0x00, 0x80, 0x3e,
};

int band_group_of(int k) {
    int group = 1;
    for (const int start : {3, 6, 10, 15, 21, 28, 36})
        if (k >= start) ++group;
    return group;
}

TEST(CodedComponent, AngularImagesWorkedExample) {
    std::vector<uint8_t> bytes = kDirectionImagesExample;
    range::Encoder coder;
    range::IntegerModel model(23);
    for (const int dc : {8, 4, -8}) {
        model.put(coder, 13, dc);
        for (int k = 1; k < 64; ++k) model.put(coder, 14 + band_group_of(k), 0);
    }
    model.put(coder, 2, 3);
    const std::vector<uint8_t> payload = coder.finish();
    bytes.insert(bytes.end(), payload.begin(), payload.end());
    std::string hex;
    for (const uint8_t v : payload) hex += fmt::format("{:02x} ", v);
    // The bytes the viewer's test reads.
    EXPECT_EQ(hex, "00 b7 ff fc 00 00 00 00 39 91 d8 00 01 18 ba 4f 00 f0 20 f0 00 ");
    std::vector<float> a(192), b(1);
    get_component(bytes.data(), bytes.size(), {a.data(), 192, 1}, {b.data(), 1, 1}, {}, "b0.k0",
                  {8, 3});
    for (int pair = 0; pair < 64; ++pair) {
        EXPECT_EQ(a[size_t(3 * pair)], 0.75f) << pair;
        EXPECT_EQ(a[size_t(3 * pair + 1)], 0.5f) << pair;
        EXPECT_EQ(a[size_t(3 * pair + 2)], 0.0f) << pair;
    }
    EXPECT_EQ(b, std::vector<float>{0.75f});
    // The images need the rows' layout, and format 2.
    EXPECT_EQ(test::error_of([&] {
                  get_component(bytes.data(), bytes.size(), {a.data(), 192, 1}, {b.data(), 1, 1},
                                {}, "b0.k0");
              }),
              "section 'b0.k0': a as images of directions, but the factor's rows are not laid "
              "out by directions");
    bytes[0] = 1;
    EXPECT_EQ(test::error_of([&] {
                  get_component(bytes.data(), bytes.size(), {a.data(), 192, 1}, {b.data(), 1, 1},
                                {}, "b0.k0", {8, 3});
              }),
              "section 'b0.k0': a as images of directions in format 1");
}

TEST(CodedComponent, SmoothAngularFactorsArePredictedByNeighbours) {
    const int views = 9, lights = 9;
    std::vector<float> a(size_t(views * lights * 3)), b(64);
    for (int v = 0; v < views; ++v)
        for (int l = 0; l < lights; ++l)
            for (int c = 0; c < 3; ++c)
                a[size_t((v * lights + l) * 3 + c)] = std::sin(0.4f * float(v)) *
                                                      std::cos(0.3f * float(l)) *
                                                      (1.0f + 0.2f * float(c));
    for (int t = 0; t < 64; ++t) b[size_t(t)] = 1.0f + 0.1f * std::sin(float(t));
    std::vector<uint8_t> by_rows, by_directions;
    put_component(by_rows, {a.data(), int64_t(a.size()), 1}, {b.data(), 64, 1}, {8, 8}, 0.002);
    put_component(by_directions, {a.data(), int64_t(a.size()), 1}, {b.data(), 64, 1}, {8, 8}, 0.002,
                  nullptr, {lights, 3});
    // By neighbouring directions (128) or as images of directions (129), whichever costs less.
    const int prediction = by_directions[1];
    ASSERT_TRUE(prediction == 128 || prediction == 129) << prediction;
    EXPECT_LT(by_rows[1], 128);
    EXPECT_LT(by_directions.size(), by_rows.size());
    std::vector<float> a2(a.size()), b2(64);
    get_component(by_directions.data(), by_directions.size(), {a2.data(), int64_t(a2.size()), 1},
                  {b2.data(), 64, 1}, {8, 8}, "b0.k0", {lights, 3});
    // Rounding: half a step; images: kImageErrorPerStep steps per plane, an outer channel being
    // its offset plus the middle one.
    const double sa = step_of(by_directions, 0);
    const double bound = prediction == 128 ? 0.5 * sa : 2 * kImageErrorPerStep * sa;
    for (size_t i = 0; i < a.size(); ++i)
        EXPECT_LE(std::abs(a2[i] - a[i]), bound * 1.0001 + std::ldexp(std::abs(a2[i]), -11)) << i;
}

// At a coarse step, a smooth angular factor costs less as images of directions, whose dead zone
// drops the detail the step cannot hold, than rounded value by value.
TEST(CodedComponent, SmoothAngularFactorsAtACoarseStepAreCodedAsImages) {
    const int views = 16, lights = 16;
    std::vector<float> a(size_t(views * lights * 3)), b(64);
    std::mt19937 rng(3);
    std::normal_distribution<float> noise(0.0f, 0.02f);
    for (int v = 0; v < views; ++v)
        for (int l = 0; l < lights; ++l)
            for (int c = 0; c < 3; ++c)
                a[size_t((v * lights + l) * 3 + c)] = std::sin(0.2f * float(v)) *
                                                          std::cos(0.15f * float(l)) *
                                                          (1.0f + 0.2f * float(c)) +
                                                      noise(rng);
    for (int t = 0; t < 64; ++t) b[size_t(t)] = 1.0f + 0.1f * std::sin(float(t));
    std::vector<uint8_t> bytes;
    put_component(bytes, {a.data(), int64_t(a.size()), 1}, {b.data(), 64, 1}, {8, 8}, 0.05, nullptr,
                  {lights, 3});
    EXPECT_EQ(bytes[1], 129);
    std::vector<float> a2(a.size()), b2(64);
    get_component(bytes.data(), bytes.size(), {a2.data(), int64_t(a2.size()), 1},
                  {b2.data(), 64, 1}, {8, 8}, "b0.k0", {lights, 3});
    double error = 0, energy = 0;
    const double bound = 2 * kImageErrorPerStep * step_of(bytes, 0);  // docs/formats.md
    for (size_t i = 0; i < a.size(); ++i) {
        error += (a2[i] - a[i]) * (a2[i] - a[i]);
        energy += a[i] * a[i];
        EXPECT_LE(std::abs(a2[i] - a[i]), bound + std::ldexp(std::abs(a2[i]), -11)) << i;
    }
    EXPECT_LT(error, 0.05 * energy);  // the smooth part is kept
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

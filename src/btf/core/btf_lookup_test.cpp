// SPDX-License-Identifier: MIT
#include "btf/core/btf_lookup.h"

#include <gtest/gtest.h>

#include <random>

namespace btf {
namespace {

constexpr int kWidth = 7, kHeight = 5;

// A deterministic, non-smooth value per (texel, view, light), so that any mix-up shows.
Rgb texel_value(int x, int y, int view, int light) {
    // Unsigned arithmetic: the products wrap (a signed one would overflow).
    const uint32_t h = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u ^
                       uint32_t(view) * 83492791u ^ uint32_t(light) * 2654435761u;
    return {float(h % 1000) / 1000.0f, float((h / 1000) % 1000) / 1000.0f,
            float((h / 1000000) % 1000) / 1000.0f};
}

void expect_rgb_near(const Rgb& a, const Rgb& b, float tolerance) {
    EXPECT_NEAR(a.r, b.r, tolerance);
    EXPECT_NEAR(a.g, b.g, tolerance);
    EXPECT_NEAR(a.b, b.b, tolerance);
}

TEST(BtfLookup, ExactAtTexelCentresAndSampleDirections) {
    const DirectionSet& set = DirectionSet::ubo81();
    const AngularInterpolator interp(set);
    int calls = 0;
    auto fetch = [&](int x, int y, int v, int l) {
        ++calls;
        EXPECT_GE(x, 0);
        EXPECT_LT(x, kWidth);
        EXPECT_GE(y, 0);
        EXPECT_LT(y, kHeight);
        return texel_value(x, y, v, l);
    };
    for (int view : {0, 5, 40, 80})
        for (int light : {0, 17, 57, 70}) {
            const AngularWeights wv = interp.weights(set[view]);
            const AngularWeights wl = interp.weights(set[light]);
            for (int y = 0; y < kHeight; ++y)
                for (int x = 0; x < kWidth; ++x) {
                    const Uv uv{(x + 0.5) / kWidth, (y + 0.5) / kHeight};
                    expect_rgb_near(lookup6d(uv, kWidth, kHeight, wv, wl, fetch),
                                    texel_value(x, y, view, light), 1e-6f);
                }
        }
    EXPECT_GT(calls, 0);
}

TEST(BtfLookup, ConstantFetchGivesTheConstant) {
    // Partition of unity over space × views × lights.
    const AngularInterpolator views(DirectionSet::dome151());
    const AngularInterpolator lights(DirectionSet::ubo81());
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> uni(-3, 3);
    std::normal_distribution<double> normal;
    const Rgb constant{0.25f, 1.5f, 3.0f};
    for (int i = 0; i < 20000; ++i) {
        const Uv uv{uni(rng), uni(rng)};
        const Vec3 wo{normal(rng), normal(rng), normal(rng)};
        const Vec3 wi{normal(rng), normal(rng), normal(rng)};
        const Rgb value = lookup6d(uv, kWidth, kHeight, views.weights(wo), lights.weights(wi),
                                   [&](int, int, int, int) { return constant; });
        expect_rgb_near(value, constant, 3e-6f);
    }
}

TEST(BtfLookup, BilinearBetweenTexelsAndWrapsAround) {
    const AngularWeights one{{3, 0, 0}, {1, 0, 0}, 1};
    auto fetch = [](int x, int y, int, int) { return texel_value(x, y, 3, 3); };
    auto at = [&](double u, double v) {
        return lookup6d({u, v}, kWidth, kHeight, one, one, fetch);
    };
    auto mix = [](const Rgb& a, const Rgb& b, float t) { return a * (1 - t) + b * t; };
    const double yc = 2.5 / kHeight;  // centre of row 2
    // Halfway between texel columns 1 and 2.
    expect_rgb_near(at(2.0 / kWidth, yc),
                    mix(texel_value(1, 2, 3, 3), texel_value(2, 2, 3, 3), 0.5f), 1e-6f);
    // A quarter of the way.
    expect_rgb_near(at(1.75 / kWidth, yc),
                    mix(texel_value(1, 2, 3, 3), texel_value(2, 2, 3, 3), 0.25f), 1e-6f);
    // u = 0 and u = 1 lie halfway between the last and the first column, and agree.
    const Rgb edge = mix(texel_value(kWidth - 1, 2, 3, 3), texel_value(0, 2, 3, 3), 0.5f);
    expect_rgb_near(at(0, yc), edge, 1e-6f);
    expect_rgb_near(at(1, yc), edge, 1e-6f);
    expect_rgb_near(at(-1, yc), edge, 1e-6f);
    expect_rgb_near(at(5, yc), edge, 1e-6f);
    // Same in v, and at the corner all four wrapped texels mix equally.
    const double xc = 3.5 / kWidth;
    expect_rgb_near(at(xc, 0),
                    mix(texel_value(3, kHeight - 1, 3, 3), texel_value(3, 0, 3, 3), 0.5f), 1e-6f);
    const Rgb corner =
        (texel_value(0, 0, 3, 3) + texel_value(kWidth - 1, 0, 3, 3) +
         texel_value(0, kHeight - 1, 3, 3) + texel_value(kWidth - 1, kHeight - 1, 3, 3)) *
        0.25f;
    expect_rgb_near(at(0, 0), corner, 1e-6f);
    expect_rgb_near(at(1, 1), corner, 1e-6f);
    // Continuous across the seam: just inside each side of u = 0.
    const Rgb left = at(-1e-7, yc), right = at(1e-7, yc);
    expect_rgb_near(left, right, 1e-5f);
    // Periodic for any offset, including negative and large ones.
    std::mt19937_64 rng(2);
    std::uniform_real_distribution<double> uni(0, 1);
    for (int i = 0; i < 1000; ++i) {
        const double u = uni(rng), v = uni(rng);
        expect_rgb_near(at(u, v), at(u - 3, v + 17), 1e-5f);
    }
    // Non-finite coordinates do not escape the texture.
    const Rgb nan_value = at(NAN, INFINITY);
    EXPECT_TRUE(std::isfinite(nan_value.r));
}

TEST(BtfLookup, WeightsTheDirectionPairs) {
    // With a fetch that depends only on the direction indices, the lookup is the bilinear form
    // Σ w_v w_l f(v, l); unused entries (weight 0) are never fetched.
    const AngularWeights views{{4, 9, 2}, {0.5f, 0.3f, 0.2f}, 3};
    const AngularWeights lights{{7, 1, 0}, {0.75f, 0.25f, 0.0f}, 2};
    auto f = [](int v, int l) { return float(10 * v + l); };
    const Rgb value =
        lookup6d({0.3, 0.6}, kWidth, kHeight, views, lights, [&](int, int, int v, int l) {
            EXPECT_NE(l, 0) << "entries beyond count must not be fetched";
            return Rgb{f(v, l), 0, 0};
        });
    double expected = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 2; ++j)
            expected += views.weight[i] * lights.weight[j] * f(views.index[i], lights.index[j]);
    EXPECT_NEAR(value.r, expected, 1e-4);
}

TEST(BtfLookup, WrapLerp) {
    const WrapLerp a = wrap_lerp(0.5 / 4, 4);
    EXPECT_EQ(a.i0, 0);
    EXPECT_EQ(a.i1, 1);
    EXPECT_FLOAT_EQ(a.t, 0);
    const WrapLerp b = wrap_lerp(3.75 / 4, 4);
    EXPECT_EQ(b.i0, 3);
    EXPECT_EQ(b.i1, 0);
    EXPECT_FLOAT_EQ(b.t, 0.25f);
    const WrapLerp c = wrap_lerp(1e300, 4);
    EXPECT_GE(c.i0, 0);
    EXPECT_LT(c.i0, 4);
    const WrapLerp single = wrap_lerp(0.3, 1);
    EXPECT_EQ(single.i0, 0);
    EXPECT_EQ(single.i1, 0);
}

}  // namespace
}  // namespace btf

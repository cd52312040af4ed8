// SPDX-License-Identifier: MIT
#include "btf/synth/heightfield.h"

#include <gtest/gtest.h>

#include <cmath>

#include "btf/core/direction.h"

namespace btf::synth {
namespace {

TEST(Noise, IsPeriodicOnTheUnitSquare) {
    for (int i = 0; i < 50; ++i) {
        const double u = hash_unit(9, i, 1), v = hash_unit(9, i, 2);
        EXPECT_NEAR(noise(u, v, 5, 7, 3), noise(u + 1, v, 5, 7, 3), 1e-9);
        EXPECT_NEAR(noise(u, v, 5, 7, 3), noise(u, v - 1, 5, 7, 3), 1e-9);
        EXPECT_NEAR(fbm(u, v, 3, 2, 4, 0.5, 8), fbm(u - 1, v + 2, 3, 2, 4, 0.5, 8), 1e-9);
        const Cells a = worley(u, v, 6, 0.9, 4), b = worley(u + 1, v - 1, 6, 0.9, 4);
        EXPECT_NEAR(a.f1, b.f1, 1e-9);
        EXPECT_NEAR(a.f2, b.f2, 1e-9);
        EXPECT_EQ(a.id, b.id);
    }
}

TEST(Noise, RangeAndMean) {
    double sum = 0, lo = 1e9, hi = -1e9;
    const int n = 200;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const double v = noise((x + 0.5) / n, (y + 0.5) / n, 8, 8, 11);
            sum += v, lo = std::min(lo, v), hi = std::max(hi, v);
        }
    EXPECT_GT(lo, -1.05);
    EXPECT_LT(hi, 1.05);
    EXPECT_GT(hi - lo, 0.8);  // not degenerate
    EXPECT_NEAR(sum / (n * n), 0.0, 0.1);
    // Different seeds give different fields.
    EXPECT_NE(noise(0.3, 0.4, 8, 8, 1), noise(0.3, 0.4, 8, 8, 2));
}

TEST(Noise, WorleyDistancesAreOrdered) {
    for (int i = 0; i < 100; ++i) {
        const Cells c = worley(hash_unit(1, i), hash_unit(2, i), 10, 1.0, 5);
        EXPECT_LE(c.f1, c.f2);
        EXPECT_LT(c.f1, 1.5);
        EXPECT_GE(c.ix, 0);
        EXPECT_LT(c.ix, 10);
    }
}

TEST(Field, BilinearWrapsAndHitsTexelCentres) {
    Field f(4);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) f(x, y) = float(x + 10 * y);
    EXPECT_FLOAT_EQ(f.bilinear(2.5, 1.5), 12.0f);
    EXPECT_FLOAT_EQ(f.bilinear(2.5 + 4, 1.5 - 8), 12.0f);
    EXPECT_FLOAT_EQ(f.bilinear(3.0, 1.5), 12.5f);
    // Between the last and the first column: halfway between 3 and 0.
    EXPECT_FLOAT_EQ(f.bilinear(4.0, 0.5), 1.5f);
    EXPECT_FLOAT_EQ(f.wrapped(-1, 4), 3.0f);
}

TEST(Field, BlurKeepsTheMean) {
    Field f(16);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) f(x, y) = float(hash_unit(3, x, y));
    const Field b = blur(f, 2, 2);
    EXPECT_NEAR(b.mean(), f.mean(), 1e-5);
    EXPECT_LT(b.max() - b.min(), f.max() - f.min());
    const Field c = blur(Field(8, 0.25f), 3, 2);
    for (float v : c.values()) EXPECT_NEAR(v, 0.25f, 1e-6);
}

// A ridge along y: columns [10, 12) stand 10 texels tall on a flat floor.
Field ridge() {
    Field f(64);
    for (int y = 0; y < 64; ++y)
        for (int x = 10; x < 12; ++x) f(x, y) = 10.0f;
    return f;
}

TEST(RayQueries, FlatFieldIsFullyLitAndOpen) {
    const Field flat(16, 2.0f);
    std::vector<float> vis(256);
    light_visibility(flat, Direction::from_degrees(75, 40).vector(), radians(2), vis.data());
    for (float v : vis) EXPECT_EQ(v, 1.0f);
    const Field sky = sky_visibility(flat, 8);
    for (float v : sky.values()) EXPECT_FLOAT_EQ(v, 1.0f);
}

TEST(RayQueries, RidgeCastsAShadowAwayFromTheLight) {
    const Field f = ridge();
    std::vector<float> vis(64 * 64);
    // Light from +x at 45° elevation: the ridge shadows the 10 texels on its −x side.
    light_visibility(f, Direction::from_degrees(45, 0).vector(), radians(2), vis.data());
    for (int x : {2, 5, 8}) EXPECT_LT(vis[20 * 64 + x], 0.05f) << x;
    for (int x : {14, 30, 50}) EXPECT_GT(vis[20 * 64 + x], 0.95f) << x;
    // Light from −x: the shadow falls on the +x side instead.
    light_visibility(f, Direction::from_degrees(45, 180).vector(), radians(2), vis.data());
    for (int x : {13, 17, 20}) EXPECT_LT(vis[20 * 64 + x], 0.05f) << x;
    for (int x : {2, 5, 8, 30}) EXPECT_GT(vis[20 * 64 + x], 0.95f) << x;
    // The penumbra is soft: a texel right at the shadow's tip is partly lit.
    light_visibility(f, Direction::from_degrees(45, 0).vector(), radians(10), vis.data());
    const float tip = vis[20 * 64 + 0];  // 10.5 texels from the ridge top, 10 high: ≈ 45°
    EXPECT_GT(tip, 0.05f);
    EXPECT_LT(tip, 0.95f);
}

TEST(RayQueries, ViewHitsShowParallaxAndMasking) {
    std::vector<float> hx(64 * 64), hy(64 * 64);
    // A flat field 3 texels above the reference plane is seen shifted by 3·tan θ toward the
    // viewer's azimuth.
    const Field flat(64, 3.0f);
    view_hits(flat, Direction::from_degrees(45, 0).vector(), 0.0, hx.data(), hy.data());
    EXPECT_NEAR(hx[5 * 64 + 7], 7.5 + 3.0, 1e-3);
    EXPECT_NEAR(hy[5 * 64 + 7], 5.5, 1e-3);
    view_hits(flat, Direction::from_degrees(60, 90).vector(), 1.0, hx.data(), hy.data());
    EXPECT_NEAR(hx[5 * 64 + 7], 7.5, 1e-3);
    EXPECT_NEAR(hy[5 * 64 + 7], 5.5 + 2.0 * std::tan(radians(60)), 1e-3);
    // The zenith view sees every texel centre.
    view_hits(ridge(), Vec3{0, 0, 1}, 0.0, hx.data(), hy.data());
    EXPECT_FLOAT_EQ(hx[3 * 64 + 9], 9.5f);
    // Masking: for a viewer at +x, 45° up, the ridge hides the floor on its −x side. The ray
    // through floor texel 5 meets the ridge's +x wall first, which bilinear interpolation puts
    // between the texel centres 11.5 (height 10) and 12.5 (height 0): x − 5.5 = 10 − 10(x − 11.5)
    // at x = 130.5 / 11. Behind the ridge (x = 20) the viewer sees the floor itself.
    view_hits(ridge(), Direction::from_degrees(45, 0).vector(), 0.0, hx.data(), hy.data());
    EXPECT_NEAR(hx[20 * 64 + 5], 130.5 / 11, 1e-3);
    EXPECT_NEAR(hx[20 * 64 + 20], 20.5, 1e-3);
}

TEST(RayQueries, SkyVisibilityIsLowInAGroove) {
    Field f(32, 4.0f);
    for (int y = 0; y < 32; ++y)
        for (int x = 14; x < 17; ++x) f(x, y) = 0.0f;
    const Field sky = sky_visibility(f, 16);
    EXPECT_LT(sky(15, 10), 0.5f);
    EXPECT_NEAR(sky(3, 10), 1.0f, 1e-6);
}

}  // namespace
}  // namespace btf::synth

// SPDX-License-Identifier: MIT
#include "btf/quality/btf_cielab.h"

#include <gtest/gtest.h>

#include <cmath>

#include "btf/codecs/perceptual/csf.h"
#include "btf/core/color.h"
#include "btf/io/function_source.h"
#include "btf/quality/metrics.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::quality {
namespace {

// A smooth, coloured, angularly varying BTF: a diffuse texture with a soft highlight.
FunctionSource smooth(const Sampling& sampling, int size) {
    return FunctionSource(sampling, size, size, [sampling, size](int v, int l, int x, int y) {
        const Vec3 wi = sampling.lights.vector(l), wo = sampling.views.vector(v);
        const Vec3 h = normalize(wi + wo);
        const double spec = 0.3 * std::pow(std::max(0.0, h.z), 20.0);
        const double u = 2 * kPi * x / size, w = 2 * kPi * y / size;
        const double base = 0.25 + 0.1 * std::sin(u) * std::cos(w);
        const double c = std::max(0.0, wi.z);
        return Rgb{float((base + spec) * c), float((0.8 * base + spec) * c),
                   float((0.5 * base + spec) * c)};
    });
}

// `source` with every value scaled by 1 + amplitude·gain(view, light, x, y).
template <typename Gain>
FunctionSource scaled(const FunctionSource& source, Gain gain) {
    return FunctionSource(source.sampling(), source.width(), source.height(),
                          [&source, gain](int v, int l, int x, int y) {
                              const float g = float(gain(v, l, x, y));
                              const Rgb c = source.value(v, l, x, y);
                              return Rgb{c.r * g, c.g * g, c.b * g};
                          });
}

BtfCielabOptions small_grid(int grid = 2) {
    BtfCielabOptions o;
    o.grid = grid;
    return o;
}

TEST(BtfCielab, IdenticalInputsGiveZero) {
    const FunctionSource ref = smooth(test::ubo_subset(6, 8), 16);
    const BtfCielabResult r = btf_cielab(ref, ref, small_grid());
    ASSERT_EQ(r.values.size(), 4u);
    for (const auto& v : r.values) {
        EXPECT_EQ(v.mean, 0.0);
        EXPECT_EQ(v.rms, 0.0);
    }
}

// For uniform colour fields every filter has unit DC gain, so the measure reduces to CIEDE2000
// of the two colours (the property the paper requires of the CSF, §3.3).
TEST(BtfCielab, UniformFieldsReduceToCiede2000) {
    const Sampling sampling = test::ubo_subset(5, 6);
    const Rgb a{0.30f, 0.20f, 0.10f}, b{0.28f, 0.22f, 0.12f};
    const FunctionSource ref(sampling, 8, 8, [a](int, int, int, int) { return a; });
    const FunctionSource tst(sampling, 8, 8, [b](int, int, int, int) { return b; });
    const double expected = ciede2000(rgb_to_lab(a), rgb_to_lab(b));
    const BtfCielabResult r = btf_cielab(ref, tst, small_grid(3));
    for (const auto& v : r.values) {
        EXPECT_NEAR(v.mean, expected, 2e-3 * expected);
        EXPECT_NEAR(v.stddev, 0.0, 1e-3);
    }
}

TEST(BtfCielab, GrowsMonotonicallyWithNoise) {
    const FunctionSource ref = smooth(test::ubo_subset(6, 8), 16);
    double previous = 0;
    for (double amplitude : {0.01, 0.03, 0.1}) {
        const FunctionSource noisy = scaled(ref, [amplitude](int v, int l, int x, int y) {
            return 1 +
                   amplitude *
                       (2 * test::hash01(uint64_t(v), uint64_t(l), uint64_t(x), uint64_t(y)) - 1);
        });
        const BtfCielabResult r = btf_cielab(ref, noisy, small_grid());
        EXPECT_GT(r.headline().rms, previous) << amplitude;
        previous = r.headline().rms;
    }
}

// The paper's point: errors that flicker from one direction to the next are seen differently
// from the same errors held steady, once the eye integrates over moving light and view; a
// per-image measure cannot tell them apart. Both distortions below change every image by the
// same ±2 %, steadily (+2 % everywhere) or alternating with the light index.
TEST(BtfCielab, AngularStructureMattersWherePerImageMetricsSeeNone) {
    const Sampling sampling{
        DirectionSet::ubo81().subset({0, 1, 2, 3, 4, 5, 6}, "views"),
        DirectionSet::ubo81().subset(
            {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18}, "lights")};
    const FunctionSource ref = smooth(sampling, 16);
    const FunctionSource steady = scaled(ref, [](int, int, int, int) { return 1.02; });
    const FunctionSource flicker =
        scaled(ref, [](int, int l, int, int) { return l % 2 ? 0.98 : 1.02; });

    const Metrics m_steady = compare(ref, steady), m_flicker = compare(ref, flicker);
    EXPECT_NEAR(m_flicker.de2000_mean / m_steady.de2000_mean, 1.0, 0.05);

    BtfCielabOptions slow, fast;
    slow.conditions = {{10, 10}};
    fast.conditions = {{1000, 10}};
    const double slow_ratio = btf_cielab(ref, flicker, slow).headline().mean /
                              btf_cielab(ref, steady, slow).headline().mean;
    const double fast_ratio = btf_cielab(ref, flicker, fast).headline().mean /
                              btf_cielab(ref, steady, fast).headline().mean;
    // Slow motion: the angular filters barely reach a neighbour; both look alike.
    EXPECT_NEAR(slow_ratio, 1.0, 0.1);
    // Fast motion: the temporal low-pass averages the flicker away, not the steady offset.
    EXPECT_LT(fast_ratio, 0.6);
}

// The form of the same point: blur the BTF over the light directions (a Gaussian of
// σ = 10° on the 81 ubo81 lights, removing the highlight's angular detail) and compare it with a
// steady brightness change whose per-image mean ΔE00 is the same. Seen slowly both are equally
// visible; under fast motion the eye's band-pass response to angular (temporal) change makes the
// blur the larger error, which the per-image metric on the same frames cannot show.
TEST(BtfCielab, AngularBlurIsSeenUnderMotionBeyondItsPerImageError) {
    const Sampling sampling{DirectionSet::ubo81().subset({0, 1, 2, 3, 4, 5, 6}, "views"),
                            DirectionSet::ubo81()};
    const FunctionSource ref = smooth(sampling, 16);
    const Eigen::MatrixXd kernel = perceptual::angular_kernel(sampling.lights, 10);
    const FunctionSource blur(sampling, 16, 16, [&](int v, int l, int x, int y) {
        double r = 0, g = 0, b = 0;
        for (int j = 0; j < sampling.num_lights(); ++j) {
            const Rgb c = ref.value(v, j, x, y);
            r += kernel(l, j) * c.r;
            g += kernel(l, j) * c.g;
            b += kernel(l, j) * c.b;
        }
        return Rgb{float(r), float(g), float(b)};
    });
    const double de_blur = compare(ref, blur).de2000_mean;
    ASSERT_GT(de_blur, 0.2);
    // ΔE00 of a small steady scaling is close to linear in its size: match the blur's.
    const double unit =
        compare(ref, scaled(ref, [](int, int, int, int) { return 1.01; })).de2000_mean;
    const double amount = 0.01 * de_blur / unit;
    const FunctionSource steady = scaled(ref, [amount](int, int, int, int) { return 1 + amount; });
    EXPECT_NEAR(compare(ref, steady).de2000_mean / de_blur, 1.0, 0.03);

    BtfCielabOptions slow, fast;
    slow.conditions = {{10, 10}};
    fast.conditions = {{300, 10}};
    const double blur_slow = btf_cielab(ref, blur, slow).headline().mean;
    const double blur_fast = btf_cielab(ref, blur, fast).headline().mean;
    const double steady_slow = btf_cielab(ref, steady, slow).headline().mean;
    const double steady_fast = btf_cielab(ref, steady, fast).headline().mean;
    EXPECT_NEAR(blur_slow / steady_slow, 1.0, 0.1);
    EXPECT_GT(blur_fast / steady_fast, 1.3);
    EXPECT_GT(blur_fast / blur_slow, 1.3);      // the blur's error grows with motion…
    EXPECT_LT(steady_fast / steady_slow, 1.0);  // …the steady change's does not
}

TEST(BtfCielab, IndependentOfThreadCountAndOfSpilling) {
    const auto ref = test::cached(*synth::make("leather", 16, test::ubo_subset(5, 6), 3));
    const auto other = test::cached(*synth::make("leather", 16, test::ubo_subset(5, 6), 4));
    BtfCielabOptions options = small_grid();
    BtfCielabResult one, two;
    {
        ThreadLimit limit(1);
        one = btf_cielab(*ref, *other, options);
    }
    {
        ThreadLimit limit(2);
        two = btf_cielab(*ref, *other, options);
    }
    options.memory_bytes = 0;
    const BtfCielabResult spilled = btf_cielab(*ref, *other, options);
    EXPECT_FALSE(one.spilled);
    EXPECT_TRUE(spilled.spilled);
    ASSERT_EQ(one.values.size(), two.values.size());
    for (size_t i = 0; i < one.values.size(); ++i) {
        EXPECT_GT(one.values[i].mean, 0.0);
        EXPECT_EQ(one.values[i].mean, two.values[i].mean);
        EXPECT_EQ(one.values[i].rms, two.values[i].rms);
        EXPECT_EQ(one.values[i].mean, spilled.values[i].mean);
    }
}

TEST(BtfCielab, EightBitStoreStaysClose) {
    const auto ref = test::cached(*synth::make("leather", 16, test::ubo_subset(5, 6), 3));
    const auto other = test::cached(*synth::make("leather", 16, test::ubo_subset(5, 6), 4));
    BtfCielabOptions options = small_grid(1);
    const double sixteen = btf_cielab(*ref, *other, options).headline().mean;
    options.bits = 8;
    const double eight = btf_cielab(*ref, *other, options).headline().mean;
    EXPECT_NEAR(eight, sixteen, 0.05 * sixteen);
}

TEST(BtfCielab, SearchFindsAtLeastTheGridWorst) {
    const FunctionSource ref = smooth(test::ubo_subset(6, 8), 16);
    const FunctionSource flicker =
        scaled(ref, [](int, int l, int x, int) { return (l + x) % 2 ? 0.97 : 1.03; });
    BtfCielabOptions options = small_grid(3);
    const BtfCielabResult grid = btf_cielab(ref, flicker, options);
    options.search = true;
    const BtfCielabResult searched = btf_cielab(ref, flicker, options);
    EXPECT_TRUE(searched.searched);
    EXPECT_GT(searched.values.size(), grid.values.size());
    EXPECT_GE(searched.headline().rms, grid.headline().rms);
}

TEST(BtfCielab, RejectsMismatchesAndBadOptions) {
    const FunctionSource a = smooth(test::ubo_subset(3, 4), 8);
    const FunctionSource b = smooth(test::ubo_subset(3, 5), 8);
    const FunctionSource c = smooth(test::ubo_subset(3, 4), 16);
    EXPECT_THROW(btf_cielab(a, b), Error);
    EXPECT_THROW(btf_cielab(a, c), Error);
    BtfCielabOptions options;
    options.conditions = {{5000, 10}};
    EXPECT_NE(test::error_of([&] { btf_cielab(a, a, options); }).find("outside [10, 1000]"),
              std::string::npos);
    options.conditions = {{100, 10}};
    options.bits = 12;
    EXPECT_NE(test::error_of([&] { btf_cielab(a, a, options); }).find("use 8 or 16"),
              std::string::npos);
}

}  // namespace
}  // namespace btf::quality

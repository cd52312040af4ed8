// SPDX-License-Identifier: MIT
#include "btf/quality/metrics.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "btf/io/function_source.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/parallel.h"

namespace btf::quality {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;

// ---- CIEDE2000 ----------------------------------------------------------------------------------

TEST(Ciede2000, ReproducesSharmaWuDalalTestData) {
    const fs::path path = fs::path(BTF_SHARED_DIR) / "data" / "ciede2000_sharma2005.tsv";
    if (!fs::exists(path)) GTEST_SKIP() << path << " is absent";
    std::ifstream in(path);
    std::string line;
    int pairs = 0;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#' || line.rfind("pair", 0) == 0) continue;
        std::istringstream fields(line);
        int pair;
        Lab a, b;
        double expected;
        ASSERT_TRUE(fields >> pair >> a.l >> a.a >> a.b >> b.l >> b.a >> b.b >> expected) << line;
        EXPECT_NEAR(ciede2000(a, b), expected, 1e-4) << "pair " << pair;
        // Symmetric: the hue and chroma differences change sign together.
        EXPECT_NEAR(ciede2000(b, a), ciede2000(a, b), 1e-12) << "pair " << pair;
        ++pairs;
    }
    EXPECT_EQ(pairs, 34);
}

TEST(Ciede2000, ZeroForEqualColoursAndSymmetricOnRandomPairs) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> l(0, 100), ab(-120, 120);
    for (int i = 0; i < 2000; ++i) {
        const Lab a{l(rng), ab(rng), ab(rng)}, b{l(rng), ab(rng), ab(rng)};
        EXPECT_EQ(ciede2000(a, a), 0.0);
        EXPECT_NEAR(ciede2000(a, b), ciede2000(b, a), 1e-9);
        EXPECT_GT(ciede2000(a, b), 0.0);
    }
    // Achromatic pairs: only the lightness term, ΔL / S_L.
    const double l50 = 10.0 * 10.0;  // L̄ = 60
    EXPECT_NEAR(ciede2000({55, 0, 0}, {65, 0, 0}), 10 / (1 + 0.015 * l50 / std::sqrt(20 + l50)),
                1e-12);
}

// ---- SSIM ---------------------------------------------------------------------------------------

std::vector<float> random_plane(int w, int h, uint64_t seed) {
    std::vector<float> p(size_t(w) * h);
    for (int i = 0; i < w * h; ++i) p[size_t(i)] = test::hash01(seed, uint64_t(i), 0, 0);
    return p;
}

// The SSIM map straight from the definition: a 2-D window at every valid position.
double mssim_direct(const std::vector<float>& x, const std::vector<float>& y, int w, int h) {
    const int n = 11;
    const double sigma = 1.5, c1 = 1e-4, c2 = 9e-4;
    double g[n][n], sum = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            sum += g[i][j] =
                std::exp(-((i - 5) * (i - 5) + (j - 5) * (j - 5)) / (2 * sigma * sigma));
    double total = 0;
    for (int r = 0; r + n <= h; ++r)
        for (int c = 0; c + n <= w; ++c) {
            double mx = 0, my = 0;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    const size_t k = size_t(r + i) * w + c + j;
                    mx += g[i][j] / sum * x[k];
                    my += g[i][j] / sum * y[k];
                }
            double sxx = 0, syy = 0, sxy = 0;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    const size_t k = size_t(r + i) * w + c + j;
                    sxx += g[i][j] / sum * (x[k] - mx) * (x[k] - mx);
                    syy += g[i][j] / sum * (y[k] - my) * (y[k] - my);
                    sxy += g[i][j] / sum * (x[k] - mx) * (y[k] - my);
                }
            total +=
                (2 * mx * my + c1) * (2 * sxy + c2) / ((mx * mx + my * my + c1) * (sxx + syy + c2));
        }
    return total / ((w - n + 1) * (h - n + 1));
}

TEST(Mssim, IdenticalPlanesGiveOne) {
    const std::vector<float> x = random_plane(40, 30, 1);
    EXPECT_NEAR(mssim(x.data(), x.data(), 40, 30), 1.0, 1e-12);
    EXPECT_NEAR(mssim(x.data(), x.data(), 5, 7), 1.0, 1e-12);  // smaller than the window
}

TEST(Mssim, ConstantPlanesGiveTheLuminanceTerm) {
    // σ = 0 everywhere: SSIM = (2 μx μy + C1) / (μx² + μy² + C1) at every position.
    const double c1 = 0.01 * 0.01;
    for (const auto& [w, h] : {std::pair{32, 24}, {11, 11}, {6, 40}, {3, 2}}) {
        const std::vector<float> x(size_t(w) * h, 0.3f), y(size_t(w) * h, 0.5f);
        const double a = 0.3f, b = 0.5f;
        EXPECT_NEAR(mssim(x.data(), y.data(), w, h), (2 * a * b + c1) / (a * a + b * b + c1), 1e-12)
            << w << "×" << h;
    }
    // The dynamic range scales the constants: L = 255 makes C1 = (2.55)².
    const std::vector<float> x(144, 30.0f), y(144, 50.0f);
    SsimParams p;
    p.dynamic_range = 255;
    const double c1_255 = 2.55 * 2.55;
    EXPECT_NEAR(mssim(x.data(), y.data(), 12, 12, p), (3000 + c1_255) / (900 + 2500 + c1_255),
                1e-12);
}

TEST(Mssim, SeparableFilteringMatchesTheDirectDefinition) {
    const int w = 23, h = 17;
    const std::vector<float> x = random_plane(w, h, 2);
    std::vector<float> y = random_plane(w, h, 3);
    for (size_t i = 0; i < y.size(); ++i) y[i] = 0.7f * x[i] + 0.3f * y[i];
    EXPECT_NEAR(mssim(x.data(), y.data(), w, h), mssim_direct(x, y, w, h), 1e-12);
}

TEST(Mssim, SymmetricAndInvariantUnderTranspositionAndFlips) {
    const int w = 24, h = 19;
    const std::vector<float> x = random_plane(w, h, 4), y = random_plane(w, h, 5);
    const double v = mssim(x.data(), y.data(), w, h);
    EXPECT_NEAR(mssim(y.data(), x.data(), w, h), v, 1e-12);
    std::vector<float> xt(x.size()), yt(y.size()), xf(x.size()), yf(y.size());
    for (int r = 0; r < h; ++r)
        for (int c = 0; c < w; ++c) {
            xt[size_t(c) * h + r] = x[size_t(r) * w + c];
            yt[size_t(c) * h + r] = y[size_t(r) * w + c];
            xf[size_t(h - 1 - r) * w + (w - 1 - c)] = x[size_t(r) * w + c];
            yf[size_t(h - 1 - r) * w + (w - 1 - c)] = y[size_t(r) * w + c];
        }
    EXPECT_NEAR(mssim(xt.data(), yt.data(), h, w), v, 1e-12);
    EXPECT_NEAR(mssim(xf.data(), yf.data(), w, h), v, 1e-12);
}

TEST(Mssim, NoiseLowersItMonotonically) {
    const int w = 48, h = 40;
    const std::vector<float> x = random_plane(w, h, 6);
    double previous = 1.0;
    for (float amplitude : {0.01f, 0.03f, 0.1f, 0.3f, 1.0f}) {
        std::vector<float> y = x;
        for (size_t i = 0; i < y.size(); ++i) y[i] += amplitude * (test::hash01(7, i, 0, 0) - 0.5f);
        const double v = mssim(x.data(), y.data(), w, h);
        EXPECT_LT(v, previous) << amplitude;
        previous = v;
    }
    // Noise of the signal's own variance (both uniform over a unit range): 2σ²/(σ² + 2σ²) = 2/3.
    EXPECT_NEAR(previous, 2.0 / 3, 0.05);
}

TEST(Mssim, RejectsBadWindowsAndEmptyPlanes) {
    const std::vector<float> x(16, 0.5f);
    SsimParams p;
    p.window = 10;
    EXPECT_THAT(test::error_of([&] { mssim(x.data(), x.data(), 4, 4, p); }),
                HasSubstr("window 10 is not a positive odd number"));
    EXPECT_THAT(test::error_of([&] { mssim(x.data(), x.data(), 0, 4); }),
                HasSubstr("the planes are 0×4"));
}

// ---- MetricSelection ----------------------------------------------------------------------------

TEST(MetricSelection, ParsesNamesAndLeavesOthersToTheCaller) {
    MetricSelection s = MetricSelection::parse("rmse,ssim");
    EXPECT_TRUE(s.rmse && s.ssim);
    EXPECT_FALSE(s.lab || s.de2000);
    s = MetricSelection::parse(" lab , de2000 ");
    EXPECT_TRUE(s.lab && s.de2000);
    EXPECT_FALSE(s.rmse || s.ssim);

    std::vector<std::string> rest;
    s = MetricSelection::parse("btf-cielab,rmse", &rest);
    EXPECT_TRUE(s.rmse);
    EXPECT_FALSE(s.lab || s.de2000 || s.ssim);
    EXPECT_EQ(rest, std::vector<std::string>{"btf-cielab"});
    rest.clear();
    s = MetricSelection::parse("btf-cielab", &rest);
    EXPECT_FALSE(s.any());
    EXPECT_EQ(rest.size(), 1u);

    EXPECT_THAT(test::error_of([] { MetricSelection::parse("rmse,psnr"); }),
                HasSubstr("unknown metric 'psnr'; the metrics are rmse, lab, de2000, ssim"));
    EXPECT_THAT(test::error_of([] { MetricSelection::parse(" , "); }),
                HasSubstr("no metric named"));
}

// ---- comparability ------------------------------------------------------------------------------

std::unique_ptr<FunctionSource> constant_source(const Sampling& sampling, int w, int h, Rgb value,
                                                const std::string& path = {}) {
    auto s = std::make_unique<FunctionSource>(sampling, w, h,
                                              [value](int, int, int, int) { return value; });
    s->info().path = path;
    return s;
}

TEST(CheckComparable, NamesBothSourcesAndWhatDiffers) {
    const Rgb grey{0.5f, 0.5f, 0.5f};
    const auto a = constant_source(test::ubo_subset(3, 2), 8, 8, grey, "a.h5");
    check_comparable(*a, *constant_source(test::ubo_subset(3, 2), 8, 8, grey, "b.h5"));

    EXPECT_EQ(test::error_of([&] {
                  check_comparable(*a, *constant_source(test::ubo_subset(3, 2), 8, 6, grey, "b"));
              }),
              "a.h5 vs b: extent 8×8 vs 8×6 texels");
    EXPECT_EQ(test::error_of([&] {
                  check_comparable(*a, *constant_source(test::ubo_subset(2, 2), 8, 8, grey, "b"));
              }),
              "a.h5 vs b: 3 views vs 2");
    EXPECT_EQ(test::error_of([&] {
                  check_comparable(*a, *constant_source(test::ubo_subset(3, 4), 8, 8, grey, "b"));
              }),
              "a.h5 vs b: 2 lights vs 4");
    // Same counts, other directions; a source without a path is named by its format.
    Sampling moved = test::ubo_subset(3, 2);
    std::vector<Direction> views = moved.views.directions();
    views[2].phi += 1e-3;
    moved.views = DirectionSet("moved", views);
    const auto b = constant_source(moved, 8, 8, grey);
    EXPECT_THAT(test::error_of([&] { check_comparable(*a, *b); }),
                HasSubstr("a.h5 vs function: view 2 is at θ"));
    // Differences below 1e-4 rad pass.
    views[2].phi = test::ubo_subset(3, 2).views[2].phi + 1e-6;
    moved.views = DirectionSet("moved", views);
    check_comparable(*a, *constant_source(moved, 8, 8, grey));
}

// ---- compare ------------------------------------------------------------------------------------

// A copy of `source` with uniform noise of `amplitude` (peak to peak) added to every value.
std::unique_ptr<FunctionSource> noisy(std::shared_ptr<const FunctionSource> source,
                                      float amplitude) {
    return std::make_unique<FunctionSource>(
        source->sampling(), source->width(), source->height(),
        [source, amplitude](int v, int l, int x, int y) {
            const Rgb c = source->value(v, l, x, y);
            const uint64_t t = uint64_t(y) * 4096 + x;
            return Rgb{c.r + amplitude * (test::hash01(v, l, t, 0) - 0.5f),
                       c.g + amplitude * (test::hash01(v, l, t, 1) - 0.5f),
                       c.b + amplitude * (test::hash01(v, l, t, 2) - 0.5f)};
        },
        "noisy");
}

std::shared_ptr<const FunctionSource> small_material() {
    static const std::shared_ptr<const FunctionSource> source =
        test::cached(*synth::make("woven_fabric", 24, test::ubo_subset(5, 4), 3));
    return source;
}

TEST(Compare, IdenticalSourcesGiveZeroErrorAndSsimOne) {
    const auto ref = small_material();
    const Metrics m = compare(*ref, *ref);
    EXPECT_EQ(m.texels, 24 * 24);
    EXPECT_EQ(m.images, 20);
    EXPECT_EQ(m.peak, 1.0);
    EXPECT_EQ(m.rmse, 0.0);
    EXPECT_EQ(m.psnr, std::numeric_limits<double>::infinity());
    EXPECT_EQ(m.lab_mae, (std::array<double, 3>{0, 0, 0}));
    EXPECT_EQ(m.de2000_mean, 0.0);
    EXPECT_EQ(m.de2000_p95, 0.0);
    EXPECT_EQ(m.de2000_max, 0.0);
    EXPECT_NEAR(m.ssim_luminance, 1.0, 1e-12);
    for (double v : m.ssim_ycrcb) EXPECT_NEAR(v, 1.0, 1e-12);
}

TEST(Compare, GrowingNoiseRaisesErrorsAndLowersSsim) {
    const auto ref = small_material();
    Metrics previous = compare(*ref, *ref);
    for (float amplitude : {0.005f, 0.02f, 0.08f}) {
        const Metrics m = compare(*ref, *noisy(ref, amplitude));
        // Uniform noise of width A has standard deviation A / √12.
        EXPECT_NEAR(m.rmse, amplitude / std::sqrt(12.0), 0.03 * amplitude / std::sqrt(12.0));
        EXPECT_NEAR(m.psnr, 20 * std::log10(1 / m.rmse), 1e-9);
        EXPECT_GT(m.rmse, previous.rmse) << amplitude;
        for (int c = 0; c < 3; ++c) EXPECT_GT(m.lab_mae[c], previous.lab_mae[c]) << amplitude;
        EXPECT_GT(m.de2000_mean, previous.de2000_mean) << amplitude;
        EXPECT_GT(m.de2000_p95, previous.de2000_p95) << amplitude;
        EXPECT_GT(m.de2000_max, previous.de2000_max) << amplitude;
        EXPECT_LE(m.de2000_mean, m.de2000_p95);
        EXPECT_LE(m.de2000_p95, m.de2000_max);
        EXPECT_LT(m.ssim_luminance, previous.ssim_luminance) << amplitude;
        for (int c = 0; c < 3; ++c) EXPECT_LT(m.ssim_ycrcb[c], previous.ssim_ycrcb[c]) << amplitude;
        previous = m;
    }
}

TEST(Compare, PercentileAndMeansOfAKnownDistribution) {
    // Grey reference, test lighter by a per-texel amount: ΔE2000 of an achromatic pair is ΔL / S_L,
    // so the 95th percentile and the maximum are known.
    const Sampling sampling = test::ubo_subset(2, 2);
    const int w = 20, h = 10;  // 200 texels, 800 samples
    const auto ref = constant_source(sampling, w, h, {0.2f, 0.2f, 0.2f});
    FunctionSource test(sampling, w, h, [](int, int, int x, int y) {
        const float v = 0.2f * (1 + 0.002f * float(y * 20 + x));  // up to 0.2 × 1.398
        return Rgb{v, v, v};
    });
    std::vector<double> de;
    double dl = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const Lab a = rgb_to_lab(ref->value(0, 0, x, y)),
                      b = rgb_to_lab(test.value(0, 0, x, y));
            de.push_back(ciede2000(a, b));
            dl += std::abs(a.l - b.l);
        }
    std::sort(de.begin(), de.end());
    const Metrics m = compare(*ref, test);
    EXPECT_DOUBLE_EQ(m.de2000_max, de.back());
    // The 190th of 200 values is the 95th percentile; the histogram gives its bin's upper edge.
    EXPECT_GE(m.de2000_p95, de[189]);
    EXPECT_LT(m.de2000_p95, de[189] + kDe2000BinWidth);
    double mean = 0;
    for (double v : de) mean += v;
    EXPECT_NEAR(m.de2000_mean, mean / de.size(), 1e-12);
    EXPECT_NEAR(m.lab_mae[0], dl / de.size(), 1e-12);
    EXPECT_LT(m.lab_mae[1], 1e-3);  // grey stays grey (to the rounding of the RGB→XYZ matrix)
    EXPECT_LT(m.lab_mae[2], 1e-3);
}

TEST(Compare, SameResultForAnyThreadCount) {
    const auto ref = small_material();
    const auto test = noisy(ref, 0.05f);
    CompareOptions options;
    options.cos_weight = true;
    options.per_image = true;
    Metrics one, two;
    {
        ThreadLimit limit(1);
        one = compare(*ref, *test, options);
    }
    {
        ThreadLimit limit(2);
        two = compare(*ref, *test, options);
    }
    EXPECT_EQ(one.rmse, two.rmse);
    EXPECT_EQ(one.lab_mae, two.lab_mae);
    EXPECT_EQ(one.de2000_mean, two.de2000_mean);
    EXPECT_EQ(one.de2000_p95, two.de2000_p95);
    EXPECT_EQ(one.de2000_max, two.de2000_max);
    EXPECT_EQ(one.ssim_luminance, two.ssim_luminance);
    EXPECT_EQ(one.ssim_ycrcb, two.ssim_ycrcb);
    ASSERT_EQ(one.images_detail.size(), two.images_detail.size());
    for (size_t i = 0; i < one.images_detail.size(); ++i) {
        EXPECT_EQ(one.images_detail[i].rmse, two.images_detail[i].rmse);
        EXPECT_EQ(one.images_detail[i].de2000_mean, two.images_detail[i].de2000_mean);
        EXPECT_EQ(one.images_detail[i].ssim_luminance, two.images_detail[i].ssim_luminance);
    }
}

TEST(Compare, PerImageDetailAddsUpToTheTotals) {
    const auto ref = small_material();
    CompareOptions options;
    options.per_image = true;
    const Metrics m = compare(*ref, *noisy(ref, 0.05f), options);
    ASSERT_EQ(m.images_detail.size(), 20u);
    double sse = 0, de = 0, ssim = 0;
    for (size_t i = 0; i < m.images_detail.size(); ++i) {
        const ImageMetrics& d = m.images_detail[i];
        EXPECT_EQ(d.view, int(i / 4));
        EXPECT_EQ(d.light, int(i % 4));
        sse += d.rmse * d.rmse;
        de += d.de2000_mean;
        ssim += d.ssim_luminance;
    }
    EXPECT_NEAR(std::sqrt(sse / 20), m.rmse, 1e-12);
    EXPECT_NEAR(de / 20, m.de2000_mean, 1e-12);
    EXPECT_NEAR(ssim / 20, m.ssim_luminance, 1e-12);
}

TEST(Compare, CosWeightingMattersOnlyWhenErrorsDifferPerView) {
    const Sampling sampling = test::ubo_subset(6, 3);
    const Rgb grey{0.4f, 0.3f, 0.2f};
    const auto ref = constant_source(sampling, 12, 12, grey);
    CompareOptions weighted;
    weighted.cos_weight = true;

    // Uniform error: every image differs by the same amount.
    const auto uniform = constant_source(sampling, 12, 12, {0.45f, 0.3f, 0.25f});
    const Metrics u0 = compare(*ref, *uniform), u1 = compare(*ref, *uniform, weighted);
    EXPECT_FALSE(u0.cos_weighted);
    EXPECT_TRUE(u1.cos_weighted);
    EXPECT_NEAR(u1.rmse, u0.rmse, 1e-12);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(u1.lab_mae[c], u0.lab_mae[c], 1e-12);
    EXPECT_NEAR(u1.de2000_mean, u0.de2000_mean, 1e-12);
    EXPECT_EQ(u1.de2000_p95, u0.de2000_p95);
    EXPECT_NEAR(u1.ssim_luminance, u0.ssim_luminance, 1e-12);

    // Error growing with the view index (and so with θ in this subset): weighting by cos θ
    // lowers it, to exactly sqrt(Σ cos θ_v d_v² / Σ cos θ_v).
    FunctionSource per_view(sampling, 12, 12, [grey](int v, int, int, int) {
        const float d = 0.01f * float(v + 1);
        return Rgb{grey.r + d, grey.g + d, grey.b + d};
    });
    const Metrics p0 = compare(*ref, per_view), p1 = compare(*ref, per_view, weighted);
    double num = 0, den = 0;
    for (int v = 0; v < sampling.num_views(); ++v) {
        const double c = std::cos(sampling.views[v].theta);
        const Rgb t = per_view.value(v, 0, 0, 0);
        const double dr = double(t.r) - grey.r, dg = double(t.g) - grey.g,
                     db = double(t.b) - grey.b;
        num += c * (dr * dr + dg * dg + db * db) / 3;
        den += c;
    }
    EXPECT_NEAR(p1.rmse, std::sqrt(num / den), 1e-12);
    EXPECT_LT(p1.rmse, p0.rmse - 1e-4);
    EXPECT_LT(p1.de2000_mean, p0.de2000_mean);
    EXPECT_LE(p1.de2000_p95, p0.de2000_p95);
    EXPECT_EQ(p1.de2000_max, p0.de2000_max);  // the maximum is not weighted
}

TEST(Compare, SelectionComputesOnlyTheNamedMeasures) {
    const auto ref = small_material();
    const auto test = noisy(ref, 0.05f);
    CompareOptions options;
    options.metrics = MetricSelection::parse("lab");
    const Metrics m = compare(*ref, *test, options);
    EXPECT_GT(m.lab_mae[0], 0.0);
    EXPECT_EQ(m.rmse, 0.0);
    EXPECT_EQ(m.de2000_mean, 0.0);
    EXPECT_EQ(m.ssim_luminance, 0.0);
    EXPECT_TRUE(m.selection.lab);
    EXPECT_FALSE(m.selection.rmse);
    // The same numbers as with every measure selected.
    EXPECT_EQ(m.lab_mae, compare(*ref, *test).lab_mae);
}

TEST(Compare, PeakScalesPsnrAndDefaultsToTheLargestHdrValue) {
    const Sampling sampling = test::ubo_subset(2, 2);
    FunctionSource ref(sampling, 16, 16, [](int v, int l, int x, int y) {
        const float s = (v == 1 && l == 1 && x == 3 && y == 5) ? 4.0f : 0.5f;
        return Rgb{s, 0.5f * s, 0.25f * s};
    });
    ref.info().hdr = true;
    FunctionSource test(sampling, 16, 16, [&ref](int v, int l, int x, int y) {
        const Rgb c = ref.value(v, l, x, y);
        return Rgb{c.r + 0.01f, c.g, c.b};
    });
    const Metrics m = compare(ref, test);
    EXPECT_EQ(m.peak, 4.0);
    EXPECT_NEAR(m.psnr, 20 * std::log10(4.0 / m.rmse), 1e-9);
    CompareOptions options;
    options.peak = 2;
    const Metrics m2 = compare(ref, test, options);
    EXPECT_EQ(m2.peak, 2.0);
    EXPECT_EQ(m2.rmse, m.rmse);
    EXPECT_NEAR(m.psnr - m2.psnr, 20 * std::log10(2.0), 1e-9);
    // The SSIM of display-encoded values depends on the peak (values clip at it).
    EXPECT_NE(m2.ssim_luminance, m.ssim_luminance);
    // LDR references default to a peak of 1.
    ref.info().hdr = false;
    EXPECT_EQ(compare(ref, test).peak, 1.0);
    options.peak = -1;
    EXPECT_THAT(test::error_of([&] { compare(ref, test, options); }),
                HasSubstr("peak -1 is not a positive number"));
}

TEST(Compare, MismatchedSourcesAndBadValuesThrow) {
    const auto ref = small_material();
    const auto smaller = test::cached(*synth::make("woven_fabric", 16, ref->sampling(), 3));
    EXPECT_EQ(test::error_of([&] { compare(*ref, *smaller); }),
              "cached vs cached: extent 24×24 vs 16×16 texels");
    FunctionSource bad(
        ref->sampling(), 24, 24,
        [](int v, int l, int x, int y) {
            return Rgb{v == 2 && l == 1 && x == 7 && y == 4 ? NAN : 0.5f, 0.5f, 0.5f};
        },
        "bad");
    EXPECT_EQ(test::error_of([&] { compare(*ref, bad); }),
              "bad: image (view 2, light 1) holds a non-finite value at texel (7, 4)");
}

TEST(Compare, ReportsOneProgressUnitPerImage) {
    const auto ref = small_material();
    std::vector<std::string> stages;
    uint64_t last_total = 0;
    Progress progress([&](std::string_view stage, uint64_t, uint64_t total) {
        if (stages.empty() || stages.back() != stage) stages.emplace_back(stage);
        last_total = total;
    });
    compare(*ref, *ref, {}, progress);
    EXPECT_EQ(stages, std::vector<std::string>{"comparing"});
    EXPECT_EQ(last_total, 20u);
    EXPECT_EQ(progress.done(), 20u);
}

}  // namespace
}  // namespace btf::quality

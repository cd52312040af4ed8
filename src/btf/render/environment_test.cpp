// SPDX-License-Identifier: MIT
#include "btf/render/environment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "btf/render/distribution.h"
#include "btf/testing/chi_square.h"
#include "btf/testing/support.h"

namespace btf::render {
namespace {

using test::uniform01;

double luminance(const Rgb& c) {
    return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
}

// Pearson's χ² of observed against expected counts; bins expecting fewer than 5 are pooled into
// one. Returns the p-value; counts in bins expecting nothing are added to `unexpected`.
double chi_square_p(const std::vector<double>& expected, const std::vector<int64_t>& observed,
                    int64_t& unexpected) {
    double statistic = 0, pooled_expected = 0;
    int64_t pooled_observed = 0;
    int bins = 0;
    unexpected = 0;
    for (size_t i = 0; i < expected.size(); ++i) {
        if (expected[i] <= 0) {
            unexpected += observed[i];
        } else if (expected[i] < 5) {
            pooled_expected += expected[i];
            pooled_observed += observed[i];
        } else {
            const double d = double(observed[i]) - expected[i];
            statistic += d * d / expected[i];
            ++bins;
        }
    }
    if (pooled_expected > 0) {
        const double d = double(pooled_observed) - pooled_expected;
        statistic += d * d / pooled_expected;
        ++bins;
    }
    if (bins < 2) return 1;
    return Eigen::numext::igammac(0.5 * (bins - 1), 0.5 * statistic);
}

// ---- Distribution1D -----------------------------------------------------------------------------

TEST(Distribution1DTest, PdfIntegratesToOneAndFollowsWeights) {
    const std::vector<double> weights{1, 0, 3, 2, 0, 4, 0.5};
    const Distribution1D d(weights);
    const int n = int(weights.size());
    EXPECT_EQ(d.size(), n);
    EXPECT_NEAR(d.integral(), 10.5 / n, 1e-15);

    constexpr int kSteps = 70000;
    double integral = 0;
    for (int i = 0; i < kSteps; ++i) integral += d.pdf((i + 0.5) / kSteps) / kSteps;
    EXPECT_NEAR(integral, 1.0, 1e-12);
    for (int b = 0; b < n; ++b) {
        EXPECT_NEAR(d.pdf((b + 0.5) / n), weights[b] / (10.5 / n), 1e-12) << "bin " << b;
        EXPECT_NEAR(d.probability(b), weights[b] / 10.5, 1e-15) << "bin " << b;
    }
}

TEST(Distribution1DTest, SamplingHistogramMatchesWeights) {
    // 49 bins: i / 49 is not exact in binary, so bin boundaries are where rounding could put a
    // sample in the neighbouring bin.
    std::vector<double> weights(49);
    std::mt19937_64 rng(7);
    for (size_t i = 0; i < weights.size(); ++i)
        weights[i] = i % 5 == 3 ? 0.0 : 0.1 + uniform01(rng) * 3;
    const Distribution1D d(weights);
    const int n = d.size();

    constexpr int64_t kSamples = 200000;
    std::vector<int64_t> observed(size_t(n), 0);
    for (int64_t k = 0; k < kSamples; ++k) {
        const Distribution1D::Sample s = d.sample_continuous(uniform01(rng));
        ASSERT_GE(s.x, 0.0);
        ASSERT_LT(s.x, 1.0);
        ASSERT_EQ(s.bin, d.bin_of(s.x));
        ASSERT_EQ(s.pdf, d.pdf(s.x)) << "x " << s.x;
        ++observed[size_t(s.bin)];
    }
    std::vector<double> expected(weights.size());
    for (int b = 0; b < n; ++b) expected[size_t(b)] = d.probability(b) * kSamples;
    int64_t unexpected = 0;
    EXPECT_GE(chi_square_p(expected, observed, unexpected), 1e-3);
    EXPECT_EQ(unexpected, 0) << "samples in bins of weight 0";
}

TEST(Distribution1DTest, BinBoundariesAndExtremeXiStayInNonZeroBins) {
    const std::vector<double> weights{0, 0, 2, 5, 0, 0, 0};
    const Distribution1D d(weights);
    for (double xi : {0.0, 2.0 / 7, 0.5, std::nextafter(1.0, 0.0), 1.0, 1.5, -0.25, std::nan("")}) {
        const Distribution1D::Sample s = d.sample_continuous(xi);
        EXPECT_TRUE(s.bin == 2 || s.bin == 3) << "xi " << xi;
        EXPECT_GE(s.x, 2.0 / 7) << "xi " << xi;
        EXPECT_LT(s.x, 4.0 / 7) << "xi " << xi;
        EXPECT_GT(s.pdf, 0) << "xi " << xi;
        EXPECT_EQ(s.pdf, d.pdf(s.x)) << "xi " << xi;
    }
    // ξ at the CDF step between the two bins: the end of bin 2 and the start of bin 3.
    const Distribution1D::Sample step = d.sample_continuous(2.0 / 7);
    EXPECT_EQ(step.bin, 3);
    EXPECT_NEAR(step.x, 3.0 / 7, 1e-15);
    // ξ → x is monotonic.
    double previous = -1;
    for (int i = 0; i <= 1000; ++i) {
        const double x = d.sample_continuous(i / 1000.0).x;
        EXPECT_GE(x, previous);
        previous = x;
    }
}

TEST(Distribution1DTest, AllZeroWeightsGiveUniform) {
    const std::vector<double> weights(4, 0.0);
    const Distribution1D d(weights);
    EXPECT_EQ(d.integral(), 0.0);
    for (double xi : {0.0, 0.1, 0.3, 0.62, 0.99}) {
        const Distribution1D::Sample s = d.sample_continuous(xi);
        EXPECT_NEAR(s.x, xi, 1e-15);
        EXPECT_EQ(s.pdf, 1.0);
        EXPECT_EQ(d.pdf(xi), 1.0);
    }
}

TEST(Distribution1DTest, RejectsInvalidWeights) {
    EXPECT_NE(test::error_of([] { Distribution1D(std::vector<double>{}); }).find("no weights"),
              std::string::npos);
    const std::string negative = test::error_of([] {
        Distribution1D(std::vector<double>{1, -2, 3});
    });
    EXPECT_NE(negative.find("weight 1 is -2"), std::string::npos) << negative;
    EXPECT_NE(test::error_of([] {
                  Distribution1D(std::vector<double>{1, 2, std::nan("")});
              }).find("weight 2"),
              std::string::npos);
    EXPECT_NE(
        test::error_of([] { Distribution1D(std::vector<double>{HUGE_VAL}); }).find("weight 0"),
        std::string::npos);
}

// ---- Distribution2D -----------------------------------------------------------------------------

// 5 columns × 4 rows; row 2 is all zero, some single cells are zero.
const std::vector<double> kGrid{
    1, 2, 0, 4, 1,  //
    0, 0, 7, 0, 3,  //
    0, 0, 0, 0, 0,  //
    2, 2, 2, 2, 0.5,
};

TEST(Distribution2DTest, PdfIntegratesToOneAndFollowsWeights) {
    const Distribution2D d(kGrid, 5, 4);
    double total = 0;
    for (double w : kGrid) total += w;
    EXPECT_NEAR(d.integral(), total / 20, 1e-14);

    constexpr int kSub = 7;  // midpoints of 7 × 7 sub-cells per cell
    double integral = 0;
    for (int y = 0; y < 4 * kSub; ++y)
        for (int x = 0; x < 5 * kSub; ++x)
            integral += d.pdf((x + 0.5) / (5 * kSub), (y + 0.5) / (4 * kSub));
    EXPECT_NEAR(integral / (20 * kSub * kSub), 1.0, 1e-12);
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 5; ++c)
            EXPECT_NEAR(d.pdf((c + 0.5) / 5, (r + 0.5) / 4),
                        kGrid[size_t(r) * 5 + c] / (total / 20), 1e-12)
                << "column " << c << " row " << r;
}

TEST(Distribution2DTest, SamplingHistogramMatchesWeights) {
    const Distribution2D d(kGrid, 5, 4);
    double total = 0;
    for (double w : kGrid) total += w;
    constexpr int64_t kSamples = 200000;
    std::vector<int64_t> observed(kGrid.size(), 0);
    std::mt19937_64 rng(11);
    for (int64_t k = 0; k < kSamples; ++k) {
        const Distribution2D::Sample s = d.sample(uniform01(rng), uniform01(rng));
        ASSERT_GE(s.u, 0.0);
        ASSERT_LT(s.u, 1.0);
        ASSERT_GE(s.v, 0.0);
        ASSERT_LT(s.v, 1.0);
        ASSERT_EQ(s.column, std::min(int(s.u * 5), 4));
        ASSERT_EQ(s.row, std::min(int(s.v * 4), 3));
        ASSERT_EQ(s.pdf, d.pdf(s.u, s.v));
        ++observed[size_t(s.row) * 5 + s.column];
    }
    std::vector<double> expected(kGrid.size());
    for (size_t i = 0; i < kGrid.size(); ++i) expected[i] = kGrid[i] / total * kSamples;
    int64_t unexpected = 0;
    EXPECT_GE(chi_square_p(expected, observed, unexpected), 1e-3);
    EXPECT_EQ(unexpected, 0) << "samples in cells of weight 0";
}

TEST(Distribution2DTest, ArgumentOrderAndErrors) {
    // One non-zero cell at column 3, row 1 of a 4 × 2 grid: ξ1 moves u inside it, ξ2 moves v.
    const std::vector<double> grid{0, 0, 0, 0, 0, 0, 0, 1};
    const Distribution2D d(grid, 4, 2);
    const Distribution2D::Sample a = d.sample(0.1, 0.9), b = d.sample(0.9, 0.1);
    EXPECT_NEAR(a.u, 0.75 + 0.1 / 4, 1e-12);
    EXPECT_NEAR(a.v, 0.5 + 0.9 / 2, 1e-12);
    EXPECT_NEAR(b.u, 0.75 + 0.9 / 4, 1e-12);
    EXPECT_NEAR(b.v, 0.5 + 0.1 / 2, 1e-12);
    EXPECT_NEAR(a.pdf, 8.0, 1e-12);
    EXPECT_NE(test::error_of([&] { Distribution2D(grid, 3, 2); }).find("8 weights for a 3 × 2"),
              std::string::npos);
    EXPECT_NE(test::error_of([&] { Distribution2D(grid, 0, 8); }).find("0 × 8"), std::string::npos);
}

// ---- EnvironmentMap -----------------------------------------------------------------------------

Vec3 uniform_sphere(double xi1, double xi2) {
    const double y = 1 - 2 * xi1, r = std::sqrt(std::max(0.0, 1 - y * y)), phi = 2 * kPi * xi2;
    return {r * std::cos(phi), y, r * std::sin(phi)};
}

// ∫ f(ω) dω over the sphere by stratified sampling: one jittered point in each cell of an
// equal-area grid in (cos θ, φ), where dω = d(cos θ) dφ. Independent of the map's own (u, v) grid;
// jitter rather than cell midpoints, because midpoints alias with the pixel edges of sharp maps
// (a 3-pixel spot was off by 1.5% even on a 720 × 1440 grid).
template <typename F>
double integrate_sphere(F&& f, int rows, int columns, uint64_t seed) {
    std::mt19937_64 rng(seed);
    const double dy = 2.0 / rows, dphi = 2 * kPi / columns;
    double sum = 0;
    for (int j = 0; j < rows; ++j)
        for (int i = 0; i < columns; ++i) {
            const double y = -1 + (j + uniform01(rng)) * dy, r = std::sqrt(1 - y * y);
            const double phi = (i + uniform01(rng)) * dphi;
            sum += f(Vec3{r * std::cos(phi), y, r * std::sin(phi)});
        }
    return sum * dy * dphi;
}

// A black map with one bright pixel.
Image spot_image(int width, int height, int column, int row, float value) {
    Image image(width, height, 3, 0.0f);
    image.set_rgb(column, row, {value, value, value});
    return image;
}

double angle_between(const Vec3& a, const Vec3& b) {
    return std::acos(std::clamp(dot(normalize(a), normalize(b)), -1.0, 1.0));
}

TEST(EnvironmentMapTest, LatLongConvention) {
    const auto uv = [](const Vec3& d) { return direction_to_latlong(d); };
    EXPECT_NEAR(uv({0, 1, 0}).v, 0.0, 1e-15);  // +y is up: v = 0, row 0
    EXPECT_NEAR(uv({0, -1, 0}).v, 1.0, 1e-15);
    EXPECT_NEAR(uv({1, 0, 0}).u, 0.0, 1e-15);
    EXPECT_NEAR(uv({1, 0, 0}).v, 0.5, 1e-15);
    EXPECT_NEAR(uv({0, 0, 1}).u, 0.25, 1e-15);
    EXPECT_NEAR(uv({-1, 0, 0}).u, 0.5, 1e-15);
    EXPECT_NEAR(uv({0, 0, -3}).u, 0.75, 1e-15);  // any length
    EXPECT_NEAR(uv({1, 1, 0}).v, 0.25, 1e-15);
    EXPECT_LT(uv({1, 0, -1e-300}).u, 1.0);  // φ just below 2π still maps into [0, 1)
    std::mt19937_64 rng(3);
    for (int k = 0; k < 1000; ++k) {
        const double u = uniform01(rng), v = 0.001 + 0.998 * uniform01(rng);
        const Vec3 d = latlong_to_direction(u, v);
        EXPECT_NEAR(length(d), 1.0, 1e-12);
        const LatLong back = direction_to_latlong(d);
        EXPECT_NEAR(back.u, u, 1e-12);
        EXPECT_NEAR(back.v, v, 1e-12);
    }
}

TEST(EnvironmentMapTest, RowZeroIsTheZenith) {
    Image image(32, 16, 3, 0.0f);
    for (int x = 0; x < 32; ++x) image.set_rgb(x, 0, {2, 2, 2});
    const EnvironmentMap map(image);
    EXPECT_FLOAT_EQ(map.radiance({0, 1, 0}).g, 2.0f);
    EXPECT_FLOAT_EQ(map.radiance({0, -1, 0}).g, 0.0f);
    EXPECT_FLOAT_EQ(map.radiance({1, 0, 0}).g, 0.0f);
    std::mt19937_64 rng(5);
    int in_first_row = 0;
    for (int k = 0; k < 2000; ++k) {
        const EnvSample s = map.sample(uniform01(rng), uniform01(rng));
        // The blur reaches one row down; nothing further.
        ASSERT_GT(s.direction.y, std::cos(2 * kPi / 16) - 1e-12);
        if (s.direction.y > std::cos(kPi / 16)) ++in_first_row;
    }
    // Rows 0 and 1 get weights 7/8 and 1/8 of the luminance, times mean sin θ (≈ 1 : 3).
    EXPECT_GT(in_first_row, 2000 * 0.55);
    EXPECT_LT(in_first_row, 2000 * 0.85);
}

TEST(EnvironmentMapTest, BrightPixelIsSampledAroundItsDirection) {
    const int column = 40, row = 10;
    const EnvironmentMap map(spot_image(64, 32, column, row, 100));
    const Vec3 centre = latlong_to_direction((column + 0.5) / 64, (row + 0.5) / 32);
    EXPECT_FLOAT_EQ(map.radiance(centre).r, 100.0f);
    // With rotation 0 map and world frames coincide.
    const LatLong p = map.world_to_map(centre);
    EXPECT_NEAR(p.u, (column + 0.5) / 64, 1e-12);
    EXPECT_NEAR(p.v, (row + 0.5) / 32, 1e-12);

    std::mt19937_64 rng(9);
    Vec3 mean{};
    int in_pixel = 0;
    constexpr int kSamples = 4000;
    for (int k = 0; k < kSamples; ++k) {
        const EnvSample s = map.sample(uniform01(rng), uniform01(rng));
        const LatLong q = direction_to_latlong(s.direction);
        const int c = int(q.u * 64), r = int(q.v * 32);
        ASSERT_LE(std::abs(c - column), 1) << "sampled column " << c;
        ASSERT_LE(std::abs(r - row), 1) << "sampled row " << r;
        in_pixel += c == column && r == row;
        mean += s.direction;
    }
    // The [1 6 1] / 8 blur leaves (3/4)² of the weight on the pixel itself.
    EXPECT_NEAR(double(in_pixel) / kSamples, 0.5625, 0.04);
    EXPECT_LT(degrees(angle_between(mean, centre)), 1.0);
}

TEST(EnvironmentMapTest, RotationMovesTheBrightSpot) {
    const int column = 8, row = 12;  // φ_map = 47.8°, θ = 70.3°
    const double u = (column + 0.5) / 64, v = (row + 0.5) / 32;
    for (double rotation : {90.0, -30.0, 200.0}) {
        const EnvironmentMap map(spot_image(64, 32, column, row, 50), 1, rotation);
        const Vec3 expected = latlong_to_direction(u + rotation / 360, v);
        EXPECT_FLOAT_EQ(map.radiance(expected).r, 50.0f) << "rotation " << rotation;
        EXPECT_FLOAT_EQ(map.radiance(latlong_to_direction(u, v)).r, 0.0f);
        const Vec3 via_map = map.map_to_world(u, v);
        EXPECT_LT(length(via_map - expected), 1e-12);
        std::mt19937_64 rng(13);
        Vec3 mean{};
        for (int k = 0; k < 2000; ++k) mean += map.sample(uniform01(rng), uniform01(rng)).direction;
        EXPECT_LT(degrees(angle_between(mean, expected)), 1.0) << "rotation " << rotation;
    }
}

TEST(EnvironmentMapTest, BilinearLookupWrapsInU) {
    // One bright pixel in the last column: its bilinear footprint reaches across the seam into
    // column 0, and so must the sampling density.
    const EnvironmentMap map(spot_image(16, 8, 15, 4, 8));
    const Vec3 seam = latlong_to_direction(0.0, 4.5 / 8);
    const Rgb at_seam = map.radiance(seam);
    EXPECT_NEAR(at_seam.r, 4.0f, 1e-5);  // halfway between columns 15 and 0
    EXPECT_NEAR(map.radiance(latlong_to_direction(0.25 / 16, 4.5 / 8)).r, 2.0f, 1e-5);
    EXPECT_GT(map.pdf(latlong_to_direction(0.25 / 16, 4.5 / 8)), 0);
}

// Maps used by the sphere-wide tests: a constant, a sky with a sun, a rotated single pixel and
// deterministic noise.
std::vector<EnvironmentMap> test_maps() {
    std::vector<EnvironmentMap> maps;
    maps.emplace_back(Image(48, 24, 3, 1.0f));
    maps.emplace_back(EnvironmentMap::make_sky(128, 64, normalize(Vec3{0.6, 0.5, -0.4})), 1.5,
                      37.0);
    maps.emplace_back(spot_image(64, 32, 20, 5, 30), 1, -71.3);
    Image noise(40, 20, 1);
    std::mt19937_64 rng(17);
    for (float& value : noise.values()) value = float(std::pow(uniform01(rng), 4) * 10);
    maps.emplace_back(noise, 0.5, 12.0);
    return maps;
}

TEST(EnvironmentMapTest, PdfIntegratesToOneOverTheSphere) {
    // Stratified quadrature resolves features of several pixels to ~0.2%; the sharper maps of
    // test_maps() (a 2.5° sun, one pixel) are checked exactly in map coordinates below.
    SkyOptions big_sun;
    big_sun.sun_radius_degrees = 12;
    Image block(64, 32, 3, 0.0f);
    for (int y = 3; y < 9; ++y)
        for (int x = 18; x < 26; ++x) block.set_rgb(x, y, {5, 5, 5});
    std::vector<EnvironmentMap> maps = test_maps();
    maps[1] = EnvironmentMap(
        EnvironmentMap::make_sky(96, 48, normalize(Vec3{0.6, 0.5, -0.4}), big_sun), 1.5, 37.0);
    maps[2] = EnvironmentMap(block, 1, -71.3);
    for (size_t m = 0; m < maps.size(); ++m) {
        const EnvironmentMap& map = maps[m];
        const double integral =
            integrate_sphere([&](const Vec3& d) { return map.pdf(d); }, 512, 1024, 53 + m);
        EXPECT_NEAR(integral, 1.0, 0.01) << "map " << m;
    }
}

TEST(EnvironmentMapTest, PdfIntegratesToOneInMapCoordinates) {
    // Midpoints of 3 × 3 sub-cells per pixel of the map's own grid, taken to world directions:
    // pdf(ω) · 2π² sin θ is constant on each pixel, so the sum is exact for any rotation and
    // checks the world → map transform and the Jacobian of pdf() together.
    const std::vector<EnvironmentMap> maps = test_maps();
    for (size_t m = 0; m < maps.size(); ++m) {
        const EnvironmentMap& map = maps[m];
        const int columns = 3 * map.width(), rows = 3 * map.height();
        double sum = 0;
        for (int j = 0; j < rows; ++j)
            for (int i = 0; i < columns; ++i) {
                const double u = (i + 0.5) / columns, v = (j + 0.5) / rows;
                sum += map.pdf(map.map_to_world(u, v)) * 2 * kPi * kPi * std::sin(kPi * v);
            }
        EXPECT_NEAR(sum / (double(columns) * rows), 1.0, 1e-9) << "map " << m;
    }
}

TEST(EnvironmentMapTest, SamplesCarryTheirPdfAndRadiance) {
    const std::vector<EnvironmentMap> maps = test_maps();
    std::mt19937_64 rng(19);
    for (size_t m = 0; m < maps.size(); ++m) {
        const EnvironmentMap& map = maps[m];
        for (int k = 0; k < 5000; ++k) {
            const EnvSample s = map.sample(uniform01(rng), uniform01(rng));
            ASSERT_NEAR(length(s.direction), 1.0, 1e-12);
            ASSERT_EQ(s.pdf, map.pdf(s.direction)) << "map " << m;
            ASSERT_EQ(s.radiance, map.radiance(s.direction)) << "map " << m;
            ASSERT_GT(s.pdf, 0) << "map " << m;
        }
        // Wherever the lookup sees light the sampler can draw it.
        for (int k = 0; k < 20000; ++k) {
            const Vec3 d = uniform_sphere(uniform01(rng), uniform01(rng));
            if (luminance(map.radiance(d)) > 0) {
                ASSERT_GT(map.pdf(d), 0) << "map " << m;
            }
        }
    }
    EXPECT_EQ(maps[0].sample(0.3, 0.0).pdf, 0.0);  // v = 0 is the pole, where sin θ = 0
}

TEST(EnvironmentMapTest, SamplingHistogramMatchesPdf) {
    // A sky rotated by a whole number of pixels (5 of 32 columns), so each world-space bin of
    // the 32 × 16 histogram is one pixel and ∫_bin pdf dω is exact from a few midpoints.
    const EnvironmentMap map(EnvironmentMap::make_sky(32, 16, normalize(Vec3{-0.3, 0.4, 0.8})), 1,
                             5 * 360.0 / 32);
    constexpr int kW = 32, kH = 16, kSub = 4;
    std::vector<double> expected(size_t(kW) * kH, 0.0);
    constexpr int64_t kSamples = 100000;
    for (int r = 0; r < kH; ++r)
        for (int c = 0; c < kW; ++c) {
            double sum = 0;
            for (int j = 0; j < kSub; ++j)
                for (int i = 0; i < kSub; ++i) {
                    const double u = (c + (i + 0.5) / kSub) / kW, v = (r + (j + 0.5) / kSub) / kH;
                    const Vec3 d = latlong_to_direction(u, v);
                    sum += map.pdf(d) * 2 * kPi * kPi * std::sin(kPi * v);
                }
            expected[size_t(r) * kW + c] = sum / (kSub * kSub) / (kW * kH) * kSamples;
        }
    double total = 0;
    for (double e : expected) total += e;
    EXPECT_NEAR(total / kSamples, 1.0, 1e-9);

    std::vector<int64_t> observed(expected.size(), 0);
    std::mt19937_64 rng(23);
    for (int64_t k = 0; k < kSamples; ++k) {
        const LatLong p =
            direction_to_latlong(map.sample(uniform01(rng), uniform01(rng)).direction);
        const int c = std::min(int(p.u * kW), kW - 1), r = std::min(int(p.v * kH), kH - 1);
        ++observed[size_t(r) * kW + c];
    }
    int64_t unexpected = 0;
    EXPECT_GE(chi_square_p(expected, observed, unexpected), 1e-3);
    EXPECT_EQ(unexpected, 0);
}

// Irradiance E = ∫ L cos θ dω over the upper hemisphere (luminance), importance-sampled.
double irradiance_importance(const EnvironmentMap& map, int samples, uint64_t seed) {
    std::mt19937_64 rng(seed);
    double sum = 0;
    for (int k = 0; k < samples; ++k) {
        const EnvSample s = map.sample(uniform01(rng), uniform01(rng));
        if (s.pdf > 0 && s.direction.y > 0) sum += luminance(s.radiance) * s.direction.y / s.pdf;
    }
    return sum / samples;
}

// The same by stratified uniform sampling of the hemisphere (jittered equal-area cells).
double irradiance_uniform(const EnvironmentMap& map, int rows, int columns, uint64_t seed) {
    std::mt19937_64 rng(seed);
    double sum = 0;
    for (int j = 0; j < rows; ++j)
        for (int i = 0; i < columns; ++i) {
            const double y = (j + uniform01(rng)) / rows, r = std::sqrt(1 - y * y);
            const double phi = 2 * kPi * (i + uniform01(rng)) / columns;
            sum += luminance(map.radiance({r * std::cos(phi), y, r * std::sin(phi)})) * y;
        }
    return sum * 2 * kPi / (double(rows) * columns);
}

TEST(EnvironmentMapTest, ConstantMapIrradianceIsPi) {
    const EnvironmentMap map(Image(64, 32, 3, 1.0f));
    EXPECT_NEAR(map.average_luminance(), 1.0, 1e-6);
    EXPECT_NEAR(irradiance_importance(map, 20000, 29), kPi, 0.01 * kPi);
    EXPECT_NEAR(irradiance_uniform(map, 64, 128, 31), kPi, 0.001 * kPi);
    const EnvironmentMap doubled(Image(64, 32, 1, 0.5f), 4);  // grey, scaled
    EXPECT_NEAR(irradiance_importance(doubled, 20000, 37), 2 * kPi, 0.02 * kPi);
    EXPECT_NEAR(doubled.average_luminance(), 2.0, 2e-6);
}

TEST(EnvironmentMapTest, SkyIrradianceImportanceMatchesUniform) {
    const Vec3 sun = normalize(Vec3{0.5, 0.9, 0.3});
    const EnvironmentMap map(EnvironmentMap::make_sky(256, 128, sun), 1, 15);
    const double brute = irradiance_uniform(map, 512, 1024, 41);
    const double importance = irradiance_importance(map, 100000, 43);
    EXPECT_NEAR(importance / brute, 1.0, 0.015) << importance << " vs " << brute;

    // The sun provides about sun_fraction of the upward irradiance.
    SkyOptions no_sun;
    no_sun.sun_fraction = 0;
    const EnvironmentMap sky_only(EnvironmentMap::make_sky(256, 128, sun, no_sun), 1, 15);
    const double sky = irradiance_uniform(sky_only, 512, 1024, 41);
    EXPECT_NEAR(1 - sky / brute, SkyOptions{}.sun_fraction, 0.03);

    // average_luminance() against a quadrature of the lookup.
    const double mean =
        integrate_sphere([&](const Vec3& d) { return luminance(map.radiance(d)); }, 512, 1024, 59) /
        (4 * kPi);
    EXPECT_NEAR(map.average_luminance() / mean, 1.0, 0.01);
}

TEST(EnvironmentMapTest, ImportanceSamplingHasLowVarianceOnTheSky) {
    // The point of the module: on a sun-dominated sky, radiance / pdf varies far less than with
    // uniform sampling.
    const Vec3 sun = normalize(Vec3{-0.2, 0.7, 0.6});
    const EnvironmentMap map(EnvironmentMap::make_sky(256, 128, sun));
    std::mt19937_64 rng(47);
    double sum = 0, sum_sq = 0, usum = 0, usum_sq = 0;
    constexpr int kSamples = 20000;
    for (int k = 0; k < kSamples; ++k) {
        const EnvSample s = map.sample(uniform01(rng), uniform01(rng));
        const double f = s.pdf > 0 ? luminance(s.radiance) / s.pdf : 0;
        sum += f, sum_sq += f * f;
        const double g =
            luminance(map.radiance(uniform_sphere(uniform01(rng), uniform01(rng)))) * 4 * kPi;
        usum += g, usum_sq += g * g;
    }
    const double variance = sum_sq / kSamples - std::pow(sum / kSamples, 2);
    const double uniform_variance = usum_sq / kSamples - std::pow(usum / kSamples, 2);
    EXPECT_LT(variance, 0.05 * uniform_variance);
}

TEST(EnvironmentMapTest, ConstructorRejectsBadInput) {
    EXPECT_NE(test::error_of([] { EnvironmentMap{Image()}; }).find("environment map has 0 × 0"),
              std::string::npos);
    EXPECT_NE(test::error_of([] { EnvironmentMap{Image(4, 2, 2)}; }).find("2 channels"),
              std::string::npos);
    EXPECT_NE(test::error_of([] { EnvironmentMap(Image(4, 2, 3, 1.0f), -1); }).find("scale"),
              std::string::npos);
    Image bad(4, 2, 3, 1.0f);
    bad.at(3, 1, 2) = std::nanf("");
    const std::string message = test::error_of([&] { EnvironmentMap{bad}; });
    EXPECT_NE(message.find("column 3, row 1"), std::string::npos) << message;
}

TEST(EnvironmentMapTest, FromFileErrorsNameTheFile) {
    const test::TempFolder folder("envmap");
    const std::filesystem::path missing = folder.path() / "missing_sky.exr";
    EXPECT_NE(test::error_of([&] { EnvironmentMap::from_file(missing); }).find("missing_sky.exr"),
              std::string::npos);

    Image image(8, 4, 3, 0.25f);
    image.at(5, 2, 1) = -0.5f;
    const std::filesystem::path negative = folder.path() / "negative_sky.exr";
    write_image(negative, image);
    const std::string message = test::error_of([&] { EnvironmentMap::from_file(negative); });
    EXPECT_NE(message.find("negative_sky.exr: environment map pixel (column 5, row 2) channel 1 "
                           "is -0.5"),
              std::string::npos)
        << message;

    image.at(5, 2, 1) = 1.0f;
    const std::filesystem::path good = folder.path() / "good_sky.exr";
    write_image(good, image);
    const EnvironmentMap map = EnvironmentMap::from_file(good, 2, 0);
    EXPECT_EQ(map.width(), 8);
    EXPECT_EQ(map.height(), 4);
    EXPECT_FLOAT_EQ(map.radiance(latlong_to_direction(5.5 / 8, 2.5 / 4)).g, 2.0f);
    EXPECT_FLOAT_EQ(map.image().at(0, 0, 0), 0.5f);
}

TEST(EnvironmentMapTest, MakeSky) {
    const Vec3 sun = normalize(Vec3{0.3, 0.6, -0.7});
    const SkyOptions options;
    const Image sky = EnvironmentMap::make_sky(256, 128, sun, options);
    ASSERT_EQ(sky.width(), 256);
    ASSERT_EQ(sky.height(), 128);
    EXPECT_EQ(sky.values(), EnvironmentMap::make_sky(256, 128, sun, options).values());

    // The brightest pixel is on the sun.
    int best_x = 0, best_y = 0;
    double best = -1;
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 256; ++x)
            if (luminance(sky.rgb(x, y)) > best)
                best = luminance(sky.rgb(x, y)), best_x = x, best_y = y;
    const Vec3 brightest = latlong_to_direction((best_x + 0.5) / 256, (best_y + 0.5) / 128);
    EXPECT_LT(degrees(angle_between(brightest, sun)), options.sun_radius_degrees);
    const EnvironmentMap map(sky);
    EXPECT_GT(luminance(map.radiance(sun)), 1000 * luminance(map.radiance({0, 1, 0})));

    // Sky above the horizon (away from the sun) is brighter than the ground; the horizon is
    // brighter and paler than the deep blue zenith; the ground is brown.
    const auto at = [&](double elevation_degrees, double azimuth_degrees) {
        const double e = radians(elevation_degrees), a = radians(azimuth_degrees);
        return map.radiance({std::cos(e) * std::cos(a), std::sin(e), std::cos(e) * std::sin(a)});
    };
    const Rgb zenith = at(85, 120), horizon = at(3, 120), ground = at(-30, 120);
    EXPECT_GT(luminance(horizon), luminance(zenith));
    EXPECT_GT(luminance(zenith), luminance(ground));
    EXPECT_GT(zenith.b, zenith.r);
    EXPECT_GT(ground.r, ground.g);
    EXPECT_GT(ground.g, ground.b);
    double above = 0, below = 0;
    for (int x = 0; x < 256; ++x)
        above += luminance(sky.rgb(x, 10)), below += luminance(sky.rgb(x, 100));
    EXPECT_GT(above, 2 * below);

    // A sun under the horizon still yields a finite, valid map.
    const Image night = EnvironmentMap::make_sky(64, 32, {0, -1, 0.2});
    for (float value : night.values()) ASSERT_TRUE(std::isfinite(value) && value >= 0);
    EXPECT_NE(test::error_of([] {
                  EnvironmentMap::make_sky(0, 4, {0, 1, 0});
              }).find("0 × 4"),
              std::string::npos);
    EXPECT_NE(test::error_of([] {
                  EnvironmentMap::make_sky(8, 4, {0, 0, 0});
              }).find("sun"),
              std::string::npos);
}

}  // namespace
}  // namespace btf::render

// SPDX-License-Identifier: MIT
#include "btf/core/light_sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "btf/codecs/fmf/fmf.h"
#include "btf/core/color.h"
#include "btf/synth/synth.h"
#include "btf/testing/chi_square.h"
#include "btf/testing/function_material.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

// 14 views spread over the UBO2003 rings × all 81 UBO2003 lights, so that the lobes are resolved.
Sampling fourteen_views_all_lights() {
    return {test::ubo_subset(14, 1).views, DirectionSet::ubo81()};
}

// The fmf package (16 components) of a 16² synthetic material.
Package synth_package(const std::string& preset) {
    const auto source = synth::make(preset, 16, fourteen_views_all_lights(), 3);
    const auto cached = test::cached(*source);
    return fmf_codec().encode(*cached, {{"components", "16"}, {"colour", "rgb"}});
}

// A glossy material shared by the tests (brushed metal: anisotropic GGX highlights).
const Material& glossy() {
    static const std::unique_ptr<Material> material =
        fmf_codec().open(synth_package("brushed_metal"));
    return *material;
}

// (uv, ωo) pairs off the sampled views, at several elevations and azimuths.
struct Case {
    Uv uv;
    Vec3 wo;
};
std::vector<Case> cases() {
    return {{{0.13, 0.71}, Direction::from_degrees(0, 0).vector()},
            {{0.52, 0.08}, Direction::from_degrees(27, 40).vector()},
            {{0.91, 0.44}, Direction::from_degrees(48, 200).vector()},
            {{0.37, 0.96}, Direction::from_degrees(71, 305).vector()}};
}

TEST(LightSampler, MaterialDefaultsUseTheGenericSampler) {
    const Material& m = glossy();
    EXPECT_FALSE(m.native_sampling());
    EXPECT_EQ(&m.generic_sampler(), &m.generic_sampler());
    const Case c = cases()[1];
    const LightSample a = m.sample(c.uv, c.wo, 0.3, 0.8);
    const LightSample b = m.generic_sampler().sample(c.uv, c.wo, 0.3, 0.8);
    EXPECT_EQ(a.wi, b.wi);
    EXPECT_EQ(a.pdf, b.pdf);
    EXPECT_EQ(m.pdf(c.uv, c.wo, a.wi), a.pdf);
    EXPECT_EQ(m.generic_sampler().tile_size(), 16);
    EXPECT_EQ(m.generic_sampler().tiles_x(), 1);
    // sample_batch() defaults to sample() one by one.
    const std::vector<SampleQuery> queries = {{c.uv, c.wo, 0.3, 0.8}, {c.uv, c.wo, 0.9, 0.1}};
    std::vector<LightSample> batch(2);
    m.sample_batch(queries, batch);
    EXPECT_EQ(batch[0].wi, a.wi);
    EXPECT_EQ(batch[1].wi, m.sample(c.uv, c.wo, 0.9, 0.1).wi);
    batch.resize(1);
    EXPECT_EQ(test::error_of([&] { m.sample_batch(queries, batch); }),
              "sample_batch: 2 queries but 1 outputs");
}

TEST(LightSampler, SampleReportsItsPdfValueAndWeight) {
    const Material& m = glossy();
    std::mt19937_64 rng(11);
    for (const Case& c : cases())
        for (int k = 0; k < 2000; ++k) {
            const double xi1 = test::uniform01(rng), xi2 = test::uniform01(rng);
            const LightSample s = m.sample(c.uv, c.wo, xi1, xi2);
            ASSERT_NEAR(length(s.wi), 1.0, 1e-12);
            ASSERT_GE(s.wi.z, 0.0);
            ASSERT_GT(s.pdf, 0.0);
            ASSERT_EQ(s.pdf, m.pdf(c.uv, c.wo, s.wi)) << "xi " << xi1 << ", " << xi2;
            const Rgb v = m.eval(c.uv, s.wi, c.wo);
            ASSERT_EQ(s.value, v);
            ASSERT_FLOAT_EQ(s.weight.g, static_cast<float>(v.g / s.pdf));
        }
    // Below the horizon the pdf is 0; ξ outside [0, 1) is clamped.
    const Case c = cases()[2];
    EXPECT_EQ(m.pdf(c.uv, c.wo, {0.3, 0.1, -0.5}), 0.0);
    EXPECT_EQ(m.sample(c.uv, c.wo, -1, 2).wi, m.sample(c.uv, c.wo, 0, 1 - 0x1p-53).wi);
}

TEST(LightSampler, PdfIntegratesToOne) {
    // The pdf is piecewise constant on the sampler's 32² grid. 1000² midpoints, not aligned
    // with it, integrate it within 1e-3 (a grid cell cut by a quadrature boundary is off by at
    // most a quadrature cell's share of its jump; measured ≤ 7e-4); 256² midpoints, aligned,
    // exactly.
    const Material& m = glossy();
    for (const Case& c : cases()) {
        double smallest = INFINITY;
        const auto pdf = [&](const Vec3& wi) {
            const double p = m.pdf(c.uv, c.wo, wi);
            smallest = std::min(smallest, p);
            return p;
        };
        EXPECT_NEAR(test::integrate_hemisphere(pdf, 1000), 1.0, 1e-3);
        EXPECT_NEAR(test::integrate_hemisphere(pdf, 256), 1.0, 1e-6);
        // The uniform 10 % keeps the pdf at or above 0.1 / (2π) everywhere.
        EXPECT_GE(smallest, 0.1 / (2 * kPi) * (1 - 1e-5));
    }
    const test::FunctionMaterial lambert = test::lambertian_material({0.5f, 0.5f, 0.5f});
    const Vec3 wo = Direction::from_degrees(33, 10).vector();
    EXPECT_NEAR(test::integrate_hemisphere(
                    [&](const Vec3& wi) {
                        return lambert.pdf({0.2, 0.2}, wo, wi);
                    },
                    250),
                1.0, 1e-3);
}

TEST(LightSampler, ChiSquareAgainstPdf) {
    const Material& m = glossy();
    uint64_t seed = 1;
    for (const Case& c : cases()) {
        // 48² bins straddle the sampler's 32² cells, so that the placement of samples inside a
        // cell is tested too; 4² sub-cells per bin (192² in all) integrate the piecewise
        // constant pdf exactly.
        test::ChiSquareOptions options;
        options.resolution = 48;
        options.supersampling = 4;
        options.samples = 300000;
        options.seed = seed++;
        const test::ChiSquareResult r = test::chi_square_hemisphere(
            [&](double xi1, double xi2) { return m.sample(c.uv, c.wo, xi1, xi2).wi; },
            [&](const Vec3& wi) { return m.pdf(c.uv, c.wo, wi); }, options);
        EXPECT_TRUE(r.passed(1e-3)) << r.describe();
        EXPECT_NEAR(r.pdf_integral, 1.0, 1e-6);
    }
}

TEST(ChiSquare, RejectsASamplerThatDoesNotFollowItsPdf) {
    // Cosine-weighted directions tested against the uniform pdf and against a pdf 5 % too high.
    const auto cosine = [](double xi1, double xi2) {
        const DiskPoint d = square_to_disk({xi1, xi2});
        return Vec3{d.x, d.y, std::sqrt(std::max(0.0, 1 - d.x * d.x - d.y * d.y))};
    };
    const test::ChiSquareResult good =
        test::chi_square_hemisphere(cosine, [](const Vec3& w) { return w.z / kPi; });
    EXPECT_TRUE(good.passed(1e-3)) << good.describe();
    EXPECT_NEAR(good.pdf_integral, 1.0, 1e-3);
    const test::ChiSquareResult uniform =
        test::chi_square_hemisphere(cosine, [](const Vec3&) { return 1 / (2 * kPi); });
    EXPECT_LT(uniform.p_value, 1e-10) << uniform.describe();
    const test::ChiSquareResult scaled =
        test::chi_square_hemisphere(cosine, [](const Vec3& w) { return 1.05 * w.z / kPi; });
    EXPECT_FALSE(scaled.passed(1e-3)) << scaled.describe();
    // Samples where the pdf is zero fail outright.
    const test::ChiSquareResult zero = test::chi_square_hemisphere(
        cosine, [](const Vec3& w) { return w.x > 0 ? 2 * w.z / kPi : 0.0; });
    EXPECT_GT(zero.unexpected, 0);
    EXPECT_FALSE(zero.passed(1e-3));
}

TEST(LightSampler, LambertianAlbedoAndEstimator) {
    const Rgb rho{0.8f, 0.5f, 0.2f};
    const test::FunctionMaterial m = test::lambertian_material(rho);
    std::mt19937_64 rng(5);
    for (const Case& c : cases()) {
        // The midpoint rule on the R² equal-area grid overestimates ∫ cos θ dω by exactly 2/R²
        // relative (cos θ = 1 − r² on the concentric disk, quadratic across each cell).
        const Rgb a = m.albedo(c.uv, c.wo);
        const double bias = 1 + 2.0 / (32 * 32);
        EXPECT_NEAR(a.r, rho.r * bias, 1e-6);
        EXPECT_NEAR(a.g, rho.g * bias, 1e-6);
        EXPECT_NEAR(a.b, rho.b * bias, 1e-6);
        EXPECT_NEAR(quadrature_albedo(m, c.uv, c.wo, 128).r, rho.r * (1 + 2.0 / (128 * 128)), 1e-6);
        // E[value / pdf] = ∫ ρ cos θi dωi = π ρ. The sampler follows cos θi up to its grid and
        // the 10 % uniform share, so the weights vary little; 4 standard errors.
        constexpr int kN = 20000;
        double sum = 0, sum2 = 0;
        for (int k = 0; k < kN; ++k) {
            const LightSample s = m.sample(c.uv, c.wo, test::uniform01(rng), test::uniform01(rng));
            sum += s.weight.r, sum2 += double(s.weight.r) * s.weight.r;
        }
        const double mean = sum / kN, var = sum2 / kN - mean * mean;
        EXPECT_NEAR(mean, kPi * rho.r, 4 * std::sqrt(var / kN) + 1e-9);
        // Relative standard deviation of one weight: uniform sampling gives 1/√3 ≈ 0.58 (cos θi
        // is uniform on [0, 1] then); the table brings it well below 0.2.
        EXPECT_LT(std::sqrt(var) / mean, 0.2);
    }
}

TEST(LightSampler, AlbedoIsEvaluatedAtTheQuery) {
    // Albedo varies with u and with the view: it is not a tile average or a nearest view.
    const DirectionSet& ubo = DirectionSet::ubo81();
    const test::FunctionMaterial m(
        32, 32, {ubo, ubo}, [](const Uv& uv, const Vec3& wi, const Vec3& wo) {
            const float s = static_cast<float>((0.25 + uv.u) * (1 + wo.x) * std::max(wi.z, 0.0));
            return Rgb{s, s, s};
        });
    const Vec3 wo = Direction::from_degrees(40, 0).vector();
    const double expected = (0.25 + 0.3) * (1 + wo.x);
    EXPECT_NEAR(m.albedo({0.3, 0.5}, wo).g, expected * (1 + 2.0 / (32 * 32)), 1e-6);
    EXPECT_NEAR(quadrature_albedo(m, {0.3, 0.5}, wo, 128).g, expected * (1 + 2.0 / (128 * 128)),
                1e-6);
    EXPECT_NE(m.albedo({0.3, 0.5}, wo).g, m.albedo({0.31, 0.5}, wo).g);
    EXPECT_EQ(test::error_of([&] {
                  quadrature_albedo(m, {0, 0}, wo, 0);
              }),
              "albedo: quadrature resolution 0 out of range [1, 1024]");
}

// Luminance of the weights value / pdf for directions from `draw`, and their variance.
template <typename Draw>
double weight_variance(Draw&& draw, int n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    double sum = 0, sum2 = 0;
    for (int k = 0; k < n; ++k) {
        const double w = draw(test::uniform01(rng), test::uniform01(rng));
        sum += w, sum2 += w * w;
    }
    const double mean = sum / n;
    return sum2 / n - mean * mean;
}

TEST(LightSampler, ImportanceSamplingLowersVarianceOnAGlossyMaterial) {
    // Variance of the luminance of value / pdf: the blended tables against uniform hemisphere
    // sampling and against the nearest view's table alone (equal at a sampled view: case 0).
    const Material& m = glossy();
    LightSamplerOptions options;
    options.view_blend = ViewBlend::kNearest;
    const LightSampler nearest(m, options);
    for (const Case& c : cases()) {
        const double blended = weight_variance(
            [&](double xi1, double xi2) {
                return double(luminance(m.sample(c.uv, c.wo, xi1, xi2).weight));
            },
            20000, 9);
        const double single = weight_variance(
            [&](double xi1, double xi2) {
                return double(luminance(nearest.sample(c.uv, c.wo, xi1, xi2).weight));
            },
            20000, 9);
        const double uniform = weight_variance(
            [&](double xi1, double xi2) {
                const Vec3 wi = square_to_hemisphere({xi1, xi2});
                return double(luminance(m.eval(c.uv, wi, c.wo))) * 2 * kPi;
            },
            20000, 9);
        EXPECT_LT(blended, 0.1 * uniform) << "blended " << blended << ", uniform " << uniform;
        EXPECT_LE(blended, 1.0001 * single) << "blended " << blended << ", nearest " << single;
    }
}

TEST(LightSampler, NearestViewOptionPassesChiSquare) {
    const Material& m = glossy();
    LightSamplerOptions options;
    options.view_blend = ViewBlend::kNearest;
    const LightSampler nearest(m, options);
    const Case c = cases()[2];
    const test::ChiSquareResult r = test::chi_square_hemisphere(
        [&](double xi1, double xi2) { return nearest.sample(c.uv, c.wo, xi1, xi2).wi; },
        [&](const Vec3& wi) { return nearest.pdf(c.uv, c.wo, wi); });
    EXPECT_TRUE(r.passed(1e-3)) << r.describe();
    // A sampled direction's table alone: the same distribution as the blend there.
    const Vec3 view = m.sampling().views.vector(3);
    for (const Vec3& wi : {Vec3{0, 0, 1}, Direction::from_degrees(40, 100).vector()})
        EXPECT_DOUBLE_EQ(nearest.pdf(c.uv, view, wi), m.pdf(c.uv, view, wi));
}

TEST(LightSampler, TablesFollowTheTexelTile) {
    // Left half lit from +x, right half from −x: a 32-texel-wide material has two 16-texel
    // tiles side by side, and samples lean toward the lobe of their own tile.
    const DirectionSet& ubo = DirectionSet::ubo81();
    const test::FunctionMaterial m(
        32, 16, {ubo, ubo}, [](const Uv& uv, const Vec3& wi, const Vec3&) {
            const double side = uv.u < 0.5 ? wi.x : -wi.x;
            const float s =
                static_cast<float>(std::max(wi.z, 0.0) * std::pow(std::max(side, 0.0), 4));
            return Rgb{s, s, s};
        });
    EXPECT_EQ(m.generic_sampler().tiles_x(), 2);
    const Vec3 wo = Direction::from_degrees(20, 90).vector();
    std::mt19937_64 rng(3);
    int left_positive = 0, right_positive = 0;
    for (int k = 0; k < 1000; ++k) {
        const double xi1 = test::uniform01(rng), xi2 = test::uniform01(rng);
        left_positive += m.sample({0.2, 0.5}, wo, xi1, xi2).wi.x > 0;
        right_positive += m.sample({0.8, 0.5}, wo, xi1, xi2).wi.x > 0;
    }
    // The uniform 10 % puts half its samples on the other side: about 950 and 50 expected.
    EXPECT_GT(left_positive, 900);
    EXPECT_LT(right_positive, 100);
    // Two tiles × the views around ωo (one table per tile and view).
    int views = 0;
    const AngularWeights w = AngularInterpolator(ubo).weights(wo);
    for (int k = 0; k < w.count; ++k) views += w.weight[k] > 0;
    EXPECT_EQ(m.generic_sampler().tables_built(), 2 * views);
}

TEST(LightSampler, TablesFollowTheView) {
    // A mirror-like lobe around the reflection of ωo: the sampler's lobe moves with the view, at
    // the sampled views and between them.
    const DirectionSet& ubo = DirectionSet::ubo81();
    const test::FunctionMaterial m(4, 4, {ubo, ubo}, [](const Uv&, const Vec3& wi, const Vec3& wo) {
        const Vec3 mirror{-wo.x, -wo.y, wo.z};
        const float s = static_cast<float>(std::pow(std::max(dot(wi, mirror), 0.0), 30));
        return Rgb{s, s, s};
    });
    std::mt19937_64 rng(4);
    for (const Vec3& wo :
         {ubo.vector(0), ubo.vector(20), ubo.vector(50), ubo.vector(80),
          Direction::from_degrees(22, 17).vector(), Direction::from_degrees(52, 200).vector()}) {
        const Vec3 mirror{-wo.x, -wo.y, wo.z};
        double mean_cos = 0;
        for (int k = 0; k < 1000; ++k)
            mean_cos += dot(m.sample({0.5, 0.5}, wo, test::uniform01(rng), test::uniform01(rng)).wi,
                            mirror);
        // 90 % of the samples in a lobe of cos^30 (mean cosine ≈ 0.95), 10 % uniform (mean ≈
        // 0.5 at the zenith, less elsewhere).
        EXPECT_GT(mean_cos / 1000, 0.8) << "view " << wo.x << ", " << wo.y << ", " << wo.z;
    }
}

TEST(LightSampler, ManyThreadsGiveTheSameSamplesAsOne) {
    const Package package = synth_package("lacquered_wood");
    const auto one = fmf_codec().open(package), many = fmf_codec().open(package);
    struct Draw {
        Uv uv;
        Vec3 wo;
        double xi1, xi2;
    };
    std::vector<Draw> draws(4000);
    std::mt19937_64 rng(8);
    for (Draw& d : draws) {
        d.uv = {test::uniform01(rng), test::uniform01(rng)};
        d.wo = square_to_hemisphere({test::uniform01(rng), test::uniform01(rng)});
        d.xi1 = test::uniform01(rng);
        d.xi2 = test::uniform01(rng);
    }
    std::vector<LightSample> expected(draws.size());
    std::vector<double> expected_pdf(draws.size());
    for (size_t i = 0; i < draws.size(); ++i) {
        const Draw& d = draws[i];
        expected[i] = one->sample(d.uv, d.wo, d.xi1, d.xi2);
        expected_pdf[i] = one->pdf(d.uv, d.wo, expected[i].wi);
    }
    // Eight threads start on a cold cache at the same time, each taking every draw in its own
    // rotated order, so that they race to build the same tables.
    constexpr int kThreads = 8;
    std::vector<std::vector<LightSample>> got(kThreads, std::vector<LightSample>(draws.size()));
    std::vector<std::vector<double>> got_pdf(kThreads, std::vector<double>(draws.size()));
    std::atomic<int> ready{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t)
        threads.emplace_back([&, t] {
            ready.fetch_add(1);
            while (ready.load() < kThreads) std::this_thread::yield();
            for (size_t k = 0; k < draws.size(); ++k) {
                const size_t i = (k + t * draws.size() / kThreads) % draws.size();
                const Draw& d = draws[i];
                got[t][i] = many->sample(d.uv, d.wo, d.xi1, d.xi2);
                got_pdf[t][i] = many->pdf(d.uv, d.wo, got[t][i].wi);
            }
        });
    for (std::thread& t : threads) t.join();
    for (int t = 0; t < kThreads; ++t)
        for (size_t i = 0; i < draws.size(); ++i) {
            ASSERT_EQ(got[t][i].wi, expected[i].wi) << "thread " << t << " draw " << i;
            ASSERT_EQ(got[t][i].pdf, expected[i].pdf);
            ASSERT_EQ(got[t][i].value, expected[i].value);
            ASSERT_EQ(got_pdf[t][i], expected_pdf[i]);
        }
    EXPECT_EQ(many->generic_sampler().tables_built(), one->generic_sampler().tables_built());
}

TEST(LightSampler, TileGrowsToFitTheMemoryBudget) {
    const test::FunctionMaterial m = test::lambertian_material({1, 1, 1}, 256);
    const LightSampler roomy(m);
    EXPECT_EQ(roomy.tile_size(), 16);
    EXPECT_EQ(roomy.tiles_x(), 16);
    EXPECT_EQ(roomy.table_bytes(), 33 * 33 * 4);
    LightSamplerOptions tight;
    // All tables: 86.1 MiB with 16² tiles, 21.5 MiB with 32², 5.4 MiB with 64².
    tight.memory_budget = int64_t(20) << 20;
    const LightSampler small(m, tight);
    EXPECT_EQ(small.tile_size(), 64);
    EXPECT_EQ(small.tiles_x(), 4);
    tight.memory_budget = 1;  // not even one table per view: one tile over the whole material
    EXPECT_EQ(LightSampler(m, tight).tile_size(), 256);
}

TEST(LightSampler, RejectsBadOptions) {
    const test::FunctionMaterial m = test::lambertian_material({1, 1, 1});
    auto with = [&](auto set) {
        LightSamplerOptions o;
        set(o);
        return test::error_of([&] { LightSampler s(m, o); });
    };
    EXPECT_EQ(with([](auto& o) { o.resolution = 0; }),
              "light sampler: resolution 0 out of range [1, 1024]");
    EXPECT_EQ(with([](auto& o) { o.uniform_fraction = 0; }),
              "light sampler: uniform fraction 0 out of range (0, 1]");
    EXPECT_EQ(with([](auto& o) { o.tile_size = 0; }),
              "light sampler: tile size 0 out of range [1, 65536]");
    EXPECT_EQ(with([](auto& o) { o.points_per_side = 65; }),
              "light sampler: points per side 65 out of range [1, 64]");
    EXPECT_EQ(with([](auto& o) { o.memory_budget = 0; }),
              "light sampler: memory budget 0 bytes is not positive");
    const test::FunctionMaterial empty(4, 4, {DirectionSet(), DirectionSet::ubo81()},
                                       [](const Uv&, const Vec3&, const Vec3&) { return Rgb{}; });
    EXPECT_EQ(test::error_of([&] { LightSampler s(empty); }),
              "light sampler: the material has no views");
}

TEST(LightSampler, UniformWhereTheMaterialIsBlack) {
    const test::FunctionMaterial black = test::lambertian_material({0, 0, 0});
    const Vec3 wo = Direction::from_degrees(30, 30).vector();
    for (const Vec3& wi : {Vec3{0, 0, 1}, Direction::from_degrees(80, 200).vector()})
        EXPECT_NEAR(black.pdf({0.5, 0.5}, wo, wi), 1 / (2 * kPi), 1e-6);
    const LightSample s = black.sample({0.5, 0.5}, wo, 0.25, 0.75);
    EXPECT_EQ(s.value, (Rgb{0, 0, 0}));
    EXPECT_EQ(s.weight, (Rgb{0, 0, 0}));
}

TEST(LightSampler, CopiedMaterialBuildsItsOwnSampler) {
    const test::FunctionMaterial a = test::lambertian_material({0.5f, 0.5f, 0.5f});
    const LightSampler& sa = a.generic_sampler();
    const test::FunctionMaterial b = a;  // NOLINT(performance-unnecessary-copy-initialization)
    EXPECT_NE(&b.generic_sampler(), &sa);
    const Vec3 wo{0, 0, 1};
    EXPECT_EQ(a.sample({0.1, 0.1}, wo, 0.4, 0.6).wi, b.sample({0.1, 0.1}, wo, 0.4, 0.6).wi);
}

}  // namespace
}  // namespace btf

// SPDX-License-Identifier: MIT
// Stochastic filtering (core/material.h, ShadingPoint) for every codec and for UBO2014 files:
// the mean of many stochastic evaluations at a fixed query is the filtered value, a test of that
// which fails when the selection probabilities are perturbed, the batch call against the shading
// point, and the χ² test of a stochastic vertex's sampling against its pdf.
//
// The statistic: n = 10⁴ evaluations with filter numbers u from a fixed-seed generator; per
// channel the mean and its standard error s / √n; the test passes when |mean − reference| ≤ 4 SE
// (plus 1e-5 relative for float rounding). With linear colour decoding the reference is eval();
// with nonlinear decoding (CIELab planes of perceptual, UBO2014 colour model 11) it is the
// filter of decoded samples (lookup6d over eval_sample), and the gap between that and eval() is
// what filtering after decoding changes (docs/codecs.md, "Stochastic filtering").

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/codecs/lpca/lpca.h"
#include "btf/codecs/mlvq/mlvq.h"
#include "btf/codecs/pca_views/pca_views.h"
#include "btf/codecs/perceptual/perceptual.h"
#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"
#include "btf/core/light_sampler.h"
#include "btf/io/ubo2014.h"
#include "btf/synth/synth.h"
#include "btf/testing/chi_square.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

struct Case {
    std::string name;
    std::shared_ptr<const Material> material;
    bool linear = true;  ///< the codec's decoding after interpolation is linear
    /// eval() is lookup6d's interpolation over the sampled directions (mlvq has its own).
    bool shared_interpolation = true;
};

const BtfSource& source() {
    static const auto s =
        test::cached(*synth::make("woven_fabric", 16, test::ubo_subset(10, 10), 3));
    return *s;
}

std::shared_ptr<const Material> encoded(const Codec& codec, const Params& params) {
    Package package = codec.encode(source(), params);
    return std::shared_ptr<const Material>(
        open_material(decode_package(encode_package(package), "test")));
}

// A UBO2014 DFMF file of the source (exact SVD, K = 6) with colour model `model`, opened as
// `btf` opens a .btf file.
std::shared_ptr<const Material> dfmf(int32_t model, bool cosine) {
    static test::TempFolder dir("btf-stochastic");
    const fs::path path = dir.path() / ("m" + std::to_string(model) + (cosine ? "c" : "") + ".btf");
    ubo2014::FactorizeOptions options;
    options.components = 6;
    options.color_model = model;
    options.scalar_size = 2;
    options.meta.cosine_flag = cosine;
    ubo2014::write_dfmf(path, source(), options);
    return std::shared_ptr<const Material>(open_material(path));
}

const std::vector<Case>& cases() {
    static const std::vector<Case> all = [] {
        std::vector<Case> c;
        c.push_back({"fmf rgb", encoded(fmf_codec(), Params({{"components", "8"}}))});
        c.push_back(
            {"fmf decorrelated f32", encoded(fmf_codec(), Params({{"components", "8"},
                                                                  {"colour", "decorrelated"},
                                                                  {"quantize", "f32"}}))});
        c.push_back({"pca-views", encoded(pca_views_codec(), Params({{"components", "4"},
                                                                     {"views-per-group", "3"}}))});
        c.push_back(
            {"lpca", encoded(lpca_codec(), Params({{"clusters", "3"}, {"components", "3"}}))});
        c.push_back(
            {"perceptual", encoded(perceptual_codec(), Params({{"components", "12"}})), false});
        c.push_back({"mlvq", encoded(mlvq_codec(), Params({{"colour", "ycbcr"}})), true, false});
        c.push_back({"UBO2014 model 0", dfmf(ubo2014::kColorModelRgb, false)});
        c.push_back({"UBO2014 model 11", dfmf(ubo2014::kColorModelLogYUV, false), false});
        c.push_back({"UBO2014 cosine flag", dfmf(ubo2014::kColorModelRgb, true)});
        return c;
    }();
    return all;
}

struct Query {
    Uv uv;
    Vec3 wi, wo;
};

// Between texels, views and lights.
std::vector<Query> queries() {
    return {{{0.37, 0.61},
             Direction::from_degrees(38, 75).vector(),
             Direction::from_degrees(27, 200).vector()},
            {{0.81, 0.14},
             Direction::from_degrees(55, 310).vector(),
             Direction::from_degrees(48, 20).vector()},
            {{0.05, 0.93},
             Direction::from_degrees(12, 140).vector(),
             Direction::from_degrees(63, 95).vector()}};
}

// The filter of decoded samples: bilinear × barycentric × barycentric over eval_sample().
Rgb filter_of_samples(const Material& m, const Query& q) {
    const AngularInterpolator views(m.sampling().views), lights(m.sampling().lights);
    return lookup6d(
        q.uv, m.width(), m.height(), views.weights(q.wo), lights.weights(q.wi),
        [&](int x, int y, int view, int light) { return m.eval_sample(x, y, view, light); });
}

struct Mean {
    double mean[3], se[3];
};

// n stochastic evaluations with numbers warp(u), u uniform from a fixed seed; with
// `light_number`, every evaluation draws its light from a second number of its own, warped too.
Mean stochastic_mean(const Material& m, const Query& q, int n,
                     const std::function<double(double)>& warp, bool light_number = false) {
    std::mt19937_64 rng(77);
    double sum[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
    for (int i = 0; i < n; ++i) {
        const double u = warp(test::uniform01(rng));
        std::optional<double> light_u;
        if (light_number) light_u = warp(test::uniform01(rng));
        const Rgb v = ShadingPoint(m, q.uv, q.wo, Filter::kStochastic, u, light_u).eval(q.wi);
        const double c[3] = {v.r, v.g, v.b};
        for (int k = 0; k < 3; ++k) sum[k] += c[k], sq[k] += c[k] * c[k];
    }
    Mean r;
    for (int k = 0; k < 3; ++k) {
        r.mean[k] = sum[k] / n;
        const double var = std::max(0.0, (sq[k] - n * r.mean[k] * r.mean[k]) / (n - 1));
        r.se[k] = std::sqrt(var / n);
    }
    return r;
}

// Largest |mean − reference| / (4 SE + 1e-5 relative) over the channels: ≤ 1 passes.
double deviation(const Mean& s, const Rgb& ref) {
    const double r[3] = {ref.r, ref.g, ref.b};
    double worst = 0;
    for (int k = 0; k < 3; ++k) {
        const double allowed = 4 * s.se[k] + 1e-5 * std::max(1.0, std::abs(r[k]));
        worst = std::max(worst, std::abs(s.mean[k] - r[k]) / allowed);
    }
    return worst;
}

constexpr int kEvaluations = 10000;

TEST(StochasticFilter, MeanIsTheFilteredValueForEveryCodec) {
    for (const Case& c : cases()) {
        for (const Query& q : queries()) {
            const Rgb ref =
                c.linear ? c.material->eval(q.uv, q.wi, q.wo) : filter_of_samples(*c.material, q);
            const Mean s =
                stochastic_mean(*c.material, q, kEvaluations, [](double u) { return u; });
            EXPECT_LE(deviation(s, ref), 1.0)
                << c.name << ": mean " << s.mean[0] << " " << s.mean[1] << " " << s.mean[2] << " ± "
                << s.se[0] << " against " << ref.r << " " << ref.g << " " << ref.b;
            if (c.linear && c.shared_interpolation) {
                // Linear decoding: the filter of decoded samples is eval() itself.
                const Rgb f = filter_of_samples(*c.material, q);
                EXPECT_NEAR(f.r, ref.r, 1e-4 * std::max(1.0f, std::abs(ref.r))) << c.name;
                EXPECT_NEAR(f.b, ref.b, 1e-4 * std::max(1.0f, std::abs(ref.b))) << c.name;
            }
        }
    }
}

// A light number of its own (what the renderer gives a pixel's first vertex) keeps the mean, and
// the statistic sees the numbers perturbed.
TEST(StochasticFilter, MeanIsTheFilteredValueWithALightNumberOfItsOwn) {
    for (const Case& c : cases()) {
        double worst_perturbed = 0;
        for (const Query& q : queries()) {
            const Rgb ref =
                c.linear ? c.material->eval(q.uv, q.wi, q.wo) : filter_of_samples(*c.material, q);
            const Mean s = stochastic_mean(
                *c.material, q, kEvaluations, [](double u) { return u; }, true);
            EXPECT_LE(deviation(s, ref), 1.0)
                << c.name << ": mean " << s.mean[0] << " " << s.mean[1] << " " << s.mean[2] << " ± "
                << s.se[0] << " against " << ref.r << " " << ref.g << " " << ref.b;
            const Mean p = stochastic_mean(
                *c.material, q, kEvaluations, [](double u) { return u * u; }, true);
            worst_perturbed = std::max(worst_perturbed, deviation(p, ref));
        }
        EXPECT_GT(worst_perturbed, 1.0) << c.name << ": perturbed numbers went unnoticed";
    }
}

TEST(StochasticFilter, TheTestFailsWhenTheSelectionIsPerturbed) {
    // u → u² draws low indices (the first texel of each axis, the first view and light) more
    // often than their weights say: the statistic must see it on every material.
    for (const Case& c : cases()) {
        double worst = 0;
        for (const Query& q : queries()) {
            const Rgb ref =
                c.linear ? c.material->eval(q.uv, q.wi, q.wo) : filter_of_samples(*c.material, q);
            const Mean s =
                stochastic_mean(*c.material, q, kEvaluations, [](double u) { return u * u; });
            worst = std::max(worst, deviation(s, ref));
        }
        EXPECT_GT(worst, 1.0) << c.name << ": a perturbed selection went unnoticed";
    }
}

TEST(StochasticFilter, BatchEqualsTheShadingPoint) {
    std::mt19937_64 rng(5);
    for (const Case& c : cases()) {
        std::vector<StochasticQuery> qs;
        std::vector<StochasticSampleQuery> ss;
        for (int i = 0; i < 300; ++i) {
            const Uv uv{test::uniform01(rng), test::uniform01(rng)};
            const Vec3 wi = square_to_hemisphere({test::uniform01(rng), test::uniform01(rng)});
            const Vec3 wo = square_to_hemisphere({test::uniform01(rng), test::uniform01(rng)});
            const double u = test::uniform01(rng);
            qs.push_back({uv, wi, wo, u});
            ss.push_back({uv, wo, u, test::uniform01(rng), test::uniform01(rng)});
        }
        std::vector<Rgb> values(qs.size());
        c.material->eval_stochastic_batch(qs, values);
        std::vector<LightSample> drawn(ss.size());
        c.material->sample_stochastic_batch(ss, drawn);
        for (size_t i = 0; i < qs.size(); ++i) {
            const Rgb one =
                ShadingPoint(*c.material, qs[i].uv, qs[i].wo, Filter::kStochastic, qs[i].u)
                    .eval(qs[i].wi);
            const float tol = 1e-5f * std::max({1.0f, std::abs(one.r), std::abs(one.g)});
            ASSERT_NEAR(values[i].r, one.r, tol) << c.name << " query " << i;
            ASSERT_NEAR(values[i].g, one.g, tol) << c.name << " query " << i;
            ASSERT_NEAR(values[i].b, one.b, tol) << c.name << " query " << i;
            const LightSample s =
                ShadingPoint(*c.material, ss[i].uv, ss[i].wo, Filter::kStochastic, ss[i].u)
                    .sample(ss[i].xi1, ss[i].xi2);
            ASSERT_NEAR(drawn[i].wi.x, s.wi.x, 1e-9) << c.name << " sample " << i;
            ASSERT_NEAR(drawn[i].wi.z, s.wi.z, 1e-9) << c.name << " sample " << i;
            ASSERT_NEAR(drawn[i].pdf, s.pdf, 1e-9 * std::max(1.0, s.pdf))
                << c.name << " sample " << i;
        }
    }
}

// eval_sample_batch() returns eval_sample() of every index bit for bit (the factor evaluator's
// prefetching batch, mlvq's default loop), past its prefetch distance and at the edges of the
// material; an index outside it, or a count that does not match, is an error that says so.
TEST(StochasticFilter, EvalSampleBatchEqualsEvalSample) {
    std::mt19937_64 rng(9);
    for (const Case& c : cases()) {
        const Material& m = *c.material;
        std::uniform_int_distribution<int> x(0, m.width() - 1), y(0, m.height() - 1);
        std::uniform_int_distribution<int> view(0, m.sampling().num_views() - 1);
        std::uniform_int_distribution<int> light(0, m.sampling().num_lights() - 1);
        std::vector<SampleIndex> indices = {
            {0, 0, 0, 0}, {m.width() - 1, m.height() - 1, view.max(), light.max()}};
        for (int i = 0; i < 200; ++i) indices.push_back({x(rng), y(rng), view(rng), light(rng)});
        std::vector<Rgb> values(indices.size());
        m.eval_sample_batch(indices, values);
        for (size_t i = 0; i < indices.size(); ++i) {
            const SampleIndex& s = indices[i];
            const Rgb one = m.eval_sample(s.x, s.y, s.view, s.light);
            ASSERT_EQ(values[i].r, one.r) << c.name << " index " << i;
            ASSERT_EQ(values[i].g, one.g) << c.name << " index " << i;
            ASSERT_EQ(values[i].b, one.b) << c.name << " index " << i;
        }
        indices[150].light = light.max() + 1;
        EXPECT_NE(test::error_of([&] {
                      m.eval_sample_batch(indices, values);
                  }).find("light " + std::to_string(light.max() + 1) + ")"),
                  std::string::npos)
            << c.name;
        values.pop_back();
        EXPECT_NE(test::error_of([&] { m.eval_sample_batch(indices, values); }).find("outputs"),
                  std::string::npos)
            << c.name;
    }
}

TEST(StochasticFilter, VertexSamplingFollowsItsPdf) {
    // A stochastic vertex samples and reports densities for its own selection: χ² of sample()
    // against pdf() at fixed numbers u (Šidák-corrected over the cases).
    const std::vector<Query> qs = queries();
    const double alpha = 1 - std::pow(1 - 1e-3, 1.0 / (3.0 * cases().size()));
    uint64_t seed = 1;
    for (const Case& c : cases()) {
        for (size_t i = 0; i < qs.size(); ++i) {
            const ShadingPoint p(*c.material, qs[i].uv, qs[i].wo, Filter::kStochastic,
                                 0.13 + 0.31 * double(i));
            test::ChiSquareOptions options;
            options.resolution = 24;
            options.supersampling = 6;
            options.samples = 60000;
            options.seed = seed++;
            const test::ChiSquareResult r = test::chi_square_hemisphere(
                [&](double xi1, double xi2) { return p.sample(xi1, xi2).wi; },
                [&](const Vec3& wi) { return p.pdf(wi); }, options);
            EXPECT_TRUE(r.passed(alpha)) << c.name << " query " << i << ": " << r.describe();
            EXPECT_NEAR(r.pdf_integral, 1.0, 2e-3) << c.name << " query " << i;
            // The sample's value is the vertex's own evaluation.
            const LightSample s = p.sample(0.4, 0.7);
            const Rgb e = p.eval(s.wi);
            EXPECT_NEAR(s.value.r, e.r, 1e-6 * std::max(1.0f, std::abs(e.r))) << c.name;
            EXPECT_DOUBLE_EQ(s.pdf, p.pdf(s.wi)) << c.name;
        }
    }
}

TEST(StochasticFilter, DeterministicPointIsTheMaterialsOwnCalls) {
    const Material& m = *cases()[0].material;
    const Query q = queries()[0];
    const ShadingPoint p(m, q.uv, q.wo, Filter::kDeterministic, 0.5);
    const Rgb a = p.eval(q.wi), b = m.eval(q.uv, q.wi, q.wo);
    EXPECT_EQ(a.r, b.r);
    EXPECT_EQ(a.g, b.g);
    const LightSample s = p.sample(0.3, 0.6), t = m.sample(q.uv, q.wo, 0.3, 0.6);
    EXPECT_EQ(s.wi.x, t.wi.x);
    EXPECT_EQ(s.pdf, t.pdf);
    EXPECT_EQ(p.pdf(q.wi), m.pdf(q.uv, q.wo, q.wi));
    // No material: zero everywhere.
    const ShadingPoint none;
    EXPECT_EQ(none.eval(q.wi).r, 0.0f);
    EXPECT_EQ(none.pdf(q.wi), 0.0);
}

TEST(StochasticFilter, PickDrawsByWeightAndReusesTheNumber) {
    const float w[4] = {0.1f, 0.0f, 0.6f, 0.3f};
    double u = 0.05;
    EXPECT_EQ(pick<4>(w, 4, u), 0);
    EXPECT_NEAR(u, 0.5, 1e-6);
    u = 0.1;  // exactly on the boundary: the next positive weight
    EXPECT_EQ(pick<4>(w, 4, u), 2);
    EXPECT_NEAR(u, 0.0, 1e-6);
    u = 0.85;
    EXPECT_EQ(pick<4>(w, 4, u), 3);
    EXPECT_NEAR(u, 0.5, 1e-6);
    u = 0.999999999;
    EXPECT_EQ(pick<4>(w, 4, u), 3);
    EXPECT_LT(u, 1.0);
    const float zero[2] = {0, 0};
    u = 0.7;
    EXPECT_EQ(pick<2>(zero, 2, u), 0);
    // Frequencies over a stratified u: exactly the weights.
    int counts[4] = {0, 0, 0, 0};
    for (int i = 0; i < 10000; ++i) {
        double v = (i + 0.5) / 10000;
        ++counts[pick<4>(w, 4, v)];
    }
    EXPECT_EQ(counts[0], 1000);
    EXPECT_EQ(counts[1], 0);
    EXPECT_EQ(counts[2], 6000);
    EXPECT_EQ(counts[3], 3000);
}

TEST(StochasticFilter, ParsesFilterNames) {
    EXPECT_EQ(parse_filter("stochastic"), Filter::kStochastic);
    EXPECT_EQ(parse_filter("deterministic"), Filter::kDeterministic);
    EXPECT_STREQ(to_string(Filter::kStochastic), "stochastic");
    try {
        parse_filter("bilinear", "--filter");
        FAIL() << "no error";
    } catch (const Error& e) {
        EXPECT_STREQ(e.what(),
                     "--filter: 'bilinear' is not a filter (deterministic or stochastic)");
    }
}

}  // namespace
}  // namespace btf

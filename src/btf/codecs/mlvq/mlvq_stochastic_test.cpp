// SPDX-License-Identifier: MIT
// The stochastic filter of mlvq materials (MlvqMaterial::select() and the *_selected() hooks,
// reached through ShadingPoint): one texel × one view node of mlvq's own grid, drawn with
// probability equal to its weight in eval().

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "btf/codecs/mlvq/mlvq.h"
#include "btf/codecs/mlvq/small_grid_test.h"
#include "btf/core/btf_lookup.h"
#include "btf/synth/synth.h"
#include "btf/testing/chi_square.h"
#include "btf/testing/sources.h"
#include "btf/util/error.h"

namespace btf::mlvq {
namespace {
// A namespace of its own: a unity build compiles this file with mlvq_test.cpp and the other
// tests of the module, whose helpers have the same names.
namespace stochastic_filter {

const Material& leather() {
    static const std::unique_ptr<Material> material = [] {
        const auto source = test::cached(*synth::make("leather", 16, test::ubo_subset(8, 12), 5));
        return mlvq_codec().open(mlvq_codec().encode(*source, small_grid({{"colour", "ycbcr"}})));
    }();
    return *material;
}

struct Case {
    Uv uv;
    Vec3 wi, wo;
};

// Queries between texels and between the grid's view nodes (so that all 4 texels and 4 nodes
// have weight), and one with the view along the normal.
std::vector<Case> cases() {
    return {{{0.37, 0.61},
             Direction::from_degrees(50, 200).vector(),
             Direction::from_degrees(37, 65).vector()},
            {{0.905, 0.13},
             Direction::from_degrees(20, 10).vector(),
             Direction::from_degrees(71, 200).vector()},
            {{0.5, 0.47},
             Direction::from_degrees(35, 300).vector(),
             Direction::from_degrees(0, 0).vector()}};
}

// Mean and standard error per channel of `count` terms, u = number(uniform).
struct Statistic {
    double mean[3] = {0, 0, 0}, se[3] = {0, 0, 0};
};
template <typename Number>
Statistic term_statistic(const Material& m, const Case& c, int count, Number number) {
    std::mt19937_64 rng(7);
    double sum[3] = {0, 0, 0}, square[3] = {0, 0, 0};
    for (int k = 0; k < count; ++k) {
        const double u = number(test::uniform01(rng));
        const Rgb v = ShadingPoint(m, c.uv, c.wo, Filter::kStochastic, u).eval(c.wi);
        const double x[3] = {v.r, v.g, v.b};
        for (int ch = 0; ch < 3; ++ch) {
            sum[ch] += x[ch];
            square[ch] += x[ch] * x[ch];
        }
    }
    Statistic s;
    for (int ch = 0; ch < 3; ++ch) {
        s.mean[ch] = sum[ch] / count;
        const double variance = std::max(0.0, square[ch] / count - s.mean[ch] * s.mean[ch]);
        s.se[ch] = std::sqrt(variance / (count - 1));
    }
    return s;
}

// With YCbCr colour (linear in the planes) a term's mean over u is eval(): 10⁴ terms agree with
// it within 4 standard errors per channel. A wrong number of the draw (u²: the first texel and
// node too often) is caught by the same statistic at a query whose texels differ.
TEST(MlvqStochastic, MeanOfTheTermsIsEval) {
    const Material& m = leather();
    constexpr int kCount = 10000;
    for (const Case& c : cases()) {
        const Rgb e = m.eval(c.uv, c.wi, c.wo);
        const double exact[3] = {e.r, e.g, e.b};
        const Statistic s = term_statistic(m, c, kCount, [](double u) { return u; });
        for (int ch = 0; ch < 3; ++ch) {
            // 4 standard errors, and float rounding of the terms' scales.
            EXPECT_LE(std::abs(s.mean[ch] - exact[ch]), 4 * s.se[ch] + 1e-6 * std::abs(exact[ch]))
                << "channel " << ch << ": mean " << s.mean[ch] << ", eval " << exact[ch]
                << ", standard error " << s.se[ch];
            EXPECT_GT(s.se[ch], 0) << ch;  // the terms differ: the statistic can tell
        }
    }
    const Case c = cases()[0];
    const Rgb e = m.eval(c.uv, c.wi, c.wo);
    const double exact[3] = {e.r, e.g, e.b};
    const Statistic biased = term_statistic(m, c, kCount, [](double u) { return u * u; });
    double worst = 0;
    for (int ch = 0; ch < 3; ++ch)
        worst = std::max(worst, std::abs(biased.mean[ch] - exact[ch]) / biased.se[ch]);
    EXPECT_GT(worst, 4) << "standard errors between eval and the mean with u -> u^2";
}

// The selection is one of eval()'s 16 terms, a texel of the 4 and a view node m · nθv + k of the
// 2 × 2 around ωo, and the u of each term fill an interval of its weight's length: evenly spaced
// numbers draw each term as often as its weight says, up to one spacing.
TEST(MlvqStochastic, SelectionDrawsEachTermByItsWeight) {
    const auto& m = dynamic_cast<const MlvqMaterial&>(leather());
    const Case c = cases()[0];  // x between 5 and 6, y between 9 and 10; θv 37°, φv 65°
    const WrapLerp lx = wrap_lerp(c.uv.u, 16), ly = wrap_lerp(c.uv.v, 16);
    const MlvqWeights view = lookup_view(m.codebooks().grid, c.wo).weights;
    ASSERT_EQ(lx.i0, 5);
    ASSERT_EQ(ly.i0, 9);
    ASSERT_EQ(view.phi_v.index[0], 1);    // 60°
    ASSERT_EQ(view.theta_v.index[0], 1);  // 30°
    constexpr int kCount = 1 << 14;
    int count[2][2][2][2] = {};
    for (int k = 0; k < kCount; ++k) {
        const Selection s =
            ShadingPoint(m, c.uv, c.wo, Filter::kStochastic, (k + 0.5) / kCount).selection();
        const int phi = s.view / 4, theta = s.view % 4;  // nθv = 4
        ASSERT_TRUE(s.x == 5 || s.x == 6) << s.x;
        ASSERT_TRUE(s.y == 9 || s.y == 10) << s.y;
        ASSERT_TRUE(phi == 1 || phi == 2) << s.view;
        ASSERT_TRUE(theta == 1 || theta == 2) << s.view;
        ++count[s.x - 5][s.y - 9][phi - 1][theta - 1];
    }
    for (int x = 0; x < 2; ++x)
        for (int y = 0; y < 2; ++y)
            for (int p = 0; p < 2; ++p)
                for (int t = 0; t < 2; ++t) {
                    const double weight = (x ? lx.t : 1 - lx.t) * (y ? ly.t : 1 - ly.t) *
                                          view.phi_v.weight[p] * view.theta_v.weight[t];
                    EXPECT_GT(weight, 0);
                    EXPECT_NEAR(count[x][y][p][t], weight * kCount, 1.01)
                        << x << " " << y << " " << p << " " << t;
                }
}

struct SamplingPoint {
    Uv uv;
    Vec3 wo;
};

// Native sampling of a stochastic shading point draws from its one M entry: the directions follow
// the pdf it reports (χ² over equal-area bins), the pdf integrates to 1, and sample() reports
// pdf() and eval() of its direction (to within the rounding of the direction's (α, u)), and
// their ratio.
void expect_sampling_follows_its_pdf(const Material& material,
                                     const std::vector<SamplingPoint>& points,
                                     const std::vector<double>& numbers) {
    const double tests = double(points.size() * numbers.size());
    const double significance = 1 - std::pow(1 - 1e-3, 1.0 / tests);  // Šidák over the tests
    for (const auto& p : points)
        for (const double u : numbers) {
            const ShadingPoint sp(material, p.uv, p.wo, Filter::kStochastic, u);
            test::ChiSquareOptions options;
            options.samples = 100000;
            const test::ChiSquareResult r =
                test::chi_square_hemisphere([&](double a, double b) { return sp.sample(a, b).wi; },
                                            [&](const Vec3& wi) { return sp.pdf(wi); }, options);
            EXPECT_TRUE(r.passed(significance)) << u << ": " << r.describe();
            EXPECT_NEAR(r.pdf_integral, 1.0, 0.01) << u;
            // ξ2 = 0 and the largest ξ2 below 1 draw at the poles of the onion frame (u = ±1),
            // where the direction does not depend on α.
            for (const auto& [xi1, xi2] :
                 {std::pair{0.05, 0.95}, std::pair{0.37, 0.63}, std::pair{0.81, 0.19},
                  std::pair{0.3, 0.0}, std::pair{0.6, std::nextafter(1.0, 0.0)}}) {
                const LightSample ls = sp.sample(xi1, xi2);
                ASSERT_GT(ls.pdf, 0);
                // The drawn (α, u) against those that the direction gives back: rounding apart.
                EXPECT_NEAR(ls.pdf, sp.pdf(ls.wi), 1e-5 * ls.pdf);
                const Rgb v = sp.eval(ls.wi);
                EXPECT_NEAR(ls.value.r, v.r, 1e-5 * std::abs(v.r) + 1e-7);
                EXPECT_NEAR(ls.value.g, v.g, 1e-5 * std::abs(v.g) + 1e-7);
                EXPECT_NEAR(ls.value.b, v.b, 1e-5 * std::abs(v.b) + 1e-7);
                EXPECT_FLOAT_EQ(ls.weight.g, float(ls.value.g / ls.pdf));
            }
        }
}

TEST(MlvqStochastic, SamplingFollowsItsPdf) {
    const auto glossy = test::cached(*synth::make("lacquered_wood", 8, test::ubo_subset(8, 12), 3));
    const auto material = mlvq_codec().open(mlvq_codec().encode(*glossy, small_grid()));
    expect_sampling_follows_its_pdf(*material,
                                    {{{0.31, 0.62}, Direction::from_degrees(0, 0).vector()},
                                     {{0.5625, 0.0625}, Direction::from_degrees(37, 65).vector()},
                                     {{0.9, 0.4}, Direction::from_degrees(71, 200).vector()}},
                                    {0.13, 0.58, 0.91});
}

// The α and β inversions take another path for rows longer than a vector's 16 lanes: the same
// checks on a grid of 18 × 18 (α, β) samples.
TEST(MlvqStochastic, SamplingFollowsItsPdfOnRowsLongerThanAVector) {
    const auto glossy = test::cached(*synth::make("lacquered_wood", 4, test::ubo_subset(8, 12), 3));
    Params params = small_grid();
    params.set("n-alpha", "18");
    params.set("n-beta", "18");
    const auto material = mlvq_codec().open(mlvq_codec().encode(*glossy, params));
    expect_sampling_follows_its_pdf(
        *material, {{{0.4, 0.7}, Direction::from_degrees(37, 65).vector()}}, {0.2, 0.77});
}

// NaN numbers (ξ, and the share of a component of no mass that rounding can make 0 / 0) draw a
// direction in the hemisphere, as ξ = 0 does, in both the stochastic and the deterministic
// sampling; they never reach an index.
TEST(MlvqStochastic, NanNumbersDrawAsZero) {
    const Material& m = leather();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const Vec3 wo = Direction::from_degrees(40, 10).vector();
    const ShadingPoint sp(m, {0.3, 0.6}, wo, Filter::kStochastic, 0.4);
    for (const auto& [xi1, xi2] : {std::pair{nan, 0.5}, std::pair{0.5, nan}, std::pair{nan, nan}}) {
        const LightSample ls = sp.sample(xi1, xi2);
        const LightSample zero =
            sp.sample(std::isnan(xi1) ? 0.0 : xi1, std::isnan(xi2) ? 0.0 : xi2);
        EXPECT_EQ(ls.wi.x, zero.wi.x);
        EXPECT_EQ(ls.wi.y, zero.wi.y);
        EXPECT_EQ(ls.wi.z, zero.wi.z);
        const LightSample d = m.sample({0.3, 0.6}, wo, xi1, xi2);
        EXPECT_TRUE(std::isfinite(d.wi.x) && std::isfinite(d.wi.y) && d.wi.z >= 0);
        EXPECT_GT(d.pdf, 0);
    }
}

// A term of zero luminance samples the hemisphere uniformly and says so.
TEST(MlvqStochastic, ZeroLuminanceSamplesUniformly) {
    const auto& m = dynamic_cast<const MlvqMaterial&>(leather());
    TexelIndex index = m.texel_index();
    for (IndexScale& e : index.p6) e.scale = 0;
    const MlvqMaterial dark(std::make_shared<const Codebooks>(m.codebooks()), index);
    const ShadingPoint sp(dark, {0.3, 0.6}, Direction::from_degrees(40, 10).vector(),
                          Filter::kStochastic, 0.4);
    const LightSample ls = sp.sample(0.3, 0.8);
    EXPECT_DOUBLE_EQ(ls.pdf, 1 / (2 * kPi));
    EXPECT_DOUBLE_EQ(sp.pdf(Direction::from_degrees(70, 300).vector()), 1 / (2 * kPi));
    EXPECT_EQ(sp.pdf({0, 0, -1}), 0);
    EXPECT_EQ(ls.value, sp.eval(ls.wi));
}

// eval_stochastic_batch and sample_stochastic_batch equal ShadingPoint query by query, bit for
// bit: random queries (more than a group, and a tail), numbers outside [0, 1), a view along the
// normal, and a material of zero luminance.
TEST(MlvqStochastic, BatchesEqualShadingPoints) {
    const auto& m = dynamic_cast<const MlvqMaterial&>(leather());
    TexelIndex index = m.texel_index();
    for (size_t t = 0; t < index.p6.size(); t += 2) index.p6[t].scale = 0;
    const MlvqMaterial half_dark(std::make_shared<const Codebooks>(m.codebooks()), index);
    std::mt19937_64 rng(13);
    auto uni = [&rng] { return test::uniform01(rng); };
    std::vector<StochasticQuery> evals(37);
    std::vector<StochasticSampleQuery> samples(37);
    for (size_t i = 0; i < evals.size(); ++i) {
        const Uv uv{uni(), uni()};
        const Vec3 wo = Direction{std::acos(uni()), 2 * kPi * uni()}.vector();
        const double u = uni();
        evals[i] = {uv, Direction{std::acos(uni()), 2 * kPi * uni()}.vector(), wo, u};
        samples[i] = {uv, wo, u, uni(), uni()};
    }
    evals[2].u = samples[2].u = 1.5;
    evals[3].u = samples[3].u = -0.25;
    evals[4].u = samples[4].u = NAN;
    evals[5].wo = samples[5].wo = {0, 0, 1};
    samples[6].xi1 = 1.5;
    for (const MlvqMaterial* material : {&m, &half_dark}) {
        std::vector<Rgb> values(evals.size());
        material->eval_stochastic_batch(evals, values);
        for (size_t i = 0; i < evals.size(); ++i) {
            const StochasticQuery& q = evals[i];
            EXPECT_EQ(values[i],
                      ShadingPoint(*material, q.uv, q.wo, Filter::kStochastic, q.u).eval(q.wi))
                << i;
        }
        std::vector<LightSample> drawn(samples.size());
        material->sample_stochastic_batch(samples, drawn);
        for (size_t i = 0; i < samples.size(); ++i) {
            const StochasticSampleQuery& q = samples[i];
            const LightSample one =
                ShadingPoint(*material, q.uv, q.wo, Filter::kStochastic, q.u).sample(q.xi1, q.xi2);
            EXPECT_EQ(drawn[i].wi, one.wi) << i;
            EXPECT_EQ(drawn[i].pdf, one.pdf) << i;
            EXPECT_EQ(drawn[i].value, one.value) << i;
            EXPECT_EQ(drawn[i].weight, one.weight) << i;
        }
    }
    std::vector<Rgb> wrong(2);
    EXPECT_THROW(m.eval_stochastic_batch(evals, wrong), Error);
}

}  // namespace stochastic_filter
}  // namespace
}  // namespace btf::mlvq

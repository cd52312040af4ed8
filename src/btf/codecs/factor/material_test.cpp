// SPDX-License-Identifier: MIT
// FactorMaterial's fast paths against its scalar references and against the core's stochastic
// filter, on the materials of every factor codec and of UBO2014 files: half and float rows, one
// block (fmf, UBO2014) and several (view groups, texel clusters, spatial and angular levels).
//
// - eval_sample() (vectorized over components) against eval_sample_reference() (scalar);
// - eval() and eval_batch() against eval_reference(), batches of every length;
// - the stochastic filter: FactorMaterial's own select() and eval_selected() draw exactly what
//   Material's defaults draw (a material that forwards to the factor material and keeps the
//   defaults), and eval_stochastic_batch() returns exactly the shading point's values;
// - half rows: chosen exactly when every factor value is a half float, and then bit for bit the
//   values of float rows; every value the model's own sum Σ a · b + mean.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/codecs/lpca/lpca.h"
#include "btf/codecs/pca_views/pca_views.h"
#include "btf/codecs/perceptual/perceptual.h"
#include "btf/io/ubo2014.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

// A namespace of its own: the unity build compiles this file with other tests of the codecs,
// some of which have helpers of the same names (source(), cases()).
namespace btf::factor_material_test {
namespace {

using factor::FactorMaterial;

const BtfSource& source() {
    static const auto s =
        test::cached(*synth::make("woven_fabric", 16, test::ubo_subset(10, 12), 4));
    return *s;
}

struct Case {
    std::string name;
    std::shared_ptr<const Material> material;
    bool half = false;  ///< the factors are half floats: half rows expected
    const FactorMaterial& factor() const { return dynamic_cast<const FactorMaterial&>(*material); }
};

// Views and lights at the same directions (as the UBO 81 × 81 of real files): the factor material
// then looks the lights up in its view interpolator.
const BtfSource& same_directions_source() {
    static const auto s = [] {
        const Sampling twelve = test::ubo_subset(12, 12);
        return test::cached(*synth::make("woven_fabric", 12, {twelve.lights, twelve.lights}, 5));
    }();
    return *s;
}

// Through the package's bytes, as a file would open.
std::shared_ptr<const Material> encoded(const Codec& codec, const Params& params,
                                        const BtfSource& from = source()) {
    Package package = codec.encode(from, params);
    return std::shared_ptr<const Material>(
        open_material(decode_package(encode_package(package), "test")));
}

// A UBO2014 DFMF file of the source (K = 7 per channel), opened as `btf` opens a .btf file.
std::shared_ptr<const Material> dfmf(int32_t model, int scalar_size) {
    static test::TempFolder dir("btf-factor-material");
    const std::filesystem::path path =
        dir.path() / ("m" + std::to_string(model) + "s" + std::to_string(scalar_size) + ".btf");
    ubo2014::FactorizeOptions options;
    options.components = 7;
    options.color_model = model;
    options.scalar_size = scalar_size;
    ubo2014::write_dfmf(path, source(), options);
    return std::shared_ptr<const Material>(open_material(path));
}

const std::vector<Case>& cases() {
    static const std::vector<Case> all = [] {
        std::vector<Case> c;
        // One block: one plane of 3 channels, or 3 planes (uneven components when decorrelated).
        c.push_back({"fmf rgb f16", encoded(fmf_codec(), Params({{"components", "13"}})), true});
        c.push_back(
            {"fmf rgb f32 mean",
             encoded(fmf_codec(),
                     Params({{"components", "8"}, {"mean", "true"}, {"quantize", "f32"}}))});
        c.push_back({"fmf rgb u8",
                     encoded(fmf_codec(), Params({{"components", "9"}, {"quantize", "u8"}}))});
        c.push_back({"fmf decorrelated log f16",
                     encoded(fmf_codec(), Params({{"components", "20"},
                                                  {"colour", "decorrelated"},
                                                  {"log", "true"},
                                                  {"mean", "true"}})),
                     true});
        c.push_back({"fmf model11 f16",
                     encoded(fmf_codec(), Params({{"components", "6"}, {"colour", "model11"}})),
                     true});
        // Several blocks.
        c.push_back(
            {"pca-views groups f16",
             encoded(pca_views_codec(), Params({{"components", "5"}, {"views-per-group", "3"}})),
             true});
        c.push_back({"pca-views groups decorrelated f32",
                     encoded(pca_views_codec(), Params({{"components", "4"},
                                                        {"views-per-group", "4"},
                                                        {"colour", "decorrelated"},
                                                        {"quantize", "f32"}}))});
        c.push_back({"lpca clusters f16",
                     encoded(lpca_codec(), Params({{"clusters", "3"}, {"components", "4"}})),
                     true});
        c.push_back(
            {"lpca clusters u8",
             encoded(lpca_codec(),
                     Params({{"clusters", "4"}, {"components", "3"}, {"quantize", "u8"}}))});
        // Spatial and angular levels: the up-sampled angular factors are not half floats.
        c.push_back(
            {"perceptual levels f16",
             encoded(perceptual_codec(),
                     Params({{"components", "14"}, {"base-quality", "0.6"}, {"mean", "true"}}))});
        c.push_back({"perceptual one level f16",
                     encoded(perceptual_codec(), Params({{"components", "10"}})), true});
        c.push_back({"fmf rgb f16, views = lights",
                     encoded(fmf_codec(), Params({{"components", "11"}}), same_directions_source()),
                     true});
        c.push_back({"UBO2014 model 0 half", dfmf(ubo2014::kColorModelRgb, 2), true});
        c.push_back({"UBO2014 model 0 float", dfmf(ubo2014::kColorModelRgb, 4)});
        c.push_back({"UBO2014 model 11 half", dfmf(ubo2014::kColorModelLogYUV, 2), true});
        return c;
    }();
    return all;
}

// |a − b| within `relative` of the larger magnitude (at least of 1).
::testing::AssertionResult near(const Rgb& a, const Rgb& b, double relative) {
    const float x[3] = {a.r, a.g, a.b}, y[3] = {b.r, b.g, b.b};
    for (int k = 0; k < 3; ++k) {
        const double scale = std::max({1.0, double(std::abs(x[k])), double(std::abs(y[k]))});
        if (!(std::abs(double(x[k]) - double(y[k])) <= relative * scale))
            return ::testing::AssertionFailure()
                   << "(" << a.r << ", " << a.g << ", " << a.b << ") against (" << b.r << ", "
                   << b.g << ", " << b.b << ")";
    }
    return ::testing::AssertionSuccess();
}

::testing::AssertionResult same(const Rgb& a, const Rgb& b) {
    if (std::memcmp(&a, &b, sizeof a) == 0) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure()
           << "(" << a.r << ", " << a.g << ", " << a.b << ") is not bit for bit (" << b.r << ", "
           << b.g << ", " << b.b << ")";
}

Vec3 hemisphere(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> u01(0, 1);
    const double z = u01(rng), phi = 2 * kPi * u01(rng), r = std::sqrt(1 - z * z);
    return {r * std::cos(phi), r * std::sin(phi), z};
}

// Random positions (beyond [0, 1) too: wrapping) and directions, then the corner cases: texel
// centres and edges, sample directions, the horizon, below it, and a zero vector.
std::vector<StochasticQuery> stochastic_queries(const Material& m, int count, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u01(0, 1);
    std::vector<StochasticQuery> q;
    for (int i = 0; i < count; ++i)
        q.push_back(
            {{3 * u01(rng) - 1, 3 * u01(rng) - 1}, hemisphere(rng), hemisphere(rng), u01(rng)});
    const Sampling& s = m.sampling();
    const double below_one = 0x1.fffffffffffffp-1;
    const double numbers[] = {0.0, below_one, 0.5, 1e-300, -0.25, 1.0, 7.0, NAN};
    int k = 0;
    for (double u : numbers)
        for (int v = 0; v < s.num_views(); v += 3, ++k)
            q.push_back({{(k % m.width() + 0.5) / m.width(), double(k % 5) / m.height()},
                         s.lights.vector(k % s.num_lights()),
                         s.views.vector(v),
                         u});
    q.push_back({{0.25, 0.75}, {1, 0, 0}, {0, 1, 0}, 0.3});
    q.push_back({{0.5, 0.5}, {0.3, 0.2, -0.5}, {-1, 0.1, -0.01}, 0.6});
    q.push_back({{1e9, -1e9}, {0, 0, 0}, {0, 0, 1}, 0.9});
    return q;
}

std::vector<Query> deterministic_queries(const std::vector<StochasticQuery>& s) {
    std::vector<Query> q;
    for (const StochasticQuery& x : s) q.push_back({x.uv, x.wi, x.wo});
    return q;
}

// The factor material behind Material's default selection and lookups: select() and
// eval_selected() of Material itself, with the factor material's eval_sample().
class Defaults final : public Material {
  public:
    explicit Defaults(const Material& m) : m_m(m) {}
    int width() const override { return m_m.width(); }
    int height() const override { return m_m.height(); }
    const Sampling& sampling() const override { return m_m.sampling(); }
    Rgb eval(const Uv& uv, const Vec3& wi, const Vec3& wo) const override {
        return m_m.eval(uv, wi, wo);
    }
    Rgb eval_sample(int x, int y, int view, int light) const override {
        return m_m.eval_sample(x, y, view, light);
    }

  private:
    const Material& m_m;
};

TEST(FactorMaterial, CasesCoverWhatTheyClaim) {
    for (const Case& c : cases()) {
        const FactorMaterial& m = c.factor();
        EXPECT_EQ(m.half_rows(), c.half) << c.name;
    }
    const factor::Model& perceptual = cases()[9].factor().model();
    EXPECT_GT(perceptual.levels, 1);
    EXPECT_FALSE(perceptual.angular_levels.empty());
    EXPECT_GT(cases()[5].factor().model().groups.size(), 1u);
    EXPECT_GT(cases()[7].factor().model().clusters, 1);
    const Sampling& same = cases()[11].material->sampling();
    EXPECT_EQ(same.views.directions().size(), same.lights.directions().size());
    for (size_t i = 0; i < same.views.directions().size(); ++i) {
        EXPECT_EQ(same.views.directions()[i].theta, same.lights.directions()[i].theta);
        EXPECT_EQ(same.views.directions()[i].phi, same.lights.directions()[i].phi);
    }
}

TEST(FactorMaterial, EvalSampleMatchesTheScalarReference) {
    for (const Case& c : cases()) {
        const FactorMaterial& m = c.factor();
        const Sampling& s = m.sampling();
        for (int v = 0; v < s.num_views(); ++v)
            for (int l = 0; l < s.num_lights(); l += 2)
                for (int t = (v + l) % 5; t < m.width() * m.height(); t += 5) {
                    const int x = t % m.width(), y = t / m.width();
                    ASSERT_TRUE(
                        near(m.eval_sample(x, y, v, l), m.eval_sample_reference(x, y, v, l), 2e-5))
                        << c.name << " at (" << x << ", " << y << ", " << v << ", " << l << ")";
                }
    }
}

TEST(FactorMaterial, EvalAndBatchesMatchTheScalarReference) {
    for (const Case& c : cases()) {
        const FactorMaterial& m = c.factor();
        const std::vector<Query> queries = deterministic_queries(stochastic_queries(m, 600, 21));
        std::vector<Rgb> batch(queries.size());
        m.eval_batch(queries, batch);
        for (size_t i = 0; i < queries.size(); ++i) {
            const Query& q = queries[i];
            const Rgb fast = m.eval(q.uv, q.wi, q.wo);
            ASSERT_TRUE(near(fast, m.eval_reference(q.uv, q.wi, q.wo), 2e-5)) << c.name << " " << i;
            ASSERT_TRUE(same(batch[i], fast)) << c.name << " " << i;
        }
        // Short batches (shorter than the prefetch distance) and runs of equal directions.
        for (size_t length : {size_t(0), size_t(1), size_t(3), size_t(5), size_t(17)}) {
            std::vector<Query> part(queries.begin(), queries.begin() + length);
            for (size_t i = 1; i < part.size(); i += 2) {
                part[i].wi = part[i - 1].wi;
                part[i].wo = part[i - 1].wo;
            }
            std::vector<Rgb> out(length);
            m.eval_batch(part, out);
            for (size_t i = 0; i < length; ++i)
                ASSERT_TRUE(same(out[i], m.eval(part[i].uv, part[i].wi, part[i].wo)))
                    << c.name << " batch of " << length << ", query " << i;
        }
    }
}

TEST(FactorMaterial, SelectionIsMaterialsDefault) {
    for (const Case& c : cases()) {
        const Defaults defaults(*c.material);
        for (const StochasticQuery& q : stochastic_queries(*c.material, 2000, 22)) {
            const ShadingPoint fast(*c.material, q.uv, q.wo, Filter::kStochastic, q.u);
            const ShadingPoint slow(defaults, q.uv, q.wo, Filter::kStochastic, q.u);
            const Selection &a = fast.selection(), &b = slow.selection();
            ASSERT_EQ(a.x, b.x) << c.name;
            ASSERT_EQ(a.y, b.y) << c.name;
            ASSERT_EQ(a.view, b.view) << c.name;
            ASSERT_EQ(std::memcmp(&a.u, &b.u, sizeof a.u), 0)
                << c.name << ": " << a.u << " " << b.u;
            ASSERT_TRUE(same(fast.eval(q.wi), slow.eval(q.wi))) << c.name;
        }
    }
}

TEST(FactorMaterial, StochasticBatchEqualsTheShadingPoint) {
    for (const Case& c : cases()) {
        const std::vector<StochasticQuery> queries = stochastic_queries(*c.material, 3000, 23);
        // Every length up to a few groups and prefetch distances, then all at once.
        for (size_t length = 0; length <= 40; ++length) {
            std::vector<Rgb> out(length);
            c.material->eval_stochastic_batch(std::span(queries).first(length), out);
            for (size_t i = 0; i < length; ++i) {
                const StochasticQuery& q = queries[i];
                ASSERT_TRUE(same(
                    out[i],
                    ShadingPoint(*c.material, q.uv, q.wo, Filter::kStochastic, q.u).eval(q.wi)))
                    << c.name << " batch of " << length << ", query " << i;
            }
        }
        std::vector<Rgb> out(queries.size());
        c.material->eval_stochastic_batch(queries, out);
        const Defaults defaults(*c.material);
        std::vector<Rgb> slow(queries.size());
        defaults.eval_stochastic_batch(queries, slow);  // Material's default batch
        for (size_t i = 0; i < queries.size(); ++i)
            ASSERT_TRUE(same(out[i], slow[i])) << c.name << " query " << i;
    }
}

TEST(FactorMaterial, HalfRowsGiveTheValuesOfFloatRows) {
    for (const Case& c : cases()) {
        if (!c.half) continue;
        const FactorMaterial& half = c.factor();
        const FactorMaterial floats(half.model(), factor::RowStorage::kFloat);
        ASSERT_TRUE(half.half_rows());
        ASSERT_FALSE(floats.half_rows());
        const Sampling& s = half.sampling();
        for (int v = 0; v < s.num_views(); v += 2)
            for (int l = 0; l < s.num_lights(); ++l)
                for (int t = (v + l) % 3; t < half.width() * half.height(); t += 3) {
                    const int x = t % half.width(), y = t / half.width();
                    ASSERT_TRUE(same(half.eval_sample(x, y, v, l), floats.eval_sample(x, y, v, l)))
                        << c.name;
                }
        // The interpolated value: the same up to the order GCC fuses multiplies and adds in,
        // which may differ between the two compiled paths.
        const std::vector<StochasticQuery> stochastic = stochastic_queries(half, 500, 24);
        const std::vector<Query> queries = deterministic_queries(stochastic);
        std::vector<Rgb> a(queries.size()), b(queries.size());
        half.eval_batch(queries, a);
        floats.eval_batch(queries, b);
        for (size_t i = 0; i < queries.size(); ++i) ASSERT_TRUE(near(a[i], b[i], 1e-6)) << c.name;
        half.eval_stochastic_batch(stochastic, a);
        floats.eval_stochastic_batch(stochastic, b);
        for (size_t i = 0; i < queries.size(); ++i) ASSERT_TRUE(same(a[i], b[i])) << c.name;
    }
}

// value(x, y, view, light) = inverse colour of mean + Σ_k a(row, k) b(texel, k) per plane, in
// double from the model's own matrices (one block per plane).
Rgb model_value(const factor::Model& model, int x, int y, int view, int light) {
    const int channels = model.colour.channels(), nl = model.sampling.num_lights();
    double planes[3] = {0, 0, 0};
    int slot = 0;
    while (model.groups[0][size_t(slot)] != view) ++slot;
    for (int p = 0; p < model.colour.planes(); ++p) {
        const factor::Block& b = model.blocks[size_t(model.block_index(p, 0, 0))];
        for (int ch = 0; ch < channels; ++ch) {
            const int64_t row = (int64_t(slot) * nl + light) * channels + ch;
            double sum = b.mean.empty() ? 0.0 : b.mean[size_t(row)];
            for (int k = 0; k < b.components(); ++k)
                sum += double(b.a(row, k)) * double(b.b(int64_t(y) * model.width + x, k));
            planes[p + ch] = sum;
        }
    }
    return model.colour.inverse({float(planes[0]), float(planes[1]), float(planes[2])});
}

TEST(FactorMaterial, SingleBlockValuesAreTheModelsSums) {
    for (const Case& c : cases()) {
        const FactorMaterial& m = c.factor();
        const factor::Model& model = m.model();
        if (model.groups.size() != 1 || model.clusters != 1 || model.levels != 1 ||
            !model.angular_levels.empty())
            continue;
        const Sampling& s = m.sampling();
        for (int v = 0; v < s.num_views(); ++v)
            for (int l = (v % 2); l < s.num_lights(); l += 2)
                for (int t = v % 7; t < m.width() * m.height(); t += 7) {
                    const int x = t % m.width(), y = t / m.width();
                    ASSERT_TRUE(
                        near(m.eval_sample(x, y, v, l), model_value(model, x, y, v, l), 2e-5))
                        << c.name << " at (" << x << ", " << y << ", " << v << ", " << l << ")";
                }
    }
}

TEST(FactorMaterial, HalfRowsOnlyForHalfValues) {
    // A model of halves but one value: float rows; RowStorage::kFloat always floats.
    factor::Model model = cases()[0].factor().model();
    EXPECT_TRUE(FactorMaterial(model).half_rows());
    EXPECT_FALSE(FactorMaterial(model, factor::RowStorage::kFloat).half_rows());
    model.blocks[0].b(3, 1) = 0.1f;  // not a half float
    EXPECT_FALSE(FactorMaterial(model).half_rows());
}

}  // namespace
}  // namespace btf::factor_material_test

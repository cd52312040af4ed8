// SPDX-License-Identifier: MIT
#include "btf/codecs/perceptual/perceptual.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <set>
#include <tuple>

#include "btf/codecs/fmf/fmf.h"
#include "btf/codecs/perceptual/resample.h"
#include "btf/core/btf_lookup.h"
#include "btf/core/color.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/parallel.h"

namespace btf {
namespace {

using factor::FactorMaterial;
using factor::Matrix;

// A small synthetic material held in memory (shared by the tests of this file).
const BtfSource& fabric() {
    static const std::unique_ptr<FunctionSource> source =
        test::cached(*synth::make("woven_fabric", 16, test::ubo_subset(8, 10), 2));
    return *source;
}

Package encode(const BtfSource& source, Params params) {
    return perceptual_codec().encode(source, params);
}

// The planes of a BTF in CIELab, one (view · nL + light) × texel matrix each.
std::array<Matrix, 3> lab_planes(const BtfSource& source) {
    const int64_t images = source.sampling().num_images(), texels = source.num_texels();
    std::array<Matrix, 3> planes;
    for (Matrix& p : planes) p.resize(images, texels);
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); ++l) {
            const Image image = source.image(v, l);
            const int64_t row = int64_t(v) * source.num_lights() + l;
            for (int64_t t = 0; t < texels; ++t) {
                const Lab c =
                    rgb_to_lab(image.rgb(int(t % source.width()), int(t / source.width())));
                planes[0](row, t) = float(c.l);
                planes[1](row, t) = float(c.a);
                planes[2](row, t) = float(c.b);
            }
        }
    return planes;
}

// The same for a decoded material at its samples.
std::array<Matrix, 3> lab_planes(const Material& m, const BtfSource& like) {
    const auto source = std::make_unique<FunctionSource>(
        like.sampling(), like.width(), like.height(),
        [&m](int v, int l, int x, int y) { return m.eval_sample(x, y, v, l); });
    return lab_planes(*source);
}

// The linearized perceptual error the codec minimizes: Σ_planes ‖T_v (A − Â) T_uᵀ‖²_F in CIELab.
double perceptual_error(const BtfSource& source, const Material& decoded,
                        const perceptual::Viewing& viewing) {
    const perceptual::CsfTransforms t(source.sampling(), source.width(), source.height(), viewing);
    const auto a = lab_planes(source), b = lab_planes(decoded, source);
    double sum = 0;
    for (int p = 0; p < 3; ++p) {
        Matrix d = (a[p] - b[p]).transpose();  // texels × images: columns are images
        t.right(p, d, false);
        Matrix e = d.transpose();  // images × texels: columns are ABRDFs
        t.left(p, e, false);
        sum += e.cast<double>().squaredNorm();
    }
    return sum;
}

double rgb_rmse(const BtfSource& source, const Material& material) {
    double sum = 0;
    int64_t n = 0;
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); ++l) {
            const Image image = source.image(v, l);
            for (int y = 0; y < source.height(); ++y)
                for (int x = 0; x < source.width(); ++x) {
                    const Rgb a = image.rgb(x, y), b = material.eval_sample(x, y, v, l);
                    sum += double(a.r - b.r) * (a.r - b.r) + double(a.g - b.g) * (a.g - b.g) +
                           double(a.b - b.b) * (a.b - b.b);
                    n += 3;
                }
        }
    return std::sqrt(sum / double(n));
}

std::vector<Query> random_queries(int count, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u01(0, 1);
    auto direction = [&] {
        const double z = u01(rng), phi = 2 * kPi * u01(rng), r = std::sqrt(1 - z * z);
        return Vec3{r * std::cos(phi), r * std::sin(phi), z};
    };
    std::vector<Query> q(count);
    for (Query& x : q) x = {{3 * u01(rng) - 1, 3 * u01(rng) - 1}, direction(), direction()};
    return q;
}

TEST(LabColour, ConvertsToCielabPlanesAndBack) {
    factor::ColourHandling lab;
    lab.basis = factor::parse_colour_basis("lab");
    EXPECT_EQ(factor::to_string(lab.basis), "lab");
    EXPECT_EQ(lab.planes(), 3);
    EXPECT_EQ(lab.channels(), 1);
    const Rgb white = lab.forward({1, 1, 1});
    EXPECT_NEAR(white.r, 100.0f, 1e-3);  // Y = 1 is the white
    EXPECT_NEAR(white.g, 0.0f, 1e-2);
    EXPECT_NEAR(white.b, 0.0f, 1e-2);
    for (const Rgb c : {Rgb{0.2f, 0.5f, 0.1f}, Rgb{0.9f, 0.05f, 0.4f}, Rgb{0.001f, 0.002f, 0}}) {
        const Lab expected = rgb_to_lab(c);
        const Rgb p = lab.forward(c);
        EXPECT_NEAR(p.r, expected.l, 1e-4);
        EXPECT_NEAR(p.g, expected.a, 1e-4);
        EXPECT_NEAR(p.b, expected.b, 1e-4);
        const Rgb back = lab.inverse(p);
        EXPECT_NEAR(back.r, c.r, 1e-5);
        EXPECT_NEAR(back.g, c.g, 1e-5);
        EXPECT_NEAR(back.b, c.b, 1e-5);
    }
}

// With every component the untransformed factors give the BTF back although the filters were
// never inverted (a bᵀ = T_v⁻¹ Ã T_u⁻ᵀ = A at full rank).
TEST(Perceptual, FullRankReconstructsTheSource) {
    const BtfSource& source = fabric();
    for (const std::string mean : {"false", "true"}) {
        const Package p = encode(source, Params({{"components", "240"},
                                                 {"mean", mean},
                                                 {"oversampling", "0"},
                                                 {"quantize", "f32"}}));
        const auto material = perceptual_codec().open(p);
        EXPECT_LT(rgb_rmse(source, *material), 2e-4) << "mean=" << mean;
    }
}

TEST(Perceptual, PackageRoundTripThroughBytes) {
    const BtfSource& source = fabric();
    Package p = encode(source, Params({{"components", "9"}, {"quantize", "u8"}}));
    EXPECT_EQ(p.codec(), "perceptual");
    EXPECT_EQ(p.header.at("model").at("colour"), "lab");
    EXPECT_EQ(p.header.at("params").at("resolution"), 10.0);
    EXPECT_EQ(p.header.at("params").at("speed"), 100.0);
    const auto direct = perceptual_codec().open(p);
    const Package back = decode_package(encode_package(p), "memory");
    EXPECT_TRUE(back.complete());
    const auto material = open_material(back);
    const auto& fm = dynamic_cast<const FactorMaterial&>(*material);
    EXPECT_EQ(fm.total_components(), 9);
    EXPECT_EQ(fm.model().colour.basis, factor::ColourBasis::kLab);
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); l += 3)
            EXPECT_EQ(material->eval_sample(3, 5, v, l), direct->eval_sample(3, 5, v, l));
}

// Unfiltered CIELab error Σ_planes ‖A − Â‖²_F.
double lab_error(const BtfSource& source, const Material& decoded) {
    const auto a = lab_planes(source), b = lab_planes(decoded, source);
    double sum = 0;
    for (int p = 0; p < 3; ++p) sum += (a[p] - b[p]).cast<double>().squaredNorm();
    return sum;
}

// A material of low rank in linear RGB: a smooth grey structure of rank 3 and strong per-texel
// chroma noise along two isoluminant directions (rank 1 each), which carries much of the RGB
// energy but, at fine scale and without any luminance change, little of what the eye sees.
std::unique_ptr<FunctionSource> chroma_noise_material(double chroma) {
    const Sampling s = test::ubo_subset(8, 10);
    return test::cached(FunctionSource(s, 16, 16, [s, chroma](int v, int l, int x, int y) {
        const Vec3 wi = s.lights.vector(l), wo = s.views.vector(v);
        const double u = (x + 0.5) / 16, w = (y + 0.5) / 16;
        const double grey = 0.3 + 0.15 * wi.z * (1 + 0.5 * std::sin(2 * kPi * u)) +
                            0.05 * wi.z * wo.z * std::cos(2 * kPi * (u + w));
        // Isoluminant: orthogonal to the luminance weights (0.2126, 0.7152, 0.0722).
        const double n1 = chroma * (test::hash01(x, y, 1, 0) - 0.5) * (0.5 + 0.5 * wi.z);
        const double n2 = chroma * (test::hash01(x, y, 2, 0) - 0.5) * (0.5 + 0.5 * wo.z);
        return Rgb{float(grey + 0.7152 * n1 + 0.0722 * n2), float(grey - 0.2126 * n1),
                   float(grey - 0.2126 * n2)};
    }));
}

// The point of the method: at an equal number of components its perceptual error is lower than
// plain fmf's (which minimizes the RGB error) and its plain RGB error higher: it spends the
// components on what is seen (the luminance structure) instead of on chroma detail. Not a law of
// nature: the factorization runs in CIELab, and a BTF of lower rank in linear RGB than in CIELab
// can favour fmf even in the perceptual error (several synth presets do; docs/codecs.md).
TEST(Perceptual, LowersThePerceptualErrorAndNotTheRgbError) {
    const auto source = chroma_noise_material(0.3);
    const perceptual::Viewing viewing{30, 100};
    for (const int components : {2, 3}) {  // fewer than the material's rank of 5
        const std::string c = std::to_string(components);
        const auto ours = perceptual_codec().open(encode(
            *source, Params({{"components", c}, {"quantize", "f32"}, {"resolution", "30"}})));
        for (const std::string colour : {"decorrelated", "rgb"}) {
            const auto fmf = fmf_codec().open(fmf_codec().encode(
                *source, Params({{"components", c}, {"colour", colour}, {"quantize", "f32"}})));
            EXPECT_LT(perceptual_error(*source, *ours, viewing),
                      0.8 * perceptual_error(*source, *fmf, viewing))
                << components << " " << colour;
            EXPECT_GE(rgb_rmse(*source, *ours), rgb_rmse(*source, *fmf))
                << components << " " << colour;
        }
    }
}

// The same in one colour space, which holds for any material (Eckart–Young in the filtered and
// in the unfiltered space): against the unfiltered CIELab factorization (csf=false) the
// perceptual error is not higher and the plain CIELab error not lower.
TEST(Perceptual, BeatsTheUnweightedLabFactorizationInThePerceptualError) {
    const BtfSource& source = fabric();
    const perceptual::Viewing viewing{10, 100};
    for (const int components : {4, 12}) {
        const std::string c = std::to_string(components);
        const auto ours = perceptual_codec().open(
            encode(source, Params({{"components", c}, {"quantize", "f32"}})));
        const auto plain = perceptual_codec().open(
            encode(source, Params({{"components", c}, {"quantize", "f32"}, {"csf", "false"}})));
        const double ours_p = perceptual_error(source, *ours, viewing);
        const double plain_p = perceptual_error(source, *plain, viewing);
        EXPECT_LT(ours_p, plain_p) << components;
        EXPECT_GT(lab_error(source, *ours), lab_error(source, *plain)) << components;
    }
}

TEST(Perceptual, AllocatesComponentsToThePlanesByPerceptualEnergy) {
    const BtfSource& source = fabric();
    const factor::Model m =
        perceptual::factorize(source, perceptual::parse_options(Params({{"components", "10"}})));
    ASSERT_EQ(m.blocks.size(), 3u);
    int total = 0;
    float smallest_kept = INFINITY;
    for (const factor::Block& b : m.blocks) {
        total += b.components();
        for (float e : b.energy) smallest_kept = std::min(smallest_kept, e);
    }
    EXPECT_EQ(total, 10);
    // L* carries most of the (filtered) energy.
    EXPECT_GT(m.blocks[0].components(), m.blocks[1].components());
    // What one more component would add in any plane is at most the smallest kept one.
    const factor::Model more =
        perceptual::factorize(source, perceptual::parse_options(Params({{"components", "11"}})));
    float added = 0;
    for (int p = 0; p < 3; ++p)
        if (more.blocks[p].components() > m.blocks[p].components())
            added = more.blocks[p].energy.back();
    EXPECT_LE(added, smallest_kept * (1 + 1e-4));
}

TEST(Perceptual, VectorizedEvaluationMatchesTheScalarReference) {
    const BtfSource& source = fabric();
    const auto material =
        perceptual_codec().open(encode(source, Params({{"components", "13"}, {"mean", "true"}})));
    const auto& fm = dynamic_cast<const FactorMaterial&>(*material);
    const auto queries = random_queries(1000, 3);
    std::vector<Rgb> batch(queries.size());
    fm.eval_batch(queries, batch);
    for (size_t i = 0; i < queries.size(); ++i) {
        const Query& q = queries[i];
        const Rgb fast = fm.eval(q.uv, q.wi, q.wo), ref = fm.eval_reference(q.uv, q.wi, q.wo);
        ASSERT_NEAR(fast.r, ref.r, 1e-4) << i;
        ASSERT_NEAR(fast.g, ref.g, 1e-4) << i;
        ASSERT_NEAR(fast.b, ref.b, 1e-4) << i;
        ASSERT_EQ(fast, batch[i]);
    }
    // At sample directions and texel centres: the decoded samples.
    const Sampling& s = source.sampling();
    for (int v = 0; v < s.num_views(); v += 3)
        for (int l = 0; l < s.num_lights(); l += 4) {
            const Rgb a =
                fm.eval({(2 + 0.5) / 16, (7 + 0.5) / 16}, s.lights.vector(l), s.views.vector(v));
            const Rgb b = fm.eval_sample(2, 7, v, l);
            EXPECT_NEAR(a.r, b.r, 1e-4);
            EXPECT_NEAR(a.g, b.g, 1e-4);
            EXPECT_NEAR(a.b, b.b, 1e-4);
        }
}

TEST(Perceptual, PrefixesAddComponentsInDecreasingPerceptualEnergy) {
    const BtfSource& source = fabric();
    const Package full = encode(source, Params({{"components", "8"}, {"quantize", "f32"}}));
    double previous = INFINITY;
    for (int n = 0; n <= full.declared_sections; ++n) {
        Package prefix = full;
        prefix.sections.resize(n);
        if (n < 2) continue;  // tables and means: no factors yet, the planes are all zero
        const auto material = perceptual_codec().open(prefix);
        const double e = perceptual_error(source, *material, {10, 100});
        EXPECT_LT(e, previous) << n;
        previous = e;
    }
}

TEST(Perceptual, IsDeterministicForAnyThreadCount) {
    const BtfSource& source = fabric();
    for (const std::string quality : {"1", "0.6"}) {  // without and with omission
        const Params params({{"components", "7"}, {"mean", "true"}, {"base-quality", quality}});
        const auto bytes = test::bytes_per_thread_count([&] {
            Package p = encode(source, params);
            return encode_package(p);
        });
        EXPECT_EQ(bytes[0], bytes[1]) << quality;
        EXPECT_EQ(bytes[0], bytes[2]) << quality;
    }
}

TEST(Perceptual, RejectsBadParameters) {
    const BtfSource& source = fabric();
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"sped", "3"}}));
              }),
              "codec perceptual: unknown parameter 'sped' (known: components, resolution, speed, "
              "mean, csf, base-quality, max-level, max-angular-level, quantize, svd, "
              "oversampling, power-iterations, block, seed, quality)");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"base-quality", "1.5"}}));
              }),
              "parameter base-quality: 1.5 is outside [0, 1]");
    // The omission's quality under its old name sets coded storage's quality instead: refused
    // without coded storage rather than silently ignored.
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"quality", "0.5"}}));
              }),
              "parameter quality: it sets the quantization step of quantize=coded, and quantize "
              "is f16; the base quality bq of high-frequency omission is parameter base-quality");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"max-level", "9"}}));
              }),
              "parameter max-level: 9 is outside [0, 8]");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"resolution", "0.5"}}));
              }),
              "parameter resolution: 0.5 is outside [1, 1000]");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"speed", "20000"}}));
              }),
              "parameter speed: 20000 is outside [1, 10000]");
    EXPECT_EQ(test::error_of([&] {
                  encode(source, Params({{"components", "0"}}));
              }),
              "parameter components: 0 is outside [1, 4096]");
}

// ---- high-frequency omission ----------------------------------------------------------------

// Bilinear, wrapping up-sampling by 2^level written out directly: fine texel x reads the coarse
// grid at (x + 0.5) / 2^level − 0.5.
double upsampled(const Eigen::VectorXd& coarse, int cw, int ch, int level, int x, int y) {
    const double f = 1 << level;
    const double cx = (x + 0.5) / f - 0.5, cy = (y + 0.5) / f - 0.5;
    const int x0 = int(std::floor(cx)), y0 = int(std::floor(cy));
    const double tx = cx - x0, ty = cy - y0;
    auto at = [&](int i, int j) { return coarse[((j % ch + ch) % ch) * cw + (i % cw + cw) % cw]; };
    return (1 - tx) * (1 - ty) * at(x0, y0) + tx * (1 - ty) * at(x0 + 1, y0) +
           (1 - tx) * ty * at(x0, y0 + 1) + tx * ty * at(x0 + 1, y0 + 1);
}

TEST(LevelResampler, UpsamplesBilinearlyAndDownsamplesByThePseudoInverse) {
    std::mt19937_64 rng(1);
    std::normal_distribution<double> normal;
    for (const auto& [w, h, level] : {std::tuple{16, 8, 1}, {16, 8, 2}, {16, 8, 3}, {8, 8, 3}}) {
        const perceptual::LevelResampler r(w, h, level);
        const int cw = w >> level, ch = h >> level;
        ASSERT_EQ(r.coarse_width(), cw);
        Eigen::VectorXd c(cw * ch), x(w * h);
        for (auto& v : c) v = normal(rng);
        for (auto& v : x) v = normal(rng);
        const Eigen::VectorXd up = r.upsample(c);
        for (int y = 0; y < h; ++y)
            for (int i = 0; i < w; ++i)
                ASSERT_NEAR(up[y * w + i], upsampled(c, cw, ch, level, i, y), 1e-12);
        // D is a left inverse of B, and B D x is x's orthogonal projection onto B's range.
        EXPECT_LT((r.downsample(up) - c).norm(), 1e-10 * c.norm());
        const Eigen::VectorXd residual = x - r.upsample(r.downsample(x));
        EXPECT_NEAR(residual.dot(up), 0.0, 1e-10 * x.norm() * up.norm());
        EXPECT_GT(residual.norm(), 0.1 * x.norm());
    }
    EXPECT_EQ(test::error_of([] { perceptual::LevelResampler(12, 8, 3); }),
              "spatial level 3 of a 12×8 texture: the extent must be divisible by 8");
}

perceptual::OmissionReport report_of(const BtfSource& source, const Params& params,
                                     factor::Model* model = nullptr) {
    perceptual::OmissionReport report;
    factor::Model m =
        perceptual::factorize(source, perceptual::parse_options(params), Progress::none(), &report);
    if (model) *model = std::move(m);
    return report;
}

TEST(PerceptualOmission, QualityOneKeepsEveryEigenTextureAtFullResolution) {
    const BtfSource& source = fabric();
    Package plain = encode(source, Params({{"components", "10"}}));
    Package one = encode(source, Params({{"components", "10"}, {"base-quality", "1"}}));
    EXPECT_EQ(encode_package(plain), encode_package(one));
    EXPECT_FALSE(one.header.at("model").contains("levels"));
    factor::Model model;
    const auto report =
        report_of(source, Params({{"components", "10"}, {"base-quality", "1"}}), &model);
    EXPECT_EQ(model.levels, 1);
    ASSERT_EQ(report.components.size(), 10u);
    for (const auto& c : report.components) EXPECT_EQ(c.level, 0);
    // max-level=0 allows no omission at any quality.
    const auto none = report_of(
        source, Params({{"components", "10"}, {"base-quality", "0"}, {"max-level", "0"}}));
    for (const auto& c : none.components) EXPECT_EQ(c.level, 0);
}

// Bytes of the factors: the component sections (the rest of a package, the sampling and its
// interpolation tables, does not depend on the quality).
size_t factor_bytes(const Package& p) {
    size_t bytes = 0;
    for (const PackageSection& s : p.sections)
        if (s.name[0] == 'b') bytes += s.data.size();
    return bytes;
}

TEST(PerceptualOmission, LowerQualityMakesSmallerPackages) {
    const BtfSource& source = fabric();
    size_t previous = SIZE_MAX, full = 0, full_file = 0, file = 0;
    int previous_levels = 0;
    for (const std::string q : {"1", "0.97", "0.9", "0.7", "0.4", "0"}) {
        const Params params(
            {{"components", "12"}, {"base-quality", q}, {"max-angular-level", "0"}});
        Package p = encode(source, params);
        const size_t bytes = factor_bytes(p);
        file = encode_package(p).size();
        if (q == "1") {
            full = bytes;
            full_file = file;
        }
        EXPECT_LE(bytes, previous) << q;
        previous = bytes;
        const auto report = report_of(source, params);
        int levels = 0;
        for (const auto& c : report.components) levels += c.level;
        EXPECT_GE(levels, previous_levels) << q;
        previous_levels = levels;
    }
    // 12 components of 80 angular and 16² spatial values; at bq = 0 the textures have 2² texels.
    EXPECT_EQ(full, 12u * (80 + 256) * 2);
    EXPECT_EQ(previous, 12u * (80 + 4) * 2);
    EXPECT_LT(file, full_file);
    // bq = 0 weighs size alone: every eigen-texture at the coarsest level (16² → 2²).
    const auto zero = report_of(
        source, Params({{"components", "12"}, {"base-quality", "0"}, {"max-angular-level", "0"}}));
    for (const auto& c : zero.components) EXPECT_EQ(c.level, 3);
    // Levels must divide the extent: 12² texels allow ×1/2 and ×1/4, not ×1/8.
    const auto twelve = test::cached(*synth::make("leather", 12, test::ubo_subset(3, 4), 1));
    const auto report = report_of(*twelve, Params({{"components", "4"}, {"base-quality", "0"}}));
    for (const auto& c : report.components) EXPECT_EQ(c.level, 2);
}

// Angular omission: the eigen-ABRDFs of the 8 views × 10 lights may keep 4 × 5 directions (level
// 1); level 2 would keep 2 views, fewer than a triangulation needs, so it does not exist.
TEST(PerceptualOmission, AngularLevelsShrinkTheEigenAbrdfs) {
    const BtfSource& source = fabric();
    const std::vector<factor::AngularLevel> levels =
        factor::nested_angular_levels(source.sampling(), 4);
    ASSERT_EQ(levels.size(), 1u);
    EXPECT_EQ(levels[0].views.size(), 4u);
    EXPECT_EQ(levels[0].lights.size(), 5u);
    size_t previous = SIZE_MAX;
    int previous_angular = 0;
    for (const std::string q : {"1", "0.97", "0.9", "0.7", "0.4", "0"}) {
        const Params params({{"components", "12"}, {"base-quality", q}, {"max-level", "0"}});
        Package p = encode(source, params);
        EXPECT_LE(factor_bytes(p), previous) << q;
        previous = factor_bytes(p);
        const auto report = report_of(source, params);
        int angular = 0;
        for (const auto& c : report.components) {
            EXPECT_EQ(c.level, 0);
            angular += c.angular;
        }
        EXPECT_GE(angular, previous_angular) << q;
        previous_angular = angular;
        if (q == "1") EXPECT_FALSE(p.header.at("model").contains("angular_levels"));
    }
    // At bq = 0 every eigen-ABRDF has 4 · 5 values (of 80).
    EXPECT_EQ(previous, 12u * (20 + 256) * 2);
    // Both kinds together: the coarsest of each.
    Package both = encode(source, Params({{"components", "12"}, {"base-quality", "0"}}));
    EXPECT_EQ(factor_bytes(both), 12u * (20 + 4) * 2);
    const nlohmann::json& model = both.header.at("model");
    ASSERT_EQ(model.at("angular_levels").size(), 1u);
    EXPECT_EQ(model.at("angular_levels")[0].at("views").get<std::vector<int>>(), levels[0].views);
    EXPECT_EQ(model.at("angular_levels")[0].at("lights").get<std::vector<int>>(), levels[0].lights);
}

// The perceptual error omission adds is the sum of what each chosen level gives up. With one kind
// of level this is exact: the filtered ABRDFs are orthonormal (spatial levels), the filtered
// textures orthogonal (angular levels), so the components' losses add. With both kinds, cross
// terms between components remain, which the sum neglects.
TEST(PerceptualOmission, AddsThePerceptualErrorItPredicts) {
    const BtfSource& source = fabric();
    const perceptual::Viewing viewing{10, 100};
    const Params full({{"components", "12"}, {"quantize", "f32"}, {"power-iterations", "6"}});
    const auto reference = perceptual_codec().open(encode(source, full));
    const double base = perceptual_error(source, *reference, viewing);
    struct Mode {
        const char* max_level;
        const char* max_angular;
        double tolerance;  // relative
    };
    for (const Mode mode : {Mode{"3", "0", 1e-3}, Mode{"0", "2", 1e-3}, Mode{"3", "2", 0.02}})
        for (const std::string q : {"0.9", "0.5"}) {
            Params reduced = full;
            reduced.set("base-quality", q);
            reduced.set("max-level", mode.max_level);
            reduced.set("max-angular-level", mode.max_angular);
            const auto report = report_of(source, reduced);
            double predicted = 0;
            int omitted = 0;
            for (const auto& c : report.components) {
                predicted += c.lost;
                omitted += c.level > 0 || c.angular > 0;
                if (c.level == 0 && c.angular == 0) {
                    EXPECT_EQ(c.lost, 0.0);
                }
            }
            ASSERT_GT(omitted, 0) << q;
            const auto material = perceptual_codec().open(encode(source, reduced));
            const double added = perceptual_error(source, *material, viewing) - base;
            EXPECT_NEAR(added, predicted, mode.tolerance * predicted)
                << q << " " << mode.max_level << " " << mode.max_angular;
        }
}

// Column k of a block's a at every (view, light) row: for an angular level, each full direction
// reads the level's directions through their own triangulation.
std::vector<double> full_abrdf(const factor::Model& model, const factor::Block& b, int k) {
    const int nv = model.sampling.num_views(), nl = model.sampling.num_lights();
    std::vector<double> out(size_t(nv) * nl);
    if (b.angular == 0) {
        for (size_t r = 0; r < out.size(); ++r) out[r] = b.a(int64_t(r), k);
        return out;
    }
    const factor::AngularLevel& level = model.angular_levels[size_t(b.angular - 1)];
    const AngularInterpolator views(model.sampling.views.subset(level.views, "v"));
    const AngularInterpolator lights(model.sampling.lights.subset(level.lights, "l"));
    const int cl = static_cast<int>(level.lights.size());
    for (int v = 0; v < nv; ++v)
        for (int l = 0; l < nl; ++l) {
            const AngularWeights wv = views.weights(model.sampling.views.vector(v));
            const AngularWeights wl = lights.weights(model.sampling.lights.vector(l));
            double sum = 0;
            for (int i = 0; i < wv.count; ++i)
                for (int j = 0; j < wl.count; ++j)
                    sum += double(wv.weight[i]) * wl.weight[j] *
                           b.a(int64_t(wv.index[i]) * cl + wl.index[j], k);
            out[size_t(v) * nl + l] = sum;
        }
    return out;
}

// The evaluator against a reconstruction written out here: value = mean + Σ_blocks (U_angular a)
// · (B_level b)ᵀ in CIELab, then linear RGB; interpolated with lookup6d.
TEST(PerceptualOmission, EvaluatorMatchesAReferenceReconstruction) {
    const BtfSource& source = fabric();
    Package package =
        encode(source, Params({{"components", "14"}, {"base-quality", "0.6"}, {"mean", "true"}}));
    const auto material = open_material(decode_package(encode_package(package), "memory"));
    const auto& fm = dynamic_cast<const FactorMaterial&>(*material);
    const factor::Model& model = fm.model();
    ASSERT_GT(model.levels, 1);
    EXPECT_EQ(package.header.at("model").at("levels"), model.levels);
    std::set<int> used, used_angular;
    for (const factor::Block& b : model.blocks)
        if (b.components() > 0) {
            used.insert(b.level);
            used_angular.insert(b.angular);
        }
    EXPECT_GE(used.size(), 2u);
    EXPECT_EQ(used_angular.size(), 2u);
    const int w = model.width, h = model.height, nl = model.sampling.num_lights();
    // Lab planes of every sample: [plane][row][texel].
    std::vector<std::vector<double>> lab(3, std::vector<double>(size_t(model.rows(0)) * w * h, 0));
    for (const factor::Block& b : model.blocks) {
        const int cw = w >> b.level, ch = h >> b.level;
        for (int k = 0; k < b.components(); ++k) {
            const Eigen::VectorXd coarse = b.b.col(k).cast<double>();
            const std::vector<double> a = full_abrdf(model, b, k);
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x) {
                    const double t = upsampled(coarse, cw, ch, b.level, x, y);
                    for (int64_t row = 0; row < model.rows(0); ++row)
                        lab[b.plane][size_t(row) * w * h + y * w + x] += a[size_t(row)] * t;
                }
        }
        if (!b.mean.empty())
            for (int64_t row = 0; row < model.rows(0); ++row)
                for (int t = 0; t < w * h; ++t)
                    lab[b.plane][size_t(row) * w * h + t] += b.mean[row];
    }
    auto reference = [&](int x, int y, int view, int light) {
        const size_t i = size_t(int64_t(view) * nl + light) * w * h + y * w + x;
        return Rgb{float(lab[0][i]), float(lab[1][i]), float(lab[2][i])};
    };
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < nl; l += 3)
            for (int t = 0; t < w * h; t += 7) {
                const Rgb want =
                    lab_to_rgb({reference(t % w, t / w, v, l).r, reference(t % w, t / w, v, l).g,
                                reference(t % w, t / w, v, l).b});
                const Rgb got = fm.eval_sample(t % w, t / w, v, l);
                ASSERT_NEAR(got.r, want.r, 2e-4 + 1e-3 * std::abs(want.r));
                ASSERT_NEAR(got.g, want.g, 2e-4 + 1e-3 * std::abs(want.g));
                ASSERT_NEAR(got.b, want.b, 2e-4 + 1e-3 * std::abs(want.b));
            }
    const AngularInterpolator views(model.sampling.views), lights(model.sampling.lights);
    const auto queries = random_queries(1500, 9);
    std::vector<Rgb> batch(queries.size());
    fm.eval_batch(queries, batch);
    for (size_t i = 0; i < queries.size(); ++i) {
        const Query& q = queries[i];
        const Rgb planes =
            lookup6d(q.uv, w, h, views.weights(q.wo), lights.weights(q.wi), reference);
        const Rgb want = lab_to_rgb({planes.r, planes.g, planes.b});
        const Rgb got = fm.eval(q.uv, q.wi, q.wo);
        ASSERT_NEAR(got.r, want.r, 2e-4 + 1e-3 * std::abs(want.r)) << i;
        ASSERT_NEAR(got.g, want.g, 2e-4 + 1e-3 * std::abs(want.g)) << i;
        ASSERT_NEAR(got.b, want.b, 2e-4 + 1e-3 * std::abs(want.b)) << i;
        ASSERT_EQ(got, batch[i]) << i;
        const Rgb ref = fm.eval_reference(q.uv, q.wi, q.wo);
        ASSERT_NEAR(got.r, ref.r, 1e-4) << i;
        ASSERT_NEAR(got.g, ref.g, 1e-4) << i;
        ASSERT_NEAR(got.b, ref.b, 1e-4) << i;
    }
}

TEST(PerceptualOmission, PrefixesOfAMultiLevelPackageOpen) {
    const BtfSource& source = fabric();
    const Package full = encode(
        source, Params({{"components", "10"}, {"base-quality", "0.7"}, {"quantize", "f32"}}));
    // Sections: tables, angular (the up-sampling of the angular levels), means, components.
    ASSERT_EQ(full.sections[1].name, "angular");
    ASSERT_EQ(full.sections[2].name, "means");
    double previous = INFINITY;
    for (int n = 3; n <= full.declared_sections; ++n) {
        Package prefix = full;
        prefix.sections.resize(n);
        const auto material = perceptual_codec().open(prefix);
        const double e = perceptual_error(source, *material, {10, 100});
        EXPECT_LT(e, previous) << n;
        previous = e;
    }
}

TEST(PerceptualOmission, TheAngularSectionIsTheUpSamplingOfTheHeadersLevels) {
    const Package full = encode(fabric(), Params({{"components", "6"}, {"base-quality", "0.7"}}));
    const factor::Model model = factor::from_package(full);
    ASSERT_FALSE(model.angular_levels.empty());
    const PackageSection* angular = full.find("angular");
    ASSERT_NE(angular, nullptr);
    // Per level: U of the views, then of the lights, float32; each row a partition of unity.
    size_t at = 0;
    for (const factor::AngularLevel& level : model.angular_levels)
        for (const auto& [full_count, kept] :
             {std::pair{model.sampling.num_views(), level.views.size()},
              std::pair{model.sampling.num_lights(), level.lights.size()}})
            for (int i = 0; i < full_count; ++i) {
                float sum = 0;
                for (size_t j = 0; j < kept; ++j, at += 4) {
                    float w;
                    std::memcpy(&w, angular->data.data() + at, 4);
                    sum += w;
                }
                EXPECT_NEAR(sum, 1.0f, 1e-5f);
            }
    EXPECT_EQ(at, angular->data.size());
    // Weights that differ in their last bits (as an earlier lookup's may: a direction on an
    // edge lies in two triangles) are the same up-sampling; a changed weight or a NaN is not.
    auto with_weight = [&](size_t i, auto change) {
        Package p = full;
        float w;
        std::memcpy(&w, p.sections[1].data.data() + 4 * i, 4);
        w = change(w);
        std::memcpy(p.sections[1].data.data() + 4 * i, &w, 4);
        return p;
    };
    for (const size_t i : {size_t(0), size_t(1), angular->data.size() / 4 - 1}) {
        EXPECT_NO_THROW(perceptual_codec().open(
            with_weight(i, [](float w) { return std::nextafter(w, 2.0f); })));
        EXPECT_THAT(test::error_of([&] {
                        perceptual_codec().open(with_weight(i, [](float w) { return w + 0.01f; }));
                    }),
                    testing::HasSubstr("section 'angular'"));
        EXPECT_THAT(test::error_of([&] {
                        perceptual_codec().open(with_weight(i, [](float) { return NAN; }));
                    }),
                    testing::HasSubstr("weights differing by up to inf"));
    }
}

TEST(PerceptualOmission, TheModelRejectsLevelsItCannotHold) {
    factor::Model model = perceptual::factorize(
        fabric(), perceptual::parse_options(Params(
                      {{"components", "6"}, {"base-quality", "0"}, {"max-angular-level", "0"}})));
    ASSERT_EQ(model.levels, 4);
    factor::Model odd = model;
    odd.width = 12;  // not divisible by 8
    EXPECT_EQ(test::error_of([&] { odd.validate("test"); }),
              "test: 4 spatial levels need width and height divisible by 8 (12×16)");
    factor::Model clustered = model;
    clustered.clusters = 2;
    clustered.texel_cluster.assign(16 * 16, 0);
    EXPECT_EQ(test::error_of([&] { clustered.validate("test"); }),
              "test: 4 spatial levels with 2 texel clusters (levels need one cluster)");
    Package p = encode(fabric(), Params({{"components", "6"}, {"base-quality", "0"}}));
    Package spatial = p;
    spatial.header["model"]["levels"] = 5;
    EXPECT_EQ(test::error_of([&] { perceptual_codec().open(spatial); }),
              "package (perceptual): 24 blocks for 3 planes × 1 groups × 1 clusters × 5 levels × 2 "
              "angular levels");
    // Angular levels: direction indices must exist, ascend and number at least 3.
    Package bad = p;
    bad.header["model"]["angular_levels"][0]["views"] = {0, 1, 8, 9};
    EXPECT_EQ(test::error_of([&] { perceptual_codec().open(bad); }),
              "package (perceptual): angular level 1 views must be ascending indices below 8");
    bad.header["model"]["angular_levels"][0]["views"] = {0, 1};
    EXPECT_EQ(test::error_of([&] { perceptual_codec().open(bad); }),
              "package (perceptual): angular level 1 keeps 2 views (at least 3)");
    bad.header["model"]["angular_levels"][0]["views"] = {3, 1, 2};
    EXPECT_EQ(test::error_of([&] { perceptual_codec().open(bad); }),
              "package (perceptual): angular level 1 views must be ascending indices below 8");
    bad.header["model"]["angular_levels"] = nlohmann::json::array();
    EXPECT_EQ(test::error_of([&] { perceptual_codec().open(bad); }),
              "package (perceptual): 0 angular levels");
    factor::Model grouped = perceptual::factorize(
        fabric(), perceptual::parse_options(Params({{"components", "6"}, {"base-quality", "0"}})));
    ASSERT_EQ(grouped.angular_levels.size(), 1u);
    std::swap(grouped.groups[0][0], grouped.groups[0][1]);
    EXPECT_EQ(test::error_of([&] { grouped.validate("test"); }),
              "test: angular levels need one view group with the views in order (1 groups)");
}

TEST(Perceptual, IsInTheRegistry) {
    EXPECT_EQ(&find_codec("perceptual"), &perceptual_codec());
    std::vector<std::string> names;
    for (const ParamInfo& p : perceptual_codec().params()) names.push_back(p.name);
    EXPECT_NE(std::find(names.begin(), names.end(), "resolution"), names.end());
    EXPECT_NE(std::find(names.begin(), names.end(), "speed"), names.end());
}

}  // namespace
}  // namespace btf

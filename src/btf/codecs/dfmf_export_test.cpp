// SPDX-License-Identifier: MIT
#include "btf/codecs/dfmf_export.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "btf/codecs/fmf/fmf.h"
#include "btf/core/color.h"
#include "btf/io/function_source.h"
#include "btf/io/package.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

using testing::HasSubstr;

// Texel albedo × angular factor with a fixed colour: rank 1 in RGB, rank ≤ 2 in (log Y, U/Y,
// V/Y), so a few components per channel reproduce it to float precision.
FunctionSource rank_one_source() {
    return FunctionSource(test::five_views_four_lights(), 9, 7, [](int v, int l, int x, int y) {
        const float a = 0.2f + 0.05f * x + 0.03f * y, g = 0.5f + 0.1f * v + 0.07f * l;
        return Rgb{a * g, 0.8f * a * g, 0.5f * a * g};
    });
}

TEST(DfmfExport, WritesAFileThatReadsBackAsTheSource) {
    const FunctionSource source = rank_one_source();
    const test::TempFolder dir;
    for (int32_t model : {ubo2014::kColorModelRgb, ubo2014::kColorModelLogYUV}) {
        SCOPED_TRACE(model);
        DfmfExportOptions options;
        options.components = 3;
        options.color_model = model;
        const auto path = dir.path() / ("m" + std::to_string(model) + ".btf");
        export_dfmf(path, source, options);
        const auto f = ubo2014::read(path);
        EXPECT_EQ(f->body, ubo2014::Body::kDfmf);
        EXPECT_EQ(f->color_model, model);
        ASSERT_EQ(f->factors.size(), 3u);
        for (const auto& factor : f->factors) EXPECT_EQ(factor.components(), 3);
        double max_error = 0;
        for (int v = 0; v < source.num_views(); ++v)
            for (int l = 0; l < source.num_lights(); ++l)
                for (int y = 0; y < 7; ++y)
                    for (int x = 0; x < 9; ++x) {
                        const Rgb a = source.value(v, l, x, y), b = f->sample(x, y, v, l);
                        max_error =
                            std::max({max_error, double(std::abs(a.r - b.r)),
                                      double(std::abs(a.g - b.g)), double(std::abs(a.b - b.b))});
                    }
        EXPECT_LT(max_error, 1e-4);
    }
}

TEST(DfmfExport, RowsFollowTheViewOrderWhateverTheGroupOrder) {
    const FunctionSource source(
        test::five_views_four_lights(), 5, 4, [](int v, int l, int x, int y) {
            return Rgb{0.1f + 0.1f * v + 0.02f * x, 0.3f + 0.05f * l * y, 0.2f + 0.01f * v * l};
        });
    fmf::Options options;
    options.components = 6;
    options.colour.basis = factor::ColourBasis::kPerChannel;
    options.quantization = factor::Quantization::kF32;
    factor::Model model = fmf::factorize(source, options);
    // Put the views in the group in reverse order, moving their rows of a along.
    const int nv = source.num_views(), nl = source.num_lights();
    std::reverse(model.groups[0].begin(), model.groups[0].end());
    for (factor::Block& block : model.blocks) {
        factor::Matrix a = block.a;
        for (int slot = 0; slot < nv; ++slot)
            a.middleRows(int64_t(slot) * nl, nl) =
                block.a.middleRows(int64_t(nv - 1 - slot) * nl, nl);
        block.a = a;
    }
    const factor::FactorMaterial material(model);
    const ubo2014::Factorization f = to_dfmf(model, 4, {}, "reversed");
    for (int v = 0; v < nv; ++v)
        for (int l = 0; l < nl; ++l)
            for (int y = 0; y < 4; ++y)
                for (int x = 0; x < 5; ++x) {
                    const Rgb a = material.eval_sample(x, y, v, l), b = f.sample(x, y, v, l);
                    EXPECT_NEAR(a.r, b.r, 1e-5);
                    EXPECT_NEAR(a.g, b.g, 1e-5);
                    EXPECT_NEAR(a.b, b.b, 1e-5);
                }
}

TEST(DfmfExport, RefusesModelsDfmfCannotHold) {
    const FunctionSource source = rank_one_source();
    fmf::Options options;
    options.components = 2;
    options.colour.basis = factor::ColourBasis::kPerChannel;
    options.subtract_mean = true;
    EXPECT_THAT(test::error_of([&] { to_dfmf(fmf::factorize(source, options), 4, {}, "x"); }),
                HasSubstr("x: channel 0 has row means, which DFMF cannot hold"));
    options.subtract_mean = false;
    options.colour.basis = factor::ColourBasis::kDecorrelated;
    EXPECT_THAT(test::error_of([&] { to_dfmf(fmf::factorize(source, options), 4, {}, "x"); }),
                HasSubstr("x: colour handling 'decorrelated' has no DFMF colour model"));

    DfmfExportOptions bad;
    bad.color_model = 3;
    EXPECT_THAT(test::error_of([&] { factorize_dfmf(source, bad); }),
                HasSubstr("cannot factorize into colour model 3"));
}

// ---- model_of: a UBO2014 factorization as an fmf model, without refactorizing ---------------

// Random factors (model 11's log Y stays within ±1.5 for three components of ±0.5 · ±1).
ubo2014::Factorization random_ubo2014(ubo2014::Body body, int32_t colour_model, uint32_t drr) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> uniform(-0.5f, 0.5f);
    ubo2014::Factorization f;
    f.body = body;
    f.sampling = test::five_views_four_lights();
    f.width = 6, f.height = 5;
    f.color_model = colour_model;
    f.dynamic_range_reduction = drr;
    const int images = f.sampling.num_images();
    const auto factor = [&](int64_t rows, int k) {
        ubo2014::Factor out;
        out.u.resize(rows, k);
        out.sxv.resize(int64_t(f.width) * f.height, k);
        out.s.resize(k);
        for (int64_t i = 0; i < out.u.size(); ++i) out.u.data()[i] = uniform(rng);
        for (int64_t i = 0; i < out.sxv.size(); ++i) out.sxv.data()[i] = 2 * uniform(rng);
        for (int i = 0; i < k; ++i) out.s[i] = 3.0f - i;
        return out;
    };
    if (body == ubo2014::Body::kDfmf) {
        for (int k : {3, 2, 1}) f.factors.push_back(factor(images, k));
        if (colour_model == ubo2014::kColorModelRgb) f.factors[0].sxv.array() += 1.0f;
    } else {
        f.factors.push_back(factor(int64_t(images) * 3, 3));
    }
    return f;
}

TEST(DfmfImport, TheModelOfAFactorizationIsItsValueAtEverySample) {
    struct Case {
        ubo2014::Body body;
        int32_t colour;
        uint32_t drr;
        factor::ColourBasis basis;
    };
    for (const Case& c :
         {Case{ubo2014::Body::kDfmf, ubo2014::kColorModelRgb, 0, factor::ColourBasis::kPerChannel},
          Case{ubo2014::Body::kDfmf, ubo2014::kColorModelLogYUV, 0,
               factor::ColourBasis::kUboModel11},
          Case{ubo2014::Body::kFmf, 0, 0, factor::ColourBasis::kRgb},
          Case{ubo2014::Body::kFmf, 0, 1, factor::ColourBasis::kRgb}}) {
        const ubo2014::Factorization f = random_ubo2014(c.body, c.colour, c.drr);
        const factor::Model model = model_of(f, "x.btf");
        EXPECT_EQ(model.colour.basis, c.basis);
        EXPECT_EQ(model.colour.log, c.drr != 0);
        // Through a package (float32 factors) as `btf convert` writes it.
        const factor::FactorMaterial material(
            factor::from_package(factor::to_package(model, "fmf", {}, factor::Quantization::kF32)));
        // Relative to at least 1e-2: both sides sum the products of factors in floats, the
        // evaluator in another order (vector lanes), and where these random factors cancel
        // (products of ±0.25 summing to 1e-3) the orders differ by roundings of 1e-8.
        double worst = 0;
        for (int v = 0; v < f.sampling.num_views(); ++v)
            for (int l = 0; l < f.sampling.num_lights(); ++l)
                for (int y = 0; y < f.height; ++y)
                    for (int x = 0; x < f.width; ++x) {
                        const Rgb want = f.sample(x, y, v, l);
                        const Rgb got = material.eval_sample(x, y, v, l);
                        const float w[3] = {want.r, want.g, want.b}, g[3] = {got.r, got.g, got.b};
                        for (int ch = 0; ch < 3; ++ch)
                            worst = std::max(worst, std::abs(double(g[ch]) - w[ch]) /
                                                        std::max(1e-2, std::abs(double(w[ch]))));
                    }
        EXPECT_LT(worst, 1e-5) << int(c.body) << " " << c.colour << " " << c.drr;
    }
}

TEST(DfmfImport, CosineWeightedValuesAreRefusedNamingTheFile) {
    ubo2014::Factorization f = random_ubo2014(ubo2014::Body::kDfmf, ubo2014::kColorModelLogYUV, 0);
    f.meta.version = 2;
    f.meta.cosine_flag = true;
    EXPECT_THAT(test::error_of([&] { model_of(f, "x.btf"); }),
                HasSubstr("x.btf: the values are multiplied by cos θ_light"));
}

// ---- a UBO2014 file as a material: the fmf evaluator of its factors, as its package ----------

// Queries over the whole plane and hemisphere: uv in [-2, 3)² (wrapping), every fifth pair of
// directions grazing (θ in [85°, 90°]), the others with cos θ uniform.
std::vector<Query> wide_queries(int count, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(0, 1);
    const auto direction = [&](bool grazing) {
        const double theta = grazing ? radians(85 + 5 * unit(rng)) : std::acos(unit(rng));
        return Direction{theta, 2 * kPi * unit(rng)}.vector();
    };
    std::vector<Query> queries(static_cast<size_t>(count));
    for (int i = 0; i < count; ++i) {
        Query& q = queries[size_t(i)];
        q.uv = {-2 + 5 * unit(rng), -2 + 5 * unit(rng)};
        q.wi = direction(i % 5 == 1);
        q.wo = direction(i % 5 == 3);
    }
    return queries;
}

// Largest |a − b| / (|b| + 1e-2) over the channels of all queries, failing each query whose
// difference exceeds 1e-4 relative plus 1e-6.
double compare_materials(const Material& a, const Material& b, const std::vector<Query>& queries) {
    double worst = 0;
    for (const Query& q : queries) {
        const Rgb x = a.eval(q.uv, q.wi, q.wo), y = b.eval(q.uv, q.wi, q.wo);
        const float xs[3] = {x.r, x.g, x.b}, ys[3] = {y.r, y.g, y.b};
        for (int c = 0; c < 3; ++c) {
            const double d = std::abs(double(xs[c]) - ys[c]);
            EXPECT_LE(d, 1e-4 * std::abs(ys[c]) + 1e-6)
                << "uv " << q.uv.u << "," << q.uv.v << " channel " << c << ": " << xs[c] << " vs "
                << ys[c];
            worst = std::max(worst, d / (std::abs(double(ys[c])) + 1e-2));
        }
    }
    return worst;
}

// A material with detail in every direction and texel, so that interpolation matters.
FunctionSource varied_source() {
    const Sampling s = test::ubo_subset(14, 12);
    return FunctionSource(s, 8, 6, [s](int v, int l, int x, int y) {
        const Vec3 wi = s.lights.vector(l), wo = s.views.vector(v);
        const float n = test::hash01(v, l, x, y);
        const float a = 0.15f + 0.3f * test::hash01(x, y, 0, 1);
        const float g =
            float(0.3 + 0.5 * wi.z * (0.6 + 0.4 * wo.z) +
                  0.4 * std::pow(std::max(0.0, wi.x * -wo.x + wi.y * -wo.y + wi.z * wo.z), 8));
        return Rgb{a * g * (0.9f + 0.2f * n), 0.7f * a * g + 0.05f * n, 0.4f * a * g * (1 + n)};
    });
}

TEST(DfmfImport, AFileAndItsPackageAreOneMaterial) {
    const FunctionSource source = varied_source();
    const test::TempFolder dir;
    const std::vector<Query> queries = wide_queries(600, 17);
    for (int32_t model : {ubo2014::kColorModelRgb, ubo2014::kColorModelLogYUV})
        for (int scalar_size : {2, 4}) {
            const std::string name =
                fmt::format("m{}_{}", model, scalar_size == 2 ? "half" : "float");
            SCOPED_TRACE(name);
            DfmfExportOptions options;
            options.components = 5;
            options.color_model = model;
            options.scalar_size = scalar_size;
            const auto btf = dir.path() / (name + ".btf"), pkg = dir.path() / (name + ".btfpkg");
            export_dfmf(btf, source, options);
            Package converted = package_of(*ubo2014::read(btf), btf.string());
            write_package(pkg, converted);
            // What btf eval, render and report open: the same evaluator over the same factors.
            const std::unique_ptr<Material> file = open_material(btf), package = open_material(pkg);
            ASSERT_NE(dynamic_cast<const factor::FactorMaterial*>(file.get()), nullptr);
            const double worst = compare_materials(*file, *package, queries);
            RecordProperty(name + "_max_relative_difference", fmt::format("{:.3g}", worst));
            EXPECT_LT(worst, 1e-5);
            // At the sample directions and texel centres: the file's decoded values.
            const auto f = ubo2014::read(btf);
            const Sampling& s = f->sampling;
            for (int v = 0; v < s.num_views(); v += 3)
                for (int l = 0; l < s.num_lights(); l += 2)
                    for (int y = 0; y < f->height; ++y)
                        for (int x = 0; x < f->width; ++x) {
                            const Rgb want = f->sample(x, y, v, l);
                            const Rgb got =
                                file->eval({(x + 0.5) / f->width, (y + 0.5) / f->height},
                                           s.lights.vector(l), s.views.vector(v));
                            EXPECT_NEAR(got.r, want.r, 1e-5 * std::abs(want.r) + 1e-6);
                            EXPECT_NEAR(got.g, want.g, 1e-5 * std::abs(want.g) + 1e-6);
                            EXPECT_NEAR(got.b, want.b, 1e-5 * std::abs(want.b) + 1e-6);
                        }
        }
}

TEST(DfmfImport, AnFmfBodyAndItsPackageAreOneMaterial) {
    // The writer writes DFMF only: FMF factorizations are made in memory (the reader's FMF path is
    // tested on files built byte by byte in io/ubo2014_test.cpp).
    const std::vector<Query> queries = wide_queries(600, 23);
    for (uint32_t drr : {0u, 1u}) {
        SCOPED_TRACE(drr);
        auto f =
            std::make_shared<ubo2014::Factorization>(random_ubo2014(ubo2014::Body::kFmf, 0, drr));
        const std::unique_ptr<Material> file = ubo2014_material(f, "x.btf");
        Package converted = package_of(*f, "x.btf");
        const std::unique_ptr<Material> package =
            open_material(decode_package(encode_package(converted), "x.btfpkg"));
        const double worst = compare_materials(*file, *package, queries);
        RecordProperty(fmt::format("fmf_drr{}_max_relative_difference", drr),
                       fmt::format("{:.3g}", worst));
        EXPECT_LT(worst, 1e-5);
    }
}

TEST(DfmfImport, TheColourPlanesAreInterpolated) {
    // Half way between two texel centres (same row, at sample directions) the value is the
    // decoded mean of the two texels' planes (log Y, U/Y, V/Y), not the mean of their RGB values,
    // as the package interpolates them (the RGB mean differs by a few per cent here).
    const auto f = std::make_shared<ubo2014::Factorization>(
        random_ubo2014(ubo2014::Body::kDfmf, ubo2014::kColorModelLogYUV, 0));
    const std::unique_ptr<Material> material = ubo2014_material(f, "x.btf");
    const int view = 2, light = 3, y = 4;
    const int64_t row = int64_t(view) * f->sampling.num_lights() + light;
    std::array<float, 3> planes{};
    for (int c = 0; c < 3; ++c)
        for (int x : {1, 2})
            planes[size_t(c)] +=
                0.5f * f->factors[size_t(c)].u.row(row).dot(
                           f->factors[size_t(c)].sxv.row(int64_t(y) * f->width + x));
    const Rgb want = ubo_model11_to_rgb(planes);
    const Rgb got =
        material->eval({2.0 / f->width, (y + 0.5) / f->height}, f->sampling.lights.vector(light),
                       f->sampling.views.vector(view));
    EXPECT_NEAR(got.r, want.r, 1e-5 * std::abs(want.r) + 1e-6);
    EXPECT_NEAR(got.g, want.g, 1e-5 * std::abs(want.g) + 1e-6);
    EXPECT_NEAR(got.b, want.b, 1e-5 * std::abs(want.b) + 1e-6);
    const Rgb rgb_mean = (f->sample(1, y, view, light) + f->sample(2, y, view, light)) * 0.5f;
    EXPECT_GT(
        std::abs(got.r - rgb_mean.r) + std::abs(got.g - rgb_mean.g) + std::abs(got.b - rgb_mean.b),
        1e-3f);
}

TEST(DfmfImport, ACosineWeightedFileIsEvaluatedOnItsDecodedSamples) {
    // The factor model cannot hold cos θ_light: such a file keeps the material that interpolates
    // its decoded (cosine-divided) RGB samples, and has no package.
    ubo2014::Factorization f = random_ubo2014(ubo2014::Body::kDfmf, ubo2014::kColorModelLogYUV, 0);
    f.meta.version = 2;
    f.meta.cosine_flag = true;
    const test::TempFolder dir;
    const auto btf = dir.path() / "cos.btf";
    ubo2014::write_dfmf(btf, f);
    const std::unique_ptr<Material> material = open_material(btf);
    const std::unique_ptr<Material> reference = ubo2014::make_material(ubo2014::read(btf));
    EXPECT_EQ(dynamic_cast<const factor::FactorMaterial*>(material.get()), nullptr);
    for (const Query& q : wide_queries(50, 3)) {
        const Rgb a = material->eval(q.uv, q.wi, q.wo), b = reference->eval(q.uv, q.wi, q.wo);
        EXPECT_EQ(a.r, b.r);
        EXPECT_EQ(a.g, b.g);
        EXPECT_EQ(a.b, b.b);
    }
    EXPECT_THAT(test::error_of([&] { package_of(*ubo2014::read(btf), btf.string()); }),
                HasSubstr("cos.btf: the values are multiplied by cos θ_light"));
}

TEST(DfmfImport, OpeningABadFileNamesIt) {
    const test::TempFolder dir;
    const auto btf = dir.path() / "short.btf";
    test::write_file(btf, "!DFMF08FC\x01\x02");
    const std::string e = test::error_of([&] { open_material(btf); });
    EXPECT_THAT(e, HasSubstr("short.btf"));
    EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 0) << e;
}

}  // namespace
}  // namespace btf

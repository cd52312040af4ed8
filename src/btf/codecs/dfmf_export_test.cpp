#include "btf/codecs/dfmf_export.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "btf/codecs/fmf/fmf.h"
#include "btf/io/function_source.h"
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
                                                        std::max(1e-3, std::abs(double(w[ch]))));
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

}  // namespace
}  // namespace btf

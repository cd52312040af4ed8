// SPDX-License-Identifier: MIT
#include "btf/codecs/mlvq/mlvq.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "btf/codecs/fmf/fmf.h"
#include "btf/codecs/material_source.h"
#include "btf/codecs/mlvq/small_grid_test.h"
#include "btf/core/btf_lookup.h"
#include "btf/core/light_sampler.h"
#include "btf/io/function_source.h"
#include "btf/synth/synth.h"
#include "btf/testing/chi_square.h"
#include "btf/testing/function_material.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf::mlvq {
namespace {

const BtfSource& leather() {
    static const std::unique_ptr<FunctionSource> source =
        test::cached(*synth::make("leather", 16, test::ubo_subset(8, 12), 5));
    return *source;
}

// F_x of every texel of `source` in planes, as the encoder sees it.
std::vector<float> resampled_planes(const BtfSource& source, const MlvqGrid& grid,
                                    ColourModel colour) {
    const Resampler r(grid, source.sampling());
    const SourceTexels raw = read_rows(source, 0, source.height());
    std::vector<float> f = r.resample(raw);
    const int64_t n = grid.samples();
    for (int64_t t = 0; t < source.num_texels(); ++t) {
        float* v = f.data() + t * 3 * n;
        for (int64_t s = 0; s < n; ++s) {
            const auto p = to_planes(colour, {v[s], v[n + s], v[2 * n + s]});
            v[s] = p[0];
            v[n + s] = p[1];
            v[2 * n + s] = p[2];
        }
    }
    return f;
}

double texel_mse(const Codebooks& books, const IndexScale& p6, const float* f) {
    const MlvqGrid& g = books.grid;
    const int64_t n = g.samples();
    double sum = 0;
    for (int m = 0; m < g.n_phi_v; ++m)
        for (int k = 0; k < g.n_theta_v; ++k)
            for (int i = 0; i < g.n_alpha; ++i)
                for (int j = 0; j < g.n_beta; ++j) {
                    const int64_t s = g.index(m, k, i, j);
                    const auto p = books.sample(p6, m, k, i, j);
                    for (int c = 0; c < 3; ++c) {
                        const double d = double(p[size_t(c)]) - f[c * n + s];
                        sum += d * d;
                    }
                }
    return sum / double(3 * n);
}

// The reconstruction of a texel inserted in training step 1 is within its threshold: the chain
// of code-books bounds the error level by level (the chroma thresholds are below ε_P4 here).
TEST(Mlvq, TrainedTexelsReconstructWithinTheThreshold) {
    const BtfSource& source = leather();
    Params params = small_grid(
        {{"threshold", "1e-6"}, {"chroma-threshold", "1e-6"}, {"first", "0.2"}, {"second", "0.1"}});
    const Options options = parse_options(params);
    const auto [books, index] = encode(source, options);
    const std::vector<float> f = resampled_planes(source, options.encoder.grid, books.colour);
    const int64_t length = 3 * options.encoder.grid.samples();
    // Steps 1 and 2 insert the first 20 % and 10 % more of the Halton texels, at the threshold
    // and at 2.5 times it; the frozen rest takes the nearest code-vectors, without a bound.
    int step1 = 0, step2 = 0;
    double worst = 0;
    for (int64_t t = 0; t < source.num_texels(); ++t) {
        const double e = texel_mse(books, index.p6[size_t(t)], f.data() + t * length);
        step1 += e <= 1e-6 * (1 + 1e-4);
        step2 += e <= 2.5e-6 * (1 + 1e-4);
        worst = std::max(worst, e);
    }
    EXPECT_GE(step1, 51);
    EXPECT_GE(step2, 51 + 26);
    EXPECT_LT(worst, 1e-4);  // about 10 % of the luminance on this material
    EXPECT_GT(books.size_p4(), 1u);
    EXPECT_LT(books.size_p4(), size_t(source.num_texels()));
}

// The MSSIM measure (§4.4.2): a tighter percentile threshold keeps more code-vectors and decodes
// closer to the resampled input.
TEST(Mlvq, MssimMeasureTradesSizeForSimilarity) {
    const BtfSource& source = leather();
    const MlvqGrid grid = parse_options(small_grid()).encoder.grid;
    const std::vector<float> f = resampled_planes(source, grid, ColourModel::kYCbCr);
    const int64_t length = 3 * grid.samples();
    size_t previous_p1 = 0;
    double previous_error = INFINITY;
    for (const char* threshold : {"0.2", "0.05", "0.01"}) {
        const Options options =
            parse_options(small_grid({{"measure", "mssim"}, {"threshold", threshold}}));
        const auto [books, index] = encode(source, options);
        double error = 0;
        for (int64_t t = 0; t < source.num_texels(); ++t)
            error += texel_mse(books, index.p6[size_t(t)], f.data() + t * length);
        EXPECT_GE(books.size_p1(), previous_p1) << threshold;
        EXPECT_LT(error, previous_error) << threshold;
        previous_p1 = books.size_p1();
        previous_error = error;
    }
}

// Identical texels get the same P4 entry and scale.
TEST(Mlvq, IdenticalTexelsShareCodeVectors) {
    const BtfSource& base = leather();
    const FunctionSource tiled(base.sampling(), 16, 16, [&base](int v, int l, int x, int y) {
        return static_cast<const FunctionSource&>(base).value(v, l, x % 4, y % 4);
    });
    const auto [books, index] = encode(tiled, parse_options(small_grid()));
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            EXPECT_EQ(index.p6[size_t(y) * 16 + x], index.p6[size_t(y % 4) * 16 + x % 4])
                << x << " " << y;
    EXPECT_LE(books.size_p4(), 16u);
}

double rmse(const BtfSource& source, const Material& m) {
    return sample_rmse(source, m);
}

TEST(Mlvq, PackageRoundTripDecodesTheMaterial) {
    const BtfSource& source = leather();
    Package package = mlvq_codec().encode(source, small_grid());
    const auto material = open_material(decode_package(encode_package(package), "m"));
    const auto& m = dynamic_cast<const MlvqMaterial&>(*material);
    EXPECT_EQ(m.width(), 16);
    EXPECT_EQ(m.sampling().num_views(), 8);
    // The decoded material is as close to the source as the resampling onto the grid allows:
    // its RMSE exceeds that of the unquantized grid function by little.
    const Options options = parse_options(small_grid());
    const MlvqGrid& grid = options.encoder.grid;
    const std::vector<float> f = resampled_planes(source, grid, ColourModel::kYCbCr);
    const int64_t n = grid.samples();
    const test::FunctionMaterial grid_function(
        16, 16, source.sampling(), [&](const Uv& uv, const Vec3& wi, const Vec3& wo) {
            const MlvqWeights w = lookup(grid, wi, wo);
            const float* t = f.data() + (int64_t(uv.v * 16) * 16 + int64_t(uv.u * 16)) * 3 * n;
            return from_planes(ColourModel::kYCbCr, reconstruct(grid, w, t),
                               reconstruct(grid, w, t + n), reconstruct(grid, w, t + 2 * n));
        });
    const double resampling = rmse(source, grid_function);
    const double e = rmse(source, m);
    EXPECT_LT(e, 1.2 * resampling) << resampling;
    EXPECT_GT(e, 0.0);
    // The stored code-books equal the encoder's up to scalar quantization.
    const auto [books, index] = encode(source, options);
    EXPECT_EQ(m.codebooks().size_p4(), books.size_p4());
    EXPECT_EQ(m.codebooks().size_p1(), books.size_p1());
    ASSERT_EQ(m.texel_index().p6.size(), index.p6.size());
    for (size_t t = 0; t < index.p6.size(); ++t) {
        EXPECT_EQ(m.texel_index().p6[t].index, index.p6[t].index);
        EXPECT_NEAR(m.texel_index().p6[t].scale, index.p6[t].scale, 0.02 * index.p6[t].scale);
    }
    // eval at a sample's directions and a texel centre equals eval_sample.
    const Vec3 wi = source.sampling().lights.vector(3), wo = source.sampling().views.vector(2);
    const Rgb at = m.eval({(5 + 0.5) / 16, (7 + 0.5) / 16}, wi, wo);
    const Rgb exact = m.eval_sample(5, 7, 2, 3);
    EXPECT_NEAR(at.r, exact.r, 1e-6);
    EXPECT_NEAR(at.g, exact.g, 1e-6);
    EXPECT_NEAR(at.b, exact.b, 1e-6);
    // eval_batch (sharing the lookup between queries of equal directions) equals eval().
    std::vector<Query> queries;
    for (int k = 0; k < 40; ++k)
        queries.push_back({{0.037 * k, 0.071 * k},
                           Direction::from_degrees(5 + k / 8 * 15, 40.0 * (k / 8)).vector(),
                           Direction::from_degrees(60 - k / 10 * 12, 100.0 + k / 10).vector()});
    std::vector<Rgb> batch(queries.size());
    m.eval_batch(queries, batch);
    for (size_t k = 0; k < queries.size(); ++k)
        EXPECT_EQ(batch[k], m.eval(queries[k].uv, queries[k].wi, queries[k].wo)) << k;
}

// LogLuv (the HDR colour model): chromaticity u′v′ does not scale with intensity; the decoded
// material is as close as with YCbCr, and an HDR package stores 16-bit P2 scales.
TEST(Mlvq, LogLuvColourDecodesAsWellAsYCbCr) {
    const BtfSource& source = leather();
    const double ycbcr = rmse(
        source, *mlvq_codec().open(mlvq_codec().encode(source, small_grid({{"colour", "ycbcr"}}))));
    const Package package = mlvq_codec().encode(source, small_grid({{"colour", "logluv"}}));
    EXPECT_EQ(package.header.at("colour"), "logluv");
    EXPECT_EQ(package.header.at("quantization").at("P2").at("bits"), 8);  // an LDR source
    const double logluv = rmse(source, *mlvq_codec().open(package));
    EXPECT_LT(logluv, 1.1 * ycbcr);
    for (const float v : {0.0f, 0.02f, 0.5f, 3.0f}) {
        const Rgb c{v, 0.8f * v, 0.3f * v};
        const auto p = to_planes(ColourModel::kLogLuv, c);
        const Rgb back = from_planes(ColourModel::kLogLuv, p[0], p[1], p[2]);
        EXPECT_NEAR(back.r, c.r, 1e-5 + 1e-5 * v);
        EXPECT_NEAR(back.b, c.b, 1e-5 + 1e-5 * v);
    }
    // A tiny set of code-books written for an HDR source.
    Codebooks books;
    nlohmann::json header;
    std::vector<PackageSection> sections;
    books.grid = {3, 3, 2, 3};
    books.p1 = {0.2f, 0.5f, 0.3f};
    books.p2 = {{0, 0.2f}, {0, 0.5f}, {0, 0.3f}};
    books.c = {{0.1f, 0.2f}};
    books.i1 = {0, 0, 0};
    books.i2 = {0, 0, 0};
    books.m = {{0, 0}};
    books.p3 = {{0, 0.5f}, {0, 0.5f}};
    books.p4 = {{0, 0.3f}, {0, 0.3f}, {0, 0.4f}};
    write_codebooks(books, true, header, sections);
    EXPECT_EQ(header.at("quantization").at("P2").at("bits"), 16);
}

TEST(Mlvq, PrefixesOfThePackageOpen) {
    const BtfSource& source = leather();
    const Package full = mlvq_codec().encode(source, small_grid());
    ASSERT_EQ(full.sections.front().name, "codebooks");
    double previous = INFINITY;
    for (size_t n = 2; n <= full.sections.size(); ++n) {
        Package prefix = full;
        prefix.sections.resize(n);
        const double e = rmse(source, *mlvq_codec().open(prefix));
        EXPECT_LE(e, previous * 1.05) << n;
        previous = e;
    }
    Package only_books = full;
    only_books.sections.resize(1);
    EXPECT_EQ(test::error_of([&] { mlvq_codec().open(only_books); }),
              "package (mlvq): section 'P6.2' is missing");
}

TEST(Mlvq, RejectsMalformedPackages) {
    const Package full = mlvq_codec().encode(leather(), small_grid());
    Package p = full;
    p.sections[0].data.pop_back();
    EXPECT_EQ(test::error_of([&] { mlvq_codec().open(p); }),
              "package (mlvq): section 'codebooks' is too short for the 77 entries of I2 its "
              "header declares");
    p = full;
    p.header["codebooks"]["P4"] = 0;
    EXPECT_NE(test::error_of([&] { mlvq_codec().open(p); }).find("package (mlvq): "),
              std::string::npos);
    p = full;
    p.header["grid"]["n_alpha"] = 1;
    EXPECT_NE(test::error_of([&] { mlvq_codec().open(p); }).find("package (mlvq): "),
              std::string::npos);
    p = full;
    p.header.erase("materials");
    EXPECT_NE(test::error_of([&] { mlvq_codec().open(p); }).find("package (mlvq): bad header"),
              std::string::npos);
    EXPECT_EQ(test::error_of([&] {
                  mlvq_codec().encode(leather(), Params({{"treshold", "1"}}));
              }),
              "codec mlvq: unknown parameter 'treshold' (known: threshold, level-factor, "
              "chroma-threshold, measure, colour, n-alpha, n-beta, n-theta-v, n-phi-v, first, "
              "second, growth)");
}

// Several materials in one package share the code-books (§5.1, C.R.5): each decodes about as
// well as from its own package, and the shared package is smaller than the separate ones.
TEST(Mlvq, SharedCodeBooksDecodeEachMaterial) {
    const auto other = test::cached(*synth::make("leather", 16, test::ubo_subset(8, 12), 6));
    const auto fabric = test::cached(*synth::make("woven_fabric", 8, test::ubo_subset(6, 9), 2));
    const std::vector<const BtfSource*> sources = {&leather(), other.get(), fabric.get()};
    const Options options = parse_options(small_grid());
    auto [books, indices] = encode_shared(sources, options);
    ASSERT_EQ(indices.size(), 3u);
    Package shared = to_package(books, indices, options);
    const auto materials = open_all(decode_package(encode_package(shared), "shared"));
    ASSERT_EQ(materials.size(), 3u);
    size_t separate = 0;
    for (size_t k = 0; k < sources.size(); ++k) {
        EXPECT_EQ(materials[k]->width(), sources[k]->width());
        EXPECT_EQ(materials[k]->sampling().num_lights(), sources[k]->num_lights());
        Package own = mlvq_codec().encode(*sources[k], small_grid());
        separate += encode_package(own).size();
        const double alone = rmse(*sources[k], *mlvq_codec().open(own));
        EXPECT_LT(rmse(*sources[k], *materials[k]), 1.15 * alone) << k;
    }
    EXPECT_LT(encode_package(shared).size(), separate);
    EXPECT_EQ(shared.header.at("materials").size(), 3u);
    // A prefix holding the code-books and the coarsest P6 of the first material opens that one.
    Package prefix = shared;
    prefix.sections.resize(2);
    EXPECT_EQ(open_all(prefix).size(), 1u);
    EXPECT_EQ(mlvq_codec().open(prefix)->width(), leather().width());

    // Through the codec interface: encode_several() writes the same sections (the header adds
    // the names), open_all() opens every material, and open() the first.
    const std::vector<std::string> names = {"a", "b", "c"};
    const Package again = mlvq_codec().encode_several(sources, names, small_grid());
    ASSERT_EQ(again.sections.size(), shared.sections.size());
    for (size_t k = 0; k < again.sections.size(); ++k)
        EXPECT_EQ(again.sections[k].data, shared.sections[k].data) << again.sections[k].name;
    EXPECT_EQ(again.header.at("materials")[1].at("name"), "b");
    EXPECT_EQ(mlvq_codec().open_all(again).size(), 3u);
    EXPECT_EQ(mlvq_codec().open(again)->width(), leather().width());  // the first
    EXPECT_EQ(test::error_of([&] { fmf_codec().encode_several(sources, names, small_grid()); }),
              "codec fmf compresses one input; several inputs share code-books only with mlvq");
}

// The evaluator's decoded code-books (decoded.h) hold the chain of equation 4: through the fused
// P4 ∘ P3 and an M entry's samples, every grid sample of every texel decodes to what
// Codebooks::sample() walks to, luminance within the half's 2⁻¹¹ and chromaticity exactly up to
// float rounding (a package stores C in 8-bit codes, which the decoded form keeps).
TEST(MlvqDecoded, EqualsTheCodeBookChain) {
    const Package package = mlvq_codec().encode(leather(), small_grid());
    const Codebooks books = read_codebooks(package);
    const DecodedBooks d(books);
    const MlvqGrid& g = books.grid;
    ASSERT_EQ(d.size_m(), books.size_m());
    const std::vector<IndexScale> p6 = open_all(package).front()->texel_index().p6;
    int64_t compared = 0;
    for (size_t t = 0; t < p6.size(); t += 7)
        for (int m = 0; m < g.n_phi_v; ++m)
            for (int k = 0; k < g.n_theta_v; ++k) {
                const IndexScale& v = d.view(p6[t].index, m, k);
                for (int i = 0; i < g.n_alpha; ++i)
                    for (int j = 0; j < g.n_beta; ++j) {
                        const std::array<float, 3> chain = books.sample(p6[t], m, k, i, j);
                        const DecodedBooks::Sample& s = d.sample(v.index, i, j);
                        const double y = double(p6[t].scale) * v.scale * DecodedBooks::luminance(s);
                        EXPECT_NEAR(y, chain[0], 5e-4 * std::abs(chain[0]) + 1e-12);
                        const std::array<float, 2> c = d.chroma(s);
                        EXPECT_NEAR(c[0], chain[1], 1e-6);
                        EXPECT_NEAR(c[1], chain[2], 1e-6);
                        ++compared;
                    }
            }
    EXPECT_GT(compared, 10000);
    // Row integrals: trapezoids of the decoded luminance.
    const float* rows = d.rows(0);
    double total = 0;
    for (int i = 0; i < g.n_alpha; ++i) {
        double sum = 0;
        for (int j = 0; j < g.n_beta; ++j)
            sum += DecodedBooks::luminance(d.sample(0, i, j)) *
                   ((j == 0 || j == g.n_beta - 1) ? 0.5 : 1.0);
        EXPECT_NEAR(rows[i], sum, 1e-6 * sum + 1e-12);
        total += sum * ((i == 0 || i == g.n_alpha - 1) ? 0.5 : 1.0);
    }
    EXPECT_NEAR(rows[g.n_alpha], total, 1e-6 * total + 1e-12);
}

// Decoded entries lie in 4 × 4 tiles that overlap by a sample: every copy of a sample holds the
// same bits, the 2 × 2 corners of every (α, β) window lie in one tile (two 8-byte reads, α rows
// kTile apart) within one cache line, and the sampling record holds the same luminance row by
// row, line-aligned. Grids of 7 × 7 (tiles overlapping at the end) and 11 × 12
// (the paper's α; an axis that the tiles do not end on).
TEST(MlvqDecoded, TilesHoldEveryWindowInOneLine) {
    for (const auto& [n_alpha, n_beta] : {std::pair{7, 7}, std::pair{11, 12}}) {
        Params params = small_grid();
        params.set("n-alpha", std::to_string(n_alpha));
        params.set("n-beta", std::to_string(n_beta));
        const Codebooks books = read_codebooks(mlvq_codec().encode(leather(), params));
        const DecodedBooks d(books);
        const MlvqGrid& g = books.grid;
        for (uint32_t m = 0; m < d.size_m(); m += 5) {
            const DecodedBooks::Sample* e = d.entry(m);
            ASSERT_EQ(reinterpret_cast<uintptr_t>(e) % 64, 0u);
            auto same = [](const DecodedBooks::Sample& a, const DecodedBooks::Sample& b) {
                return a.y == b.y && a.chroma[0] == b.chroma[0] && a.chroma[1] == b.chroma[1];
            };
            for (int i = 0; i + 1 < g.n_alpha; ++i)
                for (int j = 0; j + 1 < g.n_beta; ++j) {
                    const int off = DecodedBooks::offset(g, i, j);
                    EXPECT_EQ(off / 16, (off + DecodedBooks::kTile + 1) / 16) << i << " " << j;
                    EXPECT_TRUE(same(e[off + 1], d.sample(m, i, j + 1)));
                    EXPECT_TRUE(same(e[off + DecodedBooks::kTile], d.sample(m, i + 1, j)));
                    EXPECT_TRUE(same(e[off + DecodedBooks::kTile + 1], d.sample(m, i + 1, j + 1)));
                }
            ASSERT_EQ(reinterpret_cast<uintptr_t>(d.record(m)) % 64, 0u);
            ASSERT_EQ(d.rows(m), d.record(m));
            const char* halves = static_cast<const char*>(d.luminance_row(m, 0));
            ASSERT_EQ(halves, reinterpret_cast<const char*>(d.record(m) + g.n_alpha + 1));
            for (int i = 0; i < g.n_alpha; ++i) {
                ASSERT_EQ(d.luminance_row(m, i), halves + 2 * i * g.n_beta);
                for (int j = 0; j < g.n_beta; ++j)
                    EXPECT_EQ(DecodedBooks::luminance_at(d.luminance_row(m, i), j),
                              DecodedBooks::luminance(d.sample(m, i, j)))
                        << i << " " << j;
            }
            // The record holds the halves, padded to whole lines.
            EXPECT_EQ(d.record_floats() % 16, 0u);
            EXPECT_GE(d.record_floats() * 4, size_t(g.n_alpha + 1) * 4 + 2 * g.n_alpha * g.n_beta);
            // and the window of a load from the last row's start.
            EXPECT_GE(d.record_floats() * 4, size_t(g.n_alpha + 1) * 4 +
                                                 2 * (g.n_alpha - 1) * g.n_beta +
                                                 DecodedBooks::kRowWindow);
        }
        // Each decoded value equals the code-book chain (checked above for the default grid).
        for (int i = 0; i < g.n_alpha; ++i)
            for (int j = 0; j < g.n_beta; ++j) {
                const std::array<float, 3> chain = books.sample({0, 1.0f}, 0, 0, i, j);
                const IndexScale& v = d.view(0, 0, 0);
                const double y = double(v.scale) * DecodedBooks::luminance(d.sample(v.index, i, j));
                EXPECT_NEAR(y, chain[0], 5e-4 * std::abs(chain[0]) + 1e-12);
            }
    }
}

// Importance sampling (§5.2): the directions follow the reported pdf (χ² test over equal-area
// bins), the pdf integrates to 1 and is what sample() reports, for several (uv, ωo) including
// a view between grid samples and a position between texels.
TEST(MlvqSampling, FollowsItsPdfWhichIntegratesToOne) {
    const auto glossy = test::cached(*synth::make("lacquered_wood", 8, test::ubo_subset(8, 12), 3));
    const auto material = mlvq_codec().open(mlvq_codec().encode(*glossy, small_grid()));
    ASSERT_TRUE(material->native_sampling());
    const struct {
        Uv uv;
        Vec3 wo;
    } cases[] = {{{0.31, 0.62}, Direction::from_degrees(0, 0).vector()},
                 {{0.5625, 0.0625}, Direction::from_degrees(37, 65).vector()},
                 {{0.9, 0.4}, Direction::from_degrees(71, 200).vector()}};
    for (const auto& c : cases) {
        test::ChiSquareOptions options;
        options.samples = 100000;
        const test::ChiSquareResult r = test::chi_square_hemisphere(
            [&](double a, double b) { return material->sample(c.uv, c.wo, a, b).wi; },
            [&](const Vec3& wi) { return material->pdf(c.uv, c.wo, wi); }, options);
        EXPECT_TRUE(r.passed(1e-3)) << r.describe();
        EXPECT_NEAR(r.pdf_integral, 1.0, 0.01);
        // The last two draw at the poles of the onion frame (u = ±1, ξ2 = 0 and below 1).
        for (const auto& [xi1, xi2] :
             {std::pair{0.05, 0.95}, std::pair{0.37, 0.63}, std::pair{0.81, 0.19},
              std::pair{0.3, 0.0}, std::pair{0.6, std::nextafter(1.0, 0.0)}}) {
            const LightSample ls = material->sample(c.uv, c.wo, xi1, xi2);
            EXPECT_GT(ls.pdf, 0);
            EXPECT_NEAR(ls.pdf, material->pdf(c.uv, c.wo, ls.wi), 1e-5 * ls.pdf);
            const Rgb v = material->eval(c.uv, ls.wi, c.wo);
            EXPECT_NEAR(ls.value.g, v.g, 1e-5 * v.g + 1e-7);
            EXPECT_NEAR(ls.value.r, v.r, 1e-5 * std::abs(v.r) + 1e-7);
            EXPECT_NEAR(ls.weight.g, v.g / ls.pdf, 1e-5 * std::abs(v.g / ls.pdf) + 1e-9);
        }
    }
}

// sample_batch() runs the stages of sample() over groups: the same samples, bit for bit, for
// random queries (more than a group, and a tail) and for a texel of zero luminance.
TEST(MlvqSampling, BatchEqualsOneByOne) {
    const auto material = mlvq_codec().open(mlvq_codec().encode(leather(), small_grid()));
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<SampleQuery> queries(37);
    for (SampleQuery& q : queries) {
        q.uv = {uni(rng), uni(rng)};
        q.wo = Direction{std::acos(uni(rng)), 2 * kPi * uni(rng)}.vector();
        q.xi1 = uni(rng);
        q.xi2 = uni(rng);
    }
    queries[3].xi1 = 1.5;  // clamped
    queries[5].wo = {0, 0, 1};
    std::vector<LightSample> batch(queries.size());
    material->sample_batch(queries, batch);
    for (size_t i = 0; i < queries.size(); ++i) {
        const SampleQuery& q = queries[i];
        const LightSample one = material->sample(q.uv, q.wo, q.xi1, q.xi2);
        EXPECT_EQ(batch[i].wi, one.wi) << i;
        EXPECT_EQ(batch[i].pdf, one.pdf) << i;
        EXPECT_EQ(batch[i].value.g, one.value.g) << i;
        EXPECT_EQ(batch[i].weight.r, one.weight.r) << i;
    }
    std::vector<LightSample> wrong(2);
    EXPECT_EQ(test::error_of([&] { material->sample_batch(queries, wrong); }),
              "sample_batch: 37 queries but 2 outputs");
}

// The pdf is the model's luminance over its integral: pdf(ωi) / Y(ωi) is the same for every ωi.
TEST(MlvqSampling, PdfIsProportionalToTheLuminance) {
    const auto material = mlvq_codec().open(mlvq_codec().encode(leather(), small_grid()));
    const auto& m = dynamic_cast<const MlvqMaterial&>(*material);
    const Uv uv{0.3, 0.7};
    const Vec3 wo = Direction::from_degrees(28, 140).vector();
    double ratio = 0;
    for (const auto& [t, p] : {std::pair{10.0, 30.0}, {40.0, 200.0}, {65.0, 300.0}}) {
        const Vec3 wi = Direction::from_degrees(t, p).vector();
        const MlvqWeights w = lookup(m.codebooks().grid, wi, wo);
        double y = 0;
        const WrapLerp lx = wrap_lerp(uv.u, 16), ly = wrap_lerp(uv.v, 16);
        const int64_t texel[4] = {ly.i0 * 16 + lx.i0, ly.i0 * 16 + lx.i1, ly.i1 * 16 + lx.i0,
                                  ly.i1 * 16 + lx.i1};
        const double s[4] = {(1 - lx.t) * (1 - ly.t), lx.t * (1 - ly.t), (1 - lx.t) * ly.t,
                             lx.t * ly.t};
        for (int k = 0; k < 4; ++k) y += s[k] * m.planes(texel[k], w)[0];
        const double r = m.pdf(uv, wo, wi) / y;
        if (ratio == 0) ratio = r;
        EXPECT_NEAR(r, ratio, 1e-4 * ratio);
    }
}

// Albedo from the code-books' integrals equals a fine quadrature of eval().
TEST(MlvqSampling, AlbedoMatchesAQuadratureOfTheValues) {
    const auto material = mlvq_codec().open(mlvq_codec().encode(leather(), small_grid()));
    for (const auto& [uv, wo] : {std::pair{Uv{0.3, 0.7}, Direction::from_degrees(28, 140)},
                                 {Uv{0.71, 0.2}, Direction::from_degrees(55, 10)}}) {
        const Rgb a = material->albedo(uv, wo.vector());
        const Rgb q = quadrature_albedo(*material, uv, wo.vector(), 128);
        EXPECT_NEAR(a.r, q.r, 0.01 * q.r);
        EXPECT_NEAR(a.g, q.g, 0.01 * q.g);
        EXPECT_NEAR(a.b, q.b, 0.01 * q.b);
    }
}

TEST(Mlvq, IsInTheRegistry) {
    EXPECT_EQ(&find_codec("mlvq"), &mlvq_codec());
}

}  // namespace
}  // namespace btf::mlvq

// SPDX-License-Identifier: MIT
// A BSVTF file as a material: its tiles decoded as the encoder decoded them, and its value the
// evaluator's with every finest tile resident — the value a BSVTF renderer converges to.

#include "btf/bsvtf/material.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>

#include "btf/bsvtf/evaluator.h"
#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/codec.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"

namespace btf::bsvtf {
namespace {

struct Made {
    factor::Model model;
    Pyramid pyramid;
    EncodedPyramid encoded;
    Package bsvtf;  // as read back from its bytes
};

Made bsvtf_of_synthetic(const Params& params, double relative_error) {
    const auto source = synth::make("lacquered_wood", 32, test::ubo_subset(5, 6), 4);
    const Package fmf = find_codec("fmf").encode(*source, params, Progress::none());
    Made m{factor::from_package(fmf), {}, {}, {}};
    m.pyramid = Pyramid::build(m.model, {8, 4});
    m.encoded = encode_pyramid(m.pyramid, step_for(m.pyramid, relative_error));
    Package written = make_bsvtf(fmf, m.model, m.pyramid, m.encoded, relative_error);
    m.bsvtf = decode_package(encode_package(written), "x.bsvtf");
    return m;
}

Vec3 direction(std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0, 1);
    const double z = 0.05 + 0.95 * u(rng), phi = 2 * M_PI * u(rng), r = std::sqrt(1 - z * z);
    return {r * std::cos(phi), r * std::sin(phi), z};
}

TEST(BsvtfMaterial, DecodesEveryTileAsTheEncoderDid) {
    const Made m = bsvtf_of_synthetic(Params{{"components", "7"}, {"quantize", "f16"}}, 0.02);
    const Bsvtf file = read_bsvtf(m.bsvtf, "x.bsvtf");
    EXPECT_GT(m.encoded.step, 0);
    EXPECT_EQ(decode_tiles(file, "x.bsvtf"), m.encoded.decoded);
}

// Every codec command opens a .bsvtf through open_material(); its value is the evaluator's
// (tile lookups with padding, the BSVTF renderer's path) with the finest tiles.
TEST(BsvtfMaterial, IsTheEvaluatorWithEveryFinestTile) {
    for (const Params& params :
         {Params{{"components", "7"}, {"quantize", "f16"}, {"colour", "rgb"}},
          Params{{"components", "9"}, {"colour", "decorrelated"}, {"log", "true"}}}) {
        const Made m = bsvtf_of_synthetic(params, 0.02);
        const std::unique_ptr<Material> material = open_material(m.bsvtf);
        ASSERT_EQ(material->width(), 32);
        const Evaluator evaluator(m.model, m.pyramid);
        const size_t values = size_t(m.pyramid.geometry().values());
        std::mt19937 rng(5);
        std::uniform_real_distribution<double> uv(-2, 3);
        Evaluator::Angular angular;
        double worst = 0, mean_abs = 0;
        for (int q = 0; q < 2000; ++q) {
            const Uv at{uv(rng), uv(rng)};
            const Vec3 wi = direction(rng), wo = direction(rng);
            evaluator.angular(wi, wo, angular);
            const WrapLerp lx = wrap_lerp(at.u, 32), ly = wrap_lerp(at.v, 32);
            const Rgb want = evaluator.value(angular, [&](int g) {
                const TileId id{g, 0, lx.i0 / 8, ly.i0 / 8};
                const std::span<const uint16_t> tile(
                    m.encoded.decoded.data() + m.pyramid.index(id) * values, values);
                return std::optional(
                    sample_tile(tile, m.pyramid.geometry(), id, lx.i0, lx.t, ly.i0, ly.t));
            });
            const Rgb got = material->eval(at, wi, wo);
            const float g3[3] = {got.r, got.g, got.b}, w3[3] = {want.r, want.g, want.b};
            for (int c = 0; c < 3; ++c) {
                const double scale = std::max(1e-3, double(std::abs(w3[c])));
                worst = std::max(worst, std::abs(double(g3[c]) - double(w3[c])) / scale);
                mean_abs += std::abs(w3[c]);
            }
        }
        EXPECT_GT(mean_abs / 6000, 1e-3);  // the materials are not black
        EXPECT_LT(worst, 2e-5) << params.values().at("colour");
    }
}

TEST(BsvtfMaterial, ADamagedTileIsNamed) {
    Made m = bsvtf_of_synthetic(Params{{"components", "4"}}, 0.02);
    for (PackageSection& section : m.bsvtf.sections)
        if (section.name == "tiles") section.data[12] ^= 0xFF;  // the first tile's deflate stream
    try {
        open_material(m.bsvtf);
        FAIL() << "a damaged tile was decoded";
    } catch (const Error& e) {
        EXPECT_THAT(e.what(), testing::HasSubstr("bsvtf: tile "));
    }
}

}  // namespace
}  // namespace btf::bsvtf

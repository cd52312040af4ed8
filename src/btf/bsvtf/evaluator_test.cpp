// SPDX-License-Identifier: MIT
// A cache holding every finest tile reproduces the fmf material: the BSVTF evaluator, reading
// the eigen-textures from losslessly transmitted tiles through the tile cache, against
// FactorMaterial::eval for random positions and directions, for rgb and for decorrelated + log
// colour.

#include <gtest/gtest.h>

#include <random>

#include "btf/bsvtf/cache.h"
#include "btf/bsvtf/evaluator.h"
#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/codec.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"

namespace btf::bsvtf {
namespace {

Vec3 random_direction(std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0, 1);
    const double z = 0.05 + 0.95 * u(rng), phi = 2 * M_PI * u(rng), r = std::sqrt(1 - z * z);
    return {r * std::cos(phi), r * std::sin(phi), z};
}

void check(const Params& params) {
    const auto source = synth::make("lacquered_wood", 32, test::ubo_subset(5, 6), 4);
    const Package package = find_codec("fmf").encode(*source, params, Progress::none());
    const factor::Model model = factor::from_package(package);
    const factor::FactorMaterial fmf(model);
    const Pyramid pyramid = Pyramid::build(model, {8, 4});
    const EncodedPyramid sent = encode_pyramid(pyramid, 0);  // lossless
    // The cache, filled with every finest tile.
    const TileLayout& layout = pyramid;
    TileCache cache({&layout}, {&pyramid.weights()}, int(pyramid.tile_count()));
    Votes votes({&layout});
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x) votes.add(0, 0, (x + 0.5) / 32, (y + 0.5) / 32);
    while (const auto add = cache.best_add(votes)) cache.add(add->tile);
    for (const TileKey& t : cache.tiles()) ASSERT_EQ(t.id.level, 0);

    const Evaluator evaluator(model, pyramid);
    const size_t values = size_t(pyramid.geometry().values());
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> uv(-2, 3);
    Evaluator::Angular angular;
    double worst = 0;
    for (int q = 0; q < 3000; ++q) {
        const Uv at{uv(rng), uv(rng)};
        const Vec3 wi = random_direction(rng), wo = random_direction(rng);
        evaluator.angular(wi, wo, angular);
        const WrapLerp lx = wrap_lerp(at.u, 32), ly = wrap_lerp(at.v, 32);
        const Rgb got = evaluator.value(angular, [&](int g) -> std::optional<std::array<float, 4>> {
            const TileKey t = cache.lookup(0, g, 0, lx.i0, ly.i0);
            const std::span<const uint16_t> data(sent.decoded.data() + pyramid.index(t.id) * values,
                                                 values);
            return sample_tile(data, pyramid.geometry(), t.id, lx.i0, lx.t, ly.i0, ly.t);
        });
        const Rgb want = fmf.eval(at, wi, wo);
        const float g3[3] = {got.r, got.g, got.b}, w3[3] = {want.r, want.g, want.b};
        for (int c = 0; c < 3; ++c) {
            const double scale = std::max(1e-3, double(std::abs(w3[c])));
            worst = std::max(worst, std::abs(double(g3[c]) - double(w3[c])) / scale);
        }
    }
    EXPECT_LT(worst, 2e-5) << params.values().at("colour");
}

TEST(Evaluator, AllFinestTilesReproduceTheFmfMaterial) {
    check(Params{{"components", "7"}, {"quantize", "f16"}, {"colour", "rgb"}});
    check(Params{
        {"components", "9"}, {"quantize", "f16"}, {"colour", "decorrelated"}, {"log", "true"}});
}

}  // namespace
}  // namespace btf::bsvtf

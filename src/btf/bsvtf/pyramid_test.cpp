// SPDX-License-Identifier: MIT
// The BSVTF tile pyramid: level images, padding, tile numbering, the parent prediction, the
// weights of equation 8, and lookups from tiles against the factor model's own interpolation.

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>
#include <random>
#include <set>

#include "btf/bsvtf/pyramid.h"
#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/core/btf_lookup.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/half.h"

namespace btf::bsvtf {
namespace {

float half_round(float v) {
    return static_cast<float>(Eigen::half(v));
}

// A model with one plane, `k` components and b given by fn(x, y, k); a is not used by the tiles.
factor::Model model_of(int width, int height, int k,
                       const std::function<float(int, int, int)>& fn) {
    factor::Model m;
    m.width = width;
    m.height = height;
    m.groups = {{0}};
    factor::Block block;
    block.a = factor::Matrix::Zero(3, k);
    block.b = factor::Matrix(int64_t(width) * height, k);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < k; ++c)
                block.b(int64_t(y) * width + x, c) = half_round(fn(x, y, c));
    block.energy.assign(size_t(k), 1.0f);
    m.blocks.push_back(std::move(block));
    return m;
}

float pattern(int x, int y, int c) {
    return std::sin(0.7f * float(x) + 0.3f * float(c)) * std::cos(0.45f * float(y)) +
           0.1f * float(c);
}

TEST(Pyramid, LevelsTilesAndGroups) {
    const factor::Model m = model_of(40, 24, 6, pattern);
    const Pyramid p = Pyramid::build(m, {8, 4});
    // 40 × 24 → 20 × 12 → 10 × 6 → 5 × 3 (fits one tile of 8): 4 levels.
    EXPECT_EQ(p.levels(), 4);
    EXPECT_EQ(p.tiles_x(0), 5);
    EXPECT_EQ(p.tiles_y(0), 3);
    EXPECT_EQ(p.tiles_x(1), 3);
    EXPECT_EQ(p.tiles_y(1), 2);
    EXPECT_EQ(p.tiles_x(3), 1);
    ASSERT_EQ(p.groups().size(), 2u);
    EXPECT_EQ(p.groups()[0].count, 4);
    EXPECT_EQ(p.groups()[1].first, 4);
    EXPECT_EQ(p.groups()[1].count, 2);
    EXPECT_EQ(p.tile_count(), 2u * (15 + 6 + 2 + 1));
    std::set<TileId> seen;
    for (size_t t = 0; t < p.tile_count(); ++t) {
        const TileId id = p.id(t);
        EXPECT_EQ(p.index(id), t);
        EXPECT_TRUE(seen.insert(id).second);
        if (p.has_parent(id)) {
            const TileId parent = p.parent(id);
            EXPECT_LT(parent.x, p.tiles_x(parent.level));
            EXPECT_LT(parent.y, p.tiles_y(parent.level));
        } else {
            EXPECT_EQ(id.level, p.levels() - 1);
        }
    }
    // The missing channels of the second group are zero.
    const std::span<const uint16_t> t = p.tile({1, 0, 2, 1});
    for (size_t i = 0; i < t.size(); i += 4) {
        EXPECT_EQ(t[i + 2], 0);
        EXPECT_EQ(t[i + 3], 0);
    }
}

TEST(Pyramid, EveryTexelOfEveryTileIsItsLevelsTexelWrapped) {
    const int W = 32, H = 16, K = 5;
    const factor::Model m = model_of(W, H, K, pattern);
    const TileGeometry g{8, 4};
    const Pyramid p = Pyramid::build(m, g);
    // Level images by the definition.
    std::vector<std::vector<float>> level(static_cast<size_t>(K));
    for (int c = 0; c < K; ++c)
        for (int i = 0; i < W * H; ++i) level[size_t(c)].push_back(m.blocks[0].b(i, c));
    for (int j = 0; j < p.levels(); ++j) {
        const int w = W >> j, h = H >> j;
        if (j > 0) {
            for (int c = 0; c < K; ++c) {
                std::vector<float> next(static_cast<size_t>(w * h));
                const std::vector<float>& f = level[size_t(c)];
                for (int y = 0; y < h; ++y)
                    for (int x = 0; x < w; ++x)
                        next[size_t(y * w + x)] =
                            0.25f * (f[size_t(2 * y * 2 * w + 2 * x)] +
                                     f[size_t(2 * y * 2 * w + 2 * x + 1)] +
                                     f[size_t((2 * y + 1) * 2 * w + 2 * x)] +
                                     f[size_t((2 * y + 1) * 2 * w + 2 * x + 1)]);
                level[size_t(c)] = std::move(next);
            }
        }
        for (int ty = 0; ty < p.tiles_y(j); ++ty)
            for (int tx = 0; tx < p.tiles_x(j); ++tx)
                for (int gi = 0; gi < 2; ++gi) {
                    const std::span<const uint16_t> tile = p.tile({gi, j, tx, ty});
                    for (int ly = 0; ly < g.stride(); ++ly)
                        for (int lx = 0; lx < g.stride(); ++lx) {
                            const int x = ((tx * 8 + lx - 4) % w + w) % w;
                            const int y = ((ty * 8 + ly - 4) % h + h) % h;
                            for (int ch = 0; ch < 4; ++ch) {
                                const int c = gi * 4 + ch;
                                const float want =
                                    c < K ? half_round(level[size_t(c)][size_t(y * w + x)]) : 0.0f;
                                const uint16_t bits =
                                    tile[(size_t(ly) * size_t(g.stride()) + size_t(lx)) * 4 +
                                         size_t(ch)];
                                ASSERT_EQ(from_half(bits), want)
                                    << "level " << j << " tile " << tx << "," << ty << " texel "
                                    << lx << "," << ly;
                            }
                        }
                }
    }
}

TEST(Pyramid, LookupsFromTilesAreTheModelsBilinearInterpolation) {
    const int W = 24, H = 16;
    const factor::Model m = model_of(W, H, 4, pattern);
    const Pyramid p = Pyramid::build(m, {8, 4});
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> uv(-1.5, 2.5);
    for (int q = 0; q < 2000; ++q) {
        const Uv at{uv(rng), uv(rng)};
        const std::array<float, 4> got = p.sample(0, 0, at);
        const WrapLerp lx = wrap_lerp(at.u, W), ly = wrap_lerp(at.v, H);
        for (int c = 0; c < 4; ++c) {
            const auto b = [&](int x, int y) { return m.blocks[0].b(int64_t(y) * W + x, c); };
            const float want = b(lx.i0, ly.i0) * (1 - lx.t) * (1 - ly.t) +
                               b(lx.i1, ly.i0) * lx.t * (1 - ly.t) +
                               b(lx.i0, ly.i1) * (1 - lx.t) * ly.t + b(lx.i1, ly.i1) * lx.t * ly.t;
            ASSERT_NEAR(got[size_t(c)], want, 1e-6f) << at.u << ", " << at.v;
        }
    }
}

TEST(Pyramid, ThePredictionOfAChildIsItsParentsLevelSampledAtTheChildsTexels) {
    const int W = 32, H = 32;
    const factor::Model m = model_of(W, H, 4, pattern);
    const TileGeometry g{8, 4};
    const Pyramid p = Pyramid::build(m, g);
    for (size_t t = 0; t < p.tile_count(); ++t) {
        const TileId id = p.id(t);
        if (!p.has_parent(id)) continue;
        const std::vector<float> pred = predict_child(p.tile(p.parent(id)), g, id);
        const int w = p.level_width(id.level), h = p.level_height(id.level);
        for (int ly = 0; ly < g.stride(); ++ly)
            for (int lx = 0; lx < g.stride(); ++lx) {
                const int x = id.x * g.tile + lx - g.pad, y = id.y * g.tile + ly - g.pad;
                const std::array<float, 4> want =
                    p.sample(id.group, id.level + 1, {(x + 0.5) / w, (y + 0.5) / h});
                for (int c = 0; c < 4; ++c)
                    ASSERT_NEAR(
                        pred[(size_t(ly) * size_t(g.stride()) + size_t(lx)) * 4 + size_t(c)],
                        want[size_t(c)], 1e-5f)
                        << "tile level " << id.level << " (" << id.x << ", " << id.y << ") texel "
                        << lx << ", " << ly;
            }
    }
}

TEST(Pyramid, WeightsAreEquationEight) {
    // Constant eigen-textures: a tile equals its up-sampled parent (weight 0); the coarsest tile
    // weighs its mean squared value.
    const Pyramid flat = Pyramid::build(
        model_of(32, 32, 2, [](int, int, int c) { return c ? 0.5f : 2.0f; }), {8, 4});
    for (size_t t = 0; t < flat.tile_count(); ++t) {
        const TileId id = flat.id(t);
        EXPECT_FLOAT_EQ(flat.weight(id), flat.has_parent(id) ? 0.0f : 4.0f + 0.25f);
    }
    // One bright texel at (5, 2): level 0's tile (0, 0) differs from its parent (the 2 × 2 average
    // spread bilinearly); the weight is the mean of the squared differences over its 64 texels.
    const auto spike = [](int x, int y, int c) {
        return (x == 5 && y == 2 && c == 0) ? 8.0f : 0.0f;
    };
    const factor::Model m = model_of(32, 32, 1, spike);
    const Pyramid p = Pyramid::build(m, {8, 4});
    const TileId id{0, 0, 0, 0};
    double sum = 0;
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            const float parent = p.sample(0, 1, {(x + 0.5) / 32, (y + 0.5) / 32})[0];
            const double d = double(spike(x, y, 0)) - parent;
            sum += d * d;
        }
    EXPECT_NEAR(p.weight(id), sum / 64, 1e-5);
    EXPECT_GT(p.weight(id), 0.5);
    EXPECT_EQ(p.weight({0, 0, 3, 3}), 0.0f);  // far from the spike
}

TEST(Pyramid, RefusesWhatItCannotTile) {
    EXPECT_NE(test::error_of([] {
                  Pyramid::build(model_of(24, 24, 1, pattern), {8, 3});
              }).find("multiple of 8"),
              std::string::npos);
    // 36 × 36 with tiles of 8: 4 levels, 36 is not divisible by 8.
    EXPECT_NE(test::error_of([] {
                  Pyramid::build(model_of(36, 36, 1, pattern), {8, 4});
              }).find("divisible by 8"),
              std::string::npos);
    factor::Model two = model_of(16, 16, 1, pattern);
    two.groups = {{0}, {1}};
    EXPECT_NE(test::error_of([&] {
                  Pyramid::build(two, {8, 4});
              }).find("2 view groups"),
              std::string::npos);
}

TEST(Pyramid, CutsAnFmfPackage) {
    const auto source = synth::make("woven_fabric", 32, test::ubo_subset(4, 5), 1);
    const Package package = find_codec("fmf").encode(
        *source, Params{{"components", "6"}, {"quantize", "f16"}}, Progress::none());
    const factor::Model model = factor::from_package(package);
    const Pyramid p = Pyramid::build(model, {8, 4});
    EXPECT_EQ(p.levels(), 3);
    EXPECT_EQ(p.groups().size(), 2u);
    // The finest level reproduces the package's eigen-textures exactly (they are half floats).
    for (int c = 0; c < 6; ++c) {
        const std::array<float, 4> v = p.sample(c / 4, 0, {(7 + 0.5) / 32, (19 + 0.5) / 32});
        EXPECT_EQ(v[size_t(c % 4)], model.blocks[0].b(19 * 32 + 7, c));
    }
}

}  // namespace
}  // namespace btf::bsvtf

// SPDX-License-Identifier: MIT
// The BSVTF tile cache: votes (equation 9), priorities and swap costs (equations 8–10) on
// hand-made cases, add and swap, the decision rule, and the invariants under random operation.

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <set>

#include <Eigen/Core>

#include <nlohmann/json.hpp>
#include "btf/bsvtf/cache.h"
#include "btf/testing/support.h"

namespace btf::bsvtf {
namespace {

// 32 × 32 texels in tiles of 8: levels 32, 16, 8 → 16 + 4 + 1 tiles per group.
TileLayout layout(int groups = 1, int width = 32, int height = 32) {
    std::vector<Group> g;
    for (int i = 0; i < groups; ++i) g.push_back({0, 4 * i, 4});
    return TileLayout(width, height, {8, 4}, g);
}

std::string describe(const TileKey& t) {
    return fmt::format("m{} g{} l{} ({}, {})", t.material, t.id.group, t.id.level, t.id.x, t.id.y);
}

std::string describe(const TileCache& cache) {
    std::string out;
    for (const TileKey& t : cache.tiles()) out += " " + describe(t);
    return out;
}

TEST(Votes, APixelVotesForItsTileAndEveryAncestor) {
    const TileLayout l = layout();
    Votes votes({&l});
    votes.add(0, 0, (20 + 0.5) / 32, (3 + 0.5) / 32);  // level-0 texel (20, 3): tile (2, 0)
    EXPECT_EQ(votes(0, {0, 0, 2, 0}), 1u);
    EXPECT_EQ(votes(0, {0, 1, 1, 0}), 1u);
    EXPECT_EQ(votes(0, {0, 2, 0, 0}), 1u);
    EXPECT_EQ(votes(0, {0, 0, 3, 0}), 0u);
    // A pixel needing level 1 votes from level 1 up, not for level 0.
    votes.add(0, 1, (20 + 0.5) / 32, (3 + 0.5) / 32);
    EXPECT_EQ(votes(0, {0, 0, 2, 0}), 1u);
    EXPECT_EQ(votes(0, {0, 1, 1, 0}), 2u);
    EXPECT_EQ(votes(0, {0, 2, 0, 0}), 2u);
    // Every group of the material sees the same votes; levels beyond the pyramid are clamped;
    // coordinates wrap.
    EXPECT_EQ(votes(0, {3, 1, 1, 0}), 2u);
    votes.add(0, 9, -0.99, 1.01);
    EXPECT_EQ(votes(0, {0, 2, 0, 0}), 3u);
    votes.clear();
    EXPECT_EQ(votes(0, {0, 2, 0, 0}), 0u);
}

TEST(TileCache, StartsWithTheCoarsestTileOfEveryGroup) {
    const TileLayout a = layout(2), b = layout(1, 64, 32);
    const std::vector<float> wa(a.tile_count(), 1.0f), wb(b.tile_count(), 1.0f);
    const TileCache cache({&a, &b}, {&wa, &wb}, 10);
    // b: 64 × 32 → 32 × 16 → 16 × 8 (2 × 1 tiles) → 8 × 4: 4 levels, one coarsest tile.
    EXPECT_EQ(cache.size(), 3);
    EXPECT_TRUE(cache.resident({0, {0, 2, 0, 0}}));
    EXPECT_TRUE(cache.resident({0, {1, 2, 0, 0}}));
    EXPECT_TRUE(cache.resident({1, {0, 3, 0, 0}}));
    EXPECT_EQ(cache.problems(), "");
    EXPECT_EQ(cache.lookup(0, 1, 0, 31, 31).id, (TileId{1, 2, 0, 0}));
    EXPECT_NE(test::error_of([&] {
                  TileCache({&a, &b}, {&wa, &wb}, 2);
              }).find("cannot hold"),
              std::string::npos);
}

TEST(TileCache, PriorityAndSwapCostFollowEquationsEightToTen) {
    const TileLayout l = layout();
    std::vector<float> w(l.tile_count(), 0.0f);
    w[l.index({0, 0, 1, 1})] = 0.5f;  // level-0 tile (1, 1) against its parent
    w[l.index({0, 1, 0, 0})] = 2.0f;  // its parent against the root
    w[l.index({0, 0, 0, 0})] = 3.0f;
    Votes votes({&l});
    for (int i = 0; i < 7; ++i) votes.add(0, 0, (9 + 0.5) / 32, (10 + 0.5) / 32);  // tile (1, 1)
    for (int i = 0; i < 2; ++i) votes.add(0, 0, (1 + 0.5) / 32, (1 + 0.5) / 32);   // tile (0, 0)
    TileCache cache({&l}, {&w}, 8);
    // P = w · v.
    EXPECT_DOUBLE_EQ(cache.priority({0, {0, 0, 1, 1}}, votes), 0.5 * 7);
    EXPECT_DOUBLE_EQ(cache.priority({0, {0, 1, 0, 0}}, votes), 2.0 * 9);
    // c(a, t) = v(t) · Σ w over t and its ancestors below a.
    EXPECT_DOUBLE_EQ(cache.swap_cost({0, {0, 1, 0, 0}}, {0, {0, 0, 1, 1}}, votes), 7 * 0.5);
    EXPECT_DOUBLE_EQ(cache.swap_cost({0, {0, 2, 0, 0}}, {0, {0, 0, 1, 1}}, votes), 7 * (0.5 + 2.0));
    EXPECT_DOUBLE_EQ(cache.swap_cost({0, {0, 2, 0, 0}}, {0, {0, 0, 0, 0}}, votes), 2 * (3.0 + 2.0));
    // The best add is a child of a resident tile: only level 1 can be added now.
    auto add = cache.best_add(votes);
    ASSERT_TRUE(add);
    EXPECT_EQ(add->tile.id, (TileId{0, 1, 0, 0}));
    EXPECT_DOUBLE_EQ(add->value, 18);
    cache.add(add->tile);
    // Now (0, 0) of level 0 (P = 3 · 2 = 6) beats (1, 1) (P = 3.5); tiles without votes never.
    add = cache.best_add(votes);
    ASSERT_TRUE(add);
    EXPECT_EQ(add->tile.id, (TileId{0, 0, 0, 0}));
    cache.add(add->tile);
    cache.add(cache.best_add(votes)->tile);
    EXPECT_FALSE(cache.best_add(votes));
    // The cheapest swap: (0, 0) and (1, 1) for their parent costs 6 + 3.5.
    const auto swap = cache.cheapest_swap(votes);
    ASSERT_TRUE(swap);
    EXPECT_EQ(swap->tile.id, (TileId{0, 1, 0, 0}));
    EXPECT_DOUBLE_EQ(swap->value, 9.5);
    cache.swap(swap->tile, swap->out[0], swap->out[1]);
    EXPECT_FALSE(cache.resident({0, {0, 0, 1, 1}}));
    EXPECT_TRUE(cache.resident({0, {0, 1, 0, 0}}));
    EXPECT_EQ(cache.problems(), "");
}

TEST(TileCache, AddNeedsAResidentParentAndRemovesCoveredAncestors) {
    const TileLayout l = layout();
    const std::vector<float> w(l.tile_count(), 1.0f);
    TileCache cache({&l}, {&w}, 6);
    EXPECT_NE(test::error_of([&] {
                  cache.add({0, {0, 0, 0, 0}});
              }).find("parent is not resident"),
              std::string::npos);
    for (int i = 0; i < 4; ++i) cache.add({0, {0, 1, i % 2, i / 2}});
    // The root is covered by its four children: it left, and the cache holds 4.
    EXPECT_FALSE(cache.resident({0, {0, 2, 0, 0}}));
    EXPECT_EQ(cache.size(), 4);
    for (int i = 0; i < 2; ++i) cache.add({0, {0, 0, i, 0}});
    EXPECT_EQ(cache.size(), 6);
    EXPECT_NE(test::error_of([&] {
                  cache.add({0, {0, 0, 0, 1}});
              }).find("full"),
              std::string::npos);
    EXPECT_EQ(cache.problems(), "");
    // Lookups find the finest resident tile on the path.
    EXPECT_EQ(cache.lookup(0, 0, 0, 1, 1).id, (TileId{0, 0, 0, 0}));
    EXPECT_EQ(cache.lookup(0, 0, 0, 1, 9).id, (TileId{0, 1, 0, 0}));
    EXPECT_EQ(cache.lookup(0, 0, 1, 1, 1).id, (TileId{0, 1, 0, 0}));
}

TEST(TileCache, InvariantsHoldUnderTheDecisionRuleWithChangingVotes) {
    const TileLayout a = layout(2), b = layout(1, 64, 64);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    std::vector<float> wa(a.tile_count()), wb(b.tile_count());
    for (float& x : wa) x = uni(rng);
    for (float& x : wb) x = uni(rng);
    TileCache cache({&a, &b}, {&wa, &wb}, 24);
    Votes votes({&a, &b});
    int adds = 0, swaps = 0;
    for (int frame = 0; frame < 200; ++frame) {
        // A "view": a random window of each material at a random level.
        votes.clear();
        for (int m = 0; m < 2; ++m) {
            const double u0 = uni(rng), v0 = uni(rng), size = 0.1 + 0.5 * uni(rng);
            const int level = int(uni(rng) * 3);
            for (int k = 0; k < 200; ++k)
                votes.add(m, level, u0 + size * uni(rng), v0 + size * uni(rng));
        }
        for (int op = 0; op < 8; ++op) {
            const auto add = cache.best_add(votes);
            if (!add) break;
            if (cache.size() == cache.capacity()) {
                const auto swap = cache.cheapest_swap(votes);
                if (!swap || swap->value >= add->value) break;
                const std::string before = describe(cache);
                cache.swap(swap->tile, swap->out[0], swap->out[1]);
                ++swaps;
                ASSERT_EQ(cache.problems(), "")
                    << "frame " << frame << ": swap for " << describe(swap->tile) << " of "
                    << describe(swap->out[0]) << " and " << describe(swap->out[1])
                    << "; before:" << before;
                // The add may no longer be possible (its parent may have left): plan again.
                continue;
            }
            const std::string before = describe(cache);
            cache.add(add->tile);
            ++adds;
            ASSERT_EQ(cache.problems(), "")
                << "frame " << frame << ": add of " << describe(add->tile) << "; before:" << before;
            ASSERT_LE(cache.size(), cache.capacity());
        }
        // Every lookup lands on a resident tile.
        for (int k = 0; k < 20; ++k) {
            const int level = int(uni(rng) * 3);
            const TileKey t = cache.lookup(0, 1, level, int(uni(rng) * float(a.level_width(level))),
                                           int(uni(rng) * float(a.level_height(level))));
            ASSERT_TRUE(cache.resident(t));
        }
    }
    EXPECT_GT(adds, 50);
    EXPECT_GT(swaps, 20);
}

TEST(TileCache, AnAmpleCacheEndsWithTheFinestTilesWhereTheyAreNeeded) {
    const TileLayout l = layout(2);
    std::vector<float> w(l.tile_count(), 1.0f);
    TileCache cache({&l}, {&w}, 64);
    Votes votes({&l});
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x) votes.add(0, 0, (x + 0.5) / 32, (y + 0.5) / 32);
    while (const auto add = cache.best_add(votes)) cache.add(add->tile);
    // 16 finest tiles per group, nothing else.
    EXPECT_EQ(cache.size(), 32);
    for (const TileKey& t : cache.tiles()) EXPECT_EQ(t.id.level, 0);
    EXPECT_EQ(cache.problems(), "");
}

// A pyramid of 32 × 32 texels in tiles of 8 (levels 32, 16, 8) of a smooth pattern.
Pyramid pattern_pyramid() {
    factor::Model m;
    m.width = m.height = 32;
    m.groups = {{0}};
    factor::Block block;
    block.a = factor::Matrix::Zero(3, 4);
    block.b = factor::Matrix(32 * 32, 4);
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 32; ++x)
            for (int c = 0; c < 4; ++c)
                block.b(y * 32 + x, c) = static_cast<float>(
                    Eigen::half(std::sin(0.4f * float(x) + float(c)) * std::cos(0.3f * float(y)) +
                                0.2f * float(c)));
    block.energy.assign(4, 1.0f);
    m.blocks.push_back(std::move(block));
    return Pyramid::build(m, {8, 4});
}

// What sample_cached must give when a coarser level shows level `level`: the bilinear lookup of
// `level` whose texels are the coarser level's bilinear values at their centres.
std::array<float, 4> through_coarser(const Pyramid& p, int level, int coarse, const Uv& uv) {
    const WrapLerp lx = wrap_lerp(uv.u, p.level_width(level)),
                   ly = wrap_lerp(uv.v, p.level_height(level));
    std::array<float, 4> out{};
    const int xs[2] = {lx.i0, lx.i1}, ys[2] = {ly.i0, ly.i1};
    const float wx[2] = {1 - lx.t, lx.t}, wy[2] = {1 - ly.t, ly.t};
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const std::array<float, 4> t = p.sample(
                0, coarse,
                {(xs[i] + 0.5) / p.level_width(level), (ys[j] + 0.5) / p.level_height(level)});
            for (int c = 0; c < 4; ++c) out[size_t(c)] += wx[i] * wy[j] * t[size_t(c)];
        }
    return out;
}

// The decisions of TileCache::decide on recorded votes, in web/test/data/cache-trace.json: the web
// viewer's port of the cache (web/src/cache.ts) replays the same votes and must take exactly these
// decisions (web/test/unit.test.mjs). This test keeps the file in step with the C++: it fails when
// the decisions differ from the file; BTF_UPDATE_TRACE=1 rewrites it.
nlohmann::json decision_trace() {
    const std::vector<TileLayout> layouts = {
        TileLayout(256, 256, {64, 4}, {{0, 0, 4}, {0, 4, 3}}),  // 3 levels, 2 groups
        TileLayout(512, 256, {64, 4}, {{0, 0, 2}}),             // 4 levels, 1 group
    };
    std::mt19937 rng(20261201);
    const auto uniform = [&] { return double(rng() >> 8) / double(1u << 24); };
    std::vector<std::vector<float>> weights;
    nlohmann::json materials = nlohmann::json::array();
    for (const TileLayout& l : layouts) {
        std::vector<float> w(l.tile_count());
        for (size_t i = 0; i < w.size(); ++i)  // coarser tiles weigh more, as in real pyramids
            w[i] = float((0.2 + uniform()) * double(1 << l.id(i).level));
        nlohmann::json groups = nlohmann::json::array();
        for (const Group& g : l.groups()) groups.push_back({g.plane, g.first, g.count});
        materials.push_back({{"width", l.width()},
                             {"height", l.height()},
                             {"tile", l.geometry().tile},
                             {"pad", l.geometry().pad},
                             {"groups", groups},
                             {"weights", w}});
        weights.push_back(std::move(w));
    }
    TileCache cache({&layouts[0], &layouts[1]}, {&weights[0], &weights[1]}, 14);
    Votes votes({&layouts[0], &layouts[1]});
    const auto key_json = [](const TileKey& t) {
        return nlohmann::json{t.material, t.id.group, t.id.level, t.id.x, t.id.y};
    };
    nlohmann::json frames = nlohmann::json::array();
    for (int f = 0; f < 40; ++f) {
        // A viewpoint that wanders over both materials and zooms in and out.
        nlohmann::json pixels = nlohmann::json::array();
        votes.clear();
        const double cu = 0.5 + 0.45 * std::sin(f * 0.3), cv = 0.5 + 0.45 * std::cos(f * 0.2);
        const int zoom = (f / 8) % 3;
        for (int p = 0; p < 60; ++p) {
            const int m = p % 3 == 0 ? 1 : 0;
            const int level = std::max(0, zoom - 1 + int(uniform() * 2));
            // On a grid of 2⁻²⁴: the file holds the same numbers whether the compiler fused the
            // multiply-adds above into FMAs (-O2) or not (-O1).
            const auto on_grid = [](double x) {
                return std::ldexp(std::round(std::ldexp(x, 24)), -24);
            };
            const double u = on_grid(cu + (uniform() - 0.5) * 0.3);
            const double v = on_grid(cv + (uniform() - 0.5) * 0.3);
            votes.add(m, level, u, v);
            pixels.push_back({m, level, u, v});
        }
        // Tiles whose data has not arrived yet.
        std::set<std::pair<int, size_t>> missing;
        nlohmann::json unavailable = nlohmann::json::array();
        for (int m = 0; m < 2; ++m)
            for (size_t i = 0; i < layouts[size_t(m)].tile_count(); ++i)
                if ((i * 7 + size_t(f)) % 2 == 0 &&
                    layouts[size_t(m)].id(i).level + 1 < layouts[size_t(m)].levels()) {
                    missing.insert({m, i});
                    unavailable.push_back({m, i});
                }
        const TileCache::Decision d = cache.decide(
            votes,
            [&](const TileKey& t) {
                return !missing.count({t.material, layouts[size_t(t.material)].index(t.id)});
            },
            6);
        EXPECT_EQ(cache.problems(), "") << "frame " << f;
        nlohmann::json ops = nlohmann::json::array();
        for (const TileCache::Operation& op : d.operations) {
            const bool add = op.kind == TileCache::Operation::Kind::kAdd;
            nlohmann::json o = {
                {"kind", add ? "add" : "swap"}, {"tile", key_json(op.tile)}, {"value", op.value}};
            if (!add) o["out"] = {key_json(op.out[0]), key_json(op.out[1])};
            ops.push_back(std::move(o));
        }
        nlohmann::json resident = nlohmann::json::array();
        for (const TileKey& t : cache.tiles()) resident.push_back(key_json(t));
        frames.push_back({{"pixels", pixels},
                          {"unavailable", unavailable},
                          {"operations", ops},
                          {"wanted", d.wanted ? key_json(*d.wanted) : nlohmann::json()},
                          {"resident", resident}});
    }
    return {{"about",
             "TileCache::decide on recorded votes (src/btf/bsvtf/cache_test.cpp writes it; "
             "web/test/unit.test.mjs replays it)"},
            {"capacity", 14},
            {"max_operations", 6},
            {"materials", materials},
            {"frames", frames}};
}

TEST(TileCache, DecisionsMatchTheTraceTheWebViewerReplays) {
    const nlohmann::json trace = decision_trace();
    // Exercised: adds, swaps, and a swap waiting for an ancestor that has not arrived.
    int adds = 0, swaps = 0, waits = 0;
    for (const auto& f : trace["frames"]) {
        for (const auto& op : f["operations"]) (op["kind"] == "add" ? adds : swaps) += 1;
        waits += f["wanted"].is_null() ? 0 : 1;
    }
    EXPECT_GT(adds, 20);
    EXPECT_GT(swaps, 10);
    EXPECT_GT(waits, 0) << adds << " adds, " << swaps << " swaps";
    const std::filesystem::path file =
        std::filesystem::path(BTF_SOURCE_DIR) / "web/test/data/cache-trace.json";
    if (std::getenv("BTF_UPDATE_TRACE")) {
        std::filesystem::create_directories(file.parent_path());
        std::ofstream(file) << trace.dump(1) << "\n";
    }
    std::ifstream in(file);
    ASSERT_TRUE(in) << file << " is missing: run this test with BTF_UPDATE_TRACE=1";
    const nlohmann::json recorded = nlohmann::json::parse(in);
    EXPECT_TRUE(recorded == trace)
        << file << " no longer matches TileCache::decide: check the change, mirror it in "
        << "web/src/cache.ts, and rewrite the file with BTF_UPDATE_TRACE=1";
}

TEST(SampleCached, EveryPathReadsInsideItsTileAndGivesTheLevelsValue) {
    const Pyramid p = pattern_pyramid();
    const TileLayout& layout = p;
    const auto data = [&](const TileKey& t) { return p.tile(t.id).data(); };
    // Positions near the texture's edges (where lookups wrap) and inside.
    std::vector<Uv> positions = {{0.001, 0.001}, {0.999, 0.002}, {0.0005, 0.9995}, {0.5, 0.5}};
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(-1, 2);
    for (int i = 0; i < 300; ++i) positions.push_back({u(rng), u(rng)});

    // Only the root: every level is shown by level 2.
    TileCache coarse({&layout}, {&p.weights()}, 21);
    for (const Uv& at : positions)
        for (int level = 0; level < 3; ++level) {
            const auto got = sample_cached(coarse, layout, 0, 0, level, at, data);
            ASSERT_TRUE(got);
            const std::array<float, 4> want =
                level == 2 ? p.sample(0, 2, at) : through_coarser(p, level, 2, at);
            for (int c = 0; c < 4; ++c)
                ASSERT_NEAR((*got)[size_t(c)], want[size_t(c)], 1e-5f)
                    << at.u << ", " << at.v << " level " << level;
        }
    // Every finest tile and nothing else: levels 1 and 2 are the box averages of level 0, which is
    // what the pyramid stores for them (up to half-float rounding).
    TileCache fine({&layout}, {&p.weights()}, 21);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x) fine.add({0, {0, 1, x, y}});
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x) fine.add({0, {0, 0, x, y}});
    ASSERT_EQ(fine.size(), 16);
    for (const Uv& at : positions)
        for (int level = 0; level < 3; ++level) {
            const auto got = sample_cached(fine, layout, 0, 0, level, at, data);
            ASSERT_TRUE(got);
            const std::array<float, 4> want = p.sample(0, level, at);
            for (int c = 0; c < 4; ++c)
                ASSERT_NEAR((*got)[size_t(c)], want[size_t(c)], 2e-3f)
                    << at.u << ", " << at.v << " level " << level;
        }
    // A tile whose data has not arrived gives nothing.
    EXPECT_FALSE(sample_cached(fine, layout, 0, 0, 0, {0.5, 0.5},
                               [](const TileKey&) -> const uint16_t* { return nullptr; }));
}

}  // namespace
}  // namespace btf::bsvtf

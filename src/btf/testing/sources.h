// SPDX-License-Identifier: MIT
#pragma once
// Small samplings and deterministic noise for the codec tests (GoogleTest only; not part of the
// library).

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <vector>

#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/core/math.h"
#include "btf/io/function_source.h"

namespace btf::test {

/// The first `views` and `lights` of a fixed spread of UBO2003 directions over all rings (up to
/// 14 views and 12 lights), so that neighbouring views exist in every direction.
inline Sampling ubo_subset(int views, int lights) {
    static const std::vector<int> view_index = {0, 1, 3, 5, 7, 10, 13, 19, 25, 31, 37, 45, 55, 70};
    static const std::vector<int> light_index = {0, 2, 4, 8, 12, 16, 22, 30, 40, 50, 60, 70};
    const DirectionSet& ubo = DirectionSet::ubo81();
    return {ubo.subset({view_index.begin(), view_index.begin() + views}, "views"),
            ubo.subset({light_index.begin(), light_index.begin() + lights}, "lights")};
}

/// Five views and four lights at hand-picked directions (off the UBO grid).
inline Sampling five_views_four_lights() {
    const DirectionSet views("views", {{0, 0},
                                       {radians(30), 0},
                                       {radians(30), radians(120)},
                                       {radians(30), radians(240)},
                                       {radians(60), radians(60)}});
    const DirectionSet lights("lights", {{0, 0},
                                         {radians(45), radians(90)},
                                         {radians(45), radians(200)},
                                         {radians(70), radians(10)}});
    return {views, lights};
}

/// A float in [0, 1) from integer coordinates (thread-safe, no state).
inline float hash01(uint64_t a, uint64_t b, uint64_t c, uint64_t d) {
    uint64_t h = 0x9E3779B97F4A7C15ull;
    for (uint64_t v : {a, b, c, d}) {
        h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 31;
    }
    return static_cast<float>(h >> 40) * 0x1.0p-24f;
}

/// A copy of `source` with every image held in memory (a synthetic source renders each read).
inline std::unique_ptr<FunctionSource> cached(const BtfSource& source) {
    auto images = std::make_shared<std::vector<Image>>();
    for (int v = 0; v < source.num_views(); ++v)
        for (int l = 0; l < source.num_lights(); ++l) images->push_back(source.image(v, l));
    const int lights = source.num_lights();
    return std::make_unique<FunctionSource>(
        source.sampling(), source.width(), source.height(),
        [images, lights](int v, int l, int x, int y) {
            return (*images)[size_t(v) * lights + l].rgb(x, y);
        },
        "cached");
}

}  // namespace btf::test

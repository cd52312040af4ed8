// SPDX-License-Identifier: MIT
// BSVTF files (bsvtf/file.h): read_bsvtf() on any package (checksums recomputed by the package
// mutator), then what a renderer does with it: decode tiles coarsest first, each against its
// decoded parent, and evaluate the material from the angular factors and the coarsest tiles; for
// small files also the material every command opens (bsvtf/material.h: every tile decoded).
#include <map>
#include <optional>

#include "btf/bsvtf/evaluator.h"
#include "btf/bsvtf/file.h"
#include "btf/bsvtf/material.h"
#include "btf/bsvtf/tile_codec.h"
#include "fuzz/support/fuzz.h"
#include "fuzz/support/package_mutator.h"

BTF_FUZZ_PACKAGE_MUTATOR()

namespace {

using namespace btf;
using namespace btf::bsvtf;

// Tiles decoded per input: enough for a few levels of a small material.
constexpr size_t kMaxTiles = 48;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return fuzz::run([&] {
        const Package package = decode_package({data, size}, "input");
        const Bsvtf b = read_bsvtf(package, "input");
        const TileLayout& layout = b.layout;
        const TileGeometry& g = layout.geometry();
        const size_t values = size_t(g.values());
        std::map<size_t, std::vector<uint16_t>> decoded;
        for (int level = layout.levels() - 1; level >= 0 && decoded.size() < kMaxTiles; --level)
            for (size_t t = 0; t < layout.tile_count() && decoded.size() < kMaxTiles; ++t) {
                const TileId id = layout.id(t);
                if (id.level != level) continue;
                std::vector<float> prediction;
                if (layout.has_parent(id)) {
                    const auto parent = decoded.find(layout.index(layout.parent(id)));
                    if (parent == decoded.end()) continue;
                    prediction = predict_child(parent->second, g, id);
                }
                std::vector<uint16_t> tile(values);
                decode_tile(b.payload(t), prediction, g, tile);
                decoded.emplace(t, std::move(tile));
            }

        const Evaluator evaluator(b.model, layout);
        Evaluator::Angular angular;
        const Vec3 directions[] = {{0, 0, 1}, normalize(Vec3{0.4, -0.3, 0.8})};
        for (const Vec3& wi : directions) {
            evaluator.angular(wi, directions[1], angular);
            (void)evaluator.value(angular, [&](int group) -> std::optional<std::array<float, 4>> {
                const TileId coarsest{group, layout.levels() - 1, 0, 0};
                const auto tile = decoded.find(layout.index(coarsest));
                if (tile == decoded.end()) return std::nullopt;
                return sample_tile(tile->second, g, coarsest, 0, 0.5f, 0, 0.5f);
            });
        }
        if (layout.tile_count() <= kMaxTiles)
            fuzz::exercise(*bsvtf::open_material(package, "input"));
    });
}

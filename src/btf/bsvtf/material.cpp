// SPDX-License-Identifier: MIT
#include "btf/bsvtf/material.h"

#include "btf/bsvtf/tile_codec.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/limits.h"
#include "btf/util/parallel.h"

namespace btf::bsvtf {

std::vector<uint16_t> decode_tiles(const Bsvtf& file, const std::string& what, Progress& progress) {
    const TileLayout& layout = file.layout;
    const TileGeometry& g = layout.geometry();
    const size_t values = size_t(g.values());
    check_alloc(checked_bytes(uint64_t(layout.tile_count()) * values, 2).value_or(UINT64_MAX), what,
                "decoding the tiles");
    std::vector<uint16_t> decoded(layout.tile_count() * values);
    progress.begin("decoding tiles", layout.tile_count());
    for_each_level_coarsest_first(layout, [&](size_t t) {
        const TileId id = layout.id(t);
        std::vector<float> prediction;
        if (layout.has_parent(id))
            prediction = predict_child(
                {decoded.data() + layout.index(layout.parent(id)) * values, values}, g, id);
        try {
            decode_tile(file.payload(t), prediction, g, {decoded.data() + t * values, values});
        } catch (const Cancelled&) {
            throw;
        } catch (const Error& e) {
            fail("{}: tile {} (group {}, level {}, x {}, y {}): {}", what, t, id.group, id.level,
                 id.x, id.y, e.what());
        }
        progress.advance();
    });
    progress.finish();
    return decoded;
}

factor::Model finest_model(const Bsvtf& file, const std::vector<uint16_t>& decoded,
                           const std::string& what) {
    const TileLayout& layout = file.layout;
    const TileGeometry& g = layout.geometry();
    factor::Model model = file.model;
    const int64_t texels = int64_t(model.width) * model.height;
    int64_t components = 0;
    for (const factor::Block& block : model.blocks) components += block.components();
    check_alloc(checked_bytes(uint64_t(texels) * uint64_t(components), 4).value_or(UINT64_MAX),
                what, "the eigen-textures");
    for (int plane = 0; plane < model.colour.planes(); ++plane) {
        factor::Block& block = model.blocks[size_t(model.block_index(plane, 0, 0))];
        block.b = factor::Matrix::Zero(texels, block.components());
    }
    for (int gi = 0; gi < int(layout.groups().size()); ++gi) {
        const Group& group = layout.groups()[size_t(gi)];
        factor::Block& block = model.blocks[size_t(model.block_index(group.plane, 0, 0))];
        for (int ty = 0; ty < layout.tiles_y(0); ++ty)
            for (int tx = 0; tx < layout.tiles_x(0); ++tx) {
                const uint16_t* tile =
                    decoded.data() + layout.index({gi, 0, tx, ty}) * size_t(g.values());
                for (int ly = 0; ly < g.tile; ++ly)
                    for (int lx = 0; lx < g.tile; ++lx) {
                        const int x = tx * g.tile + lx, y = ty * g.tile + ly;
                        if (x >= model.width || y >= model.height) continue;
                        const uint16_t* texel =
                            tile +
                            (size_t(ly + g.pad) * size_t(g.stride()) + size_t(lx + g.pad)) * 4;
                        for (int c = 0; c < group.count; ++c)
                            block.b(int64_t(y) * model.width + x, group.first + c) =
                                from_half(texel[c]);
                    }
            }
    }
    // The energy of each component (a BSVTF file keeps its order, not its singular values).
    for (factor::Block& block : model.blocks) {
        block.energy.resize(size_t(block.components()));
        for (int k = 0; k < block.components(); ++k)
            block.energy[size_t(k)] = block.a.col(k).norm() * block.b.col(k).norm();
    }
    return model;
}

std::unique_ptr<Material> open_material(const Package& package, const std::string& what) {
    const Bsvtf file = read_bsvtf(package, what);
    return std::make_unique<factor::FactorMaterial>(
        finest_model(file, decode_tiles(file, what), what));
}

}  // namespace btf::bsvtf

// SPDX-License-Identifier: MIT
#include "btf/bsvtf/pyramid.h"

#include <algorithm>
#include <cmath>

#include "btf/core/btf_lookup.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/parallel.h"

namespace btf::bsvtf {

namespace {

int wrap(int i, int n) {
    const int r = i % n;
    return r < 0 ? r + n : r;
}

// One group's level as an image of 4 channels per texel, row-major.
struct LevelImage {
    int width = 0, height = 0;
    std::vector<float> values;
    float at(int x, int y, int c) const {
        return values[(size_t(wrap(y, height)) * size_t(width) + size_t(wrap(x, width))) * 4 +
                      size_t(c)];
    }
};

LevelImage downsample(const LevelImage& fine) {
    LevelImage out{fine.width / 2, fine.height / 2, {}};
    out.values.resize(size_t(out.width) * size_t(out.height) * 4);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x)
            for (int c = 0; c < 4; ++c)
                out.values[(size_t(y) * size_t(out.width) + size_t(x)) * 4 + size_t(c)] =
                    0.25f * (fine.at(2 * x, 2 * y, c) + fine.at(2 * x + 1, 2 * y, c) +
                             fine.at(2 * x, 2 * y + 1, c) + fine.at(2 * x + 1, 2 * y + 1, c));
    return out;
}

}  // namespace

TileLayout::TileLayout(int width, int height, TileGeometry geometry, std::vector<Group> groups)
    : m_geometry(geometry), m_width(width), m_height(height), m_groups(std::move(groups)) {
    if (geometry.tile < 8 || geometry.pad < 2 || geometry.stride() % 8 != 0)
        fail(
            "tile size {} with padding {}: the tile must be at least 8 texels, the "
            "padding at least 2, and tile + 2 × padding a multiple of 8",
            geometry.tile, geometry.pad);
    if (width < 1 || height < 1) fail("{} × {} texels", width, height);
    m_levels = 1;
    while (std::max(width >> (m_levels - 1), height >> (m_levels - 1)) > geometry.tile) ++m_levels;
    const int divisor = 1 << (m_levels - 1);
    if (width % divisor != 0 || height % divisor != 0)
        fail(
            "{} × {} texels: with tiles of {} the pyramid has {} levels, so width and "
            "height must be divisible by {}",
            width, height, geometry.tile, m_levels, divisor);
    for (int level = 0; level < m_levels; ++level) {
        m_level_base.push_back(m_tiles_per_group);
        m_tiles_per_group += size_t(tiles_x(level)) * size_t(tiles_y(level));
    }
}

Pyramid Pyramid::build(const factor::Model& model, TileGeometry geometry, Progress& progress) {
    if (model.groups.size() != 1 || model.clusters != 1 || model.levels != 1 ||
        !model.angular_levels.empty())
        fail(
            "the tiles need one factorization of the whole BTF at full resolution (an "
            "fmf package), not {} view groups, {} texel clusters, {} spatial and {} angular "
            "levels",
            model.groups.size(), model.clusters, model.levels, model.angular_count());
    std::vector<Group> groups;
    for (int plane = 0; plane < model.colour.planes(); ++plane) {
        const int k = model.blocks[size_t(model.block_index(plane, 0, 0))].components();
        for (int first = 0; first < k; first += 4)
            groups.push_back({plane, first, std::min(4, k - first)});
    }
    Pyramid p(TileLayout(model.width, model.height, geometry, std::move(groups)));
    const size_t tiles = p.tile_count();
    p.m_data.assign(tiles * size_t(geometry.values()), 0);
    p.m_weights.assign(tiles, 0.0f);

    progress.begin("cutting eigen-textures into tiles", p.groups().size());
    const int T = geometry.tile, P = geometry.pad, S = geometry.stride();
    parallel_for(0, int64_t(p.groups().size()), [&](int64_t g) {
        const Group& group = p.groups()[size_t(g)];
        const factor::Block& block = model.blocks[size_t(model.block_index(group.plane, 0, 0))];
        LevelImage image{model.width, model.height, {}};
        image.values.assign(size_t(model.width) * size_t(model.height) * 4, 0.0f);
        for (int64_t texel = 0; texel < block.b.rows(); ++texel)
            for (int c = 0; c < group.count; ++c)
                image.values[size_t(texel) * 4 + size_t(c)] = block.b(texel, group.first + c);
        for (int level = 0; level < p.levels(); ++level) {
            if (level > 0) image = downsample(image);
            for (int ty = 0; ty < p.tiles_y(level); ++ty)
                for (int tx = 0; tx < p.tiles_x(level); ++tx) {
                    const TileId id{int(g), level, tx, ty};
                    uint16_t* out = p.m_data.data() + p.index(id) * size_t(geometry.values());
                    for (int ly = 0; ly < S; ++ly)
                        for (int lx = 0; lx < S; ++lx)
                            for (int c = 0; c < 4; ++c)
                                out[(size_t(ly) * size_t(S) + size_t(lx)) * 4 + size_t(c)] =
                                    to_half(image.at(tx * T + lx - P, ty * T + ly - P, c));
                }
        }
        // Equation 8, from the stored (half) values: each tile against its up-sampled parent.
        for (int level = 0; level < p.levels(); ++level)
            for (int ty = 0; ty < p.tiles_y(level); ++ty)
                for (int tx = 0; tx < p.tiles_x(level); ++tx) {
                    const TileId id{int(g), level, tx, ty};
                    const std::span<const uint16_t> tile = p.tile(id);
                    std::vector<float> parent;
                    if (p.has_parent(id))
                        parent = predict_child(p.tile(p.parent(id)), geometry, id);
                    double sum = 0;
                    int count = 0;
                    for (int ly = P; ly < P + T; ++ly)
                        for (int lx = P; lx < P + T; ++lx) {
                            if (tx * T + lx - P >= p.level_width(level) ||
                                ty * T + ly - P >= p.level_height(level))
                                continue;
                            ++count;
                            for (int c = 0; c < 4; ++c) {
                                const size_t i =
                                    (size_t(ly) * size_t(S) + size_t(lx)) * 4 + size_t(c);
                                const double d =
                                    double(from_half(tile[i])) - (parent.empty() ? 0.0 : parent[i]);
                                sum += d * d;
                            }
                        }
                    p.m_weights[p.index(id)] = float(sum / std::max(1, count));
                }
        progress.advance();
    });
    progress.finish();
    return p;
}

int TileLayout::tiles_x(int level) const {
    return (level_width(level) + m_geometry.tile - 1) / m_geometry.tile;
}
int TileLayout::tiles_y(int level) const {
    return (level_height(level) + m_geometry.tile - 1) / m_geometry.tile;
}

size_t TileLayout::index(const TileId& id) const {
    return size_t(id.group) * m_tiles_per_group + m_level_base[size_t(id.level)] +
           size_t(id.y) * size_t(tiles_x(id.level)) + size_t(id.x);
}

TileId TileLayout::id(size_t index) const {
    TileId id;
    id.group = int(index / m_tiles_per_group);
    size_t rest = index % m_tiles_per_group;
    while (id.level + 1 < m_levels && rest >= m_level_base[size_t(id.level) + 1]) ++id.level;
    rest -= m_level_base[size_t(id.level)];
    id.x = int(rest % size_t(tiles_x(id.level)));
    id.y = int(rest / size_t(tiles_x(id.level)));
    return id;
}

std::span<const uint16_t> Pyramid::tile(const TileId& id) const {
    return {m_data.data() + index(id) * size_t(geometry().values()), size_t(geometry().values())};
}

double Pyramid::squared_sum(const TileId& id) const {
    const TileGeometry& g = geometry();
    const std::span<const uint16_t> data = tile(id);
    double sum = 0;
    for (int y = g.pad; y < g.pad + g.tile; ++y)
        for (int x = g.pad; x < g.pad + g.tile; ++x)
            for (int c = 0; c < 4; ++c) {
                const double v =
                    from_half(data[(size_t(y) * size_t(g.stride()) + size_t(x)) * 4 + size_t(c)]);
                sum += v * v;
            }
    return sum;
}

std::array<float, 4> Pyramid::sample(int group, int level, const Uv& uv) const {
    const WrapLerp lx = wrap_lerp(uv.u, level_width(level));
    const WrapLerp ly = wrap_lerp(uv.v, level_height(level));
    const TileId id{group, level, lx.i0 / geometry().tile, ly.i0 / geometry().tile};
    return sample_tile(tile(id), geometry(), id, lx.i0, lx.t, ly.i0, ly.t);
}

std::array<float, 4> sample_tile(std::span<const uint16_t> tile, const TileGeometry& geometry,
                                 const TileId& id, int i0x, float tx, int i0y, float ty) {
    const int S = geometry.stride();
    const int x = i0x - id.x * geometry.tile + geometry.pad;
    const int y = i0y - id.y * geometry.tile + geometry.pad;
    const float w00 = (1 - tx) * (1 - ty), w10 = tx * (1 - ty);
    const float w01 = (1 - tx) * ty, w11 = tx * ty;
    const uint16_t* r0 = tile.data() + (size_t(y) * size_t(S) + size_t(x)) * 4;
    const uint16_t* r1 = r0 + size_t(S) * 4;
    std::array<float, 4> out;
    for (int c = 0; c < 4; ++c)
        out[size_t(c)] = from_half(r0[c]) * w00 + from_half(r0[4 + c]) * w10 +
                         from_half(r1[c]) * w01 + from_half(r1[4 + c]) * w11;
    return out;
}

std::vector<float> predict_child(std::span<const uint16_t> parent, const TileGeometry& geometry,
                                 const TileId& child) {
    const int T = geometry.tile, P = geometry.pad, S = geometry.stride();
    // Child texel (unwrapped level-j coordinate u) sits at (u + 0.5) / 2 − 0.5 on the parent's
    // level; the parent tile's local coordinate adds P and subtracts its origin.
    const auto axis = [&](int origin, int local, int& i0, float& t) {
        const int u = origin * T + local - P;
        const double c = (u + 0.5) / 2 - 0.5 - (origin / 2) * T + P;
        i0 = int(std::floor(c));
        t = float(c - i0);
    };
    std::vector<float> out(size_t(geometry.values()));
    for (int ly = 0; ly < S; ++ly) {
        int y0;
        float ty;
        axis(child.y, ly, y0, ty);
        for (int lx = 0; lx < S; ++lx) {
            int x0;
            float tx;
            axis(child.x, lx, x0, tx);
            const uint16_t* r0 = parent.data() + (size_t(y0) * size_t(S) + size_t(x0)) * 4;
            const uint16_t* r1 = r0 + size_t(S) * 4;
            for (int c = 0; c < 4; ++c)
                out[(size_t(ly) * size_t(S) + size_t(lx)) * 4 + size_t(c)] =
                    from_half(r0[c]) * (1 - tx) * (1 - ty) + from_half(r0[4 + c]) * tx * (1 - ty) +
                    from_half(r1[c]) * (1 - tx) * ty + from_half(r1[4 + c]) * tx * ty;
        }
    }
    return out;
}

}  // namespace btf::bsvtf

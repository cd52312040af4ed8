// SPDX-License-Identifier: MIT
#pragma once
/// Bidirectional Sparse Virtual Texture Functions (Schwartz, Ruiters & Klein 2013), the tile
/// pyramid: the eigen-textures of a full-matrix factorization cut into tiles of a mip pyramid,
/// so that a renderer keeps only the tiles it needs in a fixed-size cache.
///
/// A factorized BTF is value(row, texel) = mean[row] + Σ_k a(row, k) · b(texel, k) (factor/model.h)
/// with orthonormal columns of a (fmf: a = U, b = V·Σ). Each column b(·, k) is a W × H image, an
/// eigen-texture. Four components of one colour plane share a *group* (the four channels of an
/// RGBA tile). Each group is a virtual texture with a mip pyramid: level 0 is the W × H texels of
/// the model, level j + 1 the 2 × 2 box average of level j, up to the first level that fits one
/// tile. (The paper counts levels the other way, l = L − j with L the finest.)
///
/// A tile holds T × T texels of one level and group, plus `pad` texels of its neighbours on each
/// side (wrapping around the texture, as the evaluator's bilinear lookup wraps), 4 channels, half
/// floats: (T + 2·pad)² × 4 values, texel-major (channels innermost). Tile (x, y) of level j covers
/// level-j texels [x·T, x·T + T) × [y·T, y·T + T); its parent is tile (x/2, y/2) of level j + 1.
/// Texel centres follow btf::wrap_lerp: level-j texel i is centred at (i + 0.5) / W_j, so a
/// bilinear lookup at any level is the lookup6d convention at that level's resolution, and a
/// lookup of level 0 from tiles is exactly the model's spatial interpolation.
///
/// Each tile carries the weight of equation 8, w(i, l, l − 1): the mean over its texels of the
/// squared difference between the tile and its parent up-sampled bilinearly, summed over the four
/// channels — because a's columns are orthonormal, the squared error an ABRDF takes when the tile
/// is replaced by its parent (summed over all rows). The coarsest level's tiles weigh their mean
/// squared value (the error of having nothing).

#include <array>
#include <compare>
#include <cstdint>
#include <span>
#include <vector>

#include "btf/codecs/factor/model.h"
#include "btf/core/material.h"
#include "btf/util/parallel.h"
#include "btf/util/progress.h"

namespace btf::bsvtf {

/// Tile size and padding. T + 2·pad must be a multiple of 8 (the tile codec's DCT blocks).
struct TileGeometry {
    int tile = 64;
    int pad = 4;
    int stride() const { return tile + 2 * pad; }
    int texels() const { return stride() * stride(); }
    /// Values of a tile: texels × 4 channels.
    int values() const { return texels() * 4; }
};

struct TileId {
    int group = 0;
    int level = 0;  ///< 0 = finest
    int x = 0, y = 0;
    auto operator<=>(const TileId&) const = default;
};

/// The group of four components of one colour plane.
struct Group {
    int plane = 0;
    int first = 0;  ///< first component (of the plane's block)
    int count = 0;  ///< 1 to 4; missing channels are 0
};

/// Where the tiles of a W × H factorization are: levels, tiles per level, groups, and the dense
/// numbering of tiles (group-major, then level from finest, then row-major).
class TileLayout {
  public:
    TileLayout() = default;
    /// Throws btf::Error for a geometry the tile codec cannot use (T + 2·pad not a multiple of 8,
    /// T < 8, pad < 2) or a width and height not divisible by 2^(levels − 1).
    TileLayout(int width, int height, TileGeometry geometry, std::vector<Group> groups);

    const TileGeometry& geometry() const { return m_geometry; }
    int width() const { return m_width; }
    int height() const { return m_height; }
    /// Levels, the coarsest (levels() − 1) fitting one tile.
    int levels() const { return m_levels; }
    int level_width(int level) const { return m_width >> level; }
    int level_height(int level) const { return m_height >> level; }
    int tiles_x(int level) const;
    int tiles_y(int level) const;
    const std::vector<Group>& groups() const { return m_groups; }

    size_t tile_count() const { return m_tiles_per_group * m_groups.size(); }
    size_t tiles_per_group() const { return m_tiles_per_group; }
    size_t index(const TileId& id) const;
    TileId id(size_t index) const;
    TileId parent(const TileId& id) const { return {id.group, id.level + 1, id.x / 2, id.y / 2}; }
    bool has_parent(const TileId& id) const { return id.level + 1 < m_levels; }

  private:
    TileGeometry m_geometry;
    int m_width = 0, m_height = 0, m_levels = 0;
    std::vector<Group> m_groups;
    std::vector<size_t> m_level_base;  // per level: first tile index within a group
    size_t m_tiles_per_group = 0;
};

/// Calls fn(tile index) for every tile of `layout`, level by level from the coarsest (the tiles of
/// one level in parallel): every tile's parent is done before the tile, as prediction needs.
template <typename Fn>
void for_each_level_coarsest_first(const TileLayout& layout, Fn&& fn) {
    for (int level = layout.levels() - 1; level >= 0; --level) {
        std::vector<size_t> tiles;
        for (size_t t = 0; t < layout.tile_count(); ++t)
            if (layout.id(t).level == level) tiles.push_back(t);
        parallel_for(0, int64_t(tiles.size()), [&](int64_t k) { fn(tiles[size_t(k)]); });
    }
}

/// The tiles themselves, cut from a factor model (preprocessing).
class Pyramid : public TileLayout {
  public:
    Pyramid() = default;  ///< no tiles
    /// Cuts the eigen-textures of `model` into tiles. The model must be a single-group,
    /// single-cluster, full-resolution factorization without angular levels (an fmf package);
    /// width and height must be divisible by 2^(levels − 1). Throws btf::Error saying what does
    /// not fit.
    static Pyramid build(const factor::Model& model, TileGeometry geometry,
                         Progress& progress = Progress::none());

    /// The tile's half-float bits, geometry().values() of them.
    std::span<const uint16_t> tile(const TileId& id) const;
    /// Σ of the squared values of the tile's own T × T texels (no padding), all four channels.
    double squared_sum(const TileId& id) const;
    /// Equation 8's weight w(i, l, l − 1).
    float weight(const TileId& id) const { return m_weights[index(id)]; }
    const std::vector<float>& weights() const { return m_weights; }

    /// The group's four channels at `uv` on `level`: bilinear, wrapping, read from the one tile
    /// that holds the lookup's first texel (its padding holds the others).
    std::array<float, 4> sample(int group, int level, const Uv& uv) const;

  private:
    explicit Pyramid(TileLayout layout) : TileLayout(std::move(layout)) {}
    std::vector<uint16_t> m_data;  // tile_count() × values()
    std::vector<float> m_weights;
};

/// Bilinear lookup in a tile: the four channels at level-j texel coordinates (x, y) given as the
/// first texel of a wrap_lerp (i0 in [0, W_j)) and its blend factor.
std::array<float, 4> sample_tile(std::span<const uint16_t> tile, const TileGeometry& geometry,
                                 const TileId& id, int i0x, float tx, int i0y, float ty);

/// The up-sampling of a parent tile onto the texels of one of its children (padding included):
/// geometry().values() floats, each the bilinear interpolation of the parent's level at the
/// child texel's centre. `parent` holds half-float bits.
std::vector<float> predict_child(std::span<const uint16_t> parent, const TileGeometry& geometry,
                                 const TileId& child);

}  // namespace btf::bsvtf

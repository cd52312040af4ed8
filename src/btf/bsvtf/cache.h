// SPDX-License-Identifier: MIT
#pragma once
/// The BSVTF tile cache (Schwartz et al. 2013, §3 and §5): a fixed number of tile slots shared by
/// every material of a scene, filled by `add` and `swap` operations chosen from the feedback of
/// the frames drawn. One implementation of the logic, used by the headless simulator
/// (`btf bsvtf-sim`); the web viewer's BSVTF mode mirrors it.
///
/// Levels are numbered from the finest (0) as in pyramid.h; the paper's l is L − j.
///
/// - Votes (equation 9): a feedback pixel that needs level j at some texel of a material votes for
///   the level-j tile holding that texel and for each of its ancestors; every component group of
///   the material gets the same votes (the paper repeats them in the groups' layout).
/// - add(t): t's parent is resident and a slot is free; afterwards any resident ancestor whose
///   texels are all covered by resident tiles below it is removed (it shows no pixel any more). Its
///   gain is the priority P(t) = w(t) · v(t), w being equation 8's weight of t against its parent.
/// - swap(a; t1, t2): two resident tiles leave and their common ancestor a comes in (unless it is
///   resident already or covered by other resident tiles below it), freeing at least one slot. Its
///   cost (equation 10) is c(a, t) = v(t) · Σ w(s) over t and its ancestors s strictly below a —
///   the error, by the same measure, of showing a where t showed; the paper's sum also includes a's
///   own weight against its parent, which does not change when a comes in, so it is left out here.
/// - The decision rule (§5.2): while a slot is free, add the candidate of highest P > 0. When the
///   cache is full, find the cheapest swap c*; if c* < P* of the best add, swap, then add.
///
/// Invariants (checked by problems()): every texel of every group of every material is covered by
/// a resident tile (the initial state holds the coarsest tile of every group, and neither
/// operation uncovers anything); no resident tile is covered entirely by resident tiles below it
/// (in particular none has all its children resident); the cache holds at most `capacity` tiles.

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "btf/bsvtf/pyramid.h"
#include "btf/core/btf_lookup.h"

namespace btf::bsvtf {

struct TileKey {
    int material = 0;
    TileId id;
    auto operator<=>(const TileKey&) const = default;
};

/// Feedback votes of one frame, per material and tile position (shared by the groups).
class Votes {
  public:
    explicit Votes(std::vector<const TileLayout*> layouts);
    void clear();
    /// One feedback pixel: `material` is seen at level `level` (clamped to the pyramid) at
    /// texture coordinates (u, v) (wrapping).
    void add(int material, int level, double u, double v);
    /// v(t) of equation 9 (t's group is ignored).
    uint32_t operator()(int material, const TileId& t) const;

  private:
    std::vector<const TileLayout*> m_layouts;
    std::vector<std::vector<uint32_t>> m_votes;  // [material][tile index of group 0]
};

class TileCache {
  public:
    /// `layouts` and `weights` (equation 8, per tile index) of every material. The cache starts
    /// with the coarsest tile of every group of every material; throws btf::Error if those do
    /// not fit into `capacity` slots.
    TileCache(std::vector<const TileLayout*> layouts,
              std::vector<const std::vector<float>*> weights, int capacity);

    int capacity() const { return m_capacity; }
    int size() const { return m_size; }
    bool resident(const TileKey& t) const;
    /// The slot a resident tile occupies (0 … capacity − 1), for an atlas texture; −1 otherwise.
    int slot(const TileKey& t) const;
    /// Every resident tile.
    std::vector<TileKey> tiles() const;

    /// The resident tile of (material, group) that shows level-`level` texel (x, y): the tile at
    /// that level or its nearest resident ancestor, else (when a region is covered only by finer
    /// tiles) the coarsest resident tile below it.
    TileKey lookup(int material, int group, int level, int x, int y) const;

    /// P(t) = w(t) · v(t).
    double priority(const TileKey& t, const Votes& votes) const;
    /// c(a, t) of equation 10 (see above); a must be an ancestor of t.
    double swap_cost(const TileKey& ancestor, const TileKey& t, const Votes& votes) const;

    struct Operation {
        enum class Kind { kAdd, kSwap } kind = Kind::kAdd;
        TileKey tile;  ///< added (kAdd), or the ancestor coming in (kSwap)
        TileKey out[2];
        double value = 0;  ///< P of the add, or c of the swap
    };
    /// The best add (a non-resident tile with a resident parent that resident tiles below it do
    /// not cover already, highest P > 0), excluding tiles for which `skip(t)` is true (e.g. not
    /// yet received).
    template <typename Skip>
    std::optional<Operation> best_add(const Votes& votes, Skip&& skip) const;
    /// Calls fn(tile, P) for every add candidate with P > 0 (what best_add chooses from).
    template <typename Fn>
    void for_each_add_candidate(const Votes& votes, Fn&& fn) const;
    std::optional<Operation> best_add(const Votes& votes) const {
        return best_add(votes, [](const TileKey&) { return false; });
    }
    /// The cheapest swap of two resident tiles (never the last cover of anything).
    std::optional<Operation> cheapest_swap(const Votes& votes) const;

    /// What decide() did.
    struct Decision {
        std::vector<Operation> operations;  ///< applied, in order
        /// Set when the rule chose a swap whose ancestor is neither resident nor available: the
        /// tile to ask for (the first one not available on the ancestor's path from the
        /// coarsest level); decide() stops there.
        std::optional<TileKey> wanted;
    };
    /// The decision rule of §5.2, applied: while a slot is free, the best add; when the cache is
    /// full, the cheapest swap if it costs less than the best add gains, then that add; at most
    /// `max_operations` operations. Only tiles for which `available(t)` is true (their data is
    /// at hand) are added or brought back by a swap. The simulator and the web viewer
    /// (web/src/cache.ts) run exactly this.
    template <typename Available>
    Decision decide(const Votes& votes, Available&& available, int max_operations);

    /// Applies an add (the parent must be resident and a slot free); throws btf::Error otherwise.
    void add(const TileKey& t);
    /// Applies a swap (both tiles resident, `ancestor` a common ancestor of both).
    void swap(const TileKey& ancestor, const TileKey& t1, const TileKey& t2);

    /// What is wrong with the cache's state ("" when every invariant holds).
    std::string problems() const;

  private:
    struct Material {
        const TileLayout* layout;
        const std::vector<float>* weights;
        std::vector<int> slot;  // per tile index: slot or −1
    };
    std::vector<TileId> children(const Material& m, const TileId& t) const;
    void insert(const TileKey& t);
    void erase(const TileKey& t);
    /// Every texel of t is covered by resident tiles below t.
    bool covered_below(const Material& m, const TileId& t) const;
    void remove_covered_ancestors(const TileKey& t);
    float weight(const TileKey& t) const;

    std::vector<Material> m_materials;
    std::vector<int> m_free;  // free slots
    int m_capacity = 0;
    int m_size = 0;
};

/// The four channels of (material, group) at `uv` on `level` as the cache shows them: each of
/// the bilinear lookup's four level texels is read from the tile the cache shows for it — its
/// own tile; a coarser tile, bilinear at the texel's centre; or finer tiles, the average of the
/// 2^d × 2^d texels below it (the pyramid's box filter). `tile_data(TileKey)` gives a tile's
/// half-float bits, or nullptr when it has not arrived: then nothing.
template <typename TileData>
std::optional<std::array<float, 4>> sample_cached(const TileCache& cache, const TileLayout& layout,
                                                  int material, int group, int level, const Uv& uv,
                                                  TileData&& tile_data);

/// One texel of a level from a tile of any level that covers it (see sample_cached); `texel`
/// receives the four channels. False when the tile's data is missing.
bool texel_from_tile(const uint16_t* data, const TileGeometry& geometry, const TileId& tile,
                     int level, int x, int y, std::array<float, 4>& texel);

template <typename TileData>
std::optional<std::array<float, 4>> sample_cached(const TileCache& cache, const TileLayout& layout,
                                                  int material, int group, int level, const Uv& uv,
                                                  TileData&& tile_data) {
    level = std::clamp(level, 0, layout.levels() - 1);
    const WrapLerp lx = wrap_lerp(uv.u, layout.level_width(level));
    const WrapLerp ly = wrap_lerp(uv.v, layout.level_height(level));
    const int xs[2] = {lx.i0, lx.i1}, ys[2] = {ly.i0, ly.i1};
    const float wx[2] = {1 - lx.t, lx.t}, wy[2] = {1 - ly.t, ly.t};
    std::array<float, 4> out{};
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const TileKey t = cache.lookup(material, group, level, xs[i], ys[j]);
            std::array<float, 4> texel;
            if (!texel_from_tile(tile_data(t), layout.geometry(), t.id, level, xs[i], ys[j], texel))
                return std::nullopt;
            for (int c = 0; c < 4; ++c) out[size_t(c)] += wx[i] * wy[j] * texel[size_t(c)];
        }
    return out;
}

template <typename Available>
TileCache::Decision TileCache::decide(const Votes& votes, Available&& available,
                                      int max_operations) {
    Decision d;
    for (int op = 0; op < max_operations; ++op) {
        const auto add = best_add(votes, [&](const TileKey& t) { return !available(t); });
        if (!add) break;
        if (m_size < m_capacity) {
            this->add(add->tile);
            d.operations.push_back(*add);
            continue;
        }
        const auto swap = cheapest_swap(votes);
        if (!swap || swap->value >= add->value) break;
        if (!resident(swap->tile) && !available(swap->tile)) {
            const TileLayout& l = *m_materials[size_t(swap->tile.material)].layout;
            TileId t = swap->tile.id;
            while (l.has_parent(t) && !available(TileKey{swap->tile.material, l.parent(t)}))
                t = l.parent(t);
            d.wanted = TileKey{swap->tile.material, t};
            break;
        }
        this->swap(swap->tile, swap->out[0], swap->out[1]);
        d.operations.push_back(*swap);
    }
    return d;
}

template <typename Fn>
void TileCache::for_each_add_candidate(const Votes& votes, Fn&& fn) const {
    for (int mi = 0; mi < int(m_materials.size()); ++mi) {
        const Material& m = m_materials[size_t(mi)];
        for (size_t i = 0; i < m.slot.size(); ++i) {
            if (m.slot[i] < 0) continue;
            for (const TileId& c : children(m, m.layout->id(i))) {
                if (m.slot[m.layout->index(c)] >= 0 || covered_below(m, c)) continue;
                const TileKey key{mi, c};
                const double p = priority(key, votes);
                if (p > 0) fn(key, p);
            }
        }
    }
}

template <typename Skip>
std::optional<TileCache::Operation> TileCache::best_add(const Votes& votes, Skip&& skip) const {
    std::optional<Operation> best;
    for_each_add_candidate(votes, [&](const TileKey& key, double p) {
        if (!skip(key) && (!best || p > best->value))
            best = Operation{Operation::Kind::kAdd, key, {}, p};
    });
    return best;
}

}  // namespace btf::bsvtf

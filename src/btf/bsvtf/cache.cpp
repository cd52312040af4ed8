// SPDX-License-Identifier: MIT
#include "btf/bsvtf/cache.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "btf/core/btf_lookup.h"
#include "btf/util/error.h"
#include "btf/util/half.h"

namespace btf::bsvtf {

// ---- sampling through the cache --------------------------------------------------------------

bool texel_from_tile(const uint16_t* data, const TileGeometry& g, const TileId& tile, int level,
                     int x, int y, std::array<float, 4>& texel) {
    if (!data) return false;
    const auto value = [&](int lx, int ly, int c) {
        return from_half(data[(size_t(ly) * size_t(g.stride()) + size_t(lx)) * 4 + size_t(c)]);
    };
    const int ox = tile.x * g.tile - g.pad, oy = tile.y * g.tile - g.pad;  // texel of local 0
    if (tile.level == level) {
        for (int c = 0; c < 4; ++c) texel[size_t(c)] = value(x - ox, y - oy, c);
        return true;
    }
    if (tile.level > level) {
        // Bilinear on the coarser level at the texel's centre: (x + 0.5) / 2^d − 0.5 there, which
        // lies within the tile or its first padding texel.
        const double scale = 1.0 / double(1 << (tile.level - level));
        const double px = (x + 0.5) * scale - 0.5, py = (y + 0.5) * scale - 0.5;
        const int ix = int(std::floor(px)), iy = int(std::floor(py));
        const float tx = float(px - ix), ty = float(py - iy);
        const int lx = ix - ox, ly = iy - oy;
        for (int c = 0; c < 4; ++c)
            texel[size_t(c)] =
                value(lx, ly, c) * (1 - tx) * (1 - ty) + value(lx + 1, ly, c) * tx * (1 - ty) +
                value(lx, ly + 1, c) * (1 - tx) * ty + value(lx + 1, ly + 1, c) * tx * ty;
        return true;
    }
    // Finer: the average of the texels below it that lie in this tile (all of them when the
    // tile size is a multiple of 2^d, as for powers of two).
    const int n = 1 << (level - tile.level);
    const int x0 = (x << (level - tile.level)) - ox, y0 = (y << (level - tile.level)) - oy;
    texel.fill(0.0f);
    int count = 0;
    for (int ly = y0; ly < y0 + n; ++ly)
        for (int lx = x0; lx < x0 + n; ++lx) {
            if (lx < g.pad || ly < g.pad || lx >= g.pad + g.tile || ly >= g.pad + g.tile) continue;
            ++count;
            for (int c = 0; c < 4; ++c) texel[size_t(c)] += value(lx, ly, c);
        }
    if (count == 0) return false;
    for (float& v : texel) v /= float(count);
    return true;
}

// ---- votes -----------------------------------------------------------------------------------

Votes::Votes(std::vector<const TileLayout*> layouts) : m_layouts(std::move(layouts)) {
    for (const TileLayout* l : m_layouts) m_votes.emplace_back(l->tiles_per_group(), 0u);
}

void Votes::clear() {
    for (auto& v : m_votes) std::fill(v.begin(), v.end(), 0u);
}

void Votes::add(int material, int level, double u, double v) {
    const TileLayout& l = *m_layouts[size_t(material)];
    level = std::clamp(level, 0, l.levels() - 1);
    const WrapLerp x = wrap_lerp(u, l.level_width(level));
    const WrapLerp y = wrap_lerp(v, l.level_height(level));
    TileId t{0, level, x.i0 / l.geometry().tile, y.i0 / l.geometry().tile};
    std::vector<uint32_t>& votes = m_votes[size_t(material)];
    for (;;) {
        ++votes[l.index(t)];
        if (!l.has_parent(t)) break;
        t = l.parent(t);
    }
}

uint32_t Votes::operator()(int material, const TileId& t) const {
    const TileLayout& l = *m_layouts[size_t(material)];
    return m_votes[size_t(material)][l.index({0, t.level, t.x, t.y})];
}

// ---- the cache -------------------------------------------------------------------------------

TileCache::TileCache(std::vector<const TileLayout*> layouts,
                     std::vector<const std::vector<float>*> weights, int capacity)
    : m_capacity(capacity) {
    if (layouts.size() != weights.size()) throw Error("TileCache: one weight list per layout");
    int coarsest = 0;
    for (size_t i = 0; i < layouts.size(); ++i) {
        if (weights[i]->size() != layouts[i]->tile_count())
            throw Error("TileCache: the weights do not match the layout");
        m_materials.push_back(
            {layouts[i], weights[i], std::vector<int>(layouts[i]->tile_count(), -1)});
        const TileLayout& l = *layouts[i];
        coarsest += int(l.groups().size()) * l.tiles_x(l.levels() - 1) * l.tiles_y(l.levels() - 1);
    }
    if (coarsest > capacity)
        fail(
            "bsvtf: a cache of {} tiles cannot hold the coarsest level of every material ({} "
            "tiles)",
            capacity, coarsest);
    for (int s = capacity - 1; s >= 0; --s) m_free.push_back(s);
    for (int mi = 0; mi < int(m_materials.size()); ++mi) {
        const TileLayout& l = *m_materials[size_t(mi)].layout;
        const int top = l.levels() - 1;
        for (int g = 0; g < int(l.groups().size()); ++g)
            for (int y = 0; y < l.tiles_y(top); ++y)
                for (int x = 0; x < l.tiles_x(top); ++x) insert({mi, {g, top, x, y}});
    }
}

bool TileCache::resident(const TileKey& t) const {
    return slot(t) >= 0;
}

int TileCache::slot(const TileKey& t) const {
    const Material& m = m_materials[size_t(t.material)];
    return m.slot[m.layout->index(t.id)];
}

std::vector<TileKey> TileCache::tiles() const {
    std::vector<TileKey> out;
    for (int mi = 0; mi < int(m_materials.size()); ++mi) {
        const Material& m = m_materials[size_t(mi)];
        for (size_t i = 0; i < m.slot.size(); ++i)
            if (m.slot[i] >= 0) out.push_back({mi, m.layout->id(i)});
    }
    return out;
}

TileKey TileCache::lookup(int material, int group, int level, int x, int y) const {
    const Material& m = m_materials[size_t(material)];
    const TileLayout& l = *m.layout;
    level = std::clamp(level, 0, l.levels() - 1);
    const int T = l.geometry().tile;
    TileId t{group, level, x / T, y / T};
    while (m.slot[l.index(t)] < 0 && l.has_parent(t)) t = l.parent(t);
    if (m.slot[l.index(t)] >= 0) return {material, t};
    // Nothing at or above the level: finer tiles cover the texel (coverage never fails).
    for (int k = level - 1; k >= 0; --k) {
        t = {group, k, (x << (level - k)) / T, (y << (level - k)) / T};
        if (m.slot[l.index(t)] >= 0) return {material, t};
    }
    throw Error("bsvtf: a texel is not covered by the tile cache");
}

float TileCache::weight(const TileKey& t) const {
    const Material& m = m_materials[size_t(t.material)];
    return (*m.weights)[m.layout->index(t.id)];
}

double TileCache::priority(const TileKey& t, const Votes& votes) const {
    return double(weight(t)) * double(votes(t.material, t.id));
}

double TileCache::swap_cost(const TileKey& ancestor, const TileKey& t, const Votes& votes) const {
    const TileLayout& l = *m_materials[size_t(t.material)].layout;
    double sum = 0;
    for (TileId s = t.id; s.level < ancestor.id.level; s = l.parent(s))
        sum += weight({t.material, s});
    return double(votes(t.material, t.id)) * sum;
}

std::vector<TileId> TileCache::children(const Material& m, const TileId& t) const {
    std::vector<TileId> out;
    if (t.level == 0) return out;
    const TileLayout& l = *m.layout;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const TileId c{t.group, t.level - 1, 2 * t.x + dx, 2 * t.y + dy};
            if (c.x < l.tiles_x(c.level) && c.y < l.tiles_y(c.level)) out.push_back(c);
        }
    return out;
}

std::optional<TileCache::Operation> TileCache::cheapest_swap(const Votes& votes) const {
    // For every ancestor of a resident tile, the two cheapest resident tiles below it.
    struct Two {
        double cost[2] = {INFINITY, INFINITY};
        TileKey tile[2];
    };
    std::map<TileKey, Two> below;
    for (int mi = 0; mi < int(m_materials.size()); ++mi) {
        const Material& m = m_materials[size_t(mi)];
        const TileLayout& l = *m.layout;
        for (size_t i = 0; i < m.slot.size(); ++i) {
            if (m.slot[i] < 0) continue;
            const TileKey t{mi, l.id(i)};
            double sum = 0;
            const double v = votes(mi, t.id);
            for (TileId s = t.id; l.has_parent(s);) {
                sum += weight({mi, s});
                s = l.parent(s);
                const double cost = v * sum;
                Two& two = below[{mi, s}];
                if (cost < two.cost[0]) {
                    two.cost[1] = two.cost[0];
                    two.tile[1] = two.tile[0];
                    two.cost[0] = cost;
                    two.tile[0] = t;
                } else if (cost < two.cost[1]) {
                    two.cost[1] = cost;
                    two.tile[1] = t;
                }
            }
        }
    }
    std::optional<Operation> best;
    for (const auto& [ancestor, two] : below) {
        if (!std::isfinite(two.cost[1])) continue;
        // Equal costs: the lowest ancestor (the least resolution given up).
        const double c = two.cost[0] + two.cost[1];
        if (!best || c < best->value ||
            (c == best->value && ancestor.id.level < best->tile.id.level))
            best = Operation{Operation::Kind::kSwap, ancestor, {two.tile[0], two.tile[1]}, c};
    }
    return best;
}

void TileCache::insert(const TileKey& t) {
    Material& m = m_materials[size_t(t.material)];
    int& s = m.slot[m.layout->index(t.id)];
    if (s >= 0) return;
    if (m_free.empty()) throw Error("bsvtf: the tile cache is full");
    s = m_free.back();
    m_free.pop_back();
    ++m_size;
}

void TileCache::erase(const TileKey& t) {
    Material& m = m_materials[size_t(t.material)];
    int& s = m.slot[m.layout->index(t.id)];
    if (s < 0) return;
    m_free.push_back(s);
    s = -1;
    --m_size;
}

bool TileCache::covered_below(const Material& m, const TileId& t) const {
    const std::vector<TileId> kids = children(m, t);
    if (kids.empty()) return false;
    return std::all_of(kids.begin(), kids.end(), [&](const TileId& c) {
        return m.slot[m.layout->index(c)] >= 0 || covered_below(m, c);
    });
}

void TileCache::remove_covered_ancestors(const TileKey& t) {
    const Material& m = m_materials[size_t(t.material)];
    const TileLayout& l = *m.layout;
    for (TileId a = t.id; l.has_parent(a);) {
        a = l.parent(a);
        if (m.slot[l.index(a)] >= 0 && covered_below(m, a)) erase({t.material, a});
    }
}

void TileCache::add(const TileKey& t) {
    const Material& m = m_materials[size_t(t.material)];
    const TileLayout& l = *m.layout;
    if (resident(t)) throw Error("bsvtf: add of a resident tile");
    if (!l.has_parent(t.id) || !resident({t.material, l.parent(t.id)}))
        throw Error("bsvtf: add of a tile whose parent is not resident");
    if (covered_below(m, t.id))
        throw Error("bsvtf: add of a tile that resident tiles below it cover already");
    insert(t);
    remove_covered_ancestors(t);
}

void TileCache::swap(const TileKey& ancestor, const TileKey& t1, const TileKey& t2) {
    const TileLayout& l = *m_materials[size_t(ancestor.material)].layout;
    const auto below = [&](const TileKey& t) {
        if (t.material != ancestor.material || t.id.group != ancestor.id.group ||
            t.id.level >= ancestor.id.level)
            return false;
        TileId s = t.id;
        while (s.level < ancestor.id.level) s = l.parent(s);
        return s == ancestor.id;
    };
    if (!(t1 < t2 || t2 < t1) || !resident(t1) || !resident(t2) || !below(t1) || !below(t2))
        throw Error("bsvtf: swap needs two resident tiles below the ancestor");
    erase(t1);
    erase(t2);
    // The ancestor comes in unless resident tiles below it cover it all already.
    if (!covered_below(m_materials[size_t(ancestor.material)], ancestor.id)) insert(ancestor);
    remove_covered_ancestors(ancestor);
}

std::string TileCache::problems() const {
    if (m_size > m_capacity) return fmt::format("{} tiles in a cache of {}", m_size, m_capacity);
    int counted = 0;
    for (int mi = 0; mi < int(m_materials.size()); ++mi) {
        const Material& m = m_materials[size_t(mi)];
        const TileLayout& l = *m.layout;
        for (size_t i = 0; i < m.slot.size(); ++i) {
            const TileId t = l.id(i);
            if (m.slot[i] >= 0) {
                ++counted;
                if (covered_below(m, t))
                    return fmt::format(
                        "material {}: tile (group {}, level {}, {}, {}) is resident "
                        "but covered by resident tiles below it",
                        mi, t.group, t.level, t.x, t.y);
            }
            // Coverage: every finest tile has a resident tile on its path to the root.
            if (t.level == 0) {
                TileId s = t;
                while (m.slot[l.index(s)] < 0 && l.has_parent(s)) s = l.parent(s);
                if (m.slot[l.index(s)] < 0)
                    return fmt::format(
                        "material {}: group {} tile ({}, {}) of level 0 is not "
                        "covered",
                        mi, t.group, t.x, t.y);
            }
        }
    }
    if (counted != m_size)
        return fmt::format("{} resident tiles counted, {} recorded", counted, m_size);
    return "";
}

}  // namespace btf::bsvtf

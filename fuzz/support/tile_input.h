// SPDX-License-Identifier: MIT
#pragma once
/// The input of the bsvtf_tile target: two bytes that choose what the decoder is told, then the
/// tile payload (bsvtf/tile_codec.h) itself.
///
///     byte 0   bits 0–1: tile size 8 << b (8, 16, 32, 64); bits 2–3: padding 4 · (1 + b)
///     byte 1   0: a tile without parent (no prediction); else a prediction, a fixed pattern
///              scaled by byte 1 / 32
///     byte 2…  the payload
#include <cstdint>
#include <span>
#include <vector>

#include "btf/bsvtf/pyramid.h"

namespace btf::fuzz {

inline bsvtf::TileGeometry tile_geometry(uint8_t b) {
    return {8 << (b & 3), 4 * (1 + ((b >> 2) & 3))};
}

inline std::vector<float> tile_prediction(uint8_t b, const bsvtf::TileGeometry& g) {
    std::vector<float> p;
    if (b == 0) return p;
    p.resize(size_t(g.values()));
    for (size_t i = 0; i < p.size(); ++i)
        p[i] = (float(uint32_t(i * 2654435761u) >> 24) / 128.0f - 1.0f) * float(b) / 32.0f;
    return p;
}

}  // namespace btf::fuzz

// SPDX-License-Identifier: MIT
// The BSVTF tile decoder (bsvtf/tile_codec.h): decode_tile() on any payload, for a geometry and
// prediction chosen by the first two bytes (support/tile_input.h).
#include "btf/bsvtf/tile_codec.h"
#include "fuzz/support/fuzz.h"
#include "fuzz/support/tile_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 2) return 0;
    return btf::fuzz::run([&] {
        const btf::bsvtf::TileGeometry geometry = btf::fuzz::tile_geometry(data[0]);
        const std::vector<float> prediction = btf::fuzz::tile_prediction(data[1], geometry);
        std::vector<uint16_t> out(size_t(geometry.values()));
        btf::bsvtf::decode_tile({data + 2, size - 2}, prediction, geometry, out);
    });
}

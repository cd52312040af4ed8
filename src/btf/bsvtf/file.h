// SPDX-License-Identifier: MIT
#pragma once
/// The BSVTF file (`btf bsvtf PKG -o OUT.bsvtf`): everything a BSVTF renderer or server needs,
/// from an fmf package. It is a btfkit package (io/package.h: checksummed sections) with codec
/// "bsvtf":
///
/// Header: "source", the fmf package's header (sampling, colour, model, its section list);
/// "bsvtf": {"width", "height", "tile", "pad", "levels", "groups": [[plane, first, count], …],
/// "step" (the tile codec's quantization step; 0 = lossless), "relative_error" (what it was chosen
/// for), "tiles" (count), "u_format" ("f16" when every angular factor is a half float, as in f16
/// packages, else "f32")}.
///
/// Sections, in this order:
/// - "tables" and "means": the fmf package's own (interpolation tables, row means);
/// - "tiles.index": per tile in TileLayout::index() order, 16 bytes little endian: float32 weight
///   w(i, l, l − 1) (equation 8), uint32 payload size, uint64 payload offset in "tiles";
/// - "u<g>" per group g: the angular factors of its components, the columns a(·, k) of
///   k = first … first + count − 1 one after the other, in u_format (the Eigen-ABRDFs, streamed
///   as packets of their own);
/// - "tiles": the tiles' payloads (tile_codec.h), back to back, coarsest level first.

#include <filesystem>
#include <string>
#include <vector>

#include "btf/bsvtf/pyramid.h"
#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/io/package.h"

namespace btf::bsvtf {

struct Bsvtf {
    /// The fmf model's angular part: its blocks have every component's a column and the means;
    /// b is empty (the tiles hold it).
    factor::Model model;
    TileLayout layout;
    float step = 0;
    double relative_error = 0;
    std::vector<float> weights;     ///< per tile
    std::vector<uint64_t> offsets;  ///< per tile, in `payloads`
    std::vector<uint32_t> sizes;
    std::vector<uint8_t> payloads;

    std::span<const uint8_t> payload(size_t tile) const {
        return {payloads.data() + offsets[tile], sizes[tile]};
    }
};

/// True when every angular factor of `model` is a half float (the factors of an f16 package):
/// the U packets are then half floats, else float32.
bool angular_factors_are_half(const factor::Model& model);

/// The BSVTF package of an fmf package, its model (factor::from_package), the model's pyramid
/// and the pyramid's encoding.
Package make_bsvtf(const Package& fmf, const factor::Model& model, const Pyramid& pyramid,
                   const EncodedPyramid& encoded, double relative_error);

/// Reads a BSVTF package; `what` names it in errors. Throws btf::Error for another codec, a
/// missing section or inconsistent sizes.
Bsvtf read_bsvtf(const Package& package, const std::string& what);

}  // namespace btf::bsvtf

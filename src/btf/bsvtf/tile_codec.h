// SPDX-License-Identifier: MIT
#pragma once
/// Transmission compression of BSVTF tiles (Schwartz et al. 2013, §6): a tile is sent as its
/// difference to the up-sampled parent that the receiver already holds, 8 × 8 DCT per channel,
/// coefficients quantized with one step for the whole material, deflated (libdeflate).
///
/// Error bound: the DCT is orthonormal and every coefficient is rounded to a multiple of `step`,
/// so the reconstruction of each 8 × 8 block of each channel is within an RMS error of step / 2
/// of the tile (before the final rounding to half floats). The encoder predicts each tile from
/// its parent as *decoded*, so errors do not add up from level to level. step = 0 is lossless:
/// the half-float bits, byte-shuffled and deflated.
///
/// Payload: byte 0 the format (1 = DCT, 2 = lossless), bytes 1–4 the step (float32, little
/// endian), bytes 5–8 the inflated size, then the deflate stream. DCT format: per channel, per
/// 8 × 8 block in row-major block order, 64 coefficients in zig-zag order as zig-zag-signed
/// LEB128 varints.

#include <cstdint>
#include <span>
#include <vector>

#include "btf/bsvtf/pyramid.h"
#include "btf/util/progress.h"

namespace btf::bsvtf {

/// Encodes one tile (geometry.values() half-float bits) against `prediction` (geometry.values()
/// floats: predict_child() of the decoded parent; empty for a tile without parent).
std::vector<uint8_t> encode_tile(std::span<const uint16_t> tile, std::span<const float> prediction,
                                 const TileGeometry& geometry, float step, int deflate_level = 9);

/// The inverse: writes geometry.values() half-float bits to `out`. Throws btf::Error for a
/// damaged payload.
void decode_tile(std::span<const uint8_t> payload, std::span<const float> prediction,
                 const TileGeometry& geometry, std::span<uint16_t> out);

/// Every tile of a pyramid encoded, parents before children, each against its decoded parent.
struct EncodedPyramid {
    float step = 0;
    std::vector<std::vector<uint8_t>> payloads;  ///< by Pyramid::index()
    std::vector<uint16_t> decoded;               ///< what a receiver reconstructs, all tiles
    uint64_t raw_bytes = 0;                      ///< tiles × values × 2
    uint64_t encoded_bytes = 0;
    /// RMS of (decoded − tile) over the texels of level 0 (the tiles' own, no padding), relative
    /// to the RMS of their values: the error the codec adds to the eigen-textures.
    double relative_rms_error = 0;
};

/// The step for a relative error: 2 · `relative_error` · RMS of the level-0 tile values, so that
/// the error the codec adds at level 0 is at most `relative_error` of the eigen-textures' RMS
/// (and, the angular factors being orthonormal, of the factorized BTF's energy about its mean).
float step_for(const Pyramid& pyramid, double relative_error);

EncodedPyramid encode_pyramid(const Pyramid& pyramid, float step, int deflate_level = 9,
                              Progress& progress = Progress::none());

}  // namespace btf::bsvtf

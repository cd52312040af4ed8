// SPDX-License-Identifier: MIT
#pragma once
/// The 8 × 8 DCT and the integer coding that btfkit's transform coders share (the BSVTF tile
/// codec, the coded factor storage): the orthonormal DCT-II in double, the zig-zag order, and
/// zig-zag-signed LEB128 varints. Every sum runs in a fixed order, so decoders written after
/// these functions (the viewer's) can reproduce them.

#include <cstdint>
#include <string_view>
#include <vector>

namespace btf::dct8 {

/// kZigZag[i]: the index (row · 8 + column) of the i-th coefficient in zig-zag order.
extern const int kZigZag[64];

/// out = the 2-D orthonormal DCT-II of the 8 × 8 block `in` (row-major), and its inverse.
void forward(const double in[64], double out[64]);
void inverse(const double in[64], double out[64]);

/// Appends v as a zig-zag-signed LEB128 varint.
void put_varint(std::vector<uint8_t>& out, int64_t v);
/// Reads one varint at p (advanced past it); throws btf::Error "<what>: …" when the bytes end
/// first or the number exceeds 64 bits.
int64_t get_varint(const uint8_t*& p, const uint8_t* end, std::string_view what);

}  // namespace btf::dct8

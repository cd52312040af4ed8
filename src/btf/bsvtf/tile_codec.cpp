// SPDX-License-Identifier: MIT
#include "btf/bsvtf/tile_codec.h"

#include <libdeflate.h>

#include <cmath>
#include <cstring>
#include <memory>

#include "btf/util/dct8.h"
#include "btf/util/error.h"
#include "btf/util/half.h"
#include "btf/util/parallel.h"

namespace btf::bsvtf {

namespace {

constexpr uint8_t kDct = 1, kLossless = 2;
constexpr size_t kHeader = 9;

std::vector<uint8_t> deflate(const std::vector<uint8_t>& raw, int level, uint8_t format,
                             float step) {
    std::unique_ptr<libdeflate_compressor, decltype(&libdeflate_free_compressor)> c(
        libdeflate_alloc_compressor(level), libdeflate_free_compressor);
    if (!c) throw std::bad_alloc();
    std::vector<uint8_t> out(kHeader + libdeflate_deflate_compress_bound(c.get(), raw.size()));
    out[0] = format;
    std::memcpy(&out[1], &step, 4);
    const uint32_t n = uint32_t(raw.size());
    std::memcpy(&out[5], &n, 4);
    const size_t size = libdeflate_deflate_compress(c.get(), raw.data(), raw.size(),
                                                    out.data() + kHeader, out.size() - kHeader);
    if (size == 0) throw Error("tile: deflate failed");
    out.resize(kHeader + size);
    return out;
}

// Prediction value i, or 0 without a parent.
float predicted(std::span<const float> prediction, size_t i) {
    return prediction.empty() ? 0.0f : prediction[i];
}

}  // namespace

std::vector<uint8_t> encode_tile(std::span<const uint16_t> tile, std::span<const float> prediction,
                                 const TileGeometry& geometry, float step, int deflate_level) {
    const size_t values = size_t(geometry.values());
    if (tile.size() != values || (!prediction.empty() && prediction.size() != values))
        throw Error("encode_tile: the tile or its prediction has the wrong size");
    std::vector<uint8_t> raw;
    if (step <= 0) {
        // Lossless: high bytes, then low bytes (the shuffle groups the similar exponents).
        raw.resize(values * 2);
        for (size_t i = 0; i < values; ++i) {
            raw[i] = uint8_t(tile[i] >> 8);
            raw[values + i] = uint8_t(tile[i] & 0xff);
        }
        return deflate(raw, deflate_level, kLossless, 0);
    }
    const int S = geometry.stride(), blocks = S / 8;
    raw.reserve(values);
    double block[64], coef[64];
    for (int c = 0; c < 4; ++c)
        for (int by = 0; by < blocks; ++by)
            for (int bx = 0; bx < blocks; ++bx) {
                for (int r = 0; r < 8; ++r)
                    for (int n = 0; n < 8; ++n) {
                        const size_t i =
                            (size_t(by * 8 + r) * size_t(S) + size_t(bx * 8 + n)) * 4 + size_t(c);
                        block[r * 8 + n] = double(from_half(tile[i])) - predicted(prediction, i);
                    }
                dct8::forward(block, coef);
                for (int k = 0; k < 64; ++k)
                    dct8::put_varint(raw, std::llround(coef[dct8::kZigZag[k]] / step));
            }
    return deflate(raw, deflate_level, kDct, step);
}

void decode_tile(std::span<const uint8_t> payload, std::span<const float> prediction,
                 const TileGeometry& geometry, std::span<uint16_t> out) {
    const size_t values = size_t(geometry.values());
    if (out.size() != values || (!prediction.empty() && prediction.size() != values))
        throw Error("decode_tile: the output or the prediction has the wrong size");
    if (payload.size() < kHeader) throw Error("tile: the payload is shorter than its header");
    const uint8_t format = payload[0];
    float step;
    uint32_t inflated;
    std::memcpy(&step, &payload[1], 4);
    std::memcpy(&inflated, &payload[5], 4);
    if (format != kDct && format != kLossless)
        throw Error(fmt::format("tile: unknown format {}", int(format)));
    if (inflated > values * 10) throw Error("tile: the inflated size is implausible");
    std::vector<uint8_t> raw(inflated);
    std::unique_ptr<libdeflate_decompressor, decltype(&libdeflate_free_decompressor)> d(
        libdeflate_alloc_decompressor(), libdeflate_free_decompressor);
    if (!d) throw std::bad_alloc();
    if (libdeflate_deflate_decompress(d.get(), payload.data() + kHeader, payload.size() - kHeader,
                                      raw.data(), raw.size(), nullptr) != LIBDEFLATE_SUCCESS)
        throw Error("tile: the deflate stream is damaged");
    if (format == kLossless) {
        if (inflated != values * 2) throw Error("tile: a lossless tile has the wrong size");
        for (size_t i = 0; i < values; ++i)
            out[i] = uint16_t(uint16_t(raw[i]) << 8 | raw[values + i]);
        return;
    }
    if (!(step > 0) || !std::isfinite(step)) throw Error("tile: the quantization step is invalid");
    const int S = geometry.stride(), blocks = S / 8;
    const uint8_t* p = raw.data();
    const uint8_t* end = p + raw.size();
    double coef[64], block[64];
    for (int c = 0; c < 4; ++c)
        for (int by = 0; by < blocks; ++by)
            for (int bx = 0; bx < blocks; ++bx) {
                for (int k = 0; k < 64; ++k)
                    coef[dct8::kZigZag[k]] = double(dct8::get_varint(p, end, "tile")) * step;
                dct8::inverse(coef, block);
                for (int r = 0; r < 8; ++r)
                    for (int n = 0; n < 8; ++n) {
                        const size_t i =
                            (size_t(by * 8 + r) * size_t(S) + size_t(bx * 8 + n)) * 4 + size_t(c);
                        out[i] = to_half(float(block[r * 8 + n] + predicted(prediction, i)));
                    }
            }
    if (p != end) throw Error("tile: bytes after the coefficients");
}

float step_for(const Pyramid& pyramid, double relative_error) {
    if (!(relative_error > 0)) return 0;
    const TileGeometry& g = pyramid.geometry();
    double sum = 0;
    uint64_t count = 0;
    for (size_t t = 0; t < pyramid.tile_count(); ++t) {
        const TileId id = pyramid.id(t);
        if (id.level != 0) continue;
        sum += pyramid.squared_sum(id);
        count += uint64_t(g.tile) * uint64_t(g.tile) * 4;
    }
    const double rms = count ? std::sqrt(sum / double(count)) : 0;
    return float(2 * relative_error * rms);
}

EncodedPyramid encode_pyramid(const Pyramid& pyramid, float step, int deflate_level,
                              Progress& progress) {
    const TileGeometry& g = pyramid.geometry();
    const size_t values = size_t(g.values());
    EncodedPyramid e;
    e.step = step;
    e.payloads.resize(pyramid.tile_count());
    e.decoded.resize(pyramid.tile_count() * values);
    progress.begin("compressing tiles", pyramid.tile_count());
    // Coarsest level first: a child is predicted from its parent as the receiver decodes it.
    for_each_level_coarsest_first(pyramid, [&](size_t t) {
        const TileId id = pyramid.id(t);
        std::vector<float> prediction;
        if (pyramid.has_parent(id)) {
            const size_t parent = pyramid.index(pyramid.parent(id));
            prediction = predict_child({e.decoded.data() + parent * values, values}, g, id);
        }
        e.payloads[t] = encode_tile(pyramid.tile(id), prediction, g, step, deflate_level);
        decode_tile(e.payloads[t], prediction, g, {e.decoded.data() + t * values, values});
        progress.advance();
    });
    progress.finish();
    double err = 0, energy = 0;
    for (size_t t = 0; t < pyramid.tile_count(); ++t) {
        e.encoded_bytes += e.payloads[t].size();
        if (pyramid.id(t).level != 0) continue;
        const std::span<const uint16_t> tile = pyramid.tile(pyramid.id(t));
        for (int y = g.pad; y < g.pad + g.tile; ++y)
            for (int x = g.pad; x < g.pad + g.tile; ++x)
                for (int c = 0; c < 4; ++c) {
                    const size_t i = (size_t(y) * size_t(g.stride()) + size_t(x)) * 4 + size_t(c);
                    const double v = from_half(tile[i]);
                    const double d = double(from_half(e.decoded[t * values + i])) - v;
                    err += d * d;
                    energy += v * v;
                }
    }
    e.raw_bytes = uint64_t(pyramid.tile_count()) * values * 2;
    e.relative_rms_error = energy > 0 ? std::sqrt(err / energy) : 0;
    return e;
}

}  // namespace btf::bsvtf

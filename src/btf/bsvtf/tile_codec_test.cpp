// SPDX-License-Identifier: MIT
// The BSVTF tile codec: lossless round trips, the DCT's error bound per 8 × 8 block, closed-loop
// prediction over a whole pyramid, the step for a relative error, and damaged payloads.

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cmath>
#include <random>

#include "btf/bsvtf/tile_codec.h"
#include "btf/codecs/codec.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"
#include "btf/util/half.h"

namespace btf::bsvtf {
namespace {

// The eigen-textures of a small synthetic material, fmf with 8 components in half floats.
const Pyramid& fabric() {
    static const Pyramid p = [] {
        const auto source = synth::make("woven_fabric", 64, test::ubo_subset(4, 5), 1);
        const Package package = find_codec("fmf").encode(
            *source, Params{{"components", "8"}, {"quantize", "f16"}}, Progress::none());
        return Pyramid::build(factor::from_package(package), {16, 4});
    }();
    return p;
}

TEST(TileCodec, LosslessRoundTripsEveryBit) {
    const Pyramid& p = fabric();
    const TileGeometry& g = p.geometry();
    std::vector<uint16_t> out(size_t(g.values()));
    for (size_t t = 0; t < p.tile_count(); t += 3) {
        const std::vector<uint8_t> payload = encode_tile(p.tile(p.id(t)), {}, g, 0);
        decode_tile(payload, {}, g, out);
        ASSERT_TRUE(std::equal(out.begin(), out.end(), p.tile(p.id(t)).begin())) << t;
    }
}

TEST(TileCodec, EachBlockIsWithinHalfAStepRms) {
    const Pyramid& p = fabric();
    const TileGeometry& g = p.geometry();
    const int S = g.stride();
    std::vector<uint16_t> out(size_t(g.values()));
    for (const float step : {0.002f, 0.02f, 0.2f}) {
        for (size_t t = 0; t < p.tile_count(); ++t) {
            const TileId id = p.id(t);
            std::vector<float> prediction;
            if (p.has_parent(id)) prediction = predict_child(p.tile(p.parent(id)), g, id);
            const std::vector<uint8_t> payload = encode_tile(p.tile(id), prediction, g, step);
            decode_tile(payload, prediction, g, out);
            const std::span<const uint16_t> tile = p.tile(id);
            for (int c = 0; c < 4; ++c)
                for (int by = 0; by < S / 8; ++by)
                    for (int bx = 0; bx < S / 8; ++bx) {
                        double sum = 0, largest = 0;
                        for (int y = by * 8; y < by * 8 + 8; ++y)
                            for (int x = bx * 8; x < bx * 8 + 8; ++x) {
                                const size_t i =
                                    (size_t(y) * size_t(S) + size_t(x)) * 4 + size_t(c);
                                const double d = double(from_half(out[i])) - from_half(tile[i]);
                                sum += d * d;
                                largest = std::max(largest, std::abs(double(from_half(tile[i]))));
                            }
                        // step / 2, plus the final rounding to half floats (2⁻¹¹ relative).
                        ASSERT_LE(std::sqrt(sum / 64), step / 2 + largest * std::ldexp(1.0, -11))
                            << "step " << step << ", tile " << t << ", channel " << c;
                    }
        }
    }
}

TEST(TileCodec, ThePyramidIsEncodedAgainstDecodedParentsWithinTheRequestedError) {
    const Pyramid& p = fabric();
    double previous_ratio = 0;
    for (const double relative : {0.002, 0.01, 0.05}) {
        const float step = step_for(p, relative);
        const EncodedPyramid e = encode_pyramid(p, step);
        EXPECT_LE(e.relative_rms_error, relative) << relative;
        EXPECT_GT(e.relative_rms_error, relative / 20) << "the codec uses far less than its budget";
        const double ratio = double(e.raw_bytes) / double(e.encoded_bytes);
        EXPECT_GT(ratio, previous_ratio) << "a larger error must compress more";
        previous_ratio = ratio;
        // What a receiver decodes from the payloads, parents first, is e.decoded.
        const TileGeometry& g = p.geometry();
        std::vector<uint16_t> received(e.decoded.size());
        for (int level = p.levels() - 1; level >= 0; --level)
            for (size_t t = 0; t < p.tile_count(); ++t) {
                const TileId id = p.id(t);
                if (id.level != level) continue;
                std::vector<float> prediction;
                if (p.has_parent(id)) {
                    const size_t parent = p.index(p.parent(id));
                    prediction = predict_child(
                        {received.data() + parent * size_t(g.values()), size_t(g.values())}, g, id);
                }
                decode_tile(e.payloads[t], prediction, g,
                            {received.data() + t * size_t(g.values()), size_t(g.values())});
            }
        EXPECT_EQ(received, e.decoded);
    }
    EXPECT_GT(previous_ratio, 4.0);
    // Lossless: every bit, and deflate alone gains something.
    const EncodedPyramid lossless = encode_pyramid(p, 0);
    EXPECT_EQ(lossless.relative_rms_error, 0);
    EXPECT_LT(lossless.encoded_bytes, lossless.raw_bytes);
}

TEST(TileCodec, DamagedPayloadsAreErrors) {
    const Pyramid& p = fabric();
    const TileGeometry& g = p.geometry();
    const TileId id = p.id(0);
    std::vector<uint16_t> out(size_t(g.values()));
    std::vector<uint8_t> payload = encode_tile(p.tile(id), {}, g, 0.01f);
    EXPECT_NE(test::error_of([&] {
                  decode_tile(std::span(payload).first(5), {}, g, out);
              }).find("shorter than its header"),
              std::string::npos);
    std::vector<uint8_t> bad = payload;
    bad[0] = 7;
    EXPECT_NE(test::error_of([&] { decode_tile(bad, {}, g, out); }).find("unknown format 7"),
              std::string::npos);
    bad = payload;
    bad.resize(bad.size() - 4);
    EXPECT_NE(test::error_of([&] { decode_tile(bad, {}, g, out); }).find("tile:"),
              std::string::npos);
    const TileGeometry other{8, 4};
    EXPECT_NE(test::error_of([&] { decode_tile(payload, {}, other, out); }).find("wrong size"),
              std::string::npos);
}

}  // namespace
}  // namespace btf::bsvtf

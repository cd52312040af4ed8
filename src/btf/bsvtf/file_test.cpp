// SPDX-License-Identifier: MIT
// The BSVTF file: what make_bsvtf writes, read_bsvtf reads back — the angular factors and means
// of the fmf package, the tile layout, the weights and the payloads — and its errors.

#include <gtest/gtest.h>

#include "btf/bsvtf/file.h"
#include "btf/codecs/codec.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf::bsvtf {
namespace {

struct Fixture {
    Package fmf;
    factor::Model model;
    Pyramid pyramid;
    EncodedPyramid encoded;
};

Fixture make(const std::string& quantize) {
    const auto source = synth::make("leather", 32, test::ubo_subset(3, 4), 2);
    Package fmf = find_codec("fmf").encode(
        *source, Params{{"components", "7"}, {"quantize", quantize}}, Progress::none());
    factor::Model model = factor::from_package(fmf);
    Pyramid pyramid = Pyramid::build(model, {8, 4});
    EncodedPyramid encoded = encode_pyramid(pyramid, step_for(pyramid, 0.02));
    return {std::move(fmf), std::move(model), std::move(pyramid), std::move(encoded)};
}

TEST(BsvtfFile, ReadsBackWhatWasWritten) {
    for (const std::string quantize : {"f16", "f32"}) {
        const Fixture f = make(quantize);
        Package written = make_bsvtf(f.fmf, f.model, f.pyramid, f.encoded, 0.02);
        const std::vector<uint8_t> bytes = encode_package(written);
        const Package package = decode_package(bytes, "x.bsvtf");
        EXPECT_EQ(package.header["bsvtf"]["u_format"], quantize == "f16" ? "f16" : "f32");
        const Bsvtf b = read_bsvtf(package, "x.bsvtf");
        // The angular part: every component's a, the means, the sampling.
        const factor::Block& want = f.model.blocks[0];
        const factor::Block& got = b.model.blocks[0];
        ASSERT_EQ(got.a.rows(), want.a.rows());
        ASSERT_EQ(got.a.cols(), 7);
        EXPECT_TRUE(got.a == want.a) << quantize;
        EXPECT_EQ(got.mean, want.mean);
        EXPECT_EQ(b.model.sampling.views.size(), f.model.sampling.views.size());
        // The tiles.
        EXPECT_EQ(b.layout.tile_count(), f.pyramid.tile_count());
        EXPECT_EQ(b.layout.levels(), f.pyramid.levels());
        EXPECT_EQ(b.layout.groups().size(), 2u);
        EXPECT_EQ(b.layout.groups()[1].count, 3);
        EXPECT_EQ(b.weights, f.pyramid.weights());
        EXPECT_EQ(b.step, f.encoded.step);
        for (size_t t = 0; t < b.layout.tile_count(); ++t) {
            const std::span<const uint8_t> p = b.payload(t);
            ASSERT_TRUE(std::equal(p.begin(), p.end(), f.encoded.payloads[t].begin(),
                                   f.encoded.payloads[t].end()))
                << t;
        }
        // Coarsest tiles first in the stream.
        EXPECT_EQ(b.offsets[b.layout.index({0, b.layout.levels() - 1, 0, 0})], 0u);
    }
}

TEST(BsvtfFile, TilesAreStoredRawForByteRanges) {
    const Fixture f = make("f16");
    Package written = make_bsvtf(f.fmf, f.model, f.pyramid, f.encoded, 0.02);
    PackageWriteOptions options;
    options.zstd_level = 19;
    const std::vector<uint8_t> bytes = encode_package(written, options);
    const Package package = decode_package(bytes, "x.bsvtf");
    const Bsvtf b = read_bsvtf(package, "x.bsvtf");
    const PackageSection& tiles = package.at("tiles");
    EXPECT_EQ(tiles.coding, SectionCoding::kRaw);
    // A tile's payload is at the file offset the header and the index give.
    const uint64_t start = bytes.size() - tiles.stored_size;  // the last section
    for (size_t t = 0; t < b.layout.tile_count(); t += 7)
        EXPECT_TRUE(std::equal(b.payload(t).begin(), b.payload(t).end(),
                               bytes.begin() + int64_t(start + b.offsets[t])))
            << t;
    EXPECT_EQ(package.at("tables").coding, SectionCoding::kZstd);  // the others as asked
}

TEST(BsvtfFile, ErrorsNameTheProblem) {
    const Fixture f = make("f16");
    EXPECT_NE(test::error_of([&] {
                  read_bsvtf(f.fmf, "m.btfpkg");
              }).find("m.btfpkg: a 'fmf' package, not a BSVTF"),
              std::string::npos);
    Package written = make_bsvtf(f.fmf, f.model, f.pyramid, f.encoded, 0.02);
    Package cut = written;
    cut.sections.erase(cut.sections.begin() + 3);  // u0
    EXPECT_NE(test::error_of([&] { read_bsvtf(cut, "m.bsvtf"); }).find("u0"), std::string::npos);
    Package bad = written;
    bad.sections[2].data.resize(bad.sections[2].data.size() - 16);  // tiles.index
    EXPECT_NE(test::error_of([&] { read_bsvtf(bad, "m.bsvtf"); }).find("tiles.index"),
              std::string::npos);
}

TEST(BsvtfFile, GroupsMustContinueTheirPlaneBeforeAnythingIsAllocated) {
    // A group's `first` of 4096 used to zero-fill rows × 4097 factors before any section was
    // checked (terabytes for a crafted direction set).
    const Fixture f = make("f16");
    const Package written = make_bsvtf(f.fmf, f.model, f.pyramid, f.encoded, 0.02);
    ASSERT_GE(written.header["bsvtf"]["groups"].size(), 2u);
    Package far = written;
    far.header["bsvtf"]["groups"][1][1] = 4096;
    EXPECT_NE(test::error_of([&] {
                  read_bsvtf(far, "m.bsvtf");
              }).find("m.bsvtf: group 1 [0, 4096, 3] does not continue plane 0 at component 4"),
              std::string::npos);
    Package overlap = written;
    overlap.header["bsvtf"]["groups"][1][1] = 2;
    EXPECT_NE(test::error_of([&] { read_bsvtf(overlap, "m.bsvtf"); }).find("does not continue"),
              std::string::npos);
}

}  // namespace
}  // namespace btf::bsvtf

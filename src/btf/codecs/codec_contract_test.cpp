// SPDX-License-Identifier: MIT
// What every codec in the registry promises, tested the same way for each (as a renderer tests
// every BSDF through one adapter): its package opens, re-reads from its bytes to the same
// material, and every clean prefix of it that opens is a material whose error does not grow as
// sections arrive; the full package is within a loose bound of the source.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "btf/codecs/codec.h"
#include "btf/codecs/material_source.h"
#include "btf/io/package.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/util/error.h"

namespace btf {
namespace {

// Small settings that still exercise each codec's structure (several groups, clusters, levels);
// factors in f32, so that what a further component adds is not hidden under the rounding of
// halves (the error then levels off at the halves' noise floor, in steps of either sign).
const std::map<std::string, Params>& small_settings() {
    static const std::map<std::string, Params> settings = {
        {"fmf", Params{{"components", "8"}, {"quantize", "f32"}}},
        {"pca-views", Params{{"components", "4"}, {"views-per-group", "2"}, {"quantize", "f32"}}},
        {"lpca", Params{{"clusters", "2"}, {"components", "3"}, {"quantize", "f32"}}},
        {"perceptual", Params{{"components", "8"}, {"quantize", "f32"}}},
        {"mlvq", Params{{"n-alpha", "5"}, {"n-beta", "5"}, {"n-theta-v", "3"}, {"n-phi-v", "4"}}},
    };
    return settings;
}

TEST(CodecContract, EveryCodecRoundTripsAndItsPrefixesImprove) {
    const auto source = test::cached(*synth::make("woven_fabric", 8, test::ubo_subset(6, 9), 2));
    for (const Codec* codec : codecs()) {
        const std::string name(codec->name());
        SCOPED_TRACE(name);
        ASSERT_TRUE(small_settings().count(name)) << "a new codec: give it small settings here";
        const Params& params = small_settings().at(name);
        EXPECT_NO_THROW(codec->validate(params));
        Package full = codec->encode(*source, params);
        const std::vector<uint8_t> bytes = encode_package(full);
        const Package reread = decode_package(bytes, name + ".btfpkg");
        EXPECT_EQ(reread.codec(), name);

        // The package's material, through the bytes or not, is the same.
        const double error = sample_rmse(*source, *codec->open(full));
        EXPECT_EQ(sample_rmse(*source, *open_material(reread)), error);
        EXPECT_LT(error, 0.25) << "far from the source";  // values are reflectances, ~0.1–1

        // Prefixes: each that opens is no worse than the one before it.
        double previous = INFINITY;
        int opened = 0;
        for (size_t n = 0; n <= reread.sections.size(); ++n) {
            Package prefix = reread;
            prefix.sections.resize(n);
            std::unique_ptr<Material> material;
            try {
                material = codec->open(prefix);
            } catch (const Error&) {
                EXPECT_EQ(opened, 0)
                    << "a longer prefix than one that opened was refused at " << n << " sections";
                continue;
            }
            const double e = sample_rmse(*source, *material);
            // Float evaluation: below ~1e-6 (values are ~0.1–1) the error is rounding alone.
            EXPECT_LE(e, previous + 1e-6) << n << " sections";
            previous = e;
            ++opened;
        }
        EXPECT_GE(opened, 2) << "no lower-quality prefix opens";
        EXPECT_EQ(previous, error);
    }
}

}  // namespace
}  // namespace btf

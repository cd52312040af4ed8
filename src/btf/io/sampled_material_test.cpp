// SPDX-License-Identifier: MIT
#include "btf/io/sampled_material.h"

#include <gtest/gtest.h>

#include <cmath>

#include "btf/core/image.h"
#include "btf/synth/synth.h"
#include "btf/util/error.h"

namespace btf {
namespace {

TEST(SampledMaterial, ReproducesTheSourceAtItsSamples) {
    const DirectionSet& ubo = DirectionSet::ubo81();
    const auto source = synth::make("leather", 8, {ubo, ubo}, 1);
    const SampledMaterial material(*source);
    EXPECT_EQ(material.width(), 8);
    EXPECT_EQ(material.sampling().num_views(), 81);
    Image image;
    for (const auto& [view, light] : {std::pair{0, 0}, {12, 40}, {80, 80}}) {
        source->read_image(view, light, image);
        for (int y = 0; y < 8; y += 3)
            for (int x = 0; x < 8; x += 3) {
                const Rgb s = image.rgb(x, y);
                const Rgb e = material.eval_sample(x, y, view, light);
                EXPECT_NEAR(e.g, s.g, 1e-3 * (1 + std::abs(s.g)));
                // At a texel centre and the sampled directions, interpolation returns the sample.
                const Rgb v = material.eval({(x + 0.5) / 8, (y + 0.5) / 8}, ubo.vector(light),
                                            ubo.vector(view));
                EXPECT_NEAR(v.r, e.r, 1e-5 * (1 + std::abs(e.r)));
                EXPECT_NEAR(v.b, e.b, 1e-5 * (1 + std::abs(e.b)));
            }
    }
}

TEST(SampledMaterial, RefusesWhatDoesNotFitTheMemoryLimit) {
    const DirectionSet& ubo = DirectionSet::ubo81();
    const auto source = synth::make("leather", 8, {ubo, ubo}, 1);
    try {
        SampledMaterial(*source, 1 << 20);
        FAIL() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("6561 images uncompressed takes"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace btf

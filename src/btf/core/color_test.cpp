#include "btf/core/color.h"

#include <gtest/gtest.h>

namespace btf {
namespace {

TEST(Color, SrgbTransferMatchesStandard) {
    EXPECT_FLOAT_EQ(srgb_to_linear(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(srgb_to_linear(1.0f), 1.0f);
    // IEC 61966-2-1: 0.5 encoded → 0.21404 linear; linear 0.0031308 is the breakpoint.
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.214041, 1e-5);
    EXPECT_NEAR(linear_to_srgb(0.0031308f), 0.04045, 1e-5);
    for (int i = 0; i <= 255; ++i) {
        const float e = i / 255.0f;
        EXPECT_NEAR(linear_to_srgb(srgb_to_linear(e)), e, 2e-6) << i;
    }
}

}  // namespace
}  // namespace btf

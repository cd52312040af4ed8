// SPDX-License-Identifier: MIT
#include "btf/core/color.h"

#include <gtest/gtest.h>

namespace btf {
namespace {

TEST(Color, SrgbTransferMatchesStandard) {
    EXPECT_FLOAT_EQ(srgb_to_linear(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(srgb_to_linear(1.0f), 1.0f);
    // IEC 61966-2-1: 0.5 encoded → 0.21404 linear; the linear segment ends at 0.04045 / 0.0031308.
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.214041, 1e-5);
    EXPECT_NEAR(srgb_to_linear(0.04045f), 0.0031308, 1e-6);
    EXPECT_NEAR(linear_to_srgb(0.0031308f), 0.04045, 1e-5);
    for (int i = 0; i <= 255; ++i) {
        const float e = i / 255.0f;
        EXPECT_NEAR(linear_to_srgb(srgb_to_linear(e)), e, 2e-6) << i;
    }
}

TEST(Color, WhiteMapsToD65) {
    const Xyz w = rgb_to_xyz({1, 1, 1});
    EXPECT_NEAR(w.x, 0.95047, 1e-4);
    EXPECT_NEAR(w.y, 1.00000, 1e-4);
    EXPECT_NEAR(w.z, 1.08883, 1e-4);
    const Lab lab = rgb_to_lab({1, 1, 1});
    EXPECT_NEAR(lab.l, 100.0, 1e-3);
    EXPECT_NEAR(lab.a, 0.0, 1e-2);
    EXPECT_NEAR(lab.b, 0.0, 1e-2);
}

// Reference CIELab values of the sRGB primaries (D65, 2° observer), as published by
// B. Lindbloom's colour calculator and reproduced by most colour libraries.
TEST(Color, LabOfPrimariesMatchesPublishedValues) {
    struct Case {
        Rgb rgb;
        Lab lab;
    };
    const Case cases[] = {
        {{1, 0, 0}, {53.2408, 80.0925, 67.2032}},
        {{0, 1, 0}, {87.7347, -86.1827, 83.1793}},
        {{0, 0, 1}, {32.2970, 79.1875, -107.8602}},
        {{0, 0, 0}, {0, 0, 0}},
    };
    for (const Case& c : cases) {
        const Lab lab = rgb_to_lab(c.rgb);
        EXPECT_NEAR(lab.l, c.lab.l, 2e-3);
        EXPECT_NEAR(lab.a, c.lab.a, 2e-3);
        EXPECT_NEAR(lab.b, c.lab.b, 2e-3);
    }
    // Mid grey: sRGB code 119/255 is close to L* = 50 (a commonly quoted check value).
    EXPECT_NEAR(rgb_to_lab({srgb_to_linear(119 / 255.0f), srgb_to_linear(119 / 255.0f),
                            srgb_to_linear(119 / 255.0f)})
                    .l,
                50.0, 0.2);
}

TEST(Color, LabRoundTrip) {
    for (float r : {0.0f, 0.001f, 0.2f, 0.7f, 1.0f})
        for (float g : {0.0f, 0.05f, 0.5f, 1.0f})
            for (float b : {0.0f, 0.008f, 0.3f, 1.0f}) {
                const Rgb back = lab_to_rgb(rgb_to_lab({r, g, b}));
                EXPECT_NEAR(back.r, r, 1e-5);
                EXPECT_NEAR(back.g, g, 1e-5);
                EXPECT_NEAR(back.b, b, 1e-5);
            }
}

TEST(Color, YCbCrBt601) {
    // ITU-R BT.601 full-range: red → Y 0.299, Cb −0.168736, Cr 0.5.
    const YCbCr red = rgb_to_ycbcr({1, 0, 0});
    EXPECT_NEAR(red.y, 0.299, 1e-6);
    EXPECT_NEAR(red.cb, -0.168736, 1e-6);
    EXPECT_NEAR(red.cr, 0.5, 1e-6);
    const YCbCr blue = rgb_to_ycbcr({0, 0, 1});
    EXPECT_NEAR(blue.cb, 0.5, 1e-6);
    const Rgb back = ycbcr_to_rgb(rgb_to_ycbcr({0.2f, 0.6f, 0.9f}));
    EXPECT_NEAR(back.r, 0.2, 1e-6);
    EXPECT_NEAR(back.g, 0.6, 1e-6);
    EXPECT_NEAR(back.b, 0.9, 1e-6);
}

TEST(Color, LogLuvOfD65WhiteAndRoundTrip) {
    // CIE 1976 UCS chromaticity of D65: u' = 0.1978, v' = 0.4683.
    const LogLuv w = rgb_to_logluv({1, 1, 1});
    EXPECT_NEAR(w.u, 0.1978, 1e-4);
    EXPECT_NEAR(w.v, 0.4683, 1e-4);
    EXPECT_NEAR(w.log_y, 0.0, 1e-4);
    const LogLuv bright = rgb_to_logluv({8, 8, 8});
    EXPECT_NEAR(bright.log_y, 3.0, 1e-4);
    for (Rgb c : {Rgb{0.3f, 0.2f, 0.1f}, Rgb{5.0f, 0.5f, 2.0f}, Rgb{0.01f, 0.02f, 0.5f}}) {
        const Rgb back = logluv_to_rgb(rgb_to_logluv(c));
        EXPECT_NEAR(back.r, c.r, 1e-4 * std::max(1.0f, c.r));
        EXPECT_NEAR(back.g, c.g, 1e-4 * std::max(1.0f, c.g));
        EXPECT_NEAR(back.b, c.b, 1e-4 * std::max(1.0f, c.b));
    }
}

TEST(Color, UboYuvMatchesBtflibInverse) {
    // FORMATS.md §7: RGB = [[1, 0, 1.13983], [1, −0.39465, −0.58060], [1, 2.03211, 0]] · YUV.
    const Rgb rgb = ubo_yuv_to_rgb({0.5f, 0.1f, -0.2f});
    EXPECT_NEAR(rgb.r, 0.5 + 1.13983 * -0.2, 1e-6);
    EXPECT_NEAR(rgb.g, 0.5 - 0.39465 * 0.1 - 0.58060 * -0.2, 1e-6);
    EXPECT_NEAR(rgb.b, 0.5 + 2.03211 * 0.1, 1e-6);
    for (Rgb c : {Rgb{0.3f, 0.2f, 0.1f}, Rgb{0.9f, 0.5f, 0.7f}, Rgb{0.0f, 0.0f, 0.0f}}) {
        const Rgb back = ubo_yuv_to_rgb(rgb_to_ubo_yuv(c));
        EXPECT_NEAR(back.r, c.r, 2e-4);
        EXPECT_NEAR(back.g, c.g, 2e-4);
        EXPECT_NEAR(back.b, c.b, 2e-4);
    }
}

TEST(Color, UboModel11) {
    // Model 11 stores (log(Y + eps), U/(Y + eps), V/(Y + eps)); black decodes to black.
    const auto black = rgb_to_ubo_model11({0, 0, 0});
    EXPECT_NEAR(black[0], std::log(kUboLogEps), 1e-6);
    const Rgb b = ubo_model11_to_rgb(black);
    EXPECT_NEAR(b.r, 0.0, 1e-6);
    for (Rgb c : {Rgb{0.3f, 0.2f, 0.1f}, Rgb{2.5f, 1.5f, 0.7f}, Rgb{0.01f, 0.011f, 0.012f}}) {
        const auto m = rgb_to_ubo_model11(c);
        const float y = rgb_to_ubo_yuv(c)[0];
        EXPECT_NEAR(m[0], std::log(y + kUboLogEps), 1e-5);
        const Rgb back = ubo_model11_to_rgb(m);
        EXPECT_NEAR(back.r, c.r, 3e-4 * std::max(1.0f, c.r));
        EXPECT_NEAR(back.g, c.g, 3e-4 * std::max(1.0f, c.g));
        EXPECT_NEAR(back.b, c.b, 3e-4 * std::max(1.0f, c.b));
    }
}

}  // namespace
}  // namespace btf

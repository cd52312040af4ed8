// SPDX-License-Identifier: MIT
#include "btf/quality/colormap.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "btf/core/color.h"
#include "btf/testing/xml.h"
#include "btf/util/error.h"

namespace btf::quality {
namespace {

using ::testing::HasSubstr;

double delta_e76(const Rgb& a, const Rgb& b) {
    const Lab x = rgb_to_lab(a), y = rgb_to_lab(b);
    return std::sqrt((x.l - y.l) * (x.l - y.l) + (x.a - y.a) * (x.a - y.a) +
                     (x.b - y.b) * (x.b - y.b));
}

TEST(Colormap, EndpointsAreDarkBlueAndLightYellow) {
    const Rgb low = colormap(0), high = colormap(1);
    EXPECT_NEAR(rgb_to_lab(low).l, kColormapLightness[0], 0.3);
    EXPECT_NEAR(rgb_to_lab(high).l, kColormapLightness[1], 0.3);
    EXPECT_GT(low.b, low.r);
    EXPECT_GT(low.b, low.g);
    EXPECT_GT(high.r, high.b);
    EXPECT_GT(high.g, high.b);
    // Out-of-range and NaN inputs clamp to the ends.
    const Rgb below = colormap(-3), above = colormap(7), nan = colormap(std::nan(""));
    EXPECT_EQ(below.r, low.r);
    EXPECT_EQ(below.b, low.b);
    EXPECT_EQ(above.g, high.g);
    EXPECT_EQ(nan.b, low.b);
}

TEST(Colormap, LightnessRisesLinearlyInsideTheGamut) {
    double previous = -1;
    for (int i = 0; i <= 200; ++i) {
        const double t = i / 200.0;
        const Rgb c = colormap(t);
        for (float v : {c.r, c.g, c.b}) {
            EXPECT_GE(v, 0.0f) << t;
            EXPECT_LE(v, 1.0f) << t;
        }
        const double l = rgb_to_lab(c).l;
        EXPECT_NEAR(l, kColormapLightness[0] + (kColormapLightness[1] - kColormapLightness[0]) * t,
                    0.5)
            << t;
        EXPECT_GT(l, previous) << t;
        previous = l;
    }
}

TEST(Colormap, StepsAreRoughlyEvenPerceptually) {
    // Ten equal steps of the value: no step is more than three times another (a rainbow map
    // fails this badly).
    double smallest = 1e9, largest = 0;
    for (int i = 0; i < 10; ++i) {
        const double d = delta_e76(colormap(i / 10.0), colormap((i + 1) / 10.0));
        smallest = std::min(smallest, d);
        largest = std::max(largest, d);
    }
    EXPECT_GT(smallest, 5.0);
    EXPECT_LT(largest / smallest, 3.0);
}

TEST(Colormap, SrgbHex) {
    EXPECT_EQ(srgb_hex({1, 1, 1}), "#ffffff");
    EXPECT_EQ(srgb_hex({0, 0, 0}), "#000000");
    EXPECT_EQ(srgb_hex({0.5f, 2.0f, -1.0f}), "#bcff00");  // sRGB(0.5) = 0.7354 → 188
}

TEST(Colormap, HeatMapColoursValuesOnTheScale) {
    const std::vector<float> values = {0.0f, 2.5f, 5.0f, 9.0f, 1.0f, 4.0f};
    const Image image = heat_map(values, 3, 2, 5.0);
    ASSERT_EQ(image.width(), 3);
    ASSERT_EQ(image.height(), 2);
    auto same = [](const Rgb& a, const Rgb& b) {
        return std::abs(a.r - b.r) < 1e-6f && std::abs(a.g - b.g) < 1e-6f &&
               std::abs(a.b - b.b) < 1e-6f;
    };
    EXPECT_TRUE(same(image.rgb(0, 0), colormap(0)));
    EXPECT_TRUE(same(image.rgb(1, 0), colormap(0.5)));
    EXPECT_TRUE(same(image.rgb(2, 0), colormap(1)));
    EXPECT_TRUE(same(image.rgb(0, 1), colormap(1)));  // above the scale: the top colour
    EXPECT_TRUE(same(image.rgb(2, 1), colormap(0.8)));
    EXPECT_THAT([&] { heat_map(values, 4, 2, 5.0); },
                testing::ThrowsMessage<Error>(HasSubstr("6 values for a 4×2 image")));
    EXPECT_THROW(heat_map(values, 3, 2, 0.0), Error);
}

TEST(Colormap, NiceCeil) {
    EXPECT_DOUBLE_EQ(nice_ceil(0.3), 0.5);
    EXPECT_DOUBLE_EQ(nice_ceil(2.2), 2.5);
    EXPECT_DOUBLE_EQ(nice_ceil(3.7), 5);
    EXPECT_DOUBLE_EQ(nice_ceil(7), 10);
    EXPECT_DOUBLE_EQ(nice_ceil(10), 10);
    EXPECT_DOUBLE_EQ(nice_ceil(0.012), 0.02);
    EXPECT_DOUBLE_EQ(nice_ceil(0), 1);
}

TEST(Colormap, ColorbarSvgStatesItsScale) {
    const std::string svg = colorbar_svg(5, "\u0394E00 <per texel>");
    const test::XmlDocument doc = test::parse_xml(svg);
    ASSERT_TRUE(doc.ok()) << doc.error << "\n" << svg;
    EXPECT_EQ(doc[0].name, "svg");
    const int ticks = doc.find_with("g", "class", "ticks");
    ASSERT_GE(ticks, 0);
    std::vector<std::string> values, labels;
    for (int t : doc.find("text", ticks)) {
        values.push_back(doc[t].attribute("data-value"));
        labels.push_back(doc[t].text);
    }
    EXPECT_EQ(values, (std::vector<std::string>{"0", "1", "2", "3", "4", "5"}));
    EXPECT_EQ(labels.back(), "\u2265 5");  // larger values are drawn in the top colour
    // The gradient runs from the map's bottom colour to its top colour.
    const std::vector<int> stops = doc.find("stop");
    ASSERT_GE(stops.size(), 2u);
    EXPECT_EQ(doc[stops.front()].attribute("stop-color"), srgb_hex(colormap(0)));
    EXPECT_EQ(doc[stops.back()].attribute("stop-color"), srgb_hex(colormap(1)));
    bool title = false;
    for (int t : doc.find("text")) title = title || doc[t].text == "\u0394E00 <per texel>";
    EXPECT_TRUE(title);
    EXPECT_THROW(colorbar_svg(0, "x"), Error);
}

}  // namespace
}  // namespace btf::quality

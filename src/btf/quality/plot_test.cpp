// SPDX-License-Identifier: MIT
#include "btf/quality/plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "btf/testing/xml.h"

namespace btf::quality {
namespace {

void expect_ticks(const AxisTicks& axis, const std::vector<double>& expected) {
    ASSERT_EQ(axis.ticks.size(), expected.size());
    for (size_t i = 0; i < expected.size(); ++i)
        EXPECT_NEAR(axis.ticks[i], expected[i], 1e-12 * std::max(1.0, std::abs(expected[i]))) << i;
    EXPECT_DOUBLE_EQ(axis.min, axis.ticks.front());
    EXPECT_DOUBLE_EQ(axis.max, axis.ticks.back());
}

TEST(Plot, LinearAxisOnNiceSteps) {
    expect_ticks(linear_axis(0, 1), {0, 0.2, 0.4, 0.6, 0.8, 1.0});
    expect_ticks(linear_axis(3, 97), {0, 20, 40, 60, 80, 100});
    expect_ticks(linear_axis(-0.3, 0.7), {-0.4, -0.2, 0, 0.2, 0.4, 0.6, 0.8});
    expect_ticks(linear_axis(21.3, 38.9), {20, 25, 30, 35, 40});
    // Reversed bounds are the same range; an empty range is widened around its value.
    expect_ticks(linear_axis(1, 0), {0, 0.2, 0.4, 0.6, 0.8, 1.0});
    expect_ticks(linear_axis(5, 5), {4.4, 4.6, 4.8, 5.0, 5.2, 5.4, 5.6});
    // The zero tick is exactly zero (no -0 or 1e-17 from accumulated steps).
    const AxisTicks a = linear_axis(-0.7, 0.9);
    bool zero = false;
    for (double t : a.ticks) zero = zero || t == 0.0;
    EXPECT_TRUE(zero);
}

TEST(Plot, LogAxisOnOneTwoFiveOrDecades) {
    expect_ticks(log_axis(0.03, 0.4), {0.02, 0.05, 0.1, 0.2, 0.5});
    expect_ticks(log_axis(0.25, 0.9), {0.2, 0.5, 1});
    expect_ticks(log_axis(0.001, 10), {0.001, 0.01, 0.1, 1, 10});
    // A single value sits between its neighbouring nice numbers.
    expect_ticks(log_axis(2, 2), {1, 2, 5});
    expect_ticks(log_axis(0.3, 0.3), {0.2, 0.5});
}

TEST(Plot, TickLabelsAreShort) {
    EXPECT_EQ(format_tick(0.1 + 0.2), "0.3");
    EXPECT_EQ(format_tick(0), "0");
    EXPECT_EQ(format_tick(12.5), "12.5");
    EXPECT_EQ(format_tick(1e-5), "1e-05");
    EXPECT_EQ(format_tick(-40), "-40");
}

TEST(Plot, XmlEscape) {
    EXPECT_EQ(xml_escape("a<b>&\"c\"'d'"), "a&lt;b&gt;&amp;&quot;c&quot;&#39;d&#39;");
    EXPECT_EQ(xml_escape("\u0394E00 plain"), "\u0394E00 plain");
}

// The text of every <text> inside the group of class `group`.
std::vector<std::string> texts_in(const test::XmlDocument& doc, const std::string& group) {
    std::vector<std::string> out;
    const int g = doc.find_with("g", "class", group);
    if (g < 0) return out;
    for (int t : doc.find("text", g)) out.push_back(doc[t].text);
    return out;
}

TEST(Plot, SvgIsWellFormedWithTicksSeriesAndLegend) {
    PlotOptions options;
    options.title = "PSNR <against> rate";
    options.x = {"bits per sample", true};
    options.y = {"PSNR (dB)", false};
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<PlotSeries> series = {
        {"fmf", {{1.0, 30, "components=16"}, {0.1, 20, "components=2"}, {0.5, inf, "lossless"}}},
        {"a<b&c", {{0.2, 25, ""}, {-1, 22, "x <= 0 on a log axis"}}},
    };
    const std::string svg = svg_line_plot(options, series);
    const test::XmlDocument doc = test::parse_xml(svg);
    ASSERT_TRUE(doc.ok()) << doc.error << "\n" << svg;
    EXPECT_EQ(doc[0].name, "svg");
    EXPECT_EQ(doc[0].attribute("xmlns"), "http://www.w3.org/2000/svg");
    EXPECT_EQ(doc[0].attribute("width"), "640");

    // Ticks: x is logarithmic over [0.1, 1] (1-2-5), y linear over [20, 30].
    EXPECT_EQ(texts_in(doc, "x-ticks"), (std::vector<std::string>{"0.1", "0.2", "0.5", "1"}));
    EXPECT_EQ(texts_in(doc, "y-ticks"),
              (std::vector<std::string>{"20", "22", "24", "26", "28", "30"}));

    // Title and labels round-trip through the escaping.
    bool title = false;
    for (int t : doc.find("text")) title = title || doc[t].text == "PSNR <against> rate";
    EXPECT_TRUE(title);
    EXPECT_EQ(doc[doc.find_with("text", "class", "x-label")].text, "bits per sample");

    // One group per series; unplottable points are left out, the others carry a tooltip.
    const int fmf = doc.find_with("g", "data-name", "fmf");
    const int other = doc.find_with("g", "data-name", "a<b&c");
    ASSERT_GE(fmf, 0);
    ASSERT_GE(other, 0);
    EXPECT_EQ(doc.find("title", fmf).size(), 2u);
    EXPECT_EQ(doc.find("title", other).size(), 1u);
    EXPECT_EQ(doc.find("polyline", fmf).size(), 1u);
    EXPECT_EQ(doc.find("polyline", other).size(), 0u);  // a single point draws no line

    // The marker of (0.1, 20) sits on the tick lines of 0.1 and 20: the first series' markers are
    // circles, and its points are drawn in order of x.
    const std::vector<int> circles = doc.find("circle", fmf);
    ASSERT_EQ(circles.size(), 2u);
    const int x_ticks = doc.find_with("g", "class", "x-ticks");
    const int y_ticks = doc.find_with("g", "class", "y-ticks");
    const std::vector<int> x_lines = doc.find("line", x_ticks);
    const std::vector<int> y_lines = doc.find("line", y_ticks);
    EXPECT_EQ(doc[circles[0]].attribute("cx"), doc[x_lines.front()].attribute("x1"));
    EXPECT_EQ(doc[circles[0]].attribute("cy"), doc[y_lines.front()].attribute("y1"));
    EXPECT_EQ(doc[circles[1]].attribute("cx"), doc[x_lines.back()].attribute("x1"));
    EXPECT_EQ(doc[circles[1]].attribute("cy"), doc[y_lines.back()].attribute("y1"));
    EXPECT_NE(doc[doc.find("title", circles[0])[0]].text.find("components=2"), std::string::npos);

    EXPECT_EQ(texts_in(doc, "legend"), (std::vector<std::string>{"fmf", "a<b&c"}));
}

TEST(Plot, EmptyPlotSaysSo) {
    PlotOptions options;
    options.x.log = true;
    const std::string svg = svg_line_plot(options, {{"none", {{0, 1, ""}}}});
    const test::XmlDocument doc = test::parse_xml(svg);
    ASSERT_TRUE(doc.ok()) << doc.error;
    bool message = false;
    for (int t : doc.find("text")) message = message || doc[t].text == "no data to plot";
    EXPECT_TRUE(message);
}

}  // namespace
}  // namespace btf::quality

// SPDX-License-Identifier: MIT
// The report's configuration parser, image selection, page and numbers, without encoding anything
// (report_test.cpp writes whole reports).

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "btf/quality/plot.h"
#include "btf/quality/report.h"
#include "btf/testing/xml.h"
#include "btf/util/error.h"

namespace btf::quality {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;
using Pairs = std::vector<std::pair<std::string, std::string>>;

TEST(ReportConfig, SweepsValuesOfOneParameter) {
    const std::vector<CodecConfig> configs = parse_codec_configs("fmf:C=8,16,32");
    ASSERT_EQ(configs.size(), 3u);
    for (const CodecConfig& c : configs) EXPECT_EQ(c.codec, "fmf");
    EXPECT_EQ(configs[0].params, (Pairs{{"components", "8"}}));
    EXPECT_EQ(configs[1].params, (Pairs{{"components", "16"}}));
    EXPECT_EQ(configs[2].params, (Pairs{{"components", "32"}}));
    EXPECT_EQ(configs[1].label(), "fmf components=16");
    EXPECT_EQ(configs[1].parameters_text(), "components=16");
    EXPECT_EQ(configs[1].to_params().get_int("components", 0, 1, 100), 16);
}

TEST(ReportConfig, AliasesAndSeveralParameters) {
    const std::vector<CodecConfig> configs = parse_codec_configs("pca-views:k=1,C=8");
    ASSERT_EQ(configs.size(), 1u);
    EXPECT_EQ(configs[0].codec, "pca-views");
    EXPECT_EQ(configs[0].params, (Pairs{{"views-per-group", "1"}, {"components", "8"}}));
    EXPECT_EQ(configs[0].parameters_text(), "views-per-group=1, components=8");

    // Spaces around items are ignored; the codec's own names work as well as the aliases.
    const std::vector<CodecConfig> same = parse_codec_configs(
        " pca-views : views-per-group=1 , "
        "components = 8");
    EXPECT_EQ(same, configs);
}

TEST(ReportConfig, CodecAloneUsesItsDefaults) {
    const std::vector<CodecConfig> configs = parse_codec_configs("lpca");
    ASSERT_EQ(configs.size(), 1u);
    EXPECT_EQ(configs[0].codec, "lpca");
    EXPECT_TRUE(configs[0].params.empty());
    EXPECT_EQ(configs[0].parameters_text(), "defaults");
    EXPECT_EQ(configs[0].label(), "lpca");
}

TEST(ReportConfig, CartesianProductFirstParameterSlowest) {
    const std::vector<CodecConfig> configs = parse_codec_configs("fmf:C=8,16,quantize=f16,u8");
    ASSERT_EQ(configs.size(), 4u);
    EXPECT_EQ(configs[0].params, (Pairs{{"components", "8"}, {"quantize", "f16"}}));
    EXPECT_EQ(configs[1].params, (Pairs{{"components", "8"}, {"quantize", "u8"}}));
    EXPECT_EQ(configs[2].params, (Pairs{{"components", "16"}, {"quantize", "f16"}}));
    EXPECT_EQ(configs[3].params, (Pairs{{"components", "16"}, {"quantize", "u8"}}));
}

TEST(ReportConfig, SeveralArgumentsInOrder) {
    const std::vector<CodecConfig> configs =
        parse_codec_configs(std::vector<std::string>{"fmf:C=4,8", "pca-views:k=1,C=8", "lpca"});
    ASSERT_EQ(configs.size(), 4u);
    EXPECT_EQ(configs[0].label(), "fmf components=4");
    EXPECT_EQ(configs[1].label(), "fmf components=8");
    EXPECT_EQ(configs[2].label(), "pca-views views-per-group=1 components=8");
    EXPECT_EQ(configs[3].label(), "lpca");
}

// The message of the btf::Error `text` raises.
std::string error_of(const std::string& text) {
    try {
        parse_codec_configs(text);
    } catch (const Error& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(ReportConfig, ErrorsNameTheProblemOnOneLine) {
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"nope:C=8", "unknown codec 'nope' (known: fmf, pca-views, lpca"},
        {"fmf:X=1", "codec fmf: unknown parameter 'X' (known: components, colour"},
        {"lpca:k=2", "codec lpca: unknown parameter 'k'"},  // the alias only where it applies
        {"fmf:8", "value '8' has no parameter"},
        {"fmf:C=8,components=16", "parameter components is given twice"},
        {"fmf:C=8,8", "parameter components: value 8 is given twice"},
        {"fmf:C=2,0", "parameter components: 0 is outside [1, 4096]"},  // before any encoding
        {"fmf:", "no parameters after ':'"},
        {"fmf:C=8,,16", "empty item"},
        {"fmf:=3", "parameter name missing"},
        {"fmf:C=", "parameter C: value missing"},
        {":C=8", "no codec name"},
    };
    for (const auto& [text, expected] : cases) {
        const std::string message = error_of(text);
        EXPECT_THAT(message, AllOf(HasSubstr("codec configuration '" + text + "'"),
                                   HasSubstr(expected), Not(HasSubstr("\n"))))
            << text;
    }
    EXPECT_THAT(
        [] {
            parse_codec_configs(std::vector<std::string>{"fmf:C=8", "fmf:C=4,8"});
        },
        testing::ThrowsMessage<Error>(HasSubstr("'fmf:C=4,8': fmf components=8 appears twice")));
    EXPECT_THROW(parse_codec_configs(std::vector<std::string>{}), Error);
}

TEST(ReportImages, NormalAndGrazingDirections) {
    const Sampling ubo{DirectionSet::ubo81(), DirectionSet::ubo81()};
    const std::vector<ReportImage> images = default_report_images(ubo);
    ASSERT_EQ(images.size(), 3u);
    EXPECT_EQ(images[0].label, "normal view, frontal light");
    EXPECT_NEAR(images[0].view_direction.theta_deg(), 0, 1e-6);
    EXPECT_NEAR(images[0].light_direction.theta_deg(), 0, 1e-6);
    EXPECT_EQ(images[1].label, "normal view, grazing light");
    EXPECT_NEAR(images[1].view_direction.theta_deg(), 0, 1e-6);
    EXPECT_NEAR(images[1].light_direction.theta_deg(), 75, 1e-6);
    EXPECT_NEAR(images[1].light_direction.phi_deg(), 0, 1e-6);
    EXPECT_EQ(images[2].label, "grazing view, frontal light");
    EXPECT_NEAR(images[2].view_direction.theta_deg(), 75, 1e-6);
    EXPECT_NEAR(images[2].light_direction.theta_deg(), 0, 1e-6);
    for (const ReportImage& image : images) {
        EXPECT_NEAR(ubo.views[image.view].theta, image.view_direction.theta, 1e-12);
        EXPECT_NEAR(ubo.lights[image.light].theta, image.light_direction.theta, 1e-12);
    }

    // A single view: no separate grazing view.
    const Sampling one{DirectionSet("one", {Direction{}}), DirectionSet::ubo81()};
    EXPECT_EQ(default_report_images(one).size(), 2u);
}

// A report as write_report() would fill it, for the page alone.
Report sample_report() {
    Report r;
    r.reference.name = "<script>alert('x')</script> & co";
    r.reference.format = "synthetic";
    r.reference.width = 16;
    r.reference.height = 16;
    r.reference.views = 3;
    r.reference.lights = 4;
    r.reference.view_set = "views";
    r.reference.light_set = "lights";
    r.reference.raw_8bit_bytes = 16 * 16 * 12 * 3;
    r.images = {{0, 0, "normal view, frontal light", {}, {}},
                {0, 3, "normal view, grazing light", {}, Direction::from_degrees(30, 0)}};
    r.crop_width = r.crop_height = 8;
    r.btf_cielab = true;
    r.generator = "btfkit test";
    r.command_line = "btf report in.h5 --codecs 'fmf:C=2,4' -o <out>";
    for (int i = 0; i < 3; ++i) {
        ConfigResult c;
        c.config = i < 2 ? CodecConfig{"fmf", {{"components", std::to_string(2 << i)}}}
                         : CodecConfig{"lpca", {{"seed", "<7>"}}};
        c.id = "0" + std::to_string(i + 1) + "-x";
        c.bytes = 1000u * (i + 1);
        c.bits_per_sample = 8.0 * c.bytes / (256 * 12);
        c.ratio = r.reference.raw_8bit_bytes / c.bytes;
        c.metrics.rmse = 0.02 / (i + 1);
        c.metrics.psnr = 30 + i;
        c.metrics.ssim_luminance = 0.9 + 0.01 * i;
        BtfCielabResult cielab;
        cielab.values = {{{10, 2}, 1.5 - 0.1 * i, 0.1, 1.6}, {{100, 10}, 2.5 - 0.1 * i, 0.2, 2.7}};
        cielab.worst = 1;
        c.cielab = cielab;
        for (size_t k = 0; k < r.images.size(); ++k)
            c.images.push_back({"images/a.png", "images/b.png", 1.0, 2.0});
        r.configs.push_back(c);
    }
    return r;
}

TEST(ReportPage, WellFormedEscapedWithOneRowPerConfiguration) {
    const Report report = sample_report();
    const std::string html = report_html(report);
    const test::XmlDocument doc = test::parse_xml(html);
    ASSERT_TRUE(doc.ok()) << doc.error;
    EXPECT_EQ(doc[0].name, "html");
    // Names are text, never markup.
    EXPECT_TRUE(doc.find("script").empty());
    EXPECT_EQ(doc[doc.find("title")[0]].text, "Compression report: " + report.reference.name);
    EXPECT_EQ(doc[doc.find("h1")[0]].text, "Compression report: " + report.reference.name);
    EXPECT_THAT(html, Not(HasSubstr("<out>")));
    EXPECT_THAT(html, HasSubstr("-o &lt;out&gt;"));

    const int table = doc.find_with("table", "id", "results");
    ASSERT_GE(table, 0);
    const std::vector<int> rows = doc.find("tr", doc.find("tbody", table)[0]);
    ASSERT_EQ(rows.size(), 3u);
    const std::vector<int> cells = doc.find("td", rows[2]);
    ASSERT_EQ(cells.size(), 13u);
    EXPECT_EQ(doc[cells[1]].text, "lpca");
    EXPECT_EQ(doc[cells[2]].text, "seed=<7>");
    EXPECT_EQ(doc[cells[8]].text, "32.00");                                 // PSNR
    EXPECT_THAT(doc[cells[12]].text, HasSubstr("2.30at 100°/s, 10 px/°"));  // worst condition
    // The best of a column is marked: the smallest package, the highest PSNR.
    EXPECT_EQ(doc[doc.find("td", rows[0])[3]].attribute("class"), "best");
    EXPECT_EQ(doc[doc.find("td", rows[2])[3]].attribute("class"), "");
    EXPECT_EQ(doc[cells[8]].attribute("class"), "best");

    // Pictures: both plots, and per selected image one row per configuration plus a colour bar.
    std::vector<std::string> sources;
    for (int img : doc.find("img")) sources.push_back(doc[img].attribute("src"));
    EXPECT_EQ(std::count(sources.begin(), sources.end(), "rd-psnr.svg"), 1);
    EXPECT_EQ(std::count(sources.begin(), sources.end(), "rd-de2000.svg"), 1);
    EXPECT_EQ(std::count(sources.begin(), sources.end(), "rd-btf-cielab.svg"), 1);
    EXPECT_EQ(std::count(sources.begin(), sources.end(), "colorbar-1.svg"), 1);
    EXPECT_EQ(std::count(sources.begin(), sources.end(), "colorbar-2.svg"), 1);
    EXPECT_EQ(std::count(sources.begin(), sources.end(), "images/b.png"), 6);
    // A 16-texel heat map is shown enlarged by a whole factor, without smoothing.
    const int heat = doc.find_with("img", "src", "images/b.png");
    EXPECT_EQ(doc[heat].attribute("width"), "192");
    EXPECT_EQ(doc[heat].attribute("class"), "pixels");
    // No network: nothing refers outside the folder.
    for (const auto& element : doc.elements)
        for (const char* key : {"src", "href"})
            EXPECT_THAT(element.attribute(key), Not(HasSubstr(":"))) << element.name;
    EXPECT_TRUE(doc.find("link").empty());
    EXPECT_THAT(html, Not(HasSubstr("<script")));
    EXPECT_THAT(html, HasSubstr("view \u03b8 0\u00b0, \u03c6 0\u00b0"));
    EXPECT_THAT(html, HasSubstr("light \u03b8 30\u00b0, \u03c6 0\u00b0"));
}

TEST(ReportPage, JsonAndPlots) {
    const Report report = sample_report();
    const nlohmann::json j = report_json(report);
    EXPECT_EQ(j["generator"], "btfkit report");
    ASSERT_EQ(j["configs"].size(), 3u);
    EXPECT_EQ(j["configs"][2]["params"]["seed"], "<7>");
    EXPECT_DOUBLE_EQ(j["configs"][1]["btf_cielab"]["mean"].get<double>(), 2.4);
    EXPECT_DOUBLE_EQ(j["configs"][1]["btf_cielab"]["angular_speed"].get<double>(), 100);

    const test::XmlDocument psnr = test::parse_xml(rate_distortion_svg(report, RdMeasure::kPsnr));
    ASSERT_TRUE(psnr.ok()) << psnr.error;
    const int fmf = psnr.find_with("g", "data-name", "fmf");
    const int lpca = psnr.find_with("g", "data-name", "lpca");
    ASSERT_GE(fmf, 0);
    ASSERT_GE(lpca, 0);
    EXPECT_EQ(psnr.find("title", fmf).size(), 2u);
    EXPECT_EQ(psnr.find("title", lpca).size(), 1u);
    EXPECT_EQ(psnr.find("polyline", fmf).size(), 1u);

    // Mean CIEDE2000: every configuration has it, so the same series as PSNR.
    const test::XmlDocument de = test::parse_xml(rate_distortion_svg(report, RdMeasure::kDe2000));
    ASSERT_TRUE(de.ok()) << de.error;
    EXPECT_EQ(de.find("title", de.find_with("g", "data-name", "fmf")).size(), 2u);
    EXPECT_EQ(de.find("title", de.find_with("g", "data-name", "lpca")).size(), 1u);

    Report without = report;
    without.configs[2].cielab.reset();
    const test::XmlDocument cielab =
        test::parse_xml(rate_distortion_svg(without, RdMeasure::kBtfCielab));
    ASSERT_TRUE(cielab.ok()) << cielab.error;
    EXPECT_GE(cielab.find_with("g", "data-name", "fmf"), 0);
    EXPECT_LT(cielab.find_with("g", "data-name", "lpca"), 0);
}

}  // namespace
}  // namespace btf::quality

// SPDX-License-Identifier: MIT
// Whole reports of a tiny synthetic material: files, table, pictures, atomic output.

#include "btf/quality/report.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "btf/core/image.h"
#include "btf/io/package.h"
#include "btf/quality/colormap.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/xml.h"
#include "btf/util/error.h"

namespace btf::quality {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string read_text(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// Names in `folder` that start with '.' (temporary report folders).
std::vector<std::string> hidden_entries(const fs::path& folder) {
    std::vector<std::string> out;
    for (const auto& entry : fs::directory_iterator(folder)) {
        const std::string name = entry.path().filename().string();
        if (!name.empty() && name[0] == '.') out.push_back(name);
    }
    return out;
}

class WriteReport : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        s_source = test::cached(*synth::make("woven_fabric", 16, test::ubo_subset(3, 4), 1));
    }
    static void TearDownTestSuite() { s_source.reset(); }

    void SetUp() override {
        m_dir = fs::path(testing::TempDir()) /
                fmt::format("report_test_{}_{}", ::getpid(),
                            testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(m_dir);
        fs::create_directories(m_dir);
    }
    void TearDown() override { fs::remove_all(m_dir); }

    ReportOptions options(const std::string& name) const {
        ReportOptions o;
        o.configs = parse_codec_configs("fmf:C=1,6");
        o.output = m_dir / name;
        o.crop = 8;
        o.cielab.grid = 2;
        o.generator = "btfkit test";
        o.command_line = "btf report synthetic --codecs fmf:C=1,6";
        return o;
    }

    static std::unique_ptr<BtfSource> s_source;
    fs::path m_dir;
};
std::unique_ptr<BtfSource> WriteReport::s_source;

TEST_F(WriteReport, WritesEveryPartForTwoConfigurations) {
    const ReportOptions opts = options("report");
    const Report report = write_report(*s_source, opts);
    const fs::path dir = m_dir / "report";
    EXPECT_EQ(report.folder, dir);
    for (const char* name :
         {"index.html", "report.json", "rd-psnr.svg", "rd-de2000.svg", "rd-btf-cielab.svg",
          "colorbar-1.svg", "colorbar-2.svg", "colorbar-3.svg"})
        EXPECT_TRUE(fs::is_regular_file(dir / name)) << name;
    EXPECT_TRUE(hidden_entries(m_dir).empty());

    // Three selected images (normal view: frontal and grazing light; grazing view).
    ASSERT_EQ(report.images.size(), 3u);
    ASSERT_EQ(report.configs.size(), 2u);
    const int texels = 16 * 16, images = 3 * 4;
    for (const ConfigResult& c : report.configs) {
        ASSERT_FALSE(c.package.empty());
        ASSERT_TRUE(fs::is_regular_file(dir / c.package)) << c.package;
        EXPECT_EQ(fs::file_size(dir / c.package), c.bytes);
        EXPECT_EQ(read_package(dir / c.package).codec(), "fmf");
        EXPECT_DOUBLE_EQ(c.bits_per_sample, 8.0 * double(c.bytes) / (texels * images));
        EXPECT_DOUBLE_EQ(c.ratio, double(texels) * images * 3 / double(c.bytes));
        EXPECT_GT(c.encode_seconds, 0);
        EXPECT_GT(c.metrics.rmse, 0);
        EXPECT_GT(c.metrics.psnr, 10);
        EXPECT_GT(c.metrics.ssim_luminance, 0);
        EXPECT_LE(c.metrics.ssim_luminance, 1);
        ASSERT_TRUE(c.cielab.has_value());
        EXPECT_EQ(c.cielab->values.size(), 4u);  // the 2 × 2 grid
        ASSERT_EQ(c.images.size(), 3u);
        for (const ConfigImage& ci : c.images) {
            const Image crops = read_image(dir / ci.crops);
            EXPECT_EQ(crops.width(), 3 * 8 + 2 * 4) << ci.crops;
            EXPECT_EQ(crops.height(), 8) << ci.crops;
            const Image heat = read_image(dir / ci.heat_map);
            EXPECT_EQ(heat.width(), 16) << ci.heat_map;
            EXPECT_EQ(heat.height(), 16) << ci.heat_map;
            EXPECT_GE(ci.de2000_max, ci.de2000_mean);
        }
    }
    // More components: larger package, smaller error.
    EXPECT_GT(report.configs[1].bytes, report.configs[0].bytes);
    EXPECT_LT(report.configs[1].metrics.rmse, report.configs[0].metrics.rmse);
    EXPECT_LT(report.configs[1].metrics.de2000_mean, report.configs[0].metrics.de2000_mean);
    EXPECT_LT(report.configs[1].images[0].de2000_mean, report.configs[0].images[0].de2000_mean);
    // One heat-map scale per selected image, a nice number above its errors, on its colour bar.
    ASSERT_EQ(report.heat_max.size(), 3u);
    for (size_t k = 0; k < 3; ++k) {
        EXPECT_EQ(nice_ceil(report.heat_max[k]), report.heat_max[k]);
        for (const ConfigResult& c : report.configs)
            EXPECT_GT(report.heat_max[k], c.images[k].de2000_mean);
        const test::XmlDocument bar =
            test::parse_xml(read_text(dir / fmt::format("colorbar-{}.svg", k + 1)));
        ASSERT_TRUE(bar.ok()) << bar.error;
        const std::vector<int> ticks = bar.find("text", bar.find_with("g", "class", "ticks"));
        ASSERT_FALSE(ticks.empty());
        EXPECT_EQ(std::stod(bar[ticks.back()].attribute("data-value")), report.heat_max[k]);
    }
    // The crop window is the centre of the image.
    EXPECT_EQ(report.crop_x, 4);
    EXPECT_EQ(report.crop_y, 4);

    // The page: one table row per configuration, naming codec and parameters.
    const test::XmlDocument page = test::parse_xml(read_text(dir / "index.html"));
    ASSERT_TRUE(page.ok()) << page.error;
    const int table = page.find_with("table", "id", "results");
    ASSERT_GE(table, 0);
    const std::vector<int> rows = page.find("tr", page.find("tbody", table)[0]);
    ASSERT_EQ(rows.size(), 2u);
    for (int r = 0; r < 2; ++r) {
        const std::vector<int> cells = page.find("td", rows[size_t(r)]);
        ASSERT_EQ(cells.size(), 13u);
        EXPECT_EQ(page[cells[1]].text, "fmf");
        EXPECT_EQ(page[cells[2]].text, r == 0 ? "components=1" : "components=6");
    }
    // Every picture the page shows is in the folder.
    for (int img : page.find("img"))
        EXPECT_TRUE(fs::is_regular_file(dir / page[img].attribute("src")))
            << page[img].attribute("src");
    EXPECT_THAT(read_text(dir / "index.html"), HasSubstr(opts.command_line));

    // The numbers, for scripts.
    const nlohmann::json j = nlohmann::json::parse(read_text(dir / "report.json"));
    EXPECT_EQ(j["generator"], "btfkit report");
    ASSERT_EQ(j["configs"].size(), 2u);
    EXPECT_EQ(j["configs"][0]["bytes"].get<uint64_t>(), report.configs[0].bytes);

    // Plots: one series (one codec) with both configurations.
    const test::XmlDocument plot = test::parse_xml(read_text(dir / "rd-psnr.svg"));
    ASSERT_TRUE(plot.ok()) << plot.error;
    const int series = plot.find_with("g", "data-name", "fmf");
    ASSERT_GE(series, 0);
    EXPECT_EQ(plot.find("title", series).size(), 2u);
}

TEST_F(WriteReport, RendersTheReferenceAndEveryConfiguration) {
    // A "render" that looks at the material from one direction per pixel row: enough to see that
    // the section compares each package's material with the uncompressed reference.
    ReportOptions opts = options("rendered");
    opts.btf_cielab = false;
    int calls = 0;
    opts.render = [&calls](const Material& material, Progress&) {
        ++calls;
        ReportRender r;
        r.image = Image(12, 6, 3);
        for (int y = 0; y < 6; ++y)
            for (int x = 0; x < 12; ++x)
                r.image.set_rgb(x, y,
                                material.eval({(x + 0.5) / 12, 0.3},
                                              Direction::from_degrees(10.0 * y, 40).vector(),
                                              Direction::from_degrees(20, 0).vector()));
        r.caption = "grid of evaluations";
        return r;
    };
    const Report report = write_report(*s_source, opts);
    const fs::path dir = m_dir / "rendered";
    EXPECT_EQ(calls, 3);  // the reference and two configurations
    EXPECT_EQ(report.render_caption, "grid of evaluations");
    EXPECT_TRUE(fs::is_regular_file(dir / report.render_reference));
    EXPECT_TRUE(fs::is_regular_file(dir / "colorbar-render.svg"));
    ASSERT_TRUE(report.configs[0].render && report.configs[1].render);
    for (const ConfigResult& c : report.configs) {
        EXPECT_EQ(read_image(dir / c.render->image).width(), 12);
        EXPECT_EQ(read_image(dir / c.render->heat_map).width(), 12);
    }
    // Six components reproduce the reference better than one.
    EXPECT_LT(report.configs[1].render->de2000_mean, report.configs[0].render->de2000_mean);
    EXPECT_GT(report.configs[1].render->ssim, report.configs[0].render->ssim);
    const std::string html = read_text(dir / "index.html");
    EXPECT_NE(html.find("<h2 id=\"renders\">Rendered</h2>"), std::string::npos);
    EXPECT_NO_THROW(test::parse_xml(html));
}

TEST_F(WriteReport, RefusesFoldersItDidNotWrite) {
    ReportOptions opts = options("mine");
    opts.btf_cielab = false;
    opts.configs = parse_codec_configs("fmf:C=2");
    fs::create_directories(opts.output);
    { std::ofstream(opts.output / "notes.txt") << "keep me"; }
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("folder exists and is not empty")));
    opts.force = true;
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("not a btfkit report folder")));
    EXPECT_EQ(read_text(opts.output / "notes.txt"), "keep me");
    // A report.json that btf report did not write does not make a folder a report.
    { std::ofstream(opts.output / "report.json") << R"({"generator": "someone else"})"; }
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("not a btfkit report folder")));
    EXPECT_EQ(read_text(opts.output / "notes.txt"), "keep me");

    // A file of that name, or a missing parent folder.
    { std::ofstream(m_dir / "file") << "x"; }
    opts.output = m_dir / "file";
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("is not a folder")));
    opts.output = m_dir / "missing" / "report";
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("does not exist")));
    EXPECT_TRUE(hidden_entries(m_dir).empty());
}

TEST_F(WriteReport, ReplacesAnEarlierReportOnlyWithForce) {
    ReportOptions opts = options("report/");  // a trailing slash names the same folder
    opts.btf_cielab = false;
    opts.keep_packages = false;
    opts.configs = parse_codec_configs("fmf:C=2");
    fs::create_directories(m_dir / "report");  // an empty folder is fine
    const Report first = write_report(*s_source, opts);
    EXPECT_EQ(first.folder, m_dir / "report");
    EXPECT_FALSE(fs::exists(m_dir / "report" / "packages"));
    EXPECT_TRUE(first.configs[0].package.empty());
    EXPECT_FALSE(fs::exists(m_dir / "report" / "rd-btf-cielab.svg"));

    opts.configs = parse_codec_configs("fmf:C=3");
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("--force")));
    opts.force = true;
    write_report(*s_source, opts);
    const nlohmann::json j = nlohmann::json::parse(read_text(m_dir / "report" / "report.json"));
    EXPECT_EQ(j["configs"][0]["params"]["components"], "3");
    EXPECT_TRUE(hidden_entries(m_dir).empty());
}

TEST_F(WriteReport, FailureOrCancelLeavesNothing) {
    // The second configuration's value is refused by the codec, after the first was measured.
    ReportOptions opts = options("report");
    opts.btf_cielab = false;
    // (parse_codec_configs refuses 0 already; the list is built by hand to reach the encoder.)
    opts.configs = parse_codec_configs("fmf:C=2");
    opts.configs.push_back(opts.configs.front());
    opts.configs.back().params = {{"components", "0"}};
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("fmf components=0: parameter components")));
    EXPECT_FALSE(fs::exists(m_dir / "report"));
    EXPECT_TRUE(hidden_entries(m_dir).empty());

    opts.configs = parse_codec_configs("fmf:C=2");
    Progress progress([&](std::string_view stage, uint64_t, uint64_t) {
        if (stage.find("comparing") != std::string_view::npos) progress.cancel();
    });
    EXPECT_THROW(write_report(*s_source, opts, progress), Cancelled);
    EXPECT_FALSE(fs::exists(m_dir / "report"));
    EXPECT_TRUE(hidden_entries(m_dir).empty());
}

TEST_F(WriteReport, ProgressHasOneStagePerConfigurationStep) {
    ReportOptions opts = options("report");
    opts.btf_cielab = false;
    std::vector<std::string> stages;
    Progress progress([&](std::string_view stage, uint64_t, uint64_t) {
        if (stages.empty() || stages.back() != stage) stages.emplace_back(stage);
    });
    write_report(*s_source, opts, progress);
    auto has = [&](const std::string& text) {
        return std::find(stages.begin(), stages.end(), text) != stages.end();
    };
    EXPECT_TRUE(has("1/2 fmf components=1: comparing")) << testing::PrintToString(stages);
    EXPECT_TRUE(has("2/2 fmf components=6: comparing"));
    EXPECT_TRUE(has("2/2 fmf components=6: error images"));
    EXPECT_TRUE(has("writing the report"));
}

TEST_F(WriteReport, ChosenImagesAndBadOptions) {
    ReportOptions opts = options("report");
    opts.btf_cielab = false;
    opts.configs = parse_codec_configs("fmf:C=2");
    opts.images = {{2, 1, "", {}, {}}};
    opts.crop = 100;  // larger than the image: the whole image
    opts.heat_max = 3;
    const Report report = write_report(*s_source, opts);
    ASSERT_EQ(report.images.size(), 1u);
    EXPECT_EQ(report.images[0].label, "view 2, light 1");
    EXPECT_NEAR(report.images[0].view_direction.theta, s_source->sampling().views[2].theta, 1e-12);
    EXPECT_EQ(report.heat_max, std::vector<double>{3});
    const Image crops = read_image(m_dir / "report" / report.configs[0].images[0].crops);
    EXPECT_EQ(crops.width(), 3 * 16 + 8);
    EXPECT_EQ(crops.height(), 16);

    opts.output = m_dir / "other";
    opts.images = {{3, 0, "", {}, {}}};
    EXPECT_THAT([&] { write_report(*s_source, opts); },
                testing::ThrowsMessage<Error>(HasSubstr("(view 3, light 0) outside 3 views")));
    EXPECT_FALSE(fs::exists(m_dir / "other"));
}

}  // namespace
}  // namespace btf::quality

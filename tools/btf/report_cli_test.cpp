// SPDX-License-Identifier: MIT
// End-to-end tests of `btf report`: what a user types, what they get back.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "btf/testing/cli.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test::CliResult;
using test::run;

std::string read_text(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

class ReportCli : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        s_dir = fs::path(testing::TempDir()) / ("report_cli_test_" + std::to_string(::getpid()));
        fs::remove_all(s_dir);
        fs::create_directories(s_dir);
    }
    static void TearDownTestSuite() { fs::remove_all(s_dir); }
    static std::string path(const std::string& name) { return (s_dir / name).string(); }
    static fs::path s_dir;
};
fs::path ReportCli::s_dir;

TEST_F(ReportCli, BadArgumentsGiveOneLineBeforeOpeningTheInput) {
    // The input does not exist: the configuration is refused first.
    CliResult r = run("report " + path("missing.h5") + " --codecs fmf:C=4 nope -o " + path("r"));
    EXPECT_EQ(r.code, 1);
    EXPECT_THAT(r.output, HasSubstr("codec configuration 'nope': unknown codec 'nope' (known: "));
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;

    r = run("report " + path("missing.h5") + " --codecs fmf:Q=4 -o " + path("r"));
    EXPECT_EQ(r.code, 1);
    EXPECT_THAT(r.output, HasSubstr("codec fmf: unknown parameter 'Q' (known: components"));

    fs::create_directories(path("full"));
    { std::ofstream(path("full/keep.txt")) << "mine"; }
    r = run("report " + path("missing.h5") + " --codecs fmf -o " + path("full"));
    EXPECT_EQ(r.code, 1);
    EXPECT_THAT(r.output, HasSubstr("--force"));
    r = run("report " + path("missing.h5") + " --codecs fmf --force -o " + path("full"));
    EXPECT_EQ(r.code, 1);
    EXPECT_THAT(r.output, HasSubstr("not a btfkit report folder"));
    EXPECT_EQ(read_text(path("full/keep.txt")), "mine");

    r = run("report " + path("missing.h5") + " --codecs fmf --image 0,0 -o " + path("r"));
    EXPECT_EQ(r.code, 1);
    EXPECT_THAT(r.output, HasSubstr("--image: expected"));
    EXPECT_FALSE(fs::exists(path("r")));

    // --no-btf-cielab and --btf-cielab-grid contradict each other.
    r = run("report x --codecs fmf --no-btf-cielab --btf-cielab-grid 2 -o " + path("r"));
    EXPECT_NE(r.code, 0);
}

TEST_F(ReportCli, WritesTheReportAndSaysWhere) {
    const std::string input = path("fabric.h5");
    ASSERT_EQ(
        run("synth --preset woven_fabric --size 16 --sampling ubo81 --seed 2 -o " + input).code, 0);
    const std::string out = path("report");
    const CliResult r = run("report " + input +
                            " --views 0,1,7 --codecs fmf:C=2,4 pca-views:k=1,C=2 "
                            "--btf-cielab-grid 1 --crop 8 --image 0,0:60,0 -o " +
                            out + "/");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("fmf components=2: "));
    EXPECT_THAT(r.output, HasSubstr("pca-views views-per-group=1 components=2: "));
    EXPECT_THAT(r.output, HasSubstr("report: " + out + "/index.html"));
    EXPECT_THAT(r.output, HasSubstr("BTF-CIELab"));
    for (const char* name : {"index.html", "report.json", "rd-psnr.svg", "rd-btf-cielab.svg"})
        EXPECT_TRUE(fs::is_regular_file(fs::path(out) / name)) << name;

    const nlohmann::json j = nlohmann::json::parse(read_text(fs::path(out) / "report.json"));
    // "btfkit <version>", and " (git <commit>)" when built from a checkout.
    EXPECT_THAT(j["version"].get<std::string>(),
                ::testing::StartsWith("btfkit " BTF_PROJECT_VERSION));
    EXPECT_EQ(j["reference"]["views"], 3);
    EXPECT_EQ(j["reference"]["lights"], 81);
    ASSERT_EQ(j["configs"].size(), 3u);
    ASSERT_EQ(j["images"].size(), 1u);
    EXPECT_EQ(j["images"][0]["view"], 0);
    EXPECT_THAT(j["command"].get<std::string>(), HasSubstr("--codecs fmf:C=2,4 pca-views:k=1,C=2"));
    EXPECT_THAT(read_text(fs::path(out) / "index.html"), HasSubstr("--image 0,0:60,0"));

    // Again into the same folder: refused, then replaced with --force.
    CliResult again =
        run("report " + input + " --views 0 --codecs fmf:C=2 --no-btf-cielab -o " + out);
    EXPECT_EQ(again.code, 1);
    again =
        run("report " + input + " --views 0 --codecs fmf:C=2 --no-btf-cielab --force -o " + out);
    ASSERT_EQ(again.code, 0) << again.output;
    EXPECT_FALSE(fs::exists(fs::path(out) / "rd-btf-cielab.svg"));
}

}  // namespace
}  // namespace btf

// SPDX-License-Identifier: MIT
// End-to-end tests of `btf quality`: what a user types, what they get back.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "btf/testing/cli.h"

namespace btf {
namespace {

namespace fs = std::filesystem;

using test::CliResult;
using test::run;

// Two 16² materials and an 8² one on a 7-direction set (49 images each), made once.
class QualityCli : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        s_dir = fs::path(testing::TempDir()) / ("quality_cli_test_" + std::to_string(::getpid()));
        fs::remove_all(s_dir);
        fs::create_directories(s_dir);
        std::ofstream(path("dirs.txt")) << "0 0\n30 0\n30 120\n30 240\n60 60\n60 180\n60 300\n";
        const std::string common = " --size 16 --sampling " + path("dirs.txt");
        for (const auto& [name, args] :
             {std::pair<std::string, std::string>{"a.h5", common + " --seed 1"},
              {"b.h5", common + " --seed 2"},
              {"small.h5", " --size 8 --sampling " + path("dirs.txt")}}) {
            const CliResult r = run("synth --preset leather" + args + " -o " + path(name));
            ASSERT_EQ(r.code, 0) << r.output;
        }
    }
    static void TearDownTestSuite() { fs::remove_all(s_dir); }
    static std::string path(const std::string& name) { return (s_dir / name).string(); }
    static fs::path s_dir;
};
fs::path QualityCli::s_dir;

// The value column of a table row ("name  value").
std::string row_value(const std::string& output, const std::string& name) {
    std::smatch match;
    if (!std::regex_search(output, match, std::regex("\n" + name + " +([^\n]*)"))) return "";
    return match[1];
}

TEST_F(QualityCli, IdenticalInputsShowNoErrorInTheTable) {
    const CliResult r = run("quality " + path("a.h5") + " " + path("a.h5"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("16 x 16 texels, 7 views x 7 lights, unweighted"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("\nmetric "), std::string::npos) << r.output;
    EXPECT_EQ(row_value(r.output, "RMSE"), "0 (linear RGB)") << r.output;
    // The synthetic material is HDR: the peak is its largest value.
    EXPECT_TRUE(
        std::regex_match(row_value(r.output, "PSNR"), std::regex(R"(inf dB \(peak 0\.\d+\))")))
        << r.output;
    for (const char* name :
         {"MAE L\\*", "MAE a\\*", "MAE b\\*", "dE2000 mean", "dE2000 p95", "dE2000 max"})
        EXPECT_EQ(row_value(r.output, name), "0") << name << "\n" << r.output;
    for (const char* name : {"MSSIM luminance", "MSSIM Y", "MSSIM Cr", "MSSIM Cb"})
        EXPECT_EQ(row_value(r.output, name), "1") << name << "\n" << r.output;
    // Aligned: every value starts in the same column.
    const size_t column =
        r.output.find("0 (linear RGB)") - r.output.rfind('\n', r.output.find("RMSE")) - 1;
    EXPECT_EQ(r.output.find("inf dB") - r.output.rfind('\n', r.output.find("PSNR")) - 1, column);
}

TEST_F(QualityCli, JsonHasEverySelectedMeasure) {
    CliResult r = run("quality --json --cos-weight " + path("a.h5") + " " + path("b.h5"));
    ASSERT_EQ(r.code, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(r.output);
    EXPECT_EQ(j["width"], 16);
    EXPECT_EQ(j["images"], 49);
    EXPECT_EQ(j["cos_weighted"], true);
    const double peak = j["peak"].get<double>();
    EXPECT_GT(peak, 0.1);
    EXPECT_LT(peak, 1.0);
    EXPECT_GT(j["rmse"].get<double>(), 0.0);
    EXPECT_NEAR(j["psnr"].get<double>(), 20 * std::log10(peak / j["rmse"].get<double>()), 1e-9);
    for (const char* key : {"L", "a", "b"}) EXPECT_GT(j["lab_mae"][key].get<double>(), 0.0) << key;
    EXPECT_GT(j["de2000"]["mean"].get<double>(), 0.0);
    EXPECT_GE(j["de2000"]["p95"].get<double>(), j["de2000"]["mean"].get<double>());
    EXPECT_GE(j["de2000"]["max"].get<double>(), j["de2000"]["p95"].get<double>());
    EXPECT_EQ(j["de2000"]["p95_bin_width"], 0.01);
    for (const char* key : {"luminance", "Y", "Cr", "Cb"}) {
        EXPECT_GT(j["ssim"][key].get<double>(), 0.0) << key;
        EXPECT_LT(j["ssim"][key].get<double>(), 1.0) << key;
    }

    // Only what --metrics names; identical inputs have no finite PSNR (null).
    r = run("quality --json --metrics rmse --peak 2 " + path("a.h5") + " " + path("a.h5"));
    ASSERT_EQ(r.code, 0) << r.output;
    const nlohmann::json k = nlohmann::json::parse(r.output);
    EXPECT_EQ(k["peak"], 2.0);
    EXPECT_EQ(k["rmse"], 0.0);
    EXPECT_TRUE(k["psnr"].is_null());
    EXPECT_FALSE(k.contains("ssim"));
    EXPECT_FALSE(k.contains("de2000"));
}

TEST_F(QualityCli, PackageAgainstItsSourceMatchesCompressRmse) {
    const std::string package = path("b.btfpkg");
    CliResult r = run("compress " + path("b.h5") + " -o " + package + " --components 2");
    ASSERT_EQ(r.code, 0) << r.output;
    std::smatch match;
    ASSERT_TRUE(std::regex_search(r.output, match, std::regex("RMSE ([0-9.e+-]+)"))) << r.output;
    const double compress_rmse = std::stod(match[1]);
    r = run("quality --json --metrics rmse,ssim " + path("b.h5") + " " + package);
    ASSERT_EQ(r.code, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(r.output);
    EXPECT_NEAR(j["rmse"].get<double>(), compress_rmse, 0.0051 * compress_rmse);
    EXPECT_LT(j["ssim"]["luminance"].get<double>(), 1.0);
}

TEST_F(QualityCli, MismatchedInputsAndBadOptionsFailWithOneLine) {
    CliResult r = run("quality " + path("a.h5") + " " + path("small.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("a.h5 vs "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("small.h5: extent 16×16 vs 8×8 texels"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;

    r = run("quality --metrics rmse,psnr " + path("a.h5") + " " + path("b.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--metrics: unknown metric 'psnr'"), std::string::npos) << r.output;
    r = run("quality --grid 3 " + path("a.h5") + " " + path("b.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--grid and --search apply to btf-cielab"), std::string::npos)
        << r.output;
    r = run("quality --metrics btf-cielab --peak 2 " + path("a.h5") + " " + path("b.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--cos-weight and --peak apply to"), std::string::npos) << r.output;
    r = run("quality " + path("a.h5") + " " + path("missing.h5"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("missing.h5: no such file or folder"), std::string::npos) << r.output;
}

TEST_F(QualityCli, BtfCielabHeadlineNamesItsViewingCondition) {
    CliResult r = run("quality --metrics btf-cielab --grid 2 " + path("a.h5") + " " + path("b.h5"));
    ASSERT_EQ(r.code, 0) << r.output;
    for (const char* name : {"BTF-CIELab mean", "BTF-CIELab stddev", "BTF-CIELab rms"})
        EXPECT_FALSE(row_value(r.output, name).empty()) << name << "\n" << r.output;
    EXPECT_TRUE(
        std::regex_search(row_value(r.output, "BTF-CIELab at"),
                          std::regex("^ω = [0-9.e+]+ °/s, r_s = [0-9.e+]+ px/deg \\(grid\\)$")))
        << r.output;
    EXPECT_TRUE(row_value(r.output, "RMSE").empty()) << r.output;

    r = run("quality --json --metrics btf-cielab,rmse --grid 2 " + path("a.h5") + " " +
            path("b.h5"));
    ASSERT_EQ(r.code, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(r.output);
    EXPECT_GT(j["rmse"].get<double>(), 0.0);
    const nlohmann::json& c = j["btf_cielab"];
    EXPECT_EQ(c["conditions"].size(), 4u);
    EXPECT_EQ(c["searched"], false);
    EXPECT_GE(c["rms"].get<double>(), c["mean"].get<double>());
    for (const char* key : {"mean", "stddev", "rms", "angular_speed", "resolution"})
        EXPECT_TRUE(c[key].is_number()) << key;
}

}  // namespace
}  // namespace btf

// SPDX-License-Identifier: MIT
// End-to-end tests of `btf bsvtf`: an fmf package becomes a BSVTF file with a summary line of
// sizes and error; other inputs give one line, exit 1 and no output file.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "btf/bsvtf/file.h"
#include "btf/io/package.h"
#include "btf/testing/cli.h"
#include "btf/testing/support.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using test::run;

TEST(BsvtfCli, PreprocessesAnFmfPackage) {
    const test::TempFolder dir("bsvtf_cli");
    const std::string h5 = (dir.path() / "m.h5").string(), pkg = (dir.path() / "m.btfpkg").string();
    ASSERT_EQ(run("synth --preset woven_fabric --size 64 -o " + h5).code, 0);
    test::CliResult r = run("compress " + h5 + " --codec fmf --components 6 --no-error -o " + pkg);
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string out = (dir.path() / "m.bsvtf").string();
    r = run("bsvtf " + pkg + " -o " + out + " --tile 16 --tile-error 0.02");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("64 × 64 texels, 2 groups of 4 components, 3 levels of 16 × 16 tiles "
                            "(+4 padding): 42 tiles"),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("compressed ("), std::string::npos) << r.output;
    const bsvtf::Bsvtf b = bsvtf::read_bsvtf(read_package(out), out);
    EXPECT_EQ(b.layout.tile_count(), 42u);
    EXPECT_DOUBLE_EQ(b.relative_error, 0.02);
    r = run("info " + out);
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("btfkit BSVTF"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("42: 3 levels of 16 × 16 texels + 4 padding"), std::string::npos)
        << r.output;

    r = run("bsvtf " + pkg + " -o " + out + " --tile 16 --lossless");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("lossless"), std::string::npos) << r.output;
    EXPECT_EQ(bsvtf::read_bsvtf(read_package(out), out).step, 0.0f);
}

// The three numbers `btf eval` prints.
std::array<double, 3> rgb_of(const test::CliResult& r) {
    std::array<double, 3> rgb{-1, -1, -1};
    EXPECT_EQ(std::sscanf(r.output.c_str(), "%lf %lf %lf", &rgb[0], &rgb[1], &rgb[2]), 3)
        << r.output;
    return rgb;
}

TEST(BsvtfCli, AFileIsAMaterialForEveryCommand) {
    const test::TempFolder dir("bsvtf_material_cli");
    const auto at = [&](const std::string& name) { return (dir.path() / name).string(); };
    ASSERT_EQ(run("synth --preset woven_fabric --size 32 -o " + at("m.h5")).code, 0);
    test::CliResult r = run("compress " + at("m.h5") +
                            " --codec fmf --components 6 --no-error -o " + at("m.btfpkg"));
    ASSERT_EQ(r.code, 0) << r.output;
    r = run("bsvtf " + at("m.btfpkg") + " -o " + at("m.bsvtf") + " --tile 16 --lossless");
    ASSERT_EQ(r.code, 0) << r.output;

    // Lossless tiles: the package's value up to the half floats the tiles hold.
    for (const char* query : {" --uv 0.3,0.7 --light 30,40 --view 20,200",
                              " --uv -1.9,4.25 --light 60,300 --view 45,10"}) {
        const test::CliResult fmf = run("eval " + at("m.btfpkg") + query);
        const test::CliResult tiles = run("eval " + at("m.bsvtf") + query);
        ASSERT_EQ(fmf.code, 0) << fmf.output;
        ASSERT_EQ(tiles.code, 0) << tiles.output;
        const auto want = rgb_of(fmf), got = rgb_of(tiles);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(got[c], want[c], 2e-3 * std::max(std::abs(want[c]), 0.01)) << query;
    }

    r = run("--quiet decompress " + at("m.bsvtf") + " -o " + at("d.h5"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(fs::exists(at("d.h5")));

    r = run("quality " + at("m.btfpkg") + " " + at("m.bsvtf") + " --metrics rmse --json");
    ASSERT_EQ(r.code, 0) << r.output;
    const nlohmann::json quality = nlohmann::json::parse(r.output);
    EXPECT_LT(quality.at("rmse").get<double>(), 1e-3) << r.output;

    std::ofstream(at("scene.json")) << R"({
      "camera": {"position": [0, 1, 3], "look_at": [0, 0.3, 0], "width": 24, "height": 16},
      "render": {"integrator": "direct", "spp": 1},
      "objects": [{"shape": "sphere", "radius": 0.5, "position": [0, 0.4, 0],
                   "material": {"type": "btf", "file": "m.bsvtf"}}],
      "lights": [{"type": "directional", "direction": [1, 2, 1], "irradiance": 3}]
    })";
    r = run("--quiet render " + at("scene.json") + " --compare " + at("m.btfpkg") + " " +
            at("m.bsvtf") + " -o " + at("cmp.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("ΔE00 mean 0.0"), std::string::npos) << r.output;
    r = run("--quiet render " + at("scene.json") + " -o " + at("one.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(fs::exists(at("one.png")));
}

TEST(BsvtfCli, RefusesOtherInputsWithOneLine) {
    const test::TempFolder dir("bsvtf_cli");
    const std::string h5 = (dir.path() / "m.h5").string(), pca = (dir.path() / "p.btfpkg").string();
    ASSERT_EQ(run("synth --preset leather --size 16 -o " + h5).code, 0);
    ASSERT_EQ(run("compress " + h5 + " --codec pca-views --components 2 --no-error -o " + pca).code,
              0);
    const std::string out = (dir.path() / "o.bsvtf").string();
    test::CliResult r = run("bsvtf " + pca + " -o " + out);
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("p.btfpkg: a 'pca-views' package: btf bsvtf needs an fmf package"),
              std::string::npos)
        << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(out));
    r = run("bsvtf " + h5 + " -o " + out);
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("m.h5"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
    // 36 × 36 texels in tiles of 8: 4 levels, so width and height must be divisible by 8.
    ASSERT_EQ(run("synth --preset leather --size 36 -o " + h5).code, 0);
    const std::string fmf = (dir.path() / "f.btfpkg").string();
    ASSERT_EQ(run("compress " + h5 + " --codec fmf --components 2 --no-error -o " + fmf).code, 0);
    r = run("bsvtf " + fmf + " -o " + out + " --tile 8");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("f.btfpkg: 36 × 36 texels"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("must be divisible by 8"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
}

TEST(BsvtfCli, SimulatesAPathAndLogsEveryFrame) {
    const test::TempFolder dir("bsvtf_sim_cli");
    const auto at = [&](const std::string& name) { return (dir.path() / name).string(); };
    ASSERT_EQ(run("synth --preset leather --size 32 -o " + at("m.h5")).code, 0);
    ASSERT_EQ(run("compress " + at("m.h5") + " --codec fmf --components 4 --no-error -o " +
                  at("m.btfpkg"))
                  .code,
              0);
    test::write_file(dir.path() / "scene.json", R"({
      "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 48, "height": 32},
      "objects": [{"shape": "sphere", "material": {"type": "btf", "file": "m.btfpkg"}}],
      "lights": [{"type": "directional", "direction": [0, 1, 1], "irradiance": 2}]})");
    test::write_file(dir.path() / "path.json", R"({"frames": 5, "keys": [
      {"frame": 0, "position": [0, 0, 3], "look_at": [0, 0, 0]},
      {"frame": 4, "position": [0, 0, 2], "look_at": [0, 0, 0]}]})");
    test::CliResult r = run("bsvtf-sim --scene " + at("scene.json") + " --path " + at("path.json") +
                            " --cache 288 --tile 16 --bandwidth 4mbit --log " + at("log.csv") +
                            " --frames " + at("frames") + " --plot " + at("ssim.svg"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("1 materials (preprocessing"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("memory: tile cache 144 tiles"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("SSIM against full FMF: mean"), std::string::npos) << r.output;
    const std::string log = test::read_file(dir.path() / "log.csv");
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 6) << log;  // header + 5 frames
    EXPECT_EQ(log.rfind("frame,time_s,bytes,", 0), 0u) << log;
    EXPECT_TRUE(fs::exists(dir.path() / "frames" / "frame-0004.png"));
    const std::string svg = test::read_file(dir.path() / "ssim.svg");
    EXPECT_NE(svg.find("<svg"), std::string::npos);
    EXPECT_NE(svg.find("MiB received"), std::string::npos);

    r = run("bsvtf-sim --scene " + at("scene.json") + " --path " + at("path.json") +
            " --bandwidth fast");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--bandwidth 'fast'"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace btf

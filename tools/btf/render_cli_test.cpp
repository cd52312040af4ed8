// SPDX-License-Identifier: MIT
// End-to-end tests of `btf render`: a scene with a compressed material renders to PNG and EXR;
// bad scenes give one line, a non-zero exit and no image; --material stands in for every BTF
// material; every scene in examples/scenes renders. And `btf image-diff`.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "btf/core/image.h"
#include "btf/quality/render_compare.h"
#include "btf/testing/cli.h"

namespace btf {
namespace {

namespace fs = std::filesystem;
using test::CliResult;
using test::run;

class RenderCli : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        s_dir = fs::path(testing::TempDir()) / ("render_cli_test_" + std::to_string(::getpid()));
        fs::remove_all(s_dir);
        fs::create_directories(s_dir);
    }
    static void TearDownTestSuite() { fs::remove_all(s_dir); }
    static std::string path(const std::string& name) { return (s_dir / name).string(); }
    static void write(const std::string& name, const std::string& text) {
        std::ofstream(path(name)) << text;
    }
    static fs::path s_dir;
};
fs::path RenderCli::s_dir;

TEST_F(RenderCli, RendersACompressedMaterialOnShapes) {
    ASSERT_EQ(run("synth --preset leather --size 8 -o " + path("m.h5")).code, 0);
    CliResult r =
        run("compress " + path("m.h5") + " --codec fmf --components 4 -o " + path("m.btfpkg"));
    ASSERT_EQ(r.code, 0) << r.output;
    write("scene.json", R"({
      "camera": {"position": [0, 1, 3], "look_at": [0, 0.3, 0], "fov": 40, "width": 32, "height": 24},
      "render": {"integrator": "direct", "spp": 2},
      "objects": [
        {"shape": "sphere", "radius": 0.4, "position": [-0.5, 0.4, 0], "uv_scale": 2,
         "material": {"type": "btf", "file": "m.btfpkg"}},
        {"shape": "cylinder", "radius": 0.3, "height": 0.8, "position": [0.5, 0.4, 0],
         "material": {"type": "btf", "file": "m.btfpkg"}},
        {"shape": "plane", "width": 4, "depth": 4, "material": {"type": "diffuse"}}
      ],
      "lights": [{"type": "environment", "sky": {"width": 64}}]
    })");
    r = run("--quiet render " + path("scene.json") + " -o " + path("out.png") + " --aov");
    ASSERT_EQ(r.code, 0) << r.output;
    const Image png = read_image(path("out.png"));
    EXPECT_EQ(png.width(), 32);
    EXPECT_EQ(png.height(), 24);
    EXPECT_GT(*std::max_element(png.values().begin(), png.values().end()), 0.05f);
    for (const char* aov : {"out.albedo.exr", "out.normal.exr", "out.uv.exr"})
        EXPECT_TRUE(fs::exists(path(aov))) << aov;

    r = run("--quiet render " + path("scene.json") + " -o " + path("out.exr") +
            " --integrator path --spp 1 --size 16,12");
    ASSERT_EQ(r.code, 0) << r.output;
    const Image exr = read_image(path("out.exr"));
    EXPECT_EQ(exr.width(), 16);
    EXPECT_EQ(exr.height(), 12);
}

TEST_F(RenderCli, StochasticAndDeterministicFilteringConvergeToOneImage) {
    // Filtering after shading is unbiased: the two renders' means agree (fmf rgb decodes
    // linearly), and the scene's "filter" key and --filter choose it.
    ASSERT_EQ(run("synth --preset ceramic_tiles --size 8 -o " + path("f.h5")).code, 0);
    CliResult r =
        run("compress " + path("f.h5") + " --codec fmf --components 4 -o " + path("f.btfpkg"));
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string scene = R"({
      "camera": {"position": [0, 1, 3], "look_at": [0, 0.3, 0], "fov": 40, "width": 24, "height": 16},
      "render": {"integrator": "direct", "spp": 256, "filter": "FILTER"},
      "objects": [{"shape": "sphere", "radius": 0.6, "position": [0, 0.4, 0], "uv_scale": 3,
                   "material": {"type": "btf", "file": "f.btfpkg"}}],
      "lights": [{"type": "directional", "direction": [1, 2, 1], "irradiance": 3}]
    })";
    const auto with = [&](const std::string& filter) {
        std::string text = scene;
        text.replace(text.find("FILTER"), 6, filter);
        return text;
    };
    write("fs.json", with("stochastic"));
    write("fd.json", with("deterministic"));
    write("fx.json", with("bilinear"));
    const auto mean = [](const Image& image) {
        double sum = 0;
        for (const float v : image.values()) sum += v;
        return sum / double(image.values().size());
    };
    ASSERT_EQ((r = run("--quiet render " + path("fs.json") + " -o " + path("fs.exr"))).code, 0)
        << r.output;
    ASSERT_EQ((r = run("--quiet render " + path("fd.json") + " -o " + path("fd.exr"))).code, 0)
        << r.output;
    // The command line overrides the scene.
    ASSERT_EQ((r = run("--quiet render " + path("fs.json") + " --filter deterministic -o " +
                       path("fo.exr")))
                  .code,
              0)
        << r.output;
    const double s = mean(read_image(path("fs.exr"))), d = mean(read_image(path("fd.exr")));
    EXPECT_GT(d, 0.01);
    EXPECT_NEAR(s / d, 1.0, 0.03);
    EXPECT_EQ(read_image(path("fo.exr")).values(), read_image(path("fd.exr")).values());
    EXPECT_NE(read_image(path("fs.exr")).values(), read_image(path("fd.exr")).values());
    r = run("render " + path("fx.json") + " -o " + path("fx.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("unknown filter \"bilinear\" (stochastic, deterministic)"),
              std::string::npos)
        << r.output;
    EXPECT_FALSE(fs::exists(path("fx.png")));
    r = run("render " + path("fs.json") + " --filter bilinear -o " + path("fx.png"));
    EXPECT_NE(r.code, 0);
    EXPECT_FALSE(fs::exists(path("fx.png")));
}

TEST_F(RenderCli, CompareRendersTwoVersionsOfAMaterial) {
    ASSERT_EQ(run("synth --preset brushed_metal --size 8 -o " + path("c.h5")).code, 0);
    ASSERT_EQ(
        run("compress " + path("c.h5") + " --codec fmf --components 1 -o " + path("c1.btfpkg"))
            .code,
        0);
    write("cmp.json", R"({
      "camera": {"position": [0, 1, 3], "look_at": [0, 0.3, 0], "width": 24, "height": 16},
      "render": {"integrator": "direct", "spp": 2},
      "objects": [{"shape": "sphere", "radius": 0.5, "position": [0, 0.4, 0],
                   "material": {"type": "btf", "file": "unused-when-comparing.btfpkg"}}],
      "lights": [{"type": "directional", "direction": [1, 2, 1], "irradiance": 3}]
    })");
    // The same material twice: identical renders.
    CliResult r = run("--quiet render " + path("cmp.json") + " --compare " + path("c1.btfpkg") +
                      " " + path("c1.btfpkg") + " -o " + path("same.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("ΔE00 mean 0.000"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("SSIM 1.0000"), std::string::npos) << r.output;
    // Raw data against one component: visibly different.
    r = run("--quiet render " + path("cmp.json") + " --compare " + path("c.h5") + " " +
            path("c1.btfpkg") + " -o " + path("cmp.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(r.output.find("ΔE00 mean 0.000"), std::string::npos) << r.output;
    for (const char* f : {"cmp.png", "cmp.a.png", "cmp.b.png", "cmp.diff.png", "cmp.json"})
        EXPECT_TRUE(fs::exists(path(f))) << f;
    EXPECT_EQ(read_image(path("cmp.png")).width(), 3 * 24 + 8);

    r = run("render " + path("cmp.json") + " --compare " + path("c.h5") + " " + path("c1.btfpkg") +
            " -o " + path("cmp.exr"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("--compare writes a picture"), std::string::npos) << r.output;
}

TEST_F(RenderCli, MaterialReplacesEveryBtfMaterialOfTheScene) {
    ASSERT_EQ(run("synth --preset knitted_wool --size 8 -o " + path("w.h5")).code, 0);
    CliResult r =
        run("compress " + path("w.h5") + " --codec fmf --components 2 -o " + path("w.btfpkg"));
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string scene = R"({
      "camera": {"position": [0, 1, 3], "look_at": [0, 0.3, 0], "width": 24, "height": 16},
      "render": {"integrator": "direct", "spp": 2},
      "objects": [{"shape": "sphere", "radius": 0.5, "position": [0, 0.4, 0],
                   "material": {"type": "btf", "file": "FILE"}},
                  {"shape": "plane", "material": {"type": "diffuse"}}],
      "lights": [{"type": "directional", "direction": [1, 2, 1], "irradiance": 3}]
    })";
    const auto with = [&](const std::string& file) {
        std::string text = scene;
        text.replace(text.find("FILE"), 4, file);
        return text;
    };
    write("own.json", with("w.btfpkg"));
    write("other.json", with("absent.btfpkg"));
    // The scene's own file and --material naming the same package: the same image, and the
    // scene's file is not opened.
    ASSERT_EQ((r = run("render " + path("own.json") + " -o " + path("own.exr"))).code, 0)
        << r.output;
    ASSERT_EQ((r = run("render " + path("other.json") + " --material " + path("w.btfpkg") + " -o " +
                       path("other.exr")))
                  .code,
              0)
        << r.output;
    EXPECT_EQ(read_image(path("own.exr")).values(), read_image(path("other.exr")).values());

    r = run("render " + path("own.json") + " --material " + path("absent.btfpkg") + " -o " +
            path("no.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("absent.btfpkg: no such file"), std::string::npos) << r.output;
    write("plain.json",
          R"({"camera": {}, "objects": [{"shape": "plane", "material": {"type": "diffuse"}}]})");
    r = run("render " + path("plain.json") + " --material " + path("w.btfpkg") + " -o " +
            path("no.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("plain.json: --material needs an object with a \"btf\" material"),
              std::string::npos)
        << r.output;
    r = run("render " + path("own.json") + " --material " + path("w.btfpkg") + " --compare " +
            path("w.btfpkg") + " " + path("w.btfpkg") + " -o " + path("no.png"));
    EXPECT_NE(r.code, 0);
    EXPECT_FALSE(fs::exists(path("no.png")));
}

// The scenes in examples/scenes, each with the material file it names (demo.btfpkg beside it;
// users render them with --material demo or their own package): copied with a tiny stand-in
// material and rendered at a tiny size. Relative paths (the material, meshes) resolve beside the
// scene file.
TEST_F(RenderCli, EveryExampleSceneRenders) {
    const fs::path examples = fs::path(BTF_SOURCE_DIR) / "examples" / "scenes";
    const fs::path dir = path("example_scenes");
    fs::create_directories(dir);
    std::vector<std::string> scenes;
    for (const fs::directory_entry& entry : fs::directory_iterator(examples)) {
        if (!entry.is_regular_file() || entry.path().extension() == ".btfpkg") continue;
        fs::copy_file(entry.path(), dir / entry.path().filename());
        if (entry.path().extension() == ".json") scenes.push_back(entry.path().stem().string());
    }
    ASSERT_GE(scenes.size(), 4u) << examples;
    ASSERT_EQ(run("synth --preset woven_fabric --size 8 -o " + path("demo.h5")).code, 0);
    CliResult r = run("compress " + path("demo.h5") + " --codec fmf --components 2 -o " +
                      (dir / "demo.btfpkg").string());
    ASSERT_EQ(r.code, 0) << r.output;
    for (const std::string& scene : scenes) {
        const fs::path png = dir / (scene + ".png");
        r = run("render " + (dir / (scene + ".json")).string() + " --size 24,16 --spp 2 -o " +
                png.string());
        ASSERT_EQ(r.code, 0) << scene << ": " << r.output;
        const Image image = read_image(png.string());
        EXPECT_EQ(image.width(), 24) << scene;
        EXPECT_EQ(image.height(), 16) << scene;
        double sum = 0;
        for (const float v : image.values()) sum += v;
        EXPECT_GT(sum / double(image.values().size()), 0.02) << scene << ": black";
    }
}

TEST_F(RenderCli, BadScenesGiveOneLineAndNoImage) {
    write("typo.json", R"({"camera": {}, "objects": [{"shape": "sphere", "radius": 1,
      "material": {"type": "diffuse", "albedoo": 0.5}}]})");
    CliResult r = run("render " + path("typo.json") + " -o " + path("typo.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("typo.json: objects[0].material: unknown key \"albedoo\""),
              std::string::npos)
        << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(path("typo.png")));

    write("nofile.json", R"({"camera": {}, "objects": [{"shape": "plane",
      "material": {"type": "btf", "file": "absent.btfpkg"}}]})");
    r = run("render " + path("nofile.json") + " -o " + path("nofile.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("absent.btfpkg: no such file"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(path("nofile.png")));

    // Output names are checked before anything is rendered.
    r = run("render " + path("typo.json") + " -o " + path("out.notanimage"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("out.notanimage: unsupported image format"), std::string::npos)
        << r.output;
    r = run("render " + path("typo.json") + " -o " + path("no-such-folder/out.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;

    r = run("render " + path("missing.json") + " -o " + path("m.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("missing.json: cannot open the scene file"), std::string::npos)
        << r.output;
}

// btf image-diff: PNGs are compared as shown, EXRs tone-mapped first; sizes must agree.
TEST_F(RenderCli, ImageDiffComparesPicturesAsShown) {
    // A linear picture and its tone-mapped PNG look the same; a darker PNG does not.
    Image linear(24, 16, 3);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 24; ++x)
            linear.set_rgb(x, y, {0.05f * float(x), 0.1f * float(y), 0.4f});
    write_image(path("linear.exr"), linear);
    write_image(path("shown.png"), quality::tone_map(linear, 1.0));
    Image darker = quality::tone_map(linear, 1.0);
    for (float& v : darker.values()) v *= 0.8f;
    write_image(path("darker.png"), darker);

    CliResult r =
        run("image-diff " + path("shown.png") + " " + path("linear.exr") + " --exposure 1 --json");
    ASSERT_EQ(r.code, 0) << r.output;
    const auto same = nlohmann::json::parse(r.output);
    EXPECT_LT(same["de2000_mean"].get<double>(), 0.3) << r.output;  // 8-bit rounding only
    EXPECT_GT(same["ssim"].get<double>(), 0.999) << r.output;

    r = run("image-diff " + path("darker.png") + " " + path("linear.exr") + " --exposure 1 -o " +
            path("diff.png"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("ΔE00 mean"), std::string::npos) << r.output;
    const Image side = read_image(path("diff.png"));
    EXPECT_EQ(side.width(), 3 * 24 + 2 * 4);  // A | B | heat map
    EXPECT_EQ(side.height(), 16);
    r = run("image-diff " + path("darker.png") + " " + path("linear.exr") + " --exposure 1 --json");
    const auto differ = nlohmann::json::parse(r.output);
    EXPECT_GT(differ["de2000_mean"].get<double>(), 3.0) << r.output;

    // A wrong size, a missing file and a float output are one-line errors without output.
    write_image(path("small.png"), Image(8, 8, 3, 0.5f));
    r = run("image-diff " + path("shown.png") + " " + path("small.png") + " -o " + path("no.png"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("small.png: 8 × 8 pixels, but"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(path("no.png")));
    r = run("image-diff " + path("shown.png") + " " + path("absent.png"));
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.output.find("absent.png"), std::string::npos) << r.output;
    r = run("image-diff " + path("shown.png") + " " + path("shown.png") + " -o " + path("d.exr"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("d.exr: the comparison is a picture"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace btf

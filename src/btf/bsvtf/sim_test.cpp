// SPDX-License-Identifier: MIT
// The BSVTF simulator on a small scene: with an unlimited link, an ample cache and lossless tiles
// every frame is the full-FMF frame; a smaller cache gives lower SSIM but never holds more than
// its capacity; over a slow link the frames improve as bytes arrive; and its errors.

#include <gtest/gtest.h>

#include <fstream>

#include "btf/bsvtf/sim.h"
#include "btf/codecs/codec.h"
#include "btf/io/package.h"
#include "btf/synth/synth.h"
#include "btf/testing/sources.h"
#include "btf/testing/support.h"

namespace btf::bsvtf {
namespace {

namespace fs = std::filesystem;

class Sim : public testing::Test {
  protected:
    static void SetUpTestSuite() {
        s_dir = std::make_unique<test::TempFolder>("bsvtf_sim");
        int seed = 1;
        for (const char* preset : {"woven_fabric", "leather"}) {
            const auto source = synth::make(preset, 64, test::ubo_subset(6, 8), seed++);
            Package p = find_codec("fmf").encode(
                *source, Params{{"components", "8"}, {"quantize", "f16"}}, Progress::none());
            write_package(path(std::string(preset) + ".btfpkg"), p);
        }
        write("scene.json", R"({
          "camera": {"position": [0, 0.9, 3.2], "look_at": [0, 0.4, 0], "fov": 40, "width": 96, "height": 64},
          "objects": [
            {"shape": "sphere", "radius": 0.6, "position": [-0.7, 0.6, 0], "uv_scale": [2, 1],
             "material": {"type": "btf", "file": "woven_fabric.btfpkg"}},
            {"shape": "sphere", "radius": 0.6, "position": [0.7, 0.6, 0], "uv_scale": [2, 1],
             "material": {"type": "btf", "file": "leather.btfpkg"}},
            {"shape": "plane", "width": 6, "depth": 6, "material": {"type": "diffuse"}}
          ],
          "lights": [{"type": "directional", "direction": [-0.3, 1, 0.5], "irradiance": 3}]
        })");
        write("path.json", R"({"frames": 12, "keys": [
          {"frame": 0, "position": [0, 0.9, 3.2], "look_at": [0, 0.4, 0]},
          {"frame": 11, "position": [-0.5, 0.8, 1.6], "look_at": [-0.7, 0.6, 0]}]})");
    }
    static void TearDownTestSuite() { s_dir.reset(); }
    static fs::path path(const std::string& name) { return s_dir->path() / name; }
    static void write(const std::string& name, const std::string& text) {
        std::ofstream(path(name)) << text;
    }
    static SimReport run(SimOptions options) {
        options.geometry = {16, 4};
        return simulate(path("scene.json"), read_camera_path(path("path.json")), options,
                        Progress::none());
    }
    static std::unique_ptr<test::TempFolder> s_dir;
};
std::unique_ptr<test::TempFolder> Sim::s_dir;

TEST_F(Sim, AnAmpleCacheOverAnUnlimitedLinkShowsTheFullFmfFrames) {
    SimOptions o;
    o.bandwidth = 0;
    o.cache = 24 * 30;  // 900 slots: every tile of both materials
    o.tile_error = 0;
    o.feedback_divisor = 1;
    const SimReport r = run(o);
    ASSERT_EQ(r.frames.size(), 12u);
    ASSERT_EQ(r.materials.size(), 2u);
    for (const SimFrame& f : r.frames) {
        EXPECT_GT(f.ssim, 0.9999) << f.frame;
        EXPECT_LT(f.de2000, 0.01) << f.frame;
        EXPECT_EQ(f.pending, 0);
    }
    // The memory report: tiles and the angular factors of both materials.
    EXPECT_EQ(r.capacity, 900);
    EXPECT_EQ(r.cache_bytes, 900u * 24 * 24 * 4 * 2);
    for (const SimMaterial& m : r.materials) {
        EXPECT_EQ(m.levels, 3);
        EXPECT_EQ(m.components, 8);
        EXPECT_EQ(m.fmf_bytes, (64u * 64 + 6 * 8 * 3) * 8 * 2);
        EXPECT_EQ(m.codec_error, 0);
    }
}

TEST_F(Sim, ASmallerCacheLosesDetailButStaysWithinItsCapacity) {
    SimOptions o;
    o.bandwidth = 0;
    o.tile_error = 0;
    double previous = 0;
    std::string means;
    std::vector<double> previous_means;
    for (const int side : {96, 168, 24 * 30}) {  // 16, 49 and 900 slots
        o.cache = side;
        const SimReport r = run(o);
        double mean = 0;
        for (const SimFrame& f : r.frames) {
            EXPECT_LE(f.resident, r.capacity);
            mean += f.ssim / double(r.frames.size());
        }
        EXPECT_GT(mean, previous) << side;
        previous = mean;
        means += std::to_string(mean) + " ";
        previous_means.push_back(mean);
    }
    // 16 slots hold little more than the coarsest tiles; 49 hold what these frames need.
    EXPECT_LT(previous_means[0], previous_means[1] - 0.01) << means;
}

TEST_F(Sim, OverASlowLinkFramesImproveAsBytesArrive) {
    SimOptions o;
    o.bandwidth = 2e6;  // 8.3 KB per frame at 30 frames per second
    o.cache = 24 * 30;
    const SimReport r = run(o);
    for (size_t i = 1; i < r.frames.size(); ++i)
        EXPECT_GE(r.frames[i].bytes, r.frames[i - 1].bytes);
    EXPECT_EQ(r.frames.front().resident, 4);  // the coarsest tile of each group of both
    EXPECT_GT(r.frames.back().bytes, 0u);
    EXPECT_GT(r.frames.back().ssim, r.frames.front().ssim + 0.05);
    int adds = 0;
    for (const SimFrame& f : r.frames) adds += f.adds;
    EXPECT_GT(adds, 0);
    EXPECT_GT(r.frames.back().resident, 4);
}

TEST_F(Sim, ErrorsNameTheProblem) {
    write(
        "dark.json",
        R"({"camera": {}, "objects": [{"shape": "sphere", "material": {"type": "btf", "file": "leather.btfpkg"}}],
                         "lights": [{"type": "environment", "sky": {"width": 32}}]})");
    const std::string dark = test::error_of([] {
        simulate(path("dark.json"), read_camera_path(path("path.json")), {}, Progress::none());
    });
    EXPECT_NE(dark.find("point and directional lights"), std::string::npos) << dark;
    write("bad_path.json",
          R"({"frames": 3, "keys": [{"frame": 2, "position": [0, 0, 1], "look_at": [0, 0, 0]},
                              {"frame": 1, "position": [0, 0, 1], "look_at": [0, 0, 0]}]})");
    EXPECT_NE(test::error_of([] {
                  read_camera_path(path("bad_path.json"));
              }).find("bad_path.json: bad camera path: key frames must increase"),
              std::string::npos);
    SimOptions tiny;
    tiny.cache = 72;  // one slot of 72 × 72 for the 4 coarsest tiles
    EXPECT_NE(test::error_of([&] {
                  simulate(path("scene.json"), read_camera_path(path("path.json")), tiny,
                           Progress::none());
              }).find("cannot hold the coarsest level"),
              std::string::npos);
}

}  // namespace
}  // namespace btf::bsvtf

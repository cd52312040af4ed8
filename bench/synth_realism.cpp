// SPDX-License-Identifier: MIT
// Realism check of the synthetic presets against the real measured UBO2003 view.
//
// For each preset, two views (θ = 0° and θ = 45°, φ = 0°) of the ubo81 × ubo81 sampling: the
// relative RMSE (RMSE / RMS value, no mean subtraction) of the best rank-k approximation of the
// light matrix (texels × 81 lights · 3 channels), printed as a Markdown table beside the same
// numbers for the real view. Also writes one picture grid per preset (4 lights × the 2 views)
// and one of the real view at the same lights, as sRGB PNGs.
//
// Usage: synth_realism [--size N] [--seed S] [--images DIR] [--data DIR] [--presets a,b,...]
//   --size    texels per side of the synthetic materials (default 256, the real view's size)
//   --images  folder for synth_<preset>.png and synth_real.png (default: docs/images of the
//             source tree; "-" writes no pictures)
//   --data    the real view's folder (default: ../shared/data/ubo2003-proposte-view000/
//             tv000_pv000); skipped with a note when absent

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "btf/core/direction.h"
#include "btf/core/image.h"
#include "btf/quality/lowrank.h"
#include "btf/synth/synth.h"
#include "btf/util/error.h"

namespace fs = std::filesystem;

namespace {

const std::vector<int> kRanks = {1, 4, 8, 16, 32};
constexpr int kTile = 128;  // picture-grid cell size

// Light index → JPEG of one UBO2003 view folder, from the tl/pl angles in the file names.
std::map<int, fs::path> real_view_files(const fs::path& folder) {
    std::map<int, fs::path> files;
    for (const auto& entry : fs::directory_iterator(folder)) {
        const std::string name = entry.path().filename().string();
        int number = 0, tl = 0, pl = 0, tv = 0, pv = 0;
        if (std::sscanf(name.c_str(), "%d tl%d pl%d tv%d pv%d", &number, &tl, &pl, &tv, &pv) != 5)
            continue;
        const int light = btf::DirectionSet::ubo81().find(btf::Direction::from_degrees(tl, pl));
        if (light >= 0) files[light] = entry.path();
    }
    return files;
}

// Box-filters an image down to kTile × kTile (sizes that are multiples of kTile) or samples it
// nearest-neighbour (other sizes).
btf::Image to_tile(const btf::Image& image) {
    btf::Image tile(kTile, kTile, 3);
    const int f = image.width() / kTile;
    const bool box = f >= 1 && image.width() == f * kTile && image.height() == f * kTile;
    for (int y = 0; y < kTile; ++y)
        for (int x = 0; x < kTile; ++x)
            for (int c = 0; c < 3; ++c) {
                double sum = 0;
                if (box) {
                    for (int j = 0; j < f; ++j)
                        for (int i = 0; i < f; ++i) sum += image.at(x * f + i, y * f + j, c);
                    sum /= f * f;
                } else {
                    sum = image.at(x * image.width() / kTile, y * image.height() / kTile, c);
                }
                tile.at(x, y, c) = float(sum);
            }
    return tile;
}

void paste(btf::Image& grid, const btf::Image& tile, int col, int row) {
    for (int y = 0; y < kTile; ++y)
        for (int x = 0; x < kTile; ++x)
            for (int c = 0; c < 3; ++c)
                grid.at(col * kTile + x, row * kTile + y, c) = tile.at(x, y, c);
}

std::string row_of(const btf::LowRankError& e) {
    std::string s;
    for (double v : e.relative_rmse) s += fmt::format(" {:.3f} |", v);
    return s;
}

}  // namespace

int main(int argc, char** argv) {
    int size = 256;
    uint64_t seed = 1;
    fs::path images = fs::path(BTF_SOURCE_DIR) / "docs" / "images";
    fs::path data = fs::path(BTF_SHARED_DIR) / "data" / "ubo2003-proposte-view000" / "tv000_pv000";
    std::vector<std::string> presets = btf::synth::preset_names();
    CLI::App app{"Synthetic vs. real: pictures and rank-k relative RMSE (docs/synth.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--seed", seed, "synthesis seed")->capture_default_str();
    app.add_option("--images", images, "folder for the pictures, or - for none")
        ->capture_default_str();
    app.add_option("--data", data, "the real measured view's images")->capture_default_str();
    app.add_option("--presets", presets, "presets (default: all)")
        ->delimiter(',')
        ->check(CLI::IsMember(btf::synth::preset_names()));
    CLI11_PARSE(app, argc, argv);
    const bool pictures = images != "-";
    try {
        const btf::DirectionSet& ubo = btf::DirectionSet::ubo81();
        const btf::Sampling sampling{ubo, ubo};
        const std::vector<int> views = {0, ubo.find(btf::Direction::from_degrees(45, 0))};
        const std::vector<int> lights = {ubo.find(btf::Direction::from_degrees(0, 0)),
                                         ubo.find(btf::Direction::from_degrees(30, 90)),
                                         ubo.find(btf::Direction::from_degrees(60, 0)),
                                         ubo.find(btf::Direction::from_degrees(75, 210))};

        std::printf(
            "| material | view (θ, φ) | k = 1 | k = 4 | k = 8 | k = 16 | k = 32 | "
            "k = 8 / real |\n|---|---|---|---|---|---|---|---|\n");
        double real_k8 = 0;
        std::string real_row;
        if (fs::is_directory(data)) {
            const auto files = real_view_files(data);
            if (int(files.size()) != ubo.size())
                btf::fail("{}: found {} of the 81 light images", data.string(), files.size());
            const btf::Image first = btf::read_image(files.begin()->second);
            const auto real = btf::light_matrix_low_rank(
                first.width(), first.height(), ubo.size(),
                [&](int light, btf::Image& out) { out = btf::read_image(files.at(light)); },
                kRanks);
            real_k8 = real.relative_rmse[2];
            real_row =
                fmt::format("| real UBO2003 view (PROPOSTE) | (0°, 0°) |{} 1.00 |", row_of(real));
            std::printf("%s\n", real_row.c_str());
            if (pictures) {
                btf::Image grid(kTile * int(lights.size()), kTile, 3);
                for (size_t c = 0; c < lights.size(); ++c)
                    paste(grid, to_tile(btf::read_image(files.at(lights[c]))), int(c), 0);
                btf::write_image(images / "synth_real.png", grid);
            }
        } else {
            std::fprintf(stderr, "note: %s is absent; no real reference row\n",
                         data.string().c_str());
        }
        std::fflush(stdout);

        for (const std::string& preset : presets) {
            const auto start = std::chrono::steady_clock::now();
            const auto source = btf::synth::make(preset, size, sampling, seed);
            for (int view : views) {
                const auto e = btf::light_matrix_low_rank(*source, view, kRanks);
                const btf::Direction& d = ubo[view];
                std::printf("| %s | (%.0f°, %.0f°) |%s %s |\n", preset.c_str(), d.theta_deg(),
                            d.phi_deg(), row_of(e).c_str(),
                            real_k8 > 0
                                ? fmt::format("{:.2f}", e.relative_rmse[2] / real_k8).c_str()
                                : "–");
                std::fflush(stdout);
            }
            if (pictures) {
                btf::Image grid(kTile * int(lights.size()), kTile * int(views.size()), 3);
                for (size_t r = 0; r < views.size(); ++r)
                    for (size_t c = 0; c < lights.size(); ++c)
                        paste(grid, to_tile(source->image(views[r], lights[c])), int(c), int(r));
                btf::write_image(images / ("synth_" + preset + ".png"), grid);
            }
            const double seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            std::fprintf(stderr, "%s: %.1f s\n", preset.c_str(), seconds);
        }
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "synth_realism: %s\n", e.what());
        return 1;
    }
    return 0;
}

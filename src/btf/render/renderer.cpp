// SPDX-License-Identifier: MIT
#include "btf/render/renderer.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <vector>

#include "btf/quality/render_compare.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::render {

namespace {

constexpr int kTile = 32;

struct Tile {
    int x0, y0, x1, y1;
};

std::vector<Tile> make_tiles(int width, int height) {
    std::vector<Tile> tiles;
    for (int y = 0; y < height; y += kTile)
        for (int x = 0; x < width; x += kTile)
            tiles.push_back({x, y, std::min(width, x + kTile), std::min(height, y + kTile)});
    return tiles;
}

}  // namespace

RenderResult render(const Scene& scene, const RenderOptions& options, Progress& progress) {
    const Camera& camera = scene.camera;
    if (camera.width <= 0 || camera.height <= 0)
        throw Error("render: the camera's image size must be positive");
    if (options.spp <= 0 && options.time_limit <= 0)
        throw Error("render: give a number of samples per pixel or a time limit");
    const int width = camera.width, height = camera.height;
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };

    std::vector<double> sum(size_t(width) * height * 3, 0.0);
    std::atomic<uint64_t> dropped{0};
    RenderResult result;
    if (options.aovs) {
        result.albedo = Image(width, height, 3);
        result.normal = Image(width, height, 3);
        result.uv = Image(width, height, 3);
    }
    const std::vector<Tile> tiles = make_tiles(width, height);
    const bool timed = options.time_limit > 0;
    // Progress in tiles × passes; with only a time limit, in per mille of the time.
    const uint64_t total = options.spp > 0 ? uint64_t(options.spp) * tiles.size() : 1000;
    progress.begin("rendering", total);
    uint64_t reported = 0;
    int pass = 0;
    for (; options.spp <= 0 || pass < options.spp; ++pass) {
        if (timed && pass > 0 && elapsed() >= options.time_limit) break;
        parallel_for(0, int64_t(tiles.size()), [&](int64_t t) {
            progress.poll();  // Ctrl-C stops within a tile, also when only time limits the run
            const Tile& tile = tiles[size_t(t)];
            for (int y = tile.y0; y < tile.y1; ++y)
                for (int x = tile.x0; x < tile.x1; ++x) {
                    const uint64_t pixel = uint64_t(y) * width + x;
                    Rng rng(options.seed, pixel, uint64_t(pass));
                    const double jx = rng.uniform(), jy = rng.uniform();
                    const Ray ray = camera.ray(x + jx, y + jy);
                    FirstHit first;
                    const bool want_aovs = options.aovs && pass == 0;
                    const Rgb L =
                        radiance(scene, ray, rng, options.integrator, want_aovs ? &first : nullptr,
                                 primary_filter_numbers(options.seed, pixel, uint64_t(pass)));
                    double* p = &sum[pixel * 3];
                    // A NaN or infinite sample (a pdf underflow) would ruin the pixel for good.
                    if (std::isfinite(L.r) && std::isfinite(L.g) && std::isfinite(L.b))
                        p[0] += L.r, p[1] += L.g, p[2] += L.b;
                    else
                        dropped.fetch_add(1, std::memory_order_relaxed);
                    if (want_aovs && first.found) {
                        result.albedo.set_rgb(x, y, first.albedo);
                        result.normal.set_rgb(
                            x, y,
                            {float(first.normal.x), float(first.normal.y), float(first.normal.z)});
                        result.uv.set_rgb(x, y, {float(first.uv.u), float(first.uv.v), 0.0f});
                    }
                }
            if (options.spp > 0) progress.advance();
        });
        if (options.spp <= 0) {
            const uint64_t now =
                std::min<uint64_t>(999, uint64_t(1000 * elapsed() / options.time_limit));
            if (now > reported) progress.advance(now - reported), reported = now;
        }
    }
    progress.finish();
    result.spp = pass;
    result.seconds = elapsed();
    result.dropped = dropped.load();
    result.color = Image(width, height, 3);
    const double inv = pass > 0 ? 1.0 / pass : 0;
    // A pixel's mean can be below zero where a compressed BTF rings below zero (surfaces return
    // signed values so that the estimate stays unbiased): radiance is not negative.
    for (size_t i = 0; i < sum.size(); ++i)
        result.color.data()[i] = float(std::max(sum[i] * inv, 0.0));
    return result;
}

namespace {
std::filesystem::path aov_path(const std::filesystem::path& path, const char* name) {
    return (path.parent_path() / path.stem()).string() + "." + name + ".exr";
}
}  // namespace

void check_render_output(const std::filesystem::path& path, bool aovs) {
    check_image_output(path);
    if (aovs)
        for (const char* name : {"albedo", "normal", "uv"})
            check_image_output(aov_path(path, name));
}

void write_render(const std::filesystem::path& path, const RenderResult& result, double exposure) {
    AtomicOutputSet files;
    write_image(files.add(path), is_float_image_format(path)
                                     ? result.color
                                     : quality::tone_map(result.color, exposure));
    if (!result.albedo.empty()) {
        write_image(files.add(aov_path(path, "albedo")), result.albedo);
        write_image(files.add(aov_path(path, "normal")), result.normal);
        write_image(files.add(aov_path(path, "uv")), result.uv);
    }
    files.commit();
}

}  // namespace btf::render

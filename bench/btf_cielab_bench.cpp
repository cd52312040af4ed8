// SPDX-License-Identifier: MIT
// BTF-CIELab cost at realistic size (docs/benchmarks.md, "Quality (issue 4)"): a synthetic
// material as the reference (written to a btfkit HDF5 file first, not timed) against its fmf
// compression (the package decoded on the fly, as `btf quality REF PKG` does), over the 5 × 5
// viewing-condition grid. Prints the wall time of each stage, the peak resident memory, the
// filtered-channel store and the value at every condition.

#include <malloc.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>

#include "bench_common.h"
#include "btf/codecs/codec.h"
#include "btf/codecs/material_source.h"
#include "btf/io/h5.h"
#include "btf/io/open.h"
#include "btf/quality/btf_cielab.h"
#include "btf/synth/synth.h"

using namespace btf;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
    int size = 256, components = 32, grid = 5, bits = 16;
    double memory_gib = 4;
    std::string preset = "woven_fabric", against = "fmf";
    fs::path dir = "/tmp";
    CLI::App app{"BTF-CIELab wall time and memory (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--components", components, "fmf rank of the test material")
        ->capture_default_str();
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--against", against,
                   "test material: fmf (the reference compressed) or seed (another instance of the "
                   "preset, to time the measure alone)")
        ->check(CLI::IsMember({"fmf", "seed"}))
        ->capture_default_str();
    app.add_option("--grid", grid, "viewing conditions per axis")->capture_default_str();
    app.add_option("--bits", bits, "bits per stored channel value")->capture_default_str();
    app.add_option("--memory", memory_gib, "GiB for the store before it spills to disk")
        ->capture_default_str();
    app.add_option("--dir", dir, "folder for the temporary files")->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    const fs::path h5_path = dir / fmt::format("btfkit_cielab_{}.h5", ::getpid());
    try {
        const DirectionSet& ubo = DirectionSet::ubo81();
        {
            const auto synth = synth::make(preset, size, {ubo, ubo}, 1);
            h5::write(*synth, h5_path);
        }
        malloc_trim(0);
        const auto reference = open_source(h5_path);
        bench::Stopwatch clock;
        std::unique_ptr<BtfSource> test;
        if (against == "fmf") {
            const Package package =
                find_codec("fmf").encode(*reference, {{"components", std::to_string(components)}});
            std::fprintf(stderr, "fmf C = %d encoded in %.1f s\n", components, clock.seconds());
            test = std::make_unique<MaterialSource>(open_material(package), "fmf");
        } else {
            test = synth::make(preset, size, {ubo, ubo}, 2);
        }

        std::map<std::string, double> stage_seconds;
        std::string stage;
        bench::Stopwatch stage_clock;
        std::mutex mutex;
        Progress progress([&](std::string_view name, uint64_t, uint64_t) {
            std::lock_guard lock(mutex);
            if (name == stage) return;
            if (!stage.empty()) {
                stage_seconds[stage] += stage_clock.seconds();
                std::fprintf(stderr, "  %s: %.1f s\n", stage.c_str(), stage_clock.seconds());
            }
            stage = std::string(name);
            stage_clock = bench::Stopwatch();
        });
        quality::BtfCielabOptions options;
        options.grid = grid;
        options.bits = bits;
        options.memory_bytes = int64_t(memory_gib * double(int64_t(1) << 30));
        options.scratch = dir;
        const bool reset = bench::reset_peak_rss();
        const int64_t rss_before = bench::current_rss();
        clock = bench::Stopwatch();
        const quality::BtfCielabResult result =
            quality::btf_cielab(*reference, *test, options, progress);
        const double seconds = clock.seconds();
        progress.begin("done", 0);
        double reading = 0, spatial = 0, angular = 0;
        for (const auto& [name, s] : stage_seconds)
            (name.find("reading") != std::string::npos   ? reading
             : name.find("spatial") != std::string::npos ? spatial
                                                         : angular) += s;

        const std::string what = against == "fmf" ? fmt::format("fmf C = {}", components)
                                                  : std::string("another instance (seed 2)");
        std::printf("%s %d² × 81 × 81 vs %s, %d × %d conditions, %d-bit store, %d threads\n\n",
                    preset.c_str(), size, what.c_str(), grid, grid, bits,
                    int(std::thread::hardware_concurrency()));
        std::printf(
            "| wall time | reading + lαβ | spatial passes | angular passes + CIEDE2000 | "
            "peak RSS above start | stores | spilled |\n|---|---|---|---|---|---|---|\n");
        std::printf(
            "| %.0f s (%.1f min) | %.0f s | %.0f s | %.0f s | %.0f MiB%s | %.2f GB | %s |\n\n",
            seconds, seconds / 60, reading, spatial, angular,
            bench::mib(bench::peak_rss() - rss_before), reset ? "" : " (whole process)",
            double(result.store_bytes) / 1e9, result.spilled ? "yes" : "no");
        std::printf("| ω (°/s) | r_s (px/°) | mean ΔE00 | std | RMS |\n|---|---|---|---|---|\n");
        for (size_t i = 0; i < result.values.size(); ++i) {
            const auto& v = result.values[i];
            std::printf("| %.3g | %.3g | %.3f | %.3f | %.3f%s |\n", v.condition.angular_speed,
                        v.condition.resolution, v.mean, v.stddev, v.rms,
                        int(i) == result.worst ? " (worst)" : "");
        }
    } catch (const std::exception& e) {
        std::error_code ec;
        fs::remove(h5_path, ec);
        std::fprintf(stderr, "btf_cielab_bench: %s\n", e.what());
        return 1;
    }
    std::error_code ec;
    fs::remove(h5_path, ec);
    return 0;
}

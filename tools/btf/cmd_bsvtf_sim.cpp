// SPDX-License-Identifier: MIT
// btf bsvtf-sim --scene S.json --path P.json --cache 2048 --bandwidth 10mbit: the headless
// BSVTF simulator (src/btf/bsvtf/sim.h) — renders a camera path through a fixed tile cache fed
// over a simulated link and compares every frame with the full-FMF frame; writes a per-frame
// log (CSV) and prints a summary.

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>

#include <nlohmann/json.hpp>

#include "btf/bsvtf/sim.h"
#include "btf/core/image.h"
#include "btf/quality/plot.h"
#include "btf/quality/render_compare.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

// "10mbit", "512kbit", "1gbit", a number of bits per second, or "unlimited" (0).
double parse_bandwidth(const std::string& text) {
    if (text == "unlimited" || text == "0") return 0;
    static const std::regex form(R"(^\s*([0-9]*\.?[0-9]+)\s*([kmgKMG]?)(bit|bps)?\s*$)");
    std::smatch m;
    if (!std::regex_match(text, m, form))
        fail("--bandwidth '{}': give e.g. 10mbit, 512kbit, 1gbit or unlimited", text);
    const double scale = m[2] == ""                     ? 1
                         : (m[2] == "k" || m[2] == "K") ? 1e3
                         : (m[2] == "m" || m[2] == "M") ? 1e6
                                                        : 1e9;
    return std::stod(m[1]) * scale;
}

}  // namespace

Command register_bsvtf_sim(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string scene, path, bandwidth = "10mbit", size, log, frames, plot;
        int cache = 2048, divisor = 4, store = 256;
        double fps = 30;
        TileOptions tiles;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "bsvtf-sim",
        "Simulate BSVTF rendering and streaming without a GPU: a scene of fmf materials along a "
        "camera path through a fixed tile cache fed over a link of given bandwidth; each frame "
        "compared with the full FMF frame (SSIM, PSNR, ΔE00)");
    cmd->add_option("--scene", args->scene,
                    "scene file (docs/scenes.md) whose BTF materials are "
                    "fmf packages")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--path", args->path,
                    "camera path (JSON: {\"frames\": N, \"keys\": [{\"frame\", \"position\", "
                    "\"look_at\"}, …]})")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--cache", args->cache, "tile cache side in texels")
        ->check(CLI::Range(72, 65536));
    cmd->add_option("--bandwidth", args->bandwidth, "link: 10mbit, 100mbit, … or unlimited");
    cmd->add_option("--fps", args->fps, "frames per second of the path")
        ->check(CLI::Range(1.0, 1000.0));
    cmd->add_option("--size", args->size,
                    "frame size 'width,height' (default: the scene's camera)");
    add_tile_options(*cmd, args->tiles);
    cmd->add_option("--feedback", args->divisor, "feedback image divisor")
        ->check(CLI::Range(1, 64));
    cmd->add_option("--store", args->store, "client store of received tiles, MiB")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--log", args->log, "per-frame log (CSV)");
    cmd->add_option("--plot", args->plot, "SVG plot of SSIM against the bytes received");
    cmd->add_option("--frames", args->frames,
                    "folder for PNGs of every frame: rendered | full FMF (created if missing)");

    return {
        cmd, [args, &global] {
            bsvtf::SimOptions options;
            options.cache = args->cache;
            options.bandwidth = parse_bandwidth(args->bandwidth);
            options.fps = args->fps;
            options.geometry = {args->tiles.tile, args->tiles.pad};
            options.tile_error = args->tiles.relative_error();
            options.feedback_divisor = args->divisor;
            options.store_bytes = uint64_t(args->store) << 20;
            if (!args->size.empty()) {
                const auto [w, h] = parse_pair(args->size, "--size");
                if (w < 1 || h < 1 || w > 8192 || h > 8192)
                    fail("--size {}: width and height must be 1 to 8192", args->size);
                options.width = w;
                options.height = h;
            }
            std::optional<AtomicOutput> log, plot;
            if (!args->log.empty()) log.emplace(args->log);
            if (!args->plot.empty()) plot.emplace(args->plot);
            if (!args->frames.empty()) std::filesystem::create_directories(args->frames);
            const bsvtf::CameraPath path = bsvtf::read_camera_path(args->path);
            Progress progress = make_progress(global);
            const bsvtf::SimReport report =
                bsvtf::simulate(args->scene, path, options, progress,
                                [&](const bsvtf::SimFrame& f, const Image& rendered,
                                    const Image& reference, double exposure) {
                                    if (args->frames.empty()) return;
                                    const Image a = quality::tone_map(rendered, exposure);
                                    const Image b = quality::tone_map(reference, exposure);
                                    Image both(a.width() * 2 + 4, a.height(), 3, 1.0f);
                                    for (int y = 0; y < a.height(); ++y)
                                        for (int x = 0; x < a.width(); ++x) {
                                            both.set_rgb(x, y, a.rgb(x, y));
                                            both.set_rgb(a.width() + 4 + x, y, b.rgb(x, y));
                                        }
                                    write_image(std::filesystem::path(args->frames) /
                                                    fmt::format("frame-{:04d}.png", f.frame),
                                                both);
                                });
            if (log) {
                std::ofstream out(log->temp_path());
                out << "frame,time_s,bytes,tile_bytes,resident,adds,swaps,pending,ssim,psnr_db,"
                       "de2000\n";
                for (const bsvtf::SimFrame& f : report.frames)
                    out << fmt::format("{},{:.4f},{},{},{},{},{},{},{:.5f},{:.3f},{:.4f}\n",
                                       f.frame, f.time, f.bytes, f.tile_bytes, f.resident, f.adds,
                                       f.swaps, f.pending, f.ssim, f.psnr, f.de2000);
                if (!out) fail("{}: cannot write", args->log);
                out.close();
                log->commit();
            }
            if (plot) {
                quality::PlotSeries series{"SSIM against the full-FMF frame", {}};
                for (const bsvtf::SimFrame& f : report.frames)
                    series.points.push_back(
                        {double(f.bytes) / 1048576.0, f.ssim, fmt::format("frame {}", f.frame)});
                quality::PlotOptions o;
                o.title = fmt::format("{} materials, cache {}², {}", report.materials.size(),
                                      args->cache, args->bandwidth);
                o.x.label = "MiB received";
                o.y.label = "SSIM";
                std::ofstream out(plot->temp_path());
                out << quality::svg_line_plot(o, {series});
                if (!out) fail("{}: cannot write", args->plot);
                out.close();
                plot->commit();
            }
            uint64_t fmf = 0, u = 0;
            double prep = 0;
            for (const bsvtf::SimMaterial& m : report.materials) {
                fmf += m.fmf_bytes;
                u += m.u_bytes;
                prep += m.prep_seconds;
            }
            std::printf("%zu materials (preprocessing %.1f s), %d frames at %d × %d\n",
                        report.materials.size(), prep, int(report.frames.size()), report.width,
                        report.height);
            std::printf(
                "memory: tile cache %d tiles, %s + Eigen-ABRDFs %s = %s; plain FMF "
                "%s\n",
                report.capacity, human_bytes(double(report.cache_bytes)).c_str(),
                human_bytes(double(u)).c_str(), human_bytes(double(report.cache_bytes + u)).c_str(),
                human_bytes(double(fmf)).c_str());
            double mean = 0;
            const bsvtf::SimFrame* reach = nullptr;
            for (const bsvtf::SimFrame& f : report.frames) {
                mean += f.ssim / double(report.frames.size());
                if (!reach && f.ssim >= 0.95) reach = &f;
            }
            const bsvtf::SimFrame& last = report.frames.back();
            std::printf(
                "SSIM against full FMF: mean %.4f, last %.4f (PSNR %.2f dB, ΔE00 %.3f); "
                "received %s\n",
                mean, last.ssim, last.psnr, last.de2000, human_bytes(double(last.bytes)).c_str());
            if (reach)
                std::printf("SSIM 0.95 first reached at frame %d after %s\n", reach->frame,
                            human_bytes(double(reach->bytes)).c_str());
            else
                std::printf("SSIM 0.95 not reached\n");
        }};
}

}  // namespace btf::cli

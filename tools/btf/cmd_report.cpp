// SPDX-License-Identifier: MIT
// btf report REF --codecs CONFIG... -o DIR: compress a reference BTF with several codec
// configurations and write a self-contained HTML report folder (results table, rate–distortion
// plots, error heat maps and crops) that opens offline.

#include <cmath>
#include <cstdio>

#include "btf/quality/report.h"
#include "btf/render/renderer.h"
#include "btf/render/scene_file.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

// "θv,φv:θl,φl" → the two directions.
std::pair<Direction, Direction> parse_image(const std::string& text) {
    const size_t colon = text.find(':');
    if (colon == std::string::npos)
        fail("--image: expected 'view_theta,view_phi:light_theta,light_phi' in degrees, got '{}'",
             text);
    return {parse_direction(text.substr(0, colon), "--image (view)"),
            parse_direction(text.substr(colon + 1), "--image (light)")};
}

}  // namespace

Command register_report(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string input, output, views;
        OpenOptions open;
        std::vector<std::string> codecs, images;
        int grid = quality::BtfCielabOptions{}.grid;
        bool no_cielab = false, force = false, no_packages = false;
        int crop = quality::ReportOptions{}.crop;
        double gain = quality::ReportOptions{}.difference_gain;
        double heat_max = 0;
        int zstd = quality::ReportOptions{}.zstd_level;
        std::string scene;
        int render_spp = 0;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "report",
        "Compress a reference BTF with several codec configurations and write an HTML report "
        "folder: size, ratio, time, RMSE, PSNR, ΔE00, MSSIM and BTF-CIELab of each, "
        "rate–distortion plots, error heat maps and crops (docs/quality.md, \"Report\")");
    cmd->add_option("reference", args->input,
                    "reference BTF file or folder (any format btfkit reads, or a package)")
        ->required();
    cmd->add_option("--codecs", args->codecs,
                    "codec configurations, each codec[:key=value,…]; an item without '=' adds a "
                    "value to the parameter before it and several values sweep it, e.g. "
                    "fmf:C=8,16,32 pca-views:k=1,C=8 lpca (C = components, k = views-per-group; "
                    "`btf codecs` lists the parameters)")
        ->required()
        ->expected(1, -1);
    cmd->add_option("-o,--output", args->output, "report folder to create (index.html inside)")
        ->required();
    cmd->add_flag("--force", args->force,
                  "replace an existing report folder (never a folder btf report did not write)");
    auto* grid = cmd->add_option("--btf-cielab-grid", args->grid,
                                 "BTF-CIELab: viewing conditions per axis of the log-uniform grid")
                     ->check(CLI::Range(1, 64));
    cmd->add_flag("--no-btf-cielab", args->no_cielab, "skip BTF-CIELab (the slowest measure)")
        ->excludes(grid);
    cmd->add_option("--image", args->images,
                    "a (view, light) image to show as crops and heat map, 'θv,φv:θl,φl' in "
                    "degrees, nearest measured directions (repeatable; default: normal view with "
                    "frontal and grazing light, grazing view)");
    cmd->add_option("--crop", args->crop, "side of the crops in texels, from the image centre")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--gain", args->gain, "amplification of the difference crop")
        ->check(CLI::Range(0.01, 1000.0));
    cmd->add_option("--heat-max", args->heat_max,
                    "top of the heat-map scale in ΔE00 (default: from the errors)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_flag("--no-packages", args->no_packages,
                  "do not keep the encoded packages in the report's packages/ folder");
    cmd->add_option("--zstd", args->zstd, "zstd level of the package sections (0 = store raw)")
        ->check(CLI::Range(0, 22));
    auto* scene = cmd->add_option("--scene", args->scene,
                                  "also render this scene (docs/scenes.md) with the reference and "
                                  "every configuration as its BTF materials, and compare the "
                                  "renders (section \"Rendered\")");
    cmd->add_option("--render-spp", args->render_spp,
                    "samples per pixel of those renders (default: the scene's)")
        ->check(CLI::Range(1, 1 << 20))
        ->needs(scene);
    add_open_options(*cmd, args->open, args->views);

    return {cmd, [args, &global] {
                // Everything that can be checked without the input first: a report takes long.
                quality::ReportOptions options;
                options.configs = quality::parse_codec_configs(args->codecs);
                options.output = args->output;
                options.force = args->force;
                quality::check_report_output(options.output, options.force);
                std::vector<std::pair<Direction, Direction>> chosen;
                for (const std::string& text : args->images) chosen.push_back(parse_image(text));
                options.btf_cielab = !args->no_cielab;
                options.cielab.grid = args->grid;
                options.crop = args->crop;
                options.difference_gain = args->gain;
                options.heat_max = args->heat_max;
                options.keep_packages = !args->no_packages;
                options.zstd_level = args->zstd;
                options.reference_name = args->input;
                options.generator = version_line();
                options.command_line = global.command_line;

                if (!args->scene.empty()) {
                    // Each render loads the scene with its material (a non-owning pointer: the
                    // material outlives the render); the first, the reference's, checks it.
                    options.render = [path = args->scene, spp = args->render_spp](
                                         const Material& material, Progress& progress) {
                        render::LoadOptions load;
                        load.btf_override = std::shared_ptr<const Material>(
                            std::shared_ptr<const Material>(), &material);
                        const render::LoadedScene loaded = render::load_scene(path, load);
                        if (loaded.btf_objects == 0)
                            fail("{}: --scene needs an object with a \"btf\" material", path);
                        render::RenderOptions ro = loaded.settings.options;
                        if (spp > 0) ro.spp = spp;
                        if (ro.spp == 0) ro.spp = 16;  // the scene's time limit does not apply
                        ro.time_limit = 0;
                        quality::ReportRender out;
                        out.image = render::render(loaded.scene, ro, progress).color;
                        out.exposure = loaded.settings.exposure;
                        out.caption =
                            fmt::format("{}: {} × {} pixels, {} samples per pixel, {} integrator",
                                        path, loaded.scene.camera.width, loaded.scene.camera.height,
                                        ro.spp, ro.integrator.max_depth == 1 ? "direct" : "path");
                        return out;
                    };
                }
                const auto source = open_input(args->input, args->open, args->views);
                for (size_t i = 0; i < chosen.size(); ++i) {
                    quality::ReportImage image;
                    image.view = source->sampling().views.nearest(chosen[i].first.vector());
                    image.light = source->sampling().lights.nearest(chosen[i].second.vector());
                    image.label = "--image " + args->images[i];
                    options.images.push_back(image);
                }
                Progress progress = make_progress(global);
                const quality::Report report = quality::write_report(*source, options, progress);

                for (const quality::ConfigResult& c : report.configs) {
                    std::string line = fmt::format(
                        "{}: {}, ratio {}, {:.3g} bits/sample, encoded in {:.2f} s, RMSE {:.4g}, "
                        "PSNR {:.2f} dB, ΔE00 {:.2f}, MSSIM {:.4f}",
                        c.config.label(), human_bytes(double(c.bytes)), format_ratio(c.ratio),
                        c.bits_per_sample, c.encode_seconds, c.metrics.rmse, c.metrics.psnr,
                        c.metrics.de2000_mean, c.metrics.ssim_luminance);
                    if (c.cielab)
                        line += fmt::format(", BTF-CIELab {:.2f}", c.cielab->headline().mean);
                    std::printf("%s\n", line.c_str());
                }
                const std::string index = (report.folder / "index.html").string();
                std::printf("report: %s\n", index.c_str());
            }};
}

}  // namespace btf::cli

// btf info FILE: format, extent, sampling, sizes and value statistics.

#include <nlohmann/json.hpp>

#include <cstdio>

#include "btf/io/inspect.h"
#include "cli.h"

namespace btf::cli {

Command register_info(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string path;
        std::string views;
        OpenOptions open;
        int64_t sample = 256;
        bool all = false;
        bool json = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand("info",
                                       "Describe a BTF: format, extent, sampling, sizes, "
                                       "value statistics");
    cmd->add_option("file", args->path, "BTF file or folder (any format btfkit reads)")->required();
    cmd->add_option("--sample", args->sample,
                    "images to read for the statistics, spread over all (view, light) pairs")
        ->check(CLI::Range(int64_t{0}, int64_t{1} << 40));
    cmd->add_flag("--all", args->all, "statistics over every image");
    cmd->add_flag("--json", args->json, "print JSON instead of text");
    add_open_options(*cmd, args->open, args->views);

    return {cmd, [args, &global] {
                const auto source =
                    open_source(args->path, finish_open_options(args->open, args->views));
                Progress progress = make_progress(global);
                const ValueStats stats =
                    value_stats(*source, args->all ? 0 : args->sample, progress);
                const Sampling& s = source->sampling();
                const SourceInfo& info = source->info();
                const uint64_t on_disk = disk_usage(args->path);
                const double raw_float = double(source->raw_bytes());
                const double raw_8bit = raw_float / 4;

                if (args->json) {
                    nlohmann::json j;
                    j["file"] = args->path;
                    j["format"] = info.format;
                    j["width"] = source->width();
                    j["height"] = source->height();
                    j["views"] = {{"count", s.num_views()}, {"set", s.views.name()}};
                    j["lights"] = {{"count", s.num_lights()}, {"set", s.lights.name()}};
                    j["images"] = s.num_images();
                    j["hdr"] = info.hdr;
                    j["bytes_on_disk"] = on_disk;
                    j["bytes_raw_float32"] = source->raw_bytes();
                    j["statistics"] = {{"images", stats.images},
                                       {"min", stats.min},
                                       {"max", stats.max},
                                       {"mean", stats.mean},
                                       {"mean_luminance", stats.mean_luminance},
                                       {"non_finite", stats.non_finite}};
                    if (!info.note.empty()) j["note"] = info.note;
                    std::printf("%s\n", j.dump(2).c_str());
                    return;
                }
                auto row = [](const char* key, const std::string& value) {
                    std::printf("%-12s %s\n", key, value.c_str());
                };
                row("file", args->path);
                row("format", info.format + (info.hdr ? " (HDR)" : ""));
                row("extent", fmt::format("{} x {} texels", source->width(), source->height()));
                row("views", fmt::format("{} ({})", s.num_views(), s.views.name()));
                row("lights", fmt::format("{} ({})", s.num_lights(), s.lights.name()));
                row("images", fmt::format("{}", s.num_images()));
                row("on disk", human_bytes(double(on_disk)));
                row("raw size", fmt::format("{} as float32 RGB, {} as 8-bit RGB; on disk {:.1f}:1 "
                                            "smaller than float32",
                                            human_bytes(raw_float), human_bytes(raw_8bit),
                                            on_disk ? raw_float / double(on_disk) : 0.0));
                row("statistics",
                    fmt::format("over {} of {} images{}", stats.images, s.num_images(),
                                stats.images < s.num_images() ? " (--all for every image)" : ""));
                row("  min",
                    fmt::format("{:.4f} {:.4f} {:.4f}", stats.min[0], stats.min[1], stats.min[2]));
                row("  max",
                    fmt::format("{:.4f} {:.4f} {:.4f}", stats.max[0], stats.max[1], stats.max[2]));
                row("  mean", fmt::format("{:.4f} {:.4f} {:.4f} (luminance {:.4f})", stats.mean[0],
                                          stats.mean[1], stats.mean[2], stats.mean_luminance));
                if (stats.non_finite) row("  NaN/Inf", fmt::format("{} texels", stats.non_finite));
                if (!info.note.empty()) row("note", info.note);
            }};
}

}  // namespace btf::cli

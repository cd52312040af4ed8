// SPDX-License-Identifier: MIT
// btf info FILE: format, extent, sampling, sizes and value statistics; for a btfkit package its
// codec, parameters, ratio and sections.

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>

#include "btf/bsvtf/file.h"
#include "btf/codecs/codec.h"
#include "btf/codecs/factor/model.h"
#include "btf/io/inspect.h"
#include "btf/io/package.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

// Sections whose names differ only in numbers ("b0.k3", "b2.k17": one per component) are
// summarized together under the name with '*' for each number.
std::string section_kind(const std::string& name) {
    std::string kind;
    for (size_t i = 0; i < name.size(); ++i) {
        if (std::isdigit(static_cast<unsigned char>(name[i]))) {
            if (kind.empty() || kind.back() != '*') kind += '*';
        } else {
            kind += name[i];
        }
    }
    return kind;
}

struct SectionGroup {
    std::string kind;
    int count = 0, zstd = 0;
    uint64_t stored = 0, decoded = 0;
};

std::vector<SectionGroup> group_sections(const Package& package) {
    std::vector<SectionGroup> groups;
    for (const PackageSection& s : package.sections) {
        const std::string kind = section_kind(s.name);
        auto it = std::find_if(groups.begin(), groups.end(),
                               [&](const SectionGroup& g) { return g.kind == kind; });
        if (it == groups.end()) it = groups.insert(groups.end(), SectionGroup{kind});
        ++it->count;
        it->zstd += s.coding == SectionCoding::kZstd ? 1 : 0;
        it->stored += s.stored_size;
        it->decoded += s.data.size();
    }
    return groups;
}

std::string param_text(const nlohmann::json& value) {
    if (value.is_string()) return value.get<std::string>();
    // Parameters stored as float show as typed, not with float32's binary digits.
    if (value.is_number_float()) return fmt::format("{:g}", value.get<double>());
    return value.dump();
}

// A BSVTF file (btf bsvtf): the fmf material it comes from and its tiles.
void bsvtf_info(const std::string& path, const Package& package, bool json) {
    const bsvtf::Bsvtf b = bsvtf::read_bsvtf(package, path);
    const bsvtf::TileLayout& l = b.layout;
    uint64_t u_bytes = 0;
    for (size_t g = 0; g < l.groups().size(); ++g)
        u_bytes += package.at(fmt::format("u{}", g)).data.size();
    int components = 0;
    for (const bsvtf::Group& g : l.groups()) components += g.count;
    const Sampling& s = b.model.sampling;
    if (json) {
        nlohmann::json j;
        j["file"] = path;
        j["format"] = "btfkit BSVTF";
        j["width"] = l.width();
        j["height"] = l.height();
        j["views"] = {{"count", s.num_views()}, {"set", s.views.name()}};
        j["lights"] = {{"count", s.num_lights()}, {"set", s.lights.name()}};
        j["components"] = components;
        j["groups"] = l.groups().size();
        j["levels"] = l.levels();
        j["tile"] = l.geometry().tile;
        j["pad"] = l.geometry().pad;
        j["tiles"] = l.tile_count();
        j["tile_bytes"] = b.payloads.size();
        j["u_bytes"] = u_bytes;
        j["step"] = b.step;
        j["relative_error"] = b.relative_error;
        j["bytes_on_disk"] = package.file_bytes;
        std::printf("%s\n", j.dump(2).c_str());
        return;
    }
    std::printf("%s\n", path.c_str());
    std::printf("  format       btfkit BSVTF (btf bsvtf), from an fmf package\n");
    std::printf("  extent       %d × %d texels, %d views × %d lights (%s / %s)\n", l.width(),
                l.height(), s.num_views(), s.num_lights(), s.views.name().c_str(),
                s.lights.name().c_str());
    std::printf("  components   %d in %zu groups of 4, colour %s\n", components, l.groups().size(),
                factor::to_string(b.model.colour.basis).c_str());
    std::printf("  tiles        %zu: %d levels of %d × %d texels + %d padding\n", l.tile_count(),
                l.levels(), l.geometry().tile, l.geometry().tile, l.geometry().pad);
    std::printf("  tile data    %s, %s\n", human_bytes(double(b.payloads.size())).c_str(),
                b.step > 0 ? fmt::format("DCT, relative error at most {}", b.relative_error).c_str()
                           : "lossless");
    std::printf("  U packets    %s\n", human_bytes(double(u_bytes)).c_str());
    std::printf("  on disk      %s\n", human_bytes(double(package.file_bytes)).c_str());
}

void package_info(const std::string& path, bool json) {
    const Package package = read_package(path);
    if (package.codec() == "bsvtf") return bsvtf_info(path, package, json);
    // Opening checks the package through its codec and gives extent and sampling for any codec.
    // A package of several materials (mlvq's shared code-books) is described by its first; its
    // ratio counts them all.
    std::vector<std::unique_ptr<Material>> materials;
    try {
        materials = open_materials(package);
    } catch (const Cancelled&) {
        throw;
    } catch (const Error& e) {
        fail("{}: {}", path, e.what());
    }
    const Material* material = materials.front().get();
    const Sampling& s = material->sampling();
    double raw_8bit = 0;
    for (const auto& m : materials)
        raw_8bit +=
            double(m->width()) * double(m->height()) * double(m->sampling().num_images()) * 3.0;
    const double bytes = double(package.file_bytes);
    const nlohmann::json params = package.header.value("params", nlohmann::json::object());
    std::string quantization;
    if (const auto m = package.header.find("model"); m != package.header.end() && m->is_object() &&
                                                     m->contains("quantization") &&
                                                     (*m)["quantization"].is_string())
        quantization = (*m)["quantization"].get<std::string>();
    const std::vector<SectionGroup> groups = group_sections(package);
    const int present = static_cast<int>(package.sections.size());

    if (json) {
        nlohmann::json j;
        j["file"] = path;
        j["format"] = "btfkit package";
        j["codec"] = package.codec();
        j["params"] = params;
        j["width"] = material->width();
        j["height"] = material->height();
        j["views"] = {{"count", s.num_views()}, {"set", s.views.name()}};
        j["lights"] = {{"count", s.num_lights()}, {"set", s.lights.name()}};
        j["images"] = s.num_images();
        if (!quantization.empty()) j["quantization"] = quantization;
        j["bytes_on_disk"] = package.file_bytes;
        j["bytes_raw_8bit"] = static_cast<uint64_t>(raw_8bit);
        j["ratio_vs_8bit"] = bytes > 0 ? raw_8bit / bytes : 0.0;
        j["sections"] = {{"present", present},
                         {"declared", package.declared_sections},
                         {"prefix", !package.complete()}};
        nlohmann::json stored = nlohmann::json::array();
        for (const SectionGroup& g : groups)
            stored.push_back({{"kind", g.kind},
                              {"count", g.count},
                              {"zstd", g.zstd},
                              {"stored_bytes", g.stored},
                              {"decoded_bytes", g.decoded}});
        j["sections"]["stored"] = stored;
        if (const auto t = package.header.find("codebook_table"); t != package.header.end()) {
            j["codebooks"] = *t;
            nlohmann::json ratios = nlohmann::json::array();
            for (const auto& b : package.header.at("storage_bytes"))
                ratios.push_back(raw_8bit / std::max(1.0, b.get<double>()));
            j["compression_ratios"] = ratios;
        }
        std::printf("%s\n", j.dump(2).c_str());
        return;
    }
    auto row = [](const std::string& key, const std::string& value) {
        std::printf("%-12s %s\n", key.c_str(), value.c_str());
    };
    std::vector<std::string> items;
    for (const auto& [key, value] : params.items()) items.push_back(key + "=" + param_text(value));
    row("file", path);
    row("format", fmt::format("btfkit package, codec {}", package.codec()));
    row("parameters",
        items.empty() ? "(codec defaults)" : fmt::format("{}", fmt::join(items, " ")));
    row("extent", fmt::format("{} x {} texels", material->width(), material->height()));
    row("views", fmt::format("{} ({})", s.num_views(), s.views.name()));
    row("lights", fmt::format("{} ({})", s.num_lights(), s.lights.name()));
    row("images", fmt::format("{}", s.num_images()));
    if (!quantization.empty()) row("quantization", quantization);
    row("on disk", human_bytes(bytes));
    row("ratio",
        fmt::format("{} vs 8-bit RGB raw ({})", format_ratio(bytes > 0 ? raw_8bit / bytes : 0.0),
                    human_bytes(raw_8bit)));
    row("sections", package.complete()
                        ? fmt::format("{} of {} (complete)", present, package.declared_sections)
                        : fmt::format("{} of {}: a prefix, decoded as a lower-quality material",
                                      present, package.declared_sections));
    for (const SectionGroup& g : groups) {
        std::string coding = g.zstd == g.count ? "zstd"
                             : g.zstd == 0
                                 ? "raw"
                                 : fmt::format("{} zstd, {} raw", g.zstd, g.count - g.zstd);
        row("  " + g.kind,
            fmt::format("{}{} stored ({}), {} decoded",
                        g.count > 1 ? fmt::format("{} sections, ", g.count) : "",
                        human_bytes(double(g.stored)), coding, human_bytes(double(g.decoded))));
    }
    // Vector-quantization packages (mlvq): code-book sizes as in Table 3 of Havran et al. 2010,
    // and the compression ratios of its Table 2's four representations.
    if (const auto t = package.header.find("codebook_table"); t != package.header.end()) {
        row("code-books", "entries, bytes stored (compact indices, 8/16-bit values)");
        for (const auto& b : *t)
            row("  " + b.at("name").get<std::string>(),
                fmt::format("{:>9} {:>12}", b.at("entries").get<int64_t>(),
                            human_bytes(b.at("bytes").get<double>())));
        // The code-books may serve several materials: ratios against all of them.
        double raw_all = 0;
        for (const auto& m : package.header.at("materials"))
            raw_all += m.at("width").get<double>() * m.at("height").get<double>() *
                       double(m.at("views").at("theta").size()) *
                       double(m.at("lights").at("theta").size()) * 3;
        if (package.header.at("materials").size() > 1)
            row("materials",
                fmt::format("{} sharing the code-books", package.header.at("materials").size()));
        const auto& sizes = package.header.at("storage_bytes");
        const char* names[] = {"C.R.1 (32-bit indices and floats)", "C.R.2 (compact indices)",
                               "C.R.3 (8/16-bit floats)", "C.R.4 (both; as stored)"};
        for (size_t i = 0; i < 4 && i < sizes.size(); ++i)
            row(i == 0 ? "ratios" : "",
                fmt::format("{} {}", format_ratio(raw_all / std::max(1.0, sizes[i].get<double>())),
                            names[i]));
    }
}

}  // namespace

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
    cmd->add_option("file", args->path,
                    "BTF file or folder (any format btfkit reads), or a btfkit package")
        ->required();
    cmd->add_option("--sample", args->sample,
                    "images to read for the statistics, spread over all (view, light) pairs")
        ->check(CLI::Range(int64_t{0}, int64_t{1} << 40));
    cmd->add_flag("--all", args->all, "statistics over every image");
    cmd->add_flag("--json", args->json, "print JSON instead of text");
    add_open_options(*cmd, args->open, args->views);

    return {cmd, [args, &global] {
                if (probe_package(args->path)) {
                    if (!args->views.empty() || args->open.encoding != Encoding::kLinear)
                        fail("{}: --views and --raw do not apply to a btfkit package", args->path);
                    package_info(args->path, args->json);
                    return;
                }
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

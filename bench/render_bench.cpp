// SPDX-License-Identifier: MIT
// The renderer with BTF materials (docs/benchmarks.md, "Renderer"): for synthetic presets
// (64² texels × 81 × 81 by default) compressed with fmf (C = 16, rgb) and mlvq (default
// threshold), on the demo scene (a sphere and a cloth drape on a floor under a procedural sky):
//
//  1. throughput: paths per second at 512² on all cores (path integrator, max depth 6);
//  2. variance reduction: the RMSE of the linear image against a long reference render, after
//     the same wall time with the material's importance sampling and with cosine-weighted
//     sampling (the other strategies of the MIS stay), over the pixels that see a BTF object;
//  3. generic against native sampling on the mlvq material: paths per second and the RMSE at
//     equal time, the generic tabulated sampler against mlvq's code-book sampler.
// Prints Markdown.
//
//   build/<dir>/render_bench [--presets brushed_metal,lacquered_wood,ceramic_tiles,woven_fabric]
//                            [--texels 64] [--size 256] [--seconds 8] [--reference-spp 1024]

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/codec.h"
#include "btf/core/light_sampler.h"
#include "btf/io/package.h"
#include "btf/render/renderer.h"
#include "btf/synth/synth.h"
#include "demo_scene.h"

using namespace btf;
using render::BtfSurface;
using render::Camera;
using render::DiffuseSurface;
using render::EnvironmentLight;
using render::EnvironmentMap;
using render::Hit;
using render::RenderOptions;
using render::RenderResult;
using render::SamplingMode;
using render::Scene;
using render::SceneObject;
using render::Transform;

namespace {

using bench::btf_mask;
using bench::demo_scene;

std::shared_ptr<const Material> compress(const BtfSource& source, const std::string& codec,
                                         const Params& params) {
    Package package = find_codec(codec).encode(source, params);
    const std::vector<uint8_t> bytes = encode_package(package);
    return open_material(decode_package(bytes, codec + " package"));
}

struct Timed {
    double rmse = 0;
    int spp = 0;
};

// Renders for `seconds` (seed 1; the reference used another seed) and measures the RMSE.
Timed at_equal_time(const Scene& scene, double seconds, const Image& reference,
                    const std::vector<bool>& mask) {
    RenderOptions options;
    options.spp = 0;
    options.time_limit = seconds;
    options.integrator.max_depth = 6;
    const RenderResult r = render::render(scene, options);
    return {bench::masked_error(r.color, reference, mask).rmse, r.spp};
}

}  // namespace

int main(int argc, char** argv) {
    std::string presets_text = "brushed_metal,lacquered_wood,ceramic_tiles,woven_fabric";
    int texels = 64, size = 256, reference_spp = 1024;
    double seconds = 8;
    CLI::App app{"The renderer: throughput, BTF importance sampling against cosine sampling"};
    app.add_option("--presets", presets_text, "synthetic presets, comma-separated")
        ->capture_default_str();
    app.add_option("--texels", texels, "texels per side of the materials")->capture_default_str();
    app.add_option("--size", size, "image width for the variance measurements")
        ->capture_default_str();
    app.add_option("--seconds", seconds, "render time of each equal-time render")
        ->capture_default_str();
    app.add_option("--reference-spp", reference_spp, "samples per pixel of the reference renders")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    std::vector<std::string> presets;
    {
        std::stringstream in(presets_text);
        for (std::string p; std::getline(in, p, ',');) presets.push_back(p);
    }
    try {
        const DirectionSet& ubo = DirectionSet::ubo81();
        std::printf(
            "| material (%d² texels) | codec | paths/s at 512² (all cores) | reference spp | "
            "spp in %.0f s: IS / cosine | RMSE: IS | RMSE: cosine | cosine / IS |\n"
            "|---|---|---|---|---|---|---|---|\n",
            texels, seconds);
        std::vector<std::string> generic_rows, table_rows;
        for (const std::string& preset : presets) {
            const auto source = synth::make(preset, texels, {ubo, ubo}, 1);
            const std::shared_ptr<const Material> fmf =
                compress(*source, "fmf", {{"components", "16"}, {"colour", "rgb"}});
            const std::shared_ptr<const Material> mlvq = compress(*source, "mlvq", {});
            for (const auto& [codec, material] : {std::pair{"fmf C=16", fmf}, {"mlvq", mlvq}}) {
                // Throughput at 512².
                const Scene big = demo_scene(material, SamplingMode::kMaterial, 512);
                RenderOptions options;
                options.spp = 4;
                options.integrator.max_depth = 6;
                // The first pass builds the generic sampler's tables (fmf; mlvq samples
                // natively and builds none): its extra time over a second pass is their cost.
                const RenderOptions one{1, 0, 9, false, options.integrator};
                const double first = render::render(big, one).seconds;
                const double second = render::render(big, one).seconds;
                if (material == fmf)
                    table_rows.push_back(
                        fmt::format("| {} | {:.2f} s | {:.2f} s | {} tables, {:.1f} MiB |", preset,
                                    first, second, material->generic_sampler().tables_built(),
                                    double(material->generic_sampler().tables_built() *
                                           material->generic_sampler().table_bytes()) /
                                        (1 << 20)));
                const RenderResult t = render::render(big, options);
                const double paths_per_second = double(t.paths()) / t.seconds;

                // The reference and the equal-time renders.
                const Scene scene = demo_scene(material, SamplingMode::kMaterial, size);
                const Scene cosine = demo_scene(material, SamplingMode::kCosine, size);
                const std::vector<bool> mask = btf_mask(scene);
                RenderOptions ref_options;
                ref_options.spp = reference_spp;
                ref_options.seed = 12345;
                ref_options.integrator.max_depth = 6;
                const Image reference = render::render(scene, ref_options).color;
                const Timed is = at_equal_time(scene, seconds, reference, mask);
                const Timed cos = at_equal_time(cosine, seconds, reference, mask);
                std::printf("| %s | %s | %.2f M | %d | %d / %d | %.4f | %.4f | **%.2f×** |\n",
                            preset.c_str(), codec, paths_per_second / 1e6, reference_spp, is.spp,
                            cos.spp, is.rmse, cos.rmse, cos.rmse / is.rmse);
                std::fflush(stdout);
                if (material == mlvq) {
                    const Scene generic = demo_scene(material, SamplingMode::kGeneric, size);
                    const Scene generic_big = demo_scene(material, SamplingMode::kGeneric, 512);
                    render::render(generic_big, {1, 0, 9, false, options.integrator});
                    const RenderResult g = render::render(generic_big, options);
                    const Timed gt = at_equal_time(generic, seconds, reference, mask);
                    generic_rows.push_back(fmt::format(
                        "| {} | {:.2f} M | {:.2f} M | {} / {} | {:.4f} | {:.4f} |", preset,
                        paths_per_second / 1e6, double(g.paths()) / g.seconds / 1e6, is.spp, gt.spp,
                        is.rmse, gt.rmse));
                }
            }
        }
        std::printf(
            "\n| mlvq material | paths/s, native sampling | paths/s, generic sampler | spp in "
            "%.0f s: native / generic | RMSE: native | RMSE: generic "
            "|\n|---|---|---|---|---|---|\n",
            seconds);
        for (const std::string& row : generic_rows) std::printf("%s\n", row.c_str());
        std::printf(
            "\n| fmf material | first 1-spp pass at 512² (builds the generic sampler's tables) | "
            "second pass | tables |\n|---|---|---|---|\n");
        for (const std::string& row : table_rows) std::printf("%s\n", row.c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "render_bench: %s\n", e.what());
        return 1;
    }
}

// btf render SCENE.json -o OUT.png|OUT.exr: renders a scene (docs/scenes.md) with the CPU path
// tracer; the command line overrides the scene's "render" block.

#include <cstdio>

#include "btf/render/renderer.h"
#include "btf/render/scene_file.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

Command register_render(CLI::App& app, GlobalOptions& global) {
    struct Args {
        std::string scene, output, integrator, sampling = "material", size;
        int spp = -1, max_depth = -1;
        double time = -1, exposure = NAN;
        int64_t seed = -1;
        bool aovs = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "render",
        "Render a scene (JSON, see docs/scenes.md) with BTF materials: path tracing on "
        "all cores, EXR (linear) or PNG (tone-mapped) output");
    cmd->add_option("scene", args->scene, "scene file (.json)")->required();
    cmd->add_option("-o,--output", args->output,
                    "output image: .png (tone-mapped) or .exr (linear)")
        ->required();
    cmd->add_option("--spp", args->spp, "samples per pixel (0 = until --time)")
        ->check(CLI::Range(0, 1 << 20));
    cmd->add_option("--time", args->time, "stop after this many seconds")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--integrator", args->integrator, "path or direct")
        ->check(CLI::IsMember({"path", "direct"}));
    cmd->add_option("--max-depth", args->max_depth, "surface interactions per path (path)")
        ->check(CLI::Range(1, 1000));
    cmd->add_option("--seed", args->seed, "random seed")
        ->check(CLI::Range(int64_t(0), int64_t(INT32_MAX)));
    cmd->add_option("--size", args->size,
                    "image size 'width,height' (default: the scene's camera)");
    cmd->add_option("--exposure", args->exposure, "exposure in EV for the tone-mapped PNG");
    cmd->add_option("--sampling", args->sampling,
                    "how BTF surfaces draw light directions: material (their importance "
                    "sampling) or cosine")
        ->check(CLI::IsMember({"material", "cosine"}));
    cmd->add_flag("--aov", args->aovs,
                  "also write <out>.albedo.exr, <out>.normal.exr, <out>.uv.exr");

    return {cmd, [args, &global] {
                render::LoadOptions load;
                load.sampling = args->sampling == "cosine" ? render::SamplingMode::kCosine
                                                           : render::SamplingMode::kMaterial;
                render::LoadedScene loaded = render::load_scene(args->scene, load);
                render::RenderOptions options = loaded.settings.options;
                if (args->integrator == "direct") options.integrator.max_depth = 1;
                if (args->integrator == "path" && options.integrator.max_depth == 1)
                    options.integrator.max_depth = 8;
                if (args->max_depth > 0) {
                    if (options.integrator.max_depth == 1 && args->integrator != "path")
                        fail("--max-depth applies to the path integrator");
                    options.integrator.max_depth = args->max_depth;
                }
                if (args->spp >= 0) options.spp = args->spp;
                if (args->time >= 0) options.time_limit = args->time;
                if (args->spp == 0 && options.time_limit <= 0) fail("--spp 0 needs --time");
                if (args->seed >= 0) options.seed = uint64_t(args->seed);
                if (!args->size.empty()) {
                    const auto [w, h] = parse_pair(args->size, "--size");
                    if (w <= 0 || h <= 0 || w > 16384 || h > 16384)
                        fail("--size {}: width and height must be 1 to 16384", args->size);
                    loaded.scene.camera.width = w;
                    loaded.scene.camera.height = h;
                }
                options.aovs = args->aovs;
                const double exposure =
                    std::isnan(args->exposure) ? loaded.settings.exposure : args->exposure;
                Progress progress = make_progress(global);
                const render::RenderResult result = render::render(loaded.scene, options, progress);
                render::write_render(args->output, result, exposure);
                if (!global.quiet)
                    std::printf("%s: %d × %d, %d samples per pixel, %.1f s (%.2f M paths/s)\n",
                                args->output.c_str(), result.color.width(), result.color.height(),
                                result.spp, result.seconds,
                                double(result.paths()) / result.seconds / 1e6);
            }};
}

}  // namespace btf::cli

// SPDX-License-Identifier: MIT
// btf render SCENE.json -o OUT.png|OUT.exr: renders a scene (docs/scenes.md) with the CPU path
// tracer; the command line overrides the scene's "render" block, and --material the scene's BTF
// materials.

#include <cstdio>
#include <fstream>

#include <nlohmann/json.hpp>

#include "btf/core/image.h"
#include "btf/quality/render_compare.h"
#include "btf/render/renderer.h"
#include "btf/render/scene_file.h"
#include "btf/util/atomic_file.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

struct RenderArgs {
    std::string scene, output, integrator, sampling = "material", size, filter, material;
    int spp = -1, max_depth = -1;
    double time = -1, exposure = NAN;
    int64_t seed = -1;
    bool aovs = false;
    std::vector<std::string> compare;
};

using render::RenderSetup;

// The scene's "render" block with the command line's overrides applied.
RenderSetup setup_render(const RenderArgs& args, render::LoadedScene& loaded) {
    render::RenderOverrides o;
    o.integrator = args.integrator;
    o.spp = args.spp;
    o.max_depth = args.max_depth;
    o.time_limit = args.time;
    o.seed = args.seed;
    o.filter = args.filter;
    if (!args.size.empty()) std::tie(o.width, o.height) = parse_pair(args.size, "--size");
    if (!args.size.empty() && (o.width <= 0 || o.height <= 0))
        fail("--size {}: width and height must be 1 to 16384", args.size);
    o.aovs = args.aovs;
    o.exposure = args.exposure;
    return render::apply_overrides(loaded, o);
}

void print_result(const std::string& name, const render::RenderResult& result) {
    std::printf("%s: %d × %d, %d samples per pixel, %.1f s (%.2f M paths/s)\n", name.c_str(),
                result.color.width(), result.color.height(), result.spp, result.seconds,
                double(result.paths()) / result.seconds / 1e6);
    if (result.dropped)
        std::fprintf(stderr, "btf: warning: %llu samples were not finite and were left out\n",
                     static_cast<unsigned long long>(result.dropped));
}

// <stem><suffix> beside `output`.
std::string sibling(const std::string& output, const std::string& suffix) {
    const std::filesystem::path p(output);
    return ((p.parent_path() / p.stem()).string() + suffix);
}

void run_compare(const RenderArgs& args, render::LoadOptions load, const GlobalOptions& global) {
    const std::string ext = lower_extension(args.output);
    if (output_kind(args.output) != OutputKind::kOther || is_float_image_format(args.output))
        fail("{}: --compare writes a picture: give a .png or .jpg output", args.output);
    if (args.aovs) fail("--aov does not apply to --compare");
    const std::string outputs[4] = {args.output, sibling(args.output, ".a" + ext),
                                    sibling(args.output, ".b" + ext),
                                    sibling(args.output, ".diff" + ext)};
    for (const std::string& out : outputs) check_image_output(out);
    const std::string json_path = sibling(args.output, ".json");
    { const AtomicOutput probe(json_path); }

    render::RenderResult results[2];
    RenderSetup setup;
    for (int i = 0; i < 2; ++i) {
        // One material in memory at a time (raw data can take gigabytes).
        load.btf_override = render::open_material_file(args.compare[size_t(i)]);
        render::LoadedScene loaded = render::load_scene(args.scene, load);
        if (loaded.btf_objects == 0)
            fail("{}: --compare needs an object with a \"btf\" material", args.scene);
        setup = setup_render(args, loaded);
        if (i == 1) {
            // B gets exactly A's samples per pixel (A may have stopped at a time limit).
            setup.options.spp = results[0].spp;
            setup.options.time_limit = 0;
        }
        Progress progress = make_progress(global);
        results[i] = render::render(loaded.scene, setup.options, progress);
        if (!global.quiet) print_result(args.compare[size_t(i)], results[i]);
    }
    const quality::RenderComparison c =
        quality::compare_renders(results[0].color, results[1].color, setup.exposure);
    const Image a = quality::tone_map(results[0].color, setup.exposure);
    const Image b = quality::tone_map(results[1].color, setup.exposure);
    nlohmann::json metrics = quality::metrics_json(c);
    metrics.update({{"a", args.compare[0]},
                    {"b", args.compare[1]},
                    {"scene", args.scene},
                    {"spp", results[0].spp},
                    {"exposure", setup.exposure}});
    AtomicOutputSet files;  // all five files or none
    write_image(files.add(outputs[0]), quality::side_by_side(a, b, c.heat_map));
    write_image(files.add(outputs[1]), a);
    write_image(files.add(outputs[2]), b);
    write_image(files.add(outputs[3]), c.heat_map);
    {
        std::ofstream out(files.add(json_path));
        out << metrics.dump(2) << "\n";
        if (!out) fail("{}: cannot write", json_path);
    }
    files.commit();
    std::printf("A: %s\nB: %s\n%s\n%s: A | B | ΔE00 from 0 (dark) to %g (bright)\n",
                args.compare[0].c_str(), args.compare[1].c_str(), quality::summary(c).c_str(),
                args.output.c_str(), c.heat_max);
}

}  // namespace

Command register_render(CLI::App& app, GlobalOptions& global) {
    auto args = std::make_shared<RenderArgs>();
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
                    "how BTF surfaces draw light directions: material (their own importance "
                    "sampling), generic (the tabulated sampler, even for mlvq) or cosine")
        ->check(CLI::IsMember({"material", "generic", "cosine"}));
    cmd->add_option("--filter", args->filter,
                    "how BTF materials are filtered at a path vertex: stochastic (one texel, view "
                    "and light drawn by their weights; unbiased and faster; the default unless "
                    "the scene says otherwise) or deterministic (every term)")
        ->check(CLI::IsMember({"stochastic", "deterministic"}));
    cmd->add_flag("--aov", args->aovs,
                  "also write <out>.albedo.exr, <out>.normal.exr, <out>.uv.exr");
    CLI::Option* material = cmd->add_option(
        "--material", args->material,
        "render every object with a \"btf\" material with this one instead (any package, .btf "
        "or raw BTF; 'demo': the built-in demo material, made once in the cache folder as for "
        "btf serve); the scene's \"file\" is then not opened");
    cmd->add_option("--compare", args->compare,
                    "render the scene twice, every BTF material replaced by A, then by B (any "
                    "package, .btf or raw BTF), and write A | B | ΔE00 heat map to the output, "
                    "<out>.a.png, <out>.b.png, <out>.diff.png and the metrics in <out>.json")
        ->expected(2)
        ->excludes(material);

    return {cmd, [args, &global] {
                render::LoadOptions load;
                load.sampling = args->sampling == "cosine"    ? render::SamplingMode::kCosine
                                : args->sampling == "generic" ? render::SamplingMode::kGeneric
                                                              : render::SamplingMode::kMaterial;
                if (args->compare.empty()) {
                    render::check_render_output(args->output, args->aovs);
                    if (args->material == "demo")
                        load.btf_override = render::open_material_file(demo_package(global));
                    else if (!args->material.empty())
                        load.btf_override = render::open_material_file(args->material);
                    render::LoadedScene loaded = render::load_scene(args->scene, load);
                    if (!args->material.empty() && loaded.btf_objects == 0)
                        fail("{}: --material needs an object with a \"btf\" material", args->scene);
                    const RenderSetup setup = setup_render(*args, loaded);
                    Progress progress = make_progress(global);
                    const render::RenderResult result =
                        render::render(loaded.scene, setup.options, progress);
                    render::write_render(args->output, result, setup.exposure);
                    if (!global.quiet) print_result(args->output, result);
                    return;
                }
                run_compare(*args, load, global);
            }};
}

}  // namespace btf::cli

// Stochastic against deterministic filtering in the renderer at equal time (docs/benchmarks.md,
// "Stochastic filtering"): for each package given, the demo scene of scripts/demo.sh (a sphere
// and a cloth drape of the material on a grey floor under the procedural sky, path tracing with
// MIS, maximum depth 6):
//
//  1. a reference rendered with the deterministic filter at --reference-spp samples per pixel
//     (seed 12345): the image both filters converge to (for codecs whose decoding after
//     interpolation is linear, as fmf and mlvq with YCbCr), after a 1-spp pass with each filter
//     that builds what is built on first use (the generic sampler's tables);
//  2. for each T of --seconds, one render of T seconds with each filter (seed 1): its samples
//     per pixel and paths per second (all cores), the RMSE of linear radiance against the
//     reference over the pixels that see a BTF object, and the ratio deterministic / stochastic
//     (> 1: stochastic is closer at equal time);
//  3. the mean radiance over those pixels of the longest renders against the reference's, as a
//     multiple of its standard error (RMSE / √(3 · pixels)): unbiased renders stay within a few.
// Prints Markdown.
//
//   build/<dir>/filter_bench PACKAGE... [--size 256] [--seconds 5,20,60] [--reference-spp 1024]

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "btf/codecs/codec.h"
#include "btf/render/renderer.h"
#include "demo_scene.h"

using namespace btf;
using render::BtfSurface;
using render::DiffuseSurface;
using render::EnvironmentLight;
using render::EnvironmentMap;
using render::Hit;
using render::RenderOptions;
using render::RenderResult;
using render::Scene;
using render::SceneObject;
using render::Transform;

namespace {

// The demo scene with the material's own importance sampling.
Scene scene_of(std::shared_ptr<const Material> material, int width) {
    return bench::demo_scene(std::move(material), render::SamplingMode::kMaterial, width);
}

RenderOptions options_for(Filter filter) {
    RenderOptions o;
    o.integrator.max_depth = 6;
    o.integrator.filter = filter;
    return o;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<std::string> packages;
    std::string seconds_text = "5,20,60";
    int size = 256, reference_spp = 1024;
    CLI::App app{"Stochastic against deterministic filtering in the renderer at equal time"};
    app.add_option("packages", packages, "materials (any package or UBO2014 file)")->required();
    app.add_option("--size", size, "image width for the RMSE measurements")->capture_default_str();
    app.add_option("--seconds", seconds_text, "render times, comma-separated")
        ->capture_default_str();
    app.add_option("--reference-spp", reference_spp, "samples per pixel of the reference")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    std::vector<double> seconds;
    {
        std::stringstream in(seconds_text);
        for (std::string s; std::getline(in, s, ',');) seconds.push_back(std::stod(s));
    }
    try {
        std::vector<std::string> means;
        std::printf(
            "| material | T | spp: deterministic / stochastic | paths/s: deterministic / "
            "stochastic | RMSE: deterministic | RMSE: stochastic | deterministic / stochastic "
            "|\n|---|---|---|---|---|---|---|\n");
        for (const std::string& path : packages) {
            const std::shared_ptr<const Material> material(open_material(path));
            const std::string name = std::filesystem::path(path).filename().string();
            const Scene scene = scene_of(material, size);
            for (const Filter filter : {Filter::kDeterministic, Filter::kStochastic}) {
                RenderOptions o = options_for(filter);
                o.spp = 1;
                render::render(scene, o);
            }
            const std::vector<bool> mask = bench::btf_mask(scene);
            RenderOptions ref_options = options_for(Filter::kDeterministic);
            ref_options.spp = reference_spp;
            ref_options.seed = 12345;
            const Image reference = render::render(scene, ref_options).color;
            bench::MaskedError last[2];
            for (const double t : seconds) {
                bench::MaskedError s[2];
                int spp[2];
                double rate[2];
                for (int f = 0; f < 2; ++f) {
                    RenderOptions o =
                        options_for(f == 0 ? Filter::kDeterministic : Filter::kStochastic);
                    o.spp = 0;
                    o.time_limit = t;
                    const RenderResult r = render::render(scene, o);
                    s[f] = bench::masked_error(r.color, reference, mask);
                    spp[f] = r.spp;
                    rate[f] = double(r.paths()) / r.seconds;
                    last[f] = s[f];
                }
                std::printf(
                    "| %s | %.0f s | %d / %d | %.2f M / %.2f M | %.4f | %.4f | **%.2f×** |\n",
                    name.c_str(), t, spp[0], spp[1], rate[0] / 1e6, rate[1] / 1e6, s[0].rmse,
                    s[1].rmse, s[0].rmse / s[1].rmse);
                std::fflush(stdout);
            }
            const bench::MaskedError ref = bench::masked_error(reference, reference, mask);
            std::string row = fmt::format("| {} | {:.5f} |", name, ref.mean);
            for (int f = 0; f < 2; ++f) {
                const double se = last[f].rmse / std::sqrt(last[f].values);
                row += fmt::format(" {:.5f} ({:+.2f} SE) |", last[f].mean,
                                   (last[f].mean - ref.mean) / se);
            }
            means.push_back(row);
        }
        std::printf(
            "\n| material | mean radiance of the BTF pixels: reference | deterministic, %.0f s | "
            "stochastic, %.0f s |\n|---|---|---|---|\n",
            seconds.back(), seconds.back());
        for (const std::string& row : means) std::printf("%s\n", row.c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "filter_bench: %s\n", e.what());
        return 1;
    }
}

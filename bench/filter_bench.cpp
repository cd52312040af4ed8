// SPDX-License-Identifier: MIT
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
// With --variance-spp N, first (and with --seconds "" only) the two costs that decide the
// equal-time comparison, each measured apart, without a reference and its noise: the variance
// of one path's estimate per filter, from two renders of N spp with different seeds
// (E[(a − b)²] = 2 σ² / N over the BTF pixels' values), and the paths per second of those
// renders, in the order deterministic, stochastic, stochastic, deterministic so that a drifting
// machine speed falls on both. The equal-time RMSE ratio of unbiased renders follows:
// √((σ²_det / rate_det) / (σ²_sto / rate_sto)).
// Prints Markdown.
//
//   build/<dir>/filter_bench PACKAGE... [--size 256] [--seconds 5,20,60] [--reference-spp 1024]
//                                       [--variance-spp N] [--variance-seed S]

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

// A material's scene, rendered once at 1 spp with each filter first (so that the measured
// renders find the generic sampler's tables built), and the mask of its BTF pixels.
struct Prepared {
    std::string name;
    Scene scene;
    std::vector<bool> mask;
};
Prepared prepare(const std::string& path, int size) {
    const std::shared_ptr<const Material> material(open_material(path));
    Prepared p{std::filesystem::path(path).filename().string(), scene_of(material, size), {}};
    for (const Filter filter : {Filter::kDeterministic, Filter::kStochastic}) {
        RenderOptions o = options_for(filter);
        o.spp = 1;
        render::render(p.scene, o);
    }
    p.mask = bench::btf_mask(p.scene);
    return p;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<std::string> packages;
    std::string seconds_text = "5,20,60";
    int size = 256, reference_spp = 1024, variance_spp = 0;
    uint64_t variance_seed = 101;
    CLI::App app{"Stochastic against deterministic filtering in the renderer at equal time"};
    app.add_option("packages", packages, "materials (any package or UBO2014 file)")->required();
    app.add_option("--size", size, "image width for the RMSE measurements")->capture_default_str();
    app.add_option("--seconds", seconds_text, "render times, comma-separated")
        ->capture_default_str();
    app.add_option("--reference-spp", reference_spp, "samples per pixel of the reference")
        ->capture_default_str();
    app.add_option("--variance-spp", variance_spp,
                   "samples per pixel of the variance and speed measurement (0: none)")
        ->capture_default_str();
    app.add_option("--variance-seed", variance_seed,
                   "seed of the first variance render (the second takes the next)")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    std::vector<double> seconds;
    {
        std::stringstream in(seconds_text);
        for (std::string s; std::getline(in, s, ',');) seconds.push_back(std::stod(s));
    }
    try {
        if (variance_spp > 0) {
            std::printf(
                "| material | spp | variance per path: deterministic / stochastic | stochastic / "
                "deterministic | paths/s: deterministic / stochastic | equal-time RMSE, "
                "deterministic / stochastic |\n|---|---|---|---|---|---|\n");
            for (const std::string& path : packages) {
                const auto [name, scene, mask] = prepare(path, size);
                Image image[2][2];
                double paths[2] = {0, 0}, seconds_spent[2] = {0, 0};
                const std::pair<int, int> order[] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
                for (const auto& [f, k] : order) {
                    RenderOptions o =
                        options_for(f == 0 ? Filter::kDeterministic : Filter::kStochastic);
                    o.spp = variance_spp;
                    o.seed = variance_seed + uint64_t(k);
                    RenderResult r = render::render(scene, o);
                    paths[f] += double(r.paths());
                    seconds_spent[f] += r.seconds;
                    image[f][k] = std::move(r.color);
                }
                double variance[2], rate[2];
                for (int f = 0; f < 2; ++f) {
                    const double d = bench::masked_error(image[f][0], image[f][1], mask).rmse;
                    variance[f] = d * d * variance_spp / 2;
                    rate[f] = paths[f] / seconds_spent[f];
                }
                std::printf("| %s | %d | %.5f / %.5f | %.3f | %.3f M / %.3f M | **%.3f×** |\n",
                            name.c_str(), variance_spp, variance[0], variance[1],
                            variance[1] / variance[0], rate[0] / 1e6, rate[1] / 1e6,
                            std::sqrt((variance[0] / rate[0]) / (variance[1] / rate[1])));
                std::fflush(stdout);
            }
            if (seconds.empty()) return 0;
            std::printf("\n");
        }
        std::vector<std::string> means;
        std::printf(
            "| material | T | spp: deterministic / stochastic | paths/s: deterministic / "
            "stochastic | RMSE: deterministic | RMSE: stochastic | deterministic / stochastic "
            "|\n|---|---|---|---|---|---|---|\n");
        for (const std::string& path : packages) {
            const auto [name, scene, mask] = prepare(path, size);
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

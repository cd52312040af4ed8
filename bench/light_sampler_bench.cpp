// SPDX-License-Identifier: MIT
// Throughput of the generic light sampler (btf/core/light_sampler.h) on a decoded fmf material
// (FactorMaterial): C = 32 components, rgb mode, of a synthetic material (default woven_fabric,
// 256² texels × 81 views × 81 lights), encoded here with power-iterations=0 by default (the cost
// of sampling depends on the factors' shapes, not on their values). This is the reference that
// mlvq's native importance sampling (issue 5) is compared with.
//
// - table building: a fresh material, one sample() per (tile, view) pair, so that each call
//   builds one table; time per table;
// - cold: a fresh material, `--samples` random draws (uniform uv, ωo uniform over the hemisphere,
//   uniform ξ), one thread, including the tables built on the way;
// - warm: the same draws again, every table built (best of --repeat), one thread and two;
// - for comparison in the same run: pdf() at the sampled directions, eval() alone at the same
//   (uv, ωi, ωo) (the share of the value in a sample), albedo() (a 32² quadrature), and a
//   sampler that uses the nearest view's table alone (ViewBlend::kNearest), cold and warm.
//
// Prints a Markdown table.
//
//   build/<dir>/light_sampler_bench [--preset woven_fabric] [--size 256] [--components 32]
//                                   [--power-iterations 0] [--samples 1048576] [--repeat 3]

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/core/light_sampler.h"
#include "btf/synth/synth.h"

namespace {

using namespace btf;

struct Draw {
    Uv uv;
    Vec3 wo;
    double xi1, xi2;
};

}  // namespace

int main(int argc, char** argv) {
    std::string preset = "woven_fabric";
    int size = 256, components = 32, repeat = 3, power_iterations = 0;
    size_t count = size_t(1) << 20;
    CLI::App app{"Throughput of the generic light sampler on an fmf material (docs/benchmarks.md)"};
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--components", components, "fmf components")->capture_default_str();
    app.add_option("--power-iterations", power_iterations, "of the encode")->capture_default_str();
    app.add_option("--samples", count, "random draws")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    app.add_option("--repeat", repeat, "runs of the warm cases; the best counts")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        const DirectionSet& ubo = DirectionSet::ubo81();
        std::vector<uint8_t> bytes;
        {
            bench::Stopwatch clock;
            const auto source = synth::make(preset, size, {ubo, ubo}, 1);
            Package package = fmf_codec().encode(
                *source, {{"components", std::to_string(components)},
                          {"colour", "rgb"},
                          {"power-iterations", std::to_string(power_iterations)}});
            bytes = encode_package(package);
            std::fprintf(stderr, "synthesized and encoded %s %d² × 81 × 81, C = %d, in %.1f s\n",
                         preset.c_str(), size, components, clock.seconds());
        }
        auto fresh = [&] { return open_material(decode_package(bytes, "light_sampler_bench")); };

        std::mt19937_64 rng(7);
        std::vector<Draw> draws(count);
        for (Draw& d : draws) {
            d.uv = {bench::uniform01(rng), bench::uniform01(rng)};
            d.wo = bench::random_direction(rng);
            d.xi1 = bench::uniform01(rng);
            d.xi2 = bench::uniform01(rng);
        }
        std::vector<LightSample> out(count);

        // Table building: one draw per (tile, view) on a fresh material.
        double t_build = 0;
        int64_t tables = 0;
        int tile = 0, tiles = 0;
        {
            const auto m = fresh();
            const LightSampler& s = m->generic_sampler();
            tile = s.tile_size();
            tiles = s.tiles_x() * s.tiles_y();
            bench::Stopwatch clock;
            for (int ty = 0; ty < s.tiles_y(); ++ty)
                for (int tx = 0; tx < s.tiles_x(); ++tx) {
                    const Uv uv{(tx + 0.5) * tile / m->width(), (ty + 0.5) * tile / m->height()};
                    for (int v = 0; v < ubo.size(); ++v) s.sample(uv, ubo.vector(v), 0.5, 0.5);
                }
            t_build = clock.seconds();
            tables = s.tables_built();
        }

        // Cold, then warm on the same material.
        const auto m = fresh();
        const LightSampler& sampler = m->generic_sampler();
        double t_cold = 0;
        {
            bench::Stopwatch clock;
            for (size_t i = 0; i < count; ++i)
                out[i] = m->sample(draws[i].uv, draws[i].wo, draws[i].xi1, draws[i].xi2);
            t_cold = clock.seconds();
        }
        const int64_t cold_tables = sampler.tables_built();
        const double t_warm = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < count; ++i)
                out[i] = m->sample(draws[i].uv, draws[i].wo, draws[i].xi1, draws[i].xi2);
        });
        const double t_warm2 = bench::best_of(repeat, [&] {
            auto half = [&](size_t b, size_t e) {
                for (size_t i = b; i < e; ++i)
                    out[i] = m->sample(draws[i].uv, draws[i].wo, draws[i].xi1, draws[i].xi2);
            };
            std::thread other(half, count / 2, count);
            half(0, count / 2);
            other.join();
        });
        // The nearest view's table alone (ViewBlend::kNearest), on the same material: a cold
        // pass to build its tables, then warm.
        LightSamplerOptions nearest_options;
        nearest_options.view_blend = ViewBlend::kNearest;
        const LightSampler nearest(*m, nearest_options);
        double t_nearest_cold = 0;
        {
            bench::Stopwatch clock;
            for (size_t i = 0; i < count; ++i)
                out[i] = nearest.sample(draws[i].uv, draws[i].wo, draws[i].xi1, draws[i].xi2);
            t_nearest_cold = clock.seconds();
        }
        const int64_t nearest_tables = nearest.tables_built();
        const double t_nearest = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < count; ++i)
                out[i] = nearest.sample(draws[i].uv, draws[i].wo, draws[i].xi1, draws[i].xi2);
        });
        // Back to the default sampler's directions for pdf() and eval().
        for (size_t i = 0; i < count; ++i)
            out[i] = m->sample(draws[i].uv, draws[i].wo, draws[i].xi1, draws[i].xi2);
        double sink = 0;
        const double t_pdf = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < count; ++i) sink += m->pdf(draws[i].uv, draws[i].wo, out[i].wi);
        });
        const double t_eval = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < count; ++i)
                sink += m->eval(draws[i].uv, out[i].wi, draws[i].wo).g;
        });
        const size_t albedo_count = std::min<size_t>(count, 4096);
        const double t_albedo = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < albedo_count; ++i) sink += m->albedo(draws[i].uv, draws[i].wo).g;
        });
        std::fprintf(stderr, "(sink %g)\n", sink);

        const double n = double(count);
        auto row = [](const std::string& what, double per, const std::string& rate) {
            const std::string time = per >= 1e-3   ? fmt::format("{:.2f} ms", per * 1e3)
                                     : per >= 1e-6 ? fmt::format("{:.1f} µs", per * 1e6)
                                                   : fmt::format("{:.1f} ns", per * 1e9);
            std::printf("| %s | %s | %s |\n", what.c_str(), time.c_str(), rate.c_str());
        };
        auto rate = [](double per_second) {
            return fmt::format("**{:.2f} M/s**", per_second / 1e6);
        };
        std::printf(
            "Generic sampler (R = %d, %d² points per tile, ε = %.2f) on fmf C = %d, rgb mode "
            "(power-iterations %d), %s %d² × 81 × 81: %d² texel tiles (%d tiles × 81 views, "
            "%.1f KiB per table); %zu random draws; warm cases best of %d\n\n"
            "| case | per call | rate |\n|---|---|---|\n",
            sampler.options().resolution, sampler.options().points_per_side,
            sampler.options().uniform_fraction, components, power_iterations, preset.c_str(), size,
            tile, tiles, double(sampler.table_bytes()) / 1024, count, repeat);
        row(fmt::format("building one table (all {} of them, one `sample()` each), 1 thread",
                        tables),
            t_build / double(tables), fmt::format("{:.0f} tables/s", double(tables) / t_build));
        row(fmt::format("`sample()`, cold (builds {} tables on the way), 1 thread", cold_tables),
            t_cold / n, rate(n / t_cold));
        row("`sample()` (blend of ≤ 3 views), warm, 1 thread", t_warm / n, rate(n / t_warm));
        row("`sample()`, warm, 2 threads", t_warm2 / n,
            fmt::format("{} ({:.2f}×)", rate(n / t_warm2), t_warm / t_warm2));
        row(fmt::format("nearest view only: `sample()`, cold (builds {} tables), 1 thread",
                        nearest_tables),
            t_nearest_cold / n, rate(n / t_nearest_cold));
        row("nearest view only: `sample()`, warm, 1 thread", t_nearest / n, rate(n / t_nearest));
        row("`pdf()` at the sampled directions, warm, 1 thread", t_pdf / n, rate(n / t_pdf));
        row("`eval()` alone at the same (uv, ωi, ωo), 1 thread", t_eval / n, rate(n / t_eval));
        row("`albedo()` (32² quadrature), 1 thread", t_albedo / double(albedo_count),
            fmt::format("{:.0f} /s", double(albedo_count) / t_albedo));
        std::printf(
            "\nShare of eval() in a warm sample(): %.0f %%. Memory of all tables: %.1f MiB.\n",
            100 * t_eval / t_warm,
            double(tables) * double(sampler.table_bytes()) / double(1 << 20));
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "light_sampler_bench: %s\n", e.what());
        return 1;
    }
    return 0;
}

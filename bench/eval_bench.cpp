// SPDX-License-Identifier: MIT
// Evaluation throughput of a decoded fmf material (FactorMaterial): C = 32 components, rgb mode,
// of a synthetic woven_fabric (default 256² texels × 81 views × 81 lights), encoded here from the
// synthetic source with power-iterations=0 by default (2 passes instead of 8: the cost of an
// evaluation depends on the factors' shapes, not on their values).
//
// - random queries: uniformly random uv and directions (uniform over the hemisphere), one
//   thread, through eval() and through one eval_batch() call; the angular interpolator's two
//   weights() lookups per query alone, in the same run, for the share they take; the scalar
//   reference path eval_reference() (lookup6d over 36 reconstructed samples); and 1024 random
//   queries evaluated over and over, whose factor rows stay in cache, to separate the cost of
//   memory latency from that of the arithmetic;
// - coherent queries: a 512² image of a plane under one light and one view (one eval_batch()
//   over the uv grid, all queries with the same directions), and the same through eval();
// - two threads: the query array split in two halves, one std::thread each.
//
// Each figure is the best of --repeat runs (the machine is shared). Prints a Markdown table.
//
//   build/<dir>/eval_bench [--size 256] [--components 32] [--power-iterations 0]
//                          [--queries 2097152] [--repeat 3]

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/core/angular_interpolator.h"
#include "btf/synth/synth.h"

namespace {

using namespace btf;

// fn(begin, end) on two threads over the halves of [0, n).
void two_threads(size_t n, const std::function<void(size_t, size_t)>& fn) {
    std::thread other([&] { fn(n / 2, n); });
    fn(0, n / 2);
    other.join();
}

}  // namespace

int main(int argc, char** argv) {
    int size = 256, components = 32, repeat = 3, power_iterations = 0;
    size_t count = size_t(1) << 21;
    CLI::App app{"Evaluation throughput of an fmf material (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--components", components, "fmf components")->capture_default_str();
    app.add_option("--power-iterations", power_iterations, "of the encode")->capture_default_str();
    app.add_option("--queries", count, "random queries")->capture_default_str();
    app.add_option("--repeat", repeat, "runs; the best counts")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        const DirectionSet& ubo = DirectionSet::ubo81();
        std::unique_ptr<Material> material;
        {
            bench::Stopwatch clock;
            const auto source = synth::make("woven_fabric", size, {ubo, ubo}, 1);
            Package package = fmf_codec().encode(
                *source, {{"components", std::to_string(components)},
                          {"colour", "rgb"},
                          {"power-iterations", std::to_string(power_iterations)}});
            const std::vector<uint8_t> bytes = encode_package(package);
            material = open_material(decode_package(bytes, "eval_bench package"));
            std::fprintf(stderr, "synthesized and encoded %d² × 81 × 81, C = %d, in %.1f s\n", size,
                         components, clock.seconds());
        }
        const Material& m = *material;

        std::mt19937_64 rng(7);
        const std::vector<Query> random = bench::random_queries(count, rng);
        constexpr int kImage = 512;
        const Vec3 wi = Direction::from_degrees(37, 65).vector();
        const Vec3 wo = Direction::from_degrees(22, 190).vector();
        const std::vector<Query> image = bench::image_queries(kImage, wi, wo);
        std::vector<Rgb> out(std::max(random.size(), image.size()));
        std::vector<Rgb> check(random.size());

        // The interpolator's lookups alone: two weights() per query, as eval() does.
        const AngularInterpolator views(ubo), lights(ubo);
        int64_t sink = 0;
        const double t_weights = bench::best_of(repeat, [&] {
            for (const Query& q : random) {
                const AngularWeights vw = views.weights(q.wo), lw = lights.weights(q.wi);
                sink += vw.index[0] + lw.index[0];
            }
        });
        const double t_eval = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < random.size(); ++i)
                check[i] = m.eval(random[i].uv, random[i].wi, random[i].wo);
        });
        // The same work with the factors in cache: the first 1024 queries, evaluated again and
        // again (as many evaluations as the full array), to separate memory latency from compute.
        constexpr size_t kWarm = 1024;
        const size_t warm_rounds = std::max<size_t>(1, random.size() / kWarm);
        const double t_warm = bench::best_of(repeat, [&] {
            for (size_t r = 0; r < warm_rounds; ++r)
                for (size_t i = 0; i < std::min(kWarm, random.size()); ++i)
                    out[i] = m.eval(random[i].uv, random[i].wi, random[i].wo);
        });
        const double t_batch = bench::best_of(
            repeat, [&] { m.eval_batch(random, std::span<Rgb>(out.data(), random.size())); });
        float max_diff = 0;
        for (size_t i = 0; i < random.size(); ++i)
            max_diff = std::max({max_diff, std::abs(out[i].r - check[i].r),
                                 std::abs(out[i].g - check[i].g), std::abs(out[i].b - check[i].b)});
        const double t_batch2 = bench::best_of(repeat, [&] {
            two_threads(random.size(), [&](size_t b, size_t e) {
                m.eval_batch(std::span<const Query>(random.data() + b, e - b),
                             std::span<Rgb>(out.data() + b, e - b));
            });
        });
        const size_t reference_count = std::min<size_t>(random.size(), 1 << 18);
        double t_reference = INFINITY;
        if (const auto* fm = dynamic_cast<const factor::FactorMaterial*>(&m)) {
            t_reference = bench::best_of(repeat, [&] {
                for (size_t i = 0; i < reference_count; ++i)
                    out[i] = fm->eval_reference(random[i].uv, random[i].wi, random[i].wo);
            });
        }
        const double t_image = bench::best_of(
            repeat, [&] { m.eval_batch(image, std::span<Rgb>(out.data(), image.size())); });
        const double t_image_eval = bench::best_of(repeat, [&] {
            for (size_t i = 0; i < image.size(); ++i)
                out[i] = m.eval(image[i].uv, image[i].wi, image[i].wo);
        });
        const double t_image2 = bench::best_of(repeat, [&] {
            two_threads(image.size(), [&](size_t b, size_t e) {
                m.eval_batch(std::span<const Query>(image.data() + b, e - b),
                             std::span<Rgb>(out.data() + b, e - b));
            });
        });
        std::fprintf(stderr, "max |eval − eval_batch| over the random queries: %g (sink %lld)\n",
                     double(max_diff), static_cast<long long>(sink));

        const double n = double(random.size()), ni = double(image.size());
        auto row = [](const char* what, double evals, double seconds, const char* target) {
            std::printf("| %s | %.1f ns | **%.2f M/s** | %s |\n", what, seconds / evals * 1e9,
                        evals / seconds / 1e6, target);
        };
        std::printf(
            "fmf C = %d, rgb mode (power-iterations %d), woven_fabric %d² × 81 × 81; %zu random "
            "queries, a %d² image; "
            "best of %d\n\n| case | per evaluation | evaluations/s | target |\n|---|---|---|---|\n",
            components, power_iterations, size, random.size(), kImage, repeat);
        row("random queries, `eval()`, 1 thread", n, t_eval, "≥ 10 M/s");
        row("random queries: the 2 `AngularInterpolator::weights()` of each, alone", n, t_weights,
            "");
        row("1024 random queries again and again (factors in cache), `eval()`, 1 thread",
            double(warm_rounds * std::min(kWarm, random.size())), t_warm, "");
        if (std::isfinite(t_reference))
            row("random queries, `eval_reference()` (scalar lookup6d), 1 thread",
                double(reference_count), t_reference, "");
        row("random queries, `eval_batch()`, 1 thread", n, t_batch, "≥ 10 M/s");
        row("random queries, `eval_batch()`, 2 threads", n, t_batch2, "");
        row("512² image, one light and view, `eval_batch()`, 1 thread", ni, t_image, "≥ 50 M/s");
        row("512² image, one light and view, `eval_batch()`, 2 threads", ni, t_image2, "");
        row("512² image, one light and view, `eval()`, 1 thread", ni, t_image_eval, "");
        std::printf(
            "\nShare of the two weights() lookups in a random eval(): %.0f %%. Scaling to 2 "
            "threads: %.2f× (random), %.2f× (image).\n",
            100 * t_weights / t_eval, t_batch / t_batch2, t_image / t_image2);
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "eval_bench: %s\n", e.what());
        return 1;
    }
    return 0;
}

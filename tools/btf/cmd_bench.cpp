// SPDX-License-Identifier: MIT
// btf bench eval|sample|eval-sample FILE [--filter stochastic|deterministic] [--threads N]
// [--queries N] [--coherent] [--repeat R] [--json]: how fast this machine evaluates (or
// importance-samples) a compressed material, so that a user sees what it costs before rendering
// with it.
//
// --filter: stochastic (the default, as `btf render` renders) goes through
// eval_stochastic_batch / sample_stochastic_batch with one uniform number per query;
// deterministic through eval_batch / sample_batch. `eval-sample` measures the uninterpolated
// lookup eval_sample(x, y, view, light) at random texels and sample indices (no filter), through
// eval_sample_batch.
//
// Queries: random (uv uniform over one repetition of the texture, light and view directions
// uniform over the hemisphere) or --coherent (one image: a uv grid over the texture under one
// light and one view, all queries with the same directions, as a renderer's primary hits on a
// flat, directly lit surface). They are made before the clock starts, from a fixed seed, and
// evaluated through eval_batch / sample_batch (what a renderer calls) in batches of 4096, split
// over the threads in equal contiguous parts. The best of --repeat runs counts: the machine may be
// shared, and the best run is the one least disturbed.

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <span>
#include <thread>
#include <vector>

#include "btf/core/hemisphere.h"
#include "btf/util/error.h"
#include "cli.h"

namespace btf::cli {

namespace {

constexpr size_t kBatch = 4096;

// A direction uniform over the upper hemisphere (the area-preserving square map).
Vec3 hemisphere(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double a = u(rng), b = u(rng);
    return square_to_hemisphere({a, b});
}

std::vector<Query> make_queries(size_t n, bool coherent) {
    std::vector<Query> out(n);
    std::mt19937_64 rng(20261202);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    if (!coherent) {
        for (Query& q : out) q = {{u(rng), u(rng)}, hemisphere(rng), hemisphere(rng)};
        return out;
    }
    // One image: a side × side grid of pixel centres over the texture, one light, one view.
    const size_t side = std::max<size_t>(1, size_t(std::ceil(std::sqrt(double(n)))));
    const Vec3 wi = Direction::from_degrees(40, 30).vector();
    const Vec3 wo = Direction::from_degrees(20, 200).vector();
    for (size_t i = 0; i < n; ++i)
        out[i] = {
            {(double(i % side) + 0.5) / double(side), (double(i / side) + 0.5) / double(side)},
            wi,
            wo};
    return out;
}

std::vector<SampleQuery> make_sample_queries(const std::vector<Query>& queries) {
    std::vector<SampleQuery> out(queries.size());
    std::mt19937_64 rng(20261203);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (size_t i = 0; i < queries.size(); ++i)
        out[i] = {queries[i].uv, queries[i].wo, u(rng), u(rng)};
    return out;
}

// The filter numbers of stochastic queries.
std::vector<double> make_filter_numbers(size_t n) {
    std::vector<double> out(n);
    std::mt19937_64 rng(20261204);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (double& x : out) x = u(rng);
    return out;
}

// Random texels and sample indices for eval-sample.
std::vector<SampleIndex> make_sample_indices(size_t n, const Material& m) {
    std::vector<SampleIndex> out(n);
    std::mt19937_64 rng(20261205);
    std::uniform_int_distribution<int> x(0, m.width() - 1), y(0, m.height() - 1);
    std::uniform_int_distribution<int> view(0, m.sampling().num_views() - 1);
    std::uniform_int_distribution<int> light(0, m.sampling().num_lights() - 1);
    for (SampleIndex& s : out) s = {x(rng), y(rng), view(rng), light(rng)};
    return out;
}

// Seconds of one run of `work(begin, end)` over [0, n) split over `threads` threads.
template <typename Work>
double timed(size_t n, int threads, const Work& work) {
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t)
        pool.emplace_back(
            [&, t] { work(n * size_t(t) / size_t(threads), n * size_t(t + 1) / size_t(threads)); });
    work(0, n / size_t(threads));
    for (std::thread& th : pool) th.join();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

Command register_bench(CLI::App& app, GlobalOptions&) {
    struct Args {
        std::string what, path, filter = "stochastic";
        size_t queries = size_t(1) << 20;
        int repeat = 3, threads = 1;
        bool coherent = false, json = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* cmd = app.add_subcommand(
        "bench",
        "Measure how fast this machine evaluates or samples a compressed material (btfkit "
        "package, BSVTF file or UBO2014 .btf): random or coherent queries, best of a few runs");
    cmd->add_option("what", args->what,
                    "eval (evaluation), sample (importance sampling) or eval-sample (the "
                    "uninterpolated lookup at random texels and sample indices)")
        ->required()
        ->check(CLI::IsMember({"eval", "sample", "eval-sample"}));
    cmd->add_option("file", args->path, "the material")->required();
    cmd->add_option("--queries", args->queries, "queries per run")
        ->check(CLI::Range(size_t(1), size_t(1) << 28))
        ->capture_default_str();
    cmd->add_option("--threads", args->threads, "threads evaluating at once, each on its own part")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    cmd->add_option("--repeat", args->repeat, "runs; the best counts")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    cmd->add_flag("--coherent", args->coherent,
                  "one image: a uv grid under one light and one view (default: random uv and "
                  "directions)");
    cmd->add_option("--filter", args->filter,
                    "stochastic (one texel, view and light drawn per query, as btf render does) "
                    "or deterministic (the filtered value)")
        ->check(CLI::IsMember({"stochastic", "deterministic"}))
        ->capture_default_str();
    cmd->add_flag("--json", args->json, "print the result as JSON");

    return {
        cmd, [args] {
            const std::unique_ptr<Material> material = open_material_file(args->path);
            const int threads = args->threads;
            const size_t n = args->queries;
            const bool stochastic = parse_filter(args->filter) == Filter::kStochastic;
            const bool eval = args->what != "sample", lookup = args->what == "eval-sample";
            std::vector<Query> queries;
            if (!lookup) queries = make_queries(n, args->coherent);
            std::vector<SampleQuery> samples;
            if (!eval) samples = make_sample_queries(queries);
            std::vector<double> numbers;
            if (stochastic && !lookup) numbers = make_filter_numbers(n);
            std::vector<StochasticQuery> stochastic_queries;
            std::vector<StochasticSampleQuery> stochastic_samples;
            if (stochastic && eval && !lookup) {
                stochastic_queries.resize(n);
                for (size_t i = 0; i < n; ++i)
                    stochastic_queries[i] = {queries[i].uv, queries[i].wi, queries[i].wo,
                                             numbers[i]};
            }
            if (stochastic && !eval) {
                stochastic_samples.resize(n);
                for (size_t i = 0; i < n; ++i)
                    stochastic_samples[i] = {samples[i].uv, samples[i].wo, numbers[i],
                                             samples[i].xi1, samples[i].xi2};
            }
            std::vector<SampleIndex> indices;
            if (lookup) indices = make_sample_indices(n, *material);
            std::vector<Rgb> values(eval ? n : 0);
            std::vector<LightSample> drawn(eval ? 0 : n);
            auto work = [&](size_t begin, size_t end) {
                if (lookup) {
                    for (size_t b = begin; b < end; b += kBatch) {
                        const size_t e = std::min(end, b + kBatch);
                        material->eval_sample_batch(std::span(indices).subspan(b, e - b),
                                                    std::span(values).subspan(b, e - b));
                    }
                    return;
                }
                for (size_t b = begin; b < end; b += kBatch) {
                    const size_t e = std::min(end, b + kBatch);
                    const std::span<Rgb> value_part = std::span(values).subspan(b, e - b);
                    const std::span<LightSample> drawn_part = std::span(drawn).subspan(b, e - b);
                    if (eval && stochastic)
                        material->eval_stochastic_batch(
                            std::span(stochastic_queries).subspan(b, e - b), value_part);
                    else if (eval)
                        material->eval_batch(std::span(queries).subspan(b, e - b), value_part);
                    else if (stochastic)
                        material->sample_stochastic_batch(
                            std::span(stochastic_samples).subspan(b, e - b), drawn_part);
                    else
                        material->sample_batch(std::span(samples).subspan(b, e - b), drawn_part);
                }
            };
            double best = INFINITY;
            for (int r = 0; r < args->repeat; ++r) best = std::min(best, timed(n, threads, work));
            // A value the compiler must keep, and a check that every query was answered.
            double checksum = 0;
            for (size_t i = 0; i < n; ++i) {
                const Rgb& v = eval ? values[i] : drawn[i].value;
                checksum += double(v.r) + double(v.g) + double(v.b);
            }
            if (!std::isfinite(checksum))
                fail("{}: a query gave a value that is not a finite number", args->path);
            const double rate = double(n) / best;
            const char* mode = args->coherent ? "coherent" : "random";
            const char* filter = lookup ? "none" : args->filter.c_str();
            if (args->json) {
                nlohmann::json j = {
                    {"file", args->path},     {"what", args->what},   {"queries", n},
                    {"mode", mode},           {"filter", filter},     {"threads", threads},
                    {"repeat", args->repeat}, {"best_seconds", best}, {"checksum", checksum}};
                j[eval ? "evals_per_s" : "samples_per_s"] = rate;
                std::printf("%s\n", j.dump(1).c_str());
            } else {
                std::printf(
                    "%s: %s %.2f M/s (%s, filter %s, %d thread%s, %zu queries, best of %d)\n",
                    args->path.c_str(), args->what.c_str(), rate / 1e6, lookup ? "random" : mode,
                    filter, threads, threads == 1 ? "" : "s", n, args->repeat);
            }
        }};
}

}  // namespace btf::cli

// SPDX-License-Identifier: MIT
// UBO2014 files as they are (docs/benchmarks.md, "Viewer: every codec"): writes the benchmark's
// DFMF file, and measures evaluation on such a file.
//
//   ubo2014_files write OUT.btf [--size 256] [--components 32] [--model 0|11] [--float]
//       A DFMF file of size² texels on the 151-direction dome (151 views × 151 lights) with
//       `components` random components per channel, half floats unless --float: the shape of a
//       measured UBO2014 material (values: a positive first component plus smaller ones of
//       decreasing energy; for model 11 log Y around log 0.2 and small chroma ratios). What is
//       measured depends on the shapes of the factors, not on their values.
//
//   ubo2014_files eval FILE.btf [--queries 1048576] [--repeat 3]
//       Opening time and eval() throughput (random uv and directions over the
//       hemisphere, one thread, best of --repeat, the runs of the two alternating) of the file as
//       btf::open_material opens it (the fmf evaluator over the file's factors, interpolating
//       colour planes), and, as the reference in the same run, of the material that interpolates
//       decoded RGB samples (ubo2014::make_material: what files with the cosine flag still use, and
//       what every UBO2014 file used before).

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/codec.h"
#include "btf/core/direction.h"
#include "btf/io/ubo2014.h"

namespace {

using namespace btf;

ubo2014::Factorization random_dfmf(int size, int components, int32_t model, int scalar_size) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<float> uniform(-1.0f, 1.0f);
    const DirectionSet& dome = DirectionSet::dome151();
    ubo2014::Factorization f;
    f.body = ubo2014::Body::kDfmf;
    f.sampling = {dome, dome};
    f.width = f.height = size;
    f.color_model = model;
    f.meta.measurement_setup = "btfkit benchmark (random factors)";
    const int64_t rows = f.sampling.num_images(), texels = int64_t(size) * size;
    for (int c = 0; c < 3; ++c) {
        ubo2014::Factor factor;
        factor.scalar_size = scalar_size;
        factor.u.resize(rows, components);
        factor.sxv.resize(texels, components);
        factor.s.resize(components);
        for (int k = 0; k < components; ++k) {
            const float energy = 1.0f / float(1 + k);
            factor.s[k] = energy;
            for (int64_t r = 0; r < rows; ++r)
                factor.u(r, k) = k == 0 ? 0.8f + 0.2f * uniform(rng) : 0.1f * uniform(rng);
            // First component: the level of the channel (model 11: log Y near log 0.2 and chroma
            // ratios near 0; model 0: reflectances near 0.3), the others small variations.
            const float level =
                model == ubo2014::kColorModelLogYUV ? (c == 0 ? -1.6f : 0.02f) : 0.3f;
            for (int64_t t = 0; t < texels; ++t)
                factor.sxv(t, k) =
                    k == 0 ? level * (1.0f + 0.2f * uniform(rng)) : 0.2f * energy * uniform(rng);
        }
        f.factors.push_back(std::move(factor));
    }
    return f;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"UBO2014 files as they are: the benchmark file and eval on it"};
    app.require_subcommand(1);
    std::string path;
    int size = 256, components = 32, model = 0, repeat = 3;
    bool use_float = false;
    size_t count = size_t(1) << 20;
    CLI::App* write = app.add_subcommand("write", "write the benchmark's DFMF file");
    write->add_option("file", path, "output .btf")->required();
    write->add_option("--size", size, "texels per side")->capture_default_str();
    write->add_option("--components", components, "per channel")->capture_default_str();
    write->add_option("--model", model, "DFMF colour model: 0 or 11")
        ->check(CLI::IsMember({0, 11}))
        ->capture_default_str();
    write->add_flag("--float", use_float, "float32 factors (half floats by default)");
    CLI::App* eval = app.add_subcommand("eval", "eval() throughput on a .btf file");
    eval->add_option("file", path, "UBO2014 .btf")->required();
    eval->add_option("--queries", count, "random queries")->capture_default_str();
    eval->add_option("--repeat", repeat, "runs; the best counts")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        if (write->parsed()) {
            bench::Stopwatch clock;
            ubo2014::write_dfmf(path, random_dfmf(size, components, model, use_float ? 4 : 2));
            std::fprintf(stderr, "wrote %s (%d² texels, dome151, K = %d, model %d, %s) in %.1f s\n",
                         path.c_str(), size, components, model, use_float ? "float" : "half",
                         clock.seconds());
            return 0;
        }
        std::mt19937_64 rng(7);
        const std::vector<Query> queries = bench::random_queries(count, rng);
        std::vector<Rgb> out(queries.size()), reference(queries.size());
        bench::Stopwatch clock;
        const std::unique_ptr<Material> material = open_material(path);
        const double t_open = clock.seconds();
        clock = {};
        const std::unique_ptr<Material> rgb = ubo2014::make_material(ubo2014::read(path));
        const double t_open_rgb = clock.seconds();
        // Runs of the two alternate, so that both see the same load of a shared machine.
        double t_eval = INFINITY, t_rgb = INFINITY;
        for (int r = 0; r < repeat; ++r) {
            t_eval = std::min(t_eval, bench::best_of(1, [&] {
                                  for (size_t i = 0; i < queries.size(); ++i)
                                      out[i] = material->eval(queries[i].uv, queries[i].wi,
                                                              queries[i].wo);
                              }));
            t_rgb = std::min(t_rgb, bench::best_of(1, [&] {
                                 for (size_t i = 0; i < queries.size(); ++i)
                                     reference[i] =
                                         rgb->eval(queries[i].uv, queries[i].wi, queries[i].wo);
                             }));
        }
        double sum = 0;
        for (size_t i = 0; i < queries.size(); ++i) {
            const float d[3] = {out[i].r - reference[i].r, out[i].g - reference[i].g,
                                out[i].b - reference[i].b};
            const float v[3] = {reference[i].r, reference[i].g, reference[i].b};
            for (int c = 0; c < 3; ++c) sum += std::abs(d[c]) / std::max(1e-3f, std::abs(v[c]));
        }
        const double n = double(queries.size());
        std::printf(
            "%s: %zu random queries, one thread, best of %d (mean relative difference of the two: "
            "%.2g)\n\n| material | open | eval() | evaluations/s |\n|---|---|---|---|\n",
            path.c_str(), queries.size(), repeat, sum / (3 * n));
        std::printf(
            "| `btf::open_material` (fmf evaluator, planes interpolated) | %.2f s | %.1f ns "
            "| **%.2f M/s** |\n",
            t_open, t_eval / n * 1e9, n / t_eval / 1e6);
        std::printf(
            "| `ubo2014::make_material` (decoded RGB interpolated) | %.2f s | %.1f ns | "
            "%.2f M/s |\n",
            t_open_rgb, t_rgb / n * 1e9, n / t_rgb / 1e6);
        std::printf("\nratio fmf evaluator / RGB material: %.1f×\n", t_rgb / t_eval);
    } catch (const btf::Error& e) {
        std::fprintf(stderr, "ubo2014_files: %s\n", e.what());
        return 1;
    }
    return 0;
}

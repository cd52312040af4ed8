// SPDX-License-Identifier: MIT
// The mlvq codec on a synthetic material (default woven_fabric, 256² texels × 81 views × 81
// lights): encode time by stage, code-book sizes and compression ratios C.R.1–C.R.4, the RMSE
// over every sample, and single-thread evaluation throughput for random queries (uniform uv and
// directions) and for a 512² image under one light and view, and importance-sampling rates (the
// native sampler against the generic tabulated one), against an fmf material (C = 32, rgb) of the
// same source measured in the same run.
// With --packages MLVQ FMF the encode is skipped and the rates are measured on two saved
// packages (e.g. from `btf compress`), to iterate on the evaluator without re-encoding.
// Prints Markdown.
//
//   build/<dir>/mlvq_bench [--size 256] [--preset woven_fabric] [--threshold 3e-5]
//                          [--level-factor 1] [--queries 1048576] [--repeat 3]
//   build/<dir>/mlvq_bench --packages mlvq.btfpkg fmf.btfpkg

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/fmf/fmf.h"
#include "btf/codecs/material_source.h"
#include "btf/codecs/mlvq/mlvq.h"
#include "btf/core/light_sampler.h"
#include "btf/synth/synth.h"

using namespace btf;

namespace {

// Encodes the synthetic material with mlvq and fmf (C = 32), prints the encode stages, the
// code-book sizes, the compression ratios and the RMSE, and returns the two decoded materials.
std::pair<std::unique_ptr<Material>, std::unique_ptr<Material>> encode_and_report(
    const std::string& preset, int size, const std::string& threshold,
    const std::string& level_factor) {
    const DirectionSet& ubo = DirectionSet::ubo81();
    const auto source = synth::make(preset, size, {ubo, ubo}, 1);
    const Params params({{"threshold", threshold},
                         {"chroma-threshold", threshold},
                         {"level-factor", level_factor}});
    const mlvq::Options options = mlvq::parse_options(params);
    mlvq::EncodeReport report;
    bench::Stopwatch clock;
    auto [books, index] = mlvq::encode(*source, options, Progress::none(), &report);
    const double encode_seconds = clock.seconds();
    const int64_t texels = int64_t(size) * size;
    Package package = mlvq::to_package(books, {index}, options);
    const std::vector<uint8_t> bytes = encode_package(package);
    auto material = open_material(decode_package(bytes, "mlvq_bench package"));

    // fmf at its defaults but for the size (C = 32, rgb): the like-for-like reference.
    Package fmf_package = fmf_codec().encode(*source, {{"components", "32"}, {"colour", "rgb"}});
    const std::vector<uint8_t> fmf_bytes = encode_package(fmf_package);
    auto fmf = open_material(decode_package(fmf_bytes, "fmf package"));

    std::printf("%s %d² × 81 × 81, threshold %s, level-factor %s\n\n", preset.c_str(), size,
                threshold.c_str(), level_factor.c_str());
    std::printf("| stage | seconds |\n|---|---|\n");
    std::printf("| reading and resampling %lld training texels | %.1f |\n",
                (long long)report.trained, report.seconds_reading);
    std::printf("| training the code-books (steps 1, 2) | %.1f |\n", report.seconds_training);
    std::printf("| reading, resampling and encoding all %lld texels (frozen code-books) | %.1f |\n",
                (long long)report.texels, report.seconds_frozen);
    std::printf("| total | %.1f |\n\n", encode_seconds);

    const double raw = double(texels) * 81 * 81 * 3;
    const mlvq::StorageSizes sizes = mlvq::storage_sizes(books, texels, source->info().hdr);
    std::printf("| code-book | entries | bytes |\n|---|---|---|\n");
    for (const auto& [name, entries, b] : sizes.books)
        std::printf("| %s | %lld | %lld |\n", name.c_str(), (long long)entries, (long long)b);
    std::printf(
        "\nC.R.1 1:%.0f, C.R.2 1:%.0f, C.R.3 1:%.0f, C.R.4 1:%.0f; package %zu bytes "
        "(1:%.0f, zstd); RMSE %.4f (fmf C = 32: %zu bytes, RMSE %.4f)\n\n",
        raw / double(sizes.bytes[0]), raw / double(sizes.bytes[1]), raw / double(sizes.bytes[2]),
        raw / double(sizes.bytes[3]), bytes.size(), raw / double(bytes.size()),
        sample_rmse(*source, *material), fmf_bytes.size(), sample_rmse(*source, *fmf));
    return {std::move(material), std::move(fmf)};
}

// The most random queries per second the machine's memory allows the decoded entries: a query
// reads 16 entries (4 texels × 2 θv × 2 φv) at unrelated places, 8 bytes from each of two α rows
// of a (α, β) window, and this machine loads only so many random lines per second from a buffer
// that large (bench::random_line_rate). The lines a window spans are counted over every window
// of the grid in the decoded layout (decoded.h: tiles that start on a line). The views and P6 are
// not counted: an upper bound.
void print_memory_ceiling(const mlvq::DecodedBooks& decoded, int repeat) {
    using Sample = mlvq::DecodedBooks::Sample;
    const mlvq::MlvqGrid& g = decoded.grid();
    double lines = 0;
    int windows = 0;
    for (int i = 0; i + 1 < g.n_alpha; ++i)
        for (int j = 0; j + 1 < g.n_beta; ++j, ++windows) {
            const size_t off = size_t(mlvq::DecodedBooks::offset(g, i, j)) * sizeof(Sample);
            const size_t next = off + mlvq::DecodedBooks::kTile * sizeof(Sample);  // row α + 1
            const size_t first[2] = {off / 64, next / 64},
                         last[2] = {(off + 7) / 64, (next + 7) / 64};
            lines += double(last[0] - first[0] + 1 + last[1] - first[1] + 1) -
                     (first[1] <= last[0] ? double(last[0] - first[1] + 1) : 0.0);
        }
    lines /= windows;
    const double rate = bench::random_line_rate(decoded.entry_bytes(), repeat);
    std::printf(
        "| memory ceiling: %.1f M random 64-byte lines/s from %.0f MB (the decoded entries), "
        "%.2f lines per entry × 16 | at most %.2f M/s | |\n",
        rate / 1e6, double(decoded.entry_bytes()) / 1e6, lines, rate / (16 * lines) / 1e6);
}

}  // namespace

int main(int argc, char** argv) {
    int size = 256, repeat = 3;
    std::string preset = "woven_fabric", threshold = "3e-5", level_factor = "1";
    size_t count = size_t(1) << 20;
    std::vector<std::string> packages;
    CLI::App app{"The mlvq codec: encode time, sizes, evaluation rate (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--preset", preset, "synthetic material")->capture_default_str();
    app.add_option("--threshold", threshold, "mlvq threshold (and chroma-threshold)")
        ->capture_default_str();
    app.add_option("--level-factor", level_factor, "mlvq level-factor")->capture_default_str();
    app.add_option("--queries", count, "random queries")->capture_default_str();
    app.add_option("--repeat", repeat, "runs; the best counts")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    app.add_option("--packages", packages, "measure the rates only, on these mlvq and fmf packages")
        ->expected(2);
    CLI11_PARSE(app, argc, argv);
    try {
        std::unique_ptr<Material> material, fmf;
        if (packages.empty()) {
            std::tie(material, fmf) = encode_and_report(preset, size, threshold, level_factor);
        } else {
            material = open_material(std::filesystem::path(packages[0]));
            fmf = open_material(std::filesystem::path(packages[1]));
            std::printf("%s and %s\n\n", packages[0].c_str(), packages[1].c_str());
        }
        std::mt19937_64 rng(7);
        std::uniform_real_distribution<double> uni(0, 1);
        const std::vector<Query> random = bench::random_queries(count, rng);
        float sink = 0;
        auto rate = [&](const Material& m) {
            const double t = bench::best_of(repeat, [&] {
                for (const Query& q : random) sink += m.eval(q.uv, q.wi, q.wo).g;
            });
            return double(random.size()) / t;
        };
        const double r_mlvq = rate(*material), r_fmf = rate(*fmf);
        std::vector<Rgb> random_out(random.size());
        auto batch_rate = [&](const Material& m) {
            const double t = bench::best_of(repeat, [&] { m.eval_batch(random, random_out); });
            return double(random.size()) / t;
        };
        const double b_mlvq = batch_rate(*material), b_fmf = batch_rate(*fmf);
        // A 512² image of a plane under one light and one view: coherent queries.
        constexpr int kImage = 512;
        const Vec3 wi = Direction::from_degrees(37, 65).vector();
        const Vec3 wo = Direction::from_degrees(22, 190).vector();
        const std::vector<Query> image = bench::image_queries(kImage, wi, wo);
        std::vector<Rgb> out(image.size());
        auto image_rate = [&](const Material& m) {
            const double t = bench::best_of(repeat, [&] { m.eval_batch(image, out); });
            return double(image.size()) / t;
        };
        const double i_mlvq = image_rate(*material), i_fmf = image_rate(*fmf);
        std::printf("| evaluation, one thread | mlvq | fmf C = 32 (same run) |\n|---|---|---|\n");
        std::printf("| random queries, eval() | %.2f M/s | %.2f M/s |\n", r_mlvq / 1e6,
                    r_fmf / 1e6);
        std::printf("| random queries, one eval_batch() | %.2f M/s | %.2f M/s |\n", b_mlvq / 1e6,
                    b_fmf / 1e6);
        std::printf("| 512² image, one light and view, eval_batch() | %.2f M/s | %.2f M/s |\n",
                    i_mlvq / 1e6, i_fmf / 1e6);
        print_memory_ceiling(dynamic_cast<const mlvq::MlvqMaterial&>(*material).decoded(), repeat);

        // Importance sampling: random uv, ωo and ξ, one thread; mlvq's native sampler (§5.2)
        // against the generic tabulated sampler on the same mlvq material and on fmf (tables
        // built beforehand, so the rate is the steady state).
        std::vector<std::array<double, 2>> xi(random.size());
        for (auto& x : xi) x = {uni(rng), uni(rng)};
        auto sample_rate = [&](const std::function<LightSample(const Query&, double, double)>& f) {
            const double t = bench::best_of(repeat, [&] {
                for (size_t i = 0; i < random.size(); ++i)
                    sink += float(f(random[i], xi[i][0], xi[i][1]).pdf);
            });
            return double(random.size()) / t;
        };
        const double s_native = sample_rate(
            [&](const Query& q, double a, double b) { return material->sample(q.uv, q.wo, a, b); });
        std::vector<SampleQuery> sample_queries(random.size());
        for (size_t i = 0; i < random.size(); ++i)
            sample_queries[i] = {random[i].uv, random[i].wo, xi[i][0], xi[i][1]};
        std::vector<LightSample> samples(random.size());
        const double s_batch = double(random.size()) / bench::best_of(repeat, [&] {
                                   material->sample_batch(sample_queries, samples);
                               });
        const double s_generic_mlvq = sample_rate([&](const Query& q, double a, double b) {
            return material->generic_sampler().sample(q.uv, q.wo, a, b);
        });
        const double s_generic_fmf = sample_rate(
            [&](const Query& q, double a, double b) { return fmf->sample(q.uv, q.wo, a, b); });
        std::printf(
            "\n| importance sampling, one thread, random (uv, ωo, ξ) | per second |\n"
            "|---|---|\n");
        std::printf("| mlvq native (code-books, §5.2), sample() | %.2f M |\n", s_native / 1e6);
        std::printf("| mlvq native, one sample_batch() | %.2f M |\n", s_batch / 1e6);
        std::printf("| generic tabulated sampler on the mlvq material | %.2f M |\n",
                    s_generic_mlvq / 1e6);
        std::printf("| generic tabulated sampler on fmf C = 32 | %.2f M |\n", s_generic_fmf / 1e6);
        std::fprintf(stderr, "(checksum %g)\n", double(sink));
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "mlvq_bench: %s\n", e.what());
        return 1;
    }
}

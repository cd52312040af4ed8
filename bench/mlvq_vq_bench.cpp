// SPDX-License-Identifier: MIT
// Code-vector search of the mlvq code-books (src/btf/codecs/mlvq/vq.h): queries per second of
// Codebook::find() (the exact index and, for mssim, its exact filters) against
// find_brute_force() in the same run, on luminance slices of a synthetic material sampled on
// the paper's light parametrization: for each view, 11 × 11 lights on the (α, β) grid aligned
// with the view azimuth (α uniform in [−90°, 90°], sin β uniform in [−1, 1]), views at θv = 0,
// 15, ..., 75° and 4 azimuths. P1 data are the 1-D β slices (11 values), P2 data the 11 × 11
// (α, β) slices, luminance Y of linear RGB, in a fixed shuffled order.
//
// For each row the threshold is the largest of a geometric ladder (×0.6 steps) at which
// find_or_add() over the training stream reaches the target code-book size; the code-book is
// that stream's first `size` code-vectors. Queries are held-out slices. Columns: matches (share
// of queries within the threshold), bounded (signatures whose lower bound the index computed)
// and compared (code-vectors compared in full or until abandoned), both as shares of the
// code-book per query, single-thread queries/s of find() and of brute force and their ratio,
// how many brute-forced answers were identical (index and error, bit for bit), the batch rate
// (find_batch, --threads), and the time find_or_add() took to grow the code-book.
//
//   build/<dir>/mlvq_vq_bench [--size 64] [--preset lacquered_wood] [--threads 2]
//                             [--queries 2000] [--min-time 0.5] [--quick]

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench_common.h"
#include "btf/codecs/mlvq/vq.h"
#include "btf/synth/synth.h"

namespace {

using namespace btf;
using mlvq::Codebook;
using mlvq::CodebookOptions;
using mlvq::Match;

constexpr int kAlpha = 11, kBeta = 11;

struct Slices {
    std::vector<std::vector<float>> p1, p2;
};

// Luminance of every texel for every view and (α, β) light, cut into P1 and P2 slices.
Slices render(const std::string& preset, int size) {
    Slices out;
    const std::vector<double> thetas = {0, 15, 30, 45, 60, 75};
    for (int az = 0; az < 4; ++az) {
        const double phi_v = radians(90.0 * az + 10);
        std::vector<Direction> views;
        for (double t : thetas)
            if (t > 0 || az == 0) views.push_back({radians(t), phi_v});
        std::vector<Direction> lights;
        const Vec3 ex{std::cos(phi_v), std::sin(phi_v), 0},
            ey{-std::sin(phi_v), std::cos(phi_v), 0};
        for (int a = 0; a < kAlpha; ++a)
            for (int b = 0; b < kBeta; ++b) {
                const double alpha = kPi * (double(a) / (kAlpha - 1) - 0.5);
                const double beta = std::asin(-1 + 2.0 * b / (kBeta - 1));
                const Vec3 v = ex * std::sin(beta) + ey * (std::sin(alpha) * std::cos(beta)) +
                               Vec3{0, 0, 1} * (std::cos(alpha) * std::cos(beta));
                lights.push_back(Direction::from_vector(v));
            }
        const Sampling sampling{DirectionSet("views", views), DirectionSet("alpha-beta", lights)};
        const auto source = synth::make(preset, size, sampling, 1);
        const size_t texels = size_t(size) * size;
        for (int v = 0; v < sampling.num_views(); ++v) {
            std::vector<std::vector<float>> y(texels, std::vector<float>(kAlpha * kBeta));
            std::vector<Image> images(kAlpha * kBeta);
            parallel_for(0, kAlpha * kBeta,
                         [&](int64_t l) { source->read_image(v, int(l), images[l]); });
            for (int l = 0; l < kAlpha * kBeta; ++l) {
                const float* px = images[l].data();
                for (size_t t = 0; t < texels; ++t)
                    y[t][l] =
                        0.2126f * px[3 * t] + 0.7152f * px[3 * t + 1] + 0.0722f * px[3 * t + 2];
            }
            for (auto& slice : y) {
                for (int a = 0; a < kAlpha; ++a)
                    out.p1.emplace_back(slice.begin() + a * kBeta, slice.begin() + (a + 1) * kBeta);
                out.p2.push_back(std::move(slice));
            }
        }
    }
    std::mt19937_64 rng(7);
    std::shuffle(out.p1.begin(), out.p1.end(), rng);
    std::shuffle(out.p2.begin(), out.p2.end(), rng);
    return out;
}

struct Grown {
    Codebook book;
    double threshold = 0;
    double seconds = 0;
};

// Grows a code-book over `stream` with find_or_add() until it holds `target` code-vectors, at the
// largest threshold of the ladder that gets there.
Grown grow(const CodebookOptions& base, const std::vector<std::vector<float>>& stream,
           size_t target, double start) {
    for (double t = start; t > 1e-30; t *= 0.6) {
        CodebookOptions o = base;
        o.threshold = t;
        Codebook book(o);
        bench::Stopwatch clock;
        for (const auto& v : stream) {
            book.find_or_add(v);
            if (book.size() == target) break;
        }
        if (book.size() == target) return {std::move(book), t, clock.seconds()};
    }
    fail("mlvq_vq_bench: no threshold grows a code-book of {} from {} vectors", target,
         stream.size());
}

struct Row {
    std::string data, measure;
    size_t size = 0;
    double threshold = 0, matches = 0, compared = 0, bounded = 0, fast_qps = 0, brute_qps = 0,
           batch_qps = 0, grow_s = 0;
    size_t checked = 0, identical = 0;
};

Row measure(const std::string& name, const CodebookOptions& base,
            const std::vector<std::vector<float>>& data, size_t target, size_t queries,
            double min_time, int threads) {
    if (data.size() < queries + target) fail("mlvq_vq_bench: too few slices for {}", name);
    const std::vector<std::vector<float>> held(data.end() - ptrdiff_t(queries), data.end());
    const std::vector<std::vector<float>> stream(data.begin(), data.end() - ptrdiff_t(queries));
    double start = 0;
    if (base.measure == mlvq::Measure::mse) {
        for (const auto& v : stream)
            for (float x : v) start += double(x) * x;
        start /= double(stream.size() * stream[0].size());
    } else {
        start = 0.5;
    }
    Grown g = grow(base, stream, target, start);
    g.book.rebuild_index();
    Row row;
    row.data = name;
    row.measure = base.measure == mlvq::Measure::mse ? "mse" : "mssim";
    row.size = g.book.size();
    row.threshold = g.threshold;
    row.grow_s = g.seconds;

    std::vector<Match> fast(held.size());
    mlvq::SearchStats stats;
    {
        ThreadLimit one(1);
        bench::Stopwatch clock;
        size_t done = 0;
        do {
            for (size_t i = 0; i < held.size(); ++i)
                fast[i] = g.book.find(held[i], g.threshold, done == 0 ? &stats : nullptr);
            done += held.size();
        } while (clock.seconds() < min_time);
        row.fast_qps = double(done) / clock.seconds();
    }
    for (const Match& m : fast) row.matches += bool(m);
    row.matches /= double(held.size());
    row.compared = double(stats.compared) / double(stats.codebook);
    row.bounded = double(stats.bounded) / double(stats.codebook);
    {
        bench::Stopwatch clock;
        size_t done = 0;
        while (done < held.size() && (done < 20 || clock.seconds() < min_time)) {
            const Match m = g.book.find_brute_force(held[done], g.threshold);
            row.identical += m.index == fast[done].index && m.error == fast[done].error;
            ++done;
        }
        row.brute_qps = double(done) / clock.seconds();
        row.checked = done;
    }
    {
        ThreadLimit limit(threads);
        std::vector<float> flat;
        for (const auto& v : held) flat.insert(flat.end(), v.begin(), v.end());
        bench::Stopwatch clock;
        size_t done = 0;
        do {
            const std::vector<Match> batch = g.book.find_batch(flat, g.threshold);
            for (size_t i = 0; i < batch.size(); ++i)
                if (batch[i].index != fast[i].index) fail("mlvq_vq_bench: batch differs at {}", i);
            done += batch.size();
        } while (clock.seconds() < min_time);
        row.batch_qps = double(done) / clock.seconds();
    }
    std::fprintf(stderr, "%s %s %zu: %.0f q/s vs %.0f q/s\n", name.c_str(), row.measure.c_str(),
                 row.size, row.fast_qps, row.brute_qps);
    return row;
}

std::string rate(double qps) {
    if (qps >= 1e6) return fmt::format("{:.2f} M", qps / 1e6);
    if (qps >= 1e3) return fmt::format("{:.1f} k", qps / 1e3);
    return fmt::format("{:.0f}", qps);
}

}  // namespace

int main(int argc, char** argv) {
    int size = 64, threads = 2;
    size_t queries = 2000;
    double min_time = 0.5;
    bool quick = false;
    uint32_t index_dims = mlvq::CodebookOptions{}.index_dims;
    std::string preset = "lacquered_wood", filter;
    CLI::App app{"mlvq code-vector search: index vs brute force (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side of the synthetic material")
        ->capture_default_str();
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--threads", threads, "threads of the batch column")->capture_default_str();
    app.add_option("--queries", queries, "held-out queries per row")->capture_default_str();
    app.add_option("--min-time", min_time, "seconds per timed loop")->capture_default_str();
    app.add_flag("--quick", quick, "small code-books only");
    app.add_option("--index-dims", index_dims, "principal coordinates of the index signatures")
        ->capture_default_str();
    app.add_option("--filter", filter, "only rows whose label (\"P1 mse 5000\") contains this");
    CLI11_PARSE(app, argc, argv);
    try {
        bench::Stopwatch clock;
        const Slices slices = render(preset, size);
        std::fprintf(stderr, "rendered %zu P1 and %zu P2 slices of %s %d² in %.1f s\n",
                     slices.p1.size(), slices.p2.size(), preset.c_str(), size, clock.seconds());
        CodebookOptions p1, p2;
        p1.name = "P1", p1.layout.dims = {kBeta};
        p2.name = "P2", p2.layout.dims = {kAlpha, kBeta};
        p1.index_dims = p2.index_dims = index_dims;
        // Brute-force MSSIM on the largest code-books would take minutes per row.
        const std::vector<size_t> sizes =
            quick ? std::vector<size_t>{100, 1000} : std::vector<size_t>{100, 1000, 5000, 20000};
        std::vector<Row> rows;
        for (mlvq::Measure m : {mlvq::Measure::mse, mlvq::Measure::mssim})
            for (int level : {1, 2})
                for (size_t n : sizes) {
                    CodebookOptions& o = level == 1 ? p1 : p2;
                    o.measure = m;
                    const auto& data = level == 1 ? slices.p1 : slices.p2;
                    const bool mse = m == mlvq::Measure::mse;
                    const std::string label =
                        fmt::format("P{} {} {}", level, mse ? "mse" : "mssim", n);
                    if (label.find(filter) == std::string::npos || n + queries > data.size() ||
                        (!mse && n > (level == 1 ? 5000u : 1000u)))
                        continue;
                    rows.push_back(measure(level == 1 ? "P1 (11)" : "P2 (11×11)", o, data, n,
                                           queries, min_time, threads));
                }

        fmt::print(
            "| data | measure | code-book | threshold | matches | bounded | compared | "
            "find() | brute force | ratio | identical | find_batch ({} threads) | grow |\n",
            threads);
        fmt::print("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for (const Row& r : rows)
            fmt::print(
                "| {} | {} | {} | {:.3g} | {:.0f} % | {:.2f} % | {:.2f} % | {} q/s | {} q/s | "
                "**{:.0f}×** | {}/{} | {} q/s | {:.2f} s |\n",
                r.data, r.measure, r.size, r.threshold, 100 * r.matches, 100 * r.bounded,
                100 * r.compared, rate(r.fast_qps), rate(r.brute_qps), r.fast_qps / r.brute_qps,
                r.identical, r.checked, rate(r.batch_qps), r.grow_s);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "mlvq_vq_bench: %s\n", e.what());
        return 1;
    }
    return 0;
}

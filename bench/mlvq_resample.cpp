// SPDX-License-Identifier: MIT
// mlvq resampling throughput: a synthetic material on the UBO2003 sampling (81 views × 81 lights)
// resampled onto an MLVQ grid (default 11 × 11 × 7 × 16 = 13552 samples per texel and channel).
// Prints the time to build the resampling table, the time to read the texel rows (the synthetic
// source renders every image), and the gather's rate in texels per second on one thread and on
// all threads.
//
//   build/<dir>/mlvq_resample [--size 64] [--rows 64] [--preset woven_fabric]

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <ctime>
#include <thread>

#include "bench_common.h"
#include "btf/codecs/mlvq/parametrization.h"
#include "btf/synth/synth.h"
#include "btf/util/parallel.h"

using namespace btf;

int main(int argc, char** argv) {
    int size = 64, rows = 64, repeats = 3;
    std::string preset = "woven_fabric";
    mlvq::MlvqGrid grid;
    CLI::App app{"mlvq resampling throughput (ubo81 source -> MLVQ grid)"};
    app.add_option("--size", size, "texels per side of the synthetic material")
        ->capture_default_str();
    app.add_option("--rows", rows, "texel rows resampled (one band)")->capture_default_str();
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--repeats", repeats, "timed repetitions (the best is reported)")
        ->capture_default_str();
    app.add_option("--n-alpha", grid.n_alpha)->capture_default_str();
    app.add_option("--n-beta", grid.n_beta)->capture_default_str();
    app.add_option("--n-theta-v", grid.n_theta_v)->capture_default_str();
    app.add_option("--n-phi-v", grid.n_phi_v)->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        const DirectionSet& ubo = DirectionSet::ubo81();
        const Sampling sampling{ubo, ubo};
        const auto source = synth::make(preset, size, sampling, 1);
        rows = std::min(rows, size);

        bench::Stopwatch table_clock;
        const mlvq::Resampler resampler(grid, sampling);
        const double table_s = table_clock.seconds();
        int64_t terms = 0;
        for (int64_t s = 0; s < resampler.samples(); ++s) terms += resampler.terms(s).size();

        bench::Stopwatch read_clock;
        const mlvq::SourceTexels raw = mlvq::read_rows(*source, 0, rows);
        const double read_s = read_clock.seconds();

        // Into one output buffer, touched once before timing (so that page faults of a fresh
        // allocation are not counted as resampling).
        std::vector<float> out(size_t(raw.texels()) * 3 * size_t(resampler.samples()), 1.0f);
        // Best wall-clock and process CPU seconds of `repeats` runs (CPU time tells the work
        // apart from waiting for a core on a shared machine).
        auto cpu_seconds = [] {
            timespec t{};
            clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
            return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
        };
        auto best_of = [&](int threads, double& cpu) {
            ThreadLimit limit(threads);
            double best = 1e300;
            cpu = 1e300;
            for (int r = 0; r < repeats; ++r) {
                const double cpu0 = cpu_seconds();
                bench::Stopwatch clock;
                resampler.resample(raw, out);
                best = std::min(best, clock.seconds());
                cpu = std::min(cpu, cpu_seconds() - cpu0);
            }
            return best;
        };
        double one_cpu = 0, all_cpu = 0;
        const double one = best_of(1, one_cpu), all = best_of(0, all_cpu);
        const double texels = double(raw.texels());
        std::printf(
            "source: %s %d² × 81 views × 81 lights; grid %d × %d × %d × %d = %lld samples\n",
            preset.c_str(), size, grid.n_alpha, grid.n_beta, grid.n_theta_v, grid.n_phi_v,
            static_cast<long long>(resampler.samples()));
        std::printf("table: %.3f s, %.2f terms per sample (≤ 9)\n", table_s,
                    double(terms) / double(resampler.samples()));
        std::printf("read %d rows (%lld texels, %.0f MiB raw float): %.2f s\n", rows,
                    static_cast<long long>(raw.texels()), bench::mib(raw.bytes()), read_s);
        std::printf(
            "resample, 1 thread:   %.0f texels/s wall, %.0f texels per CPU second (%.2f ns per "
            "output value)\n",
            texels / one, texels / one_cpu,
            one_cpu / (texels * 3 * double(resampler.samples())) * 1e9);
        std::printf("resample, %d threads: %.0f texels/s wall (%.2f CPU seconds per wall second)\n",
                    static_cast<int>(std::thread::hardware_concurrency()), texels / all,
                    all_cpu / all);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "mlvq_resample: %s\n", e.what());
        return 1;
    }
    return 0;
}

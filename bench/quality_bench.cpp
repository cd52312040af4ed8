// SPDX-License-Identifier: MIT
// Throughput of quality::compare(): texels per second (one texel = one RGB sample of one image)
// for each measure alone and for all four together, comparing a synthetic material held in memory
// (default woven_fabric, 128² texels × 81 views × 81 lights) with the same plus uniform noise of
// ±amplitude/2 (a fixed noise image, shifted per image, added while reading). Both sources read
// from memory, so the figures are the cost of the measures (plus two image copies). texels/s is
// the wall-clock rate; texels/cpu-s the rate per second of CPU time summed over all threads.
//
//   build/<dir>/quality_bench [--size 128] [--preset woven_fabric] [--threads 2]
//                             [--noise 0.02] [--benchmark_filter=...]

#include <benchmark/benchmark.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "bench_common.h"
#include "btf/quality/metrics.h"
#include "btf/synth/synth.h"

namespace {

using namespace btf;

// `base` plus a fixed noise image, shifted by the image index.
class NoisySource final : public BtfSource {
  public:
    NoisySource(const bench::MemorySource& base, float amplitude) : m_base(base) {
        m_info = base.info();
        m_info.format = "noisy " + m_info.format;
        m_noise.resize(size_t(base.num_texels()) * 3);
        uint64_t state = 0x9E3779B97F4A7C15ull;
        for (float& v : m_noise) {
            state ^= state << 13, state ^= state >> 7, state ^= state << 17;  // xorshift64
            v = amplitude * (float(state >> 40) * 0x1.0p-24f - 0.5f);
        }
    }
    int width() const override { return m_base.width(); }
    int height() const override { return m_base.height(); }
    const Sampling& sampling() const override { return m_base.sampling(); }
    const SourceInfo& info() const override { return m_info; }
    void read_image(int view, int light, Image& out) const override {
        out.reshape(width(), height(), 3);
        const float* in = m_base.pixels(view, light);
        const size_t n = m_noise.size();
        const size_t shift = (size_t(view) * 7919 + size_t(light) * 104729) % n;
        float* o = out.data();
        const float* noise = m_noise.data();
        for (size_t i = 0; i < n - shift; ++i) o[i] = in[i] + noise[i + shift];
        for (size_t i = n - shift; i < n; ++i) o[i] = in[i] + noise[i + shift - n];
    }

  private:
    const bench::MemorySource& m_base;
    SourceInfo m_info;
    std::vector<float> m_noise;
};

double process_cpu_seconds() {
    timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

struct Pair {
    std::unique_ptr<bench::MemorySource> reference;
    std::unique_ptr<NoisySource> test;
};

void BM_Compare(benchmark::State& state, const Pair& pair, const std::string& metrics) {
    quality::CompareOptions options;
    options.metrics = quality::MetricSelection::parse(metrics);
    quality::Metrics m;
    double cpu_seconds = 0;
    for (auto _ : state) {
        const double cpu_start = process_cpu_seconds();
        m = quality::compare(*pair.reference, *pair.test, options);
        cpu_seconds += process_cpu_seconds() - cpu_start;
    }
    const double texels = double(m.texels) * double(m.images);
    state.counters["texels/s"] =
        benchmark::Counter(texels, benchmark::Counter::kIsIterationInvariantRate);
    // Per second of CPU time of all threads: what each core delivers, less sensitive to other
    // processes on a shared machine than the wall-clock rate.
    state.counters["texels/cpu-s"] = texels * double(state.iterations()) / cpu_seconds;
    state.counters["images/s"] =
        benchmark::Counter(double(m.images), benchmark::Counter::kIsIterationInvariantRate);
    state.SetLabel(
        fmt::format("rmse {:.4g} dE {:.3g} ssim {:.4g}", m.rmse, m.de2000_mean, m.ssim_luminance));
}

}  // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);  // takes the --benchmark_* options
    int size = 128, threads = 2;
    std::string preset = "woven_fabric";
    float noise = 0.02f;
    CLI::App app{"Throughput of quality::compare() per measure (docs/benchmarks.md)"};
    app.add_option("--size", size, "texels per side")->capture_default_str();
    app.add_option("--preset", preset, "synthetic preset")->capture_default_str();
    app.add_option("--threads", threads, "worker threads (0 = all cores)")->capture_default_str();
    app.add_option("--noise", noise, "peak-to-peak amplitude of the noise")->capture_default_str();
    CLI11_PARSE(app, argc, argv);
    try {
        ThreadLimit limit(threads);
        Pair pair;
        {
            bench::Stopwatch clock;
            const DirectionSet& ubo = DirectionSet::ubo81();
            const auto source = synth::make(preset, size, {ubo, ubo}, 1);
            pair.reference = std::make_unique<bench::MemorySource>(*source);
            pair.test = std::make_unique<NoisySource>(*pair.reference, noise);
            std::fprintf(stderr, "synthesized %s %d² × 81 × 81 into memory in %.1f s\n",
                         preset.c_str(), size, clock.seconds());
        }
        for (const char* metrics : {"rmse", "lab", "de2000", "ssim", "rmse,lab,de2000,ssim"})
            benchmark::RegisterBenchmark(
                (std::string("BM_Compare/") + metrics).c_str(),
                [&pair, metrics](benchmark::State& state) { BM_Compare(state, pair, metrics); })
                ->Unit(benchmark::kSecond)
                ->UseRealTime()
                ->Iterations(1);
        benchmark::RunSpecifiedBenchmarks();
        benchmark::Shutdown();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "quality_bench: %s\n", e.what());
        return 1;
    }
    return 0;
}

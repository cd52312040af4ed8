// SPDX-License-Identifier: MIT
// Speed of the synthetic BTF sources.
//
// BM_FullBtf128/<preset>: every image of a 128² × 81 views × 81 lights BTF (6561 images), read
// with parallel_for over images, from a fresh source (so the per-view and per-light
// precomputations are included). Target: under 60 s on 2 cores.
// BM_Images256/<preset>: images/s at 256² with warm caches (parallel over images), i.e. the
// steady-state cost of one shading pass.
//
// Run: build/synth/synth_bench [--benchmark_filter=...]

#include <benchmark/benchmark.h>

#include <atomic>

#include "btf/synth/synth.h"
#include "btf/util/parallel.h"

namespace {

const btf::Sampling& ubo_sampling() {
    static const btf::Sampling sampling{btf::DirectionSet::ubo81(), btf::DirectionSet::ubo81()};
    return sampling;
}

double checksum_images(const btf::BtfSource& source, int64_t first, int64_t count) {
    const int lights = source.num_lights();
    std::atomic<int64_t> sum{0};
    btf::parallel_for(first, first + count, [&](int64_t i) {
        const int64_t image = i % source.sampling().num_images();
        btf::Image out;
        source.read_image(int(image / lights), int(image % lights), out);
        sum += int64_t(out.values()[0] * 1000);
    });
    return double(sum.load());
}

void BM_FullBtf128(benchmark::State& state, const std::string& preset) {
    for (auto _ : state) {
        const auto source = btf::synth::make(preset, 128, ubo_sampling(), 1);
        benchmark::DoNotOptimize(checksum_images(*source, 0, source->sampling().num_images()));
    }
    state.counters["images/s"] =
        benchmark::Counter(double(ubo_sampling().num_images()) * double(state.iterations()),
                           benchmark::Counter::kIsRate);
}

void BM_Images256(benchmark::State& state, const std::string& preset) {
    const auto source = btf::synth::make(preset, 256, ubo_sampling(), 1);
    // Warm the caches of the views and lights used below.
    constexpr int64_t kBatch = 81 * 4;
    checksum_images(*source, 0, kBatch);
    for (auto _ : state) benchmark::DoNotOptimize(checksum_images(*source, 0, kBatch));
    state.counters["images/s"] = benchmark::Counter(double(kBatch) * double(state.iterations()),
                                                    benchmark::Counter::kIsRate);
}

const bool kRegistered = [] {
    for (const std::string& preset : btf::synth::preset_names()) {
        benchmark::RegisterBenchmark(("BM_FullBtf128/" + preset).c_str(), BM_FullBtf128, preset)
            ->Unit(benchmark::kSecond)
            ->Iterations(1)
            ->UseRealTime();
        benchmark::RegisterBenchmark(("BM_Images256/" + preset).c_str(), BM_Images256, preset)
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
    }
    return true;
}();

}  // namespace

BENCHMARK_MAIN();

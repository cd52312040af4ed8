// SPDX-License-Identifier: MIT
// Angular interpolation throughput: AngularInterpolator::weights() on random directions (grid
// lookup, four or eight at a time with weights4(), and the brute-force search over all triangles
// as the reference), and the full 6-D lookup (≤ 3 views × ≤ 3 lights × bilinear) with a trivial
// fetch.
//
//   build/<dir>/interp_bench --benchmark_min_time=1

#include <benchmark/benchmark.h>

#include <array>
#include <random>
#include <vector>

#include "btf/core/angular_interpolator.h"
#include "btf/core/btf_lookup.h"

namespace {

using namespace btf;

// Uniform random directions on the upper hemisphere.
std::vector<Vec3> random_directions(int count, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<Vec3> out;
    out.reserve(count);
    for (int i = 0; i < count; ++i)
        out.push_back(Direction{std::acos(uni(rng)), 2 * kPi * uni(rng)}.vector());
    return out;
}

const DirectionSet& set_by_index(int i) {
    return i == 0 ? DirectionSet::ubo81() : DirectionSet::dome151();
}

void BM_Weights(benchmark::State& state) {
    const AngularInterpolator interp(set_by_index(static_cast<int>(state.range(0))));
    const std::vector<Vec3> dirs = random_directions(1 << 16, 1);
    size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(interp.weights(dirs[i]));
        i = (i + 1) & (dirs.size() - 1);
    }
    state.SetItemsProcessed(state.iterations());
    state.SetLabel(interp.directions().name());
    if (interp.fallback_count() != 0) state.SkipWithError("grid lookup fell back to brute force");
}
BENCHMARK(BM_Weights)->Arg(0)->Arg(1);

// weights4(): four directions per call, and the two-interpolator form (a batch's views and
// lights) with eight; items are directions, so the figures compare with BM_Weights.
void BM_Weights4(benchmark::State& state) {
    const AngularInterpolator interp(set_by_index(static_cast<int>(state.range(0))));
    const std::vector<Vec3> dirs = random_directions(1 << 16, 1);
    const bool paired = state.range(1) != 0;
    size_t i = 0;
    std::array<AngularWeights, 4> a, b;
    for (auto _ : state) {
        const std::array<const Vec3*, 4> first = {&dirs[i], &dirs[i + 1], &dirs[i + 2],
                                                  &dirs[i + 3]};
        if (paired) {
            const std::array<const Vec3*, 4> second = {&dirs[i + 4], &dirs[i + 5], &dirs[i + 6],
                                                       &dirs[i + 7]};
            AngularInterpolator::weights4(interp, first, a, interp, second, b);
            benchmark::DoNotOptimize(b);
        } else {
            interp.weights4(first, a);
        }
        benchmark::DoNotOptimize(a);
        i = (i + 8) & (dirs.size() - 1);
    }
    state.SetItemsProcessed(state.iterations() * (paired ? 8 : 4));
    state.SetLabel(interp.directions().name() + (paired ? ", two at once" : ""));
    if (interp.fallback_count() != 0) state.SkipWithError("grid lookup fell back to brute force");
}
BENCHMARK(BM_Weights4)->Args({0, 0})->Args({1, 0})->Args({0, 1})->Args({1, 1});

void BM_WeightsBruteForce(benchmark::State& state) {
    const AngularInterpolator interp(set_by_index(static_cast<int>(state.range(0))));
    const std::vector<Vec3> dirs = random_directions(1 << 16, 1);
    size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(interp.weights_brute_force(dirs[i]));
        i = (i + 1) & (dirs.size() - 1);
    }
    state.SetItemsProcessed(state.iterations());
    state.SetLabel(interp.directions().name());
}
BENCHMARK(BM_WeightsBruteForce)->Arg(0)->Arg(1);

// lookup6d with precomputed weights: 9 direction pairs (fewer where a query sits on the rim)
// × 4 texels, with a fetch that only computes a value from its arguments.
void BM_Lookup6d(benchmark::State& state) {
    const AngularInterpolator interp(set_by_index(static_cast<int>(state.range(0))));
    const std::vector<Vec3> dirs = random_directions(1 << 12, 2);
    std::vector<AngularWeights> weights;
    for (const Vec3& d : dirs) weights.push_back(interp.weights(d));
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<Uv> uvs(1 << 12);
    for (Uv& uv : uvs) uv = {uni(rng), uni(rng)};
    auto fetch = [](int x, int y, int v, int l) {
        return Rgb{float(x + v), float(y + l), float(x ^ y)};
    };
    size_t i = 0;
    for (auto _ : state) {
        const size_t j = (i * 7 + 13) & (weights.size() - 1);
        benchmark::DoNotOptimize(lookup6d(uvs[i], 256, 256, weights[i], weights[j], fetch));
        i = (i + 1) & (uvs.size() - 1);
    }
    state.SetItemsProcessed(state.iterations());
    state.SetLabel(interp.directions().name());
}
BENCHMARK(BM_Lookup6d)->Arg(0)->Arg(1);

// What an evaluator pays per eval(uv, wi, wo): two weights() queries plus lookup6d.
void BM_WeightsAndLookup6d(benchmark::State& state) {
    const AngularInterpolator interp(set_by_index(static_cast<int>(state.range(0))));
    const std::vector<Vec3> dirs = random_directions(1 << 12, 2);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<Uv> uvs(1 << 12);
    for (Uv& uv : uvs) uv = {uni(rng), uni(rng)};
    auto fetch = [](int x, int y, int v, int l) {
        return Rgb{float(x + v), float(y + l), float(x ^ y)};
    };
    size_t i = 0;
    for (auto _ : state) {
        const size_t j = (i * 7 + 13) & (dirs.size() - 1);
        benchmark::DoNotOptimize(
            lookup6d(uvs[i], 256, 256, interp.weights(dirs[i]), interp.weights(dirs[j]), fetch));
        i = (i + 1) & (uvs.size() - 1);
    }
    state.SetItemsProcessed(state.iterations());
    state.SetLabel(interp.directions().name());
}
BENCHMARK(BM_WeightsAndLookup6d)->Arg(0)->Arg(1);

void BM_Build(benchmark::State& state) {
    for (auto _ : state) {
        const AngularInterpolator interp(set_by_index(static_cast<int>(state.range(0))));
        benchmark::DoNotOptimize(interp.num_triangles());
    }
    state.SetLabel(set_by_index(static_cast<int>(state.range(0))).name());
}
BENCHMARK(BM_Build)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

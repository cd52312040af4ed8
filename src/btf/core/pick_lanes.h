// SPDX-License-Identifier: MIT
#pragma once
/// pick() of btf/core/material.h for kPickLanes queries at once, one per lane of a vector of
/// doubles: the same operations on the same doubles, so the same draws bit for bit, with
/// kPickLanes chains of picks in flight instead of one. Batches of stochastic queries draw their
/// texels, views and lights with it (the factor evaluator, mlvq).

#include <cstdint>

namespace btf {

constexpr int kPickLanes = 4;
typedef double PickLanes __attribute__((vector_size(8 * kPickLanes)));
typedef int64_t PickMask __attribute__((vector_size(8 * kPickLanes)));  // lanes 0 or −1, or indices

/// Weights w[i] (zero from each lane's count on), last[i] the lanes whose count is i + 1, u each
/// lane's number, replaced as pick() replaces it; returns each lane's index. Every candidate
/// remaining number is computed and the drawn one kept, so the division does not wait for the
/// comparisons.
template <int N>
inline PickMask pick_lanes(const PickLanes* w, const PickMask* last, PickLanes& u) {
    PickLanes low[N];
    PickLanes total{};
#pragma GCC unroll 32
    for (int i = 0; i < N; ++i) {
        low[i] = total;
        total += w[i];
    }
    const PickMask some = total > 0;
    const PickLanes target = u * total;
    PickMask taken{}, positive_last{}, index{};
    PickLanes next{};
#pragma GCC unroll 32
    for (int i = 0; i < N; ++i) {
        const PickMask positive = w[i] > 0;
        const PickMask stop = positive & ((target < low[i] + w[i]) | last[i]) & ~taken;
        const PickLanes candidate = (target - low[i]) / w[i];
        next = (PickLanes)(((PickMask)next & ~stop) | ((PickMask)candidate & stop));
        index = (index & ~stop) | ((PickMask{} + i) & stop);
        positive_last = (positive_last & ~positive) | ((PickMask{} + i) & positive);
        taken |= stop;
    }
    constexpr double kBelowOne = 0x1.fffffffffffffp-1;
    // As std::clamp(next, 0, kBelowOne); no stop: kBelowOne and the last positive weight.
    next = next < PickLanes{} ? PickLanes{} : next;
    next = PickLanes{} + kBelowOne < next ? PickLanes{} + kBelowOne : next;
    next = taken ? next : PickLanes{} + kBelowOne;
    index = taken ? index : positive_last;
    // No positive weight: index 0, the number unchanged.
    u = some ? next : u;
    return some ? index : PickMask{};
}

}  // namespace btf

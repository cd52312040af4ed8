// SPDX-License-Identifier: MIT
#pragma once
// Tests of direction samplers over the upper hemisphere (GoogleTest helpers; not part of the
// library): a chi-square goodness-of-fit test of a sampler against its pdf, and the integral of
// a function over the hemisphere. Used by the generic light sampler's tests and by codecs with
// native importance sampling (mlvq).
//
// The chi-square test (after Mitsuba 3's ChiSquareTest): the hemisphere is binned into n × n
// cells of equal solid angle by the area-preserving square↔hemisphere map (btf/core/hemisphere.h).
// `samples` directions are drawn with ξ from a fixed-seed generator and counted per bin; the
// expected count of a bin is samples × ∫_bin pdf dω, integrated by the midpoint rule on s × s
// sub-cells (each of solid angle 2π / (n s)²). Bins with an expected count below `min_expected`
// are pooled into one bin (dropped if the pool's expectation stays below it), and
//     χ² = Σ (observed − expected)² / expected,   dof = bins − 1,
//     p   = Q(dof / 2, χ² / 2)   (the regularized upper incomplete gamma function, Eigen's
//     igammac).
// A sampler that draws from its pdf passes with probability 1 − significance; with a fixed seed
// the outcome is deterministic. Use significance 1e-3 per test, or a Šidák-corrected
// 1 − (1 − 1e-3)^(1/k) when one test case runs k of them. The pdf is not renormalized: a pdf that
// integrates to 0.97 fails too. A sample below the horizon, of non-unit length or not finite, or in
// a bin whose expected count is 0, fails the test outright.

#include <unsupported/Eigen/SpecialFunctions>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "btf/core/hemisphere.h"
#include "btf/core/math.h"

namespace btf::test {

/// A double in [0, 1) from the 53 high bits of the generator: the same sequence on every
/// platform (std::uniform_real_distribution is implementation-defined).
inline double uniform01(std::mt19937_64& rng) {
    return double(rng() >> 11) * 0x1p-53;
}

/// ∫ f(ω) dω over the upper hemisphere by the midpoint rule on an n × n equal-area grid.
inline double integrate_hemisphere(const std::function<double(const Vec3&)>& f, int n) {
    double sum = 0;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) sum += f(square_to_hemisphere({(c + 0.5) / n, (r + 0.5) / n}));
    return sum * 2 * kPi / (double(n) * n);
}

struct ChiSquareOptions {
    int resolution = 16;    ///< n: n × n equal-area bins
    int supersampling = 8;  ///< s: pdf evaluations per bin side for the expected counts
    int64_t samples = 200000;
    uint64_t seed = 1;
    double min_expected = 5;  ///< bins expecting fewer samples are pooled
};

struct ChiSquareResult {
    double statistic = 0;
    int dof = 0;
    double p_value = 0;
    double pdf_integral = 0;  ///< ∫ pdf dω over the hemisphere, from the same quadrature
    int64_t invalid = 0;      ///< samples below the horizon, not unit length or not finite
    int64_t unexpected = 0;   ///< samples in bins whose expected count is 0
    std::string worst;        ///< the bins that contribute most to χ², for failure messages

    bool passed(double significance) const {
        return invalid == 0 && unexpected == 0 && p_value >= significance;
    }
    std::string describe() const {
        return fmt::format(
            "chi2 {:.1f}, dof {}, p {:.3g}, integral of pdf {:.5f}, invalid {}, "
            "in zero-pdf bins {}; largest contributions: {}",
            statistic, dof, p_value, pdf_integral, invalid, unexpected, worst);
    }
};

/// Runs the test: `sample(ξ1, ξ2)` returns a direction, `pdf(ω)` its density per solid angle.
inline ChiSquareResult chi_square_hemisphere(const std::function<Vec3(double, double)>& sample,
                                             const std::function<double(const Vec3&)>& pdf,
                                             const ChiSquareOptions& options = {}) {
    const int n = options.resolution, s = options.supersampling;
    const size_t bins = size_t(n) * n;
    ChiSquareResult result;

    std::vector<double> expected(bins, 0.0);
    const double sub_area = 2 * kPi / (double(n) * s * n * s);
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            double sum = 0;
            for (int j = 0; j < s; ++j)
                for (int i = 0; i < s; ++i)
                    sum += pdf(square_to_hemisphere(
                        {(c * s + i + 0.5) / (n * s), (r * s + j + 0.5) / (n * s)}));
            expected[size_t(r) * n + c] = sum * sub_area;
        }
    for (double& e : expected) result.pdf_integral += e;
    for (double& e : expected) e *= double(options.samples);

    std::vector<int64_t> observed(bins, 0);
    std::mt19937_64 rng(options.seed);
    for (int64_t k = 0; k < options.samples; ++k) {
        const double xi1 = uniform01(rng), xi2 = uniform01(rng);
        const Vec3 w = sample(xi1, xi2);
        const double len = length(w);
        if (!std::isfinite(len) || std::abs(len - 1) > 1e-6 || w.z < -1e-9) {
            ++result.invalid;
            continue;
        }
        const SquarePoint p = hemisphere_to_square(w);
        const int c = std::min(static_cast<int>(p.u * n), n - 1);
        const int r = std::min(static_cast<int>(p.v * n), n - 1);
        ++observed[size_t(r) * n + c];
    }

    // Pool the bins with small expectations (smallest first), then sum the contributions.
    std::vector<size_t> order(bins);
    for (size_t i = 0; i < bins; ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return expected[a] < expected[b]; });
    double pooled_expected = 0;
    int64_t pooled_observed = 0;
    struct Contribution {
        double value;
        size_t bin;
        double expected;
        int64_t observed;
    };
    std::vector<Contribution> contributions;
    int used = 0;
    for (size_t i : order) {
        if (expected[i] <= 0) {
            result.unexpected += observed[i];
        } else if (expected[i] < options.min_expected) {
            pooled_expected += expected[i];
            pooled_observed += observed[i];
        } else {
            const double d = double(observed[i]) - expected[i];
            contributions.push_back({d * d / expected[i], i, expected[i], observed[i]});
            ++used;
        }
    }
    if (pooled_expected >= options.min_expected) {
        const double d = double(pooled_observed) - pooled_expected;
        contributions.push_back({d * d / pooled_expected, bins, pooled_expected, pooled_observed});
        ++used;
    } else if (used > 0) {
        // Too little to form a bin of its own: add it to the smallest regular bin.
        Contribution& smallest = contributions.front();
        smallest.expected += pooled_expected;
        smallest.observed += pooled_observed;
        const double d = double(smallest.observed) - smallest.expected;
        smallest.value = d * d / smallest.expected;
    }
    for (const Contribution& c : contributions) result.statistic += c.value;
    result.dof = std::max(used - 1, 0);
    result.p_value =
        result.dof > 0 ? Eigen::numext::igammac(0.5 * result.dof, 0.5 * result.statistic) : 1.0;

    std::sort(contributions.begin(), contributions.end(),
              [](const Contribution& a, const Contribution& b) { return a.value > b.value; });
    for (size_t k = 0; k < std::min<size_t>(3, contributions.size()); ++k) {
        const Contribution& c = contributions[k];
        const std::string where = c.bin == bins
                                      ? std::string("pooled")
                                      : fmt::format("row {} col {}", c.bin / n, c.bin % n);
        result.worst += fmt::format("{}{}: observed {} expected {:.1f}", k ? "; " : "", where,
                                    c.observed, c.expected);
    }
    return result;
}

}  // namespace btf::test

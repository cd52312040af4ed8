// SPDX-License-Identifier: MIT
#include "btf/render/distribution.h"

#include <algorithm>
#include <climits>
#include <cmath>

#include "btf/util/error.h"

namespace btf::render {

namespace {

std::vector<double> checked_weights(std::span<const double> weights, const char* what) {
    check(!weights.empty(), "{}: no weights", what);
    check(weights.size() <= size_t(INT_MAX), "{}: {} weights (at most {} are supported)", what,
          weights.size(), INT_MAX);
    for (size_t i = 0; i < weights.size(); ++i)
        check(std::isfinite(weights[i]) && weights[i] >= 0,
              "{}: weight {} is {} (weights must be finite and ≥ 0)", what, i, weights[i]);
    return {weights.begin(), weights.end()};
}

}  // namespace

Distribution1D::Distribution1D(std::span<const double> weights)
    : m_weights(checked_weights(weights, "Distribution1D")) {
    const size_t n = m_weights.size();
    m_cdf.resize(n + 1);
    // The running sums are divided by the last of them, so the CDF reaches exactly 1 at the last
    // non-zero bin and stays there: trailing zero bins get empty steps and are never drawn.
    double sum = 0;
    m_cdf[0] = 0;
    for (size_t i = 0; i < n; ++i) {
        sum += m_weights[i];
        m_cdf[i + 1] = sum;
    }
    check(std::isfinite(sum), "Distribution1D: the {} weights sum to {} (too large)", n, sum);
    m_integral = sum / double(n);
    m_uniform = !(sum > 0);
    if (m_uniform) {
        for (size_t i = 0; i <= n; ++i) m_cdf[i] = double(i) / double(n);
    } else {
        for (size_t i = 1; i <= n; ++i) m_cdf[i] = std::min(m_cdf[i] / sum, 1.0);
        m_density_scale = double(n) / sum;
    }
    m_cdf[n] = 1;
}

int Distribution1D::bin_of(double x) const {
    const int n = size();
    if (!(x > 0)) return 0;  // also catches NaN
    if (x >= 1) return n - 1;
    return std::min(int(x * n), n - 1);
}

double Distribution1D::pdf(double x) const {
    if (m_uniform) return 1;
    return m_weights[size_t(bin_of(x))] * m_density_scale;
}

Distribution1D::Sample Distribution1D::sample_continuous(double xi) const {
    const int n = size();
    xi = xi >= 0 ? std::min(xi, kOneMinusEpsilon) : 0.0;  // NaN → 0
    // upper_bound finds the first CDF entry above ξ; the bin before it has cdf[b] ≤ ξ < cdf[b+1],
    // a non-empty step, so a bin of weight 0 cannot be chosen.
    const auto it = std::upper_bound(m_cdf.begin(), m_cdf.end(), xi);
    const int bin = std::clamp(int(it - m_cdf.begin()) - 1, 0, n - 1);
    const double lo = m_cdf[size_t(bin)], step = m_cdf[size_t(bin) + 1] - lo;
    const double dx = step > 0 ? std::min((xi - lo) / step, kOneMinusEpsilon) : 0.0;
    double x = std::min((bin + dx) / n, kOneMinusEpsilon);
    // (bin + dx) / n can round across a bin boundary, and so can x · n inside bin_of(); nudge x by
    // single ulps until pdf(x) sees the bin the sample was drawn from.
    while (bin_of(x) < bin) x = std::nextafter(x, 1.0);
    while (bin_of(x) > bin) x = std::nextafter(x, 0.0);
    return {x, m_uniform ? 1.0 : m_weights[size_t(bin)] * m_density_scale, bin};
}

namespace {

std::vector<Distribution1D> make_rows(std::span<const double> weights, int width, int height) {
    check(width >= 1 && height >= 1, "Distribution2D: the grid is {} × {} (must be at least 1 × 1)",
          width, height);
    check(weights.size() == size_t(width) * size_t(height),
          "Distribution2D: {} weights for a {} × {} grid (expected {})", weights.size(), width,
          height, size_t(width) * size_t(height));
    std::vector<Distribution1D> rows;
    rows.reserve(size_t(height));
    for (int r = 0; r < height; ++r) rows.emplace_back(weights.subspan(size_t(r) * width, width));
    return rows;
}

std::vector<double> row_integrals(const std::vector<Distribution1D>& rows) {
    std::vector<double> integrals(rows.size());
    for (size_t r = 0; r < rows.size(); ++r) integrals[r] = rows[r].integral();
    return integrals;
}

}  // namespace

Distribution2D::Distribution2D(std::span<const double> weights, int width, int height)
    : m_width(width),
      m_height(height),
      m_conditional(make_rows(weights, width, height)),
      m_marginal(row_integrals(m_conditional)) {}

Distribution2D::Sample Distribution2D::sample(double xi1, double xi2) const {
    const Distribution1D::Sample row = m_marginal.sample_continuous(xi2);
    const Distribution1D::Sample column = m_conditional[size_t(row.bin)].sample_continuous(xi1);
    return {column.x, row.x, row.pdf * column.pdf, column.bin, row.bin};
}

double Distribution2D::pdf(double u, double v) const {
    const int row = m_marginal.bin_of(v);
    return m_marginal.pdf(v) * m_conditional[size_t(row)].pdf(u);
}

}  // namespace btf::render

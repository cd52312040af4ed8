// SPDX-License-Identifier: MIT
#pragma once
/// Piecewise-constant probability distributions over [0,1) and [0,1)², sampled by inverting their
/// cumulative distribution functions (the building block of environment-map importance sampling).
///
/// A distribution is built once from non-negative weights and is immutable afterwards: every
/// method is const, deterministic and safe to call from many threads at once. Sampling costs one
/// binary search (std::upper_bound) per dimension; pdf() is O(1).
///
/// Bins of weight 0 are never sampled: for ξ in [0,1) the inverse CDF always lands in a bin whose
/// CDF step is non-empty, and the returned point always lies inside the bin it was drawn from
/// (pdf(x) of the returned x is the returned pdf, bit for bit).

#include <cstddef>
#include <span>
#include <vector>

namespace btf::render {

/// The largest double below 1: keeps ξ, sampled points and angles mapped to [0, 1) strictly
/// inside it when rounding would reach 1.
inline constexpr double kOneMinusEpsilon = 0x1.fffffffffffffp-1;

/// Piecewise-constant density over [0,1) from n weights: bin i covers [i/n, (i+1)/n) and has
/// density w_i / (Σ w / n). If every weight is 0 the distribution is uniform (density 1) while
/// integral() still reports 0, so callers can tell an empty function from a flat one.
class Distribution1D {
  public:
    /// The result of sample_continuous().
    struct Sample {
        double x = 0;    ///< the sampled point, in [0, 1)
        double pdf = 0;  ///< its density with respect to x
        int bin = 0;     ///< the bin containing x, in [0, n)
    };

    /// Throws btf::Error if `weights` is empty, has more than INT_MAX entries, or holds a negative
    /// or non-finite value.
    explicit Distribution1D(std::span<const double> weights);

    /// The number of bins n.
    int size() const { return int(m_weights.size()); }
    /// ∫₀¹ f(x) dx of the piecewise-constant function the weights define, i.e. Σ w / n.
    double integral() const { return m_integral; }
    /// The weight of bin i as given to the constructor.
    double weight(int bin) const { return m_weights[size_t(bin)]; }

    /// Draws x by inverting the CDF at ξ (ξ is clamped to [0, 1)); the position of ξ inside its
    /// CDF step places x linearly inside the bin, so ξ → x is monotonic and continuous.
    Sample sample_continuous(double xi) const;
    /// The density at x (x outside [0,1) is clamped to the first or last bin).
    double pdf(double x) const;
    /// The probability of drawing bin i.
    double probability(int bin) const { return m_cdf[size_t(bin) + 1] - m_cdf[size_t(bin)]; }
    /// The bin containing x (clamped to [0, n)).
    int bin_of(double x) const;

  private:
    std::vector<double> m_weights;
    std::vector<double> m_cdf;  // n + 1 entries, m_cdf[0] = 0, m_cdf[n] = 1
    double m_integral = 0;
    double m_density_scale = 0;  // density of bin i = weight_i × m_density_scale (or 1 if uniform)
    bool m_uniform = false;
};

/// Piecewise-constant density over [0,1)² from a width × height grid of weights stored row by row
/// (row r, column c at index r·width + c). Column c covers u in [c/width, (c+1)/width), row r
/// covers v in [r/height, (r+1)/height). It is sampled as a marginal distribution over rows (each
/// row weighted by its mean) and one conditional distribution over columns per row. A row whose
/// weights are all 0 is never drawn; if every weight is 0 the distribution is uniform.
class Distribution2D {
  public:
    /// The result of sample().
    struct Sample {
        double u = 0, v = 0;  ///< the sampled point, in [0, 1)²
        double pdf = 0;       ///< its density with respect to du dv
        int column = 0, row = 0;
    };

    /// Throws btf::Error if width or height is < 1, `weights` does not hold width × height values,
    /// or a weight is negative or not finite.
    Distribution2D(std::span<const double> weights, int width, int height);

    int width() const { return m_width; }
    int height() const { return m_height; }
    /// ∫∫ f(u, v) du dv of the piecewise-constant function, i.e. the mean weight.
    double integral() const { return m_marginal.integral(); }

    /// Draws (u, v): ξ2 chooses the row v from the marginal distribution, ξ1 the column u from
    /// that row's conditional distribution (the argument order follows the coordinates: ξ1 → u,
    /// ξ2 → v).
    Sample sample(double xi1, double xi2) const;
    /// The density at (u, v) with respect to du dv, exactly the one sample() reports there.
    double pdf(double u, double v) const;

  private:
    int m_width = 0, m_height = 0;
    std::vector<Distribution1D> m_conditional;  // one per row
    Distribution1D m_marginal;                  // over rows
};

}  // namespace btf::render

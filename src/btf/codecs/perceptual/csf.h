// SPDX-License-Identifier: MIT
#pragma once
/// The linearized contrast sensitivity filters of the perceptual codec (Guthe, Müller, Schneider,
/// Klein 2009, "BTF-CIELab", §5 and Table 2): per CIELab plane the product of a spatial and an
/// angular Gaussian mixture, applied as a spatial filter T_u on each texture (a column of texel
/// values) and an angular filter T_v over the (view, light) pairs of each ABRDF.
///
/// Every Gaussian is e(x) ∝ exp(−x²/σ²), normalized to unit integral, so each mixture's DC gain is
/// the sum of its weights (1 for every mixture of Table 2).
///
/// Discretization:
/// - Spatial: texels are converted to degrees of visual angle by `resolution` (texels per degree),
///   so a Gaussian of σ degrees is s = σ · resolution texels wide. The texture is periodic (BTF
///   textures tile, and the evaluator wraps); the filter multiplies its 2-D DFT by the mixture's
///   continuous transfer function H(f) = Σ w_i exp(−π² s_i² |f|²) at the DFT frequencies (f in
///   cycles per texel; isotropic; the separable Gaussians are applied together). The filter is
///   symmetric and keeps constants exactly (H(0) = Σ w).
/// - Angular: the angle between two directions (great circle, degrees) divided by the angular
///   speed ω (degrees per second) is a time; a Gaussian of σ seconds is σ·ω degrees wide. The 4-D
///   Gaussian over (light, view) separates into a light and a view kernel. On the irregular
///   direction sets each Gaussian's discrete kernel row is normalized to sum 1 (the unit integral
///   of the continuous Gaussian), then the Gaussians are mixed with their weights:
///       T_v = Σ_i w_i K_view,i ⊗ K_light,i,   K_i(d, d') = exp(−∠(d, d')² / (σ_i ω)²) / row sum,
///   so every row of T_v sums to Σ w_i = 1. Row normalization makes T_v non-symmetric; the codec
///   applies T_v and T_vᵀ where each belongs.

#include <Eigen/Core>
#include <vector>

#include "btf/codecs/factor/rsvd.h"
#include "btf/core/direction.h"

namespace btf::perceptual {

/// One Gaussian of a mixture: weight and width σ of w · e(x), e(x) ∝ exp(−x²/σ²), ∫e = 1.
struct Gaussian {
    double weight = 0;
    double sigma = 0;
};

/// A separable CSF (Table 2): spatial mixture (σ in degrees of visual angle) × angular mixture (σ
/// in seconds).
struct Csf {
    std::vector<Gaussian> spatial, angular;
};
/// Table 2, achromatic stimulus (the L* plane).
const Csf& achromatic_csf();
/// Table 2, chromatic stimulus (the a* and b* planes).
const Csf& chromatic_csf();

/// How the material is seen.
struct Viewing {
    double resolution = 10;  ///< r_s, texels per degree of visual angle
    double speed = 100;      ///< ω, degrees of direction change per second
};

/// The periodic, isotropic spatial filter of a Gaussian mixture on width × height textures.
class SpatialFilter {
  public:
    SpatialFilter(const std::vector<Gaussian>& mixture, double texels_per_degree, int width,
                  int height);
    int width() const { return m_width; }
    int height() const { return m_height; }
    /// The transfer function at DFT bin (kx, ky).
    float transfer(int kx, int ky) const { return m_transfer[size_t(ky) * m_width + kx]; }
    /// Filters every column of `textures` (width · height rows, texel y · width + x) in place.
    /// Pairs of columns are filtered as the real and imaginary part of one complex FFT (the
    /// transfer function is real and even); pairs run in parallel, each independently, so the
    /// result does not depend on the number of threads. Throws btf::Error on a row count that is
    /// not width · height.
    void apply(factor::Matrix& textures) const;

  private:
    int m_width, m_height;
    std::vector<float> m_transfer;
};

/// Row-normalized discrete Gaussian over a direction set: K(i, j) = exp(−∠(i, j)² / σ²) / Σ_j …,
/// with ∠ the great-circle angle in degrees and σ in degrees (> 0).
Eigen::MatrixXd angular_kernel(const DirectionSet& set, double sigma_degrees);

/// The angular filter over (view, light) pairs of a Gaussian mixture (σ in seconds) at an angular
/// speed: T = Σ_i w_i K_view,i ⊗ K_light,i, acting on vectors indexed view · lights + light.
class AngularFilter {
  public:
    AngularFilter(const std::vector<Gaussian>& mixture, double degrees_per_second,
                  const Sampling& sampling);
    int views() const { return m_views; }
    int lights() const { return m_lights; }
    /// y ← T y, or Tᵀ y when `transpose`, for every column of y (views · lights rows). Columns run
    /// in parallel, each independently. Throws btf::Error on a wrong row count.
    void apply(factor::Matrix& y, bool transpose) const;
    /// T as an explicit (views · lights)² matrix (tests and small samplings).
    Eigen::MatrixXd matrix() const;

  private:
    int m_views, m_lights;
    std::vector<double> m_weights;
    std::vector<Eigen::MatrixXf> m_view_kernels, m_light_kernels;
};

/// The transforms of the perceptual codec's three CIELab planes for factor::randomized_svd and
/// factor::untransformed_factors: matrix p (0 = L*, achromatic; 1, 2 = a*, b*, chromatic) has
/// rows view · lights + light (one view group, one channel) and columns the texels; left() is the
/// angular filter T_v, right() the spatial filter T_u of the plane's CSF.
class CsfTransforms final : public factor::Transforms {
  public:
    CsfTransforms(const Sampling& sampling, int width, int height, const Viewing& viewing);
    void left(int matrix, factor::Matrix& y, bool transpose) const override;
    void right(int matrix, factor::Matrix& z, bool transpose) const override;
    const SpatialFilter& spatial(int plane) const {
        return plane == 0 ? m_spatial[0] : m_spatial[1];
    }
    const AngularFilter& angular(int plane) const {
        return plane == 0 ? m_angular[0] : m_angular[1];
    }

  private:
    std::vector<SpatialFilter> m_spatial;  // achromatic, chromatic
    std::vector<AngularFilter> m_angular;
};

}  // namespace btf::perceptual

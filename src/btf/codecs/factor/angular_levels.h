// SPDX-License-Identifier: MIT
#pragma once
/// Angular levels of eigen-ABRDFs (high-frequency omission over directions, Guthe et al. 2009
/// §5.3): a component's angular factor stored on a subset of the view and light directions and
/// interpolated back to every (view, light) pair.
///
/// Subsets: each direction set is put in farthest-point order (first the direction nearest the
/// pole, then repeatedly the one whose smallest great-circle angle to those already chosen is
/// largest; ties go to the lower index). Level j keeps the first ⌈n / 2^j⌉ directions of each set,
/// so the levels are nested and spread evenly over the hemisphere, and the outermost ring is
/// reached early (rim directions are far from everything chosen before them). A level exists while
/// both subsets keep at least kMinAngularDirections directions.
///
/// Up-sampling U = U_view ⊗ U_light: every full direction takes the barycentric weights of the
/// subset's AngularInterpolator (the same triangulation and rim rules as every lookup), so a full
/// direction that belongs to the subset reads exactly itself. A factor column with rows
/// (view · nL + light) · channels + channel becomes, per channel c, the matrix F_c (views × lights)
/// and up-samples as U_view · F_c · U_lightᵀ.
///
/// Down-sampling D = D_view ⊗ D_light with D = (UᵀU)⁻¹Uᵀ per set: the least-squares fit, so
/// U·D·x is the closest up-sampled column to x in the sum of squares over all full samples (each
/// measured sample counts once, whatever the density of the set around it). UᵀU is positive
/// definite because every subset direction is itself a full direction.

#include <Eigen/Core>
#include <vector>

#include "btf/core/direction.h"

namespace btf::factor {

/// The fewest directions per set an angular level may keep.
inline constexpr int kMinAngularDirections = 3;

/// The directions of one angular level: indices into the sampling's views and lights (ascending).
struct AngularLevel {
    std::vector<int> views, lights;
    bool operator==(const AngularLevel&) const = default;
};

/// Farthest-point order of a direction set (see above).
std::vector<int> farthest_point_order(const DirectionSet& set);

/// Levels 1..count (fewer when the sets run out: ⌈n / 2^j⌉ < kMinAngularDirections).
std::vector<AngularLevel> nested_angular_levels(const Sampling& sampling, int count);

/// U and D of one level for factor columns of a sampling with `channels` rows per (view, light).
class AngularResampler {
  public:
    /// Throws btf::Error for indices outside the sampling, repeated indices or subsets smaller
    /// than kMinAngularDirections.
    AngularResampler(const Sampling& sampling, const AngularLevel& level, int channels);
    int64_t full_rows() const { return m_full_rows; }
    int64_t coarse_rows() const { return m_coarse_rows; }

    /// full = U · coarse, for every column.
    Eigen::MatrixXd upsample(const Eigen::MatrixXd& coarse) const;
    /// coarse = D · full = argmin_c ‖U c − full‖, for every column.
    Eigen::MatrixXd downsample(const Eigen::MatrixXd& full) const;
    /// U of the views (views × level views) and of the lights (lights × level lights): at most
    /// three non-zero barycentric weights per row.
    const Eigen::MatrixXd& up_views() const { return m_up_views; }
    const Eigen::MatrixXd& up_lights() const { return m_up_lights; }

  private:
    // y (rows (i · m_l + j) · channels + c) = (A ⊗ B) x, with A: rows_a × cols_a over views and
    // B: rows_b × cols_b over lights.
    Eigen::MatrixXd apply(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                          const Eigen::MatrixXd& x) const;
    int m_channels;
    int64_t m_full_rows, m_coarse_rows;
    Eigen::MatrixXd m_up_views, m_up_lights;      // full × coarse
    Eigen::MatrixXd m_down_views, m_down_lights;  // coarse × full
};

}  // namespace btf::factor

// SPDX-License-Identifier: MIT
#include "btf/codecs/perceptual/resample.h"

#include <vector>

#include "btf/core/btf_lookup.h"
#include "btf/util/error.h"

namespace btf::perceptual {

namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// The 1-D up-sampling of n fine texels from n >> level coarse ones: fine texel i reads the coarse
// grid bilinearly (wrapping) at its centre, as the evaluator does (wrap_lerp at (i + 0.5) / n).
Eigen::SparseMatrix<double> axis_upsampling(int n, int level) {
    const int coarse = n >> level;
    std::vector<Eigen::Triplet<double>> entries;
    for (int i = 0; i < n; ++i) {
        const WrapLerp up = wrap_lerp((i + 0.5) / n, coarse);
        entries.emplace_back(i, up.i0, 1.0 - double(up.t));
        entries.emplace_back(i, up.i1, double(up.t));  // duplicates (coarse = 1) are summed
    }
    Eigen::SparseMatrix<double> b(n, coarse);
    b.setFromTriplets(entries.begin(), entries.end());
    return b;
}

}  // namespace

LevelResampler::LevelResampler(int width, int height, int level)
    : m_width(width), m_height(height), m_level(level) {
    check(level >= 1 && level < 31 && width > 0 && height > 0 && width % (1 << level) == 0 &&
              height % (1 << level) == 0,
          "spatial level {} of a {}×{} texture: the extent must be divisible by {}", level, width,
          height, level >= 1 && level < 31 ? (1 << level) : 0);
    m_bx = axis_upsampling(width, level);
    m_by = axis_upsampling(height, level);
    const Sparse sx = Sparse(m_bx.transpose()) * m_bx, sy = Sparse(m_by.transpose()) * m_by;
    m_sx.compute(sx);
    m_sy.compute(sy);
    check(m_sx.info() == Eigen::Success && m_sy.info() == Eigen::Success,
          "spatial level {} of a {}×{} texture: the up-sampling is singular", level, width, height);
}

Eigen::VectorXd LevelResampler::upsample(const Eigen::VectorXd& coarse) const {
    check(coarse.size() == int64_t(coarse_width()) * coarse_height(),
          "up-sampling: {} values for a {}×{} grid", coarse.size(), coarse_width(),
          coarse_height());
    const Eigen::Map<const RowMajor> c(coarse.data(), coarse_height(), coarse_width());
    // F = B_y C B_xᵀ, as (B_x (B_y C)ᵀ)ᵀ so that every product is sparse × dense.
    const RowMajor yc = m_by * c;                            // height × coarse width
    const RowMajor f = (m_bx * yc.transpose()).transpose();  // height × width
    return Eigen::Map<const Eigen::VectorXd>(f.data(), f.size());
}

Eigen::VectorXd LevelResampler::downsample(const Eigen::VectorXd& fine) const {
    check(fine.size() == int64_t(m_width) * m_height, "down-sampling: {} values for {}×{}",
          fine.size(), m_width, m_height);
    const Eigen::Map<const RowMajor> f(fine.data(), m_height, m_width);
    // C = (B_yᵀB_y)⁻¹ B_yᵀ F B_x (B_xᵀB_x)⁻¹.
    const Eigen::MatrixXd xt = m_sx.solve(Eigen::MatrixXd(m_bx.transpose() * f.transpose()));
    const Eigen::MatrixXd c = m_sy.solve(Eigen::MatrixXd(m_by.transpose() * xt.transpose()));
    const RowMajor out = c;  // coarse height × coarse width, row-major
    return Eigen::Map<const Eigen::VectorXd>(out.data(), out.size());
}

}  // namespace btf::perceptual

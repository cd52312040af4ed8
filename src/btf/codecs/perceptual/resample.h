// SPDX-License-Identifier: MIT
#pragma once
/// Spatial levels of eigen-textures (high-frequency omission, Guthe et al. 2009 §5.3): the
/// bilinear, wrapping up-sampling B by 2^level per axis that the factor model's evaluator applies
/// to a block of a reduced level (factor/model.h, "Spatial levels"), and its pseudo-inverse
/// D = (BᵀB)⁻¹Bᵀ, the least-squares down-sampling: B·D·x is the closest texture to x that the
/// coarse grid can represent.

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

namespace btf::perceptual {

class LevelResampler {
  public:
    /// width and height must be divisible by 2^level (level ≥ 1); throws btf::Error otherwise.
    LevelResampler(int width, int height, int level);
    int width() const { return m_width; }
    int height() const { return m_height; }
    int coarse_width() const { return m_width >> m_level; }
    int coarse_height() const { return m_height >> m_level; }

    /// fine (width · height, texel y · width + x) = B · coarse (coarse texel j · coarse_width + i).
    Eigen::VectorXd upsample(const Eigen::VectorXd& coarse) const;
    /// coarse = D · fine = argmin_c ‖B c − fine‖.
    Eigen::VectorXd downsample(const Eigen::VectorXd& fine) const;

  private:
    using Sparse = Eigen::SparseMatrix<double>;
    using Solver = Eigen::SimplicialLDLT<Sparse>;
    int m_width, m_height, m_level;
    Sparse m_bx, m_by;  // fine × coarse, per axis
    Solver m_sx, m_sy;  // BᵀB per axis, factorized
};

}  // namespace btf::perceptual

// SPDX-License-Identifier: MIT
#pragma once
/// Truncated SVDs of BTF matrices too large for memory, run as streaming passes over the rows of
/// one or more matrices. Two methods:
///
/// - Subspace iteration: the randomized range finder with oversampling and q power iterations of
///   Halko, Martinsson and Tropp (2011, algorithms 4.3/4.4 and 5.1), 2 + 2q passes.
/// - Block Krylov (Musco and Musco 2015, on the column side): blocks X₀ (below),
///   X_{i+1} = orth(MᵀM Xᵢ ⊥ X₀…Xᵢ), q + 2 blocks of b columns, then the best rank-k
///   approximation within their span (Rayleigh–Ritz: the SVD of M·[X₀ … X_{q+1}]). Each pass
///   reads the batches once and computes both Y = M Xᵢ and Z = Mᵀ Y from the rows in hand, so
///   q + 2 passes; for equal accuracy it needs about half the products of subspace iteration.
///   X₀ is not Gaussian but the b leading right singular vectors of 4b rows sampled evenly
///   from up to 16 batches (read once more: 16 of fmf's 81 views): a BTF's images are so
///   alike that their leading subspace is close to the whole matrix's. Matrices too small for
///   the blocks ((q + 2)·b > min(rows, cols) or (q + 1)·b < rank) fall back to subspace
///   iteration.
///
/// A pass reads every row batch once and multiplies it with thin matrices; memory is bounded by
/// the thin factors (rows × l and cols × l floats, l the sketch width) plus one batch, never
/// the whole matrix. Several matrices that share the batches (the three colour planes of a
/// decorrelated factorization, the view groups of pca-views) are factorized in the same passes.
///
/// Numerics are deterministic for a given seed: row products are computed in fixed row chunks,
/// column products in fixed column slices, each by OpenBLAS on one thread (util/blas.h), sums in
/// a fixed order, independent of the number of threads.
///
/// Across ranks (docs/distributed.md): with a current_collective() of N > 1 ranks
/// (util/collective.h), each rank reads only its contiguous share of the batches. The products
/// with the columns' side (Mᵀ·Q, the texel side, cols × l) are summed over the ranks; the row
/// side's products (M·X, rows × l, small next to it) are completed by the same sum, every rank
/// holding zeros in the rows it did not read, which makes them exact copies of what one process
/// computes. Every orthogonalization and small SVD then runs on identical thin matrices on every
/// rank, with no communication of its own. Results differ from one process's only by the order
/// in which the ranks' partial texel-side sums are added (float rounding), and are the same bits
/// in every run with as many ranks; with one rank they are one process's bits.
///
/// Optional linear maps around the streamed matrices (Transforms) factorize L·M·Rᵀ instead of M
/// without ever forming it: only the thin sketches are mapped (the perceptual codec's CSF filters,
/// Guthe et al. 2009 §5). untransformed_factors() then returns to M's space in one more pass.
/// With a left map, block Krylov cannot combine the two products of a block in one pass (L mixes
/// rows of different batches) and takes 2q + 3 passes.

#include <Eigen/Core>

#include <cstdint>
#include <vector>

#include "btf/util/progress.h"

namespace btf::factor {

/// Row-major float matrix (row r contiguous).
using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// One or more matrices whose rows are read together in batches.
class RowBatches {
  public:
    virtual ~RowBatches() = default;
    virtual int matrices() const = 0;
    virtual int64_t rows(int matrix) const = 0;
    virtual int64_t cols(int matrix) const = 0;
    virtual int batches() const = 0;
    /// Reads batch `batch`: for each matrix m, the rows [first[m], first[m] + out[m].rows()) of
    /// matrix m (out[m] may have no rows). Called from one thread at a time; may use worker
    /// threads inside. `first` and `out` are resized to matrices().
    virtual void read(int batch, std::vector<int64_t>& first, std::vector<Matrix>& out) const = 0;
    /// The number of rows of matrix `matrix` that read(batch) gives, without reading them: block
    /// Krylov plans the rows it samples before reading any. The default reads the batch.
    virtual int64_t batch_rows(int batch, int matrix) const;
    /// Rows held in memory already: like read(), but gives pointers to them instead of copies
    /// (row-major, contiguous, cols(m) floats per row; null where a matrix has no rows in the
    /// batch). Returns false (the default) when the rows must be read.
    virtual bool view(int batch, std::vector<int64_t>& first, std::vector<const float*>& data,
                      std::vector<int64_t>& rows) const {
        (void)batch, (void)first, (void)data, (void)rows;
        return false;
    }
};

/// Linear maps L_m (rows × rows) and R_m (cols × cols) around matrix m. They are applied to thin
/// matrices only (l = rank + oversampling columns): randomized_svd() then factorizes
/// M̃_m = L_m · (M_m − mean) · R_mᵀ, using the products M̃Ω = L(M(RᵀΩ)) and M̃ᵀQ = R(Mᵀ(LᵀQ)).
/// Implementations must be deterministic and may use worker threads.
class Transforms {
  public:
    virtual ~Transforms() = default;
    /// y ← L_m y, or L_mᵀ y when `transpose` (y has rows(m) rows).
    virtual void left(int matrix, Matrix& y, bool transpose) const = 0;
    /// z ← R_m z, or R_mᵀ z when `transpose` (z has cols(m) rows).
    virtual void right(int matrix, Matrix& z, bool transpose) const = 0;
};

enum class SvdMethod { kSubspace, kBlockKrylov };

struct SvdOptions {
    int rank = 16;  ///< components kept (clamped to min(rows, cols))
    SvdMethod method = SvdMethod::kSubspace;
    /// Subspace: extra random vectors of the range finder. Block Krylov: the blocks span at
    /// least 2 · (rank + oversampling) columns together, unless `block` says otherwise.
    int oversampling = 10;
    /// q. Subspace: power iterations, sharper for slowly decaying spectra, 2 passes each. Block
    /// Krylov: q + 2 blocks, one pass each.
    int power_iterations = 2;
    /// Block Krylov: columns per block (0: ⌈2 · (rank + oversampling) / (q + 2)⌉).
    int block = 0;
    /// Subtract each row's mean over the columns before factorizing (PCA with row-mean centring).
    bool subtract_mean = false;
    uint64_t seed = 1;
    /// Factorize L·(M − mean)·Rᵀ instead of M − mean (null: no maps). Not owned.
    const Transforms* transforms = nullptr;
};

/// value(r, c) ≈ mean[r] + Σ_k u(r, k) · sigma[k] · v(c, k); u and v have orthonormal columns.
struct Svd {
    Matrix u;                 ///< rows × rank
    Eigen::VectorXf sigma;    ///< rank singular values, descending
    Matrix v;                 ///< cols × rank
    std::vector<float> mean;  ///< rows entries when subtract_mean, else empty
    double total_energy = 0;  ///< ‖M − mean‖²_F, so that the truncation error is known:
                              ///< ‖M − M_k‖²_F = total_energy − Σ sigma²
                              ///< (with Transforms: of the untransformed M − mean)
    /// Σ of the squares of all rank + oversampling singular values of the sketch: the energy of
    /// the factorized (with Transforms: transformed) matrix within the sketched subspace. At most
    /// its total energy; equal to it when the sketch spans the row space (exact_svd: always).
    double sketch_energy = 0;
};

/// Randomized truncated SVDs of every matrix of `batches` (one result per matrix) by
/// options.method. Reports one progress unit per batch read.
std::vector<Svd> randomized_svd(const RowBatches& batches, const SvdOptions& options,
                                Progress& progress = Progress::none());

/// Factors of the untransformed matrices that transformed SVDs imply (Guthe et al. 2009, §5.4:
/// "accumulate the untransformed basis textures and ABRDFs"). For M̃ = L (M − mean) Rᵀ ≈ P Σ Qᵀ,
/// the first keep[m] triplets of svds[m], one streaming pass computes
///     a = (M − mean) Rᵀ Q Σ⁻¹   (rows × k)      b = (M − mean)ᵀ Lᵀ P   (cols × k)
/// so that L a = M̃ Q Σ⁻¹ and R b = M̃ᵀ P. For an exact SVD these are P and Q Σ, hence
/// a bᵀ = L⁻¹ P Σ Qᵀ R⁻ᵀ without inverting L or R (neither needs to be invertible or
/// symmetric). `svds` must come from randomized_svd(batches, …) with these transforms (its means
/// are subtracted again) or from exact_svd() of the transformed matrices; kept singular values
/// must be positive. Reports one progress unit per batch.
struct Factors {
    Matrix a;  ///< rows × k
    Matrix b;  ///< cols × k
};
std::vector<Factors> untransformed_factors(const RowBatches& batches, const Transforms& transforms,
                                           const std::vector<Svd>& svds,
                                           const std::vector<int>& keep,
                                           Progress& progress = Progress::none());

/// Passes over the source that randomized_svd() makes with these options (with `transforms`: a
/// left map), for matrices large enough for block Krylov's blocks.
int svd_passes(const SvdOptions& options, bool transforms = false);

/// Exact truncated SVD of an in-memory matrix (Eigen BDCSVD in double): the reference for tests.
Svd exact_svd(const Matrix& matrix, int rank, bool subtract_mean);

/// A RowBatches over in-memory matrices (tests, small inputs): batch b holds rows
/// [b·batch_rows, (b+1)·batch_rows) of every matrix.
class MemoryRows final : public RowBatches {
  public:
    MemoryRows(std::vector<const Matrix*> matrices, int batch_rows);
    int matrices() const override { return static_cast<int>(m_matrices.size()); }
    int64_t rows(int m) const override { return m_matrices[m]->rows(); }
    int64_t cols(int m) const override { return m_matrices[m]->cols(); }
    int batches() const override { return m_batches; }
    void read(int batch, std::vector<int64_t>& first, std::vector<Matrix>& out) const override;
    bool view(int batch, std::vector<int64_t>& first, std::vector<const float*>& data,
              std::vector<int64_t>& rows) const override;
    int64_t batch_rows(int batch, int matrix) const override;

  private:
    std::vector<const Matrix*> m_matrices;
    int m_batch_rows;
    int m_batches;
};

}  // namespace btf::factor

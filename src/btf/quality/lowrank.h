// SPDX-License-Identifier: MIT
#pragma once
/// How well one view of a BTF is approximated by a low-rank matrix: the realism check of the
/// synthetic materials and a quick measure of how hard a material is for PCA-based codecs.
///
/// For a view, the light matrix A has one row per texel and one column per (light, channel)
/// (column 3·light + channel; 243 columns for 81 lights). The best rank-k approximation in the
/// Frobenius norm (Eckart–Young) leaves the squared error Σ_{i>k} σ_i², where σ_i are A's
/// singular values; σ_i² are the eigenvalues of the Gram matrix AᵀA. The Gram matrix is
/// accumulated in double precision band by band of texel rows, so memory is the Gram matrix plus
/// one band (all images of a view are read once when the band budget holds the whole view).

#include <cstdint>
#include <functional>
#include <vector>

#include "btf/core/image.h"
#include "btf/util/progress.h"

namespace btf {

class BtfSource;

/// Result of light_matrix_low_rank().
struct LowRankError {
    int64_t rows = 0;  ///< texels
    int cols = 0;      ///< lights × 3
    double rms = 0;    ///< RMS value of the matrix (no mean subtraction)
    std::vector<int> ranks;
    /// RMSE of the best rank-k approximation divided by rms, per entry of `ranks`.
    std::vector<double> relative_rmse;
    /// Fraction of the sum of squares the rank-k approximation keeps, per entry of `ranks`.
    std::vector<double> energy;
    /// Eigenvalues of AᵀA (squared singular values of A), descending.
    std::vector<double> eigenvalues;
};

struct LowRankOptions {
    /// Memory for one band of texel rows as float (rows × cols × 4 bytes). A view larger than
    /// this is processed in several bands, each reading all images of the view again.
    int64_t band_bytes = int64_t(256) << 20;
};

/// Low-rank approximation error of the light matrix of view `view` of `source`, for each rank in
/// `ranks` (ranks ≥ the number of columns give 0). Images are read in parallel.
/// Throws btf::Error for a view out of range, a negative rank, or an image of the wrong size.
LowRankError light_matrix_low_rank(const BtfSource& source, int view, const std::vector<int>& ranks,
                                   const LowRankOptions& options = {},
                                   Progress& progress = Progress::none());

/// The same for images supplied by a callback: `read(light, out)` fills `out` with the
/// width × height linear RGB image of light `light` in [0, lights). It may be called from several
/// threads at once.
LowRankError light_matrix_low_rank(int width, int height, int lights,
                                   const std::function<void(int light, Image& out)>& read,
                                   const std::vector<int>& ranks,
                                   const LowRankOptions& options = {},
                                   Progress& progress = Progress::none());

}  // namespace btf

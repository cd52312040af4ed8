// SPDX-License-Identifier: MIT
#include "btf/quality/lowrank.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

#include "btf/io/source.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf {

LowRankError light_matrix_low_rank(const BtfSource& source, int view, const std::vector<int>& ranks,
                                   const LowRankOptions& options, Progress& progress) {
    check(view >= 0 && view < source.num_views(), "low-rank check: view {} is outside [0, {})",
          view, source.num_views());
    return light_matrix_low_rank(
        source.width(), source.height(), source.num_lights(),
        [&](int light, Image& out) { source.read_image(view, light, out); }, ranks, options,
        progress);
}

LowRankError light_matrix_low_rank(int width, int height, int lights,
                                   const std::function<void(int light, Image& out)>& read,
                                   const std::vector<int>& ranks, const LowRankOptions& options,
                                   Progress& progress) {
    check(width > 0 && height > 0 && lights > 0,
          "low-rank check: empty light matrix ({}x{} texels, {} lights)", width, height, lights);
    for (int k : ranks) check(k >= 0, "low-rank check: rank {} is negative", k);
    const int cols = 3 * lights;
    const int64_t row_bytes = int64_t(width) * cols * 4;
    const int band_rows =
        int(std::clamp<int64_t>(options.band_bytes / std::max<int64_t>(row_bytes, 1), 1, height));
    const int bands = (height + band_rows - 1) / band_rows;

    using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(cols, cols);
    double sum_squares = 0;
    RowMatrix band;
    progress.begin("low-rank: reading images", uint64_t(bands) * lights);
    for (int band_index = 0; band_index < bands; ++band_index) {
        const int y0 = band_index * band_rows, y1 = std::min(height, y0 + band_rows);
        const int64_t texels = int64_t(y1 - y0) * width;
        band.resize(texels, cols);
        parallel_for(0, lights, [&](int64_t light) {
            Image image;
            read(int(light), image);
            check(image.width() == width && image.height() == height && image.channels() >= 3,
                  "low-rank check: image of light {} is {}x{}x{}, expected {}x{}x3", light,
                  image.width(), image.height(), image.channels(), width, height);
            const int ch = image.channels();
            for (int64_t t = 0; t < texels; ++t) {
                const float* p = image.data() + (int64_t(y0) * width + t) * ch;
                for (int c = 0; c < 3; ++c) band(t, 3 * light + c) = p[c];
            }
            progress.advance();
        });
        // Accumulate AᵀA in double, a fixed chunk of rows at a time (fixed order: the result does
        // not depend on the number of threads).
        constexpr int64_t kChunk = 2048;
        for (int64_t r = 0; r < texels; r += kChunk) {
            const int64_t m = std::min(kChunk, texels - r);
            const Eigen::MatrixXd chunk = band.middleRows(r, m).cast<double>();
            gram.selfadjointView<Eigen::Lower>().rankUpdate(chunk.transpose());
            sum_squares += chunk.squaredNorm();
        }
    }
    progress.finish();
    gram = gram.selfadjointView<Eigen::Lower>();

    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(gram, Eigen::EigenvaluesOnly);
    check(solver.info() == Eigen::Success, "low-rank check: eigen-decomposition failed");
    LowRankError result;
    result.rows = int64_t(width) * height;
    result.cols = cols;
    result.rms = std::sqrt(sum_squares / (double(result.rows) * cols));
    result.ranks = ranks;
    const Eigen::VectorXd& ascending = solver.eigenvalues();
    for (int i = cols - 1; i >= 0; --i) result.eigenvalues.push_back(std::max(0.0, ascending[i]));
    // Tail sums from the smallest eigenvalue up: accurate even when the tail is tiny.
    std::vector<double> tail(cols + 1, 0.0);
    for (int i = cols - 1; i >= 0; --i) tail[i] = tail[i + 1] + result.eigenvalues[i];
    const double total = sum_squares > 0 ? sum_squares : 1.0;
    for (int k : ranks) {
        const double rest = k >= cols ? 0.0 : std::min(tail[k], total);
        result.relative_rmse.push_back(sum_squares > 0 ? std::sqrt(rest / total) : 0.0);
        result.energy.push_back(sum_squares > 0 ? 1.0 - rest / total : 1.0);
    }
    return result;
}

}  // namespace btf

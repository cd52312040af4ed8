#include "btf/codecs/factor/rsvd.h"

#include <fmt/format.h>

#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <random>

#include "btf/util/error.h"
#include "btf/util/parallel.h"

namespace btf::factor {

namespace {

// Column slice of the transposed products: fixed, so sums do not depend on the thread count.
constexpr int64_t kColumnSlice = 2048;
// Row chunk of the direct products: large enough that packing the right-hand factor (cols × l)
// once per chunk costs little next to the product, small enough that a view's batch (nL · 3
// rows) still splits over the cores.
constexpr int64_t kRowChunk = 64;

Matrix orthonormal_basis(const Matrix& y) {
    Eigen::HouseholderQR<Matrix> qr(y);
    return qr.householderQ() * Matrix::Identity(y.rows(), y.cols());
}

Matrix gaussian(int64_t rows, int64_t cols, uint64_t seed) {
    Matrix out(rows, cols);
    std::mt19937_64 rng(seed);
    std::normal_distribution<float> normal;
    for (int64_t i = 0; i < out.size(); ++i) out.data()[i] = normal(rng);
    return out;
}

// Reads every batch once, centring rows if requested; calls use(m, first, rows) per matrix.
template <typename Use>
void pass(const RowBatches& batches, bool subtract_mean, std::vector<std::vector<float>>* means,
          std::vector<double>* energy, Progress& progress, std::string_view stage, Use&& use) {
    progress.begin(stage, static_cast<uint64_t>(batches.batches()));
    std::vector<int64_t> first;
    std::vector<Matrix> block;
    for (int b = 0; b < batches.batches(); ++b) {
        progress.poll();
        batches.read(b, first, block);
        for (int m = 0; m < batches.matrices(); ++m) {
            Matrix& rows = block[m];
            if (rows.rows() == 0) continue;
            if (rows.cols() != batches.cols(m) || first[m] < 0 ||
                first[m] + rows.rows() > batches.rows(m))
                fail(
                    "factorization: batch {} gives matrix {} rows [{}, {}) × {} columns, expected "
                    "rows within {} × {}",
                    b, m, first[m], first[m] + rows.rows(), rows.cols(), batches.rows(m),
                    batches.cols(m));
            if (subtract_mean) {
                for (int64_t r = 0; r < rows.rows(); ++r) {
                    const float mean = static_cast<float>(rows.row(r).cast<double>().mean());
                    rows.row(r).array() -= mean;
                    if (means) (*means)[m][first[m] + r] = mean;
                }
            }
            if (energy) (*energy)[m] += rows.cast<double>().squaredNorm();
            use(m, first[m], rows);
        }
        progress.advance();
    }
    progress.finish();
}

// y.middleRows(first, n) = rows · x, parallel over fixed row chunks.
void multiply_rows(const Matrix& rows, const Matrix& x, int64_t first, Matrix& y) {
    parallel_chunks(0, rows.rows(), kRowChunk, [&](int64_t r0, int64_t r1) {
        y.middleRows(first + r0, r1 - r0).noalias() = rows.middleRows(r0, r1 - r0) * x;
    });
}

// z += rowsᵀ · q.middleRows(first, n), parallel over fixed column slices.
void multiply_transposed(const Matrix& rows, const Matrix& q, int64_t first, Matrix& z) {
    const auto qb = q.middleRows(first, rows.rows());
    parallel_chunks(0, rows.cols(), kColumnSlice, [&](int64_t c0, int64_t c1) {
        z.middleRows(c0, c1 - c0).noalias() += rows.middleCols(c0, c1 - c0).transpose() * qb;
    });
}

}  // namespace

std::vector<Svd> randomized_svd(const RowBatches& batches, const SvdOptions& options,
                                Progress& progress) {
    const int count = batches.matrices();
    if (options.rank < 1) fail("factorization: rank {} must be at least 1", options.rank);
    if (options.oversampling < 0 || options.power_iterations < 0)
        fail("factorization: oversampling and power iterations must not be negative");
    std::vector<int> rank(count), width(count);
    for (int m = 0; m < count; ++m) {
        const int64_t smaller = std::min(batches.rows(m), batches.cols(m));
        if (smaller < 1) fail("factorization: matrix {} is empty", m);
        rank[m] = static_cast<int>(std::min<int64_t>(options.rank, smaller));
        width[m] = static_cast<int>(std::min<int64_t>(rank[m] + options.oversampling, smaller));
    }
    const int total_passes = 2 + 2 * options.power_iterations;
    int pass_number = 0;
    auto stage = [&] {
        return fmt::format("factorizing: pass {} of {}", ++pass_number, total_passes);
    };

    // Range finder: Y = M Ω.
    std::vector<Svd> result(count);
    std::vector<std::vector<float>> means(count);
    std::vector<double> energy(count, 0.0);
    std::vector<Matrix> y(count), z(count), basis(count);
    // With transforms the passes multiply M by mapped operands (RᵀΩ, LᵀQ) and map the products
    // (L·, R·): basis holds the unmapped thin factors, operand what a pass multiplies with.
    const Transforms* maps = options.transforms;
    std::vector<Matrix> operand(count);
    auto direct_pass = [&] {
        for (int m = 0; m < count; ++m) {
            if (maps) {
                operand[m] = basis[m];
                maps->right(m, operand[m], true);
            }
            y[m] = Matrix::Zero(batches.rows(m), width[m]);
        }
        const bool first_pass = pass_number == 0;
        pass(batches, options.subtract_mean, first_pass ? &means : nullptr,
             first_pass ? &energy : nullptr, progress, stage(),
             [&](int m, int64_t first, const Matrix& rows) {
                 multiply_rows(rows, maps ? operand[m] : basis[m], first, y[m]);
             });
        if (maps)
            for (int m = 0; m < count; ++m) maps->left(m, y[m], false);
    };
    for (int m = 0; m < count; ++m) {
        if (options.subtract_mean) means[m].assign(batches.rows(m), 0.0f);
        basis[m] = gaussian(batches.cols(m), width[m], options.seed + 7919 * uint64_t(m));
    }
    direct_pass();

    auto transposed_pass = [&] {
        for (int m = 0; m < count; ++m) {
            basis[m] = orthonormal_basis(y[m]);
            if (maps) {
                operand[m] = basis[m];
                maps->left(m, operand[m], true);
            }
            z[m] = Matrix::Zero(batches.cols(m), width[m]);
        }
        pass(batches, options.subtract_mean, nullptr, nullptr, progress, stage(),
             [&](int m, int64_t first, const Matrix& rows) {
                 multiply_transposed(rows, maps ? operand[m] : basis[m], first, z[m]);
             });
        if (maps)
            for (int m = 0; m < count; ++m) maps->right(m, z[m], false);
    };
    for (int i = 0; i < options.power_iterations; ++i) {
        transposed_pass();
        for (int m = 0; m < count; ++m) basis[m] = orthonormal_basis(z[m]);
        direct_pass();
    }
    // Final: Z = Mᵀ Q, so M ≈ Q Zᵀ; with Z = Q₂ R and Rᵀ = Ur S Vrᵀ: M ≈ (Q Ur) S (Q₂ Vr)ᵀ.
    transposed_pass();
    for (int m = 0; m < count; ++m) {
        Eigen::HouseholderQR<Matrix> qr(z[m]);
        const Matrix q2 = qr.householderQ() * Matrix::Identity(z[m].rows(), width[m]);
        const Eigen::MatrixXd r = qr.matrixQR()
                                      .topRows(width[m])
                                      .triangularView<Eigen::Upper>()
                                      .toDenseMatrix()
                                      .cast<double>();
        Eigen::JacobiSVD<Eigen::MatrixXd> svd(r.transpose(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
        Svd& out = result[m];
        const int k = rank[m];
        out.u = basis[m] * svd.matrixU().leftCols(k).cast<float>();
        out.v = q2 * svd.matrixV().leftCols(k).cast<float>();
        out.sigma = svd.singularValues().head(k).cast<float>();
        out.mean = std::move(means[m]);
        out.total_energy = energy[m];
        out.sketch_energy = svd.singularValues().squaredNorm();
    }
    return result;
}

std::vector<Factors> untransformed_factors(const RowBatches& batches, const Transforms& transforms,
                                           const std::vector<Svd>& svds,
                                           const std::vector<int>& keep, Progress& progress) {
    const int count = batches.matrices();
    if (static_cast<int>(svds.size()) != count || static_cast<int>(keep.size()) != count)
        fail("untransformed factors: {} SVDs and {} counts for {} matrices", svds.size(),
             keep.size(), count);
    const bool centred = !svds[0].mean.empty();
    // Operands: Rᵀ Q Σ⁻¹ for the row products, Lᵀ P for the column products.
    std::vector<Matrix> right(count), left(count);
    std::vector<Factors> out(count);
    for (int m = 0; m < count; ++m) {
        const Svd& svd = svds[m];
        const int k = keep[m];
        if (k < 0 || k > svd.sigma.size() || svd.u.rows() != batches.rows(m) ||
            svd.v.rows() != batches.cols(m) || svd.mean.empty() == centred)
            fail("untransformed factors: SVD {} does not match its matrix", m);
        if (k > 0 && !(svd.sigma[k - 1] > 0))
            fail("untransformed factors: SVD {} keeps a zero singular value", m);
        right[m] = svd.v.leftCols(k);
        transforms.right(m, right[m], true);
        right[m] = right[m] * svd.sigma.head(k).cwiseInverse().asDiagonal();
        left[m] = svd.u.leftCols(k);
        transforms.left(m, left[m], true);
        out[m].a = Matrix::Zero(batches.rows(m), k);
        out[m].b = Matrix::Zero(batches.cols(m), k);
    }
    pass(batches, centred, nullptr, nullptr, progress, "factorizing: untransforming",
         [&](int m, int64_t first, const Matrix& rows) {
             if (keep[m] == 0) return;
             multiply_rows(rows, right[m], first, out[m].a);
             multiply_transposed(rows, left[m], first, out[m].b);
         });
    return out;
}

Svd exact_svd(const Matrix& matrix, int rank, bool subtract_mean) {
    Eigen::MatrixXd m = matrix.cast<double>();
    Svd out;
    if (subtract_mean) {
        out.mean.resize(m.rows());
        for (int64_t r = 0; r < m.rows(); ++r) {
            const double mean = m.row(r).mean();
            m.row(r).array() -= mean;
            out.mean[r] = static_cast<float>(mean);
        }
    }
    out.total_energy = m.squaredNorm();
    Eigen::BDCSVD<Eigen::MatrixXd> svd(m, Eigen::ComputeThinU | Eigen::ComputeThinV);
    const int k = static_cast<int>(std::min<int64_t>(rank, std::min(m.rows(), m.cols())));
    out.u = svd.matrixU().leftCols(k).cast<float>();
    out.v = svd.matrixV().leftCols(k).cast<float>();
    out.sigma = svd.singularValues().head(k).cast<float>();
    out.sketch_energy = out.total_energy;
    return out;
}

MemoryRows::MemoryRows(std::vector<const Matrix*> matrices, int batch_rows)
    : m_matrices(std::move(matrices)), m_batch_rows(std::max(1, batch_rows)) {
    int64_t rows = 0;
    for (const Matrix* m : m_matrices) rows = std::max<int64_t>(rows, m->rows());
    m_batches = static_cast<int>((rows + m_batch_rows - 1) / m_batch_rows);
}

void MemoryRows::read(int batch, std::vector<int64_t>& first, std::vector<Matrix>& out) const {
    first.assign(m_matrices.size(), 0);
    out.resize(m_matrices.size());
    for (size_t m = 0; m < m_matrices.size(); ++m) {
        const int64_t begin =
            std::min<int64_t>(int64_t(batch) * m_batch_rows, m_matrices[m]->rows());
        const int64_t end = std::min<int64_t>(begin + m_batch_rows, m_matrices[m]->rows());
        first[m] = begin;
        out[m] = m_matrices[m]->middleRows(begin, end - begin);
    }
}

}  // namespace btf::factor

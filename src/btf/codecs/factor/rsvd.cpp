// SPDX-License-Identifier: MIT
#include "btf/codecs/factor/rsvd.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <optional>
#include <random>

#include "btf/util/blas.h"
#include "btf/util/collective.h"
#include "btf/util/error.h"
#include "btf/util/parallel.h"
#include "btf/util/thin_products.h"

namespace btf::factor {

namespace {

// Column slice of the transposed products: fixed, so sums do not depend on the thread count.
constexpr int64_t kColumnSlice = 2048;
// Row chunk of the direct products: small enough that a view's batch (nL · 3 rows) splits over
// the cores; for OpenBLAS (CPUs without AVX-512), large enough that packing the right-hand
// factor (cols × l) once per chunk costs little next to the product (128 rows: 1.1× faster than
// 64 at fmf's shapes, bench/gemm_pass). btfkit's own kernels give the same bits for any chunk.
constexpr int64_t kRowChunk = 128;
// Row chunk of the Gram–Schmidt sums over the thin factors' rows (fixed, for the same reason).
constexpr int64_t kThinChunk = 4096;

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

// The ranks of a distributed run (util/collective.h) and this rank's share of the batches; one
// process: every batch, and sums that do nothing.
struct Ranks {
    Collective* collective = nullptr;
    int first = 0, last = 0;  // batches [first, last)

    explicit Ranks(const RowBatches& batches) : collective(current_collective()) {
        const auto [f, l] =
            collective ? rank_share(batches.batches(), collective->rank(), collective->size())
                       : std::pair<int64_t, int64_t>(0, batches.batches());
        first = static_cast<int>(f);
        last = static_cast<int>(l);
    }
    bool owns(int batch) const { return batch >= first && batch < last; }
    // Sums over the ranks (each holds zeros where it read nothing, or its partial sums).
    void sum(Matrix& m) const {
        if (collective) collective->sum(m.data(), m.size());
    }
    void sum(std::vector<float>& v) const {
        if (collective) collective->sum(v.data(), static_cast<int64_t>(v.size()));
    }
    void sum(std::vector<double>& v) const {
        if (collective) collective->sum(v.data(), static_cast<int64_t>(v.size()));
    }
};

// The rows of one matrix in one batch, as read or as held in memory (row-major, cols floats per
// row).
struct Rows {
    const float* data;
    int64_t rows, cols;
};

// Σ of the squares of rows [r0, r1) × columns [c0, c1), in double, row by row; along a row in
// 16 running sums of every 16th column (a fixed order the compiler can vectorize: one running sum
// would make each addition wait for the one before), added up at the end of the row.
double sum_of_squares(const Rows& rows, int64_t r0, int64_t r1, int64_t c0, int64_t c1) {
    constexpr int kLanes = 16;
    double sum = 0;
    for (int64_t r = r0; r < r1; ++r) {
        const float* row = rows.data + r * rows.cols;
        double lanes[kLanes] = {};
        int64_t c = c0;
        for (; c + kLanes <= c1; c += kLanes)
            for (int j = 0; j < kLanes; ++j) lanes[j] += double(row[c + j]) * row[c + j];
        double row_sum = 0;
        for (; c < c1; ++c) row_sum += double(row[c]) * row[c];
        for (const double lane : lanes) row_sum += lane;
        sum += row_sum;
    }
    return sum;
}

// Σ of the squares of the rows in double, summed per fixed row chunk and then in chunk order.
double squared_norm(const Rows& rows) {
    const int64_t chunks = (rows.rows + kRowChunk - 1) / kRowChunk;
    std::vector<double> sums(chunks, 0.0);
    parallel_chunks(0, rows.rows, kRowChunk, [&](int64_t r0, int64_t r1) {
        sums[r0 / kRowChunk] = sum_of_squares(rows, r0, r1, 0, rows.cols);
    });
    double total = 0;
    for (double s : sums) total += s;
    return total;
}

// pass() over this rank's share of the batches.
template <typename Use>
void pass_batches(const RowBatches& batches, const Ranks& ranks, bool subtract_mean,
                  std::vector<std::vector<float>>* means, std::vector<double>* energy,
                  Progress& progress, Use& use) {
    std::vector<int64_t> first, counts;
    std::vector<const float*> data;
    std::vector<Matrix> block;
    for (int b = ranks.first; b < ranks.last; ++b) {
        progress.poll();
        const bool viewed = !subtract_mean && batches.view(b, first, data, counts);
        if (!viewed) {
            batches.read(b, first, block);
            data.resize(block.size());
            counts.resize(block.size());
        }
        for (int m = 0; m < batches.matrices(); ++m) {
            const int64_t cols = viewed ? batches.cols(m) : block[m].cols();
            const int64_t count = viewed ? counts[m] : block[m].rows();
            if (count == 0) continue;
            if (cols != batches.cols(m) || first[m] < 0 || first[m] + count > batches.rows(m))
                fail(
                    "factorization: batch {} gives matrix {} rows [{}, {}) × {} columns, expected "
                    "rows within {} × {}",
                    b, m, first[m], first[m] + count, cols, batches.rows(m), batches.cols(m));
            if (!viewed) {
                Matrix& rows = block[m];
                if (subtract_mean) {
                    parallel_for(0, rows.rows(), [&](int64_t r) {
                        const float mean = static_cast<float>(rows.row(r).cast<double>().mean());
                        rows.row(r).array() -= mean;
                        if (means) (*means)[m][first[m] + r] = mean;
                    });
                }
                data[m] = rows.data();
            }
            const Rows rows{data[m], count, cols};
            if (energy) (*energy)[m] += squared_norm(rows);
            use(m, first[m], rows);
        }
        progress.advance();
    }
}

// Reads every batch of this rank's share once (or views it, when the rows are in memory and need
// no centring), centring rows if requested; calls use(m, first, rows) per matrix. Across ranks, a
// failure on any rank is thrown on every rank at the end of the pass; the caller sums what the
// pass computed.
template <typename Use>
void pass(const RowBatches& batches, const Ranks& ranks, bool subtract_mean,
          std::vector<std::vector<float>>* means, std::vector<double>* energy, Progress& progress,
          std::string_view stage, Use&& use) {
    progress.begin(stage, static_cast<uint64_t>(ranks.last - ranks.first));
    together(ranks.collective,
             [&] { pass_batches(batches, ranks, subtract_mean, means, energy, progress, use); });
    progress.finish();
}

// y.middleRows(first, n) = rows · xtᵀ (xt: w × cols, the thin factor transposed), parallel over
// fixed row chunks (util/thin_products.h).
void multiply_rows(const Rows& rows, const Matrix& xt, int64_t first, Matrix& y) {
    const int64_t w = xt.rows();
    parallel_chunks(0, rows.rows, kRowChunk, [&](int64_t r0, int64_t r1) {
        thin::multiply(rows.data + r0 * rows.cols, r1 - r0, rows.cols, rows.cols, xt.data(), w,
                       rows.cols, y.data() + (first + r0) * w, w);
    });
}

// zt += q.middleRows(first, n)ᵀ · rows (zt: w × cols, the transpose of z = Mᵀ q), parallel over
// fixed column slices (util/thin_products.h; as zᵀ, the rows are read in their own order).
// With `energy`, also adds the rows' Σ of squares to it, summed per slice while the slice is in
// the cache from the product, then in slice order.
void multiply_transposed(const Rows& rows, const Matrix& q, int64_t first, Matrix& zt,
                         double* energy = nullptr) {
    const int64_t w = q.cols();
    std::vector<double> sums(energy ? (rows.cols + kColumnSlice - 1) / kColumnSlice : 0);
    parallel_chunks(0, rows.cols, kColumnSlice, [&](int64_t c0, int64_t c1) {
        thin::multiply_add_transposed(q.data() + first * w, rows.rows, w, w, rows.data + c0,
                                      c1 - c0, rows.cols, zt.data() + c0, rows.cols);
        if (energy) sums[c0 / kColumnSlice] = sum_of_squares(rows, 0, rows.rows, c0, c1);
    });
    for (double sum : sums) *energy += sum;
}

// aᵀ·b in double for tall a and b of as many rows, summed over fixed row chunks in chunk order.
Eigen::MatrixXd inner(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
    const int64_t n = a.rows(), chunks = (n + kThinChunk - 1) / kThinChunk;
    std::vector<Eigen::MatrixXd> parts(chunks);
    parallel_chunks(0, n, kThinChunk, [&](int64_t r0, int64_t r1) {
        parts[r0 / kThinChunk].noalias() =
            a.middleRows(r0, r1 - r0).transpose() * b.middleRows(r0, r1 - r0);
    });
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(a.cols(), b.cols());
    for (const Eigen::MatrixXd& part : parts) out += part;
    return out;
}

// aᵀ·a in double, as inner().
Eigen::MatrixXd gram(const Eigen::MatrixXd& a) {
    return inner(a, a);
}

// z ← z·R⁻¹ with zᵀz = RᵀR (Cholesky QR), in parallel over fixed row chunks; false, leaving z
// as it was, when zᵀz is too ill-conditioned for it (then Householder QR must do).
bool cholesky_orthonormalize(Eigen::MatrixXd& z) {
    const Eigen::LLT<Eigen::MatrixXd> llt(gram(z));
    if (llt.info() != Eigen::Success) return false;
    const Eigen::VectorXd d = llt.matrixL().toDenseMatrix().diagonal();
    if (!(d.minCoeff() > 1e-6 * d.maxCoeff())) return false;
    const Eigen::MatrixXd r_inverse =
        llt.matrixU().solve(Eigen::MatrixXd::Identity(z.cols(), z.cols()));
    parallel_chunks(0, z.rows(), kThinChunk, [&](int64_t r0, int64_t r1) {
        z.middleRows(r0, r1 - r0) = z.middleRows(r0, r1 - r0) * r_inverse;
    });
    return true;
}

// Removes from `z` its components in the span of the orthonormal columns of `basis` (twice:
// "twice is enough"), in double, with sums over fixed row chunks.
void project_out(const Eigen::MatrixXd& basis, Eigen::MatrixXd& z) {
    if (basis.cols() == 0) return;
    for (int round = 0; round < 2; ++round) {
        const Eigen::MatrixXd c = inner(basis, z);
        parallel_chunks(0, z.rows(), kThinChunk, [&](int64_t r0, int64_t r1) {
            z.middleRows(r0, r1 - r0).noalias() -= basis.middleRows(r0, r1 - r0) * c;
        });
    }
}

}  // namespace

int svd_passes(const SvdOptions& options, bool transforms) {
    const int q = options.power_iterations;
    if (options.method == SvdMethod::kSubspace) return 2 + 2 * q;
    return transforms ? 3 + 2 * q : 2 + q;
}

namespace {

struct Shapes {
    std::vector<int> rank, width;
};

Shapes check_options(const RowBatches& batches, const SvdOptions& options) {
    const int count = batches.matrices();
    if (options.rank < 1) fail("factorization: rank {} must be at least 1", options.rank);
    if (options.oversampling < 0 || options.power_iterations < 0 || options.block < 0)
        fail("factorization: oversampling, power iterations and block must not be negative");
    Shapes out;
    out.rank.resize(count);
    out.width.resize(count);
    for (int m = 0; m < count; ++m) {
        const int64_t smaller = std::min(batches.rows(m), batches.cols(m));
        if (smaller < 1) fail("factorization: matrix {} is empty", m);
        out.rank[m] = static_cast<int>(std::min<int64_t>(options.rank, smaller));
        out.width[m] =
            static_cast<int>(std::min<int64_t>(out.rank[m] + options.oversampling, smaller));
    }
    return out;
}

std::vector<Svd> subspace_iteration(const RowBatches& batches, const Ranks& ranks,
                                    const SvdOptions& options, const Shapes& shapes,
                                    Progress& progress) {
    const int count = batches.matrices();
    const std::vector<int>& rank = shapes.rank;
    const std::vector<int>& width = shapes.width;
    const int total_passes = svd_passes(options);
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
                operand[m].transposeInPlace();
            } else {
                operand[m] = basis[m].transpose();
            }
            y[m] = Matrix::Zero(batches.rows(m), width[m]);
        }
        const bool first_pass = pass_number == 0;
        pass(batches, ranks, options.subtract_mean, first_pass ? &means : nullptr,
             first_pass ? &energy : nullptr, progress, stage(),
             [&](int m, int64_t first, const Rows& rows) {
                 multiply_rows(rows, operand[m], first, y[m]);
             });
        for (int m = 0; m < count; ++m) {
            ranks.sum(y[m]);
            if (first_pass) ranks.sum(means[m]);
        }
        if (first_pass) ranks.sum(energy);
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
            z[m] = Matrix::Zero(width[m], batches.cols(m));  // zᵀ during the pass
        }
        pass(batches, ranks, options.subtract_mean, nullptr, nullptr, progress, stage(),
             [&](int m, int64_t first, const Rows& rows) {
                 multiply_transposed(rows, maps ? operand[m] : basis[m], first, z[m]);
             });
        for (int m = 0; m < count; ++m) {
            ranks.sum(z[m]);
            z[m].transposeInPlace();
            if (maps) maps->right(m, z[m], false);
        }
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

// The next Krylov block: `z` made orthogonal to the blocks so far (basis.leftCols(used)) and
// orthonormalized, into basis.middleCols(used, b). Columns that lie in the span already (a matrix
// of lower rank than the blocks) are replaced by random directions, so that the blocks stay
// orthonormal.
void next_block(Eigen::MatrixXd& basis, int64_t used, Eigen::MatrixXd z, uint64_t seed) {
    const int64_t b = z.cols();
    Eigen::VectorXd before = z.colwise().norm();
    project_out(basis.leftCols(used), z);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    bool replaced = false;
    for (int64_t c = 0; c < b; ++c) {
        if (z.col(c).norm() > 1e-5 * before[c] && std::isfinite(z.col(c).norm())) continue;
        for (int64_t r = 0; r < z.rows(); ++r) z(r, c) = normal(rng);
        replaced = true;
    }
    if (replaced) project_out(basis.leftCols(used), z);
    // Cholesky QR twice (CholeskyQR2), projecting once more in between; Householder QR where the
    // block is too ill-conditioned for it.
    if (cholesky_orthonormalize(z)) {
        project_out(basis.leftCols(used), z);
        if (cholesky_orthonormalize(z)) {
            basis.middleCols(used, b) = z;
            return;
        }
    }
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(z);
    basis.middleCols(used, b) = qr.householderQ() * Eigen::MatrixXd::Identity(z.rows(), b);
    // Householder Q spans z's columns only where they are independent: project once more.
    Eigen::MatrixXd block = basis.middleCols(used, b);
    project_out(basis.leftCols(used), block);
    Eigen::HouseholderQR<Eigen::MatrixXd> again(block);
    basis.middleCols(used, b) = again.householderQ() * Eigen::MatrixXd::Identity(z.rows(), b);
}

// Rows of each matrix sampled from up to kSampleBatches batches spread evenly over the source,
// evenly spaced within each batch, at most `want[m]` of them in all: the start of block Krylov.
// Reading a few batches costs a few per cent of a pass; rows held in memory are copied only.
constexpr int kSampleBatches = 16;
std::vector<Matrix> sample_rows(const RowBatches& batches, const Ranks& ranks,
                                const std::vector<int64_t>& want, bool subtract_mean,
                                Progress& progress) {
    const int count = batches.matrices(), nb = std::min(batches.batches(), kSampleBatches);
    // The plan first, from the batches' row counts: which rows of which batch go where, the same
    // on every rank whichever batches it reads.
    struct Take {
        int64_t rows = 0, share = 0, at = 0;  // the batch's rows, taken, first row of out
    };
    std::vector<std::vector<Take>> plan(nb, std::vector<Take>(count));
    std::vector<int> sampled(nb);
    std::vector<int64_t> taken(count, 0);
    for (int i = 0; i < nb; ++i) {
        sampled[i] = static_cast<int>((int64_t(2 * i + 1) * batches.batches()) / (2 * nb));
        for (int m = 0; m < count; ++m) {
            Take& t = plan[i][m];
            t.rows = batches.batch_rows(sampled[i], m);
            // This batch's share of what is still wanted from the batches left.
            t.share = std::min<int64_t>(t.rows,
                                        (want[m] - taken[m] + (nb - i) - 1) / std::max(1, nb - i));
            t.at = taken[m];
            taken[m] += t.share;
        }
    }
    std::vector<Matrix> out(count);
    for (int m = 0; m < count; ++m) out[m] = Matrix::Zero(taken[m], batches.cols(m));
    int reads = 0;
    for (int i = 0; i < nb; ++i) reads += ranks.owns(sampled[i]);
    progress.begin("factorizing: sampling rows for the start", static_cast<uint64_t>(reads));
    together(ranks.collective, [&] {
        std::vector<int64_t> first, counts;
        std::vector<const float*> data;
        std::vector<Matrix> block;
        for (int i = 0; i < nb; ++i) {
            const int b = sampled[i];
            if (!ranks.owns(b)) continue;
            progress.poll();
            const bool viewed = batches.view(b, first, data, counts);
            if (!viewed) batches.read(b, first, block);
            for (int m = 0; m < count; ++m) {
                const Take& t = plan[i][m];
                if (t.share == 0) continue;
                const int64_t n = viewed ? counts[m] : block[m].rows();
                if (n != t.rows || (!viewed && block[m].cols() != batches.cols(m)))
                    fail(
                        "factorization: batch {} gives matrix {} {} rows × {} columns, expected "
                        "{} × {}",
                        b, m, n, viewed ? batches.cols(m) : block[m].cols(), t.rows,
                        batches.cols(m));
                const Eigen::Map<const Matrix> rows(viewed ? data[m] : block[m].data(), n,
                                                    batches.cols(m));
                for (int64_t j = 0; j < t.share; ++j) {
                    auto row = out[m].row(t.at + j);
                    row = rows.row((2 * j + 1) * n / (2 * t.share));
                    if (subtract_mean) row.array() -= static_cast<float>(row.cast<double>().mean());
                }
            }
            progress.advance();
        }
    });
    progress.finish();
    for (int m = 0; m < count; ++m) ranks.sum(out[m]);
    return out;
}

// The first block: the b leading right singular vectors of the sampled rows S (from the s × s
// Gram matrix S Sᵀ in double), completed by Gaussian columns where S has fewer than b rows.
// For redundant data such as a BTF's images, the rows' leading subspace is close to the whole
// matrix's: the Krylov blocks start near their goal instead of at random.
Eigen::MatrixXd start_block(const Matrix& sampled, int64_t cols, int64_t b, uint64_t seed) {
    Eigen::MatrixXd z(cols, b);
    const int64_t s = sampled.rows(), taken = std::min(s, b);
    if (taken > 0) {
        // S Sᵀ over fixed column slices in float, the slices summed in double in order.
        const int64_t slices = (cols + kThinChunk - 1) / kThinChunk;
        std::vector<Matrix> parts(slices);
        parallel_chunks(0, cols, kThinChunk, [&](int64_t c0, int64_t c1) {
            const auto slice = sampled.middleCols(c0, c1 - c0);
            parts[c0 / kThinChunk].noalias() = slice * slice.transpose();
        });
        Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(s, s);
        for (const Matrix& part : parts) gram += part.cast<double>();
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram);
        const Matrix lead = eigen.eigenvectors().rightCols(taken).rowwise().reverse().cast<float>();
        parallel_chunks(0, cols, kThinChunk, [&](int64_t c0, int64_t c1) {
            z.block(c0, 0, c1 - c0, taken) =
                (sampled.middleCols(c0, c1 - c0).transpose() * lead).cast<double>();
        });
    }
    if (taken < b) z.rightCols(b - taken) = gaussian(cols, b - taken, seed).cast<double>();
    return z;
}

std::vector<Svd> block_krylov(const RowBatches& batches, const Ranks& ranks,
                              const SvdOptions& options, const Shapes& shapes, Progress& progress) {
    const int count = batches.matrices();
    const Transforms* maps = options.transforms;
    // A first block X₀ (from sampled rows) and q + 1 blocks after it, b columns each, within
    // min(rows, cols) columns in all; the blocks after X₀ must hold the rank.
    std::vector<int> block(count), depth(count);
    int passes_depth = 0;
    for (int m = 0; m < count; ++m) {
        const int64_t smaller = std::min(batches.rows(m), batches.cols(m));
        const int64_t q = options.power_iterations, k = shapes.rank[m];
        int64_t b =
            options.block > 0 ? options.block : (2 * (k + options.oversampling) + q + 1) / (q + 2);
        b = std::min(std::max(b, (k + q) / (q + 1)), smaller);
        block[m] = static_cast<int>(b);
        depth[m] = static_cast<int>(std::min<int64_t>(q + 1, smaller / b - 1));
        if (int64_t(depth[m]) * b < k)
            return subspace_iteration(batches, ranks, options, shapes, progress);
        passes_depth = std::max(passes_depth, depth[m]);
    }
    const int total_passes = maps ? 1 + 2 * passes_depth : 1 + passes_depth;
    int pass_number = 0;
    auto stage = [&] {
        return fmt::format("factorizing: pass {} of {}", ++pass_number, total_passes);
    };

    std::vector<std::vector<float>> means(count);
    std::vector<double> energy(count, 0.0);
    std::vector<Eigen::MatrixXd> basis(count);  // [X₀ … X_depth], cols × (depth + 1) b
    std::vector<Matrix> ys(count);              // [M̃X₀ … M̃X_depth], rows × (depth + 1) b
    std::vector<Matrix> operand(count), y(count), z(count);
    std::vector<int64_t> want(count);
    for (int m = 0; m < count; ++m) want[m] = std::min<int64_t>(4 * block[m], batches.rows(m));
    const std::vector<Matrix> sampled =
        sample_rows(batches, ranks, want, options.subtract_mean, progress);
    for (int m = 0; m < count; ++m) {
        if (options.subtract_mean) means[m].assign(batches.rows(m), 0.0f);
        const int64_t w = int64_t(depth[m] + 1) * block[m];
        basis[m].resize(batches.cols(m), w);
        ys[m].resize(batches.rows(m), w);
        const uint64_t seed = options.seed + 7919 * uint64_t(m);
        Matrix start = start_block(sampled[m], batches.cols(m), block[m], seed).cast<float>();
        if (maps) maps->right(m, start, false);  // rows of M Rᵀ: R applied to the sampled rows
        next_block(basis[m], 0, start.cast<double>(), seed);
    }
    for (int i = 0; i <= passes_depth; ++i) {
        // This pass: Y = M̃ Xᵢ and, without maps, Z = M̃ᵀ Y from the same rows.
        const bool fused = !maps;
        for (int m = 0; m < count; ++m) {
            if (i > depth[m]) continue;
            operand[m] = basis[m].middleCols(int64_t(i) * block[m], block[m]).cast<float>();
            if (maps) maps->right(m, operand[m], true);
            operand[m].transposeInPlace();
            y[m] = Matrix::Zero(batches.rows(m), block[m]);
            if (fused && i < depth[m]) z[m] = Matrix::Zero(block[m], batches.cols(m));  // zᵀ
        }
        // The first pass sums the energy too: in the transposed products' slices where they run
        // (every matrix has a second block), else on its own.
        const bool first_pass = i == 0, energy_in_slices = first_pass && fused;
        pass(batches, ranks, options.subtract_mean, first_pass ? &means : nullptr,
             first_pass && !energy_in_slices ? &energy : nullptr, progress, stage(),
             [&](int m, int64_t first, const Rows& rows) {
                 if (i > depth[m]) return;
                 multiply_rows(rows, operand[m], first, y[m]);
                 if (fused && i < depth[m])
                     multiply_transposed(rows, y[m], first, z[m],
                                         energy_in_slices ? &energy[m] : nullptr);
             });
        for (int m = 0; m < count; ++m) {
            if (first_pass) ranks.sum(means[m]);
            if (i > depth[m]) continue;
            ranks.sum(y[m]);
            if (fused && i < depth[m]) ranks.sum(z[m]);
        }
        if (first_pass) ranks.sum(energy);
        for (int m = 0; m < count; ++m) {
            if (i > depth[m]) continue;
            if (maps) maps->left(m, y[m], false);
            ys[m].middleCols(int64_t(i) * block[m], block[m]) = y[m];
        }
        if (i == passes_depth) break;
        if (maps) {
            // Z = R Mᵀ (Lᵀ Y), in a pass of its own.
            for (int m = 0; m < count; ++m) {
                if (i >= depth[m]) continue;
                operand[m] = y[m];
                maps->left(m, operand[m], true);
                z[m] = Matrix::Zero(block[m], batches.cols(m));  // zᵀ
            }
            pass(batches, ranks, options.subtract_mean, nullptr, nullptr, progress, stage(),
                 [&](int m, int64_t first, const Rows& rows) {
                     if (i < depth[m]) multiply_transposed(rows, operand[m], first, z[m]);
                 });
            for (int m = 0; m < count; ++m)
                if (i < depth[m]) ranks.sum(z[m]);
        }
        for (int m = 0; m < count; ++m) {
            if (i >= depth[m]) continue;
            z[m].transposeInPlace();
            if (maps) maps->right(m, z[m], false);
            next_block(basis[m], int64_t(i + 1) * block[m], z[m].cast<double>(),
                       options.seed + 7919 * uint64_t(m) + uint64_t(i + 1));
        }
    }

    // Rayleigh–Ritz: M̃ V ≈ Uy S Wᵀ (V = the blocks), so M̃ ≈ M̃ V Vᵀ ≈ Uy S (V W)ᵀ, the best
    // rank-k approximation with rows in span(V).
    std::vector<Svd> result(count);
    for (int m = 0; m < count; ++m) {
        const int k = shapes.rank[m];
        Svd& out = result[m];
        const int64_t w = ys[m].cols();
        // The SVD of Y = M̃V from the eigen-decomposition of YᵀY (w × w, summed in parallel):
        // Y = U S Wᵀ with U = Y W S⁻¹. Where the kept singular values span more than 10⁴ (their
        // squares 10⁸, beyond what the Gram matrix resolves in double), Householder QR of Y.
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram(ys[m].cast<double>()));
        Eigen::MatrixXd w_vectors = eigen.eigenvectors().rowwise().reverse();
        Eigen::VectorXd sigma = eigen.eigenvalues().reverse().cwiseMax(0.0).cwiseSqrt();
        if (eigen.info() == Eigen::Success && sigma[k - 1] > 1e-4 * sigma[0]) {
            const Matrix right =
                (w_vectors.leftCols(k) * sigma.head(k).cwiseInverse().asDiagonal()).cast<float>();
            out.u.resize(ys[m].rows(), k);
            parallel_chunks(0, ys[m].rows(), kThinChunk, [&](int64_t r0, int64_t r1) {
                out.u.middleRows(r0, r1 - r0).noalias() = ys[m].middleRows(r0, r1 - r0) * right;
            });
        } else {
            const Eigen::MatrixXd yd = ys[m].cast<double>();
            Eigen::HouseholderQR<Eigen::MatrixXd> qr(yd);
            const Eigen::MatrixXd r =
                qr.matrixQR().topRows(w).triangularView<Eigen::Upper>().toDenseMatrix();
            Eigen::JacobiSVD<Eigen::MatrixXd> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
            Eigen::MatrixXd u = Eigen::MatrixXd::Zero(yd.rows(), k);
            u.topRows(w) = svd.matrixU().leftCols(k);
            u.applyOnTheLeft(qr.householderQ());
            out.u = u.cast<float>();
            w_vectors = svd.matrixV();
            sigma = svd.singularValues();
        }
        const Eigen::MatrixXd kept = w_vectors.leftCols(k);
        out.v.resize(basis[m].rows(), k);
        parallel_chunks(0, basis[m].rows(), kThinChunk, [&](int64_t r0, int64_t r1) {
            out.v.middleRows(r0, r1 - r0) = (basis[m].middleRows(r0, r1 - r0) * kept).cast<float>();
        });
        out.sigma = sigma.head(k).cast<float>();
        out.mean = std::move(means[m]);
        out.total_energy = energy[m];
        out.sketch_energy = sigma.squaredNorm();
    }
    return result;
}

}  // namespace

std::vector<Svd> randomized_svd(const RowBatches& batches, const SvdOptions& options,
                                Progress& progress) {
    const Shapes shapes = check_options(batches, options);
    // OpenBLAS on one thread while it runs the products (not at all with btfkit's kernels).
    std::optional<blas::SerialBlas> serial;
    if (thin::kernel() == thin::Kernel::kBlas) serial.emplace();
    const Ranks ranks(batches);
    return options.method == SvdMethod::kBlockKrylov
               ? block_krylov(batches, ranks, options, shapes, progress)
               : subspace_iteration(batches, ranks, options, shapes, progress);
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
        right[m] = (right[m] * svd.sigma.head(k).cwiseInverse().asDiagonal()).transpose().eval();
        left[m] = svd.u.leftCols(k);
        transforms.left(m, left[m], true);
        out[m].a = Matrix::Zero(batches.rows(m), k);
        out[m].b = Matrix::Zero(k, batches.cols(m));  // bᵀ during the pass
    }
    // OpenBLAS on one thread while it runs the products (not at all with btfkit's kernels).
    std::optional<blas::SerialBlas> serial;
    if (thin::kernel() == thin::Kernel::kBlas) serial.emplace();
    const Ranks ranks(batches);
    pass(batches, ranks, centred, nullptr, nullptr, progress, "factorizing: untransforming",
         [&](int m, int64_t first, const Rows& rows) {
             if (keep[m] == 0) return;
             multiply_rows(rows, right[m], first, out[m].a);
             multiply_transposed(rows, left[m], first, out[m].b);
         });
    for (Factors& f : out) {
        ranks.sum(f.a);
        ranks.sum(f.b);
        f.b.transposeInPlace();
    }
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

int64_t RowBatches::batch_rows(int batch, int matrix) const {
    std::vector<int64_t> first;
    std::vector<Matrix> out;
    read(batch, first, out);
    return out.at(matrix).rows();
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

int64_t MemoryRows::batch_rows(int batch, int matrix) const {
    const int64_t rows = m_matrices[matrix]->rows();
    const int64_t begin = std::min<int64_t>(int64_t(batch) * m_batch_rows, rows);
    return std::min<int64_t>(begin + m_batch_rows, rows) - begin;
}

bool MemoryRows::view(int batch, std::vector<int64_t>& first, std::vector<const float*>& data,
                      std::vector<int64_t>& rows) const {
    first.assign(m_matrices.size(), 0);
    data.assign(m_matrices.size(), nullptr);
    rows.assign(m_matrices.size(), 0);
    for (size_t m = 0; m < m_matrices.size(); ++m) {
        const int64_t begin =
            std::min<int64_t>(int64_t(batch) * m_batch_rows, m_matrices[m]->rows());
        first[m] = begin;
        rows[m] = std::min<int64_t>(begin + m_batch_rows, m_matrices[m]->rows()) - begin;
        data[m] = m_matrices[m]->data() + begin * m_matrices[m]->cols();
    }
    return true;
}

}  // namespace btf::factor
